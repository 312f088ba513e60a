"""The limits a run keeps: the URDF's, tightened by ``robot.velocity_limits`` /
``robot.acceleration_limits`` and by the published limits of each ``controller.export`` target
(libfranka, the UR datasheets), computed in one place and read by the excitation and the dense
check."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ident.cli import app
from ident.excitation.constraints import JointLimits, tighten_limits
from ident.run.config import load_run_config
from ident.run.exports.common import ExportError, ExportSamples
from ident.run.exports.franka import (
    DELTA_T,
    PANDA_ACCELERATION,
    PANDA_DESIGN_VELOCITY,
    PANDA_JERK,
    PANDA_VELOCITY,
    check_franka,
)
from ident.run.exports.run_exports import check_export_targets
from ident.run.exports.urscript import UR_MODELS
from ident.run.setup import prepare_run
from ident.trajectory import JointTrajectory, read_trajectory_csv

ROOT = Path(__file__).parents[1]
QUICK = ROOT / "tests" / "data" / "run" / "quick-wrist.yaml"
PAPER6R = ROOT / "configs" / "paper6r.yaml"
runner = CliRunner()


def _config(tmp_path: Path, source: Path, old: str, new: str, name: str = "c.yaml") -> Path:
    """``source`` copied into ``tmp_path`` with ``old`` replaced by ``new`` (paths absolute)."""
    text = source.read_text()
    assert old in text, old
    text = text.replace(old, new)
    text = text.replace("../robot/", f"{ROOT / 'robot'}/").replace(
        "../../../configs/paper6r.yaml", str(PAPER6R)
    )
    path = tmp_path / name
    path.write_text(text)
    return path


def test_tighten_limits_is_the_elementwise_tighter_and_names_what_it_changed():
    inf = np.inf
    limits = JointLimits(("a", "b"), [-1.0, -inf], [1.0, inf], [2.0, inf], [inf, 5.0])
    bound = JointLimits(("a", "b"), [-2.0, -3.0], [0.5, inf], [3.0, 1.5], [4.0, 6.0])
    out, notes = tighten_limits(limits, bound, "toy")
    np.testing.assert_array_equal(out.q_lower, [-1.0, -3.0])  # max of the lower bounds
    np.testing.assert_array_equal(out.q_upper, [0.5, inf])
    np.testing.assert_array_equal(out.dq_max, [2.0, 1.5])  # a looser bound never loosens
    np.testing.assert_array_equal(out.ddq_max, [4.0, 5.0])  # inf (none) takes the bound
    assert notes == (
        "toy: position lower limits [rad] b -inf -> -3",
        "toy: position upper limits [rad] a 1 -> 0.5",
        "toy: velocity limits [rad/s] b inf -> 1.5",
        "toy: acceleration limits [rad/s^2] a inf -> 4",
    )
    with pytest.raises(ValueError, match="joints"):
        tighten_limits(limits, JointLimits(("b", "a"), *([[0.0, 0.0]] * 4)), "toy")


def _limit_rate_clips(q: np.ndarray) -> bool:
    """An independent transcription of libfranka 0.8's ``limitRate`` for joint positions
    (velocity, acceleration, jerk limited in that order from the commanded positions); True
    when it changes any command."""
    v_last = np.zeros(q.shape[1])
    a_last = np.zeros(q.shape[1])
    q_last = q[0].copy()
    for command in q[1:]:
        v = (command - q_last) / DELTA_T
        a = (v - v_last) / DELTA_T
        jerk = np.clip((a - a_last) / DELTA_T, -PANDA_JERK, PANDA_JERK)
        a_jerk = a_last + jerk * DELTA_T
        upper = np.minimum(
            PANDA_JERK / PANDA_ACCELERATION * (PANDA_VELOCITY - v_last), PANDA_ACCELERATION
        )
        lower = np.maximum(
            PANDA_JERK / PANDA_ACCELERATION * (-PANDA_VELOCITY - v_last), -PANDA_ACCELERATION
        )
        a_new = np.clip(a_jerk, lower, upper)
        v_new = v_last + a_new * DELTA_T
        if np.any(np.abs(q_last + v_new * DELTA_T - command) > 1e-12):
            return True
        q_last, v_last, a_last = command, v_new, a_new
    return False


def _cruise(peak_velocity: float, joint: int = 2) -> np.ndarray:
    """1 kHz commands from rest: joint ``joint`` accelerates at libfranka's acceleration limit
    (raised smoothly within its jerk limit) up to ``peak_velocity``, cruises, and stops."""
    A, J = 0.999 * PANDA_ACCELERATION[joint], 0.5 * PANDA_JERK[joint]
    ramp = int(np.ceil(A / J / DELTA_T))
    accel = np.arange(ramp) / ramp * A
    v = np.cumsum(accel) * DELTA_T
    n_const = max(int(np.ceil((peak_velocity - 2 * v[-1]) / A / DELTA_T)), 0)
    up = np.concatenate([accel, np.full(n_const, A), accel[::-1]])
    a = np.concatenate([np.zeros(5), up, np.zeros(200), -up, np.zeros(5)])
    v = np.cumsum(a) * DELTA_T
    v *= peak_velocity / v.max()  # <= 1: the accelerations stay within A
    assert np.max(np.abs(np.diff(v))) / DELTA_T <= A * (1 + 1e-9)
    q = np.zeros((a.size, 7))
    q[:, joint] = -1.0 + np.cumsum(v) * DELTA_T
    q[:, 3] = -1.5  # inside the Panda's range of joint 4
    q[:, 5] = 1.5
    return q


def test_the_franka_design_velocity_is_one_limitrate_never_clips():
    joint = 2
    # at the design velocity with the full acceleration right up to it: no clipping, and the
    # exporter's check (libfranka's rule) agrees with the independent transcription
    q = _cruise(PANDA_DESIGN_VELOCITY[joint])
    assert not _limit_rate_clips(q)
    names = tuple(f"panda_joint{k}" for k in range(1, 8))
    check_franka(ExportSamples(np.arange(len(q)) * DELTA_T, q, None, None, names))
    # the URDF's 2.175 rad/s (what the design kept before): clipped, and refused
    fast = _cruise(2.17)
    assert _limit_rate_clips(fast)
    with pytest.raises(ExportError, match="panda_joint3"):
        check_franka(ExportSamples(np.arange(len(fast)) * DELTA_T, fast, None, None, names))
    # just inside libfranka's velocity limit but at full acceleration: clipped as well (why the
    # design keeps A^2/J below it)
    assert PANDA_DESIGN_VELOCITY[joint] < PANDA_VELOCITY[joint] - 0.019
    assert _limit_rate_clips(_cruise(PANDA_VELOCITY[joint] - 0.002))


def _panda(tmp_path: Path, export: str) -> Path:
    return _config(
        tmp_path,
        ROOT / "configs" / "panda.yaml",
        "controller: {rate_hz: 1000.0, n_periods: 1}",
        f"controller: {{rate_hz: 1000.0, n_periods: 1, export: {export}}}",
    )


def test_a_franka_target_tightens_the_limits_the_excitation_and_the_dense_check_read(tmp_path):
    plain = prepare_run(load_run_config(_panda(tmp_path, "[]")))
    urdf_velocity = np.array([2.175] * 4 + [2.61] * 3)  # robot/urdf/panda.urdf
    np.testing.assert_allclose(plain.safety.limits.dq_max, urdf_velocity)
    assert plain.limit_notes == ()
    setup = prepare_run(load_run_config(_panda(tmp_path, "[ros2, franka]")))
    expected = np.minimum(urdf_velocity, PANDA_DESIGN_VELOCITY)
    for limits in (setup.safety.limits, setup.family.limits, JointLimits.from_robot(setup.robot)):
        np.testing.assert_allclose(limits.dq_max, expected)
        # panda.yaml's acceleration_limits are Franka's datasheet, libfranka's less kLimitEps
        np.testing.assert_allclose(limits.ddq_max, PANDA_ACCELERATION)
    # joint 3, by hand from libfranka's constants (kLimitEps 1e-3, 3 lost packets of 1 ms):
    v_max, a_max, j_max = 2.175 - 1e-3 - 3e-3 * (10 - 1e-3), 10 - 1e-3, 5000 - 1e-3
    assert expected[2] == pytest.approx(v_max - a_max**2 / j_max, abs=1e-12)  # 2.124
    assert setup.limit_notes[0].startswith("franka: velocity limits [rad/s] panda_joint1 2.175 ->")
    assert "panda_joint3 2.175 -> 2.12401" in setup.limit_notes[0]
    assert setup.limit_notes[1].startswith("franka: acceleration limits")


def test_a_urscript_target_tightens_to_the_datasheet_speeds(tmp_path):
    ur5 = ROOT / "configs" / "ur5.yaml"
    old = "controller: {rate_hz: 1000.0, n_periods: 1}"
    path = _config(tmp_path, ur5, old, "controller: {rate_hz: 1000.0, export: [urscript]}")
    setup = prepare_run(load_run_config(path))
    np.testing.assert_allclose(setup.safety.limits.dq_max, UR_MODELS["ur5"])  # URDF: 3.15, 3.2
    np.testing.assert_allclose(setup.safety.limits.ddq_max, 8.0)  # the config's, kept
    assert setup.limit_notes == (
        "urscript: velocity limits [rad/s] "
        + ", ".join(
            f"{n} {urdf} -> 3.14159"
            for n, urdf in zip(setup.robot.joint_names, [3.15] * 3 + [3.2] * 3, strict=True)
        ),
    )
    # without configured accelerations, the 5 rad/s^2 the URScript check uses
    path = _config(
        tmp_path,
        path,
        "acceleration_limits: 8.0",
        "acceleration_limits: null",
        name="ur5-noacc.yaml",
    )
    setup = prepare_run(load_run_config(path))
    np.testing.assert_allclose(setup.safety.limits.ddq_max, 5.0)


def test_robot_velocity_limits_tighten_the_urdf_by_list_or_by_joint_name(tmp_path):
    old = "  acceleration_limits: [15.0"
    lower = "  velocity_limits: [1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 9.0]\n" + old
    setup = prepare_run(load_run_config(_config(tmp_path, ROOT / "configs/panda.yaml", old, lower)))
    np.testing.assert_allclose(
        setup.safety.limits.dq_max, [1.0, 1.1, 1.2, 1.3, 1.4, 1.5, 2.61]
    )  # 9.0 is above the URDF's 2.61: the URDF's holds
    by_name = "  velocity_limits: {panda_joint3: 0.7}\n" + old
    path = _config(tmp_path, ROOT / "configs/panda.yaml", old, by_name, name="named.yaml")
    setup = prepare_run(load_run_config(path))
    np.testing.assert_allclose(
        setup.family.limits.dq_max, [2.175, 2.175, 0.7, 2.175, 2.61, 2.61, 2.61]
    )


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("[1.0, -1.0, 1.0]", "positive, finite"),
        ("[1.0, .nan]", "finite"),
        ("{joint_4: .inf}", "finite"),
        ("0.0", "positive, finite"),
        ("[1.0, 2.0]", "has 2 values, the chain has 6 joints"),
        ("{joint_9: 1.0}", "names 'joint_9', not a moving joint"),
        ("fast", "velocity_limits"),
    ],
)
def test_bad_velocity_limits_are_one_error_line_exit_2_and_no_folder(tmp_path, value, expected):
    robot = f"robot: {PAPER6R}"
    path = _config(
        tmp_path,
        QUICK,
        "robot: ../../../configs/paper6r.yaml",
        f"robot: {{description: {PAPER6R}, velocity_limits: {value}}}",
    )
    assert robot not in path.read_text()
    result = runner.invoke(app, ["run", str(path), "--out", str(tmp_path / "runs"), "--quick"])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    assert lines[0].startswith(f"error: {path}"), lines[0]
    assert "robot.velocity_limits" in lines[0] or "velocity_limits" in lines[0]
    assert expected in lines[0], lines[0]
    assert not (tmp_path / "runs").exists()


@pytest.mark.slow
def test_a_design_that_would_outrun_libfranka_is_kept_within_it_and_exported(tmp_path):
    """Today's refusal, forced: the URDF allows joint 1 3.0 rad/s, and excitation.bounds make
    its velocity at least 2.05 rad/s (max |dq_1| = 2.598 b2 with a2 = 0, 2 harmonics). Without
    the franka limits the seed-0 design reaches 2.317 rad/s and the export is refused
    (measured with the code before this change); with them the design keeps 2.099 rad/s, the
    dense check certifies it, and the Franka file is written with zero clipping."""
    urdf = (ROOT / "robot/urdf/panda.urdf").read_text()
    assert 'velocity="2.175"' in urdf
    (tmp_path / "fast.urdf").write_text(urdf.replace('velocity="2.175"', 'velocity="3.0"', 1))
    config = tmp_path / "forced.yaml"
    config.write_text(
        f"""robot:
  urdf: fast.urdf
  tip_link: panda_link7
  lock: {{panda_finger_joint1: 0.02, panda_finger_joint2: 0.02}}
  package_dirs: [{ROOT / "robot/meshes"}]
  acceleration_limits: [15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]
