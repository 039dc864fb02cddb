"""Calibration: fit free scenario parameters to observations, with their uncertainty.

The misfit of a parameter vector theta is the Gaussian negative log-posterior (times 2)

    S(theta) = sum_k ((m_k(theta) - d_k) / sigma_k)^2 + sum_j ((theta_j - mu_j) / s_j)^2,

with m_k the model's value of observed point k (:mod:`multilayer.io.observables`), d_k the
observation and sigma_k its standard deviation, and the second sum over the parameters
that have a Gaussian prior N(mu_j, s_j^2) (the others have a uniform prior within their
bounds).  It is minimised in three stages, each a batch of independent runs on Dask:

1. global search: differential evolution (Storn & Price 1997, J. Global Optim. 11;
   :func:`scipy.optimize.differential_evolution`), every generation (population x
   parameters parameter sets, each run once per experiment) evaluated as one batch;
   a parameter set whose run fails gets S = inf and is replaced by the search;
2. local refinement: trust-region reflective least squares on the whitened residuals
   (Branch, Coleman & Li 1999; :func:`scipy.optimize.least_squares`), each Jacobian
   a batch of forward-difference runs;
3. uncertainty: the Laplace (Gauss-Newton) approximation of the posterior at the best
   fit, covariance C = (J^T J)^-1 with J the Jacobian of the whitened residuals from a
   batch of central differences (Tarantola 2005, "Inverse problem theory", eq. 3.51
   linearised).  It is exact for a model linear in theta over +/- a few sigma.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from multilayer.app.ensemble import Ensemble, Evaluation
from multilayer.errors import Interrupted
from multilayer.io.disk import write_whole
from multilayer.io.observables import Measure
from multilayer.io.study import Calibration

CALIBRATION_FILE = "calibration.nc"


class _Failed(Exception):
    """A run of the refinement or uncertainty stage failed."""


@dataclass
class Candidate:
    """One parameter set evaluated: its runs (one per experiment) and its misfit."""

    stage: str
    step: int
    theta: np.ndarray
    evaluations: list[Evaluation]
    misfit: float
    predicted: np.ndarray | None

    @property
    def status(self) -> str:
        bad = [e.status for e in self.evaluations if e.status != "ok"]
        return bad[0] if bad else "ok"


@dataclass
class Fit:
    """The outcome of a calibration."""

    names: list[str]
    theta: np.ndarray
    """Best fit."""
    misfit: float
    predicted: np.ndarray
    covariance: np.ndarray
    """Laplace covariance at the best fit (nan if its runs failed)."""
    search_theta: np.ndarray
    """Best of the global search."""
    candidates: list[Candidate] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def sigma(self) -> np.ndarray:
        """Standard deviations: square roots of the covariance's diagonal."""
        return np.sqrt(np.diag(self.covariance))


