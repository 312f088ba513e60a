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

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.base_parameters import BaseParameters
from ident.dynamics.chain import KinematicChain
from ident.dynamics.friction import (
    KINDS,
    ExtraTerms,
    extra_columns,
    extra_names,
    figaroh_coupling_columns,
)
from ident.errors import ConfigError, DataError, ModelError, NotIdentifiable
from ident.identify import preprocess
from ident.identify.config import IdentifyConfig
from ident.identify.essential import EssentialResult, essential_parameters
from ident.identify.estimate import Estimate, least_squares, rank_report
from ident.identify.logs import RobotLog, read_log
from ident.identify.motion import measured_motion
from ident.identify.reference import ReferenceParameter, expression_to_vector, read_reference
from ident.identify.validation import (
    PredictionMetrics,
    held_out_warnings,
    prediction_metrics,
    time_split,
)
from ident.trajectory import JointTrajectory

__all__ = [
    "PRIORITY_LABELS",
    "IdentifyResult",
    "ParameterModel",
    "build_parameter_model",
    "identify",
    "load_robot_model",
]

FloatArray = npt.NDArray[np.float64]

# Per-joint priority of the sequential base-parameter choice (figaroh's column order).
PRIORITY_LABELS = ("Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz", "mcx", "mcy", "mcz", "m")
_N_RANDOM_STATES = 200  # random states for the structural base parameters
# Relative rank tolerance of the structural base parameters. URDFs give angles to ~11 digits
# (rpy="-1.57079632679"), so axes meant to be orthogonal are off by ~5e-12 and machine-precision
# tolerances would call, e.g., Izz2 and Ia2 separately identifiable; 1e-6 is far above that
# round-off and far below any physical effect.
_BASE_RTOL = 1e-6


def load_robot_model(urdf: str | Path) -> pin.Model:
    """Load a fixed-base serial URDF with Pinocchio.

    Raises
    ------
    ModelError
        If the URDF cannot be parsed or is not a chain of 1-DoF joints.
    """
    from ident.inputs import read_urdf_text

    read_urdf_text(urdf)  # UTF-8 text without a DTD: Pinocchio and the write-back agree
    try:
        model = pin.buildModelFromUrdf(str(urdf))
    except (RuntimeError, ValueError) as e:
        raise ModelError(f"{urdf}: cannot load the URDF ({e}).") from e
    if model.nq != model.nv or model.nv != model.njoints - 1:
        raise ModelError(
            f"{urdf}: only chains of revolute/prismatic joints are supported "
            f"(nq={model.nq}, nv={model.nv}, joints={model.njoints - 1})."
        )
    return model


@dataclass(frozen=True, eq=False)
class ParameterModel:
    """All parameters of the identification model and its base parameters.

    Attributes
    ----------
    names :
        Every parameter in priority order (see module docstring), length n_all.
    inertial_index :
        For each name, its column in the rigid-body regressor (Pinocchio order), or -1.
    extra_index :
        For each name, its column in :func:`~ident.dynamics.friction.extra_columns`, or -1.
    terms :
        The extra terms.
    base :
        :class:`~ident.dynamics.base_parameters.BaseParameters` over ``names``.
    nominal :
        Nominal values of ``names`` (URDF inertias, zero friction), shape (n_all,).
    """

    names: tuple[str, ...]
    inertial_index: npt.NDArray[np.intp]
    extra_index: npt.NDArray[np.intp]
    terms: ExtraTerms
    base: BaseParameters
    nominal: FloatArray

    @property
    def base_names(self) -> tuple[str, ...]:
        """Names of the base parameters (independent name, ``R`` suffix when regrouped)."""
        return self.base.base_names

    def columns(self, Y_rigid: FloatArray, Y_extra: FloatArray, index: npt.ArrayLike) -> FloatArray:
        """Regressor columns of the parameters ``index`` (into :attr:`names`).

        ``Y_rigid`` (n, nv, 10 n) and ``Y_extra`` (n, nv, n_extra) -> (n, nv, len(index)).
        """
        return _gather_columns(self.inertial_index, self.extra_index, Y_rigid, Y_extra, index)


def _gather_columns(
    inertial_index: npt.NDArray[np.intp],
    extra_index: npt.NDArray[np.intp],
    Y_rigid: FloatArray,
    Y_extra: FloatArray,
    index: npt.ArrayLike,
) -> FloatArray:
    """Columns ``index`` of the parameter list from the rigid-body and extra regressors."""
    index = np.asarray(index, dtype=np.intp)
    out = np.empty((*Y_rigid.shape[:2], index.size))
    rigid = inertial_index[index] >= 0
    out[:, :, rigid] = Y_rigid[:, :, inertial_index[index[rigid]]]
    out[:, :, ~rigid] = Y_extra[:, :, extra_index[index[~rigid]]]
    return out


