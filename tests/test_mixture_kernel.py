"""The compiled map and Newton iteration of the mixture's local step
(engine/mixture/local_kernel.py) against their numpy reference (engine/mixture/local_step.py):
in columns of one layer under the built-in dilatant law the local step with the kernels
gives the reference's result bit for bit, every field and the count of iterations (the same
operations in the same order), loose and dense, with and without a compressibility, at rest
(``u == 0.0`` and ``h' == h*`` exactly), at fronts that need sub-steps or the bracketing of
the pore pressure, at a trial with no thickness, and where the kernels hand a trial or the
whole iteration back to numpy (its messages unchanged); a law without the compiled form (a
third-party law, a subclass that redefines a mixture method) and columns of several layers
run on the numpy path."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from multilayer.engine.config import MixtureConfig
from multilayer.engine.mixture import local_kernel, newton_system
from multilayer.engine.mixture.local_step import LocalResult, LocalStep
from multilayer.errors import RunError
from multilayer.plugins.builtins import DilatantCoulomb
from multilayer.plugins.contract import Material

WATER = MixtureConfig(
    fluid_density=1000.0, fluid_viscosity=1e-3, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
)
VISCOUS = MixtureConfig(
    fluid_density=1041.0, fluid_viscosity=96e-3, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
)
BEADS = Material(density=1830.0, grain_diameter=1e-3, particle_density=2500.0)
FINE = Material(density=1480.0, grain_diameter=160e-6, particle_density=2500.0)
LAW = DilatantCoulomb(delta_deg=22.5, K1=90.5)
FRONT = (8.7566e-4, 0.55758653, 0.26670506, 0.014280705)
"""A front column of a loose column of millimetre beads in water (tests/test_mixture_continuation.py)."""
WANDERING = (7.647190711881705e-4, 0.5575865302959222, 0.2667050642254405, 0.012471397424917822)
"""The same front in a shorter step (tests/test_mixture_continuation.py)."""


def both(local: LocalStep, *args, **kwargs) -> tuple[LocalResult, LocalResult]:
    """The local step with the compiled map and with the numpy reference alone."""
    assert local.form is not None
    compiled = local(*args, **kwargs)
    reference = LocalStep.__new__(LocalStep)
    reference.__dict__.update(local.__dict__, form=None)
    return compiled, reference(*args, **kwargs)


def identical(a: LocalResult, b: LocalResult) -> None:
    assert a.iterations == b.iterations
    for field in dataclasses.fields(LocalResult):
        x, y = getattr(a, field.name), getattr(b, field.name)
        assert np.array_equal(x, y), field.name
        assert np.array_equal(np.signbit(x), np.signbit(y)), field.name


def columns(rng: np.random.Generator, n: int, packing: tuple[float, float]) -> tuple[np.ndarray, ...]:
    """``n`` columns of one layer: solid, thickness, velocities after transport (some at rest)."""
    h = rng.uniform(1e-4, 5e-2, n)
    solid = (rng.uniform(*packing, n) * h)[None]
    u = 10.0 ** rng.uniform(-4.0, 0.0, (1, n)) * rng.choice([-1.0, 1.0, 0.0], (1, n))
    return solid, h, u


@pytest.mark.parametrize("packing", [(0.5, 0.58), (0.59, 0.64)], ids=["loose", "dense"])
@pytest.mark.parametrize("compressibility", [None, 1e-6])
@pytest.mark.parametrize(("fluid", "grains"), [(WATER, BEADS), (VISCOUS, FINE)], ids=["water", "viscous"])
def test_the_compiled_map_gives_the_reference_bit_for_bit(
    packing, compressibility, fluid, grains, iterations
):
    """Random columns, loose and dense, moving either way or at rest, from rest and from a
    guess, with and without a relaxing pore pressure: every field of the result and the
    iterations are the reference's, bit for bit (signs of zeros included)."""
    rng = np.random.default_rng(2016)
    config = dataclasses.replace(fluid, compressibility=compressibility)
    local = LocalStep(config, LAW, grains, np.array([1.0]), 9.81 * np.cos(np.radians(20.0)), 1e-10, 200)
    solid, h, u = columns(rng, 40, packing)
    previous = None if compressibility is None else rng.uniform(-50.0, 50.0, (1, 40))
    for dt in (1e-4, 5e-3):
        first, again = both(local, solid, h, u, dt, x=np.linspace(0.0, 1.0, 40), previous=previous)
        identical(first, again)
        guess = both(local, solid, h, u, dt, first.u, first.pore_pressure, previous=previous)
        identical(*guess)
    assert min(iterations) >= 1


