"""Position servos that log no torque (``actuator: {kind: position}``).

References: closed forms (the delayed command, the homogeneous fit of exact synthetic rows),
MuJoCo's own ``<position>`` actuator (the simulated log and the written MJCF's force), and the
simulator's truth (gains, velocity gains plus damping, armature, friction loss, the URDF).
"""

import dataclasses
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ident.dynamics.actuators import saturated_samples, servo_error
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model
from ident.errors import ConfigError, DataError
from ident.identify.actuators import servo_fit
from ident.identify.actuators.servo_fit import Scale, ServoFit, scaled_fit, shared_share
from ident.identify.assessment.rollout import RolloutMeasurements, rollout_score
from ident.identify.config import load_identify_config
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.model_files.files import model_files
from ident.identify.pipeline.real import identify
from ident.measure.logs import read_log
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate, write_log
from ident.model import Robot
from ident.run import init_servo

# Two links on parallel horizontal axes: gravity loads both, the joints share link 2's terms.
ARM = """<robot name="arm2"><link name="base"/>
<link name="l1"><inertial><origin xyz="0.2 0 0.01"/><mass value="2.0"/>
 <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.03"/></inertial></link>
<link name="l2"><inertial><origin xyz="0.15 0 -0.01"/><mass value="1.0"/>
 <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.012" iyz="0" izz="0.012"/></inertial></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 1 0"/>
 <limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.4 0 0"/>
 <axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="100" velocity="10"/></joint></robot>"""

RATE = 500.0
KP, KV = np.array([60.0, 30.0]), np.array([1.5, 0.8])
DAMPING, COULOMB, ARMATURE = np.array([0.3, 0.2]), np.array([0.4, 0.2]), np.array([0.05, 0.05])
FORCERANGE, DELAY_STEPS = 10.4, 2


def _reference(n_joints: int, period: float, amplitude: float, seed: int, fast: tuple = ()):
    """A smooth periodic reference (3 harmonics, then the harmonics ``fast`` of velocity
    amplitude up to 0.3 rad/s) at RATE: t, q, dq, ddq."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(period * RATE))) / RATE
    w = 2.0 * np.pi / period
    q, dq, ddq = (np.zeros((t.size, n_joints)) for _ in range(3))
    for h in (1, 2, 3, *fast):
        a, b = rng.uniform(-amplitude, amplitude, (2, n_joints)) / h
        if h > 3:
            a, b = a * 0.3 * h / amplitude, b * 0.3 * h / amplitude
        phase = w * h * t[:, None]
        q += (a * np.sin(phase) - b * np.cos(phase)) / (w * h)
        dq += a * np.cos(phase) + b * np.sin(phase)
        ddq += (-a * np.sin(phase) + b * np.cos(phase)) * w * h
    return t, q, dq, ddq


@pytest.fixture(scope="module")
def servo_log(tmp_path_factory):
    """The arm's servos simulated by MuJoCo (friction loss, damping, armature, a force range
    the first joint reaches, a 2-step command delay), logged without torque: the folder, the
    robot and the simulated log."""
    folder = tmp_path_factory.mktemp("servo")
    (folder / "arm2.urdf").write_text(ARM)
    robot = Robot.from_urdf(folder / "arm2.urdf")
    actuator = {"kind": "position", "kp": KP.tolist(), "kv": KV.tolist()}
    actuator |= {"forcerange": FORCERANGE, "delay_steps": DELAY_STEPS}
    friction = {"viscous": DAMPING.tolist(), "coulomb": COULOMB.tolist(), "semantics": "mujoco"}
    measurement = load_mujoco_measurement(
        {"rate_hz": RATE, "friction": friction, "armature": ARMATURE.tolist()}
        | {"actuator": actuator, "settle_periods": 1, "n_periods": 2}
    )
    log = simulate(robot, *_reference(2, 3.0, 2.0, 1), measurement, rng=0)
    write_log(folder, log)
    return folder, robot, log


def _config(folder: Path, actuator: dict, *, drop: str = "torque", **more) -> Path:
    """An identify config of the servo log, its ``log.<drop>`` removed (``command`` named)."""
    section = yaml.safe_load((folder / "log.yaml").read_text())["log"]
    section["command"] = {"columns": ["q_cmd_j1", "q_cmd_j2"]}
    section.pop(drop, None)
    cfg = {
        "robot": {"urdf": "arm2.urdf"},
        "log": section,
        "actuator": actuator,
        # the velocity threshold drops the friction loss's stiction (no sign(dq) law there)
        "preprocess": {"lowpass": {"cutoff_hz": 20.0}, "trim_samples": 50, "decimation": [5]}
        | {"velocity_threshold": [0.1, 0.1]},
        "model": {"offset": False},
        "validation": {"identify_fraction": 0.8},
        "urdf_update": {"model": "none"},
    } | more
    path = folder / f"identify-{len(list(folder.glob('identify-*.yaml')))}.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


def _true_base(robot: Robot, names: tuple[str, ...]) -> np.ndarray:
    """The simulator's base parameters: the URDF's bodies, the armature as rotor inertia, the
    servo's kv plus MuJoCo's damping as viscous friction, the friction loss as Coulomb's."""
    terms = ExtraTerms.from_options(2, offset=False)
    pm = build_parameter_model(robot.model, terms)
    theta = pm.nominal.copy()
    for j in range(2):
        for kind, values in (("Ia", ARMATURE), ("fv", KV + DAMPING), ("fs", COULOMB)):
            theta[pm.names.index(f"{kind}{j + 1}")] = values[j]
    assert pm.base_names == names
    return pm.base.project(theta)


