"""Exact solutions the model is checked against (docs/model.md, docs/validation.md).

* Dam breaks (shallow water, one layer): Ritter's solution on a dry frictionless bed and
  its extension to a slope with Coulomb basal friction (Mangeney, Heinrich & Roche 2000,
  eq. 18-20 with a constant acceleration); Stoker's solution on a wet bed (Stoker 1957,
  "Water Waves", sec. 10.8: a rarefaction, a uniform state and a shock).
* Inviscid simple shear of one column (Bouchut, Ionescu & Mangeney 2016, Prop. 2.2):
  above a Drucker-Prager static layer the velocity decreases uniformly,
  ``U(t, z) = max(U0(z) - S t, 0)``, and the static/flowing interface rises to where
  ``U0(b(t)) = S t``.
* Steady uniform mu(I) flow on a slope (Tsang, Dalziel & Vriend 2019, sec. 4.1):
  ``mu(I_theta) = tan(theta)`` fixes a uniform inertial number, and Bagnold's profile
  (eq. 4.1-4.3) follows from ``I = d |du/dz| / sqrt(p / rho_p)``.

The Blasius similarity solution of the same paper is in :mod:`multilayer.reference.similarity`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from multilayer.plugins.contract import Material, Rheology

GRAVITY = 9.81


# --------------------------------------------------------------------------- dam breaks


def coulomb_dam_break(
    x: np.ndarray,
    t: float,
    h0: float,
    theta_deg: float,
    delta_deg: float,
    x0: float = 0.0,
    gravity: float = GRAVITY,
) -> np.ndarray:
    """Thickness of a dam break with Coulomb friction on a slope (Mangeney et al. 2000).

    A reservoir of depth ``h0`` behind ``x0`` (x downslope) on a plane inclined at
    ``theta``, basal friction angle ``delta``, released at ``t = 0``.  In the frame that
    moves with the constant acceleration ``a = g (sin(theta) - cos(theta) tan(delta))``
    the solution is Ritter's with wave speed ``c0 = sqrt(g h0 cos(theta))``::

        h = (2 c0 - xi / t)^2 / (9 g cos(theta))   for -c0 t <= xi <= 2 c0 t,
        xi = x - x0 - a t^2 / 2,

    ``h0`` upstream and 0 downstream.  Valid while the reservoir is not exhausted and for
    ``a`` of either sign as long as the material is flowing (``delta < theta`` or the
    fan does not stop).  ``theta = delta = 0`` is Ritter's solution.
    """
    th = math.radians(theta_deg)
    accel = gravity * (math.sin(th) - math.cos(th) * math.tan(math.radians(delta_deg)))
    c0 = math.sqrt(gravity * h0 * math.cos(th))
    xi = np.asarray(x, dtype=float) - x0 - accel * t * t / 2
    fan = (2 * c0 - xi / t) ** 2 / (9 * gravity * math.cos(th))
    return np.where(xi < -c0 * t, h0, np.where(xi < 2 * c0 * t, fan, 0.0))


def ritter(x: np.ndarray, t: float, h0: float, x0: float = 0.0, gravity: float = GRAVITY) -> np.ndarray:
    """Ritter's dam break on a dry horizontal frictionless bed (depth ``h0`` behind ``x0``).

    ``h = (2 c0 - (x - x0) / t)^2 / (9 g)`` in the rarefaction ``-c0 t <= x - x0 <= 2 c0 t``,
    ``c0 = sqrt(g h0)``: :func:`coulomb_dam_break` with ``theta = delta = 0``.
    """
    return coulomb_dam_break(x, t, h0, 0.0, 0.0, x0, gravity)


@dataclass(frozen=True)
class StokerDamBreak:
    """Stoker's dam break on a wet horizontal frictionless bed (Stoker 1957, "Water Waves",
    sec. 10.8): depth ``h_left`` behind ``x0``, ``h_right`` ahead, both at rest.

    A rarefaction ``-c_l t <= x - x0 <= (u_m - c_m) t`` (``c = sqrt(g h)``) leads to a
    uniform state ``(h_m, u_m)`` that ends at a shock moving at ``s``.  The middle state
    closes the Riemann invariant of the fan, ``u_m = 2 (c_l - c_m)``, with the
    Rankine-Hugoniot conditions of the shock into still water,
    ``u_m = (h_m - h_r) sqrt(g (h_m + h_r) / (2 h_m h_r))`` and ``s = h_m u_m / (h_m - h_r)``.
    """

    h_left: float
    h_right: float
    x0: float = 0.0
    gravity: float = GRAVITY

    def __post_init__(self) -> None:
        if not 0.0 < self.h_right < self.h_left:
            raise ValueError(
                f"Stoker's dam break needs 0 < h_right < h_left, got {self.h_right}, {self.h_left}"
            )

    @property
    def middle(self) -> tuple[float, float]:
        """``(h_m, u_m)``: the root in ``(h_r, h_l)`` of the fan's invariant minus the shock's
        velocity jump, which rises strictly from negative at ``h_r`` to positive at ``h_l``."""
        from scipy.optimize import brentq

        g, hl, hr = self.gravity, self.h_left, self.h_right
        c_left = math.sqrt(g * hl)

        def mismatch(hm: float) -> float:
            return 2.0 * (c_left - math.sqrt(g * hm)) - (hm - hr) * math.sqrt(g * (hm + hr) / (2.0 * hm * hr))

        hm = float(brentq(mismatch, hr, hl, xtol=1e-15, rtol=4 * np.finfo(float).eps))
        return hm, 2.0 * (c_left - math.sqrt(g * hm))

    @property
    def shock_speed(self) -> float:
        """``s = h_m u_m / (h_m - h_r)`` (mass conserved across the shock)."""
        hm, um = self.middle
        return hm * um / (hm - self.h_right)

    def solution(self, x: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(h, u)`` at positions ``x`` and time ``t > 0``; in the fan
        ``h = (2 c_l - xi)^2 / (9 g)`` and ``u = 2 (xi + c_l) / 3`` with ``xi = (x - x0) / t``."""
        g = self.gravity
        hm, um = self.middle
        c_left = math.sqrt(g * self.h_left)
        xi = (np.asarray(x, dtype=float) - self.x0) / t
        tail, shock = um - math.sqrt(g * hm), self.shock_speed
        zones = [xi < -c_left, xi < tail, xi < shock]
        h = np.select(zones, [self.h_left, (2 * c_left - xi) ** 2 / (9 * g), hm], self.h_right)
        u = np.select(zones, [0.0, 2.0 * (xi + c_left) / 3.0, um], 0.0)
        return h, u


