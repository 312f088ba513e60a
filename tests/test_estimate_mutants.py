"""OLS / WLS (ident.identify.estimation.estimate) against textbook formulas computed here on the
rows.

What a user relies on: the estimate and its standard deviations are the textbook ones
(``sigma^2 (W^T W)^-1``, ``sigma^2 = ||r||^2 / (m - n)``); WLS weights each joint by the
inverse of its noise standard deviation, estimated with the degrees of freedom shared in
proportion to the rows, so that on a long log the sigmas are the true noise levels; every
reported number (residual per joint, relative residual, condition number, counts) is the one
its docstring states; bad input gets a message naming the fix. (Raised the mutation score of
the module; see benchmarks/mutation.py.)
"""

import numpy as np
import pytest

from ident.errors import DataError, NotIdentifiable
from ident.identify.estimation.estimate import least_squares, rank_report

NAMES = ("a", "b", "c")


def _data(n_samples=400, noise=(0.05, 0.5), seed=0):
    """Two joints (rows per sample), three parameters, per-joint Gaussian noise."""
    rng = np.random.default_rng(seed)
    W = rng.normal(size=(2 * n_samples, 3)) * [1.0, 3.0, 0.5]
    x = np.array([1.5, -0.7, 2.0])
    tau = (W @ x).reshape(n_samples, 2) + rng.normal(size=(n_samples, 2)) * noise
    return W, tau, x


def _ols(W, y):
    x, *_ = np.linalg.lstsq(W, y, rcond=None)
    return x, y - W @ x


def test_ols_is_the_textbook_estimate():
    W, tau, _ = _data()
    y = tau.reshape(-1)
    m, n = W.shape
    x_ref, r = _ols(W, y)
    sigma2 = r @ r / (m - n)
    cov_ref = sigma2 * np.linalg.inv(W.T @ W)
    est = least_squares(W, tau, NAMES, method="ols")
    np.testing.assert_allclose(est.x, x_ref, rtol=1e-10)
    np.testing.assert_allclose(est.covariance, cov_ref, rtol=1e-8)
    np.testing.assert_allclose(est.std, np.sqrt(np.diag(cov_ref)), rtol=1e-8)
    np.testing.assert_allclose(est.relative_std, 100 * est.std / np.abs(x_ref), rtol=1e-10)
    np.testing.assert_allclose(est.sigma, [np.sqrt(sigma2)] * 2, rtol=1e-10)
    r2 = r.reshape(-1, 2)
    np.testing.assert_allclose(est.residual_rms, np.sqrt((r2**2).mean(axis=0)), rtol=1e-8)
    np.testing.assert_allclose(est.group_residual_ss, (r2**2).sum(axis=0), rtol=1e-8)
    assert est.relative_residual == pytest.approx(np.linalg.norm(r) / np.linalg.norm(y))
    assert est.condition_number == pytest.approx(np.linalg.cond(W), rel=1e-10)
    assert (est.n_samples, est.n_observations) == (400, 800)
    assert (est.method, est.success, est.message, est.names) == ("ols", True, "ok", NAMES)
    np.testing.assert_allclose(est.predict(W), W @ x_ref, rtol=1e-10)


def _wls_reference(W, y, group, passes):
    """IDIM-WLS written out on the rows: sigma_j^2 = ||r_j||^2 / (m_j (m - n) / m), rows
    scaled by 1 / sigma_j, solved again; covariance sigma_w^2 (W_s^T W_s)^-1."""
    m, n = W.shape
    x, r = _ols(W, y)
    for _ in range(passes):
        sigma = np.array(
            [
                np.sqrt((r[group == j] ** 2).sum() / ((group == j).sum() * (m - n) / m))
                for j in range(group.max() + 1)
            ]
        )
        w = 1.0 / sigma[group]
        x, *_ = np.linalg.lstsq(W * w[:, None], y * w, rcond=None)
        r = y - W @ x
    sigma_w2 = ((w * r) ** 2).sum() / (m - n)
    Ws = W * w[:, None]
    return x, sigma_w2 * np.linalg.inv(Ws.T @ Ws), sigma * np.sqrt(sigma_w2)


