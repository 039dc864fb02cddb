"""Compiled transport step: the scheme of ``transport.py`` fused into one sweep per stage.

``transport.py`` (numpy) is the reference formulation; this module computes the same
step (hydrostatic reconstruction of Audusse et al. 2004, minmod slopes, HLL fluxes per
layer, mass exchange with upwinded velocity, bed slope and gravity sources, forward
Euler or Heun) with the same floating-point operations in the same order, so both agree
to round-off (tests/test_transport_kernel.py).

Each stage is one sweep over the faces of the occupied window.  A ring of three columns
holds the states the minmod slopes need, the reconstruction of the cells on both sides
of the current face and the fluxes of the previous face are kept in ``L``-vectors, and a
cell is updated as soon as both of its faces are known.  So the only arrays the size of
the mesh are the state, the intermediate Heun state and the result; everything else
stays in cache.  The window is cut into chunks of columns that are swept independently
(the face between two chunks is computed by both, identically), one chunk per thread.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from multilayer.engine.transport import MARGIN, step_boundary_mass

WALL, OUTFLOW, INFLOW, PERIODIC = 0, 1, 2, 3
BOUNDARY_CODES = {"wall": WALL, "outflow": OUTFLOW, "inflow": INFLOW, "periodic": PERIODIC}


@njit(cache=True)
def _minmod(back, ahead):
    if back * ahead > 0.0:
        return np.sign(back) * min(abs(back), abs(ahead))
    return 0.0


@njit(cache=True)
def _load(
    j, n, lo, left, right, H, U, H1, Q1, B, l, dry, from_q, inflow_h, inflow_u, h_ring, b_ring, u_ring, slot
):
    """Column ``j`` of the window extended by two ghosts per side (``j`` in -2 .. n+1)
    into ring slot ``slot``: the state (H, U), or (H1, Q1 / (l H1)) when ``from_q``."""
    mirror = False
    inflow = False
    if j < 0:
        g = -1 - j  # 0 for the ghost next to the boundary
        if left == PERIODIC:
            src = (n - 1 - g) % n
        elif left == WALL:
            src = min(g, n - 1)
            mirror = True
        else:
            src = 0
            inflow = left == INFLOW
    elif j >= n:
        g = j - n
        if right == PERIODIC:
            src = g % n
        elif right == WALL:
            src = max(n - 1 - g, 0)
            mirror = True
        else:
            src = n - 1
            inflow = right == INFLOW
    else:
        src = j
    c = lo + src
    b_ring[slot] = B[c]
    if inflow:
        h_ring[slot] = inflow_h
        for a in range(l.size):
            u_ring[slot, a] = inflow_u[a]
        return
    h = H1[c] if from_q else H[c]
    h_ring[slot] = h
    for a in range(l.size):
        if from_q:
            v = Q1[a, c] / (l[a] * h) if h > dry else 0.0
        else:
            v = U[a, c]
        u_ring[slot, a] = -v if mirror else v


@njit(cache=True)
def _reconstruct(order, h_ring, b_ring, u_ring, sm, s0, sp, rec, u_w, u_e):
    """West/east face values of the cell in slot ``s0`` (neighbours in ``sm``, ``sp``):
    ``rec`` = (h_w, h_e, b_w, b_e); ``u_w``, ``u_e`` per layer."""
    hc = h_ring[s0]
    etac = h_ring[s0] + b_ring[s0]
    dh = 0.0
    deta = 0.0
    if order == 2:
        dh = _minmod(h_ring[s0] - h_ring[sm], h_ring[sp] - h_ring[s0])
        eta_m = h_ring[sm] + b_ring[sm]
        eta_p = h_ring[sp] + b_ring[sp]
        deta = _minmod(etac - eta_m, eta_p - etac)
    h_w = hc - 0.5 * dh
    h_e = hc + 0.5 * dh
    rec[0] = h_w
    rec[1] = h_e
    rec[2] = etac - 0.5 * deta - h_w
    rec[3] = etac + 0.5 * deta - h_e
    for a in range(u_w.size):
        uc = u_ring[s0, a]
        du = _minmod(uc - u_ring[sm, a], u_ring[sp, a] - uc) if order == 2 else 0.0
        u_w[a] = uc - 0.5 * du
        u_e[a] = uc + 0.5 * du


@njit(cache=True)
def _face(recL, uL, recR, uR, rest, l, g_n, fh, fq, hface):
    """HLL fluxes of layer mass and momentum at a face from the east values of the cell
    on its left and the west values of the cell on its right (hydrostatic
    reconstruction); ``hface`` receives (hL, hR)."""
    b_face = max(recL[3], recR[2])
    hL = max(0.0, recL[1] + recL[3] - b_face)
    hR = max(0.0, recR[0] + recR[2] - b_face)
    hface[0] = hL
    hface[1] = hR
    cL = np.sqrt(g_n * hL)
    cR = np.sqrt(g_n * hR)
    lo_L = uL[0]
    hi_L = uL[0]
    lo_R = uR[0]
    hi_R = uR[0]
    for a in range(1, l.size):
        lo_L = min(lo_L, uL[a])
        hi_L = max(hi_L, uL[a])
        lo_R = min(lo_R, uR[a])
        hi_R = max(hi_R, uR[a])
    s_left = min(lo_L - cL, lo_R - cR)
    s_right = max(hi_L + cL, hi_R + cR)
    rest = rest or (min(s_left, 0.0) == max(s_right, 0.0))
    if rest:
        s_left = -1.0
        s_right = 1.0
    else:
        s_left = min(s_left, 0.0)
        s_right = max(s_right, 0.0)
    width = s_right - s_left
    wl = s_right / width
    wr = -s_left / width
    moving = 0.0 if rest else 1.0
    jump = s_left * s_right / width * moving
    pL = 0.5 * g_n * (hL * hL)
    pR = 0.5 * g_n * (hR * hR)
    for a in range(l.size):
        qL = hL * uL[a]
        qR = hR * uR[a]
        fh[a] = l[a] * (wl * qL + wr * qR + jump * (hR - hL)) * moving
        fq[a] = l[a] * (wl * (qL * uL[a] + pL) + wr * (qR * uR[a] + pR) + jump * (qR - qL))


@njit(cache=True)
def _sweep(
    stage, order, c0, c1, n, lo, left, right, at_rest,
    H, U, B, Q1, H1, l, dx, dt, g_n, g_t, dry, inflow_h, inflow_u, H_out, U_out, ends,
):  # fmt: skip
    """One stage over the cells ``c0 .. c1-1`` of the window (faces ``c0 .. c1``).

    ``stage`` 0: forward Euler from (H, U); with ``order`` 1 the result goes to
    (H_out, U_out), with ``order`` 2 to (H1, Q1).  ``stage`` 1: Heun's second stage from
    (H1, Q1), averaged with (H, U), to (H_out, U_out).  The mass fluxes through the end
    faces 0 and n of the window go to ``ends[stage]`` (the chunks holding them).
    """
    L = l.size
    from_q = stage == 1
    h_ring = np.empty(3)
    b_ring = np.empty(3)
    u_ring = np.empty((3, L))
    rec_l = np.empty(4)
    rec_r = np.empty(4)
    uw_l, ue_l, uw_r, ue_r = np.empty(L), np.empty(L), np.empty(L), np.empty(L)
    fh_w, fq_w, fh_e, fq_e = np.empty(L), np.empty(L), np.empty(L), np.empty(L)
    face_w = np.empty(2)
    face_e = np.empty(2)
    div_h = np.empty(L)
    G = np.empty(L)
    args = (n, lo, left, right, H, U, H1, Q1, B, l, dry, from_q, inflow_h, inflow_u, h_ring, b_ring, u_ring)
    for j in range(c0 - 2, c0 + 1):
        _load(j, *args, (j + 3) % 3)
    _reconstruct(order, h_ring, b_ring, u_ring, (c0 + 1) % 3, (c0 + 2) % 3, c0 % 3, rec_l, uw_l, ue_l)
    for f in range(c0, c1 + 1):
        _load(f + 1, *args, (f + 1) % 3)  # the ring now holds columns f-1, f, f+1
        _reconstruct(order, h_ring, b_ring, u_ring, (f + 2) % 3, f % 3, (f + 1) % 3, rec_r, uw_r, ue_r)
        _face(rec_l, ue_l, rec_r, uw_r, at_rest[f], l, g_n, fh_e, fq_e, face_e)
        if f == 0 or f == n:  # an end face: its mass flux, layer by layer from the bed
            total = fh_e[0]
            for a in range(1, L):
                total += fh_e[a]
            ends[stage, 0 if f == 0 else 1] = total
        if f > c0:
            i = f - 1  # the cell between the faces f-1 (west) and f (east)
            s = i % 3
            hi = h_ring[s]
            hw, he, bw, be = rec_l[0], rec_l[1], rec_l[2], rec_l[3]
            div_Q = 0.0
            for a in range(L):
                div_h[a] = (fh_e[a] - fh_w[a]) / dx
                div_Q = div_Q + div_h[a] if a > 0 else div_h[0]
            cum = 0.0
            for a in range(L - 1):
                cum = cum + (div_h[a] - l[a] * div_Q) if a > 0 else div_h[0] - l[0] * div_Q
                G[a] = cum
            c = lo + i
            if stage == 0:
                h_new = max(hi + dt * -div_Q, 0.0)
            else:
                h_new = max(0.5 * (H[c] + H1[c] + dt * -div_Q), 0.0)
            final = stage == 1 or order == 1
            if final:
                H_out[c] = h_new
            else:
                H1[c] = h_new
            for a in range(L):
                exchange = 0.0
                if a < L - 1:
                    u_G = u_ring[s, a + 1] if G[a] > 0.0 else u_ring[s, a]
                    exchange = exchange + u_G * G[a]
                if a > 0:
                    u_G = u_ring[s, a] if G[a - 1] > 0.0 else u_ring[s, a - 1]
                    exchange = exchange - u_G * G[a - 1]
                east = fq_e[a] + l[a] * 0.5 * g_n * (he * he - face_e[0] * face_e[0])
                west = fq_w[a] + l[a] * 0.5 * g_n * (hw * hw - face_w[1] * face_w[1])
                bed_slope = l[a] * g_n * 0.5 * (hw + he) * (be - bw)
                dq = -(east - west + bed_slope) / dx + exchange + g_t * l[a] * hi
                q0 = l[a] * H[c] * U[a, c]
                if stage == 0:
                    q_new = q0 + dt * dq
                else:
                    q_new = 0.5 * (q0 + Q1[a, c] + dt * dq)
                if final:
                    U_out[a, c] = q_new / (l[a] * h_new) if h_new > dry else 0.0
                else:
                    Q1[a, c] = q_new
        # the east face becomes the west face of the next cell, the right cell the left one
        fh_w, fh_e = fh_e, fh_w
        fq_w, fq_e = fq_e, fq_w
        face_w, face_e = face_e, face_w
        rec_l, rec_r = rec_r, rec_l
        uw_l, uw_r = uw_r, uw_l
        ue_l, ue_r = ue_r, ue_l


def _stages(chunks, order, n, lo, left, right, at_rest, H, U, B, Q1, H1, l, *scalars_and_out):
    """Both stages over the window in ``chunks`` independent pieces (one per thread)."""
    for stage in range(order):
        for k in prange(chunks):
            c0 = k * n // chunks
            c1 = (k + 1) * n // chunks
            if c1 > c0:
                _sweep(
                    stage, order, c0, c1, n, lo, left, right, at_rest, H, U, B, Q1, H1, l, *scalars_and_out
                )


_stages_serial = njit(cache=True)(_stages)
_stages_parallel = njit(cache=True, parallel=True)(_stages)


@njit(cache=True)
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
    lo = 0 if first < 0 or left in (INFLOW, PERIODIC) else max(first - MARGIN, 0)
    hi = N if first < 0 or right in (INFLOW, PERIODIC) else min(last + 1 + MARGIN, N)
    n = hi - lo
    west_end = moving[lo] or left == INFLOW
    east_end = moving[hi - 1] or right == INFLOW
    if left == PERIODIC:
        west_end = moving[hi - 1]
    if right == PERIODIC:
        east_end = moving[lo]
    at_rest = np.empty(n + 1, np.bool_)
    for f in range(n + 1):
        west = west_end if f == 0 else moving[lo + f - 1]
        east = east_end if f == n else moving[lo + f]
        at_rest[f] = not (west or east)
    return lo, hi, at_rest


@njit(cache=True)
def moving_columns(u: np.ndarray) -> np.ndarray:
    """Columns (N,) with a non-zero velocity in some layer of ``u`` (L, N)."""
    L, N = u.shape
    out = np.zeros(N, np.bool_)
    for a in range(L):
        for i in range(N):
            if u[a, i] != 0.0:
                out[i] = True
    return out


@njit(cache=True)
def max_wave_speed(h: np.ndarray, u: np.ndarray, g_n: float) -> float:
    """Largest max_a |u_a| + sqrt(g cos(theta) h) over the columns (0 for none)."""
    L, N = u.shape
    fastest = np.zeros(N)
    for a in range(L):
        for i in range(N):
            fastest[i] = max(fastest[i], abs(u[a, i]))
    best = 0.0
    for i in range(N):
        best = max(best, fastest[i] + np.sqrt(g_n * max(h[i], 0.0)))
    return best


class Workspace:
    """Arrays of one mesh size reused by every step: the Heun stage, the result and the
    mass fluxes through the end faces of each stage."""

    def __init__(self, layers: int, cells: int):
        self.ends = np.zeros((2, 2))
        self.h1 = np.zeros(cells)
        self.q1 = np.zeros((layers, cells))
        self.h = np.zeros(cells)
        self.u = np.zeros((layers, cells))


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
    workspace: Workspace | None = None,
    threads: int = 1,
    boundary_mass: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``transport.transport`` compiled: returns h^{n+1} (N,) and u* (L, N).

    The result lives in ``workspace`` (a new one when None) and is overwritten by its
    next use.  ``threads > 1`` sweeps that many chunks of the window in parallel.
    ``boundary_mass`` (2,), if given, receives the mass that crossed the left and the
    right boundary, positive in +x (as ``transport.transport``).
    """
    L, N = u.shape
    ws = workspace if workspace is not None else Workspace(L, N)
    if moving is None:
        moving = moving_columns(u)
    codes = BOUNDARY_CODES[left], BOUNDARY_CODES[right]
    lo, hi, at_rest = _window(h, u, moving, *codes)
    n = hi - lo
    left_kind = codes[0] if lo == 0 else OUTFLOW
    right_kind = codes[1] if hi == N else OUTFLOW
    inflow_h = float(inflow.thickness) if inflow is not None else 0.0
    inflow_u = np.asarray(inflow.velocity, dtype=float) if inflow is not None else np.zeros(L)
    ws.h[:lo] = 0.0
    ws.h[hi:] = 0.0
    ws.u[:, :lo] = 0.0
    ws.u[:, hi:] = 0.0
    chunks = min(threads, max(n // 64, 1))
    stages = _stages_parallel if chunks > 1 else _stages_serial
    stages(
        chunks, order, n, lo, left_kind, right_kind, at_rest,
        h, u, b, ws.q1, ws.h1, np.ascontiguousarray(fractions, dtype=float),
        float(dx), float(dt), float(g_n), float(g_t), float(dry), inflow_h, inflow_u, ws.h, ws.u, ws.ends,
    )  # fmt: skip
    if boundary_mass is not None:
        boundary_mass[:] = step_boundary_mass(ws.ends[:order], float(dt))
    return ws.h, ws.u
