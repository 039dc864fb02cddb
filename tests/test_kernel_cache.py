"""numba's cache of the kernels is cleared when a kernel source changes (engine/kernel_cache.py):
numba keys a cached function by its own file only, so a caller would keep a callee's old code.
The check runs before the first kernel is loaded or compiled, never at import, and two
processes starting at once after an upgrade take turns."""

from __future__ import annotations

import contextlib
import importlib
import os
import shutil
import subprocess
import sys
import time
import types
import warnings
from collections.abc import Iterator
from pathlib import Path

import pytest

from multilayer.app.precompile import work
from multilayer.engine import kernel_cache


def _index(path, stamp=(1.0, 10), **kernels):
    """Write numba's index file ``path``: its version, then the source ``stamp`` and the
    kernel file of each signature (``kernels``: signature name -> file name)."""
    import pickle

    import numba

    path.write_bytes(pickle.dumps(numba.__version__) + pickle.dumps((stamp, kernels)))


def test_a_changed_kernel_source_clears_the_cached_kernels_once(tmp_path, monkeypatch):
    engine, cache = tmp_path / "engine", tmp_path / "engine" / "__pycache__"
    cache.mkdir(parents=True)
    (engine / "vertical").mkdir()
    callee = engine / "vertical" / "callee.py"
    callee.write_text("from numba import njit\n")
    (engine / "plain.py").write_text("x = 1\n")  # not a kernel module: not part of the digest
    monkeypatch.setattr(kernel_cache, "ENGINE", engine)

    def cached(*names):
        for name in names:
            (cache / name).write_bytes(b"compiled")

    assert kernel_cache.clear_if_stale(cache)  # no digest yet: whatever is cached is of unknown sources
    cached("caller._chunk-1.py311.nbi", "caller._chunk-1.py311.1.nbc")
    assert not kernel_cache.clear_if_stale(cache)  # unchanged sources: the cache is kept
    assert len(list(cache.glob("*.nb?"))) == 2
    (engine / "plain.py").write_text("x = 2\n")
    assert not kernel_cache.clear_if_stale(cache)
    callee.write_text("from numba import njit  # edited\n")  # the callee alone changes, in a subpackage
    assert kernel_cache.clear_if_stale(cache)
    assert list(cache.glob("*.nb?")) == [] and (cache / "kernels.digest").is_file()
    assert not kernel_cache.clear_if_stale(cache)


def test_the_compiled_mark_holds_for_the_sources_it_was_made_for(tmp_path, monkeypatch):
    """``multilayer compile``'s mark says the cache holds its kernels only for the kernel
    sources and numba it was written for: an edit of a kernel source makes it false, and
    clearing the stale cache deletes it."""
    engine = tmp_path / "engine"
    (engine / "vertical").mkdir(parents=True)
    kernel = engine / "vertical" / "kernel.py"
    kernel.write_text("from numba import njit\n")
    monkeypatch.setattr(kernel_cache, "ENGINE", engine)
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.chdir(tmp_path)
    assert not kernel_cache.is_compiled(work())
    cache = engine / "vertical" / "__pycache__"
    cache.mkdir(exist_ok=True)
    _index(cache / "kernel.f-1.py311.nbi")
    kernel_cache.mark_compiled(kernel_cache.compiled_text(work()))
    assert kernel_cache.cache_directories() == [cache] and kernel_cache.is_compiled(work())
    kernel.write_text("from numba import njit  # edited\n")
    assert not kernel_cache.is_compiled(work())
    assert kernel_cache.clear_if_stale(cache) and not (cache / kernel_cache.COMPILED).exists()


