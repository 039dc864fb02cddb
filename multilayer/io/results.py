"""The result file ``result.nc`` (CF-1.8 netCDF), checkpoints and the run summary.

The file layout is the public contract of docs/results.md.  It is written
incrementally: the ``time`` dimension is unlimited, every output time is appended as one
record and the file is synced to disk straight away, so a crash or an interruption
leaves a readable file holding every output time completed so far.  The classic 64-bit
offset format is used on purpose: a netCDF-3 file whose writer dies is still valid up to
its last synced record, whereas an HDF5-based file may be left unreadable.

The attributes written when the run ends (``run_status``, ``failure``, ...) fit in room
kept free in the header from the start (the ``header_space`` attribute, removed then):
netCDF-C moves every record when the header grows, which would rewrite the whole file at
the end of a run, and fail on a full disk.  Before each record the writer checks that it
fits on the disk and under the file size limit (:mod:`multilayer.io.disk`): a run that
fills the disk stops with :class:`DiskFull` between two records, the file holding every
record written before, readable, and ``run_status: failed``.

Checkpoints (``checkpoint.npz``) hold the full :meth:`Simulation.state_dict` plus the
bookkeeping needed to continue the result file; they are replaced atomically
(temporary file + :func:`os.replace`), so a checkpoint on disk is always complete.  They
hold plain numeric and text arrays only, read with ``allow_pickle=False`` (loading one
can never execute code), and a SHA-256 checksum of their contents: a truncated,
corrupted or foreign file is an :class:`InputError` naming it.
"""

from __future__ import annotations

import contextlib
import datetime as _dt
import hashlib
import math
import os
import threading
import warnings
import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import netCDF4
import numpy as np
import xarray as xr
import yaml

from multilayer.errors import InputError, RunError, reason
from multilayer.io import disk
from multilayer.io.netcdf_layout import (
    HEADER_SPACE,
    NUMRECS_OFFSET,
    LayoutError,
    declared_size,
    read_layout,
)
from multilayer.io.result_format import (  # noqa: F401 (this module's names, as before)
    CHECKPOINT_FILE,
    FAILURE_LENGTH,
    FORCES,
    FORMAT,
    MIXTURE_VARIABLES,
    NETCDF_LOCK,
    RESULT_FILE,
    STEPS_INT32,
    VARIABLES,
    result_path,
)
from multilayer.provenance import fipy_version, provenance
from multilayer.scenario.source import safe_load


class WriteFailed(RunError):
    """A file of the run could not be written (exit code 1): its directory removed, moved or
    made read-only during the run, an I/O error, or no room (:class:`DiskFull`)."""


class DiskFull(WriteFailed):
    """A write found no room: the disk is full or the file size limit is reached (exit code 1)."""


