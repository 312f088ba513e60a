"""Log readers: files a robot controller writes -> named columns in the file's own units.

The registry and the table type are in :mod:`ident.measure.readers.registry`; this package
registers the built-in readers (CSV/TSV, long CSV, ROS 2 bags, MCAP, npz, LeRobot datasets)
on import. Add a format with :func:`register_reader` (see ``docs/logs.md``, "Extending").
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from ident.inputs import JobEstimate
from ident.measure.readers import csv as _csv
from ident.measure.readers import csv_long as _csv_long
from ident.measure.readers import npz as _npz
from ident.measure.readers import ros as _ros
from ident.measure.readers.lerobot_layout import is_lerobot
from ident.measure.readers.registry import (
    READERS,
    TIME_NAMES,
    LogTable,
    ReaderEntry,
    detect_format,
    estimate_read,
    read_tables,
    register_reader,
)

__all__ = [
    "READERS",
    "TIME_NAMES",
    "LogTable",
    "ReaderEntry",
    "detect_format",
    "estimate_read",
    "read_tables",
    "register_reader",
]

register_reader(
    "rosbag",
    _ros.read_rosbag,
    detect=_ros.is_rosbag,
    description="ROS 2 bag folder",
    estimate=_ros.estimate_rosbag,
)
register_reader(
    "mcap",
    _ros.read_mcap,
    detect=_ros.is_mcap,
    description="bare .mcap file",
    estimate=_ros.estimate_mcap,
)
register_reader(
    "npz",
    _npz.read_npz,
    detect=_npz.is_npz,
    description="numpy archive",
    estimate=_npz.estimate_npz,
)


# The LeRobot reader needs pyarrow (0.15 s to import): imported when a dataset is read, not by
# every command that imports the registry.
def _read_lerobot(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    from ident.measure.readers.lerobot import read_lerobot

    return read_lerobot(path, options)


def _estimate_lerobot(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    from ident.measure.readers.lerobot import estimate_lerobot

    return estimate_lerobot(path, options)


register_reader(
    "lerobot",
    _read_lerobot,
    detect=is_lerobot,
    description="LeRobot dataset folder or episode .parquet",
    estimate=_estimate_lerobot,
)
register_reader(
    "csv_long",
    _csv_long.read_csv_long,
    description="CSV, one row per sample and joint (time, joint, values)",
    estimate=_csv_long.estimate_csv_long,
)
register_reader(
    "csv",
    _csv.read_csv,
    detect=_csv.is_text,
    description="CSV/TSV/text, header optional",
    estimate=_csv.estimate_csv,
)
