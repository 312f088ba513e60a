"""The sampled-posture rules of the robot's link pairs (see :mod:`ident.excitation.safety.pairs`).

On the reference posture and :data:`~ident.excitation.safety.config.N_EXCLUSION_POSTURES`
random ones (:func:`_exclusion_postures`), a link pair in contact in the reference posture or
in nearly every posture is left out (:func:`_add_contact_exclusions`), and every other pair
must keep the margin in some posture (:func:`_settle_margin`, which may lower a default
margin). The convex hulls screen the postures first
(:func:`ident.excitation.safety.geometry._screen`): the exact geometry is measured only where
the hulls are close, and the answer is the exact geometry's.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.errors import ConfigError
from ident.excitation.constraints import JointLimits
from ident.excitation.family import FloatArray
from ident.excitation.safety.config import (
    _SCREEN_SLACK_M,
    ALWAYS_IN_CONTACT_FRACTION,
    MIN_LOWERED_CLEARANCE_M,
    N_EXCLUSION_POSTURES,
    PAYLOAD,
)
from ident.excitation.safety.distances import _geometry_data
from ident.excitation.safety.pairs import _flat_pairs

__all__: list[str] = []  # the package's own steps, imported by name


def _exclusion_postures(
    limits: JointLimits,
    reference_q: npt.ArrayLike | None,
    rng: np.random.Generator | int | None,
) -> FloatArray:
    """The reference posture (row 0) and :data:`N_EXCLUSION_POSTURES` random ones [rad],
    within ``limits``' position box."""
    lower, upper = limits.finite_position_box()
    if reference_q is None:
        reference = np.clip(np.zeros(limits.nq), lower, upper)
    else:
        reference = np.asarray(reference_q, dtype=float)
    gen = np.random.default_rng(rng)
    sample = gen.uniform(lower, upper, (N_EXCLUSION_POSTURES, limits.nq))
    return np.vstack([reference[None, :], sample])


def _add_contact_exclusions(
    model: pin.Model,
    postures: FloatArray,
    excluded: dict[tuple[str, str], str],
    geom: pin.GeometryModel,
    tested: list[tuple[str, str]],
    geometry_pairs: dict[tuple[str, str], list[tuple[int, int]]],
    screened: Mapping[tuple[int, int], FloatArray],
) -> None:
    """Add to ``excluded`` the ``tested`` link pairs in contact (exact geometry) in the
    reference posture, or in at least :data:`ALWAYS_IN_CONTACT_FRACTION` of the random
    ones of ``postures`` (row 0 the reference; ``geometry_pairs``: the geometry object pairs
    of each link pair; ``screened``: their hulls' distances per posture, shape
    (n_postures,)).

    The exact geometry is tested only where the hulls are within
    :data:`_SCREEN_SLACK_M` (hulls apart: meshes apart), and a pair's random postures
    only until so many are found apart that the fraction cannot be reached.
    """
    pairs, owner = _flat_pairs(tested, geometry_pairs)
    near = np.column_stack([screened[ab] <= _SCREEN_SLACK_M for ab in pairs])
    geom.removeAllCollisionPairs()
    for a, b in pairs:
        geom.addCollisionPair(pin.CollisionPair(a, b))
    data, gdata = model.createData(), pin.GeometryData(geom)
    for request in gdata.collisionRequests:
        request.security_margin = 0.0

    def contact(s: int, columns: npt.NDArray[np.int_]) -> bool:
        pin.updateGeometryPlacements(model, data, geom, gdata, postures[s])
        return any(pin.computeCollision(geom, gdata, int(p)) for p in columns if near[s, p])

    n_random = postures.shape[0] - 1
    for i, key in enumerate(tested):
        columns = np.flatnonzero(owner == i)
        maybe = np.asarray(near[:, columns].any(axis=1), dtype=bool)
        # a payload touching a link in the reference posture (an arm folded onto its
        # tool) is no reason to trust the pair elsewhere: only the 95 % rule applies to it
        if PAYLOAD not in key and maybe[0] and contact(0, columns):
            excluded[key] = "reference contact (in contact in the reference posture)"
            continue
        hits, left = 0, int(maybe[1:].sum())
        for s in (np.flatnonzero(maybe[1:]) + 1).tolist():
            if (hits + left) / n_random < ALWAYS_IN_CONTACT_FRACTION:
                break  # the fraction cannot be reached any more
            left -= 1
            hits += contact(s, columns)
        fraction = hits / n_random
        if fraction >= ALWAYS_IN_CONTACT_FRACTION:
            excluded[key] = (
                f"always in contact (in {100 * fraction:.1f} % of {n_random} random postures)"
            )
    geom.removeAllCollisionPairs()


