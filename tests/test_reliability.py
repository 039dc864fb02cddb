"""Never a silent wrong answer (docs/reliability.md): one test per class of fault.

Each asserts the exit code, that no traceback reaches the user, that the culprit is
named and that what was computed before the fault is kept.
"""

from __future__ import annotations

import json
import os
import re
import resource
import signal
import socket
import subprocess
import sys
import time
import warnings
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO

from multilayer.app import lock
from multilayer.app import simulation as simulation_module
from multilayer.engine.plugin_output import PluginOutputError
from multilayer.engine.state_check import StateError
from multilayer.engine.transport import kernel as transport_kernel
from multilayer.engine.transport import reference as transport
from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.engine.vertical.problem import ColumnProblem
from multilayer.errors import RunError
from multilayer.io.results import open_result, run_failure
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
from multilayer.plugins.builtins.jop_mu_i import JopMuI
from multilayer.plugins.builtins.power_law_mu_i import PowerLawMuI

SLUMP = {**TINY_SCENARIO, "name": "slump", "time": {"end": 0.2, "output_interval": 0.02}}


def _write(tmp_path: Path, data: dict, name: str = "slump.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def _no_traceback(text: str) -> None:
    assert "Traceback" not in text, text


# A child process that imports everything, says "ready", then runs the CLI with a patch
# applied: timings start at "ready", so interpreter start-up on a busy machine is excluded.
_CHILD = """
import sys, time, pathlib
import numpy as np
from multilayer.app.cli import main
from multilayer.engine import simulation
from multilayer.engine.vertical import column_solve as column_kernel
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
from multilayer.plugins.builtins.jop_mu_i import JopMuI
from multilayer.plugins.builtins.power_law_mu_i import PowerLawMuI
{patch}
print("ready", time.process_time(), flush=True)
sys.exit(main(sys.argv[1:]))
"""

NAN_VISCOSITY = """
def viscosity(self, shear_rate, pressure, material):
    return np.full(np.shape(pressure), np.nan)
DruckerPrager.viscosity = viscosity
DruckerPrager.viscosity_kernel = lambda self, material: None  # a plugin without a compiled form
"""

# every kernel call takes 0.2 s and never converges: one step would last 200 x 0.2 s; each
# call appends a byte to ``kernel-calls`` in the output directory as it begins
SLOW_KERNEL = """
real = column_kernel.solve
marker = pathlib.Path(sys.argv[-1]) / "kernel-started"
calls = pathlib.Path(sys.argv[-1]) / "kernel-calls"
def solve(*args, **kwargs):
    with calls.open("a") as file:
        file.write(".")
    time.sleep(0.2)
    u = real(*args, **kwargs) + np.random.default_rng().normal(0.0, 1e-3)
    marker.touch()  # after the first call: the kernel is compiled
    return u
column_kernel.solve = solve
DruckerPrager.viscosity_kernel = lambda self, material: None  # the numpy path calls the kernel
"""

# steps of at least 20 ms, so that a signal arrives while the run is going
PACED = """
step = simulation.Simulation.step
def paced(self, t_max):
    time.sleep(0.02)
    return step(self, t_max)
simulation.Simulation.step = paced
"""


def _start(patch: str, *args: object) -> subprocess.Popen:
    proc = subprocess.Popen(
        [sys.executable, "-c", _CHILD.format(patch=patch), *map(str, args)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    line = proc.stdout.readline().split()
    assert line[:1] == ["ready"], proc.communicate(timeout=60)
    proc.cpu_at_ready = float(line[1])  # CPU seconds the child spent importing
    return proc


# ----------------------------------------------------------------------------- plugin output


@pytest.mark.slow  # a NaN plugin runs by default: test_a_sweep_marks_a_member_with_a_nan_plugin_failed
def test_a_nan_returning_plugin_stops_the_run_within_ten_seconds_naming_it(tmp_path):
    """Within 10 s of CPU after start-up (it used to spin for ever); the wall-clock timeout
    is wider because the machine running the tests may be shared."""
    path, outdir = _write(tmp_path, SLUMP), tmp_path / "out"
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = _start(NAN_VISCOSITY, "run", path, "-o", outdir, "-q")
    try:
        out, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("a NaN viscosity kept the engine busy for more than 60 s")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime - proc.cpu_at_ready
    assert cpu < 10.0, f"{cpu:.1f} s of CPU after start-up"
    assert proc.returncode == 1
    _no_traceback(err)
    assert "rheology plugin 'drucker_prager'" in err and "viscosity() returned nan" in err
    assert "at x = " in err and "interface " in err and "t = 0 s" in err
    kept = open_result(outdir)
    assert kept.attrs["run_status"] == "failed" and "viscosity() returned nan" in kept.attrs["failure"]
    np.testing.assert_array_equal(kept["time"], [0.0])  # the initial state is kept
    assert float(kept["mass"][0]) == pytest.approx(0.05 * 0.1, rel=1e-12)


@pytest.mark.parametrize(
    ("method", "result", "expected"),
    [
        ("yield_stress", lambda p: -1.0 * np.ones_like(p), "yield_stress() returned -1.0 (must be >= 0)"),
        ("yield_stress", lambda p: np.ones(3), "yield_stress() returned an array of shape (3,)"),
        ("viscosity", lambda p: np.full(np.shape(p), np.inf), "viscosity() returned inf (must be finite)"),
        ("viscosity", lambda p: -np.ones_like(p), "viscosity() returned -1.0 (must be >= 0)"),
        ("viscosity", lambda p: 1 / 0, "viscosity() raised ZeroDivisionError: division by zero"),
    ],
)
def test_plugin_output_outside_the_contract_is_exit_1_naming_plugin_method_and_value(
    tmp_path, cli, monkeypatch, method, result, expected
):
    if method == "yield_stress":
        monkeypatch.setattr(DruckerPrager, method, lambda self, p, m: result(p))
    else:
        monkeypatch.setattr(DruckerPrager, method, lambda self, g, p, m: result(p))
        # a plugin without a compiled form of its viscosity (the built-in one has one)
        monkeypatch.setattr(DruckerPrager, "viscosity_kernel", lambda self, material: None)
    run = cli("run", _write(tmp_path, SLUMP), "-o", tmp_path / "out", "-q")
    assert run.code == 1
    _no_traceback(run.err)
    assert (
        "rheology plugin 'drucker_prager' (multilayer.plugins.builtins.drucker_prager.DruckerPrager)"
        in run.err
    )
    assert expected in run.err
    assert open_result(tmp_path / "out").attrs["run_status"] == "failed"


def _past_validation(law, **bad):
    """A built-in law given parameters its constructor would refuse (set after it)."""
    for name, value in bad.items():
        setattr(law, name, value)
    return law


# laws whose compiled viscosity form (newton_kernel) is outside the contract: mu_2 < mu_s
# makes the mu(I) viscosity negative, a NaN viscosity, and a shear-thinning power law
# without its shear-rate floor has an infinite viscosity at rest
BAD_COMPILED_LAWS = {
    "negative": (lambda: _past_validation(JopMuI(0.38, 0.64, 0.279), mu_2=0.2), "returned -0.6", ">= 0"),
    "nan": (lambda: _past_validation(DruckerPrager(0.3, 0.01), nu=np.nan), "returned nan", "finite"),
    "infinite": (
        lambda: _past_validation(PowerLawMuI(0.38, 0.2, 0.5), shear_rate_floor=0.0),
        "returned inf",
        "finite",
    ),
}
CHUTE = dict(
    slope_deg=25.0,
    domain={"x_min": 0.0, "x_max": 1.0, "cells": 40, "layers": 3},
    material={"density": 1550.0, "grain_diameter": 0.7e-3},
    rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279},
    base=[{"condition": "no_slip"}],
    initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.3, "height": 0.1}],
)


