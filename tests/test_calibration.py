"""Calibration and sensitivity (docs/calibration.md): study files, observables, a twin
experiment, failing runs, resume, Dask clusters, Sobol' indices.

The twin experiment calibrates mu_s and mu_2 of a tiny column collapse
(studies/twin/collapse.yaml: 30 cells x 2 layers, 0.4 s, a fraction of a second per run)
against its own front x_f(t) and deposit h(x), computed with mu_s = 0.4770 and
mu_2 = 0.7265 and perturbed by Gaussian noise: the fit must recover the true values
within three of its reported standard deviations, and those must shrink in proportion to
the noise.
"""

from __future__ import annotations

import importlib.util
import math
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import xarray as xr

from multilayer.app import calibration, cli, runner
from multilayer.app.sensitivity import indices
from multilayer.errors import InputError, RunError
from multilayer.io import observables, study

ROOT = Path(__file__).resolve().parents[1]
TWIN = ROOT / "studies" / "twin"
TRUE = np.array([0.4770, 0.7265])  # mu_s, mu_2 of collapse.yaml

spec = importlib.util.spec_from_file_location("make_observations", TWIN / "make_observations.py")
make_observations = importlib.util.module_from_spec(spec)
spec.loader.exec_module(make_observations)


def twin_study(directory: Path, noise_mm: float, search: str, refine: str, seed: int = 1) -> Path:
    """The twin calibration file in ``directory`` with observations of noise ``noise_mm``."""
    shutil.copy(TWIN / "collapse.yaml", directory)
    make_observations.write(noise_mm, seed, directory)
    text = (TWIN / "calibration.yaml").read_text()
    text = text.replace("search: {population: 4, generations: 2, seed: 1}", f"search: {search}")
    text = text.replace("refine: {evaluations: 8}", f"refine: {refine}")
    path = directory / "calibration.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def cluster():
    """A Dask cluster of one worker thread in this process (patched functions reach it)."""
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as local:
        yield local.scheduler_address


def calibrate(path: Path, outdir: Path, scheduler: str, capsys) -> tuple[int, xr.Dataset, str]:
    code = cli.main(["calibrate", str(path), "-o", str(outdir), "--scheduler", scheduler])
    out = capsys.readouterr().out
    ds = xr.load_dataset(outdir / calibration.CALIBRATION_FILE) if code == 0 else None
    return code, ds, out


# --------------------------------------------------------------------- twin experiment


@pytest.mark.slow
def test_twin_experiment_recovers_mu_s_and_mu_2_within_their_uncertainty(tmp_path, cluster, capsys):
    """Noise 1 mm: the fit lies within 3 standard deviations of the truth and its misfit
    is a plausible chi-square value for the 16 - 2 degrees of freedom."""
    path = twin_study(tmp_path, 1.0, "{population: 4, generations: 0, seed: 1}", "{evaluations: 4}")
    code, ds, out = calibrate(path, tmp_path / "out", cluster, capsys)
    assert code == 0, out
    assert "rheology.mu_s = " in out and "+/-" in out
    best, sd = ds["best"].values, ds["sd"].values
    z = (best - TRUE) / sd
    assert np.all(np.abs(z) < 3), f"best {best}, sd {sd}, z {z}"
    assert ds.attrs["misfit"] < ds.attrs["degrees_of_freedom"] + 4 * math.sqrt(2 * ds.attrs["points"])
    assert (ds["status"].values == "ok").all()
    assert np.all(np.abs(ds["fitted"].values - ds["observed"].values) < 4 * ds["observed_sd"].values)


@pytest.mark.slow
def test_twin_experiment_uncertainty_shrinks_with_the_noise(tmp_path, cluster, capsys):
    """The shipped twin calibration at noise 1 mm and 0.25 mm (the same normal deviates,
    scaled): both fits lie within 3 standard deviations of the truth, and the deviations
    shrink with the noise: fourfold for a model linear in the parameters over the
    deviations (measured: 4.0 for both, docs/calibration.md)."""
    fits = []
    for noise in (1.0, 0.25):
        directory = tmp_path / f"noise{noise}"
        directory.mkdir()
        path = twin_study(directory, noise, "{population: 4, generations: 2, seed: 1}", "{evaluations: 8}")
        code, ds, out = calibrate(path, directory / "out", cluster, capsys)
        assert code == 0, out
        best, sd = ds["best"].values, ds["sd"].values
        z = (best - TRUE) / sd
        assert np.all(np.abs(z) < 3), f"noise {noise} mm: best {best}, sd {sd}, z {z}"
        fits.append(sd)
    ratio = fits[0] / fits[1]
    assert np.all((ratio > 3) & (ratio < 5)), ratio


# --------------------------------------------------------------------- failures, resume


