"""The verdict's evidence and reasons, pinned where mutation testing found them unchecked.

Each test states what a user reads (the reason of a verdict, the parameter the report calls
the worst, the rows it judged on) on hand-built results whose numbers are known in closed
form; ``benchmarks/mutation.py --modules verdict`` measures how many mutants they kill.
"""

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from ident.identify.assessment.verdict import (
    MAJOR_SHARE,
    Evidence,
    Truth,
    covariance_torque_shares,
    decide_verdict,
    identify_verdict,
    judged_method,
    log_evidence,
    thresholds_markdown,
    truth_error,
    truth_from_config,
)

ROOT = Path(__file__).resolve().parents[1]


def test_the_documented_threshold_table_is_the_generated_one():
    text = (ROOT / "docs" / "verdict.md").read_text(encoding="utf-8")
    lines = thresholds_markdown()
    assert lines[:2] == ["| threshold | value | unit |", "| --- | --- | --- |"]
    assert "| `GOOD_RESIDUAL` | 0.1 | fraction |" in lines
    assert "\n".join(lines) in text


# ------------------------------------------------------------------ reasons a user reads


def test_truth_reason_names_every_number_and_note():
    e = Evidence(
        worst_error_percent=3.0,
        worst_error_name="m1",
        residual=0.05,
        warnings=("w1", "w2"),
        n_inconsistent=2,
        n_links=6,
    )
    v = decide_verdict(e)
    assert v.label == "usable"  # a warning rules out good
    assert v.rule == "truth"
    assert v.reason == (
        "worst major-parameter error 3 % (m1), torque residual 5 % (held-out data); "
        "2 warning(s); 2 of 6 links physically inconsistent"
    )
    assert v.as_dict() == {"label": "usable", "reason": v.reason, "rule": "truth"}


def test_log_reason_names_residual_nominal_and_sigma():
    e = Evidence(
        residual=0.02,
        residual_where="identification rows",
        nominal_residual=0.4,
        worst_std_percent=2.5,
        worst_std_name="Izz3R",
    )
    v = decide_verdict(e)
    assert (v.label, v.rule) == ("good", "log")
    assert v.reason == (
        "torque residual 2 % (identification rows), URDF nominal 40 %, worst σ 2.5 % (Izz3R)"
    )
    worse = decide_verdict(Evidence(residual=0.3, nominal_residual=0.2, worst_std_percent=None))
    assert worse.label == "not identified"
    assert worse.reason == (
        "torque residual 30 % (held-out data), URDF nominal 20 %, worst σ unknown; "
        "not better than the URDF nominal"
    )


def test_missing_evidence_gives_not_identified_with_its_reason():
    v = decide_verdict(Evidence(estimated=False, residual=0.01, worst_error_percent=1.0))
    assert (v.label, v.reason, v.rule) == (
        "not identified",
        "no estimate (every estimator failed)",
        "truth",
    )
    v = decide_verdict(Evidence(truth=True, residual=0.01))  # truth known, no error computed
    assert (v.label, v.reason) == ("not identified", "no error against the truth (no estimate)")
    v = decide_verdict(Evidence(residual=None, worst_std_percent=1.0))
    assert (v.label, v.reason, v.rule) == ("not identified", "no torque prediction to judge", "log")
    v = decide_verdict(Evidence(safe=False, residual=0.0, worst_error_percent=0.0))
    assert v.reason == "the executed trajectory failed its safety check"
    # truth=False: judged by the log rule even with an error given
    assert decide_verdict(Evidence(truth=False, worst_error_percent=1.0, residual=0.01)).rule == (
        "log"
    )


def test_non_finite_numbers_are_unknown_never_small():
    v = decide_verdict(Evidence(worst_error_percent=1.0, residual=float("nan")))
    assert v.label == "not identified"
    assert "torque residual unknown" in v.reason
    # an infinite nominal residual says nothing: the estimate is judged on its own
    assert (
        decide_verdict(
            Evidence(residual=0.01, worst_std_percent=1.0, nominal_residual=np.inf)
        ).label
        == "good"
    )
    # no σ known: not good, still usable when the residual is small
    assert decide_verdict(Evidence(residual=0.01, worst_std_percent=None)).label == "usable"


# ------------------------------------------------------------ evidence from a result


