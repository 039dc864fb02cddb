"""Where a result comes from: the package version and the git commit of its source.

The version is the installed distribution's, set from git by setuptools-scm when the
package was installed (``X.Y.Z`` at a tag ``vX.Y.Z``, ``X.Y.(Z+1).devN+gHASH`` after it;
``0.1.0`` when installed from sources without git metadata).  Since an editable install
keeps the version of the moment it was installed, the commit is read from git when the
result is written: the exact commit of the source tree that ran, and whether tracked
files differed from it (``dirty``).  Without git (an installed wheel, an archive) the
commit is the one recorded in the version, if any, and ``dirty`` is ``"unknown"``.
"""

from __future__ import annotations

import re
import subprocess
from dataclasses import dataclass
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

SOURCE_ROOT = Path(__file__).resolve().parent.parent
"""The directory holding the ``multilayer`` package (a git work tree for a checkout)."""


def installed_version(distribution: str = "multilayer") -> str:
    """The version of an installed distribution (``0+unknown`` if none), by default
    ``multilayer``'s."""
    try:
        return version(distribution)
    except PackageNotFoundError:
        return "0+unknown"


def fipy_version() -> str:
    """The installed FiPy's version, from its package metadata (FiPy is not imported)."""
    return installed_version("FiPy")


@dataclass(frozen=True)
class Provenance:
    """Version, commit and dirty flag of the code that produced a result."""

    version: str
    commit: str
    """Full commit hash, the abbreviated one recorded in the version, or ``unknown``."""
    dirty: str
    """``true`` if tracked files differed from ``commit``, ``false``, or ``unknown``."""


def _git(*args: str, root: Path) -> str | None:
    try:
        done = subprocess.run(
            ["git", "-C", str(root), *args], capture_output=True, text=True, timeout=10, check=False
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 else None


def provenance(root: Path = SOURCE_ROOT) -> Provenance:
    """The provenance of the package in ``root`` (default: this package's source tree)."""
    package_version = installed_version()
    top = _git("rev-parse", "--show-toplevel", root=root)
    commit = _git("rev-parse", "HEAD", root=root) if top and Path(top).resolve() == root.resolve() else None
    if commit:
        changes = _git("status", "--porcelain", "--untracked-files=no", root=root)
        dirty = "unknown" if changes is None else ("true" if changes else "false")
        return Provenance(package_version, commit, dirty)
    recorded = re.search(r"\+g([0-9a-f]{7,40})", package_version)
    return Provenance(package_version, recorded.group(1) if recorded else "unknown", "unknown")
