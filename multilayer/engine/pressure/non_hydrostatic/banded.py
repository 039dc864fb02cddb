"""The banded solver of the non-hydrostatic pressure: Cholesky factorisation of the
normal equations ``A lam = r`` in band storage, and the pressure bound ``lam <= lam_max``
(the total pressure never negative) by primal-dual active sets (Hintermueller, Ito &
Kunisch 2002), refactoring from the first row whose status changed.  Compiled by numba.
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.errors import RunError

MAX_ACTIVE_SET_ITERATIONS = 100
"""The least cap of the active-set iterations (:func:`iteration_cap`)."""


def iteration_cap(rows: int) -> int:
    """The iterations of :func:`bounded` allowed on ``rows`` unknowns: ``rows + 1``, at least
    :data:`MAX_ACTIVE_SET_ITERATIONS`.  For an M-matrix the active sets after the first
    iteration are nested, so the iteration ends in at most ``rows + 1`` (Hintermueller, Ito &
    Kunisch 2002, section 3).  ``A`` is not one, but from a set far from the answer its
    iteration behaves much so: from the set of the repair of the start's violation the
    pressure's iteration released a line of bound interfaces one column per iteration, 101
    iterations without a repeated set (docs/model.md, "Shear stress on vertical planes"),
    which the cap of 100 cut short."""
    return max(MAX_ACTIVE_SET_ITERATIONS, rows + 1)


@jit
def _fixed_entry(band, fixed, i, d):
    """``A'_i,i+d``: ``A`` with the rows and columns of ``fixed`` replaced by the identity."""
    if i + d >= band.shape[0]:
        return 0.0
    if fixed[i] or fixed[i + d]:
        return 1.0 if d == 0 else 0.0
    return band[i, d]


@jit
def factor(band, fixed, U, start):
    """The banded Cholesky factor ``A' = U^T U`` (``U[i, d] = U_i,i+d``) of ``A`` with the
    rows and columns of ``fixed`` replaced by the identity, in outer-product order
    (contiguous inner loops), kept in the columns before ``start``.

    ``U[:s, :s]`` depends on ``A'[:s, :s]`` only: when ``fixed`` changed from index
    ``start`` on, only the entries of the columns from ``start`` on are computed again
    (those of the ``w`` rows before it by their own recurrence, then the rows from it)."""
    n, w = band.shape[0], band.shape[1] - 1
    for p in range(max(0, start - w), start):
        for d in range(start - p, w + 1):
            U[p, d] = _fixed_entry(band, fixed, p, d)
        for m in range(max(0, p - w), p):
            k = p - m
            for d in range(start - p, w + 1 - k):
                U[p, d] -= U[m, k] * U[m, d + k]
        for d in range(start - p, w + 1):
            U[p, d] /= U[p, 0]
    for i in range(start, n):  # U[start:] = band[start:], without numba's shape check (its message
        for d in range(w + 1):  # formatting alone costs more compile time than the factorisation)
            U[i, d] = band[i, d]
    for i in range(start, n):
        if fixed[i]:
            U[i] = 0.0
            U[i, 0] = 1.0
            for d in range(1, min(w, i - start) + 1):
                U[i - d, d] = 0.0
    for i in range(max(0, start - w), start):  # finished rows: their updates of the columns from start
        source = U[i]
        for k in range(start - i, min(w, n - 1 - i) + 1):
            factor = source[k]
            target = U[i + k]
            for d in range(k, w + 1):
                target[d - k] -= factor * source[d]
    i = start
    while i < n:
        # rows i and i + 1 together: each entry of a row below takes the update of row i, then
        # that of row i + 1, in the order of one row at a time (the same result, bit for bit),
        # with half the passes over the rows below
        source = U[i]
        _normalise(source, w)
        if i + 1 == n:
            break
        second = U[i + 1]
        factor = source[1]
        for d in range(1, w + 1):
            second[d - 1] -= factor * source[d]
        _normalise(second, w)
        for k in range(2, min(w, n - 1 - i) + 1):
            factor, factor2 = source[k], second[k - 1]
            target = U[i + k]
            for d in range(k, w + 1):
                target[d - k] = (target[d - k] - factor * source[d]) - factor2 * second[d - 1]
            target[w + 1 - k] -= factor2 * second[w]
        if 0 < w and i + w + 1 < n:
            U[i + w + 1, 0] -= second[w] * second[w]
        i += 2


@jit
def _normalise(row, w):
    """Row of the Cholesky factor from its updated row of ``A``: the diagonal's square root,
    the rest divided by it."""
    if row[0] <= 0.0:
        raise RunError(
            "the non-hydrostatic pressure system is not positive definite (a non-positive pivot "
            "of its Cholesky factorisation): the constraints of the moving layers are singular"
        )
    diagonal = np.sqrt(row[0])
    inverse = 1.0 / diagonal
    row[0] = diagonal
    for d in range(1, w + 1):
        row[d] *= inverse


@jit
def substitute(U, b):
    """Solve ``U^T U x = b`` for the factor of ``factor``."""
    y = np.empty(b.size)
    _forward(U, b, y, 0)
    return _backward(U, y)


@jit
def _forward(U, b, y, start):
    """``y = U^-T b`` column by column, from row ``start`` on: ``y[:start]`` are kept from a
    solve whose ``b[:start]`` and rows ``U[:start - w]`` were the same (their updates of the
    rows from ``start`` are applied first, in the order of a whole solve: the same result,
    bit for bit)."""
    n, w = U.shape[0], U.shape[1] - 1
    for i in range(start, n):  # y[start:] = b[start:] (as in factor)
        y[i] = b[i]
    for i in range(max(0, start - w), start):
        for d in range(start - i, min(w, n - 1 - i) + 1):
            y[i + d] -= U[i, d] * y[i]
    for i in range(start, n):
        y[i] /= U[i, 0]
        for d in range(1, min(w, n - 1 - i) + 1):
            y[i + d] -= U[i, d] * y[i]


