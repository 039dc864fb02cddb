"""Transport along the slope: the hyperbolic part of the multilayer system.

Finite volumes in x for (docs/model.md; Fernandez-Nieto, Garres-Diaz, Mangeney &
Narbona-Reina 2016)::

    d_t h + d_x Q = 0,                  Q = sum_a h_a u_a,   h_a = l_a h
    d_t(h_a u_a) + d_x(h_a u_a^2 + l_a g cos(theta) h^2/2) + l_a g cos(theta) h d_x b
        = g sin(theta) h_a + u_{a+1/2} G_{a+1/2} - u_{a-1/2} G_{a-1/2}
    G_{a+1/2} = sum_{b<=a} [ d_x(h_b u_b) - l_b d_x Q ]

Space: hydrostatic reconstruction (Audusse, Bouchut, Bristeau, Klein & Perthame 2004),
first order or second order with minmod slopes of h, h + b and u_a, and an HLL flux per
layer whose wave speeds bracket the waves of every layer.  Time: forward Euler (order 1)
or Heun's SSP-RK2 (order 2).  ``h >= 0`` for a Courant number up to 1/2, and a lake at
rest stays at rest.  The mass exchanged between layers carries the velocity of the layer
it comes from (upwinding: from above when ``G > 0``).  Stresses are left to the implicit
vertical step (``engine/vertical``).

Material at rest does not carry waves: a face between two columns that are entirely at
rest carries no mass during the step, so a heap held by friction keeps its shape to the
last bit; whether it is held is decided by the vertical step (and ``Simulation.step``
redoes a step in which a column at rest starts moving).  Beside material at rest, such a
face sees the cell-centred values of both columns at both orders (the hydrostatic
reconstruction hL, hR of them), the face pressure ``g_n hL hR / 2`` and the
well-balancing terms ``g_n (h_j - hL)(h_j + hR) / 2`` in the cell ``j`` on its west and
``g_n (h_{j+1} - hR)(h_{j+1} + hL) / 2`` in the cell on its east.  A column ``j`` at rest
between two such faces then feels the mean of its two discrete free-surface slopes::

    d_t(h_a u_a)_j = l_a g_n h_j [ tan(theta) - (J_{j-1/2} + J_{j+1/2}) / (2 dx) ],
    J = hR - hL = eta_{j+1} - eta_j    (eta = h + b; |J| <= |eta_{j+1} - eta_j| where the
                                        bed of the face cuts a free surface)

so that every column of a state at rest whose discrete slopes all lie within ``mu_s`` of
``tan(theta)`` feels a driving stress below its friction (docs/model.md, "Rest"), summits,
changes of slope and toes (a dry neighbour: eta = b) included.  The closed part of a gate
(engine/gate.py) at rest is a wall, J = 0: each side feels its own hydrostatic pressure
``g_n h_j^2 / 2`` there, whatever the level beyond it (``_gate_walls``).  The mean pressure
``g_n (hL^2 + hR^2) / 4`` of the flux would give a toe ``h_{j+1}^2 / (4 h_j dx)`` (9/8 of
a linear flank's slope), and a summit flattened by the limiter 1.25 times it.

This numpy formulation is the reference the compiled transport (``kernel.py``) is tested
against bit for bit, written array by array as the equations read; it runs with
``numerics.transport_solver: numpy``.
"""

from __future__ import annotations

import math

import numpy as np

from multilayer.engine.transport import boundaries
from multilayer.engine.transport.boundaries import GHOSTS


