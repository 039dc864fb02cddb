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
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import os
import time
import types
from collections import Counter
from collections.abc import Callable
from typing import Any

from multilayer.errors import InputError

ENVIRONMENT = "MULTILAYER_THREADS"
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
    import numba

    load_tbb()
    numba.get_num_threads()  # starts the threading layer
    return bool(numba.threading_layer() == "tbb")


def parallel_chunks(threads: int, items: int, smallest: int = 1) -> int:
    """How many pieces a parallel kernel cuts ``items`` into for ``threads`` threads:
    ``CHUNKS_PER_THREAD`` per thread, of at least ``smallest`` items each."""
    return max(1, min(CHUNKS_PER_THREAD * threads, items // smallest))


def parallel_compiled(function: Callable, **options: Any) -> Any:
    """``numba.njit(cache=True, parallel=True, **options)`` of ``function``, compiled and
    cached apart from its serial compilation.

    numba's on-disk cache names a compilation by the function's qualified name and first
    line and keys it by its signature only: a serial and a parallel compilation of one
    function shared one entry, and whichever had been compiled last was loaded for both
    (the parallel kernels ran the serial code).  The parallel one is compiled from a copy
    of the function named ``<name>_parallel``."""
    from numba import njit

    load_tbb()
    name = f"{function.__name__}_parallel"
    qualname = f"{function.__qualname__}_parallel"
    code = function.__code__.replace(co_name=name, co_qualname=qualname)
    copy = types.FunctionType(code, function.__globals__, name, function.__defaults__, function.__closure__)
    copy.__qualname__, copy.__doc__, copy.__module__ = qualname, function.__doc__, function.__module__
    return njit(cache=True, parallel=True, **options)(copy)


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
        if not env.isdigit() or int(env) < 1:
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
            import numba

            count = min(count, numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
            numba.set_num_threads(count)
            numba.set_parallel_chunksize(1)  # each prange iteration (a chunk) a task of its own
        self.chosen[count] += 1
        return count
