"""``multilayer.Simulation(scenario)``: the engine's simulation of a scenario (docs/api.md)."""

from __future__ import annotations

import inspect
import numbers
import threading
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from typing import Any, NoReturn

import numpy as np

from multilayer.app import factory, numba_environment
from multilayer.engine import simulation
from multilayer.engine.plugin_output import PluginOutputError, plugin_label
from multilayer.errors import InputError
from multilayer.plugins.host import HOST_CHANGED, host_state, set_back
from multilayer.scenario import Scenario, validated_again
from multilayer.scenario.messages import shown


class Simulation(simulation.Simulation):
    """``multilayer.Simulation(scenario)``: the engine's
    :class:`~multilayer.engine.simulation.Simulation` of a validated scenario (from
    :func:`multilayer.load`), which it keeps as ``scenario``; a scenario whose keys were
    assigned since it was validated is validated again (:class:`InputError` naming the
    key), and the simulation keeps the validated copy.  numba's variables are
    checked first (:func:`multilayer.app.numba_environment.check`): numba reads
    ``NUMBA_THREADING_LAYER`` at its first parallel kernel, where an unknown layer was
    numba's own ``ValueError``, mid-run."""

    def __init__(self, scenario: Scenario):
        if not isinstance(scenario, Scenario):
            raise InputError(
                f"Simulation: got {shown(scenario)}; accepted: a Scenario, as multilayer.load returns "
                "it from a file or a mapping"
            )
        if scenario.changed_since_validation():  # keys assigned since multilayer.load: checked again
            scenario = validated_again(scenario)
        numba_environment.check()
        self._one_at_a_time = threading.RLock()  # taken through _turn
        self._on_step_thread: int | None = None  # the thread running advance's on_step
        self._on_step_readers = threading.Condition()  # turns, on_steps and readers meanwhile
        self._readers = 0
        self.scenario = scenario
        bulk, walls = factory.laws(scenario)
        self._laws = [law for law in (bulk, walls) if law is not None]
        super().__init__(
            factory.engine_config(scenario),
            bulk,
            walls,
            column_solver=factory.column_solver(scenario.numerics.vertical_solver),
        )
        factory.check_pressure(scenario)  # after the engine's checks of the initial entries

    def advance(
        self,
        t_target: float,
        on_step: Callable[[Any, float], None] | None = None,
        *,
        max_steps: int | None = simulation.MAX_STEPS,
    ) -> None:
        """The engine's :meth:`~multilayer.engine.simulation.Simulation.advance`, its target
        read as :func:`_time` reads it, one thread at a time (:meth:`step`)."""
        target = _time(t_target, "advance(t_target")
        with self._turn(f"advance(t_target={t_target!r})"):
            super().advance(target, self._reading(on_step), max_steps=max_steps)

    @contextmanager
    def _turn(self, call: str | None, *, reader: bool = False) -> Iterator[None]:
        """The simulation held by this thread once the other threads' calls are done;
        ``call`` (a step, an ``advance`` or a ``load_state``; None for one its on_step may
        make) refused where advance's on_step runs (:meth:`_not_in_on_step`), also where
        it starts while this thread waits: a thread that waited for a step under way,
        joined by the on_step after it, held both for ever.  A ``reader`` is let in there
        without the simulation, to the state between the steps (:meth:`state_dict`),
        advance's on_step returning once it has read it."""
        held = False
        with self._on_step_readers:
            while True:
                if reader and self._on_step_thread not in (None, threading.get_ident()):
                    self._readers += 1
                    break
                if call is not None:
                    self._not_in_on_step(call)
                if held := self._one_at_a_time.acquire(blocking=False):
                    break
                self._on_step_readers.wait()  # woken as a turn ends or an on_step starts
        try:
            yield
        finally:
            with self._on_step_readers:
                if held:
                    self._one_at_a_time.release()
                else:
                    self._readers -= 1
                self._on_step_readers.notify_all()

    def _reading(self, on_step: Any) -> Any:
        """``on_step`` run with :meth:`step` refused (a function; anything else is left to
        the engine's check): an ``on_step`` that stepped took ``advance`` past its target.
        It returns once the other threads reading the state meanwhile
        (:meth:`state_dict`) have their copy."""
        if not callable(on_step):
            return on_step
        if kind := _not_run(on_step):
            raise InputError(f"advance(on_step={on_step!r}): {kind}; {ON_STEP_RUN}")

        def reading(sim: Any, dt: float) -> None:
            with self._on_step_readers:
                self._on_step_thread = threading.get_ident()
                self._on_step_readers.notify_all()  # a thread waiting its turn is refused (_turn)
            try:
                returned = on_step(sim, dt)
                if (
                    inspect.isawaitable(returned)
                    or inspect.isgenerator(returned)
                    or inspect.isasyncgen(returned)
                ):
                    getattr(returned, "close", lambda: None)()  # never awaited: no warning of Python's
                    raise InputError(
                        f"advance(on_step={on_step!r}): returned {type(returned).__name__} {returned!r}, "
                        f"so its body did not run at t = {sim.t:.6g} s; {ON_STEP_RUN}"
                    )
            finally:
                with self._on_step_readers:
                    self._on_step_readers.wait_for(lambda: not self._readers)
                    self._on_step_thread = None

        return reading

    def _not_in_on_step(self, call: str) -> None:
        """:class:`InputError` naming ``call`` (a step, an ``advance`` or a ``load_state``)
        made while advance's on_step runs: from the on_step itself it stepped past the
        time advance stops at; from another thread it waited for ever for advance to
        release the simulation where the on_step waited for that thread (a thread it
        started and joined).  Outside an on_step, other threads wait their turn."""
        thread = self._on_step_thread
        if thread is None:
            return
        if thread == threading.get_ident():
            raise InputError(
                f"{call} from the on_step of advance: it stepped the simulation advance steps, past the "
                "time advance stops at; accepted: an on_step that reads the simulation (sim.t, "
                "sim.state_dict()) and steps after advance returns"
            )
        raise InputError(
            f"{call} from another thread while the on_step of advance runs: advance holds the "
            "simulation until its on_step returns, which may be waiting for this thread; accepted: "
            "state_dict() from any thread, steps and load_state once advance returns"
        )

    def step(self, t_max: float = np.inf) -> float:
        """The engine's :meth:`~multilayer.engine.simulation.Simulation.step`, its bound read
        as :func:`_time` reads it.  Calls from several threads on one simulation take turns
        (with ``advance`` and ``load_state``): two threads stepping it at once interleaved
        the stages of their steps, and ``advance(0.2)`` from two threads ended past 0.2 s
        with another state than one call, silently; a step while advance's on_step runs is
        refused (:meth:`_not_in_on_step`).  What a step changed of
        :func:`~multilayer.plugins.host.host_state` (a plugin's doing) is set back and
        named, a :class:`~multilayer.engine.plugin_output.PluginOutputError` after the
        step is kept."""
        bound = _time(t_max, "step(t_max")
        with self._turn(f"step(t_max={t_max!r})"):
            host = host_state()
            try:
                dt = super().step(bound)
            finally:
                changed = set_back(host)
            if changed:
                laws = " or ".join(map(plugin_label, self._laws))
                raise PluginOutputError(
                    f"step {self.steps} (to t = {self.t:.6g} s) changed {changed}, which no code of "
                    f"multilayer changes: {laws}, or another thread; {HOST_CHANGED}"
                )
            return dt

    def __copy__(self) -> NoReturn:
        """Refused (:meth:`_not_copied`): a shallow copy shared the state's arrays, so
        stepping the copy changed the original's thickness and velocities, not its time."""
        self._not_copied()

    def __deepcopy__(self, memo: dict) -> NoReturn:
        self._not_copied()

    def __reduce_ex__(self, protocol: Any) -> NoReturn:
        self._not_copied()

    def _not_copied(self) -> NoReturn:
        raise InputError(
            "a Simulation cannot be copied or pickled (it holds the engine's workspaces, threads and locks); "
            "accepted: state_dict() to keep a state, and load_state(saved) of a Simulation of the same "
            "scenario to continue from it"
        )

    def state_dict(self) -> dict:
        """The engine's :meth:`~multilayer.engine.simulation.Simulation.state_dict`, not
        during another thread's step: read while a step is kept, it held the forces of the
        step with the time and state before it, a checkpoint that no run reaches.  From
        another thread while advance's on_step runs, the state between its steps, read
        without waiting (the on_step may be waiting for this thread), and advance goes on
        once it is read."""
        with self._turn(None, reader=True):
            return super().state_dict()

    def load_state(self, saved: dict) -> None:
        """The engine's :meth:`~multilayer.engine.simulation.Simulation.load_state`, not
        during another thread's step; :class:`InputError` for what is no mapping, and from
        another thread while advance's on_step runs (:meth:`_not_in_on_step`)."""
        if not isinstance(saved, Mapping):
            raise InputError(
                f"load_state(saved={shown(saved)}): accepted: a mapping as state_dict() gives it"
            )
        with self._turn(None if self._on_step_thread == threading.get_ident() else "load_state(saved)"):
            super().load_state(saved)