def _errors(result, robot: Robot) -> dict[str, float]:
    """Relative errors [%] of kp, kd + fv and every base parameter."""
    fit = result.actuator
    est = result.estimate
    truth = _true_base(robot, est.names)
    out = {f"kp{j + 1}": 100 * abs(fit.kp[j] / KP[j] - 1) for j in range(2)}
    out |= {f"kd+fv{j + 1}": 100 * abs(fit.damping[j] / (KV + DAMPING)[j] - 1) for j in range(2)}
    out |= {n: 100 * abs(x / t - 1) for n, x, t in zip(est.names, est.x, truth, strict=True)}
    return out


# ----------------------------------------------------------------------------- closed forms
def test_servo_error_delays_the_command_by_whole_samples_within_each_segment():
    q = np.zeros((7, 1))
    q_cmd = np.arange(7.0)[:, None]
    e = servo_error(q, q_cmd, 2, [(0, 4), (4, 7)])
    # each segment holds its first command for its first 2 samples
    assert e[:, 0].tolist() == [0, 0, 0, 1, 4, 4, 4]
    assert np.array_equal(servo_error(q, q_cmd, 0, [(0, 7)]), q_cmd)
    # a fraction of a sample: the period's mean of the two commands it straddles
    half = servo_error(q, q_cmd, 2.25, [(0, 7)])[:, 0]
    assert half.tolist() == [0, 0, 0, 0.75, 1.75, 2.75, 3.75]


def test_saturation_test_brackets_the_unknown_kd():
    """``kd`` lies in ``[0, kd + fv]``: a sample is saturated when either end reaches the
    range (here only the end with the whole damping does)."""
    e, dq = np.array([[0.1], [0.1], [0.0]]), np.array([[-2.0], [2.0], [0.0]])
    got = saturated_samples(e, dq, np.array([10.0]), np.array([1.0]), np.array([2.5]))
    assert got[:, 0].tolist() == [True, False, False]  # |1 + 2| = 3 >= 0.98 * 2.5


def test_scaled_fit_recovers_gains_and_parameters_of_exact_homogeneous_rows():
    """``W_j beta = kp_j e_j`` exactly (random rows): with ``beta_0`` fixed at its true value
    (one equality, as the URDF's mass fixes a combination) the fit returns every ``beta`` and
    ``kp`` to round-off, and with ``kp`` given, ``beta``."""
    rng = np.random.default_rng(3)
    n, nv, p = 400, 3, 5
    W = rng.standard_normal((n, nv, p))
    W[:, :, 0] += 2.0
    beta, kp = rng.uniform(0.5, 2.0, p), np.array([40.0, 25.0, 8.0])
    e = (W @ beta) / kp
    red = ReducedObservations.from_samples(W, e)
    names = tuple(f"b{i}" for i in range(p))
    offset = np.zeros(p + nv)
    offset[0] = beta[0]
    basis = np.delete(np.eye(p + nv), 0, axis=1)
    pinned = Scale("mass", offset, basis, names[1:] + ("k1", "k2", "k3"), "beta_0")
    fit = scaled_fit(red, pinned, "ols")
    np.testing.assert_allclose(fit.u, np.concatenate([beta, kp]), rtol=1e-10)
    assert fit.relative_residual < 1e-10
    assert fit.covariance.shape == (p + nv, p + nv)
    fixed = np.concatenate([np.zeros(p), kp])
    given = Scale("kp", fixed, np.vstack([np.eye(p), np.zeros((nv, p))]), names, "kp")
    np.testing.assert_allclose(scaled_fit(red, given, "wls").u[:p], beta, rtol=1e-10)


