"""The force of the flow on the bed and the walls (engine/bed_force.py) against Newtonian
mechanics: a block sliding as a free body on a Coulomb slope, with and without side walls,
held at rest by static friction, and the momentum balance of dam breaks (every term of
``P(t_k) - P(t_{k-1}) = (t_k - t_{k-1}) (gravity - bed - walls - ends - pressure -
outflow)``) and of the normal momentum, hydrostatic and non-hydrostatic."""

from __future__ import annotations

import math

import numpy as np
import pytest
from engine import collapse_deposit, deposit_beside_a_collapse, simulation

from multilayer.engine.bed_force import FORCES, _impulses, _momentum, _sums
from multilayer.engine.transport import reference as transport
from multilayer.io import result_format

RHO, G = 1000.0, 9.81
ROUND_OFF = 1e-12


def block(theta: float, mu: float, *, width: float | None = None, mu_w: float = 0.0):
    """A uniform periodic layer 0.1 m thick on a Coulomb bed (friction ``mu``), its bulk
    friction 0.9 far above the slope: a rigid block of 100 kg per metre of slope and of
    width."""
    changes: dict = dict(
        slope_deg=theta,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 8, "layers": 4},
        rheology={"name": "drucker_prager", "mu_s": 0.9, "nu": 0.0},
        base=[{"condition": "coulomb", "mu": mu}],
        boundaries={"left": "periodic", "right": "periodic"},
        initial=[{"shape": "layer", "thickness": 0.1}],
    )
    if width is not None:
        changes["domain"]["width"] = width
        changes["walls"] = {"name": "wall_friction", "mu_w": mu_w}
    return simulation(**changes)


def test_a_sliding_block_presses_its_coulomb_friction_on_the_bed():
    """Sliding (tan theta > mu), the bed carries ``mu M g cos(theta)`` downslope and
    ``M g cos(theta)`` normal, and the momentum is ``M g (sin - mu cos) t`` at every output."""
    theta, mu, M = math.radians(30.0), 0.3, RHO * 0.1 * 1.0
    sim = block(30.0, mu)
    for t in (0.05, 0.1, 0.2):
        sim.advance(t)
        f = sim.forces.take()
        assert f["bed_force_x"] == pytest.approx(mu * M * G * math.cos(theta), rel=ROUND_OFF)
        assert f["bed_force_z"] == pytest.approx(M * G * math.cos(theta), rel=ROUND_OFF)
        assert f["gravity_force_x"] == pytest.approx(M * G * math.sin(theta), rel=ROUND_OFF)
        assert (
            f["wall_force_x"] == f["end_force_x"] == f["pressure_force_x"] == f["outflow_momentum_x"] == 0.0
        )
        expected = M * G * (math.sin(theta) - mu * math.cos(theta)) * t
        assert sim.forces.momentum(sim.h, sim.u) == pytest.approx(expected, rel=ROUND_OFF)
    assert np.ptp(sim.u) == pytest.approx(0.0, abs=1e-12)  # a plug


def test_a_block_at_rest_is_held_by_static_friction_equal_to_its_weight_along_the_slope():
    """At rest (tan theta < mu) static friction balances gravity: ``F = M g (sin, cos)``,
    the seismic force is zero and ``u == 0.0`` exactly."""
    theta, M = math.radians(20.0), RHO * 0.1 * 1.0
    sim = block(20.0, 0.5)
    sim.advance(0.2)
    f = sim.forces.take()
    assert np.all(sim.u == 0.0)
    assert f["bed_force_x"] == pytest.approx(M * G * math.sin(theta), rel=ROUND_OFF)
    assert f["bed_force_z"] == pytest.approx(M * G * math.cos(theta), rel=ROUND_OFF)


