"""Calibration of the payload's 95 % intervals on a linear-Gaussian toy of known coverage.

The toy: rows ``y = X_a phi + X_b (beta - beta_hat) + e`` with white noise ``e ~ N(0, s^2 I)``
(one group of rows) and an arm taken from an earlier log, ``beta_hat = beta + d`` with
``d ~ N(0, C_arm)`` independent of ``e``. The payload is fitted with the arm held at
``beta_hat`` (the ``X_a`` columns only): ``phi_hat - phi = H_aa^-1 X_a^T (e - X_b d)``, exactly
Gaussian with covariance ``s^2 H_aa^-1 + G C_arm G^T`` (``G = -H_aa^-1 H_ab``). The mass is a
component of ``phi``: its 95 % interval, the one ``ident payload`` reports, must hold the truth
in 95 % of the draws up to the binomial spread; ignoring ``C_arm`` must fall short.
"""

import numpy as np
import pytest

from ident.identify.estimation.observations import ReducedObservations
from ident.identify.payload.payload import estimate_payload, with_arm_uncertainty
from ident.identify.payload.payload_arm import select_columns

N_ROWS = 240
N_ARM = 4
N_DRAWS = 400
MASS = 2.5
PHI = np.r_[MASS, MASS * np.array([0.02, 0.03, 0.08]), 0.02, 0.0, 0.03, 0.0, 0.0, 0.01]
NOISE = 0.05  # the rows' noise s
#: Binomial tolerance of a 95 % coverage over N_DRAWS draws: 3.5 standard deviations
#: (sqrt(0.95 * 0.05 / 400) = 1.1 %), a false failure about once in 2000 runs.
TOLERANCE = 3.5 * np.sqrt(0.95 * 0.05 / N_DRAWS)


@pytest.fixture(scope="module")
def toy():
    """Fixed rows ``X_a`` (N_ROWS, 10), ``X_b`` (N_ROWS, N_ARM) sharing directions with
    ``X_a`` (so the arm's error moves the payload), and ``C_arm`` (N_ARM, N_ARM) whose part in
    the mass's variance is about three times the noise's."""
    rng = np.random.default_rng(7)
    X_a = rng.normal(size=(N_ROWS, 10))
    X_b = X_a[:, :N_ARM] @ rng.normal(size=(N_ARM, N_ARM)) + 0.5 * rng.normal(size=(N_ROWS, N_ARM))
    H = np.c_[X_a, X_b].T @ np.c_[X_a, X_b]
    G = -np.linalg.solve(H[:10, :10], H[:10, 10:])
    log_var = NOISE**2 * np.linalg.inv(H[:10, :10])[0, 0]
    L = rng.normal(size=(N_ARM, N_ARM))
    C_arm = L @ L.T + np.eye(N_ARM)
    C_arm *= 3.0 * log_var / (G[0] @ C_arm @ G[0])
    return X_a, X_b, C_arm


def mass_inside(toy, seed: int, with_arm: bool) -> bool:
    """One draw: whether the reported 95 % interval of the mass holds the truth."""
    X_a, X_b, C_arm = toy
    rng = np.random.default_rng(seed)
    d = rng.multivariate_normal(np.zeros(N_ARM), C_arm)
    y = X_a @ PHI - X_b @ d + NOISE * rng.normal(size=N_ROWS)
    red = ReducedObservations.from_rows(np.c_[X_a, X_b], y, np.zeros(N_ROWS), 1)
    result = estimate_payload(select_columns(red, np.arange(10)), (), method="wls")
    result = with_arm_uncertainty(result, red, C_arm if with_arm else None, "toy", None)
    lower, upper = result.intervals()[0]
    return bool(lower <= MASS <= upper)


def test_mass_interval_covers_95_percent_with_the_arm_error_propagated(toy):
    """400 draws: the mass's 95 % interval (``C_log + G C_arm G^T``) holds the truth in
    95 % +- 3.8 % (binomial, 3.5 σ; measured 95.25 %); the same intervals without the arm's
    covariance (the arm taken as exact) hold it in ``P(|N| < 1.96 / 2) = 67 %`` (measured
    69 % on 80 draws) and fail."""
    with_arm = np.mean([mass_inside(toy, 1000 + k, True) for k in range(N_DRAWS)])
    assert abs(with_arm - 0.95) <= TOLERANCE, with_arm
    without = np.mean([mass_inside(toy, 1000 + k, False) for k in range(N_DRAWS // 5)])
    assert without < 0.8, without


def test_benchmark_noise_has_a_floor_and_its_coverage_a_binomial_interval():
    """benchmarks/bench_payload.py: the simulated torque noise is the floor and 1 % of each
    joint's RMS torque added in variance (the floor alone on a joint with no load, the
    relative part where it dominates; no floor: the 1 % alone, as bench_signals and
    bench_stream simulate); the coverage's spread is the Wilson interval (scipy's)."""
    import sys
    from pathlib import Path

    from scipy.stats import binomtest

    repo = Path(__file__).resolve().parents[1]
    sys.path.insert(0, str(repo / "benchmarks"))
    from bench_payload import simulation_setup, torque_noise_std, wilson_interval

    np.testing.assert_allclose(
        torque_noise_std(np.array([0.0, 3.0, 400.0]), 0.1), [0.1, 0.1 * np.sqrt(1.09), 4.0012498]
    )
    config = repo / "configs" / "ur5.yaml"
    _, robot, (_, q, dq, ddq), plain = simulation_setup(config, seconds=10, seed=3)
    _, _, _, floored = simulation_setup(config, seconds=10, seed=3, noise_floor=0.1)
    rms = np.sqrt(np.mean(robot.rnea(q, dq, ddq) ** 2, axis=0))
    np.testing.assert_allclose(plain["torque_noise_std"], 0.01 * rms)
    np.testing.assert_allclose(floored["torque_noise_std"], np.hypot(0.1, 0.01 * rms))
    for k, n in ((76, 80), (80, 80), (71, 80), (19, 20)):
        expected = binomtest(k, n).proportion_ci(method="wilson")
        np.testing.assert_allclose(wilson_interval(k, n), (expected.low, expected.high))
