"""The payload excitation (``stage: payload``, ``excitation.family: payload``) and the payload's
bounding box in the collision model (``safety.payload_box``).

References: the box's floor distance against the lowest corner of the box placed by Pinocchio's
forward kinematics of the flange frame (independent of coal and of the geometry model); the
objective's condition number against numpy's SVD of Pinocchio's stacked regressor columns of
the last body; random designs of the same family; MuJoCo's simulated payload recovered by
``ident payload`` from a log of the designed trajectory.
"""

from __future__ import annotations

import itertools
import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml
from typer.testing import CliRunner

from ident.cli import app
from ident.dynamics.stage import whole_chain_stage
from ident.errors import ConfigError
from ident.excitation.check import check_trajectory
from ident.excitation.objective import ExcitationObjective
from ident.excitation.registry import build_family
from ident.excitation.safety import PAYLOAD, build_safety_model
from ident.measure.mujoco_config import load_mujoco_measurement
from ident.measure.mujoco_sim import simulate, write_log
from ident.optim import minimize
from ident.run.config import load_run_config
from ident.run.setup import prepare_run

REPO = Path(__file__).resolve().parents[1]
CONFIG = REPO / "configs" / "ur5-payload.yaml"
#: an off-centre, tilted, long box on the flange: a wrong frame, offset or rotation moves it
BOX = {"link": "tool0", "size": [0.04, 0.06, 0.30], "position": [0.02, -0.01, 0.15],
       "rpy": [0.2, -0.1, 0.3]}  # fmt: skip
#: the UR5 with the flange pointing straight down, 0.25 m above the floor
TOOL_DOWN = np.array([0.0, -1.2, 1.6, -1.97, -1.5708, 0.0])


@pytest.fixture(scope="module")
def setup():
    return prepare_run(load_run_config(CONFIG), source=CONFIG)


@pytest.fixture(scope="module")
def with_and_without_box(setup):
    robot, section = setup.robot, setup.config.safety
    models = {
        name: build_safety_model(
            robot, {**section.model_dump(), "payload_box": box}, package_dirs=robot.package_dirs
        )
        for name, box in (("box", BOX), ("none", None))
    }
    return robot, models


def _box_lowest_z(robot, q):
    """Height [m] of the box's lowest corner, from Pinocchio's placement of tool0."""
    model = robot.model
    data = model.createData()
    pin.framesForwardKinematics(model, data, q)
    tool = data.oMf[model.getFrameId("tool0")]
    box_in_tool = pin.SE3(pin.rpy.rpyToMatrix(*BOX["rpy"]), np.asarray(BOX["position"]))
    placed = tool * box_in_tool
    half = 0.5 * np.asarray(BOX["size"])
    corners = np.array(list(itertools.product(*[(-h, h) for h in half])))
    return float(np.min((placed.rotation @ corners.T).T[:, 2] + placed.translation[2]))


def test_payload_box_floor_distance_is_its_lowest_corner(with_and_without_box):
    robot, models = with_and_without_box
    safety = models["box"]
    column = safety.pair_names.index(f"{PAYLOAD}|floor")
    rng = np.random.default_rng(3)
    q = np.vstack([TOOL_DOWN, TOOL_DOWN + rng.uniform(-0.6, 0.6, (40, 6))])
    q[:, 1] = np.clip(q[:, 1], -2.0, -0.9)  # the upper arm up: the box mostly above the floor
    distances = safety.clearances(q)[:, column]
    expected = np.array([_box_lowest_z(robot, qk) for qk in q])
    clear = expected > 1e-3  # separated: coal's distance is exact, no penetration depth
    assert clear.sum() >= 10
    np.testing.assert_allclose(distances[clear], expected[clear], atol=1e-6)
    assert np.all(distances[~clear] <= 1e-6)
    # the box is checked against the arm's links next to it, not against those it is fixed to
    assert f"wrist_2_link|{PAYLOAD}" in safety.pair_names
    assert not any(p.startswith(f"{PAYLOAD}|wrist_3") for p in safety.pair_names)
    assert f"{PAYLOAD}|floor" not in models["none"].pair_names


def test_certificate_refuses_a_motion_only_the_payload_box_makes_unsafe(with_and_without_box):
    robot, models = with_and_without_box
    t = np.arange(0.0, 1.0, 1e-3)
    shape = np.sin(np.pi * t) ** 2  # from rest to rest
    wrist = np.array([0.0, 0.0, 0.0, 0.15, 0.2, 0.3])
    q = TOOL_DOWN + shape[:, None] * wrist
    dq = (np.pi * np.sin(2 * np.pi * t))[:, None] * wrist
    ddq = (2 * np.pi**2 * np.cos(2 * np.pi * t))[:, None] * wrist
    lowest = min(_box_lowest_z(robot, qk) for qk in q[::50])
    assert lowest < 0.0  # the 30 cm box reaches below the floor from a 25 cm high flange
    without = check_trajectory(robot, models["none"], t, q, dq, ddq)
    assert without.usable, without.summary()
    with_box = check_trajectory(robot, models["box"], t, q, dq, ddq)
    assert not with_box.usable
    assert [c.name for c in with_box.failures()] == [f"clearance:{PAYLOAD}|floor"]