class ResultWriter:
    """Append output times of a :class:`~multilayer.simulation.Simulation` to ``path``.

    A new file is created unless ``records`` is given: then the existing file is opened
    for appending and the next output time is written as record number ``records``
    (records beyond it, written after the checkpoint being resumed, are overwritten).
    ``last_time`` is the time of the last record kept (NaN before the first).  ``text`` is
    the scenario's :meth:`~multilayer.scenario.schema.Scenario.resolved_yaml`, written by
    the caller once for the header, the checkpoints and :meth:`close`.
    """

    def __init__(
        self, path: str | os.PathLike, scenario: Any, text: str, sim: Any, records: int | None = None
    ) -> None:
        self.path = Path(path)
        self.failure = ""
        """Why the run failed; written as the ``failure`` attribute on close when not empty."""
        self._broken = False  # a write failed: the netCDF handle cannot be trusted
        n_layers, n_cells = sim.read_only("u").shape
        self._mixture = getattr(sim, "mixture", None) is not None
        # the relaxing pore pressure at the bottom of each layer, where there are several
        relaxing = self._mixture and sim.mixture.config.compressibility is not None
        self._layered_pressure = relaxing and n_layers > 1
        # a mixture's records hold phi and p_e, not the forces (docs/mixture.md)
        extra = (n_layers * (1 + self._layered_pressure) + 2) * n_cells if self._mixture else len(FORCES)
        self._record_bytes = 8 * ((n_layers + 2) * n_cells + 3 + extra)
        with NETCDF_LOCK:
            try:
                self._open(scenario, text, sim, records)
            except (OSError, RuntimeError) as exc:  # no room for the header (a forced run, a full disk)
                failure = self._failure(exc, f"{'creating' if records is None else 'reopening'} {self.path}")
                if "_ds" not in self.__dict__ and not isinstance(failure, DiskFull):
                    raise  # not opened (a read-only file): the OSError names it, the file is kept
                if "_ds" in self.__dict__:
                    with contextlib.suppress(OSError, RuntimeError):
                        self._ds.close()
                    _abandon(self._ds)
                if records is None:  # a header written in part: no result file, not a damaged one
                    self.path.unlink(missing_ok=True)
                raise failure from None
        self._file = _identity(self.path)  # the file written: the path may come to name another

    def _open(self, scenario: Any, text: str, sim: Any, records: int | None) -> None:
        """Create the file (``records`` None) or reopen it to append after ``records``."""
        if records is None:
            self._ds = netCDF4.Dataset(self.path, "w", format=FORMAT)
            self._define(scenario, text, sim)
            self.records = 0
            self.last_time = math.nan
        else:
            _cut_to_header(self.path)
            self._ds = netCDF4.Dataset(self.path, "a")
            origin = provenance()
            by = made_by(origin.version, origin.commit)
            self._ds.history += f"\n{_now()} multilayer run --resume, by {by}"
            self.records = records
            self.last_time = float(self._ds["time"][records - 1])
        self._ds.run_status = "running"
        self._ds.header_space = " " * HEADER_SPACE
        self._ds.sync()

    def _failure(self, exc: BaseException, what: str) -> WriteFailed:
        """The error of a write into the file that failed with ``exc`` (``what``: the
        write, in words): :class:`DiskFull` naming the limit where no room is left.
        netCDF-C may report a later consequence of the failed write (still in define mode
        after its header update failed): the room left tells a full disk apart."""
        free, limit = disk.room(self.path)
        reason = disk.full_disk_reason(exc) or (limit.split(":")[0] if free < disk.SLACK else None)
        if reason is None:
            return WriteFailed(f"{what} failed ({exc})")
        return DiskFull(f"{reason}: {what} failed ({exc})")

    def _define(self, scenario: Any, text: str, sim: Any) -> None:
        ds = self._ds
        n_layers, n_cells = sim.read_only("u").shape
        ds.createDimension("time", None)
        ds.createDimension("x", n_cells)
        ds.createDimension("layer", n_layers)
        ds.createDimension("nv", 2)
        variables = VARIABLES
        if self._mixture:  # the forces of a mixture are not computed (docs/mixture.md)
            variables = {**{k: v for k, v in VARIABLES.items() if k not in FORCES}, **MIXTURE_VARIABLES}
            if not self._layered_pressure:
                variables.pop("pore_pressure_layer")
        for name, (dims, attrs) in variables.items():
            if name == "layer":
                var = ds.createVariable(name, "i4", dims)
            else:
                var = ds.createVariable(name, "f8", dims, fill_value=np.nan)
            var.setncatts(attrs)
        ds["front"].threshold = float(sim.front_threshold)
        ds["front"].threshold_units = "m"
        tops = np.cumsum(sim.fractions)
        ds["x"][:] = sim.x
        ds["x_bnds"][:] = np.column_stack([sim.x - sim.dx / 2, sim.x + sim.dx / 2])
        ds["layer"][:] = np.arange(1, n_layers + 1)
        ds["sigma"][:] = sim.sigma
        ds["sigma_bnds"][:] = np.column_stack([tops - sim.fractions, tops])
        ds["bed"][:] = sim.bed
        origin = provenance()
        ds.setncatts(
            {
                "Conventions": "CF-1.8",
                "title": f"multilayer simulation: {scenario.name}",
                "institution": _text(os.environ.get("MULTILAYER_INSTITUTION", "not specified")),
                "source": f"multilayer {origin.version} (commit {origin.commit}): multilayer "
                f"shallow-flow model of dense granular flows; X-sigma mesh and reference formulations "
                f"in FiPy {fipy_version()}, state in numpy, transport and vertical step by numba "
                f"kernels tested equal to them (transport_solver: {scenario.numerics.transport_solver}, "
                f"vertical_solver: {scenario.numerics.vertical_solver})",
                "history": _text(f"{_now()} multilayer run {scenario.source or scenario.name}"),
                "references": "Fernandez-Nieto, Garres-Diaz, Mangeney & Narbona-Reina "
                "(2016) J. Fluid Mech. 798; Bouchut, Ionescu & Mangeney "
                "(2016) Commun. Math. Sci. 14",
                "scenario": text,
                "steps": 0,
                "cells": int(n_cells * n_layers),
                "wall_time_s": 0.0,
                "multilayer_version": origin.version,
                "multilayer_commit": origin.commit,
                "multilayer_dirty": origin.dirty,
                "fipy_version": fipy_version(),
            }
        )

    def write(self, sim: Any) -> dict:
        """Append the current state of ``sim`` as the next output time, sync, and return
        the diagnostics written."""
        ds, i = self._ds, self.records
        diag = sim.diagnostics()
        forces = {} if self._mixture else sim.forces.take()  # the means over the interval this record closes
        if self._broken:
            raise DiskFull(f"{self.path}: an earlier write failed; no more records are written")
        self.check_file()
        self._ensure_room()
        try:
            with NETCDF_LOCK:
                h = sim.read_only("h")  # read-only views: sim.h would be checked at the next step
                ds["h"][i, :] = h
                ds["u"][i, :, :] = sim.read_only("u")
                ds["static_interface"][i, :] = diag["static_interface"]
                if self._mixture:
                    ds["phi"][i, :] = sim.mixture.phi(h)
                    ds["phi_layer"][i, :, :] = sim.mixture.phi_layers(h)
                    ds["pore_pressure_excess"][i, :] = sim.read_only("pore_pressure")[0]
                    if self._layered_pressure:
                        ds["pore_pressure_layer"][i, :, :] = sim.read_only("pore_pressure")
                ds["front"][i] = diag["front"]
                ds["mass"][i] = diag["mass"]
                for name, value in forces.items():
                    ds[name][i] = value
                ds["time"][i] = sim.t
                ds.steps = int(sim.steps)
                ds.sync()
        except (OSError, RuntimeError) as exc:
            self._broken = True
            raise self._failure(exc, f"writing output time {i} into {self.path}") from None
        self.records = i + 1
        self.last_time = float(sim.t)
        return diag

    def check_file(self) -> None:
        """Raise :class:`WriteFailed` unless ``path`` still names the file written (records
        written on into a file removed or replaced would be lost with it)."""
        if _identity(self.path) != self._file:
            raise WriteFailed(
                f"{self.path} was removed, moved or replaced during the run, with the output times written "
                "into it"
            )

    def _ensure_room(self) -> None:
        """Raise :class:`DiskFull` unless the next record fits on the disk and under the
        file size limit."""
        free, limit = disk.room(self.path)
        if free < self._record_bytes + disk.SLACK:
            raise DiskFull(f"{limit}: the next record of {self.path} needs {self._record_bytes} bytes")

    def close(
        self, steps: int, wall_time_s: float, status: str = "completed", text: str | None = None
    ) -> None:
        """Record the final step count, wall time and run status, then close the file.

        The attributes take the room kept in the header (no record moves).  After a write
        that failed (a full disk), the file is reopened to record them, its header first
        set back to the records written whole: every record written before stays readable.
        ``text``: the resolved YAML of the run's scenario, written over the header's (a
        resumed run's own)."""
        count = np.int32(steps) if steps <= STEPS_INT32 else np.float64(steps)  # a larger int32 is 0
        attrs: dict[str, Any] = {"steps": count, "wall_time_s": float(wall_time_s), "run_status": status}
        if text is not None and not self._broken:
            attrs["scenario"] = text
        if self.failure or status == "failed":  # a failed run says why, even without a message
            attrs["failure"] = _text(self.failure or "no message (an exception without one)")[:FAILURE_LENGTH]
        with NETCDF_LOCK:
            closed = False
            try:
                if not self._broken:
                    _finish(self._ds, attrs)
                self._ds.close()
                closed = True
            except (OSError, RuntimeError):
                _abandon(self._ds)
            if self._broken or not closed:
                self._repair(attrs)

    def _repair(self, attrs: dict[str, Any]) -> None:
        """Set the record count of the header to the records written whole and write
        ``attrs`` (a best effort: the reader names a file left inconsistent)."""
        try:
            layout = read_layout(self.path)
            whole = min(self.records, layout.complete_records(self.path.stat().st_size))
            if layout.numrecs != whole:
                with open(self.path, "r+b") as stream:
                    stream.seek(NUMRECS_OFFSET)
                    stream.write(int(whole).to_bytes(4, "big"))
            ds = netCDF4.Dataset(self.path, "a")
        except (OSError, RuntimeError, LayoutError):
            return
        try:
            _finish(ds, attrs)
            ds.close()
        except (OSError, RuntimeError):
            _abandon(ds)


