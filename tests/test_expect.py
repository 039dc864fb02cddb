"""Expectations (regression pins and reference values): evaluation, `multilayer check`
and the pytest plugin.

The scenario used is the inviscid single-column static/flowing problem (20 layers, a few
time steps), whose exact solution (Bouchut, Ionescu & Mangeney 2016, Prop. 2.2) gives the
expected values: U = max(70 (z - 5 mm)_+ - S t, 0), S = g cos(theta)(mu_s - tan(theta)).
"""

import copy
import math
import sys
from importlib.metadata import entry_points
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO

import multilayer
from multilayer.app import cli
from multilayer.app.expectations import Outcome, evaluate, report
from multilayer.engine.mixture.closure import DENSEST_PACKING
from multilayer.errors import InputError
from multilayer.reference.exact import InviscidSimpleShear
from multilayer.scenario.schema import Expect

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


SOURCE = "Bouchut, Ionescu & Mangeney (2016), Prop. 2.2"
TRUE = [
    {
        "kind": "reference",
        "quantity": "max_speed_final",
        "value": EXACT_MAX_SPEED,
        "rtol": 1e-3,
        "source": SOURCE,
    },
    {"kind": "regression", "quantity": "mass_final", "value": H * 0.02, "rtol": 1e-9},
]
FALSE = [
    {
        "kind": "reference",
        "quantity": "max_speed_final",
        "value": EXACT_MAX_SPEED,
        "rtol": 1e-3,
        "source": SOURCE,
    },
    {"kind": "regression", "quantity": "mass_final", "value": 2 * H * 0.02, "rtol": 0.01},
]


def _write(directory, name: str, expect: list[dict] | None) -> str:
    path = directory / name
    path.write_text(yaml.safe_dump(_scenario(expect), sort_keys=False))
    return str(path)


# --------------------------------------------------------------------------- evaluate


def test_tolerance_is_atol_plus_rtol_times_value():
    entries = [
        Expect(kind="regression", quantity="runout", value=2.0, rtol=0.1, atol=0.05),
        Expect(kind="regression", quantity="front_final", value=-1.0, rtol=0.1),  # a front at x < 0
    ]
    ok, edge = evaluate(entries, {"runout": 2.249, "front_final": -1.1000001})
    assert ok.tolerance == pytest.approx(0.25) and ok.passed
    assert edge.tolerance == pytest.approx(0.1) and not edge.passed


def test_nan_never_passes():
    outcome = Outcome("static_interface_mean_final", 0.0, float("nan"), math.inf)
    assert not outcome.passed


def test_report_lists_kind_expected_obtained_verdict_and_sources():
    text = report(
        "demo",
        [
            Outcome("front_final", 0.62, 0.61, 0.031, "regression"),
            Outcome("runout", 0.4, 0.5, 0.02, "reference", "Someone (2001), eq. 3"),
        ],
    )
    lines = text.splitlines()
    assert lines[0] == "demo: 1/2 expectations met (1/1 regression, 0/1 reference)"
    assert lines[2].split() == ["regression", "front_final", "0.62", "0.61", "0.031", "ok"]
    assert lines[3].split()[0] == "reference" and lines[3].split()[-1] == "FAILED"
    assert lines[-1] == "  reference runout: Someone (2001), eq. 3"


def test_a_failed_expectation_shows_the_digits_that_tell_its_values_apart():
    """``mass_final`` pinned at 0.005 with ``rtol: 0`` failed on 0.005000000000000001, the
    table saying ``0.005 0.005 FAILED``; a value passing or shown apart keeps 6 digits."""
    lines = report(
        "demo",
        [
            Outcome("mass_final", 0.005, 0.005000000000000001, 0.0),
            Outcome("runout", 0.0625, 0.0625, 0.0),
        ],
    ).splitlines()
    assert lines[2].split() == ["regression", "mass_final", "0.005", "0.005000000000000001", "0", "FAILED"]
    assert lines[3].split() == ["regression", "runout", "0.0625", "0.0625", "0", "ok"]


