"""The stopping rule and the globalisation of the Newton iteration of the vertical step
(newton_control.py): a rigorous error bound from the strong convexity of the step's energy,
and the Newton step taken in full or damped by an exact line search, lowering the energy
at every iteration."""

from __future__ import annotations

import math

import numpy as np
from engine import simulation

from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.engine.vertical import newton as vertical_step
from multilayer.engine.vertical.newton_control import error_bound, examine_columns
from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.plugins.contract import Rheology


def bingham(rng, L, N) -> ColumnProblem:
    """Random columns with yield stresses, conductances and walls (some of each zero)."""

    def sparse(hi, p):
        return rng.uniform(0, hi, (L, N)) * (rng.random((L, N)) < p)

    return ColumnProblem(
        m=rng.uniform(0.5, 2, (L, N)), ustar=rng.normal(0, 1, (L, N)), dt=0.1,
        kappa=sparse(3, 0.8), c=sparse(2, 0.5), w=sparse(2, 0.5), cw=sparse(1, 0.3),
    )  # fmt: skip


def bingham_examine(p: ColumnProblem, start: np.ndarray, u: np.ndarray):
    """examine_columns() for the Bingham energy of ``p`` (its own true law)."""

    def viscous(v):
        jump = np.abs(np.diff(v, axis=0, prepend=0.0))
        return np.stack([p.c * jump, p.c, p.cw * np.abs(v), p.cw])

    at_u = viscous(u)
    inertia, momentum = p.m / p.dt, p.m * p.ustar / p.dt
    return examine_columns(inertia, momentum, p.kappa, at_u[0], p.w, at_u[2], start, u, viscous(start), True)


def bingham_energy(p: ColumnProblem, u: np.ndarray) -> np.ndarray:
    s = np.diff(u, axis=0, prepend=0.0)
    terms = p.m / (2 * p.dt) * (u - p.ustar) ** 2 + p.cw / 2 * u**2 + p.w * np.abs(u)
    return np.sum(terms + p.kappa * np.abs(s) + p.c / 2 * s**2, axis=0)


def test_the_error_bound_vanishes_at_the_solution_and_bounds_the_error_elsewhere():
    """||u - u_exact||_inf <= bound for velocities near the solution with its static layers,
    plugs and locked walls (the multivalued stresses), and the bound is round-off at the
    exact minimiser."""
    rng = np.random.default_rng(3)
    p = bingham(rng, 8, 400)
    exact = column_kernel.solve(p)
    assert (exact == 0.0).sum() > 100 and (np.diff(exact, axis=0) == 0.0).sum() > 100
    bound, _ = bingham_examine(p, exact, exact)
    assert bound.max() < 1e-13
    for size in (1e-9, 1e-5, 1e-2):
        u = exact + rng.normal(0, size, exact.shape) * (exact != 0.0)  # keep the zeros
        locked = np.diff(exact, axis=0, prepend=0.0) == 0.0
        for a in range(1, 8):  # half the columns keep their plugs exactly rigid
            u[a, ::2] = np.where(locked[a, ::2], u[a - 1, ::2], u[a, ::2])
        bound, _ = bingham_examine(p, exact, u)
        error = np.abs(u - exact).max(axis=0)
        assert np.all(error <= bound * (1 + 1e-9) + 1e-15)
        assert np.median(bound / np.maximum(error, 1e-300)) < 30  # and not uselessly loose


def test_the_error_bound_with_a_limit_decides_alike_and_is_the_bound_when_not_cut():
    """``error_bound(..., limit)`` stops its pass once the bound must exceed twice the
    limit (inf then); ``bound <= limit`` is decided as by the whole pass, and a bound not
    cut is the same number."""
    rng = np.random.default_rng(5)
    p = bingham(rng, 8, 300)
    exact = column_kernel.solve(p)
    u = exact + rng.normal(0, 1, exact.shape) * 10.0 ** rng.uniform(-14, 0, exact.shape[1]) * (exact != 0.0)
    viscous = p.c * np.abs(np.diff(u, axis=0, prepend=0.0)), p.cw * np.abs(u)
    inertia, momentum = p.m / p.dt, p.m * p.ustar / p.dt
    full, _ = bingham_examine(p, u, u)
    cut = 0
    for j in range(u.shape[1]):
        args = (
            inertia[:, j],
            momentum[:, j],
            p.kappa[:, j],
            viscous[0][:, j],
            p.w[:, j],
            viscous[1][:, j],
            u[:, j],
        )
        for limit in (0.0, 1e-10, 1e-6, 1e-2):
            bound = error_bound(*args, limit)
            assert (bound <= limit) == (full[j] <= limit)
            assert bound == full[j] or (bound == np.inf and full[j] > 2 * limit)
            cut += bound == np.inf
    assert cut > 100


