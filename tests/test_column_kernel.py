"""The exact kernel of the vertical step: the minimiser of a convex energy."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize

from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.engine.vertical.problem import ColumnProblem


def energy(u: np.ndarray, p: ColumnProblem) -> float:
    """E(u) of one column (docs/model.md, "The implicit vertical step")."""
    s = np.diff(u, axis=0, prepend=0.0)
    inertia = p.m / (2 * p.dt) * (u - p.ustar) ** 2
    return np.sum(inertia + p.cw / 2 * u**2 + p.w * np.abs(u)) + np.sum(p.kappa * np.abs(s) + p.c / 2 * s**2)


def random_problem(rng, L, N) -> ColumnProblem:
    def sparse(hi, p):
        return rng.uniform(0, hi, (L, N)) * (rng.random((L, N)) < p)

    return ColumnProblem(
        m=rng.uniform(0.5, 2, (L, N)),
        ustar=rng.normal(0, 1, (L, N)),
        dt=0.1,
        kappa=sparse(3, 0.8),
        c=sparse(2, 0.5),
        w=sparse(2, 0.5),
        cw=sparse(1, 0.3),
    )


@pytest.mark.slow
def test_no_velocity_profile_has_lower_energy_than_the_solution():
    rng = np.random.default_rng(1)
    problem = random_problem(rng, 5, 15)
    u = column_kernel.solve(problem)
    for i in range(u.shape[1]):
        column = problem.columns(slice(i, i + 1))
        best = energy(u[:, i : i + 1], column)
        found = minimize(
            lambda v, column=column: energy(v[:, None], column),
            u[:, i] + 0.01,
            method="Nelder-Mead",
            options={"xatol": 1e-12, "fatol": 1e-15, "maxiter": 20000},
        ).fun
        for _ in range(50):  # and random nearby profiles
            trial = u[:, i : i + 1] + rng.normal(0, 1e-4, (u.shape[0], 1))
            found = min(found, energy(trial, column))
        assert best <= found + 1e-12


def test_static_layers_are_exactly_zero_and_plugs_exactly_rigid():
    rng = np.random.default_rng(2)
    u = column_kernel.solve(random_problem(rng, 8, 200))
    assert np.count_nonzero(u == 0.0) > 50
    assert np.count_nonzero(np.diff(u, axis=0) == 0.0) > 50


@pytest.mark.parametrize("seed", range(3))
def test_the_active_set_path_agrees_with_the_dynamic_programme(seed):
    """The guess only proposes the structure; a wrong guess falls back to the DP."""
    rng = np.random.default_rng(seed)
    problem = random_problem(rng, 8, 300)
    reference = column_kernel.solve(problem, guess=np.full(problem.shape, np.nan))  # DP everywhere
    for guess in (
        reference,
        reference + rng.normal(0, 0.1, reference.shape) * (rng.random(reference.shape) < 0.3),
    ):
        u = column_kernel.solve(problem, guess=guess)
        assert np.abs(u - reference).max() < 1e-11
        assert np.array_equal(u == 0.0, reference == 0.0)


def test_single_layer_on_a_coulomb_base_is_the_soft_threshold():
    """One layer, kappa_0 = mu p, c_0 = 0: u = sgn(u*) max(|u*| - dt kappa_0 / m, 0)."""
    ustar = np.linspace(-1, 1, 41)[None, :]
    m, dt, kappa = np.full_like(ustar, 2.0), 0.1, np.full_like(ustar, 5.0)
    zero = np.zeros_like(ustar)
    u = column_kernel.solve(ColumnProblem(m=m, ustar=ustar, dt=dt, kappa=kappa, c=zero, w=zero, cw=zero))
    exact = np.sign(ustar) * np.maximum(np.abs(ustar) - dt * 5.0 / 2.0, 0.0)
    assert np.abs(u - exact).max() < 1e-15
    assert np.all(u[np.abs(ustar) <= 0.25] == 0.0)


def test_column_problem_rejects_arrays_of_different_shapes_and_selects_columns():
    rng = np.random.default_rng(5)
    problem = random_problem(rng, 4, 6)
    with pytest.raises(ValueError, match=r"\(L, N\)"):
        ColumnProblem(
            m=problem.m,
            ustar=problem.ustar[:, :3],
            dt=0.1,
            kappa=problem.kappa,
            c=problem.c,
            w=problem.w,
            cw=problem.cw,
        )
    part = problem.columns(np.array([1, 4]))
    assert part.shape == (4, 2) and part.dt == problem.dt
    np.testing.assert_array_equal(column_kernel.solve(part), column_kernel.solve(problem)[:, [1, 4]])


def test_the_dynamic_programme_is_exact_when_its_messages_reach_far_out():
    """A column of the non-hydrostatic collapse at t = 0.03 s (a = 10, 16 layers): zero
    pressure (no yield stress, no viscosity) in the middle layers, heavy layers (m/dt ~ 6e4).
    Its messages hold vertices on their rays at abscissae ~1e13; interpolated from there, the
    top velocity lost its digits (-0.01953125 instead of -0.0209634, so that the Newton
    iteration of the step never converged).  Every jump of the solution is non-zero, so it
    is the solution of the linear momentum balance with those signs (checked consistent)."""
    inertia = np.full(16, 57973.6)
    momentum = np.array(
        [6518.9, 10289.0, 10970.3, 9689.56, 8593.87, 7386.42, 6204.09, 5007.77,
         3790.8, 2587.75, 1431.83, 390.663, -477.976, -971.752, -1228.97, -1227.24]
    )  # fmt: skip
    kappa = np.zeros(16)
    c = np.zeros(16)
    kappa[[0, 1, 12, 13, 14, 15]] = [160.136, 42.2591, 11.248, 42.6244, 54.508, 11.9121]
    c[[0, 1, 12, 13, 14, 15]] = [35.8787, 9.61251, 5.12741, 10.181, 11.5709, 5.41784]
    zero = np.zeros(16)
    u = np.empty(16)
    column_kernel._dynamic_programme(inertia, momentum, kappa, c, zero, zero, u, column_kernel._workspace(16))
    # inertia (u - u*) + sigma_a - sigma_{a+1} = 0 with sigma_k = kappa_k sgn(s_k) + c_k s_k
    sign = np.sign(np.diff(u, prepend=0.0))
    difference = np.eye(16) - np.eye(16, k=-1)  # s = D u
    stress = difference.T @ np.diag(c) @ difference
    exact = np.linalg.solve(np.diag(inertia) + stress, momentum - difference.T @ (kappa * sign))
    assert np.array_equal(np.sign(np.diff(exact, prepend=0.0)), sign)  # the signs are consistent
    assert np.abs(u - exact).max() < 1e-12


@pytest.mark.parametrize("layers", [1, 7, 40])
def test_the_memory_estimate_of_the_workspace_is_the_workspace(layers):
    """resources counts the workspace of every thread from vertical.problem.workspace_bytes,
    which must be what _workspace allocates (quadratic in the layers)."""
    from multilayer.engine.vertical.problem import workspace_bytes

    assert sum(a.nbytes for a in column_kernel._workspace(layers)) == workspace_bytes(layers)


def test_a_column_thinner_than_1e_70_m_whose_pivot_underflows_is_solved():
    """A front column 4.3e-74 m thick, at rest after transport (u* = 0) with a Newton seed of
    tiny velocities, found in a collapse: the active-set solve's pivot underflows to zero.
    The compiled step raised ZeroDivisionError; the answer of u* = 0 is u = 0 exactly (no
    load, no stress)."""
    import multilayer
    from multilayer.validation.runs import SCENARIOS

    sim = multilayer.Simulation(
        multilayer.load(
            SCENARIOS / "column_collapse_channel.yaml",
            {"domain.cells": 4, "domain.x_max": 0.008, "initial.0.x_max": 0.004},
        )
    )
    seed = [7.886258043483493e-90, 2.1985859322473188e-114, 4.357695013479453e-22, 1.3083949933391305e-114]
    seed += [8.358229349887259e-100, 7.352432240078284e-88, 1.6160532382101908e-132, 1.2920971115172889e-134]
    h, guess = np.zeros(4), np.zeros((8, 4))
    h[1], guess[:, 1] = 4.264360514057591e-74, seed
    u, iterations = sim.vertical.compiled(
        h, np.zeros((8, 4)), guess, 4.3138398641486936e-4, threshold=9.904544411531516e-11,
        max_iterations=200, rest=np.zeros((8, 4), dtype=bool), yield_gravity=np.full((8, 4), 9.81),
    )  # fmt: skip
    assert iterations[0] >= 0 and np.all(u == 0.0)