def _cut_to_header(path: Path) -> None:
    """Cut the bytes of ``path`` beyond those its header declares (:func:`declared_size`):
    a resumed run wrote its records over them and kept the rest (a terabyte of zeros
    appended to the file stayed after it)."""
    declared = declared_size(path)
    if declared is not None and path.stat().st_size > declared:
        os.truncate(path, declared)


def _finish(ds: netCDF4.Dataset, attrs: dict[str, Any]) -> None:
    """Replace the reserved header space of ``ds`` by its final attributes ``attrs``."""
    for name in ("header_space", "failure"):  # failure: of an earlier run that was resumed
        if name in ds.ncattrs():
            ds.delncattr(name)
    ds.setncatts(attrs)


def _abandon(ds: netCDF4.Dataset) -> None:
    """Forget a dataset whose close failed: netCDF-C has released it, and netCDF4 would
    close it again when the object is collected, which crashes the interpreter."""
    netCDF4.Dataset.__dict__["_isopen"].__set__(ds, 0)


def _text(value: str) -> str:
    """``value`` as valid UTF-8 text, what a netCDF attribute holds: bytes of the
    environment or of a path that are not UTF-8 (Python keeps them as lone surrogates)
    and lone surrogates of any other origin (a plugin's message in a failure) become
    U+FFFD (netCDF4 raised ``UnicodeEncodeError`` as the failed run's result was closed)."""
    try:
        raw = value.encode("utf-8", "surrogateescape")  # a byte kept by Python: one U+FFFD
    except UnicodeEncodeError:
        raw = value.encode("utf-8", "surrogatepass")
    return raw.decode("utf-8", "replace")


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")


