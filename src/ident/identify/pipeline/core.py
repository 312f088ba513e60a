"""The identification core: measurements -> identified base parameters, one code path.

:func:`identify_measurements` is what every command runs on joint-side measurements, whatever
their source: a log read by :func:`ident.measure.logs.read_log` (a robot's, or the one
``ident run``'s MuJoCo simulator writes), or the measurements of ``ident run``'s ideal source
(:mod:`ident.run.elite_identification`: the stage's torques with the known bodies' subtracted,
the measured states used as they are, the stage's parameter model).

1. automatic preprocessing settings (:func:`ident.identify.estimation.preprocess.resolve_defaults`);
2. the parameter model (rigid bodies plus friction, offsets, rotor inertias, coupled wrist;
   structural base parameters, :func:`ident.dynamics.parameter_model.build_parameter_model`);
3. the accumulation (:mod:`ident.identify.estimation.accumulate`): low-pass, differentiate, trim,
   regressor, decimate, velocity threshold, split in time, rows reduced per joint; a whole
   segment is one chunk, a long log several (a size, not another implementation);
4. the estimators of the registry on the reduced rows (:mod:`ident.identify.estimators`:
   OLS and WLS once each, and the configured one with its
   :class:`~ident.identify.estimators.registry.Contract`), essential parameters;
5. validation: held-out prediction of the identified, essential, constrained, reference and
   URDF-nominal parameters (:mod:`ident.identify.estimation.validation`) and the warnings.

The identified model (``urdf_update.model: consistent``, the default) is a physically
consistent estimate of every link: the configured estimator's when its contract promises
consistency, else :data:`MODEL_METHOD`'s, computed beside on the same rows (``model``).

Nothing here writes files; :mod:`ident.report.identify_report` does.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.blas import one_blas_thread
from ident.dynamics.chain import chain_from_model
from ident.dynamics.parameter_model import ParameterModel, build_parameter_model
from ident.errors import ConfigError, DataError
from ident.identify.actuators.servo_fit import ServoFit
from ident.identify.assessment.identifiability import Identifiability, standard_identifiability
from ident.identify.assessment.model_intervals import ModelIntervals, model_intervals
from ident.identify.assessment.verdict import truth_from_config
from ident.identify.config import IdentifyConfig, PreprocessConfig
from ident.identify.estimation import accumulate, log_chunks, preprocess
from ident.identify.estimation.essential import EssentialResult
from ident.identify.estimation.estimate import Estimate
from ident.identify.estimation.motion import (
    DEFAULT_REPLAY_RATE_HZ,
    antialiased,
    decimation_factor,
    measured_motion,
)
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimation.reference import (
    ReferenceWeights,
    read_reference,
    reference_weights,
)
from ident.identify.estimation.uncertainty import (
    BlockEquations,
    ParameterStd,
    Uncertainty,
    coverage_summary,
    parameter_std,
    parameter_uncertainty,
)
from ident.identify.estimation.validation import (
    ModelPrediction,
    prediction_metrics,
)
from ident.identify.estimators import (
    ConsistentIdentification,
    bounding_ellipsoids,
)
from ident.identify.friction.friction_fit import (
    FrictionComparison,
    compare_friction_models,
    friction_rows,
    rest_parameters,
)
from ident.identify.friction.friction_law import WrittenFrictionLaw, written_friction_law
from ident.identify.pipeline.estimates import (
    all_warnings,
    essential_result,
    held_out_vectors,
    merged_rows,
    reference_comparisons,
    run_estimators,
)
from ident.identify.pipeline.records import preprocess_records, row_records
from ident.measure.logs import RobotLog
from ident.model.selection import load_robot
from ident.robot.mimic import reject_coupled_chain
from ident.signals import derivative
from ident.trajectory import JointTrajectory

__all__ = ["MODEL_METHOD", "IdentifyResult", "identify_measurements", "replay_motion"]

FloatArray = npt.NDArray[np.float64]

#: The estimator of the identified model when the configured one promises no consistency
#: (LMI, WLS-weighted, prior toward the URDF along the directions the log does not see).
MODEL_METHOD = "lmi"

#: Longest stretch of a log shown in the replay [s].
MOTION_MAX_S = 600.0


@dataclass(frozen=True, eq=False)
class IdentifyResult:
    """Everything the identify report needs (arrays SI, samples on axis 0).

    Attributes
    ----------
    config :
        The validated config (automatic preprocessing settings resolved).
    log :
        The converted log (before processing).
    records :
        Every processing step, in order.
    parameters :
        Parameter model (names, base parameters).
    estimate :
        Least-squares estimate of the base parameters on the identification rows
        (``estimation.least_squares_method``).
    essential :
        Essential-parameter reduction, or None when disabled.
    t_validate, tau_validate, keep_validate :
        Held-out time [s], measured torques [N*m] and velocity-threshold mask, shapes
        (n_val,), (n_val, nv), (n_val, nv).
    predictions :
        Held-out predictions by label (identified, essential, the configured estimator,
        reference, URDF nominal).
    comparison, reference_note, reference_essential :
        Rows comparing our values with the reference's, how it maps onto ours.
    timings :
        Seconds per stage.
    motion, motion_note :
        The measured motion (processed, decimated to <= 50 Hz) for ``trajectory.csv`` and the
        replay, or None with the reason in ``motion_note``.
    consistent :
        Every estimator's estimate and consistency, the configured one's contract
        (:class:`~ident.identify.estimators.ConsistentIdentification`).
    warnings :
        Plain-language problems with the result; empty when none.
    reduction :
        The identification rows reduced per joint (what every estimator used).
    model :
        The identification whose ``constrained`` estimate is the identified model (consistent
        standard parameters of every link): :attr:`consistent` itself when the configured
        estimator promises consistency, else :data:`MODEL_METHOD`'s; None with
        ``urdf_update.model: none``. Its held-out prediction is
        ``predictions[model.method]``.
    uncertainty :
        Covariances of the least-squares estimate robust to correlated residuals (HAC and
        block bootstrap, :mod:`ident.identify.estimation.uncertainty`), or None when the log has too
        few blocks for them.
    prediction_std :
        Per interval method (``"ordinary"``, ``"hac"``, ``"bootstrap"``), the standard
        deviation of every held-out torque about the identified prediction [N*m], shape
        (n_val, nv); empty without :attr:`uncertainty`.
    uncertainty_summary :
        :func:`~ident.identify.estimation.uncertainty.coverage_summary` of :attr:`uncertainty`
        (held-out coverage of the prediction intervals; coverage of ``validation.truth`` when set),
        or None.
    identifiability :
        Per standard parameter: alone, only in combination, or not seen
        (:mod:`ident.identify.assessment.identifiability`).
    friction :
        With ``model.friction`` other than ``viscous_coulomb``: the friction models fitted
        (that one, or every one for ``auto``) and ranked by held-out fit; else None.
    friction_law :
        The law the written model carries (:mod:`ident.identify.friction.friction_law`): the
        configured one, or ``auto``'s winner, when it is not ``viscous_coulomb`` and there is
        a model to write; else None.
    model_intervals :
        Bootstrap intervals of the written model's standard parameters
        (:mod:`ident.identify.assessment.model_intervals`, ``urdf_update.model_bootstrap``
        re-solves), or None (switched off, no model, too few blocks; ``model_intervals_note`` says
        why when it failed).
    actuator :
        The position servos' fit (``actuator.kind: position``: gains, ``kd + fv``, delay,
        saturation; :mod:`ident.identify.actuators.servo_fit`), or None (torque logged).
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
    reduction: ReducedObservations | None = None
    model: ConsistentIdentification | None = None
    uncertainty: Uncertainty | None = None
    prediction_std: dict[str, FloatArray] = field(default_factory=dict)
    uncertainty_summary: dict | None = None
    identifiability: Identifiability | None = None
    friction: FrictionComparison | None = None
    friction_law: WrittenFrictionLaw | None = None
    model_intervals: ModelIntervals | None = None
    model_intervals_note: str = ""
    actuator: ServoFit | None = None

    @property
    def status(self) -> str:
        """``"ok"``, or ``"warning"`` when :attr:`warnings` is not empty."""
        return "warning" if self.warnings else "ok"

    @property
    def parameter_std(self) -> ParameterStd:
        """The standard deviation of :attr:`estimate` every consumer reads: the default
        interval method's, or the ordinary one when the log has too few blocks for it
        (:func:`ident.identify.estimation.uncertainty.parameter_std`)."""
        return parameter_std(self.estimate, self.uncertainty)


