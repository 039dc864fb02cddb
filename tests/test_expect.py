"""Regression expectations: multilayer.expect, `multilayer check` and the pytest plugin.

The scenario used is the inviscid single-column static/flowing problem (20 layers, a few
time steps), whose exact solution (Bouchut, Ionescu & Mangeney 2016, Prop. 2.2) gives the
expected values: U = max(70 (z - 5 mm)_+ - S t, 0), S = g cos(theta)(mu_s - tan(theta)).
"""

import copy
import math
from importlib.metadata import entry_points

import numpy as np
import pytest
import yaml

from multilayer.app import cli
from multilayer.io.scenario import Expect
from multilayer.reference.exact import InviscidSimpleShear
from multilayer.testing.expectations import Outcome, evaluate, report

pytest_plugins = ["pytester"]

THETA, MU_S, H, B0, SHEAR, T_END, LAYERS = 22.0, 0.48773, 0.02, 0.005, 70.0, 0.3, 20
EXACT = InviscidSimpleShear(theta_deg=THETA, mu_s=MU_S, depth=H, b0=B0, shear=SHEAR)
#: the top layer centre z = h - h/(2L) is the fastest (Prop. 2.2)
EXACT_MAX_SPEED = float(EXACT.velocity(np.array(H - H / (2 * LAYERS)), T_END))


def _scenario(expect: list[dict] | None) -> dict:
    data = {
        "name": "tiny-static-flowing",
        "slope_deg": THETA,
        "domain": {"x_min": 0.0, "x_max": 0.02, "cells": 2, "layers": LAYERS},
        "material": {"density": 1550, "grain_diameter": 0.7e-3},
        "rheology": {"name": "drucker_prager", "mu_s": MU_S, "nu": 0.0},
        "initial": [
            {
                "shape": "layer",
                "thickness": H,
                "velocity": {"profile": "linear", "shear_rate": SHEAR, "from_height": B0},
            }
        ],
        "boundaries": {"left": "periodic", "right": "periodic"},
        "time": {"end": T_END, "output_interval": T_END},
    }
    if expect is not None:
        data["expect"] = copy.deepcopy(expect)
    return data


TRUE = [
    {"quantity": "max_speed_final", "value": EXACT_MAX_SPEED, "rtol": 1e-3},
    {"quantity": "mass_final", "value": H * 0.02, "rtol": 1e-9},
]
FALSE = [
    {"quantity": "max_speed_final", "value": EXACT_MAX_SPEED, "rtol": 1e-3},
    {"quantity": "mass_final", "value": 2 * H * 0.02, "rtol": 0.01},
]


def _write(directory, name: str, expect: list[dict] | None) -> str:
    path = directory / name
    path.write_text(yaml.safe_dump(_scenario(expect), sort_keys=False))
    return str(path)


# --------------------------------------------------------------------------- evaluate


def test_tolerance_is_atol_plus_rtol_times_value():
    entries = [
        Expect(quantity="runout", value=2.0, rtol=0.1, atol=0.05),
        Expect(quantity="mass_final", value=-1.0, rtol=0.1),
    ]
    ok, edge = evaluate(entries, {"runout": 2.249, "mass_final": -1.1000001})
    assert ok.tolerance == pytest.approx(0.25) and ok.passed
    assert edge.tolerance == pytest.approx(0.1) and not edge.passed


def test_nan_never_passes():
    outcome = Outcome("static_interface_mean_final", 0.0, float("nan"), math.inf)
    assert not outcome.passed


def test_report_lists_expected_obtained_and_verdict():
    text = report("demo", [Outcome("front_final", 0.62, 0.61, 0.031), Outcome("runout", 0.4, 0.5, 0.02)])
    assert text.splitlines()[0] == "demo: 1/2 expectations met"
    assert "front_final" in text and "0.62" in text and "0.61" in text
    assert text.splitlines()[-1].split()[-1] == "FAILED"


# --------------------------------------------------------------------------- multilayer check


def test_check_passes_true_expectation(tmp_path, capsys):
    """The exact inviscid solution is met to 0.1 %, mass to round-off: exit 0."""
    path = _write(tmp_path, "true.yaml", TRUE)
    assert cli.main(["check", path]) == 0
    out = capsys.readouterr().out
    assert "2/2 expectations met" in out and "FAILED" not in out


def test_check_fails_false_expectation(tmp_path, capsys):
    path = _write(tmp_path, "false.yaml", FALSE)
    assert cli.main(["check", path, "-o", str(tmp_path / "kept")]) == 1
    out = capsys.readouterr().out
    assert "1/2 expectations met" in out
    line = next(line for line in out.splitlines() if "mass_final" in line)
    assert line.split()[1:4] == ["0.0008", "0.0004", "8e-06"] and line.endswith("FAILED")
    assert (tmp_path / "kept" / "tiny-static-flowing" / "result.nc").is_file()


def test_check_invalid_input_exits_2_without_running(tmp_path, capsys):
    bad = _scenario(TRUE)
    bad["expect"][0]["quantity"] = "front_speed"
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad))
    no_expect = _write(tmp_path, "none.yaml", None)
    assert cli.main(["check", str(path), no_expect, str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: expect.0.quantity" in err and "front_final" in err
    assert f"{no_expect}: expect: no expectations" in err
    assert "missing.yaml: file not found" in err
    assert "Traceback" not in err


# --------------------------------------------------------------------------- pytest plugin


def test_plugin_is_registered_through_pytest11():
    plugins = {ep.name: ep.value for ep in entry_points(group="pytest11")}
    assert plugins.get("multilayer") == "multilayer.testing.pytest_plugin"


def test_pytest_collects_scenarios_in_named_directory(pytester):
    """One item per file with expect:; files without it, and subdirectories, ignored."""
    _write(pytester.path, "true.yaml", TRUE)
    _write(pytester.path, "false.yml", FALSE)
    _write(pytester.path, "plain.yaml", None)
    (pytester.path / "fixtures").mkdir()
    _write(pytester.path / "fixtures", "nested.yaml", FALSE)
    result = pytester.runpytest_subprocess(str(pytester.path), "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1, failed=1)
    result.stdout.fnmatch_lines(
        ["*1/2 expectations met*", "*mass_final*0.0008*0.0004*FAILED*", "FAILED false.yml::false*"]
    )
    assert "nested" not in result.stdout.str()


def test_pytest_runs_a_named_file(pytester):
    path = _write(pytester.path, "true.yaml", TRUE)
    result = pytester.runpytest_subprocess(path, "-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)


def test_pytest_without_arguments_collects_no_yaml(pytester):
    """A plain `pytest` (no paths named) never turns YAML files into scenario runs."""
    _write(pytester.path, "false.yaml", FALSE)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.NO_TESTS_COLLECTED


def test_tiny_scenario_matches_exact_inviscid_solution(tmp_path):
    """The reference values used above are the model's: b(t) = b0 + S t / 70 too."""
    from multilayer.app import runner
    from multilayer.io import scenario as scenarios
    from multilayer.io.results import open_result

    scenario = scenarios.load(_write(tmp_path, "true.yaml", TRUE))
    runner.run(scenario, tmp_path / "out", quiet=True)
    final = open_result(tmp_path / "out").isel(time=-1)
    interface = float(EXACT.interface(T_END))
    assert np.all(np.abs(final["static_interface"].values - interface) <= H / LAYERS)