@pytest.mark.parametrize("damage", [b"\x90\xff\x00garbage", b"", b"not the digest\n"])
def test_a_mark_that_is_not_text_is_not_compiled(tmp_path, monkeypatch, damage):
    """A ``kernels.compiled`` mark overwritten with bytes that are not UTF-8 was a
    UnicodeDecodeError of ``multilayer compile``; any mark but the one it writes means not
    compiled (and ``multilayer compile`` compiles)."""
    monkeypatch.setattr(kernel_cache, "cache_directories", lambda: [tmp_path])
    _index(tmp_path / "kernel.f-1.py311.nbi")
    kernel_cache.mark_compiled(kernel_cache.compiled_text(work()))
    assert kernel_cache.is_compiled(work())
    (tmp_path / kernel_cache.COMPILED).write_bytes(damage)
    assert not kernel_cache.is_compiled(work())


def _fifo(path):
    path.unlink()
    os.mkfifo(path)


DAMAGE = {
    "kernel truncated": lambda d: os.truncate(d / "kernel.f-1.py311.1.nbc", 3),
    "kernel overwritten, same size": lambda d: (d / "kernel.f-1.py311.1.nbc").write_bytes(b"KERNEL"),
    "index emptied": lambda d: (d / "kernel.f-1.py311.nbi").write_bytes(b""),
    "index without the signature": lambda d: _index(d / "kernel.f-1.py311.nbi", g="kernel.f-1.py311.2.nbc"),
    "index of another source stamp": lambda d: _index(
        d / "kernel.f-1.py311.nbi", (2.0, 10), f="kernel.f-1.py311.1.nbc"
    ),
    "kernel deleted": lambda d: (d / "kernel.f-1.py311.1.nbc").unlink(),
    "kernel a directory": lambda d: (
        (d / "kernel.f-1.py311.1.nbc").unlink(),
        (d / "kernel.f-1.py311.1.nbc").mkdir(),
    ),
    "kernel a pipe": lambda d: _fifo(d / "kernel.f-1.py311.1.nbc"),
    "mark listing no file": lambda d: (d / kernel_cache.COMPILED).write_text(
        kernel_cache.compiled_text(work())
    ),
    "mark naming a file elsewhere": lambda d: (d / kernel_cache.COMPILED).write_text(
        kernel_cache.compiled_text(work()) + f"{'0' * 64} ../kernel.f-1.py311.nbi\n"
    ),
}


@pytest.mark.parametrize("damage", DAMAGE)
def test_compile_checks_the_cached_files_its_mark_records(tmp_path, monkeypatch, cli, damage):
    """``multilayer compile`` said "compiled and cached" when its mark was current though
    the cached files were damaged since (runs compiled them again, with a warning).  The
    mark records the SHA-256 of every cached file; a file missing, changed or no regular
    file (a pipe is never read) means not compiled, and the command compiles.  When the
    cache is whole it says how many files it checked.  An index is recorded by its entries:
    one that holds more signatures (a run compiled another since) is as compiled, one that
    lost a signature or whose source stamp changed (numba then reads none of it) is not."""
    from multilayer.app import precompile

    monkeypatch.setattr(kernel_cache, "cache_directories", lambda: [tmp_path])
    monkeypatch.setattr(kernel_cache, "ensure_fresh", lambda: None)
    _index(tmp_path / "kernel.f-1.py311.nbi", f="kernel.f-1.py311.1.nbc")
    (tmp_path / "kernel.f-1.py311.1.nbc").write_bytes(b"kernel")
    kernel_cache.mark_compiled(kernel_cache.compiled_text(work()))
    (tmp_path / "kernel.g_parallel-9.py311.nbi").write_bytes(b"compiled by a run since: not recorded")
    _index(tmp_path / "kernel.f-1.py311.nbi", f="kernel.f-1.py311.1.nbc", g="kernel.f-1.py311.2.nbc")
    result = cli("compile")
    assert result.code == 0 and result.out.startswith("the kernels are compiled and cached")
    assert "2 cached files checked" in result.out
    DAMAGE[damage](tmp_path)
    compiled = []
    monkeypatch.setattr(
        precompile, "_compile", lambda processes: compiled.append(processes) or precompile.Report()
    )
    result = cli("compile")
    assert result.code == 0 and compiled == [None] and "compiled the kernels in" in result.out


