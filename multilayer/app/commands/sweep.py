"""Run a parameter sweep of a scenario on Dask: DIR/<member>/result.nc and DIR/summary.csv.

The members run on a local Dask cluster (one single-threaded worker process per core, or
--workers N) or, with --scheduler, on a running cluster. DIR is -o/--output, else the
sweep file's output.directory, else results/<sweep file name>. Members completed by an
earlier run are skipped. Exit code 1 if any member is invalid or failed (see
DIR/summary.csv), 2 if the sweep file is invalid or Dask is not installed (pip install
'multilayer[studies]'). Details: docs/sweeps.md.
Example: multilayer sweep friction-sweep.yaml --workers 4
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, TextIO

from multilayer.app import progress
from multilayer.app.commands import (
    add_cluster_arguments,
    add_output_argument,
    add_resume_argument,
    base_reads,
    check_results,
    cluster_description,
    file_path,
    report_stop,
    require,
    study_directory,
)

HELP = "run a parameter sweep of a scenario on Dask (local or existing cluster)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer sweep``."""
    parser.add_argument("sweep", metavar="SWEEP", type=file_path, help="sweep YAML file")
    add_output_argument(parser, "output.directory of the sweep file, else results/<sweep file name>")
    add_cluster_arguments(parser)
    add_resume_argument(parser)
    parser.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="no progress and no summary line (invalid or failed members are still reported)",
    )


class _Report:
    """Start line, ``done / total`` progress line (terminals only) and final report."""

    def __init__(self, where: str, quiet: bool, stream: TextIO | None = None) -> None:
        self.where = where
        self.quiet = quiet
        self.stream = sys.stderr if stream is None else stream
        self.live = not quiet and progress.shown(None, self.stream)  # a terminal, not a closed stderr

    def start(self, total: int, skipped: int, invalid: int, to_run: int) -> None:
        if not self.quiet:
            target = f" on {self.where}" if to_run else ""
            print(
                f"sweep: {total} members: {skipped} already complete (skipped), "
                f"{invalid} invalid, {to_run} to run{target}",
                flush=True,
            )
        if to_run:
            self.progress(0, to_run)

    def progress(self, done: int, to_run: int) -> None:
        if self.live:
            self.stream.write(f"\rsweep: {done}/{to_run} members done")
            self.stream.flush()
            if done == to_run:
                self.stream.write("\n")


def main(args: argparse.Namespace) -> int:
    """Validate the sweep and its members, run them, write summary.csv, report."""
    require("sweep", "dask.distributed")
    from multilayer.app import sweep as sweeps  # Dask and the engine are imported only to run

    plan = sweeps.load(args.sweep)
    outdir = Path(args.output or plan.output or Path("results") / plan.path.stem)
    summary = outdir / "summary.csv"
    check_results(args, outdir, summary.name)
    reads = {"the sweep file itself": plan.path, f"the base scenario of {plan.path}": plan.base}
    reads.update(base_reads(plan.base))
    reads.update(sweeps.member_reads(plan))
    with study_directory(outdir, reads, summary.name, "sweep"):
        return _sweep(args, plan, outdir, summary)


def _sweep(args: argparse.Namespace, plan: Any, outdir: Path, summary: Path) -> int:
    """:func:`main` once the directory is held."""
    from multilayer.app import stopping
    from multilayer.app import sweep as sweeps
    from multilayer.errors import Interrupted, printable, to_stderr

    where = cluster_description(args)
    report = _Report(where, args.quiet)
    try:
        with stopping.signals_stop():
            outcomes = sweeps.run(
                plan,
                outdir,
                scheduler=args.scheduler,
                workers=args.workers,
                on_start=report.start,
                on_progress=report.progress,
            )
    except Interrupted as exc:
        if report.live:
            sys.stderr.write("\n")
        done = getattr(exc, "outcomes", None)
        kept = None
        if done is not None:
            sweeps.write_summary(plan, done, summary)
            finished = sum(o.status in ("ok", "failed") for o in done)
            kept = (
                f": {finished} of {len(done)} members complete, the others cancelled "
                f"(those stopped mid-run continue from their checkpoints); wrote {summary}"
            )
        report_stop(exc, kept, "sweep", args.sweep, outdir, args)
        raise
    sweeps.write_summary(plan, outcomes, summary)

    for outcome in outcomes:
        if outcome.status != "ok":
            values = ", ".join(outcome.member.overrides)
            to_stderr(
                printable(
                    f"multilayer: member {outcome.member.id} ({values}) {outcome.status}: {outcome.error}"
                )
            )
    counts = {status: sum(o.status == status for o in outcomes) for status in ("ok", "invalid", "failed")}
    if not args.quiet:
        print(
            printable(
                f"sweep: {counts['ok']} ok, {counts['invalid']} invalid, {counts['failed']} "
                f"failed; wrote {summary}"
            )
        )
    return 1 if counts["invalid"] or counts["failed"] else 0
