"""Profiles read from files: CSV columns with units, and GeoTIFF DEMs sampled along a polyline.

A CSV profile (docs/scenarios.md) has a header naming two columns with their units,
``x (m), z (m)``, then one ``x, value`` pair per line; blank lines and lines starting
with ``#`` are skipped.  A DEM profile samples the elevation of a GeoTIFF (read with the
optional ``rasterio``, ``pip install 'multilayer[dem]'``) along a polyline in the DEM's
map coordinates.  Profiles measured in the map frame (horizontal distance, vertical
elevation) are turned into the slope frame of the model (x along the inclined plane,
b normal to it) by :func:`map_to_slope_frame`.  Every problem raises
:class:`~multilayer.errors.InputError` naming the file and the line.
"""

from __future__ import annotations

import functools
import math
import os
import re
import typing
import warnings
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from multilayer.errors import InputError, shown
from multilayer.scenario.files import check_regular, read_text
from multilayer.scenario.limits import DEM_WINDOW, MAX_DEM_BLOCK_PIXELS, MAX_DEM_ELEVATION, MAX_PROFILE_POINTS

T = TypeVar("T")

LENGTH_UNITS = {"m": 1.0, "cm": 1e-2, "mm": 1e-3, "km": 1e3}
"""Units accepted in a CSV header, with their value in metres."""

_HEADER_CELL = re.compile(r"^\s*([A-Za-z_]\w*)\s*[\(\[]\s*([A-Za-z]+)\s*[\)\]]\s*$")
_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
"""An ASCII decimal, matched in a time linear in its length: the digits after the point
belong to an optional group that starts at the point, so no two runs of digits compete for
the same characters (with ``[0-9]+\\.?[0-9]*`` a number ended by a letter is refused only
after every split of its digits is tried, a time quadratic in its length)."""


def csv_lines(text: str) -> list[str]:
    """The lines of a CSV text, ended by ``\\n``, ``\\r\\n`` or ``\\r`` as the ``csv`` module
    and spreadsheets end them: ``str.splitlines`` also ends a line at a form feed, a
    vertical tab, ``\\x1c``-``\\x1e``, ``\\x85``, ``\\u2028`` and ``\\u2029``, rows no other
    reader of the file sees, counted in the line numbers of the messages."""
    return text.replace("\r\n", "\n").replace("\r", "\n").split("\n")


def csv_number(text: str) -> float:
    """A number of a CSV file, in ASCII decimal notation: ``float`` alone also reads
    ``1_000``, ``nan`` and the digits of other scripts, which no CSV writer means as a
    number (ValueError for them)."""
    if not _NUMBER.fullmatch(text.strip()):
        raise ValueError(f"could not convert {shown(text.strip())} to a number")
    return float(text)


def read_csv_profile(path: str | Path, columns: Sequence[str]) -> np.ndarray:
    """Points ``[[x, value], ...]`` (m) of a two-column CSV profile, x strictly increasing.

    ``columns`` lists the accepted names of the two columns, e.g. ``("x", "z|b")``
    (alternatives separated by ``|``); values are converted to metres from the units
    of the header; lines end at ``\\n``, ``\\r\\n`` or ``\\r``.  A file read before and
    unchanged since (its device, inode, size and modification time) is not parsed again
    (every member of a sweep, calibration or sensitivity study is validated).
    """
    return shared_csv_profile(path, columns).copy()


def shared_csv_profile(path: str | Path, columns: Sequence[str]) -> np.ndarray:
    """The points of :func:`read_csv_profile` without their copy: one read-only array
    shared by every reader of the file as it is, its columns contiguous (the x of a
    profile are searched, ``np.searchsorted``, without copying them)."""
    stamp = _stamp(path)
    if stamp is None:  # missing or unreadable: the reading names it
        return _parsed_csv_profile(Path(path), tuple(columns))
    return _cached_csv_profile(str(path), tuple(columns), stamp)


def _stamp(path: str | Path) -> tuple[int, ...] | None:
    """What tells a file unchanged since it was read: its device, inode, size and
    modification time (None where it cannot be looked at)."""
    try:
        status = os.stat(path)
    except (OSError, ValueError):
        return None
    return (status.st_dev, status.st_ino, status.st_size, status.st_mtime_ns)


@functools.lru_cache(maxsize=4)  # 16 MB a profile of 10^6 points
def _cached_csv_profile(path: str, columns: tuple[str, ...], stamp: tuple[int, ...]) -> np.ndarray:
    """:func:`_parsed_csv_profile` of ``path`` as it was at ``stamp``, read-only."""
    points = _parsed_csv_profile(Path(path), columns)
    points.flags.writeable = False
    return points


