"""A grain–fluid mixture in the time loop: its state, its transport and its local step
(docs/mixture.md, "The mixture in x").

The mixture (volume ``h``, solid ``s_a`` per layer, one velocity per layer) lies under an
ambient fluid at rest whose free surface is horizontal and far above.  The fluid's
hydrostatic pressure then balances its own weight, and the mixture feels the buoyant
weight of its grains: per unit volume ``phi (rho_s - rho_f) g``, a fraction
``r = phi (rho_s - rho_f) / (rho_s phi + rho_f (1 - phi))`` of the mixture's weight.  The
transport in x runs with the gravity reduced by ``r`` of the initial packing (its waves
and the pressure gradient); the local step adds the difference of the buoyant weight
along the slope of the packing each column has now, so that the downslope force is exact
(the pressure gradient keeps the initial ``r``: ``phi`` changes it by a few per cent).

Conservation: the solid ``sum s dx`` changes only through the end faces
(:mod:`~multilayer.engine.mixture.solid_transport`, checked every step like the mass),
and the fluid the mixture draws in or expels when it dilates or contracts is taken from
or given to the ambient fluid of the same column: the mixture volume balances the
boundary fluxes plus that exchange, which :attr:`MixtureFlow.ambient_exchange` records.
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.config import MixtureConfig
from multilayer.engine.mixture import solid_transport
from multilayer.engine.mixture.closure import DENSEST_PACKING
from multilayer.engine.mixture.local_step import LocalStep
from multilayer.engine.state import FlowState
from multilayer.engine.state_check import StateGuard
from multilayer.errors import InputError
from multilayer.plugins.contract import Material, Rheology


def buoyant_fraction(phi: np.ndarray | float, rho_s: float, rho_f: float) -> np.ndarray | float:
    """``r = phi (rho_s - rho_f) / (rho_s phi + rho_f (1 - phi))``: the buoyant weight of
    the grains over the weight of the mixture."""
    return phi * (rho_s - rho_f) / (rho_s * phi + rho_f * (1.0 - phi))


class MixtureFlow:
    """The mixture of a simulation: the fields ``solid`` and ``pore_pressure`` of its
    ``state`` (the solid initially ``phi0 h`` per layer), and its step."""

    def __init__(
        self,
        config: MixtureConfig,
        state: FlowState,
        phi0: np.ndarray,
        law: Rheology,
        material: Material,
        *,
        fractions: np.ndarray,
        x: np.ndarray,
        dx: float,
        g_n: float,
        g_t: float,
        periodic: bool,
        tolerance: float,
        max_iterations: int,
        dry: float,
    ):
        self.config = config
        self.fractions, self.dx, self.x, self.periodic = fractions, dx, x, periodic
        self.g_t = g_t
        self.dry = dry
        """The dry threshold: a restored column thicker holds solid (:meth:`check_restored`)."""
        self.rho_s, self.rho_f = material.particle_density, config.fluid_density
        self._state = state
        self._solid = state.add_field("solid")
        self._solid[...] = phi0 * fractions[:, None] * state.h
        self._pore_pressure = state.add_field("pore_pressure")
        volume = float(state.h.sum())
        mean = float(self._solid.sum()) / volume if volume > 0.0 else float(np.mean(phi0))
        self.reduction = float(buoyant_fraction(mean, self.rho_s, self.rho_f))
        """``r`` of the initial mean packing: the transport's gravity is reduced by it."""
        self.local = LocalStep(config, law, material, fractions, g_n, tolerance, max_iterations)
        self.guard = StateGuard(x, dx)
        self.reset(0)
        self.ambient_exchange = 0.0
        """Fluid volume (m^2 per unit width) the mixture drew from the ambient fluid since the start."""
        self.pending: dict[str, np.ndarray] = {}
        self._transported = state.h
        self.drawn = np.zeros_like(state.h)
        """Fluid volume (N,) the local steps before the last one of a step drew in, with
        the weight of their stage (1/2 for Heun's first: :meth:`average_step`)."""
        self._crossed = np.zeros(2)
        self._volumes = np.zeros(2)
        self._before = self._solid

    @property
    def solid(self) -> np.ndarray:
        """Solid volume per layer ``s_a`` (L, N), m (the state's field, handed out:
        :meth:`~multilayer.engine.state.FlowState.hand_out`)."""
        return self._state.hand_out("solid")

    @property
    def pore_pressure(self) -> np.ndarray:
        """Excess pore pressure at the bottom of each layer (L, N), Pa (``[0]``: at the
        bed; the state's field, handed out)."""
        return self._state.hand_out("pore_pressure")

    def check_restored(self, saved: dict) -> None:
        """:class:`InputError` unless a state to restore (checked by ``check_restored`` of
        state_check.py: shapes, finite numbers, ``h >= 0``) holds the mixture's ``solid`` and
        ``pore_pressure``, the solid of each layer within ``[0, l_a h]``, that of each column
        within its densest packing (``DENSEST_PACKING h``: a column packed beyond it, as a
        checkpoint's solid 1.5 times its own, stopped the first step; a layer beyond it in a
        column within it is moved to the others by the transport) and that of each column
        thicker than :attr:`dry` (the columns the local step solves) above 0: a state
        without them restored a solid of 0 (a packing of 0 in every wet column, the closure
        then blamed) or a pore pressure of 0 (the Newton iteration started elsewhere, the
        resumed run no longer the uninterrupted one), a solid outside its layer was blamed
        on a write between steps and a packing of 0 where the local step solves overflowed
        its closure at the next step, blamed on the closure's constants."""
        for name in ("solid", "pore_pressure"):
            if name not in saved:
                raise InputError(
                    f"{name}: missing; accepted: the state of a grain-fluid mixture holds solid and "
                    "pore_pressure (what state_dict() gives)"
                )
        solid, h = np.asarray(saved["solid"], dtype=float), np.asarray(saved["h"], dtype=float)
        room = self.fractions[:, None] * h
        bad = ~((solid >= 0.0) & (solid <= room * (1.0 + 1e-12)))
        if bad.any():
            a, i = (int(k[0]) for k in np.nonzero(bad))
            raise InputError(
                f"solid holds {float(solid[a, i])!r} m at layer {a + 1}, column {i}, outside [0, "
                f"{float(room[a, i])!r}] m (the layer's thickness); accepted: the solid volume of each layer "
                "within its thickness"
            )
        dense = solid.sum(axis=0) > DENSEST_PACKING * h * (1.0 + 1e-12)  # the run's bound (solid_transport)
        if dense.any():
            i = int(np.argmax(dense))
            column = float(solid[:, i].sum())
            raise InputError(
                f"solid holds {column!r} m in column {i}, {float(h[i])!r} m thick: a packing of "
                f"{column / h[i]:.6g}, beyond the densest packing of spheres, {DENSEST_PACKING:.4f}; "
                "accepted: the solid of each column within that of its densest packing"
            )
        dry = self.dry
        empty = (solid.sum(axis=0) <= 0.0) & (h > dry)
        if empty.any():
            i = int(np.argmax(empty))
            raise InputError(
                f"solid holds 0 m in column {i}, {float(h[i])!r} m thick (above numerics.dry_threshold = "
                f"{dry!r} m): a packing of 0, where the mixture's closure is not defined; accepted: solid in "
                "every column thicker than the dry threshold (a run leaves no column of fluid alone)"
            )

    def reset(self, steps: int) -> None:
        """Take the present solid as the reference of its balance (the start, or a restored state)."""
        self.guard.reset(self._solid.sum(axis=0), steps)

    def phi(self, h: np.ndarray) -> np.ndarray:
        """Depth-averaged solid fraction (N,) at thickness ``h`` (0 where dry)."""
        wet = h > 0.0
        return np.where(wet, self._solid.sum(axis=0) / np.where(wet, h, 1.0), 0.0)

    def phi_layers(self, h: np.ndarray) -> np.ndarray:
        """Solid fraction of each layer (L, N) (0 where dry)."""
        room = self.fractions[:, None] * h
        return np.where(room > 0.0, self._solid / np.where(room > 0.0, room, 1.0), 0.0)

    def step(
        self,
        h_old: np.ndarray,
        h: np.ndarray,
        u_old: np.ndarray,
        ustar: np.ndarray,
        dt: float,
        crossed: np.ndarray,
        dry: float,
        t: float,
        watch: np.ndarray | None = None,
    ) -> tuple[np.ndarray, int]:
        """The solid transported with the step (or Heun's first stage) from ``h_old`` to
        ``h`` (velocities ``u_old`` at its start, ``crossed`` the volume through the end
        faces), then the local step of the columns thicker than ``dry`` from the velocities
        ``ustar`` (the step from time ``t``; ``watch`` (N,): the columns whose start stops
        it, :meth:`LocalStep.__call__`): returns the velocities and the iterations; ``h``
        is dilated in place, the new fields wait in :attr:`pending` for the commit."""
        solid, self._crossed = solid_transport.transport(
            self._solid, h_old, h, u_old, self.fractions, crossed, self.dx, self.periodic
        )
        self._volumes = crossed.copy()
        self.drawn = np.zeros_like(h)
        previous = None
        if self.config.compressibility is not None:  # the pore pressure is carried with the mixture
            previous = solid_transport.carried(self._pore_pressure, h_old, h, crossed, self.dx, self.periodic)
        return self._local(solid, h, ustar, dt, u_old, self._pore_pressure, dry, t, watch, previous)

    def average_step(
        self,
        h_old: np.ndarray,
        first: tuple[np.ndarray, np.ndarray],
        h: np.ndarray,
        *,
        ustar: np.ndarray,
        crossed: np.ndarray,
        dt: float,
        dry: float,
        t: float,
        watch: np.ndarray | None = None,
    ) -> tuple[np.ndarray, int]:
        """After Heun's second transport stage from ``first`` = (h_1, u_1) (the result of
        :meth:`step` over the whole step) and its average ``h`` with ``h_old``: the solid
        of that stage (from ``h_1`` to ``2 h - h_old``, ``2 crossed`` minus the first
        stage's volume through the end faces) averaged with the solid at the start as the
        transport averages ``h``, then the local step of ``dt`` (half the time step) from
        ``ustar`` (``watch``: as in :meth:`step`).  The fluid the first stage drew in
        enters ``h`` with the weight 1/2 (:attr:`drawn`).  A relaxing pore pressure (with a
        compressibility) is averaged as the solid, its content ``p_e h`` at the start with
        that of the second stage, and relaxes from there."""
        h1, u1 = first
        drawn = 0.5 * (h1 - self._transported)
        solid1, crossed1 = self.pending["solid"], self._crossed
        solid2, crossed2 = solid_transport.transport(
            solid1, h1, np.maximum(2.0 * h - h_old, 0.0), u1, self.fractions, 2.0 * crossed - self._volumes,
            self.dx, self.periodic,
        )  # fmt: skip
        self._crossed = 0.5 * (crossed1 + crossed2)
        # a column the average leaves empty holds no solid (round-off of the second stage's
        # volumes, recovered from ``2 h - h_old``)
        solid = np.where(h > 0.0, 0.5 * (self._solid + solid2), 0.0)
        pressures = self.pending["pore_pressure"]
        previous = None
        if self.config.compressibility is not None:
            h2 = np.maximum(2.0 * h - h_old, 0.0)
            p2 = solid_transport.carried(
                pressures, h1, h2, 2.0 * crossed - self._volumes, self.dx, self.periodic
            )
            content, volume = self._pore_pressure * h_old + p2 * h2, h_old + h2
            previous = np.where(volume > 0.0, content / np.where(volume > 0.0, volume, 1.0), 0.0)
        velocities, iterations = self._local(solid, h, ustar, dt, u1, pressures, dry, t, watch, previous)
        self.drawn = drawn
        return velocities, iterations

    def _local(
        self,
        solid: np.ndarray,
        h: np.ndarray,
        ustar: np.ndarray,
        dt: float,
        guess: np.ndarray,
        pressure_guess: np.ndarray,
        dry: float,
        t: float,
        watch: np.ndarray | None,
        previous: np.ndarray | None = None,
    ) -> tuple[np.ndarray, int]:
        """The local step of ``dt`` of the columns thicker than ``dry`` holding ``solid`` at
        the thickness ``h`` (dilated in place) from the velocities ``ustar``, the Newton
        iteration started from ``guess`` and ``pressure_guess``, stopped by a start of the
        columns ``watch`` (:meth:`LocalStep.__call__`), a relaxing pore pressure from ``previous``."""
        self._before = self._solid
        self._transported = h.copy()
        u = np.zeros_like(ustar)
        pressure = np.zeros_like(ustar)
        wet = h > dry
        iterations = 0
        if wet.any():
            s, hw = solid[:, wet], h[wet]
            solid_transport.check_pores(s, hw, self.fractions, t, self.x[wet])
            phi = s / (self.fractions[:, None] * hw)
            correction = buoyant_fraction(phi, self.rho_s, self.rho_f) - self.reduction
            # a closure that overflows is named by the local step's own checks of its
            # results (a :class:`StateError`), not by numpy's warnings on the way there
            with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
                result = self.local(
                    s,
                    hw,
                    ustar[:, wet] + dt * correction * self.g_t,
                    dt,
                    guess[:, wet],
                    pressure_guess[:, wet],
                    x=self.x[wet],
                    t=t,
                    watch=None if watch is None else watch[wet],
                    previous=None if previous is None else previous[:, wet],
                )
            u[:, wet], h[wet], pressure[:, wet] = result.u, result.h, result.pore_pressure
            # the exchange between the layers of each column, which can gather a layer beyond
            # the densest packing (docs/mixture.md, "Layers"): the excess moves to the other
            # layers of its column, as after the transport
            exchanged = result.solid.copy()
            solid_transport.bound_packings(exchanged, self.fractions[:, None] * h[wet])
            solid = solid.copy()
            solid[:, wet] = exchanged
            iterations = result.iterations
        self.pending = {"solid": solid, "pore_pressure": pressure}
        return u, iterations

    def balanced(self, h_old: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The mixture volume whose change the transport's boundary fluxes balance over the
        step from ``h_old``: ``h_old`` plus the fluid the earlier stages drew in (with their
        weight), and the transport's result before the last local step."""
        return h_old + self.drawn, self._transported

    def check_entry(self, h: np.ndarray, t: float, steps: int) -> None:
        """The solid's bounds in the state a step starts from at ``t`` after ``steps``
        steps (the steps never leave one outside them: it was written into
        ``sim.state.fields['solid']`` or ``sim.h`` since)."""
        when = (
            f"on entry to the step from t = {t:.6g} s (step {steps + 1}): not as the steps leave it, so "
            "written into sim.state.fields['solid'] or sim.h since the last step"
        )
        solid_transport.check(self._solid, h, self.fractions, when, self.x)

    def check_step(self, h: np.ndarray, t: float, dt: float, guard: StateGuard) -> None:
        """The solid's balance and bounds after the step from ``t`` over ``dt`` (a
        :class:`~multilayer.engine.state_check.StateError` otherwise), and the fluid drawn
        from the ambient fluid added to the mixture volume's balance in ``guard``."""
        solid = self.pending["solid"]
        when = f"after the step from t = {t:.6g} s (dt = {dt:.3g} s)"
        solid_transport.check(solid, h, self.fractions, when, self.x)
        columns = solid.sum(axis=0)
        self.guard.check_step(
            self._before.sum(axis=0), columns, np.zeros((1, columns.size)), t, dt, self._crossed
        )
        exchange = (float(h.sum()) - float(self._transported.sum()) + float(self.drawn.sum())) * self.dx
        guard.add_inflow(exchange)
        self.ambient_exchange += exchange
