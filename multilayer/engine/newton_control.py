"""When the Newton iteration of the vertical step stops, and which of its steps it keeps.

Per column the step minimises the strictly convex energy (docs/model.md)::

    E(u) = sum_a m_a/(2 dt) (u_a - u*_a)^2 + sum_k Psi_k(u_k - u_{k-1}) + sum_a W_a(u_a)

with ``Psi_k(s) = kappa_k |s| + Phi_k(s)`` (``Phi_k' = tau_v``, the viscous stress) and
``W_a`` the wall term alike.  Each iteration solves a Bingham model of it exactly
(``vertical_step``), and :func:`examine` judges the model's minimiser ``u`` from the true
stresses at ``u`` alone, without another solve:

**Stopping: an a-posteriori error bound.**  ``E`` is strongly convex with modulus
``M = diag(m_a / dt)``, so any subgradient ``g`` of ``E`` at ``u`` bounds the error,
``||u - u_exact||_M <= ||g||_{M^-1}`` (from ``<g, u - u_exact> >= ||u - u_exact||_M^2``;
e.g. Nesterov 2004, "Introductory Lectures on Convex Optimization", Thm. 2.1.10), hence
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
further solve that only confirms it.

**Globalisation: keep a Newton step only if it decreases E.**  Along ``d = u - u_0`` (the
step from the model's linearisation point ``u_0``), ``phi(t) = E(u_0 + t d)`` is convex,
so ``phi'(1-) <= 0`` implies ``E(u) <= E(u_0)``; ``phi'(1-)`` needs the stresses only
(the left derivative: ``-kappa |ds|`` across a locked interface).  A Newton step failing
this test is replaced by the step of the secant (Kacanov) model from ``u_0``: true yield
stresses and conductances ``eta(rate at u_0)``.  For a viscosity nonincreasing in the rate
the secant potential ``Phi(s0) + eta(s0) (s^2 - s0^2) / 2`` majorises ``Phi``, so the
secant step decreases ``E`` (a majorise-minimise iteration: Lange, Hunter & Yang 2000,
"Optimization transfer using surrogate objective functions"; convergent: Han, Jensen &
Shimansky 1997, "The Kacanov method for some nonlinear problems").  The energy thus
decreases at every kept step, a cycle of the plain Newton iteration cannot recur, and
every iterate, the last included, is an exact output of the exact solver (static layers
``0.0``, plugs exact).  Where Newton steps decrease ``E`` (every step of a converging
Newton iteration observed), the iteration is the plain one.  The built-in viscosities
are nonincreasing in the rate except the shear-thickening power law (flow index > 1),
whose secant steps are not covered by the majorisation argument.
"""

from __future__ import annotations

import numpy as np
from numba import njit

PROGRESS = 0.9
"""A Newton step that does not lower the energy is kept if its error bound is at most this
fraction of the smallest bound kept so far."""


@njit(cache=True)
def _sign(x):
    return 1.0 if x > 0.0 else (-1.0 if x < 0.0 else 0.0)


@njit(cache=True)
def examine(inertia, momentum, kappa, viscous, w, wall_viscous, start, u):
    """(error bound, phi'(1-)) of the minimiser ``u`` of a model linearised at ``start``.

    Per layer ``a`` of one column: ``inertia = m_a / dt``, ``momentum = m_a u*_a / dt``,
    ``kappa`` the true yield stress of interface ``a`` (below layer ``a``; 0 the bed) and
    ``viscous`` its true viscous stress ``|tau_v|`` at the jump of ``u``, ``w`` the true
    wall threshold and ``wall_viscous`` the wall viscous force ``|F_v|`` at ``u_a``.  The
    bound is that of the module docstring on ``max_a |u_a - u_exact,a|``; ``phi'(1-)`` the
    left derivative of ``E(start + t (u - start))`` at ``t = 1``.
    """
    L = inertia.shape[0]
    lo = 0.0  # admissible sigma_{a+1}: [lo, hi]; {0} at the free surface
    hi = 0.0
    residual = 0.0  # ||g||^2_{M^-1}
    smallest = np.inf
    slope = 0.0
    for a in range(L - 1, -1, -1):
        below = u[a - 1] if a > 0 else 0.0
        below_start = start[a - 1] if a > 0 else 0.0
        jump = u[a] - below
        d = u[a] - start[a]
        d_jump = d - (below - below_start)
        excess = momentum[a] - inertia[a] * u[a]  # m_a/dt (u*_a - u_a)
        slope -= excess * d
        if u[a] != 0.0:
            f = _sign(u[a]) * (w[a] + wall_viscous[a])
            lo_zero, hi_zero = lo + excess - f, hi + excess - f
            slope += f * d
        else:
            lo_zero, hi_zero = lo + excess - w[a], hi + excess + w[a]
            slope -= w[a] * abs(d)
        if jump != 0.0:
            sigma = _sign(jump) * (kappa[a] + viscous[a])
            slope += sigma * d_jump
            gap = max(lo_zero - sigma, sigma - hi_zero, 0.0)
            lo = hi = sigma
        else:
            slope -= kappa[a] * abs(d_jump)
            lo, hi = max(lo_zero, -kappa[a]), min(hi_zero, kappa[a])
            gap = 0.0
            if lo > hi:  # disjoint: sigma_a is the admissible value nearest
                gap = lo - hi
                lo = hi = kappa[a] if hi_zero > kappa[a] else -kappa[a]
        residual += gap * gap / inertia[a]
        smallest = min(smallest, inertia[a])
    return np.sqrt(residual / smallest), slope


@njit(cache=True)
def examine_columns(inertia, momentum, kappa, viscous, w, wall_viscous, start, u):
    """:func:`examine` of every column of (L, N) arrays: (bounds (N,), phi'(1-) (N,))."""
    n = inertia.shape[1]
    bounds, slopes = np.empty(n), np.empty(n)
    for j in range(n):
        bounds[j], slopes[j] = examine(
            inertia[:, j], momentum[:, j], kappa[:, j], viscous[:, j], w[:, j], wall_viscous[:, j],
            start[:, j], u[:, j],
        )  # fmt: skip
    return bounds, slopes
