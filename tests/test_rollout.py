"""Rollout validation of an MJCF (:mod:`ident.identify.assessment.rollout`).

References: the project's closed-loop simulator (:func:`ident.measure.mujoco_sim.simulate`,
its own MuJoCo model from the URDF) for the truth, a hand-written ``mj_step`` loop for the
vectorized rollout, and the simulator's model with its payload (``load_mujoco``).
"""

import copy
from types import SimpleNamespace

import mujoco
import numpy as np
import pytest
from robots import UR5_URDF
from test_mujoco_sim import fourier_reference

from ident.identify.assessment.rollout import (
    NOT_RUN,
    SD_FLOOR,
    RolloutMeasurements,
    held_out_windows,
    identification_windows,
    log_motion_scale,
    motion_scale,
    reference_mjcf,
    rollout_check,
    rollout_score,
    rollout_text,
    window_count,
)
from ident.identify.config import PreprocessConfig
from ident.measure.logs import RobotLog
from ident.measure.mujoco_config import MujocoMeasurement, PayloadConfig
from ident.measure.mujoco_model import load_mujoco
from ident.measure.mujoco_sim import simulate
from ident.model import Robot

ARMATURE = [0.4, 0.4, 0.2, 0.05, 0.05, 0.05]
VISCOUS = [0.8, 0.7, 0.5, 0.2, 0.15, 0.1]
WINDOWS = np.array([[0, 301], [300, 601], [699, 1000]])  # 0.3 s each at 1 kHz


@pytest.fixture(scope="module")
def ur5():
    return Robot.from_urdf(UR5_URDF)


def _simulated(robot, viscous):
    """A noise-free, friction-free closed-loop log of 1 s at 1 kHz (one MuJoCo step per
    sample) and the truth's MJCF written by the identified model's writer."""
    config = MujocoMeasurement.model_validate(
        {
            "source": "mujoco",
            "armature": ARMATURE,
            "friction": {"viscous": viscous, "coulomb": [0.0] * 6},
            "torque_noise_std": 0.0,
            "settle_periods": 0,
            "n_periods": 1,
        }
    )
    log = simulate(robot, *fourier_reference(robot, period=1.0), config, rng=0)
    measured = RolloutMeasurements(log.t, log.q_true, log.dq_true, log.tau_cmd, log.joint_names)
    extras = {
        name: {"rotor_inertia": a, "viscous": v, "coulomb": 0.0}
        for name, a, v in zip(robot.joint_names, ARMATURE, viscous, strict=True)
    }
    return measured, mujoco.MjModel.from_xml_string(reference_mjcf(robot, extras))


@pytest.fixture(scope="module")
def undamped(ur5):
    return _simulated(ur5, [0.0] * 6)


def test_the_truth_replays_its_own_simulation_and_a_heavier_link_does_not(ur5, undamped):
    """Same bodies and armature, same Euler step: the rollout replays the simulator's states
    to float round-off (J = 1.8e-30 measured). With viscous friction the simulator integrates
    it explicitly and the MJCF implicitly (MuJoCo's Euler default): J = 6.7e-7 measured, the
    integrators' difference; a forearm 20 % heavier gives J = 9.3e-3, no armature J = 1.9."""
    measured, truth = undamped
    assert rollout_score(truth, measured, WINDOWS).objective < 1e-20
    damped_log, damped_truth = _simulated(ur5, VISCOUS)
    damped = rollout_score(damped_truth, damped_log, WINDOWS).objective
    assert 1e-9 < damped < 1e-5  # the integrators' difference, not zero
    heavier = mujoco.MjModel.from_xml_string(reference_mjcf(ur5, None))  # no armature
    heavy = rollout_score(heavier, measured, WINDOWS).objective
    body = mujoco.mj_name2id(truth, mujoco.mjtObj.mjOBJ_BODY, "forearm_link")
    truth_heavy = _copy(truth)
    truth_heavy.body_mass[body] *= 1.2
    heavy_link = rollout_score(truth_heavy, measured, WINDOWS).objective
    assert heavy_link > 100.0 * damped
    assert heavy > heavy_link  # no armature at all: worse still


def _copy(model):
    return copy.copy(model)


