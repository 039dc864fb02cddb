"""The longitudinal deviatoric normal stress of the layers (``model.normal_stress``,
docs/model.md, "Longitudinal normal stress").

The mu(I) stress ``tau = mu(I) p D / |D|`` (Jop, Forterre & Pouliquen 2006; Lagree, Staron &
Popinet 2011, eq. 2.1-2.3) has ``tau_xx = -tau_zz = mu(I) p D_xx / |D|`` with ``|D| =
sqrt(D_xx^2 + D_xz^2)``, ``p`` the mean pressure.  The vertical balance of the layers sets
``P = -sigma_zz`` (hydrostatic, or with the pressure model's yield gravity), so ``p = P +
tau_zz = P - tau_xx`` and ``sigma_xx = sigma_zz + 2 tau_xx``: layer ``a`` feels the momentum
flux ``d_x(2 h_a tau_xx,a)`` (the earth pressure of a yielding material, Savage & Hutter
1989), which the shear stresses of the vertical step leave out, and its friction acts at the
mean pressure ``P - tau_xx``.  With the bulk law's stress norm ``tau(p)`` linearised about
``P``, ``tau(p) = tau_f + e_f (p - P)``, ``e_f = d tau / d p`` (``mu`` for a Coulomb law),
``tau_xx = tau_f c / (1 + e_f c)``, ``c = D_xx / |D|``: the active (``c = 1``) and passive
(``c = -1``) limits ``tau_f / (1 + e_f)`` and ``-tau_f / (1 - e_f)``.  Here ``D_xx = d_x u_a``
along the layer, ``D_xz`` and the rate of the law are lagged from the velocities at the start
of the step.

The step after each vertical step (engine/simulation.py) is the argmin, per layer along x
over each run of columns thicker than the dry threshold (a chain), of::

    sum_i M_i (u_i - u*_i)^2 / 2 + sum_f A_f psi_f(s_f),   s_f = u_(i+1) - u_i,

``M_i = rho l_a h_i dx``, ``A_f = 2 dt l_a h_f tau_f`` with ``tau_f`` the stress norm of the
bulk law ``kappa(P) + eta(2|D|, P) 2|D|`` at the face's mean layer pressure and lagged rate,
``psi_f' = F(phi)``, ``F(phi) = sin(phi) / (1 + e_f sin(phi))``, ``tan(phi) = s_f / B_f``,
``B_f = dx |D_xz|`` (``psi_f`` is convex: ``F`` increases with ``s_f``).  Its optimality
condition is the implicit step ``M_i (u_i - u*_i) = Z_(i+1/2) - Z_(i-1/2)`` with ``Z_f = A_f
F(phi_f) = 2 dt l_a h_f tau_xx``: ``-tau_f / (1 - e_f) <= tau_xx <= tau_f / (1 + e_f)``, the
plastic limit (``B_f = 0``, a plug) exact, no regularisation.  It is unconditionally stable
and dissipative: ``sum M_i (u_i^2 - u*_i^2) / 2 = -sum M_i (u_i - u*_i)^2 / 2 - sum Z_f s_f``,
``Z_f s_f >= 0``; it conserves each chain's momentum (no stress at a chain's ends); ``u* = 0``
gives ``u = 0`` and ``Z = 0`` exactly (no stress in material the vertical step holds at
rest).  The next vertical step sees the mean pressures ``P - tau_xx`` of this one
(:meth:`NormalStress.yield_gravity`: ``P_k (1 - r_k)``, ``r = tau_xx / P`` of the layers,
the mean of a cell's faces' ratios, exact where the layers are in one plastic state,
``tau_xx`` proportional to ``P``).

The step stresses only material that moves (its rate is lagged): a deposit that the vertical
step's friction alone cannot hold, but the friction and the normal stress together can, would
creep, the vertical step letting it move by ``O(dt)`` and this step taking back most of it,
never all.  :func:`joint_rest` finds where rest is the answer of the two steps together,
with the normal stress of material at rest (rate zero: any ``tau_xx`` between the plastic
limits, the tensor law's stress at ``D = 0``), and the engine then ends the step at rest,
chain by chain (:func:`runs`: the step couples the columns of a chain only and the vertical
step none, so rest of a chain is the answer of its own two steps, whatever the others do).

It is solved in the dual: minimise ``sum_i M_i u_i^2 / 2 + sum_f psi_f*(Z_f)`` over the
bounds with ``u_i = u*_i + (Z_(i+1/2) - Z_(i-1/2)) / M_i`` (Fenchel duality; the Hessian is
tridiagonal; ``d psi_f* / d phi = A_f B_f sin(phi) / (1 + e_f sin(phi))^2``), by a projected
Newton method (Bertsekas 1982, SIAM J. Control Optim. 20, 221) in ``Z_f`` on the plastic faces
and in the angle ``phi_f``, ``Z_f = A_f F(phi_f)``, on the others, whose optimum ``phi_f =
atan(s_f / B_f)`` lies inside ``(-pi/2, pi/2)`` however close ``Z_f`` comes to its bounds;
backtracking until the dual objective falls (or, below its round-off, until the slope along
the step is not positive); converged when the Newton step would move no velocity by more than
the tolerance (or than the round-off of its cell's impulses).  Where an angle's curvature is
too small the step is damped (Levenberg-Marquardt); where the projected Newton step does not
descend, the plastic faces it takes across their bounds are fixed there and the step solved
again, then a scaled gradient step is tried; after a step that stalled (it moved no velocity
by :data:`STALL` of its Newton step's change: one line search serves every chain, and a
chain's plastic faces can meet their bounds along a path another chain's angles cut short)
the gradient step goes first.  It converged on 250 random problems with masses, ``A_f`` and
``B_f`` over up to 8 decades and ``|e_f| < 0.8`` (a slow test) and on a step of a collapse that
stalled without the rule; a step that does not converge stops the run with a message (never a
silent answer).  :func:`plastic_chain_step` is the
numpy reference of the method; the engine runs its compiled kernel
(:mod:`multilayer.engine.normal_stress_kernel`, ``compiled=True``), tested equal to it.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import NamedTuple

import numpy as np
from scipy.linalg import solve_banded

from multilayer.engine.normal_stress_kernel import (
    NODES,
    NOT_CONVERGED,
    ROUNDING,
    STALL,
    TURN,
    WEIGHTS,
    chain_step,
)
from multilayer.engine.vertical.newton import NotConverged
from multilayer.engine.vertical.stresses import StressModel
from multilayer.errors import InputError, RunError

PRESSURE_STEP = 1e-4
"""The relative pressure step of the central differences of ``d tau / d p``: their truncation
error of order ``1e-8`` of ``e_f``, their round-off ``LAW_ROUNDING eps / 1e-4``, 3e-11, times
the ratio of the law's parts to the pressure (both small for a law of stresses proportional to
the pressure, :meth:`NormalStress.bulk_law`)."""


LAW_ROUNDING = 16.0
"""The round-off of a bulk law's stress in units of the machine epsilon times the stress (a
few operations of its hooks): the error bound of ``d tau / d p`` is it times the stresses
differenced over the pressure step (:meth:`NormalStress.bulk_law`)."""


CONTRACTION = 0.9
"""The velocities of a round of :func:`joint_rest` at most this fraction of the last's (in
the norm of the kinetic energy): else the rounds are abandoned (they converge linearly
towards rest where rest is the answer; a flow keeps its velocities)."""

MARGIN = 1e-2
"""The friction :func:`joint_rest` leaves unused in its search (a fraction of the vertical
step's yield stresses), so that the rest it finds is held by the full friction exactly."""


class Chains(NamedTuple):
    """The faces of every layer's chains, flattened: the cells (indices into ``u.ravel()``)
    left and right of each face, and whether the next face shares its right cell."""

    left: np.ndarray
    right: np.ndarray
    linked: np.ndarray


def chains(wet: np.ndarray, layers: int) -> Chains:
    """The faces between two columns ``wet`` (N,) in each of ``layers`` layers."""
    n = wet.size
    columns = np.flatnonzero(wet[:-1] & wet[1:])
    left = (np.arange(layers)[:, None] * n + columns[None, :]).ravel()
    linked = np.zeros(left.size, dtype=bool)
    linked[:-1] = left[1:] == left[:-1] + 1
    return Chains(left, left + 1, linked)


def runs(wet: np.ndarray, shortest: int = 2) -> list[slice]:
    """The runs of ``shortest`` or more ``wet`` (N,) columns, each a chain of every layer (the
    columns between two dry ones or an end), as slices of the columns."""
    edges = np.flatnonzero(np.diff(np.concatenate([[False], wet, [False]]).astype(np.int8)))
    pairs = zip(edges[::2], edges[1::2], strict=True)
    return [slice(int(start), int(stop)) for start, stop in pairs if stop - start >= shortest]


def plastic_chain_step(
    ustar: np.ndarray,
    mass: np.ndarray,
    faces: Chains,
    a: np.ndarray,
    b: np.ndarray,
    e: np.ndarray | float = 0.0,
    *,
    tolerance: float,
    max_iterations: int,
    compiled: bool = False,
    where: Callable[[int], str] = "face {}".format,
) -> tuple[np.ndarray, np.ndarray]:
    """The argmin ``u`` of the module docstring's problem and the face impulses ``Z``, for
    the velocities ``ustar`` and masses ``mass`` (flat arrays), the faces' ``a`` (A_f),
    ``b`` (B_f) and pressure sensitivities ``e`` (e_f, ``|e_f| < 1``); converged when the
    Newton step would change no velocity by more than ``tolerance``.  :class:`RunError`
    after ``max_iterations``.  ``compiled``: by the kernel
    :func:`multilayer.engine.normal_stress_kernel.chain_step` (the engine's; equal to round-off,
    tested), else by the numpy code here (its reference); ``where(f)`` names face ``f`` in
    the kernel's :class:`RunError` on a step that is not finite."""
    e = np.broadcast_to(np.asarray(e, dtype=float), a.shape)
    if compiled:
        return _compiled_step(
            ustar, mass, faces, a, b, e, tolerance=tolerance, iterations=max_iterations, where=where
        )
    inv = 1.0 / mass
    smooth = (b > 0.0) & (a > 0.0)
    low, high = -a / (1.0 - e), a / (1.0 + e)  # the plastic faces' bounds: Z_f = A_f F(-+pi/2)
    left, right = faces.left, faces.right
    off = -inv[right] * faces.linked  # the coupling of face f and f + 1 through their cell
    # the unknowns: Z_f on the plastic faces (low <= Z_f <= high), the angle phi_f with Z_f = A_f
    # F(phi_f) on the smooth ones, whose optimum phi_f = atan(s_f / B_f) is inside (-pi/2, pi/2)
    v = np.zeros(a.size)
    z = np.zeros(a.size)
    u = ustar.copy()

    def change(dz: np.ndarray) -> np.ndarray:
        """The velocities' change of the impulses' change ``dz``."""
        du = np.zeros(ustar.size)
        np.add.at(du, left, dz * inv[left])
        np.add.at(du, right, -dz * inv[right])
        return du

    def gradient(v: np.ndarray, s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """dZ/dv and the dual gradient ``A F'(phi) (B tan(phi) - s)`` in ``v``."""
        jacobian = np.where(smooth, a * law_slope(v, e), 1.0)
        return jacobian, -s * jacobian + np.where(smooth, a * b * barrier_integrand(v, e), 0.0)

    def search(
        v: np.ndarray, z: np.ndarray, u: np.ndarray, step: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """Backtracking on the projected path from ``v`` along ``step`` until the dual
        objective falls (or, where the fall is below round-off, until the slope along the
        step is not positive): the new ``v``, ``Z`` and ``u``; None if no step does."""
        alpha = 1.0
        while alpha >= 1e-12:
            trial = v + alpha * step
            trial = np.where(smooth, np.clip(trial, -0.5 * np.pi, 0.5 * np.pi), np.clip(trial, low, high))
            z_trial = np.where(smooth, a * law(trial, e), trial)
            du = change(z_trial - z)
            barrier = np.where(smooth, a * b * barrier_change(v, trial, e), 0.0)
            rise = np.sum(mass * du * (u + 0.5 * du)) + np.sum(barrier)
            moved = u + du
            _, slope = gradient(trial, moved[right] - moved[left])
            if rise <= 0.0 or np.sum(slope * (trial - v)) <= 0.0:
                return trial, z_trial, moved
            alpha *= 0.5
        return None

    def turned(step: np.ndarray, g: np.ndarray) -> np.ndarray:
        """``step`` with each angle's change cut to :data:`TURN`, or scaled as a whole where
        that would not descend along the gradient ``g``."""
        clipped = np.where(smooth, np.clip(step, -TURN, TURN), step)
        if np.sum(g * clipped) < 0.0:
            return clipped
        return step * TURN / max(TURN, float(np.max(np.abs(step[smooth]), initial=0.0)))

    stalled = False
    for _ in range(max_iterations):
        s = u[right] - u[left]
        jacobian, g = gradient(v, s)
        active = (a <= 0.0) | ~smooth & (((z >= high) & (g < 0.0)) | ((z <= low) & (g > 0.0)))
        # the angles' curvature, its part -s A F''(phi) taken positive (where it is not, phi lies
        # on the wrong side of zero, far from its optimum)
        curvature = np.where(smooth, a * b * barrier_slope(v, e) + np.abs(a * s * law_curvature(v, e)), 0.0)
        diagonal = jacobian**2 * (inv[left] + inv[right]) + curvature
        # damped where the curvature is too small to keep the angle's step within TURN (Levenberg
        # -Marquardt: the Hessian stays positive definite, the step a descent direction)
        diagonal = np.where(smooth, np.maximum(diagonal, np.abs(g) / TURN), diagonal)
        coupling = off[:-1] * jacobian[:-1] * jacobian[1:]
        plain = newton_step(active, np.zeros(a.size), g, diagonal, coupling)
        # converged when the step would move no velocity by more than the tolerance or than the
        # round-off of the impulses on its cell (a thin cell between thick ones)
        held = np.zeros(ustar.size)
        np.add.at(held, left, np.abs(z))
        np.add.at(held, right, np.abs(z))
        floor = ROUNDING * np.finfo(float).eps * (held * inv + np.abs(ustar))
        size = np.abs(change(jacobian * plain))
        if not np.any(size > np.maximum(tolerance, floor)):
            return u, z
        # the plastic faces the step takes across their bounds go to them, the others solved again
        step, fixed, moves = plain, active.copy(), np.zeros(a.size)
        while (crossing := ~smooth & ~fixed & ((z + step > high) | (z + step < low))).any():
            fixed |= crossing
            moves = np.where(crossing, np.where(step > 0.0, high, low) - z, moves)
            step = newton_step(fixed, moves, g, diagonal, coupling)
        # the step with the crossing faces at their bounds, the projected Newton step, a scaled
        # gradient step; after a stalled step (STALL) the gradient step first
        attempts = [step, plain, -np.where(active, 0.0, g) / diagonal]
        found = None
        for direction in attempts[2:] + attempts[:2] if stalled else attempts:
            if (found := search(v, z, u, turned(direction, g))) is not None:
                break
        stalled = found is None or np.max(np.abs(found[2] - u)) < STALL * np.max(size)
        if found is not None:
            v, z, u = found
    raise not_converged(max_iterations)


def joint_rest(
    vertical: Callable[[np.ndarray], np.ndarray],
    normal: Callable[[np.ndarray], np.ndarray],
    ustar: np.ndarray,
    split: np.ndarray,
    start: np.ndarray,
    mass: np.ndarray,
    rounds: int,
) -> np.ndarray | None:
    """The certificate that rest, ``u = 0``, is the answer of the vertical step ``V``
    (``vertical``) and the normal-stress step at rest ``N_0`` (``normal``: rate zero, every
    face plastic, ``tau_xx`` anywhere between its passive and active limits) taken together
    from ``ustar``: the velocity change ``q`` of ``N_0``'s impulses such that ``V(ustar - q)
    == 0`` exactly; None if none is found in ``rounds`` rounds, at once where the answer of
    the two steps one after the other, ``split``, is faster than :data:`CONTRACTION` of the
    change of the velocities ``start`` of the time step in ``ustar`` (material moving faster
    than the step's forces could set it moving from rest: a flow, not material coming to
    rest), or where a step does not converge (:class:`NotConverged`: the search is abandoned,
    not the run).  Norms are those of the kinetic energy, the cells' ``mass`` (any factor)
    the weights, as in both steps.

    Found by the Dykstra-like alternation (Bauschke & Combettes 2008, Pacific J. Optim. 4,
    383) of ``N_0`` and ``V_m(w) = (1 - m) V(w / (1 - m))``, ``m`` = :data:`MARGIN`, the
    step of the energy ``(1 - m)^2 Phi(u / (1 - m))`` whose velocities held at rest are those
    of ``V`` times ``1 - m``: its iterates ``x``, ``p``, ``q`` (``x + p + q = ustar``
    throughout) converge to the argmin of the two energies together, and where that is rest,
    ``x + p`` to a velocity ``V_m`` holds on the boundary of its set, inside ``V``'s, which
    ``V`` then holds exactly after finitely many rounds.  Abandoned where a round does not
    shrink the norm of ``x`` to :data:`CONTRACTION` of the last (the answer is not rest, or
    the round-off is reached), or after ``rounds``, unless ``V`` already holds ``x + p =
    ustar - q`` exactly: that is the certificate, which needs no margin (near the round-off
    the margin's iterates lag those ``V`` holds)."""

    def norm(v: np.ndarray) -> float:
        return float(np.sqrt(np.sum(mass * v * v)))

    if not norm(split) <= CONTRACTION * norm(ustar - start):
        return None
    size = norm(ustar)
    shrink = 1.0 - MARGIN
    x, p, q = ustar, np.zeros(ustar.shape), np.zeros(ustar.shape)

    def certified() -> np.ndarray | None:
        return None if np.any(vertical(x + p)) else q

    try:
        for _ in range(rounds):
            y = shrink * vertical((x + p) / shrink)
            if not np.any(y) and not np.any(vertical(x + p)):
                return q
            p = x + p - y
            x = normal(y + q)
            q = y + q - x
            if not (shrunk := norm(x)) <= CONTRACTION * size:
                return certified()
            size = shrunk
        return certified()
    except NotConverged:
        return None


def not_converged(max_iterations: int) -> NotConverged:
    """The error of a step that did not converge in ``max_iterations``."""
    return NotConverged(
        f"the normal-stress step did not converge in {max_iterations} iterations (numerics.max_iterations)"
    )


def _compiled_step(
    ustar: np.ndarray,
    mass: np.ndarray,
    faces: Chains,
    *data: np.ndarray,
    tolerance: float,
    iterations: int,
    where: Callable[[int], str],
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`plastic_chain_step` by its kernel (``iterations``: ``max_iterations``), for the
    faces' ``data`` ``a``, ``b``, ``e``; :class:`RunError` naming the face (``where``) whose
    Newton step or result is not finite."""
    u, z = np.empty(ustar.size), np.empty(faces.left.size)
    # C-ordered and writeable, whatever the caller's arrays (a read-only view, such as the
    # broadcast ``e``, is another signature: numba would compile the kernel a second time)
    cells = [np.require(array, float, ("C", "W")) for array in (ustar, mass)]
    index = [np.require(side, np.int64, ("C", "W")) for side in (faces.left, faces.right)]
    linked = np.require(faces.linked, np.bool_, ("C", "W"))
    arrays = [np.require(array, float, ("C", "W")) for array in data]
    status = chain_step(*cells, *index, linked, *arrays, float(tolerance), int(iterations), u, z)
    if status == NOT_CONVERGED:
        raise not_converged(iterations)
    if status < 0:  # converged: its result checked as the other kernels' are
        finite = np.isfinite(u[faces.left]) & np.isfinite(u[faces.right]) & np.isfinite(z)
        if finite.all():
            return u, z
        status = int(np.flatnonzero(~finite)[0])
    f, (left, right) = status, (faces.left[status], faces.right[status])
    raise RunError(
        f"the normal-stress step is not finite at {where(f)} (a zero pivot of its Newton system or "
        f"an overflow): A_f = {data[0][f]:.6g} kg/s, B_f = {data[1][f]:.6g} m/s, e_f = {data[2][f]:.6g}, "
        f"the masses of its cells {mass[left]:.6g} and {mass[right]:.6g} kg/m, their velocities "
        f"{ustar[left]:.6g} and {ustar[right]:.6g} m/s (model.normal_stress)"
    )


def law(phi: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``F(phi) = sin(phi) / (1 + e sin(phi))``: ``tau_xx / tau`` at ``D_xx / |D| = sin(phi)``."""
    return np.sin(phi) / (1.0 + e * np.sin(phi))


def law_slope(phi: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``F'(phi) = cos(phi) / (1 + e sin(phi))^2``."""
    return np.cos(phi) / (1.0 + e * np.sin(phi)) ** 2


def law_curvature(phi: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``F''(phi) = -(sin(phi) (1 + e sin(phi)) + 2 e cos(phi)^2) / (1 + e sin(phi))^3``."""
    sin = np.sin(phi)
    return -(sin * (1.0 + e * sin) + 2.0 * e * np.cos(phi) ** 2) / (1.0 + e * sin) ** 3


def barrier_integrand(phi: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``tan(phi) F'(phi) = sin(phi) / (1 + e sin(phi))^2``: the derivative of the dual term
    ``psi*(Z) / (A B)`` in ``phi`` (``B tan(phi) = s`` at the optimum)."""
    return np.sin(phi) / (1.0 + e * np.sin(phi)) ** 2


def barrier_slope(phi: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The derivative of :func:`barrier_integrand`, ``cos(phi) (1 - e sin(phi)) / (1 + e sin(phi))^3``."""
    return np.cos(phi) * (1.0 - e * np.sin(phi)) / (1.0 + e * np.sin(phi)) ** 3


def barrier_change(start: np.ndarray, end: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``(psi*(Z(end)) - psi*(Z(start))) / (A B)``, the integral of :func:`barrier_integrand`
    from ``start`` to ``end`` (computed as one integral: no cancellation between two values)."""
    half = 0.5 * (end - start)
    phi = 0.5 * (end + start) + half * NODES[:, None]
    return half * np.sum(WEIGHTS[:, None] * barrier_integrand(phi, e), axis=0)


def newton_step(
    fixed: np.ndarray, moves: np.ndarray, g: np.ndarray, diagonal: np.ndarray, coupling: np.ndarray
) -> np.ndarray:
    """The Newton step of the tridiagonal Hessian (``diagonal``, ``coupling`` of each face
    with the next) and gradient ``g``, the faces ``fixed`` moved by ``moves``."""
    banded = np.zeros((3, g.size))
    banded[0, 1:] = np.where(fixed[:-1] | fixed[1:], 0.0, coupling)
    banded[1] = np.where(fixed, 1.0, diagonal)
    banded[2, :-1] = banded[0, 1:]
    rhs = np.where(fixed, moves, -g)
    rhs[1:] -= np.where(fixed[:-1] & ~fixed[1:], coupling * moves[:-1], 0.0)
    rhs[:-1] -= np.where(fixed[1:] & ~fixed[:-1], coupling * moves[1:], 0.0)
    return solve_banded((1, 1), banded, rhs)


class NormalStress:
    """The step of the module docstring on the layered columns of ``stresses``; it keeps the
    layers' ``tau_xx`` of its last call for the mean pressure of the next vertical step
    (:meth:`yield_gravity`), a part of the run's state (:meth:`state_dict`)."""

    def __init__(self, stresses: StressModel, fractions: np.ndarray, dx: float, tolerance: float, dry: float):
        self.stresses = stresses
        self.dry = dry
        """The thickness (m) at and below which a column is dry (``numerics.dry_threshold``):
        outside the chains, as the transport keeps it at rest."""
        self.l = fractions[:, None]
        self.dx = dx
        self.tolerance = tolerance
        self.tau_xx: np.ndarray = np.zeros((fractions.size, stresses.x.size))
        """``tau_xx`` (L, N) of the layers in the last step (Pa)."""
        self.relief: np.ndarray = np.zeros(self.tau_xx.shape)
        """``r = tau_xx / P`` (L, N) of the layers in the last step, the mean of their faces':
        their mean pressure is ``P (1 - r)``."""
        self._kept = self.tau_xx, self.relief  # the last step's, while a step is taken

    def __call__(
        self,
        h: np.ndarray,
        ustar: np.ndarray,
        u: np.ndarray,
        yield_gravity: np.ndarray | None,
        dt: float,
        *,
        velocity_scale: float,
        max_iterations: int,
    ) -> None:
        """Apply the step of ``dt`` to ``ustar`` (L, N) in place on the thickness ``h``
        after a vertical step, the rate lagged from the velocities ``u`` at the step's start and the
        pressures ``P`` from ``yield_gravity`` (None: ``g cos(theta)``)."""
        wet = h > self.dry
        L = ustar.shape[0]
        faces = chains(wet, L)
        self.tau_xx, self.relief = np.zeros(ustar.shape), np.zeros(ustar.shape)
        if faces.left.size == 0:
            return
        rho = self.stresses.material.density
        g = self.stresses.g_n if yield_gravity is None else yield_gravity
        interfaces = rho * g * self.stresses.depth_interface * h  # P_k (L, N)
        pbar = 0.5 * (interfaces + np.vstack([interfaces[1:], np.zeros((1, h.size))]))
        spacing = np.where(wet, self.stresses.spacing_fraction * h, 1.0)
        gradient = np.diff(u, axis=0, prepend=0.0) / spacing
        shear = 0.25 * (gradient + np.vstack([gradient[1:], np.zeros((1, h.size))]))  # D_xz, centres
        i, j = faces.left % h.size, faces.right % h.size
        layer = faces.left // h.size
        flat = u.ravel()
        d_xz = 0.5 * np.abs(shear.ravel()[faces.left] + shear.ravel()[faces.right])
        d_xx = (flat[faces.right] - flat[faces.left]) / self.dx
        rate = 2.0 * np.sqrt(d_xx**2 + d_xz**2)
        p = 0.5 * (pbar.ravel()[faces.left] + pbar.ravel()[faces.right])
        hf = 0.5 * (h[i] + h[j])
        x = 0.5 * (self.stresses.x[i] + self.stresses.x[j])
        tau, e = self.bulk_law(rate, p, hf, x, layer)
        a = 2.0 * dt * self.l[layer, 0] * hf * tau
        b = self.dx * d_xz
        mass = (rho * self.l * h * self.dx).ravel()
        present = np.zeros(ustar.size, dtype=bool)  # the cells of the chains, in order
        present[faces.left] = present[faces.right] = True
        cells = np.flatnonzero(present)
        position = np.cumsum(present) - 1
        local = Chains(position[faces.left], position[faces.right], faces.linked)
        new, z = plastic_chain_step(
            ustar.ravel()[cells],
            mass[cells],
            local,
            a,
            b,
            e,
            tolerance=self.tolerance * velocity_scale,
            max_iterations=max_iterations,
            compiled=True,
            where=lambda f: f"x = {x[f]:.6g} m, layer {int(layer[f])}",
        )
        ustar[np.unravel_index(cells, ustar.shape)] = new
        # each cell's tau_xx and r: the means over its faces of Z_f / (2 dt l_a h_f) and of
        # that over the face's pressure (bounded by the law's plastic limits, tau_f / p_f over
        # 1 +- e_f, where a thin cell at a front beside a thick one has P far below its faces')
        per_face = z / (2.0 * dt * self.l[layer, 0] * hf)
        ratio = np.divide(per_face, p, out=np.zeros(p.shape), where=p > 0.0)
        self.tau_xx = self._cell_mean(faces, per_face, ustar.shape)
        self.relief = self._cell_mean(faces, ratio, ustar.shape)

    @staticmethod
    def _cell_mean(faces: Chains, values: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
        """The mean over each cell's faces of the faces' ``values`` (0 off the chains)."""
        n = int(np.prod(shape))
        total = np.bincount(faces.left, values, n) + np.bincount(faces.right, values, n)
        count = np.bincount(faces.left, minlength=n) + np.bincount(faces.right, minlength=n)
        return (total / np.maximum(count, 1.0)).reshape(shape)

    def bulk_law(
        self, rate: np.ndarray, p: np.ndarray, h: np.ndarray, x: np.ndarray, layer: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The bulk law's stress norm ``tau_f`` and ``e_f = d tau / d p`` at the faces' rates
        and pressures ``p`` (0 on a face without pressure, whose stress is the law's at ``p =
        0``), the law asked once at the three pressures of every face.

        ``e_f`` is the sum of the central differences (relative step :data:`PRESSURE_STEP`)
        of the law's two parts, the yield stress ``kappa(p)`` and the viscous stress ``eta
        rate``, each taken apart: a viscous stress that does not depend on the pressure (a
        Drucker-Prager viscosity) then adds nothing, exactly, where the difference of the
        sum ``kappa + eta rate`` would lose ``d kappa / d p`` to its round-off (``eps tau /
        dp``: ``d tau / d p = 1.08`` for ``mu_s = 0.3`` at a thin front sheared at 1e7 1/s,
        ``tau / p = 1e12``).  With its round-off bound (:data:`LAW_ROUNDING`),
        :class:`RunError` where ``|e_f| >= 1`` beyond it (an unbounded passive pressure), or
        where ``|e_f| >= 1`` within it (the law's slope not resolved)."""
        dp = PRESSURE_STEP * p
        pressures = np.concatenate([p, p + dp, p - dp])
        parts = self.stresses.bulk_parts(np.tile(rate, 3), pressures, np.tile(h, 3), np.tile(x, 3))
        (kappa, kappa_up, kappa_down), (viscous, viscous_up, viscous_down) = (
            part.reshape(3, p.size) for part in parts
        )
        step = pressures[p.size : 2 * p.size] - pressures[2 * p.size :]  # exact (Sterbenz)
        change = (kappa_up - kappa_down) + (viscous_up - viscous_down)
        e = np.divide(change, step, out=np.zeros(p.shape), where=step > 0.0)
        sizes = np.abs(kappa_up) + np.abs(kappa_down) + np.abs(viscous_up) + np.abs(viscous_down)
        bound = np.divide(
            LAW_ROUNDING * np.finfo(float).eps * sizes, step, out=np.zeros(p.shape), where=step > 0.0
        )
        steep, unresolved = ~(np.abs(e) < 1.0 + bound), ~(np.abs(e) < 1.0)
        for bad, what in (
            (steep, ""),
            (unresolved, ", not resolved from the round-off of the law's stresses"),
        ):
            if bad.any():
                f = int(np.flatnonzero(bad)[0])
                raise RunError(
                    f"the normal stress needs a bulk law whose stress changes by less than the pressure "
                    f"(|d tau / d p| < 1): d tau / d p = {e[f]:.6g} +- {bound[f]:.3g}{what} at x = "
                    f"{x[f]:.6g} m, layer {int(layer[f])}, pressure {p[f]:.6g} Pa, shear rate "
                    f"{rate[f]:.6g} 1/s, yield stress {kappa[f]:.6g} Pa, viscous stress "
                    f"{viscous[f]:.6g} Pa (model.normal_stress)"
                )
        return kappa + viscous, e

    def yield_gravity(self, yield_gravity: np.ndarray | None, h: np.ndarray) -> np.ndarray:
        """The normal gravity ``G_k (1 - r_k)`` (L, N) of the mean pressures ``p_k = P_k (1 -
        r_k)`` at the interfaces, for the yield pressures ``P_k = rho G_k (h - z_k)`` of
        ``yield_gravity`` (None: ``g cos(theta)``): ``r = tau_xx / P`` of the layers in the last
        step (:attr:`relief`), the mean of the two layers at an interface, the bottom layer's
        at the bed; ``p_k >= 0`` (no tension)."""
        given = self.stresses.g_n if yield_gravity is None else yield_gravity
        g = np.broadcast_to(given, (self.l.size, h.size))
        relief = np.vstack([self.relief[:1], 0.5 * (self.relief[1:] + self.relief[:-1])])
        return g * np.maximum(1.0 - relief, 0.0)

    @contextmanager
    def kept_if_abandoned(self) -> Iterator[None]:
        """The stresses of the last step kept (``tau_xx``, ``relief``) taken back if the
        block raises: the calls of a step that is abandoned (a failure, a stop, Ctrl-C)
        replaced them (every call replaces both arrays, never writes into them).  Within
        the block, :meth:`restart` takes them back for an attempt of the step redone."""
        self._kept = self.tau_xx, self.relief
        try:
            yield
        except BaseException:
            self.restart()
            raise

    def restart(self) -> None:
        """The stresses of the last step kept back (within :meth:`kept_if_abandoned`): an
        attempt of a step redone (shorter, or with more material moving) starts from them,
        as the step taken directly would, not from those of the attempt discarded, whose
        relief the first vertical step's mean pressures read."""
        self.tau_xx, self.relief = self._kept

    def state_dict(self) -> dict[str, np.ndarray]:
        """The relief of the last step (:attr:`relief`): the next vertical step's mean
        pressures, so that a resumed run equals the uninterrupted one bit for bit."""
        return {"normal_stress_relief": self.relief.copy()}

    def load_state(self, saved: dict) -> None:
        """Restore :meth:`state_dict` (none saved: no relief, as at the start of a run);
        :class:`InputError` for a relief that is not finite."""
        relief = np.asarray(saved.get("normal_stress_relief", np.zeros(self.relief.shape)), dtype=float)
        if not np.all(np.isfinite(relief)):
            raise InputError("normal_stress_relief: values that are not finite, where finite numbers")
        self.relief = relief.copy()
