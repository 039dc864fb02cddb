"""Diagnostics written at output times (docs/results.md)."""

from __future__ import annotations

import numpy as np


def static_interface(h: np.ndarray, u: np.ndarray, interfaces: np.ndarray) -> np.ndarray:
    """Height above the bed of the top of the static region of each column (N,).

    The static region is the run of layers at rest (``u == 0.0`` exactly, as the
    implicit step leaves them) starting at the bed: 0 where the bed layer moves, ``h``
    where the whole column is at rest.
    """
    at_rest = np.cumprod(u == 0.0, axis=0)
    return interfaces[at_rest.sum(axis=0)] * h


def front(x: np.ndarray, h: np.ndarray, threshold: float) -> float:
    """Downslope-most cell centre where ``h > threshold`` (nan if there is none)."""
    wet = np.flatnonzero(h > threshold)
    return float(x[wet[-1]]) if wet.size else float("nan")


def mass(h: np.ndarray, dx: float) -> float:
    """Integral of h over x, m^2 per unit width (the volume per unit width)."""
    return float(np.sum(h) * dx)


# ---------------------------------------------------------------- measures of a run
# The measures of the collapse experiments (Mangeney et al. 2010; Farin et al. 2014),
# evaluated on the thickness h(t, x) written at output times.


def front_position(x: np.ndarray, h: np.ndarray, level: float) -> float:
    """Downslope-most point where ``h`` falls through ``level``, linear between the cell
    centres (m); nan if ``h`` never exceeds ``level``.  Over an erodible bed of thickness
    ``b`` take ``level = b + threshold``: the front of the material thicker than the bed."""
    above = np.flatnonzero(h > level)
    if not above.size:
        return float("nan")
    i = above[-1]
    if i + 1 == h.size:
        return float(x[i])
    return float(x[i] + (h[i] - level) / (h[i] - h[i + 1]) * (x[i + 1] - x[i]))


def front_history(x: np.ndarray, h: np.ndarray, level: float) -> np.ndarray:
    """The front x_f(t) (T,) of thicknesses ``h`` (T, N) at successive output times."""
    return np.array([front_position(x, row, level) for row in h])


def stop_time(t: np.ndarray, front: np.ndarray, speed: float) -> float:
    """First output time after which the front advances slower than ``speed`` (m/s) over
    every later output interval; nan if it is still that fast over the last one."""
    fast = np.flatnonzero(np.diff(front) >= speed * np.diff(t))
    if not fast.size:
        return float(t[0])
    if fast[-1] + 1 == t.size - 1:
        return float("nan")
    return float(t[fast[-1] + 1])


def time_to_fraction(t: np.ndarray, front: np.ndarray, fraction: float = 0.95) -> float:
    """First time at which the front has covered ``fraction`` of its final run-out
    ``front[-1] - front[0]``, linear between output times (s)."""
    travel = front - front[0]
    target = fraction * travel[-1]
    k = int(np.argmax(travel >= target))
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (target - travel[k - 1]) / (travel[k] - travel[k - 1]) * (t[k] - t[k - 1]))
