"""Compiled transport step: the scheme of ``reference.py`` fused into one sweep per stage.

``reference.py`` (numpy) is the reference formulation; this module computes the same
step (hydrostatic reconstruction of Audusse et al. 2004, minmod slopes, HLL fluxes per
layer, mass exchange with upwinded velocity, bed slope and gravity sources, forward
Euler or Heun, a partly open gate) with the same floating-point operations in the same
order, so both give the same bits (tests/test_transport_kernel.py).

Each stage is one sweep over the occupied window in tiles of about ``TILE`` cells
(columns x layers).  A tile loads its columns and two ghosts per side, reconstructs its
cells, computes the fluxes of its faces and updates its cells, each pass layer by layer
over the tile's columns: the rows of the (L, N) state are read and written in contiguous
runs, and the work arrays of a tile stay in the L2 cache whatever the mesh size.  So the
only arrays the size of the mesh are the state, the intermediate Heun state and the
result.  The window is cut into chunks of columns that are swept independently (the
face between two chunks or tiles is computed by both, identically), handed out to the
threads one at a time (``threads.parallel_chunks``).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import prange

from multilayer.engine.compiled import jit, parallel_compiled
from multilayer.engine.state import moving_columns
from multilayer.engine.threads import numba_threads, parallel_chunks
from multilayer.engine.transport import boundaries
from multilayer.engine.transport.boundaries import COPY, STATE, WRAP
from multilayer.engine.transport.reference import (
    MARGIN,
    second_stage_start,
    stages,
    step_boundary_mass,
    step_mass_time,
)

TILE = 16384
"""Cells (columns x layers) of one tile of the sweep: its work arrays (about 0.9 MB at 64
layers) stay in a 2 MB L2 cache, and each loop's set-up per layer is shared by 256 columns."""


@jit
def _minmod(back, ahead):
    """``reference._minmod_slope`` of one cell (the same value, bit for bit)."""
    a, b = abs(back), abs(ahead)
    smaller = a if a < b else b
    signed = smaller if back > 0.0 else -smaller
    return signed if back * ahead > 0.0 else 0.0  # values, no branches: the loops vectorise


_source = jit(boundaries.ghost_source)
"""The window column (and how) of a state column of a tile (``boundaries.ghost_source``)."""


@jit
def _work(L, T):
    """Work arrays of a tile of at most ``T`` cells of ``L`` layers (one set per chunk):
    per column (ghosts included), per layer and column, per face, per layer and face."""
    columns = (np.empty(T + 4, np.int64), np.empty(T + 4, np.int64))  # mesh column, how loaded
    scalars = np.empty((6, T + 4))  # h, b, h_w, h_e, b_w, b_e
    layers = np.empty((3, L, T + 4))  # u, u_w, u_e
    faces = np.empty((9, T + 1))  # hL, hR, the weights of the HLL flux, the pressures, resting
    fluxes = np.empty((2, L, T + 1))  # mass and momentum
    cells = np.empty((L + 9, T))  # d_x(h_a u_a) per layer, d_x Q, G, exchange, d_t(h_a u_a), terms
    gate = np.empty((2, L))  # mass and momentum fluxes seen from east of the gate
    return columns, scalars, layers, faces, fluxes, cells, gate


@jit
def _block_sum(v, start, stop):
    """numpy's sum of at most 128 values: eight partial sums, then the rest in order."""
    n = stop - start
    if n < 8:
        total = 0.0
        for i in range(start, stop):
            total += v[i]
        return total
    r = np.empty(8)
    for j in range(8):
        r[j] = v[start + j]
    whole = start + n - n % 8
    for i in range(start + 8, whole, 8):
        for j in range(8):
            r[j] += v[i + j]
    total = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]))
    for i in range(whole, stop):
        total += v[i]
    return total


