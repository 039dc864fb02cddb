"""The longitudinal normal stress (``model.normal_stress``, engine/normal_stress.py): the
plastic limit of a uniformly stretched layer, the discrete energy inequality, momentum,
exact rest, and the scenario key."""

from __future__ import annotations

from functools import partial
from pathlib import Path

import numpy as np
import pytest
from engine import collapse_deposit, deposit_beside_a_collapse
from scipy.integrate import quad

import multilayer
from multilayer.engine import simulation
from multilayer.engine.normal_stress import (
    PRESSURE_STEP,
    ROUNDING,
    TURN,
    Chains,
    barrier_change,
    chains,
    joint_rest,
    not_converged,
    plastic_chain_step,
    runs,
)
from multilayer.errors import InputError, RunError
from multilayer.validation.runs import SCENARIOS

RHO, G, MU = 1500.0, 9.81, 0.5
compiled_chain_step = partial(plastic_chain_step, compiled=True)
"""The step by the engine's kernel."""


def layer(
    cells: int = 30,
    layers: int = 2,
    thickness: float = 0.02,
    mu: float = MU,
    numerics: dict | None = None,
    rheology: dict | None = None,
    **model,
) -> multilayer.Simulation:
    """A uniform Coulomb layer (friction ``mu``; or of the law ``rheology``) on a flat bed
    with the normal stress on."""
    return multilayer.Simulation(
        multilayer.load(
            {
                "name": "stretched-layer",
                "domain": {"x_min": 0.0, "x_max": 0.3, "cells": cells, "layers": layers},
                "material": {"density": RHO, "grain_diameter": 1e-3},
                "rheology": rheology or {"name": "drucker_prager", "mu_s": mu, "nu": 0.0},
                "initial": [{"shape": "layer", "thickness": thickness}],
                "time": {"end": 0.1, "output_interval": 0.05},
                "model": {"normal_stress": True, **model},
                "numerics": numerics or {},
            }
        )
    )


@pytest.mark.parametrize("rate", [2.0, -2.0])
def test_a_uniformly_stretched_layer_keeps_its_interior_and_its_ends_feel_the_earth_pressure(rate):
    """u* = e x from rest (no shear, B = 0): tau_xx is uniform, its divergence is zero inside
    and the end cells are pulled inwards (stretched) or pushed outwards (compressed) by 2 dt
    tau_xx / (rho dx), with tau_xx = mu p sgn(D_xx) at the mean pressure p = P - tau_xx: mu P /
    (1 + mu) stretched, -mu P / (1 - mu) compressed (the plastic limit of Lagree, Staron &
    Popinet 2011, eq. 2.3, with |D| = |D_xx|; the active and passive earth pressures of a
    cohesionless material with sin(phi) = mu, Nedderman 1992, ch. 3)."""
    sim = layer()
    dt, h = 1e-4, sim.h[0]
    ustar = np.tile(rate * sim.x, (2, 1))
    at_rest = np.zeros_like(ustar)  # the lagged rate: D_xz = 0, every face plastic
    sim.normal_stress(sim.h, ustar, at_rest, None, dt, velocity_scale=1.0, max_iterations=50)
    depth = np.array([0.75, 0.25]) * h  # of the layer centres
    tau_xx = np.sign(rate) * MU * RHO * G * depth / (1 + np.sign(rate) * MU)
    pull = 2 * dt * tau_xx / (RHO * sim.dx)
    assert np.abs(pull).max() < abs(rate) * sim.dx  # the ends do not lock to their neighbours
    expected = np.tile(rate * sim.x, (2, 1))
    expected[:, 0] += pull
    expected[:, -1] -= pull
    np.testing.assert_allclose(ustar, expected, rtol=0, atol=1e-12)
    # the law holds at the mean pressure it leaves: |tau_xx| = mu (P - tau_xx), P at the centres
    found = sim.normal_stress.tau_xx
    np.testing.assert_allclose(found, np.tile(tau_xx[:, None], (1, sim.x.size)), rtol=1e-12)
    np.testing.assert_allclose(np.abs(found), MU * (RHO * G * depth[:, None] - found), rtol=1e-12)
    # and the vertical step sees the mean pressures P_k / (1 + mu) (stretched) or P_k / (1 - mu)
    # at every interface: one plastic state, tau_xx = mu p sgn(D_xx) at every depth
    mean = sim.normal_stress.yield_gravity(None, sim.h)
    np.testing.assert_allclose(mean, np.full(mean.shape, G / (1 + np.sign(rate) * MU)), rtol=1e-12)


