"""HAC and block-bootstrap covariances against closed forms and Monte-Carlo coverage."""

from __future__ import annotations

import numpy as np
import pytest

from ident.identify.estimation.uncertainty import (
    BlockEquations,
    andrews_bandwidth,
    block_bootstrap,
    hac_covariance,
    parameter_uncertainty,
    prediction_std,
    z_value,
)


def _ar1(rng: np.random.Generator, n: int, rho: float, shape: tuple = ()) -> np.ndarray:
    e = rng.standard_normal((n, *shape))
    out = np.empty_like(e)
    out[0] = e[0] / np.sqrt(1 - rho**2)
    for k in range(1, n):
        out[k] = rho * out[k - 1] + e[k]
    return out


def _blocks(X: np.ndarray, y: np.ndarray, block: int, w: float = 1.0) -> BlockEquations:
    """One joint: rows X (n, p), torques y (n,)."""
    keep = np.ones((X.shape[0], 1), dtype=bool)
    return BlockEquations.from_samples(X[:, None, :], y[:, None], keep, np.array([w]), block)


def test_blocks_solve_weighted_least_squares_and_drop_masked_rows():
    rng = np.random.default_rng(0)
    n, p = 200, 3
    Yb = rng.standard_normal((n, 2, p))
    tau = rng.standard_normal((n, 2))
    keep = rng.random((n, 2)) > 0.3
    w = np.array([2.0, 0.5])
    blocks = BlockEquations.from_samples(Yb, tau, keep, w, 7)
    # independent reference: lstsq of the kept rows scaled by w_j
    rows = np.concatenate([Yb[keep[:, j], j] * w[j] for j in range(2)])
    rhs = np.concatenate([tau[keep[:, j], j] * w[j] for j in range(2)])
    ref = np.linalg.lstsq(rows, rhs, rcond=None)[0]
    np.testing.assert_allclose(blocks.solve(), ref, rtol=1e-10)
    assert blocks.n_blocks == int(np.ceil(n / 7))
    assert blocks.n_rows.sum() == keep.sum()


def test_hac_equals_the_newey_west_double_sum_on_sample_scores():
    rng = np.random.default_rng(1)
    n, p = 300, 2
    X = np.column_stack([np.ones(n), np.sin(np.arange(n) / 7.0)])
    y = X @ np.array([1.0, -2.0]) + _ar1(rng, n, 0.6)
    x, C, S = hac_covariance(_blocks(X, y, 1), bandwidth=4.5)
    # reference: the textbook formula written out, one sample per score
    beta = np.linalg.lstsq(X, y, rcond=None)[0]
    g = X * (y - X @ beta)[:, None]
    B = sum(g[k][:, None] * g[k][None, :] for k in range(n))
    for lag in range(1, 5):
        G = sum(g[k][:, None] * g[k - lag][None, :] for k in range(lag, n))
        B = B + (1 - lag / 4.5) * (G + G.T)
    Ainv = np.linalg.inv(X.T @ X)
    np.testing.assert_allclose(x, beta, rtol=1e-10)
    np.testing.assert_allclose(C, Ainv @ B @ Ainv * n / (n - p), rtol=1e-9)
    assert S == 4.5


def test_andrews_bandwidth_closed_form_for_one_ar1_component():
    rng = np.random.default_rng(2)
    n, rho = 4000, 0.7
    s = _ar1(rng, n, rho, (1,))
    rho_hat = float(np.sum(s[1:] * s[:-1]) / np.sum(s[:-1] ** 2))
    alpha = 4 * rho_hat**2 / ((1 - rho_hat) ** 2 * (1 + rho_hat) ** 2)
    assert andrews_bandwidth(s) == pytest.approx(1.1447 * (alpha * n) ** (1 / 3), rel=1e-9)
    # white scores: the bandwidth falls to its floor of one block (no lags)
    assert andrews_bandwidth(rng.standard_normal((n, 3))) < 2.0


