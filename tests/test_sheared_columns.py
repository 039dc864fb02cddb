"""Fully sheared columns solved side by side (engine/sheared_columns.py) against the same
Newton iteration and exact solve column by column (``CompiledStep(side_by_side=False)``,
itself held to the numpy iteration and the dynamic programme in test_newton_kernel.py and
test_column_kernel.py): the same velocities and iteration counts to the last bit, and a
column leaves the block wherever the block could not do exactly what the column-by-column
iteration does."""

from __future__ import annotations

import numpy as np
import pytest
from engine import simulation

from multilayer.engine.plugin_output import PluginOutputError
from multilayer.engine.threads import CHUNKS_PER_THREAD
from multilayer.engine.vertical.newton_kernel import CompiledStep
from multilayer.engine.vertical.sheared_columns import BLOCK, cell
from multilayer.plugins.builtins import JopMuI

MATERIAL = {"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0}
JOP = {"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279}
# a sheet on a slope steeper than its friction angle: every layer shears after a few steps
CHUTE = dict(
    slope_deg=28.0,
    domain={"x_min": 0.0, "x_max": 0.24, "cells": 24, "layers": 12},
    material=MATERIAL,
    rheology=JOP,
    base=[{"condition": "no_slip"}],
    initial=[{"shape": "layer", "thickness": 0.01}],
    boundaries={"left": "periodic", "right": "periodic"},
)
# a collapse on a gentler slope that partly stops: columns at rest, plugs and sheared ones
COLLAPSE = {
    **CHUTE,
    "slope_deg": 20.0,
    "domain": {"x_min": 0.0, "x_max": 1.0, "cells": 60, "layers": 8},
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.2, "height": 0.1}],
    "boundaries": {"left": "wall", "right": "outflow"},
}


def _both(sim, steps=10, ustar_shift=0.01, guess_scale=1.0, threads=1, max_iterations=200):
    """The step from the state after ``steps`` steps by both paths: (side by side, column
    by column), each as (velocities, iterations, step object)."""
    for _ in range(steps):
        sim.step()
    ustar = sim.u + ustar_shift * (sim.h > 0)
    guess = guess_scale * sim.u
    threshold = sim.numerics.tolerance * sim.vertical.velocity_scale
    results = []
    for side_by_side in (True, False):
        step = CompiledStep(sim.vertical.stresses, side_by_side=side_by_side)
        u, iterations = step(
            sim.h, ustar, guess, 1e-3, threshold=threshold, max_iterations=max_iterations, threads=threads
        )
        results.append((u.copy(), iterations, step))
    return results


def _assert_same(results):
    (u, iterations, _), (u_ref, iterations_ref, _) = results
    np.testing.assert_array_equal(u, u_ref)
    np.testing.assert_array_equal(iterations, iterations_ref)


@pytest.mark.parametrize(
    "rheology",
    [
        JOP,  # the inertial form
        {"name": "power_law_mu_i", "mu_s": 0.38, "m": 0.3, "alpha": 0.5},  # the power form
        {"name": "drucker_prager", "mu_s": 0.38, "nu": 2e-3},  # the constant form
    ],
    ids=lambda r: r["name"],
)
def test_a_sheared_chute_is_solved_side_by_side_to_the_same_bits(rheology):
    results = _both(simulation(**{**CHUTE, "rheology": rheology}))
    _assert_same(results)
    step = results[0][2]
    assert step.columns == 24 and step.columns_side_by_side == 24  # every column, BLOCK at a time
    assert results[1][2].columns_side_by_side == 0
    u = results[0][0]
    assert (np.diff(u, axis=0) > 0).all() and (u[0] > 0).all()  # sheared at every interface


def test_a_partly_stopped_collapse_mixes_blocks_and_single_columns_to_the_same_bits():
    """Columns at rest, rigid plugs, fronts and non-adjacent wet columns leave the blocks;
    static layers are exactly 0 either way."""
    results = _both(simulation(**COLLAPSE), steps=60, ustar_shift=0.0)
    _assert_same(results)
    u, _, step = results[0]
    assert 0 < step.columns_side_by_side < step.columns
    assert (u == 0.0).any() and (u != 0.0).any()


def test_lanes_side_by_side_in_the_tile_are_solved_to_the_same_bits():
    """The tile's lanes lie side by side, a layer's BLOCK cells together (the bed below the
    bottom ones and the free surface above the top ones from the slot BED, in pads), and
    lane ALONE after them: at 40 layers, as at the other sizes, the same bits as column by
    column."""
    assert [cell(i, 40) for i in (0, 1, BLOCK)] == [BLOCK, BLOCK + 1, 2 * BLOCK + 40 * BLOCK]
    results = _both(simulation(**{**CHUTE, "domain": {**CHUTE["domain"], "layers": 40}}))
    _assert_same(results)
    assert results[0][2].columns_side_by_side == 24


def test_columns_not_converged_within_the_iterations_are_the_same():
    """With one iteration allowed and a poor guess, columns end unconverged (-1) with the
    same last iterate either way."""
    results = _both(simulation(**CHUTE), guess_scale=0.5, max_iterations=1)
    _assert_same(results)
    assert (results[0][1] == -1).any()


