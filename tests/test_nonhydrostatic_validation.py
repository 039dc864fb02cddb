"""The non-hydrostatic pressure at full resolution (docs/nonhydrostatic.md, docs/validation.md).

Marked ``validation`` (``python -m pytest -m validation``): the dispersion table and the
column-collapse comparison of the pressure options (run-out and stopping time)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from test_nonhydrostatic import standing_wave_error

from multilayer.app.simulation import Simulation
from multilayer.engine import diagnostics
from multilayer.scenario import load

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


def collapse(a: float, pressure: str) -> tuple[float, float]:
    """(L_f - L0) / L0 and the stopping time over sqrt(H0 / g) of the collapse of
    docs/validation.md: the first output time (every 0.01 s) after which the front
    (h = 1 mm, interpolated) advances slower than 1 cm/s to t = 1.5 s."""
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
    times = np.round(np.arange(0.0, 1.5 + 1e-9, 0.01), 10)
    fronts = []
    for t in times:
        sim.advance(float(t))
        fronts.append(diagnostics.front_position(sim.x, sim.h, 0.001))
    stop = diagnostics.stop_time(times, np.array(fronts), 0.01) / math.sqrt(0.05 * a / 9.81)
    return (sim.diagnostics()["front"] + 0.5 * sim.dx - 0.05) / 0.05, stop


@pytest.mark.parametrize("a", [2.0, 10.0])
def test_non_hydrostatic_collapse_against_the_2d_laws(a):
    """The run-out is closer to the experimental law (1.2 a, 1.9 a^(2/3)) than the
    hydrostatic one, which overestimates it at every a (the 30 % goal itself is not met,
    docs/validation.md), and the flow stops at 3 sqrt(H0/g) of the 2D experiments (Lube et
    al. 2005) within 20 %, as the hydrostatic one does: the duration does not tell them apart."""
    law = 1.2 * a if a < 2.3 else 1.9 * a ** (2 / 3)
    (hydrostatic, hydrostatic_stop), (non_hydrostatic, stop) = (
        collapse(a, "hydrostatic"),
        collapse(a, "non_hydrostatic"),
    )
    assert law < non_hydrostatic < hydrostatic
    assert abs(stop / 3.0 - 1.0) <= 0.2
    assert abs(hydrostatic_stop / 3.0 - 1.0) <= 0.2