def test_a_second_compile_waits_for_the_first_then_finds_its_kernels(tmp_path, monkeypatch):
    """Two ``multilayer compile`` at once on an empty cache both compiled every kernel (two
    processes each, 323 s each on two busy cores, both exit 0).  The second now waits for
    the first (and says so), then finds the kernels cached and compiles nothing."""
    import threading

    from multilayer.app import precompile

    monkeypatch.setattr(kernel_cache, "cache_directories", lambda: [tmp_path])
    monkeypatch.setattr(kernel_cache, "ensure_fresh", lambda: None)
    compiled, waiting, reports = [], threading.Event(), []
    monkeypatch.setattr(
        precompile, "_compile", lambda processes: compiled.append(processes) or precompile.Report()
    )
    second = threading.Thread(target=lambda: reports.append(precompile.compile_kernels(None, waiting.set)))
    with kernel_cache.compiling(lambda: pytest.fail("nobody holds the lock yet")):
        second.start()
        assert waiting.wait(30)
        _index(tmp_path / "kernel.f-1.py311.nbi", f="kernel.f-1.py311.1.nbc")  # the first compiles
        kernel_cache.mark_compiled(kernel_cache.compiled_text(work()))
    second.join(30)
    assert compiled == [] and reports[0].cached and reports[0].checked == 1


def test_the_digest_covers_the_kernel_modules_of_every_engine_package():
    names = {path.relative_to(kernel_cache.ENGINE).as_posix() for path in kernel_cache.kernel_modules()}
    assert {
        "vertical/newton_kernel.py",
        "vertical/sheared_columns.py",
        "vertical/column_solve.py",
        "vertical/forms.py",
        "transport/kernel.py",
        "transport/boundaries.py",  # compiled into the transport kernel
        "pressure/non_hydrostatic/banded.py",
    } <= names


LAZY = """
import sys
from collections.abc import Iterator
from pathlib import Path
from multilayer.engine import kernel_cache
import multilayer.engine.simulation
from multilayer.engine.state import span
import numpy as np
directories = kernel_cache.cache_directories()
print(all(d.is_relative_to(sys.argv[1]) for d in directories), len(directories) >= 4)
print(any((d / kernel_cache.STAMP).exists() for d in directories))  # nothing at import
span(np.array([0.0, 1.0, 0.0]))  # the first kernel: checked, then compiled and cached
print(all((d / kernel_cache.STAMP).read_text() == kernel_cache.sources_digest() for d in directories))
"""


@pytest.mark.slow  # 1-3 s of a child process or a large input, no physics
def test_the_check_runs_before_the_first_kernel_not_at_import(tmp_path):
    """With ``NUMBA_CACHE_DIR`` (as on a cluster whose installation cannot be written),
    numba caches the kernels under it, one directory per engine package: their digests
    are written when the first kernel is loaded or compiled, not when the engine is
    imported."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    done = subprocess.run(
        [sys.executable, "-c", LAZY, str(tmp_path)], env=env, capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "False", "True"]


RACER = """
import sys, time
from collections.abc import Iterator
from pathlib import Path
go = Path(sys.argv[1])
import numpy as np
from multilayer.engine import kernel_cache
from multilayer.engine.state import max_wave_speed
Path(sys.argv[2]).touch()  # ready
while not go.exists():  # both processes start the check at once
    time.sleep(0.001)
