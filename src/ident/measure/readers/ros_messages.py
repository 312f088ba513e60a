"""ROS messages as tables: every topic's numeric fields, one column each, with its time.

The message side of :mod:`ident.measure.readers.ros` (which reads bag folders and ``.mcap``
files and hands their decoded messages here): :func:`flatten` names and collects the numeric
fields of one message (``JointState``-like messages by joint name), :func:`message_tables`
writes them message by message (or a chunk's block at a time, :class:`MessageBlock`) into
preallocated arrays per topic, checked against ``IDENT_MAX_MEMORY_GB`` before each allocation,
and gives one :class:`~ident.measure.readers.LogTable` per topic with its time column by the
rule of :mod:`ident.measure.readers.ros`'s docstring (``header.stamp``, else the recorded time).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.inputs import JobEstimate, check_job
from ident.measure.readers.registry import LogTable

__all__ = ["MAX_VALUES", "MessageBlock", "RepeatedName", "flatten", "message_tables", "stamp_ns"]

MAX_VALUES = 100_000  # numbers per message, i.e. columns of a topic
_FIRST_CAPACITY = 4096  # rows allocated for a topic whose message count is not declared


def _fields(msg: Any) -> list[str]:
    names = getattr(type(msg), "__dataclass_fields__", None)
    if names is not None:
        return [n for n in names if n != "__msgtype__"]
    return [n for n in getattr(type(msg), "__slots__", ()) if not n.startswith("_")]


def stamp_ns(msg: Any) -> int | None:
    """``header.stamp`` [ns], None when the message has no header or a zero stamp."""
    header = getattr(msg, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None:
        return None
    ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
    return ns if ns > 0 else None


class RepeatedName(Exception):
    """A ``name`` list naming one joint more than once."""


def flatten(
    msg: Any, prefix: str, keys: list[str] | None, values: list[float], shape: list[Any]
) -> None:
    """Append the numeric fields of ``msg`` as column names (unless ``keys`` is None: names
    are made once per topic) and values; ``shape`` gets what the names depend on (the joint
    names and array sizes), compared from message to message."""
    names: Any = getattr(msg, "name", None)
    by_name = (
        isinstance(names, list | tuple)
        and len(names) > 0
        and all(isinstance(n, str) for n in names)
    )
    if by_name:
        shape.append(tuple(names))
        if len(set(names)) != len(names):
            repeated = next(n for n in names if names.count(n) > 1)
            raise RepeatedName(
                f"{prefix}/name lists joint '{repeated}' {names.count(repeated)} times "
                f"({', '.join(names)}); each joint must appear once (a repeated name would "
                "merge joints): fix the publisher or drop this topic (topics:)"
            )
    for field in _fields(msg):
        if field == "header":
            continue
        value = getattr(msg, field)
        if isinstance(value, bool | int | float | np.integer | np.floating):
            if keys is not None:
                keys.append(f"{prefix}/{field}")
            values.append(float(value))
        elif isinstance(value, np.ndarray | list | tuple):
            arr = np.asarray(value)
            if arr.dtype.kind not in "iuf" or arr.ndim != 1:
                continue
            shape.append(arr.size)
            if keys is not None:
                if by_name and arr.size == len(names):
                    keys += [f"{prefix}/{field}/{n}" for n in names]
                else:
                    keys += [f"{prefix}/{field}/{k}" for k in range(arr.size)]
            values += arr.tolist()
        elif _fields(value):
            flatten(value, f"{prefix}/{field}", keys, values, shape)


@dataclass(frozen=True, eq=False)
class MessageBlock:
    """Consecutive messages of one topic with a header, decoded at once: their values (m,
    n_values) in the columns of the topic's first message, stamps [ns] (0: none) and
    recorded times [ns], shape (m,)."""

    topic: str
    shape: list[Any]
    values: npt.NDArray[np.float64]
    stamps: npt.NDArray[np.int64]
    recorded: npt.NDArray[np.int64]


class _Topic:
    """One topic's values, written message by message into preallocated arrays."""

    def __init__(
        self,
        source: str,
        topic: str,
        keys: list[str],
        shape: list[Any],
        capacity: int,
        wanted: frozenset[str] | None = None,
    ) -> None:
        # the values kept: the wanted keys when the topic has any, else all of them
        select = [k for k, key in enumerate(keys) if wanted is not None and key in wanted]
        self.select: npt.NDArray[np.intp] | None = np.array(select) if select else None
        if self.select is not None:
            keys = [keys[k] for k in select]
        self.source, self.topic, self.keys, self.shape = source, topic, keys, shape
        self.n = 0
        self.values: npt.NDArray[np.float64] = np.empty((0, len(keys)))
        self.stamps: npt.NDArray[np.int64] = np.empty(0, dtype=np.int64)
        self.recorded: npt.NDArray[np.int64] = np.empty(0, dtype=np.int64)
        self.has_header = False
        self.n_missing = 0
        self.first_missing: int | None = None
        self._allocate(max(1, capacity))

    def _allocate(self, capacity: int) -> None:
        per_row = 8 * (len(self.keys) + 2)  # values, stamp, recorded time
        check_job(
            JobEstimate(
                f"{self.source}: {self.topic}: {capacity} messages x {len(self.keys)} values",
                per_row * capacity,  # the columns are views of these arrays
                0.0,
            )
        )
        # column-major: every column of the table is a contiguous view of this block
        values = np.empty((capacity, len(self.keys)), order="F")
        stamps = np.empty(capacity, dtype=np.int64)
        recorded = np.empty(capacity, dtype=np.int64)
        if self.n:
            values[: self.n] = self.values[: self.n]
            stamps[: self.n] = self.stamps[: self.n]
            recorded[: self.n] = self.recorded[: self.n]
        self.values, self.stamps, self.recorded = values, stamps, recorded

    def add(self, msg: Any, recorded_ns: int, shape: list[Any], values: list[float]) -> None:
        if shape != self.shape:
            raise DataError(
                f"{self.source}: topic {self.topic} changes its fields (joint names) at "
                f"message {self.n}; split the recording or read another topic (topics:)."
            )
        if self.n == self.values.shape[0]:
            self._allocate(2 * self.n)
        stamp = stamp_ns(msg)
        if getattr(msg, "header", None) is not None:
            self.has_header = True
        if stamp is None:
            self.n_missing += 1
            if self.first_missing is None:
                self.first_missing = self.n
            stamp = 0
        if self.select is None:
            self.values[self.n] = values
        else:
            self.values[self.n] = np.asarray(values)[self.select]
        self.stamps[self.n] = stamp
        self.recorded[self.n] = recorded_ns
        self.n += 1

    def add_block(self, block: MessageBlock) -> None:
        """Messages decoded a chunk at once (:mod:`ident.measure.readers.mcap_chunks`)."""
        if block.shape != self.shape:
            raise DataError(
                f"{self.source}: topic {self.topic} changes its fields (joint names) at "
                f"message {self.n}; split the recording or read another topic (topics:)."
            )
        m = block.values.shape[0]
        if self.n + m > self.values.shape[0]:
            self._allocate(max(2 * self.n, self.n + m))
        values = block.values if self.select is None else block.values[:, self.select]
        self.values[self.n : self.n + m] = values
        self.stamps[self.n : self.n + m] = block.stamps
        self.recorded[self.n : self.n + m] = block.recorded
        self.has_header = True
        missing = np.flatnonzero(block.stamps == 0)
        if missing.size and self.first_missing is None:
            self.first_missing = self.n + int(missing[0])
        self.n_missing += int(missing.size)
        self.n += m

    def times_ns(self) -> tuple[npt.NDArray[np.int64], str | None]:
        """Stamps [ns] by the rule of the module docstring, and the warning it gives."""
        if not self.has_header:
            return self.recorded[: self.n], None
        if self.n_missing == 0:
            return self.stamps[: self.n], None
        warning = (
            f"{self.source}: {self.topic}: {self.n_missing} of {self.n} messages have no "
            f"header.stamp, the first is message {self.first_missing}; the topic uses the "
            "time each message was recorded"
        )
        return self.recorded[: self.n], warning


