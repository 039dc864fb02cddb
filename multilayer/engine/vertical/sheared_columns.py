"""Fully sheared columns of the implicit vertical step, several side by side.

Where every interface of a column shears (the velocity jumps across each one, as in a
chute flow or the body of an avalanche) and no side wall holds a layer, the active set of
``column_solve._active_set`` makes every layer a group of its own, and the exact solve
of a Newton iteration is one Thomas sweep of the tridiagonal system

    (m_a/dt + c_a + c_{a+1}) u_a - c_a u_{a-1} - c_{a+1} u_{a+1}
        = m_a u*_a/dt - kappa_a s_a + kappa_{a+1} s_{a+1},      a = 0 ... L-1,

with ``u_{-1} = 0`` (the bed), ``c_L = kappa_L = 0`` (the free surface), ``s_a`` the sign
of the jump ``u_a - u_{a-1}`` of the iterate and ``kappa``, ``c`` the yield stresses and
conductances of the Newton model at the iterate (``forms._newton_model``).  The
solution is the exact minimiser of the step's energy when the jumps keep their signs.

The forward sweep is a chain of dependent divisions, one per layer, and column by column
(``newton_kernel._chunk``) the core waits on each.  Here ``BLOCK`` adjacent columns go
through the Newton iteration together: each pass over the layers advances every column
of the block, so that their chains overlap.  Each column's arithmetic is that of
``newton_kernel._chunk``, operation for operation: the same velocities to the bit, the
same iteration counts (tests/test_sheared_columns.py).  A column leaves the block, and
``_chunk`` solves it from the start, where it is not fully sheared, its structure is
rejected, a viscosity is outside the plugin contract, or its Newton step is damped (the
rise bound of ``newton_control`` is positive: ``_chunk`` makes the line search).

What only this copy does: it is the same iteration as ``newton_kernel._chunk`` for a
special case, kept for speed alone (the chains of divisions of several columns overlap;
docs/performance.md); every answer it gives is ``_chunk``'s to the bit, so it can be
switched off (``CompiledStep(side_by_side=False)``) without changing a result.
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.vertical.coefficients import _within_contract
from multilayer.engine.vertical.forms import (
    INERTIAL_PLATEAU,
    _newton_model,
    _pressure_parts,
    _viscosity_and_slope,
    concave,
)
from multilayer.engine.vertical.newton_control import (
    _potential_rise,
    _sign,
    error_bound,
    slope_along,
)

BLOCK = 8
"""Columns solved side by side: eight chains of divisions in flight, and the pass of the
stresses and the Newton model one loop over the 8 L cells of the block, long enough to
run as vectors at L = 8 (compiled, the loop runs as vectors of 8 values from about 40
cells on, and one cell at a time below: 22-29 against 51-53 ns per column and pass at
L = 8).  The tile holds 23 values per layer for each of the BLOCK + 1 lanes, 215 KB at
L = 128 (the 3 of the bounds touched only where a column is tested by them), the sweeps of
the solve 5 per layer and lane, 41 KB, and the rows of :func:`load` and of the block's
coefficients 8, 66 KB."""

# The tile (SLOTS, 2 BLOCK + (BLOCK + 1) L) holds, in each slot (a row), one value per
# column (lane) and layer, laid out as the mesh and the sweeps of :func:`_solve`: layer a
# of the block's lane i in cell BLOCK + a BLOCK + i (a layer's BLOCK lanes side by side,
# the cell below one BLOCK places before it), then lane ALONE's layers one after the
# other (contiguous: the arrays of ``newton_kernel._chunk``).  The BLOCK cells below the
# bottom layer and above the top one are pads: a loop may load the cells below and above
# unconditionally (no masked loads).  The pads below hold the bed's velocity, 0.0, in the
# slots of the iterates ``U0``, ``U1`` (written by nothing: the velocity below the bottom
# layer is loaded as any other, without a select);
# the pads above hold 0.0 in the slots of the Newton model ``KC``, ``CC``, ``SIGN`` (the
# free surface: :func:`_equation`);
# the slot BED marks the bottom cells and the pads above the top ones (1.0: the free
# surface, a select).  :func:`lane_of` is one lane's view, its layers contiguous.
# The slots: per step,
# m/dt, m u*/dt, the true yield stress, the wall threshold, 1/spacing, the conductance
# per unit slope (0 where not viscous), whether viscous, the pressure parts of the law
# and, once the block has finished the column, its velocities (``KEPT``); per
# iteration, the Newton model (yield stress, conductance, sign of the jump), the two
# iterates and, at each,
# the true viscous stresses and their derivatives (``TAU0 + k``, ``STIFF0 + k`` at the
# iterate ``U0 + k``: the rise bound of ``newton_control`` needs both iterates'); fixed,
# 1.0 in the bottom cell of each lane (the bed below it) and 0.0 elsewhere; per test of a
# column, each layer's term of the error bound (``GAP``), the sums of these terms from the
# surface down to each layer (``RISE``) and the smallest m/dt down to each (``SMALLEST``),
# then the sums of the rise bound's terms from the bed up to each (``RISE``: no wall term,
# see :func:`_converged`);
# while the column is set up, before any test, two of these hold its interface pressures
# and layer spacings (``PRESSURE``, ``SPACING``, :func:`fixed_parts`).
INERTIA, MOMENTUM, KAPPA, WALL, INV_SPACING, CONDUCTANCE, VISCOUS, FACTOR, OFFSET = range(9)
KEPT, KC, CC, SIGN, U0, U1, TAU0, TAU1, STIFF0, STIFF1, BED, GAP, RISE, SMALLEST = range(9, 23)
SLOTS = 23
PRESSURE, SPACING = GAP, RISE
# The arrays of the sweeps of :func:`_solve`, a value per layer and lane in each: the pivot
# (then the inverse pivot), right-hand side, conductance below, the pivots not positive up
# to the layer (then the velocities changed by more than the threshold down to it), and the
# velocity.
PIVOT, RIGHT, COUPLING, TRIED, SOLVED = range(5)
SWEEPS = 5
ALONE = BLOCK
"""The lane of the tile that holds the per-step slots of a column solved on its own
(``newton_kernel._chunk``); the block's lanes are 0 ... BLOCK - 1."""

