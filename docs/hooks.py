"""MkDocs hooks and the generated reference pages (mkdocs.yml).

Two reference pages are generated from the code and committed, so that they read on
GitHub as on the site; ``python docs/hooks.py`` rewrites them, and both
``tests/test_docs.py`` and ``mkdocs build --strict`` fail while they differ from the code:

- ``reference/scenario-keys.md`` from the schema of scenario files
  (:mod:`multilayer.scenario.schema`), the built-in rheologies and the pressure models;
- ``reference/cli-options.md`` from the argument parser of the ``multilayer`` command
  (:func:`multilayer.app.cli.build_parser`).

``reference/changelog.md`` is, in the repository, a pointer to ``CHANGELOG.md``; on the
site it is ``CHANGELOG.md`` itself, its links made relative to the page.
"""

from __future__ import annotations

import argparse
import logging
import re
import sys
import types
import typing
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pydantic import BaseModel
from pydantic_core import PydanticUndefined

from multilayer.scenario.messages import model_in

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
REGENERATE = "python docs/hooks.py"
"""The command that rewrites the generated pages."""


def generated_pages() -> dict[str, Callable[[], str]]:
    """The committed pages generated from the code: their paths under docs/ and makers."""
    return {"reference/scenario-keys.md": scenario_keys_page, "reference/cli-options.md": cli_page}


def stale_pages() -> list[str]:
    """The generated pages whose committed text differs from what the code generates."""
    return [uri for uri, make in generated_pages().items() if _read(DOCS / uri) != make()]


def _read(path: Path) -> str | None:
    return path.read_text(encoding="utf-8") if path.is_file() else None


def on_files(files: Any, config: Any) -> Any:
    """Check the generated pages against the code (a warning, an error under ``--strict``)
    and put CHANGELOG.md in place of its pointer."""
    from mkdocs.structure.files import File

    for uri in stale_pages():
        logging.getLogger("mkdocs.hooks").warning(
            "docs/%s differs from what the code generates: run `%s`", uri, REGENERATE
        )
    uri = "reference/changelog.md"
    pointer = files.get_file_from_path(uri)
    if pointer is not None:
        files.remove(pointer)
    files.append(File.generated(config, uri, content=changelog_page()))
    return files


_ROLE = re.compile(r":(?:mod|func|class|meth|data|attr|exc):(<code>)~?")
"""A Sphinx cross-reference role left in front of its rendered name by mkdocstrings."""


def on_page_content(html: str, page: Any, config: Any, files: Any) -> str:
    """The API reference without the Sphinx roles of the docstrings (``:func:`load```)."""
    return _ROLE.sub(r"\1", html)


# --- scenario keys -------------------------------------------------------------------------


def _type_text(annotation: Any) -> str:
    """A reader's name for a field's type."""
    origin = typing.get_origin(annotation)
    args = [a for a in typing.get_args(annotation) if a is not type(None)]
    if origin in (typing.Union, types.UnionType):
        return " or ".join(dict.fromkeys(_type_text(a) for a in args))
    if origin is typing.Annotated:
        return _type_text(args[0])
    if origin is typing.Literal:
        return "one of " + ", ".join(f"`{a}`" for a in args)
    if origin is list:
        return f"list of {_type_text(args[0])}" if args else "list"
    if origin is dict:
        return "mapping"
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return "mapping"
    names = {float: "number", int: "integer", str: "string", bool: "boolean", Path: "path"}
    return names.get(annotation, "any")


_SHORT = 40
"""Longest default of a mapping written out in full (characters)."""


def _default_text(info: Any) -> str:
    if info.is_required():
        return "**required**"
    default = info.default_factory() if info.default is PydanticUndefined else info.default
    if default is None:
        return "none"
    if isinstance(default, BaseModel):
        text = f"`{default.model_dump(mode='json', exclude_none=True)}`".replace("'", "")
        return text if len(text) <= _SHORT else "the defaults below"
    if isinstance(default, list):
        dumped = [
            d.model_dump(mode="json", exclude_none=True) if isinstance(d, BaseModel) else d for d in default
        ]
        return f"`{dumped}`".replace("'", "")
    return f"`{default}`"


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ").replace("<", "&lt;").replace(">", "&gt;")


def _model_sections(model: type[BaseModel], path: str) -> list[str]:
    """A table of ``model``'s keys under the heading ``path``, then one per nested mapping."""
    doc = " ".join((model.__doc__ or "").strip().split("\n\n")[0].split()).replace("``", "`")
    doc = doc if path else "A scenario file."
    lines = [f"## `{path}`" if path else "## Top level", "", doc, "", "| key | type | default | accepted |"]
    lines.append("| --- | --- | --- | --- |")
    nested: list[tuple[type[BaseModel], str]] = []
    for key, info in model.model_fields.items():
        if key == "params":  # a plugin's parameters: the rheology tables below
            continue
        cells = [f"`{key}`", _type_text(info.annotation), _default_text(info), info.description or ""]
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
        sub = model_in(info.annotation)
        if sub is not None and "params" not in sub.model_fields:  # a plugin: the rheology table
            is_list = typing.get_origin(info.annotation) is list
            nested.append((sub, f"{path}.{key}".lstrip(".") + ("[]" if is_list else "")))
    lines.append("")
    for sub, sub_path in nested:
        lines += _model_sections(sub, sub_path)
    return lines


