"""benchmarks/bench_peers.py's pieces on one short simulated UR5 log (seconds, not its --quick).

References: Pinocchio's URDF inertias (ident's truth) against MuJoCo's compiled model of the same
URDF (the map every mujoco.sysid figure goes through); the simulator's commanded torque, which is
the true model on the simulated states exactly; mujoco.sysid's own objective at the truth
against its CAD start. mujoco.sysid's tests skip when its imports (the ``peers`` extra) are
missing; CI does not install the peers.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pinocchio as pin
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "data" / "examples"))
bench_peers = importlib.import_module("bench_peers")

import make_so101  # noqa: E402

from ident.measure.mujoco_config import load_mujoco_measurement  # noqa: E402
from ident.measure.mujoco_sim import simulate  # noqa: E402
from ident.model import Robot  # noqa: E402
from ident.run.log_measurement import true_parameters  # noqa: E402


def _have_sysid() -> bool:
    if importlib.util.find_spec("absl") is None:
        return False
    import mujoco.sysid

    return hasattr(mujoco.sysid, "optimize")


needs_sysid = pytest.mark.skipif(not _have_sysid(), reason="mujoco.sysid's imports (peers extra)")


@pytest.fixture(scope="module")
def identified():
    """The UR5's simulated log, one 10 s period, and ident's identification of it."""
    c = bench_peers.make_case("ur5", periods=1)
    run, result = bench_peers.run_ident(c)
    return c, run, result


@pytest.fixture(scope="module")
def case(identified):
    """The UR5's simulated log, ident's run and its parameter model."""
    c, run, result = identified
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
    """mujoco.sysid's problem as built here (0.5 s windows, control/sensor alignment, positions
    and velocities weighted by their spread, theta writer, joint terms): its objective at the
    simulator's truth is below its CAD start's (joint terms 1.5x), and its truth parameters map
    back onto ident's truth."""
    from mujoco import sysid

    c, _, pm = case
    problem = bench_peers.sysid_problem(c, start="cad", window_s=0.5, max_windows=2)
    assert problem.n_windows == 2
    y_truth, y_start = problem.objective(problem.truth), problem.objective(problem.params)
    assert y_truth < 0.9 * y_start
    # the residual divides by the scale it is given (the duel passes the rollout objective's):
    # twice the default scale, a quarter of the objective
    q, dq, _, _ = bench_peers._sysid_samples(c)
    scale = 2.0 * np.array([q.std(axis=0), dq.std(axis=0)])
    halved = bench_peers.sysid_problem(c, start="cad", window_s=0.5, max_windows=2, scale=scale)
    assert halved.objective(halved.truth) == pytest.approx(0.25 * y_truth, rel=1e-9)
    model = sysid.apply_param_modifiers(problem.truth, problem.spec.copy())
    x = bench_peers.standard_from_mujoco(model, pm, problem.joints)
    truth = true_parameters(pm, c.setup.config)
    assert np.max(np.abs(x - truth)) < 1e-9 * np.max(np.abs(truth))


@needs_sysid
def test_sysid_best_setup_smoke_reports_its_stop(identified):
    """The duel's sysid set-up on one 0.5 s window, started from ident's written model, two
    iterations: its start holds ident's joint terms, x_scale='jac' is accepted, the stop is read
    from the optimizer's own message (the cap here) and the iterations are the Jacobians it
    computed, the CPU time is measured, and the objective does not rise."""
    c, _, result = identified
    pm = result.parameters
    ident_model = bench_peers.ident_written_model(result)
    problem = bench_peers.sysid_problem(
        c, start="ident", window_s=0.5, ident_model=ident_model, max_windows=1
    )
    for j in c.setup.robot.joint_names:
        d = int(ident_model.joint(j).dofadr[0])
        value = problem.params[f"{j}_damping"].value[0]
        assert value == pytest.approx(ident_model.dof_damping[d], rel=1e-12)
    run = bench_peers.run_sysid(
        c, pm, start="ident", window_s=0.5, max_iters=2, ident_model=ident_model, max_windows=1
    )
    assert run.info["status"] == "maximum iterations reached."
    assert run.info["iterations"] == 2
    assert run.cpu_s > 0.0
    y = run.info["objective"]
    assert y["stop"] <= y["start"]  # Gauss-Newton with a line search never goes uphill
    # a spent CPU budget stops it after its first iteration, named as not converged
    run = bench_peers.run_sysid(
        c,
        pm,
        start="ident",
        window_s=0.5,
        max_iters=5,
        ident_model=ident_model,
        max_windows=1,
        cpu_budget_s=0.0,
    )
    assert run.info["status"].startswith("NOT converged")
    assert run.info["iterations"] == 1


