"""Shared by the built-in laws: parameter checks (a ValueError is reported as exit 2) and
the frictional yield part."""

from __future__ import annotations

import numpy as np

import multilayer


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


class FrictionalYield(multilayer.Rheology):
    """The Drucker-Prager yield part shared by the frictional laws: kappa = mu_s max(p, 0)."""

    mu_s: float

    def yield_stress(self, pressure, material):
        """kappa = mu_s max(p, 0), Pa."""
        return self.mu_s * np.maximum(np.asarray(pressure, dtype=float), 0.0)
