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
import struct
import zlib
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.inputs import JobEstimate, check_job, resource_ceilings
from ident.measure.readers.registry import TIME_NAMES, LogTable, check_regular_file

__all__ = [
    "BLOCK_LINES",
    "COUNT_BYTES",
    "MAX_LINE_CHARS",
    "count_lines",
    "estimate_csv",
    "is_text",
    "open_bytes",
    "open_text",
    "read_csv",
    "sample_rows",
    "sniff_delimiter",
]

# A line of 10 000 numbers is about 200 000 characters: a longer one is not a log line.
MAX_LINE_CHARS = 1 << 20
BLOCK_LINES = 1 << 16  # lines parsed at once
COUNT_BYTES = 1 << 20  # text decompressed at once to count the lines
# the text and parsed numbers of a block held at once: 65 536 lines of up to ~200 characters
_BLOCK_BYTES = 32e6
_PARSE_BYTES_PER_S = 30e6  # text parsed per second (estimate)

FloatArray = npt.NDArray[np.float64]

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


def split_fields(line: str, delimiter: str | None) -> list[str]:
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


def lines_of(path: Path) -> Iterator[tuple[int, str]]:
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


def first_line(lines: Iterator[tuple[int, str]]) -> str:
    return next(lines, (0, ""))[1]


def count_lines(path: Path, bytes_per_line: float) -> int:
    """Lines of the text (decompressed, the last one without a line break counted), read
    :data:`COUNT_BYTES` at a time in constant memory; refused as soon as their numbers
    (``bytes_per_line`` each) would pass the memory ceiling, so a decompression bomb stops
    here, before anything grows with it.

    Raises
    ------
    ResourceLimitError
        Naming the file, the lines counted so far and ``IDENT_MAX_MEMORY_GB``.
    DataError
        For an unreadable or damaged file.
    """
    ceiling, _ = resource_ceilings()
    n, last = 0, b"\n"
    try:
        with open_bytes(path) as f:
            while chunk := f.read(COUNT_BYTES):
                n += chunk.count(b"\n")
                last = chunk[-1:]
                if n * bytes_per_line > ceiling:  # a product and a comparison per block
                    check_job(
                        JobEstimate(f"{path}: reading at least {n} lines", n * bytes_per_line, 0.0)
                    )
    except (OSError, EOFError, zlib.error) as e:  # zlib: a damaged .gz
        raise DataError(f"{path}: cannot read the log file ({e}).") from e
    return n + (last != b"\n")


def open_bytes(path: Path) -> io.BufferedIOBase:
    check_regular_file(path)
    if path.suffix == ".gz":
        return gzip.open(path, "rb")  # type: ignore[return-value]
    return open(path, "rb")  # noqa: SIM115 - closed by the caller's with


def sample_rows(path: Path, options: Mapping[str, Any]) -> tuple[int, float, list[str], str | None]:
    """The text's size [characters, decompressed], its rows (the size over the first data
    line's length), the fields of that line (the second non-blank one when there is a
    header) and the delimiter that split them: the config's or the sniffed one (None: any
    whitespace)."""
    first = ""
    seen = 0
    for _, line in lines_of(path):
        if line.strip():
            first, seen = line, seen + 1
            if seen == 2:
                break
    size = text_size(path)
    delimiter = options.get("delimiter") or sniff_delimiter(first)
    return size, size / max(len(first), 1), split_fields(first, delimiter), delimiter


