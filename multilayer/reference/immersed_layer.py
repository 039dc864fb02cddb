"""References for the uniform immersed layer (:mod:`multilayer.engine.mixture.uniform_layer`).

* The steady uniform flow (Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina 2016, J.
  Fluid Mech. 801, uniform configuration): no dilation means ``phi = phi_eq``, hence no
  excess pore pressure, ``p_s = P`` and ``tau_b = tan(delta) P + K1 eta_f gamma``.  With
  ``k_b = 0`` the fluid moves with the grains and
  ``gamma = (F - tan(delta) P) / (K1 eta_f)``, ``phi = phi_c - K2 eta_f gamma / P``,
  ``v = gamma h / 3``; with ``k_b > 0``, ``u = beta h v / (beta h + k_b)`` and one scalar
  equation in ``gamma``.
* The model integrated by a tight-tolerance implicit Runge-Kutta method (Radau IIA of
  order 5, scipy's ``solve_ivp``): the reference the backward-Euler step is checked
  against.
* The laboratory layers of Pailha, Nicolas & Pouliquen (2008, Phys. Fluids 20, 111701)
  with the parameters used with the model of Bouchut et al. (2016), and the model's
  characteristic times.
* The basal excess pore pressure of a loose layer flowing and of a dense layer creeping,
  in the limit of a stiff Darcy drag: quasi-static balances of the model.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from multilayer.engine.mixture.closure import MixtureMaterial
from multilayer.engine.mixture.uniform_layer import LayerState, UniformLayer

PAILHA_2008_FLUIDS = {
    "viscous": {"eta_f": 96e-3, "rho_f": 1041.0, "slope_deg": 25.0, "h0": 4.9e-3},
    "water": {"eta_f": 9.8e-3, "rho_f": 1026.0, "slope_deg": 28.0, "h0": 6.1e-3},
}
"""The two fluids of Pailha, Nicolas & Pouliquen (2008) with their slope and layer thickness."""

PAILHA_2008_GRAINS = {"rho_s": 2500.0, "phi_c": 0.582, "delta_deg": 22.5, "K1": 90.5, "K2": 25.0, "d": 160e-6}
"""Grains and closure constants for Pailha et al. (2008) as used with the model of Bouchut
et al. (2016).  The grain diameter (160 um) is that of the viscous-fluid experiments; its use
for the second fluid is an assumption."""

PAILHA_POULIQUEN_2009_K = 4.09
"""Dilatancy constant ``K`` of ``tan(psi) = K (phi - phi_eq)``: Pailha & Pouliquen's (2009,
J. Fluid Mech. 633) calibration as recalled here, NOT checked against the paper
(docs/mixture.md lists it as unverified)."""


def pailha_2008_layer(
    phi0: float, fluid: str = "viscous", k_b: float = 0.0, compressibility: float | None = None
) -> UniformLayer:
    """The uniform layer of Pailha et al. (2008) with initial volume fraction ``phi0`` in the
    ``"viscous"`` (96 mPa s, 25 deg, 4.9 mm) or ``"water"`` (9.8 mPa s, 28 deg, 6.1 mm) fluid,
    with the skeleton's ``compressibility`` (1/Pa) if given."""
    case = PAILHA_2008_FLUIDS[fluid]
    material = MixtureMaterial(
        rho_f=case["rho_f"], eta_f=case["eta_f"], K=PAILHA_POULIQUEN_2009_K, **PAILHA_2008_GRAINS
    )
    return UniformLayer(
        material, case["slope_deg"], case["h0"], phi0, k_b=k_b, compressibility=compressibility
    )


def time_scales(layer: UniformLayer) -> dict[str, float]:
    """The model's characteristic times (s) at its steady flow: ``t_crit = 1 / gamma``
    (approach to the critical state), ``t_visc = rho_s h^2 / (3 K1 eta_f)`` (viscous) and
    ``t_rel = rho_s / beta`` (relaxation of ``u - v`` by the drag), with ``beta`` at ``phi_c``
    (Bouchut et al. 2016)."""
    mat, steady = layer.material, steady_flow(layer)
    if steady is None:
        raise ValueError("the layer has no steady flow")
    gamma = 3.0 * steady.v / steady.h
    return {
        "t_crit": 1.0 / gamma,
        "t_visc": mat.rho_s * layer.h0**2 / (3.0 * mat.K1 * mat.eta_f),
        "t_rel": mat.rho_s / mat.drag(mat.phi_c),
    }


