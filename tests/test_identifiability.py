"""What the data cannot see: a CAD model 4x off, joint data only (the classic trap)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin
import pytest
from robots import UR5_URDF

from ident.dynamics.friction import ExtraTerms
from ident.dynamics.parameter_model import build_parameter_model
from ident.identify.assessment.identifiability import standard_identifiability
from ident.identify.estimators import get_estimator
from ident.identify.estimators.identification import problem_from_states


@pytest.fixture(scope="module")
def trap():
    """UR5 torques from its URDF inertials (the truth) + noise; a CAD nominal with every
    mass 4x and every centre of mass moved 0.5 m out of its link."""
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    terms = ExtraTerms.from_options(model.nv, viscous=True, coulomb=False, offset=False)
    pm = build_parameter_model(model, terms)
    truth = np.array(pm.nominal)
    cad = truth.copy()
    for b in range(model.nv):
        i = pm.names.index(f"m{b + 1}")
        m = truth[i]
        c = truth[i + 1 : i + 4] / m + 0.5  # far outside any link's box
        cad[i] = 4.0 * m
        cad[i + 1 : i + 4] = 4.0 * m * c
        cad[i + 4 : i + 10] *= 4.0
    pm_cad = dataclasses.replace(pm, nominal=cad)
    rng = np.random.default_rng(0)
    t = np.arange(1500) / 50.0
    w = 2 * np.pi * 0.1 * np.arange(1, 5)
    a, b = rng.uniform(-0.5, 0.5, (2, 4, model.nv))
    s, co = np.sin(np.outer(t, w)), np.cos(np.outer(t, w))
    q = s @ a + co @ b - np.array([0, 1.2, 0, 0, 0, 0])
    dq = (co * w) @ a - (s * w) @ b
    ddq = -(s * w**2) @ a - (co * w**2) @ b
    tau_true = np.array(
        [pin.rnea(model, model.createData(), *x) for x in zip(q, dq, ddq, strict=True)]
    )
    tau_true += 0.8 * dq  # viscous friction fv = 0.8 on every joint
    truth[[pm.names.index(f"fv{j + 1}") for j in range(model.nv)]] = 0.8
    tau = tau_true + 0.01 * rng.standard_normal(tau_true.shape)
    problem = problem_from_states(model, pm_cad, q, dq, ddq, tau)
    return pm, truth, cad, problem


def test_base_parameters_recovered_whatever_the_cad(trap):
    pm, truth, _, problem = trap
    est = get_estimator("ols")(problem)
    beta = pm.base.project(truth)
    major = np.abs(beta) > 1e-2 * np.abs(beta).max()
    rel = np.abs(est.x - beta)[major] / np.abs(beta[major])
    assert rel.max() < 0.01, dict(zip(np.array(pm.base_names)[major], rel, strict=True))


def test_unseparable_parameters_named_and_alone_ones_trustworthy(trap):
    pm, truth, cad, problem = trap
    ident = standard_identifiability(
        pm.base.projection, pm.names, pm.base_names, pm.base.expressions()
    )
    # closed-form facts of a UR5 (vertical joint 1, parallel joints 2-4): the base's mass
    # and the first link's mass and moments other than Izz1 do not reach any torque; the
    # masses of links 2.. enter only combined with their neighbours'
    assert {"m1", "mcx1", "mcy1", "mcz1", "Ixx1", "Iyy1"} <= set(ident.of_kind("none"))
    assert {"m2", "m3", "m6"} <= set(ident.of_kind("combination"))
    assert "fv1" in ident.of_kind("alone")
    lines = "\n".join(ident.lines())
    assert "m2: only in combination, in " in lines
    assert "m1: not seen by the data" in lines
    # the written (standard-completion) model: every parameter called 'alone' is the truth
    # although the CAD is 4x off; the others are where the CAD put them, so they are named
    theta = problem.standard_completion(get_estimator("ols")(problem).x)
    alone = [pm.names.index(n) for n in ident.of_kind("alone")]
    # errors in each parameter's physical scale (m, m L, m L^2 of the true link; 1 for
    # friction)
    scale = dataclasses.replace(problem.structure, nominal=truth).scales()
    error = np.abs(theta - truth) / scale
    assert error[alone].max() < 0.02
    wrong = {pm.names[i] for i in np.flatnonzero(error > 0.2)}
    assert {"m2", "m3"} <= wrong  # the CAD's masses, 4x off: not the data's
    assert wrong <= set(ident.of_kind("combination")) | set(ident.of_kind("none"))


def test_standard_values_of_alone_parameters_and_their_std(trap):
    pm, truth, _, problem = trap
    ident = standard_identifiability(pm.base.projection, pm.names, pm.base_names)
    est = get_estimator("ols")(problem)
    value, std = ident.standard_values(est.x, est.covariance)
    alone = np.array([k == "alone" for k in ident.kind])
    assert np.isnan(value[~alone]).all()
    # fv3 is a base parameter by itself: its value and std are the base estimate's
    k = pm.base_names.index("fv3")
    i = pm.names.index("fv3")
    assert value[i] == pytest.approx(est.x[k], rel=1e-9)
    assert std[i] == pytest.approx(est.std[k], rel=1e-6)
    # every alone value equals the standard completion (the data's value), whatever the CAD
    theta = problem.standard_completion(est.x)
    np.testing.assert_allclose(value[alone], theta[alone], rtol=1e-6, atol=1e-9)
