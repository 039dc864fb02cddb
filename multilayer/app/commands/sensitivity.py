"""Sobol' sensitivity indices of scalar outputs with respect to scenario parameters, on Dask.

Saltelli sampling of the parameter box (SALib), one Dask run per sample point, first-order
and total indices with bootstrap confidence intervals. DIR is -o/--output, else the
file's output.directory, else results/<file name>; it receives sensitivity.nc and
members/<id>/. Rerunning the command after an interruption reuses every completed run.
Exit code 1 if a run failed (the indices are then not computed), 2 if the file is
invalid. Needs Dask and SALib (pip install 'multilayer[studies]'). Details: docs/calibration.md.
Example: multilayer sensitivity docs/examples/erodible_sobol.yaml
"""

from __future__ import annotations

import argparse
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

HELP = "Sobol' sensitivity indices of run outputs with respect to scenario parameters, on Dask"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``multilayer sensitivity``."""
    add_study_arguments(parser, "sensitivity")


def main(args: argparse.Namespace) -> int:
    """Validate the file, run the sample, write sensitivity.nc, print the indices."""
    from multilayer.app.factory import check_start
    from multilayer.io.study import load_sensitivity

    require("sensitivity", "dask.distributed", "SALib")
    study = load_sensitivity(args.config, check_start)
    outdir = Path(args.output or study.config.output.directory or Path("results") / study.path.stem)
    from multilayer.app.sensitivity import SENSITIVITY_FILE

    reads = {"the sensitivity file itself": study.path, f"the base scenario of {study.path}": study.base}
    reads.update(base_reads(study.base, study.config.set))
    with study_directory(outdir, reads, SENSITIVITY_FILE, "sensitivity study"):
        return _sensitivity(args, study, outdir)


def _sensitivity(args: argparse.Namespace, study: Any, outdir: Path) -> int:
    """:func:`main` once the directory is held."""
    from multilayer.app import sensitivity
    from multilayer.errors import Interrupted, printable, to_stderr

    path = outdir / sensitivity.SENSITIVITY_FILE
    check_results(args, outdir, path.name, (study.path, "sensitivity"))

    def report(line: str) -> None:
        if not args.quiet:
            print(line, flush=True)

    def progress(done: int, to_run: int) -> None:
        if not args.quiet and (done == to_run or done % max(1, to_run // 20) == 0):
            print(f"sensitivity: {done}/{to_run} runs done", flush=True)

    points = sensitivity.sample(study)  # checked before any cluster starts
    report(f"sensitivity: on {cluster_description(args)}")
    try:
        with study_ensemble(args, study, outdir, progress) as ensemble:
            evaluations = sensitivity.run(study, ensemble, report, points)
    except Interrupted as exc:
        done = getattr(exc, "evaluations", None)
        kept = None
        if done is not None:
            sensitivity.write(study, points, done, None, path)
            finished = sum(e is not None for e in done)
            kept = (
                f": {finished} of {len(done)} runs done, the others cancelled "
                f"(those stopped mid-run continue from their checkpoints); wrote {path} (no indices)"
            )
        report_stop(exc, kept, "sensitivity", args.config, outdir, args)
        raise
    failed = [e for e in evaluations if e.status != "ok"]
    result = None  # the Sobol' estimators need every run
    if not failed:
        import numpy as np

        result = sensitivity.indices(study, np.array([e.measured for e in evaluations]))
    sensitivity.write(study, points, evaluations, result, path)
    runs = f"{ensemble.ran} run(s), {ensemble.reused} reused, {len(failed)} failed"
    print(printable(f"sensitivity: {runs}; wrote {path}"))
    if result is None:
        for e in failed[:5]:
            to_stderr(f"multilayer: member {e.id} {e.status}: {e.error}")
        to_stderr(
            "multilayer: the Sobol' estimators need every run: no indices computed; "
            "fix the failing runs (or narrow the bounds) and rerun the command"
        )
        return 1
    level = round(100 * study.config.confidence)
    for k, output in enumerate(study.config.outputs):
        print(f"  {output}: S1 and ST with {level}% confidence half-widths")
        for j, name in enumerate(study.config.parameters):
            print(
                f"    {name:30s} S1 = {result.s1[k, j]:6.3f} +/- {result.s1_conf[k, j]:.3f}   "
                f"ST = {result.st[k, j]:6.3f} +/- {result.st_conf[k, j]:.3f}"
            )
    return 0