@pytest.mark.parametrize("fault", BAD_COMPILED_LAWS)
def test_a_compiled_viscosity_outside_the_contract_stops_the_kernel_as_the_python_guard_does(fault):
    """The fused Newton kernel flags the column and stops; the error names the plugin, the
    method, the value, x, the interface and t exactly as the check of the numpy path does."""
    from engine import simulation

    make, value, rule = BAD_COMPILED_LAWS[fault]
    messages = []
    for compiled in (True, False):
        sim = simulation(**CHUTE)
        assert sim.vertical.compiled is not None and sim.vertical.compiled.laws() is not None
        sim.vertical.stresses.bulk = make()
        if not compiled:
            sim.vertical.compiled = None  # the numpy Newton iteration, which calls viscosity() itself
        with pytest.raises(PluginOutputError) as caught, np.errstate(divide="ignore"):
            sim.step()
        assert sim.t == 0.0 and sim.steps == 0  # nothing was kept
        messages.append(str(caught.value))
    kernel, numpy_path = messages
    assert f"{value}" in kernel and f"(must be {rule}) at x = 0.0125 m, interface 0 (0 is the bed)" in kernel
    assert "its compiled form, viscosity_kernel" in kernel
    # the same plugin, method, value, place, time and inputs as the Python-side guard
    # the same plugin, method, place, time and inputs as the Python-side guard, and the
    # same value to round-off (the kernel divides through an inverse)
    returned = __import__("re").compile(r"returned (\S+) ")
    kernel_value, numpy_value = (float(returned.search(m)[1]) for m in (kernel, numpy_path))
    assert kernel_value == pytest.approx(numpy_value, rel=1e-14, nan_ok=True)
    same = [returned.sub("returned VALUE ", m.rsplit(" (", 1)[0]) for m in (kernel, numpy_path)]
    assert same[0] == same[1], (kernel, numpy_path)


def test_a_compiled_viscosity_outside_the_contract_is_exit_1_naming_the_plugin(tmp_path, cli, monkeypatch):
    real = simulation_module.Simulation.__init__

    def with_bad_law(self, scenario):
        real(self, scenario)
        self.vertical.stresses.bulk = BAD_COMPILED_LAWS["negative"][0]()

    monkeypatch.setattr(simulation_module.Simulation, "__init__", with_bad_law)
    from engine import BASE

    data = {**BASE, **CHUTE, "time": {"end": 0.1, "output_interval": 0.05}}
    outdir = tmp_path / "out"
    run = cli("run", _write(tmp_path, data), "-o", outdir, "-q")
    assert run.code == 1
    _no_traceback(run.err)
    assert "rheology plugin 'jop_mu_i' (multilayer.plugins.builtins.jop_mu_i.JopMuI): viscosity()" in run.err
    assert "returned -0.6" in run.err and "its compiled form, viscosity_kernel" in run.err
    kept = open_result(outdir)
    assert kept.attrs["run_status"] == "failed" and "viscosity_kernel" in kept.attrs["failure"]
    np.testing.assert_array_equal(kept["time"], [0.0])  # the initial state is kept


def test_the_column_kernel_refuses_non_finite_input_and_never_spins_on_it():
    rng = np.random.default_rng(0)
    L, N = 6, 50
    m, ustar = rng.uniform(1, 2, (L, N)), rng.normal(0, 1, (L, N))
    kappa, c, w, cw = rng.uniform(0, 1, (L, N)), rng.uniform(0, 1, (L, N)), np.zeros((L, N)), np.zeros((L, N))
    ustar[2, 17] = np.nan
    problem = ColumnProblem(m=m, ustar=ustar, dt=0.01, kappa=kappa, c=c, w=w, cw=cw)
    with pytest.raises(RunError, match=r"ustar is nan in column 17 .* layer or interface 2"):
        column_kernel.solve(problem)
    # below the check, the merge of two relations stops at a NaN abscissa instead of
    # spinning (it used to loop for ever at 100 % CPU, deaf to Ctrl-C)
    X1, Y1 = np.array([np.nan, 1.0]), np.array([0.0, 1.0])
    X2, Y2 = np.array([0.0, 0.0]), np.array([-1.0, 1.0])
    out = np.empty(64), np.empty(64)
    assert column_kernel._add(X1, Y1, 2, 1.0, 1.0, X2, Y2, 2, 1.0, 1.0, *out)[0] == -1


@pytest.mark.slow
def test_ctrl_c_is_honoured_between_two_kernel_calls_inside_a_long_step(tmp_path, default_stop_signals):
    """The first step would take 200 kernel calls of 0.2 s (40 s).  The verdict rests on
    counts, not on the wall clock, so that it holds on a loaded machine (a bound of 1 s
    from the signal to the log line failed once at a load of 5: the checkpoint and the
    log are written after the stop): at most one kernel call begins after the signal (the
    one that may have begun between counting and signalling; the one under way finishes),
    and the run stops at t = 0, inside the first step.  The wall-clock bound, a quarter
    of that step, only shows that the stop did not wait for it."""
    path, outdir = _write(tmp_path, SLUMP), tmp_path / "out"
    proc = _start(SLOW_KERNEL, "run", path, "-q", "-o", outdir)
    deadline = time.monotonic() + 300  # the first kernel call may compile it (numba cache cold)
    while not (outdir / "kernel-started").exists():
        assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
        time.sleep(0.05)
    time.sleep(0.5)  # inside the first step
    before = len((outdir / "kernel-calls").read_text())
    sent = time.monotonic()
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    waited = time.monotonic() - sent
    assert proc.returncode == 130, err
    _no_traceback(err)
    begun = len((outdir / "kernel-calls").read_text()) - before
    assert begun <= 1, f"{begun} kernel calls began after Ctrl-C"
    assert waited < 10.0, f"stopped {waited:.2f} s after Ctrl-C, inside a step of 40 s"
    stop = "multilayer: interrupted by Ctrl-C (SIGINT) at t=0 s; resume with:"
    assert err.splitlines()[-1].startswith(stop), err  # said once: no "multilayer: interrupted" after
    assert "interrupted by Ctrl-C" in (outdir / "run.log").read_text()
    assert open_result(outdir).attrs["run_status"] == "interrupted"