# --------------------------------------------------------------------------- simple shear


@dataclass(frozen=True)
class InviscidSimpleShear:
    """One column of Drucker-Prager material (no viscosity) with a linear initial profile.

    ``U0(z) = shear (z - b0)_+`` on a slope ``theta`` with internal friction ``mu_s >
    tan(theta)`` (a no-slip base).  Bouchut, Ionescu & Mangeney (2016, Prop. 2.2): the
    flowing part decelerates uniformly at ``S = g cos(theta) (mu_s - tan(theta))``, so
    ``U(t, z) = max(U0(z) - S t, 0)`` and the static/flowing interface is
    ``b(t) = b0 + S t / shear`` until the column stops at ``t = shear (h - b0) / S``.
    """

    theta_deg: float
    mu_s: float
    depth: float
    b0: float
    shear: float
    gravity: float = GRAVITY

    @property
    def deceleration(self) -> float:
        """``S = g cos(theta) (mu_s - tan(theta))`` (m/s^2)."""
        th = math.radians(self.theta_deg)
        return self.gravity * math.cos(th) * (self.mu_s - math.tan(th))

    @property
    def stop_time(self) -> float:
        """Time at which the surface velocity reaches zero: ``shear (h - b0) / S``."""
        return self.shear * (self.depth - self.b0) / self.deceleration

    def velocity(self, z: np.ndarray, t: float) -> np.ndarray:
        """``U(t, z) = max(U0(z) - S t, 0)``."""
        initial = self.shear * np.maximum(np.asarray(z, dtype=float) - self.b0, 0.0)
        return np.maximum(initial - self.deceleration * t, 0.0)

    def interface(self, t: np.ndarray | float) -> np.ndarray:
        """Static/flowing interface ``b(t) = min(b0 + S t / shear, h)``."""
        return np.minimum(self.b0 + self.deceleration * np.asarray(t, dtype=float) / self.shear, self.depth)

    def layer_means(self, edges: np.ndarray, t: float) -> np.ndarray:
        """Mean of ``U(t, z)`` over each layer between consecutive heights ``edges`` (along
        the first axis): ``U = shear (z - b)_+`` with ``b = b0 + S t / shear``, whose
        antiderivative is ``shear (z - b)_+^2 / 2``."""
        edges = np.asarray(edges, dtype=float)
        b = self.b0 + self.deceleration * t / self.shear
        antiderivative = self.shear * np.maximum(edges - b, 0.0) ** 2 / 2
        return np.diff(antiderivative, axis=0) / np.diff(edges, axis=0)


