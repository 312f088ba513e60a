"""CSV, TSV and plain-text log readers (plain or gzip-compressed).

``read_csv`` reads a *wide* file: one column per signal and joint. The first line is a header
when any of its fields is not a number; otherwise columns are named by ``names`` (the
config's list), or by the file stem (one column: ``q1.txt`` -> ``q1``; several:
``stem:1``, ``stem:2``, ...). The delimiter is the config's, or the first of tab, comma and
semicolon in the first line, else whitespace. ``read_csv_long`` reads a *long* file: one row
per sample and joint, pivoted to the wide ``<value>/<joint>`` columns.

Error messages give file line numbers (the header, when present, is line 1; blank lines count).

Bounded memory: the text is read line by line (decompressed on the fly) and parsed in blocks
of :data:`BLOCK_LINES` lines; a line longer than :data:`MAX_LINE_CHARS` is refused when it is
read (a file without line breaks, ``/dev/zero``, a one-line decompression bomb), and the
numbers parsed so far are checked against ``IDENT_MAX_MEMORY_GB`` after every block (a
decompression bomb of many lines). Only regular files are read (not devices or pipes).
"""

from __future__ import annotations

import gzip
import io
import re
import struct
import zlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.inputs import JobEstimate, check_job
from ident.measure.readers.registry import TIME_NAMES, LogTable, check_regular_file

__all__ = [
    "BLOCK_LINES",
    "MAX_LINE_CHARS",
    "estimate_csv",
    "is_text",
    "open_text",
    "read_csv",
    "read_csv_long",
    "sniff_delimiter",
]

# A line of 10 000 numbers is about 200 000 characters: a longer one is not a log line.
MAX_LINE_CHARS = 1 << 20
BLOCK_LINES = 1 << 16  # lines parsed at once
_PARSE_BYTES_PER_S = 30e6  # text parsed per second (estimate)

_TEXT_SUFFIXES = {".csv", ".tsv", ".txt", ".dat", ".log"}


def open_text(path: Path) -> io.TextIOBase:
    """Open a text file, decompressing ``.gz`` on the fly (regular files only)."""
    check_regular_file(path)
    if path.suffix == ".gz":
        return io.TextIOWrapper(gzip.open(path, "rb"), encoding="utf-8")
    return open(path, encoding="utf-8")  # noqa: SIM115 - closed by the caller's with


def is_text(path: Path) -> bool:
    """Detector: a file named ``*.csv``, ``*.tsv``, ``*.txt``, ``*.dat``, ``*.log`` (``.gz``)."""
    suffixes = path.suffixes[-2:] if path.suffix == ".gz" else path.suffixes[-1:]
    return path.is_file() and bool(suffixes) and suffixes[0].lower() in _TEXT_SUFFIXES


def sniff_delimiter(line: str) -> str | None:
    """Tab, comma or semicolon, whichever appears first in that order of preference in
    ``line``; None (any whitespace) when none does."""
    for d in ("\t", ",", ";"):
        if d in line:
            return d
    return None


def _split(line: str, delimiter: str | None) -> list[str]:
    return [f.strip() for f in (line.split(delimiter) if delimiter else line.split())]


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def text_size(path: Path) -> int:
    """Characters of the text once decompressed (from the gzip trailer for ``.gz``, which
    holds the size modulo 4 GiB: at least the compressed size is assumed)."""
    size = path.stat().st_size
    if path.suffix != ".gz" or size < 18:
        return size
    with open(path, "rb") as f:
        f.seek(-4, io.SEEK_END)
        (isize,) = struct.unpack("<I", f.read(4))
    return max(isize, size)


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    """``(line number, text)`` of every line (1-based, blank lines included), each at most
    :data:`MAX_LINE_CHARS` long."""
    try:
        with open_text(path) as f:
            number = 0
            while True:
                line = f.readline(MAX_LINE_CHARS + 1)
                if not line:
                    return
                number += 1
                if len(line) > MAX_LINE_CHARS:
                    raise DataError(
                        f"{path}: line {number} is longer than {MAX_LINE_CHARS} characters "
                        "(not a text log, or a file without line breaks); give a CSV log."
                    )
                yield number, line
    except (OSError, UnicodeDecodeError, EOFError, zlib.error) as e:  # zlib: a damaged .gz
        raise DataError(f"{path}: cannot read the log file ({e}).") from e


def _first_line(lines: Iterator[tuple[int, str]]) -> str:
    return next(lines, (0, ""))[1]


