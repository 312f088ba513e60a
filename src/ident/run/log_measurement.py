"""``measurement.source: mujoco``: simulate a controller log, then identify it like a real one.

For each reported elite, the closed-loop MuJoCo simulation (:mod:`ident.measure.mujoco_sim`)
writes the log a robot controller would write; the log is read back by the same reader as a
measured log (:func:`ident.measure.logs.read_log`) and identified by the same function as
``ident identify`` (:func:`ident.identify.pipeline.core.identify_measurements`), with the run
config's ``identification`` sections. The run folder keeps the log and an ``identify.yaml`` next to
it, so ``ident identify elites/elite_<k>/identify.yaml`` gives the run's estimate again.

The truth is the URDF's inertials plus the configured friction and rotor inertia (armature);
offsets are zero. Its base-parameter projection is what the estimate is compared with.
"""

from __future__ import annotations

import dataclasses
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import yaml

from ident.dynamics.base_parameters import torque_shares
from ident.dynamics.friction import extra_columns
from ident.dynamics.parameter_model import ParameterModel, build_parameter_model
from ident.dynamics.parameters import payload_on_joint
from ident.dynamics.regressor import joint_torque_regressor
from ident.errors import IdentError
from ident.identify.assessment.sanity import joint_units
from ident.identify.config import IdentifyConfig, TruthConfig, UrdfUpdateConfig
from ident.identify.pipeline.core import IdentifyResult, identify_measurements
from ident.measure.log_config import LogConfig, TransmissionConfig
from ident.measure.logs import RobotLog, read_log
from ident.measure.mujoco_config import MujocoMeasurement, per_joint
from ident.measure.mujoco_sim import SimulatedLog, simulate, write_log
from ident.model import Robot
from ident.run.config import RunConfig
from ident.run.elite_identification import elite_trajectory
from ident.run.results import EliteOutcome, StageInfo, base_set_fields
from ident.run.setup import simulation_notes

__all__ = [
    "LogOutcome",
    "identify_elite_log",
    "friction_truth_note",
    "log_stage_info",
    "save_logs",
    "trajectory_column_norms",
    "identification_failure",
    "identify_config",
    "identify_log",
    "measure_and_identify",
    "simulate_log",
    "true_parameters",
    "write_identify_files",
]

FloatArray = npt.NDArray[np.float64]

#: The folder of a run's files relative to an elite's log folder (``elites/elite_<k>/``).
_RUN_FOLDER_FROM_LOG = Path("..") / ".."

#: Random states of the structural base parameters (as :func:`build_parameter_model` draws).
_N_SHARE_STATES = 200


@dataclass(frozen=True, eq=False)
class LogOutcome:
    """One elite measured by the simulator and identified from its log.

    Attributes
    ----------
    log :
        The simulated log and its truth.
    result :
        The identification of the log (the same object ``ident identify`` builds), or None
        when it failed: the log is still kept, and its ``identify.yaml`` in the run folder
        identifies it again once the cause is fixed.
    config :
        The identify config used (its ``log`` section points to a temporary copy; the run
        folder's ``identify.yaml`` points to the saved one).
    """

    log: SimulatedLog
    result: IdentifyResult | None
    config: IdentifyConfig


