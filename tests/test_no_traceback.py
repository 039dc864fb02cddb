"""Inputs that reached a traceback or a misleading message (docs/reliability.md): each is
now exit 2 (or the signal's code) with one message naming what is wrong."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import threading
import time

import netCDF4
import pytest
import yaml
from conftest import TINY_SCENARIO

from multilayer.app import lock


@pytest.mark.parametrize("pid", ["abc", None, 1e30, 10**30, 0, -1, True, [1]])
def test_a_malformed_lock_is_taken_over_as_unreadable(tmp_path, cli, write_scenario, pid):
    """0 and -1 would make os.kill test a process group or every process (always alive)."""
    outdir = tmp_path / "out"
    outdir.mkdir()
    holder = {"pid": pid, "host": socket.gethostname(), "started": "2026-01-01T00:00:00+00:00"}
    (outdir / lock.LOCK_FILE).write_text(json.dumps(holder))
    run = cli("run", write_scenario(TINY_SCENARIO), "-o", outdir, "-q")
    assert run.code == 0, run.err
    assert "taking over a stale lock (an unreadable lock: no such process)" in run.err
    assert not (outdir / lock.LOCK_FILE).exists()


def test_a_lock_that_is_a_named_pipe_is_taken_over_not_waited_on(tmp_path, cli, write_scenario):
    """``out/run.lock`` a named pipe: reading its holder waited for ever for a writer."""
    outdir = tmp_path / "out"
    outdir.mkdir()
    os.mkfifo(outdir / lock.LOCK_FILE)
    read: list[object] = []
    reader = threading.Thread(target=lambda: read.append(lock._holder(outdir / lock.LOCK_FILE)), daemon=True)
    reader.start()
    reader.join(10)
    assert read == [None], "reading a lock that is a named pipe waited for a writer"
    run = cli("run", write_scenario(TINY_SCENARIO), "-o", outdir, "-q")
    assert run.code == 0, run.err
    assert "taking over a stale lock (an unreadable lock: no such process)" in run.err
    assert not (outdir / lock.LOCK_FILE).exists()


def test_a_lock_that_is_a_directory_is_named(tmp_path, cli, write_scenario):
    outdir = tmp_path / "out"
    (outdir / lock.LOCK_FILE).mkdir(parents=True)
    run = cli("run", write_scenario(TINY_SCENARIO), "-o", outdir, "-q")
    assert run.code == 2 and "Traceback" not in run.err
    assert f"{outdir / lock.LOCK_FILE}: a stale lock that cannot be removed" in run.err


def test_unicode_digits_are_not_indices_nor_thread_counts(tmp_path, cli, write_scenario, monkeypatch):
    path = write_scenario(TINY_SCENARIO)
    result = cli("validate", path, "--set", "initial.².height=0.1")
    assert result.code == 2 and "--set initial.².height: initial has 1 entries; accepted indices: 0..0" in (
        result.err
    )
    monkeypatch.setenv("MULTILAYER_THREADS", "²")
    run = cli("run", path, "-o", tmp_path / "out", "-q")
    assert run.code == 2 and "MULTILAYER_THREADS='²'; accepted: 'auto' or an integer >= 1" in run.err


def test_counts_of_5000_digits_or_in_other_notations_are_refused_naming_the_variable_or_option(
    tmp_path, cli, write_scenario, monkeypatch
):
    """``int`` of 5000 digits raises ``ValueError`` (Python's 4300-digit limit): a traceback
    of ``run`` under ``MULTILAYER_THREADS`` or ``NUMBA_NUM_THREADS`` of them; ``--times 1_0``
    was 10, an Arabic-Indic 3 was 3 and ``--at 0_1`` was 1 m."""
    path, many = write_scenario(TINY_SCENARIO), "1" * 5000
    for variable, accepted in (
        ("MULTILAYER_THREADS", "'auto' or an integer >= 1 (ASCII digits, at most 18)"),
        ("NUMBA_NUM_THREADS", "an integer >= 1 (ASCII digits, at most 18), or unset"),
    ):
        monkeypatch.setenv(variable, many)
        run = cli("run", path, "-o", tmp_path / "out", "-q")
        assert run.code == 2 and "Traceback" not in run.err
        assert f"environment variable {variable}='{many[:60]}'; accepted: {accepted}" in run.err
        monkeypatch.delenv(variable)
    for option, value in (("--max-steps", many), ("--max-steps", "\u0663"), ("--max-steps", "1_0")):
        result = cli("validate", path, option, value)
        assert result.code == 2 and "expected an integer >= 1 (ASCII digits, at most 18), got" in result.err
        assert len(result.err.splitlines()[-1]) < 200
    result = cli("plot", tmp_path, "--at", "0_1")
    assert result.code == 2 and "--at: expected a number in ASCII decimal notation" in result.err


def test_undecodable_bytes_in_the_environment_and_in_names(tmp_path, cli, monkeypatch):
    """Bytes that are not UTF-8 (kept by Python as lone surrogates) in MULTILAYER_INSTITUTION
    and in the scenario's file name are written as U+FFFD; an output directory named by such
    bytes is refused (netCDF cannot name the file)."""
    path = tmp_path / os.fsdecode(b"sc\xff.yaml")
    path.write_text(yaml.safe_dump(TINY_SCENARIO))
    monkeypatch.setenv("MULTILAYER_INSTITUTION", os.fsdecode(b"Uni\xff\xfe"))
    run = cli("run", path, "-o", tmp_path / "out", "-q")
    assert run.code == 0, run.err
    with netCDF4.Dataset(tmp_path / "out" / "result.nc") as ds:
        assert ds.institution == "Uni\ufffd\ufffd" and "sc\ufffd.yaml" in ds.history
    refused = cli("run", path, "-o", tmp_path / os.fsdecode(b"o\xff"))
    assert refused.code == 2 and "is not a UTF-8 name" in refused.err and "Traceback" not in refused.err


@pytest.mark.parametrize("outdir", ["/proc/x", "/dev/null/x"])
def test_an_output_directory_that_cannot_be_made_is_blamed(tmp_path, cli, write_scenario, outdir):
    run = cli("run", write_scenario(TINY_SCENARIO), "-o", outdir)
    assert run.code == 2 and "Traceback" not in run.err
    assert f"{outdir}: cannot be created or written" in run.err and "(-o DIR or output.directory)" in run.err
    assert "time.output_interval" not in run.err


SLOW_START = """
import sys, time, pathlib
from multilayer.app.cli import main
from multilayer.engine import simulation
real = simulation.Simulation.__init__
def slow(self, *args, **kwargs):
    pathlib.Path(sys.argv[-2]).joinpath("building").touch()  # the lock is held
    time.sleep(30)
    real(self, *args, **kwargs)
simulation.Simulation.__init__ = slow
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow  # a child process; the fault battery tries it too
def test_a_run_stopped_during_start_up_says_so_and_leaves_no_lock(tmp_path, default_stop_signals):
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(TINY_SCENARIO))
    outdir = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_START, "run", str(path), "-o", str(outdir), "-q"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while not (outdir / "building").exists() and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 143, err
    assert "Traceback" not in err
    assert "stopped by SIGTERM during start-up, before the first step: nothing was computed" in err
    assert not (outdir / lock.LOCK_FILE).exists() and not (outdir / "result.nc").exists()