def test_side_walls_take_their_friction_out_of_the_bed_force():
    """Between walls ``W`` apart with friction ``mu_w``, a sliding block of thickness ``h``
    presses ``mu_w rho g cos(theta) h^2 / W`` per metre of slope on the two walls together
    (Jop, Forterre & Pouliquen 2005) and ``mu rho g cos(theta) h`` on the bed; at rest the
    two share the weight along the slope."""
    theta, h, width, mu, mu_w = math.radians(35.0), 0.1, 0.2, 0.3, 0.2
    sim = block(35.0, mu, width=width, mu_w=mu_w)
    sim.advance(0.1)
    f = sim.forces.take()
    assert np.all(sim.u > 0.0)
    assert f["wall_force_x"] == pytest.approx(mu_w * RHO * G * math.cos(theta) * h**2 / width, rel=1e-9)
    assert f["bed_force_x"] == pytest.approx(mu * RHO * G * math.cos(theta) * h, rel=1e-9)
    resting = block(20.0, 0.3, width=width, mu_w=mu_w)
    resting.advance(0.1)
    f = resting.forces.take()
    assert np.all(resting.u == 0.0)
    weight = RHO * h * G * math.sin(math.radians(20.0))
    assert f["bed_force_x"] + f["wall_force_x"] == pytest.approx(weight, rel=ROUND_OFF)
    assert (
        0.0 < f["wall_force_x"] <= mu_w * RHO * G * math.cos(math.radians(20.0)) * h**2 / width * (1 + 1e-12)
    )


def dam_break(pressure: str = "hydrostatic", width: float | None = None, **changes):
    """A 0.2 m high, 0.5 m long column against a wall at the left of a 2 m channel
    (``width`` apart), released at once; outflow at the right."""
    domain = {"x_min": 0.0, "x_max": 2.0, "cells": 80, "layers": 3}
    if width is not None:
        domain["width"] = width
    return simulation(
        domain=domain,
        boundaries={"left": "wall", "right": "outflow"},
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.5, "height": 0.2}],
        model={"pressure": pressure, **changes.pop("model", {})},
        **changes,
    )


def balance(sim, times):
    """The forces of each interval to ``times``, and the left-over of the downslope and
    the normal momentum balances of each (zero to round-off) relative to its largest term;
    the normal momentum ``rho sum_a h_a wbar_a dx`` (up) grows by ``bed_force_z -
    gravity_force_z``, the force into the bed less the weight."""
    momentum = sim.forces.momentum
    P0, Pz0, t0, records = momentum(sim.h, sim.u), momentum(sim.h, sim.w), sim.t, []
    for t in times:
        sim.advance(t)
        f = sim.forces.take()
        P, Pz = momentum(sim.h, sim.u), momentum(sim.h, sim.w)
        terms = [f[k] for k in ("bed_force_x", "wall_force_x", "end_force_x", "pressure_force_x")]
        net = f["gravity_force_x"] - sum(terms) - f["outflow_momentum_x"]
        scale = max(abs(P), abs(P0), abs(Pz), abs(Pz0), (t - t0) * max(abs(v) for v in f.values()))
        normal = (Pz - Pz0) - (t - t0) * (f["bed_force_z"] - f["gravity_force_z"])
        records.append((f, ((P - P0) - (t - t0) * net) / scale, normal / scale))
        P0, Pz0, t0 = P, Pz, t
    return records


@pytest.mark.parametrize("pressure", ["hydrostatic", "non_hydrostatic"])
def test_the_momentum_of_a_dam_break_changes_by_the_impulse_of_its_forces(pressure):
    """Frictionless dam break: the change of momentum between outputs is the impulse of
    the forces to round-off at every output; while the rarefaction has not reached the
    wall (``x0 / sqrt(g h0) = 0.36 s``) the hydrostatic wall carries ``rho g h0^2 / 2``
    exactly, a force the balance would miss without the end walls; the material leaves
    through the outflow later."""
    records = balance(dam_break(pressure), (0.05, 0.3, 0.8))
    for _, left_over, normal in records:
        assert abs(left_over) < 1e-13 and abs(normal) < 1e-13
    first = records[0][0]
    thrust = 0.5 * RHO * G * 0.2**2
    if pressure == "hydrostatic":
        assert first["end_force_x"] == pytest.approx(-thrust, rel=ROUND_OFF)
        assert first["pressure_force_x"] == 0.0
        assert all(f["bed_force_z"] == f["gravity_force_z"] for f, *_ in records)
    else:  # the falling column presses less on the wall and on the bed than its weight
        assert first["end_force_x"] + first["pressure_force_x"] < -0.5 * thrust
        assert first["bed_force_z"] < first["gravity_force_z"]
    assert records[0][0]["outflow_momentum_x"] == 0.0 < records[-1][0]["outflow_momentum_x"]


def sloping_dam_break(**changes):
    """The dam break on a 20 degree slope with a mu(I) bulk, a Coulomb bed and side walls."""
    return dam_break(
        slope_deg=20.0,
        rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.28},
        base=[{"condition": "coulomb", "mu": 0.3}],
        walls={"name": "wall_friction", "mu_w": 0.2},
        width=0.1,
        **changes,
    )