@jit
def _pairwise_sum(v):
    """``numpy.sum(v)`` in numpy's own order (pairwise: halves, down to blocks of at most
    128 values), so that the result is the same to the last bit.  (No recursion: numba's
    cache does not keep recursive functions.)"""
    ranges = np.empty((64, 3), np.int64)  # start, stop, halves already summed
    sums = np.empty(64)
    top = 0
    count = 0
    ranges[0, 0], ranges[0, 1], ranges[0, 2] = 0, v.size, 0
    while top >= 0:
        start, stop, done = ranges[top, 0], ranges[top, 1], ranges[top, 2]
        top -= 1
        if stop - start <= 128:
            sums[count] = _block_sum(v, start, stop)
            count += 1
        elif done:
            count -= 1
            sums[count - 1] = sums[count - 1] + sums[count]
        else:
            half = (stop - start) // 2
            half -= half % 8
            ranges[top + 1, 0], ranges[top + 1, 1], ranges[top + 1, 2] = start, stop, 1
            ranges[top + 2, 0], ranges[top + 2, 1], ranges[top + 2, 2] = start + half, stop, 0
            ranges[top + 3, 0], ranges[top + 3, 1], ranges[top + 3, 2] = start, start + half, 0
            top += 3
    return sums[0]


@jit(error_model="numpy")
def _gated(f, hl, hr, uL, uR, l, g_n, opening, fh, fq, gate_h, gate_q):
    """``reference._gated`` at face ``f`` of a tile: ``fh[:, f]``, ``fq[:, f]`` become the
    fluxes seen by the cell west of the gate, ``gate_h``, ``gate_q`` those seen by the
    cell east of it."""
    L = l.size
    open_mass = np.empty(L)
    open_momentum = np.empty(L)
    for a in range(L):
        open_mass[a] = opening[a] * fh[a, f]
        open_momentum[a] = opening[a] * fq[a, f]
    total_mass = _pairwise_sum(open_mass)
    total_momentum = _pairwise_sum(open_momentum)
    eastward = total_mass >= 0.0
    s_west = abs(uL[0])
    s_east = abs(uR[0])
    for a in range(1, L):
        s_west = max(s_west, abs(uL[a]))
        s_east = max(s_east, abs(uR[a]))
    s_west = s_west + np.sqrt(g_n * hl)
    s_east = s_east + np.sqrt(g_n * hr)
    for a in range(L):
        o = opening[a]
        mass = open_mass[a]
        momentum = open_momentum[a]
        spread_mass = l[a] * total_mass
        spread_momentum = l[a] * total_momentum
        wall_west = l[a] * (hl * uL[a] * uL[a] + 0.5 * g_n * hl * hl + 1.0 * s_west * hl * uL[a])
        wall_east = l[a] * (hr * uR[a] * uR[a] + 0.5 * g_n * hr * hr + -1.0 * s_east * hr * uR[a])
        if eastward:
            fh[a, f], gate_h[a] = mass, spread_mass
            open_west, open_east = momentum, spread_momentum
        else:
            fh[a, f], gate_h[a] = spread_mass, mass
            open_west, open_east = spread_momentum, momentum
        fq[a, f] = open_west + (1.0 - o) * wall_west
        gate_q[a] = open_east + (1.0 - o) * wall_east


@jit(error_model="numpy")
def _momentum_rate(i, west_flux, east_wb, west_wb, momentum, terms, exchange, rates):
    """d_t(h_a u_a) of cell ``i`` of a tile: the momentum fluxes (``west_flux`` at its west
    face) with the well-balancing factors ``east_wb``, ``west_wb`` of its faces, the bed
    slope, the mass exchange and gravity along the slope; ``terms`` holds the factors of
    the cell that no layer changes, ``rates`` the layer's pressure, slope and gravity
    factors and dx."""
    pressure, slope, gravity, dx = rates
    east = momentum[i + 1] + pressure * east_wb
    west = west_flux + pressure * west_wb
    return -(east - west + slope * terms[2, i] * terms[3, i]) / dx + exchange[i] + gravity * terms[4, i]


class Window(NamedTuple):
    """The occupied window a step sweeps: ``n`` columns from column ``lo``, the ghost
    rules of its sides (``boundaries``) and its ``n + 1`` faces at rest."""

    n: int
    lo: int
    left: int
    right: int
    at_rest: np.ndarray