def test_payload_box_on_an_unknown_link_is_a_config_error(setup):
    section = {**setup.config.safety.model_dump(), "payload_box": {**BOX, "link": "tool9"}}
    with pytest.raises(ConfigError, match=r"payload_box.link.*'tool9'.*tool0"):
        build_safety_model(setup.robot, section, package_dirs=setup.robot.package_dirs)


def _payload_condition(robot, objective, batch):
    """cond of the scaled last-body columns over every joint's row, by numpy's SVD."""
    model, data = robot.model, robot.model.createData()
    rows = [
        pin.computeJointTorqueRegressor(model, data, q, dq, ddq)[:, 50:60]
        for q, dq, ddq in zip(batch.q[0], batch.dq[0], batch.ddq[0], strict=True)
    ]
    w = np.vstack(rows) * objective.column_scale
    return float(np.linalg.cond(w))


def test_payload_family_moves_the_last_joints_for_the_payload_columns(setup):
    robot, family = setup.robot, setup.family
    assert family.moving_joints == (3, 4, 5)
    assert family.period == pytest.approx(5.0)
    objective = ExcitationObjective(robot, setup.stage, family)
    assert objective.columns == tuple(range(50, 60))  # the payload's, not the arm's base set
    assert objective.rows == tuple(range(6))  # held joints feel the payload
    rng = np.random.default_rng(0)
    x = rng.uniform(family.bounds[:, 0], family.bounds[:, 1])
    batch = family.trajectories(x[None])
    np.testing.assert_array_equal(
        batch.q[0, :, :3], np.tile([0.0, -1.2, 1.0], (batch.n_samples, 1))
    )
    assert np.all(batch.dq[0, :, :3] == 0.0)
    assert np.all(batch.ddq[0, :, :3] == 0.0)
    assert np.ptp(batch.q[0, :, 3:], axis=0).min() > 0.05
    (details,) = objective.details(x[None])
    assert details.cond == pytest.approx(_payload_condition(robot, objective, batch), rel=1e-6)
    # every design of the default box keeps the velocity and acceleration limits
    assert not any(k.startswith(("velocity", "acceleration")) for k in details.violations)


def test_optimized_payload_design_beats_random_designs_of_the_family(setup):
    family = setup.family.with_samples(50)
    objective = ExcitationObjective(setup.robot, setup.stage, family)
    rng = np.random.default_rng(1)
    random = rng.uniform(family.bounds[:, 0], family.bounds[:, 1], (40, len(family.bounds)))
    random_cond = np.array([d.cond for d in objective.details(random)])
    best = minimize(objective, family.bounds, method="pso", rng=2, maxiter=25, popsize=16)
    (chosen,) = objective.details(best.x[None])
    assert chosen.feasible
    assert chosen.cond < 0.5 * np.median(random_cond)
    assert chosen.cond < random_cond.min()


def test_payload_family_refuses_a_stage_that_is_not_the_payloads(setup):
    with pytest.raises(ConfigError, match=r"stage: payload"):
        build_family("payload", setup.robot, whole_chain_stage(setup.robot.chain), {})
    with pytest.raises(ConfigError, match=r"n_moving"):
        build_family("payload", setup.robot, setup.stage, {"n_moving": 9})
    with pytest.raises(ConfigError, match=r"'wrist_1_joint' moves"):
        build_family("payload", setup.robot, setup.stage, {"held": {"wrist_1_joint": 0.0}})


#: the simulated payload: 2.5 kg, its centre of mass 6 cm out of the flange and off its axis
PAYLOAD_MASS = 2.5
PAYLOAD_COM_IN_TOOL0 = np.array([0.01, -0.015, 0.06])  # m, inside configs/ur5-payload.yaml's box
PAYLOAD_SIDES = (0.10, 0.08, 0.12)