# per-column flags (lanes)
ACTIVE, SHEARED, DONE, FINE = range(4)  # of the boolean lanes
FLAGS = 4


@jit
def new_tile(L):
    """The tile of columns of ``L`` layers, zero but for the ``BED`` slot and the ``VISCOUS``
    slot, 1.0 (the compiled yield forms set it in the bottom layer alone: see
    ``newton_kernel._chunk``)."""
    t = np.zeros((SLOTS, cell(ALONE, L) + L))
    for i in range(BLOCK + 1):
        t[BED, cell(i, L)] = 1.0
    for i in range(BLOCK):  # the pads above the block's top layers: the free surface
        t[BED, cell(i, L) + BLOCK * L] = 1.0
    t[VISCOUS] = 1.0
    return t


@jit(inline="always")  # inlined: no compilation of its own
def cell(i, L):
    """The cell of layer 0 of lane ``i`` in the tile's rows (columns of ``L`` layers); its
    layer a is ``step(i)`` a cells further."""
    return BLOCK + i if i < BLOCK else 2 * BLOCK + BLOCK * L


@jit(inline="always")  # inlined: no compilation of its own
def step(i):
    """The cells from a layer of lane ``i`` to the next in the tile's rows."""
    return BLOCK if i < BLOCK else 1


@jit(inline="always")
def lane_of(t, i):
    """The rows of the block's lane ``i`` as a view of the tile: its layer a in cell 1 + a,
    the pads below (cell 0) and above (cell L + 1), as a tile of one lane for the passes and
    tests made lane by lane (the cell below one place before it)."""
    return t[:, i::BLOCK]


@jit(inline="always")
def _layer(source, s):
    """The ``BLOCK`` (8) values ``source[s] ... source[s + 7]``, one layer of the block's lanes
    side by side, all read before any is written: a copy of them then runs as vectors (LLVM
    cannot tell that two arrays do not overlap, and keeps each read after the write before
    it: a load and a store per value)."""
    o, one = np.uint64(s), np.uint64(1)  # unsigned: no test for negative indices
    a, b, c, d = o + one, o + np.uint64(2), o + np.uint64(3), o + np.uint64(4)
    e, f, g = o + np.uint64(5), o + np.uint64(6), o + np.uint64(7)
    return source[o], source[a], source[b], source[c], source[d], source[e], source[f], source[g]


@jit(borrowing=True)
def load(u_rows, iterate, ustar, guess, c0):
    """The velocities after transport and the guesses of the block's columns ``c0 ... c0 +
    BLOCK - 1`` of the (L, N) arrays ``ustar`` and ``guess`` (adjacent columns), laid out as
    the mesh: the velocities into ``u_rows`` (L BLOCK), the guesses into the tile's row
    ``iterate`` (slot ``U0``: the first iterate of :func:`sheared_block`) at the block's
    cells; row by row, each row's BLOCK values one or two cache lines, read once for the
    whole block and copied as vectors (each value to one place: copied to two, they were
    copied one at a time).  Column by column, each column
    would read its L values a row of the mesh apart, one value from each of L cache lines
    (at N = 20 000 the rows are 160 000 B apart: the lines of a column fall in a few sets of
    the L1 cache, and are gone before the next column would use them).  The tile is laid
    out as these rows: :func:`block_parts` reads ``u_rows`` into its slot ``MOMENTUM``
    (times m/dt) in one pass as vectors."""
    x0 = np.uint64(cell(0, ustar.shape[0]))
    for a in range(np.uint64(ustar.shape[0])):  # unsigned: no test for negative indices
        u, g = _layer(ustar[a], c0), _layer(guess[a], c0)
        for i in range(BLOCK):
            u_rows[a * np.uint64(BLOCK) + np.uint64(i)] = u[i]
        for i in range(BLOCK):
            iterate[x0 + a * np.uint64(BLOCK) + np.uint64(i)] = g[i]


