"""The result file: CF attributes, incremental writing, summary, checkpoints."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import fipy
import netCDF4
import numpy as np
import pytest
import xarray as xr
import yaml
from conftest import TINY_SCENARIO

import multilayer
from multilayer import scenario as scenarios
from multilayer.app import runner
from multilayer.app.simulation import Simulation
from multilayer.errors import InputError
from multilayer.io.netcdf_layout import declared_size
from multilayer.io.plotting import drawn_from
from multilayer.io.result_check import check_result
from multilayer.io.results import (
    Checkpoint,
    ResultWriter,
    load_checkpoint,
    open_result,
    save_checkpoint,
    summary,
)
from multilayer.scenario.source import safe_load

# A 0.1 m x 0.05 m column on a 25 degree slope, 40 cells x 3 layers, wall on the left.
COLUMN = {**TINY_SCENARIO, "name": "column"}


@pytest.fixture(scope="module")
def result_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    outdir = tmp_path_factory.mktemp("column")
    runner.run(scenarios.from_dict(COLUMN), outdir, quiet=True)
    return outdir


def test_every_variable_and_coordinate_has_cf_attributes(result_dir: Path) -> None:
    with netCDF4.Dataset(result_dir / "result.nc") as ds:
        assert ds.Conventions == "CF-1.8"
        for name, var in ds.variables.items():
            assert var.units and var.long_name, name
        assert {n: ds[n].axis for n in ("time", "x", "layer")} == {"time": "T", "x": "X", "layer": "Z"}
        assert ds["time"].standard_name == "time"
        assert ds["u"].coordinates == "sigma"
        assert ds["front"].threshold == 1e-3
        assert ds.dimensions["time"].isunlimited()
        for attr in ("title", "institution", "source", "history"):
            assert getattr(ds, attr)
        assert yaml.safe_load(ds.scenario)["name"] == "column"
        assert ds.cells == 40 * 3
        assert ds.steps > 0 and ds.wall_time_s > 0
        assert ds.multilayer_version == multilayer.__version__
        assert ds.fipy_version == fipy.__version__
        assert ds.run_status == "completed"


def test_contents_match_the_setup(result_dir: Path) -> None:
    ds = xr.open_dataset(result_dir / "result.nc")
    np.testing.assert_allclose(ds["time"], [0.0, 0.025, 0.05], rtol=0, atol=1e-15)
    np.testing.assert_allclose(ds["x"], 0.00625 + 0.0125 * np.arange(40), atol=1e-15)
    np.testing.assert_allclose(ds["sigma"], [1 / 6, 1 / 2, 5 / 6], atol=1e-15)
    np.testing.assert_allclose(ds["sigma_bnds"][:, 1] - ds["sigma_bnds"][:, 0], 1 / 3)
    np.testing.assert_allclose(ds["x_bnds"][:, 1] - ds["x_bnds"][:, 0], 0.0125)
    # released from rest: the column is 8 cells of 0.05 m, at rest (static to the top)
    assert np.abs(ds["u"][0]).max() == 0.0
    np.testing.assert_allclose(ds["h"][0, :8], 0.05)
    np.testing.assert_allclose(ds["static_interface"][0, :8], 0.05)
    assert float(ds["front"][0]) == pytest.approx(0.09375)
    # the front has not reached the outflow: mass 0.1 m x 0.05 m is conserved
    np.testing.assert_allclose(ds["mass"], 0.005, rtol=1e-12)
    np.testing.assert_allclose(ds["mass"], ds["h"].sum("x") * 0.0125, rtol=1e-12)


def test_summary_is_read_from_the_final_time(result_dir: Path) -> None:
    ds = xr.open_dataset(result_dir / "result.nc")
    final = ds.isel(time=-1)
    wet = final["h"] > 1e-3
    s = summary(result_dir)
    assert s["front_final"] == float(final["front"])
    assert s["runout"] == pytest.approx(float(final["front"]) - 0.09375)
    assert s["runout"] > 0  # 25 deg > atan(0.3) = 16.7 deg: the column slumps downslope
    assert s["mass_final"] == pytest.approx(0.005, rel=1e-12)
    assert s["max_speed_final"] == float(np.abs(final["u"]).max()) > 0
    assert s["static_interface_mean_final"] == pytest.approx(
        float(final["static_interface"].where(wet).mean())
    )
    assert s["wall_time_s"] == ds.attrs["wall_time_s"]
    assert s["steps"] == ds.attrs["steps"]
    # the seismic force: the force on the bed and the walls less the weight, per interval
    on_earth = ds["bed_force_x"] + ds["wall_force_x"] + ds["end_force_x"] + ds["pressure_force_x"]
    seismic = (on_earth - ds["gravity_force_x"]).values
    assert np.isnan(seismic[0]) and s["peak_seismic_force_x"] == np.abs(seismic[1:]).max() > 0
    assert s["peak_seismic_force_z"] == 0.0  # hydrostatic on a plane: only downslope radiates


def test_the_forces_balance_the_momentum_between_records(result_dir: Path) -> None:
    """The means over each output interval times the interval are the change of momentum
    (every reader checks it; here from the file's own numbers)."""
    ds = xr.open_dataset(result_dir / "result.nc")
    momentum = 1500.0 * 0.0125 * (ds["u"] * ds["h"] / 3).sum(("layer", "x")).values
    gravity = ds["gravity_force_x"].values
    assert gravity[1:] == pytest.approx(1500.0 * 0.005 * 9.81 * np.sin(np.radians(25.0)), rel=1e-12)
    net = gravity - ds["bed_force_x"] - ds["end_force_x"] - ds["outflow_momentum_x"]
    np.testing.assert_allclose(np.diff(momentum), 0.025 * net.values[1:], rtol=1e-10)
    assert np.all(ds["wall_force_x"][1:] == 0.0) and np.all(ds["pressure_force_x"][1:] == 0.0)


def test_records_are_whole_while_writing_a_reader_waits_for_the_end(tmp_path: Path) -> None:
    """While a run writes (or after its process was killed), the records synced so far are
    whole (what --resume continues from); a reader refuses the file until the run ends, and
    a record left half-written by a crash (its time not yet written) is damage."""
    sc = scenarios.from_dict(COLUMN)
    sim = Simulation(sc)
    writer = ResultWriter(tmp_path / "result.nc", sc, sc.resolved_yaml(), sim)
    writer.write(sim)
    sim.advance(0.01)
    writer.write(sim)
    assert check_result(tmp_path, "resume", records=2) == tmp_path / "result.nc"
    with pytest.raises(InputError, match="run_status is 'running': a run is still writing it"):
        open_result(tmp_path)
    # a crash in the middle of the next record: h written, time not yet
    with netCDF4.Dataset(tmp_path / "result.nc", "a") as ds:
        ds["h"][2, :] = sim.h
    check_result(tmp_path, "resume", records=2)
    with pytest.raises(InputError, match=r"output time 2 \(t = nan s\) fails its checks: time nan"):
        check_result(tmp_path, "resume", records=3)
    writer.close(sim.steps, 0.5, "interrupted")  # short of time.end: not a completed run
    assert open_result(tmp_path).sizes["time"] == 2  # the writer's header counts its own records


def test_a_long_mesh_of_small_cells_passes_the_mass_check(tmp_path: Path) -> None:
    """The mass of each record is the integral of h with the writer's dx = (x_max - x_min) /
    cells; the cell widths of x_bnds differ from it by the round-off of x (a valid file of
    1200 cells of 1 mm on [0, 1.2] covered by a deposit was refused with dx their mean)."""
    sc = scenarios.from_dict(
        {
            **COLUMN,
            "domain": {**COLUMN["domain"], "x_max": 1.2, "cells": 1200},
            "initial": [{"shape": "layer", "thickness": 0.02}],
        }
    )
    sim = Simulation(sc)
    writer = ResultWriter(tmp_path / "result.nc", sc, sc.resolved_yaml(), sim)
    writer.write(sim)
    writer.close(sim.steps, 0.0, "interrupted")  # at t = 0: not a completed run
    assert open_result(tmp_path).sizes["time"] == 1


def test_checkpoint_round_trip_is_exact_and_atomic(tmp_path: Path) -> None:
    sim = Simulation(scenarios.from_dict(COLUMN))
    sim.advance(0.01)
    path = tmp_path / "checkpoint.npz"
    save_checkpoint(path, Checkpoint(sim.state_dict(), 2, 1.25, "name: column\n"))
    assert [p.name for p in tmp_path.iterdir()] == ["checkpoint.npz"]
    back = load_checkpoint(path)
    assert (back.records, back.wall_time_s, back.scenario) == (2, 1.25, "name: column\n")
    fresh = Simulation(scenarios.from_dict(COLUMN))
    fresh.load_state(back.state)
    assert (fresh.t, fresh.steps) == (sim.t, sim.steps)
    np.testing.assert_array_equal(fresh.h, sim.h)
    np.testing.assert_array_equal(fresh.u, sim.u)


def test_a_checkpoint_unpacking_to_more_than_its_file_is_refused_before_it_is_read(tmp_path: Path) -> None:
    """A member deflated 1000 to 1, or whose header declares more data than it holds, was
    read as its declared size (a checkpoint of 1 MB took 2.3 GB before its checksum failed):
    refused from the archive's directory and the ``.npy`` headers, nothing read."""
    import io
    import zipfile

    sim = Simulation(scenarios.from_dict(COLUMN))
    path = tmp_path / "checkpoint.npz"
    save_checkpoint(path, Checkpoint(sim.state_dict(), 2, 1.25, "name: column\n"))
    arrays = dict(np.load(path))

    def rewrite(member: bytes, compress_type: int) -> None:
        with zipfile.ZipFile(path, "w") as archive:
            for name, a in arrays.items():
                data = io.BytesIO()
                np.save(data, a)
                if name == "state.h":
                    archive.writestr(f"{name}.npy", member, compress_type=compress_type)
                else:
                    archive.writestr(f"{name}.npy", data.getvalue())

    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False, "shape": (2**20,)})
    rewrite(header.getvalue() + bytes(2**23), zipfile.ZIP_DEFLATED)  # 8 MB of zeros in 8 kB
    with pytest.raises(InputError, match=r"corrupt checkpoint \(its members unpack to \d+ bytes, more than"):
        load_checkpoint(path)
    rewrite(header.getvalue() + bytes(64), zipfile.ZIP_STORED)
    with pytest.raises(InputError, match="state.h.npy declares 8388608 bytes of data in 192"):
        load_checkpoint(path)


