"""URScript export: a program that streams ``servoj`` at 500 Hz (Universal Robots).

``trajectory.script`` defines and calls ``ident_trajectory()``. It first checks that the robot
stands at the trajectory's start posture (every joint within 0.01 rad, else a popup and
``halt``: the program never moves the robot to the start by itself, that motion would be
unchecked), then calls, once per 2 ms sample,

    servoj(q, 0, 0, t=0.002, lookahead_time=0.1, gain=300)

with the plan's positions resampled to 500 Hz (quintic Hermite, :func:`~ident.run.exports.
common.resample_quintic`). ``a`` and ``v`` are unused by ``servoj``. ``lookahead_time`` [s]
(0.03-0.2) smooths the trajectory with this lookahead time, ``gain`` (100-2000) is the
proportional gain of the position servo; the values are URScript's defaults (see
``docs/execute.md``: a larger gain and a shorter lookahead track more closely and ring more).

Before writing, the 500 Hz samples are checked against the model's published joint limits:
position range and maximum joint speed of the datasheet (:data:`UR_MODELS`), on the finite
differences at 2 ms (what ``servoj`` receives) as well as the plan's own velocities.
Universal Robots publishes no joint acceleration limit (its ROS description says so); the
accelerations are checked against the run's configured acceleration limits, or 5 rad/s^2 (the
value Universal Robots' ROS description carries, unenforced) when the config has none.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from ident.fileio import atomic_write_text
from ident.run.exports.common import (
    ExportError,
    ExportSamples,
    ExportTarget,
    first_violation,
    resample_quintic,
)
from ident.trajectory import JointTrajectory

__all__ = [
    "UR_MODELS",
    "URSCRIPT_FILE",
    "accepts_urscript",
    "prepare_urscript",
    "read_urscript",
    "write_urscript",
]

URSCRIPT_FILE = "trajectory.script"
RATE_HZ = 500.0
LOOKAHEAD_TIME_S = 0.1
GAIN = 300.0
START_TOLERANCE_RAD = 0.01
FALLBACK_ACCELERATION = 5.0  # rad/s^2, Universal Robots' ROS description (not enforced there)

_DEG = math.pi / 180.0
_SLOW, _FAST = 120.0 * _DEG, 180.0 * _DEG
#: Maximum joint speed [rad/s] per joint (base .. wrist 3), from the models' datasheets;
#: joint ranges are +-360 deg on every joint of these models.
UR_MODELS: dict[str, tuple[float, ...]] = {
    "ur16e": (_SLOW, _SLOW, _FAST, _FAST, _FAST, _FAST),
    "ur10e": (_SLOW, _SLOW, _FAST, _FAST, _FAST, _FAST),
    "ur5e": (_FAST,) * 6,
    "ur3e": (_FAST, _FAST, _FAST, 2 * _FAST, 2 * _FAST, 2 * _FAST),
    "ur10": (_SLOW, _SLOW, _FAST, _FAST, _FAST, _FAST),
    "ur5": (_FAST,) * 6,
    "ur3": (_FAST, _FAST, _FAST, 2 * _FAST, 2 * _FAST, 2 * _FAST),
}
Q_RANGE = 2.0 * math.pi

_SERVOJ = re.compile(r"^\s*servoj\(\[([^\]]*)\],")


def ur_model(robot_name: str) -> str:
    """The UR model named in the URDF's robot name (``ur5``, ``ur5e``, ...).

    Raises
    ------
    ExportError
        If the name names no known UR model.
    """
    name = robot_name.lower()
    for model in UR_MODELS:  # e-Series first: 'ur5e' contains 'ur5'
        if model in name:
            return model
    raise ExportError(
        f"urscript: the robot '{robot_name}' is not a Universal Robots arm the export knows "
        f"({', '.join(UR_MODELS)}, from the URDF's robot name); remove urscript from "
        "controller.export."
    )


def accepts_urscript(joint_names: tuple[str, ...], target: ExportTarget) -> str:
    """The UR model of ``target``; ExportError for a robot that is not a 6-joint UR arm."""
    model = ur_model(target.robot_name)
    if len(joint_names) != 6:
        raise ExportError(
            f"urscript: a UR arm has 6 joints, the trajectory has {len(joint_names)}; "
            "remove urscript from controller.export."
        )
    return model


def prepare_urscript(trajectory: JointTrajectory, target: ExportTarget) -> ExportSamples:
    """The plan at 500 Hz (positions only), checked against the model's limits.

    Raises
    ------
    ExportError
        For a robot that is not a known UR model, or a limit exceeded (joint, quantity, time).
    """
    model = accepts_urscript(tuple(trajectory.joint_names), target)
    resampled = resample_quintic(trajectory, RATE_HZ)
    names, t, q = resampled.joint_names, resampled.t, resampled.q
    speed = np.array(UR_MODELS[model])
    acceleration = np.full(6, FALLBACK_ACCELERATION)
    if target.ddq_max is not None and np.all(np.isfinite(target.ddq_max)):
        acceleration = np.asarray(target.ddq_max, dtype=float)
    padded = np.vstack([q[:1], q[:1], q])  # at rest at the start posture before the first call
    v = np.diff(padded, axis=0)[1:] * RATE_HZ
    a = np.diff(np.vstack([np.zeros((1, 6)), v]), axis=0) * RATE_HZ
    fix = "; slow the excitation down or lower the velocity/acceleration limits in the run config."
    for values, limit, quantity, unit in (
        (q, np.full(6, Q_RANGE), "position", "rad"),
        (v, speed, f"speed (2 ms differences; {model} datasheet)", "rad/s"),
        (resampled.dq, speed, f"speed (plan; {model} datasheet)", "rad/s"),
        (a, acceleration, "acceleration (2 ms differences)", "rad/s^2"),
    ):
        assert values is not None
        problem = first_violation(values, limit, t, names, quantity, unit)
        if problem is not None:
            raise ExportError(f"urscript: {problem}{fix}")
    return ExportSamples(t, q, None, None, names)


def _vector(values: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:.17g}" for v in values) + "]"


def write_urscript(samples: ExportSamples, folder: Path) -> list[Path]:
    """Write ``trajectory.script`` into ``folder``; return its path."""
    q0 = samples.q[0]
    lines = [
        "# ident: excitation trajectory for a Universal Robots arm, servoj at 500 Hz.",
        "# joints: " + ",".join(samples.joint_names),
        f"# {samples.n_samples} samples, {samples.t[-1]:.6g} s; lookahead_time "
        f"{LOOKAHEAD_TIME_S:g} s (0.03-0.2), gain {GAIN:g} (100-2000).",
        "def ident_trajectory():",
        f"  start = {_vector(q0)}",
        "  actual = get_actual_joint_positions()",
        "  i = 0",
        "  while i < 6:",
        f"    if norm(actual[i] - start[i]) > {START_TOLERANCE_RAD:g}:",
        '      popup("ident: move the robot to the trajectory start posture first", '
        "error=True, blocking=True)",
        "      halt",
        "    end",
        "    i = i + 1",
        "  end",
    ]
    lines += [
        f"  servoj({_vector(q)}, 0, 0, {1.0 / RATE_HZ:g}, {LOOKAHEAD_TIME_S:g}, {GAIN:g})"
        for q in samples.q
    ]
    lines += ["  stopj(2.0)", "end", "ident_trajectory()"]
    path = folder / URSCRIPT_FILE
    atomic_write_text(path, "\n".join(lines) + "\n")
    return [path]


def read_urscript(path: Path) -> ExportSamples:
    """The ``servoj`` targets of a program written by :func:`write_urscript`, at 500 Hz."""
    names: tuple[str, ...] = ()
    rows = []
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("# joints: "):
            names = tuple(line.removeprefix("# joints: ").split(","))
        match = _SERVOJ.match(line)
        if match:
            rows.append([float(v) for v in match.group(1).split(",")])
    q = np.array(rows, dtype=float).reshape(len(rows), -1)
    return ExportSamples(np.arange(q.shape[0]) / RATE_HZ, q, None, None, names)