MIXTURE = {
    "fluid": {"density": 1000.0, "viscosity": 1e-3},
    "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
    "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
}
"""The keys making :data:`TINY_SCENARIO` a grain-fluid mixture (its initial ``phi`` 0.58)."""

FLOAT_MAX = sys.float_info.max


def _pinned(quantity: str, value: float, **tolerance: float) -> dict:
    """TINY_SCENARIO with one regression pin (a mixture for the packing ``phi_mean_final``)."""
    data = copy.deepcopy(TINY_SCENARIO)
    if quantity == "phi_mean_final":
        data.update(copy.deepcopy(MIXTURE))
        data["initial"][0]["phi"] = 0.58
    data["expect"] = [{"kind": "regression", "quantity": quantity, "value": value, **tolerance}]
    return data


@pytest.mark.parametrize(
    ("quantity", "value", "tolerance", "bound"),
    [
        ("phi_mean_final", 0.3, {"atol": 0.45}, "0.44048"),  # [-0.15, 0.75] holds [0, 0.74048]
        ("phi_mean_final", 0.3, {"rtol": 2.0}, "0.44048"),  # [-0.3, 0.9]
        ("phi_mean_final", 0.5, {"rtol": 0.5, "atol": 0.3}, "0.5"),  # 0.55 about 0.5: [-0.05, 1.05]
        ("mass_final", 0.0, {"atol": FLOAT_MAX}, "1.79769e+308"),  # [-max, max] holds every mass
        ("max_speed_final", 1e308, {"rtol": 1.0}, "1e+308"),  # [0, 2e308]: up to inf
        ("front_final", 0.0, {"atol": FLOAT_MAX}, "1.79769e+308"),  # every finite float
    ],
)
def test_an_expectation_every_run_passes_is_refused(quantity, value, tolerance, bound):
    """An interval ``value +- (atol + rtol |value|)`` holding every value the quantity can
    take (``QUANTITY_RANGES``; a packing within the densest packing of spheres, a mass or
    speed 0 or more up to the largest float, a front any finite number) passes every run:
    a check of nothing, which validated and passed.  Refused naming the key of the larger
    part of the tolerance and the largest tolerance the value accepts."""
    key = "rtol" if tolerance.get("rtol", 0.0) * abs(value) > tolerance.get("atol", 0.0) else "atol"
    with pytest.raises(InputError) as refused:
        multilayer.load(_pinned(quantity, value, **tolerance))
    said = str(refused.value)
    assert f"expect.0.{key}: {quantity} = {value!r} +- " in said
    assert f"holds every value a run's {quantity} can take" in said and "every run passes" in said
    assert f"accepted: a tolerance atol + rtol |value| below {bound} for this value" in said


@pytest.mark.parametrize(
    ("quantity", "value", "tolerance"),
    [
        ("phi_mean_final", 0.3, {"atol": 0.44}),  # [-0.14, 0.74]: a packing of 0.7403 fails
        ("phi_mean_final", 0.3, {"rtol": 1.0}),  # [0, 0.6]
        ("phi_mean_final", DENSEST_PACKING, {"atol": 0.0}),  # the densest packing itself
        ("mass_final", 0.005, {"atol": 1e308}),  # a mass beyond 1e308 fails
        ("max_speed_final", 1.0, {"rtol": 1e300}),
        ("front_final", 0.0, {"atol": 1e308}),  # a front beyond 1e308 m fails
    ],
)
def test_an_expectation_some_value_fails_is_accepted(quantity, value, tolerance):
    """An interval that misses one end of the quantity's values checks something: accepted,
    however wide (the ranges of ``QUANTITY_RANGES`` without an upper bound end at the
    largest float)."""
    assert multilayer.load(_pinned(quantity, value, **tolerance)).expect[0].value == value


