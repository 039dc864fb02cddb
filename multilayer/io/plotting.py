"""Figures and animations of a result file, drawn with Matplotlib's Agg canvas (no display).

Every layer is drawn where it is: cell ``(alpha, i)`` spans
``z = b_i + h_i * sigma_{alpha -/+ 1/2}`` over the cell ``[x_{i-1/2}, x_{i+1/2}]``, with
``x`` along the inclined plane and ``z`` normal to it (docs/model.md).  The figures and
what they show are listed in docs/results.md.

The result file is checked first (:func:`multilayer.io.result_check.check_result`): a
truncated, damaged or still running result is refused.  The records of a failed or
interrupted run are drawn, and :func:`plot_run` returns a note saying how the run ended.
"""

from __future__ import annotations

import hashlib
import math
import os
import textwrap
from collections.abc import Sequence
from functools import partial
from pathlib import Path

import numpy as np
import xarray as xr
import yaml
from matplotlib import animation, colormaps
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.collections import QuadMesh
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from PIL import Image

from multilayer.errors import InputError
from multilayer.io.disk import writable, writable_directory, write_whole
from multilayer.io.netcdf_layout import declared_size
from multilayer.io.result_check import ending
from multilayer.io.results import RESULT_FILE, open_result, seismic_force

PLOTS_DIR = "plots"
_AT_REST = "0.82"
_VELOCITY = colormaps["viridis"].with_extremes(bad=_AT_REST)
"""Colour map of u; masked cells (static material, u == 0 exactly) are grey."""
_REPRESENTATIVE = 3
"""Number of columns drawn in the profile figures when no ``--at`` is given."""
MAX_TIMES = 12
"""Most output times (``--times``) and columns (``--at``) drawn in one figure."""
MAX_FRAMES = 600
"""Most frames of an animation (one minute at 10 frames per second): output times spread
evenly over the run when it has more."""


def plot_run(
    directory: str | os.PathLike,
    times: int = 4,
    at: Sequence[float] = (),
    fmt: str = "png",
    animate: bool = False,
    xlim: Sequence[float] | None = None,
) -> tuple[list[Path], list[str]]:
    """Write the figures of ``directory/result.nc`` into ``directory/plots/``.

    ``section`` (X-Z section at ``times`` times), ``thickness`` (h(x)), ``front``
    (x_f(t) and u_f(t)), ``mass`` (volume per unit width), ``profiles`` (u(z) at the
    columns ``at``, default: :func:`representative_columns`) and ``static_interface``
    (b(t) and h(t) at the same columns), ``force`` (the forces on the bed and the walls,
    :func:`force_figure`), for a grain–fluid mixture ``mixture`` (phi(x) and the basal
    excess pore pressure), as ``fmt`` files; with ``animate`` also the section over time
    (:func:`animate_section`).  The section, its animation and the thickness are drawn
    over ``xlim`` (m), by default where the material is (:func:`material_span`).  Returns
    the paths written and
    notes on how the run ended if it did not complete (module docstring).
    """
    if not 1 <= times <= MAX_TIMES or len(at) > MAX_TIMES:
        given = f"--times {times}" if not 1 <= times <= MAX_TIMES else f"{len(at)} --at positions"
        raise InputError(f"{given}: accepted: 1 to {MAX_TIMES} times and at most {MAX_TIMES} --at positions")
    ds = open_result(directory)
    xlim = checked_xlim(ds, xlim)
    end = ending(ds.attrs)
    notes = [f"{end}; drawn up to t = {float(ds['time'][-1]):.6g} s"] if end else []
    out = writable_directory(Path(directory) / PLOTS_DIR)
    source = drawn_from(Path(directory) / RESULT_FILE)
    if stale := remove_stale(out, RUN_FIGURES, source):
        notes.append(f"removed {', '.join(stale)} from {out}: not drawn from the {RESULT_FILE} there now")
    name = yaml.safe_load(ds.attrs["scenario"])["name"]
    columns = column_indices(ds, at) if at else representative_columns(ds)
    figures = {
        "section": section_figure(ds, name, times, xlim),
        "thickness": thickness_figure(ds, name, times + 2, xlim),
        "front": front_figure(ds, name),
        "mass": mass_figure(ds, name),
        "profiles": profiles_figure(ds, name, columns, times + 2),
        "static_interface": static_interface_figure(ds, name, columns),
    }
    if "bed_force_x" in ds:  # files written before the forces lack them
        figures["force"] = force_figure(ds, name)
    if "phi" in ds:
        figures["mixture"] = mixture_figure(ds, name, times + 2)
    paths = save_figures(out, figures, fmt, RUN_FIGURES, source)
    if animate:
        paths.append(animate_section(ds, name, out / "section", xlim=xlim, source=source))
    return paths, notes