def test_a_column_at_rest_stays_at_rest_exactly():
    """A dense column at rest, held by friction: ``u == 0.0`` and ``h' == h*`` bit for bit,
    the pore pressure zero, with the kernel as in the reference."""
    local = LocalStep(WATER, LAW, BEADS, np.array([1.0]), 9.81 * np.cos(np.radians(10.0)), 1e-10, 200)
    h = np.array([1e-2, 3e-2])
    solid, rest = (0.6 * h)[None], np.zeros((1, 2))
    compiled, reference = both(local, solid, h, rest, 1e-3)
    identical(compiled, reference)
    assert np.all(compiled.u == 0.0) and np.array_equal(compiled.h, h)
    assert np.all(compiled.pore_pressure == 0.0)


def stops(local: LocalStep, column: tuple[float, ...]) -> list[str]:
    """The messages with which the local step of ``column`` stops, with the compiled
    kernels and with the numpy reference alone."""
    h, phi, v, dt = column
    messages = []
    for form in (local.form, None):
        step = LocalStep.__new__(LocalStep)
        step.__dict__.update(local.__dict__, form=form)
        with pytest.raises(RunError) as error:
            step(np.array([[phi * h]]), np.array([h]), np.array([[v]]), dt, x=np.array([0.5]), t=2.0)
        messages.append(str(error.value))
    return messages


@pytest.fixture
def iterations(monkeypatch) -> list[int]:
    """The answers of the compiled Newton iteration (-1: handed back to numpy) in the test."""
    answers, kernel = [], local_kernel.iterate_one_layer

    def counted(*args):
        answers.append(kernel(*args))
        return answers[-1]

    monkeypatch.setattr(local_kernel, "iterate_one_layer", counted)
    return answers


@pytest.mark.parametrize(("column", "max_iterations"), [(FRONT, 3), (WANDERING, 3), (FRONT, 200)])
def test_a_front_in_sub_steps_gives_the_reference_bit_for_bit(column, max_iterations, iterations):
    """The front columns, whose iteration allowed three iterations converges only in 16 and
    32 sub-steps (measured), and in one step when allowed 200: the compiled iteration in
    every sub-step, the reference's result."""
    local = LocalStep(WATER, LAW, BEADS, np.array([1.0]), 9.81, 1e-10, max_iterations)
    h, phi, v, dt = column
    compiled, reference = both(local, np.array([[phi * h]]), np.array([h]), np.array([[v]]), dt)
    identical(compiled, reference)
    assert compiled.h[0] > h and min(iterations) >= 1
    assert (len(iterations) > 1) == (max_iterations == 3)  # sub-steps


def test_a_column_that_fails_in_every_substep_stops_with_the_reference_message(iterations):
    """Allowed one iteration, the front converges in no number of sub-steps: the run stops
    with the reference's message, word for word."""
    local = LocalStep(WATER, LAW, BEADS, np.array([1.0]), 9.81, 1e-10, 1)
    messages = stops(local, FRONT)
    assert messages[0] == messages[1] and "did not converge" in messages[0]
    assert iterations and min(iterations) >= 1


def test_an_iteration_the_kernel_hands_back_is_the_reference_s(iterations):
    """A Darcy drag so large (``kozeny`` 4.4e304) that the closure overflows at some trials:
    the compiled iteration hands those steps back to numpy, whose closure stops the run, in
    every number of sub-steps, with its message."""
    config = dataclasses.replace(WATER, kozeny=4.4e304)
    local = LocalStep(config, LAW, BEADS, np.array([1.0]), 9.81, 1e-10, 200)
    messages = stops(local, FRONT)
    assert messages[0] == messages[1] and "closure overflowed" in messages[0]
    assert -1 in iterations and max(iterations) >= 1


