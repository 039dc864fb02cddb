"""Benchmark: one and two threads, on a quiet machine and beside one CPU-bound process.

Runs benchmarks/dam_break.py (the peer problem, about 10 % of its cells hold material),
benchmarks/chute.py (fully wet, 1.28 M cells) and the control benchmarks/parallel_limit.py
(a kernel with no serial part: what two threads can get here) with ``--threads 1``,
``--threads 2`` and the default ``auto``, on the machine as it is ("quiet") and beside one
competing CPU-bound process (a Python busy loop started and stopped by this script), each
run in a fresh process: what a user of a shared machine gets.  Each setting is timed quiet, busy, busy,
quiet, one run right after the other, and its ratio is the busy time over the quiet time
of the four: the speed of this machine kind drifts by a third within minutes, and a
drift that is linear in time over the four runs cancels out of the ratio (a single busy
run over a single quiet one carries it whole).  Each run prints its time to solution,
steps, cell-steps per second (whole mesh, and cells holding material; none for the
control), threads and the cores it got; each setting prints the check of its runs (the
problem's own: mass and front, the Bagnold profile, the control's geometric sum), which
the thread count and the busy process must leave unchanged to the last digit.
``--repeat N`` does it all N times and ends with the median and the range of each ratio.

    python benchmarks/threads.py [--problems dam_break chute parallel_limit] [--settings 1 2 auto]
                                  [--repeat 1]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
PROBLEMS = ("dam_break", "chute", "parallel_limit")


@dataclass
class Run:
    """One run of a benchmark script, as it printed it."""

    seconds: float  # time to solution
    steps: int
    rates: str  # cell-steps per second, whole mesh and cells holding material ("" for the control)
    used: str  # the thread counts and the cores it got
    check: str  # the physical check of the answer


def time_to_solution(problem: str, threads: str) -> Run:
    """One run of ``benchmarks/PROBLEM.py --threads THREADS`` in a fresh process."""
    out = subprocess.run(
        [sys.executable, str(HERE / f"{problem}.py"), "--threads", threads],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    timing = re.search(r"time to solution ([0-9.]+) s \(CPU ([0-9.]+) s\), steps ([0-9]+)", out)
    rates = re.search(r"cell-steps/s: ([0-9.]+ M) \(whole mesh\), ([0-9.]+ M) \(cells holding", out)
    check = re.search(r"^check: (.*)$", out, re.M)
    if timing is None or check is None:
        raise RuntimeError(f"{problem}.py printed no time to solution or check:\n{out}")
    seconds, cpu = float(timing.group(1)), float(timing.group(2))
    used = re.search(r"threads: (.*?)(?: \(a step|;)", out)
    return Run(
        seconds,
        int(timing.group(3)),
        f", {rates.group(1)} / {rates.group(2)} cell-steps/s" if rates else "",
        f"{used.group(1) if used else '?'}; {cpu / seconds:.2f} cores",
        check.group(1),
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=list(PROBLEMS), choices=PROBLEMS)
    parser.add_argument("--settings", nargs="+", default=["1", "2", "auto"])
    parser.add_argument("--repeat", type=int, default=1, help="times to do it all (default 1)")
    args = parser.parse_args()
    if args.repeat < 1:
        parser.error("--repeat takes an integer >= 1")
    print(f"cores available: {len(os.sched_getaffinity(0))}")
    ratios: dict[tuple[str, str], list[float]] = {}
    for _ in range(args.repeat):
        for problem in args.problems:
            compare(problem, args.settings, ratios)
    if args.repeat > 1:
        for (problem, setting), values in ratios.items():
            listed = ", ".join(f"{r:.2f}" for r in values)
            print(
                f"{problem:14s} threads {setting:>4}: beside one busy process, median "
                f"{statistics.median(values):.2f} x quiet, {min(values):.2f}-{max(values):.2f} ({listed})"
            )


def compare(problem: str, settings: list[str], ratios: dict[tuple[str, str], list[float]]) -> None:
    """Each setting quiet, busy, busy, quiet (module docstring); appends the ratios."""
    quiet_mean: dict[str, float] = {}
    busy_mean: dict[str, float] = {}
    for setting in settings:
        quiet: list[float] = []
        busy: list[float] = []
        checks = []
        for beside in (False, True, True, False):
            run, load = timed_run(problem, setting, beside)
            (busy if beside else quiet).append(run.seconds)
            checks.append(run.check)
            where = "beside one busy process" if beside else "quiet"
            print(
                f"{problem:14s} threads {setting:>4}: {where:23s} {run.seconds:7.2f} s, {run.steps} steps"
                f"{run.rates} (load {load:.2f}; threads {run.used})",
                flush=True,
            )
        same = "the same in the four runs" if len(set(checks)) == 1 else "DIFFERS between the runs"
        for check in dict.fromkeys(checks):
            print(f"{problem:14s} threads {setting:>4}: check ({same}): {check}", flush=True)
        quiet_mean[setting], busy_mean[setting] = statistics.mean(quiet), statistics.mean(busy)
        ratio = busy_mean[setting] / quiet_mean[setting]
        ratios.setdefault((problem, setting), []).append(ratio)
        print(f"{problem:14s} threads {setting:>4}: beside one busy process {ratio:.2f} x quiet", flush=True)
    fastest = min(quiet_mean, key=quiet_mean.__getitem__)
    print(
        f"{problem:14s} beside one busy process, over the fastest quiet setting ({fastest}): "
        + ", ".join(f"threads {s} {busy_mean[s] / quiet_mean[fastest]:.2f}" for s in settings),
        flush=True,
    )


def timed_run(problem: str, setting: str, beside_busy: bool) -> tuple[Run, float]:
    """:func:`time_to_solution`, beside a busy process started for it if ``beside_busy``,
    and the load average at its start."""
    busy = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if beside_busy else None
    try:
        load = os.getloadavg()[0]
        run = time_to_solution(problem, setting)
    finally:
        if busy is not None:
            busy.kill()
            busy.wait()
    return run, load


if __name__ == "__main__":
    main()
