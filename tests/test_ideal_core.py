"""``ident run``'s ideal source goes through the identification core.

The ideal measurement (RNEA on the true parameters plus noise) becomes a log with its measured
states, the known bodies' torques subtracted, and the stage's parameter model; its estimate is
checked here against least squares on Pinocchio's own regressor rows (an independent
reference), and every registered estimator, the documented toy one included, runs from it.
"""

import json

import numpy as np
import pinocchio as pin
import pytest
import yaml
from conftest import REPO_ROOT
from typer.testing import CliRunner

from ident.cli import app
from ident.identify.pipeline.core import identify_measurements
from ident.measure.ideal import simulate_measurements
from ident.run.config import RunConfig
from ident.run.elite_identification import (
    elite_trajectory,
    ideal_identify_config,
    ideal_log,
    identify_elite,
    noise_model,
    stage_parameters,
)
from ident.run.setup import prepare_run
from ident.run.stage_info import build_stage_info

# joints 2-4 move, bodies 2-3 are unknown: bodies 1 and 4-6 are known, and the torques of 4-6
# on rows 2-4 are not zero, so a wrong subtraction, row set or column set shows
_STAGE = {"moving": ["joint_2", "joint_3", "joint_4"], "bodies": ["joint_2", "joint_3"]}


def _config(**update) -> RunConfig:
    data = {
        "robot": str(REPO_ROOT / "configs" / "paper6r.yaml"),
        "stage": _STAGE,
        "seed": 3,
        "excitation": {"family": "joint_fourier", "n_samples": 80},
        "measurement": {"torque_noise_std": 0.05},
        **update,
    }
    return RunConfig.model_validate(data)


@pytest.fixture(scope="module")
def stage_setup():
    config = _config()
    setup = prepare_run(config)
    robot, family = setup.robot, setup.family
    info = build_stage_info(robot, setup.stage, family, "qr", np.random.default_rng(0))
    bounds = np.asarray(family.bounds, dtype=float)
    x = np.random.default_rng(1).uniform(bounds[:, 0], bounds[:, 1]) * 0.5
    return config, robot, family, info, x


def _pinocchio_rows(robot, info, meas):
    """The stage's base columns and torques from Pinocchio's regressor, known bodies
    subtracted with their true parameters."""
    model = robot.model
    data = model.createData()
    Y = np.stack(
        [
            pin.computeJointTorqueRegressor(model, data, q, dq, ddq)
            for q, dq, ddq in zip(meas.q, meas.dq, meas.ddq, strict=True)
        ]
    )
    rows, columns = list(info.rows), list(info.columns)
    theta = np.concatenate([model.inertias[i].toDynamicParameters() for i in range(1, 7)])
    known = np.setdiff1d(np.arange(theta.size), columns)
    y = meas.tau[:, rows] - Y[:, rows][:, :, known] @ theta[known]
    W = Y[:, rows][:, :, columns].reshape(-1, len(columns))
    return np.asarray(info.base.base_columns(W)), y.reshape(-1)


def test_ideal_source_is_least_squares_on_pinocchio_rows_and_the_core(stage_setup):
    config, robot, family, info, x = stage_setup
    outcome = identify_elite(config, robot, family, info, 0, x, 1.0, {}, 7)
    assert set(outcome.estimates) == {"ols", "wls"}, outcome.failures
    # the same measurements, rebuilt here with the same noise stream
    t, q, dq, ddq, _ = elite_trajectory(family, x)
    meas = simulate_measurements(robot.model, t, q, dq, ddq, noise_model(config), rng=7)
    np.testing.assert_array_equal(outcome.tau, meas.tau)
    Wb, y = _pinocchio_rows(robot, info, meas)
    ols = np.linalg.lstsq(Wb, y, rcond=None)[0]
    scale = np.abs(ols).max()
    np.testing.assert_allclose(outcome.estimates["ols"].x, ols, rtol=0, atol=1e-9 * scale)
    # the error measures' norms: base columns and true torques over the identification rows
    np.testing.assert_allclose(outcome.base_column_norms, np.linalg.norm(Wb, axis=0), rtol=1e-12)
    assert outcome.true_torque_norm == pytest.approx(np.linalg.norm(Wb @ info.true_base), 1e-12)
    # and it is the core's answer on those measurements (no second path)
    core = identify_measurements(
        ideal_identify_config(config),
        ideal_log(robot, info, meas),
        model=robot.model,
        parameters=stage_parameters(robot, info),
    )
    for method in ("ols", "wls"):
        np.testing.assert_array_equal(
            outcome.estimates[method].x, core.consistent.estimates[method].x
        )
    assert core.reduction.n_groups == len(info.rows)  # the stage's rows only