def identify_measurements(
    cfg: IdentifyConfig,
    log: RobotLog,
    *,
    model: pin.Model | None = None,
    parameters: ParameterModel | None = None,
    rng: int = 0,
    read_s: float = 0.0,
    scheduler: str | None = None,
) -> IdentifyResult:
    """Identify the base parameters from joint-side measurements (module docstring).

    The one function behind ``ident identify`` (whole log or by chunks) and the
    identification of ``ident run``. BLAS runs on one thread inside (the least-squares
    problems are small and many; threads only add synchronisation).

    Parameters
    ----------
    cfg :
        Validated config with absolute paths
        (:func:`~ident.identify.config.load_identify_config`); its ``log`` section is not read.
    log :
        The measurements, joint side, SI, uniform time grid per segment.
    model :
        The robot's Pinocchio model (loaded from ``cfg.robot`` when not given).
    parameters :
        The parameter model, or None to build it from ``cfg.model``
        (:func:`~ident.dynamics.parameter_model.build_parameter_model`); ``ident run``'s
        ideal source gives its stage's
        (:func:`~ident.dynamics.parameter_model.stage_parameter_model`).
    rng :
        Seed of the random states of the structural base parameters.
    read_s :
        Seconds spent reading the log, for the timings.
    scheduler :
        A dask.distributed scheduler address for the chunks, or None (this process).

    Raises
    ------
    IdentError
        Subclasses naming the file, field or parameter: bad config, rank deficiency.
    """
    with one_blas_thread():
        return _identify(cfg, log, model, parameters, rng=rng, read_s=read_s, scheduler=scheduler)


