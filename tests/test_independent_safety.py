"""benchmarks/independent_safety.py, the re-check of a run's trajectory written apart from
ident's safety code: it flags a collision, a collision hidden by an unjustified exclusion, the
floor and each limit, and its smallest clearance is the closed form's at every sample."""

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

ROOT = Path(__file__).resolve().parents[1]
UR5_JOINTS = [
    "shoulder_pan_joint",
    "shoulder_lift_joint",
    "elbow_joint",
    "wrist_1_joint",
    "wrist_2_joint",
    "wrist_3_joint",
]

# a box base (z 0..0.2), a vertical post (link1, turning about z) and a sphere of radius 0.05
# on a 0.3 m arm (link2, turning about y at z = 0.5): the sphere can swing into the base
TWO_LINK_URDF = """<?xml version="1.0"?>
<robot name="swing">
  <link name="base">
    <inertial><mass value="5"/>
      <inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.1"/><geometry><box size="0.2 0.2 0.2"/></geometry></collision>
  </link>
  <link name="link1">
    <inertial><origin xyz="0 0 0.15"/><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0 0 0.15"/><geometry><box size="0.04 0.04 0.3"/></geometry></collision>
  </link>
  <link name="link2">
    <inertial><origin xyz="0.3 0 0"/><mass value="1"/>
      <inertia ixx="0.001" iyy="0.001" izz="0.001" ixy="0" ixz="0" iyz="0"/></inertial>
    <collision><origin xyz="0.3 0 0"/><geometry><sphere radius="0.05"/></geometry></collision>
  </link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="link1"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2" effort="50"/></joint>
  <joint name="j2" type="revolute"><parent link="link1"/><child link="link2"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 1 0"/>
    <limit lower="-0.5" upper="UPPER" velocity="VELOCITY" effort="EFFORT"/></joint>
</robot>
"""


@pytest.fixture(scope="module")
def checker():
    spec = importlib.util.spec_from_file_location(
        "independent_safety", ROOT / "benchmarks" / "independent_safety.py"
    )
    module = importlib.util.module_from_spec(spec)
    sys.modules["independent_safety"] = module
    spec.loader.exec_module(module)
    return module


def _swing(a1: float, a2: float, period: float, rate_hz: float = 1000.0):
    """j2 = a1 sin^2(w t) + a2 sin^2(3 w t), j1 = 0.3 sin(2 w t), w = pi / period, at
    ``rate_hz``: t (n,), q, dq, ddq (n, 2) in closed form."""
    t = np.linspace(0.0, period, round(period * rate_hz) + 1)
    w = np.pi / period
    q2 = a1 * np.sin(w * t) ** 2 + a2 * np.sin(3 * w * t) ** 2
    dq2 = a1 * w * np.sin(2 * w * t) + 3 * a2 * w * np.sin(6 * w * t)
    ddq2 = 2 * a1 * w**2 * np.cos(2 * w * t) + 18 * a2 * w**2 * np.cos(6 * w * t)
    q1, dq1 = 0.3 * np.sin(2 * w * t), 0.6 * w * np.cos(2 * w * t)
    ddq1 = -1.2 * w**2 * np.sin(2 * w * t)
    return t, *(np.column_stack(pair) for pair in ((q1, q2), (dq1, dq2), (ddq1, ddq2)))


def _sphere_to_base(q: np.ndarray) -> np.ndarray:
    """The sphere's distance to the base box in closed form [m], shape (n,)."""
    c = np.column_stack(
        [
            0.3 * np.cos(q[:, 1]) * np.cos(q[:, 0]),
            0.3 * np.cos(q[:, 1]) * np.sin(q[:, 0]),
            0.5 - 0.3 * np.sin(q[:, 1]),
        ]
    )
    outside = np.abs(c - [0.0, 0.0, 0.1]) - 0.1
    return (
        np.linalg.norm(np.maximum(outside, 0.0), axis=1) + np.minimum(outside.max(axis=1), 0.0)
    ) - 0.05


