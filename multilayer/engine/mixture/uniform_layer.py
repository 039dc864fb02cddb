"""The uniform immersed layer: a saturated granular layer of uniform thickness on a plane
tilted at ``t = 0``, under a fluid at rest (Pailha, Nicolas & Pouliquen 2008, Phys. Fluids
20; the depth-averaged model of Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina 2016,
J. Fluid Mech. 801, in its uniform configuration).

In the frame of the engine (``x`` downslope, ``theta > 0``), with ``M = phi h`` the solid
volume per unit area, ``P = M (rho_s - rho_f) g cos(theta)`` and
``F = M (rho_s - rho_f) g sin(theta)`` the buoyant weight of the grains and its downslope
part, the unknowns ``h`` (mixture thickness), ``v`` and ``u`` (solid and interstitial
fluid velocities) obey

```text
d_t h                   = h Phi                                        (phi = M / h)
rho_s M d_t v           = F - tau_b sgn(v) + beta h (u - v)
rho_f (h - M) d_t u     = -(rho_f h Phi / 2 + k_b) u - beta h (u - v)
```

with the closure of :mod:`~multilayer.engine.mixture.closure` (with a compressibility,
``d_t h = -h p_e / B``, the Darcy outflow: :class:`UniformLayer`); ``sgn`` is multivalued at
``v = 0`` (the layer is held while ``|F + beta h (u - v)| <= tau_b(v = 0)``).  The fluid
layer above takes the fluid the mixture expels: ``h + h_f`` is constant.

**The time step** is backward Euler in ``(h, v, u)``, with the fluid's inertia written
``((m_f^n + m_f^{n+1})/2) u^{n+1} - m_f^n u^n`` (``m_f = rho_f (h - M)``), the discrete form of
the exchange ``rho_f h Phi u / 2`` that makes the energy identity exact
(:func:`UniformLayer.energy`).  The drag is linear in ``u^{n+1}``, which is eliminated: it
becomes an added mass of the solid, so the stiff relaxation (``rho_s / beta`` ~ 1e-5 s in
the laboratory) is solved exactly for any step.  Rest is decided exactly, as the
multivalued ``sgn`` of the dry engine's vertical step: at ``v = 0`` the dilation vanishes,
so ``h`` is kept bit for bit (with a compressibility, while no pore pressure drains) and
the layer stays at ``v == 0.0`` iff the force is within the static threshold.  Otherwise
the two remaining scalar equations for ``(h, |v|)`` are solved by a damped Newton
iteration, with a bracketing solve as fallback.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from multilayer.engine.mixture.closure import (
    BasalClosure,
    MixtureMaterial,
    basal_closure,
    closure_at,
    darcy_coefficient,
)
from multilayer.errors import InputError, RunError

GRAVITY = 9.81
NEWTON_TOLERANCE = 4.0 * np.finfo(float).eps
"""Relative change of ``h`` and ``|v|`` at which the Newton iteration of a step has converged."""
NEWTON_ITERATIONS = 60
ROUND_OFF = 8.0 * np.finfo(float).eps
"""Scaled residual of the step's equations below which they hold to round-off."""
FD_STEP = 1e-7
"""Relative increment of the finite-difference Jacobian."""


@dataclass(frozen=True)
class LayerState:
    """State of the uniform layer: time, thickness ``h`` (m), solid and fluid velocities
    ``v``, ``u`` (m/s, downslope), the distance ``x`` (m) the grains have travelled and,
    with a compressibility, the basal excess pore pressure ``p_e`` (Pa; without one it is
    the closure's and this field is not used)."""

    t: float
    h: float
    v: float
    u: float
    x: float = 0.0
    p_e: float = 0.0  # excess pore pressure at the bed (Pa): a state with a compressibility


@dataclass(frozen=True)
class Trajectory:
    """A run of the uniform layer, one entry per step (the initial state first)."""

    t: np.ndarray
    h: np.ndarray
    v: np.ndarray
    u: np.ndarray
    x: np.ndarray
    phi: np.ndarray
    p_e: np.ndarray  # excess pore pressure at the bed (Pa)
    energy: np.ndarray  # UniformLayer.energy (J/m2)


