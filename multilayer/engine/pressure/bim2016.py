"""The pressure of the slow-flow model of Bouchut, Ionescu & Mangeney (2016) in the yield stresses.

Their Theorem 4.1 closes the thin-layer expansion of a Drucker-Prager material with a
non-hydrostatic pressure in the flowing layer (eq. 4.9; the paper's angle is ``-theta`` of
this project, where ``theta > 0`` drives the flow towards ``+x``)::

    p = rho g (cos(theta) - sin(theta) d_x eta - 2 |sin(theta)| R) (h - Z),
    R = d_x U / ((d_z U)^2 + 4 (d_x U)^2)^(1/2),

with ``R`` the regularised ratio they propose in place of ``d_x U / |d_z U|`` (their
section 5), ``d_x U`` taken at fixed height ``Z`` and ``eta = b + h`` the free surface
above the reference plane (``eta = h`` on a flat bed, as in the paper).  Where the
material is at rest the ratio is the limit of their eq. 4.22, ``d_x U / |d_z U| ->
-sgn(theta) d_x b_s`` with ``b_s`` the top of the static region, which turns the static
equilibrium condition (eq. 4.13) into the free-surface slope criterion of their
section 4.1 (eq. 4.24)::

    |sin(theta) - cos(theta) d_x eta| <= mu_s (cos(theta) + sin(theta) d_x eta).

Only the yield stresses of the vertical step see this pressure; the transport keeps the
hydrostatic pressure of the shallow model (docs/nonhydrostatic.md).  ``model.pressure:
bim2016`` (:class:`Bim2016`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from multilayer.engine.diagnostics import static_interface
from multilayer.engine.pressure.model import PressureModel

if TYPE_CHECKING:
    from multilayer.engine.state import FlowState


def slope(v: np.ndarray, wet: np.ndarray, dx: float) -> np.ndarray:
    """d_x of ``v`` (last axis) between wet columns: centred where both neighbours are wet,
    one-sided where one is, zero where none is."""
    west = np.zeros(v.shape, dtype=bool)
    east = np.zeros(v.shape, dtype=bool)
    west[..., 1:] = wet[:-1]
    east[..., :-1] = wet[1:]
    vw = np.concatenate([v[..., :1], v[..., :-1]], axis=-1)
    ve = np.concatenate([v[..., 1:], v[..., -1:]], axis=-1)
    both = (ve - vw) / (2.0 * dx)
    return np.where(west & east, both, np.where(east, (ve - v) / dx, np.where(west, (v - vw) / dx, 0.0)))


def yield_gravity(
    h: np.ndarray,
    u: np.ndarray,
    bed: np.ndarray,
    fractions: np.ndarray,
    *,
    dx: float,
    gravity: float,
    theta: float,
    base_slip: np.ndarray,
    dry: float = 0.0,
) -> np.ndarray:
    """Normal gravity ``G_k`` (L, N) of the yield pressure ``p_k = rho G_k (h - z_k)`` at each
    interface ``k`` (``k = 0`` the bed) from eq. 4.9 with the regularised ratio, flowing
    interfaces, or from the static limit (eq. 4.22-4.24), interfaces at rest.

    ``u`` (L, N) are the velocities that decide which material is at rest and give the
    ratio (the start of the step); ``base_slip`` (N,) marks columns whose bed velocity is
    the bottom layer's (Coulomb or free slip) rather than zero.  ``G_k >= 0``: where the
    expansion would give a negative pressure (steep fronts, outside its validity) it is 0.
    """
    g_n = gravity * np.cos(theta)
    g_t = gravity * np.sin(theta)
    wet = h > dry
    interfaces = np.concatenate([[0.0], np.cumsum(fractions)[:-1]])[:, None]  # z_k / h
    eta_slope = slope(bed + h, wet, dx)

    # interface velocities and shear: linear interpolation between layer centres
    below = np.concatenate([np.where(base_slip, u[0], 0.0)[None], u[:-1]])
    l_below = np.concatenate([[fractions[0]], fractions[:-1]])[:, None]
    l_above = fractions[:, None]
    l_below[0] = 0.0  # the bed value sits on the interface itself
    u_face = (l_above * below + l_below * u) / (l_above + l_below)
    spacing = 0.5 * (l_above + np.concatenate([[0.0], fractions[:-1]])[:, None]) * h
    dz_u = np.where(spacing > 0, (u - below) / np.where(spacing > 0, spacing, 1.0), 0.0)
    z_slope = slope(bed + interfaces * h, wet, dx)
    dx_u = slope(u_face, wet, dx) - z_slope * dz_u  # d_x at fixed Z
    norm = np.sqrt(dz_u**2 + 4.0 * dx_u**2)
    ratio = np.where(norm > 0, dx_u / np.where(norm > 0, norm, 1.0), 0.0)
    flowing = g_n - g_t * eta_slope - 2.0 * abs(g_t) * ratio

    at_rest = (u == 0.0) & (below == 0.0)
    rest_top = bed + static_interface(h, u, np.concatenate([[0.0], np.cumsum(fractions)]))
    static = g_n - g_t * eta_slope + 2.0 * g_t * slope(rest_top, wet, dx)
    return np.maximum(np.where(at_rest, static, flowing), 0.0)


class Bim2016(PressureModel):
    """``model.pressure: bim2016``: :func:`yield_gravity` from the velocities at the start
    of the step; the velocities of the vertical step are the step's."""

    name = "bim2016"

    def yield_gravity(self, state: FlowState, h: np.ndarray) -> np.ndarray:
        s = self.setup
        return yield_gravity(
            h,
            state.u,
            s.bed,
            s.fractions,
            dx=s.dx,
            gravity=s.gravity,
            theta=s.theta,
            base_slip=~s.base_bulk,
            dry=s.dry,
        )