def _parsed_csv_profile(path: Path, columns: tuple[str, ...]) -> np.ndarray:
    """The points of :func:`read_csv_profile`, read and parsed."""
    accepted_header = f"a header '{columns[0].split('|')[0]} (m), {columns[1].split('|')[0]} (m)'"
    lines = csv_lines(read_text(path, f"a CSV file with {accepted_header}", "a readable UTF-8 CSV file"))
    rows = [
        (n, line) for n, line in enumerate(lines, 1) if line.strip() and not line.lstrip().startswith("#")
    ]
    if not rows:
        raise InputError(f"{path}: empty file; accepted: {accepted_header} and at least 2 rows")
    if len(rows) > MAX_PROFILE_POINTS + 1:
        raise InputError(
            f"{path}: {len(rows) - 1} data rows; accepted: at most {MAX_PROFILE_POINTS} (the profile is "
            "resampled to the mesh: a finer one adds nothing)"
        )
    line_no, header = rows[0]
    cells = header.split(",")
    factors = []
    for cell, names in zip(cells, columns) if len(cells) == 2 else ():
        match = _HEADER_CELL.match(cell)
        if not match or match[1] not in names.split("|") or match[2] not in LENGTH_UNITS:
            break
        factors.append(LENGTH_UNITS[match[2]])
    if len(factors) != 2:
        raise InputError(
            f"{path}: line {line_no}: header {shown(header.strip())} does not name the columns "
            f"{' and '.join(columns)} with their units; accepted: {accepted_header} "
            f"(units {', '.join(LENGTH_UNITS)})"
        )
    points: list[tuple[float, float]] = []
    for line_no, line in rows[1:]:
        fields = line.split(",")
        try:
            x, value = (csv_number(f) for f in fields) if len(fields) == 2 else (math.nan, None)
        except ValueError:
            x = math.nan
        if not (math.isfinite(x) and value is not None and math.isfinite(value)):
            raise InputError(
                f"{path}: line {line_no}: expected two numbers separated by a comma, got "
                f"{shown(line.strip())}; accepted: 'x, value' rows of finite numbers"
            )
        if not (math.isfinite(x * factors[0]) and math.isfinite(value * factors[1])):  # 1e306 km
            raise InputError(
                f"{path}: line {line_no}: {shown(line.strip())} in metres is beyond the largest float; "
                "accepted: 'x, value' rows of finite numbers, below 1.8e308 m"
            )
        if points and x * factors[0] <= points[-1][0]:
            raise InputError(
                f"{path}: line {line_no}: x = {x} does not increase; "
                "accepted: rows with strictly increasing x"
            )
        points.append((x * factors[0], value * factors[1]))
    if len(points) < 2:
        raise InputError(f"{path}: {len(points)} data row(s); accepted: at least 2 rows after the header")
    return np.asfortranarray(points)


