"""``ident run`` never reports an unsafe trajectory as usable.

References: the written ``trajectory.csv`` re-checked independently with plain Pinocchio + coal
(the URDF's collision geometry and a floor half-space) at its 1 kHz samples, and the robot's
limits; and the paper's arm stage, whose trajectories go through the floor and the pedestal.
"""

import json
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from ident.cli import app
from ident.model import Robot
from ident.trajectory import read_trajectory_csv

REPO = Path(__file__).resolve().parents[1]
runner = CliRunner()


def _only(folder: Path) -> Path:
    (path,) = [p for p in folder.iterdir() if p.is_dir()]
    return path


def test_written_trajectory_keeps_clear_of_the_floor_and_within_limits(tmp_path) -> None:
    config = REPO / "tests" / "data" / "run" / "quick-wrist.yaml"
    result = runner.invoke(app, ["run", str(config), "--out", str(tmp_path), "--no-replay"])
    assert result.exit_code == 0, result.output
    run = _only(tmp_path)
    traj = read_trajectory_csv(run / "trajectory.csv")
    assert np.all(np.diff(traj.t) <= 1e-3 + 1e-12)  # the controller's rate, 1 kHz
    # it starts and ends at rest (approach and return)
    np.testing.assert_allclose(traj.dq[[0, -1]], 0.0, atol=1e-9)
    robot = Robot.from_config("configs/paper6r.yaml")
    assert np.all(traj.q >= robot.q_lower - 1e-9)
    assert np.all(traj.q <= robot.q_upper + 1e-9)
    assert np.all(np.abs(traj.dq) <= robot.dq_max + 1e-9)
    assert np.all(np.abs(traj.ddq) <= robot.ddq_max + 1e-9)
    # independent: every link's collision geometry above the floor by the 3 cm margin
    text = (run / "robot.urdf").read_text()
    model = pin.buildModelFromXML(text)
    geom = pin.buildGeomFromUrdfString(model, text, pin.GeometryType.COLLISION)
    n_robot = len(geom.geometryObjects)
    floor = coal.Halfspace(np.array([0.0, 0.0, 1.0]), 0.0)
    geom.addGeometryObject(pin.GeometryObject("floor", 0, 0, pin.SE3.Identity(), floor))
    # the pedestal stands on the floor and link 1 turns about its vertical axis on it: their
    # height never changes; every link from joint 2 on can go down
    moving = [
        k
        for k, o in enumerate(geom.geometryObjects[:n_robot])
        if model.frames[o.parentFrame].parentJoint >= 2
    ]
    for k in moving:
        geom.addCollisionPair(pin.CollisionPair(k, n_robot))
    data, gdata = model.createData(), pin.GeometryData(geom)
    smallest = np.inf
    for q in traj.q:
        pin.computeDistances(model, data, geom, gdata, q)
        smallest = min(smallest, min(r.min_distance for r in gdata.distanceResults))
    assert smallest >= 0.03 - 1e-6


@pytest.mark.slow
def test_the_papers_arm_stage_is_reported_unsafe_with_pair_and_time(tmp_path) -> None:
    result = runner.invoke(
        app, ["run", "configs/arm.yaml", "--quick", "--out", str(tmp_path), "--no-replay"]
    )
    assert result.exit_code == 1, result.output
    assert "error: no elite trajectory is safe; elite 1 is unsafe: clearance:" in result.stderr
    assert " at t = " in result.stderr
    run = _only(tmp_path)
    assert not (run / "trajectory.csv").exists()  # nothing a robot could be given
    assert (run / "result.json").is_file()  # the design data are kept for inspection
    # configs/arm.yaml's verdict: refused (exit 1), "unsafe" however well it would identify
    verdict = json.loads((run / "result.json").read_text(encoding="utf-8"))["verdict"]
    assert verdict["label"] == "unsafe", verdict
    assert _statuses(run) == (("complete", "run complete"),) * 2


def _statuses(run: Path) -> tuple[tuple[str, str], tuple[str, str]]:
    """(status, message) of run.json and of result.json."""
    state = json.loads((run / "run.json").read_text(encoding="utf-8"))
    data = json.loads((run / "result.json").read_text(encoding="utf-8"))
    return (state["status"], state["message"]), (data["status"], data["message"])


