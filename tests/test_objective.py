from types import SimpleNamespace

import numpy as np
import pytest
from robots import ur5_with_limits

from ident.dynamics.pinocchio_check import pinocchio_regressor
from ident.excitation.fourier import JointFourierFamily
from ident.excitation.objective import (
    CRITERION_CAP,
    ExcitationObjective,
    criterion_from_gram,
    singular_values_from_gram,
)

ROBOT = ur5_with_limits()
STAGE = SimpleNamespace(torque_rows=(3, 4, 5), columns=np.arange(30, 60))  # a "wrist" stage
OMEGA = 2 * np.pi / 4  # 4 s period keeps the trajectories short


def _family(omega=OMEGA, n_samples=120, moving=(3, 4, 5)):
    return JointFourierFamily(
        ROBOT, moving, n_harmonics=4, base_frequency=omega, n_samples=n_samples
    )


@pytest.fixture(scope="module")
def objective():
    return ExcitationObjective(ROBOT, STAGE, _family())


def _swarm(family, n=6, seed=0, factor=0.5):
    rng = np.random.default_rng(seed)
    return factor * rng.uniform(family.bounds[:, 0], family.bounds[:, 1], (n, len(family.bounds)))


def _stacked_base_matrix(objective, q, dq, ddq):
    """Tall base observation matrix from a per-sample Pinocchio loop (the reference)."""
    y = pinocchio_regressor(ROBOT.model, q, dq, ddq)[:, list(objective.rows)]
    return y[:, :, list(objective.columns)].reshape(-1, len(objective.columns))


def test_base_columns(objective):
    assert set(objective.columns) <= set(range(30, 60))
    assert len(objective.columns) == objective.reference_rank
    assert 10 < len(objective.columns) < 30  # wrist with the arm held: some are not identifiable
    assert all(name[-1] in "456" for name in objective.column_names)
    assert np.all(np.isfinite(objective.column_scale))
    assert np.all(objective.column_scale > 0)


def test_vectorized_equals_per_particle(objective):
    x = _swarm(objective.family)
    swarm = objective(x)
    single = np.array([objective(xi)[0] for xi in x])
    np.testing.assert_allclose(swarm, single, rtol=1e-12)
    assert swarm.shape == (6,)


def test_gram_singular_values_match_svd_of_stacked_matrix(objective):
    x = _swarm(objective.family, n=3, seed=1)
    batch = objective.family.trajectories(x)
    details = objective.details(x)
    for i in range(3):
        w = _stacked_base_matrix(objective, batch.q[i], batch.dq[i], batch.ddq[i])
        w = w * objective.column_scale / np.sqrt(w.shape[0])
        s = np.linalg.svd(w, compute_uv=False)
        d = details[i]
        assert d.sigma_max == pytest.approx(s[0], rel=1e-10)
        assert d.sigma_min == pytest.approx(s[-1], rel=1e-8)
        assert d.cond == pytest.approx(s[0] / s[-1], rel=1e-8)
        assert d.criterion == pytest.approx(s[0] / s[-1] + 1 / s[-1] + s[0], rel=1e-8)
        assert d.logdet == pytest.approx(2 * np.sum(np.log(s)), rel=1e-8)


def test_logdet_criterion(objective):
    logdet = ExcitationObjective(ROBOT, STAGE, objective.family, criterion="logdet")
    x = _swarm(objective.family, n=3, seed=1)
    d = objective.details(x)
    dl = logdet.details(x)
    np.testing.assert_allclose([di.criterion for di in dl], [-di.logdet for di in d], rtol=1e-12)
    np.testing.assert_allclose(logdet(x), [di.fitness for di in dl], rtol=1e-15)