def steady_flow(layer: UniformLayer) -> LayerState | None:
    """The steady uniform flow of ``layer`` (at ``t = x = 0``), or ``None`` if there is
    none (``tan(theta) <= tan(delta)``, or no rate-dependent friction to balance gravity)."""
    mat = layer.material
    excess = layer.drive - mat.tan_delta * layer.weight
    viscous = mat.K1 * mat.eta_f
    if excess <= 0.0 or viscous <= 0.0:
        return None

    def state(gamma: float) -> LayerState:
        phi = mat.phi_c - mat.K2 * mat.eta_f * gamma / layer.weight
        h = layer.solid / phi
        v = gamma * h / 3.0
        bh = mat.drag(phi) * h
        u = bh * v / (bh + layer.k_b) if bh + layer.k_b > 0.0 else v
        return LayerState(0.0, h, v, u, 0.0)

    def residual(gamma: float) -> float:
        s = state(gamma)
        return excess - viscous * gamma - layer.k_b * s.u

    upper = excess / viscous
    gamma = (
        upper if layer.k_b == 0.0 else brentq(residual, 0.0, upper, xtol=1e-300, rtol=4 * np.finfo(float).eps)
    )
    if mat.phi_c - mat.K2 * mat.eta_f * gamma / layer.weight <= 0.0:
        return None
    return state(float(gamma))


def flowing_pore_pressure(layer: UniformLayer, phi: float) -> float:
    """The basal excess pore pressure (Pa) of ``layer`` (``k_b = 0``) flowing steadily at
    packing ``phi`` below its flowing critical fraction, in the limit of a stiff Darcy drag
    (Bouchut et al. 2016's closure): ``p_e = -B Phi`` with ``B`` large keeps ``Phi ~ 0``, so
    the packing is at its critical state, ``phi = phi_c - K2 eta_f gamma / p_s``, and
    ``tan(psi) ~ 0``, so the grains' friction balances the drive,
    ``F = tan(delta) p_s + K1 eta_f gamma``.  Eliminating ``gamma``::

        p_e = P - p_s = P (1 - K2 tan(theta) / (K1 (phi_c - phi) + K2 tan(delta)))

    It depends on the friction constants and the packing, not on ``K`` nor on the
    permeability (they set how slowly ``phi`` relaxes)."""
    mat = layer.material
    return layer.weight - layer.drive * mat.K2 / (mat.K1 * (mat.phi_c - phi) + mat.K2 * mat.tan_delta)


def creeping_pore_pressure(layer: UniformLayer, phi: float) -> float:
    """The basal excess pore pressure (Pa) of ``layer`` creeping at packing ``phi`` above
    ``phi_c`` (Bouchut et al. 2016's closure): at a vanishing shear rate
    ``tan(psi) = K (phi - phi_c)`` and the friction at the effective pressure balances the
    drive, ``F = (tan(delta) + K (phi - phi_c)) p_s``, so the suction is what holds the
    layer at its static threshold::

        p_e = P (1 - tan(theta) / (tan(delta) + K (phi - phi_c)))

    It depends on ``K`` and the packing, not on the permeability."""
    return layer.weight - layer.drive / layer.material.static_friction(phi)


def reference_solution(
    layer: UniformLayer, times: np.ndarray, state: LayerState | None = None, rtol: float = 1e-10
) -> np.ndarray:
    """``(h, v, u, x)`` (and ``p_e`` with a compressibility) at ``times`` (rows), integrated
    from ``state`` (default: at rest at ``t = 0``) by Radau IIA with relative tolerance
    ``rtol`` and absolute tolerances ``rtol`` times the scales ``h0``, the steady speed (or
    ``sqrt(g h0)``), its distance and the buoyant weight ``P``."""
    s = layer.initial_state() if state is None else state
    times = np.asarray(times, dtype=float)
    steady = steady_flow(layer)
    speed = steady.v if steady is not None else math.sqrt(layer.gravity * layer.h0)
    scale = [layer.h0, speed, speed, speed * max(float(times[-1]), 1.0)]
    start = [s.h, s.v, s.u, s.x]
    if layer.compressibility is not None:
        scale.append(layer.weight)
        start.append(s.p_e)
    # where no rate changes with a variable (the distance x enters none; others can be locally
    # flat, as for a dense layer at rest) scipy's finite-difference Jacobian grows that
    # column's increment until it overflows: the column is zero whatever the increment
    with np.errstate(over="ignore"):
        solution = solve_ivp(
            layer.rhs,
            (s.t, float(times[-1])),
            start,
            method="Radau",
            t_eval=times,
            rtol=rtol,
            atol=rtol * np.array(scale),
        )
    if not solution.success:
        raise RuntimeError(f"reference solution of the uniform layer failed: {solution.message}")
    return np.asarray(solution.y).T
