"""The estimator registry, OLS/WLS on reduced rows, and the constrained estimators."""

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
import robots

from ident.dynamics.chain import chain_from_model, random_states
from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model
from ident.errors import ConfigError, DataError
from ident.identify.estimation.estimate import least_squares, least_squares_reduced
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimators import (
    ESTIMATORS,
    EstimationProblem,
    choose_regularization,
    get_estimator,
    get_repeated_estimator,
    register_estimator,
    result_from_theta,
)
from ident.identify.estimators.identification import problem_from_states, standard_regressor
from ident.identify.estimators.log_cholesky import (
    log_cholesky_from_parameters,
    parameters_from_log_cholesky,
)


# ---- registry -------------------------------------------------------------------------------
def test_unknown_estimator_lists_the_known_ones():
    with pytest.raises(ConfigError, match=r"did you mean 'wls'.*known: .*lmi.*log_cholesky"):
        get_estimator("wsl")


def test_toy_estimator_from_the_docs_registers_and_runs():
    # docs/consistent-identification.md, "Extending"
    def nominal_only(problem: EstimationProblem):
        """Keep the URDF's parameters: a baseline every estimator should beat."""
        theta = problem.structure.nominal
        return result_from_theta(
            problem,
            theta,
            method="nominal",
            sigma=np.ones(problem.observations.n_groups),
            success=True,
            message="nominal parameters",
        )

    register_estimator("nominal", nominal_only)
    try:
        with pytest.raises(ValueError, match="registered twice"):
            register_estimator("nominal", nominal_only)
        problem = _ur5_problem(noise=0.0)[0]
        est = get_estimator("nominal")(problem)
        assert est.consistent
        np.testing.assert_allclose(est.x, problem.K @ problem.structure.nominal)
        # the simulated friction is not in the nominal parameters: a residual remains
        assert 0.01 < est.relative_residual < 1.0
    finally:
        del ESTIMATORS["nominal"]


# ---- OLS / WLS equal the row-based least squares ----------------------------------------------
FIELDS = ("x", "std", "relative_std", "sigma", "residual_rms", "covariance")


def _same(a, b, rtol=1e-10, atol_scale=0.0):
    """Same estimate; ``atol_scale`` times the largest entry for round-off-sized entries."""
    for name in FIELDS:
        desired = getattr(b, name)
        atol = atol_scale * np.abs(desired).max()
        np.testing.assert_allclose(getattr(a, name), desired, rtol=rtol, atol=atol, err_msg=name)
    for name in ("relative_residual", "condition_number"):
        assert getattr(a, name) == pytest.approx(getattr(b, name), rel=rtol), name
    assert a.n_observations == b.n_observations
    assert a.n_samples == b.n_samples
    assert a.message == b.message


@pytest.mark.parametrize("method", ["ols", "wls"])
@pytest.mark.parametrize("passes", [1, 2, 4])
def test_reduced_least_squares_equals_row_least_squares(method, passes):
    rng = np.random.default_rng(3)
    n_groups, n = 4, 7
    groups = rng.integers(0, n_groups, size=900)
    W = rng.normal(size=(900, n)) * np.logspace(-2, 2, n)  # columns of different units
    x_true = rng.normal(size=n)
    noise = rng.normal(size=900) * np.array([0.01, 0.1, 1.0, 0.3])[groups]
    y = W @ x_true + noise
    names = [f"p{k}" for k in range(n)]
    rows = least_squares(W, y, names, method=method, groups=groups, wls_passes=passes)
    obs = ReducedObservations.from_rows(W, y, groups, n_groups)
    _same(least_squares_reduced(obs, names, method=method, wls_passes=passes), rows)
    problem = EstimationProblem(observations=obs, names=tuple(names), wls_passes=passes)
    _same(get_estimator(method)(problem), rows)


def test_reduced_least_squares_noise_free_group_message():
    rng = np.random.default_rng(1)
    W = rng.normal(size=(300, 3))
    y = W @ np.array([1.0, 2.0, 3.0])
    groups = np.tile([0, 1, 2], 100)
    y[groups == 1] += rng.normal(size=100) * 0.1
    rows = least_squares(W, y, ["a", "b", "c"], method="wls", groups=groups)
    obs = ReducedObservations.from_rows(W, y, groups, 3)
    # the noise-free groups' residuals are round-off (1e-12 N*m): compared absolutely
    _same(least_squares_reduced(obs, ["a", "b", "c"], method="wls"), rows, 1e-8, 1e-9)