def _result(
    *,
    x=(2.0, 1.0, 1e-4),
    rel=(1.0, 3.0, 900.0),
    method="wls",
    configured="wls",
    fraction=0.7,
    warnings=(),
    consistent=None,
    truth=None,
    covariance=True,
):
    x = np.asarray(x, dtype=float)
    names = ("m1", "mcx1R", "Ia1")
    est = SimpleNamespace(
        x=x,
        relative_std=np.asarray(rel, dtype=float),
        std=np.abs(x) * np.asarray(rel) / 100.0,
        names=names,
        method=method,
    )
    if covariance:
        # uncorrelated unit columns: torque shares |x_i| / ||x||
        est.covariance = np.eye(x.size)
    predictions = {
        method: SimpleNamespace(metrics=SimpleNamespace(total_relative_residual=0.03)),
        "URDF nominal": SimpleNamespace(metrics=SimpleNamespace(total_relative_residual=0.3)),
    }
    if consistent is not None:
        predictions["lmi"] = SimpleNamespace(metrics=SimpleNamespace(total_relative_residual=0.04))
    config = SimpleNamespace(
        validation=SimpleNamespace(identify_fraction=fraction, truth=truth),
        estimation=SimpleNamespace(method=configured),
    )
    return SimpleNamespace(
        estimate=est,
        predictions=predictions,
        config=config,
        warnings=tuple(warnings),
        consistent=consistent,
    )


def test_worst_sigma_is_over_the_torque_carrying_parameters_only():
    # shares: 2/sqrt(5), 1/sqrt(5), 4.5e-5 -> Ia1 carries nothing; its 900 % σ is not judged
    e = log_evidence(_result())
    assert (e.worst_std_percent, e.worst_std_name) == (3.0, "mcx1R")
    assert e.residual == pytest.approx(0.03)
    assert e.nominal_residual == pytest.approx(0.3)
    assert e.residual_where == "held-out data"
    assert e.method == "wls"
    assert (e.n_inconsistent, e.n_links) == (None, None)
    assert e.worst_error_percent is None
    assert not e.truth_known
    assert decide_verdict(e).label == "good"
    # a parameter just above MAJOR_SHARE is judged
    x3 = 1.01 * MAJOR_SHARE * np.sqrt(5.0) / np.sqrt(1.0 - (1.01 * MAJOR_SHARE) ** 2)
    e = log_evidence(_result(x=(2.0, 1.0, x3)))
    assert (e.worst_std_percent, e.worst_std_name) == (900.0, "Ia1")
    # no covariance: every parameter is judged; a non-finite σ is the worst
    e = log_evidence(_result(covariance=False))
    assert (e.worst_std_percent, e.worst_std_name) == (900.0, "Ia1")
    e = log_evidence(_result(rel=(1.0, np.nan, 2.0)))
    assert (e.worst_std_percent, e.worst_std_name) == (np.inf, "mcx1R")


def test_in_sample_residual_and_warnings_are_said():
    e = log_evidence(
        _result(fraction=1.0, warnings=("own",)), extra_warnings=("caller",), safe=True
    )
    assert e.residual_where == "identification rows"
    assert e.warnings == ("caller", "own")
    assert e.safe is True
    assert log_evidence(_result(), safe=False).safe is False


def _consistent(flags, method="lmi"):
    links = [SimpleNamespace(consistent=f) for f in flags]
    return SimpleNamespace(estimates={method: SimpleNamespace(consistency=links)})


def test_the_configured_constrained_estimate_is_the_one_judged():
    result = _result(configured="lmi", consistent=_consistent([True, False, False]))
    assert judged_method(result) == "lmi"
    e = log_evidence(result)
    assert e.method == "lmi"
    assert e.residual == pytest.approx(0.04)  # the lmi prediction, not the wls one
    assert (e.n_inconsistent, e.n_links) == (2, 3)
    assert decide_verdict(e).label == "usable"  # inconsistent links rule out good
    # configured method without consistency data: the least-squares estimate is judged
    other = _result(configured="lmi", consistent=_consistent([True], method="log_cholesky"))
    assert judged_method(other) == "wls"
    assert (log_evidence(other).n_inconsistent, log_evidence(other).n_links) == (None, None)
    assert judged_method(_result(configured="lmi")) == "wls"