@pytest.mark.slow
def test_failing_runs_are_counted_and_the_calibration_continues(tmp_path, cluster, monkeypatch, capsys):
    """Every run with mu_s > 0.55 fails (RunError): those parameter sets get misfit inf,
    status failed and the error, and the fit is still found."""
    real_run = runner.run

    def flaky_run(member, outdir, **options):
        if member.rheology.params["mu_s"] > 0.55:
            raise RunError("the solver broke down")
        return real_run(member, outdir, **options)

    monkeypatch.setattr(runner, "run", flaky_run)
    path = twin_study(tmp_path, 1.0, "{population: 4, generations: 0, seed: 1}", "{evaluations: 2}")
    code, ds, out = calibrate(path, tmp_path / "out", cluster, capsys)
    assert code == 0, out
    failed = ds["status"].values == "failed"
    assert failed.any() and ds.attrs["failed_parameter_sets"] == failed.sum()
    assert np.isinf(ds["misfit"].values[failed]).all()
    assert all("RunError: the solver broke down" in e for e in ds["error"].values[failed])
    assert (ds["values"].values[failed, 0] > 0.55).all()
    assert np.isfinite(ds["sd"].values).all() and ds["best"].values[0] < 0.55
    assert cli.main(["plot", str(tmp_path / "out")]) == 0  # failed sets are drawn as crosses
    assert {p.name for p in (tmp_path / "out" / "plots").iterdir()} == {"misfit.png", "pairs.png", "fit.png"}


@pytest.mark.slow
def test_interrupted_calibration_resumes_from_its_completed_runs(tmp_path, cluster, capsys):
    """A rerun reuses every completed run (none is repeated) and gives the same fit; runs
    whose completion marker is missing (interrupted) run again and nothing else."""
    path = twin_study(tmp_path, 1.0, "{population: 4, generations: 0, seed: 1}", "{evaluations: 0}")
    outdir = tmp_path / "out"
    code, first, out = calibrate(path, outdir, cluster, capsys)
    assert code == 0, out
    members = sorted((outdir / "members").iterdir())
    for member in members[:3]:  # as if the study had stopped before these completed
        (member / "member.json").unlink()

    code, second, out = calibrate(path, outdir, cluster, capsys)
    assert code == 0, out
    assert second.attrs["runs"] == 3
    np.testing.assert_array_equal(second["values"].values, first["values"].values)
    np.testing.assert_array_equal(second["best"].values, first["best"].values)
    assert "calibrate: search 0: 8 parameter set(s), " in out

    code, third, _ = calibrate(path, outdir, cluster, capsys)
    assert third.attrs["runs"] == 0 and third.attrs["reused_runs"] == second.attrs["reused_runs"] + 3


@pytest.mark.slow
def test_calibration_on_a_local_cluster_of_worker_processes(tmp_path, monkeypatch, capsys):
    """Without --scheduler: a local Dask cluster of two worker processes."""
    path = twin_study(tmp_path, 1.0, "{population: 4, generations: 0, seed: 1}", "{evaluations: 0}")
    assert cli.main(["calibrate", str(path), "-o", str(tmp_path / "out"), "--workers", "2"]) == 0
    out = capsys.readouterr().out
    assert "on a local Dask cluster of 2 single-threaded worker process(es)" in out
    ds = xr.load_dataset(tmp_path / "out" / calibration.CALIBRATION_FILE)
    assert ds.sizes["candidate"] == 8 + 4  # the initial population and the central differences
    assert (ds["status"].values == "ok").all()


# --------------------------------------------------------------------- study files


@pytest.mark.parametrize(
    ("edit", "key", "what"),
    [
        (("search: {population", "serch: {population"), "serch (line 11)", "unknown key"),
        (("bounds: [0.35, 0.60]", "bounds: [0.60, 0.35]"), "parameters.rheology.mu_s.bounds (line 6)", "got"),
        (  # every point lower + fraction * width: the width overflowed, the corners were NaN
            ("bounds: [0.35, 0.60]", "bounds: [-1e308, 1e308]"),
            "parameters.rheology.mu_s.bounds (line 6)",
            "got [-1e+308, 1e+308]: the width upper - lower overflows",
        ),
        (("rheology.mu_2: {", "rheology.mu_3: {"), "parameters.rheology.mu_3 (line 7)", "invalid"),
        (
            ("units: mm}\n  - {name: deposit", "units: inch}\n  - {name: deposit"),
            "observations.0.units",
            "inch",
        ),
        (("columns: [t, x_f, sigma]", "columns: [t, xf, sigma]"), "observations.0.file (line 9)", "xf"),
        (("quantity: front,", "quantity: front_x,"), "observations.0.quantity (line 9)", "got 'front_x'"),
        (("file: front.csv", "file: nowhere.csv"), "observations.0.file", "not found"),
        (("file: front.csv", "file: front.csv/"), "observations.0.file", "front.csv/: a path ending in '/'"),
        (("base: collapse.yaml", "base: collapse.yaml/."), "base", "collapse.yaml/.: a path ending in '/.'"),
    ],
)
def test_bad_calibration_file_exits_2_naming_the_key(tmp_path, capsys, edit, key, what):
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    for name in ("front.csv", "deposit.csv"):
        shutil.copy(TWIN / name, tmp_path)
    text = (TWIN / "calibration.yaml").read_text()
    assert edit[0] in text
    (tmp_path / "c.yaml").write_text(text.replace(edit[0], edit[1], 1))
    assert cli.main(["calibrate", str(tmp_path / "c.yaml")]) == 2
    err = capsys.readouterr().err
    assert f"c.yaml: {key}" in err and what in err, err
    assert "Traceback" not in err