# ----------------------------------------------------------------------------- state guard


def _corrupt_transport(monkeypatch, after: int, fault) -> None:
    """Make the transport step number ``after`` (and later) return a corrupted state, on
    the numpy and the compiled paths (the step's result: Heun's first stage alone is left
    as it is)."""
    calls = [0]

    def corrupting(real):
        def corrupted(*args, **kwargs):
            h, u = real(*args, **kwargs)
            if kwargs.get("stage") == 0:
                return h, u
            calls[0] += 1
            if calls[0] > after:
                fault(h)
            return h, u

        return corrupted

    monkeypatch.setattr(transport, "transport", corrupting(transport.transport))
    monkeypatch.setattr(transport_kernel, "transport", corrupting(transport_kernel.transport))


@pytest.mark.parametrize(
    ("fault", "expected"),
    [
        (lambda h: h.__setitem__(5, np.nan), r"thickness h = nan at x = 0.06875 m after transport from t = "),
        (lambda h: h.__setitem__(7, h[7] + 0.01), r"mass is not conserved after the step from t = "),
    ],
)
def test_an_impossible_state_ends_the_run_keeping_the_last_good_state(
    tmp_path, cli, monkeypatch, fault, expected
):
    _corrupt_transport(monkeypatch, 15, fault)
    outdir = tmp_path / "out"
    run = cli("run", _write(tmp_path, SLUMP), "-o", outdir, "-q")
    assert run.code == 1
    _no_traceback(run.err)
    assert __import__("re").search(expected, run.err), run.err
    kept = open_result(outdir)
    assert kept.attrs["run_status"] == "failed" and expected.split(" ")[0] in kept.attrs["failure"]
    t = kept["time"].values
    assert t.size >= 3 and np.isfinite(kept["h"].values).all() and np.isfinite(kept["u"].values).all()
    assert t[-1] not in np.round(np.arange(0, 0.21, 0.02), 12)  # the last good step, between outputs
    assert f"the last good state at t={t[-1]:.6g} s" in run.err
    ckpt = np.load(outdir / "checkpoint.npz")
    assert float(ckpt["state.t"]) == t[-1]
    np.testing.assert_array_equal(ckpt["state.h"], kept["h"].values[-1])
    assert "the run did not complete (run_status failed: " + expected.split(" ")[0] in run_failure(outdir)


# a frictionless dam break, a chute fed by a supercritical inflow, a closed dam break and a
# sliding layer on a periodic slope: the four kinds of boundary, material crossing the open ones
BALANCE_CASES = {
    "outflow dam break": dict(
        boundaries={"left": "outflow", "right": "outflow"},
        initial=[{"shape": "rectangle", "x_min": 0.75, "x_max": 1.25, "height": 0.2}],
    ),
    "inflow chute": dict(
        slope_deg=25.0,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 40, "layers": 3},
        rheology={"name": "drucker_prager", "mu_s": 0.3, "nu": 0.01},
        base=[{"condition": "no_slip"}],
        boundaries={
            "left": "inflow",
            "right": "outflow",
            "inflow": {"thickness": 0.05, "velocity": {"profile": "plug", "speed": 2.0}},
        },
    ),
    "walls": dict(initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.5, "height": 0.2}]),
    "periodic": dict(
        slope_deg=20.0,
        boundaries={"left": "periodic", "right": "periodic"},
        initial=[{"shape": "rectangle", "x_min": 1.5, "x_max": 2.0, "height": 0.1}],
    ),
}


@pytest.mark.parametrize("solver", [pytest.param("numpy", marks=pytest.mark.slow), "kernel"])
@pytest.mark.parametrize("case", BALANCE_CASES)
def test_mass_balances_the_boundary_fluxes_to_round_off_on_every_kind_of_boundary(case, solver):
    """mass(t) = mass(0) + the mass that crossed the boundaries, to round-off, with either
    transport; the crossings are the scheme's own face fluxes, checked independently
    where they are known exactly: the upwind flux h_in u_in of a supercritical inflow, no
    flux through a wall, and the same flux leaving one periodic side and entering the other."""
    from engine import simulation

    domain = {"domain": {"x_min": 0.0, "x_max": 2.0, "cells": 80, "layers": 3}}
    sim = simulation(numerics={"transport_solver": solver}, **{**domain, **BALANCE_CASES[case]})
    mass0, crossed = float(sim.h.sum() * sim.dx), []
    sim.advance(1.2, lambda s, dt: crossed.append(s.boundary_mass.copy()))
    left, right = np.sum(crossed, axis=0)
    mass = float(sim.h.sum() * sim.dx)
    assert sim.net_inflow == pytest.approx(left - right, rel=1e-12)
    assert abs(mass - mass0 - sim.net_inflow) <= 1e-12 * max(mass, mass0)
    sim.check_state()  # the guard's balance at an output time
    if case == "outflow dam break":  # material left through both sides, symmetrically
        assert -left == pytest.approx(right, rel=1e-9) and right > 0.2 * mass0
    elif case == "inflow chute":  # h_in u_in for 1.2 s, and some of it already left
        assert left == pytest.approx(0.05 * 2.0 * 1.2, rel=1e-12) and right > 0.0
    elif case == "walls":
        assert not np.any(crossed)
    else:
        assert all(step[0] == step[1] for step in crossed) and np.abs(crossed).max() > 0.0


def test_the_run_balance_counts_the_rounding_of_its_own_running_sum_of_the_boundary_masses():
    """A domain drained of its whole mass (1 m2 out of the right side), then fed a trickle
    of 1e-17 m2 a step through the left: each step balances to round-off, and the run's
    balance too, although the running sum of the boundary masses, near -1, cannot hold the
    trickle (half its ulp is 1.1e-16): after 10 000 steps the domain holds 1e-13 m2 that
    the sum lost, three times the round-off bound of the steps' own balances.  A leak of
    1e-11 m2 is still caught."""
    from multilayer.engine.state_check import StateGuard

    x, dx = np.arange(10) * 0.1 + 0.05, 0.1
    guard, u, h = StateGuard(x, dx), np.zeros((1, 10)), np.ones(10)
    guard.reset(h, 0)
    empty = np.zeros(10)
    guard.check_step(h, empty, u, 0.0, 1.0, (0.0, 1.0))
    h, trickle = empty, 1e-17
    for step in range(10_000):
        fed = h.copy()
        fed[0] += trickle / dx
        guard.check_step(h, fed, u, 1.0 + step, 1.0, (trickle, 0.0))
        h = fed
    assert guard.net_inflow == -1.0  # the trickle is lost in the sum
    assert h.sum() * dx == pytest.approx(1e-13, rel=1e-9)
    guard.check_balance(h, "at the end")
    leaked = h.copy()
    leaked[5] += 1e-11 / dx
    with pytest.raises(StateError, match="mass is not conserved at the end"):
        guard.check_balance(leaked, "at the end")