@pytest.mark.parametrize("passes", [1, 2, 3])
def test_wls_is_idim_wls_written_out(passes):
    W, tau, _ = _data(n_samples=60)
    y = tau.reshape(-1)
    group = np.tile([0, 1], 60)
    x_ref, cov_ref, sigma_ref = _wls_reference(W, y, group, passes)
    est = least_squares(W, tau, NAMES, method="wls", wls_passes=passes)
    np.testing.assert_allclose(est.x, x_ref, rtol=1e-9)
    np.testing.assert_allclose(est.covariance, cov_ref, rtol=1e-7)
    np.testing.assert_allclose(est.sigma, sigma_ref, rtol=1e-8)
    r = (y - W @ x_ref).reshape(-1, 2)
    np.testing.assert_allclose(est.residual_rms, np.sqrt((r**2).mean(axis=0)), rtol=1e-8)
    assert (est.method, est.message) == ("wls", "ok")


def test_wls_sigmas_are_the_noise_levels_and_beat_ols():
    # long log: the per-joint sigma converges to the true noise standard deviation, so the
    # weights are the inverse noise levels; the WLS std of each parameter is smaller
    W, tau, x = _data(n_samples=20000, noise=(0.05, 0.5), seed=1)
    wls = least_squares(W, tau, NAMES, method="wls")
    ols = least_squares(W, tau, NAMES, method="ols")
    np.testing.assert_allclose(wls.sigma, [0.05, 0.5], rtol=0.03)
    assert np.all(wls.std < 0.5 * ols.std)
    assert np.all(np.abs(wls.x - x) < 4 * wls.std)


def test_wls_groups_with_removed_rows_share_dof_by_rows():
    # rows removed per joint (velocity threshold): groups of unequal size; the reference
    # shares the degrees of freedom in proportion to each group's rows
    W, tau, _ = _data(n_samples=100)
    y = tau.reshape(-1)
    group = np.tile([0, 1], 100)
    keep = np.ones(200, bool)
    keep[1:120:2] = False  # 60 rows of joint 2 gone
    x_ref, cov_ref, sigma_ref = _wls_reference(W[keep], y[keep], group[keep], 2)
    est = least_squares(W[keep], y[keep], NAMES, method="wls", groups=group[keep])
    np.testing.assert_allclose(est.x, x_ref, rtol=1e-9)
    np.testing.assert_allclose(est.sigma, sigma_ref, rtol=1e-8)
    np.testing.assert_allclose(est.covariance, cov_ref, rtol=1e-7)
    assert est.n_samples == est.n_observations == 140


def test_wls_noise_free_data_keeps_the_pooled_weight_and_says_so():
    W, _, x = _data(n_samples=50)
    exact = (W @ x).reshape(50, 2)
    est = least_squares(W, exact, NAMES, method="wls")
    np.testing.assert_allclose(est.x, x, rtol=1e-12)
    assert est.message == (
        "WLS: zero residual variance on group(s) 0, 1 (noise-free data); used the pooled OLS "
        "weight there."
    )
    assert est.success


def test_wls_tiny_real_noise_is_weighted_and_noise_below_1e_10_is_not():
    # the noise-free test is relative to each joint's torque RMS (1e-10): 1e-9 N*m of noise
    # on torques of about 3 N*m is noise; 1e-8 N*m on torques of about 3000 N*m is not
    W, _, x = _data(n_samples=500)
    rng = np.random.default_rng(9)
    tau = (W @ x).reshape(500, 2) + 1e-9 * rng.normal(size=(500, 2))
    assert least_squares(W, tau, NAMES, method="wls").message == "ok"
    big = 1000.0 * W
    tau = (big @ x).reshape(500, 2) + 1e-8 * rng.normal(size=(500, 2))
    assert (
        "zero residual variance on group(s) 0, 1"
        in least_squares(big, tau, NAMES, method="wls").message
    )


def test_wls_with_an_empty_group_and_a_one_row_group():
    # a joint whose rows were all removed (velocity threshold) weighs nothing and has no
    # sigma; a joint with a single row still counts
    W, tau, _ = _data(n_samples=80)
    y = tau.reshape(-1)
    group = np.tile([0, 2], 80)
    group[5] = 3  # one row of its own
    x_ref, _, _ = _wls_reference(W, y, np.searchsorted([0, 2, 3], group), 2)
    est = least_squares(W, y, NAMES, method="wls", groups=group)
    assert est.message == "ok"
    assert est.sigma.shape == (4,)
    assert np.isnan(est.sigma[1])
    assert np.all(np.isfinite(est.sigma[[0, 2, 3]]))
    np.testing.assert_allclose(est.x, x_ref, rtol=1e-9)
    assert np.all(np.isfinite(est.std))