@jit
def _backward(U, y):
    """``x = U^-1 y``."""
    n, w = U.shape[0], U.shape[1] - 1
    x = y.copy()
    for i in range(n - 1, -1, -1):  # U x = y
        s = x[i]
        for d in range(1, min(w, n - 1 - i) + 1):
            s -= U[i, d] * x[i + d]
        x[i] = s / U[i, 0]
    return x


@jit
def bounded(band, r, lam_max, active, max_iterations, U, start):
    """Minimiser of ``1/2 lam^T A lam - r^T lam`` subject to ``lam <= lam_max`` by primal-dual
    active sets (Hintermueller, Ito & Kunisch 2002) from the guess ``active`` (updated in
    place): on the active set ``lam = lam_max``, elsewhere ``(A lam)_i = r_i``; it stops
    when the set reproduces itself, i.e. the bound multiplier ``mu = r - A lam >= 0`` on
    it and ``lam <= lam_max`` off it.  The guess only changes the work, never the answer.
    Each iteration refactors the Cholesky factor ``U`` (band's shape) from the first row
    whose status changed, the first from the row ``start``: ``U`` holds on entry the factor
    (a solve's on the same ``A``) of a set equal to ``active`` before that row (0: all of
    ``U`` is computed; ``n``: none).  Returns ``lam`` and the iterations (-1: not settled);
    ``U`` holds the factor of the final set."""
    n, w = band.shape[0], band.shape[1] - 1
    rhs, y = np.empty(n), np.empty(n)
    for iteration in range(1, max_iterations + 1):
        factor(band, active, U, start)
        # the bounded unknowns move to the right-hand side of the free rows
        for j in range(n):  # rhs[:] = r (as in factor)
            rhs[j] = r[j]
        for j in range(n):
            if active[j]:
                rhs[j] = lam_max[j]
                for d in range(1, w + 1):
                    if j + d < n and not active[j + d]:
                        rhs[j + d] -= band[j, d] * lam_max[j]
                    if j - d >= 0 and not active[j - d]:
                        rhs[j - d] -= band[j - d, d] * lam_max[j]
        # rows from start - w on changed (in U and in rhs): the forward solve restarts there
        _forward(U, rhs, y, 0 if iteration == 1 else max(0, start - w))
        lam = _backward(U, y)
        start = n
        for i in range(n):
            if active[i]:  # the bound's multiplier mu = (r - A lam)_i must be positive
                mu = r[i] - band[i, 0] * lam[i]
                for d in range(1, w + 1):
                    if i + d < n:
                        mu -= band[i, d] * lam[i + d]
                    if i - d >= 0:
                        mu -= band[i - d, d] * lam[i - d]
                new = mu > 0.0
            else:
                new = lam[i] > lam_max[i]
            if new != active[i]:
                start = min(start, i)
                active[i] = new
        if start == n:
            return lam, iteration
    return lam, -1


@jit
def _gathered(active, lam_max, rows, kept, guess, bound):
    """The guess ``active[rows]`` (all False if ``active`` is empty) and the bound
    ``lam_max[rows]`` into ``guess`` and ``bound``; returns the first row where the guess
    and the set ``kept`` of a factor differ (``rows.size``: none; 0 if ``kept`` is empty)."""
    for k in range(rows.size):
        at = np.uint64(rows[k])  # unsigned: numba leaves out the wrap-around of negative indices
        guess[k] = active[at] if active.size > 0 else False
        bound[k] = lam_max[at]
    if kept.size == 0:
        return np.int64(0)
    for k in range(rows.size):
        if guess[k] != kept[k]:
            return np.int64(k)
    return np.int64(rows.size)


_NO_GUESS = np.empty(0, np.bool_)
"""No guess of the active set (all False), or no factor's set, for :func:`_gathered`."""


Factor = tuple[np.ndarray, np.ndarray]
"""The Cholesky factor of ``A`` (band storage) with the rows of a set fixed, and that set."""


def multipliers(
    band: np.ndarray,
    r: np.ndarray,
    rows: np.ndarray,
    lam_max: np.ndarray | None,
    active: np.ndarray | None,
    factored: Factor | None = None,
) -> tuple[np.ndarray, Factor]:
    """``lam`` of :func:`correction` from ``A`` (band storage) and ``r = E V*`` on the rows
    of the cells ``rows``, from the guess ``active`` of the active set (updated in place),
    and the Cholesky factor of ``A`` with the rows of the final active set fixed;
    ``factored``: such a factor of a call on the same ``A``, kept before the first row
    where its set and the guess differ (all of it: the same set)."""
    if lam_max is None:
        if factored is None:
            factored = (np.zeros(band.shape), np.zeros(r.size, np.bool_))
            factor(band, factored[1], factored[0], 0)
        return substitute(factored[0], r), factored
    guess, bound = np.empty(rows.size, np.bool_), np.empty(rows.size)
    start = _gathered(
        _NO_GUESS if active is None else active.ravel(), lam_max.ravel(), rows,
        _NO_GUESS if factored is None else factored[1], guess, bound,
    )  # fmt: skip
    U = np.empty(band.shape) if factored is None else factored[0]
    cap = iteration_cap(rows.size)
    lam, iterations = bounded(band, r, bound, guess, cap, U, start)
    if iterations < 0:
        raise RunError(
            f"the non-hydrostatic pressure bound p >= 0 was not settled in {cap} active-set iterations"
        )
    if active is not None:
        active.ravel()[rows] = guess
    return lam, (U, guess)
