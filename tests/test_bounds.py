"""Hostile sizes and degenerate values are refused before anything is built from them
(docs/reliability.md, "bounds"): exit 2 naming the file, the key and the bound, within
seconds, never a MemoryError, a RecursionError or a run that never ends."""

from __future__ import annotations

import math
import os
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO

import multilayer
from multilayer.app import resources
from multilayer.engine.mesh import cell_centres
from multilayer.io.results import load_checkpoint, open_result
from multilayer.scenario import limits, profiles

BILLION_LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(9)
)


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        (BILLION_LAUGHS, r" \(line 7\): more than 2000000 values once its aliases are expanded"),
        ("name: &a [*a]\n", r" \(line 1\): the alias \*a lies inside its own anchor"),
        ("a: &a\n  b: *a\n", r" \(line 2\): the alias \*a lies inside its own anchor"),
        ("x: " + "[" * 5000 + "]" * 5000 + "\n", r" \(line 1\): collections nested more than 100 deep"),
        (
            "# padding\n" * (limits.MAX_YAML_CHARACTERS // 10 + 1),
            r": \d+ characters of YAML; accepted: at most",
        ),
    ],
)
def test_hostile_yaml_is_refused_before_it_is_built(cli, write_scenario, text, expected):
    path = write_scenario(text)
    start = time.process_time()  # CPU: the verdict holds on a loaded machine
    for command in (("validate", path), ("run", path, "-o", path.parent / "out")):
        result = cli(*command)
        assert result.code == 2 and "Traceback" not in result.err
        assert __import__("re").search(__import__("re").escape(str(path)) + expected, result.err), result.err
    assert time.process_time() - start < 30  # the bomb took 29 s and 4 GB before
    result = cli("validate", write_scenario(TINY_SCENARIO, name="tiny.yaml"), "--set", "initial=&a [*a]")
    assert (
        result.code == 2 and "--set initial (line 1): the alias *a lies inside its own anchor" in result.err
    )


def test_a_device_a_pipe_or_an_oversized_file_is_refused(tmp_path, cli, write_scenario, monkeypatch):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)  # opening it to read would wait for a writer for ever
    for path in ("/dev/zero", fifo):
        result = cli("validate", path)
        assert result.code == 2 and f"{path}: not a regular file" in result.err
    bed = write_scenario({**TINY_SCENARIO, "bed": {"file": "/dev/zero"}})
    result = cli("validate", bed)
    assert result.code == 2 and "bed.file" in result.err and "/dev/zero: not a regular file" in result.err
    monkeypatch.setattr("multilayer.scenario.files.MAX_FILE_BYTES", 1000)
    big = write_scenario("# " + "x" * 2000 + "\n", name="big.yaml")
    result = cli("validate", big)
    assert result.code == 2 and f"{big}: longer than 1000 bytes" in result.err


def test_profiles_beyond_their_bound_are_refused_before_they_are_sampled(
    tmp_path, cli, write_scenario, monkeypatch
):
    monkeypatch.setattr(profiles, "MAX_PROFILE_POINTS", 100)
    csv = tmp_path / "bed.csv"
    csv.write_text("x (m), z (m)\n" + "".join(f"{i / 1000}, 0\n" for i in range(101)))
    result = cli("validate", write_scenario({**TINY_SCENARIO, "bed": {"file": str(csv)}}))
    assert result.code == 2 and "101 data rows; accepted: at most 100" in result.err
    monkeypatch.undo()
    dem = {"dem": "dem.tif", "polyline": [[0.0, 0.0], [1e9, 0.0]], "spacing": 1e-3}
    start = time.process_time()  # CPU: the verdict holds on a loaded machine
    result = cli("validate", write_scenario({**TINY_SCENARIO, "bed": dem}))
    assert result.code == 2 and "Traceback" not in result.err
    assert "bed.spacing: sampling the polyline (1e+09 m) every 0.001 m takes 1e+12 points" in result.err
    assert time.process_time() - start < 10  # 46 s to a MemoryError before


