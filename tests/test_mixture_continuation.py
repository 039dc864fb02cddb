"""The mixture's local step at a thin front and in sub-steps (engine/mixture/local_step.py,
continuation in ``dt``): a loose column of millimetre beads in water whose thin front
dilates within a step runs, conserving the solid and the fluid, with the pore pressure of
a loose packing below it; the front columns whose Newton iteration in the thickness
diverged or wandered converge in one step in the ratio ``h* / h'``, at the root of
backward Euler; a column in ``k`` sub-steps converges at first order to the local
relaxation the step discretises, solved by Radau IIA; a column that fails in every
sub-step still stops the run."""

from __future__ import annotations

import functools

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from multilayer.engine.config import InitialEntry, MixtureConfig, SimulationConfig
from multilayer.engine.mixture import local_step
from multilayer.engine.mixture.local_step import LocalStep
from multilayer.engine.simulation import Simulation
from multilayer.errors import RunError
from multilayer.plugins.builtins import DilatantCoulomb, JopMuI
from multilayer.plugins.contract import Material, MixtureState

# water, 1 mm glass beads, the closure constants of Pailha & Pouliquen (2009) as in
# scenarios/submarine_collapse_loose.yaml
WATER = MixtureConfig(
    fluid_density=1000.0, fluid_viscosity=1e-3, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
)
BEADS = Material(density=1830.0, grain_diameter=1e-3, particle_density=2500.0)
LAW = DilatantCoulomb(delta_deg=22.5, K1=90.5)
FRONT = (8.7566e-4, 0.55758653, 0.26670506, 0.014280705)
"""``h*`` (m), ``phi``, ``u*`` (m/s) and ``dt`` (s) of the front column (x = 0.0825 m) of
the loose column below at 0 degrees, at its second step (measured), where the Newton
iteration in the thickness ``h'`` diverged (``dt Phi >= 1`` at a trial)."""
WANDERING = (7.647190711881705e-4, 0.5575865302959222, 0.2667050642254405, 0.012471397424917822)
"""``h*`` (m), ``phi``, ``u*`` (m/s) and ``dt`` (s) of the front column of the same run at
the same time (t = 0.0146 s) in a step of 12.5 ms (measured), where the Newton iteration in
the thickness ``h'`` wandered."""


def loose_column(slope: float, layers: int) -> Simulation:
    """The loose column of Rondon, Pouliquen & Aussillous (2011) (phi0 = 0.55, 6 cm long,
    4.8 cm high, against the wall of a 30 cm tank) of 1 mm beads in water, 20 cells."""
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.06, height=0.048, phi=0.55)
    config = SimulationConfig(
        x_min=0.0, x_max=0.3, cells=20, fractions=(1.0 / layers,) * layers, material=BEADS, slope_deg=slope,
        initial=(entry,), left="wall", right="outflow", mixture=WATER,
    )  # fmt: skip
    return Simulation(config, LAW)


@pytest.mark.parametrize(
    ("layers", "slope"),
    [
        (1, 20.0),
        *(pytest.param(*case, marks=pytest.mark.slow) for case in [(1, 0.0), (1, 25.0), (3, 0.0), (3, 20.0)]),
    ],
)
def test_a_loose_column_of_millimetre_beads_in_water_runs(layers, slope):
    """Its thin front, fast and at a low effective pressure, dilates within a step far past
    the packing where its friction vanishes (the root of one step: h' = 1.6 h*, phi 0.557
    -> 0.35 at 0 degrees), where the Newton iteration in the thickness diverged (0 degrees)
    or stalled (20 degrees) at the second step; in the ratio ``h* / h'`` one step converges
    (:func:`test_a_front_column_converges_in_one_step_at_the_root_of_backward_euler`).  Over
    the first 5 steps the solid is conserved to round-off, the fluid the mixture gained is
    what the ambient fluid lost, and the bed excess pore pressure below the column is
    positive, as below every loose (contracting) column (test_mixture_flow.py; Rondon et al.
    2011) (measured: one layer +65, +142 and +164 Pa at 0, 20 and 25 degrees, three layers
    +58 and +128 Pa at 0 and 20)."""
    sim = loose_column(slope, layers)
    solid0, volume0 = sim.mixture.solid.sum() * sim.dx, sim.h.sum() * sim.dx
    for _ in range(5):
        sim.step()
        sim.check_state()  # the guard: mixture volume = start + boundaries + ambient exchange
    assert np.any(sim.u != 0.0)
    assert abs(sim.mixture.solid.sum() * sim.dx - solid0) <= 1e-14 * solid0
    fluid = (sim.h.sum() - sim.mixture.solid.sum()) * sim.dx
    assert fluid - (volume0 - solid0) == pytest.approx(sim.mixture.ambient_exchange, abs=1e-15)
    assert sim.mixture.pore_pressure[0, sim.x < 0.06].mean() > 0.0


