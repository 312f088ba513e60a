"""``ident run`` with ``controller.export``: the files are written, listed, and equal the run's
``trajectory.csv``; a robot a controller cannot drive stops before the run folder exists; an
unsafe run exports nothing."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from typer.testing import CliRunner

from ident.cli import app
from ident.run.exports import registry
from ident.run.exports.common import ExportError
from ident.run.exports.registry import EXPORT_FOLDER
from ident.run.exports.run_exports import export_run
from ident.trajectory import read_trajectory_csv

QUICK = Path(__file__).parent / "data" / "run" / "quick-wrist.yaml"
PAPER6R = QUICK.parents[3] / "configs" / "paper6r.yaml"
runner = CliRunner()


def quick_config(tmp_path: Path, export: str) -> Path:
    text = QUICK.read_text().replace("robot: ../../../configs/paper6r.yaml", f"robot: {PAPER6R}")
    path = tmp_path / "quick-export.yaml"
    path.write_text(text + f"controller: {{export: {export}}}\n")
    return path


def refuse(trajectory, target):
    raise ExportError("toy: joint 'joint_4' velocity too high at t = 1 s")


@pytest.fixture(scope="module")
def exported_run(tmp_path_factory):
    """One quick run with ros2 and a toy export that always refuses (registered for the run)."""
    tmp = tmp_path_factory.mktemp("exports-run")
    config = quick_config(tmp, "[ros2, toy]")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(registry, "EXPORTERS", dict(registry.EXPORTERS))
        registry.register_exporter("toy", registry.Exporter(refuse, None, None))  # type: ignore[arg-type]
        result = runner.invoke(app, ["run", str(config), "--out", str(tmp / "runs"), "--no-replay"])
    (run_dir,) = [d for d in (tmp / "runs").iterdir() if d.is_dir()]
    return run_dir, result


@pytest.mark.slow
def test_run_writes_the_export_and_lists_it(exported_run):
    run_dir, result = exported_run
    output = result.output
    exports = run_dir / EXPORT_FOLDER
    assert sorted(p.name for p in exports.iterdir()) == [
        "joint_trajectory.yaml",
        "joint_trajectory_bag",
    ]
    assert "Export ros2: exports/joint_trajectory.yaml, exports/joint_trajectory_bag" in output
    state = json.loads((run_dir / "run.json").read_text())
    refusal = "toy: joint 'joint_4' velocity too high at t = 1 s"
    assert state["exports"] == [
        "ros2: exports/joint_trajectory.yaml, exports/joint_trajectory_bag",
        f"REFUSED {refusal}",
    ]
    report = (run_dir / "report.md").read_text()
    assert "- Exports (`docs/execute.md`): ros2: exports/joint_trajectory.yaml" in report
    assert f"REFUSED {refusal}" in report


@pytest.mark.slow
def test_a_refused_export_is_an_error_line_and_exit_2_after_everything_is_saved(exported_run):
    run_dir, result = exported_run
    assert result.exit_code == 2, result.output
    assert "error: export refused: toy: joint 'joint_4' velocity too high at t = 1 s" in (
        result.output
    )
    state = json.loads((run_dir / "run.json").read_text())
    assert state["status"] == "complete"
    assert (run_dir / "report.md").is_file()
    assert (run_dir / "trajectory.csv").is_file()


@pytest.mark.slow
def test_the_export_is_the_runs_trajectory_csv(exported_run):
    run_dir, _ = exported_run
    plan = read_trajectory_csv(run_dir / "trajectory.csv")
    text = (run_dir / EXPORT_FOLDER / "joint_trajectory.yaml").read_text()
    message = yaml.load(text, Loader=yaml.CSafeLoader)  # libyaml: the pure-Python one takes 30 s
    assert tuple(message["joint_names"]) == plan.joint_names
    points = message["points"]
    t = np.array(
        [p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"] for p in points]
    )
    np.testing.assert_allclose(t, plan.t, rtol=0, atol=1e-9)
    for key, expected in (
        ("positions", plan.q),
        ("velocities", plan.dq),
        ("accelerations", plan.ddq),
    ):
        np.testing.assert_allclose(np.array([p[key] for p in points]), expected, rtol=0, atol=1e-9)


def test_an_export_the_robot_cannot_run_stops_before_the_run_folder(tmp_path):
    result = runner.invoke(
        app, ["run", str(quick_config(tmp_path, "[ros2, franka]")), "--out", str(tmp_path / "runs")]
    )
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1
    assert lines[0].startswith("error: ")
    assert "controller.export: franka: libfranka commands 7 joints" in lines[0]
    assert not (tmp_path / "runs").exists()


def test_an_unknown_export_name_is_one_line_listing_the_valid_ones(tmp_path):
    result = runner.invoke(
        app, ["run", str(quick_config(tmp_path, "[ros2, mcap]")), "--out", str(tmp_path / "runs")]
    )
    assert result.exit_code == 2
    assert "'mcap' is not a known export" in result.output
    assert "valid: ros2, urscript, franka" in result.output
    assert not (tmp_path / "runs").exists()


def test_an_unsafe_run_exports_nothing(tmp_path):
    plan = SimpleNamespace(usable=False, trajectory=None)
    result = SimpleNamespace(
        config=SimpleNamespace(controller=SimpleNamespace(export=["ros2", "franka"])),
        executable=plan,
        urdf_text="<robot name='x'/>",
    )
    outcome = export_run(result, tmp_path)
    assert outcome.written == {}
    assert set(outcome.refused) == {"ros2", "franka"}
    assert all("no trajectory certified safe" in why for why in outcome.refused.values())
    assert not (tmp_path / EXPORT_FOLDER).exists()
