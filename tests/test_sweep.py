"""Parameter sweeps on Dask (docs/sweeps.md): sweep files, member expansion, runs on a
real scheduler with two workers, failures, resume.

The base scenario is a 5 cm x 20 cm granular column collapsing down a 25 degree slope
(40 cells, 3 layers, 0.2 s; about a second per member).  The flow stays far from the
outflow boundary, so every member must conserve its initial mass 0.20 m x 0.05 m =
0.01 m^2 per unit width, and a higher friction coefficient must give a slower flow.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import dask
import pytest
import yaml
from dask.distributed import SpecCluster, Status  # its defaults in Dask's settings before a test sets one

from multilayer import scenario
from multilayer.app import cli, runner, sweep
from multilayer.errors import InputError, RunError
from multilayer.io import results

TINY = """\
name: tiny-collapse
slope_deg: 25.0
domain: {x_min: 0.0, x_max: 1.0, cells: 40, layers: 3}
material: {density: 1500, grain_diameter: 1.0e-3}
rheology: {name: drucker_prager, mu_s: 0.35, nu: 1.0e-4}
base: [{condition: no_slip}]
initial: [{shape: rectangle, x_min: 0.0, x_max: 0.2, height: 0.05}]
boundaries: {left: wall, right: outflow}
time: {end: 0.2, output_interval: 0.1}
"""
INITIAL_MASS = 0.20 * 0.05  # m^2 per unit width

ROOT = Path(__file__).resolve().parents[1]
# subprocesses (dask scheduler and workers, the CLI) import this source tree
ENV = {**os.environ, "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))}

# two frictions x two resolutions, one of which (0 cells) is invalid
FRICTION_SWEEP = """\
base: tiny.yaml
parameters:
  rheology.mu_s: [0.3, 0.4]
  domain.cells: [40, 0]
"""


def write_sweep(directory: Path, text: str) -> Path:
    """``text`` as ``sweep.yaml`` next to the tiny base scenario ``tiny.yaml``."""
    (directory / "tiny.yaml").write_text(TINY)
    path = directory / "sweep.yaml"
    path.write_text(text)
    return path


def read_summary(outdir: Path) -> list[dict[str, str]]:
    with (outdir / "summary.csv").open(newline="") as stream:
        return list(csv.DictReader(stream))


# --------------------------------------------------------------------- sweep files


def test_a_sweep_file_read_as_a_stream_takes_its_paths_from_the_working_directory(tmp_path, monkeypatch):
    """``multilayer sweep /dev/stdin < studies/sweep.yaml`` read its ``base`` from
    ``/dev``, the directory of the stream's name: a stream (``/dev/stdin``, ``/dev/fd/N``,
    ``/proc/self/fd/N``) names no directory, so its paths are read from the working
    directory, as a here-document's are, and the message says so; so are the files of a
    scenario read as a stream.  A file under ``/dev`` that is no stream keeps its own."""
    studies = tmp_path / "studies"
    studies.mkdir()
    path = write_sweep(studies, "base: tiny.yaml\nparameters:\n  rheology.mu_s: [0.3, 0.4]\n")
    (studies / "bed.csv").write_text("x (m), z (m)\n0, 0\n1, 0\n")
    (studies / "bedded.yaml").write_text(TINY + "bed: {file: bed.csv}\n")
    monkeypatch.chdir(tmp_path)
    with path.open() as stream:
        for name in (f"/dev/fd/{stream.fileno()}", f"/proc/self/fd/{stream.fileno()}"):
            said = r"tiny\.yaml not found; accepted: .*relative to the working directory \(/.*/\d+ names"
            with pytest.raises(InputError, match=said):
                sweep.load(name)
    monkeypatch.chdir(studies)
    with path.open() as stream:
        plan = sweep.load(f"/dev/fd/{stream.fileno()}")
    assert plan.base == studies / "tiny.yaml" and len(plan.members()) == 2
    with (studies / "bedded.yaml").open() as stream:
        assert scenario.load(f"/dev/fd/{stream.fileno()}").input_files() == {"bed.file": studies / "bed.csv"}
    assert not scenario.files.names_a_stream(Path("/dev/shm/sweep.yaml"))


def test_product_members_last_key_fastest_with_stable_ids(tmp_path):
    plan = sweep.load(
        write_sweep(
            tmp_path,
            """\
