"""numba's cache of the kernels is cleared when a kernel source changes (engine/kernel_cache.py):
numba keys a cached function by its own file only, so a caller would keep a callee's old code."""

from __future__ import annotations

import os
import subprocess
import sys

from multilayer.engine import kernel_cache


def test_a_changed_kernel_source_clears_the_cached_kernels_once(tmp_path, monkeypatch):
    engine, cache = tmp_path / "engine", tmp_path / "engine" / "__pycache__"
    cache.mkdir(parents=True)
    callee = engine / "callee.py"
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
    callee.write_text("from numba import njit  # edited\n")  # the callee alone changes
    assert kernel_cache.clear_if_stale(cache)
    assert list(cache.glob("*.nb?")) == [] and (cache / "kernels.digest").is_file()
    assert not kernel_cache.clear_if_stale(cache)


def test_the_digest_covers_the_engine_kernel_modules():
    names = {path.name for path in kernel_cache.ENGINE.glob("*.py") if b"numba" in path.read_bytes()}
    assert {"newton_kernel.py", "sheared_columns.py", "column_kernel.py", "viscous_law.py"} <= names
    stamp = kernel_cache.cache_directory() / kernel_cache.STAMP
    assert stamp.read_text() == kernel_cache.sources_digest()  # written on import


CHECK_ELSEWHERE = """
from pathlib import Path
from numba.core.caching import FunctionCache
from multilayer.engine import kernel_cache, viscous_law  # the import writes the digest
cache = kernel_cache.cache_directory()
kernel = Path(FunctionCache(viscous_law._viscosity_and_slope.py_func).cache_path)
print(cache, kernel, (cache / kernel_cache.STAMP).is_file())
entry = cache / "newton_kernel._chunk-110.py311.nbi"
entry.write_bytes(b"compiled")
print(kernel_cache.clear_if_stale(), entry.exists())  # the same sources: kept
(cache / kernel_cache.STAMP).write_text("the digest of other sources")
print(kernel_cache.clear_if_stale(), entry.exists())  # other sources: deleted
"""


def test_a_cache_outside_the_package_is_the_one_kept_consistent(tmp_path):
    """With ``NUMBA_CACHE_DIR`` (as on a cluster whose installation cannot be written),
    numba caches the kernels under it: the digest is kept there (written on import), and
    a kernel cached there is kept while the sources are the same, deleted once they
    differ."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    done = subprocess.run([sys.executable, "-c", CHECK_ELSEWHERE], env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    cache, kernel, stamped, *cleared = done.stdout.split()
    assert cache == kernel and cache.startswith(str(tmp_path)) and stamped == "True"
    assert cleared == ["False", "True", "True", "False"]
