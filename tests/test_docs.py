"""Documentation that cannot drift: every code block of README.md and docs/**/*.md is checked.

The rules (docs/index.md, "Documentation that is tested"):

- every code block is fenced and names its language: ``sh`` (commands, run),
  ``python`` (run), ``yaml`` (validated: a scenario, a fragment of one or an excerpt of a
  shipped file), ``csv`` and ``toml`` (data, checked when marked), ``text`` (output,
  equations, synopses: not run);
- the runnable blocks of a page run in page order in a copy of the repository, so a later
  block can use what an earlier one wrote; every command must exit with code 0 (plain
  ``multilayer ...`` lines and Python blocks run in this process, to save starting
  Python for each; anything else runs in bash);
- an HTML comment on the line before a block changes that: ``<!-- docs-test: ... -->``
  with directives separated by ``;``:

  ``slow`` / ``validation``
      run only under ``pytest -m slow`` / ``pytest -m validation`` (too long for the
      default run); the default run then runs the page without them;
  ``skip: REASON``
      not run (it needs another machine, say); the reason is required;
  ``exit N``
      the commands of the block must exit with code N (an example of an error);
  ``file PATH``
      the block is the text of the shipped file PATH;
  ``excerpt PATH``
      (yaml) every top-level key of the block has the value it has in PATH;
  ``save PATH``
      the block is written to PATH in the copy, for the blocks after it.
"""

from __future__ import annotations

import contextlib
import glob
import importlib.util
import io
import os
import re
import shlex
import shutil
import subprocess
import sys
import textwrap
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import matplotlib
import pytest
import yaml

matplotlib.use("Agg")  # the documented Python blocks run in this process
import matplotlib.pyplot as plt  # noqa: E402

from multilayer.app import cli, sweep  # noqa: E402
from multilayer.scenario.source import Loader  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
LANGUAGES = {"sh", "python", "yaml", "csv", "toml", "text"}
RUNNABLE = {"sh", "python", "yaml"}
LEVELS = ("default", "slow", "validation")
DIRECTIVES = {"slow", "validation", "skip", "exit", "file", "excerpt", "save"}
INSIDE = "MULTILAYER_DOCS_TEST"
"""Set for the commands run here: a documented ``pytest`` does not run the docs again."""
TINY = {
    "name": "fragment",
    "slope_deg": 25.0,
    "domain": {"x_min": 0.0, "x_max": 1.0, "cells": 20},
    "material": {"density": 1500.0, "grain_diameter": 1.0e-3},
    "rheology": {"name": "drucker_prager", "mu_s": 0.3, "nu": 0.0},
    "initial": [{"shape": "layer", "thickness": 0.01}],
    "time": {"end": 0.01, "output_interval": 0.01},
}
"""The scenario a YAML fragment (a block without ``name``) is validated in (a layer of
material: a run of none is refused)."""
_MARKER = re.compile(r"^<!--\s*docs-test:(.*?)-->\s*$")


@dataclass
class Block:
    """One fenced code block of a page."""

    page: Path
    line: int
    language: str
    text: str
    directives: dict[str, str] = field(default_factory=dict)

    @property
    def where(self) -> str:
        return f"{self.page.relative_to(ROOT)}:{self.line}"

    @property
    def level(self) -> str:
        return next((lvl for lvl in LEVELS[:0:-1] if lvl in self.directives), "default")


def parse_page(page: Path) -> tuple[list[Block], list[str]]:
    """The fenced blocks of ``page`` and the problems found (unfenced or unlabelled blocks,
    unknown directives)."""
    lines = page.read_text(encoding="utf-8").splitlines()
    blocks, problems = [], []
    i, blank_before = 0, True
    while i < len(lines):
        line = lines[i]
        if line.lstrip().startswith("```"):
            language = line.lstrip()[3:].strip()
            end = next(
                (j for j in range(i + 1, len(lines)) if lines[j].lstrip().startswith("```")), len(lines)
            )
            directives: dict[str, str] = {}
            marker = _MARKER.match(lines[i - 1].strip()) if i else None
            for item in marker[1].split(";") if marker else ():
                name, _, value = item.strip().partition(" ")
                name = name.rstrip(":")
                directives[name] = value.strip()
                if name not in DIRECTIVES or (name == "skip" and not value.strip()):
                    problems.append(f"{page.name}:{i}: unknown or incomplete directive {item.strip()!r}")
            if language not in LANGUAGES:
                problems.append(f"{page.name}:{i + 1}: fence without a known language ({language!r})")
            text = textwrap.dedent("\n".join(lines[i + 1 : end]) + "\n")  # fences may be indented in lists
            blocks.append(Block(page, i + 1, language, text, directives))
            i, blank_before = end + 1, False
            continue
        indent = "        " if _in_list(lines, i) else "    "  # in a list item, 4 spaces continue it
        if line.startswith(indent) and line.strip() and blank_before:
            problems.append(f"{page.name}:{i + 1}: indented code block; fence it with a language")
        blank_before = not line.strip()
        i += 1
    return blocks, problems


