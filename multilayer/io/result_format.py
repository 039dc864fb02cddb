"""The names and variables of the result file ``result.nc`` (docs/results.md), shared by
its writer and reader (:mod:`multilayer.io.results`, which re-exports them) and its checks
(:mod:`multilayer.io.result_check`): the checks need them without the writer, which uses
the checks (no import cycle)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Final

from xarray.backends.locks import HDF5_LOCK, NETCDFC_LOCK, combine_locks

RESULT_FILE = "result.nc"
CHECKPOINT_FILE = "checkpoint.npz"
FAILURE_LENGTH = 8000
"""Characters of the failure message kept in the ``failure`` attribute (run.log has it all)."""
STEPS_INT32 = 2**31 - 1
"""The largest step count written as an integer: the classic netCDF format of a result
holds 32-bit integers, and netCDF4 writes a larger Python integer there as 0.  A larger
count is written as a float64, exact up to :data:`STEPS_WRITTEN`."""
STEPS_WRITTEN = 2**53
"""The largest step count a result holds: float64 is exact to there (a run of that many
steps at a microsecond each would take 285 years)."""
FORMAT: Final = "NETCDF3_64BIT_OFFSET"
#: netCDF-C is not thread-safe and netCDF4-python releases the GIL in its calls: the runs of a
#: thread cluster write their result files while the study writes its own through xarray,
#: which holds these same locks around every netCDF call, so the writer holds them too
NETCDF_LOCK: Final = combine_locks([NETCDFC_LOCK, HDF5_LOCK])

#: CF attributes of every coordinate and variable: (dimensions, attributes).
VARIABLES: dict[str, tuple[tuple[str, ...], dict[str, str]]] = {
    "time": (
        ("time",),
        {
            "units": "s",
            "long_name": "simulated time since release",
            "standard_name": "time",
            "axis": "T",
        },
    ),
    "x": (
        ("x",),
        {
            "units": "m",
            "long_name": "downslope position of the cell centre along the plane",
            "axis": "X",
            "bounds": "x_bnds",
        },
    ),
    "x_bnds": (
        ("x", "nv"),
        {
            "units": "m",
            "long_name": "downslope positions of the cell edges",
        },
    ),
    "layer": (
        ("layer",),
        {
            "units": "1",
            "long_name": "layer index, 1 at the bed",
            "axis": "Z",
            "positive": "up",
        },
    ),
    "sigma": (
        ("layer",),
        {
            "units": "1",
            "long_name": "height of the layer centre as a fraction of h",
            "positive": "up",
            "bounds": "sigma_bnds",
        },
    ),
    "sigma_bnds": (
        ("layer", "nv"),
        {
            "units": "1",
            "long_name": "heights of the layer interfaces as fractions of h",
        },
    ),
    "bed": (
        ("x",),
        {
            "units": "m",
            "long_name": "bed elevation b normal to the plane",
        },
    ),
    "h": (
        ("time", "x"),
        {
            "units": "m",
            "long_name": "flow thickness normal to the plane",
        },
    ),
    "u": (
        ("time", "layer", "x"),
        {
            "units": "m s-1",
            "long_name": "downslope layer velocity",
            "coordinates": "sigma",
        },
    ),
    "static_interface": (
        ("time", "x"),
        {
            "units": "m",
            "long_name": "height above the bed of the top of the static region",
            "comment": "0: flowing down to the bed; h: the whole column at rest",
        },
    ),
    "front": (
        ("time",),
        {
            "units": "m",
            "long_name": "downslope-most cell centre with h above threshold",
        },
    ),
    "mass": (
        ("time",),
        {
            "units": "m2",
            "long_name": "integral of h over x (volume per unit width)",
        },
    ),
}

_FORCE = "mean over the interval since the previous output time, per unit channel width"
FORCES: dict[str, tuple[tuple[str, ...], dict[str, str]]] = {
    "bed_force_x": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "downslope force of the flow on the bed",
            "comment": f"{_FORCE}; basal shear, pressure on the relief of the bed and on a gate",
        },
    ),
    "bed_force_z": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "force of the flow on the bed normal to the plane, positive into the bed",
            "comment": f"{_FORCE}; weight and the change of normal momentum of the non-hydrostatic model",
        },
    ),
    "wall_force_x": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "downslope force of the flow on the side walls",
            "comment": _FORCE,
        },
    ),
    "end_force_x": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "downslope force of the flow on the end walls (wall boundaries)",
            "comment": _FORCE,
        },
    ),
    "pressure_force_x": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "downslope force of the non-hydrostatic pressure on the bed and the end walls",
            "comment": f"{_FORCE}; zero with the hydrostatic pressure",
        },
    ),
    "gravity_force_x": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "downslope component of the weight of the flow",
            "comment": _FORCE,
        },
    ),
    "gravity_force_z": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "component of the weight of the flow normal to the plane, into the bed",
            "comment": _FORCE,
        },
    ),
    "outflow_momentum_x": (
        ("time",),
        {
            "units": "N m-1",
            "long_name": "downslope momentum leaving through the open boundaries per unit time",
            "comment": _FORCE,
        },
    ),
}
"""The forces on the Earth (multilayer.engine.bed_force), the sign convention of
landslide seismology: the force the flow exerts (Toney & Allstadt 2021).  With output
times t_k the downslope momentum P obeys P(t_k) - P(t_(k-1)) = (t_k - t_(k-1)) (gravity -
bed - wall - end - pressure - outflow) to round-off; the first record (no interval) is NaN."""
VARIABLES.update(FORCES)
#: the variables of a grain–fluid mixture (docs/mixture.md), written when the run has one
MIXTURE_VARIABLES: dict[str, tuple[tuple[str, ...], dict[str, str]]] = {
    "phi": (
        ("time", "x"),
        {"units": "1", "long_name": "depth-averaged solid volume fraction of the mixture"},
    ),
    "phi_layer": (
        ("time", "layer", "x"),
        {"units": "1", "long_name": "solid volume fraction of each layer", "coordinates": "sigma"},
    ),
    "pore_pressure_excess": (
        ("time", "x"),
        {
            "units": "Pa",
            "long_name": "excess pore pressure at the bed (over the ambient fluid's hydrostatic pressure)",
        },
    ),
    "pore_pressure_layer": (
        ("time", "layer", "x"),
        {
            "units": "Pa",
            "long_name": "relaxing excess pore pressure at the bottom of each layer",
            "coordinates": "sigma",
        },
    ),
}
"""``pore_pressure_layer`` is written only where the pore pressure relaxes in several layers
(``fluid.compressibility`` with ``domain.layers`` above 1; its first layer is
``pore_pressure_excess``)."""


def result_path(path: str | os.PathLike) -> Path:
    """``path`` itself, or the ``result.nc`` inside it when it is a directory."""
    path = Path(path)
    return path / RESULT_FILE if path.is_dir() else path