def test_duel_models_are_the_rollout_checks_and_score_truth_best(identified):
    """The duel writes every estimate through ident's MJCF writer: at the truth it is the
    rollout check's own truth model (``reference_mjcf`` with the simulator's joint terms:
    masses, inertias, armature, damping, frictionloss equal), and on the held-out windows the
    truth's rollout objective is far below the CAD start's (joint terms 1.5x). A body written
    on the wrong link, swapped joint terms or another window set would not give both."""
    import mujoco

    from ident.identify.assessment.rollout import held_out_windows, reference_mjcf, rollout_score

    c, _, result = identified
    pm = result.parameters
    truth = c.log.truth
    extras = {
        j: {
            "rotor_inertia": float(truth["armature"][k]),
            "viscous": float(truth["viscous"][k]),
            "coulomb": float(truth["coulomb"][k]),
        }
        for k, j in enumerate(c.setup.robot.joint_names)
    }
    ref = mujoco.MjModel.from_xml_string(reference_mjcf(c.setup.robot, extras))
    ours = bench_peers.model_mjcf(c, pm, true_parameters(pm, c.setup.config))
    for field in ("body_mass", "body_inertia", "body_ipos", "dof_armature", "dof_damping"):
        np.testing.assert_allclose(getattr(ours, field), getattr(ref, field), atol=1e-12)
    np.testing.assert_allclose(ours.dof_frictionloss, ref.dof_frictionloss, atol=1e-12)
    measurements, windows = held_out_windows(result)
    j_truth = rollout_score(ours, measurements, windows).objective
    cad = bench_peers.model_mjcf(c, pm, bench_peers.cad_start(c, pm))
    assert j_truth < 0.1 * rollout_score(cad, measurements, windows).objective


def _record(seed, ident, sysid, load=2.0):
    """A fake duel record: ``ident`` as (torque, base, rollout, cpu, refined rollout) and
    ``sysid`` as (torque, base, rollout, cpu)."""

    def row(t, b, r, cpu, refined=None, **more):
        return {"torque": t, "base": b, "rollout": r, "cpu_s": cpu, "refined_rollout": refined,
                **more}  # fmt: skip

    stop = {"iterations": 12, "status": "norm(dx) < tol."}
    return {
        "robot": "ur5",
        "kind": "ident",
        "seed": seed,
        "load_start": load,
        "n_samples": 10000,
        "n_identify": 7000,
        "rollout_windows": 5,
        "rows": {"ident": row(*ident), "mujoco.sysid (cad)": row(*sysid, **stop)},
    }


def test_duel_table_gives_medians_worst_and_the_targets():
    """Median and worst over seeds per figure, the stop of sysid, ident's refined model's
    rollout in its own column (a dash for a tool without one), and the targets' verdict on
    the medians: a mean for the median, a best for the worst, or a verdict on the worst seed
    would print other figures."""
    records = [
        _record(0, (0.001, 0.01, 0.5, 2.0, 0.4), (0.004, 0.02, 0.1, 100.0), load=1.5),
        _record(1, (0.002, 0.02, 0.6, 3.0, 0.3), (0.009, 0.05, 0.2, 200.0)),
        _record(2, (0.009, 0.03, 0.9, 4.0, 0.8), (0.010, 0.06, 0.3, 10.0), load=3.0),
    ]
    text = bench_peers.duel_table(records)
    assert (
        "| ident | 0.0020 (0.0090) | 0.0200 (0.0300) | 0.6 (0.9) | 0.4 (0.8) | 3.0 (4.0) | - |"
        in text
    )
    assert "| mujoco.sysid (cad) | 0.0090 (0.0100) | 0.0500 (0.0600) | 0.2 (0.3) | - |" in text
    assert "12: norm(dx) < tol." in text
    assert "3 seeds: 0, 1, 2" in text
    assert "load average at start 1.5-3.0" in text
    v = bench_peers.duel_verdict(records)
    assert v["torque_ratio"] == pytest.approx(0.002 / 0.009)
    assert v["base_ratio"] == pytest.approx(0.02 / 0.05)
    assert v["cpu_ratio"] == pytest.approx(100.0 / 3.0)
    assert "error 0.22x its (holds: <= 1/3), base error 0.40x (fails), CPU 33x less (holds" in text
    records[1]["rows"]["mujoco.sysid (cad)"]["status"] = "NOT converged: stopped by the budget"
    text = bench_peers.duel_table(records)
    assert "Targets not judged: 1 sysid run(s)" in text
    assert "holds" not in text


