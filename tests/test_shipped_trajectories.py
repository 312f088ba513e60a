"""Every trajectory ``ident run`` writes for a shipped run config is safe, checked independently.

For each config under ``configs/`` that ``ident run`` accepts, the run's ``trajectory.csv``
(what a controller would execute: approach, periods, return, at the controller's rate) is
re-checked here with plain Pinocchio and coal, not with ``ident.excitation``:

- position, velocity and acceleration limits of the selected robot, and the torque of
  ``pin.rnea`` with the URDF's inertials against the URDF's ``effort`` where it is given;
- the URDF's collision geometry as loaded (meshes as coal BVH, never their hulls), at every
  sample (1 kHz), at least the config's clearance apart: every pair of links on non-adjacent
  joints except those in contact in the reference posture (0 clipped into the limits, the
  MoveIt setup assistant's "default" rule), and every geometry against the floor except those
  whose floor distance never changes and is below the margin (the base standing on it, a
  first link turning on it). Hull distances (a hull contains its mesh: a lower bound) are a
  broad phase: the mesh is measured wherever the hulls are within the margin + 5 cm. The
  floor clearance is also computed from the meshes' vertices directly.

``configs/arm.yaml`` (the paper's arm stage) has no safe elite: the run exits 1 and writes no
``trajectory.csv`` (pinned in ``tests/test_run_safety.py``).

The same run also ends with the verdict a reader of its numbers would give (docs/verdict.md):
:data:`VERDICTS` holds each config's, with the numbers that make it so.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest

from ident.excitation.safety import SafetyConfig
from ident.run.config import load_run_config
from ident.run.setup import prepare_run
from ident.trajectory import read_trajectory_csv

REPO = Path(__file__).resolve().parents[1]

# the shipped run configs with a usable design (arm.yaml has none, see the module docstring)
CONFIGS = (
    "wrist",
    "wrist-fourier",
    "arm-fourier",
    "wrist-box",
    "arm-box",
    "ur5",
    "panda",
    "ur5-payload",
)

# config -> (verdict of `ident run`, the reason a reader of the numbers agrees; measured seed 0)
VERDICTS = {
    # the paper's noisy wrist: worst major error 646 % (Izz5R), residual 17.8 %
    "wrist": ("not identified", "major parameters off by several times their value"),
    # Fourier wrist: worst major error 11 %, residual 22.7 % (the torque noise)
    "wrist-fourier": ("usable", "major parameters within 20 %, residual below 25 %"),
    # Fourier arm: worst major error 2.33 % (mcy2), residual 0.86 %
    "arm-fourier": ("good", "major parameters within 5 %, residual below 10 %"),
    # box-limited wrist: worst major error 98 % (Izz6), residual 21.6 %
    "wrist-box": ("not identified", "a major parameter off by almost its value"),
    # box-limited arm, executed elite 4: worst major error 19.3 %, residual 1.8 %
    "arm-box": ("usable", "major parameters within 20 % but not 5 %"),
    # MuJoCo UR5: worst major error 3.2 % (Ia3), held-out residual 0.28 %
    "ur5": ("good", "major parameters within 5 %, held-out residual below 10 %"),
    # MuJoCo Panda: worst major error 2.4 % (Izz3R), held-out residual 0.21 %
    "panda": ("good", "major parameters within 5 %, held-out residual below 10 %"),
    # payload stage, the bare last body's 10 parameters (ideal torques, 0.05 N*m noise): worst
    # major error 9.66 % (Ixx6), residual 8.6 %; the payload itself comes from `ident payload`
    "ur5-payload": ("usable", "the last body's parameters within 20 % but not 5 %"),
}


def _geometry(
    urdf_text: str, joint_names: list[str], locked: dict[str, float], package_dirs: list[str]
) -> tuple[pin.Model, pin.GeometryModel]:
    """The URDF's kinematic model and collision geometry reduced to the trajectory's joints."""
    model = pin.buildModelFromXML(urdf_text)
    geom = pin.buildGeomFromUrdfString(
        model, urdf_text, pin.GeometryType.COLLISION, None, package_dirs
    )
    if list(model.names[1:]) != joint_names:
        reference = pin.neutral(model)
        for name, value in locked.items():
            reference[model.joints[model.getJointId(name)].idx_q] = value
        drop = [model.getJointId(n) for n in model.names[1:] if n not in joint_names]
        model, geom = pin.buildReducedModel(model, geom, drop, reference)
    assert list(model.names[1:]) == joint_names
    return model, geom


def _mesh_vertices(geom: pin.GeometryModel) -> dict[int, np.ndarray]:
    """Vertices (n, 3) of every mesh geometry in its own frame."""
    return {
        k: np.array(obj.geometry.vertices(), dtype=float).reshape(-1, 3)
        for k, obj in enumerate(geom.geometryObjects)
        if isinstance(obj.geometry, coal.BVHModelBase)
    }


def _hulls(geom: pin.GeometryModel) -> pin.GeometryModel:
    """A copy of ``geom`` with meshes replaced by their convex hulls (qhull), a broad phase."""
    hull = geom.clone()
    for obj in hull.geometryObjects:
        shape = obj.geometry
        if isinstance(shape, coal.BVHModelBase):
            shape.buildConvexHull(False, "")  # qhull: the hull, not the mesh relabelled
            obj.geometry = shape.convex
    return hull


def _add_box(model: pin.Model, geom: pin.GeometryModel, box: object) -> None:
    """``safety.payload_box`` as a coal box on its link's joint: the frame's placement in the
    joint times the box pose (``rpy`` then ``position``, in the link's frame)."""
    if box.link:
        frame_id = model.getFrameId(box.link)
        frame = model.frames[frame_id]
        joint, in_joint = frame.parentJoint, frame.placement
    else:  # the last moving joint's frame
        joint, in_joint = model.njoints - 1, pin.SE3.Identity()
        frame_id = model.getFrameId(model.names[joint])
    pose = pin.SE3(pin.rpy.rpyToMatrix(*box.rpy), np.asarray(box.position, dtype=float))
    shape = coal.Box(*box.size)
    geom.addGeometryObject(pin.GeometryObject("payload", joint, frame_id, in_joint * pose, shape))


def _radius(obj: pin.GeometryObject) -> float:
    """Farthest point of a geometry from its joint's origin [m] (mesh vertices, a primitive's
    bounding sphere)."""
    shape = obj.geometry
    if isinstance(shape, coal.BVHModelBase):
        v = np.array(shape.vertices(), dtype=float).reshape(-1, 3)
        placed = v @ obj.placement.rotation.T + obj.placement.translation
        return float(np.linalg.norm(placed, axis=1).max())
    shape.computeLocalAABB()
    centre = obj.placement.act(np.asarray(shape.aabb_center, dtype=float))
    return float(np.linalg.norm(centre)) + float(shape.aabb_radius)


def _distance_rates(model: pin.Model, geom: pin.GeometryModel, pairs, static: int) -> np.ndarray:  # noqa: ANN001
    """``w`` (n_pairs, nq): a pair's distance changes by at most ``w @ |dq|`` [m] when the
    joints move by ``dq`` [rad]. Only the joints between the two bodies move one relative to
    the other; joint ``j`` moves a point ``p`` of a body below it by ``|dq_j| |p - o_j|``, and
    ``|p - o_j|`` is at most the joint offsets from ``j`` down to the body plus the body's
    radius around its joint (at least 1 m per unit of ``dq``: a prismatic joint's rate).
    ``static``: the index of the floor, which does not move."""
    assert model.nq == model.nv == model.njoints - 1  # one coordinate per joint
    offset = [float(np.linalg.norm(p.translation)) for p in model.jointPlacements]

    def chain(k: int) -> list[int]:  # k and its moving ancestors
        out = []
        while k > 0:
            out.append(k)
            k = model.parents[k]
        return out

    w = np.zeros((len(pairs), model.nq))
    for n, pair in enumerate(pairs):
        joints = {
            g: chain(geom.geometryObjects[g].parentJoint) if g != static else [] for g in pair
        }
        for g, other in (pair, pair[::-1]):
            if g == static:
                continue
            reach, below = _radius(geom.geometryObjects[g]), 0.0
            for j in joints[g]:  # from the body's joint up to the base
                if j not in joints[other]:
                    w[n, j - 1] += max(below + reach, 1.0)
                below += offset[j]
    return w


def _clearances(model, geom, hull, q, pairs, index, mesh, vertices, margin, n_robot):  # noqa: ANN001, ANN202, PLR0913
    """Smallest pair distance and lowest mesh vertex above the floor over every sample of ``q``.

    Conservative advancement: a pair measured ``d`` at one sample keeps
    ``d - w @ |q' - q| >= margin`` at a later ``q'`` (``w``: :func:`_distance_rates`), so
    those samples need no new distance. The others get the hull distance (a lower bound), and
    the mesh distance where the hulls are within the margin + 5 cm, as a sample-by-sample loop
    would: the same worst values wherever a pair comes near the margin.
    """
    rates = _distance_rates(model, hull, pairs, n_robot)
    data, gdata, hdata = model.createData(), pin.GeometryData(geom), pin.GeometryData(hull)
    last = np.zeros((len(pairs), q.shape[1]))
    slack = np.full(len(pairs), -np.inf)  # distance - margin at the last measurement
    smallest, lowest = np.inf, np.inf
    for qi in q:
        due = np.flatnonzero(np.einsum("ij,ij->i", rates, np.abs(qi - last)) >= slack)
        if due.size == 0:
            continue
        pin.updateGeometryPlacements(model, data, hull, hdata, qi)
        pin.updateGeometryPlacements(model, data, geom, gdata, qi)
        for j in due:
            k = int(index[j])
            d = pin.computeDistance(hull, hdata, k).min_distance  # the hull: a lower bound
            if mesh[j] and d < margin + 0.05:
                gdata.distanceRequests[k].cached_gjk_guess = np.array([1.0, 0.0, 0.0])
                d = pin.computeDistance(geom, gdata, k).min_distance
                a, b = pairs[j]
                if b == n_robot and a in vertices:
                    placed = vertices[a] @ gdata.oMg[a].rotation.T + gdata.oMg[a].translation
                    lowest = min(lowest, float(placed[:, 2].min()))
            smallest = min(smallest, d)
            last[j], slack[j] = qi, d - margin
    return smallest, lowest


def _check(config: Path, run: Path) -> dict[str, float]:
    """Worst values of the independent check; asserts every limit and clearance."""
    setup = prepare_run(load_run_config(config))
    robot = setup.robot
    margin = (setup.config.safety or SafetyConfig()).clearance_m
    traj = read_trajectory_csv(run / "trajectory.csv")
    assert list(traj.joint_names) == list(robot.joint_names)
    assert np.all(np.diff(traj.t) <= 1e-3 + 1e-12), "coarser than 1 kHz"
    np.testing.assert_allclose(traj.dq[[0, -1]], 0.0, atol=1e-9)  # starts and ends at rest

    # limits: the selected robot's (URDF + config), and the URDF's effort with rnea
    assert np.all(traj.q >= robot.q_lower - 1e-9)
    assert np.all(traj.q <= robot.q_upper + 1e-9)
    assert np.all(np.abs(traj.dq) <= robot.dq_max + 1e-9)
    assert np.all(np.abs(traj.ddq) <= robot.ddq_max + 1e-9)
    nominal = robot.model
    data = nominal.createData()
    tau = np.array(
        [
            pin.rnea(nominal, data, q, dq, a)
            for q, dq, a in zip(traj.q, traj.dq, traj.ddq, strict=True)
        ]
    )
    effort = np.asarray(nominal.effortLimit, dtype=float)
    limited = np.isfinite(effort) & (effort > 0)
    torque_ratio = float((np.abs(tau[:, limited]) / effort[limited]).max(initial=0.0))
    assert torque_ratio <= 1.0 + 1e-9, torque_ratio

    # clearances at every sample
    text = (run / "robot.urdf").read_text()
    locked = dict(getattr(robot, "locked_joints", {}) or {})
    model, geom = _geometry(
        text, list(robot.joint_names), locked, [str(d) for d in robot.package_dirs]
    )
    n_links = len(geom.geometryObjects)
    box = setup.config.safety.payload_box if setup.config.safety is not None else None
    if box is not None:  # the payload's box, placed here from the config and plain Pinocchio
        _add_box(model, geom, box)
    n_robot = len(geom.geometryObjects)
    vertices = _mesh_vertices(geom)
    floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    geom.addGeometryObject(pin.GeometryObject("floor", 0, 0, pin.SE3.Identity(), floor))
    parents = list(model.parents)
    joint = [int(o.parentJoint) for o in geom.geometryObjects]
    candidates = [
        (a, b)
        for a, b in itertools.combinations(range(n_links), 2)
        if joint[a] != joint[b] and parents[joint[a]] != joint[b] and parents[joint[b]] != joint[a]
    ]
    # the box against every link not rigidly attached to it, adjacent ones included
    candidates += [
        (a, n_links) for a in range(n_links) if n_robot > n_links and joint[a] != joint[n_links]
    ]
    candidates += [(a, n_robot) for a in range(n_robot)]
    for a, b in candidates:
        geom.addCollisionPair(pin.CollisionPair(a, b))
    hull = _hulls(geom)
    data, gdata = model.createData(), pin.GeometryData(geom)
    link = [model.frames[o.parentFrame].name for o in geom.geometryObjects[:n_robot]]
    # robot pairs in contact in the reference posture: left out, by link pair
    reference = np.clip(np.zeros(model.nq), model.lowerPositionLimit, model.upperPositionLimit)
    pin.computeCollisions(model, data, geom, gdata, reference, False)
    touching = {
        frozenset((link[a], link[b]))
        for (a, b), r in zip(candidates, gdata.collisionResults, strict=True)
        if b < n_robot and r.isCollision()
    }
    # floor pairs: left out where the distance never changes and is below the margin
    floor_d = []
    for q in traj.q[:: max(1, len(traj.q) // 200)]:
        pin.computeDistances(model, data, geom, gdata, q)
        floor_d.append([r.min_distance for r in gdata.distanceResults])
    floor_d = np.array(floor_d)
    keep = np.array(
        [
            b == n_links or frozenset((link[a], link[b])) not in touching
            if b < n_robot
            else not (np.ptp(floor_d[:, k]) < 1e-9 and floor_d[0, k] < margin)
            for k, (a, b) in enumerate(candidates)
        ]
    )
    assert keep.sum() >= n_robot // 2, "most pairs must be checked"
    kept = np.flatnonzero(keep)
    pairs = [candidates[k] for k in kept]
    mesh = np.array([a in vertices or b in vertices for a, b in pairs])
    smallest, lowest = _clearances(
        model, geom, hull, traj.q, pairs, kept, mesh, vertices, margin, n_robot
    )
    assert smallest >= margin - 1e-6, (smallest, margin)
    assert lowest >= margin - 1e-6, (lowest, margin)
    names = [
        f"{geom.geometryObjects[a].name}|{geom.geometryObjects[b].name}" for a, b in candidates
    ]
    excluded = [n for n, k in zip(names, keep, strict=True) if not k]
    if box is not None:  # the box is checked against the floor and the arm, never left out
        checked = [n for n, k in zip(names, keep, strict=True) if k and "payload" in n]
        assert "payload|floor" in checked, checked
        assert len(checked) >= 3, checked
    return {
        "clearance": smallest,
        "mesh_floor": lowest,
        "torque_ratio": torque_ratio,
        "excluded": excluded,
    }


@pytest.mark.slow
@pytest.mark.parametrize("name", CONFIGS)
def test_shipped_run_trajectory_is_safe_by_an_independent_check(name, shipped_run) -> None:
    run = shipped_run(name)
    _check(REPO / "configs" / f"{name}.yaml", run)
    # the same run (built once: CI time) reads as its numbers say
    verdict = json.loads((run / "result.json").read_text(encoding="utf-8"))["verdict"]
    label, reason = VERDICTS[name]
    assert verdict["label"] == label, (reason, verdict)
    assert verdict["rule"] == "truth"  # simulated: judged against the simulator's truth
    if name == "ur5-payload":  # the label is about the design, not the payload: it says so
        assert "ident payload" in verdict["reason"], verdict
    limit = {"good": (5.0, 0.10), "usable": (20.0, 0.25)}.get(label)
    if limit:  # the numbers behind the label, within its thresholds (docs/verdict.md)
        assert verdict["worst_error_percent"] < limit[0], verdict
        assert verdict["residual"] < limit[1], verdict
    else:  # not identified: a major parameter off by more than 20 % or the residual above 25 %
        assert verdict["worst_error_percent"] >= 20.0 or verdict["residual"] >= 0.25, verdict


def test_distance_rates_bound_every_pairs_change_of_distance() -> None:
    """The skipped samples of :func:`_clearances` are safe only if ``w @ |dq|`` bounds the
    change of every pair's distance: measured on the UR5's hulls and the floor at random
    postures and steps (a bound that missed a joint or a lever arm would be exceeded)."""
    setup = prepare_run(load_run_config(REPO / "configs" / "ur5.yaml"))
    robot = setup.robot
    text = (REPO / "robot" / "urdf" / "ur5.urdf").read_text()
    model, geom = _geometry(text, list(robot.joint_names), {}, [str(d) for d in robot.package_dirs])
    n = len(geom.geometryObjects)
    floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    geom.addGeometryObject(pin.GeometryObject("floor", 0, 0, pin.SE3.Identity(), floor))
    pairs = list(itertools.combinations(range(n + 1), 2))
    for a, b in pairs:
        geom.addCollisionPair(pin.CollisionPair(a, b))
    hull = _hulls(geom)
    rates = _distance_rates(model, hull, pairs, n)
    data, hdata = model.createData(), pin.GeometryData(hull)
    rng = np.random.default_rng(0)
    ratios = []
    for _ in range(150):
        q = rng.uniform(-3.0, 3.0, model.nq)
        dq = rng.normal(0.0, 0.05, model.nq) * (rng.random(model.nq) < 0.5)
        d = []
        for posture in (q, q + dq):
            pin.computeDistances(model, data, hull, hdata, posture)
            d.append(np.array([r.min_distance for r in hdata.distanceResults]))
        change = np.abs(d[1] - d[0])
        apart = (d[0] > 0) & (d[1] > 0) & (change > 1e-5)  # GJK's own noise is ~1e-7
        ratios.extend(change[apart] / (rates[apart] @ np.abs(dq)))
    assert len(ratios) > 500
    assert max(ratios) <= 1.0, max(ratios)
    assert max(ratios) > 0.3  # a bound, not a wild over-estimate (the skipping would not pay)
