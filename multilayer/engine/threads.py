"""How many threads the compiled kernels use, and how their work is shared.

A parallel kernel on a core that another process also wants runs at the pace of its
slowest thread when the work is split once, one piece per thread: the thread that shares
its core with the other process finishes last while the others wait at the join.  A run
beside one busy process on two cores took 2.5 times as long with two threads as with one
(docs/performance.md, "Threads").  Two things prevent it:

- **Work stealing.**  Every parallel kernel cuts its work into :func:`parallel_chunks`
  (``CHUNKS_PER_THREAD`` per thread) handed out one at a time, and numba's TBB threading
  layer (Intel oneTBB's work-stealing scheduler) lets an idle thread take the chunks a
  slower one has not started.  The ``tbb`` package ships ``libtbb`` in the environment's
  ``lib`` directory, where numba's TBB layer does not look; :func:`load_tbb` loads it
  before the first parallel kernel is compiled, so that numba finds it (its default layer
  priority is TBB, then OpenMP, then its own work queue).  Without TBB (``tbb`` not
  installed, or ``NUMBA_THREADING_LAYER`` naming another layer), OpenMP or numba's work
  queue hand the chunks out in fixed blocks, one per thread.
- **The thread count.**  In this order:

  1. the environment variable ``MULTILAYER_THREADS`` (a positive integer) wins;
  2. then the scenario key ``numerics.threads`` (a positive integer, or ``auto``);
  3. ``auto``: one thread for steps smaller than ``PARALLEL_CELLS`` cells (a parallel
     launch costs more than it gains); otherwise, with work stealing, every core this
     process may run on (beside a busy process two threads still get a fair share of
     both cores, more than one thread gets); without it, as many threads as there are
     cores left idle by the other processes, measured from ``/proc/stat`` minus this
     process's own CPU time over the last ``REFRESH`` seconds (one thread until the first
     measurement, and where ``/proc/stat`` does not exist).

- **Binding.**  A parallel kernel whose threads use every core this process may run on
  runs each thread on a core of its own (:func:`run_bound`): the TBB workers stay on
  theirs, the calling thread is held on the first core for the length of the kernel
  (given every core back if numba compiles the kernel inside the call).
  Unbound, the scheduler often places a worker that wakes at the start of a kernel beside
  the thread that woke it while a busy process keeps the other core to itself: the two
  threads of the chute beside one busy process got 1.11-1.28 cores instead of their fair
  share, 4/3; bound, 1.27-1.35 (docs/performance.md, "Threads").  Only a kernel on every
  core is bound, so that no core is left idle when several runs share a machine.
  ``MULTILAYER_BIND_THREADS=0`` turns it off.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import os
import threading
import time
import types
from collections import Counter
from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from numba import njit, prange
from numba.core import event as numba_event

from multilayer.errors import InputError

ENVIRONMENT = "MULTILAYER_THREADS"
BIND_ENVIRONMENT = "MULTILAYER_BIND_THREADS"
PARALLEL_CELLS = 200_000
"""Steps on fewer cells than this run on one thread (see docs/performance.md)."""
REFRESH = 0.5
"""Seconds between two measurements of the idle cores."""
CHUNKS_PER_THREAD = 8
"""Pieces of work per thread of a parallel kernel, handed out one at a time."""


@functools.cache
def load_tbb() -> bool:
    """Load the ``libtbb`` of the installed ``tbb`` package (once), so that numba's TBB
    threading layer can start (numba's extension finds it only on the loader's path);
    called before the first parallel kernel is compiled.  True if loaded; False where the
    package or its library is missing."""
    try:
        files = importlib.metadata.files("tbb") or []
    except importlib.metadata.PackageNotFoundError:
        return False
    for file in files:
        if file.name.startswith("libtbb.so."):
            try:
                ctypes.CDLL(str(file.locate()), mode=ctypes.RTLD_GLOBAL)
            except OSError:
                return False
            return True
    return False


@functools.cache
def steals_work() -> bool:
    """Whether numba's threading layer is TBB (it starts the layer if not started; the
    layer of a process never changes once started)."""
    load_tbb()
    numba.get_num_threads()  # starts the threading layer
    return bool(numba.threading_layer() == "tbb")


def parallel_chunks(threads: int, items: int, smallest: int = 1) -> int:
    """How many pieces a parallel kernel cuts ``items`` into for ``threads`` threads:
    ``CHUNKS_PER_THREAD`` per thread, of at least ``smallest`` items each."""
    return max(1, min(CHUNKS_PER_THREAD * threads, items // smallest))


def parallel_compiled(function: Callable, **options: Any) -> Any:
    """``numba.njit(cache=True, parallel=True, **options)`` of ``function``, compiled and
    cached apart from its serial compilation, and called through :func:`run_bound`
    (:class:`BoundKernel`).

    numba's on-disk cache names a compilation by the function's qualified name and first
    line and keys it by its signature only: a serial and a parallel compilation of one
    function shared one entry, and whichever had been compiled last was loaded for both
    (the parallel kernels ran the serial code).  The parallel one is compiled from a copy
    of the function named ``<name>_parallel``."""
    load_tbb()
    name = f"{function.__name__}_parallel"
    qualname = f"{function.__qualname__}_parallel"
    code = function.__code__.replace(co_name=name, co_qualname=qualname)
    copy = types.FunctionType(code, function.__globals__, name, function.__defaults__, function.__closure__)
    copy.__qualname__, copy.__doc__, copy.__module__ = qualname, function.__doc__, function.__module__
    return BoundKernel(njit(cache=True, parallel=True, **options)(copy))


class BoundKernel:
    """A parallel kernel called through :func:`run_bound`; its numba dispatcher's
    attributes are its own."""

    def __init__(self, dispatcher: Any):
        self.dispatcher = dispatcher

    def __call__(self, *args: Any) -> Any:
        return run_bound(self.dispatcher, args)

    def __getattr__(self, name: str) -> Any:
        return getattr(self.dispatcher, name)


class _Binding:
    """Where the threads of this process run: the thread that calls the kernels (held on
    ``core`` during each of them), the cores it may run on (``allowed``, given back after
    each), and whether numba's TBB workers were found and bound to the other cores."""

    def __init__(self) -> None:
        self.pid = os.getpid()
        self.caller = threading.get_native_id()
        self.allowed = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else set()
        self.core = min(self.allowed, default=0)
        self.probed = False
        self.bound = False
        self.held = False  # the caller is on ``core`` now (inside a kernel call)


