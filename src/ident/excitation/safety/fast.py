"""The optimizer's cheap clearances: lower bounds over a swarm's postures, exact where it matters.

:class:`FastClearances` sorts a safety model's checked geometry pairs once: cylinders,
capsules and spheres against each other or a half-space go to the compiled kernels of
:mod:`ident.excitation.safety.primitives` (all postures at once), every other pair to coal,
meshes as their convex hulls. Where a bound is within the margin, coal measures the exact
geometry (:meth:`FastClearances._refine`). Each posture's values depend on that posture alone.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.chain import chain_from_model
from ident.excitation.family import FloatArray
from ident.excitation.safety.distances import CheckedPairs, _geometry_data

__all__ = ["EXACT_WITHIN_M", "FastClearances"]

# coal's GJK without EPA reports shapes in contact as 0 or a round-off above it (1e-16 seen
# for the paper robot's cylinders 20 mm deep): at most this, the cheap term counts contact
_CONTACT_M = 1e-6

#: Clearance [m] up to which :meth:`FastClearances.clearances` gives the coal pairs' exact
#: values (hulls, meshes where poor); beyond it a pair whose bounding spheres are at least
#: this far apart gets the spheres' distance, a lower bound of at least this much, without
#: coal. ``ident init`` caps what it reads at this distance, so no result changes; coal's hull
#: distances were 56 % of a Panda run's CPU (73 % of the pairs are that far apart in its
#: random postures). The optimizer's term (:meth:`FastClearances.min_clearances`) reads only
#: ``max(margin - d, 0)``: it is exact up to the margin alone.
EXACT_WITHIN_M = 0.15


_REFINE_SCRATCH: dict[tuple[int, int, int, int], tuple[Any, pin.GeometryData]] = {}


def _pair_spheres(
    geom: pin.GeometryModel, pairs: tuple[int, ...]
) -> tuple[npt.NDArray[np.int_], FloatArray, FloatArray, FloatArray, FloatArray]:
    """Bounding spheres of the two objects of each pair, in their joints' frames: ``joint``
    (n_pairs, 2), ``centre`` (n_pairs, 2, 3) [m], ``radius`` (n_pairs, 2) [m]; a half-space
    is the pair's second object (swapped if first), with its ``normal`` (n_pairs, 2, 3) and
    ``offset`` (n_pairs, 2) [m] in its joint's frame (zero for a sphere). A pair of two
    half-spaces, or of a shape coal gives no bounding sphere, has an infinite radius."""
    import coal

    objects = geom.geometryObjects
    joint = np.zeros((len(pairs), 2), dtype=int)
    centre, normal = np.zeros((len(pairs), 2, 3)), np.zeros((len(pairs), 2, 3))
    radius, offset = np.zeros((len(pairs), 2)), np.zeros((len(pairs), 2))
    for n, p in enumerate(pairs):
        a, b = int(geom.collisionPairs[p].first), int(geom.collisionPairs[p].second)
        if isinstance(objects[a].geometry, coal.Halfspace):
            a, b = b, a
        for k, i in enumerate((a, b)):
            obj, shape = objects[i], objects[i].geometry
            joint[n, k] = int(obj.parentJoint)
            rotation, translation = obj.placement.rotation, obj.placement.translation
            if isinstance(shape, coal.Halfspace):
                normal[n, k] = rotation @ np.asarray(shape.n, dtype=float)
                offset[n, k] = float(shape.d) + float(normal[n, k] @ translation)
                radius[n, k] = np.inf if k == 0 else 0.0
                continue
            shape.computeLocalAABB()
            centre[n, k] = rotation @ np.asarray(shape.aabb_center, dtype=float) + translation
            radius[n, k] = float(shape.aabb_radius)
    return joint, centre, radius, normal, offset


def _refine_scratch(
    owner: object, model: pin.Model, geom: pin.GeometryModel
) -> tuple[Any, pin.GeometryData]:
    """Pinocchio data and unsigned geometry data (:func:`_geometry_data`) for the cheap term's
    exact distances, made once per owner, model, geometry and thread (making them took 0.14 ms
    per swarm evaluation). Reusing them changes no distance: GJK's cached guess is off, and
    every posture is placed before its distances are computed."""
    import threading
    import weakref

    key = (id(owner), id(model), id(geom), threading.get_ident())
    scratch = _REFINE_SCRATCH.get(key)
    if scratch is None:
        scratch = (model.createData(), _geometry_data(geom, signed=False))
        _REFINE_SCRATCH[key] = scratch
        weakref.finalize(owner, _REFINE_SCRATCH.pop, key, None)
    return scratch


class FastClearances:
    """The cheap term's clearances of the ``checked`` pairs of a safety model (see
    :meth:`ident.excitation.safety.SafetyModel.fast_clearances`); ``poor``, shape
    (n_geometry_pairs,): the mesh pairs whose hulls are too poor a proxy (measured on the
    mesh where the hulls are within the margin). The margin is an argument of each call:
    the optimizer's margin may be above the certificate's."""

    def __init__(self, checked: CheckedPairs, poor: npt.NDArray[np.bool_]) -> None:
        self.checked = checked
        self.model = checked.model
        self.geometry_model = checked.hulls
        self.exact_geometry_model = checked.exact
        self.n_pairs = checked.n_pairs
        self._group = checked.group
        self._hull_proxy_poor = poor
        self._prepare_fast()

    def _prepare_fast(self) -> None:
        """Sort the active geometry pairs into the vectorized ones and the coal ones."""
        import coal

        chain = chain_from_model(self.model)
        self._chain = chain  # its body_positions expand q over mimic joints
        self._placements, self._axes, self._prismatic = (
            chain.placements,
            chain.axes,
            chain.prismatic,
        )
        objects = self.geometry_model.geometryObjects
        segments: dict[int, int] = {}  # geometry index -> row of the segment tables
        joint: list[int] = []
        centre: list[FloatArray] = []
        axis: list[FloatArray] = []
        half: list[float] = []
        radius: list[float] = []
        cylinder: list[bool] = []
        for i, obj in enumerate(objects):
            shape = obj.geometry
            if isinstance(shape, (coal.Cylinder, coal.Capsule)):
                h = float(shape.halfLength)
            elif isinstance(shape, coal.Sphere):
                h = 0.0
            else:
                continue
            segments[i] = len(joint)
            pose = obj.placement.homogeneous
            joint.append(int(obj.parentJoint))
            centre.append(np.append(pose[:3, 3], 1.0))
            axis.append(np.append(pose[:3, 2], 0.0))
            half.append(h)
            radius.append(float(shape.radius))
            cylinder.append(isinstance(shape, coal.Cylinder))
        self._seg = (
            np.array(joint, dtype=int),
            np.array(centre).reshape(-1, 4),
            np.array(axis).reshape(-1, 4),
            np.array(half),
            np.array(radius),
            np.array(cylinder, dtype=bool),
        )
        seg_pairs, plane_pairs, plane_normals, plane_offsets, slow = [], [], [], [], []
        for p, pair in enumerate(self.geometry_model.collisionPairs):
            a, b = int(pair.first), int(pair.second)
            if a in segments and b in segments:
                seg_pairs.append((p, segments[a], segments[b]))
            elif a in segments and isinstance(objects[b].geometry, coal.Halfspace):
                plane_pairs.append((p, segments[a]))
                plane_normals.append(np.asarray(objects[b].geometry.n, dtype=float))
                plane_offsets.append(float(objects[b].geometry.d))
            else:
                slow.append(p)
        self._seg_pairs = np.array(seg_pairs, dtype=int).reshape(-1, 3)
        self._plane_pairs = np.array(plane_pairs, dtype=int).reshape(-1, 2)
        self._plane_normals = np.array(plane_normals).reshape(-1, 3)
        self._plane_offsets = np.array(plane_offsets)
        self._slow_pairs = tuple(slow)
        self._slow_spheres = _pair_spheres(self.geometry_model, self._slow_pairs)

    def clearances(self, q: npt.ArrayLike, clearance_m: float) -> FloatArray:
        """:meth:`ident.excitation.safety.SafetyModel.fast_clearances` for the margin
        ``clearance_m`` [m], shape (n_samples, n_pairs)."""
        q, distances, need, finite = self._fast_bounds(
            np.atleast_2d(np.asarray(q, dtype=float)),
            clearance_m,
            max(clearance_m, EXACT_WITHIN_M),
        )
        rows, pairs = np.nonzero(need)
        self._refine(q, rows, pairs, distances)
        out = self.checked.pair_minimum(distances)
        out[~finite] = -np.inf
        return out

    def min_clearances(self, q: npt.ArrayLike, clearance_m: float, owner: object) -> FloatArray:
        """:meth:`ident.excitation.safety.SafetyModel.fast_min_clearances` for the margin
        ``clearance_m`` [m], shape (n_trajectories, n_pairs); ``owner``: the safety model
        whose lifetime bounds the scratch data (:func:`_refine_scratch`). Exact up to the
        margin only: a coal pair whose bounding spheres are at least the margin apart keeps
        their distance (``max(margin - d, 0)``, all the term reads, is 0 either way; half the
        Panda's exact hull distances were between its 3 cm margin and
        :data:`EXACT_WITHIN_M`)."""
        q = np.asarray(q, dtype=float)
        n_traj, n_samples = q.shape[0], q.shape[1]
        flat, distances, need, finite = self._fast_bounds(
            q.reshape(n_traj * n_samples, -1), clearance_m, clearance_m
        )
        # the per-trajectory, per-link-pair minimum of what needs no refinement
        known = self.checked.pair_minimum(np.where(need, np.inf, distances))
        best = known.reshape(n_traj, n_samples, self.n_pairs).min(axis=1)
        rows, pairs = np.nonzero(need)
        traj, link = rows // n_samples, self._group[pairs]
        bound = distances[rows, pairs]
        useful = bound < best[traj, link]  # only what can lower the minimum
        rows, pairs, traj, link, bound = (a[useful] for a in (rows, pairs, traj, link, bound))
        if rows.size:
            model, geom = self.model, self.exact_geometry_model
            data, gdata = _refine_scratch(owner, model, geom)
            last = -1  # every posture is placed before its first distance
            compute, place = pin.computeDistance, pin.updateGeometryPlacements
            # per (trajectory, link pair), closest bound first; what cannot lower the
            # group's minimum is skipped (the loop of _refine, inlined: it runs thousands
            # of times per swarm)
            order = np.lexsort((bound, link, traj))
            for s, p, t, c, b in zip(
                rows[order].tolist(), pairs[order].tolist(), traj[order].tolist(),
                link[order].tolist(), bound[order].tolist(), strict=True,
            ):  # fmt: skip
                if b >= best[t, c]:
                    continue
                if s != last:
                    place(model, data, geom, gdata, flat[s])
                    last = s
                d = compute(geom, gdata, p).min_distance
                if d <= _CONTACT_M:  # in contact: the bound's depth (see _refine)
                    d = min(b, 0.0)
                if d < best[t, c]:
                    best[t, c] = d
        bad = ~finite.reshape(n_traj, n_samples).all(axis=1)
        best[bad] = -np.inf
        return best

    def _fast_bounds(
        self, q: FloatArray, clearance_m: float, exact_within_m: float
    ) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
        """Lower bounds of every geometry pair's distance and where the exact value is needed.

        Returns ``q`` with non-finite postures set to 0 (n, nq); ``distances``
        (n, n_geometry_pairs) [m], exact for half-spaces, primitives coal handles and hulls of
        convex geometry (coal's pairs: where their bounding spheres are within
        ``exact_within_m`` [m], the spheres' distance elsewhere), a capsule's or a hull's lower
        bound elsewhere; ``need``
        (n, n_geometry_pairs): a cylinder pair or a poor-hull mesh pair whose bound is within
        the margin ``clearance_m`` [m] (:meth:`_refine` makes it exact); ``finite`` (n,): the
        postures without NaN (the others are measured at 0).
        """
        from ident.excitation.safety.primitives import primitive_distances

        n = q.shape[0]
        finite = np.all(np.isfinite(q), axis=1)
        q = np.where(finite[:, None], q, 0.0)
        distances = np.empty((n, len(self.geometry_model.collisionPairs)))
        need = np.zeros(distances.shape, dtype=bool)
        joint, centre, axis, half, radius, cylinder = self._seg
        slow = list(self._slow_pairs)
        frames = self._joint_frames(q)
        if joint.size:
            primitive_distances(
                frames, joint, centre, axis, half, radius, cylinder, self._seg_pairs,
                self._plane_pairs, self._plane_normals, self._plane_offsets, distances,
            )  # fmt: skip
            if self._seg_pairs.size:
                p, i, k = self._seg_pairs.T
                # a cylinder's capsule is a lower bound: where it is within the margin, the
                # exact distance decides (coal, only for those postures and pairs)
                need[:, p] = (cylinder[i] | cylinder[k])[None, :] & (distances[:, p] < clearance_m)
                if need.any():
                    self._inner_capsules(frames, p, need, distances)
        if slow:
            self._coal_bounds(q, frames, slow, need, distances, clearance_m, exact_within_m)
        return q, distances, need, finite

    def _joint_frames(self, q: FloatArray) -> FloatArray:
        """Every joint's placement at the postures ``q`` (n, nq), the base's (identity) first:
        shape (n, n_joints + 1, 4, 4)."""
        from ident.excitation.safety.primitives import joint_frames

        n = q.shape[0]
        q_bodies = self._chain.body_positions(q)
        frames = joint_frames(self._placements, self._axes, self._prismatic, q_bodies)
        return np.concatenate([np.broadcast_to(np.eye(4), (n, 1, 4, 4)), frames], axis=1)

    def _inner_capsules(
        self,
        frames: FloatArray,
        p: npt.NDArray[np.int_],
        need: npt.NDArray[np.bool_],
        distances: FloatArray,
    ) -> None:
        """Settle, without coal, the cylinder pairs ``need`` (n, n_geometry_pairs) marks whose
        inner capsules touch (in place: ``distances`` becomes ``min(bound, 0)`` there and
        ``need`` False). ``frames``: the joint frames (n, n_joints + 1, 4, 4); ``p``: the
        geometry pair of each segment pair."""
        from ident.excitation.safety.primitives import primitive_distances

        joint, centre, axis, half, radius, cylinder = self._seg
        # the capsules inside the cylinders (radius min(r, h), segment shortened
        # by it): in contact, the cylinders are too, and the outer capsules' depth
        # is what _refine would give, without coal
        # (only at the postures and pairs that need it: each entry is computed
        # on its own, the others stay inf and are not read)
        inner = np.full(distances.shape, np.inf)
        r_in = np.where(cylinder, np.minimum(radius, half), radius)
        h_in = np.where(cylinder, half - r_in, half)
        none = np.zeros((0, 2), dtype=int)
        post = np.flatnonzero(need.any(axis=1))
        seg_pairs = np.ascontiguousarray(self._seg_pairs[need[:, p].any(axis=0)])
        inner_post = np.full((post.size, distances.shape[1]), np.inf)
        primitive_distances(
            np.ascontiguousarray(frames[post]), joint, centre, axis, h_in, r_in,
            cylinder, seg_pairs, none, np.zeros((0, 3)), np.zeros(0), inner_post,
        )  # fmt: skip
        inner[post] = inner_post
        sure = need & (inner < 0.0)
        distances[sure] = np.minimum(distances[sure], 0.0)
        need &= ~sure

    def _coal_bounds(
        self,
        q: FloatArray,
        frames: FloatArray,
        slow: list[int],
        need: npt.NDArray[np.bool_],
        distances: FloatArray,
        clearance_m: float,
        far: float,
    ) -> None:
        """Measure the ``slow`` geometry pairs (coal, meshes as hulls) at the postures ``q``
        (joint placements ``frames``, :meth:`_joint_frames`) into ``distances``
        (n, n_geometry_pairs) [m] where their bounding spheres are closer than ``far`` [m] (at
        least the margin; the spheres' distance elsewhere), and mark in ``need`` the
        poor-hull mesh pairs within the margin ``clearance_m`` [m] (in place)."""
        geom = self.geometry_model
        data, gdata = self.model.createData(), _geometry_data(geom)
        slow_pairs = np.asarray(slow, dtype=int)
        spheres = self._sphere_bounds(frames)
        distances[:, slow_pairs] = spheres
        for s in range(q.shape[0]):  # coal: one posture at a time, the near pairs only
            near = slow_pairs[spheres[s] < far]
            if near.size:
                pin.updateGeometryPlacements(self.model, data, geom, gdata, q[s])
                for pair in near.tolist():
                    distances[s, pair] = pin.computeDistance(geom, gdata, pair).min_distance
        poor = np.flatnonzero(self._hull_proxy_poor)
        need[:, poor] = distances[:, poor] < clearance_m

    def _sphere_bounds(self, frames: FloatArray) -> FloatArray:
        """Lower bounds [m] of the coal pairs' distances (``_slow_pairs``) at the postures of
        the joint placements ``frames`` (:meth:`_joint_frames`): the distance of their
        bounding spheres (of a sphere to a half-space), shape (n, n_slow_pairs); ``-inf``
        where a pair has no sphere bound."""
        joint, centre, radius, normal, offset = self._slow_spheres
        # world centres (n, n_pairs, 2, 3) and normals of the pairs' two objects
        placed = frames[:, joint]  # (n, n_pairs, 2, 4, 4)
        rotation, translation = placed[..., :3, :3], placed[..., :3, 3]
        world = (rotation @ centre[..., None])[..., 0] + translation
        n_world = (rotation @ normal[..., None])[..., 0]
        o_world = offset + (n_world * translation).sum(axis=-1)
        apart = np.linalg.norm(world[:, :, 0] - world[:, :, 1], axis=-1) - radius.sum(axis=1)
        # a half-space (object 1): the sphere centre's height above it, minus the radius
        above = (n_world[:, :, 1] * world[:, :, 0]).sum(axis=-1) - o_world[:, :, 1]
        plane = (normal[:, 1] != 0.0).any(axis=1)
        bounds = np.where(plane, above - radius[:, 0], apart)
        return np.where(np.isfinite(radius).all(axis=1), bounds, -np.inf)

    def _refine_context(self) -> list[Any]:
        """Pinocchio data, geometry data of the exact geometry, last posture placed."""
        return [
            self.model.createData(),
            _geometry_data(self.exact_geometry_model, signed=False),
            -1,
        ]

    def _refine(
        self,
        q: FloatArray,
        rows: npt.NDArray[np.int_],
        pairs: npt.NDArray[np.int_],
        out: FloatArray,
        context: list[Any] | None = None,
    ) -> FloatArray:
        """Exact distances of the geometry pairs ``pairs`` at postures ``q[rows]``, written
        into ``out[rows, pairs]`` (which holds their lower bounds) and returned.

        Where the shapes are in contact (coal's unsigned distance, 0 or a round-off above it,
        at most :data:`_CONTACT_M`), the bound's depth stands in (``min(bound, 0)``): the
        signed distance of the capsule around a cylinder, or of a mesh's hull, is never more
        than the shape's own (a shape inside another is no deeper in contact), so the value
        stays conservative and a penetration keeps a depth for the penalty, without coal's
        EPA (meshes have no depth in coal; for cylinders it cost 5x the distance).
        """
        values = np.empty(rows.size)
        if not rows.size:
            return values
        geom = self.exact_geometry_model
        context = self._refine_context() if context is None else context
        data, gdata = context[0], context[1]
        for k, (s, p) in enumerate(zip(rows.tolist(), pairs.tolist(), strict=True)):
            if s != context[2]:
                pin.updateGeometryPlacements(self.model, data, geom, gdata, q[s])
                context[2] = s
            d = pin.computeDistance(geom, gdata, p).min_distance
            if d <= _CONTACT_M:
                d = min(out[s, p], 0.0)
            out[s, p] = values[k] = d
        return values