def _ghosts(h, u, b, left, right, inflow: boundaries.InflowState | None):
    """The state extended by ``GHOSTS`` columns per side: ``wall`` mirrors (u -> -u),
    ``outflow`` copies, ``inflow`` prescribes h and u, ``periodic`` wraps."""

    def ghosts(kind, side):
        rule = boundaries.rule(kind)
        idx = boundaries.ghost_sources(rule, side, h.size)
        hg, ug, bg = h[idx], u[:, idx], b[idx]
        if rule == boundaries.MIRROR:
            ug = -ug
        elif rule == boundaries.STATE:
            hg = np.full(GHOSTS, inflow.thickness)
            ug = np.repeat(inflow.velocity[:, None], GHOSTS, axis=1)
        return hg, ug, bg

    (hl, ul, bl), (hr, ur, br) = ghosts(left, "left"), ghosts(right, "right")
    h_ext = np.concatenate([hl[::-1], h, hr])
    u_ext = np.concatenate([ul[:, ::-1], u, ur], axis=1)
    b_ext = np.concatenate([bl[::-1], b, br])
    return h_ext, u_ext, b_ext


def _minmod_slope(v: np.ndarray) -> np.ndarray:
    """Minmod-limited jump across each inner cell of ``v`` (last axis), length - 2."""
    back = v[..., 1:-1] - v[..., :-2]
    ahead = v[..., 2:] - v[..., 1:-1]
    return np.where(back * ahead > 0, np.sign(back) * np.minimum(np.abs(back), np.abs(ahead)), 0.0)


#: largest Courant number at which a stage of the scheme keeps h >= 0 (Audusse et al. 2004)
POSITIVITY_LIMIT = 0.5


def courant_step(speed: float, dx: float, cfl: float) -> float:
    """Time step of the Courant condition for the fastest wave ``speed``, the Courant
    number capped at the positivity limit."""
    return min(cfl, POSITIVITY_LIMIT) * dx / speed if speed > 0 else np.inf


#: how many of the transport's largest products (:func:`fluxes_overflow`) one sum adds up
FLUX_TERMS = 16.0


def fluxes_overflow(depth: float, speed: float, dx: float) -> bool:
    """Whether the transport of a state of thickness up to ``depth`` (m) and waves up to
    ``speed`` (m/s) on cells ``dx`` (m) wide computes numbers beyond the floats.  Its
    largest products, here and in the compiled ``kernel.transport`` alike, are the momentum
    flux ``h u^2 + g cos(theta) h^2 / 2`` and the HLL term ``s_L s_R (q_R - q_L) / (s_R -
    s_L)``, at most ``depth speed^2`` (``g cos(theta) h <= speed^2``), and the
    well-balanced pressure difference ``h_e^2 - h_L^2``, at most ``depth^2`` (gravity
    multiplies it after), each then divided by ``dx``; :data:`FLUX_TERMS` of them are
    summed.  Beyond, the step's state held a NaN ("thickness h = nan after transport"),
    where the culprit was the state: an initial speed of 1e160 m/s, whose ``u^2``
    overflows, or a column 1e200 m high under a gravity of 1e-200.  Python's floats: inf,
    no warning."""
    largest = depth * max(depth, speed * speed) * max(1.0, 1.0 / dx)
    return not largest * FLUX_TERMS < math.inf


def overflowing(
    h: np.ndarray, speed: float, g_n: float, dx: float, inflow: boundaries.InflowState | None = None
) -> tuple[str, str] | None:
    """What overflows of a finite state of thickness ``h`` (and ``inflow``'s beside it)
    whose fastest wave is ``speed`` (m/s): its wave speed (``g h`` or ``|u| +
    sqrt(g h)``: no time step bounds it) or its transport (:func:`fluxes_overflow`: its
    fluxes would be NaN), and why that stops it; None if nothing.  ``h`` is read only where
    ``speed`` leaves an overflow possible: ``g_n h <= speed^2`` bounds it."""
    bound = speed * speed / g_n if g_n > 0.0 else math.inf  # Python's floats: inf, no warning
    if speed < math.inf and not fluxes_overflow(bound, speed, dx):
        return None
    if speed == math.inf:
        return "the wave speed sqrt(g cos(theta) h) + |u|", "no time step bounds it"
    depth = float(h.max(initial=0.0))
    if not fluxes_overflow(depth if inflow is None else max(depth, inflow.thickness), speed, dx):
        return None
    return (
        f"the transport (thickness x wave speed^2 / cell width, waves at {speed:.6g} m/s on cells of "
        f"{dx:.6g} m)",
        "its fluxes are beyond the floats",
    )