def _in_list(lines: list[str], i: int) -> bool:
    """Whether the indented line ``i`` continues a list item (Markdown, not a code block)."""
    for j in range(i - 1, -1, -1):
        if lines[j].strip():
            return bool(re.match(r"^\s*([-*+]|\d+\.)\s", lines[j])) or lines[j].startswith("  ")
    return False


def _copy_of_repository(tmp_path: Path) -> Path:
    copy = tmp_path / "repo"
    ignore = shutil.ignore_patterns(
        ".git", ".venv", "results", "__pycache__", "*.egg-info", ".pytest_cache", "build", "site", "*.nc"
    )
    shutil.copytree(ROOT, copy, ignore=ignore)
    return copy


def _environment() -> dict[str, str]:
    env = dict(os.environ, MPLBACKEND="Agg", **{INSIDE: "1"})
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    return env


def _check(code: int, out: str, err: str, block: Block, expected: int) -> None:
    if code != expected:
        pytest.fail(
            f"{block.where}: exit code {code}, expected {expected}:\n{block.text}\n"
            f"--- stdout\n{out[-3000:]}\n--- stderr\n{err[-3000:]}"
        )


def _run(command: list[str], cwd: Path, block: Block, expected: int) -> None:
    done = subprocess.run(command, cwd=cwd, env=_environment(), capture_output=True, text=True)
    _check(done.returncode, done.stdout, done.stderr, block, expected)