def test_reduced_least_squares_checks_its_input():
    from ident.identify.estimation.estimate import least_squares_reduced
    from ident.identify.estimation.observations import ReducedObservations

    W, tau, _ = _data(n_samples=10)
    red = ReducedObservations.from_rows(W, tau.reshape(-1), np.tile([0, 1], 10), 2)
    with pytest.raises(DataError) as err:
        least_squares_reduced(red, NAMES, method="gls")
    assert str(err.value) == "method='gls' is not one of ols, wls."
    with pytest.raises(DataError) as err:
        least_squares_reduced(red, NAMES[:2])
    assert str(err.value) == "2 names for 3 columns of W."
    for field in ("R", "z"):
        bad = red.R.copy() if field == "R" else red.z.copy()
        bad.flat[0] = np.nan
        broken = ReducedObservations(
            **{"R": red.R, "z": red.z, "rho": red.rho, "yty": red.yty, "n_rows": red.n_rows}
            | {field: bad}
        )
        with pytest.raises(DataError) as err:
            least_squares_reduced(broken, NAMES)
        assert str(err.value) == "reduced observations contain NaN/inf; clean or trim the log."


def test_zero_parameter_has_infinite_relative_std():
    W, _, _ = _data(n_samples=30)
    rng = np.random.default_rng(5)
    tau = W @ np.array([1.0, 0.0, 2.0]) + 0.1 * rng.normal(size=60)
    est = least_squares(W[:, [1]], W[:, 1] * 0.0, ("b",), method="ols", rows_per_sample=2)
    assert est.x[0] == 0.0
    assert np.isinf(est.relative_std[0])
    est = least_squares(W, tau, NAMES, rows_per_sample=2)
    assert np.all(np.isfinite(est.relative_std))


def test_too_few_rows_and_exactly_one_more_than_parameters():
    W, tau, _ = _data(n_samples=2)  # 4 rows for 3 parameters: solvable (1 dof)
    est = least_squares(W, tau, NAMES)
    assert est.success
    assert est.n_observations == 4
    with pytest.raises(DataError) as err:
        least_squares(W[:3], tau.reshape(-1)[:3], NAMES)
    assert str(err.value) == (
        "too few observations: 3 rows for 3 parameters (need more than 3); use a longer log, "
        "less decimation, or fewer parameters."
    )


def test_bad_input_messages():
    W, tau, _ = _data(n_samples=10)
    cases = [
        (dict(method="gls"), "method='gls' is not one of ols, wls."),
        (dict(names=("a", "b")), "2 names for 3 columns of W."),
        (
            dict(tau=tau[:, :1].repeat(3, axis=1)),
            "W has 20 rows but tau has 30 values; they must describe the same stacked "
            "observations.",
        ),
        (
            dict(rows_per_sample=3),
            "tau has 2 columns but rows_per_sample=3; pass tau as (n_samples, n_rows) or "
            "stacked (n_samples*n_rows,).",
        ),
        (dict(tau=tau[None]), "tau must be 1-D or 2-D, got shape (1, 10, 2)."),
        (
            dict(tau=tau.reshape(-1), rows_per_sample=3),
            "W has 20 rows, not a multiple of rows_per_sample=3.",
        ),
        (dict(tau=tau.reshape(-1), groups=np.zeros(19)), "groups has 19 entries, W has 20 rows."),
        (
            dict(tau=tau.reshape(-1), groups=-np.ones(20)),
            "groups must be non-negative row-group (joint) indices.",
        ),
    ]
    for change, message in cases:
        kwargs = {"W": W, "tau": tau, "names": NAMES, **change}
        with pytest.raises(DataError) as err:
            least_squares(kwargs.pop("W"), kwargs.pop("tau"), kwargs.pop("names"), **kwargs)
        assert str(err.value) == message
    with pytest.raises(DataError) as err:
        least_squares(W[:, 0], tau, NAMES)
    assert str(err.value) == "W must be 2-D (rows, parameters), got shape (20,)."
    bad = W.copy()
    bad[3, 1] = np.nan
    with pytest.raises(DataError) as err:
        least_squares(bad, tau, NAMES)
    assert str(err.value) == "observation matrix has NaN/inf in the column(s) of b."
    bad_tau = tau.copy()
    bad_tau[0, 0] = np.inf
    with pytest.raises(DataError) as err:
        least_squares(W, bad_tau, NAMES)
    assert str(err.value) == "measured torques contain NaN/inf values; clean or trim the log."