def _hand_rollout(model, measured, start, stop, substeps):
    """``J`` of one window by a plain loop: set the state, hold each torque over ``substeps``
    ``mj_step`` calls, compare at every following sample (the module docstring's formula: the
    errors over the standard deviations of the whole log ``measured``, not the window's)."""
    model = _copy(model)
    model.opt.timestep = (measured.t[1] - measured.t[0]) / substeps
    data = mujoco.MjData(model)
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in measured.joint_names]
    qpos, dof = model.jnt_qposadr[ids], model.jnt_dofadr[ids]
    data.qpos[qpos], data.qvel[dof] = measured.q[start], measured.dq[start]
    q_hat, dq_hat = [], []
    for k in range(start, stop - 1):
        data.qfrc_applied[dof] = measured.tau[k]
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        q_hat.append(data.qpos[qpos].copy())
        dq_hat.append(data.qvel[dof].copy())
    q, dq = measured.q[start:stop], measured.dq[start:stop]
    e_q = (np.array(q_hat) - q[1:]) / np.maximum(measured.q.std(axis=0), SD_FLOOR)
    e_dq = (np.array(dq_hat) - dq[1:]) / np.maximum(measured.dq.std(axis=0), SD_FLOOR)
    return 0.5 * (np.mean(e_q**2) + np.mean(e_dq**2))


@pytest.mark.parametrize("substeps", [1, 3])
def test_one_window_equals_a_hand_written_mj_step_loop(ur5, undamped, substeps):
    """With damping and friction loss (constraints, implicit damping) and the torque held over
    several substeps: the vectorized rollout is the plain loop to round-off."""
    measured, _ = undamped
    extras = {
        name: {"rotor_inertia": a, "viscous": v, "coulomb": 0.5}
        for name, a, v in zip(ur5.joint_names, ARMATURE, VISCOUS, strict=True)
    }
    model = mujoco.MjModel.from_xml_string(reference_mjcf(ur5, extras))
    window = WINDOWS[1]
    got = rollout_score(model, measured, window[None, :], substeps=substeps)
    expected = _hand_rollout(model, measured, *window, substeps)
    assert expected > 1e-6  # the friction-free log is not this model's: a real comparison
    np.testing.assert_allclose(got.objective, expected, rtol=1e-12)
    assert got.timestep_s == pytest.approx(1e-3 / substeps, rel=1e-9)


def test_the_score_does_not_depend_on_the_window_order(ur5, undamped):
    measured, _ = undamped
    model = mujoco.MjModel.from_xml_string(reference_mjcf(ur5, None))
    score = rollout_score(model, measured, WINDOWS)
    order = [2, 0, 1]
    shuffled = rollout_score(model, measured, WINDOWS[order])
    np.testing.assert_allclose(shuffled.per_window, score.per_window[order], rtol=1e-12)
    np.testing.assert_allclose(shuffled.objective, score.objective, rtol=1e-12)
    assert score.objective > 0.1  # no armature: clearly off, so the check has teeth


# Two independent unit-inertia wheels without gravity or damping: ddq = tau.
WHEELS = """<mujoco><option gravity="0 0 0"/><worldbody>
<body name="a"><joint name="a" type="hinge" axis="0 0 1"/>
 <inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body>
<body name="b"><joint name="b" type="hinge" axis="0 0 1"/>
 <inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>"""


def test_a_joint_at_rest_in_the_scored_windows_does_not_dominate_j():
    """The scale is the whole log's motion: joint b swings in the first second and rests in the
    second, the scored one, where a small torque (1 mN*m, a friction the model lacks) makes
    the model creep 1.25e-4 rad per 0.5 s window. Over the log's motion (sd of b's q and dq:
    0.25 rad, 1.57 rad/s) J is small (2.5e-6 measured, mostly a's Euler steps); over the
    scored windows' own (0, floored at SD_FLOOR) it would be 2.2e4: a wrist at rest
    dominating the score."""
    t = np.arange(2001) / 1000.0
    w = 2.0 * np.pi
    swing = t < 1.0
    q = np.column_stack([np.sin(w * t), np.where(swing, 0.5 * np.sin(w * t), 0.0)])
    dq = np.column_stack([w * np.cos(w * t), np.where(swing, 0.5 * w * np.cos(w * t), 0.0)])
    tau = np.column_stack([-(w**2) * np.sin(w * t), np.where(swing, 0.0, 1e-3)])
    measured = RolloutMeasurements(t, q, dq, tau, ("a", "b"))
    held = np.array([[1000, 1501], [1500, 2001]])
    model = mujoco.MjModel.from_xml_string(WHEELS)
    j = rollout_score(model, measured, held).objective
    scale = np.maximum([q.std(axis=0), dq.std(axis=0)], SD_FLOOR)  # the whole log's
    np.testing.assert_allclose(measured.sd(), scale, rtol=1e-12)
    assert j < 1e-4
    rows = np.r_[1000:2001]
    windows_own = RolloutMeasurements(t, q, dq, tau, ("a", "b"), motion_scale(q[rows], dq[rows]))
    assert rollout_score(model, windows_own, held).objective > 1e3


