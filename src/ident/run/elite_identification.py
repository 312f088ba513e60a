"""The ideal measurement of an elite trajectory, identified by the identification core.

``measurement.source: ideal``: joint torques from Pinocchio's RNEA on the true parameters plus
the configured noise (:mod:`ident.measure.ideal`). The measurements become a
:class:`~ident.measure.logs.RobotLog` (:func:`ideal_log`: the measured states kept, the torques
of the known bodies outside the stage subtracted from the measured ones) and go through
:func:`ident.identify.pipeline.core.identify_measurements`, as a log does, with the stage's
parameter model (its unknown bodies, its base parameters, its torque rows) and settings that keep
every sample (:func:`ideal_identify_config`: no filter, trim, decimation or velocity threshold;
identified and validated on the whole period). Every estimator of ``estimation.methods`` is the
registry's (:mod:`ident.identify.estimators`).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from ident.dynamics.parameter_model import ParameterModel, stage_parameter_model
from ident.errors import IdentError, NotIdentifiable
from ident.identify.config import (
    EssentialConfig,
    EstimationConfig,
    IdentifyConfig,
    ModelConfig,
    PreprocessConfig,
    ReferenceConfig,
    UrdfUpdateConfig,
    ValidationConfig,
)
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimators import get_contract
from ident.identify.pipeline.core import identify_measurements
from ident.measure.ideal import Measurements, NoiseModel, simulate_measurements
from ident.measure.logs import RobotLog
from ident.run.config import MeasurementSection, RunConfig
from ident.run.results import EliteOutcome, StageInfo
from ident.run.stage_info import stage_matrix

__all__ = [
    "elite_trajectory",
    "non_finite_measurement",
    "ideal_identify_config",
    "ideal_log",
    "identify_elite",
    "noise_model",
    "stage_parameters",
]

FloatArray = npt.NDArray[np.float64]

#: Every sample of the period identifies (and validates: in sample) as it was measured.
_KEEP_EVERY_SAMPLE = PreprocessConfig(
    lowpass=None, trim_samples=0, decimation=[], velocity_threshold=None, chunked="never"
)


def elite_trajectory(
    family: Any, x: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray | None]:
    """One period of a design: ``t`` (n,), ``q, dq, ddq`` (n, nq) and the traced points
    (n, 3) [m] or None."""
    batch = family.trajectories(x[None, :])
    t = np.asarray(batch.t, dtype=float)
    q, dq, ddq = (np.asarray(a[0], dtype=float) for a in (batch.q, batch.dq, batch.ddq))
    traced = None if batch.traced_points is None else np.asarray(batch.traced_points[0])
    return t, q, dq, ddq, traced


def noise_model(config: RunConfig) -> NoiseModel:
    """The noise of the ideal measurement (``measurement`` section)."""
    m = config.measurement
    if not isinstance(m, MeasurementSection):
        raise IdentError("the ideal measurement needs measurement.source: ideal")
    std = m.torque_noise_std
    return NoiseModel(
        torque_std=tuple(std) if isinstance(std, list) else float(std),
        encoder_counts_per_rev=m.encoder_counts_per_rev,
        filter_cutoff_hz=m.filter_cutoff_hz,
    )


def core_method(methods: list[str]) -> str:
    """The estimator the core runs besides OLS and WLS: the one of ``methods`` that is not a
    least-squares estimate (the config allows at most one), else ``wls`` (or ``ols``)."""
    others = [m for m in methods if not get_contract(m).least_squares]
    if others:
        return others[0]
    return "wls" if "wls" in methods else methods[0]


def ideal_identify_config(config: RunConfig) -> IdentifyConfig:
    """The core's settings for an ideal measurement: every sample kept and used as measured
    (no low-pass, trim, decimation, velocity threshold), identified and validated on the
    whole period, no essential parameters; the estimator of ``estimation.methods``.

    The measurements come from memory, not a file: the config has no ``log`` section (the
    core does not read it).
    """
    estimation = EstimationConfig(
        method=core_method(config.estimation.methods),
        essential=EssentialConfig(enabled=False),
    )
    return IdentifyConfig.model_construct(
        name=f"{config.name}-ideal",
        robot=config.robot,
        preprocess=_KEEP_EVERY_SAMPLE,
        model=ModelConfig(),  # not read: the stage's parameter model is given
        estimation=estimation,
        validation=ValidationConfig(identify_fraction=1.0),
        reference=ReferenceConfig(),
        urdf_update=UrdfUpdateConfig(model_bootstrap=0),  # a run shows no model intervals
        source=None,
    )


def stage_parameters(robot: Any, stage: StageInfo) -> ParameterModel:
    """The stage's parameter model: its unknown bodies, base parameters and torque rows."""
    return stage_parameter_model(robot.model, stage.columns, stage.base, stage.rows)


