"""Scenario files: the schema of every key, loading YAML with the line of each key,
``--set`` overrides and the messages of invalid input (docs/scenarios.md).

- :mod:`~multilayer.scenario.schema`: the strict pydantic models, ``Scenario`` at the top;
- :mod:`~multilayer.scenario.source`: the YAML loader and the line map of a file;
- :mod:`~multilayer.scenario.overrides`: ``KEY=VALUE`` overrides;
- :mod:`~multilayer.scenario.messages`: ``<file>: <key> (line N): <problem>; accepted: <...>``;
- :mod:`~multilayer.scenario.loading`: :func:`load` a file, :func:`from_dict` a mapping;
- :mod:`~multilayer.scenario.profiles`, :mod:`~multilayer.scenario.files`: the CSV and
  DEM profiles a scenario names, and reading a user's input file.
"""

from multilayer.scenario.loading import from_dict, load, validated_again
from multilayer.scenario.overrides import apply_overrides, as_overrides
from multilayer.scenario.schema import Scenario
from multilayer.scenario.source import format_value, read_yaml

__all__ = [
    "Scenario",
    "apply_overrides",
    "as_overrides",
    "format_value",
    "from_dict",
    "load",
    "read_yaml",
    "validated_again",
]
