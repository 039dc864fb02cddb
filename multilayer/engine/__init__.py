"""The numerics of the multilayer model: mesh, transport, the implicit vertical step,
the pressure models, the state, diagnostics and the time loop (:class:`Simulation`).

The engine is built from plain typed configuration (:mod:`multilayer.engine.config`) and
the plugin instances handed to it; it never imports the scenario files, I/O, the command
line or the plugin host (tests/test_architecture.py).  Importing it compiles, loads and
registers nothing: the numba kernels are compiled (or loaded from numba's cache, checked
against their sources) on their first call (:mod:`multilayer.engine.compiled`).
"""