def open_result(
    path: str | os.PathLike, *, load: bool = True, use: Literal["answer", "records"] = "records"
) -> xr.Dataset:
    """Load a result file (or the ``result.nc`` inside a directory) into memory, or with
    ``load=False`` open it lazily (close it after use, e.g. in a ``with`` block).

    The file is checked first (:func:`multilayer.io.result_check.check_result`, for
    ``use``: ``records`` accepts the records of a failed or interrupted run, ``answer``
    only a completed run): a truncated, damaged or still running result is an
    :class:`InputError` naming the file and what is wrong.
    """
    from multilayer.io.result_check import check_result  # it reads the constants of this module

    file = check_result(path, use)
    try:
        return decoded(file, load=load)
    except (OSError, ValueError) as exc:
        raise InputError(f"{file}: not a readable netCDF result file ({reason(exc)})") from None


_DECODING = threading.Lock()
"""Held by :func:`decoded`: two threads of a study scoping the warning filters at once
would each put back what the other saw."""


def decoded(file: str | os.PathLike, *, load: bool = True) -> xr.Dataset:
    """``file`` read by xarray (loaded into memory, or with ``load=False`` opened lazily),
    the host process's warning filters left as they were: xarray's decoding of every file
    (``xarray.conventions.decode_cf_variables``) puts a filter of its own ("once" for its
    ``decode_timedelta`` FutureWarning) in front of the process's, where it overrode a
    filter the host added after the first read."""
    with _DECODING, warnings.catch_warnings():
        return xr.load_dataset(file) if load else xr.open_dataset(file)