def test_a_long_bed_profile_is_resampled_to_the_mesh_once(tmp_path, cli, write_scenario):
    """2e4 rows for 40 cells: the bed the engine sees is the same (the profile sampled at the
    cell centres, where the engine samples it), the record the size of the mesh (a file of
    1e5 rows made a checkpoint of 12 MB and the run 24 times slower)."""
    x = np.linspace(-0.1, 0.6, 20_000)
    csv = tmp_path / "bed.csv"
    csv.write_text("x (m), z (m)\n" + "".join(f"{a!r}, {0.01 * math.sin(20 * a)!r}\n" for a in x.tolist()))
    path = write_scenario({**TINY_SCENARIO, "bed": {"file": "bed.csv"}})
    scenario = multilayer.load(path)
    assert len(scenario.bed.points) == 42
    run = cli("run", path, "-o", tmp_path / "out", "-q")
    assert run.code == 0, run.err
    dom = scenario.domain
    expected = np.interp(cell_centres(dom.x_min, dom.x_max, dom.cells), x, 0.01 * np.sin(20 * x))
    np.testing.assert_array_equal(open_result(tmp_path / "out")["bed"].values, expected)
    assert (tmp_path / "out" / "checkpoint.npz").stat().st_size < 50_000
    assert len(load_checkpoint(tmp_path / "out" / "checkpoint.npz").scenario) < 10_000


@pytest.mark.parametrize("override", ["gravity=1e300", "time.cfl=1e-300", "domain.x_max=1e-300"])
def test_a_run_that_cannot_finish_is_refused_naming_the_keys_unless_the_user_says_so(
    tmp_path, cli, write_scenario, override
):
    layer = {**TINY_SCENARIO, "initial": [{"shape": "layer", "thickness": 0.01}]}
    path = write_scenario(layer)
    grains = ["--set", "material.grain_diameter=1e-301"] if "x_max" in override else []  # within the domain
    for command in (("validate", path), ("run", path, "-o", tmp_path / "out")):
        result = cli(*command, "--set", override, *grains)
        assert result.code == 2 and "Traceback" not in result.err
        assert "time.end, time.cfl, domain.x_min, domain.x_max, domain.cells, gravity: about" in result.err
        assert "more than the default bound (--max-steps) (1e+07)" in result.err
    assert not (tmp_path / "out" / "result.nc").exists()


def test_validate_prints_the_steps_and_a_run_stops_at_its_bound_resumably(
    tmp_path, cli, write_scenario, monkeypatch
):
    path = write_scenario({**TINY_SCENARIO, "time": {"end": 0.2, "output_interval": 0.05}})
    checked = cli("validate", path, "--max-steps", "1000")
    assert checked.code == 0
    assert __import__("re").search(r"about \d\d time steps \(--max-steps 1e\+03\)\)", checked.out), (
        checked.out
    )
    monkeypatch.setattr(resources, "steps", lambda scenario: resources.Steps(5.0, 1.0, 0.01, 0.01))
    stopped = cli("run", path, "-o", tmp_path / "out", "-q", "--max-steps", "10")
    assert stopped.code == 1 and "Traceback" not in stopped.err
    assert "the run has taken 10 time steps, its bound (--max-steps, default 10000000)" in stopped.err
    assert "--resume --max-steps 20" in stopped.err
    resumed = cli("run", path, "-o", tmp_path / "out", "-q", "--resume", "--max-steps", "1000")
    assert resumed.code == 0, resumed.err
    assert open_result(tmp_path / "out").attrs["run_status"] == "completed"