def _check(checker, trajectory, *, upper=1.5, velocity=2.0, effort=20.0, **kwargs):
    urdf = (
        TWO_LINK_URDF.replace("UPPER", str(upper))
        .replace("VELOCITY", str(velocity))
        .replace("EFFORT", str(effort))
    )
    robot = checker.Robot(urdf, [], ["j1", "j2"], {})
    options = {"margin_m": 0.01, "floor_z": 0.0, "excluded": [], "rate_hz": 1000.0, **kwargs}
    return checker.check_trajectory(robot, *trajectory, **options)


def test_a_safe_swing_passes_with_the_closed_form_clearance(checker):
    # two approaches to the base (the second the closest): the smallest clearance is the
    # closed form's smallest over the samples, though most samples are skipped
    trajectory = _swing(0.5, 0.25, 2.0)
    verdict = _check(checker, trajectory, excluded=["base|link1", "link1|link2"])
    assert verdict.ok, verdict.failures
    exact = _sphere_to_base(trajectory[1])
    assert verdict.clearance_m == pytest.approx(exact.min(), abs=1e-7)
    assert verdict.closest_pair == "base|link2"
    assert verdict.closest_time == pytest.approx(trajectory[0][np.argmin(exact)])
    assert verdict.n_samples == trajectory[0].size
    assert verdict.n_distances < 0.5 * verdict.n_samples * verdict.n_pairs
    # both exclusions are adjacent pairs; the peak speed of j2 against its 2 rad/s
    assert sum("adjacent" in n for n in verdict.notes) == 2
    assert verdict.velocity_ratio == pytest.approx(np.abs(trajectory[2]).max() / 2.0, rel=1e-9)


def test_a_slower_trajectory_is_checked_at_the_rate_asked_between_its_samples(checker):
    # 100 Hz samples (none at the closest moment), checked at >= 1 kHz: the quintic between
    # them reaches the closed form's smallest clearance (at 100 kHz) within 1 um, which the
    # 100 Hz samples miss by 48 um
    coarse, fine = _swing(0.5, 0.25, 2.013, rate_hz=100.0), _swing(0.5, 0.25, 2.013, 1e5)
    verdict = _check(checker, coarse, excluded=["base|link1", "link1|link2"])
    assert verdict.rate_hz >= 1000.0
    exact = _sphere_to_base(fine[1]).min()
    assert _sphere_to_base(coarse[1]).min() > exact + 4e-5
    assert verdict.clearance_m == pytest.approx(exact, abs=1e-6)


@pytest.mark.parametrize(
    ("change", "needle"),
    [
        ({"a1": 1.3}, "clearance base|link2"),  # swings into the base
        ({"a1": 1.3, "excluded": ["base|link2"]}, "clearance base|link2"),  # hidden by ident
        ({"upper": 0.6}, "position j2"),
        ({"period": 0.5}, "velocity j2"),
        ({"effort": 2.0}, "torque j2"),  # the arm's weight: 1 kg x 9.81 x 0.3 m = 2.9 N*m
        ({"floor_z": 0.25}, "floor: link2_0"),
    ],
)
def test_the_checker_flags_each_violation(checker, change, needle):
    change = dict(change)
    trajectory = _swing(change.pop("a1", 0.5), 0.25, change.pop("period", 2.0))
    verdict = _check(checker, trajectory, **change)
    assert not verdict.ok
    assert any(f.startswith(needle) for f in verdict.failures), verdict.failures
    if "excluded" in change:
        assert any("excluded by ident, but neither adjacent" in n for n in verdict.notes)