def run_failure(path: str | os.PathLike) -> str | None:
    """Why the run in ``path`` (a result file or its directory) cannot be used: ``None`` if it
    completed and its file passes every check of :func:`multilayer.io.result_check.check_result`,
    else what is wrong (the failure message, the run status, the damage).  This is how a
    sweep (and any ensemble command) decides that a member failed."""
    from multilayer.io.result_check import check_result

    try:
        check_result(path, "answer")
    except InputError as exc:
        return str(exc)
    return None


def recorded(path: str | os.PathLike, name: str) -> str:
    """The attribute ``name`` of a result file (or of the ``result.nc`` in a directory) as
    text: ``scenario``, the resolved scenario of the run it holds; ``made_by``, the
    multilayer (version and commit) that wrote its first records."""
    with NETCDF_LOCK, netCDF4.Dataset(result_path(path)) as nc:
        if name == "made_by":
            return made_by(str(nc.getncattr("multilayer_version")), str(nc.getncattr("multilayer_commit")))
        return str(nc.getncattr(name))


def record_time(path: str | os.PathLike, record: int) -> float:
    """The time (s) of record number ``record`` of a result file (or of the ``result.nc``
    in a directory)."""
    with NETCDF_LOCK, netCDF4.Dataset(result_path(path)) as nc:
        return float(nc["time"][record])


def made_by(version: str, commit: str) -> str:
    """How messages and the history name a version of multilayer."""
    return f"multilayer {version} (commit {commit})"


SUMMARY_KEYS = (
    "t_final",
    "front_final",
    "runout",
    "mass_final",
    "max_speed_final",
    "static_interface_mean_final",
    "peak_seismic_force_x",
    "peak_seismic_force_z",
    "steps",
    "wall_time_s",
)
"""The keys of :func:`summary`, in order."""
MIXTURE_SUMMARY_KEYS = ("pore_pressure_bed_mean_final", "phi_mean_final")
"""The further keys of :func:`summary` for a grain–fluid mixture."""
SUMMARY_UNITS = {
    "t_final": "s",
    "front_final": "m",
    "runout": "m",
    "mass_final": "m2",
    "max_speed_final": "m/s",
    "static_interface_mean_final": "m",
    "peak_seismic_force_x": "N/m",
    "peak_seismic_force_z": "N/m",
    "pore_pressure_bed_mean_final": "Pa",
    "phi_mean_final": "1",
    "steps": "",
    "wall_time_s": "s",
}
"""The unit of each key of :func:`summary` (CF spelling; steps are a count)."""


def summary(path: str | os.PathLike, *, checked: bool = True) -> dict[str, float]:
    """Scalar results of a completed run: the quantities ``expect`` checks can refer to.

    ``runout`` is the final minus the initial front; ``max_speed_final`` the largest
    ``|u|`` at the final time; ``static_interface_mean_final`` the mean static-interface
    height over the cells wetter than the front threshold (NaN if none);
    ``peak_seismic_force_x`` and ``_z`` the largest magnitude of the seismic single force
    per unit width, the force on the bed and the walls less the weight, over the output
    intervals (:func:`seismic_force`; NaN for a single record and for a mixture, whose
    result holds no forces); with a fluid,
    ``pore_pressure_bed_mean_final`` and ``phi_mean_final`` are the means of the basal
    excess pore pressure and of the solid fraction over the wet cells.  The file is
    checked first as the answer of a run (``checked=False``: by the run that has just
    written it, whose every state passed the state guard).
    """
    if checked:
        from multilayer.io.result_check import check_result

        check_result(path, "answer")
    # read with netCDF4 itself: the last record, the first front, the forces of every record;
    # under the lock of netCDF-C, which is not thread-safe: a run ending in one thread while
    # another created its result file crashed the process (a study's members on threads)
    with NETCDF_LOCK, netCDF4.Dataset(result_path(path)) as nc:
        nc.set_auto_mask(False)  # NaN fills stay NaN, as xarray reads them
        records = {name: var for name, var in nc.variables.items() if var.dimensions[:1] == ("time",)}
        final = {name: var[-1] for name, var in records.items()}
        front0 = float(nc["front"][0])
        threshold = float(nc["front"].getncattr("threshold"))
        seismic = seismic_force(nc.variables) if "bed_force_x" in records else None
        steps, wall_time = int(nc.getncattr("steps")), float(nc.getncattr("wall_time_s"))
    wet = final["h"] > threshold
    static = final["static_interface"][wet]
    mixture = {key: _wet_mean(final, name, wet) for key, name in _MIXTURE_MEANS.items() if name in final}
    return {
        "t_final": float(final["time"]),
        "front_final": float(final["front"]),
        "runout": float(final["front"] - front0),
        "mass_final": float(final["mass"]),
        "max_speed_final": float(np.abs(final["u"]).max()),
        "static_interface_mean_final": float(static.mean()) if static.size else float("nan"),
        **{f"peak_seismic_force_{c}": _peak(seismic[i] if seismic else None) for i, c in enumerate("xz")},
        "steps": steps,
        "wall_time_s": wall_time,
        **mixture,
    }


