"""The state guard: a state that cannot be physical stops the run before it is kept.

After every step, before the new state replaces the old one (so the last good state is
what the simulation holds when the check fails):

- ``h`` and every ``u_a`` are finite and ``h >= 0``;
- mass balances the boundary fluxes.  The finite-volume update changes the mass
  ``sum h dx`` only through the two end faces, and the transport reports the mass that
  crossed each of them in the step (``transport.reference.step_boundary_mass``: the face fluxes of
  the stages with their Heun weights, the inflow face included).  The change of mass
  minus that net inflow is round-off, bounded by ``64 eps`` times the scale of the
  terms summed, ``N dx max h + |left| + |right|``; on walls the fluxes are zero and
  the bound is the one of a closed domain;
- on periodic sides the two end faces are one face: the mass that left through one end
  is, to the last bit, the mass that entered through the other (a transport that
  reports two different fluxes there would pass the balance above while creating or
  destroying the difference).

At output times (:meth:`StateGuard.check_balance`) the same balance is checked over the
whole run: ``mass(t) = mass(0) + sum of the boundary masses`` within the sum of the
round-off bounds of the steps and of the running sum of the boundary masses itself (half
an ulp of the sum per addition: a domain drained of a large mass, then fed a trickle below
that ulp, kept the sum unchanged and failed the balance).

The thickness is checked in every column; the velocities in every column, or in the
columns ``lo .. hi-1`` where the caller knows them to be zero outside by construction
(the vertical step writes only the columns holding material and zeroes the others, so
the velocities it returns are checked where ``h > 0``).

A violation raises :class:`StateError` (a :class:`RunError`, exit code 1) naming the
quantity, its value and where (x, layer, time).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.errors import InputError, RunError

ROUND_OFF = 64 * np.finfo(float).eps


def all_finite(values: np.ndarray) -> bool:
    """True if every value of ``values`` is a finite number: one sum, and the elementwise
    test only where that sum is not finite, since the sum of finite values near the largest
    float overflows (numpy warned ``overflow encountered in reduce`` and a test on the sum
    alone called finite values not finite)."""
    with np.errstate(over="ignore", invalid="ignore"):
        total = values.sum()
    return bool(np.isfinite(total)) or bool(np.isfinite(values).all())


class StateError(RunError):
    """The state left by a step is not physical: non-finite, negative thickness or mass not conserved."""


class StateGuard:
    """Checks of the state of one simulation (columns at ``x`` of width ``dx``).

    ``net_inflow`` is the mass (m^2 per unit width) that entered through the boundaries
    minus the mass that left since the reference state (:meth:`reset`), ``mass0`` the
    mass of that state.  ``periodic``: the two ends are one face (the periodic sides).
    """

    def __init__(self, x: np.ndarray, dx: float, periodic: bool = False):
        self.x, self.dx, self.periodic = x, dx, periodic
        self.mass0 = self.net_inflow = self._round_off = 0.0
        self._steps0 = 0

    def reset(self, h: np.ndarray, steps: int) -> None:
        """Take ``h`` after ``steps`` steps as the reference of the mass balance."""
        self.mass0 = float(np.sum(h)) * self.dx
        self.net_inflow = 0.0
        self._round_off = ROUND_OFF * h.size * self.dx * float(h.max(initial=0.0))
        self._steps0 = steps

    def check_step(
        self,
        h_old: np.ndarray,
        h_new: np.ndarray,
        u_new: np.ndarray,
        t: float,
        dt: float,
        crossed,
        columns: tuple[int, int] | None = None,
    ) -> None:
        """Raise :class:`StateError` if the step from ``t`` over ``dt`` left an impossible
        state; ``crossed`` (2,) is the mass that crossed the left and right boundary in
        the step, positive in +x; ``columns`` as in :meth:`check_state`.  A step that
        passes is added to the run's balance."""

        def when() -> str:
            return f"after the step from t = {t:.6g} s (dt = {dt:.3g} s)"

        self.check_state(h_new, u_new, when, columns)
        left, right = float(crossed[0]), float(crossed[1])
        if self.periodic and left != right:  # a NaN differs too
            raise StateError(
                f"the periodic sides do not match {when()}: {right!r} m2 left through the right side and "
                f"{left!r} m2 entered through the left side, which are one face: the transport made an "
                f"error of {left - right:.3g} m2"
            )
        error, bound = self.mass_error(h_old, h_new, crossed)
        if not abs(error) <= bound:  # a NaN fails too
            raise StateError(
                f"mass is not conserved {when()}: it changed by {error + left - right:.6g} m2 while the "
                f"boundary fluxes carried {left - right:.6g} m2 in (left side {left:.6g} m2, right side "
                f"{-right:.6g} m2): the transport made an error of {error:.3g} m2, more than round-off "
                f"({bound:.3g} m2)"
            )
        self.add_inflow(left - right)
        self._round_off += bound

    def add_inflow(self, mass: float) -> None:
        """Add ``mass`` (m^2 per unit width) to the net inflow of the run's balance, and
        the rounding of that addition (half an ulp of the new sum) to its bound."""
        self.net_inflow += mass
        self._round_off += 0.5 * float(np.spacing(abs(self.net_inflow)))

    def mass_error(self, h_old: np.ndarray, h_new: np.ndarray, crossed) -> tuple[float, float]:
        """The change of mass from ``h_old`` to ``h_new`` minus the net inflow ``crossed``
        (as in :meth:`check_step`), and its round-off bound."""
        left, right = float(crossed[0]), float(crossed[1])
        change = (float(h_new.sum()) - float(h_old.sum())) * self.dx
        scale = h_new.size * self.dx * max(float(h_old.max()), float(h_new.max())) + abs(left) + abs(right)
        return change - (left - right), ROUND_OFF * scale

    def check_balance(self, h: np.ndarray, when: str) -> None:
        """Raise :class:`StateError` unless the mass of ``h`` is the reference mass plus
        the net inflow since, within the round-off of the steps in between."""
        drift = float(np.sum(h)) * self.dx - self.mass0 - self.net_inflow
        if not abs(drift) <= self._round_off:
            raise StateError(
                f"mass is not conserved {when}: it differs by {drift:.6g} m2 from {self.mass0:.6g} m2 plus "
                f"the net inflow through the boundaries {self.net_inflow:.6g} m2 (round-off allows "
                f"{self._round_off:.3g} m2)"
            )

    def check_state(
        self,
        h: np.ndarray,
        u: np.ndarray,
        when: str | Callable[[], str],
        columns: tuple[int, int] | None = None,
    ) -> None:
        """Raise :class:`StateError` unless ``h`` and ``u`` are finite and ``h >= 0``;
        ``when`` (or what it returns, called only to write a message) says when in the
        run; ``columns`` (lo, hi): ``u`` is zero outside the columns ``lo .. hi-1`` by
        construction, and is checked in them only."""
        lo, hi = (0, h.size) if columns is None else columns
        if _fine(h, _bits(u), lo, hi):
            return  # no temporaries: the cheap path of every step, one compiled call
        when = when if isinstance(when, str) else when()
        if not np.isfinite(h).all():
            j = int(np.argmin(np.isfinite(h)))
            raise StateError(f"thickness h = {float(h[j])!r} at x = {self.x[j]:.6g} m {when}")
        if h.min(initial=0.0) < 0.0:
            j = int(np.argmin(h))
            raise StateError(f"negative thickness h = {h[j]:.6g} m at x = {self.x[j]:.6g} m {when}")
        self._check_layers(u, "velocity u", when)

    def check_entry(
        self,
        h: np.ndarray,
        arrays: Mapping[str, np.ndarray],
        t: float,
        steps: int,
        columns: tuple[int, int] | None = None,
    ) -> None:
        """Raise :class:`StateError` if the state a step starts from at ``t`` after ``steps``
        steps, of thickness ``h``, is not as the steps leave it in ``arrays`` (by name:
        ``h``, ``u``, ``w``, ``q``, a model's field; those that may have been written since
        the last step): ``h`` not finite or negative, a value of ``u`` or of a layer field
        not finite, or a velocity in a column without material (``h == 0``, where every
        step leaves ``u = 0``).  ``columns`` (lo, hi): ``u`` is as the steps leave it (zero)
        outside the columns ``lo .. hi-1``, and is read in them only.  The steps never
        keep such a state, so it was written into the simulation's arrays (``sim.h``,
        ``sim.u``, ...) since: the message names the array, the cell and the layer.  One
        compiled pass over each array (a NaN written into a dry column was carried, never
        read, into the results; one in a column with material was blamed on the
        transport)."""
        lo, hi = (0, h.size) if columns is None else columns
        if all(_as_left(name, values, h, lo, hi) for name, values in arrays.items()):
            return
        for name, values in arrays.items():
            where = "sim." + name if name in ("h", "u", "w", "q") else f"sim.state.fields[{name!r}]"
            when = (
                f"on entry to the step from t = {t:.6g} s (step {steps + 1}): not as the steps leave it, so "
                f"written into {where} since the last step"
            )
            if name == "h":
                self.check_state(h, np.zeros((0, h.size)), when)
            elif name == "u":
                self._check_layers(values, "velocity u", when)
                if (moved := moving_where_empty(h, values)) is not None:
                    a, k = moved
                    raise StateError(
                        f"velocity u = {float(values[a, k])!r} at x = {self.x[k]:.6g} m, layer {a + 1} (1 is "
                        f"at the bed), where there is no material (h = 0) {when}"
                    )
            else:
                self._check_layers(values, _FIELDS.get(name, name), when)

    def check_finite(
        self,
        values: np.ndarray,
        name: str,
        when: str | Callable[[], str],
        columns: tuple[int, int] | None = None,
    ) -> None:
        """Raise :class:`StateError` naming ``name`` unless every value of the layer field
        ``values`` (L, N) is finite (the vertical velocity and pressure of the
        non-hydrostatic state); ``columns`` (lo, hi): ``values`` is zero outside the
        columns ``lo .. hi-1`` by construction, and is checked in them only."""
        lo, hi = (0, values.shape[1]) if columns is None else columns
        if not _finite(_bits(values), lo, hi):
            self._check_layers(values, name, when if isinstance(when, str) else when())

    def _check_layers(self, values: np.ndarray, name: str, when: str) -> None:
        """Raise :class:`StateError` at the first non-finite value of ``values`` (L, N)."""
        if not np.isfinite(values).all():
            a, k = (int(i) for i in np.unravel_index(np.argmin(np.isfinite(values)), values.shape))
            raise StateError(
                f"{name} = {float(values[a, k])!r} at x = {self.x[k]:.6g} m, "
                f"layer {a + 1} (1 is at the bed) {when}"
            )