def estimate_csv(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading the text log ``path`` (its size over its first line's)."""
    size, n_rows, fields, _ = sample_rows(path, options)
    n_columns = max(len(fields), 1)
    return JobEstimate(
        f"reading {path.name}: about {n_rows:.3g} rows x {n_columns} columns",
        8.0 * n_rows * (n_columns + 1) + _BLOCK_BYTES,  # the numbers, a line number per row
        size / _PARSE_BYTES_PER_S,
    )


def parse(
    path: Path,
    lines: list[tuple[int, str]],
    delimiter: str | None,
    header: list[str],
) -> FloatArray:
    """The numbers of the text ``lines`` ``(line number, text)``, shape (len(lines),
    len(header)); a line that is not numbers is named in the error."""
    if not lines:
        raise DataError(f"{path}: the file has no samples.")
    rows = [line for _, line in lines]
    try:
        data = np.loadtxt(rows, delimiter=delimiter, ndmin=2, dtype=float)
    except ValueError as e:
        for n, line in lines:
            fields = split_fields(line, delimiter)
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


def _header(
    path: Path, first: str, options: Mapping[str, Any]
) -> tuple[list[str], str | None, bool]:
    """(column names, delimiter, whether ``first`` is a header line) of a wide text log."""
    delimiter = options.get("delimiter") or sniff_delimiter(first)
    fields = split_fields(first, delimiter)
    has_header = options.get("header")
    if has_header is None:
        has_header = not all(_is_number(f) for f in fields if f)
    names = options.get("names")
    if has_header:
        header = [f.strip().strip('"') for f in fields]
        if names is not None and len(names) != len(header):
            raise DataError(
                f"{path}: names lists {len(names)} columns, the header has {len(header)}."
            )
    else:
        n = len(fields)
        if names is not None and len(names) != n:
            raise DataError(f"{path}: names lists {len(names)} columns, the file has {n} per line.")
        stem = path.name.split(".")[0]
        header = [stem] if n == 1 else [f"{stem}:{k + 1}" for k in range(n)]
    return (list(names) if names is not None else header), delimiter, bool(has_header)


def blocks(lines: Iterator[tuple[int, str]]) -> Iterator[list[tuple[int, str]]]:
    """The non-blank lines (without their line break) by :data:`BLOCK_LINES`."""
    block: list[tuple[int, str]] = []
    for number, line in lines:
        if line.strip():
            block.append((number, line.rstrip("\r\n")))
            if len(block) == BLOCK_LINES:
                yield block
                block = []
    if block:
        yield block


def grew(path: Path) -> DataError:
    """The error for a file that holds more lines than were counted before reading it."""
    return DataError(
        f"{path}: the file grew while it was read (a log still being written?); copy it "
        "once it is complete and read the copy."
    )


def _table(
    path: Path, options: Mapping[str, Any]
) -> tuple[FloatArray, list[str], npt.NDArray[np.int64]]:
    """The numbers (rows, columns; column-major: every column contiguous), the column names
    and the file line of every row. The lines are counted first (:func:`count_lines`), the
    array allocated once (checked against the memory ceiling) and filled block by block."""
    lines = lines_of(path)
    first = first_line(lines)
    header, delimiter, has_header = _header(path, first, options)
    per_line = 8.0 * (len(header) + 1)  # the numbers and the line number
    capacity = count_lines(path, per_line)
    check_job(
        JobEstimate(
            f"{path}: {capacity} lines x {len(header)} columns",
            capacity * per_line + _BLOCK_BYTES,
            0.0,
        )
    )
    data = np.empty((capacity, len(header)), order="F")
    numbers = np.empty(capacity, dtype=np.int64)
    n_rows = 0
    for block in blocks(lines if has_header else _chain([(1, first)], lines)):
        m = len(block)
        if n_rows + m > capacity:
            raise grew(path)
        data[n_rows : n_rows + m] = parse(path, block, delimiter, header)
        numbers[n_rows : n_rows + m] = [n for n, _ in block]
        n_rows += m
    if not n_rows:
        raise DataError(f"{path}: the file has no samples.")
    # the first rows of a column-major array: every column is still contiguous
    return data[:n_rows], header, numbers[:n_rows]


def _chain(*parts: Any) -> Iterator[tuple[int, str]]:
    """The items of several iterables, one after the other."""
    for part in parts:
        yield from part


def time_name(names: list[str], options: Mapping[str, Any]) -> str | None:
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
            time=time_name(header, options),
            source=str(path),
            line_numbers=line_no,
        )
    ]
