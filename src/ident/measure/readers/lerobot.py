"""LeRobot datasets (v2.x layout): parquet tables of position-servo arms, one episode a segment.

A dataset folder holds ``meta/info.json`` (``fps``; ``features``: per feature its ``dtype``,
``shape`` and ``names``, the joint names) and ``data/chunk-000/episode_000000.parquet``, ...:
one row per frame with ``timestamp`` [s] (from the episode's start), ``frame_index``,
``episode_index``, ``index`` and the features, ``observation.state`` (measured positions) and
``action`` (commanded positions) each a fixed-length list of numbers per frame. Every parquet
file under ``data/`` is read, in path order (a file may hold several episodes: episodes are cut
where ``episode_index`` changes). One episode ``.parquet`` file is read alone too (its
``meta/info.json`` two folders up when there is one).

Columns: a list feature ``f`` becomes ``f/<name>`` per element, its name from ``info.json``
(``names`` a list, or a mapping holding one list such as ``{"motors": [...]}``; a ``.pos``
suffix every name carries is dropped: ``shoulder_pan.pos`` -> ``shoulder_pan``), ``f/0``,
``f/1`` ... without names; a scalar feature keeps its name. Images, videos and strings are
not read.

Time: the episodes one after another, as :mod:`ident.measure.logs` joins several logs: each
episode's ``timestamp`` shifted to start :data:`EPISODE_GAP_S` after the previous episode's
end (``windows:`` read this continued time), and every episode its own segment
(:attr:`LogTable.segment_starts`): nothing is filtered or differentiated across an episode
boundary, whatever ``gap_factor`` or ``max_gap_s`` say. An episode whose float32 timestamps
are ``frame_index / fps`` rounded (as LeRobot writes them) takes ``frame_index / fps`` in
float64: exact however long the episode (float32 stamps look jittered past 512 s).

Refused, naming the file and the field: a column the config needs that the dataset lacks
(listing those it has), a timestamp that does not increase within an episode (naming the
episode and the frame), ``fps`` of ``info.json`` that the timestamps contradict by more than
:data:`FPS_RTOL`, list lengths that differ from the declared ``shape``, null rows. Positions
are servo angles: after the config's unit conversion they must stay within
:data:`ANGLE_BOUND_RAD` (:attr:`LogTable.angle_bound_rad`, checked by
:mod:`ident.measure.logs`): ticks or degrees declared as radians are caught there.

An episode file of no frames (a recording stopped before its first frame, a conversion that
wrote only the schema) is skipped with a warning naming it (the terminal, ``result.json``, the
report; ``validation.fail_on_warning`` makes it fatal) when other episodes hold frames: it holds
no data, so the result is the one of the dataset without it, and refusing would only make the
user edit a dataset they may not own (one downloaded from the Hub). A dataset whose every
episode is empty is refused.

Bounded memory: the sizes come from the parquet footers (rows per row group, bytes per column
chunk) before anything is read; the columns' float64 arrays plus the largest column chunk are
checked against ``IDENT_MAX_MEMORY_GB`` and allocated once; then one column of one row group is
read at a time (pyarrow) and converted into its place. Only the features the config names are
read (with ``timestamp``, ``frame_index``, ``episode_index``); option ``topics`` (``ident logs
inspect --topic``) names the features to read, a dataset's features being its topics.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.parquet as pq

from ident.config import read_text_input
from ident.errors import ConfigError, DataError
from ident.inputs import JobEstimate, check_job
from ident.measure.readers.lerobot_layout import (
    EPISODE_COLUMN,
    FRAME_COLUMN,
    INFO_PATH,
    TIME_COLUMN,
    is_lerobot,
)
from ident.measure.readers.registry import LogTable, check_regular_file

__all__ = [
    "ANGLE_BOUND_RAD",
    "EPISODE_GAP_S",
    "FPS_RTOL",
    "estimate_lerobot",
    "is_lerobot",
    "read_lerobot",
]

FloatArray = npt.NDArray[np.float64]

# A servo's angle (one turn, STS3215 / Dynamixel position mode) with a margin for a calibration
# offset: radians beyond it were logged in ticks (0..4095) or degrees.
ANGLE_BOUND_RAD = 2.0 * np.pi * 1.5
EPISODE_GAP_S = 1.0  # time between episodes in the continued time (as between logs)
FPS_RTOL = 0.01  # relative difference of the median step from 1/fps that is refused
_INFO_BYTES = 4 << 20  # info.json holds the features and paths, never data
_TIME, _EPISODE, _FRAME = TIME_COLUMN, EPISODE_COLUMN, FRAME_COLUMN
# A float32 stamp is its value to 2^-24 relative (half a unit in the last place); twice that
# tells LeRobot's frame_index / fps from recorded stamps (which differ by clock jitter).
_FLOAT32_ROUNDING = 2.0**-23
_SECONDS_PER_VALUE = 2e-8  # read and converted per value (estimate: 50 M values/s)


@dataclass(frozen=True)
class _Field:
    """One numeric column of the parquet files: its values per row (``width``), the column
    names it gives, and whether it is a list (else a scalar)."""

    name: str
    width: int
    names: tuple[str, ...]
    is_list: bool


@dataclass(frozen=True, eq=False)
class _Plan:
    """What reading will do, from ``info.json`` and the parquet footers only."""

    root: Path
    files: tuple[Path, ...]
    rows: tuple[int, ...]  # per file
    fields: tuple[_Field, ...]
    fps: float | None
    info_path: Path | None
    chunk_bytes: float  # the largest column chunk of a selected field, uncompressed

    @property
    def n_rows(self) -> int:
        return sum(self.rows)

    @property
    def empty_files(self) -> tuple[Path, ...]:
        """The episode files of no frames (skipped)."""
        return tuple(f for f, n in zip(self.files, self.rows, strict=True) if n == 0)

    def memory_bytes(self) -> float:
        """The float64 columns plus one column chunk and its float64 copy."""
        width = sum(f.width for f in self.fields)
        return 8.0 * self.n_rows * width + 3.0 * self.chunk_bytes


def _dataset(path: Path) -> tuple[Path, tuple[Path, ...], Path | None]:
    """(dataset root, parquet files in path order, info.json or None) of ``path``."""
    if path.is_dir():
        info = path / INFO_PATH
        if info.exists():
            check_regular_file(info)  # a folder or a device named as what it is
        else:
            raise DataError(
                f"{path}: not a LeRobot dataset (meta/info.json not found); give the dataset "
                "folder (meta/ and data/ inside) or one episode .parquet file."
            )
        files = tuple(sorted((path / "data").rglob("*.parquet")))
        if not files:
            raise DataError(f"{path}: no .parquet file under data/; is the dataset complete?")
        for f in files:
            check_regular_file(f)
        return path, files, info
    check_regular_file(path)
    info = path.parent.parent.parent / INFO_PATH  # data/chunk-000/<file>
    return path.parent, (path,), info if info.is_file() else None


def _load_info(info_path: Path) -> dict[str, Any]:
    """``info.json`` as a dict with a positive ``fps`` and a ``features`` mapping."""
    try:
        info = json.loads(read_text_input(info_path, what="dataset info", max_bytes=_INFO_BYTES))
    except (ValueError, RecursionError) as e:
        raise DataError(f"{info_path}: not valid JSON ({e}).") from e
    except ConfigError as e:
        raise DataError(str(e)) from e
    if not isinstance(info, dict):
        raise DataError(f"{info_path}: holds {type(info).__name__}, a JSON object expected.")
    fps = info.get("fps")
    if isinstance(fps, bool) or not isinstance(fps, int | float) or not 0 < fps < 1e6:
        raise DataError(
            f"{info_path}: fps = {fps!r}; the recording rate in frames per second expected."
        )
    if not isinstance(info.get("features", {}), dict):
        raise DataError(f"{info_path}: features is not a mapping of feature name -> spec.")
    return info


def _declared_names(info: Mapping[str, Any] | None, name: str) -> list[str] | None:
    """The element names ``info.json`` gives a feature (a list, or a mapping holding one
    list), None when it gives none."""
    spec = (info or {}).get("features", {}).get(name)
    names = spec.get("names") if isinstance(spec, dict) else None
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    if isinstance(names, list) and names and all(isinstance(n, str) for n in names):
        if all(n.endswith(".pos") for n in names):
            names = [n.removesuffix(".pos") for n in names]
        return names
    return None


def _declared_width(info: Mapping[str, Any] | None, name: str) -> int | None:
    spec = (info or {}).get("features", {}).get(name)
    shape = spec.get("shape") if isinstance(spec, dict) else None
    if isinstance(shape, list) and shape and all(isinstance(s, int) and s > 0 for s in shape):
        return int(np.prod(shape))
    return None


def _is_number(t: pa.DataType) -> bool:
    return bool(pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_boolean(t))


def _field(
    pf: pq.ParquetFile, file: Path, name: str, info: Mapping[str, Any] | None, info_path: Any
) -> _Field | None:
    """The :class:`_Field` of column ``name``, None when it holds no numbers (images, text)."""
    t = pf.schema_arrow.field(name).type
    if _is_number(t):
        return _Field(name, 1, (name,), False)
    if not (pa.types.is_list(t) or pa.types.is_fixed_size_list(t)) or not _is_number(t.value_type):
        return None
    declared = _declared_width(info, name)
    width = t.list_size if pa.types.is_fixed_size_list(t) else declared
    if width is None and pf.metadata.num_row_groups == 0:
        width = 0
    if width is None:  # a variable list and no info.json: the first row's length
        first = pf.read_row_group(0, columns=[name]).column(0)
        width = len(first[0]) if len(first) and first[0].is_valid else 0
    if declared is not None and declared != width:
        raise DataError(
            f"{info_path}: features.{name}.shape declares {declared} values per frame, "
            f"{file} holds lists of {width}; fix the shape or the file."
        )
    names = _declared_names(info, name) or [str(k) for k in range(width)]
    if len(names) != width or len(set(names)) != width:
        raise DataError(
            f"{info_path}: features.{name}.names lists {len(names)} names "
            f"({', '.join(names)}) for {width} values per frame, each once expected."
        )
    return _Field(name, width, tuple(f"{name}/{n}" for n in names), True)


def _selected(wanted: Any, present: list[str], topics: Any = None) -> list[str]:
    """The columns to read: those the config names (``feature`` or ``feature/<name>``),
    every one when it names none, only the features ``topics`` names when given (a dataset's
    topics are its features: ``ident logs inspect --topic``), and always the time, episode
    and frame columns."""
    keep = (_TIME, _EPISODE, _FRAME)
    names = set(present)
    if wanted is not None:
        names = {str(w).split("/", 1)[0] for w in wanted} | {str(w) for w in wanted}
    if topics is not None:
        names &= {str(t) for t in topics}
    return [c for c in present if c in names or c in keep]


def _check_topics(file: Path, topics: Any, present: list[str]) -> None:
    """Refuse a topic (``--topic``, ``topics:``) that is no feature of the dataset."""
    for topic in topics or ():
        if topic not in present:
            features = [c for c in present if c not in (_TIME, _EPISODE, _FRAME)]
            raise DataError(
                f"{file}: topic '{topic}' is not a feature of this LeRobot dataset (its "
                f"features are its topics: {', '.join(features)}); name one of them."
            )


def _n_leaves(t: pa.DataType) -> int:
    """Parquet leaf columns of an arrow type (a list of numbers: 1; an image struct: 2)."""
    if t.num_fields == 0:
        return 1
    return sum(_n_leaves(t.field(k).type) for k in range(t.num_fields))


def _chunk_bytes(pf: pq.ParquetFile, names: list[str]) -> float:
    """The largest uncompressed column chunk of the columns ``names`` (footer only)."""
    leaves: list[str] = []
    for field in pf.schema_arrow:  # leaf columns in schema order
        leaves += [field.name] * _n_leaves(field.type)
    md, largest = pf.metadata, 0.0
    for g in range(md.num_row_groups):
        rg = md.row_group(g)
        for j in range(min(rg.num_columns, len(leaves))):
            if leaves[j] in names:
                largest = max(largest, float(rg.column(j).total_uncompressed_size))
    return largest


def _plan(path: Path, options: Mapping[str, Any]) -> _Plan:
    """Files, fields and sizes of reading ``path`` (footers and info.json only); an episode
    file of no frames is kept with 0 rows (skipped, :attr:`_Plan.empty_files`)."""
    root, files, info_path = _dataset(path)
    info = _load_info(info_path) if info_path is not None else None
    rows, fields, chunk = [], None, 0.0
    for file in files:
        pf = _open_parquet(file)
        present = pf.schema_arrow.names
        rows.append(int(pf.metadata.num_rows))
        if rows[-1] == 0:
            continue  # an empty episode holds nothing to read or check
        _check_topics(file, options.get("topics"), present)
        names = _selected(options.get("columns"), present, options.get("topics"))
        if fields is None:
            try:
                found = [_field(pf, file, n, info, info_path or file) for n in names]
            except (OSError, pa.ArrowException, IndexError) as e:
                raise DataError(f"{file}: cannot read the parquet file ({e}).") from e
            fields = tuple(f for f in found if f is not None)
        _check_same_columns(file, present, fields)
        chunk = max(chunk, _chunk_bytes(pf, [f.name for f in fields]))
    if fields is None:
        raise DataError(
            f"{path}: the dataset holds no frames: every episode file is empty "
            f"({_listed(files, root)}); give a dataset whose episodes were recorded."
        )
    fps = float(info["fps"]) if info is not None else None
    return _Plan(root, files, tuple(rows), fields, fps, info_path, chunk)


def _open_parquet(file: Path) -> pq.ParquetFile:
    """The parquet file (its footer read) with the columns every LeRobot episode has."""
    try:
        pf = pq.ParquetFile(file)
    except (OSError, pa.ArrowException) as e:
        raise DataError(f"{file}: not a readable parquet file ({e}).") from e
    present = pf.schema_arrow.names
    for required in (_TIME, _EPISODE):
        if required not in present:
            raise DataError(
                f"{file}: column '{required}' not found; the file has {', '.join(present)} "
                "(a LeRobot episode has timestamp, frame_index, episode_index)."
            )
    return pf


def _listed(files: tuple[Path, ...], root: Path) -> str:
    """The first three ``files`` relative to ``root``, and how many more."""
    names = [str(f.relative_to(root)) if f.is_relative_to(root) else str(f) for f in files]
    more = f" and {len(names) - 3} more" if len(names) > 3 else ""
    return ", ".join(names[:3]) + more


def _check_same_columns(file: Path, present: list[str], fields: tuple[_Field, ...]) -> None:
    missing = [f.name for f in fields if f.name not in present]
    if missing:
        raise DataError(
            f"{file}: column '{missing[0]}' not found (the dataset's first file has it); "
            f"this file has {', '.join(present)}."
        )


def estimate_lerobot(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading ``path``, from ``info.json`` and the parquet footers."""
    plan = _plan(path, options)
    values = plan.n_rows * sum(f.width for f in plan.fields)
    return JobEstimate(
        f"reading {path.name}: {plan.n_rows} frames x {len(plan.fields)} columns",
        plan.memory_bytes(),
        values * _SECONDS_PER_VALUE,
    )


