"""`multilayer plot` and `multilayer export --vtk` on real runs."""

from __future__ import annotations

import gc
import os
import shutil
import subprocess
import sys
import time
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr
from matplotlib import animation
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.image import imread
from PIL import Image

from multilayer import scenario as scenarios
from multilayer.app import runner
from multilayer.io import export, plotting
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


FIGURES = ["section", "thickness", "front", "mass", "profiles", "static_interface", "force"]


def _assert_figures(directory: Path, names: list[str], fmt: str = "png") -> None:
    assert sorted(p.name for p in (directory / "plots").glob(f"*.{fmt}")) == sorted(
        f"{n}.{fmt}" for n in names
    )
    for name in names:
        image = imread(directory / "plots" / f"{name}.png")
        assert image.shape[0] > 300 and image.shape[1] > 500, name
        assert image[..., :3].std() > 0.05, f"{name} is blank"


@pytest.mark.slow  # the animation: some 4 s; the figures are drawn in the default run
def test_plot_multi_column_run_with_animation(slump_dir: Path, cli, monkeypatch) -> None:
    """The figures, and an animation with one frame per output time."""
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)  # GIF, always available
    result = cli("plot", slump_dir, "--animate")
    assert result.code == 0, result.err
    gif = slump_dir / "plots" / "section.gif"
    assert "section.png" in result.out and str(gif) in result.out
    with Image.open(gif) as movie:
        assert movie.n_frames == open_result(slump_dir).sizes["time"] == 4
    gif.unlink()
    _assert_figures(slump_dir, FIGURES)


