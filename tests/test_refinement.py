"""Refinement of the MJCF's joint extras on MuJoCo rollouts
(:mod:`ident.identify.refinement.rollout_refinement`).

Reference: a log that MuJoCo itself simulates open loop from a model with known friction loss,
damping and armature (the planted truth), on a two-link arm whose axes are vertical (gravity
does not load it, so random torques give a bounded motion).
"""

import json
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml
from robots import rp2_identify_config
from typer.testing import CliRunner

from ident.errors import ConfigError
from ident.identify.assessment.rollout import (
    RolloutMeasurements,
    reference_mjcf,
    rollout_score,
)
from ident.identify.config import load_identify_config
from ident.identify.refinement.rollout_refinement import (
    PATIENCE,
    joint_values,
    refine_joint_extras,
    refinement_text,
    rejection_reasons,
    torque_error,
    with_values,
)
from ident.model import Robot

# Two links turning about vertical axes: gravity does not load the joints.
ARM = """<robot name="planar2"><link name="base"/>
<link name="l1"><inertial><origin xyz="0.2 0.01 0"/><mass value="2.0"/>
 <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.03"/></inertial></link>
<link name="l2"><inertial><origin xyz="0.15 0 0"/><mass value="1.0"/>
 <inertia ixx="0.005" ixy="0" ixz="0" iyy="0.012" iyz="0" izz="0.012"/></inertial></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>
 <limit lower="-3" upper="3" effort="100" velocity="10"/></joint>
<joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/><origin xyz="0.4 0 0"/>
 <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="100" velocity="10"/></joint></robot>"""

NAMES = ("j1", "j2")
#: The planted truth, rows frictionloss, damping, armature [SI].
TRUTH = np.array([[0.3, 0.15], [0.4, 0.25], [0.05, 0.03]])
RATE = 1000.0
LENGTH = 301  # 0.3 s windows
TRAIN = np.array([[k * 300, k * 300 + LENGTH] for k in range(6)])  # 0 .. 1.8 s
HELD = np.array([[k * 300, k * 300 + LENGTH] for k in range(7, 11)])  # 2.1 .. 3.3 s


@pytest.fixture(scope="module")
def planted(tmp_path_factory):
    """The truth's model and 3.4 s of its open-loop motion under random smooth torques."""
    urdf = tmp_path_factory.mktemp("planar") / "planar2.urdf"
    urdf.write_text(ARM)
    robot = Robot.from_urdf(urdf)
    extras = {
        name: {"coulomb": TRUTH[0, j], "viscous": TRUTH[1, j], "rotor_inertia": TRUTH[2, j]}
        for j, name in enumerate(NAMES)
    }
    truth = mujoco.MjModel.from_xml_string(reference_mjcf(robot, extras))
    truth.opt.timestep = 1.0 / RATE
    n = int(3.4 * RATE) + 1
    t = np.arange(n) / RATE
    rng = np.random.default_rng(1)
    phases, freqs = rng.uniform(0, 2 * np.pi, (4, 2)), np.array([0.7, 1.3, 2.1, 3.4])
    tau = sum(np.sin(2 * np.pi * f * t[:, None] + p) for f, p in zip(freqs, phases, strict=True))
    tau = tau * np.array([1.5, 0.6])
    data = mujoco.MjData(truth)
    q, dq = np.zeros((n, 2)), np.zeros((n, 2))
    for k in range(n):
        q[k], dq[k] = data.qpos, data.qvel
        data.qfrc_applied[:] = tau[k]
        mujoco.mj_step(truth, data)
    return truth, RolloutMeasurements(t, q, dq, tau, NAMES)


def test_refinement_recovers_planted_extras_from_30_percent_off(planted):
    """Start 30 % off (up or down per value); no prior: the refinement finds the planted
    values within 2 % and its held-out objective reaches the truth's (measured 1e-?)."""
    truth, measured = planted
    off = np.array([[1.3, 0.7], [0.7, 1.3], [1.3, 0.7]])
    start = with_values(truth, NAMES, TRUTH * off)
    assert np.allclose(joint_values(start, NAMES), TRUTH * off)
    fit = refine_joint_extras(
        start, (measured, TRAIN), (measured, HELD), max_iterations=12, prior_weight=0.0
    )
    assert fit.best > 0
    np.testing.assert_allclose(fit.refined, TRUTH, rtol=1e-3)
    j_truth = rollout_score(truth, measured, HELD).objective
    j_start = rollout_score(start, measured, HELD).objective
    assert fit.held_out[0] == pytest.approx(j_start, rel=1e-9)
    assert fit.held_out[fit.best] <= j_truth + 1e-6 * j_start
    # ident's torque law explains the log better with the planted values (0.051 vs 0.10)
    assert torque_error(truth, measured, HELD) < torque_error(start, measured, HELD)


