"""Re-check the trajectory of an ``ident run`` folder with plain Pinocchio and coal.

Written apart from ident's safety and geometry code: the URDF, the trajectory and the run's
settings are read from the folder's files, and the checks are re-done from the URDF's own
numbers (ident is used for one thing only: reading the run config's joint limits, as the run
selected them from the URDF and the config):

- **positions** within the URDF's ``<limit lower upper>`` and **velocities** within its
  ``velocity``, for every moving joint and every mimic joint that follows one; positions,
  velocities and **accelerations** of the trajectory's joints within the run's selected
  limits (the URDF's tightened by ``robot.limits``, ``robot.velocity_limits``,
  ``robot.acceleration_limits`` and the export targets); the trajectory starts and ends at
  rest;
- **torques** from Pinocchio's RNEA (the URDF's inertials, gravity -9.81 z, no friction) within
  the URDF's ``effort`` where it gives one (``effort="0"`` or none: named as not checked);
- **self-collision**: the distance (coal, on the collision meshes and primitives as loaded by
  ``pin.buildGeomFromUrdf``) of every pair of links ident does not exclude stays at least the
  run's margin ``safety.clearance_m``. ident's excluded pairs (the chosen elite's
  ``not_checked`` in ``result.json``) are accepted only where they cannot hide a collision:
  links joined by one moving joint (links welded by fixed or locked joints count as one
  body), links of one rigid body (their distance never changes), or links in contact at the
  home posture (each joint at 0 clipped into its limits, or at the trajectory's first sample);
  any other excluded pair is checked like the rest and named. ``safety.payload_box`` is a
  coal box on its link, checked against every link of another rigid body (adjacent ones
  included) and the floor, never left out;
- **the floor**: the lowest point of every moving geometry (mesh vertices, primitives in
  closed form) stays at least the margin above ``safety.floor.z``; a geometry whose height
  never changes (the base) is reported, not failed (ident judges it once as a mounting).

The samples are those of ``trajectory.csv`` (approach, periods, return at the controller's
rate), upsampled by quintic Hermite interpolation when that is slower than the run's
``safety.check_rate_hz``. Limits, torques and the floor are evaluated at every sample. The
mesh distances, the costly part, are not measured at a sample where the distance measured
before it, minus the largest distance the two geometries can have travelled since (their
relative twist at their bounding spheres, :data:`TRAVEL_SAFETY` above the sampled speeds),
still exceeds both the margin and the smallest distance found so far (conservative
advancement): every sample closer than the margin is measured, and the smallest clearance
reported is the smallest over every sample.

Used by ``tests/test_shipped_trajectories.py`` (every shipped config's run),
``tests/test_init.py`` and ``benchmarks/bench_quickstart.py --zoo``::

    python benchmarks/independent_safety.py RUN_FOLDER
"""

from __future__ import annotations

import csv
import json
import math
import sys

# xml.etree: the URDF's joints, limits and mimic tags read straight from the file (not through
# ident's loader), so that a mistake there cannot hide here.
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import coal
import numpy as np
import pinocchio as pin
import yaml
from scipy.spatial import ConvexHull

# ident reads the run config's limits only (the robot it selected: URDF + config + export
# targets); none of its safety or geometry code is used here
from ident.model.selection import load_robot
from ident.run.config import load_run_config
from ident.run.exports.run_exports import effective_limits

#: Factor on the sampled speeds bounding the speed between two samples (conservative
#: advancement); the trajectories are C2 at >= 1 kHz, their speeds change by far less.
TRAVEL_SAFETY = 1.5
#: Tolerance of the limit comparisons (relative), against round-off in the CSV.
LIMIT_RTOL = 1e-9
#: A geometry whose height moves by less than this over the trajectory is fixed [m].
FIXED_HEIGHT_M = 1e-9
#: Speed below which the trajectory is at rest at its ends [rad/s or m/s].
REST_TOL = 1e-9
#: The name (as a link) of ``safety.payload_box``'s geometry.
PAYLOAD = "payload"


@dataclass
class Verdict:
    """The outcome of :func:`check_trajectory`.

    ``failures``: one line per violated check; ``not_checked``: checks that could not run;
    ``notes``: what was accepted and why (exclusions, the fixed geometries on the floor).
    Clearances in m, ratios ``|value| / limit``, times in s of ``trajectory.csv``.
    """

    rate_hz: float
    n_samples: int
    margin_m: float
    failures: list[str] = field(default_factory=list)
    not_checked: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    clearance_m: float = math.inf
    closest_pair: str = ""
    closest_time: float = math.nan
    floor_m: float = math.inf
    floor_geometry: str = ""
    velocity_ratio: float = 0.0
    acceleration_ratio: float = 0.0
    torque_ratio: float = 0.0
    n_pairs: int = 0
    pairs: list[str] = field(default_factory=list)
    n_distances: int = 0

    @property
    def ok(self) -> bool:
        """True when every check ran and held."""
        return not self.failures

    def summary(self) -> str:
        """One line: pass/FAIL, the smallest clearance and floor distance, the peak ratios."""
        head = "pass" if self.ok else "FAIL: " + "; ".join(self.failures[:3])
        text = (
            f"{head} ({self.n_samples} samples at {self.rate_hz:g} Hz; {self.n_pairs} link "
            f"pairs: clearance {1e3 * self.clearance_m:.1f} mm ({self.closest_pair} at "
            f"t = {self.closest_time:.3f} s), floor {1e3 * self.floor_m:.1f} mm "
            f"({self.floor_geometry}), margin {1e3 * self.margin_m:g} mm; |dq| <= "
            f"{100 * self.velocity_ratio:.0f} %, |ddq| <= {100 * self.acceleration_ratio:.0f} "
            f"%, |tau| <= {100 * self.torque_ratio:.0f} % of the limits)"
        )
        if self.not_checked:
            text += "; not checked: " + "; ".join(self.not_checked)
        return text