@jit(inline="always")  # inlined: its loops run as vectors in the caller, without a call
def set_up(t, L, lane, m, dt, ustar, guess, col, current):
    """The slots ``INERTIA`` and ``MOMENTUM`` (``m/dt``, ``m u*/dt``) of lane ``lane`` and
    its guess, of the masses ``m``: a block's lane (``lane < BLOCK``) only its masses, into
    ``MOMENTUM`` (:func:`block_parts` makes the slots of the whole block at once, from them
    and the rows of :func:`load`, laid out as the tile); lane ``ALONE`` those of column
    ``col`` of the (L, N) arrays ``ustar`` and ``guess``, the guess into ``current``.

    Both are products with ``1/dt``, ``m (1/dt)`` and ``(m u*) (1/dt)``: one division per
    call instead of two per cell (a division costs many products' throughput), the same
    operations in every place that makes them (:func:`block_parts`,
    ``block_coefficients``, ``column_solve``, ``newton.implicit_step``), so the same bits;
    each lies within an ulp or so of ``m/dt``."""
    o = np.uint64(cell(lane, L))  # unsigned: no test for negative indices
    if lane < BLOCK:  # the masses into MOMENTUM: the rest for the whole block in block_parts
        for a in range(np.uint64(L)):
            t[MOMENTUM, o + a * np.uint64(BLOCK)] = m[a]
        return
    for a in range(L):
        t[MOMENTUM, o + np.uint64(a)] = ustar[a, col]
        current[a] = guess[a, col]
    per_dt = 1.0 / dt
    for a in range(np.uint64(L)):  # contiguous: as vectors
        t[INERTIA, o + a] = m[a] * per_dt
        t[MOMENTUM, o + a] = m[a] * t[MOMENTUM, o + a] * per_dt


@jit(inline="always")  # inlined: no compilation of its own
def block_end(L):
    """The cell after the block's lanes (the first pad above them) in the tile's rows."""
    return cell(0, L) + BLOCK * L


@jit(borrowing=True)
def fixed_parts(t, start, stop, form, params, h, pressures, spacings):
    """What stays fixed during a step in cells ``start ... stop - 1`` of the tile, from their
    spacings (slot ``SPACING``), whether viscous (``VISCOUS``) and interface pressures
    (``PRESSURE``): with ``spacings``, the inverse spacing (1 where the spacing is 0) and the
    conductance per unit slope (the inverse spacing; 0 where not viscous or the spacing is
    0); with ``pressures``, the pressure parts of the bulk law ``form``
    (``forms._pressure_parts``, the column thickness ``h``)."""
    for x in range(
        np.uint64(start), np.uint64(stop if spacings else start)
    ):  # unsigned: no test for negative indices
        s = t[SPACING, x]
        inverse = 1.0 / s if s > 0.0 else 1.0
        t[INV_SPACING, x] = inverse
        t[CONDUCTANCE, x] = inverse if s > 0.0 and t[VISCOUS, x] > 0.0 else 0.0
    if pressures:
        _pressure_parts(form, params, t[PRESSURE, start:stop], h, t[FACTOR], t[OFFSET], start)


@jit(borrowing=True)
def block_parts(t, L, form, params, h, wet, j0, dt, u_rows, flags, made):
    """The block's lanes, set up (the wet columns ``j0 ...`` of the thicknesses ``h``, their
    masses in ``MOMENTUM``: :func:`set_up`; their guesses in ``U0``: :func:`load`): ``m/dt``
    and ``m u*/dt`` (products with ``1/dt``, as :func:`set_up` makes them; the u* of the rows
    of :func:`load`, laid out as the tile) in one pass
    over their cells as vectors, and so
    :func:`fixed_parts` (the pressure parts lane by lane for a law of the column thickness,
    ``forms.INERTIAL_PLATEAU``); a lane without mass at its bed leaves the block
    (``ACTIVE``).  With ``made``, all but the ``ACTIVE`` flags and the pressure parts are
    made (``block_coefficients``, in its pass)."""
    x0, per_dt = np.uint64(cell(0, L)), 1.0 / dt  # unsigned: no test for negative indices
    for s in range(np.uint64(0 if made else BLOCK * L)):
        x = x0 + s
        m = t[MOMENTUM, x]
        t[INERTIA, x] = m * per_dt
        t[MOMENTUM, x] = m * u_rows[s] * per_dt
    for i in range(BLOCK):
        flags[ACTIVE, i] = flags[ACTIVE, i] and t[INERTIA, cell(i, L)] > 0.0
    plateau = form == INERTIAL_PLATEAU
    fixed_parts(t, cell(0, L), block_end(L), form, params, 0.0, not plateau, not made)
    for i in range(BLOCK if plateau else 0):
        lane, start = lane_of(t, i), np.int64(1)  # typed, not the literal 1: one compilation
        _pressure_parts(
            form, params, lane[PRESSURE, 1 : L + 1], h[wet[j0 + i]], lane[FACTOR], lane[OFFSET], start
        )