def test_a_refinement_the_held_out_windows_refuse_is_not_accepted(planted):
    """The training windows come from other values than the held-out ones, which the start
    replays exactly: every iterate moves away on the held-out windows, so the search stops
    after PATIENCE iterations, keeps the start, and the reason is named."""
    truth, measured = planted
    other = with_values(truth, NAMES, TRUTH * 1.5)  # drives the training windows' motion
    data = mujoco.MjData(other)
    q, dq = measured.q.copy(), measured.dq.copy()
    for k in range(TRAIN[-1, 1]):  # from rest, as the fixture's motion
        q[k], dq[k] = data.qpos, data.qvel
        data.qfrc_applied[:] = measured.tau[k]
        mujoco.mj_step(other, data)
    train = RolloutMeasurements(measured.t, q, dq, measured.tau, NAMES)
    fit = refine_joint_extras(
        truth, (train, TRAIN), (measured, HELD), max_iterations=10, prior_weight=0.0
    )
    assert fit.best == 0
    assert fit.iterations == PATIENCE
    assert min(fit.held_out[1:]) > fit.held_out[0]
    np.testing.assert_array_equal(fit.refined, TRUTH)
    (reason,) = rejection_reasons(fit, 0.1, 0.1)
    assert reason.startswith("no iterate improved the held-out rollout objective")
    assert "early stop" in reason
    improved = type(fit)(**{**vars(fit), "best": 1})
    assert rejection_reasons(improved, 0.1, 0.1) == []
    assert "torque error would rise from 0.1 to 0.11" in rejection_reasons(improved, 0.1, 0.11)[0]


@pytest.mark.parametrize(
    ("refinement", "field"),
    [
        ("gradient", "refinement.method"),
        ({"method": "rollout", "max_iterations": 0}, "refinement.max_iterations"),
        ({"method": "rollout", "max_windows": 100}, "refinement.max_windows"),
        ({"method": "rollout", "prior_weight": -1.0}, "refinement.prior_weight"),
        ({"method": "rollout", "windows": 3}, "refinement.windows"),
    ],
)
def test_bad_refinement_sections_are_one_line_config_errors(tmp_path, refinement, field):
    path = rp2_identify_config(tmp_path)
    cfg = yaml.safe_load(path.read_text())
    path.write_text(yaml.safe_dump({**cfg, "refinement": refinement}))
    with pytest.raises(ConfigError) as info:
        load_identify_config(path)
    message = str(info.value)
    assert "\n" not in message
    assert str(path) in message
    assert field in message, message


def test_bad_refinement_exits_2_before_any_folder(tmp_path):
    from ident.cli import app

    path = rp2_identify_config(tmp_path)
    cfg = yaml.safe_load(path.read_text())
    path.write_text(yaml.safe_dump({**cfg, "refinement": {"method": "rollout", "max_windows": 0}}))
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["identify", str(path), "--out", str(out), "--no-replay"])
    assert result.exit_code == 2, result.output
    lines = [x for x in result.output.splitlines() if x.strip()]
    assert len(lines) == 1, result.output
    assert lines[0].startswith("error:")
    assert "refinement.max_windows" in lines[0]
    assert not out.exists() or not any(out.iterdir())


