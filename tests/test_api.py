"""The Python API (docs/api.md): load, run and Simulation, and the worked example."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
import yaml
from conftest import TINY_SCENARIO

import multilayer
from multilayer.app import cli
from multilayer.errors import InputError
from multilayer.io.results import open_result

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "scenarios" / "coulomb_dam_break.yaml"
SMALL = {"domain.cells": 60, "time.end": 0.1, "time.output_interval": 0.05}
#: attributes that say when and how fast a run went, not what it computed
RUN_ATTRS = {"history", "wall_time_s"}


RUN_LIGHT = """
import sys
sys.modules["dask"] = sys.modules["distributed"] = sys.modules["SALib"] = None  # not installed
import multilayer
multilayer.run(sys.argv[1], overrides={"domain.cells": 30, "time.end": 0.02, "time.output_interval": 0.02})
print(sorted(m for m in ("fipy",) if m in sys.modules))
"""


def test_a_run_needs_neither_dask_nor_salib_and_imports_no_fipy():
    """Without the studies extra a run goes; FiPy is imported where it is used (its mesh on
    demand, the reference solvers; the version in result.nc is read from its package
    metadata)."""
    done = subprocess.run([sys.executable, "-c", RUN_LIGHT, str(SCENARIO)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_import_multilayer_is_lazy_and_exports_the_api():
    code = "import sys, multilayer; print(sorted(m for m in ('fipy', 'numba', 'xarray') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    assert {"load", "run", "Simulation"} <= set(dir(multilayer))


def test_load_takes_a_file_a_mapping_or_a_scenario_with_overrides():
    from_file = multilayer.load(SCENARIO, {"domain.cells": 60, "initial.0.height": 0.05})
    assert from_file.domain.cells == 60 and from_file.initial[0].height == 0.05
    resolved = from_file.resolved_yaml()
    assert multilayer.load(str(SCENARIO), ["domain.cells=60", "initial.0.height=0.05"]) == from_file
    data = yaml.safe_load(SCENARIO.read_text())
    from_mapping = multilayer.load(data, {"domain.cells": 60, "initial.0.height": 0.05})
    assert from_mapping.resolved_yaml() == resolved and from_mapping.source is None
    again = multilayer.load(from_file, {"time.end": 0.2})
    assert again.time.end == 0.2 and again.domain.cells == 60
    with pytest.raises(InputError, match=r"domain\.cellz"):
        multilayer.load(SCENARIO, {"domain.cellz": 3})


def test_run_returns_the_dataset_the_command_line_writes(tmp_path: Path):
    """multilayer.run(...) in memory equals result.nc of `multilayer run` (variables,
    coordinates and the attributes that describe the computation)."""
    sets = [arg for key, value in SMALL.items() for arg in ("--set", f"{key}={value}")]
    assert cli.main(["run", str(SCENARIO), "-o", str(tmp_path / "cli"), "-q", *sets]) == 0
    from_cli = open_result(tmp_path / "cli")
    in_memory = multilayer.run(SCENARIO, overrides=SMALL)
    xr.testing.assert_identical(in_memory.drop_attrs(), from_cli.drop_attrs())
    for name, value in from_cli.attrs.items():
        if name not in RUN_ATTRS:
            assert in_memory.attrs[name] == value, name
    assert in_memory["time"].size == 3 and in_memory.attrs["run_status"] == "completed"
    written = multilayer.run(SCENARIO, tmp_path / "api", overrides=SMALL)
    assert (tmp_path / "api" / "result.nc").is_file()
    xr.testing.assert_identical(written.drop_attrs(), from_cli.drop_attrs())


def test_stepping_by_hand_to_the_output_times_gives_the_run():
    scenario = multilayer.load(SCENARIO, SMALL)
    ds = multilayer.run(scenario)
    sim = multilayer.Simulation(scenario)
    for t in ds["time"].values[1:]:
        sim.advance(t)
    assert sim.t == ds["time"].values[-1]
    np.testing.assert_array_equal(sim.h, ds["h"].values[-1])
    np.testing.assert_array_equal(sim.u, ds["u"].values[-1])


def test_the_python_example_of_the_readme_runs(monkeypatch: pytest.MonkeyPatch):
    blocks = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), flags=re.S)
    assert len(blocks) == 1
    monkeypatch.chdir(ROOT)
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)
    assert namespace["ds"]["time"].values[-1] == 0.2 and namespace["sim"].t == 0.0


def test_the_worked_example_of_docs_api_md_runs(monkeypatch: pytest.MonkeyPatch, capsys):
    """The example a notebook user pastes, run as it stands (from the repository root)."""
    import matplotlib

    matplotlib.use("Agg")
    text = (ROOT / "docs" / "api.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    assert len(blocks) == 1
    monkeypatch.chdir(ROOT)
    exec(compile(blocks[0], "docs/api.md", "exec"), {"__name__": "__api_example__"})
    error = float(re.search(r"relative L1 error of h: ([0-9.]+)", capsys.readouterr().out).group(1))
    assert error < 0.015  # the text says 0.010 (first-order scheme, 2 cm cells)
    import matplotlib.pyplot as plt

    plt.close("all")


def test_the_engine_built_from_a_configuration_is_the_scenarios_to_the_bit():
    """The engine needs no scenario: the same problem written as its typed configuration
    (integer bounds, the non-hydrostatic pressure with its default options) runs to the
    same bits as the scenario the factory turns into it."""
    from multilayer.engine.config import InitialEntry, PressureConfig, SimulationConfig
    from multilayer.engine.mesh import layer_fractions
    from multilayer.engine.simulation import Simulation
    from multilayer.plugins.builtins import DruckerPrager
    from multilayer.plugins.contract import Material

    config = SimulationConfig(
        x_min=0, x_max=1, cells=40, fractions=tuple(layer_fractions(4)),
        material=Material(density=1500.0, grain_diameter=1e-3, particle_density=2500.0), slope_deg=30.0,
        initial=(InitialEntry("rectangle", x_min=0.2, x_max=0.4, height=0.05),), left="wall", right="outflow",
        pressure=PressureConfig("non_hydrostatic"),
    )  # fmt: skip
    scenario = multilayer.load(
        {
            "name": "block",
            "slope_deg": 30.0,
            "domain": {"x_min": 0.0, "x_max": 1.0, "cells": 40, "layers": 4},
            "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
            "rheology": {"name": "drucker_prager", "mu_s": 0.4, "nu": 0.0},
            "initial": [{"shape": "rectangle", "x_min": 0.2, "x_max": 0.4, "height": 0.05}],
            "boundaries": {"left": "wall", "right": "outflow"},
            "time": {"end": 0.05, "output_interval": 0.05},
            "model": {"pressure": "non_hydrostatic"},
        }
    )
    alone, made = Simulation(config, DruckerPrager(mu_s=0.4, nu=0.0)), multilayer.Simulation(scenario)
    alone.advance(0.3)
    made.advance(0.3)
    assert alone.steps == made.steps > 10 and alone.pressure.layers == 4
    for name in ("h", "u", "w", "q"):
        np.testing.assert_array_equal(getattr(alone, name), getattr(made, name))


def test_a_run_without_outdir_that_fails_or_is_stopped_keeps_what_it_computed(monkeypatch):
    """``multilayer.run(scenario)`` runs in a temporary directory.  A run that failed said
    that ``<tmp>/result.nc`` held the output times before the failure, and one stopped by
    Ctrl-C gave the command resuming it from ``<tmp>``: both after the directory was
    removed.  Now it stays, and the error names it."""
    from multilayer.app import runner
    from multilayer.app.simulation import Simulation
    from multilayer.errors import Interrupted, RunError

    scenario = multilayer.load(TINY_SCENARIO, {"time.end": 0.1, "time.output_interval": 0.02})
    step = Simulation.step

    def failing(self: Simulation, t_max: float = np.inf) -> float:
        if self.t >= 0.05:
            raise FloatingPointError("a fault")
        return step(self, t_max)

    monkeypatch.setattr(Simulation, "step", failing)
    with pytest.raises(RunError, match=r"a fault; \S+/result.nc holds the output times up to") as failed:
        multilayer.run(scenario)
    directory = re.search(r"; (\S+)/result.nc holds", str(failed.value)).group(1)
    kept = open_result(directory)
    assert kept.attrs["run_status"] == "failed" and kept["time"].values[:3].tolist() == [0.0, 0.02, 0.04]
    shutil.rmtree(directory)
    monkeypatch.undo()
    poll = runner._StopRequest.poll

    def stopping(self: runner._StopRequest) -> None:  # Ctrl-C after 40 polls (at t = 0.06 s)
        calls.append(1)
        self.requested = self.requested or len(calls) > 40
        poll(self)

    calls: list[int] = []
    monkeypatch.setattr(runner._StopRequest, "poll", stopping)
    with pytest.raises(Interrupted, match=r"resume with: multilayer run SCENARIO.yaml -o \S+ --res") as stop:
        multilayer.run(scenario)
    directory = re.search(r"-o (\S+) --resume", str(stop.value)).group(1)
    kept = open_result(directory)
    assert kept.attrs["run_status"] == "interrupted" and kept.sizes["time"] >= 2
    shutil.rmtree(directory)
