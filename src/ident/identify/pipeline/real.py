"""``ident identify``: read the log a config names, then the identification core.

:func:`identify` reads the URDF (Pinocchio) and the log, converts motor-side signals to joint
side (:mod:`ident.measure.logs`), checks the memory and time estimate
(:func:`estimate_identify`), gives a position servo's log its torque from the servo's law
(``actuator:``, :mod:`ident.identify.actuators`), removes the torque's delay (``signals:``,
:func:`ident.identify.corrections.signal_correction.correct_log`), and hands the measurements to
:func:`ident.identify.pipeline.core.identify_measurements`, the one identification every command
runs. Nothing here writes files; :mod:`ident.report.identify_report` does.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

from ident.dynamics.parameter_model import PRIORITY_LABELS, ParameterModel, build_parameter_model
from ident.errors import DataError
from ident.identify.actuators.registry import get_actuator
from ident.identify.actuators.servo_fit import servo_fit_count
from ident.identify.assessment.model_intervals import estimated_seconds
from ident.identify.config import IdentifyConfig
from ident.identify.corrections.signal_correction import correct_log
from ident.identify.estimation import log_chunks, preprocess
from ident.identify.pipeline.core import IdentifyResult, identify_measurements
from ident.inputs import JobEstimate, check_job
from ident.measure.logs import RobotLog, estimate_log, read_log
from ident.model import Robot
from ident.model.selection import load_robot

__all__ = [
    "PRIORITY_LABELS",
    "IdentifyResult",
    "ParameterModel",
    "build_parameter_model",
    "estimate_identify",
    "identify",
    "identify_measurements",
    "load_robot_model",
]


def load_robot_model(urdf: str | Path) -> pin.Model:
    """The Pinocchio model of a URDF, loaded as every command loads it
    (:meth:`ident.model.Robot.from_urdf`: same checks, continuous joints as revolute).

    Raises
    ------
    ModelError
        If the URDF cannot be parsed or is not a chain of 1-DoF joints.
    """
    return Robot.from_urdf(urdf).model


# Cost model of estimate_identify, from benchmarks/bench_identify_long.py (one hour at 1 kHz of a
# 7-joint arm, 3.6 million samples, by chunks on a quiet 2-core machine: 26 s wall, 41 s of CPU,
# peak 900 MiB). The CPU time, rounded up, is used (the wall time on one core), so on more cores
# the estimate errs long, as an estimate that may refuse a job should.
_SECONDS_PER_SAMPLE_JOINT2 = 2.5e-7
_BYTES_BASE = 400e6  # the interpreter with numpy, scipy, Pinocchio, numba, cvxpy, matplotlib


def estimate_identify(cfg: IdentifyConfig, log: RobotLog) -> JobEstimate:
    """Rough peak memory and wall time of identifying ``log`` (n_samples, nv).

    Time: ``n_samples * nv^2`` (the regressor's rows and columns). Memory: the log's arrays,
    the chunks in flight (:func:`ident.identify.estimation.log_chunks.chunk_bytes`: one per worker,
    or the whole log as one chunk when :func:`~ident.identify.estimation.log_chunks.use_chunks` says
    so, as the core decides) and the uncertainty's blocks. A decimation still ``auto`` counts as
    none, so the estimate errs high.
    """
    n_samples, nv = log.q.shape
    n_columns = 10 * nv + 4 * nv  # rigid bodies and the extra terms, as the core counts
    pp = cfg.preprocess
    step = 1 if isinstance(pp.decimation, str) else preprocess.decimation_step(pp)
    per_joint = 2 if log.dq is None else 4  # q, tau (and measured dq, ddq); t
    log_bytes = 8.0 * n_samples * (per_joint * nv + 1)
    if log_chunks.use_chunks(log, pp, n_columns):
        chunk = pp.chunk_samples or log_chunks.default_chunk_samples((0, 0), nv, n_columns, step)
        # one chunk in flight per thread
        in_flight = min(log_chunks.local_workers(), -(-n_samples // chunk))
        work = in_flight * log_chunks.chunk_bytes(min(n_samples, chunk), nv, n_columns, step)
        path = "by chunks"
    else:
        work = log_chunks.chunk_bytes(n_samples, nv, n_columns, step)
        path = "in memory"
    blocks = 8.0 * min(log_chunks.MAX_BLOCKS, n_samples) * n_columns**2
    # a position servo's log is accumulated once per delay and saturation round beforehand
    passes = 1 + servo_fit_count(cfg.actuator, log.sampling_rate_hz)
    servo = f", {passes - 1} servo fits first" if passes > 1 else ""
    return JobEstimate(
        f"identify: {n_samples} samples x {nv} joints, {path}{servo}",
        _BYTES_BASE + log_bytes + work + blocks,
        passes * n_samples * nv**2 * _SECONDS_PER_SAMPLE_JOINT2,
    )


def estimate_model_intervals(cfg: IdentifyConfig, nv: int) -> JobEstimate | None:
    """The written model's bootstrap re-solves (``urdf_update.model_bootstrap``), or None when
    there are none (:func:`ident.identify.assessment.model_intervals.estimated_seconds`)."""
    n_boot = cfg.urdf_update.model_bootstrap if cfg.urdf_update.model != "none" else 0
    if not n_boot:
        return None
    return JobEstimate(
        f"intervals of the written model: {n_boot} re-solves of its fit "
        "(urdf_update.model_bootstrap; 0 switches them off)",
        0.0,
        estimated_seconds(n_boot, nv),
    )


def identify(
    cfg: IdentifyConfig,
    *,
    rng: int = 0,
    scheduler: str | None = None,
    on_estimate: Callable[[JobEstimate], None] | None = None,
) -> IdentifyResult:
    """Run the identification described by ``cfg``: read its log, then
    :func:`~ident.identify.pipeline.core.identify_measurements`.

    ``scheduler``: a dask.distributed scheduler address for the chunks of a long log.
    ``on_estimate``: called with the estimate of reading the log (from the files' sizes,
    :func:`ident.measure.logs.estimate_log`) before reading it, then with the memory and time
    estimate (:func:`estimate_identify`) once the log is read, before the identification, and
    with that of the written model's bootstrap (:func:`estimate_model_intervals`) when there is
    one (``ident identify`` prints those above a minute); each is checked against the
    ceilings first.

    Raises
    ------
    IdentError
        Subclasses naming the file, column or parameter: bad log, bad config, rank deficiency.
    ResourceLimitError
        If the estimate is above the ceilings (:func:`ident.inputs.check_job`).
    """
    t0 = time.perf_counter()
    source = str(cfg.source or "config")
    robot = load_robot(cfg.robot, source=source)
    model = robot.model
    joints = [model.names[i] for i in range(1, model.njoints)]
    log = _read(cfg, joints, source, on_estimate)
    still = still_joints(log)
    if len(still) == len(joints):  # said before "too few observations" hides it
        raise DataError(
            f"{source}: log: no joint moves ({', '.join(still)}: each position spans less "
            f"than {STILL_SPAN:g} rad or m over the log); there is no motion to identify from: "
            "give the log of an excitation (ident run writes one), or check log.position."
        )
    estimate = check_job(estimate_identify(cfg, log))  # before the servo's fits too
    # a servo's torque from its law (the gain, delay, saturation: identify/actuators)
    prepared = get_actuator(cfg.actuator.kind).prepare(cfg, model, log, source)
    cfg, log = prepared.config, prepared.log
    (log,) = correct_log(cfg.signals, robot, cfg.preprocess, cfg.model, log, source=source).logs
    _check_identify_job(cfg, log, estimate, on_estimate)
    try:
        result = identify_measurements(
            cfg, log, model=model, rng=rng, read_s=time.perf_counter() - t0, scheduler=scheduler
        )
    except DataError as e:
        if not str(e).startswith("too few observations"):
            raise
        if still:  # the cause, named
            raise DataError(
                f"{source}: joint(s) {', '.join(still)} never move in the log, so the rows "
                f"that would determine their parameters are missing ({e})"
            ) from e
        # the config whose log and settings (log.*, preprocess.*) left too few rows
        raise DataError(f"{source}: {e}") from e
    return dataclasses.replace(result, actuator=prepared.fit)


def _read(
    cfg: IdentifyConfig,
    joints: list[str],
    source: str,
    on_estimate: Callable[[JobEstimate], None] | None,
) -> RobotLog:
    """The log of ``cfg`` (:func:`ident.measure.logs.read_log`), once the estimate of reading
    it (from the files' sizes) is checked and handed to ``on_estimate``."""
    reading = check_job(estimate_log(cfg.log))  # from the files' sizes, before reading
    if on_estimate is not None:
        on_estimate(reading)
    log = read_log(cfg.log, cfg.transmission, joints, source=source)
    # the reader's blocks and the time checks' temporaries, freed, back to the system before
    # the identification (they stayed resident below the chunks' peak)
    log_chunks.release_free_memory()
    return log


def _check_identify_job(
    cfg: IdentifyConfig,
    log: RobotLog,
    estimate: JobEstimate,
    on_estimate: Callable[[JobEstimate], None] | None,
) -> None:
    """The identification's ``estimate`` (:func:`estimate_identify`, checked already, before
    a servo's fits) and that of the written model's bootstrap when there is one
    (:func:`estimate_model_intervals`), checked against the ceilings; both handed to
    ``on_estimate``.

    Raises
    ------
    ResourceLimitError
        If the bootstrap's estimate is above the ceilings (:func:`ident.inputs.check_job`).
    """
    extra = estimate_model_intervals(cfg, log.q.shape[1])
    if extra is not None:
        check_job(extra)
    if on_estimate is not None:
        on_estimate(estimate)
        if extra is not None:
            on_estimate(extra)  # printed when above a minute


#: A joint whose position spans less than this [rad or m] over a whole log never moves.
STILL_SPAN = 1e-6


def still_joints(log: RobotLog) -> list[str]:
    """Names of the joints of ``log`` whose position spans less than :data:`STILL_SPAN`."""
    span = np.ptp(log.q, axis=0) if log.q.shape[0] else np.zeros(log.q.shape[1])
    return [str(n) for n, s in zip(log.joint_names, span, strict=True) if s < STILL_SPAN]
