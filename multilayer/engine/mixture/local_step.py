"""The implicit local step of a layered grain–fluid mixture: velocities, dilation and
excess pore pressure of every column (docs/mixture.md, "The mixture in x and in layers").

The mixture moves with one velocity per layer (the drag relaxation, ``rho_s / beta`` ~
1e-5 s for fine grains in a viscous fluid, is far below the step: Bouchut et al. 2025
"velocity equality"; for millimetre beads in water it is ~0.02 s, longer than a step, and
the step is the limit of a stiff drag), under an ambient fluid at rest.  Layer ``a``
(thickness ``h_a = l_a h``) holds the solid volume ``s_a``, ``phi_a = s_a / h_a``.  At
interface ``a`` (below layer ``a``, ``a = 0`` the bed) the shear rate is
``gamma_a = |v_a - v_{a-1}| / (spacing_a h)`` and the closure of Bouchut, Fernández-Nieto,
Mangeney & Narbona-Reina (2016, J. Fluid Mech. 801) gives the layer's dilation rate and the
effective pressure::

    Phi_a = gamma_a K (phi_a - phi_c + K2 eta_f gamma_a / p_s,a)
    p_s,a = P_a - p_e,a,   P_a = (rho_s - rho_f) g cos(theta) sum_{b >= a} s_b
    p_e,a = -sum_{c >= a} D_c h_c W_c,   D_c = beta(phi_c) / (1 - phi_c)^2
    W_c = sum_{b <= c} spacing_b h Phi_b

with ``spacing_b h Phi_b = tan(psi_b) |v_b - v_(b-1)|`` the rise of the grains above
interface ``b`` per unit time (the integral of ``div v = gamma tan(psi)`` across the sheared
zone) and ``W_c`` the grains' rise through layer ``c``: Darcy's law for the fluid that fills
the pores the dilation opens, integrated from the top of the mixture down; for one layer it
is the uniform layer's ``p_e = -beta h^2 Phi / (2 (1 - phi)^2)``.  Every layer's dilation
sets the pore pressure of every interface at or below it: at given velocities the effective
pressures solve one coupled system per column (:meth:`LocalStep.closure`).

The step, backward Euler: the thickness ``h' - h* = dt h' sum_a l_a Phi_a`` (the fluid drawn
from or expelled to the ambient fluid), and the velocities the exact minimiser of the
column problem (``engine/vertical``) with masses ``rho_s s_a + rho_f (fluid before + fluid
after) / 2`` (the fluid joins at rest: the exchange term of the uniform layer's energy
identity), the yield stress and viscosity of the rheology at the effective pressure.  The
pore pressures and ``z = h* / h'`` (Notes) of the whole column are the unknowns of a Newton
iteration with the exact column solve inside; at rest ``gamma = 0``, so ``Phi = 0``, ``p_e =
0``, ``z = 1``, ``h' = h*`` bit for bit: a column held by friction stays at ``v == 0.0``.  In layers
the converged step then moves solid between the layers of each column (and the same volume
of fluid the other way, each carrying its layer's momentum) so that the dilation of each
interface lifts the grains above it, as in the model (:mod:`~multilayer.engine.mixture.exchange`).
With a compressibility ``alpha`` (George & Iverson 2014) each pore pressure relaxes towards
the closure's, ``alpha B_a d_t p_e,a = -(p_e,a + (M Phi)_a)`` with ``B_a = sum_b M_ab``, by
backward Euler in the same iteration (:meth:`LocalStep.closure`).

Continuation in ``dt``: a column whose Newton iteration does not converge (it stalls,
wanders, or runs out of ``numerics.max_iterations``) or diverges is done again as
``k = 2, 4, ...,`` :data:`MAX_SUBSTEPS` successive backward-Euler steps of ``dt / k`` of the
same local relaxation, each solved by the same iteration from the state the one before
reached (over a shorter step the root is nearer its start): a backward Euler of ``k`` steps,
first order in ``dt / k`` (tests/test_mixture_continuation.py); the columns that converge in
one step are never sub-stepped, so their answer is unchanged bit for bit.

Notes
-----
The ratio ``z = h* / h'``.  ``h* / (1 - dt sum_a l_a Phi_a)`` is no thickness where ``dt
sum_a l_a Phi_a >= 1``, as at a thin front sheared fast at a low effective pressure (2.9 at
the front of a loose column 10 m high of 1 cm grains: the run stopped).  ``z = 1 - dt sum_a
l_a Phi_a(h* / z)`` is finite at every trial with pores (outside, an infinite residual: the
line search halves the update), the same root; ``Phi ~ gamma^2 ~ z^2``, no pole in ``z``.

A wandering iteration.  Every Newton update the line search takes lowers the column's
residual norm (it accepts a trial only where the norm falls); the norm rises only where the
line search finds no descent and the pore pressures are bracketed
(:meth:`LocalStep._bisect`). A column whose least norm has not fallen for :data:`WINDOW`
iterations has been sent back above it by the bracketing, and Newton's descent from there
has not come below it again: the iteration cycles between the two without repeating bit for
bit, and would run out of ``numerics.max_iterations``.  It goes to the sub-steps at once, as
a stalled one does.  A column that creeps until the bracketing lands on its root makes a
new least norm every iteration and is left alone.

Conservation holds in sub-steps as in one step: the local step changes the solid of a
layer only by the exchange between the layers of its column, whose fluxes cross interior
interfaces (the column's solid is kept to round-off), and the fluid it draws in or expels
is exchanged with the ambient fluid of the same column only (no flux crosses a face in the
local step): the mixture volume's balance (engine/mixture/flow.py) records that exchange
as the column's final minus its starting thickness, whatever the steps between.

The discrete energy of a column and its inequality, step by step, in every state and any
number of layers: :mod:`multilayer.engine.mixture.exchange` (the exchange between the layers
that charges each interface the model's lift, and the proof).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from multilayer.engine.config import MixtureConfig
from multilayer.engine.mixture.closure import drag as darcy_drag
from multilayer.engine.mixture.exchange import GIVEN, between_layers
from multilayer.engine.mixture.local_kernel import Evaluation, compiled_step, mixture_form
from multilayer.engine.mixture.newton_system import solve_batched
from multilayer.engine.plugin_output import call
from multilayer.engine.state_check import all_finite
from multilayer.engine.vertical.column_solve import solve
from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.engine.vertical.stresses import INTERFACE
from multilayer.errors import InputError, RunError
from multilayer.plugins.contract import Material, MixtureState, Rheology

DERIVATIVE_STEP = 1e-7
"""Relative increment of an unknown for the finite-difference Jacobian of the Newton iteration."""
MAX_HALVINGS = 12
"""Halvings of a Newton update in the backtracking line search."""
BISECTIONS = 50
"""Bisections of the bracket of a pore pressure where the line search finds no descent."""
EXPANSIONS = 30
"""Doublings of the distance to a pore pressure low enough for its interface to hold."""
SWEEPS = 2
"""Gauss–Seidel sweeps over the layers where the line search finds no descent."""
WINDOW = 5
"""Newton iterations without a new least residual norm after which a column's iteration is
taken to wander (it goes to the sub-steps at once): the allowance of Newton's iteration,
sent above its least norm by the bracketing, to come below it again (near a regular root it
converges quadratically, in a few iterations: Dennis & Schnabel 1996, Theorem 5.2.1)."""
MAX_SUBSTEPS = 256
"""Most backward-Euler sub-steps of one local step in a column whose Newton iteration fails
(continuation in ``dt``: 2, 4, ..., 256; the front of a loose column of millimetre beads
in water needed up to 128, at 80 cells)."""
CLOSURE_TOLERANCE = 1e-12
"""Residual of the effective pressures, relative to the largest in the column, at which the
closure of several layers stops (round-off where the terms of ``M Phi`` are ~ p_s)."""
ROUND_OFF = 64 * float(np.finfo(float).eps)
"""Residual of an effective pressure, relative to the size of the terms of its equation
``p_s = P + M Phi(p_s)``, at which the closure of several layers stops too: where the
terms are far larger than ``p_s`` (a loose layer nearly liquefied, the Darcy terms
cancelling to 1e-7 of their size: nine layers at ``phi`` 0.13-0.25 in water on 31
degrees, terms of 4.5e6 Pa for ``p_s`` of 1 Pa), round-off leaves residuals of 3e-11 Pa,
above ``CLOSURE_TOLERANCE`` times ``p_s``, which no iteration can reach.  Where the terms are
~ ``p_s`` this is 1.4e-14 of them, below ``CLOSURE_TOLERANCE``, which then decides."""


@dataclass(frozen=True)
class LocalResult:
    """The local step's result in the columns it was given."""

    u: np.ndarray  # (L, n) layer velocities
    h: np.ndarray  # (n,) mixture thickness after dilation
    pore_pressure: np.ndarray  # (L, n) excess pore pressure at the bottom of each layer (Pa)
    iterations: int
    solid: np.ndarray  # (L, n) solid volume per unit area of each layer after the exchange
    solved: np.ndarray  # (L, n) velocities of the column solve, before the exchange (of the last sub-step)