RUN_FIGURES = ("section", "thickness", "front", "mass", "profiles", "static_interface", "force", "mixture")
"""The stems of the figures :func:`plot_run` may write (``force`` and ``mixture`` where the
result holds them)."""


def drawn_from(path: Path) -> str:
    """What a figure drawn from the file ``path`` records of it, in its metadata
    (:data:`METADATA_KEYS`; an animation's comment): its name and the SHA-256 of its bytes,
    those its header declares (:func:`~multilayer.io.netcdf_layout.declared_size`; a
    terabyte of zeros appended to the file held ``plot`` for hours).  A run again or
    resumed into the directory, a copy of the file or a damaged one changes it; times of
    modification did not tell (a file from the future, a copy that kept them or not)."""
    size, declared = path.stat().st_size, declared_size(path)
    left, digest = size if declared is None else min(size, declared), hashlib.sha256()
    with path.open("rb") as stream:
        while left > 0 and (chunk := stream.read(min(left, 2**20))):
            digest.update(chunk)
            left -= len(chunk)
    return f"drawn from {path.name} of SHA-256 {digest.hexdigest()}"


METADATA_KEYS = {"png": "Comment", "pdf": "Subject", "svg": "Description"}
"""The metadata entry of each figure format that holds :func:`drawn_from` (a PNG text
chunk, the PDF's subject, the SVG's Dublin Core description), as Matplotlib writes them."""


ANIMATIONS = ("mp4", "gif")
"""The formats of :func:`animate_section`."""


def records(path: Path, source: str) -> bool:
    """Whether the file ``path`` records ``source`` (:func:`drawn_from`) in its bytes,
    where each format keeps it as written (read a megabyte at a time; a file mapped in
    memory would end the process if another truncated it meanwhile)."""
    marker, before = source.encode(), b""
    with path.open("rb") as stream:
        while chunk := stream.read(2**20):
            if marker in before + chunk:
                return True
            before = chunk[-len(marker) :]
    return False


def remove_stale(out: Path, family: Sequence[str], source: str) -> list[str]:
    """Remove the files of ``out`` named as the figures of ``family`` (every stem the
    command may write, in any format it writes, an animation of the section included; a
    file of another suffix is none of them: ``front.csv`` was removed) that do not
    record ``source`` (:func:`drawn_from`), the file they are drawn from as it is now;
    returns their names.  Those were drawn from an earlier state of it (before the run was
    run again or resumed), from another file, or by a version that recorded none: an
    animation or figures in another format beside the new figures were read as drawn from
    it."""
    stale = sorted(
        path
        for stem in family
        for suffix in (*METADATA_KEYS, *ANIMATIONS)
        if (path := out / f"{stem}.{suffix}").is_file() and not records(path, source)
    )
    for path in stale:
        path.unlink(missing_ok=True)
    return [path.name for path in stale]


def save_figures(
    out: Path, figures: dict[str, Figure], fmt: str, family: Sequence[str], source: str
) -> list[Path]:
    """Write ``figures`` (stem: figure) as ``out/STEM.fmt``, recording ``source``
    (:func:`drawn_from`) in each, after removing the figures of ``family`` (every stem
    the command may write) in that format; returns the paths.  A plot
    stopped half-way (a Ctrl-C, a full disk) over an earlier one left figures of two results
    side by side, each whole and titled, read as one; a figure the earlier result had and
    this one has not (``force`` beside a mixture's) stayed.  Each is written whole (a
    temporary file renamed over its path)."""
    for stem in family:
        writable(out / f"{stem}.{fmt}").unlink(missing_ok=True)
    metadata = {METADATA_KEYS[fmt]: source}
    return [
        write_whole(
            writable(out / f"{stem}.{fmt}"), partial(fig.savefig, dpi=120, format=fmt, metadata=metadata)
        )
        for stem, fig in figures.items()
    ]


