"""benchmarks/bench_peers.py's pieces on one short simulated UR5 log (seconds, not its --quick).

References: Pinocchio's URDF inertias (ident's truth) against MuJoCo's compiled model of the same
URDF (the map every mujoco.sysid figure goes through); the simulator's commanded torque, which is
the true model on the simulated states exactly; mujoco.sysid's own objective at the truth
against its CAD start. mujoco.sysid's tests skip when its imports (the ``peers`` extra) are
missing; CI does not install the peers.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
bench_peers = importlib.import_module("bench_peers")

from ident.run.log_measurement import true_parameters  # noqa: E402


def _have_sysid() -> bool:
    if importlib.util.find_spec("absl") is None:
        return False
    import mujoco.sysid

    return hasattr(mujoco.sysid, "optimize")


needs_sysid = pytest.mark.skipif(not _have_sysid(), reason="mujoco.sysid's imports (peers extra)")


@pytest.fixture(scope="module")
def case():
    """The UR5's simulated log, one 10 s period, and ident's parameter model of it."""
    c = bench_peers.make_case("ur5", periods=1)
    run, result = bench_peers.run_ident(c)
    return c, run, result.parameters


def test_mujoco_model_maps_onto_idents_truth(case):
    """MuJoCo's compiled UR5 (fused bodies, explicit inertials, joint terms at the truth) read
    back as ident's parameters equals ident's truth: a wrong frame (inertia about the CoM), a
    missed body rotation or a swapped friction column would not."""
    c, _, pm = case
    truth = true_parameters(pm, c.setup.config)
    assert bench_peers.check_mapping(c, pm) < 1e-10 * np.max(np.abs(truth))


def test_truth_predicts_the_commanded_torque_and_ident_is_close(case):
    """The yardstick: the truth has zero parameter error and predicts the (noise-free) commanded
    torque on the held-out states to rounding; ident's WLS estimate is within 1 % of it."""
    c, run, pm = case
    truth = bench_peers.ToolRun("truth", true_parameters(pm, c.setup.config), 1.0, 0.0)
    row = bench_peers.evaluate(c, pm, truth)
    assert row["param"] < 1e-12
    assert row["noise_free"] < 1e-6
    ours = bench_peers.evaluate(c, pm, run)
    assert ours["noise_free"] < 0.01
    assert ours["param_torque"] < 0.01
    # the measured torque carries the simulator's noise: neither beats the noise floor by much
    assert ours["held_out"] == pytest.approx(row["held_out"], rel=0.2)


@needs_sysid
def test_sysid_objective_is_lowest_near_the_truth(case):
    """mujoco.sysid's problem as built here (windows, control/sensor alignment, theta writer,
    joint terms): its objective at the simulator's truth is far below its CAD start, and its
    truth parameters map back onto ident's truth."""
    from mujoco import sysid

    c, _, pm = case
    problem = bench_peers.sysid_problem(c, start="cad", window_s=0.2)
    y_truth, y_start = problem.objective(problem.truth), problem.objective(problem.params)
    assert y_truth < 0.3 * y_start
    model = sysid.apply_param_modifiers(problem.truth, problem.spec.copy())
    x = bench_peers.standard_from_mujoco(model, pm, problem.joints)
    truth = true_parameters(pm, c.setup.config)
    assert np.max(np.abs(x - truth)) < 1e-9 * np.max(np.abs(truth))


def test_pinocchio_part_prints_its_table():
    """The per-sample comparison runs (tiny sizes) and reports four rows against pin.rnea."""
    text = bench_peers.pinocchio_part(n=50, repeat=1)
    assert text.count("\n| ") == 5  # header + 4 rows (random states, loop, trajectory)
    assert "| 1.0x |" in text


def test_write_docs_replaces_only_its_blocks(tmp_path):
    """A run rewrites the blocks of the tables it printed and keeps every other line."""
    doc = tmp_path / "benchmarks.md"
    doc.write_text(
        "intro\n<!-- bench_peers:pinocchio -->\nold table\n<!-- /bench_peers:pinocchio -->\n"
        "middle\n<!-- bench_peers:figaroh -->\nkept\n<!-- /bench_peers:figaroh -->\nend\n",
        encoding="utf-8",
    )
    bench_peers.write_docs(doc, {"pinocchio": "| new |"}, "cmd --x", "the box")
    text = doc.read_text(encoding="utf-8")
    assert "old table" not in text
    assert "`cmd --x`\n\nmachine: the box\n\n| new |\n<!-- /bench_peers:pinocchio -->" in text
    assert text.startswith("intro\n")
    assert "middle\n" in text
    assert "\nkept\n" in text
    assert text.endswith("end\n")
