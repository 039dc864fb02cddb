"""A run compared with an exact solution of :mod:`multilayer.reference`, by a norm.

The ``exact:`` entries of a scenario's ``expect:`` list (docs/scenarios.md) and the mesh
studies of :mod:`multilayer.validation` measure the same error, computed here at the last
output time of a result, over the cells whose centre lies in ``[x_min, x_max]``:

    l1:   sum |f - f_exact| w / sum |f_exact| w    (w = dx for h, h_a dx for the layer velocities)
    max:  max |f - f_exact| / max |f_exact|

``f_exact`` is the exact thickness at the cell centres, or the exact velocity averaged
over each layer of the run (the quantity a layer velocity approximates).  Both norms are
relative to the size of the exact field, so the error is a fraction.  For the granular Blasius
layer the compared field is the displacement thickness delta* of each column (weights dx).
The parameters of the exact solution are read from the scenario; a scenario outside the solution's
assumptions is refused with an :class:`~multilayer.errors.InputError` naming what it needs.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from multilayer.app import factory
from multilayer.errors import InputError
from multilayer.reference import exact
from multilayer.scenario import Scenario
from multilayer.scenario.schema import ExactComparison

if TYPE_CHECKING:  # `validate` and `check` read scenarios without xarray's import
    import xarray as xr


class ExactSolution(Protocol):
    """An exact solution of a scenario: the fields it gives, for x > ``start``."""

    fields: tuple[str, ...]
    start: float

    def field(self, name: str, x: np.ndarray, edges: np.ndarray | None, t: float) -> np.ndarray:
        """At time ``t``: ``h`` at the points ``x`` (N,), or ``u``, the mean velocity over
        each layer (L, N) between the heights ``edges`` (L + 1, N) above the bed."""
        ...


class NotApplicable(ValueError):
    """The scenario is outside the solution's assumptions: ``args = (key, what it needs)``."""


def _require(ok: bool, key: str, needs: str) -> None:
    if not ok:
        raise NotApplicable(key, needs)


def _flat_hydrostatic_no_walls(sc: Scenario) -> None:
    _require(sc.bed.profile in (None, "flat"), "bed", "a flat bed")
    _require(sc.walls is None, "walls", "no side walls")
    _require(sc.gate is None, "gate", "no gate")
    _require(sc.model.pressure == "hydrostatic", "model.pressure", "the hydrostatic pressure")


def _one_base(sc: Scenario, *conditions: str) -> str:
    """The condition of a base that is the same everywhere."""
    zone = sc.base[0] if len(sc.base) == 1 else None
    _require(
        zone is not None and zone.x_min is None and zone.x_max is None and zone.condition in conditions,
        "base",
        f"one base condition over the whole domain: {' or '.join(conditions)}",
    )
    assert zone is not None
    return zone.condition


class DamBreak:
    """:func:`multilayer.reference.exact.coulomb_dam_break` (Mangeney, Heinrich & Roche 2000;
    Ritter 1892 on a horizontal frictionless bed): one layer, a reservoir at rest against
    the left end, a Coulomb or frictionless base."""

    fields: tuple[str, ...] = ("h",)
    start = -math.inf

    def __init__(self, sc: Scenario) -> None:
        _require(sc.domain.layers == 1, "domain.layers", "1 (the solution is depth-averaged)")
        _flat_hydrostatic_no_walls(sc)
        reservoir = sc.initial[0] if len(sc.initial) == 1 else None
        _require(
            reservoir is not None
            and reservoir.shape == "rectangle"
            and reservoir.velocity is None
            and reservoir.x_min == sc.domain.x_min,
            "initial",
            "one rectangle at rest starting at domain.x_min (the reservoir)",
        )
        assert reservoir is not None and reservoir.height is not None and reservoir.x_max is not None
        condition = _one_base(sc, "coulomb", "free_slip")
        friction = sc.base[0].parameters.get("mu", 0.0) if condition == "coulomb" else 0.0
        self.delta = math.degrees(math.atan(friction))
        self.theta = sc.slope_deg
        _require(
            self.theta > self.delta or self.theta == self.delta == 0.0,
            "slope_deg",
            "a slope steeper than the basal friction angle, or 0 with no friction",
        )
        self.h0, self.x0, self.gravity = reservoir.height, reservoir.x_max, sc.gravity

    def field(self, name: str, x: np.ndarray, edges: np.ndarray | None, t: float) -> np.ndarray:
        return exact.coulomb_dam_break(x, t, self.h0, self.theta, self.delta, self.x0, self.gravity)