def _identify(
    cfg: IdentifyConfig,
    log: RobotLog,
    model: pin.Model | None,
    parameters: ParameterModel | None,
    *,
    rng: int,
    read_s: float,
    scheduler: str | None,
) -> IdentifyResult:
    timings: dict[str, float] = {"read": read_s}
    t0 = time.perf_counter() - read_s
    source = str(cfg.source or "config")
    cfg, log, model, joints, ellipsoids, auto_warnings, processing = _checked_inputs(
        cfg, log, model, source
    )
    log_chunks.release_free_memory()  # the spectra's temporaries (automatic settings)
    with _timed(timings, "base_parameters"):
        pm = parameters if parameters is not None else _parameter_model(cfg, model, source, rng)
    with _timed(timings, "accumulate"):
        reference = _reference(cfg, pm)
        chunked, first, last, red = _accumulate(cfg, log, model, pm, reference, scheduler)
    records = [*processing, log_chunks.chunk_record(chunked, red), *row_records(cfg, chunked, red)]
    with _timed(timings, "estimate"):
        cons = run_estimators(cfg, model, pm, first, last, red, ellipsoids, joints, source)
        est = cons.estimates[cfg.estimation.least_squares_method]
        identified_model = _model_identification(cfg, cons, model, pm, first, last, red, joints)
    with _timed(timings, "essential"):
        essential = essential_result(cfg, red, pm)
    with _timed(timings, "validate"):
        held_out = _held_out(chunked, pm, (est, essential, cons, identified_model), scheduler)
    extras = _timed_extras(
        timings, cfg, log, chunked, pm, (est, identified_model), joints, scheduler
    )
    comparison, note, reference_essential = reference_comparisons(
        cfg, pm, (est, parameter_std(est, extras["uncertainty"])), essential, reference
    )
    judged = _judged(cfg, model, pm, (est, cons), (chunked, red), held_out, extras, auto_warnings)
    timings["total"] = time.perf_counter() - t0
    return IdentifyResult(
        config=cfg,
        log=log,
        records=tuple(records),
        parameters=pm,
        estimate=est,
        essential=essential,
        comparison=tuple(comparison),
        reference_note=note,
        joint_names=tuple(joints),
        sampling_rate_hz=log.sampling_rate_hz / preprocess.decimation_step(cfg.preprocess),
        n_identify_rows=int(red.n_rows.sum()),
        timings=timings,
        reference_essential=tuple(reference_essential),
        consistent=cons,
        reduction=red,
        model=identified_model,
        **held_out,
        **extras,
        **judged,
    )