def true_parameters(
    pm: ParameterModel, config: RunConfig, model: pin.Model | None = None
) -> FloatArray:
    """The simulator's truth over the model's parameters ``pm.names``, shape (n_all,).

    Inertial parameters from the URDF (``pm.nominal``) plus a simulated
    ``measurement.payload``'s, added to the body that carries its link
    (:func:`~ident.dynamics.parameters.payload_on_joint`; ``model``, the robot's Pinocchio
    model, is needed then); ``fv<j>`` / ``fs<j>`` / ``Ia<j>`` from the configured viscous
    friction, Coulomb friction and armature of joint j, offsets 0. A ``friction.law`` that is
    the identification's own linear model (``viscous_coulomb``, ``viscous_coulomb_offset``) adds
    its ``fv``, ``fc`` (and ``off``) to these; another law has no such truth
    (:func:`friction_truth_note`).

    Raises
    ------
    ValueError
        If the measurement simulates a payload and ``model`` is not given.
    """
    m = config.measurement
    n = pm.terms.n_joints
    values: dict[str, FloatArray] = {
        "fv": np.asarray(per_joint(m.friction.viscous, n), dtype=np.float64),  # type: ignore[union-attr]
        "fs": np.asarray(per_joint(m.friction.coulomb, n), dtype=np.float64),  # type: ignore[union-attr]
        "Ia": np.asarray(per_joint(m.armature, n), dtype=np.float64),  # type: ignore[union-attr]
        "off": np.zeros(n),
    }
    law = getattr(getattr(m, "friction", None), "law", None)
    if law is not None and law.model in _LINEAR_LAWS:
        for kind, label in (("fv", "fv"), ("fs", "fc"), ("off", "off")):
            if label in law.values:
                values[kind] = values[kind] + np.asarray(per_joint(law.values[label], n))
    truth = np.array(pm.nominal, dtype=float)
    payload = getattr(m, "payload", None)
    if payload is not None:
        if model is None:
            raise ValueError("true_parameters: the simulated payload needs the robot's model")
        joint, phi = payload_on_joint(model, payload.link, payload.parameters())
        inertial = pm.inertial_index
        on_body = (inertial >= 10 * (joint - 1)) & (inertial < 10 * joint)
        truth[on_body] += phi[inertial[on_body] - 10 * (joint - 1)]
    for i, name in enumerate(pm.names):
        kind = name.rstrip("0123456789")
        if pm.extra_index[i] >= 0 and kind in values:
            truth[i] = float(values[kind][int(name[len(kind) :]) - 1])
    return truth


#: Simulated friction laws whose parameters map onto the identification's ``fv``, ``fs``,
#: ``off`` (:func:`true_parameters`).
_LINEAR_LAWS = ("viscous_coulomb", "viscous_coulomb_offset")


def friction_truth_note(config: RunConfig) -> str:
    """Why the friction has no truth (empty when it has one): the MuJoCo source simulates a
    ``friction.law`` (Stribeck, sigmoid, load-dependent) that the identification's viscous +
    Coulomb parameters cannot equal, so their errors would compare different quantities."""
    law = getattr(getattr(config.measurement, "friction", None), "law", None)
    if law is None or law.model in _LINEAR_LAWS:
        return ""
    return (
        f"the simulated friction is the {law.model!r} law (measurement.friction.law): the "
        "joints' viscous and Coulomb parameters have no true value to compare with, so they "
        "are left out of the truth verdict (their errors below are against the configured "
        "viscous/coulomb alone; the friction-model comparison, model.friction: auto, judges "
        "the law)"
    )


def log_stage_info(config: RunConfig, robot: Robot) -> tuple[StageInfo, ParameterModel]:
    """The stage of a simulated-log run: every body, friction and rotor terms, their truth.

    The parameter model is the one :func:`identify_measurements` builds for the log (same
    terms, same random states), so names and base parameters match the estimates.
    """
    terms = config.identification.model.extra_terms(robot.nv, "identification.model")
    pm = build_parameter_model(robot.model, terms)
    truth = true_parameters(pm, config, robot.model)
    rows = tuple(range(robot.nv))
    names = pm.names
    alone = tuple(
        b == names[i] for b, i in zip(pm.base.base_names, pm.base.independent, strict=True)
    )
    share = reference_share(pm, truth, robot)
    note = friction_truth_note(config)
    if note:  # no friction truth: the base parameters holding friction are never major
        friction = [i for i, name in enumerate(names) if name.rstrip("0123456789") in ("fv", "fs")]
        holds = np.abs(np.asarray(pm.base.projection)[:, friction]).max(axis=1) > 0
        share = np.where(holds, 0.0, share)
    info = StageInfo(
        name="whole",
        rows=rows,
        columns=(),
        alone=alone,
        base_method=pm.base.method,
        known_bodies_note="all bodies are unknown; friction and rotor inertia are identified "
        "with them (the simulator's truth: the URDF's inertials plus the configured friction "
        "and armature)" + "".join(f"; {n}" for n in (note, *simulation_notes(config, robot)) if n),
        base=pm.base,
        reference_share=share,
        **base_set_fields(pm.base, names, truth),
    )
    return info, pm