base: tiny.yaml
parameters:
  rheology.mu_s: [0.3, 0.4]
  initial.0.height: [0.03, 0.04, 0.05]
""",
        )
    )
    members = plan.members()
    assert [tuple(m.values.values()) for m in members] == [
        (0.3, 0.03),
        (0.3, 0.04),
        (0.3, 0.05),
        (0.4, 0.03),
        (0.4, 0.04),
        (0.4, 0.05),
    ]
    assert members[1].overrides == ["rheology.mu_s=0.3", "initial.0.height=0.04"]
    assert [m.id[:5] for m in members] == [f"m{i:03d}-" for i in range(6)]
    assert len({m.id for m in members}) == 6
    # the ids name the values: the same on every load, changed only where a value changes
    assert [m.id for m in sweep.load(plan.path).members()] == [m.id for m in members]
    plan.path.write_text(plan.path.read_text().replace("0.05]", "0.06]"))
    changed = [a.id != b.id for a, b in zip(members, sweep.load(plan.path).members())]
    assert changed == [False, False, True, False, False, True]


def test_zip_pairs_the_lists(tmp_path):
    plan = sweep.load(
        write_sweep(
            tmp_path,
            """\
base: tiny.yaml
zip: true
parameters:
  slope_deg: [20.0, 25.0, 30.0]
  rheology.mu_s: [0.3, 0.4, 0.5]
""",
        )
    )
    assert [m.values for m in plan.members()] == [
        {"slope_deg": 20.0, "rheology.mu_s": 0.3},
        {"slope_deg": 25.0, "rheology.mu_s": 0.4},
        {"slope_deg": 30.0, "rheology.mu_s": 0.5},
    ]


def test_zip_with_lists_of_different_lengths_is_an_input_error(tmp_path):
    path = write_sweep(
        tmp_path,
        """\
base: tiny.yaml
parameters:
  slope_deg: [20.0, 25.0, 30.0]
  rheology.mu_s: [0.3, 0.4]