def test_a_law_more_sensitive_to_the_pressure_than_the_pressure_itself_stops_the_run():
    """|d tau / d p| >= 1 has no bounded passive pressure: the step names the law's slope."""
    steep = layer(cells=10, mu=1.2)
    ustar = np.tile(steep.x, (2, 1))
    with pytest.raises(RunError, match=r"\|d tau / d p\| < 1\): d tau / d p = 1\.2 \+- [0-9.e-]+ at x = "):
        steep.normal_stress(
            steep.h, ustar, np.zeros_like(ustar), None, 1e-4, velocity_scale=1.0, max_iterations=50
        )


def test_the_bulk_law_at_the_three_pressures_is_asked_once():
    """tau_f and e_f = d tau / d p (the central differences of the yield stress and of the
    viscous stress) from one call of the law's hooks at p, p + dp and p - dp stacked are
    those of three calls, to the bit (the laws act point by point): the recommended collapse
    law, h_stop and all, at random rates, pressures (one zero), thicknesses and positions."""
    sim = multilayer.Simulation(
        multilayer.load(SCENARIOS / "column_collapse_channel.yaml", {"model.normal_stress": True})
    )
    rng = np.random.default_rng(1)
    rate, p = 10.0 ** rng.uniform(-3, 2, 50), rng.uniform(0.0, 2000.0, 50)
    p[0] = 0.0
    h, x, layers = rng.uniform(1e-3, 0.1, 50), rng.uniform(0.0, 0.3, 50), rng.integers(0, 8, 50)
    tau, e = sim.normal_stress.bulk_law(rate, p, h, x, layers)
    parts, dp = sim.normal_stress.stresses.bulk_parts, PRESSURE_STEP * p
    assert np.array_equal(tau, sim.normal_stress.stresses.bulk_stress(rate, p, h, x))
    (kappa_up, viscous_up), (kappa_down, viscous_down) = parts(rate, p + dp, h, x), parts(rate, p - dp, h, x)
    change = (kappa_up - kappa_down) + (viscous_up - viscous_down)
    step = (p + dp) - (p - dp)
    assert np.array_equal(e, np.divide(change, step, out=np.zeros(50), where=dp > 0)) and e[0] == 0.0


def test_a_viscous_stress_far_above_the_pressure_leaves_the_friction_s_slope():
    """A Drucker-Prager face at a thin front: a pressure of 1e-3 to 1 Pa and a viscous stress
    rho nu rate up to 4.5e11 Pa (nu = 3 m^2/s, shear rates to 1e8 1/s, as in a free-slip
    collapse's front layers), independent of the pressure: d tau / d p = mu_s, not its round-off
    eps tau / dp (one difference of the sum gave 1.08 for mu_s = 0.3 and stopped the run)."""
    sim = layer(cells=10, rheology={"name": "drucker_prager", "mu_s": MU, "nu": 3.0})
    rate, p = (grid.ravel() for grid in np.meshgrid(10.0 ** np.arange(4, 9), 10.0 ** np.arange(-3.0, 1.0)))
    tau, e = sim.normal_stress.bulk_law(rate, p, np.full(p.size, 1e-5), np.zeros(p.size), np.zeros(p.size))
    np.testing.assert_allclose(tau, MU * p + RHO * 3.0 * rate, rtol=1e-15)
    np.testing.assert_allclose(e, MU, rtol=1e-10)


def test_a_free_slip_column_with_a_large_viscosity_runs():
    """The column of a free-slip collapse (Drucker-Prager, mu_s = 0.3, nu = 3 m^2/s, 25 deg)
    with the normal stress on: its front layers are sheared at 1e7 1/s under 0.02 Pa, and
    one difference of the sum kappa + eta rate stopped it at 0.3 s with d tau / d p = 1.08."""
    sim = multilayer.Simulation(
        multilayer.load(
            {
                "name": "free-slip-viscous",
                "slope_deg": 25.0,
                "domain": {"x_min": 0.0, "x_max": 0.5, "cells": 40, "layers": 8},
                "material": {"density": RHO, "grain_diameter": 1.0e-3},
                "rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 3.0},
                "base": [{"condition": "free_slip"}],
                "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05}],
                "boundaries": {"left": "wall", "right": "outflow"},
                "time": {"end": 0.5, "output_interval": 0.25},
                "model": {"normal_stress": True},
            }
        )
    )
    sim.advance(0.5)
    assert sim.t == 0.5


