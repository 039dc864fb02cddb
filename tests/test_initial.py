"""Initial conditions (docs/scenarios.md): stacked thicknesses and velocity profiles."""

from __future__ import annotations

import numpy as np
import pytest
from engine import simulation

from multilayer.errors import InputError


def test_entries_stack_and_carry_their_own_velocity():
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 10, "layers": 10},
        initial=[
            {"shape": "layer", "thickness": 0.1},
            {
                "shape": "rectangle",
                "x_min": 0.0,
                "x_max": 0.45,
                "height": 0.1,
                "velocity": {"profile": "plug", "speed": 2.0},
            },
        ],
    )
    # cell averages: the cell [0.4, 0.5] is half covered by the rectangle
    assert np.allclose(sim.h, np.where(sim.x < 0.4, 0.2, np.where(sim.x < 0.5, 0.15, 0.1)))
    column = sim.u[:, 0]  # h = 0.2: the lower five layers are the bed, at rest
    assert np.all(column[:5] == 0.0) and np.all(column[5:] == 2.0)
    assert np.all(sim.u[:, -1] == 0.0)


def test_linear_and_bagnold_profiles_at_the_layer_centres():
    common = {"domain": {"x_min": 0.0, "x_max": 1.0, "cells": 2, "layers": 20}}
    linear = simulation(
        initial=[
            {
                "shape": "layer",
                "thickness": 0.02,
                "velocity": {"profile": "linear", "shear_rate": 70.0, "from_height": 0.005},
            }
        ],
        **common,
    )
    z = linear.sigma * 0.02
    assert np.allclose(linear.u[:, 0], 70.0 * np.maximum(z - 0.005, 0.0), rtol=1e-14, atol=0)
    bagnold = simulation(
        initial=[
            {"shape": "layer", "thickness": 0.02, "velocity": {"profile": "bagnold", "surface_speed": 0.3}}
        ],
        **common,
    )
    assert np.allclose(bagnold.u[:, 0], 0.3 * (1 - (1 - z / 0.02) ** 1.5), rtol=1e-14, atol=0)


def test_piecewise_linear_thickness_and_bed():
    sim = simulation(
        domain={"x_min": 0.0, "x_max": 4.0, "cells": 4},
        bed={"points": [[0.0, 1.0], [4.0, 0.0]]},
        initial=[{"shape": "profile", "points": [[0.0, 0.0], [2.0, 1.0], [4.0, 0.0]]}],
    )
    assert sim.x == pytest.approx([0.5, 1.5, 2.5, 3.5])
    assert sim.h == pytest.approx([0.25, 0.75, 0.75, 0.25])
    assert sim.bed == pytest.approx([0.875, 0.625, 0.375, 0.125])


def test_geometric_layers_refine_towards_the_bed():
    sim = simulation(domain={"layers": 5, "layer_fractions": {"geometric": 1.5}})
    l = sim.fractions
    assert l.sum() == pytest.approx(1.0)
    assert np.allclose(l[1:] / l[:-1], 1.5)
    assert sim.mesh.grid.numberOfCells == 5 * sim.h.size


def test_a_layer_of_thickness_zero_is_no_layer():
    """An erodible bed of 0 mm is the rigid bed: the same state as without the entry, so
    one sweep over the bed thickness can start at 0 (scenarios/sweeps/erodible_bed.yaml)."""
    column = {"shape": "rectangle", "x_min": 0.0, "x_max": 0.45, "height": 0.1}
    domain = {"x_min": 0.0, "x_max": 1.0, "cells": 10, "layers": 4}
    bare = simulation(domain=domain, initial=[column])
    zero = simulation(domain=domain, initial=[{"shape": "layer", "thickness": 0.0}, column])
    np.testing.assert_array_equal(zero.h, bare.h)
    np.testing.assert_array_equal(zero.u, bare.u)


