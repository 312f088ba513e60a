"""``ident init --servo``: an identify config for position servos that log no torque.

Arms of low-cost bus servos (SO-100/SO-101, Koch) record LeRobot datasets: the measured and the
commanded positions in servo ticks, no torque. The config :func:`init_servo_config` writes reads
such a dataset (``format: lerobot``; ``observation.state`` and ``action``; ``unit: ticks``,
4096 ticks per turn centred on 2048, a Feetech STS3215's, marked as a guess) and identifies
through the servos' law (``actuator: {kind: position}``: the scale from the URDF's gravity
load, the delay scanned over 0..10 ms, the samples near the URDF's effort limits left out). With a
dataset (``log``): its ``fps`` sets the filters, the decimation and the trimmed edges, and
its motors the URDF does not move (a gripper) are excluded by name. The text is validated by
the identify config loader before it is returned; nothing here writes a file.
"""

from __future__ import annotations

import json
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ident.config import read_text_input, validate_config
from ident.errors import ConfigError, DataError, IdentError
from ident.identify.actuators.servo_fit import MIN_GRAVITY_SHARE
from ident.identify.config import IdentifyConfig, load_identify_config
from ident.measure.lerobot_dataset import ACTION, STATE
from ident.measure.readers.lerobot_layout import INFO_PATH
from ident.run.init_config import select_robot
from ident.run.init_robot import effort_scale, gravity_torques

__all__ = ["COUNTS_PER_REV", "ZERO_TICK", "ServoInit", "init_servo_config", "unloaded_joints"]

COUNTS_PER_REV, ZERO_TICK = 4096, 2048  # guess: Feetech STS3215 (SO-100/SO-101)
DEFAULT_FPS = 30.0  # LeRobot's usual recording rate, without a dataset
MAX_DELAY_S = 0.01  # the command delays scanned [s]
LOWPASS_HZ = 8.0  # keeps 4096-tick steps out of the accelerations (at most fps / 5)
ROWS_HZ = 100.0  # the identification's row rate after decimation
TRIM_S = 0.2  # filter edges cut at each episode's ends [s]
VELOCITY_THRESHOLD = 0.1  # rad/s: slower rows dropped (a servo's friction sticks there)


@dataclass(frozen=True)
class ServoInit:
    """The identify config written: its commented YAML (validated) and one note per choice."""

    text: str
    notes: tuple[str, ...]


def _dataset_info(log: Path) -> tuple[float, list[str]]:
    """The dataset's fps and the motor names of ``observation.state`` ([] when unnamed)."""
    info_path = log / INFO_PATH
    try:
        info = json.loads(read_text_input(info_path, what="dataset info", max_bytes=4 << 20))
        fps = float(info["fps"])
        names = info["features"][STATE].get("names") or []
    except (ValueError, KeyError, TypeError, AttributeError, ConfigError) as e:
        raise DataError(
            f"{info_path}: not a LeRobot dataset's info ({e}); give the dataset folder "
            "(meta/info.json and data/ inside) with --log."
        ) from e
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    names = [str(n).removesuffix(".pos") for n in names] if isinstance(names, list) else []
    return fps, names


def _sections(
    robot: Any, rel_log: str, fps: float, exclude: list[str], forcerange: np.ndarray
) -> list[str]:
    """The ``log:``, ``actuator:``, ``preprocess:`` and model lines."""
    n = robot.nv
    step = max(1, int(round(fps / ROWS_HZ)))
    cutoff = min(LOWPASS_HZ, fps / 5.0)
    position = f"{{columns: [{STATE}]" + (f", exclude: [{', '.join(exclude)}]" if exclude else "")
    ranges = "[" + ", ".join(f"{f:.3g}" for f in forcerange) + "]"
    return [
        "log:",
        f"  path: {rel_log}   # the dataset folder (meta/info.json, data/)",
        "  format: lerobot",
        f"  position: {position},",
        f"             unit: ticks, counts_per_rev: {COUNTS_PER_REV}, zero_tick: {ZERO_TICK}}}"
        "   # guess: STS3215",
        f"  command: {{columns: [{ACTION}]}}   # the commanded positions, converted as position",
        "actuator:",
        "  kind: position                 # tau = kp (q_cmd(t - d) - q) - kd dq, no torque logged",
        f"  forcerange: {ranges}   # N*m, the URDF's effort limits: saturated samples left out",
        f"  max_delay_s: {MAX_DELAY_S:g}              # the command's delay scanned over 0..10 ms",
        *_equal_kp_lines(robot),
        "  # with the servos' gain known (their P coefficient), give it: kp: [...] (N*m/rad,",
        "  # one or one per joint), and the delay: delay: 0.004 (s). The delay and the gains",
        "  # need an excitation with a few Hz in it (the delay trades with kd otherwise)",
        "preprocess:",
        f"  lowpass: {{cutoff_hz: {cutoff:g}, order: 4}}",
        f"  trim_samples: {int(round(TRIM_S * fps))}",
        *([f"  decimation: [{step}]"] if step > 1 else []),
        f"  velocity_threshold: [{', '.join([f'{VELOCITY_THRESHOLD:g}'] * n)}]   # rad/s",
        "model: {viscous: true, coulomb: true, rotor_inertia: true, offset: false}",
        "estimation: {method: wls, essential: {enabled: false}}",
        "validation: {identify_fraction: 0.7}",
    ]


