"""Identification stages: a subset of moving joints, torque rows and unknown bodies.

The paper identifies a 6-joint arm in two stages: first the wrist (joints 4-6 move, the arm
joints 1-3 are held still, torques 4-6 are used, the parameters of bodies 4-6 are unknown),
then the arm (joints 1-3 move with the wrist held, torques 1-3, bodies 1-3 unknown; the
wrist's parameters are known from the first stage, so its torque contribution is subtracted
and its columns are not part of this stage's observation matrix).
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ident.dynamics.chain import FloatArray, IntArray, KinematicChain
from ident.dynamics.gram import selected_rows
from ident.errors import DataError, ModelError

__all__ = [
    "HELD_FRACTION",
    "STAGE_PRESETS",
    "Stage",
    "custom_stage",
    "default_held_positions",
    "paper_stages",
    "payload_stage",
    "random_stage_states",
    "select_stage",
    "spherical_wrist_gap",
    "stage_observation_matrix",
    "stage_states",
    "whole_chain_stage",
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


def whole_chain_stage(chain: KinematicChain) -> Stage:
    """Every joint moves, every torque is used, every body is unknown: what most users do."""
    every = tuple(range(chain.n_joints))
    held = tuple(float(x) for x in default_held_positions(chain))
    return Stage("whole", every, every, tuple(range(chain.n_bodies)), held)


def payload_stage(chain: KinematicChain, n_moving: int = 3) -> Stage:
    """The payload's stage: the last ``n_moving`` joints move (fewer on a shorter chain), every
    joint's torque is used (a held joint feels the payload too), only the last body is unknown
    (a payload adds its 10 parameters to it; the other bodies are known)."""
    n = chain.n_joints
    moving = tuple(range(max(0, n - n_moving), n))
    held = tuple(float(x) for x in default_held_positions(chain))
    return Stage("payload", moving, tuple(range(n)), (chain.n_bodies - 1,), held)


def custom_stage(
    chain: KinematicChain,
    moving: Sequence[str],
    *,
    held: dict[str, float] | None = None,
    bodies: Sequence[str] | None = None,
    name: str = "custom",
) -> Stage:
    """A stage named by joints: ``moving`` joints move and give their torques.

    Parameters
    ----------
    chain :
        The robot's chain.
    moving :
        Names of the joints that move (their torque rows are used).
    held :
        Positions [rad or m] of held joints; others sit at :func:`default_held_positions`.
    bodies :
        Joints whose bodies are unknown; default: the body of every joint from the first
        moving one to the tip (the bodies whose parameters the moving joints' torques see).
        Bodies left out are known: their true (nominal) parameters are used.

    Raises
    ------
    ModelError
        For unknown joint names (the message lists the joints), a held position for a
        moving joint, or no moving joint.
    """
    names = list(chain.joint_names)

    def index(joint: str, key: str) -> int:
        if joint not in names:
            close = difflib.get_close_matches(joint, names, n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ModelError(
                f"stage.{key}: {joint!r} is not a joint of the chain; {hint}joints: "
                f"{', '.join(names)}."
            )
        return names.index(joint)

    moving_idx = tuple(sorted({index(j, "moving") for j in moving}))
    if not moving_idx:
        raise ModelError("stage.moving: name at least one joint that moves.")
    positions = default_held_positions(chain).copy()
    for joint, value in (held or {}).items():
        j = index(joint, "held")
        if j in moving_idx:
            raise ModelError(f"stage.held: joint {joint!r} moves in this stage; hold it or not.")
        positions[j] = float(value)
    # bodies by the joint that moves them (a mimic joint's body too)
    first = chain.body_names.index(names[moving_idx[0]])
    if bodies is None:
        body_idx = tuple(range(first, chain.n_bodies))
    else:
        body_idx = tuple(sorted({_body_index(chain, j) for j in bodies}))
    return Stage(name, moving_idx, moving_idx, body_idx, tuple(float(x) for x in positions))


def spherical_wrist_gap(model: object, rng: int = 0) -> float:
    """Largest distance [m] from the last three joint axes to their common point.

    Zero (to round-off) for a wrist-partitioned 6R arm, whose last three axes intersect in one
    point (the paper's geometry); evaluated at a few random postures, so a coincidence at
    one posture does not count.
    """
    data = model.createData()  # type: ignore[attr-defined]
    gen = np.random.default_rng(rng)
    worst = 0.0
    for _ in range(3):
        q = gen.uniform(-np.pi, np.pi, model.nq)  # type: ignore[attr-defined]
        pin.computeJointJacobians(model, data, q)
        points, directions = [], []
        for j in range(model.njoints - 3, model.njoints):  # type: ignore[attr-defined]
            jacobian = pin.getJointJacobian(model, data, j, pin.ReferenceFrame.WORLD)
            points.append(data.oMi[j].translation)
            directions.append(jacobian[3:, model.joints[j].idx_v])  # type: ignore[attr-defined]
        # least-squares point closest to the three lines
        A = np.zeros((3, 3))
        b = np.zeros(3)
        for p, d in zip(points, directions, strict=True):
            d = d / np.linalg.norm(d)
            P = np.eye(3) - np.outer(d, d)
            A += P
            b += P @ p
        x = np.linalg.lstsq(A, b, rcond=None)[0]
        for p, d in zip(points, directions, strict=True):
            d = d / np.linalg.norm(d)
            r = (x - p) - d * ((x - p) @ d)
            worst = max(worst, float(np.linalg.norm(r)))
    return worst


#: Stage names a config may use; ``wrist`` and ``arm`` are the paper's two stages.
STAGE_PRESETS = ("whole", "payload", "wrist", "arm")


def _body_index(chain: KinematicChain, joint: str) -> int:
    """The body moved by ``joint`` (an independent or a mimic joint of the chain)."""
    if joint not in chain.body_names:
        close = difflib.get_close_matches(joint, chain.body_names, n=1)
        hint = f"did you mean '{close[0]}'? " if close else ""
        raise ModelError(
            f"stage.bodies: {joint!r} is not a joint of the chain; {hint}joints: "
            f"{', '.join(chain.body_names)}."
        )
    return chain.body_names.index(joint)


def select_stage(robot: object, spec: str | dict) -> Stage:
    """The stage a config asks for: a preset name or ``{moving, held, bodies}``.

    ``whole`` (the default of the configs) identifies every body with every joint moving.
    ``payload`` identifies the last body from every joint's torque, the last three joints
    moving (:func:`payload_stage`; the ``payload`` excitation family designs for it).
    ``wrist`` and ``arm`` are the paper's two stages; they need a 6R arm whose last three
    axes intersect (a spherical wrist), where the wrist's torques do not depend on the arm's
    bodies.

    Raises
    ------
    ModelError
        For an unknown preset, or a paper stage on another geometry.
    """
    chain = robot.chain  # type: ignore[attr-defined]
    if isinstance(spec, dict):
        return custom_stage(chain, **spec)
    if spec == "whole":
        return whole_chain_stage(chain)
    if spec == "payload":
        return payload_stage(chain)
    if spec not in STAGE_PRESETS:
        raise ModelError(
            f"stage {spec!r} is unknown; presets: {', '.join(STAGE_PRESETS)}, or give "
            "{moving: [joints], held: {joint: position}, bodies: [joints]}."
        )
    if chain.n_joints != 6 or chain.coupled:
        mimic = f" and {chain.n_bodies - chain.n_joints} mimic joints" if chain.coupled else ""
        raise ModelError(
            f"stage {spec!r} is the paper's, for a 6R arm with a spherical wrist; this chain has "
            f"{chain.n_joints} joints{mimic}. Use stage: whole (every joint), or a custom stage."
        )
    gap = spherical_wrist_gap(robot.model)  # type: ignore[attr-defined]
    if gap > 1e-6:
        raise ModelError(
            f"stage {spec!r} is the paper's, for a 6R arm with a spherical wrist; the last three "
            f"axes of this robot miss a common point by {gap * 1e3:.1f} mm, so the wrist's "
            "torques depend on the arm's bodies. Use stage: whole, or a custom stage."
        )
    return paper_stages(chain)[spec]


def random_stage_states(
    robot: object,
    moving_joints: Sequence[int],
    held_positions: Sequence[float],
    n_samples: int,
    rng: np.random.Generator | int | None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Random states of a stage's motion: moving joints uniform within the robot's limits
    (:meth:`ident.model.Robot.random_configurations`), the others held at rest.

    Returns
    -------
    :
        ``q, dq, ddq``, each of shape (n_samples, nq).
    """
    q, dq, ddq = robot.random_configurations(n_samples, rng=rng)  # type: ignore[attr-defined]
    moving = np.zeros(q.shape[1], dtype=bool)
    moving[list(moving_joints)] = True
    q = np.where(moving, q, np.asarray(held_positions, dtype=float))
    return q, np.where(moving, dq, 0.0), np.where(moving, ddq, 0.0)


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
    return selected_rows(chain, q, dq, ddq, rows=stage.torque_rows, columns=stage.columns)