@pytest.mark.slow
def test_designed_payload_excitation_recovers_a_simulated_payload(setup, tmp_path):
    """ident run (the design, its certificate, trajectory.csv) -> MuJoCo log with the payload
    -> ident payload: mass within 2 %, centre of mass within 5 mm (the targets)."""
    raw = yaml.safe_load(CONFIG.read_text())
    raw["robot"] = {**raw["robot"], "urdf": str((REPO / "robot/urdf/ur5.urdf").resolve())}
    raw["robot"]["package_dirs"] = [str((REPO / "robot/meshes").resolve())]
    config = tmp_path / "design.yaml"
    config.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "runs"
    result = CliRunner().invoke(
        app, ["run", str(config), "--quick", "--out", str(out), "--no-replay"]
    )
    assert result.exit_code == 0, result.output
    (run,) = out.iterdir()
    assert json.loads((run / "result.json").read_text())["safety"]["ok"]
    table = np.loadtxt(run / "trajectory.csv", delimiter=",", skiprows=1)
    t, q, dq, ddq = table[:, 0], table[:, 1:7], table[:, 7:13], table[:, 13:19]
    np.testing.assert_array_equal(q[:, :3], np.tile([0.0, -1.2, 1.0], (len(t), 1)))
    assert np.ptp(q[:, 3:], axis=0).min() > 0.3  # the wrist moves

    robot = setup.robot
    tool0 = robot.model.frames[robot.model.getFrameId("tool0")]
    assert tool0.parentJoint == robot.model.njoints - 1
    com = tool0.placement.act(PAYLOAD_COM_IN_TOOL0)  # in the last link's frame
    a, b, c = PAYLOAD_SIDES
    m = PAYLOAD_MASS
    inertia = [m * (b * b + c * c) / 12, 0.0, m * (a * a + c * c) / 12, 0.0, 0.0,
               m * (a * a + b * b) / 12]  # fmt: skip
    section = {k: v for k, v in yaml.safe_load((REPO / "configs/ur5.yaml").read_text())[
        "measurement"].items() if k != "source"}  # fmt: skip
    rms = np.sqrt(np.mean(robot.rnea(q, dq, ddq) ** 2, axis=0))
    section.update(
        torque_noise_std=(0.01 * rms).tolist(),  # 1 % torque noise
        settle_periods=0,
        n_periods=1,
        payload={"mass": m, "com": com.tolist(), "inertia": inertia},
    )
    sim = simulate(robot, t, q, dq, ddq, load_mujoco_measurement(section), rng=5)
    files = write_log(tmp_path / "log", sim)
    log = yaml.safe_load(files.yaml.read_text())["log"]
    for key in ("time", "position", "torque"):
        log[key]["path"] = str(tmp_path / "log" / log[key]["path"])
    payload_config = {
        "name": "ur5-payload",
        "robot": {"urdf": raw["robot"]["urdf"]},
        "log": log,
        "preprocess": {
            "lowpass": {"cutoff_hz": 10.0},
            "torque_lowpass": {"cutoff_hz": 10.0},
            "trim_samples": 300,
            "decimation": [10],
            # the held joints' rows carry the payload's gravity: kept
            "velocity_threshold": [0.0, 0.0, 0.0, 0.15, 0.15, 0.15],
        },
        "model": {
            "viscous": [4, 5, 6],
            "coulomb": [4, 5, 6],
            "rotor_inertia": [4, 5, 6],
            "offset": False,
        },  # fmt: skip
        "payload": {"link": "tool0", "arm": "model"},  # the simulated arm is its URDF
    }
    path = tmp_path / "payload.yaml"
    path.write_text(yaml.safe_dump(payload_config, sort_keys=False))
    result = CliRunner().invoke(app, ["payload", str(path), "--out", str(tmp_path / "identified")])
    assert result.exit_code == 0, result.output
    (summary_path,) = (tmp_path / "identified").glob("*/payload.json")
    summary = json.loads(summary_path.read_text())
    assert abs(summary["mass_kg"] - m) < 0.02 * m
    assert np.linalg.norm(np.asarray(summary["com_m"]) - PAYLOAD_COM_IN_TOOL0) < 0.005


def test_payload_box_in_millimetres_is_one_error_line_and_nothing_written(tmp_path):
    raw = yaml.safe_load(CONFIG.read_text())
    raw["robot"]["urdf"] = str((REPO / "robot/urdf/ur5.urdf").resolve())
    raw["robot"]["package_dirs"] = [str((REPO / "robot/meshes").resolve())]
    raw["safety"]["payload_box"]["size"] = [100.0, 80.0, 120.0]  # mm typed as m
    config = tmp_path / "design.yaml"
    config.write_text(yaml.safe_dump(raw, sort_keys=False))
    out = tmp_path / "runs"
    result = CliRunner().invoke(app, ["run", str(config), "--out", str(out), "--no-replay"])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("error: ")
    assert "safety.payload_box.size" in lines[0]
    assert "millimetres" in lines[0]
    assert not out.exists()
