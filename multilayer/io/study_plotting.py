"""Figures of a calibration (``calibration.nc``) and a sensitivity study (``sensitivity.nc``).

Calibration: ``misfit.png`` (misfit of every parameter set against its order of
evaluation, by stage), ``pairs.png`` (every pair of parameters: the parameter sets
coloured by misfit, the best fit and its 1- and 2-sigma Laplace ellipses) and
``fit.png`` (observed points with their error bars against the fitted model, one panel
per observation).  Sensitivity: ``sobol.png`` (S1 and ST with their confidence intervals,
one panel per output).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import netCDF4
import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from multilayer.errors import InputError, reason
from multilayer.io.disk import writable_directory
from multilayer.io.plotting import PLOTS_DIR, drawn_from, save_figures
from multilayer.io.result_check import finite_number
from multilayer.io.result_format import NETCDF_LOCK
from multilayer.io.results import decoded
from multilayer.scenario.messages import shown

_STAGE_COLOURS = {"search": "C0", "refine": "C1", "uncertainty": "C2"}
_SI = {"runout": "m", "front_final": "m", "duration": "s", "mass_final": "m2", "front": "m", "h": "m"}


SOBOL_INDICES = ("S1", "S1_conf", "ST", "ST_conf")
"""Never infinite: Sobol' indices and their confidence half-widths are ratios of sample
variances (NaN where an output does not vary or runs failed)."""
REQUIRED: dict[str, tuple[dict[str, tuple[str, ...]], tuple[str, ...], tuple[str, ...]]] = {
    "calibration": (
        {
            "best": ("parameter",),
            "coordinate": ("point",),
            "covariance": ("parameter", "parameter2"),
            "fitted": ("point",),
            "misfit": ("candidate",),
            "observation": ("point",),
            "observed": ("point",),
            "observed_sd": ("point",),
            "stage": ("candidate",),
            "values": ("candidate", "parameter"),
        },
        ("parameter", "quantity"),
        (),
    ),
    "sensitivity": (
        {name: ("output", "parameter") for name in SOBOL_INDICES},
        ("output", "parameter"),
        ("confidence_level", "base_samples"),
    ),
}
"""What the figures of each kind of study file read: variables (with the dimensions the
study writes them over), coordinates, attributes."""


COUNTS = ("base_samples", "failed_runs", "runs_not_done")
"""Attributes of a sensitivity file that are counts (the first always there, the others
written since the runs could fail)."""
MAX_STUDY_BYTES = 2**30
"""Largest study file read (bytes of its decoded variables): a calibration of 10^5
parameter sets of 10 parameters is 8 MB."""


def plot_study(directory: str | os.PathLike, filename: str) -> tuple[list[Path], list[str]]:
    """Write the figures of ``directory/filename`` into ``directory/plots/``; an
    :class:`InputError` naming the file if it is not a study file multilayer wrote."""
    path = Path(directory) / filename
    try:
        size = _declared_bytes(path)
        if size > MAX_STUDY_BYTES:  # a netCDF-4 file of kilobytes can declare terabytes
            raise InputError(
                f"{path}: its variables hold {size} bytes; accepted: a file written by multilayer, of at "
                f"most {MAX_STUDY_BYTES} bytes"
            )
        ds = decoded(path)
    except (OSError, ValueError, RuntimeError) as exc:  # xarray's own text runs on for lines, with links
        raise InputError(
            f"{path}: not a readable netCDF file ({reason(exc).split('. ')[0].splitlines()[0]}); "
            "accepted: a file written by multilayer"
        ) from None
    check_study(ds, path)
    out = writable_directory(Path(directory) / PLOTS_DIR)
    notes = []
    if "misfit" in ds:
        figures = {"misfit": misfit_figure(ds), "pairs": pairs_figure(ds), "fit": fit_figure(ds)}
    else:
        figures = {"sobol": sobol_figure(ds)}
        if missing := _without_indices(ds):  # an empty panel, exit 0, said nothing
            notes.append(
                f"{path}: no Sobol' indices of {', '.join(missing)} ({_why_no_indices(ds)}): the figure "
                "shows none"
            )
    return save_figures(out, figures, "png", tuple(figures), drawn_from(path)), notes


def _declared_bytes(path: Path) -> int:
    """Bytes of the variables the netCDF file ``path`` declares (8 an element of text),
    from its header: xarray reads a dimension's coordinate whole at its opening."""
    with NETCDF_LOCK, netCDF4.Dataset(path) as nc:
        return sum(math.prod(var.shape) * getattr(var.dtype, "itemsize", 8) for var in nc.variables.values())