def reference_share(
    pm: ParameterModel, truth: FloatArray, robot: Robot, rng: int = 0
) -> FloatArray:
    """Share of the torques each base parameter explains, on random states of the robot.

    ``|beta_i| ||W_i|| / ||W_b beta||`` with ``W_b`` the base columns on random states within
    the robot's limits (:meth:`~ident.model.Robot.random_configurations`: the position range,
    the velocity and the acceleration limits the run keeps, 10 rad/s^2 where none is known):
    unit-free and independent of the trajectory, shape (n_base,).
    """
    # the robot's own acceleration limits, as the design keeps them: a Kinova limited to
    # 1.9 rad/s^2 moved at 10 rad/s^2 made its rotor and wrist inertias "major" (4x their
    # share at its real capability) though no trajectory within its limits can show them
    q, dq, ddq = robot.random_configurations(_N_SHARE_STATES, rng=rng)
    Yb = pm.columns(
        joint_torque_regressor(robot.chain, q, dq, ddq),
        extra_columns(pm.terms, dq, ddq),
        pm.base.independent,
    ).reshape(-1, len(pm.base.independent))
    return torque_shares(Yb, pm.base.project(truth))


def trajectory_column_norms(
    pm: ParameterModel,
    robot: Robot,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    true_base: FloatArray,
) -> tuple[FloatArray, float]:
    """Base-column norms ``||W_i||`` on a trajectory and the true torque norm ``||W_b beta||``.

    ``q, dq, ddq`` (n_samples, nq / nv) [rad, rad/s, rad/s^2] of the designed trajectory;
    ``true_base`` (n_base,) the simulator's truth. With them :func:`error_measures` gives each
    parameter's torque share on this trajectory (as the ideal measurement does).
    """
    Yb = pm.columns(
        joint_torque_regressor(robot.chain, q, dq, ddq),
        extra_columns(pm.terms, dq, ddq),
        pm.base.independent,
    ).reshape(-1, len(pm.base.independent))
    return np.linalg.norm(Yb, axis=0), float(np.linalg.norm(Yb @ np.asarray(true_base)))


def identify_config(
    config: RunConfig, log_section: dict[str, Any], *, robot_path: Path | None = None
) -> IdentifyConfig:
    """The ``ident identify`` config of a simulated log.

    ``log_section`` is the ``log:`` (and ``transmission:``) mapping :func:`write_log` wrote;
    ``robot_path`` replaces the run's robot file (the run folder's copy of the URDF).
    """
    robot = config.robot
    if robot_path is not None:
        robot = robot.model_copy(update={"urdf": robot_path, "description": None})
    ident = config.identification
    return IdentifyConfig(
        name=f"{config.name}-log",
        robot=robot,
        log=LogConfig.model_validate(log_section["log"]),
        transmission=TransmissionConfig.model_validate(log_section.get("transmission", {})),
        preprocess=ident.preprocess,
        model=ident.model,
        estimation=ident.estimation,
        validation=ident.validation,
        refinement=ident.refinement,
    )


def _absolute(section: dict[str, Any], folder: Path) -> dict[str, Any]:
    """``log:`` paths made absolute (they are relative to the log's folder)."""
    log = dict(section["log"])
    for key in ("time", "position", "torque"):
        if isinstance(log.get(key), dict):
            log[key] = {**log[key], "path": str(folder / log[key]["path"])}
    return {**section, "log": log}


def simulate_log(
    config: RunConfig,
    robot: Robot,
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    *,
    seed: Any,
) -> tuple[SimulatedLog, RobotLog, IdentifyConfig]:
    """Simulate one period of a trajectory in MuJoCo, write its log and read it back as a
    measured log is read. Returns the simulation, the log read and its identify config.

    Raises
    ------
    IdentError
        From the simulator (a diverging controller) or the reader.
    """
    simulator = config.measurement
    if not isinstance(simulator, MujocoMeasurement):
        raise IdentError("the simulated log needs measurement.source: mujoco")
    log = simulate(robot, t, q, dq, ddq, simulator, rng=np.random.default_rng(seed))
    with tempfile.TemporaryDirectory(prefix="ident-log-") as tmp:
        files = write_log(tmp, log)
        section = _absolute(yaml.safe_load(files.yaml.read_text(encoding="utf-8")), Path(tmp))
        cfg = identify_config(config, section)
        read = read_log(cfg.log, cfg.transmission, robot.joint_names, source=str(files.yaml))
    if log.q_cmd is not None:  # a position actuator's command, row for row with the log read
        read = dataclasses.replace(read, q_cmd=np.array(log.q_cmd))
    return log, read, cfg