def test_the_memory_estimate_is_that_of_the_model_and_bounds_its_peak(cli, write_scenario):
    """10^6 columns of 10 layers need about 2 GB (peak resident memory of a run, measured:
    benchmarks/memory_estimate.py) and were refused at 24.4 GB, 2.6 kB per cell of every
    model, on a machine of 22 GB available.  The estimate is per column and per cell of
    the model: the hydrostatic one fits under 4 GB; the other pressure models, the normal
    stress and a mixture hold more arrays per cell and are estimated above it."""
    domain = {"x_min": 0.0, "x_max": 500.0, "cells": 1_000_000, "layers": 10}
    result = cli("validate", write_scenario({**TINY_SCENARIO, "domain": domain}), "--max-memory", "4G")
    assert result.code == 0, result.err
    hydrostatic = resources.estimate(multilayer.load({**TINY_SCENARIO, "domain": domain})).memory
    assert 2.0 * 2**30 < hydrostatic < 3.0 * 2**30
    for model in ({"pressure": "bim2016"}, {"pressure": "non_hydrostatic"}, {"normal_stress": True}):
        other = multilayer.load({**TINY_SCENARIO, "domain": domain, "model": model})
        assert resources.estimate(other).memory > hydrostatic


@pytest.mark.slow
def test_the_memory_estimate_bounds_the_peak_of_a_run_within_three_times_it():
    """Three steps of a layer flowing on 2 x 10^5 columns of 10 layers, hydrostatic and
    non-hydrostatic on every layer: the estimate is above the peak resident memory of the
    process and below three times it (the benchmark's cases, benchmarks/memory_estimate.py)."""
    import subprocess
    import sys

    sys.path.insert(0, str(Path(__file__).parents[1] / "benchmarks"))
    import memory_estimate

    for name in ("hydrostatic", "non_hydrostatic (every layer)"):
        text = __import__("json").dumps(memory_estimate.scenario(200_000, 10, memory_estimate.MODELS[name]))
        done = subprocess.run(
            [sys.executable, "-c", memory_estimate.CHILD, text], capture_output=True, text=True, check=True
        )
        estimate, peak = (float(v) for v in done.stdout.split())
        assert peak < estimate < 3.0 * peak, (name, estimate, peak)


def test_memory_quadratic_in_the_layers_is_counted(cli, write_scenario):
    """20 000 layers x 2 cells: the exact column solve keeps the messages of every layer,
    128 L^2 bytes per thread (51 GB): it validated at 299 MB and failed to allocate."""
    path = write_scenario(
        {**TINY_SCENARIO, "domain": {"x_min": 0.0, "x_max": 0.5, "cells": 2, "layers": 20000}}
    )
    result = cli("validate", path, "--max-memory", "8G")
    assert result.code == 2
    assert __import__("re").search(r"2 cells x 20000 layers need about \d+(\.\d)? GB of memory", result.err)


