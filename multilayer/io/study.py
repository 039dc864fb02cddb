"""Calibration and sensitivity files: free parameters, experiments, observations, outputs.

A calibration file (docs/calibration.md)::

    base: collapse.yaml              # the base scenario, relative to this file
    set: {domain.cells: 100}         # optional: fixed overrides of every run
    parameters:                      # free parameters: dotted scenario keys
      rheology.mu_s: {bounds: [0.3, 0.7]}
      rheology.mu_2: {bounds: [0.5, 1.2], prior: {mean: 0.73, sd: 0.1}}
    experiments:                     # optional: several runs per parameter set
      a1: {initial.0.height: 0.05}
    observations:
      - {name: runout_a1, experiment: a1, quantity: runout, value: 6.0, units: cm, sigma: 0.6}
      - {name: front, quantity: front, file: front.csv, columns: [t, x_f], units: cm, sigma: 0.2}
    search: {population: 8, generations: 15, seed: 1}
    refine: {evaluations: 20}
    output: {directory: results/fit}

A sensitivity file has ``base``, ``set``, ``parameters`` (bounds only), ``outputs`` (scalar
quantities), ``samples``, ``seed`` and ``output``.  Both are validated strictly, with the
messages of scenario files: ``<file>: <key.path> (line N): <what>; accepted: <...>``.
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import numpy as np
from pydantic import BaseModel, Field, ValidationError, field_validator, model_validator

from multilayer import scenario
from multilayer.errors import InputError, reason, shortened, shown
from multilayer.scenario.files import files_directory, read_text, relative_to, why_not_a_file
from multilayer.scenario.limits import MAX_DESIGN_VALUES, MAX_PROFILE_POINTS, MAX_STUDY_RUNS
from multilayer.scenario.loading import load_base
from multilayer.scenario.messages import (
    StrictModel,
    describe,
    directory_path,
    dotted,
    field,
    file_name,
    invalid,
)
from multilayer.scenario.overrides import as_overrides, member_output
from multilayer.scenario.profiles import csv_number

Scalar = Literal["runout", "front_final", "duration", "mass_final"]
"""Scalar quantities measured on a run (multilayer.io.observables)."""
Curve = Literal["front"]
"""Quantities observed against time: the front x_f(t)."""
Profile = Literal["h"]
"""Quantities observed against x at one time: the thickness h(x)."""
Quantity = Literal[Scalar, Curve, Profile]
"""Every observable quantity."""
SCALARS: tuple[str, ...] = get_args(Scalar)
CURVES: tuple[str, ...] = get_args(Curve)
PROFILES: tuple[str, ...] = get_args(Profile)

UNITS: dict[str, float] = {
    "m": 1.0,
    "cm": 1e-2,
    "mm": 1e-3,
    "s": 1.0,
    "ms": 1e-3,
    "m2": 1.0,
    "cm2": 1e-4,
}
"""Accepted units and their factor to SI."""
_DIMENSION = {"m": "m", "cm": "m", "mm": "m", "s": "s", "ms": "s", "m2": "m2", "cm2": "m2"}
_SI = {"runout": "m", "front_final": "m", "duration": "s", "mass_final": "m2", "front": "m", "h": "m"}
_COORDINATE_SI = {"front": "s", "h": "m"}

DottedKey = Annotated[str, Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z0-9_]+)*$")]


class Prior(StrictModel):
    """A Gaussian prior on a free parameter (the default prior is uniform within bounds)."""

    mean: float = field(..., "a number")
    sd: float = field(..., "a number > 0", gt=0)


class Parameter(StrictModel):
    """A free parameter: a scenario key varied within ``bounds``."""

    bounds: Annotated[list[float], Field(min_length=2, max_length=2)] = field(
        ..., "[lower, upper] with lower < upper"
    )
    prior: Prior | None = field(None, "{mean, sd}; default: uniform within bounds")

    @model_validator(mode="after")
    def _check(self) -> Parameter:
        if not self.bounds[0] < self.bounds[1]:
            raise invalid(f"got {self.bounds}", "[lower, upper] with lower < upper", "bounds")
        lower, upper = self.bounds
        if not math.isfinite(upper - lower):  # every point is lower + fraction * width: inf, or 0 * inf = nan
            raise invalid(
                f"got {self.bounds}: the width upper - lower overflows",
                "[lower, upper] with lower < upper less than 1.8e308 apart",
                "bounds",
            )
        prior = self.prior
        if prior is None:
            return self
        if not lower <= prior.mean <= upper:
            # the search never leaves the bounds: the prior held the fit at a bound, as a
            # measurement would, and its uncertainty was the prior's, not the data's
            raise invalid(
                f"{prior.mean!r} outside the bounds [{lower!r}, {upper!r}]",
                "a mean within the bounds",
                "prior.mean",
            )
        spread = (upper - lower) / prior.sd
        if not spread * spread < math.inf:
            # the misfit of almost every parameter set was infinite: found after the search's runs
            smallest = (upper - lower) / math.sqrt(sys.float_info.max)
            raise invalid(
                f"{prior.sd!r}: the prior's square ((theta - mean) / sd)^2 overflows within the bounds "
                f"[{lower!r}, {upper!r}]",
                f"an sd above {smallest:.3g} (the width of the bounds / 1.34e154)",
                "prior.sd",
            )
        return self


class Observation(StrictModel):
    """One observed quantity with its uncertainty (values in ``units``)."""

    name: str = field(..., "a name for the observation", min_length=1)
    quantity: Quantity = field(..., ", ".join(SCALARS + CURVES + PROFILES))
    experiment: str | None = field(None, "a key of experiments (default: the only experiment)")
    value: float | None = field(None, "a number, in units (scalar quantities)")
    file: str | None = field(None, "a CSV or netCDF file, relative to the calibration file")
    columns: Annotated[list[str], Field(min_length=2, max_length=3)] | None = field(
        None, "[coordinate, value] or [coordinate, value, sigma]: CSV column names"
    )
    variable: str | None = field(None, "the name of a one-dimensional netCDF variable")
    units: str | None = field(None, "one of " + ", ".join(UNITS) + " (default SI)")
    coordinate_units: str | None = field(None, "one of " + ", ".join(UNITS) + " (default SI)")
    sigma: float | None = field(None, "a number > 0, in units (or a third CSV column)", gt=0)

    _file = field_validator("file", mode="before")(file_name)
    time: float | None = field(None, "a number >= 0 (s); default: the final time", ge=0)

    @field_validator("units", "coordinate_units")
    @classmethod
    def _unit(cls, value: str | None) -> str | None:
        if value is not None and value not in UNITS:
            raise invalid(f"unknown unit {shown(value)}", ", ".join(UNITS))
        return value

    @field_validator("columns")
    @classmethod
    def _distinct(cls, value: list[str] | None) -> list[str] | None:
        """``[t, t, sigma]`` read the times as the observed values: a fit to them."""
        if value is not None and len(set(value)) < len(value):
            raise invalid(f"a column named twice ({value})", "distinct names: [coordinate, value, sigma]")
        return value

    @model_validator(mode="after")
    def _check(self) -> Observation:
        scalar = self.quantity in SCALARS
        required: tuple[str, ...]
        optional: tuple[str, ...]
        if self.units is not None and _DIMENSION[self.units] != _SI[self.quantity]:
            raise invalid(
                f"{self.units} is not a unit of {self.quantity}",
                ", ".join(u for u, d in _DIMENSION.items() if d == _SI[self.quantity]),
                "units",
            )
        if scalar:
            required, optional = ("value", "sigma"), ("units",)
        elif self.file is not None and self.file.endswith(".nc"):
            required, optional = ("file", "variable"), ("sigma", "units", "coordinate_units")
        else:
            required, optional = ("file", "columns"), ("sigma", "units", "coordinate_units")
        if self.quantity in PROFILES:
            optional += ("time",)
        accepted = ", ".join(("name", "quantity", "experiment", *required, *optional))
        for key in required:
            if getattr(self, key) is None:
                raise invalid(f"quantity {self.quantity} requires {key}", accepted, key)
        extra = sorted(self.model_fields_set - {"name", "quantity", "experiment", *required, *optional})
        if extra:
            raise invalid(f"not a key of quantity {self.quantity}", accepted, extra[0])
        if not scalar and self.sigma is None and (self.columns is None or len(self.columns) < 3):
            raise invalid(
                f"quantity {self.quantity} needs an uncertainty",
                "sigma, or a third column [coordinate, value, sigma]",
                "sigma",
            )
        if self.coordinate_units is not None and _DIMENSION[self.coordinate_units] != _COORDINATE_SI.get(
            self.quantity
        ):
            raise invalid(
                f"{self.coordinate_units} is not a unit of the {self.quantity} coordinate",
                ", ".join(u for u, d in _DIMENSION.items() if d == _COORDINATE_SI[self.quantity]),
                "coordinate_units",
            )
        return self


def _seed() -> Any:
    """The ``seed`` field: a seed of numpy's legacy generator, which scipy's differential
    evolution seeds with it (-1 or 2^32 validated, and the study stopped with numpy's
    ``ValueError`` and a traceback)."""
    return field(1, "an integer from 0 to 4294967295 (2^32 - 1)", ge=0, le=2**32 - 1)


def _check_design(key: str, count: int, parameters: int, extra: int) -> None:
    """A validation error of ``key`` if a design of ``count x (parameters + extra)`` runs of
    ``parameters`` values each holds more than :data:`MAX_DESIGN_VALUES` values."""
    runs = count * (parameters + extra)
    if runs * parameters > MAX_DESIGN_VALUES:
        raise invalid(
            f"{count} x ({parameters} parameters{f' + {extra}' if extra else ''}) = {runs} runs of "
            f"{parameters} values: {runs * parameters * 8 / 2**30:.3g} GiB for the design alone",
            f"at most {MAX_DESIGN_VALUES} values ({MAX_DESIGN_VALUES * 8 // 2**30} GiB): fewer parameters, "
            f"or {key} smaller",
            key,
        )


def _check_runs(key: str, terms: str, runs: int) -> None:
    """A validation error of ``key`` if a study asks for more than :data:`MAX_STUDY_RUNS`
    runs, ``terms`` saying how they are counted."""
    if runs > MAX_STUDY_RUNS:
        raise invalid(
            f"{terms} = {runs:.3g} runs",
            f"a study of at most {MAX_STUDY_RUNS:.0e} runs: fewer parameters, generations or experiments, "
            "or a smaller population",
            key,
        )


class Search(StrictModel):
    """Global search: differential evolution (Storn & Price 1997)."""

    population: int = field(
        8, "an integer from 4 to 10000 (members per generation = population x parameters)", ge=4, le=10_000
    )
    generations: int = field(
        15, "an integer from 0 to 10000 (0: the initial population only)", ge=0, le=10_000
    )
    tolerance: float = field(0.01, "a number >= 0 (relative spread of the misfits to stop at)", ge=0)
    seed: int = _seed()


class Refine(StrictModel):
    """Local refinement: trust-region least squares (scipy least_squares 'trf').

    ``step`` is also the step of the Jacobian of the uncertainty stage.  It must exceed the
    scale of the small-scale roughness of the computed outputs as functions of the
    parameters (discrete time steps, the front crossing cells, solver tolerances): in the
    twin experiment of docs/calibration.md a difference over 0.1 % of the bounds gave
    standard deviations 3.5 times smaller than over 1-3 %, where they settle.
    """

    evaluations: int = field(10, "an integer from 0 to 10000 (0: no refinement)", ge=0, le=10_000)
    step: float = field(
        0.02, "a number in (0, 0.1]: finite-difference step as a fraction of the bounds", gt=0, le=0.1
    )


class StudyOutput(StrictModel):
    """Where results go."""

    directory: str | None = field(None, "a directory path")

    _directory = field_validator("directory")(directory_path)


class _Study(StrictModel):
    base: str = field(..., "the path of a scenario file, relative to this file", min_length=1)
    description: str | None = field(None, "free text")
    set: dict[DottedKey, Any] = field({}, "a mapping of dotted scenario keys to values (fixed overrides)")
    parameters: dict[DottedKey, Parameter] = field(
        ..., "a non-empty mapping of dotted scenario keys to {bounds: [lower, upper]}", min_length=1
    )
    output: StudyOutput = field(StudyOutput(), "a mapping with directory")


class CalibrationModel(_Study):
    """The calibration file as validated; attribute names are the YAML keys."""

    experiments: dict[str, dict[DottedKey, Any]] = field(
        {}, "a mapping of experiment names to mappings of dotted scenario keys to values"
    )
    observations: list[Observation] = field(..., "a non-empty list of {name, quantity, ...}", min_length=1)
    search: Search = field(Search(), "a mapping with population, generations, tolerance, seed")
    refine: Refine = field(Refine(), "a mapping with evaluations, step")

    @model_validator(mode="after")
    def _check(self) -> CalibrationModel:
        _check_design("search.population", self.search.population, len(self.parameters), 0)
        names = list(self.experiments) or ["base"]
        p, search, evaluations = len(self.parameters), self.search, self.refine.evaluations
        _check_runs(
            "search.generations",
            f"{len(names)} experiment(s) x ({search.population} x {p} parameters x "
            f"({search.generations} generations + 1) + {evaluations} evaluations x ({p} + 1) + 2 x {p})",
            len(names) * (search.population * p * (search.generations + 1) + evaluations * (p + 1) + 2 * p),
        )
        seen: set[str] = set()
        for i, obs in enumerate(self.observations):
            if obs.name in seen:
                raise invalid(
                    f"duplicate name {shown(obs.name)}", "a name used once", f"observations.{i}.name"
                )
            seen.add(obs.name)
            if obs.experiment is None and len(names) > 1:
                raise invalid("which experiment?", ", ".join(names), f"observations.{i}.experiment")
            if obs.experiment is not None and obs.experiment not in names:
                raise invalid(
                    f"unknown experiment {shown(obs.experiment)}",
                    ", ".join(names),
                    f"observations.{i}.experiment",
                )
        return self


class SensitivityModel(_Study):
    """The sensitivity file as validated."""

    outputs: list[Scalar] = field(..., "a non-empty list of " + ", ".join(SCALARS), min_length=1)
    samples: int = field(
        16, "a power of 2 from 2 to 65536 (base samples N; runs: N x (parameters + 2))", ge=2, le=65_536
    )
    seed: int = _seed()
    confidence: float = field(0.95, "a number in (0, 1)", gt=0, lt=1)

    @field_validator("outputs")
    @classmethod
    def _once(cls, outputs: list[str]) -> list[str]:
        if len(set(outputs)) < len(outputs):
            twice = next(name for name in outputs if outputs.count(name) > 1)
            raise invalid(f"{twice} twice", "each output once")
        return outputs

    @model_validator(mode="after")
    def _design(self) -> SensitivityModel:
        _check_design("samples", self.samples, len(self.parameters), 2)
        return self

    @field_validator("samples")
    @classmethod
    def _power_of_two(cls, n: int) -> int:
        if n & (n - 1):
            raise invalid(
                f"got {n}", "a power of 2 from 2 to 65536 (Sobol' sequences are balanced at 2^k points)"
            )
        return n


class ObservedData(BaseModel):
    """An observation read and converted to SI: coordinates (s or m, empty for scalars),
    values and their standard deviations."""

    observation: Observation
    experiment: str
    coordinate: list[float]
    value: list[float]
    sigma: list[float]


class Calibration(BaseModel):
    """A validated calibration file with its observations read."""

    path: Path
    base: Path
    config: CalibrationModel
    data: list[ObservedData]

    @property
    def experiments(self) -> dict[str, dict[str, Any]]:
        """Experiment name -> its overrides (``{"base": {}}`` when none are given)."""
        return dict(self.config.experiments) or {"base": {}}


class Sensitivity(BaseModel):
    """A validated sensitivity file."""

    path: Path
    base: Path
    config: SensitivityModel


def _validate(model: type[StrictModel], path: Path, kind: str) -> tuple[Any, dict]:
    data, lines = scenario.read_yaml(path, kind)
    if not isinstance(data, dict):
        raise InputError(
            f"{path}: (top level): got {type(data).__name__}; accepted: a mapping of {kind} keys"
        )
    try:
        return model.model_validate(data), lines
    except ValidationError as exc:
        messages = []
        for error in exc.errors():
            loc, what, accepted = describe(error, model)
            known = [loc[:n] for n in range(len(loc), 0, -1) if loc[:n] in lines]
            place = f" (line {lines[known[0]]})" if known else ""
            tail = f"; accepted: {accepted}" if accepted else ""
            messages.append(f"{path}: {dotted(loc)}{place}: {what}{tail}")
        raise InputError("\n".join(messages)) from None


def _at(path: Path, lines: dict, *key: str | int) -> str:
    line = f" (line {lines[key]})" if key in lines else ""
    return f"{path}: {dotted(key)}{line}"


FRONT_QUANTITIES = ("front", "front_final", "runout", "duration")
"""The observed quantities measured on the front (:mod:`multilayer.io.observables`)."""


def _giving(overrides: dict[str, Any], key: str) -> str | None:
    """The key of ``overrides`` that gives the dotted ``key`` a value: ``key`` itself, or a
    key above it whose mapping or list holds it (``rheology: {name: ..., mu_s: 0.3}`` gives
    ``rheology.mu_s``, ``initial: [{height: 0.05, ...}]`` gives ``initial.0.height``)."""
    for given, value in overrides.items():
        if given == key:
            return given
        if not key.startswith(given + "."):
            continue
        node = value
        for part in key[len(given) + 1 :].split("."):
            if isinstance(node, dict) and part in node:
                node = node[part]
            elif isinstance(node, list) and part.isdecimal() and int(part) < len(node):
                node = node[int(part)]
            else:
                break
        else:
            return given
    return None


def _check_base(
    path: Path,
    lines: dict,
    config: _Study,
    experiments: dict[str, dict[str, Any]],
    measured: dict[str, set[str]],
    check: Check | None,
) -> Path:
    """The base scenario path; every experiment with the parameters at their lower, middle
    and upper bounds must be a valid scenario that ``check`` accepts (the key named
    otherwise: a lower bound of ``domain.x_max`` leaving the initial material outside the
    domain validated, and the study failed at its first runs); no parameter is
    given a value in ``set`` or an experiment, where the parameter's value replaced it
    (an experiment of its own ``rheology.mu_2`` ran with the calibrated one, silently)."""
    given = [(("set",), config.set), *((("experiments", n), extra) for n, extra in experiments.items())]
    for within, overrides in given:
        for key in overrides:
            refused = member_output(key, "study")
            if refused:
                raise InputError(f"{_at(path, lines, *within, key)}: {refused}")
    for key in config.parameters:
        fixed = [
            ".".join(within) + ("" if given_by == key else f".{given_by}")  # the key above it named
            for within, overrides in given
            if (given_by := _giving(overrides, key)) is not None
        ]
        if fixed:
            raise InputError(
                f"{_at(path, lines, 'parameters', key)}: also given a value in {', '.join(fixed)}, which "
                "the parameter's values would replace; accepted: a parameter given no value in set or an "
                "experiment"
            )
    base = load_base(
        path, config.base, _at(path, lines, "base"), "the base scenario with set", as_overrides(config.set)
    )
    for name, extra in experiments.items():
        frontless = []
        for where in (0.0, 0.5, 1.0):
            values = {
                k: p.bounds[0] + where * (p.bounds[1] - p.bounds[0]) for k, p in config.parameters.items()
            }
            try:
                run = scenario.load(base, as_overrides({**config.set, **extra, **values}))
                if check is not None:
                    check(run, str(base))
                frontless.append(run.front_never_found())
            except InputError as exc:
                keys = [k for k in (*values, *extra) if k in str(exc)] or list(values)
                place = ("parameters", keys[0]) if keys[0] in values else ("experiments", name)
                raise InputError(
                    f"{_at(path, lines, *place)}: the scenario is invalid with "
                    f"{', '.join(f'{k} = {v:g}' for k, v in values.items())}"
                    f"{f' in experiment {name}' if extra else ''}:\n{exc}"
                ) from None
        on_front = sorted(measured.get(name, set()) & set(FRONT_QUANTITIES))
        if on_front and all(frontless):  # every run of the experiment: the front NaN, the study failed
            raise InputError(
                f"{_at(path, lines, 'base')}: numerics.front_threshold = {frontless[1]}"
                f"{f' in experiment {name}' if len(experiments) > 1 else ''}, with the parameters at their "
                f"lower, middle and upper values, and the study measures {', '.join(on_front)} on it; "
                "accepted: a smaller numerics.front_threshold (set), or no observation or output of the front"
            )
    return base


Check = Callable[[scenario.Scenario, str], None]
"""What a study's caller checks of a run's scenario before it starts (InputError naming
the file, the second argument): the app's ``factory.check_start``."""