def test_scalar_observation_needs_an_uncertainty_and_experiment_names_are_checked(tmp_path, capsys):
    (tmp_path / "s.yaml").write_text((TWIN / "collapse.yaml").read_text())
    (tmp_path / "c.yaml").write_text(
        "base: s.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\n"
        "observations:\n  - {name: r, quantity: runout, value: 9.0, units: cm}\n"
    )
    assert cli.main(["calibrate", str(tmp_path / "c.yaml")]) == 2
    assert "observations.0.sigma (line 4): quantity runout requires sigma" in capsys.readouterr().err
    (tmp_path / "c.yaml").write_text(
        "base: s.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\nexperiments: {a: {}, b: {}}\n"
        "observations:\n  - {name: r, quantity: runout, value: 9.0, units: cm, sigma: 1, experiment: c}\n"
    )
    assert cli.main(["calibrate", str(tmp_path / "c.yaml")]) == 2
    assert (
        "observations.0.experiment (line 5): unknown experiment 'c'; accepted: a, b"
        in capsys.readouterr().err
    )


@pytest.mark.parametrize(
    ("row", "fields"), [("0.1,0,12,0.5", "4 fields (0.1, 0, 12, 0.5)"), ("0.1,9", "2 fields")]
)
def test_an_observation_row_of_another_number_of_fields_than_its_header_is_named(tmp_path, row, fields):
    """``0.1,0,12,0.5`` under ``t,x_f,sigma`` (a decimal comma): ``csv.DictReader`` read t =
    0.1, x_f = 0 and sigma = 12 and dropped the fourth field, and the calibration fitted
    that front, silently."""
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "front.csv").write_text(f"t,x_f,sigma\n0.2,9,0.5\n{row}\n")
    (tmp_path / "c.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\nobservations:\n"
        "  - {name: f, quantity: front, file: front.csv, columns: [t, x_f, sigma], units: cm}\n"
    )
    with pytest.raises(InputError, match=f"front.csv: a row of {re.escape(fields)}.*, 3 in the header; acc"):
        study.load_calibration(tmp_path / "c.yaml")


@pytest.mark.parametrize(
    ("table", "columns", "phrase"),
    [
        (
            "t,x_f,sigma\n0.2,9,0.5\n",
            "[t, t, sigma]",
            r"observations.0.columns \(line 4\): a column named twice",
        ),
        (
            "t,x_f,sigma,x_f\n0.2,9,0.5,12\n",
            "[t, x_f, sigma]",
            "front.csv: its header names the column 'x_f' twice",
        ),
    ],
)
def test_an_observation_column_named_twice_is_refused(tmp_path, table, columns, phrase):
    """``columns: [t, t, sigma]`` fitted the front to the times, and a header ``t,x_f,sigma,x_f``
    (a column pasted twice) read the last ``x_f`` (``csv.DictReader`` keeps it), silently."""
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "front.csv").write_text(table)
    (tmp_path / "c.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\nobservations:\n"
        f"  - {{name: f, quantity: front, file: front.csv, columns: {columns}, units: cm}}\n"
    )
    with pytest.raises(InputError, match=phrase):
        study.load_calibration(tmp_path / "c.yaml")


def test_an_observation_header_with_spaces_after_its_commas_names_its_columns(tmp_path):
    """``t, x_f, sigma``, as a profile's header is written, had "no column 'x_f'": the names
    are read without the spaces around them, and a column missing is named with the header."""
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "c.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\nobservations:\n"
        "  - {name: f, quantity: front, file: front.csv, columns: [t, x_f, sigma], units: cm}\n"
    )
    (tmp_path / "front.csv").write_text("t, x_f , sigma\n0.1, 3.0, 0.5\n")
    (observed,) = study.load_calibration(tmp_path / "c.yaml").data
    assert (observed.coordinate, observed.value, observed.sigma) == ([0.1], [0.03], [0.005])
    (tmp_path / "front.csv").write_text("t,xf,sigma\n0.1,3.0,0.5\n")
    with pytest.raises(
        InputError, match="front.csv has no column 'x_f' \\(its header names 't', 'xf', 'sigma'\\)"
    ):
        study.load_calibration(tmp_path / "c.yaml")


