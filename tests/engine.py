"""Building scenarios for the engine tests (not a test module)."""

from __future__ import annotations

import copy
import functools
from typing import Any

import numpy as np

import multilayer
from multilayer.app.simulation import Simulation
from multilayer.scenario import Scenario, from_dict
from multilayer.validation.runs import SCENARIOS

BASE: dict[str, Any] = {
    "name": "engine-test",
    "gravity": 9.81,
    "slope_deg": 0.0,
    "domain": {"x_min": 0.0, "x_max": 10.0, "cells": 100, "layers": 2},
    "material": {"density": 1000.0, "grain_diameter": 1.0e-3},
    "rheology": {"name": "drucker_prager", "mu_s": 0.0, "nu": 0.0},
    "base": [{"condition": "free_slip"}],
    "initial": [],
    "boundaries": {"left": "wall", "right": "wall"},
    "time": {"end": 1.0, "output_interval": 1.0},
}


REPLACED = {"rheology", "walls", "bed"}  # whole mappings, never merged


def _merge(into: dict, changes: dict) -> dict:
    for key, value in changes.items():
        if isinstance(value, dict) and isinstance(into.get(key), dict) and key not in REPLACED:
            _merge(into[key], value)
        else:
            into[key] = value
    return into


def scenario(**changes: Any) -> Scenario:
    """The BASE scenario with nested ``changes`` merged in."""
    return from_dict(_merge(copy.deepcopy(BASE), changes))


def simulation(**changes: Any) -> Simulation:
    return Simulation(scenario(**changes))


def collapse_deposit() -> Simulation:
    """The channel collapse (side walls, non-hydrostatic pressure) at a = 0.5 on a coarse
    mesh (4 mm x 4 layers) with the normal stress: it spreads and stops by t = 0.3 s."""
    return multilayer.Simulation(
        multilayer.load(
            SCENARIOS / "column_collapse_channel.yaml",
            {
                "initial.0.height": 0.025,
                "domain.x_max": 0.2,
                "domain.cells": 50,
                "domain.layers": 4,
                "model.normal_stress": True,
            },
        )
    )


@functools.cache
def _deposit_state() -> dict[str, Any]:
    """The state of :func:`collapse_deposit` at rest at t = 0.3 s (computed once)."""
    sim = collapse_deposit()
    sim.advance(0.3)
    return sim.state_dict()


def deposit_beside_a_collapse() -> tuple[Simulation, slice]:
    """:func:`collapse_deposit` at rest at t = 0.3 s (its deposit over x < 0.096 m) with a
    second column, 12 mm high and 16 mm wide, added at x = 0.168-0.184 m, beyond its dry
    front: the new column collapses and flows for about 0.13 s, a chain of its own, while
    the deposit's chain stays the same: the simulation and the deposit's columns."""
    saved = _deposit_state()
    both = collapse_deposit()
    deposit = slice(0, int(np.flatnonzero(saved["h"] > both.dry)[-1]) + 1)
    h = saved["h"].copy()
    h[42:46] = 0.012
    both.load_state({**saved, "h": h})
    return both, deposit