def load_calibration(path: str | Path, check: Check | None = None) -> Calibration:
    """Read and validate a calibration file and read its observations (InputError if bad);
    ``check`` of every experiment's runs at the parameters' bounds (:func:`_check_base`)."""
    path = Path(path)
    config, lines = _validate(CalibrationModel, path, "calibration")
    experiments = dict(config.experiments) or {"base": {}}
    measured: dict[str, set[str]] = {}
    for obs in config.observations:
        measured.setdefault(obs.experiment or next(iter(experiments)), set()).add(obs.quantity)
    base = _check_base(path, lines, config, experiments, measured, check)
    data = [
        _read(path, lines, i, obs, obs.experiment or next(iter(experiments)))
        for i, obs in enumerate(config.observations)
    ]
    for i, observed in enumerate(data):
        _check_span(path, lines, i, observed, base, config, experiments[observed.experiment])
    return Calibration(path=path, base=base, config=config, data=data)


def _check_span(
    path: Path, lines: dict, index: int, observed: ObservedData, base: Path, config: Any, extra: dict
) -> None:
    """:class:`InputError` if the observation lies outside the time or the domain its runs
    simulate (the model would be compared there with values extrapolated from its ends);
    a calibrated time.end or domain bound counts at its narrowest."""
    run = scenario.load(base, as_overrides({**config.set, **extra}))
    end, x_min, x_max = run.time.end, run.domain.x_min, run.domain.x_max
    bounds = config.parameters
    end = bounds["time.end"].bounds[0] if "time.end" in bounds else end
    x_min = bounds["domain.x_min"].bounds[1] if "domain.x_min" in bounds else x_min
    x_max = bounds["domain.x_max"].bounds[0] if "domain.x_max" in bounds else x_max
    obs = observed.observation
    where = _at(path, lines, "observations", index)
    _check_reach(where, observed, run, config)
    coordinates = np.asarray(observed.coordinate, dtype=float)
    inside = coordinates.size == 0 or (coordinates.min() >= 0 and coordinates.max() <= end)
    if obs.quantity in CURVES and not inside:
        first, last, shown_end = _apart(coordinates.min(), coordinates.max(), end)
        raise InputError(
            f"{where}: observed at t = {first} to {last} s, outside the runs, which end at time.end = "
            f"{shown_end} s; accepted: observations within the simulated time, or a longer time.end (set)"
        )
    if obs.quantity in PROFILES:
        if obs.time is not None and obs.time > end:
            raise InputError(
                f"{_at(path, lines, 'observations', index, 'time')}: t = {obs.time:g} s is after the end of "
                f"the runs (time.end = {end:g} s); accepted: a time within the simulated time"
            )
        if coordinates.size and not (coordinates.min() >= x_min and coordinates.max() <= x_max):
            first, last, low, high = _apart(coordinates.min(), coordinates.max(), x_min, x_max)
            raise InputError(
                f"{where}: observed at x = {first} to {last} m, outside the domain [{low}, {high}] m of "
                "the runs; accepted: positions inside the domain"
            )