# ---- constrained estimators on a simulated UR5 -------------------------------------------------
def _ur5_problem(noise, n_samples=300, seed=0, inconsistent=False, **fields):
    model = pin.buildModelFromUrdf(str(robots.UR5_URDF))
    terms = ExtraTerms.from_options(
        model.nv, rotor_inertia=False, viscous=True, coulomb=True, offset=False
    )
    pm = build_parameter_model(model, terms)
    q, dq, ddq = random_states(chain_from_model(model), n_samples, rng=seed)
    theta = pm.nominal.copy()
    friction = np.array([n.startswith(("fv", "fs")) for n in pm.names])
    theta[friction] = 0.5
    Y = standard_regressor(model, pm, q, dq, ddq)
    tau = Y @ theta + noise * np.random.default_rng(seed + 1).normal(size=(n_samples, model.nv))
    if not inconsistent:
        pm_nominal = pm
    else:  # a prior far from the truth, which the data must correct
        pm_nominal = dataclasses.replace(pm, nominal=pm.nominal * 1.3)
    problem = problem_from_states(model, pm_nominal, q, dq, ddq, tau, **fields)
    return problem, theta, model, pm


def test_lmi_and_log_cholesky_agree_and_are_consistent():
    problem, theta_true, *_ = _ur5_problem(noise=2.0, inconsistent=True, regularization=0.1)
    lmi = get_estimator("lmi")(problem)
    lc = get_estimator("log_cholesky")(problem)
    wls = get_estimator("wls")(problem)
    assert lmi.success, lmi.message
    assert lc.success, lc.message
    assert lmi.consistent
    assert lc.consistent
    # same strictly convex problem: same optimum (the LMI keeps a 1e-6 margin)
    np.testing.assert_allclose(lc.x, lmi.x, rtol=1e-3, atol=1e-3 * np.abs(lmi.x).max())
    assert lc.relative_residual == pytest.approx(lmi.relative_residual, rel=1e-4)
    # a constrained fit cannot beat the unconstrained one on its own data
    assert lmi.relative_residual >= wls.relative_residual * (1 - 1e-9)
    # friction >= 0
    index = problem.structure.nonnegative
    assert np.all(lmi.theta[index] >= -1e-9)
    assert np.all(lc.theta[index] >= 0)
    # base values x = K theta
    np.testing.assert_allclose(lmi.x, problem.K @ lmi.theta)


def test_lmi_optimum_beats_feasible_points():
    problem, theta_true, *_ = _ur5_problem(noise=1.0, inconsistent=True, regularization=1e-3)
    lmi = get_estimator("lmi")(problem)
    structure = problem.structure
    weights = problem.weights

    def cost(theta):
        est = result_from_theta(
            problem, theta, method="x", sigma=np.ones(6), success=True, message=""
        )
        w = 1.0 / lmi.sigma if weights is None else weights
        data = float(np.sum(w**2 * est.group_residual_ss)) / problem.n_rows
        return data + problem.regularization * est.distance_to_nominal**2

    assert cost(lmi.theta) <= cost(theta_true) + 1e-9
    assert cost(lmi.theta) <= cost(structure.nominal) + 1e-9


def test_lmi_recovers_noise_free_truth_in_base_parameters():
    problem, theta_true, *_ = _ur5_problem(noise=0.0)
    lmi = get_estimator("lmi")(dataclasses.replace(problem, weights=np.ones(6)))
    beta_true = problem.K @ theta_true
    np.testing.assert_allclose(lmi.x, beta_true, rtol=1e-5, atol=1e-6 * np.abs(beta_true).max())


def test_lmi_requires_the_structure():
    problem, *_ = _ur5_problem(noise=0.1)
    with pytest.raises(DataError, match="ParameterStructure"):
        get_estimator("lmi")(dataclasses.replace(problem, structure=None))


def test_ols_reports_consistency_of_its_completion():
    problem, *_ = _ur5_problem(noise=0.1)
    est = get_estimator("ols")(problem)
    assert len(est.consistency) == 6
    np.testing.assert_allclose(problem.K @ est.theta, est.x, rtol=1e-8, atol=1e-10)
    # each link named as the structure names it; the distance of that completion to the URDF
    assert [c.body for c in est.consistency] == list(problem.structure.body_names)
    assert est.distance_to_nominal == problem.structure.distance_to_nominal(est.theta)


def test_regularization_choice_on_held_out_rows():
    ident, *_ = _ur5_problem(noise=3.0, seed=0, inconsistent=True)
    held_out, *_ = _ur5_problem(noise=3.0, seed=10, inconsistent=True)
    choice = choose_regularization(ident, held_out.observations, grid=(0.0, 1e-3, 1e-1, 10.0))
    assert choice.weight in choice.grid
    k = list(choice.grid).index(choice.weight)
    assert choice.validation_residual[k] <= choice.validation_residual.min() * 1.005
    assert choice.consistent.all()
    assert choice.estimate.regularization == choice.weight


def test_log_cholesky_roundtrip_with_pinocchio():
    rng = np.random.default_rng(0)
    for _ in range(5):
        # a consistent body: a box at a random pose
        box = pin.Inertia.FromBox(rng.uniform(0.5, 5.0), *rng.uniform(0.05, 0.5, size=3))
        inertia = pin.SE3.Random().act(box)
        theta = np.asarray(inertia.toDynamicParameters())
        psi = log_cholesky_from_parameters(theta)
        np.testing.assert_allclose(parameters_from_log_cholesky(psi), theta, rtol=1e-10, atol=1e-12)
        psi = rng.normal(size=10)
        np.testing.assert_allclose(
            log_cholesky_from_parameters(parameters_from_log_cholesky(psi)), psi, atol=1e-9
        )