def message_tables(
    source: str,
    messages: Iterable[tuple[str, int, Any] | MessageBlock],
    topics: list[str] | None,
    counts: Mapping[str, int],
    columns: Iterable[str] | None = None,
) -> list[LogTable]:
    """Group ``(topic, recorded_ns, message)`` into one table per topic (in recorded order).

    ``counts``: messages per topic the file declares (preallocation), when it does.
    ``columns``: the columns to keep (option ``columns``, module docstring), None for all.
    """
    built = _topics(source, messages, topics, counts, columns)
    if topics is not None:
        missing = [t for t in topics if t not in built]
        if missing:
            raise DataError(
                f"{source}: topic(s) {', '.join(missing)} have no numeric messages; the file "
                f"has {', '.join(sorted(built)) or 'none'}."
            )
    if not built:
        return []
    return _as_tables(source, built)


def _topics(
    source: str,
    messages: Iterable[tuple[str, int, Any] | MessageBlock],
    topics: list[str] | None,
    counts: Mapping[str, int],
    columns: Iterable[str] | None,
) -> dict[str, _Topic]:
    """The values of every topic of ``topics`` (None: every one) with numeric fields,
    message by message (or a block at a time), by topic in the order first seen
    (:func:`message_tables`)."""
    wanted = None if columns is None else frozenset(columns)
    built: dict[str, _Topic] = {}
    for item in messages:
        if isinstance(item, MessageBlock):  # follows the topic's first message, read one by one
            built[item.topic].add_block(item)
            continue
        topic, recorded_ns, msg = item
        if topics is not None and topic not in topics:
            continue
        entry = built.get(topic)
        keys: list[str] | None = [] if entry is None else None
        values: list[float] = []
        shape: list[Any] = []
        try:
            flatten(msg, topic, keys, values, shape)
        except RepeatedName as e:
            n = entry.n if entry is not None else 0
            raise DataError(f"{source}: message {n} of {topic}: {e}.") from None
        if len(values) > MAX_VALUES:
            raise DataError(
                f"{source}: a message of {topic} holds {len(values)} numbers, more than "
                f"{MAX_VALUES} per message; read other topics (topics:)."
            )
        if not values:
            continue
        if entry is None:
            assert keys is not None
            capacity = counts.get(topic) or _FIRST_CAPACITY
            entry = built[topic] = _Topic(source, topic, keys, shape, capacity, wanted)
        entry.add(msg, recorded_ns, shape, values)
    return built


def _as_tables(source: str, built: dict[str, _Topic]) -> list[LogTable]:
    """One :class:`LogTable` per topic of ``built`` (not empty): its time column ``<topic>/t``
    [s] from the first message of the file (the time rule of the module docstring, in
    integer nanoseconds), its value columns views of the topic's arrays."""
    times = {topic: entry.times_ns() for topic, entry in built.items()}
    t0 = min(int(ns.min()) for ns, _ in times.values())
    tables = []
    for topic, entry in built.items():
        ns, warning = times[topic]
        columns = {f"{topic}/t": (ns - t0).astype(float) * 1e-9}
        block = entry.values
        if entry.n < block.shape[0] // 2:  # far fewer messages than declared: trim the block
            block = np.asfortranarray(block[: entry.n])
        for k, key in enumerate(entry.keys):
            columns[key] = block[: entry.n, k]  # views, no copy
        tables.append(
            LogTable(
                columns=columns,
                time=f"{topic}/t",
                source=f"{source} {topic}",
                warnings=(warning,) if warning else (),
            )
        )
    return tables
