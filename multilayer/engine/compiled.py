"""How the engine compiles its kernels: numba's ``njit``, cached on disk, the cache checked
against the kernel sources before its first use (:mod:`multilayer.engine.kernel_cache`).

Every kernel of the engine is decorated with :func:`jit` (or made parallel by
:func:`parallel_compiled`): numba's ``njit(cache=True, **options)``, whose on-disk cache
first runs :func:`kernel_cache.ensure_fresh` (once per process) before it loads or saves a
compiled kernel.  Nothing is compiled, loaded or checked when the engine is imported.
"""

from __future__ import annotations

import contextlib
import functools
import types
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
from numba.core.caching import FunctionCache

from multilayer.engine import kernel_cache


class _CheckedCache(FunctionCache):
    """numba's on-disk cache of one kernel, made consistent with the kernel sources
    (:func:`kernel_cache.ensure_fresh`) before the first kernel of the process is loaded
    or saved; a kernel of the engine is loaded or saved only while its directory holds
    the kernels of the sources this process compiles (:func:`kernel_cache.current`).  An
    entry that cannot be read (a truncated or damaged file: numba raised the unpickling
    error) is a miss: the kernel is compiled again and the entry rewritten (a damaged index
    anew), with a warning.  A kernel that cannot be saved (the disk full, the directory made
    read-only since it was chosen) runs uncached, with a warning, and the entries already
    cached are kept (the index was deleted as if damaged: every kernel of the module was
    compiled again by the next run)."""

    def __init__(self, py_func: Callable) -> None:
        super().__init__(py_func)
        self._engine = kernel_cache.defined(Path(py_func.__code__.co_filename))

    def _current(self) -> contextlib.AbstractContextManager[bool]:
        """:func:`kernel_cache.current` of this kernel's directory (True outside the engine)."""
        if self._engine:
            return kernel_cache.current(Path(self._cache_path))
        kernel_cache.ensure_fresh()
        return contextlib.nullcontext(True)

    def load_overload(self, sig: Any, target_context: Any) -> Any:
        with self._current() as current:
            if not current:
                return None
            try:
                return super().load_overload(sig, target_context)
            except Exception as exc:  # pickle, zlib, EOF, attribute errors of a damaged entry
                _warn_cache(
                    self._cache_path, "damaged", f"{self._py_func.__qualname__}: {type(exc).__name__}: {exc}"
                )
                return None

    def save_overload(self, sig: Any, data: Any) -> None:
        with self._current() as current:
            if not current:
                return
            try:
                super().save_overload(sig, data)
            except OSError as exc:  # a full disk, a directory made read-only: the cache is left as it is
                _warn_cache(self._cache_path, "unsaved", f"{type(exc).__name__}: {exc}")
            except Exception as exc:  # its index cannot be read: written anew, without the old entries
                _warn_cache(
                    self._cache_path, "damaged", f"{self._py_func.__qualname__}: {type(exc).__name__}: {exc}"
                )
                with contextlib.suppress(Exception):  # the kernel is compiled: it runs uncached otherwise
                    Path(self._cache_file._index_path).unlink(missing_ok=True)
                    super().save_overload(sig, data)


def _checked(dispatcher: Any) -> Any:
    """``dispatcher`` with its on-disk cache enabled as ``cache=True`` would (numba's
    ``Dispatcher.enable_caching``), through :class:`_CheckedCache`; without it where numba
    finds no directory it can write (a read-only installation, no writable home nor
    ``NUMBA_CACHE_DIR``: ``cache=True`` raises there), with a warning: the kernels are then
    compiled in memory by every process."""
    try:
        dispatcher._cache = _CheckedCache(dispatcher.py_func)
    except RuntimeError:  # numba: "cannot cache function ...: no locator available"
        _warn_uncached()
    return dispatcher


_warned: set[tuple[str, str]] = set()
"""The (cache directory, fault) pairs :func:`_warn_cache` has warned about."""

_FAULTS = {
    "damaged": "holds kernels that cannot be read (the first: {}); they are compiled again",
    "unsaved": "cannot be written ({}): the kernels compiled now are not cached, and the next run "
    "compiles them again",
}
"""What :func:`_warn_cache` says of each fault of a cache directory."""


def _warn_cache(directory: str, fault: str, detail: str) -> None:
    """Say once per cache directory and ``fault`` (a key of :data:`_FAULTS`) what is wrong."""
    if (directory, fault) in _warned:
        return
    _warned.add((directory, fault))
    warnings.warn(f"numba's cache in {directory} " + _FAULTS[fault].format(detail), stacklevel=3)


@functools.cache
def _warn_uncached() -> None:
    """Say once per process that the kernels are not cached."""
    warnings.warn(
        "numba finds no directory it can write its cache to (beside the engine's modules, "
        "NUMBA_CACHE_DIR, the user's cache directory): the kernels are compiled in memory by "
        "every run (about a minute); set NUMBA_CACHE_DIR to a writable directory",
        stacklevel=2,
    )


def jit(function: Callable | None = None, *, borrowing: bool = False, **options: Any) -> Any:
    """``numba.njit(cache=True, **options)``, the cache checked before its first use:
    ``@jit`` or ``@jit(inline="always", ...)``.

    ``borrowing``: a kernel that neither allocates nor returns an array, compiled without
    numba's reference counting (its ``_nrt=False``, as numba's own string helpers), so that it
    borrows the arrays it is given from its caller, which holds them for the call.  numba
    counts a reference to every array argument at a function's entry and releases it at
    each exit, two atomic operations per array and call, and its pruning of these pairs
    (llvmlite's RefPrune) gives up on a function whose control flow between entry and exit
    runs through more than 15 blocks (a loop with branches): most kernels.  numba's own
    inlining (``inline="always"``) lowers a callee in its caller, reference counts
    included: a borrowing kernel is compiled on its own (LLVM may still inline it).  An
    allocation in a borrowing kernel is a compilation error."""
    if borrowing:
        options["_nrt"] = False
    if function is None:
        return lambda f: _checked(numba.njit(**options)(f))
    return _checked(numba.njit(**options)(function))


def parallel_compiled(function: Callable, **options: Any) -> Any:
    """:func:`jit` with ``parallel=True`` of ``function``, compiled and cached apart from
    its serial compilation.

    numba's on-disk cache names a compilation by the function's qualified name and first
    line and keys it by its signature only: a serial and a parallel compilation of one
    function shared one entry, and whichever had been compiled last was loaded for both
    (the parallel kernels ran the serial code).  The parallel one is compiled from a copy
    of the function named ``<name>_parallel``."""
    name = f"{function.__name__}_parallel"
    qualname = f"{function.__qualname__}_parallel"
    code = function.__code__.replace(co_name=name, co_qualname=qualname)
    copy = types.FunctionType(code, function.__globals__, name, function.__defaults__, function.__closure__)
    copy.__qualname__, copy.__doc__, copy.__module__ = qualname, function.__doc__, function.__module__
    return jit(copy, parallel=True, **options)