def test_shared_share_is_the_torque_of_the_columns_other_joints_also_carry():
    """Joint 1 carries columns 0 and 1, joint 2 columns 1 and 2: column 1 ties them."""
    rng = np.random.default_rng(4)
    W = rng.standard_normal((300, 2, 3))
    W[:, 0, 2] = W[:, 1, 0] = 0.0
    beta = np.array([1.0, 0.2, 3.0])
    red = ReducedObservations.from_samples(W, W @ beta)
    tau = W @ beta
    expected = np.linalg.norm(W[:, :, 1] * beta[1], axis=0) / np.linalg.norm(tau, axis=0)
    np.testing.assert_allclose(shared_share(red, beta), expected, rtol=1e-10)


# ----------------------------------------------------------------------------- ticked encoders
@pytest.fixture(scope="module")
def ticked(tmp_path_factory):
    """The arm's servos simulated as :func:`servo_log`'s (no force range), its motion with 2
    and 3 Hz harmonics (the torque's rate of change tells the delay from ``kd``), read by
    4096-tick encoders (1.5 mrad, an SO-101's STS3215), as ``ident identify`` reads it: the
    config (delay scanned over 0..8 ms, the scale from the URDF's gravity load), the robot and
    the log."""
    folder = tmp_path_factory.mktemp("ticked")
    (folder / "arm2.urdf").write_text(ARM)
    robot = Robot.from_urdf(folder / "arm2.urdf")
    # no force range: the fast motion would saturate joint 1 on 15 % of the samples, whose
    # exclusion moves the delay by up to half a sample (not this test's subject)
    actuator = {"kind": "position", "kp": KP.tolist(), "kv": KV.tolist()}
    actuator |= {"delay_steps": DELAY_STEPS}
    friction = {"viscous": DAMPING.tolist(), "coulomb": COULOMB.tolist(), "semantics": "mujoco"}
    measurement = load_mujoco_measurement(
        {"rate_hz": RATE, "friction": friction, "armature": ARMATURE.tolist()}
        | {"actuator": actuator, "settle_periods": 1, "n_periods": 2}
        | {"encoder_counts_per_rev": 4096}
    )
    write_log(folder, simulate(robot, *_reference(2, 3.0, 2.0, 1, (6, 9)), measurement, rng=0))
    actuator = {"kind": "position", "max_delay_s": 0.008}
    # 8 Hz: the ticks' noise out of the accelerations (the SO-101 example's setting)
    preprocess = {"lowpass": {"cutoff_hz": 8.0}, "trim_samples": 100, "decimation": [5]}
    preprocess |= {"velocity_threshold": [0.1, 0.1]}
    cfg = load_identify_config(_config(folder, actuator, preprocess=preprocess))
    log = read_log(cfg.log, cfg.transmission, list(robot.joint_names), source="test")
    return cfg, robot, log


def test_delay_under_4096_ticks_is_the_planted_two_samples(ticked):
    """A one-sample shift of the command changes ``kp e`` by about ``-kp h (dq + de/dt)``: a
    change of ``kd`` by ``kp h`` (10 % of ``kd + fv`` of joint 1 here) plus the torque's rate
    of change. With the ticks' noise in ``e`` unfiltered the scan's residuals barely differ;
    filtered like the positions, the scan and its refinement find the planted 2 samples.

    Measured: 2.00 samples; kp 0.1 %, kd + fv 0.2 %."""
    cfg, robot, log = ticked
    _, _, fit = servo_fit.servo_log(cfg, robot.model, log)
    assert fit.delay_auto
    assert fit.delay_candidates[0] == 0.0
    assert len(fit.delay_candidates) > 5  # 0..4 and the refined one
    assert abs(fit.delay_samples - DELAY_STEPS) < 0.1, fit.delay_residuals
    np.testing.assert_allclose(fit.damping, KV + DAMPING, rtol=0.02)
    # the refined delay's fit, mixed from its whole neighbours' reductions (between_delays),
    # is the fit of the log at that delay given (the log's rows reduced at it directly)
    given = cfg.actuator.model_copy(update={"delay": fit.delay_s})
    _, _, direct = servo_fit.servo_log(cfg.model_copy(update={"actuator": given}), robot.model, log)
    assert direct.delay_samples == pytest.approx(fit.delay_samples, abs=1e-12)
    np.testing.assert_allclose(fit.kp, direct.kp, rtol=1e-9)
    np.testing.assert_allclose(fit.damping, direct.damping, rtol=1e-9)
    assert fit.relative_residual == pytest.approx(direct.relative_residual, rel=1e-9)


