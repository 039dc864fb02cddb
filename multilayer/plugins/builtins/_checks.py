"""Shared by the built-in laws: parameter checks (a ValueError is reported as exit 2) and
the frictional yield part."""

from __future__ import annotations

import numpy as np

from multilayer.plugins.contract import Rheology

LARGEST = 1e100
"""The largest magnitude of a built-in law's parameter, and ``1 / LARGEST`` the smallest one
a law divides by (``L``, ``shear_rate_floor``, ``alpha``; ``I_0``: :data:`SMALLEST_I_0`).  The
laws multiply and divide their parameters by the run's pressures, rates and lengths and by each other:
``mu_s: 1e308`` times any pressure overflowed in the law, ``I_0: 1e-308`` in the vertical
step (the run stopped at its first step, exit 1).  Within these bounds the laws' constants
and their products with each other are finite numbers; granular and fluid parameters lie
many decades inside them."""


SMALLEST_I_0 = 1e-8
"""The smallest ``I_0`` of the mu(I) laws (``jop_mu_i``, ``pouliquen_forterre``).  The friction
rises from ``mu_s`` to ``mu_2`` over inertial numbers of order ``I_0``, that is over velocity
jumps ``I_0 sqrt(p / rho_p) dz / d`` between layers of spacing ``dz``: with ``dz`` at least a
grain and ``sqrt(p / rho_p)`` of the order of the flow's speed, about ``I_0`` times that
speed.  The vertical step resolves velocities to its tolerance (1e-10 of the velocity scale
by default) and to round-off (1e-16 of it), so below these the law is a step from ``mu_s``
to ``mu_2`` set by round-off: the compiled and numpy Newton iterations (tangent and forward
difference slopes) gave the same run to 3e-11 m/s from ``I_0 = 0.3`` down to ``1e-10``, to
2e-7 m/s at ``1e-14`` and 0.5 m/s apart at ``1e-50`` (where the compiled step also met pivots
of 0, its conductances 1e47 times the layers' inertia).  Measured values lie between 0.005
(Boyer, Guazzelli & Pouliquen 2011) and about 1 (0.279 for glass beads, Jop, Forterre &
Pouliquen 2005): ``1e-8`` is 5 decades below them and 100 times above the smallest value
tested to agree.  The limit ``I_0 -> 0`` is ``drucker_prager`` with ``mu_s = mu_2``."""


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


def inertial_scale(I_0: float) -> None:
    """Raise ValueError unless ``I_0`` of a mu(I) law is between :data:`SMALLEST_I_0` and
    :data:`LARGEST`."""
    if not I_0 > 0:
        raise ValueError(f"I_0 must be > 0, got {I_0!r}")
    if not SMALLEST_I_0 <= I_0 <= LARGEST:
        raise ValueError(
            f"I_0 must be between {SMALLEST_I_0:g} and {LARGEST:g}, got {I_0!r} (below, the friction's "
            "rise with the inertial number is finer than the vertical step resolves)"
        )


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