# --------------------------------------------------------------------------- steady uniform flow


def jop_inertial_number(theta_deg: float, mu_s: float, mu_2: float, I_0: float, mu_inf: float = 0.0) -> float:
    """``I_theta`` with ``mu(I_theta) = tan(theta)`` for the Jop et al. (2006) law.

    ``mu_s + (mu_2 - mu_s) I / (I_0 + I) = tan(theta)`` gives
    ``I_theta = I_0 (tan(theta) - mu_s) / (mu_2 - tan(theta))``; a steady flow needs
    ``mu_s < tan(theta) < mu_2``.  With the high-I term ``mu_inf I^2 / (I_0 + I)`` (Barker &
    Gray 2017), ``mu_inf I^2 + (mu_2 - tan) I - (tan - mu_s) I_0 = 0``: its positive root,
    for any ``tan(theta) > mu_s``.
    """
    tan = math.tan(math.radians(theta_deg))
    if mu_inf > 0.0:
        if not tan > mu_s:
            raise ValueError(f"no steady flow: tan(theta) = {tan:.4g} <= mu_s = {mu_s:.4g}")
        b, c = mu_2 - tan, (tan - mu_s) * I_0
        return 2.0 * c / (b + math.sqrt(b * b + 4.0 * mu_inf * c))  # the positive root, without cancellation
    if not mu_s < tan < mu_2:
        raise ValueError(f"no steady flow: tan(theta) = {tan:.4g} is not between mu_s and mu_2")
    return I_0 * (tan - mu_s) / (mu_2 - tan)


def pouliquen_h_stop(theta_deg: float, mu_1: float, mu_2: float, L: float) -> float:
    """``h_stop(theta) = L (mu_2 - tan theta) / (tan theta - mu_1)`` (Forterre & Pouliquen
    2003): the thickest uniform layer at rest on the slope ``theta`` under the friction
    ``mu_stop(h) = mu_1 + (mu_2 - mu_1) / (1 + h / L)`` (its inverse), for ``mu_1 < tan theta
    < mu_2``."""
    tan = math.tan(math.radians(theta_deg))
    if not mu_1 < tan < mu_2:
        raise ValueError(f"no h_stop: tan(theta) = {tan:.4g} is not between mu_1 and mu_2")
    return L * (mu_2 - tan) / (tan - mu_1)


def pouliquen_beta(I_0: float, L: float, grain_diameter: float, density_ratio: float) -> float:
    """``beta`` of Pouliquen's (1999) flow rule ``Fr = beta h / h_stop`` for the steady flow
    of :class:`BagnoldFlow` under ``max(mu_stop(h), mu_J(I))`` (Jop, Forterre & Pouliquen
    2005, appendix A): ``I_theta = I_0 L / h_stop`` and ``Fr = (2/5) sqrt(rho/rho_p) I_theta
    h / d``, so ``beta = (2/5) sqrt(rho/rho_p) I_0 L / d``."""
    return 0.4 * math.sqrt(density_ratio) * I_0 * L / grain_diameter


def power_law_inertial_number(theta_deg: float, mu_s: float, m: float, alpha: float) -> float:
    """``I_theta`` with ``mu_s + m I^alpha = tan(theta)`` (Tsang et al. 2019, eq. 4.10).

    ``I_theta = ((tan(theta) - mu_s) / m)^(1 / alpha)``; a steady flow needs
    ``tan(theta) > mu_s``.
    """
    tan = math.tan(math.radians(theta_deg))
    if not tan > mu_s:
        raise ValueError(f"no steady flow: tan(theta) = {tan:.4g} <= mu_s = {mu_s:.4g}")
    return ((tan - mu_s) / m) ** (1.0 / alpha)


def friction_coefficient(
    rheology: Rheology, material: Material, pressure: float = 1.0e3
) -> Callable[[float], float]:
    """``mu(I) = tau / p`` of a bulk rheology plugin at pressure ``pressure`` (Pa)."""
    p = np.array([pressure])

    def mu(inertial_number: float) -> float:
        rate = inertial_number * np.sqrt(pressure / material.particle_density) / (material.grain_diameter)
        tau = rheology.yield_stress(p, material) + rheology.viscosity(np.array([rate]), p, material) * rate
        return float(tau[0] / pressure)

    return mu