class LocalStep:
    """The local step of the mixture ``config`` in columns of layer fractions ``fractions``
    (bulk rheology ``law``, ``material.particle_density`` the grain density)."""

    def __init__(
        self,
        config: MixtureConfig,
        law: Rheology,
        material: Material,
        fractions: np.ndarray,
        g_n: float,
        tolerance: float,
        max_iterations: int,
    ):
        if law.uses:
            raise InputError(
                f"rheology {law.name}: a law that uses {', '.join(law.uses)} is not available with a fluid; "
                f"accepted: a law without 'uses' (dilatant_coulomb, drucker_prager, ...)"
            )
        self.config, self.law, self.material = config, law, material
        self.l = np.asarray(fractions, dtype=float)[:, None]
        self.spacing = 0.5 * (self.l + np.concatenate([[[0.0]], self.l[:-1]]))  # h_0/2 at the bed
        self.rho_s, self.rho_f = material.particle_density, config.fluid_density
        self.buoyant_g_n = (self.rho_s - self.rho_f) * g_n
        self.tolerance, self.max_iterations = tolerance, max_iterations
        self.compressibility = config.compressibility
        self.form = mixture_form(law, material, config)

    def masses(self, solid: np.ndarray, h: np.ndarray) -> np.ndarray:
        """``rho_s s_a + rho_f (l_a h - s_a)`` (kg/m^2): the layer masses at thickness ``h``."""
        return self.rho_s * solid + self.rho_f * (self.l * h - solid)

    def drag(self, phi: np.ndarray) -> np.ndarray:
        """``beta = kozeny eta_f phi^2 / (d^2 (1 - phi))`` (Pa s/m^2): Darcy's law with the
        Carman–Kozeny permeability (:func:`multilayer.engine.mixture.closure.drag`)."""
        return darcy_drag(self.config.kozeny, self.config.fluid_viscosity, self.material.grain_diameter, phi)

    def closure(
        self,
        solid: np.ndarray,
        h: np.ndarray,
        v: np.ndarray,
        previous: np.ndarray | None = None,
        lag: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The closure of columns of thickness ``h`` (n,) moving with the layer velocities
        ``v`` (L, n), solved exactly: the shear rates, the effective pressures, the dilation
        rates and the excess pore pressures (all (L, n)).

        The pore pressures are linear in the dilation rates, ``p_e = -M Phi`` (``M >= 0``,
        the integral from the top down: :meth:`darcy`), and ``Phi_b = gamma_b K (phi_b - phi_c) + C_b /
        p_s,b`` with ``C_b = K K2 eta_f gamma_b^2``: the effective pressures solve
        ``p_s = P + M Phi(p_s)``, for one layer the quadratic of the uniform layer (whose
        non-negative root starts the iteration), for several a Newton iteration that keeps
        ``p_s > 0`` where ``C > 0`` (the system's map is decreasing in ``p_s``: one root).

        With ``previous`` (L, n) (a compressibility) each pore pressure is a backward-Euler
        step of its own relaxation from ``previous``, ``alpha B_a (p_e,a - previous_a) / dt =
        -(p_e,a + (M Phi)_a)`` with ``lag = alpha / dt``, ``t_IG,a = alpha B_a`` and
        ``B_a = sum_b M_ab`` (the pore pressure at interface ``a`` per unit dilation rate of the
        whole column; at the bed of a uniform column the uniform layer's ``B`` in any number
        of layers): row ``a`` of ``M`` divided by ``1 + r_a`` and ``P_a`` lowered by
        ``r_a previous_a / (1 + r_a)``, ``r_a = lag B_a``; for one layer the quadratic of
        :func:`multilayer.engine.mixture.closure.basal_closure`."""
        cfg, L = self.config, self.l.shape[0]
        phi = solid / (self.l * h)
        gamma = np.abs(np.diff(v, axis=0, prepend=0.0)) / (self.spacing * h)
        weight = self.buoyant_g_n * np.cumsum(solid[::-1], axis=0)[::-1]
        M = self.darcy(solid, h)
        base = weight
        if previous is not None:
            ratio = lag * M.sum(axis=1)
            M = M / (1.0 + ratio)[:, None, :]
            base = weight - previous * ratio / (1.0 + ratio)
        linear = gamma * cfg.dilatancy * (phi - cfg.phi_critical)
        C = cfg.dilatancy * cfg.critical_shift * cfg.fluid_viscosity * gamma * gamma
        A = base + np.einsum("abn,bn->an", M, linear)
        diagonal = np.einsum("aan->an", M)
        root = np.sqrt(A * A + 4.0 * diagonal * C)
        positive = np.where(
            A >= 0.0, 0.5 * (A + root), 2.0 * diagonal * C / np.where(root - A > 0.0, root - A, 1.0)
        )
        p_s = np.where(diagonal * C > 0.0, positive, np.maximum(A, 0.0))
        if L > 1:
            p_s = self._coupled(p_s, base, M, linear, C, weight[0], polish=previous is not None)
        _finite(p_s)
        contact = p_s > 0.0
        dilation = linear + np.where(contact, C / np.where(contact, p_s, 1.0), 0.0)
        pore_pressure = weight - p_s
        return gamma, p_s, dilation, pore_pressure

    def darcy(self, solid: np.ndarray, h: np.ndarray) -> np.ndarray:
        """``M`` (L, L, n) of the columns holding ``solid`` (L, n) at thickness ``h`` (n,):
        ``M[a, b]`` is minus the excess pore pressure at the bottom of layer ``a`` per unit
        dilation rate of layer ``b`` (Pa s), Darcy's law integrated from the top down with
        ``D_c = beta(phi_c) / (1 - phi_c)^2``: the dilation of interface ``b`` raises the
        grains above it by ``spacing_b h Phi_b`` (its ``tan(psi_b) |v_b - v_(b-1)|``), and the
        fluid that fills the pores it opens crosses every layer ``c >= b``,
        ``M[a, b] = spacing_b h sum_(c >= max(a, b)) D_c h_c``
        (:mod:`~multilayer.engine.mixture.exchange`).  For one layer
        ``beta h^2 / (2 (1 - phi)^2)``, the uniform layer's; ``M`` is a positive symmetric
        matrix times the positive diagonal ``spacing h``."""
        thickness = self.l * h
        phi = solid / thickness
        Dh = self.drag(phi) / (1.0 - phi) ** 2 * thickness
        tail = np.cumsum(Dh[::-1], axis=0)[::-1]  # sum_(c >= a) D_c h_c
        L = thickness.shape[0]
        rise = self.spacing * h  # spacing_b h: the rise per unit dilation rate of interface b
        M = np.empty((L, L, h.size))
        for a in range(L):
            for b in range(L):
                M[a, b] = rise[b] * tail[max(a, b)]
        return M

    def exchange(
        self, solid: np.ndarray, h: np.ndarray, v: np.ndarray, dilation: np.ndarray, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:func:`multilayer.engine.mixture.exchange.between_layers` of these columns: the
        solid and velocities after the exchange, and where it was kept (n,)."""
        return between_layers(
            solid, h, v, dilation, dt, self.l, self.spacing, self.buoyant_g_n, self.rho_s, self.rho_f
        )

    def _coupled(
        self,
        p_s: np.ndarray,
        base: np.ndarray,
        M: np.ndarray,
        linear: np.ndarray,
        C: np.ndarray,
        bed: np.ndarray,
        polish: bool = False,
    ) -> np.ndarray:
        """Newton's iteration for ``p_s = base + M Phi(p_s)`` (``base = P`` but for a relaxing
        pore pressure) from ``p_s`` (each layer's own root, the other layers' viscous shift
        left out), halving a step that would make an effective pressure with ``C > 0``
        non-positive; ``bed`` (n,) the buoyant weight of the column, the scale of its tolerance.
        With ``polish`` (a relaxing pore pressure) one more step once within the tolerance: the
        backward-Euler equation of the relaxation is then solved to round-off."""
        viscous = C > 0.0
        L = p_s.shape[0]
        identity = np.eye(L)[None]
        polished = not polish
        for _ in range(self.max_iterations):
            x = np.where(viscous, p_s, 1.0)
            shift = np.where(viscous, C / x, 0.0)
            residual = p_s - base - np.einsum("abn,bn->an", M, linear + shift)
            terms = np.einsum("abn,bn->an", M, np.abs(linear + shift))  # M >= 0: the sum's size
            floor = ROUND_OFF * np.maximum(terms, np.abs(base))  # what round-off leaves of it
            scale = CLOSURE_TOLERANCE * np.maximum(np.abs(p_s).max(axis=0), bed)
            if np.all(np.abs(residual) <= np.maximum(scale, floor)):
                if polished:
                    return p_s
                polished = True
            jacobian = identity + np.transpose(M * np.where(viscous, C / (x * x), 0.0)[None], (2, 0, 1))
            step = np.linalg.solve(jacobian, -residual.T[..., None])[..., 0].T
            _finite(step)  # a step that is not finite would be halved for ever
            trial = p_s + step
            while np.any(viscous & ~(trial > 0.0)):
                step = np.where(viscous & ~(trial > 0.0), 0.5 * step, step)
                trial = p_s + step
            p_s = trial
        raise RunError(
            f"the mixture's closure did not converge in {self.max_iterations} iterations "
            f"(numerics.max_iterations)"
        )

    def _state(self, solid: np.ndarray, h: np.ndarray, pore_pressure: np.ndarray) -> MixtureState:
        cfg = self.config
        phi = solid / (self.l * h)
        return MixtureState(
            phi, pore_pressure, cfg.fluid_viscosity, cfg.phi_critical, cfg.dilatancy, cfg.critical_shift
        )

    def __call__(
        self,
        solid: np.ndarray,
        h_star: np.ndarray,
        ustar: np.ndarray,
        dt: float,
        guess: np.ndarray | None = None,
        pressure_guess: np.ndarray | None = None,
        *,
        x: np.ndarray | None = None,
        t: float = 0.0,
        substeps: int = 1,
        watch: np.ndarray | None = None,
        previous: np.ndarray | None = None,
    ) -> LocalResult:
        """The step of columns holding ``solid`` (L, n) after transport to ``h_star`` (n,),
        velocities ``ustar`` (L, n) (the buoyant weight along the slope included), the
        iteration started from the velocities ``guess`` and the excess pore pressures
        ``pressure_guess`` (default: at rest); ``x`` (n,) and ``t`` place the columns in
        the messages of the checked plugin calls.  With a compressibility, ``previous`` (L, n)
        is the pore pressure the relaxation starts from (:meth:`closure`).

        The step is ``substeps`` successive backward-Euler steps of ``dt / substeps`` (one
        by default), each from the state the one before reached (its velocities, thickness
        and pore pressures the next one's start and guess), each solved by :meth:`_newton`.
        A column whose iteration does not converge or diverges in one of them is done again
        from the start in twice as many (continuation in ``dt``: over a shorter step the
        root lies nearer its start), up to :data:`MAX_SUBSTEPS`; the other columns keep
        their result, so a column that converges in one step is never sub-stepped.

        ``watch`` (n,) marks columns at rest whose start ends the caller's use of the step
        (the simulation redoes its time step with them moving: docs/mixture.md, "Columns
        set moving").  If the first evaluation, at the guess, gives one of them a non-zero
        velocity, the step stops there: its result is that evaluation's (velocities,
        thickness, pore pressures; one iteration) in every column, and nothing else is
        solved.  Otherwise the watch changes nothing: a watched column whose velocities
        are zero at a pore-pressure guess of zero has converged at rest (its residual is
        zero, bit for bit)."""
        where = np.zeros(h_star.size) if x is None else x
        n = h_star.size
        u, h, s = ustar.copy(), h_star.copy(), solid.copy()
        solved = ustar.copy()
        velocities = np.zeros_like(ustar) if guess is None else guess.copy()
        pressure = np.zeros_like(ustar) if pressure_guess is None else pressure_guess.copy()
        start_pressure = None if previous is None else previous.copy()
        going, iterations = np.arange(n), 0
        failed, diverged, crowded = (np.zeros(n, dtype=bool) for _ in range(3))
        closure_error: RunError | None = None
        for j in range(substeps):
            if not going.size:
                break
            result, converged, burst, error, full = self._newton(
                s[:, going], h[going], u[:, going], dt / substeps, velocities[:, going],
                pressure[:, going], where[going], t + j * (dt / substeps), watch if j == 0 else None,
                None if start_pressure is None else start_pressure[:, going],
            )  # fmt: skip
            iterations += result.iterations
            done = going[converged]
            u[:, done], h[done] = result.u[:, converged], result.h[converged]
            s[:, done], solved[:, done] = result.solid[:, converged], result.solved[:, converged]
            pressure[:, done] = result.pore_pressure[:, converged]
            velocities[:, done] = u[:, done]
            if start_pressure is not None:
                start_pressure[:, done] = pressure[:, done]
            failed[going[~converged]], diverged[going[burst]] = True, True
            crowded[going[full]] = True
            closure_error = error or closure_error
            going = done
        k = np.flatnonzero(failed)
        if k.size and 2 * substeps > MAX_SUBSTEPS:
            column = np.flatnonzero(diverged if diverged.any() else failed)[0]
            raise self._failure(where[column], t, bool(diverged.any()), closure_error, bool(crowded[column]))
        if k.size:
            start = (None if given is None else given[:, k] for given in (guess, pressure_guess))
            again = self(
                solid[:, k], h_star[k], ustar[:, k], dt, *start, x=where[k], t=t, substeps=2 * substeps,
                previous=None if previous is None else previous[:, k],
            )  # fmt: skip
            u[:, k], h[k], pressure[:, k] = again.u, again.h, again.pore_pressure
            s[:, k], solved[:, k] = again.solid, again.solved
            iterations += again.iterations
        return LocalResult(u, h, pressure, iterations, s, solved)

    def _failure(
        self, x: float, t: float, diverged: bool, closure_error: RunError | None, crowded: bool = False
    ) -> RunError:
        """The error of a local step that failed at ``x`` from ``t`` in up to
        :data:`MAX_SUBSTEPS` sub-steps, ``diverged`` where a trial pore pressure was not finite
        or its closure failed (``closure_error``, the closure's own message, if it did),
        ``crowded`` where its exchange between the layers would take more than :data:`GIVEN`
        of a layer's solid or fluid (:meth:`exchange`)."""
        place = f"(at x = {x:.6g} m, t = {t:.6g} s; also in up to {MAX_SUBSTEPS} sub-steps)"
        if crowded and not diverged:
            return RunError(
                f"the mixture's local step would move more than {GIVEN:.0%} of a layer's solid or fluid "
                "between the layers of a column (an explicit exchange that large overshoots: its "
                f"packings could leave (0, 1)) {place}"
            )
        cfg = self.config  # the Newton steps scale with the closure's coefficients: name them as given
        coefficients = (
            "its Newton steps scale with the closure's coefficients: the Darcy drag kozeny eta_f phi^2 / "
            f"(d^2 (1 - phi)) of fluid.viscosity = {cfg.fluid_viscosity:g}, material.grain_diameter = "
            f"{self.material.grain_diameter:g} and mixture.kozeny = {cfg.kozeny:g}, and "
            f"mixture.dilatancy = {cfg.dilatancy:g} and mixture.critical_shift = {cfg.critical_shift:g}"
        ) + (
            f", with the relaxation of fluid.compressibility = {self.compressibility:g} 1/Pa"
            if self.compressibility is not None
            else ""
        )
        if diverged and closure_error is not None:
            return RunError(f"{closure_error} ({coefficients}) {place}")
        if diverged:
            return RunError(
                "the mixture's local step diverged: a trial excess pore pressure is not finite "
                f"({coefficients}) {place}"
            )
        return RunError(
            f"the mixture's local step did not converge ({coefficients}): its Newton iteration stalled, "
            f"wandered or ran out of numerics.max_iterations = {self.max_iterations} {place}"
        )

    def _newton(
        self,
        solid: np.ndarray,
        h_star: np.ndarray,
        ustar: np.ndarray,
        dt: float,
        guess: np.ndarray,
        pressure_guess: np.ndarray,
        where: np.ndarray,
        t: float,
        watch: np.ndarray | None = None,
        previous: np.ndarray | None = None,
    ) -> tuple[LocalResult, np.ndarray, np.ndarray, RunError | None, np.ndarray]:
        """One backward-Euler step of ``dt`` of the columns (the arguments of
        :meth:`__call__`; ``watch``: see there): its result, where it converged, where it
        diverged (n,) (a trial excess pore pressure not finite, or a trial state whose
        closure failed), the closure's error if one did, and where the converged step's
        exchange between the layers would take more than :data:`GIVEN` of a layer's solid or
        fluid (n,; those columns count as not converged: :meth:`exchange`).  A column that diverges leaves
        the iteration, unconverged, as does one whose iterate comes back to where it
        started, bit for bit (the iteration would repeat itself), or whose least residual
        norm has not fallen for :data:`WINDOW` iterations (it wanders; module notes).

        A Newton iteration on the unknowns of the whole column at once, ``X = (p_e, z)``
        (its ``L`` excess pore pressures and the ratio ``z = h* / h'`` of its thickness:
        module notes): at trial values the rheology at the effective pressures at ``h* /
        z`` gives the velocities by the exact column solve, the closure gives the pore
        pressures and the ratio ``1 - dt sum_a l_a Phi_a`` these velocities create
        (:meth:`closure`), and the Jacobian of the difference ``R(X)`` (by finite
        differences, one column solve per unknown; the columns are independent) gives the
        next trial, with a backtracking line search per column.  In columns of one layer
        under a law of a compiled form the map and the iteration run in the compiled kernels
        of :mod:`~multilayer.engine.mixture.local_kernel`, equal to this numpy reference bit
        for bit, which iterates wherever they hand the step back.
        Where the line search finds no descent (at the onset of a contracting packing ``R``
        has a kink where the column starts moving; a flowing branch can end in a fold), the
        pore pressures are bracketed one by one (:meth:`_bisect`) and the iteration goes on from there.

        With ``previous`` (a relaxing pore pressure) a column whose velocity guess is zero
        starts from its rest state, the pore pressure ``previous`` relaxes to at rest
        (:meth:`closure` at zero velocity), where a column that holds has converged exactly.

        Notes
        -----
        One relaxing layer: ``h' - h* = -dt h' p_e' / B'`` (George & Iverson 2014; at rest it consolidates, to
        the tolerance), with :meth:`closure`'s relaxation (the system: ``UniformLayer``); layers: ``Phi``."""
        L, n = ustar.shape
        m_before = self.masses(solid, h_star)
        momentum = m_before * ustar
        weight = self.buoyant_g_n * np.cumsum(solid[::-1], axis=0)[::-1]
        scale = np.concatenate([np.maximum(weight, np.finfo(float).tiny), np.ones((1, n))])
        filled = np.max(solid / self.l, axis=0)  # the thickness at which a layer's packing is 1: z's bound
        pores = np.divide(h_star, filled, out=np.full(n, np.inf), where=filled > 0.0)
        velocities = guess
        gamma = np.zeros_like(ustar)
        diverged, stalled, wandering = (np.zeros(n, dtype=bool) for _ in range(3))
        closure_errors: list[RunError] = []

        def law(method: str, k: np.ndarray, *args: object) -> np.ndarray:
            """The rheology's ``method`` in the columns ``k`` (its pressure argument is
            third from the end of ``args``), checked (engine/plugin_output.py)."""
            inputs = {"pressure": np.asarray(args[-3])}
            return call(self.law, method, args, inputs=inputs, x=where[k], position=INTERFACE, t=t)

        def evaluate(X: np.ndarray, k: np.ndarray) -> Evaluation:
            """At the trial ``X = (p_e, z)`` (L + 1, len(k)) of the columns ``k``; a column
            whose trial pore pressures are not finite is marked diverged, its residual
            infinite, and not evaluated (the rheology is never handed them), as is, unmarked,
            one whose ratio no thickness with pores has; where the
            closure fails, the columns are evaluated one by one and those whose closure
            fails are marked diverged."""
            if compiled is not None and (found := compiled.map(X, k, velocities)) is not None:
                return found  # one layer under a law of a compiled form (engine/mixture/local_kernel.py)
            burst = ~np.isfinite(X[:L]).all(axis=0)
            outside = ~((X[L] > 0.0) & (X[L] < pores[k]))  # a ratio no thickness with pores has
            if burst.any() or outside.any():
                diverged[k[burst]] = True
                fine = np.flatnonzero(~burst & ~outside)
                blank = Evaluation.diverged(X)
                return blank.merge(fine, evaluate(X[:, fine], k[fine])) if fine.size else blank
            p, h = X[:L], h_star[k] / X[L]
            s = solid[:, k]
            p_s = weight[:, k] - p
            state = self._state(s, h, p)
            kappa = law("mixture_yield_stress", k, p_s, state, self.material)
            eta = law("mixture_viscosity", k, gamma[:, k], p_s, state, self.material)
            m = 0.5 * (m_before[:, k] + self.masses(s, h))
            free = np.zeros_like(m)
            problem = ColumnProblem(
                m=m, ustar=momentum[:, k] / m, dt=dt, kappa=kappa, c=eta / (self.spacing * h), w=free, cw=free
            )
            v = solve(problem, velocities[:, k])
            try:  # a trial state may overflow the closure: _finite and the residual check it
                with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
                    rates, _, dilation, pressure = self.closure(
                        s, h, v, None if previous is None else previous[:, k], lag
                    )
            except RunError as error:  # at a trial state: the run stopped here before sub-steps
                if k.size > 1:
                    return Evaluation.join([evaluate(X[:, [c]], k[[c]]) for c in range(k.size)])
                diverged[k] = True
                closure_errors.append(error)
                return Evaluation.diverged(X)
            dilation = -pressure / self.darcy(s, h)[0] if drains else dilation  # the Darcy outflow (Notes)
            growth = 1.0 - dt * np.sum(self.l * dilation, axis=0)
            h_new = np.where(growth > 0.0, h_star[k] / np.where(growth > 0.0, growth, 1.0), np.inf)
            residual = (X - np.concatenate([pressure, growth[None, :]])) / scale[:, k]
            residual = np.where(np.isfinite(residual), residual, np.inf)
            return Evaluation(v, rates, pressure, h_new, dilation, residual, np.abs(residual).max(axis=0))

        def viscosity(X: np.ndarray, k: np.ndarray, rates: np.ndarray) -> np.ndarray:
            """The rheology's viscosity at the accepted iterate ``X`` of the columns ``k`` and
            the shear rates ``rates``: where it changes with the rates, the map ``R`` changes
            with them (a mu(I) law; the viscosity is taken at the last iterate's rates)."""
            p, s = X[:L], solid[:, k]
            state = self._state(s, h_star[k] / X[L], p)
            return law("mixture_viscosity", k, rates, weight[:, k] - p, state, self.material)

        lag, drains = 0.0, previous is not None and L == 1  # one relaxing layer drains (Notes)
        if previous is not None:
            lag = self.compressibility / dt if self.compressibility is not None else 0.0
            rest = self.closure(solid, h_star, np.zeros_like(ustar), previous, lag)[3]
            pressure_guess = np.where(np.any(guess != 0.0, axis=0), pressure_guess, rest)
        controls = (
            *(self.tolerance, self.max_iterations, DERIVATIVE_STEP, MAX_HALVINGS),
            *(BISECTIONS, EXPANSIONS, SWEEPS, WINDOW),
        )  # those of iterate_one_layer, in its order
        compiled = compiled_step(
            self,
            (h_star, solid, weight, m_before, momentum),
            scale,
            pores,
            dt,
            lag,
            previous,
            controls,
        )
        X = np.concatenate([pressure_guess, np.ones((1, n))])  # the ratio h* / h' of rest
        now = evaluate(X, np.arange(n))
        if watch is not None and np.any(now.v[:, watch]):  # a watched column starts: the step stops
            result = LocalResult(now.v, now.h, now.pressure, 1, solid, now.v)
            return result, np.ones(n, dtype=bool), diverged, None, np.zeros(n, dtype=bool)
        iterated = None if compiled is None else compiled.iterate(X, now, diverged)
        if iterated is not None:  # one layer under a law of a compiled form: the same iteration, compiled
            now, iteration = iterated
        else:
            best, since = now.norm.copy(), np.zeros(n, dtype=int)  # least norm, iterations since it fell
            iteration = 1
            while (
                k := np.flatnonzero(~(now.norm <= self.tolerance) & ~diverged & ~stalled & ~wandering)
            ).size:
                if iteration > self.max_iterations:
                    break
                iteration += 1
                Xk, here, lagged = X[:, k], now.take(k), gamma[:, k]
                velocities, gamma = now.v, now.rates
                moved = np.flatnonzero(~_same(viscosity(Xk, k, lagged), viscosity(Xk, k, gamma[:, k])))
                if moved.size:  # the map at the new shear rates: that of the Jacobian and line search
                    here = here.merge(moved, evaluate(Xk[:, moved], k[moved]))
                jacobian = np.empty((k.size, L + 1, L + 1))
                for j in range(L + 1):
                    step = DERIVATIVE_STEP * np.maximum(np.abs(Xk[j]), scale[j, k])
                    trial = Xk.copy()
                    trial[j] += step
                    with np.errstate(invalid="ignore"):  # inf - inf: a trial with no thickness, next diverged
                        jacobian[:, :, j] = ((evaluate(trial, k).residual - here.residual) / step).T
                update = solve_batched(jacobian, -here.residual.T).T
                fraction = np.ones(k.size)
                for _ in range(MAX_HALVINGS):
                    trial = Xk + fraction * update
                    attempt = evaluate(trial, k)
                    better = (attempt.norm < here.norm) | (attempt.norm <= self.tolerance)
                    if better.all():
                        break
                    fraction = np.where(better, fraction, 0.5 * fraction)
                stuck = np.flatnonzero(~better & ~diverged[k])
                if stuck.size:
                    trial[:, stuck], found = self._bisect(
                        evaluate, Xk[:, stuck], k[stuck], weight[:, k[stuck]]
                    )
                    attempt = attempt.merge(stuck, found)
                # back where it started, bit for bit: the iteration would repeat itself, never converging
                stalled[k] = _same(trial, Xk) & _same(attempt.v, here.v) & _same(attempt.rates, here.rates)
                X[:, k] = trial
                now = now.merge(k, attempt)
                best[k], since[k] = _progress(best[k], since[k], now.norm[k])
                wandering[k] = since[k] >= WINDOW
        converged = (now.norm <= self.tolerance) & ~diverged
        error = closure_errors[0] if closure_errors else None
        u, moved, crowded = now.v, solid, np.zeros(n, dtype=bool)
        if L > 1:  # the lift of each interface's dilation (engine/mixture/exchange.py)
            moved, u, fine = self.exchange(solid, now.h, now.v, now.dilation, dt)
            crowded = converged & ~fine
            converged &= fine
        result = LocalResult(u, now.h, now.pressure, iteration, moved, now.v)
        return result, converged, diverged, error, crowded

    @staticmethod
    def _bisect(
        evaluate: Callable[[np.ndarray, np.ndarray], Evaluation],
        X: np.ndarray,
        k: np.ndarray,
        weight: np.ndarray,
    ) -> tuple[np.ndarray, Evaluation]:
        """Nonlinear Gauss–Seidel sweeps over the pore pressures of the columns ``k``, each
        component ``a`` the root of its own residual ``R_a`` by bisection, the others held:
        ``R_a >= 0`` at the liquefied ``p_e,a = P_a`` (no contact at interface ``a``) and
        ``R_a < 0`` for pore pressures low enough that interface ``a`` holds.  For one
        layer this is a root of the step; for several it is where Newton's iteration
        goes on."""
        L = weight.shape[0]
        X = X.copy()
        for _ in range(SWEEPS):
            for a in range(L):

                def r(value: np.ndarray, a: int = a) -> np.ndarray:
                    trial = X.copy()
                    trial[a] = value
                    return evaluate(trial, k).residual[a]

                start = r(X[a])
                up = start < 0.0
                low = np.where(up, X[a], X[a] - weight[0])
                high = np.where(up, weight[a], X[a])
                for _ in range(EXPANSIONS):
                    held = up | (r(low) < 0.0)
                    if held.all():
                        break
                    low = np.where(held, low, low - 2.0 * (high - low))
                for _ in range(BISECTIONS):
                    middle = 0.5 * (low + high)
                    negative = r(middle) < 0.0
                    low, high = np.where(negative, middle, low), np.where(negative, high, middle)
                X[a] = high
        return X, evaluate(X, k)


def _progress(best: np.ndarray, since: np.ndarray, norm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least residual norms ``best`` of the columns and the iterations ``since`` they
    last fell, after an iteration that reached the norms ``norm``."""
    return np.minimum(best, norm), np.where(norm < best, 0, since + 1)


def _same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per column (axis 1), whether ``a`` and ``b`` are equal bit for bit in every layer."""
    return (a == b).all(axis=0)


def _finite(values: np.ndarray) -> None:
    """Stop the run if the closure's effective pressures (or their Newton step) are not
    finite: its coefficients overflowed (the drag, ``K``, ``K2``), never a fault of the
    rheology given them."""
    if not all_finite(values):
        raise RunError(
            "the mixture's closure overflowed: its effective pressures are not finite numbers "
            "(they scale with the Darcy drag kozeny eta_f phi^2 / (d^2 (1 - phi)) of fluid.viscosity, "
            "material.grain_diameter and mixture.kozeny, and with mixture.dilatancy and "
            "mixture.critical_shift)"
        )
