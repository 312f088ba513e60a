"""What every export shares: the target robot, the samples a file holds, resampling, checks.

An export turns the run's executable trajectory (:func:`ident.excitation.executable.
executable_trajectory`: approach, periods, return, at ``controller.rate_hz``) into the samples a
controller reads (:class:`ExportSamples`), checks them against the controller's own rules,
writes them, reads the file back and compares it with the samples (:func:`compare_samples`).

Resampling to a controller's fixed rate (URScript 500 Hz, libfranka 1 kHz) uses, joint by
joint, the quintic Hermite spline through the plan's positions, velocities and accelerations
(:func:`resample_quintic`): C2, and exact at the plan's own samples and for the quintic
transitions of the approach and the return.
"""

from __future__ import annotations

import math

# xml.etree: robot.urdf parsed independently of Pinocchio, a malformed file must be refused
# (ExportError); yourdfpy.URDF.load re-parses malformed XML with lxml recover=True (checked: a
# truncated file loads) and expands DTD entities (checked).
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.errors import IdentError
from ident.trajectory import JointTrajectory

__all__ = [
    "REREAD_TOLERANCE",
    "ExportError",
    "ExportSamples",
    "ExportTarget",
    "UrdfJoint",
    "compare_samples",
    "compare_with_plan",
    "first_violation",
    "quintic_hermite",
    "resample_quintic",
    "target_from_urdf",
]

FloatArray = npt.NDArray[np.float64]

#: Largest difference [s, rad, rad/s, rad/s^2] between a re-read file and the samples written.
REREAD_TOLERANCE = 1e-9

_MOVABLE = ("revolute", "continuous", "prismatic")


class ExportError(IdentError):
    """An export breaks its controller's rules, or its file does not read back as written."""


@dataclass(frozen=True)
class UrdfJoint:
    """A movable joint of the URDF: name, type and ``<limit>`` (NaN where absent)."""

    name: str
    kind: str
    lower: float
    upper: float
    velocity: float


@dataclass(frozen=True, eq=False)
class ExportTarget:
    """The robot an export is for.

    Attributes
    ----------
    robot_name :
        The URDF's ``<robot name=...>``.
    urdf_joints :
        The URDF's movable joints (revolute, continuous, prismatic) in file order.
    ddq_max :
        The run's acceleration limits [rad/s^2] per trajectory joint, shape (n_joints,), or
        None (used where the controller's maker publishes none: UR).
    """

    robot_name: str
    urdf_joints: tuple[UrdfJoint, ...]
    ddq_max: FloatArray | None = None

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the URDF's movable joints, in file order."""
        return tuple(j.name for j in self.urdf_joints)


def target_from_urdf(urdf_text: str, ddq_max: npt.ArrayLike | None = None) -> ExportTarget:
    """The export target of a URDF text (parsed directly, independently of Pinocchio).

    Raises
    ------
    ExportError
        If the text is not a URDF.
    """
    try:
        root = ET.fromstring(urdf_text)
    except ET.ParseError as e:
        raise ExportError(f"robot.urdf is not valid XML ({e}); cannot name the joints.") from e
    if root.tag != "robot":
        raise ExportError(f"robot.urdf: the root element is <{root.tag}>, not <robot>.")
    joints = []
    for element in root.iter("joint"):
        kind = element.get("type", "")
        if kind not in _MOVABLE:
            continue
        limit = element.find("limit")

        def value(key: str, limit: ET.Element | None = limit) -> float:
            text = None if limit is None else limit.get(key)
            return float(text) if text is not None else math.nan

        lower, upper = value("lower"), value("upper")
        if kind == "continuous":
            lower, upper = -math.inf, math.inf
        joints.append(UrdfJoint(element.get("name", ""), kind, lower, upper, value("velocity")))
    limits = None if ddq_max is None else np.asarray(ddq_max, dtype=float)
    return ExportTarget(root.get("name", ""), tuple(joints), limits)


@dataclass(frozen=True, eq=False)
class ExportSamples:
    """The samples one export file holds.

    Attributes
    ----------
    t :
        Time from the start [s], shape (n_samples,), increasing.
    q :
        Positions [rad or m], shape (n_samples, n_joints).
    dq, ddq :
        Velocities [rad/s] and accelerations [rad/s^2], same shape, or None when the format
        carries positions only.
    joint_names :
        Joint names, column order.
    """

    t: FloatArray
    q: FloatArray
    dq: FloatArray | None
    ddq: FloatArray | None
    joint_names: tuple[str, ...]

    @property
    def n_samples(self) -> int:
        """Number of samples."""
        return int(self.t.shape[0])


