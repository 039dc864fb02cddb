"""Shared by the built-in laws: parameter checks (a ValueError is reported as exit 2) and
the frictional yield part."""

from __future__ import annotations

import numpy as np

from multilayer.plugins.contract import Rheology

LARGEST = 1e100
"""The largest magnitude of a built-in law's parameter, and ``1 / LARGEST`` the smallest one
a law divides by (``I_0``, ``L``, ``shear_rate_floor``, ``alpha``).  The laws multiply and
divide their parameters by the run's pressures, rates and lengths and by each other:
``mu_s: 1e308`` times any pressure overflowed in the law, ``I_0: 1e-308`` in the vertical
step (the run stopped at its first step, exit 1).  Within these bounds the laws' constants
and their products with each other are finite numbers; granular and fluid parameters lie
many decades inside them."""


def non_negative(**values: float) -> None:
    """Raise ValueError naming the first parameter that is negative (or nan) or above
    :data:`LARGEST`."""
    for key, value in values.items():
        if not value >= 0:
            raise ValueError(f"{key} must be >= 0, got {value!r}")
        if value > LARGEST:
            raise ValueError(f"{key} must be at most {LARGEST:g}, got {value!r}")


def positive(**values: float) -> None:
    """Raise ValueError naming the first parameter that is not > 0, or beyond :data:`LARGEST`
    or its inverse."""
    for key, value in values.items():
        if not value > 0:
            raise ValueError(f"{key} must be > 0, got {value!r}")
        if not 1 / LARGEST <= value <= LARGEST:
            raise ValueError(f"{key} must be between {1 / LARGEST:g} and {LARGEST:g}, got {value!r}")


class FrictionalYield(Rheology):
    """The Drucker-Prager yield part shared by the frictional laws: kappa = mu_s max(p, 0)
    while flowing, and ``mu_start max(p, 0)`` at rest (start/stop friction, Pouliquen &
    Forterre 2002: material at rest starts above tan(theta) = mu_start, flowing material
    stops below mu_s)."""

    mu_s: float
    mu_start: float

    def _set_friction(self, mu_s: float, mu_start: float | None) -> None:
        """Set ``mu_s`` and ``mu_start`` (default ``mu_s``: no hysteresis); mu_start >= mu_s."""
        non_negative(mu_s=mu_s)
        mu_start = mu_s if mu_start is None else mu_start
        if not mu_start >= mu_s:
            raise ValueError(f"mu_start must be >= mu_s = {mu_s!r}, got {mu_start!r}")
        non_negative(mu_start=mu_start)
        self.mu_s = mu_s
        self.mu_start = mu_start

    def yield_stress(self, pressure, material):
        """kappa = mu_s max(p, 0), Pa."""
        return self.mu_s * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def static_yield_stress(self, pressure, material):
        """kappa_static = mu_start max(p, 0), Pa."""
        return self.mu_start * np.maximum(np.asarray(pressure, dtype=float), 0.0)

    def yield_stress_kernel(self, material):
        """The ``frictional`` form of :meth:`yield_stress` and :meth:`static_yield_stress`."""
        return "frictional", (self.mu_s, self.mu_start)
