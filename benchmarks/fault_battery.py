"""The fault battery of docs/reliability.md: bad inputs and faults, tried as a user would.

Every case runs the ``multilayer`` command line in a child process (with a patch applied
for the plugin and engine faults) and is *handled* when the exit code is the expected
one, no traceback is printed and stderr names the culprit (a phrase given per case); for
faults during a run, ``result.nc`` must also keep what was computed before.  Prints one
line per case and the counts.

    python benchmarks/fault_battery.py [-k SUBSTRING] [-j 2]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import yaml

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
            node[int(last)] = value
        else:
            node[last] = value
    path.write_text(yaml.safe_dump(data))
    return path


_DELETE = object()
INF, NAN = float("inf"), float("nan")

# (name, {dotted key: value}, phrase); validate and run are both tried for each
BAD_VALUES: list[tuple[str, dict, str]] = [
    ("x_max inf", {"domain.x_max": INF}, "domain.x_max"),
    ("x_max nan", {"domain.x_max": NAN}, "domain.x_max"),
    ("x_min -inf", {"domain.x_min": -INF}, "domain.x_min"),
    ("x_max < x_min", {"domain.x_max": -1.0}, "domain.x_max"),
    ("cells 0", {"domain.cells": 0}, "domain.cells"),
    ("cells float", {"domain.cells": 1.5}, "domain.cells"),
    ("cells 1e8", {"domain.cells": 100_000_000}, "of memory"),
    ("layers 1e8", {"domain.layers": 100_000_000}, "of memory"),
    ("layer_fractions inf", {"domain.layer_fractions": [INF, 1.0, 1.0]}, "domain.layer_fractions"),
    ("geometric nan", {"domain.layer_fractions": {"geometric": NAN}}, "domain.layer_fractions"),
    ("width -1", {"domain.width": -1.0}, "domain.width"),
    ("time.end inf", {"time.end": INF}, "time.end"),
    ("time.end nan", {"time.end": NAN}, "time.end"),
    ("time.end 0", {"time.end": 0.0}, "time.end"),
    ("output_interval 1e-9", {"time.output_interval": 1e-9}, "result file of about"),
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
]

BAD_FILES: list[tuple[str, str, str]] = [
    ("malformed YAML", "name: [unclosed\n", "malformed YAML"),
    ("empty file", "", "top level"),
    ("a list", "- 1\n- 2\n", "top level"),
    ("duplicate key", yaml.safe_dump(TINY) + "name: again\n", "duplicate key"),
    ("binary garbage", "\x00\x01\x02\xff", "scenario.yaml"),
]

PLUGIN_FAULTS: list[tuple[str, str, str]] = [
    ("viscosity nan", "return np.full(np.shape(p), np.nan)", "viscosity() returned nan"),
    ("viscosity inf", "return np.full(np.shape(p), np.inf)", "viscosity() returned inf"),
    ("viscosity negative", "return np.full(np.shape(p), -1.0)", "viscosity() returned -1.0"),
    ("viscosity wrong shape", "return np.ones(7)", "viscosity() returned an array of shape (7,)"),
    ("viscosity raises", "raise RuntimeError('broken')", "viscosity() raised RuntimeError: broken"),
    ("viscosity None", "return None", "viscosity() returned"),
    ("viscosity text", "return 'abc'", "viscosity() raised ValueError"),
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
        "def init(self, scenario):\n"
        "    real_init(self, scenario)\n"
        f"    self.stresses.bulk.{assignment}\n"
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
        with netCDF4.Dataset(path, "a") as ds:
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
        ("nan", 0, "values are not finite"),
        ("failed", 0, "the run failed"),
        ("all nan", 0, "values are not finite"),
        ("truncated", 2, "result.nc"),
    ):
        out.append(
            Case(f"plot: {how} result", ["plot", "{dir}/out"], code, phrase, setup=_result_damage(how))
        )
    out.append(Case("plot: no result", ["plot", "{dir}"], 2, "no result file"))
    return out


def _records(path: Path) -> int:
    try:
        import netCDF4

        with netCDF4.Dataset(path) as ds:
            return int(np.isfinite(ds["time"][:].filled(np.nan)).sum())
    except (OSError, KeyError, IndexError):
        return 0


def attempt(case: Case) -> Case:
    with tempfile.TemporaryDirectory() as tmp:
        directory = Path(tmp)
        if case.setup is not None:
            case.setup(directory)
        argv = [a.format(scenario=directory / "scenario.yaml", dir=directory) for a in case.argv]
        command = [sys.executable, "-c", CHILD.format(patch=case.patch), *argv]
        start = time.monotonic()
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        if case.signal_after_output is not None:
            while _records(directory / "out" / "result.nc") < 2 and proc.poll() is None:
                time.sleep(0.02)
            proc.send_signal(case.signal_after_output)
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
        if case.phrase not in err:
            problems.append(f"stderr lacks {case.phrase!r}")
        if case.keeps_output and _records(directory / "out" / "result.nc") < 1:
            problems.append("nothing kept in result.nc")
        case.result = {
            "handled": not problems,
            "problems": problems,
            "seconds": time.monotonic() - start,
            "stderr": err.strip().splitlines()[-1][:200] if err.strip() else "",
        }
    return case


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-k", default="", help="only the cases whose name contains this")
    parser.add_argument("-j", type=int, default=2, help="cases run at once")
    args = parser.parse_args()
    selected = [c for c in cases() if args.k in c.name]
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