def stage_courant_step(dt: float, start_speed: float, stage_speed: float, dx: float, cfl: float) -> float:
    """Time step for a step of ``dt`` redone because the state Heun's second stage starts
    from had waves of ``stage_speed``, beyond the positivity limit: the stage speed taken
    to grow linearly with the step, from ``start_speed`` (the state at the start) to
    ``stage_speed`` at ``dt`` (the state is accelerated by the step's forces), and the
    Courant number of ``courant_step`` imposed on it:
    ``dt' (start_speed + (stage_speed - start_speed) dt' / dt) = min(cfl, 1/2) dx``.
    The result is below ``dt`` (a Courant number above 1/2 at ``dt``), at least
    ``courant_step(stage_speed, ...)``."""
    c = min(cfl, POSITIVITY_LIMIT) * dx
    growth = max(stage_speed - start_speed, 0.0) / dt
    step = 2.0 * c / (start_speed + math.sqrt(start_speed * start_speed + 4.0 * growth * c))
    return step if step < dt else courant_step(stage_speed, dx, cfl)


def _gated(flux_h, flux_q, hL, uL, hR, uR, l, g_n, gate):
    """Fluxes through a partly open gate face (engine/gate.py).  Returns the mass and
    momentum fluxes seen by the cells west and east of each face.

    The part ``o_a`` of each layer below the edge leaves the donor cell (upstream of the
    net mass flux) with its HLL fluxes; the rest meets a wall, whose flux is the HLL flux
    between a state and its mirror image (u -> -u), as at a ``wall`` boundary: no mass,
    and ``l (h u^2 + g h^2/2 + s h u)`` with ``s`` the largest wave speed of the state
    (``- s h u`` seen from the east side).  The receiving cell takes the same total mass
    and momentum through the opening spread over its layers in proportion to ``l_a``:
    its sigma layers keep ``h_a = l_a h``, and mass entering its lowest layers alone would
    be moved up by the exchange ``G`` with the velocity the layer had before it arrived
    (zero in a dry cell), which concentrates the momentum in those layers.
    """
    if gate is None:
        return flux_h, flux_h, flux_q, flux_q
    face, opening = gate
    o = opening[:, None]
    f = slice(face, face + 1)

    def wall(h, u, sign):
        s = np.max(np.abs(u), axis=0) + np.sqrt(g_n * h)
        return l * (h * u * u + 0.5 * g_n * h * h + sign * s * h * u)

    mass, momentum = o * flux_h[:, f], o * flux_q[:, f]
    spread_mass, spread_momentum = l * mass.sum(axis=0), l * momentum.sum(axis=0)
    eastward = mass.sum() >= 0.0
    h_west, h_east, q_west, q_east = flux_h.copy(), flux_h.copy(), flux_q.copy(), flux_q.copy()
    h_west[:, f], h_east[:, f] = (mass, spread_mass) if eastward else (spread_mass, mass)
    open_west, open_east = (momentum, spread_momentum) if eastward else (spread_momentum, momentum)
    q_west[:, f] = open_west + (1.0 - o) * wall(hL[f], uL[:, f], 1.0)
    q_east[:, f] = open_east + (1.0 - o) * wall(hR[f], uR[:, f], -1.0)
    return h_west, h_east, q_west, q_east


