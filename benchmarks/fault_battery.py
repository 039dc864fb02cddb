"""The fault battery of docs/reliability.md: bad inputs and faults, tried as a user would.

Every case runs the ``multilayer`` command line in a child process (with a patch applied
for the plugin and engine faults) and is *handled* when the exit code is the expected
one, no traceback is printed and stderr names the culprit (a phrase given per case); for
faults during a run, ``result.nc`` must also keep what was computed before.  Prints one
line per case and the counts.

    python benchmarks/fault_battery.py [-k SUBSTRING] [--round N] [-j 2]
"""

from __future__ import annotations

import argparse
import copy
import importlib.util
import itertools
import json
import os
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import yaml

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""The signals a run stops on: the cases' children start with them at their default."""

NETCDF = threading.Lock()
"""Held by every netCDF call of this script: the cases run in threads, and neither HDF5 nor
xarray's writer (two files written at once crashed this process) is thread-safe."""

TINY = {
    "name": "tiny",
    "slope_deg": 25.0,
    "domain": {"x_min": 0.0, "x_max": 0.5, "cells": 40, "layers": 3},
    "material": {"density": 1500.0, "grain_diameter": 1.0e-3},
    "rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01},
    "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05}],
    "boundaries": {"left": "wall", "right": "outflow"},
    "time": {"end": 0.2, "output_interval": 0.02},
}

CHILD = """
import sys, time
import numpy as np
from multilayer.app.cli import main
from multilayer.engine import simulation
from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.engine.transport import reference as transport
from multilayer.engine.transport import kernel as transport_kernel
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
calls = [0]
{patch}
sys.exit(main(sys.argv[1:]))
"""


@dataclass
class Case:
    """One fault: the command (after ``multilayer``), the expected exit code and phrase."""

    name: str
    argv: list[str]
    code: int
    phrase: str
    patch: str = ""
    setup: Callable[[Path], object] | None = None  # writes the files of the case into its directory
    signal_after_output: int | None = None
    keeps_output: bool = False
    env: dict[str, str] = field(default_factory=dict)  # added to the child's environment
    file_limit: int | None = None  # RLIMIT_FSIZE of the child (ulimit -f), bytes
    signal_when: tuple[str, int] | None = None  # (file in the case's directory, signal) sent once it exists
    prefix: list[str] = field(default_factory=list)  # a command the child runs under (setpriv)
    plain: bool = False  # the command line itself, nothing imported before (numba's environment)
    here: bool = False  # run in the case's directory (a case that could write into the working one)
    ignored: tuple[int, ...] = ()  # stop signals the child starts with ignored (``nohup cmd &``)
    one_message: bool = False  # stderr must be the one message, nothing printed after it
    result: dict = field(default_factory=dict)


def _scenario(directory: Path, changes: dict | None = None, text: str | None = None) -> Path:
    path = directory / "scenario.yaml"
    if text is not None:
        path.write_text(text)
        return path
    data = json.loads(json.dumps(TINY))
    for key, value in (changes or {}).items():
        node = data
        parts = key.split(".")
        for part in parts[:-1]:
            node = node[int(part)] if isinstance(node, list) else node[part]
        last = parts[-1]
        if value is _DELETE:
            del node[last]
        elif isinstance(node, list):
            node[int(last)] = copy.deepcopy(value)
        else:
            node[last] = copy.deepcopy(value)  # a mapping shared by cases stays as given
    path.write_text(yaml.safe_dump(data))
    return path


_DELETE = object()
INF, NAN = float("inf"), float("nan")

JOP = {"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.6, "I_0": 0.3}
"""Jop's mu(I) on TINY: one Newton iteration does not converge at the first step."""

# TINY as a grain-fluid mixture (docs/mixture.md)
MIXTURE = {
    "fluid": {"density": 1000.0, "viscosity": 1e-3},
    "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
    "initial.0.phi": 0.58,
}
# (name, {dotted key: value}, phrase); validate and run are both tried for each
BAD_VALUES: list[tuple[str, dict, str]] = [
    ("x_max inf", {"domain.x_max": INF}, "domain.x_max"),
    ("x_max nan", {"domain.x_max": NAN}, "domain.x_max"),
    ("x_min -inf", {"domain.x_min": -INF}, "domain.x_min"),
    ("x_max < x_min", {"domain.x_max": -1.0}, "domain.x_max"),
    ("cells 0", {"domain.cells": 0}, "domain.cells"),
    ("cells float", {"domain.cells": 1.5}, "domain.cells"),
    ("cells 1e8", {"domain.cells": 100_000_000}, "of memory"),
    ("layers 1e5", {"domain.layers": 100_000}, "of memory"),
    ("layers 1e8", {"domain.layers": 100_000_000}, "domain.layers"),
    ("layer_fractions inf", {"domain.layer_fractions": [INF, 1.0, 1.0]}, "domain.layer_fractions"),
    ("geometric nan", {"domain.layer_fractions": {"geometric": NAN}}, "domain.layer_fractions"),
    ("width -1", {"domain.width": -1.0}, "domain.width"),
    ("time.end inf", {"time.end": INF}, "time.end"),
    ("time.end nan", {"time.end": NAN}, "time.end"),
    ("time.end 0", {"time.end": 0.0}, "time.end"),
    ("output_interval 3e-8", {"time.output_interval": 3e-8}, "result file of about"),
    ("output_interval 1e-12", {"time.output_interval": 1e-12}, "output times to time.end"),
    ("output_interval inf", {"time.output_interval": INF}, "time.output_interval"),
    ("cfl 1.5", {"time.cfl": 1.5}, "time.cfl"),
    ("gravity inf", {"gravity": INF}, "gravity"),
    ("gravity 0", {"gravity": 0.0}, "gravity"),
    ("slope 90", {"slope_deg": 90.0}, "slope_deg"),
    ("slope nan", {"slope_deg": NAN}, "slope_deg"),
    ("density -1", {"material.density": -1.0}, "material.density"),
    ("grain inf", {"material.grain_diameter": INF}, "material.grain_diameter"),
    ("mu_s negative", {"rheology.mu_s": -0.1}, "mu_s"),
    ("mu_s nan", {"rheology.mu_s": NAN}, "mu_s"),
    ("nu inf", {"rheology.nu": INF}, "nu"),
    ("nu negative", {"rheology.nu": -1.0}, "nu"),
    ("unknown rheology", {"rheology.name": "no_such_law"}, "rheology.name"),
    ("unknown parameter", {"rheology.mu_x": 1.0}, "mu_x"),
    ("rectangle outside", {"initial.0.x_min": 0.6, "initial.0.x_max": 0.8}, "initial.0 (rectangle"),
    ("rectangle partly outside", {"initial.0.x_min": 0.45, "initial.0.x_max": 0.6}, "initial.0 (rectangle"),
    ("rectangle narrower than a cell", {"initial.0.x_max": 0.005}, "narrower than one cell"),
    ("rectangle reversed", {"initial.0.x_min": 0.2}, "initial.0.x_max"),
    ("height nan", {"initial.0.height": NAN}, "initial.0.height"),
    ("height inf", {"initial.0.height": INF}, "initial.0.height"),
    ("profile negative", {"initial.0": {"shape": "profile", "points": [[0, 0.1], [0.1, -0.1]]}}, "initial.0"),
    (
        "profile all zero",
        {"initial.0": {"shape": "profile", "points": [[0, 0.0], [0.1, 0.0]]}},
        "no material",
    ),
    ("profile nan", {"initial.0": {"shape": "profile", "points": [[0, NAN], [0.1, 0.1]]}}, "initial.0"),
    ("layer thickness inf", {"initial.0": {"shape": "layer", "thickness": INF}}, "initial.0.thickness"),
    ("velocity inf", {"initial.0.velocity": {"profile": "plug", "speed": INF}}, "speed"),
    ("bed point nan", {"bed": {"points": [[0.0, 0.0], [0.5, NAN]]}}, "bed.points"),
    ("bed decreasing x", {"bed": {"points": [[0.5, 0.0], [0.0, 0.1]]}}, "bed.points"),
    ("periodic one side", {"boundaries.left": "periodic"}, "boundaries"),
    ("inflow missing", {"boundaries.left": "inflow"}, "boundaries.inflow"),
    ("coulomb without mu", {"base": [{"condition": "coulomb"}]}, "base.0"),
    ("tolerance 0", {"numerics": {"tolerance": 0.0}}, "numerics.tolerance"),
    ("max_iterations 0", {"numerics": {"max_iterations": 0}}, "numerics.max_iterations"),
    ("name missing", {"name": _DELETE}, "name"),
    ("unknown top key", {"colour": "red"}, "colour"),
    ("grains lighter than the bulk", {"material.particle_density": 1000.0}, "material.particle_density"),
    ("mixture phi 0.9", {**MIXTURE, "initial.0.phi": 0.9}, "initial.0.phi"),
    ("mixture phi_critical 0.75", {**MIXTURE, "mixture.phi_critical": 0.75}, "mixture.phi_critical"),
    ("mixture fluid viscosity 1e306", {**MIXTURE, "fluid.viscosity": 1e306}, "fluid.viscosity"),
    ("mixture compressibility 0", {**MIXTURE, "fluid.compressibility": 0.0}, "fluid.compressibility"),
    ("mixture compressibility nan", {**MIXTURE, "fluid.compressibility": NAN}, "fluid.compressibility"),
    ("mixture compressibility inf", {**MIXTURE, "fluid.compressibility": INF}, "fluid.compressibility"),
    ("mixture compressibility 2", {**MIXTURE, "fluid.compressibility": 2.0}, "fluid.compressibility"),
    (
        "mixture pouliquen_forterre",
        {
            **MIXTURE,
            "rheology": {"name": "pouliquen_forterre", "mu_1": 0.38, "mu_2": 0.64, "L": 1e-3, "I_0": 0.3},
        },
        "rheology",
    ),
    (
        "mixture grain_diameter 1e-300",
        {**MIXTURE, "material.grain_diameter": 1e-300},
        "material.grain_diameter",
    ),
]

BAD_FILES: list[tuple[str, str, str]] = [
    ("malformed YAML", "name: [unclosed\n", "malformed YAML"),
    ("empty file", "", "top level"),
    ("a list", "- 1\n- 2\n", "top level"),
    ("duplicate key", yaml.safe_dump(TINY) + "name: again\n", "duplicate key"),
    ("binary garbage", "\x00\x01\x02\xff", "scenario.yaml"),
    (
        "a !!python/object tag",
        yaml.safe_dump(TINY).replace("name: tiny", "name: !!python/object:os.system x"),
        "could not determine a constructor",
    ),
    ("a tab as indentation", yaml.safe_dump(TINY).replace("\n  ", "\n\t", 1), "that cannot start any token"),
    (
        "a merge key given twice",
        yaml.safe_dump(TINY) + "a: &a {b: 1}\nc: {<<: *a, <<: *a}\n",
        "duplicate key",
    ),
]

PLUGIN_FAULTS: list[tuple[str, str, str]] = [
    ("viscosity nan", "return np.full(np.shape(p), np.nan)", "viscosity() returned nan"),
    ("viscosity inf", "return np.full(np.shape(p), np.inf)", "viscosity() returned inf"),
    ("viscosity negative", "return np.full(np.shape(p), -1.0)", "viscosity() returned -1.0"),
    ("viscosity wrong shape", "return np.ones(7)", "viscosity() returned an array of shape (7,)"),
    ("viscosity raises", "raise RuntimeError('broken')", "viscosity() raised RuntimeError: broken"),
    ("viscosity None", "return None", "viscosity() returned"),
    ("viscosity text", "return 'abc'", "viscosity() returned values of type <U3"),
    (
        "viscosity nan mid-run",
        "calls[0] += 1\n    return np.full(np.shape(p), np.nan if calls[0] > 60 else 15.0)",
        "viscosity() returned nan",
    ),
]
YIELD_FAULTS: list[tuple[str, str, str]] = [
    ("yield stress nan", "return np.full(np.shape(p), np.nan)", "yield_stress() returned nan"),
    ("yield stress negative", "return np.full(np.shape(p), -5.0)", "yield_stress() returned -5.0"),
    ("yield stress scalar", "return 3.0", "yield_stress() returned an array of shape ()"),
]

ENGINE_FAULTS: list[tuple[str, str, str]] = [
    ("transport nan mid-run", "h[4] = np.nan", "thickness h = nan"),
    ("transport inf mid-run", "h[4] = np.inf", "thickness h = inf"),
    ("transport creates mass", "h[4] += 0.01", "mass is not conserved"),
    ("transport loses mass", "h[2] *= 0.5", "mass is not conserved"),
    ("transport negative h", "h[3] = -0.001", "negative thickness"),
    ("velocity nan mid-run", "u[1, 3] = np.nan", "velocity u = nan"),
    # 1e-11 m in the last cell while material flows out there: far below the boundary flux
    ("transport creates 1e-11 m at the outflow", "h[-1] += 1e-11", "the transport made an error of"),
]

# built-in laws given, past their validation, parameters whose compiled viscosity form
# (newton_kernel) or yield form is outside the contract: (name, rheology, attribute = value, phrase)
COMPILED_FAULTS: list[tuple[str, dict, str, str]] = [
    (
        "mu(I) with mu_2 < mu_s",
        {"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.5, "I_0": 0.3},
        "mu_2 = 0.1",
        "viscosity() returned -",
    ),
    (
        "Drucker-Prager nu nan",
        {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01},
        "nu = np.nan",
        "returned nan",
    ),
    (
        "power law without floor",
        {"name": "power_law_mu_i", "mu_s": 0.3, "m": 0.2, "alpha": 0.5},
        "shear_rate_floor = 0.0",
        "returned inf",
    ),
    # I_0 below its bound: the Newton iteration of the compiled step fails (its iterate not
    # finite, or, as round-off has it, not converging): the run stops, what it made kept
    (
        "mu(I) with I_0 1e-50",
        {"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.6, "I_0": 0.3},
        "I_0 = 1e-50",
        "the simulation failed at t=",
    ),
    # the compiled yield form (stress_kernel) outside the contract
    (
        "Drucker-Prager mu_s nan",
        {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01},
        "mu_s = np.nan",
        "yield_stress() returned nan",
    ),
]


def _plugin_patch(method: str, body: str) -> str:
    """A faulty method; a faulty viscosity belongs to a plugin without a compiled form."""
    args = "self, p, m" if method == "yield_stress" else "self, g, p, m"
    patch = f"def fault({args}):\n    {body}\nDruckerPrager.{method} = fault\n"
    if method == "viscosity":
        patch += "DruckerPrager.viscosity_kernel = lambda self, material: None\n"
    return patch


def _compiled_patch(assignment: str) -> str:
    """The scenario's built-in law given a parameter past its validation."""
    return (
        "real_init = simulation.Simulation.__init__\n"
        "def init(self, *args, **kwargs):\n"
        "    real_init(self, *args, **kwargs)\n"
        f"    self.vertical.stresses.bulk.{assignment}\n"
        "simulation.Simulation.__init__ = init\n"
    )


def _transport_patch(body: str) -> str:
    """Both transport paths (numpy and compiled) return a corrupted state after 15 calls."""
    return (
        "def corrupting(real):\n"
        "    def fault(*args, **kwargs):\n"
        "        h, u = real(*args, **kwargs)\n"
        "        calls[0] += 1\n"
        "        if calls[0] > 15:\n"
        f"            {body}\n"
        "        return h, u\n"
        "    return fault\n"
        "transport.transport = corrupting(transport.transport)\n"
        "transport_kernel.transport = corrupting(transport_kernel.transport)\n"
    )


PACED = (
    "step = simulation.Simulation.step\n"
    "def paced(self, t_max):\n    time.sleep(0.02)\n    return step(self, t_max)\n"
    "simulation.Simulation.step = paced\n"
)


def _finished_run(directory: Path) -> None:
    """A completed run in ``directory/out`` (for checkpoint and plot cases)."""
    subprocess.run(
        [
            sys.executable,
            "-m",
            "multilayer",
            "run",
            str(_scenario(directory)),
            "-o",
            str(directory / "out"),
            "-q",
        ],
        check=True,
        capture_output=True,
    )


def _damage(how: str) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        _finished_run(directory)
        ckpt = directory / "out" / "checkpoint.npz"
        data = ckpt.read_bytes()
        if how == "truncated":
            ckpt.write_bytes(data[: len(data) // 3])
        elif how == "bit flips":
            ckpt.write_bytes(data[:300] + bytes(b ^ 0x5A for b in data[300:340]) + data[340:])
        elif how == "empty":
            ckpt.write_bytes(b"")
        elif how == "not a zip":
            ckpt.write_text("hello")
        elif how == "pickle planted":
            planted: dict[str, Any] = {"state.h": np.array([{"a": 1}], dtype=object)}
            np.savez(ckpt, **planted)
        elif how in ("values changed", "keys missing"):
            arrays: dict[str, Any] = dict(np.load(ckpt))
            if how == "values changed":
                arrays["state.u"] = arrays["state.u"] * 2
            else:
                arrays.pop("state.h")
            np.savez(ckpt, **arrays)

    return setup


def _result_damage(how: str) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        _finished_run(directory)
        import netCDF4

        path = directory / "out" / "result.nc"
        if how == "truncated":
            path.write_bytes(path.read_bytes()[:500])
            return
        with NETCDF, netCDF4.Dataset(path, "a") as ds:
            if how in ("nan", "failed"):
                h = ds["h"][:]
                h[3, 2:9] = np.nan
                ds["h"][:] = h
                u = ds["u"][:]
                u[4, 1, :] = np.inf
                ds["u"][:] = u
            if how == "failed":
                ds.run_status = "failed"
                ds.failure = "viscosity() returned nan"
            if how == "all nan":
                ds["h"][:] = np.full(ds["h"].shape, np.nan)
                ds["u"][:] = np.full(ds["u"].shape, np.nan)
                ds["mass"][:] = np.full(ds["mass"].shape, np.nan)

    return setup


def _lock(pid_alive: bool, readable: bool = True) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        out = directory / "out"
        out.mkdir()
        if not readable:
            (out / "run.lock").write_text("{garbage")
            return
        pid = os.getppid() if pid_alive else 2**22 + 12345
        record = {"pid": pid, "host": socket.gethostname(), "started": "2026-01-01T00:00:00+00:00"}
        (out / "run.lock").write_text(json.dumps(record))

    return setup


BILLION_LAUGHS = "a: &a [x, x, x, x, x, x, x, x, x, x]\n" + "".join(
    f"{chr(98 + i)}: &{chr(98 + i)} [{', '.join([f'*{chr(97 + i)}'] * 10)}]\n" for i in range(9)
)
HOSTILE_YAML: list[tuple[str, str, str]] = [
    ("alias bomb", BILLION_LAUGHS, "values once its aliases are expanded"),
    ("recursive alias", "name: &a [*a]\n", "lies inside its own anchor"),
    ("recursive mapping", "a: &a\n  b: *a\n", "lies inside its own anchor"),
    ("5000-deep list", "x: " + "[" * 5000 + "]" * 5000 + "\n", "nested more than"),
    ("9 MB of YAML", "# padding\n" * 950_000, "characters of YAML"),
]

# (name, patch of DruckerPrager.yield_stress after a few good calls, phrase): a plugin on the
# numpy path (no compiled forms) misbehaving mid-run
CONTAINED: list[tuple[str, str, str]] = [
    ("sys.exit(0)", "raise SystemExit(0)", "yield_stress() raised SystemExit: 0"),
    ("KeyboardInterrupt", "raise KeyboardInterrupt", "yield_stress() raised KeyboardInterrupt"),
    ("BaseException", "raise BaseException('odd')", "yield_stress() raised BaseException: odd"),
    ("GeneratorExit", "raise GeneratorExit", "yield_stress() raised GeneratorExit"),
    ("complex values", "return np.zeros(np.shape(p), complex)", "returned values of type complex128"),
    ("text values", "return np.full(np.shape(p), 'a')", "returned values of type <U1"),
    ("objects", "return np.full(np.shape(p), None)", "returned values of type object"),
    ("writes its input", "p[...] = 0.0\n    return p", "assignment destination is read-only"),
]
DECLARED_FORMS: list[tuple[str, str, str]] = [
    ("power law with 2 numbers", "return ('power', (1.0, 2.0))", "it takes 4 numbers"),
    ("form of text", "return ('constant', ('a',))", "returned values of type <U1"),
    ("not a pair", "return 'constant'", "must be None or (form name, parameters)"),
    ("sys.exit", "raise SystemExit(3)", "viscosity_kernel() raised SystemExit: 3"),
]
CONSTRUCTOR_FAULTS: list[tuple[str, str]] = [
    ("RuntimeError", "RuntimeError('no licence')"),
    ("sys.exit", "SystemExit(1)"),
    ("ZeroDivisionError", "ZeroDivisionError('division by zero')"),
]


def _mid_run_patch(body: str) -> str:
    """DruckerPrager.yield_stress doing ``body`` after 8 good calls, on the numpy path."""
    return (
        "real = DruckerPrager.yield_stress\n"
        "def fault(self, p, m):\n"
        "    calls[0] += 1\n"
        "    if calls[0] <= 8:\n"
        "        return real(self, p, m)\n"
        f"    {body}\n"
        "DruckerPrager.yield_stress = fault\n"
        "DruckerPrager.yield_stress_kernel = lambda self, material: None\n"
        "DruckerPrager.viscosity_kernel = lambda self, material: None\n"
    )


def _declared_patch(body: str) -> str:
    return f"def declared(self, material):\n    {body}\nDruckerPrager.viscosity_kernel = declared\n"


def _constructor_patch(exc: str) -> str:
    return (
        "def constructor(self, mu_s: float, nu: float, mu_start: float | None = None):\n"
        f"    raise {exc}\n"
        "DruckerPrager.__init__ = constructor\n"
    )


RESULT_DAMAGES = ("truncated", "running", "nan", "mass", "front", "time", "header", "empty")


def _damaged_result(how: str) -> Callable[[Path], None]:
    """A finished run whose result.nc is then damaged: ``how`` of RESULT_DAMAGES."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        import netCDF4

        path = directory / "out" / "result.nc"
        if how == "truncated":
            os.truncate(path, path.stat().st_size // 2)
        elif how == "header":
            data = bytearray(path.read_bytes())
            data[20:40] = b"\xff" * 20
            path.write_bytes(bytes(data))
        elif how == "empty":
            path.write_bytes(b"")
        else:
            with NETCDF, netCDF4.Dataset(path, "a") as ds:
                if how == "running":
                    ds.run_status = "running"
                elif how == "nan":
                    ds["h"][3, 7] = np.nan
                elif how == "mass":
                    ds["mass"][4] = 1.0
                elif how == "front":
                    ds["front"][4] = 0.3
                elif how == "time":
                    ds["time"][2] = 0.001

    return setup


def _sweep(parameters: dict, paired: bool = False, base: dict = TINY) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        (directory / "base.yaml").write_text(yaml.safe_dump(base))
        sweep = {"base": "base.yaml", "parameters": parameters, "zip": paired}
        (directory / "sweep.yaml").write_text(yaml.safe_dump(sweep))

    return setup


def _calibration(
    times: str,
    header: str = "t,x_f,sigma",
    columns: tuple[str, ...] = ("t", "x_f", "sigma"),
    bounds: tuple[float, float] | list[float] = (0.2, 0.4),
    **search: int,
) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        (directory / "base.yaml").write_text(yaml.safe_dump(TINY))
        (directory / "front.csv").write_text(f"{header}\n" + times)
        observation = {
            "name": "front",
            "quantity": "front",
            "file": "front.csv",
            "columns": list(columns),
        }
        config = {
            "base": "base.yaml",
            "parameters": {"rheology.mu_s": {"bounds": list(bounds)}},
            "observations": [observation],
            "search": {"population": 4, "generations": 1, **search},
        }
        (directory / "calibration.yaml").write_text(yaml.safe_dump(config))

    return setup


def _lock_holding(pid: Any) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        _scenario(directory)
        (directory / "out").mkdir()
        record = {"pid": pid, "host": socket.gethostname(), "started": "2026-01-01T00:00:00+00:00"}
        (directory / "out" / "run.lock").write_text(json.dumps(record))

    return setup


def _lock_directory(directory: Path) -> None:
    _scenario(directory)
    (directory / "out" / "run.lock").mkdir(parents=True)


def _fifo(directory: Path) -> None:
    os.mkfifo(directory / "scenario.yaml")


def _long_csv(directory: Path) -> None:
    _scenario(directory, {"bed": {"file": "bed.csv"}})
    (directory / "bed.csv").write_text("x (m), z (m)\n" + "".join(f"{i / 1e3}, 0\n" for i in range(101)))


MANY_OUTPUTS = {"time.end": 0.2, "time.output_interval": 0.005}
"""41 records of 1624 bytes: about 84 kB of result.nc (the disk-full cases)."""
NO_ROOM_CHECK = "from multilayer.io import results\nresults.ResultWriter._ensure_room = lambda self: None\n"
FILLING_DISK = (
    "from multilayer.io import disk\n"
    "real_free = disk.free_space\n"
    "def free_space(directory):\n"
    "    calls[0] += 1\n"
    "    return 1000.0 if calls[0] > 10 else real_free(directory)\n"
    "disk.free_space = free_space\n"
)
FULL_CHECKPOINT = (
    "from multilayer.io import results\n"
    "real_savez = np.savez\n"
    "def savez(*args, **kwargs):\n"
    "    calls[0] += 1\n"
    "    if calls[0] > 3:\n"
    "        raise OSError(28, 'No space left on device')\n"
    "    return real_savez(*args, **kwargs)\n"
    "np.savez = savez\n"
)
SLOW_START = (
    "import pathlib\n"
    "real_init = simulation.Simulation.__init__\n"
    "def slow(self, *args, **kwargs):\n"
    "    pathlib.Path(sys.argv[sys.argv.index('-o') + 1]).joinpath('building').touch()\n"
    "    time.sleep(30)\n"
    "    real_init(self, *args, **kwargs)\n"
    "simulation.Simulation.__init__ = slow\n"
)
FEW_STEPS = (  # the estimate says 5 steps: the bound is reached while running
    "from multilayer.app import resources\n"
    "resources.steps = lambda sc: resources.Steps(5.0, 1.0, 0.01, 0.01)\n"
)


def round_two() -> list[Case]:
    """The hostile cases of the second round (docs/reliability.md): damaged results,
    contained plugins, full disks, bounds on sizes and degenerate values, inputs that
    reached a traceback."""
    out = [
        Case("API: sim.h[3] = 1e308 written between steps", ["validate", "{scenario}"], 1,
             "the wave speed sqrt(g cos(theta) h) + |u| of the state at t = 0.00843656 s (step 2) overflows "
             "(thickness up to 1e+308 m", setup=_scenario,
             patch=WRITTEN_BETWEEN_STEPS.format(write="sim.h[3] = 1e308"))
    ]  # fmt: skip
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    for how in RESULT_DAMAGES:
        for command in (["plot", "{dir}/out"], ["export", "{dir}/out", "--vtk"]):
            out.append(
                Case(
                    f"damaged result: {how}, {command[0]}",
                    command,
                    2,
                    "result.nc: ",
                    setup=_damaged_result(how),
                )
            )
    resume = ["run", "{scenario}", "-o", "{dir}/out", "--resume", "--set", "time.end=0.3", "-q"]
    out.append(
        Case("damaged result: truncated, resume", resume, 2, "truncated", setup=_damaged_result("truncated"))
    )
    for name, body, phrase in CONTAINED:
        out.append(
            Case(
                f"plugin: {name}",
                run,
                1,
                phrase,
                patch=_mid_run_patch(body),
                setup=_scenario,
                keeps_output=True,
            )
        )
    for name, body, phrase in DECLARED_FORMS:
        out.append(Case(f"plugin form: {name}", run, 1, phrase, patch=_declared_patch(body), setup=_scenario))
    for name, exc in CONSTRUCTOR_FAULTS:
        for command in (["validate", "{scenario}"], run):
            out.append(
                Case(
                    f"plugin constructor {name}: {command[0]}",
                    command,
                    2,
                    "DruckerPrager(mu_s=0.3, nu=0.01) raised",
                    patch=_constructor_patch(exc),
                    setup=_scenario,
                )
            )
    many = partial(_scenario, changes=MANY_OUTPUTS)
    forced = [*run, "--force"]
    # a finite drag (1.2e308) whose closure overflows (it was halved for ever), and K = 1e300:
    # refused before the run, naming the key (round 35; a run failing at its first step before)
    for name, key in (("closure overflowing", "fluid.viscosity"), ("dilatancy 1e300", "mixture.dilatancy")):
        changes = {**MIXTURE, key: 1e300}
        out.append(
            Case(
                f"mixture: {name}, run",
                run,
                2,
                f"{key}: the mixture's closure overflows on the initial column",
                setup=partial(_scenario, changes=changes),
            )
        )
    out.append(
        Case(
            "disk: ulimit -f, checked",
            forced,
            1,
            "file too large",
            setup=many,
            file_limit=48 * 1024,
            keeps_output=True,
        )
    )
    out.append(
        Case(
            "disk: ulimit -f, write fails",
            forced,
            1,
            "file too large",
            patch=NO_ROOM_CHECK,
            setup=many,
            file_limit=48 * 1024,
            keeps_output=True,
        )
    )
    out.append(Case("disk: ulimit -f, refused", run, 2, "file size limit", setup=many, file_limit=48 * 1024))
    out.append(Case("disk: full", forced, 1, "disk full", patch=FILLING_DISK, setup=many, keeps_output=True))
    out.append(
        Case(
            "disk: checkpoint full",
            forced,
            1,
            "disk full",
            patch=FULL_CHECKPOINT,
            setup=many,
            keeps_output=True,
        )
    )
    for name, text, phrase in HOSTILE_YAML:
        for command in (["validate", "{scenario}"], run):
            out.append(
                Case(f"yaml {name}: {command[0]}", command, 2, phrase, setup=partial(_scenario, text=text))
            )
    out.append(
        Case(
            "yaml: --set alias",
            ["validate", "{scenario}", "--set", "initial=&a [*a]"],
            2,
            "lies inside its own anchor",
            setup=_scenario,
        )
    )
    out.append(Case("file: /dev/zero scenario", ["validate", "/dev/zero"], 2, "not a regular file"))
    out.append(
        Case("file: a pipe as scenario", ["validate", "{scenario}"], 2, "not a regular file", setup=_fifo)
    )
    out.append(
        Case(
            "file: /dev/zero bed",
            ["validate", "{scenario}"],
            2,
            "not a regular file",
            setup=partial(_scenario, changes={"bed": {"file": "/dev/zero"}}),
        )
    )
    out.append(
        Case(
            "file: CSV beyond its rows",
            ["validate", "{scenario}"],
            2,
            "101 data rows; accepted: at most 100",
            patch="from multilayer.scenario import profiles\nprofiles.MAX_PROFILE_POINTS = 100\n",
            setup=_long_csv,
        )
    )
    dem = {"bed": {"dem": "dem.tif", "polyline": [[0.0, 0.0], [1e9, 0.0]], "spacing": 1e-3}}
    out.append(
        Case(
            "file: DEM polyline of 1e12 samples",
            ["validate", "{scenario}"],
            2,
            "takes 1e+12 points",
            setup=partial(_scenario, changes=dem),
        )
    )
    layer = {"initial": [{"shape": "layer", "thickness": 0.01}]}
    for key, value in (("gravity", 1e300), ("time.cfl", 1e-300), ("domain.x_max", 1e-300)):
        for command in (["validate", "{scenario}"], run):
            out.append(
                Case(
                    f"steps: {key} = {value:g}, {command[0]}",
                    [*command, "--set", f"{key}={value!r}"],
                    2,
                    "time steps",
                    # grains within the domain (no continuum of grains longer than it)
                    setup=partial(_scenario, changes={**layer, "material.grain_diameter": 1e-301}),
                )
            )
    out.append(
        Case(
            "steps: the run reaches --max-steps",
            [*run, "--max-steps", "10"],
            1,
            "--max-steps 20",
            patch=FEW_STEPS,
            setup=_scenario,
            keeps_output=True,
        )
    )
    wide = {"domain.cells": 2, "domain.layers": 20000}
    for command in (["validate", "{scenario}"], run):
        out.append(
            Case(
                f"memory: 20000 layers, {command[0]}",
                [*command, "--max-memory", "8G"],
                2,
                "20000 layers need about",
                setup=partial(_scenario, changes=wide),
            )
        )
    sweep = ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/sweep-out"]
    out.append(
        Case(
            "sweep: 10^12 members",
            sweep,
            2,
            "1000000000000 members",
            setup=_sweep({f"k{i}": list(range(10)) for i in range(12)}),
        )
    )
    out.append(
        Case(
            "sweep: a value twice",
            sweep,
            2,
            "give the same member",
            setup=_sweep({"rheology.mu_s": [0.4, 0.3, 0.40]}),
        )
    )
    out.append(
        Case(
            "sweep: a pair twice",
            sweep,
            2,
            "give the same member",
            setup=_sweep({"rheology.mu_s": [0.3, 0.3], "rheology.nu": [0.01, 0.01]}, True),
        )
    )
    out.append(Case("plot: --times 1000", ["plot", "{dir}", "--times", "1000"], 2, "accepted: 1 to 12 times"))
    calibrate = ["calibrate", "{dir}/calibration.yaml", "-o", "{dir}/cal"]
    out.append(
        Case(
            "calibrate: observations after the run",
            calibrate,
            2,
            "outside the runs",
            setup=_calibration("5,0.2,0.01\n9,0.3,0.01\n"),
        )
    )
    out.append(
        Case(
            "calibrate: population 10^12",
            calibrate,
            2,
            "search.population",
            setup=_calibration("0.1,0.2,0.01\n", population=10**12),
        )
    )
    for pid in ("abc", None, 1e30, 0, -1, [1]):
        out.append(Case(f"lock: pid {pid!r}", run, 0, "taking over a stale lock", setup=_lock_holding(pid)))
    out.append(
        Case("lock: a directory", run, 2, "a stale lock that cannot be removed", setup=_lock_directory)
    )
    # (name, argv, exit code, phrase, environment): a valid scenario in the case's directory
    scenario_cases: list[tuple[str, list[str], int, str, dict[str, str]]] = [
        (
            "--set initial.².height",
            ["validate", "{scenario}", "--set", "initial.².height=0.1"],
            2,
            "accepted indices",
            {},
        ),
        ("MULTILAYER_THREADS=²", run, 2, "MULTILAYER_THREADS", {"MULTILAYER_THREADS": "²"}),
        (
            "MULTILAYER_INSTITUTION not UTF-8",
            run,
            0,
            "",
            {"MULTILAYER_INSTITUTION": os.fsdecode(b"Uni\xff\xfe")},
        ),
        ("-o /proc/x", ["run", "{scenario}", "-o", "/proc/x"], 2, "/proc/x: cannot be created", {}),
        ("-o /dev/null/x", ["run", "{scenario}", "-o", "/dev/null/x"], 2, "cannot be created", {}),
        ("-o not UTF-8", ["run", "{scenario}", "-o", os.fsdecode(b"o\xff")], 2, "not a UTF-8 name", {}),
    ]
    for name, argv, code, phrase, env in scenario_cases:
        out.append(Case(name, argv, code, phrase, setup=_scenario, env=env))
    out.append(
        Case(
            "signal: SIGTERM during start-up",
            ["run", "{scenario}", "-o", "{dir}/out"],
            143,
            "during start-up, before the first step",
            patch=SLOW_START,
            setup=_scenario,
            signal_when=("out/building", signal.SIGTERM),
        )
    )
    return out


def _output_file(name: str, kind: str) -> Callable[[Path], None]:
    """``out/<name>`` made a directory, a pipe or a link to /dev/zero before the run."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        path = directory / "out" / name
        path.parent.mkdir()
        {
            "directory": path.mkdir,
            "pipe": lambda: os.mkfifo(path),
            "device": lambda: path.symlink_to("/dev/zero"),
        }[kind]()

    return setup


def _checkpoint_entry(entry: str, value: Any) -> Callable[[Path], None]:
    """A finished run whose checkpoint holds ``entry = value`` under a valid checksum."""

    def setup(directory: Path) -> None:
        from multilayer.io import results

        _finished_run(directory)
        ckpt = directory / "out" / "checkpoint.npz"
        arrays: dict[str, Any] = dict(np.load(ckpt))
        arrays.pop("checksum")
        arrays[entry] = value(arrays[entry]) if callable(value) else value
        arrays["checksum"] = np.asarray(results._checksum(arrays))
        with open(ckpt, "wb") as stream:
            np.savez(stream, **arrays)

    return setup


def _bed_file(name: str, text: str | None) -> Callable[[Path], None]:
    """A scenario whose bed is read from ``name``: a CSV of ``text``, or a pipe (None)."""

    def setup(directory: Path) -> None:
        key = "dem" if name.endswith(".tif") else "file"
        extra = {"polyline": [[0.0, 0.0], [1.0, 0.0]], "spacing": 0.1} if key == "dem" else {}
        _scenario(directory, {"bed": {key: name, **extra}})
        if text is None:
            os.mkfifo(directory / name)
        else:
            (directory / name).write_text(text, encoding="utf-8")

    return setup


def _piped_output(directory: Path, file: str) -> None:
    """A finished run whose ``out/<file>`` (a figure or a VTK file) is a pipe."""
    _finished_run(directory)
    path = directory / "out" / file
    path.parent.mkdir(exist_ok=True)
    os.mkfifo(path)


def _sweep_file(directory: Path) -> None:
    _scenario(directory)
    sweep = {"base": "scenario.yaml", "parameters": {"domain.cells": [40, 0]}}
    (directory / "sweep.yaml").write_text(yaml.safe_dump(sweep))


def round_three() -> list[Case]:
    """The hostile cases of the third round (docs/reliability.md): the gate on an end face,
    sweeps through validate, --set key paths with an empty part, output files that are no
    regular files, checkpoints of another layout, numbers of a CSV file, a pipe as a DEM."""
    out: list[Case] = []
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    for x in (0.0, 0.5):
        for command in (["validate", "{scenario}"], run):
            out.append(
                Case(
                    f"gate at x = {x}: {command[0]}",
                    command,
                    2,
                    "stands on an end face of the domain",
                    setup=partial(_scenario, changes={"gate": {"x": x, "lift_speed": 0.0}}),
                )
            )
    out.append(
        Case(
            "validate: sweep with an invalid member",
            ["validate", "{dir}/sweep.yaml"],
            2,
            "member m001-",
            setup=_sweep_file,
        )
    )
    for item in ("a..b=1", ".domain=1", "domain.=1"):
        out.append(
            Case(
                f"--set {item}",
                ["validate", "{scenario}", "--set", item],
                2,
                "no part empty",
                setup=_scenario,
            )
        )
    for name in ("result.nc", "checkpoint.npz", "run.log"):
        for kind in ("directory", "pipe", "device"):
            out.append(
                Case(
                    f"output: {name} a {kind}",
                    run,
                    2,
                    "exists and is not a regular file",
                    setup=_output_file(name, kind),
                )
            )
    resume = ["run", "{scenario}", "-o", "{dir}/out", "--resume", "--set", "time.end=0.3", "-q"]
    for name, entry, value, phrase in (
        ("u transposed", "state.u", lambda a: a.T.copy(), "u: float64 values of shape (40, 3)"),
        ("h shorter", "state.h", lambda a: a[:-1].copy(), "h: float64 values of shape (39,)"),
        ("seed window outside", "state.seed_window", np.array([-5, 400]), "outside the columns of the mesh"),
        ("t NaN", "state.t", np.array(np.nan), "state.t holds values that are not finite"),
        ("t text", "state.t", np.array("abc"), "state.t holds <U3"),
        ("scenario a number", "meta.scenario", np.array(5), "meta.scenario is not text"),
        ("steps a float", "state.steps", np.array(2.5), "steps: float64 values"),
    ):
        out.append(Case(f"checkpoint: {name}", resume, 2, phrase, setup=_checkpoint_entry(entry, value)))
    for name, number in (("Arabic-Indic digit", "\u0661"), ("underscore", "1_000")):
        text = f"x (m), z (m)\n0.0, 0.0\n0.5, {number}\n"
        out.append(
            Case(
                f"bed CSV: {name}",
                ["validate", "{scenario}"],
                2,
                "expected two numbers",
                setup=_bed_file("bed.csv", text),
            )
        )
    for command, file in (
        (["plot", "{dir}/out"], "plots/front.png"),
        (["export", "{dir}/out", "--vtk"], "vtk/result.pvd"),
    ):
        out.append(
            Case(
                f"{command[0]}: {file} a pipe",
                command,
                2,
                "exists and is not a regular file",
                setup=partial(_piped_output, file=file),
            )
        )
    for x1 in ("inf", "1e308"):
        out.append(
            Case(
                f"plot: --xlim 0 {x1}",
                ["plot", "{dir}/out", "--xlim", "0", x1],
                2,
                "times as wide",
                setup=_finished_run,
            )
        )
    out.append(
        Case(
            "bed DEM: a pipe",
            ["validate", "{scenario}"],
            2,
            "not a regular file",
            setup=_bed_file("dem.tif", None),
        )
    )
    return out


NOT_ROOT = ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner"]
"""Root without the capabilities that override the permission bits: a user of the files."""
PERIODIC = {"boundaries": {"left": "periodic", "right": "periodic"}}
UNMATCHED_PERIODIC = (  # 1e-12 m2 more enters the left side than leaves the right one, put into the flow
    "if kwargs.get('stage') != 0: kwargs['boundary_mass'][0] += 1e-12; "
    "h[int(np.argmax(h))] += 1e-12 / kwargs['dx']"
)


def _read_only(what: str) -> Callable[[Path], None]:
    """``out`` read-only (``dir``), or its ``result.nc`` in a finished run (``file``)."""

    def setup(directory: Path) -> None:
        if what == "dir":
            _scenario(directory)
            (directory / "out").mkdir(mode=0o555)
            return
        _finished_run(directory)
        target = directory / "out" / ("result.nc" if what == "file" else "")
        target.chmod(0o444 if what == "file" else 0o555)

    return setup


def round_four() -> list[Case]:
    """The hostile cases of the fourth round (docs/reliability.md): numba's environment,
    a denormal end time, periodic sides that do not match, read-only outputs (as a user,
    where root can drop its capabilities); YAML tags, tabs and merge keys are in BAD_FILES."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    out = [
        Case(
            f"env {variable}={value}",
            run,
            2,
            f"environment variable {variable}",
            setup=_scenario,
            env={variable: value},
            plain=True,
        )
        for variable, value in (
            ("NUMBA_NUM_THREADS", "0"),
            ("NUMBA_DISABLE_JIT", "1"),
            ("NUMBA_THREADING_LAYER", "x"),
        )
    ]
    out.append(
        Case(
            "env NUMBA_OPT=x",
            run,
            0,
            "could not be parsed. (ValueError",
            setup=_scenario,
            env={"NUMBA_OPT": "x"},
            plain=True,
        )
    )
    for command in (["validate", "{scenario}"], run):
        out.append(
            Case(
                f"time.end 5e-324: {command[0]}",
                command,
                2,
                "too short to step",
                setup=partial(_scenario, changes={"time.end": 5e-324}),
            )
        )
    out.append(
        Case(
            "engine: periodic sides that do not match",
            run,
            1,
            "the periodic sides do not match",
            patch=_transport_patch(UNMATCHED_PERIODIC),
            setup=partial(_scenario, changes=PERIODIC),
            keeps_output=True,
        )
    )
    if os.geteuid() == 0 and shutil.which("setpriv"):
        for name, command, what, phrase in (
            (
                "run into a read-only directory",
                run,
                "dir",
                "out: cannot be created or written (Permission denied)",
            ),
            ("run over a read-only result.nc", run, "file", "out/result.nc: Permission denied"),
            ("plot of a read-only directory", ["plot", "{dir}/out"], "run", "out/plots: Permission denied"),
            (
                "export of a read-only directory",
                ["export", "{dir}/out", "--vtk"],
                "run",
                "out/vtk: Permission denied",
            ),
        ):
            out.append(
                Case(f"as a user: {name}", command, 2, phrase, setup=_read_only(what), prefix=NOT_ROOT)
            )
    return out


def round_five() -> list[Case]:
    """The hostile cases of the fifth round (docs/reliability.md): an initial state whose
    sums overflow, through ``validate`` and ``run``, and a sweep value written twice
    differently."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    mass = "its mass, the integral of its thickness"  # validate; run bounds the steps first
    out = [
        Case(f"{name}: {command[0]}", command, 2, phrase, setup=partial(_scenario, changes=changes))
        for name, changes, phrases in (
            ("initial height 1e308", {"initial.0.height": 1e308}, (mass, "about inf time steps")),
            (
                "initial layer 1e308",
                {"initial": [{"shape": "layer", "thickness": 1e308}]},
                ("about inf time steps",) * 2,
            ),
            ("domain 1e308 m long", {"domain.x_max": 1e308}, ("no number of cells is enough",) * 2),
        )
        for command, phrase in zip((["validate", "{scenario}"], run), phrases, strict=True)
    ]
    out.append(
        Case(
            "sweep: 20 and 20.0",
            ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/sweep-out"],
            2,
            "give the same member",
            setup=_sweep({"slope_deg": [20, 21, 20.0]}),
        )
    )
    return out


def _scenario_bytes(content: bytes) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        (directory / "scenario.yaml").write_bytes(content)

    return setup


def _scenario_directory(directory: Path) -> None:
    (directory / "scenario.yaml").mkdir()


def _output_is_a_file(directory: Path) -> None:
    _scenario(directory)
    (directory / "out").write_text("")


LONG_PATH = "/".join(["a" * 200] * 25)  # 5024 characters: File name too long


def round_six() -> list[Case]:
    """The hostile cases of the sixth round (docs/reliability.md): keys YAML reads as no
    text, scenario files in other encodings, a name longer than a file name, a directory
    as the scenario, a pressure beyond 1e308 Pa, a plugin value that overflows, ``-o`` a
    file, a path too long for the system, resumes of a changed or relabelled scenario, a
    sweep beyond its members."""
    validate, run = ["validate", "{scenario}"], ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    text = yaml.safe_dump(TINY)
    files = [
        ("a key true", text + "true: x\n", "key True is not text; accepted: name"),
        ("a key null", text + "null: x\n", "key None is not text"),
        (
            "a name of 300 characters",
            text.replace("name: tiny", "name: " + "n" * 300),
            "at most 255 characters",
        ),
    ]
    out = [
        Case(f"validate: {name}", validate, 2, phrase, setup=partial(_scenario, text=body))
        for name, body, phrase in files
    ]
    for name, content, phrase in (
        (
            "UTF-16 with its byte order mark",
            text.encode("utf-16"),
            "UTF-16 text (it starts with the byte order mark",
        ),
        ("UTF-32", text.encode("utf-32"), "UTF-32 text"),
        ("a Latin-1 byte", text.encode() + b"description: caf\xe9\n", "not UTF-8 text: byte 0xE9 at line"),
        ("a NUL character", text.encode() + b"description: a\x00b\n", "the character U+0000"),
    ):
        out.append(Case(f"validate: {name}", validate, 2, phrase, setup=_scenario_bytes(content)))
    out.append(
        Case(
            "validate: a directory as the scenario",
            validate,
            2,
            "not a regular file",
            setup=_scenario_directory,
        )
    )
    heavy = partial(_scenario, changes={"material.density": 1e308})
    for command in (validate, run):
        out.append(
            Case(
                f"{command[0]}: density 1e308",
                command,
                2,
                "the pressure under the initial material",
                setup=heavy,
            )
        )
    out.append(
        Case(
            "run: mu_s 1e100 times a pressure of 4e209 Pa (overflows in the plugin)",
            run,
            1,
            "yield_stress() returned inf",
            setup=partial(_scenario, changes={"rheology.mu_s": 1e100, "material.density": 1e210}),
        )
    )
    out.append(Case("run: -o a file", run, 2, "a file, not a directory", setup=_output_is_a_file))
    for command in (
        ["validate", "{dir}/" + LONG_PATH + "/s.yaml"],
        ["run", "{scenario}", "-o", "{dir}/" + LONG_PATH, "-q"],
    ):
        out.append(
            Case(
                f"{command[0]}: a path of 5024 characters", command, 2, "File name too long", setup=_scenario
            )
        )
    resume = ["run", "{scenario}", "-o", "{dir}/out", "-q", "--resume", "--set"]
    out.append(
        Case(
            "run: --resume with numerics changed",
            [*resume, "numerics.tolerance=1e-9"],
            2,
            "changed: numerics.tolerance",
            setup=_finished_run,
        )
    )
    out.append(
        Case(
            "run: --resume renamed",
            [*resume, "name=renamed"],
            0,
            "resuming with name changed",
            setup=_finished_run,
        )
    )
    out.append(
        Case(
            "sweep: 10100 members",
            ["validate", "{dir}/sweep.yaml"],
            2,
            "at most 10000 members",
            setup=_sweep(
                {
                    "slope_deg": [20 + i / 1000 for i in range(101)],
                    "rheology.mu_s": [0.3 + i / 1e4 for i in range(100)],
                }
            ),
        )
    )
    return out


def _sobol(directory: Path) -> None:
    (directory / "base.yaml").write_text(yaml.safe_dump(TINY))
    config = {
        "base": "base.yaml",
        "parameters": {
            "rheology.mu_s": {"bounds": [0.3, 0.4]},
            "slope_deg": {"bounds": [1e-300, 2e-300]},
        },
        "outputs": ["runout"],
        "samples": 2,
    }
    (directory / "sobol.yaml").write_text(yaml.safe_dump(config))


def round_seven() -> list[Case]:
    """The hostile cases of the seventh round (docs/reliability.md): a built-in law's
    parameter beyond its bounds, a sweep value that is not a number, a study member that
    fails on a worker process, a Sobol' design on a range 1e-300 wide."""
    validate, run = ["validate", "{scenario}"], ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    big = partial(_scenario, changes={"rheology.mu_s": 1e308})
    out = [
        Case(f"{command[0]}: mu_s 1e308", command, 2, "mu_s must be at most 1e+100", setup=big)
        for command in (validate, run)
    ]
    jop = {"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.6, "I_0": 1e-308}
    out.append(
        Case(
            "validate: I_0 1e-308",
            validate,
            2,
            "I_0 must be between 1e-08 and 1e+100",
            setup=partial(_scenario, changes={"rheology": jop}),
        )
    )
    out.append(
        Case(
            "sweep: values [.nan, .nan]",
            ["validate", "{dir}/sweep.yaml"],
            2,
            "entry 0 (.nan) is not a finite number",
            setup=_sweep({"rheology.mu_s": [NAN, NAN]}),
        )
    )
    out.append(
        Case(
            "sweep: a member failing on a worker process",
            ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out", "--workers", "1"],
            1,
            "did not reach tolerance 1e-10 in 1 iterations",
            setup=_sweep({"numerics.max_iterations": [1, 200]}, base={**TINY, "rheology": JOP}),
        )
    )
    out.append(
        Case(
            "validate: a Sobol' design on a range 1e-300 wide",
            ["validate", "{dir}/sobol.yaml"],
            2,
            "two halves of the Sobol' design are correlated",
            setup=_sobol,
        )
    )
    return out


FIPY_SOLVING = (  # a file marks the first call of the FiPy reference solver
    "import pathlib\n"
    "from multilayer.reference import vertical_fipy\n"
    "real_call = vertical_fipy.VerticalStep.__call__\n"
    "def marked(self, *args, **kwargs):\n"
    "    pathlib.Path(sys.argv[sys.argv.index('-o') + 1]).joinpath('solving').touch()\n"
    "    return real_call(self, *args, **kwargs)\n"
    "vertical_fipy.VerticalStep.__call__ = marked\n"
)


def _link_to_a_file(directory: Path) -> None:
    _scenario(directory)
    (directory / "out").symlink_to(directory / "scenario.yaml")


def _odd_path(directory: Path) -> None:
    odd = directory / "uni ñ" / "sc\nn.yaml"
    odd.parent.mkdir()
    odd.write_text(yaml.safe_dump(TINY))


def round_eight() -> list[Case]:
    """The hostile cases of the eighth round (docs/reliability.md): a mu(I) law's ``I_0``
    below what the vertical step resolves, SIGTERM during a FiPy solve, ``--set`` of
    1e999 cells, ``-o`` a link to a file, paths with a newline and characters beyond ASCII."""
    validate, run = ["validate", "{scenario}"], ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    jop = {"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.6, "I_0": 1e-50}
    pf = {"name": "pouliquen_forterre", "mu_1": 0.3, "mu_2": 0.6, "L": 1e-3, "I_0": 1e-9}
    out = [
        Case(
            f"{command[0]}: {law['name']} I_0 {law['I_0']:g}",
            command,
            2,
            "I_0 must be between 1e-08",
            setup=partial(_scenario, changes={"rheology": law}),
        )
        for law in (jop, pf)
        for command in (validate, run)
    ]
    out.append(
        Case(
            "signal: SIGTERM during a FiPy solve",
            ["run", "{scenario}", "-o", "{dir}/out", "--set", "numerics.vertical_solver=fipy"],
            143,
            "resume with:",
            patch=FIPY_SOLVING,
            setup=_scenario,
            signal_when=("out/solving", signal.SIGTERM),
            keeps_output=True,
        )
    )
    out.append(
        Case(
            "--set domain.cells=1e999",
            [*validate, "--set", "domain.cells=1e999"],
            2,
            "domain.cells (from --set)",
            setup=_scenario,
        )
    )
    out.append(Case("run: -o a link to a file", run, 2, "a file, not a directory", setup=_link_to_a_file))
    out.append(
        Case(
            "run: a newline and non-ASCII characters in the paths",
            ["run", "{dir}/uni ñ/sc\nn.yaml", "-o", "{dir}/uni ñ/résumé ☃", "-q"],
            0,
            "",
            setup=_odd_path,
        )
    )
    return out


def _kernel_modules(directory: Path) -> None:
    """A caller kernel and its callee (answer ``1.0 * x``) in ``directory/engine``."""
    _scenario(directory)
    engine = directory / "engine"
    engine.mkdir()
    jit = "from multilayer.engine.compiled import jit\n"
    (engine / "callee.py").write_text(jit + "\n\n@jit\ndef f(x):\n    return 1.0 * x\n")
    (engine / "caller.py").write_text(jit + "from callee import f\n\n\n@jit\ndef g(x):\n    return f(x)\n")


# the callee edited after this process imported it, before its first kernel; a second
# process must then run the edited callee (it loaded the old one from numba's cache)
EDITED_AFTER_IMPORT = """
import subprocess
from pathlib import Path
from multilayer.engine import kernel_cache
engine = Path(sys.argv[2]).parent / "engine"
sys.path.insert(0, str(engine))
kernel_cache.ENGINE = engine
import caller
callee = engine / "callee.py"
callee.write_text(callee.read_text().replace("1.0 * x", "2.0 * x"))
caller.g(1.0)
later = subprocess.run(
    [sys.executable, "-c", "import sys; sys.path.insert(0, sys.argv[1]); "
     "from multilayer.engine import kernel_cache; from pathlib import Path; "
     "kernel_cache.ENGINE = Path(sys.argv[1]); import caller; print(caller.g(1.0))", str(engine)],
    capture_output=True, text=True,
)
if later.stdout.split() != ["2.0"]:
    sys.exit(f"the next process ran the old kernel: {later.stdout.strip()} {later.stderr[-200:]}")
"""


def _api(body: str) -> str:
    """A patch that runs ``body`` (Python API calls) and reports its InputError as the
    command line does (exit 2); anything else is not handled."""
    indented = "".join(f"    {line}\n" for line in body.strip().splitlines())
    return (
        "import multilayer\nfrom multilayer.errors import InputError\ntry:\n" + indented
        + "except InputError as exc:\n    print(f'multilayer: error: {exc}', file=sys.stderr)\n"
        "    sys.exit(2)\n"
    )  # fmt: skip


API_MISUSE: list[tuple[str, str, str]] = [
    (
        "a scenario given layers = 0 after loading",
        "sc = multilayer.load(sys.argv[2])\nsc.domain.layers = 0\nmultilayer.Simulation(sc).step()",
        "domain.layers: Input should be greater than or equal to 1",
    ),
    (
        "load_state of a state missing t",
        "sim = multilayer.Simulation(multilayer.load(sys.argv[2]))\nsim.load_state({})",
        "t: missing",
    ),
    (
        "load_state of a NaN force impulse",
        "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
        "saved = sim.state_dict()\nsaved['force_impulse'] = saved['force_impulse'] * np.nan\n"
        "sim.load_state(saved)",
        "force_impulse holds values that are not finite",
    ),
    (
        "advance to a time before now",
        "sim = multilayer.Simulation(multilayer.load(sys.argv[2]))\nsim.advance(0.01)\nsim.advance(0.005)",
        "earlier than the current time",
    ),
    (
        "an engine configuration of no layer",
        "from multilayer.engine.config import SimulationConfig\nfrom multilayer.app.factory import "
        "engine_config\nimport dataclasses\nconfig = engine_config(multilayer.load(sys.argv[2]))\n"
        "dataclasses.replace(config, fractions=())",
        "fractions = (); accepted",
    ),
]


def _linked_output(directory: Path, target: str) -> None:
    _scenario(directory)
    (directory / "out").symlink_to(target)


def _sensitivity_file(directory: Path, s1: np.ndarray, dims: tuple[str, ...]) -> None:
    """A sensitivity.nc of one output and two parameters whose S1 is ``s1`` over ``dims``."""
    import xarray as xr

    both, good = ("output", "parameter"), np.array([[0.5, 0.3]])
    indices = {"S1": (dims, s1), **{name: (both, good) for name in ("S1_conf", "ST", "ST_conf")}}
    coords = {"output": ["runout"], "parameter": ["mu_s", "nu"]}
    with NETCDF:
        xr.Dataset(indices, coords=coords, attrs={"confidence_level": 0.95, "base_samples": 64}).to_netcdf(
            directory / "sensitivity.nc"
        )


def round_nine() -> list[Case]:
    """The hostile cases of the ninth round (docs/reliability.md): a kernel module edited
    while a process runs, the Python API given a scenario changed after loading or states
    and times it cannot take, ``-o`` a link to nothing or to itself, Newton settings no
    run can use (10^29 iterations, a tolerance of 1e-16), a sensitivity.nc whose indices
    are not as written, ``numerics.order`` true or 2.0."""
    validate = ["validate", "{scenario}"]
    out = [
        Case(
            "numba's cache: a callee edited after the import",
            validate,
            0,
            "is not the code this process runs",
            patch=EDITED_AFTER_IMPORT,
            setup=_kernel_modules,
        )
    ]
    for name, body, phrase in API_MISUSE:
        out.append(Case(f"API: {name}", validate, 2, phrase, patch=_api(body), setup=_scenario))
    for name, target in (("nothing", "missing/out"), ("itself", "out")):
        out.append(
            Case(
                f"run: -o a link to {name}",
                ["run", "{scenario}", "-o", "{dir}/out", "-q"],
                2,
                "which does not exist (or links back to itself)",
                setup=partial(_linked_output, target=target),
            )
        )
    for numerics, phrase in (
        ({"max_iterations": 10**29}, "numerics.max_iterations"),
        ({"tolerance": 1e-16}, "numerics.tolerance"),
    ):
        out.extend(
            Case(
                f"{command[0]}: numerics {numerics}",
                command,
                2,
                phrase,
                setup=partial(_scenario, changes={"numerics": numerics}),
            )
            for command in (validate, ["run", "{scenario}", "-o", "{dir}/out", "-q"])
        )
    for name, s1, dims, phrase in (
        ("over other dimensions", np.array([0.5, 0.3]), ("parameter",), "S1 over ('parameter',), where over"),
        ("infinite", np.array([[np.inf, 0.3]]), ("output", "parameter"), "S1 holds infinite values"),
    ):
        out.append(
            Case(
                f"plot: a sensitivity.nc whose S1 is {name}",
                ["plot", "{dir}"],
                2,
                phrase,
                setup=partial(_sensitivity_file, s1=s1, dims=dims),
            )
        )
    for value in (True, 2.0):
        out.extend(
            Case(
                f"{command[0]}: numerics.order {value}",
                command,
                2,
                "accepted: 1 or 2 (order of the transport step",
                setup=partial(_scenario, changes={"numerics": {"order": value}}),
            )
            for command in (validate, ["run", "{scenario}", "-o", "{dir}/out", "-q"])
        )
    return out


RESUMED = """
import os, signal
from multilayer.io.results import open_result
args = sys.argv[1:]
{trigger}
if (code := main(args)) != 130:
    sys.exit(f'the interrupted run exited with {{code}}, not 130')
{untrigger}
if main([*args, '--resume']) != 0:
    sys.exit('the resume failed')
out = args[args.index('-o') + 1]
if main([*args[:args.index('-o')], '-o', out + '_direct', *args[args.index('-o') + 2:]]) != 0:
    sys.exit('the uninterrupted run failed')
a, b = open_result(out, use='answer'), open_result(out + '_direct', use='answer')
same = a.sizes == b.sizes and all(np.array_equal(a[k].values, b[k].values) for k in ('time', 'h', 'u'))
print(f"multilayer: resumed: {{a.sizes['time']}} of {{b.sizes['time']}} output times, "
      + ("equal to" if same else "NOT equal to") + " the uninterrupted run", file=sys.stderr)
sys.exit(0 if same else 1)
"""
"""``multilayer run`` given SIGINT where ``trigger`` sends it, then ``--resume``d: exit 0 when
the records equal the uninterrupted run's, to the bit."""

STOPPED_AT_AN_OUTPUT_TIME = RESUMED.format(
    trigger="from multilayer.app.simulation import Simulation\nstep = Simulation.step\n"
    "def landing(self, t_max=float('inf')):\n    dt = step(self, t_max)\n"
    "    if self.t == t_max and abs(t_max - 0.06) < 1e-12:\n        os.kill(os.getpid(), signal.SIGINT)\n"
    "    return dt\nSimulation.step = landing",
    untrigger="Simulation.step = step",
)
"""SIGINT during the step that lands on the output time 0.06 s."""

STOPPED_AFTER_THE_NORMAL_STRESS = RESUMED.format(
    trigger="from multilayer.engine.normal_stress import NormalStress\nstress = NormalStress.__call__\n"
    "def stressing(self, *args, **kwargs):\n    stress(self, *args, **kwargs)\n    calls[0] += 1\n"
    "    if calls[0] == 17:\n        os.kill(os.getpid(), signal.SIGINT)\nNormalStress.__call__ = stressing",
    untrigger="NormalStress.__call__ = stress",
)
"""SIGINT after the normal stress's step of a Heun stage, before the step's end."""


MEMBER_MEDDLED = """
import csv, json
from pathlib import Path
from multilayer.io.results import summary
args = sys.argv[1:]
out = Path(args[args.index('-o') + 1])
if main(args) != 0:
    sys.exit('the sweep failed')
member = sorted(out.glob('m000-*'))[0]
MEDDLING
if main(args) != 0:
    sys.exit('the sweep run again failed')
row = next(csv.DictReader(open(out / 'summary.csv')))
same = all(row[key] == repr(value) for key, value in summary(member).items() if key in row)
print('multilayer: the summary of m000 is ' + ('that of' if same else 'NOT that of') + ' its result.nc',
      file=sys.stderr)
sys.exit(0 if same else 1)
"""
"""A sweep, its first member's directory meddled with (``MEDDLING``: statements, ``member``
the directory), the sweep again: its summary must be that of the member's result."""

REPLACED_MEMBER = MEMBER_MEDDLED.replace(
    "MEDDLING",
    "base = Path(args[1]).parent / 'base.yaml'\n"
    "if main(['run', str(base), '-o', str(member), '-q', '--set', 'rheology.mu_s=0.1']) != 0:\n"
    "    sys.exit('the run into the member failed')",
)
"""Another scenario run into the first member's directory."""


SIDE_BY_SIDE = """
import threading
from pathlib import Path
from multilayer.io.results import open_result
where = Path(sys.argv[2]).parent
codes = []
def run(i):
    options = ['-q', '--set', 'numerics.threads=2', '--set', 'time.end=0.05']
    codes.append(main(['run', sys.argv[2], '-o', str(where / f'out{i}'), *options]))
running = [threading.Thread(target=run, args=(i,)) for i in range(3)]
[thread.start() for thread in running]
[thread.join() for thread in running]
h = [open_result(where / f'out{i}', use='answer')['h'].values for i in range(3)]
fine = codes == [0] * 3 and all(np.array_equal(h[0], other) for other in h[1:])
print('multilayer: three runs side by side: ' + ('the same' if fine else 'NOT the same'), file=sys.stderr)
sys.exit(0 if fine else 1)
"""
"""Three runs on two kernel threads each, by ``multilayer run`` in three threads of one process."""


KEPT_WITHOUT_OUTDIR = """
import os, re, shutil
import multilayer
from multilayer.errors import RunError
step = simulation.Simulation.step
def failing(self, t_max=float('inf')):
    if self.t >= 0.05:
        raise FloatingPointError('a fault')
    return step(self, t_max)
simulation.Simulation.step = failing
try:
    multilayer.run(sys.argv[2])
except RunError as exc:
    directory = re.search(r'; (\\S+)/result.nc holds', str(exc)).group(1)
    kept = os.path.isfile(os.path.join(directory, 'result.nc'))
    shutil.rmtree(directory, ignore_errors=True)
    print('multilayer: a failed run without outdir: ' + ('kept' if kept else 'NOT kept'), file=sys.stderr)
    sys.exit(0 if kept else 1)
sys.exit('the run did not fail')
"""
"""``multilayer.run`` without ``outdir``, failing at t = 0.05 s: its temporary directory must stay."""


def _sweep_into(output: str) -> Callable[[Path], None]:
    """A sweep of two slopes whose ``output.directory`` is ``output``."""

    def setup(directory: Path) -> None:
        _sweep({"slope_deg": [20.0, 25.0]})(directory)
        path = directory / "sweep.yaml"
        path.write_text(yaml.safe_dump({**yaml.safe_load(path.read_text()), "output": {"directory": output}}))

    return setup


CTRL_C_WHILE_KEPT = """
import os, signal
import multilayer
from multilayer.engine.bed_force import BedForce
scenario = multilayer.load(sys.argv[2], {'time.end': 0.1})
alone = multilayer.Simulation(scenario)
alone.advance(0.1)
forces = alone.forces.take()
record = BedForce.record
def interrupted(self, *args):
    record(self, *args)
    calls[0] += 1
    if calls[0] == 3:
        os.kill(os.getpid(), signal.SIGINT)
BedForce.record = interrupted
sim = multilayer.Simulation(scenario)
try:
    sim.advance(0.1)
except KeyboardInterrupt:
    pass
BedForce.record = record
sim.advance(0.1)
same = np.array_equal(sim.h, alone.h) and sim.steps == alone.steps and sim.forces.take() == forces
print('multilayer: Ctrl-C after the forces of a step, then advance: ' + ('the run' if same else 'NOT'),
      file=sys.stderr)
sys.exit(0 if same else 1)
"""
"""``Simulation.advance`` under Python's own SIGINT handler, a Ctrl-C once the third step's
forces are recorded, then advanced again: the uninterrupted run, forces included."""


AXIS_CENTRED = """
import multilayer
scenario = multilayer.load(sys.argv[2])
sim = multilayer.Simulation(scenario)
sim.advance(0.02)
x = sim.x
try:
    x -= 0.25  # centring the axis of a plot
except ValueError as exc:
    print(f'multilayer: sim.x -= 0.25: {exc}', file=sys.stderr)
sim.advance(0.05)
alone = multilayer.Simulation(scenario)
alone.advance(0.02)
alone.advance(0.05)
sys.exit(0 if np.array_equal(sim.h, alone.h) else 1)
"""
"""``x = sim.x; x -= 0.25`` mid-run: refused by numpy, the run unchanged."""


def _finished_by_another_version(directory: Path) -> None:
    """A finished run whose result records another commit of multilayer."""
    import netCDF4

    _finished_run(directory)
    with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
        ds.multilayer_commit = "0123abc"


def _uncertainty_in_cm(directory: Path) -> None:
    """A calibration whose front uncertainty, 1e-322 cm, is 0 m."""
    _calibration("0.1,12,1e-322\n")(directory)
    path = directory / "calibration.yaml"
    config = yaml.safe_load(path.read_text())
    config["observations"][0]["units"] = "cm"
    path.write_text(yaml.safe_dump(config))


def round_ten() -> list[Case]:
    """The hostile cases of the tenth round (docs/reliability.md): runs stopped and resumed
    where the state checkpointed was not that of a record or of a step kept, a bed whose
    elevations the thickness cannot be resolved against, geometric layers of fraction 0 or
    NaN, text that is no Unicode (a byte of an argument that is not UTF-8, a lone
    surrogate given from Python)."""
    validate, run = ["validate", "{scenario}"], ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    phrase = "output times, equal to the uninterrupted run"
    out = [
        Case("resume: SIGINT as the run reaches an output time", run, 0, phrase,
             patch=STOPPED_AT_AN_OUTPUT_TIME, setup=_scenario),
        Case("resume: SIGINT after a normal-stress step inside a time step", run, 0, phrase,
             patch=STOPPED_AFTER_THE_NORMAL_STRESS,
             setup=partial(_scenario, changes={"model": {"normal_stress": True}})),
        Case("validate: --set with a byte that is not UTF-8", [*validate, "--set", "name=\udcff"], 2,
             "holds the byte 0xFF, which is not UTF-8", setup=_scenario),
        Case("API: a description holding a lone surrogate", validate, 2, "holds U+D800, half of a UTF-16",
             patch=_api("import yaml\ndata = yaml.safe_load(open(sys.argv[2]))\n"
                        "data['description'] = 'a\\ud800b'\nmultilayer.run(data)"), setup=_scenario),
    ]  # fmt: skip
    out.append(
        Case("API: runs in threads on numba's workqueue layer", validate, 0,
             "three runs side by side: the same", patch=SIDE_BY_SIDE, setup=_scenario,
             env={"NUMBA_THREADING_LAYER": "workqueue"})
    )  # fmt: skip
    out.append(
        Case("API: Ctrl-C while a step is kept", validate, 0, "then advance: the run",
             patch=CTRL_C_WHILE_KEPT, setup=_scenario)
    )  # fmt: skip
    out.append(
        Case("API: a failed run without outdir keeps its directory", validate, 0,
             "a failed run without outdir: kept", patch=KEPT_WITHOUT_OUTDIR, setup=_scenario)
    )  # fmt: skip
    resume = ["run", "{scenario}", "-o", "{dir}/out", "--resume", "--set", "time.end=0.3", "-q"]
    out.append(
        Case("API: sim.x -= 0.25 mid-run", validate, 0, "sim.x -= 0.25: output array is read-only",
             patch=AXIS_CENTRED, setup=_scenario)
    )  # fmt: skip
    out.append(
        Case("resume: a run of another version", resume, 0, "its output times so far were computed by",
             setup=_finished_by_another_version)
    )  # fmt: skip
    out.append(
        Case("checkpoint: a scenario of malformed YAML", resume, 2, "meta.scenario is not the YAML mapping",
             setup=_checkpoint_entry("meta.scenario", np.array("[1")))
    )  # fmt: skip
    calibrate = ["calibrate", "{dir}/calibration.yaml", "-o", "{dir}/cal", "--workers", "1", "-q"]
    out.append(
        Case(
            "calibrate: uncertainties of 1e-200 m (the misfit overflows)",
            calibrate,
            2,
            "the squares of (model - observed) / sigma overflow",
            setup=_calibration("0.1,0.12,1e-200\n0.2,0.15,1e-200\n"),
        )
    )
    out.append(
        Case("validate: an uncertainty of 1e-322 cm", ["validate", "{dir}/calibration.yaml"], 2,
             "is 0 in SI (times 0.01)", setup=_uncertainty_in_cm)
    )  # fmt: skip
    out.append(
        Case(
            "sweep: a member's directory run into by another scenario, then the sweep again",
            ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out", "--workers", "1", "-q"],
            0,
            "the summary of m000 is that of its result.nc",
            patch=REPLACED_MEMBER,
            setup=_sweep({"slope_deg": [20.0, 25.0]}),
        )
    )
    out.append(
        Case("run: output.directory holding the NUL character", ["run", "{scenario}", "-q"], 2,
             "holds the NUL character", setup=partial(_scenario, changes={"output": {"directory": "a\0b"}}))
    )  # fmt: skip
    out.append(
        Case("sweep: output.directory holding the NUL character", ["sweep", "{dir}/sweep.yaml", "-q"], 2,
             "no NUL character", setup=_sweep_into("a\0b"))
    )  # fmt: skip
    for name, changes, said in (
        ("a flat bed at 1e15 m", {"bed": {"points": [[0.0, 1e15], [0.5, 1e15]]}}, "than numerics.dry"),
        ("geometric layers of ratio 1e308", {"domain.layer_fractions": {"geometric": 1e308}}, "gives the fr"),
    ):
        out.extend(
            Case(f"{command[0]}: {name}", command, 2, said, setup=partial(_scenario, changes=changes))
            for command in (validate, run)
        )
    return out


EXPORTED_AGAIN = """
import os
from multilayer.io import export
out = sys.argv[2]
if main(['export', out, '--vtk']) != 0:
    sys.exit('the first export failed')
if main(['run', sys.argv[3], '-o', out, '-q', '--set', 'slope_deg=30']) != 0:
    sys.exit('the second run failed')
whole = export.structured_grid
def stopped(snap):
    calls[0] += 1
    if calls[0] == 3:
        raise KeyboardInterrupt
    return whole(snap)
export.structured_grid = stopped
if main(['export', out, '--vtk']) != 130:
    sys.exit('the export was not stopped')
left = os.path.exists(os.path.join(out, 'vtk', 'result.pvd'))
print('multilayer: an export stopped half-way: ' + ('a series left' if left else 'no series'),
      file=sys.stderr)
sys.exit(1 if left else 0)
"""
"""A run exported, run again with another slope, exported again and stopped at its third
file: no ``result.pvd`` may list the second run's first files with the first run's others."""


NOWHERE_TO_SHOW = """
import os
import multilayer
err = sys.stderr
if sys.argv[3] == 'none':
    sys.stderr = None
else:  # a pipe whose reader is gone
    reader, writer = os.pipe()
    os.close(reader)
    sys.stderr = os.fdopen(writer, 'w')
try:
    multilayer.run(sys.argv[2], quiet=False)
    said = 'completed'
except Exception as exc:
    said = f'failed: {exc}'
sys.stderr = err
print(f'multilayer: a run showing its progress on {sys.argv[3]}: {said}', file=sys.stderr)
sys.exit(0 if said == 'completed' else 1)
"""
"""``multilayer.run(quiet=False)`` with ``sys.stderr`` None (pythonw) or a pipe without a reader."""


NO_SCHEDULER = """
import socket, threading
server = socket.create_server(('127.0.0.1', 0))
def serve():
    connection, _ = server.accept()
    connection.sendall({answer})
    time.sleep(100)
threading.Thread(target=serve, daemon=True).start()
sys.argv = [a.replace('ADDRESS', f'tcp://127.0.0.1:{{server.getsockname()[1]}}') for a in sys.argv]
"""
"""``--scheduler ADDRESS`` answered by a server that is no Dask scheduler: ``answer`` is what
it sends (an HTTP error page, or nothing)."""


def _result_of_another_scenario(directory: Path) -> None:
    """A finished run in ``directory/out`` whose ``result.nc`` is that of a run at 30 degrees."""
    _finished_run(directory)
    command = [sys.executable, "-m", "multilayer", "run", str(directory / "scenario.yaml"), "-q"]
    other = ["-o", str(directory / "other"), "--set", "slope_deg=30"]
    subprocess.run([*command, *other], check=True, capture_output=True)
    (directory / "other" / "result.nc").replace(directory / "out" / "result.nc")


def round_eleven() -> list[Case]:
    """The hostile cases of the eleventh round (docs/reliability.md): an empty output path,
    an export stopped half-way over an earlier one, a resume beside another run's result,
    observation rows of more or fewer fields than their header, a progress line with nowhere
    to go, a seed numpy cannot take, Sobol' indices that are not numbers, densities so small
    that the stresses underflow, a dry threshold above the front threshold, a local cluster
    of 10^7 workers, a scheduler address answered by no scheduler or by silence."""
    empty = "an empty path; accepted: a directory path"
    out = [
        Case("run: -o an empty path", ["run", "{scenario}", "-o", "", "-q"], 2, empty, setup=_scenario,
             here=True),
        Case("run: output.directory an empty path", ["run", "{scenario}", "-q"], 2, empty,
             setup=partial(_scenario, changes={"output": {"directory": ""}}), here=True),
        Case("calibrate: -o an empty path", ["calibrate", "{dir}/calibration.yaml", "-o", "", "-q"], 2, empty,
             setup=_calibration("0.1,0.12,0.01\n"), here=True),
        Case("API: multilayer.run(outdir='')", ["validate", "{scenario}"], 2, "outdir: an empty path",
             patch=_api("multilayer.run(sys.argv[2], '')"), setup=_scenario, here=True),
        Case("export: stopped half-way over an earlier export", ["export", "{dir}/out", "{scenario}"], 0,
             "an export stopped half-way: no series", patch=EXPORTED_AGAIN, setup=_finished_run),
    ]  # fmt: skip
    resume = ["run", "{scenario}", "-o", "{dir}/out", "--resume", "--set", "time.end=0.3", "-q"]
    out.append(
        Case("resume: a result.nc of another scenario beside the checkpoint", resume, 2,
             "holds the output times of another scenario than its checkpoint (changed: slope_deg)",
             setup=_result_of_another_scenario)
    )  # fmt: skip
    out.append(
        Case("calibrate: search.seed -1", ["calibrate", "{dir}/calibration.yaml", "-o", "{dir}/cal", "-q",
             "--workers", "1"], 2, "search.seed (line", setup=_calibration("0.1,0.12,0.01\n", seed=-1))
    )  # fmt: skip
    out.append(
        Case("plot: a sensitivity.nc whose S1 is NaN", ["plot", "{dir}"], 0, "no Sobol' indices of runout",
             setup=partial(_sensitivity_file, s1=np.array([[NAN, 0.3]]), dims=("output", "parameter")))
    )  # fmt: skip
    validate, run = ["validate", "{scenario}"], ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    for density in (5e-324, 1e-200):
        out.extend(
            Case(f"{command[0]}: a density of {density!r}", command, 2, "so light that the stresses underf",
                 setup=partial(_scenario, changes={"material.density": density}))
            for command in (validate, run)
        )  # fmt: skip
    out.extend(
        Case(f"{command[0]}: numerics.dry_threshold 1 m", command, 2, "not below front_threshold = 0.001 m",
             setup=partial(_scenario, changes={"numerics": {"dry_threshold": 1.0}}))
        for command in (validate, run)
    )  # fmt: skip
    elsewhere = ["sweep", "{dir}/sweep.yaml", "--scheduler", "ADDRESS"]
    page = repr(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n" * 4)
    out.append(
        Case("sweep: --scheduler answered by an HTTP server", elsewhere, 2, "cannot connect (MemoryError",
             patch=NO_SCHEDULER.format(answer=page), setup=_sweep({"slope_deg": [20.0]}))
    )  # fmt: skip
    out.append(
        Case("sweep: --scheduler that accepts and says nothing", elsewhere, 2,
             "cannot connect (TimeoutError: no answer to the handshake within 2 s",
             patch=NO_SCHEDULER.format(answer="b''"), setup=_sweep({"slope_deg": [20.0]}),
             env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "1s"})
    )  # fmt: skip
    swarm = ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out", "--workers", "10000000"]
    out.append(
        Case("sweep: --workers 10^7", swarm, 2, "10000000 worker processes of about 200 MB each need",
             setup=_sweep({"slope_deg": [20.0]}))
    )  # fmt: skip
    for where in ("none", "a closed pipe"):
        out.append(
            Case(f"API: the progress line on {where}", ["validate", "{scenario}", where], 0,
                 f"a run showing its progress on {where}: completed", patch=NOWHERE_TO_SHOW, setup=_scenario)
        )  # fmt: skip
    for name, row, said in (
        ("a decimal comma", "0.1,0,12,0.01", "a row of 4 fields (0.1, 0, 12, 0.01), 3 in the header"),
        ("a field missing", "0.1,0.12", "a row of 2 fields (0.1, 0.12), 3 in the header"),
    ):
        out.append(
            Case(f"validate: an observation row with {name}", ["validate", "{dir}/calibration.yaml"], 2, said,
                 setup=_calibration(f"0.2,0.15,0.01\n{row}\n"))
        )  # fmt: skip
    return out


WRITTEN_BETWEEN_STEPS = """
import multilayer
from multilayer.errors import RunError
sim = multilayer.Simulation(multilayer.load(sys.argv[2]))
sim.step()
{write}
try:
    sim.step()
except RunError as exc:
    print(f'multilayer: error: {{exc}}', file=sys.stderr)
    sys.exit(1)
"""
"""An API user writes into the simulation's arrays between two steps."""

LOST_MID_RUN = """
import os, shutil
from multilayer.io import results
write = results.ResultWriter.write
def lost(self, sim):
    diag = write(self, sim)
    if self.records == 3:
        {lose}
    return diag
results.ResultWriter.write = lost
"""
"""The output directory (or its result file) lost after the third output time."""

PLOTTED_AGAIN = """
import os
from matplotlib.figure import Figure
out = sys.argv[2]
if main(['plot', out]) != 0:
    sys.exit('the first plot failed')
if main(['run', sys.argv[3], '-o', out, '-q', '--set', 'slope_deg=30']) != 0:
    sys.exit('the second run failed')
whole = Figure.savefig
def stopped(fig, path, **options):
    calls[0] += 1
    if calls[0] == 3:
        raise KeyboardInterrupt
    return whole(fig, path, **options)
Figure.savefig = stopped
if main(['plot', out]) != 130:
    sys.exit('the plot was not stopped')
left = sorted(os.listdir(os.path.join(out, 'plots')))
print(f'multilayer: a plot stopped half-way left {left}', file=sys.stderr)
sys.exit(0 if left == ['section.png', 'thickness.png'] else 1)
"""
"""A run plotted, run again with another slope, plotted again and stopped in its third
figure: plots/ may hold only the second run's first two figures."""


def _sensitivity_twice(directory: Path) -> None:
    _scenario(directory)
    (directory / "s.yaml").write_text(
        "base: scenario.yaml\nparameters: {rheology.mu_s: {bounds: [0.3, 0.4]}}\noutputs: [runout, runout]\n"
    )


def round_twelve() -> list[Case]:
    """The hostile cases of the twelfth round (docs/reliability.md): the simulation's arrays
    written between steps, a step with no bound on an empty domain, a restored state of
    negative thickness, a simulation copied, the output directory removed or made read-only or its result file
    removed during a run, a plot stopped half-way over an earlier one, an MPLBACKEND
    Matplotlib refuses, negative numbers in exponent notation after an option, one scenario
    value under two keys of a study, a sensitivity output asked twice."""
    validate = ["validate", "{scenario}"]
    entry = "on entry to the step from t = 0.00843656 s (step 2): not as the steps leave it, so written into"
    out = [
        Case(f"API: {write} written between steps", validate, 1, f"{said} {entry} {write[:5]}",
             setup=_scenario, patch=WRITTEN_BETWEEN_STEPS.format(write=write))
        for write, said in (
            ("sim.h[3] = np.nan", "thickness h = nan at x = 0.04375 m"),
            ("sim.h[3] = -1.0", "negative thickness h = -1 m at x = 0.04375 m"),
            ("sim.u[1, 3] = np.inf", "velocity u = inf at x = 0.04375 m, layer 2 (1 is at the bed)"),
            # a column without material, the non-hydrostatic fields
            ("sim.u[1, 30] = np.nan", "velocity u = nan at x = 0.38125 m, layer 2 (1 is at the bed)"),
            ("sim.u[2, 30] = 5.0", "velocity u = 5.0 at x = 0.38125 m, layer 3 (1 is at the bed), where "
             "there is no material (h = 0)"),
            ("sim.w[0, 30] = np.nan", "vertical velocity w = nan at x = 0.38125 m, layer 1 (1 is at the "
             "bed)"),
            ("sim.q[0, 3] = np.inf", "non-hydrostatic pressure q = inf at x = 0.04375 m, layer 1 (1 is at "
             "the bed)"),
        )
    ]  # fmt: skip
    out.append(
        Case("API: step() with no bound on an empty domain", validate, 2,
             "step(t_max=inf): no material and no inflow, so no wave bounds the time step",
             patch=_api("multilayer.Simulation(multilayer.load(sys.argv[2], {'initial': []})).step()"),
             setup=_scenario)
    )  # fmt: skip
    out.append(
        Case("API: load_state of a negative thickness", validate, 2,
             "h holds negative thicknesses (down to -0.05",
             patch=_api("sim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
                        "sim.load_state({**sim.state_dict(), 'h': -sim.h})"), setup=_scenario)
    )  # fmt: skip
    out.append(
        Case("API: copy.copy of a Simulation", validate, 2, "a Simulation cannot be copied or pickled",
             patch=_api("import copy\ncopy.copy(multilayer.Simulation(multilayer.load(sys.argv[2])))"),
             setup=_scenario)
    )  # fmt: skip
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    for what, lose, phrase in (
        ("the output directory removed", "shutil.rmtree(self.path.parent)",
         "/out is gone (removed or moved during the run), and the files written there with it"),
        ("result.nc removed", "os.unlink(self.path)",
         "/out/result.nc was removed, moved or replaced during the run, with the output times"),
    ):  # fmt: skip
        out.append(Case(f"run: {what} during the run", run, 1, phrase, setup=_scenario,
                        patch=LOST_MID_RUN.format(lose=lose)))  # fmt: skip
    if os.geteuid() == 0 and shutil.which("setpriv"):
        out.append(
            Case("as a user: run whose output directory is made read-only during the run", run, 1,
                 "checkpoint.npz failed (Permission denied); the run stopped at t=0.04 s (step 6); ",
                 setup=_scenario, patch=LOST_MID_RUN.format(lose="os.chmod(self.path.parent, 0o555)"),
                 prefix=NOT_ROOT, keeps_output=True)
        )  # fmt: skip
    out.append(
        Case("plot: stopped half-way over an earlier plot", ["plot", "{dir}/out", "{scenario}"], 0,
             "a plot stopped half-way left ['section.png', 'thickness.png']", patch=PLOTTED_AGAIN,
             setup=_finished_run)
    )  # fmt: skip
    aliases = {"initial.0.height": [0.04], "initial.00.height": [0.05]}
    out.append(
        Case("validate: a sweep of initial.0.height and initial.00.height", ["validate", "{dir}/sweep.yaml"],
             2,
             "initial has 1 entries; accepted indices: 0..0 (without leading zeros)", setup=_sweep(aliases))
    )  # fmt: skip
    out.append(
        Case("validate: a sensitivity of outputs [runout, runout]", ["validate", "{dir}/s.yaml"], 2,
             "outputs (line 3): runout twice; accepted: each output once", setup=_sensitivity_twice)
    )  # fmt: skip
    out.append(
        Case("plot: MPLBACKEND=nonsense", ["plot", "{dir}/out"], 2,
             "environment variable MPLBACKEND='nonsense': Matplotlib refuses it", setup=_finished_run,
             env={"MPLBACKEND": "nonsense"}, plain=True)
    )  # fmt: skip
    for words, phrase in (
        (["--at", "-1e308"], "--at -1e+308: outside the domain"),
        (["--at", "-inf"], "--at -inf: outside the domain"),
        (["--xlim", "-1e-2", "-2e-3"], "--xlim -0.01 -0.002: accepted: X0 < X1"),
    ):
        out.append(
            Case(f"plot: {' '.join(words)}", ["plot", "{dir}/out", *words], 2, phrase, setup=_finished_run)
        )  # fmt: skip
    return out


ANIMATED_THEN_RUN_AGAIN = """
import os
out = sys.argv[2]
if main(['plot', out, '--animate', '--format', 'svg']) != 0:
    sys.exit('the first plot failed')
if main(['run', sys.argv[3], '-o', out, '-q', '--set', 'slope_deg=30']) != 0:
    sys.exit('the second run failed')
if main(['plot', out]) != 0:
    sys.exit('the second plot failed')
left = sorted(os.listdir(os.path.join(out, 'plots')))
print(f'multilayer: the second plot left {left}', file=sys.stderr)
sys.exit(0 if all(name.endswith('.png') for name in left) else 1)
"""
"""A run plotted with an animation and as svg, run again, plotted again as png: plots/ may
hold only figures of the second run."""

HANGING_PLUGIN = """
import os
real = DruckerPrager.yield_stress
def hangs(self, p, m):
    calls[0] += 1
    if calls[0] == 30:
        open(os.path.join(os.path.dirname(sys.argv[2]), 'hanging'), 'w').close()
        while True:
            pass
    return real(self, p, m)
DruckerPrager.yield_stress = hangs
DruckerPrager.yield_stress_kernel = lambda self, material: None
"""
"""A rheology plugin whose method loops for ever at its 30th call (then the case's SIGINT)."""


PLOTS_AT_ONCE = """
import subprocess
command = [sys.executable, '-m', 'multilayer', 'plot', sys.argv[2]]
quiet, caught = subprocess.DEVNULL, subprocess.PIPE
plots = [subprocess.Popen(command, stdout=quiet, stderr=caught, text=True) for _ in range(3)]
errors = [p.communicate()[1] for p in plots]
codes = [p.returncode for p in plots]
print(''.join(errors) + f'multilayer: three plots at once exited {codes}', file=sys.stderr)
sys.exit(0 if codes == [0, 0, 0] else 1)
"""
"""Three ``multilayer plot`` of one directory started together."""


def _prior(**prior: float) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        _calibration("0.1,0.3,0.01\n")(directory)
        config = yaml.safe_load((directory / "calibration.yaml").read_text())
        config["parameters"]["rheology.mu_s"]["prior"] = prior
        (directory / "calibration.yaml").write_text(yaml.safe_dump(config))

    return setup


def _sweep_of_base(base: Any) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        _scenario(directory)
        sweep = {"base": base, "parameters": {"slope_deg": [20]}}
        (directory / "sweep.yaml").write_text(yaml.safe_dump(sweep))

    return setup


def round_thirteen() -> list[Case]:
    """The hostile cases of the thirteenth round (docs/reliability.md; the values written
    between steps into a column without material and into the non-hydrostatic fields are
    with round twelve's): a plot over an earlier animation and figures in another format,
    a prior centred outside
    its bounds or so narrow that its square overflows, one Ctrl-C while a plugin never
    returns, three plots of one directory at once, 1001 initial entries, a sweep whose base
    is a list, a thickness of 1e308 m written between steps."""
    out: list[Case] = []
    out.append(
        Case("plot: over an earlier run's animation and svg figures", ["plot", "{dir}/out", "{scenario}"], 0,
             "not drawn from the result.nc there now", patch=ANIMATED_THEN_RUN_AGAIN, setup=_finished_run)
    )  # fmt: skip
    out.append(
        Case("validate: a calibration whose prior's mean lies outside its bounds",
             ["validate", "{dir}/calibration.yaml"], 2,
             "calibration.yaml: parameters.rheology.mu_s.prior.mean (line 16): 0.5 outside the bounds "
             "[0.2, 0.4]",
             setup=_prior(mean=0.5, sd=0.05))
    )  # fmt: skip
    out.append(
        Case("validate: a calibration whose prior's sd is 1e-320", ["validate", "{dir}/calibration.yaml"], 2,
             "parameters.rheology.mu_s.prior.sd (line 17): 1e-320: the prior's square",
             setup=_prior(mean=0.3, sd=1e-320))
    )  # fmt: skip
    out.append(
        Case("plot: three plots of one directory at once", ["plot", "{dir}/out"], 0,
             "three plots at once exited [0, 0, 0]", patch=PLOTS_AT_ONCE, setup=_finished_run)
    )  # fmt: skip
    rectangle = {"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 1e-4}
    for command in ("validate", "run"):
        out.append(
            Case(f"{command}: 1001 initial entries",
                 [command, "{scenario}"] + (["-o", "{dir}/out", "-q"] if command == "run" else []), 2,
                 "initial (line 9): List should have at most 1000 items after validation, not 1001",
                 setup=partial(_scenario, changes={"initial": [rectangle] * 1001}))
        )  # fmt: skip
    out.append(
        Case("validate: a sweep whose base is a list", ["validate", "{dir}/sweep.yaml"], 2,
             "base (line 1): got ['scenario.yaml']; accepted: the path of a scenario file",
             setup=_sweep_of_base(["scenario.yaml"]))
    )  # fmt: skip
    out.append(
        Case("signal: one SIGINT while a plugin never returns",
             ["run", "{scenario}", "-o", "{dir}/out", "-q"], 130, "interrupted by Ctrl-C (SIGINT) at t=",
             patch=HANGING_PLUGIN, setup=_scenario, signal_when=("hanging", signal.SIGINT), keeps_output=True)
    )  # fmt: skip
    return out


HANGING_PLUGIN_PACKAGE = """
import os
import numpy as np
import multilayer


class Hanging(multilayer.Rheology):
    \"\"\"Drucker-Prager's yield stress, which never returns from its call number hang_after.\"\"\"

    name = "hanging"
    applies_to = "bulk"

    def __init__(self, mu_s: float, nu: float, hang_after: float):
        self.mu_s, self.nu, self.hang_after, self.calls = mu_s, nu, hang_after, 0

    def yield_stress(self, pressure, material):
        self.calls += 1
        if self.calls >= self.hang_after:
            open(os.environ["HANGING_MARK"], "w").close()
            while True:
                pass
        return self.mu_s * np.asarray(pressure)

    def viscosity(self, shear_rate, pressure, material):
        return np.full(np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure)), self.nu)


@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(Hanging)
"""
"""A rheology plugin, installed through its entry point (a distribution's metadata on
PYTHONPATH, which the Dask workers inherit), whose yield stress never returns."""


def _plugin_package(directory: Path, name: str, module: str) -> None:
    """A distribution ``name`` in ``directory/plugin`` (put on PYTHONPATH by the case) whose
    entry point names its module ``name``, of the text ``module``."""
    plugin = directory / "plugin"
    (plugin / f"{name}-0.1.dist-info").mkdir(parents=True)
    (plugin / f"{name}.py").write_text(module)
    (plugin / f"{name}-0.1.dist-info" / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {name}\nVersion: 0.1\n"
    )
    (plugin / f"{name}-0.1.dist-info" / "entry_points.txt").write_text(f"[multilayer]\n{name} = {name}\n")


def _hanging_sweep(directory: Path) -> None:
    """A sweep of two members on the hanging plugin: the first completes, the second hangs."""
    _plugin_package(directory, "hanging", HANGING_PLUGIN_PACKAGE)
    _scenario(directory, {"rheology": {"name": "hanging", "mu_s": 0.3, "nu": 0.01, "hang_after": 1e9}})
    sweep = {"base": "scenario.yaml", "parameters": {"rheology.hang_after": [1e9, 40]}}
    (directory / "sweep.yaml").write_text(yaml.safe_dump(sweep))


FIGURES_OF_A_COPY = """
import os, shutil, time
out = sys.argv[2]
if main(['plot', out, '--format', 'svg']) != 0:
    sys.exit('the first plot failed')
future = time.time() + 10**6
os.utime(os.path.join(out, 'result.nc'), (future, future))
copy = out + '-copy'
shutil.copytree(out, copy)
if main(['plot', copy]) != 0:
    sys.exit('the plot of the copy failed')
left = sorted(os.listdir(os.path.join(copy, 'plots')))
print(f'multilayer: the plot of the copy left {left}', file=sys.stderr)
sys.exit(0 if len(left) == 14 else 1)
"""
"""A run plotted as svg, its result given a time in the future, the directory copied (new
times) and plotted as png: the svg figures, drawn from that very result, must stay."""


def _cut_result(directory: Path) -> None:
    """A completed run whose result keeps its first 3 records, the header saying so."""
    from multilayer.io.netcdf_layout import NUMRECS_OFFSET, read_layout

    _finished_run(directory)
    path = directory / "out" / "result.nc"
    layout, size = read_layout(path), path.stat().st_size
    while layout.complete_records(size - 1) >= 3:
        size -= 1
    data = bytearray(path.read_bytes()[:size])
    data[NUMRECS_OFFSET : NUMRECS_OFFSET + 4] = (3).to_bytes(4, "big")
    path.write_bytes(bytes(data))


def _sweep_of_a_sweep(directory: Path) -> None:
    _sweep_of_base("scenario.yaml")(directory)
    (directory / "outer.yaml").write_text("base: sweep.yaml\nparameters: {slope_deg: [20]}\n")


def _meddling_plugin(change: str) -> str:
    """Drucker-Prager's yield stress doing ``change`` (a statement) at its 20th call."""
    return (
        "import os, signal\n"
        "real = DruckerPrager.yield_stress\n"
        "def meddling(self, p, m):\n"
        "    calls[0] += 1\n"
        "    if calls[0] == 20:\n"
        f"        {change}\n"
        "    return real(self, p, m)\n"
        "DruckerPrager.yield_stress = meddling\n"
        "DruckerPrager.yield_stress_kernel = lambda self, material: None\n"
    )


def round_fourteen() -> list[Case]:
    """The hostile cases of the fourteenth round (docs/reliability.md): a sweep whose base
    is itself or another sweep, figures of a result from the future in a copied directory, a
    completed result cut to its first records, one SIGINT while a sweep's member is in a
    plugin that never returns, plugins changing the working directory, the stop signals'
    handlers or numpy's error handling, a study into a directory another holds or into a
    file."""
    out: list[Case] = []
    out.append(
        Case("validate: a sweep whose base is itself", ["validate", "{dir}/sweep.yaml"], 2,
             "sweep.yaml is this file itself, not a scenario; accepted: the path of a scenario file",
             setup=_sweep_of_base("sweep.yaml"))
    )  # fmt: skip
    out.append(
        Case("validate: a sweep whose base is another sweep", ["validate", "{dir}/outer.yaml"], 2,
             "sweep.yaml is a sweep or study file (it has the key parameters), not a scenario",
             setup=_sweep_of_a_sweep)
    )  # fmt: skip
    out.append(
        Case("plot: figures of a result from the future, in a copied directory", ["plot", "{dir}/out"], 0,
             "the plot of the copy left", patch=FIGURES_OF_A_COPY, setup=_finished_run)
    )  # fmt: skip
    out.append(
        Case("plot: a completed result cut to its first records", ["plot", "{dir}/out"], 2,
             "its 3 output times run from t = 0 s to 0.04 s, not from 0 to its time.end (0.2 s)",
             setup=_cut_result)
    )  # fmt: skip
    out.append(
        Case("signal: one SIGINT while a sweep's member is in a plugin that never returns",
             ["sweep", "sweep.yaml", "-o", "out", "--workers", "1"], 130,
             "of 2 members complete, the others cancelled", setup=_hanging_sweep, here=True,
             env={"PYTHONPATH": "{dir}/plugin", "HANGING_MARK": "{dir}/hanging"},
             signal_when=("hanging", signal.SIGINT))
    )  # fmt: skip
    run = ["run", "{scenario}", "-o", "out", "-q"]
    for name, change, phrase in (
        ("changes the working directory", "os.chdir('/')", "changed the working directory from"),
        ("ignores SIGINT", "signal.signal(signal.SIGINT, signal.SIG_IGN)", "changed the handler of SIGINT"),
    ):
        out.append(
            Case(f"plugin: {name} mid-run", run, 1, phrase, patch=_meddling_plugin(change), setup=_scenario,
                 here=True, keeps_output=True)
        )  # fmt: skip
    out.append(
        Case("validate: a plugin's constructor sets numpy's errors to raise", ["validate", "{scenario}"], 2,
             "DruckerPrager(mu_s=0.3, nu=0.01) changed the numpy error handling",
             patch="import functools\ninit = DruckerPrager.__init__\n@functools.wraps(init)\n"
                   "def meddling(self, **params):\n    init(self, **params)\n    np.seterr(all='raise')\n"
                   "DruckerPrager.__init__ = meddling\n",
             setup=_scenario)
    )  # fmt: skip
    out.append(
        Case("sweep: into a directory another run holds", ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out"], 2,
             "another run is writing into this directory (pid",
             setup=lambda d: (_sweep_of_base("scenario.yaml")(d), _lock_holding(os.getpid())(d)))
    )  # fmt: skip
    out.append(
        Case("calibrate: -o a file", ["calibrate", "{dir}/calibration.yaml", "-o", "{dir}/front.csv"], 2,
             "front.csv: a file, not a directory", setup=_calibration("0.1,0.3,0.01\n"))
    )  # fmt: skip
    return out


EDITED_MARKER = MEMBER_MEDDLED.replace(
    "MEDDLING",
    "marker = json.loads((member / 'member.json').read_text())\n"
    "marker['summary'].update(runout=99.0, front_final=float('nan'), steps='many')\n"
    "(member / 'member.json').write_text(json.dumps(marker))",
)
"""The first member's marker edited (a runout of 99, NaN, text)."""


def _scenario_as_its_log(directory: Path) -> None:
    """``out/run.log`` a scenario file, to be run into ``out``."""
    (directory / "out").mkdir()
    (directory / "out" / "run.log").write_text(yaml.safe_dump(TINY))


THREADS_CLUSTER = """
from dask.distributed import LocalCluster
cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=':0')
sys.argv += ['--scheduler', cluster.scheduler_address]
"""
"""A cluster of one worker thread in the command's process, given as its ``--scheduler``."""


def round_fifteen() -> list[Case]:
    """The hostile cases of the fifteenth round (docs/reliability.md): one SIGINT while a
    sweep's member on a worker thread is in a plugin that never returns, observations
    whose columns or header name a column twice, a plugin returning a masked array, the
    state's arrays replaced through the Python API, a masked state restored, a sweep
    member's marker edited, a column thinner than the dry threshold, keys holding a
    terminal escape sequence, a scenario named as a file of its run in its output directory."""
    out: list[Case] = []
    out.append(
        Case("run: a scenario out/run.log run into out",
             ["run", "{dir}/out/run.log", "-o", "{dir}/out", "-q"], 2,
             "run.log: the scenario file itself, which the run would write over",
             setup=_scenario_as_its_log)
    )  # fmt: skip
    escape = "\x1b[2J"
    out.append(
        Case("validate: a key holding a terminal escape sequence", ["validate", "{scenario}"], 2,
             "'a\\x1b[2J' (line", setup=partial(_scenario, changes={f"a{escape}": 1}))
    )  # fmt: skip
    out.append(
        Case("validate: a rheology named with a terminal escape sequence", ["validate", "{scenario}"], 2,
             "unknown rheology 'dp\\x1b[2J'",
             setup=partial(_scenario, changes={"rheology.name": f"dp{escape}"}))
    )  # fmt: skip
    out.append(
        Case("validate: --set a key holding a terminal escape sequence",
             ["validate", "{scenario}", "--set", f"rheology.{escape}=1"], 2,
             "--set 'rheology.\\x1b[2J=1': expected KEY=VALUE", setup=_scenario)
    )  # fmt: skip
    for command in ("validate", "run"):
        argv = [command, "{scenario}"] + (["-o", "{dir}/out", "-q"] if command == "run" else [])
        out.append(
            Case(f"{command}: a column of 1e-7 m, below the dry threshold", argv, 2,
                 "initial: at most 1e-07 m thick on the mesh, not above numerics.dry_threshold",
                 setup=partial(_scenario, changes={"initial.0.height": 1e-7}))
        )  # fmt: skip
    out.append(
        Case("sweep: a member's member.json edited, then the sweep again",
             ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out", "--workers", "1", "-q"], 0,
             "the summary of m000 is that of its result.nc", patch=EDITED_MARKER,
             setup=_sweep({"slope_deg": [20.0, 25.0]}))
    )  # fmt: skip
    validate = ["validate", "{scenario}"]
    for name, body, phrase in (
        ("sim.state.h replaced by a float32 array",
         "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\nsim.step()\n"
         "sim.state.h = sim.state.h.astype(np.float32)\nsim.step()",
         "state.h: the state's arrays are not replaced"),
        ("sim.state.u replaced by a list",
         "sim = multilayer.Simulation(multilayer.load(sys.argv[2]))\nsim.step()\n"
         "sim.state.u = sim.state.u.tolist()\nsim.step()",
         "state.u: the state's arrays are not replaced"),
        ("load_state of h read by netCDF4, masked",
         "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
         "saved = sim.state_dict()\nsaved['h'] = np.ma.masked_equal(saved['h'], 0.0)\nsim.load_state(saved)",
         "h: a masked array of 32 masked value(s)"),
    ):  # fmt: skip
        out.append(Case(f"API: {name}", validate, 2, phrase, patch=_api(body), setup=_scenario))
    out.append(
        Case("plugin: a masked array", ["run", "{scenario}", "-o", "{dir}/out", "-q"], 1,
             "yield_stress() returned a masked array of ",
             patch=_plugin_patch("yield_stress", "return np.ma.masked_less(0.3 * np.asarray(p), 1e300)"),
             setup=_scenario)
    )  # fmt: skip
    out.append(
        Case("validate: observation columns [t, t, sigma]", ["validate", "{dir}/calibration.yaml"], 2,
             "observations.0.columns (line 3): a column named twice",
             setup=_calibration("0.1,0.2,0.01\n", columns=("t", "t", "sigma")))
    )  # fmt: skip
    out.append(
        Case("validate: an observation file whose header names x_f twice",
             ["validate", "{dir}/calibration.yaml"],
             2, "front.csv: its header names the column 'x_f' twice",
             setup=_calibration("0.1,0.2,0.01,0.3\n", header="t,x_f,sigma,x_f"))
    )  # fmt: skip
    out.append(
        Case("signal: one SIGINT while a sweep's member on a worker thread is in a plugin that never returns",
             ["sweep", "sweep.yaml", "-o", "out"], 130,
             "did not stop (in a plugin's code that never returns?): the worker threads of inproc://",
             patch=THREADS_CLUSTER, setup=_hanging_sweep, here=True,
             env={"PYTHONPATH": "{dir}/plugin", "HANGING_MARK": "{dir}/hanging"},
             signal_when=("hanging", signal.SIGINT))
    )  # fmt: skip
    return out


def _linked_result(directory: Path) -> None:
    """A scenario, and ``out/result.nc`` a symbolic link to a file beside ``out``."""
    _scenario(directory)
    (directory / "out").mkdir()
    (directory / "precious.txt").write_text("precious")
    (directory / "out" / "result.nc").symlink_to(directory / "precious.txt")


def round_sixteen() -> list[Case]:
    """The hostile cases of the sixteenth round (docs/reliability.md): the time, the step
    count and the layer fields of a simulation replaced through the Python API, a force
    impulse no run accumulates restored, a bed profile short of the domain, an output file
    linked to a file elsewhere, a channel narrower than a grain, grains longer than the domain."""
    out: list[Case] = []
    validate = ["validate", "{scenario}"]
    for name, body, phrase in (
        ("sim.t set to a string",
         "sim = multilayer.Simulation(multilayer.load(sys.argv[2]))\nsim.t = 'a'\nsim.step()",
         "sim.t = 'a': t is read-only"),
        ("sim.state.fields['w'] replaced",
         "sim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
         "sim.state.fields['w'] = sim.state.fields['w'].T.copy()\nsim.step()",
         "state.fields['w']: the state's fields are not replaced"),
        ("load_state of a force impulse of 1e308",
         "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\nsim.step()\n"
         "saved = sim.state_dict()\nsaved['force_impulse'] = np.full(8, 1e308)\nsim.load_state(saved)",
         "accepted: impulses whose means are finite"),
    ):  # fmt: skip
        out.append(Case(f"API: {name}", validate, 2, phrase, patch=_api(body), setup=_scenario))
    huge_grains = {"rheology": {"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.28},
                   "material.grain_diameter": 1e308}  # fmt: skip
    out.append(
        Case("run: mu(I) grains 1e308 m across", ["run", "{scenario}", "-o", "{dir}/out", "-q"], 2,
             "material.grain_diameter (line 16): grains 1e+308 m across, longer than the domain",
             setup=partial(_scenario, changes=huge_grains))
    )  # fmt: skip
    walled = {"walls": {"name": "wall_friction", "mu_w": 0.2}, "domain.width": 5e-324}
    out.append(
        Case("run: a channel 5e-324 m wide", ["run", "{scenario}", "-o", "{dir}/out", "-q"], 2,
             "domain.width (line 7): a channel 4.94066e-324 m wide, narrower than one grain",
             setup=partial(_scenario, changes=walled))
    )  # fmt: skip
    out.append(
        Case("run: out/result.nc a symbolic link to a file elsewhere",
             ["run", "{scenario}", "-o", "{dir}/out", "-q"], 2, "result.nc: a symbolic link (to ",
             setup=_linked_result)
    )  # fmt: skip
    for command in ("validate", "run"):
        argv = [command, "{scenario}"] + (["-o", "{dir}/out", "-q"] if command == "run" else [])
        out.append(
            Case(f"{command}: a bed file ending at 0.2 m on a domain to 0.5 m", argv, 2,
                 "the profile bed.csv spans x = [0, 0.2] m (along the slope), short of the domain [0, 0.5] m",
                 setup=_bed_file("bed.csv", "x (m), z (m)\n0.0, 0.0\n0.2, 0.0\n"))
        )  # fmt: skip
    return out


def _linked_directory(name: str) -> Callable[[Path], None]:
    """A completed run in ``out`` whose ``out/NAME`` is a symbolic link to ``elsewhere``."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        (directory / "elsewhere").mkdir()
        (directory / "out" / name).symlink_to(directory / "elsewhere")

    return setup


def _linked_member(directory: Path) -> None:
    """A sweep of two members whose second member's directory links to ``elsewhere``."""
    from multilayer.app import sweep

    _sweep({"rheology.mu_s": [0.3, 0.4]})(directory)
    (directory / "elsewhere").mkdir()
    (directory / "sweep-out").mkdir()
    member = sweep.load(directory / "sweep.yaml").members()[1].id
    (directory / "sweep-out" / member).symlink_to(directory / "elsewhere")


def _linked_members(directory: Path) -> None:
    """A sensitivity study whose ``members/`` directory links to ``elsewhere``."""
    (directory / "base.yaml").write_text(yaml.safe_dump(TINY))
    config = {"base": "base.yaml", "parameters": {"rheology.mu_s": {"bounds": [0.3, 0.4]}},
              "outputs": ["runout"], "samples": 8}  # fmt: skip
    (directory / "sobol.yaml").write_text(yaml.safe_dump(config))
    (directory / "elsewhere").mkdir()
    (directory / "sens-out").mkdir()
    (directory / "sens-out" / "members").symlink_to(directory / "elsewhere")


def _study_file(kind: str) -> Callable[[Path], None]:
    """A sweep of one member whose ``sweep-out/summary.csv`` is ``kind``: a named pipe, or
    a symbolic link to ``precious.txt`` beside it."""

    def setup(directory: Path) -> None:
        _sweep({"rheology.mu_s": [0.3]})(directory)
        (directory / "sweep-out").mkdir()
        if kind == "pipe":
            os.mkfifo(directory / "sweep-out" / "summary.csv")
        else:
            (directory / "precious.txt").write_text("precious")
            (directory / "sweep-out" / "summary.csv").symlink_to(directory / "precious.txt")

    return setup


def _planted_checkpoint_part(kind: str) -> Callable[[Path], None]:
    """A scenario and ``out/checkpoint.npz.tmp`` a named pipe, or a symbolic link to
    ``precious.txt`` beside ``out``."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        (directory / "out").mkdir()
        part = directory / "out" / "checkpoint.npz.tmp"
        if kind == "pipe":
            os.mkfifo(part)
        else:
            (directory / "precious.txt").write_text("precious")
            part.symlink_to(directory / "precious.txt")

    return setup


def _linked_check(directory: Path) -> None:
    """A scenario with an expectation whose ``out/<name>`` links to ``elsewhere``."""
    _scenario(directory, changes={"expect": [{"kind": "regression", "quantity": "runout", "value": 0.1,
                                              "rtol": 0.5}]})  # fmt: skip
    (directory / "out").mkdir()
    (directory / "elsewhere").mkdir()
    (directory / "out" / str(TINY["name"])).symlink_to(directory / "elsewhere")


def _hard_linked_result(directory: Path) -> None:
    """A scenario, and ``out/result.nc`` a second name of ``precious.txt`` beside ``out``."""
    _scenario(directory)
    (directory / "out").mkdir()
    (directory / "precious.txt").write_text("precious")
    os.link(directory / "precious.txt", directory / "out" / "result.nc")


def _piped_lock(directory: Path) -> None:
    """A scenario and ``out/run.lock``, a named pipe."""
    _scenario(directory)
    (directory / "out").mkdir()
    os.mkfifo(directory / "out" / "run.lock")


def _piped_marker(directory: Path) -> None:
    """A sweep of one member whose directory holds ``member.json``, a named pipe."""
    from multilayer.app import sweep

    _sweep({"rheology.mu_s": [0.3]})(directory)
    member = directory / "sweep-out" / sweep.load(directory / "sweep.yaml").members()[0].id
    member.mkdir(parents=True)
    os.mkfifo(member / sweep.MARKER)


def round_seventeen() -> list[Case]:
    """The hostile cases of the seventeenth round (docs/reliability.md): a stop signal the
    run was started with ignored (``nohup cmd &``), the directories a command writes into
    (``plots/``, ``vtk/``, a study's members) symbolic links to a directory elsewhere, a
    sweep's ``summary.csv`` a named pipe or a symbolic link, a figure or VTK file beyond
    ``ulimit -f``, a forced run whose lock or result header does not fit, a named pipe or a
    symbolic link at the checkpoint's temporary name, a lock and a sweep member's marker
    that are named pipes, ``check -o``'s result directory a symbolic link, ``result.nc`` a
    hard link."""
    out: list[Case] = []
    for signum in (signal.SIGINT, signal.SIGHUP):
        name = signal.Signals(signum).name
        out.append(
            Case(f"signal: {name} to a run started with {name} ignored", ["run", "{scenario}", "-o",
                 "{dir}/out"], 0, "", patch=PACED, setup=lambda d: _scenario(d), signal_after_output=signum,
                 ignored=(signum,), keeps_output=True)
        )  # fmt: skip
    for command, name in ((["plot", "{dir}/out"], "plots"), (["export", "{dir}/out", "--vtk"], "vtk")):
        out.append(
            Case(f"{command[0]}: out/{name} a symbolic link to a directory elsewhere", command, 2,
                 f"out/{name}: a symbolic link (to ", setup=_linked_directory(name))
        )  # fmt: skip
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    sweep = ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/sweep-out", "--workers", "1"]
    sensitivity = ["sensitivity", "{dir}/sobol.yaml", "-o", "{dir}/sens-out", "--workers", "1"]
    single: list[tuple[str, list[str], int, str, Callable[[Path], object]]] = [
        ("sweep: a member's directory a symbolic link to a directory elsewhere", sweep, 2,
         "into whose target the files would be written", _linked_member),
        ("sweep: summary.csv a named pipe", sweep, 2,
         "sweep-out/summary.csv: exists and is not a regular file", _study_file("pipe")),
        ("sweep: summary.csv a symbolic link to a file elsewhere", sweep, 2,
         "sweep-out/summary.csv: a symbolic link (to ", _study_file("link")),
        ("sweep: a member's member.json a named pipe", sweep, 0, "", _piped_marker),
        ("sensitivity: members/ a symbolic link to a directory elsewhere", sensitivity, 2,
         "sens-out/members: a symbolic link (to ", _linked_members),
        ("lock: a named pipe", run, 0, "taking over a stale lock", _piped_lock),
        ("check: DIR/<name> a symbolic link to a directory elsewhere",
         ["check", "{scenario}", "-o", "{dir}/out"], 2, "into whose target the files would be written",
         _linked_check),
        ("run: out/result.nc a hard link to a file elsewhere", run, 2,
         "result.nc: a file of 2 names (hard links)", _hard_linked_result),
        ("validate: a calibration's bounds [-1e308, 1e308]", ["validate", "{dir}/calibration.yaml"], 2,
         "bounds (line 12): got [-1e+308, 1e+308]: the width upper - lower overflows",
         _calibration("0.1,0.12,0.01\n", bounds=[-1e308, 1e308])),
    ]  # fmt: skip
    out += [Case(name, argv, code, phrase, setup=setup) for name, argv, code, phrase, setup in single]
    for command, written in (
        (["plot", "{dir}/out"], "plots/section.png"),
        (["export", "{dir}/out", "--vtk"], "vtk/result_0000.vts"),
    ):
        out.append(
            Case(f"{command[0]}: ulimit -f below the first file", command, 2,
                 f"out/{written}: not written (file too large: the file size limit (ulimit -f) is 2000",
                 setup=_finished_run, file_limit=2000)
        )  # fmt: skip
    for kind, what in (("pipe", "a named pipe"), ("link", "a symbolic link to a file elsewhere")):
        out.append(
            Case(f"run: out/checkpoint.npz.tmp {what}", run, 0, "", setup=_planted_checkpoint_part(kind),
                 keeps_output=True)
        )  # fmt: skip
    for limit, code, phrase in (
        (0, 2, "run.lock: the lock cannot be written (file too large"),
        (5000, 1, "run failed: file too large: creating "),
    ):
        out.append(
            Case(f"disk: ulimit -f {limit}, forced (below the {'lock' if code == 2 else 'header'})",
                 [*run, "--force"], code, phrase, setup=lambda d: _scenario(d), file_limit=limit)
        )  # fmt: skip
    return out


def _edited_result(edit: Callable[[Any], object]) -> Callable[[Path], None]:
    """A finished run whose ``result.nc`` is then given ``edit(dataset)`` (netCDF4, in place)."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        import netCDF4

        with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
            edit(ds)

    return setup


def _transposed_velocity(directory: Path) -> None:
    """A finished run of 3 cells x 3 layers whose ``result.nc`` holds ``u`` over (time, x,
    layer), each record the transpose of the one written (the momentum balance caught it, as
    a damage of the records: its dimensions are now named)."""
    _scenario(directory, {"domain.cells": 3, "domain.layers": 3, "initial.0.x_max": 0.2})
    subprocess.run(
        [sys.executable, "-m", "multilayer", "run", str(directory / "scenario.yaml"), "-o",
         str(directory / "out"), "-q"], check=True, capture_output=True,
    )  # fmt: skip
    import netCDF4

    path = directory / "out" / "result.nc"
    path.rename(directory / "written.nc")
    with (
        NETCDF,
        netCDF4.Dataset(directory / "written.nc") as src,
        netCDF4.Dataset(path, "w", format=src.data_model) as ds,
    ):
        for name, dim in src.dimensions.items():
            ds.createDimension(name, None if dim.isunlimited() else len(dim))
        ds.setncatts({key: src.getncattr(key) for key in src.ncattrs()})
        for name, var in src.variables.items():
            attrs = {key: var.getncattr(key) for key in var.ncattrs()}
            fill = attrs.pop("_FillValue", None)
            dims = ("time", "x", "layer") if name == "u" else var.dimensions
            new = ds.createVariable(name, var.dtype, dims, fill_value=fill)
            new.setncatts(attrs)
            new[:] = var[:].transpose(0, 2, 1) if name == "u" else var[:]


def _numba_config(directory: Path, text: str) -> None:
    """The scenario and numba's configuration file ``.numba_config.yaml`` holding ``text``."""
    _scenario(directory)
    (directory / ".numba_config.yaml").write_text(text)


def _two_of_one_name(directory: Path) -> None:
    """Two scenarios named ``tiny`` with an expectation each, on other slopes."""
    expected = [{"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.01}]
    _scenario(directory, {"expect": expected}).rename(directory / "again.yaml")
    _scenario(directory, {"expect": expected, "slope_deg": 20.0})


def _parameter_of_an_experiment(directory: Path) -> None:
    """A calibration of ``rheology.mu_s`` one of whose experiments sets ``rheology.mu_s``."""
    _calibration("0.1,0.12,0.01\n")(directory)
    config = yaml.safe_load((directory / "calibration.yaml").read_text())
    config["experiments"] = {"rough": {"rheology.mu_s": 0.5}, "smooth": {"slope_deg": 20.0}}
    config["observations"][0]["experiment"] = "rough"
    (directory / "calibration.yaml").write_text(yaml.safe_dump(config))


def round_eighteen() -> list[Case]:
    """The hostile cases of the eighteenth round (docs/reliability.md): a stdout that cannot
    encode a path it prints, an expectation whose tolerance overflows, a key that replaces a
    key set before it (``--set`` and a sweep's parameters), and result files whose values a
    reader decodes otherwise than the checks read them (CF attributes multilayer does not
    write: ``missing_value``, ``scale_factor``, ``valid_max``, a time in dates) or whose grid
    is damaged (``x_bnds``, ``sigma``, ``layer``, ``u`` over other dimensions), numba's
    configuration file in the working directory holding what the engine cannot run with,
    ``check -o`` of two files of one name, an exact comparison where the exact field is 0 and
    a calibration's parameter given a value in one of its experiments."""
    out = [
        Case("run: stdout in ASCII, the output directory's name beyond it", ["run", "{scenario}", "-o",
             "{dir}/out\u00e9"], 0, "", setup=lambda d: _scenario(d), env={"PYTHONIOENCODING": "ascii"}),
        Case("validate: stdout in ASCII, the scenario's name beyond it",
             ["validate", "{dir}/sc\u00e9nario.yaml"], 0, "",
             setup=lambda d: _scenario(d).rename(d / "sc\u00e9nario.yaml"),
             env={"PYTHONIOENCODING": "ascii"}),
    ]  # fmt: skip
    for command in ("validate", "check"):
        out.append(
            Case(f"{command}: an expectation of 1e308 with rtol 10 (the tolerance overflows)", [command,
                 "{scenario}"], 2, "expect.0.rtol (line", setup=lambda d: _scenario(d, {"expect": [{"kind":
                 "regression", "quantity": "front_final", "value": 1e308, "rtol": 10.0}]}))
        )  # fmt: skip
    domain = json.dumps(TINY["domain"])
    out += [
        Case("run: --set domain.cells then --set domain", ["run", "{scenario}", "-o", "{dir}/out", "--set",
             "domain.cells=20", "--set", f"domain={domain}".replace("{", "{{").replace("}", "}}")], 2,
             "--set domain: replaces domain.cells, set before it", setup=lambda d: _scenario(d)),
        Case("validate: a sweep of domain.cells then domain", ["validate", "{dir}/sweep.yaml"], 2,
             "replaces domain.cells, set before it",
             setup=lambda d: (_scenario(d), (d / "sweep.yaml").write_text(
                 f"base: scenario.yaml\nparameters:\n  domain.cells: [20, 30]\n  domain: [{domain}]\n"))),
    ]  # fmt: skip
    edits: list[tuple[str, Callable[[Any], object], str]] = [
        ("h given missing_value 0", lambda ds: ds["h"].setncattr("missing_value", 0.0),
         "h has missing_value 0.0"),
        ("u given scale_factor 2", lambda ds: ds["u"].setncattr("scale_factor", 2.0),
         "u has scale_factor 2.0"),
        ("u given valid_max 0.01", lambda ds: ds["u"].setncattr("valid_max", 0.01), "u has valid_max 0.01"),
        ("time in seconds since 2000-01-01",
         lambda ds: ds["time"].setncattr("units", "seconds since 2000-01-01"),
         "time has units 'seconds since 2000-01-01'"),
        ("an x_bnds NaN", lambda ds: ds["x_bnds"].__setitem__((3, 0), np.nan), "its cell edges x_bnds"),
        ("a sigma NaN", lambda ds: ds["sigma"].__setitem__(1, np.nan), "its layer heights sigma"),
        ("layer indices 5, 5, 5", lambda ds: ds["layer"].__setitem__(slice(None), 5), "its layer indices"),
    ]  # fmt: skip
    for name, edit, phrase in edits:
        for argv in (["plot", "{dir}/out"], ["export", "{dir}/out", "--vtk"]):
            out.append(Case(f"{argv[0]}: result.nc's {name}", argv, 2, phrase, setup=_edited_result(edit)))
    for text, phrase in (
        ("disable_jit: 1\n", "(numba's configuration file): disable_jit: '1'"),
        ("num_threads: 0\n", "(numba's configuration file): num_threads: '0'"),
        ("a: [\n", "(numba's configuration file, read by numba at its import): while parsing"),
        ("- 1\n", "(numba's configuration file, read by numba at its import): got [1]"),
    ):
        out.append(
            Case(f"run: .numba_config.yaml in the working directory holding {text.strip()!r}",
                 ["run", "{scenario}", "-o", "{dir}/out", "-q"], 2, phrase, plain=True, here=True,
                 setup=partial(_numba_config, text=text))
        )  # fmt: skip
    window = (
        (
            "expect=[{kind: reference, exact: {solution: coulomb_dam_break, field: h, norm: l1, x_min: 1.9}, "
            "atol: 0.01, source: x}]"
        )
        .replace("{", "{{")
        .replace("}", "}}")
    )
    out.append(
        Case("validate: an exact comparison where the exact h is 0 in the window",
             ["validate", str(Path(__file__).resolve().parents[1] / "scenarios" / "coulomb_dam_break.yaml"),
              "--set", window],
             2, "the exact h is 0 in the window at t = 0.5 s")
    )  # fmt: skip
    out.append(
        Case("validate: a calibration's parameter given a value in an experiment",
             ["validate", "{dir}/calibration.yaml"], 2,
             "parameters.rheology.mu_s (line 17): also given a value in experiments.rough",
             setup=_parameter_of_an_experiment)
    )  # fmt: skip
    out.append(
        Case("check: two files of one name into one directory",
             ["check", "{scenario}", "{dir}/again.yaml", "-o", "{dir}/out"], 2,
             "again.yaml: name: 'tiny', the name of", setup=_two_of_one_name)
    )  # fmt: skip
    out.append(
        Case("plot: result.nc's u over (time, x, layer)", ["plot", "{dir}/out"], 2,
             "its variable u is over ('time', 'x', 'layer')", setup=_transposed_velocity)
    )  # fmt: skip
    return out


def _tagged(old: str, new: str) -> Callable[[Path], None]:
    """The scenario with the text ``old`` of its YAML replaced by ``new``."""

    def setup(directory: Path) -> None:
        _scenario(directory, text=yaml.safe_dump(TINY).replace(old, new))

    return setup


def _csv_bed(text: str | None = None, make: Callable[[Path], object] | None = None) -> Callable[[Path], None]:
    """A scenario whose bed is ``bed.csv``, written as ``text`` (newlines kept) or made by ``make``."""

    def setup(directory: Path) -> None:
        _scenario(directory, {"bed": {"file": "bed.csv"}})
        if text is not None:
            (directory / "bed.csv").write_bytes(text.encode())
        if make is not None:
            make(directory / "bed.csv")

    return setup


def _entry_point_plugin(module: str) -> Callable[[Path], None]:
    """The scenario and a distribution ``third`` whose module is the text ``module``."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        _plugin_package(directory, "third", module)

    return setup


SHADOWING_PLUGIN = """
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager


class Shadow(DruckerPrager):
    name = "drucker_prager"

    def yield_stress(self, pressure, material):
        raise RuntimeError("the shadow ran")


@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(Shadow)
    register(Shadow)
"""
"""A third-party plugin registering the built-in's name, twice: both rejected, the built-in runs."""

HOST_KEPT = """
import os, signal, warnings, logging
import numpy as np
warnings.simplefilter('error')
np.seterr(all='raise')
def host():
    handlers = [signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)]
    return {'numpy errors': np.geterr(), 'warnings filters': list(warnings.filters), 'cwd': os.getcwd(),
            'environment': dict(os.environ), 'logging': (logging.root.level, list(logging.root.handlers)),
            'signal handlers': handlers}
before = host()
import multilayer, netCDF4
before['environment'] = dict(os.environ)  # netCDF4's import sets HDF5_PLUGIN_PATH
done = multilayer.run(sys.argv[2]).attrs['run_status']
changed = [key for key, value in host().items() if value != before[key]]
print(f'multilayer: run {done}, changed {changed}', file=sys.stderr)
sys.exit(0 if done == 'completed' and not changed else 1)
"""
"""A host that turns warnings into errors and numpy's floating-point errors into exceptions
runs a scenario through the Python API: it must complete and change nothing of the host."""


FAILING_PLUGIN = """
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager


class Failing(DruckerPrager):
    name = "failing"

    def yield_stress_kernel(self, material):
        return None

    def yield_stress(self, pressure, material):
        raise RuntimeError("always fails")


@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(Failing)
"""


def _failing_sweep(directory: Path) -> None:
    """A sweep of two members on a third-party law that always raises."""
    _entry_point_plugin(FAILING_PLUGIN)(directory)
    _scenario(directory, {"rheology": {"name": "failing", "mu_s": 0.3, "nu": 0.01}})
    (directory / "sweep.yaml").write_text("base: scenario.yaml\nparameters:\n  rheology.mu_s: [0.3, 0.4]\n")


def _relaxing(changes: dict) -> Callable[[Path], None]:
    """The loose immersed layer with a relaxing pore pressure, to t = 0.5 s, with ``changes``
    (top-level and dotted keys of its mappings)."""

    def setup(directory: Path) -> None:
        path = Path(__file__).resolve().parents[1] / "scenarios" / "immersed_layer_loose.yaml"
        data = yaml.safe_load(path.read_text())
        for key in ("expect", "output"):
            data.pop(key)
        data["time"] = {"end": 0.5, "output_interval": 0.1}
        data["fluid"]["compressibility"] = 1e-6
        for key, value in changes.items():
            *parents, last = key.split(".")
            node = data
            for part in parents:
                node = node.setdefault(part, {})
            node[last] = value
        (directory / "scenario.yaml").write_text(yaml.safe_dump(data))

    return setup


SIGNAL_IN_CHECKPOINT = """
import os, signal
real_savez = np.savez
def savez(stream, **arrays):
    calls[0] += 1
    if calls[0] == 2:  # the second checkpoint, mid-run: the signal arrives while it is written
        os.kill(os.getpid(), signal.{name})
    real_savez(stream, **arrays)
np.savez = savez
first = main(sys.argv[1:])
np.savez = real_savez
if first != {code}:
    sys.exit(f'the run signalled while writing its checkpoint exited {{first}}')
sys.argv.append('--resume')
"""
"""A run sent a stop signal while it writes its second checkpoint, then resumed: the run
must stop as on any signal (its exit code) and the checkpoint must resume."""


LOADED = "import yaml\ndata = yaml.safe_load(open(sys.argv[2]))\n"
"""The start of a patch: the case's scenario read as a mapping, ``data``."""
SAVED = (
    "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
    "saved = sim.state_dict()\n"
)
"""The start of a patch: a simulation of the case's scenario and its state, ``saved``."""


def round_nineteen() -> list[Case]:
    """The hostile cases of the nineteenth round (docs/reliability.md): YAML tags and values
    PyYAML's constructors cannot read or read as other types (dates, bytes, sets), integers
    beyond the floats, NaN and infinity spelt otherwise, keys that only look like ours; CSV
    beds with other line ends, repeated or unordered x, a directory, a pipe, a loop of
    links or a unit that overflows; the Python API given numbers of other types and a host
    that raises on warnings; third-party plugins that fail to import or shadow a built-in,
    plugin values of other dtypes; a relaxing pore pressure at extreme compressibilities."""
    validate, run = ["validate", "{scenario}"], ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    big = "1" + "0" * 400
    out = [
        Case(
            "validate: mu_s !!float abc",
            validate,
            2,
            "(line 19, column 9): malformed YAML: tag:yaml.org,2002:float cannot read 'abc'",
            setup=_tagged("mu_s: 0.3", "mu_s: !!float abc"),
        ),
        Case(
            "validate: cells !!int 1e5",
            validate,
            2,
            "tag:yaml.org,2002:int cannot read '1e5'",
            setup=_tagged("cells: 40", "cells: !!int 1e5"),
        ),
        Case(
            "validate: cells !!bool maybe",
            validate,
            2,
            "tag:yaml.org,2002:bool cannot read 'maybe'",
            setup=_tagged("cells: 40", "cells: !!bool maybe"),
        ),
        Case(
            "validate: time.end !!timestamp 2001-13-45",
            validate,
            2,
            "tag:yaml.org,2002:timestamp cannot read '2001-13-45'",
            setup=_tagged("end: 0.2", "end: !!timestamp 2001-13-45"),
        ),
        Case(
            "validate: time.end a date",
            validate,
            2,
            "time.end (line 24): Input should be a valid number (got datetime.date(2001, 12, 14))",
            setup=_tagged("end: 0.2", "end: 2001-12-14"),
        ),
        Case(
            "validate: name !!binary",
            validate,
            2,
            "name (line 17): Input should be a valid string (got b'hello')",
            setup=_tagged("name: tiny", "name: !!binary aGVsbG8="),
        ),
        Case(
            "validate: layer_fractions !!set",
            validate,
            2,
            "domain.layer_fractions (line 7): got {",
            setup=_tagged("layers: 3", "layers: 3\n  layer_fractions: !!set {1, 2, 3}"),
        ),
        Case(
            "validate: mu_s !!str 0.3",
            validate,
            2,
            "rheology.mu_s (line 19): drucker_prager: Input should be a valid number (got '0.3')",
            setup=_tagged("mu_s: 0.3", "mu_s: !!str 0.3"),
        ),
        Case(
            "validate: cells 10^400",
            validate,
            2,
            "domain.cells (line 5): Input should be less than or equal to 1000000000",
            setup=_tagged("cells: 40", f"cells: {big}"),
        ),
        Case(
            "validate: mu_s 10^400",
            validate,
            2,
            "rheology.mu_s (line 19): drucker_prager: Input should be a valid number",
            setup=_tagged("mu_s: 0.3", f"mu_s: {big}"),
        ),
        Case(
            "validate: x_max -10^400",
            validate,
            2,
            "domain.x_max (line 7): Input should be a valid number",
            setup=_tagged("x_max: 0.5", f"x_max: -{big}"),
        ),
        Case(
            "validate: max_iterations 0x" + "f" * 8 + "...",
            validate,
            2,
            "numerics.max_iterations (line 26): Input should be less than or equal to 100000",
            setup=lambda d: _scenario(
                d, text=yaml.safe_dump(TINY) + "numerics: {max_iterations: 0x" + "f" * 400 + "}\n"
            ),
        ),
        Case(
            "validate: mu_s .Nan",
            validate,
            2,
            "rheology.mu_s (line 19): drucker_prager: Input should be a valid number (got '.Nan')",
            setup=_tagged("mu_s: 0.3", "mu_s: .Nan"),
        ),
        Case("validate: mu_s .iNF", validate, 2, "(got '.iNF')", setup=_tagged("mu_s: 0.3", "mu_s: .iNF")),
        Case(
            "validate: a full-width key \uff44omain",
            validate,
            2,
            "'\\uff44omain' (line 4): unknown key",
            setup=_tagged("domain:", "\uff44omain:"),
        ),
        Case(
            "validate: a key mu_s and a zero-width space",
            validate,
            2,
            "rheology.'mu_s\\u200b' (line 19): unknown parameter of drucker_prager (mu_s missing)",
            setup=_tagged("mu_s: 0.3", "mu_s\u200b: 0.3"),
        ),
        Case(
            "validate: a Cyrillic s in mu_s beside mu_s",
            validate,
            2,
            "rheology.'mu_\\u0455' (line 20): unknown parameter",
            setup=_tagged("mu_s: 0.3", "mu_s: 0.3\n  mu_\u0455: 0.4"),
        ),
        Case(
            "run: --set rheology.mu_s='!!float abc'",
            ["run", "{scenario}", "-o", "{dir}/out", "--set", "rheology.mu_s=!!float abc"],
            2,
            "--set rheology.mu_s: malformed YAML value",
            setup=_scenario,
        ),
        Case(
            "validate: a sweep value !!int x",
            ["validate", "{dir}/sweep.yaml"],
            2,
            "sweep.yaml (line 3, column 18): malformed YAML: tag:yaml.org,2002:int cannot read 'x'",
            setup=lambda d: (
                _scenario(d),
                (d / "sweep.yaml").write_text(
                    "base: scenario.yaml\nparameters:\n  domain.cells: [!!int x]\n"
                ),
            ),
        ),
        Case(
            "validate: a sweep of an empty list",
            ["validate", "{dir}/sweep.yaml"],
            2,
            "parameters.rheology.mu_s (line 3): got []; accepted: a non-empty list",
            setup=_sweep({"rheology.mu_s": []}),
        ),
        Case(
            "validate: a sweep of {start, stop, num}",
            ["validate", "{dir}/sweep.yaml"],
            2,
            "accepted: a non-empty list of values",
            setup=_sweep({"rheology.mu_s": {"start": 0.1, "stop": 0.5, "num": 10**6}}),
        ),
        Case(
            "run: .numba_config.yaml holding num_threads: !!int abc",
            run,
            2,
            "(numba's configuration file, read by numba at its import): "
            "tag:yaml.org,2002:int cannot read 'abc'",
            plain=True,
            here=True,
            setup=partial(_numba_config, text="num_threads: !!int abc\n"),
        ),
        Case(
            "plot: result.nc's scenario holding !!float abc",
            ["plot", "{dir}/out"],
            2,
            "its scenario attribute is missing or damaged",
            setup=_edited_result(
                lambda ds: ds.setncattr(
                    "scenario", ds.getncattr("scenario").replace("end: 0.2", "end: !!float abc")
                )
            ),
        ),
        Case(
            "resume: a checkpoint's scenario holding !!float abc",
            ["run", "{scenario}", "-o", "{dir}/out", "--resume", "-q"],
            2,
            "meta.scenario is not the YAML mapping of a scenario",
            setup=_checkpoint_entry(
                "meta.scenario", lambda a: np.asarray(str(a).replace("end: 0.2", "end: !!float abc"))
            ),
        ),
    ]
    out += [
        Case("validate: an integer of 5000 digits", validate, 2,
             "(line 5, column 10): malformed YAML: tag:yaml.org,2002:int cannot read '444",
             setup=_tagged("cells: 40", "cells: " + "4" * 5000)),
        Case("validate: a key ''", validate, 2, "scenario.yaml: '' (line 26): unknown key",
             setup=lambda d: _scenario(d, text=yaml.safe_dump(TINY) + '"": 1\n')),
        Case("validate: two YAML documents", validate, 2,
             "(line 26, column 1): malformed YAML: but found another document",
             setup=lambda d: _scenario(d, text=yaml.safe_dump(TINY) + "---\nname: other\n")),
        Case("validate: a %YAML 2.0 directive", validate, 2,
             "malformed YAML: found incompatible YAML document",
             setup=lambda d: _scenario(d, text="%YAML 2.0\n---\n" + yaml.safe_dump(TINY))),
    ]  # fmt: skip
    header = "x (m), z (m)\n"
    for name, setup, code, phrase in (
        ("CRLF line ends", _csv_bed(header.replace("\n", "\r\n") + "0,0.01\r\n0.5,0\r\n"), 0, ""),
        (
            "a byte order mark and CR line ends",
            _csv_bed(("\ufeff" + header + "0,0.01\n0.5,0\n").replace("\n", "\r")),
            0,
            "",
        ),
        (
            "x given twice",
            _csv_bed(header + "0,0.1\n0,0.2\n0.5,0\n"),
            2,
            "bed.csv: line 3: x = 0.0 does not increase",
        ),
        (
            "x decreasing",
            _csv_bed(header + "0.5,0\n0,0.1\n"),
            2,
            "bed.csv: line 3: x = 0.0 does not increase",
        ),
        ("a NaN", _csv_bed(header + "0,nan\n0.5,0\n"), 2, "bed.csv: line 2: expected two numbers"),
        (
            "x 1e306 km (beyond the floats in metres)",
            _csv_bed("x (km), z (m)\n0,0\n1e306,0\n"),
            2,
            "bed.csv: line 3: '1e306,0' in metres is beyond the largest float",
        ),
        (
            "z 1e306 km",
            _csv_bed("x (m), z (km)\n0,0\n0.5,1e306\n"),
            2,
            "bed.csv: line 3: '0.5,1e306' in metres is beyond the largest float",
        ),
        ("a directory", _csv_bed(make=Path.mkdir), 2, "bed.csv: not a regular file"),
        ("a named pipe", _csv_bed(make=os.mkfifo), 2, "bed.csv: not a regular file"),
        (
            "a link to itself",
            _csv_bed(make=lambda p: p.symlink_to(p)),
            2,
            "bed.csv is a symbolic link to nothing or in a loop",
        ),
        (
            "a link to /dev/zero",
            _csv_bed(make=lambda p: p.symlink_to("/dev/zero")),
            2,
            "bed.csv: not a regular file",
        ),
    ):
        out.append(Case(f"validate: a bed CSV with {name}", validate, code, phrase, setup=setup))
    for name, body, phrase in (
        (
            "Decimal('NaN') as mu_s",
            LOADED
            + "from decimal import Decimal\ndata['rheology']['mu_s'] = Decimal('NaN')\nmultilayer.load(data)",
            "rheology.mu_s: drucker_prager: Input should be a finite number (got Decimal('NaN'))",
        ),
        (
            "np.bool_ as domain.cells",
            "import numpy as np\nmultilayer.load(sys.argv[2], {'domain.cells': np.bool_(True)})",
            "domain.cells",
        ),
        (
            "np.longdouble 1e400 as mu_s",
            LOADED
            + "import numpy as np\ndata['rheology']['mu_s'] = np.longdouble('1e400')\nmultilayer.load(data)",
            "Input should be a finite number (got np.longdouble('1e+400'))",
        ),
        (
            "bytes as name",
            LOADED + "data['name'] = b'tiny'\nmultilayer.load(data)",
            "name: Input should be a valid string (got b'tiny')",
        ),
        (
            "a path holding NUL",
            "multilayer.load(sys.argv[2] + '\\0x')",
            "cannot read the file (embedded null byte)",
        ),
        (
            "load_state of a Decimal time",
            SAVED + "from decimal import Decimal\nsaved['t'] = Decimal('0.01')\nsim.load_state(saved)",
            "t: object values of shape ()",
        ),
        (
            "load_state of a bool thickness",
            SAVED + "saved['h'] = saved['h'] > 0\nsim.load_state(saved)",
            "h: bool values of shape (40,)",
        ),
        (
            "load_state, then its arrays written",
            SAVED + "sim.load_state(saved)\nsaved['h'][:] = np.nan\nsim.advance(0.05)\n"
            "sys.exit(0 if np.isfinite(sim.h).all() else 1)",
            "",
        ),
    ):
        out.append(
            Case(f"API: {name}", validate, 0 if not phrase else 2, phrase, patch=_api(body), setup=_scenario)
        )
    out.append(
        Case(
            "API: a run in a host raising on warnings and numpy errors",
            validate,
            0,
            "run completed, changed []",
            patch=HOST_KEPT,
            setup=_scenario,
        )
    )
    for name, body in (
        ("float32 viscosity", "return np.full(np.shape(p), 15.0, dtype=np.float32)"),
        ("integer viscosity", "return np.full(np.shape(p), 15, dtype=np.int64)"),
    ):
        out.append(
            Case(f"plugin: {name}", run, 0, "", patch=_plugin_patch("viscosity", body), setup=_scenario)
        )
    out.append(
        Case(
            "plugin: boolean yield stress",
            run,
            1,
            "yield_stress() returned",
            patch=_plugin_patch("yield_stress", "return np.ones(np.shape(p), dtype=bool)"),
            setup=_scenario,
            keeps_output=True,
        )
    )
    plugin_env = {"PYTHONPATH": "{dir}/plugin"}
    out += [
        Case(
            "plugin: an entry point whose module fails to import",
            run,
            0,
            "rheology plugin third 0.1 (entry point third = third) skipped: ZeroDivisionError",
            setup=_entry_point_plugin("1 / 0\n"),
            env=plugin_env,
        ),
        Case(
            "plugin: an entry point registering a built-in's name twice",
            run,
            0,
            "rheology name 'drucker_prager' is already registered by multilayer",
            setup=_entry_point_plugin(SHADOWING_PLUGIN),
            env=plugin_env,
        ),
    ]
    for signum, code in ((signal.SIGTERM, 143), (signal.SIGHUP, 129)):
        name = signal.Signals(signum).name
        out.append(
            Case(
                f"resume: {name} while the checkpoint is written",
                run,
                0,
                f"interrupted by {name} at t=",
                patch=SIGNAL_IN_CHECKPOINT.format(name=name, code=code),
                setup=_scenario,
            )
        )
    out += [
        Case(
            "sweep: every member failing",
            ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out"],
            1,
            "(rheology.mu_s=0.4) failed: RunError: scenario 'tiny': the simulation failed at t=0 s (step 0): "
            "rheology plugin 'failing' (third.Failing): yield_stress() raised RuntimeError: always fails",
            setup=_failing_sweep,
            env={"PYTHONPATH": "{dir}/plugin"},
        ),
        Case(
            "validate: an observation header 't, x_f, sigma' (spaces after the commas)",
            ["validate", "{dir}/calibration.yaml"],
            0,
            "",
            setup=_calibration("0.1,0.12,0.01\n", header="t, x_f, sigma"),
        ),
        Case(
            "validate: an observation header naming xf",
            ["validate", "{dir}/calibration.yaml"],
            2,
            "front.csv has no column 'x_f' (its header names 't', 'xf', 'sigma')",
            setup=_calibration("0.1,0.12,0.01\n", header="t,xf,sigma"),
        ),
    ]
    for name, changes in (
        ("5e-324", {"fluid.compressibility": 5e-324}),
        ("1 with order 1", {"fluid.compressibility": 1.0, "numerics.order": 1}),
        ("1e-6 in 3 layers", {"domain.layers": 3}),
        ("1 in 3 layers", {"fluid.compressibility": 1.0, "domain.layers": 3}),
        (
            "1e-6 in a channel between walls",
            {"domain.width": 0.01, "boundaries": {"left": "wall", "right": "outflow"}},
        ),
    ):
        out.append(
            Case(
                f"run: a relaxing pore pressure of compressibility {name}",
                run,
                0,
                "",
                setup=_relaxing(changes),
            )
        )
    return out


def cases() -> list[Case]:
    out: list[Case] = []
    budget = ["--max-memory", "8G", "--max-output", "1G"]
    for name, changes, phrase in BAD_VALUES:
        for command in ("validate", "run"):
            argv = [command, "{scenario}", *budget] + (["-o", "{dir}/out", "-q"] if command == "run" else [])
            out.append(Case(f"{command}: {name}", argv, 2, phrase, setup=partial(_scenario, changes=changes)))
    for name, text, phrase in BAD_FILES:
        out.append(
            Case(
                f"validate: {name}",
                ["validate", "{scenario}"],
                2,
                phrase,
                setup=partial(_scenario, text=text),
            )
        )
    out.append(Case("validate: missing file", ["validate", "{dir}/nothing.yaml"], 2, "file not found"))
    out.append(
        Case(
            "run: --set unknown key",
            ["run", "{scenario}", "--set", "domain.colour=1", "-o", "{dir}/o"],
            2,
            "domain.colour",
            setup=lambda d: _scenario(d),
        )
    )
    out.append(
        Case(
            "run: --set malformed",
            ["run", "{scenario}", "--set", "time.end=[1", "-o", "{dir}/o"],
            2,
            "--set time.end",
            setup=lambda d: _scenario(d),
        )
    )
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    for name, body, phrase in PLUGIN_FAULTS:
        out.append(
            Case(
                f"plugin: {name}",
                run,
                1,
                phrase,
                patch=_plugin_patch("viscosity", body),
                setup=lambda d: _scenario(d),
                keeps_output=True,
            )
        )
    for name, body, phrase in YIELD_FAULTS:
        out.append(
            Case(
                f"plugin: {name}",
                run,
                1,
                phrase,
                patch=_plugin_patch("yield_stress", body),
                setup=lambda d: _scenario(d),
                keeps_output=True,
            )
        )
    for name, rheology, assignment, phrase in COMPILED_FAULTS:
        out.append(
            Case(
                f"compiled law: {name}",
                run,
                1,
                phrase,
                patch=_compiled_patch(assignment),
                setup=partial(_scenario, changes={"rheology": rheology}),
                keeps_output=True,
            )
        )
    # material released against the outflow end, so that it flows out from the start
    outflowing = {"initial": [{"shape": "rectangle", "x_min": 0.3, "x_max": 0.5, "height": 0.05}]}
    for name, body, phrase in ENGINE_FAULTS:
        out.append(
            Case(
                f"engine: {name}",
                run,
                1,
                phrase,
                patch=_transport_patch(body),
                setup=partial(_scenario, changes=outflowing if "outflow" in name else None),
                keeps_output=True,
            )
        )
    resume = ["run", "{scenario}", "-o", "{dir}/out", "--resume", "--set", "time.end=0.3", "-q"]
    for how in (
        "truncated",
        "bit flips",
        "empty",
        "not a zip",
        "pickle planted",
        "values changed",
        "keys missing",
    ):
        out.append(Case(f"checkpoint: {how}", resume, 2, "start again without --resume", setup=_damage(how)))
    out.append(
        Case("checkpoint: resume without a run", resume, 2, "nothing to resume", setup=lambda d: _scenario(d))
    )
    out.append(
        Case(
            "lock: live holder",
            run,
            2,
            "another run is writing into this directory (pid",
            setup=lambda d: (_scenario(d), _lock(True)(d)),
        )
    )
    out.append(
        Case(
            "lock: stale holder",
            run,
            0,
            "taking over a stale lock",
            setup=lambda d: (_scenario(d), _lock(False)(d)),
        )
    )
    out.append(
        Case(
            "lock: unreadable",
            run,
            0,
            "taking over a stale lock",
            setup=lambda d: (_scenario(d), _lock(False, readable=False)(d)),
        )
    )
    for signum, code in ((signal.SIGINT, 130), (signal.SIGTERM, 143), (signal.SIGHUP, 129)):
        name = signal.Signals(signum).name
        out.append(
            Case(
                f"signal: {name}",
                ["run", "{scenario}", "-o", "{dir}/out"],
                code,
                "resume with:",
                patch=PACED,
                setup=lambda d: _scenario(d),
                signal_after_output=signum,
                keeps_output=True,
            )
        )
    for how, code, phrase in (
        ("nan", 2, "fails its checks: h = nan"),
        ("failed", 2, "fails its checks: h = nan"),
        ("all nan", 2, "fails its checks: h = nan"),
        ("truncated", 2, "result.nc"),
    ):
        out.append(
            Case(f"plot: {how} result", ["plot", "{dir}/out"], code, phrase, setup=_result_damage(how))
        )
    out.append(Case("plot: no result", ["plot", "{dir}"], 2, "no result file"))
    return (
        out
        + round_two()
        + round_three()
        + round_four()
        + round_five()
        + round_six()
        + round_seven()
        + round_eight()
        + round_nine()
        + round_ten()
        + round_eleven()
        + round_twelve()
        + round_thirteen()
        + round_fourteen()
        + round_fifteen()
        + round_sixteen()
        + round_seventeen()
        + round_eighteen()
        + round_nineteen()
        + round_twenty()
        + round_twenty_one()
        + round_twenty_two()
        + round_twenty_three()
        + round_twenty_four()
        + round_twenty_five()
        + round_twenty_six()
        + round_twenty_seven()
        + round_twenty_eight()
        + round_twenty_nine()
        + round_thirty()
        + round_thirty_one()
        + round_thirty_two()
        + round_thirty_three()
        + round_thirty_four()
        + round_thirty_five()
        + round_thirty_seven()
        + round_thirty_eight()
        + round_thirty_nine()
        + round_forty()
        + round_forty_one()
        + round_forty_two()
        + round_forty_three()
        + round_forty_four()
        + round_forty_five()
        + round_forty_six()
        + round_forty_seven()
        + round_forty_eight()
        + round_forty_nine()
        + round_fifty()
    )


def _result_attribute(variable: str | None, key: str, value: Any) -> Callable[[Path], None]:
    """A finished run whose result.nc's attribute ``key`` (of ``variable``, None: global) is
    set to ``value``, or deleted for None."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        import netCDF4

        with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
            owner = ds if variable is None else ds[variable]
            owner.delncattr(key) if value is None else owner.setncattr(key, value)

    return setup


def _checkpoint_bomb(declared_only: bool) -> Callable[[Path], None]:
    """A finished run whose checkpoint's state.h is 256 MB of zeros deflated to 256 kB, or
    (``declared_only``) a stored member whose header declares 8 TB in a few bytes."""

    def setup(directory: Path) -> None:
        import io
        import zipfile

        _finished_run(directory)
        path = directory / "out" / "checkpoint.npz"
        arrays = dict(np.load(path))
        count = 2**40 if declared_only else 2**25
        header = io.BytesIO()
        np.lib.format.write_array_header_1_0(
            header, {"descr": "<f8", "fortran_order": False, "shape": (count,)}
        )
        with zipfile.ZipFile(path, "w") as archive:
            for name, a in arrays.items():
                data = io.BytesIO()
                np.save(data, a)
                if name != "state.h":
                    archive.writestr(f"{name}.npy", data.getvalue())
                elif declared_only:
                    archive.writestr(f"{name}.npy", header.getvalue() + bytes(64))
                else:
                    info = zipfile.ZipInfo(f"{name}.npy")
                    info.compress_type = zipfile.ZIP_DEFLATED
                    with archive.open(info, "w", force_zip64=True) as member:
                        member.write(header.getvalue())
                        for _ in range(count * 8 // 2**24):
                            member.write(bytes(2**24))

    return setup


def netcdf4_copy(path: Path, cells: int, records: int = 0, forged: bool = False) -> None:
    """The result file ``path`` rewritten in the netCDF-4 format (HDF5) with ``cells`` cells
    along x, the variables over x never written (a file of kilobytes), ``records`` output
    times if given (one value written at the last), the scenario saying ``cells`` if
    ``forged`` (tests/test_damaged_results.py uses it too)."""
    import netCDF4

    copy = path.with_name("copy.nc")
    with NETCDF, netCDF4.Dataset(path) as src, netCDF4.Dataset(copy, "w", format="NETCDF4") as dst:
        attrs = {key: src.getncattr(key) for key in src.ncattrs()}
        if forged:
            attrs["scenario"] = attrs["scenario"].replace(
                f"cells: {len(src.dimensions['x'])}", f"cells: {cells}"
            )
        dst.setncatts(attrs)
        for name, dim in src.dimensions.items():
            dst.createDimension(name, None if dim.isunlimited() else cells if name == "x" else len(dim))
        for name, var in src.variables.items():
            fill = var.getncattr("_FillValue") if "_FillValue" in var.ncattrs() else None
            chunks = [min(cells, 2**20) if d == "x" else 1 for d in var.dimensions]
            new = dst.createVariable(
                name, var.dtype, var.dimensions, zlib=True, fill_value=fill, chunksizes=chunks
            )
            new.setncatts({key: var.getncattr(key) for key in var.ncattrs() if key != "_FillValue"})
            if "x" not in var.dimensions:
                new[:] = var[:]
        if records:
            dst["time"][records - 1] = 1.0
    os.replace(copy, path)


def _hdf5_result(cells: int, records: int = 0, forged: bool = False) -> Callable[[Path], None]:
    """A finished run whose result.nc is :func:`netcdf4_copy`'s."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        netcdf4_copy(directory / "out" / "result.nc", cells, records, forged)

    return setup


def _sensitivity(attrs: dict | None = None, outputs: int = 0) -> Callable[[Path], None]:
    """A sensitivity.nc of one output and two parameters with ``attrs``, or (``outputs``) a
    netCDF-4 one declaring that many outputs, never written."""

    def setup(directory: Path) -> None:
        import netCDF4

        with NETCDF, netCDF4.Dataset(directory / "sensitivity.nc", "w", format="NETCDF4") as ds:
            ds.createDimension("output", outputs or 1)
            ds.createDimension("parameter", 2)
            for name in ("output", "S1", "S1_conf", "ST", "ST_conf"):
                dims = ("output",) if name == "output" else ("output", "parameter")
                var = ds.createVariable(
                    name,
                    "f8",
                    dims,
                    zlib=True,
                    chunksizes=(min(outputs or 1, 2**20),) + (1,) * (len(dims) - 1),
                )
                if not outputs:
                    var[:] = np.full(var.shape, np.nan if name == "S1" else 0.3)
            if not outputs:
                ds.createVariable("parameter", str, ("parameter",))[:] = np.array(
                    ["mu_s", "nu"], dtype=object
                )
            ds.setncatts({"confidence_level": 0.95, "base_samples": 8, **(attrs or {})})

    return setup


def _scenario_appended(extra: str, checkpoint: bool = True) -> Callable[[Path], None]:
    """A run stopped after its first records whose result.nc's scenario (and its checkpoint's,
    checksummed again, if ``checkpoint``) ends with the YAML ``extra``."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        import netCDF4

        from multilayer.io.results import Checkpoint, load_checkpoint, save_checkpoint

        path = directory / "out" / "checkpoint.npz"
        saved = load_checkpoint(path)
        if checkpoint:
            save_checkpoint(
                path, Checkpoint(saved.state, saved.records, saved.wall_time_s, saved.scenario + extra)
            )
        with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
            ds.scenario = saved.scenario + extra
            ds.run_status = "interrupted"

    return setup


LAUGHS_BELOW = "extra:\n" + "".join(f"  {line}\n" for line in BILLION_LAUGHS.splitlines())
"""The billion laughs, under a key ``extra`` of a scenario."""


def _sweep_over_a_long_bed(directory: Path) -> None:
    """A sweep of 20 members of TINY over a bed CSV of 10^6 rows (15 MB)."""
    base = {**TINY, "bed": {"file": "bed.csv"}}
    _sweep({"slope_deg": [20.0 + 0.25 * i for i in range(20)]}, base=base)(directory)
    rows = np.linspace(0.0, 0.5, 10**6)
    (directory / "bed.csv").write_text("x (m), z (m)\n" + "".join(f"{x:.9f}, 0\n" for x in rows))


DAMAGED_MEMBER_STEPS = MEMBER_MEDDLED.replace(
    "MEDDLING",
    "import netCDF4\nwith netCDF4.Dataset(member / 'result.nc', 'a') as ds:\n    ds.steps = 'many'",
)
"""The first member's result.nc given ``steps: 'many'``, then the sweep again."""


def round_twenty() -> list[Case]:
    """The hostile cases of the twentieth round (docs/reliability.md): counts of 5000 digits
    or in other notations (environment, options), result files missing or damaging the
    attributes their readers read, files declaring more than they hold (a checkpoint
    deflated 1000 to 1, a netCDF-4 result or study file of kilobytes declaring billions of
    cells or outputs), a study file's attributes damaged."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    resume = [*run, "--resume"]
    many = "1" * 5000
    out = [
        Case("env MULTILAYER_THREADS of 5000 digits", run, 2, "MULTILAYER_THREADS='1111",
             setup=_scenario, env={"MULTILAYER_THREADS": many}),
        Case("env NUMBA_NUM_THREADS of 5000 digits", run, 2, "NUMBA_NUM_THREADS='1111",
             setup=_scenario, env={"NUMBA_NUM_THREADS": many}, plain=True),
        Case("validate: --max-steps of 5000 digits", ["validate", "{scenario}", "--max-steps", many], 2,
             "--max-steps: expected an integer >= 1 (ASCII digits", setup=_scenario),
        Case("validate: --max-steps in Arabic-Indic digits",
             ["validate", "{scenario}", "--max-steps", "\u0663"],
             2, "--max-steps: expected an integer >= 1 (ASCII digits", setup=_scenario),
        Case("plot: --times 1_0", ["plot", "{dir}/out", "--times", "1_0"], 2,
             "--times: expected an integer >= 1", setup=_finished_run),
        Case("plot: --at 0_1", ["plot", "{dir}/out", "--at", "0_1"], 2,
             "--at: expected a number in ASCII decimal notation", setup=_finished_run),
        Case("plot: --at in full-width digits", ["plot", "{dir}/out", "--at", "\uff10.\uff13"], 2,
             "--at: expected a number in ASCII decimal notation", setup=_finished_run),
        Case("plot: result.nc without the front's threshold", ["plot", "{dir}/out"], 2,
             "its variable front's attribute threshold is missing",
             setup=_result_attribute("front", "threshold", None)),
        Case("export: result.nc whose steps are 'many'", ["export", "{dir}/out", "--vtk"], 2,
             "its attribute steps is 'many', not an integer from 0 to 2^53",
             setup=_result_attribute(None, "steps", "many")),
        Case("plot: result.nc whose wall_time_s is NaN", ["plot", "{dir}/out"], 2,
             "its attribute wall_time_s is nan, not a finite number >= 0",
             setup=_result_attribute(None, "wall_time_s", float("nan"))),
        Case("resume: result.nc without multilayer_version", resume, 2,
             "its attribute multilayer_version is missing",
             setup=_result_attribute(None, "multilayer_version", None)),
        Case("resume: result.nc without multilayer_commit", resume, 2,
             "its attribute multilayer_commit is missing",
             setup=_result_attribute(None, "multilayer_commit", None)),
        Case("sweep: a member's result.nc whose steps are 'many', then the sweep again",
             ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out", "--workers", "1", "-q"], 0,
             "the summary of m000 is that of its result.nc", patch=DAMAGED_MEMBER_STEPS,
             setup=_sweep({"slope_deg": [20.0, 25.0]})),
        Case("resume: a checkpoint of 256 kB unpacking to 256 MB", resume, 2,
             "corrupt checkpoint (its members unpack to", setup=_checkpoint_bomb(False)),
        Case("resume: a checkpoint whose state.h declares 8 TB", resume, 2,
             "state.h.npy declares 8796093022208 bytes of data in 192", setup=_checkpoint_bomb(True)),
        Case("plot: a netCDF-4 result.nc of 4e9 unwritten cells", ["plot", "{dir}/out"], 2,
             "its dimension x has 4000000000 entries, not its scenario attribute's domain.cells (40)",
             setup=_hdf5_result(4 * 10**9)),
        Case("plot: a netCDF-4 result.nc of 4e9 unwritten cells, its scenario saying so",
             ["plot", "{dir}/out"], 2,
             "cells x 3 layers takes about 626 GiB of memory, more than is available now",
             setup=_hdf5_result(4 * 10**9, forged=True)),
        Case("export: a netCDF-4 result.nc of 2e7 output times", ["export", "{dir}/out", "--vtk"], 2,
             "it holds 20000000 output times; accepted: at most 10000002, as a run writes them",
             setup=_hdf5_result(40, 2 * 10**7)),
        Case("plot: sensitivity.nc whose failed_runs is 'abc'", ["plot", "{dir}"], 2,
             "its attribute failed_runs is 'abc', not a count", setup=_sensitivity({"failed_runs": "abc"})),
        Case("plot: sensitivity.nc whose confidence_level is NaN", ["plot", "{dir}"], 2,
             "its attribute confidence_level is nan, not in (0, 1)",
             setup=_sensitivity({"confidence_level": float("nan")})),
        Case("plot: sensitivity.nc whose base_samples is 1e300", ["plot", "{dir}"], 2,
             "its attribute base_samples is 1e+300, not a count",
             setup=_sensitivity({"base_samples": 1e300})),
        Case("plot: a netCDF-4 sensitivity.nc of 8 kB declaring 4e9 outputs", ["plot", "{dir}"], 2,
             "sensitivity.nc: its variables hold 288000000000 bytes", setup=_sensitivity(outputs=4 * 10**9)),
        Case("resume: a checkpoint and its result.nc whose scenario holds an alias inside its own anchor",
             resume, 2, "corrupt checkpoint (meta.scenario is not the YAML mapping of a scenario)",
             setup=_scenario_appended("extra: &a [*a]\n")),
        Case("resume: a checkpoint and its result.nc whose scenario holds the billion laughs", resume, 2,
             "corrupt checkpoint (meta.scenario is not the YAML mapping of a scenario)",
             setup=_scenario_appended(LAUGHS_BELOW)),
        Case("validate: a sweep of 20 members over a bed CSV of 10^6 rows (each read once)",
             ["validate", "{dir}/sweep.yaml"], 0, "", setup=_sweep_over_a_long_bed),
        Case("plot: result.nc whose scenario holds the billion laughs", ["plot", "{dir}/out"], 2,
             "its scenario attribute is missing or damaged", setup=_scenario_appended(LAUGHS_BELOW, False)),
    ]  # fmt: skip
    return out


def _result_edit(edit: str) -> Callable[[Path], None]:
    """A finished run whose result.nc is edited by ``edit``, Python run on its open
    netCDF4 Dataset ``ds``."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        import netCDF4

        with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
            exec(edit, {"ds": ds})

    return setup


def _initial_csv(text: str) -> Callable[[Path], None]:
    """A scenario whose initial thickness is the profile ``h.csv``, written as ``text``."""

    def setup(directory: Path) -> None:
        _scenario(directory, {"initial": [{"shape": "profile", "file": "h.csv"}]})
        (directory / "h.csv").write_bytes(text.encode())

    return setup


def _sweep_over_a_long_map_frame_bed(directory: Path) -> None:
    """A sweep of 20 members of TINY (friction) over a map-frame bed CSV of 10^6 rows."""
    base = {**TINY, "bed": {"file": "bed.csv", "frame": "map"}}
    _sweep({"rheology.mu_s": [0.2 + 0.01 * i for i in range(20)]}, base=base)(directory)
    rows = np.linspace(0.0, 0.6, 10**6)
    (directory / "bed.csv").write_text("x (m), z (m)\n" + "".join(f"{x:.9f}, {-0.4 * x:.9f}\n" for x in rows))


def _sweep_over_a_long_initial_profile(directory: Path) -> None:
    """A sweep of 20 members of TINY (friction) whose initial thickness is a CSV of 10^6 rows."""
    base = {**TINY, "initial": [{"shape": "profile", "file": "h.csv"}]}
    _sweep({"rheology.mu_s": [0.2 + 0.01 * i for i in range(20)]}, base=base)(directory)
    rows = np.linspace(0.0, 0.5, 10**6)
    (directory / "h.csv").write_text(
        "x (m), h (m)\n" + "".join(f"{x:.9f}, {0.05 if x < 0.1 else 0.0}\n" for x in rows)
    )


def round_twenty_one() -> list[Case]:
    """The hostile cases of the twenty-first round (docs/reliability.md): CSV rows holding
    characters ``str.splitlines`` ends a line at (a form feed, ``\\u2028``, ``\\x85``), result
    files whose cell centres or bed are not their scenario's (consistently edited), a Dask
    scheduler address whose port is no port, and a sweep over a map-frame bed of 10^6 rows."""
    validate = ["validate", "{scenario}"]
    sweep = ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/out", "-q"]
    got = "expected two numbers separated by a comma, got"
    shift = "for name in ('x', 'x_bnds', 'front'):\n    ds[name][:] = ds[name][:] + 100.0"
    out = [
        Case("validate: a bed CSV row holding a form feed", validate, 2,
             f"bed.csv: line 2: {got} '0, 0\\x0c0.5, 0'", setup=_csv_bed("x (m), z (m)\n0, 0\f0.5, 0\n")),
        Case("validate: a bed CSV row holding a line separator U+2028", validate, 2,
             f"bed.csv: line 2: {got} '0, 0\\u20280.5, 0'",
             setup=_csv_bed("x (m), z (m)\n0, 0\u20280.5, 0\n")),
        Case("run: an initial-thickness CSV row holding a next-line character U+0085",
             ["run", "{scenario}", "-o", "{dir}/out", "-q"], 2,
             f"h.csv: line 3: {got} '0.1, 0.05\\x850.2, 0'",
             setup=_initial_csv("x (m), h (m)\n0, 0.05\n0.1, 0.05\x850.2, 0\n0.5, 0\n")),
        Case("validate: a bed CSV whose comment holds a form feed, its error a line later (the line named)",
             validate, 2, f"bed.csv: line 4: {got} '0.5, x'",
             setup=_csv_bed("x (m), z (m)\n# a note\fof two parts\n0, 0\n0.5, x\n")),
        Case("validate: a bed CSV with CR line ends and a byte order mark", validate, 0, "",
             setup=_csv_bed("\ufeffx (m), z (m)\r0, 0\r0.5, 0\r")),
        Case("plot: result.nc whose x, x_bnds and front are moved 100 m", ["plot", "{dir}/out"], 2,
             "its cell centres x or edges x_bnds are not the 40 cells of its scenario's domain [0, 0.5] m",
             setup=_result_edit(shift)),
        Case("export: result.nc whose x, x_bnds and front are moved 100 m",
             ["export", "{dir}/out", "--vtk"], 2,
             "its cell centres x or edges x_bnds are not the 40 cells of its scenario's domain [0, 0.5] m",
             setup=_result_edit(shift)),
        Case("export: result.nc whose bed is raised 1 m", ["export", "{dir}/out", "--vtk"], 2,
             "its bed is not its scenario's bed: 1 m at x = 0.00625 m, where the scenario's bed is at 0 m",
             setup=_result_edit("ds['bed'][:] = ds['bed'][:] + 1.0")),
        Case("plot: result.nc whose scenario's bed is of no profile", ["plot", "{dir}/out"], 2,
             "its scenario attribute's bed is not a flat bed or points",
             setup=_result_edit("ds.scenario = ds.scenario.replace('profile: flat', 'profile: lumpy')")),
        Case("resume: result.nc whose bed is raised 1 m",
             ["run", "{scenario}", "-o", "{dir}/out", "--resume"], 2,
             "its bed is not its scenario's bed", setup=_result_edit("ds['bed'][:] = ds['bed'][:] + 1.0")),
        Case("sweep: --scheduler tcp://[::1]:99999", [*sweep, "--scheduler", "tcp://[::1]:99999"], 2,
             "cannot connect (ValueError: port 99999 is no TCP port (1 to 65535))",
             setup=_sweep({"slope_deg": [20.0, 25.0]})),
        Case("sweep: --scheduler localhost:0", [*sweep, "--scheduler", "localhost:0"], 2,
             "cannot connect (ValueError: port 0 is no TCP port (1 to 65535))",
             setup=_sweep({"slope_deg": [20.0, 25.0]})),
        Case("validate: a sweep of 20 members over a map-frame bed CSV of 10^6 rows (turned once)",
             ["validate", "{dir}/sweep.yaml"], 0, "", setup=_sweep_over_a_long_map_frame_bed),
        Case("validate: a sweep of 20 members whose initial thickness is a CSV of 10^6 rows (read once)",
             ["validate", "{dir}/sweep.yaml"], 0, "", setup=_sweep_over_a_long_initial_profile),
    ]  # fmt: skip
    return out


def round_twenty_two() -> list[Case]:
    """The hostile cases of the twenty-second round (docs/reliability.md): values valid one
    by one and absurd together: a front threshold no cell can reach (said by the run, refused
    where an ``expect`` entry needs the front), cells narrower than the floats at the
    domain's place, an inflow leaving the domain faster than its waves can enter, two
    ``expect`` entries on one quantity that no value passes together, ``base`` zones that
    apply to no column; a directory of a run and a study, and a study's plotted with a run's
    options."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    validate = ["validate", "{scenario}"]
    runout = [{"kind": "regression", "quantity": "runout", "value": 0.2, "rtol": 0.1}]
    unreachable = {"numerics": {"front_threshold": 0.5}}  # the column in one cell: 0.4 m
    far = {
        "domain.x_min": 1e6,
        "domain.x_max": 1e6 + 1e-6,
        "domain.cells": 10000,
        "material.grain_diameter": 1e-12,
        "initial.0.x_min": 1e6,
        "initial.0.x_max": 1e6 + 1e-7,
        "time.end": 1e-9,
        "time.output_interval": 5e-10,
    }
    pins = [
        {"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.02},
        {"kind": "regression", "quantity": "mass_final", "value": 0.004, "rtol": 0.02},
    ]

    between = {"condition": "coulomb", "mu": 0.5, "x_min": 0.1, "x_max": 0.105}

    def leaving(side: str, speed: float) -> dict:
        other = "right" if side == "left" else "left"
        inflow = {"thickness": 0.01, "velocity": {"profile": "plug", "speed": speed}}
        return {"initial": [], "boundaries": {side: "inflow", other: "outflow", "inflow": inflow}}

    out = [
        Case("run: a front threshold of 0.5 m, above the column of 0.4 m held in one cell (said)", run, 0,
             "the front is absent (NaN) at every output time", setup=lambda d: _scenario(d, unreachable)),
        Case("validate: a front threshold no cell can reach and an expect entry on the run-out", validate,
             2, "numerics.front_threshold (line",
             setup=lambda d: _scenario(d, {**unreachable, "expect": runout})),
        Case("check: a front threshold no cell can reach and an expect entry on the run-out",
             ["check", "{scenario}"], 2, "and expect checks runout",
             setup=lambda d: _scenario(d, {**unreachable, "expect": runout})),
        Case("run: 10^4 cells of 1e-10 m at x = 1e6 m, where floats are 1.16e-10 m apart", run, 2,
             "10000 cells of 1e-10 m, where floats near x = 1e+06 m are 1.16e-10 m apart",
             setup=lambda d: _scenario(d, far)),
        Case("run: a left inflow at -5 m/s into an empty domain", run, 2,
             "the left side's inflow moves out of the domain at 5 m/s",
             setup=lambda d: _scenario(d, leaving("left", -5.0))),
        Case("validate: a right inflow at +5 m/s", validate, 2,
             "the right side's inflow moves out of the domain at 5 m/s",
             setup=lambda d: _scenario(d, leaving("right", 5.0))),
        Case("run: a left inflow at -0.1 m/s (a reservoir: material enters)", run, 0, "",
             setup=lambda d: _scenario(d, leaving("left", -0.1))),
        Case("check: two expect entries on mass_final, 0.005 +- 1e-4 and 0.004 +- 8e-5",
             ["check", "{scenario}"], 2, "expect.1.value (line",
             setup=lambda d: _scenario(d, {"expect": pins})),
        Case("run: a Coulomb base zone between two cell centres (0.1 to 0.105 m, cells of 0.0125 m)", run,
             2, "holds no cell centre (cells of 0.0125 m)",
             setup=lambda d: _scenario(d, {"base": [{"condition": "no_slip"}, between]})),
        Case("validate: a base zone under a later zone on every cell", validate, 2,
             "applies to no column: later entries",
             setup=lambda d: _scenario(d, {"base": [{"condition": "no_slip", "x_max": 0.2},
                                                    {"condition": "free_slip"}]})),
        Case("plot: a run's directory that also holds a sensitivity.nc", ["plot", "{dir}/out"], 2,
             "holds result.nc (a run) and sensitivity.nc (a study)", setup=_run_and_study),
        Case("plot: a sensitivity study's directory with --format svg --animate",
             ["plot", "{dir}", "--format", "svg", "--animate"], 2,
             "--format, --animate apply to a run's figures only", setup=_sensitivity()),
    ]  # fmt: skip
    return out


def _input_in_output(key: str, name: str, link: bool = False) -> Callable[[Path], None]:
    """A scenario whose ``bed`` (``key`` bed) or initial thickness (``initial``) is the file
    ``out/name``, a file its run writes, or (``link``) ``bed.csv`` hard-linked there."""

    def setup(directory: Path) -> None:
        (directory / "out").mkdir()
        written = directory / "out" / name
        if key == "bed":
            bed = directory / "bed.csv" if link else written
            bed.write_text("x (m), z (m)\n0, 0\n0.5, 0\n")
            if link:
                os.link(bed, written)
            _scenario(directory, {"bed": {"file": bed.relative_to(directory).as_posix()}})
        else:
            written.write_text("x (m), h (m)\n0, 0.05\n0.1, 0.05\n0.1001, 0\n0.5, 0\n")
            _scenario(directory, {"initial": [{"shape": "profile", "file": f"out/{name}"}]})

    return setup


def _calibration_of(
    observation: dict, base: dict = TINY, extra: dict | None = None
) -> Callable[[Path], None]:
    """A calibration of ``rheology.mu_s`` on ``base`` against one ``observation`` (a front
    file ``front.csv`` beside it: 0.12 m at 0.05 s, 7 m at 0.1 s), with the keys ``extra``."""

    def setup(directory: Path) -> None:
        (directory / "base.yaml").write_text(yaml.safe_dump(base))
        (directory / "front.csv").write_text("t,x_f,sigma\n0.05,0.12,0.01\n0.1,7,0.01\n")
        config = {
            "base": "base.yaml",
            "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
            "observations": [{"name": "seen", **observation}],
            "search": {"population": 4, "generations": 1},
            **(extra or {}),
        }
        (directory / "calibration.yaml").write_text(yaml.safe_dump(config))

    return setup


def round_twenty_three() -> list[Case]:
    """The hostile cases of the twenty-third round (docs/reliability.md): files a run reads
    that it would write over (a bed or initial-thickness file at ``out/result.nc``,
    ``out/run.lock``, ``out/run.log``, hard-linked at ``out/checkpoint.npz``), a run of no
    material, observations no run can come near, sizes Python's ``float`` refuses or that
    are infinite, a sweep of its members' output directory; booleans as numbers, a YAML
    key that is a list, a domain whose length overflows and a resume shortening the run as
    controls."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    validate = ["validate", "{scenario}"]
    front = {"quantity": "front", "file": "front.csv", "columns": ["t", "x_f", "sigma"]}
    out = [
        Case("validate: time.end true (a boolean where a number is expected)", validate, 2,
             "time.end (line 24): Input should be a valid number (got True)",
             setup=lambda d: _scenario(d, {"time.end": True})),
        Case("run: --set initial=[] without an inflow (a run of nothing)", [*run, "--set", "initial=[]"], 2,
             "initial: an empty list and no inflow: the run would hold no material", setup=_scenario),
        Case("validate: initial: [] without an inflow", validate, 2, "initial: an empty list and no inflow",
             setup=lambda d: _scenario(d, {"initial": []})),
        Case("run: a bed file out/result.nc, run into out", run, 2, "result.nc: the file bed.file of",
             setup=_input_in_output("bed", "result.nc")),
        Case("run: a bed file out/run.lock, run into out", run, 2, "run.lock: the file bed.file of",
             setup=_input_in_output("bed", "run.lock")),
        Case("run: an initial-thickness file out/run.log, run into out", run, 2,
             "run.log: the file initial.0.file of", setup=_input_in_output("initial", "run.log")),
        Case("run: a bed file hard-linked at out/checkpoint.npz, run into out", run, 2,
             "checkpoint.npz: the file bed.file of", setup=_input_in_output("bed", "checkpoint.npz", True)),
        Case("validate: a calibration's front observed at 7 m on a domain of 0.5 m",
             ["validate", "{dir}/calibration.yaml"], 2,
             "observed front 7 m at 0.1 s (sigma 0.01 m), more than 3 standard deviations from what any run "
             "gives (a front within the domain [0, 0.5] m)", setup=_calibration_of(front)),
        Case("validate: a calibration's duration observed at 3 s, runs to 0.2 s",
             ["validate", "{dir}/calibration.yaml"], 2, "a duration within the simulated time, 0 to 0.2 s",
             setup=_calibration_of({"quantity": "duration", "value": 3.0, "sigma": 0.1})),
        Case("validate: --max-memory 1.2.3", [*validate, "--max-memory", "1.2.3"], 2,
             "not a size: '1.2.3'; accepted: a finite number of bytes > 0", setup=_scenario),
        Case("run: --max-output 1e999", [*run, "--max-output", "1e999"], 2,
             "not a size > 0: '1e999' is inf bytes; accepted", setup=_scenario),
        Case("validate: a sweep of output.directory", ["validate", "{dir}/sweep.yaml"], 2,
             "parameters.output.directory (line 3): a member's output is not its own",
             setup=_sweep({"output.directory": ["a", "b"]})),
        Case("validate: a YAML key that is a list (? [a, b])", validate, 2, "found unhashable key",
             setup=lambda d: _scenario(d, text=yaml.safe_dump(TINY) + "? [a, b]\n: 1\n")),
        Case("validate: a domain from -1e308 to 1e308 m (its length overflows)", validate, 2,
             "the domain is inf m long", setup=lambda d: _scenario(
                 d, {"domain.x_min": -1e308, "domain.x_max": 1e308, "initial.0.x_max": 1e307})),
        Case("resume: --set time.end=0.1 below the checkpoint at 0.2 s",
             [*run, "--resume", "--set", "time.end=0.1"], 2, "a run can be extended, not shortened",
             setup=_finished_run),
    ]  # fmt: skip
    return out


def _front_file(**front: Any) -> Callable[[Path], None]:
    """A calibration of TINY (to t = 2 s) against a front read from the netCDF file
    ``front.nc``: a variable ``x_f`` over ``t`` (0.02, 0.04 s), changed by ``front``:
    ``coordinate`` False (no variable t), ``units`` of t, ``values`` and their ``kind``."""

    def setup(directory: Path) -> None:
        import netCDF4

        values = front.get("values", (0.02, 0.03))
        kind = front.get("kind", "f8")
        with NETCDF, netCDF4.Dataset(directory / "front.nc", "w") as ds:
            ds.createDimension("t", len(values))
            if front.get("coordinate", True):
                t = ds.createVariable("t", "f8", ("t",))
                t[:], t.units = [0.02, 0.04][: len(values)], front.get("units", "s")
            x = ds.createVariable("x_f", kind, ("t",))
            x.units = "m"
            x[:] = np.array(values, dtype=object if kind is str else kind)
        base = {**TINY, "time": {"end": 2.0, "output_interval": 0.5}}
        _calibration_of({"quantity": "front", "file": "front.nc", "variable": "x_f", "sigma": 0.01}, base)(
            directory
        )

    return setup


def _study_over_its_file(command: str) -> Callable[[Path], None]:
    """A study whose input is the file it writes into ``out``: a sweep's base scenario
    ``out/summary.csv``, a calibration's observations ``out/calibration.nc``, a sensitivity
    study's base ``out/sensitivity.nc``."""

    def setup(directory: Path) -> None:
        (directory / "out").mkdir()
        if command == "calibrate":
            _front_file()(directory)
            os.replace(directory / "front.nc", directory / "out" / "calibration.nc")
            config = yaml.safe_load((directory / "calibration.yaml").read_text())
            config["observations"][0]["file"] = "out/calibration.nc"
        elif command == "sweep":
            (directory / "out" / "summary.csv").write_text(yaml.safe_dump(TINY))
            config = {"base": "out/summary.csv", "parameters": {"slope_deg": [20.0, 25.0]}}
        else:
            (directory / "out" / "sensitivity.nc").write_text(yaml.safe_dump(TINY))
            config = {
                "base": "out/sensitivity.nc",
                "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
                "outputs": ["runout"],
                "samples": 8,
            }
        (directory / "study.yaml").write_text(yaml.safe_dump(config))

    return setup


def _study_of_the_runout(base: dict) -> Callable[[Path], None]:
    """A sensitivity study of the run-out of ``base`` to its friction and slope."""

    def setup(directory: Path) -> None:
        (directory / "base.yaml").write_text(yaml.safe_dump(base))
        parameters = {"rheology.mu_s": {"bounds": [0.2, 0.4]}, "slope_deg": {"bounds": [20.0, 30.0]}}
        study = {"base": "base.yaml", "parameters": parameters, "outputs": ["runout"], "samples": 64}
        (directory / "study.yaml").write_text(yaml.safe_dump(study))

    return setup


def _study_of_a_bed(sobol: bool) -> Callable[[Path], None]:
    """A study of the elevations of the 399 inner points of a bed of 400: Sobol' indices of
    the mass from 65536 base samples (``sobol``), or a calibration to the mass with a
    population of 10^4."""

    def setup(directory: Path) -> None:
        n = 400
        base = {**TINY, "bed": {"points": [[0.5 * i / (n - 1), 0.0] for i in range(n)]}}
        (directory / "base.yaml").write_text(yaml.safe_dump(base))
        parameters = {f"bed.points.{i}.1": {"bounds": [0.0, 0.001]} for i in range(1, n)}
        study: dict = {"base": "base.yaml", "parameters": parameters}
        if sobol:
            study.update(outputs=["mass_final"], samples=65536)
        else:
            observation = {"name": "m", "quantity": "mass_final", "value": 0.005, "sigma": 1e-4}
            study.update(observations=[observation], search={"population": 10_000})
        (directory / "study.yaml").write_text(yaml.safe_dump(study))

    return setup


def _retyped_result(variable: str, dtype: str) -> Callable[[Path], None]:
    """A finished run whose result.nc's ``variable`` is stored as ``dtype`` (its values cast,
    no fill value): the file copied variable by variable."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        import netCDF4

        path = directory / "out" / "result.nc"
        copy = path.with_name("copy.nc")
        with NETCDF, netCDF4.Dataset(path) as src, netCDF4.Dataset(copy, "w", format=src.data_model) as dst:
            src.set_auto_maskandscale(False)
            dst.setncatts({key: src.getncattr(key) for key in src.ncattrs()})
            for name, dim in src.dimensions.items():
                dst.createDimension(name, None if dim.isunlimited() else len(dim))
            for name, var in src.variables.items():
                kind = np.dtype(dtype) if name == variable else var.dtype
                fill = (
                    None
                    if name == variable
                    else var.getncattr("_FillValue")
                    if "_FillValue" in var.ncattrs()
                    else None
                )
                new = dst.createVariable(name, kind, var.dimensions, fill_value=fill)
                new.setncatts({key: var.getncattr(key) for key in var.ncattrs() if key != "_FillValue"})
                new.set_auto_maskandscale(False)
                new[:] = var[:].astype(kind)
        os.replace(copy, path)

    return setup


def round_twenty_four() -> list[Case]:
    """The hostile cases of the twenty-fourth round (docs/reliability.md): netCDF
    observations that are not numbers over their coordinate (no coordinate variable, times
    in dates, text, no values), studies whose input is the file they write or that measure
    the front where no cell can reach its threshold, study designs of gigabytes; as
    controls, a
    front in days, a result whose ``h`` or time is stored in single precision, a failed
    run's message and a version holding a terminal escape sequence."""
    study = ["-o", "{dir}/out", "-q"]
    calibration = ["validate", "{dir}/calibration.yaml"]
    not_numbers = "accepted: a variable of numbers over a coordinate variable t of numbers"
    escape = "ds.run_status = 'failed'; ds.failure = 'boom \\x1b[2J end'"
    front = {"quantity": "front", "file": "front.csv", "columns": ["t", "x_f", "sigma"]}
    unreachable = {**TINY, "numerics": {"front_threshold": 0.5}}  # the column in one cell: 0.4 m
    out = [
        Case("validate: a netCDF front over a dimension without a coordinate variable", calibration, 2,
             "the dimension t of x_f has no coordinate variable (its entries would be read at t = 0, 1, 2",
             setup=_front_file(coordinate=False)),
        Case("validate: a netCDF front whose times are in seconds since 2000-01-01", calibration, 2,
             "t has units 'seconds since 2000-01-01', which are read as dates",
             setup=_front_file(units="seconds since 2000-01-01")),
        Case("validate: a netCDF front of text", calibration, 2,
             f"x_f holds values of type <U1; {not_numbers}", setup=_front_file(values=("a", "b"), kind=str)),
        Case("validate: a netCDF front of no values", calibration, 2, "x_f holds no values",
             setup=_front_file(values=())),
        Case("validate: a netCDF front whose times are in days", calibration, 2, "unit 'days' in",
             setup=_front_file(units="days")),
        Case("validate: a netCDF front of numbers over its times (s)", calibration, 0, "",
             setup=_front_file()),
        Case("sweep: its base scenario out/summary.csv, into out", ["sweep", "{dir}/study.yaml", *study], 2,
             "summary.csv: the base scenario of", setup=_study_over_its_file("sweep")),
        Case("calibrate: its observations out/calibration.nc, into out",
             ["calibrate", "{dir}/study.yaml", *study], 2, "calibration.nc: the file observations.0.file of",
             setup=_study_over_its_file("calibrate")),
        Case("sensitivity: its base scenario out/sensitivity.nc, into out",
             ["sensitivity", "{dir}/study.yaml", *study], 2, "sensitivity.nc: the base scenario of",
             setup=_study_over_its_file("sensitivity")),
        Case("validate: a calibration whose set gives output.directory", calibration, 2,
             "set.output.directory (line 19): a member's output is not its own",
             setup=_calibration_of(front, {**TINY, "time": {"end": 2.0, "output_interval": 0.5}},
                                   {"set": {"output.directory": "elsewhere"}})),
        Case("validate: a calibration whose experiment gives output", calibration, 2,
             "experiments.a.output (line 4): a member's output is not its own",
             setup=_calibration_of(front, {**TINY, "time": {"end": 2.0, "output_interval": 0.5}},
                                   {"experiments": {"a": {"output": {"directory": "elsewhere"}}}})),
        Case("validate: a calibration of the front whose threshold no cell can reach", calibration, 2,
             "and the study measures front on it", setup=_calibration_of(front, unreachable)),
        Case("validate: a calibration of the mass whose front threshold no cell can reach", calibration, 0,
             "",
             setup=_calibration_of({"quantity": "mass_final", "value": 0.005, "sigma": 1e-4}, unreachable)),
        Case("validate: a sensitivity study of the run-out whose threshold no cell can reach",
             ["validate", "{dir}/study.yaml"], 2, "and the study measures runout on it",
             setup=_study_of_the_runout(unreachable)),
        Case("validate: a sensitivity study of 65536 base samples of 399 parameters (a design of 78 GiB)",
             ["validate", "{dir}/study.yaml"], 2,
             "samples (line 1601): 65536 x (399 parameters + 2) = 26279936 runs of 399 values: 78.1 GiB",
             setup=_study_of_a_bed(True)),
        Case("validate: a calibration of 399 parameters, a population of 10^4 (12 GiB)",
             ["validate", "{dir}/study.yaml"], 2,
             "search.population (line 1605): 10000 x (399 parameters) = 3990000 runs of 399 values",
             setup=_study_of_a_bed(False)),
        Case("plot: result.nc whose h is stored as float32", ["plot", "{dir}/out"], 2,
             "is not the integral of h", setup=_retyped_result("h", "f4")),
        Case("export: result.nc whose time is stored as float32", ["export", "{dir}/out", "--vtk"], 2,
             "is not the impulse of its forces", setup=_retyped_result("time", "f4")),
        Case("plot: a failed run whose failure holds a terminal escape sequence", ["plot", "{dir}/out"], 0,
             "the run failed: boom \\x1b[2J end", setup=_result_edit(escape)),
    ]  # fmt: skip
    return out


def round_twenty_five() -> list[Case]:
    """The hostile cases of the twenty-fifth round (docs/reliability.md): DEM beds in degrees,
    feet (map or heights) or no frame at all, sampled at X = 1e300 m, of two bands or
    complex values, with a rotated or degenerate geotransform, scaled integers, a VRT file
    named ``.tif``, a raster of 4 x 10^8 pixels under a memory limit and one block of that
    size; files a study's base scenario reads where the study writes (``out/summary.csv``,
    ``out/calibration.nc``, ``out/sensitivity.nc``, a member's directory); a calibration of
    1.2 x 10^9 runs; as controls, a DEM of one pixel, of nodata only, a text file named
    ``.tif`` and a calibration of its default size."""
    validate = ["validate", "{scenario}"]
    study = ["-o", "{dir}/out", "-q"]
    metres = (
        "accepted: a single-band GeoTIFF of elevations in metres in a projected coordinate reference system"
    )
    memory = ["sh", "-c", 'ulimit -v 3000000 && exec "$0" "$@"']  # 3 GB of address space
    mass = {"quantity": "mass_final", "value": 0.005, "sigma": 1e-4}
    out = [
        Case("validate: a DEM in degrees (EPSG:4326, pixels of 0.01 degree)", validate, 2,
             "a geographic coordinate reference system (EPSG:4326), whose coordinates are not metres",
             setup=_dem(crs="EPSG:4326")),
        Case("validate: a DEM without a coordinate reference system", validate, 2,
             f"no coordinate reference system: where its pixels lie, or in what units, is not said; {metres}",
             setup=_dem(crs=None)),
        Case("validate: a DEM in US survey feet (EPSG:2227)", validate, 2,
             "map coordinates in US survey foot (0.304801 m), not metres", setup=_dem(crs="EPSG:2227")),
        Case("validate: a DEM in UTM metres over NAVD88 heights in feet (EPSG:32610+6360)", validate, 2,
             "elevations in 'US survey foot', not metres", setup=_dem(crs="EPSG:32610+6360")),
        Case("validate: a DEM sampled along a polyline at X = 1e300 m", validate, 2,
             "no elevation at (1e+300, 0.2), 0 m along the polyline", setup=_dem(far=True)),
        Case("validate: a DEM whose elevations are in feet (band unit ft)", validate, 2,
             "elevations in 'ft', not metres", setup=_dem(units="ft")),
        Case("validate: a DEM of int16 centimetres (scale 0.01), rising 5 deg", validate, 0, "",
             setup=_dem(scale=0.01)),
        Case("validate: a DEM whose geotransform is rotated 90 degrees", validate, 0, "",
             setup=_dem(rotated=True)),
        Case("validate: a DEM whose geotransform maps its pixels on a line", validate, 2,
             "a geotransform (0.01, 0.01, 0.0, 0.01, 0.01, 1.0) that maps its pixels on no area",
             setup=_dem(transform=(0.01, 0.01, 0.0, 0.01, 0.01, 1.0))),
        Case("validate: a DEM of two bands", validate, 2, "dem.tif: 2 bands, which one is the elevation",
             setup=_dem(bands=2)),
        Case("validate: a DEM of complex values", validate, 2, "values of type complex64, not real numbers",
             setup=_dem(dtype="complex64")),
        Case("validate: a VRT file named dem.tif reading another raster", validate, 2,
             "not recognized as being in a supported file format", setup=_dem(vrt=True)),
        Case("validate: a DEM of 20000 x 20000 pixels under 3 GB of memory", validate, 0, "",
             setup=_dem(huge=True), prefix=memory),
        Case("validate: a DEM of one block of 20000 x 20000 pixels", validate, 2,
             "blocks of 20000 x 20000 pixels, decoded whole to read any of their pixels",
             setup=_dem(huge=True, strip=True), prefix=memory),
        Case("validate: a DEM of one pixel", validate, 0, "", setup=_dem(pixel=True)),
        Case("validate: a DEM of nodata only", validate, 2,
             "no elevation at (0.05, 0.2), 0 m along the polyline", setup=_dem(nodata=True)),
        Case("validate: a text file named dem.tif", validate, 2, "cannot read the DEM",
             setup=_dem(text=True)),
        Case("sweep: its base scenario's bed file out/summary.csv, into out",
             ["sweep", "{dir}/study.yaml", *study], 2,
             "summary.csv: the file bed.file of", setup=_base_reads_output("sweep", "summary.csv")),
        Case("calibrate: its base scenario's initial-thickness file out/calibration.nc, into out",
             ["calibrate", "{dir}/calibration.yaml", *study], 2,
             "calibration.nc: the file initial.0.file of", setup=_base_reads_output(
                 "calibrate", "calibration.nc")),
        Case("sensitivity: its base scenario's bed file out/sensitivity.nc, into out",
             ["sensitivity", "{dir}/study.yaml", *study], 2,
             "sensitivity.nc: the file bed.file of", setup=_base_reads_output(
                 "sensitivity", "sensitivity.nc")),
        Case("sweep: of bed.file, its second value out/summary.csv, into out",
             ["sweep", "{dir}/study.yaml", *study], 2, "summary.csv: the file bed.file of member m001-",
             setup=_base_reads_output("sweep", "summary.csv", member=True)),
        Case("calibrate: an experiment's bed file out/calibration.nc, into out",
             ["calibrate", "{dir}/calibration.yaml", *study], 2, "calibration.nc: the file bed.file of",
             setup=_base_reads_output("calibrate", "calibration.nc", member=True)),
        Case("sweep: its base scenario's bed file in its first member's directory",
             ["sweep", "{dir}/study.yaml", *study], 2,
             "where a member of the sweep runs; accepted: files the sweep reads outside its members",
             setup=_base_reads_output("sweep", None)),
        Case("validate: a calibration of 10^4 generations of 10^4 x 4 members over 3 experiments",
             ["validate", "{dir}/calibration.yaml"], 2,
             "search.generations (line 31): 3 experiment(s) x (10000 x 4 parameters x (10000 generations "
             "+ 1) + 10 evaluations x (4 + 1) + 2 x 4) = 1.2e+09 runs; accepted: a study of at most 1e+07 "
             "runs",
             setup=_calibration_of(mass, extra={
                 "parameters": {f"rheology.{k}": {"bounds": [0.2, 0.4]} for k in ("mu_s", "nu")} | {
                     f"initial.0.{k}": {"bounds": [0.04, 0.06]} for k in ("height",)} | {
                     "slope_deg": {"bounds": [20.0, 30.0]}},
                 "experiments": {"a": {}, "b": {"time.end": 0.3}, "c": {"time.end": 0.4}},
                 "search": {"population": 10_000, "generations": 10_000}})),
        Case("validate: a calibration of the default search", ["validate", "{dir}/calibration.yaml"], 0, "",
             setup=_calibration_of(mass, extra={"search": {}})),
    ]  # fmt: skip
    return out


def _dem(**kind: Any) -> Callable[[Path], None]:
    """TINY on the bed of a GeoTIFF ``dem.tif`` (UTM, 80 x 40 pixels of 0.01 m, rising at 5
    degrees towards +X) along a polyline at Y = 0.2 m, changed by ``kind``: its ``crs``, the
    band's ``units``, int16 values of ``scale`` (m), a ``rotated`` or other ``transform``,
    ``bands``, a ``dtype``, a ``vrt`` file wrapping it, ``huge`` (20000 x 20000 pixels, sparse;
    ``strip``: one block), one ``pixel``, ``nodata`` only, ``text``, or a polyline ``far``
    away (X = 1e300 m)."""

    def setup(directory: Path) -> None:
        import rasterio
        from rasterio.transform import Affine

        rows, cols = (20000, 20000) if kind.get("huge") else (1, 1) if kind.get("pixel") else (40, 80)
        x = (np.arange(min(cols, 80)) + 0.5) * 0.01
        z = np.tile(100 + x * np.tan(np.radians(5.0)), (min(rows, 40), 1))
        transform = Affine(0.01, 0.0, 0.0, 0.0, -0.01, 0.4)
        if kind.get("rotated"):  # rows along -X, columns along +Y: the same terrain
            z, transform = z.T[::-1].copy(), Affine(0.0, -0.01, 0.8, 0.01, 0.0, 0.0)
        if "transform" in kind:
            transform = Affine(*kind["transform"])
        if kind.get("pixel"):
            z, transform = np.array([[5.0]]), Affine(1.0, 0.0, 0.0, 0.0, -1.0, 1.0)
        dtype = kind.get("dtype", "int16" if "scale" in kind else "float64")
        raster = directory / ("inner.tif" if kind.get("vrt") else "dem.tif")
        if kind.get("text"):
            raster.write_text("elevation: 100 m\n")
        else:
            profile: dict[str, Any] = {
                "driver": "GTiff",
                "dtype": dtype,
                "crs": kind.get("crs", "EPSG:32632"),
            }
            if kind.get("huge"):
                blocks = {"blockysize": rows, "compress": "deflate"} if kind.get("strip") else {"tiled": True}
                profile.update(sparse_ok=True, dtype="float32", **blocks)
            with rasterio.open(
                raster, "w", height=max(rows, z.shape[0]), width=max(cols, z.shape[1]), transform=transform,
                count=kind.get("bands", 1),
                nodata=-9999.0 if kind.get("nodata") else None, **profile,
            ) as dem:  # fmt: skip
                values = np.full_like(z, -9999.0) if kind.get("nodata") else z
                if "scale" in kind:
                    values = np.round(values / kind["scale"])
                for band in range(1, dem.count + 1):
                    window = rasterio.windows.Window(0, 0, z.shape[1], z.shape[0])
                    dem.write(values.astype(dem.dtypes[0]), band, window=window)
                if "scale" in kind:
                    dem.scales = (kind["scale"],)
                if "units" in kind:
                    dem.units = (kind["units"],)
        if kind.get("vrt"):
            (directory / "dem.tif").write_text(
                '<VRTDataset rasterXSize="80" rasterYSize="40"><SRS>EPSG:32632</SRS>'
                "<GeoTransform>0, 0.01, 0, 0.4, 0, -0.01</GeoTransform>"
                '<VRTRasterBand dataType="Float64" band="1"><SimpleSource>'
                f'<SourceFilename relativeToVRT="0">{raster}</SourceFilename><SourceBand>1</SourceBand>'
                "</SimpleSource></VRTRasterBand></VRTDataset>"
            )
        line = [[0.05, 0.2], [0.75, 0.2]] if not kind.get("pixel") else [[0.2, 0.5], [0.8, 0.5]]
        far = (
            {"polyline": [[1e300, 0.2], [1.0000000001e300, 0.2]], "spacing": 1e289} if kind.get("far") else {}
        )
        _scenario(directory, {"bed": {"dem": "dem.tif", "polyline": line, "extend": "flat", **far}})

    return setup


def round_twenty_six() -> list[Case]:
    """The hostile cases of the twenty-sixth round (docs/reliability.md): a sparse DEM (blocks
    never written) without a nodata value, an elevation of 1e308 m and an undeclared float32
    fill value, a sidecar ``.aux.xml`` setting a scale or a nodata value, a DEM cut short
    (also under ``GTIFF_IGNORE_READ_ERRORS=YES``), a finished run extended from an end
    between two output times; as controls, a sparse DEM whose blocks on the polyline are
    written, one with a nodata value, a DEM as high as Everest, a sidecar of statistics
    only, a mask sidecar and an extension from an output time."""
    validate = ["validate", "{scenario}"]
    extend = ["run", "{scenario}", "-o", "{dir}/out", "--set", "time.end=0.3", "--resume", "-q"]
    never = "on the polyline was never written (a sparse GeoTIFF) and the DEM has no nodata value"
    out = [
        Case("validate: a sparse DEM without nodata, its blocks on the polyline unwritten", validate, 2,
             f"dem.tif: the block of pixels (0-31, 32-63) (rows, columns) {never}",
             setup=_dem26(sparse="line")),
        Case("validate: a sparse DEM without nodata, its blocks on the polyline written", validate, 0, "",
             setup=_dem26(sparse="elsewhere")),
        Case("validate: a sparse DEM with a nodata value, its blocks on the polyline unwritten", validate, 2,
             "dem.tif: no elevation at", setup=_dem26(sparse="line", nodata=-9999.0)),
        Case("validate: a DEM holding 1e308 m at one pixel of the polyline", validate, 2,
             "dem.tif: an elevation of 1e+308 m at pixel (row 20, column 40) on the polyline",
             setup=_dem26(value=1e308)),
        Case("validate: a float32 DEM holding its undeclared fill value -3.4e38 on the polyline", validate, 2,
             "dem.tif: an elevation of -3.40282e+38 m at pixel (row 20, column 40)",
             setup=_dem26(value=-3.4028234663852886e38, dtype="float32")),
        Case("validate: a DEM 8849 m high (Everest)", validate, 0, "", setup=_dem26(offset=8749.0)),
        Case("validate: a DEM whose sidecar dem.tif.aux.xml sets a scale of 0.3048", validate, 2,
             "dem.tif.aux.xml changes its scales from (1.0,) to (0.3048,)",
             setup=_dem26(aux="<Scale>0.3048</Scale>")),
        Case("validate: a DEM whose sidecar dem.tif.aux.xml sets nodata to an elevation it holds",
             validate, 2,
             "dem.tif.aux.xml changes its nodata from None to 100.0",
             setup=_dem26(aux="<NoDataValue>100</NoDataValue>", value=100.0)),
        Case("validate: a DEM whose sidecar dem.tif.aux.xml holds statistics only", validate, 0, "",
             setup=_dem26(aux='<Metadata><MDI key="STATISTICS_MEAN">100.1</MDI></Metadata>')),
        Case("validate: a DEM whose mask sidecar dem.tif.msk masks the polyline", validate, 2,
             "dem.tif: no elevation at", setup=_dem26(mask=True)),
        Case("validate: a tiled, compressed DEM cut to half its bytes", validate, 2,
             "dem.tif: cannot read the DEM (dem.tif, band 1: IReadBlock failed at X offset 1, Y offset 0",
             setup=_dem26(cut=True)),
        Case("validate: that DEM cut short under GTIFF_IGNORE_READ_ERRORS=YES", validate, 2,
             "dem.tif: cannot read the DEM (dem.tif, band 1: IReadBlock failed at X offset 1, Y offset 0",
             setup=_dem26(cut=True), env={"GTIFF_IGNORE_READ_ERRORS": "YES"}),
        Case("run --resume: a run finished at 0.21 s extended to 0.3 s (output every 0.02 s)", extend, 0,
             "not an output time of k x 0.02 s: its record at 0.21 s stays", setup=_finished_at(0.21)),
        Case("run --resume: a run finished at 0.2 s extended to 0.3 s (output every 0.02 s)", extend, 0, "",
             setup=_finished_at(0.2)),
    ]  # fmt: skip
    return out


def _dem26(**kind: Any) -> Callable[[Path], None]:
    """The DEM of :func:`_dem` (80 x 40 pixels of 0.01 m, 100 m high, the polyline along row
    20), changed by ``kind``: ``sparse`` (tiles of 32 x 32 pixels, only the first written:
    ``line``, or every tile of the polyline: ``elsewhere``) with a ``nodata`` value, a
    ``value`` at pixel (20, 40) of a ``dtype``, an ``offset`` added, an ``aux`` sidecar of
    band 1 holding that XML, a ``mask`` sidecar masking row 20, or ``cut`` to half its
    bytes (tiled, deflated)."""

    def setup(directory: Path) -> None:
        import rasterio
        from rasterio.windows import Window

        _dem()(directory)
        path = directory / "dem.tif"
        with rasterio.open(path) as dem:
            z, profile = dem.read(1), dict(dem.profile)
        z = z + kind.get("offset", 0.0)
        if "value" in kind:
            z[20, 40] = kind["value"]
        profile.update(dtype=kind.get("dtype", "float64"), nodata=kind.get("nodata"))
        if "sparse" in kind or kind.get("cut"):
            profile.update(tiled=True, blockxsize=32, blockysize=32, sparse_ok=True, compress="deflate")
        with rasterio.Env(GDAL_TIFF_INTERNAL_MASK=False), rasterio.open(path, "w", **profile) as dem:
            if kind.get("sparse") == "line":
                dem.write(z[:32, :32].astype(profile["dtype"]), 1, window=Window(0, 0, 32, 32))
            elif kind.get("sparse") == "elsewhere":  # rows 0-31 of the polyline's tiles, not rows 32-39
                dem.write(z[:32].astype(profile["dtype"]), 1, window=Window(0, 0, 80, 32))
            else:
                dem.write(z.astype(profile["dtype"]), 1)
            if kind.get("mask"):
                dem.write_mask(np.where(np.arange(40)[:, None] == 20, 0, 255).repeat(80, 1).astype("uint8"))
        if "aux" in kind:
            (directory / "dem.tif.aux.xml").write_text(
                f'<PAMDataset><PAMRasterBand band="1">{kind["aux"]}</PAMRasterBand></PAMDataset>'
            )
        if kind.get("cut"):
            data = path.read_bytes()
            path.write_bytes(data[: len(data) // 2])

    return setup


def _finished_at(end: float) -> Callable[[Path], None]:
    """A completed run to ``time.end = end`` in ``directory/out`` (output every 0.02 s)."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        command = ["run", str(directory / "scenario.yaml"), "-o", str(directory / "out"), "-q"]
        subprocess.run(
            [sys.executable, "-m", "multilayer", *command, "--set", f"time.end={end}"],
            check=True,
            timeout=120,
        )

    return setup


def _base_reads_output(command: str, name: str | None, member: bool = False) -> Callable[[Path], None]:
    """A study into ``out`` whose base scenario reads the file ``out/name`` the study writes
    (a bed CSV file; an initial-thickness file for a calibration), or, with no ``name``, a
    bed file in the directory of the sweep's first member; with ``member``, the second
    member of a sweep of ``bed.file`` or an experiment of a calibration reads it."""

    def setup(directory: Path) -> None:
        from multilayer.app.sweep import load as load_sweep

        out = directory / "out"
        out.mkdir()
        parameters: dict[str, list[Any]] = {"slope_deg": [20.0, 25.0]}
        base: dict[str, Any] = dict(TINY)
        if command == "calibrate":
            written = out / str(name)
            written.write_text("x (m), h (m)\n0, 0.05\n0.1, 0.05\n0.1001, 0\n0.5, 0\n")
            mass = {"quantity": "mass_final", "value": 0.005, "sigma": 1e-4}
            if member:
                written.write_text("x (m), z (m)\n0, 0\n0.5, 0\n")
                (directory / "flat.csv").write_text("x (m), z (m)\n0, 0\n0.5, 0\n")
                base["bed"] = {"file": "flat.csv"}
                experiments = {"a": {}, "b": {"bed.file": f"out/{name}"}}
                mass = {**mass, "experiment": "a"}
                _calibration_of(mass, base, {"experiments": experiments})(directory)
                return
            base["initial"] = [{"shape": "profile", "file": f"out/{name}"}]
            _calibration_of(mass, base)(directory)
            return
        if command == "sweep" and name is None:
            (directory / "study.yaml").write_text(
                yaml.safe_dump({"base": "base.yaml", "parameters": parameters})
            )
            (directory / "base.yaml").write_text(yaml.safe_dump(TINY))
            first = load_sweep(directory / "study.yaml").members()[0].id
            (out / first).mkdir()
            written = out / first / "member.json"
        else:
            written = out / str(name)
        written.write_text("x (m), z (m)\n0, 0\n0.5, 0\n")
        base["bed"] = {"file": written.relative_to(directory).as_posix()}
        if member:
            (directory / "flat.csv").write_text("x (m), z (m)\n0, 0\n0.5, 0\n")
            parameters = {"bed.file": ["flat.csv", written.relative_to(directory).as_posix()]}
            base["bed"] = {"file": "flat.csv"}
        (directory / "base.yaml").write_text(yaml.safe_dump(base))
        if command == "sweep":
            config: dict[str, Any] = {"base": "base.yaml", "parameters": parameters}
        else:
            config = {
                "base": "base.yaml",
                "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
                "outputs": ["mass_final"],
                "samples": 16,
            }
        (directory / "study.yaml").write_text(yaml.safe_dump(config))

    return setup


def _run_and_study(directory: Path) -> None:
    _finished_run(directory)
    _sensitivity()(directory / "out")


def round_twenty_seven() -> list[Case]:
    """The hostile cases of the twenty-seventh round (docs/reliability.md): the Python API
    given a generator, an open file or numpy durations as scenario values; a study's ``set``
    or experiment giving a parameter's value through a key above it; an output directory
    under a user the system does not know or an empty ``HOME``; a fluid without a mixture;
    a layer fraction of 5e-324; as controls, numbers held in an object array, ``~/x`` under
    a known ``HOME``, a layer fraction of 1e-301 and a ``set`` of another key."""
    validate = ["validate", "{scenario}"]
    load = "import yaml\ndata = yaml.safe_load(open(sys.argv[2]))\n"
    mass = {"quantity": "mass_final", "value": 0.005, "sigma": 1e-3}
    rheology = {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01}
    duration = "is a numpy date or duration (or an array of them), not a number"
    home = "accepted: a directory path whose leading ~ is a home directory, or no ~"
    thin = {"domain.layer_fractions": [5e-324, 0.5, 0.5]}
    forced = ["run", "{scenario}", "-o", "{dir}/out", "-q", "--force"]
    out = [
        Case("API: multilayer.load of a mapping whose initial is a generator", validate, 2,
             "<scenario>: initial: <generator object", patch=_api(
                 load + "data['initial'] = (e for e in data['initial'])\nmultilayer.load(data)"),
             setup=_scenario),
        Case("API: multilayer.load of a mapping whose bed.file is an open file", validate, 2,
             f"<scenario>: bed.file: <_io.TextIOWrapper name='{os.devnull}'", patch=_api(
                 load + "data['bed'] = {'profile': 'file', 'file': open('/dev/null')}\n"
                 "multilayer.load(data)"), setup=_scenario),
        Case("API: domain.x_max = np.timedelta64(5) (a duration of no unit)", validate, 2,
             f"<scenario>: domain.x_max: np.timedelta64(5) {duration}", patch=_api(
                 load + "import numpy as np\ndata['domain']['x_max'] = np.timedelta64(5)\n"
                 "multilayer.load(data)"), setup=_scenario),
        Case("API: overrides {'time.end': np.timedelta64(1)}", validate, 2,
             f"overrides: time.end: np.timedelta64(1) {duration}", patch=_api(
                 "import numpy as np\nmultilayer.load(sys.argv[2], {'time.end': np.timedelta64(1)})"),
             setup=_scenario),
        Case("API: bed.points an array of numpy durations", validate, 2, "<scenario>: bed.points: array(",
             patch=_api(load + "import numpy as np\n"
                        "data['bed'] = {'points': np.array([[0, 0], [5, 0]], dtype='m8')}\n"
                        "multilayer.load(data)"), setup=_scenario),
        Case("API: bed.points an object array of numbers", validate, 0, "", patch=_api(
            load + "import numpy as np\n"
            "data['bed'] = {'points': np.array([[0.0, 0.0], [0.5, -0.1]], dtype=object)}\n"
            "multilayer.load(data)"), setup=_scenario),
        Case("validate: a calibration whose set gives rheology holding the parameter rheology.mu_s",
             ["validate", "{dir}/calibration.yaml"], 2,
             "parameters.rheology.mu_s (line 8): also given a value in set.rheology, which",
             setup=_calibration_of(mass, extra={"set": {"rheology": rheology}})),
        Case("validate: a calibration whose experiment gives rheology holding rheology.mu_s",
             ["validate", "{dir}/calibration.yaml"], 2,
             "also given a value in experiments.a.rheology, which",
             setup=_calibration_of({**mass, "experiment": "a"},
                                   extra={"experiments": {"a": {"rheology": rheology}, "b": {}}})),
        Case("validate: a calibration of initial.0.height whose set gives initial",
             ["validate", "{dir}/calibration.yaml"], 2, "also given a value in set.initial, which",
             setup=_calibration_of(mass, extra={
                 "set": {"initial": TINY["initial"]},
                 "parameters": {"initial.0.height": {"bounds": [0.04, 0.06]}}})),
        Case("validate: a calibration of rheology.mu_s whose set gives initial",
             ["validate", "{dir}/calibration.yaml"], 0, "",
             setup=_calibration_of(mass, extra={"set": {"initial": TINY["initial"]}})),
        Case("validate: output.directory ~nosuchuser/x", validate, 2,
             f"output.directory (line 19): '~nosuchuser/x': no user 'nosuchuser' on this system; {home}",
             setup=partial(_scenario, changes={"output": {"directory": "~nosuchuser/x"}})),
        Case("validate: a sweep into ~nosuchuser/x", ["validate", "{dir}/sweep.yaml"], 2,
             f"output.directory (line 3): '~nosuchuser/x': no user 'nosuchuser' on this system; {home}",
             setup=_sweep_into("~nosuchuser/x")),
        Case("run: output.directory ~/x under HOME=''", ["run", "{scenario}", "-q"], 2,
             f"'~/x': HOME is '', not an absolute path; {home}",
             setup=partial(_scenario, changes={"output": {"directory": "~/x"}}), env={"HOME": ""}),
        Case("sweep: into ~/x under HOME=''", ["sweep", "{dir}/sweep.yaml", "-q"], 2,
             f"'~/x': HOME is '', not an absolute path; {home}", setup=_sweep_into("~/x"), env={"HOME": ""}),
        Case("validate: output.directory ~/x under HOME of the case's directory", validate, 0, "",
             setup=partial(_scenario, changes={"output": {"directory": "~/x"}}), env={"HOME": "{dir}"}),
        Case("validate: fluid without mixture", validate, 2,
             "fluid (line 9): fluid is given without mixture; accepted: both fluid and mixture",
             setup=partial(_scenario, changes={"fluid": MIXTURE["fluid"]})),
        Case("validate: a layer fraction of 5e-324", validate, 2,
             "domain.layer_fractions (line 6): a layer fraction of 4.94e-324: in a column at "
             "numerics.dry_threshold = 1e-06 m, the thinnest wet one, that layer is 0 m thick",
             setup=partial(_scenario, changes=thin)),
        Case("run: a layer fraction of 5e-324", ["run", "{scenario}", "-o", "{dir}/out", "-q"], 2,
             "accepted: layer fractions >= 2.23e-308 m / numerics.dry_threshold = 2.23e-302",
             setup=partial(_scenario, changes=thin)),
        Case("run: a layer fraction of 1e-301", ["run", "{scenario}", "-o", "{dir}/out", "-q"], 0, "",
             setup=partial(_scenario, changes={"domain.layer_fractions": [1e-301, 0.5, 0.5]})),
        Case("validate: a plugin whose constructor has a parameter 'name'", validate, 2,
             "Labelled.__init__ has a parameter 'name', a key a scenario cannot give it: in `rheology:` and "
             "`walls:` `name` chooses the law", setup=_labelled("name"), env={"PYTHONPATH": "{dir}/plugin"}),
        Case("validate: a plugin whose constructor has a parameter 'label'", validate, 0, "",
             setup=_labelled("label"), env={"PYTHONPATH": "{dir}/plugin"}),
        Case("validate: an inflow 1e308 m thick", validate, 2,
             "boundaries.inflow (line 2): an inflow 1e+308 m thick at 1 m/s: its wave speed",
             setup=partial(_scenario, changes={"boundaries": _inflow(1e308, 1.0)})),
        Case("run --force: an inflow 1e308 m thick", forced, 2,
             "boundaries.inflow (line 2): an inflow 1e+308 m thick at 1 m/s: its wave speed",
             setup=partial(_scenario, changes={"boundaries": _inflow(1e308, 1.0)})),
        Case("run --force: an inflow 0.01 m thick at 1e308 m/s", forced, 2,
             "h u^2 + g cos(slope_deg) h^2 / 2 = inf m3/s2",
             setup=partial(_scenario, changes={"boundaries": _inflow(0.01, 1e308)})),
        Case("run: an inflow 0.01 m thick at 1 m/s", ["run", "{scenario}", "-o", "{dir}/out", "-q"], 0, "",
             setup=partial(_scenario, changes={"boundaries": _inflow(0.01, 1.0)})),
    ]  # fmt: skip
    return out


def _redirected(redirection: str) -> list[str]:
    """A prefix running the child with its descriptors redirected by ``redirection`` (sh)."""
    return ["sh", "-c", f'exec "$@" {redirection}', "sh"]


def round_twenty_eight() -> list[Case]:
    """The hostile cases of the twenty-eighth round (docs/reliability.md): a standard output
    on a full device or closed, a standard error on a full device; as controls, the null
    device and a closed stdout a command writes nothing to."""
    stdout = "cannot write to the standard output ("
    full, closed = _redirected(">/dev/full"), _redirected(">&-")
    run = ["run", "{scenario}", "-o", "{dir}/out"]
    bad = partial(_scenario, changes={"domain.cells": -1})
    out = [
        Case("run > /dev/full", run, 2, f"{stdout}No space left on device); accepted: a standard output",
             setup=_scenario, prefix=full),
        Case("plugins > /dev/full", ["plugins"], 2, f"{stdout}No space left on device)", prefix=full),
        Case("validate > /dev/full", ["validate", "{scenario}"], 2, f"{stdout}No space left on device)",
             setup=_scenario, prefix=full),
        Case("--version > /dev/full", ["--version"], 2, f"{stdout}No space left on device)", prefix=full),
        Case("--help > /dev/full", ["--help"], 2, f"{stdout}No space left on device)", prefix=full),
        Case("plugins >&- (stdout closed)", ["plugins"], 2, f"{stdout}it is closed)", prefix=closed),
        Case("validate of an invalid scenario 2>/dev/full", ["validate", "{scenario}"], 2, "",
             setup=bad, prefix=_redirected("2>/dev/full")),
        Case("run of an invalid scenario 2>/dev/full", run, 2, "", setup=bad,
             prefix=_redirected("2>/dev/full")),
        Case("run > /dev/null", run, 0, "", setup=_scenario, prefix=_redirected(">/dev/null")),
        Case("run -q >&- (stdout closed, nothing written)", [*run, "-q"], 0, "", setup=_scenario,
             prefix=closed),
        Case("sweep > /dev/full", ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/sweep-out", "--workers", "1"], 2,
             f"{stdout}No space left on device)", setup=_sweep({"slope_deg": [20.0]}), prefix=full),
        Case("sweep 2>&- (stderr closed, progress not quiet)",
             ["sweep", "{dir}/sweep.yaml", "-o", "{dir}/sweep-out", "--workers", "1"], 0, "",
             setup=_sweep({"slope_deg": [20.0]}), prefix=_redirected("2>&-")),
        Case("calibrate 2>&- (stderr closed, progress not quiet)",
             ["calibrate", "{dir}/calibration.yaml", "-o", "{dir}/cal", "--workers", "1"], 0, "",
             setup=_calibration("0.1,0.1,0.05\n0.2,0.15,0.05\n", generations=0),
             prefix=_redirected("2>&-")),
    ]  # fmt: skip
    return out


def _inflow(thickness: float, speed: float) -> dict:
    """The boundaries of TINY with a plug inflow on the left."""
    velocity = {"profile": "plug", "speed": speed}
    return {"left": "inflow", "right": "outflow", "inflow": {"thickness": thickness, "velocity": velocity}}


LABELLED_PLUGIN = """
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager


class Labelled(DruckerPrager):
    name = "labelled"

    def __init__(self, mu_s: float, nu: float, {parameter}: str = "x"):
        super().__init__(mu_s, nu)


@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(Labelled)
"""
"""A third-party law with a parameter of a name given by the case (``name``: one no scenario
can set)."""


def _labelled(parameter: str) -> Callable[[Path], None]:
    """TINY on the law of :data:`LABELLED_PLUGIN` whose third parameter is ``parameter``."""

    def setup(directory: Path) -> None:
        _entry_point_plugin(LABELLED_PLUGIN.replace("{parameter}", parameter))(directory)
        _scenario(directory, {"rheology": {"name": "labelled", "mu_s": 0.3, "nu": 0.01}})

    return setup


PYTEST = "import pytest\nsys.exit(int(pytest.main(['-q', '-p', 'no:cacheprovider', sys.argv[1]])))"
"""A patch running pytest (and so multilayer's pytest plugin) on the case's first argument."""


def _scenarios_beside(**files: str) -> Callable[[Path], None]:
    """``directory/tests`` holding TINY with an ``expect`` entry and the YAML ``files`` (name:
    text): data files a user's tests keep beside the scenarios pytest collects."""

    def setup(directory: Path) -> None:
        tests = directory / "tests"
        tests.mkdir()
        expect = [{"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.5}]
        (tests / "tiny.yaml").write_text(yaml.safe_dump({**TINY, "expect": expect}))
        for name, text in files.items():
            (tests / name).write_text(text)

    return setup


def _hidden(head: str, sweep: bool = False) -> Callable[[Path], None]:
    """TINY without its slope (and without its name when ``head`` gives one) after the text
    ``head``, or a sweep file of TINY beginning with it (``sweep``)."""

    def setup(directory: Path) -> None:
        if sweep:
            _sweep({"slope_deg": [20.0]})(directory)
            path = directory / "sweep.yaml"
            path.write_text(head + path.read_text())
            return
        data = {k: v for k, v in TINY.items() if k != "slope_deg" and not (k == "name" and "name:" in head)}
        _scenario(directory, text=head + yaml.safe_dump(data, sort_keys=False))

    return setup


def round_twenty_nine() -> list[Case]:
    """The hostile cases of the twenty-ninth round (docs/reliability.md): a law's or base
    zone's parameter assigned NaN or an infinity through the Python API after loading; a
    plot window Matplotlib would widen; a result file given as the directory of ``plot``
    and ``export``; data files beside the scenarios pytest collects (5000 lists deep, 2 x
    10^6 values); a key, a rheology's name, a home directory, a ``--set`` key path, a
    ``--max-memory`` and an observation's units of 10^5 characters (the message quoted them
    whole); a scenario whose slope follows U+0085 in a
    comment or U+2028 in a description, a sweep file holding U+2029; numbers of 10^5 and 10^6
    digits ended by a letter in a bed CSV, an observation file and ``--at`` (a match
    quadratic in the digits, hours); as controls, a window of 2.2e-6 of the
    domain, pytest of the scenarios alone and U+2028 written as an escape."""
    validate = ["validate", "{scenario}"]
    load = "sc = multilayer.load(sys.argv[2])\n"
    narrow = "at least 1e-06 times as wide (Matplotlib widens a narrower window)"
    a_file = "/out/result.nc: a file, not a directory; accepted: the output directory of `multilayer run`"
    long = "k" * 100_000
    yaml_1_1 = "where YAML 1.1 (multilayer's parser) ends a line and an editor does not"
    run = ["run", "{scenario}", "-o", "{dir}/out"]
    out = [
        Case("API: rheology.mu_start = nan assigned after loading", validate, 2,
             "rheology.mu_start: drucker_prager: Input should be a finite number (got nan)",
             patch=_api(load + "sc.rheology.params['mu_start'] = float('nan')\nmultilayer.Simulation(sc)"),
             setup=_scenario),
        Case("API: rheology.mu_s = -inf assigned after loading", validate, 2,
             "rheology.mu_s: drucker_prager: Input should be a finite number (got -inf)",
             patch=_api(load + "sc.rheology.params['mu_s'] = float('-inf')\nmultilayer.Simulation(sc)"),
             setup=_scenario),
        Case("API: a Coulomb base zone's mu = nan assigned after loading, multilayer.run", validate, 2,
             "base.0.mu: got nan; accepted: a friction coefficient >= 0", patch=_api(
                 load + "sc.base[0].model_extra['mu'] = float('nan')\nmultilayer.run(sc)"),
             setup=partial(_scenario, changes={"base": [{"condition": "coulomb", "mu": 0.3}]})),
        Case("plot --xlim -1e-320 1e-320", ["plot", "{dir}/out", "--xlim", "-1e-320", "1e-320"], 2,
             "--xlim -1e-320 1e-320: accepted: X0 < X1 (m), overlapping the domain [0, 0.5], at most 1000 "
             f"and {narrow}", setup=_finished_run),
        Case("plot --xlim 0.2 0.2000000000000001",
             ["plot", "{dir}/out", "--xlim", "0.2", "0.2000000000000001"], 2, narrow, setup=_finished_run),
        Case("plot --xlim 0.2 0.2000011 (2.2e-6 of the domain)",
             ["plot", "{dir}/out", "--xlim", "0.2", "0.2000011"], 0, "", setup=_finished_run),
        Case("plot DIR/result.nc", ["plot", "{dir}/out/result.nc"], 2, a_file, setup=_finished_run),
        Case("export DIR/result.nc --vtk", ["export", "{dir}/out/result.nc", "--vtk"], 2, a_file,
             setup=_finished_run),
        Case("pytest DIR: a scenario beside a YAML file 5000 lists deep", ["{dir}/tests"], 0, "",
             patch=PYTEST, setup=_scenarios_beside(**{"deep.yaml": "[" * 5000 + "]" * 5000})),
        Case("pytest DIR: a scenario beside a YAML file of 2 x 10^6 values", ["{dir}/tests"], 0, "",
             patch=PYTEST, setup=_scenarios_beside(**{"values.yaml": f"[{', '.join(['1'] * 2_000_001)}]"})),
        Case("pytest DIR: a scenario alone", ["{dir}/tests"], 0, "", patch=PYTEST, setup=_scenarios_beside()),
        Case("validate: a key of 10^5 characters (? key)", validate, 2,
             f"{long[:57]}... (line 14): unknown key", setup=partial(_scenario, changes={long: 1})),
        Case("validate: a rheology named by 10^5 characters", validate, 2,
             f"rheology.name (line 20): unknown rheology '{long[:56]}...; accepted: dilatant_coulomb",
             setup=partial(_scenario, changes={"rheology.name": long})),
        Case("validate: output.directory ~ and 10^5 characters", validate, 2,
             f"'~{long[:55]}...: no user '{long[:56]}... on this system",
             setup=partial(_scenario, changes={"output": {"directory": f"~{long}"}})),
        Case("validate --set of a key path of 10^5 characters", [*validate, "--set", f"domain.{long}=1"], 2,
             f"domain.{long[:57]}... (from --set): unknown key", setup=_scenario),
        Case("validate --max-memory of 10^5 characters", [*validate, "--max-memory", f"{long}x"], 2,
             f"argument --max-memory: not a size: '{long[:56]}...; accepted", setup=_scenario),
        Case("validate: an observation's units of 10^5 characters", ["validate", "{dir}/calibration.yaml"], 2,
             f"observations.0.units (line 6): unknown unit '{long[:56]}...; accepted: m, cm",
             setup=_calibration_of({"quantity": "mass_final", "value": 0.005, "sigma": 1e-3, "units": long})),
        Case("validate: slope_deg after U+0085 in a comment", validate, 2,
             f"(line 1, column 23): the character U+0085 (NEXT LINE), {yaml_1_1}",
             setup=_hidden("name: tiny  # slope 25\x85slope_deg: 40\n")),
        Case("run: slope_deg after U+2028 in a description", [*run, "-q"], 2,
             f"(line 1, column 33): the character U+2028 (LINE SEPARATOR), {yaml_1_1}",
             setup=_hidden("description: chute at 25 degrees\u2028slope_deg: 40\n")),
        Case("validate: a sweep whose comment holds U+2029", ["validate", "{dir}/sweep.yaml"], 2,
             "sweep.yaml (line 1, column 8): the character U+2029 (PARAGRAPH SEPARATOR)",
             setup=_hidden("# sweep\u2029\n", sweep=True)),
        Case("validate: U+2028 written as an escape in a double-quoted description", validate, 0, "",
             setup=_hidden('description: "chute\\Lat 25 degrees\\u2028"\n')),
        Case("validate: a bed CSV row of 10^6 digits and an x", validate, 2,
             f"bed.csv: line 3: expected two numbers separated by a comma, got '0.5, {'9' * 51}...",
             setup=_csv_bed(f"x (m), z (m)\n0, 0\n0.5, {'9' * 10**6}x\n")),
        Case("plot --at of 10^5 digits and an x", ["plot", "{dir}/out", "--at", f"{'9' * 10**5}x"], 2,
             f"argument --at: expected a number in ASCII decimal notation (0.25, -1e-3), got '{'9' * 56}...",
             setup=_finished_run),
        Case("validate: an observation of 10^6 digits and an x (beyond the csv module's field limit)",
             ["validate", "{dir}/calibration.yaml"], 2,
             "front.csv: line 2: field larger than field limit (131072); accepted: a CSV file of numbers",
             setup=_calibration(f"0.1,{'9' * 10**6}x,0.05\n")),
        Case("validate: an observation of 10^5 digits and an x", ["validate", "{dir}/calibration.yaml"], 2,
             f"front.csv (could not convert '{'9' * 56}... to a number); accepted: a CSV file of numbers",
             setup=_calibration(f"0.1,{'9' * 10**5}x,0.05\n")),
    ]  # fmt: skip
    return out


USING_PLUGIN = """
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager


class Porous(DruckerPrager):
    name = "porous"
    uses = {uses}

    def yield_stress(self, pressure, material, porosity=0.4, thickness=None):
        return super().yield_stress(pressure, material)


@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(Porous)
"""
"""A third-party law declaring the column quantities ``uses`` given by the case, with a
default for a quantity the engine never gives."""


def _using(uses: str) -> Callable[[Path], None]:
    """TINY on the law of :data:`USING_PLUGIN` declaring ``uses``."""

    def setup(directory: Path) -> None:
        _entry_point_plugin(USING_PLUGIN.replace("{uses}", uses))(directory)
        _scenario(directory, {"rheology": {"name": "porous", "mu_s": 0.3, "nu": 0.01}})

    return setup


def _unlisted_run(directory: Path) -> None:
    """A finished run whose directory this user can neither list nor enter (``r--``)."""
    _finished_run(directory)
    (directory / "out").chmod(0o444)


def _loop(directory: Path) -> None:
    """``scenario.yaml`` a symbolic link to ``other.yaml``, a link back to it."""
    (directory / "scenario.yaml").symlink_to("other.yaml")
    (directory / "other.yaml").symlink_to("scenario.yaml")


GONE = ["sh", "-c", 'mkdir gone && cd gone && rmdir ../gone && exec "$@"', "sh"]
"""A prefix running the child in a working directory removed after it was entered."""


def round_thirty() -> list[Case]:
    """The hostile cases of the thirtieth round (docs/reliability.md): numpy values of the
    Python API a cast or ``tolist()`` changes (a 0-d object array, masked values, long
    doubles beyond the floats in ``load_state`` and in a plugin's values and compiled form);
    a scenario's ``initial`` and ``bed`` assigned values of another type after loading;
    a third-party law declaring a column quantity the engine never gives; a removed
    working directory; a umask taking the owner's permissions; ``plot`` and ``export`` of a
    directory this user cannot enter; as controls, an absolute output directory and
    ``plugins`` in a removed working directory, a plugin's float16 and ``np.matrix``
    values, a scenario that is a loop of symbolic links, a merge key of a scalar, stdout
    through ``head -c 10``, stdin closed and an unwritable ``NUMBA_CACHE_DIR``; a None
    assigned to ``gravity`` and ``bed`` after loading, observations of sigma 1e300 m, and
    a result ``failed`` without its ``failure``, with a number for it, or of 2^62 steps."""
    validate = ["validate", "{scenario}"]
    run = ["run", "{scenario}", "-o", "{dir}/out"]
    load = "import numpy as np\nyaml = __import__('yaml')\ndata = yaml.safe_load(open(sys.argv[2]))\n"
    loaded = "sc = multilayer.load(sys.argv[2])\n"
    state = (
        "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
        "saved = sim.state_dict()\n"
    )
    masked = "a masked array of 1 masked value(s) (a netCDF file's fill values, or np.ma.masked)"
    huge = "np.longdouble('1e400')"
    gone = "the working directory no longer exists (removed after this shell entered it)"
    unlisted = "out: a directory this user cannot list or enter (permissions dr--r--r--)"
    uses = "Porous.uses must be a tuple of the column quantities the engine gives a law (thickness), got"
    plugin_env = {"PYTHONPATH": "{dir}/plugin"}
    out = [
        Case("API: multilayer.load of a mapping whose slope_deg is a 0-d object array", validate, 0, "",
             patch=_api(load + "data['slope_deg'] = np.array(25.0, dtype=object)\nmultilayer.load(data)"),
             setup=_scenario),
        Case("API: multilayer.load of a mapping whose slope_deg is np.ma.masked", validate, 2,
             f"slope_deg: {masked}", setup=_scenario,
             patch=_api(load + "data['slope_deg'] = np.ma.masked\nmultilayer.load(data)")),
        Case("API: overrides {'rheology.mu_s': np.ma.masked}", validate, 2, f"rheology.mu_s: {masked}",
             patch=_api(load + "multilayer.load(sys.argv[2], {'rheology.mu_s': np.ma.masked})"),
             setup=_scenario),
        Case("API: bed.points a masked array, one value masked", validate, 2, f"bed.points: {masked}",
             patch=_api(load + "data['bed'] = {'points': np.ma.array([[0, 0], [0.5, 0.1]], "
                        "mask=[[0, 0], [0, 1]])}\nmultilayer.load(data)"),
             setup=_scenario),
        Case("API: scenario.initial.append(None) after loading, multilayer.Simulation", validate, 2,
             "initial.1: expected a mapping (got None)", setup=_scenario,
             patch=_api(loaded + "sc.initial.append(None)\nmultilayer.Simulation(sc)")),
        Case("API: scenario.bed = 5 after loading, multilayer.run", validate, 2,
             "bed: expected a mapping (got 5)", patch=_api(loaded + "sc.bed = 5\nmultilayer.run(sc)"),
             setup=_scenario),
        Case("API: scenario.bed = {'points': ...} (a mapping) after loading", validate, 0, "",
             setup=_scenario, patch=_api(loaded + "sc.bed = {'points': [[0, 0], [0.5, -0.1]]}\n"
                                         "assert abs(multilayer.Simulation(sc).bed[0] + 0.00125) < 1e-12")),
        Case(f"API: load_state of t = {huge}", validate, 2,
             "t holds values that are not finite as float64 (what the simulation holds)",
             patch=_api(state + f"saved['t'] = {huge}\nsim.load_state(saved)"), setup=_scenario),
        Case(f"API: load_state of h times {huge}", validate, 2,
             "h holds values that are not finite as float64 (what the simulation holds)",
             patch=_api(state + f"saved['h'] = saved['h'].astype(np.longdouble) * {huge}\n"
                        "sim.load_state(saved)"), setup=_scenario),
        Case(f"plugin: a yield stress of long doubles times {huge}", run, 1,
             "yield_stress() returned inf (must be finite)",
             patch=_plugin_patch("yield_stress", f"return (p * 0.3).astype(np.longdouble) * {huge}"),
             setup=_scenario, keeps_output=True),
        Case(f"plugin: a compiled viscosity form whose parameter is {huge}", run, 1,
             "viscosity() returned inf (must be finite)",
             patch=f"DruckerPrager.viscosity_kernel = lambda self, m: ('constant', np.array([{huge}]))\n",
             setup=_scenario, keeps_output=True),
        Case("plugin: a third-party law declaring uses = ('porosity',)", validate, 2,
             f"{uses} ('porosity',): a quantity it never gives would leave the law on its own default",
             setup=_using("('porosity',)"), env=plugin_env),
        Case("plugin: a third-party law declaring uses = 'thickness' (a string)", validate, 2,
             f"{uses} 'thickness'", setup=_using("'thickness'"), env=plugin_env),
        Case("validate in a removed working directory", validate, 2, gone, setup=_scenario, prefix=GONE,
             here=True),
        Case("run into results/<name> in a removed working directory", ["run", "{scenario}", "-q"], 2,
             f"results/tiny: {gone}", setup=_scenario, prefix=GONE, here=True),
        Case("run -o ABSOLUTE in a removed working directory", [*run, "-q"], 0, "", setup=_scenario,
             prefix=GONE, here=True),
        Case("plugins in a removed working directory", ["plugins"], 0, "", prefix=GONE, here=True),
        Case("as a user: run under umask 0177", [*run, "-q"], 2,
             "out: cannot be created or written (Permission denied): the umask 0177 leaves the directories "
             "made here without permissions their owner needs (drw-------)",
             setup=_scenario, prefix=[*NOT_ROOT, "sh", "-c", 'umask 0177 && exec "$@"', "sh"]),
        Case("as a user: plot of a directory this user cannot enter", ["plot", "{dir}/out"], 2, unlisted,
             setup=_unlisted_run, prefix=NOT_ROOT),
        Case("as a user: export --vtk of a directory this user cannot enter",
             ["export", "{dir}/out", "--vtk"], 2, unlisted, setup=_unlisted_run, prefix=NOT_ROOT),
        Case("plugin: a yield stress of float16", [*run, "-q"], 0, "",
             patch=_plugin_patch("yield_stress", "return (p * 0.3).astype(np.float16)"), setup=_scenario),
        Case("plugin: a viscosity as np.matrix", [*run, "-q"], 0, "",
             patch=_plugin_patch("viscosity", "return np.asmatrix(np.full(np.shape(p), 0.01))"),
             setup=_scenario),
        Case("validate: a scenario that is a loop of symbolic links", validate, 2,
             "is a symbolic link to nothing or in a loop", setup=_loop),
        Case("validate: a merge key of a scalar", validate, 2,
             "malformed YAML: expected a mapping or list of mappings for merging, but found scalar",
             setup=partial(_scenario, text=yaml.safe_dump(TINY) + "extra: &a 3\nnumerics: {<<: *a}\n")),
        Case("plugins | head -c 10", ["plugins"], 0, "", prefix=["sh", "-c", '"$@" | head -c 10', "sh"]),
        Case("run with stdin closed", [*run, "-q"], 0, "", setup=_scenario, prefix=_redirected("<&-")),
        Case("run under NUMBA_CACHE_DIR=/proc/x (unwritable)", [*run, "-q"], 0, "", setup=_scenario,
             env={"NUMBA_CACHE_DIR": "/proc/x"}),
        Case("API: scenario.gravity = None after loading, multilayer.Simulation", validate, 2,
             "gravity: Input should be a valid number (got None)", setup=_scenario,
             patch=_api(loaded + "sc.gravity = None\nmultilayer.Simulation(sc)")),
        Case("API: scenario.bed = None after loading, multilayer.run", validate, 2,
             "bed: expected a mapping (got None)", setup=_scenario,
             patch=_api(loaded + "sc.bed = None\nmultilayer.run(sc)")),
        Case("calibrate: uncertainties of 1e300 m (the misfit underflows to 0 everywhere)",
             ["calibrate", "{dir}/calibration.yaml", "-o", "{dir}/cal", "--workers", "1", "-q"], 2,
             "though their predictions differ: the squares of (model - observed) / sigma underflow",
             setup=_calibration("0.1,0.12,1e300\n0.2,0.15,1e300\n")),
        Case("plot: result.nc of run_status failed without its failure", ["plot", "{dir}/out"], 2,
             "run_status is 'failed' and its attribute failure (why) is missing",
             setup=_result_attribute(None, "run_status", "failed")),
        Case("plot: result.nc of run_status failed whose failure is 3.5", ["plot", "{dir}/out"], 2,
             "its attribute failure is 3.5, not text of 1 to 8000 characters",
             setup=_failed_because(3.5)),
        Case("plot: result.nc whose steps are 2^62", ["plot", "{dir}/out"], 2,
             "its attribute steps is 4.611686018427388e+18, not an integer from 0 to 2^53",
             setup=_result_attribute(None, "steps", np.float64(2.0**62))),
    ]  # fmt: skip
    return out


QUIET_STDOUT = [
    "sh", "-c",
    'out=$("$@" 2>&-); code=$?; '
    '[ -z "$out" ] || { printf "on stdout: %s\\n" "$out" >&2; exit 99; }; exit $code',
    "sh",
]  # fmt: skip
"""A prefix running the child with stderr closed (``2>&-``) that fails it (exit 99, the
text on the battery's stderr) when anything is written on its stdout."""

HOST_WITHOUT_STDERR = """
import contextlib, io
sys.stderr, written = None, io.StringIO()
with contextlib.redirect_stdout(written):
    multilayer.run(sys.argv[2], overrides={'numerics.front_threshold': 1.0}, quiet=False)
sys.stderr = sys.__stderr__
if written.getvalue():
    print('on the host stdout: ' + written.getvalue(), file=sys.stderr)
    sys.exit(99)
"""
"""A host process without stderr (pythonw) running a scenario that warns: its stdout,
the host's own, must hold nothing of multilayer's."""

FORKED = """
import multiprocessing
multilayer.run(sys.argv[2])
child = multiprocessing.get_context('fork').Process(target=lambda: multilayer.run(sys.argv[2]))
child.start()
child.join(100)
if child.exitcode != 0:
    print(f'the forked run exited {child.exitcode}', file=sys.stderr)
    sys.exit(3)
"""
"""``multilayer.run`` in a child forked after the parent ran (its kernels compiled)."""


def round_thirty_one() -> list[Case]:
    """The hostile cases of the thirty-first round (docs/reliability.md): values of another
    type assigned to a scenario after loading (booleans where numbers are, which pydantic
    wrote as 1; floats equal to the validated integer; numpy numbers and arrays, long
    doubles, integers past the floats, a law without parameters); keys of a law's
    parameters and of a calibration's ``set`` that YAML reads as no text; messages of the
    commands and of the library where stderr is closed or absent; a failed expectation
    whose values print alike, an observation time past ``time.end`` by 1e-10 s (its
    message); as controls, numpy numbers assigned, one layer, two cells, a
    slope of 89.9 degrees, an output interval beyond the end, an end one rounding past an
    output time, a scenario of CRLF lines after a byte order mark, a calibration of one
    observation and a run in a forked child."""
    validate = ["validate", "{scenario}"]
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    loaded = "sc = multilayer.load(sys.argv[2])\n"
    number, integer = "Input should be a valid number", "Input should be a valid integer"
    assigned = "assigned since the scenario was validated, a value the scenario cannot hold"
    not_text = "is not text; accepted: name and the parameters of the law, as text"
    bom_crlf = "\ufeff" + yaml.safe_dump(TINY).replace("\n", "\r\n")
    api = [  # (assignment, built by, phrase)
        ("sc.slope_deg = True", "Simulation", f"slope_deg: {number} (got True)"),
        ("sc.time.end = True", "run", f"time.end: {number} (got True)"),
        ("sc.domain.cells = True", "Simulation", f"domain.cells: {integer} (got True)"),
        ("sc.initial[0].height = True", "run", f"initial.0.height: {number} (got True)"),
        ("sc.material.density = np.True_", "Simulation", f"material.density: {number} (got True)"),
        (
            "sc.rheology.params['nu'] = np.True_",
            "Simulation",
            f"rheology.nu: drucker_prager: {number} (got True)",
        ),
        ("sc.domain.cells = 40.0", "Simulation", f"domain.cells: {integer} (got 40.0)"),
        ("sc.domain.x_max = np.array([0.75])", "Simulation", f"domain.x_max: {number} (got [0.75])"),
        (
            "sc.domain.x_max = np.longdouble('1e400')",
            "run",
            f"domain.x_max: {number} (got \"np.longdouble('1e+400')\")",
        ),
        ("sc.domain.x_max = 10**400", "Simulation", f"domain.x_max: {assigned} (OverflowError"),
        ("sc.rheology.params = None", "run", f"rheology.params: {assigned}"),
    ]
    out = [
        Case(f"API: {assign} after loading, multilayer.{call}", validate, 2, phrase, setup=_scenario,
             patch=_api(loaded + f"import numpy as np\n{assign}\nmultilayer.{call}(sc)"))
        for assign, call, phrase in api
    ] + [
        Case("API: np.float32 slope_deg and np.int32 cells after loading (their values)", validate, 0, "",
             setup=_scenario,
             patch=_api(loaded + "import numpy as np\n"
                        "sc.slope_deg, sc.domain.cells = np.float32(20), np.int32(41)\n"
                        "s = multilayer.Simulation(sc).scenario\n"
                        "assert (s.slope_deg, s.domain.cells) == (20.0, 41) and type(s.slope_deg) is float")),
        Case("API: slope_deg = 25 (an integer, the same value) after loading", validate, 0, "",
             setup=_scenario,
             patch=_api(loaded + "sc.slope_deg = 25\n"
                        "assert multilayer.Simulation(sc).scenario.slope_deg == 25.0")),
        Case("validate: a law's parameter key true", validate, 2, f"rheology (line 18): key True {not_text}",
             setup=partial(_scenario, changes={"rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01,
                                                          True: 2}})),
        Case("run: --set rheology={..., null: 2}",
             [*run, "--set", "rheology={{name: drucker_prager, mu_s: 0.3, nu: 0.01, null: 2}}"], 2,
             f"rheology (from --set): key None {not_text}", setup=_scenario),
        Case("validate: a calibration whose set has a key null", ["validate", "{dir}/calibration.yaml"], 2,
             "set (line 18): key None is not text; accepted: keys that are text",
             setup=_calibration_of({"quantity": "front", "file": "front.csv", "columns": ["t", "x_f",
                                   "sigma"]}, extra={"set": {None: 3}})),
        Case("validate of an invalid scenario 2>&- (nothing on stdout)", validate, 2, "",
             setup=partial(_scenario, changes={"domain.cells": -1}), prefix=QUIET_STDOUT),
        Case("run -q of a scenario that warns, 2>&- (nothing on stdout)", run, 0, "",
             setup=partial(_scenario, changes={"numerics": {"front_threshold": 1.0}}), prefix=QUIET_STDOUT),
        Case("API: multilayer.run(quiet=False) warning in a host without stderr", validate, 0, "",
             setup=_scenario, patch=_api(HOST_WITHOUT_STDERR)),
        Case("check: mass_final pinned at 0.005 with rtol 0 (values alike at 6 digits)",
             ["check", "{scenario}", "-o", "{dir}/checked"], 1, "0.005000000000000001          0  FAILED",
             setup=partial(_scenario, changes={"expect": [
                 {"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.0}]}),
             prefix=_redirected("1>&2")),
        Case("run: one layer", run, 0, "", setup=partial(_scenario, changes={"domain.layers": 1})),
        Case("run: two cells", run, 0, "",
             setup=partial(_scenario, changes={"domain.cells": 2, "initial.0.x_max": 0.25})),
        Case("run: a slope of 89.9 degrees", run, 0, "",
             setup=partial(_scenario, changes={"slope_deg": 89.9})),
        Case("run: an output interval longer than time.end", run, 0, "",
             setup=partial(_scenario, changes={"time.output_interval": 5.0})),
        Case("run: time.end 0.30000000000000004, 3 output intervals of 0.1 s", run, 0, "",
             setup=partial(_scenario, changes={"time": {"end": 0.1 * 3, "output_interval": 0.1}})),
        Case("run: a scenario of CRLF lines after a UTF-8 byte order mark", run, 0, "",
             setup=partial(_scenario, text=bom_crlf)),
        Case("validate: a calibration observed 1e-10 s after time.end",
             ["validate", "{dir}/calibration.yaml"], 2,
             "t = 0.2000000001 to 0.2000000001 s, outside the runs, which end at time.end = 0.2 s",
             setup=_calibration("0.2000000001,0.12,0.01\n")),
        Case("validate: a calibration of one observation", ["validate", "{dir}/calibration.yaml"], 0, "",
             setup=_calibration("0.1,0.12,0.01\n")),
        Case("API: multilayer.run in a child forked after the parent ran", validate, 0, "", setup=_scenario,
             patch=_api(FORKED)),
    ]  # fmt: skip
    return out


MIXTURE32 = {**MIXTURE, "material.particle_density": 2500.0}
"""TINY as a grain-fluid mixture of grains of 2500 kg/m^3 (the cases of round 32)."""

WET_ONLY_PLUGIN = """
import multilayer, numpy as np
from multilayer.plugins.contract import Rheology


class WetOnly(Rheology):
    name = "wet_only"

    def __init__(self, mu: float = 0.3):
        self.mu = mu

    def mixture_yield_stress(self, pressure, mixture, material):
        return self.mu * np.maximum(pressure, 0.0) * mixture.phi / 0.58

    def mixture_viscosity(self, shear_rate, pressure, mixture, material):
        return np.zeros(np.shape(pressure))


@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(WetOnly)
"""
"""A third-party law implementing only the mixture's methods (no dry yield stress)."""


def _mixture_patch(method: str, body: str) -> str:
    """``DruckerPrager.<method>`` (a mixture method) running ``body`` before the real one."""
    args = "self, p, mixture, m" if method == "mixture_yield_stress" else "self, g, p, mixture, m"
    return (
        f"real = DruckerPrager.{method}\ndef fault({args}):\n    {body}\n"
        f"    return real({args})\nDruckerPrager.{method} = fault\n"
    )


def _finished_mixture(directory: Path, changes: dict | None = None, end: float | None = None) -> None:
    """A completed run of :data:`MIXTURE32` (with ``changes``, to ``end``) in ``directory/out``."""
    extra = {"time.end": end} if end is not None else {}
    scenario = _scenario(directory, {**MIXTURE32, **(changes or {}), **extra})
    subprocess.run(
        [sys.executable, "-m", "multilayer", "run", str(scenario), "-o", str(directory / "out"), "-q"],
        check=True, capture_output=True,
    )  # fmt: skip
    if end is not None:  # the scenario the case resumes with runs on to TINY's end
        _scenario(directory, {**MIXTURE32, **(changes or {})})


def _mixture_result(edit: Callable[[Any], object], changes: dict | None = None) -> Callable[[Path], None]:
    """A finished mixture run (with ``changes``) whose ``result.nc`` is then given
    ``edit(dataset)`` (netCDF4, in place)."""

    def setup(directory: Path) -> None:
        _finished_mixture(directory, changes)
        import netCDF4

        with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
            edit(ds)

    return setup


def _wet_cell(ds: Any) -> int:
    return int(np.argmax(ds["h"][-1]))


def _dry_cell(ds: Any) -> int:
    return int(np.flatnonzero(ds["h"][-1] == 0.0)[0])


def _mixture_checkpoint(entry: str, value: Any, changes: dict | None = None) -> Callable[[Path], None]:
    """A mixture run to 0.1 s whose checkpoint holds ``entry = value(old)`` (deleted for
    None) under a valid checksum; the scenario runs on to 0.2 s."""

    def setup(directory: Path) -> None:
        from multilayer.io import results

        _finished_mixture(directory, changes, end=0.1)
        ckpt = directory / "out" / "checkpoint.npz"
        arrays: dict[str, Any] = dict(np.load(ckpt))
        arrays.pop("checksum")
        if value is None:
            arrays.pop(entry)
        else:
            arrays[entry] = value(arrays[entry])
        arrays["checksum"] = np.asarray(results._checksum(arrays))
        with open(ckpt, "wb") as stream:
            np.savez(stream, **arrays)

    return setup


def _wet_only(directory: Path) -> None:
    """:data:`MIXTURE32` on the law of :data:`WET_ONLY_PLUGIN`, installed as ``third``."""
    _plugin_package(directory, "third", WET_ONLY_PLUGIN)
    _scenario(directory, {**MIXTURE32, "rheology": {"name": "wet_only", "mu": 0.3}})


def round_thirty_two() -> list[Case]:
    """The hostile cases of the thirty-second round (docs/reliability.md), in the grain-fluid
    mixture, the newer model options and the data paths: a mixture law writing into the
    excess pore pressure it is given (the Newton iterate) or forcing its copy writeable; a
    mixture's ``phi`` changed within ``[0, 1)`` in a wet and in a dry cell, ``phi_layer``
    set where ``h`` is 0 and ``pore_pressure_excess`` unlike ``pore_pressure_layer``'s first
    layer; ``mixture.critical_shift`` 1e100 and 1e300 (a Newton iteration that overflows);
    a mixture's checkpoint without ``solid`` or ``pore_pressure`` or whose solid leaves its
    layers; ``expect`` entries no run can pass (a negative speed, mass or static height, a
    solid fraction of 2); as controls, packings and fluids at and past their bounds, a mixture
    between periodic sides, with vertical shear, a gate or walls, the non-hydrostatic pressure
    with every option and a gate between periodic sides, a plot of a mixture failed at its
    first step, a plugin's negative mixture viscosity, a law of the mixture's methods only
    and a resume with the fluid changed."""
    validate = ["validate", "{scenario}"]
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    resume = [*run, "--resume"]
    check = ["check", "{scenario}"]
    export = ["export", "{dir}/out", "--vtk"]
    mixture = partial(_scenario, changes=MIXTURE32)
    fluid = {"density": 1000.0, "viscosity": 1e-3}

    def mixed(**changes: Any) -> Callable[[Path], Path]:
        dotted = {k.replace("__", "."): v for k, v in changes.items()}
        return partial(_scenario, changes={**MIXTURE32, **dotted})

    def closure(**constants: float) -> dict:
        return {"mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0, **constants}}

    def pin(quantity: str, value: float, atol: float) -> list[dict]:
        return [{"kind": "regression", "quantity": quantity, "value": value, "atol": atol}]

    read_only = "mixture_yield_stress() raised ValueError: assignment destination is read-only"
    not_mean = "is not the mean of phi_layer over the layers"
    no_run = "no run passes"
    kept = "not a checkpoint this version of multilayer writes for this scenario"
    layered = {"fluid": {**fluid, "compressibility": 1e-3}}  # pore_pressure_layer in 3 layers
    nh = {"model": {"pressure": "non_hydrostatic", "normal_stress": True, "vertical_shear": True}}
    periodic = {"boundaries": {"left": "periodic", "right": "periodic"}}
    gate = {"gate": {"x": 0.1, "lift_speed": 0.5}}
    out = [
        Case("plugin: a mixture law writing into the excess pore pressure it is given", run, 1, read_only,
             patch=_mixture_patch("mixture_yield_stress", "mixture.pore_pressure[...] = 0.0"), setup=mixture,
             keeps_output=True),
        Case("plugin: a mixture law forcing its copy of the pore pressure writeable and scaling it", run, 0,
             "", setup=mixture, patch=_mixture_patch(
                 "mixture_yield_stress",
                 "mixture.pore_pressure.flags.writeable = True\n    mixture.pore_pressure[...] *= 10.0")),
        Case("plot: a mixture's phi changed to 0.3 in a wet cell", ["plot", "{dir}/out"], 2, not_mean,
             setup=_mixture_result(lambda ds: ds["phi"].__setitem__((-1, _wet_cell(ds)), 0.3))),
        Case("export: a mixture's phi 0.5 where h is 0", export, 2,
             "phi = 0.5 where h is 0 (no mixture there: 0)",
             setup=_mixture_result(lambda ds: ds["phi"].__setitem__((-1, _dry_cell(ds)), 0.5))),
        Case("export: a mixture's phi_layer 0.4 in every layer where h is 0", export, 2,
             "phi_layer is 0.4 where h is 0 (no mixture: 0)", setup=_mixture_result(
                 lambda ds: ds["phi_layer"].__setitem__((-1, slice(None), _dry_cell(ds)), 0.4))),
        Case("plot: pore_pressure_excess 100 Pa off pore_pressure_layer's first layer", ["plot", "{dir}/out"],
             2, "is not pore_pressure_layer of the first layer", setup=_mixture_result(
                 lambda ds: ds["pore_pressure_excess"].__setitem__(
                     (-1, _wet_cell(ds)), ds["pore_pressure_excess"][-1, _wet_cell(ds)] + 100.0), layered)),
        Case("mixture: critical_shift 1e100 in three layers, run", run, 1,
             "mixture.dilatancy = 4 and mixture.critical_shift = 1e+100)",
             setup=mixed(**closure(critical_shift=1e100)), keeps_output=True),
        # refused before the run since round 35 (its first step diverged, naming the closure's keys)
        Case("mixture: critical_shift 1e300 in three layers, run", run, 2,
             "mixture.critical_shift: the mixture's closure overflows on the initial column",
             setup=mixed(**closure(critical_shift=1e300))),
        Case("resume: a mixture's checkpoint without solid", resume, 2,
             "solid: missing; accepted: the state of a grain-fluid mixture holds solid and pore_pressure",
             setup=_mixture_checkpoint("state.solid", None)),
        Case("resume: a mixture's checkpoint without pore_pressure", resume, 2, "pore_pressure: missing",
             setup=_mixture_checkpoint("state.pore_pressure", None)),
        Case("resume: a mixture's checkpoint whose solid is 3 times its own", resume, 2,
             "m at layer 1, column 0, outside [0, ",
             setup=_mixture_checkpoint("state.solid", lambda s: 3 * s)),
        Case("resume: a mixture's checkpoint whose solid is 1 mm less (negative)", resume, 2, kept,
             setup=_mixture_checkpoint("state.solid", lambda s: s - 1e-3)),
        Case("validate: expect max_speed_final = -1 +- 0.1", validate, 2,
             f"max_speed_final = -1.0 +- 0.1: {no_run} (its max_speed_final is 0 or more)",
             setup=partial(_scenario, changes={"expect": pin("max_speed_final", -1.0, 0.1)})),
        Case("check: expect mass_final = -1 +- 0.5", check, 2, f"mass_final = -1.0 +- 0.5: {no_run}",
             setup=partial(_scenario, changes={"expect": pin("mass_final", -1.0, 0.5)})),
        Case("check: a mixture's expect phi_mean_final = 2 +- 0.1", check, 2,
             f"phi_mean_final = 2.0 +- 0.1: {no_run} (its phi_mean_final is in [0, 0.74048] (pi/sqrt(18)",
             setup=mixed(expect=pin("phi_mean_final", 2.0, 0.1))),
        Case("validate: expect static_interface_mean_final = -0.2 +- 0.1", validate, 2, no_run,
             setup=partial(_scenario, changes={"expect": pin("static_interface_mean_final", -0.2, 0.1)})),
        Case("control: expect max_speed_final = 0 +- 0 (validate)", validate, 0, "",
             setup=partial(_scenario, changes={"expect": pin("max_speed_final", 0.0, 0.0)})),
        Case("control: phi0 = phi_c, run", run, 0, "", setup=mixed(initial__0__phi=0.58)),
        Case("control: fluid viscosity 0 (no drag), run", run, 0, "",
             setup=mixed(fluid={**fluid, "viscosity": 0.0})),
        Case("control: compressibility 1, run", run, 0, "",
             setup=mixed(fluid={**fluid, "compressibility": 1.0})),
        Case("validate: compressibility 1 + ulp", validate, 2, "fluid.compressibility",
             setup=mixed(fluid={**fluid, "compressibility": 1.0000000000000002})),
        Case("validate: compressibility 0", validate, 2, "fluid.compressibility",
             setup=mixed(fluid={**fluid, "compressibility": 0.0})),
        Case("validate: a fluid denser than the grains", validate, 2,
             "fluid density 3000.0 is not below the grain density 2500.0",
             setup=mixed(fluid={**fluid, "density": 3000.0})),
        Case("validate: phi0 1 - 1e-16", validate, 2, "initial.0.phi",
             setup=mixed(initial__0__phi=1 - 1e-16)),
        Case("control: a mixture between periodic sides, run", run, 0, "", setup=mixed(**periodic)),
        Case("validate: a mixture with vertical shear", validate, 2, "model.vertical_shear",
             setup=mixed(model={"vertical_shear": True})),
        Case("validate: a mixture behind a gate", validate, 2, "gate (line", setup=mixed(**gate)),
        Case("control: non-hydrostatic, normal stress, vertical shear, a gate, periodic sides, run", run, 0,
             "", setup=partial(_scenario, changes={**nh, **gate, **periodic})),
        Case("plot: a mixture run failed at its first step", ["plot", "{dir}/out"], 0, "drawn up to t = 0 s",
             setup=lambda d: subprocess.run(
                 [sys.executable, "-m", "multilayer", "run", str(mixed(**closure(critical_shift=1e100))(d)),
                  "-o", str(d / "out"), "-q"], capture_output=True)),
        Case("plugin: a negative mixture viscosity", run, 1, "mixture_viscosity() returned -1.0",
             patch="DruckerPrager.mixture_viscosity = lambda self, g, p, s, m: np.full(np.shape(p), -1.0)\n",
             setup=mixture, keeps_output=True),
        Case("plugin: a third-party law of the mixture's methods only", run, 2,
             "WetOnly does not implement yield_stress()", env={"PYTHONPATH": "{dir}/plugin"},
             setup=_wet_only),
        Case("resume: a mixture's run with fluid.viscosity changed",
             [*resume, "--set", "fluid.viscosity=0.002"], 2, "changed: fluid.viscosity",
             setup=lambda d: _finished_mixture(d, end=0.1)),
    ]  # fmt: skip
    return out


def _failed_because(failure: object) -> Callable[[Path], None]:
    """A finished run whose result.nc says ``run_status: failed`` with ``failure``."""

    def setup(directory: Path) -> None:
        _result_attribute(None, "run_status", "failed")(directory)
        import netCDF4

        with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
            ds.setncattr("failure", failure)

    return setup


def _records(path: Path) -> int:
    try:
        import netCDF4

        with NETCDF, netCDF4.Dataset(path) as ds:
            return int(np.isfinite(ds["time"][:].filled(np.nan)).sum())
    except (OSError, KeyError, IndexError):
        return 0


def attempt(case: Case) -> Case:
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        if case.setup is not None:
            case.setup(directory)
        argv = [a.format(scenario=directory / "scenario.yaml", dir=directory) for a in case.argv]
        child = ["-m", "multilayer"] if case.plain else ["-c", CHILD.format(patch=case.patch)]
        command = [*case.prefix, sys.executable, *child, *argv]
        limit, ignored = case.file_limit, case.ignored

        def limited() -> None:
            if limit is not None:
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
            for signum in STOP_SIGNALS:  # as from a terminal, whatever the battery was started with
                signal.signal(signum, signal.SIG_IGN if signum in ignored else signal.SIG_DFL)

        start = time.monotonic()
        proc = subprocess.Popen(
            command,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, **{key: value.format(dir=directory) for key, value in case.env.items()}},
            preexec_fn=limited,
            cwd=directory if case.here else None,
        )
        if case.signal_after_output is not None:
            while _records(directory / "out" / "result.nc") < 2 and proc.poll() is None:
                time.sleep(0.02)
            proc.send_signal(case.signal_after_output)
        if case.signal_when is not None:
            marker, signum = case.signal_when
            while not (directory / marker).exists() and proc.poll() is None:
                time.sleep(0.02)
            proc.send_signal(signum)
        try:
            out, err = proc.communicate(timeout=120)
        except subprocess.TimeoutExpired:
            proc.kill()
            out, err = proc.communicate()
            err += "\n(killed after 120 s)"
        problems = []
        if proc.returncode != case.code:
            problems.append(f"exit {proc.returncode}, expected {case.code}")
        if "Traceback" in err:
            problems.append("traceback")
        if "encountered in" in err:  # numpy's RuntimeWarnings: the message is the run's own
            problems.append("numpy warning")
        if case.phrase not in err:
            problems.append(f"stderr lacks {case.phrase!r}")
        if case.one_message and len(err.strip().splitlines()) != 1:
            problems.append(f"{len(err.strip().splitlines())} lines on stderr, not one message")
        if case.keeps_output and _records(directory / "out" / "result.nc") < 1:
            problems.append("nothing kept in result.nc")
        case.result = {
            "handled": not problems,
            "problems": problems,
            "seconds": time.monotonic() - start,
            "stderr": err.strip().splitlines()[-1][:200] if err.strip() else "",
        }
    return case


LOCKS_AT_ONCE = """
import json, multiprocessing, os, socket
from pathlib import Path
from multilayer.app import lock
directory, earlier = Path(sys.argv[2]), sys.argv[3]

def take(barrier, results):
    barrier.wait()
    try:
        with lock.locked(directory):
            start = time.monotonic()
            time.sleep(0.1)
            results.put(('held', start, time.monotonic()))
    except Exception as exc:
        results.put(('refused', str(exc), 0.0))

context, overlaps, refusals = multiprocessing.get_context('fork'), 0, set()
for trial in range(10):
    directory.mkdir(exist_ok=True)
    if earlier == 'stale':
        dead = {'pid': 2**31 - 2, 'host': socket.gethostname(), 'started': '2026-01-01T00:00:00+00:00'}
        (directory / lock.LOCK_FILE).write_text(json.dumps(dead))
    barrier, results = context.Barrier(6), context.Queue()
    workers = [context.Process(target=take, args=(barrier, results)) for _ in range(6)]
    started = [worker.start() for worker in workers]
    outcomes = [results.get(timeout=60) for _ in workers]
    ended = [worker.join() for worker in workers]
    held = sorted((a, b) for what, a, b in outcomes if what == 'held')
    overlaps += any(later[0] < first[1] for first, later in zip(held, held[1:]))
    refusals |= {m.split(' (pid')[0].split(': ', 1)[1] for what, m, _ in outcomes if what == 'refused'}
said = f'{overlaps} of 10 trials with two holders at once; refused: {sorted(refusals)}'
print(f'multilayer: {said}', file=sys.stderr)
sys.exit(1 if overlaps else 0)
"""
"""Six processes taking one directory's lock at the same instant, ten times: the number of
trials in which two held it at once (runs started together into one directory)."""

EXPORTS_AT_ONCE = PLOTS_AT_ONCE.replace("'plot', sys.argv[2]]", "'export', sys.argv[2], '--vtk']").replace(
    "three plots", "three exports"
)
"""Three ``multilayer export --vtk`` of one directory started together."""


def _made_directory(*names: str) -> Callable[[Path], None]:
    """A finished run whose ``out/NAME`` are directories (files an output would replace)."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        for name in names:
            (directory / "out" / name).mkdir(parents=True)

    return setup


def _held_after_a_run(directory: Path) -> None:
    """A finished run whose directory's lock a live process (the battery) holds."""
    _finished_run(directory)
    record = {"pid": os.getppid(), "host": socket.gethostname(), "started": "2026-01-01T00:00:00+00:00"}
    (directory / "out" / "run.lock").write_text(json.dumps(record))


def _sensitivity33(parameters: dict, **extra: Any) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        _scenario(directory)
        study = {"base": "scenario.yaml", "parameters": parameters, "outputs": ["runout"], "samples": 32}
        study.update(extra)
        (directory / "study.yaml").write_text(yaml.safe_dump(study, sort_keys=False))

    return setup


def _sweep33(text: str) -> Callable[[Path], None]:
    def setup(directory: Path) -> None:
        _scenario(directory)
        (directory / "study.yaml").write_text("base: scenario.yaml\n" + text)

    return setup


def round_thirty_three() -> list[Case]:
    """The hostile cases of the thirty-third round (docs/reliability.md), in the study files
    and at the operating system's level: six processes taking one output directory's lock
    at the same instant, from no lock and from a stale one (two held it at once); ``plot
    --animate`` whose animation's file is a directory (Matplotlib warned under the
    message); sensitivity bounds reversed or equal, a seed of 2^64, a parameter unknown to
    the rheology or past the end of ``initial``, a parameter also given in ``set``; sweep
    values of a key given before the mapping holding it, values equal to the last bit;
    ``plot`` and ``export`` of a run still writing its result and whose figure or VTK file
    is a directory; as controls, three exports of one directory at once, an animation and a
    valid sensitivity file."""
    study = ["validate", "{dir}/study.yaml"]
    run_live = ["run", "{scenario}", "-o", "{dir}/out", "--resume", "-q"]
    bounds = "accepted: [lower, upper] with lower < upper"
    mu_s, nu = {"bounds": [0.3, 0.4]}, {"bounds": [0.0, 0.02]}
    one_holder = (
        "0 of 10 trials with two holders at once; refused: ['another run is writing into this directory']"
    )
    animate = ["plot", "{dir}/out", "--animate"]
    return [
        Case("lock: six runs taking one directory at once, no lock before", ["lock", "{dir}/out", "none"], 0,
             one_holder, patch=LOCKS_AT_ONCE),
        Case("lock: six runs taking one directory at once, a stale lock before",
             ["lock", "{dir}/out", "stale"], 0, one_holder, patch=LOCKS_AT_ONCE),
        Case("plot --animate: plots/section.gif and section.mp4 directories", animate, 2,
             "exists and is not a regular file (a directory", one_message=True,
             setup=_made_directory("plots/section.gif", "plots/section.mp4")),
        Case("plot: plots/section.png a directory", ["plot", "{dir}/out"], 2,
             "out/plots/section.png: exists and is not a regular file", one_message=True,
             setup=_made_directory("plots/section.png")),
        Case("export: vtk/result_0003.vts a directory", ["export", "{dir}/out", "--vtk"], 2,
             "out/vtk/result_0003.vts: exists and is not a regular file", one_message=True,
             setup=_made_directory("vtk/result_0003.vts")),
        Case("run --resume into a directory a live run holds", run_live, 2,
             "another run is writing into this directory (pid", one_message=True,
             setup=_held_after_a_run),
        Case("plot: a result still being written (run_status running)", ["plot", "{dir}/out"], 2,
             "run_status is 'running': a run is still writing it", one_message=True,
             setup=_damaged_result("running")),
        Case("sensitivity: bounds reversed [0.4, 0.3]", study, 2, bounds, one_message=True,
             setup=_sensitivity33({"rheology.mu_s": {"bounds": [0.4, 0.3]}, "rheology.nu": nu})),
        Case("sensitivity: bounds equal [0.3, 0.3]", study, 2, bounds, one_message=True,
             setup=_sensitivity33({"rheology.mu_s": {"bounds": [0.3, 0.3]}, "rheology.nu": nu})),
        Case("sensitivity: seed 2^64", study, 2, "accepted: an integer from 0 to 4294967295",
             one_message=True,
             setup=_sensitivity33({"rheology.mu_s": mu_s, "rheology.nu": nu}, seed=2**64)),
        Case("sensitivity: rheology.mu_2 of drucker_prager", study, 2, "unknown parameter of drucker_prager",
             setup=_sensitivity33({"rheology.mu_2": {"bounds": [0.5, 0.6]}, "rheology.nu": nu})),
        Case("sensitivity: initial.5.height of one initial entry", study, 2, "accepted indices: 0..0",
             setup=_sensitivity33({"initial.5.height": {"bounds": [0.03, 0.05]}, "rheology.nu": nu})),
        Case("sensitivity: a parameter also given in set", study, 2, "also given a value in set",
             one_message=True, setup=_sensitivity33({"rheology.mu_s": mu_s, "rheology.nu": nu},
                                                    set={"rheology.mu_s": 0.35})),
        Case("sweep: rheology.mu_s swept before rheology", study, 2,
             "set before it, whose value would be lost",
             setup=_sweep33("parameters:\n  rheology.mu_s: [0.3, 0.35]\n"
                            "  rheology: [{name: drucker_prager, mu_s: 0.4, nu: 0.0}]\n")),
        Case("sweep: time.end 0.1 and 0.1000000000000000001", study, 2, "it would run twice",
             one_message=True,
             setup=_sweep33("parameters: {time.end: [0.1, 0.1000000000000000001]}\n")),
        Case("control: three exports of one directory at once", ["export", "{dir}/out"], 0,
             "three exports at once exited [0, 0, 0]", patch=EXPORTS_AT_ONCE, setup=_finished_run),
        Case("control: plot --animate of a finished run", animate, 0, "",
             setup=_finished_run),
        Case("control: a sensitivity file of two parameters", study, 0, "",
             setup=_sensitivity33({"rheology.mu_s": mu_s, "rheology.nu": nu})),
    ]  # fmt: skip


VTK_FIELDS = """
import glob, re
code = main(sys.argv[1:])
text = open(sorted(glob.glob(sys.argv[2] + '/vtk/result_*.vts'))[-1]).read()
print(f"multilayer: cell data {sorted(set(re.findall('Name=.([a-z_]+).', text)))}", file=sys.stderr)
sys.exit(code)
"""
"""``export`` of ``sys.argv[2]``, then the names of the cell data of its last ``.vts`` on stderr."""

THREE_THREADS = """
import threading, multilayer
results = {}
def go(i):
    try:
        results[i] = float(multilayer.run(sys.argv[2])['mass'][-1])
    except BaseException as exc:
        results[i] = repr(exc)
threads = [threading.Thread(target=go, args=(i,)) for i in range(3)]
[t.start() for t in threads]
[t.join() for t in threads]
print(f"multilayer: three runs in threads: {sorted(map(str, results.values()))}", file=sys.stderr)
sys.exit(0)
"""
"""Three ``multilayer.run`` of ``sys.argv[2]`` at once, each in a thread of one process."""

ASK_NO_FURTHER = "import multilayer.app.sensitivity as _s\n_s.sample = lambda study: sys.exit(0)\n"
"""A sensitivity study stopped once its directory and file are checked (before any run)."""

CALIBRATE_NO_FURTHER = (
    "import multilayer.app.commands.calibrate as _c\n_c.study_ensemble = lambda *a, **k: sys.exit(0)\n"
)
"""A calibration stopped once its directory and file are checked (before any run)."""


def _study_ran_with(name: str, attribute: str, earlier: str) -> Callable[[Path], None]:
    """``out/<name>`` (a study's file of results) recording ``earlier`` as the study file it ran."""

    def setup(directory: Path) -> None:
        import netCDF4

        (directory / "out").mkdir(exist_ok=True)
        with NETCDF, netCDF4.Dataset(directory / "out" / name, "w") as ds:
            ds.setncattr(attribute, earlier)

    return setup


def _changed_sensitivity(directory: Path) -> None:
    _sensitivity33({"rheology.mu_s": {"bounds": [0.3, 0.4]}, "rheology.nu": {"bounds": [0.0, 0.02]}})(
        directory
    )
    _study_ran_with("sensitivity.nc", "sensitivity", "base: scenario.yaml\nsamples: 16\n")(directory)


def _changed_calibration(directory: Path) -> None:
    _calibration("0.05,0.12,0.01\n0.1,0.2,0.01\n")(directory)
    _study_ran_with("calibration.nc", "calibration", "base: base.yaml\n")(directory)


def _same_sensitivity(directory: Path) -> None:
    _sensitivity33({"rheology.mu_s": {"bounds": [0.3, 0.4]}, "rheology.nu": {"bounds": [0.0, 0.02]}})(
        directory
    )
    _study_ran_with("sensitivity.nc", "sensitivity", (directory / "study.yaml").read_text())(directory)


def _in_a_non_ascii_directory(directory: Path) -> None:
    (directory / "é").mkdir()
    _scenario(directory / "é")


def round_thirty_four() -> list[Case]:
    """The hostile cases of the thirty-fourth round (docs/reliability.md), in the process's
    limits and environment and the leftovers of the earlier rounds: an address-space limit
    (``ulimit -v``) of 300 MB (``validate``: SciPy's import spun for ever; ``run``: named as
    a directory not writable) and 400-600 MB (a MemoryError traceback reading a scenario of
    1 kB, or an ImportError), a mesh beyond the address space though within
    the machine's memory and a MemoryError in ``export``; a mixture's checkpoint of solid 0
    (refused only by the closure at the next step); a sweep key ``''`` or ``rheology..mu_s``
    (named as a member's ``--set``) and sweeps over ``name`` and ``description`` (each
    member the same run); ``sensitivity`` and ``calibrate --resume`` whose file changed; a
    film thinner than the dry threshold (a warning before the error); ``export --vtk`` of a
    mixture (no ``phi`` nor pore pressure); as controls, a resume of a mixture's own
    checkpoint, an unchanged sensitivity file resumed, a limit of 1.5 GB, a run in a
    non-ASCII directory under ``LC_ALL=C``, 2000 layers and three runs in threads of one
    process."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    resume = [*run, "--resume"]
    sweep = ["validate", "{dir}/study.yaml"]
    export = ["export", "{dir}/out", "--vtk"]

    def limited(megabytes: int) -> list[str]:
        return ["prlimit", f"--as={megabytes * 10**6}", "--"]

    def column_emptied(solid: np.ndarray) -> np.ndarray:
        solid = solid.copy()
        solid[:, 1] = 0.0
        return solid

    address = "(ulimit -v), where its libraries"
    empty = "has an empty part; accepted: a dotted scenario key, no part empty"
    unrun = "does not change the run: every member would run the same simulation"
    changed = "changed since the study in"
    solid0 = "solid holds 0 m in column 0, "
    mixture_fields = "cell data ['h', 'phi', 'pore_pressure_excess', 'static', 'u']"
    layered = {"fluid": {"density": 1000.0, "viscosity": 1e-3, "compressibility": 1e-3}}
    mesh = {"domain.cells": 2_000_000, "time.end": 1e-5, "time.output_interval": 1e-5}
    return [
        Case("ulimit -v 300 MB: run", run, 2, address, prefix=limited(300), plain=True, setup=_scenario,
             one_message=True),
        Case("ulimit -v 300 MB: validate", ["validate", "{scenario}"], 2, address, prefix=limited(300),
             plain=True, setup=_scenario, one_message=True),
        Case("ulimit -v 400 MB: validate", ["validate", "{scenario}"], 2, address, prefix=limited(400),
             plain=True, setup=_scenario, one_message=True),
        Case("ulimit -v 600 MB: run", run, 2, address, prefix=limited(600), plain=True, setup=_scenario,
             one_message=True),
        Case("ulimit -v 500 MB: plot", ["plot", "{dir}/out"], 2, address, prefix=limited(500), plain=True,
             setup=_finished_run, one_message=True),
        Case("ulimit -v 1.2 GB: a mesh of 2e6 cells (2.4 GB) within the machine's memory", run, 2,
             "more than the address space of this process (ulimit -v)", prefix=limited(1200), plain=True,
             setup=partial(_scenario, changes=mesh), one_message=True),
        Case("export: a MemoryError while writing a file", export, 2, "multilayer: error: out of memory",
             patch="import multilayer.io.export as _e\ndef _full(*a):\n    raise MemoryError()\n"
                   "_e.structured_grid = _full\n", setup=_finished_run, one_message=True),
        Case("resume: a mixture's checkpoint whose solid is 0", resume, 2, solid0,
             setup=_mixture_checkpoint("state.solid", lambda s: 0.0 * s), one_message=True),
        Case("resume: a mixture's checkpoint whose column 1 holds no solid", resume, 2,
             "solid holds 0 m in column 1, ", setup=_mixture_checkpoint("state.solid", column_emptied),
             one_message=True),
        Case("sweep: a key ''", sweep, 2, f"parameters.'' (line 3): the key '' {empty}",
             setup=_sweep33("parameters:\n  '': [1, 2]\n"), one_message=True),
        Case("sweep: a key rheology..mu_s", sweep, 2, f"the key 'rheology..mu_s' {empty}",
             setup=_sweep33("parameters:\n  rheology..mu_s: [0.3, 0.4]\n"), one_message=True),
        Case("sweep: over name", sweep, 2, f"parameters.name (line 3): name {unrun}",
             setup=_sweep33("parameters:\n  name: [a, b]\n"), one_message=True),
        Case("sweep: over description", sweep, 2, f"description {unrun}",
             setup=_sweep33("parameters:\n  description: [a, b]\n  rheology.mu_s: [0.3, 0.4]\n"),
             one_message=True),
        Case("sensitivity --resume: the sensitivity file changed since",
             ["sensitivity", "{dir}/study.yaml", "-o", "{dir}/out", "--resume"], 0, changed,
             patch=ASK_NO_FURTHER, setup=_changed_sensitivity),
        Case("calibrate --resume: the calibration file changed since",
             ["calibrate", "{dir}/calibration.yaml", "-o", "{dir}/out", "--resume", "-q"], 0, changed,
             patch=CALIBRATE_NO_FURTHER, setup=_changed_calibration),
        Case("run: a film of 1e-9 m, below the dry threshold", run, 2, "not above numerics.dry_threshold",
             setup=partial(_scenario, changes={"initial.0": {"shape": "layer", "thickness": 1e-9}}),
             one_message=True),
        Case("export --vtk: a mixture's phi and pore pressure", export, 0, mixture_fields, patch=VTK_FIELDS,
             setup=_finished_mixture),
        Case("export --vtk: a mixture's phi and pore pressure per layer", export, 0, mixture_fields,
             patch=VTK_FIELDS, setup=lambda d: _finished_mixture(d, layered)),
        Case("control: resume of a mixture's own checkpoint", resume, 0, "",
             setup=lambda d: _finished_mixture(d, end=0.1)),
        Case("control: sensitivity --resume of an unchanged file",
             ["sensitivity", "{dir}/study.yaml", "-o", "{dir}/out", "--resume"], 0, "",
             patch=ASK_NO_FURTHER, setup=_same_sensitivity),
        Case("control: ulimit -v 1.5 GB, run", run, 0, "", prefix=limited(1500), plain=True, setup=_scenario),
        Case("control: LC_ALL=C, a run in a directory named é", ["run", "{dir}/é/scenario.yaml", "-q"], 0, "",
             env={"LC_ALL": "C", "LANG": "C"}, setup=_in_a_non_ascii_directory, plain=True, here=True),
        Case("control: 2000 layers, run", run, 0, "",
             setup=partial(_scenario, changes={"domain.layers": 2000})),
        Case("control: three multilayer.run at once in threads of one process", ["threads", "{scenario}"], 0,
             "three runs in threads: ['0.005000000000000001', '0.005000000000000001', "
             "'0.005000000000000001']", patch=THREE_THREADS, setup=_scenario),
        Case("control: a film of 1e-5 m, above the dry threshold, run", run, 0, "",
             setup=partial(_scenario, changes={"initial.0": {"shape": "layer", "thickness": 1e-5}})),
    ]  # fmt: skip


UNSHOWABLE = (
    "class Unshowable(RuntimeError):\n"
    "    def __str__(self):\n"
    "        raise ValueError('a message of the exception itself')\n"
)
"""An exception of a third party whose ``__str__`` raises (Python's traceback module says
``<exception str() failed>``)."""
NOT_TEXT = "class Unshowable(ValueError):\n    def __str__(self):\n        return 3\n"
"""An exception whose ``__str__`` returns no string (``str()`` raises ``TypeError``)."""


WALL_VISCOSITY = (
    "from multilayer.plugins.builtins.wall_friction import WallFriction\n"
    "WallFriction.viscosity = lambda self, g, p, m: np.full(np.shape(p), 1e308)\n"
    "WallFriction.viscosity_kernel = lambda self, material: None\n"
)
"""The built-in wall law returning a viscosity of 1e308 Pa s from its Python method."""


def _constructor_raising(exception: str) -> str:
    """DruckerPrager's constructor raising ``Unshowable()``, defined by ``exception``."""
    return exception + _constructor_patch("Unshowable()")


def _observations35(rows: str, header: str = "t,x_f,sigma") -> Callable[[Path], None]:
    """A calibration of TINY whose observation file holds ``rows`` under ``header``, as
    written by the battery's other calibration cases."""
    return _calibration(rows, header=header)


_NO_COMPILATION = (
    "DruckerPrager.yield_stress_kernel = lambda self, material: None\n"
    "DruckerPrager.viscosity_kernel = lambda self, material: None\n"
    "import atexit, os\n"
    "from numba.core import event\n"
    "compiled = []\n"
    "class _Compiling(event.Listener):\n"
    "    def on_start(self, e):\n"
    "        compiled.append(e.data['dispatcher'].py_func.__qualname__)\n"
    "    def on_end(self, e):\n"
    "        pass\n"
    "event.register('numba:compile', _Compiling())\n"
    "def _report():\n"
    "    if compiled:\n"
    "        print(f'multilayer: compiled {compiled}', file=sys.stderr, flush=True)\n"
    "        os._exit(1)\n"
    "atexit.register(_report)\n"
)
"""DruckerPrager on the numpy path (a third-party law's), any compilation of numba a failure."""


def round_thirty_five() -> list[Case]:
    """The hostile cases of the thirty-fifth round (docs/reliability.md), in third-party
    rheology plugins misbehaving at run time and values at the edge of the scenario's
    ranges: a plugin's exception whose ``__str__`` raises or returns no string, raised mid-run,
    by its constructor (a ``RuntimeError`` and a ``ValueError``) and on importing its entry
    point (its own message replaced the one naming the plugin, or a traceback); a yield
    stress of 1e308 Pa, finite (numpy warned of an overflow in the finiteness test of the
    column solve: the sum of finite values overflowed) and a viscosity of 1e308 Pa s (its
    stresses overflowed: numpy's warnings, then the column kernel's coefficient ``c`` named
    instead of the plugin), of the bulk law and of the wall law; as controls, ``plot`` of a
    result holding another tool's variable and of one whose ``h`` is renamed, a yield
    stress of float32 and of integers, observations unsorted, at one time twice and under a
    byte order mark, a slope of 89.99999 degrees, a mixture of phi 1e-9; a mixture whose
    fluid viscosity or dilatancy of 1e300 overflows its closure (``validate`` said OK, the
    run stopped at step 0: refused at validation naming the key) beside a viscosity of 1e3, and a
    run on two threads under a law without compiled forms after ``multilayer compile``
    (it compiled the numpy path's parallel column solve)."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    validate = ["validate", "{scenario}"]
    observations = ["validate", "{dir}/calibration.yaml"]
    unshown = "(its message cannot be shown: str() raised "
    mid_run = "yield_stress() raised Unshowable: " + unshown
    constructed = "DruckerPrager(mu_s=0.3, nu=0.01) raised Unshowable: " + unshown
    plugin_env = {"PYTHONPATH": "{dir}/plugin"}
    importing = "raise Unshowable()\n"
    huge = "return np.full(np.shape(p), 1e308)"
    walled = {"walls": {"name": "wall_friction", "mu_w": 0.2}, "domain.width": 0.1}
    junk = "ds.createDimension('extra', 2)\nds.createVariable('junk', 'f8', ('extra',))\n"
    huge_viscosity = "def fault(self, g, p, m):\n    return np.full(np.shape(p), 1e308)\n" + (
        "DruckerPrager.viscosity = fault\nDruckerPrager.viscosity_kernel = lambda self, material: None\n"
    )
    return [
        Case("run: a plugin's exception whose __str__ raises, mid-run", run, 1, mid_run + "ValueError)",
             patch=UNSHOWABLE + _mid_run_patch("raise Unshowable()"), setup=_scenario, keeps_output=True,
             one_message=True),
        Case("run: a plugin's exception whose __str__ returns 3, mid-run", run, 1, mid_run + "TypeError)",
             patch=NOT_TEXT + _mid_run_patch("raise Unshowable()"), setup=_scenario, keeps_output=True,
             one_message=True),
        Case("validate: a constructor's RuntimeError whose __str__ raises", validate, 2,
             constructed + "ValueError)", patch=_constructor_raising(UNSHOWABLE), setup=_scenario,
             one_message=True),
        Case("run: a constructor's RuntimeError whose __str__ raises", run, 2, constructed + "ValueError)",
             patch=_constructor_raising(UNSHOWABLE), setup=_scenario, one_message=True),
        Case("validate: a constructor's ValueError whose __str__ returns 3", validate, 2,
             "rheology (line 18): drucker_prager: " + unshown + "TypeError)",
             patch=_constructor_raising(NOT_TEXT), setup=_scenario, one_message=True),
        Case("validate: an entry point whose module raises an exception whose __str__ raises", validate, 0,
             "rheology plugin third 0.1 (entry point third = third) skipped: Unshowable: " + unshown,
             setup=_entry_point_plugin(UNSHOWABLE + importing), env=plugin_env),
        Case("validate: an entry point whose module raises an exception whose __str__ returns 3",
             validate, 0, "skipped: Unshowable: " + unshown + "TypeError)",
             setup=_entry_point_plugin(NOT_TEXT + importing), env=plugin_env),
        Case("run: a plugin's yield stress of 1e308 Pa mid-run", run, 0, "", patch=_mid_run_patch(huge),
             setup=_scenario),
        Case("run: a plugin's viscosity of 1e308 Pa s", run, 1,
             "viscosity() returned 1e+308 Pa s at the shear rate 0 1/s, whose viscous stress or its slope",
             patch=huge_viscosity, setup=_scenario, keeps_output=True, one_message=True),
        Case("run: a wall law's viscosity of 1e308 Pa s", run, 1,
             "rheology plugin 'wall_friction' (multilayer.plugins.builtins.wall_friction.WallFriction): "
             "viscosity() returned 1e+308 Pa s", patch=WALL_VISCOSITY, keeps_output=True, one_message=True,
             setup=partial(_scenario, changes=walled)),
        Case("control: plot of a result holding a variable of another tool over a dimension of its own",
             ["plot", "{dir}/out"], 0, "",
             setup=_result_edit(junk)),
        Case("control: plot of a result whose h is renamed h_old", ["plot", "{dir}/out"], 2,
             "not a multilayer result: no variable h", one_message=True,
             setup=_result_edit("ds.renameVariable('h', 'h_old')\n")),
        Case("control: a plugin's yield stress of float32 mid-run", run, 0, "",
             patch=_mid_run_patch("return np.zeros(np.shape(p), np.float32)"), setup=_scenario),
        Case("control: a plugin's yield stress of integers mid-run", run, 0, "",
             patch=_mid_run_patch("return np.zeros(np.shape(p), int)"), setup=_scenario),
        Case("control: observations unsorted in time", observations, 0, "",
             setup=_observations35("0.2,0.15,0.01\n0.1,0.12,0.01\n")),
        Case("control: observations twice at one time", observations, 0, "",
             setup=_observations35("0.1,0.15,0.01\n0.1,0.12,0.01\n")),
        Case("control: observations under a byte order mark", observations, 0, "",
             setup=_observations35("0.1,0.12,0.01\n", header="\ufefft,x_f,sigma")),
        Case("control: a slope of 89.99999 degrees, run", run, 0, "",
             setup=partial(_scenario, changes={"slope_deg": 89.99999})),
        Case("control: a mixture of phi 1e-9, run", run, 0, "",
             setup=partial(_scenario, changes={**MIXTURE32, "initial.0.phi": 1e-9})),
        *[
            Case(f"{command[0]}: a mixture of {key} 1e300 (its closure overflows)", command, 2,
                 f"{key}: the mixture's closure overflows on the initial column", one_message=True,
                 setup=partial(_scenario, changes={**MIXTURE32, key: 1e300}))
            for key in ("fluid.viscosity", "mixture.dilatancy") for command in (validate, run)
        ],
        Case("control: a mixture of fluid.viscosity 1e3, validate", validate, 0, "",
             setup=partial(_scenario, changes={**MIXTURE32, "fluid.viscosity": 1e3})),
        Case("control: a run under a third-party law on two threads after compile compiles nothing", run, 0,
             "",
             setup=partial(_scenario, changes={"numerics": {"threads": 2}}), patch=_NO_COMPILATION),
    ]  # fmt: skip


AFTER_THE_RUN = (
    "import atexit, netCDF4\n"
    "def _report():\n"
    "    directory = sys.argv[sys.argv.index('-o') + 1]\n"
    "    with netCDF4.Dataset(directory + '/result.nc') as ds:\n"
    "        h, u = ds['h'][:].filled(np.nan), ds['u'][:].filled(np.nan)\n"
    "{check}"
    "atexit.register(_report)\n"
)
"""A report on stderr after the run of what its ``result.nc`` holds: ``{check}``, lines
of ``_report`` given ``h`` (time, x) and ``u`` (time, layer, x)."""

AT_REST = "    print(f'multilayer: max |u| over the run {float(np.abs(u).max())!r}', file=sys.stderr)\n"
"""The largest speed of the run (0.0: every layer kept at rest to the bit)."""
SYMMETRIC = (
    "    gap = float(np.abs(h - h[:, ::-1]).max())\n"
    "    near = gap <= 64 * 2.0**-52 * float(h.max())\n"
    "    said = 'symmetric to round-off' if near else f'asymmetric by {gap!r} m'\n"
    "    print(f'multilayer: h {said}', file=sys.stderr)\n"
)
"""``h`` mirrored about the centre of the domain at every output time, within 64 eps of its
largest value (the sums of the two halves are taken in opposite orders)."""
SAME_AS = (
    "    with netCDF4.Dataset(directory + '/../{other}/result.nc') as ds:\n"
    "        same = np.array_equal(h, ds['h'][:].filled(np.nan))\n"
    "        same = same and np.array_equal(u, ds['u'][:].filled(np.nan))\n"
    "    print(f'multilayer: records equal to those of {other} to the bit: {{same}}', file=sys.stderr)\n"
)
"""The records of the run compared bit for bit with those of ``{other}`` (a run of the same
scenario in the case's directory)."""


def _run_into(directory: Path, name: str, *options: str) -> None:
    """``multilayer run`` of the case's scenario into ``directory/name``."""
    command = [sys.executable, "-m", "multilayer", "run", str(directory / "scenario.yaml"), "-o"]
    subprocess.run([*command, str(directory / name), "-q", *options], check=True, capture_output=True)


def _one_thread(changes: dict) -> Callable[[Path], None]:
    """The scenario ``changes`` run on one thread into ``one`` (the case runs it on two)."""

    def setup(directory: Path) -> None:
        _scenario(directory, {**changes, "numerics": {"threads": 1}})
        _run_into(directory, "one")
        _scenario(directory, {**changes, "numerics": {"threads": 2}})

    return setup


JOP37 = {"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.28}
HELD = {"name": "jop_mu_i", "mu_s": 0.5, "mu_2": 0.8, "I_0": 0.3}
"""mu(I) whose static friction 0.5 holds a layer on 20 degrees (tan 20 deg = 0.36)."""
LAYER = {"shape": "layer", "thickness": 0.01}
INFLOW37 = {"thickness": 0.01, "velocity": {"profile": "plug", "speed": 0.5}}
MIXTURE37: dict[str, Any] = {
    "material": {"density": 1830.0, "grain_diameter": 225e-6, "particle_density": 2500.0},
    "rheology": {"name": "dilatant_coulomb", "delta_deg": 22.5, "K1": 90.5},
    "fluid": {"density": 1010.0, "viscosity": 0.0121},
    "mixture": {"phi_critical": 0.582, "dilatancy": 4.09, "critical_shift": 25.0},
}
"""The loose submarine collapse of Rondon et al. (2011) (scenarios/submarine_collapse_loose.yaml)."""


def round_thirty_seven() -> list[Case]:
    """The cases of the thirty-seventh round (docs/reliability.md): valid runs at the
    scales and in the set-ups where a run-time guard could stop them wrongly, or let a
    wrong state through: a landslide 1e4 m thick on 1e5 m, a 1 mm column on 10^4 cells, a
    film of 2e-6 m, densities of 1e2 and 1e4, 256 geometric layers; layers at rest below
    their friction angle under each pressure model and the normal stress (u must stay 0.0
    to the bit); runs of 3500 and 25 000 steps through open sides (the mass balance over
    the run); a consolidating mixture; a symmetric collapse (h mirrored to round-off);
    two threads against one (equal to the bit); a mesh of
    10^6 columns of 10 layers that the memory estimate refused at 24.4 GB, needing 2 GB,
    and 2 x 10^5 columns of 10 under 1 GB."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    held = {"slope_deg": 20.0, "rheology": HELD, "initial.0": LAYER, "time.end": 0.5}
    held["time.output_interval"] = 0.25
    collapse = {
        "slope_deg": 0.0,
        "domain": {"x_min": -0.5, "x_max": 0.5, "cells": 100, "layers": 3},
        "rheology": JOP37,
        "initial.0": {"shape": "rectangle", "x_min": -0.1, "x_max": 0.1, "height": 0.1},
        "boundaries": {"left": "wall", "right": "wall"},
    }
    landslide = {
        "domain": {"x_min": 0.0, "x_max": 1e5, "cells": 400, "layers": 3},
        "material.grain_diameter": 0.1,
        "initial.0": {"shape": "rectangle", "x_min": 0.0, "x_max": 2e4, "height": 1e4},
        "time": {"end": 200.0, "output_interval": 50.0},
    }
    lab = {
        "domain": {"x_min": 0.0, "x_max": 0.02, "cells": 10000, "layers": 2},
        "material.grain_diameter": 1e-5,
        "initial.0": {"shape": "rectangle", "x_min": 0.0, "x_max": 0.002, "height": 0.001},
        "time": {"end": 0.02, "output_interval": 0.005},
    }
    drain = {
        "slope_deg": 30.0,
        "domain": {"x_min": 0.0, "x_max": 0.05, "cells": 5, "layers": 1},
        "rheology": {"name": "drucker_prager", "mu_s": 0.0, "nu": 0.01},
        "initial.0": LAYER,
        "time": {"end": 2000.0, "output_interval": 500.0},
        "numerics": {"dry_threshold": 1e-12, "front_threshold": 1e-9},
    }
    through = {
        "slope_deg": 30.0,
        "domain": {"x_min": 0.0, "x_max": 0.2, "cells": 20, "layers": 2},
        "initial": [],
        "boundaries": {"left": "inflow", "right": "outflow", "inflow": INFLOW37},
        "time": {"end": 20.0, "output_interval": 5.0},
    }
    consolidating = {
        **MIXTURE37,
        "slope_deg": 0.0,
        "domain": {"x_min": 0.0, "x_max": 0.3, "cells": 60, "layers": 1},
        "fluid": {**MIXTURE37["fluid"], "compressibility": 1e-5},
        "initial.0": {"shape": "rectangle", "x_min": 0.0, "x_max": 0.06, "height": 0.048, "phi": 0.55},
        "boundaries": {"left": "wall", "right": "wall"},
        "time": {"end": 5.0, "output_interval": 2.5},
    }
    mesh = {"slope_deg": 35.0, "initial.0": LAYER, "time.end": 2e-4, "time.output_interval": 1e-4}
    million = {"domain": {"x_min": 0.0, "x_max": 500.0, "cells": 1_000_000, "layers": 10}}
    fifth = {**mesh, "domain": {"x_min": 0.0, "x_max": 100.0, "cells": 200_000, "layers": 10}}
    rest = "multilayer: max |u| over the run 0.0"
    film = {"initial.0": {"shape": "layer", "thickness": 2e-6}}
    film["numerics"] = {"dry_threshold": 1e-9, "front_threshold": 1e-7}
    geometric = {"domain.layers": 256, "domain.layer_fractions": {"geometric": 1.05}}
    geometric.update({"time.end": 0.05, "time.output_interval": 0.01})
    equal = "records equal to those of {} to the bit: True"
    models: dict[str, dict[str, Any]] = {
        "hydrostatic": {},
        "bim2016": {"model": {"pressure": "bim2016"}},
        "non_hydrostatic": {"model": {"pressure": "non_hydrostatic"}},
        "the normal stress": {"model": {"normal_stress": True}},
    }
    completes: dict[str, dict[str, Any]] = {  # valid runs that must complete: no guard may stop them
        "a landslide 1e4 m thick on a domain 1e5 m long": landslide,
        "a column 1 mm high on 10^4 cells of 2 um": lab,
        "a film of 2e-6 m above a dry threshold of 1e-9 m": film,
        **{f"a density of {density:g} kg/m3": {"material.density": density} for density in (1e2, 1e4)},
        "256 layers of geometric ratio 1.05": geometric,
        "a layer draining through its outflow in 25 000 steps": drain,
        "an inflow through an empty chute to its outflow in 3500 steps": through,
        "a mixture of one relaxing layer consolidating for 5 s": consolidating,
    }
    return [
        *[Case(f"run: {what}", run, 0, "", setup=partial(_scenario, changes=changes))
          for what, changes in completes.items()],
        *[
            Case(f"run: a layer held by its friction on 20 degrees, {name}, wall and outflow", run, 0, rest,
                 patch=AFTER_THE_RUN.format(check=AT_REST),
                 setup=partial(_scenario, changes={**held, **model}))
            for name, model in models.items()
        ],
        Case("run: a layer held by its friction between periodic sides, non_hydrostatic", run, 0, rest,
             patch=AFTER_THE_RUN.format(check=AT_REST),
             setup=partial(_scenario, changes={**held, **models["non_hydrostatic"],
                                               "boundaries": {"left": "periodic", "right": "periodic"}})),
        Case("run: a symmetric collapse between walls stays symmetric", run, 0, "h symmetric to round-off",
             patch=AFTER_THE_RUN.format(check=SYMMETRIC), setup=partial(_scenario, changes=collapse)),
        Case("run: a symmetric collapse under non_hydrostatic stays symmetric", run, 0,
             "h symmetric to round-off",
             patch=AFTER_THE_RUN.format(check=SYMMETRIC),
             setup=partial(_scenario, changes={**collapse, **models["non_hydrostatic"]})),
        Case("run: two threads against one, non_hydrostatic", run, 0, equal.format("one"),
             patch=AFTER_THE_RUN.format(check=SAME_AS.format(other="one")),
             setup=_one_thread({**collapse, **models["non_hydrostatic"]})),
        Case("run: two threads against one, the normal stress", run, 0, equal.format("one"),
             patch=AFTER_THE_RUN.format(check=SAME_AS.format(other="one")),
             setup=_one_thread({**collapse, **models["the normal stress"]})),
        Case("validate: 10^6 columns of 10 layers (a run needs 2 GB) under --max-memory 4G",
             ["validate", "{scenario}", "--max-memory", "4G"], 0, "",
             setup=partial(_scenario, changes={**mesh, **million})),
        Case("run: 2 x 10^5 columns of 10 layers under --max-memory 1G", [*run, "--max-memory", "1G"], 0, "",
             setup=partial(_scenario, changes=fifth)),
        Case("control: 10^6 columns of 10 layers under --max-memory 2G",
             ["validate", "{scenario}", "--max-memory", "2G"], 2, "need about 2.",
             setup=partial(_scenario, changes={**mesh, **million}), one_message=True),
    ]  # fmt: skip


SOLID_KEPT = (
    "    with netCDF4.Dataset(directory + '/result.nc') as ds:\n"
    "        phi = ds['phi'][:].filled(np.nan)\n"
    "    solid = np.nansum(phi * h, axis=1)\n"
    "    drift = float(np.abs(solid / solid[0] - 1.0).max())\n"
    "    bounded = bool(np.all(h >= 0.0) and np.all((phi >= 0.0) & (phi < 1.0)))\n"
    "    said = 'to round-off' if drift <= 1e-12 else f'to {drift!r}'\n"
    "    print(f'multilayer: solid kept {said}; h >= 0 and phi in [0, 1): {bounded}', file=sys.stderr)\n"
)
"""The solid volume ``sum phi h`` of every output time against the first's, within 1e-12
(no flux through walls or between periodic sides: it is kept to round-off), and ``h >= 0``
with every packing in ``[0, 1)``; the fluid's balance with the ambient fluid is the state
guard's, checked at every step of a run that completes."""


def _mixture39(height: float, grain: float, slope: float, end: float, **more: Any) -> dict[str, Any]:
    """The loose collapse of :data:`MIXTURE37` scaled to a column ``height`` high and 1.25
    ``height`` long, of grains of diameter ``grain``, on ``slope`` degrees, between walls
    5 column lengths apart, 30 cells, run to ``end``; ``more``: other keys."""
    column = {"shape": "rectangle", "x_min": 0.0, "x_max": 1.25 * height, "height": height, "phi": 0.55}
    return {
        **MIXTURE37,
        "material": {**MIXTURE37["material"], "grain_diameter": grain},
        "slope_deg": slope,
        "domain": {"x_min": 0.0, "x_max": 6.25 * height, "cells": 30, "layers": 1},
        "initial.0": column,
        "boundaries": {"left": "wall", "right": "wall"},
        "time": {"end": end, "output_interval": end / 4.0},
        **more,
    }


def round_thirty_nine() -> list[Case]:
    """The cases of the thirty-ninth round (docs/reliability.md): valid grain-fluid mixture
    runs that must complete, from a column 1 mm high to one 100 m high, grains of 0.1 mm to
    5 cm, fluids of 1e-3 to 1 Pa s, slopes of 0 to 30 degrees, loose and dense packings,
    three layers, a thin film between periodic sides and a run of 60 s.  At the thin front
    of a large column a step's dilation rate ``Phi`` reaches ``dt Phi > 1`` at a trial of the
    local step's Newton iteration (2.9 at the first trial of the fifth step of the column
    10 m high): its update of the thickness, ``h* / (1 - dt Phi)``, was not a thickness, and
    the run stopped ("the mixture's local step diverged", or did not converge, in up to 256
    sub-steps).  Each must exit 0 with its solid kept to round-off and its packings in
    ``[0, 1)``."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    kept = "solid kept to round-off; h >= 0 and phi in [0, 1): True"
    film = _mixture39(1.0, 1e-4, 30.0, 15.0, boundaries={"left": "periodic", "right": "periodic"})
    film.update({"initial.0": {"shape": "layer", "thickness": 1e-4, "phi": 0.55}})
    film["domain"] = {"x_min": 0.0, "x_max": 0.1, "cells": 30, "layers": 1}
    completes: dict[str, dict[str, Any]] = {  # valid mixture runs that must complete
        "a loose column 10 m high of 1 cm grains on 10 degrees": _mixture39(10.0, 1e-2, 10.0, 5.0),
        "a loose column 1 mm high of 0.1 mm grains on 30 degrees": _mixture39(1e-3, 1e-4, 30.0, 0.2),
        "a loose column 100 m high of 5 cm grains on 30 degrees": _mixture39(100.0, 5e-2, 30.0, 20.0),
        "a loose column 10 m high of 0.1 mm grains in a fluid of 1e-3 Pa s": _mixture39(
            10.0, 1e-4, 10.0, 5.0, fluid={"density": 1000.0, "viscosity": 1e-3}
        ),
        "a loose column 10 m high of 1 cm grains in a fluid of 1 Pa s": _mixture39(
            10.0, 1e-2, 10.0, 5.0, fluid={"density": 1010.0, "viscosity": 1.0}
        ),
        "a dense column (0.60) 10 m high of 1 cm grains on 30 degrees": {
            **_mixture39(10.0, 1e-2, 30.0, 5.0),
            "initial.0.phi": 0.6,
        },
        "a loose column of Rondon et al. (2011) in three layers on 10 degrees": {
            **_mixture39(0.048, 225e-6, 10.0, 1.0),
            "domain.layers": 3,
        },
        "a loose film 0.1 mm thick of 0.1 mm grains on 30 degrees between periodic sides": film,
        "a loose column 10 m high of 1 cm grains on 0 degrees for 60 s": _mixture39(10.0, 1e-2, 0.0, 60.0),
    }
    return [
        Case(f"run: {what}", run, 0, kept, patch=AFTER_THE_RUN.format(check=SOLID_KEPT),
             setup=partial(_scenario, changes=changes))
        for what, changes in completes.items()
    ]  # fmt: skip


def _engine_directory() -> Path:
    """The installed engine's directory (the kernel modules numba caches beside)."""
    import importlib.util

    spec = importlib.util.find_spec("multilayer")
    assert spec is not None and spec.submodule_search_locations is not None
    return Path(spec.submodule_search_locations[0]) / "engine"


def _copied_cache(marked: bool) -> Callable[[Path], None]:
    """The scenario and ``cache``, a ``NUMBA_CACHE_DIR`` holding a copy of the kernels the
    engine's directories cache (compiled there by ``multilayer compile``), as numba's
    locator for that variable places them (``<directory>_<SHA-1 of its path>``), with the
    mark of ``multilayer compile`` or without."""
    import hashlib

    def setup(directory: Path) -> None:
        _scenario(directory)
        for pycache in sorted(_engine_directory().rglob("__pycache__")):
            if not (pycache / "kernels.digest").is_file():
                continue
            source = str(pycache.parent)
            copy = directory / "cache" / f"{pycache.parent.name}_{hashlib.sha1(source.encode()).hexdigest()}"
            copy.mkdir(parents=True)
            names = ["*.nbi", "*.nbc", "kernels.digest", *(["kernels.compiled"] if marked else [])]
            for name in names:
                for file in pycache.glob(name):
                    shutil.copy2(file, copy / file.name)

    return setup


FORKED_AFTER_THREADS = """
import multiprocessing, multilayer
def go(outdir):
    result = multilayer.run(sys.argv[2], outdir=outdir, overrides={'numerics.threads': 2})
    return result.attrs['run_status'], float(result['mass'][-1])
parent = go(sys.argv[3] + '/parent')
with multiprocessing.get_context(sys.argv[4]).Pool(1) as pool:
    child = pool.apply_async(go, (sys.argv[3] + '/child',)).get(timeout=100)
print(f'multilayer: forked child: {child[0]}, mass as the parent: {child == parent}', file=sys.stderr)
sys.exit(0 if child == parent else 1)
"""
"""A run on two threads, then one in a child of multiprocessing's ``sys.argv[4]`` context."""

POOL_RUNS = """
import multiprocessing, multilayer
with multiprocessing.get_context(sys.argv[4]).Pool(2) as pool:
    results = pool.starmap(multilayer.run, [(sys.argv[2], f'{sys.argv[3]}/m{i}') for i in range(2)])
print(f"multilayer: {sys.argv[4]} pool: {[float(r['mass'][-1]) for r in results]}", file=sys.stderr)
sys.exit(0)
"""
"""Two ``multilayer.run`` in a pool of multiprocessing's ``sys.argv[4]`` context (the
function the pool calls is the library's: a new process cannot import this script)."""

HOST_KEPT_WHOLE = """
import atexit, faulthandler, logging, os, signal, threading, warnings
import numba, numpy as np
import dask.threaded, matplotlib.pyplot, netCDF4, scipy.special, fipy  # what their imports set is theirs
logging.getLogger('multilayer').setLevel(logging.DEBUG)
def host():
    import numba
    mask = os.umask(0o022); os.umask(mask)
    stoppable = [s for s in signal.Signals if s not in (signal.SIGKILL, signal.SIGSTOP)]
    handlers = {s.name: signal.getsignal(s) for s in stoppable}
    loggers = {name: (getattr(l, 'level', None), list(getattr(l, 'handlers', [])))
               for name, l in logging.root.manager.loggerDict.items()}
    return {'signal handlers': handlers, 'threads': sorted(t.name for t in threading.enumerate()),
            'hooks': (sys.excepthook, sys.unraisablehook, threading.excepthook, sys.displayhook,
                      warnings.showwarning, sys.breakpointhook),
            'warnings filters': list(warnings.filters), 'numpy errors': np.geterr(),
            'numpy printing': np.get_printoptions(), 'umask': mask, 'cwd': os.getcwd(),
            'recursion limit': sys.getrecursionlimit(), 'switch interval': sys.getswitchinterval(),
            'faulthandler': faulthandler.is_enabled(), 'streams': (sys.stdin, sys.stdout, sys.stderr),
            'numba threads': (numba.get_num_threads(), numba.get_parallel_chunksize()),
            'numba config': {k: v for k, v in vars(numba.config).items()
                             if k.isupper() and isinstance(v, (int, str))},
            'loggers': loggers, 'matplotlib': (matplotlib.get_backend(), dict(matplotlib.rcParams))}
import matplotlib
before = host()
import multilayer
result = multilayer.run(sys.argv[2], outdir=sys.argv[3] + '/run', overrides={'numerics.threads': 2})
done = result.attrs['run_status']
sim = multilayer.Simulation(multilayer.load(sys.argv[2], {'numerics.threads': 2}))
sim.step()
after = host()
new = set(after['loggers']) - set(before['loggers'])  # loggers the libraries' imports made
after['loggers'] = {k: v for k, v in after['loggers'].items() if k not in new}
changed = [key for key, value in host().items() if key != 'loggers' and value != before[key]]
changed += ['loggers'] if after['loggers'] != before['loggers'] else []
print(f'multilayer: run {done}, changed {changed}', file=sys.stderr)
sys.exit(0 if done == 'completed' and not changed else 1)
"""
"""A host that set its loggers, signals and numba's settings runs a scenario and steps a
simulation on two threads through the Python API: nothing of the host may change (its
threads, hooks, signal handlers, warning filters, numba's thread count and configuration,
logging, umask, streams, Matplotlib's backend and settings)."""

IN_A_THREAD = """
import threading
out = {}
def go():
    import multilayer
    out['status'] = multilayer.run(sys.argv[2], outdir=sys.argv[3] + '/run').attrs['run_status']
thread = threading.Thread(target=go)
thread.start(); thread.join()
print(f"multilayer: imported and run in a thread: {out.get('status')}", file=sys.stderr)
sys.exit(0 if out.get('status') == 'completed' else 1)
"""
"""The first import of multilayer and a run, in a thread that is not the main one."""

ENDING_PLUGIN = """
import os
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
class Ending(DruckerPrager):
    name = "ending"
    yield_stress_kernel = lambda self, material: None
    viscosity_kernel = lambda self, material: None
    def yield_stress(self, *arguments):
        os._exit(3)
@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(Ending)
"""
"""A third-party law whose yield stress ends its process (``os._exit``: a crash of C code)."""


THIRD_PLUGIN = """
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
class Third(DruckerPrager):
    name = "NAME"
    yield_stress_kernel = lambda self, material: None
    viscosity_kernel = lambda self, material: None
@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(Third)
"""
"""A third-party law ``NAME``: Drucker-Prager on the numpy path."""


def _third_party_sweep(law: str) -> Callable[[Path], None]:
    """A sweep of one member under the third-party law ``law``: ``ending`` of
    :data:`ENDING_PLUGIN`, or ``third`` of :data:`THIRD_PLUGIN`."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        module = ENDING_PLUGIN if law == "ending" else THIRD_PLUGIN.replace("NAME", law)
        _plugin_package(directory, law, module)
        (directory / "study.yaml").write_text(
            f"base: scenario.yaml\nparameters:\n  rheology: [{{name: {law}, mu_s: 0.3, nu: 0.01}}]\n"
        )

    return setup


def _two_distributions(directory: Path) -> None:
    """Distributions ``first`` and ``second`` each registering a law named ``shared``."""
    _scenario(directory, {"rheology": {"name": "shared", "mu_s": 0.3, "nu": 0.01}})
    for name in ("first", "second"):
        _plugin_package(directory, name, THIRD_PLUGIN.replace("NAME", "shared"))


def _entry_point_to(value: str, module: str) -> Callable[[Path], None]:
    """A distribution ``third`` whose entry point is ``third = VALUE`` over ``module``."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        _plugin_package(directory, "third", module)
        entry_points = directory / "plugin" / "third-0.1.dist-info" / "entry_points.txt"
        entry_points.write_text(f"[multilayer]\nthird = {value}\n")

    return setup


def round_thirty_eight() -> list[Case]:
    """The hostile cases of the thirty-eighth round (docs/reliability.md), in the
    installation, numba's kernel cache and the host process, as a user on a cluster or in
    a notebook meets them: a run on two threads in a child of multiprocessing's fork
    context after a threaded run of its parent (numba's GNU OpenMP layer sent the child
    SIGTERM: "interrupted by SIGTERM", and the pool hung); ``multilayer compile`` under
    ``PYTHONWARNINGS=error`` (its children's pipes left open: a ResourceWarning's
    traceback); a sweep whose third-party law ends its process (the study's own warm-up
    step ran it: the study ended, exit 3, without a word); as controls, ``-OO``, ``-O``
    and ``-I``, ``PYTHONWARNINGS=error`` runs, sweeps and plots, pools of the spawn and
    forkserver contexts, a host whose settings must stay, an import and run in a thread, a
    ``NUMBA_CACHE_DIR`` holding a copied cache and one that is a file, entry points naming
    no plugin, a missing attribute and one name registered by two distributions."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    validate = ["validate", "{scenario}"]
    sweep = ["sweep", "{dir}/study.yaml", "-o", "{dir}/out", "-q", "--workers", "1"]
    plugin_env = {"PYTHONPATH": "{dir}/plugin"}
    cache = {"NUMBA_CACHE_DIR": "{dir}/cache"}
    errors = {"PYTHONWARNINGS": "error"}
    isolated = ["sh", "-c", 'exec "$0" -I "$@"']
    completed = "forked child: completed, mass as the parent: True"
    return [
        Case("fork: a run on two threads in a child forked after a threaded run",
             ["fork", "{scenario}", "{dir}", "fork"], 0, completed, patch=FORKED_AFTER_THREADS,
             setup=_scenario),
        Case("compile: PYTHONWARNINGS=error over a cache of the kernels without its mark", ["compile"], 0,
             "", env={**cache, **errors}, plain=True, setup=_copied_cache(False)),
        Case("sweep: a third-party law ending its process (os._exit)", sweep, 1,
             "(rheology={mu_s: 0.3, name: ending, nu: 0.01}) failed: KilledWorker", env=plugin_env,
             setup=_third_party_sweep("ending")),
        Case("control: a sweep of a third-party law", sweep, 0, "", env=plugin_env,
             setup=_third_party_sweep("third")),
        Case("control: python -OO (PYTHONOPTIMIZE=2), plugins", ["plugins"], 0, "",
             env={"PYTHONOPTIMIZE": "2"}, plain=True),
        Case("control: python -O (PYTHONOPTIMIZE=1), validate", validate, 0, "",
             env={"PYTHONOPTIMIZE": "1"}, plain=True, setup=_scenario),
        Case("control: python -I, run", run, 0, "", prefix=isolated, plain=True, setup=_scenario),
        Case("control: PYTHONWARNINGS=error, run", run, 0, "", env=errors, plain=True, setup=_scenario),
        Case("control: PYTHONWARNINGS=error, run on two threads warning of its front threshold",
             [*run, "--set", "numerics.threads=2", "--set", "numerics.front_threshold=0.5"], 0,
             "the front is absent (NaN) at every output time", env=errors, plain=True, setup=_scenario),
        Case("control: PYTHONWARNINGS=error, sweep",
             ["sweep", "{dir}/study.yaml", "-o", "{dir}/out", "-q", "--workers", "2"], 0, "", env=errors,
             plain=True, setup=_sweep33("parameters:\n  rheology.mu_s: [0.3, 0.35]\n")),
        Case("control: PYTHONWARNINGS=error, plot of a run", ["plot", "{dir}/out"], 0, "",
             env=errors, plain=True, setup=_finished_run),
        Case("control: two multilayer.run in a spawn pool", ["pool", "{scenario}", "{dir}", "spawn"], 0,
             "spawn pool: [0.005000000000000001, 0.005000000000000001]", patch=POOL_RUNS, setup=_scenario),
        Case("control: two multilayer.run in a forkserver pool",
             ["pool", "{scenario}", "{dir}", "forkserver"], 0,
             "forkserver pool: [0.005000000000000001, 0.005000000000000001]", patch=POOL_RUNS,
             setup=_scenario),
        Case("control: a host's threads, hooks, handlers, filters, numba and logging kept by a run",
             ["host", "{scenario}", "{dir}"], 0, "run completed, changed []", patch=HOST_KEPT_WHOLE,
             setup=_scenario),
        Case("control: multilayer imported and run in a thread", ["thread", "{scenario}", "{dir}"], 0,
             "imported and run in a thread: completed", patch=IN_A_THREAD, setup=_scenario),
        Case("control: NUMBA_CACHE_DIR a copied cache, compile", ["compile"], 0, "", env=cache, plain=True,
             setup=_copied_cache(True)),
        Case("control: NUMBA_CACHE_DIR a copied cache, a run compiles nothing", run, 0, "", env=cache,
             patch=_NO_COMPILATION.split("\n", 2)[2], setup=_copied_cache(True)),
        Case("control: NUMBA_CACHE_DIR a regular file, validate", validate, 0, "",
             env={"NUMBA_CACHE_DIR": "{dir}/scenario.yaml"}, plain=True, setup=_scenario),
        Case("plugin: an entry point naming a number, not a module of hooks", validate, 0,
             "(entry point third = third:VALUE) skipped: registers no rheology", env=plugin_env,
             setup=_entry_point_to("third:VALUE", "VALUE = 3\n")),
        Case("plugin: an entry point naming an attribute its module lacks", validate, 0,
             "skipped: AttributeError: module 'third' has no attribute 'Missing'", env=plugin_env,
             setup=_entry_point_to("third:Missing", "")),
        Case("plugin: two distributions registering one name", validate, 0,
             "rheology name 'shared' is already registered by first 0.1", env=plugin_env,
             setup=_two_distributions),
    ]  # fmt: skip


LOUD_PLUGIN = """
print("loud: imported")
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
class Loud(DruckerPrager):
    "\\x1b[31mA loud law\\x1b[0m, ringing \\a."
    name = "loud"
    yield_stress_kernel = lambda self, material: None
    viscosity_kernel = lambda self, material: None
    def __init__(self, mu_s: float, nu: float, tag: str = "\\x1b[2J"):
        print("loud: constructed")
        super().__init__(mu_s, nu)
@multilayer.hookimpl
def multilayer_register_rheologies(register):
    print("loud: registering")
    register(Loud)
"""
"""A third-party law printing as it is imported, registers and is constructed, whose
docstring and a parameter's default hold escape sequences of the terminal."""

STDOUT_LINES = """
import contextlib, io
captured = io.StringIO()
with contextlib.redirect_stdout(captured):
    code = main(sys.argv[1:])
lines = captured.getvalue().splitlines()
bad = [line for line in lines if {test}]
print(f'multilayer: {{len(lines)}} lines on stdout, {what}: {{bad[:2]}}', file=sys.stderr)
sys.exit(code if not bad else 1)
"""
"""The command's stdout captured: exit 1 if a line of it passes ``test`` (``what`` says which)."""


def _loud_plugin(directory: Path) -> None:
    """:data:`LOUD_PLUGIN` installed in ``directory/plugin``; the scenario under its law, its
    distribution's name holding an escape sequence."""
    _scenario(directory, {"rheology": {"name": "loud", "mu_s": 0.3, "nu": 0.01}})
    _plugin_package(directory, "loud", LOUD_PLUGIN)
    metadata = directory / "plugin" / "loud-0.1.dist-info" / "METADATA"
    metadata.write_text("Metadata-Version: 2.1\nName: loud\x1b[5m\nVersion: 0.1\n")


def _netcdf_observation(how: str) -> Callable[[Path], None]:
    """A calibration of ``mu_s`` against a front curve in ``front.nc`` written as another tool
    writes one: ``how`` in units arrays, a number, bytes, an unlimited and compressed
    variable, a group beside it, a symbolic link loop for the file."""

    def setup(directory: Path) -> None:
        import netCDF4

        _scenario(directory)
        config = {
            "base": "scenario.yaml",
            "parameters": {"rheology.mu_s": {"bounds": [0.2, 0.4]}},
            "observations": [
                {"name": "front", "quantity": "front", "file": "front.nc", "variable": "x_f", "sigma": 0.01}
            ],
            "search": {"population": 4, "generations": 1},
        }
        (directory / "calibration.yaml").write_text(yaml.safe_dump(config))
        if how in ("a loop of symbolic links", "a link to nothing"):
            os.symlink("front.nc" if how == "a loop of symbolic links" else "nothing.nc", directory / "link")
            os.replace(directory / "link", directory / "front.nc")
            return
        with NETCDF, netCDF4.Dataset(directory / "front.nc", "w") as ds:
            ds.createDimension("t", None if how == "unlimited and compressed" else 3)
            t = ds.createVariable("t", "f8", ("t",))
            t[:] = [0.05, 0.1, 0.15]
            dtype = "i1" if how == "int8 in cm" else "f8"
            front = ds.createVariable("x_f", dtype, ("t",), zlib=how == "unlimited and compressed")
            front[:] = [5, 9, 12] if dtype == "i1" else [0.05, 0.09, 0.12]
            t.units, front.units = "s", "cm" if dtype == "i1" else "m"
            if how == "units an array":
                front.units = np.array([1.0, 2.0])
            elif how == "coordinate units an array":
                t.units = np.array([1, 2], dtype="i4")
            elif how == "units a number":
                front.units = 5.0
            elif how == "a group holding x_f":
                group = ds.createGroup("more")
                group.createDimension("t", 2)
                group.createVariable("x_f", "f8", ("t",))[:] = [np.nan, np.inf]

    return setup


def _study_at_bounds(kind: str, parameter: str, bounds: list[float]) -> Callable[[Path], None]:
    """A ``kind`` (calibration or sensitivity) study of ``parameter`` within ``bounds``."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        study: dict[str, Any] = {"base": "scenario.yaml", "parameters": {parameter: {"bounds": bounds}}}
        if kind == "calibration":
            mass = {"name": "mass", "quantity": "mass_final", "value": 0.001, "sigma": 0.001}
            study["observations"] = [mass]
            study["search"] = {"population": 4, "generations": 1}
        else:
            study.update(outputs=["runout"], samples=8)
        (directory / "study.yaml").write_text(yaml.safe_dump(study))

    return setup


def _linked_base(kind: str) -> Callable[[Path], None]:
    """A ``kind`` (sweep or sensitivity) study whose base ``scenario.yaml`` is a symbolic link
    in a loop with ``other.yaml``."""

    def setup(directory: Path) -> None:
        (directory / "other.yaml").symlink_to("scenario.yaml")
        (directory / "scenario.yaml").symlink_to("other.yaml")
        study: dict[str, Any] = {"base": "scenario.yaml", "parameters": {"rheology.mu_s": [0.3, 0.35]}}
        if kind == "sensitivity":
            study.update(parameters={"rheology.mu_s": {"bounds": [0.2, 0.4]}}, outputs=["runout"], samples=8)
        (directory / "study.yaml").write_text(yaml.safe_dump(study))

    return setup


def _fifo_base(directory: Path) -> None:
    """A calibration whose base scenario is a named pipe (nobody writes it)."""
    _calibration("0.1,0.2,0.01\n")(directory)
    (directory / "base.yaml").unlink()
    os.mkfifo(directory / "base.yaml")


def _accented_scenario(directory: Path) -> None:
    shutil.copy(_scenario(directory), directory / "\u00e9.yaml")


def round_forty() -> list[Case]:
    """The hostile cases of the fortieth round (docs/reliability.md): a third-party law's
    own text on the commands' stdout (its prints at import, registration and construction
    went into ``plugins``, ``validate`` and ``run``; its docstring's and its
    distribution's escape sequences reached the terminal through ``plugins``; under
    ``-OO`` every description was empty); netCDF observations of another tool (``units``
    an array: a traceback); a study's base and observation file that are symbolic links
    to nothing or in a loop ("not found"); a calibration and a sensitivity study whose
    bound leaves the column outside the domain or below the dry threshold (``validate``
    said ok, the study failed at its runs); ``é`` on the command line under an ASCII locale (refused as bytes
    that are not UTF-8); as controls, environment variables of the libraries, accepted
    extremes of a scenario and hostile ``--set`` paths and study files."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    validate = ["validate", "{scenario}"]
    plugin_env = {"PYTHONPATH": "{dir}/plugin"}
    ascii_locale = {"LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    loud = STDOUT_LINES.format(test="line.startswith('loud: ')", what="lines of the plugin")
    escapes = STDOUT_LINES.format(test="'\\x1b' in line or '\\a' in line", what="escape sequences")
    empty = STDOUT_LINES.format(test="line.endswith(']: ')", what="empty descriptions")
    study = ["validate", "{dir}/study.yaml"]
    calibration = ["validate", "{dir}/calibration.yaml"]
    outside = "the scenario is invalid with domain.x_max = 0.05"
    dangling = "is a symbolic link to nothing or in a loop"
    extremes: dict[str, dict[str, Any]] = {
        "a gate lifted at 1e-300 m/s (it never opens)": {"gate": {"x": 0.1, "lift_speed": 1e-300}},
        "a gate lifted at 1e300 m/s": {"gate": {"x": 0.1, "lift_speed": 1e300}},
        "a slope of -89.9 degrees": {"slope_deg": -89.9},
        "gravity 1e-300": {"gravity": 1e-300},
        "1000 threads on two cores": {"numerics": {"threads": 1000}},
    }
    return [
        Case("plugins: a law printing at import and registration (stdout)", ["plugins"], 0,
             "lines on stdout, lines of the plugin: []", patch=loud, env=plugin_env, setup=_loud_plugin),
        Case("validate: a law printing in its constructor (stdout)", validate, 0,
             "lines on stdout, lines of the plugin: []", patch=loud, env=plugin_env, setup=_loud_plugin),
        Case("run: a law printing at import (stdout)", run[:-1], 0,
             "lines on stdout, lines of the plugin: []", patch=loud, env=plugin_env, setup=_loud_plugin),
        Case("plugins: escape sequences in a docstring, a default and a distribution's name", ["plugins"],
             0, "lines on stdout, escape sequences: []", patch=escapes, env=plugin_env, setup=_loud_plugin),
        Case("plugins: python -OO (no docstrings)", ["plugins"], 0, "lines on stdout, empty descriptions: []",
             patch=empty, env={"PYTHONOPTIMIZE": "2"}),
        Case("plugins: python -OO, a third-party law", ["plugins"], 0,
             "lines on stdout, empty descriptions: []", patch=empty,
             env={"PYTHONOPTIMIZE": "2", **plugin_env}, setup=_loud_plugin),
        *[
            Case(f"calibration: a netCDF observation, {how}", calibration, 2, f"front.nc: {phrase}",
                 setup=_netcdf_observation(how))
            for how, phrase in (
                ("units an array", "x_f has units array([1., 2.]), not text"),
                ("coordinate units an array", "t has units array([1, 2], dtype=int32), not text"),
            )
        ],
        Case("calibration: a netCDF observation, units a number", calibration, 2, "5.0",
             setup=_netcdf_observation("units a number")),
        *[
            Case(f"calibration: a netCDF observation, {how}", calibration, 2, f"front.nc {dangling}",
                 setup=_netcdf_observation(how))
            for how in ("a loop of symbolic links", "a link to nothing")
        ],
        *[
            Case(f"validate: a {kind} whose base is a loop of symbolic links", study, 2,
                 f"scenario.yaml {dangling}", setup=_linked_base(kind))
            for kind in ("sweep", "sensitivity")
        ],
        *[
            Case(f"control: a netCDF observation, {how}", calibration, 0, "", setup=_netcdf_observation(how))
            for how in ("int8 in cm", "unlimited and compressed", "a group holding x_f")
        ],
        Case("validate: a sensitivity study whose x_max bound cuts the column", study, 2, outside,
             setup=_study_at_bounds("sensitivity", "domain.x_max", [0.05, 1.0])),
        Case("sensitivity: its x_max bound cutting the column",
             ["sensitivity", "{dir}/study.yaml", "-o", "{dir}/out", "-q", "--workers", "1"], 2, outside,
             setup=_study_at_bounds("sensitivity", "domain.x_max", [0.05, 1.0])),
        Case("validate: a calibration whose x_max bound cuts the column", study, 2, outside,
             setup=_study_at_bounds("calibration", "domain.x_max", [0.05, 1.0])),
        Case("validate: a calibration whose height bound is a film below the dry threshold", study, 2,
             "not above numerics.dry_threshold", setup=_study_at_bounds("calibration", "initial.0.height",
                                                                      [1e-9, 0.05])),
        Case("validate: a sensitivity study of rheology.name", study, 2, "rheology.name (from --set)",
             setup=_study_at_bounds("sensitivity", "rheology.name", [0.2, 0.4])),
        Case("validate: a calibration whose base is a named pipe", ["validate", "{dir}/calibration.yaml"], 2,
             "is not a regular file", setup=_fifo_base),
        Case("run: --set description=\u00e9 under an ASCII locale", [*run, "--set", "description=\u00e9"], 0,
             "", env=ascii_locale, plain=True, setup=_scenario),
        Case("run: -o \u00e9 under an ASCII locale", ["run", "{scenario}", "-o", "{dir}/\u00e9", "-q"], 2,
             "is a UTF-8 name, which this process's locale (encoding ascii) cannot give netCDF",
             env=ascii_locale, plain=True, setup=_scenario),
        Case("control: run of \u00e9.yaml under an ASCII locale",
             ["run", "{dir}/\u00e9.yaml", "-o", "{dir}/out"], 0, "", env=ascii_locale, plain=True,
             setup=_accented_scenario),
        Case("control: OMP_NUM_THREADS=abc, a run on two threads", [*run, "--set", "numerics.threads=2"], 0,
             "", env={"OMP_NUM_THREADS": "abc"}, plain=True, setup=_scenario),
        Case("control: TMPDIR a missing directory, run", run, 0, "", env={"TMPDIR": "{dir}/nothing"},
             plain=True, setup=_scenario),
        Case("control: MPLCONFIGDIR a regular file, plot", ["plot", "{dir}/out"], 0, "",
             env={"MPLCONFIGDIR": "{dir}/scenario.yaml"}, plain=True, setup=_finished_run),
        Case("control: HOME empty, plot", ["plot", "{dir}/out"], 0, "", env={"HOME": ""}, plain=True,
             setup=_finished_run),
        *[
            Case(f"control: run, {what}", run, 0, "", setup=partial(_scenario, changes=changes))
            for what, changes in extremes.items()
        ],
        Case("validate: --set through a value (name.first)", [*validate, "--set", "name.first=1"], 2,
             "name is a value, not a mapping", setup=_scenario),
        Case("validate: --set of index -1", [*validate, "--set", "initial.-1.height=0.04"], 2,
             "accepted indices: 0..0", setup=_scenario),
    ]  # fmt: skip


LOUD_RUN_PLUGIN = """
import multilayer
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
class LoudRun(DruckerPrager):
    "Drucker-Prager on the numpy path, printing in its methods."
    name = "loudrun"
    yield_stress_kernel = lambda self, material: None
    viscosity_kernel = lambda self, material: None
    def yield_stress(self, *arguments, **keywords):
        print("loud: yield_stress")
        return super().yield_stress(*arguments, **keywords)
    def viscosity(self, *arguments, **keywords):
        print("loud: viscosity")
        return super().viscosity(*arguments, **keywords)
@multilayer.hookimpl
def multilayer_register_rheologies(register):
    register(LoudRun)
"""
"""A third-party law printing a line each time its yield stress or viscosity is called."""

OWN_STDOUT = """
import subprocess
done = subprocess.run([sys.executable, '-m', 'multilayer', *sys.argv[1:]], stdout=subprocess.PIPE, text=True)
lines = done.stdout.splitlines()
bad = [line for line in lines if line.startswith('loud: ')]
said = [line for line in lines if any(word in line for word in (': wrote ', ' ok, ', 'expectations met'))]
print(f'multilayer: {len(lines)} lines on stdout, its summary: {bool(said)}, lines of the plugin: {bad[:2]}',
      file=sys.stderr)
sys.exit(done.returncode if said and not bad else 1)
"""
"""The command run in a process of its own whose stdout (the descriptor, which the workers
of a study share) is read: exit 1 if a line of the plugin is there or the summary is not."""

STDOUT_REPLACED = """
import contextlib, io
calls[0] = 0
real_yield = DruckerPrager.yield_stress
def replacing(self, *arguments):
    calls[0] += 1
    if calls[0] == 3:
        sys.stdout = None
    return real_yield(self, *arguments)
DruckerPrager.yield_stress = replacing
DruckerPrager.yield_stress_kernel = lambda self, material: None
captured = io.StringIO()
with contextlib.redirect_stdout(captured):
    code = main(sys.argv[1:])
    kept = sys.stdout is captured
said = [line for line in captured.getvalue().splitlines() if ': wrote ' in line]
print(f'multilayer: stdout kept: {kept}, summary lines: {len(said)}', file=sys.stderr)
sys.exit(code if kept and said else 1)
"""
"""A law setting ``sys.stdout`` to None at its third call, under ``multilayer run``."""

API_PRINTING = """
import contextlib, io, multilayer
captured = io.StringIO()
with contextlib.redirect_stdout(captured):
    status = multilayer.run(sys.argv[2], sys.argv[3] + '/run').attrs['run_status']
    kept = sys.stdout is captured
count = captured.getvalue().count('loud: yield_stress')
print(f'multilayer: run {status}, host stdout kept: {kept}, its lines there: {count > 0}', file=sys.stderr)
sys.exit(0 if status == 'completed' and kept and count else 1)
"""
"""``multilayer.run`` in a host that redirected its stdout, under :data:`LOUD_RUN_PLUGIN`:
the law's lines go where the host sends its stdout (the library leaves it alone)."""


def _loud_run(kind: str) -> Callable[[Path], None]:
    """:data:`LOUD_RUN_PLUGIN` installed in ``directory/plugin``; the scenario under its law,
    for ``kind`` check with an expectation it meets, for sweep a sweep of one member."""

    def setup(directory: Path) -> None:
        law = {"name": "loudrun", "mu_s": 0.3, "nu": 0.01}
        met = {"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.01}
        _scenario(directory, {"rheology": law, **({"expect": [met]} if kind == "check" else {})})
        _plugin_package(directory, "loudrun", LOUD_RUN_PLUGIN)
        if kind == "sweep":
            (directory / "study.yaml").write_text(
                "base: scenario.yaml\nparameters:\n  rheology.mu_s: [0.3]\n"
            )

    return setup


def _linked_scenario(target: str) -> Callable[[Path], None]:
    """``scenario.yaml`` a symbolic link to ``target`` (``nothing.yaml``, or ``scenario.yaml``
    itself: a loop)."""

    def setup(directory: Path) -> None:
        (directory / "scenario.yaml").symlink_to(target)

    return setup


def _linked_bed(directory: Path) -> None:
    """A scenario whose bed is read from ``bed.csv``, a symbolic link to nothing."""
    _scenario(directory, {"bed": {"file": "bed.csv"}})
    (directory / "bed.csv").symlink_to("nothing.csv")


def _classic_result(directory: Path) -> None:
    """A finished run whose ``result.nc`` xarray wrote again as netCDF3 (``NETCDF3_CLASSIC``)."""
    _finished_run(directory)
    import xarray as xr

    path = directory / "out" / "result.nc"
    with NETCDF:
        with xr.open_dataset(path) as ds:
            loaded = ds.load()
        loaded.to_netcdf(path, format="NETCDF3_CLASSIC")


def _crlf_scenario(directory: Path) -> None:
    path = _scenario(directory)
    path.write_bytes(path.read_bytes().replace(b"\n", b"\r\n"))


def _study41(text: str) -> Callable[[Path], None]:
    """The scenario and ``study.yaml`` of ``text``."""

    def setup(directory: Path) -> None:
        _scenario(directory)
        (directory / "study.yaml").write_text(text)

    return setup


def _read_only_tmpdir(directory: Path) -> None:
    _scenario(directory)
    (directory / "tmp").mkdir()
    (directory / "tmp").chmod(0o555)


SENSITIVITY_MU_S = (
    "base: scenario.yaml\nparameters:\n  rheology.mu_s: {bounds: [0.2, 0.4]}\noutputs: [runout]\n"
)
"""A sensitivity study of the run-out to ``rheology.mu_s`` in [0.2, 0.4] (``scenario.yaml``)."""
CALIBRATION_MU_S = (
    "base: scenario.yaml\nparameters:\n  rheology.mu_s: {bounds: [0.2, 0.4]}\n"
    "observations: [{name: m, quantity: mass_final, value: 0.001, sigma: 0.001}]\n"
)
"""A calibration of ``rheology.mu_s`` in [0.2, 0.4] against the final mass (``scenario.yaml``)."""


def round_forty_one() -> list[Case]:
    """The hostile cases of the forty-first round (docs/reliability.md): a third-party law
    printing as it runs (``run``, ``check`` and a sweep's members wrote its lines into
    their stdout, which carries the summary or the report) or setting ``sys.stdout`` to
    None (``run``'s summary was a traceback); numbers where another tool's netCDF file
    holds text (a message said ``np.float64(5.0)``, or ``'3'`` of a status 3); a scenario
    file that is a symbolic link to nothing or in a loop (said "file not found" or the
    OS's "Too many levels of symbolic links"); ``multilayer.run(quiet=np.True_)``
    (refused); and, handled before, the Python API given numpy scalars, 0-d and 1-element
    arrays, huge integers, booleans, complex and read-only arrays, YAML documents, keys
    and tags of other tools, CRLF line ends, names that are paths, ``--set`` keys,
    options after ``--``, budgets and workers beyond bounds, the environment (HOME unset,
    TMPDIR read-only, COLUMNS not a number) and study files at their bounds."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    validate = ["validate", "{scenario}"]
    study = ["validate", "{dir}/study.yaml"]
    plugin_env = {"PYTHONPATH": "{dir}/plugin"}
    quiet_stdout = "its summary: True, lines of the plugin: []"
    dangling = "is a symbolic link to nothing or in a loop"
    body = yaml.safe_dump(TINY)
    load = (
        "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
        "saved = sim.state_dict()\n"
    )
    sensitivity, calibration = SENSITIVITY_MU_S, CALIBRATION_MU_S
    return [
        # a law's own prints as it runs, and a law replacing sys.stdout
        Case("run: a law printing in its yield stress and viscosity as it runs (stdout)",
             ["run", "{scenario}", "-o", "{dir}/out"], 0, quiet_stdout, patch=OWN_STDOUT, env=plugin_env,
             setup=_loud_run("run")),
        Case("sweep: a member's law printing as it runs (the workers' stdout)",
             ["sweep", "{dir}/study.yaml", "-o", "{dir}/out", "--workers", "1"], 0, quiet_stdout,
             patch=OWN_STDOUT, env=plugin_env, setup=_loud_run("sweep")),
        Case("check: a law printing as it runs (stdout)", ["check", "{scenario}"], 0, quiet_stdout,
             patch=OWN_STDOUT, env=plugin_env, setup=_loud_run("check")),
        Case("run: a law setting sys.stdout to None as it runs", ["run", "{scenario}", "-o", "{dir}/out"], 0,
             "stdout kept: True, summary lines: 1", patch=STDOUT_REPLACED, setup=_scenario),
        Case("control: multilayer.run in a host redirecting stdout, a law printing as it runs",
             ["host", "{scenario}", "{dir}"], 0, "host stdout kept: True, its lines there: True",
             patch=API_PRINTING, env=plugin_env, setup=_loud_run("run")),
        # numbers where another tool's file holds text
        Case("calibration: a netCDF observation whose units are the number 5.0",
             ["validate", "{dir}/calibration.yaml"], 2, "front.nc: x_f has units 5.0, not text",
             setup=_netcdf_observation("units a number")),
        Case("plot: result.nc whose h has units 5.0 (a number)", ["plot", "{dir}/out"], 2,
             "its variable h has units 5.0, which multilayer does not write",
             setup=_edited_result(lambda ds: ds["h"].setncattr("units", 5.0))),
        Case("export: result.nc whose time has units 7 (an int16)", ["export", "{dir}/out", "--vtk"], 2,
             "its variable time has units 7, which multilayer does not write",
             setup=_edited_result(lambda ds: ds["time"].setncattr("units", np.int16(7)))),
        Case("plot: result.nc whose run_status is the number 3", ["plot", "{dir}/out"], 2,
             "run_status 3 is not one of",
             setup=_edited_result(lambda ds: ds.setncattr("run_status", np.int32(3)))),
        Case("plot: result.nc written again by xarray as netCDF3", ["plot", "{dir}/out"], 2,
             "which multilayer does not write", setup=_classic_result),
        # symbolic links
        Case("validate: the scenario a symbolic link to nothing", validate, 2, f"scenario.yaml {dangling}",
             setup=_linked_scenario("nothing.yaml")),
        Case("run: the scenario a symbolic link to itself", run, 2, f"scenario.yaml {dangling}",
             setup=_linked_scenario("scenario.yaml")),
        Case("validate: bed.file a symbolic link to nothing", validate, 2, f"bed.csv {dangling}",
             setup=_linked_bed),
        # the Python API
        Case("API: multilayer.run(quiet=np.True_)", ["validate", "{scenario}"], 0, "",
             patch=_api("import numpy as np\n"
                        "multilayer.run(sys.argv[2], sys.argv[2] + '.out', quiet=np.True_)"),
             setup=_scenario),
        Case("API: overrides time.end np.float32(nan)", validate, 2,
             "overrides: time.end: nan is not a value",
             patch=_api("import numpy as np\nmultilayer.load(sys.argv[2], {'time.end': np.float32('nan')})"),
             setup=_scenario),
        Case("API: overrides domain.cells a 1-element array", validate, 2,
             "domain.cells (from --set): Input should be a valid integer (got [40])",
             patch=_api("import numpy as np\nmultilayer.load(sys.argv[2], {'domain.cells': np.array([40])})"),
             setup=_scenario),
        Case("API: overrides domain.cells 2**100", validate, 2,
             "domain.cells (from --set): Input should be less than or equal to 1000000000",
             patch=_api("multilayer.load(sys.argv[2], {'domain.cells': 2**100})"), setup=_scenario),
        Case("API: overrides rheology.mu_s True", validate, 2,
             "rheology.mu_s (from --set): drucker_prager: Input should be a valid number (got True)",
             patch=_api("multilayer.load(sys.argv[2], {'rheology.mu_s': True})"), setup=_scenario),
        Case("control: API overrides domain.cells a 0-d array", validate, 0, "",
             patch=_api("import numpy as np\n"
                        "loaded = multilayer.load(sys.argv[2], {'domain.cells': np.array(40)})\n"
                        "assert loaded.domain.cells == 40"),
             setup=_scenario),
        Case("API: Simulation.advance(10**400)", validate, 2, "more than 1e308 s",
             patch=_api(load + "sim.advance(10**400)"), setup=_scenario),
        Case("API: Simulation.advance(np.array([0.01]))", validate, 2, "accepted: a finite number (s)",
             patch=_api(load + "sim.advance(np.array([0.01]))"), setup=_scenario),
        Case("API: load_state of a complex h", validate, 2, "h: complex128 values of shape (40,)",
             patch=_api(load + "sim.load_state({**saved, 'h': saved['h'].astype(complex)})"),
             setup=_scenario),
        Case("API: load_state of steps 2**70", validate, 2,
             "steps = 1180591620717411303424, beyond what the simulation holds",
             patch=_api(load + "sim.load_state({**saved, 'steps': 2**70})"), setup=_scenario),
        Case("control: API load_state of read-only arrays, then a step", validate, 0, "",
             patch=_api(load + "for value in saved.values():\n    if isinstance(value, np.ndarray):\n"
                        "        value.flags.writeable = False\nsim.load_state(saved)\nsim.step()"),
             setup=_scenario),
        # YAML of other tools
        Case("validate: two YAML documents in the scenario", validate, 2, "but found another document",
             setup=partial(_scenario, text=body + "---\n" + body)),
        Case("validate: a top-level key 1", validate, 2, "(top level): key 1 is not text",
             setup=partial(_scenario, text=body + "1: 2\n")),
        Case("validate: a top-level key null", validate, 2, "(top level): key None is not text",
             setup=partial(_scenario, text=body + "~: 2\n")),
        Case("validate: a list as a key", validate, 2, "found unhashable key",
             setup=partial(_scenario, text=body + "? [a, b]\n: 2\n")),
        Case("validate: time.end !!float nan", validate, 2, "time.end (line",
             setup=partial(_scenario, text=body.replace("end: 0.2", "end: !!float nan"))),
        Case("validate: domain.cells of 23 digits", validate, 2, "domain.cells (line",
             setup=partial(_scenario, text=body.replace("cells: 40", "cells: 99999999999999999999999"))),
        Case("validate: name ../escape", validate, 2, "name (line",
             setup=partial(_scenario, text=body.replace("name: tiny", "name: ../escape"))),
        Case("validate: a name holding a newline", validate, 2, "name (line",
             setup=partial(_scenario, text=body.replace("name: tiny", 'name: "a\\nb"'))),
        Case("control: run of a scenario with CRLF line ends", run, 0, "", setup=_crlf_scenario),
        # the command line
        Case("validate: --set =1", [*validate, "--set", "=1"], 2, "--set '=1': expected KEY=VALUE",
             setup=_scenario),
        Case("validate: --set time..end=1", [*validate, "--set", "time..end=1"], 2,
             "--set 'time..end=1': expected KEY=VALUE", setup=_scenario),
        Case("run: -o after --", ["run", "{scenario}", "-q", "--", "-o", "{dir}/out"], 2,
             "unrecognized arguments: -- -o", setup=_scenario),
        Case("run: --set time.end given twice", [*run, "--set", "time.end=0.1", "--set", "time.end=0.2"],
             2, "--set time.end: replaces time.end, set before it", setup=_scenario),
        Case("run: --max-memory 1e400G", [*run, "--max-memory", "1e400G"], 2, "'1e400G' is inf bytes",
             setup=_scenario),
        Case("sweep: --workers 100000",
             ["sweep", "{dir}/study.yaml", "-o", "{dir}/out", "--workers", "100000"], 2,
             "--workers 100000: 100000 worker processes",
             setup=_study41("base: scenario.yaml\nparameters:\n  rheology.mu_s: [0.3]\n")),
        # the environment
        Case("control: HOME unset, run", run, 0, "", prefix=["env", "-u", "HOME"], plain=True,
             setup=_scenario),
        Case("control: TMPDIR read-only, multilayer.run without outdir", validate, 0, "",
             patch=_api("multilayer.run(sys.argv[2])"), env={"TMPDIR": "{dir}/tmp"}, setup=_read_only_tmpdir),
        Case("control: COLUMNS=abc, run --help", ["run", "--help"], 0, "", env={"COLUMNS": "abc"},
             plain=True),
        # study files at their bounds
        Case("validate: a sensitivity study of 0 samples", study, 2,
             "samples (line 5): Input should be greater",
             setup=_study41(sensitivity + "samples: 0\n")),
        Case("validate: a sensitivity study of true samples", study, 2,
             "samples (line 5): Input should be a valid",
             setup=_study41(sensitivity + "samples: true\n")),
        Case("validate: a sensitivity study of 2**40 samples", study, 2,
             "samples (line 5): Input should be less",
             setup=_study41(sensitivity + "samples: 1099511627776\n")),
        Case("validate: a sensitivity study of bounds [0.3, 0.3]", study, 2,
             "got [0.3, 0.3]; accepted: [lower, upper] with lower < upper",
             setup=_study41(sensitivity.replace("0.2, 0.4", "0.3, 0.3"))),
        Case("validate: a calibration of 1e9 generations", study, 2, "search.generations (line",
             setup=_study41(calibration + "search: {population: 4, generations: 1000000000}\n")),
        Case("validate: a sweep whose base is itself", study, 2, "study.yaml is this file itself",
             setup=_study41("base: study.yaml\nparameters:\n  rheology.mu_s: [0.3]\n")),
    ]  # fmt: skip


def _law42(method: str, body: str) -> str:
    """DruckerPrager's ``method`` returning what ``body`` makes of its own ``value``, on
    the numpy path (its compiled forms withdrawn); ``calls[0]`` counts the calls."""
    indented = "".join(f"    {line}\n" for line in body.strip().splitlines())
    return (
        f"real = DruckerPrager.{method}\n"
        "def fault(self, *args):\n"
        "    calls[0] += 1\n"
        "    value = real(self, *args)\n"
        f"{indented}"
        f"DruckerPrager.{method} = fault\n"
        "DruckerPrager.yield_stress_kernel = lambda self, material: None\n"
        "DruckerPrager.viscosity_kernel = lambda self, material: None\n"
    )


LAW_LAYOUTS: list[tuple[str, str, str]] = [
    ("viscosity as big-endian floats", "viscosity", "return value.astype('>f8')"),
    ("yield stress as big-endian floats", "yield_stress", "return value.astype('>f8')"),
    ("yield stress in Fortran order", "yield_stress", "return np.asfortranarray(value)"),
    ("viscosity as a strided view", "viscosity", "return np.repeat(value, 2, axis=-1)[..., ::2]"),
    ("viscosity as a nested list", "viscosity", "return np.asarray(value).tolist()"),
    ("yield stress of 5e-324", "yield_stress", "return np.full_like(value, 5e-324)"),
]
"""Valid values of a law in layouts numpy and the kernels take apart: (what, method, body of
:func:`_law42`)."""


SECOND_SIGNAL = """
import os, signal
from multilayer.io import results
close = results.ResultWriter.close
def closing(self, steps, wall_time_s, status='completed', scenario=None):
    if status == 'interrupted':
        os.kill(os.getpid(), signal.SIGTERM)
    return close(self, steps, wall_time_s, status, scenario)
results.ResultWriter.close = closing
"""
"""The second SIGTERM of a run stopping on its first: sent as the stop closes ``result.nc``."""


def _two_runs_one_mesh(cells: int) -> Callable[[Path], None]:
    """A finished run of TINY in ``out`` and a scenario of ``cells`` cells beside it."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        _scenario(directory, {"domain.cells": cells})

    return setup


def _scenario_text(edit: Callable[[str], str]) -> Callable[[Path], None]:
    """TINY's YAML text edited by ``edit``."""

    def setup(directory: Path) -> None:
        (directory / "scenario.yaml").write_text(edit(yaml.safe_dump(TINY)))

    return setup


def round_forty_two() -> list[Case]:
    """The hostile cases of the forty-second round (docs/reliability.md): initial states
    whose transport overflows the floats though their wave speeds are finite (an initial
    speed of 1e160 m/s under ``--force``; a column 1e200 m high under a gravity of 1e-200,
    which ``validate`` said ok): the first step's state held a NaN, named as "thickness h =
    nan after transport", no key; 300 000 bed points inline (each YAML text was parsed
    three times, and ``validate`` read the file twice); and, handled before, subnormal
    and edge values of the scenario's and a mixture's keys, YAML of other tools
    (``!!omap``, local and ``%TAG`` tags, a merge of a scalar, a quoted ``<<``, a document
    after ``...``, CR line ends), ``--set`` of whole sections, aliases and binary values,
    studies of degenerate parameter spaces, a resume and ``load_state`` on another mesh,
    two SIGTERMs and SIGTERM during a slow law, laws returning big-endian,
    Fortran-ordered, strided, nested-list and subnormal values or a NaN in one cell
    mid-run, the Python API given streams, bytes, ``datetime64``, ``Fraction``, sets and
    mapping proxies, and ``MULTILAYER_THREADS`` 0 and -1."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    forced = [*run, "--force"]
    validate = ["validate", "{scenario}"]
    study = ["validate", "{dir}/study.yaml"]
    body = yaml.safe_dump(TINY)
    load = "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
    mixture = {**MIXTURE}
    overflow = "the transport of the initial state overflows"
    tall = {"initial.0.height": 1e200, "gravity": 1e-200}
    sensitivity, calibration = SENSITIVITY_MU_S, CALIBRATION_MU_S
    return [
        # subnormal and overflowing scenario values
        Case("control: run of gravity 5e-324", run, 0, "",
             setup=partial(_scenario, changes={"gravity": 5e-324})),
        Case("run: rheology.nu 5e-324 (it underflows beside the yield stress)", run, 2,
             "nu must be 0 or at least 1e-30", setup=partial(_scenario, changes={"rheology.nu": 5e-324})),
        Case("control: run of rheology.mu_s 5e-324", run, 0, "",
             setup=partial(_scenario, changes={"rheology.mu_s": 5e-324})),
        Case("control: run of mu(I) grains 5e-324 m across", run, 0, "",
             setup=partial(_scenario, changes={"rheology": JOP, "material.grain_diameter": 5e-324})),
        Case("control: run of a channel 1e308 m wide",
             run, 0, "", setup=partial(_scenario, changes={"walls": {"name": "wall_friction", "mu_w": 0.2},
                                                         "domain.width": 1e308})),
        Case("validate: an initial speed of 1e160 m/s (u^2 overflows)", validate, 2, "steps",
             setup=partial(_scenario, changes={"initial.0.velocity": {"profile": "plug", "speed": 1e160}})),
        Case("run --force: an initial speed of 1e160 m/s (u^2 overflows)", forced, 2, overflow,
             setup=partial(_scenario, changes={"initial.0.velocity": {"profile": "plug", "speed": 1e160}})),
        Case("validate: a column 1e200 m high under a gravity of 1e-200 (h^2 overflows)", validate, 2,
             overflow, setup=partial(_scenario, changes=tall)),
        Case("run: a column 1e200 m high under a gravity of 1e-200 (h^2 overflows)", run, 2, overflow,
             setup=partial(_scenario, changes=tall)),
        Case("run --force: a column 1e200 m high under a gravity of 1e-200 (h^2 overflows)", forced, 2,
             overflow, setup=partial(_scenario, changes=tall)),
        Case("control: run of a column 1e100 m high under a gravity of 1e-100", run, 0, "",
             setup=partial(_scenario, changes={"initial.0.height": 1e100, "gravity": 1e-100})),
        Case("validate: time.output_interval 5e-324", validate, 2, "time.output_interval",
             setup=partial(_scenario, changes={"time.output_interval": 5e-324})),
        Case("validate: time.end 1e300 with output every 1e295 s", validate, 2, "steps",
             setup=partial(_scenario, changes={"time.end": 1e300, "time.output_interval": 1e295})),
        Case("control: run of one cell holding a layer", run, 0, "",
             setup=partial(_scenario, changes={"domain.cells": 1,
                                               "initial.0": {"shape": "layer", "thickness": 0.05}})),
        Case("run: an initial profile with points 5e-324 m apart", run, 0, "",
             setup=partial(_scenario, changes={"initial.0": {
                 "shape": "profile", "points": [[0, 0.05], [5e-324, 0.05], [0.1, 0.0]]}})),
        Case("control: run over a bed of a cliff 5e-324 m wide", run, 0, "",
             setup=partial(_scenario, changes={"bed": {"points": [[0, 0], [0.3, 0], [0.3 + 5.6e-17, 0.01],
                                                                   [0.5, 0.01]]}})),
        Case("control: run into a wall of bed 1e6 m high", run, 0, "",
             setup=partial(_scenario, changes={"bed": {
                 "points": [[0, 0], [0.25, 0], [0.26, 1e6], [0.5, 1e6]]}})),
        # a grain-fluid mixture at the edges of its keys
        Case("control: run of a mixture in a fluid of viscosity 5e-324", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "fluid.viscosity": 5e-324})),
        Case("control: run of a mixture of kozeny 5e-324", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "mixture.kozeny": 5e-324})),
        Case("validate: a mixture of no solid (phi 0)", validate, 2, "initial.0.phi",
             setup=partial(_scenario, changes={**mixture, "initial.0.phi": 0.0})),
        Case("control: run of a mixture in a fluid of density 0", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "fluid.density": 0.0})),
        Case("run: neutrally buoyant grains (fluid.density = particle_density)", run, 2,
             "is not below the grain density",
             setup=partial(_scenario, changes={**mixture, "fluid.density": 1500.0,
                                               "material.particle_density": 1500.0})),
        Case("control: run of a mixture of phi_critical 5e-324", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "mixture.phi_critical": 5e-324})),
        Case("control: run of a mixture of dilatancy 0", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "mixture.dilatancy": 0.0})),
        # YAML features of other tools
        Case("validate: a merge key of a list holding a scalar", validate, 2, "scenario.yaml",
             setup=partial(_scenario, text=body + "a: &a {b: 1}\nc: {<<: [*a, 5]}\n")),
        Case("validate: domain as an !!omap", validate, 2, "domain",
             setup=_scenario_text(lambda t: t.replace(
                 "domain:\n  cells: 40\n  layers: 3\n  x_max: 0.5\n  x_min: 0.0\n",
                 "domain: !!omap [cells: 40, layers: 3, x_max: 0.5, x_min: 0.0]\n"))),
        Case("validate: domain.cells of a local tag !cells", validate, 2, "scenario.yaml",
             setup=_scenario_text(lambda t: t.replace("cells: 40", "cells: !cells 40"))),
        Case("validate: a %TAG directive and a value of its tag", validate, 2, "scenario.yaml",
             setup=_scenario_text(lambda t: "%TAG !e! tag:example.com,2000:\n---\n"
                                  + t.replace("name: tiny", "name: !e!name tiny"))),
        Case("validate: a quoted key '<<' (no merge)", validate, 2, "<<",
             setup=partial(_scenario, text=body + '"<<": {slope_deg: 10}\n')),
        Case("control: run of a scenario of CR line ends", run, 0, "",
             setup=_scenario_text(lambda t: t.replace("\n", "\r"))),
        Case("validate: garbage after the end-of-document marker", validate, 2, "scenario.yaml",
             setup=partial(_scenario, text=body + "...\nslope_deg: 10\n")),
        # --set with unusual paths and values
        Case("validate: --set initial.0={}", [*validate, "--set", "initial.0={{}}"], 2, "initial.0",
             setup=_scenario),
        Case("validate: --set rheology.name=jop_mu_i (nu left)",
             [*validate, "--set", "rheology.name=jop_mu_i"], 2, "nu", setup=_scenario),
        Case("validate: --set domain={}", [*validate, "--set", "domain={{}}"], 2, "domain.x_min",
             setup=_scenario),
        Case("validate: --set an undefined alias", [*validate, "--set", "domain.cells=*cells"], 2, "--set",
             setup=_scenario),
        Case("validate: --set name=!!binary", [*validate, "--set", "name=!!binary aGk="], 2, "name",
             setup=_scenario),
        Case("validate: --set initial.1.height past the end", [*validate, "--set", "initial.1.height=0.1"], 2,
             "initial.1", setup=_scenario),
        # studies of degenerate parameter spaces
        Case("control: a sweep of one member of one value", ["sweep", "{dir}/study.yaml", "-o", "{dir}/out",
                                                              "--workers", "1", "-q"], 0, "",
             setup=_study41("base: scenario.yaml\nparameters:\n  rheology.mu_s: [0.3]\n")),
        Case("validate: a sweep of a value that is a mapping", study, 2, "rheology.mu_s",
             setup=_study41("base: scenario.yaml\nparameters:\n  rheology.mu_s: [{a: 1}]\n")),
        Case("validate: a sweep paired over lists of unequal lengths", study, 2, "paired",
             setup=_study41("base: scenario.yaml\npaired: true\nparameters:\n  rheology.mu_s: [0.3, 0.35]\n"
                            "  rheology.nu: [0.01, 0.02, 0.03]\n")),
        Case("validate: a sensitivity study of bounds [.nan, 0.4]", study, 2, "bounds",
             setup=_study41(sensitivity.replace("0.2, 0.4", ".nan, 0.4"))),
        Case("validate: a calibration of bounds [0.2, .inf]", study, 2, "bounds",
             setup=_study41(calibration.replace("0.2, 0.4", "0.2, .inf"))),
        Case("validate: a calibration of no parameter", study, 2, "parameters",
             setup=_study41(calibration.replace("  rheology.mu_s: {bounds: [0.2, 0.4]}\n", "").replace(
                 "parameters:\n", "parameters: {}\n"))),
        Case("validate: a sensitivity study of no output", study, 2, "outputs",
             setup=_study41(sensitivity.replace("[runout]", "[]"))),
        Case("validate: a sensitivity study of one base sample", study, 2,
             "samples (line 5): Input should be greater than or equal to 2",
             setup=_study41(sensitivity + "samples: 1\n")),
        # results and states of another scenario or mesh
        Case("run --resume: the checkpoint of a mesh of 40 cells, the scenario of 80",
             ["run", "{scenario}", "-o", "{dir}/out", "-q", "--resume"], 2, "domain.cells",
             setup=_two_runs_one_mesh(80)),
        Case("control: validate of 300 000 bed points inline (4.6 MiB of YAML)", validate, 0, "",
             setup=_scenario_text(lambda t: t + "bed: {points: [" + ",".join(
                 f"[{0.5 * i / 299999:.9f},0]" for i in range(300000)) + "]}\n")),
        Case("API: load_state of a state of 80 cells into one of 40", validate, 2,
             "h: float64 values of shape",
             patch=_api(load + "finer = multilayer.load(sys.argv[2], {'domain.cells': 80})\n"
                        "sim.load_state(multilayer.Simulation(finer).state_dict())"), setup=_scenario),
        # signals
        Case("run: SIGTERM, a second SIGTERM as result.nc is closed", run, 143, "SIGTERM", keeps_output=True,
             patch=SECOND_SIGNAL + PACED, signal_after_output=signal.SIGTERM, setup=_scenario),
        Case("run: SIGTERM while a slow law runs", run, 143, "SIGTERM", keeps_output=True,
             patch=_law42("yield_stress", "time.sleep(0.01)\nreturn value"),
             signal_after_output=signal.SIGTERM, setup=_scenario),
        # third-party laws returning numbers in unusual layouts
        *(Case(f"control: a law's {what}", run, 0, "", patch=_law42(method, body), setup=_scenario)
          for what, method, body in LAW_LAYOUTS),
        Case("run: a law's viscosity of -0.0 with no yield stress", run, 0, "",
             patch=_law42("viscosity", "return np.full_like(value, -0.0)")
             + _law42("yield_stress", "return np.zeros_like(value)").replace("real =", "real2 =").replace(
                 "real(self", "real2(self"), setup=_scenario),
        Case("run: a law's yield stress NaN in one cell of one interface mid-run", run, 1,
             "yield_stress() returned nan", keeps_output=True,
             patch=_law42("yield_stress", "value = np.array(value, dtype=float)\n"
                          "if calls[0] > 30:\n    value.flat[value.size // 2] = np.nan\nreturn value"),
             setup=_scenario),
        # the Python API given unusual types
        Case("API: multilayer.load of an open text stream", validate, 2, "scenario: got",
             patch=_api("import io\nmultilayer.load(io.StringIO(open(sys.argv[2]).read()))"),
             setup=_scenario),
        Case("API: multilayer.load of a bytes path", validate, 2, "scenario: got",
             patch=_api("multilayer.load(sys.argv[2].encode())"), setup=_scenario),
        Case("API: multilayer.run(outdir=42)", validate, 2, "outdir: got 42",
             patch=_api("multilayer.run(sys.argv[2], 42)"), setup=_scenario),
        Case("API: Simulation.step(t_max=np.datetime64)", validate, 2, "t_max",
             patch=_api(load + "sim.step(np.datetime64('2020-01-01'))"), setup=_scenario),
        Case("control: API Simulation.advance(Fraction(1, 100))", validate, 0, "",
             patch=_api(load + "from fractions import Fraction\nsim.advance(Fraction(1, 100))\n"
                        "assert type(sim.t) is float, type(sim.t)"), setup=_scenario),
        Case("API: load of a mapping whose initial is a set", validate, 2, "initial",
             patch=_api("import yaml\ndata = yaml.safe_load(open(sys.argv[2]))\n"
                        "data['initial'] = {frozenset(data['initial'][0].items())}\nmultilayer.load(data)"),
             setup=_scenario),
        Case("control: API load of a mapping proxy with numpy str keys", validate, 0, "",
             patch=_api("import types, yaml\nimport numpy as np\ndata = yaml.safe_load(open(sys.argv[2]))\n"
                        "data = {np.str_(k): v for k, v in data.items()}\n"
                        "multilayer.load(types.MappingProxyType(data))"), setup=_scenario),
        # the environment
        Case("run: MULTILAYER_THREADS=0", run, 2, "MULTILAYER_THREADS", env={"MULTILAYER_THREADS": "0"},
             setup=_scenario),
        Case("run: MULTILAYER_THREADS=-1", run, 2, "MULTILAYER_THREADS", env={"MULTILAYER_THREADS": "-1"},
             setup=_scenario),
    ]  # fmt: skip


TALL43 = {"initial.0.height": 1000.0, "model": {"pressure": "non_hydrostatic"}}
"""TINY's column 1000 m high on its cells 0.0125 m wide, under the non-hydrostatic pressure."""


def _law43(method: str, body: str) -> str:
    """DruckerPrager's ``method`` running ``body`` (its arguments ``args``, its own value
    ``value``, ``calls[0]`` its calls so far) on the numpy path: :func:`_law42` with the
    arguments named."""
    return _law42(method, body).replace(
        "def fault(self, *args):", "def fault(self, *args):\n    args = list(args)"
    )


def _raising(exception: str) -> str:
    """A yield stress raising ``exception`` (an expression) at its 31st call."""
    return _law43("yield_stress", f"if calls[0] > 30:\n    raise {exception}\nreturn value")


STRANGE_ERROR = """
class Strange(Exception):
    def __str__(self):
        raise ValueError('no text')
"""
"""An exception whose text cannot be made."""


def _out_entry(name: str, kind: str) -> Callable[[Path], None]:
    """A finished run in ``out`` whose entry ``name`` is replaced by a FIFO, a directory, a
    link to ``/dev/zero`` or a link to itself (``kind``)."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        path = directory / "out" / name
        path.unlink(missing_ok=True)
        if kind == "fifo":
            os.mkfifo(path)
        elif kind == "directory":
            path.mkdir()
        elif kind == "zero":
            path.symlink_to("/dev/zero")
        else:
            path.symlink_to(path.name)

    return setup


def _older_checkpoint(directory: Path) -> None:
    """A finished run whose checkpoint's entries lost their ``state.``/``meta.`` prefix, as
    an older layout might have written them."""
    _finished_run(directory)
    path = directory / "out" / "checkpoint.npz"
    with np.load(path) as saved:
        entries = {key.split(".", 1)[-1]: saved[key] for key in saved.files}
    with path.open("wb") as stream:
        np.savez(stream, **entries)


HOLD_OPEN = """
import sys, time, netCDF4
ds = netCDF4.Dataset(sys.argv[1], 'a')
open(sys.argv[2], 'w').close()
time.sleep(40)
"""
"""Another tool holding ``result.nc`` open for writing (HDF5's lock on it) for 40 s."""


def _held_open(directory: Path, mode: str = "a") -> None:
    """A finished run whose ``result.nc`` another process holds open for writing (``mode``
    ``a``; ``r``: for reading)."""
    _finished_run(directory)
    marker = directory / "opened"
    subprocess.Popen(
        [
            sys.executable,
            "-c",
            HOLD_OPEN.replace("'a'", repr(mode)),
            str(directory / "out" / "result.nc"),
            str(marker),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    deadline = time.monotonic() + 60
    while not marker.exists() and time.monotonic() < deadline:
        time.sleep(0.05)


def _inline_bed(points: int) -> Callable[[Path], None]:
    """TINY over a flat bed of ``points`` points given inline."""
    return _scenario_text(
        lambda t: (
            t
            + "bed: {points: ["
            + ",".join(f"[{0.5 * i / (points - 1):.9f},0]" for i in range(points))
            + "]}\n"
        )
    )


def round_forty_three() -> list[Case]:
    """The hostile cases of the forty-third round (docs/reliability.md): columns 300 and
    1000 m high on cells of 0.125 and 0.0125 m under the non-hydrostatic pressure (its bound
    ``p >= 0`` not settled: the message named the solver only), a law raising an exception
    holding a lone surrogate (a traceback as the result was closed) or setting
    ``sys.stderr`` to None (no message); and, handled before, a run of an inline bed of
    150 000 points, laws raising ``RecursionError``, ``MemoryError``, ``StopIteration``, an
    exception whose text cannot be made, of a megabyte or of newlines and escapes,
    returning masked, complex, boolean, half-precision, read-only or matrix values, a wrong
    shape on some calls only or their own argument, writing into their arguments or setting
    the environment; mixtures with walls, a gate, periodic sides, one layer, the normal
    stress and the non-hydrostatic pressure; ``PYTHONWARNINGS=error``,
    ``PYTHONOPTIMIZE=2``, ``OMP_NUM_THREADS=0``, ``NUMBA_NUM_THREADS`` below
    ``numerics.threads``, ``MULTILAYER_INSTITUTION`` of non-UTF-8 bytes or 100 000
    characters; a run's entries (result, checkpoint, log, lock, plots, vtk) replaced by
    FIFOs, directories, files, links to ``/dev/zero`` or to themselves, a result held open
    by another writer, a checkpoint of an older layout; and sweeps and studies of a
    repeated name, of equal values and of integer keys."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    resume = [*run, "--resume"]
    validate = ["validate", "{scenario}"]
    plot = ["plot", "{dir}/out"]
    export = ["export", "{dir}/out"]
    sweep = ["sweep", "{dir}/study.yaml", "-o", "{dir}/study", "--workers", "1", "-q"]
    mixture = {**MIXTURE}
    tall = {**TALL43}
    settle = "accepted: model.pressure_layers: 1"
    read_only = "yield_stress() raised ValueError: assignment destination is read-only"
    return [
        # a tall narrow column under the non-hydrostatic pressure
        Case("control: validate of a column 1000 m high on cells 0.0125 m wide, non-hydrostatic", validate,
             0, "", setup=partial(_scenario, changes=tall)),
        Case("run: a column 1000 m high on cells 0.0125 m wide, non-hydrostatic", run, 1, settle,
             keeps_output=True, setup=partial(_scenario, changes=tall)),
        Case("run: a column 1000 m high in five layers, non-hydrostatic (its first step)", run, 1,
             "each layer 2e+04 cells thick", setup=partial(_scenario, changes={**tall, "domain.layers": 5})),
        Case("control: run of a column 1000 m high on one pressure layer", run, 0, "",
             setup=partial(_scenario, changes={**tall, "model": {"pressure": "non_hydrostatic",
                                                                 "pressure_layers": 1}})),
        Case("run: a column 300 m high on four cells 0.125 m wide, non-hydrostatic", run, 1, settle,
             keeps_output=True, setup=partial(_scenario, changes={
                 **tall, "initial.0.height": 300.0, "domain.cells": 4, "initial.0.x_max": 0.25})),
        Case("control: run over 150 000 bed points inline", run, 0, "", setup=_inline_bed(150000)),
        # laws failing in new ways
        Case("run: a law raising RecursionError mid-run", run, 1, "yield_stress() raised RecursionError",
             keeps_output=True, patch=_raising("RecursionError('deep')"), setup=_scenario),
        Case("run: a law raising MemoryError mid-run", run, 1, "yield_stress() raised MemoryError",
             keeps_output=True, patch=_raising("MemoryError()"), setup=_scenario),
        Case("run: a law raising StopIteration mid-run", run, 1, "yield_stress() raised StopIteration",
             keeps_output=True, patch=_raising("StopIteration"), setup=_scenario),
        Case("run: a law raising an exception whose text cannot be made", run, 1,
             "yield_stress() raised Strange",
             keeps_output=True, patch=STRANGE_ERROR + _raising("Strange()"), setup=_scenario),
        Case("run: a law raising an exception holding a lone surrogate", run, 1,
             "yield_stress() raised ValueError", keeps_output=True,
             patch=_raising("ValueError('bad \\ud800 text')"), setup=_scenario),
        Case("run: a law raising an exception of a megabyte of text", run, 1,
             "yield_stress() raised ValueError",
             keeps_output=True, one_message=True, patch=_raising("ValueError('x' * 2**20)"), setup=_scenario),
        Case("run: a law raising an exception holding newlines and escapes", run, 1,
             "raised ValueError: a\\nb\\x1b[2Jc", keeps_output=True,
             patch=_raising("ValueError('a\\nb\\x1b[2Jc')"), setup=_scenario),
        Case("run: a law's viscosity of a wrong shape on every seventh call", run, 1,
             "viscosity() returned an array of shape", keeps_output=True,
             patch=_law43("viscosity", "value = np.asarray(value)\n"
                          "return value[..., :-1] if calls[0] % 7 == 0 and calls[0] > 20 else value"),
             setup=_scenario),
        Case("run: a law's yield stress as a masked array, one cell masked", run, 1,
             "yield_stress() returned",
             keeps_output=True,
             patch=_law43("yield_stress", "value = np.ma.masked_array(np.asarray(value, float))\n"
                          "if calls[0] > 30:\n    value[..., 0] = np.ma.masked\nreturn value"),
             setup=_scenario),
        Case("run: a law's yield stress of complex numbers", run, 1, "yield_stress() returned",
             keeps_output=True, patch=_law43("yield_stress", "return np.asarray(value) + 0j"),
             setup=_scenario),
        Case("run: a law's viscosity of booleans", run, 1, "viscosity() returned",
             patch=_law43("viscosity", "return np.asarray(value) > 0"), setup=_scenario),
        Case("control: a law's yield stress in half precision", run, 0, "",
             patch=_law43("yield_stress", "return np.asarray(value).astype(np.float16)"), setup=_scenario),
        Case("control: a law's viscosity read-only", run, 0, "",
             patch=_law43("viscosity", "value = np.array(value)\nvalue.setflags(write=False)\nreturn value"),
             setup=_scenario),
        Case("run: a law's yield stress as an np.matrix", run, 1, "yield_stress() returned",
             patch=_law43("yield_stress", "import warnings\nwarnings.simplefilter('ignore')\n"
                          "return np.asmatrix(np.asarray(value).reshape(1, -1))"), setup=_scenario),
        Case("control: a law's yield stress returning its pressure argument itself", run, 0, "",
             patch=_law43("yield_stress", "return args[0]"), setup=_scenario),
        Case("run: a law writing NaN into its pressure argument after its answer", run, 1, read_only,
             patch=_law43("yield_stress", "value = np.array(value)\nargs[0][...] = np.nan\nreturn value"),
             setup=_scenario),
        Case("run: a law writing NaN into its shear-rate argument after its answer", run, 1,
             read_only.replace("yield_stress", "viscosity"),
             patch=_law43("viscosity", "value = np.array(value)\nargs[0][...] = np.nan\nreturn value"),
             setup=_scenario),
        Case("run: a law setting sys.stderr to None, then failing", run, 1,
             "yield_stress() raised ValueError",
             patch=_law43("yield_stress", "if calls[0] > 30:\n    sys.stderr = None\n"
                          "    raise ValueError('late')\nreturn value"), setup=_scenario),
        Case("control: a law setting MULTILAYER_THREADS=0 mid-run", run, 0, "",
             patch=_law43("yield_stress", "os.environ['MULTILAYER_THREADS'] = '0'\nreturn value").replace(
                 "real =", "import os\nreal ="), setup=_scenario),
        # a grain-fluid mixture with the other options
        Case("validate: a mixture under the non-hydrostatic pressure", validate, 2, "model.pressure",
             setup=partial(_scenario, changes={**mixture, "model": {"pressure": "non_hydrostatic"}})),
        Case("validate: a mixture with the normal stress", validate, 2, "model.normal_stress",
             setup=partial(_scenario, changes={**mixture, "model": {"normal_stress": True}})),
        Case("validate: a mixture between walls", validate, 2, "walls",
             setup=partial(_scenario, changes={**mixture, "walls": {"name": "wall_friction", "mu_w": 0.2},
                                               "domain.width": 0.1})),
        Case("validate: a mixture behind a gate", validate, 2, "gate",
             setup=partial(_scenario, changes={**mixture, "gate": {"x": 0.1, "lift_speed": 1.0}})),
        Case("control: run of a mixture between periodic sides", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "boundaries": {"left": "periodic",
                                                                         "right": "periodic"}})),
        Case("control: run of a compressible mixture in one layer", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "domain.layers": 1,
                                               "fluid.compressibility": 1e-3})),
        Case("control: run of a compressible mixture over a bed of points", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "fluid.compressibility": 1e-3, "bed": {
                 "points": [[0, 0.02], [0.25, 0.0], [0.5, 0.0]]}})),
        Case("control: run of a mixture of dilatancy 0 under mu(I)", run, 0, "",
             setup=partial(_scenario, changes={**mixture, "mixture.dilatancy": 0.0, "rheology": JOP})),
        # the environment
        Case("control: PYTHONWARNINGS=error, a run", run, 0, "", env={"PYTHONWARNINGS": "error"}, plain=True,
             setup=_scenario),
        Case("control: PYTHONOPTIMIZE=2, run --help", ["run", "--help"], 0, "", env={"PYTHONOPTIMIZE": "2"},
             plain=True),
        Case("validate: PYTHONOPTIMIZE=2, a bad key", [*validate, "--set", "domain.cells=0"], 2,
             "domain.cells", env={"PYTHONOPTIMIZE": "2"}, plain=True, setup=_scenario),
        Case("control: OMP_NUM_THREADS=0, a run", run, 0, "", env={"OMP_NUM_THREADS": "0"}, plain=True,
             setup=_scenario),
        Case("control: NUMBA_NUM_THREADS=1 below numerics.threads 2 (the cap)",
             [*run, "--set", "numerics.threads=2"], 0, "", env={"NUMBA_NUM_THREADS": "1"}, plain=True,
             setup=_scenario),
        Case("control: MULTILAYER_INSTITUTION of non-UTF-8 bytes", run, 0, "",
             env={"MULTILAYER_INSTITUTION": "lab \udcff"}, setup=_scenario),
        Case("control: MULTILAYER_INSTITUTION of 100 000 characters", run, 0, "",
             env={"MULTILAYER_INSTITUTION": "x" * 100_000}, setup=_scenario),
        # a run's files replaced by what they are not
        Case("plot: result.nc a FIFO", plot, 2, "result.nc", setup=_out_entry("result.nc", "fifo")),
        Case("export --vtk: result.nc a FIFO", [*export, "--vtk"], 2, "result.nc",
             setup=_out_entry("result.nc", "fifo")),
        Case("plot: result.nc a link to /dev/zero", plot, 2, "result.nc",
             setup=_out_entry("result.nc", "zero")),
        Case("plot: result.nc a link to itself", plot, 2, "result.nc", setup=_out_entry("result.nc", "self")),
        Case("run --resume: checkpoint.npz a FIFO", resume, 2, "checkpoint.npz",
             setup=_out_entry("checkpoint.npz", "fifo")),
        Case("run --resume: checkpoint.npz a link to /dev/zero", resume, 2, "checkpoint.npz",
             setup=_out_entry("checkpoint.npz", "zero")),
        Case("run --resume: checkpoint.npz of an older layout", resume, 2, "checkpoint.npz",
             setup=_older_checkpoint),
        Case("run: run.log a directory", run, 2, "run.log", setup=_out_entry("run.log", "directory")),
        Case("run: run.log a FIFO", run, 2, "run.log", setup=_out_entry("run.log", "fifo")),
        Case("run: run.log a link to itself", run, 2, "run.log", setup=_out_entry("run.log", "self")),
        Case("run: run.lock a directory", run, 2, "run.lock", setup=_out_entry("run.lock", "directory")),
        Case("control: run over a run.lock that is a FIFO (no lock: taken)", run, 0, "",
             setup=_out_entry("run.lock", "fifo")),
        Case("run: result.nc a directory", run, 2, "result.nc", setup=_out_entry("result.nc", "directory")),
        Case("plot: plots a file", plot, 2, "plots", setup=_made_file43("plots")),
        Case("export --vtk: vtk a file", [*export, "--vtk"], 2, "vtk", setup=_made_file43("vtk")),
        Case("control: plot of a result.nc another process holds open for writing", plot, 0, "",
             setup=_held_open),
        # studies
        Case("validate: a sweep of one name twice", ["validate", "{dir}/study.yaml"], 2, "name",
             setup=_sweep33("parameters:\n  name: [a, a]\n")),
        Case("sweep: of one name twice", sweep, 2, "name", setup=_sweep33("parameters:\n  name: [a, a]\n")),
        Case("validate: a sensitivity study of domain.cells", ["validate", "{dir}/study.yaml"], 2,
             "domain.cells",
             setup=_study41(SENSITIVITY_MU_S.replace("rheology.mu_s: {bounds: [0.2, 0.4]}",
                                                      "domain.cells: {bounds: [20, 80]}"))),
        Case("validate: a calibration of domain.layers", ["validate", "{dir}/study.yaml"], 2, "domain.layers",
             setup=_study41(CALIBRATION_MU_S.replace("rheology.mu_s: {bounds: [0.2, 0.4]}",
                                                      "domain.layers: {bounds: [1, 4]}"))),
        Case("validate: a sweep of cells 40 and 40.0", ["validate", "{dir}/study.yaml"], 2, "domain.cells",
             setup=_sweep33("parameters:\n  domain.cells: [40, 40.0]\n")),
    ]  # fmt: skip


def _made_file43(name: str) -> Callable[[Path], None]:
    """A finished run in ``out`` beside a file ``name`` where a command writes a directory."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        (directory / "out" / name).write_text("a file\n")

    return setup


def _result_with_a_text_variable(directory: Path) -> None:
    """A finished run whose result.nc also holds another tool's variable of characters
    over ``x``."""
    _finished_run(directory)
    import netCDF4

    with NETCDF, netCDF4.Dataset(directory / "out" / "result.nc", "a") as ds:
        ds.createDimension("nchar", 4)
        ds.createVariable("label", "S1", ("x", "nchar"))[0] = netCDF4.stringtochar(np.array(["text"], "S4"))


def _optimized_run(directory: Path) -> None:
    """A run under ``python -OO`` into ``first``: the first after the kernels changed
    compiles about twenty of them again (docs/reliability.md, round 44), beyond a case's
    time on a busy machine; the case's own run is the next one."""
    subprocess.run(
        [
            sys.executable,
            "-OO",
            "-m",
            "multilayer",
            "run",
            str(_scenario(directory)),
            "-o",
            str(directory / "first"),
            "-q",
        ],
        check=True,
        capture_output=True,
    )


ON_STEP = "import numpy as np\nsim = multilayer.Simulation(multilayer.load(sys.argv[2]))\n"
"""The start of a Python API case: a simulation of the case's scenario."""


def _yaml44(edit: Callable[[str], str]) -> Callable[[Path], None]:
    """TINY's YAML text edited by ``edit`` (:func:`_scenario_text`), written as bytes."""

    def setup(directory: Path) -> None:
        (directory / "scenario.yaml").write_bytes(edit(yaml.safe_dump(TINY)).encode())

    return setup


def round_forty_four() -> list[Case]:
    """The hostile cases of the forty-fourth round (docs/reliability.md): a run resumed
    into, or run over, a result another process holds open for writing (exit 0: the classic
    netCDF format takes no lock), a law's message holding a line feed (two lines), a
    domain 5e-324 m long (a traceback), an ``on_step`` stepping the simulation (``advance``
    went past its target), a run under ``PYTHONOPTIMIZE=2`` (its first compiles kernels
    again); and, handled before, YAML merge keys, Python and timestamp tags, integers of
    5000 digits, hexadecimal, octal and tagged numbers, NaN spellings, a nested key twice, a
    byte order mark, tabs, a ``%YAML 1.3`` directive; values at the ends of the floats;
    ``--set`` of tags, negative indices and spaced keys; sweeps of sets, NaN and merges;
    ``load_state`` of views and impossible times; a subclass stepping twice; ``TMPDIR``
    missing, a Turkish locale, an ASCII-only stderr, an unknown ``TZ``; and laws setting
    warnings to errors, the recursion limit, threads, their own parameters, or returning
    subclasses, long doubles, 0-d arrays, DataFrames and memory maps."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    resume = ["run", "{scenario}", "-o", "{dir}/out", "-q", "--resume", "--set", "time.end=0.3"]
    validate = ["validate", "{scenario}"]
    plot = ["plot", "{dir}/out"]
    body = yaml.safe_dump(TINY)
    cells = lambda value: _yaml44(lambda t: t.replace("cells: 40", f"cells: {value}"))  # noqa: E731
    sweep = ["validate", "{dir}/study.yaml"]
    return [
        # YAML of other tools and of YAML 1.1
        Case("validate: a key merged from the domain's anchor into an unknown key", validate, 2,
             "other (line",
             setup=_yaml44(lambda t: t.replace("domain:\n", "domain: &d\n") + "other: {<<: *d, cells: 0}\n")),
        Case("validate: domain merged from an anchor, cells overridden to 0", validate, 2, "domain.cells",
             setup=partial(_scenario, text=body.replace("domain:\n  cells: 40\n  layers: 3\n  x_max: 0.5\n"
                                                        "  x_min: 0.0\n",
                                                        "domain:\n  <<: &d {cells: 40, layers: 3,"
                                                        " x_max: 0.5, x_min: 0.0}\n  cells: 0\n"))),
        Case("control: domain merged from two anchors", validate, 0, "",
             setup=partial(_scenario, text=body.replace("domain:\n  cells: 40\n  layers: 3\n  x_max: 0.5\n"
                                                        "  x_min: 0.0\n",
                                                        "domain:\n  <<: [{cells: 40, layers: 3},"
                                                        " {x_max: 0.5, x_min: 0.0}]\n"))),
        Case("validate: name as !!python/name:os.system", validate, 2, "scenario.yaml",
             setup=_yaml44(lambda t: t.replace("name: tiny", "name: !!python/name:os.system ''"))),
        Case("validate: time.end as !!timestamp", validate, 2, "time.end",
             setup=_yaml44(lambda t: t.replace("end: 0.2", "end: !!timestamp 2001-12-14"))),
        Case("validate: time.end as a plain date", validate, 2, "time.end",
             setup=_yaml44(lambda t: t.replace("end: 0.2", "end: 2001-12-14"))),
        Case("validate: domain.cells of 5000 digits", validate, 2, "scenario.yaml (line 5",
             setup=cells("4" * 5000)),
        Case("validate: domain.cells !!int of 5000 digits", validate, 2, "scenario.yaml (line 5",
             setup=cells("!!int " + "4" * 5000)),
        Case("control: domain.cells 0x28 (YAML 1.2 hexadecimal)", validate, 0, "", setup=cells("0x28")),
        Case("control: domain.cells 0o50 (YAML 1.2 octal)", validate, 0, "", setup=cells("0o50")),
        Case("validate: domain.cells !!str 40", validate, 2, "domain.cells", setup=cells("!!str 40")),
        Case("validate: domain.cells !!float 40", validate, 2, "domain.cells", setup=cells("!!float 40")),
        Case("validate: gravity .NaN", validate, 2, "gravity",
             setup=_scenario_text(lambda t: t + "gravity: .NaN\n")),
        Case("validate: gravity NaN (text in YAML 1.2)", validate, 2, "gravity",
             setup=_scenario_text(lambda t: t + "gravity: NaN\n")),
        Case("validate: time.end +.inf", validate, 2, "time.end",
             setup=_yaml44(lambda t: t.replace("end: 0.2", "end: +.inf"))),
        Case("validate: a key twice in a nested mapping", validate, 2, "cells",
             setup=_yaml44(lambda t: t.replace("cells: 40", "cells: 40\n  cells: 80"))),
        Case("control: a byte order mark and CRLF line ends", run, 0, "",
             setup=_yaml44(lambda t: "\ufeff" + t.replace("\n", "\r\n"))),
        Case("validate: a tab indenting a key", validate, 2, "scenario.yaml",
             setup=_yaml44(lambda t: t.replace("  cells: 40", "\tcells: 40"))),
        Case("validate: a %YAML 1.3 directive", validate, 2, "scenario.yaml",
             setup=_yaml44(lambda t: "%YAML 1.3\n---\n" + t)),
        Case("validate: name !!null", validate, 2, "name", setup=_yaml44(lambda t: t.replace("name: tiny",
             "name: !!null"))),
        # scenario values at the ends of the floats
        Case("run: material.density 1.7976931348623157e308", run, 2, "material.density",
             setup=partial(_scenario, changes={"material.density": 1.7976931348623157e308})),
        Case("run: gravity 1.7976931348623157e308", run, 2, "gravity",
             setup=partial(_scenario, changes={"gravity": 1.7976931348623157e308})),
        Case("control: run on a slope of 89.99999999999999 degrees", run, 0, "",
             setup=partial(_scenario, changes={"slope_deg": 89.99999999999999})),
        Case("validate: a domain from -1.79e308 to 1.79e308 m", validate, 2, "domain",
             setup=partial(_scenario, changes={"domain.x_min": -1.7976931348623157e308,
                                               "domain.x_max": 1.7976931348623157e308})),
        Case("validate: a domain 5e-324 m long", validate, 2, "domain.cells",
             setup=partial(_scenario, changes={"domain.x_max": 5e-324})),
        Case("run: rheology.nu 1.7976931348623157e308", run, 2, "nu must be at most",
             setup=partial(_scenario, changes={"rheology.nu": 1.7976931348623157e308})),
        Case("run: rheology.mu_s 1.7976931348623157e308", run, 2, "mu_s must be at most",
             setup=partial(_scenario, changes={"rheology.mu_s": 1.7976931348623157e308})),
        Case("validate: time.cfl 5e-324", validate, 2, "time.cfl",
             setup=partial(_scenario, changes={"time.cfl": 5e-324})),
        Case("run: numerics.tolerance 5e-324 under mu(I)", run, 2, "numerics.tolerance",
             setup=partial(_scenario, changes={"rheology": JOP, "numerics": {"tolerance": 5e-324}})),
        Case("validate: initial height 1.7976931348623157e308", validate, 2, "initial.0 (rectangle",
             setup=partial(_scenario, changes={"initial.0.height": 1.7976931348623157e308})),
        # --set with odd values
        Case("validate: --set domain.cells=0x28", [*validate, "--set", "domain.cells=0x28"], 0, "",
             setup=_scenario),
        Case("validate: --set a !!python/object/apply value", [*validate, "--set",
             "rheology=!!python/object/apply:os.system [echo]"], 2, "--set rheology", setup=_scenario),
        Case("validate: --set initial.-1.height", [*validate, "--set", "initial.-1.height=0.1"], 2,
             "initial.-1",
             setup=_scenario),
        Case("validate: --set ' time.end '=0 (spaces around the key)", [*validate, "--set", " time.end =0"],
             2,
             "time.end (from --set)", setup=_scenario),
        Case("validate: --set time=null", [*validate, "--set", "time=null"], 2, "time", setup=_scenario),
        Case("validate: --set domain.cells of 5000 digits", [*validate, "--set",
             "domain.cells=" + "7" * 5000], 2,
             "domain.cells", setup=_scenario),
        # studies of hostile content
        Case("validate: a sweep of a !!set of values", sweep, 2, "rheology.mu_s",
             setup=_study41("base: scenario.yaml\nparameters:\n  rheology.mu_s: !!set {0.3: null}\n")),
        Case("validate: a sweep of .nan", sweep, 2, "rheology.mu_s",
             setup=_study41("base: scenario.yaml\nparameters:\n  rheology.mu_s: [0.3, .nan]\n")),
        Case("control: a sweep whose parameters are merged from two mappings", sweep, 0, "",
             setup=_study41("base: scenario.yaml\nparameters: {<<: [{rheology.mu_s: [0.3]},"
                            " {rheology.nu: [0.01]}]}\n")),
        # result files of other tools
        Case("control: plot of a result.nc holding a variable of characters", plot, 0, "",
             setup=_result_with_a_text_variable),
        Case("run --resume: result.nc held open for writing by another process", resume, 2,
             "result.nc: open for writing by another process", setup=_held_open),
        Case("run: over a result.nc held open for writing by another process", run, 2,
             "result.nc: open for writing by another process", setup=_held_open),
        Case("control: run --resume, result.nc held open for reading by another process", resume, 0, "",
             setup=partial(_held_open, mode="r")),
        # the Python API misused
        Case("API: on_step calling step() itself", validate, 2, "from the on_step of advance",
             patch=_api(ON_STEP + "sim.advance(0.05, on_step=lambda s, dt: s.step())\n"
                        "assert sim.t <= 0.05 + 1e-12, sim.t"), setup=_scenario),
        Case("API: on_step calling advance() past the target", validate, 2, "from the on_step of advance",
             patch=_api(ON_STEP + "sim.advance(0.05, on_step=lambda s, dt: s.advance(0.1) if s.t < 0.05 "
                        "else None)"), setup=_scenario),
        Case("control: API load_state of Fortran-ordered and reversed views", validate, 0, "",
             patch=_api(ON_STEP + "sim.advance(0.02)\nsaved = sim.state_dict()\n"
                        "odd = {k: (np.asfortranarray(v)[:, ::-1][:, ::-1] if getattr(v, 'ndim', 0) == 2"
                        " else v)"
                        " for k, v in saved.items()}\nsim.load_state(odd)\nsim.advance(0.04)"),
                        setup=_scenario),
        Case("API: load_state of h as a 0-d array", validate, 2, "h",
             patch=_api(ON_STEP + "saved = sim.state_dict()\nsaved['h'] = np.array(0.01)\n"
                        "sim.load_state(saved)"),
             setup=_scenario),
        Case("API: load_state of t = -1", validate, 2, "t",
             patch=_api(ON_STEP + "saved = sim.state_dict()\nsaved['t'] = -1.0\nsim.load_state(saved)"),
             setup=_scenario),
        Case("API: load_state of steps = -5", validate, 2, "steps",
             patch=_api(ON_STEP + "saved = sim.state_dict()\nsaved['steps'] = -5\nsim.load_state(saved)"),
             setup=_scenario),
        Case("API: a subclass of Simulation stepping twice per step", validate, 2, "step(t_max=0.05)",
             patch=_api("class Twice(multilayer.Simulation):\n    def step(self, t_max=float('inf')):\n"
                        "        super().step(t_max)\n        return super().step(t_max)\n"
                        "sim = Twice(multilayer.load(sys.argv[2]))\nsim.advance(0.05)\nassert sim.t == 0.05"),
             setup=_scenario),
        # the environment
        Case("control: TMPDIR a directory that does not exist, multilayer.run", validate, 0, "",
             env={"TMPDIR": "{dir}/missing"}, patch=_api("multilayer.run(sys.argv[2], quiet=True)"),
             setup=_scenario),
        Case("control: LANG=tr_TR.UTF-8 (a dotless i), run", run, 0, "", env={"LANG": "tr_TR.UTF-8",
             "LC_ALL": "tr_TR.UTF-8"}, plain=True, setup=_scenario),
        Case("validate: PYTHONIOENCODING=ascii:strict, a message quoting a non-ASCII value", validate, 2,
             "rheology.name", env={"PYTHONIOENCODING": "ascii:strict"}, plain=True,
             setup=partial(_scenario, changes={"rheology.name": "dr\u00fccker"})),
        Case("control: TZ of no zone, run", run, 0, "", env={"TZ": "No/Such_Zone"}, plain=True,
             setup=_scenario),
        Case("control: PYTHONOPTIMIZE=2, a run after a first one", run, 0, "", env={"PYTHONOPTIMIZE": "2"},
             plain=True, setup=_optimized_run),
        # rheology laws doing odd things
        Case("run: a law setting warnings to errors", run, 0, "",
             patch=_law43("yield_stress", "import warnings\nwarnings.simplefilter('error')\nreturn value"),
             setup=_scenario),
        Case("run: a law lowering the recursion limit to 60", run, 0, "",
             patch=_law43("yield_stress", "sys.setrecursionlimit(60)\nreturn value"), setup=_scenario),
        Case("control: a law starting a daemon thread at each call", run, 0, "",
             patch=_law43("yield_stress",
             "import threading\nthreading.Thread(target=time.sleep, args=(0.01,), "
                          "daemon=True).start()\nreturn value"), setup=_scenario),
        Case("control: a law's yield stress as an ndarray subclass", run, 0, "",
             patch="class Sub(np.ndarray):\n    pass\n"
             + _law43("yield_stress", "return np.asarray(value).view(Sub)"), setup=_scenario),
        Case("control: a law's viscosity in long double", run, 0, "",
             patch=_law43("viscosity", "return np.asarray(value).astype(np.longdouble)"), setup=_scenario),
        Case("run: a law's yield stress as a 0-d array", run, 1, "yield_stress() returned",
             patch=_law43("yield_stress", "return np.asarray(np.asarray(value).flat[0])"), setup=_scenario),
        Case("run: a law's viscosity as a pandas DataFrame", run, 0, "",
             patch=_law43("viscosity", "import pandas\nreturn pandas.DataFrame(np.atleast_2d(value))"),
             setup=_scenario),
        Case("run: a law's yield stress as a memory map", run, 0, "",
             patch=_law43("yield_stress", "import tempfile\nvalue = np.asarray(value, float)\n"
                          "m = np.memmap(tempfile.TemporaryFile(), dtype=float, shape=value.shape, "
                          "mode='w+')\n"
                          "m[...] = value\nreturn m"), setup=_scenario),
        Case("run: a law changing its own mu_s to NaN mid-run", run, 1, "yield_stress() returned nan",
             keeps_output=True, patch=_law43("yield_stress",
             "if calls[0] > 30:\n    self.mu_s = float('nan')\n"
                                              "return real(self, *args)"), setup=_scenario),
        Case("run: a law raising an exception holding a newline", run, 1, "raised ValueError",
             one_message=True,
             keeps_output=True, patch=_raising("ValueError('first line\\nsecond line')"), setup=_scenario),
        Case("run: a law raising an exception of carriage returns", run, 1, "raised ValueError",
             one_message=True,
             keeps_output=True, patch=_raising("ValueError('over\\rwritten\\r\\n')"), setup=_scenario),
    ]  # fmt: skip


ONE_LAYER45 = {
    **MIXTURE32,
    "rheology": {"name": "dilatant_coulomb", "delta_deg": 25.0, "K1": 0.0},
    "domain.layers": 1,
}
""":data:`MIXTURE32` in one layer under the dilatant law: the compiled Newton iteration of
one-layer columns (in three layers the exchanges between them gather a packing beyond the
densest at t = 0.17 s, a failure the run names)."""

MIXTURE_SIM = (
    "import numpy as np\nfrom multilayer.errors import RunError\n"
    "sim = multilayer.Simulation(multilayer.load(sys.argv[2]))\nsaved = sim.state_dict()\n"
)
"""The start of a Python API case on a mixture: its simulation and its first state."""

ON_STEP_THREAD = """
import threading
outcome = []
def on_step(s, dt):
    def other():
        try:
            outcome.append(CALL)
        except InputError as exc:
            outcome.append(exc)
    worker = threading.Thread(target=other, daemon=True)
    worker.start()
    worker.join(30)
    if worker.is_alive():
        print('multilayer: the other thread waited for ever', file=sys.stderr)
        os._exit(3)
    if isinstance(outcome[-1], InputError):
        raise outcome[-1]
import os
sim.advance(0.02, on_step=on_step)
"""
"""An ``on_step`` that starts a thread making ``CALL`` on the simulation and waits for it
(exit 3 when the thread is still waiting after 30 s)."""

FAILED_ONCE = """
import numpy as np
from multilayer.errors import RunError
sim = multilayer.Simulation(multilayer.load(sys.argv[2]))
try:
    sim.advance(0.1)
except RunError as exc:
    failed = str(exc)
else:
    sys.exit('the law did not fail')
kept = sim.state_dict()
assert sim.t < 0.1 and all(np.isfinite(v).all() for v in kept.values() if isinstance(v, np.ndarray)), sim.t
sim.advance(0.1)
fresh = multilayer.Simulation(multilayer.load(sys.argv[2]))
fresh.advance(0.1)
same = all(np.array_equal(a, fresh.state_dict()[k]) for k, a in sim.state_dict().items())
print(f'multilayer: failed once ({failed[:60]}), then on to 0.1 s: the uninterrupted run: {same}',
      file=sys.stderr)
sys.exit(0 if same else 1)
"""
"""A simulation whose law fails once (``fails[0]`` set by the patch) mid-run: the state is
the last good one, and stepping on from it reaches the state of an uninterrupted run."""


NEWTON_START = """
sim.advance(0.02)
saved = sim.state_dict()
fresh = multilayer.Simulation(multilayer.load(sys.argv[2]))
fresh.load_state(saved)
saved['pore_pressure'][saved['pore_pressure'] != 0] = 1e12
sim.load_state(saved)
sim.advance(0.04)
fresh.advance(0.04)
gap = np.abs(sim.state_dict()['h'] - fresh.state_dict()['h']).max()
assert gap < 1e-9, gap
"""
"""A one-layer mixture whose pore pressure (where not 0) is set to 1e12 Pa at 0.02 s, the
start of the Newton iteration of the closure (no compressibility): at 0.04 s its
thickness is that of the run from its own pore pressure."""


def _mixture_law45(method: str, body: str, law: str = "DruckerPrager") -> str:
    """:func:`_mixture_patch` of the built-in ``law`` (DruckerPrager or DilatantCoulomb, whose
    compiled form is then not used) with ``calls[0]`` counting the calls and ``value`` the
    real method's answer: ``body`` returns what the law returns."""
    args = "self, p, mixture, m" if method == "mixture_yield_stress" else "self, g, p, mixture, m"
    indented = "".join(f"    {line}\n" for line in body.splitlines())
    return (
        "from multilayer.plugins.builtins.dilatant_coulomb import DilatantCoulomb\n"
        f"{law}.mixture_kernel = lambda self, material: None\n"
        f"real = {law}.{method}\ndef fault({args}):\n    calls[0] += 1\n"
        f"    value = real({args})\n{indented}{law}.{method} = fault\n"
    )


def _dry_run_then_mixture(directory: Path) -> None:
    """A dry run of TINY to 0.1 s in ``out``; the scenario beside it a mixture."""
    _scenario(directory, {"time.end": 0.1})
    subprocess.run(
        [
            sys.executable,
            "-m",
            "multilayer",
            "run",
            str(directory / "scenario.yaml"),
            "-o",
            str(directory / "out"),
            "-q",
        ],
        check=True,
        capture_output=True,
    )
    _scenario(directory, MIXTURE32)


def _mixed45(base: dict, **changes: Any) -> Callable[[Path], Path]:
    """The scenario ``base`` with ``changes`` (their dotted keys written with ``__``)."""
    return partial(_scenario, changes={**base, **{k.replace("__", "."): v for k, v in changes.items()}})


def round_forty_five() -> list[Case]:
    """The hostile cases of the forty-fifth round (docs/reliability.md): the grain-fluid
    mixture at the ends of its keys, in many layers, over an erodible bed and under laws
    returning hostile values; mixtures' checkpoints, states and results damaged within
    their bounds; the Python API used out of order (a step after a failure, states of
    other scenarios, an ``on_step`` waiting for a thread that steps); the non-hydrostatic
    pressure with odd inputs; option combinations of the command line; integers of more
    digits than Python converts."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    resume = [*run, "--resume"]
    validate = ["validate", "{scenario}"]
    plot = ["plot", "{dir}/out"]
    export = ["export", "{dir}/out"]
    check = ["check", "{scenario}", "-o", "{dir}/checked"]
    mixed = partial(_mixed45, MIXTURE32)
    one = partial(_mixed45, ONE_LAYER45)
    nh = {"model": {"pressure": "non_hydrostatic"}}
    thread = lambda call: _api(MIXTURE_SIM + ON_STEP_THREAD.replace("CALL", call))  # noqa: E731
    fails_once = lambda method, law: _mixture_law45(  # noqa: E731
        method, "if calls[0] == 40:\n    raise RuntimeError('once')\nreturn value", law
    )
    return [
        # the mixture at the ends of its keys
        Case("control: run of a mixture packed at 0.74 (below the densest packing)", run, 0, "",
             setup=mixed(initial__0__phi=0.74)),
        Case("control: run of a mixture of phi 1e-6 (almost all fluid)", run, 0, "",
             setup=mixed(initial__0__phi=1e-6)),
        Case("control: run of grains of 1500.000001 kg/m^3 in a fluid of 1500", run, 0, "",
             setup=mixed(material__particle_density=1500.000001, fluid__density=1500.0)),
        Case("run: a mixture of dilatancy 1e10", run, 1, "mixture.dilatancy = 1e+10", keeps_output=True,
             setup=mixed(mixture__dilatancy=1e10)),
        Case("run: a mixture of critical_shift 1e10 in one layer", run, 0, "",
             setup=one(mixture__critical_shift=1e10)),
        Case("run: a mixture of kozeny 1e300", run, 2, "mixture.kozeny", setup=mixed(mixture__kozeny=1e300)),
        Case("control: run of a mixture of grains 0.5 m across", run, 0, "",
             setup=mixed(material__grain_diameter=0.5)),
        Case("run: a mixture in a fluid of viscosity 1e5 Pa s under Drucker-Prager", run, 1,
             "fluid.viscosity = 100000", keeps_output=True, setup=mixed(fluid__viscosity=1e5)),
        Case("control: run of a mixture in a fluid of viscosity 1e5 Pa s, one layer, the dilatant law", run,
             0, "", setup=one(fluid__viscosity=1e5)),
        Case("control: run of a mixture of compressibility 1e-300", run, 0, "",
             setup=mixed(fluid__compressibility=1e-300)),
        Case("run: a mixture of compressibility 1 in one layer, the dilatant law", run, 1,
             "fluid.compressibility = 1 1/Pa", keeps_output=True, setup=one(fluid__compressibility=1.0)),
        Case("control: run of a mixture of compressibility 1, packed at 0.74, one layer", run, 0, "",
             setup=mixed(domain__layers=1, fluid__compressibility=1.0, initial__0__phi=0.74)),
        Case("control: run of a mixture in ten geometric layers", run, 0, "",
             setup=mixed(domain__layers=10, domain__layer_fractions={"geometric": 1.5})),
        Case("control: run of a mixture of two columns of other packings, one over the other", run, 0, "",
             setup=mixed(initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05,
                                   "phi": 0.5},
                                  {"shape": "rectangle", "x_min": 0.05, "x_max": 0.15, "height": 0.03,
                                   "phi": 0.65}])),
        Case("control: run of a mixture column over an erodible mixture bed", run, 0, "",
             setup=mixed(initial=[{"shape": "layer", "thickness": 0.003, "phi": 0.6},
                                  {"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05,
                                   "phi": 0.55}])),
        Case("control: run of a mixture moving uphill (slope -30 degrees, plug 1 m/s)", run, 0, "",
             setup=mixed(slope_deg=-30.0, initial__0__velocity={"profile": "plug", "speed": 1.0})),
        Case("control: run of a mixture of delta 89.9999 degrees (static)", run, 0, "",
             setup=mixed(rheology={"name": "dilatant_coulomb", "delta_deg": 89.9999, "K1": 0.0})),
        Case("run: a mixture of K1 1e300", run, 2, "K1 must be at most",
             setup=mixed(rheology={"name": "dilatant_coulomb", "delta_deg": 25.0, "K1": 1e300})),
        Case("validate: a mixture whose column is below numerics.dry_threshold", validate, 2,
             "numerics.dry_threshold", setup=mixed(numerics={"dry_threshold": 0.1})),
        Case("control: run of a mixture over a cliff 5e-17 m wide", run, 0, "",
             setup=mixed(bed={"points": [[0, 0], [0.3, 0], [0.3 + 5.6e-17, -0.01], [0.5, -0.01]]})),
        # mixture laws returning hostile values
        Case("run: a mixture yield stress of inf mid-run", run, 1, "mixture_yield_stress() returned inf",
             keeps_output=True, setup=mixed(),
             patch=_mixture_law45("mixture_yield_stress", "return np.full(np.shape(value), np.inf) "
                                  "if calls[0] > 40 else value")),
        Case("run: a mixture viscosity of nan mid-run in one layer", run, 1,
             "mixture_viscosity() returned nan",
             keeps_output=True, setup=one(),
             patch=_mixture_law45("mixture_viscosity", "return np.full(np.shape(value), np.nan) "
                                  "if calls[0] > 40 else value", "DilatantCoulomb")),
        Case("run: a mixture yield stress of the shape of phi over the columns", run, 1,
             "mixture_yield_stress() returned an array of shape", setup=mixed(),
             patch=_mixture_law45("mixture_yield_stress", "return np.asarray(mixture.phi).reshape(-1)[:5]")),
        Case("run: a mixture law writing into phi", run, 1, "assignment destination is read-only",
             setup=mixed(), patch=_mixture_law45("mixture_yield_stress",
                                                 "np.asarray(mixture.phi)[...] = 0.9\nreturn value")),
        Case("control: a mixture yield stress of 1e300 (static)", run, 0, "", setup=mixed(),
             patch=_mixture_law45("mixture_yield_stress", "return np.full(np.shape(value), 1e300)")),
        Case("run: a mixture viscosity of 1e300", run, 0, "", setup=one(),
             patch=_mixture_law45("mixture_viscosity", "return np.full(np.shape(value), 1e300)")),
        Case("run: a mixture yield stress negative where the pore pressure is above 0", run, 1,
             "mixture_yield_stress() returned -", setup=mixed(initial__0__phi=0.5),
             patch=_mixture_law45("mixture_yield_stress",
                                  "return np.where(np.asarray(mixture.pore_pressure) > 0, -1.0, value)")),
        Case("control: a mixture law returning lists", run, 0, "", setup=mixed(),
             patch=_mixture_law45("mixture_yield_stress", "return np.asarray(value).tolist()")),
        Case("control: a mixture law replacing its argument's phi by NaN after its answer", run, 0, "",
             setup=mixed(),
             patch=_mixture_law45("mixture_yield_stress", "object.__setattr__(mixture, 'phi', np.nan)\n"
                                  "return value")),
        # mixtures' checkpoints and states within their bounds but impossible
        Case("run --resume: a mixture's checkpoint packed at 0.87 (solid 1.5 times its own)", resume, 2,
             "beyond the densest packing of spheres, 0.7405; accepted: the solid of each column",
             setup=_mixture_checkpoint("state.solid", lambda s: 1.5 * s)),
        Case("run --resume: a mixture's checkpoint of pore_pressure nan", resume, 2, "pore_pressure",
             setup=_mixture_checkpoint("state.pore_pressure", lambda p: np.full_like(p, np.nan))),
        Case("run --resume: a mixture's checkpoint of pore_pressure 1e300, compressible", resume, 1,
             "", setup=_mixture_checkpoint("state.pore_pressure", lambda p: np.full_like(p, 1e300),
                                           {"fluid.compressibility": 1e-3})),
        Case("run --resume: a mixture's checkpoint whose pore_pressure has a layer too few", resume, 2,
             "pore_pressure", setup=_mixture_checkpoint("state.pore_pressure", lambda p: p[:-1])),
        Case("run --resume: a dry run's checkpoint, the scenario now a mixture", resume, 2, "fluid",
             setup=_dry_run_then_mixture),
        Case("API: load_state of a mixture's state into a dry simulation", validate, 2, "solid",
             patch=_api(MIXTURE_SIM + "dry = multilayer.Simulation(multilayer.load(sys.argv[2], "
                        "{'fluid': None, 'mixture': None, 'initial.0.phi': None}))\ndry.load_state(saved)"),
             setup=mixed()),
        Case("API: load_state of a dry state into a mixture", validate, 2, "solid: missing",
             patch=_api(MIXTURE_SIM + "dry = multilayer.Simulation(multilayer.load(sys.argv[2], "
                        "{'fluid': None, 'mixture': None, 'initial.0.phi': None}))\n"
                        "sim.load_state(dry.state_dict())"), setup=mixed()),
        Case("API: load_state of a mixture of three layers into one of one", validate, 2, "shape",
             patch=_api(MIXTURE_SIM + "one = multilayer.Simulation(multilayer.load(sys.argv[2], "
                        "{'domain.layers': 1}))\none.load_state(saved)"), setup=mixed()),
        Case("API: load_state of a mixture's solid as integers", validate, 2, "solid",
             patch=_api(MIXTURE_SIM + "saved['solid'] = np.ones(saved['solid'].shape, int)\n"
                        "sim.load_state(saved)"), setup=mixed()),
        Case("control: API state_dict of a mixture changed in place does not change the simulation",
             validate, 0, "",
             patch=_api(MIXTURE_SIM + "sim.advance(0.02)\nmine = sim.state_dict()\n"
                        "mine['solid'] *= 2\nmine['pore_pressure'][...] = 1e9\nsim.advance(0.04)\n"
                        "fresh = multilayer.Simulation(multilayer.load(sys.argv[2]))\nfresh.advance(0.02)\n"
                        "fresh.advance(0.04)\n"
                        "assert all(np.array_equal(v, fresh.state_dict()[k]) for k, v in "
                        "sim.state_dict().items())"), setup=mixed()),
        Case("API: load_state of one column 1000 m deep into a one-layer mixture", validate, 0, "",
             patch=_api(MIXTURE_SIM + "saved['h'][20] = 1000.0\nsaved['solid'][0, 20] = 580.0\n"
                        "sim.load_state(saved)\ntry:\n    sim.advance(0.001)\nexcept RunError as exc:\n"
                        "    print(f'multilayer: {exc}', file=sys.stderr)\n    sys.exit(1)"), setup=one()),
        Case("API: load_state of a one-layer mixture's pore pressure of 1e12 (the Newton start)", validate,
             0, "",
             patch=_api(MIXTURE_SIM + NEWTON_START), setup=one()),
        Case("API: a step after a failure of the mixture law (the state kept, then on)", validate, 0, "",
             patch=fails_once("mixture_yield_stress", "DruckerPrager") + _api(FAILED_ONCE), setup=mixed()),
        Case("API: a step after a failure of the mixture law in one layer", validate, 0, "",
             patch=fails_once("mixture_viscosity", "DilatantCoulomb") + _api(FAILED_ONCE), setup=one()),
        Case("API: load_state of a five-layer state into a three-layer one", validate, 2, "shape",
             patch=_api(ON_STEP + "five = multilayer.Simulation(multilayer.load(sys.argv[2], "
                        "{'domain.layers': 5}))\nsim.load_state(five.state_dict())"), setup=_scenario),
        Case("API: load_state of a non-hydrostatic state into a hydrostatic one", validate, 2,
             "newton_seed: not an entry of this simulation's state",
             patch=_api(ON_STEP + "other = multilayer.Simulation(multilayer.load(sys.argv[2], "
                        "{'model': {'pressure': 'non_hydrostatic'}}))\nother.advance(0.02)\n"
                        "sim.load_state(other.state_dict())\nsim.advance(0.04)"), setup=_scenario),
        Case("API: advance(max_steps=0)", validate, 2, "max_steps",
             patch=_api(ON_STEP + "sim.advance(0.05, max_steps=0)"), setup=_scenario),
        # threads and the on_step of advance
        Case("API: on_step waiting for a thread that advances the simulation", validate, 2,
             "from another thread while the on_step of advance runs",
             patch=thread("s.advance(s.t + 0.01)"), setup=mixed()),
        Case("API: on_step waiting for a thread that steps the simulation", validate, 2,
             "from another thread while the on_step of advance runs",
             patch=thread("s.step()"), setup=mixed()),
        Case("API: on_step waiting for a thread that loads a state", validate, 2,
             "from another thread while the on_step of advance runs",
             patch=thread("s.load_state(saved)"), setup=mixed()),
        Case("control: on_step waiting for a thread reading state_dict()", validate, 0, "",
             patch=thread("s.state_dict()['t']"), setup=mixed()),
        Case("control: two threads advancing one simulation take turns", validate, 0, "",
             patch=_api(ON_STEP + "import threading\nworker = threading.Thread(target=sim.advance, "
                        "args=(0.04,))\nworker.start()\nsim.advance(0.04)\nworker.join(60)\n"
                        "assert not worker.is_alive() and sim.t == 0.04, sim.t"), setup=_scenario),
        # results of mixtures damaged
        Case("export --vtk: a mixture's phi nan in a wet cell", [*export, "--vtk"], 2,
             "phi = nan is not in [0,",
             setup=_mixture_result(lambda ds: ds["phi"].__setitem__((-1, _wet_cell(ds)), np.nan))),
        Case("plot: a mixture's pore_pressure_excess inf", plot, 2, "pore_pressure_excess",
             setup=_mixture_result(lambda ds: ds["pore_pressure_excess"].__setitem__(
                 (-1, _wet_cell(ds)), np.inf))),
        Case("plot: a mixture's phi and phi_layer 0.8 (above the densest packing)", plot, 2,
             "phi = 0.8 is not in [0, 0.7405]",
             setup=_mixture_result(lambda ds: (ds["phi"].__setitem__((-1, _wet_cell(ds)), 0.8),
                                               ds["phi_layer"].__setitem__((-1, slice(None), _wet_cell(ds)),
                                                                           0.8)))),
        Case("export --vtk: a mixture's result without phi_layer", [*export, "--vtk"], 2, "phi_layer",
             setup=_mixture_result(lambda ds: ds.renameVariable("phi_layer", "other"))),
        Case("check: a mixture whose expect phi_mean_final is met", check, 0, "",
             setup=mixed(expect=[{"kind": "regression", "quantity": "phi_mean_final", "value": 0.58,
                                  "atol": 0.1}])),
        # the non-hydrostatic pressure with odd inputs
        Case("validate: non-hydrostatic, pressure_layers 5 of 3 layers", validate, 2, "model.pressure_layers",
             setup=partial(_scenario, changes={"model": {**nh["model"], "pressure_layers": 5}})),
        Case("control: run non-hydrostatic on one cell", run, 0, "",
             setup=partial(_scenario, changes={**nh, "domain.cells": 1,
                                               "initial.0": {"shape": "layer", "thickness": 0.05}})),
        Case("control: run non-hydrostatic into a wall of bed 1e6 m high", run, 0, "",
             setup=partial(_scenario, changes={**nh, "bed": {
                 "points": [[0, 0], [0.25, 0], [0.26, 1e6], [0.5, 1e6]]}})),
        Case("control: run non-hydrostatic behind a gate lifted at 1e-300 m/s", run, 0, "",
             setup=partial(_scenario, changes={**nh, "gate": {"x": 0.1, "lift_speed": 1e-300}})),
        Case("control: run non-hydrostatic on a slope of -89.9 degrees", run, 0, "",
             setup=partial(_scenario, changes={**nh, "slope_deg": -89.9})),
        # option combinations of the command line
        Case("run --resume --force --max-steps 1 of a finished run", [*resume, "--force", "--max-steps", "1"],
             0, "", setup=_finished_run),
        Case("run: -o the scenario file itself", ["run", "{scenario}", "-o", "{scenario}", "-q"], 2,
             "scenario.yaml", setup=_scenario),
        Case("run: --set fluid of a dry scenario",
             [*run, "--set", "fluid={{density: 1000, viscosity: 0.001}}"], 2,
             "fluid is given without mixture", setup=_scenario),
        Case("run: --set initial.0.phi of a dry scenario", [*run, "--set", "initial.0.phi=0.6"], 2,
             "initial.0.phi", setup=_scenario),
        Case("run: --max-steps 1 of a mixture", [*run, "--max-steps", "1"], 2, "--max-steps", setup=mixed()),
        Case("run --resume: a mixture, --set fluid=null", [*resume, "--set", "fluid=null"], 2, "fluid",
             setup=lambda d: _finished_mixture(d, end=0.1)),
        # integers of more digits than Python converts
        Case("validate: domain.cells of 5000 digits (what is accepted)", validate, 2,
             "more than the 4300 an integer may have",
             setup=_yaml44(lambda t: t.replace("cells: 40", "cells: " + "4" * 5000))),
        Case("validate: --set domain.cells of 5000 digits (what is accepted)",
             [*validate, "--set", "domain.cells=" + "7" * 5000], 2, "domain.cells", setup=_scenario),
        Case("API: load of a mapping of domain.cells 10**5000", validate, 2, "domain.cells",
             patch=_api("import yaml\ndata = yaml.safe_load(open(sys.argv[2]))\n"
                        "data['domain']['cells'] = 10**5000\nmultilayer.load(data)"), setup=_scenario),
        Case("API: Simulation.advance(10**5000)", validate, 2, "advance(t_target",
             patch=_api(ON_STEP + "sim.advance(10**5000)"), setup=_scenario),
    ]  # fmt: skip


def _socket_at(name: str, scenario: bool = True) -> Callable[[Path], None]:
    """A UNIX socket bound at ``directory/name`` (the scenario beside it, ``scenario``)."""

    def setup(directory: Path) -> None:
        if scenario:
            _scenario(directory, {"bed": {"file": "bed.csv"}} if name == "bed.csv" else None)
        with socket.socket(socket.AF_UNIX) as bound:
            bound.bind(str(directory / name))

    return setup


GROWING = """
import sys, time
end = time.monotonic() + 30
with open(sys.argv[1], 'a') as stream:
    while time.monotonic() < end:
        stream.write('# a comment appended by another process\\n')
        stream.flush()
        time.sleep(0.001)
"""
"""Another process appending comment lines to a file for 30 s."""


def _growing_scenario(directory: Path) -> None:
    """The scenario, which another process appends comments to while it is read."""
    path = _scenario(directory)
    subprocess.Popen(
        [sys.executable, "-c", GROWING, str(path)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
    )
    time.sleep(0.2)


def _sparse(name: str) -> Callable[[Path], None]:
    """A finished run whose ``out/name`` is extended to a terabyte of zeros (a sparse file:
    no room taken), as a tool appending to the wrong file or a damaged copy leaves it."""

    def setup(directory: Path) -> None:
        _finished_run(directory)
        os.truncate(directory / "out" / name, 2**40)

    return setup


def _sweep_with_sparse_member(directory: Path) -> None:
    """A sweep of one member run to its end, whose member's result.nc is then extended to a
    terabyte of zeros."""
    _sweep33(ONE_MEMBER)(directory)
    subprocess.run(
        [sys.executable, "-m", "multilayer", "sweep", str(directory / "study.yaml"), "-o",
         str(directory / "study"), "--workers", "1", "-q"],
        check=True, capture_output=True,
    )  # fmt: skip
    for result in (directory / "study").glob("*/result.nc"):
        os.truncate(result, 2**40)


THEN_PLOTTED = """
code = main(sys.argv[1:])
if code:
    sys.exit(code)
sys.exit(main(['plot', sys.argv[sys.argv.index('-o') + 1]]))
"""
"""The command (a resume), then ``plot`` of its output directory."""

TWO_RESUMES = """
import subprocess
from multilayer.io.result_check import check_result
import netCDF4
out = sys.argv[3] + '/out'
command = [sys.executable, '-m', 'multilayer', 'run', sys.argv[2], '-o', out, '-q', '--resume',
           '--set', 'time.end=0.6']
started = [subprocess.Popen(command, stderr=subprocess.PIPE, text=True) for _ in range(2)]
codes = sorted(p.wait(timeout=100) for p in started)
said = ' | '.join(p.stderr.read().strip() for p in started)
check_result(out)
with netCDF4.Dataset(out + '/result.nc') as ds:
    whole = ds.run_status == 'completed' and float(ds['time'][-1]) == 0.6
refused = codes == [0, 2] and 'run.lock' in said
print(f'multilayer: two resumes: exit {codes}, the result completed to 0.6 s: {whole}', file=sys.stderr)
sys.exit(0 if whole and (codes == [0, 0] or refused) else 1)
"""
"""Two ``multilayer run --resume`` of one finished run started together: one runs, the
other is refused by the lock (or starts after the first ended); the result is whole."""

SIGNAL_IN_SUMMARY = """
import csv, os, signal
real_writerow = csv.DictWriter.writerow
def writerow(self, row):
    calls[0] += 1
    if calls[0] == 2:  # the first member's row of summary.csv
        os.kill(os.getpid(), signal.{name})
    return real_writerow(self, row)
csv.DictWriter.writerow = writerow
"""
"""A stop signal to a sweep as it writes the first row of its ``summary.csv``."""

SIGNAL_IN_FIGURE = """
import os, signal
from matplotlib.figure import Figure
real_savefig = Figure.savefig
def savefig(self, *args, **kwargs):
    calls[0] += 1
    if calls[0] == 2:
        os.kill(os.getpid(), signal.{name})
    return real_savefig(self, *args, **kwargs)
Figure.savefig = savefig
"""
"""A stop signal to ``plot`` as it writes its second figure."""

SIGNAL_IN_VTK = """
import os, signal
from multilayer.io import export
real_text_file = export._text_file
def text_file(path, text):
    calls[0] += 1
    if calls[0] == 3:
        os.kill(os.getpid(), signal.{name})
    return real_text_file(path, text)
export._text_file = text_file
"""
"""A stop signal to ``export --vtk`` as it writes its third file."""


def _expect46(entry: str) -> Callable[[Path], None]:
    """TINY with the ``expect`` list of YAML text ``entry``."""
    return _scenario_text(lambda t: t + "expect:\n" + entry + "\n")


PIN46 = "- {kind: regression, quantity: mass_final, value: 0.005, "
"""The start of an ``expect`` entry on TINY's final mass (0.005000000000000001)."""


def round_forty_six() -> list[Case]:
    """The hostile cases of the forty-sixth round (docs/reliability.md): a ``result.nc``
    followed by a terabyte of zeros (``plot`` hashed them for hours; ``--resume`` kept them
    after its records), an empty path as the file of ``run``, ``validate``,
    ``check``, ``sweep``, ``calibrate`` and ``sensitivity`` (named as ``.``), Dask settings
    it cannot read (a traceback) or a missing temporary directory of Dask's (not named);
    and, handled before, sockets, growing files and ``/dev/stdin`` as files, two resumes at
    once, stop signals while a sweep's summary, a figure or a VTK file is written,
    ``--set`` index spellings and keys in other Unicode forms, long command lines, hostile
    ``expect:`` entries, output intervals and ends at the ends of the floats and studies
    writing into odd directories."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    empty = "an empty path; accepted: the path of a YAML file"
    resume = [*run, "--resume"]
    validate, check = ["validate", "{scenario}"], ["check", "{scenario}"]
    timing = "time.output_interval"
    plot = ["plot", "{dir}/out"]
    sweep = ["sweep", "{dir}/study.yaml", "-o", "{dir}/study", "--workers", "1", "-q"]
    one = _sweep33(ONE_MEMBER)
    unreadable = "the local Dask cluster could not read its settings"
    return [
        # files that are not what they seem
        Case("validate: the scenario a UNIX socket", validate, 2, "scenario.yaml",
             setup=_socket_at("scenario.yaml", scenario=False)),
        Case("validate: bed.file a UNIX socket", validate, 2, "bed.csv", setup=_socket_at("bed.csv")),
        Case("sweep: the sweep file a UNIX socket", sweep, 2, "study.yaml", setup=_socket_at("study.yaml")),
        Case("run: -o a UNIX socket", run, 2, "out", setup=_socket_at("out")),
        Case("validate: /dev/stdin an endless pipe (yes)", ["validate", "/dev/stdin"], 2,
             "/dev/stdin: not a regular file", prefix=["sh", "-c", 'yes | "$0" "$@"']),
        Case("control: run of /dev/stdin redirected from the scenario", ["run", "/dev/stdin", "-o",
             "{dir}/out", "-q"], 0, "", prefix=["sh", "-c", 'exec "$0" "$@" < "$SCENARIO"'],
             env={"SCENARIO": "{dir}/scenario.yaml"}, setup=_scenario),
        Case("control: validate of a scenario another process appends to", validate, 0, "",
             setup=_growing_scenario),
        Case("plot: result.nc followed by a terabyte of zeros", plot, 0, "", setup=_sparse("result.nc")),
        Case("control: export --vtk of a result.nc followed by a terabyte of zeros",
             ["export", "{dir}/out", "--vtk"], 0, "", setup=_sparse("result.nc")),
        Case("run --resume: result.nc followed by a terabyte of zeros, then plot",
             [*resume, "--set", "time.end=0.3"], 0, "", patch=THEN_PLOTTED, setup=_sparse("result.nc")),
        Case("run --resume: checkpoint.npz followed by a terabyte of zeros",
             [*resume, "--set", "time.end=0.3"], 2, "checkpoint.npz", setup=_sparse("checkpoint.npz")),
        Case("control: sweep of a member whose result.nc is followed by a terabyte of zeros", sweep, 0, "",
             setup=_sweep_with_sparse_member),
        Case("run: result.nc a symbolic link to another run's result", run, 2, "a symbolic link",
             setup=_linked_result46),
        Case("control: two resumes of one run started together", ["two", "{scenario}", "{dir}"], 0,
             "the result completed to 0.6 s: True", patch=TWO_RESUMES, setup=_finished_run),
        # empty paths
        *[Case(f"{command}: an empty path as its file", [command, ""], 2, empty)
          for command in ("validate", "run", "check", "sweep", "calibrate", "sensitivity")],
        # stop signals while files are written
        Case("sweep: SIGTERM as summary.csv is written", sweep, 143, "SIGTERM",
             patch=SIGNAL_IN_SUMMARY.format(name="SIGTERM"), setup=one),
        Case("plot: SIGHUP as the second figure is written", plot, 129, "SIGHUP",
             patch=SIGNAL_IN_FIGURE.format(name="SIGHUP"), setup=_finished_run),
        Case("export --vtk: SIGINT as the third file is written", ["export", "{dir}/out", "--vtk"], 130, "",
             patch=SIGNAL_IN_VTK.format(name="SIGINT"), setup=_finished_run),
        # Dask's settings
        Case("sweep: DASK_TEMPORARY_DIRECTORY a directory that does not exist", sweep, 2,
             "DASK_TEMPORARY_DIRECTORY", env={"DASK_TEMPORARY_DIRECTORY": "{dir}/nothing"}, setup=one),
        Case("sweep: DASK_TEMPORARY_DIRECTORY a regular file", sweep, 2, "DASK_TEMPORARY_DIRECTORY",
             env={"DASK_TEMPORARY_DIRECTORY": "{dir}/scenario.yaml"}, setup=one),
        Case("sweep: DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc", sweep, 2,
             "set in the environment: DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT",
             env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "abc"}, setup=one),
        Case("sensitivity: DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc",
             ["sensitivity", "{dir}/study.yaml", "-o", "{dir}/study", "--workers", "1", "-q"], 2, unreadable,
             env={"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "abc"},
             setup=_study41(SENSITIVITY_MU_S)),
        # studies writing into odd directories, and their options
        Case("sweep: -o /dev/null", [*sweep[:3], "/dev/null", *sweep[4:]], 2, "/dev/null", setup=one),
        Case("sweep: -o its own sweep file", [*sweep[:3], "{dir}/study.yaml", *sweep[4:]], 2, "study.yaml",
             setup=one),
        Case("sweep: -o a symbolic link to itself", sweep, 2, "study", setup=_study_linked_to_itself),
        Case("sweep: --resume of a directory never written", [*sweep, "--resume"], 2, "study", setup=one),
        Case("sweep: --workers 0", [*sweep[:5], "0", "-q"], 2, "--workers", setup=one),
        Case("sweep: --scheduler ''", [*sweep[:4], "--scheduler", "", "-q"], 2, "--scheduler", setup=one),
        Case("validate: a sweep of output.directory", ["validate", "{dir}/study.yaml"], 2, "output",
             setup=_sweep33("parameters:\n  output.directory: [a, b]\n")),
        Case("validate: a sensitivity study of mu_s in [1e308, 1.7976931348623157e308]",
             ["validate", "{dir}/study.yaml"], 2, "mu_s",
             setup=_study41(SENSITIVITY_MU_S.replace("0.2, 0.4", "1.0e+308, 1.7976931348623157e+308"))),
        # the command line
        Case("validate: --set initial.+0.height", [*validate, "--set", "initial.+0.height=0.04"], 2,
             "accepted indices: 0..0", setup=_scenario),
        Case("validate: --set 'initial. 0.height'", [*validate, "--set", "initial. 0.height=0.04"], 2,
             "accepted indices: 0..0", setup=_scenario),
        Case("validate: --set a key in NFD (slope with a combining accent)",
             [*validate, "--set", "slope\u0301_deg=3"], 2, "unknown key", setup=_scenario),
        Case("validate: --set a key of a full-width letter (NFKC slope_deg)",
             [*validate, "--set", "\uff53lope_deg=3"], 2, "unknown key", setup=_scenario),
        Case("validate: --set description given 5000 times", [*validate, *["--set", "description=x"] * 5000],
             2, "set before it", setup=_scenario),
        Case("validate: 3000 --set of unknown keys", [*validate, *[f"--set=k{i}=1" for i in range(3000)]], 2,
             "unknown key", setup=_scenario),
        Case("control: validate --set description of 100 000 characters",
             [*validate, "--set", "description=" + "x" * 100_000], 0, "", setup=_scenario),
        Case("validate: names of an accented letter in NFC and in NFD",
             ["validate", "{dir}/a.yaml", "{dir}/b.yaml"], 2, "name (line 17)", setup=_two_forms),
        # hostile expect: entries
        Case("check: expect rtol .nan", check, 2, "expect.0.rtol", setup=_expect46(PIN46 + "rtol: .nan}")),
        Case("check: expect value .inf", check, 2, "expect.0.value",
             setup=_expect46(PIN46.replace("0.005", ".inf") + "rtol: 0}")),
        Case("check: expect rtol -1e-300", check, 2, "expect.0.rtol",
             setup=_expect46(PIN46 + "rtol: -1e-300}")),
        Case("check: expect kind Regression", check, 2, "expect.0.kind",
             setup=_expect46(PIN46.replace("regression", "Regression") + "rtol: 0.1}")),
        Case("check: expect quantity steps", check, 2, "expect.0.quantity",
             setup=_expect46(PIN46.replace("mass_final", "steps") + "rtol: 0.1}")),
        Case("check: expect a mapping, not a list", check, 2, "expect (line",
             setup=_expect46("  " + PIN46[2:] + "rtol: 0.1}")),
        Case("check: expect value true", check, 2, "expect.0.value",
             setup=_expect46(PIN46.replace("0.005", "true") + "rtol: 0.1}")),
        Case("check: expect rtol -0.0, one ulp off (an exact pin that fails)", check, 1, "",
             setup=_expect46(PIN46 + "rtol: -0.0}")),
        Case("check: expect atol 5e-324, one ulp off", check, 1, "",
             setup=_expect46(PIN46 + "atol: 5e-324}")),
        Case("control: check of an exact pin, rtol 0 and atol 0", check, 0, "",
             setup=_expect46(PIN46.replace("0.005", "0.005000000000000001") + "rtol: 0, atol: 0}")),
        Case("control: check of one expect entry twice", check, 0, "",
             setup=_expect46(PIN46 + "rtol: 0.01}\n" + PIN46 + "rtol: 0.01}")),
        # plot and export options
        Case("plot: --at given 13 times", [*plot, *["--at", "0.1"] * 13], 2, "at most 12 --at positions",
             setup=_finished_run),
        Case("export: no format", ["export", "{dir}/out"], 2, "--vtk", setup=_finished_run),
        # time.end and output_interval at the ends of the floats
        Case("control: run to 0.3 s every 0.1 s (3 x 0.1 > 0.3)", run, 0, "",
             setup=partial(_scenario, changes={"time.end": 0.3, timing: 0.1})),
        Case("control: run of an output interval beyond time.end", run, 0, "",
             setup=partial(_scenario, changes={timing: 1.0})),
        Case("control: run of an output interval one ulp below time.end", run, 0, "",
             setup=partial(_scenario, changes={timing: 0.19999999999999998})),
        Case("control: validate of an output interval of 1.7976931348623157e308 s", validate, 0, "",
             setup=partial(_scenario, changes={timing: 1.7976931348623157e308})),
        Case("validate: time.end and output_interval 1.7976931348623157e308 s", validate, 2, "steps",
             setup=partial(_scenario, changes={"time.end": 1.7976931348623157e308,
                                               timing: 1.7976931348623157e308})),
        Case("control: run --resume to one ulp after the end",
             [*resume, "--set", "time.end=0.2000000000000001"], 0, "the run is finished there",
             setup=_finished_run),
        Case("run --resume to one ulp before the end",  # a run is extended, never shortened (round 48)
             [*resume, "--set", "time.end=0.19999999999999998"], 2, "beyond time.end", setup=_finished_run),
    ]  # fmt: skip


PHYSICS47 = """
_command = main


def main(argv):
    code = _command(argv)
    if code:
        return code
    import os
    import netCDF4
    from multilayer.io.result_check import check_result
    checks = os.environ['PHYSICS'].split(',')
    file = check_result(argv[argv.index('-o') + 1])
    with netCDF4.Dataset(file) as ds:
        h, u = np.asarray(ds['h'][:]), np.asarray(ds['u'][:])
        dx = np.diff(np.asarray(ds['x_bnds'][:]), axis=1)[:, 0]
        steps = int(ds.getncattr('steps'))
        solid = np.asarray(ds['phi'][:]) if 'phi' in ds.variables else np.ones_like(h)
    said = []
    if not (np.isfinite(h).all() and np.isfinite(u).all()):
        said.append('non-finite h or u')
    if not (h >= 0).all():
        said.append(f'h < 0 ({h.min():.3g} m)')
    if 'closed' in checks:  # closed or periodic sides: the volume (of the grains) is conserved
        volume = (solid * h) @ dx
        drift = abs(volume[-1] - volume[0]) / volume[0]
        if not drift <= 8 * np.finfo(float).eps * (steps + 1):  # a rounding of each cell and flux per step
            said.append(f'the volume changed by {drift:.3g} of itself in {steps} steps')
    if 'rest' in checks and np.abs(u).max() != 0:
        said.append(f'a column under its yield moved (max |u| = {np.abs(u).max():.3g} m/s)')
    summary = '; '.join(said) or f'checked {checks} over {steps} steps'
    print('multilayer: physics: ' + summary, file=sys.stderr)
    return 1 if said else 0
"""
"""The command (a ``run``), then the physics of its result (``PHYSICS``, a comma-separated
list): finite ``h`` and ``u`` and ``h >= 0`` always; ``closed``: the volume (``phi h`` in a
mixture) conserved to its round-off, ``8 eps`` per step (a rounding of every cell and
flux, relative to the volume); ``rest``: every velocity exactly 0 at every output; and the
result file read back by the result check."""

LAYER47 = {
    "initial": [{"shape": "layer", "thickness": 0.01}],
    "boundaries": {"left": "periodic", "right": "periodic"},
    "slope_deg": 10.0,
}
"""A uniform 1 cm layer on a periodic 10 degree slope (below TINY's friction angle, 16.7
degrees): under its yield everywhere, at rest for ever."""
WALLS47 = {"boundaries": {"left": "wall", "right": "wall"}}
"""TINY between two walls: closed."""
PERIODIC47 = {"boundaries": {"left": "periodic", "right": "periodic"}}


def _edge47(name: str, changes: dict, checks: str = "", code: int = 0, phrase: str = "physics") -> Case:
    """A run of TINY with ``changes``, the scenario ``validate`` accepts: it completes with
    the physics ``checks`` of :data:`PHYSICS47`, or stops with exit ``code`` and ``phrase``."""
    return Case(name, ["run", "{scenario}", "-o", "{dir}/out", "-q"], code, phrase, patch=PHYSICS47,
                env={"PHYSICS": checks}, setup=partial(_scenario, changes=changes))  # fmt: skip


def _random47(seed: int) -> tuple[str, dict, str]:
    """A scenario drawn from the accepted values of TINY's keys (seeded: reproducible) and
    the checks it must pass: closed or periodic sides conserve the volume."""
    draw = np.random.default_rng(seed)
    sides = ["wall", "periodic", "outflow"][draw.integers(3)]
    right = "wall" if sides == "wall" else sides
    rheology = [
        {"name": "drucker_prager", "mu_s": float(draw.uniform(0, 1)), "nu": float(10 ** draw.uniform(-4, 0))},
        {"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": float(10 ** draw.uniform(-3, 0))},
        {"name": "power_law_mu_i", "mu_s": 0.3, "m": float(draw.uniform(0.1, 3)), "alpha": 1.0},
        {"name": "pouliquen_forterre", "mu_1": 0.38, "mu_2": 0.64, "L": 1e-3, "I_0": 0.3},
    ][draw.integers(4)]
    cells = int(draw.integers(1, 200))
    changes: dict[str, Any] = {
        "slope_deg": float(draw.uniform(-60, 60)),
        "domain.cells": cells,
        "domain.layers": int(draw.integers(1, 20)),
        "material.grain_diameter": float(10 ** draw.uniform(-6, -1)),
        "rheology": rheology,
        "initial.0.height": float(10 ** draw.uniform(-4, 0)),
        "boundaries": {"left": sides, "right": right},
        "time.cfl": float(draw.uniform(0.01, 0.99)),
        "numerics": {"order": int(draw.integers(1, 3))},
    }
    if cells < 6:  # the rectangle is 0.1 m of the 0.5 m domain: a cell at least
        changes["initial.0"] = {"shape": "layer", "thickness": changes.pop("initial.0.height")}
    shown = {k.split(".")[-1]: v.get("name", v) if isinstance(v, dict) else v for k, v in changes.items()}
    text = ", ".join(f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}" for k, v in shown.items()
                     if k not in ("boundaries", "numerics", "0"))  # fmt: skip
    return f"seed {seed}: {sides}, {text}", changes, "closed" if sides != "outflow" else ""


def round_forty_seven() -> list[Case]:
    """The valid cases of the forty-seventh round (docs/reliability.md): scenarios that
    ``validate`` accepts, at the ends of every accepted range and in seeded random
    combinations, each run and its result checked as a physicist would (the volume of a
    closed or periodic domain conserved to round-off, finite fields, ``h >= 0``, a column
    under its yield exactly at rest, the file read back), or stopped with exit 2 and a
    message naming a true limit: never a traceback, a hang, or a guard stopping a valid
    run for a numerical artefact."""
    rest, closed = "closed,rest", "closed"
    dp = {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01}
    jop = {"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.3}
    pf = {"name": "pouliquen_forterre", "mu_1": 0.38, "mu_2": 0.64, "L": 1e-3, "I_0": 0.3}
    friction = float(np.degrees(np.arctan(0.3)))  # TINY's friction angle, 16.699 degrees
    big = {"domain.x_max": 5000.0, "initial.0.x_max": 1000.0}
    mixture = {**MIXTURE, **WALLS47, "rheology": {"name": "dilatant_coulomb", "delta_deg": 22.5, "K1": 90.5},
               "material.particle_density": 2500.0}  # fmt: skip
    wide = {"domain.width": 0.1, "walls": {"name": "wall_friction", "mu_w": 0.2}}
    nh = {"model": {"pressure": "non_hydrostatic"}, "domain.layers": 8, "slope_deg": 0.0}
    column = {"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05}  # TINY's
    edges: list[tuple[str, dict, str]] = [
        # thickness
        ("a column of 10 um between walls", {**WALLS47, "initial.0.height": 1e-5}, closed),
        ("a column 1 % above the dry threshold", {**WALLS47, "initial.0.height": 1.01e-6}, closed),
        ("a column of 1 km (domain 5 km)", {**WALLS47, **big, "initial.0.height": 1000.0, "time.end": 1.0,
                                            "time.output_interval": 0.1}, closed),  # fmt: skip
        ("a layer of 2 um at rest", {**LAYER47, "initial.0.thickness": 2e-6}, rest),
        ("a layer of 10 km at rest", {**LAYER47, "initial.0.thickness": 1e4}, rest),
        # layers
        ("1 layer between walls", {**WALLS47, "domain.layers": 1}, closed),
        ("1 layer at rest", {**LAYER47, "domain.layers": 1}, rest),
        ("200 layers between walls", {**WALLS47, "domain.layers": 200}, closed),
        ("64 layers at rest", {**LAYER47, "domain.layers": 64}, rest),
        ("8 layers, geometric fractions r = 10", {**WALLS47, "domain.layers": 8,
                                                  "domain.layer_fractions": {"geometric": 10.0}}, closed),
        ("8 layers, geometric fractions r = 0.1", {**WALLS47, "domain.layers": 8,
                                                   "domain.layer_fractions": {"geometric": 0.1}}, closed),
        ("3 layers, fractions 1e-6 and two halves",
         {**WALLS47, "domain.layer_fractions": [1e-6, 0.4999995, 0.4999995]}, closed),
        # grains and rheologies
        ("Jop mu(I), grains of 1 nm", {**WALLS47, "rheology": jop, "material.grain_diameter": 1e-9}, closed),
        ("Jop mu(I), grains of 0.5 m (the domain, 10 times the column)", {**WALLS47, "rheology": jop,
                                                            "material.grain_diameter": 0.5}, closed),
        ("Jop mu(I) at rest", {**LAYER47, "rheology": jop}, rest),
        ("Jop mu(I) with mu_start and mu_inf", {**WALLS47, "rheology": {**jop, "mu_start": 0.45,
                                                                        "mu_inf": 1e-3}}, closed),
        ("Jop mu(I), I_0 = 1e-6", {**WALLS47, "rheology": {**jop, "I_0": 1e-6}}, closed),
        ("power-law mu(I), m = 0.01", {**WALLS47, "rheology": {"name": "power_law_mu_i", "mu_s": 0.3,
                                                               "m": 0.01, "alpha": 1.0}}, closed),
        ("power-law mu(I) at rest", {**LAYER47, "rheology": {"name": "power_law_mu_i", "mu_s": 0.3, "m": 1.0,
                                                             "alpha": 1.0}}, rest),
        ("Pouliquen-Forterre between walls", {**WALLS47, "rheology": pf}, closed),
        ("Pouliquen-Forterre, a layer below h_stop at rest", {**LAYER47, "rheology": pf, "slope_deg": 22.0,
                                                              "initial.0.thickness": 1e-3}, rest),
        ("Pouliquen-Forterre, L = 1e-9", {**WALLS47, "rheology": {**pf, "L": 1e-9}}, closed),
        ("dilatant Coulomb, dry", {**WALLS47, "rheology": {"name": "dilatant_coulomb", "delta_deg": 22.5,
                                                           "K1": 90.5}}, closed),
        # slopes
        ("a layer 0.001 degree below the friction angle at rest",
         {**LAYER47, "slope_deg": friction - 1e-3}, rest),
        ("a layer 0.001 degree above the friction angle", {**LAYER47, "slope_deg": friction + 1e-3}, closed),
        ("slope 89.999 degrees between walls", {**WALLS47, "slope_deg": 89.999}, closed),
        ("slope -89.999 degrees between walls", {**WALLS47, "slope_deg": -89.999}, closed),
        ("slope 89.999 degrees, periodic", {**PERIODIC47, "slope_deg": 89.999, "time.end": 0.05,
                                            "time.output_interval": 0.01}, closed),  # fmt: skip
        # friction
        ("mu_s 0 and nu 1e-6 between walls", {**WALLS47, "rheology": {**dp, "mu_s": 0, "nu": 1e-6}}, closed),
        ("mu_s 0 and nu 0 between walls", {**WALLS47, "rheology": {**dp, "mu_s": 0.0, "nu": 0.0}}, closed),
        ("mu_s 1e6 at rest on a 60 degree slope", {**LAYER47, "slope_deg": 60.0,
                                                   "rheology": {**dp, "mu_s": 1e6}}, rest),
        ("mu_s 1e100, a rectangle at rest", {**WALLS47, "rheology": {**dp, "mu_s": 1e100}}, rest),
        ("nu 1e6 between walls", {**WALLS47, "rheology": {**dp, "nu": 1e6}}, closed),
        ("a coulomb base of mu 0", {**WALLS47, "base": [{"condition": "coulomb", "mu": 0.0}]}, closed),
        ("a coulomb base of mu 1e6 at rest", {**LAYER47, "slope_deg": 60.0,
                                              "base": [{"condition": "coulomb", "mu": 1e6}]}, ""),
        ("a free-slip base, periodic", {**PERIODIC47, "base": [{"condition": "free_slip"}]}, closed),
        # domains
        ("a domain of 1 mm", {**WALLS47, "domain.x_max": 1e-3, "initial.0.x_max": 2e-4,
                              "initial.0.height": 1e-4, "numerics": {"front_threshold": 1e-5}}, closed),
        ("a domain of 1000 km", {**WALLS47, "domain.x_max": 1e6, "initial.0.x_max": 2e5,
                                 "initial.0.height": 100.0, "time.end": 10.0, "time.output_interval": 1.0},
         closed),
        ("a domain at x = 1e6 m", {**WALLS47, "domain.x_min": 1e6, "domain.x_max": 1e6 + 0.5,
                                   "initial.0.x_min": 1e6, "initial.0.x_max": 1e6 + 0.1}, closed),
        ("1 cell, a layer at rest between walls", {**LAYER47, **WALLS47, "domain.cells": 1}, rest),
        ("1 cell, periodic", {**PERIODIC47, "domain.cells": 1, "slope_deg": 40.0,
                              "initial.0": {"shape": "layer", "thickness": 0.01}}, closed),
        ("2 cells, a column between walls", {**WALLS47, "domain.cells": 2, "initial.0.x_max": 0.25}, closed),
        ("20000 cells between walls", {**WALLS47, "domain.cells": 20000, "time.end": 0.01,
                                       "time.output_interval": 0.005}, closed),
        # time
        ("cfl 0.001", {**WALLS47, "time.cfl": 0.001, "time.end": 0.01, "time.output_interval": 0.01}, closed),
        ("cfl 0.999", {**WALLS47, "time.cfl": 0.999}, closed),
        ("cfl 0.999, first order", {**WALLS47, "time.cfl": 0.999, "numerics": {"order": 1}}, closed),
        ("cfl 0.999, periodic", {**PERIODIC47, "time.cfl": 0.999}, closed),
        ("output interval equal to time.end", {**WALLS47, "time.output_interval": 0.2}, closed),
        ("1000 outputs", {**WALLS47, "time.output_interval": 0.2 / 1000}, closed),
        ("numerics.tolerance 1e-14", {**WALLS47, "rheology": jop, "numerics": {"tolerance": 1e-14}}, closed),
        ("numerics.max_iterations 1, Drucker-Prager", {**WALLS47, "numerics": {"max_iterations": 1}}, closed),
        # walls, erodible beds, gate
        ("side walls of mu_w 0", {**WALLS47, **wide, "walls.mu_w": 0.0}, closed),
        ("side walls 1 mm apart of mu_w 1, a rectangle at rest", {**WALLS47, **wide, "domain.width": 1e-3,
                                                                 "walls.mu_w": 1.0}, ""),
        ("side walls 1 km apart", {**WALLS47, **wide, "domain.width": 1e3}, closed),
        ("an erodible bed of 10 um", {**WALLS47, "initial": [{"shape": "layer", "thickness": 1e-5},
                                                             column]}, closed),
        ("an erodible bed of 1 m", {**WALLS47, "initial": [{"shape": "layer", "thickness": 1.0},
                                                           column]}, closed),
        ("a gate lifted at once", {**WALLS47, "gate": {"x": 0.1, "lift_speed": INF}}, closed),
        ("a gate never lifted", {**WALLS47, "gate": {"x": 0.1, "lift_speed": 0.0}}, closed),
        ("a gate at the last face", {**WALLS47, "gate": {"x": 0.49375, "lift_speed": 1.0}}, closed),
        # pressure models
        ("non-hydrostatic, 1 pressure layer", {**WALLS47, **nh, "model.pressure_layers": 1}, closed),
        ("non-hydrostatic, 8 pressure layers of 8", {**WALLS47, **nh, "model.pressure_layers": 8}, closed),
        ("non-hydrostatic, 1 layer", {**WALLS47, **nh, "domain.layers": 1}, closed),
        ("non-hydrostatic with vertical shear, periodic", {**PERIODIC47, **nh,
                                                           "model.vertical_shear": True}, closed),
        ("non-hydrostatic, a layer at rest", {**LAYER47, **nh, "slope_deg": 10.0}, rest),
        ("bim2016 pressure", {**WALLS47, "model": {"pressure": "bim2016"}}, closed),
        ("normal stress, periodic", {**PERIODIC47, "model": {"normal_stress": True}}, closed),
        # mixtures
        ("mixture phi 0.01", {**mixture, "initial.0.phi": 0.01}, closed),
        ("mixture phi 0.74", {**mixture, "initial.0.phi": 0.74}, closed),
        ("mixture phi_critical and phi 0.74", {**mixture, "initial.0.phi": 0.74,
                                               "mixture.phi_critical": 0.74}, closed),
        ("mixture in a fluid of density 0 and viscosity 0", {**mixture, "fluid": {"density": 0.0,
                                                                                 "viscosity": 0.0}}, closed),
        ("mixture, compressibility 1", {**mixture, "fluid.compressibility": 1.0}, closed),
        ("mixture, compressibility 1e-300", {**mixture, "fluid.compressibility": 1e-300}, closed),
        # the rest of the accepted ranges
        ("gravity 1e-6", {**WALLS47, "gravity": 1e-6}, closed),
        ("gravity 1000", {**WALLS47, "gravity": 1000.0}, closed),
        ("density 1e-100", {**WALLS47, "material.density": 1e-100}, closed),
        ("density 1e10", {**WALLS47, "material.density": 1e10}, closed),
        ("an initial speed of 100 m/s, periodic",
         {**PERIODIC47, "initial.0.velocity": {"profile": "plug", "speed": 100.0}}, closed),
        ("dry threshold 1e-300", {**WALLS47, "numerics": {"dry_threshold": 1e-300}}, closed),
        ("an inflow of 1 mm at 1 mm/s", {"boundaries": {"left": "inflow", "right": "outflow", "inflow": {
            "thickness": 1e-3, "velocity": {"profile": "plug", "speed": 1e-3}}}}, ""),
    ]  # fmt: skip
    return [_edge47(name, changes, checks) for name, changes, checks in edges] + [
        _edge47(*_random47(seed)) for seed in range(4701, 4711)
    ]


ONE_MEMBER = "parameters:\n  rheology.mu_s: [0.3]\n"
"""The parameters of a sweep of one member (:func:`_sweep33`)."""


def _study_linked_to_itself(directory: Path) -> None:
    """A sweep of one member whose output directory ``study`` is a symbolic link to itself."""
    _sweep33(ONE_MEMBER)(directory)
    (directory / "study").symlink_to("study")


def _linked_result46(directory: Path) -> None:
    """A finished run in ``out`` and one in ``other``; ``out/result.nc`` a symbolic link to
    ``other/result.nc``."""
    _finished_run(directory)
    shutil.copytree(directory / "out", directory / "other")
    (directory / "out" / "result.nc").unlink()
    (directory / "out" / "result.nc").symlink_to(directory / "other" / "result.nc")


def _two_forms(directory: Path) -> None:
    """``a.yaml`` and ``b.yaml``: TINY named ``é`` in NFC and in NFD."""
    for stem, name in (("a", "\u00e9"), ("b", "e\u0301")):
        (directory / f"{stem}.yaml").write_text(yaml.safe_dump({**TINY, "name": name}))


def round_forty_eight() -> list[Case]:
    """The hostile cases of the forty-eighth round (docs/reliability.md): ``expect:``
    entries every run passes (an interval holding every value of its quantity: ``atol``
    0.45 or ``rtol`` 2 on a packing of 0.3, ``atol`` 1.8e308 on a front or a mass at 0,
    ``rtol`` 1 on a speed of 1e308) and a packing pinned beyond the densest packing of
    spheres, all validated; ``--resume`` to an end one ulp before or after a finished
    run's end (the result then claimed an end its records do not reach, and every reader
    refused it); file arguments ending in ``/`` or ``/.`` (``validate s.yaml/`` read
    ``s.yaml``); a Dask setting the local cluster cannot read, whose message Dask's log
    followed after a wait of 10 s; and, handled before, ``-o``, ``plot`` and ``export``
    of ``result.nc/``."""
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    resume = [*run, "--resume", "--set"]
    validate, check = ["validate", "{scenario}"], ["check", "{scenario}"]
    sweep = ["sweep", "{dir}/study.yaml", "-o", "{dir}/study", "--workers", "1", "-q"]
    study = ["{dir}/study.yaml", "-o", "{dir}/study", "--workers", "1", "-q"]
    unreadable = {"DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT": "abc"}
    nothing = "every run passes, a check of nothing"
    slash = "a path ending in '/'"
    kept = "the run is finished there and keeps time.end = 0.2 s"

    def pinned(quantity: str, value: float, **tolerance: float) -> Callable[[Path], Path]:
        """TINY (a mixture for a packing) with one regression pin."""
        entry = {"kind": "regression", "quantity": quantity, "value": value, **tolerance}
        mixture = MIXTURE32 if quantity == "phi_mean_final" else {}
        return partial(_scenario, changes={**mixture, "expect": [entry]})

    return [
        # expect: entries every run passes: (name, command, exit code, phrase, quantity, value, tolerance)
        *[Case(name, argv, code, phrase, setup=pinned(quantity, value, **tolerance))
          for name, argv, code, phrase, quantity, value, tolerance in [
            ("check: expect phi_mean_final 0.3, atol 0.45 (holds [0, 0.74048])", check, 2,
             "phi_mean_final = 0.3 +- 0.45 holds every value a run's phi_mean_final can take",
             "phi_mean_final", 0.3, {"atol": 0.45}),
            ("check: expect phi_mean_final 0.3, rtol 2", check, 2, "expect.0.rtol", "phi_mean_final", 0.3,
             {"rtol": 2.0}),
            ("validate: expect phi_mean_final 0.5, rtol 0.5 and atol 0.3", validate, 2, "expect.0.atol",
             "phi_mean_final", 0.5, {"rtol": 0.5, "atol": 0.3}),
            ("check: expect mass_final 0, atol 1.7976931348623157e308", check, 2, nothing, "mass_final", 0.0,
             {"atol": 1.7976931348623157e308}),
            ("validate: expect front_final 0, atol 1.7976931348623157e308", validate, 2, "expect.0.atol",
             "front_final", 0.0, {"atol": 1.7976931348623157e308}),
            ("validate: expect max_speed_final 1e308, rtol 1", validate, 2, "expect.0.rtol",
             "max_speed_final", 1e308, {"rtol": 1.0}),
            ("validate: expect phi_mean_final 0.7405, atol 0 (beyond the densest packing)", validate, 2,
             "no run passes (its phi_mean_final is in [0, 0.74048] (pi/sqrt(18)", "phi_mean_final", 0.7405,
             {"atol": 0.0}),
            ("control: validate of expect phi_mean_final 0.3, atol 0.44", validate, 0, "", "phi_mean_final",
             0.3, {"atol": 0.44}),
            ("control: validate of expect phi_mean_final at the densest packing, atol 0", validate, 0, "",
             "phi_mean_final", 0.7404804896930609, {"atol": 0.0}),
            ("control: check of expect mass_final 0.005, atol 1e308 (a mass beyond 1e308 fails)", check, 0,
             "", "mass_final", 0.005, {"atol": 1e308}),
          ]],
        # --resume to the end of a finished run, to the last digit
        Case("run --resume: time.end one ulp before a finished run's end",
             [*resume, "time.end=0.19999999999999998"], 2, "beyond time.end = 0.19999999999999998 s",
             setup=_finished_run),
        Case("run --resume: time.end 0.1 s before a finished run's end", [*resume, "time.end=0.1"], 2,
             "accepted: a time.end at or after 0.2 s", setup=_finished_run),
        Case("run --resume: time.end one ulp after a finished run's end, then plot",
             [*resume, "time.end=0.20000000000000004"], 0, kept, patch=THEN_PLOTTED, setup=_finished_run),
        Case("run --resume: time.end 0.9e-9 of it after a finished run's end, then plot",
             [*resume, "time.end=0.20000000018"], 0, kept, patch=THEN_PLOTTED, setup=_finished_run),
        Case("run --resume: time.end a finished run's own end, then plot", [*resume, "time.end=0.2"], 0,
             "the result's last record is at time.end = 0.2 s: the run is finished there",
             patch=THEN_PLOTTED, setup=_finished_run),
        Case("control: run --resume to 2e-9 of it after a finished run's end, then plot",
             [*resume, "time.end=0.2000000004"], 0, "", patch=THEN_PLOTTED, setup=_finished_run),
        # file arguments ending in a slash
        *[Case(f"{command}: its file followed by '/'", [command, "{dir}/scenario.yaml/"], 2,
               f"scenario.yaml/: {slash}", setup=_scenario)
          for command in ("run", "validate", "check", "sweep", "calibrate", "sensitivity")],
        Case("validate: the scenario followed by '/.'", ["validate", "{dir}/scenario.yaml/."], 2,
             "scenario.yaml/.: a path ending in '/.'", setup=_scenario),
        Case("validate: the scenario followed by '//'", ["validate", "{dir}/scenario.yaml//"], 2,
             f"scenario.yaml//: {slash}", setup=_scenario),
        Case("validate: a directory followed by '/'", ["validate", "{dir}/"], 2, slash, setup=_scenario),
        Case("validate: the second of two files followed by '/'", [*validate, "{dir}/scenario.yaml/"], 2,
             f"scenario.yaml/: {slash}", setup=_scenario),
        Case("control: validate of {dir}/./scenario.yaml", ["validate", "{dir}/./scenario.yaml"], 0, "",
             setup=_scenario),
        Case("plot: DIR result.nc/", ["plot", "{dir}/out/result.nc/"], 2, "a file, not a directory",
             setup=_finished_run),
        Case("export: DIR result.nc/", ["export", "{dir}/out/result.nc/", "--vtk"], 2,
             "a file, not a directory", setup=_finished_run),
        Case("run: -o result.nc/", [*run[:3], "{dir}/out/result.nc/", "-q"], 2, "a file, not a directory",
             setup=_finished_run),
        # a Dask setting the local cluster cannot read: its message alone, nothing logged after
        Case("sweep: DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc, the message alone", sweep, 2,
             "could not read its settings", env=unreadable, setup=_sweep33(ONE_MEMBER), one_message=True),
        Case("sensitivity: DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc, the message alone",
             ["sensitivity", *study], 2, "could not read its settings", env=unreadable,
             setup=_study41(SENSITIVITY_MU_S), one_message=True),
        Case("calibrate: DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc, the message alone",
             ["calibrate", *study], 2, "could not read its settings", env=unreadable,
             setup=_study41(CALIBRATION_MU_S), one_message=True),
    ]  # fmt: skip


RACE50 = """
import os, threading, time
import numpy as np
from multilayer.engine import simulation as engine
sim = multilayer.Simulation(multilayer.load(sys.argv[2]))
stepping, outcome = threading.Event(), []
engine_step = engine.Simulation.step
def step(self, t_max=np.inf):
    dt = engine_step(self, t_max)
    if not stepping.is_set():
        stepping.set()
        time.sleep(0.3)
    return dt
engine.Simulation.step = step
def called():
    stepping.wait()
    try:
        return CALL
    except InputError as exc:
        return exc
worker = threading.Thread(target=lambda: outcome.append(called()), daemon=True)
worker.start()
def on_step(s, dt):
    worker.join(30)
    if worker.is_alive():
        print('multilayer: the other thread waited for ever', file=sys.stderr)
        os._exit(3)
sim.advance(0.02, on_step=on_step)
if isinstance(outcome[0], InputError):
    raise outcome[0]
"""
"""A thread that calls ``CALL`` while ``advance`` is in its first step (held 0.3 s there),
and the ``on_step`` after that step waiting for it (exit 3 when it still waits after 30 s)."""

UNINTERRUPTED = """
alone = multilayer.Simulation(multilayer.load(sys.argv[2]))
alone.advance(sim.t)
assert np.array_equal(sim.h, alone.h) and np.array_equal(sim.u, alone.u), 'not the uninterrupted state'
"""
"""The end of an API case: ``sim`` holds the state of an uninterrupted run to its time."""

STEPPED_AGAIN = """
import math
import multilayer
from multilayer.errors import RunError
sim = multilayer.Simulation(multilayer.load(sys.argv[2]))
sim.step()
sim.h[3] = math.nan
for attempt in range(2):
    try:
        sim.step()
    except RunError as exc:
        said = str(exc)
print(f'multilayer: run failed: {said}', file=sys.stderr)
sys.exit(1)
"""
"""A NaN written into ``sim.h`` and the simulation stepped twice: the second message printed."""

LAW50 = '''
import os, signal, tempfile
import numpy as np
import multilayer
{head}

def memmapped(a):
    m = np.memmap(tempfile.TemporaryFile(), dtype=float, mode="w+", shape=np.shape(a))
    m[...] = a
    return m

def frozen(a):
    v = np.asarray(a).view()
    v.flags.writeable = False
    return v

class Law(multilayer.Rheology):
    """Drucker-Prager friction and a constant viscosity (round fifty)."""
    name = "{name}"
    applies_to = "bulk"
    def __init__(self, mu_s: float = 0.3, eta: float = 15.0):
        self.mu_s, self.eta = mu_s, eta
    def yield_stress(self, pressure, material):
        return {wrap}(self.mu_s * np.maximum(pressure, 0.0))
    def viscosity(self, shear_rate, pressure, material):
        return {wrap}(np.full(np.broadcast_shapes(np.shape(shear_rate), np.shape(pressure)), self.eta))
    def viscosity_kernel(self, material):
        return {form}

@multilayer.hookimpl
def multilayer_register_rheologies({register}):
    {register}(Law)
'''
"""A third-party law of round fifty, its module's ``head`` run as it is imported, its
values passed through ``wrap`` and its compiled viscosity form ``form``."""


def _law50(
    head: str = "", wrap: str = "", form: str = "None", register: str = "register"
) -> Callable[[Path], None]:
    """TINY on the law :data:`LAW50` installed through its entry point (PYTHONPATH ``{dir}/plugin``)."""

    def setup(directory: Path) -> None:
        module = LAW50.format(head=head, name="law50", wrap=wrap, form=form, register=register)
        _plugin_package(directory, "law50", module)
        _scenario(directory, {"rheology": {"name": "law50"}})

    return setup


def _study_elsewhere(base_here: bool) -> Callable[[Path], None]:
    """A sweep of one member in ``studies/``, its base ``scenario.yaml`` in the case's
    directory (the working directory) if ``base_here``, beside the sweep file otherwise."""

    def setup(directory: Path) -> None:
        studies = directory / "studies"
        studies.mkdir()
        _scenario(directory if base_here else studies)
        (studies / "sweep.yaml").write_text("base: scenario.yaml\n" + ONE_MEMBER)

    return setup


def _bed_in_the_working_directory(directory: Path) -> None:
    """``inputs/scenario.yaml`` reading ``bed.file: bed.csv``, which is in the case's directory."""
    (directory / "inputs").mkdir()
    _scenario(directory / "inputs", {"bed": {"file": "bed.csv"}})
    (directory / "bed.csv").write_text("x (m), z (m)\n0, 0\n0.5, 0\n")


def round_fifty() -> list[Case]:
    """The hostile cases of the fiftieth round (docs/reliability.md), the Python API and the
    plugin contract as a notebook and a third-party law's author meet them: a thread that
    called while ``advance`` was in a step, joined by the ``on_step`` after it (both held
    for ever); an ``on_step`` that is an ``async def`` or a generator function, or returns
    a coroutine (its body never ran, silently); a state refused on entry and stepped again
    unchanged (then blamed on the transport); a plugin's module that changes the working
    directory, numpy's error handling or the SIGINT handler as it is imported (the host
    changed for good); a compiled viscosity form other than the plugin's ``viscosity``
    (another flow, silently); ``sweep /dev/stdin`` and ``validate /dev/stdin`` reading
    their relative paths from ``/dev``; and, handled before, ``sys.exit``, Ctrl-C and
    ``multilayer.run`` inside an ``on_step``, the state's arrays made read-only or reshaped
    by the user, a result whose file was deleted, plugin values as ``np.matrix``, memmaps
    and read-only views, a hook implementation of another signature."""
    validate = ["validate", "{scenario}"]
    run = ["run", "{scenario}", "-o", "{dir}/out", "-q"]
    plugin = {"PYTHONPATH": "{dir}/plugin"}
    refused = "from another thread while the on_step of advance runs"
    changed = "importing and registering it changed the "
    not_viscosity = "which is not its viscosity()"
    redirected = ["sh", "-c", 'exec "$0" "$@" < "$STREAM"']
    sweep = ["sweep", "/dev/stdin", "-o", "{dir}/study", "--workers", "1", "-q"]
    study = {"STREAM": "{dir}/studies/sweep.yaml"}
    return [
        # a thread waiting for a step under way, joined by the on_step after it
        *[Case(f"API: a thread calling {call} during a step, joined by the next on_step", validate, 2,
               refused, patch=_api(RACE50.replace("CALL", call)), setup=_scenario)
          for call in ("sim.step()", "sim.advance(0.05)", "sim.load_state(sim.state_dict())")],
        Case("control: a thread reading state_dict() during a step, joined by the next on_step", validate, 0,
             "", patch=_api(RACE50.replace("CALL", "sim.state_dict()['t']")), setup=_scenario),
        # on_steps whose body never runs
        *[Case(f"API: {name} as on_step", validate, 2, phrase,
               patch=_api(ON_STEP + body + "sim.advance(0.02, on_step=on_step)"), setup=_scenario)
          for name, body, phrase in [
              ("an async def", "async def on_step(s, dt):\n    pass\n", "an async function (async def)"),
              ("a generator function", "def on_step(s, dt):\n    yield dt\n",
               "a generator function (it yields)"),
              ("a function returning a coroutine", "async def later(s, dt):\n    pass\n"
               "on_step = lambda s, dt: later(s, dt)\n", "returned coroutine"),
          ]],
        # what an on_step does to the host, handled before
        Case("control: sys.exit in on_step, then advance continues the run", validate, 0, "",
             patch=_api(ON_STEP + "def leave(s, dt):\n    sys.exit(3)\ntry:\n"
                        "    sim.advance(0.04, on_step=leave)\nexcept SystemExit:\n    pass\n"
                        "sim.advance(0.04)\n" + UNINTERRUPTED), setup=_scenario),
        Case("control: KeyboardInterrupt in the third on_step, then advance to the same state", validate,
             0, "",
             patch=_api(ON_STEP + "calls = [0]\ndef stop(s, dt):\n    calls[0] += 1\n    if calls[0] == 3:\n"
                        "        raise KeyboardInterrupt\ntry:\n    sim.advance(0.04, on_step=stop)\n"
                        "except KeyboardInterrupt:\n    pass\nsim.advance(0.04)\n" + UNINTERRUPTED),
             setup=_scenario),
        Case("control: multilayer.run called inside on_step", validate, 0, "",
             patch=_api(ON_STEP + "def nested(s, dt):\n    ds = multilayer.run(multilayer.load(sys.argv[2], "
                        "overrides={'time.end': 0.02}))\n    assert float(ds['mass'][-1]) > 0\n"
                        "sim.advance(0.01, on_step=nested)\n" + UNINTERRUPTED), setup=_scenario),
        # the state's arrays between steps
        Case("API: a NaN written into sim.h, stepped twice", validate, 1, "on entry to the step",
             patch=STEPPED_AGAIN, setup=_scenario),
        Case("control: sim.h made read-only by the user between steps", validate, 0, "",
             patch=_api(ON_STEP + "sim.step()\nview = sim.h\nview.flags.writeable = False\n"
                        "sim.advance(0.04)\n" + UNINTERRUPTED), setup=_scenario),
        Case("control: sim.u reshaped in place by the user between steps", validate, 0, "",
             patch=_api(ON_STEP + "sim.step()\nsim.u.shape = (40, 3)\nsim.advance(0.04)\n" + UNINTERRUPTED),
             setup=_scenario),
        Case("control: a result of multilayer.run whose result.nc was deleted", validate, 0, "",
             patch=_api("import os\nout = os.path.join(os.path.dirname(sys.argv[2]), 'out')\n"
                        "ds = multilayer.run(multilayer.load(sys.argv[2], overrides={'time.end': 0.04}),"
                        " out)\nos.remove(os.path.join(out, 'result.nc'))\n"
                        "assert float(ds['h'].isel(time=-1).sum()) > 0"),
             setup=_scenario),
        # a plugin's module changing the process as it is imported
        Case("run: a plugin's module changing the working directory as it is imported", run, 2,
             changed + "working directory", env=plugin, setup=_law50(head='os.chdir("/")')),
        Case("run: a plugin's module calling np.seterr(all='ignore') as it is imported", run, 2,
             changed + "numpy error handling", env=plugin, setup=_law50(head='np.seterr(all="ignore")')),
        Case("run: a plugin's module ignoring SIGINT as it is imported", run, 2,
             changed + "handler of SIGINT", env=plugin,
             setup=_law50(head="signal.signal(signal.SIGINT, signal.SIG_IGN)")),
        Case("run: a hook implementation of another signature", run, 2,
             "are declared in the hookimpl but can not be found in the hookspec", env=plugin,
             setup=_law50(register="reg")),
        # plugin values of numpy's other kinds
        *[Case(f"control: run of a plugin returning {kind}", run, 0, "", env=plugin, setup=_law50(wrap=wrap))
          for kind, wrap in [("np.matrix values", "np.asmatrix"), ("memmaps", "memmapped"),
                             ("read-only views", "frozen")]],
        # compiled forms other than the plugin's viscosity
        Case("run: a compiled form of 100 times the plugin's viscosity", run, 1, not_viscosity, env=plugin,
             setup=_law50(form="('constant', (100 * self.eta,))"), keeps_output=True),
        Case("run: a compiled form one part in a million off the plugin's viscosity", run, 1, not_viscosity,
             env=plugin, setup=_law50(form="('constant', (self.eta * (1 + 1e-6),))"), keeps_output=True),
        Case("run: an inertial form declared for a constant viscosity", run, 1, not_viscosity, env=plugin,
             setup=_law50(form="('inertial', (1.0, 1.0, 1.0))"), keeps_output=True),
        Case("control: run of a plugin declaring its own compiled form", run, 0, "", env=plugin,
             setup=_law50(form="('constant', (self.eta,))")),
        # a stream as the file: its relative paths read from the working directory
        Case("control: sweep /dev/stdin from studies/sweep.yaml, its base in the working directory", sweep, 0,
             "", prefix=redirected, env=study, here=True, setup=_study_elsewhere(base_here=True)),
        Case("sweep: /dev/stdin from studies/sweep.yaml, its base beside it only", sweep, 2,
             "relative to the working directory (/dev/stdin names a stream", prefix=redirected, env=study,
             here=True, setup=_study_elsewhere(base_here=False)),
        Case("control: validate /dev/stdin from inputs/scenario.yaml, its bed in the working directory",
             ["validate", "/dev/stdin"], 0, "", prefix=redirected,
             env={"STREAM": "{dir}/inputs/scenario.yaml"}, here=True, setup=_bed_in_the_working_directory),
    ]  # fmt: skip


RESULTS49 = """
_physics = main


def main(argv):
    code = _physics(argv)
    if code or argv[0] != 'run':
        return code
    import os, signal
    import netCDF4
    from multilayer.app.simulation import Simulation
    checks = os.environ['PHYSICS'].split(',')
    out, scenario = argv[argv.index('-o') + 1], argv[1]
    said, done = [], []

    def records(directory):
        with netCDF4.Dataset(directory + '/result.nc') as ds:
            return {k: np.asarray(ds[k][:]) for k in ('time', 'h', 'u', 'phi') if k in ds.variables}

    for check in checks:
        what, _, value = check.partition('=')
        if what == 'gate':  # a closed gate at x, a wall on the left: nothing passes the gate
            with netCDF4.Dataset(out + '/result.nc') as ds:
                h, bounds = np.asarray(ds['h'][:]), np.asarray(ds['x_bnds'][:])
                steps = int(ds.getncattr('steps'))
                solid = np.asarray(ds['phi'][:]) if 'phi' in ds.variables else np.ones_like(h)
            face = bounds[np.argmin(np.abs(bounds[:, 0] - float(value))), 0]
            behind = bounds[:, 1] <= face
            volume = (solid * h)[:, behind] @ np.diff(bounds[behind], axis=1)[:, 0]
            drift = abs(volume[-1] - volume[0]) / volume[0]
            if not drift <= 8 * np.finfo(float).eps * (steps + 1):
                said.append(f'the volume behind the closed gate changed by {drift:.3g} of itself')
            if (h[0, ~behind] == 0).all() and (h[:, ~behind] != 0).any():  # dry beyond it at the start
                said.append(f'{float(h[:, ~behind].max()):.3g} m passed the closed gate')
            done.append('gate')
        elif what in ('resume', 'interrupt'):  # stopped, then --resume'd: the unbroken run to the bit
            again = [*argv[:argv.index('-o')], '-o', out + '_' + what, *argv[argv.index('-o') + 2:]]
            if what == 'resume':  # stopped at the output time `value`, resumed to time.end
                first = _command([*again, '--set', 'time.end=' + value])
            else:  # SIGINT at step `value`
                step = Simulation.step

                def stopping(self, t_max=float('inf')):
                    calls[0] += 1
                    if calls[0] == int(value):
                        os.kill(os.getpid(), signal.SIGINT)
                    return step(self, t_max)

                Simulation.step = stopping
                first = _command(again)
                Simulation.step = step
            second = _command([*again, '--resume'])
            a, b = records(out), records(out + '_' + what)
            same = a.keys() == b.keys() and all(np.array_equal(a[k], b[k]) for k in a)
            if (first, second) != ((0, 0) if what == 'resume' else (130, 0)) or not same:
                said.append(f'{what} at {value}: exits {first}, {second}, equal to the unbroken run: {same}')
            done.append(what)
        elif what == 'plot':
            if _command(['plot', out, '--times', '2']) != 0:
                said.append('plot failed')
            done.append('plot')
    if _command(['export', out, '--vtk']) != 0:
        said.append('export --vtk failed')
    summary = '; '.join(said) or 'checked ' + ', '.join([*done, 'export'])
    print('multilayer: results: ' + summary, file=sys.stderr)
    return 1 if said else 0
"""
"""After :data:`PHYSICS47`, more of ``PHYSICS`` (comma-separated): ``gate=X``, a closed gate
at ``X`` behind a wall: the volume behind it conserved to ``8 eps`` per step and, where
nothing lay beyond it at the start, ``h`` 0.0 there at every output; ``resume=T``, the run stopped at the
output time ``T`` and ``--resume``d, ``interrupt=N``, given SIGINT at its step ``N`` and
``--resume``d: its records (``time``, ``h``, ``u``, ``phi``) equal the unbroken run's to
the bit; ``plot``: ``multilayer plot`` succeeds; always ``multilayer export --vtk``."""


def _dem49(directory: Path) -> None:
    """``terrain.tif``: a plane falling at TINY's 25 degrees towards +X with a bump of 1 cm,
    in UTM metres, pixels of 1 cm (read only with the optional rasterio)."""
    import rasterio
    from rasterio.transform import Affine

    X = np.arange(80) * 0.01
    elevation = -np.tan(np.radians(25.0)) * X + 0.01 * np.exp(-(((X - 0.3) / 0.05) ** 2))
    with rasterio.open(directory / "terrain.tif", "w", driver="GTiff", height=20, width=80, count=1,
                       dtype="float64", crs="EPSG:32632",
                       transform=Affine(0.01, 0.0, 1000.0, 0.0, -0.01, 5000.0)) as dem:  # fmt: skip
        dem.write(np.tile(elevation, (20, 1)), 1)


def _bed_csv49(directory: Path) -> None:
    (directory / "bed.csv").write_text("x (m), z (mm)\n0.0, 0\n0.2, 0\n0.3, 8\n0.4, 0\n0.5, 0\n")


@dataclass
class Feature49:
    """A feature a scenario switches on: its ``changes`` to TINY (a function of the
    scenario's data), the files it reads, and whether a layer under its yield stays at rest
    with it."""

    name: str
    group: str  # features of one group exclude each other (one rheology, one pair of ends)
    change: Callable[[dict], None]
    files: Callable[[Path], None] | None = None
    rest: bool = True


def _features49() -> list[Feature49]:
    def ends(left: str, right: str, inflow: dict | None = None) -> Callable[[dict], None]:
        def change(data: dict) -> None:
            data["boundaries"] = {"left": left, "right": right, **({"inflow": inflow} if inflow else {})}

        return change

    def merge(**changes: Any) -> Callable[[dict], None]:
        def change(data: dict) -> None:
            for key, value in changes.items():
                node, parts = data, key.split("__")
                for part in parts[:-1]:
                    node = node.setdefault(part, {})
                node[parts[-1]] = copy.deepcopy(value)

        return change

    def added(*entries: dict) -> Callable[[dict], None]:
        return lambda data: data["initial"].extend(copy.deepcopy(entries))

    def mixture(compressibility: float | None) -> Callable[[dict], None]:
        def change(data: dict) -> None:
            data["fluid"] = {"density": 1000.0, "viscosity": 1e-3}
            if compressibility is not None:
                data["fluid"]["compressibility"] = compressibility
            data["mixture"] = {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0}
            data["material"]["particle_density"] = 2500.0
            if data["rheology"]["name"] == "drucker_prager":  # a mixture's own law, unless another is drawn
                data["rheology"] = {"name": "dilatant_coulomb", "delta_deg": 22.5, "K1": 90.5}
            for entry in data["initial"]:
                entry["phi"] = 0.58

        return change

    plug = {"profile": "plug", "speed": 0.2}
    dem = {"profile": "dem", "dem": "terrain.tif", "polyline": [[1000.005, 4999.9], [1000.7, 4999.9]]}
    features = [
        Feature49("periodic ends", "ends", ends("periodic", "periodic")),
        Feature49("walls at both ends", "ends", ends("wall", "wall")),
        Feature49("an inflow", "ends", ends("inflow", "outflow", {"thickness": 0.01, "velocity": plug}),
                  rest=False),
        Feature49("a gate lifted at 0.5 m/s", "gate", merge(gate={"x": 0.1, "lift_speed": 0.5})),
        Feature49("a closed gate", "gate", merge(gate={"x": 0.1, "lift_speed": 0.0})),
        Feature49("side walls", "walls", merge(domain__width=0.1,
                                               walls={"name": "wall_friction", "mu_w": 0.2})),
        Feature49("an erodible bed", "bed layer", added({"shape": "layer", "thickness": 0.005})),
        Feature49("non-hydrostatic", "pressure", merge(model__pressure="non_hydrostatic")),
        Feature49("normal stress", "normal stress", merge(model__normal_stress=True)),
        Feature49("Jop mu(I)", "law", merge(rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64,
                                                        "I_0": 0.3})),
        Feature49("power-law mu(I)", "law", merge(rheology={"name": "power_law_mu_i", "mu_s": 0.3, "m": 1.0,
                                                              "alpha": 1.0})),
        Feature49("Pouliquen-Forterre", "law", merge(rheology={"name": "pouliquen_forterre", "mu_1": 0.38,
                                                                 "mu_2": 0.64, "L": 1e-3, "I_0": 0.3})),
        Feature49("a mixture", "fluid", mixture(None), rest=False),
        Feature49("a compressible mixture", "fluid", mixture(1e-7), rest=False),
        Feature49("one layer", "layers", merge(domain__layers=1)),
        Feature49("8 geometric layers", "layers", merge(domain__layers=8,
                                                        domain__layer_fractions={"geometric": 1.5})),
        Feature49("a bed of points", "bed", merge(bed={"points": [[0.0, 0.0], [0.25, 0.01], [0.5, 0.0]]})),
        Feature49("a bed from a CSV file", "bed", merge(bed={"file": "bed.csv"}), files=_bed_csv49),
        Feature49("three shapes, moving", "shapes", added(
            {"shape": "rectangle", "x_min": 0.2, "x_max": 0.3, "height": 0.02, "velocity": plug},
            {"shape": "profile", "points": [[0.3, 0.0], [0.35, 0.01], [0.4, 0.0]]}), rest=False),
    ]  # fmt: skip
    if importlib.util.find_spec("rasterio") is not None:  # the optional [dem] extra
        features.append(Feature49("a DEM bed", "bed", merge(bed=dem), files=_dem49, rest=False))
    return features


REST49 = Feature49("a layer under its yield", "shapes", lambda data: data.update(
    slope_deg=10.0, initial=[{"shape": "layer", "thickness": 0.01}]))  # fmt: skip
"""A uniform 1 cm layer on a 10 degree slope, below the friction angle of every law drawn
(16.7 degrees for TINY's ``mu_s`` 0.3, the beds' bumps included): at rest for ever."""


def _combined49(features: tuple[Feature49, ...]) -> tuple[dict, Callable[[Path], None], str]:
    """TINY (20 cells, to 0.1 s) with ``features`` switched on (the layer under its yield
    first, a mixture last: it gives every initial entry its packing), the setup writing it
    and the files it reads, and the checks of :data:`RESULTS49` its result must pass."""
    data = {**json.loads(json.dumps(TINY)), "time": {"end": 0.1, "output_interval": 0.02}}
    data["domain"]["cells"] = 20  # cheap: the gate at 0.1 m still on a face
    for feature in sorted(features, key=lambda f: (f is not REST49, f.group == "fluid")):
        feature.change(data)
    sides = data["boundaries"]["left"], data["boundaries"]["right"]
    closed = all(side in ("wall", "periodic") for side in sides)
    checks = ["closed"] if closed else []
    if closed and REST49 in features and all(f.rest for f in features):
        checks.append("rest")
    if data.get("gate", {}).get("lift_speed") == 0.0 and sides[0] == "wall":
        checks.append(f"gate={data['gate']['x']}")
    text = yaml.safe_dump(data)

    def setup(directory: Path) -> None:
        _scenario(directory, text=text)
        for feature in features:
            if feature.files is not None:
                feature.files(directory)

    return data, setup, ",".join(checks)


FLUID_REFUSES49 = {"pressure": "model.pressure", "normal stress": "model.normal_stress", "walls": "walls",
                   "gate": "gate", "law": "rheology", "ends": "boundaries"}  # fmt: skip
"""The key named when a feature of the group is refused with a fluid (docs/scenarios.md,
"fluid and mixture": hydrostatic pressure, no normal stress, no walls or gate, a law of the
pressure and shear rate only, wall, outflow or periodic sides), in the order named."""


STOPS49 = {
    "normal stress + power-law mu(I)": (1, "stress changes by less than the pressure (|d tau / d p| < 1)"),
}
"""The combinations whose run stops with a message naming a true limit: the power law's
``mu(I) = 0.3 + I`` passes 1 at the front (``I`` about 1), where the normal stress's passive
pressure ``-tau / (1 - d tau / d p)`` is unbounded (docs/model.md, "Longitudinal normal
stress"; Rankine's states need ``sin(phi) = mu < 1``)."""

SLOW49 = {(law, mixture) for law in ("Jop mu(I)", "power-law mu(I)")
          for mixture in ("a mixture", "a compressible mixture")}  # fmt: skip
"""Pairs left out: a mu(I) law in a mixture of three layers.  Its local Newton iteration
now converges in a few iterations, but the run stops (exit 1, in about 20 s under Jop's;
at 20 cells where a thin, loose front column sheared at an effective pressure of about 1 Pa
dilates so fast that the exchange between its layers would move more than a quarter of a
layer's solid, at every sub-step): docs/reliability.md."""


def _case49(features: tuple[Feature49, ...], extra: str = "") -> Case:
    """The run of TINY with ``features`` (its checks and ``extra`` ones), or, where
    ``validate`` refuses the combination with a fluid, that refusal: exit 2, one message
    naming the key."""
    data, setup, checks = _combined49(features)
    name = " + ".join(f.name for f in features)
    if "fluid" in data:
        groups = {f.group for f in features}
        refused = [key for group, key in FLUID_REFUSES49.items() if group in groups]
        law, sides = data["rheology"]["name"], data["boundaries"]
        refused = [key for key in refused if key != "rheology" or law == "pouliquen_forterre"]
        refused = [key for key in refused if key != "boundaries" or "inflow" in sides]
        if refused:  # one message, at the first key, naming the others
            others = f"not supported with a fluid (nor are {', '.join(refused[1:])})"
            phrase = others if refused[1:] else f"{refused[0]} (line"
            return Case(f"validate: {name}", ["validate", "{scenario}"], 2, phrase, setup=setup,
                        one_message=True)  # fmt: skip
    code, phrase = STOPS49.get(name, (0, "multilayer: results:"))
    return Case(name, ["run", "{scenario}", "-o", "{dir}/out", "-q"], code, phrase,
                patch=PHYSICS47 + RESULTS49, env={"PHYSICS": ",".join(filter(None, [checks, extra]))},
                setup=setup)  # fmt: skip


def _random49(seed: int, features: list[Feature49]) -> tuple[Feature49, ...]:
    """A seeded draw of one feature or none from every group (reproducible)."""
    draw = np.random.default_rng(seed)
    groups = sorted({f.group for f in features})
    chosen = []
    for group in groups:
        members = [f for f in features if f.group == group]
        pick = int(draw.integers(len(members) + 1))
        if pick < len(members):
            chosen.append(members[pick])
    return tuple(chosen)


def round_forty_nine() -> list[Case]:
    """The valid cases of the forty-ninth round (docs/reliability.md): the features a
    scenario switches on (ends, gates, side walls, an erodible bed, the pressure models, the
    normal stress, the built-in laws, mixtures, layers, beds of points, files and DEMs,
    several initial shapes, a layer under its yield) in every pair of two groups, a few
    triples and seeded random draws, each run checked as a physicist would
    (:data:`PHYSICS47`, :data:`RESULTS49`: the volume of a closed domain conserved, a layer
    under its yield at rest, nothing through a closed gate, ``export``, for a sample
    ``plot`` and a stop or SIGINT then ``--resume`` equal to the unbroken run to the bit),
    or refused by ``validate`` with one message naming the keys a fluid excludes."""
    features = [*_features49(), REST49]
    named = {f.name: f for f in features}
    pairs = [pair for pair in itertools.combinations(features, 2)
             if pair[0].group != pair[1].group and (pair[0].name, pair[1].name) not in SLOW49]  # fmt: skip
    triples = [tuple(named[n] for n in names) for names in [
        ("a closed gate", "side walls", "an erodible bed"),
        ("non-hydrostatic", "normal stress", "8 geometric layers"),
        ("a compressible mixture", "8 geometric layers", "a bed from a CSV file"),
        ("an inflow", "Pouliquen-Forterre", "three shapes, moving"),
        ("periodic ends", "Jop mu(I)", "a layer under its yield"),
        ("walls at both ends", "a mixture", "a bed of points"),
        ("a gate lifted at 0.5 m/s", "non-hydrostatic", "side walls"),
        ("walls at both ends", "a closed gate", "a layer under its yield"),
    ]]  # fmt: skip
    draws = [_random49(seed, features) for seed in range(4901, 4907)]
    every = [*pairs, *triples, *draws]
    samples = {0: "plot", 1: "resume=0.06", 3: "interrupt=5"}  # each for one case in 18
    return [_case49(combo, samples.get(i % 18, "")) for i, combo in enumerate(every)]


ROUNDS: dict[int, Callable[[], list[Case]]] = {
    2: round_two, 3: round_three, 4: round_four, 5: round_five, 6: round_six, 7: round_seven,
    8: round_eight, 9: round_nine, 10: round_ten, 11: round_eleven, 12: round_twelve,
    13: round_thirteen, 14: round_fourteen, 15: round_fifteen, 16: round_sixteen,
    17: round_seventeen, 18: round_eighteen, 19: round_nineteen, 20: round_twenty,
    21: round_twenty_one, 22: round_twenty_two, 23: round_twenty_three, 24: round_twenty_four,
    25: round_twenty_five, 26: round_twenty_six, 27: round_twenty_seven,
    28: round_twenty_eight, 29: round_twenty_nine, 30: round_thirty, 31: round_thirty_one,
    32: round_thirty_two,
    33: round_thirty_three,
    34: round_thirty_four,
    35: round_thirty_five,
    37: round_thirty_seven,
    38: round_thirty_eight,
    39: round_thirty_nine,
    40: round_forty,
    41: round_forty_one,
    42: round_forty_two,
    43: round_forty_three,
    44: round_forty_four,
    45: round_forty_five,
    46: round_forty_six,
    47: round_forty_seven,
    48: round_forty_eight,
    49: round_forty_nine,
    50: round_fifty,
}  # fmt: skip
"""The rounds after the first, by number (``--round``)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="only the cases whose name contains this")
    parser.add_argument("-j", type=int, default=2, help="cases run at once")
    parser.add_argument(
        "--round",
        type=int,
        choices=sorted(ROUNDS),
        help="only the cases of this round (2 to 35, 37 to 50; all: none)",
    )
    args = parser.parse_args()
    every = ROUNDS[args.round]() if args.round is not None else cases()
    selected = [c for c in every if args.k in c.name]
    if not selected:
        parser.error(f"no case's name contains {args.k!r}")
    done = []
    with ThreadPoolExecutor(args.j) as pool:
        for case in pool.map(attempt, selected):  # printed as they finish, in order
            mark = "ok  " if case.result["handled"] else "FAIL"
            detail = "; ".join(case.result["problems"]) or case.result["stderr"][:110]
            print(f"{mark} {case.result['seconds']:5.1f} s  {case.name}: {detail}", flush=True)
            done.append(case)
    handled = sum(c.result["handled"] for c in done)
    slowest = max(done, key=lambda c: c.result["seconds"])
    print(
        f"\n{len(done)} cases tried, {handled} handled, {len(done) - handled} not handled; "
        f"slowest {slowest.result['seconds']:.1f} s ({slowest.name})"
    )


if __name__ == "__main__":
    main()
