"""The state guard: a state that cannot be physical stops the run before it is kept.

After every step, before the new state replaces the old one (so the last good state is
what the simulation holds when the check fails):

- ``h`` and every ``u_a`` are finite and ``h >= 0``;
- mass is conserved to the boundary fluxes.  The finite-volume update changes the mass
  ``sum h dx`` only through the two boundary faces, so on a closed domain (walls or
  periodic) the change is round-off, bounded by ``64 eps N dx max h``.  At an open side
  (outflow or inflow) the HLL mass flux of a face is at most ``2 S H`` with ``S`` the
  largest wave speed ``|u| + sqrt(g cos(theta) h)`` and ``H`` the largest thickness of
  the two cells next to the boundary (or of the inflow state); a change of mass beyond
  ``dt`` times twice that bound per open side (Heun's two stages see states between
  the old and the new one) is a violation, and a dry edge admits no flux at all.

A violation raises :class:`StateError` (a :class:`RunError`, exit code 1) naming the
quantity, its value and where (x, layer, time).
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.transport import Inflow
from multilayer.errors import RunError

CLOSED = frozenset({"wall", "periodic"})
ROUND_OFF = 64 * np.finfo(float).eps


class StateError(RunError):
    """The state left by a step is not physical: non-finite, negative thickness or mass not conserved."""


class StateGuard:
    """Checks of the state of one simulation (columns at ``x`` of width ``dx``)."""

    def __init__(
        self, x: np.ndarray, dx: float, g_n: float, left: str, right: str, inflow: Inflow | None = None
    ):
        self.x, self.dx, self.g_n = x, dx, g_n
        self.open_sides = [
            (side, cells) for side, cells in ((left, [0, 1]), (right, [-1, -2])) if side not in CLOSED
        ]
        self.inflow = inflow

    def check_step(
        self, h_old: np.ndarray, u_old: np.ndarray, h_new: np.ndarray, u_new: np.ndarray, t: float, dt: float
    ) -> None:
        """Raise :class:`StateError` if the step from ``t`` over ``dt`` left an impossible state."""
        when = f"after the step from t = {t:.6g} s (dt = {dt:.3g} s)"
        self.check_state(h_new, u_new, when)
        change = (float(np.sum(h_new)) - float(np.sum(h_old))) * self.dx
        allowed = ROUND_OFF * h_new.size * self.dx * max(float(h_old.max()), float(h_new.max()))
        allowed += dt * sum(
            self._flux_bound(h_old, u_old, h_new, u_new, cells) for _, cells in self.open_sides
        )
        if abs(change) > allowed:
            sides = " and ".join(f"{side}" for side, _ in self.open_sides) or "none (closed domain)"
            raise StateError(
                f"mass is not conserved {when}: it changed by {change:.6g} m2, more than the "
                f"boundary fluxes allow ({allowed:.3g} m2; open sides: {sides})"
            )

    def check_state(self, h: np.ndarray, u: np.ndarray, when: str) -> None:
        """Raise :class:`StateError` unless ``h`` and ``u`` are finite and ``h >= 0``."""
        if h.min(initial=0.0) >= 0.0 and _finite(h) and _finite(u):
            return  # two reductions per array, no temporaries: the cheap path of every step
        if not np.isfinite(h).all():
            j = int(np.argmin(np.isfinite(h)))
            raise StateError(f"thickness h = {float(h[j])!r} at x = {self.x[j]:.6g} m {when}")
        if h.min(initial=0.0) < 0.0:
            j = int(np.argmin(h))
            raise StateError(f"negative thickness h = {h[j]:.6g} m at x = {self.x[j]:.6g} m {when}")
        if not np.isfinite(u).all():
            a, k = (int(i) for i in np.unravel_index(np.argmin(np.isfinite(u)), u.shape))
            raise StateError(
                f"velocity u = {float(u[a, k])!r} at x = {self.x[k]:.6g} m, "
                f"layer {a + 1} (1 is at the bed) {when}"
            )

    def _flux_bound(self, h_old, u_old, h_new, u_new, cells) -> float:
        """Twice the largest HLL mass flux ``2 S H`` through one open side, old or new state."""
        h = max(float(h_old[cells].max()), float(h_new[cells].max()))
        u = max(float(np.abs(u_old[:, cells]).max()), float(np.abs(u_new[:, cells]).max()))
        if self.inflow is not None:
            h = max(h, self.inflow.thickness)
            u = max(u, float(np.abs(self.inflow.velocity).max()))
        return 2.0 * 2.0 * (u + float(np.sqrt(self.g_n * h))) * h


def _finite(a: np.ndarray) -> bool:
    """True if every value of ``a`` is finite: one pass (the sum), the exact test only if
    the sum is not finite (a NaN or an infinity, or an overflow of the sum)."""
    return bool(np.isfinite(np.sum(a)) or np.isfinite(a).all())
