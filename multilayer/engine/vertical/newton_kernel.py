"""The implicit vertical step compiled: viscous linearisation and exact solve fused per column.

``newton.implicit_step`` iterates, over all unconverged columns at once, the Newton model of
the viscous stresses (``StressModel.linearise``, numpy, calling the rheology plugins) and the
exact solver (``column_solve``).  Each column's iteration depends on that column only, so the
same iteration runs here column by column with every quantity in cache, when the bulk and
wall laws declare a compiled form of their viscosity (``Rheology.viscosity_kernel``).  The
model is that of ``stresses.py``, evaluated with what stays fixed during a step (masses,
pressure parts, inverse spacings) computed once per column, except its slope: the compiled
forms differentiate their stress exactly where the numpy path takes a forward difference.
The slope only sets the speed of the iteration (the model passes through the true stress
either way), so both paths agree to round-off times the conditioning of the step, with the
same layers at rest and Newton counts within 1 % (tests/test_newton_kernel.py).  Adjacent
columns that are fully sheared (every interface yielded, no side walls) go through the same
iteration several at a time, side by side (``sheared_columns``), to the same bits.

What only this copy of the iteration does: it never leaves compiled code, and never stores
the coefficients of the whole mesh (they are computed column by column): the path of every
law with compiled forms, the built-in ones included.  The numpy iteration stays for laws
written in Python and for another exact solver (``newton.py``).
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
from numba import prange

from multilayer.engine.compiled import jit, parallel_compiled
from multilayer.engine.plugin_output import PluginOutputError, outside_contract
from multilayer.engine.threads import numba_threads, parallel_chunks
from multilayer.engine.vertical import sheared_columns as sc
from multilayer.engine.vertical.block_coefficients import ROWS, block_coefficients, join, layer_rows
from multilayer.engine.vertical.coefficients import (
    ColumnArrays,
    CompiledCoefficients,
    YieldInputs,
    column_coefficients,
)
from multilayer.engine.vertical.column_solve import _active_set, _dynamic_programme, _workspace, not_finite
from multilayer.engine.vertical.forms import (
    NO_PARAMETERS,
    _newton_model,
    _pressure_parts,
    _viscosity_and_slope,
    as_tuple,
    concave,
    law_of,
)
from multilayer.engine.vertical.newton_control import HALVINGS, energy_rise, error_bound, slope_along
from multilayer.engine.vertical.results import Results, bounds, clear_dry, tally, written
from multilayer.engine.vertical.sheared_columns import (
    ALONE,
    BLOCK,
    cell,
    new_tile,
    sheared_block,
    unload,
)
from multilayer.engine.vertical.stresses import INTERFACE, LAYER, ColumnStresses, StressModel

YIELD_CONTRACT, NOT_FINITE = 1 << 40, 1 << 41
"""Fault codes of a column: compiled yield values outside the plugin contract; an iterate not finite."""
_NOT_GIVEN = ColumnArrays(*(np.zeros((1, 1)),) * 5, np.zeros((1, 1), bool), np.zeros((1, 1)))
"""The ``given`` coefficients of ``_columns`` when they are computed in the kernel."""


class Columns(NamedTuple):
    """The columns a call solves: the wet ones ``wet`` (n,) of the thicknesses ``h`` (N,),
    their velocities after transport ``ustar`` and the guess ``guess`` (L, N)."""

    wet: np.ndarray
    h: np.ndarray
    ustar: np.ndarray
    guess: np.ndarray


class Laws(NamedTuple):
    """The compiled viscosity forms (``forms.FORMS`` code and parameters) of the bulk and
    wall laws, the channel width (0: no walls) and the density."""

    bulk_form: int
    bulk_params: np.ndarray
    wall_form: int
    wall_params: np.ndarray
    width: float
    density: float


class Control(NamedTuple):
    """The step ``dt``, the velocity threshold of convergence, the iteration limit, and
    whether fully sheared columns go side by side (``sheared_columns``)."""

    dt: float
    threshold: float
    max_iterations: int
    blocks: bool


@jit(borrowing=True)
def _true_stresses(
    u, inverse_spacing, conductance, bulk_form, bulk_params, factor, offset, eta, slope, walls,
    inverse_half, wall_form, wall_params, wall_factor, wall_offset, per_area, wall_eta, wall_slope, state,
):  # fmt: skip
    """Viscosities and stress slopes at the velocities ``u`` of one column, and ``state`` (4, L)
    of ``newton_control.energy_rise``: viscous stresses ``|tau_v|`` and their derivatives with
    respect to the jump, viscous wall forces and their derivatives.  Returns the fault code of
    ``_columns`` (0: every viscosity finite and >= 0; ``NOT_FINITE`` where a velocity is not,
    the law not at fault), the viscosity (or velocity) and the rate (or layer)."""
    below = 0.0
    for a in range(u.shape[0]):
        rate = abs(u[a] - below) * inverse_spacing[a]
        below = u[a]
        eta[a], slope[a] = _viscosity_and_slope(bulk_form, bulk_params, rate, factor[a], offset[a])
        if not (eta[a] >= 0.0 and eta[a] < np.inf):  # the plugin contract
            if not rate < np.inf:  # not the law's fault: an iterate that is not finite
                return (NOT_FINITE, u[a], a) if not abs(u[a]) < np.inf else (NOT_FINITE, u[a - 1], a - 1)
            return a + 1, eta[a], rate
        viscous = conductance[a] > 0.0
        state[0, a] = eta[a] * rate if viscous else 0.0
        state[1, a] = max(slope[a], 0.0) * conductance[a]
        state[2, a] = 0.0
        state[3, a] = 0.0
        if walls:
            rate = abs(u[a]) * inverse_half
            wall_eta[a], wall_slope[a] = _viscosity_and_slope(
                wall_form, wall_params, rate, wall_factor[a], wall_offset[a]
            )
            if not (wall_eta[a] >= 0.0 and wall_eta[a] < np.inf):
                return (-(a + 1), wall_eta[a], rate) if rate < np.inf else (NOT_FINITE, u[a], a)
            state[2, a] = per_area[a] * wall_eta[a] * rate
            state[3, a] = per_area[a] * max(wall_slope[a], 0.0) * inverse_half
    return 0, 0.0, 0.0


@jit(borrowing=True)  # not inlined: called only where the structure of the iterate fails
def _other_structures(
    inertia, momentum, kappa, c, w, cw, current, ustar, col, proposal, u, first, grounded, U, diag, low, rhs,
    hint,
):  # fmt: skip
    """Where the active set (``column_solve._active_set``) rejects the lock/sign structure of the iterate
    ``current`` (its ``hint`` of that rejection given): solve with, in turn, the structure of the velocities
    ``ustar`` of column ``col`` before the step, that of ``current`` with its speeds and jumps below ``1e-9
    max |current|`` set to 0 (the round-off of an earlier solve can open a locked interface or set moving a
    layer held by the walls; not tried where that is ``current`` itself, as for a column at rest: the same
    structure, rejected again), the trial structure of the column held at rest (:func:`_trial_structure`: the
    structure of material leaving rest), and that of ``current`` repaired up to L times (one per interface),
    one interface at a time, as each rejection hints (the edge of a plug that moved by a layer).  True once
    one is the exact minimiser (each is checked for optimality by the active set itself), False if none is:
    then the O(L^2) dynamic programme solves.

    A proposal costs an ordinary solve, the dynamic programme about 60 at L = 32 (so a column that still needs
    the programme costs at most L + 3 solves more); in the peer dam break the first two take the share of the
    solves that need the programme from 0.22 % to 0.09 %; the trial structure solves the first step of a
    uniform layer released from rest on a slope steeper than its friction angle (every column needed the
    programme there); the repairs solve most of the rest under a non-hydrostatic pressure, whose columns hold
    several plugs whose edges move."""
    L = current.shape[0]
    interface, state = hint[0], hint[1]  # the rejection of current
    for attempt in range(3 + L):
        if attempt == 0:
            for a in range(L):
                proposal[a] = ustar[a, col]
        elif attempt == 1:
            top = 0.0
            for a in range(L):
                top = max(top, abs(current[a]))
            below = 0.0  # the bed
            same = True
            for a in range(L):
                value = current[a] if abs(current[a]) > 1e-9 * top else 0.0
                proposal[a] = below if abs(value - below) <= 1e-9 * top else value
                below = proposal[a]
                same = same and proposal[a] == current[a]
            if same:  # current itself (a column at rest, one without such speeds): rejected
                continue
        elif attempt == 2:
            _trial_structure(momentum, kappa, w, proposal)
        else:
            if interface < 0:
                return False
            if attempt == 3:
                for a in range(L):
                    proposal[a] = current[a]
            # the interface locked (state 0) or sliding with the sign state; the layers
            # above move with it, keeping their jumps (a locked one stays exactly locked)
            below = proposal[interface - 1] if interface > 0 else 0.0
            value = below
            if state != 0:
                top = 0.0
                for a in range(L):
                    top = max(top, abs(proposal[a]))
                value = below + state * (1e-6 * top if top > 0.0 else 1.0)
            shift = value - proposal[interface]
            proposal[interface] = value
            for a in range(interface + 1, L):
                proposal[a] += shift
        if _active_set(
            inertia, momentum, kappa, c, w, cw, proposal, u, first, grounded, U, diag, low, rhs, hint
        ):  # fmt: skip
            return True
        if attempt >= 3:
            interface, state = hint[0], hint[1]
    return False


@jit(borrowing=True)
def _trial_structure(momentum, kappa, w, proposal):
    """The lock/sign structure (as velocities for ``column_solve._active_set``) of a trial from rest, as the
    elastic predictor of plasticity: with the whole column held at rest, the interface below layer ``a``
    carries the force ``F_a = sum_{b >= a} m_b u*_b / dt`` of the layers above, of which their walls hold
    at most ``sum_{b >= a} w_b``; an interface where the rest exceeds its yield stress ``kappa_a`` slides
    in the direction of ``F_a``, the others stay locked."""
    L = momentum.shape[0]
    force = 0.0
    held = 0.0
    for a in range(L - 1, -1, -1):  # the forces, top down, kept in proposal for the pass up
        force += momentum[a]
        held += w[a]
        proposal[a] = force
    below = 0.0  # the bed
    for a in range(L):
        force = proposal[a]
        proposal[a] = below
        if abs(force) > kappa[a] + held:
            proposal[a] += 1.0 if force > 0.0 else -1.0
        below = proposal[a]
        held -= w[a]


@jit
def _chunk(k, chunks, columns, inputs, fused, given, laws, control, out):
    """Chunk ``k`` of ``chunks`` of :func:`_columns` (its wet columns ``k n // chunks`` to
    ``(k + 1) n // chunks``): compiled once, called on one thread as the one chunk
    (``_serial``) and by the parallel kernel per chunk.  Allocates the work arrays of the
    chunk, then iterates its columns (:func:`_iterate`, without reference counting).  The
    named tuples of the arguments come as plain tuples (:func:`_plain`) and are named here."""
    columns, inputs, given = Columns(*columns), YieldInputs(*inputs), ColumnArrays(*given)
    laws, control, out = Laws(*laws), Control(*control), Results(*out)
    L = inputs.l.size
    sweep = BLOCK * L
    work = (
        _workspace(L),
        np.empty(L + 1, np.int64),  # first, grounded, U, diag, low, rhs of the active set
        np.empty(L, np.bool_),
        np.empty(L),
        np.empty(L),
        np.empty(L),
        np.empty(L),
        np.empty(2, np.int64),  # hint: of a structure the active set rejects
        np.empty(L),  # kc, cc: the Newton model's interface yield stresses, conductances
        np.empty(L),
        np.empty(L),  # wc, cwc: and wall thresholds, wall conductances
        np.zeros(L),
        np.empty(L),  # current, new
        np.empty(L),
        np.zeros(L),  # zero: the viscous stresses of a column at rest
        np.empty(L),  # proposal: a structure proposed to the active set; a point of a line search
        np.empty((4, L)),  # viscosities, stress slopes, wall viscosities, wall slopes at current
        np.empty((4, L)),  # and at new
        np.empty((4, L)),  # state_c, state_n of newton_control.energy_rise
        np.empty((4, L)),
        new_tile(L),  # the work arrays of sheared_block, and lane ALONE
        np.empty(L),  # m (the pressures and spacings: in the tile, sheared_columns.PRESSURE, SPACING)
        np.ones(L, np.bool_),  # viscous (above layer 0: coefficients.column_coefficients)
        np.zeros((5, L)),  # wall_pressure, wall_factor, wall_offset, per_area, wall_true
        np.empty((sc.FLAGS, BLOCK), np.bool_),  # flags, finished of sheared_block
        np.zeros(BLOCK, np.bool_),
        # the sweeps of sheared_block, an array each (the compiler tells apart two arrays, not two rows)
        (np.empty(sweep), np.empty(sweep), np.empty(sweep), np.empty(sweep), np.empty(sweep)),
        np.empty((1 + ROWS, L * BLOCK)),  # the u* rows of sheared_columns.load, those of block_coefficients
    )
    _iterate(k, chunks, columns, inputs, fused, given, laws, control, out, work)


@jit(borrowing=True)  # reference counting cost a fifth of the instructions of a column at rest
def _iterate(k, chunks, columns, inputs, fused, given, laws, control, out, work):
    """The Newton iterations of the columns of chunk ``k`` (:func:`_chunk`) in its work
    arrays ``work``: borrowed (``compiled.jit``), as are the arrays of every callee."""
    wet, h, ustar, guess = columns.wet, columns.h, columns.ustar, columns.guess
    # the parameters as tuples: passed to the forms without reference counting
    bulk_form, bulk_params = laws.bulk_form, as_tuple(laws.bulk_params)
    wall_form, wall_params = laws.wall_form, as_tuple(laws.wall_params)
    width, density = laws.width, laws.density
    dt, threshold = control.dt, control.threshold
    max_iterations, blocks = control.max_iterations, control.blocks
    u_out, iterations, fallbacks, faults = out.u, out.iterations, out.fallbacks, out.faults
    fault_values, side_by_side = out.fault_values, out.side_by_side
    L = inputs.l.size
    n = wet.size
    walls = width > 0.0
    inverse_half = 2.0 / width if walls else 0.0
    # the tangent and chord bounds of newton_control.energy_rise hold
    concave_stresses = concave(bulk_form, bulk_params) and (not walls or concave(wall_form, wall_params))
    ws, first, grounded, U, diag, low, rhs, hint = work[:8]
    kc, cc, wc, cwc, current, new, zero, proposal = work[8:16]
    # viscosities, stress slopes and viscous stresses at current and new (interfaces, walls)
    laws_c, laws_n, state_c, state_n, tile, coefficients, viscous, walls_of = work[16:24]
    flags, finished, sweeps = work[24], work[25], work[26]
    u_rows, rows = work[27][0], work[27][1:]  # rows: of block_coefficients
    iterates = tile[sc.U0]  # where sc.load puts a block's guesses
    eta_c, slope_c, weta_c, wslope_c = laws_c[0], laws_c[1], laws_c[2], laws_c[3]
    eta_n, slope_n, weta_n, wslope_n = laws_n[0], laws_n[1], laws_n[2], laws_n[3]
    # the coefficients of StressModel.columns of the column (coefficients.column_coefficients)
    m = coefficients
    wall_pressure = walls_of[0]
    # and from them, per layer, in the tile (lane ALONE: the column solved on its own; the lanes of a
    # block are set up straight into their own): m_a / dt, m_a u*_a / dt, the yield stresses, inverse
    # spacing, conductance per unit slope (0 where not viscous), pressure parts of the bulk law, the
    # wall yield threshold per unit area (else the wall threshold); with walls, the pressure parts
    # of the wall law, the wall area factor (2 / W) h_a, and the true wall thresholds
    alone = slice(cell(ALONE, L), cell(ALONE, L) + L)
    inertia, momentum, kappa = tile[sc.INERTIA, alone], tile[sc.MOMENTUM, alone], tile[sc.KAPPA, alone]
    wall, inverse_spacing = tile[sc.WALL, alone], tile[sc.INV_SPACING, alone]
    conductance, factor, offset = tile[sc.CONDUCTANCE, alone], tile[sc.FACTOR, alone], tile[sc.OFFSET, alone]
    wall_factor, wall_offset, per_area, wall_true = walls_of[1], walls_of[2], walls_of[3], walls_of[4]
    # the yield stresses, wall thresholds, pressures and spacings straight into the rows of the tile
    # (at a lane's cells)
    column = ColumnArrays(
        m, tile[sc.KAPPA], tile[sc.WALL], tile[sc.PRESSURE], tile[sc.SPACING], viscous, wall_pressure
    )
    g_m, g_kappa, g_w, g_pressure = given.m, given.kappa, given.w, given.pressure  # read once per chunk
    g_spacing, g_viscous, g_wall = given.spacing, given.viscous, given.wall_pressure
    start, stop = k * n // chunks, (k + 1) * n // chunks
    layer_rows(inputs, rows)  # (read where fused only)
    # The columns are set up in turn.  A group of BLOCK adjacent columns without walls goes into
    # the tile and is solved side by side (sheared_block); the columns it did not finish come
    # back from the tile one by one (``drain``) to the iteration below.
    following, j0, block, drain = start, start, False, BLOCK
    while True:
        if drain < BLOCK:  # a column of the last block that it did not finish
            j = j0 + drain
            drain += 1
            if finished[j - j0]:
                continue
            col = wet[j]
            fine = unload(tile, L, flags, j - j0, guess, col, viscous, wall_true, current)
        else:
            if following == stop:
                break
            j, col = following, wet[following]
            following += 1
            if (j - start) % BLOCK == 0:
                j0 = j
                block = blocks and not walls and j + BLOCK <= stop and wet[j + BLOCK - 1] - col == BLOCK - 1
                if block:  # the block's u* and guesses, row by row
                    sc.load(u_rows, iterates, ustar, guess, col)
                if block and fused:  # and its coefficients, laid out as the tile
                    block_coefficients(col, h, inputs, tile, L, column, flags, rows, dt, u_rows)
                    j, following = j + BLOCK - 1, j + BLOCK  # its lanes set up: joined at once (join)
            lane = j - j0 if block else ALONE
            o, step = cell(lane, L), sc.step(lane)  # the lane's layer a: cell o + a step of the tile
            # the coefficients of StressModel.columns: from the compiled yield forms, or given (the
            # yield stresses and wall thresholds straight into the lane's slots)
            if fused and block:
                fine = flags[sc.FINE, lane]
            elif fused:
                fine = column_coefficients(col, h[col], inputs, column, o, 1, False) == 0
            else:
                fine = True
                for a in range(L):
                    x = np.uint64(o + a * step)
                    m[a], tile[sc.KAPPA, x], tile[sc.WALL, x] = g_m[a, j], g_kappa[a, j], g_w[a, j]
                    tile[sc.PRESSURE, x], tile[sc.SPACING, x] = g_pressure[a, j], g_spacing[a, j]
                    viscous[a] = g_viscous[a, j]
                    wall_pressure[a] = g_wall[a, j]
            # what stays fixed during the iteration, a few rows per loop over the layers (a loop
            # over all reloads its rows' pointers), the laws' switch outside them
            if not (fused and block):  # m/dt, m u*/dt (a block's masses and bed layer: block_coefficients)
                sc.set_up(tile, L, lane, m, dt, ustar, guess, col, current)
            layers = 0 if fused and block else 1 if fused else L  # compiled yield forms: layer 0 alone
            for a in range(layers):  # (new_tile: 1.0 above)
                tile[sc.VISCOUS, np.uint64(o + a * step)] = 1.0 if viscous[a] else 0.0
            if not block:  # a block's lanes: all together once set up (sc.block_parts)
                sc.fixed_parts(tile, o, o + L, bulk_form, bulk_params, h[col], np.bool_(True), np.bool_(True))
            if walls and not block:
                start_of_walls = np.int64(0)  # not the literal 0: one compilation for both laws
                _pressure_parts(
                    wall_form, wall_params, wall_pressure, h[col], wall_factor, wall_offset, start_of_walls
                )
                for a in range(L):
                    per_area[a] = (2.0 / width) * m[a] / density
                    wall[a] = wall[a] / max(per_area[a], 1e-300)  # the wall threshold, per unit area
                    wall_true[a] = per_area[a] * wall[a]
            elif not block:
                for a in range(L):
                    wall_true[a] = wall[a]
            if block:
                join(tile, L, flags, 0 if fused else lane, lane, fine, not fused or inputs.walls)
                if lane == BLOCK - 1:
                    sc.block_parts(tile, L, bulk_form, bulk_params, h, wet, j0, dt, u_rows, flags, fused)
                    sheared_block(
                        tile, sweeps, flags, finished, bulk_form, bulk_params, threshold, max_iterations, j0,
                        wet[j0], u_out, iterations, fallbacks, faults, fault_values, side_by_side,
                    )  # fmt: skip
                    drain = 0
                continue
        if not fine:
            faults[j] = YIELD_CONTRACT  # outside the plugin contract: see CompiledStep
            continue
        wall_c = wc if walls else wall
        iterations[j] = -1
        fallbacks[j] = 0
        # a guess at rest in every layer has no jump and no slip: no viscous stress, whatever the
        # laws, and the bound reads none; the laws are evaluated for a column to iterate
        resting = inertia[0] > 0.0
        for a in range(L):
            resting = resting and current[a] == 0.0
        bound = np.inf
        if resting:
            bound = error_bound(inertia, momentum, kappa, zero, wall_true, zero, current, threshold)
        fault, fault_values[j, 0], fault_values[j, 1] = 0, 0.0, 0.0
        if not bound <= threshold:
            fault, fault_values[j, 0], fault_values[j, 1] = _true_stresses(
                current, inverse_spacing, conductance, bulk_form, bulk_params, factor, offset, eta_c, slope_c,
                walls, inverse_half, wall_form, wall_params, wall_factor, wall_offset, per_area, weta_c,
                wslope_c, state_c,
            )  # fmt: skip
            if (
                fault == 0
                and not resting
                and inertia[0] > 0.0
                and current[0] == 0.0
                and current[L - 1] == 0.0
            ):
                bound = error_bound(
                    inertia, momentum, kappa, state_c[0], wall_true, state_c[2], current, threshold
                )
        last = max_iterations  # 0 for a guess at rest within the bound (see _columns)
        if fault == 0 and bound <= threshold:
            iterations[j] = 0
            last = 0
        for iteration in range(1, last + 1):
            if fault != 0:
                break
            # the Newton model at the current velocities (StressModel.linearise)
            below = 0.0
            for a in range(L):
                rate = abs(current[a] - below) * inverse_spacing[a]
                below = current[a]
                ka, t = _newton_model(kappa[a], rate, eta_c[a], slope_c[a])
                kc[a] = ka if viscous[a] else kappa[a]
                cc[a] = t * conductance[a]
                if walls:
                    rate = abs(current[a]) * inverse_half
                    wa, ta = _newton_model(wall[a], rate, weta_c[a], wslope_c[a])
                    wc[a] = per_area[a] * wa
                    cwc[a] = per_area[a] * ta * inverse_half
            if not inertia[0] > 0.0:  # no mass: nothing to solve
                for a in range(L):
                    current[a] = 0.0
                iterations[j] = iteration
                break
            if not _active_set(
                inertia, momentum, kc, cc, wall_c, cwc, current, new, first, grounded, U, diag, low, rhs, hint
            ) and not _other_structures(
                inertia, momentum, kc, cc, wall_c, cwc, current, ustar, col, proposal, new, first, grounded,
                U, diag, low, rhs, hint,
            ):  # fmt: skip
                _dynamic_programme(inertia, momentum, kc, cc, wall_c, cwc, new, ws)
                fallbacks[j] += 1
            fault, fault_values[j, 0], fault_values[j, 1] = _true_stresses(
                new, inverse_spacing, conductance, bulk_form, bulk_params, factor, offset, eta_n, slope_n,
                walls, inverse_half, wall_form, wall_params, wall_factor, wall_offset, per_area, weta_n,
                wslope_n, state_n,
            )  # fmt: skip
            if fault != 0:
                break
            done = (
                error_bound(inertia, momentum, kappa, state_n[0], wall_true, state_n[2], new, threshold)
                <= threshold
            )
            if not done:
                change = 0.0
                for a in range(L):
                    change = max(change, abs(new[a] - current[a]))
                done = change <= threshold
            if done or energy_rise(
                inertia, momentum, kappa, state_n[0], wall_true, state_n[2], current, new,
                state_c[0], state_c[1], state_c[2], state_c[3], concave_stresses,
            ) <= 0.0:  # fmt: skip
                # the full step (newton_control)
                current, new = new, current
                eta_c, eta_n, slope_c, slope_n = eta_n, eta_c, slope_n, slope_c
                weta_c, weta_n, wslope_c, wslope_n = weta_n, weta_c, wslope_n, wslope_c
                state_c, state_n = state_n, state_c
                if done:
                    iterations[j] = iteration
                    break
                continue
            # the damped step: the minimiser of phi(t) = E(current + t (new - current)) on [0, 1],
            # bisected on the sign of phi'(t+); the closing pass evaluates the point taken
            size = 0.0
            for a in range(L):
                size = max(size, abs(new[a] - current[a]))
            lo, hi = 0.0, 1.0
            for halving in range(HALVINGS + 1):
                closing = halving == HALVINGS or not (hi - lo) * size > threshold
                mid = (lo if lo > 0.0 else hi) if closing else 0.5 * (lo + hi)
                for a in range(L):
                    proposal[a] = current[a] + mid * (new[a] - current[a])
                fault, fault_values[j, 0], fault_values[j, 1] = _true_stresses(
                    proposal, inverse_spacing, conductance, bulk_form, bulk_params, factor, offset, eta_n,
                    slope_n, walls, inverse_half, wall_form, wall_params, wall_factor, wall_offset, per_area,
                    weta_n, wslope_n, state_n,
                )  # fmt: skip
                if fault != 0 or closing:
                    break
                if slope_along(
                    inertia, momentum, kappa, state_n[0], wall_true, state_n[2], current, new, proposal, 1.0
                ) >= 0.0:  # fmt: skip
                    hi = mid
                else:
                    lo = mid
            if fault != 0:
                break
            current, proposal = proposal, current
            eta_c, eta_n, slope_c, slope_n = eta_n, eta_c, slope_n, slope_c
            weta_c, weta_n, wslope_c, wslope_n = weta_n, weta_c, wslope_n, wslope_c
            state_c, state_n = state_n, state_c
        faults[j] = fault
        for a in range(L):
            u_out[a, col] = current[a]
            if not abs(current[a]) < np.inf and fault == 0:  # a non-finite iterate compares as converged
                fault = faults[j] = NOT_FINITE
                fault_values[j, 0], fault_values[j, 1] = current[a], a


def _columns(chunks, columns, inputs, fused, given, laws, control, out):
    """Newton iterations of every wet column (``wet`` indexes the columns of h, ustar and guess);
    ``fallbacks`` counts the solves per column that needed the O(L^2) dynamic programme.  A
    column where a compiled viscosity is not finite and >= 0 stops iterating: ``faults`` gets
    a + 1 for the bulk law at interface a, -(a + 1) for the wall law of layer a (0: none),
    ``fault_values`` the viscosity and the shear rate; one with compiled yield values outside
    the plugin contract is not solved (``YIELD_CONTRACT``), one with an iterate not finite stops.

    The coefficients of ``StressModel.columns`` come, with ``fused``, from the compiled
    yield forms column by column (``coefficients.column_coefficients`` with ``inputs``),
    so that the whole mesh never holds them (on a fully wet mesh, writing and reading
    them back costs more memory traffic than the Newton step of a column in cache);
    otherwise from the (L, n) arrays ``given`` (m, kappa, w, pressure, spacing, viscous,
    wall_pressure).  What does not change from one iteration to the next (masses,
    pressure parts of the laws, inverse spacings, wall thresholds) is computed once per
    step, straight into the tile of ``sheared_columns``: into a block's lane, or into the
    lane ``ALONE``, whose rows are the arrays of the column solved on its own (views made
    once per chunk: per-column views or tuples of arrays each cost reference counting).
    A column whose guess is at rest at the bed and the surface and already within the
    error bound of ``newton_control`` is not solved (``iterations`` 0): the bound is
    rigorous, so the guess is as good an answer as a converged iterate.  A guess at rest in
    every layer has no velocity jump and no slip, hence no viscous stress whatever the laws:
    its bound is computed without evaluating them (the laws of the material at rest, most
    of a deposit, are evaluated only where a column has to be iterated).

    With ``blocks``, adjacent columns without side walls are set up ``BLOCK`` at a time
    and iterated side by side while fully sheared (``sheared_columns.sheared_block``;
    ``side_by_side`` marks the columns it solved); the others, and those that leave the
    block, are iterated here one by one, to the same bits."""
    for k in prange(chunks):
        # k is unsigned under prange: one signature of _chunk for both kernels
        _chunk(np.int64(k), chunks, columns, inputs, fused, given, laws, control, out)


def _plain(columns, inputs, fused, given, laws, control, out):
    """The arguments of :func:`_chunk` after ``chunks``, each named tuple as a plain tuple: numba's dispatcher
    types a tuple of arrays in compiled code, a named tuple field by field in Python (4 of 9 us a call)."""
    return tuple(columns), tuple(inputs), fused, tuple(given), tuple(laws), tuple(control), tuple(out)


_parallel = parallel_compiled(_columns)
_serial = functools.partial(_chunk, 0, 1)
"""The kernel on one thread: ``_columns`` without ``chunks``, as its one chunk (no serial
wrapper of ``_chunk`` to compile: numba optimises a callee again inside each caller)."""


class CompiledStep:
    """The compiled implicit step of a stress model, for laws that have compiled forms.

    The laws are read from the stress model at each use, so a law swapped on a running
    simulation is honoured (and without a compiled form sends the step to numpy).
    """

    def __init__(self, stresses: StressModel, *, side_by_side: bool = True):
        self.stresses = stresses
        self.coefficients = CompiledCoefficients(stresses)  # StressModel.columns, compiled
        self.side_by_side = side_by_side  # fully sheared columns BLOCK at a time (sheared_columns)
        self.columns = 0  # column steps so far
        self.columns_side_by_side = 0  # of which solved side by side
        self.solves = 0  # column solves so far
        self.fallbacks = 0  # of which by the O(L^2) dynamic programme (the active set failed)
        self.not_converged = 0  # columns of the last call not converged within max_iterations
        self.most_iterations = 1  # the most Newton iterations of a column in the last call (at least 1)
        # the results, two reused in turn from call to call, and their columns that may be non-zero
        self._out: list[np.ndarray] = []
        self._written = [(0, 0), (0, 0)]

    def laws(self) -> tuple[tuple[int, np.ndarray], tuple[int, np.ndarray] | None] | None:
        """(bulk, walls) compiled forms, None when some law has none."""
        return self.stresses.forms("viscosity", self._read_laws)

    def _read_laws(self) -> tuple[tuple[int, np.ndarray], tuple[int, np.ndarray] | None] | None:
        s = self.stresses
        bulk = law_of(s.bulk, s.material)
        walls = law_of(s.walls, s.material) if s.walls is not None else None
        if bulk is None or (s.walls is not None and walls is None):
            return None
        return bulk, walls

    def __call__(
        self,
        h: np.ndarray,
        ustar: np.ndarray,
        u_guess: np.ndarray,
        dt: float,
        *,
        threshold: float,
        max_iterations: int,
        threads: int = 1,
        rest: np.ndarray | None = None,
        yield_gravity: np.ndarray | None = None,
        known: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """New velocities (L, N) and the Newton iterations of each wet column solved (-1: not converged
        within ``max_iterations``; counted in :attr:`not_converged` and :attr:`most_iterations`).  The
        velocities are overwritten by the call after the next (a time step of order 2 keeps its first
        vertical step's while it makes the second).  ``rest`` and ``yield_gravity`` go to
        ``StressModel.columns`` (compiled: ``coefficients.CompiledCoefficients``).  ``known = (same,
        answer)``: the wet columns ``same`` (N,) take the velocities of ``answer`` (L, N) unsolved."""
        laws = self.laws()
        if laws is None:
            raise ValueError("a law of this stress model has no compiled form (see laws())")
        (bulk_form, bulk_params), walls = laws
        occupied = (h > 0).nonzero()[0]  # (h is (N,): np.flatnonzero, without its Python wrappers)
        wet = occupied if known is None else occupied[~known[0][occupied]]  # (the others: answers known)
        inputs, fused = self.coefficients.inputs(rest, yield_gravity, window := bounds(occupied))  # (lo, hi)
        given = _NOT_GIVEN if fused else self._given(self.coefficients(h, wet, rest, yield_gravity))
        if not self._out or self._out[0].shape != ustar.shape:
            self._out, self._written = [np.zeros_like(ustar), np.zeros_like(ustar)], [(0, 0), (0, 0)]
        self._out.reverse()  # the other one: the result of the last call stays
        self._written.reverse()
        (lo, hi), u = self._written[0], self._out[0]
        thickness = np.ascontiguousarray(h, dtype=float)
        clear_dry(u, thickness, lo, hi)  # zero outside them already; the kernel writes the wet ones
        self._written[0] = written(u, window, known)  # the known answers written
        out = Results(
            u, np.empty(wet.size, np.int64), np.empty(wet.size, np.int64), np.empty(wet.size, np.int64),
            np.empty((wet.size, 2)), np.zeros(wet.size, np.bool_),
        )  # fmt: skip
        iterations, faults = out.iterations, out.faults
        wall_form, wall_params = walls if walls is not None else (0, NO_PARAMETERS)
        columns = Columns(wet, thickness, np.ascontiguousarray(ustar), np.ascontiguousarray(u_guess))
        compiled_laws = Laws(
            bulk_form, bulk_params, wall_form, wall_params,
            float(self.stresses.width) if walls is not None else 0.0, float(self.stresses.material.density),
        )  # fmt: skip
        control = Control(float(dt), float(threshold), int(max_iterations), self.side_by_side)
        # one thread: the chunk kernel itself, as one chunk (no serial wrapper to compile)
        kernel = functools.partial(_parallel, parallel_chunks(threads, wet.size)) if threads > 1 else _serial
        with numba_threads(threads):
            kernel(*_plain(columns, inputs, fused, given, compiled_laws, control, out))
        counts = tally(out, max_iterations)
        if counts[0]:  # a fault
            if (bad := np.flatnonzero(faults == NOT_FINITE)).size:  # never taken as converged
                x = float(self.stresses.x[wet[bad[0]]])
                raise not_finite(out.fault_values[bad[0]], x, self.stresses.t)
            # the plugins' own methods: they raise, naming the plugin, for a yield value outside the contract
            cs = self.stresses.columns(h, wet, rest, yield_gravity)
            if (faults == YIELD_CONTRACT).any():  # a compiled yield form that disagrees with its plugin
                out.side_by_side[:] = False
                with numba_threads(threads):
                    kernel(*_plain(columns, inputs, False, self._given(cs), compiled_laws, control, out))
            if faults.any():
                raise self._fault(cs, faults, out.fault_values)
            counts = tally(out, max_iterations)  # of the call with the plugins' yield values
        _, self.not_converged, self.most_iterations, solves, fallbacks, side_by_side = counts
        self.columns += wet.size
        self.columns_side_by_side += side_by_side
        self.solves += solves
        self.fallbacks += fallbacks
        return u, iterations

    @staticmethod
    def _given(cs: ColumnStresses) -> ColumnArrays:
        """The (L, n) coefficients of the kernel when they are not computed in it."""
        arrays = (cs.m, cs.kappa, cs.w, cs.pressure, cs.spacing, cs.viscous, cs.wall_pressure)
        return ColumnArrays(*(np.ascontiguousarray(a) for a in arrays))

    def _fault(self, cs: ColumnStresses, faults: np.ndarray, values: np.ndarray) -> PluginOutputError:
        """The error naming the law, the viscosity and where, for the first column whose
        compiled viscosity was outside the plugin contract (``faults`` of ``_columns``)."""
        j = int(np.flatnonzero(faults)[0])
        bulk, a = faults[j] > 0, abs(int(faults[j])) - 1
        pressure = cs.pressure[a, j] if bulk else cs.wall_pressure[a, j]
        return outside_contract(
            self.stresses.bulk if bulk else self.stresses.walls, "viscosity()", float(values[j, 0]),
            x=float(cs.x[j]), where=(INTERFACE if bulk else LAYER).format(index=a, number=a + 1),
            t=self.stresses.t, given={"shear rate": float(values[j, 1]), "pressure": float(pressure)},
            note=f"its compiled form, viscosity_kernel; {int(np.count_nonzero(faults))} column(s) affected",
        )  # fmt: skip
