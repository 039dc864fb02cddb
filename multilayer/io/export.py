"""ParaView export: one VTK XML structured grid (``.vts``) per output time.

The grid is the layered mesh in physical coordinates: point ``(i, k)`` sits at cell
edge ``x_{i-1/2}`` and height ``z = b + h * sigma_{k-1/2}`` (b and h averaged over the
two cells sharing the edge), stored as VTK point ``(x, z, 0)`` so that ParaView's 2D
view shows the section.  Cell data: ``u`` (m/s), ``h`` (m) of the column and ``static``
(1 below the static/flowing interface, 0 above); of a grain-fluid mixture also ``phi``
(the solid volume fraction) and ``pore_pressure_excess`` (Pa), each of its layer where
the result holds them per layer, else of its column.  ``result.pvd`` lists the files with
their times, so ParaView opens the run as one time series.  Plain ASCII, written here:
no VTK library needed.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import xarray as xr

from multilayer.io.disk import writable, writable_directory, write_whole
from multilayer.io.result_check import ending
from multilayer.io.results import open_result

VTK_DIR = "vtk"
MIXTURE_FIELDS = (
    ("phi", "phi", "phi_layer"),
    ("pore_pressure_excess", "pore_pressure_excess", "pore_pressure_layer"),
)
"""A grain-fluid mixture's cell data: (name, the result's column variable, its per-layer
variable, taken where the result holds it)."""
SERIES_FILE = re.compile(r"result_[0-9]{4,}\.vts")
"""The name of an output time's file, ``result_NNNN.vts``."""


def export_vtk(directory: str | os.PathLike) -> tuple[list[Path], str | None]:
    """Write ``directory/vtk/result_NNNN.vts`` per output time and ``result.pvd``; returns
    the paths (``result.pvd`` first) and how the run ended if it did not complete."""
    ds = open_result(directory)
    out = writable_directory(Path(directory) / VTK_DIR)
    pvd = writable(out / "result.pvd")
    # the series of an earlier export goes first: one stopped half-way (Ctrl-C, a full disk)
    # left it listing this run's first files and the earlier run's others, read as one run
    pvd.unlink(missing_ok=True)
    for earlier in out.iterdir():  # and its files: those past this run's last were left beside them,
        if SERIES_FILE.fullmatch(earlier.name) and (earlier.is_symlink() or earlier.is_file()):
            earlier.unlink()  # one series of two runs to ParaView's group of result_..vts
    entries, paths = [], []
    for k in range(ds.sizes["time"]):
        path = _text_file(out / f"result_{k:04d}.vts", structured_grid(ds.isel(time=k)))
        paths.append(path)
        entries.append(f'    <DataSet timestep="{float(ds["time"][k])!r}" file="{path.name}"/>')
    text = (
        '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
        "  <Collection>\n" + "\n".join(entries) + "\n  </Collection>\n"
        "</VTKFile>\n"
    )
    _text_file(pvd, text)
    return [pvd, *paths], ending(ds.attrs)


def _text_file(path: Path, text: str) -> Path:
    """``path`` holding ``text``, written whole (:func:`multilayer.io.disk.write_whole`): an
    export stopped half-way (a Ctrl-C, a full disk) leaves no file cut short."""
    return write_whole(writable(path), lambda part: part.write_text(text))


def _to_edges(values: np.ndarray) -> np.ndarray:
    """Cell values (N,) averaged onto the N+1 cell edges (end edges copy the end cells)."""
    padded = np.concatenate([values[:1], values, values[-1:]])
    return 0.5 * (padded[:-1] + padded[1:])


def structured_grid(snap: xr.Dataset) -> str:
    """The ``.vts`` text of one output time of a result dataset."""
    n_layers, n_cells = snap.sizes["layer"], snap.sizes["x"]
    sig = snap["sigma_bnds"].values
    levels = np.append(sig[:, 0], sig[-1, 1])
    x_edges = np.append(snap["x_bnds"].values[:, 0], snap["x_bnds"].values[-1, 1])
    bed, h = snap["bed"].values, snap["h"].values
    z = _to_edges(bed) + _to_edges(h) * levels[:, None]  # (L+1, N+1), x fastest
    points = np.column_stack([np.broadcast_to(x_edges, z.shape).ravel(), z.ravel(), np.zeros(z.size)])
    static = h * snap["sigma"].values[:, None] < snap["static_interface"].values
    cells = {
        "u": snap["u"].values,
        "h": np.broadcast_to(h, (n_layers, n_cells)),
        "static": static.astype(float),
    }
    for name, column, layered in MIXTURE_FIELDS:  # a grain-fluid mixture's, per layer where written
        if layered in snap:
            cells[name] = snap[layered].values
        elif column in snap:
            cells[name] = np.broadcast_to(snap[column].values, (n_layers, n_cells))
    extent = f"0 {n_cells} 0 {n_layers} 0 0"
    arrays = "\n".join(_data_array(name, a) for name, a in cells.items())
    return (
        '<?xml version="1.0"?>\n'
        '<VTKFile type="StructuredGrid" version="0.1" byte_order="LittleEndian">\n'
        f'  <StructuredGrid WholeExtent="{extent}">\n'
        "    <FieldData>\n"
        f"{_data_array('TIME', np.array([float(snap['time'])]), tuples=1)}\n"
        "    </FieldData>\n"
        f'    <Piece Extent="{extent}">\n'
        f'      <CellData Scalars="u">\n{arrays}\n      </CellData>\n'
        f"      <Points>\n{_data_array(None, points, components=3)}\n      </Points>\n"
        "    </Piece>\n  </StructuredGrid>\n</VTKFile>\n"
    )


def _data_array(name: str | None, values: np.ndarray, components: int = 1, tuples: int | None = None) -> str:
    """One ASCII ``<DataArray>`` of float64 values in C order."""
    attrs = f' Name="{name}"' if name else ""
    if components > 1:
        attrs += f' NumberOfComponents="{components}"'
    if tuples is not None:
        attrs += f' NumberOfTuples="{tuples}"'
    text = " ".join(repr(float(v)) for v in np.ravel(values))
    return f'        <DataArray type="Float64"{attrs} format="ascii">{text}</DataArray>'