def _gate_walls(gate, east_wb, west_wb, he, hw, hL, hR):
    """The well-balancing terms (L, N) beside a gate face at rest: the part ``1 - o_a`` of
    each layer that meets the gate's wall takes ``h_j^2 - hL^2`` (west of it;
    ``h_j^2 - hR^2`` east), so that with the wall's ``g_n hL^2 / 2`` each side feels its
    own hydrostatic pressure ``g_n h_j^2 / 2`` whatever the level beyond the gate; the
    open part ``o_a`` keeps the terms of a face at rest."""
    face, o = gate
    east_wb = np.broadcast_to(east_wb, (o.size, east_wb.size)).copy()
    west_wb = np.broadcast_to(west_wb, (o.size, west_wb.size)).copy()
    if face >= 1:  # the cell west of the gate
        j = face - 1
        east_wb[:, j] = o * east_wb[:, j] + (1.0 - o) * (he[j] ** 2 - hL[face] ** 2)
    if face < west_wb.shape[1]:  # the cell east of it
        west_wb[:, face] = o * west_wb[:, face] + (1.0 - o) * (hw[face] ** 2 - hR[face] ** 2)
    return east_wb, west_wb


def _rates(h, u, b, l, *, dx, g_n, g_t, left, right, inflow, order, at_rest, start, dry, gate=None):
    """Time derivatives of h (N,) and of the layer momenta h_a u_a (L, N), the mass and
    the momentum fluxes through the two end faces (left, right, left, right) and the
    fastest wave across a face that carries mass (``max(-s_left, s_right)``); ``gate`` is
    ``(face, opening)``, a face of the window and the opening fractions (L,) there."""
    h_ext, u_ext, b_ext = _ghosts(h, u, b, left, right, inflow)
    # cells 1 .. N+2 of the extended arrays (interior plus one ghost per side)
    if order == 2:
        dh = _minmod_slope(h_ext)
        deta = _minmod_slope(h_ext + b_ext)
        du = _minmod_slope(u_ext)
    else:
        dh = deta = du = 0.0
    hc, uc, bc = h_ext[1:-1], u_ext[:, 1:-1], b_ext[1:-1]
    etac = hc + bc
    h_w, h_e = hc - 0.5 * dh, hc + 0.5 * dh  # west / east face values of each cell
    b_w, b_e = etac - 0.5 * deta - h_w, etac + 0.5 * deta - h_e
    u_w, u_e = uc - 0.5 * du, uc + 0.5 * du
    # faces beside material at rest (module docstring): at rest, holding material at the
    # start of the step on one side at least, and no column filled during the step (a
    # dry column that Heun's second stage finds wet belongs to a moving front).  They see
    # the cell-centred values on both sides, first order, not the limiter's slopes
    wet = _ghosts(start, u, b, left, right, inflow)[0][1:-1] > dry
    kept = wet | (hc <= dry)
    resting = at_rest & (wet[:-1] | wet[1:]) & kept[:-1] & kept[1:]  # the N+1 faces of hc
    h_e[:-1], b_e[:-1] = np.where(resting, hc[:-1], h_e[:-1]), np.where(resting, bc[:-1], b_e[:-1])
    h_w[1:], b_w[1:] = np.where(resting, hc[1:], h_w[1:]), np.where(resting, bc[1:], b_w[1:])

    # hydrostatic reconstruction at the N+1 faces: east face of cell j, west face of j+1
    b_face = np.maximum(b_e[:-1], b_w[1:])
    hL = np.maximum(0.0, h_e[:-1] + b_e[:-1] - b_face)
    hR = np.maximum(0.0, h_w[1:] + b_w[1:] - b_face)
    uL, uR = u_e[:, :-1], u_w[:, 1:]

    # HLL wave speeds (Harten, Lax & van Leer 1983) bracketing every layer's waves
    cL, cR = np.sqrt(g_n * hL), np.sqrt(g_n * hR)
    s_left = np.minimum(np.min(uL, axis=0) - cL, np.min(uR, axis=0) - cR)
    s_right = np.maximum(np.max(uL, axis=0) + cL, np.max(uR, axis=0) + cR)
    at_rest = at_rest | (np.minimum(s_left, 0.0) == np.maximum(s_right, 0.0))  # no wave at all
    s_left = np.where(at_rest, -1.0, np.minimum(s_left, 0.0))
    s_right = np.where(at_rest, 1.0, np.maximum(s_right, 0.0))
    width = s_right - s_left
    wl, wr, jump = s_right / width, -s_left / width, s_left * s_right / width * ~at_rest
    fastest = float(np.where(at_rest, 0.0, np.maximum(-s_left, s_right)).max(initial=0.0))

    # HLL fluxes of layer mass h_a and momentum h_a u_a (per unit l_a); no mass crosses a
    # face at rest, even when Heun's second stage sees the velocities of the first
    qL, qR = hL * uL, hR * uR
    flux_h = l * (wl * qL + wr * qR + jump * (hR - hL)) * ~at_rest
    # the pressure g_n h^2 / 2, g_n hL hR / 2 between two columns at rest
    pL = np.where(resting, 0.5 * g_n * (hL * hR), 0.5 * g_n * hL**2)
    pR = np.where(resting, pL, 0.5 * g_n * hR**2)
    flux_q = l * (wl * (qL * uL + pL) + wr * (qR * uR + pR) + jump * (qR - qL))
    flux_h_west, flux_h_east, flux_q_west, flux_q_east = _gated(flux_h, flux_q, hL, uL, hR, uR, l, g_n, gate)

    # well-balancing: the pressure at each cell's own face values, g_n (h_e^2 - hL^2) / 2,
    # or g_n (h_j - hL)(h_j + hR) / 2 at a face at rest (zero unless the face's bed is above
    # the cell's), and the bed slope term between them (zero at first order)
    hw, he, bw, be = h_w[1:-1], h_e[1:-1], b_w[1:-1], b_e[1:-1]
    east_wb = np.where(resting[1:], (he - hL[1:]) * (he + hR[1:]), he**2 - hL[1:] ** 2)
    west_wb = np.where(resting[:-1], (hw - hR[:-1]) * (hw + hL[:-1]), hw**2 - hR[:-1] ** 2)
    if gate is not None and resting[gate[0]]:
        east_wb, west_wb = _gate_walls(gate, east_wb, west_wb, he, hw, hL, hR)
    east = flux_q_west[:, 1:] + l * 0.5 * g_n * east_wb
    west = flux_q_east[:, :-1] + l * 0.5 * g_n * west_wb
    bed_slope = l * g_n * 0.5 * (hw + he) * (be - bw)

    div_h = (flux_h_west[:, 1:] - flux_h_east[:, :-1]) / dx  # d_x(h_a u_a) per layer
    div_Q = div_h.sum(axis=0)

    # mass exchange through the L-1 internal interfaces, upwinded velocity
    G = np.cumsum(div_h - l * div_Q, axis=0)[:-1]
    u_G = np.where(G > 0.0, u[1:], u[:-1])
    exchange = np.zeros_like(u)
    exchange[:-1] += u_G * G
    exchange[1:] -= u_G * G

    dq = -(east - west + bed_slope) / dx + exchange + g_t * l * h
    # the mass and momentum fluxes through the two end faces, as the cells next to them see them
    ends = (
        _layer_sum(flux_h_east[:, 0]),
        _layer_sum(flux_h_west[:, -1]),
        _layer_sum(flux_q_east[:, 0]),
        _layer_sum(flux_q_west[:, -1]),
    )
    return -div_Q, dq, ends, fastest


