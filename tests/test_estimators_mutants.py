"""The estimator registry, OLS/WLS through it and the choice of the prior weight, at their
boundaries (fast: toy estimators, no solver).

What a user relies on: ``estimation.method`` names an estimator or gets one line with the
closest name and the known ones; each shipped estimator declares what it guarantees (the
report and the write-back read that); ``ols``/``wls`` are exactly the least squares of the
reduced rows; the prior weight chosen is the *smallest* one whose held-out residual is within
the tolerance of the best, with WLS row weights fitted once. (Raised the mutation score of the
package; see benchmarks/mutation.py.)
"""

import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest

from ident.errors import ConfigError, DataError
from ident.identify.estimation.estimate import least_squares_reduced
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimators import (
    ESTIMATORS,
    EstimationProblem,
    choose_regularization,
    get_estimator,
    register_estimator,
)
from ident.identify.estimators.registry import CONTRACTS, UNCONSTRAINED, Contract, get_contract
from ident.identify.estimators.regularization import relative_residual


def _reduced(seed=0, n=120, p=3, noise=(0.1, 1.0)):
    rng = np.random.default_rng(seed)
    W = rng.normal(size=(n, 2, p))
    x = np.arange(1.0, p + 1)
    tau = W @ x + rng.normal(size=(n, 2)) * noise
    groups = np.tile([0, 1], n)
    return ReducedObservations.from_rows(W.reshape(-1, p), tau.reshape(-1), groups, 2), W, tau


def test_unknown_name_is_one_line_with_the_closest_and_the_known_ones():
    known = ", ".join(sorted(ESTIMATORS))
    with pytest.raises(ConfigError) as err:
        get_estimator("lmj")
    assert str(err.value) == f"unknown estimator 'lmj'; did you mean 'lmi'? (known: {known})."
    with pytest.raises(ConfigError) as err:
        get_contract("zzzzzz")
    assert str(err.value) == f"unknown estimator 'zzzzzz' (known: {known})."


def test_shipped_estimators_declare_their_guarantees():
    assert get_contract("ols") == get_contract("wls")
    assert get_contract("wls") == Contract(
        consistent=False, needs_prior=False, supports_chunks=True, least_squares=True
    )
    for name in ("lmi", "log_cholesky"):
        assert get_contract(name) == Contract(
            consistent=True, needs_prior=True, supports_chunks=True, least_squares=False
        )
    assert UNCONSTRAINED == Contract(
        consistent=False, needs_prior=False, supports_chunks=True, least_squares=False
    )


def test_registration_as_call_and_decorator_with_and_without_contract():
    def toy(problem):
        return least_squares_reduced(problem.observations, problem.names)

    promise = Contract(consistent=True, needs_prior=False)
    try:
        assert register_estimator("toy_call", toy) is toy
        assert get_estimator("toy_call") is toy
        assert get_contract("toy_call") is UNCONSTRAINED  # promises nothing by default
        ESTIMATORS["toy_raw"] = toy  # put in the table directly: promises nothing either
        assert get_contract("toy_raw") is UNCONSTRAINED
        decorated = register_estimator("toy_deco", contract=promise)(toy)
        assert decorated is toy
        assert get_contract("toy_deco") is promise
        with pytest.raises(ValueError, match=r"^estimator 'toy_deco' is registered twice$"):
            register_estimator("toy_deco", toy)
        assert get_contract("toy_deco") is promise  # the first registration stands
    finally:
        for name in ("toy_call", "toy_deco", "toy_raw"):
            ESTIMATORS.pop(name, None)
            CONTRACTS.pop(name, None)


@pytest.mark.parametrize("method", ["ols", "wls"])
def test_registry_least_squares_is_the_reduced_least_squares(method):
    red, _, _ = _reduced()
    problem = EstimationProblem(red, ("a", "b", "c"), wls_passes=3)
    est = get_estimator(method)(problem)
    ref = least_squares_reduced(red, ("a", "b", "c"), method=method, wls_passes=3)
    np.testing.assert_allclose(est.x, ref.x, rtol=1e-12)
    np.testing.assert_allclose(est.covariance, ref.covariance, rtol=1e-12)
    assert (est.method, est.n_samples) == (method, ref.n_samples)
    assert est.theta.size == 0  # no structure: no standard parameters, no consistency
    assert est.consistent is None
    if method == "wls":  # three passes differ from two (the noise levels are unequal)
        two = least_squares_reduced(red, ("a", "b", "c"), method="wls")
        assert not np.allclose(two.x, est.x, rtol=1e-12, atol=0)


def test_problem_checks():
    red, _, _ = _reduced()
    with pytest.raises(DataError) as err:
        EstimationProblem(red, ("a", "b"))
    assert str(err.value) == "2 names for 3 observation columns."
    with pytest.raises(DataError) as err:
        EstimationProblem(red, ("a", "b", "c"), regularization=-1.0)
    assert str(err.value) == "regularization = -1.0 must be >= 0."
    with pytest.raises(DataError, match="must be >= 0"):
        EstimationProblem(red, ("a", "b", "c"), regularization=float("nan"))
    problem = EstimationProblem(red, ("a", "b", "c"))
    assert problem.n_rows == 240
    np.testing.assert_array_equal(problem.K, np.eye(3))
    with pytest.raises(DataError) as err:
        problem.require_structure("lmi")
    assert str(err.value) == (
        "estimator 'lmi' works on the standard parameters: give the problem a "
        "ParameterStructure (bodies, extras, nominal values) and its base_map."
    )


