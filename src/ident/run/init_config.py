"""``ident init``: a commented run config for a URDF, derived from the robot itself.

From the URDF alone it chooses

- **the chain**: the robot selection's rules (``robot.tip_link`` / ``robot.base_link``, or
  :func:`ident.model.suggested_locks` for a branched file), plus a lock for a moving joint
  named like a gripper (``gripper``, ``finger``, ``hand``) at the tip; every lock is stated
  with its reason;
- **limits**: the URDF's velocity limits; acceleration limits from the URDF's
  ``<limit acceleration=...>`` where present, otherwise the rule of thumb
  ``ddq_max = ACCELERATION_PER_VELOCITY * dq_max`` (full speed in a third of a second);
- **the excitation**: the joint-space Fourier series of ``configs/ur5.yaml`` (4 harmonics,
  10 s period) whose coefficient bound keeps *every* design of the search box within
  ``VELOCITY_MARGIN`` of each joint's velocity limit and within its acceleration limit
  (:func:`ident.excitation.fourier.fourier_bound_factors`), and mean postures in a box around
  a posture that clears the floor and every link pair the most;
- **safety**: the floor under the lowest point of the base's collision geometry (``z = 0``
  for most URDFs) and a clearance of 5 % of the reach
  (between 1 and 3 cm);
- **the measurement**: MuJoCo with friction, rotor inertia and torque noise scaled to each
  joint's effort limit (or, without one, to the gravity torque of the links it carries), each
  marked as a guess to replace with the robot's value;
- **the budget**: the optimizer settings of ``configs/ur5.yaml`` and a minimal ``quick``
  section; the run's wall time is estimated by :func:`ident.run.setup.estimate_run`.

The text is validated by the run config loader and :func:`ident.run.setup.prepare_run` before
it is returned; nothing here writes a file.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pinocchio as pin
import yaml

from ident.config import validate_config
from ident.errors import ConfigError, IdentError
from ident.excitation.fourier import fourier_bound_factors
from ident.excitation.safety import build_safety_model
from ident.inputs import read_urdf_text
from ident.model.robot import Robot
from ident.model.selection import RobotSelection, load_robot
from ident.robot.urdf_load import (
    build_model,
    chain_locks,
    continuous_as_revolute,
    parse_xml,
    suggested_locks,
)
from ident.run.config import RunConfig
from ident.run.setup import estimate_run, prepare_run

__all__ = [
    "ACCELERATION_PER_VELOCITY",
    "N_HARMONICS",
    "PERIOD_S",
    "VELOCITY_MARGIN",
    "InitResult",
    "init_config",
]

N_HARMONICS = 4
PERIOD_S = 10.0
#: Share of each velocity limit the excitation may reach (a margin for tracking errors).
VELOCITY_MARGIN = 0.8
#: Rule of thumb for missing acceleration limits: ddq_max = this * dq_max [1/s].
ACCELERATION_PER_VELOCITY = 3.0
#: Velocity assumed for a joint whose URDF has no velocity limit [rad/s].
DEFAULT_VELOCITY = 1.0
#: Guessed measurement settings per N*m of a joint's effort limit.
VISCOUS_PER_EFFORT = 0.02  # N*m*s/rad per N*m (UR5: 3 for 150 N*m)
COULOMB_PER_EFFORT = 0.03  # N*m per N*m
ARMATURE_PER_EFFORT = 0.003  # kg*m^2 per N*m (UR5: 0.5 for 150 N*m)
NOISE_PER_EFFORT = 0.003  # N*m per N*m, at most ...
NOISE_PER_TORQUE = 0.01  # ... and 1 % of the torque the excitation needs at the joint
_GRIPPER = re.compile(r"gripper|finger|hand", re.IGNORECASE)
_N_POSTURES = 300
_Q0_HALF_WIDTH = 0.5  # rad: the mean postures' search box around the chosen posture
_G = 9.81


@dataclass(frozen=True)
class InitResult:
    """A run config written for a robot.

    Attributes
    ----------
    text :
        The commented YAML, validated.
    notes :
        What was chosen and why (the chain, each lock, the guesses), one line each.
    seconds, quick_seconds :
        Estimated wall time of ``ident run`` and ``ident run --quick`` [s].
    """

    text: str
    notes: tuple[str, ...]
    seconds: float
    quick_seconds: float


def _fmt(value: float) -> str:
    return f"{float(value):.3g}"


def _list(values: np.ndarray) -> str:
    return "[" + ", ".join(_fmt(v) for v in values) + "]"


def _choose_locks(
    urdf: Path, base_link: str | None, tip_link: str | None, lock: dict[str, float]
) -> tuple[dict[str, float], list[str]]:
    """Joints to lock (name -> position) and one reason line per lock."""
    where = str(urdf)
    text = read_urdf_text(urdf)
    revolute_text, _ = continuous_as_revolute(parse_xml(text, where), text)
    model = build_model(revolute_text, where)
    reasons: dict[str, str] = {name: "given with --lock" for name in lock}
    if base_link is not None or tip_link is not None:
        for name in chain_locks(model, base_link, tip_link, where):
            reasons.setdefault(name, "outside the chain from the base link to the tip link")
    else:
        for name in suggested_locks(model):
            jid = model.getJointId(name)
            leaf = not any(int(model.parents[k]) == jid for k in range(1, model.njoints))
            reasons.setdefault(
                name,
                "a gripper finger (a single joint at the tip)"
                if leaf
                else "a side branch (the chain follows the deepest branch)",
            )
        # a moving gripper joint at the end of a serial chain: its fingers ride on the last link
        kept = [
            k for k in range(1, model.njoints) if model.names[k] not in reasons and model.nvs[k]
        ]
        for k in reversed(kept):
            name = model.names[k]
            if not _GRIPPER.search(name):
                break
            reasons[name] = "a gripper joint (named so): the fingers ride on the last link"
    values: dict[str, float] = {}
    for name in reasons:
        if name in lock:
            values[name] = float(lock[name])
            continue
        jid = model.getJointId(name)
        idx = model.joints[jid].idx_q
        low, high = model.lowerPositionLimit[idx], model.upperPositionLimit[idx]
        values[name] = float(np.clip(0.0, low, high)) if high > low else 0.0
    lines = [f"{name} locked at {_fmt(values[name])}: {why}" for name, why in reasons.items()]
    return values, lines


def _urdf_acceleration_limits(urdf_text: str, joint_names: tuple[str, ...]) -> np.ndarray:
    """``<limit acceleration=...>`` per joint (NaN where absent), shape (n_joints,)."""
    root = ET.fromstring(urdf_text)
    found: dict[str, float] = {}
    for joint in root.iter("joint"):
        limit = joint.find("limit")
        if limit is not None and limit.get("acceleration") is not None:
            try:
                found[joint.get("name", "")] = float(limit.get("acceleration", "nan"))
            except ValueError:
                continue
    out = np.array([found.get(n, np.nan) for n in joint_names])
    return np.where(np.isfinite(out) & (out > 0), out, np.nan)


def _package_dirs(urdf: Path, text: str, given: list[Path]) -> list[Path]:
    """``package://NAME/...`` resolved: the given folders, else the nearest ancestor of the
    URDF's folder that holds a folder ``NAME``."""
    if given:
        return [p.resolve() for p in given]
    names = sorted(set(re.findall(r"package://([^/\"']+)/", text)))
    found: list[Path] = []
    for name in names:
        for parent in urdf.resolve().parents:
            if (parent / name).is_dir():
                if parent not in found:
                    found.append(parent)
                break
        else:
            raise ConfigError(
                f"{urdf}: the meshes of package://{name}/ are not in any folder above the URDF; "
                "give the folder that contains it with --package-dir DIR."
            )
    return found


