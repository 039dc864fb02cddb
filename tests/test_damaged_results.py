"""A damaged result is never read as a good one (docs/reliability.md): every reader of
``result.nc`` (plot, export, summary, run_failure, open_result, sweeps and calibrations,
``--resume``) refuses a file that is truncated, still ``running``, read decoded otherwise
than written (CF attributes multilayer does not write) or whose records fail their checks
(a grain-fluid mixture's too), with exit code 2 naming the file and what is wrong."""

from __future__ import annotations

import json
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO, fault_battery

from multilayer import scenario as scenarios
from multilayer.app import runner, sweep
from multilayer.errors import InputError
from multilayer.io.netcdf_layout import NUMRECS_OFFSET, read_layout
from multilayer.io.results import SUMMARY_KEYS, open_result, run_failure, summary

SHORT = {**TINY_SCENARIO, "name": "short", "time": {"end": 0.08, "output_interval": 0.02}}
"""5 output times of the tiny column."""
IMMERSED = {
    **SHORT,
    "domain": {"x_min": 0.0, "x_max": 0.5, "cells": 20, "layers": 1},
    "rheology": {"name": "dilatant_coulomb", "delta_deg": 22.5, "K1": 90.5},
    "material": {"density": 1500.0, "grain_diameter": 160e-6, "particle_density": 2500.0},
    "fluid": {"density": 1041.0, "viscosity": 0.096},
    "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05, "phi": 0.55}],
}
"""The same as a loose grain-fluid mixture in the first fluid of Pailha et al. (2008), in one layer."""


def _finish(directory: Path, scenario: dict) -> Path:
    (directory / "short.yaml").write_text(yaml.safe_dump(scenario), encoding="utf-8")
    runner.run(scenarios.load(directory / "short.yaml"), directory / "out", quiet=True)
    return directory