@pytest.mark.parametrize("link", [None, "ee_link"])  # the last moving link, a welded link
def test_the_truth_with_a_payload_is_the_simulators_model(ur5, link):
    """The reference MJCF with the simulator's payload has the simulator's inverse dynamics
    (its payload added by MuJoCo's spec, :func:`load_mujoco`)."""
    payload = PayloadConfig(
        mass=2.0, com=[0.01, -0.02, 0.05], inertia=[0.01, 0, 0.02, 0, 0, 0.015], link=link
    )
    ours = mujoco.MjModel.from_xml_string(reference_mjcf(ur5, None, (link, payload.parameters())))
    sim = load_mujoco(ur5, payload=payload)
    q, dq, ddq = ur5.random_configurations(5, rng=3)
    torques = []
    for model, names in ((ours, ur5.joint_names), (sim.model, ur5.joint_names)):
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
        ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, n) for n in names]
        data = mujoco.MjData(model)
        out = []
        for k in range(q.shape[0]):
            data.qpos[model.jnt_qposadr[ids]] = q[k]
            data.qvel[model.jnt_dofadr[ids]] = dq[k]
            data.qacc[model.jnt_dofadr[ids]] = ddq[k]
            mujoco.mj_inverse(model, data)
            out.append(data.qfrc_inverse[model.jnt_dofadr[ids]].copy())
        torques.append(np.array(out))
    scale = np.abs(torques[1]).max()
    np.testing.assert_allclose(torques[0], torques[1], rtol=0.0, atol=1e-12 * scale)


def _two_segment_log(states):
    """Two segments at 1 kHz with a gap: samples 0-1499 (t 0..1.499 s) and 1500-2599
    (t 5.0..6.099 s), smooth signals; measured ``dq``/``ddq`` when ``states``."""
    t = np.concatenate([np.arange(1500), 5000 + np.arange(1100)]) / 1000.0
    q = np.column_stack([np.sin(3.0 * t), np.cos(2.0 * t)])
    dq = np.column_stack([3.0 * np.cos(3.0 * t), -2.0 * np.sin(2.0 * t)])
    return RobotLog(
        t=t,
        q=q,
        tau=np.column_stack([t, -t]),
        sampling_rate_hz=1000.0,
        joint_names=("a", "b"),
        segments=((0, 1500), (1500, 2600)),
        dq=dq if states else None,
        ddq=np.zeros_like(q) if states else None,
    )


def _result(log, held_out, pp):
    """What :func:`held_out_windows` reads of an identification."""
    config = SimpleNamespace(
        preprocess=pp, validation=SimpleNamespace(identify_fraction=0.7), robot=None
    )
    return SimpleNamespace(
        log=log, t_validate=log.t[held_out], config=config, joint_names=log.joint_names
    )


NO_FILTER = PreprocessConfig(lowpass=None, decimation=[], trim_samples=0)


def test_windows_come_from_the_held_out_part_capped_and_spread():
    """Held out: samples 1100-1480 (step 10, as decimated) and 2300-2590. Windows of 0.1 s
    (101 samples, sharing their ends): 1100, 1200, 1300 and 2300, 2400; four of the five
    spread evenly: 1100, 1200, 2300, 2400. Measured states and no filter: the samples as
    logged."""
    log = _two_segment_log(states=True)
    held = np.r_[1100:1481:10, 2300:2591:10]
    measured, windows = held_out_windows(_result(log, held, NO_FILTER), 0.1, max_windows=4)
    starts = [1100, 1200, 2300, 2400]
    np.testing.assert_array_equal(windows, [[101 * k, 101 * (k + 1)] for k in range(4)])
    index = np.concatenate([np.arange(s, s + 101) for s in starts])
    for got, logged in ((measured.t, log.t), (measured.q, log.q), (measured.dq, log.dq)):
        np.testing.assert_array_equal(got, logged[index])
    # J's scale: the whole log's motion (both segments, both parts), not the windows'
    whole = [log.q.std(axis=0), log.dq.std(axis=0)]
    np.testing.assert_allclose(measured.scale, whole, rtol=1e-12)
    assert not np.allclose(motion_scale(measured.q, measured.dq), whole, rtol=0.01)