def test_a_mass_error_just_above_round_off_is_caught_at_an_open_boundary(tmp_path, cli, monkeypatch):
    """1e-11 m added to one cell while material flows out (1e-10 of the thickness, far below
    any bound of the boundary flux): exit 1 naming the transport and the size of its error,
    the last good state kept."""
    delta, dx = 1e-11, 0.5 / 40
    _corrupt_transport(monkeypatch, 15, lambda h: h.__setitem__(30, h[30] + delta))
    outflowing = dict(SLUMP, initial=[{"shape": "rectangle", "x_min": 0.3, "x_max": 0.5, "height": 0.05}])
    outdir = tmp_path / "out"
    run = cli("run", _write(tmp_path, outflowing), "-o", outdir, "-q")
    assert run.code == 1
    _no_traceback(run.err)
    found = __import__("re").search(
        r"mass is not conserved after the step from t = .*: the transport "
        r"made an error of (\S+) m2, more than round-off",
        run.err,
    )
    assert found, run.err
    assert float(found[1]) == pytest.approx(delta * dx, rel=1e-3)  # the injected error, measured
    kept = open_result(outdir)
    assert kept.attrs["run_status"] == "failed" and np.isfinite(kept["h"].values).all()
    assert (
        kept["time"].values[-1] > 0.0
        and f"the last good state at t={kept['time'].values[-1]:.6g} s" in run.err
    )


def test_a_sweep_marks_a_member_with_a_nan_plugin_failed(tmp_path, cli, monkeypatch):
    from dask.distributed import LocalCluster

    real = DruckerPrager.viscosity

    def viscosity(self, shear_rate, pressure, material):  # NaN for one member only
        return real(self, shear_rate, pressure, material) * (np.nan if self.mu_s == 0.4 else 1.0)

    monkeypatch.setattr(DruckerPrager, "viscosity", viscosity)
    monkeypatch.setattr(DruckerPrager, "viscosity_kernel", lambda self, material: None)
    _write(tmp_path, dict(SLUMP, time={"end": 0.04, "output_interval": 0.02}), "tiny.yaml")
    sweep = tmp_path / "sweep.yaml"
    sweep.write_text("base: tiny.yaml\nparameters:\n  rheology.mu_s: [0.3, 0.4]\n")
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        result = cli("sweep", sweep, "-o", tmp_path / "out", "--scheduler", cluster.scheduler_address)
    assert result.code == 1
    _no_traceback(result.err)
    rows = (tmp_path / "out" / "summary.csv").read_text().splitlines()
    assert ",ok," in rows[1] and ",failed," in rows[2] and "viscosity() returned nan" in rows[2]
    # the good member's result and the failed member's initial state are kept
    good, bad = (open_result(next((tmp_path / "out").glob(f"m{i:03d}-*"))) for i in (0, 1))
    assert good.attrs["run_status"] == "completed" and good.sizes["time"] == 3
    assert bad.attrs["run_status"] == "failed" and np.isfinite(bad["h"].values).all()


# ----------------------------------------------------------------------------- initial state


def test_material_outside_the_domain_is_exit_2_naming_the_entry(tmp_path, cli):
    data = dict(SLUMP, initial=[{"shape": "rectangle", "x_min": 0.6, "x_max": 0.7, "height": 0.05}])
    for command in ("validate", "run"):
        result = cli(command, _write(tmp_path, data), *(["-o", tmp_path / "out"] if command == "run" else []))
        assert result.code == 2
        _no_traceback(result.err)
        assert "initial.0 (rectangle on x in [0.6, 0.7] m): 0.005 of its 0.005 m2 lie outside" in result.err


# ----------------------------------------------------------------------------- sizes


@pytest.mark.parametrize(
    ("override", "expected"),
    [
        ("domain.cells=100000000", "x 3 layers need about 110 GB of memory, more than --max-memory (8 GB)"),
        # the messages of the exact column solve, 128 L^2 bytes per thread: 1.28e12 bytes each
        ("domain.layers=100000", " TB of memory, more than --max-memory (8 GB)"),
        ("time.output_interval=1e-6", "output times of 40 cells x 3 layers make a result file of about"),
    ],
)
def test_runs_that_do_not_fit_are_refused_with_the_estimate_unless_forced(tmp_path, cli, override, expected):
    path = _write(tmp_path, SLUMP)
    budget = ["--max-memory", "8G", "--max-output", "100M"]
    for command in (["validate", path], ["run", path, "-o", tmp_path / "out"]):
        result = cli(*command, "--set", override, *budget)
        assert result.code == 2
        _no_traceback(result.err)
        assert expected in result.err and "--force" in result.err
    assert not (tmp_path / "out").exists()  # refused before anything is written
    forced = cli("validate", path, "--set", override, *budget, "--force")
    assert forced.code == 0 and "about" in forced.out


@pytest.mark.parametrize(
    "override", ["domain.x_max=.inf", "time.end=.inf", "time.output_interval=.nan", "gravity=-.inf"]
)
def test_non_finite_domain_and_time_values_are_exit_2(tmp_path, cli, override):
    result = cli("run", _write(tmp_path, SLUMP), "-o", tmp_path / "out", "--set", override)
    assert result.code == 2
    _no_traceback(result.err)
    assert f"{override.split('=')[0]} (from --set): Input should be a finite number" in result.err


# ----------------------------------------------------------------------------- checkpoints


def _finished(tmp_path, cli) -> tuple[Path, Path]:
    short = dict(SLUMP, time={"end": 0.04, "output_interval": 0.02})
    path, outdir = _write(tmp_path, short), tmp_path / "out"
    assert cli("run", path, "-o", outdir, "-q").code == 0
    return path, outdir


