"""Shared by the built-in laws: parameter checks (a ValueError is reported as exit 2) and
the frictional yield part."""

from __future__ import annotations

import numpy as np

from multilayer.plugins.contract import Rheology


def non_negative(**values: float) -> None:
    """Raise ValueError naming the first parameter that is negative (or nan)."""
    for key, value in values.items():
        if not value >= 0:
            raise ValueError(f"{key} must be >= 0, got {value!r}")


def positive(**values: float) -> None:
    """Raise ValueError naming the first parameter that is not > 0."""
    for key, value in values.items():
        if not value > 0:
            raise ValueError(f"{key} must be > 0, got {value!r}")


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