def test_gains_from_the_urdf_gravity_load_under_4096_ticks(ticked):
    """``scale_from: mass``: the gravity torques' combinations held at the URDF's fix ``kp``
    (both joints carry gravity, none named undetermined); tied by ``equal_kp`` (wrongly here:
    60 and 30 N*m/rad), the two gains are one number and the residual grows.

    Measured: kp within 0.3 %."""
    cfg, robot, log = ticked
    _, _, fit = servo_fit.servo_log(cfg, robot.model, log)
    np.testing.assert_allclose(fit.kp, KP, rtol=0.02)
    assert np.all(fit.kp_std > 0)
    assert fit.gravity_load is not None
    assert not any("carry (almost) none" in text for text in fit.undetermined())
    tied = cfg.model_copy(
        update={"actuator": cfg.actuator.model_copy(update={"equal_kp": [["j1", "j2"]]})}
    )
    _, _, one = servo_fit.servo_log(tied, robot.model, log)
    # one number, near joint 1's (its gravity load, 7.9 N*m rms, is 6.6 times joint 2's);
    # a wrong tie shows in the residual
    assert one.kp[0] == one.kp[1]
    assert abs(one.kp[0] / KP[0] - 1) < 0.05
    assert one.relative_residual > 2.0 * fit.relative_residual


# ----------------------------------------------------------------------------- end to end
@pytest.mark.slow
@pytest.mark.parametrize("scale", ["mass", "kp"])
def test_servo_log_without_torque_identifies_gains_delay_and_parameters(servo_log, scale):
    """``ident identify`` on the servo log with its torque dropped: the gain from the URDF's
    mass (or given), ``kd + fv``, the 2-step delay (scanned over 0..4 samples) and the base
    parameters against the simulator's truth; every sample where the simulated servo sat at
    its force range is excluded.

    Measured: scale from the mass: kp within 0.05 %, kd + fv within 0.1 %, base parameters
    within 2.2 % (Ia2, biased by ``(kd + fv) h / 2``: the central difference of MuJoCo's
    semi-implicit Euler positions is the velocity half a step later); kp given: the same.
    """
    folder, robot, log = servo_log
    actuator = {"kind": "position", "forcerange": FORCERANGE, "max_delay_s": 0.008}
    if scale == "kp":
        actuator["kp"] = KP.tolist()
    estimates = []
    result = identify(load_identify_config(_config(folder, actuator)), on_estimate=estimates.append)
    fit = result.actuator
    # the job's estimate counts the servo's passes over the log: 5 delays, then 3 rounds of
    # 3, and 4 refinements of 2 (the differences of the best delay's neighbours)
    assert any(e.what.endswith(", 22 servo fits first") for e in estimates)
    errors = _errors(result, robot)
    report = ", ".join(f"{k} {v:.3f} %" for k, v in errors.items())
    print(f"servo fit (scale from {scale}): delay {fit.delay_samples} samples; {report}")
    # refined to a fraction: the saturated samples' exclusion leaves it within a quarter
    assert abs(fit.delay_samples - DELAY_STEPS) < 0.25, fit.delay_residuals
    assert fit.delay_candidates[0] <= 1
    assert fit.delay_candidates[-1] >= 3
    # well inside 2 % and 5 %: the scale fixed by a combination that holds a rotor inertia
    # (its URDF value 0, Ia1 = 0.05 here) put every kp and kd + fv 0.53 % off
    assert max(errors["kp1"], errors["kp2"]) < 0.3, report
    assert max(errors["kd+fv1"], errors["kd+fv2"]) < 0.4, report
    assert max(v for k, v in errors.items() if not k.startswith(("kp", "kd"))) < 4.0, report
    if scale == "kp":
        assert np.array_equal(fit.kp, KP)
        assert np.isnan(fit.kp_std).all()
    else:
        assert np.all(fit.kp_std > 0)
        assert np.all(fit.kp_std < 0.01 * KP)
    truly = np.abs(log.tau_actuator) >= FORCERANGE - 1e-9  # the simulator's saturation
    assert truly[:, 0].sum() > 100
    assert not truly[:, 1].any()
    assert fit.n_saturated[0] >= truly[:, 0].sum()
    assert fit.n_saturated[1] == 0
    assert fit.n_excluded >= truly.any(axis=1).sum()
    assert "kd + fv" in " ".join(fit.undetermined())


