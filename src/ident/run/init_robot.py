"""What ``ident init`` reads from a robot: the chain and its locks, limits, geometry, torques.

Pure functions on a URDF file or an :class:`ident.model.Robot`; :mod:`ident.run.init_config`
turns their answers into a run config.
"""

from __future__ import annotations

import re

# xml.etree: reads <limit acceleration=...>, an extension yourdfpy does not model (yourdfpy.Limit
# holds effort, velocity, lower, upper only; checked).
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from ident.errors import ConfigError
from ident.excitation.safety import MIN_LOWERED_CLEARANCE_M, SafetyModel, build_safety_model
from ident.excitation.safety.fast import EXACT_WITHIN_M
from ident.model.robot import Robot
from ident.robot.limits import JointLimits
from ident.robot.mimic import mimic_lock_reasons, read_mimics
from ident.robot.urdf_load import (
    build_model,
    chain_locks,
    prepare_urdf,
    suggested_locks,
    urdf_file_text,
)

__all__ = [
    "ENGINEER_CLEARANCE_M",
    "MARGIN_ROOM",
    "PLACEHOLDER_LOAD_SPAN",
    "base_bottom",
    "chain_tip_link",
    "choose_locks",
    "clear_posture",
    "effort_scale",
    "find_package_dirs",
    "gain_scale",
    "gravity_torques",
    "joint_loads",
    "keepable_clearance",
    "link_side_inertias",
    "placeholder_effort",
    "placeholder_velocity",
    "robot_reach",
    "self_clearance_model",
    "torque_scale",
    "urdf_acceleration_limits",
]

_GRIPPER = re.compile(r"gripper|finger|hand", re.IGNORECASE)
_N_POSTURES = 300
#: A safety margin below this [m] is named with the link pairs that force it.
ENGINEER_CLEARANCE_M = 0.01
#: The margin is at most this fraction of a link pair's largest clearance.
MARGIN_ROOM = 2.0
_N_CANDIDATES = 16  # postures of clear_posture measured on the exact geometry
_FAR_M = EXACT_WITHIN_M  # beyond this clearance [m] a posture is as good as any other
#: Equal effort limits on joints whose loads differ by more than this factor are placeholders
#: (two orders of magnitude: real ratings follow the load, UR5 150..28, Panda 87..12 N*m).
PLACEHOLDER_LOAD_SPAN = 100.0


def _fmt(value: float) -> str:
    return f"{float(value):.3g}"


def choose_locks(
    urdf: Path,
    base_link: str | None,
    tip_link: str | None,
    lock: dict[str, float],
    package_dirs: Sequence[Path] = (),
) -> tuple[dict[str, float], list[str]]:
    """Joints to lock (name -> position) and one reason line per lock."""
    where = str(urdf)
    text = urdf_file_text(urdf, package_dirs, where)  # read as Robot.from_urdf reads it
    prepared = prepare_urdf(text, where)
    root = prepared.root
    model = build_model(prepared.text, where)
    reasons: dict[str, str] = {name: "given with --lock" for name in lock}
    if base_link is not None or tip_link is not None:
        for name in chain_locks(model, base_link, tip_link, where):
            reasons.setdefault(name, "outside the chain from the base link to the tip link")
    else:
        _branch_reasons(model, reasons)
    values: dict[str, float] = {}
    for name in reasons:
        if name in lock:
            values[name] = float(lock[name])
            continue
        jid = model.getJointId(name)
        idx = model.joints[jid].idx_q
        low, high = model.lowerPositionLimit[idx], model.upperPositionLimit[idx]
        values[name] = float(np.clip(0.0, low, high)) if high > low else 0.0
    mimics = read_mimics(root, model, where)
    for name, why in mimic_lock_reasons(mimics, values).items():
        if name not in lock:  # a lock given with --lock stands
            values[name] = float(mimics[name].position(values[mimics[name].leader]))
            reasons[name] = why
    lines = [f"{name} locked at {_fmt(values[name])}: {why}" for name, why in reasons.items()]
    return values, lines


