"""CMA-ES (``method="cma"``) and the optimizer registry."""

from __future__ import annotations

import numpy as np
import pytest

from ident.errors import OptimizationError
from ident.optim import METHODS, method_defaults, minimize, register_method


def sphere(x):
    return np.sum((x - 0.3) ** 2, axis=1)


def rosenbrock(x):
    return np.sum(100.0 * (x[:, 1:] - x[:, :-1] ** 2) ** 2 + (1.0 - x[:, :-1]) ** 2, axis=1)


def test_cma_finds_the_known_optima():
    res = minimize(sphere, [(-5, 5)] * 6, "cma", rng=0, popsize=12, max_nfev=3000)
    assert res.fun < 1e-12
    np.testing.assert_allclose(res.x, 0.3, atol=1e-6)
    res = minimize(rosenbrock, [(-2, 2)] * 4, "cma", rng=1, popsize=10, max_nfev=6000)
    np.testing.assert_allclose(res.x, 1.0, atol=1e-4)  # known optimum (1, ..., 1)


def test_cma_uses_only_the_given_generator():
    legacy = np.random  # cma seeds numpy's global state unless told not to: check it does not
    legacy.seed(123)  # noqa: NPY002
    state = legacy.get_state()[1].copy()  # noqa: NPY002
    a = minimize(sphere, [(-1, 1)] * 3, "cma", rng=5, popsize=8, max_nfev=400)
    assert np.array_equal(legacy.get_state()[1], state)  # noqa: NPY002
    legacy.seed(999)  # noqa: NPY002 - a different global state must not change the result
    b = minimize(sphere, [(-1, 1)] * 3, "cma", rng=5, popsize=8, max_nfev=400)
    np.testing.assert_array_equal(a.x, b.x)
    assert a.nfev == b.nfev == 400


def test_cma_restarts_after_convergence_and_keeps_the_budget():
    res = minimize(sphere, [(-1, 1)] * 2, "cma", rng=0, popsize=6, max_nfev=6 * 400)
    assert res.nfev == 6 * 400
    assert res.history.mutation_iterations.size >= 1  # restart iterations
    stopped = minimize(
        sphere, [(-1, 1)] * 2, "cma", rng=0, popsize=6, max_nfev=6 * 400, restarts=False
    )
    assert stopped.nfev < 6 * 400
    assert "cma converged" in stopped.message


def test_cma_starts_from_x0_and_checks_sigma0():
    x0 = np.full((1, 3), 0.3)
    res = minimize(sphere, [(-1, 1)] * 3, "cma", rng=0, popsize=6, maxiter=0, x0=x0)
    assert res.fun == 0.0
    assert method_defaults("cma")["sigma0"] == 0.3
    with pytest.raises(OptimizationError, match="sigma0"):
        minimize(sphere, [(-1, 1)] * 3, "cma", rng=0, popsize=6, maxiter=2, sigma0=2.0)


def _random_search(problem, x0, *, shrink):
    """Toy optimizer (docs/optimizers.md, "Extending"): uniform samples in a box that
    shrinks around the best point by ``shrink`` per iteration."""
    x = problem.initial_population(x0)
    problem.evaluate(x)
    stop = problem.end_iteration(0)
    half = 0.5 * problem.span
    t = 0
    while not stop and t < problem.maxiter:
        t += 1
        half = half * shrink
        low = np.maximum(problem.best_x - half, problem.lower)
        high = np.minimum(problem.best_x + half, problem.upper)
        problem.evaluate(low + problem.rng.random((problem.popsize, problem.dim)) * (high - low))
        stop = problem.end_iteration(t)
    return {}


@pytest.fixture
def toy_method():
    register_method("shrinking_random", _random_search, defaults={"shrink": 0.9},
                    default_popsize=10)  # fmt: skip
    yield "shrinking_random"
    del METHODS["shrinking_random"]


def test_registered_toy_method_runs_with_the_common_contract(toy_method):
    res = minimize(sphere, [(-1, 1)] * 2, toy_method, rng=0, max_nfev=500)
    assert res.nfev == 500
    assert res.fun < 1e-4
    assert res.method == toy_method
    again = minimize(sphere, [(-1, 1)] * 2, toy_method, rng=0, max_nfev=500, shrink=0.9)
    np.testing.assert_array_equal(res.x, again.x)
    with pytest.raises(OptimizationError, match="did you mean 'shrink'"):
        minimize(sphere, [(-1, 1)] * 2, toy_method, rng=0, max_nfev=500, shrnk=0.5)
    with pytest.raises(OptimizationError, match="registered twice"):
        register_method(toy_method, _random_search)
