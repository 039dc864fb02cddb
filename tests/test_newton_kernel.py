"""The compiled vertical step (Newton model and exact solve fused per column) against the
numpy iteration of vertical_step.implicit_step with the plugins' own numpy laws."""

from __future__ import annotations

import numpy as np
import pytest
from engine import simulation

from multilayer.engine.plugin_output import PluginOutputError
from multilayer.engine.vertical import forms as viscous_law
from multilayer.engine.vertical import newton_kernel
from multilayer.plugins.builtins import DruckerPrager, JopMuI, PouliquenForterre, PowerLawMuI, WallFriction
from multilayer.plugins.contract import Material, Rheology

MATERIAL = Material(density=1550.0, grain_diameter=0.7e-3, particle_density=2500.0)
LAWS = [
    JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279),
    JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279, mu_inf=0.05),
    PowerLawMuI(mu_s=0.38, m=0.3, alpha=0.5),
    PowerLawMuI(mu_s=0.38, m=0.3, alpha=1.5),
    DruckerPrager(mu_s=0.5, nu=1e-3),
    WallFriction(mu_w=0.3),
]


def test_the_kernels_read_every_parameter_of_every_form():
    """``forms.as_tuple`` (the parameters the Newton kernel hands the forms) holds all
    ``PARAMETERS`` of ``forms.parameters``, and every form fits in them: a form with more
    would have its last parameters dropped."""
    values = viscous_law.parameters(np.arange(1.0, viscous_law.PARAMETERS + 1.0))
    assert viscous_law.as_tuple(values) == tuple(values)
    assert all(form.parameters <= viscous_law.PARAMETERS for form in viscous_law.FORMS.values())
    assert viscous_law.parameters([2.0]).tolist() == [2.0] + [0.0] * (viscous_law.PARAMETERS - 1)


def _form(law):
    """(code, parameters) of the law's compiled viscosity form, the parameters a tuple, as
    the kernels hand them to the forms (``forms.as_tuple``)."""
    form, params = viscous_law.law_of(law, MATERIAL)
    return form, tuple(params)


def _pressure_parts(form, params, pressure, h=0.01):
    """(factor, offset) per pressure, of the compiled form's pressure parts."""
    factor, offset = np.empty(pressure.size), np.empty(pressure.size)
    viscous_law._pressure_parts(form, params, pressure, h, factor, offset, 0)
    return list(zip(factor, offset))


ETA = MATERIAL.density * 1e-3
"""The viscosity of :class:`_Declared` (Pa s): its kinematic viscosity ``nu`` times the density."""


class _Declared(DruckerPrager):
    """Drucker-Prager declaring the compiled form ``form`` for its viscosity."""

    name = "declared"

    def __init__(self, form: tuple):
        super().__init__(mu_s=0.5, nu=1e-3)
        self.form = form

    def viscosity_kernel(self, material):
        return self.form


@pytest.mark.parametrize(
    ("form", "where"),
    [
        (("constant", (100 * ETA,)), "at pressure 0 Pa, shear rate 0.001 1/s"),  # 100 times its eta
        (("inertial", (1.0, 1.0, 1.0)), "at pressure 0 Pa, shear rate 0.001 1/s"),  # another law
        (("constant", (ETA * (1 + 1e-6),)), "at pressure 0 Pa, shear rate 0.001 1/s"),  # beyond round-off
    ],
    ids=["100-times", "another-form", "one-part-in-a-million"],
)
def test_a_compiled_form_that_is_not_the_plugins_viscosity_stops_naming_it(form, where):
    """A declared form other than the plugin's ``viscosity`` computed the compiled step
    with it: a ``constant`` form of 100 times ``nu`` gave another flow, silently.  The form
    is held equal to ``viscosity`` at the sample points first (``forms.SAMPLES``), and a
    difference names the plugin, the form, the point and both values; the built-in laws'
    forms, including the ``inertial_plateau`` form whose viscosity differs from the
    plugin's by round-off amplified near its plateau, pass."""
    with pytest.raises(
        PluginOutputError, match="declares the compiled form .* which is not its viscosity"
    ) as caught:
        viscous_law.law_of(_Declared(form), MATERIAL)
    assert where in str(caught.value) and "rheology plugin 'declared'" in str(caught.value)
    assert viscous_law.law_of(_Declared(("constant", (ETA,))), MATERIAL)[0] == viscous_law.CONSTANT
    for law in [*LAWS, PouliquenForterre(mu_1=0.3, mu_2=0.6, L=1e-3, I_0=0.3)]:
        assert viscous_law.law_of(law, MATERIAL) is not None