def _branch_reasons(model: pin.Model, reasons: dict[str, str]) -> None:
    """Add to ``reasons`` the joints :func:`suggested_locks` locks in a branched ``model``,
    and a moving gripper joint at the end of its chain, each with why.

    A locked joint is "a gripper finger" only if it hangs from the chain's last joint (a
    finger of the tool at the tip); any other is off the chain (a head, the other arm), named
    with the chain's first and last links.
    """
    locked = set(suggested_locks(model))
    kept = [k for k in range(1, model.njoints) if model.names[k] not in locked]
    tip = max(kept, default=0, key=lambda k: _depth(model, k))
    chain = f"{_child_link(model, 0)}→{_child_link(model, tip)}"
    for name in sorted(locked, key=model.getJointId):
        jid = model.getJointId(name)
        leaf = not any(int(model.parents[k]) == jid for k in range(1, model.njoints))
        reasons.setdefault(
            name,
            "a gripper finger (a single joint at the tip)"
            if leaf and int(model.parents[jid]) == tip and tip > 0
            else f"not on the chain {chain} (a side branch: the chain follows the deepest one)",
        )
    # a moving gripper joint at the end of a serial chain: its fingers ride on the last link
    kept = [k for k in range(1, model.njoints) if model.names[k] not in reasons and model.nvs[k]]
    for k in reversed(kept):
        name = model.names[k]
        if not _GRIPPER.search(name):
            break
        reasons[name] = "a gripper joint (named so): the fingers ride on the last link"


def _depth(model: pin.Model, joint: int) -> int:
    """Number of joints from the root to ``joint`` (itself included)."""
    depth = 0
    while joint > 0:
        depth, joint = depth + 1, int(model.parents[joint])
    return depth


def _child_link(model: pin.Model, joint: int) -> str:
    """The link a joint moves (for joint 0, the root link): the first body frame on it."""
    bodies = [f.name for f in model.frames if f.type == pin.FrameType.BODY]
    on_joint = [
        f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == joint
    ]
    return (on_joint or bodies or ["?"])[0]


def chain_tip_link(model: pin.Model) -> str:
    """The link the last joint of a serial ``model`` moves (the chain's tip link)."""
    return _child_link(model, model.njoints - 1)


def urdf_acceleration_limits(urdf_text: str, joint_names: tuple[str, ...]) -> np.ndarray:
    """``<limit acceleration=...>`` per joint (NaN where absent), shape (n_joints,)."""
    root = ET.fromstring(urdf_text)
    found: dict[str, float] = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is not None and limit.get("acceleration") is not None:
            try:
                found[joint.get("name", "")] = float(limit.get("acceleration", "nan"))
            except ValueError:
                continue
    out = np.array([found.get(n, np.nan) for n in joint_names])
    return np.where(np.isfinite(out) & (out > 0), out, np.nan)


def find_package_dirs(urdf: Path, text: str, given: list[Path]) -> list[Path]:
    """``package://NAME/...`` resolved: the given folders, else the nearest ancestor of the
    URDF's folder that holds a folder ``NAME``."""
    if given:
        return [p.resolve() for p in given]
    # package:// URIs, and xacro's $(find NAME) (served from the same folders)
    found_names = re.findall(r"package://([^/\"']+)/|\$\(find ([^)\s]+)\)", text)
    names = sorted({a or b for a, b in found_names})
    found: list[Path] = []
    for name in names:
        for parent in urdf.resolve().parents:
            if (parent / name).is_dir():
                if parent not in found:
                    found.append(parent)
                break
        else:
            raise ConfigError(
                f"{urdf}: the meshes of package://{name}/ are not in any folder above the URDF; "
                "give the folder that contains it with --package-dir DIR."
            )
    return found