def _checked_inputs(
    cfg: IdentifyConfig, log: RobotLog, model: pin.Model | None, source: str
) -> tuple[IdentifyConfig, RobotLog, pin.Model, list[str], tuple, list[str], list[dict]]:
    """Everything checked before any chunk is computed: ``(cfg, log, model, joints, ellipsoids,
    warnings, records)``, the config and the log with their ``auto`` preprocessing settings
    resolved, the robot's model (loaded from ``cfg.robot`` when ``model`` is None), its joint
    names (the log's), the links' bounding ellipsoids when asked, the warnings of reading the log
    and of the automatic settings, and the records of the processing (which check its settings:
    cutoff below Nyquist...)."""
    model = model if model is not None else load_robot(cfg.robot, source=source).model
    joints = _check_joints(log, model, source)
    ellipsoids = _ellipsoids(cfg, model, source)
    cfg, log, auto_warnings = _resolve_settings(cfg, log)
    processing = [
        *log.records,
        *preprocess_records(
            cfg.preprocess, log.sampling_rate_hz, model.nv, source, states=log.ddq is not None
        ),
    ]
    return cfg, log, model, joints, ellipsoids, auto_warnings, processing


def _judged(
    cfg: IdentifyConfig,
    model: pin.Model,
    pm: ParameterModel,
    fits: tuple[Estimate, ConsistentIdentification],
    rows: tuple[log_chunks.ChunkedLog, ReducedObservations],
    held_out: dict[str, Any],
    extras: dict[str, Any],
    auto_warnings: list[str],
) -> dict[str, Any]:
    """The coverage of the intervals (``uncertainty_summary``) and every warning (``warnings``:
    ``auto_warnings``, the estimates', then the friction models' ``extras["friction_problem"]``,
    which is taken out of ``extras``), as :class:`IdentifyResult` fields.

    ``fits`` is the least-squares estimate and every estimator's identification, ``rows`` the
    chunked log and its reduced identification rows, ``held_out`` what :func:`_held_out` returned,
    ``extras`` what :func:`_timed_extras` returned."""
    est, cons = fits
    chunked, red = rows
    tau_val, keep_val = held_out["tau_validate"], held_out["keep_validate"]
    predictions = held_out["predictions"]
    residual = tau_val - predictions["identified"].tau_pred
    summary = _uncertainty_summary(
        cfg, extras["uncertainty"], extras["prediction_std"], residual, keep_val
    )
    fit = (est, extras["uncertainty"])  # the warnings read its one σ
    problems = [
        *auto_warnings,
        *all_warnings(cfg, model, pm, fit, cons, red, chunked, predictions, (tau_val, keep_val)),
        *extras.pop("friction_problem"),
    ]
    return {"uncertainty_summary": summary, "warnings": tuple(problems)}