def seismic_force(ds: Any) -> tuple[np.ndarray, np.ndarray]:
    """The seismic single force per unit width (N/m) of each output interval, downslope and
    normal: the mean force of the flow on the bed and the walls less its weight, ``F - M g``
    (-dP/dt without outflow; Favreau et al. 2010, Toney & Allstadt 2021), NaN at the first
    record.  ``ds`` maps the names of :data:`FORCES` to their records (a result's
    ``xarray.Dataset``, or arrays)."""
    f = {name: np.asarray(ds[name][:], dtype=float) for name in FORCES}
    total = f["bed_force_x"] + f["wall_force_x"] + f["end_force_x"] + f["pressure_force_x"]
    return total - f["gravity_force_x"], f["bed_force_z"] - f["gravity_force_z"]


def _peak(values: np.ndarray | None) -> float:
    """The largest magnitude of ``values`` after the first record (NaN if none)."""
    return float(np.abs(values[1:]).max()) if values is not None and values.size > 1 else float("nan")


_MIXTURE_MEANS = dict(zip(MIXTURE_SUMMARY_KEYS, ("pore_pressure_excess", "phi")))


def _wet_mean(final: dict[str, np.ndarray], name: str, wet: np.ndarray) -> float:
    """Mean of ``name`` over the wet cells (NaN if none)."""
    return float(final[name][wet].mean()) if wet.any() else float("nan")


@dataclass
class Checkpoint:
    """Everything needed to continue a run: engine state and result-file bookkeeping."""

    state: dict[str, Any]
    """:meth:`Simulation.state_dict` at the checkpoint."""
    records: int
    """Number of output times in ``result.nc`` at the checkpoint."""
    wall_time_s: float
    """Wall time spent on the run up to the checkpoint, s."""
    scenario: str
    """Resolved YAML of the scenario that produced the state."""


_META = ("records", "wall_time_s", "scenario")