class _UniformLayer:
    """A uniform periodic layer on a flat bed: h stays its initial thickness, the layer
    velocities are the exact profile averaged over each layer (:meth:`layer_means`)."""

    fields: tuple[str, ...] = ("h", "u")
    start = -math.inf

    def __init__(self, sc: Scenario) -> None:
        _flat_hydrostatic_no_walls(sc)
        _require(
            sc.boundaries.left == sc.boundaries.right == "periodic", "boundaries", "periodic on both sides"
        )
        layer = sc.initial[0] if len(sc.initial) == 1 else None
        _require(layer is not None and layer.shape == "layer", "initial", "one uniform layer")
        assert layer is not None and layer.thickness is not None
        self.depth = layer.thickness

    def layer_means(self, edges: np.ndarray, t: float) -> np.ndarray:
        """The exact velocity averaged over the layers between ``edges`` (L + 1, N)."""
        raise NotImplementedError

    def field(self, name: str, x: np.ndarray, edges: np.ndarray | None, t: float) -> np.ndarray:
        if name == "h":
            return np.full(np.shape(x), self.depth)
        assert edges is not None, "the layer velocities need the layer edges"
        return self.layer_means(edges, t)


class SimpleShear(_UniformLayer):
    """:class:`multilayer.reference.exact.InviscidSimpleShear` (Bouchut, Ionescu & Mangeney
    2016, Prop. 2.2): a uniform layer of Drucker-Prager material without viscosity on a
    no-slip base, released with a linear velocity profile."""

    def __init__(self, sc: Scenario) -> None:
        super().__init__(sc)
        _one_base(sc, "no_slip")
        params = sc.rheology.params
        _require(
            sc.rheology.name == "drucker_prager" and params.get("nu") == 0 and params.get("mu_start") is None,
            "rheology",
            "drucker_prager with nu = 0 (no viscosity) and no mu_start",
        )
        velocity = sc.initial[0].velocity
        _require(
            velocity is not None and velocity.profile == "linear",
            "initial",
            "a layer with a linear velocity profile",
        )
        assert velocity is not None and velocity.shear_rate is not None
        _require(
            params["mu_s"] > math.tan(math.radians(sc.slope_deg)),
            "slope_deg",
            "a slope below the friction angle atan(mu_s) (the column decelerates)",
        )
        self.solution = exact.InviscidSimpleShear(
            sc.slope_deg,
            params["mu_s"],
            self.depth,
            velocity.from_height or 0.0,
            velocity.shear_rate,
            sc.gravity,
        )

    def layer_means(self, edges: np.ndarray, t: float) -> np.ndarray:
        return self.solution.layer_means(edges, t)


class Bagnold(_UniformLayer):
    """:class:`multilayer.reference.exact.BagnoldFlow` (Tsang et al. 2019, eq. 4.1): the
    steady uniform flow of a mu(I) law (``jop_mu_i`` or ``power_law_mu_i``) on a no-slip
    base, reached from any initial velocity."""

    def __init__(self, sc: Scenario) -> None:
        super().__init__(sc)
        _one_base(sc, "no_slip")
        p = sc.rheology.params
        _require(sc.rheology.name in ("jop_mu_i", "power_law_mu_i"), "rheology", "jop_mu_i or power_law_mu_i")
        try:
            if sc.rheology.name == "jop_mu_i":
                i_theta = exact.jop_inertial_number(sc.slope_deg, p["mu_s"], p["mu_2"], p["I_0"])
            else:
                i_theta = exact.power_law_inertial_number(sc.slope_deg, p["mu_s"], p["m"], p["alpha"])
        except ValueError as exc:
            raise NotApplicable("slope_deg", f"a slope with a steady flow ({exc})") from None
        material = factory.material(sc)
        self.flow = exact.BagnoldFlow(
            self.depth,
            i_theta,
            material.grain_diameter,
            sc.slope_deg,
            sc.gravity,
            material.density / material.particle_density,
        )

    def layer_means(self, edges: np.ndarray, t: float) -> np.ndarray:
        return np.stack([self.flow.layer_means(column) for column in edges.T], axis=1)


class GranularBlasius:
    """:func:`multilayer.reference.similarity.solve_similarity` (Tsang, Dalziel & Vriend 2019,
    eq. 4.13, 4.15-4.17): the steady boundary layer that grows from the leading edge x0 where
    a plug inflow of a power-law mu(I) material (mu_s = 0) passes from a free-slip to a
    no-slip base, delta* = zeta_disp eps H ((x - x0) / H)^(1/(1+alpha)).  The theory is
    leading order in delta*/H."""

    fields: tuple[str, ...] = ("displacement_thickness",)

    def __init__(self, sc: Scenario) -> None:
        _flat_hydrostatic_no_walls(sc)
        p = sc.rheology.params
        _require(
            sc.rheology.name == "power_law_mu_i" and p.get("mu_s") == 0,
            "rheology",
            "power_law_mu_i with mu_s = 0",
        )
        inflow = sc.boundaries.inflow
        _require(
            sc.boundaries.left == "inflow" and inflow is not None and inflow.velocity.profile == "plug",
            "boundaries",
            "a plug inflow on the left",
        )
        assert inflow is not None and inflow.velocity.speed is not None
        rough, smooth = (sc.base + [sc.base[0]])[:2]
        _require(
            len(sc.base) == 2
            and (rough.condition, rough.x_min, rough.x_max) == ("no_slip", None, None)
            and (smooth.condition, smooth.x_min) == ("free_slip", None)
            and smooth.x_max is not None,
            "base",
            "a no-slip base with a free-slip zone up to x_max, the leading edge",
        )
        assert smooth.x_max is not None
        from multilayer.reference import similarity  # SciPy's integrators: this solution's only

        self.start, self.depth, self.alpha = smooth.x_max, inflow.thickness, p["alpha"]
        eps = similarity.boundary_layer_scale(
            self.alpha,
            p["m"],
            sc.slope_deg,
            inflow.thickness,
            inflow.velocity.speed,
            sc.material.grain_diameter,
            sc.gravity,
        )
        self.scale = similarity.solve_similarity(self.alpha).displacement_thickness * eps * self.depth

    def field(self, name: str, x: np.ndarray, edges: np.ndarray | None, t: float) -> np.ndarray:
        return self.scale * (np.maximum(x - self.start, 0.0) / self.depth) ** (1 / (1 + self.alpha))


