"""Fit free scenario parameters to observations, with their uncertainty, on Dask.

Global search (differential evolution, one Dask batch per generation), local refinement
(trust-region least squares) and a Laplace covariance at the best fit. DIR is -o/--output,
else the file's output.directory, else results/<calibration file name>; it receives
calibration.nc and members/<id>/ (one run each). Rerunning the same command after an
interruption reuses every completed run. Exit code 2 if the file is invalid or Dask is not
installed (pip install 'multilayer[studies]'), 1 if no run succeeded. Details:
docs/calibration.md.
Example: multilayer calibrate docs/examples/twin.yaml --workers 2
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from multilayer.app.commands import (
    add_study_arguments,
    base_reads,
    check_results,
    cluster_description,
    report_stop,
    require,
    study_directory,
    study_ensemble,
)
from multilayer.app.progress import shown
from multilayer.scenario.files import files_directory

HELP = "fit scenario parameters to observations (global search, refinement, uncertainty) on Dask"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer calibrate``."""
    add_study_arguments(parser, "calibration")


def main(args: argparse.Namespace) -> int:
    """Validate the file, calibrate, write calibration.nc, print the fit."""
    require("calibrate", "dask.distributed")
    from multilayer.app.factory import check_start
    from multilayer.io.study import load_calibration

    plan = load_calibration(args.config, check_start)
    outdir = args.output or plan.config.output.directory or Path("results") / plan.path.stem
    outdir = Path(outdir)
    from multilayer.app.calibration import CALIBRATION_FILE

    reads = {"the calibration file itself": plan.path, f"the base scenario of {plan.path}": plan.base}
    for extra in plan.experiments.values():  # an experiment may read a bed of its own
        reads.update(base_reads(plan.base, {**plan.config.set, **extra}))
    for i, observed in enumerate(plan.data):
        if observed.observation.file is not None:
            reads[f"the file observations.{i}.file of {plan.path}"] = (
                files_directory(plan.path) / observed.observation.file
            )
    with study_directory(outdir, reads, CALIBRATION_FILE, "calibration"):
        return _calibrate(args, plan, outdir)


def _calibrate(args: argparse.Namespace, plan: Any, outdir: Path) -> int:
    """:func:`main` once the directory is held."""
    from multilayer.app import calibration as calibrations
    from multilayer.errors import Interrupted, printable

    live = not args.quiet and shown(None)  # a terminal, not a closed stderr (2>&-)

    def report(line: str) -> None:
        if not args.quiet:
            print(line, flush=True)

    def progress(done: int, to_run: int) -> None:
        if live:  # a self-updating count of the runs of the current batch
            sys.stderr.write(
                f"\rcalibrate: {done}/{to_run} runs of this batch done" + ("\n" if done == to_run else "")
            )
            sys.stderr.flush()

    path = outdir / calibrations.CALIBRATION_FILE
    check_results(args, outdir, path.name, (plan.path, "calibration"))
    report(
        f"calibrate: {len(plan.config.parameters)} parameter(s), {len(plan.experiments)} experiment(s), "
        f"on {cluster_description(args)}"
    )
    calibrator: calibrations.Calibrator | None = None

    def save(state: str) -> None:
        if calibrator is not None:
            calibrations.write(calibrator.snapshot(), calibrator, path, state)

    def batch_done() -> None:  # calibration.nc after every batch: an interruption keeps it
        if calibrator is not None:
            save(f"running: {calibrator.stage} {calibrator.step - 1} done")

    try:
        with study_ensemble(args, plan, outdir, progress) as ensemble:
            calibrator = calibrations.Calibrator(plan, ensemble, report, on_batch=batch_done)
            fit = calibrator.run()
    except Interrupted as exc:
        if live:
            sys.stderr.write("\n")
        kept = None
        if calibrator is not None:
            save(f"interrupted in {calibrator.stage} {calibrator.step}")
            best = calibrator.snapshot()
            kept = (
                f" in {calibrator.stage} {calibrator.step}: {len(best.candidates)} "
                f"parameter set(s) evaluated, best misfit {best.misfit:.6g}; wrote {path}"
            )
        report_stop(exc, kept, "calibrate", args.config, outdir, args)
        raise
    calibrations.write(fit, calibrator, path)
    points = f"{fit.predicted.size} observed point(s)"
    print(printable(f"calibrate: misfit {fit.misfit:.6g} for {points}; wrote {path}"))
    for name, value, sd in zip(fit.names, fit.theta, fit.sigma):
        print(f"  {name} = {value:.6g} +/- {sd:.3g}")
    for note in fit.notes:
        print(f"  note: {note}")
    return 0
