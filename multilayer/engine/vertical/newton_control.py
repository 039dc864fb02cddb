"""When the Newton iteration of the vertical step stops, and how far it steps.

Per column the step minimises the strictly convex energy (docs/model.md)::

    E(u) = sum_a m_a/(2 dt) (u_a - u*_a)^2 + sum_k Psi_k(u_k - u_{k-1}) + sum_a W_a(u_a)

with ``Psi_k(s) = kappa_k |s| + Phi_k(s)`` (``Phi_k' = tau_v``, the viscous stress) and
``W_a`` the wall term alike.  Each iteration solves a Bingham model of it exactly
(``newton``), and :func:`error_bound` and :func:`energy_rise` judge the model's
minimiser ``u`` from the true stresses at ``u`` alone, without another solve:

**Stopping: an a-posteriori error bound.**  ``E`` is strongly convex with modulus
``M = diag(m_a / dt)``, so any subgradient ``g`` of ``E`` at ``u`` bounds the error,
``||u - u_exact||_M <= ||g||_{M^-1}`` (the subdifferential of an M-strongly convex
function is M-strongly monotone and holds 0 at ``u_exact``, so ``<g, u - u_exact> >=
||u - u_exact||_M^2``; then Cauchy-Schwarz), hence
``max_a |u_a - u_exact,a| <= ||g||_{M^-1} / sqrt(min_a m_a / dt)``, the bound compared
with the velocity threshold.  ``g_a = m_a/dt (u_a - u*_a) + sigma_a - sigma_{a+1} + f_a``
for interface stresses ``sigma_k`` in the subdifferential of ``Psi_k`` at the jumps of
``u`` (a single value ``sgn(s) (kappa + tau_v(|s|))`` across a jump ``s != 0``, the
interval ``[-kappa, kappa]`` across a locked interface) and wall forces ``f_a`` alike.
The multivalued ones are chosen from the free surface down (``sigma_L = 0``): the set of
``sigma_a`` that zero ``g_a`` given the admissible ``sigma_{a+1}`` is an interval; it is
intersected with the admissible set of ``sigma_a``, and where they are disjoint the gap
is the residual ``g_a`` and ``sigma_a`` the nearest admissible value.  At the exact
solution every intersection holds its stresses, so the bound vanishes there: it is
rigorous and stops the iteration at the solve that reaches the tolerance, instead of a
further solve that only confirms it.  It uses the inertia's convexity only: where the
viscous conductances exceed ``m/dt`` by ~1e6 (steps far longer than the viscous time of a
strongly shear-thinning law), round-off in ``u`` can hold it above a tolerance of 1e-10,
so a Newton step that changes no velocity by more than the threshold (the former
criterion) also stops the iteration.

**Globalisation: an exact line search along the Newton step.**  From ``u_0`` the
iteration solves the Newton model and takes the step ``d = u_N - u_0`` towards its
minimiser ``u_N`` in full, or damped: ``u_0 + t* d`` with ``t*`` the minimiser over
``[0, 1]`` of the convex ``phi(t) = E(u_0 + t d)``.  The plugins give stresses, not
potentials, so every test is built from stresses (:func:`slope_along` is the one-sided
``phi'``, a sum of stresses times velocity changes).  The full step is taken when an upper
bound of ``E(u_N) - E(u_0)`` is ``<= 0`` (:func:`energy_rise`): the smaller of ``phi'(1-)``
(``phi(1) - phi(0) <= phi'(1-)``) and the exact inertial, yield and wall-threshold terms
plus a bound of each viscous potential's change: for laws whose viscous stress is known to
be concave in the rate (``concave``: the compiled forms of every built-in law but the
shear-thickening power law) its tangent at ``u_0`` where the rate grows and its chord where
it shrinks; for any other law (a stress nondecreasing in the rate, the plugin contract)
``tau_v(|s|) (|s| - |s_0|)`` with the stress at the end, an upper bound since the stress
between is no larger.  (The tangent is no bound for a stress with a convex kink, such as
the plateau of a law with a thickness-dependent threshold: with it the iteration cycled
between two iterates each "lower" than the other.)
Otherwise ``t*`` is found by bisection on the sign of ``phi'(t+)`` (one stress evaluation
per halving, until the velocities it leaves undecided are within the threshold), and the
step ends at the last ``t`` where ``phi'(t+) < 0``.

*Descent* (the iteration cannot cycle).  (i) The Newton model ``E_m`` and ``E`` have the
same subdifferential at ``u_0``: the model's law passes through the true stress at the
current jumps and has the true yield stress where they vanish, and the inertial and wall
terms are exact (docs/numerics.md).  So ``E'(u_0; d) = E_m'(u_0; d)``.  (ii) ``E_m`` is
convex and ``u_N`` its minimiser, and both are strongly convex with modulus ``M``, so
``E_m'(u_0; d) <= E_m(u_N) - E_m(u_0) - ||d||_M^2 / 2 < 0`` unless ``d = 0``, where
``0`` is in ``dE(u_0)``: ``u_0`` is the exact step.  (iii) ``phi`` is convex with
``phi'(0+) < 0``: a full step taken on ``phi'(1-) <= 0`` or on the rise bound lowers ``E``,
and a damped ``t`` with ``phi'(t+) < 0`` has ``phi(t) - phi(0) <= t phi'(t-) <= t phi'(t+)
< 0``.  Every iteration therefore lowers ``E`` strictly until the exact step is reached;
with model curvatures bounded between ``M`` and a multiple of it, a damped Newton method
with exact (or sufficient-decrease) line searches converges globally to the minimiser of a
strongly convex ``smooth + sum kappa |s|`` energy (Lee, Sun & Saunders 2014, "Proximal
Newton-type methods for minimizing composite functions", SIAM J. Optim. 24, 1420,
Thm 3.1), and near it the rise bound shows the decrease of the full step, so the local rate
is Newton's.  A damped iterate is not an output of the exact solver (a layer locked at
``u_N`` but not at ``u_0`` is not locked in between); it only linearises the next model.
The iteration ends at a full step whose error bound is within the threshold: an exact
output (static layers ``0.0``, plugs exact).  Where no step is damped the iteration is the
plain Newton iteration.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multilayer.engine.compiled import jit

HALVINGS = 60
"""The most halvings of a line search (it stops once the velocities it leaves undecided are
within the threshold: about 35 for a step of the velocity scale at a tolerance of 1e-10)."""


@jit
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@jit
def _potential_rise(start, end, stress_start, stiffness_start, stress_end, concave):
    """An upper bound of ``Phi(end) - Phi(start)`` for a potential whose derivative (the
    stress, >= 0) is nondecreasing in the magnitude: the stress at ``end`` times the change;
    with ``concave`` (the stress concave in the magnitude) the tangent at ``start`` above it
    when the magnitude grows, the chord below it when it shrinks."""
    if not concave:
        return (end - start) * stress_end
    if end >= start:
        return (end - start) * (stress_start + 0.5 * stiffness_start * (end - start))
    return -(start - end) * 0.5 * (stress_start + stress_end)


@jit(inline="always")  # inlined: as the lines it replaces in error_bound
def zeroing(lo, hi, momentum, inertia, u, w, wall_viscous):
    """The interval of ``sigma_a`` that zeroes ``g_a`` of one layer (:func:`error_bound`)
    given ``sigma_{a+1}`` in ``[lo, hi]``, its speed ``u`` and its wall terms."""
    excess = momentum - inertia * u  # m_a/dt (u*_a - u_a)
    if u != 0.0:
        f = _sign(u) * (w + wall_viscous)
        return lo + excess - f, hi + excess - f
    return lo + excess - w, hi + excess + w


@jit(borrowing=True)  # compiled once, linked into its callers (numba inlining lowered it at each call)
def error_bound(inertia, momentum, kappa, viscous, w, wall_viscous, u, limit):
    """The bound of the module docstring on ``max_a |u_a - u_exact,a|`` for one column,
    or ``inf`` once the pass finds it above twice ``limit`` (``limit = inf``: always the
    bound; the comparison with ``limit`` is the same either way).

    Per layer ``a``: ``inertia = m_a / dt``, ``momentum = m_a u*_a / dt``, ``kappa`` the
    true yield stress of interface ``a`` (below layer ``a``; 0 the bed) and ``viscous`` its
    true viscous stress ``|tau_v|`` at the jump of ``u``, ``w`` the true wall threshold and
    ``wall_viscous`` the wall viscous force ``|F_v|`` at ``u_a``.
    """
    L = inertia.shape[0]
    # a residual above 4 limit^2 times the smallest m/dt so far: the bound exceeds 2 limit
    # (the residual only grows and the smallest only shrinks as the pass goes on)
    cap = 4.0 * limit * limit
    lo = 0.0  # admissible sigma_{a+1}: [lo, hi]; {0} at the free surface
    hi = 0.0
    residual = 0.0  # ||g||^2_{M^-1}
    smallest = np.inf
    for a in range(L - 1, -1, -1):
        jump = u[a] - (u[a - 1] if a > 0 else 0.0)
        lo_zero, hi_zero = zeroing(lo, hi, momentum[a], inertia[a], u[a], w[a], wall_viscous[a])
        gap = 0.0
        if jump != 0.0:
            sigma = _sign(jump) * (kappa[a] + viscous[a])
            gap = max(lo_zero - sigma, sigma - hi_zero, 0.0)
            lo = hi = sigma
        else:
            lo, hi = max(lo_zero, -kappa[a]), min(hi_zero, kappa[a])
            if lo > hi:  # disjoint: sigma_a is the admissible value nearest
                gap = lo - hi
                lo = hi = kappa[a] if hi_zero > kappa[a] else -kappa[a]
        smallest = min(smallest, inertia[a])
        if gap > 0.0:
            residual += gap * gap / inertia[a]
            if residual > cap * smallest:  # an iteration far from converged: the rest is moot
                return np.inf
    return np.sqrt(residual / smallest)


@jit(borrowing=True)
def slope_along(inertia, momentum, kappa, viscous, w, wall_viscous, start, end, v, side):
    """The one-sided derivative ``phi'(t+)`` (``side`` 1) or ``phi'(t-)`` (``side`` -1) of
    ``phi(t) = E(start + t (end - start))`` at the velocities ``v = start + t (end - start)``
    of one column, from the true stresses at ``v`` (arguments of :func:`error_bound`,
    ``viscous`` and ``wall_viscous`` at the jumps and speeds of ``v``): where a jump or a
    speed of ``v`` is zero the yield stress adds ``side kappa |change|``."""
    slope = 0.0
    for a in range(inertia.shape[0]):
        jump = v[a] - (v[a - 1] if a > 0 else 0.0)
        d = end[a] - start[a]
        d_jump = (end[a] - (end[a - 1] if a > 0 else 0.0)) - (start[a] - (start[a - 1] if a > 0 else 0.0))
        slope += (inertia[a] * v[a] - momentum[a]) * d
        if v[a] != 0.0:
            slope += _sign(v[a]) * (w[a] + wall_viscous[a]) * d
        else:
            slope += side * w[a] * abs(d)
        if jump != 0.0:
            slope += _sign(jump) * (kappa[a] + viscous[a]) * d_jump
        else:
            slope += side * kappa[a] * abs(d_jump)
    return slope


@jit(borrowing=True)
def energy_rise(
    inertia, momentum, kappa, viscous, w, wall_viscous, start, u,
    tau, stiffness, wall_tau, wall_stiffness, concave,
):  # fmt: skip
    """An upper bound of ``E(u) - E(start)`` for one column (arguments of
    :func:`error_bound`; at ``start`` the viscous stresses ``tau``, their derivatives
    ``stiffness`` with respect to the jump, the viscous wall forces ``wall_tau`` and their
    derivatives ``wall_stiffness``; ``concave``: every viscous stress is concave in the
    rate): the smaller of ``phi'(1-)`` (:func:`slope_along`) and :func:`rise_bound`."""
    rise = rise_bound(
        inertia, momentum, kappa, viscous, w, wall_viscous, start, u,
        tau, stiffness, wall_tau, wall_stiffness, concave,
    )  # fmt: skip
    return min(slope_along(inertia, momentum, kappa, viscous, w, wall_viscous, start, u, u, -1.0), rise)