def test_scaled_form_does_not_prefer_a_slower_version():
    """Same path, slowed down by s (time scaling), same number of samples per period."""
    base = _family(moving=range(6), n_samples=500)  # 500 samples per period, as the paper configs
    rng = np.random.default_rng(2)
    for _ in range(200):  # a fast but feasible trajectory
        x = 0.5 * rng.uniform(base.bounds[:, 0], base.bounds[:, 1], (1, len(base.bounds)))
        if base.trajectories(x).violations.feasible()[0]:
            break
    else:
        pytest.fail("no feasible trajectory drawn")
    is_amplitude = np.array([not n.startswith("q0") for n in base.variable_names])
    scaled, raw = [], []
    for s in (1.0, 1.5, 2.0, 3.0):
        family = _family(omega=OMEGA / s, moving=range(6), n_samples=500)
        xs = x.copy()
        xs[:, is_amplitude] /= s  # a/(w l) unchanged: same positions, velocities / s
        if s == 2.0:  # really the same path
            np.testing.assert_allclose(
                family.trajectories(xs).q, base.trajectories(x).q, atol=1e-12
            )
        assert family.trajectories(xs).violations.feasible()[0]
        scaled.append(ExcitationObjective(ROBOT, None, family)(xs)[0])
        raw.append(ExcitationObjective(ROBOT, None, family, scaled=False)(xs)[0])
    # the scaled criterion gets worse with every slow-down ...
    assert np.all(np.diff(scaled) > 0.0), scaled
    # ... while eq. 15 on the raw SI matrix prefers a slower version here
    assert min(raw[1:]) < raw[0], raw


def test_scaled_form_independent_of_sample_count():
    x = _swarm(_family(), n=2, seed=3)
    f120, f240 = _family(n_samples=120), _family(n_samples=240)
    d120 = ExcitationObjective(ROBOT, STAGE, f120).details(x)
    d240 = ExcitationObjective(ROBOT, STAGE, f240).details(x)
    r120 = ExcitationObjective(ROBOT, STAGE, f120, scaled=False).details(x)
    r240 = ExcitationObjective(ROBOT, STAGE, f240, scaled=False).details(x)
    for a, b, ra, rb in zip(d120, d240, r120, r240, strict=True):
        assert b.sigma_max == pytest.approx(a.sigma_max, rel=1e-2)
        assert b.cond == pytest.approx(a.cond, rel=1e-2)
        assert rb.sigma_max / ra.sigma_max == pytest.approx(np.sqrt(2), rel=1e-2)


def test_penalties_finite_and_ordering(objective):
    family = objective.family
    x = _swarm(family, n=3, seed=4)
    x[1] = family.bounds[:, 1] * 5  # far outside: violates velocity limits
    x[2, 0] = np.nan
    f = objective(x)
    assert np.all(np.isfinite(f))
    d = objective.details(x)
    assert not d[1].feasible
    assert d[1].penalty >= objective.penalty_weight
    assert f[1] > f[0]
    assert f[2] > f[0]
    np.testing.assert_allclose(objective.violation(x), family.trajectories(x).violations.total())
    assert objective.violation(x)[1] > 0.0


def test_rank_deficient_trajectory_is_capped():
    family = _family()
    objective = ExcitationObjective(ROBOT, STAGE, family)
    x = np.zeros((1, len(family.bounds)))  # no motion at all
    d = objective.details(x)[0]
    assert d.criterion == CRITERION_CAP
    assert np.isfinite(d.fitness)
    value, cond, *_ = criterion_from_gram(np.full((1, 3, 3), np.nan))
    assert value[0] == CRITERION_CAP
    assert cond[0] == np.inf


def test_singular_values_from_gram_accurate_when_ill_conditioned():
    rng = np.random.default_rng(5)
    w = rng.standard_normal((3, 600, 8)) * np.logspace(0, 5, 8)  # badly scaled columns
    w[1, :, 7] = w[1, :, 6] * 2.0 + 1e-7 * w[1, :, 5]  # nearly dependent columns
    reference = np.linalg.svd(w, compute_uv=False)
    sigma = singular_values_from_gram(np.einsum("bri,brj->bij", w, w))
    assert reference[0, 0] / reference[0, -1] > 1e4
    np.testing.assert_allclose(sigma[[0, 2]], reference[[0, 2]], rtol=1e-9)
    np.testing.assert_allclose(sigma[1, :-1], reference[1, :-1], rtol=1e-9)
    # a singular Gram matrix (zero column) gives sigma_min = 0, not NaN
    w[2, :, 3] = 0.0
    sigma = singular_values_from_gram(np.einsum("bri,brj->bij", w, w))
    assert sigma[2, -1] == 0.0
    assert np.all(np.isfinite(sigma))
