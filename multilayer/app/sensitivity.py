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

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from multilayer.app.ensemble import NOT_RUN, Ensemble, Evaluation
from multilayer.errors import InputError
from multilayer.io.disk import write_whole
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


MAX_AB_CORRELATION = 0.2
"""Largest accepted correlation between a parameter's columns of the matrices A and B."""


def sample(study: Sensitivity) -> np.ndarray:
    """The Saltelli sample, shape (N (D + 2), D), in the order A, AB_1 .. AB_D, B per base
    sample.

    The estimators assume the base matrices A and B independent.  They are the two halves
    of a 2D-dimensional Sobol' point set, and for few points some pairs of its dimensions
    are strongly correlated (with 5 parameters: |r| up to 0.93 at N = 16, 0.13 at N = 32;
    the indices then do not even add up to 1).  An :class:`InputError` naming ``samples``
    is raised when a correlation exceeds :data:`MAX_AB_CORRELATION`.
    """
    from SALib.sample import sobol

    n, names = study.config.samples, list(study.config.parameters)
    problem = _problem(study)
    points = sobol.sample(problem, n, calc_second_order=False, scramble=True, seed=study.config.seed)
    # in the unit cube (a range 1e-300 wide made the variances 0: a correlation 0/0, NaN,
    # which passed the check with a numpy warning); a constant column counts as correlated
    lower, upper = np.array(problem["bounds"], dtype=float).T
    blocks = ((points - lower) / (upper - lower)).reshape(n, len(names) + 2, len(names))
    with np.errstate(all="ignore"):
        r = [abs(np.corrcoef(blocks[:, 0, j], blocks[:, -1, j])[0, 1]) for j in range(len(names))]
    r = [value if np.isfinite(value) else 1.0 for value in r]
    worst = int(np.argmax(r))
    if r[worst] > MAX_AB_CORRELATION:
        raise InputError(
            f"{study.path}: samples: with {n} base samples the two halves of the Sobol' design are "
            f"correlated (|r| = {r[worst]:.2f} for {names[worst]}), which biases the indices; "
            f"accepted: a larger power of 2 (correlation <= {MAX_AB_CORRELATION})"
        )
    return points


def run(
    study: Sensitivity, ensemble: Ensemble, report: Callable[[str], None], points: np.ndarray
) -> list[Evaluation]:
    """Evaluate every point of the sample ``points`` (:func:`sample`)."""
    names = list(study.config.parameters)
    measure = Measure(tuple((q, (), None) for q in study.config.outputs))
    report(f"sensitivity: {len(points)} runs ({study.config.samples} base samples x ({len(names)} + 2))")
    evaluations = ensemble.evaluate(
        [{n: float(v) for n, v in zip(names, row)} for row in points], [measure] * len(points)
    )
    return evaluations


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
    study: Sensitivity,
    points: np.ndarray,
    evaluations: Sequence[Evaluation | None],
    result: Indices | None,
    path: Path,
) -> None:
    """Write ``sensitivity.nc``: every run (parameters, outputs, status) and the indices.

    An evaluation None is a run not done (an interrupted study): status ``not run``.  The
    file is replaced atomically (written next to it, then renamed).
    """
    import xarray as xr

    names, outputs = list(study.config.parameters), list(study.config.outputs)
    missing = np.full(len(outputs), np.nan)
    values = np.array(
        [e.measured if e is not None and e.measured is not None else missing for e in evaluations]
    ).reshape(len(evaluations), len(outputs))
    nan = np.full((len(outputs), len(names)), np.nan)
    result = result or Indices(nan, nan, nan, nan)
    dims = ("output", "parameter")
    ds = xr.Dataset(
        {
            "lower": ("parameter", [p.bounds[0] for p in study.config.parameters.values()]),
            "upper": ("parameter", [p.bounds[1] for p in study.config.parameters.values()]),
            "sample": (("run", "parameter"), points, {"long_name": "parameter values of every run"}),
            "value": (("run", "output"), values, {"long_name": "output of every run (SI; nan: failed)"}),
            "status": ("run", np.array([e.status if e else NOT_RUN for e in evaluations], dtype=object)),
            "member": ("run", np.array([e.id if e else "" for e in evaluations], dtype=object)),
            "error": ("run", np.array([e.error if e else "" for e in evaluations], dtype=object)),
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
            "failed_runs": int(sum(e is not None and e.status != "ok" for e in evaluations)),
            "runs_not_done": int(sum(e is None for e in evaluations)),
            "sensitivity": study.path.read_text(encoding="utf-8"),
        },
    )
    write_whole(path, ds.to_netcdf)