@pytest.fixture(scope="module")
def monte_carlo():
    """200 fits of a line with smooth regressors and AR(1) noise (rho = 0.8)."""
    rng = np.random.default_rng(3)
    n, reps = 1000, 200
    t = np.arange(n) / n
    X = np.column_stack([np.ones(n), np.sin(2 * np.pi * 3 * t), np.cos(2 * np.pi * 5 * t)])
    beta = np.array([1.0, 0.5, -0.3])
    z = z_value(0.95)
    inside = {"ordinary": [], "hac": [], "bootstrap": []}
    ratio = []
    for r in range(reps):
        y = X @ beta + _ar1(rng, n, 0.8)
        blocks = _blocks(X, y, 5)
        x = blocks.solve()
        resid = y - X @ x
        ordinary = resid @ resid / (n - 3) * np.linalg.inv(X.T @ X)
        unc = parameter_uncertainty(blocks, ("a", "b", "c"), x, ordinary, n_boot=200, rng=r)
        for m in inside:
            inside[m].append(np.abs(x - beta) <= z * unc.std(m))
        ratio.append(unc.std("bootstrap") / unc.std("hac"))
    return {m: float(np.mean(v)) for m, v in inside.items()}, np.array(ratio)


def test_hac_covers_at_the_nominal_rate_where_the_ordinary_covariance_does_not(monte_carlo):
    coverage, _ = monte_carlo
    assert 0.88 <= coverage["hac"] <= 0.99, coverage
    assert coverage["ordinary"] < 0.75, coverage  # AR(1) 0.8: std ~3x too small


def test_block_bootstrap_covers_and_agrees_with_hac(monte_carlo):
    coverage, ratio = monte_carlo
    assert 0.85 <= coverage["bootstrap"] <= 0.99, coverage
    assert 0.7 < np.median(ratio) < 1.3


def test_bootstrap_of_independent_blocks_matches_the_sandwich():
    rng = np.random.default_rng(4)
    n = 2000
    X = np.column_stack([np.ones(n), rng.standard_normal(n)])
    y = X @ np.array([0.3, 2.0]) + rng.standard_normal(n) * (1 + np.abs(X[:, 1]))
    blocks = _blocks(X, y, 1)
    _, C, _ = hac_covariance(blocks, bandwidth=1.0)  # HC1 (heteroscedastic, no lags)
    boot = block_bootstrap(blocks, 1, n_boot=2000, rng=5)
    np.testing.assert_allclose(
        np.sqrt(np.diag(np.cov(boot, rowvar=False))), np.sqrt(np.diag(C)), rtol=0.1
    )


def test_prediction_std_closed_form():
    rng = np.random.default_rng(6)
    Yb = rng.standard_normal((4, 2, 3))
    L = rng.standard_normal((3, 3))
    C = L @ L.T
    sigma = np.array([0.5, 2.0])
    out = prediction_std(Yb, C, sigma)
    k, j = 2, 1
    assert out[k, j] == pytest.approx(np.sqrt(Yb[k, j] @ C @ Yb[k, j] + sigma[j] ** 2))
    assert z_value(0.95) == pytest.approx(1.959964, rel=1e-6)


@pytest.fixture(scope="module")
def rp2(tmp_path_factory):
    """The rp2 arm's 12 s log identified once (WLS): config and result."""
    from robots import rp2_identify_config

    from ident.identify.config import load_identify_config
    from ident.identify.pipeline.real import identify

    cfg = load_identify_config(rp2_identify_config(tmp_path_factory.mktemp("rp2")))
    return cfg, identify(cfg)


def test_identify_blocks_reproduce_its_estimate_in_base_order(rp2):
    """The second pass's blocks (kernel -> base column order, WLS weights) solve to the
    identified WLS estimate, whole log or in chunks, and every held-out std is finite."""
    from ident.identify.pipeline.real import identify

    cfg, result = rp2
    est, unc = result.estimate, result.uncertainty
    assert unc is not None
    np.testing.assert_allclose(unc.x, est.x)
    chunked = cfg.model_copy(
        update={
            "preprocess": cfg.preprocess.model_copy(
                update={"chunked": "always", "chunk_samples": 1500}
            )
        }
    )
    for res in (result, identify(chunked)):
        u = res.uncertainty
        np.testing.assert_allclose(res.estimate.x, est.x, rtol=1e-8, atol=1e-10)
        # a wrong column order or weighting gives another solution entirely
        assert np.all(np.abs(u.x_blocks - est.x) < 0.05 * u.std("hac"))
        assert np.all(u.std("hac") > 0)
    # bootstrap and HAC are both computed; the held-out stds exceed the residual RMS
    for method in ("ordinary", "hac", "bootstrap"):
        std = result.prediction_std[method]
        assert std.shape == result.tau_validate.shape
        assert np.all(std >= est.residual_rms[None, :] * (1 - 1e-12))


