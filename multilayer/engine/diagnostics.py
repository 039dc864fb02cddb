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