@pytest.mark.parametrize(
    ("table", "phrase"),
    [
        (
            f"t,x_f,sigma\n0.1,{'9' * 10**6}x,0.5\n",
            "front.csv: line 2: field larger than field limit (131072)",
        ),
        (f"t,x_f,sigma\n0.1,{'9' * 10**5}x,0.5\n", f"(could not convert '{'9' * 56}... to a number)"),
        (f"t,{'y' * 10**5},sigma\n0.1,3.0,0.5\n", f"(its header names 't', '{'y' * 51}...); accepted"),
    ],
)
def test_an_observation_field_beyond_the_csv_modules_limit_or_long_is_named_in_one_line(
    tmp_path, table, phrase
):
    """A field longer than the ``csv`` module's limit (131072 characters) was its
    ``_csv.Error``, a traceback (exit 1); a shorter one that is no number, or a long header
    name, was quoted whole (a message of 100 kB)."""
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "front.csv").write_text(table)
    (tmp_path / "c.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\nobservations:\n"
        "  - {name: f, quantity: front, file: front.csv, columns: [t, x_f, sigma], units: cm}\n"
    )
    with pytest.raises(InputError) as caught:
        study.load_calibration(tmp_path / "c.yaml")
    assert phrase in str(caught.value) and len(str(caught.value)) < 500


def _calibration_and_sensitivity(
    directory: Path, parameters: str, calibration: str = "", sensitivity: str = ""
):
    """``c.yaml`` and ``s.yaml`` in ``directory``: a calibration and a sensitivity of the twin
    collapse varying ``parameters`` (a YAML mapping), each with its extra lines."""
    shutil.copy(TWIN / "collapse.yaml", directory)
    (directory / "c.yaml").write_text(
        f"base: collapse.yaml\nparameters: {parameters}\n{calibration}"
        "observations:\n  - {name: r, quantity: runout, value: 9.0, units: cm, sigma: 1}\n"
    )
    (directory / "s.yaml").write_text(
        f"base: collapse.yaml\nparameters: {parameters}\noutputs: [runout]\n{sensitivity}"
    )


@pytest.mark.parametrize("seed", [-1, 2**32])
def test_a_seed_numpy_cannot_take_is_refused(tmp_path, capsys, seed):
    """``seed: -1`` validated: the calibration stopped in scipy's differential evolution
    and the sensitivity's ``validate`` in its design, with numpy's ``ValueError`` and a
    traceback."""
    _calibration_and_sensitivity(
        tmp_path, "{rheology.mu_s: {bounds: [0.4, 0.5]}}", f"search: {{seed: {seed}}}\n", f"seed: {seed}\n"
    )
    for name, key in (("c.yaml", "search.seed"), ("s.yaml", "seed")):
        assert cli.main(["validate", str(tmp_path / name)]) == 2
        assert f"{key} (line " in (err := capsys.readouterr().err) and "Traceback" not in err
        assert "accepted: an integer from 0 to 4294967295 (2^32 - 1)" in err


@pytest.mark.parametrize("mean", [0.6, 0.3999, -1e308])
def test_a_prior_whose_mean_lies_outside_the_bounds_is_refused(tmp_path, capsys, mean):
    """A Gaussian prior centred outside the bounds validated: the search, which never
    leaves the bounds, was held at a bound by the prior, and the fit's uncertainty was the
    prior's.  Its mean within them (a bound included) validates."""
    parameters = f"{{rheology.mu_s: {{bounds: [0.4, 0.5], prior: {{mean: {mean}, sd: 0.05}}}}}}"
    _calibration_and_sensitivity(tmp_path, parameters)
    assert cli.main(["validate", str(tmp_path / "c.yaml")]) == 2
    err = capsys.readouterr().err
    assert err == (
        f"multilayer: error: {tmp_path / 'c.yaml'}: parameters.rheology.mu_s.prior.mean (line 2): {mean!r} "
        "outside the bounds [0.4, 0.5]; accepted: a mean within the bounds\n"
    )
    _calibration_and_sensitivity(tmp_path, parameters.replace(str(mean), "0.5"))
    assert cli.main(["validate", str(tmp_path / "c.yaml")]) == 0


def test_a_prior_so_narrow_that_its_square_overflows_is_refused_before_any_run(tmp_path, capsys):
    """A prior's sd of 1e-320 against bounds 0.1 wide validated; the calibration ran its
    whole global search (248 runs of the tiny column) to find every misfit infinite.  It is
    refused by ``validate``; 1e-150 validates."""
    parameters = "{rheology.mu_s: {bounds: [0.4, 0.5], prior: {mean: 0.45, sd: 1e-320}}}"
    _calibration_and_sensitivity(tmp_path, parameters)
    assert cli.main(["validate", str(tmp_path / "c.yaml")]) == 2
    assert capsys.readouterr().err == (
        f"multilayer: error: {tmp_path / 'c.yaml'}: parameters.rheology.mu_s.prior.sd (line 2): 1e-320: the "
        "prior's square ((theta - mean) / sd)^2 overflows within the bounds [0.4, 0.5]; accepted: an sd "
        "above 7.46e-156 (the width of the bounds / 1.34e154)\n"
    )
    _calibration_and_sensitivity(tmp_path, parameters.replace("1e-320", "1e-150"))
    assert cli.main(["validate", str(tmp_path / "c.yaml")]) == 0


