"""Benchmark: the first run after installation, which compiles the numba kernels, against the next.

Runs ``multilayer run SCENARIO`` twice, each in a fresh process with numba's cache in a
new temporary directory (``NUMBA_CACHE_DIR``, so the installation's own cache is neither
used nor touched): the first run compiles the kernels it uses and caches them, the
second loads them.  Prints the wall and CPU time of each (the whole command: Python's
start, the imports, the run, the result file) and their difference, the compilation.
The default scenario is the README's.  ``--set`` is passed on to ``multilayer run``
(``--set numerics.threads=2`` compiles the parallel kernels too, on a large enough mesh).

``--compile`` runs ``multilayer compile`` (the installation's step that compiles the
kernels ahead, in parallel) into that cache first and prints its wall and CPU time: the
first run then loads the kernels as the second does.

``--kernels`` runs the first one under a listener of numba's compilations and lists the
CPU time numba spent on each function of the engine it compiled, its callees' compilations
excluded (numba compiles a kernel's callees inside it, then optimises them again in it);
the listener sees the run's process only, not the child that compiles the Newton kernel
beside it (``multilayer.app.compilation.compile_ahead``: its CPU time is in the run's),
and ``--json FILE`` writes that list with the times, the commit and the load average.

    python benchmarks/first_run.py [SCENARIO.yaml] [--set KEY=VALUE ...] [--compile] [--kernels [--json FILE]]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

LISTENER = r"""
import json, os, sys, time
from numba.core import event

records, stack = [], []


class Compilations(event.Listener):
    def on_start(self, e):
        d = e.data.get("dispatcher")
        name = f"{d.py_func.__module__}.{d.py_func.__qualname__}" if d is not None else "?"
        stack.append([name, time.process_time(), 0.0])

    def on_end(self, e):
        name, start, callees = stack.pop()
        spent = time.process_time() - start
        if stack:
            stack[-1][2] += spent
        records.append({"function": name, "cpu_s": spent - callees, "nested": len(stack)})


sys.argv = ["multilayer", *sys.argv[2:]]
from multilayer.app.cli import main

with event.install_listener("numba:compile", Compilations()):
    code = main()
json.dump(records, open(os.environ["FIRST_RUN_RECORDS"], "w"))
sys.exit(code)
"""
"""The first run under a listener of numba's compile events (``--kernels``)."""


def timed_command(command: list[str], env: dict[str, str]) -> tuple[float, float]:
    """(wall s, CPU s of the child processes) of ``command``, which must succeed."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        sys.exit(f"{' '.join(command)} failed (exit {done.returncode}):\n{done.stderr}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "scenario", nargs="?", type=Path, default=ROOT / "scenarios" / "erodible_bed_collapse.yaml"
    )
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--compile", action="store_true", help="run 'multilayer compile' first")
    parser.add_argument("--kernels", action="store_true", help="list the compile time of each function")
    parser.add_argument("--json", type=Path, help="with --kernels: write the list and the times there")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        records = Path(out) / "records.json"
        env = {**os.environ, "NUMBA_CACHE_DIR": cache, "FIRST_RUN_RECORDS": str(records)}
        arguments = ["run", str(args.scenario), "-q", *(f"--set={override}" for override in args.overrides)]
        times: dict[str, tuple[float, float]] = {}
        if args.compile:
            ahead = timed_command([sys.executable, "-m", "multilayer", "compile"], env)
            print(f"{'multilayer compile':30s} wall {ahead[0]:6.1f} s, CPU {ahead[1]:6.1f} s", flush=True)
        for name in ("first (compiles the kernels)", "second (loads them)"):
            directory = Path(out) / name.split()[0]
            start = (
                [sys.executable, "-c", LISTENER, "-"]
                if args.kernels and not times
                else [sys.executable, "-m", "multilayer"]
            )
            times[name] = timed_command([*start, *arguments, "-o", str(directory)], env)
            print(f"{name:30s} wall {times[name][0]:6.1f} s, CPU {times[name][1]:6.1f} s", flush=True)
        compiled = json.loads(records.read_text()) if args.kernels else []
    (wall1, cpu1), (wall2, cpu2) = times.values()
    print(f"{'compilation':30s} wall {wall1 - wall2:6.1f} s, CPU {cpu1 - cpu2:6.1f} s")
    if args.kernels:
        report(compiled, args, times)


def report(compiled: list[dict], args: argparse.Namespace, times: dict) -> None:
    """The CPU time numba spent on each function of the engine (callees excluded)."""
    engine = [r for r in compiled if r["function"].startswith("multilayer.")]
    total: dict[str, list] = {}
    for r in compiled:
        entry = total.setdefault(r["function"], [0, 0.0])
        entry[0] += 1
        entry[1] += r["cpu_s"]
    print(f"{len(engine)} compilations of the engine's functions, {len(compiled)} in all")
    for function, (count, cpu) in sorted(total.items(), key=lambda item: -item[1][1])[:15]:
        print(f"{cpu:7.2f} s CPU  {count} x {function}")
    if args.json:
        commit = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
        )
        record = {
            "benchmark": "first_run",
            "scenario": str(args.scenario.name),
            "overrides": args.overrides,
            "commit": commit.stdout.strip(),
            "load_average": os.getloadavg(),
            "runs_wall_cpu_s": times,
            "compilations": compiled,
        }
        args.json.write_text(json.dumps(record, indent=1))


if __name__ == "__main__":
    main()