@pytest.mark.parametrize("law", LAWS, ids=lambda law: f"{law.name}")
def test_compiled_viscosity_is_the_plugin_viscosity(law):
    rng = np.random.default_rng(0)
    rate = np.concatenate([[0.0, 1e-9], 10.0 ** rng.uniform(-8, 3, 200)])
    pressure = np.concatenate([[0.0, -1.0], 10.0 ** rng.uniform(-3, 4, 200)])
    form, params = _form(law)
    parts = _pressure_parts(form, params, pressure)
    got = np.array(
        [viscous_law._viscosity_and_slope(form, params, r, *part)[0] for r, part in zip(rate, parts)]
    )
    np.testing.assert_allclose(got, law.viscosity(rate, pressure, MATERIAL), rtol=1e-14, atol=0.0)


@pytest.mark.parametrize("law", LAWS, ids=lambda law: f"{law.name}")
def test_compiled_slope_is_the_derivative_of_the_plugin_stress(law):
    """The slope of the Newton model, d(eta gamma)/d gamma, against a centred difference
    of the plugin's own stress eta(gamma, p) gamma (away from the kink of a rate floor)."""
    rng = np.random.default_rng(1)
    rate = 10.0 ** rng.uniform(-6, 3, 300)
    pressure = 10.0 ** rng.uniform(-3, 4, 300)
    form, params = _form(law)
    if form == viscous_law.FORMS["power"]:
        keep = np.abs(rate / params[3] - 1.0) > 1e-4
        rate, pressure = rate[keep], pressure[keep]
    step = 1e-6 * rate

    def stress(r):
        return law.viscosity(r, pressure, MATERIAL) * r

    centred = (stress(rate + step) - stress(rate - step)) / (2.0 * step)
    parts = _pressure_parts(form, params, pressure)
    got = np.array(
        [viscous_law._viscosity_and_slope(form, params, r, *part)[1] for r, part in zip(rate, parts)]
    )
    np.testing.assert_allclose(got, centred, rtol=1e-7, atol=1e-12 * np.abs(centred).max())


def test_a_law_without_a_compiled_form_keeps_the_numpy_path():
    class Plain(Rheology):
        name = "plain"

    assert viscous_law.law_of(Plain(), MATERIAL) is None
    sim = simulation(rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279})
    assert sim.vertical.compiled.laws() is not None
    sim.vertical.stresses.bulk = Plain()  # swapped on a running simulation: honoured
    assert sim.vertical.compiled.laws() is None