def sampled(points: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``np.interp(x, *points.T)`` of a profile ``[[x, value], ...]`` (x strictly
    increasing), reading only the rows that bracket ``x``: the same values (each ``x`` is
    interpolated between the same two rows), in work of ``len(x)`` searches of the rows.
    ``np.interp`` itself copies a read-only array, such as :func:`shared_csv_profile`."""
    px, values = points[:, 0], points[:, 1]
    above = np.searchsorted(px, x, side="right")
    rows = np.unique(np.clip(np.concatenate([above - 1, above]), 0, len(px) - 1))
    return np.interp(x, px[rows], values[rows])


def read_dem_profile(
    path: str | Path, polyline: Sequence[Sequence[float]], spacing: float | None
) -> np.ndarray:
    """Map-frame profile ``[[s, Z], ...]`` of a GeoTIFF DEM along ``polyline``, read-only.

    ``s`` is the horizontal distance along the polyline (map units, m) from its first
    vertex and ``Z`` the elevation of band 1, interpolated bilinearly between pixel
    centres every ``spacing`` (default: the smaller pixel size) and at every vertex.  A
    DEM read before along the same polyline and unchanged since (as
    :func:`shared_csv_profile`) is not read again: one array shared by its readers.
    """
    vertices = np.asarray(polyline, dtype=float)
    if spacing is not None:  # the samples are counted before the DEM is read
        _check_samples(path, vertices, spacing, "spacing")
    check_regular(Path(path), "a GeoTIFF file", "a readable GeoTIFF file")
    stamp = _stamp(path)
    if stamp is None:  # gone since: the reading names it
        return _parsed_dem_profile(Path(path), vertices, spacing)
    line = tuple(tuple(float(v) for v in vertex) for vertex in vertices.tolist())
    return _cached_dem_profile(str(path), line, spacing, stamp)


@functools.lru_cache(maxsize=4)  # 16 MB a profile of 10^6 samples
def _cached_dem_profile(
    path: str, line: tuple[tuple[float, ...], ...], spacing: float | None, stamp: tuple[int, ...]
) -> np.ndarray:
    """:func:`_parsed_dem_profile` of ``path`` as it was at ``stamp``, read-only."""
    points = _parsed_dem_profile(Path(path), np.array(line, dtype=float), spacing)
    points.flags.writeable = False
    return points


def _parsed_dem_profile(path: Path, vertices: np.ndarray, spacing: float | None) -> np.ndarray:
    """The profile of :func:`read_dem_profile`, read from the DEM: a single-band GeoTIFF of
    real numbers in a projected coordinate reference system of metres, its elevations in
    metres (a band unit of ``m`` or none), their scale and offset applied (an ``int16``
    DEM of centimetres), read in windows of at most :data:`DEM_WINDOW` pixels a side
    around the samples, never whole."""
    try:
        import rasterio
        from rasterio.windows import Window
    except ImportError:
        raise InputError(
            f"{path}: reading a GeoTIFF DEM needs the optional package rasterio; "
            "accepted: install it with pip install 'multilayer[dem]', or give the bed as a CSV file"
        ) from None
    try:
        # a damaged block is an error, not zeros, whatever the environment says
        with rasterio.Env(GTIFF_IGNORE_READ_ERRORS="NO"):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always", rasterio.errors.NotGeoreferencedWarning)
                # GeoTIFF only: a VRT file (XML) named dem.tif reads the files, devices and URLs it names
                dem = rasterio.open(path, driver="GTiff")
            with dem:
                georeferenced = not any(
                    issubclass(w.category, rasterio.errors.NotGeoreferencedWarning) for w in caught
                )
                _check_sidecar(path, dem)
                scale, offset, pixel, to_pixel = _dem_frame(path, dem, georeferenced)
                step = spacing or pixel
                _check_samples(path, vertices, step, "spacing" if spacing else "dem (its pixel size)")
                samples, s = _polyline_samples(vertices, step)
                col = to_pixel.a * samples[:, 0] + to_pixel.b * samples[:, 1] + to_pixel.c
                row = to_pixel.d * samples[:, 0] + to_pixel.e * samples[:, 1] + to_pixel.f

                def pixels(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
                    values = np.empty(len(rows))
                    tiles = (rows // DEM_WINDOW) * (dem.width // DEM_WINDOW + 1) + cols // DEM_WINDOW
                    order = np.argsort(tiles, kind="stable")
                    for group in np.split(order, np.flatnonzero(np.diff(tiles[order])) + 1):
                        r, c = rows[group], cols[group]
                        r_0, c_0 = int(r.min()), int(c.min())
                        window = Window(c_0, r_0, int(c.max()) - c_0 + 1, int(r.max()) - r_0 + 1)
                        if dem.nodata is None:
                            _check_written(path, dem, r, c)
                        block = dem.read(1, window=window, masked=True)
                        values[group] = np.ma.filled(block.astype(float), np.nan)[r - r_0, c - c_0]
                    # beyond the Earth's radius: no terrain (a NaN is named below)
                    far = np.flatnonzero(np.abs(values * scale + offset) > MAX_DEM_ELEVATION)
                    if far.size:
                        raise InputError(
                            f"{path}: an elevation of {values[far[0]] * scale + offset:g} m at pixel (row "
                            f"{rows[far[0]]}, column {cols[far[0]]}) on the polyline; accepted: elevations "
                            f"within {MAX_DEM_ELEVATION:g} m of the datum (a fill value is declared with "
                            "gdal_translate -a_nodata)"
                        )
                    return values

                with np.errstate(all="ignore"):  # an infinite or huge elevation is named below
                    z = _bilinear((dem.height, dem.width), pixels, row - 0.5, col - 0.5) * scale + offset
    except rasterio.errors.RasterioError as exc:
        cause = exc.__cause__ or exc  # "Read failed. See previous exception": GDAL's own words
        raise InputError(f"{path}: cannot read the DEM ({cause}); accepted: a GeoTIFF file") from None
    bad = np.flatnonzero(~np.isfinite(z))
    if bad.size:
        x0, y0 = samples[bad[0]]
        raise InputError(
            f"{path}: no elevation at ({x0:g}, {y0:g}), {s[bad[0]]:g} m along the polyline "
            "(outside the DEM, a nodata pixel or a value that is not finite); accepted: a polyline inside "
            "the DEM's valid pixels"
        )
    return np.column_stack([s, z])


def _check_written(path: Path, dem: Any, rows: np.ndarray, cols: np.ndarray) -> None:
    """:class:`InputError` if a block of the DEM holding one of the pixels ``rows, cols`` was
    never written (a sparse GeoTIFF: its offset and byte count 0 in the file, as GDAL writes
    it with ``SPARSE_OK=TRUE``), for a DEM without a nodata value: GDAL reads such a block as
    zeros, an elevation of 0 m.  GDAL's GeoTIFF driver gives the offset of each block it
    finds as the band's metadata ``BLOCK_OFFSET_<column>_<row>`` of the ``TIFF`` domain,
    none for an unwritten block."""
    block_rows, block_cols = dem.block_shapes[0]
    for i, j in sorted(set(zip((rows // block_rows).tolist(), (cols // block_cols).tolist()))):
        if not dem.get_tag_item(f"BLOCK_OFFSET_{j}_{i}", "TIFF", bidx=1):
            raise InputError(
                f"{path}: the block of pixels ({i * block_rows}-{(i + 1) * block_rows - 1}, "
                f"{j * block_cols}-{(j + 1) * block_cols - 1}) (rows, columns) on the polyline was never "
                "written (a sparse GeoTIFF) and the DEM has no nodata value: its elevations would be read as "
                "0 m; accepted: a DEM whose blocks on the polyline are written, or one with a nodata value "
                "(gdal_translate -a_nodata sets one)"
            )


_SIDECAR_KEYS = ("crs", "transform", "nodata", "scales", "offsets", "units")
"""What a sidecar ``.aux.xml`` file may change of a DEM, checked by :func:`_check_sidecar`."""


def _check_sidecar(path: Path, dem: Any) -> None:
    """:class:`InputError` if GDAL read a sidecar ``.aux.xml`` file beside the DEM (its
    persistent auxiliary metadata) that changes its coordinate reference system,
    geotransform, nodata value, scale, offset or units from what the GeoTIFF says: a copy
    of ``dem.tif`` left beside an old ``dem.tif.aux.xml`` would be read in feet, or with
    valid pixels taken as nodata, with nothing in the file itself to tell."""
    # .aux.xml, or an .aux of ERDAS Imagine; a mask (.msk) masks pixels (named as nodata),
    # overviews (.ovr) are not read at full resolution
    sidecars = [f for f in dem.files[1:] if not str(f).lower().endswith((".msk", ".ovr"))]
    if not sidecars:
        return
    import rasterio

    with rasterio.Env(GDAL_PAM_ENABLED="NO"), rasterio.open(path, driver="GTiff") as plain:
        changed = [k for k in _SIDECAR_KEYS if str(getattr(dem, k)) != str(getattr(plain, k))]  # NaN nodata
        if changed:
            said = ", ".join(f"{k} from {getattr(plain, k)} to {getattr(dem, k)}" for k in changed)
            raise InputError(
                f"{path}: the sidecar file {sidecars[0]} changes its {said}; accepted: a GeoTIFF that says "
                "these itself (gdal_translate dem.tif out.tif writes the sidecar's values into the file), "
                "without a sidecar that changes them"
            )


_METRES = ("", "m", "metre", "meter", "metres", "meters")
"""Band units read as elevations in metres (none: the GeoTIFF convention)."""


def _dem_frame(path: Path, dem: Any, georeferenced: bool) -> tuple[float, float, float, Any]:
    """The scale, offset, pixel size (m) and map-to-pixel transform of an open DEM, after
    checking that it is one band of real numbers in a projected frame of metres, its
    elevations in metres: :class:`InputError` naming what it is otherwise (a DEM in
    degrees was sampled as if its 0.01-degree pixels were 0.01 m wide, silently)."""
    accepted = (
        "; accepted: a single-band GeoTIFF of elevations in metres in a projected coordinate "
        "reference system of metres (gdalwarp -t_srs EPSG:... reprojects one)"
    )
    if dem.count != 1:
        raise InputError(f"{path}: {dem.count} bands, which one is the elevation is not said{accepted}")
    kind = np.dtype(dem.dtypes[0]).kind
    if kind not in "iuf":
        raise InputError(f"{path}: values of type {dem.dtypes[0]}, not real numbers{accepted}")
    if not georeferenced or dem.crs is None:
        raise InputError(
            f"{path}: {'no geotransform' if not georeferenced else 'no coordinate reference system'}: "
            f"where its pixels lie, or in what units, is not said{accepted}"
        )
    if not dem.crs.is_projected:
        raise InputError(
            f"{path}: a {'geographic' if dem.crs.is_geographic else 'non-projected'} coordinate reference "
            f"system ({dem.crs.to_string()[:60]}), whose coordinates are not metres{accepted}"
        )
    try:
        unit, factor = dem.crs.linear_units_factor
    except ValueError:  # rasterio's CRSError: units PROJ cannot tell
        unit, factor = "units that cannot be read", math.nan
    if factor != 1.0:
        raise InputError(f"{path}: map coordinates in {unit} ({factor:g} m), not metres{accepted}")
    vertical = (dem.units[0] or "").strip()
    if vertical.lower() not in _METRES:
        raise InputError(f"{path}: elevations in {vertical!r}, not metres{accepted}")
    block_rows, block_cols = dem.block_shapes[0]
    if block_rows * block_cols > MAX_DEM_BLOCK_PIXELS:
        raise InputError(
            f"{path}: blocks of {block_cols} x {block_rows} pixels, decoded whole to read any of their "
            f"pixels; accepted: blocks of at most {MAX_DEM_BLOCK_PIXELS} pixels "
            "(gdal_translate -co TILED=YES tiles it)"
        )
    scale, offset = float(dem.scales[0]), float(dem.offsets[0])
    if not (math.isfinite(scale) and scale != 0.0 and math.isfinite(offset)):
        raise InputError(f"{path}: a scale {scale:g} and offset {offset:g} of its values{accepted}")
    t = dem.transform
    determinant = t.a * t.e - t.b * t.d
    pixel = min(math.hypot(t.a, t.d), math.hypot(t.b, t.e))  # a rotated DEM's too
    if not (math.isfinite(determinant) and determinant != 0.0 and pixel > 0.0):
        raise InputError(f"{path}: a geotransform {tuple(t)[:6]} that maps its pixels on no area{accepted}")
    return scale, offset, pixel, ~t


def _polyline_samples(vertices: np.ndarray, step: float) -> tuple[np.ndarray, list[float]]:
    """Points every ``step`` along the polyline ``vertices`` and at each vertex, and their
    distance along it."""
    xy, s = [vertices[0]], [0.0]
    for start, end in zip(vertices[:-1], vertices[1:]):
        length = float(np.hypot(*(end - start)))
        count = max(1, math.ceil(length / step - 1e-9))
        for k in range(1, count + 1):
            xy.append(start + (end - start) * k / count)
            s.append(s[-1] + length / count)
    return np.asarray(xy), s


def _check_samples(path: str | Path, vertices: np.ndarray, step: float, key: str) -> None:
    """:class:`InputError` if sampling the polyline ``vertices`` every ``step`` (m) takes
    more than :data:`MAX_PROFILE_POINTS` points (``key`` names what sets the step)."""
    lengths = np.hypot(*np.diff(vertices, axis=0).T)
    count = 1.0 + float(np.sum(np.maximum(1.0, np.ceil(lengths / step - 1e-9))))
    if not count <= MAX_PROFILE_POINTS:  # a NaN or infinite length fails too
        raise InputError(
            f"{path}: bed.{key}: sampling the polyline ({float(np.sum(lengths)):.6g} m) every {step:g} m "
            f"takes {count:.3g} points; accepted: at most {MAX_PROFILE_POINTS} points (a larger spacing, "
            "a shorter polyline)"
        )


def _bilinear(
    shape: tuple[int, int],
    pixels: Callable[[np.ndarray, np.ndarray], np.ndarray],
    row: np.ndarray,
    col: np.ndarray,
) -> np.ndarray:
    """Bilinear interpolation of a band of ``shape`` at fractional pixel-centre indices;
    NaN outside.  ``pixels(rows, cols)`` gives the band's values at integer indices: only
    the four pixels around each point inside are read."""
    rows, cols = shape
    inside = (row >= -0.5) & (row <= rows - 0.5) & (col >= -0.5) & (col <= cols - 0.5)
    value = np.full(len(row), np.nan)
    if not inside.any():
        return value
    row, col = row[inside], col[inside]  # a point at 1e300 is cast to no integer
    r0 = np.clip(np.floor(row).astype(np.int64), 0, max(rows - 2, 0))
    c0 = np.clip(np.floor(col).astype(np.int64), 0, max(cols - 2, 0))
    fr, fc = row - r0, col - c0
    r1, c1 = np.minimum(r0 + 1, rows - 1), np.minimum(c0 + 1, cols - 1)
    n = len(row)
    read = pixels(np.concatenate([r0, r1, r0, r1]), np.concatenate([c0, c0, c1, c1]))
    v00, v10, v01, v11 = read[:n], read[n : 2 * n], read[2 * n : 3 * n], read[3 * n :]
    value[inside] = v00 * (1 - fr) * (1 - fc) + v10 * fr * (1 - fc) + v01 * (1 - fr) * fc + v11 * fr * fc
    return value


_DERIVED: dict[tuple[int, str], tuple[np.ndarray, Any]] = {}
"""The values of :func:`derived`, by the identity of their read-only profile (held in the
value, so that no other array takes its id) and their key, most recently used last."""

DERIVED_KEPT = 8
"""Values of :func:`derived` kept (a slope-frame profile of 10^6 rows takes 16 MB)."""


def derived(points: np.ndarray, key: str, compute: Callable[[np.ndarray], T]) -> T:
    """``compute(points)``, computed once per ``key`` for a read-only profile shared by its
    readers (:func:`shared_csv_profile`, :func:`read_dem_profile`): every member of a
    study is validated, and one reading a file read before costs no work per row; a
    writeable profile is computed for each call."""
    if points.flags.writeable:
        return compute(points)
    slot = (id(points), key)
    found = _DERIVED.pop(slot, None)
    if found is None or found[0] is not points:
        found = (points, compute(points))
    _DERIVED[slot] = found
    while len(_DERIVED) > DERIVED_KEPT:
        _DERIVED.pop(next(iter(_DERIVED)), None)
    return typing.cast(T, found[1])


def shared_slope_frame(points: np.ndarray, slope_deg: float, where: str) -> np.ndarray:
    """:func:`map_to_slope_frame` of ``points``, read-only, its columns contiguous, once per
    slope for a shared profile (:func:`derived`)."""

    def frame(profile: np.ndarray) -> np.ndarray:
        rotated = np.asfortranarray(map_to_slope_frame(profile, slope_deg, where))
        rotated.flags.writeable = False
        return rotated

    return derived(points, f"slope frame at {float(slope_deg).hex()} deg", frame)


def value_range(points: np.ndarray) -> tuple[float, float]:
    """The smallest and the largest value of a profile ``[[x, value], ...]``, once for a
    shared profile (:func:`derived`)."""
    return derived(
        points, "value range", lambda profile: (float(profile[:, 1].min()), float(profile[:, 1].max()))
    )


def map_to_slope_frame(points: np.ndarray, slope_deg: float, where: str) -> np.ndarray:
    """Slope-frame bed ``[[x, b], ...]`` of a map-frame profile ``[[s, Z], ...]``.

    With theta the slope (downhill towards +x) and the origin at the first point,
    ``x = s cos(theta) - (Z - Z_0) sin(theta)`` along the plane and
    ``b = s sin(theta) + (Z - Z_0) cos(theta)`` normal to it, so a plane descending at
    theta is b = 0.  ``where`` names the source in the error raised when x does not
    increase (terrain steeper than 90 degrees minus theta facing the flow).
    """
    theta = math.radians(slope_deg)
    s, z = points[:, 0], points[:, 1] - points[0, 1]
    x = s * math.cos(theta) - z * math.sin(theta)
    b = s * math.sin(theta) + z * math.cos(theta)
    folds = np.flatnonzero(np.diff(x) <= 0)
    if folds.size:
        k = folds[0]  # the elevations named: a DEM pixel of 1e308 m is told from a cliff
        raise InputError(
            f"{where}: at {s[k + 1]:g} m along the profile the terrain rises more steeply than "
            f"{90 - slope_deg:g} deg (from Z = {points[k, 1]:g} m at {s[k]:g} m to "
            f"Z = {points[k + 1, 1]:g} m), "
            f"so x along the {slope_deg:g} deg plane does not increase; "
            "accepted: a profile whose x along the plane increases"
        )
    return np.column_stack([x, b])
