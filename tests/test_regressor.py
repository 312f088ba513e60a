"""The hand-derived Newton-Euler regressor against Pinocchio."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import PANDA_URDF, UR5_URDF, random_chain

from ident.dynamics.chain import chain_from_model, random_states
from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.dynamics.pinocchio_check import (
    compare_with_pinocchio,
    pinocchio_regressor,
    pinocchio_rnea,
)
from ident.dynamics.regressor import joint_torque_regressor, joint_torque_regressor_numpy
from ident.errors import DataError

ROOT = Path(__file__).parents[1]
DATA = Path(__file__).parent / "data" / "urdf"


def _panda() -> pin.Model:
    model = pin.buildModelFromUrdf(str(PANDA_URDF))
    fingers = [model.getJointId(f"panda_finger_joint{k}") for k in (1, 2)]
    return pin.buildReducedModel(model, fingers, pin.neutral(model))


def _unaligned() -> pin.Model:
    """Random 6-joint model with unaligned revolute and prismatic axes."""
    joint_types = [
        pin.JointModelRevoluteUnaligned,
        pin.JointModelPrismaticUnaligned,
        lambda _: pin.JointModelRX(),
        lambda _: pin.JointModelPZ(),
        lambda _: pin.JointModelRY(),
        lambda axis: pin.JointModelRevoluteUnaligned(-axis),
    ]
    return random_chain(joint_types, seed=7)


MODELS = {
    "rp2": lambda: pin.buildModelFromUrdf(str(DATA / "rp2.urdf")),
    "ur5": lambda: pin.buildModelFromUrdf(str(UR5_URDF)),
    "panda": _panda,
    "unaligned": _unaligned,
    "paper6r": lambda: pin.buildModelFromUrdf(str(ROOT / "robot/urdf/paper6r.urdf")),
}


@pytest.mark.parametrize("name", sorted(MODELS))
def test_regressor_equals_pinocchio_and_reproduces_rnea(name: str) -> None:
    model = MODELS[name]()
    chain = chain_from_model(model)
    q, dq, ddq = random_states(chain, 50, rng=0)
    ours = joint_torque_regressor(chain, q, dq, ddq)
    reference = pinocchio_regressor(model, q, dq, ddq)
    assert ours.shape == (50, model.nv, 10 * model.nv)
    scale = np.abs(reference).max()
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-9 * max(1.0, scale))
    np.testing.assert_allclose(ours, reference, rtol=0, atol=1e-9)
    tau = ours @ parameters_from_model(model)
    np.testing.assert_allclose(tau, pinocchio_rnea(model, q, dq, ddq), rtol=0, atol=1e-9)
    # the numpy reference implementation agrees with the compiled kernel
    np.testing.assert_allclose(joint_torque_regressor_numpy(chain, q, dq, ddq), ours, atol=1e-12)


def test_compare_with_pinocchio_reports_small_errors() -> None:
    model = MODELS["ur5"]()
    q, dq, ddq = random_states(chain_from_model(model), 20, rng=1)
    report = compare_with_pinocchio(model, q, dq, ddq)
    assert report["n_samples"] == 20
    assert report["max_abs_error"] < 1e-10
    assert report["max_rel_error"] < 1e-12
    assert report["rnea_max_abs_error"] < 1e-10
    assert report["regressor_scale"] > 1.0


def test_a_wrong_gravity_or_parameter_breaks_the_match() -> None:
    """The comparison can fail: perturbing the chain changes the regressor."""
    model = MODELS["rp2"]()
    chain = chain_from_model(model)
    q, dq, ddq = random_states(chain, 5, rng=2)
    ours = joint_torque_regressor(chain, q, dq, ddq)
    model.gravity.linear = np.array([0.0, 0.0, -9.0])
    assert np.abs(ours - pinocchio_regressor(model, q, dq, ddq)).max() > 0.1


def test_single_state_and_shape_errors() -> None:
    model = MODELS["rp2"]()
    chain = chain_from_model(model)
    y = joint_torque_regressor(chain, np.zeros(2), np.zeros(2), np.zeros(2))
    assert y.shape == (1, 2, 20)
    # at rest only gravity acts: the prismatic joint carries the weight along its axis
    axis_in_base = model.jointPlacements[2].rotation @ np.array([0.0, 0.6, 0.8])
    np.testing.assert_allclose(y[0, 1, 10], 9.81 * axis_in_base[2], atol=1e-12)
    with pytest.raises(DataError, match=r"dq must have shape \(n_samples, 2\)"):
        joint_torque_regressor(chain, np.zeros((3, 2)), np.zeros((3, 3)), np.zeros((3, 2)))


def test_parameter_names_follow_pinocchio_order() -> None:
    names = parameter_names(2)
    assert names[:10] == (
        "m1",
        "mcx1",
        "mcy1",
        "mcz1",
        "Ixx1",
        "Ixy1",
        "Iyy1",
        "Ixz1",
        "Iyz1",
        "Izz1",
    )
    assert names[10] == "m2"
    assert len(names) == 20
    model = MODELS["rp2"]()
    params = parameters_from_model(model)
    inertia = model.inertias[1]
    assert params[0] == pytest.approx(inertia.mass)
    np.testing.assert_allclose(params[1:4], inertia.mass * inertia.lever)


def test_kernels_compile_once_for_writeable_and_read_only_states() -> None:
    # numba compiles one specialization per argument type and an array's read-only flag is
    # part of it: a caller passing read-only logs and one passing fresh arrays made each kernel
    # compile twice (6-13 s of CPU on a first run); the wrappers hand the kernels one type
    from ident.dynamics import _kernels
    from ident.dynamics.gram import regressor_gram, selected_rows

    chain = chain_from_model(pin.buildModelFromUrdf(str(UR5_URDF)))
    q, dq, ddq = random_states(chain, 5, rng=0)
    frozen = [a.copy() for a in (q, dq, ddq)]
    for a in frozen:
        a.flags.writeable = False
    for states in ((q, dq, ddq), frozen, (q.T.copy().T, dq, ddq)):  # writeable, read-only, F
        y = joint_torque_regressor(chain, *states)
        selected_rows(chain, *states)
        regressor_gram(chain, *states)
    np.testing.assert_array_equal(y, joint_torque_regressor(chain, q, dq, ddq))
    # one type of q, dq, ddq (arguments 4-6) whatever the caller passed; other tests of the
    # same process may add a specialization for another ``out`` (a strided view: 'A' layout)
    for kernel in (_kernels.regressor_into, _kernels.selected_rows_into):
        assert len({signature[4:7] for signature in kernel.signatures}) == 1, kernel.signatures
