"""ROS 2 logs: bag folders (``rosbags``) and bare ``.mcap`` files (``mcap-ros2-support``).

Each topic becomes one :class:`~ident.measure.readers.LogTable` with a time column
``<topic>/t`` [s], relative to the first message of the file, computed in integer nanoseconds so
that an epoch time keeps its sub-microsecond resolution. Message fields become columns:

- ``sensor_msgs/JointState`` (and any message with a ``name`` list and arrays of the same
  length): ``<topic>/position/<joint name>``, ``<topic>/velocity/<joint name>``,
  ``<topic>/effort/<joint name>``; a name listed twice is refused (it would merge joints);
- other messages: every numeric field ``<topic>/<field>``, numeric arrays
  ``<topic>/<field>/<index>``, nested messages ``<topic>/<field>/<sub>``
  (e.g. ``std_msgs/Float64MultiArray`` -> ``/cmd/data/0``).

Time of a message: its ``header.stamp`` when every message of the topic has a non-zero one;
when some or all lack it, the whole topic uses the time each message was recorded (never a mix
of the two clocks, which can be 1.7e9 s apart), with a warning naming the count and the first
message; a topic whose messages have no header uses the recorded time. Messages are kept in
the order they were recorded: the time rule of :mod:`ident.measure.timebase` then handles
duplicates and backwards jumps.

Bounded memory: messages are decoded one at a time and their values written into arrays
preallocated from the message counts the file declares (doubled when it declares none); the
arrays' size is checked against ``IDENT_MAX_MEMORY_GB`` before each allocation. A bag
compressed as whole files is decompressed 1 MB at a time into a temporary folder, refused as
soon as it passes the same ceiling (or its zstd frame declares more). A compressed
MCAP chunk may not declare more than :data:`MAX_CHUNK_BYTES` once decompressed, a message may
not be longer than :data:`MAX_MESSAGE_BYTES` nor hold more than :data:`MAX_VALUES` numbers;
all are checked before the data are decompressed or decoded.

Why two libraries: ``rosbags`` reads ROS 2 bag *folders* (``metadata.yaml`` with sqlite3 or
mcap storage) and needs no ROS installation; a single ``.mcap`` file without its folder (as
Foxglove and many loggers write) carries its message definitions in the file and is decoded by
``mcap-ros2-support``, which builds the message classes from those definitions.

Option ``topics``: the topics to read (default: every topic with numeric fields). Option
``columns``: the column names the caller will use; a topic that holds some of them keeps only
those (a 7-joint ``JointState`` log read for positions and efforts keeps 14 of its 21 value
columns: 37 % less memory on a long log); a topic that holds none of them keeps all.
"""

from __future__ import annotations

import dataclasses
import tempfile
from collections.abc import Iterable, Iterator, Mapping
from pathlib import Path, PurePath
from typing import Any

import numpy as np

from ident.errors import DataError, IdentError
from ident.inputs import JobEstimate, check_job, resource_ceilings
from ident.measure.readers.registry import LogTable
from ident.measure.readers.ros_messages import (
    MAX_VALUES,
    MessageBlock,
    RepeatedName,
    flatten,
    message_tables,
    stamp_ns,
)

__all__ = [
    "MAX_CHUNK_BYTES",
    "MAX_MESSAGE_BYTES",
    "MAX_VALUES",
    "estimate_mcap",
    "estimate_rosbag",
    "is_mcap",
    "is_rosbag",
    "read_mcap",
    "read_rosbag",
]

# Writers use chunks of 1 to 4 MB and a JointState of 7 joints is about 300 bytes: these bounds
# leave a wide margin and stop a decompression bomb before it is decompressed.
MAX_CHUNK_BYTES = 64 << 20
MAX_MESSAGE_BYTES = 16 << 20
_DECOMPRESS_BYTES = 1 << 20  # a whole-file compressed bag is decompressed 1 MB at a time
_SECONDS_PER_MESSAGE = 1e-4  # decoding and flattening one by one, measured: 70 us
_SECONDS_PER_JOINT_STATE = 1e-5  # a JointState of an MCAP chunk read at once: 4.1 s for 600k
# messages at load 11 on 2 cores (a long log's figure; mcap_chunks)


