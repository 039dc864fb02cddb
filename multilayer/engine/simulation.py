"""The time loop of the multilayer model: transport, then the implicit vertical step.

Each step is a Lie splitting of the multilayer system (docs/model.md)::

    (h, h_a u*_a)   <- transport in x with mass exchange and gravity   (transport.py)
    u^{n+1}         <- argmin of the implicit stress energy per column (vertical_step.py)

and diagnostics (static interface, front, mass) are evaluated at output times.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from multilayer.engine import (
    bim2016,
    diagnostics,
    initial_state,
    newton_kernel,
    nonhydrostatic,
    stress,
    threads,
    transport,
    transport_kernel,
    vertical_step,
)
from multilayer.engine.gate import Gate
from multilayer.engine.mesh import LayeredMesh
from multilayer.engine.state_check import StateGuard
from multilayer.errors import InputError, RunError

if TYPE_CHECKING:  # the engine reads a validated scenario; it never loads one
    from multilayer.scenario import Scenario
    from multilayer.scenario.schema import BaseZone

BASE_KINDS = {"no_slip": stress.NO_SLIP, "coulomb": stress.COULOMB, "free_slip": stress.FREE_SLIP}


def basal_conditions(regions: Sequence[BaseZone], x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Basal condition code and Coulomb coefficient of each column centred at ``x``;
    a region covers ``x_min <= x < x_max`` and later regions win where they overlap."""
    kind = np.full(x.size, stress.NO_SLIP)
    mu = np.zeros(x.size)
    for region in regions:
        lo = -np.inf if region.x_min is None else region.x_min
        hi = np.inf if region.x_max is None else region.x_max
        inside = (x >= lo) & (x < hi)
        kind[inside] = BASE_KINDS[region.condition]
        mu[inside] = region.mu or 0.0
    return kind, mu