def test_pinocchio_part_prints_its_table():
    """The per-sample comparison runs (tiny sizes) and reports four rows against pin.rnea."""
    text = bench_peers.pinocchio_part(n=50, repeat=1)
    assert text.count("\n| ") == 5  # header + 4 rows (random states, loop, trajectory)
    assert "| 1.0x |" in text


def test_long_log_part_runs_ident_identify_in_its_own_process():
    """The long-log piece generates a 7-joint 1 kHz log, runs `ident identify` on it in a
    subprocess, from a numpy archive and from an MCAP, and prints that process's wall, CPU and
    peak memory and the model it wrote (3 s of log here; the hour with --long-minutes 60).
    Catches a piece that reports nothing measured (a failed run raises), the parent's memory
    instead of the child's (the child's peak includes its own interpreter, > 100 MB, and is
    printed as a whole number of MB), or an MCAP row that is not the MCAP's."""
    text = bench_peers.long_log_part(0.05)
    rows = [line for line in text.splitlines() if line.startswith(("| numpy", "| MCAP"))]
    assert [r.split()[1] for r in rows] == ["numpy", "MCAP"]
    for row in rows:
        wall, cpu, peak = (float(c) for c in row.strip("|").split("|")[1:4])
        assert 0.0 < wall
        assert 0.0 < cpu
        assert peak > 100.0
        assert "URDF + MJCF, reloaded to" in row
    assert "3000 samples" in text


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


def test_figaroh_fixture_trajectory_matches_its_manifest():
    """The UR10 fixture's training series rebuilt from its coefficients has the ranges FIGAROH's
    manifest records (q range, max |dq|): a wrong series form (cos for sin, a missing 1/(k w),
    a wrong centre) would not."""
    fixture = bench_peers.load_ur10_fixture()
    q, dq, ddq = bench_peers.fixture_trajectory(fixture)
    assert q.shape == dq.shape == ddq.shape == (1000, 6)
    np.testing.assert_allclose(np.ptp(q, axis=0), fixture["q_range_rad"], rtol=1e-12)
    np.testing.assert_allclose(np.abs(dq).max(axis=0), fixture["dq_max_abs"], rtol=1e-12)
    # ddq is the derivative of dq (central difference of the closed form's samples)
    h = 1.0 / fixture["rate_hz"]
    np.testing.assert_allclose(np.gradient(dq, h, axis=0)[1:-1], ddq[1:-1], atol=0.01)


@pytest.fixture(scope="module")
def excitation():
    """The excitation piece at its --quick budget (UR10 with FIGAROH's limits, 7-joint Panda)."""
    return bench_peers.excitation_part(None, quick=True)


@pytest.mark.slow
def test_excitation_figure_is_cond_of_the_raw_base_regressor(excitation):
    """Each printed condition number equals numpy's cond() of the raw Pinocchio regressor of the
    designed period restricted to the printed base columns, and those columns are a base (rank
    of the full non-zero-column matrix by SVD). A column-normalised matrix (ident's own
    criterion), friction columns, a missing or extra base column, or another trajectory's
    samples would not give it."""
    text, rows = excitation
    assert {r["robot"] for r in rows} == {"ur10", "panda"}
    for row in rows:
        d = row["design"]
        data = d.model.createData()
        y = np.vstack(
            [
                pin.computeJointTorqueRegressor(d.model, data, q, v, a)
                for q, v, a in zip(d.q, d.dq, d.ddq, strict=True)
            ]
        )
        assert y.shape == (d.q.shape[0] * d.model.nv, 10 * d.model.nv)
        nonzero = (y**2).sum(axis=0) >= 1e-6
        assert set(row["columns"]) <= set(np.flatnonzero(nonzero))
        sv = np.linalg.svd(y[:, nonzero], compute_uv=False)
        rank = int(np.sum(sv > sv[0] * 1e-10))
        w = y[:, row["columns"]]
        assert np.linalg.matrix_rank(w) == rank == w.shape[1]
        expected = np.linalg.cond(w)
        assert row["cond"] == pytest.approx(expected, rel=1e-9)
        assert f"| {expected:.4g} ({w.shape[1]} columns) |" in text
        # the scaled matrix of ident's own criterion gives another figure
        assert d.own_cond != pytest.approx(expected, rel=0.01)


