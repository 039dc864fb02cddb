"""Coulomb friction with dilatancy, for grain–fluid mixtures (docs/mixture.md).

The stress of Bouchut, Fernández-Nieto, Mangeney & Narbona-Reina (2016, J. Fluid Mech.
801) at effective pressure ``p_s`` and shear rate ``gamma``, after Pailha & Pouliquen
(2009, J. Fluid Mech. 633)::

    tau = (tan(delta) + tan(psi)) p_s + K1 eta_f gamma,
    tan(psi) = K (phi - phi_eq),   phi_eq = phi_c - K2 eta_f gamma / p_s,

splits exactly into a rate-independent yield part and a linear viscous part, because
``tan(psi) p_s = K (phi - phi_c) p_s + K K2 eta_f gamma``::

    kappa = max(tan(delta) + K (phi - phi_c), 0) max(p_s, 0),    eta = (K1 + K K2) eta_f.

(The clip at 0 applies to packings looser than ``phi_c - tan(delta)/K``, which cannot
rest.)  Without a fluid it is the Coulomb law ``tan(delta) max(p, 0)``.
"""

from __future__ import annotations

import math

import numpy as np

from multilayer.plugins.builtins._checks import non_negative
from multilayer.plugins.contract import Material, MixtureState, Rheology


class DilatantCoulomb(Rheology):
    """Coulomb friction tan(delta) plus the dilatancy friction and the viscous friction
    ``K1 eta_f gamma`` of an immersed granular layer."""

    name = "dilatant_coulomb"
    applies_to = "bulk"

    def __init__(self, delta_deg: float, K1: float):
        """``delta_deg``: friction angle at the critical state (degrees, in [0, 90));
        ``K1``: viscous friction constant (-)."""
        non_negative(delta_deg=delta_deg, K1=K1)
        if not delta_deg < 90.0:
            raise ValueError(f"delta_deg must be < 90, got {delta_deg!r}")
        self.tan_delta = math.tan(math.radians(delta_deg))
        self.K1 = K1

    def yield_stress(self, pressure, material):
        """Without a fluid: ``tan(delta) max(p, 0)``, Pa."""
        return self.tan_delta * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def viscosity(self, shear_rate, pressure, material):
        """Without a fluid: no viscous part."""
        return np.zeros(np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure)))

    def mixture_yield_stress(
        self, pressure: np.ndarray, mixture: MixtureState, material: Material
    ) -> np.ndarray:
        """``max(tan(delta) + K (phi - phi_c), 0) max(p_s, 0)``, Pa."""
        friction = self.tan_delta + mixture.dilatancy * (np.asarray(mixture.phi) - mixture.phi_critical)
        return np.maximum(friction, 0.0) * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def mixture_viscosity(
        self, shear_rate: np.ndarray, pressure: np.ndarray, mixture: MixtureState, material: Material
    ) -> np.ndarray:
        """``(K1 + K K2) eta_f``, Pa s."""
        eta = (self.K1 + mixture.dilatancy * mixture.critical_shift) * mixture.fluid_viscosity
        return np.full(np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure)), eta)

    def mixture_kernel(self, material):
        """The compiled ``dilatant`` form of the two mixture methods above."""
        return "dilatant", (self.tan_delta, self.K1)
