"""Identification stages: a subset of moving joints, torque rows and unknown bodies.

The paper identifies a 6-joint arm in two stages: first the wrist (joints 4-6 move, the arm
joints 1-3 are held still, torques 4-6 are used, the parameters of bodies 4-6 are unknown),
then the arm (joints 1-3 move with the wrist held, torques 1-3, bodies 1-3 unknown; the
wrist's parameters are known from the first stage, so its torque contribution is subtracted
and its columns are not part of this stage's observation matrix).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ident.dynamics.chain import FloatArray, IntArray, KinematicChain
from ident.errors import DataError, ModelError

__all__ = [
    "Stage",
    "HELD_FRACTION",
    "default_held_positions",
    "paper_stages",
    "stage_observation_matrix",
    "stage_states",
]


@dataclass(frozen=True)
class Stage:
    """One identification stage.

    Attributes
    ----------
    name :
        Label, e.g. ``"wrist"``.
    moving_joints :
        0-based indices of the joints that move.
    torque_rows :
        0-based rows of ``tau`` (joints) whose torques are used.
    bodies :
        0-based bodies whose parameters are unknown in this stage.
    held_positions :
        Position of every joint [rad or m], length nq; only the entries of joints that do
        not move are used.
    """

    name: str
    moving_joints: tuple[int, ...]
    torque_rows: tuple[int, ...]
    bodies: tuple[int, ...]
    held_positions: tuple[float, ...]

    @property
    def columns(self) -> IntArray:
        """Parameter columns of :attr:`bodies` (10 per body, in body order)."""
        return np.array([10 * b + k for b in self.bodies for k in range(10)], dtype=np.intp)

    @property
    def held_joints(self) -> tuple[int, ...]:
        """Joints that do not move in this stage."""
        return tuple(j for j in range(len(self.held_positions)) if j not in self.moving_joints)


# Fraction of each joint's range at which held joints sit by default (golden-ratio conjugate).
HELD_FRACTION = (np.sqrt(5.0) - 1.0) / 2.0


def default_held_positions(chain: KinematicChain) -> FloatArray:
    """Default positions of held joints [rad or m], shape (n,).

    ``lower + HELD_FRACTION * (upper - lower)`` with ``HELD_FRACTION = 0.618...``; where a
    limit is unknown, the range is ``[-pi, pi]`` rad or ``[-1, 1]`` m. Not the middle of the
    range: mid-range angles are typically 0 or +-90 deg, poses where a joint axis can be
    parallel to gravity and a stage loses base parameters (for example the paper robot's wrist
    stage loses two when the arm holds the joint-4 axis vertical). An irrational fraction of the
    range avoids such special poses without a random draw.
    """
    lower, upper = chain.position_box()
    return lower + HELD_FRACTION * (upper - lower)


def paper_stages(
    chain: KinematicChain, held_positions: Sequence[float] | None = None
) -> dict[str, Stage]:
    """The paper's two stages of a 6-joint arm: ``"wrist"`` (joints, rows and bodies 4-6,
    arm held) and ``"arm"`` (1-3, wrist held).

    Parameters
    ----------
    chain :
        A 6-joint serial chain.
    held_positions :
        Positions of all six joints [rad or m] at which non-moving joints are held; default
        0.618 of each joint's range (:func:`default_held_positions`).

    Raises
    ------
    ModelError
        If the chain does not have 6 joints.
    """
    if chain.n_joints != 6:
        raise ModelError(
            f"the paper's wrist/arm stages need a 6-joint arm, this chain has {chain.n_joints} "
            "joints; define the stages with ident.dynamics.stage.Stage"
        )
    held = default_held_positions(chain) if held_positions is None else np.asarray(held_positions)
    if held.shape != (6,):
        raise DataError(f"held_positions must have 6 entries, got shape {held.shape}")
    held_tuple = tuple(float(x) for x in held)
    wrist, arm = (3, 4, 5), (0, 1, 2)
    return {
        "wrist": Stage("wrist", wrist, wrist, wrist, held_tuple),
        "arm": Stage("arm", arm, arm, arm, held_tuple),
    }


def stage_states(
    stage: Stage,
    q_moving: FloatArray,
    dq_moving: FloatArray,
    ddq_moving: FloatArray,
    nq: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Full states of a stage: held joints fixed at rest, moving joints as given.

    Parameters
    ----------
    stage :
        The stage.
    q_moving, dq_moving, ddq_moving :
        States of the moving joints, each of shape (n_samples, len(moving_joints)).
    nq :
        Number of joints of the robot.

    Returns
    -------
    :
        ``q, dq, ddq`` of shape (n_samples, nq): held joints at ``held_positions`` with zero
        velocity and acceleration.
    """
    if len(stage.held_positions) != nq:
        raise DataError(f"stage {stage.name!r} holds {len(stage.held_positions)} joints, nq={nq}")
    moving = list(stage.moving_joints)
    arrays = [np.atleast_2d(np.asarray(x, dtype=float)) for x in (q_moving, dq_moving, ddq_moving)]
    for label, x in zip(("q_moving", "dq_moving", "ddq_moving"), arrays, strict=True):
        if x.ndim != 2 or x.shape[1] != len(moving) or x.shape[0] != arrays[0].shape[0]:
            raise DataError(
                f"{label} must have shape (n_samples, {len(moving)}) for stage {stage.name!r}, "
                f"got {x.shape}"
            )
    n_samples = arrays[0].shape[0]
    q = np.tile(np.asarray(stage.held_positions, dtype=float), (n_samples, 1))
    dq = np.zeros((n_samples, nq))
    ddq = np.zeros((n_samples, nq))
    q[:, moving], dq[:, moving], ddq[:, moving] = arrays
    return q, dq, ddq


def stage_observation_matrix(
    chain: KinematicChain, stage: Stage, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Stacked observation matrix of a stage.

    Parameters
    ----------
    chain :
        Kinematic chain.
    stage :
        The stage (rows and columns kept).
    q, dq, ddq :
        Full states, shape (n_samples, nq) (see :func:`stage_states`).

    Returns
    -------
    :
        ``W`` of shape (n_samples * len(torque_rows), len(columns)); sample-major: row
        ``k * len(torque_rows) + r`` is joint ``torque_rows[r]`` at sample ``k``.
    """
    from ident.dynamics.gram import selected_rows

    return selected_rows(chain, q, dq, ddq, rows=stage.torque_rows, columns=stage.columns)