def resample_quintic(trajectory: JointTrajectory, rate_hz: float) -> ExportSamples:
    """The trajectory on the grid ``k / rate_hz`` by quintic Hermite interpolation.

    Parameters
    ----------
    trajectory :
        The plan: ``t`` [s] from 0, ``q, dq, ddq`` of shape (n_samples, n_joints); it must end
        at rest (as the executable trajectory does: the return ends at home).
    rate_hz :
        The controller's rate [Hz].

    Returns
    -------
    :
        ``k / rate_hz`` for ``k = 0 .. ceil(t_end * rate_hz)``: the last sample is the first
        grid point at or after the plan's end, where the robot rests at the final posture
        (held: zero velocity and acceleration). Positions, velocities, accelerations.

    Raises
    ------
    ExportError
        If the grid runs past a plan that does not end at rest.

    Notes
    -----
    When the plan is already on that grid (to 1e-12 s) its samples are returned unchanged.
    """
    t = np.asarray(trajectory.t, dtype=float)
    n = int(math.ceil(t[-1] * rate_hz - 1e-9)) + 1
    grid = np.arange(n) / rate_hz
    names = tuple(trajectory.joint_names)
    if n == t.shape[0] and np.max(np.abs(grid - t)) <= 1e-12:
        return ExportSamples(
            grid, trajectory.q.copy(), trajectory.dq.copy(), trajectory.ddq.copy(), names
        )
    inside = grid <= t[-1]
    resting = max(np.max(np.abs(trajectory.dq[-1])), np.max(np.abs(trajectory.ddq[-1])))
    if not inside.all() and not resting <= 1e-9:
        raise ExportError(
            f"the trajectory ends in motion (|dq|, |ddq| up to {resting:.3g}) between two "
            f"samples of the {rate_hz:g} Hz grid; an export needs it to end at rest."
        )
    out = [np.empty((n, trajectory.q.shape[1])) for _ in range(3)]
    for order, values in enumerate(
        quintic_hermite(t, trajectory.q, trajectory.dq, trajectory.ddq, grid[inside])
    ):
        out[order][inside] = values
    # past the plan's end the robot rests at its final posture
    out[0][~inside] = trajectory.q[-1]
    out[1][~inside] = 0.0
    out[2][~inside] = 0.0
    return ExportSamples(grid, out[0], out[1], out[2], names)


