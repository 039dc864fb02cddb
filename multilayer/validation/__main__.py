"""``python -m multilayer.validation [SECTION ...]``: run validation cases and write their
report (``validation.md`` and ``figures/`` in the working directory by default)."""

from __future__ import annotations

from pathlib import Path

from multilayer.validation import report

INTRO = """# Validation

Written by `python -m multilayer.validation`: each section runs shipped scenarios of
multilayer, measures them and compares them with an exact solution or a published result.
"""

if __name__ == "__main__":
    raise SystemExit(
        report.main(
            None,
            description=__doc__ or "",
            report=Path("validation.md"),
            runs=Path("results") / "validation",
            intro=INTRO,
            command="python -m multilayer.validation",
        )
    )
