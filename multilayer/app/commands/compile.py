"""Compile the numba kernels of the engine now, in parallel, and cache them.

A step of the installation: without it the first run compiles the kernels it uses
(about a minute of one core) before its first step.  Runs afterwards load them from
numba's cache in well under a second.  Once the kernels are cached this command returns
at once; after an update of multilayer or numba it compiles them again.  The parallel
(threaded) kernels are compiled by the first run with ``numerics.threads`` above 1.
"""

from __future__ import annotations

import argparse
import os

from multilayer.app.commands import positive_int

HELP = "compile the numba kernels now (a step of the installation), in parallel"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--processes",
        type=positive_int,
        default=None,
        metavar="N",
        help="child processes compiling at once (default: the cores this process may use)",
    )


def main(args: argparse.Namespace) -> int:
    """Compile; exit 1 naming the tasks that failed, or when numba cannot cache."""
    from multilayer.app.precompile import compile_kernels
    from multilayer.engine.kernel_cache import cache_directories
    from multilayer.errors import to_stderr

    directories = [str(d) for d in cache_directories()]
    if not directories:
        to_stderr(
            "multilayer compile: numba finds no directory it can write its cache to here, so every "
            "run compiles the kernels it uses; set NUMBA_CACHE_DIR to a writable directory"
        )
        return 1

    def waiting() -> None:
        to_stderr("multilayer compile: waiting for another multilayer compile of this cache")

    report = compile_kernels(args.processes, waiting)
    where = os.path.commonpath(directories)
    if report.cached:
        print(f"the kernels are compiled and cached ({where}; {report.checked} cached files checked)")
        return 0
    for name, message in report.failed.items():
        to_stderr(f"multilayer compile: {name} failed: {message}")
    if report.failed:
        return 1
    processes = f"{report.processes} process" + ("es" if report.processes > 1 else "")
    print(f"compiled the kernels in {report.seconds:.1f} s ({processes}); cached in {where}")
    return 0