@pytest.mark.parametrize(
    "rheology, walls",
    [
        ({"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279}, None),
        (
            {"name": "power_law_mu_i", "mu_s": 0.38, "m": 0.3, "alpha": 0.5},
            {"name": "wall_friction", "mu_w": 0.2},
        ),
    ],
)
def test_compiled_step_equals_the_numpy_iteration_on_a_collapse(rheology, walls):
    """A collapse on a slope that partly stops: the same velocities to round-off and the
    same layers exactly at rest."""
    runs = []
    for compiled in (False, True):
        sim = simulation(
            slope_deg=20.0,
            domain={"x_min": 0.0, "x_max": 1.0, "cells": 60, "layers": 6, "width": 0.1},
            material={"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
            rheology=rheology,
            walls=walls,
            base=[{"condition": "no_slip"}],
            initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.2, "height": 0.1}],
            boundaries={"left": "wall", "right": "outflow"},
        )
        assert sim.vertical.compiled.laws() is not None
        if not compiled:
            sim.vertical.compiled = None
        for _ in range(60):
            sim.step()
        runs.append(sim)
    ref, got = runs
    # the slopes differ (exact in the kernel, a forward difference of relative step 1e-7 in
    # numpy): the fixed points are the same, but a step's last iteration can fall either side
    # of the threshold.  Each path stops within the threshold of the exact step (the error
    # bound of newton_control), so their velocities differ by at most twice the threshold
    # at each step; through the transport (Courant numbers < 1) the thickness by less than
    # 2 x 60 thresholds relative to the velocity scale.
    assert abs(got.newton_iterations - ref.newton_iterations) <= 0.01 * ref.newton_iterations
    threshold = ref.numerics.tolerance * ref.vertical.velocity_scale
    np.testing.assert_allclose(got.h, ref.h, rtol=120 * threshold / ref.vertical.velocity_scale, atol=0.0)
    np.testing.assert_allclose(got.u, ref.u, rtol=0.0, atol=2 * threshold)
    assert np.array_equal(got.u == 0.0, ref.u == 0.0)
    assert (ref.u == 0.0).any() and (ref.u != 0.0).any()  # both static and moving layers


@pytest.mark.slow  # compiles the parallel variant of the kernel
def test_threads_cut_the_columns_into_chunks_without_changing_the_answer():
    sim = simulation(
        slope_deg=20.0,
        domain={"x_min": 0.0, "x_max": 1.0, "cells": 50, "layers": 6},
        material={"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
        rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279},
        base=[{"condition": "no_slip"}],
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 0.5, "height": 0.1}],
    )
    for _ in range(5):
        sim.step()
    ustar = sim.u + 0.01 * (sim.h > 0)
    kw = dict(threshold=1e-12, max_iterations=200)
    one, its_one = sim.vertical.compiled(sim.h, ustar, sim.u, 1e-3, threads=1, **kw)
    one = one.copy()
    two, its_two = sim.vertical.compiled(sim.h, ustar, sim.u, 1e-3, threads=2, **kw)
    assert np.array_equal(one, two) and np.array_equal(its_one, its_two)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled", "numpy"])
def test_a_layer_at_rest_below_its_friction_angle_is_not_solved_and_stays_exactly_at_rest(compiled):
    """A guess at rest within the error bound is the answer (newton_control): a mu(I)
    layer at rest on a slope below its friction angle (tan 10 deg < mu_s = 0.38) takes no
    column solve and stays exactly at rest; above it (30 deg) every column is solved and
    moves."""
    for slope, moves in ((10.0, False), (30.0, True)):
        sim = simulation(
            slope_deg=slope,
            domain={"x_min": 0.0, "x_max": 1.0, "cells": 20, "layers": 6},
            material={"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
            rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279},
            base=[{"condition": "no_slip"}],
            initial=[{"shape": "layer", "thickness": 0.01}],
            boundaries={"left": "wall", "right": "wall"},
        )
        solves = [0]
        if compiled:
            solved = sim.vertical.compiled
        else:
            sim.vertical.compiled, exact = None, sim.vertical.solver

            def counted(problem, solves=solves, exact=exact, **kw):
                solves[0] += problem.m.shape[1]
                return exact(problem, **kw)

            sim.vertical.solver = counted
        for _ in range(5):
            sim.step()
        if compiled:
            solves[0] = solved.solves
        if moves:
            assert np.all(sim.u != 0.0) and solves[0] >= 5 * sim.h.size
        else:
            assert np.all(sim.u == 0.0) and solves[0] == 0


