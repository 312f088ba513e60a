"""Residuals and held-out errors carry each joint's torque unit: N*m for a revolute joint, N
for a prismatic one, in the terminal summary, report.md and result.json of ``ident identify``."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import rp2_identify_config
from typer.testing import CliRunner

from ident.cli import app

ROOT = Path(__file__).resolve().parents[1]
URDF = ROOT / "tests" / "data" / "urdf" / "rp2.urdf"
RATE_HZ = 100.0


@pytest.fixture(scope="module")
def rp2_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rp2")
    res = CliRunner().invoke(
        app, ["identify", str(rp2_identify_config(tmp)), "--out", str(tmp / "runs"), "--no-replay"]
    )
    assert res.exit_code == 0, res.output
    (run_dir,) = (tmp / "runs").iterdir()
    return res.output, run_dir


def _urdf_units() -> dict[str, str]:
    """The reference: each moving joint's type as the URDF file declares it."""
    import xml.etree.ElementTree as ET

    unit = {"revolute": "N*m", "continuous": "N*m", "prismatic": "N"}
    joints = ET.parse(URDF).getroot().iter("joint")
    return {j.get("name"): unit[j.get("type")] for j in joints if j.get("type") != "fixed"}


def test_joint_units_follow_the_urdf_joint_types():
    from ident.identify.assessment.sanity import joint_units

    model = pin.buildModelFromUrdf(str(URDF))
    names = [model.names[i] for i in range(1, model.njoints)]
    assert dict(zip(names, joint_units(model), strict=True)) == _urdf_units()
    assert _urdf_units() == {"shoulder": "N*m", "slider": "N"}


def test_terminal_shows_each_joints_unit(rp2_run):
    output, run_dir = rp2_run
    data = json.loads((run_dir / "result.json").read_text())
    lines = [line for line in output.splitlines() if "RMSE per joint" in line]
    assert lines
    for line in lines:
        assert "[N*m]" not in line
        values = re.search(r"RMSE per joint (.*)$", line).group(1)
        assert re.fullmatch(r"\S+ N\*m, \S+ N", values), line
    # the numbers are result.json's held-out errors (3 digits)
    identified = next(line for line in lines if line.startswith("held-out identified"))
    rmse = [float(v.split()[0]) for v in identified.split("RMSE per joint ")[1].split(", ")]
    expected = data["validation"]["identified"]["above_velocity_threshold"]["rmse"]
    np.testing.assert_allclose(rmse, expected, rtol=5e-3)


def test_report_and_result_json_show_each_joints_unit(rp2_run):
    _, run_dir = rp2_run
    md = (run_dir / "report.md").read_text()
    assert "| RMSE shoulder [N*m] | RMSE slider [N] |" in md
    assert re.search(r"^\| shoulder \| \S+ N\*m \| \S+ N\*m \|$", md, re.MULTILINE)
    assert re.search(r"^\| slider \| \S+ N \| \S+ N \|$", md, re.MULTILINE)
    assert "[N*m]" not in md.split("## Residuals on the identification part")[1].split("##")[0]
    data = json.loads((run_dir / "result.json").read_text())
    assert data["joint_units"] == _urdf_units()
    assert "RMSE slider [N]" in (run_dir / "report.html").read_text()


def test_parameter_units_follow_the_joint_type(rp2_run):
    """parameters.csv and the report's base-parameter table: the slider's friction in N*s/m
    and N (a revolute-only labelling would say N*m*s/rad and N*m), the shoulder's in N*m."""
    import csv

    _, run_dir = rp2_run
    with (run_dir / "parameters.csv").open() as f:
        units = {row["name"]: row["unit"] for row in csv.DictReader(f)}
    # 1-based joint numbers in the URDF's order: 1 shoulder (revolute), 2 slider (prismatic)
    expected = {"fv1": "N*m*s/rad", "fs1": "N*m", "fv2": "N*s/m", "fs2": "N"}
    assert {k: units[k] for k in expected} == expected
    assert all(units[name] for name in units), units  # every base parameter has a unit
    md = (run_dir / "report.md").read_text()
    assert re.search(r"^\| \d+ \| fv2 \| N\*s/m \|", md, re.MULTILINE)
    assert re.search(r"^\| \d+ \| fs1 \| N\*m \|", md, re.MULTILINE)


def test_parameter_unit_without_joint_types_is_revolute():
    from ident.identify.assessment.metrics import parameter_unit

    assert parameter_unit("fv2") == "N*m*s/rad"
    assert parameter_unit("fv2", ("N*m", "N")) == "N*s/m"
    assert parameter_unit("Ia2R", ("N*m", "N")) == "kg"
    assert parameter_unit("off1", ("N*m", "N")) == "N*m"
    assert parameter_unit("fvm2", ("N*m", "N")) == "N*m*s/rad"  # motors turn
    assert parameter_unit("Izz2R", ("N*m", "N")) == "kg*m^2"


def test_torque_plot_labels_each_joints_unit(monkeypatch):
    """The held-out torque figure: the slider's panel in N, the shoulder's in N*m."""
    from ident.report import plots

    captured = {}

    def capture(fig, **_kw):
        captured["labels"] = [ax.get_ylabel() for ax in fig.axes]
        return b""

    monkeypatch.setattr(plots, "figure_png", capture)
    t = np.linspace(0.0, 1.0, 20)
    tau = np.zeros((20, 2))
    plots.torque_png(t, tau, {"wls": tau}, ["shoulder", "slider"], units=("N*m", "N"))
    assert captured["labels"] == ["shoulder\n[N*m]", "slider\n[N]"]


def test_run_result_json_carries_each_joints_unit():
    """``ident run``'s result.json (robot.joint_units) and so its report's residual RMS: from the
    URDF's joint types, for the joints the run uses."""
    from types import SimpleNamespace

    from ident.report.run_data import _joint_units

    result = SimpleNamespace(urdf_text=URDF.read_text(), joint_names=("shoulder", "slider"))
    assert _joint_units(result) == [_urdf_units()[n] for n in ("shoulder", "slider")]
    assert _joint_units(result) == ["N*m", "N"]
