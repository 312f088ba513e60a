"""The log-reader registry: files a robot controller writes -> named columns in their units.

A reader turns one file (or one bag folder) into one or more :class:`LogTable` objects: named
1-D columns of equal length, in the units of the file, with the name of the time column when
the file has one. Choosing columns, converting units and sides, joining tables and resampling
happen afterwards, once (:mod:`ident.measure.logs`, :mod:`ident.measure.timebase`).

Readers live in :data:`READERS`, keyed by the ``format:`` name of a log config; a file without
``format:`` gets the first registered reader whose ``detect`` accepts it. Built in:

============  ===========================================================================
``csv``       CSV/TSV/whitespace text, plain or ``.gz``, with or without a header line
              (wide: one column per joint and signal; one value per line in its own file)
``csv_long``  CSV with one row per sample and joint: a time, a joint-name and value columns
``rosbag``    ROS 2 bag folder (sqlite3 or mcap storage) read with ``rosbags``
``mcap``      a bare ``.mcap`` file with ROS 2 (CDR) messages read with ``mcap-ros2-support``
``npz``       a numpy archive (1-D arrays are columns, 2-D ``name`` -> ``name/0``, ...)
``lerobot``   a LeRobot dataset folder (parquet episodes) or one episode ``.parquet`` file
============  ===========================================================================

Add a format with :func:`register_reader` (see ``docs/logs.md``, "Extending").
"""

from __future__ import annotations

import difflib
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError, DataError
from ident.inputs import JobEstimate

__all__ = [
    "READERS",
    "LogTable",
    "ReaderEntry",
    "check_regular_file",
    "detect_format",
    "estimate_read",
    "read_tables",
    "register_reader",
]

FloatArray = npt.NDArray[np.float64]

# Names a time column is recognised by (case-insensitive) when the config names none.
TIME_NAMES = ("t", "time", "time_s", "timestamp", "stamp", "%time")


@dataclass(frozen=True, eq=False)
class LogTable:
    """Named columns of one log source, all of the same length, in the file's units.

    Attributes
    ----------
    columns :
        Column name -> values, each of shape (n_samples,).
    time :
        Name of the time column [s] when the source has one, else None.
    source :
        File (and topic) the table comes from, for messages.
    line_numbers :
        File line of each sample (text logs), for messages; None otherwise.
    warnings :
        What the reader did that a user must know (e.g. receive times used for messages
        without a stamp), one sentence each with the count and the first place.
    segment_starts :
        Rows (0-based, increasing, > 0) where an independent recording starts (an episode
        of a dataset): the log is split there into segments whatever its time stamps say,
        so nothing is filtered or differentiated across. Empty for one recording.
    angle_bound_rad :
        Largest plausible ``|position|`` [rad] of the source's angles (servo positions: one
        turn and a margin); a position beyond it after the config's unit conversion was
        logged in another unit and is refused. None: no bound (a continuous joint turns on).
    """

    columns: Mapping[str, FloatArray]
    time: str | None = None
    source: str = ""
    line_numbers: npt.NDArray[np.int64] | None = field(default=None, repr=False)
    warnings: tuple[str, ...] = ()
    segment_starts: tuple[int, ...] = ()
    angle_bound_rad: float | None = None

    @property
    def n_samples(self) -> int:
        """Number of samples (0 for a table without columns)."""
        return int(next(iter(self.columns.values())).shape[0]) if self.columns else 0

    def column(self, name: str) -> FloatArray:
        """The column ``name``; DataError naming the closest existing names otherwise."""
        if name not in self.columns:
            raise DataError(_missing(name, list(self.columns), self.source))
        return self.columns[name]


def _missing(name: str, available: list[str], source: str) -> str:
    close = difflib.get_close_matches(name, available, n=3)
    hint = f" (closest: {', '.join(close)})" if close else ""
    shown = ", ".join(available[:40]) + (" ..." if len(available) > 40 else "")
    return f"{source}: column '{name}' not found{hint}; the log has {shown}."