def _apart(*values: float) -> list[str]:
    """``values`` written with 6 significant digits, or each as Python writes it (to the
    last digit) where two would read alike: an observation at t = 0.2000000001 s was said
    "at t = 0.2 to 0.2 s, outside the runs, which end at time.end = 0.2 s"."""
    short = [f"{float(v):g}" for v in values]
    return short if len(set(short)) == len(set(map(float, values))) else [repr(float(v)) for v in values]


REACH_SIGMAS = 3.0
"""An observed value farther than this many standard deviations from every value a run can
give is refused: no parameter set can come near it."""


def _check_reach(where: str, observed: ObservedData, run: Any, config: Any) -> None:
    """:class:`InputError` if an observed value lies more than :data:`REACH_SIGMAS` standard
    deviations outside what every run gives (a front within the domain, a run-out no longer
    than it, a duration within the simulated time, a mass and a thickness >= 0; a
    calibrated time.end or domain bound counts at its widest): a front observed at 7 m on a
    domain of 0.5 m was fitted, every member's misfit growing with its distance from the
    domain's end, and the calibration reported the parameters at a bound as the best fit."""
    bounds = config.parameters
    x_min = bounds["domain.x_min"].bounds[0] if "domain.x_min" in bounds else run.domain.x_min
    x_max = bounds["domain.x_max"].bounds[1] if "domain.x_max" in bounds else run.domain.x_max
    end = bounds["time.end"].bounds[1] if "time.end" in bounds else run.time.end
    quantity = observed.observation.quantity
    reach = {
        "front": (x_min, x_max, f"a front within the domain [{x_min:g}, {x_max:g}] m"),
        "front_final": (x_min, x_max, f"a front within the domain [{x_min:g}, {x_max:g}] m"),
        "runout": (x_min - x_max, x_max - x_min, f"a run-out no longer than the domain, {x_max - x_min:g} m"),
        "duration": (0.0, end, f"a duration within the simulated time, 0 to {end:g} s"),
        "mass_final": (0.0, math.inf, "a mass >= 0"),
        "h": (0.0, math.inf, "a thickness >= 0"),
    }
    low, high, runs_give = reach[quantity]
    value, sigma = np.asarray(observed.value), np.asarray(observed.sigma)
    with np.errstate(over="ignore"):  # 3 sigma beyond the largest float: inf, which reaches anything
        far = (value + REACH_SIGMAS * sigma < low) | (value - REACH_SIGMAS * sigma > high)
    if far.any():
        k = int(np.flatnonzero(far)[0])
        at = f" at {observed.coordinate[k]:g} {_COORDINATE_SI[quantity]}" if observed.coordinate else ""
        unit = _SI[quantity]
        raise InputError(
            f"{where}: observed {quantity} {value[k]:g} {unit}{at} (sigma {sigma[k]:g} {unit}), more than "
            f"{REACH_SIGMAS:g} standard deviations from what any run gives ({runs_give}): no parameter set "
            f"can come near it; accepted: observations a run can reproduce, in SI after their units"
        )


