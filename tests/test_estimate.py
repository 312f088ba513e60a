import numpy as np
import pytest

from ident.errors import DataError, NotIdentifiable
from ident.identify.estimation.estimate import least_squares, rank_report


def _problem(rng, n_samples=400, n_rows=3, n_params=5):
    W = rng.normal(size=(n_samples * n_rows, n_params)) * rng.uniform(0.1, 10.0, n_params)
    x = rng.normal(size=n_params)
    return W, x


def test_exact_recovery_noise_free():
    rng = np.random.default_rng(0)
    W, x = _problem(rng)
    tau = (W @ x).reshape(-1, 3)
    names = [f"p{i}" for i in range(5)]
    for method in ("ols", "wls"):
        est = least_squares(W, tau, names, method=method)
        np.testing.assert_allclose(est.x, x, rtol=1e-10, atol=1e-12)
        assert est.relative_residual < 1e-12
        assert est.success
        assert est.n_samples == 400
        assert est.residual_rms.shape == (3,)
    wls = least_squares(W, tau, names, method="wls")
    assert "noise-free" in wls.message


def test_closed_form_one_parameter():
    # tau = a * t: OLS slope and its std have closed forms.
    t = np.linspace(0.0, 1.0, 11)
    tau = 2.0 * t + np.array([0.1, -0.1] * 5 + [0.0])
    est = least_squares(t[:, None], tau, ["a"])
    a = t @ tau / (t @ t)
    r = tau - a * t
    sigma2 = r @ r / (t.size - 1)
    assert est.x[0] == pytest.approx(a, rel=1e-14)
    assert est.std[0] == pytest.approx(np.sqrt(sigma2 / (t @ t)), rel=1e-12)
    assert est.relative_std[0] == pytest.approx(100 * est.std[0] / abs(a), rel=1e-12)


def test_std_matches_monte_carlo_spread():
    # The reported std is the spread of the estimate over repeated noisy experiments.
    rng = np.random.default_rng(1)
    W, x = _problem(rng, n_samples=100)
    sigma = 0.5
    estimates, stds = [], []
    for _ in range(400):
        tau = W @ x + sigma * rng.normal(size=W.shape[0])
        est = least_squares(W, tau, [f"p{i}" for i in range(5)], rows_per_sample=3)
        estimates.append(est.x)
        stds.append(est.std)
    spread = np.std(estimates, axis=0, ddof=1)
    # 400 draws: the sample std of the spread is within ~3.5 % (1 sigma); allow 12 %.
    np.testing.assert_allclose(np.mean(stds, axis=0), spread, rtol=0.12)


def test_wls_weights_noisy_joint_down():
    rng = np.random.default_rng(2)
    W, x = _problem(rng, n_samples=600)
    noise = np.array([0.01, 0.01, 1.0])  # joint 2 is 100x noisier
    tau = (W @ x).reshape(-1, 3) + noise * rng.normal(size=(600, 3))
    names = [f"p{i}" for i in range(5)]
    ols = least_squares(W, tau, names, method="ols")
    wls = least_squares(W, tau, names, method="wls")
    np.testing.assert_allclose(wls.sigma, noise, rtol=0.15)
    assert np.all(wls.std < ols.std)
    assert np.linalg.norm(wls.x - x) < np.linalg.norm(ols.x - x)


def test_wls_equals_ols_for_equal_noise():
    rng = np.random.default_rng(3)
    W, x = _problem(rng, n_samples=2000)
    tau = W @ x + 0.1 * rng.normal(size=W.shape[0])
    names = [f"p{i}" for i in range(5)]
    # One group: identical by construction.
    ols1 = least_squares(W, tau, names, method="ols")
    wls1 = least_squares(W, tau, names, method="wls")
    np.testing.assert_allclose(wls1.x, ols1.x, rtol=1e-12)
    np.testing.assert_allclose(wls1.std, ols1.std, rtol=1e-12)
    # Three groups with the same noise: differences far below the std.
    ols = least_squares(W, tau, names, method="ols", rows_per_sample=3)
    wls = least_squares(W, tau, names, method="wls", rows_per_sample=3)
    assert np.all(np.abs(wls.x - ols.x) < 0.1 * ols.std)
    np.testing.assert_allclose(wls.std, ols.std, rtol=0.05)


def test_groups_argument_matches_rows_per_sample():
    rng = np.random.default_rng(4)
    W, x = _problem(rng)
    tau = W @ x + 0.1 * rng.normal(size=W.shape[0])
    names = [f"p{i}" for i in range(5)]
    a = least_squares(W, tau, names, method="wls", rows_per_sample=3)
    b = least_squares(W, tau, names, method="wls", groups=np.tile([0, 1, 2], 400))
    np.testing.assert_allclose(a.x, b.x, rtol=1e-12)
    np.testing.assert_allclose(a.residual_rms, b.residual_rms, rtol=1e-12)


def test_rank_deficiency_names_parameters():
    rng = np.random.default_rng(5)
    W, x = _problem(rng)
    names = ["m1", "mx1", "Ia2", "fv2", "fs2"]
    dead = W.copy()
    dead[:, 3] = 0.0
    with pytest.raises(NotIdentifiable, match=r"fv2 have no effect"):
        least_squares(dead, dead @ x, names)
    combo = W.copy()
    combo[:, 4] = 2.0 * combo[:, 1] - combo[:, 2]
    with pytest.raises(NotIdentifiable, match=r"mx1, Ia2, fs2 enter the torques only in a linear"):
        least_squares(combo, combo @ x, names)


def test_rank_report_names_a_multi_dimensional_null_space_once():
    rng = np.random.default_rng(7)
    W = rng.standard_normal((300, 6))
    names = ["a", "b", "c", "d", "e", "f"]
    W[:, 2] = W[:, 0] + W[:, 1]  # two independent dependencies among a, b, c, d
    W[:, 3] = W[:, 0] - 2.0 * W[:, 1]
    W[:, 5] = 0.0  # f not excited
    msg = rank_report(W, names)
    assert msg == (
        "parameter(s) f have no effect on the torques (not excited by the motion, or removed by "
        "the velocity threshold); parameters a, b, c, d enter the torques only in a linear "
        "combination (2 independent combinations of these 4 are undetermined). "
        "Reduce to base parameters, drop the parameter(s), or record a motion that excites them."
    )
    assert rank_report(W, names, advice="").endswith("are undetermined).")
    assert rank_report(W[:, [0, 1, 4]], ["a", "b", "e"]) is None


def test_bad_input():
    rng = np.random.default_rng(6)
    W, x = _problem(rng, n_samples=1, n_rows=3, n_params=5)
    with pytest.raises(DataError, match="too few observations: 3 rows for 5 parameters"):
        least_squares(W, W @ x, list("abcde"))
    W, x = _problem(rng)
    tau = W @ x
    tau[7] = np.nan
    with pytest.raises(DataError, match="NaN"):
        least_squares(W, tau, list("abcde"))
    with pytest.raises(DataError, match="method"):
        least_squares(W, W @ x, list("abcde"), method="tls")


def test_result_is_read_only():
    rng = np.random.default_rng(7)
    W, x = _problem(rng)
    est = least_squares(W, W @ x + rng.normal(size=W.shape[0]), list("abcde"))
    with pytest.raises(ValueError, match="read-only"):
        est.x[0] = 1.0
