"""Figures of a result file, drawn with Matplotlib's Agg canvas (no display needed).

Every layer is drawn where it is: cell ``(alpha, i)`` spans
``z = b_i + h_i * sigma_{alpha -/+ 1/2}`` over the cell ``[x_{i-1/2}, x_{i+1/2}]``, with
``z`` normal to the inclined plane (docs/model.md).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr
import yaml
from matplotlib import colormaps
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from multilayer.io.results import open_result

PLOTS_DIR = "plots"
_AT_REST = "0.82"
_VELOCITY = colormaps["viridis"].with_extremes(bad=_AT_REST)
"""Colour map of u; masked cells (static material, u == 0 exactly) are grey."""


def plot_run(directory: str | os.PathLike, times: int = 4) -> list[Path]:
    """Write the figures of ``directory/result.nc`` into ``directory/plots/``.

    Always: ``section.png`` (X-Z section at ``times`` times), ``thickness.png``
    (h(x)) and ``front_mass.png``; for single-column runs also ``profiles.png``
    (u(z) at several times) and ``static_interface.png`` (b(t) and h(t)).
    Returns the paths written.
    """
    ds = open_result(directory)
    out = Path(directory) / PLOTS_DIR
    out.mkdir(exist_ok=True)
    name = yaml.safe_load(ds.attrs["scenario"])["name"]
    figures = {
        "section.png": section_figure(ds, name, times),
        "thickness.png": thickness_figure(ds, name, times + 2),
        "front_mass.png": front_mass_figure(ds, name),
    }
    if ds.sizes["x"] == 1:
        figures["profiles.png"] = profiles_figure(ds, name, times + 2)
        figures["static_interface.png"] = static_interface_figure(ds, name)
    paths = []
    for filename, fig in figures.items():
        fig.savefig(out / filename, dpi=120)
        paths.append(out / filename)
    return paths


def _time_indices(ds: xr.Dataset, n: int) -> np.ndarray:
    """Up to ``n`` output-time indices spread evenly from the first to the last."""
    return np.unique(np.linspace(0, ds.sizes["time"] - 1, n).round().astype(int))


def _staircase(ds: xr.Dataset, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, values) tracing a piecewise-constant cell field as a staircase."""
    return ds["x_bnds"].values.ravel(), np.repeat(values, 2, axis=-1)


def section_figure(ds: xr.Dataset, name: str, times: int = 4) -> Figure:
    """X-Z sections: layers coloured by u, bed, free surface and static interface."""
    picks = _time_indices(ds, times)
    fig = Figure(figsize=(9, 2.2 * len(picks) + 1), layout="constrained")
    axes = fig.subplots(len(picks), 1, sharex=True, sharey=True, squeeze=False)[:, 0]
    u = ds["u"].values[picks]
    vmin, vmax = min(u.min(), 0.0), max(u.max(), 1e-12)
    sig = ds["sigma_bnds"].values
    edges = np.append(sig[:, 0], sig[-1, 1])
    bed = ds["bed"].values
    for ax, k in zip(axes, picks):
        snap = ds.isel(time=k)
        h = snap["h"].values
        z = bed + h * edges[:, None]  # (L+1, N) interface heights
        xs, zs = _staircase(ds, z)
        # odd columns join neighbouring cells: zero width, never seen
        colour = np.ma.masked_all((ds.sizes["layer"], xs.size - 1))
        colour[:, ::2] = np.ma.masked_equal(snap["u"].values, 0.0)  # static: grey
        mesh = ax.pcolormesh(xs, zs, colour, cmap=_VELOCITY, vmin=vmin, vmax=vmax)
        ax.plot(*_staircase(ds, bed), color="k", lw=1.2, label="bed", zorder=3)
        ax.plot(*_staircase(ds, bed + h), color="tab:blue", lw=1.0, label="free surface")
        wet = h > ds["front"].attrs["threshold"]
        static = np.where(wet, bed + snap["static_interface"].values, np.nan)
        ax.plot(*_staircase(ds, static), color="tab:red", lw=1.0, ls="--", label="static / flowing interface")
        ax.set_title(f"t = {float(snap['time']):.3g} s", fontsize="medium")
        ax.set_ylabel("z normal to slope (m)")
    handles, _ = axes[0].get_legend_handles_labels()
    handles.append(Patch(color=_AT_REST, label="at rest (u = 0)"))
    axes[0].legend(handles=handles, loc="upper right", fontsize="small")
    axes[-1].set_xlabel("x along slope (m)")
    fig.colorbar(mesh, ax=list(axes), label="downslope velocity u (m/s)")
    fig.suptitle(f"{name}: X-Z section")
    return fig