def _layer_sum(flux: np.ndarray) -> float:
    """Sum of the layer fluxes of one face, layer by layer from the bed (the order of the
    compiled sweep, so that both paths give the same bits)."""
    total = float(flux[0])
    for value in flux[1:]:
        total += float(value)
    return total


def step_boundary_mass(stage_fluxes: np.ndarray, dt: float) -> np.ndarray:
    """Mass (m^2 per unit width) through the left and right end faces during a step of
    ``dt``, positive in +x, from the face mass fluxes of each stage ``(order, 2)``:
    ``dt F`` for forward Euler, ``dt (F_1 + F_2) / 2`` for Heun, whose update
    ``h + dt (R(h) + R(h_1)) / 2`` weighs both stages by one half.  The same weights
    give the momentum through the end faces from their momentum fluxes."""
    if stage_fluxes.shape[0] == 1:
        return dt * stage_fluxes[0]
    return 0.5 * dt * (stage_fluxes[0] + stage_fluxes[1])


def step_mass_time(mass: float, stage_fluxes: np.ndarray, dt: float) -> float:
    """The integral over the step of the mass per unit width that gravity acts on
    (m^2 s): ``dt M`` for forward Euler, ``dt (M + M_1) / 2`` for Heun, whose first stage
    holds ``M_1 = M - dt (F_right - F_left)`` (``mass`` = ``M`` at the start, the end-face
    mass fluxes of the first stage in ``stage_fluxes[0]``)."""
    if stage_fluxes.shape[0] == 1:
        return dt * mass
    return 0.5 * dt * (mass + (mass - dt * (stage_fluxes[0][1] - stage_fluxes[0][0])))