def _timed_extras(
    timings: dict[str, float],
    cfg: IdentifyConfig,
    log: RobotLog,
    chunked: log_chunks.ChunkedLog,
    pm: ParameterModel,
    fits: tuple[Estimate, ConsistentIdentification | None],
    joints: list[str],
    scheduler: str | None,
) -> dict[str, Any]:
    """The robust intervals (of the least-squares estimate and of the written model ``fits``),
    the friction-model comparison, the replay motion and what the data cannot see, timed:
    :class:`IdentifyResult` fields, plus ``friction_problem`` (warnings)."""
    est, identified_model = fits
    out: dict[str, Any] = {"identifiability": _identifiability(pm)}
    with _timed(timings, "uncertainty"):
        out["uncertainty"], blocks = _uncertainty(chunked, est, scheduler)
    n_boot = cfg.urdf_update.model_bootstrap
    if identified_model is not None and out["uncertainty"] is not None and n_boot > 0:
        if not _same_weights(est, identified_model):
            blocks = None  # freed before the written model's own blocks are built
        with _timed(timings, "model_intervals"):
            out["model_intervals"], out["model_intervals_note"] = _model_intervals(
                chunked, (est, identified_model), out["uncertainty"], blocks, n_boot, scheduler
            )
    # 53 MB for 57 parameters: freed before the pass over the held-out chunks below, whose
    # chunks in flight would otherwise come on top of them
    del blocks
    with _timed(timings, "uncertainty"):
        out["prediction_std"] = _prediction_std(chunked, est, out["uncertainty"], scheduler)
    with _timed(timings, "friction_models"):
        out["friction"], out["friction_law"], out["friction_problem"] = _friction_models(
            cfg, chunked, pm, identified_model, tuple(joints)
        )
    if cfg.model.friction == "viscous_coulomb":
        del timings["friction_models"]
    log_chunks.release_free_memory()
    with _timed(timings, "motion"):
        out["motion"], out["motion_note"] = replay_motion(log, cfg.preprocess, tuple(joints))
    return out


def _identifiability(pm: ParameterModel) -> Identifiability:
    """Which standard parameters the base parameters see alone, in combination, or not."""
    return standard_identifiability(
        pm.base.projection, pm.names, pm.base_names, pm.base.expressions()
    )


@contextmanager
def _timed(timings: dict[str, float], key: str) -> Iterator[None]:
    """Add the seconds the block takes to ``timings[key]``."""
    start = time.perf_counter()
    try:
        yield
    finally:
        timings[key] = timings.get(key, 0.0) + time.perf_counter() - start


def _friction_models(
    cfg: IdentifyConfig,
    chunked: log_chunks.ChunkedLog,
    pm: ParameterModel,
    written: ConsistentIdentification | None,
    joints: tuple[str, ...],
) -> tuple[FrictionComparison | None, WrittenFrictionLaw | None, list[str]]:
    """The friction models of ``model.friction`` fitted and ranked (None for the default), and
    the law the written model carries (the configured one or the winner, when it is not
    ``viscous_coulomb`` and ``written`` has a consistent estimate), or None and the reason as
    a warning: the identification is kept whatever happens here."""
    name = cfg.model.friction
    if name == "viscous_coulomb":
        return None, None, []
    try:
        fit_rows, held_out = friction_rows(chunked, pm)
        names = None if name == "auto" else [name]
        comparison = compare_friction_models(fit_rows, held_out, names)
    except DataError as e:
        return None, None, [f"model.friction = {name}: the friction models were not fitted ({e})"]
    chosen = comparison.winner if name == "auto" else name
    ambiguous = "" if name == "auto" else comparison.fit(name).ambiguous
    problems = [f"model.friction = {name}: its fit is ambiguous, {ambiguous}"] if ambiguous else []
    consistent = None if written is None else written.constrained
    if chosen == comparison.baseline or consistent is None or not consistent.success:
        return comparison, None, problems
    rest = rest_parameters(chunked, pm, consistent.x)
    law = written_friction_law(comparison.fit(chosen), fit_rows, held_out, rest, joints)
    return comparison, law, problems