def test_one_scenario_value_under_two_keys_or_one_output_twice_is_refused(tmp_path, capsys):
    """``initial.0.height`` and ``initial.00.height``, two parameters of a sensitivity, a
    calibration or a sweep, validated: both set the one height, the later over the earlier,
    which was never varied (its Sobol' indices read as an insensitive parameter; the sweep's
    members labelled with values they did not run).  ``outputs: [runout, runout]`` too."""
    both = "{initial.0.height: {bounds: [0.04, 0.05]}, initial.00.height: {bounds: [0.04, 0.05]}}"
    _calibration_and_sensitivity(tmp_path, both)
    (tmp_path / "w.yaml").write_text(
        "base: collapse.yaml\nparameters: {initial.0.height: [0.04], initial.00.height: [0.05]}\n"
    )
    (tmp_path / "o.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\noutputs: [runout, runout]\n"
    )
    for name in ("c.yaml", "s.yaml", "w.yaml"):
        assert cli.main(["validate", str(tmp_path / name)]) == 2
        err = capsys.readouterr().err
        assert (
            "--set initial.00.height: initial has 1 entries; accepted indices: 0..0 (without leading zeros)"
            in err
        )
    assert cli.main(["validate", str(tmp_path / "o.yaml")]) == 2
    assert "outputs (line 3): runout twice; accepted: each output once" in capsys.readouterr().err


def _netcdf_front(directory: Path, units: dict[str, Any]) -> Path:
    """``c.yaml`` in ``directory``: a calibration against the front of ``front.nc``, 5 and 9
    (``x_f``) at 100 and 200 (``t``), whose ``units`` attributes are ``units``."""
    attrs = {name: {"units": unit} for name, unit in units.items()}
    ds = xr.Dataset({"x_f": ("t", [5.0, 9.0], attrs["x_f"])}, coords={"t": ("t", [100.0, 200.0], attrs["t"])})
    ds.to_netcdf(directory / "front.nc")
    shutil.copy(TWIN / "collapse.yaml", directory)
    (directory / "c.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\n"
        "observations:\n  - {name: f, quantity: front, file: front.nc, variable: x_f, sigma: 0.5}\n"
    )
    return directory / "c.yaml"


def test_observations_from_netcdf_take_the_units_attributes(tmp_path):
    """A front curve in a netCDF file, in cm against ms, reads back in m against s."""
    data = study.load_calibration(_netcdf_front(tmp_path, {"x_f": "cm", "t": "ms"})).data[0]
    assert data.coordinate == pytest.approx([0.1, 0.2])
    assert data.value == pytest.approx([0.05, 0.09]) and data.sigma == pytest.approx([0.005, 0.005])


@pytest.mark.parametrize("holder", ["x_f", "t"])
def test_a_netcdf_units_attribute_that_is_not_text_is_named(tmp_path, holder):
    """Another tool's ``units`` of numbers (an array) on the observation or its coordinate:
    a ``ValueError`` of numpy's truth value, with a traceback."""
    path = _netcdf_front(tmp_path, {"x_f": "cm", "t": "ms", holder: np.array([1.0, 2.0])})
    with pytest.raises(InputError, match=f"front.nc: {holder} has units array\\(\\[1., 2.\\]\\), not text"):
        study.load_calibration(path)