def _effort_scale(robot: Robot) -> np.ndarray:
    """Per joint: the URDF effort limit, or twice the largest static gravity torque [N*m]."""
    effort = np.asarray(robot.model.effortLimit, dtype=float)
    model = robot.model
    data = model.createData()
    rng = np.random.default_rng(0)
    lower = np.where(np.isfinite(robot.q_lower), robot.q_lower, -np.pi)
    upper = np.where(np.isfinite(robot.q_upper), robot.q_upper, np.pi)
    gravity = np.zeros(model.nv)
    for q in rng.uniform(lower, upper, (50, model.nq)):
        gravity = np.maximum(gravity, np.abs(pin.computeGeneralizedGravity(model, data, q)))
    fallback = np.maximum(2.0 * gravity, 1.0)
    return np.where(np.isfinite(effort) & (effort > 0), effort, fallback)


def _torque_scale(
    robot: Robot,
    home: np.ndarray,
    dq_peak: np.ndarray,
    ddq_peak: np.ndarray,
    armature: np.ndarray,
) -> np.ndarray:
    """Per joint: the 95th percentile of |tau| over seeded states of the excitation's range
    (within 0.5 rad of ``home``, speeds and accelerations up to their peaks) [N*m], rigid
    bodies (Pinocchio's RNEA) plus the rotor inertia."""
    rng = np.random.default_rng(0)
    n = 200
    lower = np.maximum(home - _Q0_HALF_WIDTH, robot.q_lower)
    upper = np.minimum(home + _Q0_HALF_WIDTH, robot.q_upper)
    q = rng.uniform(lower, upper, (n, robot.nq))
    dq = rng.uniform(-1.0, 1.0, (n, robot.nv)) * dq_peak
    ddq = rng.uniform(-1.0, 1.0, (n, robot.nv)) * ddq_peak
    tau = robot.rnea(q, dq, ddq) + armature * ddq
    return np.asarray(np.percentile(np.abs(tau), 95.0, axis=0), dtype=float)


