"""Base parameters at their decision boundaries, pinned where mutation testing found gaps.

Closed-form matrices built from orthonormal columns, so every score is known exactly: a column
``cos(d) q0 + sin(d) q2`` is ``sin(d)`` away from the span of ``q0``, ``q1``.
``benchmarks/mutation.py --modules base_parameters`` measures how many mutants they kill.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from ident.dynamics.base_parameters import (
    NEAR_DEPENDENCE_FLOOR,
    RANK_RTOL,
    compute_base_parameters,
    nearly_aligned_axes,
    torque_shares,
)
from ident.errors import DataError, IdentWarning

NAMES = ("p0", "p1", "p2")


def _orthonormal(n_rows: int = 30, n_cols: int = 3) -> np.ndarray:
    q, _ = np.linalg.qr(np.random.default_rng(0).normal(size=(n_rows, n_cols)))
    return q


def _near(d: float, scale: float = 1.0) -> np.ndarray:
    """Columns e0, e1 and ``scale (cos d e0 + sin d e2)``: the third scores sin(d) (unit
    coordinate columns: the first pivot's ``|R_00|`` is exactly 1)."""
    q = np.eye(30)[:, :3]
    return np.column_stack([q[:, 0], q[:, 1], scale * (np.cos(d) * q[:, 0] + np.sin(d) * q[:, 2])])


@pytest.mark.parametrize("method", ["sequential", "qr"])
def test_a_nearly_dependent_column_is_merged_and_named_in_a_warning(method):
    d = 1e-5  # a URDF angle rounded to 5 digits
    with pytest.warns(IdentWarning) as record:
        base = compute_base_parameters(_near(d, scale=3.0), NAMES, method=method)
    (message,) = [str(w.message) for w in record if issubclass(w.category, IdentWarning)]
    assert message.startswith("Parameter(s) p2 (1.0e-05) are nearly, not exactly, combinations")
    assert "below the rank tolerance 0.001" in message
    assert message.endswith("as if the axes were exactly aligned.")
    np.testing.assert_array_equal(base.independent, [0, 1])
    np.testing.assert_array_equal(base.dependent, [2])
    np.testing.assert_array_equal(base.nearly_dependent, [2])
    assert base.scores[2] == pytest.approx(np.sin(d), rel=1e-4)
    # beta0 = p0 + 3 cos(d) p2 (least squares on the span), in the parameters' units
    np.testing.assert_allclose(base.K, [[3.0 * np.cos(d)], [0.0]], atol=1e-9)
    assert base.base_names == ("p0R", "p1")
    assert base.expressions() == ["p0 + 3 p2", "p1"]
    assert base.counts()["n_dependent"] == 1
    assert base.method == method


@pytest.mark.parametrize("method", ["sequential", "qr"])
def test_exact_dependence_is_not_reported_as_near(method):
    with warnings.catch_warnings():
        warnings.simplefilter("error", IdentWarning)
        base = compute_base_parameters(_near(0.0), NAMES, method=method)
    np.testing.assert_array_equal(base.dependent, [2])
    assert base.scores[2] < NEAR_DEPENDENCE_FLOOR
    assert base.nearly_dependent.size == 0
    assert base.near_dependence_note() == ""


@pytest.mark.parametrize("method", ["sequential", "qr"])
def test_a_score_at_the_tolerance_is_dependent_just_above_it_independent(method):
    W = _near(2e-3)
    score = compute_base_parameters(W, NAMES, method=method).scores[2]
    assert score == pytest.approx(np.sin(2e-3), rel=1e-6)
    assert score > RANK_RTOL  # the default tolerance keeps it
    with pytest.warns(IdentWarning, match="p2"):
        at = compute_base_parameters(W, NAMES, method=method, rtol=score)
    assert at.rank == 2
    assert at.dependent.tolist() == [2]
    assert at.tolerance == score
    assert at.nearly_dependent.tolist() == [2]  # at most the tolerance: merged and named
    below = compute_base_parameters(W, NAMES, method=method, rtol=score * (1 - 1e-9))
    assert below.rank == 3
    assert below.dependent.size == 0


def test_coefficients_print_with_their_sign_and_precision():
    q = _orthonormal()
    W = np.column_stack([q[:, 0], q[:, 1], -0.123456 * q[:, 0] + 2.5 * q[:, 1]])
    base = compute_base_parameters(W, NAMES, method="sequential")
    assert base.expressions() == ["p0 - 0.1235 p2", "p1 + 2.5 p2"]
    assert base.expressions(precision=2) == ["p0 - 0.12 p2", "p1 + 2.5 p2"]
    assert base.base_names == ("p0R", "p1R")
    np.testing.assert_allclose(base.projection, [[1.0, 0.0, -0.123456], [0.0, 1.0, 2.5]])


def test_the_zero_column_tolerance_is_relative_to_the_largest_column():
    q = _orthonormal()
    tiny = 1e-15  # below 30 rows * eps next to a unit column: round-off, unidentifiable
    W = np.column_stack([q[:, 0], tiny * q[:, 1], 1e-6 * q[:, 2]])
    base = compute_base_parameters(W, NAMES)
    assert base.unidentifiable.tolist() == [1]
    assert base.independent.tolist() == [0, 2]  # small units are not zero
    # a given rtol is also the zero-column tolerance
    coarse = compute_base_parameters(W, NAMES, rtol=1e-5)
    assert coarse.unidentifiable.tolist() == [1, 2]
    assert coarse.scores[1] == 0.0
    assert coarse.scores[2] == 0.0


@pytest.mark.parametrize("method", ["sequential", "qr"])
def test_empty_and_zero_matrices(method):
    base = compute_base_parameters(np.zeros((0, 3)), NAMES, method=method)
    assert base.rank == 0
    assert base.unidentifiable.tolist() == [0, 1, 2]
    assert base.K.shape == (0, 0)
    zero = compute_base_parameters(np.zeros((4, 3)), NAMES, method=method)
    assert zero.unidentifiable.tolist() == [0, 1, 2]
    assert zero.rank == 0
    assert zero.project(np.ones(3)).shape == (0,)


def test_qr_keeps_the_best_conditioned_columns_in_parameter_order():
    q = _orthonormal()
    # p0 = p2 / 2: qr may keep either; it lists the kept ones in the original order
    W = np.column_stack([0.5 * q[:, 0], q[:, 1], q[:, 0]])
    base = compute_base_parameters(W, NAMES, method="qr")
    assert base.rank == 2
    assert base.independent.tolist() == sorted(base.independent.tolist())
    params = np.array([1.0, 2.0, 3.0])
    np.testing.assert_allclose(base.base_columns(W) @ base.project(params), W @ params)
    assert base.scores[base.independent].min() == pytest.approx(1.0)


def test_wrong_shapes_are_reported():
    base = compute_base_parameters(_near(0.0), NAMES)
    with pytest.raises(DataError, match=r"params must have 3 entries on the last axis"):
        base.project(np.ones(4))
    with pytest.raises(DataError, match=r"W must have 3 columns, got shape \(2, 4\)"):
        base.base_columns(np.ones((2, 4)))
    with pytest.raises(
        DataError, match=r"^W contains NaN or inf; check the states used to build it$"
    ):
        compute_base_parameters(np.array([[1.0, np.inf, 0.0]]), NAMES)
    with pytest.raises(DataError, match=r"W must be 2-D \(n_rows, n_params\)"):
        compute_base_parameters(np.ones(3), NAMES)
    with pytest.raises(ValueError, match="read-only"):
        base.K[0, 0] = 1.0  # results are frozen: a caller cannot corrupt a shared model


def test_torque_shares_closed_form():
    W = np.column_stack([3.0 * _orthonormal()[:, 0], 4.0 * _orthonormal()[:, 1]])
    shares = torque_shares(W, np.array([1.0, -1.0]))
    np.testing.assert_allclose(shares, [3.0 / 5.0, 4.0 / 5.0])
    np.testing.assert_array_equal(torque_shares(W, np.zeros(2)), [0.0, 0.0])


def test_integer_matrices_are_classified_like_float_ones():
    W = np.array([[1, 0, 2], [0, 3, 0], [1, 0, 2], [0, 1, 0]])  # p2 = 2 p0
    base = compute_base_parameters(W, NAMES, method="sequential")
    assert base.dependent.tolist() == [2]
    np.testing.assert_allclose(base.K, [[2.0], [0.0]], atol=1e-12)
    shares = torque_shares(W[:, :2], np.array([1, 1]))  # ||W_i|| / ||W beta||, beta = 1
    np.testing.assert_allclose(shares, [np.sqrt(2 / 12), np.sqrt(10 / 12)])


def test_more_parameters_than_rows_leave_the_extra_columns_scored_zero():
    W = np.random.default_rng(1).normal(size=(2, 3))
    base = compute_base_parameters(W, NAMES, method="qr")
    assert base.rank == 2
    assert base.scores[base.dependent].tolist() == [0.0]


def test_small_torques_have_the_same_shares():
    W = np.column_stack([3.0 * _orthonormal()[:, 0], 4.0 * _orthonormal()[:, 1]])
    np.testing.assert_allclose(torque_shares(1e-4 * W, np.array([1.0, -1.0])), [0.6, 0.8])


def _chain(axes, parents, gravity=(0.0, 0.0, -9.81)):
    """The fields of a KinematicChain that nearly_aligned_axes reads (identity placements)."""
    n = len(axes)
    names = tuple(f"j{k + 1}" for k in range(n))
    return SimpleNamespace(
        joint_names=names,
        body_names=names,  # a chain without mimic joints: one body per joint
        parents=np.asarray(parents),
        placements=np.tile(np.eye(4), (n, 1, 1)),
        axes=np.asarray(axes, dtype=float),
        gravity=np.asarray(gravity, dtype=float),
    )


def test_a_first_axis_nearly_along_or_across_gravity_is_named():
    d = 1e-5
    along = [np.sin(d), 0.0, np.cos(d)]
    across = [np.cos(d), 0.0, np.sin(d)]
    ((name, other, deviation, nominal),) = nearly_aligned_axes(_chain([along], [-1]))
    assert (name, other, nominal) == ("j1", "gravity", 0.0)
    assert deviation == pytest.approx(d, rel=1e-6)
    ((*_, nominal),) = nearly_aligned_axes(_chain([across], [-1], gravity=(0, 0, -0.5)))
    assert nominal == 90.0
    # the tolerance is inclusive: a deviation equal to it is reported
    assert len(nearly_aligned_axes(_chain([along], [-1]), tolerance=deviation)) == 1
    assert nearly_aligned_axes(_chain([[0.0, 0.0, 1.0]], [-1])) == []  # exact: nothing
    # without gravity a first joint has nothing to compare with; its children still do
    pairs = nearly_aligned_axes(_chain([[0, 0, 1.0], along], [-1, 0], gravity=(0, 0, 0)))
    assert [(a, b) for a, b, _, _ in pairs] == [("j2", "j1")]
