"""Write LeRobot datasets (v2.x layout), the layout :mod:`ident.measure.readers.lerobot` reads.

``meta/info.json`` (``fps``, ``features`` with ``dtype``, ``shape`` and ``names``) and one
parquet file per episode under ``data/chunk-000/``, one row per frame: ``timestamp`` (frame
``k`` at ``k / fps`` unless given, float32 as LeRobot writes it), ``frame_index``,
``episode_index``, ``index``, ``task_index`` and the list features (``observation.state``,
``action``, ...) as lists of float32.

:func:`write_simulated_dataset` writes what a position-servo arm would record: the simulator's
logs (:func:`ident.measure.mujoco_sim.simulate` with ``actuator: {kind: position}``), one
episode each, the measured positions as ``observation.state`` and the commands as ``action``,
both in servo ticks (``zero_tick + q counts_per_rev / (2 pi)``: the encoder's whole ticks, the
conversion the reader's ``unit: ticks`` undoes), and :func:`lerobot_log_section` the ``log:``
section of an identify config that reads it.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pyarrow as pa
import pyarrow.parquet as pq

from ident.errors import DataError
from ident.measure.mujoco_sim import SimulatedLog
from ident.measure.readers.lerobot_layout import (
    DATA_PATH,
    EPISODE_COLUMN,
    FRAME_COLUMN,
    INDEX_COLUMN,
    INFO_PATH,
    TASK_COLUMN,
    TIME_COLUMN,
)

__all__ = [
    "STATE",
    "ACTION",
    "lerobot_log_section",
    "to_ticks",
    "write_dataset",
    "write_simulated_dataset",
]

FloatArray = npt.NDArray[np.float64]

STATE, ACTION = "observation.state", "action"  # the measured and the commanded positions


def _list_column(values: np.ndarray, variable: bool) -> pa.Array:
    """(n_frames, k) values as a list column of float32 (fixed-size, or variable lists)."""
    flat = pa.array(np.asarray(values, dtype=np.float32).ravel())
    if variable:
        offsets = pa.array(np.arange(0, values.size + 1, values.shape[1], dtype=np.int32))
        return pa.ListArray.from_arrays(offsets, flat)
    return pa.FixedSizeListArray.from_arrays(flat, values.shape[1])


def _episode_table(
    episode: Mapping[str, np.ndarray], e: int, first_index: int, fps: float, variable: bool
) -> pa.Table:
    """One episode's rows: its list features, then the time and index columns."""
    n = next(len(v) for k, v in episode.items() if k != TIME_COLUMN)
    columns: dict[str, Any] = {
        key: _list_column(np.asarray(values), variable)
        for key, values in episode.items()
        if key != TIME_COLUMN
    }
    stamps = episode.get(TIME_COLUMN, np.arange(n) / fps)
    columns[TIME_COLUMN] = pa.array(np.asarray(stamps, dtype=np.float32))
    columns[FRAME_COLUMN] = pa.array(np.arange(n, dtype=np.int64))
    columns[EPISODE_COLUMN] = pa.array(np.full(n, e, dtype=np.int64))
    columns[INDEX_COLUMN] = pa.array(np.arange(first_index, first_index + n, dtype=np.int64))
    columns[TASK_COLUMN] = pa.array(np.zeros(n, dtype=np.int64))
    return pa.table(columns)


