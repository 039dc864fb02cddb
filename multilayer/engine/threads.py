"""How many threads the compiled kernels use: numba's thread count, and nothing else.

In this order:

1. the environment variable ``MULTILAYER_THREADS`` (a positive integer, or ``auto``) wins;
2. then the scenario key ``numerics.threads`` (a positive integer, or ``auto``);
3. ``auto``: one thread for steps smaller than ``PARALLEL_CELLS`` cells (a parallel launch
   costs more than it gains; every shipped scenario is below it), otherwise every core
   this process may run on, at most numba's ``NUMBA_NUM_THREADS``.

A step on one thread runs the serial kernels and touches no numba setting.  A step on
more threads runs the parallel kernels inside :func:`numba_threads`, which sets numba's
thread count for the calls and gives the caller's setting back after them.  A parallel
kernel cuts its work into :func:`parallel_chunks` (``CHUNKS_PER_THREAD`` per thread) handed
out one at a time, so that a thread slowed by another process on its core takes fewer
(numba's TBB threading layer steals work between its threads; it is the layer numba
prefers when the optional ``tbb`` package is installed, ``pip install 'multilayer[tbb]'``,
whose ``libtbb`` :func:`load_tbb` makes visible to numba before the first parallel kernel).
The library pins no thread to a core, reads no system statistics and registers nothing.
"""

from __future__ import annotations

import ctypes
import functools
import importlib.metadata
import os
import threading
import warnings
from collections import Counter
from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext

from multilayer.errors import MAX_COUNT_DIGITS, InputError, ascii_count

ENVIRONMENT = "MULTILAYER_THREADS"
PARALLEL_CELLS = 200_000
"""Steps on fewer cells than this run on one thread (see docs/performance.md)."""
CHUNKS_PER_THREAD = 8
"""Pieces of work per thread of a parallel kernel, handed out one at a time."""
THREADS_ACCEPTED = "auto or an integer >= 1 (the environment variable MULTILAYER_THREADS wins)"
"""What ``numerics.threads`` accepts."""


@functools.cache
def load_tbb() -> bool:
    """Load the ``libtbb`` of the installed ``tbb`` package (once), so that numba's TBB
    threading layer can start (numba finds it only on the loader's path).  True if loaded;
    False where the package (the optional ``tbb`` extra) or its library is missing."""
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


def parallel_chunks(threads: int, items: int, smallest: int = 1) -> int:
    """How many pieces a parallel kernel cuts ``items`` into for ``threads`` threads:
    ``CHUNKS_PER_THREAD`` per thread, of at least ``smallest`` items each."""
    return max(1, min(CHUNKS_PER_THREAD * threads, items // smallest))


_LAUNCHES = threading.RLock()
"""Held by :func:`numba_threads`: one thread of the process at a time runs parallel kernels.
numba's workqueue threading layer (the one it falls back to where neither TBB nor OpenMP
is found, or ``NUMBA_THREADING_LAYER=workqueue``) is not thread-safe: two simulations
stepped in two threads, as docs/api.md allows, terminated the whole process ("Concurrent
access has been detected").  The other layers would run both on the same cores."""


_SERIAL = nullcontext()
"""What :func:`numba_threads` gives for one thread: made once (a generator-based context
costs a microsecond a call, several calls a step)."""


def numba_threads(count: int) -> AbstractContextManager[None]:
    """numba's thread count (and a chunk of one iteration per task, so that the chunks of
    :func:`parallel_chunks` are handed out one at a time) set to ``count`` for the calls of
    the block, at most numba's ``NUMBA_NUM_THREADS``, one thread of the process at a time
    (:data:`_LAUNCHES`); the caller's settings are given back after it.  Nothing for
    ``count <= 1`` (the serial kernels)."""
    return _SERIAL if count <= 1 else _parallel_launch(count)


_launched_in: int | None = None
"""The process id of the process whose parallel launch started numba's threading layer
(None: no parallel kernel was launched by this library before)."""


def forked_from_gnu_openmp() -> bool:
    """Whether this process is a fork (``multiprocessing``'s default on Linux, ``os.fork``)
    of a process that ran parallel kernels on numba's OpenMP threading layer built with GNU
    OpenMP, the layer numba takes where TBB is not installed.  GNU OpenMP cannot run in such
    a child: numba's first parallel launch there prints "Terminating: fork() called from a
    process already using GNU OpenMP, this is unsafe." and sends the process SIGTERM (numba's
    documentation, "Threading layers": ``omp`` is not fork-safe with GNU OpenMP), which
    stopped the child's run as if the user had.  Said once per process, with a warning; the
    step then runs the serial kernels, whose answer is the parallel ones'."""
    if _launched_in is None or _launched_in == os.getpid():
        return False
    import numba
    from numba.np.ufunc import omppool  # type: ignore[attr-defined]

    if numba.threading_layer() != "omp" or getattr(omppool, "openmp_vendor", "GNU") != "GNU":
        return False
    _warn_forked()
    return True


@functools.cache
def _warn_forked() -> None:
    warnings.warn(
        "this process is a fork of one that ran numba's GNU OpenMP threads, which cannot run in a "
        "forked process: its steps run on one thread (start such processes with multiprocessing's "
        "'spawn' or 'forkserver' context, or install numba's TBB layer: pip install 'multilayer[tbb]')",
        stacklevel=4,
    )


@contextmanager
def _parallel_launch(count: int) -> Iterator[None]:
    """:func:`numba_threads` for ``count >= 2`` threads."""
    import numba

    global _launched_in
    load_tbb()  # before numba starts its threading layer
    with _LAUNCHES:
        if _launched_in is None:
            _launched_in = os.getpid()
        previous = numba.get_num_threads(), numba.get_parallel_chunksize()
        numba.set_num_threads(min(count, numba.config.NUMBA_NUM_THREADS))  # type: ignore[attr-defined]
        numba.set_parallel_chunksize(1)
        try:
            yield
        finally:
            numba.set_num_threads(previous[0])
            numba.set_parallel_chunksize(previous[1])


def available_cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def requested(setting: int | str = "auto") -> int | None:
    """The fixed thread count asked for (environment first), None for ``auto``."""
    env = os.environ.get(ENVIRONMENT, "").strip()
    if env and env != "auto":
        count = ascii_count(env)  # '²'.isdigit() is True; int() of 5000 digits raised
        if count is None or count < 1:
            raise InputError(
                f"environment variable {ENVIRONMENT}={env[:60]!r}; accepted: 'auto' or an integer >= 1 "
                f"(ASCII digits, at most {MAX_COUNT_DIGITS})"
            )
        return count
    if env == "auto" or setting == "auto":
        return None
    return int(setting)


class ThreadPolicy:
    """Chooses the thread count of each step (module docstring)."""

    def __init__(self, setting: int | str = "auto"):
        self.fixed = requested(setting)
        self.cores = available_cores()
        self.chosen: Counter[int] = Counter()  # steps run with each thread count

    def threads(self, cells: int) -> int:
        """Threads for a step that computes ``cells`` cells."""
        if self.fixed is not None:
            count = self.fixed
        elif cells < PARALLEL_CELLS:
            count = 1
        else:
            count = self.cores
        if count > 1:
            import numba

            count = min(count, numba.config.NUMBA_NUM_THREADS)  # type: ignore[attr-defined]
            if forked_from_gnu_openmp():
                count = 1
        self.chosen[count] += 1
        return count
