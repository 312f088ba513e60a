import numpy as np
import pytest

from ident.excitation.constraints import (
    NONFINITE_VIOLATION,
    JointLimits,
    continuity_violations,
    evaluate_constraints,
    limit_violations,
    penalty,
)


@pytest.fixture
def limits():
    return JointLimits(
        joint_names=("j1", "j2"),
        q_lower=np.array([-1.0, -np.inf]),
        q_upper=np.array([1.0, np.inf]),
        dq_max=np.array([2.0, np.inf]),
        ddq_max=np.array([4.0, 8.0]),
    )


def _states(q1, dq1, ddq1):
    # two particles, three samples, two joints; joint 2 always quiet
    q = np.zeros((2, 3, 2))
    dq = np.zeros((2, 3, 2))
    ddq = np.zeros((2, 3, 2))
    q[1, 1, 0], dq[1, 2, 0], ddq[1, 0, 0] = q1, dq1, ddq1
    return q, dq, ddq


def test_satisfied_is_exactly_zero(limits):
    v = limit_violations(*_states(1.0, -2.0, 4.0), limits)  # exactly at the limits
    assert v.names[:2] == ("position:j1", "position:j2")
    assert np.all(v.values == 0.0)
    assert np.all(v.feasible())


def test_violated_magnitudes_exact(limits):
    v = limit_violations(*_states(-1.5, 3.0, -5.0), limits)
    d = v.as_dict(1)
    assert d == {
        "position:j1": pytest.approx(0.5 / 2.0, rel=1e-15),
        "velocity:j1": pytest.approx(0.5, rel=1e-15),
        "acceleration:j1": pytest.approx(0.25, rel=1e-15),
    }
    assert v.as_dict(0) == {}
    np.testing.assert_array_equal(v.feasible(), [True, False])
    assert v.total()[1] == pytest.approx(1.0)


def test_infinite_limits_never_violated(limits):
    q, dq, ddq = _states(0.0, 0.0, 0.0)
    q[:, :, 1] = 1e6
    dq[:, :, 1] = -1e6
    assert np.all(limit_violations(q, dq, ddq, limits).values[:, :2] == 0.0)
    ddq[0, 0, 1] = 16.0  # joint 2 has a finite acceleration limit
    assert limit_violations(q, dq, ddq, limits).as_dict(0) == {"acceleration:j2": 1.0}


def test_nonfinite_is_large_and_finite(limits):
    q, dq, ddq = _states(np.nan, np.inf, 0.0)
    v = limit_violations(q, dq, ddq, limits)
    assert np.all(np.isfinite(v.values))
    assert v.as_dict(1)["position:j1"] == NONFINITE_VIOLATION
    assert v.as_dict(1)["velocity:j1"] == NONFINITE_VIOLATION


def test_continuity(limits):
    start = (np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2)))
    end = (
        np.array([[0.0, 0.0], [0.2, 2 * np.pi]]),
        np.zeros((2, 2)),
        np.array([[0, 1e-12], [0, 0]]),
    )
    v = continuity_violations(start, end, limits)
    assert v.names == ("continuity:j1", "continuity:j2")
    np.testing.assert_allclose(v.values, [[0.0, 0.0], [0.1, 1.0]])  # 2 pi on the 2 pi fallback


def test_evaluate_and_penalty(limits):
    q, dq, ddq = _states(0.0, 3.0, 0.0)
    v = evaluate_constraints(q, dq, ddq, limits, reachability=np.array([0.0, 0.3]))
    assert v.names[-1] == "reachability"
    assert v.as_dict(1) == {"velocity:j1": 0.5, "reachability": pytest.approx(0.3)}
    p = penalty(v, 100.0)
    np.testing.assert_allclose(p, [0.0, 100.0 * 1.8])
    with pytest.raises(ValueError, match="both"):
        evaluate_constraints(q, dq, ddq, limits, start=(q[:, 0], dq[:, 0], ddq[:, 0]))


def test_limit_violations_equal_the_sample_wise_formula(limits):
    """The one-pass extremes give what the formula over every sample gives, NaN and inf too
    (a kernel that skipped NaN, or took max |q| for the position, would differ)."""
    rng = np.random.default_rng(3)
    q, dq, ddq = (rng.normal(scale=s, size=(6, 50, 2)) for s in (1.0, 2.5, 5.0))
    q[1, 7, 0], dq[2, 3, 0], ddq[3, 9, 0], q[4, 0, 1], dq[5, 49, 0] = (
        np.nan, np.nan, np.inf, -np.inf, -np.inf,
    )  # fmt: skip
    span = limits.q_upper - limits.q_lower
    with np.errstate(invalid="ignore"):
        above = np.max(q - limits.q_upper, axis=1)
        below = np.max(limits.q_lower - q, axis=1)
        position = np.maximum(np.maximum(above, below), 0.0) / span
        velocity = np.maximum(np.max(np.abs(dq), axis=1) - limits.dq_max, 0.0) / limits.dq_max
        acceleration = np.maximum(np.max(np.abs(ddq), axis=1) - limits.ddq_max, 0.0)
    position = np.where(np.isfinite(span), position, 0.0)
    position = np.where(np.all(np.isfinite(q), axis=1), position, NONFINITE_VIOLATION)
    velocity = np.where(np.isfinite(limits.dq_max), velocity, 0.0)
    acceleration = np.where(np.isfinite(limits.ddq_max), acceleration / limits.ddq_max, 0.0)
    expected = np.concatenate([position, velocity, acceleration], axis=1)
    expected = np.where(np.isfinite(expected), expected, NONFINITE_VIOLATION)
    got = limit_violations(q, dq, ddq, limits).values
    np.testing.assert_array_equal(got, expected)
    assert got[1, 0] == NONFINITE_VIOLATION
    assert got[2, 2] == NONFINITE_VIOLATION
