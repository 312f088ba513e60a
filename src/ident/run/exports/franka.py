"""Franka (Panda) export: joint positions at 1 kHz for libfranka's joint position interface.

The file ``franka_q_1khz.csv`` holds one line per millisecond, ``q1,...,q7`` [rad] (17
significant digits), after ``#`` comment lines that name the joints; line ``k`` is the command
of the control callback at ``t = k * 1 ms`` (the first line is the start posture, where the
robot must stand). ``docs/execute.md`` has a C++ snippet that reads it into
``franka::JointPositions``.

Before writing, the positions are checked as libfranka's ``limitRate`` for joint positions
would see them (``src/rate_limiting.cpp`` of libfranka 0.8, Panda limits of
``include/franka/rate_limiting.h``): from the robot at rest, the finite differences at 1 kHz

- ``v_k = (q_k - q_{k-1}) / 1 ms``, ``a_k = (v_k - v_{k-1}) / 1 ms``,
  ``j_k = (a_k - a_{k-1}) / 1 ms``

must pass ``limitRate`` unchanged: ``|j_k| <= kMaxJointJerk`` and ``a_k`` within
``[max(-A, (J/A)(-V - v_{k-1})), min(A, (J/A)(V - v_{k-1}))]`` with ``V = kMaxJointVelocity``,
``A = kMaxJointAcceleration``, ``J = kMaxJointJerk``: zero clipping. The positions must lie
within the Panda's joint ranges (Franka's "control parameters" page). A violation refuses the
export with the joint, the quantity and the time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ident.fileio import atomic_write_text
from ident.run.exports.common import (
    ExportError,
    ExportSamples,
    ExportTarget,
    FloatArray,
    first_violation,
    resample_quintic,
)
from ident.trajectory import JointTrajectory

__all__ = [
    "FRANKA_FILE",
    "PANDA_ACCELERATION",
    "PANDA_JERK",
    "PANDA_Q_MAX",
    "PANDA_Q_MIN",
    "accepts_franka",
    "PANDA_VELOCITY",
    "check_franka",
    "limit_rate_bounds",
    "prepare_franka",
    "read_franka",
    "write_franka",
]

FRANKA_FILE = "franka_q_1khz.csv"
RATE_HZ = 1000.0
DELTA_T = 1e-3  # libfranka's kDeltaT [s]
_LIMIT_EPS = 1e-3  # libfranka's kLimitEps
_PACKETS_LOST = 3.0  # libfranka's kTolNumberPacketsLost

#: kMaxJointJerk [rad/s^3] (libfranka 0.8, include/franka/rate_limiting.h)
PANDA_JERK = np.array([7500.0, 3750.0, 5000.0, 6250.0, 7500.0, 10000.0, 10000.0]) - _LIMIT_EPS
#: kMaxJointAcceleration [rad/s^2]
PANDA_ACCELERATION = np.array([15.0, 7.5, 10.0, 12.5, 15.0, 20.0, 20.0]) - _LIMIT_EPS
#: kMaxJointVelocity [rad/s]: the published 2.175 / 2.61 rad/s less the margin for 3 lost packets
PANDA_VELOCITY = (
    np.array([2.1750, 2.1750, 2.1750, 2.1750, 2.6100, 2.6100, 2.6100])
    - _LIMIT_EPS
    - _PACKETS_LOST * DELTA_T * PANDA_ACCELERATION
)
#: Joint ranges [rad] (Franka documentation, "Robot and interface specifications")
PANDA_Q_MAX = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973])
PANDA_Q_MIN = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973])


def finite_differences(q: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Velocity, acceleration and jerk libfranka derives from commands ``q`` at 1 kHz.

    The robot is at rest at ``q[0]`` before the first command (two earlier commands equal to
    ``q[0]``). Each output has the shape of ``q`` (n_samples, 7); row ``k`` belongs to
    command ``k``.
    """
    padded = np.vstack([q[:1], q[:1], q[:1], q])
    v = np.diff(padded, axis=0) / DELTA_T
    a = np.diff(v, axis=0) / DELTA_T
    j = np.diff(a, axis=0) / DELTA_T
    return v[2:], a[1:], j