def write_dataset(
    root: Path,
    episodes: Sequence[Mapping[str, np.ndarray]],
    *,
    fps: float = 30.0,
    names: Sequence[str] | Mapping[str, Sequence[str] | None] = (),
    info: Mapping[str, Any] | None = None,
    variable_lists: bool = False,
    row_group_size: int | None = None,
) -> Path:
    """A dataset folder ``root`` of ``episodes`` (each: feature -> values (n_frames, k), and
    optionally ``timestamp`` (n_frames,) [s]); ``names`` the element names of every list
    feature, or per feature; ``info`` replaces keys of ``meta/info.json``. Returns ``root``."""
    features: dict[str, Any] = {}
    index = 0
    for e, episode in enumerate(episodes):
        table = _episode_table(episode, e, index, fps, variable_lists)
        for key, values in episode.items():
            if key != TIME_COLUMN:
                given = names.get(key) if isinstance(names, Mapping) else list(names) or None
                shape = [np.asarray(values).shape[1]]
                features[key] = {"dtype": "float32", "shape": shape, "names": given}
        index += table.num_rows
        path = root / DATA_PATH.format(episode_chunk=0, episode_index=e)
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table, path, row_group_size=row_group_size)
    for key in (TIME_COLUMN, FRAME_COLUMN, EPISODE_COLUMN, INDEX_COLUMN, TASK_COLUMN):
        dtype = "float32" if key == TIME_COLUMN else "int64"
        features[key] = {"dtype": dtype, "shape": [1], "names": None}
    meta = {
        "codebase_version": "v2.1",
        "robot_type": "so100",
        "total_episodes": len(episodes),
        "total_frames": index,
        "chunks_size": 1000,
        "fps": fps,
        "data_path": DATA_PATH,
        "features": features,
        **(info or {}),
    }
    (root / INFO_PATH).parent.mkdir(parents=True, exist_ok=True)
    (root / INFO_PATH).write_text(json.dumps(meta, indent=1))
    return root


def to_ticks(q: FloatArray, counts_per_rev: int, zero_tick: float) -> FloatArray:
    """Servo ticks of the positions ``q`` [rad], any shape: ``zero_tick + q counts / (2 pi)``
    (the inverse of the reader's ``unit: ticks``); positions on the encoder's grid give whole
    ticks, rounded off the float error."""
    ticks = zero_tick + np.asarray(q, dtype=float) * counts_per_rev / (2.0 * np.pi)
    whole = np.rint(ticks)
    return np.where(np.abs(ticks - whole) < 1e-6, whole, ticks)


def write_simulated_dataset(
    root: Path,
    logs: Sequence[SimulatedLog],
    *,
    counts_per_rev: int,
    zero_tick: float,
    extra_motors: Mapping[str, float] | None = None,
) -> Path:
    """The simulated position-servo ``logs`` as a LeRobot dataset in ``root``, one episode
    each, at their rate: ``observation.state`` the encoder positions, ``action`` the commands,
    in ticks (:func:`to_ticks`); ``extra_motors`` (name -> tick) adds motors the robot does not
    model (a gripper) held at a tick. Returns ``root``.

    Raises
    ------
    DataError
        A log of a motor actuator (no commanded positions), or logs of different joints or
        rates.
    """
    if not logs:
        raise DataError(f"{root}: no simulated log to write.")
    first, extra = logs[0], dict(extra_motors or {})
    episodes = []
    for log in logs:
        if log.q_cmd is None:
            raise DataError(
                f"{root}: a LeRobot dataset records commanded positions; simulate with "
                "measurement.actuator.kind: position."
            )
        if log.joint_names != first.joint_names or log.rate_hz != first.rate_hz:
            raise DataError(f"{root}: every episode needs the same joints and rate.")
        held = np.tile(np.asarray(list(extra.values()), dtype=float), (log.n_samples, 1))
        state = to_ticks(log.q, counts_per_rev, zero_tick)
        action = to_ticks(log.q_cmd, counts_per_rev, zero_tick)
        episodes.append({STATE: np.hstack([state, held]), ACTION: np.hstack([action, held])})
    names = [*first.joint_names, *extra]
    info = {"robot_type": "so101"}
    return write_dataset(root, episodes, fps=first.rate_hz, names=names, info=info)


def lerobot_log_section(
    path: str, counts_per_rev: int, zero_tick: float, exclude: Sequence[str] = ()
) -> dict[str, Any]:
    """The ``log:`` section of an identify config reading the dataset at ``path`` (as the
    config will name it): the positions ``observation.state`` and the commands ``action`` in
    ticks, matched to the URDF's joints by name, the motors ``exclude`` left out."""
    position: dict[str, Any] = {"columns": [STATE]}
    if exclude:
        position["exclude"] = list(exclude)
    position |= {"unit": "ticks", "counts_per_rev": counts_per_rev, "zero_tick": zero_tick}
    return {
        "path": path,
        "format": "lerobot",
        "position": position,
        "command": {"columns": [ACTION]},
    }