def test_a_consistent_estimator_runs_on_a_stage(stage_setup):
    # lmi on the stage's two bodies: a physically consistent estimate of the stage's
    # parameters, whose base parameters fit the rows about as well as least squares
    config, robot, family, info, x = stage_setup
    config = config.model_copy(
        update={"estimation": config.estimation.model_copy(update={"methods": ["wls", "lmi"]})}
    )
    outcome = identify_elite(config, robot, family, info, 0, x, 1.0, {}, 7)
    assert set(outcome.estimates) == {"wls", "lmi"}, outcome.failures
    lmi = outcome.estimates["lmi"]
    assert len(lmi.consistency) == 2  # bodies 2 and 3, the stage's
    assert all(c.consistent for c in lmi.consistency)
    assert lmi.relative_residual < 1.05 * outcome.estimates["wls"].relative_residual


def test_two_estimators_besides_least_squares_are_refused():
    with pytest.raises(ValueError, match="at most one estimator besides ols and wls"):
        _config(estimation={"methods": ["wls", "lmi", "log_cholesky"]})


# ---- the documented toy estimator (unconstrained) from ident run with the ideal source ------
# (the `ridge` fixture: tests/conftest.py)
@pytest.mark.slow
def test_ident_run_ideal_source_runs_the_documented_toy_estimator(ridge, tmp_path):
    data = {
        "robot": str(REPO_ROOT / "configs" / "paper6r.yaml"),
        "stage": "wrist",
        "seed": 0,
        "excitation": {"family": "paper_wrist", "n_samples": 60},
        "elites": {"n_particles": 6, "n_elites": 2, "maxiter": 30},
        "emupso": {"n_particles": 6, "maxiter": 3, "n_runs": 1, "n_report_elites": 1},
        "measurement": {"torque_noise_std": 0.02},
        "estimation": {"methods": ["wls", "ridge"]},
    }
    config = tmp_path / "wrist-ridge.yaml"
    config.write_text(yaml.safe_dump(data))
    out = CliRunner().invoke(app, ["run", str(config), "--no-replay", "--out", str(tmp_path / "r")])
    assert out.exit_code == 0, out.output
    (run_dir,) = (tmp_path / "r").iterdir()
    assert json.loads((run_dir / "run.json").read_text())["status"] == "complete"
    result = json.loads((run_dir / "result.json").read_text())
    estimates = result["elites"][0]["estimates"]
    assert set(estimates) == {"wls", "ridge"}, result["elites"][0]["failures"]
    # ridge with a 1e-9 shrink is close to the WLS-weighted least squares (the shrink moves
    # the wrist's poorly excited parameters a little): its own estimate, near WLS's
    wls, toy = np.array(estimates["wls"]["x"]), np.array(estimates["ridge"]["x"])
    assert not np.array_equal(toy, wls)
    assert np.linalg.norm(toy - wls) < 1e-2 * np.linalg.norm(wls)
    # judged against the truth like the least-squares ones, and named in the terminal
    assert estimates["ridge"]["max_rel_error_major"] > 0
    assert "RIDGE" in out.output or "ridge" in out.output
