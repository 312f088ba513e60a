"""Pseudo-inertia and consistency checks against Pinocchio and closed forms."""

import numpy as np
import pinocchio as pin
import pytest

from ident.identify.estimation.consistency import (
    body_consistency,
    parameters_from_pseudo_inertia,
    pseudo_inertia,
    pseudo_inertia_min_eigenvalue,
    triangle_inequality_margin,
)


def _box(rng):
    box = pin.Inertia.FromBox(rng.uniform(0.5, 5.0), *rng.uniform(0.05, 0.5, size=3))
    return np.asarray(pin.SE3.Random().act(box).toDynamicParameters())


def test_pseudo_inertia_equals_pinocchio():
    rng = np.random.default_rng(0)
    for _ in range(10):
        theta = rng.normal(size=10)  # linear map: any vector, consistent or not
        expected = pin.PseudoInertia.FromDynamicParameters(theta).toMatrix()
        np.testing.assert_allclose(pseudo_inertia(theta), expected, atol=1e-14)
        np.testing.assert_allclose(parameters_from_pseudo_inertia(pseudo_inertia(theta)), theta)
    stacked = rng.normal(size=(3, 2, 10))
    assert pseudo_inertia(stacked).shape == (3, 2, 4, 4)


def test_box_is_consistent_and_inflated_inertia_is_not():
    rng = np.random.default_rng(1)
    theta = _box(rng)
    assert pseudo_inertia_min_eigenvalue(theta) > 0
    assert triangle_inequality_margin(theta) > 0
    (check,) = body_consistency(theta, np.arange(10)[None, :], ("link",))
    assert check.consistent
    assert check.problems == ()
    assert check.body == "link"
    # a thin rod along z has I_zz ~ 0 about its centre: lowering Izz further breaks it
    rod = np.asarray(pin.Inertia.FromCylinder(2.0, 1e-3, 1.0).toDynamicParameters())
    rod[9] -= 1e-3
    (check,) = body_consistency(rod, np.arange(10)[None, :])
    assert not check.consistent
    assert check.min_eigenvalue < 0
    assert check.problems


def test_point_mass_is_on_the_boundary():
    theta = np.asarray(
        pin.Inertia(3.0, np.array([0.1, 0.2, 0.3]), np.zeros((3, 3))).toDynamicParameters()
    )
    assert pseudo_inertia_min_eigenvalue(theta) == pytest.approx(0.0, abs=1e-12)


def test_negative_mass_is_inconsistent():
    theta = _box(np.random.default_rng(2))
    theta[0] = -1.0
    (check,) = body_consistency(theta, np.arange(10)[None, :])
    assert not check.consistent
    assert "mass" in check.problems[0]
    assert np.isnan(triangle_inequality_margin(theta))
