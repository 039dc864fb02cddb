"""The engine of a scenario: its typed configuration and its plugin instances.

The engine is built from plain configuration (:mod:`multilayer.engine.config`) and the
rheology plugin instances handed to it; it never sees a scenario file, the schema or the
plugin host.  This module is the one place that turns a validated
:class:`~multilayer.scenario.Scenario` into them: :func:`engine_config` copies the keys
(and computes what the scenario notation implies: the layer fractions, the material, the
pressure model's options), :func:`laws` instantiates the plugins through the plugin host,
:func:`column_solver` picks the exact solver of the column problem (the FiPy reference
for ``numerics.vertical_solver: fipy``); :class:`multilayer.app.simulation.Simulation`
builds the engine's simulation of a scenario with them.  Importing this module imports
no kernel (``multilayer validate`` uses it).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import partial
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from multilayer.app import resources
from multilayer.engine import config as cfg
from multilayer.engine import initial_state
from multilayer.engine.mesh import layer_fractions
from multilayer.engine.pressure.model import models, options
from multilayer.errors import InputError
from multilayer.plugins import host
from multilayer.plugins.contract import Material, Rheology
from multilayer.scenario import Scenario

if TYPE_CHECKING:
    from multilayer.engine.vertical.problem import ColumnProblem, VerticalSolver
    from multilayer.scenario import schema


def _velocity(spec: schema.Velocity) -> cfg.Velocity:
    return cfg.Velocity(
        spec.profile,
        speed=spec.speed or 0.0,
        shear_rate=spec.shear_rate or 0.0,
        from_height=spec.from_height or 0.0,
        surface_speed=spec.surface_speed or 0.0,
    )


def _points(points: list[list[float]] | np.ndarray | None) -> cfg.Points | None:
    """The points of a profile; a file's rows (an array) as they are."""
    if isinstance(points, np.ndarray):
        return points
    return None if points is None else tuple((float(x), float(v)) for x, v in points)


def _initial(entry: schema.InitialShape) -> cfg.InitialEntry:
    return cfg.InitialEntry(
        entry.shape,
        thickness=entry.thickness,
        x_min=entry.x_min,
        x_max=entry.x_max,
        height=entry.height,
        points=_points(entry.points),
        velocity=None if entry.velocity is None else _velocity(entry.velocity),
        phi=entry.phi,
    )


def basal_regions(zones: Sequence[schema.BaseZone]) -> tuple[cfg.BasalRegion, ...]:
    """The engine's basal regions of the ``base`` entries of a scenario."""
    return tuple(
        cfg.BasalRegion(z.condition, MappingProxyType(z.parameters), z.x_min, z.x_max) for z in zones
    )


def initial_entries(scenario: Scenario) -> tuple[cfg.InitialEntry, ...]:
    """The engine's entries of the initial state of a scenario."""
    return tuple(_initial(entry) for entry in scenario.initial)


def check_initial(scenario: Scenario, where: str, *, on_mesh: bool = True) -> None:
    """The initial entries of ``scenario`` within its domain, none narrower than a cell,
    and (``on_mesh``) their thickness on the mesh above ``numerics.dry_threshold``
    somewhere unless an inflow feeds the run (:class:`InputError` naming ``where``
    otherwise): as the engine checks them, before a run says anything of its state (a
    film too thin to flow was refused after a warning that it had no front)."""
    dom = scenario.domain
    entries = initial_entries(scenario)
    initial_state.check_entries(entries, dom.x_min, dom.x_max, (dom.x_max - dom.x_min) / dom.cells, where)
    if on_mesh:
        h0 = initial_state.initial_thickness(
            entries, initial_state.cell_edges(dom.x_min, dom.x_max, dom.cells)
        )
        fed = scenario.boundaries.inflow is not None
        initial_state.check_not_dry(h0, scenario.numerics.dry_threshold, fed, where)
        check_closure(scenario, float(h0.max(initial=0.0)), where)


