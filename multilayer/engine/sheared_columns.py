"""Fully sheared columns of the implicit vertical step, several side by side.

Where every interface of a column shears (the velocity jumps across each one, as in a
chute flow or the body of an avalanche) and no side wall holds a layer, the active set of
``column_kernel._active_set`` makes every layer a group of its own, and the exact solve
of a Newton iteration is one Thomas sweep of the tridiagonal system

    (m_a/dt + c_a + c_{a+1}) u_a - c_a u_{a-1} - c_{a+1} u_{a+1}
        = m_a u*_a/dt - kappa_a s_a + kappa_{a+1} s_{a+1},      a = 0 ... L-1,

with ``u_{-1} = 0`` (the bed), ``c_L = kappa_L = 0`` (the free surface), ``s_a`` the sign
of the jump ``u_a - u_{a-1}`` of the iterate and ``kappa``, ``c`` the yield stresses and
conductances of the Newton model at the iterate (``viscous_law._newton_model``).  The
solution is the exact minimiser of the step's energy when the jumps keep their signs.

The forward sweep is a chain of dependent divisions, one per layer, and column by column
(``newton_kernel._chunk``) the core waits on each.  Here ``BLOCK`` adjacent columns go
through the Newton iteration together: each pass over the layers advances every column
of the block, so that their chains overlap.  Each column's arithmetic is that of
``newton_kernel._chunk``, operation for operation: the same velocities to the bit, the
same iteration counts (tests/test_sheared_columns.py).  A column leaves the block, and
``_chunk`` solves it from the start, where it is not fully sheared, its structure is
rejected, a viscosity is outside the plugin contract, or it is not converged before
iteration ``TRUSTED`` (where the energy test of ``newton_control`` begins).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from multilayer.engine.newton_control import TRUSTED, _sign, error_bound
from multilayer.engine.viscous_law import _newton_model, _viscosity_and_slope

BLOCK = 4
"""Columns solved side by side: four chains of divisions in flight (2, 4 and 8 measured
the same on the chute; the tile holds 18 values per layer for each of the BLOCK + 1
lanes, 46 KB at L = 64)."""

# the tile (BLOCK + 1, SLOTS, L) holds one value per column (lane) and layer: per step,
# m/dt, m u*/dt, the true yield stress, the wall threshold, 1/spacing, the conductance per
# unit slope (0 where not viscous), whether viscous, the pressure parts of the law and the
# guess; per iteration, the Newton model (yield stress, conductance, sign of the jump), the
# forward sweep (inverse pivot, right-hand side), the true viscous stress at the new
# velocities and the two iterates
INERTIA, MOMENTUM, KAPPA, WALL, INV_SPACING, CONDUCTANCE, VISCOUS, FACTOR, OFFSET = range(9)
GUESS, KC, CC, SIGN, DIAG, RHS, TAU, U0, U1 = range(9, 18)
SLOTS = 18
ALONE = BLOCK
"""The lane of the tile (BLOCK + 1, SLOTS, L) that holds the per-step slots of a column
solved on its own (``newton_kernel._chunk``); the block's lanes are 0 ... BLOCK - 1."""

# per-column flags (lanes)
ACTIVE, SHEARED, DONE, FINE = range(4)  # of the boolean lanes


@njit(cache=True)
def join(t, flags, i, fine):
    """Lane ``i`` of the block, whose per-step slots ``newton_kernel._chunk`` has set up
    (``fine``: its yield values are within the plugin contract), takes part in the block
    iteration if ``fine``, with mass and without a wall threshold."""
    take = fine and t[i, INERTIA, 0] > 0.0
    for a in range(t.shape[2]):
        take = take and t[i, WALL, a] == 0.0
    flags[FINE, i] = fine
    flags[ACTIVE, i] = take


@njit(cache=True)
def unload(t, flags, i, viscous, wall_true, guess):
    """Column ``i`` of the block, one it did not finish, into lane ``ALONE`` (the
    column solved on its own by ``newton_kernel._chunk``), with the arrays of one column
    that lane has no slot for (no side walls); returns ``fine``."""
    L = t.shape[2]
    for slot in range(GUESS + 1):
        for a in range(L):
            t[ALONE, slot, a] = t[i, slot, a]
    for a in range(L):
        viscous[a] = t[i, VISCOUS, a] > 0.0
        wall_true[a] = t[i, WALL, a]  # no walls
        guess[a] = t[i, GUESS, a]
    return flags[FINE, i]


@njit(cache=True, error_model="numpy")
def _stresses_and_model(t, u, form, params, flags):
    """At the velocities of slot ``u``: the true viscous stresses (slot ``TAU``; a
    viscosity outside the plugin contract ends the column's block iteration) and the
    Newton model there (``KC``, ``CC``, ``SIGN``), as ``newton_kernel._true_stresses``
    and the model of the next iteration; ``SHEARED`` tells whether every jump is nonzero.
    The pass is compiled once per form, the form a constant in it (its loops then have
    no branches)."""
    if form == 1:
        _stresses_and_model_of(t, u, 1, params, flags)
    elif form == 0:
        _stresses_and_model_of(t, u, 0, params, flags)
    else:
        _stresses_and_model_of(t, u, 2, params, flags)


