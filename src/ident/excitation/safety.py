"""Collision, environment and torque model of an excitation trajectory (what a robot can run).

A :class:`SafetyModel` holds, for one robot,

- its URDF **collision geometry** as a Pinocchio ``GeometryModel`` (coal computes the signed
  distances; meshes are replaced by their convex hulls so that a penetration has a depth);
- the **floor**, a half-space ``z <= floor.z`` in the base frame (on by default);
- the **obstacles** of the config: boxes, spheres and half-spaces (a table, a wall), fixed in
  the base frame;
- the **clearance margin** ``clearance_m`` (default 0.03 m) every checked pair must keep;
- the **torque limits**, the URDF ``effort`` of each joint with the nominal model's inverse
  dynamics (``pin.rnea``), next to the position, velocity and acceleration limits.

Checked pairs (the rule, applied once when the model is built):

1. every pair of robot geometries on different, non-adjacent joints (two geometries are
   adjacent when they move with the same joint or with a joint and its parent: links welded by
   a fixed joint belong to the same joint in Pinocchio);
2. every robot geometry against the floor and every obstacle;
3. minus the pairs that are closer than the margin in **every** posture of a seeded sample (the
   reference posture, i.e. 0 clipped into the position limits, and
   :data:`N_EXCLUSION_POSTURES` random postures within the position limits): such geometry
   overlaps by construction (the housings around an elbow, the first link's housing on the
   floor it rotates on, the base standing on the floor) and no motion could satisfy it. They
   are listed in :attr:`SafetyModel.excluded_pairs` with the reason.

Distances are reported per *link pair* (the URDF link names of the two geometries, or the
obstacle name): the minimum over the geometry pairs of the two links.

References
----------
J. Carpentier et al., "The Pinocchio C++ library", SII 2019 (``GeometryModel``); coal
(formerly hpp-fcl) for GJK/EPA signed distances.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from pydantic import Field, field_validator, model_validator

from ident.config import StrictModel
from ident.errors import ModelError
from ident.excitation.constraints import NONFINITE_VIOLATION, JointLimits
from ident.excitation.family import ConstraintViolations, FloatArray
from ident.robot.meshes import check_urdf_meshes

__all__ = [
    "DEFAULT_CLEARANCE_M",
    "N_EXCLUSION_POSTURES",
    "BoxObstacle",
    "FloorConfig",
    "ObstacleConfig",
    "PlaneObstacle",
    "SafetyConfig",
    "SafetyModel",
    "SphereObstacle",
    "build_safety_model",
    "clearances",
    "collision_violations",
    "joint_torques",
    "torque_violations",
]

DEFAULT_CLEARANCE_M = 0.03
N_EXCLUSION_POSTURES = 100
FLOOR = "floor"

Vector3 = tuple[float, float, float]


# ---------------------------------------------------------------------- config schema
class FloorConfig(StrictModel):
    """The floor: the half-space ``z <= z`` of the base frame [m]."""

    enabled: bool = True
    z: float = 0.0


class BoxObstacle(StrictModel):
    """A box: edge lengths ``size`` [m], centre ``position`` [m], orientation ``rpy`` [rad]."""

    size: Vector3
    position: Vector3 = (0.0, 0.0, 0.0)
    rpy: Vector3 = (0.0, 0.0, 0.0)

    @field_validator("size")
    @classmethod
    def _positive(cls, value: Vector3) -> Vector3:
        if min(value) <= 0.0:
            raise ValueError(f"every box edge must be > 0 m, got {list(value)}")
        return value


class SphereObstacle(StrictModel):
    """A sphere of ``radius`` [m] centred at ``position`` [m]."""

    radius: float = Field(gt=0.0)
    position: Vector3 = (0.0, 0.0, 0.0)


class PlaneObstacle(StrictModel):
    """A half-space: the solid side is ``normal . p <= offset`` [m].

    ``normal`` points into the free space (it is normalized on use): a wall 1 m in front of
    the robot along x is ``{normal: [-1, 0, 0], offset: -1.0}``; a table top at 0.2 m under the
    base is ``{normal: [0, 0, 1], offset: -0.2}``.
    """

    normal: Vector3
    offset: float

    @field_validator("normal")
    @classmethod
    def _nonzero(cls, value: Vector3) -> Vector3:
        if math.hypot(*value) < 1e-12:
            raise ValueError("plane normal must not be the zero vector")
        return value


class ObstacleConfig(StrictModel):
    """One obstacle: exactly one of ``box``, ``sphere``, ``plane``; optional ``name``."""

    name: str | None = None
    box: BoxObstacle | None = None
    sphere: SphereObstacle | None = None
    plane: PlaneObstacle | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> ObstacleConfig:
        given = [k for k in ("box", "sphere", "plane") if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(
                "an obstacle is exactly one of box, sphere, plane, e.g. "
                "{box: {size: [1.0, 0.6, 0.05], position: [0.8, 0.0, 0.3]}}; "
                f"got {', '.join(given) or 'none'}"
            )
        return self

    @property
    def kind(self) -> str:
        """``"box"``, ``"sphere"`` or ``"plane"``."""
        return next(k for k in ("box", "sphere", "plane") if getattr(self, k) is not None)


class SafetyConfig(StrictModel):
    """The ``safety`` section of a run config.

    ```yaml
    safety:
      floor: {enabled: true, z: 0.0}
      obstacles:
        - {name: table, box: {size: [1.0, 0.6, 0.05], position: [0.8, 0.0, 0.3]}}
        - {sphere: {radius: 0.1, position: [0.5, 0.5, 0.8]}}
        - {name: wall, plane: {normal: [-1.0, 0.0, 0.0], offset: -1.2}}
      clearance_m: 0.03
      self_collision: true
      torque_limits: true
      check_rate_hz: 1000
      check_samples: 16
    ```

    ``check_samples`` is the number of samples per period at which the optimization's cheap
    constraint term measures the clearances; ``check_rate_hz`` (>= 1000) the rate of the
    dense check of the chosen trajectories.
    """

    floor: FloorConfig = FloorConfig()
    obstacles: tuple[ObstacleConfig, ...] = ()
    clearance_m: float = Field(default=DEFAULT_CLEARANCE_M, ge=0.0)
    self_collision: bool = True
    torque_limits: bool = True
    check_rate_hz: float = Field(default=1000.0, ge=1000.0)
    check_samples: int = Field(default=16, ge=1)


# ---------------------------------------------------------------------- the model
@dataclass(frozen=True, eq=False)
class ExcludedPair:
    """A pair left out of the checks, and why."""

    pair: str
    reason: str


def _rpy_matrix(rpy: Sequence[float]) -> FloatArray:
    return np.asarray(pin.rpy.rpyToMatrix(*[float(v) for v in rpy]))


def _obstacle_geometry(obstacle: ObstacleConfig) -> tuple[Any, pin.SE3]:
    import coal

    if obstacle.box is not None:
        box = obstacle.box
        pose = pin.SE3(_rpy_matrix(box.rpy), np.asarray(box.position, dtype=float))
        return coal.Box(*[float(s) for s in box.size]), pose
    if obstacle.sphere is not None:
        sphere = obstacle.sphere
        return coal.Sphere(float(sphere.radius)), pin.SE3(
            np.eye(3), np.asarray(sphere.position, dtype=float)
        )
    plane = obstacle.plane
    assert plane is not None  # by ObstacleConfig's validator
    normal = np.asarray(plane.normal, dtype=float)
    norm = float(np.linalg.norm(normal))
    return coal.Halfspace(normal / norm, float(plane.offset) / norm), pin.SE3.Identity()


def _revolute_text(text: str) -> str:
    from ident.model import continuous_as_revolute

    return continuous_as_revolute(ET.fromstring(text), text)[0]


def _kinematic_model_and_geometry(
    robot: Any, urdf: str | Path | None, package_dirs: Sequence[str | Path]
) -> tuple[pin.Model, pin.GeometryModel]:
    """Pinocchio model (same joints as ``robot.model``) and its collision GeometryModel."""
    check_urdf_meshes(urdf or getattr(robot, "urdf_text", None), package_dirs, visual=False)
    if urdf is None:
        text = getattr(robot, "urdf_text", None)
        if text is None:
            raise ModelError("the robot has no URDF text; pass urdf= (a path or the text).")
    elif isinstance(urdf, Path) or (isinstance(urdf, str) and not urdf.lstrip().startswith("<")):
        text = Path(urdf).read_text(encoding="utf-8")
    else:
        text = str(urdf)
    text = _revolute_text(text)
    full = pin.buildModelFromXML(text)
    dirs = [str(d) for d in package_dirs]
    try:
        geom = pin.buildGeomFromUrdfString(full, text, pin.GeometryType.COLLISION, None, dirs)
    except (RuntimeError, ValueError) as e:
        raise ModelError(
            f"cannot load the URDF's collision geometry ({str(e).splitlines()[0]}); give the "
            "folders that hold package:// meshes as package_dirs."
        ) from e
    names = tuple(robot.model.names[1:])
    if tuple(full.names[1:]) != names:
        locked = dict(getattr(robot, "locked_joints", {}) or {})
        reference = pin.neutral(full)
        for name, value in locked.items():
            reference[full.joints[full.getJointId(name)].idx_q] = value
        ids = [full.getJointId(name) for name in full.names[1:] if name not in names]
        full, geom = pin.buildReducedModel(full, geom, ids, reference)
        if tuple(full.names[1:]) != names:
            raise ModelError(
                f"the URDF's joints {list(full.names[1:])} do not match the robot's {list(names)}"
            )
    return full, geom


def _convexify(geom: pin.GeometryModel) -> None:
    """Replace mesh geometry by its convex hull (GJK/EPA then give penetration depths).

    The hull is computed (qhull through ``buildConvexHull``, facets not triangulated: a
    triangulated hull of a finely tessellated cylinder gives one vertex more neighbours than
    coal stores, "Too many neighbors"). ``buildConvexRepresentation`` would only relabel the
    mesh as convex: for a non-convex mesh the support function's hill climbing then stops at
    local extrema, and distances come out too large (by up to 0.44 m on the UR5's upper arm
    against the floor plane), i.e. unsafe.

    Raises
    ------
    ModelError
        If qhull cannot build a mesh's hull.
    """
    import coal

    for obj in geom.geometryObjects:
        shape = obj.geometry
        if isinstance(shape, coal.BVHModelBase):
            try:
                shape.buildConvexHull(False, "")
            except RuntimeError as e:
                raise ModelError(
                    f"collision mesh of {obj.name}: its convex hull cannot be built "
                    f"({str(e).splitlines()[-1].strip()}); simplify the mesh or give the link a "
                    "primitive <collision> (box, cylinder, sphere)."
                ) from e
            obj.geometry = shape.convex


class SafetyModel:
    """Collision geometry, environment and limits of one robot; see the module docstring.

    Build it with :func:`build_safety_model`.

    Attributes
    ----------
    pair_names :
        Checked link pairs ``"<link>|<link or obstacle>"``, in the column order of
        :meth:`clearances`.
    pair_kinds :
        ``"self"``, ``"floor"`` or ``"obstacle"`` per link pair.
    excluded_pairs :
        Pairs left out, with the reason: adjacent links (named by link), or geometries closer
        than the margin in every sampled posture (named by Pinocchio geometry, e.g.
        ``link_1_0|floor``, since the other geometries of the two links stay checked).
    clearance_m :
        Required clearance [m].
    effort_max :
        Torque limits [N*m or N], shape (nv,); ``inf`` where unknown or when torque limits are
        off.
    limits :
        Position, velocity, acceleration limits.
    """

    def __init__(
        self,
        robot: Any,
        config: SafetyConfig,
        *,
        urdf: str | Path | None = None,
        package_dirs: Sequence[str | Path] = (),
        reference_q: npt.ArrayLike | None = None,
        rng: np.random.Generator | int | None = 0,
    ) -> None:
        import coal

        self.config = config
        self.clearance_m = float(config.clearance_m)
        self.robot_model: pin.Model = robot.model
        self.limits = JointLimits.from_robot(robot)
        model, geom = _kinematic_model_and_geometry(robot, urdf, package_dirs)
        _convexify(geom)
        self.model = model
        n_robot = len(geom.geometryObjects)
        link_of = [model.frames[o.parentFrame].name for o in geom.geometryObjects]
        joint_of = [int(o.parentJoint) for o in geom.geometryObjects]
        # obstacles are attached to the universe (joint 0, frame 0), fixed in the base frame
        environment: list[str] = []
        if config.floor.enabled:
            floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), float(config.floor.z))
            geom.addGeometryObject(pin.GeometryObject(FLOOR, 0, 0, pin.SE3.Identity(), floor))
            environment.append(FLOOR)
        for k, obstacle in enumerate(config.obstacles):
            name = obstacle.name or f"obstacle_{k + 1}_{obstacle.kind}"
            shape, pose = _obstacle_geometry(obstacle)
            geom.addGeometryObject(pin.GeometryObject(name, 0, 0, pose, shape))
            environment.append(name)
        parents = list(model.parents)
        candidates: list[tuple[int, int, str, str]] = []  # (geom a, geom b, pair name, kind)
        excluded: dict[str, str] = {}
        if config.self_collision:
            for a in range(n_robot):
                for b in range(a + 1, n_robot):
                    ja, jb = joint_of[a], joint_of[b]
                    name = f"{link_of[a]}|{link_of[b]}"
                    if ja == jb or parents[ja] == jb or parents[jb] == ja:
                        if link_of[a] != link_of[b]:
                            excluded.setdefault(name, "adjacent links")
                        continue
                    candidates.append((a, b, name, "self"))
        for e, env_name in enumerate(environment):
            kind = "floor" if env_name == FLOOR else "obstacle"
            for a in range(n_robot):
                candidates.append((a, n_robot + e, f"{link_of[a]}|{env_name}", kind))
        for a, b, _, _ in candidates:
            geom.addCollisionPair(pin.CollisionPair(a, b))
        self.geometry_model = geom
        # exclusion: pairs within the margin in every posture of a seeded sample
        postures = self._exclusion_postures(reference_q, rng)
        distances = self._geometry_distances(postures)
        always = np.all(distances < self.clearance_m, axis=0)
        kept = []
        objects = geom.geometryObjects
        for k, (a, b, _, _) in enumerate(candidates):
            if always[k]:
                excluded.setdefault(
                    f"{objects[a].name}|{objects[b].name}",
                    f"closer than {self.clearance_m:g} m in every one of "
                    f"{postures.shape[0]} sampled postures (overlap by construction)",
                )
            else:
                kept.append(k)
        geom.removeAllCollisionPairs()
        for k in kept:
            geom.addCollisionPair(pin.CollisionPair(candidates[k][0], candidates[k][1]))
        self.excluded_pairs = tuple(ExcludedPair(p, r) for p, r in excluded.items())
        geometry_pair_names = [candidates[k][2] for k in kept]
        self.pair_names: tuple[str, ...] = tuple(dict.fromkeys(geometry_pair_names))
        kinds = {candidates[k][2]: candidates[k][3] for k in kept}
        self.pair_kinds: tuple[str, ...] = tuple(kinds[n] for n in self.pair_names)
        self._group = np.array([self.pair_names.index(n) for n in geometry_pair_names], dtype=int)
        effort = np.asarray(getattr(robot.model, "effortLimit", np.zeros(0)), dtype=float)
        known = np.isfinite(effort) & (effort > 0.0) & (effort < 1e300)
        if effort.shape != (robot.model.nv,) or not config.torque_limits:
            known = np.zeros(robot.model.nv, dtype=bool)
            effort = np.zeros(robot.model.nv)
        self.effort_max: FloatArray = np.where(known, effort, np.inf)
        self.effort_max.setflags(write=False)

        self._prepare_fast()

    def _prepare_fast(self) -> None:
        """Sort the active geometry pairs into the vectorized ones and the coal ones."""
        import coal

        from ident.dynamics.chain import chain_from_model

        chain = chain_from_model(self.model)
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

    def fast_clearances(self, q: npt.ArrayLike) -> FloatArray:
        """Clearances of the link pairs, vectorized over postures, for the cheap term [m].

        Cylinder, capsule and sphere geometry is handled by compiled code over all postures
        (:mod:`ident.excitation._fast_clearance`): exact against half-spaces (the floor,
        planes); for a cylinder against another geometry, the capsule around it gives a lower
        bound, and where that bound is within the margin coal computes the exact distance
        (only for those postures and pairs); every other pair goes through coal. So
        ``fast_clearances(q)`` equals ``clearances(q)`` wherever either is below the margin,
        and never exceeds it. Shape (n_samples, n_pairs). Each posture's row depends on that
        posture alone (not on the others passed with it).
        """
        from ident.excitation._fast_clearance import joint_frames, primitive_distances

        q = np.atleast_2d(np.asarray(q, dtype=float))
        n = q.shape[0]
        finite = np.all(np.isfinite(q), axis=1)
        q = np.where(finite[:, None], q, 0.0)
        distances = np.empty((n, len(self.geometry_model.collisionPairs)))
        joint, centre, axis, half, radius, cylinder = self._seg
        if joint.size:
            frames = joint_frames(self._placements, self._axes, self._prismatic, q)
            frames = np.concatenate([np.broadcast_to(np.eye(4), (n, 1, 4, 4)), frames], axis=1)
            primitive_distances(
                frames, joint, centre, axis, half, radius, cylinder, self._seg_pairs,
                self._plane_pairs, self._plane_normals, self._plane_offsets, distances,
            )  # fmt: skip
            refine = {}
            if self._seg_pairs.size:
                p, i, k = self._seg_pairs.T
                # a cylinder's capsule is a lower bound: where it is within the margin, the
                # exact distance decides (coal, only for those postures and pairs)
                bound = (cylinder[i] | cylinder[k])[None, :] & (distances[:, p] < self.clearance_m)
                refine = {int(r): p[bound[r]] for r in np.flatnonzero(bound.any(axis=1))}
        else:
            refine = {}
        slow = np.asarray(self._slow_pairs, dtype=int)
        if slow.size or refine:
            data = self.model.createData()
            gdata = pin.GeometryData(self.geometry_model)
            geom = self.geometry_model
            for s in range(n):  # coal: one posture at a time
                pairs = np.concatenate([slow, refine.get(s, np.zeros(0, dtype=int))])
                if pairs.size == 0:
                    continue
                pin.updateGeometryPlacements(self.model, data, geom, gdata, q[s])
                for p in pairs:
                    _fresh_gjk_start(gdata, int(p))
                    distances[s, p] = pin.computeDistance(geom, gdata, int(p)).min_distance
        out = np.full((n, self.n_pairs), np.inf)
        np.minimum.at(out.T, self._group, distances.T)
        out[~finite] = -np.inf
        return out

    @property
    def n_pairs(self) -> int:
        """Number of checked link pairs."""
        return len(self.pair_names)

    def _exclusion_postures(
        self, reference_q: npt.ArrayLike | None, rng: np.random.Generator | int | None
    ) -> FloatArray:
        lower, upper = self.limits.finite_position_box()
        if reference_q is None:
            reference = np.clip(np.zeros(self.limits.nq), lower, upper)
        else:
            reference = np.asarray(reference_q, dtype=float)
        gen = np.random.default_rng(rng)
        sample = gen.uniform(lower, upper, (N_EXCLUSION_POSTURES, self.limits.nq))
        return np.vstack([reference[None, :], sample])

    def _geometry_distances(self, q: FloatArray) -> FloatArray:
        """Signed distances of every active geometry pair [m], shape (n_samples, n_geom_pairs)."""
        q = np.asarray(q, dtype=float)
        n_pairs = len(self.geometry_model.collisionPairs)
        out = np.empty((q.shape[0], n_pairs))
        data = self.model.createData()
        gdata = pin.GeometryData(self.geometry_model)
        for k in range(q.shape[0]):  # coal evaluates one posture at a time
            for p in range(n_pairs):
                _fresh_gjk_start(gdata, p)
            pin.computeDistances(self.model, data, self.geometry_model, gdata, q[k])
            out[k] = [r.min_distance for r in gdata.distanceResults]
        return out

    def clearances(self, q: npt.ArrayLike) -> FloatArray:
        """Signed distance of every checked link pair [m] (negative: penetration depth).

        Parameters
        ----------
        q :
            Joint positions [rad or m], shape (n_samples, nq).

        Returns
        -------
        :
            Shape (n_samples, n_pairs), columns named by :attr:`pair_names`.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.full((q.shape[0], self.n_pairs), np.inf)
        if self.n_pairs == 0:
            return out
        finite = np.all(np.isfinite(q), axis=1)
        distances = self._geometry_distances(np.where(finite[:, None], q, 0.0))
        np.minimum.at(out.T, self._group, distances.T)
        out[~finite] = -np.inf
        return out


