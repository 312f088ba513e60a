"""Base parameters of the paper's stages in the paper's DH frames vs Pinocchio's body frames.

References: an independent computation (``compute_base_parameters`` on ``W @ M`` with other
random states) and the lists of docs/paper-notes.md ("Base parameters of the paper's stages").
"""

from pathlib import Path

import numpy as np
import pytest

from ident.dynamics.base_parameters import compute_base_parameters
from ident.dynamics.stage import select_stage
from ident.model.selection import load_robot
from ident.run.config import load_run_config
from ident.run.pipeline import build_stage_info
from ident.run.setup import make_family

CONFIGS = Path(__file__).resolve().parents[1] / "configs"

# docs/paper-notes.md, DH frames, sequential method, eq. 14 column order
NOTES = {
    "wrist": {
        "independent": "mcx4 mcz4 Iyy4 mcx5 mcz5 Ixx5 Iyy5 Ixy5 Ixz5 Iyz5 mcx6 mcy6 Ixx6 Izz6 "
        "Ixy6 Ixz6 Iyz6",
        "dependent": "mcy5 Izz5 m6 mcz6 Iyy6",
        "unidentifiable": "m4 mcy4 Ixx4 Izz4 Ixy4 Ixz4 Iyz4 m5",
        # body frames (paper-notes, difference 5)
        "body_unidentifiable": "m4 mcz4 Ixx4 Ixy4 Iyy4 Ixz4 Iyz4 m5 m6",
    },
    "arm": {
        "independent": "m1 m2 mcx2 mcy2 mcz2 Ixx2 Ixy2 Iyz2 mcx3 mcz3 Ixx3 Iyy3 Ixy3 Ixz3 Iyz3",
        "dependent": "mcx1 Iyy1 Iyy2 Izz2 Ixz2 m3 mcy3 Izz3",
        "unidentifiable": "mcy1 mcz1 Ixx1 Izz1 Ixy1 Ixz1 Iyz1",
        "body_unidentifiable": "m1 mcx1 mcy1 mcz1 Ixx1 Ixy1 Iyy1 Ixz1 Iyz1 mcz2",
    },
}


@pytest.fixture(scope="module", params=["wrist", "arm"])
def built(request):
    name = request.param
    config = load_run_config(CONFIGS / f"{name}.yaml")
    robot = load_robot(config.robot)
    stage = select_stage(robot, name)
    family = make_family(config, robot, stage)
    info = build_stage_info(robot, stage, family, "qr", np.random.default_rng(0))
    return name, robot, stage, family, info


def test_dh_counts_equal_an_independent_computation(built):
    name, robot, stage, family, info = built
    gen = np.random.default_rng(99)
    n = 250
    moving = list(family.moving_joints)
    q = np.tile(np.asarray(family.held_positions, dtype=float), (n, 1))
    dq, ddq = np.zeros_like(q), np.zeros_like(q)
    q[:, moving] = gen.uniform(robot.q_lower[moving], robot.q_upper[moving], (n, 3))
    dq[:, moving] = gen.uniform(-1.0, 1.0, (n, 3)) * robot.dq_max[moving]
    ddq[:, moving] = gen.uniform(-1.0, 1.0, (n, 3)) * robot.ddq_max[moving]
    M = robot.dh_to_model_parameters()
    Y = robot.regressor(q, dq, ddq)[:, list(stage.torque_rows), :]
    cols = list(stage.columns)
    names = [robot.parameter_names()[c] for c in cols]
    ref_dh = compute_base_parameters((Y @ M)[:, :, cols].reshape(-1, 30), names, method="qr")
    ref_body = compute_base_parameters(Y[:, :, cols].reshape(-1, 30), names, method="qr")
    c = ref_dh.counts()
    assert info.dh_frames.counts == (c["n_independent"], c["n_dependent"], c["n_unidentifiable"])
    assert info.dh_frames.counts == {"wrist": (17, 5, 8), "arm": (15, 8, 7)}[name]
    c = ref_body.counts()
    assert info.counts == (c["n_independent"], c["n_dependent"], c["n_unidentifiable"])
    # the unidentifiable (zero-column) names are method independent
    assert set(info.dh_frames.unidentifiable) == {names[i] for i in ref_dh.unidentifiable}
    assert set(info.unidentifiable) == {names[i] for i in ref_body.unidentifiable}


def test_dh_lists_are_those_of_paper_notes_and_differ_from_body_frames(built):
    name, robot, _, _, info = built
    notes = {k: v.split() for k, v in NOTES[name].items()}
    dh = info.dh_frames
    assert list(dh.independent) == notes["independent"]
    assert list(dh.dependent) == notes["dependent"]
    assert list(dh.unidentifiable) == notes["unidentifiable"]
    assert sorted(info.unidentifiable) == sorted(notes["body_unidentifiable"])
    # same rank, different names (paper-notes, difference 5)
    assert dh.counts[0] == info.counts[0]
    assert set(dh.unidentifiable) != set(info.unidentifiable)
    # true DH base values: the projection of the DH-frame true parameters, and the two
    # parameterizations explain the same torques (both bases span the same column space)
    index = [robot.parameter_names().index(n) for n in dh.standard_names]
    assert np.allclose(dh.true_standard, robot.parameters_dh()[index], rtol=1e-12, atol=0)


def test_robot_without_dh_table_has_no_dh_comparison(tmp_path):
    from ident.model import Robot

    config = load_run_config(CONFIGS / "wrist.yaml")
    robot = load_robot(config.robot)
    urdf = tmp_path / "r.urdf"
    urdf.write_text(robot.urdf_text)
    plain = Robot.from_urdf(urdf)
    stage = select_stage(plain, "wrist")
    family = make_family(config, robot, stage)
    info = build_stage_info(plain, stage, family, "qr", np.random.default_rng(0))
    assert info.dh_frames is None
    assert info.counts == (17, 4, 9)
