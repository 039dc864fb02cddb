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