def _accumulate(
    cfg: IdentifyConfig,
    log: RobotLog,
    model: pin.Model,
    pm: ParameterModel,
    reference: ReferenceWeights | None,
    scheduler: str | None,
) -> tuple[
    log_chunks.ChunkedLog,
    ReducedObservations | None,
    ReducedObservations | None,
    ReducedObservations,
]:
    """The log cut in chunks and its identification rows reduced: ``(chunked, first, last,
    merged)`` (:func:`ident.identify.estimation.log_chunks.reduce_log`)."""
    columns = accumulate.BaseColumns(chain_from_model(model), pm, reference)
    chunked = log_chunks.plan_log(
        log,
        cfg.preprocess,
        columns,
        identify_fraction=cfg.validation.identify_fraction,
        chunk_samples=log_chunks.segment_chunk_samples(log, cfg.preprocess, len(pm.base_names)),
    )
    first, last = log_chunks.reduce_log(chunked, scheduler)
    return chunked, first, last, merged_rows(first, last)


def _held_out(
    chunked: log_chunks.ChunkedLog,
    pm: ParameterModel,
    fits: tuple[
        Estimate, EssentialResult | None, ConsistentIdentification, ConsistentIdentification | None
    ],
    scheduler: str | None,
) -> dict[str, Any]:
    """The held-out prediction of every vector of ``fits`` (the least-squares estimate, the
    essential parameters, every estimator's identification and the identified model's,
    :func:`~ident.identify.pipeline.estimates.held_out_vectors`), as :class:`IdentifyResult`
    fields: the held-out time [s] and torques [N*m] with their mask, shapes (n_val,),
    (n_val, nv), (n_val, nv), and every prediction with its metrics."""
    est, essential, cons, identified_model = fits
    vectors = held_out_vectors(est, essential, cons, pm, identified_model)
    tau_val, keep_val, tau_pred = log_chunks.predict_log(chunked, vectors, scheduler)
    predictions = {
        label: ModelPrediction(
            label,
            prediction_metrics(tau_val, pred, keep_val),
            prediction_metrics(tau_val, pred),
            pred,
        )
        for label, pred in tau_pred.items()
    }
    return {
        "t_validate": chunked.t_validate,
        "tau_validate": tau_val,
        "keep_validate": keep_val,
        "predictions": predictions,
    }


def _uncertainty(
    chunked: log_chunks.ChunkedLog, est: Estimate, scheduler: str | None
) -> tuple[Uncertainty | None, BlockEquations | None]:
    """HAC and block-bootstrap covariances of ``est`` and the block equations (none when the
    log has too few blocks)."""
    try:
        blocks = log_chunks.block_equations(chunked, _row_weights(est), scheduler)
        unc = parameter_uncertainty(blocks, est.names, est.x, est.covariance, rng=0)
    except (DataError, np.linalg.LinAlgError):
        return None, None
    return unc, blocks


def _row_weights(est: Estimate) -> FloatArray:
    """Per-joint row weights ``1 / sigma`` of ``est`` (0 where sigma is not positive)."""
    sigma = np.asarray(est.sigma, dtype=float)
    return np.where(np.isfinite(sigma) & (sigma > 0), 1.0 / sigma, 0.0)


def _same_weights(est: Estimate, identified: ConsistentIdentification) -> bool:
    """Whether the written model's fit weighs the rows as the least-squares ``est`` does (its
    bootstrap then reuses the block equations of :func:`_uncertainty`)."""
    weights, ls_weights = np.asarray(identified.problem.weights, dtype=float), _row_weights(est)
    if weights.shape != ls_weights.shape:
        return False
    return bool(np.allclose(weights, ls_weights, rtol=1e-12, atol=0.0))


def _prediction_std(
    chunked: log_chunks.ChunkedLog,
    est: Estimate,
    unc: Uncertainty | None,
    scheduler: str | None,
) -> dict[str, FloatArray]:
    """The held-out prediction standard deviations of every interval method of ``unc``
    (none without intervals)."""
    if unc is None:
        return {}
    return log_chunks.prediction_std_log(
        chunked, unc.covariance, np.nan_to_num(est.residual_rms), scheduler
    )


