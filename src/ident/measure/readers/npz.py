"""Binary logs as numpy archives (``.npz``): fast to write from a script or a simulator.

Every 1-D array of the archive is a column; a 2-D array ``name`` of shape (n_samples, k)
becomes the columns ``name/0`` ... ``name/k-1``; 0-d arrays (scalars such as a rate) are not
columns. A column named like time (``t``, ``time``) is the time column [s].

Before any array is loaded, the archive is checked from its headers: a zip file of ``.npy``
members, numeric arrays only (bool, integer, float: no object or string arrays, which would
need pickle or are not signals), 1 or 2 dimensions, and the declared sizes within the memory
ceiling ``IDENT_MAX_MEMORY_GB`` (a small archive declaring 100 million samples is refused, not
decompressed). Then each member is decompressed and converted to float64
:data:`BLOCK_BYTES` at a time into its final array (2-D: column-major, so every column is a
contiguous view): reading takes the columns plus one block, whatever the stored type.
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import DataError
from ident.inputs import JobEstimate, check_job
from ident.measure.readers.registry import TIME_NAMES, LogTable, check_regular_file

__all__ = ["BLOCK_BYTES", "estimate_npz", "is_npz", "read_npz"]

_READ_BYTES_PER_S = 200e6  # decompressed and converted per second (estimate)
BLOCK_BYTES = 1 << 18  # bytes of a member decompressed and converted at once (256 kB)


def is_npz(path: Path) -> bool:
    """Detector: a file named ``*.npz``."""
    return path.is_file() and path.suffix == ".npz"


@dataclass(frozen=True)
class _Member:
    """One ``.npy`` member of an archive as its header declares it."""

    info: zipfile.ZipInfo
    shape: tuple[int, ...]
    dtype: np.dtype
    fortran: bool


def _read_header(f: Any) -> tuple[Any, bool, Any]:
    """(shape, fortran_order, dtype) of the ``.npy`` stream ``f``, left at its first value."""
    if np.lib.format.read_magic(f) == (1, 0):
        return np.lib.format.read_array_header_1_0(f)
    return np.lib.format.read_array_header_2_0(f)


def _header(path: Path, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> _Member:
    """The declared shape, dtype and order of the member ``info`` (its header only)."""
    with archive.open(info) as f:
        shape, fortran, dtype = _read_header(f)
        header_bytes = f.tell()
    shape = tuple(int(n) for n in shape)
    dtype = np.dtype(dtype)
    n_values = int(np.prod(shape, dtype=object)) if shape else 1
    if header_bytes + n_values * dtype.itemsize > info.file_size:
        raise DataError(
            f"{path}: array '{info.filename.removesuffix('.npy')}' declares shape {shape} "
            f"({n_values} values) but its member holds {info.file_size} bytes; the archive is "
            "damaged or forged: write it again with numpy.savez."
        )
    return _Member(info, shape, dtype, bool(fortran))


def _headers(path: Path) -> dict[str, _Member]:
    """Name -> declared :class:`_Member` of every array, read from the ``.npy`` headers only."""
    check_regular_file(path)
    if not zipfile.is_zipfile(path):
        raise DataError(
            f"{path}: not a numpy archive (a .npz is a zip file); write it with numpy.savez."
        )
    out: dict[str, _Member] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.is_dir():
                    out[info.filename.removesuffix(".npy")] = _header(path, archive, info)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError) as e:
        raise DataError(f"{path}: cannot read the numpy archive ({e}).") from e
    if not out:
        raise DataError(f"{path}: the numpy archive holds no arrays.")
    for name, member in out.items():
        if member.dtype.kind not in "biuf":
            raise DataError(
                f"{path}: array '{name}' holds {member.dtype} values, not numbers; save the "
                "signals as float arrays."
            )
        if len(member.shape) > 2:
            raise DataError(f"{path}: array '{name}' has {len(member.shape)} dimensions (1 or 2).")
    return out


def _declared_bytes(headers: Mapping[str, _Member]) -> float:
    """Bytes of the columns as float64 (each member is converted a block at a time into its
    final array: nothing else grows with the archive)."""
    total = float(BLOCK_BYTES)
    for member in headers.values():
        if member.shape:
            total += 8.0 * float(np.prod(member.shape, dtype=float))
    return total


def estimate_npz(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading ``path``, from its array headers."""
    headers = _headers(path)
    memory = _declared_bytes(headers)
    return JobEstimate(
        f"reading {path.name}: {len(headers)} arrays", memory, memory / _READ_BYTES_PER_S
    )


def _read_member(archive: zipfile.ZipFile, member: _Member) -> npt.NDArray[np.float64]:
    """The member's values as float64, shape as declared (2-D: column-major, every column
    contiguous), decompressed and converted :data:`BLOCK_BYTES` at a time into that array."""
    shape, dtype = member.shape, member.dtype
    out = np.empty(shape, order="F")
    # the file's value order: rows of a C-order 2-D array, else out's own (flat) order
    by_rows = len(shape) == 2 and not member.fortran
    target = out if by_rows else out.T.reshape(-1)  # a view: out is Fortran-contiguous
    width = shape[1] if by_rows else 1
    step = max(1, BLOCK_BYTES // max(1, width * dtype.itemsize))
    with archive.open(member.info) as f:
        _read_header(f)
        for a in range(0, target.shape[0], step):
            m = min(step, target.shape[0] - a)
            data = f.read(m * width * dtype.itemsize)
            if len(data) != m * width * dtype.itemsize:
                raise EOFError(f"array '{member.info.filename}' ends early")
            block = np.frombuffer(data, dtype=dtype)
            target[a : a + m] = block.reshape(m, width) if by_rows else block
    return out


def read_npz(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a ``.npz`` log (option ``time_column``): the declared sizes are checked against
    the memory ceiling before any array is allocated, then each member is read by blocks."""
    headers = _headers(path)
    check_job(
        JobEstimate(f"{path}: {len(headers)} arrays as declared", _declared_bytes(headers), 0.0)
    )
    columns: dict[str, npt.NDArray[np.float64]] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for name, member in headers.items():
                if not member.shape:
                    continue
                values = _read_member(archive, member)
                if values.ndim == 1:
                    columns[name] = values
                else:
                    for k in range(values.shape[1]):  # contiguous views, not copies
                        columns[f"{name}/{k}"] = values[:, k]
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError) as e:
        raise DataError(f"{path}: cannot read the numpy archive ({e}).") from e
    if not columns:
        raise DataError(f"{path}: the numpy archive holds no 1-D or 2-D arrays.")
    lengths = {c.shape[0] for c in columns.values()}
    if len(lengths) > 1:
        raise DataError(f"{path}: arrays of different lengths {sorted(lengths)}.")
    if lengths == {0}:
        raise DataError(f"{path}: the arrays have no samples.")
    wanted = options.get("time_column")
    lower = {n.lower(): n for n in columns}
    time = wanted if wanted in columns else next((lower[t] for t in TIME_NAMES if t in lower), None)
    return [LogTable(columns=columns, time=time, source=str(path))]
