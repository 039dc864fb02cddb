"""Drucker–Prager yield stress with a constant kinematic viscosity (DESIGN.md section 2).

    kappa(p) = mu_s max(p, 0),      eta = rho nu

(Bouchut, Ionescu & Mangeney 2016, eq. 1.3-1.8 with a constant viscous part.)
"""
from __future__ import annotations

import numpy as np

import multilayer
from rheologies._checks import non_negative


class DruckerPrager(multilayer.Rheology):
    """Drucker–Prager (Coulomb) yield stress mu_s p plus a constant viscosity rho nu."""

    name = "drucker_prager"
    applies_to = "bulk"

    def __init__(self, mu_s: float, nu: float):
        """``mu_s``: friction coefficient (-); ``nu``: kinematic viscosity (m^2/s)."""
        non_negative(mu_s=mu_s, nu=nu)
        self.mu_s = mu_s
        self.nu = nu

    def yield_stress(self, pressure, material):
        """kappa = mu_s max(p, 0), Pa."""
        return self.mu_s * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def viscosity(self, shear_rate, pressure, material):
        """eta = rho nu, Pa s, independent of the shear rate and pressure."""
        shape = np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure))
        return np.full(shape, material.density * self.nu)
