"""Thread policy of the compiled kernels, and what a CLI call that runs nothing imports."""

from __future__ import annotations

import subprocess
import sys

import pytest

from multilayer.engine import threads
from multilayer.errors import InputError


def test_small_steps_run_on_one_thread_and_fixed_counts_are_kept(monkeypatch):
    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    assert threads.ThreadPolicy("auto").threads(threads.PARALLEL_CELLS - 1) == 1
    assert threads.ThreadPolicy(1).threads(10**9) == 1


def test_auto_starts_on_one_thread_until_the_idle_cores_are_measured(monkeypatch):
    monkeypatch.delenv(threads.ENVIRONMENT, raising=False)
    assert threads.ThreadPolicy("auto").threads(10**9) == 1


def test_the_environment_overrides_the_scenario(monkeypatch):
    monkeypatch.setenv(threads.ENVIRONMENT, "1")
    assert threads.ThreadPolicy(2).fixed == 1
    monkeypatch.setenv(threads.ENVIRONMENT, "auto")
    assert threads.ThreadPolicy(2).fixed is None
    monkeypatch.setenv(threads.ENVIRONMENT, "two")
    with pytest.raises(InputError, match="MULTILAYER_THREADS='two'"):
        threads.ThreadPolicy("auto")


@pytest.mark.parametrize("argv", [["--help"], ["plugins"], ["validate", "scenarios/bagnold_chute.yaml"]])
def test_commands_that_run_nothing_import_neither_fipy_nor_numba(argv):
    code = (
        "import sys\n"
        "from multilayer.app.cli import main\n"
        "try:\n"
        f"    main({argv!r})\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted(m for m in ('fipy', 'numba') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"


def test_each_parallel_kernel_is_cached_apart_from_its_serial_compilation():
    """numba's on-disk cache names a compilation by the function's qualified name and line
    and keys it by signature only: compiled from the same function, a parallel kernel and
    its serial twin shared one entry and both loaded whichever was compiled last."""
    from multilayer.engine import column_kernel, newton_kernel, stress_kernel, transport_kernel

    pairs = [
        (column_kernel._solve_serial, column_kernel._solve_parallel),
        (newton_kernel._serial, newton_kernel._parallel),
        (stress_kernel._serial, stress_kernel._parallel),
        (transport_kernel._stages_serial, transport_kernel._stages_parallel),
    ]
    for serial, parallel in pairs:
        assert parallel.targetoptions.get("parallel") and not serial.targetoptions.get("parallel")
        assert parallel.py_func.__qualname__ == serial.py_func.__qualname__ + "_parallel"
        assert parallel.py_func.__code__.co_code == serial.py_func.__code__.co_code  # the same kernel
        names = {d._cache._cache_file._index_name for d in (serial, parallel)}  # the cache files
        assert len(names) == 2, names
