"""Collision, environment and torque model of an excitation trajectory (what a robot can run).

A :class:`SafetyModel` holds, for one robot,

- its URDF **collision geometry** as a Pinocchio ``GeometryModel`` (coal computes the
  distances on the meshes as BVH, :meth:`SafetyModel.clearances`), and the same geometry with
  meshes replaced by their convex hulls, a conservative proxy (a hull contains its mesh) for
  the optimizer's cheap term and a broad phase;
- the **floor**, a half-space ``z <= floor.z`` in the base frame (on by default);
- the **obstacles** of the config: boxes, spheres and half-spaces (a table, a wall), fixed in
  the base frame;
- the **clearance margin** ``clearance_m`` (default 0.03 m) every checked pair must keep;
- the **torque limits**, the URDF ``effort`` of each joint with the nominal model's inverse
  dynamics (``pin.rnea``), next to the position, velocity and acceleration limits.

Checked pairs (the rule, applied once when the model is built, on the exact geometry: the
meshes as loaded, coal BVH, and the URDF's primitives; never on a hull):

1. every pair of robot links except those **excluded**: adjacent (a joint and its parent;
   links welded by a fixed joint belong to the same joint in Pinocchio), named by the MoveIt
   SRDF given as ``safety.srdf`` (``<disable_collisions>``), in contact in the reference
   posture (0 clipped into the limits), or in contact in at least
   :data:`ALWAYS_IN_CONTACT_FRACTION` of :data:`N_EXCLUSION_POSTURES` random postures (the
   MoveIt setup assistant's rule). A remaining pair closer than the margin in every sampled
   posture is an input error (no trajectory could keep the margin);
2. every robot geometry against the floor and every obstacle: **never excluded**. A pair
   whose distance no motion changes (the base on the floor, a first link turning about the
   vertical) is judged once: partly inside is a mounting (the paper robot's joint-1 housing
   sunk into its pedestal), deeper than the geometry's bounding radius (and
   :data:`MOUNT_TOLERANCE_M`) is an input error (a robot inside an obstacle or under the floor).
   Any other environment pair closer than the margin in every sampled posture, or at the
   home posture, is an input error, as are absurd sizes (validation).

Distances are reported per *link pair* (the URDF link names of the two geometries, or the
obstacle name): the minimum over the geometry pairs of the two links.

References
----------
J. Carpentier et al., "The Pinocchio C++ library", SII 2019 (``GeometryModel``); coal
(formerly hpp-fcl) for GJK/EPA signed distances.
"""

from __future__ import annotations

import math
import time

# xml.etree: reads MoveIt's SRDF (<disable_collisions>), which yourdfpy does not read (URDF only)
# and MjSpec has no counterpart for.
import xml.etree.ElementTree as ET
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from pydantic import Field, field_validator, model_validator

from ident.config import StrictModel, file_problem
from ident.dynamics.chain import chain_from_model
from ident.errors import ConfigError, ModelError
from ident.excitation.constraints import NONFINITE_VIOLATION, JointLimits
from ident.excitation.family import ConstraintViolations, FloatArray
from ident.robot.meshes import check_urdf_meshes, resolve_urdf_meshes
from ident.robot.mimic import coupled_model
from ident.robot.urdf_load import prepare_urdf

__all__ = [
    "ALWAYS_IN_CONTACT_FRACTION",
    "DEFAULT_CLEARANCE_M",
    "MAX_CLEARANCE_M",
    "MAX_OBSTACLES",
    "MAX_SIZE_M",
    "MESH_FIX",
    "MIN_LOWERED_CLEARANCE_M",
    "N_EXCLUSION_POSTURES",
    "BoxObstacle",
    "FloorConfig",
    "ObstacleConfig",
    "PAYLOAD",
    "PayloadBox",
    "PlaneObstacle",
    "SafetyConfig",
    "SafetyModel",
    "SphereObstacle",
    "build_safety_model",
    "clearances",
    "collision_geometry_problem",
    "collision_violations",
    "joint_torques",
    "torque_violations",
]

DEFAULT_CLEARANCE_M = 0.03
# the default margin is halved down to this while a link pair cannot keep it [m]
MIN_LOWERED_CLEARANCE_M = 0.002
# a hull distance above this (or above a margin by this) proves the meshes apart: GJK's
# tolerance (1e-6 m) with room to spare [m]
_SCREEN_SLACK_M = 1e-4
N_EXCLUSION_POSTURES = 1000  # random postures of the "always in contact" rule (MoveIt: 1000+)
ALWAYS_IN_CONTACT_FRACTION = 0.95  # MoveIt setup assistant's default
MAX_SIZE_M = 100.0  # obstacle sizes and positions, floor height [m]
MAX_CLEARANCE_M = 10.0  # the margin [m]; also below the robot's reach
MAX_OBSTACLES = 256
MAX_PAYLOAD_SIZE_M = 5.0  # payload box edges and offset from its link [m]
MOUNT_TOLERANCE_M = 0.01  # a base (or a link turning in place) may sink this deep [m] ...
# ... or, for a larger geometry, up to its bounding radius: deeper, it is inside the obstacle
FLOOR = "floor"
PAYLOAD = "payload"  # the link name of the payload's box in pair names ("payload|floor")

Vector3 = tuple[float, float, float]


def _near_robot(value: Vector3) -> Vector3:
    if max(abs(v) for v in value) > MAX_SIZE_M:
        raise ValueError(
            f"position {list(value)} is more than {MAX_SIZE_M:g} m from the robot's base "
            "(millimetres typed as metres?)"
        )
    return value


def _box_edges(value: Vector3, limit: float, what: str) -> Vector3:
    """``value``, a box's edge lengths [m], each in ``(0, limit]``."""
    if min(value) <= 0.0 or max(value) > limit:
        raise ValueError(
            f"every {what} edge must be in (0, {limit:g}] m, got {list(value)} "
            "(millimetres typed as metres?)"
        )
    return value


# ---------------------------------------------------------------------- config schema
class FloorConfig(StrictModel):
    """The floor: the half-space ``z <= z`` of the base frame [m]."""

    enabled: bool = True
    z: float = Field(default=0.0, ge=-MAX_SIZE_M, le=MAX_SIZE_M)


class BoxObstacle(StrictModel):
    """A box: edge lengths ``size`` [m], centre ``position`` [m], orientation ``rpy`` [rad]."""

    size: Vector3
    position: Vector3 = (0.0, 0.0, 0.0)
    rpy: Vector3 = (0.0, 0.0, 0.0)

    @field_validator("size")
    @classmethod
    def _positive(cls, value: Vector3) -> Vector3:
        return _box_edges(value, MAX_SIZE_M, "box")

    @field_validator("position")
    @classmethod
    def _near(cls, value: Vector3) -> Vector3:
        return _near_robot(value)


class SphereObstacle(StrictModel):
    """A sphere of ``radius`` [m] centred at ``position`` [m]."""

    radius: float = Field(gt=0.0, le=MAX_SIZE_M)
    position: Vector3 = (0.0, 0.0, 0.0)

    @field_validator("position")
    @classmethod
    def _near(cls, value: Vector3) -> Vector3:
        return _near_robot(value)


class PlaneObstacle(StrictModel):
    """A half-space: the solid side is ``normal . p <= offset`` [m].

    ``normal`` points into the free space (it is normalized on use): a wall 1 m in front of
    the robot along x is ``{normal: [-1, 0, 0], offset: -1.0}``; a table top at 0.2 m under the
    base is ``{normal: [0, 0, 1], offset: -0.2}``.
    """

    normal: Vector3
    offset: float = Field(ge=-MAX_SIZE_M, le=MAX_SIZE_M)

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


