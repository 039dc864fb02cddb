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
  at rest is statically indeterminate).  Added to it, the transport's change of momentum
  that gravity and the end faces do not carry: the pressure on the relief of the bed
  (the source terms of the hydrostatic reconstruction, Audusse, Bouchut, Bristeau, Klein
  & Perthame 2004), a gate, and the momentum the transport leaves in cells it keeps dry.
- **side walls** (``wall_force_x``): ``dt sum_a F_a`` of the vertical step.
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

import numpy as np

from multilayer.engine.state import FlowState
from multilayer.engine.transport import boundaries
from multilayer.engine.vertical.stresses import StressModel

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
        transported: tuple[np.ndarray, np.ndarray],
        u_vertical: np.ndarray,
        end: tuple[np.ndarray, dict[str, np.ndarray]],
        dt: float,
    ) -> None:
        """Add the impulses of a step of ``dt``: from the state ``start`` the transport gave
        ``transported`` (h, u*), the vertical step ``u_vertical`` and the pressure model
        ``end`` (u, its layer fields)."""
        (h0, u0), (h, ustar), (u, fields) = (start.h, start.u), transported, end
        left, right, mass_time = self.transport_terms
        rho = self.rho
        gravity = rho * self.g_t * mass_time
        change = self.momentum(h, ustar) - self.momentum(h0, u0)
        end_walls = rho * ((-left if self.walls[0] else 0.0) + (right if self.walls[1] else 0.0))
        outflow = rho * ((0.0 if self.walls[1] else right) - (0.0 if self.walls[0] else left))
        relief = gravity + rho * (left - right) - change  # what the end faces and gravity do not carry
        basal, walls = self._vertical(h, ustar, u_vertical, dt)
        pressure = self.momentum(h, u_vertical) - self.momentum(h, u)
        weight = rho * self.g_n * mass_time
        normal = weight
        if "w" in fields:  # the normal momentum of the non-hydrostatic pressure model
            normal += self.momentum(h, fields["w"]) - self.momentum(h0, start.w)
        self.impulse += (relief + basal, normal, walls, end_walls, pressure, gravity, weight, outflow)
        self.elapsed += dt

    def _vertical(self, h: np.ndarray, ustar: np.ndarray, u: np.ndarray, dt: float) -> tuple[float, float]:
        """Impulses per unit width on the bed and on the side walls in the vertical step,
        from the surface down (module docstring)."""
        m = self.rho * self.l * h
        threshold, viscous = self.stresses.wall_forces(h, u)
        passed = np.zeros(h.size)  # dt sigma above the current layer
        walls = np.zeros(h.size)
        for a in range(u.shape[0] - 1, -1, -1):
            load = passed + m[a] * (ustar[a] - u[a])
            limit = dt * threshold[a]
            moving = np.sign(u[a]) * (limit + dt * viscous[a])
            held = np.where(u[a] != 0.0, moving, np.clip(load, -limit, limit))
            walls += held
            passed = load - held
        return self.dx * float(np.sum(passed)), self.dx * float(np.sum(walls))

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

    def load_state(self, saved: dict) -> None:
        """Restore :meth:`state_dict` (none saved: a fresh start)."""
        self.impulse[:] = saved.get("force_impulse", 0.0)
        self.elapsed = float(saved.get("force_elapsed", 0.0))