def _settle_margin(
    model: pin.Model,
    postures: FloatArray,
    clearance_m: float,
    lower_margin: bool,
    geom: pin.GeometryModel,
    tested: list[tuple[str, str]],
    geometry_pairs: dict[tuple[str, str], list[tuple[int, int]]],
    screened: Mapping[tuple[int, int], FloatArray],
) -> tuple[dict[tuple[str, str], float], float, str]:
    """Check that every ``tested`` link pair can keep the margin ``clearance_m`` [m] in some
    of ``postures``.

    A margin the user did not choose (``lower_margin``) is lowered (halved, down to
    :data:`MIN_LOWERED_CLEARANCE_M`) until they can; a pair closer than the margin in every
    posture is a :class:`ConfigError`. Each pair's largest clearance over the postures is
    measured once (:func:`_largest_clearances`) and compared with every halved margin.

    Returns each tested pair's largest clearance [m] (the model's ``keepable_clearances``),
    the margin [m], and the note saying why it was lowered (empty when it was not).
    """
    pairs, owner = _flat_pairs(tested, geometry_pairs)
    hull = np.column_stack([screened[ab] for ab in pairs])
    largest = _largest_clearances(
        model, postures, clearance_m, geom, pairs, owner, len(tested), hull
    )
    keepable = dict(zip(tested, largest.tolist(), strict=True))
    margin = clearance_m
    always = largest < margin  # closer than the margin in every posture
    # a margin the user did not choose is lowered (halved, down to 2 mm) until every
    # pair can keep it in some posture; a chosen one is an input error below
    while lower_margin and always.any() and margin / 2.0 >= MIN_LOWERED_CLEARANCE_M:
        margin /= 2.0
        always = largest < margin
    for i, key in enumerate(tested):
        if always[i]:
            raise ConfigError(
                f"safety.clearance_m = {clearance_m:g} m: the links {key[0]} and "
                f"{key[1]} are closer than that in every one of "
                f"{postures.shape[0]} postures (the reference and random ones), so "
                "no trajectory can keep it; lower safety.clearance_m, or disable the "
                "pair in a MoveIt SRDF (safety.srdf) if they may touch."
            )
    if margin == clearance_m:
        return keepable, clearance_m, ""
    close = ", ".join(
        f"{a}-{b}" for (a, b), d in zip(tested, largest, strict=True) if d < clearance_m
    )
    note = (
        f"safety margin lowered from the default {clearance_m:g} m to "
        f"{margin:g} m: the links {close} are closer than the default in every "
        "sampled posture (set safety.clearance_m to choose the margin)"
    )
    return keepable, margin, note


def _largest_clearances(
    model: pin.Model,
    postures: FloatArray,
    clearance_m: float,
    geom: pin.GeometryModel,
    pairs: list[tuple[int, int]],
    owner: npt.NDArray[np.int_],
    n_links: int,
    hull: FloatArray,
) -> FloatArray:
    """Per link pair, the largest over ``postures`` of its clearance (the smallest distance
    of its geometry ``pairs``, ``owner``: the link pair of each) [m], shape (n_links,): exact
    where below the margin ``clearance_m``; at least the margin otherwise.

    ``hull`` (n_postures, n_pairs): the hulls' distances, lower bounds of the exact ones.
    A link pair whose hulls keep the margin in some posture keeps it. For the others the
    exact geometry is measured posture by posture (those whose hulls are farthest apart
    first, and only the geometry pairs whose hulls are within the margin: the others
    cannot bring the link pair below it), until a posture keeps the margin.
    """
    screen = clearance_m + _SCREEN_SLACK_M
    link_hull = np.full((hull.shape[0], n_links), np.inf)
    np.minimum.at(link_hull.T, owner, hull.T)
    largest = link_hull.max(axis=0)
    close = [i for i in range(n_links) if largest[i] < screen]
    if not close:
        return largest
    columns = [int(p) for i in close for p in np.flatnonzero(owner == i)]
    geom.removeAllCollisionPairs()
    for p in columns:
        geom.addCollisionPair(pin.CollisionPair(*pairs[p]))
    data, gdata = model.createData(), _geometry_data(geom, signed=False)
    for i in close:
        mine = [k for k, p in enumerate(columns) if owner[p] == i]
        largest[i] = -np.inf
        for s in np.argsort(-link_hull[:, i], kind="stable").tolist():
            pin.updateGeometryPlacements(model, data, geom, gdata, postures[s])
            value = min(
                (
                    pin.computeDistance(geom, gdata, k).min_distance
                    if hull[s, columns[k]] < screen
                    else hull[s, columns[k]]
                    for k in mine
                ),
                default=np.inf,
            )
            largest[i] = max(largest[i], value)
            if largest[i] >= clearance_m:
                break
    geom.removeAllCollisionPairs()
    return largest