def _rescues(problem, spoil) -> tuple[int, int]:
    """Columns of ``problem`` whose structure ``spoil(exact column)`` the active set rejects,
    and of those the ones ``newton_kernel._other_structures`` rescues, each checked to be
    the exact minimiser (the dynamic programme's answer) with the same static layers."""
    from multilayer.engine.vertical import column_solve as column_kernel

    exact = column_kernel.solve(problem, guess=np.full(problem.shape, np.nan))  # dynamic programme
    L = problem.shape[0]
    work = [np.empty(L + 1, np.int64), np.empty(L, np.bool_), *(np.empty(L) for _ in range(4))]
    work.append(np.empty(2, np.int64))  # the hint of a rejection
    rejected = rescued = 0
    for col in range(problem.shape[1]):
        inertia = problem.m[:, col] / problem.dt
        momentum = inertia * problem.ustar[:, col]
        parts = (problem.kappa, problem.c, problem.w, problem.cw)
        coefficients = [np.ascontiguousarray(a[:, col]) for a in parts]
        top = np.abs(exact[:, col]).max()
        spoilt = spoil(exact[:, col].copy(), coefficients[0])
        u = np.empty(L)
        if column_kernel._active_set(inertia, momentum, *coefficients, spoilt, u, *work):
            continue
        rejected += 1
        if newton_kernel._other_structures(
            inertia, momentum, *coefficients, spoilt, problem.ustar, col, np.empty(L), u, *work
        ):
            rescued += 1
            assert np.abs(u - exact[:, col]).max() <= 1e-11 * max(top, 1.0)
            assert np.array_equal(u == 0.0, exact[:, col] == 0.0)
    return rejected, rescued


def test_a_structure_spoilt_by_round_off_is_rescued_exactly_without_the_dynamic_programme():
    """Where the active set rejects the structure of an iterate, the structures proposed
    next (the velocities before the step; the iterate with its round-off speeds and jumps
    closed) are checked for optimality by the active set itself: a rescued solve is the
    exact minimiser, the dynamic programme's answer, with the same static layers.  The
    iterates here are exact answers with jumps of 1e-13 of the top speed added across
    their locked interfaces and static layers, which the first attempt rejects."""
    from test_column_kernel import random_problem

    rng = np.random.default_rng(7)

    def spoil(u, kappa):
        locked = np.diff(u, prepend=0.0) == 0  # static layers and plugs
        return u + 1e-13 * np.abs(u).max() * rng.choice([-1.0, 1.0], u.size) * locked

    rejected, rescued = _rescues(random_problem(rng, 12, 400), spoil)
    assert rejected > 100 and rescued > 0.9 * rejected


def test_a_plug_edge_moved_by_one_interface_is_repaired_exactly_without_the_dynamic_programme():
    """Columns without walls whose iterate is the exact answer with one interface changed:
    a locked one opened (a jump of 1e-6 of the top speed) or a yielded one locked, as when
    the edge of a plug moves by a layer between Newton iterates (under a non-hydrostatic
    pressure, several plugs per column).  The active set rejects the structure and hints
    the interface to change back (the primal-dual active set update): the repaired
    structure is the exact minimiser, the dynamic programme's answer, with the same static
    layers.  One violation changed at a time is not sure to end (a primal-dual update of one
    interface can cycle, as in 1 of these 300 columns, whose random coefficients are far
    from a flow's): such a column goes on to the programme, still exact."""
    from test_column_kernel import random_problem

    from multilayer.engine.vertical.problem import ColumnProblem

    rng = np.random.default_rng(11)
    p = random_problem(rng, 16, 300)
    p = ColumnProblem(m=p.m, ustar=p.ustar, dt=p.dt, kappa=p.kappa, c=p.c, w=0 * p.w, cw=0 * p.cw)

    def spoil(u, kappa):
        i = rng.choice(np.flatnonzero(kappa > 0.0))
        below = u[i - 1] if i > 0 else 0.0
        jump = 1e-6 * np.abs(u).max() * rng.choice([-1.0, 1.0]) if u[i] == below else 0.0
        u[i + 1 :] += below + jump - u[i]
        u[i] = below + jump
        return u

    rejected, rescued = _rescues(p, spoil)
    assert rejected > 100 and rejected - rescued <= rejected // 100