@pytest.mark.parametrize("damage", ["truncate", "flip", "pickle", "checksum"])
def test_a_corrupt_checkpoint_is_exit_2_with_its_path(tmp_path, cli, damage):
    path, outdir = _finished(tmp_path, cli)
    ckpt = outdir / "checkpoint.npz"
    data = ckpt.read_bytes()
    if damage == "truncate":
        ckpt.write_bytes(data[: len(data) // 2])
    elif damage == "flip":
        ckpt.write_bytes(data[:200] + bytes(b ^ 0xFF for b in data[200:260]) + data[260:])
    elif damage == "pickle":  # an object array: loading it would run pickle
        np.savez(ckpt, **{"state.h": np.array([object()], dtype=object)})
    else:
        arrays = dict(np.load(ckpt))
        arrays["state.h"] = arrays["state.h"] + 1.0
        np.savez(ckpt, **arrays)
    before = open_result(outdir)
    result = cli("run", path, "-o", outdir, "--resume", "--set", "time.end=0.06")
    assert result.code == 2
    _no_traceback(result.err)
    assert f"{ckpt}: corrupt checkpoint" in result.err and "start again without --resume" in result.err
    kept = open_result(outdir)  # the finished run's result is left as it was
    assert kept.attrs["run_status"] == "completed"
    np.testing.assert_array_equal(kept["h"].values, before["h"].values)


# ----------------------------------------------------------------------------- lock


def test_a_directory_in_use_is_refused_naming_the_holder_and_a_stale_lock_taken_over(tmp_path, cli):
    path, outdir = _write(tmp_path, SLUMP), tmp_path / "out"
    outdir.mkdir()
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        started = "2026-01-01T00:00:00+00:00"
        record = {"pid": holder.pid, "host": socket.gethostname(), "started": started}
        (outdir / lock.LOCK_FILE).write_text(json.dumps(record))
        result = cli("run", path, "-o", outdir, "-q")
        assert result.code == 2
        _no_traceback(result.err)
        assert f"another run is writing into this directory (pid {holder.pid} on host" in result.err
        assert started in result.err and not (outdir / "result.nc").exists()
        assert json.loads((outdir / lock.LOCK_FILE).read_text()) == record  # the holder's lock is kept
    finally:
        holder.kill()
        holder.wait()
    result = cli("run", path, "-o", outdir, "-q", "--set", "time.end=0.02")  # the holder is gone: stale
    assert result.code == 0
    assert f"taking over a stale lock (pid {holder.pid}" in result.err
    assert "taking over a stale lock" in (outdir / "run.log").read_text()
    assert not (outdir / lock.LOCK_FILE).exists()  # released at the end


def _take_the_lock_at_once(directory: str, barrier, results) -> None:
    barrier.wait()
    try:
        with lock.locked(Path(directory)):
            start = time.monotonic()
            time.sleep(0.2)
            results.put(("held", start, time.monotonic()))
    except Exception as exc:  # noqa: BLE001 - the refusal is the result
        results.put(("refused", str(exc), 0.0))


@pytest.mark.parametrize(
    "earlier", ["none", *(pytest.param(e, marks=pytest.mark.slow) for e in ("stale", "empty"))]
)  # 1.3 s each
def test_runs_started_at_once_take_the_lock_one_at_a_time(tmp_path, earlier):
    """Six processes taking one directory's lock at the same instant: never two at once (a
    lock just created and still empty was read as unreadable, so stale, and taken over, and
    two took over one stale lock, the second deleting the first's: 7 and 11 of 30 trials
    had two holders); the others are refused naming the holder."""
    import multiprocessing

    context = multiprocessing.get_context("fork")
    for trial in range(4):
        directory = tmp_path / f"out{trial}"
        directory.mkdir()
        if earlier == "stale":
            dead = {"pid": 2**31 - 2, "host": socket.gethostname(), "started": "2026-01-01T00:00:00+00:00"}
            (directory / lock.LOCK_FILE).write_text(json.dumps(dead))
        elif earlier == "empty":
            (directory / lock.LOCK_FILE).write_text("")
        barrier, results = context.Barrier(6), context.Queue()
        workers = [
            context.Process(target=_take_the_lock_at_once, args=(str(directory), barrier, results))
            for _ in range(6)
        ]
        for worker in workers:
            worker.start()
        outcomes = [results.get(timeout=60) for _ in workers]
        for worker in workers:
            worker.join()
        held = sorted((start, end) for what, start, end in outcomes if what == "held")
        assert held, outcomes
        assert all(later[0] >= earlier_[1] for earlier_, later in zip(held, held[1:], strict=False)), held
        refused = [message for what, message, _ in outcomes if what == "refused"]
        busy = "another run is writing into this directory (pid"
        assert all(busy in message for message in refused), refused
        assert not (directory / lock.LOCK_FILE).exists()


# ----------------------------------------------------------------------------- signals


@pytest.mark.parametrize(
    ("signum", "code"),
    [(signal.SIGTERM, 143), (signal.SIGHUP, 129)],
)
@pytest.mark.slow  # the same path as Ctrl-C, which runs by default (test_ctrl_c_is_honoured_between_...)
def test_sigterm_and_sighup_stop_like_ctrl_c(tmp_path, signum, code, default_stop_signals):
    path, outdir = _write(tmp_path, SLUMP), tmp_path / "out"
    proc = _start(PACED, "run", path, "-o", outdir)
    deadline = time.monotonic() + 60
    while not (outdir / "result.nc").exists() or (outdir / "run.log").read_text().count("output t =") < 1:
        assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == code, err
    _no_traceback(err)
    name = signal.Signals(signum).name
    assert f"interrupted by {name} at t=" in err and f"multilayer run {path} -o {outdir} --resume" in err
    assert f"interrupted by {name}" in (outdir / "run.log").read_text()
    kept = open_result(outdir)
    assert kept.attrs["run_status"] == "interrupted" and kept.sizes["time"] >= 2
    assert not (outdir / lock.LOCK_FILE).exists()


def _ignoring_ctrl_c_and_hangup() -> None:
    """As a job started with ``&`` by a non-interactive shell under ``nohup`` starts."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGHUP, signal.SIG_IGN)


@pytest.mark.slow  # a child run; handled_by's own test runs by default, the fault battery tries it too
def test_a_run_started_with_ctrl_c_and_hangup_ignored_keeps_them_ignored(tmp_path):
    """A run started with SIGINT and SIGHUP ignored (``nohup cmd &`` in a script) took them
    anyway: a Ctrl-C meant for the shell's foreground job, or the terminal closing, stopped
    it.  It now keeps them ignored, as Python itself does SIGINT, and runs to its end."""
    path, outdir = _write(tmp_path, SLUMP), tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-c", _CHILD.format(patch=PACED), "run", str(path), "-o", str(outdir), "-q"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=_ignoring_ctrl_c_and_hangup,
    )
    deadline = time.monotonic() + 120
    while not (outdir / "run.log").exists() or "output t =" not in (outdir / "run.log").read_text():
        assert time.monotonic() < deadline and proc.poll() is None, proc.communicate()
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    proc.send_signal(signal.SIGHUP)
    _out, err = proc.communicate(timeout=120)
    assert proc.returncode == 0, err
    assert open_result(outdir).attrs["run_status"] == "completed"


def test_a_signal_the_process_ignores_stays_ignored_while_a_run_or_study_handles_the_others():
    """:func:`runner.handled_by` (a run's and a study's stop handler) leaves a stop signal
    the process ignores as it is and sets the others back after."""
    from multilayer.app import runner

    def handler(signum, frame):
        """The run's handler, never called here."""

    before = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        term = signal.getsignal(signal.SIGTERM)
        with runner.handled_by(handler):
            assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN
            assert signal.getsignal(signal.SIGTERM) is handler
        assert signal.getsignal(signal.SIGINT) == signal.SIG_IGN and signal.getsignal(signal.SIGTERM) is term
    finally:
        signal.signal(signal.SIGINT, before)


@pytest.mark.slow
def test_reading_plotting_exporting_and_resuming_a_result_leave_the_warning_filters_alone(
    tmp_path, cli, tiny_scenario, write_scenario
):
    """xarray puts a filter of its own in front of the process's at every file it decodes:
    one the host added after a first read was overridden by it at the next.  The result is
    read through :func:`multilayer.io.results.decoded`, which leaves the filters alone.
    (The filters that numpy, scipy and matplotlib add once, when first imported, are
    theirs: each path is taken once before the filters are compared.)"""
    import multilayer

    tiny_scenario["time"] = {"end": 0.02, "output_interval": 0.01}
    path, out = write_scenario(tiny_scenario), tmp_path / "out"
    paths = {
        "open_result": lambda: open_result(out),
        "multilayer.run": lambda: multilayer.run(path, tmp_path / "api"),
        "plot": lambda: cli("plot", out),
        "export": lambda: cli("export", out, "--vtk"),
        "resume": lambda: cli("run", path, "-o", out, "--resume", "--set", "time.end=0.03", "-q"),
    }
    assert cli("run", path, "-o", out, "-q").code == 0
    for take in paths.values():
        take()
    with warnings.catch_warnings():
        warnings.simplefilter("error", FutureWarning)  # the host's own, after the first read
        before = list(warnings.filters)
        for name, take in paths.items():
            result = take()
            assert getattr(result, "code", 0) == 0, result.err
            assert warnings.filters == before, name


# ----------------------------------------------------------------------------- plot


@pytest.mark.slow
def test_plot_of_a_failed_result_draws_its_records_and_says_how_it_ended(tmp_path, cli):
    _path, outdir = _finished(tmp_path, cli)
    with netCDF4.Dataset(outdir / "result.nc", "a") as ds:
        ds.run_status = "failed"
        ds.failure = "viscosity() returned nan"
    result = cli("plot", outdir)
    assert result.code == 0
    _no_traceback(result.err)
    assert "the run failed: viscosity() returned nan; drawn up to t = 0.04 s" in result.err
    assert all((outdir / "plots" / name).stat().st_size > 0 for name in ("section.png", "thickness.png"))


def test_the_lock_is_per_process(tmp_path):
    with lock.locked(tmp_path):
        assert json.loads((tmp_path / lock.LOCK_FILE).read_text())["pid"] == os.getpid()
        with pytest.raises(Exception, match="this process already runs into this directory"):
            with lock.locked(tmp_path):
                pass
    assert not (tmp_path / lock.LOCK_FILE).exists()


# ----------------------------------------------------------------------------- project errors


def test_stepping_past_the_end_or_without_progress_is_a_named_error_never_a_hang():
    """``step(t_max)`` not later than ``t`` is bad input; a step too small to change ``t``
    (a run far longer than its time step) is a run error instead of an endless loop."""
    from engine import simulation

    from multilayer.errors import InputError

    sim = simulation(initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 2.0, "height": 0.5}])
    sim.step()
    with pytest.raises(
        InputError,
        match=r"step\(t_max=0.0\): t_max must be a number at least 4.45e-308 s later than the curr",
    ):
        sim.step(0.0)
    sim.load_state({**sim.state_dict(), "t": 1e17})  # dt ~ 1e-2 s is below the spacing of floats at 1e17
    with pytest.raises(RunError, match=r"the time step dt = .* s at t = 1e\+17 s does not advance the time"):
        sim.advance(2e17, max_steps=None)
    assert sim.t == 1e17 and sim.steps == 1