zip: true
""",
    )
    with pytest.raises(InputError) as error:
        sweep.load(path)
    assert str(error.value) == (
        f"{path}: zip (line 5): the lists under parameters have different lengths "
        "(slope_deg: 3, rheology.mu_s: 2); accepted: lists of equal length with zip: true"
    )


@pytest.mark.parametrize(
    "text, key, what",
    [
        ("base: tiny.yaml\nparameters: {slope_deg: [20]}\nworkers: 3\n", "workers (line 3)", "unknown key"),
        ("parameters: {slope_deg: [20]}\n", "base", "required key is missing"),
        ("base: nowhere.yaml\nparameters: {slope_deg: [20]}\n", "base (line 1)", "not found"),
        ("base: tiny.yaml\n", "parameters", "got None"),
        ("base: tiny.yaml\nparameters: {}\n", "parameters (line 2)", "got {}"),
        ("base: tiny.yaml\nparameters:\n  slope_deg: []\n", "parameters.slope_deg (line 3)", "got []"),
        ("base: tiny.yaml\nparameters:\n  slope_deg: 20\n", "parameters.slope_deg (line 3)", "got 20"),
        (
            "base: tiny.yaml\nparameters: {slope_deg: [20]}\nzip: yes please\n",
            "zip (line 3)",
            "got 'yes please'",
        ),
        (
            "base: tiny.yaml\nparameters: {slope_deg: [20]}\noutput: {dir: x}\n",
            "output.dir (line 3)",
            "unknown key",
        ),
    ],
)
def test_invalid_sweep_file_exits_2_naming_file_and_key(tmp_path, capsys, text, key, what):
    path = write_sweep(tmp_path, text)
    assert cli.main(["sweep", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert f"multilayer: error: {path}: {key}: " in err
    assert what in err and "Traceback" not in err
    assert not (tmp_path / "out").exists()


def test_a_sweep_key_with_an_empty_part_or_of_no_effect_on_the_run_is_named(tmp_path):
    """A key with an empty part was named as a member's ``--set``, a key the file does not
    hold; members differing in ``name`` or ``description`` only ran one simulation each."""
    said = {
        "''": "the key '' has an empty part; accepted: a dotted scenario key, no part empty",
        "rheology.": "the key 'rheology.' has an empty part",
        "name": "name does not change the run: every member would run the same simulation",
        "description": "description does not change the run",
    }
    for key, what in said.items():
        path = write_sweep(tmp_path, f"base: tiny.yaml\nparameters:\n  {key}: [a, b]\n")
        with pytest.raises(InputError) as error:
            sweep.load(path)
        assert str(error.value).startswith(f"{path}: parameters.{key} (line 3): {what}")


def test_invalid_base_scenario_exits_2(tmp_path, capsys):
    path = write_sweep(tmp_path, FRICTION_SWEEP)
    (tmp_path / "tiny.yaml").write_text(TINY.replace("cells: 40", "cells: many"))
    assert cli.main(["sweep", str(path)]) == 2
    err = capsys.readouterr().err
    assert f"{path}: base (line 1): the base scenario is invalid" in err
    assert "domain.cells (line 3)" in err


def test_workers_with_scheduler_is_refused(tmp_path, capsys):
    path = write_sweep(tmp_path, FRICTION_SWEEP)
    with pytest.raises(SystemExit) as exit_:
        cli.main(["sweep", str(path), "--scheduler", "tcp://127.0.0.1:8786", "--workers", "2"])
    assert exit_.value.code == 2
    assert "argument --workers: not allowed with argument --scheduler" in capsys.readouterr().err


def test_unreachable_scheduler_exits_2_before_anything_runs(tmp_path, capsys):
    path = write_sweep(tmp_path, FRICTION_SWEEP)
    argv = ["sweep", str(path), "-o", str(tmp_path / "out"), "--scheduler", "nowhere"]
    assert cli.main(argv) == 2
    assert "--scheduler nowhere: cannot connect" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "value", [0.4, 1e-5, 3, "jop_mu_i", "1e-5", True, None, [[0.0, 0.1], [1.0, 0.0]], {"geometric": 1.2}]
)
def test_values_reach_the_scenario_as_written(value):
    """A member's override text reads back to the sweep file's value, as ``--set`` reads it."""
    text = sweep.format_value(value)
    data, _ = scenario.apply_overrides({}, [f"key={text}"])
    assert data == {"key": value}


def test_worked_example_of_the_docs_is_valid():
    """The example sweep of docs/sweeps.md, shipped next to the scenarios: 6 valid members."""
    plan = sweep.load(ROOT / "scenarios" / "sweeps" / "bed_thickness_rheology.yaml")
    assert plan.base == ROOT / "scenarios" / "sweeps" / ".." / "erodible_bed_collapse.yaml"
    members = plan.members()
    assert len(members) == 6
    for member in members:
        loaded = scenario.load(plan.base, member.overrides)
        assert loaded.rheology.name == member.values["rheology"]["name"]
        assert loaded.initial[0].thickness == member.values["initial.0.thickness"]


def test_member_continues_its_own_checkpoint_and_restarts_on_another(tmp_path):
    """``run_member`` (what a worker runs) resumes a run of the same scenario left without
    its completion marker, and starts afresh over a checkpoint of another scenario."""
    base = tmp_path / "tiny.yaml"
    base.write_text(TINY)
    member_dir = tmp_path / "m000"
    first = runner.run(scenario.load(base, ["rheology.mu_s=0.3"]), member_dir, quiet=True)

    same = scenario.load(base, ["rheology.mu_s=0.3"])
    fp_same = sweep.scenario_fingerprint(same)
    resumed = sweep.run_member(same, str(member_dir), fp_same, ["rheology.mu_s=0.3"])
    assert "resumed run" in (member_dir / runner.LOG_FILE).read_text()
    del resumed["wall_time_s"], first["wall_time_s"]
    assert resumed == first  # nothing left to compute: the same steps and diagnostics
    assert sweep.completed(member_dir, fp_same)["steps"] == first["steps"]

    other = scenario.load(base, ["rheology.mu_s=0.4"])
    fp_other = sweep.scenario_fingerprint(other)
    summary = sweep.run_member(other, str(member_dir), fp_other, ["rheology.mu_s=0.4"])
    assert "new run" in (member_dir / runner.LOG_FILE).read_text()
    assert summary["max_speed_final"] < first["max_speed_final"]  # more friction, slower
    assert sweep.completed(member_dir, fp_same) is None
    assert sweep.completed(member_dir, fp_other) == summary


def test_a_member_whose_result_another_run_replaced_is_not_reused(tmp_path):
    """A run of another scenario into a completed member's directory (``multilayer run -o
    sweep/m000``, to look at a member more closely) left the member's marker: the sweep run
    again reported the marker's summary for it and a calibration measured the other run as
    the member.  The member is reused only if ``result.nc`` records its scenario."""
    base = tmp_path / "tiny.yaml"
    base.write_text(TINY)
    member_dir = tmp_path / "m000"
    member = scenario.load(base, ["rheology.mu_s=0.3"])
    fingerprint = sweep.scenario_fingerprint(member)
    summary = sweep.run_member(member, str(member_dir), fingerprint, ["rheology.mu_s=0.3"])
    assert sweep.completed(member_dir, fingerprint) == summary
    # a marker edited or damaged: its summary was reported as the member's (a runout of 99,
    # NaN, text, all "ok"); the summary is the result's
    marker = json.loads((member_dir / sweep.MARKER).read_text())
    marker["summary"].update(runout=99.0, front_final=float("nan"), steps="many")
    (member_dir / sweep.MARKER).write_text(json.dumps(marker))
    assert sweep.completed(member_dir, fingerprint) == summary
    runner.run(scenario.load(base, ["rheology.mu_s=0.4"]), member_dir, quiet=True)
    assert (member_dir / sweep.MARKER).is_file() and results.run_failure(member_dir) is None
    assert sweep.completed(member_dir, fingerprint) is None


# --------------------------------------------------------------------- on a real cluster


@pytest.fixture(scope="module")
def scheduler(tmp_path_factory):
    """A Dask scheduler and two single-threaded workers on 127.0.0.1, as subprocesses
    (``dask scheduler`` / ``dask worker``), torn down whatever the tests do."""
    workdir = tmp_path_factory.mktemp("dask-cluster")
    scheduler_file = workdir / "scheduler.json"
    log = (workdir / "cluster.log").open("w")
    processes: list[subprocess.Popen] = []

    def start(*args: str) -> None:
        processes.append(
            subprocess.Popen(
                [sys.executable, "-m", "dask", *args, "--no-dashboard"],
                cwd=workdir,
                env=ENV,
                stdout=log,
                stderr=subprocess.STDOUT,
                start_new_session=True,
            )
        )

    try:
        start("scheduler", "--host", "127.0.0.1", "--port", "0", "--scheduler-file", str(scheduler_file))
        deadline = time.monotonic() + 60
        while not scheduler_file.is_file():
            assert processes[0].poll() is None and time.monotonic() < deadline, (
                "the Dask scheduler did not start:\n" + (workdir / "cluster.log").read_text()
            )
            time.sleep(0.1)
        address = json.loads(scheduler_file.read_text())["address"]
        for name in ("worker-a", "worker-b"):
            start(
                "worker",
                address,
                "--host",
                "127.0.0.1",
                "--nworkers",
                "1",
                "--nthreads",
                "1",
                "--name",
                name,
                "--local-directory",
                str(workdir),
            )
        from dask.distributed import Client

        with Client(address, timeout="30s") as client:
            client.wait_for_workers(2, timeout=60)
        yield address
    finally:
        for process in processes:  # each in its own session: the worker's nanny and child too
            os.killpg(process.pid, signal.SIGTERM)
        for process in processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait()
        log.close()


def run_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "multilayer", "sweep", *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=ENV,
    )


@pytest.fixture(scope="module")
def friction_sweep(scheduler, tmp_path_factory):
    """The 4-member friction sweep (2 valid, 2 invalid) run once on the cluster."""
    directory = tmp_path_factory.mktemp("friction-sweep")
    path = write_sweep(directory, FRICTION_SWEEP)
    outdir = directory / "out"
    first = run_cli(str(path), "-o", str(outdir), "--scheduler", scheduler)
    return path, outdir, first


@pytest.mark.slow  # 10 s to start a scheduler and two workers; in-process clusters stay in the default run
def test_sweep_on_a_scheduler_with_two_workers(friction_sweep):
    path, outdir, first = friction_sweep
    assert first.returncode == 1, first.stderr  # two members are invalid
    assert "4 members: 0 already complete (skipped), 2 invalid, 2 to run" in first.stdout

    rows = read_summary(outdir)
    assert [(r["rheology.mu_s"], r["domain.cells"], r["status"]) for r in rows] == [
        ("0.3", "40", "ok"),
        ("0.3", "0", "invalid"),
        ("0.4", "40", "ok"),
        ("0.4", "0", "invalid"),
    ]
    for row in rows:
        if row["status"] == "invalid":  # the reason, in the summary and on stderr
            assert "domain.cells" in row["error"] and "an integer from 1 to 1000000000" in row["error"]
            assert (
                f"member {row['member']} (rheology.mu_s={row['rheology.mu_s']}, "
                f"domain.cells=0) invalid: " in first.stderr
            )
            assert row["front_final"] == "" and not (outdir / row["member"]).exists()
    ok = [row for row in rows if row["status"] == "ok"]
    assert sorted(p.parent.name for p in outdir.glob("*/result.nc")) == [r["member"] for r in ok]

    for row in ok:
        result = outdir / row["member"] / "result.nc"
        summary = results.summary(result)
        # the row holds the result's own diagnostics, and the worker ran the member's friction
        assert {key: float(row[key]) for key in ("front_final", "runout", "mass_final", "wall_time_s")} == {
            key: summary[key] for key in ("front_final", "runout", "mass_final", "wall_time_s")
        }
        with results.open_result(result) as ds:
            resolved = yaml.safe_load(ds.attrs["scenario"])
        assert resolved["rheology"]["mu_s"] == float(row["rheology.mu_s"])
        assert summary["t_final"] == pytest.approx(0.2, abs=1e-12)
        assert summary["mass_final"] == pytest.approx(INITIAL_MASS, rel=1e-12)
    # more friction, slower flow: mu_s = 0.3 (first) against 0.4 (second); the front moves
    # by whole cells (dx = 2.5 cm), so the two run-outs may share a cell
    assert float(ok[0]["max_speed_final"]) > float(ok[1]["max_speed_final"]) > 0
    assert float(ok[0]["runout"]) >= float(ok[1]["runout"]) > 0


@pytest.mark.slow  # the real cluster of the test above; a local-cluster rerun stays in the default run
def test_second_run_of_a_completed_sweep_runs_nothing(friction_sweep, scheduler):
    path, outdir, first = friction_sweep
    results_before = {p: p.stat().st_mtime_ns for p in outdir.glob("*/*")}
    rows_before = read_summary(outdir)

    second = run_cli(str(path), "-o", str(outdir), "--scheduler", scheduler)
    assert second.returncode == 1  # the two invalid members are still invalid
    assert "4 members: 2 already complete (skipped), 2 invalid, 0 to run\n" in second.stdout
    assert {p: p.stat().st_mtime_ns for p in outdir.glob("*/*")} == results_before
    assert read_summary(outdir) == rows_before


# --------------------------------------------------------------------- failures, local cluster


@pytest.mark.slow
def test_a_failing_member_does_not_stop_the_others_and_reruns_alone(tmp_path, monkeypatch, capsys):
    from dask.distributed import LocalCluster

    path = write_sweep(
        tmp_path,
        """\
