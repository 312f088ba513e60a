import json
from pathlib import Path

import numpy as np
import pytest

from ident.dynamics.stage import select_stage
from ident.errors import TrajectoryError
from ident.model.selection import load_robot
from ident.run.config import load_run_config
from ident.run.pipeline import RunInterrupted, build_stage_info, identify_elite, run_pipeline
from ident.run.setup import make_family

QUICK = Path(__file__).parent / "data" / "run" / "quick-wrist.yaml"


@pytest.fixture(scope="module")
def config():
    return load_run_config(QUICK)


@pytest.fixture(scope="module")
def noise_free(config):
    return run_pipeline(config)


@pytest.fixture(scope="module")
def noisy(config):
    cfg = config.model_copy(
        update={"measurement": config.measurement.model_copy(update={"torque_noise_std": 0.05})}
    )
    return run_pipeline(cfg)


def _check_exact(elite, stage):
    """Noise-free recovery, unit-free: every parameter's error explains less than 1e-8 of
    the stage's torques, and the parameters explaining at least 1e-4 of them are recovered
    to 1e-8 relative. (Parameters with a tiny torque share, e.g. products of the paper's
    1e-6 kg*m first moments, keep only cond(W_b) * eps / share relative digits.)"""
    Wb = np.asarray(elite.base_column_norms)
    total = elite.true_torque_norm
    true = stage.true_base
    assert total > 0
    for est in elite.estimates.values():
        err = np.abs(est.x - true)
        assert np.max(err * Wb / total) < 1e-8
        significant = np.abs(true) * Wb / total >= 1e-4
        assert significant.sum() >= len(true) // 3
        assert np.max(err[significant] / np.abs(true[significant])) < 1e-8


def test_noise_free_identification_recovers_true_base_parameters(noise_free):
    assert noise_free.status == "complete"
    stage = noise_free.stage
    assert len(noise_free.elites) == 2
    for elite in noise_free.elites:
        assert set(elite.estimates) == {"ols", "wls"}
        for est in elite.estimates.values():
            assert est.names == stage.base_names
        _check_exact(elite, stage)


def test_true_base_parameters_reproduce_the_full_model(noise_free, config):
    """W_b @ beta_true == W @ p_true on random states: the truth the errors refer to."""
    robot = load_robot(config.robot)
    stage = noise_free.stage
    rng = np.random.default_rng(5)
    q = rng.uniform(-1, 1, (30, 6))
    dq, ddq = rng.normal(size=(30, 6)), rng.normal(size=(30, 6))
    q[:, :3] = q[0, :3]  # the wrist stage holds the arm
    dq[:, :3] = ddq[:, :3] = 0.0
    Y = robot.regressor(q, dq, ddq)[:, list(stage.rows)]
    full = Y[:, :, list(stage.columns)] @ stage.true_standard
    base = stage.base.base_columns(Y[:, :, list(stage.columns)].reshape(-1, len(stage.columns)))
    np.testing.assert_allclose(base @ stage.true_base, full.reshape(-1), atol=1e-9)


def test_noisy_errors_fall_within_reported_std(noisy):
    stage = noisy.stage
    for elite in noisy.elites:
        for method, est in elite.estimates.items():
            within = np.abs(est.x - stage.true_base) <= 3.0 * est.std
            assert within.mean() >= 0.8, (method, within.mean())
            assert np.all(np.isfinite(est.std))
            assert np.all(est.std > 0)


def test_chosen_trajectories_violate_no_constraint(noise_free, config):
    robot = load_robot(config.robot)
    for elite in noise_free.elites:
        assert np.all(elite.q >= robot.q_lower - 1e-12)
        assert np.all(elite.q <= robot.q_upper + 1e-12)
        assert np.all(np.abs(elite.dq) <= robot.dq_max + 1e-12)
        assert np.all(np.abs(elite.ddq) <= robot.ddq_max + 1e-12)
        assert elite.details["penalty"] == 0.0
    fitness = [e.fitness for e in noise_free.elites]
    assert fitness == sorted(fitness)
    assert noise_free.elites[0].fitness <= min(r.fun for r in noise_free.runs) + 1e-12


def test_same_seed_same_result_other_seed_differs(noise_free, config):
    again = run_pipeline(config)
    np.testing.assert_array_equal(again.elites[0].x, noise_free.elites[0].x)
    np.testing.assert_array_equal(again.runs[1].history, noise_free.runs[1].history)
    other = run_pipeline(config.with_seed(config.seed + 1))
    assert not np.array_equal(other.elites[0].x, noise_free.elites[0].x)