def test_report_intervals_are_the_default_methods(rp2):
    """result.json's intervals: x +- 1.96 std of the default method; unseen parameters named."""
    from ident.identify.estimation.uncertainty import DEFAULT_METHOD
    from ident.report.identify_report import result_dict

    _, result = rp2
    entry = result_dict(result)["uncertainty"]
    unc = result.uncertainty
    assert entry["method"] == DEFAULT_METHOD == "bootstrap"
    lo_hi = np.array([p["interval_95"] for p in entry["parameters"]])
    half = 1.959964 * np.sqrt(np.diag(unc.covariance["bootstrap"]))
    np.testing.assert_allclose(lo_hi, np.column_stack([unc.x - half, unc.x + half]), rtol=1e-6)
    np.testing.assert_allclose(unc.x, result.estimate.x)
    # rp2: the first joint turns about the vertical: the mass of link 1 never reaches a torque
    assert "m1" in entry["identifiability"]["not_seen"]
    assert 0.8 < entry["held_out_inside"]["bootstrap"] <= 1.0
    # fv1 is a base parameter alone: its standard-parameter interval is the base one
    (fv1,) = [p for p in entry["identifiability"]["alone"] if p["name"] == "fv1"]
    k = list(unc.names).index("fv1")
    np.testing.assert_allclose(fv1["interval_95"], lo_hi[k], rtol=1e-6)


def test_repeatability_flags_a_drifting_log_only():
    from ident.identify.assessment.repeatability import repeatability

    rng = np.random.default_rng(7)
    std = np.array([[0.1, 1.0, 0.01]] * 6) * rng.uniform(0.8, 1.2, (6, 3))
    x = np.array([2.0, -5.0, 0.3]) + std * rng.standard_normal((6, 3))
    ok = repeatability(x, std, ("a", "b", "c"))
    assert ok.disagree == ()
    # closed form: equal std -> the statistic is (n - 1) s^2 / sigma^2
    same = repeatability(x[:, :1], np.full((6, 1), 0.1), ("a",))
    s2 = np.var(x[:, 0], ddof=1)
    from scipy.stats import chi2

    assert same.p_value[0] == pytest.approx(chi2.sf(5 * s2 / 0.01, 5))
    drift = x.copy()
    drift[4, 1] += 8 * std[4, 1]  # log 5: parameter b drifted by 8 sigma
    bad = repeatability(drift, std, ("a", "b", "c"))
    assert bad.disagree == (("b", 4),)
    assert "log 5 lies farthest" in bad.lines()[0]


def test_cli_repeatability_names_the_drifted_parameter(tmp_path):
    """Two logs of the rp2 arm, the second with the slider's viscous friction 2.0 -> 2.6:
    ``ident repeatability`` exits 1 and names fv2; the same log twice agrees (exit 0)."""
    import yaml
    from robots import rp2_identify_config
    from typer.testing import CliRunner

    from ident.cli import app

    first = rp2_identify_config(tmp_path)
    cfg = yaml.safe_load(first.read_text())
    log = np.genfromtxt(tmp_path / "rp2.csv", delimiter=",", names=True)
    dq = np.gradient(log["q_slider"], log["t"])
    rows = np.column_stack(
        [
            log["t"],
            log["q_shoulder"],
            log["q_slider"],
            log["tau_shoulder"],
            log["tau_slider"] + 0.6 * dq,
        ]
    )
    drifted = tmp_path / "drifted.csv"
    header = "t,q_shoulder,q_slider,tau_shoulder,tau_slider"
    drifted.write_text(header + "\n" + "\n".join(",".join(f"{v:.9g}" for v in r) for r in rows))
    for key in ("time", "position", "torque"):
        cfg["log"][key]["path"] = str(drifted)
    second = tmp_path / "drifted.yaml"
    second.write_text(yaml.safe_dump(cfg))
    runner = CliRunner()
    same = runner.invoke(app, ["repeatability", str(first), str(first)])
    assert same.exit_code == 0, same.output
    assert "agree within their predicted std" in same.output
    out = runner.invoke(app, ["repeatability", str(first), str(second)])
    assert out.exit_code == 1, out.output
    flagged = [line for line in out.output.splitlines() if line.startswith("disagree:")]
    assert any(line.startswith("disagree: fv2:") for line in flagged), out.output
    bad = runner.invoke(app, ["repeatability", str(first)])
    assert bad.exit_code == 2
    assert bad.output.startswith("error: repeatability needs at least two")
