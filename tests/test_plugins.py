"""Plugin discovery: a real third-party distribution, broken and duplicate plugins."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pydantic
import pytest
import xarray as xr
from conftest import fault_battery

import multilayer
from multilayer import Material
from multilayer.errors import InputError
from multilayer.plugins import host as plugins
from multilayer.scenario import load

THIRDPARTY = Path(__file__).parent / "thirdparty_plugin"
MULTILAYER = [sys.executable, "-m", "multilayer"]


def pip(*args: str) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q", *args],
        capture_output=True,
        text=True,
    )
    if done.returncode:
        pytest.fail(f"pip {' '.join(args)} failed:\n{done.stderr}")


@pytest.fixture(
    scope="module",
    params=["entry point on the path", pytest.param("pip install", marks=pytest.mark.slow)],
)
def bingham(request, tmp_path_factory):
    """The plugin of tests/thirdparty_plugin made discoverable, for this module, either

    - as pip leaves an installed distribution: its module and a ``.dist-info`` directory
      holding its metadata and entry point, on ``sys.path`` and ``PYTHONPATH`` (no package
      index needed), or
    - pip-installed as a user would (a built wheel; the isolated build fetches setuptools
      from the package index, hence marked ``slow``), into a directory of this test's own
      on ``sys.path`` and ``PYTHONPATH``: a distribution installed into the shared
      environment was removed by one xdist worker's uninstall under another's test.
    """
    root = tmp_path_factory.mktemp("plugin")
    if request.param == "pip install":
        source = root / "multilayer-bingham"
        shutil.copytree(THIRDPARTY, source)  # the build writes into its source tree
        site = root / "site-packages"
        pip("install", "--no-deps", "--target", str(site), str(source))
    else:
        site = root
        module = (THIRDPARTY / "multilayer_bingham.py").read_text()
        fake_distribution(root, "multilayer-bingham", module, module="multilayer_bingham", version="1.0.0")
    with pytest.MonkeyPatch.context() as mp:
        mp.syspath_prepend(str(site))
        mp.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(site), os.environ.get("PYTHONPATH")])))
        plugins.refresh()
        yield
    sys.modules.pop("multilayer_bingham", None)
    plugins.refresh()


def bingham_scenario(tiny_scenario, **params):
    tiny_scenario["rheology"] = {"name": "bingham", **params}
    return tiny_scenario


@pytest.mark.slow
def test_installed_plugin_is_listed(bingham):
    result = subprocess.run([*MULTILAYER, "plugins"], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    assert "bingham [bulk]: Bingham plastic: constant yield stress, constant viscosity." in result.stdout
    assert "parameters: bingham(tau_y: float, eta: float)" in result.stdout
    assert "from: multilayer-bingham 1.0.0 (entry point bingham = multilayer_bingham)" in result.stdout
    assert "jop_mu_i [bulk]" in result.stdout  # the built-ins are still there


@pytest.mark.slow
def test_installed_plugin_usable_by_name(bingham, tiny_scenario, write_scenario):
    path = write_scenario(bingham_scenario(tiny_scenario, tau_y=40.0, eta=2.0))
    result = subprocess.run([*MULTILAYER, "validate", str(path)], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    law = plugins.instantiate(load(path).rheology)
    np.testing.assert_array_equal(law.yield_stress(np.zeros(3), Material(1500, 1e-3, 2500)), 40.0)


@pytest.mark.slow
def test_installed_plugin_parameters_are_validated(bingham, tiny_scenario, write_scenario):
    for params, key, needle in [
        ({"tau_y": 40.0, "eta": 2.0, "tau_z": 1.0}, "rheology.tau_z", "unknown parameter of bingham"),
        ({"tau_y": 40.0}, "rheology.eta", "missing parameter"),
        ({"tau_y": -4.0, "eta": 2.0}, "rheology", "tau_y and eta must be >= 0"),
    ]:
        path = write_scenario(bingham_scenario(tiny_scenario, **params))
        result = subprocess.run([*MULTILAYER, "validate", str(path)], capture_output=True, text=True)
        assert result.returncode == 2
        assert "Traceback" not in result.stderr
        assert f"{path}: {key} (line " in result.stderr and needle in result.stderr
        assert "accepted: bingham(tau_y: float, eta: float)" in result.stderr


def test_installed_plugin_runs(bingham, tiny_scenario, write_scenario, tmp_path):
    """A Bingham layer stays exactly at rest while its yield stress exceeds the basal shear
    stress rho g h sin(theta) = 1500 * 9.81 * 0.01 * sin(20 deg) = 50.3 Pa."""
    scenario = bingham_scenario(tiny_scenario, tau_y=60.0, eta=2.0)
    scenario.update(
        slope_deg=20.0,
        initial=[{"shape": "layer", "thickness": 0.01}],
        boundaries={"left": "periodic", "right": "periodic"},
    )
    path = write_scenario(scenario)
    result = subprocess.run(
        [*MULTILAYER, "run", str(path), "-o", str(tmp_path / "out"), "-q"], capture_output=True, text=True
    )
    assert result.returncode == 0, result.stderr
    with xr.open_dataset(tmp_path / "out" / "result.nc") as ds:
        assert float(np.abs(ds["u"]).max()) == 0.0
        np.testing.assert_allclose(ds["h"].values, 0.01, rtol=1e-12)


# ---------------------------------------------------------------- broken plugins


def fake_distribution(
    root: Path, name: str, module_source: str, module: str | None = None, version: str = "1.0"
) -> None:
    """An installed distribution ``name`` (a .dist-info directory, as pip writes it) whose
    entry point ``<name> = <module>`` in the ``multilayer`` group is the module ``module``
    (default ``<name>_plugin``) with the source ``module_source``."""
    module = module or f"{name.replace('-', '_')}_plugin"
    entry = name.removeprefix("multilayer-")
    info = root / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    (info / "entry_points.txt").write_text(f"[multilayer]\n{entry} = {module}\n")
    (root / f"{module}.py").write_text(textwrap.dedent(module_source))


BROKEN = {
    "import-fails": (
        "import numpy\nraise ImportError('needs numpy >= 99')\n",
        "ImportError: needs numpy >= 99",
    ),
    "not-a-rheology": (
        """
        import multilayer
        class Thing:
            name = "thing"
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(Thing)
        """,
        "is not a subclass of multilayer.Rheology",
    ),
    "no-hookimpl": ("def multilayer_register_rheologies(register):\n    pass\n", "registers no rheology"),
    "exits-on-import": ("import sys\nsys.exit(3)\n", "SystemExit: 3"),
    "registers-a-number": (
        """
        import multilayer
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(42)
        """,
        "42 is not a subclass of multilayer.Rheology",
    ),
    "bad-applies-to": (
        """
        import multilayer
        class Odd(multilayer.Rheology):
            name = "odd"
            applies_to = "base"
            def yield_stress(self, pressure, material): return pressure
            def viscosity(self, shear_rate, pressure, material): return pressure
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(Odd)
        """,
        "applies_to must be 'bulk' or 'walls'",
    ),
    "a-parameter-name": (  # never settable: ``name: x`` in the scenario chose the law x
        """
        import multilayer
        from multilayer.plugins.builtins.drucker_prager import DruckerPrager
        class Labelled(DruckerPrager):
            name = "labelled"
            def __init__(self, mu_s: float, nu: float, name: str = "x"):
                super().__init__(mu_s, nu)
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(Labelled)
        """,
        "Labelled.__init__ has a parameter 'name', a key a scenario cannot give it: in `rheology:` and "
        "`walls:` `name` chooses the law; accepted: other parameter names",
    ),
    "uses-a-quantity-never-given": (  # a law for a quantity of another version ran on its default
        """
        import multilayer
        from multilayer.plugins.builtins.drucker_prager import DruckerPrager
        class Porous(DruckerPrager):
            name = "porous"
            uses = ("porosity",)
            def yield_stress(self, pressure, material, porosity=0.4):
                return super().yield_stress(pressure, material)
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(Porous)
        """,
        "Porous.uses must be a tuple of the column quantities the engine gives a law (thickness), got "
        "('porosity',): a quantity it never gives would leave the law on its own default",
    ),
    "uses-a-string": (  # "thickness" in "thickness" is true, tuple("thickness") is letters
        """
        import multilayer
        from multilayer.plugins.builtins.drucker_prager import DruckerPrager
        class Porous(DruckerPrager):
            name = "porous"
            uses = "thickness"
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(Porous)
        """,
        "Porous.uses must be a tuple of the column quantities the engine gives a law (thickness), got "
        "'thickness'",
    ),
    "changes-the-process-on-import": (  # a notebook's directory and numpy's errors changed for good
        """
        import os
        import numpy as np
        import multilayer
        from multilayer.plugins.builtins.drucker_prager import DruckerPrager
        os.chdir("/")
        np.seterr(all="ignore")
        class Quiet(DruckerPrager):
            name = "quiet"
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(Quiet)
        """,
        "importing and registering it changed the working directory from ",
    ),
    "duplicate": (
        """
        import multilayer
        from multilayer.plugins.builtins.drucker_prager import DruckerPrager
        class Impostor(DruckerPrager):
            pass
        @multilayer.hookimpl
        def multilayer_register_rheologies(register):
            register(Impostor)
        """,
        f"rheology name 'drucker_prager' is already registered by multilayer {multilayer.__version__} "
        "(entry point builtins = multilayer.plugins.builtins); this second registration was rejected",
    ),
}


@pytest.fixture
def fresh_catalogue():
    plugins.refresh()
    yield
    plugins.refresh()


@pytest.mark.parametrize("name", BROKEN)
def test_broken_plugin_is_reported_without_hiding_others(name, tmp_path, monkeypatch, fresh_catalogue):
    source, error = BROKEN[name]
    fake_distribution(tmp_path, name, source)
    monkeypatch.syspath_prepend(str(tmp_path))
    here, errors = Path.cwd(), np.geterr()
    with pytest.warns(plugins.PluginWarning, match=f"rheology plugin {name} 1.0"):
        catalogue = plugins.catalogue()
    [broken] = [b for b in catalogue.broken if b.source.startswith(f"{name} 1.0")]
    assert broken.source == f"{name} 1.0 (entry point {name} = {name.replace('-', '_')}_plugin)"
    assert error in broken.error
    assert os.getcwd() == str(here) and np.geterr() == errors  # set back, where a plugin changed them
    assert {"drucker_prager", "jop_mu_i", "power_law_mu_i", "wall_friction"} <= set(catalogue.rheologies)
    assert catalogue.rheologies["drucker_prager"].source.startswith("multilayer ")


@pytest.mark.slow  # installs a broken distribution in a child process
def test_cli_lists_broken_plugin_and_still_runs(tmp_path, tiny_scenario, write_scenario):
    fake_distribution(tmp_path / "site", "import-fails", BROKEN["import-fails"][0])
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "site")}
    listing = subprocess.run([*MULTILAYER, "plugins"], capture_output=True, text=True, env=env)
    assert listing.returncode == 0
    assert "broken plugins (skipped):\n  import-fails 1.0" in listing.stdout
    assert "drucker_prager [bulk]" in listing.stdout
    path = write_scenario(tiny_scenario)
    check = subprocess.run([*MULTILAYER, "validate", str(path)], capture_output=True, text=True, env=env)
    assert check.returncode == 0
    assert "multilayer: warning: rheology plugin import-fails 1.0" in check.stderr
    assert "Traceback" not in check.stderr


def test_lookup_and_instantiate():
    with pytest.raises(
        InputError,
        match="unknown rheology 'nope'; accepted: .*drucker_prager, jop_mu_i, pouliquen_forterre, "
        "power_law_mu_i$",
    ):
        plugins.lookup("nope", "bulk")
    with pytest.raises(
        InputError, match="'wall_friction' applies to walls, not bulk; accepted: .*drucker_prager"
    ):
        plugins.lookup("wall_friction", "bulk")

    class Spec:
        name, params = "jop_mu_i", {"mu_s": 0.38, "mu_2": 0.64, "I_0": -1.0}

    with pytest.raises(InputError, match=r"I_0 must be > 0.*accepted: jop_mu_i\(mu_s: float"):
        plugins.instantiate(Spec)
    Spec.params = {"mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279}
    assert plugins.instantiate(Spec).I_0 == 0.279


def test_parameter_model_is_strict():
    model = plugins.parameter_model(plugins.registry()["drucker_prager"])
    assert model.model_validate({"mu_s": 1, "nu": 0.5}).mu_s == 1.0
    for bad in ({"mu_s": True, "nu": 0.5}, {"mu_s": "0.5", "nu": 0.5}, {"mu_s": 0.5}):
        with pytest.raises(pydantic.ValidationError):
            model.model_validate(bad)


def test_a_plugin_printing_writes_to_stderr_and_its_text_is_listed_printable(
    tmp_path, monkeypatch, capsys, fresh_catalogue, tiny_scenario, write_scenario
):
    """A plugin printing as it is imported, registers and is constructed wrote its lines
    into the output of ``plugins`` and ``validate``, which scripts read; its docstring's
    escape sequence reached the terminal through ``plugins``."""
    from multilayer.app.cli import main

    fake_distribution(tmp_path, "loud", fault_battery().LOUD_PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    assert main(["plugins"]) == 0
    listing = capsys.readouterr()
    assert "loud: " not in listing.out and "loud: imported\nloud: registering" in listing.err
    assert (
        "loud [bulk]: \\x1b[31mA loud law\\x1b[0m, ringing \\x07." in listing.out
        and "\x1b" not in listing.out
    )
    path = write_scenario({**tiny_scenario, "rheology": {"name": "loud", "mu_s": 0.3, "nu": 0.01}})
    assert main(["validate", str(path)]) == 0
    checked = capsys.readouterr()
    assert "loud: " not in checked.out and "loud: constructed" in checked.err


def test_a_plugin_printing_as_it_runs_writes_to_stderr_under_run_and_to_the_hosts_stdout_in_the_api(
    tmp_path, monkeypatch, capsys, fresh_catalogue, tiny_scenario, write_scenario
):
    """A law printing in its yield stress and viscosity wrote a line per call into the
    stdout of ``multilayer run``, which carries the summary; through the Python API the
    host's stdout is the host's, and the law's lines go there."""
    import multilayer
    from multilayer.app.cli import main

    fake_distribution(tmp_path, "loudrun", fault_battery().LOUD_RUN_PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    law = {"name": "loudrun", "mu_s": 0.3, "nu": 0.01}
    path = write_scenario({**tiny_scenario, "rheology": law, "time": {"end": 0.02, "output_interval": 0.01}})
    stdout = sys.stdout
    assert main(["run", str(path), "-o", str(tmp_path / "cli")]) == 0
    ran = capsys.readouterr()
    assert sys.stdout is stdout
    assert ": wrote " in ran.out and "loud: " not in ran.out and "loud: yield_stress" in ran.err
    assert multilayer.run(path, tmp_path / "api").attrs["run_status"] == "completed"
    ran = capsys.readouterr()
    assert "loud: yield_stress" in ran.out and "loud: " not in ran.err


def test_a_plugin_printing_as_it_runs_writes_to_stderr_under_check(
    tmp_path, monkeypatch, capsys, fresh_catalogue, tiny_scenario, write_scenario
):
    """``multilayer check`` prints its report on stdout: a law printing as the scenario
    runs wrote its lines between the report's."""
    from multilayer.app.cli import main

    fake_distribution(tmp_path, "loudrun", fault_battery().LOUD_RUN_PLUGIN)
    monkeypatch.syspath_prepend(str(tmp_path))
    met = {"kind": "regression", "quantity": "mass_final", "value": 0.005, "rtol": 0.01}
    law = {"name": "loudrun", "mu_s": 0.3, "nu": 0.01}
    time = {"end": 0.02, "output_interval": 0.01}
    path = write_scenario({**tiny_scenario, "rheology": law, "time": time, "expect": [met]})
    assert main(["check", str(path)]) == 0
    checked = capsys.readouterr()
    assert "1/1 expectations met" in checked.out and "loud: " not in checked.out
    assert "loud: yield_stress" in checked.err


def test_a_plugin_replacing_stdout_as_it_runs_leaves_run_its_summary(
    monkeypatch, capsys, tiny_scenario, write_scenario
):
    """A law setting ``sys.stdout`` to None as it ran: ``multilayer run``'s summary was a
    traceback (None has no ``flush``).  The stdout of the command is set back after the run."""
    from multilayer.app.cli import main
    from multilayer.plugins.builtins.drucker_prager import DruckerPrager

    real = DruckerPrager.yield_stress

    def replacing(self, *arguments):
        sys.stdout = None
        return real(self, *arguments)

    monkeypatch.setattr(DruckerPrager, "yield_stress", replacing)
    monkeypatch.setattr(DruckerPrager, "yield_stress_kernel", lambda self, material: None)
    path = write_scenario({**tiny_scenario, "time": {"end": 0.02, "output_interval": 0.01}})
    stdout = sys.stdout
    assert main(["run", str(path), "-o", str(path.parent / "out")]) == 0
    assert sys.stdout is stdout and ": wrote " in capsys.readouterr().out


def test_the_workers_of_a_local_cluster_print_to_stderr(monkeypatch):
    """The local cluster's worker processes share the study's stdout, which carries its
    summary: their preload sends what a law prints as a member runs to stderr (run here in
    a thread, where it leaves the signal handlers alone)."""
    import logging
    import threading

    from multilayer.app import stopping

    monkeypatch.setattr(sys, "stdout", sys.stdout)  # set back after the test
    logger = logging.getLogger("distributed.worker")
    monkeypatch.setattr(logger, "filters", list(logger.filters))
    thread = threading.Thread(target=stopping.dask_setup, args=(None,))
    thread.start()
    thread.join()
    assert sys.stdout is sys.stderr


def test_plugins_constructed_in_threads_leave_the_process_stdout_alone():
    """In a thread that is not the main one, what a plugin prints is not sent to stderr:
    ``sys.stdout`` is the process's, and two threads each swapping it for stderr and
    restoring what they found left it swapped for good.  Two laws constructed at once, the
    first entering its constructor before the second and leaving it first (as the
    redirection restored the first's original, the second restored stderr): ``sys.stdout``
    is the same object throughout and after."""
    import sys
    import threading
    import time

    from multilayer.plugins.builtins.drucker_prager import DruckerPrager

    stdout, seen = sys.stdout, []
    entered, both = threading.Event(), threading.Barrier(2)

    class Slow(DruckerPrager):
        def __init__(self, lag: float, **params) -> None:
            entered.set()
            seen.append(sys.stdout)
            both.wait()
            time.sleep(lag)
            super().__init__(**params)

    def construct(lag: float) -> None:
        plugins.construct(Slow, {"lag": lag, "mu_s": 0.3, "nu": 0.01})

    first = threading.Thread(target=construct, args=(0.0,))
    second = threading.Thread(target=construct, args=(0.1,))
    first.start()
    entered.wait()
    second.start()
    first.join()
    second.join()
    assert sys.stdout is stdout and seen == [stdout, stdout]


def test_a_law_without_a_docstring_is_described_by_its_class(monkeypatch):
    """``python -OO`` removes every docstring: ``multilayer plugins`` listed each law with
    an empty description."""
    from multilayer.plugins.builtins.drucker_prager import DruckerPrager

    monkeypatch.setattr(plugins.inspect, "getdoc", lambda obj: None)
    assert plugins.description(DruckerPrager) == (
        "no description: class DruckerPrager of module multilayer.plugins.builtins.drucker_prager"
    )
