"""DH description -> URDF text: joint frames, inertials in the URDF link frames, primitive visuals.

Frames
------
Standard DH: the chain is ``J_1(q_1) F_1 J_2(q_2) F_2 ... J_n(q_n) F_n`` with the joint motion
``J_i`` about (along) z and the fixed ``F_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``. URDF joint
``i`` moves about z of its joint frame, whose ``<origin>`` in the parent link frame is
``F_{i-1}`` (identity for joint 1), so URDF link ``i`` sits on the axis of joint ``i`` and DH
frame ``i`` is ``link_i * F_i``. Each link's inertial, given in DH frame ``i``, is therefore moved
by ``F_i`` into the URDF link frame: the ``<inertial><origin>`` is the centre of mass and its
``rpy`` the orientation of DH frame ``i``, so the ``<inertia>`` entries are exactly the
configuration's tensor about the centre of mass in DH axes.

Modified DH: ``T_i = G_i J_i(q_i)`` with ``G_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``;
the joint origin is ``G_i`` and URDF link frames coincide with DH frames.

In both cases a fixed joint ``flange_joint`` adds the frame ``flange`` equal to DH frame ``n``.
When the last three joints are revolute and their axes meet in one point (a spherical wrist) a
fixed joint ``wrist_centre_joint`` adds the frame ``wrist_centre`` at that point, attached to the
link of the first wrist joint (for the paper's robot: the origin of DH frame 4).

Every visual is a primitive cylinder and is repeated as the link's ``<collision>`` geometry;
``base_link`` carries the pedestal, a column standing on the base plane ``z = 0`` around joint
1's axis. Collision geometry has no mass: forward kinematics and inertials do not depend on it.

Velocity and effort limits the description does not know are written as ``0`` (URDF requires the
attributes); :class:`ident.model.Robot` reads ``0`` as "unknown".
"""

from __future__ import annotations

import math

# xml.etree: writes the URDF of a DH config, byte for byte as shipped (a leading comment,
# materials, our number format, attribute order); yourdfpy writes no comment and its own attribute
# order and numbers (checked: <origin xyz=.. rpy=..>, "0.0 -0.0 0.0").
import xml.etree.ElementTree as ET

import numpy as np
import numpy.typing as npt

from ident.errors import ModelError
from ident.robot.dh import DHTable, Step, elementary_transform, rot_z, trans_z
from ident.robot.inertia import URDF_INERTIA_ENTRIES
from ident.robot.robot_config import RobotDescription

__all__ = [
    "BASE_LINK",
    "FLANGE",
    "WRIST_CENTRE",
    "dh_frame_in_link",
    "joint_origins",
    "urdf_from_description",
    "wrist_centre",
]

FloatArray = npt.NDArray[np.float64]

BASE_LINK = "base_link"
FLANGE = "flange"
WRIST_CENTRE = "wrist_centre"

_LINK_COLOUR = ("orange", "0.93 0.46 0.10 1")
_JOINT_COLOUR = ("grey", "0.35 0.35 0.38 1")
# below this, a length [m] or angle [rad] in an <origin> is cos/sin round-off: written as 0
_ORIGIN_ZERO = 1e-14


def joint_origins(dh: DHTable) -> tuple[FloatArray, FloatArray]:
    """URDF joint origins and the pose of the flange in the last link.

    Returns
    -------
    origins :
        Pose of joint ``i``'s frame in its parent link frame, shape (n_joints, 4, 4).
    flange :
        Pose of DH frame ``n`` in URDF link ``n``, shape (4, 4).
    """
    n = dh.n_joints
    fixed = np.array([dh.fixed_transform(i) for i in range(n)])
    if dh.convention == "standard":
        origins = np.concatenate([np.eye(4)[None], fixed[:-1]])
        return origins, fixed[-1]
    return fixed, np.eye(4)


def dh_frame_in_link(dh: DHTable, i: int) -> FloatArray:
    """Pose of DH frame ``i`` (0-based link index) in URDF link ``i``."""
    return dh.fixed_transform(i) if dh.convention == "standard" else np.eye(4)


