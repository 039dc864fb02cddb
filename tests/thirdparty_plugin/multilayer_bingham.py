"""A third-party rheology plugin for multilayer: the Bingham plastic.

    tau = tau_y sgn(gamma) + eta gamma     (|tau| <= tau_y at rest)

i.e. a pressure-independent yield stress ``tau_y`` (Pa) and a constant viscosity
``eta`` (Pa s).
"""

import numpy as np

import multilayer


class Bingham(multilayer.Rheology):
    """Bingham plastic: constant yield stress, constant viscosity."""

    name = "bingham"
    applies_to = "bulk"

    def __init__(self, tau_y: float, eta: float):
        if tau_y < 0 or eta < 0:
            raise ValueError(f"tau_y and eta must be >= 0, got tau_y={tau_y}, eta={eta}")
        self.tau_y = tau_y
        self.eta = eta

    def yield_stress(self, pressure, material):
        """kappa = tau_y, Pa."""
        return np.full(np.shape(pressure), self.tau_y)

    def viscosity(self, shear_rate, pressure, material):
        """eta, Pa s."""
        return np.full(np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure)), self.eta)


@multilayer.hookimpl
def multilayer_register_rheologies(register):
    """Make ``rheology: {name: bingham, tau_y: ..., eta: ...}`` available."""
    register(Bingham)
