"""Drucker–Prager yield stress with a constant kinematic viscosity (docs/model.md, "Rheologies").

    kappa(p) = mu_s max(p, 0),      eta = rho nu

(Bouchut, Ionescu & Mangeney 2016, eq. 1.3-1.8 with a constant viscous part); with
``nu = 0`` the pure Coulomb (constant friction) law.  Optional start/stop friction:
``mu_start max(p, 0)`` at rest (Pouliquen & Forterre 2002).
"""

from __future__ import annotations

import numpy as np

from multilayer.plugins.builtins._checks import FrictionalYield, non_negative

#: the smallest non-zero kinematic viscosity (m^2/s): below about 1e-90 the vertical step's
#: products underflow and give NaN (found by the property tests); granular flows have 1e-6 and more
SMALLEST_VISCOSITY = 1e-30


class DruckerPrager(FrictionalYield):
    """Drucker–Prager (Coulomb) yield stress mu_s p plus a constant viscosity rho nu."""

    name = "drucker_prager"
    applies_to = "bulk"

    def __init__(self, mu_s: float, nu: float, mu_start: float | None = None):
        """``mu_s``: friction coefficient (-); ``nu``: kinematic viscosity (m^2/s);
        ``mu_start`` >= ``mu_s``: friction of material at rest (-), default ``mu_s``."""
        self._set_friction(mu_s, mu_start)
        non_negative(nu=nu)
        if 0 < nu < SMALLEST_VISCOSITY:
            raise ValueError(
                f"nu must be 0 or at least {SMALLEST_VISCOSITY:g} m^2/s (a smaller viscosity underflows "
                f"beside the yield stress in double precision: use 0), got {nu!r}"
            )
        self.nu = nu

    def viscosity(self, shear_rate, pressure, material):
        """eta = rho nu, Pa s, independent of the shear rate and pressure."""
        shape = np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure))
        return np.full(shape, material.density * self.nu)

    def viscosity_kernel(self, material):
        """The ``constant`` form of :meth:`viscosity`."""
        return "constant", (material.density * self.nu,)
