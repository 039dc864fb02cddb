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

The constraint and its normal equations are assembled in :mod:`.constraint`, solved by
the banded Cholesky factorisation with active sets of :mod:`.banded`; this module
advects ``w``, projects the moving cells and keeps the arrays of a simulation
(:class:`Projection`).

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

The pressure is the projection of the update (Almgren, Bell & Crutchfield 2000): the
velocities a step starts from violate the constraint a little (the cell means of the face
corrections, rows joining as their cells start moving, dilation under the bound), and the
projection of ``V*`` repairs that with an impulse, which divided by a short step is no
pressure.  So ``q = -lam_q / dt`` with ``lam_q`` the multiplier of the same bounded problem
for ``E V* - E^n V^n`` (``E^n V^n`` the constraint of the step's start on this step's rows
and unknowns), the violation the step itself makes: linear in ``dt``, as is the bound.

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

from typing import TYPE_CHECKING

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.pressure.non_hydrostatic.banded import multipliers
from multilayer.engine.pressure.non_hydrostatic.buffers import NO_BAND as _NO_BAND
from multilayer.engine.pressure.non_hydrostatic.buffers import Buffers
from multilayer.engine.pressure.non_hydrostatic.constraint import (
    Constraint,
    correct,
    entries,
    layering,
    normal_equations,
    product,
    unknowns,
)
from multilayer.engine.state import span
from multilayer.errors import RunError

