"""The compiled transport sweep against the numpy reference formulation (transport.py).

Both compute the same scheme with the same operations in the same order, so they must
agree to the last bit on every boundary kind, at both orders, on dry fronts, over a bed,
with faces at rest, through a partly open gate, with one tile or many, and whatever the
number of chunks the window is cut into.
"""

from __future__ import annotations

import numpy as np
import pytest
from engine import simulation

from multilayer.engine import state
from multilayer.engine.transport import boundaries
from multilayer.engine.transport import kernel as transport_kernel
from multilayer.engine.transport import reference as transport

BOUNDARIES = [("wall", "wall"), ("wall", "outflow"), ("periodic", "periodic"), ("inflow", "outflow")]


def random_state(seed: int, cells: int = 240, layers: int = 5):
    """A rough state: dry stretches and fronts, a bumpy bed, sheared layer velocities."""
    rng = np.random.default_rng(seed)
    h = np.where(rng.random(cells) < 0.8, rng.random(cells), 0.0)
    h[: cells // 6] = 0.0  # a dry stretch, so that the window does not start at 0
    h[-cells // 6 :] = 0.0
    u = rng.normal(size=(layers, cells)) * (h > 0)
    b = np.cumsum(rng.normal(size=cells)) * 0.05
    fractions = rng.random(layers) + 0.1
    return h, u, b, fractions / fractions.sum()


def both(h, u, b, fractions, threads=(1,), **kw):
    """Both paths agree to the last bit on the state and on the mass and the momentum
    through the boundaries (and the integral of the mass gravity acts on), the kernel on
    each number of ``threads``."""
    crossed, momentum = np.full(2, np.nan), np.full(3, np.nan)
    expected = transport.transport(
        h, u, b, fractions, boundary_mass=crossed, boundary_momentum=momentum, **kw
    )
    for count in threads:
        crossed_kernel, momentum_kernel = np.full(2, np.nan), np.full(3, np.nan)
        got = transport_kernel.transport(
            h, u, b, fractions, threads=count, boundary_mass=crossed_kernel,
            boundary_momentum=momentum_kernel, **kw,
        )  # fmt: skip
        for e, g in zip(expected, got):
            np.testing.assert_array_equal(g, e)
        np.testing.assert_array_equal(crossed_kernel, crossed)
        np.testing.assert_array_equal(momentum_kernel, momentum)
    return crossed


@pytest.mark.parametrize("threaded", [False, pytest.param(True, marks=pytest.mark.slow)], ids=["1", "3"])
@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("left, right", BOUNDARIES)
def test_compiled_transport_equals_the_numpy_reference(order, left, right, threaded):
    h, u, b, fractions = random_state(seed=order)
    inflow = boundaries.InflowState(0.7, np.linspace(0.2, 1.0, u.shape[0])) if left == "inflow" else None
    kw = dict(
        dx=0.1, dt=0.004, g_n=9.0, g_t=1.5, left=left, right=right, inflow=inflow, dry=1e-6, order=order
    )
    both(h, u, b, fractions, **kw)
    if threaded:  # the parallel variant of the kernel (compiled only for this test)
        both(h, u, b, fractions, threads=(3,), **kw)
    # material at rest: only some columns carry waves
    moving = np.random.default_rng(7).random(h.size) < 0.5
    both(h, u * moving, b, fractions, moving=moving, **kw)
    # material at both ends, moving out through open sides (or across the periodic ones)
    h[:3], h[-3:], u[:, :3], u[:, -3:] = 0.4, 0.3, -1.0, 0.8
    crossed = both(h, u, b, fractions, **kw)
    h_new = transport.transport(h, u, b, fractions, **kw)[0]
    assert (h_new.sum() - h.sum()) * kw["dx"] == pytest.approx(crossed[0] - crossed[1], abs=1e-14)
    if right != "wall":
        assert crossed[1] != 0.0
    if left == "periodic":
        assert crossed[0] == crossed[1]


@pytest.mark.parametrize("left, right", BOUNDARIES)
def test_heun_stages_alone_equal_the_reference_and_compose_to_heun(left, right):
    """Each of Heun's stages alone (the split step of ``Simulation.step``) gives the same
    bits on both paths, the second from any given state (here the first stage's, part of
    it stopped as a vertical step would); from the first stage's own result the two make
    Heun's step (to round-off: its momentum goes through the velocity)."""
    h, u, b, fractions = random_state(seed=3)
    inflow = boundaries.InflowState(0.7, np.linspace(0.2, 1.0, u.shape[0])) if left == "inflow" else None
    kw = dict(dx=0.1, dt=0.004, g_n=9.0, g_t=1.5, left=left, right=right, inflow=inflow, dry=1e-6, order=2)
    both(h, u, b, fractions, stage=0, **kw)
    h1, u1 = (a.copy() for a in transport.transport(h, u, b, fractions, stage=0, **kw))
    stopped = u1 * (np.random.default_rng(5).random(h.size) < 0.5)
    crossed, momentum = np.zeros(2), np.zeros(3)
    reference = transport.transport(
        h, u, b, fractions, stage=1, first=(h1, stopped), boundary_mass=crossed,
        boundary_momentum=momentum, **kw,
    )  # fmt: skip
    workspace = transport_kernel.Workspace(*u.shape)
    transport_kernel.transport(h, u, b, fractions, stage=0, workspace=workspace, **kw)
    crossed_kernel, momentum_kernel = np.zeros(2), np.zeros(3)
    got = transport_kernel.transport(
        h, u, b, fractions, stage=1, first=(h1, stopped), workspace=workspace, boundary_mass=crossed_kernel,
        boundary_momentum=momentum_kernel, **kw,
    )  # fmt: skip
    for e, g in zip((*reference, crossed, momentum), (*got, crossed_kernel, momentum_kernel), strict=True):
        np.testing.assert_array_equal(g, e)
    with pytest.raises(ValueError, match="workspace of its first"):
        transport_kernel.transport(h, u, b, fractions, stage=1, first=(h1, stopped), **kw)
    whole = transport.transport(h, u, b, fractions, **kw)
    split = transport.transport(h, u, b, fractions, stage=1, first=(h1, u1), **kw)
    np.testing.assert_allclose(split[0], whole[0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(split[1], whole[1], rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("layers", [3, 40, 150])
def test_compiled_gate_equals_the_numpy_reference(order, layers):
    """A partly open gate (engine/gate.py) inside the window, at a chunk or tile edge and
    at the window's end, with flow either way or at rest (partly open or closed); 40 and
    150 layers make many tiles and the layer sums of the gate flux pairwise (numpy's
    order)."""
    h, u, b, fractions = random_state(seed=layers, cells=600, layers=layers)
    opening = np.clip(np.linspace(1.4, -0.4, layers), 0.0, 1.0)
    kw = dict(dx=0.1, dt=0.004, g_n=9.0, g_t=1.5, left="wall", right="outflow", dry=1e-6, order=order)
    lo, hi = np.flatnonzero(h)[[0, -1]]
    for face in (lo + 37, lo + 38, lo + 64, 300, hi - 2, hi + 1 + transport.MARGIN):
        for sign in (1.0, -1.0):
            both(h, sign * u, b, fractions, gate_face=int(face), opening=opening, **kw)
        for gate in (opening, np.zeros(layers)):  # at rest, the gate partly open or closed
            both(h, 0.0 * u, b, fractions, gate_face=int(face), opening=gate, **kw)


@pytest.mark.parametrize("order", [1, 2])
def test_compiled_transport_equals_the_reference_on_a_dam_break_to_the_walls(order):
    """A column released between walls: fronts running over a dry bed for many steps."""
    h = np.where(np.arange(200) < 50, 1.0, 0.0)
    u = np.zeros((3, 200))
    b = np.zeros(200)
    fractions = np.full(3, 1 / 3)
    kw = dict(dx=0.05, dt=0.005, g_n=9.81, g_t=0.0, left="wall", right="wall", dry=1e-8, order=order)
    for _ in range(60):
        moving = h > 0.0  # the released column moves (the vertical step would say so)
        h_ref, u_ref = transport.transport(h, u, b, fractions, moving=moving, **kw)
        h_new, u_new = transport_kernel.transport(h, u, b, fractions, moving=moving, **kw)
        np.testing.assert_allclose(h_new, h_ref, rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(u_new, u_ref, rtol=1e-13, atol=1e-13)
        h, u = h_ref, u_ref
    assert h[80:].max() > 0.0  # the front ran over the dry bed


@pytest.mark.parametrize("order", [1, 2])
def test_whole_runs_agree_with_either_transport(order):
    """A mu(I) collapse with the exact vertical step: the same answer to round-off."""
    runs = []
    for solver in ("numpy", "kernel"):
        sim = simulation(
            slope_deg=10.0,
            domain={"cells": 120, "layers": 4},
            material={"density": 1550.0, "grain_diameter": 0.7e-3},
            rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279},
            base=[{"condition": "no_slip"}],
            initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 2.0, "height": 0.5}],
            boundaries={"left": "wall", "right": "outflow"},
            numerics={"order": order, "transport_solver": solver},
        )
        for _ in range(40):
            sim.step()
        runs.append(sim)
    ref, got = runs
    assert got.t == pytest.approx(ref.t, rel=1e-12)
    np.testing.assert_allclose(got.h, ref.h, rtol=1e-11, atol=1e-12)
    np.testing.assert_allclose(got.u, ref.u, rtol=1e-9, atol=1e-10)
    assert np.array_equal(got.u == 0.0, ref.u == 0.0)  # the same layers exactly at rest


def test_wave_speed_and_moving_columns():
    h, u, _, _ = random_state(seed=3)
    expected = np.max(np.max(np.abs(u), axis=0) + np.sqrt(9.0 * h))
    assert state.max_wave_speed(h, u, 9.0) == expected
    assert np.array_equal(state.moving_columns(u), np.any(u != 0.0, axis=0))
    # the survey at the start of a step: the same speed and columns, and the layers at rest
    u[:, ::3] = 0.0  # columns at rest
    u[1:, 1::3] = 0.0  # columns moving in their bottom layer only
    expected = np.max(np.max(np.abs(u), axis=0) + np.sqrt(9.0 * h))
    moving, rest = np.ones(h.size, bool), np.zeros(u.shape, bool)
    N = h.size
    speed, surveyed, velocities = state.survey(h, u, 0.5, 9.0, moving, rest, (0, N), (0, N))
    assert speed == expected and surveyed == (0, N)
    assert np.array_equal(moving, np.any(u != 0.0, axis=0))
    assert np.array_equal(rest, (u == 0.0) & (h > 0.5))
    first, last = np.flatnonzero(moving)[[0, -1]]
    assert velocities == (first, last + 1)
    # material at rest set moving: added to the moving columns, dry or moving ones not
    u_new = u.copy()
    u_new[:, rest.any(axis=0)] = 1.0
    before = moving.copy()
    assert (rest.any(axis=0) & ~before).any()
    assert state.start_moving(u_new, h, 0.5, moving)
    assert np.array_equal(moving, before | (rest.any(axis=0) & (h > 0.5)))
    assert not state.start_moving(u_new, h, 0.5, moving)
    # material and velocities left in a few columns only: the survey reads those (and the
    # columns that may hold velocities) and clears the flags of the last survey outside
    h_few, u_few = np.zeros_like(h), np.zeros_like(u)
    h_few[100:110] = np.linspace(0.2, 2.0, 10)
    u_few[:, 102:115] = 1.0  # (velocities without material: read too)
    u_few[:, 104] = u_few[1:, 106] = 0.0
    speed, surveyed, velocities = state.survey(h_few, u_few, 0.5, 9.0, moving, rest, (102, 115), (0, N))
    assert speed == np.max(np.max(np.abs(u_few), axis=0) + np.sqrt(9.0 * h_few)) and surveyed == (100, 115)
    assert np.array_equal(moving, np.any(u_few != 0.0, axis=0))
    assert np.array_equal(rest, (u_few == 0.0) & (h_few > 0.5))
    first, last = np.flatnonzero(moving)[[0, -1]]
    assert velocities == (first, last + 1)


def test_the_survey_of_a_running_dam_break_reads_only_its_material_and_finds_every_flag():
    """A Coulomb dam break whose material covers a fifth of the mesh: at every step the
    survey (of the columns holding material or velocities) gives the moving columns, the
    layers at rest and the wave speed of a survey of the whole mesh."""
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 10.0, "cells": 200, "layers": 4},
        rheology={"name": "drucker_prager", "mu_s": 0.4, "nu": 0.0},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 1.0, "height": 0.5}],
    )
    N = sim.h.size
    for _ in range(40):
        sim.step()
        moving, rest = np.zeros(N, bool), np.zeros(sim.u.shape, bool)
        whole = state.survey(sim.h, sim.u, sim.dry, sim.g_n, moving, rest, (0, N), (0, N))[0]
        assert sim.state.survey(sim.dry, sim.g_n) == whole
        assert np.array_equal(sim.state.moving, moving) and np.array_equal(sim.state.rest, rest)
        assert sim.state._surveyed[1] - sim.state._surveyed[0] < N // 2


