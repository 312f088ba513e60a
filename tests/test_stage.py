"""The paper's identification stages: states, observation matrices, base parameters."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from robots import UR5_URDF

from ident.dynamics.base_parameters import compute_base_parameters
from ident.dynamics.chain import chain_from_model, random_states
from ident.dynamics.parameters import parameter_names
from ident.dynamics.pinocchio_check import pinocchio_regressor
from ident.dynamics.stage import (
    Stage,
    default_held_positions,
    paper_stages,
    stage_observation_matrix,
    stage_states,
)
from ident.errors import DataError, ModelError

DATA = Path(__file__).parent / "data" / "urdf"


@pytest.fixture(scope="module")
def ur5():
    model = pin.buildModelFromUrdf(str(UR5_URDF))
    return model, chain_from_model(model)


def test_paper_stages_are_wrist_then_arm(ur5) -> None:
    _, chain = ur5
    stages = paper_stages(chain)
    wrist, arm = stages["wrist"], stages["arm"]
    assert wrist.moving_joints == wrist.torque_rows == wrist.bodies == (3, 4, 5)
    assert arm.moving_joints == arm.torque_rows == arm.bodies == (0, 1, 2)
    np.testing.assert_array_equal(wrist.columns, np.arange(30, 60))
    np.testing.assert_array_equal(arm.columns, np.arange(0, 30))
    assert arm.held_joints == (3, 4, 5)
    np.testing.assert_allclose(wrist.held_positions, default_held_positions(chain))
    fraction = (default_held_positions(chain) - chain.q_lower) / (chain.q_upper - chain.q_lower)
    np.testing.assert_allclose(fraction, 0.618034, atol=1e-6)


def test_stage_states_hold_the_other_joints_at_rest() -> None:
    stage = Stage("s", (1, 3), (1, 3), (1, 3), (0.1, 0.2, 0.3, 0.4))
    q, dq, ddq = stage_states(stage, [[1.0, 2.0]], [[3.0, 4.0]], [[5.0, 6.0]], 4)
    np.testing.assert_array_equal(q, [[0.1, 1.0, 0.3, 2.0]])
    np.testing.assert_array_equal(dq, [[0.0, 3.0, 0.0, 4.0]])
    np.testing.assert_array_equal(ddq, [[0.0, 5.0, 0.0, 6.0]])
    with pytest.raises(DataError, match=r"dq_moving must have shape \(n_samples, 2\)"):
        stage_states(stage, np.zeros((2, 2)), np.zeros((2, 3)), np.zeros((2, 2)), 4)


@pytest.mark.parametrize("name", ["wrist", "arm"])
def test_stage_observation_matrix_slices_the_pinocchio_regressor(ur5, name: str) -> None:
    model, chain = ur5
    stage = paper_stages(chain)[name]
    moving = list(stage.moving_joints)
    q, dq, ddq = random_states(chain, 40, rng=4)
    states = stage_states(stage, q[:, moving], dq[:, moving], ddq[:, moving], chain.nq)
    W = stage_observation_matrix(chain, stage, *states)
    reference = pinocchio_regressor(model, *states)[:, list(stage.torque_rows)][:, :, stage.columns]
    assert W.shape == (40 * 3, 30)
    np.testing.assert_allclose(W, reference.reshape(-1, 30), rtol=0, atol=1e-10)
    names = [parameter_names(6)[c] for c in stage.columns]
    qr = compute_base_parameters(W, names, method="qr")
    sequential = compute_base_parameters(W, names, method="sequential")
    assert qr.rank == sequential.rank == np.linalg.matrix_rank(reference.reshape(-1, 30))
    assert qr.n_params == 30


def test_paper_stages_need_six_joints() -> None:
    chain = chain_from_model(pin.buildModelFromUrdf(str(DATA / "rp2.urdf")))
    with pytest.raises(ModelError, match="6-joint arm, this chain has 2 joints"):
        paper_stages(chain)


def test_arm_stage_of_the_paper_robot_combines_body_1_about_its_axis() -> None:
    """Closed form: in DH frame 1 the joint-1 axis is y1, a1 from the origin, so body 1 acts
    only through its inertia about that axis, Iyy1 + 2 a1 mcx1 + a1^2 m1 (parallel axes)."""
    from ident.model import Robot

    robot = Robot.from_config(Path(__file__).parents[1] / "configs/paper6r.yaml")
    chain = robot.chain
    stage = paper_stages(chain)["arm"]
    moving = list(stage.moving_joints)
    q, dq, ddq = robot.random_configurations(100, rng=6)
    W = stage_observation_matrix(
        chain, stage, *stage_states(stage, q[:, moving], dq[:, moving], ddq[:, moving], 6)
    )
    W_dh = W @ robot.dh_to_model_parameters()[np.ix_(stage.columns, stage.columns)]
    names = [parameter_names(6)[c] for c in stage.columns]
    order = [names.index(n) for n in ("Iyy1", "mcx1", "m1")] + [
        i for i, n in enumerate(names) if n not in ("Iyy1", "mcx1", "m1")
    ]
    base = compute_base_parameters(W_dh[:, order], [names[i] for i in order], method="sequential")
    a1 = robot.dh.a[0]
    row = list(base.independent).index(0)  # Iyy1 is kept
    coefficients = dict(zip([base.names[j] for j in base.dependent], base.K[row], strict=True))
    assert coefficients["mcx1"] == pytest.approx(2 * a1, rel=1e-9)
    assert coefficients["m1"] == pytest.approx(a1**2, rel=1e-9)
    assert base.expressions(3)[row].startswith(f"Iyy1 + {2 * a1:.3g} mcx1 + {a1**2:.3g} m1")
    unidentifiable = {base.names[j] for j in base.unidentifiable}
    assert {"mcy1", "mcz1", "Ixx1", "Izz1", "Ixy1", "Ixz1", "Iyz1"} == unidentifiable
