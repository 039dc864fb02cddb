"""The compiled map of the mixture's local step (engine/mixture/local_kernel.py) against its
numpy reference (engine/mixture/local_step.py): in columns of one layer under the built-in
dilatant law the local step with the kernel gives the reference's result bit for bit (the
same operations in the same order), loose and dense, with and without a compressibility,
at rest (``u == 0.0`` and ``h' == h*`` exactly), at a front that needs sub-steps and where
the kernel hands a trial back to the numpy map; a law without the compiled form (a
third-party law, a subclass that redefines a mixture method) and columns of several layers
run on the numpy path."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from multilayer.engine.config import MixtureConfig
from multilayer.engine.mixture import local_kernel
from multilayer.engine.mixture.local_step import LocalResult, LocalStep
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
"""A front column of a loose column of millimetre beads in water whose step needs sub-steps
(tests/test_mixture_continuation.py)."""


def both(local: LocalStep, *args, **kwargs) -> tuple[LocalResult, LocalResult]:
    """The local step with the compiled map and with the numpy reference alone."""
    assert local.form is not None
    compiled = local(*args, **kwargs)
    reference = LocalStep.__new__(LocalStep)
    reference.__dict__.update(local.__dict__, form=None)
    return compiled, reference(*args, **kwargs)


def identical(a: LocalResult, b: LocalResult) -> None:
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
def test_the_compiled_map_gives_the_reference_bit_for_bit(packing, compressibility, fluid, grains):
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
        assert first.iterations == again.iterations
        guess = both(local, solid, h, u, dt, first.u, first.pore_pressure, previous=previous)
        identical(*guess)


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


def test_a_front_in_sub_steps_gives_the_reference_bit_for_bit():
    """The front column whose step diverges in one step and converges in sub-steps."""
    local = LocalStep(WATER, LAW, BEADS, np.array([1.0]), 9.81, 1e-10, 200)
    h, phi, v, dt = FRONT
    compiled, reference = both(local, np.array([[phi * h]]), np.array([h]), np.array([[v]]), dt)
    identical(compiled, reference)
    assert compiled.iterations == reference.iterations and compiled.h[0] > h


def test_a_trial_the_kernel_hands_back_is_evaluated_by_the_reference(monkeypatch):
    """A thin loose column of 1 cm gravel moving fast over a long step, whose iteration tries
    a ratio ``z`` no thickness with pores has: the kernel hands that trial to the numpy map,
    and the step is the reference's bit for bit."""
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
    assert False in answers and True in answers


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