def test_the_energy_rise_is_an_upper_bound_and_exact_for_a_bingham_law():
    """For a Bingham law (linear viscous stress: tangent and chord are exact) the rise is
    E(end) - E(start) itself, or phi'(1-) where that is smaller, an upper bound of it
    by convexity; both signs occur."""
    rng = np.random.default_rng(4)
    p = bingham(rng, 6, 200)
    exact = column_kernel.solve(p)
    other = exact + rng.normal(0, 0.3, exact.shape) * (rng.random(exact.shape) < 0.7)
    rises = []
    for start, end in ((other, exact), (exact, other)):
        _, rise = bingham_examine(p, start, end)
        difference = bingham_energy(p, end) - bingham_energy(p, start)
        scale = bingham_energy(p, start) + bingham_energy(p, end)
        assert np.all(rise >= difference - 1e-12 * scale)
        eps = 1e-5  # phi is quadratic on [1 - 2 eps, 1]: the one-sided difference of order 2 is exact
        energy = [bingham_energy(p, end - k * eps * (end - start)) for k in range(3)]
        left = (3 * energy[0] - 4 * energy[1] + energy[2]) / (2 * eps)
        assert np.all((np.abs(rise - difference) <= 1e-9 * scale) | (np.abs(rise - left) <= 1e-6 * scale))
        rises.append(rise)
    moved = np.any(other != exact, axis=0)
    assert (rises[0][moved] < 0).all() and (rises[1][moved] > 0).all()


def power_law_columns(L, N, dt, seed):
    """Strongly shear-thinning columns (power-law mu(I), alpha = 0.2) with random velocities
    after transport (up to 100 m/s), their stresses and their energy in closed form."""
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 1.0, "cells": N, "layers": L},
        material={"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
        rheology={"name": "power_law_mu_i", "mu_s": 0.38, "m": 0.3, "alpha": 0.2},
        base=[{"condition": "no_slip"}],
    )
    stresses, law = sim.vertical.stresses, sim.vertical.stresses.bulk
    rng = np.random.default_rng(seed)
    h = rng.uniform(0.01, 0.5, N)
    ustar = rng.normal(0, 1, (L, N)) * 10 ** rng.uniform(-3, 2, N)
    cs = stresses.columns(h, np.arange(N))
    alpha, floor = law.alpha, law.shear_rate_floor
    # tau_v = A max(r, floor)^(alpha - 1) r, A from the plugin's viscosity at the floor
    a = law.viscosity(np.full((L, N), floor), cs.pressure, stresses.material) / floor ** (alpha - 1)

    def energy(u):
        """E of every column (docs/model.md), the viscous potential integrated exactly."""
        jump = np.diff(u, axis=0, prepend=0.0)
        rate = np.abs(jump) / cs.spacing
        below = a * floor ** (alpha - 1) * np.minimum(rate, floor) ** 2 / 2
        above = a * (np.maximum(rate, floor) ** (alpha + 1) - floor ** (alpha + 1)) / (alpha + 1)
        terms = cs.m / (2 * dt) * (u - ustar) ** 2 + cs.kappa * np.abs(jump) + cs.spacing * (below + above)
        return terms.sum(axis=0)

    return stresses, cs, h, ustar, rng, energy


def test_the_safeguarded_iteration_lowers_the_energy_and_ends_within_the_tolerance():
    """On the same strongly shear-thinning columns, every iterate has a lower energy than
    the one before (in closed form, not the bounds the iteration uses), the iteration stops
    within the threshold of the step solved to round-off (60 plain Newton iterations), with
    the same layers at rest, and needs no more iterations than the plain one stopped when
    its velocities change by less than the threshold."""
    L, N, dt = 16, 200, 0.5
    stresses, cs, h, ustar, _, energy = power_law_columns(L, N, dt, seed=2)
    scale = np.abs(ustar).max()
    threshold = 1e-10 * scale
    iterates = []
    linearise = stresses.linearise

    def recording(cs_, u, ustar_, dt_):
        iterates.append(u.copy())
        return linearise(cs_, u, ustar_, dt_)

    stresses.linearise = recording
    u, iterations = vertical_step.implicit_step(stresses, h, ustar, ustar.copy(), dt, velocity_scale=scale)
    stresses.linearise = linearise
    energies = np.array([energy(v) for v in [*iterates, u]])
    steps = np.diff(energies, axis=0)
    moved = np.diff(np.array([*iterates, u]), axis=0).any(axis=1)
    assert np.all(steps[moved] < 1e-12 * np.abs(energies[1:][moved]))
    reference, plain = ustar.copy(), None
    for k in range(1, 61):
        new = column_kernel.solve(stresses.linearise(cs, reference, ustar, dt), guess=reference)
        if plain is None and np.abs(new - reference).max() <= threshold:
            plain = k
        reference = new
    assert np.abs(u - reference).max() <= threshold
    assert np.array_equal(u == 0.0, reference == 0.0)
    assert plain is not None and iterations <= plain


