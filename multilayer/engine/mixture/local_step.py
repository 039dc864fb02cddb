"""The implicit local step of a layered grain–fluid mixture: velocities, dilation and
excess pore pressure of every column (docs/mixture.md, "The mixture in x and in layers").

The mixture moves with one velocity per layer (the drag relaxation, ``rho_s / beta`` ~
1e-5 s, is far below the step: Bouchut et al. 2025 "velocity equality"), under an ambient
fluid at rest.  Layer ``a`` (thickness ``h_a = l_a h``) holds the solid volume ``s_a``,
``phi_a = s_a / h_a``.  At interface ``a`` (below layer ``a``, ``a = 0`` the bed) the
shear rate is ``gamma_a = |v_a - v_{a-1}| / (spacing_a h)`` and the closure of Bouchut,
Fernández-Nieto, Mangeney & Narbona-Reina (2016, J. Fluid Mech. 801) gives the layer's
dilation rate and the effective pressure::

    Phi_a = gamma_a K (phi_a - phi_c + K2 eta_f gamma_a / p_s,a)
    p_s,a = P_a - p_e,a,   P_a = (rho_s - rho_f) g cos(theta) sum_{b >= a} s_b
    p_e,a = p_e,a+1 - D_a h_a (W_a + W_a+1) / 2,   D_a = beta(phi_a) / (1 - phi_a)^2,   p_e,L = 0

with ``W_a = sum_{b < a} h_b Phi_b`` the grains' vertical velocity at interface ``a``
(Darcy's law for the fluid they displace, integrated from the top of the mixture down;
for one layer it is the uniform layer's ``p_e = -beta h^2 Phi / (2 (1 - phi)^2)``).  The
own layer's term makes ``p_s,a`` the root of a quadratic, as in the uniform layer.

The step, backward Euler: the thickness ``h' = h* / (1 - dt sum_a l_a Phi_a)`` (the fluid
drawn from or expelled to the ambient fluid; ``s_a`` unchanged), and the velocities the
exact minimiser of the column problem (``engine/vertical``) with masses
``rho_s s_a + rho_f (fluid before + fluid after) / 2`` (the fluid joins at rest: the
exchange term of the uniform layer's energy identity), the yield stress and viscosity of
the rheology at the effective pressure.  Velocities, pressures and thickness are iterated
to a fixed point; at rest ``gamma = 0``, so ``Phi = 0``, ``p_e = 0`` and ``h' = h*`` bit
for bit: a column held by friction stays at ``v == 0.0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from multilayer.engine.config import MixtureConfig
from multilayer.engine.plugin_output import call
from multilayer.engine.vertical.column_solve import solve
from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.engine.vertical.stresses import INTERFACE
from multilayer.errors import InputError, RunError
from multilayer.plugins.contract import Material, MixtureState, Rheology

DERIVATIVE_STEP = 1e-7
"""Relative increment of the effective pressure for the derivative of a law's yield stress."""


