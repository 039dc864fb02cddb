"""Rheology plugins are contained (docs/reliability.md): they are given read-only copies,
whatever they raise (``sys.exit``, ``KeyboardInterrupt``, any ``BaseException``) or
return (complex, text) is a failure naming them, a constructor that fails is bad input;
the user's own Ctrl-C still stops a run cleanly."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO

from multilayer.app.simulation import Simulation
from multilayer.errors import described, said
from multilayer.io.results import open_result
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
from multilayer.scenario import from_dict

SLUMP = {**TINY_SCENARIO, "name": "slump", "time": {"end": 0.1, "output_interval": 0.02}}
PLUGIN = "rheology plugin 'drucker_prager' (multilayer.plugins.builtins.drucker_prager.DruckerPrager)"


class Custom(BaseException):
    """Neither an Exception nor an interrupt."""


class Unshowable(RuntimeError):
    """A third party's exception whose ``__str__`` raises."""

    def __str__(self) -> str:
        raise ValueError("a message of the exception itself")


class NotText(ValueError):
    """A third party's exception whose ``__str__`` returns no string."""

    def __str__(self):
        return 3


UNSHOWN = "(its message cannot be shown: str() raised "


def test_said_and_described_show_an_exception_whose_str_fails():
    """An exception whose ``__str__`` raises or returns no string: its type and a note, never
    the error of ``str()`` itself in place of the message naming who raised it."""
    assert said(RuntimeError("plain")) == "plain"
    assert described(Unshowable()) == f"Unshowable: {UNSHOWN}ValueError)"
    assert described(NotText()) == f"NotText: {UNSHOWN}TypeError)"


def _numpy_path(monkeypatch) -> None:
    """The built-in law as a plugin without compiled forms: its Python methods run."""
    monkeypatch.setattr(DruckerPrager, "viscosity_kernel", lambda self, material: None)
    monkeypatch.setattr(DruckerPrager, "yield_stress_kernel", lambda self, material: None)


def _after(calls: int, action):
    """A yield_stress that behaves for ``calls`` calls, then does ``action``."""
    real = DruckerPrager.yield_stress
    count = [0]

    def yield_stress(self, pressure, material):
        count[0] += 1
        return action(pressure) if count[0] > calls else real(self, pressure, material)

    return yield_stress


def _raise(exc: BaseException):
    def action(pressure):
        raise exc

    return action


@pytest.mark.parametrize(
    ("action", "expected"),
    [
        (_raise(SystemExit(0)), "yield_stress() raised SystemExit: 0"),
        (_raise(KeyboardInterrupt()), "yield_stress() raised KeyboardInterrupt"),
        (_raise(Custom("odd")), "yield_stress() raised Custom: odd"),
        (_raise(Unshowable()), f"yield_stress() raised Unshowable: {UNSHOWN}ValueError)"),
        (_raise(NotText()), f"yield_stress() raised NotText: {UNSHOWN}TypeError)"),
        (lambda p: np.zeros(p.shape, complex), "yield_stress() returned values of type complex128"),
        (lambda p: np.full(p.shape, "1.0"), "yield_stress() returned values of type <U3"),
        (lambda p: [[None] * p.shape[1]] * p.shape[0], "yield_stress() returned values of type object"),
        (  # read as the numbers under the mask, silently
            lambda p: np.ma.masked_less(0.3 * p, 1e300),
            "yield_stress() returned a masked array of ",
        ),
        (
            lambda p: p.__setitem__(0, 0.0),
            "yield_stress() raised ValueError: assignment destination is read-only",
        ),
    ],
)
def test_whatever_a_plugin_raises_or_returns_mid_run_is_exit_1_naming_it_keeping_the_last_state(
    tmp_path, cli, write_scenario, monkeypatch, action, expected
):
    _numpy_path(monkeypatch)
    monkeypatch.setattr(DruckerPrager, "yield_stress", _after(8, action))
    run = cli("run", write_scenario(SLUMP), "-o", tmp_path / "out", "-q")
    assert run.code == 1, run.err
    assert "Traceback" not in run.err and PLUGIN in run.err and expected in run.err
    kept = open_result(tmp_path / "out")
    assert kept.attrs["run_status"] == "failed" and expected in kept.attrs["failure"]
    assert kept.sizes["time"] >= 2  # the initial state, the outputs before and the last good state