class Scheme(NamedTuple):
    """What the scheme reads besides the state: the layer fractions (L,), the steps in x
    and t, ``g cos(theta)``, ``g sin(theta)``, the dry thickness, the order (1 or 2) and
    whether the call is Heun's first stage alone (its result is then the output)."""

    l: np.ndarray
    dx: float
    dt: float
    g_n: float
    g_t: float
    dry: float
    order: int
    alone: bool


class Edges(NamedTuple):
    """The state of an inflow side (thickness, layer velocities) and the gate: its face in
    the window (-1: none there) and the opening of each layer."""

    inflow_h: float
    inflow_u: np.ndarray
    gate_face: int
    opening: np.ndarray


class Arrays(NamedTuple):
    """The state ``H`` (N,), ``U`` (L, N) and bed ``B`` (N,); Heun's first stage ``H1``,
    ``Q1``; the result ``H_out``, ``U_out``; the mass and momentum fluxes through the
    window's end faces per stage ``ends`` (2, 4: mass left, right, momentum left, right);
    the fastest wave across each face of the window ``speeds`` (n + 1)."""

    H: np.ndarray
    U: np.ndarray
    B: np.ndarray
    H1: np.ndarray
    Q1: np.ndarray
    H_out: np.ndarray
    U_out: np.ndarray
    ends: np.ndarray
    speeds: np.ndarray


@jit(inline="always")
def _widen(values, offset, count, lo, hi):
    """``lo[f]``, ``hi[f]``: the smallest and largest of themselves and ``values[f + offset]``,
    ``f < count`` (selects over contiguous rows: the loop vectorises)."""
    for f in range(count):
        value = values[f + offset]
        low, high = lo[f], hi[f]
        lo[f] = value if value < low else low
        hi[f] = value if value > high else high


