"""The exports of one run: ``controller.export`` applied to the run's certified trajectory.

Called after the run's data are saved (``trajectory.csv`` is then on disk), never for a run
without a trajectory the dense safety check certified (:class:`ident.run.safety_check.
ExecutablePlan` ``usable``): an unsafe run exports nothing, and says so.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ident.errors import ConfigError
from ident.excitation.constraints import JointLimits, tighten_limits
from ident.run.exports import registry
from ident.run.exports.common import ExportError, target_from_urdf
from ident.run.exports.registry import (
    EXPORT_FOLDER,
    ExportOutcome,
    check_export_names,
    check_export_robot,
    export_trajectory,
)
from ident.trajectory import JointTrajectory

__all__ = ["check_export_targets", "check_run_exports", "effective_limits", "export_run"]


def effective_limits(
    names: Sequence[str], robot: Any, source: str | Path = "config"
) -> tuple[JointLimits, tuple[str, ...]]:
    """The joint limits a run designs and checks within, and what each export target tightened.

    The robot's limits (the URDF's, tightened by ``robot.velocity_limits`` and
    ``robot.acceleration_limits``) and, element-wise, those of every export in ``names`` whose
    controller publishes its own (:attr:`Exporter.limits`: ``franka``, ``urscript``):
    :func:`ident.excitation.constraints.tighten_limits` applied once per target.

    Returns
    -------
    :
        The effective limits (shape (nq,) each) and one note per target and kind of limit it
        tightened, ``"franka: velocity limits [rad/s] panda_joint1 2.175 -> 2.09901, ..."``.

    Raises
    ------
    ConfigError
        ``<source>: controller.export: <export>: <why>`` for a robot a controller cannot drive.
    """
    limits = JointLimits.from_robot(robot)
    names = list(names)
    if not names:
        return limits, ()
    notes: list[str] = []
    try:
        target = target_from_urdf(str(robot.urdf_text), limits.ddq_max)
        for name in check_export_names(names):
            published = registry.EXPORTERS[name].limits
            if published is None:
                continue
            limits, changed = tighten_limits(
                limits, published(tuple(limits.joint_names), target), name
            )
            notes.extend(changed)
    except (ConfigError, ExportError) as e:
        message = str(e) if str(e).startswith("controller.export") else f"controller.export: {e}"
        raise ConfigError(f"{source}: {message}") from e
    return limits, tuple(notes)


def check_export_targets(
    names: Sequence[str], trajectory: JointTrajectory, urdf_text: str, ddq_max: Any
) -> str | None:
    """Check ``trajectory`` against the limits of each export target that publishes its own.

    For every export in ``names`` with :attr:`~ident.run.exports.registry.Exporter.limits`
    (``franka``, ``urscript``), the same ``prepare`` :func:`~ident.run.exports.registry.
    export_trajectory` runs before writing (Franka: libfranka's ``limitRate`` on the 1 kHz
    commands, jerk included; UR: the model's speeds and accelerations at 500 Hz), so that a
    trajectory the run certifies is one these controllers run unchanged. Nothing is written.

    Returns
    -------
    :
        The first refusal (``"franka: ..."``), or None.
    """
    if not names:
        return None
    target = target_from_urdf(urdf_text, None if ddq_max is None else np.asarray(ddq_max))
    for name in check_export_names(names):
        exporter = registry.EXPORTERS[name]
        if exporter.limits is None:
            continue
        try:
            exporter.prepare(trajectory, target)
        except ExportError as e:
            return str(e) if str(e).startswith(f"{name}:") else f"{name}: {e}"
    return None


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
    outcome = export_trajectory(names, trajectory, target, Path(run_dir) / EXPORT_FOLDER)
    # self-collision off: said with each file written
    return dataclasses.replace(outcome, unchecked=plan.report.unchecked())
