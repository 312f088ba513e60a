"""`ident verify` end to end: the paper robot, UR5 (a URDF nobody here wrote), bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from robots import ERD_ROBOTS, PANDA_URDF
from robots import UR5_URDF as UR5
from typer.testing import CliRunner

from ident.cli import app
from ident.dynamics.pinocchio_check import pinocchio_regressor
from ident.model import Robot

ROOT = Path(__file__).parents[1]
DATA = Path(__file__).parent / "data" / "urdf"


def _run(*args: object):
    return CliRunner().invoke(app, ["verify", *map(str, args)])


def _pinocchio_rank(robot: Robot, samples: int, seed: int) -> int:
    """Rank of the stacked Pinocchio regressor on the states verify draws (independent check)."""
    q, dq, ddq = robot.random_configurations(samples, rng=seed)
    W = pinocchio_regressor(robot.model, q, dq, ddq).reshape(-1, 10 * robot.n_bodies)
    return int(np.linalg.matrix_rank(W))


def test_verify_json_on_the_paper_robot() -> None:
    result = _run("--robot", ROOT / "configs/paper6r.yaml", "--samples", 60, "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["n_samples"] == 60
    assert report["max_abs_error"] < 1e-9
    assert report["max_rel_error"] < 1e-9
    assert report["rnea_max_rel_error"] < 1e-9
    assert report["passed"] is True
    robot = Robot.from_config(ROOT / "configs/paper6r.yaml")
    assert report["rank"] == _pinocchio_rank(robot, 60, 0)
    total = report["n_independent"] + report["n_dependent"] + report["n_unidentifiable"]
    assert total == 60
    assert set(report["stages"]) == {"wrist", "arm"}
    for stage in report["stages"].values():
        qr, sequential = stage["methods"]["qr"], stage["methods"]["sequential"]
        assert qr["rank"] == sequential["rank"]
        assert qr["n_params"] == 30
        # the rank does not depend on the frames the parameters are expressed in
        assert stage["dh_frames"]["qr"]["rank"] == qr["rank"]
    assert report["stages"]["wrist"]["bodies"] == [4, 5, 6]


def test_verify_table_on_ur5() -> None:
    result = _run("--urdf", UR5, "--samples", 40, "--seed", 3)
    assert result.exit_code == 0, result.output
    assert "ok" in result.stdout
    assert "FAILED" not in result.stdout
    assert "wrist" in result.stdout
    json_result = _run("--urdf", UR5, "--samples", 40, "--seed", 3, "--json")
    report = json.loads(json_result.stdout)
    assert report["max_rel_error"] < 1e-9
    assert report["rank"] == _pinocchio_rank(Robot.from_urdf(UR5), 40, 3)
    assert str(report["rank"]) in result.stdout


def test_verify_prismatic_fixture_has_no_stages() -> None:
    report = json.loads(_run("--urdf", DATA / "rp2.urdf", "--samples", 10, "--json").stdout)
    assert report["n_joints"] == 2
    assert report["stages"] == {}
    assert report["max_abs_error"] < 1e-12


def test_verify_bad_input_gives_one_error_line(tmp_path: Path) -> None:
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='x'><link name='a'></robot>")
    fixture = (DATA / "continuous.urdf").read_text()
    negative_mass = tmp_path / "negative_mass.urdf"
    negative_mass.write_text(fixture.replace('<mass value="1.0"/>', '<mass value="-1"/>'))
    triangle = tmp_path / "triangle.urdf"
    triangle.write_text(
        fixture.replace('ixx="0.01"', 'ixx="1"')
        .replace('iyy="0.01"', 'iyy="1"')
        .replace('izz="0.01"', 'izz="5"')
    )
    cases = [
        (
            ("--urdf", DATA / "branched.urdf"),
            ["branched.urdf", "pin.buildReducedModel", "--lock right_joint"],
        ),
        (
            ("--urdf", negative_mass),
            ["negative_mass.urdf", "link 'wheel'", "mass = -1 kg must be > 0", "fix the link"],
        ),
        (
            ("--urdf", triangle),
            ["triangle.urdf", "link 'wheel'", "triangle inequality", "I1 + I2 >= I3", "fix"],
        ),
        (
            ("--urdf", PANDA_URDF),
            ["panda.urdf", "branched", "--lock panda_finger_joint1 --lock panda_finger_joint2"],
        ),
        (
            ("--urdf", PANDA_URDF, "--lock", "panda_finger_joint1", "--lock", "panda_fnger_joint2"),
            ["panda.urdf", "'panda_fnger_joint2'", "did you mean 'panda_finger_joint2'"],
        ),
        (
            ("--urdf", PANDA_URDF, "--lock", "panda_finger_joint1=0.1"),
            ["panda_finger_joint1", "outside its limits [0, 0.04]"],
        ),
        (("--urdf", PANDA_URDF, "--lock", "panda_finger_joint1=open"), ["'open' is not a number"]),
        (("--urdf", PANDA_URDF, "--lock", "=1"), ["give a joint name"]),
        (("--urdf", PANDA_URDF, "--lock", "a", "--lock", "a=1"), ["locked twice"]),
        (("--robot", ROOT / "configs/paper6r.yaml", "--lock", "joint_1"), ["--urdf only"]),
        (("--urdf", tmp_path / "missing.urdf"), ["missing.urdf", "not found"]),
        (("--urdf", broken), ["broken.urdf", "malformed"]),
        (("--urdf", DATA / "rp2.urdf", "--robot", "configs/paper6r.yaml"), ["exactly one"]),
        ((), ["exactly one"]),
        (("--urdf", DATA / "rp2.urdf", "--samples", 0), ["--samples"]),
    ]
    for args, words in cases:
        result = _run(*args)
        assert result.exit_code == 2, (args, result.output)
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1, lines
        assert lines[0].startswith("error: ")
        for word in words:
            assert word in lines[0], (word, lines[0])


def test_verify_panda_with_its_fingers_locked() -> None:
    args = ["--urdf", PANDA_URDF, "--samples", 30, "--seed", 1, "--json"]
    args += ["--lock", "panda_finger_joint1", "--lock", "panda_finger_joint2=0.03"]
    result = _run(*args)
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert report["n_joints"] == 7
    assert report["locked_joints"] == {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.03}
    assert report["max_rel_error"] < 1e-9
    assert report["rnea_max_rel_error"] < 1e-9
    assert report["passed"] is True
    locked = Robot.from_urdf(PANDA_URDF, lock_joints=report["locked_joints"])
    assert report["rank"] == _pinocchio_rank(locked, 30, 1)
    table = _run(*[a for a in args if a != "--json"])
    assert table.exit_code == 0, table.output
    assert "panda_finger_joint2 = 0.03" in " ".join(table.stdout.split())


def test_verify_continuous_joints() -> None:
    """kinova has three continuous joints, the fixture one: verified as revolute joints."""
    kinova = ERD_ROBOTS / "kinova_description/robots/kinova.urdf"
    report = json.loads(_run("--urdf", kinova, "--samples", 30, "--json").stdout)
    assert report["n_joints"] == 6
    assert report["continuous_joints"] == [
        "j2s6s200_joint_1",
        "j2s6s200_joint_4",
        "j2s6s200_joint_6",
    ]
    assert report["max_rel_error"] < 1e-9
    assert report["passed"] is True
    assert report["ranks_agree"] is True
    result = _run("--urdf", DATA / "continuous.urdf", "--samples", 10, "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["continuous_joints"] == ["wheel_joint"]