@jit(borrowing=True)
def unload(t, L, flags, i, guesses, col, viscous, wall_true, guess):
    """Column ``i`` of the block, one it did not finish, into lane ``ALONE`` (the
    column solved on its own by ``newton_kernel._chunk``), with the arrays of one column
    that lane has no slot for (no side walls) and its guess (column ``col`` of the (L, N)
    guesses ``guesses``: the block's iterates are written over it); returns ``fine``."""
    lane, alone = lane_of(t, i), np.uint64(cell(ALONE, L) - 1)
    for slot in range(OFFSET + 1):  # the per-step slots
        for a in range(np.uint64(1), np.uint64(L + 1)):  # unsigned: no test for negative indices
            t[slot, alone + a] = lane[slot, a]
    for a in range(np.uint64(L)):
        viscous[a] = lane[VISCOUS, a + np.uint64(1)] > 0.0
        wall_true[a] = lane[WALL, a + np.uint64(1)]  # no walls
        guess[a] = guesses[a, col]
    return flags[FINE, i]


@jit(borrowing=True, error_model="numpy")
def _stresses_and_model(t, L, u, form, params, flags, model):
    """At the velocities of slot ``u``: the true viscous stresses (slot ``TAU0 + u - U0``; a
    viscosity outside the plugin contract ends the column's block iteration), as
    ``newton_kernel._true_stresses``, and with ``model`` their derivatives (``STIFF0 + u -
    U0``) and the Newton model there (``KC``, ``CC``, ``SIGN``), for the next iteration
    (a column done at ``u`` reads neither: the model is formed once the test has left a
    column to iterate); ``SHEARED`` tells whether every jump is nonzero.  Without ``model``,
    ``u`` is the answer of :func:`_solve` to the model in place, and the pass also makes the
    rest of its optimality test (a column with a yielded jump against its model's sign
    leaves the block).
    The block's lanes are swept as one loop over their cells (the bed below the bottom
    cell of each lane); where some column is unsheared, outside the contract or rejected, its lanes
    are swept again one by one (:func:`lane_of`) to tell which (the same values again).  The pass is
    compiled once per built-in form, the form a literal constant in it (its loop then has
    no branches; ``forms.INERTIAL``, ``CONSTANT``, ``POWER``); any other form of
    ``forms.FORMS`` runs the pass compiled for every form (the same values)."""
    start, stop, below = cell(0, L), block_end(L), BLOCK
    if form == 1:
        faults, unsheared = _sweep(t, u, 1, params, start, stop, below, model)
    elif form == 0:
        faults, unsheared = _sweep(t, u, 0, params, start, stop, below, model)
    elif form == 2:
        faults, unsheared = _sweep(t, u, 2, params, start, stop, below, model)
    else:
        faults, unsheared = _sweep(t, u, form, params, start, stop, below, model)
    if faults == 0 and unsheared == 0:  # every column within the contract and fully sheared
        for i in range(BLOCK):
            flags[SHEARED, i] = True
        return
    for i in range(BLOCK):  # each lane's view: a tile of one lane
        lane_faults, lane_unsheared = _sweep(lane_of(t, i), u, form, params, 1, L + 1, 1, model)
        flags[ACTIVE, i] = flags[ACTIVE, i] and lane_faults == 0
        flags[SHEARED, i] = lane_unsheared == 0


@jit(borrowing=True, error_model="numpy")
def _sweep(t, u, form, params, start, stop, down, model):
    """Cells ``start ... stop - 1`` of the tile's rows of :func:`_stresses_and_model` (the
    velocities in slot ``u``, the cell below ``down`` places before; the stores of the
    model with ``model`` only, a condition the compiler takes out of the loop); returns the
    faults, the viscosities outside the plugin contract and, without ``model``, the yielded
    interfaces (``KC`` > 0, the bed's included) the jump crosses against the sign ``SIGN``
    of the model (the test of ``column_solve._active_set``) and the velocities that are not
    finite (finite as ``coefficients._within_contract`` tells; ``_chunk`` names them: a
    column leaves the block for it to solve), and how many jumps are zero."""
    faults = unsheared = 0
    tau, stiffness, down = TAU0 + (u - U0), STIFF0 + (u - U0), np.uint64(down)
    for x in range(np.uint64(start), np.uint64(stop)):  # unsigned: no test for negative indices
        g, below = t[u, x], t[u, x - down]  # below the bottom layer: the pads, 0.0 (the bed)
        jump = g - below
        rate = abs(jump) * t[INV_SPACING, x]
        eta, slope = _viscosity_and_slope(form, params, rate, t[FACTOR, x], t[OFFSET, x])
        within = _within_contract(eta)  # the plugin contract
        faults += not within
        unsheared += g == below
        t[tau, x] = eta * rate if t[CONDUCTANCE, x] > 0.0 else 0.0
        if model:
            t[stiffness, x] = max(slope, 0.0) * t[CONDUCTANCE, x]
            kappa, conductance = _newton_model(t[KAPPA, x], rate, eta, slope)
            t[KC, x] = kappa if t[VISCOUS, x] > 0.0 else t[KAPPA, x]
            t[CC, x] = conductance * t[CONDUCTANCE, x]
            t[SIGN, x] = _sign(jump)
        else:
            faults += ((t[KC, x] > 0.0) & (t[SIGN, x] * jump < 0.0)) | (not g * 0.0 == 0.0)
    return faults, unsheared