@dataclass(frozen=True)
class UniformLayer:
    """A layer of thickness ``h0`` and volume fraction ``phi0`` at rest on a plane tilted at
    ``slope_deg``; ``k_b`` (Pa s/m) is the Navier friction of the pore fluid on the bed.

    ``compressibility`` ``alpha`` (1/Pa), if given, makes the basal excess pore pressure a
    state that relaxes to the closure's value, ``alpha d_t p_e = -p_e / B - Phi`` with
    ``B = beta h^2 / (2 (1 - phi)^2)``, over ``t_IG = alpha B`` (the pressure equation of
    George & Iverson 2014, Proc. R. Soc. A 470, 20130820, as compared by Bouchut et al.
    2016), and the thickness changes by the fluid that pore pressure drives out through the
    pores, ``d_t h = -h p_e / B = h (Phi + alpha d_t p_e)`` (George & Iverson's dilation
    rate: the dilatancy and the skeleton's elastic change); ``None`` is the closure of
    Bouchut et al. (2016), ``p_e = -B Phi`` at once and ``d_t h = h Phi``.

    Notes
    -----
    The step with a compressibility, backward Euler from ``(h, v, u, p_e)`` with
    ``r' = alpha B' / dt``::

        (1 + r') p_e' = r' p_e - B' Phi(h', |v'|, P - p_e')
        h' - h = -dt h' p_e' / B'          (= dt h' Phi' + alpha h' (p_e' - p_e))

    and the momentum equations of the module docstring.  Held at rest (``Phi = 0``),
    ``p_e' = p_e r' / (1 + r')`` and ``h' = h / (1 + dt p_e' / B')``: the layer consolidates
    as a positive pore pressure drains (swells as a negative one draws fluid in), at
    ``v == 0.0``; with ``p_e = 0`` its state is kept bit for bit.  The energy
    ``E + alpha h p_e^2 / 6`` (:meth:`energy`) obeys, exactly,
    ``E' - E = -dt D' - alpha dt h' Phi' (p_e'^2 - p_e^2) / 6 - (numerical dissipation)
    + (P / 2 + alpha p_e^2 / 6) alpha h' (p_e' - p_e)``: the last term, the elastic part of
    the volume change working against the grains' weight and the pore energy, has either
    sign, so no energy inequality is proven (in the tested runs it decreases at every step)."""

    material: MixtureMaterial
    slope_deg: float
    h0: float
    phi0: float
    k_b: float = 0.0
    gravity: float = GRAVITY
    compressibility: float | None = None

    def __post_init__(self) -> None:
        for name in ("slope_deg", "h0", "phi0", "k_b", "gravity"):
            value = getattr(self, name)
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise InputError(f"uniform layer: {name} = {value!r} is not a finite number")
        alpha = self.compressibility
        if alpha is not None and not (
            isinstance(alpha, int | float) and math.isfinite(alpha) and alpha > 0.0
        ):
            raise InputError(
                f"uniform layer: compressibility = {alpha!r}; accepted: a finite number > 0 (1/Pa)"
            )
        checks = (
            (0.0 <= self.slope_deg < 90.0, "slope_deg", "in [0, 90) (degrees)"),
            (self.h0 > 0.0, "h0", "> 0 (m)"),
            (0.0 < self.phi0 < 1.0, "phi0", "in (0, 1)"),
            (self.k_b >= 0.0, "k_b", ">= 0 (Pa s/m)"),
            (self.gravity > 0.0, "gravity", "> 0 (m/s2)"),
        )
        for ok, name, accepted in checks:
            if not ok:
                raise InputError(f"uniform layer: {name} = {getattr(self, name)!r}; accepted: {accepted}")

    # ------------------------------------------------------------------ constants

    @property
    def solid(self) -> float:
        """``M = phi h`` (m): the solid volume per unit area, conserved."""
        return self.phi0 * self.h0

    @property
    def weight(self) -> float:
        """``P = M (rho_s - rho_f) g cos(theta)`` (Pa): buoyant weight of the grains normal to the bed."""
        return self._buoyant() * math.cos(math.radians(self.slope_deg))

    @property
    def drive(self) -> float:
        """``F = M (rho_s - rho_f) g sin(theta)`` (Pa): its downslope part."""
        return self._buoyant() * math.sin(math.radians(self.slope_deg))

    def _buoyant(self) -> float:
        mat = self.material
        return self.solid * (mat.rho_s - mat.rho_f) * self.gravity

    def initial_state(self) -> LayerState:
        """The layer at rest, ``t = 0``."""
        return LayerState(0.0, self.h0, 0.0, 0.0, 0.0)

    def closure(self, h: float, v: float, lag: float = 0.0, previous: float = 0.0) -> BasalClosure:
        """The dilatancy closure of the layer at thickness ``h`` and solid velocity ``v``; with
        ``lag = alpha / dt``, a backward-Euler step of its relaxation from ``previous``
        (:func:`~multilayer.engine.mixture.closure.basal_closure`)."""
        return basal_closure(self.material, self.solid, self.weight, h, abs(v), lag, previous)

    def state_closure(self, s: LayerState) -> BasalClosure:
        """The closure in the state ``s``: at its pore pressure ``s.p_e`` with a compressibility."""
        if self.compressibility is None:
            return self.closure(s.h, s.v)
        mat, phi = self.material, self.solid / s.h
        return closure_at(mat, phi, 3.0 * abs(s.v) / s.h, mat.drag(phi), self.weight, self.weight - s.p_e)

    def relaxation_time(self, h: float) -> float:
        """``t_IG = alpha beta h^2 / (2 (1 - phi)^2)`` (s) at thickness ``h`` (0 without a
        compressibility): Bouchut et al. (2016)'s time of the pore pressure of George &
        Iverson (2014)."""
        if self.compressibility is None:
            return 0.0
        phi = self.solid / h
        return self.compressibility * darcy_coefficient(self.material.drag(phi), h, phi)

    def held_at_rest(self, h: float | None = None) -> bool:
        """Whether the layer of thickness ``h`` (default ``h0``) at rest stays at rest:
        ``F <= (tan(delta) + K (phi - phi_c)) P``."""
        phi = self.solid / (self.h0 if h is None else h)
        return self.drive <= self.material.static_friction(phi) * self.weight

    # ------------------------------------------------------------------ the model

    def rhs(self, t: float, y: np.ndarray) -> np.ndarray:
        """``d/dt (h, v, u, x)`` (and ``p_e`` with a compressibility): the model as an ODE
        (for a reference solver).  At ``v = 0`` the Coulomb force is the multivalued one:
        zero acceleration while the force stays within the threshold."""
        h, v, u = float(y[0]), float(y[1]), float(y[2])
        mat = self.material
        relaxed = self.compressibility is not None
        cl = self.state_closure(LayerState(t, h, v, u, 0.0, float(y[4]))) if relaxed else self.closure(h, v)
        force = self.drive + cl.beta * h * (u - v)
        if v != 0.0:
            force -= math.copysign(cl.tau_b, v)
        elif abs(force) <= cl.tau_b:
            force = 0.0
        else:
            force -= math.copysign(cl.tau_b, force)
        B = darcy_coefficient(cl.beta, h, cl.phi)
        volume = -cl.p_e / B if relaxed else cl.dilation  # d_t h / h: the Darcy outflow with alpha
        fluid_mass = mat.rho_f * (h - self.solid)
        du = 0.0
        if fluid_mass > 0.0:
            du = (-(0.5 * mat.rho_f * h * volume + self.k_b) * u - cl.beta * h * (u - v)) / fluid_mass
        rates = [h * volume, force / (mat.rho_s * self.solid), du, v]
        if relaxed:  # alpha d_t p_e = -p_e / B - Phi
            rates.append(-(cl.p_e + B * cl.dilation) / self.relaxation_time(h))
        return np.array(rates)

    def energy(self, s: LayerState) -> float:
        """``E = rho_s M v^2/2 + rho_f (h - M) u^2/2 + P h/2 - F x`` (J/m2): kinetic energy of
        both phases, potential energy of the buoyant grains (centre at ``h/2``) and the work
        of the downslope weight.  ``d_t E = -dissipation <= 0`` (docs/mixture.md).  With a
        compressibility, plus the energy stored in the compressed pores, ``alpha h p_e^2 / 6``."""
        mat = self.material
        kinetic = 0.5 * mat.rho_s * self.solid * s.v**2 + 0.5 * mat.rho_f * (s.h - self.solid) * s.u**2
        energy = kinetic + 0.5 * self.weight * s.h - self.drive * s.x
        if self.compressibility is not None:
            energy += self.compressibility * s.h * s.p_e**2 / 6.0
        return energy

    def dissipation(self, s: LayerState) -> float:
        """``D = -d_t E`` (W/m2): Coulomb and viscous friction, drag, fluid friction on the bed,
        the Darcy flow through the pores, minus the part of the lifting work of dilation that
        the dilatancy friction does not pay:

        ``D = tan(delta) p_s |v| + K1 eta_f gamma |v| + beta h (u - v)^2 + k_b u^2
        + 3 beta h v^2 tan(psi)^2 / (2 (1 - phi)^2) - P |v| tan(psi) / 2``,

        non-negative whenever ``tan(delta) p_s >= P tan(psi) / 2``.  With a compressibility the
        Darcy term is ``h p_e^2 / (3 B) - alpha h Phi p_e^2 / 6`` at the state's ``p_e`` (equal to the
        one above at ``p_e = -B Phi``)."""
        mat, cl, speed = self.material, self.state_closure(s), abs(s.v)
        if self.compressibility is None:
            darcy = 1.5 * cl.beta * s.h * s.v**2 * cl.tan_psi**2 / (1.0 - cl.phi) ** 2
        else:
            B = darcy_coefficient(cl.beta, s.h, cl.phi)
            darcy = s.h * s.p_e**2 * (1.0 / (3.0 * B) - self.compressibility * cl.dilation / 6.0)
        return (
            mat.tan_delta * cl.p_s * speed
            + mat.K1 * mat.eta_f * cl.gamma * speed
            + cl.beta * s.h * (s.u - s.v) ** 2
            + self.k_b * s.u**2
            + darcy
            - 0.5 * self.weight * speed * cl.tan_psi
        )

    # ------------------------------------------------------------------ time stepping

    def step(self, s: LayerState, dt: float) -> LayerState:
        """One backward-Euler step of length ``dt`` from ``s`` (module docstring)."""
        if not (dt > 0.0 and math.isfinite(dt)):
            raise RunError(f"uniform layer: the time step dt = {dt!r} is not a finite number > 0")
        # held (v == 0.0, no dilation, h kept) iff within the static threshold, which is
        # negative for a packing looser than phi_c - tan(delta)/K: such a layer cannot rest
        # (with a compressibility, at the effective pressure the pore pressure relaxing at rest leaves)
        step = _Step(self, s, dt)
        h_rest = s.h
        if step.lag > 0.0:
            h_rest = step.consolidated()
            threshold = step.closure(h_rest, 0.0).tau_b
        else:
            threshold = self.material.static_friction(self.solid / s.h) * self.weight
        rhs = step.at(h_rest)[1]
        if abs(rhs) <= dt * threshold:
            h_new, v_new = h_rest, 0.0
        else:
            step.sign = math.copysign(1.0, rhs)
            h_new, speed = step.solve_moving()
            v_new = step.sign * speed
        u_new = step.fluid_velocity(h_new, v_new)
        p_e = step.closure(h_new, v_new).p_e if step.lag > 0.0 else 0.0
        new = LayerState(s.t + dt, h_new, v_new, u_new, s.x + dt * v_new, p_e)
        if not all(math.isfinite(q) for q in (new.h, new.v, new.u, new.x)) or new.h <= self.solid:
            raise RunError(
                f"uniform layer: impossible state at t = {new.t!r}: h = {new.h!r} (must exceed "
                f"M = {self.solid!r}), v = {new.v!r}, u = {new.u!r}"
            )
        return new

    def run(self, t_end: float, dt: float, state: LayerState | None = None) -> Trajectory:
        """Steps of ``dt`` (the last one shortened to land on ``t_end``) from ``state``
        (default: :meth:`initial_state`)."""
        s = self.initial_state() if state is None else state
        states = [s]
        while s.t < t_end * (1.0 - 1e-14):
            s = self.step(s, min(dt, t_end - s.t))
            states.append(s)
        h = np.array([q.h for q in states])
        return Trajectory(
            t=np.array([q.t for q in states]),
            h=h,
            v=np.array([q.v for q in states]),
            u=np.array([q.u for q in states]),
            x=np.array([q.x for q in states]),
            phi=self.solid / h,
            p_e=np.array([self.state_closure(q).p_e for q in states]),
            energy=np.array([self.energy(q) for q in states]),
        )


