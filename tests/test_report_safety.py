"""Safety plots of a run report: the compact series of a dense check, the figures, the table.

Reference for the reduction: the full series of a synthetic SafetyReport reduced by plain
numpy (min over pairs, max over joints, no decimation); for a run: the elite's own check
summary (written from the same SafetyReport) and the figure files.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from ident.cli import app
from ident.excitation.check import ConstraintCheck, SafetyReport
from ident.excitation.safety_series import safety_series, worst_checks
from ident.report.safety_section import chosen_elite, safety_headline, safety_section

QUICK = Path(__file__).parent / "data" / "run" / "quick-wrist.yaml"


def _report(n: int = 10_001) -> SafetyReport:
    t = np.linspace(0.0, 10.0, n)
    clearance = np.column_stack([0.2 + 0.1 * np.sin(t), 0.05 + 0.02 * np.cos(3 * t + 0.1)])
    vel = np.column_stack([0.5 * np.abs(np.sin(t)), 0.3 * np.ones(n)])
    acc = np.column_stack([0.1 * t, 0.2 * np.ones(n)])
    tau = np.column_stack([1.2 * np.abs(np.cos(0.7 * t)), 0.1 * np.ones(n)])
    i = int(np.argmin(clearance[:, 1]))
    k = int(np.argmax(tau[:, 0]))
    checks = (
        ConstraintCheck("clearance:a|b", "clearance", 0.15, 0.03, 0.0, -0.12),
        ConstraintCheck("clearance:c|floor", "clearance", clearance[i, 1], 0.03, t[i], -0.0),
        ConstraintCheck("torque:j1", "torque", 12.0, 10.0, t[k], 2.0, 1.2),
        ConstraintCheck("velocity:j1", "velocity", 0.5, 1.0, 1.5, -0.5, 0.5),
    )
    return SafetyReport(
        False, 1000.0, "none", t, ("a|b", "c|floor"), clearance, vel, acc, tau, checks
    )


def test_series_keep_the_extremes_of_the_full_check():
    report = _report()
    s = safety_series(report, max_points=500)
    assert len(s["t"]) <= 500
    assert all(len(s[k]) == len(s["t"]) for k in ("min_clearance", "torque_ratio"))
    full_min = report.clearance.min(axis=1)
    assert min(s["min_clearance"]) == pytest.approx(full_min.min(), abs=0.0)
    assert s["closest_clearance"] == pytest.approx(full_min.min(), abs=0.0)
    assert s["closest_pair"] == "c|floor"
    assert max(s["torque_ratio"]) == pytest.approx(report.torque_ratio.max(), abs=0.0)
    assert max(s["acceleration_ratio"]) == pytest.approx(1.0)
    # samples are the check's own: values at the kept times equal the full series there
    t = np.asarray(s["t"])
    index = np.searchsorted(report.t, t)
    np.testing.assert_array_equal(report.t[index], t)
    np.testing.assert_array_equal(np.asarray(s["min_clearance"]), full_min[index])
    np.testing.assert_array_equal(
        np.asarray(s["velocity_ratio"]), report.velocity_ratio.max(axis=1)[index]
    )


def test_worst_checks_put_failures_first():
    names = [c.name for c in worst_checks(_report())]
    assert names[0] == "torque:j1"  # the only failure
    assert "clearance:c|floor" in names
    assert "clearance:a|b" not in names


def test_section_marks_an_unsafe_elite():
    data = {
        "chosen_elite": None,
        "safety": {"ok": False, "message": "no elite passed"},
        "elites": [{"rank": 1, "safety_series": safety_series(_report())}],
    }
    elite, unsafe = chosen_elite(data)
    assert elite["rank"] == 1
    assert unsafe
    md = "\n".join(safety_section(data, {"figures/clearance.png"}))
    assert "UNSAFE" in md
    assert "figures/clearance.png" in md
    assert "| torque:j1 | **violated** |" in md
    assert "UNSAFE" in safety_headline(data)


@pytest.mark.slow
def test_run_report_has_safety_figures_and_series(tmp_path):
    result = CliRunner().invoke(app, ["run", str(QUICK), "--out", str(tmp_path), "--no-replay"])
    assert result.exit_code == 0, result.output
    (run,) = [p for p in tmp_path.iterdir() if p.is_dir()]
    for name in ("clearance.png", "limits.png"):
        assert (run / "figures" / name).read_bytes().startswith(b"\x89PNG")
    data = json.loads((run / "result.json").read_text())
    for elite in data["elites"]:
        s = elite["safety_series"]
        assert len(s["t"]) <= 2000
        assert s["n_checked"] >= 1000
        # the elite's check summary (same SafetyReport): "<pair>: clearance 0.0417 m at t = ..."
        match = re.search(
            r"clearance:(\S+): clearance ([0-9.]+) m at t = ([0-9.]+) s", elite["safety"]["summary"]
        )
        assert match is not None
        assert s["closest_pair"] == match.group(1)
        assert min(s["min_clearance"]) == pytest.approx(float(match.group(2)), abs=6e-5)
        assert s["closest_time"] == pytest.approx(float(match.group(3)), abs=6e-4)
    md = (run / "report.md").read_text()
    assert "## Trajectory safety" in md
    assert "figures/clearance.png" in md
    rank = data["chosen_elite"]
    assert f"elite {rank} executed; smallest clearance" in md


def test_section_lists_the_pairs_not_checked_and_why():
    from dataclasses import replace

    report = replace(
        _report(),
        not_checked=(
            ("base_link|link_1", "adjacent"),
            ("link_5|link_7", "reference contact (in contact in the reference posture)"),
            ("base_link_0|floor", "constant distance -0.0030 m (...); judged once"),
        ),
    )
    s = safety_series(report)
    assert s["not_checked"][1] == {
        "pair": "link_5|link_7",
        "reason": "reference contact (in contact in the reference posture)",
    }
    data = {"chosen_elite": 1, "elites": [{"rank": 1, "safety_series": s}]}
    md = "\n".join(safety_section(data, set()))
    assert "Not checked along the trajectory" in md
    # the table escapes the pipe of a pair name
    assert "| link_5\\|link_7 | reference contact (in contact in the reference posture) |" in md
    assert "| base_link_0\\|floor | constant distance -0.0030 m (...); judged once |" in md