@pytest.mark.parametrize(
    ("command", "name"),
    [("validate", "c.yaml"), ("validate", "s.yaml"), ("calibrate", "c.yaml"), ("sensitivity", "s.yaml")],
)
def test_a_bound_leaving_the_initial_material_outside_the_domain_is_refused_before_any_run(
    tmp_path, capsys, command, name
):
    """``domain.x_max`` down to 0.03 m, within the column of 0.05 m: ``validate`` said ok, and
    the study ran until its runs at the lower bound failed (exit 1)."""
    _calibration_and_sensitivity(
        tmp_path, "{domain.x_max: {bounds: [0.03, 0.3]}}", sensitivity="samples: 8\n"
    )
    assert (
        cli.main(
            [command, str(tmp_path / name), "-o", str(tmp_path / "out")][: 2 if command == "validate" else 4]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "parameters.domain.x_max (line 2): the scenario is invalid with domain.x_max = 0.03" in err
    assert "lie outside the domain" in err and not (tmp_path / "out").exists()


# --------------------------------------------------------------------- observables


def test_interpolated_front_of_a_linear_ramp_is_exact():
    """h = 2 (0.3 - x) on cell centres: the threshold 0.01 is crossed at x = 0.295 exactly,
    between cell centres (the result file's front is the last wet centre, 0.29)."""
    x = np.arange(0.005, 0.5, 0.01)
    h = np.maximum(2 * (0.3 - x), 0.0)
    assert observables.interpolated_front(x, h, 0.01) == pytest.approx(0.295, abs=1e-12)
    assert math.isnan(observables.interpolated_front(x, np.zeros_like(x), 0.01))


def test_duration_and_thickness_interpolate_between_outputs():
    """A front advancing at 1 m/s until it stops at 0.30 m at t = 0.3 s: within 5 mm of its
    final position at t = 0.295 s; h halfway between two records is their mean."""
    t = np.array([0.0, 0.1, 0.2, 0.3, 0.4])
    fronts = np.array([0.0, 0.1, 0.2, 0.3, 0.3])
    x = np.linspace(0.005, 0.495, 50)
    h = np.array([np.where(x < f + 0.0051, 0.02, 0.0) for f in fronts])
    ds = xr.Dataset(
        {
            "h": (("time", "x"), h),
            "front": ("time", fronts, {"threshold": 0.01}),
            "mass": ("time", h.sum(axis=1) * 0.01),
        },
        coords={"time": t, "x": x},
    )
    assert observables.scalar(ds, "duration") == pytest.approx(0.295, abs=2e-3)
    assert observables.scalar(ds, "runout") == pytest.approx(0.3, abs=0.011)
    mid = observables.thickness(ds, [0.15], at_time=0.15)
    assert mid == pytest.approx(0.5 * (np.interp(0.15, x, h[1]) + np.interp(0.15, x, h[2])))


# --------------------------------------------------------------------- sensitivity


def test_sobol_indices_of_the_ishigami_function(tmp_path):
    """The Ishigami function (Ishigami & Homma 1990) on [-pi, pi]^3, a = 7, b = 0.1, whose
    indices are known in closed form: S1 = (0.314, 0.442, 0), ST = (0.558, 0.442, 0.244).
    Every exact value lies within the estimate's 95 % interval (N = 512)."""
    from multilayer.app.sensitivity import sample

    config = study.SensitivityModel.model_validate(
        {
            "base": "unused.yaml",
            "parameters": {k: {"bounds": [-math.pi, math.pi]} for k in ("a", "b", "c")},
            "outputs": ["runout"],
            "samples": 512,
        }
    )
    plan = study.Sensitivity(path=tmp_path / "sobol.yaml", base=tmp_path / "unused.yaml", config=config)
    x = sample(plan)
    y = np.sin(x[:, 0]) + 7 * np.sin(x[:, 1]) ** 2 + 0.1 * x[:, 2] ** 4 * np.sin(x[:, 0])
    result = indices(plan, y[:, None])
    s1, st = np.array([0.3139, 0.4424, 0.0]), np.array([0.5576, 0.4424, 0.2437])
    assert np.all(np.abs(result.s1[0] - s1) <= result.s1_conf[0] + 0.01), (result.s1, result.s1_conf)
    assert np.all(np.abs(result.st[0] - st) <= result.st_conf[0] + 0.01), (result.st, result.st_conf)
    assert np.all(result.s1_conf[0] < 0.15)


@pytest.mark.slow  # the Sobol estimator runs by default: test_sobol_indices_of_the_ishigami_function
def test_sensitivity_command_writes_every_run_and_the_indices(tmp_path, cluster, capsys):
    """One parameter, 8 base samples: 24 sample points (16 distinct runs: with one
    parameter AB_1 is B), all in sensitivity.nc, then sobol.png.  With one parameter all the
    variance is its own: S1 = ST = 1 within the intervals."""
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "sobol.yaml").write_text(
        "base: collapse.yaml\nparameters:\n  initial.0.height: {bounds: [0.04, 0.06]}\n"
        "outputs: [runout]\nsamples: 8\n"
    )
    outdir = tmp_path / "out"
    assert (
        cli.main(["sensitivity", str(tmp_path / "sobol.yaml"), "-o", str(outdir), "--scheduler", cluster])
        == 0
    )
    out = capsys.readouterr().out
    assert "16 run(s), 0 reused, 0 failed" in out and "S1 = " in out
    ds = xr.load_dataset(outdir / "sensitivity.nc")
    assert ds.sizes["run"] == 24 and (ds["status"].values == "ok").all()
    for key in ("S1", "ST"):
        assert abs(float(ds[key].values.item()) - 1) <= float(ds[f"{key}_conf"].values.item()) + 0.05, (
            float(ds[key].values.item()),
            float(ds[f"{key}_conf"].values.item()),
        )
    # a taller column runs out further
    assert np.corrcoef(ds["sample"].values[:, 0], ds["value"].values[:, 0])[0, 1] > 0.9
    assert (
        cli.main(["sensitivity", str(tmp_path / "sobol.yaml"), "-o", str(outdir), "--scheduler", cluster])
        == 0
    )
    assert "0 run(s), 24 reused" in capsys.readouterr().out
    assert cli.main(["plot", str(outdir)]) == 0
    assert (outdir / "plots" / "sobol.png").is_file()


def test_too_few_samples_for_the_parameters_exit_2(tmp_path, capsys):
    """16 base samples for 5 parameters: the halves A and B of the design are correlated."""
    study_file = ROOT / "studies" / "erodible_bed_sobol.yaml"
    (tmp_path / "studies").mkdir()
    (tmp_path / "scenarios").mkdir()
    shutil.copy(ROOT / "scenarios" / "erodible_bed_collapse.yaml", tmp_path / "scenarios")
    text = re.sub(r"\nsamples: \d+\n", "\nsamples: 16\n", study_file.read_text())
    assert "\nsamples: 16\n" in text
    (tmp_path / "studies" / "s.yaml").write_text(text)
    assert cli.main(["sensitivity", str(tmp_path / "studies" / "s.yaml")]) == 2
    assert "samples: with 16 base samples the two halves of the Sobol' design are correlated" in (
        capsys.readouterr().err
    )


def test_bad_sensitivity_file_exits_2_naming_the_key(tmp_path, capsys):
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "sobol.yaml").write_text(
        "base: collapse.yaml\nparameters:\n  rheology.mu_s: {bounds: [0.45, 0.5]}\n"
        "outputs: [runout]\nsamples: 6\n"
    )
    assert cli.main(["sensitivity", str(tmp_path / "sobol.yaml")]) == 2
    assert "sobol.yaml: samples (line 5): got 6; accepted: a power of 2" in capsys.readouterr().err


