"""Payload identification: the 10 inertial parameters a payload adds to the last link.

A payload rigidly attached to the last moving link adds its standard parameters
``phi = [m, mcx, mcy, mcz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz]`` (about the last joint's frame,
Pinocchio order) to that body's. The joint torques are linear in them:

``tau - Y(q, dq, ddq) theta_arm = Y_n(q, dq, ddq) phi + E(dq, ddq) e``

with ``Y`` the rigid-body regressor (:mod:`ident.dynamics.regressor`), ``theta_arm`` the arm's
known parameters (its URDF's inertials, e.g. the URDF ``ident identify`` wrote) moved to the
right-hand side, ``Y_n`` the 10 columns of the last body and ``E`` the configured extra columns
(friction, rotor inertia, offsets; :mod:`ident.dynamics.friction`), estimated with ``phi``
because a URDF carries none of them reliably. A second log without the payload adds rows with
the same ``E`` columns and no ``Y_n`` columns, which pins the extras down.

The logs go through the one preprocessing of every identification (low-pass, differentiate,
trim, decimate, velocity threshold: :func:`ident.identify.estimation.accumulate.iter_chunks`, in
chunks of bounded size) and are reduced per joint
(:func:`ident.identify.estimation.accumulate.reduce_chunk`; the rows and their blocks:
:mod:`ident.identify.payload.payload_rows`). The estimate is WLS
(:func:`ident.identify.estimation.estimate.least_squares_reduced`: standard deviations from the
residual), then, with ``method: lmi``, the registry's ``lmi`` estimator on the same rows with the
payload as its one body: pseudo-inertia positive definite, extras >= 0
(:mod:`ident.identify.estimators.lmi`), no prior (the prior floor is 0).

**Intervals.** The standard deviations are those of every identification
(:func:`ident.identify.estimation.uncertainty.parameter_std`): a moving-block bootstrap of the WLS
estimate over consecutive blocks of decimated samples
(:mod:`ident.identify.estimation.uncertainty`), which holds on correlated residuals (filtered,
decimated rows, closed-loop and friction errors), where the ordinary ``sigma^2 (W^T W)^-1`` comes
out 2-3x too small. While the rows are reduced, each chunk also yields per-joint *unweighted* block
normal equations ``A_bj = sum_k Y_kj^T Y_kj``, ``c_bj = sum_k Y_kj^T y_kj`` (:func:`payload_rows`;
blocks of ``ceil(n_samples / MAX_BLOCKS)`` decimated samples that never cross a chunk, segment or
log boundary); after WLS they are summed with its weights ``1 / sigma_j^2``
(:func:`weighted_blocks`) and bootstrapped exactly as ``ident identify`` does. A log with too few
blocks (no more blocks than unknowns) falls back to the ordinary standard deviations, with a note.
The centre of mass's follow by the delta method from the same covariance.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.chain import KinematicChain, chain_from_model
from ident.dynamics.friction import ExtraTerms, extra_names
from ident.dynamics.parameters import parameter_names, parameters_from_model
from ident.errors import ConfigError, DataError, ModelError, NotIdentifiable
from ident.identify.config import PreprocessConfig
from ident.identify.estimation import log_chunks, preprocess
from ident.identify.estimation.consistency import pseudo_inertia_min_eigenvalue
from ident.identify.estimation.estimate import Estimate, least_squares_reduced
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimation.uncertainty import (
    BlockEquations,
    ParameterStd,
    Uncertainty,
    parameter_std,
    parameter_uncertainty,
    z_value,
)
from ident.identify.estimators import get_estimator
from ident.identify.estimators.problem import EstimationProblem, ParameterStructure
from ident.identify.model_files.files import ModelFiles, model_files
from ident.identify.payload import payload_arm
from ident.identify.payload.payload_config import PayloadConfig
from ident.identify.payload.payload_rows import (  # re-exported: the rows are part of the API
    PayloadColumns,
    block_length,
    decimated_samples,
    merge_blocks,
    payload_observations,
    payload_rows,
    weighted_blocks,
)
from ident.measure.logs import RobotLog, read_log
from ident.model import Robot
from ident.model.selection import load_robot
from ident.robot.inertia import (
    PINOCCHIO_ORDER,
    com_and_inertia,
    consistency_problems,
    parameters_from_com,
    transform_parameters,
)

__all__ = [
    "INTERVAL_LEVEL",
    "PAYLOAD_NAMES",
    "PayloadColumns",
    "PayloadResult",
    "arm_with_payload",
    "block_length",
    "payload_model_files",
    "calibrated_std",
    "consistent_problem",
    "decimated_samples",
    "estimate_payload",
    "identify_payload",
    "in_reporting_frame",
    "link_placement",
    "merge_blocks",
    "payload_observations",
    "payload_rows",
    "read_payload_logs",
    "weighted_blocks",
    "with_arm_uncertainty",
]

FloatArray = npt.NDArray[np.float64]

#: Names of the payload's parameters (Pinocchio order, about the last joint's frame).
PAYLOAD_NAMES = tuple(f"{label}_payload" for label in PINOCCHIO_ORDER)

#: Confidence level of the intervals in ``payload.json``.
INTERVAL_LEVEL = 0.95

_MIN_NOMINAL_MASS = 0.05  # [kg] scale of the LMI's unknowns when WLS finds a tiny mass


def calibrated_std(
    wls: Estimate, blocks: tuple[BlockEquations, ...] | None
) -> tuple[ParameterStd, Uncertainty | None]:
    """The one standard deviation of ``wls``
    (:func:`~ident.identify.estimation.uncertainty.parameter_std`) from the per-joint ``blocks``
    weighted by its ``1 / sigma_j``, as ``ident identify`` computes it; the ordinary one with a note
    when there are no blocks or too few."""
    unc = None
    if blocks is not None:
        sigma = np.asarray(wls.sigma, dtype=float)
        weights = np.where(np.isfinite(sigma) & (sigma > 0), 1.0 / sigma, 0.0)
        try:
            unc = parameter_uncertainty(
                weighted_blocks(blocks, weights), wls.names, wls.x, wls.covariance, rng=0
            )
        except (DataError, np.linalg.LinAlgError):
            unc = None
    return parameter_std(wls, unc), unc


@dataclass(frozen=True, eq=False)
class PayloadResult:
    """The estimated payload and how well it is determined (SI).

    Attributes
    ----------
    phi :
        Payload parameters about the last joint's frame, Pinocchio order, shape (10,)
        (the consistent estimate with ``method: lmi``, else WLS).
    std :
        Standard deviations of ``phi``, shape (10,): the block bootstrap of the WLS estimate
        (``std_method``), or its ordinary ones when the logs have too few blocks.
    link :
        Frame of ``com`` and ``inertia_com``.
    mass, mass_std :
        Mass and its standard deviation [kg].
    com, com_std :
        Centre of mass in ``link``'s frame and its standard deviations [m], shape (3,).
    inertia_com :
        Inertia about the centre of mass, ``link``'s axes [kg*m^2], shape (3, 3).
    min_eigenvalue :
        Smallest eigenvalue of the pseudo-inertia of ``phi`` (>= 0: realizable).
    wls :
        The WLS estimate of every column (payload then extras).
    consistent :
        The LMI estimate, or None with ``method: wls``.
    method :
        ``lmi`` or ``wls``.
    extras :
        Estimated extra parameters by name (friction, rotor inertia, offsets).
    timings :
        Seconds per stage.
    signals :
        What ``signals:`` removed from the logs (JSON-ready,
        :meth:`ident.identify.corrections.signal_correction.SignalCorrection.summary`), or None.
    std_method, std_note :
        Where ``std`` comes from (``bootstrap`` or ``ordinary``) and, for ``ordinary``, why.
    uncertainty :
        The covariances of every interval method of the WLS estimate (payload then extras),
        or None when the logs have too few blocks.
    ordinary_mass_std, ordinary_com_std :
        The ordinary (independent-residual) standard deviations of the mass [kg] and of the
        centre of mass [m] (3,), for comparison.
    arm_from :
        Where the arm's parameters come from
        (:data:`~ident.identify.payload.payload_arm.ARM_FROM`'s text), ``""`` when not said.
    arm_note :
        How the arm was used (lost payload directions, the corrections' size), or ``""``.
    warnings :
        The fit's warnings (:func:`~ident.identify.payload.payload_arm.payload_fit_warnings`).
    floor_residual :
        Relative residual of the same rows with the arm free and no payload (NaN: not run).
    interval_factor :
        Factor the standard deviations were widened by for the fit's excess residual (>= 1).
    """

    phi: FloatArray
    std: FloatArray
    link: str
    mass: float
    mass_std: float
    com: FloatArray
    com_std: FloatArray
    inertia_com: FloatArray
    min_eigenvalue: float
    wls: Estimate
    consistent: Estimate | None
    method: str
    extras: dict[str, float]
    timings: dict[str, float]
    signals: dict | None = None
    std_method: str = "ordinary"
    std_note: str = ""
    uncertainty: Uncertainty | None = None
    ordinary_mass_std: float = float("nan")
    ordinary_com_std: FloatArray | None = None
    arm_from: str = ""
    arm_note: str = ""
    warnings: tuple[str, ...] = ()
    floor_residual: float = float("nan")
    interval_factor: float = 1.0

    def intervals(self, level: float = INTERVAL_LEVEL) -> tuple[FloatArray, FloatArray]:
        """``[lower, upper]`` of the mass [kg] (2,) and of the centre of mass [m] (3, 2) at
        confidence ``level`` (normal, ``+- z std``)."""
        z = z_value(level)
        mass = np.array([self.mass - z * self.mass_std, self.mass + z * self.mass_std])
        return mass, np.column_stack([self.com - z * self.com_std, self.com + z * self.com_std])

    def summary(self) -> dict:
        """JSON-ready values (SI) for ``payload.json``."""
        mass_interval, com_interval = self.intervals()
        unc = self.uncertainty
        return {
            "method": self.method,
            "link": self.link,
            "mass_kg": self.mass,
            "mass_std_kg": self.mass_std,
            "com_m": self.com.tolist(),
            "com_std_m": self.com_std.tolist(),
            # std / intervals: the one σ (std_method), as result.json's
            "std_method": self.std_method,
            **({"std_note": self.std_note} if self.std_note else {}),
            "interval_level": INTERVAL_LEVEL,
            "mass_interval_kg": mass_interval.tolist(),
            "com_interval_m": com_interval.tolist(),
            "ordinary_std": {
                "mass_kg": self.ordinary_mass_std,
                "com_m": None if self.ordinary_com_std is None else self.ordinary_com_std.tolist(),
            },
            **(
                {}
                if unc is None
                else {
                    "bootstrap": {
                        "n_blocks": unc.n_blocks,
                        "block_samples": unc.block_samples,
                        "run_length_blocks": int(np.ceil(unc.bandwidth)),
                        "n_boot": unc.n_boot,
                    }
                }
            ),
            "inertia_com_kgm2": self.inertia_com.tolist(),
            "parameters_last_joint_frame": dict(zip(PAYLOAD_NAMES, self.phi.tolist(), strict=True)),
            "parameters_std": dict(zip(PAYLOAD_NAMES, self.std.tolist(), strict=True)),
            "pseudo_inertia_min_eigenvalue": self.min_eigenvalue,
            "relative_residual": self.wls.relative_residual,
            "arm_from": self.arm_from,
            **({"arm_note": self.arm_note} if self.arm_note else {}),
            "floor_relative_residual": (
                self.floor_residual if np.isfinite(self.floor_residual) else None
            ),
            "interval_factor": self.interval_factor,
            "warnings": list(self.warnings),
            "residual_rms_per_joint": self.wls.residual_rms.tolist(),
            "condition_number": self.wls.condition_number,
            "extras": self.extras,
            "message": (self.consistent or self.wls).message,
            "timings_s": self.timings,
            **({} if self.signals is None else {"signals": self.signals}),
        }


def link_placement(model: pin.Model, link: str | None, source: str) -> tuple[str, pin.SE3]:
    """The frame reported (name, placement in the last joint's frame)."""
    last = model.njoints - 1
    if link is None:
        for frame in model.frames:
            if frame.parentJoint == last and frame.type == pin.FrameType.BODY:
                return str(frame.name), frame.placement
        return str(model.names[last]), pin.SE3.Identity()
    if not model.existFrame(link):
        raise ConfigError(
            f"{source}: payload.link = {link!r} is not a link of the robot; name a link that "
            "rides on the last moving joint, or null."
        )
    frame = model.frames[model.getFrameId(link)]
    if frame.parentJoint != last:
        raise ConfigError(
            f"{source}: payload.link = {link!r} does not ride on the last moving joint "
            f"{model.names[last]!r}; name a link fixed to it, or null."
        )
    return link, frame.placement


def estimate_payload(
    red: ReducedObservations,
    extra: tuple[str, ...],
    *,
    method: str = "lmi",
    placement: pin.SE3 | None = None,
    link: str = "last link",
    blocks: tuple[BlockEquations, ...] | None = None,
    arm_names: tuple[str, ...] = (),
) -> PayloadResult:
    """WLS (and LMI) estimate of the payload from reduced rows ``[Y_n | E | Y_b]`` (module
    docstring).

    Parameters
    ----------
    red :
        Reduced rows, columns ``PAYLOAD_NAMES + extra + arm_names``.
    extra :
        Names of the extra columns (:func:`ident.dynamics.friction.extra_names`).
    method :
        ``lmi`` or ``wls``.
    placement :
        Pose of the reporting frame in the last joint's frame (default: identity).
    link :
        Name of the reporting frame.
    blocks :
        Per-joint unweighted block normal equations of the same rows (:func:`payload_rows`):
        the standard deviations are their block bootstrap; None: the ordinary ones (a note).
    arm_names :
        Names of the arm's base-parameter corrections estimated with the payload
        (:mod:`ident.identify.payload.payload_arm`; none: the arm is the URDF's).

    Raises
    ------
    NotIdentifiable
        If the logs do not determine every payload and extra parameter (names them).
    """
    names = PAYLOAD_NAMES + tuple(extra) + tuple(arm_names)
    t0 = time.perf_counter()
    wls = least_squares_reduced(red, names, method="wls")
    timings = {"wls": time.perf_counter() - t0}
    x = wls.x
    consistent = None
    if method == "lmi":
        t1 = time.perf_counter()
        consistent = _consistent_estimate(red, wls, extra, names)
        x = consistent.x
        timings["lmi"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    sd, unc = calibrated_std(wls, blocks)
    timings["intervals"] = time.perf_counter() - t2
    return _payload_result(
        x, sd, wls, extra, placement=placement, link=link, method=method,
        consistent=consistent, timings=timings, uncertainty=unc,
    )  # fmt: skip


def _payload_result(
    x: FloatArray,
    sd: ParameterStd,
    wls: Estimate,
    extra: tuple[str, ...],
    *,
    placement: pin.SE3 | None,
    link: str,
    method: str,
    consistent: Estimate | None,
    timings: dict[str, float],
    uncertainty: Uncertainty | None,
) -> PayloadResult:
    """The :class:`PayloadResult` of the estimate ``x`` (payload, extras, arm) with the
    standard deviations ``sd`` and the WLS ``wls`` (its ordinary covariance)."""
    phi = np.asarray(x[:10], dtype=float)
    std = sd.std[:10]
    mass, com, com_std, inertia_com = in_reporting_frame(phi, sd.covariance[:10, :10], placement)
    ordinary = in_reporting_frame(phi, wls.covariance[:10, :10], placement)[2]
    return PayloadResult(
        phi=phi,
        std=std,
        link=link,
        mass=mass,
        mass_std=float(std[0]),
        com=com,
        com_std=com_std,
        inertia_com=inertia_com,
        min_eigenvalue=float(pseudo_inertia_min_eigenvalue(phi)),
        wls=wls,
        consistent=consistent,
        method=method,
        extras=dict(zip(extra, (float(v) for v in x[10 : 10 + len(extra)]), strict=True)),
        timings=timings,
        std_method=sd.method,
        std_note=sd.note,
        uncertainty=uncertainty,
        ordinary_mass_std=float(np.sqrt(max(wls.covariance[0, 0], 0.0))),
        ordinary_com_std=ordinary,
    )


def estimate_payload_prior(
    red: ReducedObservations,
    extra: tuple[str, ...],
    arm_names: tuple[str, ...],
    prior_cov: FloatArray,
    floor: Estimate,
    *,
    placement: pin.SE3 | None = None,
    link: str = "last link",
) -> PayloadResult:
    """Posterior mean and covariance of ``[phi | e | dbeta]`` with the prior
    ``dbeta ~ N(0, prior_cov)`` (n_b, n_b) on the arm's base-parameter corrections
    (:func:`~ident.identify.payload.payload_arm.cad_prior_covariance`) and the rows weighted by
    the ``1 / sigma_j`` of ``floor`` (the same rows fitted with the arm free,
    :func:`~ident.identify.payload.payload_arm.floor_fit`): a ridge toward the prior arm.
    Columns of ``red``: ``PAYLOAD_NAMES + extra + arm_names``. ``std_method``: ``posterior``.
    """
    names = PAYLOAD_NAMES + tuple(extra) + tuple(arm_names)
    t0 = time.perf_counter()
    sigma = np.asarray(floor.sigma, dtype=float)
    w = np.where(np.isfinite(sigma) & (sigma > 0) & (red.n_rows > 0), 1.0 / sigma, 0.0)
    H = np.einsum("g,gki,gkj->ij", w**2, red.R, red.R)
    g = np.einsum("g,gki,gk->i", w**2, red.R, red.z)
    n_b = len(arm_names)
    H[-n_b:, -n_b:] += np.linalg.inv(prior_cov)  # the prior's precision on dbeta
    cov = np.linalg.inv(H)
    x = cov @ g
    ss = red.residual_ss(x)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        rel = np.where(x != 0.0, 100.0 * std / np.abs(x), np.inf)
    post = replace(
        floor, x=x, names=names, std=std, relative_std=rel, covariance=cov,
        residual_rms=np.sqrt(ss / np.maximum(red.n_rows, 1)),
        relative_residual=float(np.sqrt(ss.sum() / red.yty.sum())),
        group_residual_ss=ss, condition_number=float(np.linalg.cond(H)),
        message="posterior with the CAD prior on the arm",
    )  # fmt: skip
    sd = ParameterStd(std=std, relative_std=rel, method="posterior", covariance=cov)
    return _payload_result(
        x, sd, post, extra, placement=placement, link=link, method="wls", consistent=None,
        timings={"prior": time.perf_counter() - t0}, uncertainty=None,
    )  # fmt: skip


def _lmi_structure(
    names: tuple[str, ...], extra: tuple[str, ...], x: FloatArray
) -> ParameterStructure:
    """The payload as the LMI's one body; friction and rotor inertia >= 0.

    The nominal (the LMI's scale of the unknowns, not a prior) is a point mass at the WLS
    centre of mass, its mass at least ``_MIN_NOMINAL_MASS`` [kg] and the centre of mass
    within 1 m of the last joint's frame.
    """
    mass = max(abs(float(x[0])), _MIN_NOMINAL_MASS)
    com = x[1:4] / mass
    com = com / max(1.0, float(np.linalg.norm(com)))  # a scale, not a prior: keep it sane
    nominal = np.zeros(len(names))
    nominal[:10] = parameters_from_com(np.asarray(mass), com, np.zeros((3, 3)))
    kinds = [n.rstrip("0123456789") for n in extra]
    nonnegative = [10 + i for i, k in enumerate(kinds) if k in ("Ia", "fv", "fs", "Iam")]
    return ParameterStructure(
        names=names,
        bodies=np.arange(10)[None, :],
        body_names=("payload",),
        nonnegative=np.asarray(nonnegative, dtype=np.intp),
        nominal=nominal,
    )


def consistent_problem(
    red: ReducedObservations, wls: Estimate, extra: tuple[str, ...], names: tuple[str, ...]
) -> EstimationProblem:
    """The problem of the consistent (``lmi``) estimate on the WLS rows: realizable payload,
    extras >= 0 (:func:`_lmi_structure`), no prior.

    Rows are weighted by WLS's per-joint ``1 / sigma`` (joints without rows get 0); ``names``:
    the payload's, the ``extra`` ones, then further free unknowns (the arm's corrections, a
    stream's replaced parameters).
    """
    return EstimationProblem(
        observations=red,
        names=names,
        structure=_lmi_structure(names, tuple(extra), wls.x),
        weights=np.where(red.n_rows > 0, 1.0 / wls.sigma, 0.0),
        options={"prior_floor": 0.0, "friction": "free"},
    )


def _consistent_estimate(
    red: ReducedObservations, wls: Estimate, extra: tuple[str, ...], names: tuple[str, ...]
) -> Estimate:
    """The registry's ``lmi`` estimate of :func:`consistent_problem`."""
    return get_estimator("lmi")(consistent_problem(red, wls, extra, names))


def in_reporting_frame(
    phi: FloatArray, cov: FloatArray, placement: pin.SE3 | None
) -> tuple[float, FloatArray, FloatArray, FloatArray]:
    """Mass [kg], centre of mass [m] (3,), its std [m] (3,), inertia about it [kg*m^2] (3, 3).

    ``phi`` (10,) and its covariance ``cov`` (10, 10) are about the last joint's frame; the
    results are in the frame at ``placement`` in it (identity when None). The centre of mass's
    std is by the delta method: ``c = R^T (h / m - p)``, ``dc/dm = -R^T h / m^2``,
    ``dc/dh = R^T / m``.
    """
    if placement is not None:
        # parameters in the reporting frame: the inverse placement acts on them
        rotation, translation = placement.rotation, placement.translation
        phi_link = transform_parameters(phi, rotation.T, -rotation.T @ translation)
    else:
        phi_link, rotation = phi, np.eye(3)
    mass, com, inertia_com = com_and_inertia(phi_link)
    m, h = float(phi[0]), phi[1:4]
    J = np.zeros((3, 4))
    J[:, 0] = -rotation.T @ h / m**2
    J[:, 1:] = rotation.T / m
    com_cov = J @ cov[:4, :4] @ J.T
    return (
        float(mass),
        np.asarray(com, dtype=float),
        np.sqrt(np.clip(np.diag(com_cov), 0.0, None)),
        np.asarray(inertia_com, dtype=float),
    )


def _settings(cfg: PayloadConfig, log: RobotLog) -> PreprocessConfig:
    """The preprocessing with ``auto`` resolved on the payload log's first segment."""
    pp, _, _ = preprocess.resolve_for_log(cfg.preprocess, log)
    return pp


def read_payload_logs(cfg: PayloadConfig, model: pin.Model) -> tuple[RobotLog, RobotLog | None]:
    """``(with_payload, without_payload or None)`` read from the config's log sections."""
    source = str(cfg.source or "config")
    joints = [str(model.names[i]) for i in range(1, model.njoints)]
    with_log = read_log(cfg.log, cfg.transmission, joints, source=source)
    without = cfg.payload.without
    if without is None:
        return with_log, None
    return with_log, read_log(
        without, cfg.transmission, joints, source=f"{source}: payload.without"
    )


def identify_payload(
    cfg: PayloadConfig,
    *,
    robot: Robot | None = None,
    logs: tuple[RobotLog, RobotLog | None] | None = None,
) -> PayloadResult:
    """Read the config's logs and estimate the payload (module docstring); the arm's
    parameters come from the log without the payload, the identified model or the CAD prior
    (:mod:`ident.identify.payload.payload_arm`), and the result says which.

    Parameters
    ----------
    cfg :
        Validated config (:func:`~ident.identify.payload.payload_config.load_payload_config`).
    robot :
        The arm without the payload (loaded from ``cfg.robot`` when not given).
    logs :
        ``(with_payload, without_payload or None)`` already read (else read from ``cfg``).

    Raises
    ------
    IdentError
        Subclasses naming the file, field or parameter.
    """
    source = str(cfg.source or "config")
    t0 = time.perf_counter()
    robot = robot if robot is not None else load_robot(cfg.robot, source=source)
    model = robot.model
    link, placement = link_placement(model, cfg.payload.link, source)
    with_log, without_log = read_payload_logs(cfg, model) if logs is None else logs
    pp = _settings(cfg, with_log)
    if pp.velocity_threshold is not None and len(pp.velocity_threshold) != model.nv:
        raise ConfigError(
            f"{source}: preprocess.velocity_threshold has {len(pp.velocity_threshold)} values, "
            f"the robot has {model.nv} joints; give one per joint [rad/s]."
        )
    terms = cfg.model.extra_terms(model.nv, source)
    chain = chain_from_model(model)
    arm = payload_arm.arm_base(chain, terms)
    t1 = time.perf_counter()
    red, blocks = _all_rows(chain, terms, arm, parameters_from_model(model), pp,
                            (with_log, without_log))  # fmt: skip
    t2 = time.perf_counter()
    source_key = payload_arm.arm_source(cfg.payload.arm, robot.urdf_path, without_log is not None)
    arm_cov = payload_arm.identified_covariance(
        robot.urdf_path, arm, extra_names(terms), parameter_names(arm.projection.shape[1] // 10)
    )
    try:
        result = _estimate_for_arm(
            red, blocks, extra_names(terms), arm, (source_key, arm_cov), cfg, model, placement, link
        )
    except NotIdentifiable as e:
        raise NotIdentifiable(
            f"{source}: the logs do not determine the payload: {e} Move the last joints more "
            "(several orientations of the last link against gravity, accelerations), add a log "
            "without the payload (payload.without), or leave out friction terms (model)."
        ) from e
    timings = {"read": t1 - t0, "accumulate": t2 - t1, **result.timings}
    return replace(result, timings=timings)


def _all_rows(
    chain: KinematicChain,
    terms: ExtraTerms,
    arm: payload_arm.ArmBase,
    theta_arm: FloatArray,
    pp: PreprocessConfig,
    logs: tuple[RobotLog, RobotLog | None],
) -> tuple[ReducedObservations, tuple[BlockEquations, ...]]:
    """Reduced rows and per-joint blocks ``[Y_n | E | Y_b]`` of both logs (the log without
    the payload with zero ``Y_n``). The blocks are fewer than :data:`MAX_BLOCKS
    <ident.identify.estimation.log_chunks.MAX_BLOCKS>` when the columns are many, so their
    memory stays near 110 MB."""
    given = [log for log in logs if log is not None]
    nv = chain.nv
    p = 10 + len(extra_names(terms)) + arm.index.size
    budget = max(64, int(110e6 / (8 * nv * (p * p + p + 1))))
    step = block_length(
        sum(decimated_samples(log, pp) for log in given), min(log_chunks.MAX_BLOCKS, budget)
    )
    red, blocks = payload_rows(
        given[0], pp, PayloadColumns(chain, terms, theta_arm, arm_index=arm.index), step
    )
    if len(given) > 1:
        columns = PayloadColumns(chain, terms, theta_arm, with_payload=False, arm_index=arm.index)
        red_without, blocks_without = payload_rows(given[1], pp, columns, step)
        red = red.merge(red_without)
        blocks = merge_blocks(blocks, blocks_without)
    return red, blocks


def _estimate_for_arm(
    red: ReducedObservations,
    blocks: tuple[BlockEquations, ...],
    extra: tuple[str, ...],
    arm: payload_arm.ArmBase,
    source: tuple[str, tuple[FloatArray | None, str]],
    cfg: PayloadConfig,
    model: pin.Model,
    placement: pin.SE3,
    link: str,
) -> PayloadResult:
    """The payload with the arm from ``source``'s key (:data:`payload_arm.ARM_FROM`), the
    fit's warnings and the intervals widened by its excess residual; ``source``'s second item
    is the identified arm's covariance and its note
    (:func:`~ident.identify.payload.payload_arm.identified_covariance`), propagated into the
    intervals of ``model`` (:func:`with_arm_uncertainty`)."""
    source_key, arm_cov = source
    n_p = 10 + len(extra)
    names = PAYLOAD_NAMES + tuple(extra) + arm.names
    not_payload = np.arange(10, len(names))
    floor = payload_arm.floor_fit(red, not_payload, names)
    lost = payload_arm.lost_payload_directions(red, 10, names) if source_key == "without" else []
    note = ""
    if source_key == "without" and not lost:
        result = estimate_payload(red, extra, method=cfg.payload.method, placement=placement,
                                  link=link, blocks=blocks, arm_names=arm.names)  # fmt: skip
        floor = result.wls  # the arm is free already: the fit is its own floor
    elif source_key == "model":
        keep = np.arange(n_p)
        result = estimate_payload(payload_arm.select_columns(red, keep), extra,
                                  method=cfg.payload.method, placement=placement, link=link,
                                  blocks=payload_arm.select_blocks(blocks, keep))  # fmt: skip
        result = with_arm_uncertainty(result, red, *arm_cov, placement)
    else:
        if floor is None:
            raise NotIdentifiable("the log does not determine the arm's base parameters.")
        # The prior holds the arm, not the payload: its own columns must have full rank.
        unexcited = payload_arm.lost_payload_directions(
            payload_arm.select_columns(red, np.arange(n_p)), 10, names[:n_p]
        )
        if unexcited:
            raise NotIdentifiable(
                f"the log leaves {len(unexcited)} of the payload's 10 directions unexcited "
                f"(the first: {unexcited[0]})."
            )
        prior = payload_arm.cad_prior_covariance(parameters_from_model(model), arm)
        result = estimate_payload_prior(red, extra, arm.names, prior, floor,
                                        placement=placement, link=link)  # fmt: skip
        if lost:
            note = (
                "the payload direction(s) " + "; ".join(lost) + " are not separable from the "
                "arm's parameters in these logs: they come from the CAD prior."
            )
    return _with_fit_check(result, floor, source_key, note)


def with_arm_uncertainty(
    result: PayloadResult,
    red: ReducedObservations,
    arm_cov: FloatArray | None,
    source: str,
    placement: pin.SE3 | None,
) -> PayloadResult:
    """``result`` (the arm taken as exact, its columns ``[Y_n | E]``) with the identified arm's
    uncertainty propagated into its standard deviations.

    The arm's error ``dbeta`` (covariance ``arm_cov`` (n_b, n_b),
    :func:`~ident.identify.payload.payload_arm.identified_covariance`) enters the payload rows as
    ``Y_b dbeta`` (``red``: columns ``[Y_n | E | Y_b]``); the WLS estimate moves by
    ``G dbeta``, ``G = -H_aa^-1 H_ab`` with ``H = sum_j w_j^2 R_j^T R_j`` (``w_j = 1 / sigma_j``,
    the estimate's weights; ``a`` the payload and extra columns, ``b`` the arm's). The arm
    comes from another log, so its error is independent of this log's noise and
    ``cov(phi) = C_log + G C_arm G^T`` (``C_log`` the log's bootstrap covariance). Without
    ``arm_cov`` the intervals assume the arm exact and the note says why (``source``).
    """
    if arm_cov is None:
        note = f"the identified arm's uncertainty is not in the intervals: {source}."
        return replace(result, arm_note=note)
    n_p = len(result.wls.names)
    sigma = np.asarray(result.wls.sigma, dtype=float)
    w = np.where(np.isfinite(sigma) & (sigma > 0) & (red.n_rows > 0), 1.0 / sigma, 0.0)
    H = np.einsum("g,gki,gkj->ij", w**2, red.R, red.R)
    G = -np.linalg.solve(H[:n_p, :n_p], H[:n_p, n_p:])[:10]
    added = G @ arm_cov @ G.T  # (10, 10)
    sd_log = result.std
    covariance = _log_covariance(result)[:10, :10] + added
    mass, com, com_std, _ = in_reporting_frame(result.phi, covariance, placement)
    std = np.sqrt(np.clip(np.diag(covariance), 0.0, None))
    note = (
        f"the identified arm's uncertainty ({source}) is in the intervals: mass σ "
        f"{1e3 * sd_log[0]:.2g} g from the log, {1e3 * np.sqrt(added[0, 0]):.2g} g from the arm."
    )
    return replace(result, std=std, mass_std=float(std[0]), com_std=com_std, arm_note=note)


def _log_covariance(result: PayloadResult) -> FloatArray:
    """The covariance ``result.std`` comes from: the bootstrap's, else the ordinary one."""
    unc = result.uncertainty
    if result.std_method != "ordinary" and unc is not None:
        return np.asarray(unc.covariance[unc.method], dtype=float)
    return np.asarray(result.wls.covariance, dtype=float)


def _with_fit_check(
    result: PayloadResult, floor: Estimate | None, source_key: str, note: str
) -> PayloadResult:
    """``result`` with its arm source, the fit's warnings and its standard deviations
    widened by the excess residual (:func:`payload_arm.payload_fit_warnings`)."""
    floor_residual = None if floor is None else float(floor.relative_residual)
    warnings, factor = payload_arm.payload_fit_warnings(
        result.wls.relative_residual, floor_residual, source_key
    )
    return replace(
        result,
        std=result.std * factor,
        mass_std=result.mass_std * factor,
        com_std=result.com_std * factor,
        arm_from=payload_arm.ARM_FROM[source_key],
        arm_note=note or result.arm_note,
        warnings=tuple(warnings),
        floor_residual=float("nan") if floor_residual is None else floor_residual,
        interval_factor=factor,
    )


def arm_with_payload(robot: Robot, phi: npt.ArrayLike) -> tuple[FloatArray, tuple[str, ...]]:
    """Standard parameters of the arm with the payload added to its last body, and names.

    ``theta = theta_URDF`` with ``phi`` (about the last joint's frame) added to the last
    body's 10 parameters; for :func:`ident.identify.model_files.files.write_model_files`.
    """
    theta = parameters_from_model(robot.model).copy()
    theta[-10:] += np.asarray(phi, dtype=float)
    return theta, parameter_names(robot.n_bodies)


def payload_model_files(robot: Robot, result: PayloadResult) -> tuple[ModelFiles | None, str]:
    """The arm + payload model files (:func:`arm_with_payload`,
    :func:`ident.identify.model_files.files.model_files`), or None and why they are not written.

    A model file must be a physical body. The URDF's last body plus ``result.phi`` is one when
    both are (the pseudo-inertia is linear in the parameters: a sum of two positive definite
    ones), so with ``method: lmi`` it holds; the WLS payload is unconstrained, and where the
    log does not tell the payload from the arm's errors (one log on a CAD arm) it can be no
    body at all. That is a result, not bad input: the estimate is still reported, with the
    reason the files are missing (returned as the second item, else ``""``).
    """
    theta, names = arm_with_payload(robot, result.phi)
    problems = consistency_problems(theta[-10:])
    if not problems:
        try:
            return model_files(robot, theta, names), ""
        except ModelError as e:  # the URDF's other bodies, MuJoCo: the estimate still stands
            return None, "model files not written: " + " ".join(str(e).split())
    last = robot.model.names[robot.model.njoints - 1]
    fix = (
        "payload.method: lmi keeps the payload a physical body"
        if result.method == "wls"
        else "the URDF's own last body is not a physical body; fix its <inertial>"
    )
    return None, (
        f"model files not written: the last moving body (joint {last}) plus the "
        f"{result.method.upper()} payload is not physically consistent "
        f"({'; '.join(problems)}); payload.json holds the estimate; {fix}."
    )