def _reach(robot: Robot, q: np.ndarray) -> float:
    """Largest distance of a joint origin from the base at posture ``q`` [m]."""
    data = robot.model.createData()
    pin.forwardKinematics(robot.model, data, q)
    return float(max(np.linalg.norm(data.oMi[k].translation) for k in range(robot.model.njoints)))


def _base_bottom(robot: Robot) -> float:
    """Lowest point of the collision geometry fixed to the world (the base) [m], in the base
    frame; 0 without such geometry. Its bounding boxes' corners: exact for boxes, a lower
    bound for meshes and round shapes."""
    safety = build_safety_model(
        robot, {"floor": {"enabled": False}}, package_dirs=robot.package_dirs
    )
    model, geometry = safety.model, safety.geometry_model
    data, gdata = model.createData(), pin.GeometryData(geometry)
    reference = np.clip(np.zeros(model.nq), model.lowerPositionLimit, model.upperPositionLimit)
    pin.updateGeometryPlacements(model, data, geometry, gdata, reference)
    lowest = 0.0
    for k, obj in enumerate(geometry.geometryObjects):
        if obj.parentJoint != 0:
            continue
        obj.geometry.computeLocalAABB()
        box = obj.geometry.aabb_local
        corners = np.array(
            [
                [x, y, z]
                for x in (box.min_[0], box.max_[0])
                for y in (box.min_[1], box.max_[1])
                for z in (box.min_[2], box.max_[2])
            ]
        )
        placement = gdata.oMg[k]
        z = (corners @ placement.rotation.T + placement.translation)[:, 2].min()
        if np.isfinite(z):
            lowest = min(lowest, float(z))
    return lowest


def _home_posture(robot: Robot, clearance_m: float, floor_z: float) -> tuple[np.ndarray, float]:
    """A posture clear of the floor and of itself: of the reference posture (0 clipped into the
    limits) and seeded random ones, the one whose smallest clearance is largest, preferring
    the reference posture while it keeps three margins. Returns it and its clearance [m]."""
    safety = build_safety_model(
        robot,
        {"clearance_m": clearance_m, "floor": {"enabled": True, "z": floor_z}},
        package_dirs=robot.package_dirs,
    )
    lower = np.where(np.isfinite(robot.q_lower), robot.q_lower, -np.pi)
    upper = np.where(np.isfinite(robot.q_upper), robot.q_upper, np.pi)
    reference = np.clip(np.zeros(robot.nq), lower, upper)
    rng = np.random.default_rng(0)
    # postures near the reference first: a robot's zero is usually a sensible posture
    near = np.clip(reference + rng.uniform(-1.0, 1.0, (_N_POSTURES, robot.nq)), lower, upper)
    postures = np.vstack([reference[None, :], near])
    if safety.n_pairs == 0:
        return reference, np.inf
    worst = safety.clearances(postures).min(axis=1)
    if worst[0] >= 3.0 * clearance_m:
        return reference, float(worst[0])
    best = int(np.argmax(np.minimum(worst, 0.15)))  # beyond 15 cm: the first such posture
    return postures[best], float(worst[best])


