"""Reference solutions: exact and similarity solutions, and the FiPy formulation of the
vertical step that the compiled kernel is tested against."""
