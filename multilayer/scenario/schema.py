"""The schema of scenario files: one strict pydantic model per YAML mapping.

The keys are documented in docs/scenarios.md; the attribute names are the YAML keys.
Each field's description is the "accepted" part of its messages
(:mod:`multilayer.scenario.messages`).
"""

from __future__ import annotations

import heapq
import math
import sys
import typing
from pathlib import Path
from typing import Annotated, Any, Literal, get_args

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    FieldSerializationInfo,
    PrivateAttr,
    SerializerFunctionWrapHandler,
    Strict,
    ValidationError,
    ValidationInfo,
    field_serializer,
    field_validator,
    model_serializer,
    model_validator,
)
from pydantic_core import PydanticSerializationError

from multilayer.engine import basal
from multilayer.engine.gate import gate_face
from multilayer.engine.mesh import cell_centres, layer_fractions
from multilayer.engine.mixture import closure
from multilayer.engine.pressure import model as pressure_models
from multilayer.engine.threads import THREADS_ACCEPTED
from multilayer.engine.transport import boundaries as lateral
from multilayer.errors import InputError
from multilayer.plugins import host as plugins
from multilayer.scenario import limits, messages, profiles
from multilayer.scenario.files import files_directory
from multilayer.scenario.messages import (
    StrictModel,
    check_kind,
    directory_path,
    dotted,
    field,
    increasing,
    invalid,
    ordered,
    shown,
)
from multilayer.scenario.source import dump

Quantity = Literal[
    "front_final",
    "mass_final",
    "runout",
    "max_speed_final",
    "static_interface_mean_final",
    "pore_pressure_bed_mean_final",
    "phi_mean_final",
]
QUANTITIES: tuple[str, ...] = get_args(Quantity)
"""Quantities an ``expect`` entry can check (see multilayer.results.summary)."""
MIXTURE_QUANTITIES = ("pore_pressure_bed_mean_final", "phi_mean_final")
"""Those of a run with a fluid only."""
QUANTITY_RANGES: dict[str, tuple[float, float, str]] = {
    "mass_final": (0.0, math.inf, "0 or more"),
    "max_speed_final": (0.0, math.inf, "0 or more"),
    "static_interface_mean_final": (0.0, math.inf, "0 or more"),
    "phi_mean_final": (
        0.0,
        closure.DENSEST_PACKING,
        f"in [0, {closure.DENSEST_PACKING:.6g}] (pi/sqrt(18), the densest packing of spheres)",
    ),
}
"""The values a run's quantity can take, ``(low, high, in words)``: ``low <= q <= high``
(a solid volume fraction as the result check reads it, within the densest packing of
spheres); any number for a quantity not listed.  An ``expect`` entry whose interval
misses them fails every run, and `multilayer check` ran the whole scenario to say so;
one whose interval holds them all passes every run, a check of nothing."""

_FRACTION_SUM_TOLERANCE = 1e-6
_PACKING = f"a solid volume fraction in (0, {closure.DENSEST_PACKING:.4f}) (the densest packing of spheres)"


Point = Annotated[list[float], Field(min_length=2, max_length=2)]


class Domain(StrictModel):
    """Computational domain along the slope and its layers."""

    x_min: float = field(..., "a number (m)")
    x_max: float = field(..., "a number > x_min (m)")
    cells: int = field(..., f"an integer from 1 to {limits.MAX_CELLS}", ge=1, le=limits.MAX_CELLS)
    layers: int = field(1, f"an integer from 1 to {limits.MAX_LAYERS}", ge=1, le=limits.MAX_LAYERS)
    layer_fractions: Any = field(
        "uniform", "'uniform', a list of `layers` numbers > 0 summing to 1, or {geometric: r > 0}"
    )
    width: float | None = field(None, "a number > 0 (m)", gt=0)

    @model_validator(mode="after")
    def _check(self) -> Domain:
        ordered(self.x_min, self.x_max)
        if not math.isfinite(self.x_max - self.x_min):
            raise invalid(
                f"the domain is {self.x_max - self.x_min} m long",
                "x_min and x_max less than 1e308 m apart",
                "x_max",
            )
        dx = (self.x_max - self.x_min) / self.cells
        ends = max(abs(self.x_min), abs(self.x_max))
        spacing = float(np.spacing(ends))
        if not dx >= limits.MIN_CELL_SPACINGS * spacing:
            most = math.floor((self.x_max - self.x_min) / (limits.MIN_CELL_SPACINGS * spacing))
            # a domain 5e-324 m long: its cells' width underflows to 0
            rounded = f"up to {spacing / dx:.2g} of a cell" if dx > 0 else "more than a cell"
            raise invalid(
                f"{self.cells} cells of {dx:.3g} m, where floats near x = {ends:g} m are {spacing:.3g} m "
                f"apart: the cell edges would be rounded by {rounded} (cells of unequal or no width)",
                f"cells at least {limits.MIN_CELL_SPACINGS} float spacings wide there: at most {most} "
                "cells, or a domain nearer x = 0"
                if most > 0
                else f"a domain at least {limits.MIN_CELL_SPACINGS * spacing:.3g} m long per cell",
                "cells",
            )
        accepted = Domain.model_fields["layer_fractions"].description or ""
        value = self.layer_fractions
        if isinstance(value, list):
            if len(value) != self.layers or not all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and 0 < v < np.inf for v in value
            ):
                raise invalid(
                    f"expected {self.layers} numbers > 0, got {shown(value)}", accepted, "layer_fractions"
                )
            if abs(sum(value) - 1) > _FRACTION_SUM_TOLERANCE:
                raise invalid(f"fractions sum to {shown(sum(value))}, not 1", accepted, "layer_fractions")
        elif isinstance(value, dict):
            ratio = value.get("geometric")
            if (
                set(value) != {"geometric"}
                or isinstance(ratio, bool)
                or not isinstance(ratio, (int, float))
                or not 0 < ratio < np.inf
            ):
                raise invalid(f"got {shown(value)}", accepted, "layer_fractions")
            with np.errstate(all="ignore"):  # a power that overflows or underflows is named below
                fractions = layer_fractions(self.layers, value)
            if not np.all((fractions > 0) & (fractions < np.inf)):  # {geometric: 1e308} gave NaN, 1e-308 zero
                raise invalid(
                    f"{shown(value)} over {self.layers} layers gives the fractions "
                    f"{shown(fractions.tolist())}",
                    "{geometric: r} whose powers r^0 .. r^(layers - 1) are positive numbers with a "
                    "finite sum, so that every layer is a fraction > 0 of h",
                    "layer_fractions",
                )
        elif value != "uniform":
            raise invalid(f"got {shown(value)}", accepted, "layer_fractions")
        return self


class MaterialSpec(StrictModel):
    """Material constants (SI)."""

    density: float = field(..., f"a number >= {limits.MIN_DENSITY:g} (kg/m^3)", gt=0)
    grain_diameter: float = field(..., "a number > 0 (m)", gt=0)
    particle_density: float | None = field(
        None, f"a number >= {limits.MIN_DENSITY:g} (kg/m^3); default: density", gt=0
    )

    @model_validator(mode="after")
    def _default_particle_density(self) -> MaterialSpec:
        for key in ("density", "particle_density"):
            if (value := getattr(self, key)) is not None and value < limits.MIN_DENSITY:
                raise invalid(
                    f"{value!r} kg/m^3, so light that the stresses underflow",
                    f"a number >= {limits.MIN_DENSITY:g} (kg/m^3)",
                    key,
                )
        if self.particle_density is None:
            self.particle_density = self.density
        if not self.density <= self.particle_density:
            raise invalid(
                f"the bulk density {self.density} exceeds the grain density {self.particle_density}"
                " (a solid volume fraction above 1)",
                "a number >= density (kg/m^3): the density of the grains",
                "particle_density",
            )
        return self