@pytest.mark.slow
def test_an_animation_refused_its_file_says_so_in_one_message(slump_dir: Path, cli, monkeypatch) -> None:
    """``plots/section.gif`` a directory: exit 2 naming it, and nothing more (the animation
    was made before its file was refused, collected unsaved, and Matplotlib warned
    "Animation was deleted without rendering anything" under the message)."""
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)
    (slump_dir / "plots" / "section.gif").mkdir(parents=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = cli("plot", slump_dir, "--animate")
        gc.collect()
    assert result.code == 2
    assert "plots/section.gif: exists and is not a regular file (a directory" in result.err
    assert len(result.err.strip().splitlines()) == 1, result.err
    assert not [w for w in caught if "Animation" in str(w.message)], [str(w.message) for w in caught]


def test_section_states_slope_and_vertical_exaggeration(slump_dir: Path) -> None:
    ds = open_result(slump_dir)
    fig = plotting.section_figure(ds, "slump", times=2)
    # x spans 0.3 m, z about 0.06 m: 0.22 * 0.3 / 0.06 = 1.1, rounded down to 1; 0.6 m wide: 2
    assert plotting.vertical_exaggeration(0.3, 0.06) == 1 and plotting.vertical_exaggeration(0.6, 0.06) == 2
    assert plotting.vertical_exaggeration(1.5, 0.15) == 2 and plotting.vertical_exaggeration(10, 0.05) == 20
    (x0, x1), (z0, z1) = plotting._section_limits(ds)
    factor = plotting.vertical_exaggeration(x1 - x0, z1 - z0)
    title = fig.get_suptitle()
    assert "inclined at 25 deg" in title and f"vertical exaggeration x{factor:g}" in title
    assert all(ax.get_aspect() == factor for ax in fig.axes[:2])
    mass = plotting.mass_figure(ds, "slump")
    assert mass.axes[0].get_ylabel() == "volume per unit width V (m$^2$)"


def _bed_and_pile(moving: slice) -> xr.Dataset:
    """A 2 mm bed layer on 100 cells of 1 cm over x in [0, 1] m, 2 cm thick and moving on
    ``moving`` at the last of two output times; at rest everywhere at the first."""
    edges = np.linspace(0.0, 1.0, 101)
    h = np.full((2, 100), 0.002)
    u = np.zeros((2, 2, 100))
    h[:, moving] = 0.02
    u[1, :, moving] = 0.5
    return xr.Dataset(
        {
            "h": (("time", "x"), h),
            "u": (("time", "layer", "x"), u),
            "bed": ("x", np.zeros(100)),
            "x_bnds": (("x", "nv"), np.column_stack([edges[:-1], edges[1:]])),
            "front": ("time", np.zeros(2), {"threshold": 1e-3}),
            "sigma_bnds": (("layer", "nv"), [[0.0, 0.5], [0.5, 1.0]]),
            "static_interface": (("time", "x"), np.where(u[:, 0] == 0.0, h, 0.0)),
        },
        coords={"time": [0.0, 1.0]},
        attrs={"scenario": "slope_deg: 0.0"},
    )


def test_section_is_cropped_to_where_the_material_moves() -> None:
    """A bed layer that never moves is left out: the section spans the moving cells, 0.2 to
    0.4 m, with a margin of 10 % of that span or two cells, whichever is larger, inside
    the domain; its exaggeration follows the aspect of that window."""
    ds = _bed_and_pile(slice(20, 40))
    assert plotting.material_span(ds) == pytest.approx((0.18, 0.42))
    ds = _bed_and_pile(slice(0, 90))
    assert plotting.material_span(ds) == pytest.approx((0.0, 0.99))  # 0.09 m margin, cut at 0
    (x0, x1), (z0, z1) = plotting._section_limits(ds)
    assert (z0, z1) == pytest.approx((-0.001, 0.021))  # the thickest material, 5 % padding
    # 0.99 m by 0.022 m: a factor 0.22 * 0.99 / 0.022 = 9.9, rounded down to 5
    fig = plotting.section_figure(ds, "pile", times=2)
    assert fig.axes[0].get_xlim() == pytest.approx((0.0, 0.99)) and fig.axes[0].get_aspect() == 5
    still = _bed_and_pile(slice(20, 40))
    still["u"][:] = 0.0  # nothing moves: where the material is, the whole domain here
    assert plotting.material_span(still) == (0.0, 1.0)


def test_plot_xlim(slump_dir: Path, cli) -> None:
    """``--xlim X0 X1`` sets the section's x range; one outside the domain is exit code 2."""
    ds = open_result(slump_dir)
    fig = plotting.section_figure(ds, "slump", times=2, xlim=(0.05, 0.25))
    assert fig.axes[0].get_xlim() == (0.05, 0.25)
    result = cli("plot", slump_dir, "--xlim", "0.5", "0.9")
    assert result.code == 2
    assert "--xlim 0.5 0.9: accepted: X0 < X1 (m), overlapping the domain [0, 0.3]" in result.err
    assert cli("plot", slump_dir, "--xlim", "0.2", "0.1").code == 2


def test_the_force_figure_draws_the_interval_means_and_the_seismic_force(slump_dir: Path) -> None:
    """The total downslope force is the sum of its parts, the seismic force its departure
    from the weight, drawn as steps over the output intervals."""
    ds = open_result(slump_dir)
    fig = plotting.force_figure(ds, "slump")
    forces, seismic = fig.axes[0], fig.axes[1]
    lines = {line.get_label(): line for line in forces.get_lines()}
    total = sum(ds[k].values for k in ("bed_force_x", "wall_force_x", "end_force_x", "pressure_force_x"))
    np.testing.assert_array_equal(lines["total F_x"].get_ydata(), np.repeat(total[1:], 2))
    np.testing.assert_array_equal(lines["total F_x"].get_xdata(), np.repeat(ds["time"].values, 2)[1:-1])
    downslope = {line.get_label(): line for line in seismic.get_lines()}["downslope"]
    np.testing.assert_allclose(
        downslope.get_ydata(), np.repeat(total[1:] - ds["gravity_force_x"].values[1:], 2), rtol=1e-15
    )
    assert seismic.get_ylabel() == "F - M g (N/m)"


def test_front_velocity_is_the_time_derivative_of_the_front() -> None:
    t = np.linspace(0.0, 1.0, 11)
    ds = xr.Dataset({"front": ("time", 0.1 + 0.5 * t - 0.2 * t**2)}, coords={"time": t})
    # centred differences are exact for a parabola inside; one-sided ones at the ends
    np.testing.assert_allclose(plotting.front_velocity(ds)[1:-1], 0.5 - 0.4 * t[1:-1], rtol=1e-12)


@pytest.mark.slow
def test_plot_at_chosen_positions_and_formats(slump_dir: Path, cli, tmp_path: Path) -> None:
    result = cli("plot", slump_dir, "--at", "0.055", "--at", "0.0551", "--at", "0.205", "--format", "svg")
    assert result.code == 0, result.err
    names = sorted(p.name for p in (slump_dir / "plots").glob("*.svg"))
    assert names == sorted(f"{n}.svg" for n in FIGURES)
    assert (slump_dir / "plots" / "profiles.svg").read_text().lstrip().startswith("<?xml")
    ds = open_result(slump_dir)
    assert plotting.column_indices(ds, [0.055, 0.0551, 0.205, 0.3]) == [5, 20, 29]  # same cell once
    result = cli("plot", slump_dir, "--at", "0.5")
    assert result.code == 2
    assert "--at 0.5: outside the domain; accepted: a position in [0, 0.3] (m)" in result.err
    assert cli("plot", slump_dir, "--format", "jpg").code == 2


@pytest.mark.skipif(not animation.writers.is_available("ffmpeg"), reason="ffmpeg is not installed")
def test_mp4_animation_with_ffmpeg(slump_dir: Path, cli) -> None:
    assert cli("plot", slump_dir, "--animate").code == 0
    mp4 = slump_dir / "plots" / "section.mp4"
    frames = subprocess.run(
        [
            "ffprobe",
            "-v",
            "error",
            "-count_frames",
            "-select_streams",
            "v:0",
            "-show_entries",
            "stream=nb_read_frames",
            "-of",
            "csv=p=0",
            str(mp4),
        ],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    assert int(frames) == 4


def test_plot_periodic_multi_column_run(tmp_path: Path, cli) -> None:
    """Inviscid simple shear on 4 periodic columns: every column stops from below as
    U0(b(t)) = S t (Bouchut et al. 2016, Prop. 2.2); the profile figures show it anywhere."""
    runner.run(
        scenarios.from_dict(SHEAR, overrides=["domain.cells=4", "domain.x_max=0.04"]), tmp_path, quiet=True
    )
    ds = open_result(tmp_path)
    s = 9.81 * np.cos(np.radians(20)) * (0.5 - np.tan(np.radians(20)))
    exact = 0.002 + s * ds["time"].values / 70
    for i in range(4):
        np.testing.assert_allclose(ds["static_interface"][:, i], exact, atol=0.0005)
    assert plotting.representative_columns(ds) == [0, 2, 3]  # 3 of the 4
    fig = plotting.profiles_figure(ds, "shear", [1, 3], times=3)
    assert [ax.get_title() for ax in fig.axes] == ["x = 0.015 m (cell 1)", "x = 0.035 m (cell 3)"]
    final = fig.axes[1].get_lines()[2]  # last of the 3 times at cell 3
    np.testing.assert_array_equal(final.get_xdata(), ds["u"].values[-1, :, 3])
    np.testing.assert_allclose(final.get_ydata(), ds["h"].values[-1, 3] * ds["sigma"].values)
    b_t = plotting.static_interface_figure(ds, "shear", [2]).axes[0].get_lines()[1]
    np.testing.assert_array_equal(b_t.get_ydata(), ds["static_interface"].values[:, 2])


def test_representative_columns_spread_over_the_deposit(slump_dir: Path) -> None:
    ds = open_result(slump_dir)
    wet = np.flatnonzero(ds["h"].values[-1] > ds["front"].attrs["threshold"])
    picks = plotting.representative_columns(ds)
    assert len(picks) == 3 and set(picks) <= set(wet) and picks == sorted(picks)
    assert picks[0] < np.median(wet) < picks[-1]


@pytest.mark.slow  # a whole run and every figure, for one column
def test_plot_single_column_run(tmp_path: Path, cli) -> None:
    runner.run(scenarios.from_dict(SHEAR), tmp_path, quiet=True)
    # the figure b(t) shows the analytic interface, to within one layer (0.5 mm)
    ds = open_result(tmp_path)
    s = 9.81 * np.cos(np.radians(20)) * (0.5 - np.tan(np.radians(20)))
    np.testing.assert_allclose(ds["static_interface"][:, 0], 0.002 + s * ds["time"] / 70, atol=0.0005)
    assert cli("plot", tmp_path).code == 0
    _assert_figures(tmp_path, FIGURES)


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


@pytest.mark.parametrize("layered", [False, True])
def test_vtk_export_of_a_mixture_holds_its_packing_and_pore_pressure(slump_dir: Path, layered: bool) -> None:
    """A grain-fluid mixture's ``phi`` and excess pore pressure are cell data of its VTK
    files, each layer's where the result holds them per layer, else the column's: the
    export wrote ``u``, ``h`` and ``static`` only."""
    snap = open_result(slump_dir).isel(time=-1).load()
    layers, cells = snap.sizes["layer"], snap.sizes["x"]
    phi = np.linspace(0.5, 0.6, cells)
    pressure = np.linspace(-10.0, 30.0, cells)
    snap["phi"], snap["pore_pressure_excess"] = ("x", phi), ("x", pressure)
    if layered:
        snap["phi_layer"] = (("layer", "x"), phi + np.arange(layers)[:, None] * 1e-3)
        snap["pore_pressure_layer"] = (("layer", "x"), pressure * (1.0 - np.arange(layers)[:, None] / layers))
    grid = ET.fromstring(export.structured_grid(snap))
    data = {a.get("Name"): np.fromstring(a.text, sep=" ") for a in grid.findall(".//CellData/DataArray")}
    assert sorted(data) == ["h", "phi", "pore_pressure_excess", "static", "u"]
    expected_phi = snap["phi_layer"].values if layered else np.tile(phi, (layers, 1))
    expected_p = snap["pore_pressure_layer"].values if layered else np.tile(pressure, (layers, 1))
    np.testing.assert_array_equal(data["phi"], expected_phi.ravel())
    np.testing.assert_array_equal(data["pore_pressure_excess"], expected_p.ravel())


def test_an_export_stopped_half_way_leaves_no_series_of_two_runs(
    slump_dir: Path, tmp_path: Path, cli, monkeypatch
):
    """Exported again after another run into the directory, the export stopped half-way (a
    Ctrl-C, a full disk): the earlier ``result.pvd`` listed this run's first files and the
    earlier run's others, one time series in ParaView.  It goes before the first file; the
    series is written once every file it lists is."""
    shutil.copy(slump_dir / "result.nc", tmp_path / "result.nc")
    assert cli("export", tmp_path, "--vtk").code == 0
    whole, written = export.structured_grid, []

    def stopped(snap):
        if len(written) == 2:
            raise KeyboardInterrupt
        written.append(1)
        return whole(snap)

    monkeypatch.setattr(export, "structured_grid", stopped)
    assert cli("export", tmp_path, "--vtk").code == 130
    assert not (tmp_path / "vtk" / "result.pvd").exists()
    assert sorted(path.name for path in (tmp_path / "vtk").iterdir()) == [
        "result_0000.vts",
        "result_0001.vts",
    ]


def test_an_export_after_a_longer_run_leaves_none_of_its_files(slump_dir: Path, tmp_path: Path, cli):
    """The files of an earlier export past this run's last output time were left beside
    this run's: ParaView's group of ``result_..vts`` read them as one series of two runs."""
    shutil.copy(slump_dir / "result.nc", tmp_path / "result.nc")
    (tmp_path / "vtk").mkdir()
    (tmp_path / "vtk" / "result_0999.vts").write_text("an earlier run's")
    (tmp_path / "vtk" / "notes.txt").write_text("the user's")
    assert cli("export", tmp_path, "--vtk").code == 0
    assert not (tmp_path / "vtk" / "result_0999.vts").exists() and (tmp_path / "vtk" / "notes.txt").exists()


@pytest.mark.slow
def test_a_plot_stopped_half_way_leaves_no_figures_of_two_runs(
    slump_dir: Path, tmp_path: Path, cli, monkeypatch
):
    """Plotted again after another run into the directory, the plot stopped in its third
    figure (a Ctrl-C, a full disk): plots/ held this run's first two figures beside the
    earlier run's others (each whole and titled: read as one run), and the third written
    half-way.  The figures of the set go first; each is written whole."""
    from matplotlib.figure import Figure

    shutil.copy(slump_dir / "result.nc", tmp_path / "result.nc")
    assert cli("plot", tmp_path).code == 0
    whole, written = Figure.savefig, []

    def stopped(fig, path, **options):
        if len(written) == 2:
            Path(path).write_bytes(b"\x89PNG half")
            raise KeyboardInterrupt
        written.append(Path(path).name)
        return whole(fig, path, **options)

    monkeypatch.setattr(Figure, "savefig", stopped)
    assert cli("plot", tmp_path).code == 130
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == ["section.png", "thickness.png"]
    assert written == [f".section.partial.{os.getpid()}.png", f".thickness.partial.{os.getpid()}.png"]


@pytest.mark.slow
def test_figures_and_an_animation_drawn_from_an_earlier_result_are_removed_by_the_next_plot(
    slump_dir: Path, tmp_path: Path, cli, monkeypatch
):
    """Plotted with ``--animate`` and as svg, then run again into the directory (or resumed)
    and plotted as png: the animation and the svg figures of the earlier result stayed beside
    the new figures, read as drawn from the result there now.  Each figure records the
    SHA-256 of the result it is drawn from; the next plot removes those that do not record
    the result there now (in any format) and says so; those drawn from it stay, whatever
    their format and their times (a copy of the directory, a result of a time in the
    future: times of modification decided), and so does a file of another name."""
    monkeypatch.setattr(animation.writers, "is_available", lambda name: False)  # GIF, always available
    run = tmp_path / "run"
    run.mkdir()
    shutil.copy(slump_dir / "result.nc", run / "result.nc")
    plots = run / "plots"
    assert cli("plot", run, "--format", "pdf").code == 0
    (plots / "notes.txt").write_bytes(b"kept")
    (plots / "front.csv").write_bytes(b"kept: no figure of plot's")
    future = time.time() + 10**6  # a result of a time in the future: the figures stay
    os.utime(run / "result.nc", (future, future))
    copy = tmp_path / "copy"
    shutil.copytree(run, copy)  # times not kept
    again = cli("plot", copy)
    assert again.code == 0 and again.err == "", again.err
    assert {"front.pdf", "front.png", "notes.txt"} <= {p.name for p in (copy / "plots").iterdir()}
    # an animation and svg figures, then the result changed (run again, resumed, damaged)
    assert cli("plot", run, "--format", "svg", "--animate").code == 0
    assert (plots / "section.gif").is_file() and plotting.records(
        plots / "section.gif", plotting.drawn_from(run / "result.nc")
    )
    with netCDF4.Dataset(run / "result.nc", "a") as ds:  # another run's wall time: another file
        ds.wall_time_s = float(ds.wall_time_s) + 1.0
    stale = (run / "result.nc").stat().st_mtime - 100.0  # figures newer than the result: removed anyway
    for figure in plots.iterdir():
        os.utime(figure, (stale + 200.0, stale + 200.0))
    again = cli("plot", run)
    assert again.code == 0, again.err
    figures = sorted(p.name for p in plots.iterdir())
    assert not {"section.gif", "mass.svg", "front.pdf"} & set(figures)
    assert {"notes.txt", "front.csv", "section.png", "mass.png"} <= set(figures)
    removed = [f"{stem}.{fmt}" for stem in FIGURES for fmt in ("pdf", "svg")] + ["section.gif"]
    note = f"removed {', '.join(sorted(removed))} from {plots}: not drawn from the result.nc there now"
    assert f"multilayer: warning: {note}" in again.err


@pytest.mark.parametrize("figure", ["profiles", "static_interface"])
def test_a_long_title_is_wrapped_within_the_figure(slump_dir: Path, figure: str) -> None:
    """One column: the figure is 4.8 inches wide and a long scenario name with the figure's
    description was cut at both ends."""
    ds = open_result(slump_dir)
    draw = getattr(plotting, f"{figure}_figure")
    fig = draw(ds, "erodible-bed-collapse-coulomb", [10])
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    title = fig._suptitle.get_window_extent(canvas.get_renderer())
    frame = fig.bbox
    assert frame.x0 <= title.x0 and title.x1 <= frame.x1, (title, frame)


@pytest.mark.slow
def test_plot_prints_no_warning_of_the_colour_mapping(slump_dir: Path, cli) -> None:
    """The section's colours are masked cells (at rest, the joins between cells): the values
    under the mask were uninitialised memory, which the colour mapping normalised too
    (numpy's 'overflow encountered in multiply')."""
    ds = open_result(slump_dir)
    fig = plotting.section_figure(ds, "slump", times=2)
    for mesh in (c for ax in fig.axes for c in ax.collections if hasattr(c, "get_array")):
        values = mesh.get_array()
        if values is not None:
            assert np.isfinite(np.ma.getdata(values)).all()
    result = cli("plot", slump_dir, "--at", "0.05")
    assert result.code == 0 and result.err == "", result.err


def test_an_mplbackend_matplotlib_refuses_is_named_not_a_traceback(slump_dir: Path, tmp_path: Path) -> None:
    """``MPLBACKEND=nonsense``: Matplotlib's import raised ValueError (a traceback, exit 1),
    though the figures are drawn on the Agg canvas whatever backend it names."""
    import os

    shutil.copy(slump_dir / "result.nc", tmp_path / "result.nc")
    command = [sys.executable, "-m", "multilayer", "plot", str(tmp_path)]
    done = subprocess.run(
        command, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "nonsense"}
    )
    assert done.returncode == 2 and "Traceback" not in done.stderr
    assert done.stderr.startswith(
        "multilayer: error: environment variable MPLBACKEND='nonsense': Matplotlib "
    )
    assert not (tmp_path / "plots").exists()
