"""Exact solver for one implicit vertical step of a chain of layers (the hot path).

Per column the implicit step minimises the energy ``E(u)`` of a
:class:`~multilayer.engine.vertical.problem.ColumnProblem` (docs/model.md, "The implicit
vertical step"), a strictly convex, piecewise-quadratic energy on a chain.  It is minimised exactly by
dynamic programming over the layers (Johnson 2013, "A dynamic programming algorithm for
the fused lasso"; Kolmogorov, Pock & Rolinek 2016, "Total variation on a tree"): the
derivative of each partial minimum ("message") is a maximal monotone piecewise-linear
relation, summed with the unary terms and infimal-convolved with the interface terms.
An infimal convolution adds inverse relations, so both operations are exact on vertex
lists.  Kinks are stored as vertices at exact abscissae, so a static layer comes out as
``0.0`` and the layers of a rigid plug share one velocity to the last bit: no
regularisation of ``sgn`` anywhere.

A relation is stored as vertices ``(X[i], Y[i])`` (both non-decreasing; equal ``X``
is a jump, equal ``Y`` a flat part) and the slopes of its two end rays (``inf`` for a
vertical ray, which bounds the domain).

Termination: every loop is bounded by the vertex count of its relations (at most
``8 L + 16``).  Inputs are checked finite before a call (a NaN abscissa would defeat
the comparisons that advance the merge of two relations); inside, a merge that makes no
progress or would overflow the workspace gives up and marks the column NaN, which
:func:`solve` reports.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
from numba import prange

from multilayer.engine.compiled import jit, parallel_compiled
from multilayer.engine.state_check import all_finite
from multilayer.engine.threads import numba_threads, parallel_chunks
from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.errors import RunError

INF = np.inf


@jit
def _between(x0, y0, x1, y1, x):
    """The ordinate at ``x0 < x < x1`` of the segment from ``(x0, y0)`` to ``(x1, y1)``,
    interpolated from its nearer end: a vertex far out on a ray (the messages hold some
    at abscissae ~1e13) would otherwise cancel the digits of a nearby value."""
    if x - x0 <= x1 - x:
        return y0 + (x - x0) / (x1 - x0) * (y1 - y0)
    return y1 - (x1 - x) / (x1 - x0) * (y1 - y0)


@jit(borrowing=True)
def _at(X, Y, n, sl, sr, x, i):
    """Interval [lo, hi] of the relation at ``x``, scanning from vertex ``i``.

    Returns (lo, hi, i) with ``i`` the first vertex with ``X[i] >= x``, so that a walk
    over increasing ``x`` is linear.  Vertical rays give ``-inf``/``inf``.
    """
    while i < n and X[i] < x:
        i += 1
    if i == n:
        y = Y[n - 1] + sr * (x - X[n - 1]) if x > X[n - 1] else Y[n - 1]
        return y, y, i
    if X[i] > x:
        if i == 0:
            y = Y[0] + sl * (x - X[0])
        else:  # strictly inside a segment
            y = _between(X[i - 1], Y[i - 1], X[i], Y[i], x)
        return y, y, i
    j = i
    while j + 1 < n and X[j + 1] == x:
        j += 1
    lo = -INF if (i == 0 and sl == INF) else Y[i]
    hi = INF if (j == n - 1 and sr == INF) else Y[j]
    return lo, hi, i


@jit(borrowing=True)
def _add(X1, Y1, n1, sl1, sr1, X2, Y2, n2, sl2, sr2, Xo, Yo):
    """Sum of two maximal monotone relations; writes vertices to Xo, Yo, returns (n, sl, sr)."""
    lo = max(X1[0] if sl1 == INF else -INF, X2[0] if sl2 == INF else -INF)
    hi = min(X1[n1 - 1] if sr1 == INF else INF, X2[n2 - 1] if sr2 == INF else INF)
    n = 0
    i1 = 0
    i2 = 0
    j1 = np.int64(0)  # the scans of _at, typed int64 from the start (a literal 0 compiles _at again)
    j2 = np.int64(0)
    while i1 < n1 or i2 < n2:
        # next breakpoint of the merged abscissae
        if i2 >= n2 or (i1 < n1 and X1[i1] <= X2[i2]):
            b = X1[i1]
        else:
            b = X2[i2]
        start1, start2 = i1, i2
        while i1 < n1 and X1[i1] == b:
            i1 += 1
        while i2 < n2 and X2[i2] == b:
            i2 += 1
        if i1 == start1 and i2 == start2:  # a NaN abscissa: stop rather than spin for ever
            return -1, sl1, sr1
        if b < lo or b > hi:
            continue
        lo1, hi1, j1 = _at(X1, Y1, n1, sl1, sr1, b, j1)
        lo2, hi2, j2 = _at(X2, Y2, n2, sl2, sr2, b, j2)
        ylo = lo1 + lo2
        yhi = hi1 + hi2
        if ylo > -INF:
            Xo[n] = b
            Yo[n] = ylo
            n += 1
        if yhi < INF and (yhi > ylo or ylo == -INF):
            Xo[n] = b
            Yo[n] = yhi
            n += 1
        if ylo == -INF and yhi == INF:  # a whole vertical line: keep one anchor vertex
            Xo[n] = b
            Yo[n] = 0.0
            n += 1
        if n + 3 > Xo.shape[0]:  # never write outside the workspace (cannot happen on finite input)
            return -1, sl1, sr1
    sl = INF if lo > -INF else sl1 + sl2
    sr = INF if hi < INF else sr1 + sr2
    return n, sl, sr


@jit
def _inv(s):
    if s == 0.0:
        return INF
    if s == INF:
        return 0.0
    return 1.0 / s


@jit(borrowing=True)
def _root(X, Y, n, sl, sr):
    """The abscissa where a strictly increasing relation contains 0 (exact at vertices)."""
    i = 0
    while i < n and Y[i] < 0.0:
        i += 1
    if i == n:
        return X[n - 1] - Y[n - 1] / sr
    if i == 0:
        if Y[0] == 0.0 or sl == INF:
            return X[0]
        return X[0] - Y[0] / sl
    if Y[i] == 0.0 or X[i] == X[i - 1]:
        return X[i]
    return _between(Y[i - 1], X[i - 1], Y[i], X[i], 0.0)


@jit(borrowing=True)
def _dynamic_programme(inertia, momentum, kappa, c, w, cw, u, ws):
    """Exact minimiser of E(u) for one column by dynamic programming (module docstring);
    ``inertia = m / dt`` and ``momentum = m u* / dt`` per layer."""
    L = inertia.shape[0]
    MX, MY, Mn, Msl, Msr, HX, HY, TX, TY, FX, FY, GX, GY = ws
    pair = FX.size  # the 2 vertices of FX and GX, typed int64 (a literal 2 would compile _add again)
    # ground link: h_0' = g_0' (u_0 = 0)
    HX[0] = 0.0
    HX[1] = 0.0
    HY[0] = -kappa[0]
    HY[1] = kappa[0]
    hn = pair
    hsl = c[0]
    hsr = c[0]
    for a in range(L):
        A = inertia[a] + cw[a]
        B = momentum[a]
        FX[0] = 0.0
        FX[1] = 0.0
        FY[0] = -B - w[a]
        FY[1] = -B + w[a]
        n, sl, sr = _add(FX, FY, pair, A, A, HX, HY, hn, hsl, hsr, MX[a], MY[a])
        if n < 0:
            u[:] = np.nan
            return
        Mn[a] = n
        Msl[a] = sl
        Msr[a] = sr
        if a == L - 1:
            break
        # h_a' = ( (m_a')^-1 + (g_{a+1}')^-1 )^-1 : infimal convolution with the interface term
        k = kappa[a + 1]
        GX[0] = -k
        GX[1] = k
        GY[0] = 0.0
        GY[1] = 0.0
        gs = _inv(c[a + 1])
        n2, sl2, sr2 = _add(MY[a], MX[a], n, _inv(sl), _inv(sr), GX, GY, pair, gs, gs, TY, TX)
        if n2 < 0:
            u[:] = np.nan
            return
        for i in range(n2):
            HX[i] = TX[i]
            HY[i] = TY[i]
        hn = n2
        hsl = _inv(sl2)
        hsr = _inv(sr2)
    # backward pass: u_L minimises the last message; then each layer given the one above
    u[L - 1] = _root(MX[L - 1], MY[L - 1], Mn[L - 1], Msl[L - 1], Msr[L - 1])
    for a in range(L - 2, -1, -1):
        v = u[a + 1]
        k = kappa[a + 1]
        GX[0] = v
        GX[1] = v
        GY[0] = -k
        GY[1] = k
        n, sl, sr = _add(MX[a], MY[a], Mn[a], Msl[a], Msr[a], GX, GY, pair, c[a + 1], c[a + 1], TX, TY)
        if n < 0:
            u[:] = np.nan
            return
        u[a] = _root(TX, TY, n, sl, sr)


@jit
def _workspace(L):
    cap = 8 * L + 16
    return (
        np.empty((L, cap)),
        np.empty((L, cap)),  # messages m_a' up to layer a
        np.zeros(L, np.int64),
        np.empty(L),
        np.empty(L),
        np.empty(cap),
        np.empty(cap),  # incoming message h' through the interface above
        np.empty(cap),
        np.empty(cap),
        np.empty(2),
        np.empty(2),
        np.empty(2),
        np.empty(2),
    )


@jit
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


# compiled once, linked into its callers (numba inlining lowered it at each call); a pivot of
# a column a few 1e-74 m thick can underflow to zero: its inverse is inf, not an exception
@jit(borrowing=True, error_model="numpy")
def _active_set(inertia, momentum, kappa, c, w, cw, guess, u, first, grounded, U, diag, low, rhs, hint):
    """Solve with the lock/sign structure of ``guess``; True if it is the exact minimiser
    (``inertia = m / dt`` and ``momentum = m u* / dt`` per layer).

    Interfaces with ``kappa > 0`` across which ``guess`` does not jump are locked, layers
    at rest with ``w > 0`` are held by the walls.  Locked layers form rigid groups; a
    group holding the ground (locked bed or walls) is at rest, ``u = 0.0``.  The other
    group velocities solve a tridiagonal system (the group sums of the momentum balance
    with the yielded stresses ``kappa sgn + c s``).  The structure is accepted when the
    yielded jumps keep their signs and the locked stresses admit values within their
    yield bounds (interval propagation through grounded groups).

    One pass up the column forms the groups, their equations and the forward sweep of
    the Thomas algorithm (each group is eliminated as soon as it is complete); one pass
    down substitutes back and checks optimality, so every layer is visited twice.

    A rejected structure leaves in ``hint`` (2,) the interface of the first violation
    found and its state in the update of a primal-dual active set method (Hintermüller,
    Ito & Kunisch 2003, SIAM J. Optim. 13): 0 to lock a yielded interface whose jump changed sign, +-1 to
    open a locked one whose stress exceeds its yield stress (the sign of the stress,
    hence of the jump); ``hint[0] = -1`` where the violation is of another kind.
    """
    L = inertia.shape[0]
    hint[0] = -1
    scale = 0.0
    ng = 0
    below = 0.0
    d = 0.0  # sums over the layers of the open group, then its equation
    r = 0.0
    d_below = 1.0  # the inverse pivot and right-hand side of the group below (forward sweep)
    r_below = 0.0
    sign_top = 0.0  # sign of the jump across the interface above the open group
    for a in range(L + 1):
        if a < L:
            g = guess[a]
            scale += abs(momentum[a]) + kappa[a] + w[a]
            opens = a == 0 or not (kappa[a] > 0.0 and g == below)
            if opens:
                sign_top = _sign(g - below)
        else:
            opens = True
        if opens and a > 0:  # close the group ng - 1, whose top interface is a
            j = ng - 1
            if grounded[j]:
                d, r = 1.0, 0.0
            else:
                p = first[j]
                d += c[p]
                r -= kappa[p] * low[j]
                if a < L:
                    d += c[a]
                    r += kappa[a] * sign_top
                if p > 0 and c[p] != 0.0:  # forward sweep: eliminate the coupling to group j - 1
                    f = -c[p] * d_below
                    d -= f * (-c[p] if not grounded[j - 1] else 0.0)
                    r -= f * r_below
            d = 1.0 / d
            diag[j], rhs[j] = d, r  # diag: the inverse pivots
            d_below, r_below = d, r
        if a == L:
            break
        if opens:
            first[ng] = a
            grounded[ng] = a == 0 and kappa[0] > 0.0 and g == 0.0
            low[ng] = sign_top  # low: the sign of the jump below each group
            ng += 1
            d = 0.0
            r = 0.0
        if w[a] > 0.0 and g == 0.0:
            grounded[ng - 1] = True
        d += inertia[a] + cw[a]
        r += momentum[a] - _sign(g) * w[a]
        below = g
    first[ng] = L
    slack = 1e-10 * scale + 1e-300
    # back substitution, top down, with the optimality of each group as soon as the
    # velocities it needs are known: signs of the yielded jumps and walls, bounds of
    # the locked stresses inside moving groups
    held = 0  # grounded groups, checked below
    for j in range(ng - 1, -1, -1):
        p, q = first[j], first[j + 1] - 1
        if grounded[j]:
            U[j] = 0.0
            held += 1
        else:
            r = rhs[j]
            if j + 1 < ng:
                r += c[q + 1] * U[j + 1]
            U[j] = r * diag[j]
        Uj = U[j]
        for a in range(p, q + 1):
            u[a] = Uj
        if q + 1 < L:
            sig = low[j + 1]
            if kappa[q + 1] > 0.0 and (sig == 0.0 or sig * (U[j + 1] - Uj) < 0.0):
                hint[0], hint[1] = q + 1, 0
                return False  # the yielded interface above the group
            tau = kappa[q + 1] * sig + c[q + 1] * (U[j + 1] - Uj)
        else:
            tau = 0.0
        if grounded[j]:
            continue
        for a in range(q, p, -1):  # locked interfaces inside a moving group
            if w[a] > 0.0 and _sign(guess[a]) * Uj < 0.0:
                return False
            tau -= (inertia[a] + cw[a]) * Uj - momentum[a] + _sign(guess[a]) * w[a]
            if abs(tau) > kappa[a] + slack:
                hint[0], hint[1] = a, 1 if tau > 0.0 else -1
                return False
        if w[p] > 0.0 and _sign(guess[p]) * Uj < 0.0:
            return False
    if kappa[0] > 0.0 and not (grounded[0] and guess[0] == 0.0):  # the bed yielded
        sig = low[0]
        if sig == 0.0 or sig * U[0] < 0.0:
            hint[0], hint[1] = 0, 0
            return False
    if held == 0:
        return True
    for j in range(ng):  # grounded groups: feasible stresses, top down
        if not grounded[j]:
            continue
        p, q = first[j], first[j + 1] - 1
        Ub = U[j - 1] if j > 0 else 0.0
        sig = low[j]
        if q + 1 < L:
            tau = kappa[q + 1] * low[j + 1] + c[q + 1] * (U[j + 1] - U[j])
        else:
            tau = 0.0
        lo = tau
        hi = tau
        for a in range(q, p - 1, -1):
            lo += momentum[a] - w[a]
            hi += momentum[a] + w[a]
            if a > p or (a == 0 and kappa[0] > 0.0 and guess[0] == 0.0):
                if lo > kappa[a] + slack or hi < -kappa[a] - slack:  # the interface slides
                    hint[0], hint[1] = a, 1 if lo > kappa[a] else -1
                    return False
                lo = max(lo, -kappa[a])
                hi = min(hi, kappa[a])
                if lo > hi + slack:
                    return False
            else:  # the yielded interface below the group
                tau_p = kappa[p] * sig + c[p] * (0.0 - Ub)
                if tau_p < lo - slack or tau_p > hi + slack:
                    return False
    return True


def _columns(m, ustar, dt, kappa, c, w, cw, guess, u, chunks):
    """Solve every column; arrays are (N, L) here so that each column is contiguous."""
    N, L = m.shape
    for k in prange(chunks):
        ws = _workspace(L)
        first = np.empty(L + 1, np.int64)
        grounded = np.empty(L, np.bool_)
        U, diag, low, rhs = np.empty(L), np.empty(L), np.empty(L), np.empty(L)
        hint = np.empty(2, np.int64)
        inertia, momentum = np.empty(L), np.empty(L)  # m_a / dt and m_a u*_a / dt
        per_dt = 1.0 / dt  # as products with 1/dt, the bits of the other kernels (sheared_columns.set_up)
        for i in range(k * N // chunks, (k + 1) * N // chunks):
            if m[i, 0] <= 0.0:
                u[i, :] = 0.0
                continue
            for a in range(L):
                inertia[a] = m[i, a] * per_dt
                momentum[a] = m[i, a] * ustar[i, a] * per_dt
            ki, ci, wi, cwi, ui = kappa[i], c[i], w[i], cw[i], u[i]
            if not _active_set(
                inertia, momentum, ki, ci, wi, cwi, guess[i], ui, first, grounded, U, diag, low, rhs, hint
            ):
                _dynamic_programme(inertia, momentum, ki, ci, wi, cwi, ui, ws)


_solve_serial: Any = jit(_columns)
_solve_parallel: Any = parallel_compiled(_columns)


def solve(
    problem: ColumnProblem,
    guess: np.ndarray | None = None,
    threads: int = 1,
    poll: Callable[[], None] | None = None,
) -> np.ndarray:
    """Exact minimiser of the implicit vertical step for every column (L, N).

    ``guess`` (e.g. the previous velocities, (L, N)) proposes the structure of rigid and
    static groups; it only affects the speed.  ``threads > 1`` solves that many chunks of
    columns in parallel (``engine/threads.py`` chooses it).  This is a
    :class:`~multilayer.engine.vertical.problem.VerticalSolver` (one compiled call: ``poll``
    is not called within it); the compiled functions
    take the coefficients as arrays (N, L), each column contiguous.
    """
    p = problem
    coefficients = (p.m, p.ustar, p.kappa, p.c, p.w, p.cw)
    arrays = [np.ascontiguousarray(np.transpose(a), dtype=float) for a in coefficients]
    guess = arrays[1] if guess is None else np.ascontiguousarray(np.transpose(guess), dtype=float)
    if not all(all_finite(a) for a in arrays):  # one pass each; locate only if needed
        for name, array in zip(("m", "ustar", "kappa", "c", "w", "cw"), arrays):
            _require_finite(name, array)  # the guess may hold NaN: it only proposes a structure
    if not (np.isfinite(p.dt) and p.dt > 0):
        raise RunError(f"column kernel: the time step dt = {p.dt!r} is not a finite number > 0")
    u = np.empty_like(arrays[0])
    if threads > 1:
        chunks = parallel_chunks(threads, u.shape[0])
        with numba_threads(threads):
            _solve_parallel(*arrays[:2], float(p.dt), *arrays[2:], guess, u, chunks)
    else:
        _solve_serial(*arrays[:2], float(p.dt), *arrays[2:], guess, u, 1)
    if not all_finite(u):
        _require_finite("the solution u", u)
    return u.T


def _require_finite(name: str, array: np.ndarray) -> None:
    """RunError naming ``name`` and the first non-finite (column, layer) of an (N, L) array."""
    if array.size and not (array.min() > -np.inf and array.max() < np.inf):  # NaN fails both
        i, a = np.unravel_index(np.argmin(np.isfinite(array)), array.shape)
        raise RunError(
            f"column kernel: {name} is {float(array[i, a])!r} in column {i} of the {array.shape[0]} "
            f"solved, layer or interface {a}; the kernel only accepts finite values"
        )


def not_finite(values: np.ndarray, x: float, t: float) -> RunError:
    """The error of a column whose Newton iterate (``values``: its value and layer) is not
    finite: its coefficients are beyond double precision."""
    return RunError(
        f"the vertical step's exact solve gave the velocity u = {float(values[0])!r} at x = {x:.6g} m, layer "
        f"{int(values[1]) + 1} (1 is at the bed), t = {t:.6g} s: the column's coefficients (the laws' "
        "conductances against the layers' masses) are beyond double precision"
    )
