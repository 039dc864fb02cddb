"""The numerics of the multilayer model: mesh, transport, stresses, the exact vertical step,
its compiled column kernel, diagnostics and the time loop (:class:`Simulation`).

The engine reads a validated scenario but never imports I/O, the command line or the
plugin host (a test enforces it).
"""

from multilayer.engine.kernel_cache import clear_if_stale

clear_if_stale()  # before any kernel is loaded from numba's cache (kernel_cache.py)