def stages(order: int, stage: int | None) -> tuple[int, int]:
    """The stages (first, last + 1) a transport call runs: all those of the ``order``
    (``stage`` None), Heun's first stage alone (0: a forward Euler step) or its second
    stage alone (1, from a given state: ``Simulation.step`` applies the vertical step
    between the two)."""
    if stage is None:
        return 0, order
    if stage not in (0, 1) or (stage == 1 and order != 2):
        raise ValueError(f"transport: stage {stage!r} of a step of order {order} (0, or 1 at order 2)")
    return stage, stage + 1


def second_stage_start(first: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray]:
    """The state (h (N,), u (L, N)) Heun's second stage starts from, required alone."""
    if first is None:
        raise ValueError("transport: Heun's second stage alone needs the state it starts from (first)")
    return first


def _step(h, u, b, l, *, dt, dry, stage, first, **kw):
    """Forward Euler (order 1) or Heun (order 2) step of the transport rates, or one of
    Heun's stages (``stages``; the second from the state ``first``); returns h, u, the mass
    fluxes and the momentum fluxes through the two end faces of each stage (stages, 4; the
    first stage's are computed for the second's weights) and the fastest wave across a
    face that carries mass in Heun's second stage (0 without it)."""

    def velocity(h_, q_):
        wet = h_ > dry
        return np.where(wet, q_ / (l * np.where(wet, h_, 1.0)), 0.0)

    begin, end = stages(kw["order"], stage)
    q = l * h * u
    dh, dq, ends, _ = _rates(h, u, b, l, start=h, dry=dry, **kw)
    stage_fluxes = [ends]
    # >= 0 exactly when the stage meets the Courant condition of its own state (up to
    # POSITIVITY_LIMIT): the clip then removes round-off only
    h1 = np.maximum(h + dt * dh, 0.0)
    q1 = q + dt * dq
    if begin == 1:
        h1, u1 = first
        q1 = l * h1 * u1
    stage_speed = 0.0
    if end == 2:  # Heun: the average of the state and two Euler steps
        dh, dq, ends, stage_speed = _rates(h1, velocity(h1, q1), b, l, start=h, dry=dry, **kw)
        stage_fluxes.append(ends)
        h1 = np.maximum(0.5 * (h + h1 + dt * dh), 0.0)
        q1 = 0.5 * (q + q1 + dt * dq)
    return h1, velocity(h1, q1), np.array(stage_fluxes), stage_speed


