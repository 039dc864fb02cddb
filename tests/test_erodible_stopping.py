"""The a-priori ``pouliquen_forterre`` law of the erodible-bed study for the 0.7 mm glass
beads of Mangeney et al. (2010) (docs/validation.md, "Erodible bed with a stopping
thickness"): its constants are the shipped file's frictions and the glass beads' L / d and
beta of Forterre & Pouliquen (2003), its h_stop(theta) the closed form, and the 5 mm bed
of the experiments stays exactly at rest on its own at the steepest slope of the study."""

from __future__ import annotations

import math

import numpy as np
import pytest

from multilayer.app.simulation import Simulation
from multilayer.plugins.builtins import PouliquenForterre
from multilayer.reference.exact import pouliquen_beta, pouliquen_h_stop
from multilayer.validation.cases import erodible_stopping, erodible_study, stopping
from multilayer.validation.runs import Run


def test_the_constants_are_the_shipped_frictions_and_the_glass_beads_scaled():
    law = erodible_study.stopping_law()
    shipped = Run("shipped", erodible_study.SCENARIO).load()
    r, m = shipped.rheology.params, shipped.material
    assert (law.mu_1, law.mu_2, law.mu_3) == (r["mu_s"], r["mu_2"], r["mu_start"])
    glass = stopping.law()
    assert law.L / m.grain_diameter == pytest.approx(glass.L / stopping.GRAIN, rel=1e-14)
    assert law.L == pytest.approx(1.155e-3, rel=1e-12)  # 1.65 d for d = 0.7 mm
    # I_0 gives the flow rule Fr = beta h / h_stop of the glass beads (Jop et al. 2005, app. A)
    beta = pouliquen_beta(law.I_0, law.L, m.grain_diameter, m.density / m.particle_density)
    assert beta == pytest.approx(glass.beta, rel=1e-14)


def test_h_stop_is_the_closed_form_and_infinite_at_every_slope_of_the_study():
    law = erodible_study.stopping_law()
    plugin = PouliquenForterre(mu_1=law.mu_1, mu_2=law.mu_2, L=law.L, I_0=law.I_0, mu_3=law.mu_3)
    for theta in (24.0, 28.0, 34.0):  # between delta_1 = 23.5 and delta_2 = 36 deg
        h_stop = law.h_stop(theta)
        assert h_stop == law.L * (law.mu_2 - math.tan(math.radians(theta))) / (
            math.tan(math.radians(theta)) - law.mu_1
        )
        assert plugin.mu_stop(h_stop) == pytest.approx(math.tan(math.radians(theta)), rel=1e-13)
    thick = np.array([1e-4, 5e-3, 0.14, 10.0])
    for theta in erodible_study.THETAS:  # tan(theta) < mu_1 < mu_stop(h): no finite h_stop
        assert math.tan(math.radians(theta)) < law.mu_1
        assert np.all(plugin.mu_stop(thick) > law.mu_1)
        with pytest.raises(ValueError):
            pouliquen_h_stop(theta, law.mu_1, law.mu_2, law.L)


def test_the_5_mm_bed_alone_stays_exactly_at_rest_at_23_deg():
    """The bed of the experiments at rest on its own (u == 0.0 at every step) with the law,
    at the steepest slope of the study, on a coarse mesh of the study's channel."""
    run = erodible_stopping.bed_run(max(erodible_study.THETAS), cells=60, end=0.1)
    sim = Simulation(run.load())
    h0 = sim.h.copy()
    for _ in range(20):
        sim.step()
        assert np.all(sim.u == 0.0)
    np.testing.assert_array_equal(sim.h, h0)