def test_a_layer_released_from_rest_is_solved_without_the_dynamic_programme():
    """The onset of a flow: a uniform mu(I) layer (1 cm, 64 layers) at rest on a slope
    steeper than its friction angle (tan 24 deg > mu_s = 0.38).  The first iterate at rest
    and the velocities after transport propose structures the active set rejects (the
    column is held at rest, or slides rigidly); the trial structure of the column held at
    rest (every interface where the force of the layers above exceeds the yield stress
    slides) is the exact one: no solve falls back to the O(L^2) dynamic programme, the
    first step takes at most 12 Newton iterations in its two vertical steps, and the
    velocities are those of the
    numpy iteration, whose exact solver takes the dynamic programme there."""
    runs = []
    for compiled in (True, False):
        sim = simulation(
            slope_deg=24.0,
            domain={"x_min": 0.0, "x_max": 0.04, "cells": 20, "layers": 64},
            material={"density": 1550.0, "grain_diameter": 0.7e-3, "particle_density": 2500.0},
            rheology={"name": "jop_mu_i", "mu_s": 0.38, "mu_2": 0.64, "I_0": 0.279},
            base=[{"condition": "no_slip"}],
            initial=[{"shape": "layer", "thickness": 0.01}],
            boundaries={"left": "periodic", "right": "periodic"},
        )
        if not compiled:
            sim.vertical.compiled = None
        sim.step()
        runs.append(sim)
    fused, plain = runs
    stats = fused.vertical.compiled
    # two vertical steps in the time step (after each transport stage) of 20 columns; the step is redone
    # (it sets every column moving) and solves none of them again: the transport of the uniform layer
    # gives each column the same problem whether its faces move or not (engine/vertical/step.py)
    assert stats.columns == 2 * 20 and stats.fallbacks == 0
    # both vertical steps of the time step and of its redone attempt (1 each, no column solved): measured 6
    assert 0 < fused.newton_iterations <= 12
    assert np.all(fused.u > 0.0) and np.array_equal(fused.u == 0.0, plain.u == 0.0)
    assert np.abs(fused.u - plain.u).max() <= 1e-9 * np.abs(plain.u).max()


@pytest.mark.slow
@pytest.mark.parametrize(("pressure", "share"), [("non_hydrostatic", 50), ("hydrostatic", 300)])
def test_the_dam_break_rarely_needs_the_dynamic_programme(pressure, share):
    """The mu(I) dam break of benchmarks/dam_break.py (g = 1, 200 x 32, to t = 2, order 2):
    under the non-hydrostatic pressure, whose columns hold several plugs whose edges move by
    a layer between Newton iterates, with the repaired structures at most 1 solve in 50
    falls back to the O(L^2) dynamic programme (191 of 1648 without the repairs, 1 in 9);
    under the hydrostatic pressure at most 1 in 300.  Both as before the Newton seeds were
    extrapolated (54 of 3117 and 10 of 3414 solves then; extrapolated layer by layer, which
    breaks the plugs of the seed, 63 of 2853 and 20 of 2985; jump by jump, 29 of 2833 and
    9 of 2968 with up to 8 repairs, 1 of 2847 and 0 of 2980 with up to one per interface).
    Counts, not timings."""
    sim = simulation(
        gravity=1.0,
        domain={"x_min": 0.0, "x_max": 50.0, "cells": 200, "layers": 32},
        material={"density": 1.0, "grain_diameter": 1.0 / 32.0, "particle_density": 1.0},
        rheology={"name": "jop_mu_i", "mu_s": 0.35, "mu_2": 0.56, "I_0": 0.4},
        base=[{"condition": "no_slip"}],
        bed={"points": [[0.0, 0.0], [50.0, -22.5]]},
        initial=[{"shape": "rectangle", "x_min": 0.0, "x_max": 2.0, "height": 1.0}],
        boundaries={"left": "wall", "right": "outflow"},
        time={"end": 2.0, "output_interval": 2.0},
        numerics={"order": 2, "threads": 1},
        model={"pressure": pressure},
    )
    sim.advance(2.0)
    stats = sim.vertical.compiled
    assert stats.solves > 1000 and stats.fallbacks * share <= stats.solves