@pytest.mark.slow  # a child process; the fault battery tries it too
def test_a_closed_stdout_ends_the_command_quietly(tmp_path, write_scenario):
    path = write_scenario(TINY_SCENARIO)
    reader = subprocess.Popen(["head", "-c", "0"], stdin=subprocess.PIPE)
    done = subprocess.run(
        [sys.executable, "-m", "multilayer", "validate", *[str(path)] * 50],
        stdout=reader.stdin,
        stderr=subprocess.PIPE,
        text=True,
        timeout=300,
    )
    reader.stdin.close()
    reader.wait()
    assert done.returncode in (0, 141) and "Traceback" not in done.stderr and "Exception" not in done.stderr


@pytest.mark.parametrize(
    ("variable", "value", "accepted"),
    [
        (
            "NUMBA_NUM_THREADS",
            "0",
            "an integer >= 1 (ASCII digits, at most 18), or unset",
        ),  # numba: ValueError at import
        ("NUMBA_NUM_THREADS", "two", "an integer >= 1"),  # numba: a warning quoting a traceback
        ("NUMBA_DISABLE_JIT", "1", "0 or unset: the engine's kernels need numba's compiler"),
        (
            "NUMBA_THREADING_LAYER",
            "bogus",
            "default, safe, forksafe, threadsafe, tbb, omp, workqueue, or unset",
        ),
    ],
)
def test_numba_variables_the_engine_cannot_run_with_are_refused_first(
    tmp_path, cli, write_scenario, monkeypatch, variable, value, accepted
):
    """numba reads its environment once, at its import: ``NUMBA_NUM_THREADS=0`` was a
    traceback there, ``NUMBA_DISABLE_JIT=1`` an AttributeError in the engine's cache, an
    unknown threading layer a failure in the first parallel kernel, mid-run (exit 1)."""
    monkeypatch.setenv(variable, value)
    scenario = write_scenario(TINY_SCENARIO)
    for argv in (("validate", scenario), ("run", scenario, "-o", tmp_path / "out", "-q")):
        result = cli(*argv)
        assert result.code == 2 and "Traceback" not in result.err
        assert (
            f"multilayer: error: environment variable {variable}={value!r}; accepted: {accepted}"
            in result.err
        )
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("text", "phrase"),
    [
        ("disable_jit: 1\n", "(numba's configuration file): disable_jit: '1'; accepted: 0 or unset"),
        ("num_threads: 0\n", "(numba's configuration file): num_threads: '0'; accepted: an integer >= 1"),
        ("a: [\n", "(numba's configuration file, read by numba at its import): while parsing a flow node"),
        (
            "- 1\n",
            "(numba's configuration file, read by numba at its import): got [1]; accepted: a YAML mapping",
        ),
        (  # a ValueError of PyYAML's constructor: a traceback
            "num_threads: !!int abc\n",
            "(numba's configuration file, read by numba at its import): tag:yaml.org,2002:int cannot read",
        ),
    ],
)
def test_numbas_configuration_file_in_the_working_directory_is_checked_as_its_variables(
    tmp_path, cli, write_scenario, monkeypatch, text, phrase
):
    """numba reads ``.numba_config.yaml`` in the working directory at its import, under its
    environment: ``disable_jit: 1``, ``num_threads: 0``, malformed YAML or a list there were
    tracebacks of numba's import (exit 1)."""
    scenario = write_scenario(TINY_SCENARIO)
    monkeypatch.chdir(tmp_path)
    (tmp_path / ".numba_config.yaml").write_text(text)
    result = cli("validate", scenario)
    assert result.code == 2 and "Traceback" not in result.err
    assert f"multilayer: error: {tmp_path / '.numba_config.yaml'} {phrase}" in result.err, result.err
    monkeypatch.setenv("NUMBA_DISABLE_JIT", "0")  # the environment wins over the file
    assert cli("validate", scenario).code == (0 if text == "disable_jit: 1\n" else 2)