@jit(borrowing=True)
def rise_bound(
    inertia, momentum, kappa, viscous, w, wall_viscous, start, u,
    tau, stiffness, wall_tau, wall_stiffness, concave,
):  # fmt: skip
    """The exact inertial, yield and wall-threshold terms of ``E(u) - E(start)`` plus
    :func:`_potential_rise` of each viscous potential (the arguments of
    :func:`energy_rise`): the second of its bounds.  Where this one is not positive, the
    smaller of the two (or NaN, where ``phi'(1-)`` is) is not positive either: a caller
    that only asks whether the rise is positive (``sheared_columns``) stops there."""
    rise = 0.0
    for a in range(inertia.shape[0]):
        jump = u[a] - (u[a - 1] if a > 0 else 0.0)
        jump_start = start[a] - (start[a - 1] if a > 0 else 0.0)
        d = u[a] - start[a]
        rise += d * (0.5 * inertia[a] * (u[a] + start[a]) - momentum[a])
        rise += w[a] * (abs(u[a]) - abs(start[a])) + kappa[a] * (abs(jump) - abs(jump_start))
        rise += _potential_rise(
            abs(start[a]), abs(u[a]), wall_tau[a], wall_stiffness[a], wall_viscous[a], concave
        )
        rise += _potential_rise(abs(jump_start), abs(jump), tau[a], stiffness[a], viscous[a], concave)
    return rise


