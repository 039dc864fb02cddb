"""Property-based tests (Hypothesis): engine invariants and scenario-loader robustness.

The default run tries a few examples of each property (``quick``; that of ``validate`` in a
child process under ``slow``), the same ones in every
run (derandomized, no example database): a default run passes or fails alike on every
clone.  ``-m properties`` runs many more (``thorough``), new ones each time; an example it
finds failing is pinned as a regular test (``test_the_examples_the_wide_search_found``).
"""

from __future__ import annotations

import copy
import math
import subprocess
import sys

import numpy as np
import pytest
import yaml
from conftest import TINY_SCENARIO
from engine import scenario
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from multilayer.app.simulation import Simulation
from multilayer.scenario import from_dict

THOROUGH = 150
EXAMPLES = [
    pytest.param(6, id="quick"),
    pytest.param(THOROUGH, id="thorough", marks=pytest.mark.properties),
]


def _settings(examples: int, max_examples: int | None = None, **options) -> settings:
    """Hypothesis settings of a property tried on ``examples`` (one of ``EXAMPLES``): the
    quick examples are derandomized and not stored (the same in every run); the thorough
    search draws new ones and keeps failures in the example database."""
    quick = examples < THOROUGH
    return settings(
        max_examples=examples if max_examples is None else max_examples,
        deadline=None,
        derandomize=quick,
        database=None if quick else settings.default.database,
        **options,
    )


@st.composite
def closed_scenarios(draw, open_sides: bool = False):
    """A small valid scenario between walls or periodic (``open_sides``: also outflow, and
    inflow on the left, with a random inflow state): a random block on a random slope."""
    cells = draw(st.integers(8, 30))
    layers = draw(st.integers(1, 4))
    length = draw(st.floats(0.2, 2.0))
    dx = length / cells
    width = draw(st.floats(dx, 0.5 * length))
    start = draw(st.floats(0.0, length - width))
    mu_s = draw(st.floats(0.0, 0.8))
    rheology = draw(
        st.sampled_from(
            [
                {"name": "drucker_prager", "mu_s": mu_s, "nu": draw(st.just(0.0) | st.floats(1e-30, 0.05))},
                {"name": "jop_mu_i", "mu_s": mu_s, "mu_2": mu_s + 0.2, "I_0": 0.3},
            ]
        )
    )
    side = draw(st.sampled_from(["wall", "periodic"]))
    boundaries = {"left": side, "right": side}
    if open_sides and side == "wall":
        boundaries = {
            "left": draw(st.sampled_from(["wall", "outflow", "inflow"])),
            "right": draw(st.sampled_from(["wall", "outflow"])),
        }
        if boundaries["left"] == "inflow":
            speed = draw(st.floats(-0.5, 2.0))
            boundaries["inflow"] = {
                "thickness": draw(st.floats(0.005, 0.1)),
                "velocity": {"profile": "plug", "speed": speed},
            }
    initial = [
        {"shape": "rectangle", "x_min": start, "x_max": start + width, "height": draw(st.floats(0.01, 0.2))}
    ]
    if draw(st.booleans()):
        initial.insert(0, {"shape": "layer", "thickness": draw(st.floats(0.001, 0.02))})
    return scenario(
        slope_deg=draw(st.floats(0.0, 35.0)),
        domain={"x_min": 0.0, "x_max": length, "cells": cells, "layers": layers},
        rheology=rheology,
        base=[{"condition": draw(st.sampled_from(["no_slip", "free_slip"]))}],
        initial=initial,
        boundaries=boundaries,
    )


def _step_checking_the_state(sim: Simulation, steps: int) -> None:
    """``steps`` steps, each leaving h >= 0 and h, u finite."""
    for _ in range(steps):
        sim.step()
        assert np.all(sim.h >= 0.0) and np.isfinite(sim.h).all() and np.isfinite(sim.u).all()


@pytest.mark.parametrize("examples", EXAMPLES)
def test_engine_invariants_on_random_small_closed_scenarios(examples):
    """h >= 0 and finite, u finite, mass conserved to round-off on a closed domain."""

    @_settings(examples, suppress_health_check=[HealthCheck.too_slow])
    @given(closed_scenarios())
    def check(sc):
        sim = Simulation(sc)
        mass0 = sim.diagnostics()["mass"]
        _step_checking_the_state(sim, 12)
        assert sim.diagnostics()["mass"] == pytest.approx(mass0, rel=1e-13, abs=0)

    check()


@pytest.mark.parametrize("examples", EXAMPLES)
def test_mass_balances_the_boundary_fluxes_on_random_open_scenarios(examples):
    """mass(t) = mass(0) + the net mass through the boundaries to round-off, with outflow and
    (sub- or supercritical, even reversed) inflow sides, and h >= 0, finite."""

    @_settings(examples, suppress_health_check=[HealthCheck.too_slow])
    @given(closed_scenarios(open_sides=True))
    def check(sc):
        sim = Simulation(sc)
        mass0 = sim.diagnostics()["mass"]
        _step_checking_the_state(sim, 12)
        mass = sim.diagnostics()["mass"]
        assert abs(mass - mass0 - sim.net_inflow) <= 1e-12 * max(mass0, mass)

    check()


def _block(slope, length, mu_s, nu, start, width, height, sides=("periodic", "periodic"), layer=None):
    """A scenario of ``closed_scenarios``: 8 cells x 1 layer, a Drucker-Prager block."""
    initial = [{"shape": "rectangle", "x_min": start, "x_max": start + width, "height": height}]
    return scenario(
        slope_deg=slope,
        domain={"x_min": 0.0, "x_max": length, "cells": 8, "layers": 1},
        rheology={"name": "drucker_prager", "mu_s": mu_s, "nu": nu},
        base=[{"condition": "no_slip"}],
        initial=([{"shape": "layer", "thickness": layer}] if layer else []) + initial,
        boundaries={"left": sides[0], "right": sides[1]},
    )


