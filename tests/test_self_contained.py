"""The repository stands alone: code, docs, scenarios and README cite papers and the
project's own pages (docs/model.md), never a file outside the repository, the documents
the project was started from, or issue numbers of its tracker."""

from __future__ import annotations

import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SUFFIXES = {".py", ".md", ".yaml", ".yml", ".toml", ".cff", ".cfg", ".txt", ".json"}
SKIPPED_DIRS = {".git", ".venv", "build", "dist", "results", "__pycache__", ".pytest_cache", ".ruff_cache"}
#: what an outside reader cannot follow
FORBIDDEN = re.compile(
    r"DESIGN\.md|\.\./shared|/work/shared|\bseeds?[ _/-]*0\d\d|\bthe seeds\b|seeds/"
    r"|lecture slides|\bthe slides\b|(?<!FiPy )\bissue #?\d+",
    re.IGNORECASE,
)


def _files() -> list[Path]:
    found = []
    for directory, subdirs, names in os.walk(ROOT):
        subdirs[:] = [d for d in subdirs if d not in SKIPPED_DIRS and not d.endswith(".egg-info")]
        found += [Path(directory, n) for n in names if Path(n).suffix in SUFFIXES]
    return sorted(p for p in found if p != Path(__file__).resolve())


def test_no_reference_to_files_outside_the_repository_or_to_tracker_issues():
    files = _files()
    assert any(p.name == "README.md" for p in files) and any(p.suffix == ".yaml" for p in files)
    offences = [
        f"{path.relative_to(ROOT)}:{number}: {match.group(0)!r}"
        for path in files
        for number, line in enumerate(path.read_text(encoding="utf-8", errors="replace").splitlines(), 1)
        for match in FORBIDDEN.finditer(line)
    ]
    assert not offences, "\n".join(offences)


def test_the_pattern_catches_what_it_should_and_spares_upstream_bugs():
    for text in (
        "see DESIGN.md section 7",
        "seed 002 beads",
        "the seed-001 paper",
        "Bouchut lecture slides",
        "from ../shared/x",
        "as in issue 3",
        "issue #12",
    ):
        assert FORBIDDEN.search(text), text
    for text in ("FiPy issue #1223", "the layer slides down", "random seed 3", "rng seed"):
        assert not FORBIDDEN.search(text), text