speed = max_wave_speed(np.array([0.0, 4.0]), np.array([[0.0, -1.0], [0.5, 2.0]]), 1.0)
print(speed, len(kernel_cache.CLEARED))
"""


@pytest.mark.slow
def test_two_processes_starting_at_once_after_an_upgrade(tmp_path):
    """After an upgrade (the digests of other sources in the cache, and a kernel cached by
    them), two processes that load their first kernel at the same moment both run the new
    code: the cached kernels of the old sources are deleted once, by one of them, and the
    other keeps what the first compiles since; neither fails."""
    cache = tmp_path / "cache"
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    prepare = (
        "from multilayer.engine import kernel_cache\nfor d in kernel_cache.cache_directories():\n"
        "    d.mkdir(parents=True, exist_ok=True)\n"
        "    (d / kernel_cache.STAMP).write_text('an older version')\n"
        "    (d / 'state.max_wave_speed-1.py311.nbi').write_bytes(b'of the older version')\n"
        "print(len(kernel_cache.cache_directories()))\n"
    )
    directories = int(subprocess.run([sys.executable, "-c", prepare], env=env, capture_output=True, text=True,
                                     check=True).stdout)  # fmt: skip
    go, ready = tmp_path / "go", [tmp_path / "ready-1", tmp_path / "ready-2"]
    racers = [
        subprocess.Popen(
            [sys.executable, "-c", RACER, str(go), str(flag)], env=env, stdout=subprocess.PIPE, text=True
        )
        for flag in ready
    ]
    deadline = time.monotonic() + 120
    while not all(flag.exists() for flag in ready) and time.monotonic() < deadline:
        time.sleep(0.01)  # both have imported the engine and wait
    go.touch()
    results = [racer.communicate(timeout=300)[0].split() for racer in racers]
    assert [racer.returncode for racer in racers] == [0, 0]
    assert [float(speed) for speed, _ in results] == [4.0, 4.0]  # max |u| + sqrt(g h) = 2 + 2
    assert sum(int(cleared) for _, cleared in results) == directories  # each directory cleared once
    assert not list(cache.rglob("state.max_wave_speed-1.py311.nbi"))
    assert {path.read_text() for path in cache.rglob(kernel_cache.STAMP)} == {kernel_cache.sources_digest()}


CAPABILITIES = "-dac_override,-dac_read_search,-fowner"  # root then obeys the permission bits


@pytest.mark.skipif(os.geteuid() != 0 or not shutil.which("setpriv"), reason="drops root's capabilities")
def test_kernels_run_uncached_with_a_warning_where_numba_can_write_no_cache(tmp_path):
    """A read-only installation and home (no ``NUMBA_CACHE_DIR``): numba's ``cache=True``
    raised "no locator available" when the engine was imported, a traceback on every
    run.  The kernel is compiled in memory, gives its answer, and a warning says why."""
    package = tmp_path / "readonly"
    package.mkdir()
    (package / "kernels.py").write_text(
        "from multilayer.engine.compiled import jit\n\n@jit\ndef twice(x):\n    return 2.0 * x\n"
    )
    package.chmod(0o555)
    env = {**os.environ, "HOME": str(package), "XDG_CACHE_HOME": str(package), "PYTHONPATH": str(package)}
    env.pop("NUMBA_CACHE_DIR", None)
    code = "import kernels; print(kernels.twice(1.5), type(kernels.twice._cache).__name__)"
    child = subprocess.run(
        ["setpriv", f"--bounding-set={CAPABILITIES}", sys.executable, "-W", "always", "-c", code],
        env=env, capture_output=True, text=True, cwd=package, timeout=120,
    )  # fmt: skip
    assert child.returncode == 0, child.stderr
    assert child.stdout.split() == ["3.0", "NullCache"]
    assert "numba finds no directory it can write its cache to" in child.stderr
    assert "Traceback" not in child.stderr and [p.name for p in package.iterdir()] == ["kernels.py"]


@pytest.mark.parametrize("files", ["*.nbc", "*.nbi"])
def test_a_damaged_cache_entry_is_compiled_again_with_one_warning(tmp_path, monkeypatch, files):
    """numba unpickles its cached kernels (``.nbc``) and their index (``.nbi``): a truncated
    file (a full disk, a killed writer) was an UnpicklingError from deep inside numba on
    every run (a damaged index at the save after compiling).  Now a miss: the kernel is
    compiled again, gives its answer and its entry (or index) is written anew; one warning
    per cache directory."""
    with two_kernels(tmp_path, monkeypatch, "damaged_kernels") as module:
        _compiled_again(tmp_path, module, files)


@contextlib.contextmanager
def two_kernels(tmp_path, monkeypatch, name: str) -> Iterator[types.ModuleType]:
    """The module ``name`` of two cached kernels, ``twice`` and ``thrice``, written in
    ``tmp_path`` and imported (numba caches them in its ``__pycache__``), with none of the
    cache's warnings said yet in this process."""
    from multilayer.engine import compiled

    (tmp_path / f"{name}.py").write_text(
        "from multilayer.engine.compiled import jit\n\n\n@jit\ndef twice(x):\n    return 2.0 * x\n\n\n"
        "@jit\ndef thrice(x):\n    return 3.0 * x\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(compiled, "_warned", set())
    try:
        yield importlib.import_module(name)
    finally:
        sys.modules.pop(name, None)


def test_a_kernel_that_cannot_be_saved_runs_uncached_and_keeps_the_cached_ones(tmp_path, monkeypatch):
    """A save that fails for want of disk space was taken for a damaged index: the index was
    deleted, and with it every kernel of the module cached before.  Now the new kernel runs
    uncached with one warning naming the directory and the error, and the kernel cached
    before is loaded by the next import."""
    import errno

    from numba.core.caching import IndexDataCacheFile

    with two_kernels(tmp_path, monkeypatch, "full_disk_kernels") as module:
        assert module.twice(1.5) == 3.0  # compiled and cached

        def full(*args):
            raise OSError(errno.ENOSPC, "No space left on device")

        with monkeypatch.context() as patch:
            patch.setattr(IndexDataCacheFile, "save", full)
            with pytest.warns(
                UserWarning, match=r"numba's cache in .* cannot be written \(OSError: .*No space"
            ):
                assert module.thrice(1.5) == 4.5
        module = importlib.reload(module)
        assert module.twice(2.0) == 4.0
        assert sum(module.twice.stats.cache_hits.values()) == 1  # loaded, not compiled again


def _compiled_again(tmp_path, module, files) -> None:
    """The checks of :func:`test_a_damaged_cache_entry_is_compiled_again_with_one_warning` on
    the imported module of two kernels."""
    assert (module.twice(1.5), module.thrice(1.5)) == (3.0, 4.5)  # compiled and cached
    entries = sorted((tmp_path / "__pycache__").glob(files))
    assert len(entries) == 2
    for entry in entries:
        os.truncate(entry, entry.stat().st_size // 2)
    module = importlib.reload(module)
    with pytest.warns(UserWarning, match=r"numba's cache in .* holds kernels that cannot be read") as caught:
        assert (module.twice(1.5), module.thrice(1.5)) == (3.0, 4.5)
    assert len(caught) == 1 and "compiled again" in str(caught[0].message)
    module = importlib.reload(module)  # the entries were written again: loaded without a word
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert (module.twice(2.0), module.thrice(2.0)) == (4.0, 6.0)


EDITED = """
import sys, time
from collections.abc import Iterator
from pathlib import Path
engine = Path(sys.argv[1])
sys.path.insert(0, str(engine))
from multilayer.engine import kernel_cache
kernel_cache.ENGINE = engine
import caller
for command in sys.argv[2:]:
    if command == "edit":  # after the import, before the first kernel
        callee = engine / "callee.py"
        callee.write_text(callee.read_text().replace("1.0 * x", "2.0 * x"))
    elif command == "wait":
        print(flush=True)
        while not (engine / "go").exists():
            time.sleep(0.01)
    else:
        print(caller.g(float(command) if "." in command else int(command)), flush=True)
"""


def _kernel_modules(engine):
    """A caller kernel in one module and its callee in another, the callee's answer x."""
    engine.mkdir()
    jit = "from multilayer.engine.compiled import jit\n"
    (engine / "callee.py").write_text(jit + "\n\n@jit\ndef f(x):\n    return 1.0 * x\n")
    (engine / "caller.py").write_text(jit + "from callee import f\n\n\n@jit\ndef g(x):\n    return f(x)\n")


def _edited(engine, *commands, bytecode=False, **popen):
    env = {name: value for name, value in os.environ.items() if name != "PYTHONDONTWRITEBYTECODE"}
    if not bytecode:  # Python compiles the source it reads
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    argv = [sys.executable, "-c", EDITED, str(engine), *commands]
    if popen:
        return subprocess.Popen(argv, env=env, text=True, **popen)
    return subprocess.run(argv, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.slow  # 1-3 s of a child process or a large input, no physics
def test_a_callee_edited_after_the_import_leaves_no_old_code_in_the_cache(tmp_path):
    """A process that imported the kernel modules, then found one edited when it compiled
    its first kernel, cached its old code under the new sources' digest: every later run
    loaded the caller with the old callee compiled into it (1.0 after the callee said
    2.0).  Now that process caches nothing, says why, and the next run compiles the file."""
    engine = tmp_path / "engine"
    _kernel_modules(engine)
    during = _edited(engine, "edit", "1.0")
    assert during.returncode == 0, during.stderr
    assert during.stdout.split() == ["1.0"]  # the code it imported
    assert "callee.py is not the code this process runs" in during.stderr
    after = _edited(engine, "1.0")
    assert after.returncode == 0 and after.stdout.split() == ["2.0"], after.stderr


@pytest.mark.slow
def test_a_process_older_than_the_cache_neither_saves_nor_loads_its_kernels(tmp_path):
    """A process started before an edit checked the cache then, and compiled (and cached)
    kernels later: after a newer process had cleared the directory for the new sources,
    the old process's kernel was saved there and loaded by every later run (1.0 after the
    callee said 2).  A kernel is saved or loaded only where the digest is the process's."""
    engine = tmp_path / "engine"
    _kernel_modules(engine)
    old = _edited(engine, "1.0", "wait", "1", stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    assert old.stdout is not None and old.stdout.readline().strip() == "1.0"
    assert old.stdout.readline() == "\n"  # waiting, its cache checked
    callee = engine / "callee.py"
    callee.write_text(callee.read_text().replace("1.0 * x", "2.0 * x"))
    assert _edited(engine, "1.0").stdout.split() == ["2.0"]  # clears and caches the new kernels
    (engine / "go").touch()
    out, err = old.communicate(timeout=300)
    assert old.returncode == 0 and out.split() == ["1.0"], err  # its own code, compiled, not saved
    assert _edited(engine, "1").stdout.split() == ["2.0"]


@pytest.mark.parametrize("checked", [True, False])
def test_a_hash_checked_pyc_of_an_earlier_version_was_not_run(tmp_path, monkeypatch, checked):
    """Python checks a hash-checked ``.pyc`` against the source it reads and compiles the
    source where they differ: the first run after an update of the package (its pycs of
    the earlier version checked by hash) warned that its kernel module was not the code it
    ran and cached none of its kernels.  An unchecked hash pyc of other contents is run by
    Python: that is still caught.  Either stale pyc is removed (no bytecode written)."""
    import py_compile

    module = tmp_path / "kernels.py"
    module.write_text("x = 1\n")
    mode = py_compile.PycInvalidationMode
    pyc = Path(
        py_compile.compile(
            str(module), invalidation_mode=mode.CHECKED_HASH if checked else mode.UNCHECKED_HASH
        )
    )
    module.write_text("x = 2\n")
    monkeypatch.setattr(sys, "dont_write_bytecode", True)
    assert kernel_cache._bytecode_is_of(module, module.read_bytes()) is checked
    assert not pyc.exists()


@pytest.mark.slow
def test_bytecode_of_an_earlier_version_is_not_cached_and_compiled_anew(tmp_path):
    """Python runs a module's ``.pyc`` when its header holds the source's time (whole
    seconds) and size: a kernel module rewritten with both kept (a copy keeping the time,
    or an edit within the second) ran its old code, which was cached under the new
    sources' digest; after a touch, the caller still held the old callee (1.0, for
    ever).  Now that process caches nothing and the pyc is compiled anew."""
    import py_compile

    engine = tmp_path / "engine"
    _kernel_modules(engine)
    callee = engine / "callee.py"
    py_compile.compile(str(callee), invalidation_mode=py_compile.PycInvalidationMode.TIMESTAMP, doraise=True)
    stat = callee.stat()
    callee.write_text(callee.read_text().replace("1.0 * x", "2.0 * x"))  # the same size
    os.utime(callee, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    stale = _edited(engine, "1.0", bytecode=True)
    assert stale.returncode == 0 and stale.stdout.split() == ["1.0"], stale.stderr  # Python's choice
    assert "callee.py is not the code this process runs" in stale.stderr
    assert _edited(engine, "1.0", bytecode=True).stdout.split() == ["2.0"]
    callee.touch()
    assert _edited(engine, "1.0", bytecode=True).stdout.split() == ["2.0"]


def test_the_digest_and_the_mark_are_readable_by_the_other_users_of_a_shared_cache(tmp_path, monkeypatch):
    """The digest and the mark were written as temporary files, mode 0600: in a cache shared
    by a group (``NUMBA_CACHE_DIR``, an installation for several users) the others could not
    read the digest and their runs loaded no kernel.  They have the mode of numba's own cache
    files, 0666 less the umask, and no file of the writing is left beside them."""
    status = Path("/proc/self/status")
    if not status.is_file():
        pytest.skip("the umask is read from /proc")
    line = next(line for line in status.read_text().splitlines() if line.startswith("Umask"))
    umask = int(line.split()[1], 8)
    monkeypatch.setattr(kernel_cache, "cache_directories", lambda: [tmp_path])
    kernel_cache.clear_if_stale(tmp_path, "digest")
    _index(tmp_path / "kernel.f-1.py311.nbi")
    kernel_cache.mark_compiled(kernel_cache.compiled_text(work()))
    for name in (kernel_cache.STAMP, kernel_cache.COMPILED):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o666 & ~umask, name
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        [kernel_cache.STAMP, kernel_cache.COMPILED, kernel_cache.LOCK, "kernel.f-1.py311.nbi"]
    )
    assert kernel_cache.is_compiled(work())


def test_the_compiled_mark_is_of_its_optimisation_level(tmp_path, monkeypatch):
    """``PYTHONOPTIMIZE=2 multilayer compile`` found the mark of a compilation without
    ``-OO`` and said the kernels cached, though numba keys the kernels that call others on
    their callees' code, which ``-OO`` strips of docstrings (a run then compiled about
    twenty again): the mark records the optimisation level, so a mark of one level is not
    found current at another; the children of a compilation under ``-OO`` run under it."""
    monkeypatch.setattr(kernel_cache, "cache_directories", lambda: [tmp_path])
    _index(tmp_path / "kernel.f-1.py311.nbi")
    child = (
        "from multilayer.app import compilation, precompile\nfrom multilayer.engine import kernel_cache\n"
        "print(repr((kernel_cache.compiled_text(precompile.work()), compilation.interpreter()[1:])))"
    )
    done = subprocess.run([sys.executable, "-OO", "-c", child], capture_output=True, text=True, check=True)
    optimized, flags = eval(done.stdout)
    assert flags == ["-OO"] and optimized != kernel_cache.compiled_text(work())
    assert "optimize 2" in optimized and f"optimize {sys.flags.optimize}" in work()
    kernel_cache.mark_compiled(optimized)
    assert not kernel_cache.is_compiled(work())
    kernel_cache.mark_compiled(kernel_cache.compiled_text(work()))
    assert kernel_cache.is_compiled(work())