def test_relative_residual_of_reduced_rows():
    red, W, tau = _reduced()
    x = np.array([0.5, 2.0, 3.5])
    r = tau - W @ x
    assert relative_residual(red, x) == pytest.approx(np.linalg.norm(r) / np.linalg.norm(tau))
    small = ReducedObservations.from_rows(
        1e-2 * W.reshape(-1, 3), 1e-2 * tau.reshape(-1), np.tile([0, 1], 120), 2
    )  # ||tau||^2 below 1
    assert relative_residual(small, x) == pytest.approx(np.linalg.norm(r) / np.linalg.norm(tau))
    empty = ReducedObservations.from_rows(np.zeros((4, 3)), np.zeros(4), np.zeros(4, int), 1)
    assert relative_residual(empty, x) == np.inf


# -------------------------------------------------------------- choice of the prior weight


def _shrinking(seen):
    """A toy prior-weighted estimator: the WLS estimate shrunk toward 0 by 1 / (1 + lambda);
    records the weights and regularization it was called with."""

    def estimate(problem):
        seen.append((problem.regularization, problem.weights))
        est = least_squares_reduced(
            problem.observations, problem.names, method="wls", wls_passes=problem.wls_passes
        )
        return dataclasses.replace(est, x=est.x / (1.0 + problem.regularization))

    return estimate


def test_prior_weight_is_the_smallest_within_tolerance_of_the_best():
    red, _, _ = _reduced(seed=1)
    val, _, _ = _reduced(seed=2)
    seen = []
    register_estimator("shrink", _shrinking(seen))
    try:
        problem = EstimationProblem(red, ("a", "b", "c"), wls_passes=3)
        grid = [1.0, 0.0, 1e-3, 0.02]  # unsorted on purpose
        choice = choose_regularization(problem, val, method="shrink", grid=grid, tolerance=0.0)
        np.testing.assert_array_equal(choice.grid, [0.0, 1e-3, 0.02, 1.0])
        # shrinking only hurts a well-determined fit: the validation residual grows with the
        # weight, so the best is 0 and nothing else is within a zero tolerance
        assert np.all(np.diff(choice.validation_residual) > 0)
        assert choice.weight == 0.0
        wls = least_squares_reduced(red, ("a", "b", "c"), method="wls", wls_passes=3)
        for k, w in enumerate(choice.grid):
            x = wls.x / (1.0 + w)
            assert choice.validation_residual[k] == pytest.approx(relative_residual(val, x))
        np.testing.assert_allclose(choice.estimate.x, wls.x)
        # what every estimate reported on the identification rows, kept with the choice
        np.testing.assert_allclose(choice.identification_residual, [wls.relative_residual] * 4)
        np.testing.assert_array_equal(choice.consistent, [False] * 4)
        # a looser tolerance admits more weights; the smallest admitted (0) is still chosen
        loose = choose_regularization(problem, val, method="shrink", grid=grid, tolerance=0.5)
        assert loose.weight == 0.0
        # the WLS row weights are fitted once and passed to every grid point: 1 / sigma_j
        weights = [w for _, w in seen]
        assert all(w is not None for w in weights)
        np.testing.assert_allclose(weights[0], 1.0 / wls.sigma)
        assert [r for r, _ in seen[:4]] == [0.0, 1e-3, 0.02, 1.0]
    finally:
        ESTIMATORS.pop("shrink", None)
        CONTRACTS.pop("shrink", None)


def test_prior_weight_prefers_the_weakest_prior_that_predicts_as_well():
    # an estimator whose held-out residual falls then flattens with the weight: within a 1 %
    # tolerance the smallest weight of the flat part is chosen, not the very best
    red, _, _ = _reduced(seed=3)
    val, _, _ = _reduced(seed=4)
    wls = least_squares_reduced(red, ("a", "b", "c"), method="wls")
    offsets = {0.0: 0.5, 0.1: 0.02, 1.0: 0.0199, 10.0: 0.0}

    def toward_truth(problem):
        est = least_squares_reduced(problem.observations, problem.names, method="wls")
        x = wls.x + offsets[problem.regularization]
        flag = (SimpleNamespace(consistent=problem.regularization >= 1.0),)
        return dataclasses.replace(
            est, x=x, success=problem.regularization != 10.0, consistency=flag
        )

    register_estimator("toward", toward_truth)
    try:
        problem = EstimationProblem(red, ("a", "b", "c"), weights=np.array([1.0, 1.0]))
        grid = list(offsets)
        choice = choose_regularization(problem, val, method="toward", grid=grid, tolerance=0.01)
        # the failed estimate (weight 10) counts as an infinite residual
        assert choice.validation_residual[-1] == np.inf
        best = choice.validation_residual[:3].min()
        assert choice.validation_residual[1] <= best * 1.01
        assert choice.weight == 0.1
        np.testing.assert_array_equal(choice.consistent, [False, False, True, True])
        # the default tolerance (0.5 %) chooses the same
        assert choose_regularization(problem, val, method="toward", grid=grid).weight == 0.1
        strict = choose_regularization(problem, val, method="toward", grid=grid, tolerance=0.0)
        assert strict.weight == float(grid[int(np.argmin(strict.validation_residual))])
        with pytest.raises(ValueError, match=r"^grid must hold weights >= 0, got \[\]$"):
            choose_regularization(problem, val, method="toward", grid=[])
        with pytest.raises(ValueError, match=r"got \[0.0, -1.0\]"):
            choose_regularization(problem, val, method="toward", grid=[0.0, -1.0])
    finally:
        ESTIMATORS.pop("toward", None)
        CONTRACTS.pop("toward", None)