def onset_time(t: np.ndarray, v: np.ndarray, level: float) -> float:
    """First time at which ``|v|`` reaches ``level`` (linear interpolation between samples;
    ``t[0]`` if it starts there, ``nan`` if never)."""
    speed = np.abs(np.asarray(v, dtype=float))
    above = np.flatnonzero(speed >= level)
    if above.size == 0:
        return math.nan
    i = int(above[0])
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - speed[i - 1]) * (t[i] - t[i - 1]) / (speed[i] - speed[i - 1]))


class _Step:
    """One implicit step from ``s``.  At a trial thickness ``h'`` the fluid equation is
    solved for ``u' = (m_f u + dt beta' h' v') / D`` and substituted in the solid equation,
    which becomes ``A v' + dt tau_b xi = R`` (:meth:`at`).  A moving step then solves

    ``G1 = h' - h - dt h' Phi(h', |v'|) = 0`` and
    ``G2 = A(h') |v'| + dt tau_b(h', |v'|) - sign R(h') = 0``."""

    def __init__(self, layer: UniformLayer, s: LayerState, dt: float):
        mat = layer.material
        self.layer, self.s, self.dt = layer, s, dt
        self.sign = 1.0
        self.lag = 0.0 if layer.compressibility is None else layer.compressibility / dt
        self.solid_mass = mat.rho_s * layer.solid
        self.fluid_mass = mat.rho_f * (s.h - layer.solid)

    def _fluid(self, h: float) -> tuple[float, float, float]:
        """``(D, dt beta' h', mean fluid mass)`` at ``h' = h``."""
        mat, dt = self.layer.material, self.dt
        mean = 0.5 * (self.fluid_mass + mat.rho_f * (h - self.layer.solid))
        coupling = dt * mat.drag(self.layer.solid / h) * h
        return mean + dt * self.layer.k_b + coupling, coupling, mean

    def at(self, h: float) -> tuple[float, float]:
        """``(A, R)`` at ``h' = h``."""
        s, dt = self.s, self.dt
        denominator, coupling, mean = self._fluid(h)
        mass, rhs = self.solid_mass, self.solid_mass * s.v + dt * self.layer.drive
        if denominator > 0.0:
            mass += coupling * (mean + dt * self.layer.k_b) / denominator
            rhs += coupling * self.fluid_mass * s.u / denominator
        return mass, rhs

    def fluid_velocity(self, h: float, v: float) -> float:
        """``u'`` at ``h' = h`` and ``v' = v`` (0 without fluid)."""
        denominator, coupling, _ = self._fluid(h)
        return (self.fluid_mass * self.s.u + coupling * v) / denominator if denominator > 0.0 else 0.0

    def closure(self, h: float, w: float) -> BasalClosure:
        """The closure at ``h' = h``, ``|v'| = w`` (with a compressibility, the pore pressure of
        the step's relaxation from ``p_e``)."""
        return self.layer.closure(h, w, self.lag, self.s.p_e)

    def volume_rate(self, h: float, cl: BasalClosure) -> float:
        """``(h' - h) / (dt h')`` at ``h' = h`` with the closure ``cl`` there: the dilation rate
        ``Phi'`` of the closure, or with a compressibility the Darcy outflow ``-p_e' / B'``."""
        if self.lag == 0.0:
            return cl.dilation
        return -cl.p_e / darcy_coefficient(cl.beta, h, cl.phi)

    def consolidated(self) -> float:
        """``h'`` of the layer held at rest with a compressibility: ``h' = h / (1 + dt p_e' / B')``,
        ``p_e'`` the pore pressure relaxed at rest (``Phi = 0``) at ``h'``, by fixed-point
        iteration from ``h`` (a contraction: ``h'`` moves by ``alpha p_e`` relative to ``h``);
        ``h`` bit for bit where ``p_e = 0``."""
        h = self.s.h
        for _ in range(NEWTON_ITERATIONS):
            new = self.s.h / (1.0 - self.dt * self.volume_rate(h, self.closure(h, 0.0)))
            if new == h or abs(new - h) <= NEWTON_TOLERANCE * h:
                return new
            h = new
        raise RunError(f"uniform layer: the thickness at rest did not converge at t = {self.s.t!r}")

    def residual(self, h: float, w: float) -> tuple[float, float, float]:
        """``(G1, G2, scale of G2)`` at ``h' = h``, ``|v'| = w``."""
        cl = self.closure(h, w)
        mass, rhs = self.at(h)
        return (
            h - self.s.h - self.dt * h * self.volume_rate(h, cl),
            mass * w + self.dt * cl.tau_b - self.sign * rhs,
            abs(rhs),
        )

    def solve_moving(self) -> tuple[float, float]:
        """``(h', |v'|)`` by a damped Newton iteration (finite-difference Jacobian) from
        ``(h, |v|)``, or from the speed the force excess alone would give; by
        :meth:`solve_bracketed` if it fails."""
        h0, layer = self.s.h, self.layer
        mass, rhs = self.at(h0)
        guess = (self.sign * rhs - self.dt * self.closure(h0, 0.0).tau_b) / mass  # > 0: not held
        h, w = h0, (abs(self.s.v) if self.s.v * self.sign > 0.0 else guess)

        def norm(r: tuple[float, float, float], w: float) -> float:
            return math.hypot(r[0] / h0, r[1] / (r[2] + mass * w))

        r = self.residual(h, w)
        for _ in range(NEWTON_ITERATIONS):
            size = norm(r, w)
            if size <= ROUND_OFF:
                return h, w
            dh, dw = FD_STEP * h, FD_STEP * w
            rh, rw = self.residual(h + dh, w), self.residual(h, w + dw)
            a11, a21, a12, a22 = (
                (rh[0] - r[0]) / dh,
                (rh[1] - r[1]) / dh,
                (rw[0] - r[0]) / dw,
                (rw[1] - r[1]) / dw,
            )
            det = a11 * a22 - a12 * a21
            if det == 0.0 or not math.isfinite(det):
                break
            step_h, step_w = (a22 * r[0] - a12 * r[1]) / det, (a11 * r[1] - a21 * r[0]) / det
            for _ in range(40):  # damping: stay admissible and do not increase the residual
                if h - step_h > layer.solid and w - step_w > 0.0:
                    trial = self.residual(h - step_h, w - step_w)
                    if norm(trial, w - step_w) <= size:
                        break
                step_h, step_w = 0.5 * step_h, 0.5 * step_w
            else:
                break
            h, w, r = h - step_h, w - step_w, trial
            if abs(step_h) <= NEWTON_TOLERANCE * h and abs(step_w) <= NEWTON_TOLERANCE * w:
                return h, w
        return self.solve_bracketed()

    def solve_bracketed(self) -> tuple[float, float]:
        """``|v'|`` by bracketing ``G2(h'(w), w)`` on ``(0, w_hi]``, ``h'(w)`` by bracketing
        ``G1(., w)``: both change sign on the brackets built here."""
        h0, solid, t = self.s.h, self.layer.solid, self.s.t + self.dt

        def thickness(w: float) -> float:
            g0 = self.residual(h0, w)[0]
            if g0 == 0.0:
                return h0
            lo, hi = (h0, 2.0 * h0) if g0 < 0.0 else (solid * (1.0 + 1e-12), h0)
            while self.residual(hi, w)[0] <= 0.0:
                lo, hi = hi, 2.0 * hi
                if hi > 1e6 * h0:
                    raise RunError(f"uniform layer: no thickness balances the dilation at t = {t!r}")
            return float(brentq(lambda q: self.residual(q, w)[0], lo, hi, xtol=1e-300, rtol=NEWTON_TOLERANCE))

        def g2(w: float) -> float:
            return self.residual(thickness(w), w)[1]

        mass, rhs = self.at(h0)
        hi = max(abs(rhs) / mass, 1e-300)
        while g2(hi) <= 0.0:
            hi *= 2.0
            if not math.isfinite(hi):
                raise RunError(f"uniform layer: no velocity balances the forces at t = {t!r}")
        try:
            w = float(brentq(g2, 0.0, hi, xtol=1e-300, rtol=NEWTON_TOLERANCE))
        except ValueError as err:
            raise RunError(
                f"uniform layer: the implicit step at t = {t!r} has no bracketed root ({err})"
            ) from err
        return thickness(w), w