base: tiny.yaml
parameters:
  rheology.mu_s: [0.3, 0.4, 0.5]
""",
    )
    outdir = tmp_path / "out"
    real_run = runner.run
    ran: list[float] = []
    broken = {0.4}  # mu_s of the members whose run fails

    def flaky_run(member, outdir, **options):
        mu_s = member.rheology.params["mu_s"]
        ran.append(mu_s)
        if mu_s in broken:
            raise RunError("the solver broke down")
        return real_run(member, outdir, **options)

    monkeypatch.setattr(runner, "run", flaky_run)
    # threads in this process, so that the patched runner is the one the tasks call
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        argv = ["sweep", str(path), "-o", str(outdir), "--scheduler", cluster.scheduler_address]
        assert cli.main(argv) == 1
        rows = read_summary(outdir)
        assert [row["status"] for row in rows] == ["ok", "failed", "ok"]
        assert rows[1]["error"] == "RunError: the solver broke down"
        assert "invalid" not in rows[1]["error"] and rows[1]["runout"] == ""
        assert (
            f"member {rows[1]['member']} (rheology.mu_s=0.4) failed: RunError: the solver "
            "broke down" in capsys.readouterr().err
        )
        assert sorted(ran) == [0.3, 0.4, 0.5]

        broken.clear()
        assert cli.main(argv) == 0  # resume: only the failed member runs again
        assert ran[3:] == [0.4]
        assert [row["status"] for row in read_summary(outdir)] == ["ok", "ok", "ok"]
        assert "3 members: 2 already complete (skipped), 0 invalid, 1 to run" in capsys.readouterr().out


@pytest.mark.parametrize("kind", ["a named pipe", "a link to /dev/zero", "2 MB"])
def test_a_marker_that_is_no_small_regular_file_is_not_read_through(tmp_path, kind):
    """A member's ``member.json`` a named pipe held the study for ever (reading it waits for
    a writer), a link to ``/dev/zero`` filled the memory: only a regular file's first
    :data:`sweep.MARKER_BYTES` are read, and such a member is not complete (it runs again)."""
    import threading

    marker = tmp_path / sweep.MARKER
    if kind == "a named pipe":
        os.mkfifo(marker)
    elif kind == "a link to /dev/zero":
        marker.symlink_to("/dev/zero")
    else:
        marker.write_text("[" * (2 << 20))
    found: list[object] = []
    reader = threading.Thread(target=lambda: found.append(sweep.completed(tmp_path, "f")), daemon=True)
    reader.start()
    reader.join(10)
    assert found == [None], f"reading {kind} as a marker did not end"


def test_a_local_cluster_whose_workers_cannot_start_is_a_failure_in_one_line(tmp_path, monkeypatch, capsys):
    """A local cluster whose worker processes fail to start (a script read from standard
    input: a new process cannot import its ``__main__`` again) ended the command with
    distributed's traceback ("Nanny failed to start."); it is a failure saying so, exit 1."""
    import dask.distributed

    class Fails:  # a cluster class whose constructor raises as the nannies fail
        def __init__(self, **options):
            raise RuntimeError("Nanny failed to start.")

    monkeypatch.setattr(dask.distributed, "LocalCluster", Fails)
    path = write_sweep(tmp_path, "base: tiny.yaml\nparameters:\n  rheology.mu_s: [0.3]\n")
    assert cli.main(["sweep", str(path), "-o", str(tmp_path / "out"), "--workers", "1", "-q"]) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    assert "the local Dask cluster could not start its 1 worker process(es) (Nanny failed to start;" in err
    assert not list(tmp_path.glob("out/*/result.nc"))