def unloaded_joints(robot: Any) -> list[str]:
    """The joints the URDF's gravity barely loads: rms gravity torque over seeded postures
    (:func:`gravity_torques`) below :data:`MIN_GRAVITY_SHARE` of the most loaded joint's, the
    rule by which the servo fit calls a gain not tied to the gravity scale (a pan, a wrist
    roll); [] when gravity loads none (an arm moving about vertical axes only)."""
    load = np.sqrt(np.mean(gravity_torques(robot) ** 2, axis=0))
    top = float(np.max(load)) if load.size else 0.0
    if top <= 0.0:
        return []
    return [
        name for name, g in zip(robot.joint_names, load, strict=True) if g < MIN_GRAVITY_SHARE * top
    ]


def _equal_kp_lines(robot: Any) -> list[str]:
    """``actuator.equal_kp``: with joints gravity does not load beside loaded ones, every
    joint in one group (a guess: one P setting on every servo, as LeRobot's SO-100/SO-101
    followers write it); otherwise a comment (nothing to tie, or no gravity scale at all)."""
    names = ", ".join(robot.joint_names)
    unloaded = unloaded_joints(robot)
    if not unloaded or len(unloaded) == robot.nv:
        return [
            "  # the scale from the URDF's gravity load; servos of one P setting share a gain:",
            f"  # equal_kp: [[{names}]] ties joints gravity does not load to it",
        ]
    return [
        f"  # the scale from the URDF's gravity load, which {', '.join(unloaded)} barely",
        "  # carry: their gains are tied to a loaded joint's. Guess: one P setting on every",
        "  # servo (LeRobot's default); servos of other settings go in groups of their own",
        f"  equal_kp: [[{names}]]",
    ]


def init_servo_config(urdf: str | Path, output: str | Path, log: Path | None) -> ServoInit:
    """A validated, commented identify config for the servos of ``urdf`` reading the LeRobot
    dataset ``log`` (None: a placeholder path, the config is then checked without it).

    Raises
    ------
    IdentError
        One line: the URDF, the dataset's info or the written config refused.
    """
    urdf, output = Path(urdf), Path(output)
    selection, robot, _, lock_notes = select_robot(urdf, None, None, {}, [])
    fps, motors = _dataset_info(log) if log is not None else (DEFAULT_FPS, [])
    exclude = [m for m in motors if m not in robot.joint_names]
    folder = output.resolve().parent
    rel_urdf = Path(os.path.relpath(urdf.resolve(), folder)).as_posix()
    rel_log = Path(os.path.relpath(log.resolve(), folder)).as_posix() if log else "DATASET"
    lines = [
        f"# ident identify {output.name} -- written by 'ident init {urdf.name} --servo':",
        f"# {robot.name}'s position servos identified from a LeRobot dataset ({fps:g} fps),",
        "# no torque. Lines marked 'guess' are rules of thumb: check them.",
        f"name: {output.stem}",
        f"robot: {{urdf: {rel_urdf}"
        + (f", lock: {dict(selection.lock)}" if selection.lock else "")
        + "}",
        *_sections(robot, rel_log, fps, exclude, effort_scale(robot)),
    ]
    text = "\n".join(lines) + "\n"
    _validate(text, output, urdf, log)
    notes = [f"servo mode: {robot.nv} joints, {fps:g} fps", *lock_notes]
    notes += [f"excluded: {m} (a motor the URDF does not move)" for m in exclude]
    if log is None:
        notes.append("log.path: DATASET is a placeholder: set the dataset folder")
    return ServoInit(text, tuple(notes))


def _validate(text: str, output: Path, urdf: Path, log: Path | None) -> None:
    """Load ``text`` as ``ident identify`` will, its paths made absolute (a copy in a temporary
    folder: the loader resolves paths against the file's folder); without a dataset, the
    schema only."""
    data = yaml.safe_load(text)
    data["robot"]["urdf"] = str(urdf.resolve())
    if log is None:
        validate_config(IdentifyConfig, data, output)
        return
    data["log"]["path"] = str(log.resolve())
    with tempfile.TemporaryDirectory() as tmp:
        probe = Path(tmp) / output.name
        probe.write_text(yaml.safe_dump(data), encoding="utf-8")
        try:
            load_identify_config(probe)
        except IdentError as e:
            raise type(e)(
                f"the written config would not load: {e}".replace(str(probe), str(output))
            ) from e
