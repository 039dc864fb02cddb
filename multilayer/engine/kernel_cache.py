"""numba's on-disk cache of the engine's kernels, kept consistent with their sources.

numba caches a compiled function in a directory of its choice and keys it by the
contents of that function's module file only.  A kernel that calls a kernel of another
module (the fused Newton step calls the column solve, the compiled forms, the Newton
control, ...) holds the callee's code in its own cache entry, so an edit of the callee
alone, a ``git pull`` into an editable installation or an upgrade that changes it alone
would leave the caller running the old code.  :func:`ensure_fresh` compares a digest of
the kernel sources (the engine's modules that use numba) with the one stored in each
cache directory and deletes the engine's cached kernels there when they differ: every
kernel is then compiled again on its first use.

It runs once per process, lazily: the engine's kernels are compiled through
:func:`multilayer.engine.compiled.jit`, whose cache calls it before the first kernel is
loaded or saved; importing the engine does nothing.  Two processes starting at once after
an upgrade take turns (a lock file in each directory, where ``fcntl`` exists): the first
deletes the old kernels and writes the new digest (written whole, by renaming), the second
then finds the digest current and keeps what the first has compiled since.

The digest must be that of the code the process compiles, which Python read when it
imported each module.  A module whose file changes between its import and the check
(an edit, a ``git checkout`` or a reinstallation while a process runs) would otherwise
have its old code cached under the new sources' digest, and every later process would
load it: the caller of an edited callee kept the old callee.  Each kernel module's file
is therefore digested when its kernels are defined (:func:`defined`, at its import); a
file that differs at the check, or a module imported after the check whose file differs
from the digest, means this process caches nothing (one warning naming the file).  Every
load and save of a kernel holds the directory's lock and needs its digest to be the
process's (:func:`current`): a process that started before an upgrade neither loads the
new kernels nor saves its old ones into a directory a newer process has cleared.
``multilayer compile`` marks the directories compiled for the digest, numba's version and
the work it did once it has cached its kernels (:func:`mark_compiled`, :func:`is_compiled`).

The directories are the ones numba chooses for the engine's modules: ``__pycache__``
beside them when it can be written and ``NUMBA_CACHE_DIR`` is not set; otherwise numba's
own cache locators say where (under ``NUMBA_CACHE_DIR``, or the user's cache directory for
an installation without write access).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
import threading
import types
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # not on POSIX: no lock (a concurrent start may compile a kernel twice)
    fcntl = None  # type: ignore[assignment]

ENGINE = Path(__file__).parent
STAMP = "kernels.digest"
"""The digest's file name, in each cache directory."""
LOCK = "kernels.lock"
"""The lock file's name, in each cache directory."""
COMPILING = "kernels.compiling"
"""The lock file of ``multilayer compile`` (:func:`compiling`), in the first cache directory."""
COMPILED = "kernels.compiled"
"""The name of the file, in each cache directory, that says every kernel of
``multilayer compile`` is cached (:func:`mark_compiled`)."""

_checked = False
_lock = threading.Lock()
CLEARED: list[Path] = []
"""The cache directories this process found stale and cleared."""
_defined: dict[Path, str] = {}
"""SHA-256 of each kernel module's file when its kernels were defined (:func:`defined`)."""
_sources: dict[Path, str] = {}
"""SHA-256 of each kernel module's file at the check (:func:`ensure_fresh`)."""
_digest: str | None = None
"""The digest of the kernel sources this process compiles, once checked; None: not
checked yet, or the files are not the code this process runs (nothing is cached)."""


MARKERS = (b"numba", b"multilayer.engine.compiled")
"""A module whose text names one of these holds kernels (or code compiled into them)."""


def kernel_modules() -> list[Path]:
    """The engine's modules that use numba (:data:`MARKERS`), in path order."""
    return [path for path in sorted(ENGINE.rglob("*.py")) if any(m in path.read_bytes() for m in MARKERS)]


def _module_digests() -> dict[Path, str]:
    """SHA-256 of each of :func:`kernel_modules`."""
    return {path: hashlib.sha256(path.read_bytes()).hexdigest() for path in kernel_modules()}


def _combined(digests: dict[Path, str]) -> str:
    """One digest of the modules' digests, with their paths in the engine."""
    digest = hashlib.sha256()
    for path, module in digests.items():
        digest.update(path.relative_to(ENGINE).as_posix().encode() + b"\0" + module.encode())
    return digest.hexdigest()


def sources_digest() -> str:
    """SHA-256 of the engine's modules that use numba, with their paths in the engine."""
    return _combined(_module_digests())