@pytest.mark.slow
def test_an_unsafe_run_whose_identification_fails_exits_1_naming_the_pair(
    tmp_path, monkeypatch
) -> None:
    """configs/arm.yaml (unsafe) whose simulated torques of joint_2 turn NaN at sample 6: the
    run still exits 1 naming the link pair and the time, then the measurement's cause (the
    joint, the time, the run's own simulation); with the replay on, which read the elite's
    CSV of NaN torques and ended the run with exit 2 and 'non-finite value in column'."""
    import dataclasses

    import ident.run.elite_identification as elite_identification

    original = elite_identification.simulate_measurements

    def nan_from_sample_6(*args, **kwargs):
        meas = original(*args, **kwargs)
        tau = meas.tau.copy()
        tau[6:, 1] = np.nan
        return dataclasses.replace(meas, tau=tau)

    monkeypatch.setattr(elite_identification, "simulate_measurements", nan_from_sample_6)
    result = runner.invoke(app, ["run", "configs/arm.yaml", "--quick", "--out", str(tmp_path)])
    assert result.exit_code == 1, result.output
    unsafe = "error: no elite trajectory is safe; elite 1 is unsafe: clearance:"
    (line,) = [x for x in result.stderr.splitlines() if x.startswith(unsafe)]
    assert " at t = " in line
    run = _only(tmp_path)
    t6 = read_trajectory_csv(run / "elites" / "elite_1.csv").t[6]  # the commanded time
    assert (
        "error: elite 1, wls: the run's own simulated measurement of elite 1 is not finite: "
        f"the torque of joint_2 at t = {t6:.4g} s is nan" in result.stderr
    )
    assert "non-finite value in column" not in result.output
    assert (run / "replay.html").is_file()
    assert "tau_" not in (run / "elites" / "elite_1.csv").read_text().splitlines()[0]
    assert _statuses(run) == (("complete", "run complete"),) * 2


@pytest.mark.slow
def test_elites_a_little_inside_the_margin_are_optimized_again_with_a_wider_one(tmp_path):
    """The optimizer's clearance term sees 6 samples per period; a ball above the wrist puts
    both elites of the first optimization 1.5-2.7 mm inside the 30 mm margin between those
    samples (seed 3). Instead of no trajectory, the run optimizes again with the optimizer's
    margin at 30 + 2 x 2.7 -> 37.5 mm, the certificate's staying 30 mm, and writes a
    trajectory that plain Pinocchio + coal find >= 30 mm from the ball at every 1 kHz sample
    (a run without the retry has no executable trajectory; one that loosened the certificate's
    margin instead would fail this check)."""
    import yaml

    source = REPO / "tests" / "data" / "run" / "quick-wrist.yaml"
    cfg = yaml.safe_load(source.read_text())
    cfg["robot"] = str(REPO / "configs" / "paper6r.yaml")
    ball = np.array([1.583, 0.0, 0.75])
    cfg["safety"] = {
        "clearance_m": 0.03,
        "check_samples": 6,
        "obstacles": [{"name": "ball", "sphere": {"radius": 0.05, "position": ball.tolist()}}],
    }
    config = tmp_path / "ball.yaml"
    config.write_text(yaml.safe_dump(cfg))
    from ident.run.config import load_run_config
    from ident.run.pipeline import run_pipeline

    events = []
    plan = run_pipeline(load_run_config(config), progress=events.append).executable
    assert plan.usable, plan.message
    assert "optimized again with the optimizer's margin at 37.5 mm" in plan.message
    # the retry is announced when it starts (the terminal says the estimate's worst case
    # applies), between the two optimizations
    phases = [e.phase for e in events]
    k = phases.index("retry")
    assert "run_done" in phases[:k]
    assert "optimize" in phases[k:]
    assert events[k].payload.startswith("no elite kept the 30 mm margin")
    traj = plan.trajectory
    robot = Robot.from_config("configs/paper6r.yaml")
    model = pin.buildModelFromXML(robot.urdf_text)
    geom = pin.buildGeomFromUrdfString(model, robot.urdf_text, pin.GeometryType.COLLISION)
    n_links = len(geom.geometryObjects)
    sphere = pin.GeometryObject("ball", 0, 0, pin.SE3(np.eye(3), ball), coal.Sphere(0.05))
    geom.addGeometryObject(sphere)
    for a in range(n_links):
        geom.addCollisionPair(pin.CollisionPair(a, n_links))
    data, gdata = model.createData(), pin.GeometryData(geom)
    smallest = np.inf
    for q in traj.q:
        pin.computeDistances(model, data, geom, gdata, q)
        smallest = min(smallest, min(r.min_distance for r in gdata.distanceResults))
    assert 0.03 <= smallest < 0.045  # kept, and the ball was what limited the motion
