"""Excitation trajectories: families (paper's Cartesian MFS, joint-space Fourier), constraints
(limits, collisions, floor, obstacles, torques), the excitation objective (paper eq. 15), the
dense safety check and the controller's trajectory.

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
    "SafetyConfig",
    "SafetyModel",
    "SafetyReport",
    "TrajectoryBatch",
    "build_safety_model",
    "check_trajectory",
    "dense_family_states",
    "executable_trajectory",
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
    "SafetyConfig": "ident.excitation.safety",
    "SafetyModel": "ident.excitation.safety",
    "build_safety_model": "ident.excitation.safety",
    "SafetyReport": "ident.excitation.check",
    "check_trajectory": "ident.excitation.check",
    "dense_family_states": "ident.excitation.check",
    "executable_trajectory": "ident.excitation.executable",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'ident.excitation' has no attribute {name!r}")