def _as_left(name: str, values: np.ndarray, h: np.ndarray, lo: int, hi: int) -> bool:
    """The test of :meth:`StateGuard.check_entry` of the array ``name`` (``values``): one
    reduction of ``h``, one compiled pass over the columns ``lo .. hi-1`` of ``u`` or over
    a layer field."""
    if name == "h":
        return h.min(initial=0.0) >= 0.0 and all_finite(h)
    if name == "u":
        return _finite_and_still_where_empty(_bits(values), h, lo, hi)
    return _finite(_bits(values), 0, h.size)


def _bits(u: np.ndarray) -> np.ndarray:
    """The bits of the floats of ``u`` (L, N) as unsigned integers (a view when contiguous)."""
    return np.ascontiguousarray(u, dtype=float).view(np.uint64)


def moving_where_empty(h: np.ndarray, u: np.ndarray) -> tuple[int, int] | None:
    """The first (layer, column) where ``u`` (L, N) is not zero and ``h`` (N,) is: a
    velocity no step leaves (every step leaves ``u = 0`` where there is no material);
    None if there is none."""
    empty = (np.asarray(u) != 0.0) & (np.asarray(h) == 0.0)
    if not empty.any():
        return None
    a, k = np.unravel_index(np.argmax(empty), empty.shape)
    return int(a), int(k)


