"""Scenario model: defaults, layer fractions, overrides, line numbers, resolved YAML."""

from __future__ import annotations

import re

import numpy as np
import pytest
import yaml

from multilayer.app import factory
from multilayer.errors import InputError
from multilayer.scenario import Scenario, apply_overrides, from_dict, load


def test_defaults(tiny_scenario):
    sc = from_dict(tiny_scenario)
    assert sc.gravity == 9.81 and sc.source is None
    assert sc.material.particle_density == sc.material.density == 1500.0
    assert [(z.condition, z.x_min, z.x_max) for z in sc.base] == [("no_slip", None, None)]
    assert sc.bed.profile == "flat" and sc.walls is None and sc.expect == []
    assert sc.time.cfl == 0.45
    assert sc.numerics.model_dump() == {
        "vertical_solver": "kernel",
        "transport_solver": "kernel",
        "threads": "auto",
        "order": 2,
        "tolerance": 1e-10,
        "max_iterations": 200,
        "dry_threshold": 1e-6,
        "front_threshold": 1e-3,
    }
    assert sc.rheology.name == "drucker_prager" and sc.rheology.params == {"mu_s": 0.3, "nu": 0.01}


@pytest.mark.parametrize(
    "fractions, layers, expected",
    [
        ("uniform", 4, [0.25, 0.25, 0.25, 0.25]),
        ([0.1, 0.2, 0.7], 3, [0.1, 0.2, 0.7]),
        ({"geometric": 2.0}, 3, [1 / 7, 2 / 7, 4 / 7]),  # l_a proportional to 2**(a-1)
    ],
)
def test_layer_fractions(tiny_scenario, fractions, layers, expected):
    tiny_scenario["domain"].update(layers=layers, layer_fractions=fractions)
    result = np.array(factory.engine_config(from_dict(tiny_scenario)).fractions)
    np.testing.assert_allclose(result, expected, rtol=1e-14)
    assert result.sum() == pytest.approx(1.0, abs=1e-15)


def test_scientific_notation_without_dot_is_a_number(write_scenario, tiny_scenario):
    text = yaml.safe_dump(tiny_scenario).replace("grain_diameter: 0.001", "grain_diameter: 1e-3")
    assert "1e-3" in text
    assert load(write_scenario(text)).material.grain_diameter == 1e-3


def test_overrides(write_scenario, tiny_scenario):
    path = write_scenario(tiny_scenario)
    sc = load(
        path,
        [
            "domain.cells=200",
            "initial.0.height=0.08",
            "walls={name: wall_friction, mu_w: 0.2}",
            "domain.width=0.1",
            "boundaries.right=wall",
        ],
    )
    assert sc.domain.cells == 200 and sc.initial[0].height == 0.08
    assert sc.walls.params == {"mu_w": 0.2} and sc.boundaries.right == "wall"
    assert sc.source == path


def test_apply_overrides_leaves_input_untouched(tiny_scenario):
    data, paths = apply_overrides(tiny_scenario, ["domain.cells=7", "initial.0.height=0.2"])
    assert tiny_scenario["domain"]["cells"] == 40 and data["domain"]["cells"] == 7
    assert paths == [("domain", "cells"), ("initial", 0, "height")]
    assert data["initial"][0]["height"] == 0.2 and tiny_scenario["initial"][0]["height"] == 0.05


def test_set_appends_to_a_list(write_scenario, tiny_scenario):
    """``KEY+=VALUE`` appends: a layer added under the column makes it thicker everywhere."""
    path = write_scenario(tiny_scenario)
    sc = load(path, ["initial+={shape: layer, thickness: 0.002}", "initial.1.thickness=0.003"])
    assert [e.shape for e in sc.initial] == ["rectangle", "layer"] and sc.initial[1].thickness == 0.003
    sc = load(path, ["expect+={kind: regression, quantity: mass_final, value: 0.005, rtol: 1e-9}"])  # created
    assert sc.expect[0].quantity == "mass_final"
    with pytest.raises(InputError, match=r"initial\.1\.thickness \(from --set\): Input should be greater"):
        load(path, ["initial+={shape: layer, thickness: -1}"])