def test_the_erodible_bed_sweep_runs_from_the_rigid_bed_to_5_mm():
    from pathlib import Path

    from multilayer.app import sweep

    members = sweep.load(Path(__file__).parents[1] / "scenarios" / "sweeps" / "erodible_bed.yaml").members()
    assert [m.values["initial.0.thickness"] for m in members] == [0.0, 0.001, 0.002, 0.003, 0.004, 0.005]


@pytest.mark.parametrize("cells", [37, 400, 2501])
def test_initial_mass_equals_the_shape_mass_to_round_off_at_every_resolution(cells):
    """Cell averages integrate every shape exactly: the mass does not depend on the mesh.

    A rectangle whose edges fall inside cells, a triangle-and-plateau profile with an
    end step and an erodible layer: their exact masses are 0.37 * 0.013, the trapezoid
    sums of the profile and 0.002 * (x_max - x_min)."""
    profile = [[0.512, 0.0], [0.6173, 0.021], [0.8, 0.021], [0.9071, 0.004]]
    sim = simulation(
        domain={"x_min": -0.1, "x_max": 1.3, "cells": cells, "layers": 2},
        initial=[
            {"shape": "layer", "thickness": 0.002},
            {"shape": "rectangle", "x_min": 0.0131, "x_max": 0.3831, "height": 0.013},
            {"shape": "profile", "points": profile},
        ],
    )
    px, ph = np.array(profile).T
    exact = 0.002 * 1.4 + 0.37 * 0.013 + float(np.sum(np.diff(px) * (ph[1:] + ph[:-1]) / 2))
    assert sim.diagnostics()["mass"] == pytest.approx(exact, rel=1e-13, abs=0)


def test_material_outside_the_domain_names_the_entry():
    with pytest.raises(InputError, match=r"initial\.1 \(rectangle.*lie outside the domain"):
        simulation(
            domain={"x_min": 0.0, "x_max": 1.0, "cells": 10},
            initial=[
                {"shape": "layer", "thickness": 0.01},
                {"shape": "rectangle", "x_min": 0.9, "x_max": 1.2, "height": 0.1},
            ],
        )


@pytest.mark.parametrize("height", [1e-7, 1e-320])
def test_material_nowhere_thicker_than_the_dry_threshold_is_refused(height, tmp_path):
    """A column of 1e-7 m (below ``numerics.dry_threshold``, 1e-6 m) on a slope steeper than
    its friction stayed at rest, and the run completed, its front NaN: the engine holds a
    dry column at rest.  Refused by the simulation and by ``validate``; with an inflow,
    which brings material over it, and without material, it is no error."""
    import yaml
    from conftest import TINY_SCENARIO

    from multilayer.app import cli

    thin = {**TINY_SCENARIO, "initial": [{**TINY_SCENARIO["initial"][0], "height": height}]}
    with pytest.raises(InputError, match=r"initial: at most .* m thick on the mesh, not above numerics.dry_"):
        simulation(initial=[{"shape": "layer", "thickness": height}])
    (tmp_path / "thin.yaml").write_text(yaml.safe_dump(thin))
    assert cli.main(["validate", str(tmp_path / "thin.yaml")]) == 2
    simulation(initial=[{"shape": "layer", "thickness": 0.0}])
    inflow = {
        "left": "inflow",
        "right": "outflow",
        "inflow": {"thickness": 0.01, "velocity": {"profile": "plug", "speed": 1.0}},
    }
    simulation(initial=[{"shape": "layer", "thickness": height}], boundaries=inflow)


def test_material_narrower_than_a_cell_names_the_entry():
    with pytest.raises(InputError, match=r"initial\.0 \(rectangle.*narrower than one cell.*at least 250"):
        simulation(
            domain={"x_min": 0.0, "x_max": 1.0, "cells": 10},
            initial=[{"shape": "rectangle", "x_min": 0.501, "x_max": 0.505, "height": 0.1}],
        )