def test_a_reused_workspace_leaves_nothing_outside_a_narrower_window():
    """The result arrays are reused from step to step: where an earlier, wider window
    wrote, a later step with less material must give zeros, as the reference does."""
    h, u, b, fractions = random_state(seed=5)
    kw = dict(dx=0.1, dt=0.004, g_n=9.0, g_t=1.5, left="wall", right="outflow", dry=1e-6, order=2)
    workspace = transport_kernel.Workspace(*u.shape)
    for keep in (slice(40, 200), slice(90, 120), slice(10, 230), slice(150, 160)):
        hk, uk = np.zeros_like(h), np.zeros_like(u)
        hk[keep], uk[:, keep] = h[keep], u[:, keep]
        expected = transport.transport(hk, uk, b, fractions, **kw)
        got = transport_kernel.transport(hk, uk, b, fractions, workspace=workspace, **kw)
        for e, g in zip(expected, got):
            np.testing.assert_array_equal(g, e)


def test_kept_first_stages_stay_whole_and_zero_outside_their_window():
    """Heun's first stage kept (``Workspace.keep``, the pair of results swapped) through
    the second, step after step on windows that widen and narrow: the kept stage and the
    second's result are the reference's, zeros outside their windows included."""
    h, u, b, fractions = random_state(seed=6)
    kw = dict(dx=0.1, dt=0.004, g_n=9.0, g_t=1.5, left="wall", right="outflow", dry=1e-6, order=2)
    workspace = transport_kernel.Workspace(*u.shape)
    for keep in (slice(40, 200), slice(90, 120), slice(10, 230), slice(150, 160), slice(0, 0)):
        hk, uk = np.zeros_like(h), np.zeros_like(u)
        hk[keep], uk[:, keep] = h[keep], u[:, keep]
        first = transport.transport(hk, uk, b, fractions, stage=0, **kw)
        transport_kernel.transport(hk, uk, b, fractions, stage=0, workspace=workspace, **kw)
        kept = workspace.keep()
        second = transport.transport(hk, uk, b, fractions, stage=1, first=first, **kw)
        got = transport_kernel.transport(hk, uk, b, fractions, stage=1, first=kept, workspace=workspace, **kw)
        for e, g in zip((*first, *second), (*kept, *got), strict=True):
            np.testing.assert_array_equal(g, e)