def test_a_law_steeper_than_one_beyond_its_round_off_stops_the_run(monkeypatch):
    """A power-law mu(I) = mu_s + m I^alpha (Tsang, Dalziel & Vriend 2019, J. Fluid Mech.
    872) has d tau / d p = mu_s + m (1 - alpha / 2) I^alpha, above 1 at large inertial numbers
    I = d rate / sqrt(p / rho_p): refused at 1.5, its viscous stress 1.8 p.  A slope of 1.5
    beside a viscous stress 1e12 times the pressure (its round-off bound 3e-2 / 1e-4 p) is
    not resolved: refused too, saying so."""
    m, alpha = 0.56, 0.34
    sim = layer(cells=10, rheology={"name": "power_law_mu_i", "mu_s": 0.0, "m": m, "alpha": alpha})
    inertial = (1.5 / (m * (1 - alpha / 2))) ** (1 / alpha)  # d tau / d p = 1.5
    p = np.array([2.0])
    rate = inertial * np.sqrt(p / RHO) / 1e-3
    where = (np.full(1, 1e-2), np.full(1, 0.1), np.zeros(1))
    with pytest.raises(RunError, match=r"d tau / d p = 1\.5 \+- [0-9.e-]+ at x = 0\.1 m"):
        sim.normal_stress.bulk_law(rate, p, *where)

    def parts(rate, pressure, h, x):
        return 1.5 * pressure, np.full(pressure.shape, 2e12)

    monkeypatch.setattr(sim.normal_stress.stresses, "bulk_parts", parts)
    with pytest.raises(RunError, match=r"d tau / d p = 1\.5 \+- [0-9.]+, not resolved from the round-off"):
        sim.normal_stress.bulk_law(rate, p, *where)


def integrand(phi: float, e: float) -> float:
    """The reference integrand of :func:`barrier_change`."""
    return float(np.sin(phi) / (1 + e * np.sin(phi)) ** 2)


def magnitude(phi: float, e: float) -> float:
    return abs(integrand(phi, e))


@pytest.mark.filterwarnings("ignore::scipy.integrate.IntegrationWarning")
@pytest.mark.parametrize("e", [0.0, 0.3, 0.6, 0.8, 0.9, -0.8])
def test_the_dual_term_s_change_is_its_integral(e):
    """barrier_change is the integral of sin(phi) / (1 + e sin(phi))^2 (scipy's adaptive
    quadrature as the reference) to 1e-15 of the integral of its absolute value for |e| <= 0.8
    and 1e-12 at e = 0.9, over changes of phi up to TURN anywhere in [-pi/2, pi/2]."""
    bound = 1e-15 if abs(e) <= 0.8 else 1e-12
    for start in np.linspace(-0.5 * np.pi, 0.5 * np.pi - TURN, 25):
        for width in (TURN, 0.1, 1e-3):
            exact = quad(integrand, start, start + width, args=(e,), epsabs=0, epsrel=1e-13)[0]
            scale = quad(magnitude, start, start + width, args=(e,), epsabs=0, epsrel=1e-13)[0]
            found = barrier_change(np.array([start]), np.array([start + width]), np.array([e]))[0]
            assert abs(found - exact) <= bound * scale + 1e-300