def thickness_figure(ds: xr.Dataset, name: str, times: int = 6) -> Figure:
    """Thickness profiles h(x) at several output times."""
    fig = Figure(figsize=(8, 4.5), layout="constrained")
    ax = fig.subplots()
    picks = _time_indices(ds, times)
    marker = "o" if ds.sizes["x"] < 3 else None
    for j, k in enumerate(picks):
        snap = ds.isel(time=k)
        ax.plot(
            ds["x"],
            snap["h"],
            marker=marker,
            color=_shade(j, len(picks)),
            label=f"t = {float(snap['time']):.3g} s",
        )
    ax.set_xlabel("x along slope (m)")
    ax.set_ylabel("thickness h (m)")
    ax.legend(fontsize="small")
    ax.set_title(f"{name}: thickness profiles")
    return fig


def front_mass_figure(ds: xr.Dataset, name: str) -> Figure:
    """Front position and mass against time (mass should stay constant)."""
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    ax_front, ax_mass = fig.subplots(2, 1, sharex=True)
    t = ds["time"].values
    ax_front.plot(t, ds["front"], marker=".")
    ax_front.set_ylabel("front x (m)")
    ax_front.set_title(f"front: h > {ds['front'].attrs['threshold']:g} m", fontsize="medium")
    ax_mass.plot(t, ds["mass"], marker=".", color="tab:green")
    ax_mass.set_ylabel("mass (m$^2$ per unit width)")
    ax_mass.set_xlabel("time t (s)")
    fig.suptitle(f"{name}: front and mass")
    return fig


def profiles_figure(ds: xr.Dataset, name: str, times: int = 6) -> Figure:
    """Velocity profiles u(z) of the first column at several output times."""
    fig = Figure(figsize=(6, 5.5), layout="constrained")
    ax = fig.subplots()
    picks = _time_indices(ds, times)
    for j, k in enumerate(picks):
        snap = ds.isel(time=k, x=0)
        z = float(snap["h"]) * ds["sigma"].values
        ax.plot(
            snap["u"], z, marker=".", color=_shade(j, len(picks)), label=f"t = {float(snap['time']):.3g} s"
        )
    ax.set_xlabel("downslope velocity u (m/s)")
    ax.set_ylabel("height above the bed z - b (m)")
    ax.legend(fontsize="small")
    ax.set_title(f"{name}: velocity profiles")
    return fig


def static_interface_figure(ds: xr.Dataset, name: str) -> Figure:
    """Static/flowing interface b(t) and thickness h(t) of the first column."""
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.subplots()
    col = ds.isel(x=0)
    ax.plot(col["time"], col["h"], color="tab:blue", label="free surface h")
    ax.plot(col["time"], col["static_interface"], color="tab:red", marker=".", label="static interface b(t)")
    ax.set_xlabel("time t (s)")
    ax.set_ylabel("height above the bed (m)")
    ax.legend(fontsize="small")
    ax.set_title(f"{name}: static / flowing interface")
    return fig


def _shade(j: int, n: int) -> tuple[float, float, float, float]:
    """Colour of the ``j``-th of ``n`` curves, early times light, late times dark."""
    return colormaps["viridis_r"](0.15 + 0.85 * j / max(n - 1, 1))
