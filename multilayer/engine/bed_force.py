"""The force the flow exerts on its bed, its side walls and its end walls, step by step.

What long-period seismic waves record of a landslide is the force it exerts on the
Earth (Favreau, Mangeney, Lucas, Crosta & Bouchut 2010; Allstadt 2013): by action and
reaction ``F = M g - dP/dt`` for a flow of mass ``M`` and momentum ``P``, whose departure
from the static weight, ``F - M g = -dP/dt``, is the seismic single force.  The sign
convention is that of the inversions: the force *on the Earth* (Toney & Allstadt 2021,
lsforce), here per unit channel width (N/m) in the frame of the slope, ``x`` downslope and
``z`` normal, positive into the bed.

Each term is read from the step's own numbers, so that the impulses of a step balance its
change of momentum to round-off:

- **bed, downslope** (``bed_force_x``): the vertical step solves per column
  ``m_a (u_a - u*_a) = dt (sigma_{a+1} - sigma_a - F_a)`` with ``sigma_L = 0``; summed
  from the surface down, ``dt sigma_0`` is the impulse the column passes to the bed, the
  side-wall forces ``F_a`` taken out (a moving layer's from the wall law; a layer at
  rest's up to the walls' yield threshold, the rest passed down: the share of material
  at rest is statically indeterminate).  A step of order 2 has two vertical steps
  (``Simulation.step``): the one after Heun's first stage enters the step's momentum
  with the weight 1/2 of that stage in Heun's average, the one after the average with
  weight 1, and so do their impulses.  Added to them, the transport's change of momentum
  that gravity and the end faces do not carry: the pressure on the relief of the bed
  (the source terms of the hydrostatic reconstruction, Audusse, Bouchut, Bristeau, Klein
  & Perthame 2004), a gate, and the momentum the transport leaves in cells it keeps dry.
- **side walls** (``wall_force_x``): ``dt sum_a F_a`` of the vertical steps, weighted alike.
- **end walls** (``end_force_x``, ``wall`` boundaries): the momentum flux of the transport
  through the end face, ``rho g cos(theta) h^2 / 2`` for material at rest against it.
- **pressure** (``pressure_force_x``): the non-hydrostatic pressure model's change of
  horizontal momentum, the force of that pressure on the relief of the bed and on the end
  walls (zero for the hydrostatic pressure).
- **bed, normal** (``bed_force_z``): ``rho g cos(theta) h`` integrated over the step as
  the transport's gravity is (``gravity_force_z``), plus the step's change of the normal
  momentum ``rho sum_a h_a wbar_a dx`` of the non-hydrostatic pressure model (the bed is
  all the flow can push normal to the plane): the pressure at the bed ``rho q_0`` of the
  projection, and the normal momentum the model drops where material stops (``w = 0``
  there) or changes in its advection of ``w``, which is not in conservative form.
- gravity along the slope on the flow (``gravity_force_x``) and the momentum leaving
  through open boundaries (``outflow_momentum_x``), which is no force on the Earth.

The impulses accumulate until :meth:`BedForce.take`, which returns their means over the
time since the last one: with output times ``t_k``, the downslope momentum per unit width
obeys ``P(t_k) - P(t_{k-1}) = (t_k - t_{k-1}) (gravity - bed - walls - ends - pressure -
outflow)`` to round-off (docs/results.md).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.engine.state import FlowState
from multilayer.engine.transport import boundaries
from multilayer.engine.vertical.stresses import StressModel
from multilayer.errors import InputError

FORCES = (
    "bed_force_x",
    "bed_force_z",
    "wall_force_x",
    "end_force_x",
    "pressure_force_x",
    "gravity_force_x",
    "gravity_force_z",
    "outflow_momentum_x",
)
"""The accumulated terms (module docstring), each a force per unit width (N/m) once divided
by the time."""


class VerticalImpulse(NamedTuple):
    """A vertical step of a time step: its ``weight`` in the step's momentum, the thickness
    ``h`` and velocities ``ustar`` it started from, its velocities ``u`` and its step ``dt``."""

    weight: float
    h: np.ndarray
    ustar: np.ndarray
    u: np.ndarray
    dt: float


class BedForce:
    """The impulses of the steps since the last :meth:`take` (module docstring)."""

    def __init__(
        self,
        stresses: StressModel,
        fractions: np.ndarray,
        dx: float,
        g_n: float,
        g_t: float,
        left: str,
        right: str,
    ):
        self.stresses = stresses
        self.rho = stresses.material.density
        self.l = fractions[:, None]
        self.dx, self.g_n, self.g_t = dx, g_n, g_t
        self.walls = tuple(boundaries.rule(kind) == boundaries.MIRROR for kind in (left, right))
        self.impulse = np.zeros(len(FORCES))
        """Impulses per unit width (N s/m) since the last :meth:`take`, in the order of FORCES."""
        self.elapsed = 0.0
        """Time (s) since the last :meth:`take`."""
        #: momentum (per unit density) through the left and right end faces in the last
        #: transport and the integral of its mass over the step (filled by the transport)
        self.transport_terms = np.zeros(3)

    def momentum(self, h: np.ndarray, u: np.ndarray) -> float:
        """Momentum per unit width ``rho sum_a h_a u_a dx`` (kg/s) of the layer velocities
        ``u`` (downslope; normal with the vertical velocities ``w``)."""
        return self.rho * self.dx * float(np.sum(self.l * h * u))

    def record(
        self,
        start: FlowState,
        vertical: Sequence[VerticalImpulse],
        end: tuple[np.ndarray, dict[str, np.ndarray]],
        dt: float,
    ) -> None:
        """Add the impulses of a step of ``dt`` from the state ``start``: its vertical steps
        in order (one or two, ``Simulation.step``; the last one's ``h``, ``ustar`` the
        transport's result, weight 1) and the pressure model's ``end`` (u, its layer
        fields)."""
        *earlier, last = vertical
        u, fields = end
        left, right, mass_time = self.transport_terms
        rho = self.rho
        # the momenta before and after (the normal ones those of the non-hydrostatic
        # pressure's velocities ``w``: no other model has them, its ``w`` stays zero and its
        # normal momentum with it) and the sums of each vertical step, in one compiled call
        # over every column holding material before, during or after the step
        w = fields.get("w")
        steps = [self._vertical_inputs(step) for step in vertical]
        sums = _sums(
            self.l[:, 0], start.h, start.u, start.u if w is None else start.w, last.h, u,
            u if w is None else w, w is not None, *steps[0], *steps[-1], len(steps) == 2,
            self.stresses.walls is not None, rho,
        ).tolist()  # fmt: skip
        # each sum per unit density and cell width: times ``rho dx``
        scale = self.rho * self.dx
        sums = [scale * value for value in sums]
        before, after, normal_before, normal_after = sums[:4]
        transported_, vertical_ = sums[4 * len(vertical) : 4 * len(vertical) + 2]  # the last step's
        # the earlier vertical steps' change of momentum, carried into the transport's result,
        # and the weighted impulses of every step (summed in the order of the steps, from 0)
        held = basal = walls = 0.0
        for k, step in enumerate(vertical):
            transported, stepped, bed, wall = sums[4 + 4 * k : 8 + 4 * k]  # (as _impulses)
            if k < len(earlier):
                held += step.weight * (transported - stepped)
            basal += step.weight * bed
            walls += step.weight * wall
        gravity = rho * self.g_t * mass_time
        end_walls = rho * ((-left if self.walls[0] else 0.0) + (right if self.walls[1] else 0.0))
        outflow = rho * ((0.0 if self.walls[1] else right) - (0.0 if self.walls[0] else left))
        # what the end faces and gravity do not carry in the transport
        relief = gravity + rho * (left - right) - (transported_ + held - before)
        weight = rho * self.g_n * mass_time
        normal = weight + (normal_after - normal_before)
        pressure = vertical_ - after
        self.impulse += (
            relief + basal / rho,
            normal,
            walls / rho,
            end_walls,
            pressure,
            gravity,
            weight,
            outflow,
        )
        self.elapsed += dt

    def _vertical_inputs(self, step: VerticalImpulse) -> tuple[Any, ...]:
        """The arguments of a vertical step to :func:`_sums`: its thickness, velocities,
        side walls' thresholds and viscous forces (``ustar`` in their place without walls:
        not read) and step."""
        threshold, viscous = (
            self.stresses.wall_forces(step.h, step.u)
            if self.stresses.walls is not None
            else (step.ustar, step.ustar)
        )
        return step.h, step.ustar, step.u, threshold, viscous, step.dt

    def take(self) -> dict[str, float]:
        """The mean of each term over the time since the last call (N/m; NaN when no time
        has passed), and a fresh start."""
        means = self.impulse / self.elapsed if self.elapsed > 0 else np.full(len(FORCES), np.nan)
        self.impulse[:] = 0.0
        self.elapsed = 0.0
        return dict(zip(FORCES, (float(v) for v in means), strict=True))

    def state_dict(self) -> dict[str, np.ndarray]:
        """The impulses and the time since the last :meth:`take` (a checkpoint between outputs)."""
        return {"force_impulse": self.impulse.copy(), "force_elapsed": np.asarray(self.elapsed)}

    def check_restored(self, saved: Mapping[str, Any]) -> None:
        """:class:`InputError` naming ``force_impulse`` where a state to restore holds
        impulses no run accumulates (finite ones, ``check_restored`` of state_check.py
        having read them): any without time elapsed, a mean force beyond the floats, a
        negative weight (``rho g cos(theta) int mass dt``), a downslope gravity out of
        the slope's ratio ``tan(theta)`` to the weight (both integrate the same mass),
        an end-wall force without an end wall, outflow without an open end."""
        impulse = np.asarray(saved.get("force_impulse", np.zeros(len(FORCES))), dtype=float)
        elapsed = float(saved.get("force_elapsed", 0.0))
        terms = dict(zip(FORCES, impulse.tolist(), strict=True))
        gravity, weight = terms["gravity_force_x"], terms["gravity_force_z"]
        # both sums of up to MAX_STEPS terms of one sign: 1e-6 bounds their rounding apart
        round_off = 1e-6 * (abs(gravity) + abs(weight)) * math.hypot(self.g_t, self.g_n)
        for wrong, accepted in (
            (elapsed == 0.0 and bool(impulse.any()), "zeros when force_elapsed = 0 (no time, no impulse)"),
            (bool((np.abs(impulse) > sys.float_info.max * elapsed).any()), "impulses whose means are finite"),
            (weight * self.g_n < 0.0, "a gravity_force_z (the weight's impulse) of the sign of cos(theta)"),
            (
                abs(gravity * self.g_n - weight * self.g_t) > round_off,
                "gravity_force_x = gravity_force_z tan(theta) (the slope's), to round-off",
            ),
            (terms["end_force_x"] != 0.0 and not any(self.walls), "end_force_x = 0 without an end wall"),
            (terms["outflow_momentum_x"] != 0.0 and all(self.walls), "outflow_momentum_x = 0 between walls"),
        ):
            if wrong:
                raise InputError(
                    f"force_impulse = {impulse.tolist()} (force_elapsed = {elapsed!r} s): impulses no run "
                    f"accumulates, in the order {', '.join(FORCES)}; accepted: {accepted}"
                )

    def load_state(self, saved: dict) -> None:
        """Restore :meth:`state_dict` (none saved: a fresh start)."""
        self.impulse[:] = saved.get("force_impulse", 0.0)
        self.elapsed = float(saved.get("force_elapsed", 0.0))


@jit
def _momentum(l, h, v, first, last):
    """``sum_a l_a h v_a`` over the columns ``first .. last-1``: each column's sum from the
    bed up, then the columns' sums in turn (the order of :func:`_impulses`)."""
    sums = np.zeros(last)  # (the columns first .. last-1 of it)
    lo, hi = np.uint64(first), np.uint64(last)  # unsigned: no test for negative indices
    for a in range(l.size):  # a pass along each row adds a layer to every column (as vectors)
        row, l_a = v[a], l[a]
        for i in range(lo, hi):
            sums[i] += l_a * h[i] * row[i]
    return _in_turn(sums, lo, hi)


