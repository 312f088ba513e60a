"""Kinematic chain arrays read from Pinocchio models, and the serial-chain checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import PANDA_URDF, UR5_URDF

from ident.dynamics.chain import chain_from_model, random_states
from ident.errors import ModelError

DATA = Path(__file__).parent / "data" / "urdf"


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def _forward_kinematics(chain, q: np.ndarray) -> np.ndarray:
    """Joint frames in the base frame from the chain arrays, shape (n, 4, 4)."""
    out, current = [], np.eye(4)
    for i in range(chain.n_joints):
        motion = np.eye(4)
        if chain.prismatic[i]:
            motion[:3, 3] = chain.axes[i] * q[i]
        else:
            motion[:3, :3] = _rotation(chain.axes[i], q[i])
        current = current @ chain.placements[i] @ motion
        out.append(current)
    return np.array(out)


@pytest.mark.parametrize("urdf", [DATA / "rp2.urdf", UR5_URDF], ids=lambda p: p.stem)
def test_chain_forward_kinematics_matches_pinocchio(urdf: Path) -> None:
    model = pin.buildModelFromUrdf(str(urdf))
    data = model.createData()
    chain = chain_from_model(model)
    assert chain.joint_names == tuple(model.names[1:])
    np.testing.assert_array_equal(chain.parents, np.arange(model.nv) - 1)
    q, _, _ = random_states(chain, 10, rng=0)
    for qk in q:
        pin.forwardKinematics(model, data, qk)
        expected = np.array([data.oMi[i].homogeneous for i in range(1, model.njoints)])
        np.testing.assert_allclose(_forward_kinematics(chain, qk), expected, atol=1e-12)


def test_chain_reads_axes_limits_and_gravity_of_the_prismatic_fixture() -> None:
    chain = chain_from_model(pin.buildModelFromUrdf(str(DATA / "rp2.urdf")))
    np.testing.assert_array_equal(chain.prismatic, [False, True])
    np.testing.assert_allclose(chain.axes, [[0, 0, 1], [0, 0.6, 0.8]])
    np.testing.assert_allclose(chain.q_lower, [-2.5, -0.2])
    np.testing.assert_allclose(chain.q_upper, [2.5, 0.3])
    np.testing.assert_allclose(chain.dq_max, [2.0, 0.5])
    np.testing.assert_allclose(chain.tau_max, [50.0, 100.0])
    np.testing.assert_allclose(chain.gravity, [0, 0, -9.81])
    assert not chain.placements.flags.writeable


def test_random_states_stay_within_limits_and_repeat_with_the_seed() -> None:
    chain = chain_from_model(pin.buildModelFromUrdf(str(DATA / "rp2.urdf")))
    q, dq, ddq = random_states(chain, 500, rng=3)
    assert q.shape == dq.shape == ddq.shape == (500, 2)
    assert np.all((q >= chain.q_lower) & (q <= chain.q_upper))
    assert np.all(np.abs(dq) <= chain.dq_max)
    np.testing.assert_array_equal(random_states(chain, 500, rng=3)[0], q)


@pytest.mark.parametrize(
    ("urdf", "root", "match"),
    [
        ("branched.urdf", None, "branched: joint 'right_joint'"),
        ("continuous.urdf", None, "'wheel_joint' .* continuous"),
        ("rp2.urdf", pin.JointModelFreeFlyer(), "floating base"),
    ],
)
def test_non_serial_models_are_rejected_with_the_joint_and_the_fix(urdf, root, match) -> None:
    path = str(DATA / urdf)
    model = pin.buildModelFromUrdf(path) if root is None else pin.buildModelFromUrdf(path, root)
    with pytest.raises(ModelError, match=match) as info:
        chain_from_model(model)
    assert "pin.buildReducedModel" in str(info.value)


def test_panda_needs_its_fingers_locked() -> None:
    model = pin.buildModelFromUrdf(str(PANDA_URDF))
    with pytest.raises(ModelError, match="panda_finger_joint2"):
        chain_from_model(model)
    fingers = [model.getJointId(f"panda_finger_joint{k}") for k in (1, 2)]
    reduced = pin.buildReducedModel(model, fingers, pin.neutral(model))
    assert chain_from_model(reduced).n_joints == 7