def test_keyboard_interrupt_in_progress_keeps_finished_runs(config):
    def stop_in_second_run(event):
        if event.phase == "optimize" and event.run == 1 and event.step >= 8:
            raise KeyboardInterrupt

    with pytest.raises(RunInterrupted) as info:
        run_pipeline(config, progress=stop_in_second_run)
    partial = info.value.partial
    assert isinstance(info.value.cause, KeyboardInterrupt)
    assert partial.status == "incomplete"
    assert "eMuPSO run 2 of 2" in partial.message
    assert len(partial.runs) == 1
    assert partial.initial_elites.shape[0] == 2
    assert partial.elites == ()


def test_infeasible_limits_give_a_clear_elite_search_error(config):
    excitation = config.excitation.model_copy(update={"bounds": {"q0[joint_5]": (3.0, 3.1)}})
    with pytest.raises(RunInterrupted) as info:
        run_pipeline(config.model_copy(update={"excitation": excitation}))
    cause = info.value.cause
    assert isinstance(cause, TrajectoryError)
    assert "position:joint_5" in str(cause)
    assert "initial elite search" in str(cause)


def test_a_motionless_trajectory_is_reported_not_identifiable(config, noise_free):
    robot = load_robot(config.robot)
    stage = select_stage(robot, config.stage)
    family = make_family(config, robot, stage)
    info = build_stage_info(robot, stage, family, "qr", np.random.default_rng(0))
    x = np.zeros(len(family.variable_names))  # all joints still at q0 = 0
    outcome = identify_elite(config, robot, family, info, 0, x, 1.0, {}, 0)
    assert outcome.estimates == {}
    assert set(outcome.failures) == {"ols", "wls"}
    assert all("not identifiable" in m for m in outcome.failures.values())


CONFIGS = Path(__file__).resolve().parents[1] / "configs"


def _noise_free(config):
    measurement = config.measurement.model_copy(update={"torque_noise_std": 0.0})
    return config.model_copy(update={"measurement": measurement})


@pytest.mark.parametrize("name", ["wrist", "arm"])
def test_paper_stages_quick_noise_free(name):
    """The paper's families; for the arm the known wrist torques are subtracted exactly."""
    config = _noise_free(load_run_config(CONFIGS / f"{name}.yaml").quick_version())
    result = run_pipeline(config)
    assert result.status == "complete"
    assert result.stage.name == name
    assert result.elites
    for elite in result.elites:
        assert elite.details["penalty"] == 0.0
        assert set(elite.estimates) == {"ols", "wls"}
        _check_exact(elite, result.stage)


# ident run's exit code of the paper's configs: 1 for the arm, whose executed elite fails the
# dense 1 kHz safety check (verdict "unsafe", a run warning; its identification is complete)
PAPER_EXIT = {"wrist": 0, "arm": 1}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["wrist", "arm"])
def test_paper_settings_full_run(shipped_run, name):
    """The session's shared run of the shipped config (``ident run --no-replay``: the same
    pipeline and seed), read from its result.json."""
    config = load_run_config(CONFIGS / f"{name}.yaml")
    result = json.loads((shipped_run(name, PAPER_EXIT[name]) / "result.json").read_text())
    assert result["status"] == "complete"
    runs = result["optimization"]["runs"]
    assert len(runs) == 5
    assert all(len(r["history"]) == 31 for r in runs)
    assert len(result["elites"]) == config.emupso.n_report_elites
    true_base = np.asarray(result["stage"]["true_base"])
    for elite in result["elites"]:
        assert elite["objective"]["penalty"] == 0.0
        for est in elite["estimates"].values():
            within = np.abs(np.asarray(est["x"]) - true_base) <= 3.0 * np.asarray(est["std"])
            assert within.mean() >= 0.8


def test_unreachable_cartesian_circle_is_a_clear_error():
    config = load_run_config(CONFIGS / "wrist.yaml").quick_version()
    # the flange moves on a sphere of radius d6 = 127.5 mm about the wrist centre
    excitation = config.excitation.model_copy(update={"bounds": {"d0": (500.0, 600.0)}})
    with pytest.raises(RunInterrupted) as info:
        run_pipeline(config.model_copy(update={"excitation": excitation}))
    message = str(info.value.cause)
    assert isinstance(info.value.cause, TrajectoryError)
    assert "reachability (100 %)" in message
    assert "Cartesian circle is reachable" in message


def test_encoder_quantization_enters_the_estimate(config, noise_free):
    measurement = config.measurement.model_copy(update={"encoder_counts_per_rev": 2**12})
    result = run_pipeline(config.model_copy(update={"measurement": measurement}))
    elite = result.elites[0]
    np.testing.assert_array_equal(elite.x, noise_free.elites[0].x)  # same design
    est = elite.estimates["ols"]
    exact = noise_free.elites[0].estimates["ols"]
    # coarse encoder, differentiated twice: the estimate moves, the residual is no longer zero
    assert est.relative_residual > 1e3 * max(exact.relative_residual, 1e-16)
    assert not np.allclose(est.x, exact.x, rtol=1e-6, atol=0)