def one_column(h: float, phi: float) -> tuple[LocalStep, np.ndarray, np.ndarray]:
    """The local step of one layer of beads in water, a column of thickness ``h`` at ``phi``."""
    local = LocalStep(WATER, LAW, BEADS, np.array([1.0]), 9.81, 1e-10, 200)
    return local, np.array([[phi * h]]), np.array([h])


def relaxation(
    local: LocalStep, solid: np.ndarray, h0: float, v0: float, dt: float, rtol: float
) -> np.ndarray:
    """``(v, h)`` after ``dt`` of the local relaxation of one layer that the local step
    discretises (velocity equality; the limit of its backward Euler with the mean mass)::

        m(h) dv/dt = -(kappa + eta gamma) - rho_f (dh/dt) v / 2,   dh/dt = h Phi

    with ``m(h) = rho_s s + rho_f (h - s)``, ``gamma = 2 v / h`` and the closure
    (:meth:`LocalStep.closure`) and rheology at the state, by Radau IIA (relative tolerance
    ``rtol``, absolute ``rtol`` times ``v0`` and ``h0``); the layer must not stop within ``dt``."""
    rho_f = WATER.fluid_density

    def rhs(_t: float, y: np.ndarray) -> list[float]:
        v, h = y
        gamma, p_s, dilation, p_e = local.closure(solid, np.array([h]), np.array([[v]]))
        cfg = WATER
        state = MixtureState(
            solid / h, p_e, cfg.fluid_viscosity, cfg.phi_critical, cfg.dilatancy, cfg.critical_shift
        )
        tau = (
            LAW.mixture_yield_stress(p_s, state, BEADS)
            + LAW.mixture_viscosity(gamma, p_s, state, BEADS) * gamma
        )
        growth = h * dilation[0, 0]
        mass = local.masses(solid, np.array([h]))[0, 0]
        return [-(tau[0, 0] + 0.5 * rho_f * growth * v) / mass, growth]

    def stops(_t: float, y: np.ndarray) -> float:
        return y[0]

    stops.terminal = True  # type: ignore[attr-defined]
    solution = solve_ivp(
        rhs, (0.0, dt), [v0, h0], method="Radau", rtol=rtol, atol=[rtol * v0, rtol * h0], events=stops
    )
    assert solution.status == 0  # reached dt, still moving
    return solution.y[:, -1]


@functools.cache
def substepped(h: float, phi: float, v: float, dt: float, k: int) -> np.ndarray:
    """``(v, h)`` of one local step in ``k`` sub-steps of the column ``h``, ``phi`` from ``v``."""
    local, solid, thickness = one_column(h, phi)
    result = local(solid, thickness, np.array([[v]]), dt, substeps=k)
    return np.array([result.u[0, 0], result.h[0]])


def test_a_column_in_substeps_converges_at_first_order_to_its_relaxation():
    """A column of 5 mm at phi = 0.55 sliding at 0.2 m/s, dt = 0.014 s (rho_s/beta = 0.025
    s, longer than the step, as at the failing front): the local step in 4, 8 and 16 sub-steps
    against the relaxation it discretises (:func:`relaxation`): the error in ``v`` and in
    ``h`` halves as the sub-steps halve (measured: ratios 1.91 and 1.95 in ``v``, 1.90 and
    1.95 in ``h``; errors 8.4e-4 m/s and 8.1e-6 m at 4 sub-steps)."""
    h, phi, v, dt = 5e-3, 0.55, 0.2, 0.014
    local, solid, _ = one_column(h, phi)
    exact = relaxation(local, solid, h, v, dt, 1e-10)
    errors = np.array([np.abs(substepped(h, phi, v, dt, k) - exact) for k in (4, 8, 16)])
    ratios = errors[:-1] / errors[1:]
    assert np.all((ratios > 1.8) & (ratios < 2.2)), ratios


