"""Power-law mu(I) rheology (Gray & Edwards-type fit; Tsang, Dalziel & Vriend 2019, eq. 4.10).

    mu(I) = mu_s + m I^alpha,    I = d |gamma| / sqrt(p / rho_p)

split as kappa = mu_s p and eta |gamma| = m p I^alpha, i.e.

    eta = m (d sqrt(rho_p))^alpha p^(1 - alpha/2) |gamma|^(alpha - 1).

With 0 < alpha < 2 this vanishes as p -> 0.  For alpha < 1 it is infinite at
gamma = 0, so eta is evaluated at max(|gamma|, shear_rate_floor): below the floor
(default 1e-6 1/s) the viscous stress is linear in gamma instead of following I^alpha,
and eta stays finite (its largest value is eta at the floor).  Optional start/stop
friction: ``mu_start max(p, 0)`` at rest (Pouliquen & Forterre 2002).
"""

from __future__ import annotations

import numpy as np

from multilayer.plugins.builtins._checks import FrictionalYield, non_negative, positive


class PowerLawMuI(FrictionalYield):
    """Power-law mu(I) = mu_s + m I^alpha (Tsang et al. boundary-layer fit)."""

    name = "power_law_mu_i"
    applies_to = "bulk"

    def __init__(
        self,
        mu_s: float,
        m: float,
        alpha: float,
        shear_rate_floor: float = 1e-6,
        mu_start: float | None = None,
    ):
        """``mu_s``, ``m`` >= 0 (-); 0 < ``alpha`` < 2 (-); ``shear_rate_floor`` > 0 (1/s);
        ``mu_start`` >= ``mu_s``: friction of material at rest (-), default ``mu_s``."""
        self._set_friction(mu_s, mu_start)
        non_negative(m=m)
        positive(alpha=alpha, shear_rate_floor=shear_rate_floor)
        if not alpha < 2:
            raise ValueError(f"alpha must be < 2 (eta must vanish as p -> 0), got {alpha!r}")
        self.m = m
        self.alpha = alpha
        self.shear_rate_floor = shear_rate_floor

    def viscosity(self, shear_rate, pressure, material):
        """eta = m p I^alpha / |gamma| at |gamma| >= shear_rate_floor, Pa s."""
        p = np.maximum(np.asarray(pressure, dtype=float), 0.0)
        rate = np.maximum(np.abs(shear_rate), self.shear_rate_floor)
        scale = (material.grain_diameter * np.sqrt(material.particle_density)) ** self.alpha
        return self.m * scale * p ** (1.0 - self.alpha / 2) * rate ** (self.alpha - 1.0)

    def viscosity_kernel(self, material):
        """The ``power`` form of :meth:`viscosity` (same constants, same operations)."""
        scale = (material.grain_diameter * np.sqrt(material.particle_density)) ** self.alpha
        return "power", (self.m * scale, 1.0 - self.alpha / 2, self.alpha - 1.0, self.shear_rate_floor)