def identify_log(
    cfg: IdentifyConfig, read: RobotLog, robot: Robot, *, source: Path | None = None
) -> IdentifyResult:
    """Identify a simulated log as ``ident identify`` does; ``source`` names it in messages
    (the run folder's ``identify.yaml`` of the elite)."""
    # the written model's bootstrap is `ident identify`'s (on elites/elite_<k>/identify.yaml):
    # a run does not show it, and would pay its re-solves for every elite
    quick = cfg.model_copy(
        update={"urdf_update": UrdfUpdateConfig(model_bootstrap=0), "source": source}
    )
    return identify_measurements(quick, read, model=robot.model)


def measure_and_identify(
    config: RunConfig,
    robot: Robot,
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    *,
    seed: Any,
) -> LogOutcome:
    """Simulate one period of a trajectory in MuJoCo, write its log, read and identify it.

    Raises
    ------
    IdentError
        From the simulator (diverging controller), the reader or the identification (a
        trajectory that does not excite every base parameter: ``NotIdentifiable``).
    """
    log, read, cfg = simulate_log(config, robot, t, q, dq, ddq, seed=seed)
    return LogOutcome(log=log, result=identify_log(cfg, read, robot), config=cfg)


def identification_failure(
    error: IdentError, config: RunConfig, robot: Robot, log: SimulatedLog, rank: int
) -> str:
    """Why elite ``rank``'s simulated log did not identify, naming the run config's fields.

    A joint that never reaches its velocity threshold is named with its entry of
    ``identification.preprocess.velocity_threshold`` and its largest simulated speed
    [rad/s or m/s]: the value the threshold must go below.
    """
    where = f"elite {rank}'s simulated log (elites/elite_{rank}/identify.yaml) did not identify"
    idle = getattr(error, "idle_joints", ())
    thresholds = config.identification.preprocess.velocity_threshold
    if not idle or thresholds is None:
        return f"{where}: {error}"
    names = list(log.joint_names)
    speeds = np.abs(np.asarray(log.dq_true, dtype=float)).max(axis=0)
    units = dict(zip(robot.model.names[1:], joint_units(robot.model), strict=True))
    clauses = []
    for name in idle:
        j = names.index(name)
        unit = "m/s" if units.get(name) == "N" else "rad/s"
        clauses.append(
            f"{name} moves at most {speeds[j]:.3g} {unit}, below its "
            f"identification.preprocess.velocity_threshold of {thresholds[j]:g} {unit} "
            f"(entry {j + 1} of {len(names)})"
        )
    return (
        f"{where}: no sample of {', '.join(idle)} reaches its velocity threshold: "
        f"{'; '.join(clauses)}. Lower that entry of "
        "identification.preprocess.velocity_threshold below the joint's speed, or let the "
        "joint move more (excitation.options.amplitude_bound, excitation.bounds); the log is "
        f"kept: 'ident identify elites/elite_{rank}/identify.yaml' with a lower "
        f"preprocess.velocity_threshold identifies it. The identification said: {error}"
    )


def _period_torques(log: SimulatedLog, t: FloatArray) -> FloatArray:
    """The logged (measured) torques of the first logged period at the trajectory's sample
    times ``t`` (n,), shape (n, nv) [N*m]."""
    start = log.t[0]
    return np.column_stack(
        [
            np.interp(start + t, log.t, log.tau_measured[:, j])
            for j in range(log.tau_measured.shape[1])
        ]
    )