def limit_rate_bounds(v_previous: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The acceleration interval ``limitRate`` allows after velocity ``v_previous`` [rad/s].

    ``[max(-A, (J/A)(-V - v)), min(A, (J/A)(V - v))]`` per joint, shapes like ``v_previous``.
    """
    ratio = PANDA_JERK / PANDA_ACCELERATION
    upper = np.minimum(ratio * (PANDA_VELOCITY - v_previous), PANDA_ACCELERATION)
    lower = np.maximum(ratio * (-PANDA_VELOCITY - v_previous), -PANDA_ACCELERATION)
    return lower, upper


def accepts_franka(joint_names: tuple[str, ...], target: ExportTarget | None = None) -> None:
    """Refuse a robot that is not a 7-joint arm (libfranka commands 7 joints)."""
    if len(joint_names) != 7:
        raise ExportError(
            f"franka: libfranka commands 7 joints, the trajectory has {len(joint_names)} "
            f"({', '.join(joint_names)}); remove franka from controller.export."
        )


def check_franka(samples: ExportSamples) -> None:
    """Refuse commands that libfranka's ``limitRate`` would change (module docstring).

    Raises
    ------
    ExportError
        Naming the joint, the quantity, its value, the limit and the time.
    """
    names, t, q = samples.joint_names, samples.t, samples.q
    accepts_franka(names)
    slower = "lower excitation.options.amplitude_bound or base_frequency"
    fix = {
        "position": "; give the URDF the Panda's joint ranges, or move the excitation's mean "
        "posture (excitation.bounds q0[...])",
        "velocity": f"; the run keeps the URDF's <limit velocity>, libfranka's is lower (a "
        f"margin for 3 lost packets): lower it in the URDF to the values of docs/execute.md, "
        f"or {slower}",
        "acceleration": f"; set robot.acceleration_limits to libfranka's (docs/execute.md), "
        f"or {slower}",
        "jerk": f"; {slower} (the jerk grows with the cube of the frequency)",
    }
    over = np.argwhere(q > PANDA_Q_MAX)
    if over.size:
        k, j = over[0]
        raise ExportError(
            f"franka: joint {names[j]!r} position {q[k, j]:.6g} rad is above the Panda's "
            f"maximum {PANDA_Q_MAX[j]:.6g} rad at t = {t[k]:.6g} s{fix['position']}."
        )
    under = np.argwhere(q < PANDA_Q_MIN)
    if under.size:
        k, j = under[0]
        raise ExportError(
            f"franka: joint {names[j]!r} position {q[k, j]:.6g} rad is below the Panda's "
            f"minimum {PANDA_Q_MIN[j]:.6g} rad at t = {t[k]:.6g} s{fix['position']}."
        )
    v, a, jerk = finite_differences(q)
    for values, limit, quantity, unit in (
        (v, PANDA_VELOCITY, "velocity", "rad/s"),
        (jerk, PANDA_JERK, "jerk", "rad/s^3"),
    ):
        problem = first_violation(values, limit, t, names, quantity, unit)
        if problem is not None:
            raise ExportError(
                f"franka: libfranka's limitRate would clip: {problem}{fix[quantity]}."
            )
    v_previous = np.vstack([np.zeros((1, q.shape[1])), v[:-1]])
    lower, upper = limit_rate_bounds(v_previous)
    bad = (a > upper) | (a < lower)
    if bad.any():
        k, j = np.argwhere(bad)[0]
        # within A but not within (J/A)(V - v): the velocity comes too close to its limit
        hint = fix["acceleration"] if abs(a[k, j]) > PANDA_ACCELERATION[j] else fix["velocity"]
        raise ExportError(
            f"franka: libfranka's limitRate would clip: joint {names[j]!r} acceleration "
            f"{a[k, j]:.6g} rad/s^2 is outside [{lower[k, j]:.6g}, {upper[k, j]:.6g}] rad/s^2 "
            f"(the limit {PANDA_ACCELERATION[j]:.6g} rad/s^2, reduced near the velocity limit "
            f"{PANDA_VELOCITY[j]:.6g} rad/s) at t = {t[k]:.6g} s{hint}."
        )


def prepare_franka(trajectory: JointTrajectory, target: ExportTarget) -> ExportSamples:
    """The plan at 1 kHz (positions only), checked by :func:`check_franka`."""
    resampled = resample_quintic(trajectory, RATE_HZ)
    samples = ExportSamples(resampled.t, resampled.q, None, None, resampled.joint_names)
    check_franka(samples)
    return samples


def write_franka(samples: ExportSamples, folder: Path) -> list[Path]:
    """Write ``franka_q_1khz.csv`` into ``folder``; return its path."""
    header = [
        "# ident: joint positions [rad] for libfranka's joint position interface, 1 kHz",
        "# line k (after these comments) is the command at t = k ms; line 0 is the start",
        "# posture, where the robot must stand before the control loop starts.",
        "# joints: " + ",".join(samples.joint_names),
    ]
    rows = [",".join(f"{value:.17g}" for value in row) for row in samples.q]
    path = folder / FRANKA_FILE
    atomic_write_text(path, "\n".join(header + rows) + "\n")
    return [path]


def read_franka(path: Path) -> ExportSamples:
    """Read a file written by :func:`write_franka` back (positions, ``t = k ms``)."""
    names: tuple[str, ...] = ()
    with path.open(encoding="utf-8") as f:
        for line in f:
            if not line.startswith("#"):
                break
            if line.startswith("# joints: "):
                names = tuple(line.removeprefix("# joints: ").strip().split(","))
    q = np.loadtxt(path, delimiter=",", comments="#", ndmin=2)
    return ExportSamples(np.arange(q.shape[0]) / RATE_HZ, q, None, None, names)