# --------------------------------------------------------------------- shipped studies, docs


@pytest.mark.parametrize("name", ["twin/calibration.yaml", "column_collapse_runout.yaml"])
def test_shipped_calibration_files_are_valid(name):
    plan = study.load_calibration(ROOT / "studies" / name)
    assert plan.data and all(len(d.value) == len(d.sigma) for d in plan.data)


def test_shipped_and_documented_sensitivity_files_are_valid(tmp_path):
    study.load_sensitivity(ROOT / "studies" / "erodible_bed_sobol.yaml")
    docs = (ROOT / "docs" / "calibration.md").read_text()
    example = docs.split("## The sensitivity file\n", 1)[1].split("```yaml\n", 1)[1].split("```", 1)[0]
    (tmp_path / "studies").mkdir()
    (tmp_path / "scenarios").mkdir()
    shutil.copy(ROOT / "scenarios" / "erodible_bed_collapse.yaml", tmp_path / "scenarios")
    (tmp_path / "studies" / "sobol.yaml").write_text(example)
    plan = study.load_sensitivity(tmp_path / "studies" / "sobol.yaml")
    assert plan.config.outputs == ["runout", "duration"] and plan.config.samples == 128


@pytest.mark.slow
def test_worked_example_of_the_docs(tmp_path, capsys):
    """The twin experiment of docs/calibration.md as documented: its observation files are
    what make_observations.py writes, and the calibration recovers the truth."""
    docs = (ROOT / "docs" / "calibration.md").read_text()
    commands = (
        docs.split("## Worked example: a twin experiment\n", 1)[1]
        .split("```sh\n", 1)[1]
        .split("```", 1)[0]
        .splitlines()
    )
    assert commands == [
        "python studies/twin/make_observations.py 1.0 1",
        "multilayer calibrate studies/twin/calibration.yaml",
        "multilayer plot results/twin",
    ]
    make_observations.write(1.0, 1, tmp_path)
    for name in ("front.csv", "deposit.csv"):
        assert (tmp_path / name).read_text() == (TWIN / name).read_text()
    outdir = tmp_path / "twin"
    assert cli.main(["calibrate", str(TWIN / "calibration.yaml"), "-o", str(outdir)]) == 0
    ds = xr.load_dataset(outdir / calibration.CALIBRATION_FILE)
    assert np.all(np.abs(ds["best"].values - TRUE) < 3 * ds["sd"].values)
    assert cli.main(["plot", str(outdir)]) == 0


class _Measured:
    """An ensemble whose every member completes and measures ``values`` (no run)."""

    ran = reused = 0

    def __init__(self, values: list[float]) -> None:
        self.values = np.array(values)

    def evaluate(self, points, measures):
        from multilayer.app.ensemble import Evaluation

        return [Evaluation(f"m{i}", point, "ok", self.values) for i, point in enumerate(points)]


