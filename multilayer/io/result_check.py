"""Whether a result file holds what it claims: the one check every reader makes first.

``plot``, ``export``, ``check``, ``summary``, sweeps, calibrations, ``--resume`` and
``run_failure`` read ``result.nc`` through :func:`check_result`.  A file is refused
(:class:`ResultFileError`, an :class:`InputError`: exit code 2, naming the file and what
is wrong) when

- it is not a netCDF file written by multilayer, or its header is damaged;
- it is shorter than its header declares (truncated: netCDF-C reads the missing bytes
  as zeros, without an error);
- its ``run_status`` is ``running``: a run is still writing it, or the process that
  wrote it ended without closing it;
- a record fails its checks: time finite and increasing, ``h`` finite and ``>= 0``,
  ``u`` finite, the static interface within ``[0, h]``, ``mass`` the integral of ``h``
  to round-off and ``front`` the front of ``h`` (what the writer computed from the same
  state), and the coordinates finite and increasing; the forces on the bed and the walls
  NaN in the first record only, and balancing the change of momentum between two records
  to round-off (``result_format.FORCES``; files written before these variables existed
  lack all of them); a mixture's solid volume fractions in ``[0, DENSEST_PACKING]`` (the
  densest packing of spheres) and its excess pore pressure finite;
- its ``run_status`` is ``completed`` and its records do not run from ``t = 0`` to its
  scenario's ``time.end`` (the first and last output times of every completed run,
  exactly): a file cut to its first records, its attributes kept (``ncks -d time,0,4``,
  or a header edited), was read as the run's answer at an earlier time;
- for a reader that takes the file as a run's answer (``use="answer"``), the run did
  not complete (failed, interrupted).

A reader that shows what was computed (``use="records"``: plot, export) also accepts a
failed or interrupted run, whose records are whole; ``--resume`` (``use="resume"``)
needs the first ``records`` records only, whatever the status.  The records are read
one at a time (memory of one record).
"""

from __future__ import annotations

import functools
import math
import os
from pathlib import Path
from typing import Literal

import netCDF4
import numpy as np
import psutil
import yaml

from multilayer.engine import diagnostics
from multilayer.engine.initial_state import bed_profile
from multilayer.engine.mesh import cell_centres
from multilayer.engine.mixture.closure import DENSEST_PACKING
from multilayer.errors import InputError, reason
from multilayer.io.netcdf_layout import LayoutError, read_layout
from multilayer.io.result_format import (
    FAILURE_LENGTH,
    FORCES,
    MIXTURE_VARIABLES,
    NETCDF_LOCK,
    STEPS_WRITTEN,
    VARIABLES,
    result_path,
)
from multilayer.scenario.limits import MAX_OUTPUT_TIMES
from multilayer.scenario.messages import shown
from multilayer.scenario.source import safe_load

Use = Literal["answer", "records", "resume"]
STATUSES = ("completed", "failed", "interrupted", "running")
ROUND_OFF = 64 * np.finfo(float).eps
"""Relative round-off allowed between ``mass`` and the integral of ``h``."""
BALANCE_ROUND_OFF = 1e-9
"""Relative round-off allowed in the momentum balance of the forces between two records
(the impulses of every step summed: far above the round-off of a run of 10^6 steps, far
below any damage)."""


class ResultFileError(InputError):
    """A result file that cannot be read as what it claims (exit code 2)."""


