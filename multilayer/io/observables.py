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

The measures of a collapse deposit and its duration, as the experiments define them
(a deposit ends where a few grains remain, Pouliquen 1999; the flow stops when its front
does, Lajeunesse, Monnier & Homsy 2005; Mangeney et al. 2010):

- :func:`tip`: the front where h falls through ``base + n d`` (n grain diameters above the
  bed ``base``, default :data:`TIP_DIAMETERS`);
- :func:`mass_front`: the point upslope of which :data:`MASS_FRACTION` of the material
  above ``base`` lies (cell averages: the cumulative mass is linear across each cell);
- :func:`front_stop_time`: when the front speed falls for the last time below a speed
  (default :data:`STOP_SPEED`);
- :func:`time_to_fraction`: when the front has covered a fraction (default
  :data:`MASS_FRACTION`) of its run-out.
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

TIP_DIAMETERS = 3.0
"""The deposit tip is where h falls through 3 grain diameters above the bed."""

MASS_FRACTION = 0.95
"""The mass front holds 95 % of the material upslope of it; the duration by the run-out is
the time to 95 % of it."""

STOP_SPEED = 0.01
"""m/s: the front is taken as stopped once its speed falls below 1 cm/s for good."""


def interpolated_front(x: np.ndarray, h: np.ndarray, threshold: float) -> float:
    """Downslope-most crossing of ``threshold`` by the linear interpolant of ``h`` (nan if dry)."""
    wet = np.flatnonzero(h > threshold)
    if not wet.size:
        return float("nan")
    i = wet[-1]
    if i == h.size - 1:
        return float(x[i])
    return float(x[i] + (x[i + 1] - x[i]) * (h[i] - threshold) / (h[i] - h[i + 1]))


def tip(
    x: np.ndarray, h: np.ndarray, grain_diameter: float, diameters: float = TIP_DIAMETERS, base: float = 0.0
) -> float:
    """Deposit tip (m): where h falls through ``base + diameters * grain_diameter``, linear
    between cell centres (``base``: the thickness of an erodible bed; nan if nothing is
    thicker)."""
    return interpolated_front(x, h, base + diameters * grain_diameter)


def mass_front(x: np.ndarray, h: np.ndarray, fraction: float = MASS_FRACTION, base: float = 0.0) -> float:
    """The point (m) upslope of which ``fraction`` of the material above ``base`` lies.

    The material is ``max(h - base, 0)`` held as cell averages over cells of width
    ``x[1] - x[0]`` centred on ``x``: its cumulative mass is exact at the cell edges and
    linear across each cell.  nan if there is no material above ``base``.
    """
    dx = float(x[1] - x[0])
    cumulative = np.concatenate([[0.0], np.cumsum(np.maximum(h - base, 0.0)) * dx])
    if cumulative[-1] <= 0.0:
        return float("nan")
    target = fraction * cumulative[-1]
    k = int(np.searchsorted(cumulative, target, side="left"))  # cumulative[k-1] < target <= cumulative[k]
    if k == 0:
        return float(x[0] - dx / 2)
    left_edge = x[k - 1] - dx / 2
    return float(left_edge + dx * (target - cumulative[k - 1]) / (cumulative[k] - cumulative[k - 1]))


def front_stop_time(t: np.ndarray, front: np.ndarray, speed: float = STOP_SPEED) -> float:
    """The time (s) at which the front speed falls below ``speed`` for the last time.

    The front's speed over each output interval (its finite difference, the exact speed
    at the interval's midpoint for a uniformly decelerating front) is taken at the
    midpoint, linear between midpoints.  ``t[0]`` if the front never reaches ``speed``;
    nan if it is still that fast over the last interval (not stopped).
    """
    mid = 0.5 * (t[1:] + t[:-1])
    rate = np.diff(front) / np.diff(t)
    fast = np.flatnonzero(rate >= speed)
    if not fast.size:
        return float(t[0])
    k = int(fast[-1])
    if k == rate.size - 1:
        return float("nan")
    return float(mid[k] + (mid[k + 1] - mid[k]) * (rate[k] - speed) / (rate[k] - rate[k + 1]))


def time_to_fraction(t: np.ndarray, front: np.ndarray, fraction: float = MASS_FRACTION) -> float:
    """The first time (s) at which the front has covered ``fraction`` of its run-out
    ``front[-1] - front[0]``, linear between output times."""
    travel = front - front[0]
    target = fraction * travel[-1]
    k = int(np.argmax(travel >= target))
    if k == 0:
        return float(t[0])
    return float(t[k - 1] + (t[k] - t[k - 1]) * (target - travel[k - 1]) / (travel[k] - travel[k - 1]))


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
