"""Quantities measured on a result file, to compare with observations (docs/calibration.md).

Calibration differentiates these quantities with respect to the parameters, so each is a
continuous function of the computed thickness h: the front is located to sub-cell
precision by linear interpolation of h between cell centres (the ``front`` variable of
``result.nc`` is the downslope-most wet cell centre, a staircase in the parameters).

- ``front`` (m): the downslope-most x where the piecewise-linear interpolant of h through
  the cell centres crosses the front threshold (``numerics.front_threshold``);
- ``runout`` (m): front at the last output time minus front at t = 0;
- ``front_final`` (m): front at the last output time;
- ``duration`` (s): the first time at which the front, interpolated linearly between
  output times, comes within :data:`DURATION_TOLERANCE` of its final position;
- ``mass_final`` (m^2): the mass at the last output time;
- ``h`` (m): the thickness at given x (linear between cell centres) at a given time
  (linear between output times; default the last output time).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import xarray as xr

from multilayer.io.results import open_result

DURATION_TOLERANCE = 0.005
"""m: the front is taken as stopped once within 5 mm of its final position."""


def interpolated_front(x: np.ndarray, h: np.ndarray, threshold: float) -> float:
    """Downslope-most crossing of ``threshold`` by the linear interpolant of ``h`` (nan if dry)."""
    wet = np.flatnonzero(h > threshold)
    if not wet.size:
        return float("nan")
    i = wet[-1]
    if i == h.size - 1:
        return float(x[i])
    return float(x[i] + (x[i + 1] - x[i]) * (h[i] - threshold) / (h[i] - h[i + 1]))


def front_history(ds: xr.Dataset) -> tuple[np.ndarray, np.ndarray]:
    """(output times, interpolated front at each)."""
    x, threshold = ds["x"].values, float(ds["front"].attrs["threshold"])
    fronts = np.array([interpolated_front(x, h, threshold) for h in ds["h"].values])
    return ds["time"].values, fronts


def scalar(ds: xr.Dataset, quantity: str) -> float:
    """One of ``runout``, ``front_final``, ``duration``, ``mass_final`` (see the module)."""
    if quantity == "mass_final":
        return float(ds["mass"].values[-1])
    t, front = front_history(ds)
    if quantity == "front_final":
        return float(front[-1])
    if quantity == "runout":
        return float(front[-1] - front[0])
    if quantity == "duration":
        close = np.abs(front - front[-1]) <= DURATION_TOLERANCE
        k = int(np.flatnonzero(~close)[-1]) + 1 if not close.all() else 0
        if k == 0:
            return float(t[0])
        # linear between t[k-1] (not yet close) and t[k] (close from then on)
        d0, d1 = abs(front[k - 1] - front[-1]), abs(front[k] - front[-1])
        return float(t[k - 1] + (t[k] - t[k - 1]) * (d0 - DURATION_TOLERANCE) / (d0 - d1))
    raise ValueError(f"unknown quantity {quantity!r}")


def thickness(ds: xr.Dataset, at_x: Sequence[float], at_time: float | None = None) -> np.ndarray:
    """h at ``at_x`` (linear between cell centres, 0 beyond) at ``at_time`` (default: last)."""
    t = ds["time"].values
    h = ds["h"].values
    if at_time is None or at_time >= t[-1]:
        profile = h[-1]
    else:
        k = int(np.clip(np.searchsorted(t, at_time), 1, t.size - 1))
        w = (at_time - t[k - 1]) / (t[k] - t[k - 1])
        profile = (1 - w) * h[k - 1] + w * h[k]
    return np.interp(at_x, ds["x"].values, profile, left=0.0, right=0.0)


@dataclass(frozen=True)
class Measure:
    """What to measure on one run: ``(quantity, coordinates, time)`` items.

    Called on a result path (on a Dask worker or locally), it returns every measured
    value concatenated in item order, in SI units.
    """

    items: tuple[tuple[str, tuple[float, ...], float | None], ...]

    def __call__(self, path: str | os.PathLike) -> np.ndarray:
        ds = open_result(path, use="answer")
        values: list[np.ndarray] = []
        for quantity, coordinate, time in self.items:
            if quantity == "front":
                t, front = front_history(ds)
                values.append(np.interp(coordinate, t, front))
            elif quantity == "h":
                values.append(thickness(ds, coordinate, time))
            else:
                values.append(np.array([scalar(ds, quantity)]))
        return np.concatenate(values) if values else np.empty(0)