# ----------------------------------------------------------------------------- written model
def test_identified_mjcf_servo_force_is_kp_times_the_error(servo_log):
    """The MJCF of a servo identification: MuJoCo's force of each ``<position>`` actuator is
    ``kp (ctrl - q)`` clipped to the range, and the joint damping holds ``kd + fv``."""
    folder, robot, _ = servo_log
    pm = build_parameter_model(robot.model, ExtraTerms.from_options(2, offset=False))
    theta = pm.nominal.copy()
    theta[pm.names.index("fv1")] = 1.8
    servos = {"j1": {"kp": 61.5, "forcerange": 3.0}, "j2": {"kp": 29.25, "forcerange": None}}
    files = model_files(robot, theta, pm.names, position_servos=servos)
    model = mujoco.MjModel.from_xml_string(files.mjcf)
    data = mujoco.MjData(model)
    data.qpos[:] = [0.1, -0.2]
    data.ctrl[:] = [0.2, 0.3]
    mujoco.mj_forward(model, data)
    np.testing.assert_allclose(data.actuator_force, [3.0, 29.25 * 0.5], rtol=1e-12)
    assert model.dof_damping[0] == pytest.approx(1.8)
    extras = yaml.safe_load(files.extras_json)
    assert extras["position_servos"]["joints"]["j1"] == {"kp": 61.5, "forcerange": 3.0}


def test_rollout_of_a_servo_mjcf_is_driven_by_the_measured_torques_alone(servo_log):
    """The rollout check applies the measured torques; a servo MJCF's <position> actuators
    (ctrl 0) are switched off, so it scores as the same model without them (exactly)."""
    folder, robot, _ = servo_log
    pm = build_parameter_model(robot.model, ExtraTerms.from_options(2, offset=False))
    theta = pm.nominal.copy()
    theta[pm.names.index("fv1")] = 1.8
    servos = {"j1": {"kp": 60.0, "forcerange": 10.0}, "j2": {"kp": 30.0, "forcerange": None}}
    plain = mujoco.MjModel.from_xml_string(model_files(robot, theta, pm.names).mjcf)
    text = model_files(robot, theta, pm.names, position_servos=servos).mjcf
    model = mujoco.MjModel.from_xml_string(text)
    assert model.nu == 2
    dt, n = 1e-3, 201
    plain.opt.timestep = dt
    data = mujoco.MjData(plain)
    t = np.arange(n) * dt
    tau = np.column_stack([9.0 + 2.0 * np.sin(5 * t), 0.5 * np.cos(7 * t)])
    q, dq = np.zeros((n, 2)), np.zeros((n, 2))
    for k in range(n):
        q[k], dq[k] = data.qpos, data.qvel
        data.qfrc_applied[:] = tau[k]
        mujoco.mj_step(plain, data)
    measured = RolloutMeasurements(t, q, dq, tau, ("j1", "j2"))
    windows = np.array([[0, 100], [100, 200]])
    alone = rollout_score(plain, measured, windows).objective
    assert alone < 1e-20
    assert rollout_score(model, measured, windows).objective == pytest.approx(alone, abs=1e-20)


