"""The exchange of solid between the layers of a mixture's column in the local step, and
the discrete energy of the layered local step (docs/mixture.md, "Energy").

In the model of Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina (2016, J. Fluid Mech.
801) the divergence of the grains' velocity is ``gamma tan(psi)``: the dilation of a
sheared zone lifts the grains above it, by ``tan(psi) |v_a - v_(a-1)|`` per unit time
whatever the zone's width, at the cost of the weight above it, which the dilatancy part
of the shear stress, ``tan(psi) p_s``, pays at the same place.  The layers of the mesh
keep fixed fractions of the thickness: with each layer's solid kept, the dilation of one
interface would lift every layer, at the cost of the column's mean buoyant weight.  The
local step therefore moves solid between the layers of the column (and the same volume
of fluid the other way, as multilayer models exchange mass between their layers), so
that each interface is charged the weight above it (:func:`between_layers`), and its
closure integrates the pore pressures with the same placement
(:meth:`~multilayer.engine.mixture.local_step.LocalStep.darcy`).

Notes
-----
The discrete energy of a uniform column (no transport; one local step per time step, the
Lie splitting of ``numerics.order: 1``), per unit area, with ``G = (rho_s - rho_f) g
cos(theta)``, the buoyant weights ``w_a = G s_a`` and ``F_a = (rho_s - rho_f) g sin(theta)
s_a``, ``X_a`` the distance layer ``a`` travelled, ``c_a = sum_{b < a} l_b + l_a / 2`` the
height of its centre over ``h`` and ``P_bar = sum_a w_a c_a``::

    E = sum_a m_a v_a^2 / 2 + h P_bar - sum_a F_a X_a

(a uniform packing per layer puts the grains of layer ``a`` at its centre).  The step from
``(s, h*, v*)`` (``v*`` with the drive ``F`` of the step) is

1. the column solve and the closure at the solid ``s``: ``v'``, ``p_e'``, ``Phi'`` and
   ``h' - h* = dt h' sum_a l_a Phi'_a = sum_a T_a``, with ``T_a = dt l_a h' Phi'_a`` the
   thickening of interface ``a`` and ``R_a = dt spacing_a h' Phi'_a = dt tan(psi_a)
   |v'_a - v'_(a-1)|`` its rise (``T_a = lambda_a R_a``, ``lambda_a = l_a / spacing_a``);
2. the exchange (:func:`between_layers`): the solid ``f_b`` crosses interior interface ``b``
   upwards (the same volume of fluid downwards), ``s''_a = s_a + f_a - f_(a+1)``
   (``f_0 = f_L = 0``), with ``G h' sum_b spacing_b f_b = sum_a Q_a``,
   ``Q_a = R_a P_a - T_a P_bar`` (``P_a``, ``P_bar`` of ``s``), each ``Q_a`` by fluxes of
   its own sign; every layer ends as the merger, at one velocity ``v''_a``, of what it kept
   of its mass ``m_a(s, h')`` at ``v'_a`` and the parcels of its neighbours at theirs.

The energy identity.  The column solve's momentum balance times ``v'``, the masses of the
fluid joining at rest and ``h' - h* = sum_a T_a`` give exactly (the one-layer identity of the
uniform layer, term by term) the change over 1, with the stress ``tau_a`` of interface
``a``: ``-dt sum_a |v'_a - v'_(a-1)| tau_a + sum_a T_a P_bar - K``, ``K = sum_a m*_a (v'_a -
v*_a)^2 / 2 >= 0``.  Over 2 the potential energy changes by ``G h' sum_a (s''_a - s_a) c_a =
G h' sum_b f_b (c_b - c_(b-1)) = G h' sum_b f_b spacing_b = sum_a (R_a P_a - T_a P_bar)``
(summation by parts; ``c_b - c_(b-1) = spacing_b``), and the kinetic energy by ``-K_x``,
``K_x >= 0``: the merger keeps each parcel's momentum, and the kinetic energy of a merger
is at most the sum of its parts' (Jensen).  So::

    E'' - E = -dt D - K - K_x,     dt D = dt sum_a |v'_a - v'_(a-1)| tau_a - sum_a R_a P_a

The fixed-fraction lift ``T_a P_bar`` of step 1 cancels: each interface is charged the
model's lift, the weight above it times its rise.

The inequality.  For ``dilatant_coulomb`` ``tau_a = max(tan(delta) + K (phi_a - phi_c), 0)
p_s,a + (K1 + K K2) eta_f gamma_a >= (tan(delta) + tan(psi_a)) p_s,a + K1 eta_f gamma_a``
(``tan(psi) p_s = K (phi - phi_c) p_s + K K2 eta_f gamma`` where ``p_s > 0``; at ``p_s = 0``
``tan(psi) p_s = 0``), so with ``p_s,a = P_a - p_e,a`` and ``dt tan(psi_a) |v'_a - v'_(a-1)|
= R_a``::

    dt D >= dt sum_a (tan(delta) p_s,a + K1 eta_f gamma_a) |v'_a - v'_(a-1)| - sum_a R_a p_e,a

and by the closure, ``p_e,a = -sum_(c >= a) D_c h_c W_c`` with ``dt W_c = sum_(b <= c) R_b``::

    -sum_a R_a p_e,a = sum_a R_a sum_(c >= a) D_c h_c W_c = sum_c D_c h_c W_c sum_(b <= c) R_b
                     = dt sum_c D_c h_c W_c^2 >= 0

(the model's Darcy dissipation).  Hence ``D >= 0`` and ``E'' <= E`` term by term, in every
state, dilating or contracting, for any number of layers (``p_s >= 0``: the closure's
root).  For one layer there is no interior interface, ``Q_0 = R_0 P - 2 R_0 P / 2 = 0``, no
exchange: the step is the one-layer step unchanged, and ``D = (tan(delta) p_s + K1 eta_f
gamma - tan(psi) p_e) |v|`` is the uniform layer's.  The identity holds at the converged
iterate, to ``numerics.tolerance``.  The drive itself, ``m_a (v*_a - v_a) = dt F_a``, changes
the kinetic energy by ``dt sum_a F_a v*_a - sum_a m_a (v*_a - v_a)^2 / 2``: with ``X_a``
advanced by ``dt v*_a``, ``E`` falls over the whole step too.

The side.  ``Q_a`` is the potential energy by which the fixed fractions miss the model's
placement of the interface's rise: in the coordinates of the mesh the model moves the
grains above ``a`` by ``R_a (1 - Lambda)`` relative to the fixed fractions and those below
it by ``-R_a Lambda`` (``lambda_a = 1``): away from the interface where it dilates, towards
it where it contracts, and ``Q_a`` has the sign of the side that weighs more.  The flux
carries ``Q_a`` on that side: above ``a`` (through ``b > a``, in proportion to ``(1 -
Lambda_b) phi`` of the layer the solid leaves) where ``Q_a`` has the sign of ``R_a``, below
it (through ``1 <= b <= a``, in proportion to ``Lambda_b phi``) where not; at the bed
(nothing below) and where that side holds no solid, through all interior interfaces in
proportion to ``(1 - Lambda_b) phi``.  A dilating interface then gives solid to both
sides (up where ``Q_a > 0``, low in the column; down where ``Q_a < 0``, high in it), a
contracting one gathers it: its own layer, whose packing sets its dilation rate, becomes
denser, and contracts less at the next step.  Carried on the other side, a contraction
would empty its own layer into the layers beside it, its packing falling as it contracts
(a loose column of nine layers at ``phi = 0.12`` in water emptied its second layer into
the first, 0.79, within two steps, and stopped).  The energy identity does not depend on the
side: only on ``G h' sum_b spacing_b f_b = Q_a``.

The bounds.  The weights are positive wherever the layers hold solid, so each ``Q_a`` is
carried exactly.  The exchange is kept only where every layer that gives solid gives less
than :data:`GIVEN` (a quarter) of what it holds, and likewise fluid: then every layer keeps
a positive part of each it held, so a packing in ``(0, 1)`` stays in ``(0, 1)``.  A quarter,
not all: the exchange is explicit, its fluxes computed from the packings at the start of
the step, and a step over which the dilation moves a layer's content by a fraction of order
one (``dt |Phi|`` of order one: a loose column far from its critical state, with steps of
0.3 s at millimetres per second) overshoots.  A loose column (``phi = 0.12``, water, 10.9
degrees, 40 steps): bounded at all of a layer's content, its packings swing between
neighbouring layers from step to step (0.2 and 0.93 in nine layers); at half, in four
layers, one layer ends at 0.748, beyond the densest packing of spheres; at a quarter they
compact together, to at most 0.566 and 0.579 in nine and four layers.
Otherwise the column counts as not converged and its step is done
again in sub-steps (continuation in ``dt``): the fluxes are of order ``dt``, so they fall
below the contents of the layers as the sub-steps shorten, in every column whose layers
hold solid and fluid.  What is left: a column whose lift needs solid from layers that hold
none (``phi = 0``) cannot have it, and the run stops naming the exchange after
:data:`~multilayer.engine.mixture.local_step.MAX_SUBSTEPS` sub-steps.

The packings.  The fixed fractions alone loosen every layer for the dilation of one
interface; with the exchange, the dilation of a top interface moves solid down through the
layers below it, and it loosens mostly the two layers beside the interface (twenty layers,
the top one loose over dense ones, one step: the top layer by 4.8e-6, the one below it by
5.7e-7, the others by 1.2e-8 against the 2.8e-7 the fixed fractions take off each), as in
the model, where only the sheared zone loosens.  An interface in the middle of a column,
whose lift the fixed fractions nearly charge right (``Q_a`` near 0), exchanges little: its
dilation loosens all the layers, as with the fixed fractions.
"""