@pytest.mark.parametrize(
    "override, message",
    [
        ("domain", "expected KEY=VALUE"),
        ("domain.cells+=3", "--set domain.cells+=...: domain.cells is not a list; accepted: += on a list"),
        ("initial.3.height=1", "--set initial.3.height: initial has 1 entries; accepted indices: 0..0"),
        ("initial.00.height=1", "initial has 1 entries; accepted indices: 0..0 (without leading zeros)"),
        ("name.first=x", "--set name.first: name is a value, not a mapping"),
        ("domain.cells=[1", "--set domain.cells: malformed YAML value"),
    ],
)
def test_malformed_overrides(write_scenario, tiny_scenario, override, message):
    with pytest.raises(InputError, match=re.escape(message)):
        load(write_scenario(tiny_scenario), [override])


def test_messages_carry_yaml_lines(write_scenario):
    text = """\
name: lines
domain:
  x_min: 0.0
  x_max: 1.0
  cells: 10
material: {density: 1500, grain_diameter: 1.0e-3}
rheology: {name: jop_mu_i, mu_s: 0.38, mu_2: 0.64, I_0: -0.3}
initial:
  - {shape: layer, thickness: 0.01}
  - shape: rectangle
    x_min: 0.5
    x_max: 0.2
    height: 0.1
time: {end: 1.0, output_interval: 0.1, cfll: 0.4}
"""
    path = write_scenario(text)
    with pytest.raises(InputError) as info:
        load(path)
    lines = str(info.value).splitlines()
    assert (
        f"{path}: rheology (line 7): jop_mu_i: I_0 must be > 0, got -0.3; accepted: "
        "jop_mu_i(mu_s: float, mu_2: float, I_0: float, mu_start: float | None = None, mu_inf: float = 0.0)"
        in lines
    )
    assert (
        f"{path}: initial.1.x_max (line 12): x_max = 0.2 is not > x_min = 0.5; "
        "accepted: a number > x_min = 0.5" in lines
    )
    assert f"{path}: time.cfll (line 14): unknown key; accepted: end, cfl, output_interval" in lines


def test_duplicate_keys_are_rejected(write_scenario):
    with pytest.raises(InputError, match=r"domain \(line 3\): duplicate key.*first at line 2"):
        load(write_scenario("name: dup\ndomain: {x_min: 0}\ndomain: {x_min: 1}\n"))


def test_resolved_yaml_round_trip(tiny_scenario):
    tiny_scenario.update(
        walls={"name": "wall_friction", "mu_w": 0.2},
        domain={**tiny_scenario["domain"], "width": 0.1},
        base=[{"condition": "no_slip"}, {"condition": "coulomb", "mu": 0.35, "x_max": 0.1}],
        bed={"points": [[0.0, 0.0], [0.5, -0.01]]},
        initial=[
            {
                "shape": "profile",
                "points": [[0.0, 0.02], [0.2, 0.0]],
                "velocity": {"profile": "linear", "shear_rate": 5.0},
            }
        ],
        expect=[
            {"kind": "regression", "quantity": "runout", "value": 0.1, "atol": 0.01},
            {"kind": "reference", "quantity": "mass_final", "value": 0.1, "rtol": 0.1, "source": "a paper"},
        ],
    )
    sc = from_dict(tiny_scenario)
    again = Scenario.model_validate(yaml.safe_load(sc.resolved_yaml()))
    assert again.model_dump() == sc.model_dump()
    resolved = yaml.safe_load(sc.resolved_yaml())
    assert resolved["rheology"] == {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01}
    assert resolved["bed"]["profile"] == "points"
    assert resolved["initial"][0]["velocity"]["from_height"] == 0.0
    assert resolved["material"]["particle_density"] == 1500.0


@pytest.mark.parametrize("value", [0, -2, 1.5, "many", True])
def test_numerics_threads_accepts_auto_or_a_positive_integer(write_scenario, tiny_scenario, value):
    assert load(write_scenario(tiny_scenario), ["numerics.threads=2"]).numerics.threads == 2
    with pytest.raises(
        InputError, match=r"numerics\.threads \(from --set\): got .*; accepted: auto or an integer >= 1"
    ):
        load(write_scenario(tiny_scenario), [f"numerics.threads={value}"])


@pytest.mark.parametrize(
    "overrides",
    [
        ["model.pressure=non_hydrostatic", "model.pressure_layers=0"],
        ["model.pressure=non_hydrostatic", "model.pressure_layers=5"],  # more than the 4 layers
        ["model.pressure=non_hydrostatic", "model.pressure_layers=1.5"],
        ["model.pressure=non_hydrostatic", "model.pressure_layers=true"],
        ["model.pressure_layers=2"],  # without the non-hydrostatic pressure
    ],
)
def test_pressure_layers_are_an_integer_up_to_the_layers(write_scenario, tiny_scenario, overrides):
    tiny_scenario["domain"]["layers"] = 4
    path = write_scenario(tiny_scenario)
    assert factory.engine_config(load(path, ["model.pressure=non_hydrostatic"])).pressure.options == {
        "pressure_layers": 4,  # the default: min(4, layers)
        "vertical_shear": False,
    }
    sc = load(path, ["model.pressure=non_hydrostatic", "model.pressure_layers=2"])
    assert sc.model.options == {"pressure_layers": 2} and "pressure_layers: 2" in sc.resolved_yaml()
    with pytest.raises(InputError, match=r"model\.pressure_layers \(from --set\): .*accepted: an integer"):
        load(path, overrides)