def _link_frames_at(dh: DHTable, q: FloatArray) -> FloatArray:
    """World poses of the URDF link frames at one configuration, shape (n_joints, 4, 4)."""
    origins, _ = joint_origins(dh)
    frames = np.empty((dh.n_joints, 4, 4))
    current = np.eye(4)
    for i in range(dh.n_joints):
        motion = rot_z(q[i])[0] if dh.joint_types[i] == "revolute" else trans_z(q[i])[0]
        current = current @ origins[i] @ motion
        frames[i] = current
    return frames


def wrist_centre(dh: DHTable, *, rtol: float = 1e-9) -> tuple[int, FloatArray] | None:
    """Intersection point of the last three joint axes, if they are revolute and meet.

    Returns
    -------
    :
        ``(link_index, point)``: the 0-based index of the link moved by the first wrist joint
        and the point in that link's URDF frame [m], shape (3,); ``None`` when there is no
        spherical wrist (fewer than three joints, a prismatic joint, parallel or skew axes).
    """
    n = dh.n_joints
    if n < 3 or any(t != "revolute" for t in dh.joint_types[-3:]):
        return None
    frames = _link_frames_at(dh, np.zeros(n))[-3:]
    points, axes = frames[:, :3, 3], frames[:, :3, 2]
    projectors = np.eye(3)[None] - axes[:, :, None] * axes[:, None, :]
    normal = projectors.sum(axis=0)
    if np.linalg.eigvalsh(normal)[0] < 1e-6:  # parallel axes: no unique intersection
        return None
    point = np.linalg.solve(normal, np.einsum("kij,kj->i", projectors, points))
    scale = 1.0 + float(np.max(np.abs(points)))
    distances = np.linalg.norm(np.einsum("kij,kj->ki", projectors, point - points), axis=1)
    if np.max(distances) > rtol * scale:
        return None
    first = frames[0]
    local = first[:3, :3].T @ (point - first[:3, 3])
    return n - 3, local


def _fmt(value: float, *, snap: bool = False) -> str:
    value = float(value)
    if snap and abs(value) < _ORIGIN_ZERO:
        value = 0.0
    if value == 0.0:
        return "0"
    return repr(value)


def _vector(values: npt.ArrayLike, *, snap: bool = False) -> str:
    return " ".join(_fmt(v, snap=snap) for v in np.asarray(values, dtype=float))


def _rpy(rotation: FloatArray) -> FloatArray:
    """URDF roll-pitch-yaw with ``rotation = Rz(yaw) Ry(pitch) Rx(roll)``."""
    pitch = math.atan2(-rotation[2, 0], math.hypot(rotation[0, 0], rotation[1, 0]))
    if math.cos(pitch) > 1e-12:
        roll = math.atan2(rotation[2, 1], rotation[2, 2])
        yaw = math.atan2(rotation[1, 0], rotation[0, 0])
    else:  # gimbal lock: put the whole rotation about z into yaw
        roll = 0.0
        yaw = math.atan2(-rotation[0, 1], rotation[1, 1])
    return np.array([roll, pitch, yaw])


def _origin(parent: ET.Element, transform: FloatArray) -> None:
    ET.SubElement(
        parent,
        "origin",
        xyz=_vector(transform[:3, 3], snap=True),
        rpy=_vector(_rpy(transform[:3, :3]), snap=True),
    )


def _z_to(direction: FloatArray) -> FloatArray:
    """A rotation taking the z axis onto the unit vector ``direction``."""
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, direction)
    sin, cos = np.linalg.norm(axis), float(np.dot(z, direction))
    if sin < 1e-12:
        return np.eye(3) if cos > 0 else np.diag([1.0, -1.0, -1.0])
    k = axis / sin
    skew = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + sin * skew + (1 - cos) * skew @ skew


