"""What a run does and says while numba compiles the engine's kernels.

numba compiles each kernel on its first use after installation (or after a change of the
kernel sources, engine/kernel_cache.py) and caches it, unless ``multilayer compile``
(app/precompile.py) did so ahead: the first run then waits for it inside its first step,
before the progress line can show anything (docs/performance.md, "What the figures
mean").  :func:`compile_notice` says so once, when the first compilation
starts, and reports in ``run.log`` how long the compilation took.  :func:`compile_ahead`
shortens that wait where a second core is free: the fused Newton kernel, the largest,
is compiled in a child process (a worker of app/precompile.py) while this one compiles
the transport.
"""

from __future__ import annotations

import logging
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from numba.core import event as numba_event

from multilayer.engine.threads import available_cores
from multilayer.errors import REMOVED_WORKING_DIRECTORY, InputError, working_directory_removed

NOTICE = (
    "compiling the numba kernels for their first use: once after installing or updating "
    "multilayer, about a minute, then cached for later runs ('multilayer compile' does it "
    "ahead, in parallel)"
)


class _Compilations(numba_event.Listener):
    """Counts the wall time of numba's compilations in the thread that made it (runs of
    a study may share a process; numba nests the compilation of the kernels a kernel
    calls inside its own: only the outermost ones are timed); ``on_first`` is called when
    the first one starts."""

    def __init__(self, on_first: Callable[[], None]) -> None:
        self.on_first = on_first
        self.thread = threading.get_ident()
        self.depth = 0
        self.seconds: float | None = None  # None: nothing compiled
        self._start = 0.0

    def on_start(self, event: numba_event.Event) -> None:
        if threading.get_ident() != self.thread:
            return
        if self.depth == 0:
            if self.seconds is None:
                self.seconds = 0.0
                self.on_first()
            self._start = time.perf_counter()
        self.depth += 1

    def on_end(self, event: numba_event.Event) -> None:
        if threading.get_ident() != self.thread:
            return
        self.depth -= 1
        if self.depth == 0 and self.seconds is not None:
            self.seconds += time.perf_counter() - self._start


OPTIMIZED_NOTICE = (
    "; under python -OO (PYTHONOPTIMIZE=2) the kernels that call other kernels are compiled and "
    "cached apart from those of python without it: numba keys their cache on their callees' code, "
    "whose docstrings -OO removes ('PYTHONOPTIMIZE=2 multilayer compile' caches them ahead)"
)
"""Added to :data:`NOTICE` under ``-OO``: a run there compiles about twenty kernels again,
once, though ``multilayer compile`` (without ``-OO``) said them cached; its mark is of its
own optimisation level (app/precompile.py, ``work``)."""


@contextmanager
def compile_notice(log: logging.Logger, say: Callable[[str], None] | None) -> Iterator[None]:
    """Within the block, the first numba compilation is announced in ``log`` and through
    ``say`` (None: silent); at the block's end ``log`` gets the time spent compiling.  A
    compilation in a working directory that no longer exists is an :class:`InputError`
    saying so (numba reads it)."""
    notice = NOTICE + (OPTIMIZED_NOTICE if sys.flags.optimize >= 2 else "")

    def announce() -> None:
        log.info("%s", notice)
        if say is not None:
            say(notice)

    compilations = _Compilations(announce)
    with numba_event.install_listener("numba:compile", compilations):
        try:
            yield
        except FileNotFoundError:  # numba's os.path.relpath of a source, its error naming no file
            if compilations.seconds is None or not working_directory_removed():
                raise
            raise InputError(REMOVED_WORKING_DIRECTORY) from None
        finally:
            if compilations.seconds is not None:
                log.info("numba compiled kernels for %.1f s (cached for later runs)", compilations.seconds)


def interpreter() -> list[str]:
    """The command of a child Python of this process's optimisation level: a child of
    ``python -OO`` started as ``python`` compiled, and cached, the kernels of another
    level than the one its parent marked compiled and runs (app/precompile.py, ``work``)."""
    return [sys.executable, *(["-" + "O" * sys.flags.optimize] if sys.flags.optimize else [])]