def _postures(robot: Robot, n: int) -> np.ndarray:
    """``n`` seeded postures uniform in the position box (guessed where the URDF gives no
    limit) [rad or m], shape (n, nq)."""
    rng = np.random.default_rng(0)
    lower, upper = JointLimits.from_robot(robot).finite_position_box()  # guessed if unknown
    return rng.uniform(lower, upper, (n, robot.model.nq))


def gravity_torques(robot: Robot, n: int = 50) -> np.ndarray:
    """The URDF's static gravity torques [N*m] at ``n`` seeded postures uniform in the
    position box (guessed where the URDF gives no limit), shape (n, nv)."""
    model = robot.model
    data = model.createData()
    return np.array([pin.computeGeneralizedGravity(model, data, q) for q in _postures(robot, n)])


def link_side_inertias(robot: Robot, n: int = 50) -> np.ndarray:
    """The mass matrix's diagonal [kg*m^2 or kg] (each joint's link-side inertia) at the
    postures of :func:`gravity_torques`, shape (n, nv)."""
    model = robot.model
    data = model.createData()
    # crba fills the upper triangle: the diagonal is exact
    return np.array([np.diag(pin.crba(model, data, q)) for q in _postures(robot, n)])


def joint_loads(robot: Robot, ddq_max: np.ndarray, n: int = 50) -> np.ndarray:
    """Per joint: the largest load of the links it moves [N*m] over ``n`` seeded postures
    (those of :func:`gravity_torques`): the static gravity torque plus the link-side inertia
    (:func:`link_side_inertias`) times the acceleration limit ``ddq_max`` [rad/s^2], shape
    (nv,) each."""
    inertia = link_side_inertias(robot, n)
    return np.max(np.abs(gravity_torques(robot, n)) + inertia * ddq_max, axis=0)


def gain_scale(robot: Robot, armature: np.ndarray, n: int = 50) -> np.ndarray:
    """Per joint: ``1 + Ia_j / max_q M_jj(q)``, shape (nv,): the factor on the simulated
    computed-torque controller's gains that gives each joint its intended bandwidth although
    the controller's model lacks the rotor inertia ``armature`` [kg*m^2] (joint-side), with
    ``M_jj`` the link-side inertia [kg*m^2] over ``n`` seeded postures. The largest ``M_jj``
    keeps the loop gain ``kp M_jj / (M_jj + Ia_j)`` at or below ``kp`` everywhere (a UR10's
    wrist 3: link 2e-4, rotor guess 0.162 kg*m^2: unscaled, its loop had 1/800 of its gain,
    and its guessed 1.6 N*m of friction held it until 0.8 rad behind)."""
    largest = np.max(link_side_inertias(robot, n), axis=0)
    return 1.0 + np.asarray(armature, dtype=float) / largest


def placeholder_effort(effort: np.ndarray, loads: np.ndarray) -> float:
    """The effort limit [N*m] the URDF gives every joint alike although the loads of the
    links they move (:func:`joint_loads`) span more than :data:`PLACEHOLDER_LOAD_SPAN`: a
    placeholder (a vendor's 300 N*m on every joint of an arm whose wrist carries grams); 0.0
    when the efforts are not such (they differ, are unknown, or there are under 3 joints)."""
    effort = np.asarray(effort, dtype=float)
    if effort.size < 3 or not np.all(np.isfinite(effort) & (effort > 0)):
        return 0.0
    if np.ptp(effort) > 1e-9 * effort[0]:
        return 0.0
    if np.max(loads) <= PLACEHOLDER_LOAD_SPAN * max(float(np.min(loads)), 1e-12):
        return 0.0
    return float(effort[0])


