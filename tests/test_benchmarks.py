"""The benchmark scripts run (their timings are measured by hand, never by tests)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from multilayer.app.simulation import Simulation
from multilayer.engine.threads import parallel_chunks

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


SHOW_HELP = """
import contextlib, io, runpy, sys
for script in sys.argv[1:]:
    sys.argv = [script, "--help"]
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        try:
            runpy.run_path(script, run_name="__main__")
        except SystemExit as stop:
            code = stop.code
        else:
            code = "no exit"
    print(script, code, "usage" in out.getvalue())
"""


@pytest.mark.slow
def test_benchmark_scripts_show_their_options():
    """Each script's ``--help`` exits 0 with its usage (all in one process: the imports of
    the engine once)."""
    scripts = [path for path in sorted(BENCHMARKS.glob("*.py")) if "__main__" in path.read_text()]
    assert len(scripts) >= 9  # (common.py is a module of theirs)
    done = subprocess.run(
        [sys.executable, "-c", SHOW_HELP, *map(str, scripts)], capture_output=True, text=True, cwd=BENCHMARKS
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:-1] == [f"{script} 0 True" for script in scripts]


@pytest.mark.slow
def test_a_small_chute_stays_on_the_bagnold_profile():
    """The fully wet benchmark's own check on a small mesh: started on Bagnold's profile
    with a Bagnold inflow, it stays within a few per cent of it (the layer means are not the
    discrete steady state, which the flow relaxes to over about 0.4 s)."""
    out = subprocess.run(
        [sys.executable, BENCHMARKS / "chute.py", "--cells", "60", "--layers", "8", "--steps", "5"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    line = next(x for x in out.splitlines() if x.startswith("check:"))
    error = float(line.split("surface speed = ")[1].split(" ")[0])
    assert error < 0.01


@pytest.mark.slow
def test_the_dam_break_times_a_peer_before_each_run_and_reports_the_median_ratio():
    """``--peer`` runs the command right before each of ``--pairs`` runs; each pair's
    ratio is the peer's wall time over the time to solution, and their median closes."""
    command = [sys.executable, BENCHMARKS / "dam_break.py", "--cells", "100", "--layers", "4", "--end", "0.1"]
    out = subprocess.run(
        [*command, "--peer", "sleep 0.2", "--pairs", "3"], capture_output=True, text=True, check=True
    ).stdout
    lines = out.splitlines()
    peers = [float(x.split(" took ")[1].split(" s")[0]) for x in lines if x.startswith("peer:")]
    solutions = [float(x.split()[3]) for x in lines if x.startswith("time to solution")]
    pairs = [float(x.split(" took ")[1].split(" times")[0]) for x in lines if x.startswith("pair ")]
    assert len(peers) == len(solutions) == len(pairs) == 3 and min(peers) >= 0.2
    median = float(out.split("median ")[1].split(" ")[0])
    assert median == pytest.approx(sorted(pairs)[1], abs=0.01)
    failed = subprocess.run([*command, "--peer", "exit 3"], capture_output=True, text=True)
    assert failed.returncode == 1 and "'exit 3' failed (exit 3)" in failed.stderr