@jit(borrowing=True, error_model="numpy")
def _solve(t, w, L, new, threshold, flags):
    """The exact solve with one group per layer into slot ``new``: the forward sweep and
    the back substitution of ``column_solve._active_set``, and its optimality test: each
    pivot is positive (a column whose structure is rejected leaves the block; the pass of the
    stresses at slot ``new`` tests that each yielded jump keeps its sign, :func:`_sweep`).
    As the velocities are substituted back, the layers whose velocity changed by more than
    ``threshold`` from the iterate before (a NaN change not counted) are counted down each
    lane, so that the bottom cells of the sweep ``TRIED`` hold each lane's count: the first
    test of :func:`_converged`, without a pass of its own.  The iterate before is read from
    the sweep ``SOLVED`` it is overwritten in (the last solve's, or the guesses
    :func:`sheared_block` puts there), not from the tile: a loop that also loads the tile
    runs one value at a time.

    The sweeps run in ``w``, ``SWEEPS`` arrays of ``BLOCK L`` values, each the block's
    layers one after the other and each layer its ``BLOCK`` lanes side by side (layer a
    of lane i in ``a BLOCK + i``), so that each sweep is one loop over the values in which
    a value depends on the one ``BLOCK`` places below (or above) it: the loop runs as
    vectors of the lanes of a layer, with no loop over the lanes inside it (in separate
    arrays, the compiler can tell that each value depends on none nearer than that).
    The tile is laid out as these arrays: the equations of each layer (``_active_set``'s
    sums, in its order: :func:`_equation`) are formed from it and swept forward in one pass
    over the block's cells as vectors, then substituted back (each operation that of
    ``_active_set``: the same bits), counting the failures of the pivots up the column (so
    that the top layer holds each lane's), the velocities going to slot ``new`` of the tile
    as they are made.  Indices are unsigned (as in :func:`_sweep`): no test for negative
    indices.

    Where the conductance ``c`` below a layer is 0, ``_active_set`` leaves its equation as
    formed; here it is eliminated all the same, without a branch (no masked loads): ``f``
    is then a zero, which leaves ``d`` and ``r`` as they are, neither being -0.0 (each sum of
    :func:`_equation` starts from +0.0; a difference of equal values is +0.0).  Only where
    the pivot or right-hand side below is not finite (or a pivot overflows) is it NaN: the
    column's pivot is then not positive or its velocities not finite (:func:`_sweep`), and
    it leaves the block for ``_chunk``, whose answer is the block's."""
    one, lanes, layers = np.uint64(1), np.uint64(BLOCK), np.uint64(L)
    n = layers * lanes  # the values of an array
    pivot, right, coupling, tried, solved = w[PIVOT], w[RIGHT], w[COUPLING], w[TRIED], w[SOLVED]
    x0, top = np.uint64(cell(0, L)), n - lanes  # the tile laid out as the sweeps, from cell x0
    for s in range(lanes):  # layer 0: nothing below to eliminate
        c, d, r = _equation(t, x0 + s, lanes)
        coupling[s] = c
        right[s] = r
        tried[s] = 0.0 if d > 0.0 else 1.0
        pivot[s] = 1.0 / d
    for s in range(lanes, n):  # formed and swept forward: the value below is BLOCK places before
        c, d, r = _equation(t, x0 + s, lanes)
        b = s - lanes
        f = -c * pivot[b]  # eliminated where c is 0 too (_equation: d and r are then kept)
        d = d - f * (-c)
        coupling[s] = c
        right[s] = r - f * right[b]
        tried[s] = tried[b] + (0.0 if d > 0.0 else 1.0)
        pivot[s] = 1.0 / d
    for lane in range(BLOCK):  # the test of the pivots (tried is then the count of the changes)
        if tried[top + np.uint64(lane)] > 0.0:
            flags[ACTIVE, lane] = False
    for s in range(top, n):  # the back substitution: the value above is BLOCK places after
        last, v = solved[s], right[s] * pivot[s]
        solved[s] = v
        t[new, x0 + s] = v
        tried[s] = 1.0 if abs(v - last) > threshold else 0.0
    for b in range(lanes, n):
        s = n - one - b
        above, last = solved[s + lanes], solved[s]
        v = (right[s] + coupling[s + lanes] * above) * pivot[s]
        solved[s] = v
        t[new, x0 + s] = v  # (v, not solved[s] again: the compiler cannot tell the arrays apart)
        tried[s] = tried[s + lanes] + (1.0 if abs(v - last) > threshold else 0.0)


@jit(inline="always")
def _equation(t, x, lanes):
    """The conductance below, diagonal and right-hand side of the equation of cell ``x`` of
    the tile (``_active_set``'s sums, in its order, with ``cw = w = 0``): the interface
    above is ``lanes`` places after (above the top layer, the pads: 0.0 adds nothing, the
    sums being neither -0.0 nor changed by it)."""
    c, k_above, s_above = t[CC, x], t[KC, x + lanes], t[SIGN, x + lanes]
    d = 0.0 + (t[INERTIA, x] + 0.0)
    r = 0.0 + t[MOMENTUM, x]
    d += c
    r -= t[KC, x] * t[SIGN, x]
    d += t[CC, x + lanes]
    r += k_above * s_above
    return c, d, r


