"""The work arrays of the non-hydrostatic projection, reused from call to call, and the
constraint they keep: the start's ``E^n V^n`` of the next call added up from its stored
entries where they are the start's (the projection's Notes,
:mod:`multilayer.engine.pressure.non_hydrostatic.projection`).  Compiled by numba."""

from __future__ import annotations

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.pressure.non_hydrostatic.constraint import capacity, entries, faces

NO_BAND = np.empty((0, 1))
"""The ``band`` of :func:`entries` adding up ``r = E V`` only."""

_NO_SUM = np.empty(0)
"""The ``r`` of :func:`entries` with :data:`NO_BAND`: the entries stored, nothing added up."""


class Buffers:
    """The work arrays of :func:`.projection.project_columns` for ``L`` layers, ``N`` columns and ``Lp``
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
        self.cells, self.values = np.empty(capacity(L, N, N, Lp), np.int64), np.empty(capacity(L, N, N, Lp))
        self.row_of, self.rows = np.empty(Lp * N, np.int64), np.empty(Lp * N, np.int64)
        # a band of half-width below 2 Lp (the rows of two columns; wider: periodic ends, a new one)
        self.band = np.empty(Lp * N * 2 * Lp)
        self.du = np.empty(L * N)
        self.V_start, self.dQ = np.empty(K), np.empty(K)
        # the window's thickness now and at the step's start, face masses, bound and active set
        self.thickness, self.before = np.empty(N), np.empty(N)
        self.face_mass, self.lam_max = np.empty(L * N), np.empty(Lp * N)
        self.active, self.guess = np.empty(Lp * N, np.bool_), np.empty(Lp * N, np.bool_)
        self.carried, self.violation = np.empty(Lp * N), np.empty(Lp * N)
        self.faces = (np.arange(N - 1), np.arange(1, N))  # a window's: their start (periodic: all)
        self.periodic_faces = faces(N, True)
        self.fractions: np.ndarray | None = None  # those of the depth factors
        # the fractions and pressure layers of the nodes and interpolation (:func:`layering`)
        self.layering: tuple = (None, 0, None)
        self.factors = np.empty(L)
        # what the constraint in pointer .. mass was assembled on (:meth:`assembled_on`), its
        # rows and faces (:meth:`carried_over`)
        self.built: tuple | None = None
        self.built_free, self.built_thickness = np.empty(K, np.bool_), np.empty(N)
        self.built_bed = np.empty(N)
        self.built_row_of = np.empty(Lp * N, np.int64)
        self.built_faces = self.built_n = 0
        # the rows of the stored constraint in this call's (:meth:`carried_over`)
        self.table = np.empty(Lp * N, np.int64)
        # the entries of the unknowns assembled afresh by :meth:`carried_over` (made at its first)
        self.fresh, self.origin, self.same = (
            np.empty(K, np.bool_),
            np.empty(K, np.int64),
            np.empty(N, np.bool_),
        )
        self.scratch: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None = None

    def keep(
        self,
        key: tuple,
        free: np.ndarray,
        thickness: np.ndarray,
        bed: np.ndarray,
        row_of: np.ndarray,
        rows: int,
        faces: int,
    ) -> None:
        """Record that the constraint in the arrays was assembled for ``key`` (the window,
        ``dx``, ``periodic``, ``P``) on the free unknowns ``free``, the thickness and bed
        of the window and the row of each cell ``row_of`` (``rows`` rows), with ``faces``
        faces."""
        _copy(
            free,
            thickness,
            bed,
            row_of,
            self.built_free,
            self.built_thickness,
            self.built_bed,
            self.built_row_of,
        )
        self.built, self.built_faces, self.built_n = key, faces, rows

    def assembled_on(self, key: tuple, free: np.ndarray, thickness: np.ndarray, bed: np.ndarray) -> bool:
        """Whether the constraint in the arrays is the one of ``key``, ``free``, ``thickness``
        and ``bed`` (bit for bit: its entries are a function of these only)."""
        if self.built is None or self.built[:4] != key[:4] or self.built[4] is not key[4]:
            return False
        return _same(free, thickness, bed, self.built_free, self.built_thickness, self.built_bed)

    def carried_over(
        self,
        key: tuple,
        geometry: tuple,
        free: np.ndarray,
        row_of: np.ndarray,
        V: np.ndarray,
        out: np.ndarray,
    ) -> bool:
        """``E V`` added into ``out`` (zeros) on the constraint of ``key``, ``geometry`` (the
        arguments of :func:`entries` up to ``P``), ``free`` and ``row_of``, from the
        constraint in the arrays where it was assembled for another window or other free
        unknowns, bit for bit as :func:`entries` adds it up: an unknown's entries are
        functions of the thickness and bed of its columns and of the pressure rows present
        in them only, so those of an unknown free in both, whose columns have the same
        thickness, bed and rows present in both, are the stored ones in their rows here
        (:func:`_reused`); the others are assembled afresh (on their own), and the sum
        is taken unknown by unknown in the order of :func:`entries`.  False (``out``
        untouched) where the arrays hold no constraint of the same ``dx``, ``periodic``
        and ``P``, or another window of a periodic domain."""
        built = self.built
        if (
            built is None
            or built[2:4] != key[2:4]
            or built[4] is not key[4]
            or (key[2] and built[:2] != key[:2])
        ):
            return False
        thickness, bed, K, W = geometry[0], geometry[1], free.size, built[1] - built[0]
        fresh, origin, table = self.fresh[:K], self.origin[:K], self.table[: self.built_n]
        count = _reused(
            free, row_of, thickness, bed, geometry[4], geometry[5], key[0] - built[0], self.built_free,
            self.built_row_of[: row_of.size // thickness.size * W], self.built_thickness[:W],
            self.built_bed[:W], self.built_faces, table, origin, fresh, self.same,
        )  # fmt: skip
        if self.scratch is None:
            size = self.cells.size
            self.scratch = (
                np.empty(self.pointer.size, np.int64), np.empty(size, np.int64), np.empty(size),
                np.empty(self.mass.size),
            )  # fmt: skip
        pointer, cells, values, mass = self.scratch
        if count > 0:  # (the fresh unknowns' entries alone, in the scratch arrays)
            entries(*geometry, fresh, row_of, pointer[: K + 1], cells, values, mass[:K], V, NO_BAND, _NO_SUM)
        _carry(free, origin, pointer, cells, values, self.pointer, self.cells, self.values, table, V, out)
        return True


@jit
def _copy(free, thickness, bed, row_of, free_to, thickness_to, bed_to, row_of_to):
    """``free``, ``thickness``, ``bed`` and ``row_of`` into the start of the others."""
    free_to[: free.size] = free
    thickness_to[: thickness.size] = thickness
    bed_to[: bed.size] = bed
    row_of_to[: row_of.size] = row_of


@jit(borrowing=True)
def _reused(
    free, row_of, thickness, bed, left, right, shift, built_free, built_row_of, built_thickness, built_bed,
    built_faces, table, origin, fresh, same,
):  # fmt: skip
    """For :meth:`Buffers.carried_over`: ``fresh[k]``, the free unknowns ``k`` whose stored
    entries are not theirs (not free in the stored constraint, or a column with another
    thickness or bed, bit for bit, or other pressure rows present), ``origin[k]``, the
    stored unknown whose entries are those of each other free unknown (-1: none), and
    ``table``, the row here of each stored row (-1: none); returns the count of ``fresh``.
    The stored constraint's window starts ``shift`` columns before this one (its column
    ``i + shift`` is column ``i`` here); its arrays are those of :meth:`Buffers.keep`, its
    free unknowns numbered as in :func:`entries` with ``built_faces`` faces; ``same`` (at
    least as long as the window) holds the columns whose thickness, bed and rows are the
    stored ones.  Compiled without reference counting (``borrowing``): its loops call
    :func:`_mark` once per unknown."""
    W, F = thickness.size, left.size
    L, Lp, built_W = free.size // (F + W), row_of.size // W, built_thickness.size
    # same[i]: whether the entries of column i's unknowns are the stored ones
    now, then = thickness.view(np.int64), built_thickness.view(np.int64)
    bed_now, bed_then = bed.view(np.int64), built_bed.view(np.int64)
    for i in range(W):
        j = i + shift
        same[i] = 0 <= j < built_W and now[i] == then[j] and bed_now[i] == bed_then[j]
        for g in range(Lp):
            if same[i] and (row_of[g * W + i] >= 0) != (built_row_of[g * built_W + j] >= 0):
                same[i] = False
    for g in range(Lp):
        for j in range(built_W):
            row, i = built_row_of[g * built_W + j], j - shift
            if row >= 0:
                table[row] = row_of[g * W + i] if 0 <= i < W else -1
    count = 0
    for c in range(L):  # the faces' unknowns, then the columns' (numbered as in entries)
        for f in range(F):
            old = f + shift
            kept = 0 <= old < built_faces and same[left[f]] and same[right[f]]
            count += _mark(c * F + f, c * built_faces + old, kept, free, built_free, origin, fresh)
    for a in range(L):
        for i in range(W):
            j = i + shift
            kept = 0 <= j < built_W and same[i]
            count += _mark(
                L * F + a * W + i, L * built_faces + a * built_W + j, kept, free, built_free, origin, fresh
            )
    return count


@jit(borrowing=True)
def _mark(k, old, kept, free, built_free, origin, fresh):
    """``origin[k] = old`` and ``fresh[k]`` False if the free unknown ``k`` is the stored one
    ``old`` (``kept``: its columns are the same, and ``old`` was free), else ``origin[k] =
    -1`` and ``fresh[k]`` whether ``k`` is free; returns whether ``k`` is fresh (:func:`_reused`)."""
    kept = kept and free[k] and built_free[old]
    origin[k] = old if kept else -1
    fresh[k] = free[k] and not kept
    return fresh[k]


@jit(borrowing=True)
def _carry(free, origin, pointer, cells, values, built_pointer, built_cells, built_values, table, V, out):
    """``out += E V`` unknown by unknown in the order of :func:`entries` (so to the same
    bits): of the free unknowns ``k`` with ``origin[k] >= 0`` the entries stored for the
    unknown ``origin[k]`` (``built_``) in their rows here ``table`` (:func:`_reused`), of the
    others those in ``pointer``, ``cells``, ``values``."""
    for k in range(free.size):
        if not free[k]:
            continue
        old, v = origin[k], V[k]
        if old < 0:  # (_add_column's loop: a borrowing kernel calls none that counts references)
            for p in range(np.uint64(pointer[k]), np.uint64(pointer[k + 1])):
                out[np.uint64(cells[p])] += values[p] * v
        else:
            for p in range(np.uint64(built_pointer[old]), np.uint64(built_pointer[old + 1])):
                out[np.uint64(table[np.uint64(built_cells[p])])] += built_values[p] * v


@jit
def _same(free, thickness, bed, built_free, built_thickness, built_bed):
    """Whether ``free``, ``thickness`` and ``bed`` equal the start of the others bit for bit
    (a signed zero and a NaN too)."""
    for k in range(free.size):
        if free[k] != built_free[k]:
            return False
    W = thickness.size
    return np.array_equal(thickness.view(np.int64), built_thickness[:W].view(np.int64)) and np.array_equal(
        bed.view(np.int64), built_bed[:W].view(np.int64)
    )