def test_initial_entries_beyond_their_bound_are_refused_and_built_in_the_memory_of_the_mesh(
    cli, write_scenario, monkeypatch
):
    """30 000 ``initial`` entries on 10^5 cells validated (about 944 MB) and the process was
    killed for lack of memory building them (every entry's thickness kept at once: 24 GB).
    More than ``limits.MAX_INITIAL_ENTRIES`` are refused; the thicknesses are summed one
    entry at a time (the peak is that of the mesh: ten entries hold no more than one)."""
    import tracemalloc

    from multilayer.engine import initial_state

    entry = {"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 1e-4}
    result = cli("validate", write_scenario({**TINY_SCENARIO, "initial": [entry] * 1001}))
    assert result.code == 2
    assert "initial (line 15): List should have at most 1000 items after validation, not 1001" in result.err
    assert "accepted: a list of at most 1000 {shape, ...}" in result.err
    peaks = []
    for count in (1, 10):
        domain = {"x_min": 0.0, "x_max": 0.5, "cells": 20000}
        scenario = multilayer.load({**TINY_SCENARIO, "domain": domain, "initial": [entry] * count})
        edges = np.linspace(0.0, 0.5, 20001)
        x, sigma = 0.5 * (edges[1:] + edges[:-1]), np.array([0.5])
        tracemalloc.start()
        h, _ = initial_state.initial_state(scenario.initial, x, sigma, edges)
        peaks.append(tracemalloc.get_traced_memory()[1])
        tracemalloc.stop()
        assert h.max() == pytest.approx(count * 1e-4)
    assert peaks[1] < 1.2 * peaks[0]


def _sweep(tmp_path: Path, parameters: dict, paired: bool = False) -> Path:
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": "base.yaml", "parameters": parameters, "zip": paired}))
    return path


@pytest.mark.parametrize(
    ("parameters", "paired", "expected"),
    [
        (
            {f"k{i}": list(range(10)) for i in range(12)},
            False,
            "parameters (line 2): 1000000000000 members (10 x 10 x",
        ),
        (
            {"rheology.mu_s": [0.4, 0.3, 0.40]},
            False,
            "parameters.rheology.mu_s (line 3): entries 0 and 2 give the same member (0.4)",
        ),
        (
            {"rheology.mu_s": [0.3, 0.3], "rheology.nu": [0.01, 0.01]},
            True,
            "zip (line 9): entries 0 and 1 give the same member (0.3, 0.01)",
        ),
        (
            {"slope_deg": [20, 21, 20.0]},
            False,
            "parameters.slope_deg (line 3): entries 0 and 2 give the same member",
        ),
        (
            {
                "rheology": [
                    {"name": "drucker_prager", "mu_s": 1, "nu": 0},
                    {"name": "drucker_prager", "mu_s": 1.0, "nu": 0.0},
                ]
            },
            False,
            "parameters.rheology (line 3): entries 0 and 1 give the same member",
        ),
    ],
)
def test_a_sweep_too_large_or_with_equal_members_is_refused(tmp_path, cli, parameters, paired, expected):
    start = time.process_time()  # CPU: the verdict holds on a loaded machine
    result = cli("sweep", _sweep(tmp_path, parameters, paired), "-o", tmp_path / "out")
    assert result.code == 2 and "Traceback" not in result.err
    assert expected in result.err, result.err
    assert time.process_time() - start < 10


def test_a_sweep_beyond_the_members_validate_checks_in_seconds_is_refused_at_once(tmp_path, cli):
    """``validate`` checks every member as ``sweep`` builds it (about 2 ms of CPU each for
    the tiny scenario): 10^5 members ground through minutes (about 12 ms each, the base
    file read and the scenario written out as YAML twice per member).  The bound is 10^4
    members; beyond it the file is refused before any member is built."""
    from multilayer.app.sweep import MAX_MEMBERS

    assert MAX_MEMBERS == 10_000
    path = _sweep(
        tmp_path,
        {
            "slope_deg": [20 + i / 1000 for i in range(101)],
            "rheology.mu_s": [0.3 + i / 1e4 for i in range(100)],
        },
    )
    start = time.process_time()
    result = cli("validate", path)
    assert result.code == 2 and "Traceback" not in result.err
    assert "parameters (line 2): 10100 members (100 x 101); accepted: at most 10000 members" in result.err
    assert time.process_time() - start < 1


def test_a_sweep_reads_its_base_file_once_for_all_members(tmp_path, cli, monkeypatch):
    """Each member is the base scenario with its values applied: the base file is read a
    fixed number of times (the sweep's own check, then once for the members), not once
    per member."""
    from multilayer.scenario import source

    reads: list[str] = []
    read_text = source.read_text
    monkeypatch.setattr(source, "read_text", lambda path, *args: reads.append(path) or read_text(path, *args))
    counts = []
    for size in (2, 40):
        reads.clear()
        result = cli("validate", _sweep(tmp_path, {"slope_deg": [20 + i / 10 for i in range(size)]}))
        assert result.code == 0 and f"sweep of {size} members" in result.out, result.err
        counts.append(len(reads))
    assert counts[0] == counts[1] <= 4


def test_a_sweep_pairing_a_repeated_value_with_distinct_ones_is_valid(tmp_path):
    from multilayer.app import sweep

    plan = sweep.load(_sweep(tmp_path, {"rheology.mu_s": [0.3, 0.3], "rheology.nu": [0.01, 0.02]}, True))
    assert len(plan.members()) == 2


def test_plot_bounds_its_figures(cli, tmp_path):
    result = cli("plot", tmp_path, "--times", "1000")
    assert result.code == 2 and "--times 1000: accepted: 1 to 12 times" in result.err


def _calibration(tmp_path: Path, times: str, end: float = 0.2, **search) -> Path:
    base = {**TINY_SCENARIO, "time": {"end": end, "output_interval": end}}
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(base))
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n" + times)
    path = tmp_path / "calibration.yaml"
    config = {
        "base": "base.yaml",
        "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
        "observations": [
            {"name": "front", "quantity": "front", "file": "front.csv", "columns": ["t", "x_f", "sigma"]}
        ],
        "search": {"population": 4, "generations": 1, **search},
    }
    path.write_text(yaml.safe_dump(config))
    return path


