"""Markdown pieces of the validation report: tables, verdicts, observed orders."""

from __future__ import annotations

from collections.abc import Sequence

import xarray as xr


def table(header: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    """A Markdown table."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def met(ok: bool) -> str:
    """The verdict word of a criterion."""
    return "**met**" if ok else "**not met**"


def order_column(orders: Sequence[float]) -> list[str]:
    """Observed orders between successive resolutions as a table column ('-' for the coarsest)."""
    return ["-"] + [f"{p:.2f}" for p in orders]


def resolution(ds: xr.Dataset) -> str:
    """Cells, layers and time steps of a run."""
    return f"{ds.sizes['x']} cells x {ds.sizes['layer']} layers, {int(ds.attrs['steps'])} steps"