@pytest.mark.parametrize(
    ("write", "said", "array"),
    [
        (lambda sim: sim.h.__setitem__(3, np.nan), "thickness h = nan at x = 0.04375 m", "sim.h"),
        (lambda sim: sim.h.__setitem__(slice(None), np.nan), "thickness h = nan at x = 0.00625 m", "sim.h"),
        (lambda sim: sim.h.__setitem__(30, np.nan), "thickness h = nan at x = 0.38125 m", "sim.h"),  # dry
        (lambda sim: sim.h.__setitem__(3, -1.0), "negative thickness h = -1 m at x = 0.04375 m", "sim.h"),
        (lambda sim: sim.h.__setitem__(3, np.inf), "thickness h = inf at x = 0.04375 m", "sim.h"),
        (
            lambda sim: sim.u.__setitem__((0, 3), np.nan),
            "velocity u = nan at x = 0.04375 m, layer 1 (1 is at the bed)",
            "sim.u",
        ),
        (
            lambda sim: sim.u.__setitem__((1, 3), -np.inf),
            "velocity u = -inf at x = 0.04375 m, layer 2 (1 is at the bed)",
            "sim.u",
        ),
        # a column without material: the steps never read it, the NaN was carried into the results
        (
            lambda sim: sim.u.__setitem__((1, 30), np.nan),
            "velocity u = nan at x = 0.38125 m, layer 2 (1 is at the bed)",
            "sim.u",
        ),
        (
            lambda sim: sim.u.__setitem__((2, 30), 5.0),
            "velocity u = 5.0 at x = 0.38125 m, layer 3 (1 is at the bed), where there is no material "
            "(h = 0)",
            "sim.u",
        ),
        (
            lambda sim: sim.w.__setitem__((0, 30), np.nan),
            "vertical velocity w = nan at x = 0.38125 m, layer 1 (1 is at the bed)",
            "sim.w",
        ),
        (
            lambda sim: sim.q.__setitem__((0, 3), np.inf),
            "non-hydrostatic pressure q = inf at x = 0.04375 m, layer 1 (1 is at the bed)",
            "sim.q",
        ),
    ],
)
def test_a_state_written_between_steps_is_named_as_the_entry_state_not_the_steps_error(write, said, array):
    """An API user writes into ``sim.h`` / ``sim.u`` / ``sim.w`` / ``sim.q`` (numpy arrays
    updated in place) a value no step keeps: the next step names that state on entry and the
    array written (it blamed the transport: "the transport made an error of 0.0123 m2", "h =
    nan after transport", "dt = 0.0 s does not advance the time"; a NaN or a velocity
    written into a column without material was carried into the results, exit 0), prints no
    numpy warning, and keeps the state of the last step."""
    import warnings

    from engine import simulation

    sim = simulation(**TINY_SCENARIO)
    sim.step()
    sim.step()
    write(sim)
    kept = sim.state_dict()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(StateError) as failure:
            sim.step()
    assert str(failure.value) == (
        f"{said} on entry to the step from t = {kept['t']:.6g} s (step 3): not as the steps leave it, "
        f"so written into {array} since the last step"
    )
    assert sim.steps == 2 and np.array_equal(sim.h, kept["h"], equal_nan=True)