def check_result(path: str | os.PathLike, use: Use = "answer", records: int | None = None) -> Path:
    """Check the result file ``path`` (or ``path/result.nc``) for ``use`` (module
    docstring); returns its path, raises :class:`ResultFileError` naming what is wrong.
    ``records``: with ``use="resume"``, the records that must be whole."""
    file = result_path(path)
    if not file.is_file():
        missing = "not a regular file" if file.exists() else "no result file"
        raise ResultFileError(f"{file}: {missing}; accepted: the output directory of `multilayer run`")

    def bad(what: str, accepted: str = "a result file written by `multilayer run`, whole") -> ResultFileError:
        return ResultFileError(f"{file}: {what}; accepted: {accepted}")

    whole = _whole_records(file, bad)
    try:
        with NETCDF_LOCK, netCDF4.Dataset(file) as ds:
            status, scenario = _status(ds, file, bad)
            if use != "resume" and status == "running":
                raise bad(
                    "run_status is 'running': a run is still writing it, or the process writing it "
                    "ended without closing it (killed, or the machine stopped)",
                    "a finished run: wait for it to end, or continue it with `multilayer run "
                    "SCENARIO -o DIR --resume`",
                )
            if use == "answer" and status != "completed":
                why = f": {ds.getncattr('failure')}" if "failure" in ds.ncattrs() else ""
                raise bad(f"the run did not complete (run_status {status}{why})", "a completed run")
            count = len(ds.dimensions["time"]) if "time" in ds.dimensions else 0
            needed = count if records is None else min(records, count)
            if use == "resume" and records is not None and records > count:
                raise bad(f"it holds {count} output times, fewer than the {records} of its checkpoint")
            if whole < needed:
                raise bad(
                    f"truncated: {file.stat().st_size} bytes, {whole} of its {count} output times whole "
                    "(the file is shorter than its header declares)"
                )
            _check_records(ds, needed, scenario, bad)
            if use != "resume" and status == "completed":
                _check_span(ds, count, scenario, bad)
    except (OSError, RuntimeError, KeyError, IndexError, ValueError, TypeError) as exc:
        raise bad(f"not a readable multilayer result ({type(exc).__name__}: {reason(exc)})") from None
    return file


def _whole_records(file: Path, bad) -> int:
    """Records the file holds entirely, as its classic netCDF header declares them (all of
    them for a file in another netCDF format: netCDF-C checks those itself)."""
    try:
        layout = read_layout(file)
    except LayoutError as exc:
        with open(file, "rb") as stream:
            if stream.read(4) == b"\x89HDF":
                return 2**62
        raise bad(f"not a netCDF result file ({exc})") from None
    return layout.complete_records(file.stat().st_size)


SCENARIO_NUMBERS = (("slope_deg", False), ("material.density", True), ("time.end", True))
"""The entries of a result's scenario attribute its readers compute with (the figures'
slope frame, 0 where it is absent as in a scenario; the momentum balance; the span of a
completed run), and whether they must be there."""


STEPS = "an integer from 0 to 2^53 (the step counts a run writes)"

ATTRIBUTES = (
    ("steps", STEPS),
    ("wall_time_s", "a finite number >= 0"),
    ("multilayer_version", "text"),
    ("multilayer_commit", "text"),
)
"""The global attributes of a result its readers read (a study's summary of a member, the
version a resumed run compares with its own), with what they must be."""


def _attribute(value: object, kind: str) -> bool:
    """True when the attribute ``value`` (as netCDF4 reads it) is ``kind`` of :data:`ATTRIBUTES`
    (or "a finite number > 0 (m)")."""
    if kind == "text":
        return isinstance(value, str)
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        return False
    if kind == STEPS:  # an int32, or a float64 beyond it (ResultWriter.close)
        number = float(value)
        return math.isfinite(number) and number.is_integer() and 0 <= int(value) <= STEPS_WRITTEN
    number = float(value)
    return math.isfinite(number) and (number >= 0 if ">= 0" in kind else number > 0)


def _check_attributes(ds: netCDF4.Dataset, bad) -> None:
    """Raise ``bad(...)`` unless the attributes of :data:`ATTRIBUTES` and the front's
    ``threshold`` are there and what they must be: a sweep run again over its members read
    a damaged ``steps`` as a traceback of its summary, and a missing ``multilayer_version``
    was one of ``--resume``."""
    front = ds["front"]
    for owner, name, kind in [(ds, name, kind) for name, kind in ATTRIBUTES] + [
        (front, "threshold", "a finite number > 0 (m)")
    ]:
        whose = "its variable front's" if owner is front else "its"
        if name not in owner.ncattrs():
            raise bad(f"{whose} attribute {name} is missing")
        value = owner.getncattr(name)
        if not _attribute(value, kind):
            plain = value.item() if isinstance(value, np.generic) else value
            raise bad(f"{whose} attribute {name} is {shown(plain)}, not {kind}")


