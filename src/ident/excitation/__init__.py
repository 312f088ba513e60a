"""Excitation trajectories: families (paper's Cartesian MFS, joint-space Fourier), constraints
and the excitation objective (paper eq. 15).

The public names are imported lazily so that ``import ident.excitation`` stays cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "ConstraintViolations",
    "ExcitationFamily",
    "ExcitationObjective",
    "JointFourierFamily",
    "JointLimits",
    "ObjectiveDetails",
    "PaperArmFamily",
    "PaperWristFamily",
    "TrajectoryBatch",
]

_LAZY = {
    "ConstraintViolations": "ident.excitation.family",
    "ExcitationFamily": "ident.excitation.family",
    "TrajectoryBatch": "ident.excitation.family",
    "JointLimits": "ident.excitation.constraints",
    "JointFourierFamily": "ident.excitation.fourier",
    "ExcitationObjective": "ident.excitation.objective",
    "ObjectiveDetails": "ident.excitation.objective",
    "PaperArmFamily": "ident.excitation.mfs",
    "PaperWristFamily": "ident.excitation.wrist",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'ident.excitation' has no attribute {name!r}")