class PayloadBox(StrictModel):
    """The bounding box of a payload (a tool, a grasped object) rigidly attached to a link.

    ``size``: edge lengths [m]; ``position``: the box centre and ``rpy``: its orientation [rad],
    both in the frame of ``link`` (a URDF link or frame name; ``null``: the last moving joint's
    frame, the frame of the last link). The box joins the robot's collision geometry as a link
    named ``payload``: it is checked against the floor, the obstacles and every robot link
    except those rigidly attached to it (the same joint); a link adjacent to it is checked too.
    """

    size: Vector3
    position: Vector3 = (0.0, 0.0, 0.0)
    rpy: Vector3 = (0.0, 0.0, 0.0)
    link: str | None = None

    @field_validator("size")
    @classmethod
    def _positive(cls, value: Vector3) -> Vector3:
        return _box_edges(value, MAX_PAYLOAD_SIZE_M, "payload box")

    @field_validator("position")
    @classmethod
    def _near(cls, value: Vector3) -> Vector3:
        if max(abs(v) for v in value) > MAX_PAYLOAD_SIZE_M:
            raise ValueError(
                f"payload box centre {list(value)} is more than {MAX_PAYLOAD_SIZE_M:g} m from "
                "its link (millimetres typed as metres?)"
            )
        return value


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
      payload_box: {size: [0.1, 0.1, 0.2], position: [0.0, 0.0, 0.1], link: tool0}
    ```

    ``check_samples`` is the number of samples per period at which the optimization's cheap
    constraint term measures the clearances; ``check_rate_hz`` (>= 1000) the rate of the
    dense check of the chosen trajectories. ``srdf`` is a MoveIt SRDF whose
    ``<disable_collisions link1= link2= reason=/>`` pairs are not checked (relative to the
    config file). Sizes are bounded: obstacles and the floor within :data:`MAX_SIZE_M` of the
    base, at most :data:`MAX_OBSTACLES` obstacles, ``clearance_m`` at most
    :data:`MAX_CLEARANCE_M` (and below the robot's reach, checked with the robot).
    """

    floor: FloorConfig = FloorConfig()
    obstacles: tuple[ObstacleConfig, ...] = Field(default=(), max_length=MAX_OBSTACLES)
    clearance_m: float = Field(default=DEFAULT_CLEARANCE_M, ge=0.0, le=MAX_CLEARANCE_M)
    self_collision: bool = True
    srdf: Path | None = None
    torque_limits: bool = True
    check_rate_hz: float = Field(default=1000.0, ge=1000.0)
    check_samples: int = Field(default=16, ge=1)
    payload_box: PayloadBox | None = None


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


def _attach_payload_box(model: pin.Model, geom: pin.GeometryModel, box: PayloadBox) -> None:
    """Add the payload's box to ``geom`` on a new frame :data:`PAYLOAD` of ``model``.

    The frame sits at the box centre, on ``box.link``'s joint (``null``: the last joint), so
    the box moves rigidly with that link and its pairs are named ``payload|...``.

    Raises
    ------
    ConfigError
        If ``box.link`` is not a frame of the model (the message lists the frames of the
        last joint), or the model already has a frame named :data:`PAYLOAD`.
    """
    import coal

    if model.existFrame(PAYLOAD):
        raise ConfigError(
            f"safety.payload_box: the robot already has a link or frame named {PAYLOAD!r}; "
            "rename it in the URDF or leave payload_box out."
        )
    if box.link is None:
        joint = model.njoints - 1
        parent = model.getFrameId(model.names[joint], pin.FrameType.JOINT)
        link_in_joint = pin.SE3.Identity()
    else:
        if not model.existFrame(box.link):
            last = model.njoints - 1
            frames = [f.name for f in model.frames if f.parentJoint == last]
            raise ConfigError(
                f"safety.payload_box.link: {box.link!r} is not a link or frame of the robot; "
                f"frames of the last link: {', '.join(frames)} (null: the last joint's frame)."
            )
        parent = model.getFrameId(box.link)
        frame = model.frames[parent]
        joint, link_in_joint = int(frame.parentJoint), frame.placement
    box_in_link = pin.SE3(_rpy_matrix(box.rpy), np.asarray(box.position, dtype=float))
    placement = link_in_joint * box_in_link  # box centre in the parent joint's frame
    frame_id = model.addFrame(pin.Frame(PAYLOAD, joint, parent, placement, pin.FrameType.OP_FRAME))
    shape = coal.Box(*[float(s) for s in box.size])
    geom.addGeometryObject(pin.GeometryObject(PAYLOAD, joint, frame_id, placement, shape))


def _revolute_text(text: str) -> str:
    """The text Pinocchio reads, rewritten as :meth:`ident.Robot.from_urdf` does."""
    return prepare_urdf(text, "the URDF").text


MESH_FIX = (
    "give the folder that holds them with --package-dir / robot.package_dirs, or set "
    "safety.self_collision: false to design without self-collision checks"
)
"""The fix named when collision meshes are missing (every command that builds a safety model)."""


def _urdf_source(robot: Any, urdf: str | Path | None) -> tuple[str, Path | None, str]:
    """The URDF text, its folder (None for text) and the name that locates it in messages."""
    if urdf is None:
        text = getattr(robot, "urdf_text", None)
        if text is None:
            raise ModelError("the robot has no URDF text; pass urdf= (a path or the text).")
        path = getattr(robot, "urdf_path", None)
        return str(text), None if path is None else Path(path).parent, str(path or "the URDF")
    if isinstance(urdf, Path) or (isinstance(urdf, str) and not urdf.lstrip().startswith("<")):
        return Path(urdf).read_text(encoding="utf-8"), Path(urdf).parent, str(urdf)
    return str(urdf), None, "the URDF"


def collision_geometry_problem(robot: Any, package_dirs: Sequence[str | Path] = ()) -> str:
    """Why self-collision cannot be checked for ``robot`` (empty when it can): the missing
    collision meshes (the first three and their count), or a URDF without geometry.

    ``ident init`` asks before it writes ``safety.self_collision``; a safety model with
    self-collision on raises it, with its fix (:data:`MESH_FIX` for missing meshes).
    """
    return _collision_urdf(robot, None, package_dirs)[2][0]


def _collision_urdf(
    robot: Any, urdf: str | Path | None, package_dirs: Sequence[str | Path]
) -> tuple[str, tuple[tuple[str, str], ...], tuple[str, str]]:
    """The URDF text with its collision meshes found (absolute paths; a link's visual geometry
    where its collision geometry is absent or missing), the notes the certificate shows
    (``(link, what)``), and why self-collision cannot be checked and the fix (``('', '')``
    when it can).

    Raises
    ------
    ModelError
        A mesh that would crash coal (:func:`ident.robot.meshes.check_urdf_meshes`).
    """
    text, base, where = _urdf_source(robot, urdf)
    resolved = resolve_urdf_meshes(text, package_dirs, base, visual_for_collision=True)
    check_urdf_meshes(resolved.text, visual=False, name=where)  # before coal: no segfault
    notes = [(link, "visual mesh used for collision") for link in resolved.visual_for_collision]
    lost = dict.fromkeys(m.link for m in resolved.missing if m.kind == "collision")
    notes += [
        (link, "not checked against the floor and obstacles: its collision mesh is missing")
        for link in lost
    ]
    problem = resolved.missing_line("collision", where)
    if problem:
        return resolved.text, tuple(notes), (problem, MESH_FIX)
    if "<collision" not in resolved.text:
        problem = f"{where} has no <collision> or <visual> geometry"
        fix = (
            "add <collision> geometry to its links, or set safety.self_collision: false to "
            "design without self-collision checks"
        )
        return resolved.text, tuple(notes), (problem, fix)
    return resolved.text, tuple(notes), ("", "")


def _kinematic_model_and_geometry(
    robot: Any,
    urdf: str | Path | None,
    package_dirs: Sequence[str | Path],
    self_collision: bool = True,
) -> tuple[pin.Model, pin.GeometryModel, tuple[tuple[str, str], ...]]:
    """Pinocchio model (same joints as ``robot.model``), its collision GeometryModel and the
    geometry notes of :func:`_collision_urdf` (``(link, what)``).

    The meshes reach Pinocchio as absolute paths in the URDF text (:func:`ident.robot.meshes.
    resolve_urdf_meshes`), not through Pinocchio's ``package_dirs``: its own lookup knows
    neither the URDF's folder nor ``file://`` paths of another machine, and one resolver for
    every loader keeps the safety model, the mesh checks and the replay on the same files.
    """
    text, notes, (problem, fix) = _collision_urdf(robot, urdf, package_dirs)
    if problem and self_collision:
        raise ModelError(f"{problem}; {fix}.")
    text = _revolute_text(text)
    full = pin.buildModelFromXML(text)
    try:
        geom = pin.buildGeomFromUrdfString(full, text, pin.GeometryType.COLLISION, None, [])
    except (RuntimeError, ValueError) as e:
        raise ModelError(
            f"cannot load the URDF's collision geometry ({str(e).splitlines()[0]}); {MESH_FIX}."
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
    # the robot's mimic joints move with their leaders here too (the same q as robot.model)
    mimics = getattr(robot, "mimic_joints", ())
    return (
        coupled_model(full, mimics, str(getattr(robot, "urdf_path", None) or "URDF")),
        geom,
        notes,
    )


_LOADED: dict[
    tuple[Any, ...], tuple[pin.Model, pin.GeometryModel, tuple[tuple[str, str], ...]]
] = {}
_LOADED_HULLS: dict[tuple[Any, ...], pin.GeometryModel] = {}  # the same, meshes as hulls
# the last screening of SafetyModel._screen: its threshold [m] and its bounds
_SCREENED: dict[tuple[Any, ...], tuple[float, FloatArray]] = {}


def _loaded_geometry(
    robot: Any,
    urdf: str | Path | None,
    package_dirs: Sequence[str | Path],
    self_collision: bool = True,
) -> tuple[pin.Model, pin.GeometryModel, tuple[tuple[str, str], ...], tuple[Any, ...]]:
    """:func:`_kinematic_model_and_geometry`, remembered for the last robot (its URDF text,
    joints, locked joints and mesh folders): ``ident init`` builds three safety models of one
    robot, and reading large meshes took seconds each time. Returns copies (the caller adds
    the environment and a payload to them) and the geometry notes."""
    if urdf is None:
        source = getattr(robot, "urdf_text", None)
    elif isinstance(urdf, Path) or not urdf.lstrip().startswith("<"):
        source = Path(urdf).read_text(encoding="utf-8")
    else:
        source = urdf
    key = (
        source,
        tuple(robot.model.names),
        tuple(sorted((getattr(robot, "locked_joints", {}) or {}).items())),
        tuple(str(d) for d in package_dirs),
        self_collision,
    )
    if key not in _LOADED:
        _LOADED.clear()
        _LOADED_HULLS.clear()
        _LOADED[key] = _kinematic_model_and_geometry(robot, urdf, package_dirs, self_collision)
    model, geom, notes = _LOADED[key]
    return model.copy(), geom.clone(), notes, key


def _loaded_hulls(key: tuple[Any, ...], geom: pin.GeometryModel) -> pin.GeometryModel:
    """A copy of ``geom`` with its meshes replaced by their hulls (:func:`_convexify`); the
    first objects, those :func:`_loaded_geometry` loaded under ``key``, from the hulls made
    once per robot, the others (environment, payload: primitives) as they are."""
    if key not in _LOADED_HULLS:
        hulls = _LOADED[key][1].clone()
        _convexify(hulls)
        _LOADED_HULLS[key] = hulls
    out = _LOADED_HULLS[key].clone()
    for obj in list(geom.geometryObjects)[out.ngeoms :]:
        out.addGeometryObject(obj)
    return out


def _with_pairs(geom: pin.GeometryModel, pairs: Sequence[tuple[Any, ...]]) -> pin.GeometryModel:
    """``geom`` with exactly the collision pairs ``(a, b, ...)`` of ``pairs`` (in place)."""
    geom.removeAllCollisionPairs()
    for pair in pairs:
        geom.addCollisionPair(pin.CollisionPair(pair[0], pair[1]))
    return geom


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


_MAX_SRDF_BYTES = 10_000_000


def _read_srdf(path: Path) -> list[tuple[str, str, str]]:
    """The ``<disable_collisions link1= link2= reason=/>`` entries of a MoveIt SRDF.

    Raises
    ------
    ConfigError
        If the file cannot be read or parsed, or is larger than 10 MB.
    """
    problem = file_problem(path)
    if problem is not None:
        raise ConfigError(f"safety.srdf: {path} {problem}; give MoveIt's .srdf file.")
    try:
        with path.open("rb") as f:  # bounded: never more than 10 MB, whatever the file
            data = f.read(_MAX_SRDF_BYTES + 1)
        if len(data) > _MAX_SRDF_BYTES:
            raise ConfigError(f"safety.srdf: {path} is larger than 10 MB; is it an SRDF?")
        root = ET.fromstring(data)
    except (OSError, ET.ParseError) as e:
        raise ConfigError(
            f"safety.srdf: cannot read {path} as an SRDF ({e}); give MoveIt's .srdf file."
        ) from e
    pairs = []
    for node in root.iter("disable_collisions"):
        a, b = node.get("link1"), node.get("link2")
        if not a or not b:
            raise ConfigError(
                f"safety.srdf: {path}: a <disable_collisions> lacks link1 or link2; "
                'write <disable_collisions link1="a" link2="b" reason="Adjacent"/>.'
            )
        pairs.append((a, b, node.get("reason") or "no reason given"))
    return pairs


def _bounding_radius(obj: pin.GeometryObject) -> float:
    """Radius [m] of a ball about the parent joint's origin that holds the geometry."""
    shape = obj.geometry
    shape.computeLocalAABB()
    centre = obj.placement.act(np.asarray(shape.aabb_center, dtype=float))
    return float(np.linalg.norm(centre) + float(shape.aabb_radius))


def _motion_coefficients(model: pin.Model, geom: pin.GeometryModel, n_robot: int) -> FloatArray:
    """Per robot geometry, how far its points can move per unit of each joint's motion.

    Row ``g``, column ``v``: for a revolute ancestor joint, a bound on the distance of the
    geometry's points from the joint's origin [m] (the joint offsets along the chain plus the
    geometry's bounding radius, whatever the posture); 1 for a prismatic ancestor; 0 for
    joints that do not move it. A point's displacement over a step is at most
    ``row . |dq| dt``. Shape (n_robot, nv).
    """
    out = np.zeros((n_robot, model.nv))
    offsets = [
        float(np.linalg.norm(model.jointPlacements[j].translation)) for j in range(model.njoints)
    ]
    chain = chain_from_model(model)  # a mimic joint moves with its leader: |m| per unit of it
    for g in range(n_robot):
        obj = geom.geometryObjects[g]
        reach = _bounding_radius(obj)
        j = int(obj.parentJoint)
        while j > 0:
            scale = abs(float(chain.scaling[j - 1]))
            out[g, chain.coordinates[j - 1]] += scale * (1.0 if chain.prismatic[j - 1] else reach)
            reach += offsets[j]
            j = int(model.parents[j])
    return out


def _reach(
    model: pin.Model,
    objects: Sequence[pin.GeometryObject],
    joint_of: Sequence[int],
    coefficients: FloatArray,
) -> float:
    """A bound [m] on the distance of any point of the robot from its base: for each of the
    robot's objects (``joint_of``: its parent joint), the first joint's offset plus the
    object's motion coefficient about it, or its bounding radius when fixed to the base."""
    offsets = [float(np.linalg.norm(p.translation)) for p in model.jointPlacements]
    return max(
        (
            float(coefficients[g, model.joints[1].idx_v]) + offsets[1]
            if joint_of[g] > 0
            else _bounding_radius(objects[g])
            for g in range(len(joint_of))
        ),
        default=0.0,
    )


def _add_environment(geom: pin.GeometryModel, config: SafetyConfig) -> list[str]:
    """Add the floor and the obstacles of ``config`` to ``geom``; their names, in order.

    Obstacles are attached to the universe (joint 0, frame 0), fixed in the base frame.
    """
    import coal

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
    return environment


def _candidate_pairs(
    link_of: Sequence[str],
    environment: Sequence[str],
    excluded: Mapping[tuple[str, str], str],
    self_collision: bool,
) -> list[tuple[int, int, str, str]]:
    """``(geom a, geom b, pair name, kind)`` of every pair that may be checked: the robot's
    link pairs not ``excluded`` (with ``self_collision``), then every robot object against
    each environment object (numbered after the ``len(link_of)`` robot objects)."""
    n_robot = len(link_of)
    candidates: list[tuple[int, int, str, str]] = []
    if self_collision:
        for a in range(n_robot):
            for b in range(a + 1, n_robot):
                name = f"{link_of[a]}|{link_of[b]}"
                if link_of[a] != link_of[b] and _pair_key(link_of[a], link_of[b]) not in excluded:
                    candidates.append((a, b, name, "self"))
    for e, env_name in enumerate(environment):
        kind = "floor" if env_name == FLOOR else "obstacle"
        for a in range(n_robot):
            candidates.append((a, n_robot + e, f"{link_of[a]}|{env_name}", kind))
    return candidates


def _constant_pairs(
    objects: Sequence[pin.GeometryObject],
    candidates: Sequence[tuple[int, int, str, str]],
    constant: Mapping[int, float],
) -> tuple[ExcludedPair, ...]:
    """The ``candidates`` no motion changes (``constant``: candidate index -> distance [m]),
    named by the robot object and the environment object."""
    return tuple(
        ExcludedPair(
            f"{objects[candidates[k][0]].name}|{candidates[k][2].split('|', 1)[1]}",
            f"constant distance {d:.4f} m (no joint moves one relative to the other); judged once",
        )
        for k, d in constant.items()
    )


def _pair_motion_coefficients(
    coefficients: FloatArray,
    n_environment: int,
    pairs: Sequence[tuple[int, int, str, str]],
    group: npt.NDArray[np.int64],
    n_pairs: int,
    nv: int,
) -> FloatArray:
    """Read-only shape (n_pairs, nv): per checked pair, the largest over its geometry
    ``pairs`` (row ``group[p]``) of the robot objects' ``coefficients`` (shape
    (n_robot, nv); 0 for the environment) of the joints that move one side but not both."""
    out = np.zeros((n_pairs, nv))
    padded = np.vstack([coefficients, np.zeros((n_environment, nv))])
    for p, (a, b, _, _) in enumerate(pairs):
        # the joints above both bodies move them together: only the others change the
        # pair's relative posture (for an environment pair, every joint above the link)
        common = (padded[a] > 0.0) & (padded[b] > 0.0)
        row = out[group[p]]
        np.maximum(row, np.where(common, 0.0, padded[a] + padded[b]), out=row)
    out.setflags(write=False)
    return out


def _mesh_pairs(
    geom: pin.GeometryModel, pairs: Sequence[tuple[int, int, str, str]]
) -> npt.NDArray[np.bool_]:
    """Per geometry pair, whether a mesh is on either side (where the hull and the geometry
    differ: the exact certificate measures them on the mesh).

    A mesh against a half-space (the floor, a plane) does not count: the point of a mesh
    nearest a plane is a vertex, one of its hull's, so apart they have the same distance;
    sunk in, :meth:`SafetyModel.clearances` keeps the deeper of the two, the hull's (its
    deepest vertex).
    """
    import coal

    is_mesh = [isinstance(o.geometry, coal.BVHModelBase) for o in geom.geometryObjects]
    plane = [isinstance(o.geometry, coal.Halfspace) for o in geom.geometryObjects]
    return np.array(
        [(is_mesh[a] or is_mesh[b]) and not (plane[a] or plane[b]) for a, b, _, _ in pairs],
        dtype=bool,
    )


def _effort_max(limits: JointLimits, torque_limits: bool) -> FloatArray:
    """Read-only torque limits [N*m or N], shape (nv,): the robot's effort limits
    (``limits.tau_max``), ``inf`` where unknown (``limits.unknown`` says why) or when
    ``torque_limits`` is off."""
    out = np.array(limits.tau_max if torque_limits else np.full(limits.nq, np.inf), dtype=float)
    out.setflags(write=False)
    return out


def _adjacent_pairs(
    parents: Sequence[int], link_of: Sequence[str], joint_of: Sequence[int], n_robot: int
) -> tuple[dict[tuple[str, str], str], dict[tuple[str, str], list[tuple[int, int]]]]:
    """The robot's link pairs (keyed by the sorted link names) that are adjacent or hold a
    payload, with the reason, and the geometry object pairs ``(a, b)`` of every link pair
    (``link_of``, ``joint_of``: the link and parent joint of each of the ``n_robot`` robot
    objects; ``parents``: each joint's parent joint)."""
    excluded: dict[tuple[str, str], str] = {}
    geometry_pairs: dict[tuple[str, str], list[tuple[int, int]]] = {}
    for a in range(n_robot):
        for b in range(a + 1, n_robot):
            if link_of[a] == link_of[b]:
                continue
            key = _pair_key(link_of[a], link_of[b])
            ja, jb = joint_of[a], joint_of[b]
            # a payload's box is checked against the links next to it: only the links
            # it is fixed to (the same joint) are excluded
            next_to = PAYLOAD not in key and (parents[ja] == jb or parents[jb] == ja)
            if ja == jb and PAYLOAD in key:
                excluded.setdefault(key, "payload attached (fixed to this link)")
            elif ja == jb or next_to:
                excluded.setdefault(key, "adjacent")
            geometry_pairs.setdefault(key, []).append((a, b))
    return excluded, geometry_pairs


def _add_srdf_exclusions(excluded: dict[tuple[str, str], str], srdf: Path, links: set[str]) -> None:
    """Add to ``excluded`` the pairs of ``links`` the SRDF disables (not already excluded)."""
    for first, second, reason in _read_srdf(srdf):
        key = _pair_key(first, second)
        if first in links and second in links and key not in excluded:
            excluded[key] = f"SRDF ({reason})"


def _sphere_bounds(
    model: pin.Model,
    geom: pin.GeometryModel,
    pairs: Sequence[tuple[int, int]],
    postures: FloatArray,
) -> FloatArray:
    """Distances of the spheres around the geometry ``pairs`` (each about its local bounding
    box's centre, of the box's half-diagonal: it holds the geometry) at ``postures`` [m],
    shape (n_postures, n_pairs): a lower bound of the geometries' distance."""
    objects = geom.geometryObjects
    used = sorted({g for pair in pairs for g in pair})
    centre = np.zeros((len(objects), 3))
    radius = np.zeros(len(objects))
    joint = np.zeros(len(objects), dtype=int)
    for g in used:
        shape = objects[g].geometry
        shape.computeLocalAABB()
        centre[g] = objects[g].placement.act(np.asarray(shape.aabb_center, dtype=float))
        radius[g] = float(shape.aabb_radius)
        joint[g] = int(objects[g].parentJoint)
    data = model.createData()
    rotation = np.empty((postures.shape[0], model.njoints, 3, 3))
    translation = np.empty((postures.shape[0], model.njoints, 3))
    for s, q in enumerate(postures):
        pin.forwardKinematics(model, data, q)
        for j in range(model.njoints):
            rotation[s, j] = data.oMi[j].rotation
            translation[s, j] = data.oMi[j].translation
    world = np.einsum("sgij,gj->sgi", rotation[:, joint], centre) + translation[:, joint]
    a, b = (np.array([pair[k] for pair in pairs], dtype=int) for k in (0, 1))
    gap = np.linalg.norm(world[:, a] - world[:, b], axis=2)
    return np.asarray(gap - radius[a] - radius[b])


def _flat_pairs(
    tested: Sequence[tuple[str, str]],
    geometry_pairs: Mapping[tuple[str, str], list[tuple[int, int]]],
) -> tuple[list[tuple[int, int]], npt.NDArray[np.int64]]:
    """The geometry object pairs of the ``tested`` link pairs, in order, and the index in
    ``tested`` of the link pair each belongs to."""
    pairs = [ab for k in tested for ab in geometry_pairs[k]]
    owner = np.array([i for i, k in enumerate(tested) for _ in geometry_pairs[k]], dtype=int)
    return pairs, owner


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
        Robot link pairs left out, with the reason: ``adjacent``, ``SRDF``, ``reference
        contact`` or ``always in contact`` (judged on the exact geometry, never on a hull).
    constant_pairs :
        Environment pairs whose distance no motion changes (the base on the floor, a first
        link turning on it), judged once when the model is built, with their distance.
    geometry_notes :
        ``(link, what)``: links whose visual geometry stands in for their collision geometry,
        and links left without geometry (``self_collision: false`` with a mesh missing).
    clearance_m :
        Required clearance [m].
    motion_coefficients :
        Shape (n_pairs, nv): a pair's relative displacement over a step is at most
        ``motion_coefficients @ (|dq| dt)`` [m] (see :func:`_motion_coefficients`; the joints
        above both links of a pair move them together and count 0).
    reach_m :
        A bound on the distance of any point of the robot from its base [m].
    seconds_per_posture, hull_seconds_per_posture :
        CPU of one posture of the dense check [s] (the meshes' exact distances timed when
        the model is built, at random postures), and of the same on the hulls (the
        optimizer's cheap term), for the run's time estimate.
    keepable_clearances :
        Per tested link pair, its largest clearance over the sampled postures [m]: exact
        below the margin asked for, at least that margin otherwise.
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
        home_q: npt.ArrayLike | None = None,
        rng: np.random.Generator | int | None = 0,
        lower_margin: bool | None = None,
    ) -> None:
        self.config = config
        self.clearance_m = float(config.clearance_m)
        # the default margin (no safety.clearance_m given) may be lowered to one the robot's
        # links can keep (see _self_exclusions); None: lower it only when not given
        self.lower_margin = (
            "clearance_m" not in config.model_fields_set if lower_margin is None else lower_margin
        )
        self.margin_note = ""
        self.seconds_per_posture = self.hull_seconds_per_posture = 0.0  # _poor_hull_pairs
        self._hull_geometry: pin.GeometryModel | None = None
        self.keepable_clearances: dict[tuple[str, str], float] = {}  # see _settle_margin
        self.robot_model: pin.Model = robot.model
        self.limits = JointLimits.from_robot(robot)
        # geometry_notes: (link, what) of visual stand-ins and links without geometry
        model, geom, self.geometry_notes, self._geometry_key = _loaded_geometry(
            robot, urdf, package_dirs, config.self_collision
        )
        if config.payload_box is not None:  # part of the robot: before anything counts links
            _attach_payload_box(model, geom, config.payload_box)
        self.model = model
        n_robot = len(geom.geometryObjects)
        objects = geom.geometryObjects
        link_of = [model.frames[o.parentFrame].name for o in objects]
        joint_of = [int(o.parentJoint) for o in objects]
        coefficients = _motion_coefficients(model, geom, n_robot)
        self.reach_m = _reach(model, objects, joint_of, coefficients)
        if n_robot and self.clearance_m > self.reach_m:
            raise ConfigError(
                f"safety.clearance_m = {self.clearance_m:g} m is larger than the robot's reach "
                f"({self.reach_m:.3f} m): no posture could keep it; give a margin of a few "
                "centimetres (default 0.03)."
            )
        environment = _add_environment(geom, config)
        self.postures = self._exclusion_postures(reference_q, rng)
        excluded = (
            self._self_exclusions(robot, geom, link_of, joint_of, n_robot)
            if config.self_collision
            else {}
        )
        candidates = _candidate_pairs(link_of, environment, excluded, config.self_collision)
        _estimate_environment(n_robot, len(environment))
        constant = self._judge_candidates(geom, candidates, home_q)
        kept = [k for k in range(len(candidates)) if k not in constant]
        self.excluded_pairs = tuple(
            ExcludedPair(f"{a}|{b}", reason) for (a, b), reason in excluded.items()
        )
        self.constant_pairs = _constant_pairs(objects, candidates, constant)
        kept_pairs = [candidates[k] for k in kept]
        self.exact_geometry_model = _with_pairs(geom, kept_pairs)
        self.geometry_model = _with_pairs(self._hulls(geom), kept_pairs)
        geometry_pair_names = [pair[2] for pair in kept_pairs]
        self.pair_names: tuple[str, ...] = tuple(dict.fromkeys(geometry_pair_names))
        kinds = {pair[2]: pair[3] for pair in kept_pairs}
        self.pair_kinds: tuple[str, ...] = tuple(kinds[n] for n in self.pair_names)
        self._group = np.array([self.pair_names.index(n) for n in geometry_pair_names], dtype=int)
        self.motion_coefficients = _pair_motion_coefficients(
            coefficients, len(environment), kept_pairs, self._group, self.n_pairs, model.nv
        )
        self._mesh_pairs = _mesh_pairs(geom, kept_pairs)
        self._hull_proxy_poor = self._poor_hull_pairs()
        self.effort_max: FloatArray = _effort_max(self.limits, config.torque_limits)

        self._prepare_fast()

    # ------------------------------------------------------------------ building
    def _self_exclusions(
        self,
        robot: Any,
        geom: pin.GeometryModel,
        link_of: list[str],
        joint_of: list[int],
        n_robot: int,
    ) -> dict[tuple[str, str], str]:
        """Robot link pairs left out, keyed by the sorted link names, with the reason.

        Adjacent (parent and child joints, links welded by fixed joints included), named in
        the SRDF, in contact (exact geometry) in the reference posture, or in contact in at
        least :data:`ALWAYS_IN_CONTACT_FRACTION` of the random postures. A remaining pair that
        is closer than the margin in every posture is an input error.

        The convex hulls screen the postures first (:meth:`_screen`): a hull contains its
        mesh, so two hulls apart are two meshes apart; the exact geometry is measured only
        where the hulls are close. The answer is the exact geometry's.
        """
        parents = list(self.model.parents)
        excluded, geometry_pairs = _adjacent_pairs(parents, link_of, joint_of, n_robot)
        if self.config.srdf is not None:
            _add_srdf_exclusions(excluded, Path(self.config.srdf), set(link_of))
        tested = [k for k in geometry_pairs if k not in excluded]
        if not tested:
            return excluded
        pairs, _ = _flat_pairs(tested, geometry_pairs)
        hull = self._screen(geom, pairs)
        screened = dict(zip(pairs, hull.T, strict=True))
        self._add_contact_exclusions(excluded, geom, tested, geometry_pairs, screened)
        if self.clearance_m > 0.0:
            tested = [k for k in tested if k not in excluded]
            self._settle_margin(geom, tested, geometry_pairs, screened)
        return excluded

    def _screen(self, geom: pin.GeometryModel, pairs: list[tuple[int, int]]) -> FloatArray:
        """Lower bounds of the exact distances of the geometry ``pairs`` at the exclusion
        postures [m], shape (n_postures, n_pairs): their convex hulls' signed distance (meshes
        replaced by their hulls, primitives as they are; a hull contains its mesh) wherever
        the bounding spheres (:func:`_sphere_bounds`, containing the geometry) are within
        the margin (and :data:`_SCREEN_SLACK_M`), the spheres' distance elsewhere."""
        threshold = self.clearance_m + _SCREEN_SLACK_M
        key = (self._geometry_key, tuple(pairs), self.postures.tobytes())
        if key in _SCREENED and _SCREENED[key][0] >= threshold:
            # the same robot, pairs and postures screened at a margin at least as large (init
            # builds three models): every bound there is exact below this one's threshold
            return _SCREENED[key][1].copy()
        out = _sphere_bounds(self.model, geom, pairs, self.postures)
        near = out < threshold
        if near.any():
            hull = self._hulls(geom)
            hull.removeAllCollisionPairs()
            for a, b in pairs:
                hull.addCollisionPair(pin.CollisionPair(a, b))
            data, gdata = self.model.createData(), _geometry_data(hull)
            for s in np.flatnonzero(near.any(axis=1)).tolist():  # coal: one posture at a time
                pin.updateGeometryPlacements(self.model, data, hull, gdata, self.postures[s])
                for p in np.flatnonzero(near[s]).tolist():
                    out[s, p] = pin.computeDistance(hull, gdata, p).min_distance
            hull.removeAllCollisionPairs()
        _SCREENED.clear()
        _SCREENED[key] = (threshold, out.copy())
        return out

    def _hulls(self, geom: pin.GeometryModel) -> pin.GeometryModel:
        """``geom`` (robot and environment, before any pair is chosen) with every mesh
        replaced by its convex hull (:func:`_convexify`), made once per model."""
        if self._hull_geometry is None:
            self._hull_geometry = _loaded_hulls(self._geometry_key, geom)
        return self._hull_geometry

    def _add_contact_exclusions(
        self,
        excluded: dict[tuple[str, str], str],
        geom: pin.GeometryModel,
        tested: list[tuple[str, str]],
        geometry_pairs: dict[tuple[str, str], list[tuple[int, int]]],
        screened: Mapping[tuple[int, int], FloatArray],
    ) -> None:
        """Add to ``excluded`` the ``tested`` link pairs in contact (exact geometry) in the
        reference posture, or in at least :data:`ALWAYS_IN_CONTACT_FRACTION` of the random
        ones (``geometry_pairs``: the geometry object pairs of each link pair; ``screened``:
        their hulls' distances per posture, shape (n_postures,)).

        The exact geometry is tested only where the hulls are within
        :data:`_SCREEN_SLACK_M` (hulls apart: meshes apart), and a pair's random postures
        only until so many are found apart that the fraction cannot be reached.
        """
        pairs, owner = _flat_pairs(tested, geometry_pairs)
        near = np.column_stack([screened[ab] <= _SCREEN_SLACK_M for ab in pairs])
        geom.removeAllCollisionPairs()
        for a, b in pairs:
            geom.addCollisionPair(pin.CollisionPair(a, b))
        data, gdata = self.model.createData(), pin.GeometryData(geom)
        for request in gdata.collisionRequests:
            request.security_margin = 0.0

        def contact(s: int, columns: npt.NDArray[np.int_]) -> bool:
            pin.updateGeometryPlacements(self.model, data, geom, gdata, self.postures[s])
            return any(pin.computeCollision(geom, gdata, int(p)) for p in columns if near[s, p])

        n_random = self.postures.shape[0] - 1
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
        self,
        geom: pin.GeometryModel,
        tested: list[tuple[str, str]],
        geometry_pairs: dict[tuple[str, str], list[tuple[int, int]]],
        screened: Mapping[tuple[int, int], FloatArray],
    ) -> None:
        """Check that every ``tested`` link pair can keep the margin in some posture.

        A margin the user did not choose is lowered (halved, down to
        :data:`MIN_LOWERED_CLEARANCE_M`) until they can (``clearance_m`` and ``margin_note``
        updated); a pair closer than the margin in every posture is a :class:`ConfigError`.
        Each pair's largest clearance over the postures is measured once
        (:meth:`_largest_clearances`) and compared with every halved margin.
        """
        pairs, owner = _flat_pairs(tested, geometry_pairs)
        hull = np.column_stack([screened[ab] for ab in pairs])
        largest = self._largest_clearances(geom, pairs, owner, len(tested), hull)
        self.keepable_clearances = dict(zip(tested, largest.tolist(), strict=True))
        margin = self.clearance_m
        always = largest < margin  # closer than the margin in every posture
        # a margin the user did not choose is lowered (halved, down to 2 mm) until every
        # pair can keep it in some posture; a chosen one is an input error below
        while self.lower_margin and always.any() and margin / 2.0 >= MIN_LOWERED_CLEARANCE_M:
            margin /= 2.0
            always = largest < margin
        if margin < self.clearance_m and not always.any():
            close = ", ".join(
                f"{a}-{b}"
                for (a, b), d in zip(tested, largest, strict=True)
                if d < self.clearance_m
            )
            self.margin_note = (
                f"safety margin lowered from the default {self.clearance_m:g} m to "
                f"{margin:g} m: the links {close} are closer than the default in every "
                "sampled posture (set safety.clearance_m to choose the margin)"
            )
            self.clearance_m = margin
        for i, key in enumerate(tested):
            if always[i]:
                raise ConfigError(
                    f"safety.clearance_m = {self.clearance_m:g} m: the links {key[0]} and "
                    f"{key[1]} are closer than that in every one of "
                    f"{self.postures.shape[0]} postures (the reference and random ones), so "
                    "no trajectory can keep it; lower safety.clearance_m, or disable the "
                    "pair in a MoveIt SRDF (safety.srdf) if they may touch."
                )

    def _largest_clearances(
        self,
        geom: pin.GeometryModel,
        pairs: list[tuple[int, int]],
        owner: npt.NDArray[np.int_],
        n_links: int,
        hull: FloatArray,
    ) -> FloatArray:
        """Per link pair, the largest over the postures of its clearance (the smallest
        distance of its geometry ``pairs``, ``owner``: the link pair of each) [m], shape
        (n_links,): exact where below the margin; at least the margin otherwise.

        ``hull`` (n_postures, n_pairs): the hulls' distances, lower bounds of the exact ones.
        A link pair whose hulls keep the margin in some posture keeps it. For the others the
        exact geometry is measured posture by posture (those whose hulls are farthest apart
        first, and only the geometry pairs whose hulls are within the margin: the others
        cannot bring the link pair below it), until a posture keeps the margin.
        """
        screen = self.clearance_m + _SCREEN_SLACK_M
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
        data, gdata = self.model.createData(), _geometry_data(geom, signed=False)
        for i in close:
            mine = [k for k, p in enumerate(columns) if owner[p] == i]
            largest[i] = -np.inf
            for s in np.argsort(-link_hull[:, i], kind="stable").tolist():
                pin.updateGeometryPlacements(self.model, data, geom, gdata, self.postures[s])
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
                if largest[i] >= self.clearance_m:
                    break
        geom.removeAllCollisionPairs()
        return largest

    def _collisions(
        self,
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
        data = self.model.createData()
        gdata = pin.GeometryData(geom)
        for request in gdata.collisionRequests:
            request.security_margin = margin
        for s in np.flatnonzero(where.any(axis=1)).tolist():  # coal: one posture at a time
            pin.updateGeometryPlacements(self.model, data, geom, gdata, postures[s])
            for p in np.flatnonzero(where[s]).tolist():
                out[s, p] = pin.computeCollision(geom, gdata, p)
        geom.removeAllCollisionPairs()
        return out

    def _judge_candidates(
        self,
        geom: pin.GeometryModel,
        candidates: list[tuple[int, int, str, str]],
        home_q: npt.ArrayLike | None,
    ) -> dict[int, float]:
        """Check the environment pairs before any motion; return those of constant distance.

        A robot geometry fixed to the base, or one whose distance to an obstacle no joint
        changes (a first link turning on the floor), has one distance: below
        ``-MOUNT_TOLERANCE_M`` (inside the floor or an obstacle) it is an input error;
        otherwise the pair is judged once and not checked along trajectories. Any other
        environment pair closer than the margin in every sampled posture, or at the home
        posture when one is given, is an input error.
        """
        env = [k for k, c in enumerate(candidates) if c[3] != "self"]
        constant: dict[int, float] = {}
        if not env:
            return constant
        pairs = [(candidates[k][0], candidates[k][1]) for k in env]
        n_env = min(self.postures.shape[0], 101)
        # the hulls screen: hulls apart by the margin are meshes apart by it
        hull = self._exact_distances(self._hulls(geom), pairs, self.postures[:n_env])
        near = hull < self.clearance_m + _SCREEN_SLACK_M
        within = self._collisions(geom, pairs, self.postures[:n_env], self.clearance_m, near)
        always = [env[i] for i in np.flatnonzero(within.all(axis=0))]
        if always:
            probe = self.postures[: min(n_env, 6)]
            d = self._exact_distances(
                geom, [(candidates[k][0], candidates[k][1]) for k in always], probe
            )
            for i, k in enumerate(always):
                a, _, name, _ = candidates[k]
                link, obstacle = name.split("|", 1)
                if np.ptp(d[:, i]) <= 1e-6:
                    shape = geom.geometryObjects[a].geometry
                    shape.computeLocalAABB()
                    if d[0, i] < -max(MOUNT_TOLERANCE_M, float(shape.aabb_radius)):
                        raise ConfigError(
                            f"safety: the robot's {link} is {-d[0, i]:.3f} m inside "
                            f"{'the floor' if obstacle == FLOOR else repr(obstacle)} whatever "
                            "its joints do; check the obstacle's position and size (and "
                            "safety.floor.z) in metres."
                        )
                    constant[k] = float(d[0, i])
                else:
                    raise ConfigError(
                        f"safety: the robot's {link} is closer than clearance_m = "
                        f"{self.clearance_m:g} m to "
                        f"{'the floor' if obstacle == FLOOR else repr(obstacle)} in every one "
                        f"of {n_env} sampled postures (e.g. {d[0, i]:.3f} m in the reference "
                        "posture); move the obstacle (positions in metres, base frame) or "
                        "lower the margin."
                    )
        if home_q is not None:
            rest = [k for k in env if k not in constant]
            home = np.asarray(home_q, dtype=float)[None, :]
            pairs = [(candidates[k][0], candidates[k][1]) for k in rest]
            d = self._exact_distances(geom, pairs, home)[0]
            for i, k in enumerate(rest):
                if d[i] < self.clearance_m:
                    link, obstacle = candidates[k][2].split("|", 1)
                    raise ConfigError(
                        f"controller.home: the robot's {link} is {d[i]:.3f} m from "
                        f"{'the floor' if obstacle == FLOOR else repr(obstacle)}, below "
                        f"safety.clearance_m = {self.clearance_m:g} m; choose another home "
                        "posture or move the obstacle."
                    )
        return constant

    def _exact_distances(
        self, geom: pin.GeometryModel, pairs: list[tuple[int, int]], postures: FloatArray
    ) -> FloatArray:
        """Distances of geometry pairs on the given (exact) geometry [m], shape (n, n_pairs)."""
        out = np.empty((postures.shape[0], len(pairs)))
        geom.removeAllCollisionPairs()
        for a, b in pairs:
            geom.addCollisionPair(pin.CollisionPair(a, b))
        data = self.model.createData()
        gdata = _geometry_data(geom)
        for s, q in enumerate(postures):
            pin.updateGeometryPlacements(self.model, data, geom, gdata, q)
            for p in range(len(pairs)):
                out[s, p] = pin.computeDistance(geom, gdata, p).min_distance
        geom.removeAllCollisionPairs()
        return out

    def _poor_hull_pairs(self) -> npt.NDArray[np.bool_]:
        """Mesh pairs whose hulls are closer than the margin in at least half of 100 sampled
        postures: the cheap term measures them on the meshes (a hull would forbid too much).
        Sets :attr:`seconds_per_posture` (:meth:`_measure_exact_cost`) on the way."""
        poor = np.zeros(self._mesh_pairs.shape, dtype=bool)
        n = 101 if self._mesh_pairs.any() and self.clearance_m > 0.0 else 11
        start = time.process_time()
        hull = self._distances(self.geometry_model, self.postures[:n])
        self.seconds_per_posture = (time.process_time() - start) / n
        self.hull_seconds_per_posture = self.seconds_per_posture
        if n == 11:
            return poor
        self._measure_exact_cost(hull)
        return self._mesh_pairs & (np.mean(hull < self.clearance_m, axis=0) >= 0.5)

    def _measure_exact_cost(self, hull: FloatArray) -> None:
        """Add to :attr:`seconds_per_posture` (the hulls' and primitives' CPU of one posture
        of the dense check, timed) the meshes': from ``hull``, the hulls' distances at sampled
        postures (n, n_geometry_pairs) [m], each mesh pair's exact distance (timed here on
        one posture) where its hulls are within the margin and 1 mm (where the dense check,
        :meth:`clearances` with ``within``, measures the mesh)."""
        mesh = np.flatnonzero(self._mesh_pairs)
        share = np.mean(hull[:, mesh] < self.clearance_m + 1e-3, axis=0)
        needed = mesh[share > 0.0]
        if not needed.size:
            return
        gdata = _geometry_data(self.exact_geometry_model)
        row = np.zeros(hull.shape[1])
        start = time.process_time()
        self._exact_into(self.postures[1], needed.tolist(), gdata, row)
        per_pair = (time.process_time() - start) / needed.size
        self.seconds_per_posture += per_pair * float(share.sum())

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

    def fast_clearances(self, q: npt.ArrayLike) -> FloatArray:
        """Clearances of the link pairs, vectorized over postures, for the cheap term [m].

        Never more than the exact clearance (every proxy is conservative), and equal to it
        wherever a pair is within the margin without touching, except for meshes, whose
        convex hull stands in (a hull contains its mesh, so its distance is a lower bound).
        Where a pair touches, the depth is the bound's (the capsule around a cylinder, a
        mesh's hull): as deep or deeper than the exact one, without coal's EPA.

        - cylinder, capsule and sphere geometry is handled by compiled code over all postures
          (:mod:`ident.excitation._fast_clearance`): exact against half-spaces (the floor,
          planes); for a cylinder against another geometry the capsule around it gives a
          lower bound, and where that bound is within the margin coal computes the exact
          distance (only for those postures and pairs; not where the capsules inside the two
          cylinders already touch: the cylinders do too);
        - every other pair goes through coal, meshes as their convex hulls; where a pair's
          hulls are closer than the margin in most postures (:meth:`_poor_hull_pairs`: the
          UR5's forearm and wrist 2) the mesh itself is measured wherever the hulls are within
          the margin.

        Shape (n_samples, n_pairs). Each posture's row depends on that posture alone (not on
        the others passed with it).
        """
        q, distances, need, finite = self._fast_bounds(np.atleast_2d(np.asarray(q, dtype=float)))
        rows, pairs = np.nonzero(need)
        self._refine(q, rows, pairs, distances)
        out = self._pair_minimum(distances)
        out[~finite] = -np.inf
        return out

    def _pair_minimum(self, distances: FloatArray) -> FloatArray:
        """Per link pair, the smallest of its geometry pairs' columns: (n, n_geometry_pairs)
        -> (n, n_pairs) (``np.minimum.reduceat`` over the columns sorted by link pair)."""
        if self.n_pairs == 0:
            return np.full((distances.shape[0], 0), np.inf)
        order = np.argsort(self._group, kind="stable")
        starts = np.searchsorted(self._group[order], np.arange(self.n_pairs))
        return np.asarray(np.minimum.reduceat(distances[:, order], starts, axis=1))

    def fast_min_clearances(self, q: npt.ArrayLike) -> FloatArray:
        """The smallest :meth:`fast_clearances` of each trajectory, pair by pair [m].

        ``fast_min_clearances(q) == fast_clearances(q.reshape(-1, nq)).reshape(n, s, -1)
        .min(axis=1)``, bit for bit, with fewer exact distances: of a trajectory's postures
        whose lower bound (capsule, hull) of a pair is within the margin, coal measures them
        in increasing order of the bound and stops once the next bound is not below the
        smallest distance found (no posture left can be closer).

        Parameters
        ----------
        q :
            Joint positions [rad or m], shape (n_trajectories, n_samples, nq).

        Returns
        -------
        :
            Shape (n_trajectories, n_pairs).
        """
        q = np.asarray(q, dtype=float)
        n_traj, n_samples = q.shape[0], q.shape[1]
        flat, distances, need, finite = self._fast_bounds(q.reshape(n_traj * n_samples, -1))
        # the per-trajectory, per-link-pair minimum of what needs no refinement
        known = self._pair_minimum(np.where(need, np.inf, distances))
        best = known.reshape(n_traj, n_samples, self.n_pairs).min(axis=1)
        rows, pairs = np.nonzero(need)
        traj, link = rows // n_samples, self._group[pairs]
        bound = distances[rows, pairs]
        useful = bound < best[traj, link]  # only what can lower the minimum
        rows, pairs, traj, link, bound = (a[useful] for a in (rows, pairs, traj, link, bound))
        if rows.size:
            model, geom = self.model, self.exact_geometry_model
            data, gdata = _refine_scratch(self, model, geom)
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
        self, q: FloatArray
    ) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_], npt.NDArray[np.bool_]]:
        """Lower bounds of every geometry pair's distance and where the exact value is needed.

        Returns ``q`` with non-finite postures set to 0 (n, nq); ``distances``
        (n, n_geometry_pairs) [m], exact for half-spaces, primitives coal handles and hulls of
        convex geometry, a capsule's or a hull's lower bound elsewhere; ``need``
        (n, n_geometry_pairs): a cylinder pair or a poor-hull mesh pair whose bound is within
        the margin (:meth:`_refine` makes it exact); ``finite`` (n,): the postures without
        NaN (the others are measured at 0).
        """
        from ident.excitation._fast_clearance import joint_frames, primitive_distances

        n = q.shape[0]
        finite = np.all(np.isfinite(q), axis=1)
        q = np.where(finite[:, None], q, 0.0)
        distances = np.empty((n, len(self.geometry_model.collisionPairs)))
        need = np.zeros(distances.shape, dtype=bool)
        joint, centre, axis, half, radius, cylinder = self._seg
        if joint.size:
            q_bodies = self._chain.body_positions(q)
            frames = joint_frames(self._placements, self._axes, self._prismatic, q_bodies)
            frames = np.concatenate([np.broadcast_to(np.eye(4), (n, 1, 4, 4)), frames], axis=1)
            primitive_distances(
                frames, joint, centre, axis, half, radius, cylinder, self._seg_pairs,
                self._plane_pairs, self._plane_normals, self._plane_offsets, distances,
            )  # fmt: skip
            if self._seg_pairs.size:
                p, i, k = self._seg_pairs.T
                # a cylinder's capsule is a lower bound: where it is within the margin, the
                # exact distance decides (coal, only for those postures and pairs)
                need[:, p] = (cylinder[i] | cylinder[k])[None, :] & (
                    distances[:, p] < self.clearance_m
                )
                if need.any():
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
        slow = list(self._slow_pairs)
        if slow:
            geom = self.geometry_model
            data, gdata = self.model.createData(), _geometry_data(geom)
            for s in range(n):  # coal: one posture at a time
                pin.updateGeometryPlacements(self.model, data, geom, gdata, q[s])
                for pair in slow:
                    distances[s, pair] = pin.computeDistance(geom, gdata, pair).min_distance
            poor = np.flatnonzero(self._hull_proxy_poor)
            need[:, poor] = distances[:, poor] < self.clearance_m
        return q, distances, need, finite

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

    def _exact_into(
        self, q: FloatArray, pairs: Sequence[int], gdata: pin.GeometryData, row: FloatArray
    ) -> None:
        """Replace the hull distances ``row[pairs]`` of one posture by the mesh distances.

        coal reports meshes in contact as 0 (no depth): there the hulls' (negative) signed
        distance is kept, so a penetration still has a depth for the penalty.
        """
        geom = self.exact_geometry_model
        pin.updateGeometryPlacements(self.model, self.model.createData(), geom, gdata, q)
        for p in pairs:
            d = pin.computeDistance(geom, gdata, int(p)).min_distance
            row[p] = d if d > 0.0 else min(d, row[p])

    def with_optimizer_margin(self, clearance_m: float) -> SafetyModel:
        """The same model whose cheap term (:func:`collision_violations`) asks for
        ``clearance_m`` [m] instead: the optimizer's penalty margin, set above the
        certificate's when trajectories kept the margin at the checked samples but not
        between them. Geometry, pairs and limits are shared; the dense check of a trajectory
        uses the model it is given (keep the original for the certificate)."""
        import copy

        if not clearance_m >= self.clearance_m:
            raise ValueError(
                f"the optimizer's margin {clearance_m} m is below the certificate's "
                f"{self.clearance_m} m"
            )
        tighter = copy.copy(self)
        tighter.clearance_m = float(clearance_m)
        return tighter

    @property
    def n_pairs(self) -> int:
        """Number of checked link pairs."""
        return len(self.pair_names)

    def _exclusion_postures(
        self, reference_q: npt.ArrayLike | None, rng: np.random.Generator | int | None
    ) -> FloatArray:
        """The reference posture (row 0) and :data:`N_EXCLUSION_POSTURES` random ones [rad]."""
        lower, upper = self.limits.finite_position_box()
        if reference_q is None:
            reference = np.clip(np.zeros(self.limits.nq), lower, upper)
        else:
            reference = np.asarray(reference_q, dtype=float)
        gen = np.random.default_rng(rng)
        sample = gen.uniform(lower, upper, (N_EXCLUSION_POSTURES, self.limits.nq))
        return np.vstack([reference[None, :], sample])

    def _distances(self, geom: pin.GeometryModel, q: FloatArray) -> FloatArray:
        """Signed distances of every active pair of ``geom`` [m], shape (n_samples, n_pairs)."""
        q = np.asarray(q, dtype=float)
        n_pairs = len(geom.collisionPairs)
        out = np.empty((q.shape[0], n_pairs))
        data = self.model.createData()
        gdata = _geometry_data(geom)
        for k in range(q.shape[0]):  # coal evaluates one posture at a time
            pin.computeDistances(self.model, data, geom, gdata, q[k])
            out[k] = [r.min_distance for r in gdata.distanceResults]
        return out

    def clearances(self, q: npt.ArrayLike, within: npt.ArrayLike | None = None) -> FloatArray:
        """Signed distance of every checked link pair on the exact geometry [m].

        Meshes are measured as they are (coal BVH), primitives as primitives. Where two meshes
        touch, coal gives 0: the value is then their hulls' signed distance (<= 0, a depth).

        Parameters
        ----------
        q :
            Joint positions [rad or m], shape (n_samples, nq).
        within :
            Optional, shape (n_samples, n_pairs) [m]: the exact distance is needed only where
            it is below these values. Elsewhere the convex hulls' distance (a lower bound: a
            hull contains its mesh) stands in, except that each pair's smallest value is made
            exact (the postures are measured in increasing order of their hulls' distance
            until it exceeds the smallest exact distance found). Default: exact everywhere.

        Returns
        -------
        :
            Shape (n_samples, n_pairs), columns named by :attr:`pair_names`; never more than
            the exact distance.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        out = np.full((q.shape[0], self.n_pairs), np.inf)
        if self.n_pairs == 0:
            return out
        finite = np.all(np.isfinite(q), axis=1)
        q = np.where(finite[:, None], q, 0.0)
        distances = self._distances(self.geometry_model, q)
        mesh = self._mesh_pairs
        if mesh.any():
            if within is None:
                need = np.broadcast_to(mesh, distances.shape).copy()
            else:
                limit = np.asarray(within, dtype=float)[:, self._group]
                need = mesh[None, :] & (distances < limit)
            gdata = _geometry_data(self.exact_geometry_model)
            for s in np.flatnonzero(need.any(axis=1)):
                self._exact_into(q[s], np.flatnonzero(need[s]).tolist(), gdata, distances[s])
            if within is not None:  # each pair's smallest value exact
                for p in np.flatnonzero(mesh):
                    known = need[:, p]
                    best = distances[known, p].min() if known.any() else np.inf
                    rest = np.flatnonzero(~known)
                    for s in rest[np.argsort(distances[rest, p], kind="stable")]:
                        if distances[s, p] >= best:  # hulls in increasing order: done
                            break
                        self._exact_into(q[s], [int(p)], gdata, distances[s])
                        best = min(best, distances[s, p])
        out = self._pair_minimum(distances)
        out[~finite] = -np.inf
        return out

    def pair_clearances(self, q: npt.ArrayLike, columns: Sequence[int]) -> FloatArray:
        """Exact clearances of some link pairs only [m], shape (n_samples, len(columns)).

        The same values as ``clearances(q)[:, columns]`` (a depth where meshes touch is
        reported as 0 or less), for the few pairs :func:`ident.excitation.check` refines.
        """
        q = np.atleast_2d(np.asarray(q, dtype=float))
        columns = [int(c) for c in columns]
        out = np.full((q.shape[0], len(columns)), np.inf)
        where = {c: i for i, c in enumerate(columns)}
        pairs = [p for p in range(self._group.size) if int(self._group[p]) in where]
        geom = self.exact_geometry_model
        data, gdata = self.model.createData(), _geometry_data(geom)
        for s in range(q.shape[0]):
            if not np.all(np.isfinite(q[s])):
                out[s] = -np.inf
                continue
            pin.updateGeometryPlacements(self.model, data, geom, gdata, q[s])
            for p in pairs:
                d = pin.computeDistance(geom, gdata, p).min_distance
                i = where[int(self._group[p])]
                out[s, i] = min(out[s, i], d)
        return out


def _pair_key(a: str, b: str) -> tuple[str, str]:
    return (a, b) if a <= b else (b, a)


def _estimate_environment(n_robot: int, n_environment: int) -> None:
    """Warn with an estimate of the time when many environment pairs are checked."""
    n_pairs = n_robot * n_environment
    if n_pairs <= 200:
        return
    import warnings

    from ident.errors import IdentWarning

    seconds = n_pairs * 101 * 5e-6  # collision tests of the environment pairs, then distances
    warnings.warn(
        f"safety: {n_environment} environment objects (floor, obstacles) x {n_robot} robot "
        f"geometries = {n_pairs} pairs: "
        f"about {seconds:.0f} s to judge them, then about {n_pairs * 10e-6 * 1000:.0f} s per "
        "1000 postures the optimizer or the check measures (the run's estimate includes it).",
        IdentWarning,
        stacklevel=3,
    )


def build_safety_model(
    robot: Any,
    config: SafetyConfig | Mapping[str, Any] | None = None,
    *,
    urdf: str | Path | None = None,
    package_dirs: Sequence[str | Path] = (),
    reference_q: npt.ArrayLike | None = None,
    home_q: npt.ArrayLike | None = None,
    lower_margin: bool | None = None,
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
    home_q :
        The posture the robot starts from (``controller.home``) [rad], shape (nq,): closer
        than the margin to the floor or an obstacle there is an input error.
    lower_margin :
        Lower the margin (halving it, not below :data:`MIN_LOWERED_CLEARANCE_M`) while a link
        pair is closer than it in every sampled posture, and say so in ``margin_note``;
        default: only when the config does not give ``clearance_m`` (the default margin).

    Raises
    ------
    ModelError
        If the collision geometry cannot be loaded or does not match the robot's joints.
    ConfigError
        If the environment or the margin cannot be kept whatever the robot does (a base inside
        the floor or an obstacle, a link closer than the margin in every sampled posture, a
        margin beyond the robot's reach), or the SRDF cannot be read.
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
        home_q=home_q,
        lower_margin=lower_margin,
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


# coal's GJK without EPA reports shapes in contact as 0 or a round-off above it (1e-16 seen
# for the paper robot's cylinders 20 mm deep): at most this, the cheap term counts contact
_CONTACT_M = 1e-6


_REFINE_SCRATCH: dict[tuple[int, int, int, int], tuple[Any, pin.GeometryData]] = {}


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


def collision_violations(
    safety: SafetyModel, q: FloatArray, n_check: int | None = None
) -> ConstraintViolations:
    """Cheap clearance constraint of a swarm: distances at ``n_check`` samples per trajectory.

    Uses :meth:`SafetyModel.fast_min_clearances` (vectorized over the swarm; the minimum of
    :meth:`SafetyModel.fast_clearances` over the samples, exact wherever a pair is within the
    margin, so the term equals the exact one at the checked samples).

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
    d = safety.fast_min_clearances(q[:, idx])
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