def _writable(directory: Path) -> bool:
    """Whether numba's in-tree locator would cache in ``directory`` (it creates the
    directory and a temporary file in it)."""
    try:
        directory.mkdir(exist_ok=True)
        tempfile.TemporaryFile(dir=directory).close()
    except OSError:
        return False
    return True


def _numba_cache_path(module: Path) -> Path | None:
    """Where numba's cache locators put the kernels of ``module`` (None: nowhere): asked
    of numba's ``FunctionCache`` for a function of that file."""
    from numba.core.caching import FunctionCache

    def probe() -> None:
        return None

    function = types.FunctionType(probe.__code__.replace(co_filename=str(module)), {})
    try:
        return Path(FunctionCache(function).cache_path)
    except RuntimeError:  # no locator: numba caches nothing
        return None


def cache_directories() -> list[Path]:
    """The directories numba caches the engine's kernels in, one per directory of kernel
    modules (none where it cannot cache).

    Without ``NUMBA_CACHE_DIR`` and ``NUMBA_CACHE_LOCATOR_CLASSES`` in the environment,
    nor a ``.numba_config.yaml`` in the working directory (numba reads its settings from
    it), numba caches in a writable ``__pycache__`` beside the module first, found without
    asking numba.  Otherwise numba's ``FunctionCache`` is asked for a function of each
    directory (its locators place every module of a directory in the same directory)."""
    configured = (
        os.environ.get("NUMBA_CACHE_DIR")
        or os.environ.get("NUMBA_CACHE_LOCATOR_CLASSES")
        or Path(".numba_config.yaml").exists()
    )
    found: list[Path] = []
    for module in {path.parent: path for path in kernel_modules()}.values():
        in_tree = module.parent / "__pycache__"
        directory = in_tree if not configured and _writable(in_tree) else _numba_cache_path(module)
        if directory is not None and directory not in found:
            found.append(directory)
    return found


@contextlib.contextmanager
def _locked(directory: Path, name: str = LOCK, on_wait: Callable[[], None] | None = None) -> Iterator[None]:
    """Hold the lock file ``name`` of ``directory`` (other processes taking it wait;
    ``on_wait`` is called first when one holds it)."""
    if fcntl is None:
        yield
        return
    with open(directory / name, "a") as handle:
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            if on_wait is not None:
                on_wait()
            fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)


@contextlib.contextmanager
def compiling(on_wait: Callable[[], None]) -> Iterator[None]:
    """Hold the lock of ``multilayer compile`` (:data:`COMPILING` in the first cache
    directory; nothing where numba caches nothing): two at once, the second waits for the
    first (``on_wait`` says so), then finds its kernels cached instead of compiling them
    again.  A process that dies releases it."""
    directories = cache_directories()
    with contextlib.ExitStack() as stack:
        if directories:
            with contextlib.suppress(OSError):  # numba cannot cache there either: unlocked
                directories[0].mkdir(parents=True, exist_ok=True)
                stack.enter_context(_locked(directories[0], COMPILING, on_wait))
        yield


