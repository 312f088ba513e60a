"""The SO-101-like arm's LeRobot example: the dataset the simulator writes, the shipped example
run as a user runs it, ``ident init --servo``, and the reader's lazy pyarrow.

References: the simulator's own log (:func:`ident.measure.mujoco_sim.simulate`, the committed
dataset's episodes regenerated bit for bit), the servo truth of ``data/examples/make_so101.py``
(``kv + damping``, ``kp``) and MuJoCo's reading of the written MJCF.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from ident.cli import app
from ident.errors import DataError
from ident.identify.config import load_identify_config
from ident.identify.pipeline.real import identify
from ident.measure.lerobot_dataset import lerobot_log_section, to_ticks, write_simulated_dataset
from ident.measure.log_config import LogConfig, TransmissionConfig
from ident.measure.logs import read_log
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate
from ident.model import Robot

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "data" / "examples"))
import make_so101  # noqa: E402

EXAMPLE = ROOT / "configs" / "examples" / "lerobot-so101.yaml"


@pytest.fixture(scope="module")
def so101():
    return Robot.from_urdf(make_so101.URDF)


def test_so101_urdf_is_a_light_five_joint_servo_arm(so101):
    masses = [so101.model.inertias[j].mass for j in range(1, so101.model.njoints)]
    assert so101.joint_names[0] == "shoulder_pan"
    assert so101.nv == 5
    assert all(0.05 <= m <= 0.2 for m in masses), masses
    assert np.allclose(so101.model.effortLimit, 2.9)


def test_committed_dataset_is_the_simulated_servo_log_in_ticks(so101, tmp_path):
    """Episode 0 simulated again equals the committed file: the encoder positions and the
    commands as whole ticks (``zero + q 4096 / 2 pi``), read back to the same radians."""
    (log,) = make_so101.simulate_episodes(so101, make_so101.EPISODE_SEEDS[:1])
    shipped = make_so101.DATASET / "data" / "chunk-000" / "episode_000000.parquet"
    table = pq.read_table(shipped).to_pydict()
    state = np.array(table["observation.state"])
    expected = make_so101.ZERO_TICK + log.q * make_so101.COUNTS_PER_REV / (2 * np.pi)
    np.testing.assert_allclose(state[:, :5], expected, rtol=0, atol=1e-6)
    assert np.array_equal(state, np.rint(state))
    assert np.all(state[:, 5] == make_so101.ZERO_TICK)  # the gripper, held
    np.testing.assert_array_equal(np.array(table["frame_index"]), np.arange(log.n_samples))
    section = lerobot_log_section(str(make_so101.DATASET), 4096, 2048, ["gripper"])
    read = read_log(LogConfig.model_validate(section), TransmissionConfig(), so101.joint_names)
    assert read.segments == ((0, log.n_samples), (log.n_samples, 2 * log.n_samples))
    np.testing.assert_allclose(read.q[: log.n_samples], log.q, rtol=0, atol=1e-12)
    assert read.q_cmd is not None
    np.testing.assert_allclose(read.q_cmd[: log.n_samples], log.q_cmd, rtol=0, atol=1e-12)
    assert read.sampling_rate_hz == pytest.approx(make_so101.RATE_HZ, rel=1e-12)


def test_writer_refuses_a_motor_log(so101, tmp_path):
    t, q, dq, ddq = make_so101.reference(so101, 0)
    config = load_mujoco_measurement({"rate_hz": 500.0, "settle_periods": 0, "n_periods": 1})
    log = simulate(so101, t[:100], q[:100], dq[:100], ddq[:100], config)
    with pytest.raises(DataError, match="actuator.kind: position"):
        write_simulated_dataset(tmp_path / "ds", [log], counts_per_rev=4096, zero_tick=2048)
    assert to_ticks(np.array([np.pi / 2]), 4096, 2048)[0] == 3072.0


@pytest.mark.slow
def test_shipped_example_identifies_as_a_user_runs_it(tmp_path):
    """``ident identify configs/examples/lerobot-so101.yaml``: kd + fv within 1 % of the
    simulator's kv + damping, the rollout check run, and an MJCF whose <position> actuators
    MuJoCo reads with the given gains."""
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["identify", str(EXAMPLE), "--out", str(out), "--no-replay"])
    assert result.exit_code == 0, result.output
    (run,) = out.iterdir()
    data = json.loads((run / "result.json").read_text())
    truth = np.add(make_so101.SERVO["kv"], make_so101.SERVO["damping"])
    np.testing.assert_allclose(data["actuator"]["kd_plus_fv"], truth, rtol=0.01)
    assert data["rollout"]["note"] is None, data["rollout"]
    assert data["rollout"]["objective"] < 1e-3 * data["rollout"]["reference_objective"]
    model = mujoco.MjModel.from_xml_path(str(run / data["model"]["files"]["mjcf"]))
    np.testing.assert_allclose(model.actuator_gainprm[:, 0], make_so101.SERVO["kp"])
    assert (run / "report.html").is_file()


def test_init_servo_needs_servo_for_log(tmp_path):
    out = tmp_path / "servo.yaml"
    args = ["init", str(make_so101.URDF), "-o", str(out), "--log", str(make_so101.DATASET)]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2, result.output
    assert result.output.startswith("error:")
    assert "--servo" in result.output
    assert not out.exists()


@pytest.mark.slow
def test_init_servo_config_validates_and_runs_on_the_example_dataset(tmp_path):
    """``ident init URDF --servo --log DATASET``: position servos, ticks, the gripper excluded
    by name, filters from the dataset's 500 fps; the config identifies the dataset."""
    out = tmp_path / "cfg" / "servo.yaml"
    out.parent.mkdir()
    args = ["init", str(make_so101.URDF), "-o", str(out), "--servo", "--log"]
    result = CliRunner().invoke(app, [*args, str(make_so101.DATASET)])
    assert result.exit_code == 0, result.output
    cfg = load_identify_config(out)
    assert cfg.actuator.kind == "position"
    assert cfg.actuator.scale == "mass"
    assert cfg.log.format == "lerobot"
    assert cfg.log.position.unit == "ticks"
    assert cfg.log.position.exclude == ["gripper"]
    assert cfg.preprocess.decimation == [5]  # 500 fps -> 100 Hz rows
    fit = identify(cfg).actuator
    assert fit.delay_candidates[0] <= fit.delay_samples <= 5  # scanned over 0..10 ms
    assert fit.kp.shape == (5,)
    assert np.all(np.isfinite(fit.kp))


def test_registry_imports_no_pyarrow():
    """pyarrow (0.15 s) is imported when a LeRobot dataset is read, not with the registry."""
    code = "import sys, ident.measure.readers; print('pyarrow' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_committed_urdf_is_what_ident_urdf_writes():
    """robot/urdf/so101.urdf is generated: ``ident urdf configs/so101.yaml`` writes it again."""
    from ident.robot.robot_config import load_robot_config
    from ident.robot.urdf import urdf_from_description

    text = urdf_from_description(load_robot_config(ROOT / "configs" / "so101.yaml"))
    assert text == make_so101.URDF.read_text()
