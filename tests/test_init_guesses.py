"""``ident init``'s measurement guesses: scaled to the URDF's effort limits, unless they are
placeholders (one value on every joint while the loads of the links the joints move differ by
orders of magnitude), then to those loads; the loads against Pinocchio's RNEA."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.signal
from robots import PANDA_URDF, UR5_URDF

from ident.excitation.fourier import fourier_bound_factors
from ident.model.robot import Robot
from ident.run import init_robot
from ident.run.init_config import MIN_PERIOD_S, _guess_scale, _preprocess, excitation_period
from ident.run.init_robot import (
    PLACEHOLDER_LOAD_SPAN,
    gain_scale,
    joint_loads,
    placeholder_effort,
    placeholder_velocity,
)

#: The SO-101 shipped with ident: 2.9 N*m on every joint (its servo's rating), a wrist roll
#: that carries grams.
SO101_URDF = Path(__file__).resolve().parents[1] / "robot" / "urdf" / "so101.urdf"


@pytest.fixture(scope="module")
def so101():
    return Robot.from_urdf(SO101_URDF)


def test_joint_loads_are_gravity_plus_link_inertia_at_the_acceleration_limit(so101):
    ddq = np.array([10.0, 20.0, 5.0, 30.0, 40.0])
    loads = joint_loads(so101, ddq, n=20)
    # reference: Pinocchio's RNEA at each posture, the joint alone accelerated at its limit
    # (tau_j = g_j(q) + M_jj(q) ddq_j), no CRBA
    expected = np.zeros(so101.nv)
    for q in init_robot._postures(so101, 20):
        for j in range(so101.nv):
            ddq_j = np.zeros(so101.nv)
            ddq_j[j] = ddq[j]
            gravity = so101.rnea(q[None], np.zeros((1, so101.nv)), np.zeros((1, so101.nv)))[0]
            total = so101.rnea(q[None], np.zeros((1, so101.nv)), ddq_j[None])[0]
            inertial = total[j] - gravity[j]
            expected[j] = max(expected[j], abs(gravity[j]) + inertial)
    np.testing.assert_allclose(loads, expected, rtol=1e-9)


def test_equal_efforts_on_unequal_loads_are_placeholders(so101):
    # the SO-101: 2.9 N*m everywhere, loads from ~1 N*m (shoulder lift) to grams (wrist roll)
    ddq = np.full(so101.nv, 30.0)
    loads = joint_loads(so101, ddq)
    assert loads.max() > PLACEHOLDER_LOAD_SPAN * loads.min()
    assert placeholder_effort(so101.model.effortLimit, loads) == pytest.approx(2.9)
    scale, placeholder = _guess_scale(so101, np.full(so101.nv, 2.9), ddq)
    assert placeholder == pytest.approx(2.9)
    np.testing.assert_allclose(scale, 2.0 * loads)
    # the wrist roll's rotor-inertia guess (0.003 kg*m^2 per N*m): of the order of the link
    # inertia it drives, where the effort-scaled one was hundreds of times it
    q = np.zeros((1, so101.nq))
    unit = np.zeros((1, so101.nv))
    unit[0, -1] = 1.0
    inertia = (so101.rnea(q, 0 * unit, unit) - so101.rnea(q, 0 * unit, 0 * unit))[0, -1]
    assert 0.003 * scale[-1] < 2.0 * inertia
    assert 0.003 * 2.9 > 100.0 * inertia
    # the same efforts where the loads are alike, efforts that differ, unknown ones, 2 joints
    assert placeholder_effort(np.full(5, 2.9), np.linspace(1.0, 50.0, 5)) == 0.0
    assert placeholder_effort(np.array([3.0, 3.0, 3.0, 2.9, 2.9]), loads) == 0.0
    assert placeholder_effort(np.array([np.inf] * 5), loads) == 0.0
    assert placeholder_effort(np.array([300.0, 300.0]), np.array([100.0, 0.01])) == 0.0


@pytest.mark.parametrize("urdf", [UR5_URDF, PANDA_URDF], ids=["ur5", "panda"])
def test_real_effort_limits_keep_scaling_the_guesses(urdf):
    # UR5 150/28 N*m, Panda 87/12 N*m: rated by the load; the guesses scale with them
    lock = {"panda_finger_joint1": 0.0, "panda_finger_joint2": 0.0} if urdf == PANDA_URDF else {}
    robot = Robot.from_urdf(urdf, lock_joints=lock)
    effort = np.asarray(robot.model.effortLimit, dtype=float)
    scale, placeholder = _guess_scale(robot, effort, np.full(robot.nv, 10.0))
    assert placeholder == 0.0
    np.testing.assert_array_equal(scale, effort)


def test_equal_velocities_are_placeholders_only_beside_placeholder_efforts():
    # the iiwa_stack's xacro: 10 rad/s and 300 N*m on every joint, both copies
    assert placeholder_velocity(np.full(7, 10.0), 300.0) == 10.0
    # equal velocities beside real effort ratings (UR5 3.15 on the big joints, Z1 3.1415):
    # given, as the URDF says; velocities that differ; an unknown one; two joints
    assert placeholder_velocity(np.full(6, 3.1415), 0.0) == 0.0
    assert placeholder_velocity(np.array([1.48, 1.48, 1.75, 1.31, 2.27, 2.36, 2.36]), 300.0) == 0
    assert placeholder_velocity(np.array([10.0, 10.0, np.inf]), 300.0) == 0.0
    assert placeholder_velocity(np.array([10.0, 10.0]), 300.0) == 0.0


def test_controller_gains_carry_the_rotor_inertia_guess(so101):
    # reference: each joint's link-side inertia M_jj from Pinocchio's RNEA (unit acceleration
    # of that joint alone, gravity removed), the largest over the same seeded postures
    armature = np.array([0.1, 0.02, 0.01, 0.005, 0.001])
    largest = np.zeros(so101.nv)
    zero = np.zeros((1, so101.nv))
    for q in init_robot._postures(so101, 20):
        for j in range(so101.nv):
            unit = zero.copy()
            unit[0, j] = 1.0
            m_jj = (so101.rnea(q[None], zero, unit) - so101.rnea(q[None], zero, zero))[0, j]
            largest[j] = max(largest[j], m_jj)
    r = gain_scale(so101, armature, n=20)
    np.testing.assert_allclose(r, 1.0 + armature / largest, rtol=1e-9)
    # the loop gain kp r M_jj / (M_jj + Ia_j) at the largest M_jj is exactly kp: never above
    np.testing.assert_allclose(r * largest / (largest + armature), 1.0, rtol=1e-12)


def test_excitation_period_is_where_the_position_ranges_stop_binding_the_box():
    # a 2-joint toy, by hand: half rooms h = 1.05 - 0.05 and 2.05 - 0.05 rad. The position term
    # 0.7 h w / c_q of the amplitude bound meets the velocity term 0.8 dq / c_v at
    # w = 0.8 dq c_q / (0.7 h c_v), the acceleration term 0.8 ddq / (w c_a) at
    # w^2 = 0.8 ddq c_q / (0.7 h c_a); the joint is free beyond the first of the two
    c_q, c_v, c_a = fourier_bound_factors(4)
    toy = SimpleNamespace(q_lower=np.array([-1.05, -2.05]), q_upper=np.array([1.05, 2.05]))
    dq, ddq = np.array([10.0, 1.0]), np.array([30.0, 30.0])
    w_a = np.sqrt(0.8 * 30.0 * c_q / (0.7 * 1.0 * c_a))  # 4.45 rad/s (velocity: 9.2)
    w_b = 0.8 * 1.0 * c_q / (0.7 * 2.0 * c_v)  # 0.46 rad/s (acceleration: 3.15)
    expected = 2.0 * np.pi / (0.25 * w_b + 0.75 * w_a)  # the upper quartile of the two: 1.82 s
    period = excitation_period(toy, dq, ddq)
    assert period == pytest.approx(np.floor(expected * 100.0) / 100.0)
    # not the fixed 10 s, nor the smallest (13.6 s, clipped to 10 s) nor the largest (1.41 s)
    assert 1.8 < period < 1.85
    # a UR's +-2 pi joints, velocity-bound at 10 s: 10 s kept; tight ranges: the floor where
    # the simulated controller tracks the 4th harmonic (a fifth of its 100 rad/s)
    ur = SimpleNamespace(q_lower=np.full(2, -2 * np.pi), q_upper=np.full(2, 2 * np.pi))
    assert excitation_period(ur, np.array([2.16, 3.2]), np.array([6.5, 9.6])) == 10.0
    tight = SimpleNamespace(q_lower=np.full(2, -0.1), q_upper=np.full(2, 0.1))
    assert excitation_period(tight, dq, ddq) == pytest.approx(np.ceil(MIN_PERIOD_S * 100) / 100)
    assert MIN_PERIOD_S == pytest.approx(2.0 * np.pi * 4 / 20.0)


def test_faster_excitations_filter_wider_and_drop_the_coulomb_spread():
    factors = fourier_bound_factors(4)
    _, c_v, c_a = factors
    # at 10 s and a UR10's bounds: 10 Hz and 0.15 rad/s (or 10 % of the box's speed), the
    # configs written before
    cutoff, threshold = _preprocess(np.array([0.01, 0.2]), 2.0 * np.pi / 10.0, factors)
    assert cutoff == pytest.approx(10.0)
    np.testing.assert_allclose(threshold, [0.1 * c_v * 0.01, 0.15])
    # at 1.8 s (SO-101): 20 Hz at most, and the speed a reversal at the box's acceleration
    # c_a A w reaches in 1 / (2 cutoff)
    w = 2.0 * np.pi / 1.8
    cutoff, threshold = _preprocess(np.array([0.01, 0.4]), w, factors)
    assert cutoff == 20.0
    np.testing.assert_allclose(threshold, [c_a * 0.01 * w / 40.0, c_a * 0.4 * w / 40.0])
    # the spread it drops: scipy's zero-phase 4th-order Butterworth on a Coulomb step at 1 kHz
    # is still 13.6 % off 25 ms (1 / (2 cutoff)) after it and within 4 % at 50 ms
    b, a = scipy.signal.butter(4, cutoff / 500.0)
    t = (np.arange(-2000, 2000) + 0.5) / 1000.0
    step = scipy.signal.filtfilt(b, a, np.sign(t))
    assert abs(step[np.argmin(abs(t - 0.025))] - 1.0) == pytest.approx(0.136, abs=0.005)
    assert abs(step[np.argmin(abs(t - 0.05))] - 1.0) < 0.04