def _regressors(
    chain: KinematicChain, terms: ExtraTerms, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> tuple[FloatArray, FloatArray]:
    from ident.dynamics.regressor import joint_torque_regressor

    return joint_torque_regressor(chain, q, dq, ddq), extra_columns(terms, dq, ddq)


def build_parameter_model(model: pin.Model, terms: ExtraTerms, *, rng: int = 0) -> ParameterModel:
    """Name, order and reduce to base parameters every parameter of the model.

    Parameters
    ----------
    model :
        Pinocchio model.
    terms :
        Extra (friction, offset, rotor, coupling) terms.
    rng :
        Seed of the random states used to find the structural base parameters.
    """
    from ident.dynamics.base_parameters import compute_base_parameters
    from ident.dynamics.chain import chain_from_model, random_states
    from ident.dynamics.parameters import parameter_names, parameters_from_model

    n = model.nv
    chain = chain_from_model(model)
    rigid_names = parameter_names(n)
    extras = extra_names(terms)
    names: list[str] = []
    for j in range(1, n + 1):
        names += [f"{label}{j}" for label in PRIORITY_LABELS]
        names += [f"{kind}{j}" for kind in KINDS if j - 1 in terms.per_joint[kind]]
    names += [e for e in extras if e.startswith(("Iam", "fvm", "fsm"))]
    inertial_index = np.array(
        [rigid_names.index(nm) if nm in rigid_names else -1 for nm in names], dtype=np.intp
    )
    extra_index = np.array(
        [extras.index(nm) if nm in extras else -1 for nm in names], dtype=np.intp
    )
    q, dq, ddq = random_states(chain, _N_RANDOM_STATES, rng=rng)
    Y_rigid, Y_extra = _regressors(chain, terms, q, dq, ddq)
    W = _gather_columns(
        inertial_index, extra_index, Y_rigid, Y_extra, np.arange(len(names))
    ).reshape(-1, len(names))
    base = compute_base_parameters(W, names, method="sequential", rtol=_BASE_RTOL)
    rigid_nominal = parameters_from_model(model)
    nominal = np.where(inertial_index >= 0, rigid_nominal[np.maximum(inertial_index, 0)], 0.0)
    return ParameterModel(
        names=tuple(names),
        inertial_index=inertial_index,
        extra_index=extra_index,
        terms=terms,
        base=base,
        nominal=nominal,
    )


@dataclass(frozen=True, eq=False)
class ModelPrediction:
    """A parameter set judged on the held-out part."""

    label: str
    metrics: PredictionMetrics  # rows above the velocity threshold (as identified)
    metrics_all: PredictionMetrics  # every held-out sample, standstill included
    tau_pred: FloatArray


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

    @property
    def status(self) -> str:
        """``"ok"``, or ``"warning"`` when :attr:`warnings` is not empty."""
        return "warning" if self.warnings else "ok"


def _coupling_convention_map(pm: ParameterModel) -> dict[str, list[str]]:
    """Our parameters summing to a reference (figaroh-basis) parameter of the coupled wrist."""
    pair = pm.terms.coupled_wrist
    if pair is None:
        return {}
    a, b = (j + 1 for j in pair)
    out = {}
    for kind, motor in (("fv", f"fvm{b}"), ("Ia", f"Iam{b}")):
        for j in (a, b):
            if f"{kind}{j}" in pm.names:
                out[f"{kind}{j}"] = [f"{kind}{j}", motor]
    return out


def _compare_with_reference(
    pm: ParameterModel, est: Estimate, reference: list[ReferenceParameter], column: str
) -> tuple[list[dict], str]:
    """Match reference base parameters to ours: same expression, or a documented sum."""
    base = pm.base
    projection = base.projection
    base_names = pm.base_names
    coupled = _coupling_convention_map(pm)
    rows = []
    for ref in reference:
        vector = expression_to_vector(ref.terms, pm.names)
        ref_value, ref_rel = ref.value(column)
        row = {
            "reference": ref.expression,
            "reference_value": ref_value,
            "reference_relative_std_pct": ref_rel,
            "ours": None,
            "value": None,
            "relative_std_pct": None,
            "match": "none",
            "nominal": None,
        }
        if ref.lead in coupled:
            members = [base_names.index(n) for n in coupled[ref.lead] if n in base_names]
            if len(members) == len(coupled[ref.lead]):
                weights = np.zeros(len(base_names))
                weights[members] = 1.0
                value = float(weights @ est.x)
                std = float(np.sqrt(weights @ est.covariance @ weights))
                row.update(
                    ours=" + ".join(coupled[ref.lead]),
                    value=value,
                    relative_std_pct=100.0 * std / abs(value) if value else float("inf"),
                    match="coupling basis",
                )
        elif vector is not None:
            for k in range(projection.shape[0]):
                scale = np.max(np.abs(projection[k]))
                if np.allclose(projection[k], vector, atol=2e-4 * max(scale, 1.0), rtol=1e-3):
                    row.update(
                        ours=base_names[k],
                        value=float(est.x[k]),
                        relative_std_pct=float(est.relative_std[k]),
                        match="same expression",
                        nominal=float(projection[k] @ pm.nominal),
                    )
                    break
        rows.append(row)
    note = (
        f"Reference values: the '{column}' column. Values are compared where the reference "
        "expression equals one of our base parameters (coefficients within 2e-4, the "
        "reference prints 4-5 digits). The coupled wrist uses another basis in the reference "
        "(see ident.dynamics.friction): its fv/Ia of the wrist joints equal our sums "
        "'fv_j + fvm', 'Ia_j + Iam'."
    )
    return rows, note


def _reference_prediction(
    pm: ParameterModel,
    reference: list[ReferenceParameter],
    values: FloatArray,
    Y_rigid: FloatArray,
    Y_extra: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
) -> tuple[FloatArray, list[str]]:
    """Torques [N*m] (n, nv) predicted by the reference's base parameters ``values``.

    The reference's base parameter ``k`` multiplies the column of its first (independent)
    term; the coupled-wrist terms use the reference's own basis
    (:func:`~ident.dynamics.friction.figaroh_coupling_columns`). Also returns the reference
    parameters that have no column here (they contribute nothing).
    """
    index = {n: i for i, n in enumerate(pm.names)}
    wrist = ("Iam", "fvm", "fsm")
    weights_rigid = np.zeros(Y_rigid.shape[2])
    weights_extra = np.zeros(Y_extra.shape[2])
    weights_wrist = np.zeros(3)
    missing = []
    for ref, value in zip(reference, values, strict=True):
        stem = ref.lead.rstrip("0123456789")
        if pm.terms.coupled_wrist is not None and stem in wrist:
            weights_wrist[wrist.index(stem)] += value
        elif ref.lead in index:
            i = index[ref.lead]
            if pm.inertial_index[i] >= 0:
                weights_rigid[pm.inertial_index[i]] += value
            else:
                weights_extra[pm.extra_index[i]] += value
        else:
            missing.append(ref.lead)
    tau = Y_rigid @ weights_rigid + Y_extra @ weights_extra
    if pm.terms.coupled_wrist is not None:
        tau += figaroh_coupling_columns(dq, ddq, pm.terms.coupled_wrist) @ weights_wrist
    return tau, missing


def identify(cfg: IdentifyConfig, *, rng: int = 0) -> IdentifyResult:
    """Run the identification described by ``cfg`` (see :func:`_identify`).

    The least-squares problems here are small (thousands of rows, tens of columns) and many
    (essential parameters); multi-threaded BLAS only adds synchronisation to them (35x slower
    measured on a loaded 2-core machine), so BLAS runs on one thread inside this call.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - optional speed-up
        return _identify(cfg, rng=rng)
    with threadpool_limits(limits=1, user_api="blas"):
        return _identify(cfg, rng=rng)


def _identify(cfg: IdentifyConfig, *, rng: int = 0) -> IdentifyResult:
    """Run the identification described by ``cfg``.

    Parameters
    ----------
    cfg :
        Validated config with absolute paths (:func:`~ident.identify.config.load_identify_config`).
    rng :
        Seed of the random states used to find the structural base parameters (the result does
        not depend on it beyond round-off).

    Raises
    ------
    IdentError
        Subclasses naming the file, column or parameter: bad log, bad config, rank deficiency.
    """
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    source = str(cfg.source or "config")
    model = load_robot_model(cfg.robot.urdf)
    model_joints = [model.names[i] for i in range(1, model.njoints)]
    joints = cfg.robot.joints or model_joints
    if list(joints) != model_joints:
        raise ConfigError(
            f"{source}: robot.joints = {joints} must list the URDF's joints in chain order "
            f"({', '.join(model_joints)})."
        )
    log = read_log(cfg.log, cfg.transmission, joints, source=source)
    timings["read"] = time.perf_counter() - t0
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
    from ident.dynamics.chain import chain_from_model

    Y_rigid, Y_extra = _regressors(chain_from_model(model), terms, q, dq, ddq)
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
        tau_ref, missing_ref = _reference_prediction(
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
        est = least_squares(W_id, tau_id, base_names, method=cfg.estimation.method, groups=groups)
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
    timings["estimate"] = time.perf_counter() - t5

    essential = None
    if cfg.estimation.essential.enabled:
        t6 = time.perf_counter()
        essential = essential_parameters(
            W_id,
            tau_id,
            base_names,
            method=cfg.estimation.method,
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
    if essential is not None:
        add("essential", Yb_d[part][:, :, list(essential.kept)] @ essential.estimate.x)
    comparison: list[dict] = []
    note = ""
    if reference:
        add("reference", bank[4][part])
        comparison, note = _compare_with_reference(pm, est, reference, cfg.reference.column)
        if missing_ref:
            note += f" Reference parameters without a column here: {', '.join(missing_ref)}."
    add("URDF nominal", Yb_d[part] @ base.project(pm.nominal))
    reference_essential: list[dict] = []
    if cfg.reference.essential_parameters is not None:
        rows, _ = _compare_with_reference(
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
    )