def _cylinder(
    link: ET.Element, start: FloatArray, end: FloatArray, radius: float, colour: str
) -> None:
    """A cylinder from ``start`` to ``end`` [m] (link frame): the visual and the same collision.

    The collision primitive is the visual cylinder itself, so what the replay shows is what
    the clearance check (:mod:`ident.excitation.safety`) measures.
    """
    length = float(np.linalg.norm(end - start))
    if length < 1e-9:
        return
    pose = np.eye(4)
    pose[:3, :3] = _z_to((end - start) / length)
    pose[:3, 3] = 0.5 * (start + end)
    for kind in ("visual", "collision"):
        element = ET.SubElement(link, kind)
        _origin(element, pose)
        geometry = ET.SubElement(element, "geometry")
        ET.SubElement(geometry, "cylinder", radius=_fmt(radius), length=_fmt(length))
        if kind == "visual":
            ET.SubElement(element, "material", name=colour)


def _polyline(steps: tuple[Step, ...]) -> list[FloatArray]:
    """Points visited by the translations of a chain of elementary steps, from the origin."""
    points = [np.zeros(3)]
    done: list[Step] = []
    for step in steps:
        done.append(step)
        if step[0] in ("tz", "tx") and abs(step[1]) > 0.0:
            points.append(elementary_transform(done)[:3, 3])
    return points


def _link_radii(dh: DHTable) -> FloatArray:
    reach = float(np.sum(np.abs(dh.a)) + np.sum(np.abs(dh.d)))
    base = 0.035 * max(reach, 0.2)
    taper = np.linspace(1.0, 0.6, dh.n_joints) if dh.n_joints > 1 else np.ones(1)
    return base * taper


def urdf_from_description(robot: RobotDescription) -> str:
    """Build the URDF text of a DH-described robot.

    Parameters
    ----------
    robot :
        The description (SI), e.g. from :func:`ident.robot.robot_config.load_robot_config`.

    Returns
    -------
    :
        URDF XML text with ``base_link``, one link and joint per DH row (config names), the
        ``flange`` frame and, for a spherical wrist, the ``wrist_centre`` frame. Raises
        :class:`ModelError` if a link or joint name collides with a generated one.
    """
    dh = robot.dh
    _check_generated_names(robot)
    origins, flange = joint_origins(dh)
    radii = _link_radii(dh)
    root = ET.Element("robot", name=robot.name)
    source = f" from {robot.source.name}" if robot.source else ""
    root.append(
        ET.Comment(
            f" Generated by `ident urdf`{source} ({dh.convention} DH); do not edit by hand. "
        )
    )
    for name, rgba in (_LINK_COLOUR, _JOINT_COLOUR):
        ET.SubElement(ET.SubElement(root, "material", name=name), "color", rgba=rgba)

    base = ET.SubElement(root, "link", name=BASE_LINK)
    # the pedestal: a column on the base plane (z = 0, the floor of the safety model) up to
    # the housing of joint 1, wider than every link, so that a motion through the robot's own
    # base is a collision with base_link
    plinth = 1.6 * radii[0]
    _cylinder(base, np.zeros(3), np.array([0, 0, plinth]), plinth, _JOINT_COLOUR[0])

    parent = BASE_LINK
    for i in range(dh.n_joints):
        _add_joint(root, robot, i, parent, origins[i])
        link = ET.SubElement(root, "link", name=robot.link_names[i])
        _add_inertial(link, robot, i)
        _add_link_body(link, dh, i, float(radii[i]))
        parent = robot.link_names[i]

    flange_link = _add_fixed_frame(root, "flange_joint", parent, FLANGE, flange)
    disc = np.array([0.0, 0.0, 0.3 * radii[-1]])
    _cylinder(flange_link, -disc, np.zeros(3), 0.8 * radii[-1], _JOINT_COLOUR[0])

    centre = wrist_centre(dh)
    if centre is not None:
        index, point = centre
        pose = np.eye(4)
        pose[:3, 3] = point
        _add_fixed_frame(root, "wrist_centre_joint", robot.link_names[index], WRIST_CENTRE, pose)

    ET.indent(root, space="  ")
    return '<?xml version="1.0"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _check_generated_names(robot: RobotDescription) -> None:
    """Raise :class:`ModelError` when a link or joint name is another's or a generated one."""
    generated = {BASE_LINK, FLANGE, WRIST_CENTRE, "flange_joint", "wrist_centre_joint"}
    names = list(robot.link_names) + list(robot.joint_names)
    clash = sorted(generated.intersection(names))
    duplicates = sorted(set(robot.link_names).intersection(robot.joint_names))
    if clash or duplicates:
        where = f" ({robot.source})" if robot.source else ""
        raise ModelError(
            f"robot{where}: link/joint name(s) {', '.join(clash + duplicates)} collide with each "
            f"other or with the generated frames {', '.join(sorted(generated))}; rename them."
        )


