"""The non-hydrostatic pressure at full resolution (docs/nonhydrostatic.md, docs/validation.md).

Marked ``validation`` (``python -m pytest -m validation``): the dispersion table and the
column-collapse comparison of the pressure options."""

from __future__ import annotations

from pathlib import Path

import pytest
from test_nonhydrostatic import standing_wave_error

from multilayer.engine.simulation import Simulation
from multilayer.io.scenario import load

pytestmark = pytest.mark.validation

SCENARIOS = Path(__file__).resolve().parents[1] / "scenarios"


def test_dispersion_table():
    """40 cells per half wavelength: the error falls with the layer count at every kh >= 0.5
    and is below 1 % at kh <= 3 from two layers on."""
    for kh in (0.5, 1.0, 2.0, 3.0):
        errors = [abs(standing_wave_error(kh, layers, cells=40)) for layers in (1, 2, 3, 5)]
        assert errors == sorted(errors, reverse=True), (kh, errors)
        assert max(errors[1:]) < 0.01, (kh, errors)
    assert abs(standing_wave_error(0.1, 5, cells=40)) < 0.002


def runout(a: float, pressure: str) -> float:
    """(L_f - L0) / L0 of the collapse of docs/validation.md."""
    sim = Simulation(
        load(
            SCENARIOS / "column_collapse.yaml",
            [
                f"initial.0.height={0.05 * a:g}",
                "domain.x_max=2.0",
                "domain.cells=500",
                "time.end=1.5",
                f"model.pressure={pressure}",
            ],
        )
    )
    sim.advance(1.5)
    return (sim.diagnostics()["front"] + 0.5 * sim.dx - 0.05) / 0.05


@pytest.mark.parametrize("a", [2.0, 10.0])
def test_non_hydrostatic_collapse_runs_out_less_than_hydrostatic(a):
    """Closer to the experimental law (1.2 a, 1.9 a^(2/3)) than the hydrostatic model, which
    overestimates it at every a; the 30 % goal itself is not met (docs/validation.md)."""
    law = 1.2 * a if a < 2.3 else 1.9 * a ** (2 / 3)
    hydrostatic, non_hydrostatic = runout(a, "hydrostatic"), runout(a, "non_hydrostatic")
    assert law < non_hydrostatic < hydrostatic
