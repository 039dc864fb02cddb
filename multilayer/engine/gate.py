"""A lifting gate: the release of a granular column as in the laboratory.

In the experiments of Mangeney et al. (2010) and Farin, Mangeney & Roche (2014) the column
is held by a vertical gate that is lifted at the start of the run.  The gate stands on the
face between two columns at ``x``; its lower edge rises from the bed, normal to the
slope, at ``lift_speed``::

    e(t) = lift_speed * t          (infinite speed: e = inf, the instantaneous release)

In the multilayer model a layer occupies the heights ``[h z_{a-1}, h z_a]`` above the bed
(``z`` the interface fractions).  Through the gate face only the part of each layer below
the edge passes: its flux is multiplied by the **opening fraction**

    o_a = clip((e - h z_{a-1}) / (h l_a), 0, 1),

``h`` the thicker of the two columns on either side of the face (so nothing passes above
the edge on either side), and the rest of the face is a wall (transport/reference.py).  The opening
is evaluated once per step, at the middle of the step.
"""

from __future__ import annotations

import math

import numpy as np


def gate_face(x: float, x_min: float, dx: float, cells: int) -> int:
    """The index of the face nearest to ``x`` among the ``cells + 1`` faces ``x_min + i dx``
    (face i between cells i-1 and i), the lower one on a tie."""
    guess = min(max(math.floor((x - x_min) / dx), 0), cells)
    near = range(max(guess - 1, 0), min(guess + 2, cells) + 1)  # the floor may be one off
    return min(near, key=lambda i: (abs(x_min + dx * i - x), i))


class Gate:
    """A gate on the face nearest to ``x`` whose lower edge rises at ``lift_speed`` (m/s),
    on a mesh of ``cells`` cells of ``dx`` from ``x_min``."""

    def __init__(
        self, x: float, lift_speed: float, x_min: float, dx: float, cells: int, interfaces: np.ndarray
    ):
        #: index of the gate face among the N + 1 faces (face i lies between cells i-1 and i)
        self.face = gate_face(x, x_min, dx, cells)
        self.x = x_min + dx * self.face
        self.lift_speed = float(lift_speed)
        self._bottoms = interfaces[:-1]  # z_{a-1}: bottom of each layer as a fraction of h
        self._fractions = np.diff(interfaces)

    def edge(self, t: float) -> float:
        """Height of the lower edge above the bed at time ``t`` (m); inf once released."""
        if math.isinf(self.lift_speed):
            return math.inf
        return self.lift_speed * t

    def opening(self, h: np.ndarray, t: float) -> np.ndarray | None:
        """Opening fractions o_a (L,) of the layers at the gate face at time ``t``, or None
        once the edge is above the material on both sides (the gate no longer acts)."""
        cells = [i for i in (self.face - 1, self.face) if 0 <= i < h.size]
        depth = max(float(h[i]) for i in cells)
        edge = self.edge(t)
        if edge >= depth:
            return None
        return np.clip((edge - depth * self._bottoms) / (depth * self._fractions), 0.0, 1.0)