def _without_indices(ds: xr.Dataset) -> list[str]:
    """The outputs of a sensitivity file with an index that is NaN."""
    return [str(o) for o, s1, st in zip(ds["output"].values, ds["S1"].values, ds["ST"].values) if
            np.isnan(s1).any() or np.isnan(st).any()]  # fmt: skip


def _why_no_indices(ds: xr.Dataset) -> str:
    """Why an index is NaN: runs that failed or were not done, or an output that does not vary."""
    failed, not_done = int(ds.attrs.get("failed_runs", 0)), int(ds.attrs.get("runs_not_done", 0))
    if failed or not_done:
        return f"{failed} runs failed, {not_done} not done; the estimators need every run"
    return "the output does not vary over the samples"


def check_study(ds: xr.Dataset, path: Path) -> None:
    """:class:`InputError` naming ``path`` unless ``ds`` holds what the figures read, over
    the dimensions the study writes (a variable over others was drawn, exit 0), and Sobol'
    indices that are not infinite (drawn, with numpy's warning)."""
    kind = "calibration" if "misfit" in ds else "sensitivity"
    variables, coordinates, attributes = REQUIRED[kind]
    accepted = f"accepted: the file that multilayer {'calibrate' if kind == 'calibration' else kind} writes"
    missing = [name for name in (*variables, *coordinates) if name not in ds.variables]
    missing += [f"attribute {name}" for name in attributes if name not in ds.attrs]
    if missing:
        raise InputError(f"{path}: not a {kind} file: no {', '.join(missing)}; {accepted}")
    for name, dims in variables.items():
        if ds[name].dims != dims:
            raise InputError(f"{path}: {name} over {ds[name].dims}, where over {dims}; {accepted}")
    if kind == "sensitivity":  # the figure's titles and notes compute with them
        level = _plain(ds.attrs["confidence_level"])
        if not (finite_number(level) and 0 < float(level) < 1):
            raise InputError(
                f"{path}: its attribute confidence_level is {shown(level)}, not in (0, 1); {accepted}"
            )
        for name in COUNTS:
            count = _plain(ds.attrs.get(name, 0 if name != "base_samples" else None))
            if not (finite_number(count) and float(count).is_integer() and 0 <= float(count) < 2**63):
                raise InputError(f"{path}: its attribute {name} is {shown(count)}, not a count; {accepted}")
    if kind == "calibration":
        _check_calibration_values(ds, path, accepted)
    for name in SOBOL_INDICES if kind == "sensitivity" else ():
        values = np.asarray(ds[name].values)
        if values.dtype.kind != "f" or np.isinf(values).any():
            what = "infinite values" if values.dtype.kind == "f" else f"values of type {values.dtype}"
            raise InputError(f"{path}: {name} holds {what}, where numbers or nan; {accepted}")


CALIBRATION_VALUES = {
    "values": "finite numbers",
    "observed": "finite numbers",
    "observed_sd": "finite numbers > 0",
    "misfit": "numbers >= 0, inf where a run failed",
    "best": "finite numbers, or nan throughout (no parameter set evaluated)",
    "fitted": "finite numbers, or nan throughout (the best set has no prediction)",
    "covariance": "finite numbers, or nan throughout (not computed yet)",
}
"""What a calibration writes in the variables its figures compute with (its runs' measures
are finite, or the run failed: :mod:`multilayer.app.ensemble`)."""


