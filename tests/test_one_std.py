"""One standard deviation everywhere: the verdict, the warnings, the reports and result.json
read the default interval method's (the moving-block bootstrap's), not the ordinary one that
assumes independent residuals (:func:`ident.identify.estimation.uncertainty.parameter_std`)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from ident.identify.assessment.verdict import GOOD_STD_PERCENT, decide_verdict, log_evidence
from ident.identify.estimation.estimate import least_squares
from ident.identify.estimation.uncertainty import (
    BlockEquations,
    parameter_std,
    parameter_uncertainty,
)

ROOT = Path(__file__).resolve().parents[1]
N, RHO, NOISE = 2000, 0.97, 0.5
T = np.arange(N) / N
# smooth regressors (what a filtered excitation gives): AR(1) noise does not average out
X = np.column_stack([np.ones(N), np.sin(2 * np.pi * 2 * T), np.cos(2 * np.pi * 3 * T)])
BETA = np.array([1.0, 0.8, -0.6])
NAMES = ("m1", "mcx1", "Ia1")


def _ar1(rng: np.random.Generator, n: int, rho: float) -> np.ndarray:
    e = rng.standard_normal(n)
    out = np.empty(n)
    out[0] = e[0] / np.sqrt(1 - rho**2)
    for k in range(1, n):
        out[k] = rho * out[k - 1] + e[k]
    return out * np.sqrt(1 - rho**2)  # unit variance


def _fit(seed: int) -> tuple[object, object]:
    """OLS of one joint's torques with AR(1)-correlated noise, and its robust covariances."""
    y = X @ BETA + NOISE * _ar1(np.random.default_rng(seed), N, RHO)
    est = least_squares(X, y[:, None], NAMES, method="ols")
    keep = np.ones((N, 1), dtype=bool)
    blocks = BlockEquations.from_samples(X[:, None, :], y[:, None], keep, np.ones(1), 1)
    unc = parameter_uncertainty(blocks, NAMES, est.x, est.covariance, rng=seed)
    return est, unc


def _result(est: object, unc: object) -> SimpleNamespace:
    """What :func:`log_evidence` reads of an identify result: held-out residual 3 %, URDF 30 %."""
    pred = {
        "ols": SimpleNamespace(metrics=SimpleNamespace(total_relative_residual=0.03)),
        "URDF nominal": SimpleNamespace(metrics=SimpleNamespace(total_relative_residual=0.3)),
    }
    config = SimpleNamespace(
        validation=SimpleNamespace(identify_fraction=0.7, truth=None),
        estimation=SimpleNamespace(method="ols"),
    )
    return SimpleNamespace(
        estimate=est,
        uncertainty=unc,
        predictions=pred,
        config=config,
        warnings=(),
        consistent=None,
    )


@pytest.fixture(scope="module")
def correlated():
    """One fit, and the spread of the estimate over 60 noise draws (the independent truth)."""
    est, unc = _fit(0)
    spread = np.std([_fit_x(s) for s in range(1, 61)], axis=0, ddof=1)
    return est, unc, spread


def _fit_x(seed: int) -> np.ndarray:
    y = X @ BETA + NOISE * _ar1(np.random.default_rng(seed), N, RHO)
    return np.linalg.lstsq(X, y, rcond=None)[0]


def test_the_verdict_reads_the_calibrated_std_where_the_ordinary_one_says_good(correlated):
    est, unc, spread = correlated
    # the Monte-Carlo spread of the estimate: the bootstrap σ has its size, the ordinary not
    assert np.all(unc.std() > 0.5 * spread), (unc.std(), spread)
    assert np.all(unc.std() < 2.0 * spread), (unc.std(), spread)
    assert np.all(est.std < 0.4 * spread), (est.std, spread)
    # the ordinary σ alone (a log without the bootstrap) would say good ...
    ordinary = log_evidence(_result(est, None))
    assert ordinary.std_method == "ordinary"
    assert ordinary.worst_std_percent < GOOD_STD_PERCENT
    assert decide_verdict(ordinary).label == "good"
    # ... the calibrated σ does not: the data do not pin the parameters to 5 %
    e = log_evidence(_result(est, unc))
    sd = parameter_std(est, unc)
    assert e.std_method == sd.method == "bootstrap"
    k = list(NAMES).index(e.worst_std_name)
    assert e.worst_std_percent == pytest.approx(100 * unc.std()[k] / abs(est.x[k]))
    assert e.worst_std_percent == pytest.approx(float(np.max(sd.relative_std)))
    assert e.worst_std_percent > GOOD_STD_PERCENT
    v = decide_verdict(e)
    assert v.label == "usable", v
    assert "bootstrap" in v.reason