SOLUTIONS: dict[str, Callable[[Scenario], ExactSolution]] = {
    "coulomb_dam_break": DamBreak,
    "inviscid_simple_shear": SimpleShear,
    "bagnold": Bagnold,
    "granular_blasius": GranularBlasius,
}
"""Name (``expect: [{exact: {solution: NAME}}]``) -> the solution of a scenario."""


def solution(sc: Scenario, comparison: ExactComparison, where: str = "exact") -> ExactSolution:
    """The exact solution of ``comparison`` with the scenario's parameters; :class:`InputError`
    (naming ``where``, the key of the comparison, and what is accepted) if the scenario is
    outside the solution's assumptions or the solution does not give the compared field."""
    name = comparison.solution
    try:
        found = SOLUTIONS[name](sc)
    except NotApplicable as refused:
        key, needs = refused.args
        raise InputError(
            f"{where}: the exact solution {name} does not apply: {key} differs; accepted: {needs}"
        ) from None
    if comparison.field not in found.fields:
        raise InputError(
            f"{where}.field: {name} gives no {comparison.field}; accepted: {', '.join(found.fields)}"
        )
    dx = (sc.domain.x_max - sc.domain.x_min) / sc.domain.cells
    centres = sc.domain.x_min + dx * (np.arange(sc.domain.cells) + 0.5)
    inside = _window(comparison, centres)
    if not inside.any():
        raise InputError(
            f"{where}: no cell centre between x_min and x_max; accepted: a window inside the domain"
        )
    if comparison.field != "u":  # the norm it is relative to is the solution's alone: known now
        size = np.abs(found.field(comparison.field, centres[inside], None, sc.time.end))
        if not size.max() > 0:  # 0 / 0: a NaN that failed, after the run, with numpy's warning
            raise InputError(
                f"{where}: the exact {comparison.field} is 0 in the window at t = {sc.time.end:g} s: no "
                "error relative to it; accepted: a window where the exact solution is not 0"
            )
    if math.isfinite(found.start) and (comparison.x_min is None or comparison.x_min <= found.start):
        raise InputError(
            f"{where}.x_min: {name} holds for x > {found.start:g}; accepted: a number > {found.start:g}"
        )
    return found


def _window(comparison: ExactComparison, x: np.ndarray) -> np.ndarray:
    """The cells whose centre lies in ``[x_min, x_max]`` of the comparison."""
    lo = -np.inf if comparison.x_min is None else comparison.x_min
    hi = np.inf if comparison.x_max is None else comparison.x_max
    return (x >= lo) & (x <= hi)


def error(ds: xr.Dataset, sc: Scenario, comparison: ExactComparison, where: str = "exact") -> float:
    """The relative error norm of ``comparison.field`` at the last output time of ``ds`` (the
    result of ``sc``) against the exact solution (module docstring)."""
    reference = solution(sc, comparison, where)
    final = ds.isel(time=-1)
    t, x, h = float(final["time"]), ds["x"].values, final["h"].values
    inside = _window(comparison, x)
    fractions = ds["sigma_bnds"].values[:, 1] - ds["sigma_bnds"].values[:, 0]
    edges = np.concatenate([[0.0], np.cumsum(fractions)])[:, None] * h[None, :]
    expected = reference.field(comparison.field, x, edges, t)
    if comparison.field == "h":
        values, weights = h, np.ones_like(h)
    elif comparison.field == "displacement_thickness":
        from multilayer.reference import similarity

        values = similarity.displacement_thickness(final["u"].values, fractions[:, None] * h[None, :])
        weights = np.ones_like(h)
    else:
        values, weights = final["u"].values, fractions[:, None] * h[None, :]
    difference, size = np.abs(values - expected)[..., inside], np.abs(expected)[..., inside]
    with np.errstate(invalid="ignore", divide="ignore"):  # no material in the window: NaN, which fails
        if comparison.norm == "max":
            return float(difference.max() / size.max())
        return float(np.sum(difference * weights[..., inside]) / np.sum(size * weights[..., inside]))