def build_safety_model(
    robot: Any,
    config: SafetyConfig | Mapping[str, Any] | None = None,
    *,
    urdf: str | Path | None = None,
    package_dirs: Sequence[str | Path] = (),
    reference_q: npt.ArrayLike | None = None,
) -> SafetyModel:
    """The safety model of a robot (see :class:`SafetyModel` and the module docstring).

    Parameters
    ----------
    robot :
        An :class:`ident.Robot` (or an object with ``model`` and the limits, plus ``urdf``).
    config :
        The ``safety`` section (a :class:`SafetyConfig` or its mapping); default
        ``SafetyConfig()`` (floor at z = 0, 0.03 m margin,
        self-collision and torque limits on).
    urdf :
        URDF path or text with the collision geometry; default ``robot.urdf_text``.
    package_dirs :
        Folders searched for ``package://`` meshes.
    reference_q :
        The reference posture of the exclusion rule [rad], shape (nq,); default 0 clipped into
        the position limits.

    Raises
    ------
    ModelError
        If the collision geometry cannot be loaded or does not match the robot's joints.
    """
    if config is None:
        config = SafetyConfig()
    elif not isinstance(config, SafetyConfig):
        config = SafetyConfig.model_validate(config)
    return SafetyModel(
        robot,
        config,
        urdf=urdf,
        package_dirs=package_dirs,
        reference_q=reference_q,
    )