@jit(inline="always")
def _together(lanes, L):
    """Whether a pass of the tests over the block's cells costs less than one over each of
    ``lanes`` of its lanes: a pass's set-up (its loops' overlap checks and the call) costs
    about as many instructions as ``PASS_CELLS`` of its cells."""
    return lanes * (L + PASS_CELLS) > BLOCK * L + PASS_CELLS


PASS_CELLS = 12
"""The set-up of a pass of the tests over some cells of the tile, in cells (:func:`_together`)."""


@jit(borrowing=True, error_model="numpy")
def _converged(t, L, new, current, threshold, concave_stress, flags, beyond):
    """``DONE``: the largest change from slot ``current`` to slot ``new`` is within
    ``threshold`` (``beyond``, each lane's count of the layers that changed by more:
    :func:`_solve`), or else the error bound of ``newton_control.error_bound`` at ``new`` (its
    true stresses in ``TAU0 + new - U0``) is: the test of ``_chunk``, column by column, its
    cheaper half first (a few instructions per layer against some 55 for the bound; in a
    steady chute most columns are done by the change).  A column not done whose rise bound
    (``newton_control.energy_rise``) is positive leaves the block (``ACTIVE`` False):
    ``_chunk`` damps its step.  The sums of both bounds are made each lane's in the order
    of ``error_bound`` and ``newton_control.rise_bound``, each cell's sum that of the cell
    before it in the lane plus its own terms (:func:`_sums`, :func:`_rise_terms`): a pass
    over the block's cells runs as vectors, the lanes side by side.  The terms of the
    bounds go through one pass over the block's cells where most of its columns need them
    (:func:`_together`), else a pass over each column's.  The rise bound is without its
    wall's potential term: a column of the block has no wall threshold, force or stiffness
    (``block_coefficients.join``), so that term is a zero (of either sign), or NaN where a speed is not
    finite, and then so is the wall term of the layer (0 times it): leaving it out of the
    sum changes at most the sign of a zero sum, which neither test of the sum tells apart."""
    bounded = 0  # the columns to test by the error bound (fully sheared)
    for i in range(BLOCK):  # the largest change within threshold (max ignores a NaN change, as this count)
        flags[DONE, i] = beyond[i] == 0.0 and 0.0 <= threshold
        bounded += not flags[DONE, i] and flags[SHEARED, i]
    together = _together(bounded, L)
    if together:
        _gaps(t, cell(0, L), block_end(L), new, np.uint64(BLOCK))
        _sums(t, L)
    rising = 0  # the columns not done
    for i in range(BLOCK):
        if flags[DONE, i]:
            continue
        v, lane = lane_of(t, i), slice(1, L + 1)
        if flags[SHEARED, i] and together:
            converged = _bounded(v[RISE, 1], v[SMALLEST, 1], threshold)  # the lane's bottom cell
        elif flags[SHEARED, i]:
            _gaps(v, 1, L + 1, new, np.uint64(1))
            converged = _within_bound(v, 1, L, threshold)
        else:
            wall = v[WALL, lane]  # 0 in every column that takes part (join): no wall threshold or force
            bound = error_bound(
                v[INERTIA, lane], v[MOMENTUM, lane], v[KAPPA, lane], v[TAU0 + (new - U0), lane], wall, wall,
                v[new, lane], threshold,
            )  # fmt: skip
            converged = bound <= threshold
        flags[DONE, i] = converged
        rising += not converged
    together = _together(rising, L)
    if together:
        _rise_terms(t, cell(0, L), block_end(L), new, current, concave_stress, np.uint64(BLOCK))
    for i in range(0 if rising == 0 else BLOCK):
        if flags[DONE, i]:
            continue
        v = lane_of(t, i)
        if not together:
            _rise_terms(v, 1, L + 1, new, current, concave_stress, np.uint64(1))
        rise = v[RISE, L]  # the lane's top cell: the sum of all its layers
        if not rise <= 0.0:  # newton_control.energy_rise, the smaller of it and phi'(1-)
            lane = slice(1, L + 1)
            wall, u_new = v[WALL, lane], v[new, lane]
            tau_new = v[TAU0 + (new - U0), lane]
            rise = min(
                slope_along(
                    v[INERTIA, lane], v[MOMENTUM, lane], v[KAPPA, lane], tau_new, wall, wall,
                    v[current, lane], u_new, u_new, -1.0,
                ),
                rise,
            )  # fmt: skip
        if rise > 0.0:
            flags[ACTIVE, i] = False


@jit(borrowing=True, error_model="numpy")
def _rise_terms(t, start, stop, new, current, concave_stress, one):
    """The rise bound of :func:`_converged` of cells ``start ... stop - 1``, from slot
    ``current`` to slot ``new``: each layer's terms as ``newton_control.rise_bound`` makes
    them (the layer below read from the cell below, ``one`` place before; below the bottom
    layer, the pads' 0.0, the bed's), added to the sum of the cell below in its order, into
    slot ``RISE`` (0.0 in the pads below)."""
    one = np.uint64(one)
    for y in range(np.uint64(start) - one, np.uint64(start)):  # the pads below: no sum yet
        t[RISE, y] = 0.0
    for y in range(np.uint64(start), np.uint64(stop if one == 1 else start)):  # a lane: as the column
        _rise(t, y, new, current, concave_stress, np.uint64(1))
    for y in range(np.uint64(start), np.uint64(start if one == 1 else stop)):  # the lanes side by side
        _rise(t, y, new, current, concave_stress, np.uint64(BLOCK))  # (BLOCK a constant: as vectors)