@jit(error_model="numpy")
def _tile(stage, t0, t1, window, scheme, edges, arrays, work):
    """One stage on the cells ``t0 .. t1-1`` of the window (faces ``t0 .. t1``), layer by
    layer over the tile's columns (contiguous rows of the (L, N) arrays).

    Columns ``t0-2 .. t1+1`` (ghosts included) are loaded, the cells ``t0-1 .. t1``
    reconstructed, the faces ``t0 .. t1`` get their HLL fluxes (the gate's at
    ``gate_face``), and the cells are updated.  ``stage`` 0: forward Euler from (H, U),
    to (H_out, U_out) at order 1 or alone and to (H1, Q1) otherwise; ``stage`` 1: Heun's
    second stage from (H1, Q1), averaged with (H, U), to (H_out, U_out).  The mass fluxes through
    the end faces 0 and n of the window, as the cells next to them see them, go to
    ``ends[stage]`` (summed over the layers from the bed up), the fastest wave across
    each face that carries mass (0 for a face at rest) to ``speeds[t0 .. t1]``.
    """
    n, lo, left, right, at_rest = window.n, window.lo, window.left, window.right, window.at_rest
    l, dx, dt, order, alone = scheme.l, scheme.dx, scheme.dt, scheme.order, scheme.alone
    g_n, g_t, dry = scheme.g_n, scheme.g_t, scheme.dry
    inflow_h, inflow_u, gate_face, opening = edges.inflow_h, edges.inflow_u, edges.gate_face, edges.opening
    H, U, B, H1, Q1 = arrays.H, arrays.U, arrays.B, arrays.H1, arrays.Q1
    H_out, U_out, ends, speeds = arrays.H_out, arrays.U_out, arrays.ends, arrays.speeds
    L = l.size
    m = t1 - t0
    (col, kind), scalars, layers, faces, fluxes, cells, (gate_h, gate_q) = work
    hx, bx, h_w, h_e, b_w, b_e = scalars[0], scalars[1], scalars[2], scalars[3], scalars[4], scalars[5]
    ux, u_w, u_e = layers[0], layers[1], layers[2]
    hL, hR, wl, wr = faces[0], faces[1], faces[2], faces[3]
    jump, moving, pL, pR, resting = faces[4], faces[5], faces[6], faces[7], faces[8]
    fh, fq = fluxes[0], fluxes[1]
    div_h, div_Q, G, exchange, dq = cells[:L], cells[L], cells[L + 1], cells[L + 2], cells[L + 3]
    terms = cells[L + 4 :]
    from_q = stage == 1
    final = stage == 1 or order == 1 or alone
    # load the state of the columns t0-2 .. t1+1 (index k = column - t0 + 2)
    for k in range(m + 4):
        src, how = _source(t0 - 2 + k, n, left, right)
        c = lo + src
        col[k] = c
        kind[k] = how
        bx[k] = B[c]
        if how == 2:
            hx[k] = inflow_h
        else:
            hx[k] = H1[c] if from_q else H[c]
    # the columns k_lo .. k_hi-1 are in the window: the mesh columns first .. first+count-1
    # in order, read as row slices indexed from 0 (an index such as first + k could be
    # negative to the compiler: each would wrap around, element by element, and the loop
    # would not vectorise); the others (at most two per side) are ghosts
    k_lo, k_hi = max(0, 2 - t0), min(m + 4, n + 2 - t0)
    count = k_hi - k_lo
    first = lo + t0 - 2 + k_lo
    h_in = H1[first : first + count]
    for a in range(L):
        row = ux[a][k_lo:k_hi]
        if from_q:
            q_in = Q1[a, first : first + count]
            for k in range(count):
                h = h_in[k]
                v = q_in[k] / (l[a] * h)
                row[k] = v if h > dry else 0.0
        else:
            u_in = U[a, first : first + count]
            for k in range(count):
                row[k] = u_in[k]
    for a in range(L):
        row = ux[a]
        for g in range(m + 4 - count):
            k = g if g < k_lo else g + count  # the ghosts
            c = col[k]
            if kind[k] == 2:
                v = inflow_u[a]
            elif from_q:
                v = Q1[a, c] / (l[a] * H1[c]) if H1[c] > dry else 0.0
            else:
                v = U[a, c]
            row[k] = -v if kind[k] == 1 else v
    # reconstruction: west/east values of the cells k = 1 .. m+2
    for k in range(1, m + 3):
        hc = hx[k]
        etac = hx[k] + bx[k]
        dh = 0.0
        deta = 0.0
        if order == 2:
            dh = _minmod(hx[k] - hx[k - 1], hx[k + 1] - hx[k])
            deta = _minmod(etac - (hx[k - 1] + bx[k - 1]), (hx[k + 1] + bx[k + 1]) - etac)
        h_w[k] = hc - 0.5 * dh
        h_e[k] = hc + 0.5 * dh
        b_w[k] = etac - 0.5 * deta - h_w[k]
        b_e[k] = etac + 0.5 * deta - h_e[k]
    # the faces at rest beside material at rest (reference._rates) see the cell-centred
    # values on both sides
    for f in range(m + 1):
        wet_l = H[col[f + 1]] > dry
        wet_r = H[col[f + 2]] > dry
        kept = (wet_l or hx[f + 1] <= dry) and (wet_r or hx[f + 2] <= dry)
        resting[f] = 1.0 if at_rest[t0 + f] and (wet_l or wet_r) and kept else 0.0
    for f in range(m + 1):
        if resting[f] != 0.0:
            h_e[f + 1] = hx[f + 1]
            b_e[f + 1] = bx[f + 1]
            h_w[f + 2] = hx[f + 2]
            b_w[f + 2] = bx[f + 2]
    for a in range(L):
        row, west, east = ux[a], u_w[a], u_e[a]
        for k in range(1, m + 3):
            uc = row[k]
            du = _minmod(uc - row[k - 1], row[k + 1] - uc) if order == 2 else 0.0
            west[k] = uc - 0.5 * du
            east[k] = uc + 0.5 * du
    # faces f = 0 .. m (window face t0 + f) between the cells k = f + 1 and f + 2:
    # hydrostatic reconstruction and HLL wave speeds bracketing every layer's waves
    # the slowest and fastest layer on each side of each face, row by row (contiguous
    # rows, selects: the loops vectorise), kept in rows that the next loop overwrites
    for f in range(m + 1):
        wl[f] = wr[f] = u_e[0, f + 1]
        pL[f] = pR[f] = u_w[0, f + 2]
    for a in range(1, L):
        _widen(u_e[a], 1, m + 1, wl, wr)  # the east values of the cells left of the faces
        _widen(u_w[a], 2, m + 1, pL, pR)  # the west values of the cells right of them
    # the face scalars, face by face without inner loops (they vectorise)
    for f in range(m + 1):
        s_lo, s_hi, r_lo, r_hi = wl[f], wr[f], pL[f], pR[f]
        b_face = max(b_e[f + 1], b_w[f + 2])
        hl = max(0.0, h_e[f + 1] + b_e[f + 1] - b_face)
        hr = max(0.0, h_w[f + 2] + b_w[f + 2] - b_face)
        hL[f] = hl
        hR[f] = hr
        cl = np.sqrt(g_n * hl)
        cr = np.sqrt(g_n * hr)
        s_left = min(s_lo - cl, r_lo - cr)
        s_right = max(s_hi + cl, r_hi + cr)
        lowest = min(s_left, 0.0)
        highest = max(s_right, 0.0)
        rest = at_rest[t0 + f] | (lowest == highest)  # no wave at all
        s_left = -1.0 if rest else lowest
        s_right = 1.0 if rest else highest
        width = s_right - s_left
        wl[f] = s_right / width
        wr[f] = -s_left / width
        moving[f] = 0.0 if rest else 1.0
        speeds[t0 + f] = 0.0 if rest else max(-lowest, highest)
        jump[f] = s_left * s_right / width * moving[f]
        if resting[f] != 0.0:  # the pressure between two columns at rest (reference._rates)
            pL[f] = pR[f] = 0.5 * g_n * (hl * hr)
        else:
            pL[f] = 0.5 * g_n * (hl * hl)
            pR[f] = 0.5 * g_n * (hr * hr)
    for a in range(L):
        la = l[a]
        east, west, mass, momentum = u_e[a], u_w[a], fh[a], fq[a]
        for f in range(m + 1):
            uL = east[f + 1]
            uR = west[f + 2]
            qL = hL[f] * uL
            qR = hR[f] * uR
            mass[f] = la * (wl[f] * qL + wr[f] * qR + jump[f] * (hR[f] - hL[f])) * moving[f]
            momentum[f] = la * (wl[f] * (qL * uL + pL[f]) + wr[f] * (qR * uR + pR[f]) + jump[f] * (qR - qL))
    gate = gate_face - t0 if t0 <= gate_face <= t1 else -1
    if gate >= 0:
        _gated(
            gate,
            hL[gate],
            hR[gate],
            u_e[:, gate + 1],
            u_w[:, gate + 2],
            l,
            g_n,
            opening,
            fh,
            fq,
            gate_h,
            gate_q,
        )
    for f in (0, m):  # an end face of the window in this tile
        if t0 + f == 0 or t0 + f == n:
            seen_from_east = t0 + f == 0 and f == gate
            total = gate_h[0] if seen_from_east else fh[0, f]
            momentum_total = gate_q[0] if seen_from_east else fq[0, f]
            for a in range(1, L):
                total += gate_h[a] if seen_from_east else fh[a, f]
                momentum_total += gate_q[a] if seen_from_east else fq[a, f]
            ends[stage, 0 if t0 + f == 0 else 1] = total
            ends[stage, 2 if t0 + f == 0 else 3] = momentum_total
    # the cells: divergence of the layer mass fluxes, mass exchange, update
    for a in range(L):
        rate, mass = div_h[a], fh[a]
        for i in range(m):
            rate[i] = (mass[i + 1] - mass[i]) / dx
        if 0 <= gate < m:  # the cell east of the gate sees the gate's flux from its side
            rate[gate] = (mass[gate + 1] - gate_h[a]) / dx
    for i in range(m):
        div_Q[i] = div_h[0, i]
    for a in range(1, L):
        for i in range(m):
            div_Q[i] = div_Q[i] + div_h[a, i]
    for i in range(m):
        c = col[i + 2]
        if stage == 0:
            h_new = max(hx[i + 2] + dt * -div_Q[i], 0.0)
        else:
            h_new = max(0.5 * (H[c] + H1[c] + dt * -div_Q[i]), 0.0)
        if final:
            H_out[c] = h_new
        else:
            H1[c] = h_new
    # the factors of the momentum rate that do not depend on the layer
    for i in range(m):
        k = i + 2
        hw = h_w[k]
        he = h_e[k]
        # the pressure at the east and the west face
        if resting[i + 1] != 0.0:
            terms[0, i] = (he - hL[i + 1]) * (he + hR[i + 1])
        else:
            terms[0, i] = he * he - hL[i + 1] * hL[i + 1]
        if resting[i] != 0.0:
            terms[1, i] = (hw - hR[i]) * (hw + hL[i])
        else:
            terms[1, i] = hw * hw - hR[i] * hR[i]
        terms[2, i] = hw + he
        terms[3, i] = b_e[k] - b_w[k]  # bed slope
        terms[4, i] = hx[k]  # gravity along the slope
    c0 = col[2]
    h_old, h_out = H[c0 : c0 + m], H_out[c0 : c0 + m]
    for a in range(L):
        la = l[a]
        row, rate, momentum = ux[a], div_h[a], fq[a]
        upper, lower = ux[min(a + 1, L - 1)], ux[max(a - 1, 0)]
        # mass exchange with the layers above (G[a], upwinded velocity) and below (G[a-1])
        if a == 0 and L > 1:
            for i in range(m):
                cum = rate[i] - la * div_Q[i]
                up, here = upper[i + 2], row[i + 2]
                u_G = up if cum > 0.0 else here
                exchange[i] = 0.0 + u_G * cum
                G[i] = cum
        elif 0 < a < L - 1:
            for i in range(m):
                below = G[i]
                cum = below + (rate[i] - la * div_Q[i])
                up, here, down = upper[i + 2], row[i + 2], lower[i + 2]
                u_G = up if cum > 0.0 else here
                u_B = here if below > 0.0 else down
                exchange[i] = (0.0 + u_G * cum) - u_B * below
                G[i] = cum
        elif a > 0:
            for i in range(m):
                below = G[i]
                here, down = row[i + 2], lower[i + 2]
                u_B = here if below > 0.0 else down
                exchange[i] = 0.0 - u_B * below
        else:
            exchange[:m] = 0.0
        rates = (la * 0.5 * g_n, la * g_n * 0.5, g_t * la, dx)
        for i in range(m):
            dq[i] = _momentum_rate(i, momentum[i], terms[0, i], terms[1, i], momentum, terms, exchange, rates)
        if 0 <= gate <= m:  # the cells beside the gate
            o, walled = opening[a], resting[gate] != 0.0
            if 1 <= gate and walled:  # a gate at rest: its wall part (reference._gate_walls)
                i, he = gate - 1, h_e[gate + 1]
                wall = o * terms[0, i] + (1.0 - o) * (he * he - hL[gate] * hL[gate])
                dq[i] = _momentum_rate(i, momentum[i], wall, terms[1, i], momentum, terms, exchange, rates)
            if gate < m:  # the cell east of the gate sees the gate's flux from its side
                hw, wall = h_w[gate + 2], terms[1, gate]
                if walled:
                    wall = o * wall + (1.0 - o) * (hw * hw - hR[gate] * hR[gate])
                dq[gate] = _momentum_rate(
                    gate, gate_q[a], terms[0, gate], wall, momentum, terms, exchange, rates
                )
        # rows from column c0 on, indexed by i >= 0 (as the loads above)
        u_old, q_mid, u_new = U[a, c0 : c0 + m], Q1[a, c0 : c0 + m], U_out[a, c0 : c0 + m]
        if not final:
            for i in range(m):
                q_mid[i] = la * h_old[i] * u_old[i] + dt * dq[i]
        elif stage == 0:
            for i in range(m):
                q_new = la * h_old[i] * u_old[i] + dt * dq[i]
                h_new = h_out[i]
                velocity = q_new / (la * h_new)
                u_new[i] = velocity if h_new > dry else 0.0
        else:
            for i in range(m):
                q_new = 0.5 * (la * h_old[i] * u_old[i] + q_mid[i] + dt * dq[i])
                h_new = h_out[i]
                velocity = q_new / (la * h_new)
                u_new[i] = velocity if h_new > dry else 0.0