def test_a_checkpoint_whose_scenario_is_beyond_the_yaml_bounds_is_corrupt(tmp_path: Path) -> None:
    """An alias inside its own anchor (a RecursionError of ``--resume``, which compares the
    checkpoint's scenario with its result's key by key) and the billion laughs (minutes
    of that comparison) are bounded as in a scenario file."""
    laughs = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
        f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(9)
    )
    sim = Simulation(scenarios.from_dict(COLUMN))
    path = tmp_path / "checkpoint.npz"
    for text, phrase in (
        ("extra: &a [*a]\n", "lies inside its own anchor"),
        (laughs, "values once its aliases"),
    ):
        with pytest.raises(yaml.YAMLError, match=phrase):
            safe_load(text)
        save_checkpoint(path, Checkpoint(sim.state_dict(), 2, 1.25, "name: column\n" + text))
        with pytest.raises(InputError, match="meta.scenario is not the YAML mapping of a scenario"):
            load_checkpoint(path)


def test_missing_or_broken_result_is_an_input_error(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="no result file"):
        open_result(tmp_path)
    (tmp_path / "result.nc").write_text("not netCDF")
    with pytest.raises(InputError, match="not a netCDF result file"):
        summary(tmp_path)


def test_a_failed_run_says_why_and_a_step_count_beyond_int32_is_written_whole(tmp_path: Path) -> None:
    """A run failed by an exception without a message wrote no ``failure``; a step count
    beyond 2^31 - 1 was written to the classic file's 32-bit integer as 0 (netCDF4 says
    nothing): it is a float64 there, exact to 2^53, and ``check_result`` reads it."""
    sc = scenarios.from_dict(COLUMN)
    sim = Simulation(sc)
    writer = ResultWriter(tmp_path / "result.nc", sc, sc.resolved_yaml(), sim)
    writer.write(sim)
    writer.close(2**40 + 1, 0.5, "failed")
    check_result(tmp_path, "records")
    with netCDF4.Dataset(tmp_path / "result.nc") as ds:
        assert ds.getncattr("steps") == 2**40 + 1
        assert ds.getncattr("failure") == "no message (an exception without one)"


