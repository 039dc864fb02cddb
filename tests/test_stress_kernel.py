"""The velocity-independent coefficients of the vertical step computed in one compiled pass
(engine/vertical/coefficients.py) against the numpy reference ``StressModel.columns``: the same bits."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from multilayer.engine.basal import BasalColumns
from multilayer.engine.vertical import stresses as stress
from multilayer.engine.vertical.coefficients import CompiledCoefficients, yield_law_of
from multilayer.plugins.builtins import DruckerPrager, JopMuI, PouliquenForterre, PowerLawMuI, WallFriction
from multilayer.plugins.builtins._checks import FrictionalYield
from multilayer.plugins.contract import Material

MATERIAL = Material(density=1550.0, grain_diameter=0.7e-3, particle_density=2500.0)
BULK = {
    "jop_mu_i": JopMuI(mu_s=0.38, mu_2=0.64, I_0=0.279, mu_start=0.45),
    "power_law_mu_i": PowerLawMuI(mu_s=0.38, m=0.3, alpha=0.5),
    "drucker_prager": DruckerPrager(mu_s=0.5, nu=1e-3, mu_start=0.6),
    "pouliquen_forterre": PouliquenForterre(mu_1=0.38, mu_2=0.64, L=0.02, I_0=0.279, mu_3=0.45),
}


def _model(bulk, walls: bool, rng) -> tuple[stress.StressModel, np.ndarray]:
    """A model of 7 layers of unequal thickness over 40 columns, every basal condition
    present; returns it and a thickness with dry columns."""
    N = 40
    fractions = rng.uniform(0.5, 1.5, 7)
    fractions /= fractions.sum()
    kind = rng.choice(["no_slip", "coulomb", "free_slip"], N)
    base = BasalColumns(  # Coulomb friction with a cohesion in some columns
        bulk=kind == "no_slip",
        friction=np.where(kind == "coulomb", rng.uniform(0.2, 0.6, N), 0.0),
        cohesion=np.where(kind == "coulomb", rng.uniform(0.0, 50.0, N) * (rng.uniform(size=N) < 0.5), 0.0),
    )
    model = stress.StressModel(
        bulk, MATERIAL, fractions, 9.81 * np.cos(0.3), base,
        walls=WallFriction(mu_w=0.25) if walls else None, width=0.1 if walls else None,
        x=np.linspace(0.0, 1.0, N),
    )  # fmt: skip
    h = rng.uniform(0.0, 0.2, N) * (rng.uniform(size=N) > 0.2)
    return model, h


@pytest.mark.parametrize("walls", [False, True], ids=["no walls", "walls"])
@pytest.mark.parametrize("name", BULK)
@pytest.mark.parametrize("start_stop", [False, True], ids=["flowing", "layers at rest"])
@pytest.mark.parametrize("gravity", [False, True], ids=["g cos theta", "yield_gravity"])
def test_compiled_coefficients_are_the_numpy_ones_bit_for_bit(name, walls, start_stop, gravity):
    rng = np.random.default_rng(len(name) + 2 * walls + 4 * start_stop + 8 * gravity)
    model, h = _model(BULK[name], walls, rng)
    wet = np.flatnonzero(h > 0)
    L, N = model.l.shape[0], h.size
    rest = rng.uniform(size=(L, N)) < 0.5 if start_stop else None
    # a pressure of the non-hydrostatic kind: sometimes negative (clamped at 0 by the laws)
    yield_gravity = rng.uniform(-2.0, 12.0, (L, N)) if gravity else None
    compiled = CompiledCoefficients(model)
    assert compiled.laws() is not None
    got = compiled(h, wet, rest, yield_gravity)
    ref = model.columns(h, wet, rest, yield_gravity)
    for field in dataclasses.fields(stress.ColumnStresses):
        mine, theirs = getattr(got, field.name), getattr(ref, field.name)
        np.testing.assert_array_equal(mine, theirs, err_msg=field.name)
        assert mine.dtype == theirs.dtype and mine.tobytes() == theirs.tobytes(), field.name  # every bit
    if start_stop:  # the static yield stress was used where both layers were at rest
        static = rest[:, wet] & np.vstack([np.ones((1, wet.size), bool), rest[:-1, wet]])
        assert static[1:].any()
        law = BULK[name]
        mu_start = law.mu_stop(ref.thickness, law.mu_3) if name == "pouliquen_forterre" else law.mu_start
        np.testing.assert_array_equal(
            got.kappa[1:][static[1:]],
            np.broadcast_to(mu_start, static.shape)[1:][static[1:]] * ref.pressure[1:][static[1:]].clip(0),
        )
    # the arrays are reused: a second call with fewer columns gives its own answer
    again = compiled(h, wet[::2], rest, yield_gravity)
    np.testing.assert_array_equal(again.kappa, model.columns(h, wet[::2], rest, yield_gravity).kappa)


def test_a_redefined_yield_stress_keeps_the_plugins_own_methods():
    """A compiled form describes the class that declares it: a subclass (or an instance)
    redefining yield_stress or static_yield_stress below it is called itself."""

    class Doubled(JopMuI):
        def yield_stress(self, pressure, material):
            return 2.0 * super().yield_stress(pressure, material)

    class Stiffer(DruckerPrager):
        def static_yield_stress(self, pressure, material):
            return 3.0 * super().static_yield_stress(pressure, material)

    assert yield_law_of(BULK["jop_mu_i"], MATERIAL) == (0.38, 0.45, 0.0, np.inf)
    assert yield_law_of(WallFriction(0.25), MATERIAL) == (0.25, 0.25, 0.0, np.inf)
    assert yield_law_of(BULK["pouliquen_forterre"], MATERIAL) == (0.38, 0.45, 0.64 - 0.38, 0.02)
    assert yield_law_of(Doubled(0.38, 0.64, 0.279), MATERIAL) is None
    assert yield_law_of(Stiffer(0.5, 1e-3), MATERIAL) is None
    patched = JopMuI(0.38, 0.64, 0.279)
    patched.yield_stress = lambda p, m: np.zeros_like(p)
    assert yield_law_of(patched, MATERIAL) is None
    assert issubclass(Doubled, FrictionalYield)
    # and the coefficients then come from the plugin itself
    rng = np.random.default_rng(3)
    model, h = _model(Doubled(0.38, 0.64, 0.279), False, rng)
    wet = np.flatnonzero(h > 0)
    compiled = CompiledCoefficients(model)
    assert compiled.laws() is None
    np.testing.assert_array_equal(compiled(h, wet).kappa, model.columns(h, wet).kappa)


def test_a_compiled_yield_value_outside_the_contract_is_reported_by_the_numpy_checks():
    """A built-in law given a NaN friction past its validation: the same error, naming the
    plugin, the method, the value and where, as the numpy path."""
    from multilayer.engine.plugin_output import PluginOutputError

    rng = np.random.default_rng(4)
    law = JopMuI(0.38, 0.64, 0.279)
    model, h = _model(law, False, rng)
    law.mu_s = np.nan
    wet = np.flatnonzero(h > 0)
    messages = []
    for columns in (CompiledCoefficients(model), model.columns):
        with pytest.raises(PluginOutputError) as caught:
            columns(h, wet)
        messages.append(str(caught.value))
    assert messages[0] == messages[1]
    assert "'jop_mu_i'" in messages[0] and "yield_stress() returned nan" in messages[0]