def ideal_log(robot: Any, stage: StageInfo, meas: Measurements) -> RobotLog:
    """The ideal measurements as a log: measured states, and the measured torques minus those
    of the known bodies (outside the stage: their true parameters), every joint [N*m]."""
    all_rows = tuple(range(robot.nv))
    _, known = stage_matrix(robot, all_rows, stage.columns, meas.q, meas.dq, meas.ddq)
    t = np.asarray(meas.t, dtype=float)
    return RobotLog(
        t=t - t[0],
        q=np.asarray(meas.q, dtype=float),
        tau=np.asarray(meas.tau, dtype=float) - known,
        sampling_rate_hz=float((t.shape[0] - 1) / (t[-1] - t[0])),
        joint_names=tuple(robot.joint_names),
        records=({"step": "ideal measurement", "detail": "RNEA on the true parameters"},),
        dq=np.asarray(meas.dq, dtype=float),
        ddq=np.asarray(meas.ddq, dtype=float),
    )


def identify_elite(
    config: RunConfig,
    robot: Any,
    family: Any,
    stage: StageInfo,
    index: int,
    x: FloatArray,
    fitness: float,
    details: dict[str, float],
    seed: Any,
) -> EliteOutcome:
    """Measure (simulate) one elite trajectory and estimate the stage's base parameters.

    Estimator failures (rank-deficient base matrix on this trajectory, ...) are recorded in
    ``failures`` with their message; they do not raise.
    """
    t, q, dq, ddq, traced = elite_trajectory(family, x)
    meas = simulate_measurements(
        robot.model, t, q, dq, ddq, noise_model(config), rng=np.random.default_rng(seed)
    )
    unmeasured = non_finite_measurement(meas, tuple(robot.joint_names), index + 1)
    estimates, failures, norms, true_norm = _estimate_elite(config, robot, stage, meas, unmeasured)
    return EliteOutcome(
        rank=index + 1,
        x=x,
        fitness=fitness,
        details=details,
        t=t,
        q=q,
        dq=dq,
        ddq=ddq,
        traced_points=traced,
        tau=None if unmeasured else np.asarray(meas.tau),
        estimates=estimates,
        failures=failures,
        base_column_norms=norms,
        true_torque_norm=true_norm,
    )


def _estimate_elite(
    config: RunConfig,
    robot: Any,
    stage: StageInfo,
    meas: Measurements,
    unmeasured: str,
) -> tuple[dict[str, Any], dict[str, str], FloatArray | None, float | None]:
    """The stage's base parameters estimated from an elite's measurements ``meas`` by every
    method of ``config.estimation.methods``; ``unmeasured``: why the simulation gave no
    usable measurement (empty when it did).

    Returns the successful estimates and each failed method's message (every method fails
    with the same message when the measurements cannot be identified), and the base columns'
    norms and the true torque norm (:func:`_column_norms`; None without an identification).
    """
    estimates: dict[str, Any] = {}
    failures: dict[str, str] = {}
    norms: FloatArray | None = None
    true_norm: float | None = None
    methods = config.estimation.methods
    try:
        if unmeasured:  # the run's own simulation: its cause, never a file that cannot be read
            raise IdentError(unmeasured)
        result = identify_measurements(
            ideal_identify_config(config),
            ideal_log(robot, stage, meas),
            model=robot.model,
            parameters=stage_parameters(robot, stage),
        )
    except NotIdentifiable as e:
        failures = {m: f"not identifiable on this trajectory: {e}" for m in methods}
    except IdentError as e:
        failures = {m: str(e) for m in methods}
    else:
        assert result.consistent is not None  # the core always sets both
        assert result.reduction is not None
        for method in methods:
            est = result.consistent.estimates[method]
            if est.success:
                estimates[method] = est
            else:
                failures[method] = est.message
        norms, true_norm = _column_norms(result.reduction, stage.true_base)
    return estimates, failures, norms, true_norm


def non_finite_measurement(meas: Measurements, joint_names: tuple[str, ...], rank: int) -> str:
    """Why the simulated measurement of elite ``rank`` is unusable: its first non-finite torque
    and where it comes from (the elite's states, or the dynamics on finite states); empty when
    every torque is finite."""
    bad = ~np.isfinite(np.asarray(meas.tau, dtype=float))
    if not bad.any():
        return ""
    i, j = (int(k) for k in np.argwhere(bad)[0])
    states = np.concatenate([np.ravel(meas.q[i]), np.ravel(meas.dq[i]), np.ravel(meas.ddq[i])])
    cause = (
        "the elite's own trajectory is not finite there (the excitation family's formula)"
        if not np.isfinite(states).all()
        else "the robot's true parameters give a non-finite torque at finite states (check "
        "the URDF's inertials)"
    )
    return (
        f"the run's own simulated measurement of elite {rank} is not finite: the torque of "
        f"{joint_names[j]} at t = {float(meas.t[i]):.4g} s is {float(meas.tau[i, j])}: {cause}; "
        "nothing was identified from it"
    )


def _column_norms(red: ReducedObservations, true_base: FloatArray) -> tuple[FloatArray, float]:
    """Norms of the base columns ``||W_i||`` and of the true torques ``||W_b beta||`` over the
    identification rows, from their reduction (``W_j = Q_j R_j`` per joint)."""
    norms = np.sqrt(np.einsum("gij,gij->j", red.R, red.R))
    return norms, float(np.linalg.norm(red.R @ true_base))
