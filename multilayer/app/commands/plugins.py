"""List every registered rheology (built-in or third-party) and any broken plugin.

For each rheology: its name, what it applies to (bulk or walls), its parameters (the
constructor's keyword arguments, as written in a scenario), a one-line description
and the distribution and entry point that provide it.
"""

from __future__ import annotations

import argparse
import warnings

from multilayer.errors import printable
from multilayer.plugins import host as plugins

HELP = "list the available rheologies and their parameters"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``multilayer plugins`` takes no options."""


def main(args: argparse.Namespace) -> int:
    """Print the catalogue; broken plugins are listed, not warned about.  Every line
    :func:`~multilayer.errors.printable`: a plugin's docstring, parameter defaults and
    distribution metadata are a third party's text, and an escape sequence there reached
    the terminal."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", plugins.PluginWarning)
        catalogue = plugins.catalogue()
    for name, item in sorted(catalogue.rheologies.items()):
        print(printable(f"{name} [{item.cls.applies_to}]: {plugins.description(item.cls)}"))
        print(printable(f"    parameters: {plugins.signature_text(item.cls)}"))
        print(printable(f"    from: {item.source}"))
    if catalogue.broken:
        print("\nbroken plugins (skipped):")
        for broken in catalogue.broken:
            print(printable(f"  {broken.source}: {broken.error}"))
    return 0