class PluginSpec(StrictModel):
    """A rheology plugin chosen by ``name``; the other keys are its constructor arguments.

    In YAML the spec is flat (``{name: jop_mu_i, mu_s: 0.48, ...}``); ``params`` holds the
    validated keyword arguments (defaults filled in).
    """

    name: str = field(..., "a registered rheology name (see `multilayer plugins`)")
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
            raise invalid(problem or self.name, ", ".join(plugins.available(applies_to)), "name")
        try:
            params = plugins.parameter_model(cls).model_validate(self.params).model_dump()
            # an optional parameter left at None (e.g. mu_start) is not written out
            params = {key: value for key, value in params.items() if value is not None}
        except ValidationError as exc:
            # a key not of the law is named first: a typo (mu_z, or mu_s with an invisible
            # character) was said as "mu_s: missing parameter", naming no key of the file
            errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
            error = errors[0]
            key = ".".join(map(str, error["loc"]))  # the path of the key, as the file wrote it
            missing = [dotted(e["loc"]) for e in errors if e["type"] == "missing"]
            message = (
                f"unknown parameter of {self.name}" + (f" ({', '.join(missing)} missing)" if missing else "")
                if error["type"] == "extra_forbidden"
                else f"missing parameter of {self.name}"
                if error["type"] == "missing"
                else f"{self.name}: {error['msg']} (got {shown(error['input'])})"
            )
            raise invalid(message, plugins.signature_text(cls), key) from None
        try:
            plugins.construct(cls, params)
        except (TypeError, ValueError) as exc:
            raise invalid(f"{self.name}: {exc}", plugins.signature_text(cls)) from None
        return self.model_copy(update={"params": params})


class BaseZone(StrictModel):
    """A basal condition (``multilayer.engine.basal``) with its parameters on
    [x_min, x_max] (unbounded where omitted); in YAML flat, ``{condition: coulomb, mu: 0.3}``."""

    model_config = ConfigDict(extra="allow")

    condition: str = field(..., basal.accepted())
    x_min: float | None = field(None, "a number (m)")
    x_max: float | None = field(None, "a number > x_min (m)")

    @model_validator(mode="after")
    def _check(self) -> BaseZone:
        condition = basal.CONDITIONS.get(self.condition)
        if condition is None:
            raise invalid(f"got {shown(self.condition)}", basal.accepted(), "condition")
        given = self.model_extra or {}
        accepted = ", ".join(("condition", *condition.parameters, "x_min", "x_max"))
        for key in condition.parameters:
            if key not in given:
                raise invalid(f"condition {self.condition} requires {key}", accepted, key)
        for key, value in given.items():
            if key not in condition.parameters:
                raise invalid(f"not a key of condition {self.condition}", accepted, key)
            number = type(value) in (int, float) and np.isfinite(value)
            if not (number and value >= 0):
                raise invalid(f"got {shown(value)}", condition.parameters[key], key)
        if self.x_min is not None and self.x_max is not None:
            ordered(self.x_min, self.x_max)
        return self

    @property
    def parameters(self) -> dict[str, float]:
        """The condition's parameters (numbers >= 0)."""
        return {key: float(value) for key, value in (self.model_extra or {}).items()}

    @model_serializer
    def _flat(self) -> dict[str, Any]:
        data: dict[str, Any] = {"condition": self.condition, **(self.model_extra or {})}
        data.update({key: getattr(self, key) for key in ("x_min", "x_max") if getattr(self, key) is not None})
        return data


def _file_in(info: ValidationInfo, name: Path) -> Path:
    """``name`` relative to the scenario file's directory (the working directory without one)."""
    directory = (info.context or {}).get("directory") or Path.cwd()
    return Path(directory) / name


def _profile_array(read: typing.Callable[[], np.ndarray], key: str) -> np.ndarray:
    """The points of a profile read from a file: an :class:`InputError` (a bad file) becomes
    a validation error of ``key``, reported with the scenario file and line."""
    try:
        return read()
    except InputError as exc:
        message, _, accepted = str(exc).partition("; accepted: ")
        raise invalid(message, accepted, key) from None


class Bed(StrictModel):
    """Bed elevation b(x) on the inclined plane: flat, piecewise linear through points, or
    read from a CSV file or a GeoTIFF DEM (turned into ``points`` on loading)."""

    profile: Literal["flat", "points", "file", "dem"] | None = field(
        None, "flat, points (with points), file (with file) or dem (with dem and polyline)"
    )
    points: list[Point] | None = field(None, "a list [[x, b], ...] with increasing x (m)")
    file: Annotated[Path, Strict(False)] | None = field(
        None, "a CSV file with a header 'x (m), z (m)' (units m, cm, mm or km), relative to the scenario"
    )
    frame: Literal["slope", "map"] | None = field(
        None, "slope (x along the plane, z normal to it; default) or map (horizontal distance, elevation)"
    )
    dem: Annotated[Path, Strict(False)] | None = field(
        None, "a GeoTIFF DEM, relative to the scenario (needs pip install 'multilayer[dem]')"
    )
    polyline: list[Point] | None = field(
        None, "a list of at least 2 map points [[X, Y], ...] in the DEM's coordinates (m)"
    )
    spacing: float | None = field(None, "a number > 0 (m); default: the DEM's pixel size", gt=0)
    extend: Literal["flat"] | None = field(
        None, "flat: the profile continued level beyond its ends where it does not span the domain"
    )

    _files = field_validator("file", "dem", mode="before")(messages.file_name)

    _map_points: np.ndarray | None = PrivateAttr(None)
    """A map-frame profile [[s, Z], ...], turned into ``_read`` with the scenario's slope."""
    _read: np.ndarray | None = PrivateAttr(None)
    """A slope-frame profile [[x, b], ...] read from a file or a DEM, x strictly increasing
    (the reading checks it), turned into ``points`` at the mesh by :meth:`resample`: as
    an array (shared by every scenario reading the file), a member of a sweep of a bed
    of 10^6 rows costs no list of its rows."""

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
        check_kind(
            self,
            "profile",
            {
                "flat": ((), ()),
                "points": (("points",), ("extend",)),
                "file": (("file",), ("frame", "extend")),
                "dem": (("dem", "polyline"), ("spacing", "extend")),
            },
        )
        if self.profile == "file":
            path = _file_in(info, typing.cast(Path, self.file))
            points = _profile_array(lambda: profiles.shared_csv_profile(path, ("x", "z|b")), "file")
            if self.frame == "map":
                self._map_points = points
            else:
                self._read = points
        elif self.profile == "dem":
            polyline = typing.cast(list[list[float]], self.polyline)
            if len(polyline) < 2:
                raise invalid(
                    "needs at least 2 points", "a list [[X, Y], ...] of 2 or more points", "polyline"
                )
            path = _file_in(info, typing.cast(Path, self.dem))
            self._map_points = _profile_array(
                lambda: profiles.read_dem_profile(path, polyline, self.spacing), "dem"
            )
        if self.points is not None:
            increasing(self.points, "points", "b")
        return self

    def in_slope_frame(self, slope_deg: float) -> None:
        """Turn a map-frame profile (``frame: map`` or a DEM) into the slope frame."""
        map_points = self._map_points
        if map_points is not None:
            source = self.dem or self.file
            self._read = _profile_array(
                lambda: profiles.shared_slope_frame(map_points, slope_deg, str(source)),
                f"bed.{'dem' if self.dem else 'file'}",
            )
            self._map_points = None

    def check_extent(self, domain: Domain) -> None:
        """A profile spans the domain ``[x_min, x_max]`` unless ``extend: flat`` asks to
        continue it level beyond its ends: a profile of a file or a DEM ending short of the
        domain was continued level silently (the engine interpolates), a terrain the
        scenario never gave."""
        if self.extend == "flat" or (self._read is None and not self.points):
            return
        points = self._read if self._read is not None else typing.cast(list[list[float]], self.points)
        first, last = float(points[0][0]), float(points[-1][0])
        if first <= domain.x_min and last >= domain.x_max:
            return
        source = f"{self.dem or self.file} " if self.dem or self.file else ""
        raise invalid(
            f"the profile {source}spans x = [{first:g}, {last:g}] m (along the slope), short of the domain "
            f"[{domain.x_min:g}, {domain.x_max:g}] m",
            "a profile reaching both ends of the domain, or extend: flat to continue it level past its ends",
            "bed.dem" if self.dem else "bed.file" if self.file else "bed.points",
        )

    def resample(self, domain: Domain) -> None:
        """A profile read from a file with more points than ``domain`` has cells, sampled
        once at the cell centres (where the engine samples the bed) and at the two ends:
        the run is the same, and its record (every checkpoint, ``result.nc``) stays the
        size of the mesh.  Only the rows around the samples are looked at
        (:func:`~multilayer.scenario.profiles.sampled`): validating a scenario again costs
        no work per row of a file already read."""
        read, self._read = self._read, None
        if read is None:
            return
        if len(read) <= domain.cells + 2:
            self.points = read.tolist()
            return
        x = np.concatenate(
            [[domain.x_min], cell_centres(domain.x_min, domain.x_max, domain.cells), [domain.x_max]]
        )
        self.points = np.column_stack([x, profiles.sampled(read, x)]).tolist()

    def check_resolution(self, domain: Domain, dry: float) -> None:
        """The thickness is resolved against the bed: the engine computes the free surface
        ``h + b`` (the transport's well-balanced faces, the pressures), whose round-off is
        the spacing of the floats at ``b``.  A column on a flat bed shifted to 1e15 m ran
        its front to 0.094 m, not 0.131 m, with no message (1e12 m changed ``h`` by 6e-5
        m).  Every elevation of the domain (a point inside it or the profile at an end,
        where the largest lie) is below ``2^53`` times the largest power of two within
        ``numerics.dry_threshold``, so that spacing is at most the dry threshold, the
        thinnest thickness the model tells from none."""
        if not self.points:
            return
        px, pb = np.asarray(self.points, dtype=float).T
        inside = pb[(px >= domain.x_min) & (px <= domain.x_max)]
        ends = np.interp([domain.x_min, domain.x_max], px, pb)
        highest = float(np.max(np.abs(np.concatenate([inside, ends]))))
        limit = math.ldexp(1.0, math.floor(math.log2(dry)) + 53)
        if highest >= limit:
            raise invalid(
                f"an elevation of {highest:.6g} m in the domain, where floats are "
                f"{np.spacing(highest):.3g} m apart: coarser than numerics.dry_threshold = {dry:g} m (the "
                "free surface h + b is computed; the thickness would be resolved no finer)",
                f"elevations of magnitude below {limit:.6g} m in the domain (the datum of b is free: "
                "subtract a constant)",
                "bed.dem" if self.dem else "bed.file" if self.file else "bed.points",
            )

    @model_serializer(mode="wrap")
    def _as_points(self, handler: typing.Callable[[Bed], dict[str, Any]]) -> dict[str, Any]:
        """A bed read from a file is recorded as its points, so the record stands alone.  A
        value of another type assigned after loading (``scenario.bed = None``, a mapping) is
        written as it is, for the validation again to read (pydantic calls this with it)."""
        data = handler(self)
        if not isinstance(self, Bed):  # reading its attributes: an AttributeError naming this function
            return data
        if self.profile in ("file", "dem"):
            extend = {"extend": self.extend} if self.extend else {}
            return {"profile": "points", "points": data["points"], **extend}
        return data


