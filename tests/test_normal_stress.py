"""The longitudinal normal stress (``model.normal_stress``, engine/normal_stress.py): the
plastic limit of a uniformly stretched layer, the discrete energy inequality, momentum,
exact rest, and the scenario key."""

from __future__ import annotations

import numpy as np
import pytest

import multilayer
from multilayer.engine.normal_stress import Chains, chains, plastic_chain_step
from multilayer.errors import InputError
from multilayer.validation.runs import SCENARIOS

RHO, G, MU = 1500.0, 9.81, 0.5


def layer(cells: int = 30, layers: int = 2, thickness: float = 0.02, **model) -> multilayer.Simulation:
    """A uniform Coulomb layer (mu = MU) on a flat bed with the normal stress on."""
    return multilayer.Simulation(
        multilayer.load(
            {
                "name": "stretched-layer",
                "domain": {"x_min": 0.0, "x_max": 0.3, "cells": cells, "layers": layers},
                "material": {"density": RHO, "grain_diameter": 1e-3},
                "rheology": {"name": "drucker_prager", "mu_s": MU, "nu": 0.0},
                "initial": [{"shape": "layer", "thickness": thickness}],
                "time": {"end": 0.1, "output_interval": 0.05},
                "model": {"normal_stress": True, **model},
            }
        )
    )


def test_a_uniformly_stretched_layer_keeps_its_interior_and_its_ends_feel_the_yield_stress():
    """u* = e x from rest (no shear, B = 0): tau_xx = mu p is uniform, its divergence is zero
    inside and the end cells are pulled inwards by 2 dt mu pbar_a / (rho dx) (the plastic
    limit of Lagree, Staron & Popinet 2011, eq. 2.3, with |D| = |D_xx|)."""
    sim = layer()
    e, dt, h = 2.0, 1e-4, sim.h[0]
    ustar = np.tile(e * sim.x, (2, 1))
    at_rest = np.zeros_like(ustar)  # the lagged rate: D_xz = 0, every face plastic
    sim.normal_stress(sim.h, ustar, at_rest, None, dt, velocity_scale=1.0, max_iterations=50)
    depth = np.array([0.75, 0.25]) * h  # of the layer centres
    pull = 2 * dt * MU * RHO * G * depth / (RHO * sim.dx)
    assert pull.max() < e * sim.dx  # the ends do not lock to their neighbours
    expected = np.tile(e * sim.x, (2, 1))
    expected[:, 0] += pull
    expected[:, -1] -= pull
    np.testing.assert_allclose(ustar, expected, rtol=0, atol=1e-12)


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


@pytest.mark.parametrize("wide", [False, True])
@pytest.mark.parametrize("seed", range(5))
def test_the_step_dissipates_conserves_momentum_and_solves_the_plastic_law(seed, wide):
    """The discrete energy identity sum M (u^2 - u*^2)/2 = -sum M (u - u*)^2/2 - sum Z s with
    Z s >= 0 (dissipative), |Z| <= A, the momentum of each chain kept, and the law: Z = A s /
    sqrt(s^2 + B^2) on the smooth faces (checked as s = B Z / sqrt(A^2 - Z^2) to 1e-9 m/s where
    that is well conditioned, sgn(s) = sgn(Z) nearer the bound); on the plastic ones s = 0
    below the bound and sgn(s) = sgn(Z) at it."""
    ustar, mass, faces, a, b = random_problem(seed, wide=wide)
    u, z = plastic_chain_step(ustar, mass, faces, a, b, tolerance=1e-12, max_iterations=200)
    s = u[faces.right] - u[faces.left]
    energy = 0.5 * np.sum(mass * (u**2 - ustar**2))
    assert energy == pytest.approx(-0.5 * np.sum(mass * (u - ustar) ** 2) - np.sum(z * s), abs=1e-15)
    assert np.all(z * s >= -1e-14) and np.all(np.abs(z) <= a)
    half = ustar.size // 4  # the chains of each layer either side of the dry column
    for chain in (slice(0, half), slice(half + 1, 2 * half), slice(2 * half, 3 * half)):
        assert np.sum(mass[chain] * u[chain]) == pytest.approx(np.sum(mass[chain] * ustar[chain]), abs=1e-14)
    smooth = (b > 0) & (a > 0)
    inside = smooth & (np.abs(z) < a * (1 - 1e-6))  # where s(Z) = B Z / sqrt(A^2 - Z^2) is well conditioned
    rate = b[inside] * z[inside] / np.sqrt(a[inside] ** 2 - z[inside] ** 2)
    np.testing.assert_allclose(s[inside], rate, rtol=0, atol=1e-9)  # velocities (m/s)
    assert np.all(z[smooth & ~inside] * s[smooth & ~inside] > 0)
    plastic = ~smooth & (a > 0)
    below = plastic & (np.abs(z) < a * (1 - 1e-9))
    assert np.all(np.abs(s[below]) <= 1e-10)
    assert np.all(z[plastic & (np.abs(s) > 1e-10)] * s[plastic & (np.abs(s) > 1e-10)] > 0)


def test_material_at_rest_stays_exactly_at_rest():
    """u* = 0 gives u = 0 exactly, and a heap whose flanks (10 degrees) are below its friction
    angle stays exactly at rest with the normal stress on (no stress creates motion)."""
    ustar, mass, faces, a, b = random_problem(0)
    u, z = plastic_chain_step(np.zeros_like(ustar), mass, faces, a, b, tolerance=1e-12, max_iterations=5)
    assert np.all(u == 0.0) and np.all(z == 0.0)
    slope = np.tan(np.radians(10.0))
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
    heap.advance(0.05)
    assert heap.steps >= 10 and np.all(heap.u == 0.0)


def test_the_key_is_a_boolean_off_by_default_and_not_with_a_fluid(tiny_scenario):
    assert multilayer.Simulation(multilayer.load(tiny_scenario)).normal_stress is None
    with pytest.raises(InputError, match=r"model\.normal_stress.*accepted: true or false"):
        multilayer.load(tiny_scenario, {"model.normal_stress": "yes"})
    with pytest.raises(InputError, match=r"model\.normal_stress.*not supported with a fluid"):
        multilayer.load(SCENARIOS / "immersed_layer_loose.yaml", {"model.normal_stress": True})
