"""The exact collision certificate (ident.excitation.check + safety) against an independent
loop: plain Pinocchio + coal on the URDF's collision meshes as loaded (BVH, no hull), its own
pair rule (non-adjacent link pairs not in contact at the reference posture; every moving
geometry against the floor), written here without ident's geometry code; and the bound that
covers the motion between samples, against coal distances at nearby postures."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from ident.excitation import JointFourierFamily
from ident.excitation.check import check_trajectory, dense_family_states
from ident.excitation.executable import executable_trajectory
from ident.excitation.safety import build_safety_model
from ident.model import Robot
from ident.run.setup import load_run

REPO = Path(__file__).resolve().parents[1]
UR5_SEED0 = REPO / "tests" / "data" / "ur5_seed0_unsafe_design.json"


def _independent_minima(urdf_text, package_dirs, locked, q, margin):
    """Smallest coal distance per link pair over the postures ``q`` (n, nq), on the meshes as
    loaded; link pairs: not adjacent, not in contact at 0 clipped into the limits; every
    geometry against the floor half-space z >= 0, except those at a constant distance below
    ``margin`` (the base standing on it: judged once, not along the trajectory)."""
    import coal

    full = pin.buildModelFromXML(urdf_text)
    geom = pin.buildGeomFromUrdfString(
        full, urdf_text, pin.GeometryType.COLLISION, None, [str(d) for d in package_dirs]
    )
    if locked:
        ref = pin.neutral(full)
        for name, value in locked.items():
            ref[full.joints[full.getJointId(name)].idx_q] = value
        ids = [full.getJointId(n) for n in locked]
        model, geom = pin.buildReducedModel(full, geom, ids, ref)
    else:
        model = full
    n = len(geom.geometryObjects)
    link = [model.frames[o.parentFrame].name for o in geom.geometryObjects]
    joint = [int(o.parentJoint) for o in geom.geometryObjects]
    parents = list(model.parents)
    floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    geom.addGeometryObject(pin.GeometryObject("floor", 0, 0, pin.SE3.Identity(), floor))
    pairs = []
    for a in range(n):
        for b in range(a + 1, n):
            ja, jb = joint[a], joint[b]
            if link[a] == link[b] or ja == jb or parents[ja] == jb or parents[jb] == ja:
                continue
            pairs.append((a, b))
        pairs.append((a, n))
    for a, b in pairs:
        geom.addCollisionPair(pin.CollisionPair(a, b))
    data, gdata = model.createData(), pin.GeometryData(geom)
    reference = np.clip(np.zeros(model.nq), model.lowerPositionLimit, model.upperPositionLimit)
    pin.computeCollisions(model, data, geom, gdata, reference, False)
    touching = {
        tuple(sorted((link[a], link[b])))
        for (a, b), r in zip(pairs, gdata.collisionResults, strict=True)
        if b < n and r.isCollision()
    }
    d = np.empty((q.shape[0], len(pairs)))
    for k, qk in enumerate(q):
        for request in gdata.distanceRequests:
            request.cached_gjk_guess = np.array([1.0, 0.0, 0.0])
        pin.computeDistances(model, data, geom, gdata, qk)
        d[k] = [r.min_distance for r in gdata.distanceResults]
    minima: dict[str, float] = {}
    for p, (a, b) in enumerate(pairs):
        if b == n:
            if np.ptp(d[:, p]) < 1e-9 and d[0, p] < margin:  # base, or link 1 turning on it
                continue
            name = f"{link[a]}|floor"
        elif tuple(sorted((link[a], link[b]))) in touching:
            continue
        else:
            name = f"{link[a]}|{link[b]}"
        minima[name] = min(minima.get(name, np.inf), float(d[:, p].min()))
    return minima


def _agree(report, safety, minima):
    checks = {c.name.removeprefix("clearance:"): c for c in report.checks if c.kind == "clearance"}
    assert set(checks) == set(minima)
    for name, value in minima.items():
        got = checks[name].value
        if value <= 0.0:  # meshes touch: coal gives 0, the certificate a depth (<= 0)
            assert got <= 0.0, name
        else:
            assert got == pytest.approx(value, abs=1e-6), name
    independent_ok = min(minima.values()) >= safety.clearance_m
    certified_ok = all(c.ok for c in checks.values())
    assert certified_ok <= independent_ok  # the certificate is never less strict
    return independent_ok, certified_ok


@pytest.fixture(scope="module")
def ur5_setup():
    return load_run(REPO / "configs" / "ur5.yaml")


def _ur5_seed0(setup):
    x = np.asarray(json.loads(UR5_SEED0.read_text())["x"])
    family = setup.family
    start = family.trajectories(x[None, :]).q[0, 0]
    return executable_trajectory(family, x, start, rate_hz=1000.0, n_periods=1)


def test_ur5_seed0_trajectory_is_refused_where_the_forearm_hits_wrist_2(ur5_setup) -> None:
    """The executable trajectory the old rule let through (forearm|wrist-2 dropped because
    their hulls overlap): the certificate names the pair and the time, and the independent
    loop over the meshes agrees on the window around it."""
    traj = _ur5_seed0(ur5_setup)
    window = (traj.t >= 3.7) & (traj.t <= 4.4)
    t, q, dq, ddq = (a[window] for a in (traj.t, traj.q, traj.dq, traj.ddq))
    report = check_trajectory(ur5_setup.robot, ur5_setup.safety, t, q, dq, ddq)
    assert not report.usable
    worst = report.failures()[0]
    assert worst.name == "clearance:forearm_link|wrist_2_link"
    assert worst.value < 0.0
    assert 3.821 <= worst.time <= 4.305
    k = report.pair_names.index("forearm_link|wrist_2_link")
    touching = report.t[report.clearance[:, k] <= 0.0]
    assert touching.min() == pytest.approx(3.821, abs=1e-9)
    assert touching.max() == pytest.approx(4.305, abs=1e-9)
    robot = ur5_setup.robot
    minima = _independent_minima(robot.urdf_text, robot.package_dirs, {}, q[::5], 0.01)
    assert minima["forearm_link|wrist_2_link"] <= 0.0


@pytest.mark.parametrize("name", ["ur5", "panda", "paper"])
def test_certificate_agrees_with_an_independent_mesh_loop(name, ur5_setup) -> None:
    if name == "ur5":
        setup = ur5_setup
        traj = _ur5_seed0(setup)
        keep = slice(0, 3700, 20)  # the approach and the first seconds: clear
        t, q, dq, ddq = (a[keep] for a in (traj.t, traj.q, traj.dq, traj.ddq))
        robot, safety, locked = setup.robot, setup.safety, {}
        rate = 50.0
    elif name == "panda":
        setup = load_run(REPO / "configs" / "panda.yaml")
        robot, safety = setup.robot, setup.safety
        locked = {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.02}
        family = setup.family
        x = np.random.default_rng(4).uniform(family.bounds[:, 0], family.bounds[:, 1])
        t, q, dq, ddq = dense_family_states(family, x, 1000.0)
        t, q, dq, ddq = t[::50], q[::50], dq[::50], ddq[::50]
        rate = 20.0
    else:
        robot = Robot.from_config("configs/paper6r.yaml")
        safety = build_safety_model(robot)
        locked = {}
        family = JointFourierFamily(
            robot, [3, 4, 5], n_harmonics=3, base_frequency=2 * np.pi / 4, n_samples=200,
            held_positions=(0.0, -0.8, -0.5, 0.0, 0.0, 0.0), amplitude_bound=0.3,
        )  # fmt: skip
        x = np.random.default_rng(1).uniform(family.bounds[:, 0], family.bounds[:, 1])
        x[0::5] = 0.0
        batch = family.trajectories(x[None])
        t, q, dq, ddq = batch.t, batch.q[0], batch.dq[0], batch.ddq[0]
        rate = 50.0
    # the check at the samples as given (no resampling): the same postures on both sides
    report = check_trajectory(robot, safety, t * rate / 1000.0, q, dq, ddq)
    assert report.resampling == "none"
    minima = _independent_minima(robot.urdf_text, robot.package_dirs, locked, q, safety.clearance_m)
    independent_ok, certified_ok = _agree(report, safety, minima)
    if name == "paper":
        assert independent_ok
        assert certified_ok
    # the run's estimate: every mesh pair's exact distance at one posture (timed), which holds
    # the near pairs' share the dense check's own CPU per posture counts; none without meshes
    extra = safety.seconds_per_posture - safety.hull_seconds_per_posture
    if name == "paper":
        assert safety.mesh_seconds_per_posture == 0.0
    else:
        assert safety.mesh_seconds_per_posture > 0.0
        assert safety.mesh_seconds_per_posture >= extra - 1e-12


def test_motion_bound_covers_the_distance_change_between_nearby_postures(ur5_setup) -> None:
    """|d(q + dq) - d(q)| <= motion_coefficients @ |dq| for every pair (coal on the meshes):
    the bound the certificate subtracts between samples."""
    safety = ur5_setup.safety
    rng = np.random.default_rng(11)
    lower, upper = safety.limits.finite_position_box()
    q = rng.uniform(lower, upper, (30, 6))
    step = rng.normal(0.0, 0.02, (30, 6))
    d0 = safety.clearances(q)
    d1 = safety.clearances(q + step)
    bound = np.abs(step) @ np.asarray(safety.motion_coefficients).T
    positive = (d0 > 0.0) & (d1 > 0.0)  # contact depths are hull depths, not distances
    assert positive.sum() > 500
    assert np.all(np.abs(d1 - d0)[positive] <= bound[positive] + 1e-9)
    # and it is not vacuous: within a factor 30 of the largest change seen
    assert np.max(np.abs(d1 - d0)[positive] / bound[positive]) > 1.0 / 30.0


def test_a_thin_plate_crossed_between_two_samples_is_caught() -> None:
    """The flange sweeps 30 cm in one 1 ms step across a 2 mm plate: both samples keep the
    margin, the motion between them does not."""
    robot = Robot.from_config("configs/paper6r.yaml")
    arm_up = np.array([0.0, -0.8, -0.5, 0.0, 0.0, 0.0])
    flange = robot.frame_positions(arm_up[None, :], "flange")[0]
    plate = {
        "name": "plate",
        "box": {"size": [0.002, 0.05, 0.05], "position": list(flange), "rpy": [0, 0, np.pi / 2]},
    }
    safety = build_safety_model(robot, {"floor": {"enabled": False}, "obstacles": [plate]})
    q = np.vstack([arm_up, arm_up])
    q[0, 0], q[1, 0] = -0.15, 0.15
    dq = np.zeros_like(q)
    dq[:, 0] = 300.0
    report = check_trajectory(robot, safety, [0.0, 1e-3], q, dq, np.zeros_like(q))
    plate_checks = [c for c in report.checks if c.name.endswith("|plate")]
    assert min(c.value for c in plate_checks) >= safety.clearance_m  # the samples are clear
    assert any(not c.ok for c in plate_checks)  # the certificate is not
    assert min(c.between for c in plate_checks) < 0.0


def test_advancement_skips_only_what_keeps_the_limit_and_keeps_each_minimum_exact(
    ur5_setup,
) -> None:
    """Conservative advancement (``clearances`` with ``travel``) against the exact distance at
    every sample, on 0.25 s of the UR5 trajectory that comes into contact: no value above the
    exact one, every value below the limit exact, each pair's smallest value exact, and the
    same check verdict as without advancement."""
    from ident.excitation.check import step_displacements

    safety = ur5_setup.safety
    traj = _ur5_seed0(ur5_setup)
    window = (traj.t >= 3.75) & (traj.t < 4.0)
    t, q, dq, ddq = (a[window] for a in (traj.t, traj.q, traj.dq, traj.ddq))
    step = step_displacements(safety, t, dq, ddq)
    travel = np.vstack([np.zeros((1, safety.n_pairs)), np.cumsum(step, axis=0)])
    within = np.full((t.size, safety.n_pairs), safety.clearance_m + 0.02)
    advanced = safety.clearances(q, within=within, travel=travel)
    exact = safety.clearances(q)
    assert np.all(advanced <= exact + 1e-6)  # GJK's tolerance: the bound is from another sample
    below = exact < within
    assert below.any()
    assert (~below).any()
    np.testing.assert_array_equal(advanced[below], exact[below])
    np.testing.assert_array_equal(advanced.min(axis=0), exact.min(axis=0))
    # the bound is used: some values above the limit are bounds, not the exact distance
    assert np.any(advanced[~below] < exact[~below])


def test_hull_distances_of_each_posture_are_that_postures_own() -> None:
    """``_distances`` reads coal's results through proxies made once: every row must still be
    its own posture's distances (stale proxies would repeat one row), pair by pair as
    ``pin.computeDistance`` gives them on fresh geometry data."""
    from ident.excitation.safety.distances import _distances

    robot = Robot.from_config("configs/paper6r.yaml")
    checked = build_safety_model(robot)._checked
    rng = np.random.default_rng(3)
    q = rng.uniform(-1.5, 1.5, (4, checked.model.nq))
    got = _distances(checked.model, checked.hulls, q)
    data, gdata = checked.model.createData(), pin.GeometryData(checked.hulls)
    expected = np.empty_like(got)
    for s in range(q.shape[0]):
        pin.updateGeometryPlacements(checked.model, data, checked.hulls, gdata, q[s])
        for p in range(got.shape[1]):
            expected[s, p] = pin.computeDistance(checked.hulls, gdata, p).min_distance
    assert np.ptp(got, axis=0).max() > 1e-3  # the postures differ
    np.testing.assert_allclose(got, expected, atol=1e-5)  # GJK tolerance
