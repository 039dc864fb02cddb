"""The layout is the architecture (docs/architecture.md), checked on the source (AST): the
engine imports nothing of the scenario files, I/O, the command line, the plugin host, the
testing helpers, the validation cases or the reference solutions, not even for type
checking; nothing of the library imports the validation cases; no import cycle, between
packages or between modules; the time step and the engine's modules stay short."""

from __future__ import annotations

import ast
import functools
import importlib.metadata
import re
import sys
import tomllib
from pathlib import Path

import multilayer

PACKAGE = Path(multilayer.__file__).parent
FORBIDDEN_FOR_ENGINE = (
    "multilayer.io",
    "multilayer.scenario",
    "multilayer.app",
    "multilayer.plugins.host",
    "multilayer.testing",
    "multilayer.validation",
    "multilayer.reference",
)
STEP_LINES = 25
MODULE_LINES = 700


def _module(path: Path, root: Path = PACKAGE) -> str:
    parts = [root.name, *path.relative_to(root).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module(path): path for path in sorted(PACKAGE.rglob("*.py"))}


@functools.cache  # every test of this file reads the same modules
def _imports(path: Path) -> frozenset[str]:
    """Every name ``path`` imports, anywhere in it (function bodies and ``TYPE_CHECKING``
    blocks included): ``a.b`` for ``import a.b``, ``a.b.c`` for ``from a.b import c`` (a
    module ``a.b.c``, or a name of ``a.b``)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return frozenset(found)


def _resolve(name: str, modules: dict[str, Path]) -> str | None:
    """The module of ``modules`` that the imported name ``name`` is (or is in)."""
    while name not in modules:
        if "." not in name:
            return None
        name = name.rsplit(".", 1)[0]
    return name


def _graph(modules: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the modules it imports."""
    graph = {}
    for module, path in modules.items():
        targets = {_resolve(name, modules) for name in _imports(path)}
        graph[module] = {t for t in targets if t is not None and t != module}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one node (Tarjan 1972), iteratively."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in graph:
        if root in index:
            continue
        work = [(root, iter(sorted(graph.get(root, ()))))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = []
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.append(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(sorted(component))
    return found


def _package(module: str) -> str:
    """``multilayer.engine`` of ``multilayer.engine.vertical.newton``."""
    return ".".join(module.split(".")[:2])


def test_the_engine_imports_nothing_of_the_layers_above_it():
    offences = [
        f"{path.relative_to(PACKAGE.parent)} imports {name}"
        for path in sorted((PACKAGE / "engine").rglob("*.py"))
        for name in sorted(_imports(path))
        if name.startswith(FORBIDDEN_FOR_ENGINE)
    ]
    assert not offences, "\n".join(offences)


def _distributions(requirements: list[str]) -> set[str]:
    return {re.split(r"[\[<>=!~; ]", r, maxsplit=1)[0].lower().replace("_", "-") for r in requirements}


def test_every_third_party_import_is_a_declared_dependency():
    """What the package imports comes with ``pip install .`` or with the extra that needs it:
    ``pip install -e .`` then ``multilayer run`` once failed on ``import psutil``, which only
    the test extra (through Dask) had installed."""
    project = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text())["project"]
    required = _distributions(project["dependencies"])
    declared = required.union(
        *(_distributions(extra) for extra in project["optional-dependencies"].values()),
        *(_distributions(importlib.metadata.requires(d) or []) for d in required),  # pydantic-core
    )
    providers = importlib.metadata.packages_distributions()
    missing = {}
    for module, path in MODULES.items():
        for top in {name.split(".")[0] for name in _imports(path)}:
            if top in sys.stdlib_module_names or top in ("multilayer", "__future__"):
                continue
            if not _distributions(providers.get(top, [top])) & declared:
                missing[top] = module
    assert not missing, f"imported, not declared in pyproject.toml: {missing}"


def test_only_the_validation_package_imports_itself():
    """multilayer.validation uses the library; the library never uses it."""
    offences = [
        f"{path.relative_to(PACKAGE.parent)} imports {name}"
        for path in sorted(PACKAGE.rglob("*.py"))
        if "validation" not in path.relative_to(PACKAGE).parts[:1]
        for name in sorted(_imports(path))
        if name.startswith("multilayer.validation")
    ]
    assert not offences, "\n".join(offences)


def test_no_module_of_the_package_imports_its_public_facade():
    """``multilayer/__init__.py`` re-exports the public API for users; inside the package
    every module imports the module that defines what it uses."""
    graph = _graph(MODULES)
    assert [module for module, targets in graph.items() if "multilayer" in targets] == []


def test_no_import_cycle_between_packages_or_modules():
    graph = {module: targets for module, targets in _graph(MODULES).items() if module != "multilayer"}
    assert _cycles(graph) == []
    packages: dict[str, set[str]] = {}
    for module, targets in graph.items():
        packages.setdefault(_package(module), set()).update(
            _package(t) for t in targets if _package(t) != _package(module)
        )
    assert _cycles(packages) == []


def test_the_rules_see_a_forbidden_import_and_a_cycle(tmp_path):
    module = tmp_path / "m.py"
    module.write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from multilayer.io import scenario\n"
        "def f():\n    from multilayer.app import runner\n"
    )
    assert {"multilayer.io.scenario", "multilayer.app.runner"} <= _imports(module)
    (tmp_path / "pkg").mkdir()
    for name, imported in (("a", "pkg.b"), ("b", "pkg.c"), ("c", "pkg.a"), ("d", "pkg.a")):
        (tmp_path / "pkg" / f"{name}.py").write_text(f"import {imported}\n")
    modules = {f"pkg.{p.stem}": p for p in (tmp_path / "pkg").glob("*.py")}
    assert _cycles(_graph(modules)) == [["pkg.a", "pkg.b", "pkg.c"]]


def test_the_time_step_reads_in_a_few_lines():
    """``Simulation.step``: transport, vertical stress step, pressure, Courant check, guard,
    commit, in at most ``STEP_LINES`` lines of code (docstring, comments and blank lines aside)."""
    path = PACKAGE / "engine" / "simulation.py"
    lines = path.read_text().splitlines()
    step = next(
        node
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.FunctionDef) and node.name == "step"
    )
    body = step.body[1:] if isinstance(step.body[0], ast.Expr) else step.body  # the docstring
    code = [line for line in lines[body[0].lineno - 1 : step.end_lineno] if line.strip()]
    code = [line for line in code if not line.strip().startswith("#")]
    assert len(code) <= STEP_LINES, "\n".join(code)


def test_no_engine_module_is_long():
    long = {
        str(path.relative_to(PACKAGE)): count
        for path in (PACKAGE / "engine").rglob("*.py")
        if (count := len(path.read_text().splitlines())) > MODULE_LINES
    }
    assert long == {}