@pytest.fixture(scope="module")
def finished(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _finish(tmp_path_factory.mktemp("finished"), SHORT)


@pytest.fixture(scope="module")
def finished_mixture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _finish(tmp_path_factory.mktemp("finished_mixture"), IMMERSED)


def _truncate(path: Path) -> None:
    os.truncate(path, path.stat().st_size * 2 // 3)


def _status(status: str) -> Callable[[Path], None]:
    def damage(path: Path) -> None:
        with netCDF4.Dataset(path, "a") as ds:
            ds.run_status = status

    return damage


def _set(name: str, index: tuple, value: float) -> Callable[[Path], None]:
    def damage(path: Path) -> None:
        with netCDF4.Dataset(path, "a") as ds:
            ds[name][index] = value

    return damage


def _attribute(name: str, key: str, value: object) -> Callable[[Path], None]:
    def damage(path: Path) -> None:
        with netCDF4.Dataset(path, "a") as ds:
            ds[name].delncattr(key) if value is None else ds[name].setncattr(key, value)

    return damage


def _global(key: str, value: object) -> Callable[[Path], None]:
    """The global attribute ``key`` set to ``value``, or deleted for None."""

    def damage(path: Path) -> None:
        with netCDF4.Dataset(path, "a") as ds:
            ds.delncattr(key) if value is None else ds.setncattr(key, value)

    return damage


def _scenario_text(old: str, new: str) -> Callable[[Path], None]:
    def damage(path: Path) -> None:
        with netCDF4.Dataset(path, "a") as ds:
            assert old in ds.scenario
            ds.scenario = ds.scenario.replace(old, new)

    return damage


def _shifted(path: Path) -> None:
    """The cell centres, their edges and the front moved 100 m down the slope, consistently."""
    with netCDF4.Dataset(path, "a") as ds:
        for name in ("x", "x_bnds", "front"):
            ds[name][:] = ds[name][:] + 100.0


def _header(path: Path) -> None:
    data = bytearray(path.read_bytes())
    data[20:40] = b"\xff" * 20  # inside the dimension list
    path.write_bytes(bytes(data))


def _cut(path: Path) -> None:
    """The first 3 records kept, the header saying so, its attributes (completed) kept."""
    with open(path, "r+b") as stream:
        stream.seek(NUMRECS_OFFSET)
        stream.write((3).to_bytes(4, "big"))
    layout = read_layout(path)
    size = path.stat().st_size
    while layout.complete_records(size - 1) >= 3:
        size -= 1
    os.truncate(path, size)


DAMAGES = {
    "records removed": (
        _cut,
        r"its 3 output times run from t = 0 s to 0.04 s, not from 0 to its time.end \(0.08 s\)",
    ),
    "truncated": (_truncate, r"truncated: \d+ bytes, \d of its 5 output times whole"),
    "running": (_status("running"), "run_status is 'running': a run is still writing it"),
    "nan in h": (_set("h", (3, 7), np.nan), r"output time 3 \(t = 0.06 s\) fails its checks: h = nan at x"),
    "negative h": (_set("h", (2, 1), -1e-3), r"output time 2 \(t = 0.04 s\) fails its checks: h = -0.001 m"),
    "inf in u": (_set("u", (1, 2, 3), np.inf), r"output time 1 \(t = 0.02 s\) fails its checks: u = inf"),
    "mass changed": (_set("mass", (4,), 1.0), r"output time 4 .* mass 1.0 m2 is not the integral of h"),
    "front changed": (_set("front", (4,), 0.3), r"output time 4 .* front 0.3 m is not the front of h"),
    "time reversed": (_set("time", (2,), 0.01), r"output time 2 .* is not finite and after the previous one"),
    "h changed": (_set("h", (1, 0), 0.2), r"output time 1 .* mass .* is not the integral of h"),
    "force changed": (
        _set("bed_force_x", (3,), 1e3),
        r"output time 3 .* the change of momentum since the previous output time, .* is not the impulse",
    ),
    "force at t = 0": (_set("end_force_x", (0,), 0.0), r"output time 0 .* end_force_x is 0.0, not NaN"),
    "header": (_header, "not a (netCDF result file|readable multilayer result)"),
    # read decoded, as xarray reads them: dry cells NaN, velocities scaled, times as dates
    "missing_value": (_attribute("h", "missing_value", 0.0), "its variable h has missing_value 0.0"),
    "scale_factor": (_attribute("u", "scale_factor", 2.0), "its variable u has scale_factor 2.0"),
    "time in dates": (
        _attribute("time", "units", "seconds since 2000-01-01"),
        "its variable time has units 'seconds since 2000-01-01'",
    ),
    "x_bnds nan": (_set("x_bnds", (3, 0), np.nan), "its cell edges x_bnds are not finite"),
    "sigma nan": (_set("sigma", (1,), np.nan), "its layer heights sigma and sigma_bnds are not finite"),
    # the mesh and the bed are those of the scenario: shifted or replaced consistently, every
    # other check passed and the figures and VTK files showed the flow 100 m away (exit 0)
    "x shifted": (
        _shifted,
        r"its cell centres x or edges x_bnds are not the 40 cells of its scenario's domain \[0, 0.5\] m "
        r"\(x from 100.006 to 100.494 m\)",
    ),
    "bed changed": (
        _set("bed", (5,), 0.01),
        r"its bed is not its scenario's bed: 0.01 m at x = 0.06875 m, where the scenario's bed is at 0 m",
    ),
    "scenario bed": (
        _scenario_text("profile: flat", "profile: lumpy"),
        r"its scenario attribute's bed is not a flat bed or points",
    ),
    # the scenario attribute: a tag PyYAML's constructor cannot read (was a ValueError), a slope
    # the figures compute with that is text (a traceback of plot)
    "scenario tag": (
        _scenario_text("end: 0.08", "end: !!float abc"),
        "its scenario attribute is missing or damaged",
    ),
    # an alias inside its own anchor: --resume compared it with the checkpoint's, a RecursionError
    "scenario recursive": (
        _scenario_text("name: short", "name: short\nextra: &a [*a]"),
        "its scenario attribute is missing or damaged",
    ),
    "scenario slope": (
        _scenario_text("slope_deg: 25.0", "slope_deg: steep"),
        "its scenario attribute's slope_deg is 'steep', not a finite number",
    ),
    # the attributes a reader reads: a sweep run again read its members' summaries (steps
    # 'many' was a ValueError), --resume the version (missing: an AttributeError, as the
    # front's threshold was for every reader)
    "steps text": (_global("steps", "many"), r"its attribute steps is 'many', not an integer from 0 to 2\^"),
    "version missing": (_global("multilayer_version", None), "its attribute multilayer_version is missing"),
    # more steps than a run writes (an int32, a float64 from 2^31 to 2^53), a failed run
    # without its reason or with a number for one ('plot' said "the run failed: 3.5")
    "steps 2^62": (
        _global("steps", np.float64(2.0**62)),
        r"its attribute steps is 4\.6\d*e\+18, not an integer from 0 to 2\^53",
    ),
    "failed without failure": (
        _global("run_status", "failed"),
        "run_status is 'failed' and its attribute failure \\(why\\) is missing",
    ),
    "failure a number": (
        lambda path: (_global("run_status", "failed")(path), _global("failure", 3.5)(path)),
        "its attribute failure is 3.5, not text of 1 to 8000 characters",
    ),
    "threshold missing": (
        _attribute("front", "threshold", None),
        "its variable front's attribute threshold is missing",
    ),
    # another tool's number where multilayer writes text: said as the number the file holds
    # (a message said "units np.float64(5.0)", and "run_status '3'" as if it were text)
    "units a number": (_attribute("h", "units", 5.0), r"its variable h has units 5\.0, which multilayer"),
    "status a number": (_global("run_status", np.int32(3)), "run_status 3 is not one of completed"),
    "not netCDF": (lambda path: path.write_text("not netCDF"), r"not a netCDF result file \(not a classic"),
    "empty": (lambda path: path.write_bytes(b""), "not a netCDF result file"),
}
MIXTURE_DAMAGES = {
    "mixture: nan in phi": (
        _set("phi", (2, 3), np.nan),
        r"output time 2 .* phi = nan is not in \[0, 0\.7405\]",
    ),
    "mixture: phi 2": (
        _set("phi_layer", (1, 0, 2), 2.0),
        r"output time 1 .* phi_layer = 2.0 is not in \[0, 0\.7405\]",
    ),
    "mixture: phi and phi_layer 0.8 in a wet cell": (
        lambda path: (_set("phi_layer", (2, slice(None), 1), 0.8)(path), _set("phi", (2, 1), 0.8)(path)),
        r"output time 2 .* phi = 0.8 is not in \[0, 0\.7405\], the densest packing of spheres",
    ),
    "mixture: pore pressure inf": (
        _set("pore_pressure_excess", (3, 1), np.inf),
        r"output time 3 .* pore_pressure_excess = inf is not finite",
    ),
    "mixture: phi 0.3 in a wet cell": (
        _set("phi", (2, 1), 0.3),
        r"output time 2 .* phi = 0.3 is not the mean of phi_layer over the layers at x index 1",
    ),
    "mixture: phi 0.5 where h is 0": (
        _set("phi", (1, 19), 0.5),
        r"output time 1 .* phi = 0.5 where h is 0 \(no mixture there: 0\) at x index 19",
    ),
}
"""Damages of a grain-fluid mixture's variables (a packing of 0.8, above the densest packing
of spheres, in a layer and its mean, was drawn and exported; the last two are within the
bound, read as the run's answer were they not checked against ``phi_layer`` and ``h``)."""


@pytest.fixture(params=[*DAMAGES, *MIXTURE_DAMAGES])
def damaged(request, tmp_path: Path) -> tuple[Path, str]:
    mixture = request.param in MIXTURE_DAMAGES
    finished = request.getfixturevalue("finished_mixture" if mixture else "finished")
    shutil.copytree(finished, tmp_path, dirs_exist_ok=True)
    damage, message = (MIXTURE_DAMAGES if mixture else DAMAGES)[request.param]
    damage(tmp_path / "out" / "result.nc")
    return tmp_path, message


def test_every_reader_refuses_a_damaged_result_naming_the_file_and_the_damage(damaged, cli):
    directory, message = damaged
    outdir = directory / "out"
    for command in (("plot", outdir), ("export", outdir, "--vtk")):
        result = cli(*command)
        assert result.code == 2, (command, result.err)
        assert "Traceback" not in result.err
        assert __import__("re").search(f"{outdir / 'result.nc'}: .*{message}", result.err), result.err
    for read in (summary, open_result, lambda path: open_result(path, load=False)):
        with pytest.raises(InputError, match=message):
            read(outdir)
    assert __import__("re").search(message, run_failure(outdir) or "")
    fingerprint = sweep.scenario_fingerprint(scenarios.load(directory / "short.yaml"))
    summary_ = dict.fromkeys(SUMMARY_KEYS, 0.0)
    (outdir / sweep.MARKER).write_text(json.dumps({"fingerprint": fingerprint, "summary": summary_}))
    assert sweep.completed(outdir, fingerprint) is None  # a sweep or calibration runs it again
    assert not (outdir / "plots").exists() and not (outdir / "vtk").exists()


def test_resume_of_a_truncated_result_is_exit_2_and_of_a_killed_run_goes_on(finished, tmp_path, cli):
    shutil.copytree(finished, tmp_path, dirs_exist_ok=True)
    outdir, path = tmp_path / "out", tmp_path / "short.yaml"
    longer = yaml.safe_load(path.read_text())
    longer["time"]["end"] = 0.12
    path.write_text(yaml.safe_dump(longer))
    _status("running")(outdir / "result.nc")  # killed: resumable, the records whole
    assert cli("run", path, "-o", outdir, "-q", "--resume").code == 0
    assert open_result(outdir).sizes["time"] == 7
    _truncate(outdir / "result.nc")
    resumed = cli("run", path, "-o", outdir, "-q", "--resume")
    assert resumed.code == 2 and "Traceback" not in resumed.err
    assert "truncated" in resumed.err and "or run without --resume to start afresh" in resumed.err


def test_a_failed_or_interrupted_result_is_shown_with_a_note_and_is_not_an_answer(finished, tmp_path, cli):
    shutil.copytree(finished, tmp_path, dirs_exist_ok=True)
    outdir = tmp_path / "out"
    with netCDF4.Dataset(outdir / "result.nc", "a") as ds:
        ds.run_status = "failed"
        ds.failure = "viscosity() returned nan"
    shown = cli("export", outdir, "--vtk")
    assert shown.code == 0
    assert "the run failed: viscosity() returned nan; exported up to its last output time" in shown.err
    assert "the run did not complete (run_status failed: viscosity() returned nan)" in run_failure(outdir)
    with pytest.raises(InputError, match="accepted: a completed run"):
        summary(outdir)


def _netcdf4_copy(path: Path, cells: int, forged: bool = False) -> None:
    """The fault battery's netCDF-4 copy of a result: ``cells`` cells never written."""
    fault_battery().netcdf4_copy(path, cells, forged=forged)


def test_a_result_larger_than_its_scenario_or_the_memory_is_refused_before_it_is_read(
    finished, tmp_path, cli, monkeypatch
):
    """A netCDF-4 result of 63 kB whose x held 4e9 unwritten cells was a MemoryError
    traceback of ``plot`` (one of 5e8 took 4.6 GB): its dimensions are those of its
    scenario, and a record is checked only in the memory there is."""
    from multilayer.io import result_check

    shutil.copytree(finished, tmp_path, dirs_exist_ok=True)
    path = tmp_path / "out" / "result.nc"
    _netcdf4_copy(path, 10**7)
    assert path.stat().st_size < 10**6
    result = cli("plot", tmp_path / "out")
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        "its dimension x has 10000000 entries, not its scenario attribute's domain.cells (40)" in result.err
    )
    shutil.copy(finished / "out" / "result.nc", path)
    _netcdf4_copy(path, 10**7, forged=True)
    monkeypatch.setattr(result_check.psutil, "virtual_memory", lambda: type("M", (), {"available": 2**30}))
    with pytest.raises(
        InputError, match=r"checking its 10000000 cells x 3 layers takes about 1.56 GiB of memory"
    ):
        result_check.check_result(path)