def test_groups_give_the_number_of_groups_from_the_largest_index():
    # three groups, rows in any order: the per-group outputs have one entry per index
    W, tau, _ = _data(n_samples=30)
    group = np.tile([2, 0, 1], 20)
    est = least_squares(W, tau.reshape(-1), NAMES, method="ols", groups=group)
    assert est.residual_rms.shape == est.sigma.shape == (3,)
    r = tau.reshape(-1) - W @ est.x
    np.testing.assert_allclose(
        est.residual_rms, [np.sqrt((r[group == j] ** 2).mean()) for j in range(3)], rtol=1e-8
    )


# ---------------------------------------------------------------------------- rank report


def test_rank_report_full_rank_dead_column_and_combination():
    rng = np.random.default_rng(0)
    W = rng.normal(size=(50, 4))
    names = ("m1", "mx1", "Izz1", "fv1")
    assert rank_report(W, names) is None
    dead = W.copy()
    dead[:, 2] = 0.0
    assert rank_report(dead, names, advice="") == (
        "parameter(s) Izz1 have no effect on the torques (not excited by the motion, or removed "
        "by the velocity threshold)."
    )
    combo = W.copy()
    combo[:, 3] = 2.0 * combo[:, 0] - combo[:, 1]
    text = rank_report(combo, names)
    assert text == (
        "parameters m1, mx1, fv1 enter the torques only in a linear combination. Reduce to base "
        "parameters, drop the parameter(s), or record a motion that excites them."
    )
    # a tiny column (below max(m, n) eps of the largest norm) counts as dead, a small one not
    small = W.copy()
    small[:, 1] *= 1e-9
    assert rank_report(small, names) is None
    tiny = W.copy()
    tiny[:, 1] *= 1e-18
    assert "mx1 have no effect" in rank_report(tiny, names)
    assert rank_report(np.zeros((5, 2)), ("p", "q"), advice="") == (
        "parameter(s) p, q have no effect on the torques (not excited by the motion, or removed "
        "by the velocity threshold)."
    )


def test_rank_deficient_least_squares_raises_the_report():
    W, tau, _ = _data(n_samples=20)
    W = W.copy()
    W[:, 2] = W[:, 0] + W[:, 1]
    with pytest.raises(NotIdentifiable) as err:
        least_squares(W, tau, NAMES)
    assert str(err.value).startswith("parameters a, b, c enter the torques only")


def test_reduced_least_squares_defaults_and_small_or_zero_torques():
    from ident.identify.estimation.estimate import least_squares_reduced
    from ident.identify.estimation.observations import ReducedObservations

    W, tau, _ = _data(n_samples=40)
    y = 1e-3 * tau.reshape(-1)  # torques of a small joint: ||tau|| below 1 N*m
    red = ReducedObservations.from_rows(W, y, np.tile([0, 1], 40), 2)
    ols = least_squares_reduced(red, NAMES)  # default: OLS
    assert ols.method == "ols"
    x, r = _ols(W, y)
    assert ols.relative_residual == pytest.approx(np.linalg.norm(r) / np.linalg.norm(y))
    assert ols.n_samples == 80  # default: the rows
    # the default WLS is the two-pass one of least_squares
    wls = least_squares_reduced(red, NAMES, method="wls")
    ref = least_squares(W, y, NAMES, method="wls", groups=np.tile([0, 1], 40))
    np.testing.assert_allclose(wls.x, ref.x, rtol=1e-10)
    three = least_squares(W, y, NAMES, method="wls", groups=np.tile([0, 1], 40), wls_passes=3)
    assert not np.allclose(wls.x, three.x, rtol=1e-12, atol=0)
    # no torque at all: the relative residual is undefined, reported as inf
    zero = ReducedObservations.from_rows(W, 0 * y, np.tile([0, 1], 40), 2)
    assert least_squares_reduced(zero, NAMES).relative_residual == np.inf