def quintic_hermite(
    t: FloatArray, q: FloatArray, dq: FloatArray, ddq: FloatArray, times: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The piecewise quintic through ``(q, dq, ddq)`` at the samples ``t``, at ``times``.

    On each interval ``[t_i, t_i + h]`` the quintic matching position, velocity and
    acceleration at both ends (as :func:`ident.excitation.executable.quintic`), in closed form
    for every interval at once: with ``dp = q_{i+1} - q_i``,
    ``c3 = (20 dp - (8 v1 + 12 v0) h - (3 a0 - a1) h^2) / (2 h^3)``,
    ``c4 = (-30 dp + (14 v1 + 16 v0) h + (3 a0 - 2 a1) h^2) / (2 h^4)``,
    ``c5 = (12 dp - 6 (v1 + v0) h - (a0 - a1) h^2) / (2 h^5)``.

    Parameters
    ----------
    t :
        Increasing sample times [s], shape (n_samples,).
    q, dq, ddq :
        Positions, velocities, accelerations at ``t``, shape (n_samples, n_joints).
    times :
        Where to evaluate [s], within ``[t[0], t[-1]]``, shape (n_times,).

    Returns
    -------
    :
        ``q, dq, ddq`` at ``times``, each of shape (n_times, n_joints).
    """
    i = np.clip(np.searchsorted(t, times, side="right") - 1, 0, t.shape[0] - 2)
    h = (t[i + 1] - t[i])[:, None]
    tau = (times - t[i])[:, None]
    p0, v0, a0 = q[i], dq[i], ddq[i]
    p1, v1, a1 = q[i + 1], dq[i + 1], ddq[i + 1]
    dp = p1 - p0
    c3 = (20 * dp - (8 * v1 + 12 * v0) * h - (3 * a0 - a1) * h**2) / (2 * h**3)
    c4 = (-30 * dp + (14 * v1 + 16 * v0) * h + (3 * a0 - 2 * a1) * h**2) / (2 * h**4)
    c5 = (12 * dp - 6 * (v1 + v0) * h - (a0 - a1) * h**2) / (2 * h**5)
    position = p0 + tau * (v0 + tau * (0.5 * a0 + tau * (c3 + tau * (c4 + tau * c5))))
    velocity = v0 + tau * (a0 + tau * (3 * c3 + tau * (4 * c4 + tau * 5 * c5)))
    acceleration = a0 + tau * (6 * c3 + tau * (12 * c4 + tau * 20 * c5))
    return position, velocity, acceleration


def first_violation(
    values: FloatArray,
    limit: npt.ArrayLike,
    t: FloatArray,
    joint_names: tuple[str, ...],
    quantity: str,
    unit: str,
) -> str | None:
    """The first sample where ``|values|`` exceeds ``limit``, in words; None when none does.

    ``values`` has shape (n_samples, n_joints), ``limit`` shape (n_joints,) (inf: no limit),
    ``t`` the time [s] of each row.
    """
    limit = np.broadcast_to(np.asarray(limit, dtype=float), (values.shape[1],))
    over = np.abs(values) > limit
    if not over.any():
        return None
    k, j = np.argwhere(over)[0]
    worst = int(np.argmax(np.max(np.abs(values) / limit, axis=0)))
    return (
        f"joint {joint_names[j]!r} {quantity} {values[k, j]:.6g} {unit} exceeds the limit "
        f"{limit[j]:.6g} {unit} at t = {t[k]:.6g} s (worst: joint {joint_names[worst]!r}, "
        f"{np.max(np.abs(values[:, worst])):.6g} {unit})"
    )


def compare_samples(written: ExportSamples, reread: ExportSamples, source: str) -> None:
    """Require the re-read file to hold the written samples to :data:`REREAD_TOLERANCE`.

    Raises
    ------
    ExportError
        Naming the file, the quantity, the joint and the sample that differ.
    """
    if reread.joint_names != written.joint_names:
        raise ExportError(
            f"{source}: re-read joint names {list(reread.joint_names)} differ from the written "
            f"{list(written.joint_names)}."
        )
    pairs = [("t", written.t[:, None], reread.t[:, None]), ("q", written.q, reread.q)]
    for name in ("dq", "ddq"):
        a, b = getattr(written, name), getattr(reread, name)
        if (a is None) != (b is None):
            raise ExportError(f"{source}: {name} written and re-read differ in presence.")
        if a is not None and b is not None:
            pairs.append((name, a, b))
    for name, a, b in pairs:
        if a.shape != b.shape:
            raise ExportError(
                f"{source}: re-read {name} has shape {b.shape}, written {a.shape}; the file is "
                "truncated or malformed."
            )
        error = np.abs(a - b)
        if not np.all(error <= REREAD_TOLERANCE):  # NaN fails too
            k, j = np.argwhere(~(error <= REREAD_TOLERANCE))[0]
            joint = "time" if name == "t" else f"joint {written.joint_names[j]!r}"
            raise ExportError(
                f"{source}: re-read {name} of {joint} differs from the plan by "
                f"{error[k, j]:.3g} at sample {k} (t = {written.t[k]:.6g} s), more than "
                f"{REREAD_TOLERANCE:g}."
            )


def compare_with_plan(reread: ExportSamples, plan: JointTrajectory, source: str) -> int:
    """Require the re-read positions to equal the plan's where their times coincide (1e-9 s).

    A file resampled to a controller's rate shares the times of the plan's grid it can (all of
    them at the plan's own rate, every other one at half of it); there its positions must be
    the plan's to :data:`REREAD_TOLERANCE`, independently of the resampling.

    Returns
    -------
    :
        The number of samples compared.

    Raises
    ------
    ExportError
        Naming the file, the joint and the time that differ.
    """
    t = np.asarray(plan.t, dtype=float)
    index = np.clip(np.searchsorted(t, reread.t), 1, t.shape[0] - 1)
    nearest = np.where(
        np.abs(t[index - 1] - reread.t) <= np.abs(t[index] - reread.t), index - 1, index
    )
    same = np.abs(t[nearest] - reread.t) <= REREAD_TOLERANCE  # ns-rounded stamps coincide
    error = np.abs(reread.q[same] - plan.q[nearest[same]])
    if not np.all(error <= REREAD_TOLERANCE):
        k, j = np.argwhere(~(error <= REREAD_TOLERANCE))[0]
        time = reread.t[same][k]
        raise ExportError(
            f"{source}: joint {plan.joint_names[j]!r} position differs from the plan by "
            f"{error[k, j]:.3g} at t = {time:.6g} s, more than {REREAD_TOLERANCE:g}."
        )
    return int(same.sum())
