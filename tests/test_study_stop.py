"""Stopping an ensemble study (sweep, calibrate, sensitivity) with one Ctrl-C or SIGTERM
(multilayer/app/stopping.py, docs/calibration.md): the command stops within seconds,
cancels the members not finished, writes what was computed, prints the resume command,
exits with 128 + the signal number, and the resume command completes the study reusing
every finished run.

The time bounds are generous (the machine is shared): a member stops within
``STOP_FILE_POLL`` seconds and the workers within ``CLOSE_GRACE``, 2.5-3.3 s in all
measured from the signal to the exit on two loaded cores.
"""

from __future__ import annotations

import os
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from multilayer.app import calibration, cli
from multilayer.errors import Interrupted

ROOT = Path(__file__).resolve().parents[1]
TWIN = ROOT / "studies" / "twin"
STOP_WITHIN = 10.0
"""Seconds allowed from the signal to the exit (about one expected)."""


def _signal_when(condition, signum: int, timeout: float = 120.0) -> threading.Thread:
    """Send ``signum`` to this process once ``condition()`` holds (from a thread)."""

    def watch() -> None:
        end = time.monotonic() + timeout
        while not condition() and time.monotonic() < end:
            time.sleep(0.05)
        os.kill(os.getpid(), signum)

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


@pytest.fixture(scope="module")
def threads_cluster():
    """A Dask cluster of two worker threads in this process."""
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0") as local:
        yield local.scheduler_address


@pytest.mark.slow
def test_ctrl_c_stops_a_calibration_which_keeps_its_results_and_resumes(
    tmp_path, threads_cluster, capsys, default_stop_signals
):
    """SIGINT during the second generation of the twin calibration, on a cluster of worker
    threads: exit 130 promptly, calibration.nc holds the first generation (written after it)
    and says where it stopped, the message gives the resume command, and that command
    completes the calibration reusing the runs done before the stop."""
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    for name in ("front.csv", "deposit.csv"):
        shutil.copy(TWIN / name, tmp_path)
    text = (TWIN / "calibration.yaml").read_text()
    text = text.replace("generations: 2", "generations: 1").replace("evaluations: 8", "evaluations: 0")
    (tmp_path / "c.yaml").write_text(text)
    outdir = tmp_path / "out"
    result = outdir / calibration.CALIBRATION_FILE
    argv = ["calibrate", str(tmp_path / "c.yaml"), "-o", str(outdir), "--scheduler", threads_cluster]

    _signal_when(result.is_file, signal.SIGINT)
    code = cli.main(argv)
    err = capsys.readouterr().err
    assert code == 130, err
    assert "interrupted by Ctrl-C (SIGINT) in search 1" in err, err
    assert err.splitlines()[-1].startswith("multilayer: resume with: "), err  # said once
    resume = err.split("resume with: ", 1)[1].splitlines()[0]
    assert shlex.split(resume) == ["multilayer", *argv[:4], "--resume", *argv[4:]], resume
    partial = xr.load_dataset(result)
    assert partial.attrs["progress"] == "interrupted in search 1"
    first = partial["stage"].values == "search"
    assert (partial["step"].values[first] == 0).sum() == 8  # the first generation, whole
    assert np.isfinite(partial["best"].values).all()
    assert not list(outdir.glob("members/*/run.lock"))  # every member stopped (threads are not killed)

    code = cli.main(shlex.split(resume)[1:])
    assert code == 0, capsys.readouterr().err
    final = xr.load_dataset(result)
    assert final.attrs["progress"] == "complete"
    assert final.attrs["reused_runs"] >= 8
    n = partial.sizes["candidate"]
    np.testing.assert_array_equal(final["values"].values[:8], partial["values"].values[:8])
    assert final.sizes["candidate"] > n and np.isfinite(final["sd"].values).all()


def test_resume_without_results_exits_2(tmp_path, capsys):
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    for name in ("front.csv", "deposit.csv", "calibration.yaml"):
        shutil.copy(TWIN / name, tmp_path)
    assert (
        cli.main(["calibrate", str(tmp_path / "calibration.yaml"), "-o", str(tmp_path / "o"), "--resume"])
        == 2
    )
    assert "nothing to resume (calibration.nc missing)" in capsys.readouterr().err


