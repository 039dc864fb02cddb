"""Benchmark: the CPU time of ``model.normal_stress`` on the channel collapse (docs/model.md,
"Longitudinal normal stress").

Runs the validation case collapse_channel at each aspect ratio with cells of ``--cells`` to
the case's end time with the option off and on, each in its own process, after one step
that compiles or loads the kernels, and prints the CPU time (``time.process_time``, which
a busy machine inflates less than wall time), the steps and the tip run-out (x_tip - L0) /
L0 of each run; with ``--source DIR`` (a source tree of another commit, e.g. from ``git
archive``) also the option on with that tree's code.

    python benchmarks/normal_stress_cost.py [--ratios 2 4] [--cells 2e-3] [--source DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time


def one(a: float, dx: float, stressed: bool) -> dict[str, float]:
    """CPU time (s), steps and tip run-out of one run, in this process."""
    import multilayer
    from multilayer.io import observables
    from multilayer.validation.cases import collapse_channel as case

    scenario = case.run(a, dx, case.STRESSED if stressed else None).load()
    sim = multilayer.Simulation(scenario)
    sim.step()  # compiles or loads the kernels
    start = time.process_time()
    sim.advance(case.end_time(a))
    cpu = time.process_time() - start
    tip = observables.tip(sim.x, sim.h, scenario.material.grain_diameter)
    return {"cpu": cpu, "steps": sim.steps, "tip": (tip - case.L0) / case.L0}


def child(a: float, dx: float, stressed: bool, source: str | None = None) -> dict[str, float]:
    """:func:`one` in a child process (with the code of ``source`` first on its path)."""
    env = dict(os.environ) if source is None else {**os.environ, "PYTHONPATH": source}
    arguments = [sys.executable, __file__, "--one", str(a), str(dx), "on" if stressed else "off"]
    done = subprocess.run(arguments, env=env, capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ratios", type=float, nargs="+", default=[2.0, 4.0], help="aspect ratios a")
    parser.add_argument("--cells", type=float, default=2e-3, help="cell size (m)")
    parser.add_argument("--source", help="a source tree of another commit: the option on with its code too")
    parser.add_argument("--one", nargs=3, metavar=("A", "DX", "ON"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one is not None:
        print(json.dumps(one(float(args.one[0]), float(args.one[1]), args.one[2] == "on")))
        return
    runs = [("off", False, None), ("on", True, None)]
    if args.source is not None:
        runs.insert(1, ("on, --source", True, args.source))
    print("a   | run          | CPU (s) | steps | tip run-out")
    for a in args.ratios:
        for label, stressed, source in runs:
            found = child(a, args.cells, stressed, source)
            print(f"{a:<3g} | {label:<12} | {found['cpu']:7.2f} | {found['steps']:5d} | {found['tip']:.12f}")


if __name__ == "__main__":
    main()