def _check_calibration_values(ds: xr.Dataset, path: Path, accepted: str) -> None:
    """:class:`InputError` naming ``path``, the variable and its first value out of
    :data:`CALIBRATION_VALUES` (a damaged file would be drawn as a fit)."""
    for name, allowed in CALIBRATION_VALUES.items():
        values = np.asarray(ds[name].values)
        if values.dtype.kind not in "fiu":
            raise InputError(
                f"{path}: {name} holds values of type {values.dtype}, where {allowed}; {accepted}"
            )
        values = values.astype(float)
        if name == "misfit":
            good = values >= 0
        elif name == "observed_sd":
            good = np.isfinite(values) & (values > 0)
        elif name in ("best", "fitted", "covariance") and np.isnan(values).all():
            continue  # not evaluated or computed yet
        else:
            good = np.isfinite(values)
        if not good.all():
            raise InputError(f"{path}: {name} holds {values[~good][0]:g}, where {allowed}; {accepted}")


def _plain(value: Any) -> Any:
    """An attribute as xarray reads it (a numpy scalar or a 1-element array) as Python's value."""
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(())[()]
    return value.item() if isinstance(value, np.generic) else value


def misfit_figure(ds: xr.Dataset) -> Figure:
    """Misfit of every parameter set in evaluation order, coloured by stage (log scale)."""
    fig = Figure(figsize=(7, 4), layout="constrained")
    ax = fig.add_subplot()
    misfit = ds["misfit"].values
    stages = ds["stage"].values.astype(str)
    order = np.arange(misfit.size)
    for stage, colour in _STAGE_COLOURS.items():
        sel = (stages == stage) & np.isfinite(misfit)
        if sel.any():
            ax.semilogy(order[sel], np.maximum(misfit[sel], 1e-12), ".", color=colour, label=stage)
    failed = ~np.isfinite(misfit)
    if failed.any():
        ax.plot(
            order[failed],
            np.full(failed.sum(), misfit[~failed].max() if (~failed).any() else 1.0),
            "x",
            color="red",
            label="failed",
        )
    ax.plot(
        order,
        np.minimum.accumulate(np.where(np.isfinite(misfit), misfit, np.inf)),
        "k-",
        lw=1,
        label="best so far",
    )
    ax.set_xlabel("parameter set (order of evaluation)")
    ax.set_ylabel("misfit (sum of squared whitened residuals)")
    ax.legend()
    return fig


