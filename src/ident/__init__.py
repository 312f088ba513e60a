"""ident: dynamic parameter identification of serial robot arms.

The library API, one name per step of the workflow (the heavy parts, Pinocchio, numba, MuJoCo,
are imported on first use, so ``import ident`` is cheap)::

    import ident

    robot = ident.load_robot(ident.RobotSelection(urdf="robot/urdf/ur5.urdf"))
    stage = ident.select_stage(robot, "whole")
    setup = ident.load_run("configs/ur5.yaml")        # a run config, checked
    result = ident.run_pipeline(setup)                 # design, measure, identify
    identified = ident.identify_config(ident.load_identify_config("configs/tx40.yaml"))

``ident.identify_config`` reads the log a config names and identifies it;
``ident.identify_measurements`` identifies measurements already in memory (a
:class:`~ident.measure.logs.RobotLog`): the one identification every command runs.
``ident.identify`` is the sub-package, not a function. The stable API is this module's
``__all__`` and the registries (docs/api.md); everything else is internal.

Extension points are registries: :func:`register_family` (excitation families),
:func:`register_estimator` (estimators), ``ident.optim.minimize`` (optimizers).
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = [
    "Robot",
    "RobotSelection",
    "__version__",
    "identify_config",
    "identify_measurements",
    "least_squares",
    "load_identify_config",
    "load_robot",
    "load_run",
    "minimize",
    "register_estimator",
    "register_family",
    "run_pipeline",
    "select_stage",
]

__version__ = "0.1.0"

_LAZY = {
    "Robot": "ident.model",
    "RobotSelection": "ident.model.selection",
    "load_robot": "ident.model.selection",
    "select_stage": "ident.dynamics.stage",
    "register_family": "ident.excitation.registry",
    "minimize": "ident.optim",
    "register_estimator": "ident.identify.estimators",
    "least_squares": "ident.identify.estimation.estimate",
    "load_identify_config": "ident.identify.config",
    "identify_config": "ident.identify.pipeline.real",
    "identify_measurements": "ident.identify.pipeline.core",
    "load_run": "ident.run.setup",
    "run_pipeline": "ident.run.pipeline",
}


#: Public names that differ from the name in their module.
_RENAMED = {"identify_config": "identify"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), _RENAMED.get(name, name))
    if name == "identify":  # the sub-package, whether or not it was imported already
        return importlib.import_module("ident.identify")
    raise AttributeError(f"module 'ident' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
