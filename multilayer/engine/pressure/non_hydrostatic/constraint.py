"""The constraint of the non-hydrostatic projection, assembled column by column.

The rows ``E`` (or, with fewer pressure layers, ``P^T E``) of the layer divergence
constraint of Fernandez-Nieto, Parisot, Penel & Sainte-Marie (2018) in the Keller-box
form of Stelling & Zijlema (2003), for the unknowns ``V`` (the face velocities of each
layer and the layer means ``wbar``), their masses ``M``, and the normal equations
``A = E M^-1 E^T`` in band storage with ``r = E V*`` over the moving cells (the Notes of
:mod:`multilayer.engine.pressure.non_hydrostatic.projection` state the rows).  The
pressure interfaces of ``pressure_layers < L`` groups and their interpolation ``P`` are
here too.  Compiled by numba.

Notes
-----
A face unknown ``v_c,f`` (layer ``c``, the columns ``i`` on the left and ``e`` on the right,
the mass ``fr_c m`` with ``m = (h_i + h_e) / 2``) has in the pressure row ``g`` of its
columns the entries::

    (P^T E)_(i,g),(c,f) =  fr_c m / dx flux_c,g + D B_c,g + H C_c,g,
    (P^T E)_(e,g),(c,f) = -fr_c m / dx flux_c,g + D B_c,g + H C_c,g,

``D = (b_e - b_i) / dx`` and ``H = (h_e - h_i) / dx`` the slopes of the bed and of the
thickness, ``flux``, ``B`` and ``C`` numbers of the layering alone
(:func:`_face_coefficients`).  Its term of ``A = E M^-1 E^T`` between the rows ``(x, g)``
and ``(y, g')`` (``x, y`` in ``{i, e}``, with the signs ``s_x, s_y`` above) is::

    s_x s_y fr_c flux_c,g flux_c,g' m / dx^2
      + (s_x flux_c,g B_c,g' + s_y flux_c,g' B_c,g) D / dx
      + (s_x flux_c,g C_c,g' + s_y flux_c,g' C_c,g) H / dx
      + (B_c,g B_c,g' D^2 + (B_c,g C_c,g' + C_c,g B_c,g') D H + C_c,g C_c,g' H^2) / (fr_c m),

a quadratic form in ``(m / dx^2, D / dx, H / dx, D^2 / m, D H / m, H^2 / m)``.  With fewer
pressure layers (``L_p < L``), where the L unknowns of a face are all free and each of its
columns has all its pressure rows or none, the face's block of ``A`` is that form with its
six coefficients summed over the layers once per assembly (:func:`_layer_sums`, O(L)
operations): six products per pair of its ``2 L_p`` rows, against the products of the
entries of its L unknowns.  Likewise ``wbar_a`` has the entries ``P_a,g - P_a+1,g`` and
the mass ``fr_a h``, so a column whose L ``wbar`` are free adds ``1 / h`` times sums over
the layers.  The same ``A`` to round-off; ``r = E V*`` is added entry by entry either way
(the same bits).  With a pressure on every layer a face's unknowns have about as many
products as its rows have pairs, and nothing is summed.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from multilayer.engine.compiled import jit


@dataclass
class Constraint:
    """The columns of the constraint matrix ``E``, unknown by unknown (module Notes).

    Unknowns: the face velocities ``a * F + f`` then the ``wbar`` at ``L * F + a * N + i``;
    unknown ``k`` has the entries ``values[pointer[k]:pointer[k + 1]]`` in the rows (cells
    ``a * N + i``) ``cells[pointer[k]:pointer[k + 1]]``.  ``mass`` are the masses ``M``,
    ``left`` and ``right`` the columns of the faces; ``geometry`` the arguments of
    :func:`entries` that made it, up to ``P``."""

    pointer: np.ndarray
    cells: np.ndarray
    values: np.ndarray
    mass: np.ndarray
    left: np.ndarray
    right: np.ndarray
    shape: tuple[int, int]
    geometry: tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray, np.ndarray, np.ndarray]

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
        np.empty(capacity(L, N, left.size, Lp), np.int64),
        np.empty(capacity(L, N, left.size, Lp)),
    )
    geometry = (
        np.asarray(h, dtype=float), np.asarray(bed, dtype=float), np.asarray(fractions, dtype=float),
        float(dx), left, right, P,
    )  # fmt: skip
    no_band = (np.empty(0), np.empty((0, 1)), np.empty(0))
    n = entries(*geometry, np.ones(K, np.bool_), np.arange(Lp * N), pointer, cells, values, mass, *no_band)[0]
    cells, values = cells[:n], values[:n]
    shape = (P.shape[1] * N, L * left.size + L * N)
    return Constraint(pointer, cells, values, mass, left, right, shape, geometry)


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
def layering(fractions: tuple[float, ...], pressure_layers: int) -> tuple[np.ndarray, np.ndarray]:
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


@jit
def entries(
    h, bed, fractions, dx, left, right, P, free, row_of, pointer, cells, values, mass, v_star, band, r
):
    """``P^T E`` column by column (see :class:`Constraint`) for the unknowns ``free`` (the
    others have no entries) in the rows ``row_of[cell] >= 0`` (the entries in the others
    are left out): each entry is stored with its row ``row_of[cell]``.  In ``E``, ``F_c``
    enters the rows ``c`` and ``c + 1`` with 1/2; ``S_j`` (interface ``j``, its velocity
    ``vhat_j = beta_j,c-1 v_c-1 + beta_j,c v_c`` weighted by the thicknesses) enters row 0
    with -1/2 (``j`` = 0, 1), row ``j - 1`` with -1/2 (``j >= 2``) and row ``j + 1`` with
    +1/2; ``wbar_a`` enters row ``a`` with +1 and row ``a + 1`` with -1.  Each entry of row
    ``a`` goes to the pressure rows ``g`` with ``P_a,g != 0``, times ``P_a,g`` (the
    identity: ``E`` itself).  Written into ``pointer``, ``cells`` (the rows), ``values``
    (at least :func:`capacity` long) and ``mass`` (``M``, of every unknown).  With a
    ``band`` of rows (not empty), the terms of each free unknown are added, unknown by
    unknown once all are stored, to ``A = E M^-1 E^T`` (band storage ``band[i, d] =
    A_i,i+d``, of a half-width large enough) and to ``r = E V*`` (module Notes), except
    that the terms of the faces and columns whose L unknowns are all free (:func:`_whole`),
    with ``L_p < L``, are added from sums over the layers (module Notes;
    :func:`_layer_sums`, :func:`_add_sums`: the same ``A`` to round-off); with an empty
    band and an ``r`` of the rows, to ``r`` only (an empty ``r``: nothing added up).
    Returns the number of entries and the half-width of ``A`` (the largest spread of the
    rows of an unknown)."""
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
    seen, at_left, at_right = np.empty(L, np.int64), np.empty(L), np.empty(L)
    n = width = np.int64(0)  # not literal 0s: numba would also compile the callees for them
    if Lp < L:
        # fewer pressure rows: the entries of a face unknown of layer c are, per pressure row
        # g, h_face / dx times those of its F rows plus the slopes times those of its S rows;
        # those of the wbar of a column with all its rows (base >= 0 below), a template
        flux, slopes, lowest, highest = _face_coefficients(P, beta, L)
        count, template, weight = _column_template(P, first, targets)
    # with a band and fewer pressure rows: the faces and columns whose every unknown is free,
    # with all rows or none in each of their columns; their terms of A, summed over the layers
    # (module Notes), are added after the loop
    whole_face, whole_column, base = _whole(free, row_of, left, right, L, Lp, band.shape[0] > 0)
    # the hot indices are unsigned integers (np.uint64): numba then leaves out the wrap-around
    # of negative indices, a third of the instructions of these loops
    flat, stride = band.reshape(band.size), np.uint64(band.shape[1])  # band[i, d] = flat[i * stride + d]
    unsigned_N = np.uint64(N)
    # first the entries of every unknown, the faces' then the columns' (k = c F + f, then
    # L F + a N + i), then their terms of A and r unknown by unknown: the same sums, in the
    # same order, as adding each unknown's terms as it is stored, in three short loops where
    # numba keeps the values of each in registers (one loop of all was a third longer)
    for c in range(L):
        for f in range(F):
            k = c * F + f
            pointer[k] = n
            i, e = np.uint64(left[f]), np.uint64(right[f])
            h_face = fractions[c] * 0.5 * (h[i] + h[e])
            mass[k] = h_face
            if not free[k]:
                continue
            # every entry of a face unknown is in a cell of its own (i != e)
            if Lp < L:
                s0 = ((bed[e] + sigma[c] * h[e]) - (bed[i] + sigma[c] * h[i])) / dx
                s1 = ((bed[e] + sigma[c + 1] * h[e]) - (bed[i] + sigma[c + 1] * h[i])) / dx
                ratio = h_face / dx
                layer = np.uint64(c)
                for g in range(np.uint64(lowest[c]), np.uint64(highest[c] + 1)):
                    a0, a1, fc = slopes[0, layer, g], slopes[1, layer, g], flux[layer, g]
                    sloped = s0 * a0 + s1 * a1
                    n = _store(cells, values, n, row_of[g * unsigned_N + i], ratio * fc + sloped)
                    n = _store(cells, values, n, row_of[g * unsigned_N + e], sloped - ratio * fc)
            else:
                touched = np.int64(0)  # the rows of E this unknown enters, in the order they first come
                for row in range(c, min(c + 2, L)):
                    flux_left, flux_right = 0.5 * h_face / dx, -0.5 * h_face / dx
                    touched = _accumulate(seen, at_left, at_right, touched, row, flux_left, flux_right)
                for j in (c, c + 1):
                    if beta[j, c] == 0.0:
                        continue
                    slope = ((bed[e] + sigma[j] * h[e]) - (bed[i] + sigma[j] * h[i])) / dx
                    for m in range(_slope_rows(j, L, rows, weights)):
                        value = weights[m] * 0.5 * beta[j, c] * slope
                        touched = _accumulate(seen, at_left, at_right, touched, rows[m], value, value)
                for t in range(touched):
                    n = _store(cells, values, n, row_of[seen[t] * N + i], at_left[t])
                    n = _store(cells, values, n, row_of[seen[t] * N + e], at_right[t])
    for a in range(L):
        for column in range(N):
            k = L * F + a * N + column
            pointer[k] = n
            i = np.uint64(column)
            mass[k] = fractions[a] * h[i]
            if not free[k]:
                continue
            if base[i] >= 0:  # all rows of the column: the entries of the template
                for t in range(np.uint64(count[a])):
                    cells[np.uint64(n)], values[np.uint64(n)] = base[i] + template[a, t], weight[a, t]
                    n += 1
            else:
                for g in range(first[a], first[a] + targets[a]):
                    n = _store(cells, values, n, row_of[np.uint64(g) * unsigned_N + i], P[a, g])
                if a + 1 < L:
                    for g in range(first[a + 1], first[a + 1] + targets[a + 1]):
                        row = row_of[np.uint64(g) * unsigned_N + i]
                        if row < 0:
                            continue
                        for m in range(pointer[k], n):  # the same row as one of wbar_a's: added
                            if cells[m] == row:
                                values[m] += -P[a + 1, g]
                                break
                        else:
                            n = _store(cells, values, n, row, -P[a + 1, g])
    pointer[L * F + L * N] = n
    banded = band.shape[0] > 0
    f = column = 0  # the face or column of the unknown k
    for k in range(L * F + L * N):
        if k < L * F:
            summed = whole_face.size > 0 and whole_face[f]
            f = f + 1 if f + 1 < F else 0
        else:
            summed = whole_column.size > 0 and whole_column[column]
            column = column + 1 if column + 1 < N else 0
        if not free[k]:
            continue
        begin, end = np.uint64(pointer[k]), np.uint64(pointer[k + 1])
        if banded and not summed:
            # the terms of unknown k, each pair of its (distinct) rows once
            inverse, lo, hi = 1.0 / mass[k], band.shape[0], -1
            v = v_star[k]
            for p in range(begin, end):
                row, value = np.uint64(cells[p]), values[p]
                lo, hi = min(lo, np.int64(row)), max(hi, np.int64(row))
                r[row] += value * v
                scaled = value * inverse
                at = row * stride
                flat[at] += scaled * value
                for q in range(p + np.uint64(1), end):
                    other = np.uint64(cells[q])
                    if other > row:
                        flat[at + (other - row)] += scaled * values[q]
                    else:
                        flat[other * stride + (row - other)] += (values[q] * inverse) * value
            width = max(width, hi - lo)
        elif r.size > 0:  # r = E V* only (or its terms of A are summed)
            _add_column(cells, values, begin, end, v_star[k], r)
    if whole_face.size + whole_column.size > 0:  # (no faces in a single column)
        sums = _layer_sums(flux, slopes, lowest, highest, sigma, fractions, P, first, targets)
        width = max(width, _add_sums(h, bed, dx, left, right, whole_face, whole_column, base, *sums, band))
    return n, width


@jit
def _whole(free, row_of, left, right, L, Lp, wanted):
    """With fewer pressure rows than layers (``Lp < L``): the faces whose L unknowns are
    all free, each of their columns with all its pressure rows or none (not both none), and
    the columns whose L ``wbar`` are free with all their rows (empty arrays unless
    ``wanted``); and the first row of each column whose rows are all there and consecutive,
    -1 for the others (all -1 with ``Lp == L``)."""
    N, F = row_of.size // Lp, left.size
    if Lp == L:
        return np.zeros(0, np.bool_), np.zeros(0, np.bool_), np.full(N, -1, np.int64)
    base, present = np.empty(N, np.int64), np.zeros(N, np.int64)
    for g in range(Lp):
        for i in range(N):
            if row_of[g * N + i] >= 0:
                present[i] += 1
    for i in range(N):
        base[i] = row_of[i] if present[i] == Lp else -1
        for g in range(1, Lp):  # rows numbered column by column (unknowns) are consecutive
            if base[i] >= 0 and row_of[g * N + i] != base[i] + g:
                base[i] = -1
    if not wanted:
        return np.zeros(0, np.bool_), np.zeros(0, np.bool_), base
    whole_face, whole_column = np.empty(F, np.bool_), np.empty(N, np.bool_)
    for f in range(F):
        i, e = left[f], right[f]
        whole = (base[i] >= 0 or present[i] == 0) and (base[e] >= 0 or present[e] == 0)
        whole = whole and present[i] + present[e] > 0
        for c in range(L):
            whole = whole and free[c * F + f]
        whole_face[f] = whole
    for i in range(N):
        whole = base[i] >= 0
        for a in range(L):
            whole = whole and free[L * F + a * N + i]
        whole_column[i] = whole
    return whole_face, whole_column, base


@jit
def _column_template(P, first, targets):
    """The entries of ``wbar_a`` in a column with all its pressure rows, in the order and
    with the values :func:`entries` gives them otherwise: ``count[a]`` entries, in the rows
    ``template[a, t]`` past the column's first, of values ``weight[a, t]`` (``P_a,g``, then
    ``-P_a+1,g`` added to the same row or a new one)."""
    L, Lp = P.shape
    count, template, weight = np.zeros(L, np.int64), np.zeros((L, 2 * Lp), np.int64), np.zeros((L, 2 * Lp))
    for a in range(L):
        for g in range(first[a], first[a] + targets[a]):
            template[a, count[a]], weight[a, count[a]] = g, P[a, g]
            count[a] += 1
        if a + 1 < L:
            for g in range(first[a + 1], first[a + 1] + targets[a + 1]):
                for m in range(count[a]):
                    if template[a, m] == g:
                        weight[a, m] += -P[a + 1, g]
                        break
                else:
                    template[a, count[a]], weight[a, count[a]] = g, -P[a + 1, g]
                    count[a] += 1
    return count, template, weight


@jit
def _layer_sums(flux, slopes, lowest, highest, sigma, fractions, P, first, targets):
    """The six coefficients of the faces' terms of ``A = E M^-1 E^T`` and the column sums
    of the ``wbar``, summed over the layers (module Notes; :func:`_add_sums` adds them).

    ``face_pairs`` (g, g') and ``face_sums`` where the coefficients are not all zero, for
    the blocks (left, left) and (right, right) (``g <= g'``) and (left, right): those of
    block ``b`` at ``blocks[b] .. blocks[b + 1] - 1``; ``column_pairs`` (g, g' - g >= 0) and
    ``column_sums``, per unit ``1 / h``; the spread of the rows of one column that a face
    unknown and a ``wbar`` have at most.  Each layer adds only to the pairs of its rows
    ``lowest .. highest`` (the others' terms are zero)."""
    L, Lp = P.shape
    dense = np.zeros((3, Lp, Lp, 6))
    B, C = np.zeros(Lp), np.zeros(Lp)
    reach = 0
    for c in range(L):
        low, high = lowest[c], highest[c] + 1
        reach = max(reach, high - 1 - low)
        weight = 1.0 / fractions[c]
        for g in range(low, high):
            B[g] = slopes[0, c, g] + slopes[1, c, g]
            C[g] = sigma[c] * slopes[0, c, g] + sigma[c + 1] * slopes[1, c, g]
        for block in range(3):
            sign_x, sign_y = (1.0, 1.0) if block == 0 else ((-1.0, -1.0) if block == 1 else (1.0, -1.0))
            for g in range(low, high):
                for k in range(g if block < 2 else low, high):
                    fg, fk = flux[c, g], flux[c, k]
                    sums = dense[block, g, k]
                    sums[0] += sign_x * sign_y * fractions[c] * fg * fk
                    sums[1] += sign_x * fg * B[k] + sign_y * fk * B[g]
                    sums[2] += sign_x * fg * C[k] + sign_y * fk * C[g]
                    sums[3] += B[g] * B[k] * weight
                    sums[4] += (B[g] * C[k] + C[g] * B[k]) * weight
                    sums[5] += C[g] * C[k] * weight
    face_pairs, face_sums = np.empty((3 * Lp * Lp, 2), np.int64), np.empty((3 * Lp * Lp, 6))
    blocks = np.zeros(4, np.int64)
    for block in range(3):
        blocks[block + 1] = blocks[block]
        for g in range(Lp):
            for k in range(g if block < 2 else 0, Lp):
                if _any(dense[block, g, k]):
                    face_pairs[blocks[block + 1], 0], face_pairs[blocks[block + 1], 1] = g, k
                    face_sums[blocks[block + 1]] = dense[block, g, k]
                    blocks[block + 1] += 1
    column = np.zeros((Lp, Lp))
    drop = np.zeros(Lp)  # P_a,g - P_a+1,g where a's or a+1's entries are
    column_reach = 0
    for a in range(L):
        low, high = first[a], first[a] + targets[a]
        if a + 1 < L:
            low, high = min(low, first[a + 1]), max(high, first[a + 1] + targets[a + 1])
        column_reach = max(column_reach, high - 1 - low)
        for g in range(low, high):
            drop[g] = P[a, g] - (P[a + 1, g] if a + 1 < L else 0.0)
        for g in range(low, high):
            for k in range(g, high):
                column[g, k] += drop[g] * drop[k] / fractions[a]
    column_pairs, column_sums = np.empty((Lp * Lp, 2), np.int64), np.empty(Lp * Lp)
    kept = 0
    for g in range(Lp):
        for k in range(g, Lp):
            if column[g, k] != 0.0:
                column_pairs[kept, 0], column_pairs[kept, 1], column_sums[kept] = g, k - g, column[g, k]
                kept += 1
    return face_pairs, face_sums, blocks, column_pairs[:kept], column_sums[:kept], reach, column_reach


@jit
def _add_sums(
    h, bed, dx, left, right, whole_face, whole_column, base, face_pairs, face_sums, blocks, column_pairs,
    column_sums, reach, column_reach, band,
):  # fmt: skip
    """Add the terms of ``A`` of the faces ``whole_face`` and the columns ``whole_column``
    (:func:`_whole`) to ``band`` from the sums of :func:`_layer_sums`; returns the spread of
    the rows of their unknowns (the half-width they need)."""
    flat, stride = band.reshape(band.size), np.uint64(band.shape[1])
    width = -1
    for f in range(left.size):
        if not whole_face[f]:
            continue
        i, e = left[f], right[f]
        m = 0.5 * (h[i] + h[e])
        slope, spread = (bed[e] - bed[i]) / dx, (h[e] - h[i]) / dx
        t0, t1, t2 = m / (dx * dx), slope / dx, spread / dx
        t3, t4, t5 = slope * slope / m, slope * spread / m, spread * spread / m
        x, y = base[i], base[e]
        width = max(width, reach + (abs(y - x) if x >= 0 and y >= 0 else 0))
        for block in range(3):  # the first rows of the pairs' columns: (x, x), (y, y), (x, y)
            one, two = (x, x) if block == 0 else ((y, y) if block == 1 else (x, y))
            if one < 0 or two < 0:
                continue
            for p in range(np.uint64(blocks[block]), np.uint64(blocks[block + 1])):
                value = face_sums[p, 0] * t0 + face_sums[p, 1] * t1 + face_sums[p, 2] * t2
                value += face_sums[p, 3] * t3 + face_sums[p, 4] * t4 + face_sums[p, 5] * t5
                row, other = one + face_pairs[p, 0], two + face_pairs[p, 1]
                if other < row:  # band storage from the lower row
                    row, other = other, row
                flat[np.uint64(row) * stride + np.uint64(other - row)] += value
    for i in range(whole_column.size):
        if not whole_column[i]:
            continue
        inverse, x = 1.0 / h[i], base[i]
        width = max(width, column_reach)
        for p in range(np.uint64(column_pairs.shape[0])):
            at = np.uint64(x + column_pairs[p, 0]) * stride + np.uint64(column_pairs[p, 1])
            flat[at] += column_sums[p] * inverse
    return width


@jit
def _any(values):
    """Whether any of ``values`` is not zero (``np.any`` would allocate the comparison)."""
    for value in values:
        if value != 0.0:
            return True
    return False


@jit
def product(pointer, cells, values, free, v, r):
    """``r += E v`` of the constraint stored by :func:`entries` (``cells``: rows), over the
    free unknowns, added in the order of the r-only mode of :func:`entries` (so to the
    same bits)."""
    for k in range(free.size):
        if free[k]:
            _add_column(cells, values, pointer[k], pointer[k + 1], v[k], r)


@jit
def _add_column(cells, values, begin, end, v, r):
    """``r += v`` times the entries ``begin .. end-1`` (in their rows ``cells``)."""
    for p in range(np.uint64(begin), np.uint64(end)):
        r[np.uint64(cells[p])] += values[p] * v


def capacity(L: int, N: int, F: int, Lp: int) -> int:
    """Entries of :func:`entries` at most: the rows 0, c - 1, ..., c + 2 of ``E`` for a face
    unknown of layer c, and a, a + 1 for ``wbar_a``, each going to the pressure rows it has
    (1 or 2), in both columns of a face."""
    return 2 * min(Lp, 10) * L * F + min(Lp, 4) * L * N


@jit
def _slope_rows(j, L, rows, weights):
    """The rows of ``E`` that the slope flux ``S_j`` enters and their weights (see
    :func:`entries`); returns their count."""
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


@jit
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


@jit
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


@jit
def _store(rows, values, n, row, value):
    """Store the entry ``value`` in ``row`` at ``n`` unless the row takes no part (``row <
    0``); returns the new end."""
    if row < 0:
        return n
    rows[np.uint64(n)], values[np.uint64(n)] = row, value
    return n + 1


@jit
def unknowns(mass, left, right, moving, u, w, offset, nodes, free, V_star, row_of, rows, structure):
    """The free unknowns (faces with a moving side and material, the moving cells' ``wbar``),
    the row of each cell (-1: none; the moving pressure interfaces ``nodes``, column by
    column: ``A`` is then banded, of half-width about ``L_p + 3``), the cells of the rows
    and ``V*``, for the columns ``offset ..`` of ``u`` and ``w`` (see :func:`correction`),
    into ``free``, ``V_star``, ``row_of`` and ``rows``; returns the number of rows (without
    ``structure``, 0: the rows those a call with the same ``moving`` made, not made again)."""
    L, N = moving.shape
    F, Lp = left.size, nodes.size
    for c in range(L):
        for f in range(F):
            k = c * F + f
            i, e = np.uint64(left[f]), np.uint64(right[f])  # unsigned: no wrap-around (see entries)
            free[k] = (moving[c, i] or moving[c, e]) and mass[k] > 0.0
            V_star[k] = 0.5 * (u[c, np.uint64(offset) + i] + u[c, np.uint64(offset) + e])
    for a in range(L):
        for i in range(N):
            k = L * F + a * N + i
            free[k] = moving[a, i]
            V_star[k] = w[a, np.uint64(offset + i)] if moving[a, i] else 0.0
    n = 0
    for i in range(N if structure else 0):
        for g in range(Lp):
            row_of[g * N + i] = -1
            if moving[nodes[g], i]:
                row_of[g * N + i] = n
                rows[n] = g * N + i
                n += 1
    return n


def normal_equations(
    h: np.ndarray,
    bed: np.ndarray,
    fractions: np.ndarray,
    dx: float,
    left: np.ndarray,
    right: np.ndarray,
    P: np.ndarray,
    free: np.ndarray,
    row_of: np.ndarray,
    n: int,
    v_star: np.ndarray,
    storage: np.ndarray,
    arrays: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """``A = E M^-1 E^T`` in band storage ``band[i, d] = A_i,i+d`` (``n`` rows, the band of
    row ``i`` contiguous; in ``storage`` if it is large enough) and ``r = E V*``, over the
    free unknowns and the rows ``row_of[cell] >= 0`` (module Notes), added up by
    :func:`entries` (its arguments up to ``row_of``) as it stores the constraint in
    ``arrays`` (``pointer``, ``cells``, ``values``, ``mass``; the cells are the rows)."""
    bound = _band_bound(row_of, left, right, h.size, P.shape[1])
    if storage.size < n * (bound + 1):
        storage = np.empty(n * (bound + 1))
    wide = storage[: n * (bound + 1)].reshape((n, bound + 1))
    wide[:] = 0.0
    r = np.zeros(n)
    _, width = entries(h, bed, fractions, dx, left, right, P, free, row_of, *arrays, v_star, wide, r)
    return _narrow(storage, n, bound, width), r


@jit
def _band_bound(row_of, left, right, N, Lp):
    """The half-width of the band at most: the spread of the rows of a column, or of the
    two columns of a face."""
    lowest, highest = np.full(N, Lp * N, np.int64), np.full(N, -1, np.int64)
    for g in range(Lp):
        for i in range(N):
            row = row_of[g * N + i]
            if row >= 0:
                lowest[i], highest[i] = min(lowest[i], row), max(highest[i], row)
    bound = 0
    for i in range(N):
        if highest[i] >= 0:
            bound = max(bound, highest[i] - lowest[i])
    for f in range(left.size):
        i, e = left[f], right[f]
        if highest[i] >= 0 and highest[e] >= 0:
            bound = max(bound, max(highest[i], highest[e]) - min(lowest[i], lowest[e]))
    return bound


@jit
def _narrow(storage, n, bound, width):
    """The band of ``n`` rows stored with the half-width ``bound`` in ``storage``, moved in
    place to the half-width ``width <= bound`` (each row to a lower address)."""
    for row in range(n):
        for d in range(width + 1):
            storage[row * (width + 1) + d] = storage[row * (bound + 1) + d]
    return storage[: n * (width + 1)].reshape((n, width + 1))


@jit
def correct(pointer, cells, values, mass, free, lam, dV):
    """``dV = -M^-1 E^T lam`` on the free unknowns (zero elsewhere), into ``dV``, from the
    constraint stored by :func:`entries` in the rows taking part (``cells``: rows)."""
    for k in range(free.size):
        dV[k] = 0.0
        if free[k]:
            s = 0.0  # unsigned indices: no wrap-around of negative ones (see entries)
            for e in range(np.uint64(pointer[k]), np.uint64(pointer[k + 1])):
                s += values[e] * lam[np.uint64(cells[e])]
            dV[k] = -s / mass[k]
    return dV