def _model_intervals(
    chunked: log_chunks.ChunkedLog,
    fits: tuple[Estimate, ConsistentIdentification],
    unc: Uncertainty,
    blocks: BlockEquations | None,
    n_boot: int,
    scheduler: str | None,
) -> tuple[ModelIntervals | None, str]:
    """The bootstrap of the written model's constrained fit
    (:mod:`ident.identify.assessment.model_intervals`) with the base parameters' bootstrap run
    length; the blocks are rebuilt when the model's row weights are not those of the least-squares
    estimate (the first of ``fits``). None and the reason when it fails: the identification is
    kept."""
    est, identified = fits
    weights = np.asarray(identified.problem.weights, dtype=float)
    try:
        if blocks is None or not _same_weights(est, identified):
            blocks = log_chunks.block_equations(chunked, weights, scheduler)
        length = int(np.ceil(unc.bandwidth))
        return model_intervals(identified, blocks, length, n_boot=n_boot, rng=1), ""
    except (DataError, np.linalg.LinAlgError, ValueError) as e:
        return None, f"no intervals on the written model: {e}"


def _uncertainty_summary(
    cfg: IdentifyConfig,
    unc: Uncertainty | None,
    pred_std: dict[str, FloatArray],
    residual: FloatArray,
    keep: npt.NDArray[np.bool_],
) -> dict | None:
    """Coverage of the prediction intervals on the held-out rows, and of the true base
    parameters when ``validation.truth`` gives them in the estimate's order."""
    if unc is None:
        return None
    truth = truth_from_config(cfg.validation.truth)
    values = truth.values if truth is not None and truth.names == unc.names else None
    return coverage_summary(unc, truth=values, held_out=(residual, pred_std, keep))


def _check_joints(log: RobotLog, model: pin.Model, source: str) -> list[str]:
    reject_coupled_chain(model, "identification", source)
    joints = [str(model.names[i]) for i in range(1, model.njoints)]
    if list(log.joint_names) != joints:
        raise DataError(
            f"{source}: the log's joints ({', '.join(log.joint_names)}) are not the robot's "
            f"({', '.join(joints)})."
        )
    return joints


def _ellipsoids(cfg: IdentifyConfig, model: pin.Model, source: str) -> tuple:
    """The links' bounding ellipsoids when asked (before any work: a missing geometry is a
    config error), else ``()``."""
    if not cfg.estimation.ellipsoids:
        return ()
    if cfg.robot.urdf is None:
        raise ConfigError(
            f"{source}: estimation.ellipsoids needs a URDF with link geometry "
            "(robot.urdf); a DH description has none. Set estimation.ellipsoids: false."
        )
    return tuple(
        bounding_ellipsoids(
            model, cfg.robot.urdf, package_dirs=cfg.robot.package_dirs, source=source
        )
    )


def _resolve_settings(
    cfg: IdentifyConfig, log: RobotLog
) -> tuple[IdentifyConfig, RobotLog, list[str]]:
    """``auto`` preprocessing settings chosen on the first segment, their records and
    warnings."""
    settings, records, warnings = preprocess.resolve_for_log(cfg.preprocess, log)
    cfg = cfg.model_copy(update={"preprocess": settings})
    log = dataclasses.replace(log, records=(*log.records, *records))
    return cfg, log, [*log.warnings, *warnings]  # what reading the log changed, first


def _parameter_model(
    cfg: IdentifyConfig, model: pin.Model, source: str, rng: int
) -> ParameterModel:
    terms = cfg.model.extra_terms(model.nv, source)
    return build_parameter_model(model, terms, rng=rng)


def _reference(cfg: IdentifyConfig, pm: ParameterModel) -> ReferenceWeights | None:
    """The reference's base parameters as column weights, or None without a reference."""
    if cfg.reference.base_parameters is None:
        return None
    reference = read_reference(cfg.reference.base_parameters)
    values = np.array([r.value(cfg.reference.column)[0] for r in reference])
    return reference_weights(pm, reference, values)