def _study_files(tmp_path: Path) -> None:
    """A sweep and a sensitivity study of a collapse whose members run for seconds."""
    text = (TWIN / "collapse.yaml").read_text()
    text = text.replace("cells: 20", "cells: 80").replace("end: 0.3", "end: 3.0")
    (tmp_path / "collapse.yaml").write_text(text)
    (tmp_path / "sweep.yaml").write_text(
        "base: collapse.yaml\nparameters:\n  rheology.mu_s: [0.40, 0.42, 0.44, 0.46, 0.48, 0.50]\n"
    )
    (tmp_path / "sobol.yaml").write_text(
        "base: collapse.yaml\nparameters:\n  initial.0.height: {bounds: [0.04, 0.06]}\n"
        "outputs: [runout]\nsamples: 8\n"
    )


def _interrupt(argv: list[str], cwd: Path, signum: int, group: bool) -> tuple[int, str, float]:
    """Run ``multilayer ARGV`` in a new session, send ``signum`` (to the whole process group,
    as a terminal's Ctrl-C, if ``group``) once a member has written its first output time
    after the initial state (it is stepping); return the exit code, stderr and the seconds
    from the signal to the exit."""
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    process = subprocess.Popen(
        [sys.executable, "-m", "multilayer.app.cli", *argv],
        cwd=cwd,
        env=env,
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    end = time.monotonic() + 300
    while process.poll() is None and time.monotonic() < end:
        if any("output t = " in log.read_text() for log in cwd.glob("out/**/run.log")):
            break
        time.sleep(0.05)
    sent = time.monotonic()
    (os.killpg if group else os.kill)(process.pid, signum)
    try:
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
    return process.returncode, err, time.monotonic() - sent


@pytest.mark.slow
@pytest.mark.parametrize(
    ("command", "signum", "group", "code"),
    [("sweep", signal.SIGINT, True, 130), ("sensitivity", signal.SIGTERM, False, 143)],
)
def test_one_signal_stops_a_study_on_a_local_process_cluster(
    tmp_path, command, signum, group, code, default_stop_signals
):
    """``multilayer sweep`` with Ctrl-C sent to its whole process group (as a terminal does:
    the workers receive it too) and ``multilayer sensitivity`` with SIGTERM sent to the
    main process, each on a local cluster of two worker processes: stopped within seconds,
    exit code 128 + the signal, partial results written, and the printed resume command
    completes the study."""
    _study_files(tmp_path)
    config = "sweep.yaml" if command == "sweep" else "sobol.yaml"
    rc, err, seconds = _interrupt([command, config, "-o", "out", "--workers", "2"], tmp_path, signum, group)
    assert rc == code, err
    assert seconds < STOP_WITHIN, (seconds, err)
    assert "Traceback" not in err, err
    assert err.splitlines()[-1].startswith("multilayer: resume with: "), err  # said once
    resume = err.split("resume with: ", 1)[1].splitlines()[0]
    assert resume == f"multilayer {command} {config} -o out --resume --workers 2"
    if command == "sweep":
        rows = (tmp_path / "out" / "summary.csv").read_text().splitlines()[1:]
        assert len(rows) == 6 and any(",interrupted," in row for row in rows)
    else:
        ds = xr.load_dataset(tmp_path / "out" / "sensitivity.nc")
        assert "not run" in ds["status"].values and ds.attrs["runs_not_done"] > 0
    # the member that was stepping checkpointed and stopped (a worker still loading the
    # compiled kernels for its first step does not look for the stop file: it is killed
    # with its worker after CLOSE_GRACE, leaving a stale lock the resume takes over)
    stopped = [
        log.parent for log in tmp_path.glob("out/**/run.log") if "stop of its study" in log.read_text()
    ]
    assert stopped and not any((member / "run.lock").exists() for member in stopped)

    done = subprocess.run(
        [sys.executable, "-m", "multilayer.app.cli", *shlex.split(resume)[1:]],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    if command == "sweep":
        rows = (tmp_path / "out" / "summary.csv").read_text().splitlines()[1:]
        assert all(",ok," in row for row in rows)
    else:
        ds = xr.load_dataset(tmp_path / "out" / "sensitivity.nc")
        assert (ds["status"].values == "ok").all() and np.isfinite(ds["ST"].values).all()


def test_a_local_workers_heartbeat_to_a_closed_scheduler_is_one_line_not_a_traceback():
    """A stopped study closes its local cluster's scheduler (in the study's process) while
    the workers may still beat: the worker logged the connection's traceback on the
    terminal.  The preload of the local cluster's workers (``stopping.dask_setup``) keeps
    the line and drops the traceback; other records keep theirs."""
    import io
    import logging

    from multilayer.app import stopping

    logger = logging.getLogger("distributed.worker")
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    logger.addHandler(handler)
    filters = list(logger.filters)
    handlers = {signum: signal.getsignal(signum) for signum in (signal.SIGINT, signal.SIGHUP)}
    try:
        stopping.dask_setup(None)  # as in a worker process: it ignores SIGINT and SIGHUP too
        for message in ("Failed to communicate with scheduler during heartbeat.", "another failure"):
            try:
                raise OSError("Timed out trying to connect")
            except OSError:
                logger.exception(message)
    finally:
        logger.removeHandler(handler)
        logger.filters[:] = filters
        for signum, previous in handlers.items():
            signal.signal(signum, previous)
    lines = stream.getvalue().splitlines()
    assert lines[0] == "Failed to communicate with scheduler during heartbeat."
    assert lines[1] == "another failure" and "Traceback (most recent call last):" in lines[2:]


@pytest.mark.parametrize(
    ("stop", "said"),
    [
        (Interrupted("interrupted by Ctrl-C (SIGINT)", said=True), ""),
        (Interrupted("stopped by SIGTERM", 15), "multilayer: stopped by SIGTERM\n"),
        (KeyboardInterrupt(), "multilayer: interrupted\n"),
    ],
)
def test_a_stop_is_said_once(stop, said, capsys):
    """A stopped run or study prints how it stopped, what it kept and how to resume; the
    command line then printed ``multilayer: interrupted`` after it.  It prints a stop only
    where nothing said it, with its cause."""
    import argparse

    def handler(args):
        raise stop

    code = cli._dispatch(argparse.Namespace(handler=handler))
    assert code == getattr(stop, "exit_code", 130) and capsys.readouterr().err == said


def test_closing_a_stopped_local_cluster_sets_the_distributed_loggers_level_back():
    """``close_quickly`` quietens the ``distributed`` logger while the workers say goodbye:
    a library must not leave its host's logging changed (a notebook's study stopped, then
    its own cluster's warnings were hidden)."""
    import logging

    from multilayer.app import stopping

    class Cluster:
        workers: dict = {}
        level = None

        def close(self):
            Cluster.level = logging.getLogger("distributed").level

    logger = logging.getLogger("distributed")
    before = logger.level
    logger.setLevel(logging.DEBUG)
    try:
        stopping.close_quickly(Cluster())
        assert Cluster.level == logging.ERROR and logger.level == logging.DEBUG
    finally:
        logger.setLevel(before)


def test_members_whose_lock_outlives_the_stop_are_named(tmp_path, monkeypatch):
    """A member on a worker thread in a plugin's code that never returns is not stopped
    (Dask cannot stop a thread): the study named none and said that those stopped mid-run
    continue from their checkpoints.  It names the members whose lock, taken since the
    study began, is still held after the grace; a lock released meanwhile or older than
    the study (stale, of an earlier run) is not named."""
    from multilayer.app import stopping

    monkeypatch.setattr(stopping, "STOP_GRACE", 0.3)
    since = time.time() - 1.0
    for name in ("m000", "m001", "m002"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "run.lock").write_text("{}")
    os.utime(tmp_path / "m002" / "run.lock", (since - 60, since - 60))
    releasing = threading.Timer(0.1, (tmp_path / "m001" / "run.lock").unlink)
    releasing.start()
    assert stopping.still_running(tmp_path, since) == ["m000"]
    releasing.join()