@dataclass(frozen=True)
class UrdfJoint:
    """A joint as the URDF writes it (NaN: a limit the file does not give)."""

    name: str
    kind: str
    parent: str
    child: str
    lower: float
    upper: float
    velocity: float
    effort: float
    mimic: tuple[str, float, float] | None  # leader, multiplier, offset


def read_urdf_joints(text: str) -> dict[str, UrdfJoint]:
    """The ``<joint>`` elements of a URDF text, by name."""
    joints = {}
    for node in ET.fromstring(text).iter("joint"):
        parent, child = node.find("parent"), node.find("child")
        if parent is None or child is None:
            continue  # a <transmission>'s <joint> reference
        limit = node.find("limit")

        def value(key: str, default: float = math.nan, limit: Any = limit) -> float:
            raw = None if limit is None else limit.get(key)
            return default if raw is None else float(raw)

        mimic = node.find("mimic")
        joints[node.get("name", "")] = UrdfJoint(
            name=node.get("name", ""),
            kind=node.get("type", ""),
            parent=parent.get("link", ""),
            child=child.get("link", ""),
            lower=value("lower"),
            upper=value("upper"),
            velocity=value("velocity"),
            effort=value("effort"),
            mimic=None
            if mimic is None
            else (
                mimic.get("joint", ""),
                float(mimic.get("multiplier", 1.0)),
                float(mimic.get("offset", 0.0)),
            ),
        )
    return joints


