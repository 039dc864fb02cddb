"""Exact rest (Bouchut, Ionescu & Mangeney 2016, sec. 4.1): material whose driving
stress stays below the yield stress never moves, neither by transport nor by the
vertical step."""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine import simulation

from multilayer.engine.transport import reference as transport

JOP = {"name": "jop_mu_i", "mu_s": math.tan(math.radians(26.0)), "mu_2": 0.7, "I_0": 0.279}
DRUCKER_PRAGER = {"name": "drucker_prager", "mu_s": math.tan(math.radians(26.0)), "nu": 5e-5}


def held(sim, steps: int) -> tuple[float, float]:
    h0 = sim.h.copy()
    for _ in range(steps):
        sim.step()
    return float(np.abs(sim.u).max()), float(np.abs(sim.h - h0).max())


@pytest.mark.slow
@pytest.mark.parametrize("rheology", [JOP, DRUCKER_PRAGER], ids=["jop_mu_i", "drucker_prager"])
def test_heap_below_the_friction_angle_on_an_inclined_no_slip_bed(rheology):
    """A triangular heap with flanks of slope 0.1 on a 10 degree plane: the driving
    slope tan(10) + 0.1 = 0.28 stays below mu_s = tan(26) = 0.49 everywhere."""
    sim = simulation(
        slope_deg=10.0,
        domain={"x_min": -0.5, "x_max": 2.5, "cells": 100, "layers": 8},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        rheology=rheology,
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "profile", "points": [[0.0, 0.0], [1.0, 0.1], [2.0, 0.0]]}],
    )
    max_u, max_dh = held(sim, 3000)
    assert max_u == 0.0
    assert max_dh <= 1e-12
    assert sim.steps == 3000


def layer_on_a_slope(slope_deg: float, cells: int):
    """A 5 cm layer on a periodic slope, Jop mu(I) with mu_s = tan(26 deg) = 0.49."""
    return simulation(
        slope_deg=slope_deg,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": cells, "layers": 8},
        material={"density": 1550.0, "grain_diameter": 0.7e-3},
        rheology=JOP,
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "layer", "thickness": 0.05}],
        boundaries={"left": "periodic", "right": "periodic"},
    )


def test_uniform_layer_on_a_slope_below_the_friction_angle():
    """tan(20 deg) = 0.36 < mu_s: the layer stays put.  Its last step leaves h and u as
    they were to the bit: the state is a fixed point of the step, which every later step
    repeats (3000 steps held it as 300 do)."""
    sim = layer_on_a_slope(20.0, cells=50)
    max_u, max_dh = held(sim, 299)
    h, u = sim.h.copy(), sim.u.copy()
    sim.step()
    assert max_u == 0.0
    assert max_dh <= 1e-12
    assert np.array_equal(sim.h, h) and np.array_equal(sim.u, u)


def test_the_same_layer_above_the_friction_angle_flows():
    """The converse: at 28 degrees (tan = 0.53 > 0.49) the layer accelerates."""
    sim = layer_on_a_slope(28.0, cells=10)
    held(sim, 20)
    assert np.all(sim.u[-1] > 0.0)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("bed", ["flat, with dry columns", "bumpy, under a wet layer"])
