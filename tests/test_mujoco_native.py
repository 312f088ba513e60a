"""The MuJoCo-native measurement source: ``friction.semantics: mujoco`` and ``actuator``.

References: closed forms (a 1-DoF pendulum against MuJoCo's friction loss; the step response of
a second-order servo), Pinocchio's RNEA (the closed-loop truth while the joints slide), the log
read back, and the simulator's truth for the identification of a native log.
"""

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
from robots import UR5_URDF
from test_mimic import M, O, _write, arm_urdf
from test_mujoco_sim import FRICTION, fourier_reference

from ident.errors import ConfigError
from ident.measure.mujoco_config import ActuatorConfig, load_mujoco_measurement
from ident.measure.mujoco_model import (
    FRICTION_SOLIMP,
    JOINT_PARAMETER_FIELDS,
    load_mujoco,
    set_joint_parameters,
)
from ident.measure.mujoco_sim import simulate, write_log
from ident.model import Robot
from ident.run.config import load_run_config
from ident.run.log_measurement import identify_log, log_stage_info, simulate_log

REPO = Path(__file__).resolve().parents[1]
QUICK = REPO / "tests" / "data" / "run" / "quick-ur5-mujoco.yaml"

# One link on a revolute joint about `axis`, its centre of mass 0.3 m out along x.
_ONE_LINK = """<robot name="one">
  <link name="base"/>
  <link name="arm"><inertial><origin xyz="0.3 0 0"/><mass value="1.0"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="{axis}"/><limit lower="-10" upper="10" effort="1" velocity="10"/></joint>
</robot>
"""


def _one_link(tmp_path: Path, axis: str) -> Robot:
    path = tmp_path / f"one_{axis.replace(' ', '')}.urdf"
    path.write_text(_ONE_LINK.format(axis=axis))
    return Robot.from_urdf(path)


def _inertia(robot: Robot, q: float, armature: float) -> float:
    """The joint's inertia [kg*m^2] at q: Pinocchio's mass matrix plus the rotor's."""
    nominal = robot.model.copy()
    nominal.armature[:] = 0.0
    return float(pin.crba(nominal, nominal.createData(), np.array([q]))[0, 0]) + armature


# ----------------------------------------------------------------------------- friction loss
@pytest.mark.parametrize("net", [-4.0, -2.0, 2.0, 4.0])
def test_frictionloss_sticks_inside_its_band_and_slides_against_exactly_its_value(tmp_path, net):
    """A horizontal pendulum (gravity about its joint), friction loss F = 3 N*m, Ia = 0.05.

    ``|tau - g| < F``: it stays put, up to the soft constraint's creep ``(1 - dmin) h a_free``.
    ``|tau - g| > F``: at every step ``ddq = (tau - g(q) - F sign(dq)) / (M(q) + Ia)``, the
    closed form with Pinocchio's g and M, to the constraint solver's tolerance.
    """
    robot = _one_link(tmp_path, "0 1 0")
    F, Ia, h, n_steps = 3.0, 0.05, 1e-3, 500
    mj = load_mujoco(robot, timestep_s=h, native_friction=True)
    set_joint_parameters(mj, {"fs": np.array([F]), "Ia": np.array([Ia])})
    data = mujoco.MjData(mj.model)
    gravity = float(robot.rnea(np.zeros(1), np.zeros(1), np.zeros(1))[0][0])
    data.qfrc_applied[mj.dof_index] = gravity + net  # constant: net torque at q = 0
    q, acc, expected = [], [], []
    for _ in range(n_steps):
        q_k, dq_k = float(data.qpos[0]), float(data.qvel[0])
        mujoco.mj_step(mj.model, data)
        q.append(q_k)
        acc.append(float(data.qacc[0]))
        g_k = float(robot.rnea(np.array([q_k]), np.zeros(1), np.zeros(1))[0][0])
        slide = np.sign(dq_k) if dq_k != 0.0 else np.sign(net)
        expected.append((gravity + net - g_k - F * slide) / _inertia(robot, q_k, Ia))
    a_free = abs(net) / _inertia(robot, 0.0, Ia)
    if abs(net) < F:
        creep = (1.0 - FRICTION_SOLIMP[0]) * h * a_free * n_steps * h
        assert abs(q[-1]) <= 1.5 * creep, (q[-1], creep)
        assert abs(q[-1]) < 1e-6 * 0.5 * a_free * (n_steps * h) ** 2  # free: 1e6 times more
    else:
        np.testing.assert_allclose(acc, expected, rtol=1e-9, atol=1e-9)
        assert abs(acc[0]) == pytest.approx((abs(net) - F) / _inertia(robot, 0.0, Ia), rel=1e-12)


