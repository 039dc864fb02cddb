"""Lateral boundaries of the transport, one registry entry each: the ghost cells of a side.

The transport extends the state by ``GHOSTS`` columns beyond each end of the domain
(docs/model.md).  A boundary says how they are filled, by one of the ghost rules:

- ``COPY``: the edge column (``outflow``: zero gradient, waves leave);
- ``MIRROR``: the mirror images of the columns at the edge with ``u -> -u`` (``wall``:
  no flux of mass through the end face);
- ``STATE``: a prescribed state, ``boundaries.inflow`` (``inflow``): its end face carries
  waves and mass even before material next to it moves;
- ``WRAP``: the columns at the other end (``periodic``, set on both sides): the faces of
  the non-hydrostatic pressure wrap around too.

A side whose ghosts are not ``COPY`` or ``MIRROR`` is *open*: the occupied window the
transport sweeps always reaches it.  :func:`ghost_sources` gives the columns of the numpy
reference formulation and :func:`ghost_source` the same one column at a time, compiled
by numba into the kernel (:mod:`multilayer.engine.transport.kernel`); so a new boundary
with an existing rule is one :func:`register` call here, and a new rule one more branch
of these two functions, tested against each other (tests/test_boundaries.py).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multilayer.engine import registry

GHOSTS = 2
"""Ghost columns per side: the second-order reconstruction looks two columns away."""

COPY, MIRROR, STATE, WRAP = 0, 1, 2, 3
"""The ghost rules (module docstring)."""


@dataclass(frozen=True)
class Boundary:
    """A lateral boundary: its ``name``, its ghost ``rule`` and how messages list it."""

    name: str
    rule: int
    accepted: str

    @property
    def open(self) -> bool:
        """The occupied window always reaches this side (material may come in through it)."""
        return self.rule in (STATE, WRAP)

    @property
    def needs_state(self) -> bool:
        """The side takes the state of ``boundaries.inflow``."""
        return self.rule == STATE

    @property
    def wraps(self) -> bool:
        """The side continues at the other end: the boundary must be set on both sides."""
        return self.rule == WRAP


BOUNDARIES: dict[str, Boundary] = {}
"""The registered lateral boundaries by name."""


def register(boundary: Boundary) -> Boundary:
    """Add ``boundary`` to :data:`BOUNDARIES` (a name registered twice is an error)."""
    return registry.add(BOUNDARIES, boundary, "boundary")


def accepted() -> str:
    """``wall, outflow, inflow or periodic``: the boundaries as messages list them."""
    return registry.listing([b.accepted for b in BOUNDARIES.values()])


register(Boundary("wall", MIRROR, "wall"))
register(Boundary("outflow", COPY, "outflow"))
register(Boundary("inflow", STATE, "inflow"))
register(Boundary("periodic", WRAP, "periodic"))


@dataclass(frozen=True)
class InflowState:
    """The state of the ghosts of a ``STATE`` side: thickness (m) and layer velocities (L,) (m/s)."""

    thickness: float
    velocity: np.ndarray


def rule(name: str) -> int:
    """The ghost rule of the boundary ``name``."""
    return BOUNDARIES[name].rule


def ghost_sources(side_rule: int, side: str, N: int) -> np.ndarray:
    """Columns (of ``N``) whose state the two ghosts of ``side`` take, the ghost nearest
    the boundary first: the edge column (``COPY``, ``STATE``: replaced by the prescribed
    state), its mirror images (``MIRROR``) or the columns at the other end (``WRAP``)."""
    left = side == "left"
    if side_rule == WRAP:
        return np.array([-1, -2] if left else [0, 1]) % N
    if side_rule == MIRROR:
        return np.clip([0, 1] if left else [N - 1, N - 2], 0, N - 1)
    return np.full(GHOSTS, 0 if left else N - 1)


def ghost_source(j: int, n: int, left: int, right: int) -> tuple[int, int]:
    """:func:`ghost_sources` for one column: the column of the window whose state column
    ``j`` (-2 .. n+1, ghosts outside 0 .. n-1) takes, and how: 0 copied, 1 mirrored
    (u -> -u), 2 the prescribed state instead.  ``left`` and ``right`` are the ghost rules
    of the sides.  Compiled by numba in the transport kernel (called per column there)."""
    if j < 0:
        g = -1 - j  # 0 for the ghost next to the boundary
        if left == WRAP:
            return (n - 1 - g) % n, 0
        if left == MIRROR:
            return min(g, n - 1), 1
        return 0, 2 if left == STATE else 0
    if j >= n:
        g = j - n
        if right == WRAP:
            return g % n, 0
        if right == MIRROR:
            return max(n - 1 - g, 0), 1
        return n - 1, 2 if right == STATE else 0
    return j, 0
