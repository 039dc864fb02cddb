"""Shared fixtures: a tiny valid scenario, a writer for scenario files, an in-process CLI."""

from __future__ import annotations

import copy
import importlib.util
import os
import shutil
import signal
import sys
import tempfile
import time
import types
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import yaml


def _rewrite_test_modules_only() -> None:
    """pytest rewrites the asserts of every module of a distribution that registers a
    plugin (``pytest11``): all of ``multilayer`` (its plugin of ``expect:`` lists) and of
    ``hypothesis``.  Their asserts are the library's own checks, not the tests', and the
    rewriting is not cached where Python writes no bytecode (``PYTHONDONTWRITEBYTECODE``,
    a read-only checkout): each xdist worker parsed and rewrote some 200 library modules,
    a sixth of its collection's CPU time.  The marks are taken off pytest's hook (its
    ``_must_rewrite``; a pytest without it is left as it is) before the library is
    imported here; the test modules and this file are rewritten as before."""
    for hook in sys.meta_path:
        marked = getattr(hook, "_must_rewrite", None)
        if isinstance(marked, set):
            marked.difference_update({"multilayer", "hypothesis"})
            getattr(hook, "_marked_for_rewrite_cache", {}).clear()


_rewrite_test_modules_only()

from multilayer.app.cli import main  # noqa: E402
from multilayer.app.precompile import compile_kernels  # noqa: E402

WARM_UP_ITEMS = 100
"""A run of at least this many tests on two or more xdist workers compiles the numba
kernels first (``multilayer compile``, in parallel processes) in the first worker while
the others wait, so that no two workers compile the same kernel."""
WARM_UP_WAIT = 900.0
"""Seconds a worker waits for the first one's compilation before going on without it."""


STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))
"""The signals whose handlers no test may leave changed (:func:`_signal_handlers_kept`)."""


@pytest.fixture(autouse=True)
def _signal_handlers_kept() -> Any:
    """A library does not change its host process: a test after which a stop signal's
    handler is not the one it started with fails at its teardown, naming the signal, and
    the handler is set back so that the tests after it start from the process's own."""
    before = {signum: signal.getsignal(signum) for signum in STOP_SIGNALS}
    yield
    changed = {signum: handler for signum, handler in before.items() if signal.getsignal(signum) != handler}
    for signum, handler in changed.items():
        if handler is not None:  # a handler not set from Python cannot be set back
            signal.signal(signum, handler)
    names = ", ".join(signal.Signals(signum).name for signum in changed)
    assert not changed, f"the test left the handler of {names} changed"


