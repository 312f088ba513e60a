"""The initial-elites stage (paper section 4.1) and seeding a swarm from elites."""

from __future__ import annotations

import numpy as np
import pytest

from ident.errors import OptimizationError
from ident.optim import minimize
from ident.optim.elites import find_feasible_elites, spawn_from_elites


def disc_violation(x):
    """0 inside the disc of radius 1 around (3, -2), distance to it outside."""
    d = np.hypot(x[:, 0] - 3.0, x[:, 1] + 2.0)
    return np.maximum(d - 1.0, 0.0)


def test_finds_compliant_elites():
    res = find_feasible_elites(disc_violation, [(-10, 10)] * 2, rng=0, maxiter=300)
    assert res.success, res.message
    assert res.elites.shape == (5, 2)
    assert res.violations.shape == (5,)
    np.testing.assert_array_equal(disc_violation(res.elites), 0.0)
    assert res.nfev == 10 * (res.nit + 1)
    again = find_feasible_elites(disc_violation, [(-10, 10)] * 2, rng=0, maxiter=300)
    np.testing.assert_array_equal(res.elites, again.elites)


def test_impossible_constraint_reports_failure():
    res = find_feasible_elites(lambda x: 1.0 + np.sum(x**2, 1), [(-1, 1)] * 3, rng=0, maxiter=20)
    assert not res.success
    assert res.elites.shape == (0, 3)
    assert "only 0 of 5" in res.message
    assert res.nfev == 10 * 21 * 4  # the first swarm and 3 restarts, 21 evaluations each
    once = find_feasible_elites(
        lambda x: 1.0 + np.sum(x**2, 1), [(-1, 1)] * 3, rng=0, maxiter=20, restarts=0
    )
    assert once.nfev == 10 * 21


def _trap(x):
    """Violation with a wide basin above zero at x = -0.5 and a narrow feasible window at 0.9:
    a swarm settles in the basin; only fresh random points find the window."""
    x = x[:, 0]
    return np.where(np.abs(x - 0.9) < 0.02, 0.0, 0.1 + (x + 0.5) ** 2)


def test_a_stalled_swarm_restarts_and_a_quick_search_is_unchanged():
    kwargs = {"n_particles": 10, "n_elites": 1, "maxiter": 30, "rng": 3}
    stuck = find_feasible_elites(_trap, [(-1, 1)], restarts=0, **kwargs)
    assert not stuck.success  # settled in the basin
    found = find_feasible_elites(_trap, [(-1, 1)], restarts=20, **kwargs)
    assert found.success
    assert abs(found.elites[0, 0] - 0.9) < 0.02
    assert "restart" in found.message
    # a search that succeeds within maxiter draws nothing more: identical with or without
    a = find_feasible_elites(disc_violation, [(-10, 10)] * 2, rng=0, maxiter=50, restarts=0)
    b = find_feasible_elites(disc_violation, [(-10, 10)] * 2, rng=0, maxiter=50)
    assert a.success
    np.testing.assert_array_equal(a.elites, b.elites)
    assert a.nfev == b.nfev


def test_spawn_from_elites_seeds_emupso():
    elites = np.array([[3.0, -2.0], [3.5, -2.5]])
    x0 = spawn_from_elites(elites, 20, [(-10, 10)] * 2, 0.05, rng=1)
    assert x0.shape == (20, 2)
    np.testing.assert_array_equal(x0[:2], elites)
    assert np.all(np.abs(x0[2::2] - elites[0]).max(0) < 6 * 0.05 * 20)
    assert np.all(x0 >= -10)
    assert np.all(x0 <= 10)
    res = minimize(disc_violation, [(-10, 10)] * 2, rng=0, popsize=20, maxiter=0, x0=x0)
    assert res.fun == 0.0
    with pytest.raises(OptimizationError, match="elites"):
        spawn_from_elites(np.zeros((1, 3)), 4, [(-1, 1)] * 2)


def test_spawn_clips_to_bounds():
    x = spawn_from_elites(np.array([[1.0, 0.0]]), 500, [(0, 1)] * 2, 0.5, rng=0)
    assert np.all(x >= 0)
    assert np.all(x <= 1)