def placeholder_velocity(velocity: np.ndarray, effort_placeholder: float) -> float:
    """The velocity limit [rad/s] the URDF gives every joint alike when its effort limits are
    placeholders too (``effort_placeholder`` > 0, :func:`placeholder_effort`): limits copied
    to every joint, not the robot's ratings (the iiwa_stack's and the SO-101's 10 rad/s;
    KUKA rates the iiwa 14's joints 1.3-2.4 rad/s); 0.0 otherwise (equal velocity limits beside
    real effort ratings, as the UR5's or Z1's, are taken as given)."""
    velocity = np.asarray(velocity, dtype=float)
    if not effort_placeholder or velocity.size < 3:
        return 0.0
    if not np.all(np.isfinite(velocity) & (velocity > 0)) or np.ptp(velocity) > 1e-9 * velocity[0]:
        return 0.0
    return float(velocity[0])


def effort_scale(robot: Robot) -> np.ndarray:
    """Per joint: the URDF effort limit, or twice the largest static gravity torque [N*m]."""
    effort = np.asarray(robot.model.effortLimit, dtype=float)
    gravity = np.max(np.abs(gravity_torques(robot)), axis=0)
    fallback = np.maximum(2.0 * gravity, 1.0)
    return np.where(np.isfinite(effort) & (effort > 0), effort, fallback)


def torque_scale(
    robot: Robot,
    home: np.ndarray,
    dq_peak: np.ndarray,
    ddq_peak: np.ndarray,
    armature: np.ndarray,
    half_width: float,
) -> np.ndarray:
    """Per joint: the 95th percentile of |tau| over seeded states of the excitation's range
    (within ``half_width`` [rad] of ``home``, speeds and accelerations up to their peaks)
    [N*m]: rigid bodies (Pinocchio's RNEA) plus the rotor inertia."""
    rng = np.random.default_rng(0)
    n = 200
    lower = np.maximum(home - half_width, robot.q_lower)
    upper = np.minimum(home + half_width, robot.q_upper)
    q = rng.uniform(lower, upper, (n, robot.nq))
    dq = rng.uniform(-1.0, 1.0, (n, robot.nv)) * dq_peak
    ddq = rng.uniform(-1.0, 1.0, (n, robot.nv)) * ddq_peak
    tau = robot.rnea(q, dq, ddq) + armature * ddq
    return np.asarray(np.percentile(np.abs(tau), 95.0, axis=0), dtype=float)


