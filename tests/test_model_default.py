"""The default identified model: the physically consistent estimate of every link, written by
``ident run`` and ``ident identify`` as ``<urdf>_identified.urdf`` + ``.xml`` (MJCF) + the
joint extras, reloaded with parity; the cautious copy only on request, under its own name.

References: the simulator's truth (the run's URDF inertials plus the configured friction and
armature) on a trajectory the run never saw (tests/model_truth.py: Pinocchio RNEA of the
written URDF, MuJoCo inverse dynamics of the written MJCF); the consistency of each written
link from its pseudo-inertia.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from model_truth import truth_comparison
from test_core import _wide_log

from ident.identify.estimation.consistency import pseudo_inertia_min_eigenvalue
from ident.identify.model_files.urdf_update import model_of_urdf
from ident.identify.pipeline.core import identify_measurements
from ident.model.selection import RobotSelection, load_robot
from ident.report.identify_report import write_identify_report


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_shipped_run_writes_the_consistent_model_and_it_matches_the_truth(name, shipped_run):
    # configs/ur5.yaml and configs/panda.yaml (hand locked) identify with method: wls; the
    # model written is the LMI estimate beside it (a run wrote no model at all before)
    folder = shipped_run(name)
    data = json.loads((folder / "result.json").read_text())
    model = data["model"]
    assert model["written"], model["note"]
    assert model["method"] == "lmi"
    assert model["elite"] == data["executed_elite"]
    assert model["files"] == {
        "urdf": f"{name}_identified.urdf",
        "mjcf": f"{name}_identified.xml",
        "joint_extras": f"{name}_joint_extras.json",
        "covariance": f"{name}_identified_covariance.json",
    }
    assert max(model["reload_parity"]["urdf"], model["reload_parity"]["mjcf"]) <= 1e-9
    held = model["held_out_relative_residual"]  # consistency costs nothing held out
    assert held["lmi"] <= 1.02 * held["wls"], held
    assert not list(folder.glob("*_cautious.urdf"))
    # every link of the written file is physically consistent
    robot = load_robot(RobotSelection(**data["config"]["robot"]))
    written = model_of_urdf((folder / model["files"]["urdf"]).read_text(), robot.locked_joints)
    for j in range(1, written.njoints):
        assert pseudo_inertia_min_eigenvalue(written.inertias[j].toDynamicParameters()) >= 0
    # its torques on an unseen trajectory: the truth's within 1 % (measured: ~0.2 %)
    errors = truth_comparison(folder)
    assert max(errors.values()) < 0.01, errors
    assert "## Identified model" in (folder / "report.md").read_text()


@pytest.fixture(scope="module")
def wide():
    """The wide-csv example (method: wls) identified once."""
    cfg, log = _wide_log()
    return cfg, log, identify_measurements(cfg, log)


def test_identify_writes_the_consistent_model_by_default_and_the_cautious_copy_on_request(
    wide, tmp_path
):
    cfg, _, result = wide
    assert cfg.estimation.method == "wls"
    assert not result.consistent.estimates["wls"].consistent
    cautious = cfg.urdf_update.model_copy(update={"cautious": True})
    result = type(result)(
        **{**vars(result), "config": cfg.model_copy(update={"urdf_update": cautious})}
    )
    write_identify_report(result, tmp_path, replay=False)
    data = json.loads((tmp_path / "result.json").read_text())
    model = data["model"]
    assert model["written"]
    assert model["method"] == "lmi"
    assert max(model["reload_parity"]["urdf"], model["reload_parity"]["mjcf"]) <= 1e-9
    assert data["urdf"]["file"] == "arm3_cautious.urdf"
    identified = (tmp_path / "arm3_identified.urdf").read_text()
    copy = (tmp_path / "arm3_cautious.urdf").read_text()
    # the identified model is the LMI estimate of every link (the WLS fit's links are
    # inconsistent here, so a write-back of WLS values would fail), not the cautious copy
    theta = result.model.constrained.theta
    index = result.model.structure.bodies
    robot = load_robot(cfg.robot)
    for text, same in ((identified, True), (copy, False)):
        reloaded = model_of_urdf(text, robot.locked_joints)
        bodies = np.array([reloaded.inertias[j].toDynamicParameters() for j in (1, 2, 3)])
        assert np.allclose(bodies, theta[index], rtol=1e-9, atol=1e-12) is same
    report = (tmp_path / "report.md").read_text()
    assert "- `arm3_identified.urdf`: **the identified model**" in report
    assert "- `arm3_cautious.urdf`: the cautious copy" in report


def test_model_none_writes_no_model_and_says_so(wide, tmp_path):
    cfg, log, _ = wide
    cfg = cfg.model_copy(
        update={"urdf_update": cfg.urdf_update.model_copy(update={"model": "none"})}
    )
    result = identify_measurements(cfg, log)
    assert result.model is None
    assert "lmi" not in result.predictions
    write_identify_report(result, tmp_path, replay=False)
    assert [p.name for p in tmp_path.glob("*.urdf")] == ["robot.urdf"]  # the replay's copy
    assert not list(tmp_path.glob("*.xml"))
    assert json.loads((tmp_path / "result.json").read_text())["model"]["note"] == (
        "no model written: urdf_update.model is none"
    )
    assert (
        "No model file: no model written: urdf_update.model is none."
        in (tmp_path / "report.md").read_text()
    )
