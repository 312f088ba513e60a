"""The LeRobot dataset layout (v2.x) that the reader reads and the writer writes.

Kept apart from :mod:`ident.measure.readers.lerobot` (which needs ``pyarrow``, 0.15 s to
import): the registry's detector and every command that reads no dataset import this module
only.
"""

from __future__ import annotations

from pathlib import Path

__all__ = [
    "DATA_PATH",
    "EPISODE_COLUMN",
    "FRAME_COLUMN",
    "INDEX_COLUMN",
    "INFO_PATH",
    "TASK_COLUMN",
    "TIME_COLUMN",
    "is_lerobot",
]

TIME_COLUMN = "timestamp"  # [s] from the episode's start, float32 in LeRobot's files
FRAME_COLUMN = "frame_index"  # the frame's number within its episode
EPISODE_COLUMN = "episode_index"
INDEX_COLUMN = "index"  # the frame's number within the dataset
TASK_COLUMN = "task_index"
INFO_PATH = Path("meta") / "info.json"
#: One parquet file per episode, relative to the dataset folder (``info.json``'s ``data_path``).
DATA_PATH = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet"


def is_lerobot(path: Path) -> bool:
    """Detector: a folder with ``meta/info.json``, or a ``.parquet`` file (an ``info.json``
    that is no file still marks a dataset: the reader names what it is)."""
    if path.is_dir():
        return (path / INFO_PATH).exists()
    return path.is_file() and path.suffix == ".parquet"
