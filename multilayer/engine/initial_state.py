"""Initial conditions of a scenario (docs/scenarios.md).

Thickness entries stack in the order given: each occupies the height range above the
entries before it, so an erodible bed listed first lies under a column listed second.
Each entry may carry a velocity profile, evaluated at the centres of the layers that
fall inside it, with the height ``zeta`` measured from the bottom of that entry.

Thicknesses are cell averages: every shape is a piecewise-linear function of x (a
rectangle has vertical sides) integrated exactly over each cell, so the initial mass
equals the shape's mass to round-off at any resolution.  An entry with material outside
the domain, or narrower than one cell (not represented by the mesh), is an
:class:`InputError` naming the entry.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from multilayer.engine.config import InitialEntry, Points, Velocity
from multilayer.engine.transport.reference import fluxes_overflow
from multilayer.errors import InputError


def bed_profile(points: Points | None, x: np.ndarray) -> np.ndarray:
    """Bed elevation b(x): zero without ``points``, piecewise linear through them."""
    if points is None or len(points) == 0:
        return np.zeros_like(x)
    px, pb = np.asarray(points, dtype=float).T
    return np.interp(x, px, pb)


def bagnold_shape(height_fraction: np.ndarray) -> np.ndarray:
    """Bagnold's profile scaled by its surface speed: ``1 - (1 - z/h)^(3/2)``, ``z/h`` in
    [0, 1] (GDR MiDi 2004; Tsang, Dalziel & Vriend 2019, eq. 4.1)."""
    depth = np.clip(1.0 - np.asarray(height_fraction, dtype=float), 0.0, 1.0)
    return 1.0 - depth**1.5


def cell_edges(x_min: float, x_max: float, cells: int) -> np.ndarray:
    """The ``cells + 1`` edges of equal cells on ``[x_min, x_max]`` (both ends exact)."""
    edges = x_min + (x_max - x_min) / cells * np.arange(cells + 1)
    edges[-1] = x_max
    return edges


def piecewise_linear_integral(px: np.ndarray, py: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Integral from ``-inf`` to each of ``at`` of the piecewise-linear function through
    ``(px, py)`` (non-decreasing ``px``; a repeated abscissa is a jump), zero outside."""
    cumulative = np.concatenate([[0.0], np.cumsum(0.5 * np.diff(px) * (py[1:] + py[:-1]))])
    k = np.clip(np.searchsorted(px, at, side="right") - 1, 0, px.size - 2)
    inside = (at >= px[0]) & (at < px[-1])
    span = px[k + 1] - px[k]
    frac = np.divide(at - px[k], span, out=np.zeros_like(at), where=span > 0)
    y = py[k] + frac * (py[k + 1] - py[k])
    partial = cumulative[k] + 0.5 * (at - px[k]) * (py[k] + y)
    return np.where(inside, partial, np.where(at >= px[-1], cumulative[-1], 0.0))