def check_closure(scenario: Scenario, h: float, where: str) -> None:
    """A mixture's closure bounded on its initial column of thickness ``h`` (the thickest on
    the mesh), at each packing given (:func:`closure.discriminant_bound`): the effective
    pressure's quadratic at a shear rate of :data:`closure.SHEAR_RATE_SCALE` must stay below
    :data:`closure.DISCRIMINANT_LIMIT`, or :class:`InputError` naming the keys, first the
    one to blame (:func:`_closure_culprit`): beyond it the run's first steps overflow the
    closure."""
    from multilayer.engine.mixture import closure

    fluid, mix = scenario.fluid, scenario.mixture
    if fluid is None or mix is None:
        return
    grains = scenario.material.particle_density or scenario.material.density
    g = scenario.gravity * math.cos(math.radians(scenario.slope_deg))
    phis = [e.phi for e in scenario.initial if e.phi is not None] + [mix.phi_critical]
    keys = {
        "fluid.viscosity": fluid.viscosity,
        "material.grain_diameter": scenario.material.grain_diameter,
        "mixture.kozeny": mix.kozeny,
        "mixture.dilatancy": mix.dilatancy,
        "mixture.critical_shift": mix.critical_shift,
    }

    def bound(phi: float, values: dict[str, float]) -> float:
        eta = values["fluid.viscosity"]
        beta = closure.drag(values["mixture.kozeny"], eta, values["material.grain_diameter"], phi)
        weight = (grains - fluid.density) * g * phi * h
        K, K2 = values["mixture.dilatancy"], values["mixture.critical_shift"]
        return closure.discriminant_bound(beta, h, phi, weight, K, K2, eta)

    for phi in phis:
        value = bound(phi, keys)
        if not value <= closure.DISCRIMINANT_LIMIT:
            culprit = _closure_culprit(keys, partial(bound, phi))
            given = ", ".join(f"{key} = {number:g}" for key, number in keys.items())
            raise InputError(
                f"{where}: {culprit}: the mixture's closure overflows on the initial column ({h:.3g} m "
                f"thick, phi = {phi:g}): with {given}, its effective pressure's quadratic a^2 + 4 c at a "
                f"shear rate of {closure.SHEAR_RATE_SCALE:g} 1/s is {value:.3g}; accepted: values of these "
                f"keys whose a^2 + 4 c stays below {closure.DISCRIMINANT_LIMIT:g} (a = P + B gamma K, c = B "
                "K K2 eta_f gamma^2, B the Darcy coefficient, docs/mixture.md)"
            )


def closure_reference() -> dict[str, float]:
    """The closure's keys in the experiments of Pailha, Nicolas & Pouliquen (2008) and Pailha
    & Pouliquen (2009), and the Carman-Kozeny constant 150: what :func:`_closure_culprit`
    puts one key back to."""
    from multilayer.reference import immersed_layer as pailha  # its scipy is not validate's

    return {
        "fluid.viscosity": pailha.PAILHA_2008_FLUIDS["viscous"]["eta_f"],
        "material.grain_diameter": pailha.PAILHA_2008_GRAINS["d"],
        "mixture.kozeny": 150.0,
        "mixture.dilatancy": pailha.PAILHA_POULIQUEN_2009_K,
        "mixture.critical_shift": pailha.PAILHA_2008_GRAINS["K2"],
    }


def _closure_culprit(keys: dict[str, float], bound: Callable[[dict[str, float]], float]) -> str:
    """The key of ``keys`` whose value, put back to :func:`closure_reference`'s, lowers
    ``bound`` the most: the largest value named another key than the one that overflowed
    the closure (``mixture.kozeny`` 1e300 was blamed on ``mixture.critical_shift``)."""
    reference = closure_reference()
    return min(keys, key=lambda key: bound({**keys, key: reference[key]}))


def check_start(scenario: Scenario, where: str) -> None:
    """What a run checks of ``scenario`` before its first step (:class:`InputError` naming
    ``where`` otherwise): material to run, the initial entries on the mesh and their
    pressure; the check a study gives :func:`multilayer.io.study.load_calibration` and
    :func:`~multilayer.io.study.load_sensitivity` for its runs at the bounds."""
    scenario.check_material()
    check_initial(scenario, where)
    check_pressure(scenario)