def test_a_dam_break_with_friction_and_side_walls_on_a_slope_balances_its_momentum():
    """mu(I) bulk, Coulomb bed and side walls on a 20 degree slope: every term non-zero,
    the balance to round-off."""
    records = balance(sloping_dam_break(), (0.05, 0.2))
    for f, left_over, _ in records:
        assert abs(left_over) < 1e-13
        assert f["bed_force_x"] > 0.0 and f["wall_force_x"] > 0.0 and f["end_force_x"] < 0.0


@pytest.mark.parametrize("order", [1, 2])
def test_the_normal_stress_keeps_the_momentum_balance(order):
    """model.normal_stress exchanges momentum between the columns of a layer only (its
    impulses cancel along each run of columns): with it, the slope's dam break with friction
    and side walls still balances its momentum to round-off, at both orders."""
    sim = sloping_dam_break(model={"normal_stress": True}, numerics={"order": order})
    for _, left_over, _ in balance(sim, (0.05, 0.2)):
        assert abs(left_over) < 1e-13
    assert np.any(sim.normal_stress.tau_xx != 0.0)  # the stress acted


def test_a_collapse_held_at_rest_by_the_normal_stress_balances_its_momentum():
    """The channel collapse (side walls, non-hydrostatic pressure) with the normal stress,
    coarse: it comes to rest by 0.3 s, held by its friction and its normal stress together
    (the vertical step's impulse from u* less the normal stress's velocity change): the
    balance to round-off while it stops and at rest, where the bed and the side walls hold
    the end wall's push (no downslope gravity on the flat bed)."""
    sim = collapse_deposit()
    records = balance(sim, (0.1, 0.3, 0.4))
    assert np.all(sim.u == 0.0)
    for _, left_over, normal in records:
        assert abs(left_over) < 1e-13 and abs(normal) < 1e-13
    f = records[-1][0]
    assert f["bed_force_x"] + f["wall_force_x"] + f["end_force_x"] == pytest.approx(0.0, abs=1e-12)
    assert f["end_force_x"] < 0.0 < f["bed_force_x"]


def test_a_deposit_at_rest_beside_a_flowing_chain_balances_its_momentum():
    """A collapse deposit held at rest by its friction and normal stress, chain by chain,
    beside a column that collapses and flows (tests/test_normal_stress.py): the balance to
    round-off while the one flows and the other rests."""
    sim, deposit = deposit_beside_a_collapse()
    sim.forces.take()  # the impulses saved with the deposit's state, before the new column
    records = balance(sim, (0.35, 0.4))
    assert np.all(sim.u[:, deposit] == 0.0) and np.any(sim.u != 0.0)
    for _, left_over, normal in records:
        assert abs(left_over) < 1e-13 and abs(normal) < 1e-13


def test_the_transport_conserves_momentum_on_a_flat_bed():
    """What the end faces and gravity do not carry is zero on a flat bed without dry cells
    (interior fluxes cancel, the well-balanced pressure terms vanish): the bed force of the
    transport is then only the pressure on the relief of the bed."""
    rng = np.random.default_rng(3)
    h = 0.1 + rng.random(60)
    u = rng.normal(size=(3, 60))
    fractions = np.full(3, 1 / 3)
    terms = np.zeros(3)
    h1, u1 = transport.transport(
        h, u, np.zeros(60), fractions, dx=0.05, dt=0.002, g_n=8.0, g_t=3.0, left="wall", right="outflow",
        boundary_momentum=terms,
    )  # fmt: skip
    change = np.sum(fractions[:, None] * (h1 * u1 - h * u)) * 0.05
    assert change == pytest.approx(terms[0] - terms[1] + 3.0 * terms[2], abs=1e-15)
    assert terms[2] == pytest.approx(0.002 * np.sum(h) * 0.05, rel=1e-3)


def test_the_result_variables_are_the_engines_forces():
    assert set(result_format.FORCES) == set(FORCES)
    for dims, attrs in result_format.FORCES.values():
        assert dims == ("time",) and attrs["units"] == "N m-1"


