"""The stopping rule and the safeguard of the Newton iteration of the vertical step
(newton_control.py): a rigorous error bound from the strong convexity of the step's energy,
and steps kept only when they lower the energy (or halve the bound)."""

from __future__ import annotations

import numpy as np
from engine import simulation
from scipy.integrate import quad

from multilayer.engine import column_kernel, vertical_step
from multilayer.engine.column_problem import ColumnProblem
from multilayer.engine.newton_control import examine, examine_columns


def bingham(rng, L, N) -> ColumnProblem:
    """Random columns with yield stresses, conductances and walls (some of each zero)."""

    def sparse(hi, p):
        return rng.uniform(0, hi, (L, N)) * (rng.random((L, N)) < p)

    return ColumnProblem(
        m=rng.uniform(0.5, 2, (L, N)), ustar=rng.normal(0, 1, (L, N)), dt=0.1,
        kappa=sparse(3, 0.8), c=sparse(2, 0.5), w=sparse(2, 0.5), cw=sparse(1, 0.3),
    )  # fmt: skip


def bingham_examine(p: ColumnProblem, start: np.ndarray, u: np.ndarray):
    """examine() of every column for the Bingham energy of ``p`` (its own true law)."""
    jump = np.abs(np.diff(u, axis=0, prepend=0.0))
    return examine_columns(p.m / p.dt, p.m * p.ustar / p.dt, p.kappa, p.c * jump, p.w, p.cw * np.abs(u), start, u)


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


def test_the_descent_test_is_the_left_derivative_of_the_energy_along_the_step():
    """phi'(1-) of phi(t) = E(start + t (end - start)), with the kinks of static layers,
    plugs and walls at the end point."""
    rng = np.random.default_rng(4)
    p = bingham(rng, 6, 200)
    end = column_kernel.solve(p)
    start = end + rng.normal(0, 0.3, end.shape)
    _, slope = bingham_examine(p, start, end)
    eps = 1e-5  # phi is quadratic on [1 - 2 eps, 1]: the one-sided difference of order 2 is exact
    energy = [bingham_energy(p, end - k * eps * (end - start)) for k in range(3)]
    left = (3 * energy[0] - 4 * energy[1] + energy[2]) / (2 * eps)
    np.testing.assert_allclose(slope, left, rtol=1e-6, atol=1e-6)
    assert (slope > 0).any() and (slope < 0).any()
