"""The check of the state a step starts from reads what code outside the engine may have
written since the last step, and only that (docs/reliability.md, "state").

The arrays handed out (``sim.h``, ``sim.u``, ``sim.w``, ``sim.q``, ``sim.mixture.solid``,
``sim.mixture.pore_pressure``) are checked at the next step and at every step while a
reference to them or to a view of them lives; ``sim.state`` is checked whole at every
step once given out, a restored state once; read-only views (``sim.read_only``) and the
engine's own reads add nothing.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from conftest import TINY_SCENARIO
from engine import simulation
from test_damaged_results import IMMERSED

from multilayer.engine.state import _Holder
from multilayer.engine.state_check import StateError, _bits, _fine, _finite
from multilayer.errors import InputError, RunError

NON_HYDROSTATIC = {**TINY_SCENARIO, "model": {"pressure": "non_hydrostatic"}}
MIXTURE = {**IMMERSED, "base": [{"condition": "no_slip"}]}
"""A loose grain-fluid mixture released in one layer: 20 cells, wet in the first 4."""


def _reads(sim: Any) -> list[tuple[list[str], tuple[int, int] | None]]:
    """The arrays (by name) and the columns of ``u`` each entry check of ``sim`` reads."""
    reads: list[tuple[list[str], tuple[int, int] | None]] = []
    check = sim.guard.check_entry

    def spied(h, arrays, t, steps, columns=None):
        reads.append((sorted(arrays), columns))
        check(h, arrays, t, steps, columns)

    sim.guard.check_entry = spied
    return reads


def _refused(sim: Any, said: str, array: str) -> None:
    """The next step of ``sim`` raises the :class:`StateError` of its entry check saying
    ``said``, written into ``array``, and keeps the state of the last step."""
    before = sim.state_dict()
    with pytest.raises(StateError) as failure:
        sim.step()
    assert str(failure.value) == (
        f"{said} on entry to the step from t = {before['t']:.6g} s (step {before['steps'] + 1}): not as "
        f"the steps leave it, so written into {array} since the last step"
    )
    assert sim.steps == before["steps"]


def test_what_is_not_handed_out_is_not_read_and_what_is_is_read_while_it_lives():
    """The first step reads every array; reads of a run's writer and checks (read-only
    views, diagnostics, ``state_dict``) add nothing; ``sim.h`` read once adds ``h`` and
    ``u`` (in the moving columns) to the next step only; ``sim.state`` every array to
    every step."""
    sim = simulation(**TINY_SCENARIO)
    reads = _reads(sim)
    sim.step()
    assert reads == [(["h", "q", "u", "w"], None)]
    for _ in range(3):
        sim.read_only("h").sum(), sim.read_only("u").max(), sim.diagnostics(), sim.state_dict()
        sim.check_state()
        sim.step()
    assert len(reads) == 1
    assert sim.h.max() > 0.0  # a temporary: read at the next step only
    sim.step()
    sim.step()
    ((names, (lo, hi)),) = reads[1:]
    assert names == ["h", "u"] and 0 < hi - lo < 40  # u in the moving columns only
    view = sim.read_only("u")
    with pytest.raises(ValueError, match="read-only"):
        view[0, 0] = 1.0
    with pytest.raises(ValueError, match="cannot set WRITEABLE flag"):
        view[:, 1:].flags.writeable = True
    assert sim.state is not None
    sim.step()
    sim.step()
    assert reads[2:] == [(["h", "q", "u", "w"], None)] * 2


@pytest.mark.parametrize(
    ("take", "write", "said", "array"),
    [
        (
            lambda sim: sim.h[1:],
            lambda kept: kept.__setitem__(2, np.nan),
            "thickness h = nan at x = 0.04375 m",
            "sim.h",
        ),
        (
            lambda sim: sim.u.T,
            lambda kept: kept.__setitem__((30, 2), 5.0),
            "velocity u = 5.0 at x = 0.38125 m, layer 3 (1 is at the bed), where there is no material "
            "(h = 0)",
            "sim.u",
        ),
        (
            lambda sim: np.asarray(memoryview(sim.w)),
            lambda kept: kept.__setitem__((0, 30), np.nan),
            "vertical velocity w = nan at x = 0.38125 m, layer 1 (1 is at the bed)",
            "sim.w",
        ),
        (
            lambda sim: sim.q.reshape(-1),
            lambda kept: kept.__setitem__(3, np.inf),
            "non-hydrostatic pressure q = inf at x = 0.04375 m, layer 1 (1 is at the bed)",
            "sim.q",
        ),
    ],
)
def test_a_reference_kept_to_an_array_handed_out_and_written_steps_later_is_named(take, write, said, array):
    """A view of ``sim.h`` (a slice, a transpose, a buffer, a reshape) kept after the array
    itself is gone and written three steps later is named as on main: the array, the cell
    and the layer, the state of the last step kept."""
    sim = simulation(**TINY_SCENARIO)
    sim.step()
    kept = take(sim)
    for _ in range(3):
        sim.step()
    write(kept)
    _refused(sim, said, array)


def test_a_state_refused_on_entry_and_stepped_again_unchanged_is_refused_again():
    """A NaN written into ``sim.h`` (the array not kept) was named on entry to the step;
    stepped again, unchanged, it was taken as the steps left it and named "after
    transport", the transport's doing: a state refused stays to be read at the next step,
    and is named again as written, until it is repaired."""
    sim = simulation(**TINY_SCENARIO)
    sim.step()
    sim.h[3] = math.nan
    for _ in range(2):
        with pytest.raises(
            StateError, match=r"thickness h = nan .* on entry to the step .* written into sim\.h"
        ):
            sim.step()
    sim.h[3] = 0.0
    sim.u[:, 3] = 0.0
    sim.step()
    assert np.isfinite(sim.h).all() and sim.steps == 2


def test_a_thickness_written_to_zero_under_moving_material_is_named_with_u_read_where_it_moves():
    """Only ``h`` handed out: ``u`` is read in the columns the steps left moving, where a
    thickness written to zero leaves a velocity without material (named as a velocity
    written into ``sim.u``, as when every column was read)."""
    sim = simulation(**TINY_SCENARIO)
    for _ in range(3):
        sim.step()
    h = sim.h
    moving = float(sim.read_only("u")[0, 3])
    assert moving != 0.0
    h[3] = 0.0
    said = f"velocity u = {moving!r} at x = 0.04375 m, layer 1 (1 is at the bed), where there is no material"
    _refused(sim, f"{said} (h = 0)", "sim.u")


def test_a_models_fields_handed_out_and_written_later_are_named():
    """A mixture's ``solid`` and ``pore_pressure`` (``sim.mixture``) and the Newton seed of
    the non-hydrostatic pressure (``sim.state.fields``), kept and written two steps later."""
    sim = simulation(**MIXTURE)
    sim.step()
    solid, pressure = sim.mixture.solid, sim.mixture.pore_pressure[0]
    sim.step()
    sim.step()
    solid[0, 2] = -1e-3
    entry = r"on entry to the step from t = .* so written into sim.state.fields\['solid'\] or sim.h since"
    with pytest.raises(RunError, match=r"solid volume s = -0.001 m outside .* " + entry):
        sim.step()
    solid[0, 2] = 0.0
    pressure[15] = np.nan
    said = "pore_pressure = nan at x = 0.3875 m, layer 1 (1 is at the bed)"
    _refused(sim, said, "sim.state.fields['pore_pressure']")
    sim = simulation(**NON_HYDROSTATIC)
    sim.step()
    fields = sim.state.fields
    sim.step()
    sim.step()
    fields["newton_seed"][1, 30] = np.inf
    _refused(
        sim,
        "newton_seed = inf at x = 0.38125 m, layer 2 (1 is at the bed)",
        "sim.state.fields['newton_seed']",
    )


def test_a_restored_state_is_read_whole_and_a_reference_from_before_still_counts():
    """``load_state`` writes every array: the next step reads them all; a solid outside
    ``[0, h]`` is refused by ``load_state`` itself, naming the entry, the state kept (it was
    restored and named by the next step as a write between steps); a view of ``sim.h``
    taken before the restore and written two steps after it is named."""
    sim = simulation(**MIXTURE)
    sim.step()
    saved = sim.state_dict()
    saved["solid"][0, 2] = -1e-3
    with pytest.raises(InputError, match=r"^solid holds -0.001 m at layer 1, column 2, outside \[0, "):
        sim.load_state(saved)
    assert sim.mixture.solid[0, 2] > 0.0
    sim.step()
    sim = simulation(**TINY_SCENARIO)
    sim.step()
    h = sim.h
    sim.load_state(sim.state_dict())
    reads = _reads(sim)
    for _ in range(2):
        sim.step()
    assert [names for names, _ in reads] == [["h", "q", "u", "w"], ["h", "u"]]
    h[30] = -1.0
    _refused(sim, "negative thickness h = -1 m at x = 0.38125 m", "sim.h")


def _shares_the_state(root: Any, state: list[np.ndarray]) -> list[tuple[str, np.ndarray]]:
    """Every array reachable from ``root`` through public attributes, properties, mappings
    and sequences of the package's objects (but ``state``) that shares memory with one of
    ``state``, with its path."""
    found: list[tuple[str, np.ndarray]] = []
    seen: dict[int, Any] = {}  # kept alive: an id is not reused within the walk
    stack = [(root, "sim")]
    while stack:
        obj, path = stack.pop()
        if id(obj) in seen:
            continue
        seen[id(obj)] = obj
        if isinstance(obj, np.ndarray):
            if any(np.shares_memory(obj, array) for array in state):
                found.append((path, obj))
            continue
        if isinstance(obj, dict):
            stack += [(value, f"{path}[{key!r}]") for key, value in obj.items()]
        elif isinstance(obj, list | tuple):
            stack += [(value, f"{path}[{i}]") for i, value in enumerate(obj)]
        elif type(obj).__module__.startswith("multilayer"):
            names = {
                *getattr(obj, "__dict__", ()),
                *(k for k in dir(type(obj)) if isinstance(getattr(type(obj), k), property)),
            }
            stack += [
                (getattr(obj, name), f"{path}.{name}")
                for name in names
                if not name.startswith("_") and name != "state"
            ]
    return found


@pytest.mark.parametrize("scenario", [TINY_SCENARIO, NON_HYDROSTATIC, MIXTURE])
def test_no_public_path_to_the_state_escapes_the_hand_out(scenario):
    """Every array sharing memory with the state that a simulation's public attributes and
    properties reach (the mixture's, the pressure model's, ...) is handed out: recorded
    while it lives, or read-only for good; ``sim.state`` itself is checked whole."""
    sim = simulation(**scenario)
    for steps in (0, 2):  # fresh, and stepped
        for _ in range(steps):
            sim.step()
        found = _shares_the_state(sim, [sim._state.array(name) for name in sim._state.names])
        assert {path for path, _ in found} >= {"sim.h", "sim.u", "sim.w", "sim.q"}
        for path, array in found:
            base = array
            while isinstance(base, np.ndarray):
                base = base.base
            assert isinstance(base, _Holder), path


@pytest.mark.parametrize(
    "replacement",
    [
        lambda a: a.astype(np.float32),  # the transport was blamed for the mass its rounding lost
        np.asfortranarray,  # compiled for anew (10 s)
        lambda a: a.tolist(),  # numba's TypingError
        lambda a: a[:1].copy(),  # a broadcast's ValueError
    ],
)
@pytest.mark.parametrize("name", ["h", "u", "w", "q"])
def test_the_states_arrays_are_written_in_place_not_replaced(name, replacement):
    """``sim.state.u = ...`` rebound the array the kernels take: each replacement failed
    its own way, or ran on.  The state's arrays are refused as replaced, naming them."""
    sim = simulation(**TINY_SCENARIO)
    sim.step()
    with pytest.raises(InputError, match=rf"^state\.{name}: the state's arrays are not replaced; accepted"):
        setattr(sim.state, name, replacement(np.atleast_2d(getattr(sim.state, name))))
    assert sim.state.array(name) is getattr(sim.state, name)
    sim.state.h[...] = sim.state.h  # in place: as before
    sim.step()


