"""Batches of runs of one base scenario on Dask, measured and reused across restarts.

Calibration and sensitivity analysis evaluate the model at batches of parameter points
(a generation of the global search, the columns of a finite-difference Jacobian, a
Sobol' sample).  Each point is a member in the sense of :mod:`multilayer.app.sweep`: the
base scenario with dotted-key overrides, run by :func:`sweep.run_member` into
``DIR/members/<id>/`` (``result.nc`` and the completion marker ``member.json``), where
the id is a hash of the overrides.  A member completed by an earlier, interrupted study
is therefore found again and not rerun; one interrupted mid-run continues from its
checkpoint.  A member that is invalid or fails is reported as such, never raised.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from multilayer import scenario
from multilayer.app import stopping, sweep
from multilayer.errors import InputError, Interrupted, RunError, described
from multilayer.io.disk import writable_directory
from multilayer.io.results import RESULT_FILE
from multilayer.scenario import as_overrides

MEMBERS_DIR = "members"

Status = Literal["ok", "invalid", "failed"]
"""What became of a member: measured, rejected by scenario validation, or failed to run or measure."""

NOT_RUN = "not run"
"""The status of a member in the written results of a study interrupted before it ran."""


@dataclass
class Evaluation:
    """One member: its overrides, what became of it and what was measured on it."""

    id: str
    values: dict[str, Any]
    status: Status
    measured: np.ndarray | None = None
    error: str = ""
    reused: bool = False
    """True if an earlier run of the study had completed this member."""


def _run_and_measure(
    member_scenario: scenario.Scenario,
    member_dir: str,
    fingerprint: str,
    overrides: list[str],
    measure: Callable[[Path], np.ndarray],
) -> np.ndarray:
    """On a worker: run the member (see :func:`sweep.run_member`), then measure it."""
    sweep.run_member(member_scenario, member_dir, fingerprint, overrides)
    return _measured(measure, Path(member_dir))


def _measured(measure: Callable[[Path], np.ndarray], member_dir: Path) -> np.ndarray:
    values = np.asarray(measure(member_dir / RESULT_FILE), dtype=float)
    if not np.all(np.isfinite(values)):
        raise RunError(
            f"a measured quantity is not finite ({values.tolist()}), e.g. no front above threshold"
        )
    return values


class Ensemble:
    """Evaluates batches of members of ``base`` on the Dask ``client`` into ``outdir``.

    ``fixed`` overrides apply to every member; ``on_progress(done, to_run)`` is called
    after each member that ran.
    """

    def __init__(
        self,
        base: Path,
        outdir: Path,
        client: Any,
        fixed: dict[str, Any] | None = None,
        on_progress: Callable[[int, int], None] | None = None,
    ) -> None:
        self.base = base
        self.outdir = Path(outdir).resolve() / MEMBERS_DIR
        self.client = client
        self.fixed = dict(fixed or {})
        self.on_progress = on_progress
        self.ran = 0
        self.reused = 0

    def member_id(self, values: dict[str, Any]) -> str:
        """``e-<hash of the overrides>``: the same values give the same directory."""
        return "e-" + sweep.overrides_digest(as_overrides({**self.fixed, **values}))

    def evaluate(
        self, points: list[dict[str, Any]], measure: Sequence[Callable[[Path], np.ndarray]]
    ) -> list[Evaluation]:
        """Run (or reuse) the member of each point and measure it with ``measure[i]``.

        On a stop request (:mod:`multilayer.app.stopping`) the members not finished are
        cancelled and :class:`~multilayer.errors.Interrupted` is raised with the attribute
        ``evaluations``: one :class:`Evaluation` or None (not finished) per point.
        """
        results: list[Evaluation | None] = [None] * len(points)
        try:
            self._evaluate(points, measure, results)
        except Interrupted as exc:
            exc.evaluations = results  # type: ignore[attr-defined]
            raise
        evaluations = [r for r in results if r is not None]
        if len(evaluations) != len(points):
            raise RuntimeError(f"{len(points) - len(evaluations)} point(s) of the batch were not evaluated")
        return evaluations

    def _evaluate(
        self,
        points: list[dict[str, Any]],
        measure: Sequence[Callable[[Path], np.ndarray]],
        results: list[Evaluation | None],
    ) -> None:
        """:meth:`evaluate`, filling ``results`` as the members finish."""
        stopping.StopFile(writable_directory(self.outdir, make=False)).clear()
        pending: dict[str, list[int]] = {}
        submit: list[tuple[str, scenario.Scenario, str, list[str], int]] = []
        for i, values in enumerate(points):
            stopping.check()
            ident = self.member_id(values)
            if ident in pending:  # the same point twice in one batch: run it once
                pending[ident].append(i)
                continue
            overrides = as_overrides({**self.fixed, **values})
            try:
                member_scenario = scenario.load(self.base, overrides)
            except InputError as exc:
                results[i] = Evaluation(ident, values, "invalid", error=str(exc))
                continue
            fingerprint = sweep.scenario_fingerprint(member_scenario)
            member_dir = writable_directory(self.outdir / ident, make=False)  # its run makes it
            if sweep.completed(member_dir, fingerprint) is not None:
                try:
                    results[i] = Evaluation(
                        ident, values, "ok", _measured(measure[i], member_dir), reused=True
                    )
                except Exception as exc:  # noqa: BLE001 - a bad member must not stop the study
                    results[i] = Evaluation(ident, values, "failed", error=described(exc))
                self.reused += 1
                continue
            pending[ident] = [i]
            submit.append((ident, member_scenario, fingerprint, overrides, i))
        if submit:
            futures = {
                self.client.submit(
                    sweep.contained,
                    _run_and_measure,
                    member_scenario,
                    str(self.outdir / ident),
                    fingerprint,
                    overrides,
                    measure[i],
                    key=f"multilayer-{ident}-{os.urandom(4).hex()}",
                    pure=False,
                ): ident
                for ident, member_scenario, fingerprint, overrides, i in submit
            }
            for done, future in enumerate(
                stopping.as_completed(self.client, list(futures), self.outdir), start=1
            ):
                ident, result = futures[future], sweep.result_of(future)
                measured: np.ndarray | None
                status: Status
                if isinstance(result, sweep.Failed):
                    measured, status, error = None, "failed", result.error
                else:
                    measured, status, error = result, "ok", ""
                for i in pending[ident]:
                    results[i] = Evaluation(ident, points[i], status, measured, error)
                self.ran += 1
                if self.on_progress is not None:
                    self.on_progress(done, len(submit))
