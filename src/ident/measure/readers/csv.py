"""CSV, TSV and plain-text log readers (plain or gzip-compressed).

``read_csv`` reads a *wide* file: one column per signal and joint. The first line is a header
when any of its fields is not a number; otherwise columns are named by ``names`` (the
config's list), or by the file stem (one column: ``q1.txt`` -> ``q1``; several:
``stem:1``, ``stem:2``, ...). The delimiter is the config's, or the first of tab, comma and
semicolon in the first line, else whitespace. ``read_csv_long`` reads a *long* file: one row
per sample and joint, pivoted to the wide ``<value>/<joint>`` columns.

Error messages give file line numbers (the header, when present, is line 1; blank lines count).
"""

from __future__ import annotations

import gzip
import io
import re
import zlib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.measure.readers.registry import TIME_NAMES, LogTable

__all__ = ["is_text", "open_text", "read_csv", "read_csv_long", "sniff_delimiter"]

_TEXT_SUFFIXES = {".csv", ".tsv", ".txt", ".dat", ".log"}


def open_text(path: Path) -> io.TextIOBase:
    """Open a text file, decompressing ``.gz`` on the fly."""
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


def _read_text(path: Path) -> tuple[str, str]:
    try:
        with open_text(path) as f:
            first = f.readline()
            rest = f.read()
    except (OSError, UnicodeDecodeError, EOFError, zlib.error) as e:  # zlib: a damaged .gz
        raise DataError(f"{path}: cannot read the log file ({e}).") from e
    return first, rest


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
    first, rest = _read_text(path)
    delimiter = options.get("delimiter") or sniff_delimiter(first)
    fields = _split(first, delimiter)
    has_header = options.get("header")
    if has_header is None:
        has_header = not all(_is_number(f) for f in fields if f)
    names = options.get("names")
    if has_header:
        header = [f.strip().strip('"') for f in fields]
        body, offset = rest, 2
        if names is not None and len(names) != len(header):
            raise DataError(
                f"{path}: names lists {len(names)} columns, the header has {len(header)}."
            )
        if names is not None:
            header = list(names)
    else:
        body, offset = first + rest, 1
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
    numbered = [(k + offset, line) for k, line in enumerate(body.splitlines()) if line.strip()]
    data = _parse(path, numbered, delimiter, header)
    line_no = np.array([n for n, _ in numbered], dtype=np.int64)
    return data, header, line_no


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
    columns = {name: np.ascontiguousarray(data[:, k]) for k, name in enumerate(header)}
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
    Every other column ``v`` becomes one column ``v/<joint>`` per joint, on the sorted set of
    time stamps; every joint must have a row at every time stamp.
    """
    first, rest = _read_text(path)
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
    j_idx = header.index(joint_col)
    numbered = [(k + 2, line) for k, line in enumerate(rest.splitlines()) if line.strip()]
    split = [_split(line, delimiter) for _, line in numbered]
    joints_raw = [fields[j_idx] if len(fields) > j_idx else "" for fields in split]
    numeric_header = [h for k, h in enumerate(header) if k != j_idx]
    numeric_lines = [
        (n, (delimiter or " ").join(f for k, f in enumerate(fields) if k != j_idx))
        for (n, _), fields in zip(numbered, split, strict=True)
    ]
    data = _parse(path, numeric_lines, delimiter or None, numeric_header)
    t = data[:, numeric_header.index(time_col)]
    joint_names = list(dict.fromkeys(joints_raw))
    stamps = np.unique(t)
    columns: dict[str, FloatArray] = {time_col: stamps}
    joints_arr = np.array(joints_raw)
    for joint in joint_names:
        rows = np.flatnonzero(joints_arr == joint)
        tj = t[rows]
        order = np.argsort(tj, kind="stable")
        if rows.size != stamps.size or np.any(tj[order] != stamps):
            raise DataError(
                f"{path}: joint '{joint}' has {rows.size} rows for {stamps.size} time stamps; "
                "every joint needs one row per time stamp in the long format."
            )
        for k, name in enumerate(numeric_header):
            if name != time_col:
                columns[f"{name}/{joint}"] = np.ascontiguousarray(data[rows[order], k])
    return [LogTable(columns=columns, time=None if unit_unknown else time_col, source=str(path))]
