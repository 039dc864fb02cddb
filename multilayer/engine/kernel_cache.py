"""numba's on-disk cache of the engine's kernels, kept consistent with their sources.

numba caches a compiled function next to its module (``__pycache__/*.nbi``, ``*.nbc``)
and keys it by that module's file only.  A kernel that calls a kernel of another module
(``newton_kernel`` calls ``sheared_columns``, ``column_kernel``, ``newton_control``,
``viscous_law``, ``stress_kernel``) holds the callee's code in its own cache entry, so an
edit of the callee alone, or a ``git pull`` into an editable installation that changes
it alone, would leave the caller running the old code.  :func:`clear_if_stale` compares
a digest of the kernel sources (the engine's modules that use numba) with the one stored
beside the cache and deletes the engine's cached kernels when they differ: every kernel
is then compiled again on its first use.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

ENGINE = Path(__file__).parent
CACHE = ENGINE / "__pycache__"
STAMP = CACHE / "kernels.digest"


def sources_digest() -> str:
    """SHA-256 of the engine's modules that use numba, in name order."""
    digest = hashlib.sha256()
    for path in sorted(ENGINE.glob("*.py")):
        text = path.read_bytes()
        if b"numba" in text:
            digest.update(path.name.encode() + b"\0" + text)
    return digest.hexdigest()


def clear_if_stale() -> bool:
    """Delete the engine's cached kernels if the kernel sources changed since they were
    cached (True if it did).  Where the cache directory cannot be written (an installation
    without write access: numba then caches elsewhere, and an upgrade rewrites every
    file), nothing is done."""
    try:
        current = sources_digest()
        if STAMP.is_file() and STAMP.read_text() == current:
            return False
        CACHE.mkdir(exist_ok=True)
        for entry in [*CACHE.glob("*.nbi"), *CACHE.glob("*.nbc")]:
            entry.unlink(missing_ok=True)
        STAMP.write_text(current)
    except OSError:
        return False
    return True
