"""The export registry: ``controller.export: [name, ...]`` of a run config names entries here.

An exporter turns the run's executable trajectory (approach, periods, return, already certified
safe by the run) into the files a robot controller runs. It is three functions::

    prepare(trajectory, target) -> ExportSamples   # resample, check the target's rules
    write(samples, folder) -> [Path, ...]          # the files (or folders) it wrote
    read(path) -> ExportSamples                    # one written path, read back

``prepare`` raises :class:`~ident.run.exports.common.ExportError` naming the joint, the
quantity and the time when the controller's own rules are broken; nothing is written then.
:func:`export_trajectory` runs every requested ``prepare`` first, then writes each export that
passed, reads every written path back and compares it with the samples to 1e-9, and with the
plan itself at the times they share; a mismatch removes the files and refuses that export.
Register a new format with :func:`register_exporter`; nothing else needs to know its name::

    import numpy as np
    from ident.run.exports.common import ExportSamples, resample_quintic
    from ident.run.exports.registry import Exporter, register_exporter

    def prepare(trajectory, target):
        s = resample_quintic(trajectory, 250.0)  # a 250 Hz controller, positions only
        return ExportSamples(s.t, s.q, None, None, s.joint_names)

    def write(samples, folder):
        path = folder / "q_250hz.txt"
        np.savetxt(path, samples.q, fmt="%.17g")
        return [path]

    def read(path):
        q = np.loadtxt(path, ndmin=2)
        return ExportSamples(np.arange(len(q)) / 250.0, q, None, None, ("j1", "j2"))

    register_exporter("q250", Exporter(prepare, write, read, "positions at 250 Hz"))

Built in: ``ros2`` (:mod:`~ident.run.exports.ros2`), ``urscript``
(:mod:`~ident.run.exports.urscript`), ``franka`` (:mod:`~ident.run.exports.franka`);
``docs/execute.md`` says how to run each on the robot.
"""

from __future__ import annotations

import difflib
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ident.errors import ConfigError
from ident.excitation.constraints import JointLimits
from ident.run.exports.common import (
    ExportError,
    ExportSamples,
    ExportTarget,
    compare_samples,
    compare_with_plan,
)
from ident.run.exports.franka import (
    accepts_franka,
    franka_limits,
    prepare_franka,
    read_franka,
    write_franka,
)
from ident.run.exports.ros2 import accepts_ros2, prepare_ros2, read_ros2, write_ros2
from ident.run.exports.urscript import (
    accepts_urscript,
    prepare_urscript,
    read_urscript,
    urscript_limits,
    write_urscript,
)
from ident.trajectory import JointTrajectory

__all__ = [
    "EXPORTERS",
    "EXPORT_FOLDER",
    "ExportOutcome",
    "Exporter",
    "check_export_names",
    "check_export_robot",
    "export_trajectory",
    "register_exporter",
]

#: Sub-folder of the run folder that holds the exports.
EXPORT_FOLDER = "exports"


@dataclass(frozen=True)
class Exporter:
    """A registered export format (see the module docstring)."""

    prepare: Callable[[JointTrajectory, ExportTarget], ExportSamples]
    write: Callable[[ExportSamples, Path], list[Path]]
    read: Callable[[Path], ExportSamples]
    description: str = ""
    #: ``accepts(joint_names, target)`` raises ExportError for a robot the format cannot
    #: drive (checked by :func:`check_export_robot` before a run folder exists)
    accepts: Callable[[tuple[str, ...], ExportTarget], Any] | None = None
    #: ``limits(joint_names, target)``: the controller's own joint limits
    #: (:class:`~ident.excitation.constraints.JointLimits`, ``inf`` where it has none); a run
    #: that exports to it designs and checks its trajectory within them
    #: (:func:`ident.run.exports.run_exports.effective_limits`)
    limits: Callable[[tuple[str, ...], ExportTarget], JointLimits] | None = None


EXPORTERS: dict[str, Exporter] = {}


def register_exporter(name: str, exporter: Exporter, *, replace: bool = False) -> None:
    """Make ``controller.export: [name]`` write files with ``exporter``.

    Raises
    ------
    ValueError
        If ``name`` is not an identifier or is taken (``replace=True`` overrides on purpose).
    """
    if not name or not name.replace("_", "").isalnum():
        raise ValueError(f"export name {name!r} must be a non-empty identifier")
    if name in EXPORTERS and not replace:
        raise ValueError(f"export {name!r} is registered already")
    EXPORTERS[name] = exporter