def examine_columns(
    inertia: np.ndarray,
    momentum: np.ndarray,
    kappa: np.ndarray,
    viscous: np.ndarray,
    w: np.ndarray,
    wall_viscous: np.ndarray,
    start: np.ndarray,
    u: np.ndarray,
    at_start: np.ndarray,
    concave: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`error_bound` and :func:`energy_rise` of every column of (L, N) arrays
    (``at_start`` (4, L, N)): (bounds (N,), rises (N,)).

    The columns are copied to contiguous rows first, so that one compilation of the two
    functions, the one of the compiled step (``newton_kernel``), serves every layout."""
    rows = _rows(inertia, momentum, kappa, viscous, w, wall_viscous, start, u)
    return _examine_compiled(
        *rows, np.ascontiguousarray(np.moveaxis(at_start, 2, 0), dtype=float), bool(concave)
    )


def _rows(*arrays: np.ndarray) -> list[np.ndarray]:
    """(L, N) arrays as contiguous (N, L) float rows: one compilation serves every layout."""
    return [np.ascontiguousarray(np.transpose(a), dtype=float) for a in arrays]


def _examine_rows(inertia, momentum, kappa, viscous, w, wall_viscous, start, u, at_start, concave):
    """:func:`examine_columns` on (N, L) arrays and ``at_start`` (N, 4, L)."""
    n = inertia.shape[0]
    bounds, rises = np.empty(n), np.empty(n)
    for j in range(n):
        args = (inertia[j], momentum[j], kappa[j], viscous[j], w[j], wall_viscous[j])
        bounds[j] = error_bound(
            args[0], args[1], args[2], args[3], args[4], args[5], u[j], np.inf
        )  # inlined: no *args
        at = at_start[j]
        rises[j] = energy_rise(*args, start[j], u[j], at[0], at[1], at[2], at[3], concave)
    return bounds, rises


_examine_compiled: Any = jit(_examine_rows)


def slopes_along(
    inertia: np.ndarray,
    momentum: np.ndarray,
    kappa: np.ndarray,
    viscous: np.ndarray,
    w: np.ndarray,
    wall_viscous: np.ndarray,
    start: np.ndarray,
    end: np.ndarray,
    v: np.ndarray,
    side: float,
) -> np.ndarray:
    """:func:`slope_along` of every column of (L, N) arrays: (N,)."""
    return _slopes_compiled(
        *_rows(inertia, momentum, kappa, viscous, w, wall_viscous, start, end, v), float(side)
    )


@jit
def _slopes_compiled(inertia, momentum, kappa, viscous, w, wall_viscous, start, end, v, side):
    """:func:`slopes_along` on (N, L) arrays."""
    out = np.empty(inertia.shape[0])
    for j in range(inertia.shape[0]):
        out[j] = slope_along(
            inertia[j], momentum[j], kappa[j], viscous[j], w[j], wall_viscous[j], start[j], end[j], v[j], side
        )
    return out