def test_calibration_observations_outside_the_run_are_exit_2(tmp_path, cli):
    result = cli("calibrate", _calibration(tmp_path, "5,0.2,0.01\n9,0.3,0.01\n"), "-o", tmp_path / "out")
    assert result.code == 2 and "Traceback" not in result.err
    assert "): observed at t = 5 to 9 s, outside the runs, which end at time.end = 0.2 s" in (result.err)
    population = cli(
        "calibrate", _calibration(tmp_path, "0.1,0.2,0.01\n", population=10**12), "-o", tmp_path / "o"
    )
    assert population.code == 2 and "search.population" in population.err


def test_an_observation_just_past_the_end_is_said_to_the_digits_that_place_it(tmp_path, cli):
    """A time 1e-10 s past ``time.end`` was said "observed at t = 0.2 to 0.2 s, outside the
    runs, which end at time.end = 0.2 s": each time is written to its last digit where two
    would read alike at 6 digits."""
    result = cli("validate", _calibration(tmp_path, "0.2000000001,0.12,0.01\n"))
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        "observed at t = 0.2000000001 to 0.2000000001 s, outside the runs, which end at time.end = 0.2 s"
        in result.err
    ), result.err


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        (
            "domain.cells=1" + "0" * 400,
            "domain.cells (from --set): Input should be less than or equal to 1000000000",
        ),
        (
            "domain.layers=1" + "0" * 400,
            "domain.layers (from --set): Input should be less than or equal to 100000",
        ),
        (
            "time.output_interval=1e-320",
            "time.output_interval (from --set): inf output times to time.end = 0.05 s",
        ),
        (
            "time.end=1e308",
            "): inf output times to time.end = 1e+308 s; accepted: at most 10000000 output times",
        ),
        ("domain.x_min=-1e308", "narrower than one cell (dx = 2.5e+306 m)"),
    ],
)
def test_numbers_too_large_for_the_estimates_are_exit_2(cli, write_scenario, override, expected):
    """Integers past the range of a float and ratios that overflow to infinity reached the
    estimates as OverflowError tracebacks."""
    result = cli("validate", write_scenario(TINY_SCENARIO), "--set", override)
    assert result.code == 2 and "Traceback" not in result.err
    assert expected in result.err, result.err


def test_api_overrides_that_are_no_scenario_value_are_input_errors():
    from multilayer.errors import InputError

    for value in (object(), float("nan"), {1, 2}):
        with pytest.raises(InputError, match=r"overrides: time.end: .* is not a value of a scenario"):
            multilayer.load(TINY_SCENARIO, overrides={"time.end": value})


@pytest.mark.parametrize("content", [b"CDF\x02garbage", b"\x89HDF\r\n\x1a\ngarbage", b""])
def test_a_damaged_study_file_is_exit_2_when_plotted(tmp_path, cli, content):
    (tmp_path / "sensitivity.nc").write_bytes(content)
    result = cli("plot", tmp_path)
    assert result.code == 2 and "Traceback" not in result.err
    assert f"{tmp_path / 'sensitivity.nc'}: not a" in result.err