needs_figaroh = pytest.mark.skipif(
    importlib.util.find_spec("figaroh") is None, reason="figaroh (peers extra)"
)


@needs_figaroh
def test_peer_convention_is_figarohs_regressor():
    """FIGAROH's own regressor of the UR10 (its ``build_regressor_basic`` without friction,
    actuator inertia or offset, its zero-column elimination at 1e-6) on the fixture's trajectory
    equals the matrix the excitation piece conditions, row for row after FIGAROH's joint-major
    order, and gives the same condition number on the piece's base columns: a friction column,
    a scaled column or a different elimination would not."""
    import warnings
    from types import SimpleNamespace

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # ndcurves' converter registration
        from figaroh.identification.parameter import get_standard_parameters
        from figaroh.tools.regressor import (
            build_regressor_basic,
            build_regressor_reduced,
            get_index_eliminate,
        )
    from robots import ERD_ROBOTS

    model = pin.buildModelFromUrdf(str(ERD_ROBOTS / "ur_description/urdf/ur10_robot.urdf"))
    q, dq, ddq = bench_peers.fixture_trajectory(bench_peers.load_ur10_fixture())
    config = {
        "has_friction": False,
        "has_actuator_inertia": False,
        "has_joint_offset": False,
        "is_joint_torques": True,
        "is_external_wrench": False,
        "force_torque": None,
        "act_idxv": list(range(model.nv)),
    }
    robot = SimpleNamespace(model=model, data=model.createData())
    w_fig = build_regressor_basic(robot, q, dq, ddq, config)
    eliminated, _ = get_index_eliminate(w_fig, get_standard_parameters(model, config), 1e-6)
    w_fig = build_regressor_reduced(w_fig, eliminated)
    kept = [c for c in range(10 * model.nv) if c not in eliminated]
    w, columns = bench_peers.peer_columns(model, q, dq, ddq)
    local = [kept.index(int(c)) for c in columns]  # raises if a base column was eliminated
    # FIGAROH stacks joint-major (all samples of joint 1, then joint 2, ...)
    ours = w.reshape(q.shape[0], model.nv, -1).transpose(1, 0, 2).reshape(-1, w.shape[1])
    np.testing.assert_allclose(ours, w_fig[:, local], rtol=0, atol=1e-10 * np.abs(w_fig).max())
    assert np.linalg.cond(w) == pytest.approx(np.linalg.cond(w_fig[:, local]), rel=1e-9)
    assert np.linalg.matrix_rank(w_fig) == len(columns)