def test_a_lake_at_rest_on_a_beach_pushes_the_bed_as_hard_as_the_walls():
    """Water at rest between two walls over a bed rising from 0 to 0.5 m (no friction): the
    walls take ``-rho g h_0^2 / 2`` and ``+rho g h_N^2 / 2`` (the thicknesses of the cells
    next to them), the relief of the bed the difference, and nothing moves."""
    sim = simulation(
        domain={"cells": 50},
        bed={"points": [[0.0, 0.0], [10.0, 0.5]]},
        initial=[{"shape": "profile", "points": [[0.0, 1.0], [10.0, 0.5]]}],
    )
    sim.advance(0.2)
    f = sim.forces.take()
    assert np.abs(sim.u).max() < 1e-12
    thrust = 0.5 * RHO * G * (sim.h[0] ** 2 - sim.h[-1] ** 2)
    assert f["end_force_x"] == pytest.approx(-thrust, rel=1e-12)
    assert f["bed_force_x"] == pytest.approx(thrust, rel=1e-9)


def test_the_seismic_force_of_a_slide_that_stops_pulls_upslope_then_downslope_and_sums_to_zero():
    """A column released on a slope gentler than its bed friction: while it accelerates the
    force on the Earth less the weight points upslope, while it brakes downslope (the
    signature inverted by landslide seismology, Ekstrom & Stark 2013), and once the
    material is at rest again its impulse is zero: ``-(P_end - P_0)`` (a film reaches the
    end walls: they are part of the Earth)."""
    sim = simulation(
        slope_deg=15.0,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 50, "layers": 2},
        rheology={"name": "drucker_prager", "mu_s": 0.5, "nu": 0.0},
        base=[{"condition": "coulomb", "mu": 0.5}],
        boundaries={"left": "wall", "right": "wall"},
        initial=[{"shape": "rectangle", "x_min": 0.3, "x_max": 0.4, "height": 0.1}],
    )
    seismic, impulse, t0 = [], 0.0, 0.0
    for t in np.arange(0.02, 1.0, 0.02):
        sim.advance(t)
        f = sim.forces.take()
        on_earth = f["bed_force_x"] + f["wall_force_x"] + f["end_force_x"] + f["pressure_force_x"]
        seismic.append(on_earth - f["gravity_force_x"])
        impulse += (t - t0) * seismic[-1]
        t0 = t
    assert np.all(sim.u == 0.0)
    assert seismic[0] < 0.0 < max(seismic)
    assert abs(impulse) < 1e-12 * RHO * 0.1 * 0.1 * G


@pytest.mark.parametrize("two", [False, True])
@pytest.mark.parametrize("walled", [False, True])
def test_the_one_call_of_a_steps_sums_gives_the_bits_of_the_separate_sums(two, walled):
    """``_sums``, the one compiled call of ``BedForce.record``: the window where ``h +
    (h_a + h_b) > 0`` and, in it, the bits of ``_momentum`` and ``_impulses`` called apart."""
    rng = np.random.default_rng(7)
    L, N = 4, 30
    l = np.full(L, 1.0 / L)
    h = np.where(np.arange(N) % 7 < 4, 0.0, rng.random(N))
    h[:3] = h[-3:] = 0.0
    h_a, h_b = h.copy(), h.copy()
    h_a[3], h_b[-4] = 0.2, 0.3  # material during the step only: the window grows
    u, w, u_end, w_end = (rng.normal(size=(L, N)) for _ in range(4))
    a = (h_a, rng.normal(size=(L, N)), rng.normal(size=(L, N)), rng.random((L, N)), rng.random((L, N)), 0.01)
    b = (h_b, rng.normal(size=(L, N)), np.zeros((L, N)), rng.random((L, N)), rng.random((L, N)), 0.005)
    h_end = h_b if two else h_a
    sums = _sums(l, h, u, w, h_end, u_end, w_end, True, *a, *(b if two else a), two, walled, 2.0)
    wet = np.flatnonzero(h + sum([h_a, h_b] if two else [h_a]) > 0)
    first, stop = int(wet[0]), int(wet[-1]) + 1
    apart = [_momentum(l, h, u, first, stop), _momentum(l, h_end, u_end, first, stop)]
    apart += [_momentum(l, h, w, first, stop), _momentum(l, h_end, w_end, first, stop)]
    for h_s, ustar, u_s, threshold, viscous, dt in [a, b] if two else [a]:
        apart += list(_impulses(l, h_s, ustar, u_s, walled, threshold, viscous, 2.0, dt, first, stop))
    assert sums.tolist() == apart + [0.0] * (12 - len(apart))