MARGIN = 4
"""Dry cells kept on each side of the material: a Heun step moves a front by at most two
cells and the slopes look one cell further."""


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
    inflow: boundaries.InflowState | None = None,
    dry: float = 0.0,
    order: int = 2,
    moving: np.ndarray | None = None,
    gate_face: int | None = None,
    opening: np.ndarray | None = None,
    boundary_mass: np.ndarray | None = None,
    stage_speed: np.ndarray | None = None,
    boundary_momentum: np.ndarray | None = None,
    stage: int | None = None,
    first: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """One explicit transport step: returns h^{n+1} (N,) and the velocities u* (L, N).

    ``g_n = g cos(theta)`` and ``g_t = g sin(theta)``; columns not thicker than ``dry``
    leave the step at rest.  ``moving`` (N,) marks the columns that carry waves during
    the step (default: those with a non-zero velocity).  ``opening`` (L,) are the opening
    fractions of the layers at face ``gate_face`` (face i between cells i-1 and i) of a
    partly lifted gate (engine/gate.py); None: no gate.  ``boundary_mass`` (2,), if
    given, receives the mass (m^2 per unit width) that crossed the left and the right
    boundary during the step, positive in +x (the mass balance of ``state_check``).
    ``stage_speed`` (1,), if given, receives the fastest wave (HLL speed) across a face
    that carries mass in Heun's second stage (0 at order 1): the step keeps ``h >= 0``
    only if ``dt`` meets the Courant condition of that stage too.  ``boundary_momentum``
    (3,), if given, receives the momentum per unit width and density (m^3/s) that crossed
    the left and the right boundary, positive in +x, and the integral over the step of
    the mass that gravity acts on (``step_mass_time``): the terms of the transport's
    momentum balance (``engine/bed_force.py``).  ``stage`` 0 or 1 runs one of Heun's
    stages alone (``stages``): the first returns its forward Euler step, the second starts
    from ``first`` = (h_1, u_1) and returns the average with the state; the boundary terms
    then hold those of the stages so far.
    """
    if opening is not None and gate_face is None:
        raise ValueError("transport: a gate opening was given without its gate_face")
    N = h.size
    if moving is None:
        moving = np.any(u != 0.0, axis=0)
    occupied = np.flatnonzero((h > 0.0) | moving)
    sides = boundaries.BOUNDARIES[left], boundaries.BOUNDARIES[right]
    lo = 0 if occupied.size == 0 or sides[0].open else max(occupied[0] - MARGIN, 0)
    hi = N if occupied.size == 0 or sides[1].open else min(occupied[-1] + 1 + MARGIN, N)
    # the dry cells outside the window stay dry and at rest; inside it, a window edge
    # away from the domain boundary is dry, which an outflow ghost copies exactly
    window = slice(lo, hi)
    hw, uw = h[window], u[:, window]
    moving = moving[window]
    ends = [moving[0] or sides[0].needs_state, moving[-1] or sides[1].needs_state]
    if sides[0].wraps:
        ends[0] = moving[-1]
    if sides[1].wraps:
        ends[1] = moving[0]
    moving_ext = np.concatenate([[ends[0]], moving, [ends[1]]])
    at_rest = ~(moving_ext[:-1] | moving_ext[1:])
    gate = None
    if opening is not None and gate_face is not None and lo <= gate_face <= hi:
        gate = (gate_face - lo, np.asarray(opening, dtype=float))
    if stages(order, stage)[0] == 1:
        h1, u1 = second_stage_start(first)
        first = (h1[window], u1[:, window])
    h_new, u_new = np.zeros_like(h), np.zeros_like(u)
    h_new[window], u_new[:, window], stage_fluxes, fastest = _step(
        hw,
        uw,
        b[window],
        fractions[:, None],
        dt=dt,
        dry=dry,
        stage=stage,
        first=first,
        dx=dx,
        g_n=g_n,
        g_t=g_t,
        left=left if lo == 0 else "outflow",
        right=right if hi == N else "outflow",
        inflow=inflow,
        order=order,
        at_rest=at_rest,
        gate=gate,
    )
    # a window edge inside the domain is dry: no flux there
    if boundary_mass is not None:
        boundary_mass[:] = step_boundary_mass(stage_fluxes[:, :2], dt)
    if boundary_momentum is not None:
        boundary_momentum[:2] = step_boundary_mass(stage_fluxes[:, 2:], dt)
        boundary_momentum[2] = step_mass_time(float(np.sum(h) * dx), stage_fluxes[:, :2], dt)
    if stage_speed is not None:
        stage_speed[0] = fastest
    return h_new, u_new
