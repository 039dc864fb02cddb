"""The validation cases, one module each: its runs, its measures, its criteria and its
section of the report (``section(ctx) -> str``)."""

from __future__ import annotations

from collections.abc import Callable

from multilayer.validation.cases import (
    bagnold,
    chute,
    collapse_channel,
    column_collapse,
    dam_break,
    erodible_bed,
    erodible_options,
    erodible_stopping,
    erodible_study,
    immersed_layer,
    static_interface,
    stopping,
    submarine_collapse,
    well_posedness,
)
from multilayer.validation.runs import Context

SECTIONS: dict[str, Callable[[Context], str]] = {
    case.NAME: case.section
    for case in (
        static_interface,
        dam_break,
        bagnold,
        stopping,
        well_posedness,
        chute,
        column_collapse,
        collapse_channel,
        erodible_bed,
        erodible_study,
        erodible_options,
        erodible_stopping,
        submarine_collapse,
        immersed_layer,
    )
}
"""Section name -> the case's section, in report order."""