@pytest.mark.parametrize(
    "sc",
    [
        _block(13.0, 1.875, 0.5, 0.0, 0.0, 0.5, 0.01171875),
        _block(5.0, 2.0, 0.0, 0.03125, 0.0, 0.25, 0.01),
        _block(17.0, 2.0, 0.5, 0.0, 0.0, 0.5, 0.01171875, layer=0.001953125),
        _block(12.0, 1.25, 0.5, 0.0, 0.25, 0.5, 0.125),
        _block(16.0, 2.0, 0.0, 0.03125, 0.0, 0.25, 0.03125, sides=("wall", "outflow")),
    ],
)
def test_the_examples_the_wide_search_found(sc):
    """Examples of ``closed_scenarios(open_sides=True)`` on which the thorough search found
    the mass not balanced (as Hypothesis shrank them): a block on 5-17 degrees, each step of
    its state nearly at rest long (0.3-0.7 s), Heun's second stage beyond the Courant
    condition of the waves the step's gravity gave it; the clip of its negative thicknesses
    created 3e-6 to 2e-3 m2.  The step is now redone until that stage meets the condition."""
    sim = Simulation(sc)
    mass0 = sim.diagnostics()["mass"]
    _step_checking_the_state(sim, 12)
    mass = sim.diagnostics()["mass"]
    assert abs(mass - mass0 - sim.net_inflow) <= 1e-12 * max(mass0, mass)


@pytest.mark.parametrize("examples", EXAMPLES)
def test_exact_rest_stays_exact(examples):
    """A uniform layer below its friction angle stays at rest to the last bit."""

    @_settings(examples)
    @given(
        mu_s=st.floats(0.1, 0.9),
        fraction=st.floats(0.0, 0.95),
        layers=st.integers(1, 5),
        thickness=st.floats(0.001, 0.5),
        side=st.sampled_from(["wall", "periodic"]),
    )
    def check(mu_s, fraction, layers, thickness, side):
        slope = math.degrees(math.atan(fraction * mu_s))
        sim = Simulation(
            scenario(
                slope_deg=slope,
                domain={"cells": 12, "layers": layers},
                rheology={"name": "drucker_prager", "mu_s": mu_s, "nu": 0.01},
                base=[{"condition": "no_slip"}],
                initial=[{"shape": "layer", "thickness": thickness}],
                boundaries={"left": side, "right": side},
            )
        )
        h0 = sim.h.copy()
        for _ in range(5):
            sim.step()
        assert np.all(sim.u == 0.0) and np.array_equal(sim.h, h0)

    check()


# ----------------------------------------------------------------------------- scenario loader

_KEYS = ["name", "slope_deg", "domain", "material", "rheology", "initial", "boundaries", "time"]
_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**12), 10**12),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8),
    st.lists(st.integers(-3, 3), max_size=3),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=2),
)


def _paths(node, prefix=()):
    """Every key path of a nested mapping/list."""
    yield prefix
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _paths(value, (*prefix, key))
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from _paths(value, (*prefix, index))


_ALL_PATHS = [p for p in _paths(TINY_SCENARIO) if p]


@st.composite
def mutations(draw):
    """The tiny scenario with a few keys replaced, deleted or added."""
    data = copy.deepcopy(TINY_SCENARIO)
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(_ALL_PATHS))
        node = data
        try:
            for part in path[:-1]:
                node = node[part]
            action = draw(st.sampled_from(["replace", "delete", "add"]))
            if action == "replace":
                node[path[-1]] = draw(_VALUES)
            elif action == "delete" and isinstance(node, dict):
                node.pop(path[-1], None)
            elif isinstance(node, dict):
                node[draw(st.text(min_size=1, max_size=6))] = draw(_VALUES)
        except (KeyError, IndexError, TypeError):
            continue  # an earlier mutation removed or replaced the parent
    return data


@pytest.mark.parametrize("examples", EXAMPLES)
def test_scenario_mutations_load_or_fail_with_input_error(examples):
    """Loading never raises anything but InputError, whatever the values (in-process)."""
    from multilayer.app import resources
    from multilayer.errors import InputError

    @_settings(examples, examples * 8)
    @given(mutations())
    def check(data):
        try:
            loaded = from_dict(data)
            resources.check(loaded, None, resources.Budget(memory=2**30, output=2**30))
            Simulation(loaded)  # what validates and fits must also build
        except InputError as exc:
            assert str(exc)

    check()


@pytest.mark.parametrize(  # 5 s of CPU; the in-process mutations run by default
    "examples", [pytest.param(6, id="quick", marks=pytest.mark.slow), EXAMPLES[1]]
)
def test_validate_of_mutated_files_exits_0_or_2_without_traceback(tmp_path_factory, examples):
    """The command line on mutated files: exit 0 or 2, never a traceback."""
    directory = tmp_path_factory.mktemp("mutations")

    @_settings(examples, max(2, examples // 3))
    @given(st.lists(mutations(), min_size=6, max_size=6))
    def check(datas):
        files = []
        for i, data in enumerate(datas):
            path = directory / f"m{i}.yaml"
            path.write_text(yaml.safe_dump(data, allow_unicode=True))
            files.append(str(path))
        result = subprocess.run(
            [sys.executable, "-m", "multilayer", "validate", *files],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert result.returncode in (0, 2), result.stderr
        assert "Traceback" not in result.stderr

    check()
