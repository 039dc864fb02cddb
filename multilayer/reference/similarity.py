"""The granular Blasius boundary layer of a chute flow and the measures compared with it.

Tsang, Dalziel & Vriend (2019, J. Fluid Mech., eq. 4.15-4.18): downstream of a change
from a slipping to a no-slip base, a power-law ``mu(I) ~ mu_s + m I**alpha`` gives the
self-similar profile ``u / U = f'(zeta)``, ``zeta = z / Lambda(x)``,
``Lambda = eps H (x / H)**(1 / (1 + alpha))``, with ``f`` solving (eq. 4.16)::

    f''' + (f'')**(2 - alpha) f / (1 + alpha) = 0,  f(0) = f'(0) = 0,  f'(inf) = 1.

For ``alpha = 1`` this is the classical Blasius equation ``f''' + f f'' / 2 = 0``.

The similarity equation is solved by shooting on ``f''(0)`` (``solve_ivp`` + ``brentq``).
For ``alpha < 1`` the far field is algebraic (``1 - f' ~ zeta**(-2 / (1 - alpha))``), so
the integration stops at a finite ``zeta_max`` and the remainder is added from the
leading-order tail: with ``f ~ f_m + (zeta - zeta_m)`` beyond ``zeta_m`` the equation for
``g = f''`` integrates in closed form.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.integrate import quad, solve_ivp
from scipy.optimize import brentq

_RTOL = 1e-11
_ATOL = 1e-13


def _tail_curvature(s: np.ndarray, g_m: float, f_m: float, alpha: float) -> np.ndarray:
    """Leading-order ``f''(zeta_m + s)`` for ``s >= 0`` given ``f''`` and ``f`` at ``zeta_m``.

    Integrates ``g' = -f g**(2 - alpha) / (1 + alpha)`` with ``f = f_m + s``.
    """
    c = 1.0 / (1.0 + alpha)
    phase = c * (f_m * s + 0.5 * s * s)
    if np.isclose(alpha, 1.0):
        return g_m * np.exp(-phase)
    p = 2.0 - alpha
    return (g_m ** (1.0 - p) + (p - 1.0) * phase) ** (-1.0 / (p - 1.0))


@dataclass(frozen=True)
class SimilaritySolution:
    """Solution of the granular Blasius equation (Tsang et al. 2019, eq. 4.16)."""

    alpha: float
    """Exponent of the power-law mu(I)."""
    fpp0: float
    """Wall curvature ``f''(0)`` found by shooting."""
    zeta_max: float
    """End of the numerical integration; the tail beyond is analytic."""

    @cached_property
    def _ode(self):
        return _integrate(self.alpha, self.fpp0, self.zeta_max, dense=True)

    @cached_property
    def _tail_excess(self) -> float:
        """``int_{zeta_max}^inf (1 - f') dzeta``, from the analytic tail."""
        f_m, _, g_m = self._ode.y[:, -1]
        return _tail_moment(f_m, g_m, self.alpha, 1)

    @cached_property
    def _tail_table(self) -> tuple[np.ndarray, np.ndarray]:
        """``1 - f'`` on a geometric grid of ``s = zeta - zeta_max`` (trapezoid from the far end)."""
        f_m, _, g_m = self._ode.y[:, -1]
        s = np.concatenate([[0.0], np.geomspace(1e-4, 1e8, 6000)])
        g = _tail_curvature(s, g_m, f_m, self.alpha)
        pieces = 0.5 * (g[1:] + g[:-1]) * np.diff(s)
        remainder = np.concatenate([np.cumsum(pieces[::-1])[::-1], [0.0]])
        # beyond 1e8, g ~ s**(-2/(1-alpha)) (or Gaussian for alpha = 1): negligible
        return s, remainder

    def velocity(self, zeta: np.ndarray) -> np.ndarray:
        """Scaled velocity ``u / U = f'(zeta)`` for ``zeta >= 0``."""
        zeta = np.atleast_1d(np.asarray(zeta, dtype=float))
        fp = self._ode.sol(np.clip(zeta, 0.0, self.zeta_max))[1]
        beyond = zeta > self.zeta_max
        if np.any(beyond):
            s, remainder = self._tail_table
            fp[beyond] = 1.0 - np.interp(zeta[beyond] - self.zeta_max, s, remainder)
        return fp

    @property
    def displacement_thickness(self) -> float:
        """``zeta_disp = lim (zeta - f(zeta))`` (eq. 4.17); about 4.35 for alpha = 0.34."""
        f_m = self._ode.y[0, -1]
        return float(self.zeta_max - f_m + self._tail_excess)

    @property
    def momentum_thickness(self) -> float:
        """``int_0^inf f' (1 - f') dzeta`` (0.6641 for the classical Blasius layer)."""

        def integrand(z: float) -> float:
            fp = self._ode.sol(z)[1]
            return fp * (1.0 - fp)

        inner = quad(integrand, 0.0, self.zeta_max, limit=500, epsabs=1e-13)[0]
        return float(inner + self._tail_excess)


def _rhs(alpha: float):
    c = 1.0 / (1.0 + alpha)
    p = 2.0 - alpha

    def rhs(_zeta: float, y: np.ndarray) -> np.ndarray:
        f, fp, g = y
        return np.array([fp, g, -c * np.maximum(g, 0.0) ** p * f])

    return rhs


def _integrate(alpha: float, fpp0: float, zeta_max: float, dense: bool = False):
    return solve_ivp(
        _rhs(alpha),
        (0.0, zeta_max),
        [0.0, 0.0, fpp0],
        method="DOP853",
        rtol=_RTOL,
        atol=_ATOL,
        dense_output=dense,
    )


def _tail_moment(f_m: float, g_m: float, alpha: float, k: int) -> float:
    """``int_0^inf s**k f''(zeta_max + s) ds`` of the analytic tail (k = 0: ``1 - f'(zeta_max)``)."""
    return quad(
        lambda s: s**k * float(_tail_curvature(np.asarray(s), g_m, f_m, alpha)),
        0.0,
        np.inf,
        epsabs=1e-14,
        epsrel=1e-12,
        limit=500,
    )[0]


def _far_velocity(alpha: float, fpp0: float, zeta_max: float) -> float:
    """``f'(inf)`` for the initial curvature ``fpp0``: integration plus analytic tail."""
    f_m, fp_m, g_m = _integrate(alpha, fpp0, zeta_max).y[:, -1]
    return fp_m + _tail_moment(f_m, g_m, alpha, 0)


def solve_similarity(alpha: float, zeta_max: float | None = None) -> SimilaritySolution:
    """Solve eq. 4.16 of Tsang et al. (2019) by shooting on ``f''(0)``.

    ``alpha`` must lie in (-1, 1] (for alpha <= -1 no similarity solution exists, section
    4.5 of the paper).  ``zeta_max`` defaults to 12 for alpha = 1 and 200 otherwise.
    """
    if not -1.0 < alpha <= 1.0:
        raise ValueError(f"alpha must lie in (-1, 1], got {alpha}")
    if zeta_max is None:
        zeta_max = 12.0 if np.isclose(alpha, 1.0) else 200.0
    fpp0 = brentq(lambda s: _far_velocity(alpha, s, zeta_max) - 1.0, 1e-3, 5.0, xtol=1e-13, rtol=1e-13)
    return SimilaritySolution(alpha=alpha, fpp0=fpp0, zeta_max=zeta_max)


def froude_number(speed: float, depth: float, gravity: float = 9.81) -> float:
    """Froude number ``U / sqrt(g H)`` of the incident flow (Tsang et al. 2019, sec. 2)."""
    return float(speed / np.sqrt(gravity * depth))


def boundary_layer_scale(
    alpha: float,
    m: float,
    theta_deg: float,
    depth: float,
    speed: float,
    grain_diameter: float,
    gravity: float = 9.81,
) -> float:
    """Thickness scale ``eps`` of eq. 4.13 (``Lambda = eps H (x / H)**(1/(1+alpha))``).

    ``Fr = U / sqrt(g H)`` (the paper's definition, sec. 2: eq. 4.13 carries the
    ``cos theta`` factors itself) and ``delta = d / H``; the similarity variable is
    ``zeta = z / Lambda(x)`` and the displacement thickness ``zeta_disp * Lambda(x)``.
    """
    cos = np.cos(np.radians(theta_deg))
    froude = froude_number(speed, depth, gravity)
    delta = grain_diameter / depth
    return float(
        (alpha * m * cos / froude**2 * (delta * froude / np.sqrt(cos)) ** alpha) ** (1.0 / (1.0 + alpha))
    )


def shape_factor(u: np.ndarray, fractions: np.ndarray) -> np.ndarray:
    """Shape factor ``chi = mean(u**2) / mean(u)**2`` (Tsang et al. 2019, eq. 1.2).

    ``u`` has the layers along axis 0 (shape (L,) or (L, N)); ``fractions`` (L,) are the
    layer thickness fractions.  1 for a plug flow, 5/4 for the Bagnold profile.
    """
    w = np.asarray(fractions, dtype=float).reshape((-1,) + (1,) * (np.ndim(u) - 1))
    mean = np.sum(w * u, axis=0)
    return np.sum(w * np.asarray(u) ** 2, axis=0) / mean**2


def displacement_thickness(
    u: np.ndarray, thickness: np.ndarray, outer_speed: np.ndarray | float | None = None
) -> np.ndarray:
    """Displacement thickness ``int (1 - u / U_e) dz`` of layered profiles.

    ``u`` (L,) or (L, N) layer velocities, ``thickness`` the layer thicknesses (same shape
    or (L,)), ``U_e`` the outer speed, by default the top-layer velocity.
    """
    u = np.asarray(u, dtype=float)
    outer = u[-1] if outer_speed is None else np.asarray(outer_speed, dtype=float)
    return np.sum(np.asarray(thickness) * (1.0 - u / outer), axis=0)