@jit
def _finite_and_still_where_empty(bits: np.ndarray, h: np.ndarray, lo: int, hi: int) -> bool:
    """True if every value of the columns ``lo .. hi-1`` of ``bits`` (L, N: the floats of
    ``_bits``) is finite (its exponent not all ones, as :func:`_finite`) and zero (of
    either sign) in the columns where ``h == 0``: both tests in one pass over the values,
    with the columns' mask of the magnitude bits (all ones where ``h == 0``, else none)
    formed once, so that the pass is bitwise only and vectorises."""
    exponent = np.uint64(0x7FF0000000000000)
    magnitude = np.uint64(0x7FFFFFFFFFFFFFFF)
    empty = np.empty(hi - lo, dtype=np.uint64)
    for i in range(empty.size):
        empty[i] = magnitude if h[lo + i] == 0.0 else np.uint64(0)
    found = np.uint64(0)
    for a in range(bits.shape[0]):
        row = bits[a, lo:hi]
        for i in range(row.size):
            value = row[i]
            found |= np.uint64((value & exponent) == exponent) | (value & empty[i])
    return found == 0


@jit
def _finite(bits: np.ndarray, lo: int, hi: int) -> bool:
    """True if every value of the columns ``lo .. hi-1`` of ``bits`` (L, N: the floats of
    ``_bits``) is finite: one pass testing the exponent (all ones for an infinity or a
    NaN), which vectorises."""
    exponent = np.uint64(0x7FF0000000000000)
    found = np.uint64(0)
    for a in range(bits.shape[0]):
        row = bits[a, lo:hi]
        for i in range(row.size):
            found |= np.uint64((row[i] & exponent) == exponent)
    return found == 0


