"""``ident payload``: a simulated payload recovered against its truth; MuJoCo payload; bad input.

References: MuJoCo's inverse dynamics of the arm with the welded payload body against Pinocchio's
RNEA with the payload's inertia added to the last body (independent code paths), the payload the
simulator was given, and the written URDF reloaded by Pinocchio against MuJoCo's truth model.
"""

import json
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest
import yaml
from robots import UR5_URDF
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import ConfigError, ModelError
from ident.excitation.fourier import fourier_series
from ident.identify.model_files.urdf_update import model_of_urdf
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_model import load_mujoco
from ident.measure.mujoco_sim import simulate, write_log
from ident.model import Robot

PAYLOAD = {
    "mass": 3.0,
    "com": [0.03, -0.02, 0.07],
    "inertia": [0.012, 0.001, 0.01, 0.0, 0.0, 0.008],
}
MEASUREMENT = {
    "friction": {"viscous": [3.0, 3.0, 2.0, 0.5, 0.5, 0.5], "coulomb": [5.0, 5.0, 3.0, 1, 1, 1]},
    "armature": [0.5, 0.5, 0.3, 0.05, 0.05, 0.05],
    "encoder_counts_per_rev": 524288,
    "settle_periods": 0,
    "n_periods": 1,
}
PREPROCESS = {
    "lowpass": {"cutoff_hz": 10.0},
    "torque_lowpass": {"cutoff_hz": 10.0},
    "trim_samples": 300,
    "decimation": [10],
    "velocity_threshold": [0.15] * 6,
}


@pytest.fixture(scope="module")
def ur5():
    return Robot.from_urdf(UR5_URDF)


def with_payload(robot, phi):
    """Pinocchio model of the arm with ``phi`` added to its last body (the reference)."""
    model = robot.model.copy()
    last = model.njoints - 1
    model.inertias[last] = model.inertias[last] + pin.Inertia.FromDynamicParameters(phi)
    return model


def test_mujoco_payload_is_a_body_welded_to_the_last_link(ur5):
    cfg = load_mujoco_measurement({"payload": PAYLOAD})
    mj = load_mujoco(ur5, payload=cfg.payload)
    data = mujoco.MjData(mj.model)
    reference = with_payload(ur5, cfg.payload.parameters())
    ref_data = reference.createData()
    rng = np.random.default_rng(0)
    for _ in range(10):
        q, dq, ddq = rng.uniform(-2, 2, 6), rng.normal(size=6), rng.normal(size=6) * 3
        data.qpos[mj.qpos_index], data.qvel[mj.dof_index], data.qacc[mj.dof_index] = q, dq, ddq
        mujoco.mj_inverse(mj.model, data)
        expected = pin.rnea(reference, ref_data, q, dq, ddq)
        np.testing.assert_allclose(data.qfrc_inverse[mj.dof_index], expected, atol=1e-10)
        # the payload is felt: the arm alone differs by newtons
        assert np.abs(ur5.rnea(q, dq, ddq)[0] - expected).max() > 1.0


_ONE_JOINT_URDF = """<robot name="one"><link name="base"/>
<link name="arm"><inertial><mass value="2"/>
<inertia ixx="0.1" iyy="0.1" izz="0.1" ixy="0" ixz="0" iyz="0"/></inertial></link>
<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/><axis xyz="0 1 0"/>
<limit lower="-2" upper="2" effort="10" velocity="2"/></joint></robot>"""


def test_mujoco_payload_link_must_be_a_urdf_link(tmp_path):
    """An unknown link is refused, and so is "world" in a URDF without such a link (MuJoCo's
    spec names its world body "world": a check asking MuJoCo only would take it)."""
    urdf = tmp_path / "one.urdf"
    urdf.write_text(_ONE_JOINT_URDF)
    robot = Robot.from_urdf(urdf)
    for link in ("nope", "world"):
        cfg = load_mujoco_measurement({"payload": {**PAYLOAD, "link": link}})
        with pytest.raises(ModelError, match=rf"payload.link = '{link}' is not a link"):
            load_mujoco(robot, payload=cfg.payload)


def test_mujoco_payload_must_be_a_rigid_body():
    bad = {**PAYLOAD, "inertia": [0.001, 0.0, 0.001, 0.0, 0.0, 0.05]}  # Izz > Ixx + Iyy
    with pytest.raises(ConfigError, match=r"measurement.*payload.*triangle"):
        load_mujoco_measurement({"payload": bad}, source="measurement")


