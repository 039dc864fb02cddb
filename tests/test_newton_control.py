"""The stopping rule and the safeguard of the Newton iteration of the vertical step
(newton_control.py): a rigorous error bound from the strong convexity of the step's energy,
and steps kept only when they lower the energy (or halve the bound)."""

from __future__ import annotations

import numpy as np
from engine import simulation

from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.engine.vertical import newton as vertical_step
from multilayer.engine.vertical.newton_control import error_bound, examine_columns
from multilayer.engine.vertical.problem import ColumnProblem


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
    return examine_columns(inertia, momentum, p.kappa, at_u[0], p.w, at_u[2], start, u, viscous(start))


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


def test_a_secant_step_lowers_the_energy_from_any_velocities():
    """The property the safeguard relies on: the secant model (true yield stresses,
    conductances eta at the current rates) majorises the energy for a viscosity
    nonincreasing in the rate, so its exact minimiser lowers the energy, from any
    velocities."""
    L, N, dt = 8, 300, 0.05
    stresses, cs, _, ustar, rng, energy = power_law_columns(L, N, dt, seed=1)
    start = ustar * rng.uniform(-1, 2, (L, N)) * (rng.random((L, N)) < 0.8)
    before = energy(start)
    secant = column_kernel.solve(stresses.linearise(cs, start, ustar, dt, np.ones(N, bool)), guess=start)
    assert np.all(energy(secant) < before)


def test_the_safeguarded_iteration_lowers_the_energy_and_ends_within_the_tolerance():
    """On the same strongly shear-thinning columns, every iterate has a lower energy than
    the one before (in closed form, not the bounds the iteration uses; the test applies
    from iteration TRUSTED on, but no step before raises it either), the iteration stops
    within the threshold of the step solved to round-off (60 plain Newton iterations), with
    the same layers at rest, and needs no more iterations than the plain one stopped when
    its velocities change by less than the threshold."""
    L, N, dt = 16, 200, 0.5
    stresses, cs, h, ustar, _, energy = power_law_columns(L, N, dt, seed=2)
    scale = np.abs(ustar).max()
    threshold = 1e-10 * scale
    iterates = []
    linearise = stresses.linearise

    def recording(cs_, u, ustar_, dt_, secant=None):
        iterates.append(u.copy())
        return linearise(cs_, u, ustar_, dt_, secant)

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
