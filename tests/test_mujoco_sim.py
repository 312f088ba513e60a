"""The MuJoCo measurement source: model loading, closed-loop truth, tracking, the log it writes.

References: Pinocchio's RNEA (inverse dynamics of the loaded model and the simulated truth), the
semi-implicit Euler update (the logged acceleration is the one integrated), the encoder step,
numpy's CSV reader and today's ``ident identify`` log reader.
"""

import mujoco
import numpy as np
import pytest
import yaml
from robots import PANDA_URDF, UR5_URDF

from ident.errors import ConfigError, DataError
from ident.identify.config import load_identify_config
from ident.identify.pipeline.real import identify
from ident.measure.logs import read_log
from ident.measure.mujoco_config import check_joint_counts, load_mujoco_measurement
from ident.measure.mujoco_model import load_mujoco
from ident.measure.mujoco_sim import (
    LOG_CSV,
    coulomb_law,
    reference_at_rate,
    simulate,
    write_log,
)
from ident.model import Robot

PANDA_LOCKS = {"panda_finger_joint1": 0.01, "panda_finger_joint2": 0.035}


@pytest.fixture(scope="module")
def ur5():
    return Robot.from_urdf(UR5_URDF)


@pytest.fixture(scope="module")
def panda():
    return Robot.from_urdf(PANDA_URDF, lock_joints=PANDA_LOCKS)


def fourier_reference(robot, *, period=0.5, rate_hz=1000.0, amplitude=1.0, seed=0):
    """A smooth periodic joint reference (3 harmonics) about the middle of the joint ranges."""
    rng = np.random.default_rng(seed)
    n = int(round(period * rate_hz))
    t = np.arange(n) / rate_hz
    w = 2.0 * np.pi / period
    q = np.zeros((n, robot.nq))
    dq, ddq = np.zeros_like(q), np.zeros_like(q)
    for harmonic in (1, 2, 3):
        a, b = rng.uniform(-amplitude, amplitude, (2, robot.nq)) / harmonic
        wl, phase = w * harmonic, w * harmonic * t[:, None]
        q += a / wl * np.sin(phase) - b / wl * np.cos(phase)
        dq += a * np.cos(phase) + b * np.sin(phase)
        ddq += -a * wl * np.sin(phase) + b * wl * np.cos(phase)
    middle = 0.5 * (np.clip(robot.q_lower, -3.0, 3.0) + np.clip(robot.q_upper, -3.0, 3.0))
    return t, q + middle, dq, ddq


FRICTION = {
    "friction": {
        "viscous": [0.8, 0.7, 0.5, 0.2, 0.15, 0.1],
        "coulomb": [2.0, 1.8, 1.2, 0.5, 0.4, 0.3],
    },
    "armature": [0.4, 0.4, 0.2, 0.05, 0.05, 0.05],
}


# ----------------------------------------------------------------------------- model loading
@pytest.mark.parametrize("which", ["ur5", "panda", "paper6r", "ur5_elbow_locked"])
def test_mujoco_inverse_dynamics_equals_pinocchio_rnea(which, ur5, panda):
    robots = {
        "ur5": lambda: ur5,
        "panda": lambda: panda,  # fingers locked at 0.01 and 0.035 m
        "paper6r": lambda: Robot.from_config("configs/paper6r.yaml"),
        "ur5_elbow_locked": lambda: Robot.from_urdf(UR5_URDF, lock_joints={"elbow_joint": 1.0}),
    }
    robot = robots[which]()
    mj = load_mujoco(robot)
    model, data = mj.model, mujoco.MjData(mj.model)
    assert model.nq == robot.nq  # locked joints are fixed in MuJoCo
    assert model.nv == robot.nv
    rng = np.random.default_rng(1)
    lower, upper = np.clip(robot.q_lower, -np.pi, np.pi), np.clip(robot.q_upper, -np.pi, np.pi)
    for _ in range(20):
        q = rng.uniform(lower, upper)
        dq, ddq = rng.normal(size=robot.nv) * 2.0, rng.normal(size=robot.nv) * 5.0
        data.qpos[mj.qpos_index], data.qvel[mj.dof_index], data.qacc[mj.dof_index] = q, dq, ddq
        mujoco.mj_inverse(model, data)
        expected = robot.rnea(q, dq, ddq)[0]
        np.testing.assert_allclose(
            data.qfrc_inverse[mj.dof_index], expected, rtol=0, atol=1e-10 * np.abs(expected).max()
        )


