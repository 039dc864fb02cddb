"""Whether the compiled form a rheology plugin declares describes the methods it runs.

A plugin may declare the compiled form of its viscous part (``Rheology.viscosity_kernel``)
and of its yield part (``Rheology.yield_stress_kernel``; docs/plugins.md, "Compiled
forms").  A form describes the methods of the class that declares it: where a subclass
(or the instance itself) redefines one of them below that class, the form no longer
describes what the plugin computes, and the engine calls the plugin's own methods.
"""

from __future__ import annotations


def _owner(rheology: object, name: str) -> type | None:
    """The class whose definition of ``name`` an instance uses (None: the instance's own)."""
    if name in vars(rheology):
        return None
    return next((cls for cls in type(rheology).__mro__ if name in vars(cls)), None)


def describes(rheology: object, kernel: str, methods: tuple[str, ...]) -> bool:
    """True when the definition of ``kernel`` that ``rheology`` uses comes from a class at
    or below every class whose definition of ``methods`` it uses."""
    kernel_owner = _owner(rheology, kernel)
    if kernel_owner is None:
        return False
    for method in methods:
        method_owner = _owner(rheology, method)
        if method_owner is None or not issubclass(kernel_owner, method_owner):
            return False
    return True
