"""`multilayer plot` and `multilayer export --vtk` on real runs."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from multilayer.app import runner
from multilayer.io import scenario as scenarios
from multilayer.io.results import open_result

MATERIAL = {"density": 1500.0, "grain_diameter": 1.0e-3}

# A column slumping down a 25 degree slope: 30 cells x 3 layers.
SLUMP = {
    "name": "slump",
    "slope_deg": 25.0,
    "domain": {"x_min": 0.0, "x_max": 0.3, "cells": 30, "layers": 3},
    "material": MATERIAL,
    "rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01},
    "bed": {"points": [[0.0, 0.01], [0.3, 0.0]]},
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05}],
    "boundaries": {"left": "wall", "right": "outflow"},
    "time": {"end": 0.06, "output_interval": 0.02},
}

# Inviscid simple shear (Bouchut et al. 2016, Prop. 2.2): one column of 20 layers,
# U0(z) = 70 (z - 0.002) above 0.002 m, stopping from below: U0(b(t)) = S t with
# S = g cos(theta) (mu_s - tan(theta)).
SHEAR = {
    "name": "simple-shear",
    "slope_deg": 20.0,
    "domain": {"x_min": 0.0, "x_max": 0.01, "cells": 1, "layers": 20},
    "material": MATERIAL,
    "rheology": {"name": "drucker_prager", "mu_s": 0.5, "nu": 0.0},
    "initial": [
        {
            "shape": "layer",
            "thickness": 0.01,
            "velocity": {"profile": "linear", "shear_rate": 70.0, "from_height": 0.002},
        }
    ],
    "boundaries": {"left": "periodic", "right": "periodic"},
    "time": {"end": 0.2, "output_interval": 0.025},
}


@pytest.fixture(scope="module")
def slump_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    outdir = tmp_path_factory.mktemp("slump")
    runner.run(scenarios.from_dict(SLUMP), outdir, quiet=True)
    return outdir


def _assert_figures(directory: Path, names: list[str]) -> None:
    assert sorted(p.name for p in (directory / "plots").iterdir()) == sorted(names)
    for name in names:
        image = imread(directory / "plots" / name)
        assert image.shape[0] > 300 and image.shape[1] > 500, name
        assert image[..., :3].std() > 0.05, f"{name} is blank"


def test_plot_multi_column_run(slump_dir: Path, cli) -> None:
    result = cli("plot", slump_dir)
    assert result.code == 0, result.err
    _assert_figures(slump_dir, ["section.png", "thickness.png", "front_mass.png"])
    assert "section.png" in result.out


def test_plot_single_column_run(tmp_path: Path, cli) -> None:
    runner.run(scenarios.from_dict(SHEAR), tmp_path, quiet=True)
    # the figure b(t) shows the analytic interface, to within one layer (0.5 mm)
    ds = open_result(tmp_path)
    s = 9.81 * np.cos(np.radians(20)) * (0.5 - np.tan(np.radians(20)))
    np.testing.assert_allclose(ds["static_interface"][:, 0], 0.002 + s * ds["time"] / 70, atol=0.0005)
    assert cli("plot", tmp_path).code == 0
    _assert_figures(
        tmp_path, ["section.png", "thickness.png", "front_mass.png", "profiles.png", "static_interface.png"]
    )


def test_plot_without_a_result_is_an_input_error(tmp_path: Path, cli) -> None:
    result = cli("plot", tmp_path)
    assert result.code == 2
    assert f"{tmp_path / 'result.nc'}: no result file" in result.err


def test_vtk_export_puts_the_layers_at_their_physical_heights(slump_dir: Path, cli) -> None:
    assert cli("export", slump_dir, "--vtk").code == 0
    ds = open_result(slump_dir)
    pvd = ET.parse(slump_dir / "vtk" / "result.pvd").getroot()
    steps = pvd.findall("Collection/DataSet")
    np.testing.assert_allclose([float(s.get("timestep")) for s in steps], ds["time"])
    last = ET.parse(slump_dir / "vtk" / steps[-1].get("file")).getroot()
    assert last.find("StructuredGrid").get("WholeExtent") == "0 30 0 3 0 0"
    points = np.fromstring(last.find(".//Points/DataArray").text, sep=" ").reshape(4, 31, 3)
    cells = {a.get("Name"): np.fromstring(a.text, sep=" ") for a in last.findall(".//CellData/DataArray")}
    final = ds.isel(time=-1)
    np.testing.assert_allclose(points[0, :, 0], np.linspace(0.0, 0.3, 31), atol=1e-15)
    # interior edges sit at the averages of the two neighbouring cells
    bed, h = final["bed"].values, final["h"].values
    np.testing.assert_allclose(points[0, 1:-1, 1], (bed[:-1] + bed[1:]) / 2, atol=1e-15)
    np.testing.assert_allclose(points[3, 1:-1, 1] - points[0, 1:-1, 1], (h[:-1] + h[1:]) / 2, atol=1e-15)
    np.testing.assert_allclose(points[1, 1:-1, 1] - points[0, 1:-1, 1], (h[:-1] + h[1:]) / 6, atol=1e-15)
    np.testing.assert_array_equal(cells["u"], final["u"].values.ravel())
    np.testing.assert_array_equal(cells["h"], np.tile(h, 3))
    assert set(np.unique(cells["static"])) <= {0.0, 1.0}
    assert np.all(cells["static"][cells["u"] != 0.0] == 0.0)  # moving cells are not static
