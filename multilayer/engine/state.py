"""The state of the flow and how a step's result replaces it (the windowed commit).

The state is the thickness ``h`` (N,) and the layer velocities ``u`` (L, N) at the cell
centres, and the further fields per layer (L, N) that a model keeps in :attr:`FlowState.fields`:
the vertical velocities ``w`` and pressures ``q`` of the non-hydrostatic pressure (zero
under the other pressures) and whatever a model adds with :meth:`FlowState.add_field`
(the Newton seed of the non-hydrostatic pressure; a grain-fluid mixture would add its
solid fraction and pore pressure the same way).

A step changes only the columns holding material: :meth:`FlowState.commit` copies ``u``
in the columns that moved at the start of the step or hold material at its end, and the
other fields in those that held material in this step or the last one (the columns
outside are zero by construction and stay so).  :meth:`FlowState.survey` reads the
state once at the start of a step: the moving columns, the layers at rest and the
fastest wave, in the columns that hold material or may hold velocities (those a step
wrote; every column after the state is restored: a velocity written into a column
without material is refused before, ``StateGuard.check_entry``).  The compiled scans of
the state are here too.

Code outside the engine (a user of the Python API, ``on_step``) is given the state's
arrays by :meth:`FlowState.hand_out`, which records which of them it may write into:
:meth:`FlowState.exposed` names those the check of the state the next step starts from
reads (the engine reads the arrays themselves and exposes none).
"""

from __future__ import annotations

import _signal  # whole(): signal's functions without its enum wrappers
import reprlib
import signal
import threading
import weakref
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from types import FrameType
from typing import Any, NoReturn

import numpy as np

from multilayer.engine.compiled import jit
from multilayer.errors import InputError