def _check_dimensions(ds: netCDF4.Dataset, scenario: dict, bad) -> None:
    """Raise ``bad(...)`` unless the dimensions of ``ds`` are those of its ``scenario`` (cells
    and layers; 2 bounds), it holds no more output times than a run writes and a record can
    be checked in the memory available now.  Its variables are read whole along x: a
    result in the netCDF-4 format (HDF5) whose x held 4e9 unwritten, compressed cells (a
    file of 63 kB) was a MemoryError traceback of ``plot``, one of 5e8 took 4.6 GB before
    it was refused, and one that fits in the memory exhausted it."""
    domain = scenario.get("domain")
    expected = {"x": "domain.cells", "layer": "domain.layers", "nv": ""}
    for name, key in expected.items():
        size = (domain.get(key.split(".")[1]) if isinstance(domain, dict) else None) if key else 2
        found = len(ds.dimensions[name]) if name in ds.dimensions else None
        if not (type(size) is int and found == size):
            where = f"its scenario attribute's {key} ({shown(size)})" if key else "2 (the bounds of a cell)"
            raise bad(f"its dimension {name} has {found} entries, not {where}")
    count = len(ds.dimensions["time"]) if "time" in ds.dimensions else 0
    if count > MAX_OUTPUT_TIMES + 2:  # every output time and the end
        raise bad(f"it holds {count} output times", f"at most {MAX_OUTPUT_TIMES + 2}, as a run writes them")
    cells, layers = len(ds.dimensions["x"]), len(ds.dimensions["layer"])
    needed = 8.0 * cells * (3 * layers + 12)  # a record, its momentum, the coordinates and the bed
    available = float(psutil.virtual_memory().available)
    if needed > available:
        raise bad(
            f"checking its {cells} cells x {layers} layers takes about {needed / 2**30:.3g} GiB of memory, "
            f"more than is available now ({available / 2**30:.3g} GiB)",
            "a result whose records fit in the memory of this machine",
        )


def _status(ds: netCDF4.Dataset, file: Path, bad) -> tuple[str, dict]:
    """The run status of ``ds`` and its scenario (read once for every check), having checked
    that the variables, the scenario and the attributes are those of a result."""
    missing = [name for name in VARIABLES if name not in ds.variables]
    if set(missing) == set(FORCES):  # written before the forces were
        missing = []
    if missing:
        raise bad(f"not a multilayer result: no variable {', '.join(missing)}")
    try:
        scenario = safe_load(str(ds.getncattr("scenario")))
    except (AttributeError, yaml.YAMLError):
        scenario = None
    if not isinstance(scenario, dict) or "name" not in scenario:
        raise bad("its scenario attribute is missing or damaged")
    for key, required in SCENARIO_NUMBERS:
        node: object = scenario
        for part in key.split("."):
            node = node.get(part) if isinstance(node, dict) else None
        if (required or node is not None) and not finite_number(node):
            raise bad(f"its scenario attribute's {key} is {shown(node)}, not a finite number")
    _check_attributes(ds, bad)
    _check_dimensions(ds, scenario, bad)
    given = ds.getncattr("run_status") if "run_status" in ds.ncattrs() else ""
    status = given if isinstance(given, str) else ""  # a number was said as text: '3'
    if status not in STATUSES:
        raise bad(f"run_status {shown(given)} is not one of {', '.join(STATUSES)}")
    _check_failure(ds, status, bad)
    return status, scenario


