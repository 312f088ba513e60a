"""A stage's parameters: observation matrix, base parameters, true values, torque shares.

The base parameters of a stage are structural: found once on random states of the stage's
motion (the moving joints within their limits, the others held), they hold for almost every
trajectory; a trajectory that does not excite one shows up as a rank-deficient estimate.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.dynamics.base_parameters import compute_base_parameters, torque_shares
from ident.dynamics.stage import random_stage_states
from ident.errors import IdentError
from ident.robot.inertia import PAPER_ORDER, PINOCCHIO_ORDER
from ident.run.results import FrameBaseInfo, StageInfo, base_set_fields

__all__ = ["build_stage_info", "dh_frame_base", "stage_matrix", "stage_regressor"]

FloatArray = npt.NDArray[np.float64]

_N_STRUCTURE_SAMPLES = 500


def stage_matrix(
    robot: Any,
    rows: tuple[int, ...],
    columns: tuple[int, ...],
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Stage observation matrix and the known torque contribution of the other bodies.

    Returns
    -------
    W :
        Shape (n_samples * n_rows, n_cols), sample-major.
    known :
        Torques of the parameters outside the stage on the stage's rows, with their true
        values [N*m], shape (n_samples, n_rows).
    """
    Y = stage_regressor(robot, rows, q, dq, ddq)
    params = np.asarray(robot.parameters(), dtype=float)
    other = np.setdiff1d(np.arange(Y.shape[2]), np.asarray(columns, dtype=int))
    known = Y[:, :, other] @ params[other]
    W = Y[:, :, list(columns)].reshape(-1, len(columns))
    return W, known


def stage_regressor(
    robot: Any, rows: tuple[int, ...], q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Rows ``rows`` of the joint-torque regressor, shape (n_samples, n_rows, n_params)."""
    return np.asarray(robot.regressor(q, dq, ddq))[:, list(rows), :]


def dh_frame_base(
    robot: Any,
    rows: tuple[int, ...],
    columns: tuple[int, ...],
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
) -> FrameBaseInfo | None:
    """Base parameters of a stage about the paper's DH frames (``None`` without a DH table).

    The regressor in the DH parameterization is ``Y @ robot.dh_to_model_parameters()``
    (docs/paper-notes.md, "Eq. 14: parameter order and frames"); its stage columns are put in
    the paper's eq. 14 order per body and reduced by the paper's sequential rank test.
    """
    if getattr(robot, "dh", None) is None:
        return None
    M = np.asarray(robot.dh_to_model_parameters(), dtype=float)
    Y = stage_regressor(robot, rows, q, dq, ddq) @ M
    names_all = tuple(robot.parameter_names())
    # eq. 14 order within each body (the stage's columns are whole bodies, 10 each)
    to_paper = [PINOCCHIO_ORDER.index(label) for label in PAPER_ORDER]
    order = [c - c % 10 + to_paper[c % 10] for c in columns]
    if sorted(order) != sorted(columns):
        raise IdentError("the stage's parameter columns are not whole bodies of 10 parameters")
    W = Y[:, :, order].reshape(-1, len(order))
    names = tuple(names_all[c] for c in order)
    base = compute_base_parameters(W, names, method="sequential")
    true_standard = np.asarray(robot.parameters_dh(), dtype=float)[order]
    return FrameBaseInfo(
        frames="DH", method="sequential", **base_set_fields(base, names, true_standard)
    )


def build_stage_info(robot: Any, stage: Any, family: Any, base_method: str, rng: Any) -> StageInfo:
    """Base parameters of the stage, from random states of the stage's motion.

    The states span the moving joints' position, velocity and acceleration limits, the held
    joints sit where the family holds them; the classification is structural (it holds for
    almost every motion of the stage), and a trajectory that does not excite a base
    parameter shows up as a rank-deficient estimate, reported per elite.
    """
    names_all = tuple(robot.parameter_names())
    params = np.asarray(robot.parameters(), dtype=float)
    rows = tuple(int(r) for r in stage.torque_rows)
    columns = tuple(int(c) for c in stage.columns)
    q, dq, ddq = random_stage_states(
        robot, family.moving_joints, family.held_positions, _N_STRUCTURE_SAMPLES, rng
    )
    W, _ = stage_matrix(robot, rows, columns, q, dq, ddq)
    names = tuple(names_all[c] for c in columns)
    base = compute_base_parameters(W, names, method=base_method)
    fields = base_set_fields(base, names, params[list(columns)])
    true_base, base_names = fields["true_base"], fields["base_names"]
    reference_share = torque_shares(np.asarray(base.base_columns(W), dtype=float), true_base)
    # ident.dynamics.base_parameters suffixes "R" to a base parameter with others combined in
    alone = tuple(b == names[i] for b, i in zip(base_names, base.independent, strict=True))
    others = np.setdiff1d(np.arange(params.shape[0]), np.asarray(columns))
    known_note = (
        "all bodies are unknown in this stage"
        if others.size == 0
        else "the bodies outside the stage are known (identified in the other stage; here "
        "their true parameters): their torque contribution on the stage's rows is computed "
        "and subtracted before the estimate"
    )
    return StageInfo(
        name=str(stage.name),
        rows=rows,
        columns=columns,
        alone=alone,
        base_method=base_method,
        known_bodies_note=known_note,
        base=base,
        dh_frames=dh_frame_base(robot, rows, columns, q, dq, ddq),
        reference_share=reference_share,
        **fields,
    )