def _basilisk_collapse():
    """benchmarks/basilisk_collapse.py as a module."""
    spec = importlib.util.spec_from_file_location("basilisk_collapse", BENCHMARKS / "basilisk_collapse.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_basilisk_collapse_stops_with_status_2_without_basilisk():
    """Without a Basilisk tree the comparison says what it needs and exits 2 (a benchmark,
    not a test: nothing is run)."""
    env = {key: value for key, value in os.environ.items() if key != "BASILISK"}
    done = subprocess.run(
        [sys.executable, BENCHMARKS / "basilisk_collapse.py"], capture_output=True, text=True, env=env
    )
    assert done.returncode == 2 and "--basilisk DIR" in done.stderr


def test_the_basilisk_collapse_measures_a_deposit_as_the_record_does():
    """The mound holds the rectangle's volume H0 L0; Basilisk's output is read back and
    measured: a deposit falling linearly from 1 cm at the wall to 0 at 10 cm has its 1.5 mm
    tip at 8.5 cm, (x - L0)/L0 = 0.7, and a tip that never moves stopped at the first output."""
    bc = _basilisk_collapse()
    points = np.array(bc.mound_points())
    assert np.trapezoid(points[:, 1], points[:, 0]) == pytest.approx(bc.H_COLUMN * bc.L_COLUMN, rel=1e-5)
    x = (np.arange(200) + 0.5) * 1e-3
    h = np.maximum(0.01 * (1.0 - x / 0.1), 0.0)
    block = "\n".join(f"{a:.9g} {b:.12g} 0" for a, b in zip(x, h, strict=True))
    text = "".join(f"t {t:g}\n{block}\n" for t in (0.0, 0.01, 0.02)) + "\n# Multigrid, 3 steps\n"
    measured = bc.measures(bc.parse_output(text))
    assert measured["tip"] == pytest.approx(0.7, abs=1e-9)
    assert measured["mass"] == pytest.approx(h.sum() * 1e-3) and measured["mass_change"] == 0.0
    assert measured["t_stop"] == 0.0 and measured["umax_end"] == 0.0


def test_the_scaling_sweep_refuses_no_repeats():
    out = subprocess.run(
        [sys.executable, BENCHMARKS / "scaling.py", "--repeat", "0"], capture_output=True, text=True
    )
    assert (
        out.returncode == 2
        and "--repeat takes an integer >= 1" in out.stderr
        and "Traceback" not in out.stderr
    )


def test_the_scaling_sweep_keeps_the_fastest_run_of_each_point():
    """Each point of the sweep keeps its fastest run (as timeit does), the median and the
    slowest beside it and the largest peak memory; flatness is slowest over fastest."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import scaling
    finally:
        sys.path.remove(str(BENCHMARKS))
    runs = [
        {
            "columns": 10,
            "layers": 8,
            "ns_per_cell_step": t,
            "bytes_per_cell": b,
            "bytes_per_cell_above_baseline": b / 2,
        }
        for t, b in ((90.0, 100.0), (70.0, 120.0), (110.0, 90.0))
    ]
    best = scaling.fastest(runs)
    assert best["ns_per_cell_step"] == 70.0 and best["runs"] == 3
    assert best["median_ns_per_cell_step"] == 90.0 and best["slowest_ns_per_cell_step"] == 110.0
    assert best["bytes_per_cell"] == 120.0 and best["bytes_per_cell_above_baseline"] == 60.0
    rows = [
        best,
        {**best, "layers": 64, "ns_per_cell_step": 50.0},
        {**best, "layers": 4, "ns_per_cell_step": 500.0},
    ]
    ratio, points = scaling.spread(rows, "layers", "columns", 10, 8, 128)
    assert ratio == pytest.approx(70.0 / 50.0) and len(points) == 2


def test_the_warm_up_steps_a_problem_on_each_thread_count(monkeypatch):
    """The kernels a timed run uses are compiled before the timing by a step of the
    warm-up problem on one thread and, with two cores, one on two."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import chute
        import common
    finally:
        sys.path.remove(str(BENCHMARKS))
    monkeypatch.setattr(common, "available_cores", lambda: 2)
    asked = []  # thread counts asked for (run on one, not to compile the parallel kernels here)
    one_thread = common.ThreadPolicy(1)
    monkeypatch.setattr(common, "ThreadPolicy", lambda count: asked.append(count) or one_thread)
    made = []

    def make():
        sim = common.Simulation(chute.scenario(20, 4, 2, 1.0, 1))
        made.append(sim)
        return sim

    sim, timing = common.timed(make, 2e-3, warm_up=make)
    assert len(made) == 3 and sim is made[-1]
    assert asked == [1, 2] and [s.steps for s in made[:2]] == [1, 1]
    assert timing.steps == sim.steps > 0


@pytest.mark.parametrize("cells", [500, 2500])
def test_the_warm_up_problems_are_long_enough_for_the_parallel_transport(cells):
    """On two threads the transport cuts its window into chunks of at least 64 columns:
    the warm-up problems' windows hold two chunks or more, so that the warm-up compiles
    the parallel transport (a dam break on [0, 2] starts with a window of about 4 % of
    the mesh)."""
    sys.path.insert(0, str(BENCHMARKS))
    try:
        import chute
        import dam_break
    finally:
        sys.path.remove(str(BENCHMARKS))
    for config in (
        chute.scenario(cells, 4, 2, 1.0, 2),
        dam_break.scenario(cells, 4, 2, 1.0, 2, column=dam_break.WARM_UP_COLUMN),
    ):
        holding = np.count_nonzero(Simulation(config).h > 0)
        assert parallel_chunks(2, holding, 64) > 1
    benchmark = Simulation(dam_break.scenario(cells, 4, 2, 1.0, 2))  # its own column: too short
    assert parallel_chunks(2, np.count_nonzero(benchmark.h > 0), 64) == 1


def test_the_pailha_readings_follow_their_rules_on_made_up_curves(tmp_path, capsys):
    """``benchmarks/pailha2008_readings.py`` on made-up records (not the digitisation): the
    onset interpolated where a record crosses 0.1 mm/s and its first time where it starts
    above, the velocity only at the fixed times a record reaches, the pressure point of largest
    magnitude with its sign; a missing file exits 2 naming it."""
    path = BENCHMARKS / "pailha2008_readings.py"
    spec = importlib.util.spec_from_file_location("pailha2008_readings", path)
    assert spec is not None and spec.loader is not None
    readings = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(readings)
    from multilayer.validation.cases.immersed_layer import PHI0S

    for k, phi0 in enumerate(PHI0S):
        name = f"{round(phi0 * 1000)}.txt"
        start = 0.3 if k == 0 else 0.05  # mm/s: the first record starts above the onset speed
        (tmp_path / f"v_t_exp_{name}").write_text(f"time\tvelocity\n2\t{start}\n50\t0.15\n120\t0.4\n")
        (tmp_path / f"p_t_exp_{name}").write_text("time\tpressure\n0\t1.5\n40\t-2.25\n90\t0.5\n")
    onsets, speeds = readings.readings(tmp_path)
    assert onsets[1] == f"{PHI0S[0]:g},2.00,120.00,2.00,0.00,90.00,-2.25,40.00"
    assert onsets[2].split(",")[3] == "26.00"  # 0.05 + 0.1 (t - 2) / 48 = 0.1
    assert speeds[1:4] == [f"{PHI0S[0]:g},10,0.2750", f"{PHI0S[0]:g},100,0.3286", f"{PHI0S[1]:g},10,0.0667"]
    assert len(speeds) == 1 + 2 * len(PHI0S)  # not at 300 s, beyond the records
    (tmp_path / "p_t_exp_592.txt").unlink()
    assert readings.main([str(tmp_path)]) == 2
    assert "p_t_exp_592.txt" in capsys.readouterr().err