def test_compiling_the_kernels_takes_one_single_threaded_step(tmp_path, monkeypatch):
    """``compile_kernels`` (run before local worker processes start) steps the member
    once on one thread, and leaves a member that fails to its own run."""
    from multilayer.app.simulation import Simulation

    (tmp_path / "tiny.yaml").write_text(TINY)
    member = scenario.load(tmp_path / "tiny.yaml")
    stepped = []

    def step(self, t_max=float("inf")):
        stepped.append(self.thread_policy.threads(10**9))
        raise RunError("a member that fails")

    monkeypatch.setattr(Simulation, "step", step)
    assert sweep.compile_kernels(member) is None
    assert stepped == [1]


@pytest.mark.slow
def test_local_cluster_zip_sweep(tmp_path, monkeypatch, capsys):
    """Without --scheduler: a local cluster of worker processes, here a zipped sweep.

    Slow (about 30 s of CPU starting the worker processes); runs on Dask workers are
    covered in the default run by the scheduler tests."""
    path = write_sweep(
        tmp_path,
        """\
base: tiny.yaml
zip: true
parameters:
  slope_deg: [20.0, 25.0]
  rheology.mu_s: [0.3, 0.35]
output: {directory: zipped}
""",
    )
    monkeypatch.chdir(tmp_path)  # output.directory is relative to the current directory
    warmed = []  # the kernels are compiled in this process before the workers start
    monkeypatch.setattr(sweep, "compile_kernels", lambda member: warmed.append(member) or None)
    assert cli.main(["sweep", str(path), "--workers", "2", "--quiet"]) == 0
    assert capsys.readouterr().out == ""
    assert [(m.slope_deg, m.rheology.params["mu_s"]) for m in warmed] == [(20.0, 0.3)]
    rows = read_summary(tmp_path / "zipped")
    assert [(r["slope_deg"], r["rheology.mu_s"], r["status"]) for r in rows] == [
        ("20.0", "0.3", "ok"),
        ("25.0", "0.35", "ok"),
    ]
    for row in rows:
        assert float(row["mass_final"]) == pytest.approx(INITIAL_MASS, rel=1e-12)
        assert (tmp_path / "zipped" / row["member"] / "result.nc").is_file()