def inertial_number_for_slope(mu: Callable[[float], float], theta_deg: float, upper: float = 1e3) -> float:
    """``I_theta`` solving ``mu(I) = tan(theta)`` numerically, for any monotone ``mu(I)``.

    The closed forms :func:`jop_inertial_number` and :func:`power_law_inertial_number`
    are checked against it.
    """
    from scipy.optimize import brentq

    target = np.tan(np.radians(theta_deg))
    if mu(0.0) >= target:
        raise ValueError(f"no steady flow: mu(0) = {mu(0.0):.4g} >= tan(theta) = {target:.4g}")
    if mu(upper) <= target:
        raise ValueError(f"no steady flow: mu(I) stays below tan(theta) = {target:.4g}")
    return float(brentq(lambda i: mu(i) - target, 0.0, upper, xtol=1e-14, rtol=1e-13))


@dataclass(frozen=True)
class BagnoldFlow:
    """Steady uniform mu(I) flow on a no-slip base (Tsang et al. 2019, eq. 4.1-4.3, u_s = 0).

    With ``p = rho g cos(theta) (h - z)`` and ``I = d |du/dz| / sqrt(p / rho_p)`` held at
    ``I_theta`` everywhere::

        u(z) = (2 I / (3 d)) sqrt(g cos(theta) rho / rho_p) (h^1.5 - (h - z)^1.5),

    ``density_ratio = rho / rho_p`` (the paper takes 1).
    """

    depth: float
    inertial_number: float
    grain_diameter: float
    theta_deg: float
    gravity: float = GRAVITY
    density_ratio: float = 1.0

    @property
    def _scale(self) -> float:
        """``(2 I / (3 d)) sqrt(g cos(theta) rho / rho_p)``, the factor of ``h^1.5 - (h - z)^1.5``."""
        root = math.sqrt(self.gravity * math.cos(math.radians(self.theta_deg)) * self.density_ratio)
        return 2.0 * self.inertial_number / (3.0 * self.grain_diameter) * root

    def velocity(self, z: np.ndarray) -> np.ndarray:
        """``u(z)``, with ``z`` clipped to ``[0, h]``."""
        z = np.clip(np.asarray(z, dtype=float), 0.0, self.depth)
        return self._scale * (self.depth**1.5 - (self.depth - z) ** 1.5)

    @property
    def surface_velocity(self) -> float:
        """``u(h) = (2 I / (3 d)) sqrt(g cos(theta) rho / rho_p) h^1.5``."""
        return float(self._scale * self.depth**1.5)

    @property
    def mean_velocity(self) -> float:
        """Depth average: 3/5 of the surface velocity (eq. 4.2-4.3)."""
        return 0.6 * self.surface_velocity

    def layer_means(self, edges: np.ndarray) -> np.ndarray:
        """Mean of ``u`` over each layer between consecutive heights ``edges``: the quantity a
        layer velocity approximates (antiderivative ``h^1.5 z + (h - z)^2.5 / 2.5``), with
        ``edges`` clipped to ``[0, h]`` (the top edge of a summed column may exceed ``h`` by
        round-off)."""
        edges = np.clip(np.asarray(edges, dtype=float), 0.0, self.depth)
        antiderivative = self._scale * (self.depth**1.5 * edges + (self.depth - edges) ** 2.5 / 2.5)
        return np.diff(antiderivative) / np.diff(edges)


def bagnold_depth(
    flux: float,
    inertial_number: float,
    grain_diameter: float,
    theta_deg: float,
    gravity: float = GRAVITY,
    density_ratio: float = 1.0,
) -> float:
    """Depth of the Bagnold flow carrying ``flux`` (m^2/s): Tsang et al. (2019), eq. 4.3,

    ``h_Bag = (5 d q / (2 I_theta sqrt(g cos(theta) rho / rho_p)))^(2/5)``, the depth that a
    chute flow of flux ``q`` reaches far downstream of a change to a no-slip base
    (``density_ratio = rho / rho_p``, 1 in the paper).
    """
    root = math.sqrt(gravity * math.cos(math.radians(theta_deg)) * density_ratio)
    return (5.0 * grain_diameter * flux / (2.0 * inertial_number * root)) ** 0.4
