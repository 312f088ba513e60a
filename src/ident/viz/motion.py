"""A replayed trajectory's motion: the model's configurations along it, its segments, the
replay's keyframes and the traced frame's path.

A log whose time jumps backwards or has gaps is replayed segment after segment
(:func:`replay_segments`); keyframes are one per ``1 / fps`` s of replay time
(:func:`_resample`); the traced path is decimated to a light line (:func:`_path_lines`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.errors import DataError, ModelError
from ident.measure.timebase import find_segments
from ident.trajectory import JointTrajectory
from ident.viz.visual_robot import _SceneRobot

__all__ = ["joint_configurations", "replay_duration", "replay_segments"]

FloatArray = npt.NDArray[np.float64]

# Keep the path line light: a 1 kHz, 60 s log is decimated to at most this many points.
_MAX_PATH_POINTS = 4000


# Segments of a log drawn as lines of their own (more: one line through all of them).
_MAX_SEGMENT_LINES = 50


def joint_configurations(
    model: pin.Model, trajectory: JointTrajectory, *, urdf_path: str | Path | None = None
) -> FloatArray:
    """Configurations of ``model`` along a trajectory whose columns are named joints.

    The trajectory's joints are matched to the model's by name (any column order).

    Parameters
    ----------
    model :
        Pinocchio model of a fixed-base robot (revolute, prismatic, continuous joints).
    trajectory :
        Joint positions [rad] or [m], shape (n_samples, n_joints). Its ``source`` (the CSV)
        is named in messages.
    urdf_path :
        The model's URDF, named in messages.

    Returns
    -------
    :
        Configurations, shape (n_samples, model.nq); a continuous joint's angle becomes
        its (cos, sin) pair.

    Raises
    ------
    DataError
        The trajectory's joint names are not exactly the model's 1-DoF joints.
    ModelError
        The model has a joint with more than one degree of freedom (floating base...).
    """
    model_joints = [model.names[j] for j in range(1, model.njoints)]
    multi = [model.names[j] for j in range(1, model.njoints) if model.joints[j].nv != 1]
    if multi:
        raise ModelError(
            f"replay supports 1-DoF joints only; joints {multi} have several degrees of freedom."
        )
    names = list(trajectory.joint_names)
    if sorted(names) != sorted(model_joints):
        raise _joint_mismatch(names, model_joints, trajectory.source, urdf_path)
    q = np.tile(pin.neutral(model), (trajectory.n_samples, 1))
    for column, name in enumerate(names):
        joint = model.joints[model.getJointId(name)]
        angle = trajectory.q[:, column]
        if joint.nq == 1:
            q[:, joint.idx_q] = angle
        else:  # continuous joint: unit complex number (cos, sin)
            q[:, joint.idx_q] = np.cos(angle)
            q[:, joint.idx_q + 1] = np.sin(angle)
    return q


def _joint_mismatch(
    names: list[str], model_joints: list[str], source: str | None, urdf_path: str | Path | None
) -> DataError:
    """The error naming how the trajectory's joints (from the CSV ``source``) differ from the
    URDF's, and the fix."""
    missing = [j for j in model_joints if j not in names]
    extra = [j for j in names if j not in model_joints]
    csv = f"trajectory {source}" if source else "the trajectory"
    urdf = f"URDF {urdf_path}" if urdf_path is not None else "the URDF"
    if len(names) != len(model_joints):
        what = (
            f"{csv} has {len(names)} joints {names}, {urdf} has {len(model_joints)} "
            f"joints {model_joints}"
        )
    else:
        what = f"the joints of {csv} {names} do not match the joints of {urdf} {model_joints}"
    details = [f"missing from the trajectory: {missing}"] if missing else []
    details += [f"unknown to the URDF: {extra}"] if extra else []
    lock = (
        "; or hold the joints the trajectory does not move fixed (--lock NAME=VALUE, "
        "robot.lock in a config)"
        if missing and not extra
        else ""
    )
    return DataError(
        f"{what} ({'; '.join(details)}); the q_<joint> columns must name the URDF's "
        "joints (any order): rename the columns or use the URDF of the robot that made "
        f"the trajectory{lock}."
    )


def replay_segments(t: npt.ArrayLike) -> list[tuple[int, int]]:
    """Sample ranges of a trajectory that are replayed one after another.

    A log is split where its time stops increasing (a backwards jump: two runs appended, a
    clock reset) and at gaps (a step longer than :data:`ident.measure.timebase.GAP_FACTOR`
    median steps, the rule of the log readers, :func:`ident.measure.timebase.find_segments`):
    the replay shows each segment at its own speed and skips the time between them.

    Parameters
    ----------
    t :
        Time stamps [s], shape (n_samples,).

    Returns
    -------
    :
        ``[(start, stop), ...]`` index ranges covering ``0..n_samples`` in order.
    """
    t = np.asarray(t, dtype=float)
    backwards = np.flatnonzero(np.diff(t) <= 0.0) + 1
    bounds = [0, *backwards.tolist(), t.size]
    out: list[tuple[int, int]] = []
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        out += [(a + c, a + d) for c, d in find_segments(t[a:b])]
    return out


