"""ROS 2 export: ``trajectory_msgs/msg/JointTrajectory`` as YAML and as a bag (MCAP).

At the plan's own samples (``controller.rate_hz``), no resampling:

- ``joint_trajectory.yaml``: the message in the field layout of
  ``trajectory_msgs/msg/JointTrajectory`` (``header {stamp {sec, nanosec}, frame_id}``,
  ``joint_names``, ``points`` with ``positions``, ``velocities``, ``accelerations``,
  ``effort`` and ``time_from_start {sec, nanosec}``), what ``ros2 topic pub`` takes, and the
  ``trajectory`` of a ``control_msgs/action/FollowJointTrajectory`` goal;
- ``joint_trajectory_bag/``: a rosbag2 folder (``metadata.yaml`` + one MCAP file, schema
  encoding ``ros2msg``, message encoding ``cdr``) with that one message on
  ``/joint_trajectory``, for ``ros2 bag play``.

The header stamp is zero ("start now" for a joint trajectory controller). ``time_from_start``
is the plan's time rounded to the nanosecond (at most 0.5 ns off).

Checked before writing: ``time_from_start`` strictly increasing; the joint names are movable
joints of the run's URDF, each once, in the URDF's order; every point has one position,
velocity and acceleration per joint, finite; positions within the URDF's ``<limit>`` and
speeds within its ``velocity`` where the URDF gives them.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ident.fileio import atomic_write_text
from ident.run.exports.common import (
    ExportError,
    ExportSamples,
    ExportTarget,
    first_violation,
)
from ident.trajectory import JointTrajectory

__all__ = [
    "BAG_FOLDER",
    "MSGTYPE",
    "TOPIC",
    "YAML_FILE",
    "accepts_ros2",
    "message_from_yaml",
    "prepare_ros2",
    "read_ros2",
    "write_ros2",
]

YAML_FILE = "joint_trajectory.yaml"
BAG_FOLDER = "joint_trajectory_bag"
TOPIC = "/joint_trajectory"
MSGTYPE = "trajectory_msgs/msg/JointTrajectory"
_NS = 1_000_000_000


def _nanoseconds(t: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(t, dtype=float) * _NS).astype(np.int64)


def accepts_ros2(names: tuple[str, ...], target: ExportTarget) -> None:
    """Refuse joint names that are not movable joints of the URDF, each once, in its order."""
    urdf = target.joint_names
    unknown = [n for n in names if n not in urdf]
    if unknown:
        raise ExportError(
            f"ros2: joint names {unknown} are not movable joints of the URDF "
            f"'{target.robot_name}' (its joints: {', '.join(urdf)}); a controller would "
            "reject the message."
        )
    if len(set(names)) != len(names) or list(names) != [n for n in urdf if n in names]:
        raise ExportError(
            f"ros2: joint names {list(names)} repeat a joint or are not in the URDF's order "
            f"({', '.join(urdf)})."
        )


def prepare_ros2(trajectory: JointTrajectory, target: ExportTarget) -> ExportSamples:
    """The plan's samples, checked against the message's and the URDF's rules.

    Raises
    ------
    ExportError
        Time not strictly increasing (after rounding to ns), a joint name the URDF does not
        have as a movable joint or out of the URDF's order, a duplicate, a non-finite value,
        or a position/speed beyond the URDF's limits.
    """
    names = tuple(trajectory.joint_names)
    accepts_ros2(names, target)
    ns = _nanoseconds(trajectory.t)
    steps = np.diff(ns)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0)) + 1
        raise ExportError(
            f"ros2: time_from_start is not strictly increasing at point {k} "
            f"(t = {trajectory.t[k]:.9g} s); the controller would reject the trajectory."
        )
    for name in ("q", "dq", "ddq"):
        values = getattr(trajectory, name)
        if not np.all(np.isfinite(values)):
            raise ExportError(f"ros2: the trajectory's {name} holds NaN or infinite values.")
    joints = {j.name: j for j in target.urdf_joints}
    lower = np.array([joints[n].lower for n in names])
    upper = np.array([joints[n].upper for n in names])
    velocity = np.array([joints[n].velocity for n in names])
    velocity = np.where(np.isfinite(velocity) & (velocity > 0.0), velocity, np.inf)
    outside = (trajectory.q < np.nan_to_num(lower, nan=-np.inf)) | (
        trajectory.q > np.nan_to_num(upper, nan=np.inf)
    )
    if outside.any():
        k, j = np.argwhere(outside)[0]
        raise ExportError(
            f"ros2: joint {names[j]!r} position {trajectory.q[k, j]:.6g} is outside the URDF's "
            f"[{lower[j]:.6g}, {upper[j]:.6g}] at t = {trajectory.t[k]:.6g} s."
        )
    problem = first_violation(trajectory.dq, velocity, trajectory.t, names, "speed", "rad/s")
    if problem is not None:
        raise ExportError(f"ros2: {problem} (the URDF's <limit velocity>).")
    return ExportSamples(
        ns / _NS, trajectory.q.copy(), trajectory.dq.copy(), trajectory.ddq.copy(), names
    )


def _yaml_float(value: float) -> str:
    """``repr`` (17 significant digits, exact), spelled so YAML 1.1 reads a float.

    PyYAML (``ros2 topic pub``) reads ``1e-05`` as a string: a mantissa needs a dot.
    """
    text = repr(float(value))
    return text.replace("e", ".0e") if "e" in text and "." not in text else text


def _floats(values: np.ndarray) -> str:
    return "[" + ", ".join(_yaml_float(v) for v in values) + "]"


def _yaml_text(samples: ExportSamples) -> str:
    """The message as YAML; flow-style lists, floats with 17 significant digits (repr)."""
    assert samples.dq is not None
    assert samples.ddq is not None
    lines = [
        "# trajectory_msgs/msg/JointTrajectory written by ident (docs/execute.md)",
        "header:",
        "  stamp: {sec: 0, nanosec: 0}",
        "  frame_id: ''",
        "joint_names: [" + ", ".join(f"'{n}'" for n in samples.joint_names) + "]",
        "points:",
    ]
    for k, ns in enumerate(_nanoseconds(samples.t)):
        sec, nanosec = divmod(int(ns), _NS)
        lines += [
            f"- positions: {_floats(samples.q[k])}",
            f"  velocities: {_floats(samples.dq[k])}",
            f"  accelerations: {_floats(samples.ddq[k])}",
            "  effort: []",
            f"  time_from_start: {{sec: {sec}, nanosec: {nanosec}}}",
        ]
    return "\n".join(lines) + "\n"


def _message(samples: ExportSamples, typestore: Any) -> Any:
    types = typestore.types
    point, duration = (
        types["trajectory_msgs/msg/JointTrajectoryPoint"],
        types["builtin_interfaces/msg/Duration"],
    )
    points = []
    assert samples.dq is not None
    assert samples.ddq is not None
    for k, ns in enumerate(_nanoseconds(samples.t)):
        sec, nanosec = divmod(int(ns), _NS)
        points.append(
            point(
                positions=np.array(samples.q[k], dtype=np.float64),
                velocities=np.array(samples.dq[k], dtype=np.float64),
                accelerations=np.array(samples.ddq[k], dtype=np.float64),
                effort=np.zeros(0, dtype=np.float64),
                time_from_start=duration(sec=sec, nanosec=nanosec),
            )
        )
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=0, nanosec=0), frame_id=""
    )
    return types[MSGTYPE](header=header, joint_names=list(samples.joint_names), points=points)


def _typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_HUMBLE)


def _qos() -> Any:
    """The QoS a default ROS 2 publisher offers (reliable, volatile, keep last), as rosbag2
    records it; ``ros2 bag play`` publishes with it."""
    from rosbags.interfaces import (
        Qos,
        QosDurability,
        QosHistory,
        QosLiveliness,
        QosReliability,
        QosTime,
    )

    infinite = QosTime(sec=2147483647, nsec=4294967295)
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=1,
        reliability=QosReliability.RELIABLE,
        durability=QosDurability.VOLATILE,
        deadline=infinite,
        lifespan=infinite,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=infinite,
        avoid_ros_namespace_conventions=False,
    )


def write_ros2(samples: ExportSamples, folder: Path) -> list[Path]:
    """Write ``joint_trajectory.yaml`` and the bag folder into ``folder``; return both paths."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    yaml_path = atomic_write_text(folder / YAML_FILE, _yaml_text(samples))
    typestore = _typestore()
    bag = folder / BAG_FOLDER
    # rosbags refuses an existing folder: write into a fresh temporary one, then move it
    staging = Path(tempfile.mkdtemp(dir=folder, prefix=".bag-")) / BAG_FOLDER
    try:
        with Writer(staging, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
            connection = writer.add_connection(
                TOPIC, MSGTYPE, typestore=typestore, offered_qos_profiles=[_qos()]
            )
            data = typestore.serialize_cdr(_message(samples, typestore), MSGTYPE)
            writer.write(connection, 0, data)
        if bag.exists():
            shutil.rmtree(bag)
        staging.rename(bag)
    finally:
        shutil.rmtree(staging.parent, ignore_errors=True)
    return [yaml_path, bag]


def message_from_yaml(path: Path) -> dict[str, Any]:
    """The message dictionary of a YAML file written by :func:`write_ros2`."""
    loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
    with path.open(encoding="utf-8") as f:
        data = yaml.load(f, Loader=loader)  # noqa: S506 - a safe loader
    if not isinstance(data, dict):
        raise ExportError(f"{path}: not a JointTrajectory message.")
    return data


def samples_from_message(message: Any) -> ExportSamples:
    """Samples of a JointTrajectory given as a dict (YAML) or a deserialized message."""

    def field(obj: Any, name: str) -> Any:
        return obj[name] if isinstance(obj, dict) else getattr(obj, name)

    points = field(message, "points")
    times = [field(p, "time_from_start") for p in points]
    ns = np.array([int(field(d, "sec")) * _NS + int(field(d, "nanosec")) for d in times])
    arrays = []
    for key in ("positions", "velocities", "accelerations"):
        values = np.array([np.asarray(field(p, key)) for p in points])
        if values.size and values.dtype.kind not in "fi":  # YAML read a value as a string
            raise ExportError(f"JointTrajectory: {key} holds non-numbers ({values.dtype}).")
        arrays.append(values.astype(float))
    names = tuple(str(n) for n in field(message, "joint_names"))
    shape = (len(points), len(names))
    q, dq, ddq = (a.reshape(shape) for a in arrays)
    return ExportSamples(ns / _NS, q, dq, ddq, names)


def read_ros2(path: Path) -> ExportSamples:
    """Read the YAML file or the bag folder written by :func:`write_ros2` back.

    The bag is read with ``rosbags``' ``AnyReader``; it must hold exactly one message on
    :data:`TOPIC` of type :data:`MSGTYPE`.
    """
    if path.is_file():
        return samples_from_message(message_from_yaml(path))
    from rosbags.highlevel import AnyReader

    with AnyReader([path], default_typestore=_typestore()) as reader:
        connections = [c for c in reader.connections if c.topic == TOPIC]
        messages = list(reader.messages(connections=connections))
        if len(messages) != 1 or connections[0].msgtype != MSGTYPE:
            raise ExportError(
                f"{path}: expected one {MSGTYPE} message on {TOPIC}, found {len(messages)}."
            )
        connection, _, raw = messages[0]
        return samples_from_message(reader.deserialize(raw, connection.msgtype))
