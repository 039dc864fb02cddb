"""The Python API for scripts and notebooks: :func:`load` a scenario, :func:`run` it.

``multilayer.load`` and ``multilayer.run`` are these functions; ``multilayer.Simulation``
steps a loaded scenario by hand (docs/api.md).  :func:`run` goes through the same runner
as ``multilayer run``, so its Dataset is the CLI's ``result.nc``.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import xarray as xr

from multilayer import scenario as scenarios
from multilayer.errors import InputError, Interrupted, RunError, plain_scalar
from multilayer.io.results import open_result
from multilayer.scenario import Scenario, limits
from multilayer.scenario.messages import directory_ending, shown

ScenarioLike = Scenario | str | os.PathLike | Mapping[str, Any]
Overrides = Mapping[str, Any] | Sequence[str]


def _override_strings(overrides: Overrides) -> list[str]:
    """``--set`` strings from ``{"domain.cells": 200}`` or ``["domain.cells=200"]``."""
    accepted = 'a mapping of dotted keys to values, or a list of "KEY=VALUE" strings'
    if isinstance(overrides, Mapping):
        strings = []
        for key, value in overrides.items():
            if not isinstance(key, str) or "=" in key:
                raise InputError(
                    f"overrides: key {shown(key)}; accepted: {accepted} (keys are strings without '=')"
                )
            try:
                text = json.dumps(limits.plain_data(value, f"overrides: {key}"), allow_nan=False)
            except (TypeError, ValueError):
                raise InputError(
                    f"overrides: {key}: {shown(value)} is not a value of a scenario; accepted: "
                    f"{limits.PLAIN_VALUES}"
                ) from None
            strings.append(f"{key}={text}")  # JSON is YAML
        return strings
    if isinstance(overrides, str):
        return [overrides]
    if not isinstance(overrides, Sequence) or not all(isinstance(item, str) for item in overrides):
        raise InputError(f"overrides: got {shown(overrides)}; accepted: {accepted}")
    return list(overrides)


def load(source: ScenarioLike, overrides: Overrides = ()) -> Scenario:
    """A validated scenario from a YAML file or a mapping, with ``overrides`` applied.

    ``overrides`` maps dotted keys to values (``{"domain.cells": 200, "initial.0.height":
    0.05}``) or lists ``"KEY=VALUE"`` strings as ``multilayer run --set`` takes them.
    Raises :class:`multilayer.errors.InputError` naming the file, the key and what is
    accepted.  A :class:`Scenario` given as ``source`` is validated again with the
    overrides applied.
    """
    sets = _override_strings(overrides)
    if isinstance(source, Scenario):
        return scenarios.validated_again(source, sets)
    if isinstance(source, Mapping):
        return scenarios.from_dict(limits.plain_data(source, "<scenario>"), overrides=sets)
    accepted = "a Scenario, a mapping of scenario keys or the path of a YAML file"
    path = _path(source, "scenario", accepted)
    if isinstance(source, str) and (why := directory_ending(source)):  # which pathlib drops
        raise InputError(f"scenario: {why}; accepted: {accepted}")
    return scenarios.load(path, sets)


def _path(value: object, what: str, accepted: str) -> Path:
    """``value`` as a path (:class:`InputError` naming ``what`` if it is none)."""
    if not isinstance(value, (str, os.PathLike)) or isinstance(os.fspath(value), bytes):
        raise InputError(f"{what}: got {shown(value)}; accepted: {accepted}")
    if not os.fspath(value):  # Path('') is '.': a run went into the working directory
        raise InputError(f"{what}: an empty path; accepted: {accepted} ('.' for the working directory)")
    return Path(value)


def run(
    scenario: ScenarioLike,
    outdir: str | os.PathLike | None = None,
    *,
    overrides: Overrides = (),
    quiet: bool = True,
) -> xr.Dataset:
    """Run a scenario to its ``time.end`` and return the result as an in-memory Dataset.

    With ``outdir`` the run writes ``outdir/result.nc`` (plus ``run.log`` and a checkpoint)
    exactly as ``multilayer run -o outdir`` does.  Without it the run goes through a
    temporary directory that is removed afterwards, unless the run fails or is interrupted:
    then it stays, with the output times computed and the checkpoint, and the error names
    it (and the command that resumes the run).  The Dataset has the layout of
    docs/results.md.  ``scenario`` is anything :func:`load` takes; ``quiet=False`` shows
    the progress line (and says so when numba compiles the kernels, once after installing;
    the Newton kernel in a child process where a second core is free).  Raises
    :class:`multilayer.errors.RunError` if the engine fails.
    """
    from multilayer.app.numba_environment import named

    with named():
        from multilayer.app import runner  # the engine is imported only to run

    given = plain_scalar(quiet)  # numpy's True (an element of a mask) is True
    if not isinstance(given, bool):  # "no" or 0.0 read as true would silence the progress line
        raise InputError(f"quiet: got {shown(quiet)}; accepted: True or False")
    quiet = given
    loaded = load(scenario, overrides)
    if outdir is not None:
        outdir = _path(outdir, "outdir", "None or the path of a directory")
        runner.run(loaded, outdir, quiet=quiet)
        return open_result(outdir)
    tmp = tempfile.mkdtemp(prefix="multilayer-")
    kept = False
    try:
        runner.run(loaded, tmp, quiet=quiet)
        return open_result(tmp)
    except (RunError, Interrupted):  # what was computed is kept where the message says (it was removed)
        kept = True
        raise
    finally:
        if not kept:
            shutil.rmtree(tmp, ignore_errors=True)
