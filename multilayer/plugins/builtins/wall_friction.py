"""Coulomb friction on the side walls of a channel (Jop, Forterre & Pouliquen 2005; docs/model.md).

    kappa(p) = mu_w max(p, 0),    eta = 0

The engine applies it to each layer velocity u_a through F_a = (2 mu_w / W) h_a pbar_a sgn(u_a).
"""

from __future__ import annotations

import numpy as np

from multilayer.plugins.builtins._checks import non_negative
from multilayer.plugins.contract import Rheology


class WallFriction(Rheology):
    """Coulomb side-wall friction mu_w p (no viscous part)."""

    name = "wall_friction"
    applies_to = "walls"

    def __init__(self, mu_w: float):
        """``mu_w``: wall friction coefficient (-)."""
        non_negative(mu_w=mu_w)
        self.mu_w = mu_w

    def yield_stress(self, pressure, material):
        """kappa = mu_w max(p, 0), Pa."""
        return self.mu_w * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def yield_stress_kernel(self, material):
        """The ``frictional`` form of :meth:`yield_stress` (the same at rest)."""
        return "frictional", (self.mu_w, self.mu_w)

    def viscosity(self, shear_rate, pressure, material):
        """eta = 0, Pa s."""
        return np.zeros(np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure)))

    def viscosity_kernel(self, material):
        """The ``constant`` form of :meth:`viscosity` (no viscous part)."""
        return "constant", (0.0,)