_binding: _Binding | None = None
PROBES = 5
"""Runs of the probe kernel that look for the TBB workers before binding is given up."""
PROBE_CHUNKS = 32
"""Pieces of work per thread of the probe kernel, of about 40 microseconds each."""
PROBE_STEPS, PROBE_FACTOR = 20_000, 0.999999
"""Each piece of the probe kernel: ``x <- PROBE_FACTOR x + 1``, ``PROBE_STEPS`` times from 0."""


def _occupy(work: np.ndarray) -> None:
    """The probe kernel: ``work.size`` pieces of ``PROBE_STEPS`` multiply-adds (about 40
    microseconds) each, enough for every thread of the pool to take some."""
    for k in prange(work.size):
        x = 0.0
        for _ in range(PROBE_STEPS):
            x = x * PROBE_FACTOR + 1.0
        work[k] = x


_probe = njit(cache=True, parallel=True)(_occupy)


def _thread_run_times() -> dict[int, int]:
    """Nanoseconds each thread of this process has run (``/proc/self/task/*/schedstat``)."""
    times: dict[int, int] = {}
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return times
    for task in tasks:
        try:
            with open(f"/proc/self/task/{task}/schedstat") as stat:
                times[int(task)] = int(stat.read().split()[0])
        except (OSError, ValueError, IndexError):
            continue
    return times


def _bind_workers(binding: _Binding, count: int) -> None:
    """Find numba's TBB workers, the threads other than Python's own that run the probe
    kernel on ``count`` threads, and bind each to one of the cores other than
    ``binding.core``.  The probe runs until it finds as many of them as those cores (the
    first parallel kernel of a process also starts the workers, which may take longer than
    the probe), at most ``PROBES`` times."""
    others = sorted(binding.allowed - {binding.core})
    for _ in range(PROBES):
        before = _thread_run_times()
        _probe(np.empty(PROBE_CHUNKS * count))
        after = _thread_run_times()
        python_threads = {t.native_id for t in threading.enumerate()}
        workers = sorted(t for t, ran in after.items() if ran > before.get(t, -1) and t not in python_threads)
        if len(workers) == len(others):
            try:
                for worker, core in zip(workers, others, strict=True):
                    os.sched_setaffinity(worker, {core})
            except OSError:
                return
            binding.bound = True
            return


def binding_wanted() -> bool:
    """Whether threads may be bound to cores: ``MULTILAYER_BIND_THREADS`` unset, empty or
    ``1``; ``0`` turns it off."""
    value = os.environ.get(BIND_ENVIRONMENT, "").strip()
    if value not in ("", "0", "1"):
        raise InputError(
            f"environment variable {BIND_ENVIRONMENT}={value!r}; accepted: 0 (off) or 1 (on, the default)"
        )
    return value != "0"