def test_a_column_at_rest_feels_the_mean_of_its_two_discrete_free_surface_slopes(bed, order):
    """The discrete property behind exact rest (transport/reference.py): from a state at
    rest, a transport stage leaves h unchanged to the bit and gives every column the
    velocity ``dt [g_t - g_n (eta_{j+1} - eta_{j-1}) / (2 dx)]`` (eta = h + b; a dry
    column's eta = b, a wall's ghost mirrors the column next to it), at both orders: the
    driving stress of each column is its weight times the mean of its two discrete
    slopes, whatever the kinks of the free surface, toes and bed steps included where
    every free surface is above the beds beside it."""
    rng = np.random.default_rng(3)
    cells, dx, dt, g_n, g_t = 60, 0.01, 1e-3, 9.0, 1.2
    if bed.startswith("flat"):
        h = np.where(rng.random(cells) < 0.7, rng.uniform(0.02, 0.1, cells), 0.0)
        b = np.zeros(cells)
    else:
        h = rng.uniform(0.5, 1.0, cells)
        b = rng.uniform(0.0, 0.05, cells)
    fractions = np.array([0.2, 0.3, 0.5])
    u = np.zeros((3, cells))
    h_new, u_new = transport.transport(
        h, u, b, fractions, dx=dx, dt=dt, g_n=g_n, g_t=g_t, left="wall", right="wall",
        dry=1e-6, order=order, stage=0,
    )  # fmt: skip
    eta = np.concatenate([[h[0] + b[0]], h + b, [h[-1] + b[-1]]])
    expected = np.where(h > 1e-6, dt * (g_t - g_n * (eta[2:] - eta[:-2]) / (2.0 * dx)), 0.0)
    assert np.array_equal(h_new, h)
    np.testing.assert_allclose(u_new, np.broadcast_to(expected, u.shape), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("step", [0.3, 1.5, -0.3])
def test_a_closed_gate_is_a_wall_to_each_column_at_rest_beside_it(step, order):
    """A closed gate (engine/gate.py) between two columns at rest over a bed step: each
    side feels its own hydrostatic pressure ``g_n h_j^2 / 2`` at the gate, so every column
    still feels the mean of its two discrete slopes with the gate's face counted level
    (J = 0, as a wall's mirror ghost), whatever the level beyond the gate: below the high
    side's bed (step 1.5), above it, or the gate on the high side's west (-0.3).  Before,
    the face at rest's well-balancing term ``(h_j - hL)(h_j + hR)`` let the far side's
    level in: ``g_n (h_j - hL)(hR - hL) / 2`` more on the low side."""
    rng = np.random.default_rng(5)
    cells, face, dx, dt, g_n, g_t = 40, 20, 0.01, 1e-3, 9.0, 1.2
    h = rng.uniform(0.5, 1.0, cells)
    b = rng.uniform(0.0, 0.05, cells) + np.where(np.arange(cells) >= face, step, 0.0)
    fractions = np.array([0.2, 0.3, 0.5])
    u = np.zeros((3, cells))
    h_new, u_new = transport.transport(
        h, u, b, fractions, dx=dx, dt=dt, g_n=g_n, g_t=g_t, left="wall", right="wall", dry=1e-6,
        order=order, stage=0, gate_face=face, opening=np.zeros(3),
    )  # fmt: skip
    slopes = np.diff(h + b)
    slopes[face - 1] = 0.0  # the gate's face
    J = np.concatenate([[0.0], slopes, [0.0]])  # the walls at both ends
    expected = dt * (g_t - g_n * (J[:-1] + J[1:]) / (2.0 * dx))
    assert np.array_equal(h_new, h)
    np.testing.assert_allclose(u_new, np.broadcast_to(expected, u.shape), rtol=1e-12, atol=1e-15)


MU_S = 0.5


def heap(points, cells: int = 80, order: int = 2, slope_deg: float = 0.0, layers: int = 1, **changes):
    """A heap of the piecewise-linear free surface through ``points`` (x, h) on a 0.4 m
    no-slip bed, Drucker-Prager with ``mu_s = 0.5``.  Its cell averages have discrete
    slopes ``(h_{i+1} - h_i) / dx`` within the range of the slopes of its pieces (a cell
    average's difference is the mean of ``h(x + dx) - h(x)``), toes included (the dry
    cells' h = 0)."""
    return simulation(
        slope_deg=slope_deg,
        domain={"x_min": 0.0, "x_max": 0.4, "cells": cells, "layers": layers},
        material={"density": 1500.0, "grain_diameter": 1e-3},
        rheology={"name": "drucker_prager", "mu_s": MU_S, "nu": 0.0},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "profile", "points": [list(p) for p in points]}],
        numerics={"order": order},
        **changes,
    )


def triangle(ratio: float) -> list[tuple[float, float]]:
    """A triangular heap 0.2 m wide whose flanks rise at ``ratio`` times ``mu_s``."""
    return [(0.1, 0.0), (0.2, 0.1 * ratio * MU_S), (0.3, 0.0)]


