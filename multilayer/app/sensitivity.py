"""Variance-based (Sobol') sensitivity indices of scalar outputs on a Dask ensemble.

The parameters are taken independent and uniform within their bounds.  The sample is
Saltelli's scheme on a scrambled Sobol' sequence (Saltelli et al. 2010, Comput. Phys.
Commun. 181; SALib's ``sobol`` sampler): N base points give N (D + 2) runs for D
parameters.  First-order indices S1 use the estimator of Saltelli et al. (2010, table 2,
eq. (b)), total indices ST Jansen's (1999, ibid. eq. (f)); their confidence intervals are
bootstrap percentile intervals over the N base points (SALib ``sobol.analyze``;
Herman & Usher 2017, J. Open Source Softw. 2).  Runs are members of an
:class:`~multilayer.app.ensemble.Ensemble`, so an interrupted study resumes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from multilayer.app.ensemble import Ensemble, Evaluation
from multilayer.io.observables import Measure
from multilayer.io.study import Sensitivity

SENSITIVITY_FILE = "sensitivity.nc"
BOOTSTRAP_RESAMPLES = 1000


@dataclass
class Indices:
    """Sobol' indices: arrays of shape (outputs, parameters) with their half-widths."""

    s1: np.ndarray
    s1_conf: np.ndarray
    st: np.ndarray
    st_conf: np.ndarray


def _problem(study: Sensitivity) -> dict:
    params = study.config.parameters
    return {"num_vars": len(params), "names": list(params), "bounds": [p.bounds for p in params.values()]}


def sample(study: Sensitivity) -> np.ndarray:
    """The Saltelli sample, shape (N (D + 2), D)."""
    from SALib.sample import sobol

    return sobol.sample(
        _problem(study), study.config.samples, calc_second_order=False, scramble=True, seed=study.config.seed
    )


def run(
    study: Sensitivity, ensemble: Ensemble, report: Callable[[str], None]
) -> tuple[np.ndarray, list[Evaluation]]:
    """Evaluate every sample point; returns the sample and the evaluations."""
    points = sample(study)
    names = list(study.config.parameters)
    measure = Measure(tuple((q, (), None) for q in study.config.outputs))
    report(f"sensitivity: {len(points)} runs ({study.config.samples} base samples x ({len(names)} + 2))")
    evaluations = ensemble.evaluate(
        [{n: float(v) for n, v in zip(names, row)} for row in points], [measure] * len(points)
    )
    return points, evaluations


def indices(study: Sensitivity, outputs: np.ndarray) -> Indices:
    """S1 and ST of each output column, with bootstrap confidence half-widths."""
    from SALib.analyze import sobol

    rows = []
    for y in outputs.T:
        result = sobol.analyze(
            _problem(study),
            y,
            calc_second_order=False,
            num_resamples=BOOTSTRAP_RESAMPLES,
            conf_level=study.config.confidence,
            seed=study.config.seed,
        )
        rows.append([result[k] for k in ("S1", "S1_conf", "ST", "ST_conf")])
    s1, s1c, st, stc = (np.array([r[i] for r in rows]) for i in range(4))
    return Indices(s1, s1c, st, stc)


def write(
    study: Sensitivity, points: np.ndarray, evaluations: list[Evaluation], result: Indices | None, path: Path
) -> None:
    """Write ``sensitivity.nc``: every run (parameters, outputs, status) and the indices."""
    import xarray as xr

    names, outputs = list(study.config.parameters), list(study.config.outputs)
    values = np.array(
        [e.measured if e.measured is not None else np.full(len(outputs), np.nan) for e in evaluations]
    )
    nan = np.full((len(outputs), len(names)), np.nan)
    result = result or Indices(nan, nan, nan, nan)
    dims = ("output", "parameter")
    ds = xr.Dataset(
        {
            "lower": ("parameter", [p.bounds[0] for p in study.config.parameters.values()]),
            "upper": ("parameter", [p.bounds[1] for p in study.config.parameters.values()]),
            "sample": (("run", "parameter"), points, {"long_name": "parameter values of every run"}),
            "value": (("run", "output"), values, {"long_name": "output of every run (SI; nan: failed)"}),
            "status": ("run", np.array([e.status for e in evaluations], dtype=object)),
            "member": ("run", np.array([e.id for e in evaluations], dtype=object)),
            "error": ("run", np.array([e.error for e in evaluations], dtype=object)),
            "S1": (dims, result.s1, {"long_name": "first-order Sobol' index"}),
            "S1_conf": (dims, result.s1_conf, {"long_name": "half-width of the S1 confidence interval"}),
            "ST": (dims, result.st, {"long_name": "total Sobol' index"}),
            "ST_conf": (dims, result.st_conf, {"long_name": "half-width of the ST confidence interval"}),
        },
        coords={"parameter": names, "output": outputs},
        attrs={
            "title": f"multilayer sensitivity: {study.path}",
            "base_samples": study.config.samples,
            "confidence_level": study.config.confidence,
            "bootstrap_resamples": BOOTSTRAP_RESAMPLES,
            "failed_runs": int(sum(e.status != "ok" for e in evaluations)),
            "sensitivity": study.path.read_text(encoding="utf-8"),
        },
    )
    partial = path.with_name(path.name + ".partial")
    ds.to_netcdf(partial)
    partial.replace(path)