def load_sensitivity(path: str | Path, check: Check | None = None) -> Sensitivity:
    """Read and validate a sensitivity file (InputError if bad); ``check`` of its runs at
    the parameters' bounds (:func:`_check_base`)."""
    path = Path(path)
    config, lines = _validate(SensitivityModel, path, "sensitivity")
    base = _check_base(path, lines, config, {"base": {}}, {"base": set(config.outputs)}, check)
    return Sensitivity(path=path, base=base, config=config)


def _read(path: Path, lines: dict, index: int, obs: Observation, experiment: str) -> ObservedData:
    """The observation's values in SI, from the file itself or from ``obs.file``."""
    scale = UNITS[obs.units or _SI[obs.quantity]]
    if obs.quantity in SCALARS:
        if obs.value is None or obs.sigma is None:
            raise _unvalidated(obs, "value and sigma")
        return ObservedData(
            observation=obs,
            experiment=experiment,
            coordinate=[],
            value=_in_si([obs.value], scale, _at(path, lines, "observations", index, "value"), "value"),
            sigma=_in_si([obs.sigma], scale, _at(path, lines, "observations", index, "sigma"), "sigma"),
        )
    where = _at(path, lines, "observations", index, "file")
    if obs.file is None:
        raise _unvalidated(obs, "file")
    file = files_directory(path) / obs.file
    if not file.is_file():
        raise InputError(
            f"{where}: {file} {why_not_a_file(file)}; accepted: a CSV or netCDF file, {relative_to(path)}"
        )
    if file.suffix == ".nc":
        if obs.variable is None:
            raise _unvalidated(obs, "variable")
        coordinate, value, units, coordinate_units = _read_netcdf(file, obs.variable, where)
        sigma = None
    else:
        if obs.columns is None:
            raise _unvalidated(obs, "columns")
        coordinate, value, sigma = _read_csv(file, obs.columns, where)
        units, coordinate_units = None, None
    unit = obs.units or units or _SI[obs.quantity]
    coordinate_unit = obs.coordinate_units or coordinate_units or _COORDINATE_SI[obs.quantity]
    for u, expected in ((unit, _SI[obs.quantity]), (coordinate_unit, _COORDINATE_SI[obs.quantity])):
        if _DIMENSION.get(u) != expected:
            raise InputError(
                f"{where}: unit {shown(u)} in {file}; accepted: "
                + ", ".join(k for k, d in _DIMENSION.items() if d == expected)
            )
    scale = UNITS[unit]
    sigma = np.full_like(value, obs.sigma) if sigma is None or obs.sigma is not None else sigma
    if not (np.all(np.isfinite(value)) and np.all(np.isfinite(coordinate)) and np.all(sigma > 0)):
        raise InputError(
            f"{where}: {file} holds non-finite values or uncertainties <= 0; accepted: finite data"
        )
    return ObservedData(
        observation=obs,
        experiment=experiment,
        coordinate=_in_si(coordinate, UNITS[coordinate_unit], where, "coordinate"),
        value=_in_si(value, scale, where, "value"),
        sigma=_in_si(sigma, scale, where, "sigma"),
    )


