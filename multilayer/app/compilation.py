"""What a run says while numba compiles the engine's kernels.

numba compiles each kernel on its first use after installation (or after a change of the
kernel sources, engine/kernel_cache.py) and caches it: the first run waits for it, about
45 s on 2 cores (docs/performance.md, "What the figures mean"), inside its first step, before the
progress line can show anything.  :func:`compile_notice` says so once, when the first
compilation starts, and reports in ``run.log`` how long the compilation took.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from numba.core import event as numba_event

NOTICE = (
    "compiling the numba kernels for their first use: once after installing or updating "
    "multilayer, about a minute on 2 cores, then cached for later runs"
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


@contextmanager
def compile_notice(log: logging.Logger, say: Callable[[str], None] | None) -> Iterator[None]:
    """Within the block, the first numba compilation is announced in ``log`` and through
    ``say`` (None: silent); at the block's end ``log`` gets the time spent compiling."""

    def announce() -> None:
        log.info("%s", NOTICE)
        if say is not None:
            say(NOTICE)

    compilations = _Compilations(announce)
    with numba_event.install_listener("numba:compile", compilations):
        try:
            yield
        finally:
            if compilations.seconds is not None:
                log.info("numba compiled kernels for %.1f s (cached for later runs)", compilations.seconds)