def _write_whole(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` whole, by renaming a new file over it, with the mode of
    numba's own cache files (0666 less the umask): a temporary file's 0600 left the digest
    and the mark unreadable to the other users of a shared cache, whose runs then loaded no
    kernel and compiled every one in memory."""
    new = path.with_name(f"{path.name}.{os.getpid()}.{threading.get_ident()}.new")
    try:
        new.unlink(missing_ok=True)  # left by a process of this id that died; never followed
        descriptor = os.open(new, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        with open(descriptor, "w", encoding="utf-8") as stream:
            stream.write(text)
        os.replace(new, path)
    except OSError:
        new.unlink(missing_ok=True)
        raise


def clear_if_stale(directory: Path, digest: str | None = None) -> bool:
    """Delete the engine's cached kernels in ``directory`` if the kernel sources (their
    ``digest``, by default :func:`sources_digest`) changed since they were cached (True if
    they did).  Where the directory cannot be written, nothing is done."""
    current = sources_digest() if digest is None else digest
    stamp = directory / STAMP
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with _locked(directory):
            if stamp.is_file() and stamp.read_text() == current:
                return False
            for entry in [*directory.glob("*.nbi"), *directory.glob("*.nbc"), directory / COMPILED]:
                entry.unlink(missing_ok=True)
            _write_whole(stamp, current)  # a reader sees the old digest or the new one, never a part
    except OSError:
        return False
    return True


def _changed_since_import(path: Path) -> None:
    """Cache nothing more in this process: ``path``, a kernel module it imported, is not
    the file it ran (one warning)."""
    global _digest
    _digest = None
    warnings.warn(
        f"{path} is not the code this process runs (the file changed after it was imported, or "
        "Python ran the bytecode of an earlier version of it): its kernels are compiled and not "
        "cached (the next run compiles the file)",
        stacklevel=2,
    )


def _bytecode_is_of(module: Path, source: bytes) -> bool:
    """Whether the bytecode Python keeps for ``module`` (its ``.pyc``), if Python ran it,
    is that of ``source``; rewritten as a pyc Python checks against the source's hash.  A
    hash-checked pyc of earlier contents was not run (Python compiled the source it read):
    True, the stale pyc written anew or removed as below.

    Python runs a ``.pyc`` whose header holds the source's modification time, in whole
    seconds, and size: a file rewritten with the same size within the same second, or
    copied with its time kept (``cp -p``, ``rsync -t``, an archive), ran its previous
    code, in every process until the file was touched.  Such a pyc is compiled anew (as
    a hash-checked pyc, which Python then validates by the source's contents itself: the
    cost of this comparison is paid once) and False returned.  Where it cannot be
    written (a read-only installation, ``PYTHONDONTWRITEBYTECODE``: a stale one is
    removed), the comparison is made by every process (about 3 ms a module)."""
    import importlib.util
    import marshal
    import py_compile
    import sys

    try:
        cached = Path(importlib.util.cache_from_source(str(module)))
        header = cached.read_bytes()
        stat = module.stat()
    except (OSError, NotImplementedError, ValueError):  # no bytecode: Python compiled the source
        return True
    if header[:4] != importlib.util.MAGIC_NUMBER or len(header) < 16:  # Python ignores it
        return True
    flags = int.from_bytes(header[4:8], "little")
    if flags & 1:  # hash-based: Python checked it against the source it read (flag 2) or not
        of_source = header[8:16] == importlib.util.source_hash(source)
        if of_source and flags & 2:
            return True
        ran_source = bool(flags & 2)  # checked and not the source's: Python compiled the source
    elif header[8:16] != (int(stat.st_mtime) & 0xFFFFFFFF).to_bytes(4, "little") + (
        stat.st_size & 0xFFFFFFFF
    ).to_bytes(4, "little"):
        return True  # Python did not run it: the header is not the file's
    else:
        try:
            of_source = marshal.loads(header[16:]) == compile(source, str(module), "exec", dont_inherit=True)
        except (ValueError, EOFError, TypeError, SyntaxError):
            of_source = False
        ran_source = of_source
    with contextlib.suppress(OSError, py_compile.PyCompileError):
        if not sys.dont_write_bytecode:
            py_compile.compile(
                str(module),
                cfile=str(cached),
                doraise=True,
                invalidation_mode=py_compile.PycInvalidationMode.CHECKED_HASH,
            )
        elif not of_source:  # removed: the next process compiles the source
            cached.unlink()
    return ran_source


def defined(module: Path) -> bool:
    """Record the file of a module whose kernels are being defined (its import), the first
    time; True if it is one of the engine's modules (whose cache :func:`current` checks).
    Code that is not the file's (Python ran a ``.pyc`` of its previous contents,
    :func:`_bytecode_is_of`) stops the caching, and so does, imported after the check, a
    file that is not the one digested then (changed since)."""
    module = Path(module)
    if not module.is_relative_to(ENGINE):
        return False
    with _lock:
        if module not in _defined:
            try:
                source = module.read_bytes()
                _defined[module] = hashlib.sha256(source).hexdigest()
                ran_source = _bytecode_is_of(module, source)
            except OSError:
                _defined[module], ran_source = "", True
            if not ran_source:
                _defined[module] = "the bytecode of an earlier version"
            if _checked and _digest is not None and _sources.get(module) != _defined[module]:
                _changed_since_import(module)
    return True


def ensure_fresh() -> None:
    """:func:`clear_if_stale` in every cache directory of the engine's kernels, once per
    process (called before the first kernel is loaded or compiled), unless a kernel module
    this process imported has changed since (then nothing is cached)."""
    global _checked, _digest
    if _checked:
        return
    with _lock:
        if not _checked:
            _sources.update(_module_digests())
            changed = [path for path, digest in _defined.items() if _sources.get(path) != digest]
            if changed:
                _changed_since_import(changed[0])
            else:
                _digest = _combined(_sources)
                for directory in cache_directories():
                    if clear_if_stale(directory, _digest):
                        CLEARED.append(directory)
            _checked = True


def caching() -> bool:
    """Whether this process saves the kernels it compiles into numba's cache (after
    :func:`ensure_fresh`): False once a kernel module it imported is found not to be the
    code it runs (:func:`_changed_since_import`)."""
    ensure_fresh()
    return _digest is not None


@contextlib.contextmanager
def current(directory: Path) -> Iterator[bool]:
    """Hold the lock of the cache ``directory`` (after :func:`ensure_fresh`); yields whether
    its kernels are those of the sources this process compiles (its digest file holds the
    process's digest): a kernel is loaded from it or saved into it only then."""
    ensure_fresh()
    with contextlib.ExitStack() as stack:
        fresh = False
        if _digest is not None:
            try:
                stack.enter_context(_locked(directory))
                fresh = (directory / STAMP).read_text() == _digest
            except (OSError, UnicodeDecodeError):
                fresh = False
        yield fresh


def compiled_text(work: str) -> str:
    """What :data:`COMPILED` holds: the kernel sources' digest, numba's version (numba
    drops its cache when its version changes) and ``work``, the caller's name for what it
    compiled (a compilation of more kernels than the ones marked is not done)."""
    import numba

    return f"{sources_digest()}\nnumba {numba.__version__}\ntasks {work}\n"


def _file_digest(path: Path) -> str | None:
    """SHA-256 of the regular file ``path`` (None: missing, not a regular file, unreadable)."""
    try:
        if not path.is_file():  # a pipe or a device would be read for ever
            return None
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def _index_entries(path: Path) -> set[str] | None:
    """The entries of numba's index file ``path``, read as numba reads it (its version
    pickled, then its source stamp and its signatures' kernel files): each the SHA-256 of
    the stamp, a signature and its file; None where numba would find no entry (missing,
    unreadable, damaged, of another numba)."""
    import pickle

    import numba

    try:
        if not path.is_file():
            return None
        with path.open("rb") as f:
            if pickle.load(f) != numba.__version__:
                return None
            stamp, overloads = pickle.loads(f.read())
        return {
            hashlib.sha256(repr((stamp, key, name)).encode()).hexdigest() for key, name in overloads.items()
        }
    except Exception:  # noqa: BLE001 - whatever a damaged file makes pickle raise: no entry numba reads
        return None


def _listing(path: Path) -> str | None:
    """The mark's line of the cached file ``path``: a kernel (``.nbc``) by its SHA-256, an
    index (``.nbi``) by its entries (:func:`_index_entries`), since a later run that caches
    another signature of a module adds one to its index and leaves the others as they are."""
    if path.suffix == ".nbi":
        entries = _index_entries(path)
        return None if entries is None else f"index {path.name} {' '.join(sorted(entries))}\n"
    digest = _file_digest(path)
    return None if digest is None else f"{digest} {path.name}\n"


def _unchanged(directory: Path, line: str) -> bool:
    """Whether the file a line of the mark records (:func:`_listing`) is as recorded: a
    kernel with the same digest, an index still holding every entry recorded."""
    if line.startswith("index "):
        name, _, recorded = line[len("index ") :].partition(" ")
        entries = _index_entries(directory / name) if name == Path(name).name else None
        return entries is not None and set(recorded.split()) <= entries
    digest, _, name = line.partition(" ")
    return name == Path(name).name and _file_digest(directory / name) == digest


def mark_compiled(text: str) -> None:
    """Record in every cache directory that the kernels of ``multilayer compile`` are
    cached for the sources and numba of ``text`` (:func:`compiled_text` when the
    compilation started), with each cached file there (:func:`_listing`: a kernel's
    SHA-256, an index's entries), written whole, by renaming."""
    for directory in cache_directories():
        try:
            files = sorted([*directory.glob("*.nbi"), *directory.glob("*.nbc")])
            listing = "".join(line for path in files if (line := _listing(path)))
            _write_whole(directory / COMPILED, text + listing)
        except OSError:  # numba cannot cache there either
            pass


def compiled_files(work: str) -> int | None:
    """How many cached files :func:`mark_compiled` recorded in every cache directory, each
    found as recorded (:func:`_unchanged`: a kernel unchanged, an index that holds every
    signature it held, and maybe more), for the current sources, numba and ``work``
    (:func:`compiled_text`); None when a directory has no such mark (numba cannot cache,
    a mark holds anything else, bytes that are not text or no file included) or a
    recorded file is missing or changed since (a damaged cache: numba compiles that
    kernel again on its next use)."""
    text = compiled_text(work).encode()
    directories = cache_directories()
    checked = 0
    for directory in directories:
        try:
            mark = (directory / COMPILED).read_bytes()
            lines = mark[len(text) :].decode("utf-8").splitlines() if mark.startswith(text) else None
        except (OSError, UnicodeDecodeError):
            return None
        if not lines:  # what multilayer compile leaves lists its kernels
            return None
        if not all(_unchanged(directory, line) for line in lines):
            return None
        checked += len(lines)
    return checked if directories else None


def is_compiled(work: str) -> bool:
    """Whether :func:`mark_compiled` recorded the current sources, numba and ``work`` in
    every cache directory and the files it recorded are unchanged (:func:`compiled_files`)."""
    return compiled_files(work) is not None
