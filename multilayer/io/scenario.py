"""Scenario files: YAML loading, ``--set`` overrides and strict validation.

The keys are documented in docs/scenarios.md.  Every
invalid input raises :class:`~multilayer.errors.InputError` with one message per
problem, ``<file>: <key.path> (line N): <what is wrong>; accepted: <...>``.
"""

from __future__ import annotations

import copy
import re
import typing
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import numpy as np
import yaml
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    Strict,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_serializer,
    model_validator,
)
from pydantic_core import PydanticCustomError

from multilayer.errors import InputError
from multilayer.io import profiles
from multilayer.io.files import read_text
from multilayer.plugins import host as plugins
from multilayer.plugins.contract import Material, Rheology

Quantity = Literal["front_final", "mass_final", "runout", "max_speed_final", "static_interface_mean_final"]
QUANTITIES: tuple[str, ...] = get_args(Quantity)
"""Quantities an ``expect`` entry can check (see multilayer.results.summary)."""

_FRACTION_SUM_TOLERANCE = 1e-6


# --------------------------------------------------------------------------- YAML


class Loader(yaml.SafeLoader):
    """SafeLoader that also reads ``1e-3`` and ``2E5`` as floats (the YAML 1.2 rule)."""


Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)

KeyPath = tuple[str | int, ...]


def _line_map(node: yaml.Node, where: str, path: KeyPath = (), lines=None) -> dict[KeyPath, int]:
    """1-based line of every key path in a composed YAML document; rejects duplicate keys."""
    lines = {} if lines is None else lines
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            child = (*path, key_node.value)
            line = key_node.start_mark.line + 1
            if child in lines:
                raise InputError(
                    f"{where}: {_dotted(child)} (line {line}): duplicate key; "
                    f"accepted: each key once (first at line {lines[child]})"
                )
            lines[child] = line
            _line_map(value_node, where, child, lines)
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            lines[(*path, index)] = item.start_mark.line + 1
            _line_map(item, where, (*path, index), lines)
    return lines