def clearances(safety: SafetyModel, q: npt.ArrayLike) -> FloatArray:
    """Signed link-pair distances [m], shape (n_samples, n_pairs).

    See :meth:`SafetyModel.clearances`.
    """
    return safety.clearances(q)


def joint_torques(model: pin.Model, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
    """Nominal inverse dynamics ``pin.rnea`` [N*m or N], shape (n_samples, nv)."""
    from ident.dynamics.pinocchio_check import pinocchio_rnea

    return np.asarray(pinocchio_rnea(model, q, dq, ddq), dtype=float)


def _subsample(n_samples: int, n_check: int) -> npt.NDArray[np.int64]:
    """``n_check`` sample indices spread evenly over ``0..n_samples-1``."""
    if n_check >= n_samples:
        return np.arange(n_samples)
    return np.unique(np.round(np.linspace(0, n_samples, n_check, endpoint=False)).astype(int))


_GJK_START = np.array([1.0, 0.0, 0.0])  # coal's default initial GJK direction


def _fresh_gjk_start(gdata: pin.GeometryData, pair: int) -> None:
    """Start the next GJK of ``pair`` from coal's default direction.

    Pinocchio keeps each pair's last GJK direction in its request and coal starts from it, so
    a distance (exact to GJK's tolerance, ~1e-6 m) would depend on the posture computed before
    it: the cheap term of one particle on the other particles of the swarm (an optimizer on
    the margin then keeps a point that is infeasible on its own), the dense check on the
    sampling rate. From a fixed start, a posture's distances depend on that posture alone.
    """
    gdata.distanceRequests[pair].cached_gjk_guess = _GJK_START


def collision_violations(
    safety: SafetyModel, q: FloatArray, n_check: int | None = None
) -> ConstraintViolations:
    """Cheap clearance constraint of a swarm: distances at ``n_check`` samples per trajectory.

    Uses :meth:`SafetyModel.fast_clearances` (vectorized over the swarm; exact wherever a
    pair is within the margin, so the term equals the exact one at the checked samples).

    Parameters
    ----------
    safety :
        The safety model.
    q :
        Joint positions, shape (n_particles, n_samples, nq).
    n_check :
        Samples per trajectory (evenly spread); default ``safety.config.check_samples``.

    Returns
    -------
    :
        One constraint ``clearance:<pair>`` per link pair:
        ``max(clearance_m - min_t d, 0) / clearance_m`` (with a 1 cm scale when the margin is
        0), i.e. 1 = "touching", 2 = "one margin deep".
    """
    n_check = safety.config.check_samples if n_check is None else int(n_check)
    idx = _subsample(q.shape[1], n_check)
    sub = q[:, idx].reshape(-1, q.shape[2])
    d = safety.fast_clearances(sub).reshape(q.shape[0], idx.size, safety.n_pairs).min(axis=1)
    scale = safety.clearance_m if safety.clearance_m > 0.0 else 0.01
    values = np.maximum(safety.clearance_m - d, 0.0) / scale
    values = np.where(np.isfinite(values), values, NONFINITE_VIOLATION)
    return ConstraintViolations(tuple(f"clearance:{p}" for p in safety.pair_names), values)


def torque_violations(
    safety: SafetyModel,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    n_check: int | None = None,
) -> ConstraintViolations:
    """Torque-limit constraint of a swarm at ``n_check`` samples per trajectory.

    Returns
    -------
    :
        ``torque:<joint>`` = ``max(max_t |tau| - effort, 0) / effort`` for the joints with a
        known effort limit (none when no limit is known).
    """
    known = np.flatnonzero(np.isfinite(safety.effort_max))
    names = tuple(f"torque:{safety.limits.joint_names[j]}" for j in known)
    if known.size == 0:
        return ConstraintViolations(names, np.zeros((q.shape[0], 0)))
    n_check = safety.config.check_samples if n_check is None else int(n_check)
    idx = _subsample(q.shape[1], n_check)
    flat = [a[:, idx].reshape(-1, a.shape[2]) for a in (q, dq, ddq)]
    finite = np.all(np.isfinite(np.hstack(flat)), axis=1)
    tau = np.full((flat[0].shape[0], q.shape[2]), np.inf)
    if finite.any():
        tau[finite] = joint_torques(safety.robot_model, *(f[finite] for f in flat))
    peak = np.abs(tau).reshape(q.shape[0], idx.size, -1).max(axis=1)[:, known]
    limit = safety.effort_max[known]
    values = np.maximum(peak - limit, 0.0) / limit
    return ConstraintViolations(names, np.where(np.isfinite(values), values, NONFINITE_VIOLATION))