def test_a_packing_beyond_the_densest_packing_is_no_value_of_phi_mean_final():
    """``phi_mean_final`` ranges within the densest packing of spheres (its bound in the
    engine and the result check), not [0, 1): a pin at 0.75 no run passes is refused, and
    the message names the bound."""
    with pytest.raises(InputError) as refused:
        multilayer.load(_pinned("phi_mean_final", 0.75, atol=0.005))
    assert (
        "expect.0.value: phi_mean_final = 0.75 +- 0.005: no run passes (its phi_mean_final is in "
        f"[0, {DENSEST_PACKING:.6g}] (pi/sqrt(18), the densest packing of spheres))"
    ) in str(refused.value)


@pytest.mark.parametrize(
    "entry, message",
    [
        ({"quantity": "runout", "value": 1.0, "rtol": 0.1}, "expect.0.kind"),
        ({"kind": "validation", "quantity": "runout", "value": 1.0, "rtol": 0.1}, "accepted: regression ("),
        ({"kind": "reference", "quantity": "runout", "value": 1.0, "rtol": 0.1}, "requires source"),
        (
            {"kind": "regression", "quantity": "runout", "value": 1.0, "rtol": 0.1, "source": "me"},
            "expect.0.source",
        ),
    ],
    ids=["no_kind", "unknown_kind", "reference_without_source", "regression_with_source"],
)
def test_every_entry_says_its_kind_and_a_reference_its_source(tmp_path, capsys, entry, message):
    path = _write(tmp_path, "bad.yaml", [entry])
    assert cli.main(["validate", path]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


# --------------------------------------------------------------------------- exact solutions


EXACT_U = {
    "kind": "reference",
    "exact": {"solution": "inviscid_simple_shear", "field": "u", "norm": "l1"},
    "atol": (H / LAYERS / (H - float(EXACT.interface(T_END)))) ** 2 / 4,
    "source": SOURCE,
}
"""The layer velocities within the bound of the layer discretisation: every layer moves
rigidly at the exact deceleration except the one holding the kink of U, off by at most
shear dz / 8, a relative L1 error (dz / (h - b))^2 / 4."""


def _with_exact(**changes: object) -> dict:
    return {**EXACT_U, "exact": {**EXACT_U["exact"], **changes}}


@pytest.mark.parametrize(
    "entry, message",
    [
        ({**EXACT_U, "kind": "regression"}, "a comparison with an exact solution is a reference"),
        ({**EXACT_U, "quantity": "runout"}, "expect.0.quantity"),
        ({k: v for k, v in EXACT_U.items() if k != "atol"}, "requires atol"),
        ({**EXACT_U, "rtol": 0.1}, "expect.0.rtol"),
        (_with_exact(solution="ritter"), "expect.0.exact.solution"),
        (_with_exact(norm="l2"), "expect.0.exact.norm"),
        (_with_exact(x_min=0.02, x_max=0.01), "expect.0.exact.x_max"),
    ],
    ids=[
        "regression",
        "with_quantity",
        "no_atol",
        "rtol",
        "unknown_solution",
        "unknown_norm",
        "empty_window",
    ],
)
def test_an_exact_comparison_is_a_reference_with_an_atol(tmp_path, capsys, entry, message):
    """Only kind, exact, atol and source: the checked value is an error, expected 0."""
    path = _write(tmp_path, "bad.yaml", [entry])
    assert cli.main(["validate", path]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_check_compares_the_layer_velocities_with_the_exact_solution(tmp_path, capsys):
    path = _write(tmp_path, "exact.yaml", [EXACT_U])
    assert cli.main(["check", path]) == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if "u_l1_error_inviscid_simple_shear" in line)
    kind, _, expected, obtained, tolerance, verdict = line.split()
    assert (kind, float(expected), verdict) == ("reference", 0.0, "ok")
    assert 0 < float(obtained) <= float(tolerance)


@pytest.mark.parametrize(
    "entry, message",
    [
        (
            _with_exact(solution="coulomb_dam_break", field="h"),
            "expect.0.exact: the exact solution coulomb_dam_break does not apply: domain.layers differs; "
            "accepted: 1",
        ),
        (_with_exact(x_min=0.5), "expect.0.exact: no cell centre between x_min and x_max"),
    ],
    ids=["not_applicable", "window_outside"],
)
def test_check_refuses_a_comparison_that_does_not_apply_before_running(tmp_path, capsys, entry, message):
    """`check` refuses before running, `validate` too."""
    path = _write(tmp_path, "bad.yaml", [entry])
    assert cli.main(["check", path, "-o", str(tmp_path / "kept")]) == 2
    err = capsys.readouterr().err
    assert f"{path}: {message}" in err and "Traceback" not in err
    assert not (tmp_path / "kept").exists()
    assert cli.main(["validate", path]) == 2
    assert f"{path}: {message}" in capsys.readouterr().err


def test_check_refuses_a_field_the_solution_does_not_give(tmp_path, capsys):
    data = _scenario([_with_exact(solution="coulomb_dam_break", field="u")])
    data.update(
        slope_deg=0.0,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 20},
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.5, "height": 0.1}],
        boundaries={"left": "wall", "right": "outflow"},
        base=[{"condition": "free_slip"}],
    )
    path = tmp_path / "dam.yaml"
    path.write_text(yaml.safe_dump(data))
    assert cli.main(["check", str(path)]) == 2
    assert (
        f"{path}: expect.0.exact.field: coulomb_dam_break gives no u; accepted: h" in capsys.readouterr().err
    )