def one_step(h: float, phi: float, v: float, dt: float, monkeypatch: pytest.MonkeyPatch) -> tuple:
    """One Newton iteration of one step (no sub-steps) of the column ``h``, ``phi`` from
    ``v``: its result, whether it converged, the residual norms of its iterations, the local
    step and the solid."""
    norms: list[float] = []
    progress = local_step._progress

    def spy(best: np.ndarray, since: np.ndarray, norm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        norms.extend(norm)
        return progress(best, since, norm)

    monkeypatch.setattr(local_step, "_progress", spy)
    local, solid, thickness = one_column(h, phi)
    local.form = None  # the numpy iteration, whose norms the spy sees (the compiled one: the same bits)
    rest = np.zeros((1, 1))
    result, converged, diverged, _, _ = local._newton(
        solid, thickness, np.array([[v]]), dt, rest, rest, np.zeros(1), 0.0
    )
    assert not diverged[0] and norms
    return result, bool(converged[0]), norms, local, solid


@pytest.mark.parametrize(("column", "ratio"), [(FRONT, 1.6072), (WANDERING, 1.7465)])
def test_a_front_column_converges_in_one_step_at_the_root_of_backward_euler(column, ratio, monkeypatch):
    """The front columns :data:`FRONT` and :data:`WANDERING`, whose Newton iteration in the
    thickness diverged (a trial where ``dt Phi >= 1`` has no ``h* / (1 - dt Phi)``) or
    wandered (49 iterations, then sub-steps): in the ratio ``z = h* / h'`` the step's
    equation ``z = 1 - dt Phi`` is finite at every trial, and one step converges (measured:
    6 and 7 iterations), its least residual norm falling at every iteration (so the window
    never takes it for a wandering one), at the root of backward Euler: ``h' (1 - dt Phi')
    = h*`` to the tolerance (measured: 5.9e-13 and 2.7e-14 of ``h*``), ``h' = 1.61 h*`` and
    ``1.75 h*`` (the front dilates, ``phi`` 0.557 to 0.347 and 0.319), the solid kept bit
    for bit."""
    h, phi, v, dt = column
    result, converged, norms, local, solid = one_step(h, phi, v, dt, monkeypatch)
    assert converged and result.iterations <= 8
    assert np.all(np.diff(norms) < 0.0), norms
    dilation = local.closure(solid, result.h, result.solved)[2]
    assert abs(result.h[0] * (1.0 - dt * dilation[0, 0]) - h) <= 1e-10 * h
    assert result.h[0] / h == pytest.approx(ratio, abs=1e-4)
    assert np.array_equal(result.solid, solid) and result.u[0, 0] > 0.0


def test_substeps_of_the_front_column_approach_its_relaxation():
    """The front column :data:`FRONT` in 1, 2, 4, 8 and 16 sub-steps approaches the
    relaxation the step discretises (:func:`relaxation`; the front dilates to phi = 0.29):
    the error in ``v`` falls at every doubling (measured: 2.7e-2, 1.7e-2, 1.1e-2, 7.5e-3 and
    4.8e-3 m/s)."""
    h, phi, v, dt = FRONT
    local, solid, _ = one_column(h, phi)
    exact = relaxation(local, solid, h, v, dt, 1e-8)  # the errors are 1e-3 of v and more
    errors = [np.abs(substepped(h, phi, v, dt, k) - exact)[0] for k in (1, 2, 4, 8, 16)]
    assert np.all(np.diff(errors) < 0.0), errors


def test_a_column_that_fails_in_every_substep_stops_the_run():
    """A Newton iteration allowed one iteration (numerics.max_iterations = 1) cannot reach
    the tolerance in a moving column in any number of sub-steps: the run stops with the
    column, the time, the key and the closure's coefficients, after the largest number of
    sub-steps."""
    local = LocalStep(WATER, LAW, BEADS, np.array([1.0]), 9.81, 1e-10, 1)
    h, phi, v, dt = FRONT
    with pytest.raises(
        RunError,
        match=r"did not converge \(.*critical_shift = 25\): .*max_iterations = 1 \(at x = 0\.5 m, t = 2 s",
    ):
        local(np.array([[phi * h]]), np.array([h]), np.array([[v]]), dt, x=np.array([0.5]), t=2.0)


GRAVEL_FRONT = (0.0011131979662245201, 0.00025635155926708066, 1.256134537102833, 0.05298422414140064)
"""``h*`` (m), solid ``phi h*`` (m), ``u*`` (m/s) and ``dt`` (s) of the front column (x =
16.15 m) of a loose column (``phi0 = 0.55``) 10 m thick and 12.5 m long of 1 cm grains in
the fluid of scenarios/submarine_collapse_loose.yaml on 10 degrees (60 cells), at its fifth
step (measured): at the first trial of the step (``p_e = 0``, ``h = h*``) ``dt Phi = 2.87``,
so ``h* / (1 - dt Phi)`` is not a thickness, and the iteration in the thickness diverged in
every number of sub-steps (the run stopped at its fourth step)."""


def test_a_front_where_dt_phi_exceeds_one_dilates_in_one_step_conserving_its_solid():
    """The column :data:`GRAVEL_FRONT`, its packing 0.23 far below ``phi_c``: one step
    converges (no sub-steps) at the root of backward Euler, ``h' (1 - dt Phi') = h*`` to the
    tolerance (measured: 10.9 h*, phi 0.021: the viscous shift ``K2 eta_f gamma / p_s`` puts
    the critical packing below zero at this shear and effective pressure, the model's own
    dilation); the thickness and the packing are positive, the solid kept bit for bit, the
    fluid drawn ``h' - h*`` that of the dilation, ``dt h' Phi'``, to the tolerance.  Without
    a drive (``u* = 0``) the column is the exact rest state: ``u == 0.0``, ``h' == h*`` and
    ``p_e == 0.0``."""
    h, s, v, dt = GRAVEL_FRONT
    config = MixtureConfig(
        fluid_density=1010.0, fluid_viscosity=0.0121, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
    )
    gravel = Material(density=1830.0, grain_diameter=1e-2, particle_density=2500.0)
    local = LocalStep(config, LAW, gravel, np.array([1.0]), 9.81 * np.cos(np.radians(10.0)), 1e-10, 200)
    solid, thickness, rest = np.array([[s]]), np.array([h]), np.zeros((1, 1))
    result, converged, diverged, _, _ = local._newton(
        solid, thickness, np.array([[v]]), dt, rest, rest, np.zeros(1), 0.0
    )
    assert converged[0] and not diverged[0]
    dilation = local.closure(solid, result.h, result.solved)[2][0, 0]
    assert abs(result.h[0] * (1.0 - dt * dilation) - h) <= 1e-10 * h
    assert abs(result.h[0] - h - dt * result.h[0] * dilation) <= 1e-10 * h
    phi = s / result.h[0]
    assert result.h[0] > h and 0.0 < phi < s / h and np.isfinite(result.u).all()
    assert np.array_equal(result.solid, solid)
    still = local(solid, thickness, rest, dt)
    assert np.array_equal(still.u, rest) and np.array_equal(still.h, thickness)
    assert np.array_equal(still.pore_pressure, rest)


def test_a_layered_mixture_under_jop_mu_i_converges_in_a_few_newton_iterations(monkeypatch):
    """Under a law whose viscosity changes with the shear rate (Jop et al. 2006 mu(I)) the
    map of the Newton iteration changes with the last iterate's shear rates: the Jacobian
    and the line search take the residual of the iterate at the new rates, not the one of
    the iteration before (whose difference, over a finite-difference step of 1e-7, swamped
    the Jacobian: every column ran out of its 200 iterations, then each of its sub-steps).
    Three layers of 1 mm grains at phi 0.58 in water on 25 degrees, one step of 0.02 s
    (measured: at most 7 iterations per Newton iteration, sub-steps of half the step at
    most; before, 200 in every one down to 1/32 of the step); the solid is
    conserved to round-off and every packing stays in [0, 1)."""
    calls: list[tuple[float, int]] = []
    newton = LocalStep._newton

    def counted(self, solid, h_star, ustar, dt, *args, **kwargs):
        found = newton(self, solid, h_star, ustar, dt, *args, **kwargs)
        calls.append((dt, found[0].iterations))
        return found

    monkeypatch.setattr(LocalStep, "_newton", counted)
    mixture = MixtureConfig(
        fluid_density=1000.0, fluid_viscosity=1e-3, phi_critical=0.58, dilatancy=4.0, critical_shift=25.0
    )
    grains = Material(density=1500.0, grain_diameter=1e-3, particle_density=2500.0)
    entry = InitialEntry("rectangle", x_min=0.0, x_max=0.1, height=0.05, phi=0.58)
    config = SimulationConfig(
        x_min=0.0, x_max=0.5, cells=20, fractions=(1.0 / 3.0,) * 3, material=grains, slope_deg=25.0,
        initial=(entry,), left="wall", right="outflow", mixture=mixture,
    )  # fmt: skip
    sim = Simulation(config, JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.3))
    solid0 = sim.mixture.solid.sum() * sim.dx
    sim.step()
    sim.check_state()
    assert np.any(sim.u != 0.0)
    assert calls and max(iterations for _, iterations in calls) <= 20
    assert min(dt for dt, _ in calls) >= 0.5 * max(dt for dt, _ in calls)  # at most 2 sub-steps
    assert abs(sim.mixture.solid.sum() * sim.dx - solid0) <= 1e-14 * solid0
    held = sim.h > 0.0
    phi = sim.mixture.solid[:, held] / (sim.fractions[:, None] * sim.h[held])
    assert np.all(np.isfinite(sim.h)) and np.all(np.isfinite(sim.u))
    assert np.all((phi >= 0.0) & (phi < 1.0))
