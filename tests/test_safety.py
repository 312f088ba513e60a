"""Collision / environment model, cheap constraint term and dense check (ident.excitation.safety,
ident.excitation.check), against independent Pinocchio + coal computations and closed forms."""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
import pytest
from pydantic import ValidationError
from robots import ERD_SHARE, UR5_URDF

from ident.excitation import ExcitationObjective, JointFourierFamily, PaperArmFamily
from ident.excitation.check import check_trajectory, dense_family_states
from ident.excitation.safety import (
    SafetyConfig,
    build_safety_model,
    collision_violations,
    torque_violations,
)
from ident.excitation.safety.fast import EXACT_WITHIN_M
from ident.model import Robot

# a wrist-stage motion with the arm raised (upper arm 0.8 rad up, forearm forward): safe
ARM_UP = (0.0, -0.8, -0.5, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def paper():
    return Robot.from_config("configs/paper6r.yaml")


@pytest.fixture(scope="module")
def safety(paper):
    return build_safety_model(paper)


def _wrist_family(paper, n_samples=200):
    return JointFourierFamily(
        paper,
        [3, 4, 5],
        n_harmonics=3,
        base_frequency=2 * np.pi / 4,
        n_samples=n_samples,
        held_positions=ARM_UP,
        amplitude_bound=0.3,
    )


def _safe_design(family):
    x = np.random.default_rng(1).uniform(family.bounds[:, 0], family.bounds[:, 1])
    x[0::5] = 0.0  # q0 of each joint: the middle of its range
    return x


def test_config_schema_rejects_ambiguous_obstacles():
    cfg = SafetyConfig.model_validate(
        {
            "obstacles": [
                {"name": "table", "box": {"size": [1, 0.6, 0.05], "position": [0.8, 0, 0.3]}},
                {"sphere": {"radius": 0.1, "position": [0.5, 0.5, 0.8]}},
                {"plane": {"normal": [-1, 0, 0], "offset": -1.2}},
            ]
        }
    )
    assert [o.kind for o in cfg.obstacles] == ["box", "sphere", "plane"]
    assert cfg.floor.enabled
    assert cfg.clearance_m == 0.03
    assert cfg.check_rate_hz == 1000
    with pytest.raises(ValidationError, match="exactly one"):
        SafetyConfig.model_validate(
            {"obstacles": [{"box": {"size": [1, 1, 1]}, "sphere": {"radius": 1}}]}
        )
    with pytest.raises(ValidationError, match="check_rate_hz"):
        SafetyConfig(check_rate_hz=500)
    with pytest.raises(ValidationError, match="extra"):
        SafetyConfig.model_validate({"clearance": 0.1})


def test_pair_rule_on_the_paper_robot(safety):
    excluded = {e.pair: e.reason for e in safety.excluded_pairs}
    # adjacent links are never checked
    assert excluded["base_link|link_1"] == "adjacent"
    assert "base_link|link_1" not in safety.pair_names
    # the elbow's and the wrist's housings touch in the reference posture (0 clipped)
    assert excluded["link_2|link_4"].startswith("reference contact")
    assert set(excluded.values()) <= {"adjacent"} | {excluded["link_2|link_4"]}
    # the environment is never excluded: the base stands on the floor and link 1's housing
    # turns about the vertical in it, at a constant distance, judged once
    constant = {e.pair: e.reason for e in safety.constant_pairs}
    assert set(constant) == {"base_link_0|floor", "link_1_0|floor", "link_1_1|floor"}
    assert "-0.0938 m" in constant["link_1_0|floor"]
    assert not any(pair.endswith("|floor") for pair in excluded)
    # what the problem report needs: the wrist against the pedestal and the floor
    for pair in ("base_link|link_5", "link_1|link_5", "link_5|floor", "flange|floor"):
        assert pair in safety.pair_names
    assert set(safety.pair_kinds) == {"self", "floor"}


def test_floor_clearance_matches_the_cylinders_lowest_point(paper, safety):
    """Closed form: a cylinder (axis u, half length h, radius r, centre c) reaches down to
    c_z - h |u_z| - r sqrt(1 - u_z^2)."""
    rng = np.random.default_rng(3)
    q = rng.uniform(paper.q_lower, paper.q_upper, (20, 6))
    got = safety.clearances(q)
    model, geom = safety.model, safety.geometry_model
    data, gdata = model.createData(), pin.GeometryData(geom)
    for k in range(q.shape[0]):
        pin.updateGeometryPlacements(model, data, geom, gdata, q[k])
        lowest: dict[str, float] = {}
        for i, obj in enumerate(geom.geometryObjects):
            if not isinstance(obj.geometry, coal.Cylinder):
                continue
            pose = gdata.oMg[i]
            uz = pose.rotation[2, 2]
            z = pose.translation[2] - obj.geometry.halfLength * abs(uz)
            z -= obj.geometry.radius * np.sqrt(max(1.0 - uz * uz, 0.0))
            link = model.frames[obj.parentFrame].name
            name = f"{link}|floor"
            lowest[name] = min(lowest.get(name, np.inf), z)
        for j, name in enumerate(safety.pair_names):
            if name.endswith("|floor") and name != "link_1|floor":  # link_1: one part excluded
                assert got[k, j] == pytest.approx(lowest[name], abs=1e-6)


def test_obstacles_sphere_box_plane(paper):
    cfg = SafetyConfig(
        floor={"enabled": False},
        self_collision=False,
        obstacles=[
            {"name": "ball", "sphere": {"radius": 0.1, "position": [2.0, 0.0, 0.0]}},
            {"name": "wall", "plane": {"normal": [-2.0, 0.0, 0.0], "offset": -4.0}},
            {"name": "block", "box": {"size": [0.2, 0.2, 0.2], "position": [0.0, 0.0, 3.0]}},
        ],
    )
    s = build_safety_model(paper, cfg)
    flange = paper.frame_positions(np.zeros((1, 6)), "flange")[0]
    c = s.clearances(np.zeros((1, 6)))[0]
    col = {n: c[i] for i, n in enumerate(s.pair_names)}
    # the flange disc (radius 0.8 r6) reaches at most its radius past its centre
    assert col["flange|ball"] <= np.linalg.norm(flange - [2.0, 0.0, 0.0]) - 0.1 + 1e-9
    assert col["flange|wall"] <= 2.0 - flange[0] + 1e-9  # wall x >= 2
    assert col["base_link|block"] == pytest.approx(3.0 - 0.1 - 0.12012, abs=1e-5)
    assert set(s.pair_kinds) == {"obstacle"}


def test_paper_arm_trajectory_through_the_pedestal_is_detected(paper, safety):
    """The arm stage keeps the wrist centre near z = 0, 10 cm from the base axis (e0 at its
    lower bound of the shipped box): the dense check names the pedestal pair and the time."""
    family = PaperArmFamily(paper, n_samples=500)
    x = family.bounds.mean(axis=1)
    x[family.variable_names.index("e0")] = 100.0
    batch = family.trajectories(x[None])
    assert batch.violations.feasible()[0]  # the paper's constraints alone accept it
    wc = batch.traced_points[0]
    assert np.max(np.abs(wc[:, 2])) < 0.02
    assert np.max(np.hypot(wc[:, 0], wc[:, 1])) < 0.12
    report = check_trajectory(paper, safety, *dense_family_states(family, x, 1000.0))
    assert not report.usable
    assert report.resampling == "none"
    assert report.t[1] - report.t[0] <= 1e-3
    pedestal = [c for c in report.failures() if c.name.startswith("clearance:base_link|")]
    assert pedestal, report.summary()
    worst = min(pedestal, key=lambda c: c.value)
    assert worst.value < 0.0
    assert worst.excess > safety.clearance_m
    assert 0.0 <= worst.time < family.period
    i = int(np.argmin(np.abs(report.t - worst.time)))
    assert report.clearance[i, report.pair_names.index(worst.name[len("clearance:") :])] == (
        pytest.approx(worst.value)
    )
    assert "base_link|" in report.summary() or "unsafe" in report.summary()
    # the cheap term of the optimization sees it too: the objective calls it infeasible
    objective = ExcitationObjective(paper, None, family, safety=safety, n_reference_samples=200)
    assert objective.violation(x[None])[0] > 0.0
    detail = objective.details(x[None])[0]
    assert not detail.feasible
    assert any(k.startswith("clearance:") for k in detail.violations)


def test_safe_trajectory_confirmed_by_plain_pinocchio_and_coal(paper, safety):
    family = _wrist_family(paper)
    x = _safe_design(family)
    t, q, dq, ddq = dense_family_states(family, x, 1000.0)
    report = check_trajectory(paper, safety, t, q, dq, ddq)
    assert report.usable, report.summary()
    # independent: the URDF's collision geometry, the floor half-space, coal distances at 1 kHz
    model = pin.buildModelFromXML(paper.urdf_text)
    geom = pin.buildGeomFromUrdfString(model, paper.urdf_text, pin.GeometryType.COLLISION)
    floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    geom.addGeometryObject(pin.GeometryObject("floor", 0, 0, pin.SE3.Identity(), floor))
    constant = {e.pair for e in safety.constant_pairs}
    names = [o.name for o in geom.geometryObjects]
    link = [model.frames[o.parentFrame].name if o.name != "floor" else "floor"
            for o in geom.geometryObjects]  # fmt: skip
    for a in range(len(names)):
        for b in range(a + 1, len(names)):
            if f"{link[a]}|{link[b]}" in safety.pair_names and (
                f"{names[a]}|{names[b]}" not in constant
            ):
                geom.addCollisionPair(pin.CollisionPair(a, b))
    assert len(geom.collisionPairs) >= 40
    data, gdata = model.createData(), pin.GeometryData(geom)
    assert t[1] - t[0] <= 1e-3
    smallest = np.inf
    for k in range(t.shape[0]):
        # every GJK from coal's default direction, not from the one Pinocchio cached for the
        # pair at the previous posture (that moves a distance by up to GJK's 1e-6 tolerance)
        for request in gdata.distanceRequests:
            request.cached_gjk_guess = np.array([1.0, 0.0, 0.0])
        pin.computeDistances(model, data, geom, gdata, q[k])
        smallest = min(smallest, min(r.min_distance for r in gdata.distanceResults))
    assert smallest >= safety.clearance_m
    assert smallest == pytest.approx(report.min_clearance.value, abs=1e-9)


def test_margin_decides(paper):
    family = _wrist_family(paper)
    x = _safe_design(family)
    states = dense_family_states(family, x, 1000.0)
    relaxed = check_trajectory(paper, build_safety_model(paper), *states)
    worst = relaxed.min_clearance.value
    strict = build_safety_model(paper, SafetyConfig(clearance_m=worst + 0.01))
    report = check_trajectory(paper, strict, *states)
    assert not report.usable
    fail = report.failures()[0]
    assert fail.value == pytest.approx(worst, abs=1e-12)
    # measured from the certified bound between samples: at most one step's motion lower
    assert 0.01 - 1e-12 <= fail.excess <= 0.01 + 2e-3


def test_coarse_input_is_resampled_by_cubic_hermite(paper, safety):
    family = _wrist_family(paper, n_samples=200)  # 50 Hz
    x = _safe_design(family)
    batch = family.trajectories(x[None])
    report = check_trajectory(paper, safety, batch.t, batch.q[0], batch.dq[0], batch.ddq[0])
    assert report.resampling == "cubic_hermite"
    assert np.max(np.diff(report.t)) <= 1e-3 + 1e-12
    # the interpolated velocity ratios agree with the closed form at the same times
    dense = family.with_samples(4000).trajectories(x[None])
    keep = report.t <= dense.t[-1]
    exact = np.abs(np.interp(report.t[keep], dense.t, dense.dq[0][:, 4])) / paper.dq_max[4]
    assert np.max(np.abs(report.velocity_ratio[keep, 4] - exact)) < 1e-3


def test_velocity_and_position_violations_are_reported(paper, safety):
    family = _wrist_family(paper)
    x = _safe_design(family)
    t, q, dq, ddq = dense_family_states(family, x, 1000.0)
    fast = check_trajectory(paper, safety, t / 20.0, q, dq * 20.0, ddq * 400.0, rate_hz=20000)
    kinds = {c.kind for c in fast.failures()}
    assert {"velocity", "acceleration"} <= kinds
    assert not fast.usable
    v = fast.check("velocity:joint_5")
    assert v.ratio == pytest.approx(np.max(np.abs(dq[:, 4])) * 20.0 / paper.dq_max[4])
    q_bad = q.copy()
    q_bad[500, 3] = paper.q_upper[3] + 0.1
    bad = check_trajectory(paper, safety, t, q_bad, dq, ddq)
    p = bad.check("position:joint_4")
    assert not bad.usable
    assert p.excess == pytest.approx(0.1)
    assert p.time == pytest.approx(t[500])
    nan = q.copy()
    nan[3, 0] = np.nan
    assert not check_trajectory(paper, safety, t, nan, dq, ddq).usable


def test_torque_limits_with_the_nominal_model():
    ur5 = Robot.from_urdf(UR5_URDF)
    s = build_safety_model(ur5, {"clearance_m": 0.01}, package_dirs=[ERD_SHARE])
    assert np.allclose(s.effort_max, ur5.model.effortLimit)
    rng = np.random.default_rng(0)
    q = rng.uniform(-1, 1, (2, 8, 6))
    dq = rng.uniform(-1, 1, (2, 8, 6))
    ddq = rng.uniform(-200, 200, (2, 8, 6))
    data = ur5.model.createData()
    tau = np.array([[pin.rnea(ur5.model, data, q[p, k], dq[p, k], ddq[p, k]) for k in range(8)]
                    for p in range(2)])  # fmt: skip
    expected = np.maximum(np.abs(tau).max(axis=1) - s.effort_max, 0) / s.effort_max
    got = torque_violations(s, q, dq, ddq, n_check=8)
    assert got.names[0] == "torque:shoulder_pan_joint"
    np.testing.assert_allclose(got.values, expected, rtol=1e-12)
    assert got.values.max() > 0.0
    off = build_safety_model(
        ur5, SafetyConfig(torque_limits=False, clearance_m=0.01), package_dirs=[ERD_SHARE]
    )
    assert torque_violations(off, q, dq, ddq).values.shape == (2, 0)


def test_cheap_term_is_the_margin_excess_at_evenly_spread_samples(paper, safety):
    family = _wrist_family(paper)
    x = _safe_design(family)
    batch = family.trajectories(np.vstack([x, x]))
    v = collision_violations(safety, batch.q, n_check=10)
    assert v.values.shape == (2, safety.n_pairs)
    assert v.names[0].startswith("clearance:")
    idx = np.arange(0, 200, 20)  # 10 samples evenly spread over the 200
    d = safety.fast_clearances(batch.q[0, idx]).min(axis=0)
    expected = np.maximum(safety.clearance_m - d, 0.0) / safety.clearance_m
    np.testing.assert_allclose(v.values[0], expected, atol=1e-12)
    np.testing.assert_array_equal(v.values[0], v.values[1])
    # the same as with the exact distances at those samples
    exact = safety.clearances(batch.q[0, idx]).min(axis=0)
    np.testing.assert_allclose(
        v.values[0], np.maximum(safety.clearance_m - exact, 0.0) / 0.03, atol=1e-4
    )
    assert np.all(v.values == 0.0)  # a safe trajectory


def test_fast_clearances_are_exact_within_the_margin(paper):
    """The vectorized term: exact for the floor (cylinder's lowest point), for pairs coal
    handles (the box) up to EXACT_WITHIN_M (beyond, their bounding spheres' distance, at
    least that much) and wherever a pair is within the margin without touching; a lower
    bound elsewhere (in contact: the depth of the capsule around a cylinder, never less deep
    than the cylinder's)."""
    s = build_safety_model(
        paper,
        {
            "obstacles": [
                {"name": "ball", "sphere": {"radius": 0.2, "position": [0.8, 0, 0.5]}},
                {"name": "crate", "box": {"size": [0.3, 0.3, 0.3], "position": [0, 0.9, 0.4]}},
            ]
        },
    )
    q = np.random.default_rng(0).uniform(paper.q_lower, paper.q_upper, (200, 6))
    exact, fast = s.clearances(q), s.fast_clearances(q)
    gjk = 1e-6  # coal's GJK/EPA tolerance: computeDistance and computeDistances differ by it
    assert np.all(fast <= exact + gjk)
    near = ((exact < s.clearance_m) | (fast < s.clearance_m)) & (exact > gjk)
    assert near.sum() > 50
    np.testing.assert_allclose(fast[near], exact[near], atol=gjk)
    contact = exact <= gjk
    assert contact.sum() > 100
    assert np.all(fast[contact] <= 0.0)
    n_close = 0
    for k, name in enumerate(s.pair_names):
        if name.endswith(("|floor", "|crate")):  # exact up to EXACT_WITHIN_M, then a bound
            close = exact[:, k] < EXACT_WITHIN_M
            n_close += close.sum()
            np.testing.assert_allclose(fast[close, k], exact[close, k], atol=1e-9, err_msg=name)
            assert np.all(fast[~close, k] >= EXACT_WITHIN_M - 1e-9), name
    assert n_close > 100


def test_cheap_term_of_a_swarm_is_the_smallest_fast_clearance_and_never_misses_contact(
    paper, safety
):
    """The swarm's cheap term measures only the postures that can lower a trajectory's
    smallest clearance (closest bound first): the minimum is that of every posture measured,
    bit for bit, on whole-arm motions of which many touch (a pruning that skipped a closer
    posture, or stopped at the first exact distance, differs); and a trajectory the exact
    distances put within the margin is never given zero violation (a contact taken for a
    clearance would)."""
    family = JointFourierFamily(
        paper, [0, 1, 2, 3, 4, 5], n_harmonics=2, base_frequency=2 * np.pi / 4, n_samples=64
    )
    low, high = family.bounds.T
    x = np.random.default_rng(5).uniform(low, high, (24, low.size))
    q = family.trajectories(x).q[:, ::4]  # (24, 16, 6)
    every = safety.fast_clearances(q.reshape(-1, 6)).reshape(24, 16, -1).min(axis=1)
    np.testing.assert_array_equal(safety.fast_min_clearances(q), every)
    exact = safety.clearances(q.reshape(-1, 6)).reshape(24, 16, -1).min(axis=1)
    assert np.sum(exact <= 0.0) >= 5
    assert np.sum((exact > 0) & (exact < safety.clearance_m)) >= 1
    assert np.all(every <= exact + 1e-6)
    v = collision_violations(safety, family.trajectories(x).q, n_check=16).values
    within = exact < safety.clearance_m - 1e-6
    assert np.all(v[within] > 0.0)


def test_fast_clearances_of_a_posture_do_not_depend_on_the_others(paper):
    """A swarm's cheap term is a function of each particle alone: the same postures give the
    same distances, bit for bit, whatever was computed before them (coal's GJK would start
    from the last direction Pinocchio cached for the pair, and move the result by up to its
    1e-6 tolerance: enough for an optimizer on the margin to keep an infeasible point)."""
    s = build_safety_model(
        paper,
        {
            "obstacles": [
                {"name": "crate", "box": {"size": [0.3, 0.3, 0.3], "position": [0, 0.9, 0.4]}}
            ]
        },
    )
    q = np.random.default_rng(3).uniform(paper.q_lower, paper.q_upper, (120, 6))
    forward = s.fast_clearances(q)
    backward = s.fast_clearances(q[::-1])[::-1]
    alone = np.vstack([s.fast_clearances(q[k : k + 1]) for k in range(0, 120, 7)])
    near = forward < s.clearance_m
    assert near.sum() > 50  # coal decides many of these distances
    np.testing.assert_array_equal(forward, backward)
    np.testing.assert_array_equal(forward[::7], alone)


def test_segment_distance_closed_forms():
    from ident.excitation.safety.primitives import segment_distances

    p = np.array([[0.0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, 0]])
    q = np.array([[1.0, 0, 0], [1, 0, 0], [1, 0, 0], [0, 0, 0]])
    a = np.array([[0.5, 1, -1], [2, 0, 1], [0.5, 2, 0], [3, 4, 0]])
    b = np.array([[0.5, 1, 1], [3, 0, 1], [0.7, 2, 0], [3, 4, 0]])
    expected = [1.0, np.hypot(1, 1), 2.0, 5.0]  # crossing, end-end, parallel, two points
    np.testing.assert_allclose(segment_distances(p, q, a, b), expected, atol=1e-12)


def test_mesh_floor_clearance_is_the_lowest_vertex_of_the_mesh():
    """UR5 collision meshes (non-convex): the clearance of each link to the floor equals the
    lowest vertex of its mesh, computed by hand from Pinocchio's placements. A mesh merely
    relabelled as convex (coal's ``buildConvexRepresentation``) gives distances up to 0.44 m
    too large here, because the support function's hill climbing stops at local extrema."""
    from ident.model.selection import load_robot
    from ident.run.config import load_run_config

    robot = load_robot(load_run_config("configs/ur5.yaml").robot)
    s = build_safety_model(
        robot, {"self_collision": False, "clearance_m": 0.02}, package_dirs=robot.package_dirs
    )
    model = robot.model
    geom = pin.buildGeomFromUrdfString(
        model,
        robot.urdf_text,
        pin.GeometryType.COLLISION,
        None,
        [str(d) for d in robot.package_dirs],
    )
    meshes = {
        model.frames[o.parentFrame].name: np.asarray(o.geometry.vertices(), dtype=float)
        for o in geom.geometryObjects
        if isinstance(o.geometry, coal.BVHModelBase)
    }
    q = np.random.default_rng(3).uniform(robot.q_lower, robot.q_upper, (60, 6))
    measured = s.clearances(q)
    data, gdata = model.createData(), pin.GeometryData(geom)
    checked = 0
    for k, name in enumerate(s.pair_names):
        link, other = name.split("|")
        if other != "floor" or link not in meshes:
            continue
        obj = next(i for i, o in enumerate(geom.geometryObjects) if o.name.startswith(link))
        lowest = []
        for qi in q:
            pin.updateGeometryPlacements(model, data, geom, gdata, qi)
            M = gdata.oMg[obj]
            lowest.append((meshes[link] @ M.rotation.T + M.translation)[:, 2].min())
        np.testing.assert_allclose(measured[:, k], lowest, atol=1e-6, err_msg=name)
        checked += 1
    assert checked >= 5


def test_swarm_term_on_meshes_is_exact_up_to_its_margin_and_a_bound_beyond():
    """The optimizer's term on a mesh robot measures coal's hull pairs only where their
    bounding spheres are within its margin: below the margin its minima equal every posture's
    fast clearance bit for bit (and so does the violation it gives); beyond it they may be
    the spheres' bound, never below the margin. A term that skipped a pair within the margin,
    or kept a bound below it, differs."""
    ur5 = Robot.from_urdf(UR5_URDF)
    s = build_safety_model(ur5, {"clearance_m": 0.01}, package_dirs=[ERD_SHARE])
    q = ur5.random_configurations(40 * 6, rng=2)[0].reshape(40, 6, -1)
    every = s.fast_clearances(q.reshape(-1, q.shape[-1])).reshape(40, 6, -1).min(axis=1)
    fast = s.fast_min_clearances(q)
    margin = s.clearance_m
    assert np.sum(every < margin) >= 10  # random postures: many pairs inside the margin
    np.testing.assert_array_equal(np.minimum(fast, margin), np.minimum(every, margin))
    beyond = every >= margin
    assert np.all(fast[beyond] >= margin)
    assert np.any(fast[beyond] < every[beyond])  # bounds where no exact value was needed
    v = collision_violations(s, q, n_check=6)
    np.testing.assert_array_equal(v.values, np.maximum(margin - every, 0.0) / margin)