if TYPE_CHECKING:
    from multilayer.engine.vertical_shear import VerticalShear


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
    mass = cons.mass
    n = unknowns(mass, cons.left, cons.right, moving, u, w, offset, layers, free, V_star, row_of, rows, True)
    arrays = (
        np.empty(K + 1, np.int64),
        np.empty(cons.cells.size, np.int64),
        np.empty(cons.cells.size),
        np.empty(K),
    )
    band, r = normal_equations(*cons.geometry, free, row_of, n, V_star, np.empty(0), arrays)
    lam = multipliers(band, r, rows[:n], lam_max, active)[0]
    dV = np.empty(K)
    correct(*arrays, free, lam, dV)
    return V_star, dV, free


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
    start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project the moving cells on the non-hydrostatic constraint (module Notes), with the
    pressure on ``pressure_layers`` groups of layers (default: every layer; module Notes,
    "Fewer pressure layers").

    ``u`` (L, N) are the velocities after the vertical step, ``w`` (L, N) the layer-mean
    vertical velocities before the projection.  Returns the new ``u`` and ``w`` and the
    kinematic pressures ``q`` (L, N) at the bottom interface of each layer (``q`` per unit
    density, m^2/s^2; zero at the free surface): those of the projection of the update
    from ``start``, the thickness, velocities and ``w`` (L, N) of the step's start (module
    Notes; None: a start that satisfies the constraint).  Cells at rest (``u == 0.0``) or
    dry keep ``u = w = 0``.  With ``g_n = g cos(theta)`` the total pressure
    ``g_n (h - z) + q`` is kept non-negative (granular matter takes no tension); the cells
    ``tension_free`` (L, N) where it was zero the step before (:func:`tension_free`) start
    the active-set iterations (speed only: the answer does not depend on them).
    """
    u_new, w_new, q = u.copy(), np.zeros(w.shape), np.zeros(u.shape)
    project_columns(
        h, u, w, bed, fractions, (u_new, w_new, q), dx=dx, dt=dt, periodic=periodic, dry=dry, g_n=g_n,
        tension_free=tension_free, pressure_layers=pressure_layers, start=start,
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
    start: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
    buffers: Buffers | None = None,
) -> tuple[int, int, bool]:
    """:func:`project` into ``out`` (u, w, q; L, N), written in the columns ``lo .. hi-1``
    it returns with whether every ``w`` and ``q`` written is finite; those columns are the
    ones of the moving material and one column at rest on each side (the faces beyond join
    cells at rest and carry no correction; every column if periodic): ``out`` must hold
    ``u`` and zeros elsewhere (the answer there).  ``(0, 0, True)``: nothing moves.
    ``buffers``: the work arrays of the shape of ``u`` and these pressure layers (reused
    from call to call: a new array touched afresh costs a page fault per 4 KiB); they keep
    the constraint of the call, which gives ``E^n V^n`` in the next call where the start is
    on the same thickness, window and free unknowns (:meth:`Buffers.assembled_on`)."""
    L, N = u.shape
    first, last = _moving_columns(u, h, dry)
    if last < 0:
        return 0, 0, True
    lo, hi = (0, N) if periodic else (max(first - 1, 0), min(last + 2, N))
    window = slice(lo, hi)
    moving = _moving(u, h, dry, lo, hi)
    layers = L if pressure_layers is None else pressure_layers
    if buffers is not None and buffers.layering[0] is fractions and buffers.layering[1] == layers:
        nodes, P = buffers.layering[2]
    else:
        nodes, P = layering(tuple(fractions), layers)
        # the constraint of the free unknowns in the rows taking part only (``correction`` on
        # ``constraint``, without the rest), in arrays reused from call to call
        buffers = Buffers(L, N, nodes.size) if buffers is None else buffers
        buffers.layering = (fractions, layers, (nodes, P))
    W = hi - lo
    left, right = (
        buffers.periodic_faces if periodic else (buffers.faces[0][: W - 1], buffers.faces[1][: W - 1])
    )
    if buffers.fractions is not fractions:
        buffers.factors, buffers.fractions = depth_factors(fractions), fractions
    thickness, face_mass = buffers.thickness[:W], buffers.face_mass[: L * left.size]
    lam_max = active = None
    if g_n is not None:
        # the bound at the pressure interfaces holds on every interface: both sides are
        # linear in sigma between them
        lam_max = buffers.lam_max[: nodes.size * W].reshape((nodes.size, W))
        active = buffers.active[: nodes.size * W].reshape((nodes.size, W))
    _window(
        h, fractions, buffers.factors, nodes, dry, lo, left, right, thickness, face_mass,
        0.0 if g_n is None else dt * g_n, _NO_CELLS if tension_free is None else tension_free,
        _NO_BOUND if lam_max is None else lam_max, _NO_CELLS if active is None else active,
    )  # fmt: skip
    guess = active  # the guess, kept for the pressure's solve (the first's updates ``active``)
    if active is not None and start is not None:
        guess = buffers.guess[: active.size].reshape(active.shape)
        guess[:] = active
    K = L * left.size + L * W
    free, V_star, dV, mass = buffers.free[:K], buffers.V_star[:K], buffers.dV[:K], buffers.mass[:K]
    row_of = buffers.row_of[: nodes.size * (hi - lo)]
    n = unknowns(face_mass, left, right, moving, u, w, lo, nodes, free, V_star, row_of, buffers.rows, True)
    arrays = (buffers.pointer[: K + 1], buffers.cells, buffers.values, mass)
    key, geometry = (lo, hi, periodic, dx, P), (thickness, bed[window], fractions, dx, left, right, P)
    carried = None
    if start is not None:  # E V of the step's start, on the rows of this step (before arrays hold E V*)
        h0, u0, w0 = start
        V0 = buffers.V_start[:K]  # the same free unknowns and rows, the start's values
        unknowns(face_mass, left, right, moving, u0, w0, lo, nodes, free, V0, row_of, buffers.rows, False)
        before = buffers.before[:W]
        _thickness(h0, dry, lo, before)
        carried = buffers.carried[:n]
        carried[:] = 0.0
        if buffers.assembled_on(key, free, before, geometry[1]):
            # the last projection's constraint is the start's (it ended on the thickness this
            # step starts from): its stored entries, added up in the order entries adds them
            product(*arrays[:3], free, V0, carried)
        elif not buffers.carried_over(key, (before, *geometry[1:]), free, row_of, V0, carried):
            buffers.built = None  # the arrays are written over
            entries(before, *geometry[1:], free, row_of, *arrays, V0, _NO_BAND, carried)
    buffers.built = None
    band, r = normal_equations(*geometry, free, row_of, n, V_star, buffers.band, arrays)
    buffers.keep(key, free, thickness, geometry[1], row_of, n, left.size)
    lam, factored = multipliers(band, r, buffers.rows[:n], lam_max, active)
    correct(*arrays, free, lam, dV)
    dQ = dV
    if carried is not None and _violation(r, carried, buffers.violation[:n]):
        # the pressure: the projection of the update (the violation the step made), not of V*,
        # from the interfaces where the bound held the step before (its own final set then,
        # not the first's, which the start's repair moves) and the first's factor kept before
        # the first row where the two sets differ; only its wbar part is read
        dQ, W = buffers.dQ[:K], L * left.size
        lam = multipliers(band, buffers.violation[:n], buffers.rows[:n], lam_max, guess, factored)[0]
        correct(arrays[0][W:], *arrays[1:3], mass[W:], free[W:], lam, dQ[W:])
    finite = _finish(dV, dQ, u, w, h, fractions, moving, left, right, dt, lo, buffers.du, *out)
    return lo, hi, finite


_NO_BOUND, _NO_CELLS = np.empty((0, 0)), np.empty((0, 0), np.bool_)
"""No bound ``lam_max`` and no active set or guess of it, for :func:`_window`."""


@jit
def _window(
    h, fractions, factors, nodes, dry, lo, left, right, thickness, face_mass, bound, guess, lam_max, active
):
    """The thickness (``h`` where above ``dry``, else 0) of the columns ``lo ..`` (as many
    as ``thickness`` has), the masses ``fractions_a / 2 (h_left + h_right)`` of the faces
    ``left``, ``right`` of each layer ``a`` (``face_mass[a * F + f]``), the bound
    ``lam_max = bound * (h - z)`` at the pressure interfaces ``nodes`` (``factors``:
    :func:`depth_factors`) and the guess ``active`` of the active set, ``guess`` at those
    interfaces (all False if ``guess`` is empty), in one pass each (``lam_max`` and
    ``active`` empty: none)."""
    W, F = thickness.size, left.size
    _thickness(h, dry, lo, thickness)
    for a in range(fractions.size):
        half = fractions[a] * 0.5
        for f in range(F):
            face_mass[a * F + f] = half * (thickness[np.uint64(left[f])] + thickness[np.uint64(right[f])])
    for g in range(lam_max.shape[0]):
        layer = np.uint64(nodes[g])
        for i in range(W):
            at = np.uint64(lo + i)  # unsigned: numba leaves out the wrap-around of negative indices
            lam_max[g, i] = bound * (factors[layer] * h[at])
            active[g, i] = guess[layer, at] if guess.shape[0] > 0 else False


@jit
def _restart(u, written, columns, u_out, w_out, q_out):
    """Zero ``u_out``, ``w_out`` and ``q_out`` in the columns ``written`` (start, stop), then
    copy ``u`` into ``u_out`` in the columns ``columns``."""
    for a in range(u.shape[0]):
        for i in range(written[0], written[1]):
            at = np.uint64(i)  # unsigned: numba leaves out the wrap-around of negative indices
            u_out[a, at] = w_out[a, at] = q_out[a, at] = 0.0
        for i in range(columns[0], columns[1]):
            u_out[a, np.uint64(i)] = u[a, np.uint64(i)]


@jit
def _begin(
    u, w, q, h_before, factors, g_n, dx, dt, periodic, lo, hi, first, last,
    written_lo, written_hi, tension_lo, tension_hi, u_out, w_out, q_out, w_star, tension,
):  # fmt: skip
    """The start of :meth:`Projection.__call__` in one call (scalars and arrays only: a
    tuple is typed in Python at each call): :func:`_restart` of ``u_out``, ``w_out`` and
    ``q_out`` (written before in the columns ``written_lo .. written_hi-1``) from ``u`` in
    the columns ``lo .. hi-1``, the advected ``w`` (:func:`_advect`) of those columns into
    ``w_star`` (only the moving cells take part, in the columns holding material) and
    :func:`tension_free` of ``q`` on ``h_before`` (the step's start, ``q`` zero outside
    the columns ``first .. last-1``) into ``tension`` (written before in ``tension_lo ..
    tension_hi-1``)."""
    _restart(u, (written_lo, written_hi), (lo, hi), u_out, w_out, q_out)
    _advect(w, u, dx, dt, periodic, lo, hi, w_star)
    _tension_free(q, h_before, factors, g_n, first, last, tension, tension_lo, tension_hi)


@jit
def _violation(r, carried, out):
    """``r - carried`` into ``out``; returns whether ``carried`` has an entry other than 0."""
    nonzero = False
    for k in range(r.size):
        out[k] = r[k] - carried[k]
        nonzero = nonzero or carried[k] != 0.0
    return nonzero


@jit
def _thickness(h, dry, lo, out):
    """``h`` where above ``dry``, else 0, of the columns ``lo ..`` (as many as ``out`` has)
    into ``out``."""
    for i in range(out.size):
        depth = h[np.uint64(lo + i)]
        out[i] = depth if depth > dry else 0.0


@jit
def _moving(u, h, dry, lo, hi):
    """The cells (L, hi - lo) of the columns ``lo .. hi-1`` that take part: ``u != 0`` where
    ``h > dry``."""
    moving = np.empty((u.shape[0], hi - lo), np.bool_)
    for a in range(u.shape[0]):
        for i in range(hi - lo):
            at = np.uint64(lo + i)  # unsigned: numba leaves out the wrap-around of negative indices
            moving[a, i] = u[a, at] != 0.0 and h[at] > dry
    return moving


@jit
def _finish(dV, dQ, u, w, h, fractions, moving, left, right, dt, lo, storage, u_out, w_out, q_out):
    """The projected ``u`` (each column the mean of the corrections ``dV`` of its two faces),
    ``w`` and the pressures ``q_a = sum_{b >= a} h_b dw_b / dt`` (``dw`` the ``wbar`` part of
    the pressure's correction ``dQ``) of the columns ``lo ..`` (as many as ``moving`` has)
    into ``u_out``, ``w_out`` and ``q_out`` (module Notes); ``storage`` holds the changes of
    ``u`` (at least L N long).  Returns whether every ``w`` and ``q`` written is finite."""
    L, N = moving.shape
    check = 0.0  # the sum of value - value over the w and q written: NaN once one is not finite
    F = left.size
    du = storage[: L * N].reshape((L, N))
    du[:] = 0.0
    # unsigned indices (np.uint64): numba leaves out the wrap-around of negative ones
    for c in range(L):
        for f in range(F):
            half = 0.5 * dV[c * F + f]  # each column is the left of one face at most, and the right of one
            du[c, np.uint64(left[f])] += half
            du[c, np.uint64(right[f])] += half
    for a in range(L):
        for i in range(N):
            at = np.uint64(lo + i)
            if moving[a, i]:
                u_out[a, at] = u[a, at] + du[a, i]
                value = w[a, at] + dV[L * F + a * N + i]
                w_out[a, at] = value
                check += value - value
            else:
                u_out[a, at] = u[a, at]
                w_out[a, at] = 0.0
    for i in range(N):
        total, at, depth = 0.0, np.uint64(lo + i), h[np.uint64(lo + i)]
        for a in range(L - 1, -1, -1):
            layer = np.uint64(a)
            total += fractions[layer] * depth * dQ[L * F + a * N + i]
            value = total / dt
            q_out[layer, at] = value
            check += value - value
    return check == 0.0


@jit
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


@jit
def _advect(w, u, dx, dt, periodic, lo, hi, out):
    """First-order upwind transport of the layer vertical velocities by the layer
    velocities, ``d_t w + u d_x w = 0`` (zero-gradient ends unless periodic), into the
    columns ``lo .. hi-1`` of ``out``."""
    L, N = w.shape
    ratio = dt / dx
    for a in range(L):
        for column in range(lo, hi):
            i = np.uint64(column)  # unsigned: numba leaves out the wrap-around of negative indices
            here, speed = w[a, i], u[a, i]
            if speed > 0.0:
                west = w[a, i - 1] if i > 0 else (w[a, N - 1] if periodic else here)
                out[a, i] = here - ratio * (speed * (here - west))
            elif speed < 0.0:
                east = w[a, i + 1] if i < N - 1 else (w[a, 0] if periodic else here)
                out[a, i] = here - ratio * (speed * (east - here))
            else:
                out[a, i] = here


TALL_ASPECT = 100.0
"""The thickness of a pressure layer, in cell widths, beyond which a bound ``p >= 0`` not
settled on several pressure layers is put down to the columns' shape (docs/nonhydrostatic.md,
"Tall narrow columns"): in the tests the iteration failed on pressure layers from 747 to 2e4
cells thick, and settled on the same columns with one pressure layer."""


def unsettled_columns(h: np.ndarray, pressure_layers: int, dx: float) -> str:
    """What the message of a bound ``p >= 0`` not settled adds: the thickness of the
    deepest column's pressure layers in cell widths and, beyond :data:`TALL_ASPECT` on
    several pressure layers, the keys that let it settle.  On such columns the coupling of
    the normal equations across columns, ``m / dx^2``, outweighs the one within a column,
    ``1 / m`` (``m`` a layer's thickness), by ``(m / dx)^2``, and the primal-dual iteration
    (Hintermueller, Ito & Kunisch 2002), whose active sets are proven nested for an
    M-matrix, did not settle in the tests: a column 1000 m high on cells 0.0125 m wide
    with three pressure layers (6.5e3 cells thick at the failure), one 300 m high on cells
    0.125 m wide (747).  With one pressure layer each column has one unknown, and the
    iteration settled on every such column tried; a column 100 m high on those cells of
    0.0125 m (2.7e3 cells thick at its start) settled on three.  Whether it settles
    depends on the state the flow reaches: ``validate`` cannot tell."""
    deepest = float(np.max(h))
    aspect = deepest / pressure_layers / dx
    said = (
        f": the deepest column holds {deepest:.6g} m in {pressure_layers} pressure layers on cells "
        f"{dx:.6g} m wide, each layer {aspect:.3g} cells thick"
    )
    if aspect <= TALL_ASPECT or pressure_layers == 1:
        return said
    return (
        f"{said}, a shape on which the iteration did not settle in the tests (several pressure layers "
        "hundreds of cells thick or more); accepted: model.pressure_layers: 1 (one pressure unknown per "
        "column), wider cells (fewer domain.cells or a longer domain) or model.pressure: hydrostatic (a "
        "shallow-flow model is made for flows much thinner than they are long)"
    )


def depth_below(h: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Depth ``h - z_a`` (L, N) of the bottom interface of each layer below the surface."""
    return depth_factors(fractions)[:, None] * h


def depth_factors(fractions: np.ndarray) -> np.ndarray:
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
    _tension_free(q, h, depth_factors(fractions), g_n, lo, hi, out, 0, 0)
    return out


@jit
def _tension_free(q, h, factors, g_n, lo, hi, out, begin, stop):
    """:func:`tension_free` into the columns ``lo .. hi-1`` of ``out``, its columns ``begin
    .. stop-1`` set False first."""
    for a in range(q.shape[0]):
        for column in range(begin, stop):
            out[a, np.uint64(column)] = False
        for column in range(lo, hi):
            i = np.uint64(column)  # unsigned: numba leaves out the wrap-around of negative indices
            depth = factors[a] * h[i]
            out[a, i] = depth > 0.0 and g_n * depth + q[a, i] <= 1e-9 * g_n * depth


@jit
def _yield_gravity(q, h, factors, g_n, lo, hi, out, start, stop):
    """Normal gravity ``G_k`` of the interface pressures with the non-hydrostatic part,
    ``rho G_k (h - z_k) = rho g cos(theta) (h - z_k) + rho q_k``, never negative, into the
    columns ``lo .. hi-1`` of ``out`` (``factors``: :func:`depth_factors`), its columns
    ``start .. stop-1`` set to ``max(g_n, 0)`` first."""
    for a in range(q.shape[0]):
        for column in range(start, stop):
            out[a, np.uint64(column)] = max(g_n, 0.0)
        for column in range(lo, hi):
            i = np.uint64(column)  # unsigned: numba leaves out the wrap-around of negative indices
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
        shear: VerticalShear | None = None,
    ):
        self.fractions, self.bed = fractions, bed
        self.shear = shear  # model.vertical_shear: its step on the advected w (None: off)
        self.dx, self.periodic, self.dry, self.g_n = dx, periodic, dry, g_n
        self.pressure_layers = pressure_layers
        shape = (fractions.size, bed.size)
        self.u, self.w, self.q = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        self._w_star = np.zeros(shape)  # read at the moving cells only
        self._buffers = Buffers(*shape, layering(tuple(fractions), pressure_layers or shape[0])[0].size)
        self._gravity = np.full(shape, max(g_n, 0.0))
        self._factors = depth_factors(fractions)
        self._tension_free = np.zeros(shape, np.bool_)  # the guess of the active set (tension_free)
        self._written = (0, 0)  # the columns of u, w, q written by the last call
        self.finite = True  # whether every w and q of the last call is finite
        self._gravity_written = self._tension_written = (0, 0)

    def __call__(
        self,
        h: np.ndarray,
        u: np.ndarray,
        start: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
        dt: float,
        columns: tuple[int, int],
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The projected ``u``, ``w`` and the pressures ``q`` (overwritten by the next call)
        of the vertical step's velocities ``u`` on the thickness ``h``, from the state at the
        step's start, ``start = (h, u, w, q)`` (``w`` and ``q`` zero outside the columns
        ``columns``).  ``u`` is zero outside the columns holding material (the vertical step
        zeroes them)."""
        h_before, u_before, w, q = start
        lo, hi = span(h)
        _begin(
            u, w, q, h_before, self._factors, self.g_n, self.dx, dt, self.periodic, lo, hi, *columns,
            *self._written, *self._tension_written, self.u, self.w, self.q, self._w_star, self._tension_free,
        )  # fmt: skip
        self._tension_written = columns
        if self.shear is not None:
            self.shear(h, u, (w, q), dt, (lo, hi), self._w_star)
        try:
            first, last, self.finite = project_columns(
                h, u, self._w_star, self.bed, self.fractions, (self.u, self.w, self.q), dx=self.dx, dt=dt,
                periodic=self.periodic, dry=self.dry, g_n=self.g_n, tension_free=self._tension_free,
                pressure_layers=self.pressure_layers, start=(h_before, u_before, w), buffers=self._buffers,
            )  # fmt: skip
        except RunError as exc:  # the bound not settled: said with the columns' aspect
            raise RunError(
                f"{exc}{unsettled_columns(h, self.pressure_layers or self.fractions.size, self.dx)}"
            ) from None
        self._written = (min(lo, first), max(hi, last)) if last > first else (lo, hi)
        return self.u, self.w, self.q

    def yield_gravity(self, q: np.ndarray, h: np.ndarray, columns: tuple[int, int]) -> np.ndarray:
        """Normal gravity ``G_k`` (L, N) of the interface pressures with the non-hydrostatic
        part of ``q`` (zero outside the columns ``columns``) on the thickness ``h``,
        ``rho G_k (h - z_k) = rho g cos(theta) (h - z_k) + rho q_k``, never negative
        (overwritten by the next call)."""
        lo, hi = columns
        _yield_gravity(q, h, self._factors, self.g_n, lo, hi, self._gravity, *self._gravity_written)
        self._gravity_written = columns
        return self._gravity