def is_rosbag(path: Path) -> bool:
    """Detector: a folder with ``metadata.yaml`` (a ROS 2 bag)."""
    return path.is_dir() and (path / "metadata.yaml").is_file()


def is_mcap(path: Path) -> bool:
    """Detector: a file named ``*.mcap``."""
    return path.is_file() and path.suffix == ".mcap"


def _damaged(path: Path, what: str, e: Exception) -> DataError:
    return DataError(
        f"{path}: cannot read the {what} ({type(e).__name__}: {e}); the file is damaged or "
        "not what it declares: copy it again from the robot, or re-record it."
    )


def _too_big(path: Path, what: str, size: int, limit: int) -> DataError:
    return DataError(
        f"{path}: {what} declares {size} bytes once decompressed, more than {limit} allowed "
        "(a decompression bomb or a damaged file); re-record it with smaller chunks."
    )


def _estimate(
    path: Path, n_messages: int, n_bytes: int, n_fast: int = 0, kept: float = 0.0
) -> JobEstimate:
    """Reading ``n_messages`` of ``n_bytes`` serialized, ``n_fast`` of them ``JointState``
    messages of an MCAP file (read a chunk at once). Memory: the numbers of a message take at
    most its bytes (8 each in CDR), plus its two stamps and its time, 24 bytes (a bound: a
    7-joint JointState of 387 bytes holds 21 numbers, 168 bytes); ``kept`` [bytes] lowers that
    bound where the numbers are known (:func:`_joint_state_bytes`)."""
    seconds = (n_messages - n_fast) * _SECONDS_PER_MESSAGE + n_fast * _SECONDS_PER_JOINT_STATE
    memory = max(n_bytes + 24.0 * n_messages - kept, 0.0)
    return JobEstimate(f"reading {path.name}: {n_messages} messages", memory, seconds)


def _joint_state_bytes(path: Path, f: Any, channel: Any, n: int) -> float:
    """How much lower the bound of :func:`_estimate` is for the ``n`` messages of a
    ``JointState`` channel once its first message is decoded (as the reader decodes it): each
    takes its numbers, stamp and time (8 bytes each), not its serialized size plus 24 bytes
    (an hour at 1 kHz of 7 joints: 0.66 GB instead of 1.48 GB). 0 when it cannot be decoded:
    the reader then says why."""
    from mcap.reader import make_reader

    try:
        f.seek(0)
        for schema, ch, message in make_reader(f).iter_messages(topics=[channel.topic]):
            values: list[float] = []
            flatten(_Decoders().get(path, schema, ch)(message.data), ch.topic, None, values, [])
            return max(0.0, n * (len(message.data) + 24.0 - 8.0 * (len(values) + 2)))
    except Exception:  # a bound is still given; reading reports the problem
        return 0.0
    return 0.0


