"""Small LeRobot datasets for the reader tests: the project's writer
(:func:`ident.measure.lerobot_dataset.write_dataset`) and the closed form of the ticks."""

from __future__ import annotations

import numpy as np

from ident.measure.lerobot_dataset import write_dataset

__all__ = ["TICKS_PER_REV", "ZERO_TICK", "ticks_to_rad", "write_dataset"]

# Feetech STS3215 (SO-100 / SO-101 arms): 4096 ticks per turn, centre 2048
TICKS_PER_REV = 4096
ZERO_TICK = 2048


def ticks_to_rad(ticks: np.ndarray, zero: float = ZERO_TICK) -> np.ndarray:
    """Closed form of the conversion the reader's config declares: (ticks - zero) 2 pi / 4096."""
    return (np.asarray(ticks, dtype=float) - zero) * 2.0 * np.pi / TICKS_PER_REV