ON_STEP_RUN = (
    "advance calls on_step and neither awaits nor iterates what it returns; accepted: a function "
    "of (sim, dt) doing its work when called (a plain def or lambda)"
)
"""What an ``on_step`` whose body never runs is told (:func:`_not_run`)."""


def _not_run(on_step: Any) -> str:
    """What ``on_step`` is if calling it does not run its body, in words, or "": an ``async
    def`` returns a coroutine and a generator function a generator, which advance ignored
    (the body never ran, silently, but for Python's "never awaited" warning at exit)."""
    for test, kind in (
        (inspect.iscoroutinefunction, "an async function (async def)"),
        (inspect.isasyncgenfunction, "an async generator function"),
        (inspect.isgeneratorfunction, "a generator function (it yields)"),
    ):
        if test(on_step):
            return kind
    return ""


def _time(value: Any, call: str) -> Any:
    """A time given to the API as a Python float, which the engine keeps as ``t`` when it
    lands on it: a boolean is no time (``advance(True)`` made ``t`` the boolean), a number
    of numpy (``np.float32``) or a 0-d array is its value as a float (``t`` kept its type,
    and float32 arithmetic after), an integer past 1e308 none the engine can reach
    (Python's ``OverflowError``).  :class:`InputError` naming the call for those; anything
    else is left to the engine's checks."""
    item = value.item() if isinstance(value, np.ndarray) and value.ndim == 0 else value
    if isinstance(item, bool | np.bool_):
        raise InputError(f"{call}={value!r}): a boolean; accepted: a number of seconds")
    if not isinstance(item, numbers.Real):
        return value
    try:
        return float(item)
    except OverflowError:
        raise InputError(
            f"{call}={shown(value)}): more than 1e308 s; accepted: a finite number (s)"
        ) from None