class Simulation:
    """A scenario's state on the X-sigma mesh and the loop that advances it.

    Stepping API (docs/api.md): ``Simulation(multilayer.load(...))`` builds the initial
    state; :meth:`step` takes one stable time step, :meth:`advance` steps to a given
    time; the state is ``t`` (s), ``h`` (N,) and ``u`` (L, N) at the cell centres ``x``
    and layer centres ``sigma * h``; :meth:`diagnostics` gives the static interface,
    front and mass; :meth:`state_dict` and :meth:`load_state` save and restore it.
    ``h`` and ``u`` are numpy arrays updated in place: copy them to keep a snapshot
    (``mesh.cell_variable`` makes FiPy variables of them on the FiPy mesh).
    """

    def __init__(self, scenario: Scenario):
        sc = scenario
        self.scenario = sc
        dom = sc.domain
        self.mesh = LayeredMesh(dom.x_min, dom.x_max, dom.cells, dom.fractions())
        self.x, self.dx = self.mesh.x, self.mesh.dx
        self.fractions, self.sigma = self.mesh.fractions, self.mesh.sigma
        theta = math.radians(sc.slope_deg)
        self.theta = theta
        self.pressure = sc.model.pressure
        # the non-hydrostatic pressure's interfaces (docs/nonhydrostatic.md)
        self.pressure_layers = sc.model.resolved_pressure_layers(dom.layers)
        self.g_n = sc.gravity * math.cos(theta)
        self.g_t = sc.gravity * math.sin(theta)
        self.numerics = sc.numerics
        self.front_threshold = float(sc.numerics.front_threshold)

        self.stresses = stress.StressModel(
            sc.rheology.instantiate(),
            sc.material.as_material(),
            self.fractions,
            self.g_n,
            *basal_conditions(sc.base, self.x),
            walls=sc.walls.instantiate() if sc.walls is not None else None,
            width=dom.width,
            x=self.x,
        )
        self.base_slip = self.stresses.base_kind != stress.NO_SLIP
        self.solver = vertical_step.solver_for(sc.numerics.vertical_solver)
        # the fused compiled Newton iteration (used when every law has a compiled form)
        kernel = sc.numerics.vertical_solver == "kernel"
        self.compiled_step = newton_kernel.CompiledStep(self.stresses) if kernel else None
        self.transport = (
            transport.transport if sc.numerics.transport_solver == "numpy" else transport_kernel.transport
        )
        self.workspace = transport_kernel.Workspace(self.fractions.size, dom.cells)
        self.thread_policy = threads.ThreadPolicy(sc.numerics.threads)

        bc = sc.boundaries
        self.left, self.right = bc.left, bc.right
        self.inflow = None
        if bc.inflow is not None:
            u_in = initial_state.velocity_profile(
                bc.inflow.velocity,
                self.sigma * bc.inflow.thickness,
                np.full(self.sigma.shape, bc.inflow.thickness),
            )
            self.inflow = transport.Inflow(float(bc.inflow.thickness), u_in)

        self.gate = None
        if sc.gate is not None:
            faces = dom.x_min + self.dx * np.arange(dom.cells + 1)
            self.gate = Gate(sc.gate.x, sc.gate.lift_speed, faces, self.mesh.interfaces)

        self.edges = initial_state.cell_edges(dom.x_min, dom.x_max, dom.cells)
        initial_state.check_entries(sc.initial, dom.x_min, dom.x_max, self.dx, str(sc.source or "<scenario>"))
        h0, u0 = initial_state.initial_state(sc.initial, self.x, self.sigma, self.edges)
        # the state is numpy; sim.mesh.cell_variable gives FiPy variables of it on demand
        self.h = np.ascontiguousarray(h0, dtype=float)
        self.u = np.ascontiguousarray(u0, dtype=float).reshape(self.fractions.size, dom.cells)
        self.bed = initial_state.bed_profile(sc.bed, self.x)
        # non-hydrostatic state: layer-mean vertical velocities and interface pressures
        self.w = np.zeros_like(self.u)
        self.q = np.zeros_like(self.u)
        # with the non-hydrostatic pressure, the velocities of the last vertical step before
        # the projection seed the next one's Newton iteration (elsewhere u does): they keep
        # the plugs (layers locked together) that the per-layer corrections would break
        # (the other pressures seed it with u itself: the same array, never copied)
        self.newton_seed = self.u.copy() if self.pressure == "non_hydrostatic" else self.u
        # the columns lo .. hi-1 outside which w, q and the seed are zero (the material of the
        # last step: the projection and the vertical step change nothing beyond it)
        self._projected = (0, dom.cells)
        self.projection = (
            nonhydrostatic.Projection(
                self.fractions,
                self.bed,
                dx=self.dx,
                periodic=self.left == "periodic",
                dry=sc.numerics.dry_threshold,
                g_n=self.g_n,
                pressure_layers=self.pressure_layers,
            )
            if self.pressure == "non_hydrostatic"
            else None
        )
        # per-step masks, allocated once: columns that move at the start of the step and
        # during it (material at rest set moving), layers of material at rest
        self._moving_start = np.zeros(dom.cells, dtype=bool)
        self._moving = np.zeros(dom.cells, dtype=bool)
        self._rest = np.zeros(self.u.shape, dtype=bool)
        self.t = 0.0
        self.steps = 0
        self.newton_iterations = 0
        self.guard = StateGuard(self.x, self.dx)
        self.guard.check_state(self.h, self.u, "in the initial state")
        self.guard.reset(self.h, self.steps)
        #: mass (m2) through the left and right boundary in the last step, positive in +x
        self.boundary_mass = np.zeros(2)
        # the fastest wave across a face that carried mass in the last transport's second stage
        self._stage_speed = np.zeros(1)
        #: called between kernel calls within a step; may raise to abandon the step (Ctrl-C)
        self.poll: Callable[[], None] | None = None
        # the scale of the Newton tolerance: gravity waves on the deepest initial or
        # inflowing material, or the fastest initial or inflow velocity
        h_in, u_in = (self.inflow.thickness, self.inflow.velocity) if self.inflow else (0.0, np.zeros(1))
        self.velocity_scale = max(
            math.sqrt(sc.gravity * max(float(self.h.max(initial=0.0)), h_in)),
            float(np.abs(self.u).max(initial=0.0)),
            float(np.abs(u_in).max()),
            1e-12,
        )

    @property
    def net_inflow(self) -> float:
        """Mass (m^2 per unit width) that entered through the boundaries minus the mass
        that left, since the start (or since the state restored by ``load_state``)."""
        return self.guard.net_inflow

    @property
    def cells(self) -> int:
        """Number of cells of the X-sigma mesh (columns x layers)."""
        return self.h.size * self.fractions.size

    def time_step(self) -> float:
        """Largest stable step of the transport (Courant condition), inflow state included."""
        speed = self._with_inflow(transport_kernel.max_wave_speed(self.h, self.u, self.g_n))
        return transport.courant_step(speed, self.dx, self.scenario.time.cfl)

    def _with_inflow(self, speed: float) -> float:
        """The fastest wave of the state, ``speed``, or of the inflow state if faster."""
        if self.inflow is not None:
            h_in, u_in = np.array([self.inflow.thickness]), self.inflow.velocity.reshape(-1, 1)
            speed = max(speed, transport_kernel.max_wave_speed(h_in, u_in, self.g_n))
        return speed

    def step(self, t_max: float = np.inf) -> float:
        """Advance one time step, never beyond ``t_max``; returns the step taken."""
        if not t_max > self.t:
            raise InputError(
                f"step(t_max={t_max!r}): t_max must be later than the current time t = {self.t!r} s"
            )
        # one pass over the state: the moving columns, the layers of material at rest (the
        # static yield stress applies to them) and the fastest wave
        speed = transport_kernel.survey(
            self.h, self.u, self.numerics.dry_threshold, self.g_n, self._moving_start, self._rest
        )
        speed = self._with_inflow(speed)
        dt = min(transport.courant_step(speed, self.dx, self.scenario.time.cfl), t_max - self.t)
        projected = self.pressure == "non_hydrostatic"
        while True:
            self._check_advances(dt)
            h_new, u_new, w_new, q_new, seed, iterations = self._transport_with_starting_columns(dt)
            # the vertical step zeroes the velocities of the columns without material: the
            # columns lo .. hi-1 (the first to the last with h > 0) hold every non-zero
            # velocity of the step's end (the non-hydrostatic projection changes only the
            # moving cells, and w and q are zero elsewhere)
            lo, hi = transport_kernel.span(h_new)
            # Heun's second stage is a forward Euler step from the first stage's state: it keeps
            # h >= 0 (and the scheme its stability) under the Courant condition of that state's
            # waves (Gottlieb & Shu 1998), which the state at the start cannot foresee: the
            # transport accelerates the material by gravity without the friction of the vertical
            # step (a thin film nearly at rest on a steep slope: g sin(theta) dt far above
            # sqrt(g h)); past it, redo the step shorter
            stage_speed = float(self._stage_speed[0])
            faster = transport.courant_step(stage_speed, self.dx, transport.POSITIVITY_LIMIT)
            if dt <= faster or not math.isfinite(stage_speed):  # the state guard names a non-finite state
                break
            dt = transport.stage_courant_step(dt, speed, stage_speed, self.dx, self.scenario.time.cfl)
        # the state guard: an impossible state is never kept (the last good one stays)
        self.guard.check_step(self.h, h_new, u_new, self.t, dt, self.boundary_mass, (lo, hi))
        if projected:
            for values, name in ((w_new, "vertical velocity w"), (q_new, "non-hydrostatic pressure q")):
                self.guard.check_finite(
                    values,
                    name,
                    lambda: f"after the step from t = {self.t:.6g} s (dt = {dt:.3g} s)",
                    (lo, hi),
                )
        self.h[...] = h_new
        # the velocities are zero outside the columns that moved at the start (the survey
        # read them all) and outside lo .. hi-1 in the new state: copy the columns between
        first, last = transport_kernel.span(self._moving_start)
        first, last = (lo, hi) if first == last else (min(first, lo), max(last, hi))
        self.u[:, first:last] = u_new[:, first:last]
        if projected:  # the non-hydrostatic state (kept as it is otherwise), zero outside lo .. hi-1
            start, stop = min(self._projected[0], lo), max(self._projected[1], hi)
            self.w[:, start:stop] = w_new[:, start:stop]
            self.q[:, start:stop] = q_new[:, start:stop]
            self.newton_seed[:, start:stop] = seed[:, start:stop]
            self._projected = (lo, hi)
        self.newton_iterations += iterations
        self.steps += 1
        # land exactly on t_max when the step was cut to reach it
        self.t = t_max if dt == t_max - self.t else self.t + dt
        return dt

    def _check_advances(self, dt: float) -> None:
        """Refuse a step that would not advance t: never loop on it."""
        if not (dt > 0 and self.t + dt > self.t):
            raise RunError(
                f"the time step dt = {dt!r} s at t = {self.t!r} s does not advance the time (the fastest "
                f"wave speed is {transport_kernel.max_wave_speed(self.h, self.u, self.g_n)!r} m/s; dt "
                f"below the resolution of t when the run is too long for its step)"
            )

    def _transport_with_starting_columns(
        self, dt: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
        """One step of :meth:`_transport_and_stresses` and :meth:`_project` from the current
        state (returns h, u, w, q, the Newton seed of the next step and the Newton
        iterations).  Columns that move carry waves; material at rest that the step sets
        moving carries them from the start of the step: the step is redone until that set is
        complete (a dry column being filled is no material at rest and needs no redo)."""
        moving, rest, dry = self._moving, self._rest, self.numerics.dry_threshold
        moving[...] = self._moving_start  # a step redone shorter starts from the same columns
        iterations = 0
        self.stresses.t = self.t
        while True:
            h_new, seed, more = self._transport_and_stresses(dt, moving, rest)
            iterations += more
            # the non-hydrostatic projection never sets material at rest moving, so the set is
            # judged on the vertical step's velocities and the projection done once, after it
            if not transport_kernel.start_moving(seed, self.h, dry, moving):
                u_new, w_new, q_new = self._project(h_new, seed, dt)
                return h_new, u_new, w_new, q_new, seed, iterations

    def _transport_and_stresses(
        self, dt: float, moving: np.ndarray, rest: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, int]:
        """Transport (h, u*) and the implicit vertical step (u^{n+1}) over ``dt``; ``rest``
        (L, N) marks the layers at rest at the start of the step.  Returns h, u (the Newton
        seed of the next step) and the Newton iterations."""
        opening = self.gate.opening(self.h, self.t + 0.5 * dt) if self.gate is not None else None
        # the occupied columns bound the work of the step, and so its thread count
        count = self.thread_policy.threads(self.fractions.size * int(np.count_nonzero(self.h)))
        compiled = self.transport is transport_kernel.transport
        kernel_options: dict[str, Any] = {"workspace": self.workspace, "threads": count} if compiled else {}
        if self.gate is not None:
            kernel_options.update(gate_face=self.gate.face, opening=opening)
        h_new, ustar = self.transport(
            self.h,
            self.u,
            self.bed,
            self.fractions,
            dx=self.dx,
            dt=dt,
            g_n=self.g_n,
            g_t=self.g_t,
            left=self.left,
            right=self.right,
            inflow=self.inflow,
            dry=self.numerics.dry_threshold,
            order=self.numerics.order,
            moving=moving,
            boundary_mass=self.boundary_mass,
            stage_speed=self._stage_speed,
            **kernel_options,
        )
        self.guard.check_state(
            h_new, ustar, lambda: f"after transport from t = {self.t:.6g} s (dt = {dt:.3g} s)"
        )
        yield_gravity = None
        if self.pressure == "bim2016":
            yield_gravity = bim2016.yield_gravity(
                h_new,
                self.u,
                self.bed,
                self.fractions,
                dx=self.dx,
                gravity=self.scenario.gravity,
                theta=self.theta,
                base_slip=self.base_slip,
                dry=self.numerics.dry_threshold,
            )
        elif self.projection is not None:
            yield_gravity = self.projection.yield_gravity(self.q, h_new, self._projected)
        # the seed changes the Newton work, not the answer: where the unprojected seed does
        # not converge, the step is solved again from u (as the other pressures are)
        seeds = [self.newton_seed, self.u] if self.pressure == "non_hydrostatic" else [self.u]
        for attempt, seed in enumerate(seeds, start=1):
            try:
                u_new, iterations = vertical_step.implicit_step(
                    self.stresses,
                    h_new,
                    ustar,
                    seed,
                    dt,
                    solver=self.solver,
                    tolerance=self.numerics.tolerance,
                    max_iterations=self.numerics.max_iterations,
                    velocity_scale=self.velocity_scale,
                    rest=rest,
                    poll=self.poll,
                    yield_gravity=yield_gravity,
                    threads=count,
                    compiled=self.compiled_step,
                )
                break
            except RunError:
                if attempt == len(seeds):
                    raise
        return h_new, u_new, iterations

    def _project(self, h_new: np.ndarray, u_new: np.ndarray, dt: float) -> tuple[np.ndarray, ...]:
        """With the non-hydrostatic pressure, the projection of the vertical step's velocities
        ``u_new`` (returns u, w, q); the other pressures keep them."""
        if self.projection is None:
            return u_new, self.w, self.q
        return self.projection(h_new, u_new, self.w, self.q, self.h, dt, self._projected)

    def advance(self, t_target: float, on_step: Callable[[Simulation, float], None] | None = None) -> None:
        """Step until ``t == t_target``; ``on_step(sim, dt)`` is called after every step."""
        while self.t < t_target:
            dt = self.step(t_target)
            if on_step is not None:
                on_step(self, dt)

    def check_state(self) -> None:
        """The state guard at an output time: ``h``, ``u`` finite, ``h >= 0`` and the mass
        equal to its value at the start (or at the restored checkpoint) plus the net
        inflow through the boundaries, within round-off.  Raises :class:`StateError`."""
        when = f"at t = {self.t:.6g} s (step {self.steps})"
        self.guard.check_state(self.h, self.u, when)
        self.guard.check_balance(self.h, when)

    def diagnostics(self) -> dict:
        """Static interface height (N,), front position (m) and mass (m^2) now."""
        return {
            "static_interface": diagnostics.static_interface(self.h, self.u, self.mesh.interfaces),
            "front": diagnostics.front(self.x, self.h, self.front_threshold),
            "mass": diagnostics.mass(self.h, self.dx),
        }

    def state_dict(self) -> dict:
        """Everything needed to continue the run exactly (see ``load_state``)."""
        return {
            "t": self.t,
            "steps": self.steps,
            "newton_iterations": self.newton_iterations,
            "h": self.h.copy(),
            "u": self.u.copy(),
            "w": self.w.copy(),
            "q": self.q.copy(),
            "newton_seed": self.newton_seed.copy(),
        }

    def load_state(self, state: dict) -> None:
        """Restore a state saved by ``state_dict``."""
        self.t = float(state["t"])
        self.steps = int(state["steps"])
        self.newton_iterations = int(state.get("newton_iterations", 0))
        self.h[...] = state["h"]
        self.u[...] = state["u"]
        self.w[...] = state.get("w", 0.0)
        self.q[...] = state.get("q", 0.0)
        if self.newton_seed is not self.u:
            self.newton_seed[...] = state.get("newton_seed", self.u)
            self._projected = (0, self.h.size)
        self.guard.check_state(self.h, self.u, f"in the restored state at t = {self.t:.6g} s")
        self.guard.reset(self.h, self.steps)