def replay_duration(t: npt.ArrayLike, speed: float = 1.0) -> float:
    """Replay time [s] of a trajectory with time stamps ``t`` [s]: its segments' spans / speed."""
    t = np.asarray(t, dtype=float)
    return sum(float(t[b - 1] - t[a]) for a, b in replay_segments(t)) / speed


def _resample(
    trajectory: JointTrajectory, q: FloatArray, fps: float, speed: float
) -> tuple[FloatArray, list[int]]:
    """Configurations at replay times ``k / fps``, segment after segment.

    Within a segment (:func:`replay_segments`) starting at ``t_s``, replay frame ``k`` shows
    trajectory time ``t_s + k * speed / fps``; the next segment starts at the next frame.
    Returns the configurations, shape (n_frames, nq), and the first frame of each segment.
    """
    parts, starts, n = [], [], 0
    for a, b in replay_segments(trajectory.t):
        t = trajectory.t[a:b] - trajectory.t[a]
        n_frames = int(math.floor(t[-1] / speed * fps + 1e-9)) + 1
        t_frames = np.arange(n_frames) * speed / fps
        out = np.empty((n_frames, q.shape[1]))
        for k in range(q.shape[1]):  # linear interpolation; keyframes are dense (fps >= 10)
            out[:, k] = np.interp(t_frames, t, q[a:b, k])
        parts.append(out)
        starts.append(n)
        n += n_frames
    return np.vstack(parts), starts


def _frame_positions(model: pin.Model, q: FloatArray, frame_id: int) -> FloatArray:
    """World positions [m] of a frame, shape (n_samples, 3)."""
    data = model.createData()
    out = np.empty((q.shape[0], 3))
    for k in range(q.shape[0]):  # Pinocchio evaluates one configuration at a time
        pin.framesForwardKinematics(model, data, q[k])
        out[k] = data.oMf[frame_id].translation
    return out


def _joint_positions(model: pin.Model, q: FloatArray) -> FloatArray:
    """World positions [m] of every joint origin, shape (n_samples, njoints, 3)."""
    data = model.createData()
    out = np.empty((q.shape[0], model.njoints, 3))
    for k in range(q.shape[0]):
        pin.forwardKinematics(model, data, q[k])
        out[k] = np.array([m.translation for m in data.oMi])
    return out


def _path_lines(
    model: pin.Model, q: FloatArray, segments: list[tuple[int, int]], frame_id: int
) -> list[FloatArray]:
    """The traced frame's positions [m], one (n_points, 3) array per segment (a single one,
    across the segments, beyond :data:`_MAX_SEGMENT_LINES` segments)."""
    if len(segments) == 1 or len(segments) > _MAX_SEGMENT_LINES:
        return [_frame_positions(model, _decimate(q, _MAX_PATH_POINTS), frame_id)]
    budget = max(2, _MAX_PATH_POINTS // len(segments))
    return [_frame_positions(model, _decimate(q[a:b], budget), frame_id) for a, b in segments]


def _decimate(points: FloatArray, max_points: int) -> FloatArray:
    if points.shape[0] <= max_points:
        return points
    index = np.unique(np.linspace(0, points.shape[0] - 1, max_points).round().astype(int))
    return points[index]


@dataclass(frozen=True, eq=False)
class _Motion:
    """One trajectory as the scene draws it.

    Attributes
    ----------
    trajectory, q :
        The trajectory and the model's configurations at its samples, shape (n_samples, nq).
    keyframes :
        Configurations at the replay's keyframes (one per ``1 / fps`` s of replay time),
        shape (n_frames, nq).
    segment_starts :
        First keyframe of each segment of the log (:func:`replay_segments`).
    path_lines :
        The traced frame's positions [m], one (n_points, 3) array per line drawn.
    points :
        Joint origins at every keyframe, then the traced path's points [m], shape (n, 3),
        in the robot's own frame: what the spacing and the camera must show.
    """

    trajectory: JointTrajectory
    q: FloatArray
    keyframes: FloatArray
    segment_starts: list[int]
    path_lines: list[FloatArray]
    points: FloatArray


def _replay_motions(
    robot: _SceneRobot,
    trajectories: Sequence[JointTrajectory],
    fps: float,
    speed: float,
    urdf_path: Path,
) -> list[_Motion]:
    """Keyframes, traced path and extent of each trajectory, replayed at ``fps`` keyframes
    per second [1/s] and ``speed``. Raises :class:`DataError` (joints that do not match the
    URDF at ``urdf_path``: :func:`joint_configurations`, every trajectory checked first)."""
    model = robot.model
    configurations = [joint_configurations(model, t, urdf_path=urdf_path) for t in trajectories]
    motions = []
    for trajectory, q in zip(trajectories, configurations, strict=True):
        keyframes, starts = _resample(trajectory, q, fps, speed)
        # the traced path, one line per segment (at most _MAX_SEGMENT_LINES, else one line)
        lines = _path_lines(model, q, replay_segments(trajectory.t), robot.frame_id)
        joints = _joint_positions(model, keyframes).reshape(-1, 3)
        points = np.vstack([joints, np.vstack(lines)])
        motions.append(_Motion(trajectory, q, keyframes, starts, lines, points))
    return motions