def test_a_study_holds_its_directory_and_names_one_that_is_a_file(tmp_path, cli, write_scenario):
    """Two sweeps (or calibrations, sensitivity studies) into one directory both ran every
    member, each member's second run refused as another run's, and a stop of one stopped the
    other's members (the directory's stop file); ``-o`` a file was "File exists" (and the
    sweep's, "stop-requested: Not a directory").  A study holds ``DIR/run.lock`` as a run
    does, and its directory is made as a run's is."""
    import socket

    write_scenario(TINY, "base.yaml")
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n0.1,0.3,0.01\n")
    bounds = {"rheology.mu_s": {"bounds": [0.2, 0.4]}}
    observation = {
        "name": "front",
        "quantity": "front",
        "file": "front.csv",
        "columns": ["t", "x_f", "sigma"],
    }
    files = {
        "sweep": write_scenario({"base": "base.yaml", "parameters": {"rheology.mu_s": [0.3]}}, "sweep.yaml"),
        "calibrate": write_scenario(
            {"base": "base.yaml", "parameters": bounds, "observations": [observation]}, "calibration.yaml"
        ),
        "sensitivity": write_scenario(
            {"base": "base.yaml", "parameters": bounds, "outputs": ["runout"], "samples": 4}, "sobol.yaml"
        ),
    }
    held = tmp_path / "held"
    held.mkdir()
    holder = {"pid": os.getppid(), "host": socket.gethostname(), "started": "2026-01-01T00:00:00+00:00"}
    (held / "run.lock").write_text(json.dumps(holder))
    (tmp_path / "a_file").write_text("")
    for command, path in files.items():
        result = cli(command, path, "-o", held)
        assert result.code == 2 and "Traceback" not in result.err, result.err
        assert f"{held}: another run is writing into this directory (pid {os.getppid()}" in result.err
        assert sorted(p.name for p in held.iterdir()) == ["run.lock"]
        result = cli(command, path, "-o", tmp_path / "a_file")
        assert result.code == 2 and f"{tmp_path / 'a_file'}: a file, not a directory" in result.err, (
            result.err
        )