@jit(inline="always")  # inlined: no compilation of its own
def _in_turn(values, lo, hi):
    """The sum of ``values[lo:hi]`` in their order (the columns from left to right)."""
    total = 0.0
    for i in range(lo, hi):
        total += values[i]
    return total


@jit
def _impulses(l, h, ustar, u_vertical, walled, threshold, viscous, rho, dt, first, last):
    """Over the columns ``first .. last-1``, per unit density and cell width: the downslope
    momenta ``sum_a l_a h u`` before and after a vertical step (after the transport, with
    its velocities ``ustar``, and with its velocities ``u_vertical``), and its impulses per
    unit area on the bed and on the side walls times ``rho`` (module docstring): ``passed``
    is ``dt sigma`` above the layer, a moving layer's wall force is ``sgn(u_a) dt (threshold
    + viscous)``, a resting layer's the load up to ``dt threshold`` (none unless ``walled``).

    Each column's sums are made in arrays of their own, row by row of the (L, N) arrays
    from the bed up (a pass along a row runs as vectors; a pass from the surface down did
    not: LLVM's check that the arrays do not overlap, made once for all the rows, sends
    rows whose address decreases to the scalar loop), then added column after column.
    Without walls the bed's impulse is the sum of the layers' changes of momentum (in
    that pass); with walls, the load is passed from the surface down, each layer's wall
    taking its share."""
    passed, transported, vertical, walls = np.zeros(last), np.zeros(last), np.zeros(last), np.zeros(last)
    lo, hi = np.uint64(first), np.uint64(last)  # unsigned: no test for negative indices
    for a in range(l.size):
        before, after, l_a = ustar[a], u_vertical[a], l[a]
        for i in range(lo, hi):
            m = l_a * h[i]
            transported[i] += m * before[i]
            vertical[i] += m * after[i]
            if not walled:
                passed[i] += rho * m * (before[i] - after[i])
    for a in range(l.size - 1 if walled else -1, -1, -1):
        before, after, l_a = ustar[a], u_vertical[a], l[a]
        limits, forces = threshold[a], viscous[a]
        for i in range(lo, hi):
            load = passed[i] + rho * (l_a * h[i]) * (before[i] - after[i])
            limit = dt * limits[i]
            if after[i] > 0.0:
                held = limit + dt * forces[i]
            elif after[i] < 0.0:
                held = -(limit + dt * forces[i])
            else:
                held = min(max(load, -limit), limit)
            walls[i] += held
            passed[i] = load - held
    out = np.empty(4)
    for k, sums in enumerate((transported, vertical, passed, walls)):
        out[k] = _in_turn(sums, lo, hi)
    return out