def test_lmi_with_bounding_ellipsoids_keeps_the_mass_inside():
    from ident.identify.estimation.consistency import pseudo_inertia
    from ident.identify.model_files.urdf_update import parse_urdf
    from ident.robot.ellipsoids import link_ellipsoids

    problem, *_ = _ur5_problem(noise=5.0, inconsistent=True, regularization=1e-3)
    structure = problem.structure
    ellipsoids = link_ellipsoids(
        parse_urdf(robots.UR5_URDF.read_text()),
        structure.body_names,
        package_dirs=[robots.ERD_SHARE],
    )
    assert all(e is not None for e in ellipsoids)
    bounded = dataclasses.replace(
        problem, structure=dataclasses.replace(structure, ellipsoids=ellipsoids)
    )
    est = get_estimator("lmi")(bounded)
    assert est.success, est.message
    assert est.consistent
    for index, e in zip(structure.bodies, ellipsoids, strict=True):
        J = pseudo_inertia(est.theta[index])
        assert np.trace(J @ e.homogeneous_matrix()) >= -1e-9 * np.abs(J).max()
    free = get_estimator("lmi")(problem)
    assert est.relative_residual >= free.relative_residual * (1 - 1e-6)  # tighter set


def test_prior_on_unseen_directions_leaves_the_seen_ones_to_the_data():
    # consistent data (the constraints inactive): with the prior only on the directions no
    # data see (default), a heavy weight leaves the base values at WLS's; on every direction
    # ("all") it drags them toward the prior by 1e3 times more
    problem, *_ = _ur5_problem(noise=0.05, regularization=1e3)
    wls = get_estimator("wls")(problem)
    scale = np.abs(wls.x).max()
    unseen = get_estimator("lmi")(dataclasses.replace(problem, options={"prior_floor": 0.0}))
    every = get_estimator("lmi")(
        dataclasses.replace(problem, options={"prior_floor": 0.0, "prior_directions": "all"})
    )
    assert unseen.consistent
    assert np.abs(unseen.x - wls.x).max() < 1e-8 * scale
    assert np.abs(every.x - wls.x).max() > 1e-5 * scale
    # the unseen directions are at the prior: the standard parameters are the ones closest
    # to the nominal among those with these base values
    np.testing.assert_allclose(
        unseen.theta, problem.standard_completion(unseen.x), atol=1e-9 * np.abs(unseen.theta).max()
    )


def test_repeated_lmi_gives_each_problem_the_plain_lmi_estimate():
    """The weight grid's and the model bootstrap's estimator compiles one program and re-solves
    it with each problem's data: each estimate is lmi's (a stale data parameter, a program
    kept across a changed fixed-friction set or prior weight would give another)."""
    problem, *_ = _ur5_problem(noise=2.0, inconsistent=True, regularization=0.1)
    other, *_ = _ur5_problem(noise=2.0, seed=3, inconsistent=True, regularization=0.1)
    problems = [
        problem,
        dataclasses.replace(other, structure=problem.structure),  # other data
        dataclasses.replace(problem, regularization=10.0),  # other prior weight
        problem,
        dataclasses.replace(problem, options={"friction": "free"}),  # no fixed friction
    ]
    repeated = get_repeated_estimator("lmi")
    thetas = []
    for p in problems:
        plain, again = get_estimator("lmi")(p), repeated(p)
        assert again.success, again.message
        scale = np.abs(plain.theta).max()
        np.testing.assert_allclose(again.theta, plain.theta, rtol=0, atol=1e-5 * scale)
        assert again.regularization == p.regularization
        thetas.append(again.theta)
    assert np.abs(thetas[1] - thetas[0]).max() > 1e-3 * np.abs(thetas[0]).max()
    assert repeated.n_programs == 2  # one for the held friction, one for the free
    assert get_repeated_estimator("wls") is get_estimator("wls")


def test_positive_friction_is_held_at_its_wls_value():
    problem, *_ = _ur5_problem(noise=2.0, inconsistent=True, regularization=0.1)
    wls = get_estimator("wls")(problem)
    structure = problem.structure
    index = {n: k for k, n in enumerate(problem.names)}
    held = [structure.names[i] for i in structure.friction if wls.x[index[structure.names[i]]] > 0]
    assert held
    for name, options in (("lmi", {}), ("log_cholesky", {})):
        est = get_estimator(name)(dataclasses.replace(problem, options=options))
        for n in held:
            assert est.x[index[n]] == pytest.approx(wls.x[index[n]], rel=1e-6), (name, n)
    free = get_estimator("lmi")(dataclasses.replace(problem, options={"friction": "free"}))
    assert max(abs(free.x[index[n]] / wls.x[index[n]] - 1) for n in held) > 1e-3
    with pytest.raises(DataError, match="friction"):
        get_estimator("lmi")(dataclasses.replace(problem, options={"friction": "wls"}))