def test_a_studys_warm_up_runs_no_third_party_law_in_the_studys_process(monkeypatch, tiny_scenario):
    """The warm-up step of a study runs in the study's own process: a third-party law there
    that ends its process (``os._exit``) ended the study silently, before any member ran.
    It is skipped for such a law (its members run it on the workers); a built-in law's is
    stepped."""
    import multilayer
    from multilayer.app import simulation
    from multilayer.plugins import host

    stepped = []

    class Stepped:
        def __init__(self, member: scenario.Scenario) -> None:
            stepped.append(member.rheology.name)

        def step(self) -> None:
            pass

    monkeypatch.setattr(simulation, "Simulation", Stepped)
    member = multilayer.load(tiny_scenario)
    sweep.compile_kernels(member)
    assert stepped == ["drucker_prager"] and host.is_builtin("drucker_prager")
    assert not host.is_builtin("no_such_law")
    monkeypatch.setattr(host, "is_builtin", lambda name: name != "drucker_prager")  # as a third party's
    sweep.compile_kernels(member)
    assert stepped == ["drucker_prager"]


def test_a_missing_dask_temporary_directory_is_named(tmp_path):
    """A Dask temporary directory that cannot be made is named with its variable."""
    with dask.config.set({"temporary-directory": str(tmp_path / "nothing")}):
        with pytest.raises(
            InputError, match="Dask's temporary-directory .*nothing .*DASK_TEMPORARY_DIRECTORY"
        ):
            with sweep.dask_client(None, 1):
                pass


