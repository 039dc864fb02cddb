"""The environment variables of numba that the engine cannot run with, checked by the
command line before a command imports numba (numba reads them once, at its import).

- ``NUMBA_NUM_THREADS`` (numba's thread pool): numba's import raised a ``ValueError``
  for ``0`` and warned, quoting a traceback, for text; an ASCII integer >= 1 here.
- ``NUMBA_DISABLE_JIT``: the engine's kernels are numba functions (their cache, their
  parallel variants, their compiled signatures): unset or ``0``.
- ``NUMBA_THREADING_LAYER``: a layer numba knows (numba's documentation, "Setting the
  threading layer"); another name failed in the first parallel kernel, mid-run.

Other variables numba cannot read it warns about and ignores (the command line prints
the warning without the traceback it quotes).  Through the Python API the variables are
set before the host imports anything, and the library cannot change numba's import: where
the import of the engine fails (numba's own ``ValueError`` for ``NUMBA_NUM_THREADS=0``,
the engine's kernels not numba functions under ``NUMBA_DISABLE_JIT=1``), :func:`named`
names the variable instead; ``multilayer.Simulation`` and the runner call :func:`check`
before anything is built (numba reads ``NUMBA_THREADING_LAYER`` only at its first
parallel kernel).
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager

from multilayer.errors import InputError

THREADING_LAYERS = ("default", "safe", "forksafe", "threadsafe", "tbb", "omp", "workqueue")
"""The values of ``NUMBA_THREADING_LAYER`` numba knows."""


def check() -> None:
    """:class:`InputError` naming the variable, its value and what is accepted, for a
    value of the module docstring's variables the engine cannot run with."""
    threads = os.environ.get("NUMBA_NUM_THREADS")
    if threads is not None and not (threads.strip().isascii() and threads.strip().isdigit() and int(threads)):
        _refuse("NUMBA_NUM_THREADS", threads, "an integer >= 1 (ASCII digits), or unset")
    disabled = os.environ.get("NUMBA_DISABLE_JIT")
    if disabled is not None and disabled.strip() not in ("", "0"):
        _refuse("NUMBA_DISABLE_JIT", disabled, "0 or unset: the engine's kernels need numba's compiler")
    layer = os.environ.get("NUMBA_THREADING_LAYER")
    if layer is not None and layer not in THREADING_LAYERS:
        _refuse("NUMBA_THREADING_LAYER", layer, ", ".join(THREADING_LAYERS) + ", or unset")


@contextmanager
def named() -> Iterator[None]:
    """Within the block (an import of the engine, which imports numba), an exception
    raised where a variable of the module docstring holds a value the engine cannot run
    with is the :class:`InputError` of :func:`check` naming it, from that exception."""
    try:
        yield
    except Exception as failure:
        try:
            check()
        except InputError as error:
            raise error from failure
        raise


def _refuse(name: str, value: str, accepted: str) -> None:
    raise InputError(f"environment variable {name}={value[:60]!r}; accepted: {accepted}")
