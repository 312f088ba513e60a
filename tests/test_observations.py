"""ReducedObservations: per-group QR reduction against the dense least-squares problem."""

import numpy as np
import pytest

from ident.errors import DataError
from ident.identify.estimation.observations import ReducedObservations


def _problem(seed: int = 0, m: int = 300, n: int = 7, g: int = 3):
    rng = np.random.default_rng(seed)
    W = rng.normal(size=(m, n)) * np.logspace(0, 3, n)  # badly scaled columns
    y = W @ rng.normal(size=n) + rng.normal(scale=0.1, size=m)
    groups = rng.integers(0, g, size=m)
    return W, y, groups, g


def test_residual_of_any_x_equals_the_dense_residual_per_group() -> None:
    W, y, groups, g = _problem()
    red = ReducedObservations.from_rows(W, y, groups, g)
    x = np.random.default_rng(1).normal(size=W.shape[1])
    dense = np.bincount(groups, weights=(W @ x - y) ** 2, minlength=g)
    np.testing.assert_allclose(red.residual_ss(x), dense, rtol=1e-10)
    np.testing.assert_allclose(red.yty, np.bincount(groups, weights=y**2, minlength=g))
    np.testing.assert_array_equal(red.n_rows, np.bincount(groups, minlength=g))


def test_chunks_merge_to_the_whole_and_weighted_solution_matches_lstsq() -> None:
    W, y, groups, g = _problem(2, m=1000)
    whole = ReducedObservations.from_rows(W, y, groups, g)
    parts = [
        ReducedObservations.from_rows(W[a:b], y[a:b], groups[a:b], g)
        for a, b in ((0, 3), (3, 400), (400, 1000))
    ]  # a chunk with fewer rows than n
    merged = parts[0].merge(parts[1]).merge(parts[2])
    x = np.random.default_rng(3).normal(size=W.shape[1])
    np.testing.assert_allclose(merged.residual_ss(x), whole.residual_ss(x), rtol=1e-10)
    np.testing.assert_allclose(merged.rho, whole.rho, rtol=1e-9)
    w = np.array([1.0, 3.0, 0.5])
    R, z = merged.stacked(w)
    x_red = np.linalg.solve(R, z)
    x_ref = np.linalg.lstsq(W * w[groups][:, None], y * w[groups], rcond=None)[0]
    np.testing.assert_allclose(x_red, x_ref, rtol=1e-10)
    # the factor keeps W's singular values (no squared condition number)
    np.testing.assert_allclose(
        np.linalg.svd(merged.stacked()[0], compute_uv=False),
        np.linalg.svd(W, compute_uv=False),
        rtol=1e-10,
    )


def test_from_samples_groups_rows_by_joint_and_rejects_bad_shapes() -> None:
    rng = np.random.default_rng(4)
    Y = rng.normal(size=(50, 2, 4))
    tau = rng.normal(size=(50, 2))
    red = ReducedObservations.from_samples(Y, tau)
    x = rng.normal(size=4)
    np.testing.assert_allclose(red.residual_ss(x), ((Y @ x - tau) ** 2).sum(axis=0), rtol=1e-10)
    with pytest.raises(DataError):
        ReducedObservations.from_samples(Y, tau[:, :1])
    with pytest.raises(DataError):
        ReducedObservations.from_rows(Y[:, 0], tau[:, 0], np.full(50, 5), 2)