# The glass beads of Forterre & Pouliquen (2003) as used by Jop, Forterre & Pouliquen (2005):
# tan d1, tan d2, L (m), beta; I_0 = 5 beta d / (2 L sqrt(phi)) (Bagnold profile), d = 0.5 mm
TAN_D1, TAN_D2, LENGTH, BETA = 0.3819, 0.6435, 0.825e-3, 0.136
GRAIN, GRAIN_DENSITY, PACKING = 0.5e-3, 2500.0, 0.6
I_0 = 5 * BETA * GRAIN / (2 * LENGTH * math.sqrt(PACKING))


class KinkedMuI(Rheology):
    """``mu = max(mu_c, mu_J(I))``: Jop et al.'s mu(I) with a static threshold ``mu_c`` above
    its ``mu_s`` (the Pouliquen-Forterre law at a fixed thickness): yield stress ``mu_c p``,
    viscous stress ``p max(0, mu_J(I) - mu_c)``, zero up to ``I_c`` and a convex kink there."""

    name = "kinked_mu_i"

    def __init__(self, mu_c: float):
        self.mu_c = mu_c

    def yield_stress(self, pressure, material):
        return self.mu_c * np.maximum(pressure, 0.0)

    def viscosity(self, shear_rate, pressure, material):
        p, rate = np.maximum(pressure, 0.0), np.abs(shear_rate)
        tau = p * np.maximum(self.mu_j(self.inertial(rate, p, material)) - self.mu_c, 0.0)
        return np.divide(tau, rate, out=np.zeros(tau.shape), where=rate > 0)

    @staticmethod
    def inertial(rate, p, material):
        scale = material.grain_diameter * math.sqrt(material.particle_density)
        return np.divide(scale * rate, np.sqrt(p), out=np.zeros(np.broadcast(p, rate).shape), where=p > 0)

    @staticmethod
    def mu_j(inertial):
        return TAN_D1 + (TAN_D2 - TAN_D1) * inertial / (I_0 + inertial)

    def potential(self, rate, p, material):
        """``int_0^rate tau_v`` in closed form: ``p^1.5 / (d sqrt(rho_p))`` times
        ``int_{I_c}^{I} (mu_J - mu_c)`` above ``I_c = I_0 (mu_c - tan d1)/(tan d2 - mu_c)``."""
        scale = material.grain_diameter * math.sqrt(material.particle_density)
        i_c = I_0 * (self.mu_c - TAN_D1) / (TAN_D2 - self.mu_c)
        i = np.maximum(self.inertial(rate, p, material), i_c)
        integral = (TAN_D2 - self.mu_c) * (i - i_c) - (TAN_D2 - TAN_D1) * I_0 * np.log(
            (I_0 + i) / (I_0 + i_c)
        )
        return p**1.5 / scale * integral


def kinked_layer(speed: float, layers: int = 16):
    """A glass-bead layer 0.8 h_stop(22 deg) thick in 4 columns, moving as a plug at
    ``speed``, with its stress model on the kinked law of its thickness, its velocities after
    the transport of a step, and the energy of the step in closed form."""
    theta = math.radians(22.0)
    h_stop = LENGTH * (TAN_D2 - math.tan(theta)) / (math.tan(theta) - TAN_D1)
    h = 0.8 * h_stop
    mu_c = TAN_D1 + (TAN_D2 - TAN_D1) / (1.0 + h / LENGTH)  # Forterre & Pouliquen 2003: mu_stop(h)
    sim = simulation(
        slope_deg=22.0,
        domain={"x_min": 0.0, "x_max": 0.04, "cells": 4, "layers": layers},
        material={
            "density": PACKING * GRAIN_DENSITY,
            "grain_diameter": GRAIN,
            "particle_density": GRAIN_DENSITY,
        },
        rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.28},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "layer", "thickness": h, "velocity": {"profile": "plug", "speed": speed}}],
        boundaries={"left": "periodic", "right": "periodic"},
    )
    stresses = sim.vertical.stresses
    law = stresses.bulk = KinkedMuI(mu_c)
    cs = stresses.columns(sim.h, np.arange(4))
    dt = sim.time_step()
    ustar = sim.u + 9.81 * math.sin(theta) * dt  # after transport: the uniform layer gains g sin(theta) dt

    def energy(u):
        jump = np.diff(u, axis=0, prepend=0.0)
        viscous = cs.spacing * law.potential(np.abs(jump) / cs.spacing, cs.pressure, stresses.material)
        return np.sum(cs.m / (2 * dt) * (u - ustar) ** 2 + cs.kappa * np.abs(jump) + viscous, axis=0)

    return sim, stresses, cs, ustar, dt, energy