class FlowState:
    """``h`` (N,), ``u`` (L, N) and the layer ``fields`` of a simulation, updated in place."""

    def __init__(self, h: np.ndarray, u: np.ndarray):
        L, N = u.shape
        self.h = h
        self.u = u
        self.fields = Fields()
        self._defaults: dict[str, str | float] = {}
        self._exposed = {"h", "u"}  # arrays to check at the next step's entry: all at the start
        self._for_good = False  # the state object itself was handed out: every array, every step
        self._handed_out: list[tuple[str, weakref.ref]] = []  # writeable arrays given out, while alive
        self._exposing = threading.Lock()
        self.w = self.add_field("w")
        """Layer-mean vertical velocities (L, N), m/s (the non-hydrostatic pressure)."""
        self.q = self.add_field("q")
        """Kinematic non-hydrostatic pressures at the bottom interface of each layer (L, N), m^2/s^2."""
        self.window = (0, N)
        """Columns ``lo .. hi-1`` outside which the fields are zero (those of the last step)."""
        self.moving = np.zeros(N, dtype=bool)
        """Columns with a non-zero velocity at the start of the step (:meth:`survey`)."""
        self.rest = np.zeros((L, N), dtype=bool)
        """Layers at rest (``u == 0``) at the start of the step, in columns thicker than dry."""
        self._velocities = (0, N)  # columns outside which u is zero
        self._surveyed = (0, N)  # columns outside which moving and rest are False

    def __setattr__(self, name: str, value: object) -> None:
        """The arrays ``h``, ``u``, ``w`` and ``q`` are written in place, never replaced: the
        kernels take them as C-ordered float64 arrays of their shape, and one replaced (by
        ``sim.state.u = u.T.copy()``, a float32 or Fortran-ordered array or a list) was
        compiled for anew, or failed in numba's typing or a broadcast, or blamed the
        transport for the mass its float32 rounding lost.  :class:`InputError` naming it."""
        if name in ("h", "u", "w", "q") and name in self.__dict__:
            raise InputError(
                f"state.{name}: the state's arrays are not replaced; accepted: writing into it in place, "
                f"state.{name}[...] = values (or sim.{name}[...] = values), or sim.load_state(saved)"
            )
        super().__setattr__(name, value)

    def add_field(self, name: str, default: str | float = 0.0) -> np.ndarray:
        """A new layer field (L, N), initially ``default``: a number, or the name of a field
        (or ``"u"``) whose values it starts from (and takes when a saved state lacks it)."""
        values = np.empty_like(self.u)
        values[...] = (
            self.u if default == "u" else self.fields[default] if isinstance(default, str) else default
        )
        self.fields.add(name, values)
        self._defaults[name] = default
        self._exposed.add(name)
        return values

    @property
    def names(self) -> tuple[str, ...]:
        """The names of the state's arrays: ``h``, ``u`` and the fields."""
        return ("h", "u", *self.fields)

    def array(self, name: str) -> np.ndarray:
        """The state's array ``name`` (:attr:`names`) itself."""
        return self.h if name == "h" else self.u if name == "u" else self.fields[name]

    def hand_out(self, name: str, writeable: bool = True) -> np.ndarray:
        """The array ``name`` (:attr:`names`; :class:`InputError` otherwise) for code
        outside the engine: a numpy array on the state's memory, writeable and recorded
        as exposed (:meth:`exposed`) while it, or any array or buffer made from it, is
        alive; or read-only (``writeable=False``: numpy refuses to make it or a view of
        it writeable) and not recorded."""
        if not isinstance(name, str) or name not in self.names:
            raise InputError(f"{name!r}: no array of the state; accepted: {', '.join(self.names)}")
        if not writeable:
            return read_only(self.array(name))
        holder = _Holder(self.array(name), writeable)
        with self._exposing:
            self._exposed.add(name)
            self._handed_out.append((name, weakref.ref(holder)))
        return np.asarray(holder)

    def expose(self, for_good: bool = False) -> None:
        """Every array may have been written before the next step (a restored state); with
        ``for_good`` at every step from now on (the state object itself given out: it
        holds the arrays)."""
        with self._exposing:
            self._exposed.update(self.names)
            self._for_good = self._for_good or for_good

    def exposed(self) -> tuple[dict[str, np.ndarray], tuple[int, int] | None]:
        """The arrays code outside the engine may have written into since the last call,
        by name, and the columns of ``u`` to read (None: all).  Those handed out writeable
        since, and those handed out before that are still alive (a reference kept, a view
        of it, a buffer); every array at the start, after :meth:`expose` and for good
        after ``expose(for_good=True)``: a write needs an array made by :meth:`hand_out`
        alive, so one not named cannot have been written (but through the memory's
        address itself).  ``u`` comes with ``h`` (a thickness written to zero under a
        velocity), in the columns where the steps left it non-zero unless exposed itself."""
        if not (self._exposed or self._for_good):  # none handed out since, none alive then
            return {}, None
        with self._exposing:
            names = set(self.names) if self._for_good else self._exposed
            self._handed_out = [(name, ref) for name, ref in self._handed_out if ref() is not None]
            self._exposed = {name for name, _ in self._handed_out}
        columns = None if "u" in names else self._velocities
        names |= {"u"} if "h" in names else set()
        return {name: self.array(name) for name in self.names if name in names}, columns

    @contextmanager
    def entry(self) -> Iterator[tuple[dict[str, np.ndarray], tuple[int, int] | None]]:
        """:meth:`exposed`, for the checks of a step's entry within: a state they refuse
        stays to be read at the next step (:meth:`expose`), where, stepped again unchanged,
        it was taken as the steps leave it and named as the transport's doing."""
        exposed = self.exposed()
        try:
            yield exposed
        except BaseException:
            self.expose()
            raise

    def survey(self, dry: float, g_n: float) -> float:
        """Fill :attr:`moving` and :attr:`rest` from the state (columns thicker than ``dry``)
        and return the largest wave speed ``max_a |u_a| + sqrt(g cos(theta) h)``."""
        speed, self._surveyed, self._velocities = survey(
            self.h, self.u, dry, g_n, self.moving, self.rest, self._velocities, self._surveyed
        )
        return speed

    def commit(
        self, h: np.ndarray, u: np.ndarray, fields: Mapping[str, np.ndarray], columns: tuple[int, int]
    ) -> None:
        """Take a step's result: ``h``, ``u`` and the layer ``fields`` it produced (the
        others are kept), all zero outside the columns ``columns`` (lo, hi) that hold
        material at its end, and ``u`` also outside those moving at its start."""
        lo, hi = columns
        self.h[...] = h
        first, last = span(self.moving)
        first, last = (lo, hi) if first == last else (min(first, lo), max(last, hi))
        self.u[:, first:last] = u[:, first:last]
        self._velocities = (first, last)  # u was zero outside the moving columns
        if fields:
            start, stop = min(self.window[0], lo), max(self.window[1], hi)
            for name, values in fields.items():
                self.fields[name][:, start:stop] = values[:, start:stop]
            self.window = (lo, hi)

    def state_dict(self) -> dict[str, np.ndarray]:
        """Copies of ``h``, ``u`` and every field."""
        return {"h": self.h.copy(), "u": self.u.copy(), **{k: v.copy() for k, v in self.fields.items()}}

    def load_state(self, saved: Mapping[str, np.ndarray]) -> None:
        """Restore :meth:`state_dict` (a field missing from ``saved`` takes its default)."""
        self.h[...] = saved["h"]
        self.u[...] = saved["u"]
        for name, values in self.fields.items():
            default = self._defaults[name]
            fallback = (
                self.u if default == "u" else self.fields[default] if isinstance(default, str) else default
            )
            values[...] = saved.get(name, fallback)
        self.window = self._velocities = (0, self.h.size)
        self.expose()