def cell_average(px: np.ndarray, py: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Mean over each cell ``[edges[i], edges[i+1]]`` of the piecewise-linear function
    through ``(px, py)``, zero outside ``[px[0], px[-1]]`` (exact, to round-off)."""
    return np.diff(piecewise_linear_integral(px, py, edges)) / np.diff(edges)


def entry_points(entry: InitialEntry) -> tuple[np.ndarray, np.ndarray] | None:
    """The thickness of a bounded entry as a piecewise-linear function (vertices), or None
    for a ``layer`` (uniform over the whole domain)."""
    if entry.shape == "layer":
        return None
    if entry.shape == "rectangle":
        # x_min, x_max and height are required for a rectangle (scenario validation)
        assert entry.x_min is not None and entry.x_max is not None and entry.height is not None
        a, b, height = float(entry.x_min), float(entry.x_max), float(entry.height)
        return np.array([a, a, b, b]), np.array([0.0, height, height, 0.0])
    px, ph = np.asarray(entry.points, dtype=float).T
    return px, ph


def entry_thickness(entry: InitialEntry, edges: np.ndarray) -> np.ndarray:
    """Cell-averaged thickness of one ``initial`` entry on the cells between ``edges`` (N+1,)."""
    points = entry_points(entry)
    if points is None:
        assert entry.thickness is not None  # required for a layer (scenario validation)
        return np.full(edges.size - 1, float(entry.thickness))
    return cell_average(*points, edges)


def check_entries(entries: Sequence[InitialEntry], x_min: float, x_max: float, dx: float, where: str) -> None:
    """:class:`InputError` naming the first entry with material outside the domain
    ``[x_min, x_max]`` or narrower than one cell of width ``dx``; ``where`` names the scenario."""
    bounds = np.array([x_min, x_max], dtype=float)
    for index, entry in enumerate(entries):
        points = entry_points(entry)
        if points is None:
            assert entry.thickness is not None  # required for a layer (scenario validation)
            _finite_mass(float(entry.thickness) * float(x_max - x_min), f"{where}: initial.{index} (layer)")
            continue
        px, ph = points
        wet = np.flatnonzero(ph > 0)
        if wet.size == 0:
            raise InputError(
                f"{where}: initial.{index} ({entry.shape}): holds no material (h = 0 everywhere); "
                "accepted: a shape with some thickness > 0"
            )
        lo, hi = px[max(wet[0] - 1, 0)], px[min(wet[-1] + 1, px.size - 1)]  # support of the thickness
        name = f"{where}: initial.{index} ({entry.shape} on x in [{lo:g}, {hi:g}] m)"
        with np.errstate(over="ignore", invalid="ignore"):  # named below
            total = float(piecewise_linear_integral(px, ph, np.array([px[-1]]))[0])
            inside = float(np.diff(piecewise_linear_integral(px, ph, bounds))[0])
        _finite_mass(total, name)
        domain = f"[{x_min:g}, {x_max:g}] m"
        if inside < total * (1 - 1e-12):
            raise InputError(
                f"{name}: {total - inside:.6g} of its {total:.6g} m2 lie outside the domain "
                f"x in {domain}; accepted: shapes inside domain.x_min .. domain.x_max"
            )
        if hi - lo < dx * (1 - 1e-9):  # one cell wide, to round-off
            cells = float(x_max - x_min) / float(hi - lo)  # Python's floats: no overflow warning
            raise InputError(
                f"{name}: {hi - lo:.6g} m wide, narrower than one cell (dx = {dx:.6g} m): "
                f"the mesh cannot represent it; accepted: a shape at least one cell wide "
                + (
                    f"(raise domain.cells to at least {math.ceil(cells):.6g})"
                    if math.isfinite(cells)
                    else "(a wider shape or a shorter domain: no number of cells is enough)"
                )
            )


def check_pressure(entries: Sequence[InitialEntry], weight: float, where: str) -> None:
    """:class:`InputError` when the hydrostatic pressure under the deepest column the
    entries can stack, ``weight`` (density g cos(theta), Pa/m) times the sum of their
    largest thicknesses, is no finite number: every stress of the run is then infinite,
    which the rheology was blamed for at the first step."""
    depth = stacked_depth(entries)
    if not math.isfinite(weight * depth):  # Python's floats: inf without a warning
        raise InputError(
            f"{where}: material.density, gravity, initial: the pressure under the initial material, "
            f"density g cos(slope_deg) h = {weight:.6g} Pa/m x {depth:.6g} m, is no finite number (more "
            "than 1e308 Pa); accepted: a density, gravity and thickness whose product is a finite number"
        )


def stacked_depth(entries: Sequence[InitialEntry]) -> float:
    """The deepest column the entries can stack: the sum of their largest thicknesses (m)."""
    depth = 0.0
    for entry in entries:
        points = entry_points(entry)
        depth += float(entry.thickness) if points is None else float(points[1].max())  # type: ignore[arg-type]
    return depth


def check_transport(depth: float, speed: float, dx: float, where: str) -> None:
    """:class:`InputError` when the transport of the initial state, ``depth`` (m) deep with
    waves up to ``speed`` (m/s) on cells ``dx`` (m) wide, computes numbers beyond the floats
    (:func:`~multilayer.engine.transport.reference.fluxes_overflow`): its first step's
    fluxes are NaN, which the step's state check named ("thickness h = nan after
    transport") without the keys that made it."""
    if fluxes_overflow(depth, speed, dx):
        raise InputError(
            f"{where}: initial, gravity, domain.cells: the transport of the initial state overflows: it "
            "computes thickness x wave speed^2 / cell width and thickness^2 for thicknesses up to "
            f"{depth:.3g} m and waves up to {speed:.3g} m/s (its speeds and a dam break's front, 2 sqrt(g "
            f"cos(slope_deg) h)) on cells of {dx:.3g} m, beyond 1e308; accepted: initial thicknesses and "
            "speeds, gravity and cells whose products are finite numbers"
        )


def _finite_mass(mass: float, name: str) -> None:
    """:class:`InputError` naming the entry ``name`` when its mass (m2) is no finite number
    (a thickness near 1e308 m: every sum of the state overflows)."""
    if not math.isfinite(mass):
        raise InputError(
            f"{name}: its mass, the integral of its thickness, is no finite number (more than 1e308 m2); "
            "accepted: thicknesses whose integral over the domain is a finite number"
        )


def velocity_profile(velocity: Velocity | None, zeta: np.ndarray, thickness: np.ndarray) -> np.ndarray:
    """Velocity at height ``zeta`` above the bottom of an entry of local ``thickness``.

    ``plug``: uniform ``speed``; ``linear``: ``shear_rate * max(zeta - from_height, 0)``;
    ``bagnold``: ``surface_speed * (1 - (1 - zeta/H)^(3/2))`` (Tsang, Dalziel & Vriend 2019, eq. 4.1).
    """
    if velocity is None:
        return np.zeros_like(zeta)
    if velocity.profile == "plug":
        return np.full_like(zeta, float(velocity.speed))
    if velocity.profile == "linear":
        return velocity.shear_rate * np.maximum(zeta - velocity.from_height, 0.0)
    return velocity.surface_speed * bagnold_shape(zeta / np.where(thickness > 0, thickness, 1.0))


def initial_thickness(entries: Sequence[InitialEntry], edges: np.ndarray) -> np.ndarray:
    """Cell-averaged thickness (N,) of the stacked ``initial`` entries on the cells between
    ``edges`` (N+1,), one entry at a time: the memory of the mesh, whatever the entries."""
    h = np.zeros(edges.size - 1)
    for entry in entries:
        h += entry_thickness(entry, edges)
    return h


def check_not_dry(h: np.ndarray, dry: float, fed: bool, where: str) -> None:
    """:class:`InputError` if the initial thickness ``h`` on the mesh holds material but
    nowhere more than the dry threshold ``dry``, and no inflow (``fed``) comes to it: the
    engine holds a dry column at rest (a film of 1e-7 m on a slope steeper than its
    friction stayed put, and the run completed); ``where`` names the scenario."""
    if not fed and 0.0 < h.max(initial=0.0) <= dry:
        raise InputError(
            f"{where}: initial: at most {h.max(initial=0.0):.3g} m thick on the mesh, not above "
            f"numerics.dry_threshold = {dry:g} m, below which a column is dry (held at rest); accepted: "
            "material thicker than numerics.dry_threshold in some cell, or a smaller numerics.dry_threshold"
        )


def initial_state(
    entries: Sequence[InitialEntry], x: np.ndarray, sigma: np.ndarray, edges: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Cell-averaged thickness h (N,) and layer velocities u (L, N) at the cell centres
    ``x`` of the stacked ``initial`` entries (cells between ``edges``, (N+1,))."""
    h = initial_thickness(entries, edges)
    z = sigma[:, None] * h[None, :]  # layer centres above the bed
    u = np.zeros((sigma.size, x.size))
    base = np.zeros_like(x)
    for entry in entries:
        thick = entry_thickness(entry, edges)
        inside = (z >= base) & (z < base + thick) & (thick > 0)
        profile = velocity_profile(entry.velocity, z - base, np.broadcast_to(thick, z.shape))
        u = np.where(inside, profile, u)
        base = base + thick
    return h, u