def _sensitivity_file(path, s1, dims=("output", "parameter"), **attrs):
    """A sensitivity.nc of one output and two parameters whose S1 is ``s1`` over ``dims``."""
    import xarray as xr

    both, good = ("output", "parameter"), np.array([[0.5, 0.3]])
    indices = {"S1": (dims, s1), **{name: (both, good) for name in ("S1_conf", "ST", "ST_conf")}}
    coords = {"output": ["runout"], "parameter": ["mu_s", "nu"]}
    attrs = {"confidence_level": 0.95, "base_samples": 64, **attrs}
    xr.Dataset(indices, coords=coords, attrs=attrs).to_netcdf(path)


@pytest.mark.parametrize(
    ("attrs", "phrase"),
    [
        ({"failed_runs": "abc"}, "its attribute failed_runs is 'abc', not a count"),
        ({"runs_not_done": np.nan}, "its attribute runs_not_done is nan, not a count"),
        ({"confidence_level": "abc"}, "its attribute confidence_level is 'abc', not in (0, 1)"),
        ({"base_samples": 1e300}, "its attribute base_samples is 1e+300, not a count"),
    ],
)
def test_a_study_file_whose_attributes_the_figure_computes_with_are_damaged_is_exit_2(
    tmp_path, cli, attrs, phrase
):
    """``int()`` and ``float()`` of them were a ValueError traceback of plot (exit 1), and a
    count of 1e300 was printed with its 301 digits in the figure's note."""
    _sensitivity_file(tmp_path / "sensitivity.nc", np.array([[np.nan, 0.3]]), **attrs)
    result = cli("plot", tmp_path)
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        f"{tmp_path / 'sensitivity.nc'}: {phrase}; accepted: the file that multilayer sensitivity"
        in result.err
    )


def test_a_study_file_declaring_more_than_it_can_hold_is_refused_before_it_is_read(tmp_path, cli):
    """A netCDF-4 sensitivity.nc of 8 kB declaring 4e9 outputs, never written, was a
    MemoryError traceback of plot: xarray reads a dimension's coordinate at its opening."""
    import netCDF4

    with netCDF4.Dataset(tmp_path / "sensitivity.nc", "w", format="NETCDF4") as ds:
        ds.createDimension("output", 4 * 10**9)
        ds.createDimension("parameter", 2)
        for name in ("output", "S1", "S1_conf", "ST", "ST_conf"):
            dims = ("output",) if name == "output" else ("output", "parameter")
            ds.createVariable(name, "f8", dims, zlib=True, chunksizes=(2**20,) + (1,) * (len(dims) - 1))
        ds.confidence_level, ds.base_samples = 0.95, 8
    result = cli("plot", tmp_path)
    assert result.code == 2 and "Traceback" not in result.err
    assert "sensitivity.nc: its variables hold 288000000000 bytes; accepted: a file written by" in result.err


@pytest.mark.parametrize(
    ("s1", "dims", "phrase"),
    [
        (np.array([0.5, 0.3]), ("parameter",), "S1 over ('parameter',), where over ('output', 'parameter')"),
        (np.array([[np.inf, 0.3]]), ("output", "parameter"), "S1 holds infinite values, where numbers"),
        (np.array([[1, 0]]), ("output", "parameter"), "S1 holds values of type int64"),
    ],
)
def test_a_study_file_whose_indices_are_not_as_written_is_exit_2(tmp_path, cli, s1, dims, phrase):
    """Indices over other dimensions than the study writes were drawn (exit 0), infinite
    ones drawn with numpy's "invalid value encountered in dot"; xarray's message for a file
    that is not netCDF ran on for three lines with links."""
    _sensitivity_file(tmp_path / "sensitivity.nc", s1, dims)
    result = cli("plot", tmp_path)
    assert result.code == 2 and "warning" not in result.err, result.err
    assert f"{tmp_path / 'sensitivity.nc'}: {phrase}" in result.err
    (tmp_path / "sensitivity.nc").write_bytes(b"garbage")
    result = cli("plot", tmp_path)
    assert result.code == 2 and len(result.err.strip().splitlines()) == 1, result.err