def _vandal(real, calls):
    """A yield stress that forces its copy of the pressure writeable and scales it."""

    def vandal(self, pressure, material):
        calls.append(pressure)
        kappa = real(self, pressure, material)
        pressure.flags.writeable = True  # numpy allows it on an array that owns its data
        pressure *= 10.0
        return kappa

    return vandal


def _hoarder(real, calls):
    """A yield stress that keeps what it returned and zeroes it at its next call."""

    def hoarder(self, pressure, material):
        for earlier in calls:
            earlier *= 0.0
        calls.append(real(self, pressure, material))
        return calls[-1]

    return hoarder


@pytest.mark.parametrize("misbehaving", [_vandal, _hoarder])
def test_a_plugin_changing_what_it_was_given_or_what_it_returned_changes_nothing(monkeypatch, misbehaving):
    """It writes into its own copy of the pressure, or into the arrays it returned before:
    the results are those of a clean twin, to the last bit (neither the state nor the
    stresses are its to change)."""
    _numpy_path(monkeypatch)
    scenario = from_dict(SLUMP)
    clean = Simulation(scenario)
    clean.advance(0.05)
    calls: list = []
    monkeypatch.setattr(DruckerPrager, "yield_stress", misbehaving(DruckerPrager.yield_stress, calls))
    twin = Simulation(scenario)
    twin.advance(0.05)
    assert len(calls) > 5
    np.testing.assert_array_equal(twin.h, clean.h)
    np.testing.assert_array_equal(twin.u, clean.u)


def test_a_mixture_law_writing_into_the_pore_pressure_it_was_given_changes_nothing(monkeypatch):
    """The mixture's state (``MixtureState``) is given with read-only copies of its arrays:
    its excess pore pressure was a view of the Newton iterate, which a law writing into it
    changed (the step then failed to converge, blamed on the iteration). Forced writeable
    and scaled, the copy changes nothing, to the last bit."""
    _numpy_path(monkeypatch)
    mixture = {
        **SLUMP,
        "material": {"density": 1500.0, "grain_diameter": 1e-3, "particle_density": 2500.0},
        "fluid": {"density": 1000.0, "viscosity": 1e-3},
        "mixture": {"phi_critical": 0.58, "dilatancy": 4.0, "critical_shift": 25.0},
        "initial": [{**SLUMP["initial"][0], "phi": 0.58}],
    }
    scenario = from_dict(mixture)
    clean = Simulation(scenario)
    clean.advance(0.02)
    real, calls = DruckerPrager.mixture_yield_stress, []

    def vandal(self, pressure, state, material):
        calls.append(state)
        for array in (state.pore_pressure, state.phi):
            assert not array.flags.writeable
            array.flags.writeable = True
            array *= 10.0
        return real(self, pressure, state, material)

    monkeypatch.setattr(DruckerPrager, "mixture_yield_stress", vandal)
    twin = Simulation(scenario)
    twin.advance(0.02)
    assert len(calls) > 5
    np.testing.assert_array_equal(twin.h, clean.h)
    np.testing.assert_array_equal(twin.u, clean.u)
    np.testing.assert_array_equal(twin.mixture.pore_pressure, clean.mixture.pore_pressure)


