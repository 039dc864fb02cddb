"""Whether the compiled form a rheology plugin declares describes the methods it runs.

A plugin may declare the compiled form of its viscous part (``Rheology.viscosity_kernel``)
and of its yield part (``Rheology.yield_stress_kernel``; docs/plugins.md, "Compiled
forms").  A form describes the methods of the class that declares it: where a subclass
(or the instance itself) redefines one of them below that class, the form no longer
describes what the plugin computes, and the engine calls the plugin's own methods.
"""

from __future__ import annotations

import functools
from typing import Any


def describes(rheology: object, kernel: str, methods: tuple[str, ...]) -> bool:
    """True when the definition of ``kernel`` that ``rheology`` uses comes from a class at
    or below every class whose definition of ``methods`` it uses (never when the instance
    itself defines one of them)."""
    instance = getattr(rheology, "__dict__", {})  # none with __slots__
    if kernel in instance or any(method in instance for method in methods):
        return False
    cls: Any = type(rheology)
    # the definitions the class resolves now: a method patched on a class is a new key
    return _class_describes(
        cls, kernel, methods, tuple(getattr(cls, name, None) for name in (kernel, *methods))
    )


@functools.lru_cache(maxsize=256)
def _class_describes(cls: Any, kernel: str, methods: tuple[str, ...], definitions: tuple) -> bool:
    """``describes`` for the class ``cls`` whose attributes ``kernel, *methods`` resolve to
    ``definitions`` (part of the key of the cache)."""
    kernel_owner = _owner(cls, kernel)
    if kernel_owner is None:
        return False
    for method in methods:
        method_owner = _owner(cls, method)
        if method_owner is None or not issubclass(kernel_owner, method_owner):
            return False
    return True


def _owner(cls: Any, name: str) -> type | None:
    """The class of ``cls.__mro__`` whose definition of ``name`` ``cls`` uses (None: none)."""
    return next((base for base in cls.__mro__ if name in vars(base)), None)