def _log(robot, folder, payload, seed):
    """A 5 s closed-loop log of one Fourier excitation, 1 % torque noise."""
    rate, period = 1000.0, 5.0
    t = np.arange(int(rate * period)) / rate
    rng = np.random.default_rng(7)
    a, b = rng.uniform(-0.4, 0.4, (2, 1, 6, 4))
    q0 = np.array([0.0, -1.57, 0.0, -1.57, 0.0, 0.0])
    q, dq, ddq = (x[0] for x in fourier_series(t, a, b, q0[None], 2 * np.pi / period))
    rms = np.sqrt(np.mean(robot.rnea(q, dq, ddq) ** 2, axis=0))
    section = {**MEASUREMENT, "torque_noise_std": (0.01 * rms).tolist(), "payload": payload}
    sim = simulate(robot, t, q, dq, ddq, load_mujoco_measurement(section), rng=seed)
    files = write_log(folder, sim)
    log = yaml.safe_load(files.yaml.read_text())["log"]
    for key in ("time", "position", "torque"):
        log[key]["path"] = str(folder / log[key]["path"])
    return log


@pytest.fixture(scope="module")
def payload_config(ur5, tmp_path_factory):
    folder = tmp_path_factory.mktemp("payload")
    config = {
        "name": "ur5-payload",
        "robot": {"urdf": str(UR5_URDF)},
        "log": _log(ur5, folder / "with", PAYLOAD, 1),
        "preprocess": PREPROCESS,
        "model": {"viscous": True, "coulomb": True, "rotor_inertia": True, "offset": False},
        "payload": {"without": _log(ur5, folder / "without", None, 2)},
    }
    return folder, config


def test_payload_recovered_against_the_simulated_truth(ur5, payload_config, tmp_path):
    folder, config = payload_config
    path = tmp_path / "payload.yaml"
    path.write_text(yaml.safe_dump(config))
    result = CliRunner().invoke(app, ["payload", str(path), "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    (run,) = (tmp_path / "runs").iterdir()
    summary = json.loads((run / "payload.json").read_text())
    truth = load_mujoco_measurement({"payload": PAYLOAD}).payload
    mass_error = summary["mass_kg"] - truth.mass
    com_error = np.asarray(summary["com_m"]) - truth.com
    assert abs(mass_error) < 0.02 * truth.mass  # the targets: 2 % of the mass
    assert np.linalg.norm(com_error) < 0.005
    # the intervals cover the truth (4 std), and are not vacuous
    assert abs(mass_error) < 4 * summary["mass_std_kg"] + 1e-6
    assert summary["mass_std_kg"] < 0.01 * truth.mass
    assert summary["pseudo_inertia_min_eigenvalue"] > 0.0
    # the one calibrated σ, named (docs/uncertainty.md), and its 95 % interval
    assert summary["std_method"] == "bootstrap"
    assert "(bootstrap σ)" in result.output
    lo, hi = summary["mass_interval_kg"]
    assert hi - lo == pytest.approx(2 * 1.959964 * summary["mass_std_kg"])
    # the written URDF is the arm + payload: Pinocchio's RNEA of it is MuJoCo's truth model
    (urdf,) = run.glob("*_payload.urdf")
    written = model_of_urdf(urdf.read_text(), {})
    reference = with_payload(ur5, truth.parameters())
    q, dq, ddq = ur5.random_configurations(20, rng=0)
    d1, d2 = written.createData(), reference.createData()
    tau_written = np.array([pin.rnea(written, d1, *s) for s in zip(q, dq, ddq, strict=True)])
    tau_truth = np.array([pin.rnea(reference, d2, *s) for s in zip(q, dq, ddq, strict=True)])
    assert np.abs(tau_written - tau_truth).max() < 0.02 * np.abs(tau_truth).max()
    assert np.abs(ur5.rnea(q, dq, ddq) - tau_truth).max() > 0.05 * np.abs(tau_truth).max()


def test_bad_payload_section_is_one_error_line_and_nothing_written(payload_config, tmp_path):
    _, config = payload_config
    bad = {**config, "payload": {**config["payload"], "method": "lmx"}}
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(bad))
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["payload", str(path), "--out", str(out)])
    assert result.exit_code == 2
    lines = result.output.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("error: ")
    for part in (str(path), "payload.method", "lmi"):  # the file, the field, the fix
        assert part in lines[0]
    assert not out.exists() or not any(out.iterdir())