def _add_joint(
    root: ET.Element, robot: RobotDescription, i: int, parent: str, origin: FloatArray
) -> None:
    """The ``<joint>`` of DH row ``i`` (0-based): about (along) z of its frame, placed at
    ``origin`` (shape (4, 4)) in the ``parent`` link; its limits [rad or m, rad/s or m/s,
    N*m or N], an unknown velocity or effort written as ``0``."""
    joint = ET.SubElement(root, "joint", name=robot.joint_names[i], type=robot.dh.joint_types[i])
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=robot.link_names[i])
    _origin(joint, origin)
    ET.SubElement(joint, "axis", xyz="0 0 1")
    ET.SubElement(
        joint,
        "limit",
        lower=_fmt(robot.q_lower[i]),
        upper=_fmt(robot.q_upper[i]),
        effort=_fmt(robot.effort_max[i]) if np.isfinite(robot.effort_max[i]) else "0",
        velocity=_fmt(robot.dq_max[i]) if np.isfinite(robot.dq_max[i]) else "0",
    )


def _add_inertial(link: ET.Element, robot: RobotDescription, i: int) -> None:
    """The ``<inertial>`` of link ``i``: mass [kg] and the tensor about the centre of mass
    [kg*m^2], in a frame at the centre of mass with the axes of DH frame ``i``."""
    dh_in_link = dh_frame_in_link(robot.dh, i)
    inertial_pose = dh_in_link.copy()
    inertial_pose[:3, 3] = dh_in_link[:3, :3] @ robot.com[i] + dh_in_link[:3, 3]
    inertial = ET.SubElement(link, "inertial")
    ET.SubElement(
        inertial,
        "origin",
        xyz=_vector(inertial_pose[:3, 3]),
        rpy=_vector(_rpy(inertial_pose[:3, :3]), snap=True),
    )
    ET.SubElement(inertial, "mass", value=_fmt(robot.mass[i]))
    tensor = robot.inertia_com[i]
    ET.SubElement(
        inertial,
        "inertia",
        {key: _fmt(tensor[i, j]) for key, (i, j) in URDF_INERTIA_ENTRIES.items()},
    )


def _add_link_body(link: ET.Element, dh: DHTable, i: int, radius: float) -> None:
    """Visuals (and the same collisions) of link ``i``: the joint housing, then cylinders of
    ``radius`` [m] along the DH offsets to the next joint."""
    half = np.array([0.0, 0.0, 1.25 * radius])
    _cylinder(link, -half, half, 1.25 * radius, _JOINT_COLOUR[0])
    if dh.convention == "standard":
        steps = dh.fixed_steps(i)
    else:
        steps = dh.fixed_steps(i + 1) if i + 1 < dh.n_joints else ()
    points = _polyline(steps)
    for start, end in zip(points[:-1], points[1:], strict=True):
        _cylinder(link, start, end, radius, _LINK_COLOUR[0])


def _add_fixed_frame(
    root: ET.Element, joint_name: str, parent: str, child: str, pose: FloatArray
) -> ET.Element:
    """A fixed joint placing the new link ``child`` at ``pose`` (shape (4, 4)) in ``parent``;
    returns the link element."""
    joint = ET.SubElement(root, "joint", name=joint_name, type="fixed")
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)
    _origin(joint, pose)
    return ET.SubElement(root, "link", name=child)
