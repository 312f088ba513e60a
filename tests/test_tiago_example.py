"""The TIAGo example (configs/examples/tiago.yaml): a real robot's log, identified from the
config alone through the CLI; held-out residual against the URDF's nominal; the consistent
model written and reloaded."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from typer.testing import CliRunner

from ident.cli import app
from ident.identify.estimation.consistency import pseudo_inertia_min_eigenvalue
from ident.identify.model_files.files import reload_parity, write_model_files
from ident.identify.model_files.urdf_update import model_of_urdf
from ident.model.selection import load_robot
from ident.robot.inertia import PINOCCHIO_ORDER

ROOT = Path(__file__).resolve().parents[1]
CONFIG = ROOT / "configs" / "examples" / "tiago.yaml"
ARM = ["arm_1_joint", "arm_2_joint", "arm_3_joint", "arm_4_joint"]  # the excited arm joints


@pytest.fixture(scope="module")
def run(tiago_identified):
    """``ident identify configs/examples/tiago.yaml --out TMP``, and the result it computed
    (tests/conftest.py: shared with tests/test_one_std.py)."""
    return tiago_identified


def test_tiago_held_out_residual_beats_the_urdf_nominal(run):
    output, _, summary, _ = run
    held_out = {k: v["all_samples"] for k, v in summary["validation"].items()}
    total = {k: v["total_relative_residual"] for k, v in held_out.items()}
    # pinned (measured 2026-11: WLS 0.1119, LMI 0.1111, URDF nominal 9.248; the nominal has
    # no offset for the torso's gravity compensation, 183 N of its 0.19 N-residual joint)
    assert total["identified"] == pytest.approx(0.1119, rel=0.03)
    assert total["lmi"] == pytest.approx(0.1111, rel=0.03)
    assert total["URDF nominal"] == pytest.approx(9.248, rel=0.03)
    assert total["lmi"] <= total["identified"] * 1.02  # consistency costs nothing held out
    # and per arm joint, without the torso: ident's RMSE at most half the URDF's
    joints = list(summary["residual_rms"])
    for name in ARM:
        j = joints.index(name)
        assert held_out["identified"]["rmse"][j] < 0.5 * held_out["URDF nominal"]["rmse"][j]
        assert held_out["lmi"]["rmse"][j] < 0.5 * held_out["URDF nominal"]["rmse"][j]
    assert "held-out URDF nominal: relative residual 9.2" in output
    assert "held-out lmi: relative residual 0.111" in output


def test_tiago_verdict_reads_as_its_numbers_say(run):
    # usable: held-out residual 11 % (URDF nominal 925 %) predicts torques it was not fitted
    # to; not good: the log's warnings (unexcited torso and wrist parameters) rule it out
    output, _, summary, _ = run
    v = summary["verdict"]
    assert (v["label"], v["rule"]) == ("usable", "log"), v
    assert 0.10 <= v["residual"] < 0.25, v
    assert v["warnings"], v
    assert f"verdict: {v['label']} ({v['reason']})" in output


def test_tiago_consistent_model_is_written_and_reloads(run, tmp_path):
    _, folder, _, result = run
    consistent = result.consistent
    theta, names = consistent.constrained.theta, consistent.structure.names
    robot = load_robot(result.config.robot)  # torso + arm; wheels, head, gripper locked
    files = write_model_files(
        robot, theta, names, tmp_path, "tiago", nominal=consistent.structure.nominal
    )
    # the CLI's identified model is these files (the rest of the user's file unchanged)
    assert (folder / "tiago_48_schunk_identified.urdf").read_text() == files.urdf.text
    assert (folder / "tiago_48_schunk_identified.xml").read_text() == files.mjcf
    assert (folder / "tiago_48_schunk_joint_extras.json").read_text() == files.extras_json
    assert not list(folder.glob("*_cautious.urdf"))  # the cautious copy only when asked
    recorded = json.loads((folder / "result.json").read_text())["model"]
    assert recorded["written"]
    assert recorded["method"] == "lmi"
    assert max(recorded["reload_parity"]["urdf"], recorded["reload_parity"]["mjcf"]) < 1e-9
    held = recorded["held_out_relative_residual"]  # the consistent model vs WLS, held out
    assert held["lmi"] <= 1.02 * held["wls"]
    # reloaded: Pinocchio RNEA of the URDF, MuJoCo inverse dynamics of the MJCF (no meshes)
    parity = reload_parity(robot, files, theta, names)
    assert parity.urdf_relative_error < 1e-9
    assert parity.mjcf_relative_error < 1e-9

    # every identified link of the written file is physically consistent, as estimated
    full = pin.buildModelFromUrdf(str(files.paths["urdf"]))  # the whole robot loads
    assert full.existJointName("head_1_joint")
    assert full.existJointName("wheel_left_joint")
    reloaded = model_of_urdf(files.urdf.text, robot.locked_joints)
    index = {name: i for i, name in enumerate(names)}
    for j in range(1, reloaded.njoints):
        written = reloaded.inertias[j].toDynamicParameters()
        estimated = theta[[index[f"{label}{j}"] for label in PINOCCHIO_ORDER]]
        np.testing.assert_allclose(written, estimated, rtol=1e-9, atol=1e-12)
        assert pseudo_inertia_min_eigenvalue(written) >= -1e-12


def test_tiago_replay_is_written_with_the_locked_base_head_and_gripper(run, tmp_path):
    """The measured motion replays on the identified chain (wheels, head, gripper locked):
    in the run folder and again with ``ident replay`` on it (the config's selection)."""
    from ident.trajectory import read_trajectory_csv

    _, folder, _, _ = run
    state = json.loads((folder / "run.json").read_text())
    assert state["replay"].startswith("replay.html written"), state["replay"]
    assert (folder / "replay.html").is_file()
    out = tmp_path / "again.html"
    cli = CliRunner().invoke(app, ["replay", str(folder), "--html", str(out)])
    assert cli.exit_code == 0, cli.output
    assert "traced frame" in cli.output
    motion = read_trajectory_csv(folder / "trajectory.csv", allow_positions_only=True)
    span = motion.t[-1] - motion.t[0]  # one segment: frames = span x 30 fps + 1
    assert f"{span:.2f} s at speed 1" in cli.output