def _checksum(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 of the names, dtypes, shapes and bytes of ``arrays`` (in name order)."""
    digest = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        digest.update(f"{name}|{a.dtype.str}|{a.shape}|".encode())
        digest.update(a.tobytes())
    return digest.hexdigest()


def _identity(path: Path) -> tuple[int, int] | None:
    """The device and inode of the file ``path`` names (None if none)."""
    try:
        status = path.stat()
    except OSError:
        return None
    return status.st_dev, status.st_ino


def save_checkpoint(path: str | os.PathLike, ckpt: Checkpoint) -> None:
    """Write ``ckpt`` to ``path`` atomically (temporary file, fsync, rename), with its checksum.

    The temporary file is made afresh, whatever had its name (one left by a process killed
    mid-write is this file's own; a named pipe put there held the run for ever at its first
    checkpoint, a symbolic link had its target written over)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    arrays: dict[str, Any] = {f"state.{key}": np.asarray(value) for key, value in ckpt.state.items()}
    arrays.update({f"meta.{key}": np.asarray(getattr(ckpt, key)) for key in _META})
    arrays["checksum"] = np.asarray(_checksum(arrays))
    try:
        tmp.unlink(missing_ok=True)  # the entry, not a link's target; a directory there: OSError
        with open(tmp, "xb") as f:
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        with contextlib.suppress(OSError):  # the space it took back; the previous checkpoint stands
            tmp.unlink(missing_ok=True)
        full = disk.full_disk_reason(exc)
        if full is None:
            raise WriteFailed(f"writing the checkpoint {path} failed ({reason(exc)})") from None
        raise DiskFull(f"{full}: writing the checkpoint {path} failed ({exc})") from None


def _oversized_member(path: str | os.PathLike) -> str | None:
    """What in the archive ``path`` would be read into more memory than the file holds, or
    None: :func:`save_checkpoint` stores its arrays uncompressed, each of the size its
    ``.npy`` header declares.  A member compressed 1000 to 1 (a MB of zeros deflated to a
    kB) read as its declared size: a checkpoint of 1 MB took 2.3 GB and 29 s before its
    checksum refused it, one of 20 MB exhausted the memory."""
    with zipfile.ZipFile(path) as archive:
        members = archive.infolist()
        unpacked = sum(info.file_size for info in members)
        if unpacked > os.path.getsize(path):
            return f"its members unpack to {unpacked} bytes, more than the file's"
        for info in members:
            with archive.open(info) as member:
                version = np.lib.format.read_magic(member)
                read_header = (
                    np.lib.format.read_array_header_1_0
                    if version == (1, 0)
                    else np.lib.format.read_array_header_2_0
                )
                shape, _, dtype = read_header(member)
            declared = math.prod(shape) * dtype.itemsize
            if declared > info.file_size:
                return f"{info.filename} declares {declared} bytes of data in {info.file_size}"
    return None


def load_checkpoint(path: str | os.PathLike) -> Checkpoint:
    """Read a checkpoint written by :func:`save_checkpoint`; :class:`InputError` (naming the
    file) if it is unreadable, truncated, holds objects or fails its checksum."""

    def value(a: np.ndarray) -> Any:
        return a.item() if a.ndim == 0 else a

    def corrupt(why: str) -> InputError:
        return InputError(
            f"{path}: corrupt checkpoint ({why}); start again without --resume "
            "(the run is then computed afresh)"
        )

    try:
        oversized = _oversized_member(path)
        if oversized is not None:
            raise corrupt(oversized)
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except InputError:
        raise
    except Exception as exc:  # noqa: BLE001 - damaged data raises OSError, BadZipFile, zlib.error, ...
        raise corrupt(f"{type(exc).__name__}: {exc}") from None
    stored = arrays.pop("checksum", None)
    if stored is None or stored.ndim != 0 or str(stored) != _checksum(arrays):
        raise corrupt("no checksum" if stored is None else "checksum mismatch")
    try:
        state = {k[len("state.") :]: value(a) for k, a in arrays.items() if k.startswith("state.")}
        meta = {key: value(arrays[f"meta.{key}"]) for key in _META}
        missing = {"t", "steps", "h", "u"} - set(state)
        if missing:
            raise KeyError(", ".join(sorted(missing)))
    except KeyError as exc:
        raise corrupt(f"missing {exc}") from None
    # a checkpoint of another version or edited: numbers where numbers are read, text for the scenario
    for key, a in arrays.items():
        if key != "meta.scenario" and (a.dtype.kind not in "iuf" or not np.isfinite(a).all()):
            raise corrupt(f"{key} holds {'values that are not finite' if a.dtype.kind in 'iuf' else a.dtype}")
    if (
        not isinstance(meta["scenario"], str)
        or arrays["meta.records"].dtype.kind not in "iu"
        or meta["records"] < 1
    ):
        raise corrupt("meta.scenario is not text or meta.records no count of records")
    try:  # the scenario it computed, compared key by key with the one resuming it
        scenario = safe_load(meta["scenario"])
    except yaml.YAMLError:  # was a traceback (exit 1)
        scenario = None
    if not isinstance(scenario, dict):
        raise corrupt("meta.scenario is not the YAML mapping of a scenario")
    return Checkpoint(state=state, **meta)