def test_an_attribute_s_text_holds_no_lone_surrogate() -> None:
    """A byte of the environment kept by Python is one U+FFFD, as before; a lone surrogate
    of another origin (a third-party law's message in a failed run's ``failure``) was a
    ``UnicodeEncodeError`` of netCDF4 as the result was closed: now U+FFFD too."""
    from multilayer.io import results

    assert results._text("lab \udcff") == "lab \ufffd"
    replaced = results._text("bad \ud800 text")
    assert replaced.startswith("bad \ufffd") and replaced.endswith(" text")
    replaced.encode("utf-8")


@pytest.fixture(scope="module")
def finished_tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("finished")
    (directory / "tiny.yaml").write_text(yaml.safe_dump(TINY_SCENARIO), encoding="utf-8")
    runner.run(scenarios.load(directory / "tiny.yaml"), directory / "out", quiet=True)
    return directory


def test_a_result_followed_by_a_terabyte_of_zeros_is_drawn_from_its_declared_bytes_and_resume_cuts_them(
    finished_tiny, tmp_path, cli
):
    """A `result.nc` followed by bytes its header does not declare (a terabyte of zeros in a
    sparse file) is read as netCDF-C reads it: its figures' digest is that of the declared
    bytes, and `--resume` cuts the rest before it appends its records."""
    shutil.copytree(finished_tiny, tmp_path, dirs_exist_ok=True)
    result = tmp_path / "out" / "result.nc"
    declared, source = declared_size(result), drawn_from(result)
    assert declared is not None and declared <= result.stat().st_size
    os.truncate(result, 2**40)  # sparse: `plot` hashed the terabyte for hours
    assert drawn_from(result) == source  # the bytes netCDF-C reads, and nothing after them
    assert check_result(result) == result  # the records are whole: the file is read as it is
    longer = {**TINY_SCENARIO, "time": {"end": 0.1, "output_interval": 0.025}}
    path = tmp_path / "tiny.yaml"
    path.write_text(yaml.safe_dump(longer), encoding="utf-8")
    assert cli("run", path, "-o", tmp_path / "out", "-q", "--resume").code == 0
    assert result.stat().st_size < 2**20  # the zeros cut before the records were appended
    assert check_result(result) == result and open_result(tmp_path / "out").sizes["time"] == 5
