"""Everything a run needs before it starts, built and checked before any run folder exists.

:func:`prepare_run` loads the robot selection, chooses the stage, builds the excitation family
from the registry with its options and search box, and checks the measurement settings against
the robot. Whatever is wrong in a config is found here, in a fraction of a second, so ``ident
run`` fails with one error line and leaves nothing behind.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.dynamics.stage import Stage, select_stage
from ident.errors import ConfigError, IdentError, ModelError
from ident.excitation.registry import build_family
from ident.excitation.safety import SafetyConfig, SafetyModel, build_safety_model
from ident.inputs import JobEstimate, check_job
from ident.measure.mujoco_config import check_joint_counts
from ident.measure.mujoco_model import inertia_problem, world_fixed_inertia_note
from ident.model import Robot
from ident.model.selection import load_robot, set_robot_limits
from ident.robot.mimic import reject_coupled_chain
from ident.run.config import RunConfig, load_run_config
from ident.run.exports.run_exports import effective_limits

__all__ = [
    "RunSetup",
    "estimate_run",
    "load_run",
    "make_family",
    "prepare_run",
    "simulation_notes",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class RunSetup:
    """A checked run: its config, robot, stage and excitation family.

    Attributes
    ----------
    config :
        The run config (paths resolved).
    robot :
        The selected robot.
    stage :
        The stage to identify.
    family :
        The excitation family, with ``excitation.bounds`` applied to its ``bounds``.
    safety :
        The collision, floor, obstacle and torque model (the config's ``safety`` section, or
        the defaults), which checks every reported trajectory.
    estimate :
        Rough memory and time of the run (:func:`estimate_run`), checked against the ceilings.
    limit_notes :
        One line per joint limit an export target tightened (``controller.export``; see
        :func:`ident.run.exports.run_exports.effective_limits`); the robot carries the
        tightened limits.
    simulation_notes :
        What the MuJoCo simulation leaves out of the URDF and why (the inertials MuJoCo refuses
        of links fixed to the world: :func:`~ident.measure.mujoco_model.world_fixed_inertia_note`);
        empty for other sources.
    """

    config: RunConfig
    robot: Robot
    stage: Stage
    family: Any
    safety: SafetyModel
    estimate: JobEstimate
    limit_notes: tuple[str, ...] = ()
    simulation_notes: tuple[str, ...] = ()

    @property
    def bounds(self) -> FloatArray:
        """Search box of the design variables, shape (n_vars, 2)."""
        return np.asarray(self.family.bounds, dtype=float)


def prepare_run(config: RunConfig, source: str | Path = "config") -> RunSetup:
    """Build and check everything of a run config (see the module docstring).

    Raises
    ------
    IdentError
        One line naming ``source``, the key and the fix: robot (file, chain, inertials),
        stage, family and its options, ``excitation.bounds`` names, measurement settings.
    """
    try:
        robot = load_robot(config.robot, source=source)
        reject_coupled_chain(robot.model, "a run (its identification)", str(source))
        # the limits the design and the dense check keep: the robot's, tightened by those of
        # each export target (libfranka, the UR model), set on the robot where all read them
        limits, limit_notes = effective_limits(config.controller.export, robot, source)
        set_robot_limits(robot, limits)
        spec = config.stage if isinstance(config.stage, str) else config.stage.model_dump()
        stage = select_stage(robot, spec)
        family = make_family(config, robot, stage)
        _check_measurement(config, robot, stage)
        _check_sampling(config, family)
        _check_controller(config, robot)
        safety = build_safety_model(
            robot,
            config.safety or SafetyConfig(),
            package_dirs=robot.package_dirs,
            home_q=config.controller.home,
        )
        estimate = check_job(estimate_run(config, robot, family, safety))
    except IdentError as e:
        message = str(e)
        if not message.startswith(str(source)):
            message = f"{source}: {message}"
        raise type(e)(message) from e
    return RunSetup(
        config=config,
        robot=robot,
        stage=stage,
        family=family,
        safety=safety,
        estimate=estimate,
        limit_notes=limit_notes,
        simulation_notes=simulation_notes(config, robot),
    )


# Cost model of estimate_run (measured on 2 cores: the paper's wrist run, 3100 evaluations of
# 500 samples of 6 joints in about 8 s; the MuJoCo measurement at 40 us per 1 kHz step; the
# identification of a log at about 30 us per sample of 7 joints). An order of magnitude.
_SECONDS_PER_SAMPLE_JOINT2 = 5e-6 / 36.0
_SECONDS_PER_SIMULATED_STEP = 40e-6
_SECONDS_PER_LOG_SAMPLE = 30e-6
# the dense check's CPU per posture over the one the safety model timed at random postures:
# a designed trajectory keeps its meshes farther apart (SO-101 --quick: 300 s measured,
# 1160 s from random postures); the approach and return are included
_CERTIFICATE_SHARE = 0.25
# of the exact mesh distances the safety model timed at random postures where hulls are within
# the margin ("near": seconds_per_posture less the hulls'), the share a designed trajectory
# needs: the design keeps its meshes apart. SO-101 --quick (meshes of 100k triangles, 410
# designs): near 38.5 of its 40.6 ms per posture, 0.25 of it estimated 193 s, the profiled
# dense check spent about 26 s (CPU) on the hulls, 94 s making each pair's smallest value
# exact (the next term) and under a second on near values; its estimate was 2.2x the run's CPU
_NEAR_SHARE = 0.05
# the share of the samples at which the dense check measures a mesh pair to make its smallest
# value exact (its hulls' distance is below that value), at the CPU of every mesh pair at one
# posture: Z1 --quick, 4362 exact distances over 24 mesh pairs and 11001 samples (1.7 %; one
# pair whose distance barely changes, a link turning about its own axis, 21 %), 39 of its 44 s
# of CPU; 0.02 made SO-101's --quick (meshes of 100k triangles, hulls close to them) 2.5x its
# CPU, 0.01 keeps both within 2x (Z1 0.57-0.86, SO-101 about 2 with a loaded machine's timing)
_SMALLEST_SHARE = 0.01
# the objective's cheap clearance term per design over the hulls' CPU timed per posture: it is
# vectorized over the swarm, measures coal's pairs only where their bounding spheres are within
# the margin and stops measuring a pair once no posture left can be closer
# (SafetyModel.fast_min_clearances). Objective CPU per design on 20 random designs of the
# configs ident init writes, median of 3 rounds (loaded machine): UR10 6.3 ms, Kinova 6.4, Z1
# 3.1, Baxter 23.7, SO-101 8.4, Panda 5.9, UR5 5.3; the regressor's share plus 0.15 x the
# hulls' per check sample gives 4.9, 6.6, 6.2, 12.5, 14.1, 6.8, 4.8 ms (0.35, before the term
# measured only within the margin, gave up to 3.7x: SO-101 29.8 ms; 1.0 gave 11-104 ms)
_OBJECTIVE_HULL_SHARE = 0.15
# start-up (imports), the safety model, the identification, the report and its figures:
# 25-40 s of CPU measured on the UR5, Baxter and SO-101 --quick runs (2 cores, loaded)
_SECONDS_FIXED = 30.0
_BYTES_BASE = 400e6  # the interpreter with numpy, scipy, Pinocchio, numba, MuJoCo


def estimate_run(
    config: RunConfig, robot: Robot, family: Any, safety: SafetyModel | None = None
) -> JobEstimate:
    """Rough peak memory and wall time of a run of ``config`` on ``robot``.

    Time: objective evaluations (initial elites, then every run of the optimizer) times the
    samples per period times ``nv^2`` (the regressor's rows and columns), plus the measurement
    and identification of each reported elite. Memory: the swarm's trajectories and the
    regressor of the longest identification. With a safety model, the worst case adds a
    second optimization (not the elite search) and certificate: the retry at a wider margin
    of :mod:`ident.run.pipeline` when every elite is a little inside the clearance.
    """
    nv = robot.nv
    n = config.excitation.n_samples
    e, o = config.elites, config.emupso
    optimizer = o.n_runs * o.n_particles * (o.maxiter + 1)
    evaluations = e.n_particles * (e.maxiter + 1) + optimizer
    per_evaluation = n * nv**2 * _SECONDS_PER_SAMPLE_JOINT2
    if config.safety is not None:  # the clearance and torque terms of the objective
        per_evaluation *= 3.0
    certificate = 0.0
    if safety is not None:  # the hulls' CPU per posture, timed when the model was built
        per_evaluation += (
            _OBJECTIVE_HULL_SHARE
            * min(safety.config.check_samples, n)
            * safety.hull_seconds_per_posture
        )
        certificate = _certificate_seconds(o.n_report_elites, family, safety)
    seconds = evaluations * per_evaluation + certificate + _SECONDS_FIXED
    # the retry runs the optimizer (not the elite search) and the certificate once more
    retry = optimizer * per_evaluation + certificate if safety is not None else 0.0
    swarm_bytes = 8.0 * max(e.n_particles, o.n_particles) * n * nv * 6
    log_samples = n
    m = config.measurement
    if m.source == "mujoco":
        period = (
            2.0 * np.pi / float(config.excitation.options.get("base_frequency", 2 * np.pi / 10))
        )
        log_samples = int((m.settle_periods + m.n_periods) * period * m.rate_hz)
        seconds += (
            o.n_report_elites
            * log_samples
            * (_SECONDS_PER_SIMULATED_STEP + _SECONDS_PER_LOG_SAMPLE * nv / 7.0)
        )
    regressor_bytes = 8.0 * log_samples * nv * (10 * nv + 4 * nv) * 2
    return JobEstimate(
        f"run: {evaluations} objective evaluations of {n} samples x {nv} joints, "
        f"{o.n_report_elites} measured trajectories",
        _BYTES_BASE + swarm_bytes + regressor_bytes,
        seconds,
        worst_seconds=seconds + retry,
        worst_case="if the design is retried at a wider safety margin",
    )


def _certificate_seconds(n_report_elites: int, family: Any, safety: SafetyModel) -> float:
    """The dense check's CPU [s] of the reported elites' periods and the executed trajectory,
    at the CPU per posture the safety model measured (meshes of 100k triangles cost
    milliseconds where their hulls are close), with each mesh pair's smallest value made
    exact."""
    period = float(getattr(family, "period", 10.0) or 10.0)
    samples = (n_report_elites + 1) * period * safety.config.check_rate_hz
    hulls = safety.hull_seconds_per_posture
    return samples * (
        _CERTIFICATE_SHARE * hulls
        + _NEAR_SHARE * max(safety.seconds_per_posture - hulls, 0.0)
        + _SMALLEST_SHARE * safety.mesh_seconds_per_posture
    )


def load_run(path: str | Path) -> RunSetup:
    """Load a run config file and prepare it (:func:`prepare_run`), errors naming the file."""
    return prepare_run(load_run_config(path), source=path)


def make_family(config: RunConfig, robot: Any, stage: Stage) -> Any:
    """The config's excitation family for the stage, its search box overridden by
    ``excitation.bounds``.

    Raises
    ------
    ConfigError
        If the family rejects ``excitation.options``, or a bound names no variable.
    """
    section = config.excitation
    options = dict(section.options)
    options.setdefault("n_samples", section.n_samples)
    family = build_family(section.family, robot, stage, options)
    if section.bounds:
        family.bounds = _override_bounds(family, section.family, section.bounds)
    return family


def _override_bounds(
    family: Any, family_name: str, overrides: dict[str, tuple[float, float]]
) -> FloatArray:
    bounds = np.array(family.bounds, dtype=float, copy=True)
    names = list(family.variable_names)
    for name, (low, high) in overrides.items():
        if name not in names:
            close = difflib.get_close_matches(name, names, n=1)
            if close:
                hint = f"did you mean '{close[0]}'?"
            else:
                nearest = difflib.get_close_matches(name, names, n=1, cutoff=0.0)
                hint = f"no variable is named like it (nearest: '{nearest[0]}')." if nearest else ""
            raise ConfigError(
                f"unknown key 'excitation.bounds.{name}': '{name}' is not a variable of the "
                f"'{family_name}' family; {hint} Variables: {', '.join(names)}."
            )
        bounds[names.index(name)] = (low, high)
    return bounds


def _check_controller(config: RunConfig, robot: Robot) -> None:
    """A home posture has one position per joint, within the position limits."""
    home = config.controller.home
    if home is None:
        return
    if len(home) != robot.nq:
        raise ConfigError(
            f"controller.home has {len(home)} values, the robot has {robot.nq} joints "
            f"({', '.join(robot.joint_names)}); give one position per joint [rad or m]."
        )
    for name, value, low, high in zip(
        robot.joint_names, home, robot.q_lower, robot.q_upper, strict=True
    ):
        if not (np.isfinite(value) and low <= value <= high):
            raise ConfigError(
                f"controller.home: {name} = {value} is outside its limits [{low:g}, {high:g}]."
            )


def _check_sampling(config: RunConfig, family: Any) -> None:
    """Filter cut-offs below the Nyquist frequency of the samples they filter."""
    m = config.measurement
    if m.source == "ideal":
        period = getattr(family, "period", None)
        if m.filter_cutoff_hz is not None and period:
            nyquist = 0.5 * config.excitation.n_samples / float(period)
            if m.filter_cutoff_hz >= nyquist:
                raise ConfigError(
                    f"measurement.filter_cutoff_hz = {m.filter_cutoff_hz:g} Hz is at or above the "
                    f"Nyquist frequency {nyquist:g} Hz of the trajectory's samples "
                    f"(excitation.n_samples = {config.excitation.n_samples} per {period:g} s); "
                    "lower the cut-off or sample more."
                )
        return
    nyquist = 0.5 * m.rate_hz
    pre = config.identification.preprocess
    for key, section in (("lowpass", pre.lowpass), ("torque_lowpass", pre.torque_lowpass)):
        if section is None or isinstance(section, str):  # 'auto': chosen from the log
            continue
        if section.cutoff_hz >= nyquist:
            raise ConfigError(
                f"identification.preprocess.{key}.cutoff_hz = {section.cutoff_hz:g} Hz is at or "
                f"above the Nyquist frequency {nyquist:g} Hz of measurement.rate_hz = "
                f"{m.rate_hz:g}; lower it."
            )


def simulation_notes(config: RunConfig, robot: Robot) -> tuple[str, ...]:
    """What a MuJoCo measurement leaves out of the robot's URDF, one line each (see
    :attr:`RunSetup.simulation_notes`); () for other sources."""
    if config.measurement.source != "mujoco" or not robot.urdf_text:
        return ()
    note = world_fixed_inertia_note(robot.urdf_text, robot.locked_joints)
    return (note,) if note else ()


def _check_measurement(config: RunConfig, robot: Robot, stage: Stage) -> None:
    """Per-joint measurement settings must have one value per joint of the robot."""
    if config.measurement.source == "mujoco":
        check_joint_counts(config.measurement, robot.nv, joint_names=robot.joint_names)
        if robot.urdf_text:  # up front: MuJoCo refuses it only when the simulation starts
            problem = inertia_problem(
                robot.urdf_text, str(robot.urdf_path or robot.name), robot.locked_joints
            )
            if problem:
                raise ModelError(problem)
        if len(stage.moving_joints) != robot.nv:
            raise ConfigError(
                f"measurement.source: mujoco identifies every body of the chain from its log, "
                f"so every joint must move; stage '{stage.name}' holds some. Use stage: whole, "
                "or select a shorter chain (robot.base_link / robot.tip_link); for stage: "
                "payload, leave measurement out and log trajectory.csv with the payload "
                "(docs/payload.md)."
            )
        return
    std = config.measurement.torque_noise_std
    if isinstance(std, list) and len(std) != robot.nv:
        raise ConfigError(
            f"measurement.torque_noise_std has {len(std)} values, the robot has {robot.nv} "
            f"joints ({', '.join(robot.joint_names)}); give one value or one per joint."
        )
    if robot.nv < 1:
        raise ModelError("the robot has no moving joint.")