# ----------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("actuator", "drop", "match"),
    [
        ({"kind": "position"}, "command", r"log\.command is missing"),
        ({"kind": "position"}, "nothing", r"log\.torque: actuator\.kind: position"),
        ({"kind": "motor"}, "torque", r"log\.torque is missing"),
        ({"kind": "position", "scale_from": "kp"}, "torque", r"scale_from: kp needs"),
        ({"kind": "motor", "kp": 3.0}, "nothing", r"actuator\.kp is an option of kind"),
        ({"kind": "servo"}, "torque", r"allowed: motor, position"),
        ({"kind": "position", "delay": 0.2}, "torque", r"actuator\.delay = 0\.2 s"),
        ({"kind": "position", "kp": 3.0, "equal_kp": [["j1", "j2"]]}, "torque", r"equal_kp ties"),
        ({"kind": "position", "equal_kp": [["j1"]]}, "torque", r"two or more joint names"),
    ],
)
def test_bad_actuator_sections_are_one_line_config_errors(servo_log, actuator, drop, match):
    folder, _, _ = servo_log
    path = _config(folder, actuator, drop=drop)
    if drop == "command":  # the command dropped, the torque too
        text = yaml.safe_load(path.read_text())
        del text["log"]["torque"]
        path.write_text(yaml.safe_dump(text))
    with pytest.raises(ConfigError, match=match) as info:
        load_identify_config(path)
    assert "\n" not in str(info.value)


def test_gains_far_below_the_gravity_load_they_carry_are_refused():
    """A servo torque far below the URDF's gravity load of its joint (the fit drove the gain
    to 0) is a DataError naming that joint only; with the gains given there is no check."""
    scale = Scale("mass", np.zeros(3), np.eye(3), ("a", "b", "c"), "n", own_load=np.ones(2))
    fit = ServoFit(
        ("j1", "j2"), np.array([0.5, 30.0]), *[np.zeros(2)] * 3, 2.0, 500.0, True, (2.0,),
        (0.0,), "mass", "n", None, np.zeros(2, dtype=np.int64), 0, 0.0, np.ones(2),
    )  # fmt: skip
    torque = np.column_stack([np.full(10, 0.3), np.full(10, 0.6)])  # rms 0.3 and 0.6 N*m
    with pytest.raises(DataError, match=r"cfg\.yaml: .*servo torque of j1 \(0\.3 N\*m") as info:
        servo_fit._check_gravity_carried(scale, torque, fit, "cfg.yaml")
    assert "j2" not in str(info.value)
    servo_fit._check_gravity_carried(dataclasses.replace(scale, own_load=None), torque, fit, "x")


def test_equal_kp_names_an_unknown_joint():
    with pytest.raises(ConfigError, match=r"cfg\.yaml: actuator\.equal_kp: jx is not a joint"):
        servo_fit._equal_kp([["j1", "jx"]], ("j1", "j2"), "cfg.yaml")
    assert servo_fit._equal_kp([["j2", "j1"]], ("j1", "j2"), "cfg.yaml") == ((1, 0),)


def test_servo_config_errors_exit_2_before_any_folder(servo_log, tmp_path):
    from ident.cli import app

    folder, _, _ = servo_log
    path = _config(folder, {"kind": "position", "kp": [1.0, 2.0, 3.0]})
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["identify", str(path), "--out", str(out), "--no-replay"])
    assert result.exit_code == 2, result.output
    lines = [x for x in result.output.splitlines() if x.strip()]
    assert len(lines) == 1, result.output
    assert lines[0].startswith("error:")
    assert "actuator.kp" in lines[0]
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.parametrize(("axis", "unloaded"), [("0 1 0", []), ("0 0 1", ["j1"])])
def test_init_servo_ties_the_gains_of_joints_gravity_does_not_load(tmp_path, axis, unloaded):
    """``ident init --servo`` writes ``actuator.equal_kp`` (every joint, one group) when the
    URDF has a joint gravity does not load beside loaded ones: joint 1 about the vertical
    carries exactly no gravity torque (a pan), about a horizontal axis it carries the most.
    Both joints loaded: nothing to tie, the line stays a comment."""
    urdf = tmp_path / "arm2.urdf"
    urdf.write_text(
        ARM.replace('<axis xyz="0 1 0"/>\n <limit', f'<axis xyz="{axis}"/>\n <limit', 1)
    )
    robot = Robot.from_urdf(urdf)
    assert init_servo.unloaded_joints(robot) == unloaded
    config = yaml.safe_load(init_servo.init_servo_config(urdf, tmp_path / "s.yaml", None).text)
    assert config["actuator"].get("equal_kp") == ([["j1", "j2"]] if unloaded else None)
