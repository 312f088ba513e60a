"""The ``ident identify`` pipeline: a log of a real robot -> identified base parameters.

Steps (each recorded for the report):

1. read the URDF (Pinocchio) and the log; convert motor-side signals to joint side
   (:mod:`ident.identify.logs`);
2. low-pass the positions, differentiate to ``dq`` and ``ddq``, trim the edges
   (:mod:`ident.identify.preprocess`);
3. build the regressor: rigid bodies (:mod:`ident.dynamics.regressor`) plus friction, offsets,
   rotor inertias and coupled-wrist terms (:mod:`ident.dynamics.friction`);
4. base parameters, found structurally on random states (so that a parameter the log does not
   excite is reported by name instead of silently merged), with the *sequential* column choice
   in the priority order ``Ixx Ixy Ixz Iyy Iyz Izz mcx mcy mcz m Ia fv fs off`` per joint, then
   the coupled-wrist terms: the first independent column of each group is kept, which is the
   choice of the figaroh reference, so base parameters can be compared by name;
5. zero-phase decimation of torques and base regressor rows alike; per-joint velocity threshold;
6. split in time; OLS/WLS on the first part (:mod:`ident.identify.estimate`), essential
   parameters (:mod:`ident.identify.essential`);
7. held-out prediction of the identified, essential, reference and URDF-nominal parameters
   (:mod:`ident.identify.validation`).

Nothing here writes files; :mod:`ident.report.identify_report` does.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from threadpoolctl import threadpool_limits

from ident.dynamics.chain import chain_from_model
from ident.dynamics.friction import (
    ExtraTerms,
)
from ident.dynamics.parameter_model import (
    PRIORITY_LABELS,
    ParameterModel,
    build_parameter_model,
    model_regressors,
)
from ident.errors import ConfigError, DataError, NotIdentifiable
from ident.identify import accumulate, preprocess, sanity
from ident.identify.config import IdentifyConfig
from ident.identify.essential import EssentialResult, essential_parameters
from ident.identify.estimate import Estimate, least_squares, rank_report
from ident.identify.estimators import (
    ConsistentIdentification,
    bounding_ellipsoids,
    consistent_identification,
)
from ident.identify.logs import RobotLog, estimate_log, read_log
from ident.identify.motion import measured_motion
from ident.identify.reference import (
    compare_with_reference,
    read_reference,
    reference_prediction,
)
from ident.identify.validation import (
    ModelPrediction,
    held_out_warnings,
    prediction_metrics,
    time_split,
)
from ident.inputs import JobEstimate, check_job
from ident.model import Robot
from ident.model.selection import load_robot
from ident.trajectory import JointTrajectory

__all__ = [
    "PRIORITY_LABELS",
    "IdentifyResult",
    "ParameterModel",
    "build_parameter_model",
    "estimate_identify",
    "identify",
    "load_robot_model",
]

FloatArray = npt.NDArray[np.float64]


# Per-joint priority of the sequential base-parameter choice (figaroh's column order).
def load_robot_model(urdf: str | Path) -> pin.Model:
    """The Pinocchio model of a URDF, loaded as every command loads it
    (:meth:`ident.model.Robot.from_urdf`: same checks, continuous joints as revolute).

    Raises
    ------
    ModelError
        If the URDF cannot be parsed or is not a chain of 1-DoF joints.
    """
    return Robot.from_urdf(urdf).model


@dataclass(frozen=True, eq=False)
class IdentifyResult:
    """Everything the identify report needs (arrays SI, samples on axis 0).

    Attributes
    ----------
    config :
        The validated config.
    log :
        The converted log (before processing).
    records :
        Every processing step, in order.
    parameters :
        Parameter model (names, base parameters).
    estimate :
        Estimate of the base parameters on the identification part.
    essential :
        Essential-parameter reduction, or None when disabled.
    t_validate, tau_validate :
        Held-out time [s] and measured torques [N*m], shapes (n_val,), (n_val, nv).
    predictions :
        Held-out predictions by label (identified, essential, reference, URDF nominal).
    comparison :
        Rows comparing our values with the reference values.
    reference_note :
        How the reference maps onto our parameters.
    timings :
        Seconds per stage.
    reference_essential :
        Rows comparing our essential parameters with the reference's.
    motion :
        The measured motion (processed, decimated to <= 50 Hz) for ``trajectory.csv`` and the
        replay, or None when the log is too short to decimate it (see ``motion_note``).
    motion_note :
        Why ``motion`` is None, else empty.
    consistent :
        Per-estimator physical consistency and the constrained estimate (``estimation.method``
        ``lmi`` or ``log_cholesky``; see :mod:`ident.identify.estimators.identification`).
    warnings :
        Plain-language problems with the result (held-out prediction worse than the URDF's
        nominal parameters, or above ``validation.max_relative_residual``); empty when none.
    """

    config: IdentifyConfig
    log: RobotLog
    records: tuple[dict, ...]
    parameters: ParameterModel
    estimate: Estimate
    essential: EssentialResult | None
    t_validate: FloatArray
    tau_validate: FloatArray
    keep_validate: npt.NDArray[np.bool_]
    predictions: dict[str, ModelPrediction]
    comparison: tuple[dict, ...]
    reference_note: str
    joint_names: tuple[str, ...]
    sampling_rate_hz: float
    n_identify_rows: int
    timings: dict[str, float] = field(default_factory=dict)
    reference_essential: tuple[dict, ...] = ()
    motion: JointTrajectory | None = None
    motion_note: str = ""
    warnings: tuple[str, ...] = ()
    consistent: ConsistentIdentification | None = None

    @property
    def status(self) -> str:
        """``"ok"``, or ``"warning"`` when :attr:`warnings` is not empty."""
        return "warning" if self.warnings else "ok"


# Cost model of estimate_identify, from benchmarks/bench_identify_long.py (one hour at 1 kHz of a
# 7-joint arm, 3.6 million samples, by chunks on a quiet 2-core machine: 37 s wall, 60 s of CPU,
# peak 1.63 GB). The CPU time, rounded up, is used (the wall time on one core), so on more cores
# the estimate errs long, as an estimate that may refuse a job should.
_SECONDS_PER_SAMPLE_JOINT2 = 4e-7
_BYTES_BASE = 400e6  # the interpreter with numpy, scipy, Pinocchio, numba
_LOG_ARRAYS = 8  # t, q, tau, filtered q and tau, dq, ddq, mask: (n_samples, nv) each


def estimate_identify(cfg: IdentifyConfig, log: RobotLog) -> JobEstimate:
    """Rough peak memory and wall time of identifying ``log`` (n_samples, nv).

    Time: ``n_samples * nv^2`` (the regressor's rows and columns). Memory: the log's arrays
    and either the whole regressor (in memory) or one chunk's
    (:func:`ident.identify.accumulate.use_chunks` decides, as :func:`identify_log` does).
    """
    n_samples, nv = log.q.shape
    n_columns = 10 * nv + 4 * nv  # rigid bodies and the extra terms, as identify_log counts
    log_bytes = 8.0 * _LOG_ARRAYS * n_samples * nv
    if accumulate.use_chunks(log, cfg.preprocess, n_columns):
        chunk = cfg.preprocess.chunk_samples or accumulate.default_chunk_samples(
            (0, 0), nv, n_columns
        )
        # one chunk in flight per thread
        in_flight = min(accumulate.local_workers(), -(-n_samples // chunk))
        regressor = in_flight * accumulate.regressor_bytes(min(n_samples, chunk), nv, n_columns)
        path = "by chunks"
    else:
        regressor = accumulate.regressor_bytes(n_samples, nv, n_columns)
        path = "in memory"
    return JobEstimate(
        f"identify: {n_samples} samples x {nv} joints, {path}",
        _BYTES_BASE + log_bytes + regressor,
        n_samples * nv**2 * _SECONDS_PER_SAMPLE_JOINT2,
    )


def identify(
    cfg: IdentifyConfig,
    *,
    rng: int = 0,
    scheduler: str | None = None,
    on_estimate: Callable[[JobEstimate], None] | None = None,
) -> IdentifyResult:
    """Run the identification described by ``cfg``: read its log, then :func:`identify_log`.

    ``scheduler``: a dask.distributed scheduler address for the chunks of a long log.
    ``on_estimate``: called with the estimate of reading the log (from the files' sizes,
    :func:`ident.identify.logs.estimate_log`) before reading it, then with the memory and time
    estimate (:func:`estimate_identify`) once the log is read, before the identification
    (``ident identify`` prints them); each is checked against the ceilings first.

    Raises
    ------
    IdentError
        Subclasses naming the file, column or parameter: bad log, bad config, rank deficiency.
    ResourceLimitError
        If the estimate is above the ceilings (:func:`ident.inputs.check_job`).
    """
    t0 = time.perf_counter()
    source = str(cfg.source or "config")
    model = load_robot(cfg.robot, source=source).model
    joints = [model.names[i] for i in range(1, model.njoints)]
    reading = check_job(estimate_log(cfg.log))  # from the files' sizes, before reading
    if on_estimate is not None:
        on_estimate(reading)
    log = read_log(cfg.log, cfg.transmission, joints, source=source)
    estimate = check_job(estimate_identify(cfg, log))
    if on_estimate is not None:
        on_estimate(estimate)
    return identify_log(
        cfg, log, model=model, rng=rng, read_s=time.perf_counter() - t0, scheduler=scheduler
    )


def identify_log(
    cfg: IdentifyConfig,
    log: RobotLog,
    *,
    model: pin.Model | None = None,
    rng: int = 0,
    read_s: float = 0.0,
    scheduler: str | None = None,
) -> IdentifyResult:
    """Identify from a log already read and converted to joint-side SI signals.

    Everything after reading: what ``ident identify`` does to a file's log, and what ``ident
    run`` does to the log its simulator writes (so both give the same estimate from the same
    signals).

    The least-squares problems here are small (thousands of rows, tens of columns) and many
    (essential parameters); multi-threaded BLAS only adds synchronisation to them (35x slower
    measured on a loaded 2-core machine), so BLAS runs on one thread inside this call.

    Parameters
    ----------
    cfg :
        Validated config with absolute paths (:func:`~ident.identify.config.load_identify_config`);
        its ``log`` section is not read again.
    log :
        The converted log (:func:`~ident.identify.logs.read_log`).
    model :
        The robot's Pinocchio model (loaded from ``cfg.robot`` when not given).
    rng :
        Seed of the random states used to find the structural base parameters (the result does
        not depend on it beyond round-off).
    read_s :
        Seconds spent reading the log, for the timings.
    scheduler :
        A dask.distributed scheduler address for the chunks of a long log
        (:mod:`ident.identify.accumulate`).

    Raises
    ------
    IdentError
        Subclasses naming the file, column or parameter: bad config, rank deficiency.
    """
    with threadpool_limits(limits=1, user_api="blas"):
        return _identify_log(cfg, log, model=model, rng=rng, read_s=read_s, scheduler=scheduler)


def _identify_log(
    cfg: IdentifyConfig,
    log: RobotLog,
    *,
    model: pin.Model | None,
    rng: int,
    read_s: float,
    scheduler: str | None,
) -> IdentifyResult:
    timings: dict[str, float] = {"read": read_s}
    t0 = time.perf_counter() - read_s
    source = str(cfg.source or "config")
    if model is None:
        model = load_robot(cfg.robot, source=source).model
    joints = [model.names[i] for i in range(1, model.njoints)]
    if list(log.joint_names) != joints:
        raise DataError(
            f"{source}: the log's joints ({', '.join(log.joint_names)}) are not the robot's "
            f"({', '.join(joints)})."
        )
    ellipsoids: tuple = ()
    if cfg.estimation.ellipsoids:  # before any work: a missing geometry is a config error
        if cfg.robot.urdf is None:
            raise ConfigError(
                f"{source}: estimation.ellipsoids needs a URDF with link geometry "
                "(robot.urdf); a DH description has none. Set estimation.ellipsoids: false."
            )
        ellipsoids = bounding_ellipsoids(
            model, cfg.robot.urdf, package_dirs=cfg.robot.package_dirs, source=source
        )
    first = slice(*log.segments[0])  # automatic settings: from the first segment
    settings, auto_records, auto_warnings = preprocess.resolve_defaults(
        cfg.preprocess,
        log.q[first],
        log.sampling_rate_hz,
        None if log.dq is None else log.dq[first],
    )
    auto_warnings = [*log.warnings, *auto_warnings]  # what reading the log changed, first
    cfg = cfg.model_copy(update={"preprocess": settings})
    log = dataclasses.replace(log, records=(*log.records, *auto_records))
    if accumulate.use_chunks(log, cfg.preprocess, 10 * model.nv + 4 * model.nv):
        fields = accumulate.identify_chunked(
            cfg,
            log,
            model,
            joints,
            source=source,
            rng=rng,
            timings=timings,
            t0=t0,
            scheduler=scheduler,
            ellipsoids=ellipsoids,
        )
        fields["warnings"] = (*auto_warnings, *fields["warnings"])
        return IdentifyResult(**fields)
    records = list(log.records)
    fs = log.sampling_rate_hz
    q, tau = log.q, log.tau
    t = log.t

    t1 = time.perf_counter()
    pp = cfg.preprocess
    if pp.lowpass is not None:
        try:
            q, rec = preprocess.lowpass(q, fs, pp.lowpass.cutoff_hz, pp.lowpass.order, what="q")
        except ConfigError as e:
            raise ConfigError(f"{source}: preprocess.lowpass.{e}") from e
        records.append(rec)
    if pp.torque_lowpass is not None:
        try:
            tau, rec = preprocess.lowpass(
                tau, fs, pp.torque_lowpass.cutoff_hz, pp.torque_lowpass.order, what="tau"
            )
        except ConfigError as e:
            raise ConfigError(f"{source}: preprocess.torque_lowpass.{e}") from e
        records.append(rec)
    dq, ddq, rec = preprocess.differentiate(q, fs)
    records.append(rec)
    try:
        (q, dq, ddq, tau, t), rec = preprocess.trim([q, dq, ddq, tau, t], pp.trim_samples)
    except DataError as e:
        raise DataError(f"{source}: preprocess.{e}") from e
    records.append(rec)
    timings["preprocess"] = time.perf_counter() - t1

    t_motion = time.perf_counter()
    motion: JointTrajectory | None = None
    motion_note = ""
    try:  # the measured motion is for the replay: a failure must not stop the identification
        motion, rec = measured_motion(t, q, dq, ddq, tau, fs, tuple(joints))
        records.append(rec)
    except DataError as e:
        motion_note = f"measured motion not available: {e}"
    timings["motion"] = time.perf_counter() - t_motion

    t2 = time.perf_counter()
    try:
        terms = ExtraTerms.from_options(
            model.nv,
            rotor_inertia=cfg.model.rotor_inertia,
            viscous=cfg.model.viscous,
            coulomb=cfg.model.coulomb,
            offset=cfg.model.offset,
            coupled_wrist=cfg.model.coupled_wrist,
        )
    except ConfigError as e:
        raise ConfigError(f"{source}: {e}") from e
    pm = build_parameter_model(model, terms, rng=rng)
    base = pm.base
    timings["base_parameters"] = time.perf_counter() - t2

    t3 = time.perf_counter()

    Y_rigid, Y_extra = model_regressors(chain_from_model(model), terms, q, dq, ddq)
    reference = (
        read_reference(cfg.reference.base_parameters)
        if cfg.reference.base_parameters is not None
        else []
    )
    # Decimation is linear and acts on each column alike: decimate the regressors as they
    # come out of the kernel (no large gathers) and only the reference's predicted torques.
    bank = [tau, Y_rigid, Y_extra, dq]
    if reference:
        values = np.array([r.value(cfg.reference.column)[0] for r in reference])
        tau_ref, missing_ref = reference_prediction(
            pm, reference, values, Y_rigid, Y_extra, dq, ddq
        )
        bank.append(tau_ref)
    del Y_rigid, Y_extra
    timings["regressor"] = time.perf_counter() - t3

    t4 = time.perf_counter()
    try:
        bank, fs_dec, rec = preprocess.decimate(bank, pp.decimation, fs)
    except DataError as e:
        raise DataError(f"{source}: preprocess.{e}") from e
    records.append(rec)
    step = int(np.prod(pp.decimation)) if pp.decimation else 1
    t_dec = t[::step][: bank[0].shape[0]]
    tau_d, dq_d = bank[0], bank[3]
    Yb_d = pm.columns(bank[1], bank[2], base.independent)
    try:
        keep, rec = preprocess.velocity_mask(dq_d, pp.velocity_threshold)
    except ConfigError as e:
        raise ConfigError(f"{source}: {e}") from e
    records.append(rec)
    n_dec, nv = tau_d.shape
    ident_part, val_part = time_split(n_dec, cfg.validation.identify_fraction)
    records.append(
        {
            "step": "time split",
            "detail": f"identify on samples 0..{ident_part.stop - 1} "
            f"({t_dec[ident_part.stop - 1] if ident_part.stop else 0:.3f} s), validate on "
            f"{val_part.stop - val_part.start} later samples (errors reported on the rows "
            "above the velocity threshold, as identified, and on all samples)",
        }
    )
    timings["decimate"] = time.perf_counter() - t4

    t5 = time.perf_counter()
    keep_id = keep[ident_part]
    W_id = Yb_d[ident_part][keep_id]  # rows (sample, joint) kept, sample-major
    tau_id = tau_d[ident_part][keep_id]
    groups = np.broadcast_to(np.arange(nv), keep_id.shape)[keep_id]
    base_names = pm.base_names
    try:
        est = least_squares(
            W_id, tau_id, base_names, method=cfg.estimation.least_squares_method, groups=groups
        )
    except NotIdentifiable as e:
        idle = ", ".join(joints[j] for j in range(nv) if not keep_id[:, j].any())
        if not idle:
            raise NotIdentifiable(
                f"{source}: the log does not determine every base parameter: {e}"
            ) from e
        why = rank_report(W_id, base_names, advice="") or str(e)
        raise NotIdentifiable(
            f"{source}: the log does not determine every base parameter. No sample of {idle} "
            f"reaches its velocity threshold in the identification part (joint not moving?): "
            f"{why} Record a motion that moves {idle}, or lower its velocity threshold."
        ) from e
    except DataError as e:
        raise DataError(f"{source}: {e}") from e
    consistent = consistent_identification(
        model,
        pm,
        W_id,
        tau_id,
        groups,
        method=cfg.estimation.method,
        weight=cfg.estimation.regularization.weight,
        ellipsoids=ellipsoids,
        options={"friction": cfg.estimation.friction},
    )
    timings["estimate"] = time.perf_counter() - t5

    essential = None
    if cfg.estimation.essential.enabled:
        t6 = time.perf_counter()
        essential = essential_parameters(
            W_id,
            tau_id,
            base_names,
            method=cfg.estimation.least_squares_method,
            groups=groups,
            max_relative_std_pct=cfg.estimation.essential.max_relative_std_pct,
            max_residual_increase=cfg.estimation.essential.max_residual_increase,
        )
        timings["essential"] = time.perf_counter() - t6

    # held-out prediction (or in-sample when the whole log identifies)
    part = val_part if val_part.stop > val_part.start else ident_part
    tau_val = tau_d[part]
    keep_val = keep[part]
    predictions: dict[str, ModelPrediction] = {}

    def add(label: str, tau_pred: FloatArray) -> None:
        predictions[label] = ModelPrediction(
            label,
            prediction_metrics(tau_val, tau_pred, keep_val),
            prediction_metrics(tau_val, tau_pred),
            tau_pred,
        )

    add("identified", Yb_d[part] @ est.x)
    if consistent.constrained is not None:
        add(consistent.method, Yb_d[part] @ consistent.constrained.x)
    if essential is not None:
        add("essential", Yb_d[part][:, :, list(essential.kept)] @ essential.estimate.x)
    comparison: list[dict] = []
    note = ""
    if reference:
        add("reference", bank[4][part])
        comparison, note = compare_with_reference(pm, est, reference, cfg.reference.column)
        if missing_ref:
            note += f" Reference parameters without a column here: {', '.join(missing_ref)}."
    add("URDF nominal", Yb_d[part] @ base.project(pm.nominal))
    reference_essential: list[dict] = []
    if cfg.reference.essential_parameters is not None:
        rows, _ = compare_with_reference(
            pm, est, read_reference(cfg.reference.essential_parameters), cfg.reference.column
        )
        kept = set(essential.estimate.names) if essential is not None else set()
        for row in rows:
            ours = row["ours"]
            members = ours.split(" + ") if ours else []
            row["in_our_essential_set"] = bool(members) and all(m in kept for m in members)
            reference_essential.append(row)
    problems = held_out_warnings(
        predictions["identified"].metrics.total_relative_residual,
        predictions["URDF nominal"].metrics.total_relative_residual,
        max_relative_residual=cfg.validation.max_relative_residual,
        in_sample=part is ident_part,
        n_rows=int(W_id.shape[0]),
        n_params=len(base_names),
    )
    problems = [*auto_warnings, *problems]
    problems += sanity.result_warnings(
        joint_names=tuple(joints),
        units=sanity.joint_units(model),
        names=base_names,
        x=est.x,
        std=est.std,
        relative_std=est.relative_std,
        projection=base.projection,
        all_names=pm.names,
        column_norms=np.linalg.norm(W_id, axis=0),
        tau_norm=float(np.linalg.norm(tau_id)),
        tau_validate=tau_val,
        tau_pred=predictions["identified"].tau_pred,
        keep_validate=keep_val,
    )
    if consistent.constrained is None:  # a constrained estimate is consistent by construction
        ls_method = cfg.estimation.least_squares_method
        problems += sanity.inconsistency_warnings(consistent, ls_method)
    timings["total"] = time.perf_counter() - t0
    return IdentifyResult(
        config=cfg,
        log=log,
        records=tuple(records),
        parameters=pm,
        estimate=est,
        essential=essential,
        t_validate=t_dec[part],
        tau_validate=tau_val,
        keep_validate=keep_val,
        predictions=predictions,
        comparison=tuple(comparison),
        reference_note=note,
        joint_names=tuple(joints),
        sampling_rate_hz=fs_dec,
        n_identify_rows=int(W_id.shape[0]),
        timings=timings,
        reference_essential=tuple(reference_essential),
        motion=motion,
        motion_note=motion_note,
        warnings=tuple(problems),
        consistent=consistent,
    )