@pytest.mark.slow  # compiles the parallel variant of the kernel
def test_two_threads_cut_blocks_into_chunks_to_the_same_bits():
    cells = 2 * CHUNKS_PER_THREAD * 2 * BLOCK  # two blocks per chunk
    results = _both(simulation(**{**CHUTE, "domain": {**CHUTE["domain"], "cells": cells}}), threads=2)
    _assert_same(results)
    assert results[0][2].columns_side_by_side > 0


def test_side_walls_keep_every_column_on_its_own():
    walled = {
        **CHUTE,
        "domain": {**CHUTE["domain"], "width": 0.1},
        "walls": {"name": "wall_friction", "mu_w": 0.2},
    }
    results = _both(simulation(**walled))
    _assert_same(results)
    assert results[0][2].columns_side_by_side == 0


def test_a_viscosity_outside_the_contract_in_a_block_is_reported_as_column_by_column():
    sim = simulation(**CHUTE)
    for _ in range(10):
        sim.step()
    bad = JopMuI(0.38, 0.64, 0.279)
    bad.mu_2 = 0.2  # past validation: mu_2 < mu_s, a negative viscosity
    sim.vertical.stresses.bulk = bad
    messages = []
    for side_by_side in (True, False):
        step = CompiledStep(sim.vertical.stresses, side_by_side=side_by_side)
        with pytest.raises(PluginOutputError) as caught, np.errstate(divide="ignore"):
            step(sim.h, sim.u, sim.u, 1e-3, threshold=1e-9, max_iterations=50)
        messages.append(str(caught.value))
    assert messages[0] == messages[1]
    assert "viscosity_kernel" in messages[0]


def test_the_bound_of_a_sheared_lane_decides_as_the_error_bound():
    """The error bound of a lane whose every jump is nonzero, summed from gaps computed as
    vectors (``sheared_columns._gaps``, over the lane or the whole block, and
    ``_within_bound``), against ``newton_control.error_bound`` on the same values: the same
    answer to ``bound <= limit`` for limits about the bound (within a few ulps, twice it,
    half of it), 0, inf and NaN, on iterates far from and near the exact step, with layers
    at rest (a speed of 0 between nonzero jumps) and without mass in some layer's excess."""
    from multilayer.engine.vertical import sheared_columns as sc
    from multilayer.engine.vertical.newton_control import error_bound

    rng = np.random.default_rng(7)
    for L in (1, 2, 8, 33):
        t = sc.new_tile(L)
        lane = slice(sc.cell(3, L), sc.block_end(L), sc.BLOCK)  # lane 3's cells
        view = t[:, 3 :: sc.BLOCK]  # its view (sheared_columns.lane_of): layer a in cell 1 + a
        for trial in range(200):
            jumps = rng.choice([-1.0, 1.0], L) * rng.uniform(1e-3, 1.0, L)
            u = np.cumsum(jumps)
            if trial % 4 == 1 and L > 1:  # a layer at rest, the jumps below and above it nonzero
                a = int(rng.integers(1, L))
                u[a:] -= u[a]
                u[a:] += np.concatenate(([0.0], np.cumsum(rng.uniform(0.1, 1.0, L - a - 1))))
            inertia = rng.uniform(0.5, 2.0, L)
            kappa, tau = rng.uniform(0.0, 1.0, L), rng.uniform(0.0, 1.0, L)
            # a momentum that balances the stresses (an exact step) up to a small residual
            sigma = np.sign(np.diff(u, prepend=0.0)) * (kappa + tau)
            balance = inertia * u + sigma - np.append(sigma[1:], 0.0)
            momentum = balance + (10.0 ** rng.uniform(-14, 0)) * rng.standard_normal(L)
            if trial % 5 == 2:
                momentum[rng.integers(L)] = balance[0]  # some layer's excess far off
            wall = np.zeros(L)
            t[sc.U0, lane], t[sc.INERTIA, lane], t[sc.MOMENTUM, lane] = u, inertia, momentum
            t[sc.KAPPA, lane], t[sc.TAU0, lane], t[sc.WALL, lane] = kappa, tau, wall
            assert np.all(np.diff(u, prepend=0.0) != 0.0)
            bound = error_bound(inertia, momentum, kappa, tau, wall, wall, u, np.inf)
            # the gaps of the lane, in a pass over it or over the whole block: the same
            sc._gaps(t, sc.cell(0, L), sc.block_end(L), np.int64(sc.U0), np.uint64(sc.BLOCK))
            block = t[sc.GAP, lane].copy()
            sc._gaps(view, 1, L + 1, np.int64(sc.U0), np.uint64(1))
            assert np.array_equal(t[sc.GAP, lane], block)
            for limit in (bound, np.nextafter(bound, 0.0), np.nextafter(bound, np.inf), 2.0 * bound,
                          0.5 * bound, 0.0, np.inf, np.nan):  # fmt: skip
                expected = error_bound(inertia, momentum, kappa, tau, wall, wall, u, limit) <= limit
                assert sc._within_bound(view, 1, L, limit) == expected, (L, trial, limit)