def test_pair_speeds_bound_every_pairs_change_of_distance(checker):
    # the samples the conservative advancement skips are safe only if pair_speeds bounds how
    # fast every pair's distance changes: coal's distances on the UR5's meshes at random
    # postures and 1 ms later at random joint speeds (a bound that missed a joint, a lever
    # arm or a body's extent would be exceeded; a wild over-estimate would not pay)
    urdf = (ROOT / "robot" / "urdf" / "ur5.urdf").read_text(encoding="utf-8")
    robot = checker.Robot(urdf, [str(ROOT / "robot" / "meshes")], UR5_JOINTS, {})
    checker._set_pairs(robot, [], [], checker.Verdict(1000.0, 0, 0.0))  # every pair of links
    rng = np.random.default_rng(0)
    n, h = 40, 1e-3
    q = rng.uniform(-3.0, 3.0, (n, 6))
    dq = rng.normal(0.0, 1.5, (n, 6)) * (rng.random((n, 6)) < 0.5)
    # posture k and k + n: the same motion h seconds apart (dq unchanged: a 1 ms step)
    both = (np.vstack([q, q + h * dq]), np.vstack([dq, dq]), np.zeros((2 * n, 6)))
    qs, vs, accs = robot.configurations(robot.joint_values(*both))
    rot, pos, twist, _ = checker.kinematics(robot, qs, vs, accs)
    speed = checker.pair_speeds(robot, rot, pos, twist)
    pairs = range(len(robot.geom.collisionPairs))
    d = np.zeros((2 * n, len(pairs)))
    for s in range(2 * n):
        pin.updateGeometryPlacements(robot.model, robot.data, robot.geom, robot.gdata, qs[s])
        d[s] = [checker._pair_distance(robot, p) for p in pairs]
    change = np.abs(d[n:] - d[:n])
    apart = (d[:n] > 0) & (d[n:] > 0) & (change > 1e-5)  # GJK's own noise is ~1e-7
    ratios = change[apart] / (h * np.maximum(speed[:n], speed[n:])[apart])
    assert ratios.size > 200
    assert ratios.max() <= 1.0, ratios.max()
    assert ratios.max() > 0.3


def test_the_payload_box_is_checked_against_the_other_bodies(checker):
    # a 20 cm box hanging below link2's sphere (its own body: never paired with link2) reaches
    # the base box the sphere alone keeps 46 mm from; it is checked against link1 (adjacent)
    urdf = TWO_LINK_URDF.replace("UPPER", "1.5").replace("VELOCITY", "2").replace("EFFORT", "20")
    robot = checker.Robot(urdf, [], ["j1", "j2"], {})
    robot.add_payload_box({"link": "link2", "size": [0.05, 0.05, 0.2], "position": [0.3, 0, -0.1]})
    options = {"margin_m": 0.01, "floor_z": 0.0, "rate_hz": 1000.0}
    verdict = checker.check_trajectory(
        robot, *_swing(0.5, 0.25, 2.0), excluded=["base|link1", "link1|link2"], **options
    )
    assert any(f.startswith("clearance base|payload") for f in verdict.failures), verdict.failures
    assert verdict.pairs == ["base|link2", "base|payload", "link1|payload"]
    assert not any(f.startswith("clearance base|link2") for f in verdict.failures)


def test_a_trajectory_not_at_rest_at_its_ends_fails(checker):
    t, _, dq, _ = _swing(0.5, 0.25, 2.0)  # j1 starts and ends at 0.3 w rad/s
    verdict = checker.Verdict(1000.0, t.size, 0.01)
    checker._check_rest(t, dq, verdict)
    assert [f.split(":")[0] for f in verdict.failures] == ["not at rest at t = 0.000 s"] + [
        f"not at rest at t = {t[-1]:.3f} s"
    ]
    checker._check_rest(t, dq * 0.0, verdict := checker.Verdict(1000.0, t.size, 0.01))
    assert verdict.ok


def test_the_runs_own_limits_are_checked(checker):
    # configs/ur5.yaml: the URDF gives no acceleration limit, the config's 8 rad/s^2 is
    # checked; the elbow's position range is the run's [-pi, pi]
    t = np.linspace(0.0, 0.01, 11)
    q, dq, ddq = np.zeros((11, 6)), np.zeros((11, 6)), np.zeros((11, 6))
    ddq[5, 2], q[3, 2] = 8.5, 3.2
    out = checker.Verdict(1000.0, t.size, 0.01)
    checker.check_selected_limits(ROOT / "configs" / "ur5.yaml", UR5_JOINTS, t, (q, dq, ddq), out)
    assert [f.split(" =")[0] for f in out.failures] == [
        "position elbow_joint",
        "acceleration elbow_joint",
    ]
    assert out.acceleration_ratio == pytest.approx(8.5 / 8.0)
    assert not out.not_checked
