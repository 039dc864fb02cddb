"""Running into a directory: Ctrl-C and resume, failures, log, progress line."""

from __future__ import annotations

import io
import math
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO
from numba.core import event as numba_event

from multilayer import scenario as scenarios
from multilayer.app import compilation, resources, runner
from multilayer.app.progress import Progress
from multilayer.app.simulation import Simulation
from multilayer.engine.bed_force import FORCES
from multilayer.errors import Interrupted, RunError
from multilayer.io.results import open_result

# A column slumping down a 25 degree slope, 40 cells x 3 layers, 26 output times.
SLUMP = {**TINY_SCENARIO, "name": "slump", "time": {"end": 0.5, "output_interval": 0.02}}


def _cli(*args: object) -> list[str]:
    return [sys.executable, "-m", "multilayer", *map(str, args)]


# `multilayer run` in a child process whose time steps take at least 20 ms each, so that
# the run is still going when the test's SIGINT arrives, however fast the engine is.
_PACED_RUN = """
import sys, time
from multilayer.app.cli import main
from multilayer.app.simulation import Simulation
step = Simulation.step
def paced_step(self, t_max):
    time.sleep(0.02)
    return step(self, t_max)
Simulation.step = paced_step
sys.exit(main(sys.argv[1:]))
"""


def _records(path: Path) -> int:
    """Output times completed in a result file being written (0 if not readable yet)."""
    try:
        with netCDF4.Dataset(path) as ds:
            return int(np.isfinite(ds["time"][:].filled(np.nan)).sum())
    except (OSError, KeyError, IndexError):
        return 0


