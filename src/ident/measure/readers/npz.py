"""Binary logs as numpy archives (``.npz``): fast to write from a script or a simulator.

Every 1-D array of the archive is a column; a 2-D array ``name`` of shape (n_samples, k)
becomes the columns ``name/0`` ... ``name/k-1``; 0-d arrays (scalars such as a rate) are not
columns. A column named like time (``t``, ``time``) is the time column [s].

Before any array is loaded, the archive is checked from its headers: a zip file of ``.npy``
members, numeric arrays only (bool, integer, float: no object or string arrays, which would
need pickle or are not signals), 1 or 2 dimensions, and the declared sizes within the memory
ceiling ``IDENT_MAX_MEMORY_GB`` (a small archive declaring 100 million samples is refused, not
decompressed).
"""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ident.errors import DataError
from ident.inputs import JobEstimate, check_job
from ident.measure.readers.registry import TIME_NAMES, LogTable, check_regular_file

__all__ = ["estimate_npz", "is_npz", "read_npz"]

_READ_BYTES_PER_S = 200e6  # decompressed and converted per second (estimate)


def is_npz(path: Path) -> bool:
    """Detector: a file named ``*.npz``."""
    return path.is_file() and path.suffix == ".npz"


def _headers(path: Path) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Name -> (shape, dtype) of every array, read from the ``.npy`` headers only."""
    check_regular_file(path)
    if not zipfile.is_zipfile(path):
        raise DataError(
            f"{path}: not a numpy archive (a .npz is a zip file); write it with numpy.savez."
        )
    out: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if info.is_dir():
                    continue
                name = info.filename.removesuffix(".npy")
                with archive.open(info) as f:
                    version = np.lib.format.read_magic(f)
                    if version == (1, 0):
                        shape, _, dtype = np.lib.format.read_array_header_1_0(f)
                    else:
                        shape, _, dtype = np.lib.format.read_array_header_2_0(f)
                    header_bytes = f.tell()
                shape = tuple(int(n) for n in shape)
                dtype = np.dtype(dtype)
                n_values = int(np.prod(shape, dtype=object)) if shape else 1
                if header_bytes + n_values * dtype.itemsize > info.file_size:
                    raise DataError(
                        f"{path}: array '{name}' declares shape {shape} ({n_values} values) "
                        f"but its member holds {info.file_size} bytes; the archive is damaged "
                        "or forged: write it again with numpy.savez."
                    )
                out[name] = (shape, dtype)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, NotImplementedError) as e:
        raise DataError(f"{path}: cannot read the numpy archive ({e}).") from e
    if not out:
        raise DataError(f"{path}: the numpy archive holds no arrays.")
    for name, (shape, dtype) in out.items():
        if dtype.kind not in "biuf":
            raise DataError(
                f"{path}: array '{name}' holds {dtype} values, not numbers; save the signals "
                "as float arrays."
            )
        if len(shape) > 2:
            raise DataError(f"{path}: array '{name}' has {len(shape)} dimensions (1 or 2).")
    return out


def _declared_bytes(headers: Mapping[str, tuple[tuple[int, ...], np.dtype]]) -> float:
    """Bytes of the columns as float64 (plus the arrays as stored while converting)."""
    total = 0.0
    for shape, dtype in headers.values():
        n = float(np.prod(shape, dtype=float)) if shape else 0.0
        total += n * (8.0 + dtype.itemsize)
    return total


def estimate_npz(path: Path, options: Mapping[str, Any]) -> JobEstimate:
    """Memory and time of reading ``path``, from its array headers."""
    headers = _headers(path)
    memory = _declared_bytes(headers)
    return JobEstimate(
        f"reading {path.name}: {len(headers)} arrays", memory, memory / _READ_BYTES_PER_S
    )


def read_npz(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a ``.npz`` log (option ``time_column``)."""
    headers = _headers(path)
    check_job(
        JobEstimate(f"{path}: {len(headers)} arrays as declared", _declared_bytes(headers), 0.0)
    )
    columns: dict[str, np.ndarray] = {}
    try:
        with np.load(path, allow_pickle=False) as archive:
            for name in archive.files:
                shape, _ = headers[name]
                if len(shape) == 0:
                    continue
                values = np.asarray(archive[name], dtype=float)
                if values.ndim == 1:
                    columns[name] = values
                else:
                    for k in range(values.shape[1]):  # views: the array is not copied
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