@pytest.mark.slow
def test_identify_writes_one_refinement_entry_the_report_and_terminal_show(tmp_path):
    """``ident identify`` with ``refinement: rollout`` on the rp2 log: result.json's entry,
    the report's row and the terminal line are one text; accepted, the MJCF's joints carry the
    entry's refined values and the URDF is the regressor's. The training windows overlap (8.4 s
    of identification part: 80 starting every 0.1 s, more than 16 disjoint ones), 20 of them
    (max_windows) are used, and the CPU estimate printed before counts those windows."""
    from ident.cli import app

    path = rp2_identify_config(tmp_path)
    cfg = yaml.safe_load(path.read_text())
    refinement = {"method": "rollout", "max_iterations": 3, "max_windows": 20}
    path.write_text(yaml.safe_dump({**cfg, "refinement": refinement}))
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["identify", str(path), "--out", str(out), "--no-replay"])
    assert result.exit_code == 0, result.output
    (folder,) = [p for p in out.iterdir() if p.is_dir()]
    data = json.loads((folder / "result.json").read_text())
    entry = data["refinement"]
    text = refinement_text(entry)
    assert text in result.output
    assert f"| MJCF refinement | {text} |" in (folder / "report.md").read_text()
    # the estimate printed before counts the windows the refinement then uses (not 64 and 64)
    assert (
        f"refinement on rollouts: at most 3 iterations of 7 rollouts of {entry['train_windows']} "
        f"training windows of 0.5 s (at most 20: refinement.max_windows) and one of "
        f"{entry['held_out_windows']} held-out windows: estimated "
    ) in result.output
    assert entry["max_windows"] == 20
    assert entry["train_windows"] == 20
    assert entry["held_out_windows"] == data["rollout"]["windows"]
    assert entry["objective_before"] == pytest.approx(data["rollout"]["objective"], rel=1e-9)
    mjcf = mujoco.MjModel.from_xml_path(str(folder / data["model"]["files"]["mjcf"]))
    names = tuple(entry["parameters"])
    column = 1 if entry["accepted"] else 0
    expected = [
        [entry["parameters"][n][a][column] for n in names]
        for a in ("frictionloss", "damping", "armature")
    ]
    np.testing.assert_allclose(joint_values(mjcf, names), expected, rtol=1e-12)


def test_a_run_configs_identification_section_carries_the_refinement(tmp_path):
    """``ident run``: ``identification.refinement`` reaches the log's identify config, and a
    bad value is the run config's one-line error naming the field."""
    from ident.run.config import load_run_config
    from ident.run.log_measurement import identify_config

    root = Path(__file__).resolve().parents[1]
    run = yaml.safe_load((root / "configs" / "ur5.yaml").read_text())
    run["robot"].update(
        urdf=str(root / "robot" / "urdf" / "ur5.urdf"),
        package_dirs=[str(root / "robot" / "meshes")],
    )
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump({**run, "identification": {"refinement": "rollout"}}))
    columns = {"time": {"column": "t"}, "position": {"columns": ["q"] * 6}}
    log = {"log": {"path": str(path), **columns, "torque": {"columns": ["tau"] * 6}}}
    assert identify_config(load_run_config(path), log).refinement.method == "rollout"
    bad = {"identification": {"refinement": {"method": "rollout", "prior_weight": -1}}}
    path.write_text(yaml.safe_dump({**run, **bad}))
    with pytest.raises(ConfigError, match=r"identification\.refinement\.prior_weight"):
        load_run_config(path)


def test_refined_values_rewrite_only_the_mjcf_joints(tmp_path):
    """The accepted values are written into the MJCF's joints at full precision (MuJoCo reads
    them back bit for bit), its bodies unchanged and its header kept with the added note."""
    from ident.identify.model_files.mjcf import MJCF_NOTE, with_joint_values
    from ident.identify.refinement.rollout_refinement import MJCF_ATTRIBUTES

    urdf = tmp_path / "planar2.urdf"
    urdf.write_text(ARM)
    text = reference_mjcf(Robot.from_urdf(urdf), None)
    refined = TRUTH * (1.0 + np.pi * 1e-7)  # digits a 6-digit writer would lose
    values = {
        name: {MJCF_ATTRIBUTES[k]: refined[i, j] for i, k in enumerate(("fs", "fv", "Ia"))}
        for j, name in enumerate(NAMES)
    }
    out = with_joint_values(text, values, "refined here")
    assert out.startswith(f"<!--{MJCF_NOTE}-->\n<!-- refined here -->\n<mujoco")
    before, after = mujoco.MjModel.from_xml_string(text), mujoco.MjModel.from_xml_string(out)
    np.testing.assert_array_equal(joint_values(after, NAMES), refined)
    np.testing.assert_array_equal(after.body_mass, before.body_mass)
    np.testing.assert_array_equal(after.body_inertia, before.body_inertia)