def _check_memory(path: Path, n_rows: int, n_columns: int) -> None:
    """Refuse when the numbers read so far need more than the memory ceiling (a block list
    and the final array: twice the values)."""
    check_job(
        JobEstimate(
            f"{path}: reading at least {n_rows} rows x {n_columns} columns",
            2.0 * 8.0 * n_rows * n_columns,
            0.0,
        )
    )


def estimate_csv(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading the text log ``path`` (its size over its first line's)."""
    first = ""  # the first data line (the second non-blank one when there is a header)
    seen = 0
    for _, line in _lines(path):
        if line.strip():
            first, seen = line, seen + 1
            if seen == 2:
                break
    size = text_size(path)
    n_rows = size / max(len(first), 1)
    n_columns = max(len(_split(first, options.get("delimiter") or sniff_delimiter(first))), 1)
    return JobEstimate(
        f"reading {path.name}: about {n_rows:.3g} rows x {n_columns} columns",
        2.0 * 8.0 * n_rows * n_columns,
        size / _PARSE_BYTES_PER_S,
    )


def _parse(
    path: Path,
    lines: list[tuple[int, str]],
    delimiter: str | None,
    header: list[str],
) -> FloatArray:
    if not lines:
        raise DataError(f"{path}: the file has no samples.")
    rows = [line for _, line in lines]
    try:
        data = np.loadtxt(rows, delimiter=delimiter, ndmin=2, dtype=float)
    except ValueError as e:
        for n, line in lines:
            fields = _split(line, delimiter)
            if len(fields) != len(header):
                raise DataError(
                    f"{path}: line {n} has {len(fields)} fields, the header has "
                    f"{len(header)} columns."
                ) from e
            for j, cell in enumerate(fields):
                if not _is_number(cell):
                    raise DataError(
                        f"{path}: line {n}, column '{header[j]}' (field {j + 1}): "
                        f"{cell!r} is not a number; clean or trim the log"
                        + (
                            " (text in a column: for one row per sample and joint use "
                            "format: csv_long)."
                            if line is lines[0][1]
                            else "."
                        )
                    ) from e
        raise DataError(f"{path}: a value could not be read as a number.") from e
    if data.shape[1] != len(header):
        raise DataError(
            f"{path}: rows have {data.shape[1]} fields, the header has {len(header)} columns."
        )
    return data


FloatArray = npt.NDArray[np.float64]


def _table(
    path: Path, options: Mapping[str, Any]
) -> tuple[FloatArray, list[str], npt.NDArray[np.int64]]:
    lines = _lines(path)
    first = _first_line(lines)
    delimiter = options.get("delimiter") or sniff_delimiter(first)
    fields = _split(first, delimiter)
    has_header = options.get("header")
    if has_header is None:
        has_header = not all(_is_number(f) for f in fields if f)
    names = options.get("names")
    if has_header:
        header = [f.strip().strip('"') for f in fields]
        body = lines
        if names is not None and len(names) != len(header):
            raise DataError(
                f"{path}: names lists {len(names)} columns, the header has {len(header)}."
            )
        if names is not None:
            header = list(names)
    else:
        body = _chain([(1, first)], lines)
        n = len(fields)
        if names is not None:
            if len(names) != n:
                raise DataError(
                    f"{path}: names lists {len(names)} columns, the file has {n} per line."
                )
            header = list(names)
        else:
            stem = path.name.split(".")[0]
            header = [stem] if n == 1 else [f"{stem}:{k + 1}" for k in range(n)]
    blocks: list[FloatArray] = []
    numbers: list[npt.NDArray[np.int64]] = []
    block: list[tuple[int, str]] = []

    def flush() -> None:
        blocks.append(_parse(path, block, delimiter, header))
        numbers.append(np.array([n for n, _ in block], dtype=np.int64))
        block.clear()
        _check_memory(path, sum(len(b) for b in blocks), len(header))

    for number, line in body:
        if line.strip():
            block.append((number, line.rstrip("\r\n")))
            if len(block) == BLOCK_LINES:
                flush()
    if block:
        flush()
    n_rows = sum(len(b) for b in blocks)
    if not blocks:
        raise DataError(f"{path}: the file has no samples.")
    # Fortran order: every column is contiguous, taken as a view
    data = np.concatenate(blocks, axis=0, out=np.empty((n_rows, len(header)), order="F"))
    return data, header, np.concatenate(numbers)


def _chain(*parts: Any) -> Iterator[tuple[int, str]]:
    """The items of several iterables, one after the other."""
    for part in parts:
        yield from part


def _time_name(names: list[str], options: Mapping[str, Any]) -> str | None:
    wanted = options.get("time_column")
    if wanted is not None:
        return wanted if wanted in names else None
    lower = {n.lower(): n for n in names}
    return next((lower[t] for t in TIME_NAMES if t in lower), None)


def read_csv(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a wide text log: every column by name, in the file's units.

    Options: ``delimiter`` (default sniffed), ``header`` (True/False, default detected),
    ``names`` (column names: replace the header or name a headerless file), ``time_column``.
    """
    data, header, line_no = _table(path, options)
    if len(set(header)) != len(header):
        dup = sorted({h for h in header if header.count(h) > 1})
        raise DataError(f"{path}: duplicate column name(s) {', '.join(dup)}; rename them.")
    columns = {name: data[:, k] for k, name in enumerate(header)}  # contiguous views
    return [
        LogTable(
            columns=columns,
            time=_time_name(header, options),
            source=str(path),
            line_numbers=line_no,
        )
    ]


def read_csv_long(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a long text log (one row per sample and joint) and pivot it to wide columns.

    Options: ``time_column`` (default: a column named like time), ``joint_column`` (default
    ``joint``), plus those of :func:`read_csv`. The joint column holds names (text) or numbers.
    Every other column ``v`` becomes one column ``v/<joint>`` per joint, on the time stamps in
    the order they first appear (never sorted); every joint must have one row at every time
    stamp. NaN/inf stamps are refused naming the line.
    """
    lines = _lines(path)
    first = _first_line(lines)
    delimiter = options.get("delimiter") or sniff_delimiter(first)
    header = [f.strip().strip('"') for f in _split(first, delimiter)]
    joint_col = options.get("joint_column", "joint")
    time_col = _time_name(header, options)
    # a stamp column in other units (``time_ms``) orders the rows but is not taken for seconds:
    # the config names it with its unit (``log.time: {column: time_ms, unit: ms}``)
    unit_unknown = time_col is None and options.get("time_column") is None
    if unit_unknown:
        time_col = next(
            (h for h in header if re.split(r"[^a-z]+", h.lower())[0] in TIME_NAMES), None
        )
    for what, name in (("joint_column", joint_col), ("time_column", time_col)):
        if name is None or name not in header:
            raise DataError(
                f"{path}: long format needs a {what.replace('_', ' ')} "
                f"({name or 'time'}); the header has {', '.join(header)}."
            )
    assert time_col is not None  # checked just above
    j_idx = header.index(joint_col)
    numbered = []
    for number, line in lines:  # the long format is pivoted in memory: bounded by the ceiling
        if line.strip():
            numbered.append((number, line.rstrip("\r\n")))
            if len(numbered) % BLOCK_LINES == 0:
                _check_memory(path, 8 * len(numbered), len(header))  # text and lists
    split = [_split(line, delimiter) for _, line in numbered]
    joints_raw = [fields[j_idx] if len(fields) > j_idx else "" for fields in split]
    numeric_header = [h for k, h in enumerate(header) if k != j_idx]
    numeric_lines = [
        (n, (delimiter or " ").join(f for k, f in enumerate(fields) if k != j_idx))
        for (n, _), fields in zip(numbered, split, strict=True)
    ]
    data = _parse(path, numeric_lines, delimiter or None, numeric_header)
    t = data[:, numeric_header.index(time_col)]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(
            f"{path}: time column '{time_col}': {bad.size} time stamp(s) are NaN or infinite, "
            f"the first at line {numeric_lines[bad[0]][0]}; remove or repair those rows."
        )
    joint_names = list(dict.fromkeys(joints_raw))
    # samples in the order of the file (never sorted: the time rule handles a backwards jump)
    unique, first_row, inverse = np.unique(t, return_index=True, return_inverse=True)
    appearance = np.argsort(first_row, kind="stable")
    rank = np.empty(appearance.size, dtype=np.int64)
    rank[appearance] = np.arange(appearance.size)
    stamps = unique[appearance]
    columns: dict[str, FloatArray] = {time_col: stamps}
    joints_arr = np.array(joints_raw)
    for joint in joint_names:
        rows = np.flatnonzero(joints_arr == joint)
        position = rank[inverse[rows]]
        if rows.size != stamps.size or np.any(np.bincount(position, minlength=stamps.size) != 1):
            raise DataError(
                f"{path}: joint '{joint}' has {rows.size} rows for {stamps.size} time stamps; "
                "every joint needs one row per time stamp in the long format (a stamp "
                "repeated after a clock reset: split the file into several logs, log.more)."
            )
        for k, name in enumerate(numeric_header):
            if name != time_col:
                column = np.empty(stamps.size)
                column[position] = data[rows, k]
                columns[f"{name}/{joint}"] = column
    return [LogTable(columns=columns, time=None if unit_unknown else time_col, source=str(path))]
