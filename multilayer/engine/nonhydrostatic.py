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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit

from multilayer.errors import RunError


@dataclass
class Constraint:
    """The constraint matrix ``E`` (rows: cells ``a * N + i``; columns: face velocities
    ``a * F + f`` then ``L * F + a * N + i`` the ``wbar``), the masses ``M`` and the
    faces ``(left, right)`` columns."""

    E: sp.csr_matrix
    mass: np.ndarray
    left: np.ndarray
    right: np.ndarray


def faces(N: int, periodic: bool) -> tuple[np.ndarray, np.ndarray]:
    """Columns on the left and right of each face carrying a pressure correction."""
    left = np.arange(N - 1)
    if periodic and N > 1:
        return np.append(left, N - 1), np.append(left + 1, 0)
    return left, left + 1


def constraint(
    h: np.ndarray, bed: np.ndarray, fractions: np.ndarray, dx: float, periodic: bool
) -> Constraint:
    """The local rows ``E`` of the layer divergence constraint (module Notes)."""
    L, N = fractions.size, h.size
    left, right = faces(N, periodic)
    F = left.size
    l = fractions[:, None]
    h_face = l * 0.5 * (h[left] + h[right])  # (L, F)
    sigma = np.concatenate([[0.0], np.cumsum(fractions)])
    sigma[-1] = 1.0
    z = bed + sigma[:, None] * h  # (L+1, N) interface heights
    dz = (z[:, right] - z[:, left]) / dx  # (L+1, F) interface slopes at the faces
    # interpolation of the layer velocities on the interfaces: vhat_j = sum_c beta[j, c] v_c
    beta = np.zeros((L + 1, L))
    beta[0, 0] = beta[L, L - 1] = 1.0
    for j in range(1, L):
        total = fractions[j - 1] + fractions[j]
        beta[j, j - 1], beta[j, j] = fractions[j] / total, fractions[j - 1] / total

    rows, cols, vals = [], [], []

    def add(row_layer: int, column: np.ndarray, unknown: np.ndarray, value: np.ndarray) -> None:
        rows.append(row_layer * N + column)
        cols.append(unknown)
        vals.append(value)

    # F_c enters E_c and E_{c+1} with 1/2 each
    for c in range(L):
        unknown = c * F + np.arange(F)
        for row in (c, c + 1):
            if row < L:
                add(row, left, unknown, 0.5 * h_face[c] / dx)
                add(row, right, unknown, -0.5 * h_face[c] / dx)
    # S_j at column i: 1/2 vhat_{j,f} dz_{j,f} for both faces of i; S_j enters E_0 with
    # -1/2 (j = 0, 1), E_a with -1/2 (j = a + 1) and +1/2 (j = a - 1)
    weights: dict[int, list[tuple[int, float]]] = {j: [] for j in range(L + 1)}
    weights[0].append((0, -0.5))
    weights[1].append((0, -0.5))
    for a in range(1, L):
        weights[a + 1].append((a, -0.5))
        weights[a - 1].append((a, 0.5))
    for j, targets in weights.items():
        for row, weight in targets:
            for c in range(L):
                if beta[j, c] == 0.0:
                    continue
                unknown = c * F + np.arange(F)
                value = weight * 0.5 * beta[j, c] * dz[j]
                add(row, left, unknown, value)
                add(row, right, unknown, value)
    # wbar
    columns = np.arange(N)
    for a in range(L):
        add(a, columns, L * F + a * N + columns, np.ones(N))
        if a > 0:
            add(a, columns, L * F + (a - 1) * N + columns, -np.ones(N))
    E = sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(L * N, L * F + L * N)
    )
    mass = np.concatenate([h_face.ravel(), (l * h).ravel()])
    return Constraint(E=E, mass=mass, left=left, right=right)