def test_pytest_item_of_an_exact_comparison_is_named_by_field_norm_and_solution():
    from multilayer.testing.pytest_plugin import _item_name

    assert _item_name(EXACT_U) == "reference[u_l1_error_inviscid_simple_shear]"


# --------------------------------------------------------------------------- multilayer check


def test_check_passes_true_expectation(tmp_path, capsys):
    """The exact inviscid solution is met to 0.1 %, mass to round-off: exit 0."""
    path = _write(tmp_path, "true.yaml", TRUE)
    assert cli.main(["check", path]) == 0
    out = capsys.readouterr().out
    assert "2/2 expectations met (1/1 regression, 1/1 reference)" in out and "FAILED" not in out
    assert f"reference max_speed_final: {SOURCE}" in out


def test_check_fails_false_expectation(tmp_path, capsys):
    path = _write(tmp_path, "false.yaml", FALSE)
    assert cli.main(["check", path, "-o", str(tmp_path / "kept")]) == 1
    out = capsys.readouterr().out
    assert "1/2 expectations met (0/1 regression, 1/1 reference)" in out
    line = next(line for line in out.splitlines() if "mass_final" in line)
    assert line.split()[:5] == ["regression", "mass_final", "0.0008", "0.0004", "8e-06"]
    assert line.endswith("FAILED")
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


@pytest.mark.slow  # 5 s pytester subprocess; the named-file collection stays in the default run
def test_pytest_collects_scenarios_in_named_directory(pytester):
    """One item per expect: entry, named by its kind; files without expect:, and
    subdirectories, ignored."""
    _write(pytester.path, "true.yaml", TRUE)
    _write(pytester.path, "false.yml", FALSE)
    _write(pytester.path, "plain.yaml", None)
    (pytester.path / "fixtures").mkdir()
    _write(pytester.path / "fixtures", "nested.yaml", FALSE)
    result = pytester.runpytest_subprocess(str(pytester.path), "-p", "no:cacheprovider")
    result.assert_outcomes(passed=3, failed=1)
    result.stdout.fnmatch_lines(
        [
            "*1/2 expectations met*",
            "*regression*mass_final*0.0008*0.0004*FAILED*",
            "FAILED false.yml::regression[[]mass_final[]]*",
        ]
    )
    assert "nested" not in result.stdout.str()