def _check_failure(ds: netCDF4.Dataset, status: str, bad) -> None:
    """Raise ``bad(...)`` unless the ``failure`` attribute is what a run writes: text of 1 to
    :data:`FAILURE_LENGTH` characters, there whenever ``run_status`` is ``failed`` (a run
    that failed says why, :meth:`~multilayer.io.results.ResultWriter.close`).  A number
    there was shown by ``plot`` as the reason ("the run failed: 3.5"), and a failed run
    without one as a failure without a reason."""
    if "failure" not in ds.ncattrs():
        if status == "failed":
            raise bad("run_status is 'failed' and its attribute failure (why) is missing")
        return
    value = ds.getncattr("failure")
    if not (isinstance(value, str) and 0 < len(value) <= FAILURE_LENGTH):
        plain = value.item() if isinstance(value, np.generic) else value
        raise bad(f"its attribute failure is {shown(plain)}, not text of 1 to {FAILURE_LENGTH} characters")


def finite_number(value: object) -> bool:
    """True for a finite ``int`` or ``float`` (not a ``bool``): a number of a file's text or
    attributes that its readers compute with."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


DECODING = (
    "scale_factor", "add_offset", "missing_value", "valid_min", "valid_max", "valid_range", "calendar",
    "_Unsigned",
)  # fmt: skip
"""Attributes that change the values a reader decodes (xarray's CF decoding): none is
written by multilayer."""


def _check_encoding(ds: netCDF4.Dataset, bad) -> None:
    """Raise ``bad(...)`` unless every variable of the format in ``ds`` has its dimensions
    and is decoded as written: its ``units`` (xarray decodes a time in ``seconds since
    2000-01-01`` as dates), no attribute of :data:`DECODING` and a ``_FillValue`` of NaN, if
    any (xarray masks the values equal to it: ``missing_value: 0`` made every dry cell NaN
    for ``plot`` and ``export``, where the checks, which read the values as written,
    passed them)."""
    for name, (dims, attrs) in {**VARIABLES, **MIXTURE_VARIABLES}.items():
        if name not in ds.variables:
            continue
        var = ds[name]
        if var.dimensions != dims:
            raise bad(f"its variable {name} is over {var.dimensions}, not {dims}")
        found = set(var.ncattrs())
        odd = [f"{key} {var.getncattr(key)}" for key in sorted(found.intersection(DECODING))]
        units = var.getncattr("units") if "units" in found else None
        if units != attrs.get("units"):
            odd.append(f"units {shown(units)}")
        fill = var.getncattr("_FillValue") if "_FillValue" in found else np.nan
        if not (isinstance(fill, float) and np.isnan(fill)):
            odd.append(f"_FillValue {fill}")
        if odd:
            raise bad(
                f"its variable {name} has {', '.join(odd)}, which multilayer does not write: read with "
                f"{'it' if len(odd) == 1 else 'them'}, its values are not those written"
            )


def _brackets(bounds: np.ndarray, centres: np.ndarray) -> bool:
    """True when ``bounds`` (n, 2) are finite and in order, each row around its centre."""
    return (
        bounds.shape == (centres.size, 2)
        and bool(np.all(np.isfinite(bounds)))
        and bool(np.all((bounds[:, 0] <= centres) & (centres <= bounds[:, 1])))
        and bool(np.all(np.diff(bounds[:, 0]) >= 0))
    )


def _check_span(ds: netCDF4.Dataset, count: int, scenario: dict, bad) -> None:
    """Raise ``bad(...)`` unless the records of the completed run ``ds`` (``count`` of them)
    start at ``t = 0`` and end at its ``scenario``'s ``time.end``, exactly."""
    end = scenario["time"]["end"]  # a finite number, by _status
    times = np.asarray(ds["time"][:count], dtype=float) if count else np.array([np.nan])
    if not (times[0] == 0.0 and times[-1] == end):
        raise bad(
            f"its {count} output times run from t = {times[0]:.6g} s to {times[-1]:.6g} s, not from 0 to its "
            f"time.end ({end!r} s) as a completed run's do: records were removed",
            "a completed run's records, all of them",
        )


def _scenario_bed(scenario: dict) -> list[list[float]] | None:
    """The bed points of a result's ``scenario`` (``[]``: flat) as the writer records them
    (``profile: flat`` or ``points``; a file or a DEM is recorded as its points), None if
    they are not such points."""
    bed = scenario.get("bed", {"profile": "flat"})
    if not isinstance(bed, dict):
        return None
    if bed.get("profile", "flat") == "flat":
        return []
    points = bed.get("points") if bed.get("profile") == "points" else None
    if not (isinstance(points, list) and len(points) >= 2):
        return None
    if not all(isinstance(p, list) and len(p) == 2 and all(map(finite_number, p)) for p in points):
        return None
    if not all(a[0] < b[0] for a, b in zip(points[:-1], points[1:])):
        return None
    return points


def _check_mesh(ds: netCDF4.Dataset, scenario: dict, bad) -> None:
    """Raise ``bad(...)`` unless the cell centres ``x``, their edges ``x_bnds`` and the bed
    of ``ds`` are those of its ``scenario`` (``domain.x_min``, ``x_max``, ``cells`` and
    ``bed``), as the writer computes them, to round-off: a result whose ``x`` was shifted
    100 m away from its domain, or whose bed was replaced, drew and exported the flow
    there (the records, consistent with their own ``x``, passed every other check)."""
    domain = scenario["domain"]  # its cells checked by _check_dimensions
    lo, hi, cells = domain.get("x_min"), domain.get("x_max"), domain["cells"]
    if not (finite_number(lo) and finite_number(hi) and lo < hi):
        raise bad(f"its scenario attribute's domain.x_min and x_max are {shown(lo)} and {shown(hi)}")
    dx = (float(hi) - float(lo)) / cells
    expected = cell_centres(float(lo), float(hi), cells)
    slack = 1e-9 * dx + 8 * np.spacing(max(abs(float(lo)), abs(float(hi))))
    x = np.asarray(ds["x"][:], dtype=float)
    edges = np.asarray(ds["x_bnds"][:], dtype=float)
    expected_edges = np.column_stack([expected - dx / 2, expected + dx / 2])
    with np.errstate(invalid="ignore", over="ignore"):  # damaged values are named below
        mesh = (
            edges.shape == expected_edges.shape
            and bool(np.all(np.abs(x - expected) <= slack))
            and bool(np.all(np.abs(edges - expected_edges) <= slack))
        )
    if not mesh:
        raise bad(
            f"its cell centres x or edges x_bnds are not the {cells} cells of its scenario's domain "
            f"[{float(lo):g}, {float(hi):g}] m (x from {x[0]:.6g} to {x[-1]:.6g} m)"
        )
    points = _scenario_bed(scenario)
    if points is None:
        raise bad("its scenario attribute's bed is not a flat bed or points [[x, b], ...] with increasing x")
    bed = np.asarray(ds["bed"][:], dtype=float)
    want = bed_profile(tuple((float(a), float(b)) for a, b in points), expected)
    with np.errstate(invalid="ignore", over="ignore"):
        scale = float(np.max(np.abs(want))) if want.size else 0.0
        same = bool(np.all(np.abs(bed - want) <= 1e-12 * scale + 8 * np.spacing(scale) + 1e-300))
    if not same:
        worst = int(np.nanargmax(np.where(np.isfinite(bed), np.abs(bed - want), np.inf)))
        raise bad(
            f"its bed is not its scenario's bed: {bed[worst]:.6g} m at x = {expected[worst]:.6g} m, where "
            f"the scenario's bed is at {want[worst]:.6g} m"
        )


CHUNK_VALUES = 2**23
"""Values read at once when records are checked (64 MB of doubles): whole records."""


@np.errstate(invalid="ignore", over="ignore")  # damaged values are named by the checks, not warned of
def _check_records(ds: netCDF4.Dataset, count: int, scenario: dict, bad) -> None:
    """Raise ``bad(...)`` at the first of the first ``count`` records that fails its checks
    (the mesh and bed those of the ``scenario``, the forces balanced with the momentum at
    its density);
    the records are read in chunks of about :data:`CHUNK_VALUES` values and screened at
    once, the first failing one examined on its own for the message."""
    _check_encoding(ds, bad)
    ds.set_auto_mask(False)
    x = np.asarray(ds["x"][:], dtype=float)
    if x.size == 0 or not (np.all(np.isfinite(x)) and np.all(np.diff(x) > 0)):
        raise bad("its cell centres x are not finite and increasing")
    if not np.all(np.isfinite(np.asarray(ds["bed"][:], dtype=float))):
        raise bad("its bed is not finite")
    bounds = np.asarray(ds["x_bnds"][:], dtype=float)
    if not _brackets(bounds, x):  # plot draws the section on these edges
        raise bad("its cell edges x_bnds are not finite around their cell centres x")
    sigma = np.asarray(ds["sigma"][:], dtype=float)
    if not (
        _brackets(np.asarray(ds["sigma_bnds"][:], dtype=float), sigma) and np.all((sigma >= 0) & (sigma <= 1))
    ):
        raise bad("its layer heights sigma and sigma_bnds are not finite, in order and within [0, 1]")
    if not np.array_equal(np.asarray(ds["layer"][:]), np.arange(1, sigma.size + 1)):
        raise bad(f"its layer indices are not 1 to {sigma.size}")
    _check_mesh(ds, scenario, bad)
    density = float(scenario["material"]["density"])
    # the domain over the cells, as the writer's (x_max - x_min) / cells: the mean of the cell
    # widths x + dx/2 - (x - dx/2) carries the round-off of x (6e-14 relative at 1200 cells
    # of 1 mm), ten times the round-off allowed to the mass
    dx = float((bounds[-1, 1] - bounds[0, 0]) / x.size)
    threshold = float(ds["front"].getncattr("threshold"))
    layers = len(ds.dimensions["layer"])
    step = max(1, CHUNK_VALUES // ((layers + 2) * x.size))
    before = -np.inf
    momentum = np.zeros(count)
    fractions = np.diff(np.asarray(ds["sigma_bnds"][:], dtype=float), axis=1)
    for start in range(0, count, step):
        rows = slice(start, min(start + step, count))
        t = np.asarray(ds["time"][rows], dtype=float)
        h = np.asarray(ds["h"][rows, :], dtype=float)
        u = np.asarray(ds["u"][rows, :, :], dtype=float)
        static = np.asarray(ds["static_interface"][rows, :], dtype=float)
        mass = np.asarray(ds["mass"][rows], dtype=float)
        front = np.asarray(ds["front"][rows], dtype=float)
        momentum[rows] = dx * np.sum(fractions[None] * h[:, None, :] * u, axis=(1, 2))
        previous = np.concatenate([[before], t[:-1]])
        suspect = ~(np.isfinite(t) & (t >= 0.0) & (t > previous))
        suspect |= (
            ~np.isfinite(h).all(axis=1) | ~np.isfinite(u).all(axis=(1, 2)) | ~np.isfinite(static).all(axis=1)
        )
        suspect |= (
            (h.min(axis=1) < 0.0) | (static.min(axis=1) < 0.0) | (static > h * (1 + ROUND_OFF)).any(axis=1)
        )
        integral = h.sum(axis=1) * dx
        scale = np.maximum(np.abs(integral), h.shape[1] * dx * h.max(axis=1, initial=0.0))
        suspect |= ~(np.abs(mass - integral) <= ROUND_OFF * scale)
        for bad_row in np.flatnonzero(suspect):
            j = int(bad_row)
            _check_record(bad, start + j, float(previous[j]), (t[j], h[j], u[j], static[j], mass[j]), x, dx)
        for j in range(t.size):  # the front of each record, as the writer computed it
            wet = diagnostics.front(x, h[j], threshold)
            if not (front[j] == wet or (np.isnan(front[j]) and np.isnan(wet))):
                what = f"front {float(front[j])!r} m is not the front of h ({wet:.6g} m)"
                raise _record_error(bad, start + j, float(t[j]), what)
        before = float(t[-1])
    if count and "bed_force_x" in ds.variables:
        _check_forces(ds, count, momentum, density, bad)
    if "phi" in ds.variables:
        _check_mixture(ds, count, step, fractions, bad)


def _check_mixture(ds: netCDF4.Dataset, count: int, step: int, fractions: np.ndarray, bad) -> None:
    """The mixture's records (``result_format.MIXTURE_VARIABLES``), ``step`` at a time: the
    solid volume fractions in ``[0, DENSEST_PACKING]`` (the run's bound; a packing of 0.8
    in a layer and its mean was drawn and exported) and 0 where there is no mixture (``h == 0``), the
    depth-averaged ``phi`` the mean of ``phi_layer`` weighted by the layer ``fractions`` (L,)
    to round-off, the excess pore pressure finite and, with ``pore_pressure_layer``, its
    first layer ``pore_pressure_excess`` (the writer writes each pair from one state: a
    ``phi`` changed within ``[0, 1)`` was read as the run's answer, ``phi_mean_final``)."""
    missing = [name for name in ("phi_layer", "pore_pressure_excess") if name not in ds.variables]
    if missing:
        raise bad(f"it holds a mixture's phi without {' and '.join(missing)}")
    for start in range(0, count, step):
        rows = slice(start, min(start + step, count))
        t = np.asarray(ds["time"][rows], dtype=float)
        values = {}
        for name in MIXTURE_VARIABLES:
            if name not in ds.variables:  # pore_pressure_layer: a relaxing pore pressure in layers only
                continue
            values[name] = np.asarray(ds[name][rows], dtype=float)
            flat = values[name].reshape(values[name].shape[0], -1)
            pressure = name.startswith("pore_pressure")
            ok = (
                np.isfinite(flat) if pressure else (flat >= 0.0) & (flat <= DENSEST_PACKING * (1 + ROUND_OFF))
            )
            broken = np.flatnonzero(~ok.all(axis=1))
            if broken.size:
                j = int(broken[0])
                value = float(flat[j][~ok[j]][0])
                accepted = (
                    "finite" if pressure else f"in [0, {DENSEST_PACKING:.4f}], the densest packing of spheres"
                )
                raise _record_error(bad, start + j, float(t[j]), f"{name} = {value!r} is not {accepted}")
        dry = np.asarray(ds["h"][rows, :], dtype=float) == 0.0
        phi, layered = values["phi"], values["phi_layer"]
        mean = np.sum(fractions[None, :, :1] * layered, axis=1)
        excess = values["pore_pressure_excess"]
        checks = [  # (where wrong, the values quoted, what)
            (dry & (phi != 0.0), phi, "phi = {!r} where h is 0 (no mixture there: 0)"),
            (
                dry & (layered != 0.0).any(axis=1),
                layered.max(axis=1),
                "phi_layer is {!r} where h is 0 (no mixture: 0)",
            ),
            (
                ~(np.abs(phi - mean) <= ROUND_OFF * fractions.shape[0] * np.maximum(phi, mean)),
                phi,
                "phi = {!r} is not the mean of phi_layer over the layers",
            ),
        ]
        if "pore_pressure_layer" in values:
            first = values["pore_pressure_layer"][:, 0, :] != excess
            checks.append(
                (first, excess, "pore_pressure_excess = {!r} is not pore_pressure_layer of the first layer")
            )
        for wrong, quoted, what in checks:
            if wrong.any():
                j, i = (int(k[0]) for k in np.nonzero(wrong))
                raise _record_error(
                    bad, start + j, float(t[j]), what.format(float(quoted[j, i])) + f" at x index {i}"
                )


def _check_forces(ds: netCDF4.Dataset, count: int, momentum: np.ndarray, density: float, bad) -> None:
    """The forces of the first ``count`` records: NaN in the first, finite after, and the
    change of momentum between two records (``momentum``: ``sum_a h_a u_a dx`` of each,
    per unit density) their mean times the interval (``result_format.FORCES``)."""
    t = np.asarray(ds["time"][:count], dtype=float)
    f = {name: np.asarray(ds[name][:count], dtype=float) for name in FORCES}
    for name, values in f.items():
        if not np.isnan(values[0]):
            raise _record_error(bad, 0, float(t[0]), f"{name} is {float(values[0])!r}, not NaN (no interval)")
        broken = np.flatnonzero(~np.isfinite(values[1:]))
        if broken.size:
            i = int(broken[0]) + 1
            raise _record_error(bad, i, float(t[i]), f"{name} = {float(values[i])!r} is not finite")
    terms = ("bed_force_x", "wall_force_x", "end_force_x", "pressure_force_x", "outflow_momentum_x")
    net = f["gravity_force_x"][1:] - sum(f[name][1:] for name in terms)
    change = density * np.diff(momentum)
    scale = np.abs(density * momentum[1:]) + np.abs(density * momentum[:-1])
    scale += np.diff(t) * sum(np.abs(f[name][1:]) for name in (*terms, "gravity_force_x"))
    off = np.flatnonzero(~(np.abs(change - np.diff(t) * net) <= BALANCE_ROUND_OFF * scale))
    if off.size:
        i = int(off[0]) + 1
        what = (
            f"the change of momentum since the previous output time, {float(change[i - 1]):.9g} N s/m, "
            f"is not the impulse of its forces, {float(np.diff(t)[i - 1] * net[i - 1]):.9g} N s/m"
        )
        raise _record_error(bad, i, float(t[i]), what)


def _check_record(bad, i: int, before: float, values: tuple, x: np.ndarray, dx: float) -> None:
    """Raise ``bad(...)`` saying how output time ``i`` (its time, h, u, static interface and
    mass in ``values``; ``before`` the time of the previous one) fails its checks."""
    t, h, u, static, mass = values
    record = functools.partial(_record_error, bad, i, float(t))
    if not (np.isfinite(t) and t >= 0.0 and t > before):
        raise record(f"time {float(t)!r} is not finite and after the previous one ({before:.6g} s)")
    for name, field in (("h", h), ("u", u), ("static_interface", static)):
        infinite = np.flatnonzero(~np.isfinite(field))
        if infinite.size:
            k = int(infinite[0])
            raise record(f"{name} = {float(field.flat[k])!r} at x = {x[k % x.size]:.6g} m")
    if h.min() < 0.0:
        raise record(f"h = {h.min():.6g} m < 0 at x = {x[int(np.argmin(h))]:.6g} m")
    if np.any(static < 0.0) or np.any(static > h * (1 + ROUND_OFF)):
        raise record("the static interface is outside [0, h]")
    expected = diagnostics.mass(h, dx)
    if not abs(mass - expected) <= ROUND_OFF * max(abs(expected), h.size * dx * h.max(initial=0.0)):
        raise record(f"mass {float(mass)!r} m2 is not the integral of h ({expected:.6g} m2)")


def _record_error(bad, i: int, t: float, what: str) -> ResultFileError:
    """The error of output time ``i`` (at ``t``) failing a check."""
    return bad(f"output time {i} (t = {t:.6g} s) fails its checks: {what}")


def ending(attrs: dict) -> str | None:
    """How a run that did not complete ended, in words (None for a completed one): what a
    reader that shows its records says beside them."""
    status = attrs.get("run_status", "completed")
    if status == "completed":
        return None
    what = {"failed": "the run failed", "interrupted": "the run was interrupted"}.get(status, f"run {status}")
    why = attrs.get("failure", "")
    return f"{what}: {why}" if why else what