def check_export_names(names: Sequence[str]) -> list[str]:
    """``names`` if every one is registered (duplicates dropped, order kept).

    Raises
    ------
    ConfigError
        One line naming the unknown export, the closest valid name and every valid one.
    """
    for name in names:
        if name not in EXPORTERS:
            close = difflib.get_close_matches(str(name), list(EXPORTERS), n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ConfigError(
                f"controller.export: '{name}' is not a known export; {hint}"
                f"valid: {', '.join(EXPORTERS)}."
            )
    return list(dict.fromkeys(names))


def check_export_robot(
    names: Sequence[str], joint_names: Sequence[str], target: ExportTarget
) -> None:
    """Refuse, before anything runs, an export whose controller cannot drive this robot.

    Raises
    ------
    ConfigError
        ``controller.export: <why>`` for the first export that refuses the robot.
    """
    for name in check_export_names(names):
        accepts = EXPORTERS[name].accepts
        if accepts is None:
            continue
        try:
            accepts(tuple(joint_names), target)
        except ExportError as e:
            raise ConfigError(f"controller.export: {_named(name, str(e))}") from e


@dataclass(frozen=True)
class ExportOutcome:
    """What :func:`export_trajectory` did.

    Attributes
    ----------
    written :
        Export name -> the paths it wrote, each re-read and equal to the samples.
    refused :
        Export name -> why nothing was written (the target's rule it breaks, or a re-read
        mismatch).
    unchecked :
        The checks the trajectory's certificate left out (``"self-collision not checked
        (...)"``), said on every written export's line.
    """

    written: dict[str, list[Path]] = field(default_factory=dict)
    refused: dict[str, str] = field(default_factory=dict)
    unchecked: tuple[str, ...] = ()

    def lines(self, relative_to: Path | None = None) -> list[str]:
        """One line per export: its files, or why it was refused."""

        def show(p: Path) -> str:
            return str(p.relative_to(relative_to)) if relative_to is not None else str(p)

        caveat = "".join(f"; {c}" for c in self.unchecked)
        out = [
            f"{n}: {', '.join(show(p) for p in paths)}{caveat}" for n, paths in self.written.items()
        ]
        out += [f"REFUSED {why}" for why in self.refused.values()]
        return out


def _named(name: str, message: str) -> str:
    """``message`` starting with ``name: `` (every refusal names its export)."""
    return message if message.startswith(f"{name}:") else f"{name}: {message}"


def export_trajectory(
    names: Sequence[str], trajectory: JointTrajectory, target: ExportTarget, folder: Path
) -> ExportOutcome:
    """Check every requested export, then write, re-read and compare the ones that pass.

    Parameters
    ----------
    names :
        Registered export names (``controller.export``).
    trajectory :
        The run's executable trajectory, already certified safe by the run.
    target :
        The robot (URDF joints, limits).
    folder :
        Where to write (created when something is written).

    Returns
    -------
    :
        Written paths and refusals per export.
    """
    outcome = ExportOutcome()
    prepared: dict[str, ExportSamples] = {}
    for name in check_export_names(names):
        try:
            prepared[name] = EXPORTERS[name].prepare(trajectory, target)
        except ExportError as e:
            outcome.refused[name] = _named(name, str(e))
    for name, samples in prepared.items():
        folder.mkdir(parents=True, exist_ok=True)
        paths = EXPORTERS[name].write(samples, folder)
        try:
            for path in paths:
                reread = EXPORTERS[name].read(path)
                compare_samples(samples, reread, str(path))
                compare_with_plan(reread, trajectory, str(path))
        except (ExportError, OSError, ValueError) as e:
            for path in paths:
                if path.is_dir():
                    shutil.rmtree(path, ignore_errors=True)
                else:
                    path.unlink(missing_ok=True)
            outcome.refused[name] = f"{name}: the written file does not read back as the plan: {e}"
            continue
        outcome.written[name] = paths
    return outcome


register_exporter(
    "ros2",
    Exporter(
        prepare_ros2,
        write_ros2,
        read_ros2,
        "trajectory_msgs/msg/JointTrajectory as YAML and as a rosbag2 (MCAP) folder",
        accepts_ros2,
    ),
)
register_exporter(
    "urscript",
    Exporter(
        prepare_urscript,
        write_urscript,
        read_urscript,
        "URScript, servoj at 500 Hz",
        accepts_urscript,
        urscript_limits,
    ),
)
register_exporter(
    "franka",
    Exporter(
        prepare_franka,
        write_franka,
        read_franka,
        "libfranka joint positions at 1 kHz (CSV)",
        accepts_franka,
        franka_limits,
    ),
)
