"""Transport of the solid volume per layer with the mixture's own volume fluxes.

The transport in x (``engine/transport``) moves the mixture volume ``h`` with face fluxes
that it does not return; their sum over a step is recovered exactly from the change of
``h`` and the flux through the left end face, ``F_{i+1/2} = F_{1/2} - dx sum_{j<=i}
(h_j^{n+1} - h_j^n)``.  The solid of layer ``a`` crosses a face with the volume
fraction of the upwind cell, ``phi_a F_a``, where the share ``F_a`` of layer ``a`` is its
share of the upwind column's discharge ``l_a |u_a| / sum_b l_b |u_b|`` (``l_a`` at rest);
the exchange between layers that keeps ``h_a = l_a h`` carries the solid of the layer the
volume leaves (as the momentum exchange ``G`` of Fernández-Nieto et al. 2016).  Both are
differences of the same face and interface values, so ``sum_i sum_a s_a dx`` changes only
by the solid through the two end faces: exact conservation of the solid, and a uniform
``phi`` stays uniform.  The fluid of the mixture, ``l_a h - s_a``, is the complement.
"""

from __future__ import annotations

import numpy as np

from multilayer.engine.mixture.closure import DENSEST_PACKING
from multilayer.errors import RunError


def face_volumes(h_old: np.ndarray, h_new: np.ndarray, left_volume: float, dx: float) -> np.ndarray:
    """Mixture volume (m^2 per unit width) through each of the ``N + 1`` faces during a
    step, positive in +x, from the change of ``h`` and the volume through the left face."""
    faces = np.empty(h_old.size + 1)
    faces[0] = 0.0
    np.cumsum(h_new - h_old, out=faces[1:])
    return left_volume - dx * faces


def transport(
    solid: np.ndarray,
    h_old: np.ndarray,
    h_new: np.ndarray,
    u: np.ndarray,
    fractions: np.ndarray,
    crossed: np.ndarray,
    dx: float,
    periodic: bool,
) -> tuple[np.ndarray, np.ndarray]:
    """The solid per layer ``s_a`` (L, N) after the transport step from ``h_old`` to
    ``h_new`` (velocities ``u`` (L, N) at its start, ``crossed`` (2,) the mixture volume
    through the end faces), and the solid through the two end faces (2,), positive in +x."""
    l = fractions[:, None]
    wet = h_old > 0.0
    phi = np.where(wet, solid / np.where(wet, l * h_old, 1.0), 0.0)
    speed = l * np.abs(u)
    discharge = speed.sum(axis=0)
    share = np.where(discharge > 0.0, speed / np.where(discharge > 0.0, discharge, 1.0), l)
    volumes, donor, phi = _upwind(phi, h_old, h_new, crossed, dx, periodic)
    layer_volumes = share[:, donor] * volumes
    solid_fluxes = phi[:, donor] * layer_volumes
    new = solid - np.diff(solid_fluxes, axis=1) / dx
    # the exchange between layers that restores h_a = l_a h_new, with the solid of the
    # layer the volume leaves (G > 0: from layer a + 1 down into layer a)
    misfit = l * h_new - (l * h_old - np.diff(layer_volumes, axis=1) / dx)
    G = np.cumsum(misfit, axis=0)[:-1]
    carried = np.where(G > 0.0, phi[1:], phi[:-1]) * G
    new[:-1] += carried
    new[1:] -= carried
    bound_packings(new, l * h_new)
    ends = np.array([solid_fluxes[:, 0].sum(), solid_fluxes[:, -1].sum()])
    return new, ends


def carried(
    values: np.ndarray, h_old: np.ndarray, h_new: np.ndarray, crossed: np.ndarray, dx: float, periodic: bool
) -> np.ndarray:
    """Quantities per column ``values`` (k, N) (a relaxing pore pressure at the bottom of
    each layer) carried by the mixture volume over the transport step from ``h_old`` to
    ``h_new``, each as the solid fraction of one layer: the content ``values h`` crosses
    each face with the value of its upwind cell (0 where ``h_new`` is 0)."""
    volumes, donor, filled = _upwind(values, h_old, h_new, crossed, dx, periodic)
    content = values * h_old - np.diff(filled[:, donor] * volumes, axis=1) / dx
    wet = h_new > 0.0
    return np.where(wet, content / np.where(wet, h_new, 1.0), 0.0)


