"""The layout is the architecture: the engine never imports I/O, the command line, the
plugin host, the testing helpers or the validation cases (type-only imports under
``TYPE_CHECKING`` excepted), and nothing of the library imports the validation cases."""

from __future__ import annotations

import ast
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
)


def _runtime_imports(path: Path) -> set[str]:
    """Modules imported by ``path`` outside ``if TYPE_CHECKING:`` blocks."""
    tree = ast.parse(path.read_text())
    skip: set[int] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            skip.update(id(n) for child in node.body for n in ast.walk(child))
    found = set()
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            found.add(node.module)
            found.update(f"{node.module}.{alias.name}" for alias in node.names)
    return found


def test_the_engine_imports_neither_io_nor_cli_nor_the_plugin_host():
    offences = [
        f"{path.relative_to(PACKAGE.parent)} imports {name}"
        for path in sorted((PACKAGE / "engine").rglob("*.py"))
        for name in sorted(_runtime_imports(path))
        if name.startswith(FORBIDDEN_FOR_ENGINE)
    ]
    assert not offences, "\n".join(offences)


def test_only_the_validation_package_imports_itself():
    """multilayer.validation uses the library; the library never uses it."""
    offences = [
        f"{path.relative_to(PACKAGE.parent)} imports {name}"
        for path in sorted(PACKAGE.rglob("*.py"))
        if "validation" not in path.relative_to(PACKAGE).parts[:1]
        for name in sorted(_runtime_imports(path))
        if name.startswith("multilayer.validation")
    ]
    assert not offences, "\n".join(offences)


def test_the_rule_sees_a_forbidden_import(tmp_path):
    module = tmp_path / "m.py"
    module.write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from multilayer.io import scenario\n"
        "from multilayer.app import runner\n"
    )
    assert "multilayer.app.runner" in _runtime_imports(module)
    assert "multilayer.io.scenario" not in _runtime_imports(module)
