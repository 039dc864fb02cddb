"""Benchmark: the time each shipped scenario takes, as the scenario headers and docs quote it.

Runs every scenario file given (default: all of ``scenarios/*.yaml``) once as shipped,
as ``multilayer run`` does (result file and checkpoints included) after compiling the
numba kernels, and prints its CPU time (of this process: the figure that the load of a
shared machine changes least), its wall time, the time steps and the cell-steps per
CPU second.

    python benchmarks/scenarios.py [SCENARIO.yaml ...] [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import os
import platform
import tempfile
import time
from pathlib import Path

from multilayer.app import runner
from multilayer.app.simulation import Simulation
from multilayer.scenario import load

ROOT = Path(__file__).resolve().parents[1]


def time_scenario(path: Path, overrides: list[str]) -> tuple[float, float, int, int]:
    """(CPU s, wall s, steps, cells x layers) of running ``path`` to its end time."""
    scenario = load(path, overrides)
    with tempfile.TemporaryDirectory() as outdir:
        cpu, wall = time.process_time(), time.perf_counter()
        summary = runner.run(scenario, outdir, quiet=True)
        cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    return cpu, wall, int(summary["steps"]), scenario.domain.cells * scenario.domain.layers


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "scenarios", nargs="*", type=Path, default=sorted((ROOT / "scenarios").glob("*.yaml"))
    )
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()

    warm = load(args.scenarios[0], ["time.end=1e-6", *args.overrides])
    Simulation(warm).advance(warm.time.end)  # compile the numba kernels outside the timing
    print(
        f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}"
    )
    print(f"{'scenario':28s} {'CPU s':>7s} {'wall s':>7s} {'steps':>6s} {'M cell-steps/s':>15s}")
    for path in args.scenarios:
        cpu, wall, steps, cells = time_scenario(path, args.overrides)
        print(f"{path.stem:28s} {cpu:7.1f} {wall:7.1f} {steps:6d} {cells * steps / cpu / 1e6:15.2f}")


if __name__ == "__main__":
    main()
