"""Transport along the slope, the hyperbolic part of the multilayer system (docs/model.md):
the numpy reference formulation (:mod:`.reference`), the same scheme compiled
(:mod:`.kernel`) and the lateral boundaries (:mod:`.boundaries`)."""
