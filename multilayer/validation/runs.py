"""The runs of the validation cases: shipped scenarios with ``--set`` overrides, run (or
reused) into a runs directory, and the context a case is evaluated in."""

from __future__ import annotations

import os
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import xarray as xr
import yaml
from matplotlib.figure import Figure

from multilayer.errors import RunError
from multilayer.io.results import RESULT_FILE, decoded, open_result, run_failure
from multilayer.scenario import Scenario
from multilayer.scenario import load as load_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
"""The shipped scenario files, in the source checkout the package is installed from."""


@dataclass(frozen=True)
class Run:
    """One run: a shipped scenario file plus ``--set`` overrides, stored under ``name``."""

    name: str
    scenario: str
    overrides: tuple[str, ...] = ()

    def load(self, directory: Path = SCENARIOS) -> Scenario:
        """The scenario of this run, read from ``directory``."""
        return load_scenario(directory / f"{self.scenario}.yaml", self.overrides)


Results = dict[str, xr.Dataset | str]
"""Run name -> its result, or the message of its failure."""


def _inputs(resolved: str) -> Any:
    """A resolved scenario without its ``expect`` list, which does not change the run."""
    data = yaml.safe_load(resolved) or {}
    data.pop("expect", None)
    return data


def _execute(task: tuple[Run, Path, Path]) -> str | None:
    """Run unless a completed, undamaged result of the same inputs exists in the output
    directory; the failure message if the run fails."""
    from multilayer.app import runner

    run, scenario_dir, outdir = task
    scenario = run.load(scenario_dir)
    path = outdir / RESULT_FILE
    if path.is_file() and run_failure(path) is None:
        with decoded(path, load=False) as ds:
            if _inputs(ds.attrs.get("scenario", "")) == _inputs(scenario.resolved_yaml()):
                return None
    try:
        runner.run(scenario, outdir, quiet=True)
    except RunError as exc:
        return str(exc)
    return None


def default_jobs() -> int:
    """Parallel runs by default: 2, or 1 on a single core."""
    return min(2, os.cpu_count() or 1)


@dataclass
class Context:
    """Where a case reads its scenarios, stores its runs and draws its figures."""

    runs: Path
    """Directory of the runs, one sub-directory per run name (reused while the inputs agree)."""
    scenarios: Path = SCENARIOS
    figures: Path | None = None
    """Directory of the figures; None draws none."""
    figure_link: str = "figures"
    """How the report refers to ``figures`` (relative to the report)."""
    jobs: int = 1
    failures: list[str] = field(default_factory=list)
    """``name: message`` of every run that failed."""

    def load(self, name: str, overrides: Sequence[str] = ()) -> Scenario:
        """A scenario file of ``scenarios`` with ``overrides``."""
        return load_scenario(self.scenarios / f"{name}.yaml", overrides)

    def execute(self, runs: Sequence[Run]) -> Results:
        """Run (or reuse) every run; each name maps to its dataset or its error message."""
        if len({run.name for run in runs}) != len(runs):
            raise ValueError("two runs share a name")
        tasks = [(run, self.scenarios, self.runs / run.name) for run in runs]
        if self.jobs > 1 and len(tasks) > 1:
            with ProcessPoolExecutor(max_workers=self.jobs) as pool:
                errors = list(pool.map(_execute, tasks))
        else:
            errors = [_execute(task) for task in tasks]
        out: Results = {}
        for run, error in zip(runs, errors):
            out[run.name] = error if error else open_result(self.runs / run.name)
            if error:
                self.failures.append(f"{run.name}: {error}")
        return out

    def figure(self, fig: Figure, name: str) -> str:
        """Save ``fig`` as ``validation_<name>.png`` and return its Markdown image link."""
        if self.figures is None:
            return ""
        self.figures.mkdir(parents=True, exist_ok=True)
        fig.savefig(self.figures / f"validation_{name}.png", dpi=110, bbox_inches="tight")
        return f"![{name}]({self.figure_link}/validation_{name}.png)"
