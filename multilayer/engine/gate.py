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


class Gate:
    """A gate on the face nearest to ``x`` whose lower edge rises at ``lift_speed`` (m/s)."""

    def __init__(self, x: float, lift_speed: float, x_faces: np.ndarray, interfaces: np.ndarray):
        #: index of the gate face among the N + 1 faces (face i lies between cells i-1 and i)
        self.face = int(np.argmin(np.abs(x_faces - x)))
        self.x = float(x_faces[self.face])
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