@pytest.fixture
def python_sigint() -> Any:
    """SIGINT has Python's own handler (``KeyboardInterrupt``) during the test, set back
    after it.  A process started with SIGINT ignored keeps it ignored (Python then installs
    no handler of its own), as pytest and its xdist workers do when started as a background
    job of a non-interactive shell (``bash .ci/run > log &``)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture
def default_stop_signals(python_sigint: None) -> Any:
    """The stop signals have their default handling during the test (SIGINT Python's own),
    set back after it: the child processes it starts receive them at their default (a run
    leaves a signal it inherits ignored as it is, :func:`multilayer.app.runner.handled_by`),
    also where the test run itself was started with them ignored (``&``, ``nohup``)."""
    others = [signum for signum in STOP_SIGNALS if signum != signal.SIGINT]
    previous = {signum: signal.signal(signum, signal.SIG_DFL) for signum in others}
    yield
    for signum, handler in previous.items():
        signal.signal(signum, handler)


def fault_battery() -> types.ModuleType:
    """``benchmarks/fault_battery.py``, imported once (registered under its name before it
    runs: its dataclasses look it up), for the tests that share its cases' files."""
    if "fault_battery" not in sys.modules:
        path = Path(__file__).resolve().parents[1] / "benchmarks" / "fault_battery.py"
        spec = importlib.util.spec_from_file_location("fault_battery", path)
        assert spec is not None and spec.loader is not None
        sys.modules["fault_battery"] = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(sys.modules["fault_battery"])
    return sys.modules["fault_battery"]


def _warm_up_done(worker: dict[str, Any]) -> Path:
    return Path(tempfile.gettempdir()) / f"multilayer-kernels-{worker['testrunuid']}.done"


def pytest_configure(config: pytest.Config) -> None:
    """A run without the thorough property search (the default) writes nothing where it is
    started: Hypothesis's storage (its cache of the constants of the modules it tests, made
    even with no example database) goes to a temporary directory removed at the end, not
    to ``.hypothesis/`` in the current directory; ``-m properties`` keeps its example
    database there.  Dask's scratch space goes to a temporary directory removed at the end
    too: the tests' clusters of worker threads (``LocalCluster(processes=False)``) left
    ``dask-scratch-space`` in ``TMPDIR``.  xdist's workers inherit the directories."""
    if "DASK_TEMPORARY_DIRECTORY" not in os.environ:  # read when dask is imported, after this
        scratch = tempfile.mkdtemp(prefix="multilayer-dask-")
        os.environ["DASK_TEMPORARY_DIRECTORY"] = scratch
        config.add_cleanup(lambda: shutil.rmtree(scratch, ignore_errors=True))
    if "HYPOTHESIS_STORAGE_DIRECTORY" in os.environ or "not properties" not in (config.option.markexpr or ""):
        return
    directory = tempfile.mkdtemp(prefix="multilayer-hypothesis-")
    os.environ["HYPOTHESIS_STORAGE_DIRECTORY"] = directory
    config.add_cleanup(lambda: shutil.rmtree(directory, ignore_errors=True))


def pytest_collection_finish(session: pytest.Session) -> None:
    worker = getattr(session.config, "workerinput", None)
    if not worker or worker["workercount"] < 2 or len(session.items) < WARM_UP_ITEMS:
        return
    done = _warm_up_done(worker)
    if worker["workerid"] == "gw0":
        try:
            compile_kernels(worker["workercount"])  # a failure is left to the tests to report
        finally:
            done.touch()
        return
    deadline = time.monotonic() + WARM_UP_WAIT
    while not done.exists() and time.monotonic() < deadline:
        time.sleep(0.1)


def pytest_unconfigure(config: pytest.Config) -> None:
    worker = getattr(config, "workerinput", None)
    if worker:
        _warm_up_done(worker).unlink(missing_ok=True)


TINY_SCENARIO: dict[str, Any] = {
    "name": "tiny",
    "slope_deg": 25.0,
    "domain": {"x_min": 0.0, "x_max": 0.5, "cells": 40, "layers": 3},
    "material": {"density": 1500.0, "grain_diameter": 1.0e-3},
    "rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01},
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05}],
    "boundaries": {"left": "wall", "right": "outflow"},
    "time": {"end": 0.05, "output_interval": 0.025},
}
"""A column released on a 25 degree slope: 40 cells x 3 layers, runs in about a second."""


@pytest.fixture
def tiny_scenario() -> dict[str, Any]:
    """A fresh copy of :data:`TINY_SCENARIO` to modify."""
    return copy.deepcopy(TINY_SCENARIO)


@pytest.fixture
def write_scenario(tmp_path: Path) -> Callable[..., Path]:
    """``write_scenario(data_or_text, name="scenario.yaml") -> Path`` in ``tmp_path``."""

    def write(data: dict[str, Any] | str, name: str = "scenario.yaml") -> Path:
        path = tmp_path / name
        text = data if isinstance(data, str) else yaml.safe_dump(data, sort_keys=False)
        path.write_text(text, encoding="utf-8")
        return path

    return write


@dataclass
class CliResult:
    """Exit code and captured output of one in-process CLI call."""

    code: int
    out: str
    err: str


@pytest.fixture
def cli(capsys: pytest.CaptureFixture[str]) -> Callable[..., CliResult]:
    """``cli("validate", path) -> CliResult``: :func:`multilayer.app.cli.main` in-process."""

    def run(*argv: Any) -> CliResult:
        try:
            code = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse usage errors, --help, --version
            code = exc.code
        out, err = capsys.readouterr()
        return CliResult(code, out, err)

    return run
