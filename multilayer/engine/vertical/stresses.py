"""Stresses of the vertical step: pressure, yield stresses, conductances, wall thresholds.

Hydrostatic pressure ``p(z) = rho g cos(theta) (h - z)`` (docs/model.md).  At the
interface ``k`` below layer ``k`` (0-based; ``k = 0`` is the bed) the rheology gives the
yield stress ``kappa_k = kappa(p_k)`` and the viscous conductance
``c_k = eta(|gamma_k|, p_k) / h_k`` with ``gamma_k = (u_k - u_{k-1}) / h_k`` and
``h_k`` the distance between layer centres (``h_0 / 2`` at a no-slip bed).  The basal
condition (:mod:`multilayer.engine.basal`) keeps the bulk law at interface 0 (no slip) or
replaces it by the friction of the bed, ``kappa_0 = friction p_bed + cohesion, c_0 = 0``
(Coulomb; free slip ``kappa_0 = c_0 = 0``).  Side walls of a channel of width ``W`` hold layer ``a`` with
``F_a = (2 / W) h_a tau_w(pbar_a)`` (Jop, Forterre & Pouliquen 2005; ``mu_w h / W`` summed over
the layers), ``pbar_a`` the mean pressure over the layer.

Start/stop friction (Pouliquen & Forterre 2002): where both layers adjacent to an
interface were at rest at the start of the step (the ground counts as at rest), the
interface yield stress is the rheology's ``static_yield_stress``; the choice is made once
per step, so the step stays an exact minimisation with those thresholds.

Every plugin value is checked where it is used (shape, finite, >= 0;
``plugin_output.call``), so a faulty plugin stops the run with its name, never a NaN.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import numpy as np

from multilayer.engine.basal import BasalColumns
from multilayer.engine.plugin_output import PluginOutputError, call, plugin_label
from multilayer.engine.state_check import all_finite
from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.plugins.contract import Material, Rheology


@dataclass
class ColumnStresses:
    """Everything the vertical step needs that does not depend on the velocities."""

    m: np.ndarray  # layer mass per unit area rho h_a (L, N)
    kappa: np.ndarray  # interface yield stresses (L, N)
    w: np.ndarray  # wall yield thresholds (L, N)
    pressure: np.ndarray  # interface pressures (L, N)
    spacing: np.ndarray  # distance h_k between the centres across interface k (L, N)
    viscous: np.ndarray  # True where interface k carries the bulk viscosity (L, N)
    wall_pressure: np.ndarray  # mean layer pressures pbar_a (L, N)
    x: np.ndarray  # position of each column (N,), for messages
    thickness: np.ndarray  # thickness h of each column (N,), for the laws that use it


INTERFACE = "interface {index} (0 is the bed)"
LAYER = "layer {number} (1 is at the bed)"
NORMAL = "a face between two columns of a layer (model.normal_stress)"


class StressModel:
    """Evaluates the rheology plugins on the layered columns."""

    def __init__(
        self,
        bulk: Rheology,
        material: Material,
        fractions: np.ndarray,
        g_n: float,
        base: BasalColumns,
        walls: Rheology | None = None,
        width: float | None = None,
        x: np.ndarray | None = None,
    ):
        if walls is not None and width is None:
            raise ValueError("side walls need the channel width (domain.width)")
        self.bulk = bulk
        self.x = np.arange(base.bulk.size, dtype=float) if x is None else x
        self.t = 0.0  # time of the step being computed, for messages
        self.walls = walls
        self.width: float = np.inf if width is None else width
        self.material = material
        self.g_n = g_n
        self.base = base
        self.l = fractions[:, None]
        below = np.concatenate([[0.0], np.cumsum(fractions)[:-1]])
        self.depth_interface = (1.0 - below)[:, None]  # (h - z_k) / h
        self.depth_centre = (1.0 - below - 0.5 * fractions)[:, None]
        spacing = 0.5 * (fractions + np.concatenate([[0.0], fractions[:-1]]))
        self.spacing_fraction = spacing[:, None]  # h_0/2 at the bed, (l_{k-1} + l_k)/2 above
        self._held: dict[str, Any] | None = None  # the laws' compiled forms read in this time step

    @contextmanager
    def forms_held(self) -> Iterator[None]:
        """Within: the laws' compiled forms read once (the vertical steps of a time step);
        outside, at each use (a law swapped on a running simulation is honoured)."""
        self._held = {}
        try:
            yield
        finally:
            self._held = None

    def forms(self, kind: str, read: Callable[[], Any]) -> Any:
        """``read()``, the compiled forms ``kind`` of the laws, or what it gave first within
        :meth:`forms_held`."""
        if self._held is None:
            return read()
        if kind not in self._held:
            self._held[kind] = read()
        return self._held[kind]

    def columns(
        self,
        h: np.ndarray,
        where: np.ndarray,
        rest: np.ndarray | None = None,
        yield_gravity: np.ndarray | None = None,
    ) -> ColumnStresses:
        """Velocity-independent coefficients of the columns ``where`` of thickness ``h``.

        ``rest`` (L, N) marks the layers at rest at the start of the step (None: none);
        ``yield_gravity`` (L, N), if given, replaces ``g cos(theta)`` in the interface
        pressures ``p_k = rho G_k (h - z_k)`` (the pressure of ``pressure.bim2016.yield_gravity``).
        """
        rho = self.material.density
        h = h[where]
        bulk, friction, cohesion = self.base.bulk[where], self.base.friction[where], self.base.cohesion[where]
        g_k = self.g_n if yield_gravity is None else yield_gravity[:, where]
        p = rho * g_k * self.depth_interface * h
        x = self.x[where]
        kappa = self._call(self.bulk, "yield_stress", (p, self.material), {"pressure": p}, x, INTERFACE, h)
        if rest is not None:
            rest = rest[:, where]
            # interface k lies below layer k: static where layer k and the one below it
            # (the ground for k = 0) were both at rest
            static = rest & np.vstack([np.ones_like(rest[:1]), rest[:-1]])
            if static.any():
                kappa_static = self._call(
                    self.bulk, "static_yield_stress", (p, self.material), {"pressure": p}, x, INTERFACE, h
                )
                kappa = np.where(static, kappa_static, kappa)
        viscous = np.ones(p.shape, dtype=bool)
        kappa[0] = np.where(bulk, kappa[0], friction * p[0] + cohesion)  # the basal condition
        viscous[0] = bulk
        pbar, w = self._wall_thresholds(h, x)
        return ColumnStresses(
            m=rho * self.l * h,
            kappa=kappa,
            w=w,
            pressure=p,
            spacing=self.spacing_fraction * h,
            viscous=viscous,
            wall_pressure=pbar,
            x=x,
            thickness=h,
        )

    def _wall_thresholds(self, h: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The mean layer pressures ``pbar_a`` and the wall yield thresholds per unit area
        ``(2 / W) h_a tau_w(pbar_a)`` (zero without walls) of columns of thickness ``h``."""
        pbar = self.material.density * self.g_n * self.depth_centre * h
        if self.walls is None:
            return pbar, np.zeros_like(pbar)
        tau_w = self._call(self.walls, "yield_stress", (pbar, self.material), {"pressure": pbar}, x, LAYER, h)
        return pbar, (2.0 / self.width) * self.l * h * tau_w

    def wall_forces(self, h: np.ndarray, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The side walls' yield thresholds ``w_a`` and viscous forces ``|F_v|`` per unit
        area of each layer (L, N) at the velocities ``u``: a layer moving at ``u_a`` is held
        by ``sgn(u_a) (w_a + |F_v|)``, one at rest by at most ``w_a`` (Jop, Forterre &
        Pouliquen 2005); zero without walls."""
        threshold, viscous = np.zeros_like(u), np.zeros_like(u)
        wet = np.flatnonzero(h > 0)
        if self.walls is None or wet.size == 0:
            return threshold, viscous
        x, half = self.x[wet], 0.5 * self.width
        pbar, threshold[:, wet] = self._wall_thresholds(h[wet], x)
        rate = np.abs(u[:, wet]) / half
        per_area = (2.0 / self.width) * self.l * h[wet]
        inputs = {"shear rate": rate, "pressure": pbar}
        eta = self._call(self.walls, "viscosity", (rate, pbar, self.material), inputs, x, LAYER, h[wet])
        viscous[:, wet] = per_area * eta * rate
        return threshold, viscous

    def _call(self, law, method, args, inputs, x, position, thickness) -> np.ndarray:
        """``law.method(*args)`` checked (``plugin_output.call``), given the column
        thickness (N,) as ``thickness=`` (broadcast to the shape of the pressure) if the law
        declares it in ``uses``."""
        keywords = None
        if "thickness" in getattr(law, "uses", ()):
            shape = np.shape(next(iter(inputs.values())))
            keywords = {"thickness": np.broadcast_to(thickness, shape)}
            inputs = {**inputs, "thickness": keywords["thickness"]}
        return call(law, method, args, inputs=inputs, x=x, position=position, t=self.t, keywords=keywords)

    def linearise(
        self,
        cs: ColumnStresses,
        u: np.ndarray,
        ustar: np.ndarray,
        dt: float,
    ) -> ColumnProblem:
        """The step's problem with the Newton model of the viscous part at ``u``.

        The viscous stress ``tau_v(s) = eta(|s|/h_k) s/h_k`` of a velocity jump ``s`` is
        replaced by its tangent at ``|s0|``, written as an odd law
        ``sgn(s) (tau_v(|s0|) - T |s0|) + T s`` with ``T = d tau_v/ds``: a Bingham law
        with yield stress ``kappa + tau_v(|s0|) - T |s0|`` and conductance ``T``.  Where
        that yield stress would be negative (a shear-thickening law with little yield
        stress) the secant ``T = tau_v(|s0|)/|s0|`` is used instead.  At a fixed point the
        law is exact either way: tangent or secant where the layers shear, and with the
        true yield stress where they are locked (``s0 = 0``).  ``ustar`` are the velocities
        after transport and ``dt`` the step of the problem returned.
        """
        spacing = np.where(cs.spacing > 0, cs.spacing, 1.0)
        jump = np.abs(np.diff(u, axis=0, prepend=0.0))
        kappa, c = self._newton_model(self.bulk, cs.kappa, jump / spacing, cs.pressure, cs, INTERFACE)
        kappa = np.where(cs.viscous, kappa, cs.kappa)
        c = np.where(cs.viscous & (cs.spacing > 0), c / spacing, 0.0)
        if self.walls is None:
            return ColumnProblem(m=cs.m, ustar=ustar, dt=dt, kappa=kappa, c=c, w=cs.w, cw=np.zeros_like(c))
        half = 0.5 * self.width
        per_area = (2.0 / self.width) * cs.m / self.material.density  # (2 / W) h_a
        w, c_w = self._newton_model(
            self.walls,
            cs.w / per_area.clip(min=1e-300),
            np.abs(u) / half,
            cs.wall_pressure,
            cs,
            LAYER,
        )
        return ColumnProblem(
            m=cs.m, ustar=ustar, dt=dt, kappa=kappa, c=c, w=per_area * w, cw=per_area * c_w / half
        )

    def _newton_model(
        self, law: Rheology, kappa: np.ndarray, rate: np.ndarray, pressure: np.ndarray, cs, position
    ) -> tuple[np.ndarray, np.ndarray]:
        """Yield stress and slope of the odd Bingham law through ``(rate, kappa + tau_v(rate))``.

        The slope is the tangent ``d tau_v / d gamma`` (forward difference, relative step
        1e-7; ``eta(0)`` at rest), or the secant ``tau_v / gamma`` (with the yield stress
        ``kappa``) where the tangent would make the yield stress negative.  The slope only
        sets the speed of the iteration: the law
        passes through the true stress at ``rate`` in both cases.
        """
        eta, tau, tangent = self._stress_and_tangent(law, rate, pressure, cs, position)
        offset_yield = kappa + tau - tangent * rate
        use_tangent = offset_yield >= 0.0
        return np.where(use_tangent, offset_yield, kappa), np.where(use_tangent, tangent, eta)

    def _stress_and_tangent(self, law: Rheology, rate: np.ndarray, pressure: np.ndarray, cs, position):
        """``eta``, ``tau_v = eta rate`` and ``max(d tau_v / d rate, 0)`` (forward difference,
        relative step 1e-7; ``eta(0)`` at rest) at the shear rates ``rate >= 0`` of the
        columns ``cs``."""
        step = 1e-7 * rate
        eta = self._viscosity(law, rate, pressure, cs, position)
        with np.errstate(over="ignore", invalid="ignore"):  # named below, without numpy's warning
            tau = eta * rate
            up = self._viscosity(law, rate + step, pressure, cs, position) * (rate + step)
            tangent = np.where(rate > 0, (up - tau) / np.where(step > 0, step, 1.0), eta)
        _require_finite_stress(law, eta, rate, tau, tangent)
        return eta, tau, np.maximum(tangent, 0.0)

    def viscous_stresses(self, cs: ColumnStresses, u: np.ndarray) -> np.ndarray:
        """At the velocities ``u``, (4, L, N): the true viscous stresses ``|tau_v|`` of the
        interfaces, their derivatives with respect to the velocity jump, the viscous wall
        forces ``|F_v|`` of the layers and their derivatives (``newton_control.energy_rise``)."""
        spacing = np.where(cs.spacing > 0, cs.spacing, 1.0)
        rate = np.abs(np.diff(u, axis=0, prepend=0.0)) / spacing
        eta, tau, tangent = self._stress_and_tangent(self.bulk, rate, cs.pressure, cs, INTERFACE)
        viscous = cs.viscous & (cs.spacing > 0)
        out = np.zeros((4, *u.shape))
        with np.errstate(over="ignore"):  # a slope of 1e308 over a thin layer: named below
            out[0], out[1] = np.where(viscous, tau, 0.0), np.where(viscous, tangent / spacing, 0.0)
        _require_finite_stress(self.bulk, eta, rate, out[1])
        if self.walls is not None:
            half = 0.5 * self.width
            per_area = (2.0 / self.width) * cs.m / self.material.density
            wall_rate = np.abs(u) / half
            eta, tau, tangent = self._stress_and_tangent(self.walls, wall_rate, cs.wall_pressure, cs, LAYER)
            with np.errstate(over="ignore"):
                out[2], out[3] = per_area * tau, per_area * tangent / half
            _require_finite_stress(self.walls, eta, wall_rate, out[2], out[3])
        return out

    def bulk_stress(self, rate: np.ndarray, pressure: np.ndarray, h: np.ndarray, x: np.ndarray) -> np.ndarray:
        """The stress norm ``kappa(p) + eta(rate, p) rate`` of the bulk law (flowing yield
        stress) at the shear rates ``rate`` and pressures ``pressure`` of columns of
        thickness ``h`` at ``x`` (flat arrays of one shape)."""
        kappa, viscous = self.bulk_parts(rate, pressure, h, x)
        return kappa + viscous

    def bulk_parts(
        self, rate: np.ndarray, pressure: np.ndarray, h: np.ndarray, x: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The two parts of :meth:`bulk_stress`: the yield stress ``kappa(p)`` and the viscous
        stress ``eta(rate, p) rate``."""
        kappa, eta = self.bulk_law(rate, pressure, h, x, NORMAL)
        return kappa, eta * rate

    def bulk_law(
        self, rate: np.ndarray, pressure: np.ndarray, h: np.ndarray, x: np.ndarray, position: str
    ) -> tuple[np.ndarray, np.ndarray]:
        """The yield stress ``kappa(p)`` and the viscosity ``eta(rate, p)`` of the bulk law (flat
        arrays of one shape, as :meth:`bulk_stress`), ``position`` naming where in messages."""
        inputs = {"shear rate": rate, "pressure": pressure}
        kappa = self._call(self.bulk, "yield_stress", (pressure, self.material), inputs, x, position, h)
        eta = self._call(self.bulk, "viscosity", (rate, pressure, self.material), inputs, x, position, h)
        return kappa, eta

    def _viscosity(self, law, rate, pressure, cs, position) -> np.ndarray:
        inputs = {"shear rate": rate, "pressure": pressure}
        return self._call(
            law, "viscosity", (rate, pressure, self.material), inputs, cs.x, position, cs.thickness
        )


def _require_finite_stress(law: Rheology, eta: np.ndarray, rate: np.ndarray, *derived: np.ndarray) -> None:
    """:class:`PluginOutputError` naming ``law`` if a stress or slope ``derived`` from its
    viscosities ``eta`` at the shear rates ``rate`` overflowed: each viscosity was finite
    (checked where returned), but a viscosity of 1e308 Pa s times a rate, or over a thin
    layer, is not; the column kernel named only its coefficient ``c``, after numpy's warnings."""
    for values in derived:
        if not all_finite(values):
            at = np.unravel_index(np.argmin(np.isfinite(values)), values.shape)
            raise PluginOutputError(
                f"{plugin_label(law)}: viscosity() returned {float(eta[at])!r} Pa s at the shear rate "
                f"{float(rate[at]):.6g} 1/s, whose viscous stress or its slope over the layer is beyond "
                "the floats; must be a viscosity whose stresses are finite numbers"
            )