@jit
def _sums(
    l, h, u, w, h_end, u_end, w_end, normal,
    h_a, ustar_a, u_a, threshold_a, viscous_a, dt_a,
    h_b, ustar_b, u_b, threshold_b, viscous_b, dt_b, two, walled, rho,
):  # fmt: skip
    """The sums of :meth:`BedForce.record`, per unit density and cell width, over every
    column holding material before, during or after the step (``h``, the vertical steps'
    thicknesses ``h_a`` and, if ``two``, ``h_b``: where ``h + (h_a + h_b) > 0``, in that
    order of the sum): the momenta :func:`_momentum` of ``h u`` and ``h_end u_end`` and, if
    ``normal``, of ``h w`` and ``h_end w_end`` (else zero), then the four :func:`_impulses`
    of the vertical step ``a`` and, if ``two``, of ``b`` (else zero)."""
    first = last = -1
    for i in range(h.size):
        total = 0.0 + h_a[i]
        if two:
            total = total + h_b[i]
        if h[i] + total > 0:
            if first < 0:
                first = i
            last = i
    first, stop = (first, last + 1) if first >= 0 else (0, 0)
    out = np.zeros(12)
    out[0] = _momentum(l, h, u, first, stop)
    out[1] = _momentum(l, h_end, u_end, first, stop)
    if normal:
        out[2] = _momentum(l, h, w, first, stop)
        out[3] = _momentum(l, h_end, w_end, first, stop)
    out[4:8] = _impulses(l, h_a, ustar_a, u_a, walled, threshold_a, viscous_a, rho, dt_a, first, stop)
    if two:
        out[8:12] = _impulses(l, h_b, ustar_b, u_b, walled, threshold_b, viscous_b, rho, dt_b, first, stop)
    return out