@jit(inline="always")
def _rise(t, y, new, current, concave_stress, one):
    """Cell ``y`` of :func:`_rise_terms` (unsigned), the cell below ``one`` place before."""
    at, tau_new = current - U0, TAU0 + (new - U0)
    u, start_u, below, below_start = t[new, y], t[current, y], t[new, y - one], t[current, y - one]
    jump = abs(u - below)  # magnitudes of the jumps
    jump_start = abs(start_u - below_start)
    inertial = (u - start_u) * (0.5 * t[INERTIA, y] * (u + start_u) - t[MOMENTUM, y])
    frictional = t[WALL, y] * (abs(u) - abs(start_u)) + t[KAPPA, y] * (jump - jump_start)
    viscous = _potential_rise(
        jump_start, jump, t[TAU0 + at, y], t[STIFF0 + at, y], t[tau_new, y], concave_stress
    )
    t[RISE, y] = t[RISE, y - one] + inertial + frictional + viscous  # rise_bound's order


@jit(borrowing=True, error_model="numpy")
def _gaps(t, start, stop, new, one):
    """Each layer's term of the error bound of :func:`_converged` at the velocities of slot
    ``new``, of cells ``start ... stop - 1`` (whole lanes), into slot ``GAP``: for a lane
    whose every jump is nonzero (``SHEARED``), the stress of each interface is single-valued
    (``sign(jump) (kappa + tau_v)``), so that the gap of each layer depends on its values
    and the stress above alone (0 at the free surface: above the top cell of a lane is a
    pad, ``BED``; the cells below and above ``one`` place away).  Each operation is that of
    ``error_bound``, but the wall terms of ``newton_control.zeroing``: a column of the
    block has no wall threshold or force (``block_coefficients.join``), and the zero they subtract could only
    change the sign of a zero end of the interval, which no positive gap depends on."""
    tau, one = TAU0 + (new - U0), np.uint64(one)
    for y in range(np.uint64(start), np.uint64(stop)):  # unsigned: no test for negative indices
        u, below = t[new, y], t[new, y - one]  # loaded unconditionally (the pads below: 0.0, the bed's)
        stress = _sign(t[new, y + one] - u) * (t[KAPPA, y + one] + t[tau, y + one])
        above = 0.0 if t[BED, y + one] > 0.0 else stress  # the interface above: 0 at the free surface
        zero = above + (t[MOMENTUM, y] - t[INERTIA, y] * u)  # newton_control.zeroing, without walls
        sigma = _sign(u - below) * (t[KAPPA, y] + t[tau, y])
        gap = max(zero - sigma, sigma - zero, 0.0)
        t[GAP, y] = gap * gap / t[INERTIA, y] if gap > 0.0 else 0.0


@jit(borrowing=True, error_model="numpy")
def _sums(t, L):
    """The sums of the terms of :func:`_gaps` and the smallest ``m/dt`` of every lane of the
    block, from the surface down to each layer as ``error_bound`` makes them (the same
    operations in the same order: the same bits): a pass down the block's cells as
    vectors, each cell's from the cell above (``BLOCK`` places after, a constant: a
    separate pass, as the recurrence of a pass that also read the rows of :func:`_gaps`
    needed more run-time overlap checks than LLVM makes, and ran one cell at a time), into
    slots ``RISE`` and ``SMALLEST`` (the pads above the top layer 0.0 and inf; the sums in
    place of the terms ran one cell at a time).  The bottom cells hold each lane's."""
    end, lanes = np.uint64(block_end(L)), np.uint64(BLOCK)
    for x in range(end, end + lanes):  # the pads above the top layer
        t[RISE, x], t[SMALLEST, x] = 0.0, np.inf
    for b in range(np.uint64(BLOCK * L)):  # unsigned: no test for negative indices
        y = end - np.uint64(1) - b
        t[SMALLEST, y] = min(t[SMALLEST, y + lanes], t[INERTIA, y])
        t[RISE, y] = t[RISE, y + lanes] + t[GAP, y]


@jit(borrowing=True, error_model="numpy")
def _within_bound(t, x, L, limit):
    """:func:`_bounded` of the lane whose layer 0 is cell ``x`` (the arguments of
    :func:`_converged`), from the terms of its layers in slot ``GAP`` (:func:`_gaps`), added
    up from the surface down as ``error_bound`` adds them."""
    top = np.uint64(x + L - 1)  # unsigned: no test for negative indices
    residual = 0.0
    smallest = np.inf
    for b in range(np.uint64(L)):
        y = top - b
        smallest = min(smallest, t[INERTIA, y])
        residual += t[GAP, y]
    return _bounded(residual, smallest, limit)


