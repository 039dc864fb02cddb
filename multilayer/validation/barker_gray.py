"""The partially regularised mu(I) of Barker & Gray (2017, J. Fluid Mech. 828, 5-32): a
research law of the validation package, never registered as a plugin.

Jop, Forterre & Pouliquen's (2006) mu(I) makes the incompressible equations ill posed at
low and at high inertial numbers (Barker, Schaeffer, Bohorquez & Gray 2015, J. Fluid Mech.
779, 794-818): with ``nu = I mu'(I) / mu(I)`` a law is ill posed where (Barker & Gray 2017,
eq. 3.9, in the form of the OpenFOAM-muI implementation)::

    C(I) = 4 nu^2 - 4 nu + mu^2 (1 - nu / 2)^2 > 0,

which holds as ``I -> 0`` (``C -> mu_s^2``) and, for Jop's law, again above a second root.
Barker & Gray keep Jop's law with a high-I term between the lower root ``I_1`` of ``C`` and
infinity, and replace it below ``I_1`` by a branch that is well posed down to ``I = 0``::

    mu(I) = (mu_s I_0 + mu_2 I + mu_inf I^2) / (I_0 + I)     I >= I_1
    mu(I) = sqrt(alpha / ln(A / I))                          I <  I_1

with ``A = I_1 exp(alpha / mu(I_1)^2)`` for continuity (their eq. 6.4), ``alpha = 1.9`` and
``mu_inf = 0.05`` (the constants of the implementations).  ``mu -> 0`` as ``I -> 0``: the law
has no yield stress, so material on any slope creeps.  The project's laws keep an exact
yield stress (static means ``u == 0``); this one exists to compare, in the validation, what
the regularisation changes.  The engine needs a finite ``eta`` at rest: below
``I = I_FLOOR`` the stress is taken linear in the shear rate (``eta`` held at its value at
``I_FLOOR``).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq

from multilayer.plugins.contract import Material, Rheology

ALPHA = 1.9
"""alpha of the low-I branch (Barker & Gray 2017; the value of the implementations)."""
MU_INF = 0.05
"""mu_inf of the high-I term (idem)."""
I_FLOOR = 1e-9
"""Inertial number below which the stress is linear in the shear rate (finite eta at rest)."""


def jop_friction(
    inertial: np.ndarray, mu_s: float, mu_2: float, I_0: float, mu_inf: float = 0.0
) -> np.ndarray:
    """``(mu_s I_0 + mu_2 I + mu_inf I^2) / (I_0 + I)`` (Jop et al. 2006 with Barker & Gray's
    high-I term)."""
    i = np.asarray(inertial, dtype=float)
    return (mu_s * I_0 + mu_2 * i + mu_inf * i * i) / (I_0 + i)


def ill_posedness(inertial: np.ndarray, mu_s: float, mu_2: float, I_0: float) -> np.ndarray:
    """``C(I)`` of Jop's law (no high-I term): ill posed where it is positive."""
    i = np.asarray(inertial, dtype=float)
    mu = jop_friction(i, mu_s, mu_2, I_0)
    nu = i * (mu_2 - mu_s) * I_0 / (I_0 + i) ** 2 / mu
    return 4.0 * nu * nu - 4.0 * nu + mu * mu * (1.0 - 0.5 * nu) ** 2


def well_posed_window(mu_s: float, mu_2: float, I_0: float) -> tuple[float, float]:
    """``(I_1, I_2)``: the roots of :func:`ill_posedness` between which Jop's law is well
    posed (nan, nan if it is nowhere well posed)."""
    grid = np.logspace(-8, 3, 2201)
    c = ill_posedness(grid, mu_s, mu_2, I_0)
    changes = np.flatnonzero(np.sign(c[:-1]) != np.sign(c[1:]))
    if changes.size < 2:
        return math.nan, math.nan

    def root(k: int) -> float:
        def c(i: float) -> float:
            return float(ill_posedness(np.array(i), mu_s, mu_2, I_0))

        return float(brentq(c, grid[k], grid[k + 1], xtol=1e-15, rtol=1e-14))

    return root(changes[0]), root(changes[1])


class PartialRegularisation(Rheology):
    """Barker & Gray (2017) partially regularised mu(I) (research law: no yield stress)."""

    name = "barker_gray_2017"
    applies_to = "bulk"

    def __init__(self, mu_s: float, mu_2: float, I_0: float, mu_inf: float = MU_INF, alpha: float = ALPHA):
        """Jop's ``mu_s < mu_2``, ``I_0 > 0`` and the regularisation's ``mu_inf >= 0``, ``alpha > 0``."""
        if not (0.0 < mu_s < mu_2 and I_0 > 0.0 and mu_inf >= 0.0 and alpha > 0.0):
            raise ValueError("need 0 < mu_s < mu_2, I_0 > 0, mu_inf >= 0, alpha > 0")
        self.mu_s, self.mu_2, self.I_0, self.mu_inf, self.alpha = mu_s, mu_2, I_0, mu_inf, alpha
        self.I_1 = well_posed_window(mu_s, mu_2, I_0)[0]
        if not math.isfinite(self.I_1):
            raise ValueError("Jop's law with these parameters is nowhere well posed")
        mu_1 = float(jop_friction(np.array(self.I_1), mu_s, mu_2, I_0, mu_inf))
        self.A = self.I_1 * math.exp(alpha / mu_1**2)
        """``A`` of the low-I branch (Barker & Gray 2017, eq. 6.4)."""

    def friction(self, inertial: np.ndarray) -> np.ndarray:
        """``mu(I)``, both branches; ``mu(0) = 0``."""
        i = np.asarray(inertial, dtype=float)
        low = np.sqrt(self.alpha / np.log(self.A / np.clip(i, 1e-300, self.I_1)))
        high = jop_friction(i, self.mu_s, self.mu_2, self.I_0, self.mu_inf)
        return np.where(i >= self.I_1, high, np.where(i > 0.0, low, 0.0))

    def yield_stress(self, pressure: np.ndarray, material: Material) -> np.ndarray:
        """None: ``mu(0) = 0``."""
        return np.zeros(np.shape(pressure))

    def viscosity(self, shear_rate: np.ndarray, pressure: np.ndarray, material: Material) -> np.ndarray:
        """``eta = mu(I) p / |gamma|`` with ``I = d |gamma| / sqrt(p / rho_p)`` held at least
        :data:`I_FLOOR` in both; 0 where ``p <= 0``."""
        p = np.maximum(np.asarray(pressure, dtype=float), 0.0)
        root = np.sqrt(p / material.particle_density)
        inertial = np.maximum(material.grain_diameter * np.abs(shear_rate), I_FLOOR * root)
        wet = p > 0.0
        safe = np.where(wet, inertial, 1.0)
        mu = self.friction(safe / np.where(wet, root, 1.0))
        return np.where(wet, mu * p * material.grain_diameter / safe, 0.0)
