"""Base parameters: both methods on a closed-form case and on a real robot's regressor."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from robots import UR5_URDF

from ident.dynamics.base_parameters import compute_base_parameters
from ident.dynamics.chain import chain_from_model, random_states
from ident.dynamics.parameters import parameter_names
from ident.dynamics.pinocchio_check import pinocchio_regressor
from ident.errors import DataError

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
