"""The payload excitation family: a short motion of the last joints, the arm held still.

A payload rigidly attached to the last moving link adds its 10 standard parameters to that
body's (``docs/payload.md``), so the torques see it through the last body's 10 regressor
columns, on *every* joint's row: a held joint feels the payload's gravity and inertial forces
too. The design therefore targets the **payload stage**
(:func:`ident.dynamics.stage.payload_stage`, ``stage: payload``): torque rows of all joints,
the last body's 10 columns as the unknowns, and the objective (eq. 15 or log-det on the scaled
Gram matrix, :class:`ident.excitation.objective.ExcitationObjective`) is the conditioning of
those payload columns, not of the whole arm's base parameters.

The motion is the joint-space Fourier series of :class:`ident.excitation.fourier.
JointFourierFamily` on the last ``n_moving`` joints (default: those the stage moves, the last
three), the other joints held at a posture the user chooses (``held``), with payload defaults:

- a short period (``base_frequency`` 2 pi / 5 s: 5 s per period),
- 4 harmonics,
- coefficient bounds that keep every design of the box within the joints' velocity and
  acceleration limits (:meth:`JointFourierFamily.amplitude_limits`, at most half the velocity
  limit), so the optimizer searches the safe motions only.

The payload's bounding box joins the collision model through ``safety.payload_box``
(:class:`ident.excitation.safety.PayloadBox`); the dense certificate then checks it against the
floor, the obstacles and the arm's links.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ident.dynamics.stage import Stage
from ident.errors import ConfigError
from ident.excitation.family import FloatArray
from ident.excitation.fourier import JointFourierFamily

__all__ = ["PAYLOAD_PERIOD_S", "build_payload_family", "is_payload_stage"]

#: Default period of the payload excitation [s]: short, a few orientations of the payload.
PAYLOAD_PERIOD_S = 5.0


def is_payload_stage(stage: Stage, n_joints: int) -> bool:
    """True when ``stage`` uses every joint's torque and identifies only the last body."""
    return tuple(stage.bodies) == (n_joints - 1,) and tuple(stage.torque_rows) == tuple(
        range(n_joints)
    )


def build_payload_family(robot: Any, stage: Stage, options: dict[str, Any]) -> JointFourierFamily:
    """The ``payload`` family of the registry (see the module docstring).

    Parameters
    ----------
    robot :
        An :class:`ident.Robot`.
    stage :
        The payload stage (``stage: payload``).
    options :
        ``excitation.options``: ``n_moving`` (the last joints that move; default the stage's
        moving joints), ``held`` (``{joint: position}`` [rad or m] of held joints; default
        the stage's), and any option of :class:`JointFourierFamily` except ``moving_joints``
        and ``held_positions``.

    Raises
    ------
    ConfigError
        If the stage is not the payload stage (the objective would not be the payload's).
    ValueError
        For a bad ``n_moving``, an unknown joint in ``held``, or a moving joint in ``held``.
    TypeError
        For an unknown option.
    """
    names = tuple(robot.joint_names)
    n = len(names)
    if not is_payload_stage(stage, n):
        raise ConfigError(
            "excitation.family 'payload' designs for the payload's 10 parameters (the last "
            f"body's columns on every joint's torque), but stage is '{stage.name}'; use "
            "stage: payload."
        )
    for key in ("moving_joints", "held_positions"):
        if key in options:
            raise TypeError(f"option {key!r} is not one of the payload family's; use n_moving/held")
    n_moving = int(options.pop("n_moving", len(stage.moving_joints)))
    if not 1 <= n_moving <= n:
        raise ValueError(f"options.n_moving = {n_moving}: give 1 to {n} (the last joints)")
    moving = tuple(range(n - n_moving, n))
    positions = _held_positions(stage, names, moving, options.pop("held", None) or {})
    options.setdefault("n_harmonics", 4)
    options.setdefault("base_frequency", 2.0 * np.pi / PAYLOAD_PERIOD_S)
    family = JointFourierFamily(robot, moving, held_positions=positions, **options)
    if "amplitude_bound" not in options:  # every design of the box within the limits
        within = family.amplitude_limits()
        dq_max = family.limits.dq_max[list(moving)]
        half = np.where(np.isfinite(dq_max), 0.5 * dq_max, 1.0)
        bound = np.where(np.isfinite(within), np.minimum(within, half), half)
        family = JointFourierFamily(
            robot, moving, held_positions=positions, amplitude_bound=bound, **options
        )
    return family


def _held_positions(
    stage: Stage, names: tuple[str, ...], moving: tuple[int, ...], held: Any
) -> FloatArray:
    """Positions (nq,) [rad or m] of the joints: the stage's, with ``options.held``'s
    ``{joint: position}`` over them; raises ``ValueError`` for a bad mapping, an unknown or a
    moving joint."""
    positions = np.asarray(stage.held_positions, dtype=float).copy()
    if not isinstance(held, Mapping):
        raise ValueError(f"options.held must map joint names to positions [rad], got {held!r}")
    for joint, value in held.items():
        if joint not in names:
            raise ValueError(f"options.held: {joint!r} is not a joint; joints: {', '.join(names)}")
        if names.index(joint) in moving:
            raise ValueError(
                f"options.held: {joint!r} moves (the last {len(moving)} joints move); hold it "
                "by lowering n_moving, or leave it out"
            )
        positions[names.index(joint)] = float(value)
    return positions
