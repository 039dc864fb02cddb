"""numba's on-disk cache of the engine's kernels, kept consistent with their sources.

numba caches a compiled function in a directory of its choice and keys it by the
contents of that function's module file only.  A kernel that calls a kernel of another
module (``newton_kernel`` calls ``sheared_columns``, ``column_kernel``,
``newton_control``, ``viscous_law``, ``stress_kernel``) holds the callee's code in its
own cache entry, so an edit of the callee alone, a ``git pull`` into an editable
installation or an upgrade that changes it alone would leave the caller running the old
code.  :func:`clear_if_stale` compares a digest of the kernel sources (the engine's
modules that use numba) with the one stored in the cache directory and deletes the
engine's cached kernels when they differ: every kernel is then compiled again on its
first use.

The directory is the one numba chooses for the engine's modules: ``__pycache__`` beside
them when it can be written and ``NUMBA_CACHE_DIR`` is not set; otherwise numba's own
cache locators say where (a subdirectory of ``NUMBA_CACHE_DIR``, or of the user's cache
directory for an installation without write access), at the cost of importing numba
(about 0.25 s) when the engine is imported.
"""

from __future__ import annotations

import hashlib
import os
import tempfile
from pathlib import Path

ENGINE = Path(__file__).parent
IN_TREE = ENGINE / "__pycache__"
STAMP = "kernels.digest"
"""The digest's file name, in the cache directory."""


def sources_digest() -> str:
    """SHA-256 of the engine's modules that use numba, in name order."""
    digest = hashlib.sha256()
    for path in sorted(ENGINE.glob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            digest.update(path.name.encode() + b"\0" + text)
    return digest.hexdigest()


def _writable(directory: Path) -> bool:
    """Whether numba's in-tree locator would cache in ``directory`` (it creates the
    directory and a temporary file in it)."""
    try:
        directory.mkdir(exist_ok=True)
        tempfile.TemporaryFile(dir=directory).close()
    except OSError:
        return False
    return True


def cache_directory() -> Path | None:
    """The directory numba caches the engine's kernels in; None where it cannot cache.

    Without ``NUMBA_CACHE_DIR`` and ``NUMBA_CACHE_LOCATOR_CLASSES`` in the environment,
    nor a ``.numba_config.yaml`` in the working directory (numba reads its settings from
    it), numba caches in a writable ``__pycache__`` beside the module first, and that is
    found without importing numba.  Otherwise numba's ``FunctionCache`` is asked for a
    function of the engine's directory (its locators place every module of a directory
    in the same directory)."""
    configured = (
        os.environ.get("NUMBA_CACHE_DIR")
        or os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES")
        or Path(".numba_config.yaml").exists()
    )
    if not configured and _writable(IN_TREE):
        return IN_TREE
    from numba.core.caching import FunctionCache

    try:
        return Path(FunctionCache(sources_digest).cache_path)
    except RuntimeError:  # no locator: numba caches nothing
        return None


def clear_if_stale(directory: Path | None = None) -> bool:
    """Delete the engine's cached kernels in ``directory`` (by default
    :func:`cache_directory`) if the kernel sources changed since they were cached (True
    if it did).  Where the directory cannot be written, nothing is done."""
    cache = directory if directory is not None else cache_directory()
    if cache is None:
        return False
    stamp = cache / STAMP
    try:
        current = sources_digest()
        if stamp.is_file() and stamp.read_text() == current:
            return False
        cache.mkdir(parents=True, exist_ok=True)
        for entry in [*cache.glob("*.nbi"), *cache.glob("*.nbc")]:
            entry.unlink(missing_ok=True)
        stamp.write_text(current)
    except OSError:
        return False
    return True
