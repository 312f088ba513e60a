"""WOA, GWO, GOA, DE and PSO specifics: schedules, operators, bounds."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from ident.optim import METHODS, goa, gwo, minimize, woa
from ident.optim.de import distinct_indices
from ident.optim.pso import _neighbour_best


def test_woa_gwo_a_schedule_and_budget(monkeypatch):
    a = woa.a_schedule(10)
    assert a[0] == 2.0
    assert a[-1] == pytest.approx(0.2)
    assert np.all(np.diff(a) < 0)
    seen = []
    real = woa.a_schedule
    monkeypatch.setattr(woa, "a_schedule", lambda m: seen.append(m) or real(m))
    minimize(lambda x: np.sum(x**2, 1), [(-1, 1)] * 2, "woa", rng=0, popsize=10, max_nfev=95)
    assert seen == [8]


class _Recording(np.ndarray):
    """An array that records which indices a method reads (one schedule value per iteration)."""

    def __getitem__(self, i):
        self.read.append(i)
        return np.asarray(self)[i]


def _spy_schedule(monkeypatch, module, name):
    calls = []
    real = getattr(module, name)

    def spy(m, *args):
        arr = np.asarray(real(m, *args)).view(_Recording)
        arr.read = []
        calls.append((m, arr))
        return arr

    monkeypatch.setattr(module, name, spy)
    return calls


@pytest.mark.parametrize("max_nfev", [95, 100, 137])
def test_gwo_a_and_goa_c_follow_the_real_iteration_budget(monkeypatch, max_nfev):
    popsize = 10
    planned = max_nfev // popsize - 1  # iterations after the initial population
    fun = lambda x: np.sum(x**2, 1)  # noqa: E731
    # GWO: a goes 2 -> 2/maxiter over exactly the iterations run (reference code's a(t))
    calls = _spy_schedule(monkeypatch, gwo, "a_schedule")
    res = minimize(fun, [(-1, 1)] * 2, "gwo", rng=0, popsize=popsize, max_nfev=max_nfev)
    assert res.nit == planned
    assert res.nfev <= max_nfev
    ((m, a),) = calls
    assert m == planned
    assert a.read == list(range(planned))  # one value per iteration, the last one used last
    assert a[0] == 2.0
    assert np.asarray(a)[-1] == pytest.approx(2.0 / planned)
    # GOA: c reaches c_min exactly at the last iteration that is run
    calls = _spy_schedule(monkeypatch, goa, "c_schedule")
    res = minimize(fun, [(-1, 1)] * 2, "goa", rng=0, popsize=popsize, max_nfev=max_nfev)
    assert res.nit == planned
    ((m, c),) = calls
    assert m == planned
    assert c.read == list(range(planned))
    assert np.asarray(c)[-1] == pytest.approx(4e-5)
    # an explicit maxiter smaller than the budget allows is the one that is spread over
    calls = _spy_schedule(monkeypatch, goa, "c_schedule")
    res = minimize(fun, [(-1, 1)] * 2, "goa", rng=0, popsize=popsize, max_nfev=max_nfev, maxiter=3)
    assert res.nit == 3
    assert calls[0][0] == 3
    assert calls[0][1].read == [0, 1, 2]


def test_goa_c_schedule_and_comfort_zone():
    c = goa.c_schedule(100)
    assert c[-1] == pytest.approx(4e-5)
    assert c[0] == pytest.approx(1 - (1 - 4e-5) / 100)
    assert goa.social_force(np.array([0.0]))[0] == pytest.approx(-0.5)
    # GOA paper: with f = 0.5, l = 1.5 the comfort distance (s = 0) is 2.079
    r0 = brentq(lambda r: goa.social_force(np.array([r]))[0], 1.0, 4.0)
    assert r0 == pytest.approx(2.079, abs=1e-3)


def test_de_indices_distinct_and_not_self():
    r = distinct_indices(7, np.random.default_rng(0))
    assert r.shape == (7, 3)
    for i, row in enumerate(r):
        assert len(set(row.tolist())) == 3
        assert i not in row


def test_pso_ring_topology_sees_neighbours():
    p = np.arange(5.0)[:, None]
    pf = np.array([3.0, 1.0, 4.0, 0.5, 2.0])
    best = _neighbour_best(p, pf, "ring")[:, 0]
    assert best.tolist() == [1.0, 1.0, 3.0, 3.0, 3.0]
    res = minimize(
        lambda x: np.sum(x**2, 1), [(-5, 5)] * 3, "pso", rng=0, maxiter=300, topology="ring"
    )
    assert res.fun < 1e-6


@pytest.mark.parametrize("method", list(METHODS))
def test_every_evaluated_point_inside_bounds(method):
    lo, hi = np.array([-1.0, 0.0, 10.0]), np.array([1.0, 5.0, 11.0])
    calls = []

    def linear(x):  # minimum on a corner: drives every method against the bounds
        calls.append(x.copy())
        return x @ np.array([1.0, -1.0, 1.0])

    res = minimize(linear, np.c_[lo, hi], method, rng=0, popsize=10, maxiter=40)
    allx = np.concatenate(calls)
    assert np.all(allx >= lo)
    assert np.all(allx <= hi)
    assert res.fun == pytest.approx(-1.0 - 5.0 + 10.0, abs=1.0)
