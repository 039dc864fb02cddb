"""Non-hydrostatic pressure of the multilayer model: a vertical velocity per layer and an
implicit pressure projection each step (docs/nonhydrostatic.md).

The layer-averaged Euler hierarchy of Fernandez-Nieto, Parisot, Penel & Sainte-Marie
(2018) adds to the hydrostatic multilayer system a vertical velocity ``w`` and a
non-hydrostatic (kinematic) pressure ``q`` with, per layer ``a`` between the interfaces
``z_a`` (below) and ``z_{a+1}`` (above),

    d_t(h_a u_a) + ... = - d_x(h_a qbar_a) + q_{a+1} d_x z_{a+1} - q_a d_x z_a,
    d_t(h_a wbar_a) + ... = - (q_{a+1} - q_a),
    d_x(h_a u_a) - u_{a+1} d_x z_{a+1} + u_a d_x z_a + w_{a+1} - w_a = 0,

with ``q = 0`` at the free surface, ``w_0 = u_0 d_x b`` at the bed, and, as in the
Keller-box scheme of Stelling & Zijlema (2003), ``qbar_a`` and ``wbar_a`` the means of the
interface values of layer ``a``.  Popinet (2020) uses the same layer quantities with a
different vertical stencil; the Keller box is chosen because its linear dispersion is
within 0.6 % of Airy's up to ``kh = 3`` with two layers and falls as ``1/L^2``
(docs/nonhydrostatic.md has the table), where the centred stencil needs six layers for
1 % at ``kh = 2``.

Each step, after the transport and the exact-yield vertical step, the velocities are
projected on the discrete constraint (a pressure-correction step, Chorin 1968):
``V = V* - M^-1 E^T lam`` with ``E M^-1 E^T lam = E V*``.  ``lam`` is a multiplier of
the rows of ``E`` below; the pressures ``q`` follow from the change of ``wbar``.

Notes
-----
Unknowns ``V``: the face velocities ``v_{a,f} = (u_{a,i} + u_{a,i+1}) / 2`` of each layer
at each face ``f`` between columns ``i`` and ``i+1`` (mass ``h_{a,f}``, the mean of the
two layer thicknesses) and the layer means ``wbar_{a,i}`` (mass ``h_{a,i}``).  With the
layer flux divergence ``F_{a,i} = (h_{a,f+} v_{a,f+} - h_{a,f-} v_{a,f-}) / dx`` and the
interface slope fluxes ``S_{j,i} = 1/2 sum_{f = f-, f+} vhat_{j,f} (z_{j,i+1/2 side} -
z_{j,i-1/2 side}) / dx`` (``vhat`` the face velocity interpolated on interface ``j``;
``j = 0`` the bed, ``j = L`` the surface), the constraint of each layer, recombined so that
every row is local (an invertible recombination does not change the projection), is::

    E_0 V = wbar_0 - (S_0 + S_1)/2 + F_0 / 2 = 0,
    E_a V = wbar_a - wbar_{a-1} - (S_{a+1} - S_{a-1})/2 + (F_{a-1} + F_a)/2 = 0,   a >= 1,

which is ``w_{a+1} - w_a = S_{a+1} - S_a - F_a`` with ``wbar_a = (w_a + w_{a+1})/2``.  The
projection ``V = V* - M^-1 E^T lam`` is then exactly the Keller-box pressure force above
with ``q_a = sum_{b >= a} h_b (wbar_b - wbar*_b) / dt = -lam_a / dt`` (``q_L = 0``), and,
without the pressure bound, the kinetic energy ``1/2 V^T M V`` never grows (an
orthogonal projection in the ``M`` norm).  The operator ``A = E M^-1 E^T`` is symmetric
positive definite with a stencil of three columns by seven layers; with the unknowns
ordered column by column it is banded (half-width ``L + 3``) and solved by banded
Cholesky.  The total pressure is kept non-negative, ``lam_a <= dt g cos(theta) (h - z_a)``,
by primal-dual active sets on ``1/2 lam^T A lam - lam^T E V*``.  Cell centres take the
mean of the corrections of their two faces (an approximate projection, Almgren, Bell &
Szymczak 1996).  Faces on a wall, outflow or inflow boundary carry no correction (zero
normal pressure gradient); periodic domains connect their ends.

Material at rest takes no part: only cells whose velocity after the vertical step is
non-zero are constrained and corrected, so material held by the yield stress stays at
``u == 0.0`` exactly, and a field that already satisfies the constraint (uniform flow) has
``E V* = 0``, hence ``lam = 0`` and no change at all.
``multilayer.reference.nonhydrostatic_fipy.project`` assembles the same operator
from FiPy terms on the X-sigma mesh for flat interfaces
(``multilayer/reference/nonhydrostatic_fipy.py``).

Fewer pressure layers: with ``pressure_layers = L_p < L`` the pressure lives on the bottom
interfaces of ``L_p`` groups of whole layers (:func:`pressure_nodes`) and, on every
velocity interface, is its linear interpolation in sigma, zero at the surface
(:func:`pressure_interpolation`, ``lam = P lam_p``).  The constraint is the Galerkin one,
``P^T E V = 0`` (``L_p`` rows per column), and the projection ``V = V* - M^-1 E^T P
lam_p`` with ``(P^T A P) lam_p = P^T E V*``: the orthogonal projection in the ``M`` norm on
a larger subspace than ``E V = 0``, so it still never adds kinetic energy, and ``E V* = 0``
(rest, uniform flow) still gives ``lam_p = 0``.  The band of ``P^T A P`` has half-width
about ``L_p + 3``: the factorisation costs O(L_p^3) per column instead of O(L^3).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit

from multilayer.engine.transport_kernel import span
from multilayer.errors import RunError


@dataclass
class Constraint:
    """The columns of the constraint matrix ``E``, unknown by unknown (module Notes).

    Unknowns: the face velocities ``a * F + f`` then the ``wbar`` at ``L * F + a * N + i``;
    unknown ``k`` has the entries ``values[pointer[k]:pointer[k + 1]]`` in the rows (cells
    ``a * N + i``) ``cells[pointer[k]:pointer[k + 1]]``.  ``mass`` are the masses ``M``,
    ``left`` and ``right`` the columns of the faces."""

    pointer: np.ndarray
    cells: np.ndarray
    values: np.ndarray
    mass: np.ndarray
    left: np.ndarray
    right: np.ndarray
    shape: tuple[int, int]

    @property
    def E(self) -> sp.csr_matrix:
        """``E`` as a sparse matrix (rows: cells, columns: unknowns)."""
        counts = np.diff(self.pointer)
        unknowns = np.repeat(np.arange(counts.size), counts)
        return sp.csr_matrix((self.values, (self.cells, unknowns)), shape=self.shape)


def faces(N: int, periodic: bool) -> tuple[np.ndarray, np.ndarray]:
    """Columns on the left and right of each face carrying a pressure correction."""
    left = np.arange(N - 1)
    if periodic and N > 1:
        return np.append(left, N - 1), np.append(left + 1, 0)
    return left, left + 1


def constraint(
    h: np.ndarray,
    bed: np.ndarray,
    fractions: np.ndarray,
    dx: float,
    periodic: bool,
    interpolation: np.ndarray | None = None,
) -> Constraint:
    """The local rows ``E`` of the layer divergence constraint (module Notes), or with the
    pressure ``interpolation`` ``P`` (L, L_p) of :func:`pressure_interpolation` the reduced
    rows ``P^T E`` (one per pressure interface and column: cell ``g * N + i``)."""
    L, N = fractions.size, h.size
    P = np.eye(L) if interpolation is None else np.asarray(interpolation, dtype=float)
    left, right = faces(N, periodic)
    K, Lp = L * left.size + L * N, P.shape[1]
    pointer, mass = np.empty(K + 1, np.int64), np.empty(K)
    cells, values = (
        np.empty(_capacity(L, N, left.size, Lp), np.int64),
        np.empty(_capacity(L, N, left.size, Lp)),
    )
    n = _entries(
        np.asarray(h, dtype=float), np.asarray(bed, dtype=float), np.asarray(fractions, dtype=float),
        float(dx), left, right, P, np.ones(K, np.bool_), np.arange(Lp * N), pointer, cells, values, mass,
    )  # fmt: skip
    cells, values = cells[:n], values[:n]
    return Constraint(pointer, cells, values, mass, left, right, (P.shape[1] * N, L * left.size + L * N))


def pressure_nodes(fractions: np.ndarray, pressure_layers: int) -> np.ndarray:
    """The velocity layers whose bottom interfaces carry the pressure: ``pressure_layers``
    groups of whole layers, each group's bottom interface the one nearest ``sigma = g /
    L_p`` (equal fractions of the depth when the layer fractions allow it; every group
    holds at least one layer).  ``pressure_layers == L`` gives every layer."""
    L = fractions.size
    sigma = np.concatenate([[0.0], np.cumsum(fractions)[:-1]])
    nodes = np.zeros(pressure_layers, dtype=np.int64)
    for g in range(1, pressure_layers):
        lo, hi = nodes[g - 1] + 1, L - (pressure_layers - g)
        candidates = np.arange(lo, hi + 1)
        nodes[g] = candidates[np.argmin(np.abs(sigma[candidates] - g / pressure_layers))]
    return nodes


@functools.lru_cache(maxsize=8)
def _pressure_layers(fractions: tuple[float, ...], pressure_layers: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`pressure_nodes` and :func:`pressure_interpolation`, computed once per model."""
    nodes = pressure_nodes(np.array(fractions), pressure_layers)
    return nodes, pressure_interpolation(np.array(fractions), nodes)