def test_uncertainties_whose_misfit_cannot_be_a_number_are_named(tmp_path):
    """An uncertainty of 1e-200 m: every run completed and the squared whitened residuals
    overflowed; the calibration said "every one of the 15 parameter sets failed; first
    errors: " (exit 1, no error).  It now names the uncertainties (exit 2).  1e-322 cm of
    uncertainty, 0 m in SI, validated; it is now refused with the file."""
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n0.1,0.12,1e-200\n0.2,0.15,1e-200\n")
    text = (
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\n"
        "observations:\n  - {name: f, quantity: front, file: front.csv, columns: [t, x_f, sigma]}\n"
        "search: {population: 4, generations: 1}\nrefine: {evaluations: 0}\n"
    )
    (tmp_path / "c.yaml").write_text(text)
    loaded = study.load_calibration(tmp_path / "c.yaml")
    calibrator = calibration.Calibrator(loaded, _Measured([0.5, 0.6]), print)
    with pytest.raises(InputError, match=r"c\.yaml: observations: the misfit of every parameter set whose"):
        calibrator.run()
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n0.1,12,1e-322\n0.2,15,1\n")
    (tmp_path / "c.yaml").write_text(text.replace("sigma]}", "sigma], units: cm}"))
    with pytest.raises(InputError, match=r"file \(line 4\): the sigma 9.88131e-323 is 0 in SI \(times 0"):
        study.load_calibration(tmp_path / "c.yaml")


class _Proportional(_Measured):
    """Measures ``values`` times the parameter ``rheology.mu_s``: each set predicts its own."""

    def evaluate(self, points, measures):
        from multilayer.app.ensemble import Evaluation

        return [
            Evaluation(f"m{i}", point, "ok", self.values * point["rheology.mu_s"])
            for i, point in enumerate(points)
        ]


def _huge_sigma(tmp_path, rows: str) -> study.Calibration:
    shutil.copy(TWIN / "collapse.yaml", tmp_path)
    (tmp_path / "front.csv").write_text("t,x_f,sigma\n" + rows)
    (tmp_path / "c.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\n"
        "observations:\n  - {name: f, quantity: front, file: front.csv, columns: [t, x_f, sigma]}\n"
        "search: {population: 4, generations: 1}\nrefine: {evaluations: 0}\n"
    )
    return study.load_calibration(tmp_path / "c.yaml")


def test_a_misfit_that_does_not_tell_the_parameter_sets_apart_is_refused(tmp_path):
    """Uncertainties of 1e300 m: the squared whitened residuals underflowed to 0 for every
    parameter set and the calibration reported the first one as the best fit."""
    loaded = _huge_sigma(tmp_path, "0.1,0.12,1e300\n0.2,0.15,1e300\n")
    said = r"is 0\.0, though their predictions differ: .* underflow, the largest sigma being 1e\+300"
    with pytest.raises(InputError, match=said):
        calibration.Calibrator(loaded, _Proportional([0.5, 0.6]), print).run()
    with pytest.raises(InputError, match=r"the model gives the same values at every parameter set, so the "
                       r"observations do not constrain rheology\.mu_s"):  # fmt: skip
        calibration.Calibrator(loaded, _Measured([0.5, 0.6]), print).run()


def test_an_observation_of_sigma_1e300_beside_others_weighs_nothing(tmp_path):
    """One observation of infinite uncertainty in the limit: the others pick the fit."""
    loaded = _huge_sigma(tmp_path, "0.1,0.12,1e300\n0.2,0.14,0.01\n")
    fit = calibration.Calibrator(loaded, _Proportional([0.5, 0.6]), print).run()
    assert fit.misfit < min(c.misfit for c in fit.candidates if c.theta[0] != fit.theta[0])


@pytest.mark.parametrize("target", ["nothing.csv", "loop.csv"])
def test_a_study_file_that_is_a_symbolic_link_to_nothing_or_in_a_loop_is_said_so(tmp_path, target):
    """A base scenario or an observation file that is a symbolic link to nothing, or one of
    a loop of links, was said to be "not found", where ``ls`` lists it."""
    (tmp_path / "loop.csv").symlink_to("link.csv")
    (tmp_path / "link.csv").symlink_to(target)
    _calibration_and_sensitivity(tmp_path, "{rheology.mu_s: {bounds: [0.4, 0.5]}}")
    (tmp_path / "s.yaml").write_text((tmp_path / "s.yaml").read_text().replace("collapse.yaml", "link.csv"))
    said = "link.csv is a symbolic link to nothing or in a loop"
    with pytest.raises(InputError, match=f"scenario file .*{said}"):
        study.load_sensitivity(tmp_path / "s.yaml")
    (tmp_path / "c.yaml").write_text(
        "base: collapse.yaml\nparameters: {rheology.mu_s: {bounds: [0.4, 0.5]}}\nobservations:\n"
        "  - {name: f, quantity: front, file: link.csv, columns: [t, x_f, sigma]}\n"
    )
    with pytest.raises(InputError, match=f"{said}; accepted: a CSV"):
        study.load_calibration(tmp_path / "c.yaml")
