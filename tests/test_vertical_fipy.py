"""The FiPy reference formulation of the implicit vertical step (multilayer/reference/vertical_fipy.py).

Checks against exact solutions of the step (docs/architecture.md, "Vertical step"), the
KKT conditions of the minimisation, the dense optimality system of the u-step, FiPy
FiPy issue #1223 (reused equations) and the fast kernel multilayer/engine/column_kernel.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.errors import RunError
from multilayer.reference import vertical_fipy


def zeros(L: int, N: int) -> np.ndarray:
    return np.zeros((L, N))


def interface_stress(u, m, ustar, dt, cw):
    """Stress tau_k on each interface from momentum balance, summed down from the free surface.

    Stationarity of the step for layer a (no walls) reads
    m_a/dt (u_a - u*_a) + cw_a u_a + tau_{a-1} - tau_a = 0 with tau_L = 0.
    """
    tau = np.zeros_like(u)
    above = np.zeros(u.shape[1])
    for a in range(u.shape[0] - 1, -1, -1):
        above = tau[a] = above - m[a] / dt * (u[a] - ustar[a]) - cw[a] * u[a]
    return tau


def assert_kkt(u, m, ustar, dt, kappa, c, cw, velocity_tol=1e-11):
    """The KKT conditions of the step (no walls), which certify the unique minimiser.

    Sheared interface: tau = kappa sgn(Du) + c Du.  Rigid interface (Du == 0): |tau| <= kappa.
    The stresses are sums over the column, so velocity errors ``velocity_tol`` allow
    stress errors ``velocity_tol (sum_a (m_a/dt + cw_a) + 2 c_k)``.
    """
    atol = velocity_tol * ((m / dt + cw).sum(axis=0) + 2.0 * c)
    tau = interface_stress(u, m, ustar, dt, cw)
    du = np.diff(u, axis=0, prepend=0.0)
    sheared = du != 0.0
    assert np.all(np.abs(tau - kappa * np.sign(du) - c * du)[sheared] <= atol[sheared])
    assert np.all(np.abs(tau[~sheared]) <= kappa[~sheared] + atol[~sheared])


def test_single_layer_on_coulomb_base_is_the_shrinkage():
    """One layer, Coulomb base (c_0 = 0): u = sgn(u*) max(|u*| - dt kappa_0/m, 0) exactly."""
    ustar = np.array([[-3.0, -1.0, -0.4, 0.0, 0.7, 1.0, 1.5, 4.0]])
    m, dt, kappa = np.full_like(ustar, 2.0), 0.5, np.full_like(ustar, 4.0)  # threshold 1.0
    z = zeros(*ustar.shape)
    u = vertical_fipy.solve(ColumnProblem(m=m, ustar=ustar, dt=dt, kappa=kappa, c=z, w=z, cw=z))
    expected = np.sign(ustar) * np.maximum(np.abs(ustar) - dt * kappa / m, 0.0)
    np.testing.assert_allclose(u, expected, rtol=0, atol=1e-13)
    stopped = np.abs(ustar) <= 1.0
    assert np.all(u[stopped] == 0.0)
    assert np.all(u[~stopped] != 0.0)


@pytest.mark.slow  # 6 s of FiPy solves; exact rest is also tested on the kernel path
def test_column_below_yield_stays_exactly_at_rest():
    """Uniform u* and kappa_k > (stress needed to stop everything above k): u == 0.0 exactly.

    Held either by the base and interfaces, or (free slip) by one wall-held layer.
    """
    L, N = 5, 3
    m = np.array([1.0, 2.0, 0.5, 1.5, 1.0])[:, None] * np.ones((L, N))
    ustar = np.ones((L, N)) * [[0.3, -0.2, 0.05]]
    dt = 0.1
    stop = np.cumsum((m * np.abs(ustar) / dt)[::-1], axis=0)[::-1]  # sum_{b > k} m_b |u*|/dt
    kappa = 1.01 * stop
    c = np.full((L, N), 3.0)
    fractions = [0.1, 0.2, 0.3, 0.25, 0.15]
    z = zeros(L, N)
    held = ColumnProblem(m=m, ustar=ustar, dt=dt, kappa=kappa, c=c, w=z, cw=z)
    u = vertical_fipy.solve(held, fractions=fractions)
    assert np.all(u == 0.0)
    # free-slip base, the column held by the side walls of its middle layer alone
    kappa[0], c[0] = 0.0, 0.0
    w = np.zeros((L, N))
    w[2] = 1.01 * stop[0]
    by_walls = ColumnProblem(m=m, ustar=ustar, dt=dt, kappa=kappa, c=c, w=w, cw=z)
    u = vertical_fipy.solve(by_walls, fractions=fractions)
    assert np.all(u == 0.0)


@pytest.mark.slow  # 11 s; the short FiPy-vs-kernel comparisons stay in the default run
def test_inviscid_simple_shear_decelerates_by_the_yield_gradient():
    """Inviscid simple shear (Bouchut, Ionescu & Mangeney 2016, Prop. 2.2): kappa_k = K (L - k)/L, linear u*.

    Every layer feels the net yield stress kappa_{a-1} - kappa_a = K/L, so one step gives
    u = max(u* - dt K/(L m), 0); the static layers at the bottom are exactly 0.0 and the
    column stops exactly after ceil(u*_top / (dt K/(L m))) steps (2 and 4 steps here).
    """
    L, N, K, mass, dt = 8, 2, 4.0, 1.0, 0.5
    k = np.arange(L)[:, None]
    kappa = K * (L - k) / L * np.ones((L, N))
    u = 0.06 * (k + 1) * np.array([[1.0, 2.0]])  # shear rates differ between the two columns
    m, z = np.full((L, N), mass), zeros(L, N)
    decrement = dt * K / (L * mass)  # 0.25
    step = vertical_fipy.VerticalStep(vertical_fipy.column_mesh(N, n_layers=L))
    for n in range(1, 5):
        expected = np.maximum(u - decrement, 0.0)
        u = step(ColumnProblem(m=m, ustar=u, dt=dt, kappa=kappa, c=z, w=z, cw=z))
        np.testing.assert_allclose(u, expected, rtol=0, atol=1e-11)
        assert np.all((u == 0.0) == (expected == 0.0))
        stopped = np.all(u == 0.0, axis=0)
        np.testing.assert_array_equal(stopped, n >= np.ceil(0.06 * L * np.array([1.0, 2.0]) / decrement))


def test_bingham_column_has_a_rigid_plug_and_satisfies_kkt():
    """Constant yield stress and viscosity on every interface, no-slip base (c_0 > 0)."""
    L, N = 12, 3
    m = np.ones((L, N))
    ustar = np.ones((L, N)) * [[1.0, -2.0, 0.5]]
    dt, kappa, c, cw = 0.1, np.full((L, N), 2.0), np.full((L, N), 5.0), zeros(L, N)
    u = vertical_fipy.solve(ColumnProblem(m=m, ustar=ustar, dt=dt, kappa=kappa, c=c, w=zeros(L, N), cw=cw))
    assert_kkt(u, m, ustar, dt, kappa, c, cw)
    # the stress sum_{b > k} m/dt (u* - u) exceeds kappa = 2 only in the lowest interfaces:
    # the upper part is one plug, identical to the last bit (required: 1e-9)
    du = np.diff(u, axis=0)
    for i in range(N):
        plug = np.flatnonzero(du[:, i] != 0.0).max() + 1  # lowest layer of the plug
        assert 2 <= plug <= L - 3
        assert np.all(u[plug:, i] == u[plug, i])
        assert np.all(np.abs(u[:plug, i]) < np.abs(u[plug, i]))  # sheared zone below it


def test_u_step_is_the_dense_optimality_system_on_any_geometry():
    """The FiPy u-step solves (m/dt + cw + rw) u + D^T (c + r) D u = b + D^T g exactly."""
    rng = np.random.default_rng(3)
    L, N = 4, 3
    fractions = [0.4, 0.1, 0.3, 0.2]
    step = vertical_fipy.VerticalStep(vertical_fipy.column_mesh(N, fractions))
    inertia, conductance = rng.uniform(1, 3, (L, N)), rng.uniform(0, 2, (L, N))
    source, link_flux = rng.normal(size=(L, N)), rng.normal(size=(L, N))
    step.set_operator(inertia, conductance)
    u = step.solve_u(source, link_flux)
    D = np.eye(L) - np.eye(L, k=-1)  # (Du)_k = u_{k+1} - u_k, u_0 = 0
    for i in range(N):
        A = np.diag(inertia[:, i]) + D.T @ np.diag(conductance[:, i]) @ D
        exact = np.linalg.solve(A, source[:, i] + D.T @ link_flux[:, i])
        np.testing.assert_allclose(u[:, i], exact, rtol=0, atol=1e-13)


@pytest.mark.slow  # 8 s of FiPy solves
def test_reused_equation_equals_fresh_one_after_coefficients_change():
    """FiPy issue #1223: a cached stencil must follow changes of the coefficient variables.

    The u-step equation of a ``VerticalStep`` is built once; a step reused with new
    masses, time step, yield stresses and conductances must give the same u as a
    freshly built one, both for the bare u-step and the whole minimisation.
    """
    rng = np.random.default_rng(4)
    L, N = 5, 4
    mesh = vertical_fipy.column_mesh(N, n_layers=L)
    reused = vertical_fipy.VerticalStep(mesh)
    first = [rng.uniform(1, 2, (L, N)), rng.uniform(0, 1, (L, N))]
    second = [rng.uniform(5, 9, (L, N)), rng.uniform(3, 6, (L, N))]
    source, link_flux = rng.normal(size=(L, N)), rng.normal(size=(L, N))
    reused.set_operator(*first)
    before = reused.solve_u(source, link_flux)
    reused.set_operator(*second)
    reused.u.setValue(0.0)  # the same initial guess as the fresh equation
    fresh = vertical_fipy.VerticalStep(mesh)
    fresh.set_operator(*second)
    after = reused.solve_u(source, link_flux)
    assert np.abs(after - before).max() > 0.1
    np.testing.assert_array_equal(after, fresh.solve_u(source, link_flux))

    first_problem = ColumnProblem(
        m=rng.uniform(0.5, 2, (L, N)),
        ustar=rng.normal(size=(L, N)),
        dt=0.1,
        kappa=rng.uniform(0, 3, (L, N)),
        c=rng.uniform(0, 2, (L, N)),
        w=zeros(L, N),
        cw=zeros(L, N),
    )
    reused(first_problem)
    p = first_problem
    second_problem = ColumnProblem(
        m=3 * p.m, ustar=-p.ustar, dt=0.05, kappa=0.5 * p.kappa, c=4 * p.c, w=p.w, cw=p.cw
    )
    np.testing.assert_array_equal(reused(second_problem), vertical_fipy.VerticalStep(mesh)(second_problem))


@pytest.mark.slow
def test_dry_columns_and_non_convergence():
    L, N = 3, 2
    m = np.ones((L, N)) * [[1.0, 0.0]]
    z = zeros(L, N)
    kappa = np.full((L, N), 1.0)
    problem = ColumnProblem(m=m, ustar=np.full((L, N), 5.0), dt=0.1, kappa=kappa, c=z, w=z, cw=z)
    u = vertical_fipy.solve(problem)
    assert np.all(u[:, 1] == 0.0) and np.all(u[:, 0] > 0.0)
    with pytest.raises(RunError, match="did not converge"):
        vertical_fipy.solve(problem, max_iter=2)


def random_step(rng: np.random.Generator, L: int, N: int) -> ColumnProblem:
    """Random steps mixing static, plug and sheared layers, walls and viscosity."""
    m = rng.uniform(0.5, 2.0, (L, N))
    ustar = rng.normal(0.0, 1.0, (L, N)) + rng.normal(0.0, 1.0, N)
    kappa = rng.uniform(0.0, 4.0, (L, N)) * (rng.random((L, N)) < 0.8)
    c = rng.uniform(0.0, 3.0, (L, N)) * (rng.random((L, N)) < 0.5)
    w = rng.uniform(0.0, 2.0, (L, N)) * (rng.random((L, N)) < 0.4)
    cw = rng.uniform(0.0, 1.0, (L, N)) * (rng.random((L, N)) < 0.4)
    return ColumnProblem(m=m, ustar=ustar, dt=0.1, kappa=kappa, c=c, w=w, cw=cw)


@pytest.mark.parametrize(
    "rounds, N", [(1, 20), pytest.param(3, 40, marks=pytest.mark.slow)], ids=["short", "full"]
)
def test_agrees_with_the_fast_kernel(rounds, N):
    """The FiPy reference and multilayer/engine/column_kernel.py agree to 1e-10 on random steps.

    Same static layers (exact zeros) and same plugs (exactly equal neighbours).
    """
    rng = np.random.default_rng(2024)
    L = 8
    for _ in range(rounds):
        problem = random_step(rng, L, N)
        u = vertical_fipy.solve(problem)
        u_kernel = column_kernel.solve(problem)
        np.testing.assert_allclose(u, u_kernel, rtol=0, atol=1e-10)
        np.testing.assert_array_equal(u == 0.0, u_kernel == 0.0)
        np.testing.assert_array_equal(np.diff(u, axis=0) == 0.0, np.diff(u_kernel, axis=0) == 0.0)