def test_a_dask_setting_the_cluster_cannot_read_is_an_input_error_naming_the_variables(monkeypatch):
    """A Dask setting the local cluster cannot read is an input error naming the `DASK_*`
    variables set, not a `KeyError` traceback."""
    monkeypatch.setenv("DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT", "abc")
    with dask.config.set({"distributed.comm.timeouts.connect": "abc"}):
        with pytest.raises(
            InputError, match="could not read its settings .*set in the environment: DASK_DISTRIBUTED__COMM"
        ):
            with sweep.dask_client(None, 1):
                pass


@pytest.mark.parametrize(
    "setting",
    [
        pytest.param(None, id="a study", marks=pytest.mark.slow),  # 4 s: a cluster of one worker process
        pytest.param("abc", id="a setting the cluster cannot read"),
    ],
)
def test_the_cluster_releases_its_directories_before_the_scratch_space_goes(monkeypatch, setting):
    """The local cluster's scratch space is removed once no Dask server holds a directory
    there.  A cluster whose start failed on a setting it cannot read (a connection timeout
    of ``abc``) failed to close too, its scheduler running on: the scratch space went
    first, and at the process's exit Dask logged "Failed to remove ... scheduler-..."
    after the message, having waited 10 s for the cluster to close.  Its scheduler is
    now closed before the error goes on."""
    held: list[str] = []

    class Recorded:  # sweep's shutil, recording the servers' directories left at the removal
        @staticmethod
        def rmtree(path: str, ignore_errors: bool = False) -> None:
            held.extend(p.name for p in Path(path).glob("dask-scratch-space/*") if p.is_dir())
            shutil.rmtree(path, ignore_errors=ignore_errors)

    monkeypatch.setattr(sweep, "shutil", Recorded)
    if setting is None:
        with sweep.dask_client(None, 1) as client:
            assert client.submit(sum, [1, 2]).result() == 3
    else:
        monkeypatch.setenv("DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT", setting)
        with dask.config.set({"distributed.comm.timeouts.connect": setting}):
            with pytest.raises(InputError, match="could not read its settings"):
                with sweep.dask_client(None, 1):
                    pass
    assert held == []
    assert all(cluster.status == Status.closed for cluster in SpecCluster._instances)