def column_indices(ds: xr.Dataset, at: Sequence[float]) -> list[int]:
    """Indices of the cells holding the downslope positions ``at`` (m); InputError outside."""
    edges = ds["x_bnds"].values
    lo, hi = float(edges[0, 0]), float(edges[-1, 1])
    indices = []
    for x in at:
        if not lo <= x <= hi:
            raise InputError(f"--at {x:g}: outside the domain; accepted: a position in [{lo:g}, {hi:g}] (m)")
        indices.append(int(np.clip(np.searchsorted(edges[:, 1], x), 0, ds.sizes["x"] - 1)))
    return list(dict.fromkeys(indices))


def representative_columns(ds: xr.Dataset, count: int = _REPRESENTATIVE) -> list[int]:
    """``count`` columns spread over the material: at 1/6, 1/2 and 5/6 (for 3) of the cells
    holding material (h above the front threshold) at the last output time, or at any
    time if none does then; every column if there are no more than ``count``."""
    h = ds["h"].values
    wet = h[-1] > ds["front"].attrs["threshold"]
    if not wet.any():
        wet = (h > ds["front"].attrs["threshold"]).any(axis=0)
    cells = np.flatnonzero(wet) if wet.any() else np.arange(ds.sizes["x"])
    if cells.size <= count:
        return cells.tolist()
    picks = ((np.arange(count) + 0.5) / count * cells.size).astype(int)
    return cells[picks].tolist()


TITLE_CHARACTERS_PER_INCH = 10.5
"""Characters of a figure title (Matplotlib's 'large' font, 12 pt) per inch of figure width,
with room to spare: a longer title is wrapped, never cut at the figure's edges."""


def _suptitle(fig: Figure, name: str, what: str) -> None:
    """``name: what`` over ``fig``, wrapped to its width (the scenario name on a line of its
    own when both do not fit)."""
    width = max(int(fig.get_figwidth() * TITLE_CHARACTERS_PER_INCH), 20)
    text = f"{name}: {what}"
    if len(text) > width:
        text = "\n".join([*textwrap.wrap(f"{name}:", width), *textwrap.wrap(what, width)])
    fig.suptitle(text)


def _time_indices(ds: xr.Dataset, n: int) -> np.ndarray:
    """Up to ``n`` output-time indices spread evenly from the first to the last."""
    return np.unique(np.linspace(0, ds.sizes["time"] - 1, n).round().astype(int))


def _staircase(ds: xr.Dataset, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, values) tracing a piecewise-constant cell field as a staircase."""
    return ds["x_bnds"].values.ravel(), np.repeat(values, 2, axis=-1)


def _dashes(ds: xr.Dataset, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, values) drawing a cell field as one level segment per cell, not joined."""
    edges = ds["x_bnds"].values
    x = np.column_stack([edges, np.full(len(edges), np.nan)]).ravel()
    y = np.column_stack([values, values, np.full(len(values), np.nan)]).ravel()
    return x, y


def vertical_exaggeration(width: float, height: float, aspect: float = 0.22) -> float:
    """A round factor (1, 2 or 5 x 10^k, at least 1) stretching z so that a section
    ``width`` long and ``height`` high is drawn about ``aspect`` times as high as wide."""
    wanted = aspect * width / max(height, 1e-12)
    if wanted <= 1:
        return 1.0
    decade = 10 ** math.floor(math.log10(wanted))
    return max(f * decade for f in (1, 2, 5) if f * decade <= wanted)


SECTION_MARGIN = 0.1
"""Margin of a cropped section on each side, as a fraction of the span of the material
(at least :data:`SECTION_MARGIN_CELLS` cells)."""
SECTION_MARGIN_CELLS = 2


def material_span(ds: xr.Dataset) -> tuple[float, float]:
    """The x range (m) a section is cropped to: the cells where material moves at some
    output time (else where it lies above the front threshold, else the whole domain),
    widened by :data:`SECTION_MARGIN` on each side and kept inside the domain.

    A bed layer that never moves, such as the erodible bed ahead of the front, is left out."""
    edges = ds["x_bnds"].values
    lo, hi = float(edges[0, 0]), float(edges[-1, 1])
    u, h = ds["u"].values, ds["h"].values
    columns = np.flatnonzero((u != 0.0).any(axis=(0, 1)))
    if not columns.size:
        columns = np.flatnonzero((h > ds["front"].attrs["threshold"]).any(axis=0))
    if not columns.size:
        return lo, hi
    x0, x1 = float(edges[columns[0], 0]), float(edges[columns[-1], 1])
    cell = float(np.max(edges[:, 1] - edges[:, 0]))
    margin = max(SECTION_MARGIN * (x1 - x0), SECTION_MARGIN_CELLS * cell)
    return max(lo, x0 - margin), min(hi, x1 + margin)