def test_sobol_indices_that_are_not_numbers_are_said_when_plotted(tmp_path, cli):
    """S1 NaN (runs that failed, an output that does not vary): an empty panel, exit 0,
    nothing said, as if the figure showed indices of 0."""
    _sensitivity_file(tmp_path / "sensitivity.nc", np.array([[np.nan, 0.3]]))
    result = cli("plot", tmp_path)
    assert result.code == 0 and (tmp_path / "plots" / "sobol.png").is_file()
    assert (
        f"warning: {tmp_path / 'sensitivity.nc'}: no Sobol' indices of runout (the output does not vary over "
        "the samples): the figure shows none"
    ) in result.err


def _calibration_file(path, **damage):
    """A calibration.nc of two parameters, three parameter sets (the last failed) and two
    observed points, with the variables of ``damage`` replaced."""
    import xarray as xr

    variables = {
        "best": ("parameter", [0.4, 0.01]),
        "covariance": (("parameter", "parameter2"), [[1e-4, 0.0], [0.0, 1e-6]]),
        "values": (("candidate", "parameter"), [[0.4, 0.01], [0.5, 0.02], [0.45, 0.03]]),
        "misfit": ("candidate", [1.5, 4.0, np.inf]),
        "stage": ("candidate", np.array(["search", "search", "refine"], dtype=object)),
        "observation": ("point", np.array(["front", "front"], dtype=object)),
        "quantity": ("point", np.array(["front", "front"], dtype=object)),
        "coordinate": ("point", [0.1, 0.2]),
        "observed": ("point", [0.2, 0.3]),
        "observed_sd": ("point", [0.01, 0.01]),
        "fitted": ("point", [0.21, 0.29]),
    }
    variables.update({name: (variables[name][0], value) for name, value in damage.items()})
    coords = {"parameter": ["mu_s", "nu"], "parameter2": ["mu_s", "nu"]}
    xr.Dataset(variables, coords=coords).to_netcdf(path)


@pytest.mark.parametrize(
    ("damage", "phrase"),
    [
        (
            {"covariance": [[np.nan, 0.0], [0.0, 1e-6]]},
            "covariance holds nan, where finite numbers, or nan throughout",
        ),
        ({"covariance": [[np.inf, 0.0], [0.0, 1e-6]]}, "covariance holds inf, where finite numbers, or nan"),
        ({"best": [np.nan, 0.01]}, "best holds nan, where finite numbers, or nan throughout"),
        ({"values": [[0.4, 0.01], [np.inf, 0.02], [0.45, 0.03]]}, "values holds inf, where finite numbers"),
        ({"observed_sd": [np.nan, 0.01]}, "observed_sd holds nan, where finite numbers > 0"),
        ({"observed_sd": [0.0, 0.01]}, "observed_sd holds 0, where finite numbers > 0"),
        ({"fitted": [np.inf, 0.29]}, "fitted holds inf, where finite numbers, or nan throughout"),
        (
            {"misfit": [np.nan, np.nan, np.nan]},
            "misfit holds nan, where numbers >= 0, inf where a run failed",
        ),
        ({"misfit": [1.5, -4.0, np.inf]}, "misfit holds -4, where numbers >= 0"),
    ],
)
def test_a_calibration_file_whose_values_are_damaged_is_exit_2_when_plotted(tmp_path, cli, damage, phrase):
    """NaN or infinite covariances, fits, parameter values, standard deviations or misfits,
    which no calibration writes, were drawn as a fit (exit 0; all misfits NaN with numpy's
    "All-NaN slice encountered")."""
    _calibration_file(tmp_path / "calibration.nc", **damage)
    result = cli("plot", tmp_path)
    assert result.code == 2 and "Traceback" not in result.err and "Warning" not in result.err, result.err
    assert f"{tmp_path / 'calibration.nc'}: {phrase}" in result.err, result.err


