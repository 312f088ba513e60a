"""Long text logs: one row per sample and joint (``time, joint, values...``), pivoted to wide.

Every value column ``v`` becomes one column ``v/<joint>`` per joint, on the time stamps in
the order they first appear (never sorted); every joint must have one row at every time stamp.

Bounded memory: the lines are counted first (:func:`ident.measure.readers.csv.count_lines`,
a decompression bomb stops there), the values of every row go into one array allocated once
(checked against ``IDENT_MAX_MEMORY_GB``), and the text is parsed and pivoted a block at a
time: 4 MiB at once by pyarrow's CSV parser (:mod:`ident.measure.readers.text_blocks`, about
0.6 us per row), or, for text that parser may read otherwise (whitespace-delimited, a value
that is not a number, a NaN stamp, ...), :data:`~ident.measure.readers.csv.BLOCK_LINES`
lines at a time split in Python (about 4 us per row), whose errors name the line. A log
written as controllers write it (at each stamp one row per joint, the joints in the same
order) is recognised while it is read: only one stamp per sample is kept and the wide
columns are views of the values' array (an hour of 7 joints at 1 kHz with two value
columns: 0.40 GB of values and 29 MB of stamps). Rows in any other order keep every row's
stamp and joint and are pivoted at the end (np.unique over the stamps), with that memory
checked against the ceiling first.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.inputs import JobEstimate, check_job
from ident.measure.readers.csv import (
    blocks,
    count_lines,
    first_line,
    grew,
    lines_of,
    parse,
    sample_rows,
    sniff_delimiter,
    split_fields,
    time_name,
)
from ident.measure.readers.registry import TIME_NAMES, LogTable

__all__ = ["MAX_JOINTS", "estimate_csv_long", "read_csv_long"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

MAX_JOINTS = 10_000  # distinct names in the joint column: more is not a joint column
# a block's text, fields and numbers: 65 536 lines read line by line, or 4 MiB parsed by
# pyarrow (measured 43 MB above the kept arrays: the text, its copy with the carried line,
# pyarrow's columns and pool)
_BLOCK_BYTES = 48e6
# Text read per second of CPU, rounded down from benchmarks/bench_identify_long.py's long CSV
# on the shared 2-core box at load 5-7: the hour (1288 MB, 25.2 M rows) in 16.6 s user +
# 2.3 s system by pyarrow's blocks (68 MB/s; peak 530 MiB with the interpreter); the 2 minutes
# (41 MB) in 3.1 s line by line (13 MB/s; 4.4 MB/s for the old hour at load 11).
_BYTES_PER_S = 40e6
_BYTES_PER_S_BY_LINE = 8e6


class _Layout:
    """The columns of a long log: which is the joint, which the time, which hold values."""

    def __init__(self, path: Path, first: str, options: Mapping[str, Any]) -> None:
        self.delimiter = options.get("delimiter") or sniff_delimiter(first)
        header = [f.strip().strip('"') for f in split_fields(first, self.delimiter)]
        joint_col = options.get("joint_column", "joint")
        time_col = time_name(header, options)
        # a stamp column in other units (``time_ms``) orders the rows but is not taken for
        # seconds: the config names it with its unit (``log.time: {column: time_ms, unit: ms}``)
        self.unit_unknown = time_col is None and options.get("time_column") is None
        if self.unit_unknown:
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
        self.header, self.time_col = header, time_col
        self.joint = header.index(joint_col)
        self.numeric = [k for k in range(len(header)) if k != self.joint]
        self.numeric_names = [header[k] for k in self.numeric]
        self.time = self.numeric_names.index(time_col)
        self.value_names = [h for h in self.numeric_names if h != time_col]


def _parse_block(
    path: Path, block: list[tuple[int, str]], layout: _Layout, joints: dict[str, int]
) -> tuple[FloatArray, IntArray, FloatArray]:
    """Stamps (m,), joint codes (m,) (in order of first appearance) and values (m,
    n_values) of the lines ``block``; NaN/inf stamps refused naming the line."""
    split = [split_fields(line, layout.delimiter) for _, line in block]
    n_fields = len(layout.header)
    try:
        if any(len(fields) != n_fields for fields in split):
            raise ValueError("a line with another number of fields")
        data = np.loadtxt(
            [line for _, line in block],
            delimiter=layout.delimiter,
            usecols=layout.numeric,
            ndmin=2,
            dtype=float,
        )
    except ValueError:  # the slow way, for the message naming the line and the column
        numeric_lines = [
            (
                n,
                (layout.delimiter or " ").join(
                    f for k, f in enumerate(fields) if k != layout.joint
                ),
            )
            for (n, _), fields in zip(block, split, strict=True)
        ]
        data = parse(path, numeric_lines, layout.delimiter or None, layout.numeric_names)
    t = data[:, layout.time]
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise DataError(
            f"{path}: time column '{layout.time_col}': a time stamp is NaN or infinite, "
            f"the first at line {block[bad[0]][0]}; remove or repair those rows."
        )
    codes = np.fromiter(
        (
            joints.setdefault(
                fields[layout.joint] if len(fields) > layout.joint else "", len(joints)
            )
            for fields in split
        ),
        dtype=np.int64,
        count=len(split),
    )
    if len(joints) > MAX_JOINTS:
        raise DataError(
            f"{path}: the joint column '{layout.header[layout.joint]}' holds more than "
            f"{MAX_JOINTS} names by line {block[-1][0]}; name the joint column (joint_column)."
        )
    return t.copy(), codes, np.delete(data, layout.time, axis=1)


class _Pivot:
    """The rows of a long log, a block at a time: every row's values in one array allocated
    once; while the rows come grouped (at each stamp one row per joint, the joints in the
    order of the first stamp) one stamp per group, else every row's stamp and joint code."""

    def __init__(self, path: Path, capacity: int, n_values: int) -> None:
        check_job(
            JobEstimate(
                f"{path}: {capacity} lines x {n_values} values",
                8.0 * capacity * n_values + _BLOCK_BYTES,
                0.0,
            )
        )
        self.path, self.capacity, self.n = path, capacity, 0
        self.values = np.empty((capacity, n_values), order="F")
        self.order: IntArray | None = None  # joint codes of a group (grouped rows)
        self.stamps: FloatArray | None = None  # stamp of each group (grouped rows)
        self.t: FloatArray | None = None  # every row's stamp (rows in any order)
        self.codes: IntArray | None = None  # every row's joint code (rows in any order)

    def add(self, t: FloatArray, codes: IntArray, values: FloatArray) -> None:
        a, m = self.n, t.size
        if a + m > self.capacity:
            raise grew(self.path)
        self.values[a : a + m] = values
        if self.t is None and not self._grouped(t, codes):
            self._ungroup()
        if self.t is not None and self.codes is not None:
            self.t[a : a + m] = t
            self.codes[a : a + m] = codes
        self.n += m

    def _grouped(self, t: FloatArray, codes: IntArray) -> bool:
        """Extend the grouped rows by a block (stamps ``t``, joint ``codes``); False when
        the block does not continue them."""
        a = self.n
        if self.order is None:  # the first group: the rows at the first stamp
            change = np.flatnonzero(t != t[0])
            if change.size == 0 or np.unique(codes[: change[0]]).size != change[0]:
                return False
            self.order = codes[: change[0]].copy()
            n_groups = -(-self.capacity // self.order.size)
            check_job(
                JobEstimate(
                    f"{self.path}: {n_groups} stamps",
                    8.0 * (self.values.size + n_groups) + _BLOCK_BYTES,
                    0.0,
                )
            )
            self.stamps = np.empty(n_groups)
        assert self.stamps is not None
        nj = self.order.size
        rows = np.arange(a, a + t.size)
        if not np.array_equal(codes, self.order[rows % nj]):
            return False
        start = (-a) % nj  # the first row of the block that begins a group
        self.stamps[(a + start) // nj : (a + t.size - 1) // nj + 1] = t[start::nj]
        return bool(np.array_equal(t, self.stamps[rows // nj]))

    def _ungroup(self) -> None:
        """Keep every row's stamp and joint code from now on (and for the rows so far)."""
        if self.t is not None:
            return
        check_job(
            JobEstimate(
                f"{self.path}: {self.capacity} rows in any order",
                8.0 * self.capacity * (self.values.shape[1] + 2) + _BLOCK_BYTES,
                0.0,
            )
        )
        self.t, self.codes = np.empty(self.capacity), np.empty(self.capacity, dtype=np.int64)
        if self.order is not None and self.stamps is not None and self.n:
            n, nj = self.n, self.order.size
            self.t[:n] = np.repeat(self.stamps[: -(-n // nj)], nj)[:n]
            self.codes[:n] = np.tile(self.order, -(-n // nj))[:n]

    def grouped_columns(self) -> tuple[FloatArray, list[FloatArray]] | None:
        """(stamps, per joint code the (n_stamps, n_values) values) of grouped rows with
        distinct stamps; None otherwise (then :meth:`columns` pivots every row)."""
        if self.t is not None or self.order is None or self.stamps is None:
            return None
        nj = self.order.size
        if self.n % nj:
            return None
        stamps = self.stamps[: self.n // nj]
        increasing = bool(np.all(stamps[1:] > stamps[:-1]))
        if not increasing and np.unique(stamps).size != stamps.size:
            return None
        # views: row p of every group is joint order[p]
        by_code = {int(c): self.values[p : self.n : nj] for p, c in enumerate(self.order)}
        return stamps, [by_code[c] for c in range(nj)]


def _pivot_any_order(
    path: Path, pivot: _Pivot, joints: list[str]
) -> tuple[FloatArray, list[FloatArray]]:
    """(stamps in order of first appearance, per joint code its (n_stamps, n_values) values)
    of rows in any order; DataError when a joint lacks a row at a stamp or has two."""
    pivot._ungroup()
    assert pivot.t is not None
    assert pivot.codes is not None
    n = pivot.n
    t, codes = pivot.t[:n], pivot.codes[:n]
    check_job(
        JobEstimate(
            f"{path}: {n} rows in any order, pivoted",
            8.0 * n * (2 * pivot.values.shape[1] + 6) + _BLOCK_BYTES,  # np.unique's arrays
            0.0,
        )
    )
    unique, first_row, inverse = np.unique(t, return_index=True, return_inverse=True)
    appearance = np.argsort(first_row, kind="stable")
    rank = np.empty(appearance.size, dtype=np.int64)
    rank[appearance] = np.arange(appearance.size)
    stamps = unique[appearance]
    out = []
    for code, joint in enumerate(joints):
        rows = np.flatnonzero(codes == code)
        position = rank[inverse[rows]]
        if rows.size != stamps.size or np.any(np.bincount(position, minlength=stamps.size) != 1):
            raise DataError(
                f"{path}: joint '{joint}' has {rows.size} rows for {stamps.size} time stamps; "
                "every joint needs one row per time stamp in the long format (a stamp "
                "repeated after a clock reset: split the file into several logs, log.more)."
            )
        values = np.empty((stamps.size, pivot.values.shape[1]), order="F")
        values[position] = pivot.values[rows]
        out.append(values)
    return stamps, out


def _read_blocks(
    path: Path, layout: _Layout, pivot: _Pivot, joints: dict[str, int], block_bytes: int | None
) -> bool:
    """Add the rows of ``path`` to ``pivot`` by blocks of bytes parsed at once
    (:func:`ident.measure.readers.text_blocks.number_blocks`), the joint names to ``joints``
    (code by order of first appearance); False, with ``pivot`` partly filled, when the text
    must be read line by line (a delimiter of whitespace, text the parser does not take as
    the line reader does, a NaN/inf stamp or too many joints: the line reader names the line).
    """
    if layout.delimiter is None or block_bytes == 0:
        return False
    # pyarrow (0.15 s to import) only when a long log is read
    from ident.measure.readers import text_blocks

    size = text_blocks.BLOCK_BYTES if block_bytes is None else block_bytes
    try:
        for names, index, numbers in text_blocks.number_blocks(
            path, layout.delimiter, len(layout.header), layout.joint, size
        ):
            # split_fields strips the fields: so are the names
            codes = np.array([joints.setdefault(n.strip(), len(joints)) for n in names])
            t = numbers[:, layout.time]
            if len(joints) > MAX_JOINTS or not np.all(np.isfinite(t)):
                return False
            pivot.add(t.copy(), codes[index], np.delete(numbers, layout.time, axis=1))
    except text_blocks.NotPlain:
        return False
    return True


def estimate_csv_long(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading the long text log ``path`` from its size and first data
    line: every row's values and (at most) a stamp per row, and a block; the time at the rate
    of pyarrow's blocks, or of the line reader for a whitespace-delimited log."""
    size, n_rows, fields, delimiter = sample_rows(path, options)
    n_values = max(len(fields) - 2, 1)  # all but the time and the joint
    # rows written as controllers write them keep one stamp per sample (n_rows / n_joints);
    # in any other order every row's stamp and joint are kept: the estimate counts one per row
    by_line = delimiter is None or len(delimiter) != 1
    return JobEstimate(
        f"reading {path.name}: about {n_rows:.3g} rows x {n_values} values",
        8.0 * n_rows * (n_values + 1) + _BLOCK_BYTES,
        size / (_BYTES_PER_S_BY_LINE if by_line else _BYTES_PER_S),
    )


def read_csv_long(
    path: Path, options: Mapping[str, Any], *, block_bytes: int | None = None
) -> list[LogTable]:
    """Read a long text log (one row per sample and joint) and pivot it to wide columns.

    Options: ``time_column`` (default: a column named like time), ``joint_column`` (default
    ``joint``), ``delimiter``. The joint column holds names (text) or numbers. NaN/inf stamps
    are refused naming the line. ``block_bytes``: text parsed at once by the vectorised
    parser (default :data:`ident.measure.readers.text_blocks.BLOCK_BYTES`); 0 reads line by
    line (as the reader does for any text the parser may read otherwise, or refuses).
    """
    lines = lines_of(path)
    layout = _Layout(path, first_line(lines), options)
    n_values = len(layout.value_names)
    capacity = count_lines(path, 8.0 * (n_values + 2))  # values, and stamp and joint per row
    pivot = _Pivot(path, capacity, n_values)
    joints: dict[str, int] = {}
    if not _read_blocks(path, layout, pivot, joints, block_bytes):
        del pivot  # the text is read again line by line, for the messages naming the line
        pivot, joints = _Pivot(path, capacity, n_values), {}
        for block in blocks(lines):
            pivot.add(*_parse_block(path, block, layout, joints))
    if not pivot.n:
        raise DataError(f"{path}: the file has no samples.")
    names = list(joints)
    stamps, by_joint = pivot.grouped_columns() or _pivot_any_order(path, pivot, names)
    columns: dict[str, FloatArray] = {layout.time_col: stamps}
    for joint, values in zip(names, by_joint, strict=True):
        for k, name in enumerate(layout.value_names):
            columns[f"{name}/{joint}"] = values[:, k]
    time = None if layout.unit_unknown else layout.time_col
    return [LogTable(columns=columns, time=time, source=str(path))]
