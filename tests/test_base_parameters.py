"""Base parameters: both methods on a closed-form case and on a real robot's regressor."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pinocchio as pin
import pytest
from robots import ERD_ROBOTS, UR5_URDF
from typer.testing import CliRunner

from ident.cli import app
from ident.dynamics.base_parameters import (
    NEAR_DEPENDENCE_FLOOR,
    RANK_RTOL,
    compute_base_parameters,
    nearly_aligned_axes,
)
from ident.dynamics.chain import chain_from_model, random_states
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model, model_regressors
from ident.dynamics.parameters import parameter_names
from ident.dynamics.pinocchio_check import pinocchio_regressor
from ident.errors import DataError, IdentWarning
from ident.identify.estimation.estimate import least_squares
from ident.model import Robot

NAMES = ("p0", "p1", "p2", "p3", "p4")


def _closed_form_matrix(scale: float = 1.0) -> np.ndarray:
    """Columns a, 0, 2a, scale*b, a + b: p1 has no effect, p2 and p4 are combinations."""
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=(2, 40))
    return np.column_stack([a, np.zeros(40), 2 * a, scale * b, a + b])


def test_sequential_method_on_a_closed_form_case() -> None:
    base = compute_base_parameters(_closed_form_matrix(), NAMES, method="sequential")
    np.testing.assert_array_equal(base.independent, [0, 3])
    np.testing.assert_array_equal(base.dependent, [2, 4])
    np.testing.assert_array_equal(base.unidentifiable, [1])
    # beta0 = p0 + 2 p2 + p4, beta3 = p3 + p4
    np.testing.assert_allclose(base.K, [[2.0, 1.0], [0.0, 1.0]], atol=1e-12)
    assert base.expressions() == ["p0 + 2 p2 + p4", "p3 + p4"]
    assert base.base_names == ("p0R", "p3R")
    np.testing.assert_allclose(base.project([1, 5, 2, 3, 4]), [9.0, 7.0])
    np.testing.assert_allclose(base.projection @ [1, 5, 2, 3, 4], [9.0, 7.0])
    assert base.counts() == {
        "rank": 2,
        "n_independent": 2,
        "n_dependent": 2,
        "n_unidentifiable": 1,
        "n_params": 5,
    }


@pytest.mark.parametrize("scale", [1e-6, 1.0, 1e6])
def test_classification_does_not_depend_on_column_units(scale: float) -> None:
    W = _closed_form_matrix(scale)
    for method in ("sequential", "qr"):
        base = compute_base_parameters(W, NAMES, method=method)
        assert base.rank == 2
        np.testing.assert_array_equal(base.unidentifiable, [1])
        params = np.arange(1.0, 6.0)
        np.testing.assert_allclose(base.base_columns(W) @ base.project(params), W @ params)


@pytest.fixture(scope="module")
def ur5_matrix() -> np.ndarray:
    """Stacked Pinocchio regressor of UR5 (independent of our regressor code)."""
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    q, dq, ddq = random_states(chain_from_model(model), 100, rng=0)
    return pinocchio_regressor(model, q, dq, ddq).reshape(-1, 60)


@pytest.mark.parametrize("method", ["qr", "sequential"])
def test_base_parameters_of_ur5_reproduce_the_model(ur5_matrix: np.ndarray, method: str) -> None:
    W = ur5_matrix
    base = compute_base_parameters(W, parameter_names(6), method=method)
    nonzero = np.linalg.norm(W, axis=0) > base.tolerance * np.linalg.norm(W, axis=0).max()
    normalized = W[:, nonzero] / np.linalg.norm(W[:, nonzero], axis=0)
    assert base.rank == np.linalg.matrix_rank(normalized)
    assert base.rank == np.linalg.matrix_rank(W)
    assert len(base.independent) + len(base.dependent) + len(base.unidentifiable) == 60
    assert base.K.shape == (base.rank, len(base.dependent))
    params = np.random.default_rng(1).normal(size=(5, 60))
    reproduced = base.base_columns(W) @ base.project(params).T
    expected = W @ params.T
    np.testing.assert_allclose(reproduced, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    # the decisions are clear: a wide gap between kept and combined columns
    assert base.scores[base.independent].min() > 1e-6
    assert base.scores[base.dependent].max() < 1e-12
    # m1 (mass of the first body on a vertical first axis) has no effect on the torques
    assert "m1" in [base.names[i] for i in base.unidentifiable]


def test_both_methods_agree_and_sequential_keeps_the_first_columns(ur5_matrix) -> None:
    qr = compute_base_parameters(ur5_matrix, parameter_names(6), method="qr")
    sequential = compute_base_parameters(ur5_matrix, parameter_names(6), method="sequential")
    assert qr.rank == sequential.rank
    np.testing.assert_array_equal(qr.unidentifiable, sequential.unidentifiable)
    # the first identifiable column is always independent in the sequential method
    first = np.setdiff1d(np.arange(60), sequential.unidentifiable)[0]
    assert sequential.independent[0] == first


def test_bad_input_is_reported() -> None:
    with pytest.raises(DataError, match="5 columns but 2 names"):
        compute_base_parameters(np.ones((3, 5)), ["a", "b"])
    with pytest.raises(DataError, match="unknown base-parameter method 'svd'"):
        compute_base_parameters(np.ones((3, 2)), ["a", "b"], method="svd")
    with pytest.raises(DataError, match="NaN"):
        compute_base_parameters(np.full((3, 2), np.nan), ["a", "b"])


# --- one rank tolerance: nearly parallel / perpendicular axes (URDF angles rounded) ----------

XARM7_URDF = ERD_ROBOTS / "xarm_description/urdf/xarm7.urdf"


def _xarm7_models(tmp_path):
    """The xArm7 as shipped (rpy="1.5708": axes off by 3.7e-6 rad) and with exact pi/2."""
    rounded = XARM7_URDF.read_text()
    assert 'rpy="1.5708 0 0"' in rounded
    exact = rounded.replace('"-1.5708', f'"-{math.pi / 2!r}').replace(
        '"1.5708', f'"{math.pi / 2!r}'
    )
    models = {}
    for label, text in (("rounded", rounded), ("exact", exact)):
        path = tmp_path / f"xarm7_{label}.urdf"
        path.write_text(text)
        models[label] = Robot.from_urdf(path).model
    return models


def test_rounded_urdf_angles_give_the_exact_models_base_parameters_and_a_stable_wls(tmp_path):
    models = _xarm7_models(tmp_path)
    terms = ExtraTerms.from_options(7)  # viscous, Coulomb, offset, rotor inertia: all joints
    with pytest.warns(IdentWarning, match=r"Ia2 \(4\.\de-06\).*rounded"):
        rounded = build_parameter_model(models["rounded"], terms)
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentWarning)  # the exact model merges nothing
        exact = build_parameter_model(models["exact"], terms)
    # the tolerance of 1e-6 took Ia2 (4.1e-6 off the span) for a 70th base parameter
    assert rounded.base.rank == exact.base.rank == 69
    np.testing.assert_array_equal(rounded.base.independent, exact.base.independent)
    # the combinations differ by the misalignment only
    scale = np.abs(exact.base.projection).max()
    np.testing.assert_allclose(rounded.base.projection, exact.base.projection, atol=1e-4 * scale)
    assert [rounded.names[j] for j in rounded.base.nearly_dependent] == ["Ia2"]
    assert exact.base.nearly_dependent.size == 0

    # WLS on noisy torques of the rounded robot: the base parameters are the exact model's,
    # not a +-huge pair (Ia2 against the base parameter it belongs to)
    rng = np.random.default_rng(0)
    true = rounded.nominal.copy()
    extra = np.array([not n.startswith(("m", "I")) or n.startswith("Ia") for n in rounded.names])
    true[extra] = rng.uniform(0.05, 0.5, int(extra.sum()))  # friction, offsets, rotor inertia
    chain = chain_from_model(models["rounded"])
    q, dq, ddq = random_states(chain, 400, rng=1)
    Y_rigid, Y_extra = model_regressors(chain, terms, q, dq, ddq)
    Y = rounded.columns(Y_rigid, Y_extra, np.arange(len(rounded.names)))
    tau = Y @ true
    tau_noisy = tau + 0.01 * tau.std(axis=0) * rng.standard_normal(tau.shape)
    W_base = Y[:, :, rounded.base.independent].reshape(-1, rounded.base.rank)
    est = least_squares(W_base, tau_noisy, rounded.base_names, method="wls")
    beta_exact = exact.base.project(true)
    # none left undetermined (measured: 1.1 %; the split pair's std is ~1/4e-6 times larger)
    assert est.std.max() < 0.05 * np.abs(beta_exact).max()
    assert np.abs(est.x).max() < 2.0 * np.abs(beta_exact).max()
    # within 5 standard deviations of the exact-angle model's base parameters
    np.testing.assert_array_less(np.abs(est.x - beta_exact), 5.0 * est.std + 1e-9)


def test_base_parameter_scores_keep_real_robots_far_from_the_tolerance():
    """Independent columns of a real arm score far above RANK_RTOL, dependent ones far below
    NEAR_DEPENDENCE_FLOOR: the tolerance decides nothing that is not rounding."""
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentWarning)
        pm = build_parameter_model(model, ExtraTerms.from_options(model.nv))
    base = pm.base
    assert base.scores[base.independent].min() > 100 * RANK_RTOL
    assert base.scores[base.dependent].max() < NEAR_DEPENDENCE_FLOOR


def test_nearly_aligned_axes_are_named_by_verify(tmp_path):
    models = _xarm7_models(tmp_path)
    pairs = nearly_aligned_axes(chain_from_model(models["rounded"]))
    # every rpy="1.5708" joint: 90 deg from its parent's axis to within pi/2 - 1.5708
    assert [(a, b, n) for a, b, _, n in pairs] == [
        (f"joint{j}", f"joint{j - 1}", 90.0) for j in range(2, 8)
    ]
    np.testing.assert_allclose([d for *_, d, _ in pairs], 1.5708 - math.pi / 2, rtol=1e-6)
    assert nearly_aligned_axes(chain_from_model(models["exact"])) == []

    result = CliRunner().invoke(
        app, ["verify", "--urdf", str(tmp_path / "xarm7_rounded.urdf"), "--samples", "20"]
    )
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "nearly aligned axes: joint2 and joint1 are 90 deg apart to within 3.7e-06 rad" in text
    assert "| 43 |" in text.replace("│", "|")  # the exact model's rigid-body rank