def test_joint_parameters_map_one_to_one_onto_mujoco_fields(ur5):
    mj = load_mujoco(ur5, native_friction=True)
    values = {k: np.arange(1.0, 7.0) * s for k, s in (("fv", 0.1), ("fs", 0.2), ("Ia", 0.3))}
    set_joint_parameters(mj, values)
    assert JOINT_PARAMETER_FIELDS == {
        "fv": "dof_damping",
        "fs": "dof_frictionloss",
        "Ia": "dof_armature",
    }
    for kind, field in JOINT_PARAMETER_FIELDS.items():
        assert np.array_equal(getattr(mj.model, field)[mj.dof_index], values[kind])
    # the constraint solver is on for friction only: contacts off, no joint limit
    assert not mj.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    assert mj.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONTACT
    assert not mj.model.jnt_limited.any()
    assert not mj.model.jnt_actfrclimited.any()
    plain = load_mujoco(ur5)
    assert plain.model.opt.disableflags & mujoco.mjtDisableBit.mjDSBL_CONSTRAINT


def test_mimic_follower_keeps_its_leader_with_native_friction_and_a_servo(tmp_path):
    """A mimic joint's equality and the friction-loss constraints solved together: the follower
    stays on ``M q_leader + O`` while position servos drive the leaders against friction."""
    robot = Robot.from_urdf(_write(tmp_path, "arm.urdf", arm_urdf()))
    servo = ActuatorConfig(kind="position", kp=400.0, kv=20.0)
    mj = load_mujoco(robot, timestep_s=1e-3, actuator=servo, native_friction=True)
    set_joint_parameters(mj, {"fs": np.array([0.3, 0.2])})
    assert mj.model.neq == 1
    data = mujoco.MjData(mj.model)
    follower = mj.model.jnt_qposadr[mujoco.mj_name2id(mj.model, mujoco.mjtObj.mjOBJ_JOINT, "j3")]
    t = np.arange(1000) * 1e-3
    q_cmd = np.column_stack([0.5 * np.sin(2 * np.pi * t), 0.8 * np.sin(4 * np.pi * t)])
    mj.set_state(data, q_cmd[0], np.zeros(2))
    mj.start_control(data, q_cmd[0])
    coupling, friction_rows, q = [], 0, np.empty_like(q_cmd)
    for k in range(t.size):
        data.ctrl[mj.actuator_index] = q_cmd[k]
        mujoco.mj_step(mj.model, data)
        q[k] = data.qpos[mj.qpos_index]
        coupling.append(data.qpos[follower] - (M * q[k, 1] + O))
        friction_rows = max(friction_rows, int(data.nf))
    assert friction_rows == 2  # the leaders' friction loss is in the solver
    assert np.abs(coupling).max() < 1e-3
    assert np.all(np.ptp(q, axis=0) > 0.5 * np.ptp(q_cmd, axis=0))  # the servos move them


@pytest.fixture(scope="module")
def ur5():
    return Robot.from_urdf(UR5_URDF)


# ----------------------------------------------------------------------------- actuators
_START = 0.5  # [rad] the servo's position and command before the step to 1 rad


def _step_response(robot, actuator: dict, n_steps: int, h: float, armature: float):
    """Joint position and actuator force [rad, N*m] (n_steps,) after a step of the position
    command from ``_START`` to 1 rad at step 0, from rest at ``_START`` with that command held
    before (a delayed servo's history holds it: :meth:`MujocoRobot.start_control`)."""
    mj = load_mujoco(robot, timestep_s=h, actuator=ActuatorConfig(**actuator))
    set_joint_parameters(mj, {"Ia": np.array([armature])})
    data = mujoco.MjData(mj.model)
    mj.set_state(data, np.array([_START]), np.zeros(1))
    mj.start_control(data, np.array([_START]))
    data.ctrl[mj.actuator_index] = 1.0
    q, force = np.empty(n_steps), np.empty(n_steps)
    for k in range(n_steps):
        mujoco.mj_step(mj.model, data)
        q[k], force[k] = data.qpos[0], data.actuator_force[mj.actuator_index[0]]
    return q, force