SMALL = 16
"""Columns of the copy of a run that compiles its kernels (their types do not depend on the
mesh size)."""


def _small(scenario: Any) -> Any:
    """``scenario`` on :data:`SMALL` columns, one thread: the same kernels, the same types."""
    domain = scenario.domain.model_copy(update={"cells": min(SMALL, scenario.domain.cells)})
    numerics = scenario.numerics.model_copy(update={"threads": 1})
    return scenario.model_copy(update={"domain": domain, "numerics": numerics})


def _newton_cached() -> bool:
    """Whether numba's cache holds a compilation of the fused Newton kernel (its index file,
    once the cache is checked against the kernel sources, engine/kernel_cache.py); True
    too where numba caches nothing (engine/compiled.py): a child's compilation would not
    reach the run."""
    from multilayer.engine import kernel_cache
    from multilayer.engine.vertical import newton_kernel

    kernel_cache.ensure_fresh()
    cache_file = getattr(newton_kernel._chunk._cache, "_cache_file", None)
    return cache_file is None or Path(cache_file._index_path).exists()


def _compile_newton_callees() -> None:
    """Compile (or load) the two callees of the fused Newton kernel that its compilation
    reaches last, the structure proposals and the dynamic programme of the exact solve
    (about 6 s of its 27), by the one signature it calls them with (arrays of float64,
    int64 and bool, contiguous; the programme's work arrays): the kernel, compiled in the
    child process, then links them from the cache (tests/test_compiled_kernels.py checks
    that the cache holds one signature of each)."""
    for kernel, signature in newton_callees():
        kernel.compile(signature)


def newton_callees() -> list[tuple[Any, tuple]]:
    """The callees of :func:`_compile_newton_callees` and the argument types the fused
    Newton kernel calls them with."""
    from numba import types

    from multilayer.engine.vertical import column_solve, newton_kernel

    f, f2, i, b = types.float64[::1], types.float64[:, ::1], types.int64[::1], types.boolean[::1]
    return [
        (column_solve._dynamic_programme, (f,) * 7 + (types.Tuple((f2, f2, i, *(f,) * 10)),)),
        (newton_kernel._other_structures, (f,) * 7 + (f2, types.int64, f, f, i, b) + (f,) * 4 + (i,)),
    ]


def compile_ahead(scenario: Any) -> float | None:
    """Before the run of ``scenario``: when the fused Newton kernel is not in numba's cache
    and the process may use two cores, compile it in a child process (the ``newton`` task of
    ``multilayer compile``, app/precompile.py: its types are every run's) while this process
    compiles two of its callees (:func:`_compile_newton_callees`) and the transport (one
    transport of a small copy of the run), then wait for the child.  The run then loads
    both from the cache.  Returns the seconds this took (None: no child was started).

    The copy is built, and its step found, before the child starts: the kernels both use
    (the state checks, the wave speed) are then compiled here only, and the child loads
    them (two processes compiling one function at once race on its cache entry).  A
    warm-up only: the child's output and failures are ignored (the run compiles what is
    missing and reports its own errors), and its answer is never used."""
    if available_cores() < 2 or _newton_cached():
        return None
    from multilayer.app.simulation import Simulation

    start = time.perf_counter()
    try:
        sim = Simulation(_small(scenario))
        dt = sim.time_step()
    except Exception:  # the run reports it
        return None
    compiled = sim.vertical.compiled
    if sim.mixture is not None or compiled is None or compiled.laws() is None:
        return None  # the run does not use the fused Newton kernel
    try:
        child = subprocess.Popen(
            [*interpreter(), "-m", "multilayer.app.precompile"],
            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, text=True,
        )  # fmt: skip
    except OSError:
        return None
    try:
        assert child.stdin is not None
        try:
            with child.stdin:
                child.stdin.write("newton\n")
            _compile_newton_callees()
            sim._transport(dt, 1)
        except Exception:  # the run reports it
            pass
        child.wait()
        return time.perf_counter() - start
    finally:
        if child.poll() is None:  # interrupted: the child goes with the run
            child.kill()
            child.wait()