def test_no_physical_arm_plus_payload_keeps_the_estimate_and_says_why(
    ur5, payload_config, tmp_path, monkeypatch
):
    """A WLS payload that, added to the URDF's last body, is no physical body (one log on a
    CAD arm: the payload absorbs the arm's errors): payload.json is written with the estimate
    and a warning naming the failed check and the fix, no model files, exit code 1, and the
    terminal says so (was: the model-file check's error, exit 2, nothing written)."""
    from dataclasses import replace

    from ident.dynamics.parameters import parameters_from_model
    from ident.identify.corrections import signal_correction

    real = signal_correction.identify_corrected_payload
    last = parameters_from_model(ur5.model)[-10:]

    def no_body(cfg, robot):  # the last body plus this payload: minus the last body's mass
        return replace(real(cfg, robot), phi=-2.0 * last)

    monkeypatch.setattr(signal_correction, "identify_corrected_payload", no_body)
    _, config = payload_config
    path = tmp_path / "payload.yaml"
    path.write_text(yaml.safe_dump({**config, "payload": {**config["payload"], "method": "wls"}}))
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["payload", str(path), "--out", str(out)])
    assert result.exit_code == 1, result.output
    (run,) = out.iterdir()
    summary = json.loads((run / "payload.json").read_text())
    note = summary["model_files"]["note"]
    assert summary["model_files"]["written"] is False
    assert note == summary["warnings"][-1]
    assert f"mass = {-last[0]:.6g} kg must be > 0" in note  # the check that failed, its value
    assert "wrist_3_joint" in note  # where
    assert "payload.method: lmi" in note  # and the fix
    assert f"warning: {note}" in result.output
    assert "model files: not written" in result.output
    assert summary["mass_kg"] == pytest.approx(3.0, rel=0.02)  # the estimate itself is kept
    assert sorted(p.name for p in run.iterdir() if p.suffix in (".urdf", ".xml")) == []
    assert json.loads((run / "run.json").read_text())["status"] == "complete"


def test_centre_of_mass_reported_in_another_frame_of_the_last_link(ur5):
    """Noise-free rows of a known payload: the estimate is exact, and the centre of mass in a
    frame at pose (R, p) in the last joint's frame is R^T (c - p) (a wrong-way transform, or
    the first moments used as a position, fails)."""
    from ident.identify.estimation.observations import ReducedObservations
    from ident.identify.payload.payload import estimate_payload

    truth = load_mujoco_measurement({"payload": PAYLOAD}).payload
    phi = truth.parameters()
    q, dq, ddq = ur5.random_configurations(40, rng=1)
    Y = ur5.regressor(q, dq, ddq)[:, :, -10:]
    rng = np.random.default_rng(0)
    red = ReducedObservations.from_samples(Y, Y @ phi + 1e-9 * rng.normal(size=(40, 6)))
    placement = pin.SE3(pin.rpy.rpyToMatrix(0.3, -0.2, 1.0), np.array([0.01, 0.02, 0.1]))
    result = estimate_payload(red, (), method="lmi", placement=placement, link="tool")
    np.testing.assert_allclose(result.phi, phi, rtol=1e-6, atol=1e-8)
    R, p = placement.rotation, placement.translation
    np.testing.assert_allclose(result.com, R.T @ (np.asarray(truth.com) - p), atol=1e-8)
    np.testing.assert_allclose(result.mass, truth.mass, rtol=1e-8)
    inertia = np.array(PAYLOAD["inertia"])[[0, 1, 3, 1, 2, 4, 3, 4, 5]].reshape(3, 3)
    np.testing.assert_allclose(result.inertia_com, R.T @ inertia @ R, atol=1e-7)


