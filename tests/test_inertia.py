import numpy as np
import pinocchio as pin
import pytest

from ident.robot.inertia import (
    PAPER_ORDER,
    PAPER_TO_PINOCCHIO,
    PINOCCHIO_ORDER,
    com_and_inertia,
    consistency_problems,
    paper_to_pinocchio,
    parameters_from_com,
    pinocchio_to_paper,
    transform_parameters,
)


def _random_body(rng):
    mass = rng.uniform(0.5, 5.0)
    com = rng.uniform(-0.3, 0.3, 3)
    rotation = pin.exp3(rng.normal(size=3))
    x, y, z = rng.uniform(0.05, 0.5, 3) ** 2  # a solid box: consistent by construction
    moments = mass / 12.0 * np.array([y + z, x + z, x + y])
    inertia_com = rotation @ np.diag(moments) @ rotation.T
    return mass, com, inertia_com


def test_parameters_match_pinocchio_inertia():
    rng = np.random.default_rng(0)
    for _ in range(10):
        mass, com, inertia_com = _random_body(rng)
        expected = pin.Inertia(mass, com, inertia_com).toDynamicParameters()
        np.testing.assert_allclose(
            parameters_from_com(mass, com, inertia_com), expected, atol=1e-15
        )


def test_stacked_parameters_and_inverse():
    rng = np.random.default_rng(1)
    bodies = [_random_body(rng) for _ in range(4)]
    mass = np.array([b[0] for b in bodies])
    com = np.array([b[1] for b in bodies])
    inertia_com = np.array([b[2] for b in bodies])
    params = parameters_from_com(mass, com, inertia_com)
    assert params.shape == (4, 10)
    back_mass, back_com, back_inertia = com_and_inertia(params)
    np.testing.assert_allclose(back_mass, mass)
    np.testing.assert_allclose(back_com, com, atol=1e-15)
    np.testing.assert_allclose(back_inertia, inertia_com, atol=1e-15)


def test_frame_change_matches_pinocchio_se3_action():
    rng = np.random.default_rng(2)
    for _ in range(10):
        inertia = pin.Inertia(*_random_body(rng))
        placement = pin.SE3(pin.exp3(rng.normal(size=3)), rng.normal(size=3))  # B in A
        expected = placement.act(inertia).toDynamicParameters()
        got = transform_parameters(
            inertia.toDynamicParameters(), placement.rotation, placement.translation
        )
        np.testing.assert_allclose(got, expected, atol=1e-14)


def test_frame_change_round_trip_stacked():
    rng = np.random.default_rng(3)
    params = np.array([pin.Inertia(*_random_body(rng)).toDynamicParameters() for _ in range(3)])
    rotations = np.array([pin.exp3(rng.normal(size=3)) for _ in range(3)])
    translations = rng.normal(size=(3, 3))
    there = transform_parameters(params, rotations, translations)
    inverse_rotations = np.swapaxes(rotations, 1, 2)
    inverse_translations = -np.einsum("kij,kj->ki", inverse_rotations, translations)
    back = transform_parameters(there, inverse_rotations, inverse_translations)
    np.testing.assert_allclose(back, params, atol=1e-14)


def test_paper_order_map():
    paper = np.arange(10.0)  # m, mcx, mcy, mcz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz
    pinocchio = paper_to_pinocchio(paper)
    named = dict(zip(PINOCCHIO_ORDER, pinocchio, strict=True))
    assert named == dict(zip(PAPER_ORDER, paper, strict=True))
    np.testing.assert_array_equal(pinocchio, [0, 1, 2, 3, 4, 7, 5, 8, 9, 6])
    np.testing.assert_array_equal(pinocchio_to_paper(pinocchio), paper)
    np.testing.assert_array_equal(PAPER_TO_PINOCCHIO @ PAPER_TO_PINOCCHIO.T, np.eye(10))
    stacked = np.stack([paper, 2 * paper])
    np.testing.assert_array_equal(paper_to_pinocchio(stacked)[1], 2 * pinocchio)


def test_consistency_accepts_real_bodies():
    rng = np.random.default_rng(4)
    for _ in range(10):
        assert consistency_problems(parameters_from_com(*_random_body(rng))) == []
    # a thin rod is at the triangle-inequality boundary and still consistent
    rod = parameters_from_com(1.0, np.zeros(3), np.diag([0.0, 1.0, 1.0]))
    assert consistency_problems(rod) == []


@pytest.mark.parametrize(
    ("mass", "moments", "expected"),
    [
        (-1.0, [1.0, 1.0, 1.0], "mass = -1 kg must be > 0"),
        (0.0, [1.0, 1.0, 1.0], "mass = 0 kg must be > 0"),
        (1.0, [-0.1, 1.0, 1.0], "not positive semi-definite"),
        (1.0, [0.1, 0.2, 1.0], "triangle inequality"),
    ],
)
def test_consistency_rejects(mass, moments, expected):
    params = parameters_from_com(mass, np.array([0.1, 0.0, 0.0]), np.diag(moments))
    problems = consistency_problems(params)
    assert len(problems) == 1
    assert expected in problems[0]


def test_paper_link6_read_about_origin_is_inconsistent():
    """Reading eq. 32 as inertia about the DH origin violates physics (DESIGN reading)."""
    mass = 0.186899621
    first_moment = np.array([0.004296, 0.000028941, 4.9163]) * 1e-3
    inertia = np.diag([103.8927, 103.8903, 204.5344]) * 1e-6
    about_origin = np.r_[mass, first_moment, inertia[[0, 0, 1, 0, 1, 2], [0, 1, 1, 2, 2, 2]]]
    assert consistency_problems(about_origin) != []
    about_com = parameters_from_com(mass, first_moment / mass, inertia)
    assert consistency_problems(about_com) == []
