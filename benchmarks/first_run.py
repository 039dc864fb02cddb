"""Benchmark: the first run after installation, which compiles the numba kernels, against the next.

Runs ``multilayer run SCENARIO`` twice, each in a fresh process with numba's cache in a
new temporary directory (``NUMBA_CACHE_DIR``, so the installation's own cache is neither
used nor touched): the first run compiles the kernels it uses and caches them, the
second loads them.  Prints the wall and CPU time of each (the whole command: Python's
start, the imports, the run, the result file) and their difference, the compilation.
The default scenario is the README's.  ``--set`` is passed on to ``multilayer run``
(``--set numerics.threads=2`` compiles the parallel kernels too, on a large enough mesh).

    python benchmarks/first_run.py [SCENARIO.yaml] [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


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
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as out:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}
        command = [sys.executable, "-m", "multilayer", "run", str(args.scenario), "-q"]
        command += [f"--set={override}" for override in args.overrides]
        times = {}
        for name in ("first (compiles the kernels)", "second (loads them)"):
            directory = Path(out) / name.split()[0]
            times[name] = timed_command([*command, "-o", str(directory)], env)
            print(f"{name:30s} wall {times[name][0]:6.1f} s, CPU {times[name][1]:6.1f} s", flush=True)
    (wall1, cpu1), (wall2, cpu2) = times.values()
    print(f"{'compilation':30s} wall {wall1 - wall2:6.1f} s, CPU {cpu1 - cpu2:6.1f} s")


if __name__ == "__main__":
    main()