class Problem:
    """The observations of a calibration as one vector, and the runs that predict them."""

    def __init__(self, calibration: Calibration) -> None:
        config = calibration.config
        self.names = list(config.parameters)
        self.lower = np.array([p.bounds[0] for p in config.parameters.values()])
        self.upper = np.array([p.bounds[1] for p in config.parameters.values()])
        priors = [p.prior for p in config.parameters.values()]
        self.prior = [(j, p.mean, p.sd) for j, p in enumerate(priors) if p is not None]
        self.experiments = calibration.experiments
        self.observed = np.concatenate([d.value for d in calibration.data])
        self.sigma = np.concatenate([d.sigma for d in calibration.data])
        items: dict[str, list[tuple[str, tuple[float, ...], float | None]]] = {
            e: [] for e in self.experiments
        }
        slots: dict[str, list[int]] = {e: [] for e in self.experiments}
        start = 0
        for d in calibration.data:
            n = len(d.value)
            obs = d.observation
            items[d.experiment].append((obs.quantity, tuple(d.coordinate), obs.time))
            slots[d.experiment].extend(range(start, start + n))
            start += n
        self.measures = {e: Measure(tuple(items[e])) for e in self.experiments}
        self.slots = {e: np.array(slots[e], dtype=int) for e in self.experiments}

    def points(self, theta: np.ndarray) -> list[dict[str, Any]]:
        """The runs of one parameter set: one per experiment."""
        values = {name: float(v) for name, v in zip(self.names, theta)}
        return [{**values, **extra} for extra in self.experiments.values()]

    def residuals(self, predicted: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Whitened residuals: observations, then the Gaussian priors."""
        prior = [(theta[j] - mean) / sd for j, mean, sd in self.prior]
        return np.concatenate([(predicted - self.observed) / self.sigma, prior])


class Calibrator:
    """Runs the three stages of a calibration on an :class:`Ensemble`.

    ``report(line)`` receives one line per batch (progress), ``on_batch()`` is called
    after each batch (to write the results so far, :meth:`snapshot`).
    """

    def __init__(
        self,
        calibration: Calibration,
        ensemble: Ensemble,
        report: Callable[[str], None],
        on_batch: Callable[[], None] | None = None,
    ) -> None:
        self.calibration = calibration
        self.problem = Problem(calibration)
        self.ensemble = ensemble
        self.report = report
        self.on_batch = on_batch
        self.candidates: list[Candidate] = []
        self.stage, self.step = "search", 0
        self.notes: list[str] = []
        self.search_theta: np.ndarray | None = None
        self.covariance: np.ndarray | None = None

    # ----------------------------------------------------------------- batches

    def evaluate(self, thetas: list[np.ndarray]) -> list[Candidate]:
        """Run every parameter set of a batch (all experiments) and score them."""
        problem = self.problem
        points, measures = [], []
        for theta in thetas:
            points += problem.points(theta)
            measures += list(problem.measures.values())
        before = (self.ensemble.ran, self.ensemble.reused)
        n = len(problem.experiments)
        try:
            evaluations: list[Evaluation | None] = list(self.ensemble.evaluate(points, measures))
        except Interrupted as exc:  # keep the parameter sets whose runs all finished
            evaluations = getattr(exc, "evaluations", [])
            self.candidates += self._score(thetas, evaluations, n)
            raise
        batch = self._score(thetas, evaluations, n)
        self.candidates += batch
        ran, reused = self.ensemble.ran - before[0], self.ensemble.reused - before[1]
        failed = sum(c.status != "ok" for c in batch)
        best = min(c.misfit for c in self.candidates)
        self.report(
            f"calibrate: {self.stage} {self.step}: {len(batch)} parameter set(s), {ran} run(s) "
            f"+ {reused} reused, {failed} failed; best misfit so far {best:.6g}"
        )
        self.step += 1
        if self.on_batch is not None:
            self.on_batch()
        return batch

    def _score(
        self, thetas: list[np.ndarray], evaluations: Sequence[Evaluation | None], n: int
    ) -> list[Candidate]:
        """The candidates of the parameter sets whose ``n`` runs (one per experiment) are
        all in ``evaluations``, with their misfits."""
        problem = self.problem
        batch = []
        for k, theta in enumerate(thetas):
            runs = [e for e in evaluations[k * n : (k + 1) * n] if e is not None]
            if len(runs) < n:  # a run of this set not evaluated (interrupted)
                continue
            predicted, misfit = None, math.inf
            if all(e.status == "ok" for e in runs):
                predicted = np.empty_like(problem.observed)
                for e, experiment in zip(runs, problem.experiments):
                    predicted[problem.slots[experiment]] = e.measured
                misfit = float(np.sum(problem.residuals(predicted, theta) ** 2))
            batch.append(
                Candidate(self.stage, self.step, np.array(theta, dtype=float), list(runs), misfit, predicted)
            )
        return batch

    def _map(self, func: Callable, thetas: Any) -> list[float]:
        """The ``workers`` map of differential evolution: one generation, one batch."""
        return [c.misfit for c in self.evaluate([np.asarray(t) for t in thetas])]

    def _one(self, theta: np.ndarray) -> float:
        return self.evaluate([theta])[0].misfit

    def _whitened(self, theta: np.ndarray) -> np.ndarray:
        return self._residuals(self.evaluate([theta])[0])

    def _residuals(self, candidate: Candidate) -> np.ndarray:
        """Whitened residuals of an evaluated candidate; _Failed if one of its runs failed."""
        if candidate.predicted is None:
            raise _Failed(f"the run at {self._text(candidate.theta)} failed: {self._error(candidate)}")
        return self.problem.residuals(candidate.predicted, candidate.theta)

    def _steps(self) -> np.ndarray:
        return self.calibration.config.refine.step * (self.problem.upper - self.problem.lower)

    def _jacobian(self, theta: np.ndarray, central: bool) -> np.ndarray:
        """Finite-difference Jacobian of the whitened residuals: one batch of runs."""
        lo, hi = self.problem.lower, self.problem.upper
        steps = self._steps()
        thetas, signs = [], []
        for j in range(theta.size):
            e = np.zeros_like(theta)
            e[j] = steps[j]
            sign = -1.0 if theta[j] + steps[j] > hi[j] else 1.0  # stay within the bounds
            if central and theta[j] - steps[j] >= lo[j] and theta[j] + steps[j] <= hi[j]:
                thetas += [theta + e, theta - e]
                signs.append(0.0)
            else:
                thetas += [theta + sign * e]
                signs.append(sign)
        batch = self.evaluate(thetas)
        failed = [c for c in batch if c.predicted is None]
        if failed:
            raise _Failed(f"the run at {self._text(failed[0].theta)} failed: {self._error(failed[0])}")
        base = None
        columns, k = [], 0
        for j, sign in enumerate(signs):
            if sign == 0.0:
                up, down = batch[k], batch[k + 1]
                k += 2
                columns.append((self._residuals(up) - self._residuals(down)) / (2 * steps[j]))
            else:
                if base is None:
                    base = self._whitened(theta)
                c = batch[k]
                k += 1
                columns.append((self._residuals(c) - base) / (sign * steps[j]))
        return np.column_stack(columns)

    # ----------------------------------------------------------------- stages

    def run(self) -> Fit:
        """Search, refine, estimate the uncertainty; returns the :class:`Fit`."""
        from scipy.optimize import differential_evolution, least_squares

        config, problem, notes = self.calibration.config, self.problem, self.notes
        self.stage, self.step = "search", 0
        with warnings.catch_warnings(), np.errstate(invalid="ignore", over="ignore"):
            warnings.simplefilter("ignore", RuntimeWarning)
            result = differential_evolution(
                self._one,
                bounds=list(zip(problem.lower, problem.upper)),
                popsize=config.search.population,
                maxiter=config.search.generations,
                tol=config.search.tolerance,
                seed=config.search.seed,
                init="latinhypercube",
                polish=False,
                updating="deferred",
                workers=self._map,
            )
        best = self._best()
        if not math.isfinite(best.misfit):
            raise _no_fit(self.candidates, self.calibration, problem)
        indistinct = _indistinct(self.candidates, self.calibration, problem)
        if indistinct is not None:
            raise indistinct
        self.search_theta = best.theta.copy()
        notes.append(f"global search: {result.nit} generation(s), {result.message}")

        if config.refine.evaluations:
            self.stage, self.step = "refine", 0
            try:
                refined = least_squares(
                    self._whitened,
                    best.theta,
                    jac=lambda theta: self._jacobian(np.asarray(theta), central=False),
                    bounds=(problem.lower, problem.upper),
                    x_scale=problem.upper - problem.lower,
                    method="trf",
                    max_nfev=config.refine.evaluations,
                )
                notes.append(f"refinement: {refined.nfev} evaluation(s), {refined.message}")
            except _Failed as exc:
                notes.append(f"refinement stopped: {exc}; the best parameter set so far is kept")
        best = self._best()

        self.stage, self.step = "uncertainty", 0
        try:
            jac = self._jacobian(best.theta, central=True)
            information = jac.T @ jac
            self.covariance = np.linalg.pinv(information)
            condition = np.linalg.cond(information)
            if condition > 1e12:
                notes.append(
                    f"the observations hardly constrain some combination of parameters "
                    f"(condition number of J^T J: {condition:.3g}); the covariance is a pseudo-inverse"
                )
        except _Failed as exc:
            notes.append(f"no uncertainty: {exc}")
        best = self._best()  # a central-difference run may have been better still
        at_bound = [
            name
            for name, value, lo, hi, step in zip(
                problem.names, best.theta, problem.lower, problem.upper, self._steps()
            )
            if value - lo < step or hi - value < step
        ]
        if at_bound:
            notes.append(
                f"{', '.join(at_bound)} at a bound: the posterior is cut there, so the Gaussian (Laplace) "
                "standard deviation does not describe it; widen the bounds if they are not physical limits"
            )
        if best.predicted is None:  # the search found a finite misfit, which only a prediction has
            raise RuntimeError(f"the best parameter set {self._text(best.theta)} has no prediction")
        return self.snapshot()

    def snapshot(self) -> Fit:
        """The calibration so far: the best parameter set evaluated (nan if none succeeded),
        the covariance once the uncertainty stage has computed it (else nan)."""
        n = len(self.problem.names)
        if self.candidates:
            best = self._best()
            theta, misfit, predicted = best.theta, best.misfit, best.predicted
        else:
            theta, misfit, predicted = np.full(n, np.nan), math.inf, None
        return Fit(
            names=self.problem.names,
            theta=theta,
            misfit=misfit,
            predicted=np.full(self.problem.observed.size, np.nan) if predicted is None else predicted,
            covariance=np.full((n, n), np.nan) if self.covariance is None else self.covariance,
            search_theta=theta if self.search_theta is None else self.search_theta,
            candidates=self.candidates,
            notes=list(self.notes),
        )

    def _best(self) -> Candidate:
        return min(self.candidates, key=lambda c: c.misfit)

    def _text(self, theta: np.ndarray) -> str:
        return ", ".join(f"{n} = {v:.6g}" for n, v in zip(self.problem.names, theta))

    @staticmethod
    def _error(candidate: Candidate) -> str:
        return next((e.error for e in candidate.evaluations if e.status != "ok"), "")


def _no_fit(candidates: list[Candidate], calibration: Calibration, problem: Problem) -> Exception:
    """Why no parameter set has a finite misfit: its runs failed, or, where every run of a set
    completed, the sum of squared whitened residuals overflowed (uncertainties of 1e-200 m
    made it infinite, and the message said that every set had failed, with no error)."""
    from multilayer.errors import InputError, RunError

    scored = [c for c in candidates if c.predicted is not None]
    if scored:
        smallest = int(np.argmin(problem.sigma))
        priors = [f"{problem.names[j]}: sd {sd:g}" for j, _, sd in problem.prior]
        return InputError(
            f"{calibration.path}: observations: the misfit of every parameter set whose runs completed "
            f"({len(scored)} of {len(candidates)}) is {scored[0].misfit}: the squares of (model - observed) "
            f"/ sigma overflow, the smallest sigma being {problem.sigma[smallest]:.3g} (SI)"
            + (f" and the priors' {', '.join(priors)}" if priors else "")
            + "; accepted: uncertainties (sigma, a prior's sd) for which those squares are finite numbers"
        )
    errors = {Calibrator._error(c) for c in candidates}
    return RunError(
        f"every one of the {len(candidates)} parameter sets failed; first errors: "
        + "; ".join(sorted(errors)[:3])
    )


def _indistinct(candidates: list[Candidate], calibration: Calibration, problem: Problem) -> Exception | None:
    """Why the misfit of the search picks no parameter set, where every parameter set
    whose runs completed (two or more) has the same misfit: the best fit would be
    whichever came first, an arbitrary member, reported as a fit.  The misfits are
    checked rather than each sigma: a sigma of 1e300 on one observation among others is
    that observation weighing nothing, the limit of an infinite uncertainty, and the
    other observations still pick the fit; a bound on sigma alone cannot tell, since
    whether ((model - observed) / sigma)^2 underflows depends on the residuals too.
    Where the predictions differ, the squares underflowed (observations of sigma 1e300
    gave a misfit of 0 everywhere) and the largest sigma is named; where they do not,
    the model gives the same values at every parameter set and the observations
    constrain none of them.  None where the misfits differ."""
    from multilayer.errors import InputError

    scored = [c for c in candidates if c.predicted is not None and math.isfinite(c.misfit)]
    distinct = {tuple(c.theta) for c in scored}
    if len(distinct) < 2 or len({c.misfit for c in scored}) > 1:
        return None
    first = scored[0]
    predictions = [c.predicted for c in scored if c.predicted is not None]
    where = f"{calibration.path}: observations: the misfit of every parameter set whose runs completed"
    count = f"({len(scored)} of {len(candidates)}) is {first.misfit}"
    if any(not np.array_equal(p, predictions[0]) for p in predictions):
        largest = int(np.argmax(problem.sigma))
        return InputError(
            f"{where} {count}, though their predictions differ: the squares of (model - observed) / sigma "
            f"underflow, the largest sigma being {problem.sigma[largest]:.3g} (SI), and no parameter set "
            "fits better than another; accepted: uncertainties (sigma) for which those squares are "
            "numbers that tell the parameter sets apart"
        )
    return InputError(
        f"{where} {count}: the model gives the same values at every parameter set, so the observations "
        f"do not constrain {', '.join(problem.names)} and no parameter set fits better than another; "
        "accepted: observations of quantities the parameters change"
    )


def _strings(values: Sequence[str]) -> np.ndarray:
    """Variable-length strings for netCDF."""
    return np.array(values, dtype=object)


def write(fit: Fit, calibrator: Calibrator, path: Path, progress: str = "complete") -> None:
    """Write ``calibration.nc``: every parameter set evaluated, the best fit, its
    covariance and the observed against fitted points (docs/calibration.md).

    ``progress`` (an attribute) says how far the calibration got: ``complete``, or the
    last batch done while it runs or after it was interrupted.  The file is replaced
    atomically (written next to it, then renamed), so a reader never sees half of one.
    """
    import xarray as xr

    problem, calibration = calibrator.problem, calibrator.calibration
    candidates = fit.candidates
    point_obs, point_exp, point_quantity, point_coord, point_time = [], [], [], [], []
    for d in calibration.data:
        n = len(d.value)
        point_obs += [d.observation.name] * n
        point_exp += [d.experiment] * n
        point_quantity += [d.observation.quantity] * n
        point_coord += d.coordinate or [np.nan]
        t = d.observation.time
        point_time += [np.nan if t is None else t] * n
    prior_mean = np.full(len(fit.names), np.nan)
    prior_sd = np.full(len(fit.names), np.nan)
    for j, mean, sd in problem.prior:
        prior_mean[j], prior_sd[j] = mean, sd
    ds = xr.Dataset(
        {
            "lower": ("parameter", problem.lower, {"long_name": "lower bound"}),
            "upper": ("parameter", problem.upper, {"long_name": "upper bound"}),
            "prior_mean": (
                "parameter",
                prior_mean,
                {"long_name": "mean of the Gaussian prior (nan: uniform)"},
            ),
            "prior_sd": ("parameter", prior_sd, {"long_name": "standard deviation of the Gaussian prior"}),
            "best": ("parameter", fit.theta, {"long_name": "best fit (lowest misfit)"}),
            "search_best": ("parameter", fit.search_theta, {"long_name": "best of the global search"}),
            "sd": ("parameter", fit.sigma, {"long_name": "posterior standard deviation (Laplace)"}),
            "covariance": (
                ("parameter", "parameter2"),
                fit.covariance,
                {"long_name": "posterior covariance (Laplace, Gauss-Newton)"},
            ),
            "values": (
                ("candidate", "parameter"),
                np.array([c.theta for c in candidates]).reshape(len(candidates), len(fit.names)),
                {"long_name": "parameter values of every parameter set evaluated"},
            ),
            "misfit": (
                "candidate",
                np.array([c.misfit for c in candidates], dtype=float),
                {"long_name": "sum of squared whitened residuals (inf: a run failed)", "units": "1"},
            ),
            "stage": ("candidate", _strings([c.stage for c in candidates])),
            "step": (
                "candidate",
                np.array([c.step for c in candidates], dtype=int),
                {"long_name": "generation or batch"},
            ),
            "status": ("candidate", _strings([c.status for c in candidates])),
            "members": (
                "candidate",
                _strings([" ".join(e.id for e in c.evaluations) for c in candidates]),
                {"long_name": "member directories under members/, one per experiment"},
            ),
            "error": ("candidate", _strings([Calibrator._error(c) for c in candidates])),
            "observation": ("point", _strings(point_obs)),
            "experiment": ("point", _strings(point_exp)),
            "quantity": ("point", _strings(point_quantity)),
            "coordinate": (
                "point",
                np.array(point_coord),
                {"long_name": "time (s) or x (m); nan for scalars"},
            ),
            "time": ("point", np.array(point_time), {"long_name": "time of a profile (s); nan: final"}),
            "observed": ("point", problem.observed, {"long_name": "observed value (SI)"}),
            "observed_sd": ("point", problem.sigma, {"long_name": "its standard deviation (SI)"}),
            "fitted": ("point", fit.predicted, {"long_name": "model value at the best fit (SI)"}),
        },
        coords={"parameter": fit.names, "parameter2": fit.names},
        attrs={
            "title": f"multilayer calibration: {calibration.path}",
            "progress": progress,
            "misfit": fit.misfit,
            "points": int(problem.observed.size),
            "degrees_of_freedom": int(problem.observed.size - len(fit.names)),
            "runs": calibrator.ensemble.ran,
            "reused_runs": calibrator.ensemble.reused,
            "failed_parameter_sets": int(sum(c.status != "ok" for c in candidates)),
            "notes": "\n".join(fit.notes),
            "calibration": calibration.path.read_text(encoding="utf-8"),
        },
    )
    write_whole(path, ds.to_netcdf)
