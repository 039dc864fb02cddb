"""numba's cache of the kernels is cleared when a kernel source changes (engine/kernel_cache.py):
numba keys a cached function by its own file only, so a caller would keep a callee's old code."""

from __future__ import annotations

from multilayer.engine import kernel_cache


def test_a_changed_kernel_source_clears_the_cached_kernels_once(tmp_path, monkeypatch):
    engine, cache = tmp_path / "engine", tmp_path / "engine" / "__pycache__"
    cache.mkdir(parents=True)
    callee = engine / "callee.py"
    callee.write_text("from numba import njit\n")
    (engine / "plain.py").write_text("x = 1\n")  # not a kernel module: not part of the digest
    monkeypatch.setattr(kernel_cache, "ENGINE", engine)
    monkeypatch.setattr(kernel_cache, "CACHE", cache)
    monkeypatch.setattr(kernel_cache, "STAMP", cache / "kernels.digest")

    def cached(*names):
        for name in names:
            (cache / name).write_bytes(b"compiled")

    assert kernel_cache.clear_if_stale()  # no digest yet: whatever is cached is of unknown sources
    cached("caller._chunk-1.py311.nbi", "caller._chunk-1.py311.1.nbc")
    assert not kernel_cache.clear_if_stale()  # unchanged sources: the cache is kept
    assert len(list(cache.glob("*.nb?"))) == 2
    (engine / "plain.py").write_text("x = 2\n")
    assert not kernel_cache.clear_if_stale()
    callee.write_text("from numba import njit  # edited\n")  # the callee alone changes
    assert kernel_cache.clear_if_stale()
    assert list(cache.glob("*.nb?")) == [] and (cache / "kernels.digest").is_file()
    assert not kernel_cache.clear_if_stale()


def test_the_digest_covers_the_engine_kernel_modules():
    names = {path.name for path in kernel_cache.ENGINE.glob("*.py") if b"numba" in path.read_bytes()}
    assert {"newton_kernel.py", "sheared_columns.py", "column_kernel.py", "viscous_law.py"} <= names
    assert kernel_cache.STAMP.read_text() == kernel_cache.sources_digest()  # written on import