@dataclass(frozen=True)
class LocalResult:
    """The local step's result in the columns it was given."""

    u: np.ndarray  # (L, n) layer velocities
    h: np.ndarray  # (n,) mixture thickness after dilation
    pore_pressure: np.ndarray  # (L, n) excess pore pressure at the bottom of each layer (Pa)
    iterations: int


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

    def masses(self, solid: np.ndarray, h: np.ndarray) -> np.ndarray:
        """``rho_s s_a + rho_f (l_a h - s_a)`` (kg/m^2): the layer masses at thickness ``h``."""
        return self.rho_s * solid + self.rho_f * (self.l * h - solid)

    def drag(self, phi: np.ndarray) -> np.ndarray:
        """``beta = kozeny eta_f phi^2 / (d^2 (1 - phi))`` (Pa s/m^2): Darcy's law with the
        Carman–Kozeny permeability (``closure.MixtureMaterial.drag``)."""
        d = self.material.grain_diameter
        return self.config.kozeny * self.config.fluid_viscosity * phi * phi / (d * d * (1.0 - phi))

    def closure(
        self, solid: np.ndarray, h: np.ndarray, v: np.ndarray, pore_pressure: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """One sweep of the closure from the bed up at thickness ``h`` (n,) and velocities
        ``v`` (L, n), the pore pressures above each layer taken from ``pore_pressure``:
        the shear rates, the effective pressures at these rates, their derivatives with
        respect to the shear rate (the terms from above and below held), the dilation rates
        ``Phi_a`` and the new excess pore pressures (all (L, n))."""
        cfg, l = self.config, self.l
        L = l.shape[0]
        thickness = l * h
        phi = solid / thickness
        gamma = np.abs(np.diff(v, axis=0, prepend=0.0)) / (self.spacing * h)
        weight = self.buoyant_g_n * np.cumsum(solid[::-1], axis=0)[::-1]
        D = self.drag(phi) / (1.0 - phi) ** 2
        B = 0.5 * D * thickness * thickness
        K, shift = cfg.dilatancy, cfg.critical_shift * cfg.fluid_viscosity
        p_s, slope, dilation = np.empty_like(v), np.empty_like(v), np.empty_like(v)
        rise = np.zeros_like(h)  # W_a: the grains' vertical velocity at interface a
        for a in range(L):
            above = pore_pressure[a + 1] if a + 1 < L else 0.0
            A = (
                weight[a]
                - above
                + D[a] * thickness[a] * rise
                + B[a] * gamma[a] * K * (phi[a] - cfg.phi_critical)
            )
            C = B[a] * K * shift * gamma[a] ** 2
            root = np.sqrt(A * A + 4.0 * C)
            positive = np.where(A >= 0.0, 0.5 * (A + root), 2.0 * C / np.where(root - A > 0.0, root - A, 1.0))
            p_s[a] = np.where(C > 0.0, positive, np.maximum(A, 0.0))
            # p_s^2 - A p_s - C = 0: d p_s / d gamma = (A' p_s + C') / (2 p_s - A)
            denominator = 2.0 * p_s[a] - A
            rate = B[a] * K * (phi[a] - cfg.phi_critical) * p_s[a] + 2.0 * B[a] * K * shift * gamma[a]
            slope[a] = np.where(denominator > 0.0, rate / np.where(denominator > 0.0, denominator, 1.0), 0.0)
            viscous = np.where(p_s[a] > 0.0, shift * gamma[a] / np.where(p_s[a] > 0.0, p_s[a], 1.0), 0.0)
            dilation[a] = gamma[a] * K * (phi[a] - cfg.phi_critical + viscous)
            rise = rise + thickness[a] * dilation[a]
        # the pore pressures of these dilation rates, from the top of the mixture down
        new = np.empty_like(v)
        top = np.zeros_like(h)
        for a in range(L - 1, -1, -1):
            lower = rise - thickness[a] * dilation[a]
            top = top - D[a] * thickness[a] * 0.5 * (lower + rise)
            new[a], rise = top, lower
        return gamma, p_s, slope, dilation, new

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
        *,
        x: np.ndarray | None = None,
        t: float = 0.0,
    ) -> LocalResult:
        """The step of columns holding ``solid`` (L, n) after transport to ``h_star`` (n,),
        velocities ``ustar`` (L, n) (the buoyant weight along the slope included), the
        iteration started from the velocities ``guess`` (default: at rest); ``x`` (n,) and
        ``t`` place the columns in the messages of the checked plugin calls.

        Each iteration evaluates the closure at the last velocities and solves the column
        problem exactly (a Newton iteration).  The yield stress depends on the shear rate
        through the effective pressure (it rises in a dilating packing, falls in a
        contracting one); it is linearised at the last shear rate: its tangent joins the
        viscosity and the intercept is the yield stress, wherever the stress still grows
        with the rate (the problem stays convex); elsewhere its value at the last shear
        rate is used."""
        where = np.zeros(h_star.size) if x is None else x

        def law(method: str, *args: object) -> np.ndarray:
            """The rheology's ``method`` (its pressure argument is third from the end of
            ``args``), checked (engine/plugin_output.py)."""
            inputs = {"pressure": np.asarray(args[-3])}
            return call(self.law, method, args, inputs=inputs, x=where, position=INTERFACE, t=t)

        m_before = self.masses(solid, h_star)
        momentum = m_before * ustar
        zeros = np.zeros_like(ustar)
        h, v = h_star, zeros if guess is None else guess
        pore_pressure = zeros
        velocity_scale = float(np.abs(ustar).max(initial=0.0))
        for iteration in range(1, self.max_iterations + 1):
            gamma, p_s, slope, dilation, new_pressure = self.closure(solid, h, v, pore_pressure)
            growth = 1.0 - dt * np.sum(self.l * dilation, axis=0)
            if not np.all(growth > 0.0):
                i = int(np.argmin(growth))
                raise RunError(
                    f"the mixture's dilation rate {float(np.sum(self.l[:, 0] * dilation[:, i])):.6g} 1/s "
                    f"exceeds 1/dt = {1.0 / dt:.6g} 1/s in column {i}: no thickness balances it"
                )
            h_new = h_star / growth
            state = self._state(solid, h, new_pressure)
            flowing = law("mixture_yield_stress", p_s, state, self.material)
            step = DERIVATIVE_STEP * np.maximum(np.abs(p_s), 1e-300)
            tangent = (law("mixture_yield_stress", p_s + step, state, self.material) - flowing) / step * slope
            eta = law("mixture_viscosity", gamma, p_s, state, self.material)
            newton = eta + tangent > 0.0
            kappa = np.where(newton, np.maximum(flowing - tangent * gamma, 0.0), flowing)
            eta = np.where(newton, eta + tangent, eta)
            m = 0.5 * (m_before + self.masses(solid, h_new))
            problem = ColumnProblem(
                m=m, ustar=momentum / m, dt=dt, kappa=kappa, c=eta / (self.spacing * h_new), w=zeros, cw=zeros
            )
            v_new = solve(problem, v)
            velocity_scale = max(velocity_scale, float(np.abs(v_new).max(initial=0.0)))
            done = iteration > 1 and all(
                _close(new, old, self.tolerance * scale)
                for new, old, scale in zip(
                    (v_new, h_new, new_pressure),
                    (v, h, pore_pressure),
                    (velocity_scale, float(h_star.max(initial=0.0)), float(np.abs(p_s).max(initial=0.0))),
                )
            )
            v, h, pore_pressure = v_new, h_new, new_pressure
            if done:
                return LocalResult(v, h, pore_pressure, iteration)
        raise RunError(
            f"the mixture's local step did not converge in {self.max_iterations} iterations "
            f"(numerics.max_iterations)"
        )


def _close(new: np.ndarray, old: np.ndarray, bound: float) -> bool:
    """Whether ``new`` and ``old`` differ by at most ``bound`` everywhere."""
    return bool(np.all(np.abs(new - old) <= bound))
