"""The chunk reduction's Gram path (ident.identify.estimation.accumulate.reduce_chunk) and its
fallback.

A joint's rows of a chunk are reduced from the Cholesky factor of their column-scaled Gram
matrix when its condition estimate is at most ``GRAM_MAX_COND``; otherwise by CholeskyQR2 or
Householder QR. Checked against numpy on the rows themselves (``W^T W``, ``W^T y``,
``lstsq``): a factor left scaled, a wrong ``z`` or residual, or the Gram path kept on badly
conditioned rows (where it squares the condition number) fails here.
"""

import numpy as np
import pytest

from ident.identify.estimation import accumulate
from ident.identify.estimation.observations import ReducedObservations


def _log(rng, n=400, nv=3, p=8):
    """Random rows with the chain's structure: joint j carries no term of the first 2 j
    columns; column scales spread over six decades, as inertia and friction columns do."""
    Yb = rng.normal(size=(n, nv, p)) * np.logspace(-3, 3, p)
    for j in range(nv):
        Yb[:, j, : 2 * j] = 0.0
    tau = Yb @ rng.normal(size=p) + 0.1 * rng.normal(size=(n, nv))
    keep = rng.random((n, nv)) > 0.2
    return Yb, tau, keep


def test_gram_path_gives_the_normal_equations_and_the_residual():
    rng = np.random.default_rng(11)
    Yb, tau, keep = _log(rng)
    methods: list[str] = []
    red = accumulate.reduce_chunk(Yb, tau, keep, methods)
    assert methods == ["gram"] * 3  # well-conditioned after the column scaling
    for j in range(3):
        W, y = Yb[keep[:, j], j], tau[keep[:, j], j]
        G = W.T @ W
        d = np.sqrt(np.diag(G))
        d[d == 0] = 1.0
        # R^T R = W^T W and R^T z = W^T y, entrywise relative to the column norms
        np.testing.assert_allclose(
            (red.R[j].T @ red.R[j]) / np.outer(d, d), G / np.outer(d, d), rtol=0, atol=1e-13
        )
        np.testing.assert_allclose(
            red.R[j].T @ red.z[j] / d, W.T @ y / d, rtol=0, atol=1e-13 * np.linalg.norm(y)
        )
        x, *_ = np.linalg.lstsq(W, y, rcond=None)
        assert red.rho[j] == pytest.approx(np.sum((y - W @ x) ** 2), rel=1e-10)
        assert red.yty[j] == pytest.approx(y @ y, rel=1e-14)
        assert red.n_rows[j] == keep[:, j].sum()
        np.testing.assert_array_equal(red.R[j][:, : 2 * j], 0.0)  # columns it does not carry


def _solve(red):
    R, z = red.stacked()
    return np.linalg.solve(R, z)


def test_badly_conditioned_rows_fall_back_and_keep_the_estimate(monkeypatch):
    # two nearly collinear columns: condition ~2e3 after scaling (4e6 for the Gram)
    rng = np.random.default_rng(12)
    n, p = 2000, 6
    W = rng.normal(size=(n, p)) * np.logspace(-2, 2, p)
    W[:, 4] = W[:, 3] * 1e2 * (1.0 + 1e-3 * rng.normal(size=n))
    assert 1e3 < np.linalg.cond(W / np.linalg.norm(W, axis=0)) < 1e4
    y = W @ rng.normal(size=p) + 1e-3 * rng.normal(size=n)
    Yb, tau, keep = W[:, None, :], y[:, None], np.ones((n, 1), bool)
    reference, *_ = np.linalg.lstsq(W, y, rcond=None)  # in memory, SVD
    methods: list[str] = []
    x = _solve(accumulate.reduce_chunk(Yb, tau, keep, methods))
    assert methods == ["cholesky_qr2"]
    np.testing.assert_allclose(x, reference, rtol=0, atol=1e-10 * np.abs(reference).max())
    # chunked: the same estimate from five chunks merged
    parts = [
        accumulate.reduce_chunk(Yb[a : a + 400], tau[a : a + 400], keep[a : a + 400])
        for a in range(0, n, 400)
    ]
    merged = parts[0]
    for part in parts[1:]:
        merged = merged.merge(part)
    np.testing.assert_allclose(
        _solve(merged), reference, rtol=0, atol=1e-10 * np.abs(reference).max()
    )
    # the case is hard enough to need the fallback: the Gram path alone misses by 10x more
    monkeypatch.setattr(accumulate, "GRAM_MAX_COND", np.inf)
    methods.clear()
    forced = _solve(accumulate.reduce_chunk(Yb, tau, keep, methods))
    assert methods == ["gram"]
    assert np.abs(forced - reference).max() > 1e-9 * np.abs(reference).max()


def test_rank_deficient_rows_fall_back_and_equal_the_reference():
    rng = np.random.default_rng(13)
    W = rng.normal(size=(60, 1, 4))
    W[:, 0, 3] = W[:, 0, 1] - W[:, 0, 2]  # dependent: the Gram is singular but for round-off
    tau = rng.normal(size=(60, 1))
    methods: list[str] = []
    red = accumulate.reduce_chunk(W, tau, np.ones((60, 1), bool), methods)
    assert methods in (["cholesky_qr2"], ["householder"])
    ref = ReducedObservations.from_rows(W[:, 0], tau[:, 0], np.zeros(60, np.int64), 1)
    v = rng.normal(size=4)
    np.testing.assert_allclose(red.residual_ss(v), ref.residual_ss(v), rtol=1e-12)


def test_an_exact_fit_takes_the_gram_path_with_no_residual():
    # noise-free torques (an ideal simulation): y in the span of W; the Gram path factors W
    # alone, so the exact fit neither fails nor leaves a cancelled residual
    rng = np.random.default_rng(14)
    W = rng.normal(size=(300, 1, 5)) * np.logspace(-2, 2, 5)
    truth = rng.normal(size=5)
    tau = W @ truth
    methods: list[str] = []
    red = accumulate.reduce_chunk(W, tau, np.ones((300, 1), bool), methods)
    assert methods == ["gram"]
    np.testing.assert_allclose(_solve(red), truth, rtol=1e-12)
    assert red.rho[0] <= 1e-24 * red.yty[0]