def test_locked_joint_value_matters(panda):
    """The fingers' lock values enter the model (folded into the joint origins)."""
    other = Robot.from_urdf(
        PANDA_URDF, lock_joints={"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.0}
    )
    q = np.full(panda.nq, 0.3)
    dq, ddq = np.ones(panda.nv), np.ones(panda.nv)
    torques = []
    for robot in (panda, other):
        mj = load_mujoco(robot)
        data = mujoco.MjData(mj.model)
        data.qpos[mj.qpos_index], data.qvel[mj.dof_index], data.qacc[mj.dof_index] = q, dq, ddq
        mujoco.mj_inverse(mj.model, data)
        torques.append(data.qfrc_inverse[mj.dof_index].copy())
        np.testing.assert_allclose(torques[-1], robot.rnea(q, dq, ddq)[0], atol=1e-10)
    assert np.abs(torques[0] - torques[1]).max() > 1e-6


# ----------------------------------------------------------------------------- closed loop
@pytest.mark.parametrize("kind", ["computed_torque", "pd"])
def test_commanded_torque_is_the_truth_model_on_the_simulated_states(kind, ur5):
    t, q, dq, ddq = fourier_reference(ur5)
    config = load_mujoco_measurement(
        {
            **FRICTION,
            "controller": {"kind": kind},
            "encoder_counts_per_rev": 2**18,
            "torque_noise_std": 0.3,
            "n_periods": 1,
        }
    )
    log = simulate(ur5, t, q, dq, ddq, config, rng=0)
    truth = log.truth
    expected = (
        ur5.rnea(log.q_true, log.dq_true, log.ddq_true)
        + truth["viscous"] * log.dq_true
        + truth["coulomb"] * np.sign(log.dq_true)
        + truth["armature"] * log.ddq_true
    )
    scale = np.abs(log.tau_cmd).max()
    np.testing.assert_allclose(log.tau_cmd, expected, rtol=0, atol=1e-12 * scale)
    # ddq is the acceleration MuJoCo integrated: semi-implicit Euler, h = 1 ms
    h = 1.0 / config.rate_hz
    np.testing.assert_allclose(np.diff(log.dq_true, axis=0), h * log.ddq_true[:-1], atol=1e-12)
    np.testing.assert_allclose(np.diff(log.q_true, axis=0), h * log.dq_true[1:], atol=1e-13)
    # the friction and armature are felt: the rigid-body model alone misses them
    rigid = ur5.rnea(log.q_true, log.dq_true, log.ddq_true)
    assert np.abs(log.tau_cmd - rigid).max() > 1.0
    assert np.array_equal(coulomb_law(np.array([-2.0, 0.0, 3.0])), [-1.0, 0.0, 1.0])


def test_truth_with_substeps_and_coarse_reference(ur5):
    t, q, dq, ddq = fourier_reference(ur5, rate_hz=100.0)  # interpolated to 1 kHz
    config = load_mujoco_measurement({**FRICTION, "substeps": 3, "n_periods": 1})
    log = simulate(ur5, t, q, dq, ddq, config, rng=0)
    assert log.n_samples == 500
    expected = (
        ur5.rnea(log.q_true, log.dq_true, log.ddq_true)
        + log.truth["viscous"] * log.dq_true
        + log.truth["coulomb"] * np.sign(log.dq_true)
        + log.truth["armature"] * log.ddq_true
    )
    np.testing.assert_allclose(log.tau_cmd, expected, atol=1e-12 * np.abs(log.tau_cmd).max())
    assert log.tracking_rms().max() < 0.02


@pytest.mark.parametrize(
    ("kind", "max_rms", "median_rms"), [("computed_torque", 0.03, 0.006), ("pd", 0.12, 0.01)]
)
def test_default_gains_track_a_smooth_reference(kind, max_rms, median_rms, ur5, panda):
    """UR5 and Panda, friction and armature unknown to the controller, 2^18-count encoders.

    Measured RMS errors [mrad], joints base to tip:
    computed torque: UR5 0.06 0.21 0.72 1.45 0.55 9.6; Panda 4.3 0.6 4.8 1.6 4.6 5.0 20.7;
    PD: UR5 0.4 2.9 8.5 3.9 0.8 8.6; Panda 69 2.0 79 3.9 5.9 7.3 21.9 (joints 1 and 3 of the
    Panda: their smallest effective inertia along the motion sets their gains).
    The last wrist joints have a nominal inertia 10-50 times below the armature.
    """
    for robot in (ur5, panda):
        t, q, dq, ddq = fourier_reference(robot, period=1.0)
        config = load_mujoco_measurement(
            {
                "friction": {"viscous": 0.5, "coulomb": 1.0},
                "armature": 0.05,
                "encoder_counts_per_rev": 2**18,
                "controller": {"kind": kind},
                "n_periods": 1,
            }
        )
        rms = simulate(robot, t, q, dq, ddq, config).tracking_rms()
        assert rms.max() < max_rms, (robot.name, kind, rms)
        assert np.median(rms) < median_rms, (robot.name, kind, rms)


def test_reference_interpolation_and_period_check(ur5):
    coarse = fourier_reference(ur5, rate_hz=100.0)
    fine = fourier_reference(ur5, rate_hz=1000.0)
    for got, want in zip(reference_at_rate(*coarse, 1000.0), fine[1:], strict=True):
        np.testing.assert_allclose(got, want, atol=1e-5 * np.abs(want).max())
    t, q, dq, ddq = fine
    with pytest.raises(DataError, match="not a whole number of controller periods"):
        reference_at_rate(t[:-1] * 1.0001, q[:-1], dq[:-1], ddq[:-1], 1000.0)
    with pytest.raises(DataError, match="uniformly spaced"):
        reference_at_rate(t**2, q, dq, ddq, 1000.0)


def test_unstable_gains_are_reported(ur5):
    t, q, dq, ddq = fourier_reference(ur5)
    config = load_mujoco_measurement({"controller": {"kd": 5000.0}, "n_periods": 1})
    with pytest.raises(DataError, match="tracking error of joint"):
        simulate(ur5, t, q, dq, ddq, config)


# ----------------------------------------------------------------------------- measurement
def test_encoder_quantization_and_torque_noise(ur5):
    t, q, dq, ddq = fourier_reference(ur5, period=1.0)
    counts, std = 2**16, [0.5, 0.4, 0.3, 0.2, 0.1, 0.05]
    config = load_mujoco_measurement(
        {**FRICTION, "encoder_counts_per_rev": counts, "torque_noise_std": std, "n_periods": 2}
    )
    log = simulate(ur5, t, q, dq, ddq, config, rng=3)
    step = 2.0 * np.pi / counts
    ticks = log.q / step
    np.testing.assert_allclose(ticks, np.round(ticks), rtol=0, atol=1e-6)
    assert np.abs(log.q - log.q_true).max() <= 0.5 * step * (1 + 1e-9)
    measured_std = np.std(log.tau_measured - log.tau_cmd, axis=0)
    np.testing.assert_allclose(measured_std, std, rtol=0.1)
    # the seed draws the noise only: the motion does not depend on it
    again = simulate(ur5, t, q, dq, ddq, config, rng=4)
    assert np.array_equal(again.tau_cmd, log.tau_cmd)
    assert not np.array_equal(again.tau_measured, log.tau_measured)
    assert np.array_equal(
        simulate(ur5, t, q, dq, ddq, config, rng=3).tau_measured, log.tau_measured
    )


def _identify_config(folder, urdf):
    """A full ``ident identify`` config around the written ``log.yaml`` (read by today's loader)."""
    sections = yaml.safe_load((folder / "log.yaml").read_text())
    path = folder / "identify.yaml"
    path.write_text(yaml.safe_dump({"robot": {"urdf": str(urdf)}, **sections}))
    return load_identify_config(path)


def test_written_log_reads_back_bit_identical(tmp_path, ur5):
    t, q, dq, ddq = fourier_reference(ur5)
    config = load_mujoco_measurement(
        {**FRICTION, "encoder_counts_per_rev": 2**17, "torque_noise_std": 0.2, "n_periods": 1}
    )
    log = simulate(ur5, t, q, dq, ddq, config, rng=0)
    files = write_log(tmp_path, log)
    assert files.csv == tmp_path / LOG_CSV
    assert files.yaml.is_file()
    header = files.csv.read_text().splitlines()[0].split(",")
    names = ur5.joint_names
    assert header == ["t", *(f"q_{n}" for n in names), *(f"tau_{n}" for n in names)] + [
        f"tau_cmd_{n}" for n in names
    ]
    table = np.loadtxt(files.csv, delimiter=",", skiprows=1)
    nj = len(names)
    assert np.array_equal(table[:, 0], log.t)
    assert np.array_equal(table[:, 1 : 1 + nj], log.q)
    assert np.array_equal(table[:, 1 + nj : 1 + 2 * nj], log.tau_measured)
    assert np.array_equal(table[:, 1 + 2 * nj :], log.tau_cmd)

    cfg = _identify_config(tmp_path, UR5_URDF)
    read = read_log(cfg.log, cfg.transmission, names)
    assert np.array_equal(read.q, log.q)
    assert np.array_equal(read.tau, log.tau_measured)
    assert np.array_equal(read.t, log.t - log.t[0])
    assert read.sampling_rate_hz == pytest.approx(1000.0, rel=1e-9)


def test_written_current_log_reads_back_as_torque(tmp_path, ur5):
    t, q, dq, ddq = fourier_reference(ur5)
    kt = [10.0, 10.0, 8.0, 3.0, 3.0, 2.5]
    config = load_mujoco_measurement(
        {"current": {"torque_constants": kt}, "torque_noise_std": 0.2, "n_periods": 1}
    )
    log = simulate(ur5, t, q, dq, ddq, config, rng=0)
    np.testing.assert_allclose(log.current * kt, log.tau_measured, rtol=1e-15)
    write_log(tmp_path, log)
    assert "current_shoulder_pan_joint" in (tmp_path / LOG_CSV).read_text().splitlines()[0]
    cfg = _identify_config(tmp_path, UR5_URDF)
    assert cfg.log.torque_unit == "A"
    read = read_log(cfg.log, cfg.transmission, ur5.joint_names)
    np.testing.assert_allclose(read.tau, log.tau_measured, rtol=1e-14, atol=1e-14)


# ----------------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("section", "match"),
    [
        ({"rate_hz": 0.0}, "rate_hz"),
        ({"rate_hz": -1000.0}, "rate_hz"),
        ({"rate_hz": float("inf")}, "rate_hz"),
        ({"friction": {"coulomb": -1.0}}, r"friction\.coulomb.*>= 0 N\*m"),
        ({"friction": {"viscous": [0.1, float("nan")]}}, r"friction\.viscous.*finite"),
        ({"armature": -0.1}, r"armature.*kg\*m\^2"),
        ({"torque_noise_std": [0.1, -0.2]}, "torque_noise_std"),
        ({"controller": {"kp": 0.0}}, r"controller\.kp.*> 0"),
        ({"controller": {"kind": "pid"}}, "controller.kind"),
        ({"current": {"torque_constants": [1.0, 0.0]}}, "torque_constants"),
        ({"encoder_counts_per_rev": 1}, "encoder_counts_per_rev"),
        ({"n_periods": 0}, "n_periods"),
        ({"frictoin": {}}, "did you mean 'friction'"),
    ],
)
def test_invalid_sections_are_config_errors(section, match):
    with pytest.raises(ConfigError, match=match) as info:
        load_mujoco_measurement({"source": "mujoco", **section}, "run.yaml")
    assert str(info.value).startswith("run.yaml: ")