@jit
def _fine(h: np.ndarray, bits: np.ndarray, lo: int, hi: int) -> bool:
    """True if every thickness of ``h`` (N,) is finite and not negative (``-0.0``
    included) and :func:`_finite` of ``bits`` in the columns ``lo .. hi-1``."""
    fine = True
    for i in range(h.size):
        fine &= (h[i] >= 0.0) & (h[i] < np.inf)  # False for a NaN
    return fine and _finite(bits, lo, hi)


_FIELDS = {"w": "vertical velocity w", "q": "non-hydrostatic pressure q"}
"""What the layer fields of every state are, for the messages."""

_COUNTS = ("t", "steps", "newton_iterations", "force_elapsed", "seed_dt")
"""Entries of a state that are never negative."""
_NEEDED = (("t", "steps", "h", "u"), ("seed_dt", "seed_last", "seed_window"))
"""Entries a state to restore holds: the first group always, the second all or none (a
state without the Newton seed restarts its extrapolation)."""


def masked_values(value: Any) -> int:
    """The values under the mask of ``value`` if it is a masked array (0 otherwise), which
    ``np.asarray`` would read as numbers (a netCDF file's fill values, as netCDF4 reads them)."""
    return int(np.ma.count_masked(value)) if np.ma.isMaskedArray(value) else 0


def check_restored(saved: Mapping[str, Any], fresh: Mapping[str, Any]) -> None:
    """A state to restore (a checkpoint) holds entries of ``fresh``, the state of the same
    simulation at its start, each of its shape, real numbers (integers where it holds
    integers), finite as the simulation holds them (a ``np.longdouble`` of 1e400 is
    infinite as a float64); the times, counts and thicknesses are not negative, the velocities
    zero where the thickness is and the seed's columns lie in the mesh; the entries of
    :data:`_NEEDED` are there.  :class:`InputError` naming the entry otherwise (a checkpoint
    of another version or layout, or edited, or a mapping given to ``load_state`` by hand: a
    missing entry was a ``KeyError``, a NaN vertical velocity or force impulse was kept); the
    state guard then checks ``h`` and ``u``."""
    always, together = _NEEDED
    for missing in [k for k in always if k not in saved] or (
        [k for k in together if k not in saved] if any(k in saved for k in together) else []
    ):
        raise InputError(f"{missing}: missing; accepted: what state_dict() gives ({', '.join(fresh)})")
    for key, value in saved.items():
        if key not in fresh:
            raise InputError(
                f"{key}: not an entry of this simulation's state (one of another scenario's, such as a "
                f"non-hydrostatic pressure's or a mixture's, or of another version of multilayer); "
                f"accepted: what state_dict() gives ({', '.join(fresh)})"
            )
        if masked := masked_values(value):
            raise InputError(
                f"{key}: a masked array of {masked} masked value(s) (a netCDF file's fill values, read by "
                "netCDF4), where numbers: the values under a mask would be restored"
            )
        a, ref = np.asarray(value), np.asarray(fresh[key])
        if a.dtype == object and ref.dtype.kind in "iu" and isinstance(value, int):  # beyond int64
            raise InputError(
                f"{key} = {value}, beyond what the simulation holds ({ref.dtype}: at most "
                f"{np.iinfo(ref.dtype).max}), where an integer >= 0 within that range"
            )
        if a.shape != ref.shape or a.dtype.kind not in ("iu" if ref.dtype.kind in "iu" else "iuf"):
            raise InputError(
                f"{key}: {a.dtype} values of shape {a.shape}, where {ref.dtype} of shape {ref.shape}"
            )
        with np.errstate(over="ignore"):  # a long double beyond the floats is infinite as held
            held = a.astype(ref.dtype)
        if not np.isfinite(held).all():
            raise InputError(
                f"{key} holds values that are not finite as {ref.dtype} (what the simulation holds), "
                "where finite numbers"
            )
        if key in _COUNTS and not a >= 0:
            raise InputError(f"{key} = {a}, where a number >= 0")
        if key == "h" and a.size and a.min() < 0.0:  # before it replaces the state, as every other entry
            raise InputError(
                f"h holds negative thicknesses (down to {float(a.min())!r} m), where thicknesses >= 0"
            )
    if (moved := moving_where_empty(saved["h"], saved["u"])) is not None:  # the next step would blame sim.u
        layer, k = moved
        raise InputError(
            f"u holds a velocity where h = 0 (layer {layer + 1}, column {k}: "
            f"{float(saved['u'][layer, k])!r} m/s), "
            "where 0 (no material moves there)"
        )
    first, stop = np.asarray(saved.get("seed_window", (0, 0)))
    if not 0 <= first <= stop <= np.asarray(fresh["h"]).size:
        raise InputError(f"seed_window = [{first}, {stop}], outside the columns of the mesh")