def random_heap(seed: int, ratio: float = 0.95) -> list[tuple[float, float]]:
    """A heap of 3 to 7 pieces with random lengths and slopes up to ``ratio`` mu_s in
    magnitude (summits, valleys, changes of slope), from h = 0 at x = 0.1 m back to h = 0."""
    rng = np.random.default_rng(seed)
    points, x, h = [(0.1, 0.0)], 0.1, 0.0
    for _ in range(rng.integers(2, 7)):
        length = rng.uniform(0.005, 0.04)
        slope = ratio * MU_S * rng.uniform(-1.0, 1.0)
        if h + slope * length < 0.002:  # a valley, not back to the bed
            slope = abs(slope)
        x, h = x + length, h + slope * length
        points.append((x, h))
    slope = ratio * MU_S * rng.uniform(0.3, 1.0)  # the last flank down to the toe
    points.append((x + h / slope, 0.0))
    return points


KINKS = {
    "triangle": triangle(0.95),
    "summit-and-toes-at-the-limit": triangle(0.999),
    "step-of-slopes": [(0.1, 0.0), (0.15, 0.02375), (0.2, 0.02875), (0.2605, 0.0)],
    "plateau": [(0.1, 0.0), (0.15, 0.02375), (0.2, 0.02375), (0.25, 0.0)],
    "valley": [(0.1, 0.0), (0.15, 0.02375), (0.18, 0.0095), (0.21, 0.02375), (0.26, 0.0)],
}


def kept(sim, steps: int = 20) -> bool:
    """The state is left exactly as it is by ``steps`` steps: u == 0.0, h to the bit."""
    h0 = sim.h.copy()
    for _ in range(steps):
        sim.step()
    return not np.any(sim.u) and np.array_equal(sim.h, h0)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("shape", KINKS)
def test_a_heap_whose_discrete_slopes_are_below_the_friction_is_kept_to_the_bit(shape, order):
    """docs/model.md, "Rest": a column at rest feels the mean of its two discrete
    free-surface slopes, so a heap all of whose discrete slopes stay below ``mu_s`` is an
    exact equilibrium at both orders, summits, valleys, changes of slope and toes included
    (flanks at 0.95 and 0.999 mu_s; before, the limiter's flattening of the summit and the
    toe's half-hydrostatic push set kinks of flanks above 0.8 mu_s moving)."""
    assert kept(heap(KINKS[shape], order=order))


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("seed", range(6))
def test_random_piecewise_linear_heaps_below_the_friction_are_kept_to_the_bit(seed, order):
    assert kept(heap(random_heap(seed), order=order))


@pytest.mark.parametrize(
    "model", [{}, {"normal_stress": True}, {"pressure": "non_hydrostatic"}, {"pressure": "bim2016"}]
)
def test_heaps_are_kept_in_layers_with_the_normal_stress_and_every_pressure(model):
    """In 4 layers (each interface's yield stress is its share of the column's), and with
    the normal stress, which stresses only moving material, the non-hydrostatic pressure,
    whose projection of a velocity field at rest is zero, or the bim2016 pressure, whose
    yield gravity at rest on a horizontal bed is g: the heaps stay as exact."""
    for points in (triangle(0.95), random_heap(0)):
        assert kept(heap(points, layers=4, model=model), steps=10)


def test_a_heap_on_a_slope_is_kept_where_its_driving_slopes_are_below_the_friction():
    """On a 10 degree plane the driving slope of a piece is ``tan(10) - dh/dx``: flanks of
    0.15 and -0.2 keep it between 0.03 and 0.38, below mu_s = 0.5."""
    points = [(0.1, 0.0), (0.2, 0.015), (0.275, 0.0)]
    assert kept(heap(points, slope_deg=10.0))


@pytest.mark.parametrize("order", [1, 2])
def test_a_heap_steeper_than_the_friction_slumps_and_keeps_its_mass(order):
    """The converse: with flanks at 1.05 mu_s every column whose mean discrete slope
    ``|h_{j+1} - h_{j-1}| / (2 dx)`` exceeds ``mu_s`` (the flanks but their ends, 36 of
    the 40 wet columns) moves from the first step, and the slump conserves the mass to
    round-off."""
    sim = heap(triangle(1.05), order=order)
    h0 = sim.h.copy()
    driven = np.abs(h0[2:] - h0[:-2]) / (2.0 * sim.dx) > MU_S
    sim.step()
    assert np.count_nonzero(driven) == 36 and np.all(np.any(sim.u != 0.0, axis=0)[1:-1][driven])
    for _ in range(10):
        sim.step()
    assert sim.h.sum() == pytest.approx(h0.sum(), rel=1e-13)