_LAYERS = (1, 4, 16)
"""Layer counts at which a pressure option's default (a function of ``domain.layers``) is shown."""


def scenario_keys_page() -> str:
    """Every key of a scenario file, the rheologies and their parameters, the pressure models
    and their options."""
    import warnings

    from multilayer.engine.pressure import model as pressure_models
    from multilayer.plugins import host as plugins
    from multilayer.scenario.schema import Scenario

    lines = [
        "# Scenario keys",
        "",
        "Generated from the schema that validates scenario files (`python docs/hooks.py`; the tests "
        "check it is up to date), so it lists exactly what `multilayer validate` accepts. `key[]` is "
        "a list of mappings; the *accepted* column is the text an error message gives. "
        "[Scenario files](../scenarios.md) explains how the keys are used.",
        "",
    ]
    lines += _model_sections(Scenario, "")
    lines += [
        "## Rheologies (`rheology`, `walls`)",
        "",
        "`{name: NAME, PARAMETER: VALUE, ...}`; the built-in rheologies (`multilayer plugins` lists "
        "them and those of the plugins installed).",
        "",
        "| name | applies to | parameters | description |",
        "| --- | --- | --- | --- |",
    ]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plugins.PluginWarning)
        catalogue = plugins.catalogue()
    for name, item in sorted(catalogue.rheologies.items()):
        if not item.cls.__module__.startswith("multilayer."):  # an installed third-party plugin
            continue
        cells = [f"`{name}`", item.cls.applies_to, f"`{plugins.signature_text(item.cls)}`"]
        cells.append(plugins.description(item.cls))
        lines.append("| " + " | ".join(_cell(c) for c in cells) + " |")
    lines += [
        "",
        "## Pressure models (`model`)",
        "",
        "`{pressure: NAME, OPTION: VALUE, ...}`; [Choose a pressure model](../how-to/pressure-model.md).",
        "",
        "| pressure | option | default | accepted |",
        "| --- | --- | --- | --- |",
    ]
    for name, pressure in pressure_models.models().items():
        options = pressure.options or {}
        if not options:
            lines.append(f"| `{name}` | (none) | | |")
        for key, option in options.items():
            accepted = option.accepted.replace(" = {layers}", "").replace("{layers}", "domain.layers")
            defaults = {layers: option.default(layers) for layers in _LAYERS}
            default = ", ".join(
                f"`{value}` for {layers} layer{'s' * (layers > 1)}" for layers, value in defaults.items()
            )
            if len(set(defaults.values())) == 1:
                default = f"`{defaults[1]}`"
            lines.append(f"| `{name}` | `{key}` | {default} | {_cell(accepted)} |")
    return "\n".join(lines) + "\n"


# --- command line --------------------------------------------------------------------------


def _usage(parser: argparse.ArgumentParser) -> str:
    return " ".join(parser.format_usage().split()).removeprefix("usage: ")


def _options_table(parser: argparse.ArgumentParser) -> list[str]:
    lines = ["| argument | meaning |", "| --- | --- |"]
    for action in parser._actions:
        if isinstance(action, (argparse._SubParsersAction, argparse._HelpAction)):
            continue
        if action.option_strings:
            metavar = f" {action.metavar or action.dest.upper()}" if action.nargs != 0 else ""
            name = ", ".join(f"{o}{metavar}" for o in action.option_strings)
        else:
            name = str(action.metavar or action.dest)
        meaning = (action.help or "") % {"default": action.default, "prog": parser.prog}
        if action.choices and not isinstance(action.choices, dict):
            meaning += " (" + ", ".join(str(c) for c in action.choices) + ")"
        lines.append(f"| `{name}` | {_cell(meaning)} |")
    return lines


def cli_page() -> str:
    """The usage, description and options of ``multilayer`` and of each subcommand."""
    from multilayer.app.cli import build_parser

    parser = build_parser()
    lines = [
        "# Command-line options",
        "",
        "Generated from the parser of the `multilayer` command (`python docs/hooks.py`; the tests "
        "check it is up to date), so it is what `multilayer COMMAND --help` prints. "
        "[Command line](../cli.md) explains the commands, their outputs and their exit codes.",
        "",
        "```text",
        _usage(parser),
        "```",
        "",
        parser.description or "",
        "",
        *_options_table(parser),
        "",
    ]
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, command in sub.choices.items():
        description = (command.description or "").split("\n\nExamples:")[0].strip().replace("``", "`")
        lines += [f"## `multilayer {name}`", "", "```text", _usage(command), "```", "", description, ""]
        lines += [*_options_table(command), ""]
    return "\n".join(lines) + "\n"


# --- changelog -----------------------------------------------------------------------------


def changelog_page() -> str:
    """CHANGELOG.md, its links made relative to this page."""
    text = (ROOT / "CHANGELOG.md").read_text(encoding="utf-8")
    return re.sub(r"\]\(docs/", "](../", text)


def main() -> int:
    """Rewrite the generated pages that differ from the code; print which."""
    for uri in stale_pages():
        (DOCS / uri).write_text(generated_pages()[uri](), encoding="utf-8")
        print(f"wrote docs/{uri}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