def run_bound(kernel: Any, args: tuple) -> Any:
    """``kernel(*args)``, each of its threads on a core of its own when it uses every core
    this process may run on under TBB (module docstring, "Binding")."""
    global _binding
    count = numba.get_num_threads()
    if count < 2 or not binding_wanted() or not steals_work():
        return kernel(*args)
    if _binding is None or _binding.pid != os.getpid():  # a forked child has threads of its own
        _binding = _Binding()
    binding = _binding
    if len(binding.allowed) != count or threading.get_native_id() != binding.caller:
        return kernel(*args)
    if not binding.probed:
        binding.probed = True
        _bind_workers(binding, count)
    if not binding.bound:
        return kernel(*args)
    try:
        os.sched_setaffinity(0, {binding.core})
    except OSError:  # the core was taken from this process (a changed cpuset): stop binding
        binding.bound = False
        return kernel(*args)
    binding.held = True
    try:
        return kernel(*args)
    finally:
        binding.held = False
        os.sched_setaffinity(0, binding.allowed)


class _ReleaseWhileCompiling(numba_event.Listener):
    """A kernel called for the first time with new argument types is compiled inside the
    call, for seconds, on the calling thread alone: that thread is given back every core
    for it (held on one, two test processes compiling at once shared that core)."""

    def on_start(self, event: numba_event.Event) -> None:
        binding = _binding
        if binding is not None and binding.held and threading.get_native_id() == binding.caller:
            binding.held = False
            os.sched_setaffinity(0, binding.allowed)

    def on_end(self, event: numba_event.Event) -> None:
        pass


numba_event.register("numba:compile", _ReleaseWhileCompiling())


def workers_bound() -> bool:
    """Whether this process's TBB workers run each on a core of its own (``run_bound``)."""
    return _binding is not None and _binding.pid == os.getpid() and _binding.bound


def available_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _busy_seconds() -> float | None:
    """CPU seconds spent by all processes (the non-idle jiffies of /proc/stat)."""
    try:
        with open("/proc/stat") as stat:
            fields = [int(v) for v in stat.readline().split()[1:]]
    except (OSError, ValueError):
        return None
    idle = fields[3] + (fields[4] if len(fields) > 4 else 0)  # idle + iowait
    return (sum(fields[:8]) - idle) / os.sysconf("SC_CLK_TCK")


def _own_seconds() -> float:
    t = os.times()
    return t.user + t.system


def requested(setting: int | str = "auto") -> int | None:
    """The fixed thread count asked for (environment first), None for ``auto``."""
    env = os.environ.get(ENVIRONMENT, "").strip()
    if env and env != "auto":
        if not (env.isascii() and env.isdigit()) or int(env) < 1:  # '²'.isdigit() is True
            raise InputError(
                f"environment variable {ENVIRONMENT}={env!r}; accepted: 'auto' or an integer >= 1"
            )
        return int(env)
    if env == "auto" or setting == "auto":
        return None
    return int(setting)


class ThreadPolicy:
    """Chooses the thread count of each step (module docstring)."""

    def __init__(self, setting: int | str = "auto"):
        self.fixed = requested(setting)
        binding_wanted()  # a wrong value stops the run before its first step
        self.cores = available_cores()
        self.idle = 1  # until measured
        self._last: tuple[float, float | None, float] | None = None
        self.chosen: Counter[int] = Counter()  # steps run with each thread count

    def _measure(self) -> None:
        """Update ``idle`` when ``REFRESH`` seconds have passed since the last sample."""
        now = time.monotonic()
        if self._last is not None and now - self._last[0] < REFRESH:
            return
        sample = (now, _busy_seconds(), _own_seconds())
        last, self._last = self._last, sample
        if last is None or sample[1] is None or last[1] is None:
            return
        others = (sample[1] - last[1]) - (sample[2] - last[2])
        self.idle = max(1, min(self.cores, round(self.cores - max(others, 0.0) / (now - last[0]))))

    def threads(self, cells: int) -> int:
        """Threads for a step that computes ``cells`` cells."""
        if self.fixed is not None:
            count = self.fixed
        elif cells < PARALLEL_CELLS:
            count = 1
        elif steals_work():
            count = self.cores
        else:
            self._measure()
            count = self.idle
        if count > 1:
            count = min(count, numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
            numba.set_num_threads(count)
            numba.set_parallel_chunksize(1)  # each prange iteration (a chunk) a task of its own
        self.chosen[count] += 1
        return count