def test_truth_error_is_the_worst_major_parameter():
    truth = Truth(
        names=("m1", "mcx1R", "Ia1"),
        values=np.array([2.0, 1.0, 1e-4]),
        reference_share=np.array([0.5, MAJOR_SHARE, 1e-4]),  # Ia1 is not major
    )
    x = np.array([2.1, 0.8, 5e-4])  # 5 %, 20 %, 400 %
    worst, name, n_major = truth_error(x, np.ones(3), truth.names, truth)
    assert worst == pytest.approx(20.0)
    assert (name, n_major) == ("mcx1R", 2)
    assert truth_error(x, np.ones(3), ("a", "b", "c"), truth) is None
    # the simulator's truth in an identify config reaches the verdict
    entry = SimpleNamespace(
        base_names=list(truth.names),
        values=list(truth.values),
        reference_share=list(truth.reference_share),
    )
    t = truth_from_config(entry)
    assert t.names == truth.names
    np.testing.assert_array_equal(t.reference_share, truth.reference_share)
    assert truth_from_config(None) is None
    result = _result(x=x, truth=entry)
    e = log_evidence(result, truth=t)
    assert (e.worst_error_percent, e.worst_error_name) == (pytest.approx(20.0), "mcx1R")
    v = identify_verdict(result)
    assert (v.label, v.rule) == ("usable", "truth")  # 20 % is usable, not good
    assert v.reason.startswith("worst major-parameter error 20 % (mcx1R)")
    # a truth for other parameter names is not used: the log rule
    wrong = Truth(names=("a", "b", "c"), values=truth.values, reference_share=np.ones(3))
    assert log_evidence(result, truth=wrong).worst_error_percent is None


# every branch says which rule judged it (result.json's verdict.rule)
BRANCHES = {
    "unsafe": dict(safe=False),
    "no estimate": dict(estimated=False),
    "good": dict(residual=0.01, worst_std_percent=1.0, nominal_residual=0.5),
    "usable": dict(residual=0.2, worst_std_percent=1.0, nominal_residual=0.5),
    "not identified": dict(residual=0.3, worst_std_percent=1.0, nominal_residual=0.5),
    "worse than nominal": dict(residual=0.3, worst_std_percent=1.0, nominal_residual=0.2),
}


@pytest.mark.parametrize("branch", BRANCHES)
def test_every_branch_names_its_rule(branch):
    kw = BRANCHES[branch]
    log = decide_verdict(Evidence(**kw))
    assert log.rule == "log"
    assert log.reason  # never empty: the report prints it after the label
    truth = decide_verdict(Evidence(**{**kw, "worst_error_percent": 1.0}))
    assert truth.rule == "truth"
    assert decide_verdict(Evidence(truth=True, residual=0.01)).rule == "truth"


def test_log_reasons_of_usable_and_not_identified():
    v = decide_verdict(Evidence(residual=0.2, worst_std_percent=7.0, warnings=("w",)))
    assert (v.label, v.reason) == (
        "usable",
        "torque residual 20 % (held-out data), worst σ 7 %; 1 warning(s)",
    )
    v = decide_verdict(Evidence(residual=0.3, worst_std_percent=1.0, n_inconsistent=1, n_links=2))
    assert (v.label, v.reason) == (
        "not identified",
        "torque residual 30 % (held-out data), worst σ 1 %; 1 of 2 links physically inconsistent",
    )


def test_torque_shares_do_not_depend_on_the_units_and_zero_says_nothing():
    x = np.array([99.0, 9.0, 9.0, 6.0, 1.0])  # ||x|| = 100: shares exactly x / 100
    shares = covariance_torque_shares(x, np.eye(5))
    np.testing.assert_allclose(shares, x / 100.0, rtol=1e-12)
    np.testing.assert_allclose(covariance_torque_shares(1e-3 * x, 1e6 * np.eye(5)), shares)
    zero = covariance_torque_shares(np.zeros(3), np.eye(3))
    assert zero.shape == (3,)
    assert np.isnan(zero).all()
    assert np.isnan(covariance_torque_shares(x, np.full((5, 5), np.nan))).all()


def test_a_parameter_at_exactly_the_major_share_is_judged():
    x = np.array([99.0, 9.0, 9.0, 6.0, 1.0])  # the last carries exactly MAJOR_SHARE
    assert covariance_torque_shares(x, np.eye(5))[-1] == MAJOR_SHARE
    est = SimpleNamespace(
        x=x,
        relative_std=np.array([1.0, 1.0, 1.0, 1.0, 50.0]),
        std=np.ones(5),
        names=("a", "b", "c", "d", "e"),
        method="wls",
        covariance=np.eye(5),
    )
    result = _result()
    result.estimate = est
    assert log_evidence(result).worst_std_name == "e"
