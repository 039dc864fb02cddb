"""The benchmark scripts run (their timings are measured by hand, never by tests)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


@pytest.mark.parametrize("script", ["dam_break.py", "chute.py", "scaling.py", "threads.py"])
def test_benchmark_scripts_show_their_options(script):
    out = subprocess.run([sys.executable, BENCHMARKS / script, "--help"], capture_output=True, text=True)
    assert out.returncode == 0 and "usage" in out.stdout


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