def test_a_calibration_whose_runs_all_failed_so_far_is_plotted_without_warnings(tmp_path, cli):
    """What a calibration writes after a batch whose runs all failed: misfits inf, no
    prediction (fitted nan), no covariance (nan); drawn, exit 0, nothing from numpy."""
    nan2 = [np.nan, np.nan]
    _calibration_file(tmp_path / "calibration.nc", misfit=[np.inf] * 3, fitted=nan2, covariance=[nan2, nan2])
    result = cli("plot", tmp_path)
    assert result.code == 0 and "Warning" not in result.err, result.err
    assert (tmp_path / "plots" / "misfit.png").is_file()


def test_a_member_marker_that_is_no_marker_means_run_again(tmp_path):
    from multilayer.app import sweep

    (tmp_path / "result.nc").write_bytes(b"")
    for marker in ("[1, 2]", '{"fingerprint": "x"}', '{"fingerprint": "x", "summary": 3}', "{" * 5000):
        (tmp_path / sweep.MARKER).write_text(marker)
        assert sweep.completed(tmp_path, "x") is None


@pytest.mark.slow  # 1-3 s of a child process or a large input, no physics
def test_a_mesh_that_does_not_fit_in_memory_under_force_is_named_not_a_traceback(
    tmp_path, cli, write_scenario
):
    """``--force`` skips the memory estimate; a mesh that then does not fit was a numpy
    ``MemoryError`` traceback while the simulation was built.  Under an address-space limit
    of 1 GiB above what the process holds, 10^8 cells (2.2 GiB for one array): exit 2
    naming the keys, numpy's words and the estimate, no result left."""
    import resource

    import psutil

    path = write_scenario({**TINY_SCENARIO, "domain": {**TINY_SCENARIO["domain"], "cells": 10**8}})
    limit = psutil.Process().memory_info().vms + 2**30
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        result = cli("run", path, "-o", tmp_path / "out", "--force", "-q")
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    assert result.code == 2 and "Traceback" not in result.err
    assert (
        "domain.cells, domain.layers: 100000000 cells x 3 layers do not fit in memory (Unable to allocate"
        in (result.err)
    )
    assert "the estimate is about 110 GB); accepted: fewer cells or layers" in result.err
    assert not (tmp_path / "out" / "result.nc").exists()


@pytest.mark.slow
def test_a_directory_of_a_run_and_a_study_or_a_studys_with_a_runs_options_is_exit_2(
    tmp_path, cli, write_scenario
):
    """``plot`` of a directory holding result.nc and sensitivity.nc drew the study's figures
    only, exit 0; a study's directory with ``--format svg`` or ``--animate`` drew png
    figures and no animation, exit 0."""
    assert cli("run", write_scenario(TINY_SCENARIO), "-o", tmp_path / "run", "-q").code == 0
    _sensitivity_file(tmp_path / "run" / "sensitivity.nc", np.array([[0.5, 0.3]]))
    both = cli("plot", tmp_path / "run")
    assert both.code == 2 and "Traceback" not in both.err and not (tmp_path / "run" / "plots").exists()
    assert "holds result.nc (a run) and sensitivity.nc (a study): which one to draw is not known" in both.err
    study = tmp_path / "study"
    study.mkdir()
    _sensitivity_file(study / "sensitivity.nc", np.array([[0.5, 0.3]]))
    for options, named in (
        (["--format", "svg"], "--format"),
        (["--animate"], "--animate"),
        (["--times", "4", "--at", "0.1"], "--times, --at"),
        (["--xlim", "0", "1"], "--xlim"),
    ):
        result = cli("plot", study, *options)
        assert (
            result.code == 2 and f"sensitivity.nc is a study's file; {named} apply to a run's" in result.err
        )
    assert cli("plot", study).code == 0
    (tmp_path / "run" / "sensitivity.nc").unlink()
    assert cli("plot", tmp_path / "run", "--format", "svg", "--times", "2").code == 0  # a run's options