class Fields(Mapping[str, np.ndarray]):
    """The layer fields of a :class:`FlowState` by name, a mapping whose arrays are written
    in place and never replaced nor removed (as :meth:`FlowState.__setattr__` keeps ``h``
    and ``u``): ``sim.state.fields['w'] = w.T`` went into the dict, and the kernels were
    given an array of another shape or type, or the state kept one the engine no longer
    wrote.  :class:`InputError` naming it."""

    def __init__(self) -> None:
        self._arrays: dict[str, np.ndarray] = {}

    def add(self, name: str, values: np.ndarray) -> None:
        """The new field ``name`` (:meth:`FlowState.add_field`)."""
        self._arrays[name] = values

    def __getitem__(self, name: str) -> np.ndarray:
        return self._arrays[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._arrays)

    def __len__(self) -> int:
        return len(self._arrays)

    def __setitem__(self, name: str, value: object) -> None:
        self._refuse(name)

    def __delitem__(self, name: str) -> None:
        self._refuse(name)

    def _refuse(self, name: str) -> NoReturn:
        raise InputError(
            f"state.fields[{name!r}]: the state's fields are not replaced nor removed; accepted: writing "
            f"into one in place, state.fields[{name!r}][...] = values, or sim.load_state(saved)"
        )


class Followed:
    """An attribute of a simulation that follows its state (``sim.t``, ``sim.steps``): read
    from ``_<name>``, which the steps and ``load_state`` set; assigned, :class:`InputError`
    (``sim.t = 'a'`` was kept, and a ``TypeError`` in the next step's arithmetic; ``sim.t =
    5.0`` moved the time of a state that was not at it)."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, simulation: object, owner: type | None = None) -> Any:
        return self if simulation is None else simulation.__dict__["_" + self.name]

    def __set__(self, simulation: object, value: object) -> None:
        raise InputError(
            f"sim.{self.name} = {reprlib.repr(value)}: {self.name} is read-only (it follows the state); "
            "accepted: step() or advance(t_target) to move forward, load_state(saved) to restore a state "
            f"and its t, steps"
        )


def read_only(array: np.ndarray) -> np.ndarray:
    """A read-only view of ``array`` that numpy refuses to make writeable, as every view of
    it (``view.flags.writeable = True`` makes a plain read-only view writeable again)."""
    return np.asarray(_Holder(array, writeable=False))


class _Holder:
    """The memory of an array handed out (:meth:`FlowState.hand_out`, :func:`read_only`),
    writeable or not: the base of the numpy array made from it.  numpy makes the base of
    a view the first array up its chain that owns its memory or whose base is no array:
    that array, which keeps the holder.  So the holder lives while the array, a view of
    it (of a view of it, ...) or a buffer of one does, as a weak reference to it tells;
    and numpy refuses to make any of them writeable when the holder is not."""

    __slots__ = ("__array_interface__", "__weakref__", "array")

    def __init__(self, array: np.ndarray, writeable: bool):
        interface = dict(array.__array_interface__)
        interface["data"] = (interface["data"][0], not writeable)
        self.__array_interface__ = interface
        self.array = array  # the memory's owner, kept alive with it


@jit
def span(values: np.ndarray) -> tuple[int, int]:
    """(first, last + 1) of the entries of ``values`` (N,) that are > 0 (or True);
    (0, 0) for none."""
    first = -1
    last = -1
    for i in range(values.size):
        if values[i] > 0:
            if first < 0:
                first = i
            last = i
    return (first, last + 1) if first >= 0 else (0, 0)


@jit
def moving_columns(u: np.ndarray) -> np.ndarray:
    """Columns (N,) with a non-zero velocity in some layer of ``u`` (L, N)."""
    L, N = u.shape
    out = np.zeros(N, np.bool_)
    for a in range(L):
        for i in range(N):
            if u[a, i] != 0.0:
                out[i] = True
    return out


@jit
def max_wave_speed(h: np.ndarray, u: np.ndarray, g_n: float) -> float:
    """Largest max_a |u_a| + sqrt(g cos(theta) h) over the columns (0 for none)."""
    L, N = u.shape
    fastest = np.zeros(N)
    for a in range(L):
        for i in range(N):
            fastest[i] = max(fastest[i], abs(u[a, i]))
    best = 0.0
    for i in range(N):
        best = max(best, fastest[i] + np.sqrt(g_n * max(h[i], 0.0)))
    return best


@jit
def survey(h, u, dry, g_n, moving, rest, velocities, surveyed):
    """One pass over the state at the start of a step: fills ``moving`` (N,), the columns
    with a non-zero velocity in some layer, and ``rest`` (L, N), the layers at rest
    (``u == 0``) in columns thicker than ``dry``; returns the largest wave speed
    ``max_a |u_a| + sqrt(g cos(theta) h)`` (as ``max_wave_speed``), the columns (lo, hi)
    read and those of the moving columns.  Only the columns holding material and
    ``velocities`` (lo, hi), outside which ``u`` is zero, are read; ``moving`` and ``rest``
    are cleared in the columns ``surveyed`` (lo, hi) by the last call outside them."""
    L, N = u.shape
    lo, hi = span(h)
    if velocities[1] > velocities[0]:
        lo, hi = (min(lo, velocities[0]), max(hi, velocities[1])) if hi > lo else velocities
    for i in range(surveyed[0], surveyed[1]):
        if i < lo or i >= hi:
            moving[i] = False
            for a in range(L):
                rest[a, i] = False
    # the rows of the columns lo .. hi-1 as slices indexed from 0: an index such as lo + k
    # could be negative to the compiler, each would wrap around and the loops would not
    # vectorise (five times the instructions)
    n = hi - lo
    fastest, thickness, surveyed_moving = np.zeros(n), h[lo:hi], moving[lo:hi]
    for k in range(n):
        surveyed_moving[k] = False
    for a in range(L):
        row, row_rest = u[a, lo:hi], rest[a, lo:hi]
        for k in range(n):
            v = row[k]
            surveyed_moving[k] = surveyed_moving[k] or v != 0.0
            row_rest[k] = v == 0.0 and thickness[k] > dry
            fastest[k] = max(fastest[k], abs(v))
    best = 0.0
    for k in range(n):
        best = max(best, fastest[k] + np.sqrt(g_n * max(thickness[k], 0.0)))
    first, last = span(moving[lo:hi])
    return best, (lo, hi), (lo + first, lo + last) if last > first else (0, 0)


@jit
def start_moving(u, h, dry, moving):
    """Add to ``moving`` the columns thicker than ``dry`` that were not moving and have a
    non-zero velocity in ``u`` (material at rest that a step sets moving); True if any."""
    L, N = u.shape
    started = False
    for i in range(N):
        if moving[i] or not h[i] > dry:
            continue
        for a in range(L):
            if u[a, i] != 0.0:
                moving[i] = True
                started = True
                break
    return started


@contextmanager
def whole() -> Iterator[None]:
    """The block runs whole: a Ctrl-C (SIGINT) that arrives during it is handed to the
    process's handler after it.  Under Python's own handler (``Simulation.step`` in a
    notebook, no runner) its ``KeyboardInterrupt`` was raised between two statements of a
    step being kept: after its forces were recorded (recorded again by the step redone:
    40.25 N/m where the run gives 40.32) or after its state (the time and step count of the
    step before: the run went on one step ahead of its time), silently.  For the block (a
    few array copies) the main thread's SIGINT handler is one that notes the signal; the
    process's own is put back after it and called for each signal noted.  (Blocking the
    signal in the main thread is not enough: the kernels' threads would take it.)  The
    handlers are swapped with ``_signal``'s functions, which ``signal``'s wrap: the wrappers
    convert each handler to an enum, by a failed look-up (an exception) for a Python
    function, which cost 10 of the 13 microseconds of the block in every step."""
    handler = _signal.getsignal(signal.SIGINT)
    if threading.current_thread() is not threading.main_thread() or not callable(handler):
        yield  # signals reach the main thread only; SIG_DFL and SIG_IGN call nothing here
        return
    came: list[FrameType | None] = []
    _signal.signal(signal.SIGINT, lambda signum, frame: came.append(frame))
    try:
        yield
    finally:
        _signal.signal(signal.SIGINT, handler)
        for frame in came:
            handler(signal.SIGINT, frame)
