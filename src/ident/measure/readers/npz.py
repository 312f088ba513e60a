"""Binary logs as numpy archives (``.npz``): fast to write from a script or a simulator.

Every 1-D array of the archive is a column; a 2-D array ``name`` of shape (n_samples, k)
becomes the columns ``name/0`` ... ``name/k-1``. A column named like time (``t``, ``time``)
is the time column [s].
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from ident.errors import DataError
from ident.measure.readers.registry import TIME_NAMES, LogTable

__all__ = ["is_npz", "read_npz"]


def is_npz(path: Path) -> bool:
    """Detector: a file named ``*.npz``."""
    return path.is_file() and path.suffix == ".npz"


def read_npz(path: Path, options: Mapping[str, Any]) -> list[LogTable]:
    """Read a ``.npz`` log (option ``time_column``)."""
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError) as e:
        raise DataError(f"{path}: cannot read the numpy archive ({e}).") from e
    columns: dict[str, np.ndarray] = {}
    with archive:
        for name in archive.files:
            values = np.asarray(archive[name], dtype=float)
            if values.ndim == 1:
                columns[name] = values
            elif values.ndim == 2:
                for k in range(values.shape[1]):
                    columns[f"{name}/{k}"] = np.ascontiguousarray(values[:, k])
            else:
                raise DataError(f"{path}: array '{name}' has {values.ndim} dimensions (1 or 2).")
    lengths = {c.shape[0] for c in columns.values()}
    if len(lengths) > 1:
        raise DataError(f"{path}: arrays of different lengths {sorted(lengths)}.")
    wanted = options.get("time_column")
    lower = {n.lower(): n for n in columns}
    time = wanted if wanted in columns else next((lower[t] for t in TIME_NAMES if t in lower), None)
    return [LogTable(columns=columns, time=time, source=str(path))]