def check_pressure(scenario: Scenario) -> None:
    """:func:`multilayer.engine.initial_state.check_pressure` of the scenario's initial
    state under its bulk density and gravity, and its
    :func:`~multilayer.engine.initial_state.check_transport` with the waves and cells of
    the estimate of its steps (:func:`multilayer.app.resources.steps`), an inflow's
    thickness included (``InputError`` naming them)."""
    weight = scenario.material.density * scenario.gravity * math.cos(math.radians(scenario.slope_deg))
    entries, where = initial_entries(scenario), str(scenario.source or "<scenario>")
    initial_state.check_pressure(entries, weight, where)
    need, inflow = resources.steps(scenario), scenario.boundaries.inflow
    depth = max(initial_state.stacked_depth(entries), 0.0 if inflow is None else inflow.thickness)
    initial_state.check_transport(depth, need.speed, need.dx, where)


def material(scenario: Scenario) -> Material:
    """The :class:`multilayer.Material` handed to the rheology plugins."""
    spec = scenario.material
    particle_density = spec.density if spec.particle_density is None else spec.particle_density
    return Material(spec.density, spec.grain_diameter, particle_density)


def mixture(scenario: Scenario) -> cfg.MixtureConfig | None:
    """The engine's grain–fluid mixture of ``scenario`` (its ``fluid`` and ``mixture`` keys)."""
    fluid, closure = scenario.fluid, scenario.mixture
    if fluid is None or closure is None:
        return None
    return cfg.MixtureConfig(
        fluid_density=fluid.density,
        fluid_viscosity=fluid.viscosity,
        phi_critical=closure.phi_critical,
        dilatancy=closure.dilatancy,
        critical_shift=closure.critical_shift,
        kozeny=closure.kozeny,
        compressibility=fluid.compressibility,
    )


def engine_config(scenario: Scenario) -> cfg.SimulationConfig:
    """The engine's configuration of ``scenario`` (its keys, docs/scenarios.md)."""
    sc, dom, n = scenario, scenario.domain, scenario.numerics
    fractions = layer_fractions(dom.layers, dom.layer_fractions)
    model = models()[sc.model.pressure]
    inflow = sc.boundaries.inflow
    return cfg.SimulationConfig(
        x_min=dom.x_min,
        x_max=dom.x_max,
        cells=dom.cells,
        fractions=tuple(float(f) for f in fractions),
        material=material(sc),
        gravity=sc.gravity,
        slope_deg=sc.slope_deg,
        width=dom.width,
        base=basal_regions(sc.base),
        bed=_points(sc.bed.points),
        initial=initial_entries(sc),
        left=sc.boundaries.left,
        right=sc.boundaries.right,
        inflow=None if inflow is None else cfg.Inflow(inflow.thickness, _velocity(inflow.velocity)),
        gate=None if sc.gate is None else cfg.GateConfig(sc.gate.x, sc.gate.lift_speed),
        cfl=sc.time.cfl,
        numerics=cfg.Numerics(
            transport_solver=n.transport_solver,
            threads=n.threads,
            order=n.order,
            tolerance=n.tolerance,
            max_iterations=n.max_iterations,
            dry_threshold=n.dry_threshold,
            front_threshold=n.front_threshold,
        ),
        pressure=cfg.PressureConfig(
            sc.model.pressure, MappingProxyType(options(model, sc.model.options, dom.layers))
        ),
        normal_stress=sc.model.normal_stress,
        mixture=mixture(sc),
        name=str(sc.source or "<scenario>"),
    )


def laws(scenario: Scenario) -> tuple[Rheology, Rheology | None]:
    """The bulk and wall rheology plugin instances of ``scenario`` (the plugin host)."""
    walls = None if scenario.walls is None else host.instantiate(scenario.walls)
    return host.instantiate(scenario.rheology), walls


def _fipy_solve(
    problem: ColumnProblem,
    guess: np.ndarray | None = None,
    threads: int = 1,
    poll: Callable[[], None] | None = None,
) -> np.ndarray:
    """The FiPy reference solver of the column problem; it needs no guess (it starts from
    scratch each time) and calls ``poll`` between its iterations.  FiPy is imported on the
    first call."""
    from multilayer.reference import vertical_fipy

    return vertical_fipy.solve(problem, poll=poll)


def column_solver(name: str) -> VerticalSolver | None:
    """The exact solver of the column problem for ``numerics.vertical_solver``: None for
    ``kernel`` (the engine's compiled one), the FiPy reference for ``fipy``."""
    return _fipy_solve if name == "fipy" else None