def test_a_law_with_a_kinked_viscous_stress_converges_lowering_the_energy_at_every_iteration():
    """The layer thinner than h_stop launched at 5 cm/s, whose first step the plain Newton
    iteration cannot solve (its tangent model jumps across the kink at I_c: 200 iterations,
    then a run stopped with exit 1): with the line search every iterate lowers the energy
    (in closed form) and the step ends within its threshold of the step solved to round-off
    (a fixed point of the Newton model: the exact solver returns it unchanged)."""
    sim, stresses, cs, ustar, dt, energy = kinked_layer(0.05)
    iterates, linearise = [], stresses.linearise

    def recording(cs_, u, ustar_, dt_):
        iterates.append(u.copy())
        return linearise(cs_, u, ustar_, dt_)

    stresses.linearise = recording
    scale = 0.05
    u, iterations = vertical_step.implicit_step(
        stresses, sim.h, ustar, ustar.copy(), dt, velocity_scale=scale
    )
    stresses.linearise = linearise
    assert iterations <= 30
    energies = np.array([energy(v) for v in [*iterates, u]])
    moved = np.diff(np.array([*iterates, u]), axis=0).any(axis=1)
    assert moved.any() and np.all(np.diff(energies, axis=0)[moved] < 0.0)
    again = column_kernel.solve(stresses.linearise(cs, u, ustar, dt), guess=u)
    assert np.abs(again - u).max() <= 1e-10 * scale
    assert np.all((u > 0.0) & (u < 0.05))  # still moving, slowed by the bed


def test_a_layer_below_its_threshold_stops_exactly_through_the_kink():
    """A slow sheared layer of the same law (a speed the step's deceleration removes) ends the
    step exactly at rest, u == 0.0, the iteration passing the kink on its way."""
    sim, stresses, cs, ustar, dt, _ = kinked_layer(0.0)
    ustar = ustar + 2e-5 * np.linspace(0.1, 1.0, ustar.shape[0])[:, None]
    u, _ = vertical_step.implicit_step(stresses, sim.h, ustar, ustar.copy(), dt, velocity_scale=0.05)
    assert np.all(u == 0.0)


def test_damped_steps_are_the_same_in_the_compiled_and_numpy_iterations(monkeypatch):
    """Random shear-thickening columns (power-law mu(I), flow index 1.5: no tangent bound, so
    the line search damps steps): the compiled iteration and the numpy one give the same
    velocities to 1e-10 of the velocity scale, the same layers at rest, and both damp."""
    L, N, dt = 16, 60, 0.1
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 1.0, "cells": N, "layers": L},
        material={"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
        rheology={"name": "power_law_mu_i", "mu_s": 0.38, "m": 0.3, "alpha": 1.5},
        base=[{"condition": "no_slip"}],
    )
    rng = np.random.default_rng(1)
    h = rng.uniform(0.01, 0.5, N)
    ustar = rng.normal(0, 1, (L, N)) * 10 ** rng.uniform(-3, 2, N)
    scale = np.abs(ustar).max()
    damped = []
    search = vertical_step._line_search

    def counting(*args):
        damped.append(args[6].size)
        return search(*args)

    monkeypatch.setattr(vertical_step, "_line_search", counting)
    stresses = sim.vertical.stresses
    u, _ = vertical_step.implicit_step(stresses, h, ustar, ustar.copy(), dt, velocity_scale=scale)
    compiled, _ = vertical_step.implicit_step(
        stresses, h, ustar, ustar.copy(), dt, velocity_scale=scale, compiled=sim.vertical.compiled
    )
    assert sum(damped) > 10
    assert np.abs(u - compiled).max() <= 1e-10 * scale
    assert np.array_equal(u == 0.0, compiled == 0.0)