def _assert_same_result(a: Path, b: Path) -> None:
    ra, rb = open_result(a), open_result(b)
    np.testing.assert_array_equal(ra["time"], rb["time"])
    np.testing.assert_allclose(ra["h"], rb["h"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(ra["u"], rb["u"], rtol=0, atol=1e-8)
    np.testing.assert_allclose(ra["static_interface"], rb["static_interface"], atol=1e-8)
    for name in FORCES:  # the impulses of an interval cut by the interruption are checkpointed
        np.testing.assert_allclose(ra[name], rb[name], rtol=1e-9, atol=1e-9)
    assert ra.attrs["steps"] == rb.attrs["steps"]


@pytest.mark.slow  # Ctrl-C and resume run by default: tests/test_study_stop.py, test_reliability.py
def test_sigint_stops_cleanly_and_resume_gives_the_uninterrupted_answer(
    tmp_path: Path, default_stop_signals: None
) -> None:
    path = tmp_path / "slump.yaml"
    path.write_text(yaml.safe_dump(SLUMP))
    outdir = tmp_path / "interrupted"
    proc = subprocess.Popen(
        [sys.executable, "-c", _PACED_RUN, "run", str(path), "-o", str(outdir), "--set", "domain.layers=4"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.monotonic() + 120
    while _records(outdir / "result.nc") < 2 and proc.poll() is None:
        assert time.monotonic() < deadline, "no output time written"
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    command = err.split("resume with: ")[1].splitlines()[0]
    assert command == f"multilayer run {path} -o {outdir} --resume --set domain.layers=4"
    partial = open_result(outdir)
    assert partial.attrs["run_status"] == "interrupted"
    assert 2 <= partial.sizes["time"] < 26
    assert "interrupted by Ctrl-C (SIGINT) at t=" in (outdir / "run.log").read_text()

    resumed = subprocess.run(
        _cli(*shlex.split(command)[1:], "--quiet"), capture_output=True, text=True, timeout=120
    )
    assert resumed.returncode == 0, resumed.stderr
    reference = tmp_path / "reference"
    runner.run(scenarios.load(path, ["domain.layers=4"]), reference, quiet=True)
    _assert_same_result(outdir, reference)
    with netCDF4.Dataset(outdir / "result.nc") as ds:
        assert ds.run_status == "completed"
        assert ds.history.count("\n") == 1  # the run, then one resume
    assert "restored the checkpoint" in (outdir / "run.log").read_text()


def test_resume_extends_a_finished_run_to_a_later_end(tmp_path: Path) -> None:
    short = scenarios.from_dict(SLUMP, overrides=["time.end=0.04"])
    runner.run(short, tmp_path / "extended", quiet=True)
    longer = scenarios.from_dict(SLUMP, overrides=["time.end=0.08"])
    runner.run(longer, tmp_path / "extended", resume=True, quiet=True)
    runner.run(longer, tmp_path / "direct", quiet=True)
    _assert_same_result(tmp_path / "extended", tmp_path / "direct")


def test_a_run_resumed_by_another_version_says_so(tmp_path: Path, capsys) -> None:
    """A checkpoint records no version: a run resumed after an upgrade of multilayer put the
    new version's records after the old one's, under the attributes naming the old one,
    and its history said only "--resume".  Now the resume says which versions computed
    what (stderr and run.log), and the history names the version of each resume."""
    runner.run(scenarios.from_dict(SLUMP, overrides=["time.end=0.04"]), tmp_path, quiet=True)
    with netCDF4.Dataset(tmp_path / "result.nc", "a") as ds:
        ds.multilayer_commit = "0123abc"  # as an earlier version wrote it
    capsys.readouterr()
    runner.run(scenarios.from_dict(SLUMP, overrides=["time.end=0.08"]), tmp_path, resume=True, quiet=True)
    said = "result.nc: its output times so far were computed by multilayer "
    assert said in capsys.readouterr().err and said in (tmp_path / "run.log").read_text()
    assert "(commit 0123abc), the ones to come by multilayer " in (tmp_path / "run.log").read_text()
    with netCDF4.Dataset(tmp_path / "result.nc") as ds:
        assert ds.history.splitlines()[-1].split(" multilayer run --resume, by multilayer ")[1]


def test_resume_needs_a_checkpoint_of_the_same_scenario(tmp_path: Path, cli, write_scenario) -> None:
    path = write_scenario(dict(SLUMP, time={"end": 0.02, "output_interval": 0.02}))
    result = cli("run", path, "-o", tmp_path / "none", "--resume")
    assert result.code == 2
    assert "nothing to resume" in result.err and "none" in result.err
    assert cli("run", path, "-o", tmp_path / "done", "-q").code == 0
    result = cli("run", path, "-o", tmp_path / "done", "--resume", "--set", "slope_deg=30")
    assert result.code == 2
    assert "different scenario (changed: slope_deg)" in result.err
    # a shorter end would return the old run's later state as if it were the answer
    result = cli("run", path, "-o", tmp_path / "done", "--resume", "--set", "time.end=0.01")
    assert result.code == 2
    assert "beyond time.end" in result.err and "Traceback" not in result.err


@pytest.mark.parametrize(
    ("end", "kept"),
    [(0.02, None), (0.020000000000000004, 0.02), (0.02 * (1 + 0.9e-9), 0.02)],
    ids=["its own end", "one unit of round-off later", "0.9e-9 of it later"],
)
def test_a_resume_to_the_end_of_a_finished_run_says_it_is_finished(tmp_path, cli, write_scenario, end, kept):
    """``--resume`` of a finished run to its end, or to a time.end later by no more than
    the rounding of output times (1e-9 of time.end): no output time comes after the last
    record, so nothing is computed.  The run said nothing, and with the later end the
    result claimed a time.end its records do not reach: every reader then refused it.
    Now stderr and run.log say the run is finished; the result keeps its last record's
    time as its time.end and is read as it was."""
    path = write_scenario(dict(SLUMP, time={"end": 0.02, "output_interval": 0.01}))
    assert cli("run", path, "-o", tmp_path / "done", "-q").code == 0
    before = open_result(tmp_path / "done")
    result = cli("run", path, "-o", tmp_path / "done", "-q", "--resume", "--set", f"time.end={end!r}")
    assert result.code == 0, result.err
    said = (
        "the result's last record is at time.end = 0.02 s: the run is finished there"
        if kept is None
        else f"time.end = {end!r} s is the time of the result's last record, t = 0.02 s, to within the "
        "rounding of output times (1e-09 of time.end): the run is finished there and keeps time.end = 0.02 s"
    )
    assert f"{said}; nothing to compute (a later time.end extends it)" in result.err
    assert said in (tmp_path / "done" / "run.log").read_text()
    after = open_result(tmp_path / "done")  # read as every reader reads it: checked
    assert yaml.safe_load(after.attrs["scenario"])["time"]["end"] == 0.02
    np.testing.assert_array_equal(after["time"], before["time"])
    np.testing.assert_array_equal(after["h"], before["h"])
    assert after.attrs["run_status"] == "completed"


@pytest.mark.parametrize("end", [0.019999999999999997, 0.01])
def test_a_resume_to_before_the_checkpoint_is_refused_to_the_last_digit(tmp_path, cli, write_scenario, end):
    """A time.end before a finished run's end, even by one unit of round-off: the run is
    extended, never shortened.  One unit earlier was taken (within 1e-12 of it) and the
    result then claimed an end before its last record, which every reader refused; the
    message named both times as ``0.02``.  Refused, exit 2, naming time.end and the
    checkpoint's time to every digit; the result is left as it was."""
    path = write_scenario(dict(SLUMP, time={"end": 0.02, "output_interval": 0.01}))
    assert cli("run", path, "-o", tmp_path / "done", "-q").code == 0
    result = cli("run", path, "-o", tmp_path / "done", "-q", "--resume", "--set", f"time.end={end!r}")
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        f"checkpoint.npz: the checkpoint is at t = 0.02 s, beyond time.end = {end!r} s; accepted: a time.end "
        "at or after 0.02 s (a run can be extended, not shortened)"
    ) in result.err
    assert yaml.safe_load(open_result(tmp_path / "done").attrs["scenario"])["time"]["end"] == 0.02


@pytest.mark.parametrize(
    ("changes", "refused"),
    [
        (["name=renamed", "description=another text", "expect=[]"], None),
        (["numerics.tolerance=1e-9"], "numerics.tolerance"),
        (["time.output_interval=0.01"], "time.output_interval"),
        (["material.density=1600"], "material.density, material.particle_density"),
    ],
)
def test_a_checkpoint_resumes_only_the_physics_and_numerics_it_computed(
    tmp_path: Path, cli, write_scenario, changes, refused
) -> None:
    """What a checkpoint must match to be resumed: every key that enters the computed
    solution (physics, numerics, output times); the labels (``name``, ``description``,
    ``expect``, ``output``) may change, and ``time.end`` may grow.  A relabelled resume
    was silent: it is said on stderr and in ``run.log``, the result then carries the new
    labels and its records are those of the run in one go."""
    path = write_scenario(dict(SLUMP, time={"end": 0.02, "output_interval": 0.02}))
    assert cli("run", path, "-o", tmp_path / "run", "-q").code == 0
    options = [word for change in [*changes, "time.end=0.04"] for word in ("--set", change)]
    result = cli("run", path, "-o", tmp_path / "run", "--resume", "-q", *options)
    if refused:
        assert result.code == 2 and "Traceback" not in result.err
        assert f"the checkpoint belongs to a different scenario (changed: {refused}); " in result.err
        assert "(only description, expect, name, output, time.end may change)" in result.err
        return
    assert result.code == 0, result.err
    said = "resuming with description, name changed (no part of the computed solution;"
    assert said in result.err and said in (tmp_path / "run" / "run.log").read_text()
    assert cli("run", path, "-o", tmp_path / "direct", "-q", *options).code == 0
    _assert_same_result(tmp_path / "run", tmp_path / "direct")
    assert yaml.safe_load(open_result(tmp_path / "run").attrs["scenario"])["name"] == "renamed"


def test_a_result_of_another_scenario_beside_the_checkpoint_is_not_resumed(
    tmp_path: Path, cli, write_scenario
):
    """Another scenario's ``result.nc`` beside a checkpoint (copied there, or another run
    into the directory stopped after its first records): ``--resume`` continued it and
    relabelled its records with the checkpoint's scenario, ``run_status: completed``."""
    path = write_scenario(dict(SLUMP, time={"end": 0.02, "output_interval": 0.02}))
    for name, slope in (("run", "25"), ("other", "30")):
        assert cli("run", path, "-o", tmp_path / name, "-q", "--set", f"slope_deg={slope}").code == 0
    (tmp_path / "other" / "result.nc").replace(tmp_path / "run" / "result.nc")
    result = cli("run", path, "-o", tmp_path / "run", "--resume", "-q", "--set", "time.end=0.04")
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        "result.nc: holds the output times of another scenario than its checkpoint (changed: slope_deg)"
        in (result.err)
    )


def _steps_at(outdir: Path, t: str) -> int:
    """The step count at output time ``t`` (as the log prints it) of the run in ``outdir``."""
    lines = (outdir / "run.log").read_text().splitlines()
    line = next(line for line in lines if f"output t = {t} s:" in line)
    return int(line.split("step ")[1].split(",")[0])


def _assert_equal_results(a: Path, b: Path) -> None:
    """The two runs' records equal to the bit, forces included, both completed."""
    ra, rb = open_result(a, use="answer"), open_result(b, use="answer")
    for name in ("time", "h", "u", "static_interface", "mass", "front", *FORCES):
        np.testing.assert_array_equal(ra[name], rb[name], err_msg=name)
    assert ra.attrs["steps"] == rb.attrs["steps"]


@pytest.mark.parametrize("how", ["a stop", "its step bound"])
def test_a_run_stopped_as_it_reaches_an_output_time_resumes_with_that_record(
    tmp_path: Path, monkeypatch, how: str
) -> None:
    """A stop (a signal, its study) or the step bound taken by the very step that lands on an
    output time checkpoints that state before its record is written.  The resumed run
    went on to the output times after the state, so that record was never written: 10 of
    the 11 output times, ``run_status: completed``.  It now writes the output times after
    the last record kept: the uninterrupted run's records, to the bit."""
    scenario = scenarios.from_dict(SLUMP, overrides=["time.end=0.1"])
    runner.run(scenario, tmp_path / "direct", quiet=True)
    landing = _steps_at(tmp_path / "direct", "0.06")
    out = tmp_path / "stopped"
    if how == "a stop":
        step, stop = Simulation.step, [False]

        def step_then_stop(self: Simulation, t_max: float = math.inf) -> float:
            dt = step(self, t_max)
            stop[0] = self.steps == landing
            return dt

        monkeypatch.setattr(Simulation, "step", step_then_stop)
        with pytest.raises(Interrupted, match="at t=0.06 s"):
            runner.run(scenario, out, quiet=True, stop_when=lambda: stop[0])
        monkeypatch.undo()
    else:  # the estimate of the steps (twice those taken here) would refuse the bound first
        monkeypatch.setattr(resources, "check_steps", lambda scenario, budget: None)
        with pytest.raises(RunError, match=f"has taken {landing} time steps"):
            runner.run(scenario, out, quiet=True, budget=resources.Budget(steps=landing))
        monkeypatch.undo()
    runner.run(scenario, out, quiet=True, resume=True)
    _assert_equal_results(out, tmp_path / "direct")


def test_a_step_abandoned_leaves_the_normal_stress_of_the_last_step_kept(tmp_path: Path) -> None:
    """With ``model.normal_stress`` the step replaces the stresses it keeps for the next step
    (the relief of the mean pressures) before its state is kept.  A step abandoned midway
    (a stop between two kernel calls: a signal, its study) left them: the checkpoint held
    the stresses of a step that never happened, and the resumed run differed from the
    uninterrupted one by up to 4.6e-6 m of thickness.  Now the abandoned step restores
    them: the same records to the bit, wherever the stop falls."""
    scenario = scenarios.from_dict(SLUMP, overrides=["time.end=0.1", "model.normal_stress=true"])
    runner.run(scenario, tmp_path / "direct", quiet=True)
    for stop_at in (37, 61):  # polls: between the kernel calls of a step, not at its end
        polls = [0]

        def stop_when(polls: list[int] = polls, stop_at: int = stop_at) -> bool:
            polls[0] += 1
            return polls[0] >= stop_at

        out = tmp_path / f"stopped_{stop_at}"
        with pytest.raises(Interrupted):
            runner.run(scenario, out, quiet=True, stop_when=stop_when)
        runner.run(scenario, out, quiet=True, resume=True)
        _assert_equal_results(out, tmp_path / "direct")


def test_one_ctrl_c_stops_a_run_in_a_plugin_that_never_returns_and_it_resumes_to_the_bit(
    tmp_path: Path, monkeypatch, python_sigint
) -> None:
    """A rheology plugin whose method loops for ever (in Python) at its 12th call, and the
    user's Ctrl-C there: the run's handler only noted the first signal (the stop was
    honoured between kernel calls, which never came) and a second Ctrl-C stopped it at once,
    without a checkpoint.  The first now stops it in the plugin: the step is abandoned, the
    state before it checkpointed, exit 130; resumed with the plugin mended, the records are
    the uninterrupted run's, to the bit."""
    from multilayer.plugins.builtins.drucker_prager import DruckerPrager

    monkeypatch.setattr(DruckerPrager, "yield_stress_kernel", lambda self, material: None)
    scenario = scenarios.from_dict(SLUMP, overrides=["time.end=0.06"])
    runner.run(scenario, tmp_path / "direct", quiet=True)
    real, calls = DruckerPrager.yield_stress, [0]

    def hangs(self, pressure, material):
        calls[0] += 1
        if calls[0] == 12:
            os.kill(os.getpid(), signal.SIGINT)
            deadline = time.monotonic() + 20.0  # the test fails, never hangs
            while time.monotonic() < deadline:
                pass
            raise AssertionError("the first Ctrl-C did not stop the plugin")
        return real(self, pressure, material)

    monkeypatch.setattr(DruckerPrager, "yield_stress", hangs)
    out = tmp_path / "stopped"
    with pytest.raises(Interrupted, match=r"interrupted by Ctrl-C \(SIGINT\) at t=0.0\d+ s; resume with"):
        runner.run(scenario, out, quiet=True)
    assert calls[0] == 12 and open_result(out).attrs["run_status"] == "interrupted"
    monkeypatch.setattr(DruckerPrager, "yield_stress", real)
    runner.run(scenario, out, quiet=True, resume=True)
    _assert_equal_results(out, tmp_path / "direct")


def test_engine_failure_keeps_the_output_times_done(tmp_path: Path, monkeypatch) -> None:
    step = Simulation.step

    def failing_step(self: Simulation, t_max: float) -> float:
        if self.t >= 0.03:
            raise FloatingPointError("negative thickness")
        return step(self, t_max)

    monkeypatch.setattr(Simulation, "step", failing_step)
    with pytest.raises(
        RunError, match=r"failed at t=0.03.*negative thickness.*up to t=0.02 s and the last good"
    ):
        runner.run(scenarios.from_dict(SLUMP), tmp_path, quiet=True)
    partial = open_result(tmp_path)
    assert partial["time"].values[:2].tolist() == [0.0, 0.02] and partial.sizes["time"] == 3
    assert 0.03 <= float(partial["time"][2]) < 0.04  # the last good state, where the failure came
    assert partial.attrs["run_status"] == "failed" and "negative thickness" in partial.attrs["failure"]
    assert "FloatingPointError: negative thickness" in (tmp_path / "run.log").read_text()


def test_log_has_a_line_per_output_time(tmp_path: Path) -> None:
    runner.run(scenarios.from_dict(SLUMP, overrides=["time.end=0.06"]), tmp_path, quiet=True)
    log = (tmp_path / "run.log").read_text()
    assert "new run of scenario 'slump'" in log
    assert "rheology:\n  name: drucker_prager" in log
    assert [
        line.split("output t = ")[1].split(" s:")[0] for line in log.splitlines() if "output t = " in line
    ] == ["0.02", "0.04", "0.06"]
    assert "completed:" in log


def test_output_times_land_on_multiples_of_the_interval_and_the_end() -> None:
    times = runner.output_times(1.5, 0.05)
    assert times.size == 30 and times[-1] == 1.5
    np.testing.assert_allclose(np.diff(times), 0.05, atol=1e-15)
    np.testing.assert_allclose(runner.output_times(1.0, 0.3), [0.3, 0.6, 0.9, 1.0])
    np.testing.assert_array_equal(runner.output_times(1.0, 2.0), [1.0])


@pytest.mark.parametrize(
    ("end", "interval"),
    [(0.3, 0.1), (1e-7 * 3, 1e-7), (0.30000000009, 0.1), (3.0000000000000004e-07, 1e-07),
     (1.0000000000000002, 0.1), (2.5000000000025002, 0.5), (0.1 * 3 * (1 + 2e-9), 0.1), (5.0, 1 / 7)],
)  # fmt: skip
def test_the_last_output_time_is_time_end_exactly(end: float, interval: float) -> None:
    """``time.end / time.output_interval`` within 1e-9 above a whole number n: the n-th
    multiple was the last output time, one rounding unit (or up to 1e-9 interval) before
    ``time.end``.  The times are the documented ones: the multiples more than 1e-9 interval
    before the end, then ``time.end`` exactly, as many as the resource estimate counts
    (app/resources.py)."""
    times = runner.output_times(end, interval)
    assert times[-1] == end
    k = np.arange(1, times.size)
    np.testing.assert_array_equal(times[:-1], k * interval)
    assert np.all(np.diff(times) > 1e-9 * interval)
    assert times.size == math.ceil(end / interval - 1e-9)


class _Sim:
    t, steps = 0.0, 0


def test_progress_line_reports_rate_and_time_left() -> None:
    stream = io.StringIO()
    progress = Progress(t_end=2.0, cells=120, quiet=False, stream=stream)
    sim = _Sim()
    sim.t, sim.steps = 0.1, 1
    progress(sim, 0.1)  # the first step sets the origin: t = 0, step 0
    wall0 = progress._start[0]
    line = progress.line(t=0.5, dt=0.01, steps=41, now=wall0 + 2.0)
    # 120 cells x 41 steps in 2 s; 1.5 s simulated left at 0.25 simulated s per s
    assert line == "t = 0.5 / 2 s   dt = 0.01 s   2,460 cell-steps/s   6s left"
    progress.finish()
    assert stream.getvalue().startswith("\rt = 0.1 / 2 s") and stream.getvalue()[-1] == "\n"


def test_progress_is_silent_off_a_terminal_or_when_quiet() -> None:
    stream = io.StringIO()  # not a terminal
    for quiet in (None, True):
        progress = Progress(t_end=1.0, cells=10, quiet=quiet, stream=stream)
        progress(_Sim(), 0.1)
        progress.finish()
    assert stream.getvalue() == ""


class _GoneReader(io.StringIO):
    """stderr piped to a reader that went away (``... 2>&1 | head -1``)."""

    def write(self, text: str) -> int:
        raise BrokenPipeError(32, "Broken pipe")


@pytest.mark.parametrize("stderr", [None, _GoneReader()], ids=["none", "broken pipe"])
def test_a_progress_line_with_nowhere_to_go_does_not_stop_the_run(tmp_path, monkeypatch, stderr) -> None:
    """``quiet=False`` where ``sys.stderr`` is None (pythonw) or a pipe whose reader is
    gone: the progress line's write failed the run at its first step ('the simulation
    failed at t=0.00844 s (step 1): 'NoneType' object has no attribute 'write'')."""
    monkeypatch.setattr(sys, "stderr", stderr)
    runner.run(scenarios.from_dict(TINY_SCENARIO), tmp_path, quiet=False)
    assert open_result(tmp_path).attrs["run_status"] == "completed"


def test_a_run_that_compiles_kernels_says_so_once_and_logs_the_time(tmp_path, monkeypatch, capsys):
    """The first run after installing spends its first step compiling (about 45 s): the
    terminal and run.log say so when the first compilation starts, run.log how long it
    took.  Here two kernels (one calling another) are compiled during the first step."""
    step = Simulation.step

    def compiling_step(self, t_max):
        if self.steps == 0:
            for _ in range(2):
                with numba_event.trigger_event("numba:compile", data={}):
                    with numba_event.trigger_event("numba:compile", data={}):  # a callee
                        pass
        return step(self, t_max)

    monkeypatch.setattr(Simulation, "step", compiling_step)
    runner.run(scenarios.from_dict(TINY_SCENARIO), tmp_path / "first", quiet=False)
    err = capsys.readouterr().err
    assert err.count("compiling the numba kernels") == 1
    # stderr is not a terminal here (captured): the default says it as a plain line, -q does not
    runner.run(scenarios.from_dict(TINY_SCENARIO), tmp_path / "plain", quiet=None)
    assert capsys.readouterr().err == f"multilayer: {compilation.NOTICE}\n"
    runner.run(scenarios.from_dict(TINY_SCENARIO), tmp_path / "quiet", quiet=True)
    assert capsys.readouterr().err == ""
    assert "compiling the numba kernels" in (tmp_path / "quiet" / "run.log").read_text()
    log = (tmp_path / "first" / "run.log").read_text()
    assert log.count("compiling the numba kernels") == 1
    assert "numba compiled kernels for " in log

    monkeypatch.setattr(Simulation, "step", step)  # kernels cached: not a word
    runner.run(scenarios.from_dict(TINY_SCENARIO), tmp_path / "next", quiet=False)
    assert "numba" not in capsys.readouterr().err
    assert "numba" not in (tmp_path / "next" / "run.log").read_text()


def test_the_compilation_time_counts_the_outermost_compilations_only(monkeypatch):
    """numba nests the compilation of a callee inside its caller's: it is timed once, as
    part of the caller's (the clock is read at the start and end of outermost ones only)."""
    clock = iter([0.0, 3.0, 10.0, 12.0])
    monkeypatch.setattr(compilation.time, "perf_counter", lambda: next(clock))
    firsts = []
    compilations = compilation._Compilations(lambda: firsts.append(True))
    for nested in (1, 0):
        compilations.on_start(None)
        for _ in range(nested):
            compilations.on_start(None)
            compilations.on_end(None)
        compilations.on_end(None)
    assert compilations.seconds == 5.0 and firsts == [True]
    other = threading.Thread(target=compilations.on_start, args=(None,))  # another run's thread
    other.start()
    other.join()
    assert compilations.depth == 0 and compilations.seconds == 5.0


@pytest.mark.parametrize("what", ["the directory removed", "the directory read-only", "result.nc removed"])
def test_an_output_directory_lost_during_the_run_is_a_write_error_naming_the_path(
    tmp_path, write_scenario, cli, monkeypatch, what
):
    """The output directory removed (or made read-only, or its result.nc removed) after the
    third output time: the run stops naming the file it could not write and what is kept. It
    said "the simulation failed at t=0.04 s: [Errno 2] ..." (blaming the simulation), exit 2
    "dd/run.lock: Permission denied" (the lock's removal hid how the run ended), or exit 2
    "dd/result.nc: No such file or directory" after a run written into a file gone."""
    import shutil

    from multilayer.io import results

    out = tmp_path / "out"
    write = results.ResultWriter.write

    def write_then_lose(self, sim):
        diag = write(self, sim)
        if self.records == 3:
            if what == "the directory removed":
                shutil.rmtree(out)
            elif what == "result.nc removed":
                self.path.unlink()
            else:  # a read-only directory refuses the checkpoint and the lock's removal (root ignores modes)
                monkeypatch.setattr(results.os, "replace", refused)
                monkeypatch.setattr(Path, "unlink", lambda path, missing_ok=False: refused())
        return diag

    def refused(*args):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(results.ResultWriter, "write", write_then_lose)
    scenario = write_scenario({**TINY_SCENARIO, "time": {"end": 0.1, "output_interval": 0.02}})
    result = cli("run", scenario, "-o", out, "-q")
    assert result.code == 1, result.err
    said = {
        "the directory removed": f"writing the checkpoint {out}/checkpoint.npz failed (No such file or "
        f"directory); the run stopped at t=0.04 s (step 6); the output directory {out} is gone (removed or "
        "moved during the run), and the files written there with it",
        "the directory read-only": f"writing the checkpoint {out}/checkpoint.npz failed (Permission denied); "
        f"the run stopped at t=0.04 s (step 6); {out}/result.nc keeps the 3 output times written before and "
        f"checkpoint.npz the state at t=0.02 s; once {out} can be written again, continue with:",
        "result.nc removed": f"{out}/result.nc was removed, moved or replaced during the run, with the "
        "output times written into it; the run stopped at t=0.06 s (step 9); run again (the state at t=0.04",
    }[what]
    assert said in result.err and "Traceback" not in result.err


def test_a_run_writes_its_resolved_scenario_once(tmp_path: Path, monkeypatch) -> None:
    """The resolved scenario goes into the estimate of the result, the log, the result's
    header and close, and every checkpoint: it was written four times (``text_size`` for
    the estimate, the run, the header, close), 50 MB of YAML for a bed of 450 000 points
    inline.  Now once, and its size is that text's."""
    from multilayer.scenario import schema

    written: list[int] = []
    dump = schema.dump
    monkeypatch.setattr(schema, "dump", lambda data: written.append(1) or dump(data))
    monkeypatch.setattr(runner, "compile_ahead", lambda scenario: None)  # its own small scenario
    runner.run(scenarios.from_dict(SLUMP, overrides=["time.end=0.04"]), tmp_path, quiet=True)
    assert len(written) == 1
    with netCDF4.Dataset(tmp_path / "result.nc") as ds:
        assert ds.scenario == scenarios.from_dict(SLUMP, overrides=["time.end=0.04"]).resolved_yaml()
