"""pytest plugin: scenario files with ``expect:`` become tests named by their kind.

Registered through the ``pytest11`` entry point, so ``pytest scenarios/`` or
``pytest scenarios/column_collapse.yaml`` runs each ``*.yaml`` / ``*.yml`` scenario that
carries a top-level ``expect:`` list once, with one test item per entry named
``<kind>[<quantity>]``: ``regression[front_final]`` for a value pinned from the code's
own output, ``reference[mass_final]`` for an exact or published value (so
``pytest scenarios/ -k reference`` runs the validations only).  A failing item shows the
expected vs obtained table of :mod:`multilayer.app.expectations`.

Only files named on the command line, or lying directly in a directory named there, are
collected: a plain ``pytest`` run (``testpaths``) or a recursive directory walk never
turns stray YAML files (test fixtures, third-party data) into scenario runs.  Files
without ``expect:`` are ignored.
"""

from __future__ import annotations

from pathlib import Path

import pytest

SUFFIXES = (".yaml", ".yml")


def _named_on_command_line(config: pytest.Config, path: Path) -> bool:
    if config.args_source is not pytest.Config.ArgsSource.ARGS:
        return False
    for arg in config.args:
        named = Path(arg.split("::")[0])
        named = named if named.is_absolute() else Path(config.invocation_params.dir) / named
        named = named.resolve()
        if named == path or (named.is_dir() and named == path.parent):
            return True
    return False


def _scenario_data(path: Path) -> object:
    """The YAML data of ``path`` as ``multilayer`` reads a scenario, or None where it reads
    none: a regular file within the bounds of :mod:`multilayer.scenario.limits`, parsed by
    libyaml.  Every YAML file of a directory named on the command line is read, data files
    too: PyYAML's own parser, without bounds, would stop the whole collection on one 5000
    lists deep (a ``RecursionError``) and take 48 s over one of 6 MB."""
    from multilayer.errors import InputError
    from multilayer.scenario.source import read_yaml

    try:
        return read_yaml(path)[0]
    except InputError:
        return None


def _has_expectations(path: Path) -> bool:
    data = _scenario_data(path)
    return isinstance(data, dict) and "expect" in data


def pytest_collect_file(file_path: Path, parent: pytest.Collector) -> pytest.Collector | None:
    """Collect a scenario file with ``expect:`` named (or whose directory is named) on the command line."""
    if file_path.suffix not in SUFFIXES:
        return None
    if not _named_on_command_line(parent.config, file_path.resolve()):
        return None
    if not _has_expectations(file_path):
        return None
    return ScenarioFile.from_parent(parent, path=file_path)


class ScenarioFile(pytest.File):
    """A scenario YAML file: one test item per ``expect:`` entry, sharing one run."""

    def collect(self):
        data = _scenario_data(self.path)
        assert isinstance(data, dict)  # collected by pytest_collect_file
        entries = data["expect"] if isinstance(data["expect"], list) else [None]
        names = [_item_name(entry) for entry in entries]
        for index, name in enumerate(names):
            if names.count(name) > 1:
                name = f"{name[:-1]}-{names[:index].count(name) + 1}]"
            yield ScenarioItem.from_parent(self, name=name, index=index)

    def outcomes(self):
        """Run the scenario once (on first use) and return its outcomes, or the error message."""
        if not hasattr(self, "_outcomes"):
            from multilayer import scenario as scenarios
            from multilayer.app import expectations as expect
            from multilayer.errors import InputError, RunError

            try:
                scenario = scenarios.load(self.path)
                outcomes = expect.check(scenario)
                self._outcomes = (outcomes, expect.report(scenario.name, outcomes))
            except (InputError, RunError) as exc:
                self._outcomes = (None, str(exc))
        return self._outcomes


def _item_name(entry: object) -> str:
    """``<kind>[<quantity>]``, or ``<kind>[<field>_<norm>_error_<solution>]`` for a comparison
    with an exact solution, as written in the file (the file is validated when it runs)."""
    if not isinstance(entry, dict):
        return "expect"
    exact = entry.get("exact")
    if isinstance(exact, dict):
        from multilayer.app.expectations import exact_label

        what = exact_label(*(exact.get(key, "unknown") for key in ("solution", "field", "norm")))
    else:
        what = entry.get("quantity", "unknown")
    return f"{entry.get('kind', 'unknown')}[{what}]"


class ExpectationFailure(Exception):
    """Raised by :class:`ScenarioItem` with the expected vs obtained table."""


class ScenarioItem(pytest.Item):
    """One ``expect:`` entry of a scenario file, checked against the file's (shared) run."""

    def __init__(self, *, index: int, **kwargs):
        super().__init__(**kwargs)
        self.index = index

    def runtest(self) -> None:
        assert isinstance(self.parent, ScenarioFile)
        outcomes, text = self.parent.outcomes()
        if outcomes is None:
            raise ExpectationFailure(text)
        if not outcomes[self.index].passed:
            raise ExpectationFailure(text)

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, ExpectationFailure):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style=style)

    def reportinfo(self):
        return self.path, None, f"scenario {self.path.name}::{self.name}"