def robot_reach(robot: Robot, q: np.ndarray) -> float:
    """Largest distance of a joint origin from the base at posture ``q`` [m]."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    return float(max(np.linalg.norm(data.oMi[k].translation) for k in range(robot.model.njoints)))


def self_clearance_model(
    robot: Robot, clearance_m: float, self_collision: bool = True
) -> SafetyModel:
    """The robot's safety model without the floor, for :func:`base_bottom` and
    :func:`keepable_clearance`: its margin ``clearance_m`` [m] halved (not below 2 mm) while a
    link pair is closer than it in every sampled posture, each pair's largest clearance in
    ``keepable_clearances``."""
    return build_safety_model(
        robot,
        {"clearance_m": clearance_m, "floor": {"enabled": False}, "self_collision": self_collision},
        package_dirs=robot.package_dirs,
        lower_margin=True,
    )


def base_bottom(safety: SafetyModel) -> float:
    """Lowest point of the collision geometry fixed to the world (the base) [m], in the base
    frame; 0 without such geometry. Its bounding boxes' corners: exact for boxes, a lower
    bound for meshes and round shapes."""
    model, geometry = safety.model, safety.exact_geometry_model
    data, gdata = model.createData(), pin.GeometryData(geometry)
    reference = np.clip(np.zeros(model.nq), model.lowerPositionLimit, model.upperPositionLimit)
    pin.updateGeometryPlacements(model, data, geometry, gdata, reference)
    lowest = 0.0
    for k, obj in enumerate(geometry.geometryObjects):
        if obj.parentJoint != 0:
            continue
        obj.geometry.computeLocalAABB()
        box = obj.geometry.aabb_local
        corners = np.array(
            [
                [x, y, z]
                for x in (box.min_[0], box.max_[0])
                for y in (box.min_[1], box.max_[1])
                for z in (box.min_[2], box.max_[2])
            ]
        )
        placement = gdata.oMg[k]
        z = (corners @ placement.rotation.T + placement.translation)[:, 2].min()
        if np.isfinite(z):
            lowest = min(lowest, float(z))
    return lowest


def keepable_clearance(safety: SafetyModel, clearance_m: float) -> tuple[float, list[str]]:
    """A margin [m] every link pair of ``safety`` (:func:`self_clearance_model`) keeps with room:
    ``clearance_m``, or, where a pair's largest clearance over the sampled postures is below
    it, half that clearance (a pair asked for all it can give would have to stay in the
    few postures that give it), in whole millimetres, not below 2 mm.

    Returns the margin and, when it is below :data:`ENGINEER_CLEARANCE_M`, one line per pair
    that forced it: the pair, its largest clearance and the MoveIt SRDF entry that would
    leave it out (then a margin of 1-3 cm holds for the other pairs).
    """
    largest = {k: v for k, v in safety.keepable_clearances.items() if v < clearance_m}
    margin = min([clearance_m, *(v / MARGIN_ROOM for v in largest.values())])
    margin = max(float(np.floor(margin * 1e3) / 1e3), MIN_LOWERED_CLEARANCE_M)
    if margin >= ENGINEER_CLEARANCE_M:
        return margin, []
    n = safety.postures.shape[0]
    lines = [
        f"the links {a} and {b} are never more than {v * 1e3:.1f} mm apart in {n} sampled "
        f"postures: if they may touch (a joint's housings), leave the pair out with a MoveIt "
        f'SRDF line <disable_collisions link1="{a}" link2="{b}" reason="Adjacent"/> '
        "(safety.srdf) and raise safety.clearance_m to 0.01-0.03"
        for (a, b), v in sorted(largest.items(), key=lambda kv: kv[1])
        if v / MARGIN_ROOM < ENGINEER_CLEARANCE_M
    ]
    return margin, lines


def clear_posture(
    robot: Robot, clearance_m: float, floor_z: float, self_collision: bool = True
) -> tuple[np.ndarray, float]:
    """A posture clear of the floor and of itself: of the reference posture (0 clipped into the
    limits) and seeded random ones, the one whose smallest clearance is largest, preferring
    the reference posture while it keeps three margins. Returns it and its clearance [m].

    The random postures are ranked by the optimizer's cheap clearances (a lower bound, meshes
    as their hulls); the :data:`_N_CANDIDATES` best are measured on the exact geometry (up to
    three margins, beyond which any posture will do) and the best of those is chosen. The
    clearance returned is exact below three margins, a lower bound above.
    """
    safety = build_safety_model(
        robot,
        {
            "clearance_m": clearance_m,
            "floor": {"enabled": True, "z": floor_z},
            "self_collision": self_collision,
        },
        package_dirs=robot.package_dirs,
    )
    lower, upper = JointLimits.from_robot(robot).finite_position_box()  # guessed if unknown
    reference = np.clip(np.zeros(robot.nq), lower, upper)
    rng = np.random.default_rng(0)
    # postures near the reference first: a robot's zero is usually a sensible posture
    near = np.clip(reference + rng.uniform(-1.0, 1.0, (_N_POSTURES, robot.nq)), lower, upper)
    if safety.n_pairs == 0:
        return reference, np.inf
    bound = np.minimum(safety.fast_clearances(near).min(axis=1), _FAR_M)
    ranked = near[np.argsort(-bound, kind="stable")[:_N_CANDIDATES]]
    postures = np.vstack([reference[None, :], ranked])
    # exact below three margins, a lower bound (the hulls') above: beyond three margins,
    # the reference posture, else the candidate the cheap clearances rank first
    enough = 3.0 * clearance_m
    within = np.full((postures.shape[0], safety.n_pairs), enough)
    worst = safety.clearances(postures, within).min(axis=1)
    best = 0 if worst[0] >= enough else int(np.argmax(np.minimum(worst, enough)))
    return postures[best], float(worst[best])