def init_config(
    urdf: str | Path,
    output: str | Path,
    *,
    base_link: str | None = None,
    tip_link: str | None = None,
    lock: dict[str, float] | None = None,
    package_dirs: list[Path] | None = None,
) -> InitResult:
    """A validated, commented run config for the robot of ``urdf`` (see the module docstring).

    Parameters
    ----------
    urdf :
        The robot's URDF.
    output :
        Where the config will be written (its paths are made relative to its folder).
    base_link, tip_link, lock :
        The chain, as in the ``robot:`` section; default: the file's serial chain (branches
        and gripper joints locked).
    package_dirs :
        Folders that hold the ``package://`` mesh packages; default: found above the URDF.

    Raises
    ------
    IdentError
        One line naming the problem (file, link, lock, or a config the loader refuses).
    """
    urdf = Path(urdf)
    output = Path(output)
    if not urdf.is_file():
        raise ConfigError(f"{urdf}: URDF file not found; check the path.")
    folder = output.resolve().parent
    text = read_urdf_text(urdf)
    locks, lock_notes = _choose_locks(urdf, base_link, tip_link, dict(lock or {}))
    dirs = _package_dirs(urdf, text, list(package_dirs or []))
    selection = RobotSelection(
        urdf=urdf.resolve(),
        base_link=base_link,
        tip_link=tip_link,
        lock=locks,
        package_dirs=dirs,
    )
    robot = load_robot(selection, source=urdf)
    names = robot.joint_names
    n = robot.nv

    # limits
    dq_urdf = np.asarray(robot.dq_max, dtype=float)
    dq_known = np.isfinite(dq_urdf) & (dq_urdf > 0)
    dq_max = np.where(dq_known, dq_urdf, DEFAULT_VELOCITY)
    ddq_urdf = _urdf_acceleration_limits(text, names)
    ddq_known = np.isfinite(ddq_urdf)
    ddq_max = np.where(ddq_known, ddq_urdf, ACCELERATION_PER_VELOCITY * dq_max)

    # excitation: every design of the box within the margins
    w = 2.0 * np.pi / PERIOD_S
    c_q, c_v, c_a = fourier_bound_factors(N_HARMONICS)
    amplitude = VELOCITY_MARGIN * np.minimum(dq_max / c_v, ddq_max / (w * c_a))
    amplitude = np.floor(amplitude * 1e4) / 1e4  # written with 4 decimals, never rounded up

    # geometry: floor, margin, a posture clear of both
    reference = np.clip(np.zeros(robot.nq), robot.q_lower, robot.q_upper)
    reach = _reach(robot, reference)
    clearance = float(np.clip(0.05 * reach, 0.01, 0.03))
    floor_z = float(np.floor(_base_bottom(robot) * 1e3) / 1e3)  # mm, never above the base
    home, home_clearance = _home_posture(robot, clearance, floor_z)

    effort = _effort_scale(robot)
    effort_known = np.isfinite(robot.model.effortLimit) & (robot.model.effortLimit > 0)
    viscous = VISCOUS_PER_EFFORT * effort
    coulomb = COULOMB_PER_EFFORT * effort
    armature = ARMATURE_PER_EFFORT * effort
    torque = _torque_scale(robot, home, amplitude * c_v, amplitude * c_a * w, armature)
    noise = np.minimum(NOISE_PER_EFFORT * effort, NOISE_PER_TORQUE * torque)
    threshold = np.minimum(0.15, 0.1 * amplitude * c_v)  # rad/s, below the design's speeds

    rel_urdf = Path(os.path.relpath(urdf.resolve(), folder)).as_posix()
    rel_dirs = [Path(os.path.relpath(d, folder)).as_posix() for d in dirs]
    lines: list[str] = []
    add = lines.append
    add(f"# ident run {output.name} -- written by 'ident init {urdf.name}' for {robot.name}:")
    add(f"# the chain {names[0]} .. {names[-1]} ({n} joints), every joint moving in one stage,")
    add("# a joint-space Fourier excitation designed by the optimizer, measured by a closed-loop")
    add("# MuJoCo simulation that writes a controller log, identified from that log.")
    add("# Lines marked 'guess' are rules of thumb: replace them with your robot's values.")
    add("# Units: SI (m, rad, s, N*m) unless a key says otherwise. Paths relative to this file.")
    add("robot:")
    add(f"  urdf: {rel_urdf}")
    if base_link is not None:
        add(f"  base_link: {base_link}")
    if tip_link is not None:
        add(f"  tip_link: {tip_link}")
    if locks:
        add("  lock:                        # joints held fixed [rad or m]")
        for note, (name, value) in zip(lock_notes, locks.items(), strict=True):
            add(f"    {name}: {_fmt(value)}   # {note.split(': ', 1)[1]}")
    if rel_dirs:
        add(f"  package_dirs: [{', '.join(rel_dirs)}]   # the package:// collision meshes")
    if ddq_known.all():
        add(f"  acceleration_limits: {_list(ddq_max)}   # rad/s^2, from the URDF")
    else:
        add(
            f"  acceleration_limits: {_list(ddq_max)}   # rad/s^2; guess: "
            f"{ACCELERATION_PER_VELOCITY:g} x the velocity limit (full speed in "
            f"{1 / ACCELERATION_PER_VELOCITY:.2g} s): replace with your robot's value"
        )
    add("stage: whole                   # every joint moves, every body is unknown")
    add("seed: 0")
    add("")
    add("excitation:")
    add("  family: joint_fourier")
    add("  criterion: paper")
    add(f"  n_samples: 250               # per {PERIOD_S:g} s period")
    add("  options:")
    add(f"    n_harmonics: {N_HARMONICS}")
    add(f"    base_frequency: {w!r}   # rad/s: period {PERIOD_S:g} s")
    velocity_note = (
        "the URDF's velocity limits"
        if dq_known.all()
        else f"the URDF's velocity limits ({DEFAULT_VELOCITY:g} rad/s guessed where it has none)"
    )
    add(
        f"    # rad/s, per joint: every design of the search box keeps within "
        f"{VELOCITY_MARGIN:.0%} of"
    )
    add(f"    # {velocity_note} (|dq| <= {c_v:.3g} x bound at {N_HARMONICS} harmonics) and within")
    add(f"    # the acceleration limits (|ddq| <= {c_a:.3g} x bound x base_frequency)")
    add(f"    amplitude_bound: {_list(amplitude)}")
    add(
        f"  bounds:                      # mean postures within +-{_Q0_HALF_WIDTH:g} rad of a "
        f"posture {home_clearance * 100:.0f} cm"
    )
    add("                               # clear of the floor and of itself [rad]")
    for j, name in enumerate(names):
        low = max(home[j] - _Q0_HALF_WIDTH, robot.q_lower[j])
        high = min(home[j] + _Q0_HALF_WIDTH, robot.q_upper[j])
        if high > low:
            add(f"    q0[{name}]: [{low:.4f}, {high:.4f}]")
    add("")
    add("elites: {n_particles: 10, n_elites: 5, maxiter: 100}")
    add("optimizer: pso                 # the best on arms like this one (docs/optimizers.md)")
    add("emupso: {n_particles: 20, maxiter: 150, n_runs: 1, n_report_elites: 3}")
    add("")
    add("safety:                        # in the optimization and, at 1 kHz, on the trajectory")
    add(
        f"  floor: {{enabled: true, z: {floor_z:.4g}}}   # guess: the robot stands on the floor "
        "under its base's collision geometry"
    )
    add(f"  clearance_m: {clearance:.3g}   # guess: 5 % of the reach {reach:.2f} m (1-3 cm)")
    add("  self_collision: true")
    add("  torque_limits: true")
    add("  check_samples: 50            # samples per period of the optimization's term")
    add("controller: {rate_hz: 1000.0, n_periods: 1}   # trajectory.csv: approach, period, return")
    add("")
    effort_note = (
        "the URDF's effort limits"
        if effort_known.all()
        else "the effort limits (twice the gravity torque where the URDF has none)"
    )
    add("measurement:")
    add("  source: mujoco")
    add("  rate_hz: 1000.0")
    add("  controller: {kind: computed_torque}    # default gains: 100 rad/s, critically damped")
    add(f"  # guesses scaled to {effort_note} {_list(effort)} N*m:")
    add("  # replace each with your robot's value")
    add("  friction:")
    add(f"    viscous: {_list(viscous)}   # guess: N*m*s/rad, {VISCOUS_PER_EFFORT:g} x effort")
    add(f"    coulomb: {_list(coulomb)}   # guess: N*m, {COULOMB_PER_EFFORT:g} x effort")
    add(
        f"  armature: {_list(armature)}   # guess: kg*m^2, rotor inertia, "
        f"{ARMATURE_PER_EFFORT:g} x effort"
    )
    add("  encoder_counts_per_rev: 524288   # guess: 19-bit encoders")
    add(
        f"  torque_noise_std: {_list(noise)}   # guess: N*m, {NOISE_PER_EFFORT:g} x effort, at "
        f"most {NOISE_PER_TORQUE:.0%} of the torque the motion needs {_list(torque)}"
    )
    add("  settle_periods: 1")
    add("  n_periods: 3")
    add("")
    add("identification:                # how the log is identified (an `ident identify` config)")
    add("  preprocess:")
    add("    lowpass: {cutoff_hz: 10.0, order: 4}")
    add("    torque_lowpass: {cutoff_hz: 10.0, order: 4}")
    add("    trim_samples: 500          # 0.5 s at each end: the zero-phase filters' edges")
    add("    decimation: [10]           # 1 kHz -> 100 Hz")
    add("    # rows slower than this are dropped: the filters spread the Coulomb step at a")
    add("    # velocity reversal (0.15 rad/s, or 10 % of the design's largest speed if lower)")
    add(f"    velocity_threshold: {_list(threshold)}   # rad/s")
    add("  model: {viscous: true, coulomb: true, rotor_inertia: true, offset: false}")
    add("  estimation: {method: wls, essential: {enabled: false}}")
    add("  validation: {identify_fraction: 0.7}")
    add("")
    add("quick:                         # --quick: the smallest budget that designs a trajectory")
    add("  n_samples: 100")
    add("  elites: {n_particles: 6, n_elites: 1, maxiter: 40}")
    add("  emupso: {n_particles: 6, maxiter: 4, stagnation: 2, n_runs: 1, n_report_elites: 1}")
    config_text = "\n".join(lines) + "\n"

    seconds, quick_seconds = _validate(config_text, output, urdf.resolve(), dirs)
    notes = [
        f"chain: {names[0]} .. {names[-1]} ({n} joints) of {urdf.name}",
        *[f"lock: {line}" for line in lock_notes],
        "acceleration limits: "
        + ("from the URDF" if ddq_known.all() else f"guess {ACCELERATION_PER_VELOCITY:g} x dq_max")
        + f" {_list(ddq_max)} rad/s^2",
        f"excitation: amplitude_bound {_list(amplitude)} rad/s keeps every design within "
        f"{VELOCITY_MARGIN:.0%} of the velocity limits {_list(dq_max)} rad/s",
        f"safety: floor at z = {floor_z:.4g} m (under the base), clearance {clearance:.3g} m; "
        "mean postures around a posture "
        f"{home_clearance * 100:.0f} cm clear",
        f"measurement: friction, rotor inertia and noise are guesses scaled to {effort_note}",
    ]
    return InitResult(config_text, tuple(notes), seconds, quick_seconds)


def _validate(text: str, output: Path, urdf: Path, dirs: list[Path]) -> tuple[float, float]:
    """Load ``text`` as ``ident run`` will and build the run; the estimated wall times [s].

    The relative paths of the text hold once ``output``'s folder exists; the check uses the
    absolute ones (the folder may not exist yet).
    """
    data = yaml.safe_load(text)
    data["robot"] = {**data["robot"], "urdf": str(urdf), "package_dirs": [str(d) for d in dirs]}
    config = validate_config(RunConfig, data, output)
    config = config.model_copy(update={"name": config.name or output.stem})
    try:
        setup = prepare_run(config, source=output)
    except IdentError as e:
        raise type(e)(f"the written config would not run: {e}") from e
    quick = config.quick_version()
    return (
        float(setup.estimate.seconds),
        float(estimate_run(quick, setup.robot, setup.family).seconds),
    )
