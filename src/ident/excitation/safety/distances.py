"""Distances and collisions of geometry pairs, by coal through Pinocchio, one posture at a time.

:class:`CheckedPairs` holds the geometry pairs a :class:`~ident.excitation.safety.model.
SafetyModel` checks (on the convex hulls and on the exact geometry) and which link pair each
belongs to; the functions below measure pairs of any geometry of the kinematic model. Every
distance is measured with :func:`_geometry_data`, so that a posture's distances depend on that
posture alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.excitation.family import FloatArray

__all__ = ["CheckedPairs"]


@dataclass(frozen=True, eq=False)
class CheckedPairs:
    """The geometry pairs a safety model checks.

    Attributes
    ----------
    model :
        The kinematic model (the robot's joints, a payload's frame).
    hulls :
        The checked geometry pairs with meshes replaced by their convex hulls (a conservative
        proxy: a hull contains its mesh).
    exact :
        The same pairs on the exact geometry (meshes as coal BVH, primitives as primitives).
    group :
        Shape (n_geometry_pairs,): the link pair (clearance column) of each geometry pair.
    n_pairs :
        Number of checked link pairs.
    mesh :
        Shape (n_geometry_pairs,): a mesh on either side, where the hull and the geometry
        differ (:func:`ident.excitation.safety.pairs._mesh_pairs`).
    """

    model: pin.Model
    hulls: pin.GeometryModel
    exact: pin.GeometryModel
    group: npt.NDArray[np.int64]
    n_pairs: int
    mesh: npt.NDArray[np.bool_]

    def pair_minimum(self, distances: FloatArray) -> FloatArray:
        """Per link pair, the smallest of its geometry pairs' columns: (n, n_geometry_pairs)
        -> (n, n_pairs) (``np.minimum.reduceat`` over the columns sorted by link pair)."""
        if self.n_pairs == 0:
            return np.full((distances.shape[0], 0), np.inf)
        order = np.argsort(self.group, kind="stable")
        starts = np.searchsorted(self.group[order], np.arange(self.n_pairs))
        return np.asarray(np.minimum.reduceat(distances[:, order], starts, axis=1))


def _geometry_data(geom: pin.GeometryModel, *, signed: bool = True) -> pin.GeometryData:
    """Geometry data whose every distance starts GJK from coal's default direction.

    Pinocchio enables coal's cached guess: each pair's GJK would start from the direction
    (and support vertex) of the last distance computed with the same data, so a distance
    (exact to GJK's tolerance, ~1e-6 m) would depend on the posture computed before it: the
    cheap term of one particle on the other particles of the swarm (an optimizer on the
    margin then keeps a point that is infeasible on its own), the dense check on the sampling
    rate. With the cache off, a posture's distances depend on that posture alone. (Set once
    per data: resetting the guess before every call cost more than the distance itself.)

    ``signed=False``: no penetration depth (coal's EPA) where two shapes are in contact (the
    value is then <= 0 and means "in contact" only); distances of separate shapes are the
    same, bit for bit. EPA took 14 us on average for two cylinders of the paper robot in
    contact, GJK alone 3 us.
    """
    import warnings

    import coal

    gdata = pin.GeometryData(geom)
    with warnings.catch_warnings():  # the flag is deprecated in coal 3, and still read
        warnings.simplefilter("ignore", DeprecationWarning)
        for request in gdata.distanceRequests:
            request.enable_cached_gjk_guess = False
            request.gjk_initial_guess = coal.GJKInitialGuess.DefaultGuess
            request.enable_signed_distance = signed
    return gdata


def _exact_distances(
    model: pin.Model, geom: pin.GeometryModel, pairs: list[tuple[int, int]], postures: FloatArray
) -> FloatArray:
    """Distances of geometry pairs on the given (exact) geometry [m], shape (n, n_pairs)."""
    out = np.empty((postures.shape[0], len(pairs)))
    geom.removeAllCollisionPairs()
    for a, b in pairs:
        geom.addCollisionPair(pin.CollisionPair(a, b))
    data = model.createData()
    gdata = _geometry_data(geom)
    for s, q in enumerate(postures):
        pin.updateGeometryPlacements(model, data, geom, gdata, q)
        for p in range(len(pairs)):
            out[s, p] = pin.computeDistance(geom, gdata, p).min_distance
    geom.removeAllCollisionPairs()
    return out


def _collisions(
    model: pin.Model,
    geom: pin.GeometryModel,
    pairs: list[tuple[int, int]],
    postures: FloatArray,
    margin: float,
    where: npt.NDArray[np.bool_] | None = None,
) -> npt.NDArray[np.bool_]:
    """Whether each geometry pair (exact geometry) is closer than ``margin`` [m], shape
    (n_postures, n_pairs); ``where`` (same shape): test only there (False elsewhere)."""
    out = np.zeros((postures.shape[0], len(pairs)), dtype=bool)
    if not pairs:
        return out
    if where is None:
        where = np.ones(out.shape, dtype=bool)
    geom.removeAllCollisionPairs()
    for a, b in pairs:
        geom.addCollisionPair(pin.CollisionPair(a, b))
    data = model.createData()
    gdata = pin.GeometryData(geom)
    for request in gdata.collisionRequests:
        request.security_margin = margin
    for s in np.flatnonzero(where.any(axis=1)).tolist():  # coal: one posture at a time
        pin.updateGeometryPlacements(model, data, geom, gdata, postures[s])
        for p in np.flatnonzero(where[s]).tolist():
            out[s, p] = pin.computeCollision(geom, gdata, p)
    geom.removeAllCollisionPairs()
    return out


def _distances(model: pin.Model, geom: pin.GeometryModel, q: FloatArray) -> FloatArray:
    """Signed distances of every active pair of ``geom`` [m], shape (n_samples, n_pairs)."""
    q = np.asarray(q, dtype=float)
    n_pairs = len(geom.collisionPairs)
    out = np.empty((q.shape[0], n_pairs))
    data = model.createData()
    gdata = _geometry_data(geom)
    # the results' Python proxies, made once: computeDistances rewrites them in place, and
    # making n_pairs proxies per posture cost as much as coal's distances of primitive hulls
    results = list(gdata.distanceResults)
    for k in range(q.shape[0]):  # coal evaluates one posture at a time
        pin.computeDistances(model, data, geom, gdata, q[k])
        out[k] = [r.min_distance for r in results]
    return out


def _exact_into(
    checked: CheckedPairs,
    q: FloatArray,
    pairs: Sequence[int],
    gdata: pin.GeometryData,
    row: FloatArray,
) -> None:
    """Replace the hull distances ``row[pairs]`` of one posture by the mesh distances.

    coal reports meshes in contact as 0 (no depth): there the hulls' (negative) signed
    distance is kept, so a penetration still has a depth for the penalty.
    """
    geom = checked.exact
    pin.updateGeometryPlacements(checked.model, checked.model.createData(), geom, gdata, q)
    for p in pairs:
        d = pin.computeDistance(geom, gdata, int(p)).min_distance
        row[p] = d if d > 0.0 else min(d, row[p])