@pytest.mark.parametrize(
    ("declared", "expected"),
    [
        (("power", (1.0, 2.0)), "declares the form 'power' with parameters (1.0, 2.0); it takes 4 numbers"),
        (("constant", ("a",)), "viscosity_kernel() returned values of type <U1"),
        ("constant", "viscosity_kernel() returned 'constant'; must be None or (form name, parameters)"),
        (SystemExit(3), "viscosity_kernel() raised SystemExit: 3"),
    ],
)
def test_a_malformed_compiled_form_is_exit_1_naming_the_plugin(
    tmp_path, cli, write_scenario, monkeypatch, declared, expected
):
    """The kernels read as many parameters as the form has: a declaration with fewer would be
    read past its end (numba does not check bounds)."""

    def viscosity_kernel(self, material):
        if isinstance(declared, BaseException):
            raise declared
        return declared

    monkeypatch.setattr(DruckerPrager, "viscosity_kernel", viscosity_kernel)
    run = cli("run", write_scenario(SLUMP), "-o", tmp_path / "out", "-q")
    assert run.code == 1 and "Traceback" not in run.err
    assert PLUGIN in run.err and expected in run.err


@pytest.mark.parametrize(
    ("exc", "expected"),
    [
        (RuntimeError("no licence"), "raised RuntimeError: no licence"),
        (SystemExit(1), "raised SystemExit: 1"),
        (ZeroDivisionError("division by zero"), "raised ZeroDivisionError: division by zero"),
        (Unshowable(), f"raised Unshowable: {UNSHOWN}ValueError)"),
    ],
)
def test_a_constructor_that_fails_is_exit_2_bad_parameters(
    tmp_path, cli, write_scenario, monkeypatch, exc, expected
):
    def constructor(self, mu_s: float, nu: float, mu_start: float | None = None):
        raise exc

    monkeypatch.setattr(DruckerPrager, "__init__", constructor)
    path = write_scenario(SLUMP)
    for command in (("validate", path), ("run", path, "-o", tmp_path / "out")):
        result = cli(*command)
        assert result.code == 2, result.err
        assert "Traceback" not in result.err
        assert (
            "rheology.name" not in result.err
            and "drucker_prager: DruckerPrager(mu_s=0.3, nu=0.01)" in result.err
        )
        assert expected in result.err and "accepted: drucker_prager(mu_s: float, nu: float" in result.err


def test_a_constructors_value_error_whose_message_cannot_be_shown_is_exit_2_naming_the_law(
    cli, write_scenario, monkeypatch
):
    def constructor(self, mu_s: float, nu: float, mu_start: float | None = None):
        raise NotText()

    monkeypatch.setattr(DruckerPrager, "__init__", constructor)
    result = cli("validate", write_scenario(SLUMP))
    assert result.code == 2 and "Traceback" not in result.err, result.err
    assert f"drucker_prager: {UNSHOWN}TypeError)" in result.err, result.err


def test_a_yield_stress_of_1e308_is_a_static_column_without_numpys_overflow_warning(
    tmp_path, cli, write_scenario, monkeypatch
):
    """The column solve's finiteness test summed its coefficients: finite ones of 1e308
    overflowed the sum, and numpy warned of it."""
    _numpy_path(monkeypatch)
    monkeypatch.setattr(DruckerPrager, "yield_stress", _after(8, lambda p: np.full(p.shape, 1e308)))
    run = cli("run", write_scenario(SLUMP), "-o", tmp_path / "out", "-q")
    assert run.code == 0 and "encountered" not in run.err and not run.err.strip(), run.err


def test_a_viscosity_whose_stress_overflows_is_exit_1_naming_the_plugin(
    tmp_path, cli, write_scenario, monkeypatch
):
    """A viscosity of 1e308 Pa s is finite, its stress and slope over a layer are not: the
    column kernel named its coefficient ``c`` after numpy's warnings."""
    _numpy_path(monkeypatch)
    monkeypatch.setattr(DruckerPrager, "viscosity", lambda self, rate, p, m: np.full(np.shape(p), 1e308))
    run = cli("run", write_scenario(SLUMP), "-o", tmp_path / "out", "-q")
    assert run.code == 1 and "encountered" not in run.err and len(run.err.strip().splitlines()) == 1, run.err
    assert PLUGIN in run.err and "viscosity() returned 1e+308 Pa s at the shear rate" in run.err, run.err
    assert open_result(tmp_path / "out").attrs["run_status"] == "failed"