def _upwind(
    values: np.ndarray, h_old: np.ndarray, h_new: np.ndarray, crossed: np.ndarray, dx: float, periodic: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The mixture volume through each face (:func:`face_volumes`), the upwind cell of
    each face (at the boundary faces the wrapped or the boundary cell) and ``values``
    (L, N) with the columns dry at the start filled (:func:`_filled`)."""
    N = h_old.size
    volumes = face_volumes(h_old, h_new, float(crossed[0]), dx)
    west = np.arange(-1, N) % N if periodic else np.concatenate([[0], np.arange(N)])
    east = np.arange(N + 1) % N if periodic else np.concatenate([np.arange(N), [N - 1]])
    donor = np.where(volumes > 0.0, west, east)
    return volumes, donor, _filled(values, h_old > 0.0, volumes)


def bound_packings(solid: np.ndarray, room: np.ndarray) -> None:
    """Keep in place every layer's packing within ``[0, DENSEST_PACKING]`` by moving solid
    between the layers of its column, the column's solid unchanged, after the transport and
    after the local step.  A thin layer at a front can pass on more volume than it held (its
    share of the discharge is that of the column), the upwind packings of the exchange
    between the layers can leave a layer of a thin column with less than no solid, or more
    than the densest packing, and the local step's explicit exchange can gather a layer
    beyond it (docs/mixture.md, "The packings stay in (0, 1)"): a layer's deficit is
    taken from the other layers of its column in proportion to their solid, a layer's excess
    over :data:`~multilayer.engine.mixture.closure.DENSEST_PACKING` given to them in
    proportion to their room below it.  No layer is then out of bounds unless its column's
    mean packing is (that column is left as it was, and the checks stop the run).  A
    column within the bounds is not touched."""
    full = DENSEST_PACKING * room
    deficit = np.maximum(-solid, 0.0)
    if deficit.any():
        held = np.maximum(solid, 0.0)
        total = held.sum(axis=0)
        need = deficit.sum(axis=0)
        able = total > need
        share = np.where(able, need / np.where(able, total, 1.0), 0.0)
        solid[:, able] = held[:, able] * (1.0 - share[able])
    excess = np.maximum(solid - full, 0.0)
    if excess.any():
        kept = np.minimum(solid, full)
        free = full - kept
        total = free.sum(axis=0)
        extra = excess.sum(axis=0)
        able = total > extra
        share = np.where(able, extra / np.where(able, total, 1.0), 0.0)
        solid[:, able] = kept[:, able] + free[:, able] * share[able]


def _filled(phi: np.ndarray, wet: np.ndarray, volumes: np.ndarray) -> np.ndarray:
    """``phi`` with the columns dry at the start of the step given the fraction of the
    wet column the volume reaching them comes from (they pass on what they received); a
    column reached from both sides takes the fraction of the side that gives it more.  The
    face between two dry columns carries a round-off volume (``face_volumes`` is a running
    sum: -3.5e-20 m^2 behind a front), which must not overwrite the fraction of the front's
    column with the empty one beyond it: the exchange between the layers of the newly wet
    column would then carry no solid, and its layers would keep the solid of their share
    of the discharge, the fast top layers the most (packings 0.12 at the bed to 0.77 at the
    top of a column filled at 0.55, and 1.0 further on)."""
    if wet.all() or not wet.any():
        return phi
    out = phi.copy()
    N = wet.size
    for i in range(N):  # downstream fronts (u > 0): from the west
        if not wet[i] and volumes[i] > 0.0 and i > 0:
            out[:, i] = out[:, i - 1]
    for i in range(N - 1, -1, -1):  # upstream fronts (u < 0): from the east, where it gives more
        if not wet[i] and volumes[i + 1] < 0.0 and i < N - 1 and -volumes[i + 1] > max(volumes[i], 0.0):
            out[:, i] = out[:, i + 1]
    return out


def check(solid: np.ndarray, h: np.ndarray, fractions: np.ndarray, when: str, x: np.ndarray) -> None:
    """Raise :class:`RunError` unless ``0 <= s_a <= l_a h`` in every column and layer
    (a solid fraction in [0, 1]) and ``s_a`` is finite."""
    room = fractions[:, None] * h
    bad = ~(np.isfinite(solid) & (solid >= 0.0) & (solid <= room * (1.0 + 1e-12)))
    if bad.any():
        a, i = (int(k) for k in np.unravel_index(np.argmax(bad), bad.shape))
        raise RunError(
            f"solid volume s = {float(solid[a, i])!r} m outside [0, {float(room[a, i])!r}] m (the layer's "
            f"thickness) at x = {float(x[i]):.6g} m, layer {a + 1} (1 is at the bed) {when}"
        )


def check_pores(solid: np.ndarray, h: np.ndarray, fractions: np.ndarray, t: float, x: np.ndarray) -> None:
    """Raise :class:`RunError` unless every layer of the columns ``h`` (n,) holds a packing
    in ``[0, 1)``, where the local step's closure is defined (its Darcy drag is infinite
    at ``phi = 1``), which the transport of the step from ``t`` can leave in a thin column
    at a front, and below :data:`~multilayer.engine.mixture.closure.DENSEST_PACKING`, which
    no packing of the grains exceeds and a layer exceeds only in a column whose mean packing
    does (:func:`bound_packings`)."""
    room = fractions[:, None] * h
    bad = ~(np.isfinite(solid) & (solid >= 0.0) & (solid < room))
    if bad.any():
        raise RunError(
            f"the transport of the solid in the step from t = {t:.6g} s left "
            f"{_culprit(bad, solid, room, h, x)}, outside [0, 1) where the local step's closure is "
            'defined (the exchange between the layers of a thin column at a front, docs/mixture.md, "Layers")'
        )
    dense = solid > DENSEST_PACKING * room * (1.0 + 1e-12)  # the bound to round-off (Heun's average)
    if dense.any():
        raise RunError(
            f"at t = {t:.6g} s {_culprit(dense, solid, room, h, x)}, beyond the densest packing of spheres, "
            f"{DENSEST_PACKING:.4f}, that no grains reach (the exchanges between the layers of a column can "
            'gather solid over many steps, docs/mixture.md, "Layers")'
        )


def _culprit(mask: np.ndarray, solid: np.ndarray, room: np.ndarray, h: np.ndarray, x: np.ndarray) -> str:
    """The first layer of ``mask`` (L, n), its column and its packing, as a message names them."""
    a, i = (int(k) for k in np.unravel_index(np.argmax(mask), mask.shape))
    return (
        f"layer {a + 1} (1 is at the bed) of the column at x = {float(x[i]):.6g} m "
        f"({float(h[i]):.3g} m thick) with a packing of {float(solid[a, i] / room[a, i])!r}"
    )
