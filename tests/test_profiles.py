"""Bed and initial thickness from files: CSV profiles with units, GeoTIFF DEMs along a polyline."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
import yaml

from multilayer.engine.initial_state import bed_profile, cell_edges, initial_state
from multilayer.errors import InputError
from multilayer.scenario import from_dict, load

X = np.linspace(0.005, 0.295, 30)  # cell centres of the tiny domain below
EDGES = cell_edges(0.0, 0.3, 30)


def _scenario(write_scenario, tiny_scenario, **changes):
    tiny_scenario.update(domain={"x_min": 0.0, "x_max": 0.3, "cells": 30, "layers": 3}, **changes)
    return write_scenario(tiny_scenario)


def test_csv_bed_equals_the_same_bed_given_by_points(tmp_path, write_scenario, tiny_scenario):
    points = [[0.0, 0.012], [0.1, 0.004], [0.22, 0.0065], [0.3, 0.0]]
    (tmp_path / "bed.csv").write_text(
        "# bed surveyed in the slope frame\nx (cm), z (mm)\n"
        + "".join(f"{100 * x:g}, {1000 * b:g}\n" for x, b in points)
    )
    from_points = load(_scenario(write_scenario, tiny_scenario, bed={"points": points}))
    from_file = load(_scenario(write_scenario, tiny_scenario, bed={"file": "bed.csv"}))
    np.testing.assert_allclose(from_file.bed.points, points, rtol=1e-15, atol=1e-18)
    np.testing.assert_allclose(
        bed_profile(from_file.bed.points, X), bed_profile(from_points.bed.points, X), atol=1e-17
    )
    # the result file records the points, so the record stands alone and loads back
    recorded = yaml.safe_load(from_file.resolved_yaml())
    assert recorded["bed"] == {"profile": "points", "points": from_file.bed.points}
    assert from_dict(recorded).bed.points == from_file.bed.points


def test_csv_initial_thickness_equals_the_same_profile_given_by_points(
    tmp_path, write_scenario, tiny_scenario
):
    points = [[0.0, 0.05], [0.08, 0.05], [0.12, 0.0]]
    (tmp_path / "column.csv").write_text("x (m),h (m)\n" + "".join(f"{x!r},{h!r}\n" for x, h in points))
    from_file = load(
        _scenario(write_scenario, tiny_scenario, initial=[{"shape": "profile", "file": "column.csv"}])
    )
    from_points = load(
        _scenario(write_scenario, tiny_scenario, initial=[{"shape": "profile", "points": points}])
    )
    sigma = np.array([1 / 6, 1 / 2, 5 / 6])
    h_file, _ = initial_state(from_file.initial, X, sigma, EDGES)
    h_points, _ = initial_state(from_points.initial, X, sigma, EDGES)
    np.testing.assert_array_equal(h_file, h_points)
    assert "file" not in yaml.safe_load(from_file.resolved_yaml())["initial"][0]


def _descending(s: np.ndarray, degrees: float) -> np.ndarray:
    return -s * math.tan(math.radians(degrees))


def test_map_frame_profile_is_rotated_onto_the_plane(tmp_path, write_scenario, tiny_scenario):
    """Terrain descending at 30 deg, seen from a 25 deg plane: b = -tan(5 deg) x, x = s cos 5 / cos 30."""
    s = np.array([0.0, 0.1, 0.2, 0.35])
    rows = "".join(f"{float(a)!r}, {float(z)!r}\n" for a, z in zip(s, 100.0 + _descending(s, 30.0)))
    (tmp_path / "terrain.csv").write_text("x (m), z (m)\n" + rows)
    sc = load(_scenario(write_scenario, tiny_scenario, bed={"file": "terrain.csv", "frame": "map"}))
    x, b = np.asarray(sc.bed.points).T
    np.testing.assert_allclose(x, s * math.cos(math.radians(5)) / math.cos(math.radians(30)), rtol=1e-12)
    np.testing.assert_allclose(b, -math.tan(math.radians(5)) * x, atol=1e-15)
    # a wall rising at more than 90 - 25 deg towards the flow folds the slope frame: refused
    (tmp_path / "terrain.csv").write_text("x (m), z (m)\n0, 0\n1, 0\n1.1, 1\n")
    with pytest.raises(
        InputError, match=r"bed.file \(line \d+\): terrain.csv: at 1.1 m along the profile the terrain rises"
    ):
        load(tmp_path / "scenario.yaml")


def _write_geotiff(path, elevation: np.ndarray, pixel: float, origin=(1000.0, 5000.0), nodata=None) -> None:
    rasterio = pytest.importorskip("rasterio")
    from rasterio.transform import Affine

    with rasterio.open(
        path,
        "w",
        driver="GTiff",
        height=elevation.shape[0],
        width=elevation.shape[1],
        count=1,
        dtype="float64",
        crs="EPSG:32632",
        transform=Affine(pixel, 0.0, origin[0], 0.0, -pixel, origin[1]),  # north-up
        nodata=nodata,
    ) as dem:
        dem.write(elevation, 1)


def test_dem_profile_along_a_polyline(tmp_path, write_scenario, tiny_scenario):
    """A synthetic DEM: a plane falling at 30 deg towards +X, with a step in slope.

    Bilinear sampling reproduces a plane exactly, so the profile along a polyline down the
    fall line, read on a 25 deg plane, is b = -tan(5 deg) x; the diagonal leg of the
    polyline crosses the same plane at a gentler apparent slope.
    """
    pytest.importorskip("rasterio", reason="the optional [dem] extra (rasterio) is not installed")
    pixel = 0.01
    cols, rows = np.meshgrid(np.arange(60), np.arange(40))
    east = 1000.0 + (cols + 0.5) * pixel  # pixel centres
    elevation = 200.0 + _descending(east - 1000.0, 30.0)
    _write_geotiff(tmp_path / "dem.tif", elevation, pixel)
    north = 5000.0 - 0.2
    polyline = [[1000.05, north], [1000.30, north], [1000.50, north - 0.10]]
    cells = ["domain.cells=60"]  # more cells than samples: the profile is kept, not resampled
    sc = load(_scenario(write_scenario, tiny_scenario, bed={"dem": "dem.tif", "polyline": polyline}), cells)
    x, b = np.asarray(sc.bed.points).T
    first = x <= 0.25 / math.cos(math.radians(30)) * math.cos(math.radians(5)) + 1e-12
    assert first.sum() == 26  # every pixel size along the first leg, vertices included
    np.testing.assert_allclose(b[first], -math.tan(math.radians(5)) * x[first], atol=1e-12)
    # second leg: horizontal length sqrt(0.2^2 + 0.1^2), drop 0.2 tan 30
    leg = math.hypot(0.2, 0.1)
    apparent = math.degrees(math.atan(0.2 * math.tan(math.radians(30)) / leg))
    slope_change = np.diff(b[~first]) / np.diff(x[~first])
    np.testing.assert_allclose(slope_change, -math.tan(math.radians(apparent - 25.0)), rtol=1e-9)
    # the same samples written as a map-frame CSV give the same bed
    along = np.concatenate([np.linspace(0, 0.25, 26), 0.25 + np.linspace(0, leg, 24)[1:]])
    east = 1000.05 + np.minimum(along, 0.25) + np.maximum(along - 0.25, 0) * 0.2 / leg
    z = 200.0 + _descending(east - 1000.0, 30.0)
    (tmp_path / "profile.csv").write_text(
        "x (m), z (m)\n" + "".join(f"{float(a)!r}, {float(c)!r}\n" for a, c in zip(along, z))
    )
    csv = load(_scenario(write_scenario, tiny_scenario, bed={"file": "profile.csv", "frame": "map"}), cells)
    np.testing.assert_allclose(csv.bed.points, sc.bed.points, atol=1e-12)


def test_dem_outside_or_nodata_is_an_input_error(tmp_path, write_scenario, tiny_scenario, cli):
    pytest.importorskip("rasterio", reason="the optional [dem] extra (rasterio) is not installed")
    elevation = np.full((10, 10), 5.0)
    elevation[5, 5] = -9999.0
    _write_geotiff(tmp_path / "dem.tif", elevation, 1.0, origin=(0.0, 10.0), nodata=-9999.0)
    path = _scenario(write_scenario, tiny_scenario, bed={"dem": "dem.tif", "polyline": [[1, 5], [8, 5]]})
    result = cli("validate", path)  # bilinear sampling needs the 4 pixels around a point
    assert result.code == 2
    assert "bed.dem (line" in result.err and "no elevation at (5, 5), 4 m along the polyline" in result.err
    result = cli("validate", path, "--set", "bed.polyline=[[1.5, 8.5], [12.5, 8.5]]")
    assert result.code == 2 and "no elevation at (10.5, 8.5), 9 m along the polyline" in result.err
    result = cli("validate", path, "--set", "bed.polyline=[[1.5, 8.5], [1.5, 1.5]]")
    assert result.code == 0, result.err


@pytest.mark.parametrize(
    "text, message",
    [
        ("x, z\n0, 1\n1, 0\n", "line 1: header 'x, z' does not name the columns x and z|b with their units"),
        ("x (m), z (ft)\n0, 1\n1, 0\n", "line 1: header 'x (m), z (ft)'"),
        (
            "# survey\n\nx (m), z (m)\n0, 1\n1; 0\n",
            "line 5: expected two numbers separated by a comma, got '1; 0'",
        ),
        ("x (m), z (m)\n0, 1\n0.5, nan\n", "line 3: expected two numbers"),
        ("x (m), z (m)\n0, 1\n0.5, 0\n0.5, 0\n", "line 4: x = 0.5 does not increase"),
        ("x (m), z (m)\n0, 1\n", "1 data row(s); accepted: at least 2 rows"),
    ],
)
def test_bad_csv_bed_is_exit_2_naming_the_line(tmp_path, write_scenario, tiny_scenario, cli, text, message):
    (tmp_path / "bed.csv").write_text(text)
    result = cli("validate", _scenario(write_scenario, tiny_scenario, bed={"file": "bed.csv"}))
    assert result.code == 2
    assert "bed.file (line " in result.err and f"{tmp_path / 'bed.csv'}: {message}" in result.err
    assert "Traceback" not in result.err


def test_bad_initial_profile_file_is_exit_2(tmp_path, write_scenario, tiny_scenario, cli):
    (tmp_path / "h.csv").write_text("x (m), h (m)\n0, 0.1\n0.1, -0.01\n")
    initial = [{"shape": "profile", "file": "h.csv"}]
    result = cli("validate", _scenario(write_scenario, tiny_scenario, initial=initial))
    assert result.code == 2 and "initial.0.file (line" in result.err and "negative thickness" in result.err
    result = cli(
        "validate", _scenario(write_scenario, tiny_scenario, initial=[{"shape": "profile", "file": "no.csv"}])
    )
    assert result.code == 2 and "no.csv: file not found" in result.err


def test_a_bed_profile_short_of_the_domain_is_refused_unless_extended(
    tmp_path, write_scenario, tiny_scenario
):
    """A bed of a file ending at 0.2 m on a domain to 0.3 m was continued level beyond it
    silently (numpy's interpolation), a terrain the scenario never gave.  Refused, naming
    the key, the file, the profile's extent and the domain's; ``extend: flat`` continues it."""
    (tmp_path / "short.csv").write_text("x (m), z (m)\n0.0, 0.01\n0.2, 0.0\n")
    for bed, spans in (
        ({"file": "short.csv"}, "file (line 27): the profile short.csv spans x = [0, 0.2] m"),
        ({"points": [[0.05, 0.0], [0.3, 0.0]]}, "points (line 27): the profile spans x = [0.05, 0.3] m"),
    ):
        with pytest.raises(InputError) as caught:
            load(_scenario(write_scenario, tiny_scenario, bed=bed))
        message = str(caught.value)
        assert f"bed.{spans} (along the slope), short of the domain [0, 0.3] m" in message
        assert "accepted: a profile reaching both ends of the domain, or extend: flat" in message
    extended = load(_scenario(write_scenario, tiny_scenario, bed={"file": "short.csv", "extend": "flat"}))
    assert extended.bed.points == [[0.0, 0.01], [0.2, 0.0]]
    recorded = yaml.safe_load(extended.resolved_yaml())
    assert recorded["bed"] == {"profile": "points", "points": [[0.0, 0.01], [0.2, 0.0]], "extend": "flat"}
    assert from_dict(recorded).bed.extend == "flat"


def test_a_csv_profile_read_before_and_unchanged_is_not_parsed_again(tmp_path, monkeypatch):
    """Every member of a study is validated: a bed of 10^6 rows was parsed again for each
    (7 s a member); a file changed since is read again, and each reader gets its own copy."""
    from multilayer.scenario import profiles

    profiles._cached_csv_profile.cache_clear()
    parsed = []
    real = profiles._parsed_csv_profile
    monkeypatch.setattr(
        profiles, "_parsed_csv_profile", lambda path, columns: parsed.append(path) or real(path, columns)
    )
    path = tmp_path / "bed.csv"
    path.write_text("x (m), z (m)\n0, 0\n1, 0.5\n")
    first, second = (profiles.read_csv_profile(path, ("x", "z|b")) for _ in range(2))
    assert len(parsed) == 1 and first.tolist() == second.tolist() == [[0.0, 0.0], [1.0, 0.5]]
    first[1, 1] = 9.0
    assert profiles.read_csv_profile(path, ("x", "z|b"))[1, 1] == 0.5
    os.utime(path, ns=(0, 0))  # another modification time: read again
    assert profiles.read_csv_profile(path, ("x", "z|b")).tolist() == [[0.0, 0.0], [1.0, 0.5]]
    assert len(parsed) == 2


def test_a_sweep_member_costs_no_work_per_row_of_a_bed_file_read_before(
    tmp_path, write_scenario, tiny_scenario, monkeypatch
):
    """Every member of a sweep is validated: a bed of 10^6 rows read once still cost 0.9 s
    a member (its rows turned into lists, checked, searched).  Bounded by counts, not by
    time: each file is parsed once, and a member allocates less than half of one column
    of a file of 40 000 rows (its lists took 100 bytes a row); a member changing the
    cells resamples, one changing the file reads it."""
    import tracemalloc

    from multilayer.app import sweep as sweeps
    from multilayer.scenario import profiles

    rows = 40_000
    for name, scale in (("bed.csv", 0.01), ("other.csv", 0.02)):
        x = np.linspace(0.0, 0.3, rows)
        (tmp_path / name).write_text(
            "x (m), z (m)\n" + "".join(f"{a!r}, {scale * math.sin(40 * a)!r}\n" for a in x.tolist())
        )
    profiles._cached_csv_profile.cache_clear()
    parsed = []
    real = profiles._parsed_csv_profile
    monkeypatch.setattr(
        profiles, "_parsed_csv_profile", lambda path, columns: parsed.append(path.name) or real(path, columns)
    )
    _scenario(write_scenario, tiny_scenario, bed={"file": "bed.csv"})
    sweep = sweeps.load(
        write_scenario(
            {"base": "scenario.yaml", "parameters": {"rheology.mu_s": [0.2, 0.25, 0.3, 0.35]}}, "sweep.yaml"
        )
    )
    members = sweep.members()
    sweep.member_scenario(members[0])
    tracemalloc.start()
    try:
        for member in members[1:]:
            tracemalloc.reset_peak()
            scenario = sweep.member_scenario(member)
            assert tracemalloc.get_traced_memory()[1] < rows * 8 // 2
    finally:
        tracemalloc.stop()
    assert parsed == ["bed.csv"]
    assert len(scenario.bed.points) == 32  # the 30 cell centres and the two ends
    read = profiles.read_csv_profile(tmp_path / "bed.csv", ("x", "z|b"))
    finer = sweep.member_scenario(members[1], ["domain.cells=60"])
    x = np.array([p[0] for p in finer.bed.points])
    assert len(x) == 62 and [p[1] for p in finer.bed.points] == np.interp(x, *read.T).tolist()
    other = sweep.member_scenario(members[1], ["bed.file=other.csv"])
    assert parsed == ["bed.csv", "other.csv"]
    assert [p[1] for p in other.bed.points] == pytest.approx([2 * p[1] for p in scenario.bed.points])


def test_a_profile_sampled_at_its_rows_only_equals_np_interp():
    """:func:`profiles.sampled` reads the rows bracketing each x: the values of ``np.interp``
    over all rows, at rows, between them and beyond both ends."""
    from multilayer.scenario import profiles

    rng = np.random.default_rng(5)
    px = np.cumsum(rng.uniform(1e-3, 1.0, 500))
    points = np.asfortranarray(np.column_stack([px, rng.normal(size=500)]))
    points.flags.writeable = False
    x = np.concatenate([px[::7], rng.uniform(px[0] - 5, px[-1] + 5, 200), [px[0], px[-1]]])
    assert profiles.sampled(points, x).tolist() == np.interp(x, px, points[:, 1]).tolist()


@pytest.mark.parametrize("separator", ["\f", "\v", "\x1c", "\x85", "\u2028", "\u2029"])
def test_a_csv_line_ends_only_at_a_line_feed_or_carriage_return(tmp_path, separator):
    """``str.splitlines`` ended a line at a form feed, a vertical tab, ``\\x1c``, ``\\x85``,
    ``\\u2028`` or ``\\u2029``: ``0, 0<FF>0.3, 0`` was read as two rows (exit 0), where the
    ``csv`` module and spreadsheets read one row of three fields, and the line numbers of the
    messages were not an editor's."""
    from multilayer.scenario import profiles

    path = tmp_path / "bed.csv"
    path.write_text(f"x (m), z (m)\n0, 0{separator}0.3, 0\n", encoding="utf-8")
    with pytest.raises(InputError) as caught:
        profiles.read_csv_profile(path, ("x", "z|b"))
    assert (
        f"bed.csv: line 2: expected two numbers separated by a comma, got {f'0, 0{separator}0.3, 0'!r}"
        in str(caught.value)
    )
    path.write_text(f"x (m), z (m)\n# a note{separator}of two parts\n0, 0\n0.2, x\n", encoding="utf-8")
    with pytest.raises(InputError, match="bed.csv: line 4: expected two numbers"):  # an editor's line
        profiles.read_csv_profile(path, ("x", "z|b"))
    path.write_bytes(b"x (m), z (m)\r0, 0\r\n0.3, 0.5\r")  # the line ends a CSV writer writes
    assert profiles.read_csv_profile(path, ("x", "z|b")).tolist() == [[0.0, 0.0], [0.3, 0.5]]


def test_a_map_frame_bed_is_turned_into_the_slope_frame_once_per_file_and_slope(
    tmp_path, write_scenario, tiny_scenario, monkeypatch
):
    """Every member of a sweep is validated: a bed in the map frame was turned into the
    slope frame for each (work per row of the file).  Counted: one conversion per file and
    slope, the members' beds equal to a conversion of their own; a member at another slope
    converts again."""
    from multilayer.app import sweep as sweeps
    from multilayer.scenario import profiles

    rows = 5000
    s = np.linspace(0.0, 0.4, rows)
    (tmp_path / "terrain.csv").write_text(
        "x (m), z (m)\n" + "".join(f"{a!r}, {b!r}\n" for a, b in zip(s.tolist(), _descending(s, 20).tolist()))
    )
    profiles._cached_csv_profile.cache_clear()
    profiles._DERIVED.clear()
    converted = []
    real = profiles.map_to_slope_frame
    monkeypatch.setattr(
        profiles,
        "map_to_slope_frame",
        lambda points, slope, where: converted.append(slope) or real(points, slope, where),
    )
    _scenario(write_scenario, tiny_scenario, bed={"file": "terrain.csv", "frame": "map"})
    sweep = sweeps.load(
        write_scenario(
            {"base": "scenario.yaml", "parameters": {"rheology.mu_s": [0.2, 0.3, 0.4]}}, "sweep.yaml"
        )
    )
    beds = [sweep.member_scenario(member).bed.points for member in sweep.members()]
    assert converted == [tiny_scenario["slope_deg"]] and beds[0] == beds[1] == beds[2]
    steeper = sweep.member_scenario(sweep.members()[0], ["slope_deg=30"])
    assert converted == [tiny_scenario["slope_deg"], 30]
    monkeypatch.setattr(profiles, "map_to_slope_frame", real)
    fresh = real(profiles.read_csv_profile(tmp_path / "terrain.csv", ("x", "z|b")), 30, "terrain.csv")
    x = np.array([p[0] for p in steeper.bed.points])
    assert [p[1] for p in steeper.bed.points] == np.interp(x, *fresh.T).tolist()


def test_a_dem_read_before_along_the_same_polyline_is_not_read_again(
    tmp_path, write_scenario, tiny_scenario, monkeypatch
):
    """A DEM's profile is shared as a CSV's is (read once per file, polyline, spacing and
    modification), and turned into the slope frame once per slope; the reading itself is
    replaced here (rasterio is optional)."""
    from multilayer.scenario import profiles

    profiles._cached_dem_profile.cache_clear()
    profiles._DERIVED.clear()
    reads, converted = [], []
    s = np.linspace(0.0, 0.4, 400)
    monkeypatch.setattr(
        profiles,
        "_parsed_dem_profile",
        lambda path, vertices, spacing: reads.append(vertices.tolist()) or np.column_stack([s, -0.1 * s]),
    )
    real = profiles.map_to_slope_frame
    monkeypatch.setattr(
        profiles, "map_to_slope_frame", lambda *args: converted.append(args[1]) or real(*args)
    )
    (tmp_path / "dem.tif").write_bytes(b"a GeoTIFF")
    bed = {"dem": "dem.tif", "polyline": [[0.0, 0.0], [0.4, 0.0]]}
    first, second = (load(_scenario(write_scenario, tiny_scenario, bed=bed)).bed.points for _ in range(2))
    assert first == second and reads == [[[0.0, 0.0], [0.4, 0.0]]] and len(converted) == 1
    load(_scenario(write_scenario, tiny_scenario, bed={**bed, "polyline": [[0.0, 0.0], [0.0, 0.4]]}))
    assert len(reads) == 2
    os.utime(tmp_path / "dem.tif", ns=(0, 0))  # another modification time: read again
    load(_scenario(write_scenario, tiny_scenario, bed=bed))
    assert len(reads) == 3


@pytest.mark.slow
def test_a_sweep_member_costs_no_work_per_row_of_an_initial_thickness_file_read_before(
    tmp_path, write_scenario, tiny_scenario, monkeypatch
):
    """Every member of a sweep is validated: an initial thickness of a file was parsed
    once, but each member copied its rows, made lists of them, checked them again and
    copied the lists when its keys were recorded, and `validate` wrote them as YAML to size
    the result's header (3 s a member at 10^5 rows).  Counted:
    one parse per file, a member allocating less than half of one column of a file of
    40 000 rows; the initial state, the record and a member of another file equal those of
    the same profile given by points; the rows cannot be written."""
    import tracemalloc

    from multilayer.app import resources
    from multilayer.app import sweep as sweeps
    from multilayer.scenario import profiles

    rows = 40_000
    x = np.linspace(0.0, 0.3, rows)
    h = np.where(x < 0.1, 0.05 * (1.0 + np.cos(30 * x)), 0.0)
    (tmp_path / "h.csv").write_text(
        "x (m), h (m)\n" + "".join(f"{a!r}, {b!r}\n" for a, b in zip(x.tolist(), h.tolist()))
    )
    (tmp_path / "other.csv").write_text("x (m), h (m)\n0, 0.02\n0.1, 0.02\n0.2, 0\n")
    profiles._cached_csv_profile.cache_clear()
    parsed = []
    real = profiles._parsed_csv_profile
    monkeypatch.setattr(
        profiles, "_parsed_csv_profile", lambda path, columns: parsed.append(path.name) or real(path, columns)
    )
    _scenario(write_scenario, tiny_scenario, initial=[{"shape": "profile", "file": "h.csv"}])
    sweep = sweeps.load(
        write_scenario(
            {"base": "scenario.yaml", "parameters": {"rheology.mu_s": [0.2, 0.25, 0.3, 0.35]}}, "sweep.yaml"
        )
    )
    members = sweep.members()
    resources.estimate(sweep.member_scenario(members[0]))
    tracemalloc.start()
    try:
        for member in members[1:]:
            tracemalloc.reset_peak()
            scenario = sweep.member_scenario(member)
            resources.estimate(scenario)  # validate's: the size of the result's header
            assert tracemalloc.get_traced_memory()[1] < rows * 8 // 2
    finally:
        tracemalloc.stop()
    assert parsed == ["h.csv"] and not scenario.changed_since_validation()
    assert 0 <= scenario.text_size() - len(scenario.resolved_yaml()) < 16
    by_points = from_dict(
        {**tiny_scenario, "initial": [{"shape": "profile", "points": np.column_stack([x, h]).tolist()}]}
    )
    edges = cell_edges(0.0, 0.3, 30)
    centres, sigma = 0.5 * (edges[1:] + edges[:-1]), np.array([1 / 6, 0.5, 5 / 6])
    from multilayer.app import factory

    for a, b in zip(
        initial_state(factory.initial_entries(scenario), centres, sigma, edges),
        initial_state(factory.initial_entries(by_points), centres, sigma, edges),
    ):
        np.testing.assert_array_equal(a, b)
    recorded = scenario.model_dump(mode="json", exclude_none=True, warnings=False)["initial"][
        0
    ]  # resolved_yaml's
    assert "file" not in recorded and recorded["points"] == np.column_stack([x, h]).tolist()
    with pytest.raises(ValueError, match="read-only"):
        scenario.initial[0].points[0][1] = 1.0  # type: ignore[index]
    other = sweep.member_scenario(members[1], ["initial.0.file=other.csv"])
    assert parsed == ["h.csv", "other.csv"] and other.initial[0].points.tolist() == [  # type: ignore[union-attr]
        [0.0, 0.02],
        [0.1, 0.02],
        [0.2, 0.0],
    ]
    scenario.initial[0].points = [[0.0, 0.05], [0.1, 0.0]]  # assigned since: validated again
    assert scenario.changed_since_validation()
    (tmp_path / "h.csv").write_text("x (m), h (m)\n0, 0.02\n0.1, -0.01\n")
    with pytest.raises(InputError, match=r"initial.0.file \(line \d+\): negative thickness"):
        sweep.member_scenario(members[1])
