"""Jop, Forterre & Pouliquen (2006) mu(I) rheology (docs/model.md, "Rheologies").

    mu(I) = mu_s + (mu_2 - mu_s) I / (I_0 + I),    I = d |gamma| / sqrt(p / rho_p)

split as kappa = mu_s p and eta |gamma| = (mu_2 - mu_s) p I / (I_0 + I).  Since
I / |gamma| = d sqrt(rho_p / p), multiplying through by sqrt(p) gives the form used here,

    eta = (mu_2 - mu_s) d sqrt(rho_p) p / (I_0 sqrt(p) + d sqrt(rho_p) |gamma|),

which is finite everywhere: eta -> (mu_2 - mu_s) d sqrt(rho_p p) / I_0 as gamma -> 0 and
eta -> 0 as p -> 0 (pressure is clamped at 0; eta = 0 at p = gamma = 0, its limit).
Optional start/stop friction: ``mu_start max(p, 0)`` at rest (Pouliquen & Forterre 2002).
Optional high-I term (the regularisation of large inertial numbers of Barker & Gray 2017):
``mu_inf I^2 / (I_0 + I)`` added to mu(I), which then grows like ``mu_inf I``, i.e.
``mu_inf d^2 rho_p |gamma| sqrt(p) / (I_0 sqrt(p) + d sqrt(rho_p) |gamma|)`` added to eta;
the yield part, and so exact rest, is unchanged.
"""

from __future__ import annotations

import numpy as np

from multilayer.plugins.builtins._checks import FrictionalYield, inertial_scale, non_negative


class JopMuI(FrictionalYield):
    """Jop et al. (2006) mu(I): friction rising from mu_s to mu_2 with the inertial number."""

    name = "jop_mu_i"
    applies_to = "bulk"

    def __init__(
        self, mu_s: float, mu_2: float, I_0: float, mu_start: float | None = None, mu_inf: float = 0.0
    ):
        """``mu_s`` <= ``mu_2``: friction at I -> 0 and I -> infinity (-); ``I_0`` > 0 (-);
        ``mu_start`` >= ``mu_s``: friction of material at rest (-), default ``mu_s``;
        ``mu_inf`` >= 0: the high-I coefficient (-), default 0 (Jop's law)."""
        self._set_friction(mu_s, mu_start)
        inertial_scale(I_0)
        non_negative(mu_inf=mu_inf)
        self.mu_inf = mu_inf
        if not mu_2 >= mu_s:
            raise ValueError(f"mu_2 must be >= mu_s = {mu_s!r}, got {mu_2!r}")
        non_negative(mu_2=mu_2)
        self.mu_2 = mu_2
        self.I_0 = I_0

    def viscosity(self, shear_rate, pressure, material):
        """eta = p ((mu_2 - mu_s) I + mu_inf I^2) / (|gamma| (I_0 + I)), Pa s, finite at
        gamma = 0 and p = 0."""
        p = np.maximum(np.asarray(pressure, dtype=float), 0.0)
        scale = material.grain_diameter * np.sqrt(material.particle_density)
        numerator = (self.mu_2 - self.mu_s) * scale * p
        denominator = self.I_0 * np.sqrt(p) + scale * np.abs(shear_rate)
        if self.mu_inf > 0.0:
            numerator = numerator + self.mu_inf * scale * scale * np.abs(shear_rate) * np.sqrt(p)
        return np.divide(numerator, denominator, out=np.zeros(denominator.shape), where=denominator > 0)

    def viscosity_kernel(self, material):
        """The ``inertial`` form of :meth:`viscosity` (same constants, same operations), or
        with ``mu_inf`` the ``inertial_quadratic`` one."""
        scale = material.grain_diameter * np.sqrt(material.particle_density)
        if self.mu_inf > 0.0:
            return "inertial_quadratic", (
                (self.mu_2 - self.mu_s) * scale,
                self.I_0,
                scale,
                self.mu_inf * scale * scale,
            )
        return "inertial", ((self.mu_2 - self.mu_s) * scale, self.I_0, scale)
