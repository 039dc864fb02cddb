"""pytest plugin: scenario files with ``expect:`` become regression tests.

Registered through the ``pytest11`` entry point, so ``pytest scenarios/`` or
``pytest scenarios/column_collapse.yaml`` runs each ``*.yaml`` / ``*.yml`` scenario that
carries a top-level ``expect:`` list as one test item, failing with the expected vs
obtained table of :mod:`multilayer.expect`.

Only files named on the command line, or lying directly in a directory named there, are
collected: a plain ``pytest`` run (``testpaths``) or a recursive directory walk never
turns stray YAML files (test fixtures, third-party data) into scenario runs.  Files
without ``expect:`` are ignored.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

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


def _has_expectations(path: Path) -> bool:
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError):
        return False
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
    """A scenario YAML file: one test item running all its expectations."""

    def collect(self):
        yield ScenarioItem.from_parent(self, name=self.path.stem)


class ExpectationFailure(Exception):
    """Raised by :class:`ScenarioItem` with the expected vs obtained table."""


class ScenarioItem(pytest.Item):
    """Runs one scenario and checks its ``expect:`` list."""

    def runtest(self) -> None:
        from multilayer.errors import InputError, RunError
        from multilayer.io import scenario as scenarios
        from multilayer.testing import expectations as expect

        try:
            scenario = scenarios.load(self.path)
            outcomes = expect.check(scenario)
        except (InputError, RunError) as exc:
            raise ExpectationFailure(str(exc)) from None
        table = expect.report(scenario.name, outcomes)
        if not all(o.passed for o in outcomes):
            raise ExpectationFailure(table)

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, ExpectationFailure):
            return str(excinfo.value)
        return super().repr_failure(excinfo, style=style)

    def reportinfo(self):
        return self.path, None, f"scenario {self.path.name}"
