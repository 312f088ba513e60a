"""ROS 2 logs: bag folders (``rosbags``) and bare ``.mcap`` files (``mcap-ros2-support``).

Each topic becomes one :class:`~ident.measure.readers.LogTable` with a time column
``<topic>/t`` [s] (the message's ``header.stamp`` when it has a non-zero one, else the time it
was recorded), relative to the first message of the file, computed in integer nanoseconds so
that an epoch time keeps its sub-microsecond resolution. Message fields become columns:

- ``sensor_msgs/JointState`` (and any message with a ``name`` list and arrays of the same
  length): ``<topic>/position/<joint name>``, ``<topic>/velocity/<joint name>``,
  ``<topic>/effort/<joint name>``;
- other messages: every numeric field ``<topic>/<field>``, numeric arrays
  ``<topic>/<field>/<index>``, nested messages ``<topic>/<field>/<sub>``
  (e.g. ``std_msgs/Float64MultiArray`` -> ``/cmd/data/0``).

Why two libraries: ``rosbags`` reads ROS 2 bag *folders* (``metadata.yaml`` with sqlite3 or
mcap storage) and needs no ROS installation; a single ``.mcap`` file without its folder (as
Foxglove and many loggers write) carries its message definitions in the file and is decoded by
``mcap-ros2-support``, which builds the message classes from those definitions.

Option ``topics``: the topics to read (default: every topic with numeric fields).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ident.errors import DataError
from ident.measure.readers.registry import LogTable

__all__ = ["is_mcap", "is_rosbag", "read_mcap", "read_rosbag"]


def is_rosbag(path: Path) -> bool:
    """Detector: a folder with ``metadata.yaml`` (a ROS 2 bag)."""
    return path.is_dir() and (path / "metadata.yaml").is_file()


def is_mcap(path: Path) -> bool:
    """Detector: a file named ``*.mcap``."""
    return path.is_file() and path.suffix == ".mcap"


def _fields(msg: Any) -> list[str]:
    names = getattr(type(msg), "__dataclass_fields__", None)
    if names is not None:
        return [n for n in names if n != "__msgtype__"]
    return [n for n in getattr(type(msg), "__slots__", ()) if not n.startswith("_")]


def _stamp_ns(msg: Any) -> int | None:
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None:
        return None
    ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
    return ns if ns > 0 else None


def _flatten(msg: Any, prefix: str, out: dict[str, float]) -> None:
    fields = _fields(msg)
    names = getattr(msg, "name", None)
    by_name = (
        isinstance(names, list | tuple)
        and len(names) > 0
        and all(isinstance(n, str) for n in names)
    )
    for field in fields:
        if field == "header":
            continue
        value = getattr(msg, field)
        if isinstance(value, bool | int | float | np.integer | np.floating):
            out[f"{prefix}/{field}"] = float(value)
        elif isinstance(value, np.ndarray | list | tuple):
            arr = np.asarray(value)
            if arr.dtype.kind not in "iuf" or arr.ndim != 1:
                continue
            if by_name and arr.size == len(names):
                for n, v in zip(names, arr, strict=True):
                    out[f"{prefix}/{field}/{n}"] = float(v)
            else:
                for k, v in enumerate(arr):
                    out[f"{prefix}/{field}/{k}"] = float(v)
        elif _fields(value):
            _flatten(value, f"{prefix}/{field}", out)


def _tables(
    source: str, messages: Iterable[tuple[str, int, Any]], topics: list[str] | None
) -> list[LogTable]:
    """Group ``(topic, recorded_ns, message)`` into one table per topic."""
    rows: dict[str, list[tuple[int, dict[str, float]]]] = {}
    for topic, recorded_ns, msg in messages:
        if topics is not None and topic not in topics:
            continue
        values: dict[str, float] = {}
        _flatten(msg, topic, values)
        if values:
            rows.setdefault(topic, []).append((_stamp_ns(msg) or recorded_ns, values))
    if topics is not None:
        missing = [t for t in topics if t not in rows]
        if missing:
            raise DataError(
                f"{source}: topic(s) {', '.join(missing)} have no numeric messages; the file "
                f"has {', '.join(sorted(rows)) or 'none'}."
            )
    if not rows:
        return []
    t0 = min(r[0][0] for r in rows.values())
    tables = []
    for topic, entries in rows.items():
        entries.sort(key=lambda e: e[0])
        keys = list(entries[0][1])
        if any(list(v) != keys for _, v in entries):
            raise DataError(
                f"{source}: topic {topic} changes its fields (joint names) between messages."
            )
        columns = {
            f"{topic}/t": np.array([(ns - t0) * 1e-9 for ns, _ in entries]),
            **{k: np.array([v[k] for _, v in entries]) for k in keys},
        }
        tables.append(LogTable(columns=columns, time=f"{topic}/t", source=f"{source} {topic}"))
    return tables


def read_rosbag(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a ROS 2 bag folder (sqlite3 or mcap storage) with ``rosbags``."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    topics = options.get("topics")
    try:
        with Reader(path) as reader:
            connections = [c for c in reader.connections if topics is None or c.topic in topics]

            def messages() -> Iterable[tuple[str, int, Any]]:
                for conn, timestamp, raw in reader.messages(connections=connections):
                    yield conn.topic, timestamp, typestore.deserialize_cdr(raw, conn.msgtype)

            return _tables(str(path), messages(), topics)
    except (OSError, KeyError, ValueError) as e:
        raise DataError(f"{path}: cannot read the ROS 2 bag ({e}).") from e
    except Exception as e:  # rosbags raises its own ReaderError types
        if type(e).__module__.startswith("rosbags"):
            raise DataError(f"{path}: cannot read the ROS 2 bag ({e}).") from e
        raise


def read_mcap(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a bare ``.mcap`` file of ROS 2 messages with ``mcap-ros2-support``."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    topics = options.get("topics")
    try:
        with open(path, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])

            def messages() -> Iterable[tuple[str, int, Any]]:
                for _, channel, message, decoded in reader.iter_decoded_messages(topics=topics):
                    yield channel.topic, message.log_time, decoded

            return _tables(str(path), messages(), topics)
    except (OSError, ValueError) as e:
        raise DataError(f"{path}: cannot read the MCAP file ({e}).") from e
    except Exception as e:
        if type(e).__module__.startswith("mcap"):
            raise DataError(f"{path}: cannot read the MCAP file ({e}).") from e
        raise
