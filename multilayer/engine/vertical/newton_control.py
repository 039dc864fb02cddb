"""When the Newton iteration of the vertical step stops, and which of its steps it keeps.

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

**Globalisation: past the first iterations, keep a Newton step only if it lowers E.**
From iteration ``TRUSTED`` of a column on, the iteration is a descent method on ``E``: a
Newton step from ``u_0`` to the model's minimiser ``u`` is kept if an upper bound of
``E(u) - E(u_0)`` is <= 0, computed from stresses alone (the plugins give no
potentials).  Two bounds serve, the smaller is used: ``phi'(1-)`` for the convex
``phi(t) = E(u_0 + t (u - u_0))`` (``E(u) - E(u_0) <= phi'(1-)``; the left derivative:
``-kappa |ds|`` across a locked interface); and the exact inertial, yield and wall-threshold
terms plus, for each viscous potential, its tangent at ``u_0`` where the rate grows and
its chord where it shrinks (upper bounds when the viscous stress is concave in the rate:
every built-in law but the shear-thickening power law, flow index > 1; for other laws a
second-order estimate).  The second accepts the Newton steps that overshoot along ``d``
but still lower ``E``, which the first alone would reject.  Both can fail to show the
decrease of a good Newton step whose rates cross the whole curved part of a saturating law
(a layer of a collapse front, 1 micrometre thick, locking from rates ~1e4 1/s, where the
chord halves the potential of mu(I)); the secant steps that replace such steps are slow
there (the secant/tangent ratio of mu(I) diverges for ``I >> I_0``), so the first
``TRUSTED - 1`` Newton steps of a column are kept unconditionally (the plain iteration,
which converged in 13 in that column; most columns need fewer than 10).
A Newton step failing both is replaced by the step of the secant (Kacanov) model from
``u_0``: true yield stresses and conductances ``eta(rate at u_0)``.  For a viscosity
nonincreasing in the rate (every built-in law but the shear-thickening power law) the
secant potential ``Phi(s0) + eta(s0) (s^2 - s0^2) / 2`` majorises ``Phi`` and touches it
at ``s0``, so the secant step lowers ``E`` (majorise-minimise: Lange, Hunter & Yang 2000,
"Optimization transfer using surrogate objective functions"; the Kacanov iteration
converges on its own: Han, Jensen & Shimansky 1997, "The Kacanov method for some nonlinear
problems").  From iteration ``TRUSTED`` on ``E`` thus decreases strictly at every kept
step: the iterates cannot cycle, and a Newton iteration that stalls is carried by
majorise-minimise steps.  Every iterate,
the last included, is an exact output of the exact solver (static layers ``0.0``, plugs
exact), and where every Newton step lowers ``E`` the iteration is the plain one.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from multilayer.engine.compiled import jit

TRUSTED = 10
"""Newton steps kept without the energy test: the first iterations of a column."""


@jit
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@jit
def _potential_rise(start, end, stress_start, stiffness_start, stress_end):
    """An upper bound of ``Phi(end) - Phi(start)`` for a potential whose derivative (the
    stress, >= 0) is concave in the magnitude: the tangent at ``start`` above it when the
    magnitude grows, the chord below it when it shrinks."""
    if end >= start:
        return (end - start) * (stress_start + 0.5 * stiffness_start * (end - start))
    return -(start - end) * 0.5 * (stress_start + stress_end)


@jit(inline="always")  # in its callers: no array arguments marshalled per call
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
        excess = momentum[a] - inertia[a] * u[a]  # m_a/dt (u*_a - u_a)
        if u[a] != 0.0:
            f = _sign(u[a]) * (w[a] + wall_viscous[a])
            lo_zero, hi_zero = lo + excess - f, hi + excess - f
        else:
            lo_zero, hi_zero = lo + excess - w[a], hi + excess + w[a]
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


@jit
def energy_rise(inertia, momentum, kappa, viscous, w, wall_viscous, start, u, at_start):
    """An upper bound of ``E(u) - E(start)`` for one column (arguments of
    :func:`error_bound`; ``at_start`` (4, L) holds at ``start`` the viscous stresses, their
    derivatives with respect to the jump, the viscous wall forces and their derivatives):
    the smaller of ``phi'(1-)`` and, for stresses concave in the rate, the exact inertial
    and yield terms plus :func:`_potential_rise`."""
    slope = 0.0  # phi'(1-)
    rise = 0.0
    for a in range(inertia.shape[0]):
        below = u[a - 1] if a > 0 else 0.0
        below_start = start[a - 1] if a > 0 else 0.0
        jump = u[a] - below
        jump_start = start[a] - below_start
        d = u[a] - start[a]
        d_jump = jump - jump_start
        slope += (inertia[a] * u[a] - momentum[a]) * d
        rise += d * (0.5 * inertia[a] * (u[a] + start[a]) - momentum[a])
        rise += w[a] * (abs(u[a]) - abs(start[a])) + kappa[a] * (abs(jump) - abs(jump_start))
        rise += _potential_rise(abs(start[a]), abs(u[a]), at_start[2, a], at_start[3, a], wall_viscous[a])
        rise += _potential_rise(abs(jump_start), abs(jump), at_start[0, a], at_start[1, a], viscous[a])
        if u[a] != 0.0:
            slope += _sign(u[a]) * (w[a] + wall_viscous[a]) * d
        else:
            slope -= w[a] * abs(d)
        if jump != 0.0:
            slope += _sign(jump) * (kappa[a] + viscous[a]) * d_jump
        else:
            slope -= kappa[a] * abs(d_jump)
    return min(slope, rise)


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
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`error_bound` and :func:`energy_rise` of every column of (L, N) arrays
    (``at_start`` (4, L, N)): (bounds (N,), rises (N,)).

    The columns are copied to contiguous rows first, so that one compilation of the two
    functions, the one of the compiled step (``newton_kernel``), serves every layout."""
    rows = [np.ascontiguousarray(np.transpose(a), dtype=float) for a in (inertia, momentum, kappa, viscous)]
    rows += [np.ascontiguousarray(np.transpose(a), dtype=float) for a in (w, wall_viscous, start, u)]
    return _examine_compiled(*rows, np.ascontiguousarray(np.moveaxis(at_start, 2, 0), dtype=float))


def _examine_rows(inertia, momentum, kappa, viscous, w, wall_viscous, start, u, at_start):
    """:func:`examine_columns` on (N, L) arrays and ``at_start`` (N, 4, L)."""
    n = inertia.shape[0]
    bounds, rises = np.empty(n), np.empty(n)
    for j in range(n):
        args = (inertia[j], momentum[j], kappa[j], viscous[j], w[j], wall_viscous[j])
        bounds[j] = error_bound(
            args[0], args[1], args[2], args[3], args[4], args[5], u[j], np.inf
        )  # inlined: no *args
        rises[j] = energy_rise(*args, start[j], u[j], at_start[j])
    return bounds, rises


_examine_compiled: Any = jit(_examine_rows)
