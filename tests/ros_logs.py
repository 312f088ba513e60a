"""Write small ROS 2 logs for the reader tests: bare MCAP files of JointState messages.

Messages are serialized by ``rosbags`` (CDR) and written by ``mcap``'s writer, so a test can
make a file of 100 000 messages in a few seconds, with any stamps, names and chunking.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

JOINT_STATE = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""
FLOAT64_ARRAY = """std_msgs/MultiArrayLayout layout
float64[] data
================================================================================
MSG: std_msgs/MultiArrayLayout
MultiArrayDimension[] dim
uint32 data_offset
================================================================================
MSG: std_msgs/MultiArrayDimension
string label
uint32 size
uint32 stride
"""
RECORDED_T0_NS = 1_700_000_000_000_000_000  # the recorder's clock: an epoch time


def joint_states(
    path: Path,
    q: np.ndarray,
    stamps_s: Sequence[float | None],
    *,
    names: Sequence[str] | None = None,
    chunk_size: int = 1 << 20,
    compression: str = "zstd",
    efforts: np.ndarray | None = None,
) -> Path:
    """Write ``/joint_states`` messages: positions ``q`` (n, nj), velocity ``2 q``, effort
    ``efforts`` (default ``3 q``); ``stamps_s[k]`` is the header stamp [s] (None: zero, i.e.
    no stamp); message k is recorded at ``RECORDED_T0_NS + k`` ms."""
    from mcap.writer import CompressionType, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    JointState = store.types["sensor_msgs/msg/JointState"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    names = list(names) if names is not None else [f"j{k + 1}" for k in range(q.shape[1])]
    kind = {"zstd": CompressionType.ZSTD, "none": CompressionType.NONE}[compression]
    with open(path, "wb") as f:
        writer = Writer(f, chunk_size=chunk_size, compression=kind)
        writer.start(profile="ros2", library="ident tests")
        schema = writer.register_schema(
            "sensor_msgs/msg/JointState", "ros2msg", JOINT_STATE.encode()
        )
        channel = writer.register_channel("/joint_states", "cdr", schema)
        effort = 3.0 * q if efforts is None else efforts
        for k, (row, stamp) in enumerate(zip(q, stamps_s, strict=True)):
            sec = int(np.floor(stamp)) if stamp is not None else 0
            nanosec = int(round((stamp - sec) * 1e9)) if stamp is not None else 0
            msg = JointState(
                header=Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=""),
                name=names,
                position=row,
                velocity=2.0 * row,
                effort=np.asarray(effort[k], dtype=float),
            )
            ns = RECORDED_T0_NS + k * 1_000_000
            data = store.serialize_cdr(msg, "sensor_msgs/msg/JointState")
            writer.add_message(channel, log_time=ns, data=bytes(data), publish_time=ns)
        writer.finish()
    return path


def float_array_bomb(path: Path, n_floats: int = 20_000_000, n_messages: int = 2) -> Path:
    """An MCAP of ``n_messages`` Float64MultiArray messages of ``n_floats`` zeros, one zstd
    chunk each: 11 kB on disk, 160 MB per chunk once decompressed (a bomb)."""
    from mcap.writer import CompressionType, Writer

    cdr = b"\x00\x01\x00\x00" + struct.pack("<III", 0, 0, n_floats) + bytes(4 + 8 * n_floats)
    with open(path, "wb") as f:
        writer = Writer(f, chunk_size=1, compression=CompressionType.ZSTD)
        writer.start(profile="ros2", library="ident tests")
        schema = writer.register_schema(
            "std_msgs/msg/Float64MultiArray", "ros2msg", FLOAT64_ARRAY.encode()
        )
        channel = writer.register_channel("/cmd", "cdr", schema)
        for k in range(n_messages):
            writer.add_message(channel, log_time=k, data=cdr, publish_time=k)
        writer.finish()
    return path


def flip_bytes(source: Path, target: Path, n: int = 40, seed: int = 1) -> Path:
    """``source`` with ``n`` bytes inverted at seeded places past the magic (a bad copy)."""
    data = bytearray(source.read_bytes())
    rng = np.random.default_rng(seed)
    for i in rng.integers(8, len(data) - 8, size=n):
        data[i] ^= 0xFF
    target.write_bytes(bytes(data))
    return target


Stamps = Callable[[int], float | None]


def joint_state_bag(
    folder: Path, q: np.ndarray, stamps_s: Sequence[float], *, names: Sequence[str]
) -> Path:
    """A ROS 2 bag folder (sqlite3) of ``/joint_states`` as :func:`joint_states` writes."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    JointState = store.types["sensor_msgs/msg/JointState"]
    Header = store.types["std_msgs/msg/Header"]
    Time = store.types["builtin_interfaces/msg/Time"]
    with Writer(folder, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conn = writer.add_connection("/joint_states", "sensor_msgs/msg/JointState", typestore=store)
        for k, (row, stamp) in enumerate(zip(q, stamps_s, strict=True)):
            sec = int(np.floor(stamp))
            msg = JointState(
                header=Header(
                    stamp=Time(sec=sec, nanosec=int(round((stamp - sec) * 1e9))), frame_id=""
                ),
                name=list(names),
                position=row,
                velocity=2.0 * row,
                effort=3.0 * row,
            )
            ns = RECORDED_T0_NS + k * 1_000_000
            writer.write(conn, ns, store.serialize_cdr(msg, conn.msgtype))
    return folder
