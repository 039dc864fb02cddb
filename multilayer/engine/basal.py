"""Basal conditions: what holds the bottom layer at the bed, one registry entry each.

The vertical step couples the bottom layer to the ground through interface 0
(docs/model.md, "The implicit vertical step").  A basal condition sets, column by column,
either the bulk law there (``bulk``: its yield stress ``kappa(p_0)`` and its viscosity over
half the bottom layer, a no-slip bed), or a friction law of the bed,

    kappa_0 = friction p_0 + cohesion,    c_0 = 0,

``p_0`` the pressure at the bed.  The built-in conditions:

- ``no_slip``: the bulk law at the bed (a rough bed);
- ``coulomb`` (with ``mu``): Coulomb friction ``kappa_0 = mu p_0`` (Savage & Hutter 1989);
- ``free_slip``: no stress, ``kappa_0 = c_0 = 0``.

A condition is a :class:`BasalCondition` in :data:`CONDITIONS`: its name, its parameters
(numbers >= 0, with the text the scenario messages accept) and the function giving its
:class:`Basal` coefficients from them.  The scenario schema, the stresses (numpy and
compiled) and the ``bim2016`` pressure read the registry and these coefficients only, so
a new condition of this form is one :func:`register` call here (docs/architecture.md,
"Adding a basal condition").
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from multilayer.engine import registry
from multilayer.engine.config import BasalRegion


@dataclass(frozen=True)
class Basal:
    """The coefficients of interface 0 in one column (module docstring)."""

    bulk: bool
    """The bulk law holds the bed (no slip); otherwise the friction law below, no viscosity."""
    friction: float = 0.0
    cohesion: float = 0.0
    """Pa."""


@dataclass(frozen=True)
class BasalCondition:
    """A basal condition: ``name``, its ``parameters`` (name: accepted text; each a
    number >= 0), how messages list it (``accepted``) and its coefficients."""

    name: str
    accepted: str
    parameters: Mapping[str, str]
    coefficients: Callable[[Mapping[str, float]], Basal]


CONDITIONS: dict[str, BasalCondition] = {}
"""The registered basal conditions by name."""


def register(condition: BasalCondition) -> BasalCondition:
    """Add ``condition`` to :data:`CONDITIONS` (a name registered twice is an error)."""
    return registry.add(CONDITIONS, condition, "basal condition")


def accepted() -> str:
    """``no_slip, coulomb (with mu) or free_slip``: the conditions as messages list them."""
    return registry.listing([c.accepted for c in CONDITIONS.values()])


register(BasalCondition("no_slip", "no_slip", {}, lambda p: Basal(bulk=True)))
register(
    BasalCondition(
        "coulomb",
        "coulomb (with mu)",
        {"mu": "a friction coefficient >= 0 (coulomb only)"},
        lambda p: Basal(bulk=False, friction=p["mu"]),
    )
)
register(BasalCondition("free_slip", "free_slip", {}, lambda p: Basal(bulk=False)))


@dataclass(frozen=True)
class BasalColumns:
    """:class:`Basal` of every column (N,): where the bulk law holds the bed, and the
    friction and cohesion of the others."""

    bulk: np.ndarray
    friction: np.ndarray
    cohesion: np.ndarray


def columns(regions: Sequence[BasalRegion], x: np.ndarray) -> BasalColumns:
    """The basal coefficients of the columns centred at ``x``: a region covers
    ``x_min <= x < x_max``, and later regions win where they overlap (no_slip where none
    does)."""
    bulk = np.ones(x.size, dtype=bool)
    friction = np.zeros(x.size)
    cohesion = np.zeros(x.size)
    for region in regions:
        lo = -np.inf if region.x_min is None else region.x_min
        hi = np.inf if region.x_max is None else region.x_max
        inside = (x >= lo) & (x < hi)
        law = CONDITIONS[region.condition].coefficients(region.parameters)
        bulk[inside] = law.bulk
        friction[inside] = law.friction
        cohesion[inside] = law.cohesion
    return BasalColumns(bulk, friction, cohesion)