def read_trajectory(path: Path) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``trajectory.csv``: joint names and t (n,), q, dq, ddq (n, n_joints) [s, rad, rad/s,
    rad/s^2]."""
    with path.open(newline="") as f:
        header = next(csv.reader(f))
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    names = [h[2:] for h in header if h.startswith("q_")]
    columns = {h: i for i, h in enumerate(header)}

    def block(prefix: str) -> np.ndarray:
        return data[:, [columns[prefix + n] for n in names]]

    return names, data[:, columns["t"]], block("q_"), block("dq_"), block("ddq_")


def upsample(t: np.ndarray, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray, factor: int) -> tuple:
    """The trajectory at ``factor`` times its rate: quintic Hermite between the samples
    (matching q, dq, ddq at both ends of each interval)."""
    if factor <= 1:
        return t, q, dq, ddq
    h = np.diff(t)[:, None]
    s = (np.arange(factor) / factor)[None, :, None]  # (1, factor, 1)
    p0, v0, a0 = q[:-1, None], dq[:-1, None] * h[:, None], ddq[:-1, None] * h[:, None] ** 2
    p1, v1, a1 = q[1:, None], dq[1:, None] * h[:, None], ddq[1:, None] * h[:, None] ** 2
    # the quintic's coefficients in s in [0, 1], per interval and joint
    c3 = 10 * (p1 - p0) - 6 * v0 - 4 * v1 - 1.5 * a0 + 0.5 * a1
    c4 = -15 * (p1 - p0) + 8 * v0 + 7 * v1 + 1.5 * a0 - a1
    c5 = 6 * (p1 - p0) - 3 * (v0 + v1) - 0.5 * (a0 - a1)
    pos = p0 + v0 * s + 0.5 * a0 * s**2 + c3 * s**3 + c4 * s**4 + c5 * s**5
    vel = v0 + a0 * s + 3 * c3 * s**2 + 4 * c4 * s**3 + 5 * c5 * s**4
    acc = a0 + 6 * c3 * s + 12 * c4 * s**2 + 20 * c5 * s**3
    hh = h[:, None]
    flat = lambda x: x.reshape(-1, q.shape[1])  # noqa: E731
    tt = (t[:-1, None] + h * s[..., 0]).reshape(-1)
    return (
        np.append(tt, t[-1]),
        np.vstack([flat(pos), q[-1:]]),
        np.vstack([flat(vel / hh), dq[-1:]]),
        np.vstack([flat(acc / hh**2), ddq[-1:]]),
    )


class Robot:
    """The whole URDF in Pinocchio (every joint, none locked) with its collision geometry, and
    the rule that turns the trajectory's joints into a whole-robot configuration."""

    def __init__(
        self,
        urdf_text: str,
        package_dirs: list[str],
        moving: list[str],
        locks: dict[str, float],
        mesh_dir: str | None = None,
    ) -> None:
        self.joints = read_urdf_joints(urdf_text)
        self.model = pin.buildModelFromXML(urdf_text)
        dirs = list(package_dirs) + ([mesh_dir] if mesh_dir else [])
        self.geom = pin.buildGeomFromUrdfString(
            self.model, urdf_text, pin.COLLISION, package_dirs=dirs
        )
        self.data = self.model.createData()
        self.gdata = pin.GeometryData(self.geom)
        self.moving = list(moving)
        self.locks = dict(locks)
        missing = [n for n in moving if n not in self.joints]
        if missing:
            raise ValueError(f"trajectory joints {missing} are not joints of the URDF")
        self.link_of = [self.model.frames[g.parentFrame].name for g in self.geom.geometryObjects]
        self.payload_link = ""

    def add_payload_box(self, box: dict) -> None:
        """``safety.payload_box`` (``size``, ``position``, ``rpy`` [m, rad] in the frame of
        ``link``, by default the last trajectory joint's) as a coal box geometry named
        :data:`PAYLOAD`: placed at the link frame's placement in its joint times the box pose."""
        link = box.get("link") or self.joints[self.moving[-1]].child
        frame_id = self.model.getFrameId(link)
        frame = self.model.frames[frame_id]
        pose = pin.SE3(
            pin.rpy.rpyToMatrix(*[float(a) for a in box.get("rpy") or (0.0, 0.0, 0.0)]),
            np.asarray(box.get("position") or (0.0, 0.0, 0.0), dtype=float),
        )
        shape = coal.Box(*[float(a) for a in box["size"]])
        placement = frame.placement * pose
        obj = pin.GeometryObject(PAYLOAD, frame.parentJoint, frame_id, placement, shape)
        self.geom.addGeometryObject(obj)
        self.gdata = pin.GeometryData(self.geom)
        self.link_of.append(PAYLOAD)
        self.payload_link = link

    def joint_values(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> dict[str, tuple]:
        """Every movable URDF joint's (q, dq, ddq) series (n,): the trajectory's own, mimic
        followers from their leaders, the locked ones at their config value, the others at 0
        clipped into their limits (how ident holds the joints off the chain)."""
        n = q.shape[0]
        out: dict[str, tuple] = {}
        for i, name in enumerate(self.moving):
            out[name] = (q[:, i], dq[:, i], ddq[:, i])

        def resolve(name: str) -> tuple:
            if name in out:
                return out[name]
            joint = self.joints[name]
            if joint.mimic is not None and joint.mimic[0] in self.joints:
                lead, m, o = joint.mimic
                ql, vl, al = resolve(lead)
                out[name] = (m * ql + o, m * vl, m * al)
            else:
                held = self.locks.get(name, _home_value(joint))
                out[name] = (np.full(n, held), np.zeros(n), np.zeros(n))
            return out[name]

        for name, joint in self.joints.items():
            if joint.kind not in ("fixed", "floating", "planar"):
                resolve(name)
        return out

    def configurations(self, values: dict[str, tuple]) -> tuple[np.ndarray, ...]:
        """Pinocchio's q (n, nq), v, a (n, nv) of the joint series ``values``."""
        model = self.model
        n = next(iter(values.values()))[0].shape[0]
        qs, vs, accs = np.zeros((n, model.nq)), np.zeros((n, model.nv)), np.zeros((n, model.nv))
        for j in range(1, model.njoints):
            joint, name = model.joints[j], model.names[j]
            pos, vel, acc = values[name]
            if joint.nq == 2:  # a continuous joint: (cos, sin)
                qs[:, joint.idx_q], qs[:, joint.idx_q + 1] = np.cos(pos), np.sin(pos)
            else:
                qs[:, joint.idx_q] = pos
            vs[:, joint.idx_v], accs[:, joint.idx_v] = vel, acc
        return qs, vs, accs


def _home_value(joint: UrdfJoint) -> float:
    """0 clipped into the joint's limits (0 when it has none or an empty range)."""
    if joint.kind == "continuous" or not joint.upper > joint.lower:
        return 0.0
    return float(np.clip(0.0, joint.lower, joint.upper))


def _moves(robot: Robot, name: str) -> bool:
    """True when the joint ``name`` moves: a trajectory joint or a mimic of one."""
    joint = robot.joints[name]
    if name in robot.moving:
        return True
    return (
        joint.mimic is not None and joint.mimic[0] in robot.joints and _moves(robot, joint.mimic[0])
    )


def check_limits(robot: Robot, t: np.ndarray, values: dict, tau: np.ndarray, out: Verdict) -> None:
    """Positions, velocities (``values``: joint -> (q, dq, ddq) series) and RNEA torques
    ``tau`` (n, nv) of every moving joint against the URDF's limits, into ``out``."""
    for name, joint in robot.joints.items():
        if joint.kind in ("fixed", "floating", "planar") or not _moves(robot, name):
            continue
        pos, vel, _ = values[name]
        if joint.kind != "continuous":
            if joint.upper > joint.lower:
                tol = LIMIT_RTOL * max(1.0, abs(joint.lower), abs(joint.upper))
                low, high = pos.min(), pos.max()
                if low < joint.lower - tol or high > joint.upper + tol:
                    k = int(np.argmax(np.maximum(joint.lower - pos, pos - joint.upper)))
                    out.failures.append(
                        f"position {name} = {pos[k]:.6g} at t = {t[k]:.3f} s outside "
                        f"[{joint.lower:g}, {joint.upper:g}]"
                    )
            else:
                out.not_checked.append(f"position of {name} (the URDF gives no range)")
        _peak(name, "velocity", np.abs(vel), joint.velocity, t, out)
        v = robot.model.joints[robot.model.getJointId(name)].idx_v
        _peak(name, "torque", np.abs(tau[:, v]), joint.effort, t, out)


def _peak(
    name: str,
    kind: str,
    series: np.ndarray,
    limit: float,
    t: np.ndarray,
    out: Verdict,
    whose: str = "the URDF's",
) -> None:
    """``max |series| <= limit`` (unknown when ``whose`` limit is missing, 0 or inf); ``kind``
    velocity, acceleration or torque (its peak ratio kept in ``out``)."""
    if not (limit > 0 and math.isfinite(limit)):
        out.not_checked.append(f"{kind} of {name} ({whose} limit is {limit:g})")
        return
    k = int(np.argmax(series))
    attr = f"{kind}_ratio"
    setattr(out, attr, max(getattr(out, attr), float(series[k] / limit)))
    if series[k] > limit * (1 + LIMIT_RTOL):
        out.failures.append(
            f"{kind} {name} = {series[k]:.6g} at t = {t[k]:.3f} s above {whose} {limit:g}"
        )


def kinematics(robot: Robot, qs: np.ndarray, vs: np.ndarray, accs: np.ndarray) -> tuple:
    """Per sample: each joint's rotation (n, nj, 3, 3), origin (n, nj, 3) and spatial
    velocity in the world frame at the world's origin (n, nj, 6: linear, angular) [m, m/s,
    rad/s]; the RNEA torques (n, nv) [N*m or N].

    The placements and twists are composed down the tree for all samples at once (reading
    them back from Pinocchio sample by sample costs ten times its RNEA); every joint has one
    axis (revolute, continuous, prismatic; fixed joints are not joints in Pinocchio), else
    :func:`_sampled_kinematics`."""
    model, data = robot.model, robot.data
    tau = np.array([pin.rnea(model, data, *x) for x in zip(qs, vs, accs, strict=True)])
    n, nj = qs.shape[0], model.njoints
    rot, pos = np.zeros((n, nj, 3, 3)), np.zeros((n, nj, 3))
    rot[:, 0] = np.eye(3)
    linear, angular = np.zeros((n, nj, 3)), np.zeros((n, nj, 3))
    for j in range(1, nj):
        joint, parent, place = model.joints[j], model.parents[j], model.jointPlacements[j]
        if joint.nv != 1:  # a floating or planar joint: Pinocchio's, sample by sample
            return (*_sampled_kinematics(robot, qs, vs), tau)
        jd = joint.createData()
        joint.calc(jd, pin.neutral(model))
        motion = np.asarray(jd.S, dtype=float).reshape(6)  # (linear, angular) in the joint
        angle = qs[:, joint.idx_q]
        if joint.nq == 2:  # continuous: (cos, sin)
            angle = np.arctan2(qs[:, joint.idx_q + 1], qs[:, joint.idx_q])
        speed = vs[:, joint.idx_v]
        base = rot[:, parent] @ place.rotation  # (n, 3, 3)
        pos[:, j] = pos[:, parent] + rot[:, parent] @ place.translation
        if np.linalg.norm(motion[3:]) > 0:  # revolute about the unit axis motion[3:]
            rot[:, j] = base @ _axis_rotation(motion[3:], angle)
            axis = base @ motion[3:]
            angular[:, j] = angular[:, parent] + axis * speed[:, None]
            # a turn about the line through pos[j]: p x w at the world's origin
            linear[:, j] = linear[:, parent] + np.cross(pos[:, j], axis) * speed[:, None]
        else:  # prismatic along motion[:3]
            rot[:, j], axis = base, base @ motion[:3]
            pos[:, j] += axis * angle[:, None]
            angular[:, j] = angular[:, parent]
            linear[:, j] = linear[:, parent] + axis * speed[:, None]
    return rot, pos, np.concatenate([linear, angular], axis=2), tau


def _sampled_kinematics(robot: Robot, qs: np.ndarray, vs: np.ndarray) -> tuple:
    """:func:`kinematics`' rotations, origins and twists read from Pinocchio sample by
    sample (any joint type)."""
    model, data = robot.model, robot.data
    n, nj = qs.shape[0], model.njoints
    placement, local = np.zeros((n, nj, 4, 4)), np.zeros((n, nj, 6))
    for s in range(n):
        pin.forwardKinematics(model, data, qs[s], vs[s])
        placement[s] = [m.homogeneous for m in data.oMi]
        local[s] = [v.vector for v in data.v]
    rot, pos = placement[:, :, :3, :3], placement[:, :, :3, 3]
    # the twist moved to the world's origin: angular R w, linear R v + p x (R w)
    angular = np.einsum("njab,njb->nja", rot, local[:, :, 3:])
    linear = np.einsum("njab,njb->nja", rot, local[:, :, :3]) + np.cross(pos, angular)
    return rot, pos, np.concatenate([linear, angular], axis=2)


def _axis_rotation(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations (n, 3, 3) by ``angle`` (n,) [rad] about the unit ``axis`` (3,) (Rodrigues)."""
    k = pin.skew(axis)
    s, c = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def pair_speeds(robot: Robot, rot: np.ndarray, pos: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """A bound of how fast each collision pair's distance changes, per sample (n, n_pairs)
    [m/s]: the fastest point of one geometry's bounding sphere relative to the other
    geometry's body (their twists' difference), the smaller of the two ways round."""
    objects = robot.geom.geometryObjects
    centre, radius = [], []
    for obj in objects:  # the geometry's bounding sphere, in its joint's frame
        obj.geometry.computeLocalAABB()
        centre.append(obj.placement.act(np.asarray(obj.geometry.aabb_center, dtype=float)))
        radius.append(float(obj.geometry.aabb_radius))
    out = np.zeros((rot.shape[0], len(robot.geom.collisionPairs)))
    speed: dict[tuple[int, int], np.ndarray] = {}  # (geometry, other joint) -> (n,)

    world: dict[int, np.ndarray] = {}  # geometry -> its sphere's centre (n, 3) [m]

    def norm(x: np.ndarray) -> np.ndarray:
        return np.sqrt(np.einsum("ni,ni->n", x, x))

    def sphere_speed(mine: int, jo: int) -> np.ndarray:
        if (mine, jo) not in speed:
            jm = objects[mine].parentJoint
            if mine not in world:
                world[mine] = rot[:, jm] @ centre[mine] + pos[:, jm]
            rel = twist[:, jm] - twist[:, jo]  # mine's motion seen from the other's body
            point = rel[:, :3] + np.cross(rel[:, 3:], world[mine])
            speed[mine, jo] = norm(point) + norm(rel[:, 3:]) * radius[mine]
        return speed[mine, jo]

    for p, pair in enumerate(robot.geom.collisionPairs):
        first, second = pair.first, pair.second
        out[:, p] = np.minimum(
            sphere_speed(first, objects[second].parentJoint),
            sphere_speed(second, objects[first].parentJoint),
        )
    return out


def _bodies(robot: Robot) -> dict[str, str]:
    """Each link's rigid body: the root link of the links joined to it by joints that do not
    move (fixed, locked, held) — union-find over the URDF's joints."""
    parent = {}

    def find(link: str) -> str:
        while parent.get(link, link) != link:
            link = parent[link]
        return link

    for name, joint in robot.joints.items():
        for link in (joint.parent, joint.child):
            parent.setdefault(link, link)
        if joint.kind == "fixed" or not _moves(robot, name):
            parent[find(joint.child)] = find(joint.parent)
    return {link: find(link) for link in parent}


def justify_exclusion(robot: Robot, a: str, b: str, homes: list[np.ndarray]) -> str:
    """Why ident may leave the link pair ``a``, ``b`` out ("" when nothing justifies it): one
    moving joint between their bodies, one rigid body, or contact in a posture of ``homes``
    (pinocchio configurations)."""
    body = _bodies(robot)
    if a not in body or b not in body:
        return ""
    if body[a] == body[b]:
        return "one rigid body (their distance never changes)"
    for name, joint in robot.joints.items():
        ends = {body.get(joint.parent), body.get(joint.child)}
        if _moves(robot, name) and ends == {body[a], body[b]}:
            return f"adjacent (joint {name})"
    pairs = [
        (i, k)
        for i, la in enumerate(robot.link_of)
        for k, lb in enumerate(robot.link_of)
        if i < k and {la, lb} == {a, b}
    ]
    for which, q in zip(("home", "trajectory start"), homes, strict=True):
        for i, k in pairs:
            if _in_contact(robot, q, i, k):
                return f"in contact at the {which} posture"
    return ""


def _in_contact(robot: Robot, q: np.ndarray, i: int, k: int) -> bool:
    """True when geometries ``i`` and ``k`` touch (coal collision, no margin) at ``q``."""
    pin.updateGeometryPlacements(robot.model, robot.data, robot.geom, robot.gdata, q)
    place = [robot.gdata.oMg[g] for g in (i, k)]
    shapes = [robot.geom.geometryObjects[g].geometry for g in (i, k)]
    request, result = coal.CollisionRequest(), coal.CollisionResult()
    request.security_margin = 0.0
    transforms = [coal.Transform3s(m.rotation, m.translation) for m in place]
    return coal.collide(shapes[0], transforms[0], shapes[1], transforms[1], request, result) > 0


def _pair_distance(robot: Robot, p: int) -> float:
    """The distance of the collision pair ``p`` at the current placements [m] (<= 0 in contact:
    coal's distance, or 0 where it reports a collision without a depth)."""
    d = pin.computeDistance(robot.geom, robot.gdata, p).min_distance
    if d <= 0.0 or pin.computeCollision(robot.geom, robot.gdata, p):
        return min(d, 0.0)
    return float(d)


def clearances(
    robot: Robot, t: np.ndarray, qs: np.ndarray, speed: np.ndarray, margin: float
) -> tuple[np.ndarray, np.ndarray, int]:
    """Each collision pair's (``robot.geom.collisionPairs``) smallest measured distance [m]
    and its sample index, and the number of distances measured.

    Conservative advancement: after a distance ``d`` at sample s, the pair is measured again
    at the first sample at which it may have closed ``d - level`` (``level``: the ``margin``
    [m] or the smallest distance found so far, the larger), at the rate ``speed`` (n, n_pairs)
    [m/s] (:func:`pair_speeds`, :data:`TRAVEL_SAFETY` x the larger of two samples' between
    them). So every sample below the margin is measured, and the smallest of all the pairs'
    values is the smallest distance of every sample."""
    n, n_pairs = t.size, speed.shape[1]
    best, when = np.full(n_pairs, np.inf), np.zeros(n_pairs, dtype=int)
    if n_pairs == 0:
        return best, when, 0
    step = TRAVEL_SAFETY * np.maximum(speed[1:], speed[:-1]) * np.diff(t)[:, None]
    travel = np.vstack([np.zeros((1, n_pairs)), np.cumsum(step, axis=0)])
    due = np.zeros(n_pairs, dtype=int)
    measured = 0
    while (s := int(due.min())) < n:
        pin.updateGeometryPlacements(robot.model, robot.data, robot.geom, robot.gdata, qs[s])
        for p in np.flatnonzero(due == s).tolist():
            d = _pair_distance(robot, p)
            measured += 1
            if d < best[p]:
                best[p], when[p] = d, s
            # below the margin or the smallest distance found (of any pair): the next sample
            level = max(margin, float(best.min()))
            if d <= level:
                due[p] = s + 1
            else:  # the first sample at which it may have closed d - level
                k = int(np.searchsorted(travel[:, p], travel[s, p] + d - level, side="left"))
                due[p] = max(k, s + 1)
    return best, when, measured


def floor_heights(robot: Robot, rot: np.ndarray, pos: np.ndarray) -> np.ndarray:
    """Each geometry's lowest point's height (n, n_geoms) [m] from the joints' rotations
    (n, nj, 3, 3) and origins (n, nj, 3): mesh (convex hull) and box vertices, spheres,
    capsules and cylinders in closed form; NaN for another shape."""
    objects = robot.geom.geometryObjects
    out = np.full((rot.shape[0], len(objects)), np.nan)
    for g, obj in enumerate(objects):
        j, shape = obj.parentJoint, obj.geometry
        r_j, p_j = rot[:, j], pos[:, j]  # (n, 3, 3), (n, 3)
        centre = np.einsum("nk,k->n", r_j[:, 2], obj.placement.translation) + p_j[:, 2]
        axis_z = np.einsum("nk,k->n", r_j[:, 2], obj.placement.rotation[:, 2])  # shape's z
        name = type(shape).__name__
        if name == "Sphere":
            out[:, g] = centre - shape.radius
        elif name == "Capsule":
            out[:, g] = centre - np.abs(axis_z) * shape.halfLength - shape.radius
        elif name == "Cylinder":
            side = np.sqrt(np.clip(1.0 - axis_z**2, 0.0, None))
            out[:, g] = centre - np.abs(axis_z) * shape.halfLength - shape.radius * side
        elif name == "Box" or name.startswith("BVHModel") or name.startswith("Convex"):
            local = _vertices(shape) @ obj.placement.rotation.T + obj.placement.translation
            out[:, g] = (r_j[:, 2] @ local.T).min(axis=1) + p_j[:, 2]
    return out


def _vertices(shape: Any) -> np.ndarray:
    """A box's corners or a mesh's convex hull vertices (m, 3) in the shape's frame [m]."""
    if type(shape).__name__ == "Box":
        half = np.asarray(shape.halfSide, dtype=float)
        signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
        return signs * half
    points = np.asarray(shape.vertices() if hasattr(shape, "vertices") else shape.points())
    try:
        return points[ConvexHull(points).vertices]
    except Exception:  # flat or degenerate: every vertex
        return points


def check_trajectory(
    robot: Robot,
    t: np.ndarray,
    q: np.ndarray,
    dq: np.ndarray,
    ddq: np.ndarray,
    *,
    margin_m: float,
    floor_z: float | None,
    excluded: list[str],
    rate_hz: float,
) -> Verdict:
    """Check the trajectory t (n,) [s], q, dq, ddq (n, n_moving) of ``robot.moving`` (see the
    module docstring); ``excluded``: ident's left-out pairs ``"link|link"``; ``floor_z`` [m]
    or None (no floor); ``rate_hz``: the least rate to check at."""
    own = 1.0 / float(np.median(np.diff(t)))
    t, q, dq, ddq = upsample(t, q, dq, ddq, math.ceil(rate_hz / own - 1e-6))
    out = Verdict(rate_hz=1.0 / float(np.median(np.diff(t))), n_samples=t.size, margin_m=margin_m)
    values = robot.joint_values(q, dq, ddq)
    qs, vs, accs = robot.configurations(values)
    rot, pos, twist, tau = kinematics(robot, qs, vs, accs)
    check_limits(robot, t, values, tau, out)
    home = {n: (np.array([_home_value(robot.joints[n])]),) * 3 for n in robot.moving}
    homes = [robot.configurations(robot.joint_values(*_stack(home, robot.moving)))[0][0], qs[0]]
    _set_pairs(robot, excluded, homes, out)
    speed = pair_speeds(robot, rot, pos, twist)
    best, when, out.n_distances = clearances(robot, t, qs, speed, margin_m)
    _clearance_result(robot, t, best, when, out)
    if floor_z is None:
        out.not_checked.append("the floor (safety.floor disabled)")
    else:
        _floor_result(robot, t, floor_heights(robot, rot, pos) - floor_z, out)
    return out


def _stack(series: dict, names: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(q, dq, ddq) arrays (n, len(names)) of per-joint ``series``."""
    return tuple(np.column_stack([series[n][i] for n in names]) for i in range(3))  # type: ignore


def _set_pairs(robot: Robot, excluded: list[str], homes: list[np.ndarray], out: Verdict) -> None:
    """Register in ``robot.geom`` the geometry pairs to check: every pair of geometries of two
    links, but the link pairs ident excluded with a reason found here (noted in ``out``)."""
    accepted = set()
    for entry in excluded:
        a, _, b = entry.partition("|")
        if a not in robot.link_of or b not in robot.link_of:
            continue  # the floor, an obstacle, a payload: checked on their own
        if PAYLOAD in (a, b):  # the box is left out only against its own rigid body
            body = _bodies(robot)
            other = b if a == PAYLOAD else a
            same = body.get(other, other) == body.get(robot.payload_link, robot.payload_link)
            why = "the payload box's own rigid body" if same else ""
        else:
            why = justify_exclusion(robot, a, b, homes)
        if why:
            accepted.add(frozenset((a, b)))
            out.notes.append(f"{a}|{b} left out: {why}")
        else:
            out.notes.append(
                f"{a}|{b} excluded by ident, but neither adjacent nor in contact at home: checked"
            )
    robot.geom.removeAllCollisionPairs()
    links, body = robot.link_of, _bodies(robot)
    # the payload box rides on its link's rigid body: every other body is checked against it
    ride = {PAYLOAD: body.get(robot.payload_link, robot.payload_link)}
    for i in range(len(links)):
        for k in range(i + 1, len(links)):
            if links[i] == links[k] or frozenset((links[i], links[k])) in accepted:
                continue
            if PAYLOAD in (links[i], links[k]) and ride.get(links[i], body.get(links[i])) == (
                ride.get(links[k], body.get(links[k]))
            ):
                continue  # the box and the link it is fixed to
            robot.geom.addCollisionPair(pin.CollisionPair(i, k))
    robot.gdata = pin.GeometryData(robot.geom)
    for request in robot.gdata.collisionRequests:
        request.security_margin = 0.0
    out.pairs = sorted(
        {"|".join(sorted((links[c.first], links[c.second]))) for c in robot.geom.collisionPairs}
    )
    out.n_pairs = len(out.pairs)


def _clearance_result(
    robot: Robot, t: np.ndarray, best: np.ndarray, when: np.ndarray, out: Verdict
) -> None:
    """Each link pair's smallest distance against the margin, into ``out``."""
    worst: dict[str, tuple[float, int]] = {}
    for p, c in enumerate(robot.geom.collisionPairs):
        key = "|".join(sorted((robot.link_of[c.first], robot.link_of[c.second])))
        if key not in worst or best[p] < worst[key][0]:
            worst[key] = (float(best[p]), int(when[p]))
    for key, (d, s) in sorted(worst.items(), key=lambda kv: kv[1][0]):
        if d < out.clearance_m:
            out.clearance_m, out.closest_pair, out.closest_time = d, key, float(t[s])
        if d < out.margin_m - 1e-9:
            out.failures.append(
                f"clearance {key} = {1e3 * d:.2f} mm at t = {t[s]:.3f} s below the margin "
                f"{1e3 * out.margin_m:g} mm"
            )


def _floor_result(robot: Robot, t: np.ndarray, height: np.ndarray, out: Verdict) -> None:
    """Each geometry's height above the floor (n, n_geoms) [m] against the margin."""
    for g, obj in enumerate(robot.geom.geometryObjects):
        h = height[:, g]
        if np.isnan(h).all():
            out.not_checked.append(f"floor for {obj.name} ({type(obj.geometry).__name__})")
            continue
        if h.max() - h.min() < FIXED_HEIGHT_M:
            out.notes.append(
                f"{obj.name} never moves up or down: {1e3 * h[0]:.1f} mm above the floor"
            )
            continue
        s = int(np.argmin(h))
        if h[s] < out.floor_m:
            out.floor_m, out.floor_geometry = float(h[s]), obj.name
        if h[s] < out.margin_m - 1e-9:
            out.failures.append(
                f"floor: {obj.name} {1e3 * h[s]:.2f} mm above it at t = {t[s]:.3f} s, below "
                f"the margin {1e3 * out.margin_m:g} mm"
            )


def check_run_folder(run_dir: str | Path) -> Verdict:
    """Re-check the ``trajectory.csv`` of an ``ident run`` folder (see the module docstring).

    Raises FileNotFoundError when the folder has no ``trajectory.csv`` (ident found no safe
    trajectory: nothing to re-check)."""
    run_dir = Path(run_dir)
    if not (run_dir / "trajectory.csv").is_file():
        raise FileNotFoundError(f"{run_dir}: no trajectory.csv (ident chose no trajectory)")
    config = yaml.safe_load((run_dir / "config.yaml").read_text(encoding="utf-8"))
    result = json.loads((run_dir / "result.json").read_text(encoding="utf-8"))
    # no safety section: ident's defaults (its margin is the one it recorded in result.json)
    rob, safety = config["robot"], config.get("safety") or {}
    names, t, q, dq, ddq = read_trajectory(run_dir / "trajectory.csv")
    urdf = rob.get("urdf")
    robot = Robot(
        (run_dir / "robot.urdf").read_text(encoding="utf-8"),
        [str(p) for p in rob.get("package_dirs") or []],
        names,
        {str(k): float(v) for k, v in (rob.get("lock") or {}).items()},
        mesh_dir=None if not urdf else str(Path(urdf).parent),
    )
    if safety.get("payload_box"):
        robot.add_payload_box(safety["payload_box"])
    rank = result.get("executed_elite") or result.get("chosen_elite") or 1
    series = result["elites"][rank - 1].get("safety_series") or {}
    excluded = [e["pair"] for e in series.get("not_checked") or [] if "pair" in e]
    floor = safety.get("floor") or {}
    out = check_trajectory(
        robot, t, q, dq, ddq,
        margin_m=float(safety.get("clearance_m", series.get("clearance_m", math.nan))),
        floor_z=float(floor.get("z", 0.0)) if floor.get("enabled", True) else None,
        excluded=excluded,
        rate_hz=max(float(safety.get("check_rate_hz", 1000.0)),
                    float((config.get("controller") or {}).get("rate_hz", 0.0))),
    )  # fmt: skip
    check_selected_limits(run_dir / "config.yaml", names, t, (q, dq, ddq), out)
    _check_rest(t, dq, out)
    if safety.get("obstacles"):
        out.not_checked.append(f"{len(safety['obstacles'])} obstacle(s) of safety.obstacles")
    if (config.get("measurement") or {}).get("payload"):
        out.not_checked.append("the payload's torques (measurement.payload)")
    return out


def check_selected_limits(
    config_path: Path, names: list[str], t: np.ndarray, series: tuple, out: Verdict
) -> None:
    """The trajectory's samples t (n,) [s] and ``series`` (q, dq, ddq), each (n, len(names)),
    against the limits the run selected (the URDF's tightened by the config and the export
    targets, read by ident's config loader), into ``out``: positions within [lower, upper],
    ``|dq| <= dq_max``, ``|ddq| <= ddq_max`` (a limit nobody gave: named as not checked)."""
    config = load_run_config(config_path)
    limits, _ = effective_limits(
        config.controller.export, load_robot(config.robot, source=config_path), config_path
    )
    if list(limits.joint_names) != list(names):
        out.failures.append(f"trajectory joints {names}, the run's robot's {limits.joint_names}")
        return
    q, dq, ddq = series
    lower, upper = np.asarray(limits.q_lower), np.asarray(limits.q_upper)
    tol = LIMIT_RTOL * np.maximum(1.0, np.maximum(np.abs(lower), np.abs(upper)))
    for i, name in enumerate(names):
        outside = np.maximum(lower[i] - q[:, i], q[:, i] - upper[i])
        k = int(np.argmax(outside))
        if outside[k] > tol[i]:
            out.failures.append(
                f"position {name} = {q[k, i]:.6g} at t = {t[k]:.3f} s outside the run's "
                f"[{lower[i]:g}, {upper[i]:g}]"
            )
        _peak(name, "velocity", np.abs(dq[:, i]), float(limits.dq_max[i]), t, out, "the run's")
        acc = float(limits.ddq_max[i])
        _peak(name, "acceleration", np.abs(ddq[:, i]), acc, t, out, "the run's")


def _check_rest(t: np.ndarray, dq: np.ndarray, out: Verdict) -> None:
    """The trajectory starts and ends at rest: ``|dq| <= REST_TOL`` at its first and last
    samples (dq (n, n_joints) [rad/s])."""
    for k in (0, -1):
        if np.abs(dq[k]).max() > REST_TOL:
            out.failures.append(f"not at rest at t = {t[k]:.3f} s: |dq| = {np.abs(dq[k]).max():g}")


def main() -> None:
    """``python benchmarks/independent_safety.py RUN_FOLDER...``: one line each; exit 1 on a
    failure."""
    failed = False
    for folder in sys.argv[1:]:
        verdict = check_run_folder(folder)
        print(f"{folder}: {verdict.summary()}")
        for note in verdict.notes:
            print(f"  {note}")
        failed |= not verdict.ok
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