def test_position_actuator_step_response_saturation_and_delay(tmp_path):
    """A vertical joint (no gravity torque), no friction: ``I ddq = kp (1 - q) - kv dq``.

    The underdamped closed form ``q0 + (1 - q0) s(t)``,
    ``s(t) = 1 - exp(-z w t) (cos(wd t) + z w / wd sin(wd t))``, with
    ``w^2 = kp / I``, ``2 z w = kv / I``, ``I`` the link's inertia plus the armature, matches
    MuJoCo's semi-implicit Euler to O(h w) (h = 0.1 ms, w = 31.6 rad/s: 1.4e-3 of the step
    measured; 0.05 kg*m^2 of armature lost would be 0.25). ``forcerange`` clips the force;
    ``delay_steps = k`` shifts the response by exactly k steps (bit for bit).
    """
    robot = _one_link(tmp_path, "0 0 1")
    kp, kv, Ia, h, n = 100.0, 2.0, 0.0, 1e-4, 4000
    inertia = _inertia(robot, 0.0, Ia)
    q, force = _step_response(robot, {"kind": "position", "kp": kp, "kv": kv}, n, h, Ia)
    w, z = np.sqrt(kp / inertia), kv / (2.0 * np.sqrt(kp * inertia))
    wd, t = w * np.sqrt(1.0 - z**2), h * np.arange(1, n + 1)
    step = 1.0 - _START
    closed = 1.0 - step * np.exp(-z * w * t) * (np.cos(wd * t) + z * w / wd * np.sin(wd * t))
    error = np.abs(q - closed).max() / step
    assert error < 3e-3, f"max |q - closed form| = {error:.2e} of the step"
    assert force[0] == pytest.approx(kp * step)  # kp (1 - q0) - kv 0
    # a heavier rotor: the same closed form with I + Ia (a lost armature would fail it)
    Ia = 0.05
    q_heavy, _ = _step_response(robot, {"kind": "position", "kp": kp, "kv": kv}, n, h, Ia)
    w = np.sqrt(kp / (inertia + Ia))
    z = kv / (2.0 * np.sqrt(kp * (inertia + Ia)))
    wd = w * np.sqrt(1.0 - z**2)
    closed = 1.0 - step * np.exp(-z * w * t) * (np.cos(wd * t) + z * w / wd * np.sin(wd * t))
    assert np.abs(q_heavy - closed).max() / step < 3e-3
    # saturation: |force| <= 20 N*m, held at 20 while kp (1 - q) exceeds it
    sat, f_sat = _step_response(
        robot, {"kind": "position", "kp": kp, "kv": kv, "forcerange": 20.0}, n, h, 0.0
    )
    assert np.abs(f_sat).max() == pytest.approx(20.0, rel=1e-15)
    assert f_sat[0] == 20.0
    assert np.all(f_sat[:50] == 20.0)
    climb = 20.0 / inertia * h**2 * np.cumsum(np.arange(1, 51))  # constant acceleration
    np.testing.assert_allclose(sat[:50] - _START, climb, rtol=1e-9)
    # delay: exactly k steps later, bit for bit; the held command before (no jump to 0)
    for k in (1, 3):
        late, f_late = _step_response(
            robot, {"kind": "position", "kp": kp, "kv": kv, "delay_steps": k}, n, h, 0.0
        )
        assert np.all(late[:k] == _START)
        assert np.all(f_late[:k] == 0.0)
        assert np.array_equal(late[k:], q[:-k])
        assert np.array_equal(f_late[k:], force[:-k])


