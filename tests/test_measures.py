"""Measures of a collapse run (engine/diagnostics.py) on constructed fronts."""

import numpy as np
import pytest

from multilayer.engine import diagnostics


def test_front_is_where_h_falls_through_the_level_between_centres():
    x = np.arange(6) * 0.01
    h = np.array([0.1, 0.1, 0.05, 0.003, 0.003, 0.003])  # a 3 mm bed ahead of the flow
    # level 3 mm + 1 mm = 4 mm crossed between x = 0.02 (50 mm) and 0.03 (3 mm)
    assert diagnostics.front_position(x, h, 0.004) == pytest.approx(0.02 + 0.01 * 46 / 47)
    assert np.isnan(diagnostics.front_position(x, h, 0.2))
    assert diagnostics.front_position(x, np.full(6, 0.1), 0.004) == 0.05


def test_stop_time_and_time_to_95_percent_of_a_decelerating_front():
    t = np.linspace(0.0, 3.0, 61)
    tau = 0.4
    front = 0.8 * (1.0 - np.exp(-t / tau))  # speed 2 exp(-t/tau) m/s
    # the front speed falls below 1 cm/s at t = tau ln(200) = 2.12 s: the first output
    # time after which every interval is slower
    t_stop = diagnostics.stop_time(t, front, 0.01)
    assert 2.0 < t_stop <= 2.2
    assert diagnostics.time_to_fraction(t, front, 0.95) == pytest.approx(tau * np.log(20), abs=0.01)
    assert diagnostics.stop_time(t, front, 1.0) == pytest.approx(0.3)  # below 1 m/s at tau ln 2
    assert np.isnan(diagnostics.stop_time(t, 0.1 * t, 0.01))  # still moving at the end
    assert diagnostics.stop_time(t, np.zeros_like(t), 0.01) == 0.0
