"""A mu(I) law with a thickness below which flow stops (docs/model.md, "Rheologies").

The friction of a layer of thickness ``h`` (Jop, Forterre & Pouliquen 2005, appendix A;
Forterre & Pouliquen 2003, eq. 2.3)::

    mu(I, h) = max(mu_stop(h), mu_J(I)),
    mu_stop(h) = mu_1 + (mu_2 - mu_1) / (1 + h / L),
    mu_J(I)    = mu_1 + (mu_2 - mu_1) I / (I_0 + I),    I = d |gamma| / sqrt(p / rho_p),

split as ``kappa = mu_stop(h) max(p, 0)`` (exact yield) and the viscous stress
``eta |gamma| = max(p, 0) max(0, mu_J(I) - mu_stop(h))``.  ``h`` is the thickness of the
column (``Rheology.uses``).  A uniform layer on a slope ``theta`` is at rest if and only if
``tan(theta) <= mu_stop(h)``, i.e. ``h <= h_stop(theta) = L (mu_2 - tan theta)/(tan theta -
mu_1)`` (Pouliquen 1999; the form of Forterre & Pouliquen 2003); a thicker one flows on the
``mu_J`` branch, where ``I_theta = I_0 L / h_stop`` and the Bagnold profile gives Pouliquen's
(1999) flow rule ``Fr = u / sqrt(g h cos theta) = beta h / h_stop`` with ``beta = (2/5)
sqrt(phi) I_0 L / d``, ``phi = rho / rho_p`` (Jop et al. 2005, appendix A).
Optional hysteresis (Pouliquen & Forterre 2002): material at rest holds up to
``mu_start(h) = mu_3 + (mu_2 - mu_1) / (1 + h / L)``, ``mu_3 >= mu_1``.
"""

from __future__ import annotations

import numpy as np

from multilayer.plugins.builtins._checks import inertial_scale, non_negative, positive
from multilayer.plugins.contract import Rheology


class PouliquenForterre(Rheology):
    """mu(I) with the thickness-dependent stop friction of Forterre & Pouliquen (2003)."""

    name = "pouliquen_forterre"
    applies_to = "bulk"
    uses = ("thickness",)

    def __init__(self, mu_1: float, mu_2: float, L: float, I_0: float, mu_3: float | None = None):
        """``mu_1`` = tan(delta_1) < ``mu_2`` = tan(delta_2) (-): the slopes below which no
        layer flows and above which every layer flows; ``L`` > 0 (m): the length of
        h_stop(theta); ``I_0`` > 0 (-); ``mu_3`` >= ``mu_1`` (-): the start friction's
        constant, default ``mu_1`` (no hysteresis)."""
        non_negative(mu_1=mu_1)
        positive(L=L)
        inertial_scale(I_0)
        if not mu_2 > mu_1:
            raise ValueError(f"mu_2 must be > mu_1 = {mu_1!r}, got {mu_2!r}")
        mu_3 = mu_1 if mu_3 is None else mu_3
        if not mu_3 >= mu_1:
            raise ValueError(f"mu_3 must be >= mu_1 = {mu_1!r}, got {mu_3!r}")
        non_negative(mu_2=mu_2, mu_3=mu_3)
        self.mu_1, self.mu_2, self.L, self.I_0, self.mu_3 = mu_1, mu_2, L, I_0, mu_3

    def mu_stop(self, thickness: np.ndarray, constant: float | None = None) -> np.ndarray:
        """``mu_1 + (mu_2 - mu_1) / (1 + h / L)`` (``constant`` replacing ``mu_1``)."""
        base = self.mu_1 if constant is None else constant
        return base + (self.mu_2 - self.mu_1) / (1.0 + np.asarray(thickness, dtype=float) / self.L)

    def yield_stress(self, pressure, material, *, thickness):
        """kappa = mu_stop(h) max(p, 0), Pa."""
        return self.mu_stop(thickness) * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def static_yield_stress(self, pressure, material, *, thickness):
        """kappa_static = mu_start(h) max(p, 0), Pa."""
        return self.mu_stop(thickness, self.mu_3) * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def viscosity(self, shear_rate, pressure, material, *, thickness):
        """eta = max(p, 0) max(0, mu_J(I) - mu_stop(h)) / |gamma|, Pa s (0 at rest)."""
        p = np.maximum(np.asarray(pressure, dtype=float), 0.0)
        rate = np.abs(np.asarray(shear_rate, dtype=float))
        scale = material.grain_diameter * np.sqrt(material.particle_density)
        root = np.sqrt(p)
        inertial = np.divide(scale * rate, root, out=np.zeros(np.broadcast(rate, root).shape), where=root > 0)
        mu_j = self.mu_1 + (self.mu_2 - self.mu_1) * inertial / (self.I_0 + inertial)
        tau = p * np.maximum(mu_j - self.mu_stop(thickness), 0.0)
        return np.divide(tau, rate, out=np.zeros(tau.shape), where=rate > 0)

    def yield_stress_kernel(self, material):
        """The ``frictional_thickness`` form of :meth:`yield_stress` and
        :meth:`static_yield_stress` (the operations of :meth:`mu_stop`)."""
        return "frictional_thickness", (self.mu_1, self.mu_3, self.mu_2 - self.mu_1, self.L)

    def viscosity_kernel(self, material):
        """The ``inertial_plateau`` form of :meth:`viscosity`: ``(mu_2 - mu_1) p I / (I_0 + I)``
        is ``A p |gamma| / (B sqrt(p) + C |gamma|)`` with ``C = d sqrt(rho_p)``, ``A = (mu_2 -
        mu_1) C``, ``B = I_0``, less the plateau ``(mu_2 - mu_1) p / (1 + h / L)``."""
        scale = material.grain_diameter * np.sqrt(material.particle_density)
        drop = self.mu_2 - self.mu_1
        return "inertial_plateau", (drop * scale, self.I_0, scale, drop, self.L)