def test_closed_loop_native_friction_is_the_truth_while_sliding_and_logs_the_servo(ur5, tmp_path):
    """UR5 with MuJoCo's friction loss: the actuator force is RNEA + Ia ddq + fv dq + fs sign(dq)
    on every sample where the joint slides. A position servo: its force is
    ``kp (q_cmd - q) - kv dq`` clipped, q_cmd is the reference, and the log keeps it."""
    t, q, dq, ddq = fourier_reference(ur5)
    native = {**FRICTION, "friction": {**FRICTION["friction"], "semantics": "mujoco"}}
    log = simulate(ur5, t, q, dq, ddq, load_mujoco_measurement({**native, "n_periods": 1}))
    truth = log.truth
    expected = (
        ur5.rnea(log.q_true, log.dq_true, log.ddq_true)
        + truth["viscous"] * log.dq_true
        + truth["coulomb"] * np.sign(log.dq_true)
        + truth["armature"] * log.ddq_true
    )
    # sliding through the step: the velocity keeps its sign and stays off zero (a step that
    # reaches zero velocity sticks, its friction anything within fs: no closed form)
    dq_after = log.dq_true + log.ddq_true / log.rate_hz
    sliding = (log.dq_true * dq_after > 0) & (np.minimum(abs(log.dq_true), abs(dq_after)) > 1e-3)
    assert sliding.mean() > 0.9
    error = np.abs(log.tau_actuator - expected)[sliding].max()
    assert error < 1e-9 * np.abs(log.tau_actuator).max(), error  # measured 1.5e-15
    # where a step stops a joint, the friction holds it with less than fs: stiction, which
    # ident's law (+-fs, or 0 at dq == 0 exactly) never gives
    friction = (log.tau_actuator - expected) + truth["coulomb"] * np.sign(log.dq_true)
    inside = (np.abs(friction) > 0.05 * truth["coulomb"]) & (
        np.abs(friction) < 0.95 * truth["coulomb"]
    )
    assert inside[~sliding].sum() >= 3, inside.sum()
    assert np.array_equal(log.tau_cmd, log.tau_actuator)  # a motor without range or delay
    kp, kv, limit = 2000.0, [80.0, 80.0, 40.0, 5.0, 5.0, 2.0], 60.0
    servo = {"kind": "position", "kp": kp, "kv": kv, "forcerange": limit, "delay_steps": 2}
    log = simulate(
        ur5, t, q, dq, ddq, load_mujoco_measurement({**native, "actuator": servo, "n_periods": 1})
    )
    np.testing.assert_array_equal(log.q_cmd, log.q_reference)
    q_sent = np.vstack([log.q_cmd[:1], log.q_cmd[:1], log.q_cmd[:-2]])  # 2 steps late
    servo_force = np.clip(kp * (q_sent - log.q_true) - np.array(kv) * log.dq_true, -limit, limit)
    np.testing.assert_allclose(log.tau_actuator[2:], servo_force[2:], rtol=0, atol=1e-9)
    assert np.abs(log.tau_actuator).max() == pytest.approx(limit)  # it saturates
    files = write_log(tmp_path, log)
    header = files.csv.read_text().splitlines()[0].split(",")
    assert header[-6:] == [f"q_cmd_{name}" for name in ur5.joint_names]
    table = np.loadtxt(files.csv, delimiter=",", skiprows=1)
    assert np.array_equal(table[:, -6:], log.q_cmd)


def test_run_config_servo_log_carries_its_command_into_the_log_read(ur5):
    """A run config with ``actuator: {kind: position, ...}``: the log read back (RobotLog, as
    ``ident identify`` reads it) keeps the commanded positions row for row."""
    config = load_run_config(QUICK)
    servo = ActuatorConfig(kind="position", kp=2000.0, kv=[80.0, 80.0, 40.0, 5.0, 5.0, 2.0])
    config = config.model_copy(
        update={
            "measurement": config.measurement.model_copy(
                update={"actuator": servo, "settle_periods": 0, "n_periods": 1}
            )
        }
    )
    t, q, dq, ddq = fourier_reference(ur5)
    log, read, _ = simulate_log(config, ur5, t, q, dq, ddq, seed=0)
    assert read.q_cmd is not None
    assert np.array_equal(read.q_cmd, log.q_cmd)
    assert np.array_equal(read.q, log.q)
    with pytest.raises(ValueError, match="q_cmd has shape"):
        dataclasses.replace(read, q_cmd=read.q_cmd[:-1])