XLIM_SPAN = 1000.0
"""Widest window of ``--xlim``, in lengths of the domain (wider, the domain is a dot)."""
XLIM_NARROWEST = 1e-6
"""Narrowest window of ``--xlim``, in lengths of the domain: Matplotlib widens a window
narrower than 1e-15 of its largest end, or within 2.2e-287 of zero, to +-5 % of it, silently
(``0.2 0.2000000000000001`` would be drawn over 0.19 .. 0.21, ``-1e-320 1e-320`` over -0.05 ..
0.05 m); 1e-6 of the domain, even 1000 domain lengths away from it, is far from both."""


def checked_xlim(ds: xr.Dataset, xlim: Sequence[float] | None) -> tuple[float, float]:
    """``xlim`` (``--xlim X0 X1``) if it is an interval overlapping the domain, else
    :func:`material_span` when it is None; InputError otherwise."""
    if xlim is None:
        return material_span(ds)
    edges = ds["x_bnds"].values
    lo, hi = float(edges[0, 0]), float(edges[-1, 1])
    x0, x1 = (float(x) for x in xlim)
    length = hi - lo
    if not (x0 < x1 and x0 < hi and x1 > lo and XLIM_NARROWEST * length <= x1 - x0 <= XLIM_SPAN * length):
        raise InputError(
            f"--xlim {x0!r} {x1!r}: accepted: X0 < X1 (m), overlapping the domain [{lo:g}, {hi:g}], at most "
            f"{XLIM_SPAN:g} and at least {XLIM_NARROWEST:g} times as wide (Matplotlib widens a narrower "
            "window)"
        )
    return x0, x1


def _section_limits(
    ds: xr.Dataset, xlim: Sequence[float] | None = None
) -> tuple[tuple[float, float], tuple[float, float]]:
    """x limits (:func:`checked_xlim`) and z limits holding the bed and the free surface
    between them at every output time."""
    x0, x1 = checked_xlim(ds, xlim)
    edges = ds["x_bnds"].values
    inside = (edges[:, 1] > x0) & (edges[:, 0] < x1)
    bed = ds["bed"].values[inside]
    top = float(np.nanmax(bed + ds["h"].values[:, inside], initial=float(bed.max())))
    low = float(bed.min())
    pad = 0.05 * max(top - low, 1e-6)
    return (x0, x1), (low - pad, top + pad)


def _draw_section(ax: Axes, ds: xr.Dataset, k: int, vmin: float, vmax: float) -> QuadMesh:
    """One X-Z section at output time ``k``: layers coloured by u, bed, surface, static top."""
    snap = ds.isel(time=k)
    sig = ds["sigma_bnds"].values
    edges = np.append(sig[:, 0], sig[-1, 1])
    bed = ds["bed"].values
    h = snap["h"].values
    z = bed + h * edges[:, None]  # (L+1, N) interface heights
    xs, zs = _staircase(ds, z)
    # odd columns join neighbouring cells: zero width, never seen
    # masked, and zero beneath the mask: masked_all leaves the memory as it finds it, and the
    # colour mapping normalises the values under the mask too (numpy overflow warnings)
    colour = np.ma.masked_array(np.zeros((ds.sizes["layer"], xs.size - 1)), mask=True)
    u = snap["u"].values
    colour[:, ::2] = np.ma.masked_where(u == 0.0, u)  # static material is grey
    mesh = ax.pcolormesh(xs, zs, colour, cmap=_VELOCITY, vmin=vmin, vmax=vmax)
    ax.plot(*_staircase(ds, bed), color="k", lw=1.2, label="bed", zorder=3)
    ax.plot(*_staircase(ds, bed + h), color="tab:blue", lw=1.0, label="free surface")
    wet = h > ds["front"].attrs["threshold"]
    static = np.where(wet, bed + snap["static_interface"].values, np.nan)
    ax.plot(*_dashes(ds, static), color="tab:red", lw=1.2, label="top of the static region, per column")
    ax.set_ylabel("z (m)")  # the title says z is normal to the plane
    return mesh