def test_without_the_bootstrap_the_ordinary_std_is_used_and_said(correlated):
    est, unc, _ = correlated
    sd = parameter_std(est, None)
    assert sd.method == "ordinary"
    assert not sd.calibrated
    np.testing.assert_array_equal(sd.std, est.std)
    assert "too few blocks" in sd.note
    # an uncertainty of another estimate (e.g. OLS beside WLS) is not borrowed
    other = SimpleNamespace(
        x=est.x + 1e-3, std=est.std, relative_std=est.relative_std, covariance=est.covariance
    )
    assert parameter_std(other, unc).method == "ordinary"


@pytest.fixture(scope="module")
def tiago(tiago_identified):
    """The shipped TIAGo example log identified once, and its run folder (``ident identify``'s
    report: tests/conftest.py, shared with tests/test_tiago_example.py)."""
    _, folder, _, result = tiago_identified
    return result, folder


def test_the_warnings_read_the_calibrated_std(tiago):
    result, _ = tiago
    sd = result.parameter_std
    assert sd.method == "bootstrap"
    est = result.estimate
    names = list(est.names)
    (high,) = [w for w in result.warnings if "relative standard deviation (bootstrap)" in w]
    listed = re.findall(r"(\w+) \((\d+) %, [\d.]+ % of the torques\)", high)
    assert listed
    for name, shown in listed:
        k = names.index(name)
        assert sd.relative_std[k] > 50.0
        assert int(shown) == round(sd.relative_std[k])
    # at least one of them the ordinary σ calls well determined: the warning reads the bootstrap
    assert any(est.relative_std[names.index(n)] < 50.0 for n, _ in listed)
    # a negative parameter is flagged only when it is 2 bootstrap σ below zero: Izz8 is
    # 2 ordinary σ below zero, not 2 bootstrap σ
    k = names.index("Izz8")
    assert est.x[k] + 2 * est.std[k] < 0 < est.x[k] + 2 * sd.std[k]
    assert not any(w.startswith("Izz8 =") for w in result.warnings)
    assert any(w.startswith("fs7 =") and "bootstrap" in w for w in result.warnings)


def test_report_verdict_and_result_json_show_the_same_std(tiago):
    result, folder = tiago
    data = json.loads((folder / "result.json").read_text(encoding="utf-8"))
    v = data["verdict"]
    name = v["worst_std_name"]
    assert v["std_method"] == data["std_method"] == "bootstrap"
    (entry,) = [p for p in data["base_parameters"] if p["name"] == name]
    k = list(result.estimate.names).index(name)
    sd = result.parameter_std
    assert v["worst_std_percent"] == pytest.approx(entry["relative_std_pct"], rel=1e-12)
    assert entry["relative_std_pct"] == pytest.approx(sd.relative_std[k], rel=1e-12)
    assert entry["std"] == pytest.approx(
        float(np.sqrt(result.uncertainty.covariance["bootstrap"][k, k]))
    )
    assert entry["ordinary_std"] == pytest.approx(float(result.estimate.std[k]))
    # the report's base-parameter table: the σ [%] column, three significant digits
    md = (folder / "report.md").read_text(encoding="utf-8")
    (row,) = [ln for ln in md.splitlines() if re.match(rf"\| \d+ \| {name} \|", ln)]
    cell = float(row.split("|")[5])
    assert cell == pytest.approx(float(f"{sd.relative_std[k]:.3g}"))
    assert "the bootstrap standard deviation" in md
    # parameters.csv
    csv = (folder / "parameters.csv").read_text(encoding="utf-8").splitlines()
    (line,) = [ln for ln in csv if ln.startswith(f"{name},")]
    assert float(line.split(",")[4]) == pytest.approx(sd.relative_std[k], rel=1e-12)
