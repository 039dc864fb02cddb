"""multilayer: a multilayer shallow-flow simulator of dense granular flows.

The public plugin API (DESIGN.md section 5) is re-exported here: subclass
:class:`Rheology`, decorate ``multilayer_register_rheologies`` with :data:`hookimpl`.
"""
from multilayer.plugins import hookimpl
from multilayer.rheology import Material, Rheology

__version__ = "0.1.0"

__all__ = ["Material", "Rheology", "hookimpl", "__version__"]
