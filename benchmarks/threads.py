"""Benchmark: one and two threads, on a quiet machine and beside one CPU-bound process.

Runs benchmarks/dam_break.py (the peer problem, about 10 % of its cells hold material) and
benchmarks/chute.py (fully wet, 1.28 M cells) with ``--threads 1``, ``--threads 2`` and the
default ``auto``, first as they are, then with one competing CPU-bound process (a Python
busy loop started and stopped by this script), each in a fresh process, one after the
other.  Prints the time to solution of each and its ratio to the quiet run with the same
setting: what a user of a shared machine gets.  ``--repeat N`` does it all N times and
ends with the median of each ratio (single ratios spread by a third on a shared machine).

    python benchmarks/threads.py [--problems dam_break chute] [--settings 1 2 auto] [--repeat 1]
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
EXTRA = {"dam_break": [], "chute": ["--steps", "20"]}


def time_to_solution(problem: str, threads: str) -> tuple[float, str]:
    """Wall time of one run, and what it used: the thread counts, whether its threads
    were bound to cores, and its CPU time over its wall time (the cores it got)."""
    out = subprocess.run(
        [sys.executable, str(HERE / f"{problem}.py"), "--threads", threads, *EXTRA[problem]],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    timing = re.search(r"time to solution ([0-9.]+) s \(CPU ([0-9.]+) s\)", out)
    seconds, cpu = float(timing.group(1)), float(timing.group(2))
    used = re.search(r"threads: (.*?) \(a pass", out)
    bound = ", bound to cores" if "threads bound to cores" in out else ""
    return seconds, f"{used.group(1) if used else '?'}{bound}; {cpu / seconds:.2f} cores"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=["dam_break", "chute"], choices=sorted(EXTRA))
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
                f"{problem:10s} threads {setting:>4}: beside one busy process, median "
                f"{statistics.median(values):.2f} x quiet ({listed})"
            )


def compare(problem: str, settings: list[str], ratios: dict[tuple[str, str], list[float]]) -> None:
    """Each setting quiet, then each beside one busy process; appends the ratios."""
    quiet = {}
    for setting in settings:
        load = os.getloadavg()[0]
        quiet[setting], used = time_to_solution(problem, setting)
        print(
            f"{problem:10s} threads {setting:>4}: quiet {quiet[setting]:7.2f} s (load {load:.2f}; "
            f"threads {used})",
            flush=True,
        )
    for setting in settings:
        busy = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        try:
            load = os.getloadavg()[0]
            seconds, used = time_to_solution(problem, setting)
        finally:
            busy.kill()
            busy.wait()
        ratios.setdefault((problem, setting), []).append(seconds / quiet[setting])
        print(
            f"{problem:10s} threads {setting:>4}: beside one busy process {seconds:7.2f} s, "
            f"{seconds / quiet[setting]:.2f} x quiet, {seconds / min(quiet.values()):.2f} x the fastest "
            f"quiet setting (load {load:.2f}; threads {used})",
            flush=True,
        )


if __name__ == "__main__":
    main()