def _in_si(values: Any, scale: float, where: str, what: str) -> list[float]:
    """``values`` times the unit's ``scale``: finite numbers, and uncertainties (``sigma``)
    > 0, also after the conversion (1e-322 cm of uncertainty is 0 m, 1e308 km infinite)."""
    converted = np.asarray(values, dtype=float) * scale
    bad = ~np.isfinite(converted) | ((converted <= 0) if what == "sigma" else False)
    if np.any(bad):
        first = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{where}: the {what} {np.asarray(values, dtype=float)[first]:g} is {converted[first]:g} in SI "
            f"(times {scale:g}); accepted: {'numbers > 0' if what == 'sigma' else 'numbers'} that are "
            "finite in SI units"
        )
    return list(converted)


def _unvalidated(obs: Observation, keys: str) -> RuntimeError:
    """The error for an observation without the ``keys`` its validation requires (a bug)."""
    return RuntimeError(
        f"observation {obs.name!r} ({obs.quantity}) has no {keys}: it was not validated by Observation"
    )


def _read_csv(file: Path, columns: list[str], where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Columns of a CSV file with a header row, as floats."""
    try:  # a regular file of at most limits.MAX_FILE_BYTES
        text = read_text(file, "a CSV file of numbers", "a readable UTF-8 CSV file")
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    try:
        reader = csv.DictReader(io.StringIO(text, newline=""))
        # a header written as a profile's, "t, x_f, sigma", names x_f: spaces around a name are no part of it
        header = reader.fieldnames = [name.strip() for name in reader.fieldnames or []]
        twice = [c for c in columns if header.count(c) > 1]
        if twice:  # a dict of the row keeps the last of them, silently
            raise InputError(
                f"{where}: {file}: its header names the column {shown(twice[0])} twice; accepted: a CSV file "
                "whose header names each column it reads once"
            )
        rows = list(itertools.islice(reader, MAX_PROFILE_POINTS + 1))
        for row in rows:  # more fields than the header: DictReader dropped the others, silently
            if None in row or None in row.values():
                fields = _row_text(row)
                raise InputError(
                    f"{where}: {file}: a row of {len(fields)} fields ({', '.join(fields)}), "
                    f"{len(row) - (None in row)} in the header; accepted: a CSV file of numbers with as "
                    "many fields in every row as in its header (a decimal comma splits a number in two)"
                )
        if len(rows) > MAX_PROFILE_POINTS:
            raise InputError(
                f"{where}: {file} has more than {MAX_PROFILE_POINTS} rows; accepted: at most that"
            )
        table = [[csv_number(row[c]) for row in rows] for c in columns]
    except KeyError as exc:
        raise InputError(
            f"{where}: {file} has no column {exc} (its header names "
            f"{shortened(', '.join(map(repr, header)))}); "
            f"accepted: a CSV file with a header row naming {', '.join(columns)}"
        ) from None
    except csv.Error as exc:  # a field longer than the csv module's limit (131072 characters): a traceback
        raise InputError(
            f"{where}: {file}: line {reader.line_num + 1}: {exc}; accepted: a CSV file of numbers"
        ) from None
    except (OSError, ValueError, TypeError) as exc:
        raise InputError(
            f"{where}: cannot read {file} ({reason(exc)}); accepted: a CSV file of numbers"
        ) from None
    if not table[0]:
        raise InputError(f"{where}: {file} has no rows; accepted: a CSV file with data")
    arrays = [np.asarray(t, dtype=float) for t in table]
    return arrays[0], arrays[1], arrays[2] if len(arrays) > 2 else None


def _row_text(row: dict) -> list[str]:
    """The fields of a row of ``csv.DictReader`` as written."""
    return [v for k, v in row.items() if k is not None and v is not None] + list(row.get(None, []))


def _read_netcdf(
    file: Path, variable: str, where: str
) -> tuple[np.ndarray, np.ndarray, str | None, str | None]:
    """A one-dimensional netCDF variable, its coordinate and both units attributes."""
    from multilayer.io.results import decoded

    try:
        with decoded(file, load=False) as ds:
            if variable not in ds:
                raise InputError(
                    f"{where}: {file} has no variable {shown(variable)}; accepted: "
                    + ", ".join(map(str, ds.data_vars))
                )
            if ds[variable].size > MAX_PROFILE_POINTS:
                raise InputError(
                    f"{where}: {file}: {variable} holds {ds[variable].size} values; accepted: at most "
                    f"{MAX_PROFILE_POINTS}"
                )
            var = ds[variable].load()
    except (OSError, ValueError) as exc:
        raise InputError(f"{where}: cannot read {file} ({reason(exc)}); accepted: a netCDF file") from None
    if var.ndim != 1:
        raise InputError(f"{where}: {file}: {variable} has {var.ndim} dimensions; accepted: one")
    dim = var.dims[0]
    accepted = (
        f"accepted: a variable of numbers over a coordinate variable {dim} of numbers (s, ms, m, cm, mm)"
    )
    if dim not in var.coords:  # xarray numbers the entries 0, 1, 2, ...: read as times or positions
        raise InputError(
            f"{where}: {file}: the dimension {dim} of {variable} has no coordinate variable (its entries "
            f"would be read at {dim} = 0, 1, 2, ...); {accepted}"
        )
    coord = var[dim]
    for name, values in ((variable, var), (str(dim), coord)):
        if values.dtype.kind in "mM":  # decoded by xarray from units of time
            units = values.encoding.get("units", values.attrs.get("units"))
            raise InputError(
                f"{where}: {file}: {name} has units {units!r}, which are read as "
                f"{'dates' if values.dtype.kind == 'M' else 'durations'}; {accepted}"
            )
        if values.dtype.kind not in "iuf":
            raise InputError(f"{where}: {file}: {name} holds values of type {values.dtype}; {accepted}")
    if var.size == 0:
        raise InputError(f"{where}: {file}: {variable} holds no values; {accepted}, at least one")
    units = {name: values.attrs.get("units") for name, values in ((variable, var), (str(dim), coord))}
    for name, unit in units.items():  # another tool's attribute of numbers: an array was a traceback
        if unit is not None and not isinstance(unit, str):
            raise InputError(f"{where}: {file}: {name} has units {shown(unit)}, not text; {accepted}")
    return (
        np.asarray(coord.values, dtype=float),
        np.asarray(var.values, dtype=float),
        units[variable],
        units[str(dim)],
    )