LIBRARY_IMPORT = """
import sys
import multilayer
for what in ("multilayer.Simulation", "multilayer.run(sys.argv[1], quiet=True)", "multilayer.Simulation"):
    try:
        eval(what)
        print("imported")
    except multilayer.errors.InputError as error:
        print(type(error.__cause__).__name__, error)
"""


@pytest.mark.parametrize(
    ("variable", "value", "cause", "accepted"),
    [
        ("NUMBA_NUM_THREADS", "0", "ValueError", "an integer >= 1 (ASCII digits, at most 18), or unset"),
        pytest.param(
            "NUMBA_DISABLE_JIT",
            "1",
            "AttributeError",
            "0 or unset: the engine's kernels need numba's compiler",
            marks=pytest.mark.slow,  # 2 s of CPU importing the engine
        ),
    ],
)
def test_a_numba_variable_numbas_import_fails_on_is_named_by_the_library(
    write_scenario, variable, value, cause, accepted
):
    """Set before ``import multilayer`` in Python, no command line checks them:
    ``NUMBA_NUM_THREADS=0`` was numba's own ValueError from deep inside its import (where
    the engine is first imported: ``multilayer.Simulation``, ``multilayer.run``), and
    ``NUMBA_DISABLE_JIT=1`` an AttributeError of the engine's cache.  The library cannot
    change numba's import; where it fails, an ``InputError`` names the variable, from
    numba's exception, every time it is tried.  ``import multilayer`` alone imports no
    numba and succeeds."""
    env = {**os.environ, variable: value}
    child = subprocess.run(
        [sys.executable, "-c", LIBRARY_IMPORT, str(write_scenario(TINY_SCENARIO))],
        env=env, capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    named = f"{cause} environment variable {variable}={value!r}; accepted: {accepted}"
    assert child.stdout.splitlines() == [named] * 3, child.stderr


def test_an_unknown_threading_layer_set_in_python_is_named_before_the_run(
    tmp_path, monkeypatch, write_scenario
):
    """numba reads ``NUMBA_THREADING_LAYER`` at its first parallel kernel (not at its
    import): set in Python, where no command checks it, an unknown layer was numba's own
    ``ValueError`` at the first step on two threads.  ``multilayer.Simulation`` and
    ``multilayer.run`` name it before anything is built or written."""
    import multilayer

    monkeypatch.setenv("NUMBA_THREADING_LAYER", "x")
    monkeypatch.setenv("MULTILAYER_THREADS", "2")
    scenario = multilayer.load(write_scenario(TINY_SCENARIO))
    named = "environment variable NUMBA_THREADING_LAYER='x'; accepted: default, safe, forksafe"
    with pytest.raises(multilayer.errors.InputError, match=named):
        multilayer.Simulation(scenario)
    with pytest.raises(multilayer.errors.InputError, match=named):
        multilayer.run(scenario, tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_a_warning_that_quotes_a_traceback_is_printed_without_it(capsys):
    """numba warns about a variable it cannot read (``NUMBA_OPT=x``, then ignored) quoting
    the traceback of its parse: the command line prints the first and the last line."""
    from multilayer.app import cli

    quoted = (
        "Environment variable 'NUMBA_OPT' is defined but its associated value 'x' could not be parsed.\n"
        'The parse failed with exception:\nTraceback (most recent call last):\n  File "config.py"\n'
        "ValueError: unsupported value 'x'"
    )
    cli._warning(RuntimeWarning(quoted), RuntimeWarning, "config.py", 1)
    assert capsys.readouterr().err == (
        "multilayer: warning: Environment variable 'NUMBA_OPT' is defined but its associated value 'x' could "
        "not be parsed. (ValueError: unsupported value 'x')\n"
    )


def test_a_message_reaches_the_process_stderr_after_sys_stderr_was_set_to_none(monkeypatch, capfd) -> None:
    """A third-party law setting ``sys.stderr`` to None before failing: the run's message
    went nowhere (exit 1, nothing said); it goes to the process's own stderr."""
    from multilayer.errors import to_stderr

    monkeypatch.setattr(sys, "stderr", None)
    to_stderr("multilayer: said")
    assert "multilayer: said" in capfd.readouterr().err