def identify_elite_log(
    config: RunConfig,
    robot: Robot,
    family: Any,
    stage: StageInfo,
    index: int,
    x: FloatArray,
    fitness: float,
    details: dict[str, float],
    seed: Any,
) -> EliteOutcome:
    """Simulate one elite in MuJoCo, identify its log; failures are recorded, not raised.

    The outcome's ``tau`` is the logged (measured) torque of the first logged period at the
    trajectory's sample times, None when the simulation itself failed (nothing measured);
    ``log`` holds the whole simulation for the run folder, kept when only the identification
    failed (``failures`` says why, naming the config field to change).
    """
    t, q, dq, ddq, traced = elite_trajectory(family, x)
    # the least-squares estimate, named by its own method (what ``ident identify`` reports
    # as "the estimate"); a constrained or other estimator's result is in the log outcome
    method = config.identification.estimation.least_squares_method
    outcome = EliteOutcome(
        rank=index + 1,
        x=x,
        fitness=fitness,
        details=details,
        t=t,
        q=q,
        dq=dq,
        ddq=ddq,
        traced_points=traced,
        tau=None,
        estimates={},
        failures={},
    )
    try:
        log, read, cfg = simulate_log(config, robot, t, q, dq, ddq, seed=seed)
    except IdentError as e:  # nothing measured: no torques, the simulator's cause
        failure = f"the simulation of elite {index + 1} failed, nothing was measured: {e}"
        return dataclasses.replace(outcome, failures={method: failure})
    outcome = dataclasses.replace(
        outcome, tau=_period_torques(log, t), log=LogOutcome(log=log, result=None, config=cfg)
    )
    try:
        source = Path("elites") / f"elite_{index + 1}" / "identify.yaml"
        result = identify_log(cfg, read, robot, source=source)
    except IdentError as e:
        failure = identification_failure(e, config, robot, log, index + 1)
        return dataclasses.replace(outcome, failures={method: failure})
    norms, true_norm = trajectory_column_norms(
        result.parameters, robot, q, dq, ddq, stage.true_base
    )
    return dataclasses.replace(
        outcome,
        estimates={method: result.estimate},
        log=LogOutcome(log=log, result=result, config=cfg),
        base_column_norms=norms,
        true_torque_norm=true_norm,
    )


def write_identify_files(
    folder: Path, config: RunConfig, outcome: LogOutcome, stage: StageInfo | None = None
) -> Path:
    """Save an elite's log and the ``identify.yaml`` that identifies it again; return its path.

    ``folder`` is ``<run>/elites/elite_<k>``; the robot is the run folder's ``robot.urdf``.
    With the run's ``stage``, ``validation.truth`` holds the simulator's true base parameters,
    so ``ident identify`` judges the log by the same verdict rule as the run (docs/verdict.md).
    """
    files = write_log(folder, outcome.log)
    section = yaml.safe_load(files.yaml.read_text(encoding="utf-8"))
    cfg = identify_config(config, section, robot_path=_RUN_FOLDER_FROM_LOG / "robot.urdf")
    if stage is not None and stage.reference_share is not None:
        truth = TruthConfig(
            base_names=list(stage.base_names),
            values=[float(v) for v in stage.true_base],
            reference_share=[float(v) for v in stage.reference_share],
        )
        cfg = cfg.model_copy(
            update={"validation": cfg.validation.model_copy(update={"truth": truth})}
        )
    data = cfg.model_dump(mode="json", exclude={"source"})
    data["robot"] = {k: v for k, v in data["robot"].items() if v not in (None, [], {})}
    if config.robot.inertia_check:
        data["robot"].pop("inertia_check", None)
    path = folder / "identify.yaml"
    header = (
        "# ident identify elites/.../identify.yaml: identifies this simulated log again, as\n"
        "# 'ident run' did (same reader, same settings). Paths relative to this file.\n"
    )
    path.write_text(header + yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def save_logs(result: Any, run_dir: Path) -> list[Path]:
    """Save the simulated log of every measured elite with its ``identify.yaml``.

    Returns the ``identify.yaml`` paths (empty for an ideal measurement).
    """
    written = []
    for elite in result.elites:
        if elite.log is not None:
            folder = Path(run_dir) / "elites" / f"elite_{elite.rank}"
            written.append(write_identify_files(folder, result.config, elite.log, result.stage))
    return written