def test_a_refined_copy_simulates_as_its_written_mjcf_reloaded(planted, tmp_path):
    """The rollouts the refinement scores are those of the file it writes: values set on a
    copy (armature 3x, so the friction-loss constraint's ``invweight0`` changes) roll out as
    the MJCF rewritten with them and compiled by MuJoCo; without recomputing the compiler's
    constants ``invweight0`` is off by a factor of 8 and a window's score by 8e-4."""
    from ident.identify.model_files.mjcf import with_joint_values
    from ident.identify.refinement.rollout_refinement import MJCF_ATTRIBUTES

    truth, measured = planted
    urdf = tmp_path / "planar2.urdf"
    urdf.write_text(ARM)
    text = reference_mjcf(Robot.from_urdf(urdf), None)
    start = mujoco.MjModel.from_xml_string(text)
    start.opt.timestep = 1.0 / RATE
    refined = TRUTH * np.array([[1.0], [1.0], [3.0]])
    values = {
        name: {MJCF_ATTRIBUTES[k]: refined[i, j] for i, k in enumerate(("fs", "fv", "Ia"))}
        for j, name in enumerate(NAMES)
    }
    reloaded = mujoco.MjModel.from_xml_string(with_joint_values(text, values))
    copied = with_values(start, NAMES, refined)
    np.testing.assert_allclose(copied.dof_invweight0, reloaded.dof_invweight0, rtol=1e-12)
    score = rollout_score(copied, measured, HELD).per_window
    np.testing.assert_allclose(score, rollout_score(reloaded, measured, HELD).per_window, rtol=1e-9)


def test_bench_refines_reference_stays_inside_every_limit_for_any_seed():
    """benchmarks/bench_refine.py's reference: seed 1 of the unbounded 3-harmonic reference takes
    the Panda's joint 4 0.18 rad past its range. Bounded, every seed stays RANGE_MARGIN inside
    each range and under LIMIT_FRACTION of the velocity and acceleration limits; a scaled joint
    is still one motion (its dq the derivative of its q, a clip or a q-only scale is not) and
    reaches its bound (no over-shrinking); a joint within bounds is the unbounded one exactly."""
    import importlib
    import sys

    from robots import PANDA_URDF

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    bench = importlib.import_module("bench_refine")
    panda = Robot.from_urdf(PANDA_URDF, lock_joints={"panda_finger_joint1": 0.01})
    panda.ddq_max = np.array([np.inf, 0.3, np.inf, np.inf, np.inf, np.inf, 0.4])  # rad/s^2
    kw = {"period": 10.0, "amplitude": 0.8, "rate_hz": 100.0}
    margin, frac = bench.RANGE_MARGIN, bench.LIMIT_FRACTION
    assert bench.fourier_reference(panda, seed=1, **kw)[1][:, 3].max() > panda.q_upper[3] + 0.17
    for seed in range(6):
        raw = bench.fourier_reference(panda, seed=seed, **kw)
        t, q, dq, ddq = bench.bounded_reference(panda, seed=seed, **kw)
        assert np.all(q >= panda.q_lower + margin - 1e-12)
        assert np.all(q <= panda.q_upper - margin + 1e-12)
        assert np.all(np.abs(dq) <= frac * panda.dq_max + 1e-12)
        assert np.all(np.abs(ddq) <= frac * panda.ddq_max + 1e-12)
        # periodic, so the central difference wraps; O(h^2) against the motion's size
        np.testing.assert_allclose(
            (np.roll(q, -1, 0) - np.roll(q, 1, 0)) * 50.0, dq, atol=2e-3 * np.abs(dq).max()
        )
        scaled = np.any(raw[1] != q, axis=0)
        np.testing.assert_array_equal(q[:, ~scaled], raw[1][:, ~scaled])
        for j in np.flatnonzero(scaled):  # one of its bounds is met
            near = min(q[:, j].min() - panda.q_lower[j], panda.q_upper[j] - q[:, j].max())
            assert (
                min(
                    abs(near - margin),
                    abs(np.abs(dq[:, j]).max() - frac * panda.dq_max[j]),
                    abs(np.abs(ddq[:, j]).max() - frac * panda.ddq_max[j]),
                )
                < 1e-9
            )
    assert scaled[6]  # seed 5: joint 7 under its 0.4 rad/s^2
    # --periods sets the logged periods of the MuJoCo-native measurement, None keeps the config's
    run = {"measurement": {"source": "mujoco", "n_periods": 3, "friction": {"coulomb": [1.0]}}}
    assert bench.native_measurement(run)["n_periods"] == 3
    native = bench.native_measurement(run, 12)
    assert native["n_periods"] == 12
    assert native["friction"]["semantics"] == "mujoco"
    assert "source" not in native
    assert run["measurement"]["n_periods"] == 3  # the config is not changed
    # the regressor's distance to the truth over the held-out windows and its paired standard
    # error: the same excess on every window is no error, whatever the windows' own spread;
    # else std(model - truth) / sqrt(W) / mean(truth) (ddof 1), not the unpaired spread
    truth = np.array([1.0, 2.0, 3.0, 6.0])
    assert bench.paired_gap(truth + 0.3, truth) == pytest.approx((0.1, 0.0))
    scaled_se = 0.1 * np.std(truth, ddof=1) / 2 / 3
    assert bench.paired_gap(1.1 * truth, truth) == pytest.approx((0.1, scaled_se))
    gap, se = bench.paired_gap(truth + np.array([0.3, -0.3, 0.3, -0.3]), truth)
    assert gap == pytest.approx(0.0, abs=1e-15)
    assert se == pytest.approx(np.sqrt(0.36 / 3) / 2 / 3)


