"""eMuPSO components in isolation, and their effect inside a run."""

from __future__ import annotations

import numpy as np
import pytest

from ident.errors import OptimizationError
from ident.optim import emupso, minimize
from ident.optim.emupso import (
    apply_bounds,
    best_distinct,
    clamp_velocity,
    coefficient_schedules,
    mutate_population,
    partition_sizes,
    stagnation_update,
    swarm_radius,
)


def test_schedule_end_points_and_geometric_form():
    w, c2 = coefficient_schedules(50)
    assert w.shape == c2.shape == (50,)
    assert w[0] == pytest.approx(2.1)
    assert w[-1] == pytest.approx(0.6)
    assert c2[0] == pytest.approx(1.8)
    assert c2[-1] == pytest.approx(3.9)
    # eq. 3: w_t = w0 * n^t  -> constant ratio n < 1; eq. 4: c2_t = c2_0 / m^t -> m < 1
    n = w[1:] / w[:-1]
    m = c2[:-1] / c2[1:]
    np.testing.assert_allclose(n, n[0])
    np.testing.assert_allclose(m, m[0])
    assert n[0] == pytest.approx((0.6 / 2.1) ** (1 / 49))
    assert m[0] < 1
    assert np.all(np.diff(w) < 0)
    assert np.all(np.diff(c2) > 0)
    assert coefficient_schedules(1)[0].tolist() == [2.1]


def test_schedules_follow_the_budget_really_run(monkeypatch):
    seen = []
    real = emupso.coefficient_schedules

    def spy(maxiter, *a):
        seen.append(maxiter)
        return real(maxiter, *a)

    monkeypatch.setattr(emupso, "coefficient_schedules", spy)
    minimize(lambda x: np.sum(x**2, 1), [(-1, 1)] * 2, rng=0, popsize=30, max_nfev=305)
    minimize(lambda x: np.sum(x**2, 1), [(-1, 1)] * 2, rng=0, popsize=30, max_nfev=305, maxiter=4)
    assert seen == [9, 4]  # 305 // 30 - 1 = 9 iterations after the initial swarm


def test_radius_eq5():
    pf = np.array([1.0, 2.0, 3.0, np.inf])
    assert swarm_radius(1.0, pf) == pytest.approx(1.0 - 2.0)
    assert np.isnan(swarm_radius(np.inf, np.full(3, np.inf)))


def test_stagnation_counter_relative_tolerance():
    assert stagnation_update(4, -2.0, -2.0, 1e-6) == 5
    assert stagnation_update(4, -2.0, -2.0 * (1 + 1e-7), 1e-6) == 5
    assert stagnation_update(4, -2.0, -2.0 * (1 + 1e-5), 1e-6) == 0
    assert stagnation_update(4, 0.0, 0.0, 1e-6) == 5
    assert stagnation_update(4, np.nan, -1.0, 1e-6) == 0


@pytest.mark.parametrize("big_g", [1, 3, 10])
def test_mutation_after_exactly_g_stagnant_iterations(big_g):
    # constant objective: radius is 0 at every iteration, so every iteration is stagnant
    res = minimize(
        lambda x: np.zeros(len(x)),
        [(-1, 1)] * 2,
        rng=0,
        popsize=6,
        maxiter=3 * (big_g + 1),
        stall_threshold=big_g,
    )
    period = big_g + 1
    assert res.history.mutation_iterations.tolist() == [period, 2 * period, 3 * period]
    expected = [0] + [t % period if t % period else 0 for t in range(1, 3 * period + 1)]
    assert res.history.stagnation.tolist() == expected
    assert res.history.radius.shape == (3 * period + 1,)


def test_no_mutation_while_radius_changes():
    # sphere from far away: personal bests keep improving for a while
    res = minimize(
        lambda x: np.sum(x**2, 1),
        [(-100, 100)] * 5,
        rng=0,
        popsize=20,
        maxiter=8,
        stall_threshold=10,
    )
    assert res.history.mutation_iterations.size == 0


def test_partition_sizes_k_plus_one():
    assert partition_sizes(20, 3) == [5, 5, 5, 5]
    assert partition_sizes(20, 4) == [4, 4, 4, 4, 4]
    assert partition_sizes(22, 3) == [6, 6, 5, 5]
    assert sum(partition_sizes(7, 10)) == 7