def _in_process(cwd: Path, block: Block, expected: int, call: Callable[[], int | None]) -> None:
    """``call()`` in ``cwd`` with its output captured: the exit code it returns or raises
    (an exception is exit code 1, as an uncaught one is for a script)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = call() or 0
        except SystemExit as exc:
            code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
        except Exception:
            traceback.print_exc()
            code = 1
    plt.close("all")
    _check(code, out.getvalue(), err.getvalue(), block, expected)


def _multilayer_argv(line: str, cwd: Path) -> list[str] | None:
    """The arguments of a plain ``multilayer ...`` command line (globs expanded as bash
    does), or None when the line needs a shell (pipes, redirections, variables, ...)."""
    lexer = shlex.shlex(line, posix=True, punctuation_chars=True)
    lexer.whitespace_split, lexer.commenters = True, "#"
    try:
        words = list(lexer)
    except ValueError:  # a quotation spanning lines: bash reads it
        return None
    if not words or words[0] != "multilayer" or "$" in line or any(set(w) <= set("();<>|&") for w in words):
        return None
    argv = []
    for word in words[1:]:
        matches = sorted(glob.glob(word, root_dir=cwd)) if any(c in word for c in "*?[") else []
        argv.extend(matches or [word])
    return argv


def run_sh(block: Block, cwd: Path, expected: int) -> None:
    """Plain ``multilayer`` command lines run in this process (the console script calls
    the same ``main``, and this saves starting Python for each); the rest runs in bash."""
    lines = [line for line in block.text.replace("\\\n", " ").splitlines() if line.strip()]
    argvs = [_multilayer_argv(line, cwd) for line in lines if not line.lstrip().startswith("#")]
    if None in argvs or (expected and len(argvs) != 1):
        _run(["bash", "-e", "-o", "pipefail", "-c", block.text], cwd, block, expected)
        return
    for argv in argvs:
        _in_process(cwd, block, expected, lambda argv=argv: cli.main(argv))


def check_yaml(block: Block, cwd: Path) -> None:
    """A sweep file is loaded, a scenario validated, a fragment validated inside :data:`TINY`."""
    data = yaml.load(block.text, Loader=Loader)
    expected = int(block.directives.get("exit") or 0)
    if "base" in data:
        path = cwd / "scenarios" / "sweeps" / "docs_example.yaml"
        path.write_text(block.text)
        _in_process(cwd, block, expected, lambda: sweep.load(path) and 0)
        return
    path = cwd / "docs_block.yaml"
    path.write_text(yaml.safe_dump(data if "name" in data else {**TINY, **data}, sort_keys=False))
    _in_process(cwd, block, expected, lambda: cli.main(["validate", str(path)]))


def run_block(block: Block, cwd: Path) -> None:
    """Run (or validate) one block in ``cwd``."""
    expected = int(block.directives.get("exit") or 0)
    if "save" in block.directives:
        target = cwd / block.directives["save"]
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(block.text)
    elif block.language == "sh":
        run_sh(block, cwd, expected)
    elif block.language == "python":
        code = compile(block.text, block.where, "exec")
        _in_process(cwd, block, expected, lambda: exec(code, {"__name__": "__docs__"}))
    elif block.language == "yaml" and "excerpt" not in block.directives:
        check_yaml(block, cwd)


def _runs(block: Block) -> bool:
    return "skip" not in block.directives and (block.language in RUNNABLE or "save" in block.directives)


def _pages_with(level: str) -> list[Path]:
    """The pages with a block of ``level`` to check (a page that only saves files is not run)."""
    return [
        page
        for page in PAGES
        if any(b.level == level and _runs(b) and "save" not in b.directives for b in parse_page(page)[0])
    ]


def _run_page(page: Path, level: str, tmp_path: Path) -> None:
    if os.environ.get(INSIDE):
        pytest.skip("already inside a documented command")
    cwd = _copy_of_repository(tmp_path)
    allowed = LEVELS[: LEVELS.index(level) + 1]
    for block in parse_page(page)[0]:
        if _runs(block) and block.level in allowed:
            run_block(block, cwd)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_block_is_fenced_and_marked_correctly(page: Path) -> None:
    blocks, problems = parse_page(page)
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_blocks_equal_the_shipped_files(page: Path) -> None:
    """``file`` blocks are the shipped text; ``excerpt`` blocks agree key by key."""
    for block in parse_page(page)[0]:
        if "file" in block.directives:
            shipped = (ROOT / block.directives["file"]).read_text(encoding="utf-8")
            assert block.text == shipped, f"{block.where} differs from {block.directives['file']}"
        if "excerpt" in block.directives:
            source = block.directives["excerpt"]
            shipped = yaml.load((ROOT / source).read_text(), Loader=Loader)
            for key, value in yaml.load(block.text, Loader=Loader).items():
                assert shipped.get(key) == value, (
                    f"{block.where}: {key} is {value!r}, {shipped.get(key)!r} in {source}"
                )


def _written_figures() -> list[re.Pattern[str]]:
    """Names of the figures the documented scripts write (``{...}`` stands for a word)."""
    scripts = [ROOT / "docs" / "make_figures.py", *sorted((ROOT / "multilayer" / "validation").rglob("*.py"))]
    scripts.append(ROOT / "benchmarks" / "scaling.py")  # the measured scaling figure
    scripts.append(ROOT / "docs" / "make_calibration_figures.sh")  # docs/calibration.md
    names = re.findall(r"[\"'/]([\w{}]+\.png)[\"']", "".join(p.read_text() for p in scripts))
    return [re.compile(re.sub(r"\\\{\w*\\\}", r"\\w+", re.escape(name)) + "$") for name in names]


README_LINES = 120
"""The README is read in two minutes: what it is, one figure, the set-up, a tour, links."""


def test_the_readme_is_short() -> None:
    """The README holds at most ``README_LINES`` lines; the rest is in docs/."""
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_LINES, f"README.md has {len(lines)} lines, more than {README_LINES}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_images_exist_and_are_generated(page: Path) -> None:
    """Every figure a page shows is in the repository and written by a documented script."""
    written = _written_figures()
    for target in re.findall(r"!\[[^\]]*\]\(([^)]+)\)", page.read_text()):
        assert (page.parent / target).is_file(), f"{page.name}: {target} is missing"
        name = Path(target).name
        assert any(p.match(name) for p in written), f"{page.name}: no documented script writes {target}"


@pytest.mark.parametrize("page", _pages_with("default"), ids=lambda p: str(p.relative_to(ROOT)))
def test_page_runs(page: Path, tmp_path: Path) -> None:
    _run_page(page, "default", tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("page", _pages_with("slow"), ids=lambda p: str(p.relative_to(ROOT)))
def test_page_runs_with_its_slow_blocks(page: Path, tmp_path: Path) -> None:
    _run_page(page, "slow", tmp_path)


@pytest.mark.validation
@pytest.mark.parametrize("page", _pages_with("validation"), ids=lambda p: str(p.relative_to(ROOT)))
def test_page_runs_with_its_validation_blocks(page: Path, tmp_path: Path) -> None:
    _run_page(page, "validation", tmp_path)


def test_generated_reference_pages_are_up_to_date() -> None:
    """The committed reference pages generated from the schema and the parser (docs/hooks.py)
    are what the code generates now."""
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    assert spec is not None and spec.loader is not None
    hooks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(hooks)
    stale = hooks.stale_pages()
    assert not stale, f"{stale} differ from the code: run `{hooks.REGENERATE}` and commit them"