def _section_note(ds: xr.Dataset, exaggeration: float) -> str:
    """What the section axes are: slope of the plane and vertical exaggeration."""
    slope = yaml.safe_load(ds.attrs["scenario"]).get("slope_deg", 0.0)
    return (
        f"x along the plane inclined at {slope:g} deg, z normal to it; "
        f"vertical exaggeration x{exaggeration:g}"
    )


def _moving_note(snap: xr.Dataset) -> str:
    """Where material still moves at an output time: the number of columns and the top speed."""
    speed = np.abs(snap["u"].values).max(axis=0)
    moving = int(np.count_nonzero(speed))
    if not moving:
        return "all at rest"
    return f"{moving} column{'s' * (moving > 1)} moving, max |u| = {_speed_text(speed.max())}"


def _speed_text(speed: float) -> str:
    return f"{speed * 1e3:.2g} mm/s" if speed < 0.01 else f"{speed:.3g} m/s"


def section_figure(ds: xr.Dataset, name: str, times: int = 4, xlim: Sequence[float] | None = None) -> Figure:
    """X-Z sections at ``times`` output times over ``xlim`` (default: where the material is,
    :func:`material_span`), z exaggerated by a round factor from the aspect of that window."""
    picks = _time_indices(ds, times)
    (x0, x1), (z0, z1) = _section_limits(ds, xlim)
    exaggeration = vertical_exaggeration(x1 - x0, z1 - z0)
    panel = min(8.0 * exaggeration * (z1 - z0) / (x1 - x0), 2.5)
    fig = Figure(figsize=(10, (panel + 0.55) * len(picks) + 1.2), layout="constrained")
    axes = fig.subplots(len(picks), 1, sharex=True, sharey=True, squeeze=False)[:, 0]
    u = ds["u"].values[picks]
    vmin, vmax = min(np.nanmin(u, initial=0.0), 0.0), max(np.nanmax(u, initial=0.0), 1e-12)
    for ax, k in zip(axes, picks):
        mesh = _draw_section(ax, ds, k, vmin, vmax)
        ax.set_aspect(exaggeration)
        ax.set_xlim(x0, x1)
        ax.set_ylim(z0, z1)
        snap = ds.isel(time=k)
        ax.set_title(f"t = {float(snap['time']):.3g} s: {_moving_note(snap)}", fontsize="medium")
    handles, _ = axes[0].get_legend_handles_labels()
    handles.append(Patch(color=_AT_REST, label="at rest (u = 0)"))
    fig.legend(handles=handles, loc="outside lower center", ncols=4, fontsize="small")
    axes[-1].set_xlabel("x along the plane (m)")
    fig.colorbar(mesh, ax=list(axes), label="downslope velocity u (m/s)", shrink=0.9)
    fig.suptitle(f"{name}: X-Z section\n{_section_note(ds, exaggeration)}", fontsize="medium")
    return fig


