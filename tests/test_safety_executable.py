"""The executable trajectory: approach, periods, return (ident.excitation.executable)."""

from __future__ import annotations

import numpy as np
import pytest

from ident.excitation import JointFourierFamily, PaperArmFamily
from ident.excitation.check import check_trajectory
from ident.excitation.executable import executable_trajectory, quintic, transition_duration
from ident.excitation.safety import build_safety_model
from ident.model import Robot
from ident.trajectory import read_trajectory_csv, trajectory_to_csv

ARM_UP = (0.0, -0.8, -0.5, 0.0, 0.0, 0.0)
HOME = np.array([0.0, -1.2, 0.3, 0.0, 0.5, 0.0])


@pytest.fixture(scope="module")
def paper():
    return Robot.from_config("configs/paper6r.yaml")


@pytest.fixture(scope="module")
def wrist(paper):
    family = JointFourierFamily(
        paper, [3, 4, 5], n_harmonics=3, base_frequency=2 * np.pi / 4, n_samples=200,
        held_positions=ARM_UP, amplitude_bound=0.3,
    )  # fmt: skip
    x = np.random.default_rng(1).uniform(family.bounds[:, 0], family.bounds[:, 1])
    x[0::5] = 0.0
    return family, x


def test_quintic_meets_both_boundary_states():
    rng = np.random.default_rng(0)
    start, end = tuple(rng.normal(size=(3, 4))), tuple(rng.normal(size=(3, 4)))
    q, dq, ddq = quintic(start, end, 1.7, np.array([0.0, 1.7]))
    for k, (got, s, e) in enumerate(zip((q, dq, ddq), start, end, strict=True)):
        np.testing.assert_allclose(got[0], s, atol=1e-12, err_msg=f"derivative {k}")
        np.testing.assert_allclose(got[1], e, atol=1e-10, err_msg=f"derivative {k}")
    # derivatives are those of the polynomial (finite differences)
    t = np.linspace(0.0, 1.7, 2001)
    q, dq, ddq = quintic(start, end, 1.7, t)
    np.testing.assert_allclose(np.gradient(q, t, axis=0)[1:-1], dq[1:-1], atol=1e-4)
    np.testing.assert_allclose(np.gradient(dq, t, axis=0)[1:-1], ddq[1:-1], atol=1e-4)


def test_transition_duration_keeps_within_the_limit_fraction(paper, wrist):
    family, _ = wrist
    rest = np.zeros(6)
    start, end = (np.zeros(6), rest, rest), (np.full(6, 1.0), rest, rest)
    duration = transition_duration(start, end, family.limits, limit_fraction=0.5)
    t = np.linspace(0.0, duration, 5001)
    _, dq, ddq = quintic(start, end, duration, t)
    assert np.all(np.abs(dq) <= 0.5 * paper.dq_max + 1e-12)
    assert np.all(np.abs(ddq) <= 0.5 * paper.ddq_max + 1e-12)
    # rest-to-rest peak velocity 1.875 d / T: the bound of the slowest joint is reached
    assert duration >= np.max(1.875 / (0.5 * paper.dq_max))


def test_executable_trajectory_is_c2_safe_and_round_trips_through_csv(paper, wrist, tmp_path):
    family, x = wrist
    traj = executable_trajectory(family, x, HOME, rate_hz=1000.0, n_periods=2)
    dt = np.diff(traj.t)
    np.testing.assert_allclose(dt, 1e-3, rtol=1e-9)
    # starts and ends at rest at home
    np.testing.assert_allclose(traj.q[0], HOME, atol=1e-12)
    np.testing.assert_allclose(traj.q[-1], HOME, atol=1e-9)
    np.testing.assert_allclose(traj.dq[[0, -1]], 0.0, atol=1e-9)
    # C2 everywhere: no jump in q, dq, ddq between samples (junctions included)
    for a, b in ((traj.q, traj.dq), (traj.dq, traj.ddq)):
        # (a jerk step at a junction shows as jerk * dt / 2, a few 1e-3 here)
        np.testing.assert_allclose(np.gradient(a, traj.t, axis=0)[1:-1], b[1:-1], atol=1e-2)
    # the periods are the family's closed form
    dense = family.with_samples(4000).trajectories(x[None])
    start = int(np.flatnonzero(np.all(np.abs(traj.q - dense.q[0, 0]) < 1e-12, axis=1))[0])
    np.testing.assert_allclose(
        traj.q[start : start + 8000], np.tile(dense.q[0], (2, 1)), atol=1e-12
    )
    report = check_trajectory(paper, build_safety_model(paper), traj.t, traj.q, traj.dq, traj.ddq)
    assert report.usable, report.summary()
    path = tmp_path / "trajectory.csv"
    path.write_text(trajectory_to_csv(traj), encoding="utf-8")
    back = read_trajectory_csv(path)
    np.testing.assert_array_equal(back.q, traj.q)
    assert back.joint_names == paper.joint_names


def test_moving_start_state_of_the_paper_arm_family(paper):
    """The Cartesian families start in motion: the approach ends in that state exactly."""
    family = PaperArmFamily(paper, n_samples=200)
    x = family.bounds[:, 0] + 0.8 * (family.bounds[:, 1] - family.bounds[:, 0])
    traj = executable_trajectory(family, x, np.zeros(6), rate_hz=500.0)
    first = family.with_samples(5000).trajectories(x[None])
    i = int(np.argmin(np.linalg.norm(traj.q - first.q[0, 0], axis=1)))
    np.testing.assert_allclose(traj.dq[i], first.dq[0, 0], atol=1e-9)
    np.testing.assert_allclose(traj.ddq[i], first.ddq[0, 0], atol=1e-9)
    assert np.max(np.abs(first.dq[0, 0])) > 0.0
    with pytest.raises(ValueError, match="n_periods"):
        executable_trajectory(family, x, np.zeros(6), n_periods=0)