@njit(cache=True, error_model="numpy")
def _stresses_and_model_of(t, u, form, params, flags):
    """:func:`_stresses_and_model` for one form."""
    L = t.shape[2]
    for i in range(BLOCK):  # no chain across the layers: one column after the other
        faults = 0
        unsheared = 0
        below = 0.0
        for a in range(L):
            g = t[i, u, a]
            jump = g - below
            rate = abs(jump) * t[i, INV_SPACING, a]
            eta, slope = _viscosity_and_slope(form, params, rate, t[i, FACTOR, a], t[i, OFFSET, a])
            within = (eta >= 0.0) & (eta < np.inf)  # the plugin contract
            faults += not within
            unsheared += g == below
            t[i, TAU, a] = eta * rate if t[i, CONDUCTANCE, a] > 0.0 else 0.0
            kappa, conductance = _newton_model(t[i, KAPPA, a], rate, eta, slope, False)
            t[i, KC, a] = kappa if t[i, VISCOUS, a] > 0.0 else t[i, KAPPA, a]
            t[i, CC, a] = conductance * t[i, CONDUCTANCE, a]
            t[i, SIGN, a] = _sign(jump)
            below = g
        flags[ACTIVE, i] = flags[ACTIVE, i] and faults == 0
        flags[SHEARED, i] = unsheared == 0


@njit(cache=True, error_model="numpy")
def _solve(t, new, flags):
    """The exact solve with one group per layer into slot ``new``: the forward sweep
    (inverse pivots ``DIAG``, right-hand sides ``RHS``) and the back substitution of
    ``column_kernel._active_set``, and its optimality test: each yielded jump keeps its
    sign (a column whose structure is rejected leaves the block)."""
    L = t.shape[2]
    for a in range(L):
        for i in range(BLOCK):
            d = 0.0 + (t[i, INERTIA, a] + 0.0)  # _active_set's sums, in its order (cw = w = 0)
            r = 0.0 + t[i, MOMENTUM, a]
            c = t[i, CC, a]
            d += c
            r -= t[i, KC, a] * t[i, SIGN, a]
            if a + 1 < L:
                d += t[i, CC, a + 1]
                r += t[i, KC, a + 1] * t[i, SIGN, a + 1]
            if a > 0 and c != 0.0:
                f = -c * t[i, DIAG, a - 1]
                d -= f * (-c)
                r -= f * t[i, RHS, a - 1]
            if not d > 0.0:
                flags[ACTIVE, i] = False
            t[i, DIAG, a] = 1.0 / d
            t[i, RHS, a] = r
    for a in range(L - 1, -1, -1):
        for i in range(BLOCK):
            r = t[i, RHS, a]
            if a + 1 < L:
                above = t[i, new, a + 1]
                r += t[i, CC, a + 1] * above
                u = r * t[i, DIAG, a]
                if t[i, KC, a + 1] > 0.0 and t[i, SIGN, a + 1] * (above - u) < 0.0:
                    flags[ACTIVE, i] = False
            else:
                u = r * t[i, DIAG, a]
            t[i, new, a] = u
    for i in range(BLOCK):  # the bed
        if t[i, KC, 0] > 0.0 and t[i, SIGN, 0] * t[i, new, 0] < 0.0:
            flags[ACTIVE, i] = False


@njit(cache=True, error_model="numpy")
def _converged(t, new, current, threshold, flags):
    """``DONE``: the error bound of ``newton_control.error_bound`` at slot ``new`` (true
    stresses in ``TAU``) is within ``threshold``, or else the largest change from slot
    ``current`` is: the test of ``_chunk``, column by column."""
    L = t.shape[2]
    for i in range(BLOCK):
        wall = t[i, WALL]  # 0 in every column that takes part (join): no wall threshold or force
        bound = error_bound(
            t[i, INERTIA], t[i, MOMENTUM], t[i, KAPPA], t[i, TAU], wall, wall, t[i, new], threshold
        )
        converged = bound <= threshold
        if not converged:
            change = 0.0
            for a in range(L):
                change = max(change, abs(t[i, new, a] - t[i, current, a]))
            converged = change <= threshold
        flags[DONE, i] = converged


@njit(cache=True, error_model="numpy")
def sheared_block(
    t, flags, finished, form, params, threshold, max_iterations, j0, c0,
    u_out, iterations, fallbacks, faults, fault_values, side_by_side,
):  # fmt: skip
    """The Newton iteration of ``newton_kernel._chunk`` for the ``BLOCK`` columns set up
    in the tile ``t`` (:func:`join`): wet columns ``j0 ...`` of ``_chunk``, mesh columns
    ``c0 ...``, adjacent, without side walls; side by side while each stays fully sheared.
    ``finished[i]`` tells which columns it solved, and wrote into ``_chunk``'s outputs
    (``side_by_side`` True); ``flags`` holds its boolean lanes."""
    L = t.shape[2]
    for i in range(BLOCK):
        finished[i] = False
    current, new = np.int64(U0), np.int64(U1)  # typed int64, not as literals: one compilation
    _stresses_and_model(t, current, form, params, flags)
    for i in range(BLOCK):
        flags[ACTIVE, i] = flags[ACTIVE, i] and flags[SHEARED, i]
    for iteration in range(1, min(max_iterations, TRUSTED - 1) + 1):  # steps kept unconditionally
        _solve(t, new, flags)
        _stresses_and_model(t, new, form, params, flags)  # the bound's stresses, the next model
        _converged(t, new, current, threshold, flags)
        remaining = 0
        for i in range(BLOCK):
            if not flags[ACTIVE, i]:
                continue
            if flags[DONE, i]:
                j = j0 + i
                for a in range(L):
                    u_out[a, c0 + i] = t[i, new, a]
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
            break
        current, new = new, current