from __future__ import annotations

import numpy as np

GIVEN = 0.25
"""Largest share of its solid, and of its fluid, that a layer may give in one exchange (the
bound of an explicit exchange: module notes, "The bounds"); a column whose exchange would
give more is done again in sub-steps."""


def between_layers(
    solid: np.ndarray,
    h: np.ndarray,
    v: np.ndarray,
    dilation: np.ndarray,
    dt: float,
    l: np.ndarray,
    spacing: np.ndarray,
    buoyant_g_n: float,
    rho_s: float,
    rho_f: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The solid the step's dilation moves between the layers (fractions ``l`` (L, 1), the
    distances ``spacing`` (L, 1) between their centres over ``h``, the buoyant weight per
    unit solid volume ``buoyant_g_n = (rho_s - rho_f) g cos(theta)``) of columns holding
    ``solid`` (L, n) at their new thickness ``h`` (n,), moving with ``v`` (L, n), whose
    interfaces dilate at ``dilation`` (L, n) over ``dt``: the new solid, the velocities
    after the momentum the exchange carries, and where the exchange keeps every layer's
    solid and fluid positive (n,) (module notes).

    Across the interior interface ``b`` (between layers ``b - 1`` and ``b``) the solid
    ``f_b`` rises (sinks where negative) and the same volume of fluid sinks (rises), so
    that each interface ``a`` is charged the lift ``R_a P_a`` of the model, ``R_a = dt
    spacing_a h Phi_a`` its rise and ``P_a`` the buoyant weight above it:
    ``G h sum_b spacing_b f_b = sum_a (R_a P_a - T_a P_bar)`` (``T_a = dt l_a h Phi_a``
    the thickening of the step, which the fixed fractions spread over the column at the
    cost ``T_a P_bar``; ``G = (rho_s - rho_f) g cos(theta)``), interface by interface:
    ``Q_a = R_a P_a - T_a P_bar`` is carried by a flux of its own sign, through the
    interfaces ``b > a`` in proportion to ``(1 - Lambda_b) phi`` where ``Q_a`` has the sign
    of the dilation (up where the interface dilates, down where it contracts), through
    ``1 <= b <= a`` in proportion to ``Lambda_b phi`` where not (``Lambda_b h`` the height
    of interface ``b``, ``phi`` the packing of the layer the solid leaves), through all
    interior interfaces, as above, where that side has none (the bed): a dilating interface
    gives solid away, a contracting one gathers it (module notes, "The side").  The solid
    carries its layer's velocity and the fluid its own layer's: the momentum of the
    column is kept, and its kinetic energy does not grow (every layer ends as the merger
    of what it kept and what it received).  A column whose lift needs solid from layers
    that hold none is not exchanged and is marked (its step goes to sub-steps); so is one where a
    layer would give more than :data:`GIVEN` of either."""
    L, n = solid.shape
    G = buoyant_g_n
    lam = np.cumsum(l, axis=0) - l  # Lambda_a: height of interface a over h
    centre = lam + 0.5 * l
    weight = G * np.cumsum(solid[::-1], axis=0)[::-1]  # P_a
    mean_weight = np.sum(G * solid * centre, axis=0)  # P_bar
    excess = dt * h * dilation * (spacing * weight - l * mean_weight)  # Q_a
    thickness = l * h
    phi = solid / thickness
    # (L - 1, n), interfaces 1..L-1: the packing of the layer the solid leaves, b (sinking)
    # or b - 1 (rising), weighted by Lambda_b below interface a, by 1 - Lambda_b above it
    sinking, rising = phi[1:], phi[:-1]
    cost = G * h * spacing[1:]  # the lift of a unit of solid across interface b
    flux = np.zeros((L - 1, n))
    below = np.arange(1, L)[:, None]
    carried = np.ones(n, dtype=bool)  # every excess carried (no side without solid to move)
    for a in range(L):
        sinks = excess[a] < 0.0
        above = sinks != (dilation[a] > 0.0)  # the side of interface a that carries Q_a
        weights = np.where(sinks, -sinking, rising)
        pattern = np.where(np.where(above, below > a, below <= a), weights, 0.0)
        pattern *= np.where(above, 1.0 - lam[1:], lam[1:])
        norm = np.sum(pattern * cost, axis=0)
        # that side has none (below the bed, or no solid): all interfaces, as above the interface
        pattern = np.where(norm != 0.0, pattern, weights * (1.0 - lam[1:]))
        norm = np.sum(pattern * cost, axis=0)
        carried &= (norm != 0.0) | (excess[a] == 0.0)
        flux += pattern * np.where(norm != 0.0, excess[a] / np.where(norm != 0.0, norm, 1.0), 0.0)
    rises, sinks = np.maximum(flux, 0.0), np.maximum(-flux, 0.0)
    zero = np.zeros((1, n))
    # what leaves layer a: solid up through a + 1 and down through a, fluid the other way
    solid_out = np.concatenate([rises, zero]) + np.concatenate([zero, sinks])
    fluid_out = np.concatenate([zero, rises]) + np.concatenate([sinks, zero])
    kept = ((solid_out == 0.0) | (solid_out < GIVEN * solid)) & (
        (fluid_out == 0.0) | (fluid_out < GIVEN * (thickness - solid))
    )
    fine = carried & (kept.all(axis=0) | ~np.any(flux != 0.0, axis=0))
    flux = np.where(fine, flux, 0.0)
    rises, sinks = np.maximum(flux, 0.0), np.maximum(-flux, 0.0)
    upward = rho_s * rises + rho_f * sinks  # mass from layer b - 1 to layer b, at v_(b-1)
    downward = rho_f * rises + rho_s * sinks  # from layer b to layer b - 1, at v_b
    mass = rho_s * solid + rho_f * (thickness - solid)
    kept_mass = mass - np.concatenate([upward, zero]) - np.concatenate([zero, downward])
    momentum = (
        kept_mass * v + np.concatenate([zero, upward * v[:-1]]) + np.concatenate([downward * v[1:], zero])
    )
    merged = kept_mass + np.concatenate([zero, upward]) + np.concatenate([downward, zero])
    new = solid + np.concatenate([zero, flux]) - np.concatenate([flux, zero])
    moved = np.any(flux != 0.0, axis=0)
    velocities = np.where(moved, momentum / np.where(moved, merged, 1.0), v)
    return np.where(moved, new, solid), velocities, fine
