"""Write small LeRobot datasets (v2.x layout) for the reader tests, with pyarrow.

``meta/info.json`` (``fps``, ``features`` with ``shape`` and ``names``) and one parquet file per
episode under ``data/chunk-000/``, one row per frame: ``timestamp`` (frame k at k/fps unless
given), ``frame_index``, ``episode_index``, ``index``, ``task_index`` and the list features
(``observation.state``, ``action``, ...) as fixed-size lists of float32, as LeRobot writes them.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

# Feetech STS3215 (SO-100 / SO-101 arms): 4096 ticks per turn, centre 2048
TICKS_PER_REV = 4096
ZERO_TICK = 2048


def ticks_to_rad(ticks: np.ndarray, zero: float = ZERO_TICK) -> np.ndarray:
    """Closed form of the conversion the reader's config declares: (ticks - zero) 2 pi / 4096."""
    return (np.asarray(ticks, dtype=float) - zero) * 2.0 * np.pi / TICKS_PER_REV


def _list_column(values: np.ndarray, variable: bool) -> pa.Array:
    flat = pa.array(np.asarray(values, dtype=np.float32).ravel())
    if variable:
        offsets = pa.array(np.arange(0, values.size + 1, values.shape[1], dtype=np.int32))
        return pa.ListArray.from_arrays(offsets, flat)
    return pa.FixedSizeListArray.from_arrays(flat, values.shape[1])


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
        n = next(len(v) for k, v in episode.items() if k != "timestamp")
        columns: dict[str, Any] = {}
        for key, values in episode.items():
            if key == "timestamp":
                continue
            values = np.asarray(values)
            columns[key] = _list_column(values, variable_lists)
            given = names.get(key) if isinstance(names, Mapping) else list(names) or None
            features[key] = {"dtype": "float32", "shape": [values.shape[1]], "names": given}
        stamps = episode.get("timestamp", np.arange(n) / fps)
        columns["timestamp"] = pa.array(np.asarray(stamps, dtype=np.float32))
        columns["frame_index"] = pa.array(np.arange(n, dtype=np.int64))
        columns["episode_index"] = pa.array(np.full(n, e, dtype=np.int64))
        columns["index"] = pa.array(np.arange(index, index + n, dtype=np.int64))
        columns["task_index"] = pa.array(np.zeros(n, dtype=np.int64))
        index += n
        path = root / "data" / "chunk-000" / f"episode_{e:06d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table(columns), path, row_group_size=row_group_size)
    for key in ("timestamp", "frame_index", "episode_index", "index", "task_index"):
        dtype = "float32" if key == "timestamp" else "int64"
        features[key] = {"dtype": dtype, "shape": [1], "names": None}
    meta = {
        "codebase_version": "v2.1",
        "robot_type": "so100",
        "total_episodes": len(episodes),
        "total_frames": index,
        "chunks_size": 1000,
        "fps": fps,
        "data_path": "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
        "features": features,
        **(info or {}),
    }
    (root / "meta").mkdir(parents=True, exist_ok=True)
    (root / "meta" / "info.json").write_text(json.dumps(meta, indent=1))
    return root