def test_mutation_partitions_and_sigma_scaling():
    rng = np.random.default_rng(0)
    lo, hi = np.array([0.0, -50.0]), np.array([100.0, 50.0])
    elites = np.array([[20.0, -20.0], [50.0, 0.0], [80.0, 20.0]])
    n = 40_000
    pop = mutate_population(elites, n, lo, hi, 0.01, rng)
    sizes = partition_sizes(n, 3)
    start = np.cumsum([0, *sizes])
    for i in range(3):
        part = pop[start[i] : start[i + 1]]
        np.testing.assert_allclose(part.mean(0), elites[i], atol=0.05)
        np.testing.assert_allclose(part.std(0), 0.01 * (hi - lo), rtol=0.03)
    uniform = pop[start[3] :]
    np.testing.assert_allclose(uniform.std(0), (hi - lo) / np.sqrt(12), rtol=0.03)
    # no elites: the whole swarm is uniform (random-restart MuPSO)
    assert mutate_population(np.zeros((0, 2)), 10, lo, hi, 0.1, rng).shape == (10, 2)


def test_mutated_offspring_respect_bounds():
    lo, hi = np.zeros(3), np.ones(3)
    pop = mutate_population(
        np.array([[0.0, 1.0, 0.5]]), 1000, lo, hi, 0.5, np.random.default_rng(1)
    )
    assert np.all(pop >= lo)
    assert np.all(pop <= hi)


def test_archive_keeps_best_distinct_elites():
    span = np.array([10.0, 10.0])
    x = np.array([[1.0, 1.0], [1.0, 1.0 + 1e-5], [5.0, 5.0], [2.0, 2.0], [9.0, 9.0]])
    f = np.array([0.5, 0.4, 3.0, 1.0, np.inf])
    ax, af = best_distinct(x, f, span, size=10, distinct_tol=1e-3)
    assert af.tolist() == [0.4, 1.0, 3.0]  # duplicate 0.5 dropped, inf dropped
    np.testing.assert_array_equal(ax[0], x[1])
    ax, af = best_distinct(x, f, span, size=2, distinct_tol=1e-3)
    assert af.tolist() == [0.4, 1.0]


def test_result_archive_best_first_and_contains_best():
    res = minimize(
        lambda x: np.sum(x**2, 1) + np.sum(np.cos(3 * x), 1),
        [(-5, 5)] * 2,
        rng=2,
        popsize=20,
        maxiter=150,
        stall_threshold=5,
        vmax_decay=1.0,
    )
    arch = res.archive
    assert res.history.mutation_iterations.size >= 1
    assert 1 <= len(arch) <= 10
    assert np.all(np.diff(arch.fun) >= 0)
    assert arch.fun[0] == res.fun
    np.testing.assert_array_equal(arch.x[0], res.x)
    d = np.max(np.abs(arch.x[:, None] - arch.x[None]) / 10.0, axis=2)
    assert np.all(d[~np.eye(len(arch), dtype=bool)] > 1e-3)


def test_velocity_clamp_and_mirror_units():
    v = np.array([[5.0, -5.0, 0.1]])
    clamp_velocity(v, np.array([1.0, 2.0, 3.0]))
    assert v.tolist() == [[1.0, -2.0, 0.1]]
    x = np.array([[1.5, -0.5, 0.3]])
    v = np.array([[1.0, -1.0, 0.2]])
    apply_bounds(x, v, np.zeros(3), np.ones(3))
    assert x.tolist() == [[1.0, 0.0, 0.3]]
    assert v.tolist() == [[-1.0, 1.0, 0.2]]


def test_run_respects_bounds_and_velocity_clamp():
    lo, hi = np.array([-1.0, 0.0, 10.0]), np.array([1.0, 5.0, 11.0])
    calls = []

    def linear(x):  # minimum on a corner: pushes particles out of the box
        calls.append(x.copy())
        return x @ np.array([1.0, -1.0, 1.0])

    vmax_fraction = 0.1
    res = minimize(
        linear,
        np.c_[lo, hi],
        rng=0,
        popsize=10,
        maxiter=60,
        vmax_fraction=vmax_fraction,
        vmax_decay=0.97,
        stall_threshold=4,
    )
    allx = np.concatenate(calls)
    assert np.all(allx >= lo)
    assert np.all(allx <= hi)
    mutated = set(res.history.mutation_iterations.tolist())
    for t in range(1, len(calls)):
        if t in mutated:
            continue
        step = np.abs(calls[t] - calls[t - 1])
        assert np.all(step <= vmax_fraction * (hi - lo) * 0.97 ** (t - 1) + 1e-12)
    np.testing.assert_allclose(res.x, [-1.0, 5.0, 10.0])


def test_random_mutation_variant_and_bad_options():
    res = minimize(
        lambda x: np.zeros(len(x)),
        [(-1, 1)],
        rng=0,
        popsize=5,
        maxiter=12,
        stall_threshold=3,
        mutation="random",
    )
    assert res.history.mutation_iterations.tolist() == [4, 8, 12]
    with pytest.raises(OptimizationError, match="mutation"):
        minimize(lambda x: np.zeros(len(x)), [(-1, 1)], mutation="cauchy")
    with pytest.raises(OptimizationError, match="n_elites"):
        minimize(lambda x: np.zeros(len(x)), [(-1, 1)], n_elites=0)