class Velocity(StrictModel):
    """Initial or inflow velocity profile over the depth (z above the bed)."""

    profile: Literal["plug", "linear", "bagnold"] = field(..., "plug, linear or bagnold")
    speed: float | None = field(None, "a number (m/s)")
    shear_rate: float | None = field(None, "a number (1/s)")
    from_height: float | None = field(None, "a number >= 0 (m); default 0", ge=0)
    surface_speed: float | None = field(None, "a number (m/s)")

    @model_validator(mode="after")
    def _check(self) -> Velocity:
        check_kind(
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

    def extremes(self, thickness: float) -> list[float]:
        """The slowest and fastest velocities (m/s) of the profile over a column ``thickness``
        thick: a plug's one speed; a linear profile's and Bagnold's at the bed (0) and at the
        surface, where they are monotone in between."""
        if self.profile == "plug":
            return [self.speed or 0.0]
        if self.profile == "linear":  # linear above from_height, 0 below
            return [0.0, (self.shear_rate or 0.0) * max(thickness - (self.from_height or 0.0), 0.0)]
        return [0.0, self.surface_speed or 0.0]


class SharedRows:
    """The rows of a profile file in a Python-mode dump of a scenario: equal to the dump of
    the same shared array (:func:`~multilayer.scenario.profiles.shared_csv_profile`), so
    that recording and comparing a scenario's keys (``Scenario.validated``) copies and
    compares none of its rows."""

    __slots__ = ("rows",)

    def __init__(self, rows: np.ndarray) -> None:
        self.rows = rows

    def __eq__(self, other: object) -> bool:
        return isinstance(other, SharedRows) and other.rows is self.rows

    def __hash__(self) -> int:
        return id(self.rows)

    def __repr__(self) -> str:
        return f"SharedRows({len(self.rows)} rows)"


class InitialShape(StrictModel):
    """One contribution to the initial thickness (contributions add up)."""

    shape: Literal["layer", "rectangle", "profile"] = field(..., "layer, rectangle or profile")
    thickness: float | None = field(None, "a number >= 0 (m); 0: no layer", ge=0)
    x_min: float | None = field(None, "a number (m)")
    x_max: float | None = field(None, "a number > x_min (m)")
    height: float | None = field(None, "a number > 0 (m)", gt=0)
    points: list[Point] | None = field(None, "a list [[x, h], ...] with increasing x, h >= 0 (m)")
    file: Annotated[Path, Strict(False)] | None = field(
        None, "a CSV file with a header 'x (m), h (m)' (units m, cm, mm or km), relative to the scenario"
    )
    velocity: Velocity | None = field(None, "a velocity profile; default: at rest")
    phi: float | None = field(None, f"{_PACKING}, with fluid only", gt=0, lt=closure.DENSEST_PACKING)

    _file = field_validator("file", mode="before")(messages.file_name)

    @model_validator(mode="after")
    def _check(self, info: ValidationInfo) -> InitialShape:
        if self.shape == "profile" and self.file is not None:
            if self.points is not None:
                raise invalid("give points or file, not both", "points or file", "file")
            path = _file_in(info, self.file)
            rows = _profile_array(lambda: profiles.shared_csv_profile(path, ("x", "h")), "file")
            if profiles.value_range(rows)[0] < 0:
                raise invalid("negative thickness", "a list [[x, h], ...] with h >= 0", "file")
            # the file's rows as one read-only array shared by every scenario reading the file
            # (x increasing, checked by the parser): a member of a study reading a file read
            # before costs no work per row of it (no list of its rows, no check of them again)
            self.points = typing.cast(list[Point], rows)
        check_kind(
            self,
            "shape",
            {
                "layer": (("thickness",), ("velocity", "phi")),
                "rectangle": (("x_min", "x_max", "height"), ("velocity", "phi")),
                "profile": (("points",), ("velocity", "file", "phi")),
            },
        )
        if self.shape == "rectangle":
            assert self.x_min is not None and self.x_max is not None  # required (checked above)
            ordered(self.x_min, self.x_max)
        if self.shape == "profile" and self.file is None:
            assert self.points is not None  # required (checked above)
            increasing(self.points, "points", "h")
            if any(h < 0 for _, h in self.points):
                raise invalid("negative thickness", "a list [[x, h], ...] with h >= 0", "points")
        return self

    @field_serializer("points", mode="wrap")
    def _rows(self, value: Any, handler: SerializerFunctionWrapHandler, info: FieldSerializationInfo) -> Any:
        """A file's rows (an array) as a list in a text (JSON mode, ``resolved_yaml``), as
        :class:`SharedRows` in Python mode."""
        if isinstance(value, np.ndarray):
            if (info.context or {}).get("rows") == "omitted":  # Scenario.text_size
                return []
            return value.tolist() if info.mode == "json" else SharedRows(value)
        return handler(value)

    @model_serializer(mode="wrap")
    def _as_points(self, handler: typing.Callable[[InitialShape], dict[str, Any]]) -> dict[str, Any]:
        """A profile read from a file is recorded as its points, so the record stands alone.  A
        value of another type assigned after loading (``scenario.initial.append(None)``) is
        written as it is, for the validation again to name it (pydantic calls this with it)."""
        data = handler(self)
        if isinstance(data, dict):
            data.pop("file", None)
        return data


class Inflow(StrictModel):
    """State imposed at an ``inflow`` boundary."""

    thickness: float = field(..., "a number > 0 (m)", gt=0)
    velocity: Velocity = field(..., "a velocity profile")


class Boundaries(StrictModel):
    """Boundary conditions at x_min (left) and x_max (right) (``multilayer.engine.transport.boundaries``)."""

    left: str = field("wall", lateral.accepted())
    right: str = field("wall", lateral.accepted())
    inflow: Inflow | None = field(None, "{thickness, velocity} (with an inflow side)")

    @field_validator("left", "right")
    @classmethod
    def _known(cls, value: str) -> str:
        if value not in lateral.BOUNDARIES:
            raise invalid(f"got {shown(value)}", lateral.accepted())
        return value

    @model_validator(mode="after")
    def _check(self) -> Boundaries:
        left, right = lateral.BOUNDARIES[self.left], lateral.BOUNDARIES[self.right]
        if left.wraps != right.wraps:
            key, name = ("right", left.name) if left.wraps else ("left", right.name)
            raise invalid(f"{name} must be set on both sides", f"{name} on both sides", key)
        fed = [side.name for side in (left, right) if side.needs_state]
        if fed and self.inflow is None:
            raise invalid(
                f"an {fed[0]} side requires boundaries.inflow",
                "{thickness: h, velocity: {profile: plug, speed: u}}",
                "inflow",
            )
        if self.inflow is not None and not fed:
            raise invalid("inflow given but no side is inflow", "left: inflow or right: inflow", "inflow")
        return self


class GateSpec(StrictModel):
    """A gate holding the initial column, lifted at the start of the run (engine/gate.py)."""

    x: float = field(
        ..., "a number in (domain.x_min + dx/2, domain.x_max - dx/2] (m); snapped to the nearest cell face"
    )
    lift_speed: float = field(
        ..., "a number >= 0 (m/s), normal to the plane; .inf: instantaneous release", ge=0, allow_inf_nan=True
    )


class Time(StrictModel):
    """Time stepping and output (s)."""

    end: float = field(..., "a number > 0 (s)", gt=0)
    cfl: float = field(0.45, "a number in (0, 1)", gt=0, lt=1)
    output_interval: float = field(..., "a number > 0 (s)", gt=0)

    @model_validator(mode="after")
    def _check(self) -> Time:
        if self.end < limits.MIN_END:
            raise invalid(
                f"{self.end!r} s, too short to step (half of a denormal step is zero)",
                f"a number >= {limits.MIN_END:g} (s)",
                "end",
            )
        outputs = self.end / self.output_interval
        if not outputs <= limits.MAX_OUTPUT_TIMES:
            raise invalid(
                f"{outputs:.3g} output times to time.end = {self.end:g} s",
                f"at most {limits.MAX_OUTPUT_TIMES} output times: an interval of at least "
                f"{self.end / limits.MAX_OUTPUT_TIMES:.3g} s",
                "output_interval",
            )
        return self


class Output(StrictModel):
    """Where results go."""

    directory: Annotated[Path, Strict(False)] | None = field(
        None, "a directory path (a leading ~ is the home directory); default results/<name>"
    )

    _directory = field_validator("directory", mode="before")(directory_path)


ExpectKind = Literal["regression", "reference"]
EXPECT_KINDS: tuple[str, ...] = get_args(ExpectKind)
ExactSolutionName = Literal["coulomb_dam_break", "inviscid_simple_shear", "bagnold", "granular_blasius"]
EXACT_SOLUTIONS: tuple[str, ...] = get_args(ExactSolutionName)
"""Exact solutions an ``expect`` entry can compare with (multilayer.app.exact_solutions)."""


class ExactComparison(StrictModel):
    """A field of the run's final state against an exact solution, by a relative norm."""

    solution: ExactSolutionName = field(..., ", ".join(EXACT_SOLUTIONS))
    field: Literal["h", "u", "displacement_thickness"] = field(
        ..., "h, u (the layer velocities) or displacement_thickness"
    )
    # ``field`` names the key above from here on: the helper is reached through its module
    norm: Literal["l1", "max"] = messages.field(..., "l1 or max (relative to the exact field's own norm)")
    x_min: float | None = messages.field(None, "a number (m); default: the whole domain")
    x_max: float | None = messages.field(None, "a number > x_min (m); default: the whole domain")

    @model_validator(mode="after")
    def _check(self) -> ExactComparison:
        if self.x_min is not None and self.x_max is not None:
            ordered(self.x_min, self.x_max)
        return self


class Expect(StrictModel):
    """A check on the run summary, passing when ``|actual - value| <= atol + rtol |value|``.

    ``kind: regression`` pins ``value`` from the code's own output (it guards against
    change, it validates nothing); ``kind: reference`` takes ``value`` from an exact
    solution or a published result named in ``source``, the tolerance being justified by
    that reference's uncertainty or by a convergence study.  With ``exact`` (a reference)
    the checked value is the error norm of the comparison, expected 0 within ``atol``.
    """

    kind: ExpectKind = field(
        ..., "regression (a value pinned from the code's output) or reference (an exact or published value)"
    )
    quantity: Quantity | None = field(None, ", ".join(QUANTITIES))
    value: float | None = field(None, "a number (SI)")
    exact: ExactComparison | None = field(None, "{solution, field, norm, x_min, x_max} (reference only)")
    rtol: float | None = field(None, "a number >= 0", ge=0)
    atol: float | None = field(None, "a number >= 0 (SI)", ge=0)
    source: str | None = field(None, "text naming the exact solution or publication (author, year, equation)")

    @model_validator(mode="after")
    def _check(self) -> Expect:
        if self.exact is not None:
            if self.kind != "reference":
                raise invalid("a comparison with an exact solution is a reference", "reference", "kind")
            check_kind(self, "kind", {"reference": (("exact", "atol", "source"), ())})
        else:
            if self.rtol is None and self.atol is None:
                raise invalid("needs a tolerance", "rtol and/or atol", "rtol")
            needed, tolerances = ("quantity", "value"), ("rtol", "atol")
            check_kind(
                self,
                "kind",
                {"regression": (needed, tolerances), "reference": ((*needed, "source"), tolerances)},
            )
        if self.source is not None and not self.source.strip():
            raise invalid("source is empty", "text naming the exact solution or publication", "source")
        if not math.isfinite(self.tolerance):  # value 1e308, rtol 10: inf, and 0.16 passed for 1e308
            raise invalid(
                f"atol + rtol |value| = {self.atol or 0.0!r} + {self.rtol or 0.0!r} x "
                f"{abs(self.value or 0.0)!r} overflows: every result would pass",
                "a tolerance atol + rtol |value| below 1.8e308",
                self._tolerance_key(),
            )
        if self.quantity is not None and self.value is not None:
            self._check_range(self.quantity, self.value)
        return self

    def _check_range(self, quantity: str, value: float) -> None:
        """The interval ``value +- tolerance`` must meet the values ``quantity`` can take
        (:data:`QUANTITY_RANGES`; all finite numbers for a quantity not listed) and must
        not hold them all: a pin no run passes, or one every run passes (``atol: 1e308``
        on a packing, ``value: 0.3, rtol: 2``)."""
        low, high, accepted = QUANTITY_RANGES.get(quantity, (-math.inf, math.inf, "any number"))
        if value + self.tolerance < low or value - self.tolerance > high:
            raise invalid(
                f"{quantity} = {value!r} +- {self.tolerance:.3g}: no run passes (its {quantity} is "
                f"{accepted})",
                f"a value whose interval value +- (atol + rtol |value|) holds values {accepted}",
                "value",
            )
        bottom, top = max(low, -sys.float_info.max), min(high, sys.float_info.max)  # as floats
        if value - self.tolerance <= bottom and value + self.tolerance >= top:
            bound = max(value - bottom, top - value)  # the interval holding an end, not both
            raise invalid(
                f"{quantity} = {value!r} +- {self.tolerance:.3g} holds every value a run's {quantity} "
                f"can take ({accepted}): every run passes, a check of nothing",
                f"a tolerance atol + rtol |value| below {bound:.6g} for this value",
                self._tolerance_key(),
            )

    def _tolerance_key(self) -> str:
        """The key of the larger part of :attr:`tolerance`: ``atol`` or ``rtol``."""
        return "rtol" if (self.rtol or 0.0) * abs(self.value or 0.0) > (self.atol or 0.0) else "atol"

    @property
    def tolerance(self) -> float:
        """The allowed absolute deviation, ``atol + rtol |value|`` (a missing one counts as 0)."""
        return (self.atol or 0.0) + (self.rtol or 0.0) * abs(self.value or 0.0)


_ORDER = "1 or 2 (order of the transport step in x and t)"


class Numerics(StrictModel):
    """Solver settings; the defaults suit every shipped scenario."""

    vertical_solver: Literal["kernel", "fipy"] = field("kernel", "kernel or fipy")
    transport_solver: Literal["kernel", "numpy"] = field("kernel", "kernel or numpy")
    threads: Any = field("auto", THREADS_ACCEPTED)
    order: Literal[1, 2] = field(2, _ORDER)
    tolerance: float = field(
        1e-10,
        f"a number >= {limits.MIN_TOLERANCE:g} (relative to the velocity scale; below, round-off decides)",
        ge=limits.MIN_TOLERANCE,
    )
    max_iterations: int = field(
        200, f"an integer from 1 to {limits.MAX_ITERATIONS}", ge=1, le=limits.MAX_ITERATIONS
    )
    dry_threshold: float = field(1e-6, "a number > 0 (m), below numerics.front_threshold", gt=0)
    front_threshold: float = field(1e-3, "a number > 0 (m)", gt=0)

    @model_validator(mode="after")
    def _dry_below_front(self) -> Numerics:
        # a 5 cm column on a 25 degree slope with a dry threshold of 1 m stayed at rest, exit 0
        if not self.dry_threshold < self.front_threshold:
            raise invalid(
                f"{self.dry_threshold!r} m, not below front_threshold = {self.front_threshold!r} m: the "
                "material thick enough to make the front would be dry, held at rest",
                "a number > 0 below numerics.front_threshold (m)",
                "dry_threshold",
            )
        return self

    @field_validator("order", mode="before")
    @classmethod
    def _order(cls, value: Any) -> Any:
        if type(value) is not int:  # a Literal matches by equality: true and 2.0 were taken
            raise invalid(f"got {shown(value)}", _ORDER)
        return value

    @field_validator("threads")
    @classmethod
    def _threads(cls, value: Any) -> int | str:
        if value == "auto" or (type(value) is int and value >= 1):
            return value
        raise invalid(f"got {shown(value)}", THREADS_ACCEPTED)


class Model(StrictModel):
    """Model options: the pressure that enters the stresses and its options, flat in YAML
    (``{pressure: non_hydrostatic, pressure_layers: 4}``; docs/nonhydrostatic.md)."""

    model_config = ConfigDict(extra="allow")

    pressure: str = field("hydrostatic", pressure_models.accepted())
    normal_stress: bool = field(
        False, "true or false: the longitudinal normal stress of each layer (docs/model.md)"
    )

    @field_validator("pressure")
    @classmethod
    def _known(cls, value: str) -> str:
        if value not in pressure_models.models():
            raise invalid(f"got {shown(value)}", pressure_models.accepted())
        return value

    @property
    def options(self) -> dict[str, Any]:
        """The options given for the pressure model (``model.<option>``)."""
        return dict(self.model_extra or {})

    def check_options(self, layers: int) -> None:
        """Each option given must be one of the pressure model's, with a value it accepts
        for ``layers`` layers (an option of another model is named with that model)."""
        chosen = pressure_models.models()[self.pressure]
        for key, value in self.options.items():
            owner = next((m for m in pressure_models.models().values() if key in m.options), None)
            if owner is None:
                raise invalid("unknown key", ", ".join(("pressure", *chosen.options)), f"model.{key}")
            option = owner.options[key]
            if owner is not chosen or not option.valid(value, layers):
                raise invalid(
                    f"got {shown(value)} with pressure {self.pressure} and {layers} layers",
                    f"{option.accepted.format(layers=layers)}, with pressure: {owner.name}",
                    f"model.{key}",
                )


class Fluid(StrictModel):
    """The pore and ambient fluid of a grain–fluid mixture (docs/mixture.md)."""

    density: float = field(..., "a number >= 0 (kg/m^3), below material.particle_density", ge=0)
    viscosity: float = field(..., "a number >= 0 (Pa s)", ge=0)
    compressibility: float | None = field(
        None,
        "a number in (0, 1] (1/Pa): the grain skeleton's compressibility alpha, the excess pore "
        "pressure at the bottom of each layer relaxing towards the closure's over alpha times its Darcy "
        "coefficient (beta h^2 / (2 (1 - phi)^2) for one layer); default: the closure's at once",
        gt=0,
        le=1,
    )


class Mixture(StrictModel):
    """The dilatancy closure of a grain–fluid mixture (docs/mixture.md)."""

    phi_critical: float = field(
        ..., f"{_PACKING}: the critical volume fraction at rest", gt=0, lt=closure.DENSEST_PACKING
    )
    dilatancy: float = field(..., "a number >= 0: K of tan(psi) = K (phi - phi_eq)", ge=0)
    critical_shift: float = field(..., "a number >= 0: K2 of phi_eq = phi_c - K2 eta_f gamma / p_s", ge=0)
    kozeny: float = field(150.0, "a number > 0: the Carman-Kozeny constant; default 150", gt=0)


class Scenario(StrictModel):
    """A validated scenario: attribute names are the YAML keys (docs/scenarios.md)."""

    name: str = field(
        ...,
        "letters, digits, '-', '_' and '.', starting with a letter or digit, at most 255 of them "
        "(the default output directory is results/<name>, and a file name has at most 255 bytes)",
        pattern=r"^[A-Za-z0-9][A-Za-z0-9_.-]*$",
        max_length=255,
    )
    description: str | None = field(None, "free text")
    gravity: float = field(9.81, "a number > 0 (m/s^2)", gt=0)
    slope_deg: float = field(0.0, "a number in (-90, 90) (degrees)", gt=-90, lt=90)
    domain: Domain = field(..., "a mapping with x_min, x_max, cells")
    material: MaterialSpec = field(..., "a mapping with density, grain_diameter")
    rheology: PluginSpec = field(..., "{name: <bulk rheology>, <parameters>}")
    walls: PluginSpec | None = field(None, "{name: <walls rheology>, <parameters>}")
    base: list[BaseZone] = field(
        [BaseZone(condition="no_slip")], "a non-empty list of {condition, ...}", min_length=1
    )
    bed: Bed = field(Bed(), "{profile: flat} or {points: [[x, b], ...]}")
    initial: list[InitialShape] = field(
        [],
        f"a list of at most {limits.MAX_INITIAL_ENTRIES} {{shape, ...}}",
        max_length=limits.MAX_INITIAL_ENTRIES,
    )
    boundaries: Boundaries = field(Boundaries(), "a mapping with left, right")
    gate: GateSpec | None = field(None, "{x, lift_speed}; default: no gate")
    time: Time = field(..., "a mapping with end, output_interval")
    output: Output = field(Output(), "a mapping with directory")
    expect: list[Expect] = field([], "a list of {kind, quantity, value, rtol, atol, source}")
    numerics: Numerics = field(Numerics(), "a mapping of solver settings")
    model: Model = field(Model(), "a mapping with pressure")
    fluid: Fluid | None = field(None, "{density, viscosity}; default: dry grains")
    mixture: Mixture | None = field(None, "{phi_critical, dilatancy, critical_shift, kozeny}, with fluid")

    _source: Path | None = PrivateAttr(None)
    _validated: dict[str, Any] | None = PrivateAttr(None)

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
        self.bed.check_extent(self.domain)
        self.bed.resample(self.domain)
        self.bed.check_resolution(self.domain, self.numerics.dry_threshold)
        self.model.check_options(self.domain.layers)
        self._check_thinnest_layer()
        self._check_inflow_finite()
        if self.walls is not None and self.domain.width is None:
            raise invalid(
                "walls need the channel width domain.width",
                "domain.width > 0 (m) together with walls",
                "walls",
            )
        width, grain = self.domain.width, self.material.grain_diameter
        length = self.domain.x_max - self.domain.x_min
        if grain > length:  # 1e308 m: a mu(I) law's d sqrt(rho_p) overflowed, its viscosity NaN
            raise invalid(
                f"grains {grain:g} m across, longer than the domain ({length:g} m): no continuum of grains",
                f"a diameter <= domain.x_max - domain.x_min = {length:g} m",
                "material.grain_diameter",
            )
        if width is not None and width < grain:  # 5e-324 m: 2 / W infinite, NaN wall forces
            raise invalid(
                f"a channel {width:g} m wide, narrower than one grain (material.grain_diameter = "
                f"{grain:g} m): the side walls' friction on the continuum between them (2 / W) h tau_w "
                "has no meaning",
                f"a width >= material.grain_diameter = {grain:g} m",
                "domain.width",
            )
        if self.gate is not None:
            self._check_gate()
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
            raise invalid(
                f"no basal condition on x in [{gap[0]}, {gap[1]}]",
                "entries whose x ranges cover [domain.x_min, domain.x_max]",
                "base",
            )
        self._check_base_zones()
        self._check_mixture()
        self._check_front_threshold()
        self._check_inflow()
        self._check_expect_together()
        return self

    def _check_base_zones(self) -> None:
        """Every ``base`` entry is the condition of at least one column: a zone covers the
        cells whose centre ``x`` has ``x_min <= x < x_max`` and later entries win where they
        overlap (:func:`multilayer.engine.basal.columns`), so a zone between two cell centres
        or under later zones on all its cells was ignored, exit 0.  Index ranges only,
        nothing the size of the mesh: a sweep over the zones' ends in ``O(n log n)``."""
        dom = self.domain
        dx = (dom.x_max - dom.x_min) / dom.cells

        def centre(i: int) -> float:  # as mesh.cell_centres computes it
            return float(dom.x_min) + dx * (i + 0.5)

        def first(x: float) -> int:  # the first cell whose centre is >= x
            t = (x - dom.x_min) / dx - 0.5
            i = 0 if not t > 0 else dom.cells if t >= dom.cells else math.ceil(t)
            while i > 0 and centre(i - 1) >= x:
                i -= 1
            while i < dom.cells and centre(i) < x:
                i += 1
            return i

        spans = []
        for index, zone in enumerate(self.base):
            a = first(-math.inf if zone.x_min is None else zone.x_min)
            b = first(math.inf if zone.x_max is None else zone.x_max)
            if a >= b:
                raise invalid(
                    f"condition {zone.condition} on [{zone.x_min}, {zone.x_max}] m holds no cell centre "
                    f"(cells of {dx:.3g} m): it would apply to no column",
                    "a zone holding at least one cell centre domain.x_min + (i + 1/2) dx",
                    f"base.{index}",
                )
            spans.append((a, b))
        ends = sorted({e for span in spans for e in span})
        starting = sorted((a, index) for index, (a, _) in enumerate(spans))
        active: list[int] = []  # -index of the zones covering the segment (later ones win)
        applied, k = set(), 0
        for at in ends[:-1]:  # the segment of cells [at, next end)
            while k < len(starting) and starting[k][0] <= at:
                heapq.heappush(active, -starting[k][1])
                k += 1
            while active and spans[-active[0]][1] <= at:
                heapq.heappop(active)
            if active:
                applied.add(-active[0])
        for index, zone in enumerate(self.base):
            if index not in applied:
                raise invalid(
                    f"condition {zone.condition} on [{zone.x_min}, {zone.x_max}] m applies to no column: "
                    "later entries, which win where they overlap, cover every cell centre it holds",
                    "a zone holding a cell centre no later entry covers, or no entry",
                    f"base.{index}",
                )

    def _check_expect_together(self) -> None:
        """Two ``expect`` entries on one quantity whose intervals ``value +- tolerance`` do
        not meet: no run can pass both, and `multilayer check` ran the whole scenario to
        fail one of them (an entry copied and edited, its old pin kept)."""
        seen: dict[str, list[tuple[int, Expect]]] = {}
        for index, entry in enumerate(self.expect):
            if entry.quantity is None or entry.value is None:  # a comparison with an exact solution
                continue
            for first, other in seen.setdefault(entry.quantity, []):
                assert other.value is not None
                if abs(entry.value - other.value) > entry.tolerance + other.tolerance:
                    raise invalid(
                        f"{entry.quantity} = {entry.value!r} +- {entry.tolerance:.3g}, and expect.{first} "
                        f"asks {other.value!r} +- {other.tolerance:.3g}: no value passes both",
                        "entries on one quantity whose intervals value +- (atol + rtol |value|) meet, or "
                        "one entry per quantity",
                        f"expect.{index}.value",
                    )
            seen[entry.quantity].append((index, entry))

    FRONT_QUANTITIES: typing.ClassVar[tuple[str, ...]] = (
        "front_final",
        "runout",
        "static_interface_mean_final",
    )
    """The quantities of the summary measured where ``h`` is above the front threshold."""

    def thickest_cell(self) -> float | None:
        """An upper bound (m) of the thickness any cell can reach, or None with an inflow
        or a fluid: all the initial material in one cell (``h >= 0``, and without an inflow
        the volume only leaves through the boundaries; a grain-fluid mixture's volume grows
        as it dilates, ``d_t h = h Phi``, docs/mixture.md).  A front threshold above it
        finds no front at any output time (``front`` NaN throughout)."""
        if self.boundaries.inflow is not None or self.fluid is not None:
            return None
        lo, hi = self.domain.x_min, self.domain.x_max
        mass = 0.0  # an upper bound of the initial mass per unit width (m^2)
        for entry in self.initial:
            if entry.shape == "layer":
                mass += (entry.thickness or 0.0) * (hi - lo)
            elif entry.shape == "rectangle":
                assert entry.x_min is not None and entry.x_max is not None and entry.height is not None
                mass += entry.height * max(0.0, min(entry.x_max, hi) - max(entry.x_min, lo))
            else:
                rows = np.asarray(entry.points, dtype=float)  # a file's: its shared array
                overlap = max(0.0, min(float(rows[-1, 0]), hi) - max(float(rows[0, 0]), lo))
                mass += profiles.value_range(rows)[1] * overlap
        return mass / ((hi - lo) / self.domain.cells)

    def check_material(self) -> None:
        """:class:`InputError` for a run of nothing: no initial entry and no inflow (the run
        completed over an empty domain, a mass of 0 and no front at any output time, exit
        0).  A :class:`~multilayer.Simulation` may start empty (a state is loaded into it);
        a run may not."""
        if not self.initial and self.boundaries.inflow is None:
            raise InputError(
                f"{self._source or '<scenario>'}: initial: an empty list and no inflow: the run would "
                "hold no material at any time; accepted: at least one initial entry, or an inflow "
                "boundary (boundaries.left or boundaries.right: inflow)"
            )

    def front_never_found(self) -> str | None:
        """Why ``numerics.front_threshold`` finds no front at any output time, or None."""
        most, threshold = self.thickest_cell(), self.numerics.front_threshold
        if most is None or threshold <= most:
            return None
        return (
            f"{threshold!r} m is thicker than any cell can become (all the "
            f"initial material in one cell is {most:.3g} m thick and no boundary brings material in): "
            "the front is absent (NaN) at every output time"
        )

    def _check_front_threshold(self) -> None:
        """An ``expect`` entry on a quantity measured above the front threshold (the front,
        the run-out, the static interface's mean) that can never be found is refused: the
        check failed on NaN after the whole run.  Without such an entry the run goes on
        with a warning (a thin film studied for its mass and velocity has no front)."""
        asked = [e.quantity for e in self.expect if e.quantity in self.FRONT_QUANTITIES]
        why = self.front_never_found() if asked else None
        if why is not None:
            most = self.thickest_cell()
            raise invalid(
                f"{why}, and expect checks {', '.join(dict.fromkeys(map(str, asked)))}",
                f"a number > 0 (m) up to {most:.3g} m (below the thickest initial material to find "
                "the front from the start), or no expect entry on the front",
                "numerics.front_threshold",
            )

    def _normal_gravity(self) -> float:
        """``g cos(theta)`` (m/s^2), the gravity normal to the bed."""
        return self.gravity * math.cos(math.radians(self.slope_deg))

    def _check_inflow(self) -> None:
        """An inflow whose state leaves the domain faster than its waves can enter it (a
        velocity out of the domain of at least ``2 sqrt(g cos(theta) h)``, the speed of the
        front of a dam break of ``h``) brings no material in at any time: the run completed
        with an empty domain, a mass of 0 and no front, exit 0."""
        inflow = self.boundaries.inflow
        if inflow is None:
            return
        h = inflow.thickness
        speeds = inflow.velocity.extremes(h)
        waves = 2.0 * math.sqrt(self._normal_gravity() * h)
        for side, inward in (("left", 1.0), ("right", -1.0)):
            if not lateral.BOUNDARIES[getattr(self.boundaries, side)].needs_state:
                continue
            fastest_in = max(inward * s for s in speeds)
            if fastest_in + waves <= 0:
                raise invalid(
                    f"the {side} side's inflow moves out of the domain at {-fastest_in:.3g} m/s, no "
                    f"slower than its waves can enter (2 sqrt(g cos(slope_deg) h) = {waves:.3g} m/s for "
                    f"h = {h:g} m): no material would enter through it",
                    f"a velocity into the domain ({'> 0' if inward > 0 else '< 0'} at the {side} side), "
                    f"or out of it slower than {waves:.3g} m/s",
                    "boundaries.inflow.velocity",
                )

    def _check_gate(self) -> None:
        """The gate stands on a face inside the domain: on an end face the side's boundary
        holds or releases the material and a gate would make it leak or appear."""
        x, lo, hi, cells = self.gate.x, self.domain.x_min, self.domain.x_max, self.domain.cells  # type: ignore[union-attr]
        dx = (hi - lo) / cells
        accepted = (
            f"a number in ({lo + dx / 2:.6g}, {hi - dx / 2:.6g}] (m): the nearest cell face inside the domain"
        )
        if not lo <= x <= hi:
            raise invalid(f"gate at x = {x} is outside the domain", accepted, "gate.x")
        if gate_face(x, lo, dx, cells) in (0, cells):
            raise invalid(
                f"gate at x = {x} stands on an end face of the domain (the face of its cells nearest to x), "
                "where the side's boundary holds or releases the material",
                accepted,
                "gate.x",
            )

    def _check_inflow_finite(self) -> None:
        """The inflow's wave speed ``|u| + sqrt(g cos(theta) h)``, the momentum it brings in,
        ``h u^2 + g cos(theta) h^2 / 2``, and the pressure under it, ``density g cos(theta)
        h``, are finite numbers, checked here so that the message names the inflow (an
        inflow 1e308 m thick, or at 1e308 m/s, otherwise fails later in the checks of the
        time step or of the first step's state, which name other keys)."""
        inflow = self.boundaries.inflow
        if inflow is None:
            return
        h = inflow.thickness
        g_n = self._normal_gravity()
        u = max(abs(float(speed)) for speed in inflow.velocity.extremes(h))
        speed = u + math.sqrt(g_n * h)  # Python's floats: inf, no warning
        flux = h * u * u + g_n * h * h / 2.0
        pressure = self.material.density * g_n * h
        if not (math.isfinite(speed) and math.isfinite(flux) and math.isfinite(pressure)):
            raise invalid(
                f"an inflow {h:g} m thick at {u:g} m/s: its wave speed |u| + sqrt(g cos(slope_deg) h) = "
                f"{speed:.3g} m/s, the momentum it brings in, h u^2 + g cos(slope_deg) h^2 / 2 = "
                f"{flux:.3g} m3/s2, or the pressure under it, density g cos(slope_deg) h = {pressure:.3g} "
                "Pa, is no finite number",
                "an inflow whose thickness and speed, with the density and gravity, give a finite wave "
                "speed, momentum flux and pressure",
                "boundaries.inflow",
            )

    def _check_thinnest_layer(self) -> None:
        """The thinnest layer of a column at the dry threshold, the thinnest a wet column is,
        is a normal float (``limits.MIN_LAYER_THICKNESS``): a layer fraction of 5e-324 gives
        layers of 0 m, whose velocity (momentum over thickness) is no number."""
        fraction = float(layer_fractions(self.domain.layers, self.domain.layer_fractions).min())
        dry = self.numerics.dry_threshold
        if not fraction * dry >= limits.MIN_LAYER_THICKNESS:
            raise invalid(
                f"a layer fraction of {fraction:.3g}: in a column at numerics.dry_threshold = {dry:g} m, "
                f"the thinnest wet one, that layer is {fraction * dry:.3g} m thick, below the smallest "
                f"normal float {limits.MIN_LAYER_THICKNESS:.3g} (a layer's velocity is its momentum divided "
                "by its thickness)",
                f"layer fractions >= {limits.MIN_LAYER_THICKNESS:.3g} m / numerics.dry_threshold = "
                f"{limits.MIN_LAYER_THICKNESS / dry:.3g}, or a larger numerics.dry_threshold",
                "domain.layer_fractions",
            )

    def _check_mixture(self) -> None:
        """``fluid`` and ``mixture`` come together, with ``phi`` in every initial entry and
        what the mixture's step supports (docs/mixture.md)."""
        if (self.fluid is None) != (self.mixture is None):
            given, missing = ("fluid", "mixture") if self.mixture is None else ("mixture", "fluid")
            raise invalid(
                f"{given} is given without {missing}",
                "both fluid and mixture (a grain-fluid mixture), or neither",
                given,
            )
        for i, entry in enumerate(self.initial):
            if (entry.phi is None) != (self.fluid is None):
                need = "is required with fluid" if self.fluid is not None else "is accepted with fluid only"
                raise invalid(f"phi {need}", f"{_PACKING}, with fluid only", f"initial.{i}.phi")
        for i, check in enumerate(self.expect):
            if self.fluid is None and check.quantity in MIXTURE_QUANTITIES:
                raise invalid(
                    f"{check.quantity} is a quantity of a grain-fluid mixture",
                    ", ".join(q for q in QUANTITIES if q not in MIXTURE_QUANTITIES) + " without fluid",
                    f"expect.{i}.quantity",
                )
        if self.fluid is None:
            return
        grains = self.material.particle_density or self.material.density
        if not self.fluid.density < grains:
            raise invalid(
                f"fluid density {self.fluid.density} is not below the grain density {grains}",
                "a number >= 0 below material.particle_density (kg/m^3)",
                "fluid.density",
            )
        self._check_drag(grains)
        supported = (
            (self.model.pressure == "hydrostatic", "model.pressure", "hydrostatic with fluid"),
            (not self.model.normal_stress, "model.normal_stress", "false with fluid"),
            (self.walls is None, "walls", "no walls with fluid"),
            (self.gate is None, "gate", "no gate with fluid"),
            (
                not plugins.lookup(self.rheology.name, "bulk").uses,
                "rheology",
                "a law without 'uses' (dilatant_coulomb, drucker_prager, ...) with fluid",
            ),
            (self.boundaries.inflow is None, "boundaries", "wall, outflow or periodic sides with fluid"),
            (all(z.condition == "no_slip" for z in self.base), "base", "no_slip with fluid"),
        )
        refused = [(key, accepted) for ok, key, accepted in supported if not ok]
        if refused:  # one message naming every key the fluid excludes, at the first
            others = ", ".join(key for key, _ in refused[1:])
            also = f" (nor are {others})" if others else ""
            accepted = "; ".join(accepted for _, accepted in refused)
            raise invalid(f"not supported with a fluid{also}", accepted, refused[0][0])

    def _check_drag(self, grains: float) -> None:
        """The Darcy drag of every packing given (:func:`closure.drag`) is a finite number:
        the closure's pore pressures are products of it (docs/mixture.md)."""
        assert self.fluid is not None and self.mixture is not None  # with fluid (checked by the caller)
        d, eta, kozeny = self.material.grain_diameter, self.fluid.viscosity, self.mixture.kozeny
        packings = [(f"initial.{i}.phi", e.phi) for i, e in enumerate(self.initial)]
        for key, phi in [*packings, ("mixture.phi_critical", self.mixture.phi_critical)]:
            with np.errstate(all="ignore"):
                beta = closure.drag(np.float64(kozeny), np.float64(eta), np.float64(d), np.float64(phi))
                culprit = (
                    "material.grain_diameter"
                    if not np.isfinite(1.0 / np.float64(d * d))
                    else ("fluid.viscosity" if eta >= kozeny else "mixture.kozeny")
                )
            if not np.isfinite(beta):
                raise invalid(
                    f"the Darcy drag kozeny eta_f phi^2 / (d^2 (1 - phi)) at {key} = {phi} is {beta}",
                    "fluid.viscosity, material.grain_diameter and mixture.kozeny giving a finite drag",
                    culprit,
                )

    @property
    def source(self) -> Path | None:
        """The scenario file, or None for a scenario built from a mapping."""
        return self._source

    def input_files(self) -> dict[str, Path]:
        """The files the scenario reads (``bed.file`` or ``bed.dem``, ``initial.N.file``) by
        key, resolved as on loading: relative to the scenario file's directory (the working
        directory for a scenario built from a mapping)."""
        directory = files_directory(self._source) if self._source is not None else Path.cwd()
        files = {}
        for key in ("file", "dem"):
            name = getattr(self.bed, key)
            if name is not None:
                files[f"bed.{key}"] = directory / name
        for i, entry in enumerate(self.initial):
            if entry.file is not None:
                files[f"initial.{i}.file"] = directory / entry.file
        return files

    def resolved_yaml(self) -> str:
        """The scenario with every default filled in, as YAML that loads back to it
        (libyaml's emitter where PyYAML has it: four times faster than PyYAML's own).  A
        value of another type assigned since the validation is written as it is, without
        pydantic's warning: validating the text again names it."""
        return dump(self.model_dump(mode="json", exclude_none=True, warnings=False, fallback=_item))

    def assigned_nulls(self) -> list[tuple[str | int, ...]]:
        """The paths of the keys holding None whose default is not None (``scenario.bed =
        None`` assigned after loading): :meth:`resolved_yaml` leaves every None out, as
        not given, and the default would be validated in the place of a null that the
        file refuses at that key.  A None at a key whose default is None is not given, as
        the file's null there, and left out."""
        return _assigned_nulls(self, ())

    def text_size(self) -> int:
        """At least ``len(self.resolved_yaml())``, without writing the rows of a profile file
        (the estimate of a result's header): the text without them, and the text of each
        file's rows once per file, indented as they are written (4 characters more a row)."""
        data = self.model_dump(mode="json", exclude_none=True, warnings=False, context={"rows": "omitted"})
        rows = [typing.cast(np.ndarray, e.points) for e in self.initial if isinstance(e.points, np.ndarray)]
        return len(dump(data)) + sum(
            profiles.derived(r, "YAML size", lambda r: len(dump(r.tolist())) + 4 * len(r)) for r in rows
        )

    def validated(self) -> None:
        """Record the keys as validated (:func:`~multilayer.scenario.loading.from_dict`)."""
        self._validated = self.model_dump(warnings=False)

    def changed_since_validation(self) -> bool:
        """Whether a key was assigned since the scenario was validated, or it never was
        (pydantic checks no assignment: ``scenario.domain.layers = 0`` was built into a
        simulation whose kernels wrote outside their arrays)."""
        if self._validated is None:
            return True
        try:
            return not _same(self._validated, self.model_dump(warnings=False))
        except (PydanticSerializationError, ValueError, TypeError, OverflowError):  # unwritable: named again
            return True

    def assigned_keys(self) -> list[tuple[str | int, ...]]:
        """The paths of the keys whose value is not the validated one (of another type, or
        a value no serializer of the scenario writes: ``scenario.rheology.params = None``)."""
        return _changed(self, self._validated or {}, ())


def _changed(model: BaseModel, validated: Any, path: tuple[str | int, ...]) -> list[tuple[str | int, ...]]:
    """:meth:`Scenario.assigned_keys` of ``model`` at ``path``, against its validated dump."""
    found: list[tuple[str | int, ...]] = []
    validated = validated if isinstance(validated, dict) else {}
    for name, info in type(model).model_fields.items():
        value = getattr(model, name, None)
        old = validated.get(name, _ABSENT)
        if old is _ABSENT:  # not written (a rheology's parameters are written flat, a file as its rows)
            flat = isinstance(value, dict) and any(not _same(validated.get(k), v) for k, v in value.items())
            if flat or (value is None and info.get_default(call_default_factory=True) is not None):
                found.append((*path, name))
            continue
        if isinstance(value, BaseModel) and isinstance(old, dict):
            found += _changed(value, old, (*path, name))
        elif isinstance(value, list) and isinstance(old, list) and len(value) == len(old):
            for index, item in enumerate(value):
                if isinstance(item, BaseModel) and isinstance(old[index], dict):
                    found += _changed(item, old[index], (*path, name, index))
                elif not _same(old[index], item):
                    found.append((*path, name, index))
        elif not _same(old, value):
            found.append((*path, name))
    return found


_ABSENT = object()


def _item(value: Any) -> Any:
    """A value assigned since the validation that pydantic's serializer knows no type of,
    for :meth:`Scenario.resolved_yaml` (its ``PydanticSerializationError`` was a
    traceback): a numpy number or array (``scenario.slope_deg = np.float32(20)``) as the
    Python number or list it holds, as :func:`~multilayer.scenario.limits.plain_data` reads
    it; anything else, a long double beyond the floats included, as its text, which the
    validation names at its key."""
    if isinstance(value, np.ndarray) and value.dtype.kind in "biuf":
        value = value.tolist()
        return value if not isinstance(value, np.generic) else messages.shown(value)
    if isinstance(value, np.generic) and not isinstance(item := value.item(), np.generic):
        return item
    return messages.shown(value)


def _same(validated: Any, now: Any) -> bool:
    """Whether ``now`` holds the values of ``validated`` of the same types: a boolean or a
    float assigned in the place of an integer equal to it (``scenario.domain.cells = 40.0``,
    ``True`` for 1) is a change, which :meth:`Scenario.changed_since_validation` validates
    again (``==`` took it for the validated value, and the engine was built from it)."""
    if validated is now:
        return True
    if type(validated) is not type(now):
        return False
    if isinstance(validated, dict):
        return validated.keys() == now.keys() and all(_same(validated[k], now[k]) for k in validated)
    if isinstance(validated, list | tuple):
        return len(validated) == len(now) and all(map(_same, validated, now))
    if isinstance(validated, np.ndarray):
        return validated.dtype == now.dtype and bool(np.array_equal(validated, now))
    return bool(validated == now)


def _assigned_nulls(model: BaseModel, path: tuple[str | int, ...]) -> list[tuple[str | int, ...]]:
    """:meth:`Scenario.assigned_nulls` of ``model`` at ``path``, through its fields, the
    models they hold and the models in their lists."""
    found = []
    for name, info in type(model).model_fields.items():
        value = getattr(model, name, None)
        if value is None and (info.is_required() or info.get_default(call_default_factory=True) is not None):
            found.append((*path, name))
        items = list(enumerate(value)) if isinstance(value, list) else [(None, value)]
        for index, item in items:
            if isinstance(item, BaseModel):
                found += _assigned_nulls(item, (*path, name) if index is None else (*path, name, index))
    return found