def test_list_lengths_are_checked_against_the_robot(ur5):
    config = load_mujoco_measurement({"friction": {"viscous": [0.1, 0.2]}})
    with pytest.raises(ConfigError, match=r"friction\.viscous has 2 entries, the robot has 6"):
        check_joint_counts(config, 6, joint_names=ur5.joint_names, source="run.yaml")
    t, q, dq, ddq = fourier_reference(ur5)
    with pytest.raises(ConfigError, match="shoulder_pan_joint"):
        simulate(ur5, t, q, dq, ddq, config)
    check_joint_counts(load_mujoco_measurement({"armature": [0.1] * 6}), 6)


# ----------------------------------------------------------------------------- end to end
def test_identify_recovers_friction_and_armature_from_the_written_log(tmp_path, ur5):
    """Today's ``ident identify`` on the written log finds the configured friction and armature.

    A plain (not optimized) 5 s excitation, two logged periods, no noise: measured errors within
    3.5 %. The log starts mid-motion, so the zero-phase filter's edge transients must be trimmed
    (``trim_samples: 500``; with the default 20 the estimates are off by up to 100 %).
    """
    t, q, dq, ddq = fourier_reference(ur5, period=5.0, seed=2)
    log = simulate(ur5, t, q, dq, ddq, load_mujoco_measurement({**FRICTION, "n_periods": 2}))
    write_log(tmp_path, log)
    sections = yaml.safe_load((tmp_path / "log.yaml").read_text())
    sections |= {
        "robot": {"urdf": str(UR5_URDF)},
        "preprocess": {
            "lowpass": {"cutoff_hz": 20.0},
            "torque_lowpass": {"cutoff_hz": 20.0},
            "decimation": [10],
            "velocity_threshold": [0.05] * 6,
            "trim_samples": 500,
        },
        "model": {"offset": False},
        "estimation": {"method": "wls", "essential": {"enabled": False}},
    }
    (tmp_path / "identify.yaml").write_text(yaml.safe_dump(sections))
    estimate = identify(load_identify_config(tmp_path / "identify.yaml")).estimate
    truth = {}
    for j in range(ur5.nv):
        truth[f"fv{j + 1}"] = log.truth["viscous"][j]
        truth[f"fs{j + 1}"] = log.truth["coulomb"][j]
        truth[f"Ia{j + 1}"] = log.truth["armature"][j]  # Ia1, Ia2 merge with inertias
    found = {n: x for n, x in zip(estimate.names, estimate.x, strict=True) if n in truth}
    assert len(found) == 16
    for name, value in found.items():
        assert value == pytest.approx(truth[name], rel=0.05), name