def test_pytest_runs_a_named_file_and_selects_by_kind(pytester):
    """In process (the plugin loaded through its entry point, as in a user's run, and the
    kernels already loaded); the other runs of pytest here are subprocesses."""
    path = _write(pytester.path, "true.yaml", TRUE)
    result = pytester.runpytest(path, "-p", "no:cacheprovider", "-v")
    result.assert_outcomes(passed=2)
    result.stdout.fnmatch_lines(
        [
            "*true.yaml::reference[[]max_speed_final[]] PASSED*",
            "*true.yaml::regression[[]mass_final[]] PASSED*",
        ]
    )
    only = pytester.runpytest(path, "-p", "no:cacheprovider", "-k", "reference")
    only.assert_outcomes(passed=1, deselected=1)


@pytest.mark.slow
def test_pytest_reads_the_yaml_files_of_a_named_directory_as_multilayer_does(pytester):
    """The plugin read every YAML file of a directory named on the command line with
    PyYAML's own parser, without bounds: a data file beside the scenarios 5000 lists deep
    was a ``RecursionError`` that stopped the whole collection (exit 2, no test run), one
    of 2 * 10^6 values took 48 s.  They are read as a scenario is (libyaml, bounded),
    and a file multilayer reads as no scenario is no scenario to collect."""
    _write(pytester.path, "true.yaml", TRUE)
    (pytester.path / "deep.yaml").write_text("[" * 5000 + "]" * 5000)
    (pytester.path / "values.yaml").write_text("expect: [" + ", ".join(["1"] * 2_000_001) + "]\n")
    (pytester.path / "latin1.yaml").write_bytes(b"expect: [caf\xe9]\n")
    result = pytester.runpytest(str(pytester.path), "-p", "no:cacheprovider", "-v")
    result.assert_outcomes(passed=2)
    assert "RecursionError" not in result.stdout.str()


@pytest.mark.slow
def test_pytest_without_arguments_collects_no_yaml(pytester):
    """A plain `pytest` (no paths named) never turns YAML files into scenario runs."""
    _write(pytester.path, "false.yaml", FALSE)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.NO_TESTS_COLLECTED


def test_tiny_scenario_matches_exact_inviscid_solution(tmp_path):
    """The reference values used above are the model's: b(t) = b0 + S t / 70 too."""
    from multilayer import scenario as scenarios
    from multilayer.app import runner
    from multilayer.io.results import open_result

    scenario = scenarios.load(_write(tmp_path, "true.yaml", TRUE))
    runner.run(scenario, tmp_path / "out", quiet=True)
    final = open_result(tmp_path / "out").isel(time=-1)
    interface = float(EXACT.interface(T_END))
    assert np.all(np.abs(final["static_interface"].values - interface) <= H / LAYERS)


def test_a_boundary_layer_comparison_starts_beyond_the_leading_edge(capsys):
    """The similarity solution holds downstream of the smooth-to-rough transition only."""
    entry = (
        "expect=[{kind: reference, exact: {solution: granular_blasius, field: displacement_thickness, "
        "norm: l1}, atol: 0.1, source: Tsang et al. 2019}]"
    )
    path = str(Path(__file__).resolve().parents[1] / "scenarios" / "smooth_to_rough_chute.yaml")
    assert cli.main(["validate", path, "--set", entry]) == 2
    err = capsys.readouterr().err
    assert "expect.0.exact.x_min: granular_blasius holds for x > 0; accepted: a number > 0" in err


def test_a_window_where_the_exact_field_is_0_is_refused_before_running(capsys):
    """The error relative to an exact field that is 0 in the window, 0 / 0: NaN, FAILED after
    the run, with numpy's warning."""
    entry = (
        "[{kind: reference, exact: {solution: coulomb_dam_break, field: h, norm: l1, x_min: 1.9}, "
        "atol: 0.01, source: x}]"
    )
    path = Path(__file__).parents[1] / "scenarios" / "coulomb_dam_break.yaml"
    assert cli.main(["validate", str(path), "--set", f"expect={entry}"]) == 2
    err = capsys.readouterr().err
    assert "expect.0.exact: the exact h is 0 in the window at t = 0.5 s: no error relative to it" in err