def test_a_mixtures_solid_written_between_steps_and_a_velocity_without_material_restored_are_named():
    """The solid of a mixture written outside ``[0, h]`` between steps is named on entry to
    the next step; ``load_state`` of a velocity in a column without material is refused
    before it replaces anything (the next step blamed ``sim.u``)."""
    from engine import simulation

    from multilayer.errors import InputError

    mixture = simulation(
        **{
            **TINY_SCENARIO,
            "rheology": {"name": "dilatant_coulomb", "delta_deg": 22.5, "K1": 90.5},
            "material": {"density": 1500.0, "grain_diameter": 160e-6, "particle_density": 2500.0},
            "fluid": {"density": 1041.0, "viscosity": 0.096},
            "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
            "base": [{"condition": "no_slip"}],
            "initial": [{"shape": "rectangle", "x_min": 0.0, "x_max": 0.1, "height": 0.05, "phi": 0.55}],
        }
    )
    mixture.step()
    mixture.state.fields["solid"][0, 3] = -1e-3
    entry = r"on entry to the step from t = .* so written into sim.state.fields\['solid'\] or sim.h since"
    with pytest.raises(RunError, match=r"solid volume s = -0.001 m outside .* " + entry):
        mixture.step()
    sim = simulation(**TINY_SCENARIO)
    saved = sim.state_dict()
    saved["u"][1, 30] = 2.0
    with pytest.raises(InputError, match=r"u holds a velocity where h = 0 \(layer 2, column 30: 2.0 m/s\)"):
        sim.load_state(saved)
    assert not sim.u.any()


@pytest.mark.parametrize(
    ("thickness", "named"),
    [
        (1e308, r"the wave speed sqrt\(g cos\(theta\) h\) \+ \|u\|"),
        (1e200, r"the transport \(thickness x wave speed\^2 / cell width, waves at 2\.9\d+e\+100 m/s "
         r"on cells of 0\.0125 m\)"),
    ],
)  # fmt: skip
def test_a_finite_state_whose_wave_speed_overflows_is_named_not_the_length_of_the_run(thickness, named):
    """``sim.h[3] = 1e308`` between steps (finite, >= 0: the entry check passes): g h
    overflows, the Courant step was 0 and the message blamed the length of the run ("dt
    below the resolution of t when the run is too long for its step").  ``sim.h[3] =
    1e200``: its wave speed, 3e100 m/s, is finite, but the transport's ``h^2`` and ``h s^2
    / dx`` are not, and the step's state held a NaN, named as "thickness h = nan after
    transport" with no word of the thickness that made it."""
    from engine import simulation

    sim = simulation(**TINY_SCENARIO)
    sim.step()
    sim.h[3] = thickness
    with pytest.raises(
        StateError,
        match=named
        + r" of the state at t = 0.00843656 s \(step 2\) overflows \(thickness up to "
        + re.escape(f"{thickness!r} m, velocity up to"),
    ):
        sim.step()
    assert sim.steps == 1


def test_the_transport_is_refused_where_its_products_overflow_only():
    """:func:`fluxes_overflow` bounds ``h^2``, ``h s^2`` and their quotient by ``dx``: a
    thickness whose products stay finite (1e100 m) is not refused."""
    from multilayer.engine.transport.reference import fluxes_overflow

    assert fluxes_overflow(1e200, 3e100, 0.0125) and not fluxes_overflow(1e100, 3e50, 0.0125)
    assert fluxes_overflow(0.05, 1e160, 0.0125)  # u^2 overflows
    assert fluxes_overflow(1e150, 1.0, 1e-10) and not fluxes_overflow(1e150, 1.0, 1.0)  # / dx


def test_stepping_without_a_bound_where_no_wave_bounds_the_step_is_named():
    """``sim.step()`` (no ``t_max``) on a domain with no material and no inflow: the Courant
    step is infinite; it was taken (h = nan after transport over dt = inf, a numpy warning)."""
    from engine import simulation

    from multilayer.errors import InputError

    sim = simulation(**{**TINY_SCENARIO, "initial": []})
    with pytest.raises(InputError, match=r"step\(t_max=inf\): no material and no inflow, so no wave bounds"):
        sim.step()
    assert sim.step(0.1) == 0.1 and sim.t == 0.1 and not sim.h.any()


def test_a_singular_non_hydrostatic_system_and_a_non_finite_measure_are_run_errors(tmp_path):
    from multilayer.app import ensemble
    from multilayer.engine.pressure.non_hydrostatic.banded import factor

    indefinite = np.array([[1.0, 2.0], [1.0, 0.0]])  # band rows A[i, i], A[i, i + 1] of [[1, 2], [2, 1]]
    with pytest.raises(RunError, match="the non-hydrostatic pressure system is not positive definite"):
        factor(indefinite, np.zeros(2, dtype=np.bool_), np.zeros((2, 2)), 0)
    with pytest.raises(RunError, match=r"a measured quantity is not finite \(\[nan\]\)"):
        ensemble._measured(lambda path: np.array([np.nan]), tmp_path)


@pytest.mark.parametrize(
    ("change", "name", "value", "layer"),
    [(np.nan, "vertical velocity w", "nan", 3), (1e308, "non-hydrostatic pressure q", "inf", 1)],
)
def test_a_non_finite_non_hydrostatic_state_stops_the_step_keeping_the_last_good_state(
    monkeypatch, change, name, value, layer
):
    """The projection's w and q are guarded like h and u: a change of w of layer 3 by a NaN
    (a NaN w) or by 1e308 (a finite w, an infinite q below it), made inside the kernel that
    writes them after a few good steps of a frictionless dam break, stops the step with
    the quantity named, and the state stays that of the step before."""
    from engine import simulation

    from multilayer.engine.pressure.non_hydrostatic import projection as nonhydrostatic
    from multilayer.engine.state_check import StateError

    sim = simulation(
        domain={"x_min": 0.0, "x_max": 2.0, "cells": 40, "layers": 4},
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.5, "height": 0.2}],
        model={"pressure": "non_hydrostatic"},
    )
    for _ in range(3):
        sim.step()
    good = {key: getattr(sim, key).copy() for key in ("h", "u", "w", "q")}
    t = sim.t
    finish = nonhydrostatic._finish

    def corrupted(dV, dQ, u, w, h, fractions, moving, left, right, dt, lo, *rest):
        L, N = moving.shape
        assert moving[2, 5 - lo]
        dV, dQ = dV.copy(), dQ.copy()  # the change of w and the pressure's, both changed
        dV[L * left.size + 2 * N + 5 - lo] = dQ[L * left.size + 2 * N + 5 - lo] = change
        return finish(dV, dQ, u, w, h, fractions, moving, left, right, dt, lo, *rest)

    monkeypatch.setattr(nonhydrostatic, "_finish", corrupted)
    expected = rf"{name} = {value} at x = 0\.275 m, layer {layer} .* after the step from t = "
    with pytest.raises(StateError, match=expected):
        sim.step()
    assert sim.t == t
    for key, kept in good.items():
        np.testing.assert_array_equal(getattr(sim, key), kept)