def test_a_trial_with_no_thickness_is_the_reference_s(monkeypatch, iterations):
    """A thin loose column of 1 cm gravel moving fast over a long step, whose iteration tries
    a ratio ``z`` no thickness with pores has: the compiled map hands that trial to the numpy
    map, the compiled iteration evaluates it as the reference's (an infinite residual), and
    the step is the reference's bit for bit."""
    answers, kernel = [], local_kernel.one_layer

    def counted(*args):
        answers.append(kernel(*args))
        return answers[-1]

    config = MixtureConfig(
        fluid_density=1010.0, fluid_viscosity=0.0121, phi_critical=0.582, dilatancy=4.09, critical_shift=25.0
    )
    gravel = Material(density=1830.0, grain_diameter=1e-2, particle_density=2500.0)
    local = LocalStep(config, LAW, gravel, np.array([1.0]), 9.81 * np.cos(np.radians(10.0)), 1e-10, 200)
    h, phi, v, dt = 7.680197180346033e-3, 0.4431605569871282, 2.720385703828752, 0.1537122563744174
    with monkeypatch.context() as patch:
        patch.setattr(local_kernel, "one_layer", counted)
        compiled, reference = both(local, np.array([[phi * h]]), np.array([h]), np.array([[v]]), dt)
    identical(compiled, reference)
    assert answers == [True] and min(iterations) >= 1


class Redefined(DilatantCoulomb):
    """The dilatant law with its mixture yield stress doubled: its compiled form no longer
    describes it."""

    def mixture_yield_stress(self, pressure, mixture, material):
        return 2.0 * super().mixture_yield_stress(pressure, mixture, material)


def test_laws_without_the_compiled_form_and_several_layers_run_on_the_numpy_path():
    """A subclass that redefines a mixture method, a law without the form (the default
    ``mixture_kernel``), and columns of several layers: the numpy path, whose answer for
    the redefined law differs from the built-in's."""
    g_n = 9.81 * np.cos(np.radians(25.0))
    redefined = LocalStep(WATER, Redefined(22.5, 90.5), BEADS, np.array([1.0]), g_n, 1e-10, 200)
    assert redefined.form is None
    plain = LocalStep(WATER, LAW, BEADS, np.array([1.0]), g_n, 1e-10, 200)
    assert plain.form is not None
    solid, h, u = np.array([[0.57e-2]]), np.array([1e-2]), np.array([[0.05]])
    assert not np.array_equal(redefined(solid, h, u, 1e-3).u, plain(solid, h, u, 1e-3).u)
    layers = LocalStep(WATER, LAW, BEADS, np.array([0.5, 0.5]), g_n, 1e-10, 200)
    assert layers.form is not None  # the form is known; the kernel maps columns of one layer only
    two = layers(np.array([[0.29e-2], [0.28e-2]]), h, np.array([[0.02], [0.05]]), 1e-3)
    reference = LocalStep.__new__(LocalStep)
    reference.__dict__.update(layers.__dict__, form=None)
    identical(two, reference(np.array([[0.29e-2], [0.28e-2]]), h, np.array([[0.02], [0.05]]), 1e-3))


def test_the_newton_systems_are_solved_alike_compiled_and_in_numpy_and_solved():
    """The 2 x 2 Newton systems: the compiled elimination answers ``solve_pairs``'s bits
    (whatever LAPACK numpy is built with), over entries of magnitudes 1e-150 to 1e150,
    either pivot, pivots below the least normal float, and not solved where a pivot is zero;
    the answers solve the systems (against ``numpy.linalg.solve``, to round-off times the
    condition number)."""
    rng = np.random.default_rng(1999)
    J = rng.standard_normal((20000, 2, 2)) * 10.0 ** rng.uniform(-150.0, 150.0, (20000, 2, 2))
    b = rng.standard_normal((20000, 2)) * 10.0 ** rng.uniform(-150.0, 150.0, (20000, 2))
    J[:50, 1] = 0.0  # singular: a row of zeros,
    J[50:100, :, 0] = 0.0  # a column of zeros
    J[100:200, :, 0] *= 1e-170  # pivots below numpy.finfo(float).tiny
    solved, x = newton_system.solve_pairs(J, b)
    assert not solved[:100].any() and solved[100:].all()
    for n in range(J.shape[0]):
        compiled = local_kernel.solve_2x2(J[n, 0, 0], J[n, 0, 1], J[n, 1, 0], J[n, 1, 1], b[n, 0], b[n, 1])
        assert compiled[0] == solved[n], n
        if solved[n]:
            assert np.array_equal(np.array(compiled[1:]), x[n]), n
    well = np.linalg.cond(J[200:]) < 1e6
    expected = np.linalg.solve(J[200:][well], b[200:][well][..., None])[..., 0]
    scale = np.abs(expected).max(axis=1, keepdims=True)
    assert np.all(np.abs(x[200:][well] - expected) <= 1e-9 * scale)
