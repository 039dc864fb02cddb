"""The coefficients of the step of a block of adjacent columns, laid out side by side.

:func:`coefficients.column_coefficients` makes the yield stresses, interface pressures,
spacings and masses of one column, its layers one after the other.  The tile of
``sheared_columns`` lays a block's ``BLOCK`` adjacent columns out as the mesh and its
sweeps do (a layer's columns side by side): :func:`block_coefficients` makes them for the
whole block in that layout, each value by the operations of ``column_coefficients`` (the
same bits: tests/test_block_coefficients.py), in one loop over the block's cells with no
loop over the lanes inside it, so that it runs as vectors (numba leaves LLVM's SLP
vectoriser off: a loop over a layer's eight lanes would run one value at a time).  Each
factor of a value that depends on the layer alone comes from a row of the chunk
(:func:`layer_rows`, each layer's factor repeated for the ``BLOCK`` lanes, made once per
call of the kernel), each that depends on the lane alone from a row of the block, made by
copying its ``BLOCK`` values ``BLOCK`` places on (a loop that also runs as vectors).
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.vertical.coefficients import _frictional, _within_contract, column_coefficients
from multilayer.engine.vertical.sheared_columns import (
    ACTIVE,
    BLOCK,
    CONDUCTANCE,
    FINE,
    INERTIA,
    INV_SPACING,
    KAPPA,
    MOMENTUM,
    PRESSURE,
    VISCOUS,
    WALL,
    _layer,
    cell,
)

MASS, WEIGHT, DEPTH, MU, THICKNESS, FRICTION, GRAVITY = range(7)
"""The rows of :func:`layer_rows` (``rho l_a``, ``rho g_n`` times the
depth of the interface, that depth, the friction ``mu`` of the bulk law) and of the block
(the column thickness, the friction of the column with a law of the thickness, ``rho g
depth`` of a yield gravity)."""
ROWS = 7


@jit(borrowing=True)
def layer_rows(inputs, rows):
    """The rows of the layers' factors of ``inputs`` (:class:`coefficients.YieldInputs`) in
    ``rows`` (``ROWS``, ``BLOCK L``): layer a's in cells ``a BLOCK ... a BLOCK + BLOCK - 1``,
    each as ``column_coefficients`` makes it."""
    rho, lanes = inputs.rho, np.uint64(BLOCK)
    g_p = rho * inputs.g_n
    for a in range(np.uint64(inputs.l.size)):  # unsigned: no test for negative indices
        for i in range(np.uint64(BLOCK)):
            s = a * lanes + i
            rows[MASS, s] = rho * inputs.l[a]
            rows[WEIGHT, s] = g_p * inputs.depth_interface[a]
            rows[DEPTH, s] = inputs.depth_interface[a]
            rows[MU, s] = inputs.mu


@jit(borrowing=True)
def block_coefficients(c0, h, inputs, t, L, column, flags, rows, dt, u_rows):
    """``column_coefficients`` of the ``BLOCK`` adjacent mesh columns ``c0 ...`` (thicknesses
    ``h``, no side walls) into the block's lanes of the tile ``t``: the yield stresses and
    pressures into their slots, whether the bed's layer is viscous into ``VISCOUS`` (layer 0;
    above it 1.0, from ``new_tile``), and ``flags[FINE]``, whether each column's yield values
    are within the plugin contract; in the same pass what of them stays fixed during the
    step, as ``sheared_columns.block_parts`` makes it (``m/dt``, ``m u*/dt`` of the step
    ``dt`` as products with ``1/dt``, the u* of the rows ``u_rows`` of
    ``sheared_columns.load``, the inverse spacings and conductances per unit slope:
    ``fixed_parts``, 0 where not viscous, by :func:`_inverse_spacings`; the spacings
    themselves, which nothing reads after, are not stored).  Where some yield value is
    outside the contract, ``column_coefficients`` itself tells which, column by column,
    writing the same values again (``column``: its work arrays).  ``rows``: those of
    :func:`layer_rows`, and the block's own."""
    rho, rest, lanes = inputs.rho, inputs.rest, np.uint64(BLOCK)
    n, x0 = np.uint64(BLOCK * L), np.uint64(cell(0, L))  # unsigned: no test for negative indices
    mu_static, gravity, plateau = inputs.mu_static, inputs.has_yield_gravity, inputs.thickness_law
    thickness, friction, weights = rows[THICKNESS], rows[FRICTION], rows[GRAVITY]
    for i in range(BLOCK):
        hj = h[c0 + i]
        thickness[i] = hj
        friction[i] = inputs.mu + inputs.drop / (1.0 + hj / inputs.length)
    for s in range(lanes, n):  # each lane's value, BLOCK places on (as vectors)
        thickness[s] = thickness[s - lanes]
    for s in range(lanes, n if plateau else lanes):
        friction[s] = friction[s - lanes]
    for a in range(np.uint64(L if gravity else 0)):
        g = _layer(inputs.yield_gravity[a], c0)
        for i in range(BLOCK):
            weights[a * lanes + np.uint64(i)] = g[i]
    for s in range(n if gravity else 0):  # rho g depth, as column_coefficients multiplies them
        weights[s] = rho * weights[s] * rows[DEPTH, s]
    if not gravity:
        weights = rows[WEIGHT]
    if not plateau:
        friction = rows[MU]
    _inverse_spacings(t, L, inputs.spacing_fraction, thickness)
    outside = 0  # yield values outside the contract, in all the columns (counted without branches)
    per_dt = 1.0 / dt  # one division per call, not two per cell (sheared_columns.set_up)
    for s in range(n):
        x, hj = x0 + s, thickness[s]
        m = rows[MASS, s] * hj
        t[INERTIA, x] = m * per_dt
        t[MOMENTUM, x] = m * u_rows[s] * per_dt
        p = weights[s] * hj
        t[PRESSURE, x] = p
        k = _frictional(friction[s], p)
        t[KAPPA, x] = k
        outside += not _within_contract(k)
    for i in range(BLOCK):  # interfaces at rest and the bed: column by column (a few layers each)
        col, x = c0 + i, np.uint64(cell(i, L))
        hj = h[col]
        if inputs.has_rest and inputs.resting[col]:
            mu_j = mu_static + inputs.drop / (1.0 + hj / inputs.length) if inputs.thickness_law else mu_static
            for a in range(L):
                if rest[a, col] and (a == 0 or rest[a - 1, col]):
                    k = _frictional(mu_j, t[PRESSURE, x + np.uint64(a) * lanes])
                    t[KAPPA, x + np.uint64(a) * lanes] = k
                    outside += not _within_contract(k)
        if not inputs.base_bulk[col]:  # the basal condition: the friction of the bed at interface 0
            t[KAPPA, x] = inputs.base_friction[col] * t[PRESSURE, x] + inputs.base_cohesion[col]
        t[VISCOUS, x] = 1.0 if inputs.base_bulk[col] else 0.0
        t[CONDUCTANCE, x] = t[CONDUCTANCE, x] if inputs.base_bulk[col] else 0.0
        flags[FINE, i] = True
    for i in range(BLOCK if outside > 0 else 0):  # which: the same values again
        flags[FINE, i] = column_coefficients(c0 + i, h[c0 + i], inputs, column, cell(i, L), BLOCK, False) == 0