def _values(column: pa.ChunkedArray, field: _Field, file: Path) -> FloatArray:
    """One column of one row group as float64, shape (n_rows, field.width)."""
    parts = []
    for chunk in column.chunks:
        if chunk.null_count:
            raise DataError(
                f"{file}: column '{field.name}' has {chunk.null_count} empty (null) row(s); "
                "drop those frames or re-record the episode."
            )
        if not field.is_list:
            parts.append(chunk.to_numpy(zero_copy_only=False).reshape(-1, 1))
            continue
        if pa.types.is_list(chunk.type):
            lengths = np.diff(chunk.offsets.to_numpy())
            if np.any(lengths != field.width):
                k = int(np.flatnonzero(lengths != field.width)[0])
                raise DataError(
                    f"{file}: column '{field.name}' holds {lengths[k]} values in a row "
                    f"(row {k} of its chunk), {field.width} expected in every row."
                )
        flat = chunk.flatten().to_numpy(zero_copy_only=False)
        parts.append(flat.reshape(-1, field.width))
    if not parts:
        return np.empty((0, field.width))
    return np.asarray(np.concatenate(parts), dtype=np.float64)


def _read_columns(plan: _Plan) -> dict[str, FloatArray]:
    """Every field's values (n_rows, width), column-major, filled one column chunk at a time."""
    check_job(
        JobEstimate(
            f"{plan.root}: {plan.n_rows} frames x {sum(f.width for f in plan.fields)} values",
            plan.memory_bytes(),
            0.0,
        )
    )
    out = {f.name: np.empty((plan.n_rows, f.width), order="F") for f in plan.fields}
    start = 0
    for file in (f for f in plan.files if f not in plan.empty_files):
        try:
            pf = pq.ParquetFile(file)
            for g in range(pf.metadata.num_row_groups):
                m = pf.metadata.row_group(g).num_rows
                for field in plan.fields:
                    column = pf.read_row_group(g, columns=[field.name]).column(0)
                    out[field.name][start : start + m] = _values(column, field, file)
                start += m
        except (OSError, pa.ArrowException) as e:
            raise DataError(f"{file}: cannot read the parquet file ({e}).") from e
    return out


