"""The dilatancy closure of a grain–fluid mixture at the bed of a shallow layer.

Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina (2016, J. Fluid Mech. 801), after the
critical-state dilatancy law of Roux & Radjai (1998) with the shear-rate-dependent
critical state of Pailha & Pouliquen (2009, J. Fluid Mech. 633):

```text
Phi     = gamma tan(psi)                                 depth-averaged dilation rate (div v)
tan(psi) = K (phi - phi_eq),   phi_eq = phi_c - K2 eta_f gamma / p_s
p_e     = -B Phi,              B = beta h^2 / (2 (1 - phi)^2)     excess pore pressure at the bed
p_s     = P - p_e                                        effective (grain-contact) pressure at the bed
tau_b   = (tan(delta) + tan(psi)) p_s + K1 eta_f gamma   basal shear stress of the grains
```

with ``P`` the buoyant weight of the grains per unit area (normal to the bed), ``gamma``
the depth-averaged shear rate and the drag coefficient of Darcy's law with the
Carman–Kozeny permeability, ``beta = (1 - phi)^2 eta_f / k``,
``k = d^2 (1 - phi)^3 / (c_k phi^2)`` (``c_k = 150``).

``p_e`` depends on ``Phi``, hence on ``phi_eq``, hence on ``p_s = P - p_e``; substituting
gives ``p_s^2 - a p_s - c = 0`` with ``a = P + B gamma K (phi - phi_c)`` and
``c = B K K2 eta_f gamma^2 >= 0``, whose non-negative root is taken (docs/mixture.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, NamedTuple

import numpy as np

from multilayer.errors import InputError

DENSEST_PACKING = math.pi / math.sqrt(18.0)
"""``pi / sqrt(18) = 0.7405``: no packing of equal spheres is denser (Hales 2005, Ann. Math.
162, the Kepler conjecture); a solid volume fraction at or above it is impossible."""


def drag(kozeny: float, eta_f: float, d: float, phi: Any) -> Any:
    """Drag coefficient of Darcy's law with the Carman–Kozeny permeability, ``beta = (1 - phi)^2
    eta_f / k = c_k eta_f phi^2 / (d^2 (1 - phi))`` (Pa s/m2), for a number or an array ``phi``."""
    return kozeny * eta_f * phi * phi / (d * d * (1.0 - phi))


@dataclass(frozen=True)
class MixtureMaterial:
    """Grains, pore fluid and the constants of the dilatancy closure (SI units).

    ``rho_s`` grain density (kg/m3), ``d`` grain diameter (m), ``rho_f`` fluid density
    (kg/m3, ``0 <= rho_f < rho_s``), ``eta_f`` fluid viscosity (Pa s), ``delta_deg`` basal
    friction angle, ``phi_c`` static critical volume fraction, ``K`` dilatancy constant,
    ``K1`` viscous friction constant, ``K2`` shift of the critical state with the viscous
    number ``eta_f gamma / p_s`` (Pailha & Pouliquen 2009), ``kozeny`` the Carman–Kozeny
    constant of the permeability.  ``rho_f = eta_f = 0`` removes the fluid.
    """

    rho_s: float
    d: float
    rho_f: float
    eta_f: float
    delta_deg: float
    phi_c: float
    K: float
    K1: float
    K2: float
    kozeny: float = 150.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise InputError(f"mixture material: {f.name} = {value!r} is not a finite number")
        _require(self.rho_s > 0.0, "rho_s", self.rho_s, "> 0 (kg/m3)")
        _require(self.d > 0.0, "d", self.d, "> 0 (m)")
        _require(0.0 <= self.rho_f < self.rho_s, "rho_f", self.rho_f, "in [0, rho_s) (kg/m3)")
        _require(self.eta_f >= 0.0, "eta_f", self.eta_f, ">= 0 (Pa s)")
        _require(0.0 <= self.delta_deg < 90.0, "delta_deg", self.delta_deg, "in [0, 90) (degrees)")
        _require(0.0 < self.phi_c < 1.0, "phi_c", self.phi_c, "in (0, 1)")
        for name in ("K", "K1", "K2"):
            _require(getattr(self, name) >= 0.0, name, getattr(self, name), ">= 0")
        _require(self.kozeny > 0.0, "kozeny", self.kozeny, "> 0")

    @property
    def tan_delta(self) -> float:
        """``tan(delta)``, the static basal friction coefficient at the critical state."""
        return math.tan(math.radians(self.delta_deg))

    def drag(self, phi: float) -> float:
        """Drag coefficient ``beta`` (:func:`drag`, Pa s/m2)."""
        return float(drag(self.kozeny, self.eta_f, self.d, phi))

    def static_friction(self, phi: float) -> float:
        """Friction coefficient at rest, ``tan(delta) + K (phi - phi_c)`` (``phi_eq = phi_c`` at rest)."""
        return self.tan_delta + self.K * (phi - self.phi_c)


def _require(ok: bool, name: str, value: float, accepted: str) -> None:
    if not ok:
        raise InputError(f"mixture material: {name} = {value!r}; accepted: {accepted}")


SHEAR_RATE_SCALE = 1e3
"""The shear rate (1/s) at which :func:`discriminant_bound` bounds the closure: ``3 |v| /
h`` of 10 m/s over 3 cm."""
DISCRIMINANT_LIMIT = 1e300
"""The largest :func:`discriminant_bound` accepted: the closure's quadratic takes
``sqrt(a^2 + 4 c)`` and its Newton step products of it, which overflow near 1e308."""


def discriminant_bound(
    beta: float, h: float, phi: float, weight: float, K: float, K2: float, eta_f: float
) -> float:
    """``a^2 + 4 c`` of the effective pressure's quadratic (module docstring) for a layer of
    thickness ``h`` and packing ``phi`` of drag ``beta`` and buoyant weight ``weight`` at
    :data:`SHEAR_RATE_SCALE`, with ``|phi - phi_eq| <= 1``: ``a = P + B gamma K``, ``c = B K
    K2 eta_f gamma^2`` (inf where it overflows)."""
    gamma = SHEAR_RATE_SCALE
    with np.errstate(all="ignore"):
        B = np.float64(darcy_coefficient(beta, h, phi))
        a = np.float64(weight) + B * gamma * K
        c = B * K * K2 * eta_f * gamma * gamma
        value = a * a + 4.0 * c
    return float(value) if np.isfinite(value) else math.inf


class BasalClosure(NamedTuple):
    """The closure at the bed of a layer of thickness ``h`` moving at speed ``|v|``."""

    phi: float  # solid volume fraction M / h
    gamma: float  # shear rate 3 |v| / h (1/s)
    beta: float  # drag coefficient (Pa s/m2)
    tan_psi: float  # dilatancy angle tan(psi) = K (phi - phi_eq)
    dilation: float  # Phi = gamma tan(psi) (1/s): d_t h = h Phi
    p_s: float  # effective pressure at the bed (Pa)
    p_e: float  # excess pore pressure at the bed (Pa)
    tau_b: float  # basal shear stress of the grains, >= 0 (Pa)


def darcy_coefficient(beta: float, h: float, phi: float) -> float:
    """``B = beta h^2 / (2 (1 - phi)^2)`` (Pa s): the basal excess pore pressure of a layer
    of thickness ``h`` per unit dilation rate, ``p_e = -B Phi``, Darcy's law integrated over
    the layer (Bouchut et al. 2016)."""
    return 0.5 * beta * h * h / ((1.0 - phi) * (1.0 - phi))


def basal_closure(
    mat: MixtureMaterial,
    solid: float,
    weight: float,
    h: float,
    speed: float,
    lag: float = 0.0,
    previous: float = 0.0,
) -> BasalClosure:
    """Evaluate the closure for a layer holding ``solid = phi h`` (m) of grains of buoyant
    weight ``weight = P`` (Pa), of thickness ``h > solid`` and moving at ``speed = |v|``.

    The depth-averaged shear rate of a linear velocity profile, ``gamma = 3 |v| / h``, is
    that of Bouchut et al. (2016) for the uniform layer.

    With ``lag = alpha / dt > 0`` the excess pore pressure is not the closure's but one
    backward-Euler step of length ``dt`` from ``previous`` of its relaxation towards it,
    ``alpha d_t p_e = -p_e / B - Phi`` (the skeleton's compressibility ``alpha``, George &
    Iverson 2014; relaxation time ``t_IG = alpha B``, Bouchut et al. 2016): with
    ``r = alpha B / dt`` it is the same quadratic with ``B`` divided by ``1 + r`` and ``P``
    lowered by ``r previous / (1 + r)``.  ``lag = 0`` is the closure, bit for bit.
    """
    phi = solid / h
    gamma = 3.0 * speed / h
    beta = mat.drag(phi)
    B = darcy_coefficient(beta, h, phi)
    ratio = lag * B
    B /= 1.0 + ratio
    p_s = closure_pressure(mat, phi, gamma, B, weight - previous * ratio / (1.0 + ratio))
    return closure_at(mat, phi, gamma, beta, weight, p_s)


def closure_pressure(mat: MixtureMaterial, phi: float, gamma: float, B: float, weight: float) -> float:
    """The effective pressure ``p_s`` of the closure ``p_e = -B Phi`` at the shear rate
    ``gamma``: the non-negative root of ``p_s^2 - a p_s - c = 0`` (module docstring), taken
    without cancellation where ``a < 0``."""
    a = weight + B * gamma * mat.K * (phi - mat.phi_c)
    c = B * mat.K * mat.K2 * mat.eta_f * gamma * gamma
    root = math.sqrt(a * a + 4.0 * c)
    return 0.5 * (a + root) if a >= 0.0 else 2.0 * c / (root - a) if c > 0.0 else 0.0


def closure_at(
    mat: MixtureMaterial, phi: float, gamma: float, beta: float, weight: float, p_s: float
) -> BasalClosure:
    """The closure at the effective pressure ``p_s > 0`` (Pa) given (or ``p_s = 0`` with
    ``K2 eta_f gamma = 0``): dilatancy, dilation rate and basal stress of :func:`basal_closure`,
    with the excess pore pressure ``weight - p_s``."""
    viscous_shift = mat.K2 * mat.eta_f * gamma
    if viscous_shift > 0.0:
        viscous_shift /= p_s  # p_s > 0 here: c > 0, or K = 0 and a = P > 0
    tan_psi = mat.K * (phi - mat.phi_c + viscous_shift)
    dilation = gamma * tan_psi
    tau_b = (mat.tan_delta + tan_psi) * p_s + mat.K1 * mat.eta_f * gamma
    return BasalClosure(phi, gamma, beta, tan_psi, dilation, p_s, weight - p_s, tau_b)
