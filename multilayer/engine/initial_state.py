"""Initial conditions of a scenario (docs/scenarios.md).

Thickness entries stack in the order given: each occupies the height range above the
entries before it, so an erodible bed listed first lies under a column listed second.
Each entry may carry a velocity profile, evaluated at the centres of the layers that
fall inside it, with the height ``zeta`` measured from the bottom of that entry.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from multilayer.reference.exact import bagnold_shape

if TYPE_CHECKING:  # the engine reads a validated scenario; it never loads one
    from multilayer.io.scenario import Bed, InitialShape, Velocity


def bed_profile(bed: Bed, x: np.ndarray) -> np.ndarray:
    """Bed elevation b(x): zero for ``flat``, piecewise linear through ``points``."""
    if not bed.points:
        return np.zeros_like(x)
    px, pb = np.asarray(bed.points, dtype=float).T
    return np.interp(x, px, pb)


def entry_thickness(entry: InitialShape, x: np.ndarray) -> np.ndarray:
    """Thickness of one ``initial`` entry at the cell centres."""
    if entry.shape == "layer":
        assert entry.thickness is not None  # required for a layer (scenario validation)
        return np.full_like(x, float(entry.thickness))
    if entry.shape == "rectangle":
        assert entry.height is not None  # required for a rectangle (scenario validation)
        return np.where((x >= entry.x_min) & (x <= entry.x_max), float(entry.height), 0.0)
    px, ph = np.asarray(entry.points, dtype=float).T
    return np.interp(x, px, ph, left=0.0, right=0.0)


def velocity_profile(velocity: Velocity | None, zeta: np.ndarray, thickness: np.ndarray) -> np.ndarray:
    """Velocity at height ``zeta`` above the bottom of an entry of local ``thickness``.

    ``plug``: uniform ``speed``; ``linear``: ``shear_rate * max(zeta - from_height, 0)``;
    ``bagnold``: ``surface_speed * (1 - (1 - zeta/H)^(3/2))`` (Tsang, Dalziel & Vriend 2019, eq. 4.1).
    """
    if velocity is None:
        return np.zeros_like(zeta)
    if velocity.profile == "plug":
        assert velocity.speed is not None  # required for a plug (scenario validation)
        return np.full_like(zeta, float(velocity.speed))
    if velocity.profile == "linear":
        return velocity.shear_rate * np.maximum(zeta - velocity.from_height, 0.0)
    return velocity.surface_speed * bagnold_shape(zeta / np.where(thickness > 0, thickness, 1.0))


def initial_state(
    entries: Sequence[InitialShape], x: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Thickness h (N,) and layer velocities u (L, N) of the stacked ``initial`` entries."""
    thicknesses = [entry_thickness(e, x) for e in entries]
    h = np.sum(thicknesses, axis=0) if thicknesses else np.zeros_like(x)
    z = sigma[:, None] * h[None, :]  # layer centres above the bed
    u = np.zeros((sigma.size, x.size))
    base = np.zeros_like(x)
    for entry, thick in zip(entries, thicknesses):
        inside = (z >= base) & (z < base + thick) & (thick > 0)
        profile = velocity_profile(entry.velocity, z - base, np.broadcast_to(thick, z.shape))
        u = np.where(inside, profile, u)
        base = base + thick
    return h, u