@pytest.mark.parametrize(
    "overrides",
    [
        ["model.pressure=non_hydrostatic", "model.vertical_shear=1"],
        ["model.pressure=non_hydrostatic", "model.vertical_shear=yes please"],
        ["model.vertical_shear=true"],  # without the non-hydrostatic pressure
    ],
)
def test_vertical_shear_is_true_or_false_with_the_non_hydrostatic_pressure(
    write_scenario, tiny_scenario, overrides
):
    path = write_scenario(tiny_scenario)
    sc = load(path, ["model.pressure=non_hydrostatic", "model.vertical_shear=true"])
    assert factory.engine_config(sc).pressure.options["vertical_shear"] is True
    with pytest.raises(
        InputError,
        match=r"model\.vertical_shear \(from --set\): .*accepted: true or false, with pressure: non_hydr",
    ):
        load(path, overrides)


@pytest.mark.parametrize("width", [5e-324, 1e-6])
def test_a_channel_narrower_than_a_grain_is_refused(tiny_scenario, width):
    """``domain.width: 5e-324`` with walls ran to its end, exit 0, with numpy's "invalid
    value" warning: the walls' ``2 / W`` was infinite and their forces NaN.  A channel
    narrower than one grain is refused, naming the width and the grain diameter."""
    tiny_scenario.update(
        walls={"name": "wall_friction", "mu_w": 0.2}, domain={**tiny_scenario["domain"], "width": width}
    )
    with pytest.raises(InputError, match=r"domain\.width: a channel .* m wide, narrower than one grain"):
        from_dict(tiny_scenario)
    tiny_scenario["domain"]["width"] = tiny_scenario["material"]["grain_diameter"]
    from_dict(tiny_scenario)


def test_grains_longer_than_the_domain_are_refused(tiny_scenario):
    """``material.grain_diameter: 1e308`` with the mu(I) law printed numpy's overflow warning
    and stopped the run at its first step blaming the law (its viscosity NaN).  A grain
    longer than the domain is refused, naming the diameter and the domain's length."""
    tiny_scenario["material"]["grain_diameter"] = 1e308
    with pytest.raises(InputError, match=r"material\.grain_diameter: grains 1e\+308 m across, longer than"):
        from_dict(tiny_scenario)
    tiny_scenario["material"]["grain_diameter"] = 0.5  # the domain's length
    from_dict(tiny_scenario)


@pytest.mark.parametrize("ending", ["/", "/."])
def test_a_file_name_ending_in_a_slash_is_refused_naming_the_key(
    tmp_path, write_scenario, tiny_scenario, ending
):
    """``p.csv/`` names a directory, never a file (the system refuses to open it, "Not a
    directory"), but pathlib drops the ending, so that ``bed.file: p.csv/``, an initial
    ``file: p.csv/`` and ``multilayer.load("s.yaml/")`` read the file before it: refused,
    naming the key and the name as given."""
    import multilayer

    (tmp_path / "p.csv").write_text("x (m), h (m)\n0, 0.01\n1, 0.01\n", encoding="utf-8")
    path = write_scenario(tiny_scenario)
    with pytest.raises(NotADirectoryError):
        open(f"{tmp_path}/p.csv{ending}")  # noqa: SIM115 - the system's answer (a str: pathlib drops it)
    said = f"p.csv{ending}: a path ending in '{ending}', which names a directory, never a file"
    for key in (
        f"bed={{profile: file, file: p.csv{ending}}}",
        f"initial=[{{shape: profile, file: p.csv{ending}}}]",
    ):
        with pytest.raises(InputError, match=re.escape(said)) as refused:
            load(path, [key])
        assert ("bed.file" if key.startswith("bed") else "initial.0.file") in str(refused.value)
    with pytest.raises(InputError, match=re.escape(f"scenario: {path}{ending}: a path ending in '{ending}'")):
        multilayer.load(f"{path}{ending}")