def animate_section(
    ds: xr.Dataset,
    name: str,
    stem: Path,
    fps: int = 10,
    xlim: Sequence[float] | None = None,
    source: str = "",
) -> Path:
    """The X-Z section over ``xlim`` (as :func:`section_figure`) at every output time (at
    most :data:`MAX_FRAMES`), one frame each, with the time as a label.

    Written as ``stem.mp4`` when Matplotlib finds ffmpeg, else as ``stem.gif`` (Pillow,
    installed with Matplotlib), ``source`` (:func:`drawn_from`) as its comment.  Returns
    the path written.
    """
    (x0, x1), (z0, z1) = _section_limits(ds, xlim)
    exaggeration = vertical_exaggeration(x1 - x0, z1 - z0)
    panel = min(8.0 * exaggeration * (z1 - z0) / (x1 - x0), 4.0)
    fig = Figure(figsize=(10, panel + 1.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    u = ds["u"].values
    vmin, vmax = min(np.nanmin(u, initial=0.0), 0.0), max(np.nanmax(u, initial=0.0), 1e-12)
    fig.colorbar(_draw_section(ax, ds, 0, vmin, vmax), ax=ax, label="downslope velocity u (m/s)", shrink=0.9)
    fig.suptitle(f"{name}: X-Z section\n{_section_note(ds, exaggeration)}", fontsize="medium")

    def frame(k: int) -> None:
        ax.clear()
        _draw_section(ax, ds, k, vmin, vmax)
        ax.set_aspect(exaggeration)
        ax.set_xlim(x0, x1)
        ax.set_ylim(z0, z1)
        ax.set_xlabel("x along the plane (m)")
        snap = ds.isel(time=k)
        ax.set_title(f"t = {float(snap['time']):.2f} s: {_moving_note(snap)}", loc="left", fontsize="medium")

    frame(0)
    fig.canvas.draw()
    fig.set_layout_engine("none")  # the layout of the first frame holds for all

    writer: animation.AbstractMovieWriter
    if animation.writers.is_available("ffmpeg"):
        path, writer = stem.with_suffix(".mp4"), animation.FFMpegWriter(fps=fps, metadata={"comment": source})
    else:
        path, writer = stem.with_suffix(".gif"), _CommentedGif(fps=fps, metadata={"comment": source})

    def save(part: Path) -> None:
        # made only to be saved: an animation made and then refused its file (a directory
        # there, say) was collected unsaved, and Matplotlib warned under the message
        movie = animation.FuncAnimation(fig, frame, frames=_time_indices(ds, MAX_FRAMES), repeat=False)
        movie.save(part, writer=writer, dpi=100)

    return write_whole(writable(path), save)


class _CommentedGif(animation.PillowWriter):
    """Matplotlib's GIF writer, its ``metadata["comment"]`` kept as the GIF's comment
    (Matplotlib's writes no metadata)."""

    _frames: list[Image.Image]  # the frames Matplotlib's writer gathers

    def finish(self) -> None:
        self._frames[0].save(
            self.outfile,
            save_all=True,
            append_images=self._frames[1:],
            duration=int(1000 / self.fps),
            loop=0,
            comment=self.metadata["comment"],
        )


def thickness_figure(
    ds: xr.Dataset, name: str, times: int = 6, xlim: Sequence[float] | None = None
) -> Figure:
    """Thickness profiles h(x) at several output times over ``xlim`` (as :func:`section_figure`)."""
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
    ax.set_xlim(*checked_xlim(ds, xlim))
    ax.set_xlabel("x along the plane (m)")
    ax.set_ylabel("thickness h normal to the plane (m)")
    ax.legend(fontsize="small")
    ax.set_title(f"{name}: thickness profiles")
    return fig


def mixture_figure(ds: xr.Dataset, name: str, times: int = 6) -> Figure:
    """A grain–fluid mixture: the solid fraction phi(x) and the basal excess pore pressure
    p_e(x) at several output times (where the material is), and p_e at the bed averaged
    over the material against time; with several layers, the solid fraction of each layer
    at the last output time, and the relaxing pore pressure at the bottom of each layer
    where the result holds it (``pore_pressure_layer``)."""
    layered = ds.sizes.get("layer", 1) > 1
    per_layer = [
        (variable, label)
        for variable, label in (
            ("phi_layer", "phi per layer"),
            ("pore_pressure_layer", "p_e at the bottom\nof each layer (Pa)"),
        )
        if layered and variable in ds
    ]
    fig = Figure(figsize=(8, 8 + 2.5 * len(per_layer)), layout="constrained")
    axes = fig.subplots(3 + len(per_layer), 1)
    ax_phi, ax_pe, ax_time = axes[:3]
    wet = ds["h"] > 0.0
    for j, k in enumerate(_time_indices(ds, times)):
        snap, color = ds.isel(time=k), _shade(j, times)
        label = f"t = {float(snap['time']):.3g} s"
        ax_phi.plot(ds["x"], snap["phi"].where(wet.isel(time=k)), color=color, label=label)
        ax_pe.plot(ds["x"], snap["pore_pressure_excess"].where(wet.isel(time=k)), color=color, label=label)
    mean = ds["pore_pressure_excess"].where(wet).mean("x")
    ax_time.plot(ds["time"], mean, color="k")
    ax_time.axhline(0.0, color="0.6", lw=0.8)
    ax_phi.set_ylabel("solid fraction phi")
    ax_pe.set_ylabel("excess pore pressure\nat the bed (Pa)")
    for ax in (ax_phi, ax_pe):
        ax.set_xlabel("x along the plane (m)")
        ax.legend(fontsize="small")
    ax_time.set_xlabel("time (s)")
    ax_time.set_ylabel("mean excess pore\npressure at the bed (Pa)")
    ax_phi.set_title(f"{name}: grain-fluid mixture")
    last = ds.isel(time=-1)
    for ax, (variable, ylabel) in zip(axes[3:], per_layer, strict=True):
        for a in range(ds.sizes["layer"]):
            values = last[variable].isel(layer=a).where(last["h"] > 0.0)
            ax.plot(ds["x"], values, color=_shade(a, ds.sizes["layer"]), label=f"layer {a + 1}")
        ax.set_xlabel("x along the plane (m)")
        ax.set_ylabel(f"{ylabel}\nat t = {float(last['time']):.3g} s")
        ax.legend(fontsize="small", title="1 is at the bed")
    return fig


def front_velocity(ds: xr.Dataset) -> np.ndarray:
    """Front velocity u_f = dx_f/dt (m/s) by finite differences between output times
    (centred inside, one-sided at the ends; the front moves by whole cells)."""
    t = ds["time"].values
    if t.size < 2:
        return np.zeros_like(t)
    return np.gradient(ds["front"].values, t)


def front_figure(ds: xr.Dataset, name: str) -> Figure:
    """Front position x_f(t) and front velocity u_f(t)."""
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    ax_front, ax_speed = fig.subplots(2, 1, sharex=True)
    t = ds["time"].values
    ax_front.plot(t, ds["front"], marker=".")
    ax_front.set_ylabel("front x_f (m)")
    ax_front.set_title(
        f"front: downslope-most cell centre with h > {ds['front'].attrs['threshold']:g} m", fontsize="medium"
    )
    absent = int(np.isnan(ds["front"].values).sum())
    if absent:  # NaN: no cell thicker than the threshold then; an empty panel said nothing
        threshold = ds["front"].attrs["threshold"]
        ax_front.text(
            0.5,
            0.5,
            f"no front (no cell thicker than {threshold:g} m) at {absent} of {t.size} output times",
            transform=ax_front.transAxes,
            ha="center",
            va="center",
            fontsize="small",
            color="tab:red",
        )
    ax_speed.plot(t, front_velocity(ds), marker=".", color="tab:orange")
    ax_speed.axhline(0.0, color="0.6", lw=0.8)
    ax_speed.set_ylabel("front velocity u_f (m/s)")
    ax_speed.set_title("u_f = dx_f/dt, finite differences between output times", fontsize="medium")
    ax_speed.set_xlabel("time t (s)")
    _suptitle(fig, name, "front")
    return fig


def mass_figure(ds: xr.Dataset, name: str) -> Figure:
    """Volume per unit width V(t) = integral of h dx (m^2) and its relative change."""
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    ax_volume, ax_change = fig.subplots(2, 1, sharex=True)
    t = ds["time"].values
    volume = ds["mass"].values
    ax_volume.plot(t, volume, marker=".", color="tab:green")
    ax_volume.set_ylabel("volume per unit width V (m$^2$)")
    ax_volume.set_title("V = integral of h over x (the mass divided by the bulk density)", fontsize="medium")
    change = (volume - volume[0]) / volume[0] if volume[0] else volume - volume[0]
    ax_change.plot(t, change, marker=".", color="tab:green")
    ax_change.set_ylabel("(V - V(0)) / V(0)" if volume[0] else "V - V(0) (m$^2$)")
    ax_change.set_xlabel("time t (s)")
    _suptitle(fig, name, "volume (inflow and outflow change it)")
    return fig


def _intervals(ds: xr.Dataset, values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, values) drawing the means over the output intervals (records 1 ..) as steps."""
    t = ds["time"].values
    return np.repeat(t, 2)[1:-1], np.repeat(values[1:], 2)


def force_figure(ds: xr.Dataset, name: str) -> Figure:
    """The forces the flow exerts per unit width, means over each output interval: downslope
    on the bed, the side walls, the end walls and by the non-hydrostatic pressure, their sum
    and the weight along the slope; and the seismic single force, their departure from the
    weight ``F - M g`` (downslope and normal), the force on the Earth of landslide seismology."""
    fig = Figure(figsize=(8, 6.5), layout="constrained")
    ax_force, ax_seismic = fig.subplots(2, 1, sharex=True)
    parts = {
        "bed_force_x": "bed",
        "wall_force_x": "side walls",
        "end_force_x": "end walls",
        "pressure_force_x": "non-hydrostatic pressure",
    }
    seismic_x, seismic_z = seismic_force(ds)
    weight = ds["gravity_force_x"].values
    for key, label in parts.items():
        if np.any(ds[key].values[1:] != 0.0):
            ax_force.plot(*_intervals(ds, ds[key].values), label=label)
    ax_force.plot(*_intervals(ds, seismic_x + weight), color="k", label="total F_x")
    ax_force.plot(*_intervals(ds, weight), color="0.5", ls="--", label="weight M g sin(theta)")
    ax_force.axhline(0.0, color="0.6", lw=0.8)
    ax_force.set_ylabel("downslope force (N/m)")
    ax_force.set_title(
        "force of the flow on the Earth per unit width, mean over each output interval", fontsize="medium"
    )
    ax_force.legend(fontsize="small")
    ax_seismic.plot(*_intervals(ds, seismic_x), color="k", label="downslope")
    ax_seismic.plot(*_intervals(ds, seismic_z), color="tab:purple", label="normal, into the bed")
    ax_seismic.axhline(0.0, color="0.6", lw=0.8)
    ax_seismic.set_ylabel("F - M g (N/m)")
    ax_seismic.set_title("seismic single force: departure from the static weight (-dP/dt)", fontsize="medium")
    ax_seismic.set_xlabel("time t (s)")
    ax_seismic.legend(fontsize="small")
    _suptitle(fig, name, "force on the bed and the walls")
    return fig


def _column_title(ds: xr.Dataset, i: int) -> str:
    return f"x = {float(ds['x'][i]):.4g} m (cell {i})"


def profiles_figure(ds: xr.Dataset, name: str, columns: Sequence[int], times: int = 6) -> Figure:
    """Velocity profiles u(z) at the given columns, at several output times."""
    fig = Figure(figsize=(4.2 * len(columns) + 0.6, 5.0), layout="constrained")
    axes = fig.subplots(1, len(columns), sharey=False, squeeze=False)[0]
    picks = _time_indices(ds, times)
    for ax, i in zip(axes, columns):
        for j, k in enumerate(picks):
            snap = ds.isel(time=k, x=i)
            z = float(snap["h"]) * ds["sigma"].values
            ax.plot(
                snap["u"],
                z,
                marker=".",
                color=_shade(j, len(picks)),
                label=f"t = {float(snap['time']):.3g} s",
            )
        ax.axvline(0.0, color="0.6", lw=0.8)
        ax.set_xlabel("downslope velocity u (m/s)")
        ax.set_title(_column_title(ds, i), fontsize="medium")
    axes[0].set_ylabel("height above the bed z - b, normal to the plane (m)")
    axes[-1].legend(fontsize="small")
    _suptitle(fig, name, "velocity profiles u(z) at the layer centres")
    return fig


def static_interface_figure(ds: xr.Dataset, name: str, columns: Sequence[int]) -> Figure:
    """Static/flowing interface b(t) and thickness h(t) at the given columns."""
    fig = Figure(figsize=(4.2 * len(columns) + 0.6, 4.5), layout="constrained")
    axes = fig.subplots(1, len(columns), squeeze=False)[0]
    for ax, i in zip(axes, columns):
        col = ds.isel(x=i)
        ax.plot(col["time"], col["h"], color="tab:blue", label="free surface h")
        ax.plot(
            col["time"], col["static_interface"], color="tab:red", marker=".", label="static interface b(t)"
        )
        ax.set_xlabel("time t (s)")
        ax.set_title(_column_title(ds, i), fontsize="medium")
    axes[0].set_ylabel("height above the bed (m)")
    axes[-1].legend(fontsize="small")
    _suptitle(fig, name, "top of the static region b(t) (0: flowing down to the bed; h: at rest)")
    return fig


def _shade(j: int, n: int) -> tuple[float, float, float, float]:
    """Colour of the ``j``-th of ``n`` curves, early times light, late times dark."""
    return colormaps["viridis_r"](0.15 + 0.85 * j / max(n - 1, 1))