@pytest.mark.slow
def test_reference_log_columns_matched_by_joint_name_and_a_bad_fit_warns(payload_config, tmp_path):
    """The reference log's columns listed in another order: matched by name, the same estimate
    as in joint order; columns that name no joint in the wrong order: a warning naming the
    likely cause (was: 4.9 kg instead of 3 kg and a residual of 0.89, exit 0, no word)."""
    _, config = payload_config
    runs = {}
    without = config["payload"]["without"]
    for name, reorder in (("in_order", False), ("reversed", True)):
        section = {k: dict(v) if isinstance(v, dict) else v for k, v in without.items()}
        if reorder:
            for key in ("position", "torque"):
                section[key]["columns"] = section[key]["columns"][::-1]
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump({**config, "payload": {"without": section}}))
        result = CliRunner().invoke(app, ["payload", str(path), "--out", str(tmp_path / name)])
        assert result.exit_code == 0, result.output
        (run,) = (tmp_path / name).iterdir()
        runs[name] = json.loads((run / "payload.json").read_text())
        assert "warning:" not in result.output
    assert runs["reversed"]["mass_kg"] == pytest.approx(runs["in_order"]["mass_kg"], rel=1e-9)
    assert runs["reversed"]["relative_residual"] < 0.05
    # torque columns renamed c0..c5 in reversed joint order: nothing to match them by
    log = Path(without["torque"]["path"])
    lines = log.read_text().splitlines()
    header = lines[0].split(",")
    taus = without["torque"]["columns"]
    header = [f"c{len(taus) - 1 - taus.index(h)}" if h in taus else h for h in header]
    renamed = tmp_path / "renamed.csv"
    renamed.write_text("\n".join([",".join(header), *lines[1:]]) + "\n")
    section = {k: dict(v) if isinstance(v, dict) else v for k, v in without.items()}
    for key in ("time", "position", "torque"):
        section[key]["path"] = str(renamed)
    section["torque"]["columns"] = [f"c{k}" for k in range(len(taus))]
    path = tmp_path / "renamed.yaml"
    path.write_text(yaml.safe_dump({**config, "payload": {"without": section}}))
    result = CliRunner().invoke(app, ["payload", str(path), "--out", str(tmp_path / "bad")])
    assert result.exit_code == 0, result.output
    (run,) = (tmp_path / "bad").iterdir()
    summary = json.loads((run / "payload.json").read_text())
    assert summary["relative_residual"] > 0.2
    (warning,) = summary["warnings"]
    assert "joint columns that do not match the URDF's joints" in warning
    assert f"warning: {warning}" in result.output


@pytest.mark.slow
def test_sigterm_at_each_file_of_payload(payload_config, tmp_path):
    """Interrupted at each file: exit 130 naming the folder, run.json incomplete, marker."""
    import shutil

    from lifecycle_signals import sigterm_at_each_file

    _, config = payload_config
    path = tmp_path / "payload.yaml"
    path.write_text(yaml.safe_dump(config))
    out = tmp_path / "runs"

    def find():
        children = list(out.iterdir()) if out.is_dir() else []
        return children[0] if children else None

    args = ["payload", str(path), "--out", str(out)]
    reset = lambda: shutil.rmtree(out, ignore_errors=True)  # noqa: E731
    assert (
        sigterm_at_each_file(args, find, tmp_path, reset=reset, at=(1, 3)) >= 4
    )  # run.json, json, 2 models


def test_run_truth_holds_the_simulated_payload(ur5, tmp_path):
    """``ident run``'s truth with ``measurement.payload``: the URDF's bodies with the payload
    added to the body carrying its link, against Pinocchio's ``Inertia`` moved by the link's
    placement (``se3Action``) and added to that joint's inertia; the truth without the payload
    (what ``ident run`` compared with before) differs by the payload's mass."""
    from ident.dynamics.parameters import parameters_from_model
    from ident.run.config import load_run_config
    from ident.run.log_measurement import log_stage_info, true_parameters

    root = Path(__file__).resolve().parents[1]
    data = yaml.safe_load((root / "configs" / "ur5.yaml").read_text())
    data["robot"] = {"urdf": str(UR5_URDF)}
    data["measurement"]["payload"] = {**PAYLOAD, "link": "tool0"}  # rotated, 8 cm off joint 6
    path = tmp_path / "run.yaml"
    path.write_text(yaml.safe_dump(data))
    config = load_run_config(path)
    info, pm = log_stage_info(config, ur5)
    truth = true_parameters(pm, config, ur5.model)
    reference = ur5.model.copy()
    frame = reference.frames[reference.getFrameId("tool0")]
    inertia = pin.Inertia.FromDynamicParameters(config.measurement.payload.parameters())
    joint = frame.parentJoint
    reference.inertias[joint] = reference.inertias[joint] + frame.placement.act(inertia)
    expected = parameters_from_model(reference)
    rigid = pm.inertial_index >= 0
    np.testing.assert_allclose(truth[rigid], expected[pm.inertial_index[rigid]], atol=1e-12)
    np.testing.assert_allclose(info.true_base, pm.base.project(truth), atol=1e-12)
    assert truth[pm.names.index("m6")] - pm.nominal[pm.names.index("m6")] == pytest.approx(3.0)
    with pytest.raises(ValueError, match="needs the robot's model"):
        true_parameters(pm, config)
