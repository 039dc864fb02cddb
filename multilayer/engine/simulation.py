"""The time loop of the multilayer model (docs/model.md, "Time stepping").

A step of the transport T (fluxes, mass exchange, gravity: transport/), the implicit
stresses V (the argmin of the stress energy per column, exact yield: vertical/; the local
step of a mixture: mixture/), with ``model.normal_stress`` the implicit longitudinal normal
stress N after it (normal_stress.py; the identity without it), the pressure model's
projection P (pressure/) and the impulses on the bed (bed_force.py).  At first order
(``numerics.order: 1``) it is the Lie splitting ``U^{n+1} = P N V_dt T_dt U^n`` (T a
forward Euler step).  At second order the stresses are felt within each stage of Heun's
method (SSP-RK2, Gottlieb & Shu 1998)::

    U^(1)    <- N_dt V_dt T_dt U^n                  the first stage, then the stresses
    U^(2)    <- T_dt U^(1)                          the second stage from that state
    Ubar     <- (U^n + U^(2)) / 2                   Heun's average (h, h_a u_a)
    U^{n+1}  <- P N_{dt/2} V_{dt/2} Ubar            the stresses of the other half step
    F        <- the impulses of both V (weights 1/2, 1) and of P   (bed_force.py)

so the second stage moves material with velocities that have felt the friction (a
transport stage alone would carry the push of gravity and of the pressure gradient over
a whole step, hundreds of times the velocity of a creeping wedge), the stresses act
over ``dt/2 + dt/2`` to first order, and the step ends with the stress steps: material
at rest at ``n`` stays exactly at rest (both V hold it), and material that stops does so
exactly (u == 0).  N follows V so that it sees what V leaves: on material V holds at rest
it exerts no stress (``u* = 0`` gives ``Z = 0``), and the mean pressure ``P - tau_xx`` at
which V's friction acts is that of the last N (one stage before; kept in the state, so a
resumed run equals the uninterrupted one); where the two leave material moving that they
would hold at rest together (a deposit held by its friction and its earth pressure), the
step ends at that rest (normal_stress.joint_rest).  Heun on the whole split step,
``(U^n + S S U^n)/2`` with ``S = V T``, would end with an average: a column stopped by
both V would keep half its velocity, never exactly zero (docs/numerics.md).

Then the Courant check of the step's end (redo shorter if the waves grew faster), the
state guard (an impossible state is never kept) and the windowed commit of the new state
(state.py).  Material at rest that either stress step sets moving carries waves from
the start of the step: the stages are redone until that set is complete (a mixture's
last local step stops at its first evaluation when that sets a column moving:
:meth:`Simulation._vertical_step`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from contextlib import AbstractContextManager, nullcontext
from typing import Any

import numpy as np

from multilayer.engine import basal, diagnostics, initial_state
from multilayer.engine.bed_force import BedForce, VerticalImpulse
from multilayer.engine.config import MAX_STEPS, SimulationConfig, step_bound, time_value
from multilayer.engine.gate import Gate
from multilayer.engine.mesh import LayeredMesh
from multilayer.engine.mixture.flow import MixtureFlow
from multilayer.engine.normal_stress import NormalStress, joint_rest, runs
from multilayer.engine.pressure.model import PressureModel, PressureSetup, models, options
from multilayer.engine.state import FlowState, Followed, max_wave_speed, read_only, span, start_moving, whole
from multilayer.engine.state_check import StateError, StateGuard, check_restored
from multilayer.engine.threads import ThreadPolicy
from multilayer.engine.transport import boundaries
from multilayer.engine.transport import kernel as transport_kernel
from multilayer.engine.transport import reference as transport_reference
from multilayer.engine.transport.reference import POSITIVITY_LIMIT, courant_step, stage_courant_step
from multilayer.engine.vertical.extrapolation import SeedExtrapolation
from multilayer.engine.vertical.problem import VerticalSolver
from multilayer.engine.vertical.step import VerticalStep
from multilayer.engine.vertical.stresses import StressModel
from multilayer.errors import InputError, RunError
from multilayer.plugins.contract import Rheology

MIN_STEP = 2.0 * float(np.finfo(float).tiny)
"""Shortest time step (s): the implicit step of the stresses over ``dt / 2`` divides by it,
which must be a normal number (half of a denormal step rounds to zero)."""


class Simulation:
    """A problem's state on the X-sigma mesh and the loop that advances it.

    Built from a :class:`~multilayer.engine.config.SimulationConfig`, the bulk rheology
    and the wall rheology (plugin instances) and, optionally, another exact solver of the
    column problem (the FiPy reference; default: the compiled one).  Stepping API
    (docs/api.md): :meth:`step` takes one stable time step, :meth:`advance` steps to a
    given time; the state is ``t`` (s), ``h`` (N,) and ``u`` (L, N) at the cell centres
    ``x`` and layer centres ``sigma * h`` (and ``w``, ``q`` of the non-hydrostatic
    pressure); :meth:`diagnostics` gives the static interface, front and mass;
    :meth:`state_dict` and :meth:`load_state` save and restore it.  The arrays are
    updated in place: copy them to keep a snapshot (``mesh.cell_variable`` makes FiPy
    variables of them on the FiPy mesh).
    """

    t, steps = Followed(), Followed()  # time (s) and steps taken of the state: set by the steps, load_state

    def __init__(
        self,
        config: SimulationConfig,
        bulk: Rheology,
        walls: Rheology | None = None,
        *,
        column_solver: VerticalSolver | None = None,
    ):
        c = self.config = config
        self.numerics = c.numerics
        self.mesh = LayeredMesh(c.x_min, c.x_max, c.cells, np.asarray(c.fractions, dtype=float))
        # the simulation's own writeable copies: numba compiles read-only arrays apart
        self.x, self.dx = self.mesh.x.copy(), self.mesh.dx
        self.fractions, self.sigma = self.mesh.fractions.copy(), self.mesh.sigma.copy()
        self.theta = math.radians(c.slope_deg)
        self.g_n = c.gravity * math.cos(self.theta)
        self.g_t = c.gravity * math.sin(self.theta)
        self.dry = float(c.numerics.dry_threshold)
        self.front_threshold = float(c.numerics.front_threshold)
        self.base = basal.columns(c.base, self.x)
        self.left, self.right = c.left, c.right
        self.inflow = None
        if c.inflow is not None:
            thickness = c.inflow.thickness
            u_in = initial_state.velocity_profile(
                c.inflow.velocity, self.sigma * thickness, np.full(self.sigma.shape, thickness)
            )
            self.inflow = boundaries.InflowState(float(thickness), u_in)
        self.gate = None
        if c.gate is not None:
            self.gate = Gate(c.gate.x, c.gate.lift_speed, c.x_min, self.dx, c.cells, self.mesh.interfaces)
        #: the transport: the compiled kernel, or the numpy reference formulation
        compiled = c.numerics.transport_solver == "kernel"
        self.transport: Callable[..., tuple[np.ndarray, np.ndarray]] = (
            transport_kernel.transport if compiled else transport_reference.transport
        )
        self.workspace = transport_kernel.Workspace(self.fractions.size, c.cells)
        self.thread_policy = ThreadPolicy(c.numerics.threads)

        edges = initial_state.cell_edges(c.x_min, c.x_max, c.cells)
        initial_state.check_entries(c.initial, c.x_min, c.x_max, self.dx, c.name)
        h0, u0 = initial_state.initial_state(c.initial, self.x, self.sigma, edges)
        initial_state.check_not_dry(h0, self.dry, self.inflow is not None, c.name)
        self._state = FlowState(
            np.ascontiguousarray(h0, dtype=float),
            np.ascontiguousarray(u0, dtype=float).reshape(self.fractions.size, c.cells),
        )
        self.bed = initial_state.bed_profile(c.bed, self.x)
        self.mixture = self._mixture(bulk)
        """The grain–fluid mixture (engine/mixture), None for dry grains."""
        stresses = StressModel(
            bulk, c.material, self.fractions, self.g_n, self.base, walls=walls, width=c.width, x=self.x
        )
        self.pressure = self._pressure_model(stresses, column_solver)
        self.vertical = VerticalStep(
            stresses,
            solver=column_solver,
            tolerance=c.numerics.tolerance,
            max_iterations=c.numerics.max_iterations,
            velocity_scale=self._velocity_scale(),
        )
        if c.normal_stress and c.mixture is not None:
            raise InputError(f"{c.name}: model.normal_stress: accepted: false with a grain-fluid mixture")
        #: the longitudinal normal stress after each vertical step (None: off)
        self.normal_stress = (
            NormalStress(self.vertical.stresses, self.fractions, self.dx, c.numerics.tolerance, self.dry)
            if c.normal_stress
            else None
        )
        #: the Newton seed of the step's first vertical step, extrapolated from the last steps
        self.seeds = SeedExtrapolation(self._state.u.shape)
        #: the force on the bed, side walls and end walls (bed_force.py)
        self.forces = BedForce(
            self.vertical.stresses, self.fractions, self.dx, self.g_n, self.g_t, c.left, c.right
        )
        # columns that take part in the step: those moving at its start, and material at
        # rest that it sets moving (allocated once)
        self._stepping = np.zeros(c.cells, dtype=bool)
        self._t, self._steps = 0.0, 0
        self.newton_iterations = 0
        self.guard = StateGuard(self.x, self.dx, periodic=boundaries.BOUNDARIES[self.left].wraps)
        self.guard.check_state(self._state.h, self._state.u, "in the initial state")
        self.guard.reset(self._state.h, self.steps)
        #: mass (m2) through the left and right boundary in the last step, positive in +x
        self.boundary_mass = np.zeros(2)
        # the fastest wave across a face that carried mass in the last transport's second stage
        self._stage_speed = np.zeros(1)
        #: called between kernel calls within a step; may raise to abandon the step (Ctrl-C)
        self.poll: Callable[[], None] | None = None
        # the mesh and the bed, which the parts above hold, public as read-only views:
        # ``x = sim.x; x -= 0.25`` (centring the axis of a plot) changed the run, silently;
        # the transport is given the arrays themselves (numba compiles read-only ones apart)
        self._bed, self._fractions = self.bed, self.fractions
        self.x, self.sigma = read_only(self.x), read_only(self.sigma)
        self.fractions, self.bed = read_only(self.fractions), read_only(self.bed)

    def _pressure_model(self, stresses: StressModel, solver: VerticalSolver | None) -> PressureModel:
        """The pressure model of the configuration, the defaults of its options filled in."""
        c = self.config
        model = models()[c.pressure.model]
        setup = PressureSetup(
            fractions=self.fractions,
            bed=self.bed,
            dx=self.dx,
            gravity=c.gravity,
            theta=self.theta,
            g_n=self.g_n,
            dry=self.dry,
            wraps=boundaries.BOUNDARIES[self.left].wraps,
            base_bulk=self.base.bulk,
            options=options(model, c.pressure.options, self.fractions.size),
            stresses=stresses,
            solver=solver,
        )
        return model(setup, self._state)

    def _mixture(self, bulk: Rheology) -> MixtureFlow | None:
        """The mixture of the configuration; the transport's gravity reduced by its
        buoyancy (``engine/mixture/flow.py``)."""
        c = self.config
        if c.mixture is None:
            return None
        edges = initial_state.cell_edges(c.x_min, c.x_max, c.cells)
        solid = np.zeros(c.cells)
        for entry in c.initial:
            h_entry, _ = initial_state.initial_state((entry,), self.x, self.sigma, edges)
            solid += (entry.phi or 0.0) * h_entry
        h = self._state.h
        phi0 = np.where(h > 0.0, solid / np.where(h > 0.0, h, 1.0), 0.0)
        mixture = MixtureFlow(
            c.mixture, self._state, phi0, bulk, c.material, fractions=self.fractions, x=self.x, dx=self.dx,
            g_n=self.g_n, g_t=self.g_t, periodic=boundaries.BOUNDARIES[self.left].wraps,
            tolerance=c.numerics.tolerance, max_iterations=c.numerics.max_iterations, dry=self.dry,
        )  # fmt: skip
        self.g_n *= mixture.reduction
        self.g_t *= mixture.reduction
        return mixture

    def _velocity_scale(self) -> float:
        """The scale of the Newton tolerance: gravity waves on the deepest initial or
        inflowing material, or the fastest initial or inflow velocity."""
        h_in, u_in = (self.inflow.thickness, self.inflow.velocity) if self.inflow else (0.0, np.zeros(1))
        return max(
            math.sqrt(self.config.gravity * max(float(self._state.h.max(initial=0.0)), h_in)),
            float(np.abs(self._state.u).max(initial=0.0)),
            float(np.abs(u_in).max()),
            1e-12,
        )

    @property
    def state(self) -> FlowState:
        """The engine's state (engine/state.py).  It holds every array of the state: from
        now on each is checked at every step's entry (:meth:`step`)."""
        self._state.expose(for_good=True)
        return self._state

    @property
    def h(self) -> np.ndarray:
        """Thickness (N,), m."""
        return self._state.hand_out("h")

    @property
    def u(self) -> np.ndarray:
        """Layer velocities (L, N), m/s."""
        return self._state.hand_out("u")

    @property
    def w(self) -> np.ndarray:
        """Layer-mean vertical velocities (L, N), m/s (zero but with the non-hydrostatic pressure)."""
        return self._state.hand_out("w")

    @property
    def q(self) -> np.ndarray:
        """Non-hydrostatic kinematic pressures (L, N), m^2/s^2 (zero but with it)."""
        return self._state.hand_out("q")

    def read_only(self, name: str) -> np.ndarray:
        """The state's array ``name`` (``h``, ``u``, ``w``, ``q`` or a model's field, as
        ``solid``) as a read-only view, for code that only reads it (the result writer):
        unlike ``sim.h`` it adds nothing to the next step's entry check (:meth:`step`)."""
        return self._state.hand_out(name, writeable=False)

    @property
    def net_inflow(self) -> float:
        """Mass (m^2 per unit width) that entered through the boundaries minus the mass
        that left, since the start (or since the state restored by ``load_state``)."""
        return self.guard.net_inflow

    @property
    def cells(self) -> int:
        """Number of cells of the X-sigma mesh (columns x layers)."""
        return self._state.h.size * self.fractions.size

    def time_step(self) -> float:
        """Largest stable step of the transport (Courant condition), inflow state included."""
        speed = self._with_inflow(max_wave_speed(self._state.h, self._state.u, self.g_n))
        return courant_step(speed, self.dx, self.config.cfl)

    def _with_inflow(self, speed: float) -> float:
        """The fastest wave of the state, ``speed``, or of the inflow state if faster."""
        if self.inflow is not None:
            h_in, u_in = np.array([self.inflow.thickness]), self.inflow.velocity.reshape(-1, 1)
            speed = max(speed, max_wave_speed(h_in, u_in, self.g_n))
        return speed

    def step(self, t_max: float = np.inf) -> float:
        """Advance one time step of the splitting (module docstring), never beyond ``t_max``;
        returns the step taken.  A state written between steps that no step leaves is named
        as that state, with the array it was written into (:meth:`StateGuard.check_entry`)."""
        self._check_target(t_max)
        self._check_entry()
        return self._step(t_max)

    def _check_entry(self) -> None:
        """The state a step starts from is as the steps leave it (:meth:`StateGuard.check_entry`)
        in the arrays code outside the engine may have written since the last step
        (:meth:`FlowState.entry`); the others are as the last step left them."""
        with self._state.entry() as (arrays, columns):
            if arrays:
                self.guard.check_entry(self._state.h, arrays, self.t, self.steps, columns)
            if self.mixture is not None and not arrays.keys().isdisjoint(("h", "solid")):
                self.mixture.check_entry(self._state.h, self.t, self.steps)

    def _step(self, t_max: float) -> float:
        speed = self._with_inflow(self._state.survey(self.dry, self.g_n))  # the fastest wave at the start
        if overflow := transport_reference.overflowing(self._state.h, speed, self.g_n, self.dx, self.inflow):
            deepest, fastest = float(self._state.h.max()), float(np.abs(self._state.u).max())  # finite
            raise StateError(
                f"{overflow[0]} of the state at t = {self.t:.6g} s (step {self.steps + 1}) overflows "
                f"(thickness up to {deepest!r} m, velocity up to {fastest!r} m/s): {overflow[1]}"
            )
        dt = min(courant_step(speed, self.dx, self.config.cfl), t_max - self.t)
        if dt == math.inf:  # no wave: no material and no inflow
            raise InputError(
                f"step(t_max={t_max!r}): no material and no inflow, so no wave bounds the time step; "
                "accepted: a finite t_max (the time to step to)"
            )
        threads = self.thread_policy.threads(self.fractions.size * int(np.count_nonzero(self._state.h)))
        with self._abandonable():  # a step abandoned (a failure, a stop) leaves the state of its start
            while True:  # redone shorter while Heun's second stage breaks the Courant condition
                self._check_advances(dt)
                vertical, u, iterations = self._transport_and_stresses(dt, threads)
                h = vertical[-1].h
                u, fields = self._project(h, u, dt)
                if (shorter := self._courant_check(dt, speed)) is None:
                    break
                dt = shorter
            columns = span(h)  # every non-zero velocity and field of the step's end lies within
            self._guard(h, u, fields, dt, columns)
        with whole():  # the step kept: forces, seeds, state, counts and time, or none of them
            if self.mixture is None:  # the forces of a mixture are not computed (docs/mixture.md)
                self.forces.record(self._state, vertical, (u, fields), dt)  # diagnostics
            self.seeds.accept(dt)
            self._state.commit(h, u, fields, columns)
            self.newton_iterations += iterations
            self._steps += 1
            self._t = t_max if dt == t_max - self._t else self._t + dt  # lands on t_max when cut to reach it
        return dt

    def _abandonable(self) -> AbstractContextManager[None]:
        """Where a step replaces state before it is kept: the normal stress's, which
        :meth:`NormalStress.kept_if_abandoned` takes back if the step raises.  Its
        checkpoint (a stop between kernel calls) held the stresses of a step that never
        happened, and the resumed run differed from the uninterrupted one."""
        return nullcontext() if self.normal_stress is None else self.normal_stress.kept_if_abandoned()

    def _transport_and_stresses(
        self, dt: float, threads: int
    ) -> tuple[list[VerticalImpulse], np.ndarray, int]:
        """The transport stages, each followed by a vertical step and the normal stress's
        (module docstring), redone while the step sets material at rest moving (its vertical
        steps then solve the columns whose problem changed only: ``VerticalStep.redo``): the
        vertical steps, the velocities after the last stress step and the Newton iterations
        (of every attempt, those redone included)."""
        np.copyto(self._stepping, self._state.moving)
        iterations = 0
        self.vertical.begin(keep=self.normal_stress is None)  # (its searches for rest call it again)
        with self.vertical.stresses.forms_held():  # the laws read once in the time step
            while True:
                if self.normal_stress is not None:  # each attempt from the stresses of the step's start
                    self.normal_stress.restart()
                if self.numerics.order == 1:
                    h, ustar = self._transport(dt, threads)
                    step, u, more = self._stress_steps(1.0, h, ustar, dt, threads, last=True)
                    vertical, ends = [step], [u]
                else:
                    h1, u1_star = self._transport(dt, threads, stage=0)
                    if self.transport is transport_kernel.transport:  # its workspace is reused by stage 1
                        h1, u1_star = self.workspace.keep()
                    first, u1, counted = self._stress_steps(0.5, h1, u1_star, dt, threads)
                    h, ustar = self._transport(dt, threads, stage=1, first=(h1, u1))
                    second, u, more = self._stress_steps(
                        1.0, h, ustar, 0.5 * dt, threads, first=(h1, u1), last=True
                    )
                    more += counted
                    vertical, ends = [first, second], [u1, u]
                iterations += more
                # material at rest set moving by any stress step (all: every one is marked)
                started = [start_moving(end, self._state.h, self.dry, self._stepping) for end in ends]
                if not any(started):
                    return vertical, u, iterations
                self.vertical.redo()

    def _check_target(self, t_max: float) -> None:
        if not time_value(t_max) - self.t >= MIN_STEP:
            raise InputError(
                f"step(t_max={t_max!r}): t_max must be a number at least {MIN_STEP:.3g} s later than the "
                f"current time t = {self.t!r} s"
            )

    def _check_advances(self, dt: float) -> None:
        """Refuse a step that would not advance t (never loop on it) or that the implicit
        step cannot divide by (:data:`MIN_STEP`)."""
        if not (dt >= MIN_STEP and self.t + dt > self.t):
            raise RunError(
                f"the time step dt = {dt!r} s at t = {self.t!r} s does not advance the time (the fastest "
                f"wave speed is {max_wave_speed(self._state.h, self._state.u, self.g_n)!r} m/s; dt "
                f"below the resolution of t when the run is too long for its step)"
            )

    def _transport(
        self,
        dt: float,
        threads: int,
        *,
        stage: int | None = None,
        first: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Transport over ``dt`` (h and the velocities u*) of the columns that take part
        in the step (docs/model.md), or one of Heun's stages (``stage``, the second from
        ``first``), checked by the state guard."""
        self.vertical.stresses.t = self.t  # the time of the step, for the messages of the plugin calls
        state = self._state
        options: dict[str, Any] = {}
        if self.gate is not None:
            options = {"gate_face": self.gate.face, "opening": self.gate.opening(state.h, self.t + 0.5 * dt)}
        if self.transport is transport_kernel.transport:  # the arrays it reuses, its threads
            options.update(workspace=self.workspace, threads=threads)
        h, ustar = self.transport(
            state.h, state.u, self._bed, self._fractions, dx=self.dx, dt=dt, g_n=self.g_n, g_t=self.g_t,
            left=self.left, right=self.right, inflow=self.inflow, dry=self.dry, order=self.numerics.order,
            moving=self._stepping, boundary_mass=self.boundary_mass, stage_speed=self._stage_speed,
            boundary_momentum=self.forces.transport_terms, stage=stage, first=first, **options,
        )  # fmt: skip
        # the compiled transport's result is zero outside the columns it wrote
        columns = self.workspace.written if self.transport is transport_kernel.transport else None
        self.guard.check_state(
            h, ustar, lambda: f"after transport from t = {self.t:.6g} s (dt = {dt:.3g} s)", columns
        )
        return h, ustar

    def _stress_steps(
        self,
        weight: float,
        h: np.ndarray,
        ustar: np.ndarray,
        dt: float,
        threads: int,
        first: tuple[np.ndarray, np.ndarray] | None = None,
        *,
        last: bool = False,
    ) -> tuple[VerticalImpulse, np.ndarray, int]:
        """The vertical step over ``dt`` of the velocities ``ustar`` on ``h`` (``first``, ``last``: see
        :meth:`_vertical_step`), then the normal stress's: the vertical step's impulse (of
        ``weight``), the velocities at the end and the Newton iterations.  Where the two leave the
        material of a chain moving, rest of that chain when it is the answer of the two steps
        together (:func:`multilayer.engine.normal_stress.joint_rest`, the normal stress of material
        at rest: docs/model.md, "Longitudinal normal stress"): its vertical step's impulse from
        ``ustar - q``, ``q`` the normal stress's (the same momentum).  The chains
        (:func:`multilayer.engine.normal_stress.runs`) are searched one by one: the normal stress
        couples the columns of a chain only and the vertical step none, so the two steps together,
        and rest as their answer, are a chain's own, whatever the others do."""
        u_vertical, iterations = self._vertical_step(h, ustar, dt, threads, first, last=last)
        u = self._normal_stress(h, u_vertical, dt, self._state.u)
        normal = self.normal_stress
        if normal is None or not np.any(u):
            return VerticalImpulse(weight, h, ustar, u_vertical, dt), u, iterations
        tau_xx, relief = normal.tau_xx, normal.relief  # the split step's (each call makes new arrays)
        count = [iterations]
        held, q = u_vertical.copy(), np.zeros(u.shape)  # the vertical step's answer and its input's change
        mass = self.fractions[:, None] * h
        for columns in runs(h > normal.dry):
            if not np.any(u[:, columns]):
                continue

            def vertical(w: np.ndarray, columns: slice = columns) -> np.ndarray:
                whole = np.zeros(u.shape)  # the other columns at rest: the vertical step is per column
                whole[:, columns] = w
                answer, more = self._vertical_step(h, whole, dt, threads, first)
                count[0] += more
                return answer[:, columns]

            def at_rest(w: np.ndarray, columns: slice = columns) -> np.ndarray:
                whole = np.zeros(u.shape)  # the other chains at rest: no stress there
                whole[:, columns] = w
                return self._normal_stress(h, whole, dt, np.zeros(u.shape))[:, columns]  # rate zero

            found = joint_rest(
                vertical,
                at_rest,
                ustar[:, columns],
                u[:, columns],
                self._state.u[:, columns],
                mass[:, columns],
                self.numerics.max_iterations,
            )
            if found is not None:  # the chain at rest, held by the stresses of the last step at rest
                q[:, columns], held[:, columns], u[:, columns] = found, 0.0, 0.0
                tau_xx[:, columns], relief[:, columns] = normal.tau_xx[:, columns], normal.relief[:, columns]
        normal.tau_xx, normal.relief = tau_xx, relief
        return VerticalImpulse(weight, h, ustar - q, held, dt), u, count[0]

    def _normal_stress(self, h: np.ndarray, u: np.ndarray, dt: float, lagged: np.ndarray) -> np.ndarray:
        """The longitudinal normal stress's step of ``dt`` (normal_stress.py) on the
        velocities ``u`` of a vertical step, its rate from the velocities ``lagged`` (a new
        array; ``u`` itself without it)."""
        if self.normal_stress is None:
            return u
        u = u.copy()
        self.normal_stress(
            h, u, lagged, self.pressure.yield_gravity(self._state, h), dt,
            velocity_scale=self.vertical.velocity_scale, max_iterations=self.numerics.max_iterations,
        )  # fmt: skip
        return u

    def _vertical_step(
        self,
        h: np.ndarray,
        ustar: np.ndarray,
        dt: float,
        threads: int,
        first: tuple[np.ndarray, np.ndarray] | None = None,
        *,
        last: bool = False,
    ) -> tuple[np.ndarray, int]:
        """The implicit vertical step over ``dt`` (the yield pressures and Newton seeds of
        the pressure model), or the mixture's local step (which dilates ``h`` in place;
        ``first``: after Heun's average, the state of its second stage's start): the
        velocities and the Newton iterations.  The Newton iteration starts from a seed
        within O(dt^2) of the answer in a smooth flow (the state's velocities are O(dt)
        away; a seed changes the work, not the answer): the pressure model's seed
        extrapolated from the last step (``extrapolation.py``), or after Heun's average the
        first stage's velocities.

        ``last``: the step's last stress step.  There the mixture's local step stops at its
        first evaluation if that sets moving a column that holds material and is outside
        the columns taking part in the step (those :func:`start_moving` would add): the
        step is redone with that column moving whatever the rest of the local step gives,
        so the rest is not solved (docs/mixture.md, "Columns set moving")."""
        state = self._state
        if self.mixture is not None:
            watch = ~self._stepping & (state.h > self.dry) if last else None
            if first is not None:
                return self.mixture.average_step(
                    state.h, first, h, ustar=ustar, dt=dt, crossed=self.boundary_mass, dry=self.dry, t=self.t,
                    watch=watch,
                )  # fmt: skip
            step = self.mixture.step
            return step(state.h, h, state.u, ustar, dt, self.boundary_mass, self.dry, self.t, watch)
        seeds = self.pressure.seeds(state)
        guess = first[1] if first is not None else self.seeds(seeds[0], dt, span(h))
        return self.vertical(
            h,
            ustar,
            dt,
            seeds if guess is None else (guess, *seeds),
            rest=state.rest,
            yield_gravity=self._yield_gravity(h),
            threads=threads,
            poll=self.poll,
        )

    def _yield_gravity(self, h: np.ndarray) -> np.ndarray | None:
        """The normal gravity of the vertical step's yield pressures: the pressure model's
        (None: ``g cos(theta)``), with ``model.normal_stress`` the mean pressures
        ``P - tau_xx`` of the last normal-stress step (engine/normal_stress.py)."""
        gravity = self.pressure.yield_gravity(self._state, h)
        return gravity if self.normal_stress is None else self.normal_stress.yield_gravity(gravity, h)

    def _project(self, h: np.ndarray, u: np.ndarray, dt: float) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The pressure model's projection; the layer fields of the step (the mixture's too)."""
        u, fields = self.pressure.project(self._state, h, u, dt)
        return u, fields if self.mixture is None else {**fields, **self.mixture.pending}

    def _courant_check(self, dt: float, speed: float) -> float | None:
        """None if the Courant condition held in Heun's second stage too; otherwise the
        shorter step to redo the step with (``speed``: the fastest wave at its start).

        The second stage is a forward Euler step from the first stage's state: it keeps
        ``h >= 0`` (and the scheme its stability) under the Courant condition of that
        state's waves (Gottlieb & Shu 1998), which the state at the start cannot foresee:
        the first stage accelerates the material by gravity and the pressure gradient (a
        thin film on a steep slope, little held by its friction: ``g sin(theta) dt`` far
        above ``sqrt(g h)``).  (A non-finite state passes: the state guard names it.)"""
        stage_speed = float(self._stage_speed[0])
        if dt <= courant_step(stage_speed, self.dx, POSITIVITY_LIMIT) or not math.isfinite(stage_speed):
            return None
        return stage_courant_step(dt, speed, stage_speed, self.dx, self.config.cfl)

    def _guard(
        self, h: np.ndarray, u: np.ndarray, fields: dict[str, np.ndarray], dt: float, columns: tuple[int, int]
    ) -> None:
        """The state guard: an impossible state is never kept (the last good one stays)."""
        h_old = self._state.h
        start, transported = (h_old, h) if self.mixture is None else self.mixture.balanced(h_old)
        self.guard.check_step(start, transported, u, self.t, dt, self.boundary_mass, columns)
        if self.mixture is not None:
            self.mixture.check_step(h, self.t, dt, self.guard)
        if not self.pressure.checked or self.pressure.found_finite():
            return
        for name, what in self.pressure.checked.items():
            self.guard.check_finite(
                fields[name],
                what,
                lambda: f"after the step from t = {self.t:.6g} s (dt = {dt:.3g} s)",
                columns,
            )

    def advance(
        self,
        t_target: float,
        on_step: Callable[[Simulation, float], None] | None = None,
        *,
        max_steps: int | None = MAX_STEPS,
    ) -> None:
        """Step until ``t == t_target`` (a finite number not before ``t``: :class:`InputError`
        otherwise, where the stepping would never end or never start, or went back
        silently); ``on_step(sim, dt)`` is called after every step (a value that is not
        callable is an :class:`InputError` before the first, not a ``TypeError`` after it).
        At most ``max_steps`` steps (``None``: no bound): :class:`InputError` before the
        first step when the Courant step of the state now already needs more
        (``(t_target - t) / time_step()``, a lower bound: the waves may grow), and
        :class:`RunError` once that many are taken short of ``t_target`` (the state is
        that of the last step: ``advance`` again continues)."""
        if not math.isfinite(time_value(t_target)):
            raise InputError(f"advance(t_target={t_target!r}): accepted: a finite number (s)")
        if t_target < self.t:
            raise InputError(
                f"advance(t_target={t_target!r}): earlier than the current time t = {self.t!r} s; accepted: "
                "a time not before t (a simulation steps forward only: load_state restores an earlier state)"
            )
        if on_step is not None and not callable(on_step):
            raise InputError(f"advance(on_step={on_step!r}): accepted: None or a function of (sim, dt)")
        bound = step_bound(max_steps)
        if self.t < t_target and bound < math.inf and (t_target - self.t) / (dt := self.time_step()) > bound:
            raise InputError(
                f"advance(t_target={t_target!r}): {t_target - self.t:.3g} s from t = {self.t:.6g} s in steps "
                f"of at most {dt:.3g} s (the Courant step now) take more than max_steps = {max_steps}; "
                "accepted: a nearer t_target, a larger max_steps, or max_steps=None for no bound"
            )
        taken = 0
        while self.t < t_target:
            if taken >= bound:
                raise RunError(
                    f"advance(t_target={t_target!r}): took max_steps = {max_steps} time steps, reaching "
                    f"t = {self.t:.6g} s; advance again to continue, or give a larger max_steps"
                )
            dt = self.step(t_target)
            taken += 1
            if on_step is not None:
                on_step(self, dt)

    def check_state(self) -> None:
        """The state guard at an output time: ``h``, ``u`` finite, ``h >= 0`` and the mass
        equal to its value at the start (or at the restored checkpoint) plus the net
        inflow through the boundaries, within round-off.  Raises :class:`StateError`."""
        when = f"at t = {self.t:.6g} s (step {self.steps})"
        self.guard.check_state(self._state.h, self._state.u, when)
        self.guard.check_balance(self._state.h, when)

    def diagnostics(self) -> dict:
        """Static interface height (N,), front position (m) and mass (m^2) now."""
        h, u = self._state.h, self._state.u
        return {
            "static_interface": diagnostics.static_interface(h, u, self.mesh.interfaces),
            "front": diagnostics.front(self.x, h, self.front_threshold),
            "mass": diagnostics.mass(h, self.dx),
        }

    def state_dict(self) -> dict:
        """Everything needed to continue the run exactly (see ``load_state``)."""
        return {
            "t": self.t,
            "steps": self.steps,
            "newton_iterations": self.newton_iterations,
            **self._state.state_dict(),
            **self.forces.state_dict(),
            **self.seeds.state_dict(),
            **(self.normal_stress.state_dict() if self.normal_stress is not None else {}),
        }

    def load_state(self, saved: dict) -> None:
        """Restore a state saved by ``state_dict`` (:class:`InputError` naming a wrong entry first)."""
        check_restored(saved, self.state_dict())
        for part in (self.forces, self.mixture):  # the forces and a mixture check their own entries
            part is None or part.check_restored(saved)
        with whole():
            self._t, self._steps = float(saved["t"]), int(saved["steps"])
            self.newton_iterations = int(saved.get("newton_iterations", 0))
            self._state.load_state(saved)
            self.forces.load_state(saved)
            self.seeds.load_state(saved)
            if self.normal_stress is not None:
                self.normal_stress.load_state(saved)
        self.guard.check_state(self._state.h, self._state.u, f"in the restored state at t = {self.t:.6g} s")
        self.guard.reset(self._state.h, self.steps)
        if self.mixture is not None:
            self.mixture.reset(self.steps)
