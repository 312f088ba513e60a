"""The exports of one run: ``controller.export`` applied to the run's certified trajectory.

Called after the run's data are saved (``trajectory.csv`` is then on disk), never for a run
without a trajectory the dense safety check certified (:class:`ident.run.safety_check.
ExecutablePlan` ``usable``): an unsafe run exports nothing, and says so.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ident.errors import ConfigError
from ident.run.exports.common import ExportError, target_from_urdf
from ident.run.exports.registry import (
    EXPORT_FOLDER,
    ExportOutcome,
    check_export_robot,
    export_trajectory,
)

__all__ = ["check_run_exports", "export_run"]


def check_run_exports(config: Any, robot: Any, source: str | Path) -> None:
    """Refuse, before the run folder exists, exports whose controller cannot drive ``robot``.

    Raises
    ------
    ConfigError
        ``<source>: controller.export: <export>: <why>`` (e.g. ``franka`` for a 6-joint arm).
    """
    names = list(config.controller.export)
    if not names:
        return
    try:
        target = target_from_urdf(str(robot.urdf_text))
        check_export_robot(names, tuple(robot.joint_names), target)
    except (ConfigError, ExportError) as e:
        raise ConfigError(f"{source}: {e}") from e


def export_run(result: Any, run_dir: str | Path) -> ExportOutcome | None:
    """Write the exports the run's config asks for into ``<run_dir>/exports/``.

    Parameters
    ----------
    result :
        A :class:`ident.run.pipeline.RunResult` (its ``config.controller.export``,
        ``executable`` plan, ``urdf_text`` and ``ddq_limits`` are used).
    run_dir :
        The run folder.

    Returns
    -------
    :
        None when the config asks for no export; else what was written and what was refused
        (every export is refused when the run has no certified trajectory).
    """
    names = list(result.config.controller.export)
    if not names:
        return None
    plan = getattr(result, "executable", None)
    if plan is None or not plan.usable or plan.trajectory is None:
        why = "the run has no trajectory certified safe; nothing is exported"
        return ExportOutcome(refused={name: f"{name}: {why}" for name in names})
    trajectory = plan.trajectory
    ddq = getattr(result, "ddq_limits", None)
    ddq_max = None
    if ddq is not None and np.shape(ddq) == (len(trajectory.joint_names),):
        ddq_max = np.asarray(ddq, dtype=float)
    target = target_from_urdf(result.urdf_text, ddq_max)
    return export_trajectory(names, trajectory, target, Path(run_dir) / EXPORT_FOLDER)