SLOW_PLUGIN = """
import sys, time
from multilayer.app.cli import main
from multilayer.plugins.builtins.drucker_prager import DruckerPrager
real = DruckerPrager.yield_stress
def slow(self, pressure, material):
    time.sleep(0.05)  # the user's Ctrl-C lands inside the plugin
    return real(self, pressure, material)
DruckerPrager.yield_stress = slow
DruckerPrager.yield_stress_kernel = lambda self, material: None
print("ready", flush=True)
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow  # a child process; the fault battery tries it too
def test_the_users_ctrl_c_inside_a_plugin_still_stops_the_run_cleanly(tmp_path, default_stop_signals):
    path = tmp_path / "slump.yaml"
    path.write_text(yaml.safe_dump({**SLUMP, "time": {"end": 50.0, "output_interval": 0.02}}))
    proc = subprocess.Popen(
        [sys.executable, "-c", SLOW_PLUGIN, "run", str(path), "-o", str(tmp_path / "out"), "-q"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout.readline().strip() == "ready"
    deadline = time.monotonic() + 120
    while not (tmp_path / "out" / "checkpoint.npz").exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    proc.send_signal(signal.SIGINT)
    _out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted by Ctrl-C (SIGINT)" in err and "Traceback" not in err
    assert open_result(tmp_path / "out").attrs["run_status"] == "interrupted"


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (lambda: os.chdir("/"), "changed the working directory from {cwd} to /"),
        (
            lambda: signal.signal(signal.SIGINT, signal.SIG_IGN),
            "changed the handler of SIGINT from {handler}",
        ),
        (lambda: np.seterr(all="raise"), "changed the numpy error handling from"),
    ],
)
def test_a_plugin_that_changes_the_process_it_runs_in_is_named_and_the_change_set_back(
    tmp_path, cli, write_scenario, monkeypatch, python_sigint, change, expected
):
    """A plugin's ``os.chdir`` stopped the run blaming a removed output directory (a relative
    one); one ignoring SIGINT made the run, and the process after it, deaf to Ctrl-C; numpy's
    error handling set to raise by a constructor stayed so in the host.  A step or a
    constructor that changes them is named, exit 1 (2 for a constructor: bad parameters),
    and the change set back (numpy's error handling during a call is the engine's own,
    set back after every call: no change).  SIGINT has Python's own handler to begin with
    (``python_sigint``): in a process started with it ignored, a constructor ignoring it
    changes nothing."""
    monkeypatch.chdir(tmp_path)
    _numpy_path(monkeypatch)

    def meddling(pressure):
        change()
        return np.zeros_like(pressure)

    monkeypatch.setattr(DruckerPrager, "yield_stress", _after(8, meddling))
    before = (os.getcwd(), signal.getsignal(signal.SIGINT), np.geterr())
    run = cli("run", write_scenario(SLUMP), "-o", "out", "-q")
    assert (os.getcwd(), signal.getsignal(signal.SIGINT), np.geterr()) == before
    assert "Traceback" not in run.err
    if "numpy" in expected:
        assert run.code == 0, run.err
    else:
        phrase = expected.format(cwd=tmp_path, handler="_StopRequest._handle")
        assert run.code == 1 and phrase in run.err and PLUGIN in run.err and "(set back)" in run.err, run.err
        assert open_result(tmp_path / "out").attrs["run_status"] == "failed"
    init = DruckerPrager.__init__

    def meddling_init(self, **params):
        init(self, **params)
        change()

    monkeypatch.setattr(DruckerPrager, "__init__", meddling_init)
    run = cli("validate", write_scenario(SLUMP))
    assert (os.getcwd(), signal.getsignal(signal.SIGINT), np.geterr()) == before
    phrase = expected.format(cwd=tmp_path, handler="default_int_handler")
    assert run.code == 2 and "DruckerPrager(mu_s=0.3, nu=0.01) changed" in run.err and phrase in run.err, (
        run.err
    )
