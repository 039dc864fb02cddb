"""The coefficients of a block of adjacent columns laid out side by side
(engine/vertical/block_coefficients.py) against ``column_coefficients`` column by column:
the same bits in every value, and the same columns outside the plugin contract."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from multilayer.engine.vertical import sheared_columns as sc
from multilayer.engine.vertical.block_coefficients import ROWS, block_coefficients, layer_rows
from multilayer.engine.vertical.coefficients import (
    ColumnArrays,
    YieldInputs,
    column_arrays,
    column_coefficients,
)


def _inputs(rng, L, N, rest, gravity, thickness, spacings):
    fractions = rng.uniform(0.5, 1.5, L)
    l = fractions / fractions.sum()
    depth = 1.0 - np.concatenate(([0.0], np.cumsum(l)[:-1]))
    resting = rng.random((L, N)) < 0.5
    return YieldInputs(
        resting if rest else np.zeros((1, 1), bool), rest,
        resting.any(axis=0) if rest else np.zeros(1, bool),
        rng.uniform(-2.0, 12.0, (L, N)) if gravity else np.zeros((1, 1)), gravity,
        9.81 * np.cos(0.4), 1550.0, l, depth, depth - 0.5 * l, spacings,
        rng.random(N) < 0.7, rng.uniform(0.2, 0.6, N), rng.uniform(0.0, 10.0, N),
        0.38, 0.45, thickness, 0.2 if thickness else 0.0, 0.01 if thickness else np.inf, False, 0.0, 0.0,
    )  # fmt: skip


@pytest.mark.parametrize("rest, gravity, thickness", list(itertools.product((False, True), repeat=3)))
def test_a_block_has_the_coefficients_of_its_columns_to_the_bit(rest, gravity, thickness):
    rng = np.random.default_rng(11)
    # spacing fractions all different, and in runs of equal ones (equal layers: h/2L at the bed,
    # h/L above; block_coefficients divides once per run and lane)
    runs = [np.array([0.5 / 3, 1 / 3, 1 / 3]), np.array([0.3, 0.3, 0.2, 0.1, 0.1, 0.1, 0.4, 0.4])]
    for spacings in [rng.uniform(0.5, 1.5, L) for L in (1, 3, 8)] + runs:
        L, N, c0 = spacings.size, sc.BLOCK + 3, 2
        inputs = _inputs(rng, L, N, rest, gravity, thickness, spacings)
        h = rng.uniform(1e-3, 0.2, N)
        if gravity:  # a yield value outside the plugin contract in one column
            inputs.yield_gravity[L - 1, c0 + 5] = np.nan
        t, flags = sc.new_tile(L), np.zeros((4, sc.BLOCK), np.bool_)
        work = column_arrays(L)
        rows = t[sc.KAPPA], t[sc.WALL], t[sc.PRESSURE], t[sc.SPACING]
        column = ColumnArrays(work.m, *rows, work.viscous, work.w)
        layers = np.full((ROWS, sc.BLOCK * L), np.nan)
        layer_rows(inputs, layers)
        dt, u_rows = 1e-3, rng.normal(size=sc.BLOCK * L)
        block_coefficients(c0, h, inputs, t, L, column, flags, layers, dt, u_rows)
        for i in range(sc.BLOCK):
            ref = column_arrays(L)
            ref.viscous[:] = True
            bad = column_coefficients(c0 + i, h[c0 + i], inputs, ref, 0, 1, False)
            lane = slice(sc.cell(i, L), sc.block_end(L), sc.BLOCK)
            u = u_rows[i :: sc.BLOCK]
            inverse = np.where(ref.spacing > 0.0, 1.0 / np.where(ref.spacing > 0.0, ref.spacing, 1.0), 1.0)
            conductance = np.where((ref.spacing > 0.0) & ref.viscous, inverse, 0.0)
            for slot, values in ((sc.INERTIA, ref.m * (1.0 / dt)), (sc.MOMENTUM, ref.m * u * (1.0 / dt)),
                                 (sc.KAPPA, ref.kappa), (sc.PRESSURE, ref.pressure),
                                 (sc.INV_SPACING, inverse), (sc.CONDUCTANCE, conductance)):  # fmt: skip
                assert np.array_equal(t[slot, lane].view(np.int64), values.view(np.int64)), (L, i, slot)
            assert t[sc.VISCOUS, sc.cell(i, L)] == (1.0 if ref.viscous[0] else 0.0)
            assert flags[sc.FINE, i] == (bad == 0)
        assert flags[sc.FINE].sum() == (sc.BLOCK - 1 if gravity else sc.BLOCK)