@needs_sysid
def test_sysid_servo_setup_gets_the_commands_their_history_and_the_servo_class():
    """``bench_servo.py --peer sysid``'s set-up on one SO-101 servo episode (no encoder
    ticks): sysid's windows lie in the identification ranges given; a window's initial state
    holds the two commands before it in the servo's delay history, so that the truth's model
    (position servos, force range, delay, friction loss as the simulator's) stepped under the
    logged commands replays the simulator's positions to 1e-5 rad (a history of zeros, one
    sample off, torque controls or another delay give 1e-4 and more); the start is the URDF's
    with the joint terms off and the gains 1.5x; ``kv`` is folded into the damping."""
    import mujoco
    from mujoco import sysid

    robot = Robot.from_urdf(make_so101.URDF)
    measurement = make_so101.measurement() | {"encoder_counts_per_rev": None}
    reference = make_so101.reference(robot, 0, (8, 12))
    log = simulate(robot, *reference, load_mujoco_measurement(measurement), rng=0)
    spec = make_so101.SERVO
    servo = bench_peers.ServoLog(
        q=log.q,
        q_cmd=log.q_cmd,
        segments=[(0, log.q.shape[0])],
        ranges=[(100, 400)],  # one 0.5 s window (251 samples) fits
        kp=np.array(spec["kp"]),
        kv=np.array(spec["kv"]),
        forcerange=spec["forcerange"],
        delay_steps=spec["delay_steps"],
    )
    case = bench_peers.Case("so101", SimpleNamespace(robot=robot), log, 0, servo)
    problem = bench_peers.sysid_problem(case, start="cad", window_s=0.5)
    assert problem.n_windows == 1
    for k, j in enumerate(robot.joint_names):
        assert problem.params[f"{j}_damping"].value[0] == 0.0
        assert problem.params[f"{j}_kp"].value[0] == pytest.approx(1.5 * spec["kp"][k])
    assert problem.objective(problem.truth) < 1e-3 * problem.objective(problem.params)
    model = sysid.apply_param_modifiers(problem.truth, problem.spec.copy())
    i0 = 100
    state = bench_peers._initial_state(model, log.q, log.dq_true, log.q_cmd, i0)
    data = mujoco.MjData(model)
    mujoco.mj_setState(model, data, state, mujoco.mjtState.mjSTATE_FULLPHYSICS.value)
    error = 0.0
    for k in range(50):
        data.ctrl[:] = log.q_cmd[i0 + k]
        mujoco.mj_step(model, data)
        error = max(error, float(np.max(np.abs(data.qpos - log.q_true[i0 + k + 1]))))
    assert error < 1e-5
    gains = bench_peers._servo_gains(model, problem.joints)
    np.testing.assert_allclose(gains["kv"], spec["kv"])
    np.testing.assert_allclose(model.dof_damping, np.add(spec["kv"], spec["damping"]))
    # ident's knowledge (bench_servo.sysid_case's set-up): one kp per servo setting, the
    # velocity gain in the damping; the datasheet start: armature and gains 1.5x, no friction
    tied = dataclasses.replace(servo, kp_groups=[[0, 1, 2], [3, 4]], fold_kv=True)
    problem = bench_peers.sysid_problem(
        dataclasses.replace(case, servo=tied), start="datasheet", window_s=0.5
    )
    assert not any(name.endswith("_kv") for name in problem.params.keys())
    for k, j in enumerate(robot.joint_names):
        start = {n: problem.params[f"{j}_{n}"].value[0] for n in ("armature", "damping")}
        assert start["armature"] == pytest.approx(1.5 * spec["armature"][k])
        assert start["damping"] == pytest.approx(1.5 * spec["kv"][k])
        assert problem.params[f"{j}_frictionloss"].value[0] == 0.0
    # the folded truth leaves kv out of the force range's clip: close, not the same class
    assert problem.objective(problem.truth) < 2e-2 * problem.objective(problem.params)
    group = problem.truth.copy()
    group["+".join(robot.joint_names[:3]) + "_kp"].value = np.array([7.0])
    model = sysid.apply_param_modifiers(group, problem.spec.copy())
    gains = bench_peers._servo_gains(model, problem.joints)
    np.testing.assert_allclose(gains["kp"], [7.0, 7.0, 7.0, *spec["kp"][3:]])
    np.testing.assert_allclose(gains["kv"], 0.0)


def test_sysid_leaves_out_windows_it_cannot_score():
    """sysid divides each window's residual by each sensor's norm over the window (after its
    first sample): a joint stuck the whole window (velocity exactly 0) would make its objective
    NaN. Catches a check on the wrong samples (the first sample, the initial condition, is not
    in sysid's norm: a joint that moves only there still gives a zero norm) or on positions
    only."""
    n = 50
    q = np.linspace(0.1, 0.2, 200)[:, None] * np.ones((1, 2))
    dq = np.ones((200, 2))
    assert bench_peers.sysid_scorable(q, dq, 0, n)
    stuck = dq.copy()
    stuck[2 : n + 1, 1] = 0.0  # joint 2 stuck after the window's first two samples
    stuck[1, 1] = 0.3
    assert not bench_peers.sysid_scorable(q, stuck, 0, n)
    assert bench_peers.sysid_scorable(q, stuck, n, n)  # the next window moves