def test_identification_windows_overlap_outside_the_held_out_part_and_are_counted():
    """The same log: identification part 0-1098 and 1500-2298 (the samples next to the held-out
    ones dropped, the ends after it too short). Windows of 101 samples start every 20 (a fifth
    of a window): 50 and 35 candidates; four spread evenly: candidates 0, 28, 56, 84, i.e.
    samples 0, 560, 1620, 2180. window_count gives both parts' counts without filtering (a
    count of disjoint windows, 9 + 7, or of 64 would not match)."""
    log = _two_segment_log(states=True)
    result = _result(log, np.r_[1100:1481:10, 2300:2591:10], NO_FILTER)
    measured, windows = identification_windows(result, 0.1, max_windows=4)
    index = np.concatenate([np.arange(s, s + 101) for s in (0, 560, 1620, 2180)])
    np.testing.assert_array_equal(measured.t, log.t[index])
    np.testing.assert_array_equal(windows, [[101 * k, 101 * (k + 1)] for k in range(4)])
    assert window_count(result, "identification", 0.1, max_windows=4) == 4
    assert window_count(result, "identification", 0.1, max_windows=1000) == 85
    assert window_count(result, "held-out", 0.1) == 5
    assert window_count(result, "held-out", 0.1, max_windows=4) == 4


def test_window_signals_are_the_identifications_low_pass_and_differences():
    """Filtered on the window and its margins, as the chunks are: equal to the whole
    segment filtered then differentiated (the in-memory path), away from the segment's ends."""
    from ident.identify.config import FilterConfig
    from ident.identify.estimation import preprocess

    log = _two_segment_log(states=False)
    pp = NO_FILTER.model_copy(
        update={
            "lowpass": FilterConfig(cutoff_hz=20.0),
            "torque_lowpass": FilterConfig(cutoff_hz=20.0),
        }
    )
    measured, windows = held_out_windows(_result(log, np.r_[400:1101], pp), 0.2)
    q, _ = preprocess.lowpass(log.q[:1500], 1000.0, 20.0, 4)
    dq = preprocess.differentiate(q, 1000.0)[0]
    tau, _ = preprocess.lowpass(log.tau[:1500], 1000.0, 20.0, 4, what="tau")
    index = np.concatenate([np.arange(s, s + 201) for s in (400, 600, 800)])
    assert windows.shape == (3, 2)
    np.testing.assert_allclose(measured.q, q[index], rtol=0, atol=1e-12)
    np.testing.assert_allclose(measured.dq, dq[index], rtol=0, atol=1e-9)
    np.testing.assert_allclose(measured.tau, tau[index], rtol=0, atol=1e-12)
    # the scale: every segment's q, dq filtered and differentiated as the identification does
    # them (trim_samples 0), both parts; the training windows carry the same
    q2, _ = preprocess.lowpass(log.q[1500:], 1000.0, 20.0, 4)
    dq2 = preprocess.differentiate(q2, 1000.0)[0]
    qs, dqs = np.vstack([q, q2]), np.vstack([dq, dq2])
    np.testing.assert_allclose(measured.scale, [qs.std(axis=0), dqs.std(axis=0)], rtol=1e-9)
    train, _ = identification_windows(_result(log, np.r_[400:1101], pp), 0.2)
    np.testing.assert_array_equal(train.scale, measured.scale)
    np.testing.assert_array_equal(log_motion_scale(_result(log, [], pp)), measured.scale)


def test_log_scale_by_blocks_equals_the_whole_segments(monkeypatch):
    """An hour's log is filtered for the scale by blocks with the chunks' margins, their
    moments combined: the same scale as each whole segment filtered at once (a block pass
    that dropped its margins, or summed the blocks' variances without their means' spread,
    would differ)."""
    from ident.identify.assessment import rollout
    from ident.identify.config import FilterConfig

    log = _two_segment_log(states=False)
    pp = NO_FILTER.model_copy(update={"lowpass": FilterConfig(cutoff_hz=20.0)})
    whole = log_motion_scale(_result(log, [], pp))
    monkeypatch.setattr(rollout, "SCALE_BLOCK_SAMPLES", 137)  # 11 blocks per segment
    blocks = log_motion_scale(_result(log, [], pp))
    np.testing.assert_allclose(blocks, whole, rtol=1e-9)


def test_a_check_that_cannot_run_says_why(tmp_path):
    log = _two_segment_log(states=True)
    short = _result(log, np.r_[1450:1500], NO_FILTER)  # 50 ms held out
    entry = rollout_check(short, tmp_path / "model.xml", "nominal", lambda robot: ("", 0, 1))
    assert entry["objective"] is None
    assert entry["reference"] == "nominal"
    assert entry["note"].startswith(f"{NOT_RUN}: the held-out part of the log is shorter")
    assert rollout_text(entry) == entry["note"]
    enough = _result(log, np.r_[900:1500], NO_FILTER)
    entry = rollout_check(enough, tmp_path / "model.xml", "nominal", lambda robot: ("", 0, 1))
    assert entry["note"].startswith(f"{NOT_RUN}: ")
    assert "cannot load the MJCF" in entry["note"]