@pytest.mark.parametrize("solver", ["numpy", "kernel"])
def test_periodic_sides_that_do_not_carry_the_same_mass_are_caught(solver, monkeypatch):
    """On periodic sides the two end faces are one face.  A transport that reports 1e-12 m2
    more entering the left side than leaving the right one, and puts it into the flow, keeps
    the mass balance of its own fluxes; the guard names the mismatch, with its size, and
    keeps the last good state.  The same run unbroken passes (the faces agree to the bit)."""
    from engine import simulation

    delta = 1e-12

    def corrupting(real):
        def corrupted(*args, **kwargs):
            h, u = real(*args, **kwargs)
            if kwargs.get("stage") != 0:
                kwargs["boundary_mass"][0] += delta
                h[int(np.argmax(h))] += delta / kwargs["dx"]
            return h, u

        return corrupted

    periodic = dict(numerics={"transport_solver": solver}, **BALANCE_CASES["periodic"])
    valid = simulation(**periodic)
    valid.advance(0.3)
    monkeypatch.setattr(transport, "transport", corrupting(transport.transport))
    monkeypatch.setattr(transport_kernel, "transport", corrupting(transport_kernel.transport))
    sim = simulation(**periodic)
    h0 = sim.h.copy()
    with pytest.raises(
        StateError, match=r"the periodic sides do not match after the step from t = 0 s"
    ) as caught:
        sim.step()
    error = float(re.search(r"the transport made an error of (\S+) m2", str(caught.value))[1])
    assert error == pytest.approx(delta, rel=1e-3)
    assert sim.steps == 0 and np.array_equal(sim.h, h0)


PERIODIC = sorted(
    path.stem
    for path in (Path(__file__).parents[1] / "scenarios").glob("*.yaml")
    if yaml.safe_load(path.read_text())["boundaries"]["left"] == "periodic"
)


@pytest.mark.parametrize("name", PERIODIC)
def test_the_shipped_periodic_scenarios_pass_the_periodic_check(name):
    """The shipped chutes and immersed layers on periodic sides run under the guard's
    periodic check: mass crosses the sides in every step, the same to the last bit."""
    import multilayer

    sim = multilayer.Simulation(multilayer.load(Path(__file__).parents[1] / "scenarios" / f"{name}.yaml"))
    crossed = []
    for _ in range(10):
        sim.step()
        crossed.append(sim.boundary_mass.copy())
    left, right = np.transpose(crossed)
    assert np.array_equal(left, right) and np.all(left != 0.0)
    sim.check_state()


def test_the_fipy_reference_polls_between_its_iterations_so_a_signal_stops_it_promptly():
    """One call of the FiPy reference solver (ALG2, up to 20000 FiPy solves) took minutes:
    a SIGTERM was honoured only when it returned (4.4 minutes measured on 40 cells x 3
    layers).  It calls ``poll`` before every iteration, which the run's stop request raises
    from: the solve is abandoned at the next iteration."""
    from multilayer.engine.vertical.problem import ColumnProblem
    from multilayer.reference import vertical_fipy

    shape = (3, 4)
    problem = ColumnProblem(
        m=np.full(shape, 10.0), ustar=np.full(shape, 1.0), dt=1e-3, kappa=np.full(shape, 5.0),
        c=np.full(shape, 1.0), w=np.zeros(shape), cw=np.zeros(shape),
    )  # fmt: skip
    calls = []

    def poll():
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        vertical_fipy.solve(problem, poll=poll)
    assert len(calls) == 3


def test_the_resume_command_sets_whole_a_mapping_a_set_replaced(tmp_path):
    """``--set rheology={name: drucker_prager, ...}`` on a file holding a ``jop_mu_i`` law:
    the "resume with:" command printed after an interrupt set the law's keys that differ,
    and kept the file's ``mu_2`` and ``I_0``, which ``drucker_prager`` refuses (exit 2 on
    resume).  A key the run does not have sets its nearest mapping whole."""
    import shlex

    import multilayer
    from multilayer.app.runner import _resume_command

    data = dict(TINY_SCENARIO, rheology={"name": "jop_mu_i", "mu_s": 0.3, "mu_2": 0.6, "I_0": 0.3})
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(data))
    sets = ["rheology={name: drucker_prager, mu_s: 0.3, nu: 0.01}", "initial.0.height=0.04"]
    scenario = multilayer.load(path, sets)
    words = shlex.split(_resume_command(scenario, tmp_path / "out"))
    given = [words[i + 1] for i, word in enumerate(words) if word == "--set"]
    assert any(item.startswith("rheology={") for item in given), given
    assert multilayer.load(path, given).resolved_yaml() == scenario.resolved_yaml()


@pytest.mark.slow
def test_the_commands_leave_no_file_in_tmpdir_and_only_the_documented_caches_in_home(tmp_path):
    """``run``, ``plot``, ``export`` and ``sweep`` with ``HOME`` and ``TMPDIR`` empty
    directories: a sweep left Dask's ``dask-scratch-space`` with two lock files in TMPDIR;
    in HOME only matplotlib's font cache and its empty configuration directory (docs/cli.md)."""
    home, tmp = tmp_path / "home", tmp_path / "tmp"
    home.mkdir()
    tmp.mkdir()
    env = {
        k: v for k, v in os.environ.items() if k not in ("XDG_CACHE_HOME", "XDG_CONFIG_HOME", "MPLCONFIGDIR")
    }
    env.update(HOME=str(home), TMPDIR=str(tmp))
    (tmp_path / "base.yaml").write_text(yaml.safe_dump(TINY_SCENARIO))
    (tmp_path / "sweep.yaml").write_text("base: base.yaml\nparameters:\n  rheology.mu_s: [0.3, 0.31]\n")
    out = tmp_path / "out"
    for argv in (
        ["run", "base.yaml", "-o", str(out), "-q"],
        ["plot", str(out)],
        ["export", str(out), "--vtk"],
        ["sweep", "sweep.yaml", "-o", str(tmp_path / "sweep-out"), "--workers", "1"],
    ):
        done = subprocess.run(
            [sys.executable, "-m", "multilayer", *argv], cwd=tmp_path, env=env, capture_output=True, text=True
        )
        assert done.returncode == 0, done.stderr
    assert list(tmp.iterdir()) == []
    left = {p.relative_to(home).as_posix() for p in home.rglob("*") if p.is_file()}
    assert all(re.fullmatch(r"\.cache/matplotlib/fontlist-v[\d.]+\.json", name) for name in left), left
    assert {p.relative_to(home).as_posix() for p in home.rglob("*") if p.is_dir()} <= {
        ".cache",
        ".cache/matplotlib",
        ".config",
        ".config/matplotlib",
    }


def test_all_finite_does_not_overflow_on_finite_values():
    """The sum of finite values near the largest float overflows: finite, and no warning."""
    import warnings

    from multilayer.engine.state_check import all_finite

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert all_finite(np.full((3, 4), 1e308))
        assert not all_finite(np.array([1.0, np.nan]))
        assert not all_finite(np.array([1e308, np.inf]))
        assert all_finite(np.empty(0))