def test_the_states_fields_time_and_step_count_are_not_replaced():
    """``sim.state.fields['w'] = ...`` replaced the array in the state's dict (the kernels
    were given another shape or type); ``sim.t = 'a'`` was kept and a ``TypeError`` in the
    next step, ``sim.t = 5.0`` moved the time of a state that was not at it.  Each is an
    InputError naming what sets them; nothing changes."""
    sim = simulation(**TINY_SCENARIO)
    sim.step()
    before = sim.state_dict()
    with pytest.raises(InputError, match=r"^state\.fields\['w'\]: the state's fields are not replaced"):
        sim.state.fields["w"] = sim.state.fields["w"].T.copy()
    with pytest.raises(InputError, match=r"^state\.fields\['q'\]: the state's fields are not replaced"):
        del sim.state.fields["q"]
    for name, value in (("t", "a"), ("t", 5.0), ("steps", 7)):
        with pytest.raises(InputError, match=rf"^sim\.{name} = .*: {name} is read-only"):
            setattr(sim, name, value)
    assert (sim.t, sim.steps) == (before["t"], before["steps"]) and list(sim.state.fields) == ["w", "q"]
    sim.load_state({**before, "t": 0.5, "steps": 3})  # what sets them
    assert (sim.t, sim.steps) == (0.5, 3)
    sim.step()


@pytest.mark.parametrize("value", [0.0, -0.0, 1.5, -1e-300, np.nan, np.inf, -np.inf, 1e308])
@pytest.mark.parametrize("velocity", [0.0, np.nan, np.inf])
def test_the_guards_cheap_path_passes_exactly_the_states_its_numpy_test_passed(value, velocity):
    """``_fine``, the compiled cheap path of ``check_state``: the thicknesses finite and
    not negative and the velocities finite in the columns read, as the numpy reductions it
    replaced (``h.min() >= 0``, ``h.sum()`` finite) with ``_finite`` found them (one
    column's sum overflowing aside: a finite state, passed by the full check after)."""
    h = np.array([0.0, 2.0, value, 1.0])
    u = np.zeros((3, 4))
    u[1, 2] = velocity
    bits = _bits(u)
    numpy_path = h.min(initial=0.0) >= 0.0 and math.isfinite(h.sum()) and _finite(bits, 0, 4)
    assert _fine(h, bits, 0, 4) == numpy_path
    assert _fine(h, bits, 0, 2) == (h.min(initial=0.0) >= 0.0 and math.isfinite(h.sum()))