@jit(inline="always")
def _bounded(residual, smallest, limit):
    """``newton_control.error_bound(...) <= limit`` from the sum ``residual`` of its terms
    and the smallest ``m/dt`` of a lane (:func:`_gaps`).  The answer is ``error_bound``'s:
    where the sum exceeds ``4 limit^2`` times the smallest ``m/dt`` so far, the bound
    exceeds ``2 limit``, and as the sum only grows and the smallest only shrinks, that holds
    at some layer exactly when it holds at the last: the test is made once, after the sum."""
    return not residual > 4.0 * limit * limit * smallest and np.sqrt(residual / smallest) <= limit


@jit(borrowing=True)
def _keep(t, L, new, lanes):
    """The velocities of slot ``new`` of the lanes in the bit mask ``lanes`` into slot ``KEPT``,
    kept for the output (a later solve writes over slot ``new``)."""
    if lanes == (1 << BLOCK) - 1:  # every lane: one copy as vectors
        for x in range(np.uint64(cell(0, L)), np.uint64(block_end(L))):
            t[KEPT, x] = t[new, x]
        return
    for i in range(BLOCK):
        v = lane_of(t, i)
        for y in range(np.uint64(1), np.uint64(L + 1 if lanes >> i & 1 else 1)):
            v[KEPT, y] = v[new, y]


@jit(borrowing=True, error_model="numpy")
def sheared_block(
    t, sweeps, flags, finished, form, params, threshold, max_iterations, j0, c0,
    u_out, iterations, fallbacks, faults, fault_values, side_by_side,
):  # fmt: skip
    """The Newton iteration of ``newton_kernel._chunk`` for the ``BLOCK`` columns set up
    in the tile ``t`` (``block_coefficients.join``; their guesses in slot ``U0``: :func:`load`): wet
    columns ``j0 ...`` of
    ``_chunk``, mesh columns ``c0 ...``, adjacent, without side walls; side by side while
    each stays fully sheared.  ``finished[i]`` tells which columns it solved, and wrote into
    ``_chunk``'s outputs (``side_by_side`` True): their velocities at the end, row by row
    when it finished every column; ``flags`` holds its boolean lanes."""
    L = u_out.shape[0]
    for i in range(BLOCK):
        finished[i] = False
    current, new = np.int64(U0), np.int64(U1)  # typed int64, not as literals: one compilation
    concave_stress = concave(form, params)
    model, stresses = np.bool_(True), np.bool_(False)  # not literals: one compilation
    _stresses_and_model(t, L, current, form, params, flags, model)
    for i in range(BLOCK):
        flags[ACTIVE, i] = flags[ACTIVE, i] and flags[SHEARED, i]
    solved, x0 = sweeps[SOLVED], np.uint64(cell(0, L))  # the guesses, as _solve reads its iterate
    for s in range(np.uint64(BLOCK * L)):  # unsigned: no test for negative indices
        solved[s] = t[U0, x0 + s]
    last = 0  # the columns finished by the last iteration (a bit each), when it finished the block
    for iteration in range(1, max_iterations + 1):
        _solve(t, sweeps, L, new, threshold, flags)
        _stresses_and_model(t, L, new, form, params, flags, stresses)  # the bound's stresses
        _converged(t, L, new, current, threshold, concave_stress, flags, sweeps[TRIED][:BLOCK])
        remaining, now = 0, np.int64(0)  # now typed: one compilation of _keep
        for i in range(BLOCK):
            if not flags[ACTIVE, i]:
                continue
            if flags[DONE, i]:
                j = j0 + i
                now |= 1 << i
                iterations[j] = iteration
                fallbacks[j] = 0
                faults[j] = 0
                fault_values[j, 0] = 0.0
                fault_values[j, 1] = 0.0
                side_by_side[j] = True
                finished[i] = True
                flags[ACTIVE, i] = False
            elif not flags[SHEARED, i]:
                flags[ACTIVE, i] = False
            else:
                remaining += 1
        if remaining == 0:
            last = now
            break
        _keep(t, L, new, now)  # before the next solve writes over slot new
        _stresses_and_model(t, L, new, form, params, flags, model)  # the next model (the same flags)
        current, new = new, current
    # the velocities of the columns it finished: of all of them row by row, as load reads them
    # (column by column, each column's L stores fall a row of the mesh apart); where the last
    # iteration finished every column, from the last solve's sweeps, which hold them row by row
    together = last == (1 << BLOCK) - 1
    if not together:
        _keep(t, L, new, last)
    lanes = np.uint64(BLOCK)
    for a in range(np.uint64(L if together else 0)):  # unsigned: no test for negative indices
        row = _layer(solved, a * lanes)
        for i in range(BLOCK):
            u_out[a, np.uint64(c0 + i)] = row[i]
    every = not together
    for i in range(BLOCK):
        every = every and finished[i]
    kept = t[KEPT]  # the tile laid out as the mesh
    for a in range(np.uint64(L if every else 0)):
        row = _layer(kept, x0 + a * lanes)
        for i in range(BLOCK):
            u_out[a, np.uint64(c0 + i)] = row[i]
    for i in range(0 if every or together else BLOCK):
        for a in range(np.uint64(L if finished[i] else 0)):
            u_out[a, np.uint64(c0 + i)] = kept[x0 + a * lanes + np.uint64(i)]