def pressure_interpolation(fractions: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """``P`` (L, L_p): the pressure on the bottom interface of every velocity layer,
    linear in ``sigma`` between the pressure interfaces ``nodes`` (bottom interfaces of the
    groups of :func:`pressure_nodes`) and zero at the free surface: ``q_a = sum_g P_a,g
    q_g``.  With a node at every layer it is the identity."""
    L, Lp = fractions.size, nodes.size
    sigma = np.concatenate([[0.0], np.cumsum(fractions)[:-1]])
    at = np.append(sigma[nodes], 1.0)  # the pressure interfaces and the surface
    P = np.zeros((L, Lp))
    for g in range(Lp):
        P[nodes[g], g] = 1.0
        for a in range(nodes[g] + 1, nodes[g + 1] if g + 1 < Lp else L):
            weight = (at[g + 1] - sigma[a]) / (at[g + 1] - at[g])
            P[a, g] = weight
            if g + 1 < Lp:
                P[a, g + 1] = 1.0 - weight
    return P


@njit(cache=True)
def _entries(h, bed, fractions, dx, left, right, P, free, row_of, pointer, cells, values, mass):
    """``P^T E`` column by column (see :class:`Constraint`) for the unknowns ``free`` (the
    others have no entries) in the rows ``row_of[cell] >= 0`` (the entries in the others
    are left out): each entry is stored with its row ``row_of[cell]``.  In ``E``, ``F_c``
    enters the rows ``c`` and ``c + 1`` with 1/2; ``S_j`` (interface ``j``, its velocity
    ``vhat_j = beta_j,c-1 v_c-1 + beta_j,c v_c`` weighted by the thicknesses) enters row 0
    with -1/2 (``j`` = 0, 1), row ``j - 1`` with -1/2 (``j >= 2``) and row ``j + 1`` with
    +1/2; ``wbar_a`` enters row ``a`` with +1 and row ``a + 1`` with -1.  Each entry of row
    ``a`` goes to the pressure rows ``g`` with ``P_a,g != 0``, times ``P_a,g`` (the
    identity: ``E`` itself).  Written into ``pointer``, ``cells`` (the rows), ``values``
    (at least :func:`_capacity` long) and ``mass`` (``M``, of every unknown); returns the
    number of entries."""
    L, N, F = fractions.size, h.size, left.size
    Lp = P.shape[1]
    targets = np.zeros(L, np.int64)  # the pressure rows of each row of E: first, count
    first = np.zeros(L, np.int64)
    for a in range(L):
        first[a] = Lp
        for g in range(Lp):
            if P[a, g] != 0.0:
                first[a] = min(first[a], g)
                targets[a] += 1
    sigma = np.zeros(L + 1)
    for a in range(L):
        sigma[a + 1] = sigma[a] + fractions[a]
    sigma[L] = 1.0
    beta = np.zeros((L + 1, L))
    beta[0, 0] = 1.0
    beta[L, L - 1] = 1.0
    for j in range(1, L):
        total = fractions[j - 1] + fractions[j]
        beta[j, j - 1], beta[j, j] = fractions[j] / total, fractions[j - 1] / total
    rows, weights = np.empty(3, np.int64), np.empty(3)
    touched_rows, at_left, at_right = np.empty(L, np.int64), np.empty(L), np.empty(L)
    n = 0
    if Lp < L:
        # fewer pressure rows: the entries of a face unknown of layer c are, per pressure row
        # g, h_face / dx times those of its F rows plus the slopes times those of its S rows
        flux, slopes, lowest, highest = _face_coefficients(P, beta, L)
    for c in range(L):
        for f in range(F):
            k = c * F + f
            pointer[k] = n
            i, e = left[f], right[f]
            h_face = fractions[c] * 0.5 * (h[i] + h[e])
            mass[k] = h_face
            if not free[k]:
                continue
            # every entry of a face unknown is in a cell of its own (i != e)
            if Lp < L:
                s0 = ((bed[e] + sigma[c] * h[e]) - (bed[i] + sigma[c] * h[i])) / dx
                s1 = ((bed[e] + sigma[c + 1] * h[e]) - (bed[i] + sigma[c + 1] * h[i])) / dx
                ratio = h_face / dx
                for g in range(lowest[c], highest[c] + 1):
                    a0, a1, fc = slopes[0, c, g], slopes[1, c, g], flux[c, g]
                    sloped = s0 * a0 + s1 * a1
                    n = _store(cells, values, n, row_of[g * N + i], ratio * fc + sloped)
                    n = _store(cells, values, n, row_of[g * N + e], sloped - ratio * fc)
            else:
                touched = 0  # the rows of E this unknown enters, in the order they first come
                for row in range(c, min(c + 2, L)):
                    touched = _accumulate(
                        touched_rows, at_left, at_right, touched, row, 0.5 * h_face / dx, -0.5 * h_face / dx
                    )
                for j in (c, c + 1):
                    if beta[j, c] == 0.0:
                        continue
                    slope = ((bed[e] + sigma[j] * h[e]) - (bed[i] + sigma[j] * h[i])) / dx
                    for m in range(_slope_rows(j, L, rows, weights)):
                        value = weights[m] * 0.5 * beta[j, c] * slope
                        touched = _accumulate(touched_rows, at_left, at_right, touched, rows[m], value, value)
                for t in range(touched):
                    n = _store(cells, values, n, row_of[touched_rows[t] * N + i], at_left[t])
                    n = _store(cells, values, n, row_of[touched_rows[t] * N + e], at_right[t])
    for a in range(L):
        for i in range(N):
            k = L * F + a * N + i
            pointer[k] = n
            mass[k] = fractions[a] * h[i]
            if not free[k]:
                continue
            for g in range(first[a], first[a] + targets[a]):
                n = _store(cells, values, n, row_of[g * N + i], P[a, g])
            if a + 1 < L:
                for g in range(first[a + 1], first[a + 1] + targets[a + 1]):
                    row = row_of[g * N + i]
                    if row < 0:
                        continue
                    for m in range(pointer[k], n):  # the same row as one of wbar_a's: added
                        if cells[m] == row:
                            values[m] += -P[a + 1, g]
                            break
                    else:
                        n = _store(cells, values, n, row, -P[a + 1, g])
    pointer[L * F + L * N] = n
    return n


def _capacity(L: int, N: int, F: int, Lp: int) -> int:
    """Entries of :func:`_entries` at most: the rows 0, c - 1, ..., c + 2 of ``E`` for a face
    unknown of layer c, and a, a + 1 for ``wbar_a``, each going to the pressure rows it has
    (1 or 2), in both columns of a face."""
    return 2 * min(Lp, 10) * L * F + min(Lp, 4) * L * N


@njit(cache=True)
def _slope_rows(j, L, rows, weights):
    """The rows of ``E`` that the slope flux ``S_j`` enters and their weights (see
    :func:`_entries`); returns their count."""
    count = 0
    if j <= 1:
        rows[count], weights[count] = 0, -0.5
        count += 1
    if j >= 2:
        rows[count], weights[count] = j - 1, -0.5
        count += 1
    if j <= L - 2:
        rows[count], weights[count] = j + 1, 0.5
        count += 1
    return count


@njit(cache=True)
def _face_coefficients(P, beta, L):
    """``flux[c, g]``: the entry of ``P^T E`` of a face unknown of layer ``c`` in pressure row
    ``g`` per unit ``h_face / dx`` (left column; minus it in the right one), and
    ``slopes[s, c, g]`` per unit slope of the interface ``c + s`` (both columns), and the
    pressure rows ``lowest[c]..highest[c]`` where they are not all zero."""
    Lp = P.shape[1]
    flux, slopes = np.zeros((L, Lp)), np.zeros((2, L, Lp))
    rows, weights = np.empty(3, np.int64), np.empty(3)
    for c in range(L):
        for row in range(c, min(c + 2, L)):
            for g in range(Lp):
                flux[c, g] += 0.5 * P[row, g]
        for j in (c, c + 1):
            if beta[j, c] == 0.0:
                continue
            for m in range(_slope_rows(j, L, rows, weights)):
                for g in range(Lp):
                    slopes[j - c, c, g] += weights[m] * 0.5 * beta[j, c] * P[rows[m], g]
    lowest, highest = np.full(L, Lp, np.int64), np.full(L, -1, np.int64)
    for c in range(L):
        for g in range(Lp):
            if flux[c, g] != 0.0 or slopes[0, c, g] != 0.0 or slopes[1, c, g] != 0.0:
                lowest[c], highest[c] = min(lowest[c], g), max(highest[c], g)
    return flux, slopes, lowest, highest


@njit(cache=True)
def _accumulate(touched_rows, at_left, at_right, touched, row, left_value, right_value):
    """Add the entries of ``row`` in the left and right columns of a face unknown (a new
    row at ``touched`` if it has none yet); returns the new count of rows."""
    for t in range(touched):
        if touched_rows[t] == row:
            at_left[t] += left_value
            at_right[t] += right_value
            return touched
    touched_rows[touched], at_left[touched], at_right[touched] = row, left_value, right_value
    return touched + 1


@njit(cache=True)
def _store(rows, values, n, row, value):
    """Store the entry ``value`` in ``row`` at ``n`` unless the row takes no part (``row <
    0``); returns the new end."""
    if row < 0:
        return n
    rows[n], values[n] = row, value
    return n + 1


@njit(cache=True)
def _normal_equations(pointer, cells, values, mass, free, row_of, n, v_star, storage):
    """``A = E M^-1 E^T`` in band storage ``band[i, d] = A_i,i+d`` (``n`` rows, the band of
    row ``i`` contiguous; in ``storage`` if it is large enough) and ``r = E V*``, over the
    free unknowns and the rows ``row_of[cell] >= 0`` (module Notes)."""
    width = 0
    for k in range(free.size):
        if not free[k]:
            continue
        lo, hi = n, -1
        for e in range(pointer[k], pointer[k + 1]):
            row = row_of[cells[e]]
            if row >= 0:
                lo, hi = min(lo, row), max(hi, row)
        width = max(width, hi - lo)
    if storage.size < n * (width + 1):
        storage = np.empty(n * (width + 1))
    band = storage[: n * (width + 1)].reshape((n, width + 1))
    band[:] = 0.0
    r = np.zeros(n)
    rows, entries = np.empty(64, np.int64), np.empty(64)
    for k in range(free.size):
        if not free[k]:
            continue
        count = 0  # the entries of unknown k in the rows taking part
        for e in range(pointer[k], pointer[k + 1]):
            row = row_of[cells[e]]
            if row >= 0:
                rows[count], entries[count] = row, values[e]
                count += 1
        inverse = 1.0 / mass[k]
        for e in range(count):
            row = rows[e]
            r[row] += entries[e] * v_star[k]
            scaled = entries[e] * inverse
            for d in range(count):
                if rows[d] >= row:
                    band[row, rows[d] - row] += scaled * entries[d]
    return band, r


@njit(cache=True)
def _fixed_entry(band, fixed, i, d):
    """``A'_i,i+d``: ``A`` with the rows and columns of ``fixed`` replaced by the identity."""
    if i + d >= band.shape[0]:
        return 0.0
    if fixed[i] or fixed[i + d]:
        return 1.0 if d == 0 else 0.0
    return band[i, d]


@njit(cache=True)
def _factor(band, fixed, U, start):
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
    U[start:] = band[start:]
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


@njit(cache=True)
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


@njit(cache=True)
def _substitute(U, b):
    """Solve ``U^T U x = b`` for the factor of ``_factor``."""
    y = np.empty(b.size)
    _forward(U, b, y, 0)
    return _backward(U, y)


@njit(cache=True)
def _forward(U, b, y, start):
    """``y = U^-T b`` column by column, from row ``start`` on: ``y[:start]`` are kept from a
    solve whose ``b[:start]`` and rows ``U[:start - w]`` were the same (their updates of the
    rows from ``start`` are applied first, in the order of a whole solve: the same result,
    bit for bit)."""
    n, w = U.shape[0], U.shape[1] - 1
    y[start:] = b[start:]
    for i in range(max(0, start - w), start):
        for d in range(start - i, min(w, n - 1 - i) + 1):
            y[i + d] -= U[i, d] * y[i]
    for i in range(start, n):
        y[i] /= U[i, 0]
        for d in range(1, min(w, n - 1 - i) + 1):
            y[i + d] -= U[i, d] * y[i]


@njit(cache=True)
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


@njit(cache=True)
def _bounded(band, r, lam_max, active, max_iterations):
    """Minimiser of ``1/2 lam^T A lam - r^T lam`` subject to ``lam <= lam_max`` by primal-dual
    active sets (Hintermueller, Ito & Kunisch 2002) from the guess ``active`` (updated in
    place): on the active set ``lam = lam_max``, elsewhere ``(A lam)_i = r_i``; it stops
    when the set reproduces itself, i.e. the bound multiplier ``mu = r - A lam >= 0`` on
    it and ``lam <= lam_max`` off it.  The guess only changes the work, never the answer.
    Each iteration refactors the Cholesky factor from the first row whose status changed.
    Returns ``lam`` and the iterations (-1: not settled)."""
    n, w = band.shape[0], band.shape[1] - 1
    U = np.empty(band.shape)  # the first factorisation (start 0) writes all of it
    rhs, y = np.empty(n), np.empty(n)
    start = 0
    for iteration in range(1, max_iterations + 1):
        _factor(band, active, U, start)
        # the bounded unknowns move to the right-hand side of the free rows
        rhs[:] = r
        for j in range(n):
            if active[j]:
                rhs[j] = lam_max[j]
                for d in range(1, w + 1):
                    if j + d < n and not active[j + d]:
                        rhs[j + d] -= band[j, d] * lam_max[j]
                    if j - d >= 0 and not active[j - d]:
                        rhs[j - d] -= band[j - d, d] * lam_max[j]
        # rows from start - w on changed (in U and in rhs): the forward solve restarts there
        _forward(U, rhs, y, max(0, start - w))
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


@njit(cache=True)
def _correct(pointer, cells, values, mass, free, row_of, lam, dV):
    """``dV = -M^-1 E^T lam`` on the free unknowns (zero elsewhere), into ``dV``."""
    for k in range(free.size):
        dV[k] = 0.0
        if free[k]:
            s = 0.0
            for e in range(pointer[k], pointer[k + 1]):
                row = row_of[cells[e]]
                if row >= 0:
                    s += values[e] * lam[row]
            dV[k] = -s / mass[k]
    return dV


def correction(
    cons: Constraint,
    moving: np.ndarray,
    u: np.ndarray,
    w: np.ndarray,
    lam_max: np.ndarray | None = None,
    active: np.ndarray | None = None,
    nodes: np.ndarray | None = None,
    offset: int = 0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``V*``, the correction ``dV = -M^-1 E^T lam`` and the free unknowns, over the rows
    and unknowns of the moving cells (all vectors full length).

    ``lam`` minimises ``1/2 lam^T A lam - lam^T E V*`` (``A lam = E V*``), subject to
    ``lam <= lam_max`` (L_p, N) if given: with ``lam_a = -dt q_a`` this is the bound
    ``p >= 0`` on the total pressure, solved by the primal-dual active-set method from the
    guess ``active`` (L_p, N) of the cells where the bound holds (none by default; updated
    in place to the final active set).  With pressure interfaces ``nodes`` (the velocity
    layers of :func:`pressure_nodes`; default every layer) ``E`` is the reduced ``P^T E``
    and its row ``g`` takes part where the layer ``nodes[g]`` moves.  The constraint's
    columns are the columns ``offset ..`` of ``u`` and ``w`` (``moving`` has its N).
    """
    L, N = moving.shape
    layers = np.arange(L) if nodes is None else nodes
    K = cons.mass.size
    free, V_star, row_of, rows = (
        np.empty(K, np.bool_),
        np.empty(K),
        np.empty(layers.size * N, np.int64),
        np.empty(layers.size * N, np.int64),
    )
    n = _unknowns(cons.mass, cons.left, cons.right, moving, u, w, offset, layers, free, V_star, row_of, rows)
    band, r = _normal_equations(
        cons.pointer, cons.cells, cons.values, cons.mass, free, row_of, n, V_star, np.empty(0)
    )
    lam = _multipliers(band, r, rows[:n], lam_max, active)
    dV = np.empty(K)
    _correct(cons.pointer, cons.cells, cons.values, cons.mass, free, row_of, lam, dV)
    return V_star, dV, free


def _multipliers(
    band: np.ndarray, r: np.ndarray, rows: np.ndarray, lam_max: np.ndarray | None, active: np.ndarray | None
) -> np.ndarray:
    """``lam`` of :func:`correction` from ``A`` (band storage) and ``r = E V*`` on the rows
    of the cells ``rows`` (``active`` updated in place)."""
    if lam_max is None:
        U = np.zeros(band.shape)
        _factor(band, np.zeros(r.size, dtype=np.bool_), U, 0)
        return _substitute(U, r)
    guess = np.zeros(rows.size, dtype=np.bool_) if active is None else active.ravel()[rows]
    lam, iterations = _bounded(band, r, lam_max.ravel()[rows], guess, MAX_ACTIVE_SET_ITERATIONS)
    if iterations < 0:
        raise RunError(
            "the non-hydrostatic pressure bound p >= 0 was not settled in "
            f"{MAX_ACTIVE_SET_ITERATIONS} active-set iterations"
        )
    if active is not None:
        active.ravel()[rows] = guess
    return lam


MAX_ACTIVE_SET_ITERATIONS = 100


@njit(cache=True)
def _unknowns(mass, left, right, moving, u, w, offset, nodes, free, V_star, row_of, rows):
    """The free unknowns (faces with a moving side and material, the moving cells' ``wbar``),
    the row of each cell (-1: none; the moving pressure interfaces ``nodes``, column by
    column: ``A`` is then banded, of half-width about ``L_p + 3``), the cells of the rows
    and ``V*``, for the columns ``offset ..`` of ``u`` and ``w`` (see :func:`correction`),
    into ``free``, ``V_star``, ``row_of`` and ``rows``; returns the number of rows."""
    L, N = moving.shape
    F, Lp = left.size, nodes.size
    for c in range(L):
        for f in range(F):
            k = c * F + f
            free[k] = (moving[c, left[f]] or moving[c, right[f]]) and mass[k] > 0.0
            V_star[k] = 0.5 * (u[c, offset + left[f]] + u[c, offset + right[f]])
    for a in range(L):
        for i in range(N):
            k = L * F + a * N + i
            free[k] = moving[a, i]
            V_star[k] = w[a, offset + i] if moving[a, i] else 0.0
    n = 0
    for i in range(N):
        for g in range(Lp):
            row_of[g * N + i] = -1
            if moving[nodes[g], i]:
                row_of[g * N + i] = n
                rows[n] = g * N + i
                n += 1
    return n


class _Buffers:
    """The work arrays of :func:`project_columns` for ``L`` layers, ``N`` columns and ``Lp``
    pressure layers."""

    def __init__(self, L: int, N: int, Lp: int):
        K = 2 * L * N  # the unknowns: at most N faces and N cells per layer
        self.free, self.V_star, self.dV, self.mass = (
            np.empty(K, np.bool_),
            np.empty(K),
            np.empty(K),
            np.empty(K),
        )
        self.pointer = np.empty(K + 1, np.int64)
        self.cells, self.values = np.empty(_capacity(L, N, N, Lp), np.int64), np.empty(_capacity(L, N, N, Lp))
        self.row_of, self.rows, self.own = (
            np.empty(Lp * N, np.int64),
            np.empty(Lp * N, np.int64),
            np.arange(Lp * N),
        )
        # a band of half-width below 2 Lp (the rows of two columns; wider: periodic ends, a new one)
        self.band = np.empty(Lp * N * 2 * Lp)
        self.du = np.empty(L * N)


def project(
    h: np.ndarray,
    u: np.ndarray,
    w: np.ndarray,
    bed: np.ndarray,
    fractions: np.ndarray,
    *,
    dx: float,
    dt: float,
    periodic: bool = False,
    dry: float = 0.0,
    g_n: float | None = None,
    tension_free: np.ndarray | None = None,
    pressure_layers: int | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project the moving cells on the non-hydrostatic constraint (module Notes), with the
    pressure on ``pressure_layers`` groups of layers (default: every layer; module Notes,
    "Fewer pressure layers").

    ``u`` (L, N) are the velocities after the vertical step, ``w`` (L, N) the layer-mean
    vertical velocities before the projection.  Returns the new ``u`` and ``w`` and the
    kinematic pressures ``q`` (L, N) at the bottom interface of each layer (``q`` per unit
    density, m^2/s^2; zero at the free surface).  Cells at rest (``u == 0.0``) or dry keep
    ``u = w = 0``.  With ``g_n = g cos(theta)`` the total pressure
    ``g_n (h - z) + q`` is kept non-negative (granular matter takes no tension); the cells
    ``tension_free`` (L, N) where it was zero the step before (:func:`tension_free`) start
    the active-set iteration (speed only: the answer does not depend on them).
    """
    u_new, w_new, q = u.copy(), np.zeros(w.shape), np.zeros(u.shape)
    project_columns(
        h, u, w, bed, fractions, (u_new, w_new, q), dx=dx, dt=dt, periodic=periodic, dry=dry, g_n=g_n,
        tension_free=tension_free, pressure_layers=pressure_layers,
    )  # fmt: skip
    return u_new, w_new, q


def project_columns(
    h: np.ndarray,
    u: np.ndarray,
    w: np.ndarray,
    bed: np.ndarray,
    fractions: np.ndarray,
    out: tuple[np.ndarray, np.ndarray, np.ndarray],
    *,
    dx: float,
    dt: float,
    periodic: bool = False,
    dry: float = 0.0,
    g_n: float | None = None,
    tension_free: np.ndarray | None = None,
    pressure_layers: int | None = None,
    buffers: _Buffers | None = None,
) -> tuple[int, int]:
    """:func:`project` into ``out`` (u, w, q; L, N), written in the columns ``lo .. hi-1``
    it returns only, those of the moving material and one column at rest on each side (the
    faces beyond join cells at rest and carry no correction; every column if periodic):
    ``out`` must hold ``u`` and zeros elsewhere (the answer there).  ``(0, 0)``: nothing
    moves.
    ``buffers``: the work arrays of the shape of ``u`` and these pressure layers (reused
    from call to call: a new array touched afresh costs a page fault per 4 KiB)."""
    L, N = u.shape
    first, last = _moving_columns(u, h, dry)
    if last < 0:
        return 0, 0
    lo, hi = (0, N) if periodic else (max(first - 1, 0), min(last + 2, N))
    window = slice(lo, hi)
    moving = _moving(u, h, dry, lo, hi)
    nodes, P = _pressure_layers(tuple(fractions), L if pressure_layers is None else pressure_layers)
    lam_max = active = None
    if g_n is not None:
        # the bound at the pressure interfaces holds on every interface: both sides are
        # linear in sigma between them
        lam_max = dt * g_n * (_depth_factors(fractions)[nodes, None] * h[window])
        active = np.zeros(lam_max.shape, np.bool_) if tension_free is None else tension_free[nodes, window]
    # the constraint of the free unknowns in the rows taking part only (``correction`` on
    # ``constraint``, without the rest), in arrays reused from call to call
    buffers = _Buffers(L, N, nodes.size) if buffers is None else buffers
    thickness = np.where(h[window] > dry, h[window], 0.0)
    left, right = faces(hi - lo, periodic)
    face_mass = (fractions[:, None] * 0.5 * (thickness[left] + thickness[right])).ravel()
    K = L * left.size + L * (hi - lo)
    free, V_star, dV, mass = buffers.free[:K], buffers.V_star[:K], buffers.dV[:K], buffers.mass[:K]
    row_of = buffers.row_of[: nodes.size * (hi - lo)]
    n = _unknowns(face_mass, left, right, moving, u, w, lo, nodes, free, V_star, row_of, buffers.rows)
    pointer, entry_rows, values = buffers.pointer[: K + 1], buffers.cells, buffers.values
    _entries(
        thickness, bed[window], fractions, dx, left, right, P, free, row_of, pointer, entry_rows, values, mass
    )
    own = buffers.own[:n]  # the entries are in rows already
    band, r = _normal_equations(pointer, entry_rows, values, mass, free, own, n, V_star, buffers.band)
    lam = _multipliers(band, r, buffers.rows[:n], lam_max, active)
    _correct(pointer, entry_rows, values, mass, free, own, lam, dV)
    _finish(dV, u, w, h, fractions, moving, left, right, dt, lo, buffers.du, *out)
    return lo, hi


@njit(cache=True)
def _moving(u, h, dry, lo, hi):
    """The cells (L, hi - lo) of the columns ``lo .. hi-1`` that take part: ``u != 0`` where
    ``h > dry``."""
    moving = np.empty((u.shape[0], hi - lo), np.bool_)
    for a in range(u.shape[0]):
        for i in range(lo, hi):
            moving[a, i - lo] = u[a, i] != 0.0 and h[i] > dry
    return moving


@njit(cache=True)
def _finish(dV, u, w, h, fractions, moving, left, right, dt, lo, storage, u_out, w_out, q_out):
    """The projected ``u`` (each column the mean of the corrections of its two faces), ``w``
    and the pressures ``q_a = sum_{b >= a} h_b dw_b / dt`` of the columns ``lo ..`` (as many
    as ``moving`` has) into ``u_out``, ``w_out`` and ``q_out`` (module Notes); ``storage``
    holds the changes of ``u`` (at least L N long)."""
    L, N = moving.shape
    F = left.size
    du = storage[: L * N].reshape((L, N))
    du[:] = 0.0
    for c in range(L):
        for f in range(F):
            half = 0.5 * dV[c * F + f]
            du[c, left[f]] += half  # each column is the left of one face at most, and the right of one
            du[c, right[f]] += half
    for a in range(L):
        for i in range(N):
            if moving[a, i]:
                u_out[a, lo + i] = u[a, lo + i] + du[a, i]
                w_out[a, lo + i] = w[a, lo + i] + dV[L * F + a * N + i]
            else:
                u_out[a, lo + i] = u[a, lo + i]
                w_out[a, lo + i] = 0.0
    for i in range(N):
        total = 0.0
        for a in range(L - 1, -1, -1):
            total += fractions[a] * h[lo + i] * dV[L * F + a * N + i]
            q_out[a, lo + i] = total / dt


@njit(cache=True)
def _moving_columns(u, h, dry):
    """The first and the last column with a moving cell (``u != 0`` where ``h > dry``);
    ``(-1, -1)`` if none."""
    first = last = -1
    for i in range(h.size):
        if h[i] > dry:
            for a in range(u.shape[0]):
                if u[a, i] != 0.0:
                    if first < 0:
                        first = i
                    last = i
                    break
    return first, last


@njit(cache=True)
def _advect(w, u, dx, dt, periodic, lo, hi, out):
    """First-order upwind transport of the layer vertical velocities by the layer
    velocities, ``d_t w + u d_x w = 0`` (zero-gradient ends unless periodic), into the
    columns ``lo .. hi-1`` of ``out``."""
    L, N = w.shape
    ratio = dt / dx
    for a in range(L):
        for i in range(lo, hi):
            here, speed = w[a, i], u[a, i]
            if speed > 0.0:
                west = w[a, i - 1] if i > 0 else (w[a, N - 1] if periodic else here)
                out[a, i] = here - ratio * (speed * (here - west))
            elif speed < 0.0:
                east = w[a, i + 1] if i < N - 1 else (w[a, 0] if periodic else here)
                out[a, i] = here - ratio * (speed * (east - here))
            else:
                out[a, i] = here


def depth_below(h: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Depth ``h - z_a`` (L, N) of the bottom interface of each layer below the surface."""
    return _depth_factors(fractions)[:, None] * h


def _depth_factors(fractions: np.ndarray) -> np.ndarray:
    """``(h - z_a) / h`` of the bottom interface of each layer."""
    return 1.0 - np.concatenate([[0.0], np.cumsum(fractions)[:-1]])


def tension_free(
    q: np.ndarray, h: np.ndarray, fractions: np.ndarray, g_n: float, columns: tuple[int, int] | None = None
) -> np.ndarray:
    """Interfaces (L, N) where the total pressure ``g_n (h - z) + q`` of a projection is
    zero (to round-off: the bound ``p >= 0`` was active there), ``h`` being the thickness
    the pressures ``q`` were computed with; ``columns`` (lo, hi): ``q`` is zero outside
    the columns ``lo .. hi-1`` (where none is, for ``g_n > 0``)."""
    lo, hi = (0, q.shape[1]) if columns is None else columns
    out = np.zeros(q.shape, np.bool_)
    _tension_free(q, h, _depth_factors(fractions), g_n, lo, hi, out)
    return out


@njit(cache=True)
def _tension_free(q, h, factors, g_n, lo, hi, out):
    for a in range(q.shape[0]):
        for i in range(lo, hi):
            depth = factors[a] * h[i]
            out[a, i] = depth > 0.0 and g_n * depth + q[a, i] <= 1e-9 * g_n * depth


@njit(cache=True)
def _yield_gravity(q, h, factors, g_n, lo, hi, out):
    """Normal gravity ``G_k`` of the interface pressures with the non-hydrostatic part,
    ``rho G_k (h - z_k) = rho g cos(theta) (h - z_k) + rho q_k``, never negative, into the
    columns ``lo .. hi-1`` of ``out`` (``factors``: :func:`_depth_factors`)."""
    for a in range(q.shape[0]):
        for i in range(lo, hi):
            depth = factors[a] * h[i]
            out[a, i] = max(g_n + (q[a, i] / depth if depth > 0.0 else 0.0), 0.0)


class Projection:
    """The non-hydrostatic part of a simulation's step (``w`` advected by the vertical
    step's velocities, then :func:`project_columns`) and the normal gravity of the yield
    stresses, into arrays (L, N) reused from step to step: every
    array is written in the columns holding material only (the rest kept zero, or
    ``g cos(theta)``), so a step's cost follows the material, not the domain."""

    def __init__(
        self,
        fractions: np.ndarray,
        bed: np.ndarray,
        *,
        dx: float,
        periodic: bool,
        dry: float,
        g_n: float,
        pressure_layers: int | None,
    ):
        self.fractions, self.bed = fractions, bed
        self.dx, self.periodic, self.dry, self.g_n = dx, periodic, dry, g_n
        self.pressure_layers = pressure_layers
        shape = (fractions.size, bed.size)
        self.u, self.w, self.q = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        self._w_star = np.zeros(shape)  # read at the moving cells only
        self._buffers = _Buffers(
            *shape, _pressure_layers(tuple(fractions), pressure_layers or shape[0])[0].size
        )
        self._gravity = np.full(shape, max(g_n, 0.0))
        self._written = (0, 0)  # the columns of u, w, q written by the last call
        self._gravity_written = (0, 0)

    def __call__(
        self,
        h: np.ndarray,
        u: np.ndarray,
        w: np.ndarray,
        q: np.ndarray,
        h_before: np.ndarray,
        dt: float,
        columns: tuple[int, int],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The projected ``u``, ``w`` and the pressures ``q`` (overwritten by the next call)
        of the vertical step's velocities ``u`` on the thickness ``h``, from the state's
        ``w`` and ``q`` (on ``h_before``; both zero outside the columns ``columns``).  ``u``
        is zero outside the columns holding material (the vertical step zeroes them)."""
        lo, hi = span(h)
        start, stop = self._written
        self.u[:, start:stop] = 0.0
        self.w[:, start:stop] = 0.0
        self.q[:, start:stop] = 0.0
        self.u[:, lo:hi] = u[:, lo:hi]
        # only the moving cells take part, in the columns holding material
        _advect(w, u, self.dx, dt, self.periodic, lo, hi, self._w_star)
        first, last = project_columns(
            h, u, self._w_star, self.bed, self.fractions, (self.u, self.w, self.q), dx=self.dx, dt=dt,
            periodic=self.periodic, dry=self.dry, g_n=self.g_n,
            tension_free=tension_free(q, h_before, self.fractions, self.g_n, columns),
            pressure_layers=self.pressure_layers, buffers=self._buffers,
        )  # fmt: skip
        self._written = (min(lo, first), max(hi, last)) if last > first else (lo, hi)
        return self.u, self.w, self.q

    def yield_gravity(self, q: np.ndarray, h: np.ndarray, columns: tuple[int, int]) -> np.ndarray:
        """Normal gravity ``G_k`` (L, N) of the interface pressures with the non-hydrostatic
        part of ``q`` (zero outside the columns ``columns``) on the thickness ``h``,
        ``rho G_k (h - z_k) = rho g cos(theta) (h - z_k) + rho q_k``, never negative
        (overwritten by the next call)."""
        start, stop = self._gravity_written
        self._gravity[:, start:stop] = max(self.g_n, 0.0)
        lo, hi = columns
        _yield_gravity(q, h, _depth_factors(self.fractions), self.g_n, lo, hi, self._gravity)
        self._gravity_written = columns
        return self._gravity