def _parse_yaml(text: str, where: str) -> tuple[Any, dict[KeyPath, int]]:
    try:
        node = yaml.compose(text, Loader=Loader)
        data = yaml.load(text, Loader=Loader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" (line {mark.line + 1}, column {mark.column + 1})" if mark else ""
        problem = getattr(exc, "problem", None) or str(exc)
        raise InputError(
            f"{where}{line}: malformed YAML: {problem}; accepted: a YAML mapping of scenario keys"
        ) from None
    return data, ({} if node is None else _line_map(node, where))


def _dotted(path: Sequence[str | int]) -> str:
    return ".".join(str(p) for p in path) or "(top level)"


# --------------------------------------------------------------------------- errors


def _invalid(message: str, accepted: str, key: str = "") -> PydanticCustomError:
    """A validation error at sub-key ``key`` of the model being validated."""
    return PydanticCustomError(
        "scenario", "{message}", {"message": message, "accepted": accepted, "key": key}
    )


def _check_kind(model: BaseModel, kind: str, table: dict[str, tuple[tuple[str, ...], ...]]) -> None:
    """Per-kind keys: ``table[value] = (required, optional)`` for ``model.<kind> == value``."""
    value = getattr(model, kind)
    required, optional = table[value]
    accepted = ", ".join((kind, *required, *optional))
    for key in required:
        if getattr(model, key) is None:
            raise _invalid(f"{kind} {value} requires {key}", accepted, key)
    extra = sorted(model.model_fields_set - {kind, *required, *optional})
    if extra:
        raise _invalid(f"not a key of {kind} {value}", accepted, extra[0])


def _ordered(x_min: float, x_max: float) -> None:
    """An interval [x_min, x_max] must have x_max > x_min."""
    if not x_min < x_max:
        raise _invalid(f"x_max = {x_max} is not > x_min = {x_min}", f"a number > x_min = {x_min}", "x_max")


def _increasing(points: list[list[float]], key: str, what: str) -> None:
    xs = [x for x, _ in points]
    if len(points) < 2 or any(b <= a for a, b in zip(xs, xs[1:])):
        raise _invalid(
            f"{what} needs at least 2 points with strictly increasing x",
            f"a list [[x, {what}], ...] with increasing x",
            key,
        )


# --------------------------------------------------------------------------- models


class _Model(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


def _field(default: Any = ..., accepted: str = "", **constraints: Any) -> Any:
    """A field whose ``description`` is the 'accepted' part of error messages."""
    return Field(default, description=accepted, **constraints)


Point = Annotated[list[float], Field(min_length=2, max_length=2)]


class Domain(_Model):
    """Computational domain along the slope and its layers."""

    x_min: float = _field(..., "a number (m)")
    x_max: float = _field(..., "a number > x_min (m)")
    cells: int = _field(..., "an integer >= 1", ge=1)
    layers: int = _field(1, "an integer >= 1", ge=1)
    layer_fractions: Any = _field(
        "uniform", "'uniform', a list of `layers` numbers > 0 summing to 1, or {geometric: r > 0}"
    )
    width: float | None = _field(None, "a number > 0 (m)", gt=0)

    @model_validator(mode="after")
    def _check(self) -> Domain:
        _ordered(self.x_min, self.x_max)
        accepted = Domain.model_fields["layer_fractions"].description or ""
        value = self.layer_fractions
        if isinstance(value, list):
            if len(value) != self.layers or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < np.inf for v in value
            ):
                raise _invalid(
                    f"expected {self.layers} numbers > 0, got {value!r}", accepted, "layer_fractions"
                )
            if abs(sum(value) - 1) > _FRACTION_SUM_TOLERANCE:
                raise _invalid(f"fractions sum to {sum(value)!r}, not 1", accepted, "layer_fractions")
        elif isinstance(value, dict):
            ratio = value.get("geometric")
            if (
                set(value) != {"geometric"}
                or isinstance(ratio, bool)
                or not isinstance(ratio, (int, float))
                or not 0 < ratio < np.inf
            ):
                raise _invalid(f"got {value!r}", accepted, "layer_fractions")
        elif value != "uniform":
            raise _invalid(f"got {value!r}", accepted, "layer_fractions")
        return self

    def fractions(self) -> np.ndarray:
        """Layer fractions l_1..l_L (bottom to top), shape (L,), summing to 1.

        ``uniform``: 1/L; a list: as given (renormalised to round-off);
        ``{geometric: r}``: l_a proportional to r**(a-1) (thin layers at the bed for r > 1).
        """
        if isinstance(self.layer_fractions, list):
            weights = np.asarray(self.layer_fractions, dtype=float)
        elif isinstance(self.layer_fractions, dict):
            weights = float(self.layer_fractions["geometric"]) ** np.arange(self.layers)
        else:
            weights = np.ones(self.layers)
        return weights / weights.sum()


class MaterialSpec(_Model):
    """Material constants (SI)."""

    density: float = _field(..., "a number > 0 (kg/m^3)", gt=0)
    grain_diameter: float = _field(..., "a number > 0 (m)", gt=0)
    particle_density: float | None = _field(None, "a number > 0 (kg/m^3); default: density", gt=0)

    @model_validator(mode="after")
    def _default_particle_density(self) -> MaterialSpec:
        if self.particle_density is None:
            self.particle_density = self.density
        return self

    def as_material(self) -> Material:
        """The :class:`multilayer.Material` handed to rheology plugins."""
        rho_p = self.density if self.particle_density is None else self.particle_density
        return Material(self.density, self.grain_diameter, rho_p)


class PluginSpec(_Model):
    """A rheology plugin chosen by ``name``; the other keys are its constructor arguments.

    In YAML the spec is flat (``{name: jop_mu_i, mu_s: 0.48, ...}``); ``params`` holds the
    validated keyword arguments (defaults filled in).
    """

    name: str = _field(..., "a registered rheology name (see `multilayer plugins`)")
    params: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _split(cls, data: Any) -> Any:
        if isinstance(data, dict) and not ("params" in data and set(data) <= {"name", "params"}):
            params = {k: v for k, v in data.items() if k != "name"}
            return {"params": params, **({"name": data["name"]} if "name" in data else {})}
        return data

    @model_serializer
    def _flat(self) -> dict[str, Any]:
        return {"name": self.name, **self.params}

    def checked(self, applies_to: str) -> PluginSpec:
        """This spec with validated parameters, for a law applying to ``applies_to``."""
        cls, problem = plugins.find(self.name, applies_to)
        if problem or cls is None:
            raise _invalid(problem or self.name, ", ".join(plugins.available(applies_to)), "name")
        try:
            params = plugins.parameter_model(cls).model_validate(self.params).model_dump()
            # an optional parameter left at None (e.g. mu_start) is not written out
            params = {key: value for key, value in params.items() if value is not None}
        except ValidationError as exc:
            error = exc.errors()[0]
            key = _dotted(error["loc"])
            message = (
                f"unknown parameter of {self.name}"
                if error["type"] == "extra_forbidden"
                else f"missing parameter of {self.name}"
                if error["type"] == "missing"
                else f"{self.name}: {error['msg']} (got {error['input']!r})"
            )
            raise _invalid(message, plugins.signature_text(cls), key) from None
        try:
            plugins.construct(cls, params)
        except (TypeError, ValueError) as exc:
            raise _invalid(f"{self.name}: {exc}", plugins.signature_text(cls)) from None
        return self.model_copy(update={"params": params})

    def instantiate(self) -> Rheology:
        """The plugin instance this spec describes."""
        return plugins.instantiate(self)


class BaseZone(_Model):
    """Basal condition on [x_min, x_max] (unbounded where omitted)."""

    condition: Literal["no_slip", "coulomb", "free_slip"] = _field(
        ..., "no_slip, coulomb (with mu) or free_slip"
    )
    mu: float | None = _field(None, "a friction coefficient >= 0 (coulomb only)", ge=0)
    x_min: float | None = _field(None, "a number (m)")
    x_max: float | None = _field(None, "a number > x_min (m)")

    @model_validator(mode="after")
    def _check(self) -> BaseZone:
        _check_kind(
            self,
            "condition",
            {
                "no_slip": ((), ("x_min", "x_max")),
                "coulomb": (("mu",), ("x_min", "x_max")),
                "free_slip": ((), ("x_min", "x_max")),
            },
        )
        if self.x_min is not None and self.x_max is not None:
            _ordered(self.x_min, self.x_max)
        return self


def _file_in(info: ValidationInfo, name: Path) -> Path:
    """``name`` relative to the scenario file's directory (the working directory without one)."""
    directory = (info.context or {}).get("directory") or Path.cwd()
    return Path(directory) / name


def _read_profile(read: typing.Callable[[], np.ndarray], key: str) -> list[list[float]]:
    """Points of a profile read from a file: an :class:`InputError` (a bad file) becomes a
    validation error of ``key``, reported with the scenario file and line."""
    try:
        return read().tolist()
    except InputError as exc:
        message, _, accepted = str(exc).partition("; accepted: ")
        raise _invalid(message, accepted, key) from None


class Bed(_Model):
    """Bed elevation b(x) on the inclined plane: flat, piecewise linear through points, or
    read from a CSV file or a GeoTIFF DEM (turned into ``points`` on loading)."""

    profile: Literal["flat", "points", "file", "dem"] | None = _field(
        None, "flat, points (with points), file (with file) or dem (with dem and polyline)"
    )
    points: list[Point] | None = _field(None, "a list [[x, b], ...] with increasing x (m)")
    file: Annotated[Path, Strict(False)] | None = _field(
        None, "a CSV file with a header 'x (m), z (m)' (units m, cm, mm or km), relative to the scenario"
    )
    frame: Literal["slope", "map"] | None = _field(
        None, "slope (x along the plane, z normal to it; default) or map (horizontal distance, elevation)"
    )
    dem: Annotated[Path, Strict(False)] | None = _field(
        None, "a GeoTIFF DEM, relative to the scenario (needs pip install 'multilayer[dem]')"
    )
    polyline: list[Point] | None = _field(
        None, "a list of at least 2 map points [[X, Y], ...] in the DEM's coordinates (m)"
    )
    spacing: float | None = _field(None, "a number > 0 (m); default: the DEM's pixel size", gt=0)

    _map_points: np.ndarray | None = PrivateAttr(None)
    """A map-frame profile [[s, Z], ...], turned into ``points`` with the scenario's slope."""

    @model_validator(mode="after")
    def _check(self, info: ValidationInfo) -> Bed:
        if self.profile is None:
            self.profile = (
                "dem"
                if self.dem is not None
                else "file"
                if self.file is not None
                else "points"
                if self.points is not None
                else "flat"
            )
        _check_kind(
            self,
            "profile",
            {
                "flat": ((), ()),
                "points": (("points",), ()),
                "file": (("file",), ("frame",)),
                "dem": (("dem", "polyline"), ("spacing",)),
            },
        )
        if self.profile == "file":
            path = _file_in(info, typing.cast(Path, self.file))
            points = _read_profile(lambda: profiles.read_csv_profile(path, ("x", "z|b")), "file")
            if self.frame == "map":
                self._map_points = np.array(points, dtype=float)
            else:
                self.points = points
        elif self.profile == "dem":
            polyline = typing.cast(list[list[float]], self.polyline)
            if len(polyline) < 2:
                raise _invalid(
                    "needs at least 2 points", "a list [[X, Y], ...] of 2 or more points", "polyline"
                )
            path = _file_in(info, typing.cast(Path, self.dem))
            self._map_points = np.array(
                _read_profile(lambda: profiles.read_dem_profile(path, polyline, self.spacing), "dem"),
                dtype=float,
            )
        if self.points is not None:
            _increasing(self.points, "points", "b")
        return self

    def in_slope_frame(self, slope_deg: float) -> None:
        """Turn a map-frame profile (``frame: map`` or a DEM) into slope-frame ``points``."""
        map_points = self._map_points
        if map_points is not None:
            source = self.dem or self.file
            self.points = _read_profile(
                lambda: profiles.map_to_slope_frame(map_points, slope_deg, str(source)),
                f"bed.{'dem' if self.dem else 'file'}",
            )
            self._map_points = None

    @model_serializer(mode="wrap")
    def _as_points(self, handler: typing.Callable[[Bed], dict[str, Any]]) -> dict[str, Any]:
        """A bed read from a file is recorded as its points, so the record stands alone."""
        data = handler(self)
        if self.profile in ("file", "dem"):
            return {"profile": "points", "points": data["points"]}
        return data


class Velocity(_Model):
    """Initial or inflow velocity profile over the depth (z above the bed)."""

    profile: Literal["plug", "linear", "bagnold"] = _field(..., "plug, linear or bagnold")
    speed: float | None = _field(None, "a number (m/s)")
    shear_rate: float | None = _field(None, "a number (1/s)")
    from_height: float | None = _field(None, "a number >= 0 (m); default 0", ge=0)
    surface_speed: float | None = _field(None, "a number (m/s)")

    @model_validator(mode="after")
    def _check(self) -> Velocity:
        _check_kind(
            self,
            "profile",
            {
                "plug": (("speed",), ()),
                "linear": (("shear_rate",), ("from_height",)),
                "bagnold": (("surface_speed",), ()),
            },
        )
        if self.profile == "linear" and self.from_height is None:
            self.from_height = 0.0
        return self


class InitialShape(_Model):
    """One contribution to the initial thickness (contributions add up)."""

    shape: Literal["layer", "rectangle", "profile"] = _field(..., "layer, rectangle or profile")
    thickness: float | None = _field(None, "a number >= 0 (m); 0: no layer", ge=0)
    x_min: float | None = _field(None, "a number (m)")
    x_max: float | None = _field(None, "a number > x_min (m)")
    height: float | None = _field(None, "a number > 0 (m)", gt=0)
    points: list[Point] | None = _field(None, "a list [[x, h], ...] with increasing x, h >= 0 (m)")
    file: Annotated[Path, Strict(False)] | None = _field(
        None, "a CSV file with a header 'x (m), h (m)' (units m, cm, mm or km), relative to the scenario"
    )
    velocity: Velocity | None = _field(None, "a velocity profile; default: at rest")

    @model_validator(mode="after")
    def _check(self, info: ValidationInfo) -> InitialShape:
        if self.shape == "profile" and self.file is not None:
            if self.points is not None:
                raise _invalid("give points or file, not both", "points or file", "file")
            path = _file_in(info, self.file)
            self.points = _read_profile(lambda: profiles.read_csv_profile(path, ("x", "h")), "file")
        _check_kind(
            self,
            "shape",
            {
                "layer": (("thickness",), ("velocity",)),
                "rectangle": (("x_min", "x_max", "height"), ("velocity",)),
                "profile": (("points",), ("velocity", "file")),
            },
        )
        if self.shape == "rectangle":
            assert self.x_min is not None and self.x_max is not None  # required (checked above)
            _ordered(self.x_min, self.x_max)
        if self.shape == "profile":
            assert self.points is not None  # required (checked above)
            _increasing(self.points, "points", "h")
            if any(h < 0 for _, h in self.points):
                key = "file" if self.file is not None else "points"
                raise _invalid("negative thickness", "a list [[x, h], ...] with h >= 0", key)
        return self

    @model_serializer(mode="wrap")
    def _as_points(self, handler: typing.Callable[[InitialShape], dict[str, Any]]) -> dict[str, Any]:
        """A profile read from a file is recorded as its points, so the record stands alone."""
        data = handler(self)
        data.pop("file", None)
        return data


class Inflow(_Model):
    """State imposed at an ``inflow`` boundary."""

    thickness: float = _field(..., "a number > 0 (m)", gt=0)
    velocity: Velocity = _field(..., "a velocity profile")


Boundary = Literal["wall", "outflow", "inflow", "periodic"]


class Boundaries(_Model):
    """Boundary conditions at x_min (left) and x_max (right)."""

    left: Boundary = _field("wall", "wall, outflow, inflow or periodic")
    right: Boundary = _field("wall", "wall, outflow, inflow or periodic")
    inflow: Inflow | None = _field(None, "{thickness, velocity} (with an inflow side)")

    @model_validator(mode="after")
    def _check(self) -> Boundaries:
        if (self.left == "periodic") != (self.right == "periodic"):
            key = "right" if self.left == "periodic" else "left"
            raise _invalid("periodic must be set on both sides", "periodic on both sides", key)
        has_inflow = "inflow" in (self.left, self.right)
        if has_inflow and self.inflow is None:
            raise _invalid(
                "an inflow side requires boundaries.inflow",
                "{thickness: h, velocity: {profile: plug, speed: u}}",
                "inflow",
            )
        if self.inflow is not None and not has_inflow:
            raise _invalid("inflow given but no side is inflow", "left: inflow or right: inflow", "inflow")
        return self


class GateSpec(_Model):
    """A gate holding the initial column, lifted at the start of the run (engine/gate.py)."""

    x: float = _field(..., "a number in [domain.x_min, domain.x_max] (m); snapped to the nearest cell face")
    lift_speed: float = _field(
        ..., "a number >= 0 (m/s), normal to the plane; .inf: instantaneous release", ge=0, allow_inf_nan=True
    )


class Time(_Model):
    """Time stepping and output (s)."""

    end: float = _field(..., "a number > 0 (s)", gt=0)
    cfl: float = _field(0.45, "a number in (0, 1)", gt=0, lt=1)
    output_interval: float = _field(..., "a number > 0 (s)", gt=0)


class Output(_Model):
    """Where results go."""

    directory: Annotated[Path, Strict(False)] | None = _field(
        None, "a directory path; default results/<name>"
    )


ExpectKind = Literal["regression", "reference"]
EXPECT_KINDS: tuple[str, ...] = get_args(ExpectKind)


class Expect(_Model):
    """A check on the run summary, passing when ``|actual - value| <= atol + rtol |value|``.

    ``kind: regression`` pins ``value`` from the code's own output (it guards against
    change, it validates nothing); ``kind: reference`` takes ``value`` from an exact
    solution or a published result named in ``source``, the tolerance being justified by
    that reference's uncertainty or by a convergence study.
    """

    kind: ExpectKind = _field(
        ..., "regression (a value pinned from the code's output) or reference (an exact or published value)"
    )
    quantity: Quantity = _field(..., ", ".join(QUANTITIES))
    value: float = _field(..., "a number (SI)")
    rtol: float | None = _field(None, "a number >= 0", ge=0)
    atol: float | None = _field(None, "a number >= 0 (SI)", ge=0)
    source: str | None = _field(
        None, "text naming the exact solution or publication (author, year, equation)"
    )

    @model_validator(mode="after")
    def _check(self) -> Expect:
        if self.rtol is None and self.atol is None:
            raise _invalid("needs a tolerance", "rtol and/or atol", "rtol")
        common = ("quantity", "value", "rtol", "atol")
        _check_kind(self, "kind", {"regression": ((), common), "reference": (("source",), common)})
        if self.source is not None and not self.source.strip():
            raise _invalid("source is empty", "text naming the exact solution or publication", "source")
        return self


THREADS_ACCEPTED = "auto or an integer >= 1 (the environment variable MULTILAYER_THREADS wins)"


class Numerics(_Model):
    """Solver settings; the defaults suit every shipped scenario."""

    vertical_solver: Literal["kernel", "fipy"] = _field("kernel", "kernel or fipy")
    transport_solver: Literal["kernel", "numpy"] = _field("kernel", "kernel or numpy")
    threads: Any = _field("auto", THREADS_ACCEPTED)
    order: Literal[1, 2] = _field(2, "1 or 2 (order of the transport step in x and t)")
    tolerance: float = _field(1e-10, "a number > 0", gt=0)
    max_iterations: int = _field(200, "an integer >= 1", ge=1)
    dry_threshold: float = _field(1e-6, "a number > 0 (m)", gt=0)
    front_threshold: float = _field(1e-3, "a number > 0 (m)", gt=0)

    @field_validator("threads")
    @classmethod
    def _threads(cls, value: Any) -> int | str:
        if value == "auto" or (type(value) is int and value >= 1):
            return value
        raise _invalid(f"got {value!r}", THREADS_ACCEPTED)


DEFAULT_PRESSURE_LAYERS = 4  # the choice of docs/nonhydrostatic.md, "Fewer pressure layers"


class Model(_Model):
    """Model options: the pressure that enters the stresses (docs/nonhydrostatic.md)."""

    pressure: Literal["hydrostatic", "bim2016", "non_hydrostatic"] = _field(
        "hydrostatic", "hydrostatic, bim2016 or non_hydrostatic"
    )
    pressure_layers: int | None = _field(
        None,
        "an integer from 1 to domain.layers (with pressure: non_hydrostatic; default "
        f"min({DEFAULT_PRESSURE_LAYERS}, layers))",
        strict=True,
    )

    def resolved_pressure_layers(self, layers: int) -> int:
        """The pressure layers of the non-hydrostatic option (docs/nonhydrostatic.md)."""
        return min(DEFAULT_PRESSURE_LAYERS, layers) if self.pressure_layers is None else self.pressure_layers


class Scenario(_Model):
    """A validated scenario: attribute names are the YAML keys (docs/scenarios.md)."""

    name: str = _field(
        ...,
        "letters, digits, '-', '_' and '.', starting with a letter or digit",
        pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$",
    )
    description: str | None = _field(None, "free text")
    gravity: float = _field(9.81, "a number > 0 (m/s^2)", gt=0)
    slope_deg: float = _field(0.0, "a number in (-90, 90) (degrees)", gt=-90, lt=90)
    domain: Domain = _field(..., "a mapping with x_min, x_max, cells")
    material: MaterialSpec = _field(..., "a mapping with density, grain_diameter")
    rheology: PluginSpec = _field(..., "{name: <bulk rheology>, <parameters>}")
    walls: PluginSpec | None = _field(None, "{name: <walls rheology>, <parameters>}")
    base: list[BaseZone] = _field(
        [BaseZone(condition="no_slip")], "a non-empty list of {condition, ...}", min_length=1
    )
    bed: Bed = _field(Bed(), "{profile: flat} or {points: [[x, b], ...]}")
    initial: list[InitialShape] = _field([], "a list of {shape, ...}")
    boundaries: Boundaries = _field(Boundaries(), "a mapping with left, right")
    gate: GateSpec | None = _field(None, "{x, lift_speed}; default: no gate")
    time: Time = _field(..., "a mapping with end, output_interval")
    output: Output = _field(Output(), "a mapping with directory")
    expect: list[Expect] = _field([], "a list of {kind, quantity, value, rtol, atol, source}")
    numerics: Numerics = _field(Numerics(), "a mapping of solver settings")
    model: Model = _field(Model(), "a mapping with pressure")

    _source: Path | None = PrivateAttr(None)

    @field_validator("rheology")
    @classmethod
    def _bulk(cls, spec: PluginSpec) -> PluginSpec:
        return spec.checked("bulk")

    @field_validator("walls")
    @classmethod
    def _walls(cls, spec: PluginSpec | None) -> PluginSpec | None:
        return None if spec is None else spec.checked("walls")

    @model_validator(mode="after")
    def _check(self) -> Scenario:
        self.bed.in_slope_frame(self.slope_deg)
        count = self.model.pressure_layers
        misplaced = self.model.pressure != "non_hydrostatic"
        if count is not None and (misplaced or not 1 <= count <= self.domain.layers):
            raise _invalid(
                f"got {count!r} with pressure {self.model.pressure} and {self.domain.layers} layers",
                f"an integer from 1 to domain.layers = {self.domain.layers}, with pressure: non_hydrostatic",
                "model.pressure_layers",
            )
        if self.walls is not None and self.domain.width is None:
            raise _invalid(
                "walls need the channel width domain.width",
                "domain.width > 0 (m) together with walls",
                "walls",
            )
        if self.gate is not None and not self.domain.x_min <= self.gate.x <= self.domain.x_max:
            raise _invalid(
                f"gate at x = {self.gate.x} is outside the domain",
                f"a number in [{self.domain.x_min}, {self.domain.x_max}] (m)",
                "gate.x",
            )
        covered, gap = self.domain.x_min, None
        for lo, hi in sorted(
            (-np.inf if z.x_min is None else z.x_min, np.inf if z.x_max is None else z.x_max)
            for z in self.base
        ):
            if lo > covered:
                gap = (covered, min(lo, self.domain.x_max))
                break
            covered = max(covered, hi)
        if gap is None and covered < self.domain.x_max:
            gap = (covered, self.domain.x_max)
        if gap is not None:
            raise _invalid(
                f"no basal condition on x in [{gap[0]}, {gap[1]}]",
                "entries whose x ranges cover [domain.x_min, domain.x_max]",
                "base",
            )
        return self

    @property
    def source(self) -> Path | None:
        """The scenario file, or None for a scenario built from a mapping."""
        return self._source

    def resolved_yaml(self) -> str:
        """The scenario with every default filled in, as YAML that loads back to it."""
        return yaml.safe_dump(self.model_dump(mode="json", exclude_none=True), sort_keys=False)


# --------------------------------------------------------------------------- loading


def _accepted(loc: Sequence[str | int], last_is_key: bool, root: type[BaseModel] | None = None) -> str:
    """The 'accepted' text of the field at ``loc`` (or the keys of the model holding it)
    in the model ``root`` (default :class:`Scenario`)."""
    model: type[BaseModel] | None = root or Scenario
    info = None
    mapping = False
    for part in loc:
        if isinstance(part, int) or mapping:  # a list index or a key of a mapping field
            mapping = False
            continue
        if model is None or part not in model.model_fields:
            return ""
        info = model.model_fields[part]
        mapping = typing.get_origin(info.annotation) is dict
        model = _model_in(info.annotation)
    if last_is_key:
        return ", ".join(model.model_fields) if model else ""
    return info.description or "" if info else ""


def _model_in(annotation: Any) -> type[BaseModel] | None:
    """The pydantic model inside ``annotation`` (through Optional, list, Annotated)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in typing.get_args(annotation):
        found = _model_in(arg)
        if found is not None:
            return found
    return None


def _message(error: Mapping[str, Any], root: type[BaseModel] | None = None) -> tuple[KeyPath, str, str]:
    """(key path, what is wrong, what is accepted) of one pydantic error in the model
    ``root`` (default :class:`Scenario`)."""
    loc, kind, ctx = tuple(error["loc"]), error["type"], error.get("ctx") or {}
    if kind == "scenario":
        key = tuple(int(k) if k.isdigit() else k for k in ctx["key"].split(".") if k)
        return loc + key, ctx["message"], ctx["accepted"]
    if kind == "extra_forbidden":
        return loc, "unknown key", _accepted(loc[:-1], last_is_key=True, root=root)
    if kind == "missing":
        return loc, "required key is missing", _accepted(loc, last_is_key=False, root=root)
    got = repr(error.get("input"))
    got = got if len(got) <= 60 else got[:57] + "..."
    what = (
        f"got {got}"
        if kind == "literal_error"
        else f"expected a mapping (got {got})"
        if kind in ("model_type", "model_attributes_type")
        else f"{error['msg']} (got {got})"
    )
    return loc, what, _accepted(loc, last_is_key=False, root=root)


class _Dumper(yaml.SafeDumper):
    """SafeDumper that quotes every string the scenario loader would read as another type
    (such as ``1e-5``, a float there)."""

    yaml_implicit_resolvers = Loader.yaml_implicit_resolvers


def format_value(value: Any) -> str:
    """YAML text of ``value`` that reads back to the same value, as ``--set`` parses it."""
    text = yaml.dump(value, Dumper=_Dumper, default_flow_style=True, width=2**31)
    return text.removesuffix("...\n").strip()


def as_overrides(values: dict[str, Any]) -> list[str]:
    """``KEY=VALUE`` overrides (as :func:`apply_overrides` reads them) of a mapping of
    dotted keys to values."""
    return [f"{key}={format_value(value)}" for key, value in values.items()]


def apply_overrides(data: dict[str, Any], overrides: Sequence[str]) -> tuple[dict, list[KeyPath]]:
    """``data`` with ``"dotted.key=value"`` overrides applied (value read as YAML).

    List entries are addressed by index (``initial.0.thickness``); missing mappings
    along the path are created, so keys unknown to the schema surface in validation.
    ``"dotted.key+=value"`` appends ``value`` to the list at ``dotted.key`` (created if
    missing): ``initial+={shape: layer, thickness: 0.002}``.
    """
    data = copy.deepcopy(data)
    paths: list[KeyPath] = []
    for item in overrides:
        key, sep, text = item.partition("=")
        append = key.endswith("+")
        key = key.removesuffix("+")
        if not sep or not key:
            raise InputError(
                f"--set {item!r}: expected KEY=VALUE or KEY+=VALUE; accepted: a dotted key path "
                "and a YAML value, e.g. domain.cells=200 or initial+={shape: layer, thickness: 0.002}"
            )
        try:
            value = yaml.load(text, Loader=Loader)
        except yaml.YAMLError as exc:
            raise InputError(
                f"--set {key}: malformed YAML value {text!r}; accepted: a YAML "
                f"scalar, list or mapping ({getattr(exc, 'problem', exc)})"
            ) from None
        node: Any = data
        path: KeyPath = ()
        parts = key.split(".")
        part: str | int
        for depth, part in enumerate(parts):
            if isinstance(node, list):
                if not (part.isdigit() and int(part) < len(node)):
                    raise InputError(
                        f"--set {key}: {_dotted(path)} has {len(node)} entries; "
                        f"accepted indices: 0..{len(node) - 1}"
                    )
                part = int(part)
            elif not isinstance(node, dict):
                raise InputError(
                    f"--set {key}: {_dotted(path)} is a value, not a mapping; "
                    f"accepted: a key path ending at {_dotted(path)}"
                )
            path = (*path, part)
            if depth < len(parts) - 1:
                if isinstance(node, dict) and node.get(part) is None:
                    node[part] = {}
                node = node[part]
            elif not append:
                node[part] = value
            else:
                target = node[int(part)] if isinstance(node, list) else node.setdefault(part, [])
                if not isinstance(target, list):
                    raise InputError(
                        f"--set {key}+=...: {_dotted(path)} is not a list; "
                        f"accepted: += on a list key (initial, base, expect), = elsewhere"
                    )
                target.append(value)
                path = (*path, len(target) - 1)
        paths.append(path)
    return data, paths


def from_dict(
    data: Any,
    *,
    source: str | Path | None = None,
    overrides: Sequence[str] = (),
    lines: dict[KeyPath, int] | None = None,
) -> Scenario:
    """Validate a scenario mapping (as read from YAML); :class:`InputError` if invalid."""
    where = str(source) if source is not None else "<scenario>"
    if not isinstance(data, dict):
        raise InputError(
            f"{where}: (top level): got {type(data).__name__}; "
            "accepted: a mapping of scenario keys (name, domain, material, ...)"
        )
    data, set_paths = apply_overrides(data, overrides)
    lines = lines or {}
    try:
        directory = Path(source).parent if source is not None else None
        scenario = Scenario.model_validate(data, context={"directory": directory})
    except ValidationError as exc:
        messages = []
        for error in exc.errors():
            loc, what, accepted = _message(error)
            if any(loc[: len(p)] == p or p[: len(loc)] == loc for p in set_paths):
                place = " (from --set)"
            else:
                known = [loc[:n] for n in range(len(loc), 0, -1) if loc[:n] in lines]
                place = f" (line {lines[known[0]]})" if known else ""
            tail = f"; accepted: {accepted}" if accepted else ""
            messages.append(f"{where}: {_dotted(loc)}{place}: {what}{tail}")
        raise InputError("\n".join(messages)) from None
    scenario._source = Path(source) if source is not None else None
    return scenario


def read_yaml(path: str | Path, kind: str = "scenario") -> tuple[Any, dict[KeyPath, int]]:
    """The parsed YAML of ``path`` and the line of every key path; ``InputError`` if the
    file is missing, unreadable or malformed (``kind`` names the expected file)."""
    path = Path(path)
    text = read_text(path, f"a path to a {kind} YAML file", "a readable UTF-8 YAML file")
    return _parse_yaml(text, str(path))


def load(path: str | Path, overrides: Sequence[str] = ()) -> Scenario:
    """Read, override and validate a scenario file."""
    data, lines = read_yaml(path)
    return from_dict(data, source=Path(path), overrides=overrides, lines=lines)