def correction(
    cons: Constraint,
    moving: np.ndarray,
    u: np.ndarray,
    w: np.ndarray,
    lam_max: np.ndarray | None = None,
    active: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``V*``, the correction ``dV = -M^-1 E^T lam`` and the free unknowns, over the rows
    and unknowns of the moving cells (all vectors full length).

    ``lam`` minimises ``1/2 lam^T A lam - lam^T E V*`` (``A lam = E V*``), subject to
    ``lam <= lam_max`` (L, N) if given: with ``lam_a = -dt q_a`` this is the bound
    ``p >= 0`` on the total pressure, solved by the primal-dual active-set method
    (Hintermueller, Ito & Kunisch 2002) from the guess ``active`` (L, N) of the cells where
    the bound holds (none by default).
    """
    L, N = u.shape
    left, right = cons.left, cons.right
    F = left.size
    face_free = (moving[:, left] | moving[:, right]).ravel() & (cons.mass[: L * F] > 0)
    free = np.concatenate([face_free, moving.ravel()])
    # rows column by column (cell i * L + a): A is then banded, of half-width about L + 3
    layer, column = np.nonzero(moving)
    order = np.lexsort((layer, column))
    rows = (layer * N + column)[order]
    E = cons.E[rows][:, np.flatnonzero(free)]
    inv_mass = 1.0 / cons.mass[free]
    v_star = 0.5 * (u[:, left] + u[:, right])
    V_star = np.concatenate([v_star.ravel(), np.where(moving, w, 0.0).ravel()])
    A = (E @ sp.diags(inv_mass) @ E.T).tocsr()
    r = E @ V_star[free]
    ab = bands(A)
    if lam_max is None:
        lam = solve_banded_spd(ab, r)
    else:
        guess = np.zeros(rows.size, dtype=bool) if active is None else active.ravel()[rows]
        lam = _bounded(A, ab, r, lam_max.ravel()[rows], guess)
    dV = np.zeros(free.size)
    dV[free] = -inv_mass * (E.T @ lam)
    return V_star, dV, free


def bands(A: sp.spmatrix) -> np.ndarray:
    """Upper band storage ``ab[w + i - j, j] = A[i, j]`` (``i <= j``) of a symmetric ``A``."""
    upper = sp.triu(A).tocoo()
    width = int((upper.col - upper.row).max(initial=0))
    ab = np.zeros((width + 1, A.shape[0]))
    ab[width + upper.row - upper.col, upper.col] = upper.data
    return ab


@njit(cache=True)
def solve_banded_spd(ab: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Solve ``A x = b`` for a symmetric positive definite ``A`` in upper band storage by
    banded Cholesky, ``A = U^T U`` (single-threaded; O(n w^2))."""
    w, n = ab.shape[0] - 1, ab.shape[1]
    U = ab.T.copy()  # U[j, w + k - j] = U_kj: the band of column j is contiguous
    for j in range(n):
        s = U[j, w]
        for k in range(max(0, j - w), j):
            s -= U[j, w + k - j] ** 2
        if s <= 0.0:
            raise RunError(
                "the non-hydrostatic pressure system is not positive definite (a non-positive pivot "
                "of its Cholesky factorisation): the constraints of the moving layers are singular"
            )
        d = np.sqrt(s)
        U[j, w] = d
        for i in range(j + 1, min(n, j + w + 1)):
            s = U[i, w + j - i]
            for k in range(max(0, i - w), j):
                s -= U[j, w + k - j] * U[i, w + k - i]
            U[i, w + j - i] = s / d
    x = b.copy()
    for i in range(n):  # U^T y = b
        s = x[i]
        for k in range(max(0, i - w), i):
            s -= U[i, w + k - i] * x[k]
        x[i] = s / U[i, w]
    for i in range(n - 1, -1, -1):  # U x = y
        s = x[i]
        for j in range(i + 1, min(n, i + w + 1)):
            s -= U[j, w + i - j] * x[j]
        x[i] = s / U[i, w]
    return x


@njit(cache=True)
def _fix(ab: np.ndarray, active: np.ndarray) -> np.ndarray:
    """The band of ``A`` with the rows and columns of ``active`` replaced by the identity."""
    w, n = ab.shape[0] - 1, ab.shape[1]
    out = ab.copy()
    for i in range(n):
        if active[i]:
            for j in range(i, min(n, i + w + 1)):  # row i, right of the diagonal
                out[w + i - j, j] = 0.0
            for k in range(max(0, i - w), i):  # column i, above the diagonal
                out[w + k - i, i] = 0.0
            out[w, i] = 1.0
    return out


def _bounded(
    A: sp.spmatrix, ab: np.ndarray, r: np.ndarray, lam_max: np.ndarray, active: np.ndarray
) -> np.ndarray:
    """Minimiser of ``1/2 lam^T A lam - r^T lam`` subject to ``lam <= lam_max`` by primal-dual
    active sets from the guess ``active``: on the active set ``lam = lam_max``, elsewhere
    ``(A lam)_i = r_i``; it stops when the set reproduces itself, i.e. the bound multiplier
    ``mu = r - A lam >= 0`` on it and ``lam <= lam_max`` off it.  The guess only changes the
    number of iterations, never the answer."""
    for _ in range(MAX_ACTIVE_SET_ITERATIONS):
        if active.any():
            rhs = np.where(active, lam_max, r - A @ np.where(active, lam_max, 0.0))
            lam = solve_banded_spd(_fix(ab, active), rhs)
        else:
            lam = solve_banded_spd(ab, r)
        mu = r - A @ lam
        new = np.where(active, mu > 0.0, lam > lam_max)
        if np.array_equal(new, active):
            return lam
        active = new
    raise RunError(
        f"the non-hydrostatic pressure bound p >= 0 was not settled in {MAX_ACTIVE_SET_ITERATIONS} "
        "active-set iterations"
    )


MAX_ACTIVE_SET_ITERATIONS = 100


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
    q_previous: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project the moving cells on the non-hydrostatic constraint (module Notes).

    ``u`` (L, N) are the velocities after the vertical step, ``w`` (L, N) the layer-mean
    vertical velocities before the projection.  Returns the new ``u`` and ``w`` and the
    kinematic pressures ``q`` (L, N) at the bottom interface of each layer (``q`` per unit
    density, m^2/s^2; zero at the free surface).  Cells at rest (``u == 0.0``) or dry keep
    ``u = w = 0``.  With ``g_n = g cos(theta)`` the total pressure
    ``g_n (h - z) + q`` is kept non-negative (granular matter takes no tension); the cells
    where it was zero with ``q_previous`` start the active-set iteration (speed only).
    """
    L, N = u.shape
    moving = (u != 0.0) & (h > dry)[None, :]
    if not moving.any():
        return u.copy(), np.zeros_like(w), np.zeros_like(u)
    columns = np.flatnonzero(moving.any(axis=0))
    lo, hi = max(columns[0] - 1, 0), min(columns[-1] + 2, N)
    if not periodic and (lo > 0 or hi < N):
        # only the moving material and one column at rest on each side take part: the
        # faces beyond join cells at rest and carry no correction
        window = slice(lo, hi)
        u_new, w_new, q = u.copy(), np.zeros_like(w), np.zeros_like(u)
        u_new[:, window], w_new[:, window], q[:, window] = project(
            h[window],
            u[:, window],
            w[:, window],
            bed[window],
            fractions,
            dx=dx,
            dt=dt,
            dry=dry,
            g_n=g_n,
            q_previous=None if q_previous is None else q_previous[:, window],
        )
        return u_new, w_new, q
    cons = constraint(np.where(h > dry, h, 0.0), bed, fractions, dx, periodic)
    left, right = cons.left, cons.right
    F = left.size
    lam_max = active = None
    if g_n is not None:
        depth = (1.0 - np.concatenate([[0.0], np.cumsum(fractions)[:-1]]))[:, None] * h
        lam_max = dt * g_n * depth
        if q_previous is not None:
            active = g_n * depth + q_previous <= 1e-3 * g_n * depth  # about zero then
    _, dV, _ = correction(cons, moving, u, w, lam_max, active)
    dv = dV[: L * F].reshape(L, F)
    dw = dV[L * F :].reshape(L, N)
    du = np.zeros_like(u)
    np.add.at(du.T, left, 0.5 * dv.T)  # du.T is a view: columns of du gather their faces
    np.add.at(du.T, right, 0.5 * dv.T)
    u_new = np.where(moving, u + du, u)
    w_new = np.where(moving, w + dw, 0.0)
    q = np.cumsum((fractions[:, None] * h * dw)[::-1], axis=0)[::-1] / dt
    return u_new, w_new, q


def advect(w: np.ndarray, u: np.ndarray, dx: float, dt: float, periodic: bool) -> np.ndarray:
    """First-order upwind transport of the layer vertical velocities by the layer
    velocities, ``d_t w + u d_x w = 0`` (zero-gradient ends unless periodic)."""
    if periodic:
        west, east = np.roll(w, 1, axis=1), np.roll(w, -1, axis=1)
    else:
        west = np.concatenate([w[:, :1], w[:, :-1]], axis=1)
        east = np.concatenate([w[:, 1:], w[:, -1:]], axis=1)
    return w - dt / dx * (np.maximum(u, 0.0) * (w - west) + np.minimum(u, 0.0) * (east - w))


def yield_gravity(q: np.ndarray, h: np.ndarray, fractions: np.ndarray, g_n: float) -> np.ndarray:
    """Normal gravity ``G_k`` (L, N) of the interface pressures with the non-hydrostatic part,
    ``rho G_k (h - z_k) = rho g cos(theta) (h - z_k) + rho q_k``, never negative."""
    depth = (1.0 - np.concatenate([[0.0], np.cumsum(fractions)[:-1]]))[:, None] * h
    return np.maximum(g_n + np.where(depth > 0, q / np.where(depth > 0, depth, 1.0), 0.0), 0.0)
