"""The environment variables of numba that the engine cannot run with, checked by the
command line before a command imports numba (numba reads them once, at its import).

- ``NUMBA_NUM_THREADS`` (numba's thread pool): numba's import raised a ``ValueError``
  for ``0`` and warned, quoting a traceback, for text; an ASCII integer >= 1 here.
- ``NUMBA_DISABLE_JIT``: the engine's kernels are numba functions (their cache, their
  parallel variants, their compiled signatures): unset or ``0``.
- ``NUMBA_THREADING_LAYER``: a layer numba knows (numba's documentation, "Setting the
  threading layer"); another name failed in the first parallel kernel, mid-run.

numba reads the same settings, lowercase without ``NUMBA_``, from a file
``.numba_config.yaml`` in the working directory, the environment's over them: its values
are checked as well, and a file numba's import fails on (malformed YAML, no mapping, a key
that is no text) is named, where it was a traceback of numba's import.

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

import yaml

from multilayer.errors import MAX_COUNT_DIGITS, InputError, ascii_count, reason
from multilayer.scenario.source import safe_load

THREADING_LAYERS = ("default", "safe", "forksafe", "threadsafe", "tbb", "omp", "workqueue")
"""The values of ``NUMBA_THREADING_LAYER`` numba knows."""


CONFIG_FILE = ".numba_config.yaml"
"""numba's configuration file, read from the working directory at numba's import."""


def check() -> None:
    """:class:`InputError` naming the variable, its value and what is accepted, for a
    value of the module docstring's variables the engine cannot run with, set in the
    environment or in numba's :data:`CONFIG_FILE`."""
    settings = _settings()
    threads = settings.get("NUMBA_NUM_THREADS")
    if threads is not None and not ascii_count(threads[0]):  # int() of 5000 digits raised
        _refuse(threads, f"an integer >= 1 (ASCII digits, at most {MAX_COUNT_DIGITS}), or unset")
    disabled = settings.get("NUMBA_DISABLE_JIT")
    if disabled is not None and disabled[0].strip() not in ("", "0"):
        _refuse(disabled, "0 or unset: the engine's kernels need numba's compiler")
    layer = settings.get("NUMBA_THREADING_LAYER")
    if layer is not None and layer[0] not in THREADING_LAYERS:
        _refuse(layer, ", ".join(THREADING_LAYERS) + ", or unset")


def _settings() -> dict[str, tuple[str, str]]:
    """numba's settings as its import reads them: the entries of :data:`CONFIG_FILE` in the
    working directory (a regular file), the environment's ``NUMBA_`` variables over them;
    each name (``NUMBA_NUM_THREADS``) to its value as text and where it is set."""
    found: dict[str, tuple[str, str]] = {}
    if os.path.isfile(CONFIG_FILE):
        path = os.path.abspath(CONFIG_FILE)
        where = f"{path} (numba's configuration file, read by numba at its import)"
        accepted = "a YAML mapping of numba's settings (num_threads: 4), or no such file"
        try:
            with open(CONFIG_FILE, encoding="utf-8") as stream:
                data = safe_load(stream.read())
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
            raise InputError(f"{where}: {' '.join(reason(exc).split())}; accepted: {accepted}") from None
        if data is not None and not (isinstance(data, dict) and all(isinstance(key, str) for key in data)):
            raise InputError(f"{where}: got {repr(data)[:60]}; accepted: {accepted}")
        for key, value in (data or {}).items():
            found["NUMBA_" + key.upper()] = (str(value), f"{path} (numba's configuration file): {key}: ")
    for name, value in os.environ.items():
        if name.startswith("NUMBA_"):
            found[name] = (value, f"environment variable {name}=")
    return found


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


def _refuse(setting: tuple[str, str], accepted: str) -> None:
    value, where = setting
    raise InputError(f"{where}{value[:60]!r}; accepted: {accepted}")