def test_bench_refine_bodies_moves_keep_every_body_consistent():
    """benchmarks/bench_refine_bodies.py moves the MJCF's bodies: a body written into MuJoCo and
    read back is the same body (mass, first and second moments about the frame, against
    Pinocchio's inertia at the centre of mass), a consistent body is not changed by the
    projection, and an inconsistent one (the triangle inequality broken) comes back with a
    positive semi-definite pseudo-inertia, its consistent part kept (a clip of theta's
    entries, or no projection, would fail)."""
    import importlib
    import sys

    import pinocchio as pin

    from ident.identify.estimation.consistency import pseudo_inertia

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    bodies = importlib.import_module("bench_refine_bodies")
    rng = np.random.default_rng(3)
    mj = mujoco.MjModel.from_xml_string(
        "<mujoco><worldbody><body><joint type='hinge'/><inertial pos='0 0 0' mass='1' "
        "diaginertia='1 1 1'/></body></worldbody></mujoco>"
    )
    for _ in range(3):
        # a solid box (a body), turned and moved off the frame's origin
        box = pin.Inertia.FromBox(rng.uniform(0.5, 2.0), *rng.uniform(0.02, 0.3, 3))
        placement = pin.SE3(pin.rpy.rpyToMatrix(*rng.uniform(-3, 3, 3)), rng.normal(0, 0.1, 3))
        inertia = placement.act(box)
        theta = np.asarray(inertia.toDynamicParameters())  # [m, mc, Ixx Ixy Iyy Ixz Iyz Izz]
        bodies.set_mj_inertial(mj, 1, theta)
        np.testing.assert_allclose(bodies.mj_inertial(mj, 1), theta, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(mj.body_ipos[1], inertia.lever, atol=1e-12)
        np.testing.assert_allclose(
            np.sort(mj.body_inertia[1]), np.linalg.eigvalsh(inertia.inertia), rtol=1e-10
        )
        np.testing.assert_allclose(bodies.consistent(theta), theta, rtol=1e-10, atol=1e-12)
        bad = theta.copy()
        bad[4] += 3.0 * (theta[6] + theta[9])  # Ixx above Iyy + Izz: not a body
        assert np.linalg.eigvalsh(pseudo_inertia(bad))[0] < -1e-3
        fixed = bodies.consistent(bad)
        lam = np.linalg.eigvalsh(pseudo_inertia(fixed))
        assert lam[0] >= -1e-10 * lam[-1]
        # the nearest such body: the positive eigenvalues are kept, the negative one set to 0
        np.testing.assert_allclose(
            lam[1:], np.linalg.eigvalsh(pseudo_inertia(bad))[1:], rtol=1e-9, atol=1e-12
        )