def pairs_figure(ds: xr.Dataset) -> Figure:
    """Every pair of parameters: evaluated sets coloured by misfit, best fit and ellipses."""
    names = [str(n) for n in ds["parameter"].values]
    n = len(names)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)] or [(0, 0)]
    cols = min(3, len(pairs))
    rows = -(-len(pairs) // cols)
    fig = Figure(figsize=(4.2 * cols, 3.8 * rows), layout="constrained")
    values, misfit = ds["values"].values, ds["misfit"].values
    ok = np.isfinite(misfit)
    best, cov = ds["best"].values, ds["covariance"].values
    for k, (i, j) in enumerate(pairs):
        ax = fig.add_subplot(rows, cols, k + 1)
        if i == j:  # one parameter: misfit against it
            ax.semilogy(values[ok, i], misfit[ok], ".", ms=3)
            ax.axvline(best[i], color="k")
            ax.set_xlabel(names[i])
            ax.set_ylabel("misfit")
            continue
        sc = ax.scatter(
            values[ok, i], values[ok, j], c=np.log10(np.maximum(misfit[ok], 1e-12)), s=8, cmap="viridis_r"
        )
        ax.plot(values[~ok, i], values[~ok, j], "rx", ms=4)
        ax.plot(best[i], best[j], "k*", ms=10)
        block = cov[np.ix_([i, j], [i, j])]
        if np.all(np.isfinite(block)):
            w, v = np.linalg.eigh(block)
            angle = np.linspace(0, 2 * np.pi, 200)
            circle = np.stack([np.cos(angle), np.sin(angle)])
            for level in (1, 2):
                ellipse = v @ (level * np.sqrt(np.maximum(w, 0))[:, None] * circle)
                ax.plot(best[i] + ellipse[0], best[j] + ellipse[1], "k-", lw=1 / level)
        ax.set_xlabel(names[i])
        ax.set_ylabel(names[j])
        fig.colorbar(sc, ax=ax, label="log10 misfit")
    return fig


def fit_figure(ds: xr.Dataset) -> Figure:
    """Observed points (with 1-sigma error bars) and the fitted model, per observation."""
    observations = list(dict.fromkeys(ds["observation"].values.astype(str)))
    curves = [o for o in observations if (ds["observation"].values.astype(str) == o).sum() > 1]
    scalars = [o for o in observations if o not in curves]
    panels = len(curves) + (1 if scalars else 0)
    fig = Figure(figsize=(5 * min(panels, 3), 3.8 * -(-panels // 3)), layout="constrained")
    obs_names = ds["observation"].values.astype(str)
    quantity = ds["quantity"].values.astype(str)
    for k, name in enumerate(curves):
        ax = fig.add_subplot(-(-panels // 3), min(panels, 3), k + 1)
        sel = obs_names == name
        x = ds["coordinate"].values[sel]
        ax.errorbar(
            x, ds["observed"].values[sel], ds["observed_sd"].values[sel], fmt="o", ms=3, label="observed"
        )
        ax.plot(x, ds["fitted"].values[sel], "k-", label="fitted")
        q = quantity[sel][0]
        ax.set_xlabel("t (s)" if q == "front" else "x (m)")
        ax.set_ylabel(f"{q} ({_SI[q]})")
        ax.set_title(name)
        ax.legend()
    if scalars:
        ax = fig.add_subplot(-(-panels // 3), min(panels, 3), panels)
        sel = np.isin(obs_names, scalars)
        pos = np.arange(sel.sum())
        ax.errorbar(pos, ds["observed"].values[sel], ds["observed_sd"].values[sel], fmt="o", label="observed")
        ax.plot(pos, ds["fitted"].values[sel], "k_", ms=20, mew=2, label="fitted")
        ax.set_xticks(pos, [f"{o}\n({_SI[q]})" for o, q in zip(obs_names[sel], quantity[sel])], fontsize=8)
        ax.set_title("scalar observations")
        ax.legend()
    return fig


def sobol_figure(ds: xr.Dataset) -> Figure:
    """S1 and ST of each parameter with confidence intervals, one panel per output."""
    outputs = [str(o) for o in ds["output"].values]
    names = [str(n) for n in ds["parameter"].values]
    fig = Figure(figsize=(max(6, 1.3 * len(names)) * len(outputs), 4), layout="constrained")
    pos = np.arange(len(names))
    level = round(100 * float(ds.attrs["confidence_level"]))
    for k, output in enumerate(outputs):
        ax = fig.add_subplot(1, len(outputs), k + 1)
        for offset, key, label in ((-0.2, "S1", "first order S1"), (0.2, "ST", "total ST")):
            ax.bar(
                pos + offset, ds[key].values[k], 0.4, yerr=ds[f"{key}_conf"].values[k], capsize=3, label=label
            )
        ax.axhline(0, color="k", lw=0.5)
        if output in _without_indices(ds):
            ax.text(
                0.5,
                0.5,
                f"no indices:\n{_why_no_indices(ds)}",
                transform=ax.transAxes,
                ha="center",
                wrap=True,
            )
        ax.set_xticks(pos, names, rotation=20, fontsize=8)
        ax.set_title(f"{output} ({ds.attrs['base_samples']} base samples, {level}% intervals)")
        ax.legend()
    return fig