def _file_of(plan: _Plan, row: int) -> Path:
    ends = np.cumsum(plan.rows)
    return plan.files[int(np.searchsorted(ends, row, side="right"))]


def _check_episode(
    plan: _Plan, t: FloatArray, frames: FloatArray, episode: int, first_row: int
) -> None:
    """Refuse the timestamps ``t`` [s] of one episode when they do not increase or contradict
    ``fps``; ``frames`` are its ``frame_index`` values, for messages."""
    file = _file_of(plan, first_row)
    steps = np.diff(t)
    bad = np.flatnonzero(~(steps > 0))
    if bad.size:
        k = int(bad[0]) + 1
        raise DataError(
            f"{file}: column 'timestamp' of episode {episode} does not increase at frame "
            f"{int(frames[k])} ({t[k - 1]:.9g} s then {t[k]:.9g} s); repair the episode's "
            "timestamps (frame k at k/fps) or remove the episode from the dataset."
        )
    if plan.fps is None or steps.size == 0:
        return
    step = float(np.median(steps))
    if abs(step * plan.fps - 1.0) > FPS_RTOL:
        raise DataError(
            f"{plan.info_path}: fps = {plan.fps:g} but the timestamps of episode {episode} "
            f"({file}) step {step:.6g} s ({1.0 / step:.6g} Hz); set fps to the rate the "
            "episodes were recorded at, or repair the timestamps."
        )