stage: whole
seed: 0
excitation:
  family: joint_fourier
  n_samples: 100
  options: {{n_harmonics: 2, base_frequency: 1.2566370614359172, amplitude_bound: 0.2}}
  bounds:
    "q0[panda_joint1]": [0.2, 0.4]
    "a2[panda_joint1]": [-0.01, 0.01]
    "b2[panda_joint1]": [0.79, 1.1]
elites: {{n_particles: 6, n_elites: 2, maxiter: 30}}
optimizer: pso
emupso: {{n_particles: 8, maxiter: 6, stagnation: 3, n_runs: 1, n_report_elites: 1}}
safety: {{floor: {{enabled: true, z: 0.0}}, clearance_m: 0.03, self_collision: true,
  torque_limits: true, check_samples: 50}}
controller: {{rate_hz: 1000.0, n_periods: 1, export: [franka]}}
measurement: {{torque_noise_std: 0.0}}
"""
    )
    result = runner.invoke(
        app, ["run", str(config), "--out", str(tmp_path / "runs"), "--no-replay"]
    )
    assert "limits tightened by franka: velocity limits [rad/s] panda_joint1 3 -> 2.09901" in (
        result.output
    )
    assert "REFUSED" not in result.output, result.output
    assert result.exit_code in (0, 1), result.output  # 1: identification warnings only
    (run_dir,) = [d for d in (tmp_path / "runs").iterdir() if d.is_dir()]
    trajectory = read_trajectory_csv(run_dir / "trajectory.csv")
    peak = np.max(np.abs(trajectory.dq), axis=0)
    assert 2.05 < peak[0] <= PANDA_DESIGN_VELOCITY[0]  # the excitation does reach the limit
    q = np.loadtxt(run_dir / "exports" / "franka_q_1khz.csv", delimiter=",", comments="#")
    assert not _limit_rate_clips(q)  # zero clipping, by the independent transcription
    state = json.loads((run_dir / "run.json").read_text())
    assert state["export_limits"][0].startswith("franka: velocity limits")
    assert "Limits tightened by the export targets: franka:" in (run_dir / "report.md").read_text()


@pytest.mark.slow
def test_robot_velocity_limits_below_the_design_are_kept_by_the_trajectory(tmp_path):
    """quick-wrist.yaml's design reaches 1.64 rad/s on joint 4 and 1.01 rad/s on joint 5
    (measured); with robot.velocity_limits {joint_4: 1.2, joint_5: 0.8} the executable
    trajectory (1 kHz, approach and return included) keeps below both."""
    limits = {"joint_4": 1.2, "joint_5": 0.8}
    path = _config(
        tmp_path,
        QUICK,
        "robot: ../../../configs/paper6r.yaml",
        f"robot: {{description: {PAPER6R}, velocity_limits: {limits}}}",
    )
    result = runner.invoke(app, ["run", str(path), "--out", str(tmp_path / "runs"), "--no-replay"])
    assert result.exit_code == 0, result.output
    (run_dir,) = [d for d in (tmp_path / "runs").iterdir() if d.is_dir()]
    trajectory = read_trajectory_csv(run_dir / "trajectory.csv")
    assert np.all(np.diff(trajectory.t) <= 1e-3 + 1e-12)  # the controller's 1 kHz samples
    peak = dict(zip(trajectory.joint_names, np.max(np.abs(trajectory.dq), axis=0), strict=True))
    assert peak["joint_4"] <= 1.2
    assert peak["joint_5"] <= 0.8
    assert peak["joint_4"] > 0.5  # the joints do move
    assert peak["joint_5"] > 0.4


def _ramp_trajectory(jerk: float) -> JointTrajectory:
    """1 kHz plan from rest: joint 2's acceleration rises to 5 rad/s^2 at ``jerk`` [rad/s^3],
    holds 0.2 s, and falls back; every velocity and acceleration far inside libfranka's."""
    dt = 1e-3
    ramp = np.arange(int(round(5.0 / jerk / dt)) + 1) * jerk * dt
    a = np.concatenate([np.zeros(10), ramp, np.full(200, 5.0), ramp[::-1], np.zeros(10)])
    n = a.size
    dq = np.cumsum(a) * dt
    q = np.cumsum(dq) * dt
    names = tuple(f"panda_joint{k}" for k in range(1, 8))
    start = np.array([0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0])
    Q = np.tile(start, (n, 1))
    Q[:, 1] += q
    dQ, ddQ = np.zeros((n, 7)), np.zeros((n, 7))
    dQ[:, 1], ddQ[:, 1] = dq, a
    return JointTrajectory(np.arange(n) * dt, Q, dQ, ddQ, names)


def test_the_dense_check_runs_the_franka_jerk_check_of_its_export():
    urdf = (ROOT / "robot/urdf/panda.urdf").read_text()
    smooth = _ramp_trajectory(jerk=1000.0)
    assert check_export_targets(["ros2", "franka"], smooth, urdf, None) is None
    steep = _ramp_trajectory(jerk=5000.0)  # joint 2's kMaxJointJerk is 3750 rad/s^3
    refusal = check_export_targets(["ros2", "franka"], steep, urdf, None)
    assert refusal is not None
    assert refusal.startswith("franka: libfranka's limitRate would clip: joint 'panda_joint2' jerk")
    assert check_export_targets(["ros2"], steep, urdf, None) is None  # ros2 publishes no limits