def estimate_mcap(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading the MCAP file ``path``, from its summary (or its size)."""
    from mcap.reader import make_reader

    size = path.stat().st_size
    try:
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
    except Exception:  # no readable summary (a recording cut off): from the size
        summary = None
    if summary is None or summary.statistics is None:
        return _estimate(path, size // 300, size)
    n_bytes = sum(c.uncompressed_size for c in summary.chunk_indexes) or size
    n_fast, kept = 0, 0.0
    if summary.chunk_indexes:  # read a chunk at once (_indexed_messages)
        with open(path, "rb") as f:
            _check_chunks(path, f, summary)  # before a chunk is decompressed
            for channel_id, n in summary.statistics.channel_message_counts.items():
                channel = summary.channels.get(channel_id)
                schema = summary.schemas.get(channel.schema_id) if channel is not None else None
                if schema is not None and schema.name.endswith("JointState"):
                    n_fast += int(n)
                    kept += _joint_state_bytes(path, f, channel, int(n))
    return _estimate(path, int(summary.statistics.message_count), n_bytes, n_fast, kept)


def estimate_rosbag(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading the bag folder ``path``, from its metadata and file sizes."""
    from ident.config import read_yaml

    n_bytes = sum(p.stat().st_size for p in path.iterdir() if p.is_file())
    try:  # the metadata only: opening the bag would decompress a compressed one
        info = read_yaml(path / "metadata.yaml")["rosbag2_bagfile_information"]
        n_messages = int(info["message_count"])
    except (IdentError, KeyError, TypeError, ValueError) as e:
        raise DataError(
            f"{path}/metadata.yaml: no rosbag2_bagfile_information.message_count ({e}); "
            "the bag's metadata is damaged: copy the bag again or re-record it."
        ) from e
    if info.get("compression_mode") == "file":  # stored compressed: about 3x once read
        n_bytes *= 3
    return _estimate(path, n_messages, n_bytes)


def _decompress_file(source: Path, target: Path) -> None:
    """Decompress the zstd file ``source`` into ``target``, a block at a time, refused when
    the size its frame declares, or the bytes written so far, pass the memory ceiling (the
    bag's messages are read from it: a small file that decompresses to terabytes stops at
    the ceiling, not when the disk is full).

    Raises
    ------
    ResourceLimitError
        Naming the file and ``IDENT_MAX_MEMORY_GB``.
    """
    import zstandard

    ceiling, _ = resource_ceilings()

    def refuse(size: float, what: str) -> None:
        check_job(JobEstimate(f"{source}: {what} {size:.0f} bytes once decompressed", size, 0.0))

    with open(source, "rb") as f:
        declared = zstandard.frame_content_size(f.read(18))
        if declared > ceiling:  # -1: not declared
            refuse(declared, "declares")
        f.seek(0)
        total = 0
        reader = zstandard.ZstdDecompressor().stream_reader(f, read_across_frames=True)
        with open(target, "wb") as out:
            while block := reader.read(_DECOMPRESS_BYTES):
                total += len(block)
                if total > ceiling:
                    refuse(total, "holds more than")
                out.write(block)


def _decompressed_bag(path: Path, folder: Path) -> Path:
    """``path`` itself, or when the bag is compressed as whole files (``compression_mode:
    file``), a copy in ``folder`` with its files decompressed by :func:`_decompress_file`
    and its ``metadata.yaml`` saying so (``rosbags`` would decompress them without a bound)."""
    import yaml

    from ident.config import read_yaml

    metadata = read_yaml(path / "metadata.yaml")
    info = metadata.get("rosbag2_bagfile_information") if isinstance(metadata, dict) else None
    if not isinstance(info, dict) or str(info.get("compression_mode", "")).lower() != "file":
        return path
    names = []
    for relative in info.get("relative_file_paths") or []:
        source = path / PurePath(str(relative)).name
        _decompress_file(source, folder / source.stem)
        names.append(source.stem)
    info = {**info, "relative_file_paths": names, "compression_mode": "", "compression_format": ""}
    (folder / "metadata.yaml").write_text(
        yaml.safe_dump({**metadata, "rosbag2_bagfile_information": info})
    )
    return folder


def read_rosbag(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a ROS 2 bag folder (sqlite3 or mcap storage) with ``rosbags``; a bag compressed
    as whole files is decompressed with a bound first (:func:`_decompressed_bag`)."""
    try:
        with tempfile.TemporaryDirectory(prefix="ident-bag-") as tmp:
            bag = _decompressed_bag(path, Path(tmp))
            return _read_bag(path, bag, options)
    except IdentError:
        raise
    except Exception as e:  # rosbags, sqlite3, zstandard, CDR decoding: a damaged bag
        raise _damaged(path, "ROS 2 bag", e) from e


def _read_bag(path: Path, bag: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """The tables of the bag folder ``path``, read from ``bag`` (itself or its decompressed
    copy)."""
    from mcap.reader import make_reader
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS2_HUMBLE)
    topics = options.get("topics")
    for storage in sorted(bag.glob("*.mcap")):  # mcap storage: chunks checked first
        with open(storage, "rb") as f:
            _check_chunks(storage, f, make_reader(f).get_summary())
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if topics is None or c.topic in topics]
        counts: dict[str, int] = {}
        for c in connections:
            counts[c.topic] = counts.get(c.topic, 0) + int(c.msgcount)

        _register_types(path, typestore, connections)

        def messages() -> Iterator[tuple[str, int, Any]]:
            for conn, timestamp, raw in reader.messages(connections=connections):
                if len(raw) > MAX_MESSAGE_BYTES:
                    raise _too_big(path, f"a message of {conn.topic}", len(raw), MAX_MESSAGE_BYTES)
                yield conn.topic, timestamp, typestore.deserialize_cdr(raw, conn.msgtype)

        return message_tables(str(path), messages(), topics, counts, options.get("columns"))


def _register_types(path: Path, typestore: Any, connections: list[Any]) -> None:
    """Make every connection's message type known: a standard ROS 2 type, or the definition
    the bag carries; else one error naming the type (not "the file is damaged")."""
    from rosbags.typesys import get_types_from_idl, get_types_from_msg

    for conn in connections:
        if conn.msgtype in typestore.fielddefs:
            continue
        msgdef = getattr(conn, "msgdef", None)
        text = getattr(msgdef, "data", "") or ""
        try:
            if "MSG" in str(getattr(msgdef, "format", "")).upper() and text:
                typestore.register(get_types_from_msg(text, conn.msgtype))
            elif text:
                typestore.register(get_types_from_idl(text))
        except Exception:  # noqa: BLE001 - an unparsable definition: the type stays unknown
            pass
        if conn.msgtype not in typestore.fielddefs:
            raise DataError(
                f"{path}: topic {conn.topic}: message type {conn.msgtype} is not known: it is "
                "no standard ROS 2 (Humble) type and the bag carries no definition of it; "
                "leave the topic out with topics:, or record it with a ROS 2 that stores "
                "message definitions."
            )


def _check_chunks(path: Path, f: Any, summary: Any) -> None:
    """Refuse chunks whose declared decompressed size is above :data:`MAX_CHUNK_BYTES`
    (from the summary, or by a pass over the records when the file has none)."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader

    if summary is not None and summary.chunk_indexes:
        sizes = [(c.uncompressed_size, c.compression) for c in summary.chunk_indexes]
    else:
        f.seek(0)
        sizes = [
            (r.uncompressed_size, r.compression)
            for r in StreamReader(f, emit_chunks=True, record_size_limit=MAX_CHUNK_BYTES).records
            if isinstance(r, Chunk)
        ]
    for size, compression in sizes:
        if size > MAX_CHUNK_BYTES:
            raise _too_big(path, f"a {compression or 'plain'} chunk", size, MAX_CHUNK_BYTES)


class _Decoders:
    """CDR decoders of an MCAP file's channels: the ``rosbags`` type system built from the
    definitions the file carries (about 5x faster than ``mcap-ros2-support``'s), else
    ``mcap-ros2-support``."""

    def __init__(self) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.typestore = get_typestore(Stores.EMPTY)
        self.by_channel: dict[int, Any] = {}

    def get(self, path: Path, schema: Any, channel: Any) -> Any:
        decoder = self.by_channel.get(channel.id)
        if decoder is not None:
            return decoder
        if channel.message_encoding != "cdr" or schema is None:
            raise DataError(
                f"{path}: topic {channel.topic} is encoded as {channel.message_encoding!r}; "
                "only ROS 2 (cdr) messages are read: leave it out with topics:."
            )
        try:
            decoder = self._rosbags(schema)
        except Exception:  # a definition rosbags does not parse: the reference decoder
            from mcap_ros2.decoder import DecoderFactory

            decoder = DecoderFactory().decoder_for(channel.message_encoding, schema)
        if decoder is None:
            raise DataError(f"{path}: no decoder for the messages of {channel.topic}.")
        self.by_channel[channel.id] = decoder
        return decoder

    def _rosbags(self, schema: Any) -> Any:
        from rosbags.typesys import get_types_from_idl, get_types_from_msg

        text = schema.data.decode()
        if schema.encoding == "ros2msg":
            types = get_types_from_msg(text, schema.name)
        elif schema.encoding == "ros2idl":
            types = get_types_from_idl(text)
        else:
            raise ValueError(schema.encoding)
        self.typestore.register(types)
        name = schema.name
        typestore = self.typestore
        return lambda data: typestore.deserialize_cdr(data, name)


def _linear_messages(path: Path, f: Any, cut: list[str]) -> Iterator[tuple[Any, Any, Any]]:
    """``(schema, channel, message)`` of an MCAP file without a usable summary (a writer that
    wrote none, or a recording cut off: no footer), record by record, chunks checked before
    they are decompressed. At a damaged or missing end after at least one message, reading
    stops and ``cut`` gets a warning; before any message, the error is raised."""
    from mcap.records import Channel, Chunk, Message, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    f.seek(0)
    schemas: dict[int, Any] = {}
    channels: dict[int, Any] = {}
    n = 0
    records = StreamReader(f, record_size_limit=MAX_CHUNK_BYTES).records
    while True:
        try:
            record = next(records)
            if isinstance(record, Chunk):
                if record.uncompressed_size > MAX_CHUNK_BYTES:
                    raise _too_big(
                        path,
                        f"a {record.compression} chunk",
                        record.uncompressed_size,
                        MAX_CHUNK_BYTES,
                    )
                inner = breakup_chunk(record, validate_crc=True)
            else:
                inner = [record]
        except StopIteration:
            return
        except IdentError:
            raise
        except Exception as e:  # a file cut off mid-record, or damaged from here on
            if n == 0:
                raise
            cut.append(
                f"{path}: the file ends early or is damaged after {n} messages "
                f"({type(e).__name__}); the messages before are read, the rest is lost "
                "(a recording cut off?)"
            )
            return
        for r in inner:
            if isinstance(r, Schema):
                schemas[r.id] = r
            elif isinstance(r, Channel):
                channels[r.id] = r
            elif isinstance(r, Message) and r.channel_id in channels:
                channel = channels[r.channel_id]
                n += 1
                yield schemas.get(channel.schema_id), channel, r


def _indexed_messages(
    path: Path, f: Any, summary: Any, topics: list[str] | None, decoders: _Decoders
) -> Iterator[tuple[str, int, Any] | MessageBlock]:
    """The messages of an MCAP file with a summary, one chunk at a time, in file order
    (:func:`~ident.measure.readers.mcap_chunks.chunk_messages`): ``(topic, recorded_ns,
    message)``, and after a ``JointState`` topic's first message, the topic's messages of a
    chunk that fit its layout as one :class:`MessageBlock`."""
    from ident.measure.readers.mcap_chunks import JointStateLayout, chunk_messages

    layouts: dict[int, JointStateLayout | None] = {}
    for data, records in chunk_messages(f, summary):
        by_channel: dict[int, list[tuple[int, int, int]]] = {}
        for channel_id, log_time, offset, length in records:
            channel = summary.channels.get(channel_id)
            if channel is None or (topics is not None and channel.topic not in topics):
                continue
            if length > MAX_MESSAGE_BYTES:
                raise _too_big(path, f"a message of {channel.topic}", length, MAX_MESSAGE_BYTES)
            by_channel.setdefault(channel_id, []).append((log_time, offset, length))
        for channel_id, found in by_channel.items():
            channel = summary.channels[channel_id]
            schema = summary.schemas.get(channel.schema_id)
            decode = decoders.get(path, schema, channel)
            if channel_id not in layouts:  # the first message, read one by one
                log_time, offset, length = found.pop(0)
                msg = decode(data[offset : offset + length])
                yield channel.topic, log_time, msg
                layouts[channel_id] = _layout(msg, channel.topic, data[offset : offset + length])
            layout = layouts[channel_id]
            block = None if layout is None or not found else _block(layout, channel, data, found)
            if block is not None:
                yield block
                continue
            for log_time, offset, length in found:
                yield channel.topic, log_time, decode(data[offset : offset + length])


def _layout(msg: Any, topic: str, data: bytes) -> Any:
    """The ``JointStateLayout`` of a topic from its first message (decoded ``msg``, bytes
    ``data``), or None when its messages are read one by one."""
    from ident.measure.readers.mcap_chunks import JointStateLayout

    if getattr(msg, "header", None) is None or getattr(msg, "name", None) is None:
        return None
    values: list[float] = []
    shape: list[Any] = []
    try:
        flatten(msg, topic, None, values, shape)
    except RepeatedName:
        return None
    layout = JointStateLayout.of(data, values, stamp_ns(msg))
    return None if layout is None else (layout, shape)


def _block(layout_shape: Any, channel: Any, data: bytes, found: list) -> MessageBlock | None:
    """The messages ``found`` ``(log_time, offset, length)`` of one chunk as a block, or None
    when one of them does not fit the layout."""
    layout, shape = layout_shape
    length = layout.template.size
    if any(n != length for _, _, n in found):
        return None
    offsets = np.array([o for _, o, _ in found], dtype=np.int64)
    values, stamps, fits = layout.read(layout.rows(data, offsets))
    if not fits.all():
        return None
    recorded = np.array([t for t, _, _ in found], dtype=np.int64)
    return MessageBlock(channel.topic, shape, values, stamps, recorded)


def read_mcap(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a bare ``.mcap`` file of ROS 2 messages (in the order of the file: one chunk is
    decompressed at a time). A file without a readable summary (cut off by a crash) is read
    record by record up to its damaged end, with a warning."""
    from mcap.reader import make_reader

    topics = options.get("topics")
    try:
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            try:
                summary = reader.get_summary()
            except Exception:  # no footer: a recording cut off, read record by record
                summary = None
            if summary is None or not summary.chunk_indexes:
                return _linear_tables(path, f, topics, options.get("columns"))
            _check_chunks(path, f, summary)
            counts = _declared_counts(summary)
            tables = message_tables(
                str(path),
                _indexed_messages(path, f, summary, topics, _Decoders()),
                topics,
                counts,
                options.get("columns"),
            )
            return tables  # a complete file: nothing cut
    except IdentError:
        raise
    except MemoryError as e:
        raise DataError(
            f"{path}: out of memory while reading; read fewer topics (topics:) or a shorter "
            "recording."
        ) from e
    except Exception as e:  # mcap, zstd/lz4, CDR decoding, struct: a damaged file
        raise _damaged(path, "MCAP file", e) from e


def _declared_counts(summary: Any) -> dict[str, int]:
    """Messages per topic an MCAP file's ``summary`` declares (none without statistics)."""
    counts: dict[str, int] = {}
    if summary.statistics is not None:
        for channel_id, n in summary.statistics.channel_message_counts.items():
            channel = summary.channels.get(channel_id)
            if channel is not None:
                counts[channel.topic] = counts.get(channel.topic, 0) + int(n)
    return counts


def _linear_tables(
    path: Path, f: Any, topics: list[str] | None, columns: Iterable[str] | None
) -> list[LogTable]:
    """The tables of the open MCAP file ``f`` (``path``) without a usable summary, read
    record by record (:func:`_linear_messages`); at a damaged end, every table carries the
    warning of where it was cut."""
    cut: list[str] = []
    found = _linear_messages(path, f, cut)
    decoders = _Decoders()

    def messages() -> Iterator[tuple[str, int, Any]]:
        for schema, channel, message in found:
            if topics is not None and channel.topic not in topics:
                continue
            if len(message.data) > MAX_MESSAGE_BYTES:
                raise _too_big(
                    path,
                    f"a message of {channel.topic}",
                    len(message.data),
                    MAX_MESSAGE_BYTES,
                )
            decode = decoders.get(path, schema, channel)
            yield channel.topic, message.log_time, decode(message.data)

    tables = message_tables(str(path), messages(), topics, {}, columns)
    return [dataclasses.replace(t, warnings=(*t.warnings, *cut)) for t in tables]
