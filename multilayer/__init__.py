"""multilayer: a multilayer shallow-flow simulator of dense granular flows.

The package is organised by role (docs/architecture.md):

- :mod:`multilayer.engine`: the numerics (mesh, transport, vertical step, pressure models,
  state, diagnostics, the time loop), built from typed configuration and plugin
  instances; it imports nothing of the packages above it (scenario, io, app, plugin host);
- :mod:`multilayer.reference`: exact and similarity solutions and the FiPy reference
  formulations the fast kernels are tested against;
- :mod:`multilayer.scenario`: scenario files (schema, YAML, overrides, messages);
- :mod:`multilayer.io`: results, plots, exports and study files;
- :mod:`multilayer.plugins`: the rheology plugin contract, the pluggy host, the built-ins;
- :mod:`multilayer.app`: the factory of the engine, the command line, the runner, studies;
- :mod:`multilayer.testing`: the pytest plugin of the scenarios' expectations.

The public API (docs/api.md) is re-exported here and imported lazily, so
``import multilayer`` is cheap: :func:`load` and :func:`run` a scenario,
:class:`Simulation` to step one by hand, and the plugin contract (:class:`Rheology`,
:class:`Material`, :data:`hookimpl`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

_EXPORTS = {
    "load": "multilayer.app.api",
    "run": "multilayer.app.api",
    "Material": "multilayer.plugins.contract",
    "Rheology": "multilayer.plugins.contract",
    "hookimpl": "multilayer.plugins.host",
    "Simulation": "multilayer.app.simulation",
}

__all__ = ["Material", "Rheology", "Simulation", "__version__", "hookimpl", "load", "run"]

if TYPE_CHECKING:
    from multilayer.app.api import load, run
    from multilayer.app.simulation import Simulation
    from multilayer.plugins.contract import Material, Rheology
    from multilayer.plugins.host import hookimpl


def __getattr__(name: str) -> Any:
    """Import a public name on first use (PEP 562); ``__version__`` is the installed
    version, set from git by setuptools-scm (:mod:`multilayer.provenance`).  A variable of
    numba's environment that its import fails on is named (an ``InputError``)."""
    if name == "__version__":
        from multilayer.provenance import installed_version

        globals()[name] = installed_version()
        return globals()[name]
    if name not in _EXPORTS:
        raise AttributeError(f"module 'multilayer' has no attribute {name!r}")
    from multilayer.app.numba_environment import named

    with named():  # numba's import reads its variables: a value it fails on is named
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