@jit(inline="always")  # inlined: its copies run as vectors in the caller, without a call
def _inverse_spacings(t, L, fraction, thickness):
    """The inverse spacings ``1 / (fraction_a h)`` of the block's cells (1 where the spacing is
    0) and their conductances per unit slope (the inverse; 0 where the spacing is 0: the
    bed's layer is set after), as ``sheared_columns.fixed_parts`` makes them from the
    spacings, into slots ``INV_SPACING`` and ``CONDUCTANCE``, from the spacing fractions of
    the layers and the block's row of thicknesses.  A layer whose fraction is that of the
    layer below has that layer's spacings, so the same inverses: copied, not divided again
    (of equal layers, only the bed's and the first above it divide: two divisions per lane,
    not one per cell, and the same bits)."""
    inverse, conductance = t[INV_SPACING], t[CONDUCTANCE]
    lanes = np.uint64(BLOCK)
    for a in range(np.uint64(L)):  # unsigned: no test for negative indices
        x = np.uint64(cell(0, L)) + a * lanes
        if a > 0 and fraction[a] == fraction[a - np.uint64(1)]:  # the layer below's, as vectors
            below, below_c = _layer(inverse, x - lanes), _layer(conductance, x - lanes)
            for i in range(BLOCK):
                inverse[x + np.uint64(i)] = below[i]
            for i in range(BLOCK):
                conductance[x + np.uint64(i)] = below_c[i]
            continue
        for i in range(BLOCK):
            spacing = fraction[a] * thickness[i]
            value = 1.0 / spacing if spacing > 0.0 else 1.0
            inverse[x + np.uint64(i)] = value
            conductance[x + np.uint64(i)] = value if spacing > 0.0 else 0.0


@jit(borrowing=True)
def join(t, L, flags, first, i, fine, walled):
    """Lanes ``first ... i`` of the block, whose per-step slots ``newton_kernel._chunk`` has set
    up (``fine``, lane i's ``FINE``: its yield values are within the plugin contract), take
    part in the block iteration if ``FINE``, with mass and without a wall threshold (their
    thresholds are read where they may be nonzero, ``walled``; the compiled yield forms
    without walls set them to 0); the test of the mass is ``sheared_columns.block_parts``'."""
    flags[FINE, i] = fine
    for lane in range(first, i + 1):
        x, lanes, held = np.uint64(cell(lane, L)), np.uint64(BLOCK), 0  # held: counted without branches
        for a in range(np.uint64(L if walled else 0)):  # unsigned: no test for negative indices
            held += not t[WALL, x + a * lanes] == 0.0  # a wall threshold (or NaN)
        flags[ACTIVE, lane] = flags[FINE, lane] and held == 0