def _model_identification(
    cfg: IdentifyConfig,
    cons: ConsistentIdentification,
    model: pin.Model,
    pm: ParameterModel,
    first: ReducedObservations | None,
    last: ReducedObservations | None,
    red: ReducedObservations,
    joints: list[str],
) -> ConsistentIdentification | None:
    """The identification of the identified model (:attr:`IdentifyResult.model`): ``cons``
    when its estimator promises consistency, else :data:`MODEL_METHOD` on the same rows; None
    with ``urdf_update.model: none``."""
    if cfg.urdf_update.model == "none":
        return None
    if cons.contract.consistent:
        return cons
    source = str(cfg.source or "config")
    return run_estimators(cfg, model, pm, first, last, red, (), joints, source, method=MODEL_METHOD)


def replay_motion(
    log: RobotLog, pp: PreprocessConfig, joints: tuple[str, ...]
) -> tuple[JointTrajectory | None, str]:
    """The measured motion of the replay: every segment of the log, one after another (at most
    :data:`MOTION_MAX_S` in all), each low-passed, differentiated and trimmed as the
    identification does; or None and the reason. The segments keep their time stamps (the
    gaps between them), so the replay shows them one after another
    (:func:`ident.viz.replay.replay_segments`); a segment too short to filter is left out."""
    fs = log.sampling_rate_hz
    budget = int(MOTION_MAX_S * fs)
    parts: list[JointTrajectory] = []
    problem = "no samples"
    for a, b in log.segments:
        b = min(b, a + budget)
        if b <= a:
            break
        try:
            motion = _segment_motion(log, (a, b), pp, joints)
        except (DataError, ConfigError) as e:
            problem = str(e)
            continue
        budget -= b - a
        parts.append(motion)
    if not parts:
        return None, f"measured motion not available: {problem}"
    if len(parts) == 1:
        return parts[0], ""
    return JointTrajectory(
        t=np.concatenate([m.t for m in parts]),
        q=np.vstack([m.q for m in parts]),
        dq=np.vstack([m.dq for m in parts]),
        ddq=np.vstack([m.ddq for m in parts]),
        joint_names=joints,
        tau=np.vstack([m.tau for m in parts if m.tau is not None]),
    ), ""


def _segment_motion(
    log: RobotLog, samples: tuple[int, int], pp: PreprocessConfig, joints: tuple[str, ...]
) -> JointTrajectory:
    """The measured motion of the log's samples ``[a, b)`` (:func:`replay_motion`), each
    signal decimated for the replay (:func:`ident.identify.estimation.motion.antialiased`) as soon
    as it is computed and freed before the next (10 minutes at 1 kHz of 7 joints: 34 MB a signal;
    ``dq`` and ``ddq`` are the identification's central differences, one at a time).

    Raises
    ------
    DataError, ConfigError
        A segment too short to filter, differentiate or trim.
    """
    a, b = samples
    fs = log.sampling_rate_hz
    q, tau = log.q[a:b], log.tau[a:b]
    position = preprocess.position_filter(pp)
    if position is not None:
        q, _ = preprocess.lowpass(q, fs, position.cutoff_hz, position.order)
    if pp.torque_lowpass is not None:
        tau, _ = preprocess.lowpass(
            tau, fs, pp.torque_lowpass.cutoff_hz, pp.torque_lowpass.order, what="tau"
        )
    preprocess.check_differentiable(q.shape[0])
    (t,), _ = preprocess.trim([log.t[a:b]], pp.trim_samples)

    def replayed(x: FloatArray) -> FloatArray:
        (kept,), _ = preprocess.trim([x], pp.trim_samples)
        return antialiased(kept, fs)

    q_r = replayed(q)
    dq = derivative(q, fs)
    del q
    dq_r = replayed(dq)
    ddq = derivative(dq, fs)
    del dq
    ddq_r = replayed(ddq)
    del ddq
    factor = decimation_factor(fs, DEFAULT_REPLAY_RATE_HZ)
    # already at the replay's rate: measured_motion only assembles the trajectory
    motion, _ = measured_motion(t[::factor], q_r, dq_r, ddq_r, replayed(tau), fs / factor, joints)
    return motion