def _stages(first, last, chunks, window, scheme, edges, arrays):
    """The stages ``first .. last-1`` over the window in ``chunks`` independent pieces
    (taken by the threads in turn), each swept in tiles of about ``TILE`` cells."""
    L, n = scheme.l.size, window.n
    T = max(8, TILE // L)
    for stage in range(first, last):
        for k in prange(chunks):
            c0 = k * n // chunks
            c1 = (k + 1) * n // chunks
            if c1 > c0:
                work = _work(L, min(T, c1 - c0))
                for t0 in range(c0, c1, T):
                    _tile(stage, t0, min(t0 + T, c1), window, scheme, edges, arrays, work)


_stages_serial = jit(_stages, error_model="numpy")
_stages_parallel = parallel_compiled(_stages, error_model="numpy")


@jit
def _window(h, u, moving, left, right):
    """Occupied window [lo, hi) (material plus ``MARGIN`` dry cells per side) and the
    faces (hi - lo + 1) across which no wave travels (both sides at rest)."""
    N = h.size
    first = -1
    last = -1
    for i in range(N):
        if h[i] > 0.0 or moving[i]:
            if first < 0:
                first = i
            last = i
    lo = 0 if first < 0 or left in (STATE, WRAP) else max(first - MARGIN, 0)
    hi = N if first < 0 or right in (STATE, WRAP) else min(last + 1 + MARGIN, N)
    n = hi - lo
    west_end = moving[lo] or left == STATE
    east_end = moving[hi - 1] or right == STATE
    if left == WRAP:
        west_end = moving[hi - 1]
    if right == WRAP:
        east_end = moving[lo]
    at_rest = np.empty(n + 1, np.bool_)
    for f in range(n + 1):
        west = west_end if f == 0 else moving[lo + f - 1]
        east = east_end if f == n else moving[lo + f]
        at_rest[f] = not (west or east)
    return lo, hi, at_rest


class Workspace:
    """Arrays of one mesh size reused by every step: the Heun stage and the result, and
    the columns ``written`` (lo, hi) of the result that may be non-zero; a result kept
    (:meth:`keep`) and its columns ``kept`` that may be non-zero."""

    def __init__(self, layers: int, cells: int):
        self.h1 = np.zeros(cells)
        self.q1 = np.zeros((layers, cells))
        self.h = np.zeros(cells)
        self.u = np.zeros((layers, cells))
        self.written = (0, 0)
        self.ends = np.zeros((2, 4))  # mass and momentum fluxes through the end faces, per stage
        self.speeds = np.zeros(cells + 1)  # the fastest wave across each face of the last stage
        self.h_kept = np.zeros(cells)
        self.u_kept = np.zeros((layers, cells))
        self.kept = (0, 0)

    def clear_outside(self, lo: int, hi: int) -> None:
        """Zero the result outside the columns ``lo .. hi-1`` (only what an earlier step
        wrote there: the window of a dam break is a tenth of the mesh)."""
        before, after = self.written
        for start, stop in ((before, min(lo, after)), (max(hi, before), after)):
            if stop > start:
                self.h[start:stop] = 0.0
                self.u[:, start:stop] = 0.0
        self.written = (lo, hi)

    def keep(self) -> tuple[np.ndarray, np.ndarray]:
        """The result (h, u) kept from the next use (Heun's first stage, through the second),
        swapped with the pair kept before: a copy streamed the (L, N) velocities once more."""
        self.h, self.h_kept = self.h_kept, self.h
        self.u, self.u_kept = self.u_kept, self.u
        self.written, self.kept = self.kept, self.written
        return self.h_kept, self.u_kept


@jit
def _second_stage_start(l, h1, u1, H1, Q1, lo, hi):
    """Heun's second stage's start in the columns ``lo .. hi-1``: ``H1 = h1``, ``Q1 = l h1 u1``
    (``reference._step``'s products, in its order), with no temporaries the size of the mesh."""
    H1[lo:hi] = h1[lo:hi]
    h = h1[lo:hi]
    for a in range(l.size):  # rows from column lo, indexed from 0: the loop vectorises
        la, row, out = l[a], u1[a, lo:hi], Q1[a, lo:hi]
        for c in range(h.size):
            out[c] = la * h[c] * row[c]


def transport(
    h: np.ndarray,
    u: np.ndarray,
    b: np.ndarray,
    fractions: np.ndarray,
    *,
    dx: float,
    dt: float,
    g_n: float,
    g_t: float,
    left: str,
    right: str,
    inflow=None,
    dry: float = 0.0,
    order: int = 2,
    moving: np.ndarray | None = None,
    gate_face: int | None = None,
    opening: np.ndarray | None = None,
    workspace: Workspace | None = None,
    threads: int = 1,
    boundary_mass: np.ndarray | None = None,
    stage_speed: np.ndarray | None = None,
    boundary_momentum: np.ndarray | None = None,
    stage: int | None = None,
    first: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``reference.transport`` compiled: returns h^{n+1} (N,) and u* (L, N) (or the
    result of the ``stage`` alone, ``first`` the state of Heun's second stage, as there).

    The result lives in ``workspace`` (a new one when None) and is overwritten by its
    next use; Heun's second stage alone (``stage=1``) needs the workspace of the first
    (the mass and momentum through the end faces in that stage).  ``threads > 1`` sweeps
    the window in chunks of at least 64 columns (``threads.parallel_chunks``) on that many
    threads.
    ``boundary_mass`` (2,), if given, receives the mass that crossed the left and the
    right boundary, positive in +x, and ``boundary_momentum`` (3,) the momentum and the
    integral of the mass (as ``reference.transport``).
    """
    if opening is not None and gate_face is None:
        raise ValueError("transport: a gate opening was given without its gate_face")
    L, N = u.shape
    ws = workspace if workspace is not None else Workspace(L, N)
    if moving is None:
        moving = moving_columns(u)
    codes = boundaries.rule(left), boundaries.rule(right)
    lo, hi, at_rest = _window(h, u, moving, *codes)
    n = hi - lo
    left_kind = codes[0] if lo == 0 else COPY
    right_kind = codes[1] if hi == N else COPY
    inflow_h = float(inflow.thickness) if inflow is not None else 0.0
    inflow_u = np.asarray(inflow.velocity, dtype=float) if inflow is not None else np.zeros(L)
    ws.clear_outside(lo, hi)
    gate = -1  # no gate, or its face outside the window
    if opening is not None and gate_face is not None and lo <= gate_face <= hi:
        gate = gate_face - lo
    opening = np.asarray(opening, dtype=float) if gate >= 0 else np.zeros(L)
    l = np.ascontiguousarray(fractions, dtype=float)
    begin, end = stages(order, stage)
    if begin == 1:  # Heun's second stage starts from the given state
        if workspace is None:
            raise ValueError("transport: Heun's second stage alone needs the workspace of its first")
        _second_stage_start(l, *second_stage_start(first), ws.h1, ws.q1, lo, hi)
    chunks = parallel_chunks(threads, n, 64) if threads > 1 else 1
    sweep = _stages_parallel if chunks > 1 else _stages_serial
    with numba_threads(threads if chunks > 1 else 1):
        sweep(
            begin, end, chunks, Window(n, lo, left_kind, right_kind, at_rest),
            Scheme(l, float(dx), float(dt), float(g_n), float(g_t), float(dry), int(order), stage == 0),
            Edges(inflow_h, inflow_u, gate, opening),
            Arrays(h, u, b, ws.h1, ws.q1, ws.h, ws.u, ws.ends, ws.speeds),
        )  # fmt: skip
    if boundary_mass is not None:
        boundary_mass[:] = step_boundary_mass(ws.ends[:end, :2], float(dt))
    if boundary_momentum is not None:
        boundary_momentum[:2] = step_boundary_mass(ws.ends[:end, 2:], float(dt))
        boundary_momentum[2] = step_mass_time(float(h.sum() * dx), ws.ends[:end, :2], float(dt))
    if stage_speed is not None:
        stage_speed[0] = ws.speeds[: n + 1].max() if end == 2 else 0.0
    return ws.h, ws.u