Reader = Callable[[Path, Mapping[str, Any]], list[LogTable]]
Detector = Callable[[Path], bool]
Estimator = Callable[[Path, Mapping[str, Any]], JobEstimate]


@dataclass(frozen=True)
class ReaderEntry:
    """A registered reader: ``read(path, options) -> [LogTable, ...]``, its detector and its
    cheap ``estimate(path, options)`` of the memory and time of reading (from the file's size
    and what it declares, without reading it)."""

    read: Reader
    detect: Detector | None = None
    description: str = ""
    estimate: Estimator | None = None


READERS: dict[str, ReaderEntry] = {}


def register_reader(
    name: str,
    read: Reader,
    *,
    detect: Detector | None = None,
    description: str = "",
    estimate: Estimator | None = None,
) -> None:
    """Register a log reader under the ``format:`` name ``name``.

    Parameters
    ----------
    name :
        Value of ``format:`` in a log config.
    read :
        ``read(path, options)`` returning a list of :class:`LogTable` (columns in the file's
        units, time in seconds); ``options`` holds the file entry's reader options
        (``delimiter``, ``header``, ``names``, ``topics``, ``joint_column``, ...).
    detect :
        Optional ``detect(path) -> bool`` used when a file has no ``format:``; readers are
        tried in registration order.
    description :
        One line for ``ident logs inspect --formats`` and messages.
    estimate :
        Optional ``estimate(path, options) -> JobEstimate``: memory and time of reading,
        from the file's size and headers only (printed and checked before reading).
    """
    READERS[name] = ReaderEntry(
        read=read, detect=detect, description=description, estimate=estimate
    )


def check_regular_file(path: Path) -> None:
    """Refuse a path that is not a regular file (a device such as ``/dev/zero``, a pipe).

    Raises
    ------
    DataError
        Naming the path.
    """
    if not path.is_file():
        kind = "a folder" if path.is_dir() else "not a regular file (a device or a pipe)"
        raise DataError(f"{path}: is {kind}; give a log file.")


def detect_format(path: str | Path) -> str:
    """The name of the first registered reader whose detector accepts ``path``.

    Raises
    ------
    DataError
        If the path does not exist or no reader recognises it.
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: log file not found.")
    if not path.is_dir():  # a bag or dataset folder is a log; a device or a pipe is none
        check_regular_file(path)
    for name, entry in READERS.items():
        if entry.detect is not None and entry.detect(path):
            return name
    raise DataError(
        f"{path}: no reader recognises this file; set format: to one of "
        f"{', '.join(READERS)} in the log config."
    )


def estimate_read(path: str | Path, fmt: str | None = None, **options: Any) -> JobEstimate | None:
    """The reader's estimate of reading ``path`` (None when the reader gives none).

    Raises
    ------
    DataError
        For a missing or unrecognised file, or one whose headers are malformed.
    """
    path = Path(path)
    name = fmt if fmt is not None else detect_format(path)
    entry = READERS.get(name)
    if entry is None or entry.estimate is None or not path.exists():
        return None
    return entry.estimate(path, {k: v for k, v in options.items() if v is not None})


def read_tables(path: str | Path, fmt: str | None = None, **options: Any) -> list[LogTable]:
    """Read one log source with the reader ``fmt`` (detected from the file when None).

    Raises
    ------
    ConfigError
        For an unknown format name (the message lists the registered ones).
    DataError
        For unreadable files.
    """
    path = Path(path)
    name = fmt if fmt is not None else detect_format(path)
    if name not in READERS:
        close = difflib.get_close_matches(name, list(READERS), n=1)
        hint = f" Did you mean '{close[0]}'?" if close else ""
        raise ConfigError(
            f"log format '{name}' is not registered; use one of {', '.join(READERS)}.{hint}"
        )
    if not path.exists():
        raise DataError(f"{path}: log file not found.")
    tables = READERS[name].read(path, {k: v for k, v in options.items() if v is not None})
    if not tables:
        raise DataError(f"{path}: the {name} reader found no data.")
    return tables