def random_problem(
    seed: int, n: int = 40, wide: bool = False
) -> tuple[np.ndarray, np.ndarray, Chains, np.ndarray, np.ndarray]:
    """Two layers of ``n`` columns with a dry gap, random velocities, masses and stresses,
    half of the faces plastic (B = 0); ``wide``: masses, A_f and B_f over many decades, as at
    a front (thin columns) and near the plastic limit (B_f << |s_f|)."""
    rng = np.random.default_rng(seed)
    wet = np.ones(n, dtype=bool)
    wet[n // 2] = False
    faces = chains(wet, 2)
    m = 10.0 ** rng.uniform(-9, -1, 2 * n) if wide else rng.uniform(0.01, 0.1, 2 * n)
    mass = np.where(np.tile(wet, 2), m, 1.0)
    ustar = np.where(np.tile(wet, 2), rng.normal(0.0, 0.5, 2 * n), 0.0)
    k = faces.left.size
    a = 10.0 ** rng.uniform(-13, -1.5, k) if wide else rng.uniform(0.0, 0.02, k)
    b = np.where(
        rng.random(k) < 0.5, 0.0, 10.0 ** rng.uniform(-8, 2, k) if wide else rng.uniform(0.0, 0.05, k)
    )
    return ustar, mass, faces, a, b


@pytest.mark.parametrize("sensitive", [False, True])
@pytest.mark.parametrize("wide", [False, True])
@pytest.mark.parametrize("seed", range(5))
def test_the_step_dissipates_conserves_momentum_and_solves_the_plastic_law(seed, wide, sensitive):
    """The discrete energy identity sum M (u^2 - u*^2)/2 = -sum M (u - u*)^2/2 - sum Z s with
    Z s >= 0 (dissipative), -A/(1 - e) <= Z <= A/(1 + e), the momentum of each chain kept,
    and the law: Z = A c / (1 + e c), c = s / sqrt(s^2 + B^2), on the smooth faces (checked
    as s = B c / sqrt(1 - c^2), c = Z / (A - e Z), to 1e-9 m/s where that is well
    conditioned, sgn(s) = sgn(Z) nearer the bounds); on the plastic ones s = 0 inside the
    bounds and sgn(s) = sgn(Z) at them; ``sensitive``: random pressure sensitivities e in
    (-0.8, 0.8), else e = 0.  Solved to 1e-14 m/s: on a light face the inverse law s(Z) is
    ill-conditioned (ds/dZ up to 1e6 s/kg here)."""
    ustar, mass, faces, a, b = random_problem(seed, wide=wide)
    e = np.random.default_rng(seed + 100).uniform(-0.8, 0.8, a.size) if sensitive else np.zeros(a.size)
    u, z = plastic_chain_step(ustar, mass, faces, a, b, e, tolerance=1e-14, max_iterations=200)
    s = u[faces.right] - u[faces.left]
    energy = 0.5 * np.sum(mass * (u**2 - ustar**2))
    assert energy == pytest.approx(-0.5 * np.sum(mass * (u - ustar) ** 2) - np.sum(z * s), abs=1e-15)
    low, high = -a / (1 - e), a / (1 + e)
    assert np.all(z * s >= -1e-14) and np.all((low <= z) & (z <= high))
    half = ustar.size // 4  # the chains of each layer either side of the dry column
    for chain in (slice(0, half), slice(half + 1, 2 * half), slice(2 * half, 3 * half)):
        assert np.sum(mass[chain] * u[chain]) == pytest.approx(np.sum(mass[chain] * ustar[chain]), abs=1e-14)
    smooth = (b > 0) & (a > 0)
    c = np.divide(z, a - e * z, out=np.zeros(a.size), where=smooth)
    inside = smooth & (np.abs(c) < 1 - 1e-6)  # where s(Z) is well conditioned
    rate = b[inside] * c[inside] / np.sqrt(1 - c[inside] ** 2)
    # to 1e-9 m/s, or to the round-off of the impulses on a face's cells (a thin cell between
    # thick ones: the step's documented floor, ROUNDING)
    held = np.zeros(ustar.size)
    np.add.at(held, faces.left, np.abs(z))
    np.add.at(held, faces.right, np.abs(z))
    floor = ROUNDING * np.finfo(float).eps * (held / mass + np.abs(ustar))
    bound = np.maximum(1e-9, floor[faces.left] + floor[faces.right])[inside]
    assert np.all(np.abs(s[inside] - rate) <= bound)  # velocities (m/s)
    assert np.all(z[smooth & ~inside] * s[smooth & ~inside] > 0)
    plastic = ~smooth & (a > 0)
    below = plastic & (z < high * (1 - 1e-9)) & (z > low * (1 - 1e-9))
    assert np.all(np.abs(s[below]) <= 1e-10)
    assert np.all(z[plastic & (np.abs(s) > 1e-10)] * s[plastic & (np.abs(s) > 1e-10)] > 0)


@pytest.mark.parametrize("sensitive", [False, True])
@pytest.mark.parametrize("wide", [False, True])
@pytest.mark.parametrize("seed", range(5))
def test_the_compiled_step_is_the_reference_step(seed, wide, sensitive):
    """The compiled kernel (normal_stress_kernel.chain_step, its own Thomas solve of the Newton
    steps) gives the numpy reference's velocities to 1e-12 m/s, or to the round-off floor of a
    velocity below which both iterations stop (ROUNDING eps (sum |Z| / M + |u*|) on its cell: a
    light cell between heavily loaded faces), and impulses to 1e-12 of A_f on the random
    problems above (dry gaps, half the faces plastic, up to 8 decades), both solved to 1e-14
    m/s: the two are the same algorithm, their sums taken in different orders, and numba
    compiles for the host's processor, which rounds them its own way (on an AMD EPYC the two
    differed by 1.1e-12 m/s on a cell whose floor is 4.8e-10 m/s, at most 6 % of the floor
    on every cell of these problems)."""
    ustar, mass, faces, a, b = random_problem(seed, wide=wide)
    e = np.random.default_rng(seed + 100).uniform(-0.8, 0.8, a.size) if sensitive else 0.0
    expected = plastic_chain_step(ustar, mass, faces, a, b, e, tolerance=1e-14, max_iterations=200)
    u, z = compiled_chain_step(ustar, mass, faces, a, b, e, tolerance=1e-14, max_iterations=200)
    held = np.zeros(ustar.size)
    np.add.at(held, faces.left, np.abs(expected[1]))
    np.add.at(held, faces.right, np.abs(expected[1]))
    floor = ROUNDING * np.finfo(float).eps * (held / mass + np.abs(ustar))
    assert np.all(np.abs(u - expected[0]) <= np.maximum(1e-12, floor))
    assert np.all(np.abs(z - expected[1]) <= 1e-12 * a)


def test_the_kernel_has_one_signature_whatever_the_callers_arrays():
    """A pressure sensitivity ``e`` given as one number (broadcast, copied) or as an array
    (broadcast, a read-only view), and read-only or strided velocities and masses, call the
    kernel with one signature: numba compiled a second one for the read-only ``e`` of runs,
    some 6 s at the first use of each."""
    from multilayer.engine.normal_stress_kernel import chain_step

    ustar, mass, faces, a, b = random_problem(0)
    frozen = np.repeat(ustar, 2)[::2]  # strided
    mass = mass.copy()
    mass.flags.writeable = False
    for e in (0.0, np.full(a.size, 0.2)):
        compiled_chain_step(ustar, mass, faces, a, b, e, tolerance=1e-14, max_iterations=200)
        compiled_chain_step(frozen, mass, faces, a, b, e, tolerance=1e-14, max_iterations=200)
    assert len(chain_step.signatures) == 1, chain_step.signatures


def test_the_compiled_step_on_one_face_at_rest_and_without_convergence():
    """A chain of one face per layer (two wet columns), stretched plastic (B = 0) or smooth:
    the kernel gives the reference's answer, which conserves momentum with u_2 - u_1 = 0 or
    the plastic impulse Z = A / (1 + e) (the active limit); u* = 0 stays exactly 0; and a step
    cut short of convergence raises the reference's message."""
    wet = np.array([False, True, True, False])
    faces = chains(wet, 2)
    assert faces.left.size == 2 and not faces.linked.any()
    mass = np.array([1.0, 0.02, 0.03, 1.0, 1.0, 0.01, 0.05, 1.0])
    ustar = np.array([0.0, -0.5, 0.5, 0.0, 0.0, -0.3, 0.4, 0.0])
    a, e = np.array([1e-3, 2e-3]), np.array([0.3, -0.2])
    for b in (np.zeros(2), np.array([0.01, 0.1])):
        expected = plastic_chain_step(ustar, mass, faces, a, b, e, tolerance=1e-14, max_iterations=50)
        u, z = compiled_chain_step(ustar, mass, faces, a, b, e, tolerance=1e-14, max_iterations=50)
        np.testing.assert_allclose(u, expected[0], rtol=0, atol=1e-12)
        assert np.all(np.abs(z - expected[1]) <= 1e-12 * a)
        assert np.all(u[~np.tile(wet, 2)] == 0.0)  # the dry cells feel nothing
        for layer in (slice(1, 3), slice(5, 7)):
            assert np.sum(mass[layer] * u[layer]) == pytest.approx(
                np.sum(mass[layer] * ustar[layer]), abs=1e-15
            )
        if not b.any():  # the stretches exceed what the plastic limit can stop
            np.testing.assert_allclose(z, a / (1 + e), rtol=1e-12)
    u, z = compiled_chain_step(np.zeros(8), mass, faces, a, b, e, tolerance=1e-12, max_iterations=5)
    assert np.all(u == 0.0) and np.all(z == 0.0)
    ustar, mass, faces, a, b = random_problem(3, wide=True)
    for step in (plastic_chain_step, compiled_chain_step):
        with pytest.raises(RunError, match=r"^the normal-stress step did not converge in 2 iterations "):
            step(ustar, mass, faces, a, b, tolerance=1e-14, max_iterations=2)


@pytest.mark.slow
def test_the_step_converges_on_random_problems_over_many_decades():
    """240 random problems (masses, A_f and B_f over up to 8 decades, half with random
    pressure sensitivities in (-0.8, 0.8)) all converge to 1e-12 m/s: the claim of the
    module's docstring."""
    for seed in range(120):
        for sensitive in (False, True):
            ustar, mass, faces, a, b = random_problem(1000 + seed, wide=True)
            e = np.random.default_rng(seed + 5000).uniform(-0.8, 0.8, a.size) if sensitive else 0.0
            plastic_chain_step(ustar, mass, faces, a, b, e, tolerance=1e-12, max_iterations=200)
    # the problems of the default tests, whose seed 8 stalled before the stall rule (STALL)
    for seed in range(10):
        ustar, mass, faces, a, b = random_problem(seed, wide=True)
        e = np.random.default_rng(seed + 100).uniform(-0.8, 0.8, a.size)
        for step in (plastic_chain_step, compiled_chain_step):
            step(ustar, mass, faces, a, b, e, tolerance=1e-12, max_iterations=200)


def test_a_step_that_stalled_in_a_collapse_converges_and_the_kernel_agrees():
    """The step of a channel collapse (a = 10, 2 mm cells, 8 layers, t = 0.685 s; 3040 cells,
    3032 faces) on which the projected Newton method stalled: a chain of plastic faces met its
    bounds along a path that another chain's angles cut short, every iteration.  After a
    stalled step the scaled gradient step goes first (STALL): the reference and the kernel
    converge to the run's tolerance and agree to 1e-12 m/s."""
    d = np.load(Path(__file__).parent / "data" / "normal_stress_stall.npz")
    faces = Chains(d["left"], d["right"], d["linked"])
    problem = (d["ustar"], d["mass"], faces, d["a"], d["b"], d["e"])
    u, z = plastic_chain_step(*problem, tolerance=float(d["tol"]), max_iterations=200)
    uk, zk = compiled_chain_step(*problem, tolerance=float(d["tol"]), max_iterations=200)
    assert np.abs(uk - u).max() <= 1e-12
    s = u[faces.right] - u[faces.left]
    assert np.all(z * s >= -1e-14)


@pytest.mark.parametrize("degrees", [10.0, 21.0])
def test_material_at_rest_stays_exactly_at_rest(degrees):
    """u* = 0 gives u = 0 and Z = 0 exactly, and a heap whose flanks are below what its
    kinks hold (atan(0.8 mu) = 21.8 deg at order 2, docs/model.md, "Rest") stays exactly at
    rest at every step with the normal stress on, also at 21 deg, steeper than the friction
    of its active mean pressure, atan(mu / (1 + mu)) = 18.4 deg: the normal stress follows
    the vertical step, which holds the heap at the full pressure, and exerts no stress on
    material at rest (no stress creates motion)."""
    ustar, mass, faces, a, b = random_problem(0)
    u, z = plastic_chain_step(np.zeros_like(ustar), mass, faces, a, b, tolerance=1e-12, max_iterations=5)
    assert np.all(u == 0.0) and np.all(z == 0.0)
    slope = np.tan(np.radians(degrees))
    assert MU / (1 + MU) < np.tan(np.radians(21.0)) < 0.8 * MU
    heap = multilayer.Simulation(
        multilayer.load(
            {
                "name": "heap",
                "domain": {"x_min": 0.0, "x_max": 0.4, "cells": 80, "layers": 4},
                "material": {"density": RHO, "grain_diameter": 1e-3},
                "rheology": {"name": "drucker_prager", "mu_s": MU, "nu": 0.0},
                "initial": [{"shape": "profile", "points": [[0.1, 0.0], [0.2, 0.1 * slope], [0.3, 0.0]]}],
                "time": {"end": 0.1, "output_interval": 0.05},
                "model": {"normal_stress": True},
            }
        )
    )
    h0 = heap.h.copy()
    for _ in range(10):
        heap.step()
        assert np.all(heap.u == 0.0) and np.all(heap.h == h0) and np.all(heap.normal_stress.relief == 0.0)


class Recorded:
    """A normal-stress step that records its time step and the velocities it is given."""

    def __init__(self, step, seen: list):
        self.step, self.seen = step, seen

    def __call__(self, h, ustar, u, yield_gravity, dt, **kwargs):
        self.seen.append(("normal", dt, ustar.copy()))
        self.step(h, ustar, u, yield_gravity, dt, **kwargs)

    def __getattr__(self, name):
        return getattr(self.step, name)


@pytest.mark.parametrize("order", [1, 2])
def test_the_normal_stress_acts_over_the_step_as_the_vertical_step_does(order, monkeypatch):
    """In each stage the normal stress follows the vertical step, on its velocities, over the
    same time: dt at first order; dt, then dt/2 after Heun's average at second order
    (engine/simulation.py), so that it acts over dt/2 + dt/2 to first order, as the friction;
    the search for rest of the two together follows each (abandoned here: a stretched flow)."""
    sim = layer(numerics={"order": order})
    seen: list[tuple[str, float, np.ndarray]] = []
    vertical_step = sim._vertical_step
    searching: list[bool] = []

    def recorded(h, ustar, dt, threads, first=None, *, last=False):
        u, iterations = vertical_step(h, ustar, dt, threads, first, last=last)
        seen.append(("vertical", dt, u.copy()))
        return u, iterations

    def search(*args):
        searching.append(True)
        start = len(seen)
        found = joint_rest(*args)
        seen[start:] = [("search", dt, u) for _, dt, u in seen[start:]]
        return found

    monkeypatch.setattr(sim, "_vertical_step", recorded)
    monkeypatch.setattr(sim, "normal_stress", Recorded(sim.normal_stress, seen))
    monkeypatch.setattr(simulation, "joint_rest", search)
    sim.u[:] = np.linspace(-1.0, 1.0, sim.x.size)  # stretched: the stress is felt
    dt = sim.step()
    assert len(searching) == order and np.all(sim.u != 0.0)
    seen = [record for record in seen if record[0] != "search"]
    assert [kind for kind, _, _ in seen] == ["vertical", "normal"] * order
    assert [step for _, step, _ in seen] == ([dt, dt] if order == 1 else [dt, dt, 0.5 * dt, 0.5 * dt])
    for (_, _, after_vertical), (_, _, before_normal) in zip(seen[::2], seen[1::2], strict=True):
        assert np.array_equal(after_vertical, before_normal)


@pytest.mark.parametrize(
    ("load", "bound", "rest"), [(0.3, 0.25, True), (0.39, 1.0, True), (0.3, 0.15, False), (0.5, 1.0, False)]
)
def test_rest_of_the_two_steps_together_is_found_exactly_where_it_is_their_answer(load, bound, rest):
    """Three cells of unit mass, u* = (load, 0, 0); V leaves each velocity less its friction
    impulse (0.1, 0.15, 0.15; at rest within it), N_0 has its faces plastic, |Z| <= bound.
    Rest is the answer of the two together where the statics close: the first face carries
    load - 0.1 <= bound and the three frictions hold the load, <= 0.4.  Then the search finds
    q with V(u* - q) == 0 exactly, q the velocity change of impulses within the bounds (no
    momentum: sum q = 0); else none."""
    friction = np.array([0.1, 0.15, 0.15])
    ustar, mass, faces = np.array([load, 0.0, 0.0]), np.ones(3), chains(np.ones(3, dtype=bool), 1)

    def vertical(w):
        return np.sign(w) * np.maximum(np.abs(w) - friction, 0.0)

    def normal(w):
        return plastic_chain_step(
            w, mass, faces, np.full(2, bound), np.zeros(2), tolerance=1e-14, max_iterations=50
        )[0]

    assert np.any(vertical(ustar))  # V alone does not hold it
    q = joint_rest(vertical, normal, ustar, normal(vertical(ustar)), np.zeros(3), mass, 200)
    assert (q is not None) == rest
    if rest:
        assert np.all(vertical(ustar - q) == 0.0) and abs(q.sum()) < 1e-16
        impulses = -np.cumsum(q)[:2]  # Z_f: the change of the cells left of each face
        assert np.all(np.abs(impulses) <= bound * (1 + 1e-12))


def test_a_search_for_rest_whose_step_does_not_converge_is_abandoned_not_the_run():
    """The search is an addition to the split step: a step in it that does not converge
    (its Newton iteration) ends the search without a certificate, not the run."""

    def stuck(w):
        raise not_converged(5)

    ustar = np.array([0.3, 0.0, 0.0])
    assert joint_rest(lambda w: 0.5 * w, stuck, ustar, np.zeros(3), np.zeros(3), np.ones(3), 10) is None


def test_a_collapse_deposit_comes_exactly_to_rest_and_a_resumed_run_stays_there():
    """The deposit of a collapse comes to rest, u == 0.0 exactly, held by friction and the
    normal stress together (tau_xx != 0 at rest: the vertical step alone would not hold
    it); the split steps alone left it creeping at 5e-5 m/s at t = 0.8 s.  A run resumed at
    rest goes on as the uninterrupted one, bit for bit."""
    whole = collapse_deposit()
    whole.advance(0.3)
    assert np.all(whole.u == 0.0) and np.any(whole.normal_stress.relief != 0.0)
    saved = whole.state_dict()
    resumed = collapse_deposit()
    resumed.load_state(saved)
    for sim in (whole, resumed):
        sim.advance(0.35)
    assert np.all(whole.u == 0.0) and np.array_equal(whole.h, resumed.h)
    assert np.array_equal(whole.normal_stress.relief, resumed.normal_stress.relief)
    assert np.array_equal(whole.h, saved["h"])  # nothing moved
    alone = collapse_deposit()
    alone.load_state(saved)
    alone.normal_stress = None  # the vertical step alone, at the full pressure
    alone.step()
    assert np.any(alone.u != 0.0)


def test_a_deposit_stays_exactly_at_rest_beside_a_chain_that_flows_then_rests():
    """The collapse deposit at rest (u == 0.0, held by friction and the normal stress
    together) with a second column collapsing beyond its dry front: the two chains are
    independent (the normal stress couples the columns of a chain only, the vertical step
    none), so rest stays the answer of the deposit's two steps together, and the search,
    chain by chain, finds it: u == 0.0 in the deposit at every step while the new column
    flows at 0.02-0.14 m/s (to t = 0.41 s), and nothing of the deposit moves.  A search
    over the whole domain left the deposit creeping at 1.1e-4 to 1.5e-4 m/s while the
    other flowed.

    The new column then comes to rest by itself (u == 0.0 in its chain) and from then on
    stays exactly at rest (to t = 0.5 s): its certificate, ``V(u* - q) == 0``, is taken as
    soon as it holds.  When only the 1 % margin's iterates were checked, the search was
    abandoned at the round-off one round before they certified rest, and the pile set off
    again at 2e-5 m/s for 26 steps after its first rest."""
    sim, deposit = deposit_beside_a_collapse()
    h = sim.h[deposit].copy()
    other = np.ones(sim.h.shape[-1], dtype=bool)
    other[deposit] = False
    speeds, rested = [], False
    while sim.t < 0.5:
        flowing = sim.t < 0.41  # the step starts before 0.41 s
        sim.step()
        if flowing:
            assert len(runs(sim.h > sim.dry)) == 2  # two chains throughout
            assert np.all(sim.u[:, deposit] == 0.0)
            speeds.append(np.abs(sim.u).max())
            if sim.t >= 0.41:  # nothing of the deposit moved, held by its normal stress
                assert np.array_equal(sim.h[deposit], h)
                assert np.any(sim.normal_stress.relief[:, deposit] != 0.0)
        at_rest = not np.any(sim.u[:, other])
        assert at_rest or not rested, f"set off again at t = {sim.t} s"
        rested = rested or at_rest
    assert len(speeds) >= 25 and min(speeds) > 0.02
    assert rested and not np.any(sim.u)


def test_the_relief_is_bounded_by_the_plastic_limits_at_a_front():
    """r = tau_xx / p, the mean of a cell's faces' ratios, lies within the active and passive
    limits mu / (1 + mu) and -mu / (1 - mu) however thin a cell beside a thick one (a cell's
    own P, far below its faces', gave r = -7.5e25 and a vertical step's pressure 7e26 g)."""
    sim = layer(cells=30, layers=2)
    sim.h[:] = np.where(sim.x < 0.15, 0.02, 2e-6)  # a step down to 2 micrometres
    for rate in (5.0, -5.0):
        ustar = np.tile(rate * sim.x, (2, 1))
        sim.normal_stress(
            sim.h, ustar, np.zeros_like(ustar), None, 1e-4, velocity_scale=1.0, max_iterations=50
        )
        relief = sim.normal_stress.relief
        assert np.all(relief <= MU / (1 + MU) * (1 + 1e-12)) and np.all(
            relief >= -MU / (1 - MU) * (1 + 1e-12)
        )
        assert np.abs(relief).max() > 0.9 * MU / (1 + MU)  # at the limit where it stretches


def test_a_resumed_run_with_the_normal_stress_equals_the_uninterrupted_one():
    """The relief is part of the state: a run restored from a state saved mid-run goes on as
    the uninterrupted one, bit for bit."""
    scenario = multilayer.load(SCENARIOS / "column_collapse_channel.yaml", {"model.normal_stress": True})
    whole = multilayer.Simulation(scenario)
    whole.advance(0.01)
    saved = whole.state_dict()
    assert np.any(saved["normal_stress_relief"] != 0.0)
    resumed = multilayer.Simulation(scenario)
    resumed.load_state(saved)
    for sim in (whole, resumed):
        sim.advance(0.02)
    assert np.array_equal(whole.u, resumed.u) and np.array_equal(whole.h, resumed.h)
    with pytest.raises(InputError, match="normal_stress_relief"):
        resumed.load_state(
            {**saved, "normal_stress_relief": np.full_like(saved["normal_stress_relief"], np.nan)}
        )


def test_the_key_is_a_boolean_off_by_default_and_not_with_a_fluid(tiny_scenario):
    assert multilayer.Simulation(multilayer.load(tiny_scenario)).normal_stress is None
    with pytest.raises(InputError, match=r"model\.normal_stress.*accepted: true or false"):
        multilayer.load(tiny_scenario, {"model.normal_stress": "yes"})
    with pytest.raises(InputError, match=r"model\.normal_stress.*not supported with a fluid"):
        multilayer.load(SCENARIOS / "immersed_layer_loose.yaml", {"model.normal_stress": True})


@pytest.mark.parametrize("steps", [0, 10])
def test_a_step_redone_shorter_equals_the_step_taken_directly(steps):
    """A step redone shorter (``Simulation._courant_check``) or with more material moving
    starts from the normal stress of the last step kept, whose relief the first vertical
    step's mean pressures read: the redone step is the step taken directly at the shorter
    step to the bit (the collapse with the normal stress, from its start and flowing).
    Before, its attempts started from the discarded attempt's relief: 1.6e-7 m of h and
    2.2e-4 m/s of u apart after one step."""
    redone, direct = collapse_deposit(), collapse_deposit()
    for _ in range(steps):
        redone.step()
        direct.step()
    tried: list[float] = []

    def shorter_once(dt: float, speed: float) -> float | None:
        tried.append(dt)
        # the step that lands on t + dt/2, as the direct step below takes it
        return (redone.t + 0.5 * dt) - redone.t if len(tried) == 1 else None

    redone._courant_check = shorter_once  # type: ignore[method-assign]
    redone.step()
    direct.step(direct.t + 0.5 * tried[0])
    assert len(tried) == 2 and np.any(redone.normal_stress.relief)
    for a, b in (
        (redone.h, direct.h),
        (redone.u, direct.u),
        (redone.normal_stress.relief, direct.normal_stress.relief),
    ):
        np.testing.assert_array_equal(a, b)
