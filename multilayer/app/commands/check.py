"""Run scenario files and compare their results with their `expect:` lists.

Each file is validated first (exit 2 if any is invalid or has no `expect:` entry), then
run quietly into a temporary directory (or DIR/<name> with -o) at the resolution written
in the file.  One table per file shows, for each entry, its kind (regression: a value
pinned from the code's own output; reference: an exact or published value, whose source
is printed under the table), expected vs obtained values and the verdict; the exit code is
1 if any expectation fails or any run fails, 0 if all pass.
Example: multilayer check scenarios/*.yaml
"""

from __future__ import annotations

import argparse
from pathlib import Path

from multilayer import scenario as scenarios
from multilayer.app import expectations as expect
from multilayer.app.commands import directory, file_path
from multilayer.errors import InputError, RunError, printable, to_stderr
from multilayer.io.disk import writable_directory

HELP = "run scenario files and check their expect: lists (regression pins and reference values)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer check``."""
    parser.add_argument(
        "files", metavar="FILE", nargs="+", type=file_path, help="scenario YAML files with expect:"
    )
    parser.add_argument(
        "-o",
        "--output",
        metavar="DIR",
        type=directory,
        help="keep the results in DIR/<scenario name> (default: a temporary directory, removed afterwards)",
    )


def main(args: argparse.Namespace) -> int:
    """Validate all files, then run and check each one."""
    loaded, errors = [], []
    named: dict[str, str] = {}  # with -o, the file of each name: DIR/<name> is its results
    for path in args.files:
        try:
            scenario = scenarios.load(path)
            if args.output is not None:  # a link there had the run written into its target
                writable_directory(args.output / scenario.name, make=False)
        except InputError as exc:
            errors.append(str(exc))
            continue
        first = named.setdefault(scenario.name, path)
        if args.output is not None and Path(first).resolve() != Path(path).resolve():
            errors.append(  # the second run replaced the first's results, silently
                f"{path}: name: {scenario.name!r}, the name of {first} too: its results "
                f"{args.output / scenario.name} would replace the other's; accepted: files of distinct "
                "names with -o"
            )
            continue
        if not scenario.expect:
            errors.append(
                f"{path}: expect: no expectations to check; accepted: a scenario "
                "with a non-empty expect list of {kind, quantity, value, rtol, atol, source}"
            )
            continue
        loaded.append(scenario)
    if errors:
        for message in errors:
            to_stderr(f"multilayer: error: {message}")
        return 2
    from multilayer.plugins.host import printing_to_stderr

    failed = 0
    for scenario in loaded:
        outdir = None if args.output is None else args.output / scenario.name
        try:
            with printing_to_stderr():  # the report is stdout's: what a law prints as it runs is not
                outcomes = expect.check(scenario, outdir)
        except RunError as exc:
            print(printable(f"{scenario.source}: run failed: {exc}"))
            failed += 1
            continue
        print(printable(f"{scenario.source}: " + expect.report(scenario.name, outcomes)), flush=True)
        failed += not all(o.passed for o in outcomes)
    return 1 if failed else 0