def _episodes(plan: _Plan, columns: dict[str, FloatArray]) -> tuple[FloatArray, list[int]]:
    """The continued time [s] (each episode :data:`EPISODE_GAP_S` after the previous one's
    end) and the rows where an episode starts after the first, every episode checked."""
    t_raw = columns[_TIME][:, 0]
    episode = columns[_EPISODE][:, 0]
    frames = columns[_FRAME][:, 0] if _FRAME in columns else None
    starts = (np.flatnonzero(np.diff(episode) != 0) + 1).tolist()
    bounds = [0, *starts, t_raw.size]
    t = np.empty_like(t_raw)
    offset = 0.0
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        if not np.all(np.isfinite(t_raw[a:b])):
            k = a + int(np.flatnonzero(~np.isfinite(t_raw[a:b]))[0])
            raise DataError(
                f"{_file_of(plan, a)}: column 'timestamp' of episode {int(episode[a])} is "
                f"{t_raw[k]} at row {k - a}; repair or remove the episode."
            )
        f = frames[a:b] if frames is not None else np.arange(b - a, dtype=float)
        _check_episode(plan, t_raw[a:b], f, int(episode[a]), a)
        stamps = _frame_time(t_raw[a:b], f if frames is not None else None, plan.fps)
        if a:
            offset = t[a - 1] + EPISODE_GAP_S - stamps[0]
        t[a:b] = stamps + offset
    return t, starts