# ----------------------------------------------------------------------------- identification
def test_identify_recovers_base_parameters_from_a_mujoco_native_log(ur5):
    """The run pipeline (simulate, write, read back, identify: ``ident run``'s own functions)
    on a MuJoCo-native log of the quick UR5 config: a plain 4 s Fourier excitation, 2 logged
    periods at 500 Hz, no noise (the errors are the model-class mismatch, stiction and the
    friction switch inside one step, plus the preprocessing), all samples identified.

    Measured errors: rigid-body base parameters with >= 1 % of the torques within 7.8 %
    (Ixx5R, 1.2 % of the torques; the others within 3.2 %), fv within 1.3 %, fs within 0.9 %,
    Ia3-Ia6 within 6.7 %.
    """
    config = load_run_config(QUICK)
    m, ident = config.measurement, config.identification
    measurement = m.model_copy(
        update={
            "friction": m.friction.model_copy(update={"semantics": "mujoco"}),
            "rate_hz": 500.0,
            "torque_noise_std": 0.0,
            "encoder_counts_per_rev": None,
        }
    )
    preprocess = ident.preprocess.model_copy(update={"trim_samples": 250, "decimation": [10]})
    for key in ("lowpass", "torque_lowpass"):
        section = getattr(preprocess, key).model_copy(update={"cutoff_hz": 20.0})
        preprocess = preprocess.model_copy(update={key: section})
    validation = ident.validation.model_copy(update={"identify_fraction": 1.0})
    ident = ident.model_copy(update={"preprocess": preprocess, "validation": validation})
    config = config.model_copy(update={"measurement": measurement, "identification": ident})
    t, q, dq, ddq = fourier_reference(ur5, period=4.0, seed=2, amplitude=1.5, rate_hz=500.0)
    log, read, cfg = simulate_log(config, ur5, t, q, dq, ddq, seed=0)
    estimate = identify_log(cfg, read, ur5).estimate
    stage, _ = log_stage_info(config, ur5)
    assert list(estimate.names) == list(stage.base_names)
    true = np.asarray(stage.true_base)
    errors = 100.0 * np.abs(estimate.x - true) / np.abs(true)
    share = np.asarray(stage.reference_share)
    kinds = [n.rstrip("0123456789") for n in stage.base_names]
    groups = {
        "rigid (share >= 1 %)": [
            k not in ("fv", "fs", "Ia") and s >= 0.01 for k, s in zip(kinds, share, strict=True)
        ],
        "fv": [k == "fv" for k in kinds],
        "fs": [k == "fs" for k in kinds],
        "Ia": [k == "Ia" for k in kinds],
    }
    limits = {"rigid (share >= 1 %)": 12.0, "fv": 3.0, "fs": 3.0, "Ia": 10.0}
    measured = {g: float(errors[np.array(mask)].max()) for g, mask in groups.items()}
    report = ", ".join(
        f"{n} {e:.2f} %"
        for n, e, s in zip(stage.base_names, errors, share, strict=True)
        if s >= 0.01 or n[:2] in ("fv", "fs", "Ia")
    )
    print(f"errors of the native log: {report}")
    assert sum(groups["Ia"]) == 4
    assert sum(groups["fs"]) == 6
    for group, limit in limits.items():
        assert measured[group] < limit, f"{group}: max error {measured[group]:.2f} % ({report})"


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("section", "match"),
    [
        ({"friction": {"semantics": "coulomb"}}, r"friction\.semantics"),
        (
            {
                "friction": {
                    "semantics": "mujoco",
                    "law": {
                        "model": "stribeck",
                        "values": {"fv": 0.5, "fc": 1.0, "fst": 0.5, "vs": 0.05},
                    },
                }
            },
            "MuJoCo has no such joint friction",
        ),
        ({"actuator": {"kind": "position"}}, r"position needs actuator\.kp"),
        ({"actuator": {"kind": "motor", "kv": 1.0}}, "gains of kind: position"),
        ({"actuator": {"kind": "position", "kp": 0.0}}, r"actuator\.kp.*> 0 N\*m/rad"),
        ({"actuator": {"kind": "position", "kp": 1.0, "kv": -1.0}}, r"actuator\.kv.*>= 0"),
        ({"actuator": {"forcerange": [10.0, -1.0]}}, r"actuator\.forcerange.*> 0 N\*m"),
        ({"actuator": {"delay_steps": -1}}, r"actuator\.delay_steps"),
        ({"actuator": {"delay_steps": 1.5}}, r"actuator\.delay_steps"),
        (
            {"actuator": {"kind": "position", "kp": 10.0}, "controller": {"kind": "pd"}},
            "a position actuator tracks the reference itself",
        ),
        (
            {
                "actuator": {"delay_steps": 2},
                "friction": {
                    "law": {"model": "load_dependent", "values": {"fv": 0, "fc": 0, "fl": 0.1}}
                },
            },
            "takes the commanded torque as its load",
        ),
    ],
)
def test_invalid_native_sections_are_one_line_config_errors(section, match):
    with pytest.raises(ConfigError, match=match) as info:
        load_mujoco_measurement({"source": "mujoco", **section}, "run.yaml")
    message = str(info.value)
    assert message.startswith("run.yaml: ")
    assert "\n" not in message