def _frame_time(t: FloatArray, frames: FloatArray | None, fps: float | None) -> FloatArray:
    """One episode's time [s]: ``frame_index / fps`` when its timestamps are that time rounded
    to float32 (LeRobot writes them so), else the timestamps as given.

    Why: float32 keeps 24 bits, so past 512 s of an episode the stamps' rounding reaches 0.1 %
    of a 30 Hz step and the steps look jittered (the log would be resampled, the rollout check
    refuse its windows); the frame index is exact.
    """
    if frames is None or fps is None:
        return t
    exact = frames / fps
    if np.all(np.abs(t - exact) <= _FLOAT32_ROUNDING * np.maximum(np.abs(exact), 1.0 / fps)):
        return exact
    return t


def read_lerobot(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a LeRobot dataset folder or episode file (option ``columns``: the columns the
    config names; only their features are read) as one table, episodes as segments."""
    plan = _plan(path, options)
    values = _read_columns(plan)
    t, starts = _episodes(plan, values)
    columns: dict[str, FloatArray] = {}
    for field in plan.fields:
        for k, name in enumerate(field.names):
            columns[name] = values[field.name][:, k]  # contiguous views (column-major)
    columns[_TIME] = t
    warnings: tuple[str, ...] = ()
    if plan.info_path is None:
        warnings = (
            f"{path}: no meta/info.json two folders up: fps not checked against the "
            "timestamps, joints named by index",
        )
    if plan.empty_files:  # nothing of them is lost by skipping; their absence is named
        warnings += (
            f"{plan.root}: {len(plan.empty_files)} episode file(s) hold no frames, skipped "
            f"({_listed(plan.empty_files, plan.root)}); re-record those episodes or remove "
            "the files",
        )
    return [
        LogTable(
            columns=columns,
            time=_TIME,
            source=str(path),
            warnings=warnings,
            segment_starts=tuple(starts),
            angle_bound_rad=ANGLE_BOUND_RAD,
        )
    ]
