"""Position servos that log no torque: gain, delay and saturation, the scale fixed once.

A position servo's torque is ``clip(kp (q_cmd(t - d) - q) - kd dq, +-forcerange)``
(:mod:`ident.dynamics.actuators`). With no torque in the log, the identification equation of
joint ``j`` where the clip is inactive,

    W_j(q, dq, ddq) beta - kp_j e_j = 0,      e_j = q_cmd_j(t - d) - q_j,

(``beta`` the base parameters with the friction, rotor-inertia and offset columns) is linear and
*homogeneous* in ``u = [beta, kp]``: the data fix ``u`` only up to one common scale (the joints
share the rigid-body parameters, which ties their gains together). ``kd_j`` multiplies
``-dq_j``, the viscous friction's column: the data see ``kd_j + fv_j`` only, the value of the
``fv{j}`` column. One equality fixes the scale (``actuator.scale_from``):

- ``kp``: the gains given (a datasheet): ``kp e`` moves to the right side, a plain least squares;
- ``mass``: the URDF's masses (and centres of mass) through the gravity load they put on the
  joints over the logged postures: every combination of base parameters the gravity torques
  see keeps its URDF value (:func:`mass_scale`), so the scale is as right as the URDF's
  gravity load; an arm moving about vertical axes only sees none. A joint the gravity does not
  load (a pan, a wrist roll) is tied to the scale through the shared inertias only;
  ``actuator.equal_kp`` gives it the gain of loaded joints with the same servo setting.

Solving: every row of a joint is reduced once by the identification's own accumulation
(:mod:`ident.identify.estimation.log_chunks`) with ``e_j`` in place of the torque, so the QR of
``[W_j | e_j]`` is ``[[R_j, z_j], [0, sqrt(rho_j)]]`` and ``||W_j beta - kp_j e_j||`` follows for
any ``u`` (:func:`servo_rows`). The equality is eliminated, ``u = u0 + Z v``, and ``v`` is the
identification's WLS (:func:`~ident.identify.estimation.estimate.least_squares_reduced`) on
those rows: its standard deviations give those of ``kp`` and ``kd + fv`` (``Z cov Z^T``).

The delay ``d`` (``actuator.delay: auto``): every whole number of samples within
``max_delay_s`` is fitted, then the best refined to a fraction of a sample (the command
between samples linearly interpolated, :func:`~ident.dynamics.actuators.servo_error`; a
fraction's reduction mixed from its whole neighbours', :func:`between_delays`), the
delay of the smallest residual kept (the scale is fixed the same way for every ``d``, so the
residuals compare). A shift of one sample ``h`` changes ``kp e`` by about ``-kp h (dq +
de/dt)``: its ``dq`` part is a change of ``kd`` by ``kp h``, so only the torque's rate of
change ``kp de/dt`` tells the delay from ``kd``: a motion of a few Hz (a 0.25-0.75 Hz one
with 4096-tick encoders leaves the residual's minimum to the ticks' noise and the dry
friction's reversals). With ``forcerange``, samples where the servo may reach it are excluded
(:func:`~ident.dynamics.actuators.saturated_samples`) and the fit redone until the set stops
changing; stretches left between them that are too short to filter are dropped with them.
Then :func:`servo_log` hands the identification the log with ``tau = kp e`` (the identified or
given gains, the delay applied, the excluded samples cut out): its ``fv{j}`` is ``kd + fv``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import scipy.linalg
import scipy.optimize

from ident.blas import one_blas_thread
from ident.dynamics.actuators import saturated_samples, servo_error
from ident.dynamics.chain import chain_from_model
from ident.dynamics.parameter_model import ParameterModel, build_parameter_model
from ident.errors import ConfigError, DataError
from ident.identify.config import ActuatorSection, IdentifyConfig, PreprocessConfig
from ident.identify.estimation import log_chunks, preprocess
from ident.identify.estimation.accumulate import BaseColumns
from ident.identify.estimation.estimate import Estimate, least_squares_reduced
from ident.identify.estimation.observations import ReducedObservations
from ident.measure.logs import RobotLog
from ident.measure.mujoco_config import per_joint
from ident.signals import derivative

__all__ = [
    "FIRST_FIT_QUANTILE",
    "MAX_SATURATION_ROUNDS",
    "MIN_SHARED_SHARE",
    "Scale",
    "ServoFit",
    "between_delays",
    "gravity_rows",
    "kp_scale",
    "mass_scale",
    "scaled_fit",
    "servo_fit_count",
    "servo_log",
    "servo_rows",
    "shared_share",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Fits redone at most, each excluding the samples the previous one found saturated.
MAX_SATURATION_ROUNDS = 4
#: The scanned delay's refinement: its tolerance [samples] and most fits.
DELAY_TOLERANCE = 0.01
MAX_DELAY_REFINE = 16
#: With a force range and the gains unknown, the first fit uses the samples whose every
#: joint's error is at most this quantile of that joint's errors.
FIRST_FIT_QUANTILE = 0.95
#: A joint whose torque is less than this share from parameters shared with other joints has
#: its gain barely tied to the common scale (named in :meth:`ServoFit.undetermined`).
MIN_SHARED_SHARE = 0.1
#: A joint whose URDF gravity torque is below this share of the most loaded joint's has its
#: gain tied to the scale through the shared inertias only (named in
#: :meth:`ServoFit.undetermined`).
MIN_GRAVITY_SHARE = 0.1
#: The URDF's gravity torque [N*m rms] the logged postures must load to fix the scale.
MIN_GRAVITY_LOAD = 1e-6
#: A joint's URDF gravity load more than this many times its identified servo torque (rms)
#: means the gravity-load scale failed (:func:`_check_gravity_carried`).
MAX_GRAVITY_OVER_TORQUE = 2.0
#: The gravity load is summed over every this-many-th posture of the log.
GRAVITY_POSTURE_STEP = 5
#: Gravity columns' pivots kept: those above this fraction of the largest (QR's diagonal).
GRAVITY_RANK_TOL = 1e-8


@dataclass(frozen=True, eq=False)
class Scale:
    """What fixes the common scale of ``u = [beta, kp]``: ``u = offset + basis @ v``.

    Attributes
    ----------
    kind :
        ``kp`` (the gains given) or ``mass`` (the URDF's).
    offset, basis :
        ``u0`` (n_base + nv,) and ``Z`` (n_base + nv, n_free).
    free :
        Names of ``v``, length n_free.
    note :
        What fixed it, in words (values and units).
    gravity_load :
        ``mass``: the URDF's gravity torque per joint over the log's postures [N*m rms]
        (nv,), the largest of its ``equal_kp`` group; None for ``kp``.
    own_load :
        ``mass``: the same, each joint's own (nv,); None for ``kp``.
    """

    kind: str
    offset: FloatArray
    basis: FloatArray
    free: tuple[str, ...]
    note: str
    gravity_load: FloatArray | None = None
    own_load: FloatArray | None = None


def kp_scale(pm: ParameterModel, kp: FloatArray) -> Scale:
    """The gains ``kp`` [N*m/rad] (nv,) given: ``kp`` fixed, ``beta`` free."""
    p, nv = len(pm.base_names), kp.size
    offset = np.concatenate([np.zeros(p), kp])
    basis = np.vstack([np.eye(p), np.zeros((nv, p))])
    note = "the gains given (actuator.kp) " + _values(kp, "N*m/rad")
    return Scale("kp", offset, basis, tuple(pm.base_names), note)


def mass_scale(
    pm: ParameterModel,
    columns: BaseColumns,
    q: FloatArray,
    equal_kp: tuple[tuple[int, ...], ...] = (),
) -> Scale:
    """The URDF's masses fix the scale through the gravity load they put on the joints.

    ``G`` (n nv, p): the base regressor at the postures ``q`` (n, nq) at rest (``dq = ddq =
    0``: the gravity columns; the extras' columns are zero there), ``g = G T theta_urdf`` the
    URDF's gravity torques [N*m]. The fit keeps ``G beta = g``: every combination of base
    parameters the gravity torques see (the first moments and masses, rank ``r``) at the
    URDF's value; the inertias, the extras and ``kp`` are free. ``r`` pivot columns of ``G``
    (QR with column pivoting) are eliminated: ``beta_P = G_P^+ (g - G_F beta_F)``. One
    combination alone (the total mass) would not do: a light arm's data have near-null
    directions that hold it (inertia mimicking the gravity spring of a periodic motion), and
    the fit would put the scale there and drive the gains to 0.

    ``equal_kp``: groups of joint indices with one gain (``actuator.equal_kp``): ``kp = S k``,
    ``S`` (nv, n_k) the groups' indicator (a joint in no group has a column of its own).
    Each joint's ``gravity_load`` is its group's largest: what ties its gain to the scale.

    Raises :class:`ConfigError` when the postures load no gravity (a horizontal arm): give
    ``actuator.kp``.
    """
    p = len(pm.base_names)
    nv = pm.terms.n_joints
    G = gravity_rows(pm, columns, q)
    g = G @ pm.base.projection @ pm.nominal
    rms = float(np.sqrt(np.mean(g**2))) if g.size else 0.0
    if not rms > MIN_GRAVITY_LOAD:
        raise ConfigError(
            f"actuator.scale_from: mass: the logged postures load no gravity (the URDF's "
            f"gravity torques are {rms:.3g} N*m rms): give the servos' gain actuator.kp "
            "[N*m/rad] and scale_from: kp"
        )
    _, r_diag, perm = scipy.linalg.qr(G, mode="economic", pivoting=True)
    d = np.abs(np.diag(r_diag))
    rank = int(np.sum(d > GRAVITY_RANK_TOL * d[0]))
    pivots, rest_cols = np.sort(perm[:rank]), np.sort(perm[rank:])
    solve = np.linalg.pinv(G[:, pivots])
    offset = np.zeros(p + nv)
    offset[pivots] = solve @ g
    own = np.sqrt(np.mean(g.reshape(-1, nv) ** 2, axis=0))
    gains, kp_names, load = _gain_groups(nv, equal_kp, own)
    basis = np.zeros((p + nv, rest_cols.size + gains.shape[1]))
    basis[rest_cols, np.arange(rest_cols.size)] = 1.0
    basis[pivots, : rest_cols.size] = -solve @ G[:, rest_cols]
    basis[p:, rest_cols.size :] = gains
    free = tuple(pm.base_names[k] for k in rest_cols)
    total = float(sum(v for v, n in zip(pm.nominal, pm.names, strict=True) if _is_mass(n)))
    note = (
        f"the URDF's gravity load (its masses, total {total:.4g} kg, and centres of mass): the "
        f"{rank} combinations of base parameters the gravity torques see kept at the URDF's "
        f"({rms:.3g} N*m rms over the log's postures)"
    )
    return Scale("mass", offset, basis, free + kp_names, note, load, own)


def gravity_rows(pm: ParameterModel, columns: BaseColumns, q: FloatArray) -> FloatArray:
    """The base regressor (n nv, p) at the postures ``q`` (n, nq) at rest, in base order: the
    gravity torque per unit of each base parameter [N*m per unit]."""
    nv = pm.terms.n_joints
    rest = np.zeros((q.shape[0], nv))
    G = np.zeros((q.shape[0], nv, len(pm.base_names)))
    G[:, :, columns.order] = columns(q, rest, rest)[:, :, : columns.order.size]
    return G.reshape(-1, len(pm.base_names))


def _gain_groups(
    nv: int, equal_kp: tuple[tuple[int, ...], ...], load: FloatArray
) -> tuple[FloatArray, tuple[str, ...], FloatArray]:
    """``S`` (nv, n_k) with ``kp = S k``, the names of ``k`` (``kp1=kp2`` for a group) and
    each joint's ``load`` (nv,) raised to its group's largest."""
    grouped = {j for group in equal_kp for j in group}
    groups = [list(group) for group in equal_kp] + [[j] for j in range(nv) if j not in grouped]
    groups.sort(key=min)
    S = np.zeros((nv, len(groups)))
    tied = load.copy()
    for k, group in enumerate(groups):
        S[group, k] = 1.0
        tied[group] = load[group].max()
    names = tuple("=".join(f"kp{j + 1}" for j in sorted(group)) for group in groups)
    return S, names, tied


def _is_mass(name: str) -> bool:
    """Whether a standard parameter's name is a link's mass (``m<k>``)."""
    return name.rstrip("0123456789") == "m"


def servo_rows(red: ReducedObservations) -> tuple[FloatArray, npt.NDArray[np.int64]]:
    """The rows of ``||W_j beta - kp_j e_j||`` from the reduction of ``[W_j | e_j]``.

    ``red``: the base columns' rows reduced with ``e`` as the torque (n_groups = nv, n = p).
    Returns ``M`` (nv (p + 1), p + nv) with ``||M_j u||^2 = ||W_j beta - kp_j e_j||^2`` for
    ``u = [beta, kp]`` (group ``j``'s rows ``[R_j, -z_j in column p + j]`` and
    ``[0, -sqrt(rho_j)]``), and the group of each row.
    """
    g, p = red.n_groups, red.n_params
    M = np.zeros((g, p + 1, p + g))
    M[:, :p, :p] = red.R
    for j in range(g):
        M[j, :p, p + j] = -red.z[j]
        M[j, p, p + j] = -np.sqrt(red.rho[j])
    return M.reshape(g * (p + 1), p + g), np.repeat(np.arange(g, dtype=np.int64), p + 1)


@dataclass(frozen=True, eq=False)
class _Fit:
    """One scaled fit: ``u = [beta, kp]`` (n_base + nv,), its covariance, the WLS of ``v``,
    the squared residual [N^2*m^2], the relative residual ``||W beta - kp e|| / ||kp e||`` and
    each joint's torque share of the shared parameters (:func:`shared_share`)."""

    u: FloatArray
    covariance: FloatArray
    estimate: Estimate
    residual_ss: float
    relative_residual: float
    shared: FloatArray


def shared_share(red: ReducedObservations, beta: FloatArray) -> FloatArray:
    """Per joint, the share of its torque ``||W_j beta||`` that parameters shared with other
    joints' rows carry, ``||W_j,S beta_S|| / ||W_j beta||`` (nv,): what ties its gain to the
    common scale (a column enters joint ``j`` where ``R_j`` has it, :func:`servo_rows`)."""
    carried = np.any(red.R != 0.0, axis=1)  # (nv, p)
    shared = carried.sum(axis=0) > 1
    total = np.linalg.norm(red.R @ beta, axis=1)
    part = np.linalg.norm(red.R[:, :, shared] @ beta[shared], axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(total > 0, part / total, 0.0)


def scaled_fit(red: ReducedObservations, scale: Scale, method: str = "wls") -> _Fit:
    """The homogeneous fit with the scale fixed: ``v`` by the identification's least squares
    (``method``: ``ols`` or ``wls``) on ``M Z v = -M u0`` (:func:`servo_rows`).

    Raises :class:`NotIdentifiable` (naming the parameters: a ``kp{j}`` when a joint's rows
    share nothing with the others') or :class:`DataError` (too few rows, no finite estimate).
    """
    M, groups = servo_rows(red)
    obs = ReducedObservations.from_rows(M @ scale.basis, -(M @ scale.offset), groups, red.n_groups)
    obs = dataclasses.replace(obs, n_rows=red.n_rows.copy())  # the rows behind the reduction
    est = least_squares_reduced(obs, scale.free, method=method)
    if not est.success:
        raise DataError(f"the position servos' fit failed: {est.message}")
    u = scale.offset + scale.basis @ est.x
    cov = scale.basis @ est.covariance @ scale.basis.T
    ss = float(est.group_residual_ss.sum())
    kp = u[red.n_params :]
    torque_ss = float(np.sum(kp**2 * red.yty))
    relative = float(np.sqrt(ss / torque_ss)) if torque_ss > 0 else float("inf")
    return _Fit(u, cov, est, ss, relative, shared_share(red, u[: red.n_params]))


@dataclass(frozen=True, eq=False)
class ServoFit:
    """What the position servos' fit found (``result.json``'s ``actuator``, the report).

    Attributes
    ----------
    joint_names :
        The joints, in order.
    kp, kp_std :
        Gains [N*m/rad] (nv,) and their standard deviations (NaN when given).
    damping, damping_std :
        ``kd + fv`` [N*m*s/rad] (nv,) (the servo's velocity gain and the viscous friction,
        not separable) and their standard deviations.
    delay_samples, sampling_rate_hz :
        The command's delay in samples, and the log's rate [Hz].
    delay_auto :
        True when the delay was scanned (``actuator.delay: auto``).
    delay_candidates, delay_residuals :
        The delays scanned [samples] and the relative residual of each fit (one entry when
        the delay was given).
    scale, scale_note :
        What fixed the common scale (``kp`` or ``mass``) and how, in words.
    forcerange :
        The force range [N*m] (nv,), or None (saturation not checked).
    n_saturated :
        Samples per joint where the servo may reach the force range (nv,).
    n_excluded :
        Samples the identification does not use: saturated on any joint, or in a stretch
        between such samples too short to filter.
    relative_residual :
        ``||W beta - kp e|| / ||kp e||`` of the final fit (identification rows).
    shared_share :
        Per joint, the share of its torque carried by parameters shared with other joints
        (nv,): a joint below :data:`MIN_SHARED_SHARE` has its gain barely tied to the common
        scale (a light last link whose torque is its own rotor inertia and friction).
    gravity_load :
        ``scale == "mass"``: the URDF's gravity torque per joint over the log's postures
        [N*m rms] (nv,), the largest of its ``equal_kp`` group: what ties each gain to the
        scale; None when the gains were given.
    """

    joint_names: tuple[str, ...]
    kp: FloatArray
    kp_std: FloatArray
    damping: FloatArray
    damping_std: FloatArray
    delay_samples: float
    sampling_rate_hz: float
    delay_auto: bool
    delay_candidates: tuple[float, ...]
    delay_residuals: tuple[float, ...]
    scale: str
    scale_note: str
    forcerange: FloatArray | None
    n_saturated: npt.NDArray[np.int64]
    n_excluded: int
    relative_residual: float
    shared_share: FloatArray
    gravity_load: FloatArray | None = None

    @property
    def delay_s(self) -> float:
        """The command's delay [s]."""
        return self.delay_samples / self.sampling_rate_hz

    def undetermined(self) -> list[str]:
        """The directions the data do not fix, and the checks that did not run, by name."""
        out = [
            "kd and fv: both multiply dq, only their sum kd + fv is identified per joint",
            f"the common scale of every parameter and kp: not in the data, fixed by "
            f"{self.scale_note}",
        ]
        # a gain the gravity load ties (its own joint's or its equal_kp group's) is not loose
        tied = np.zeros(len(self.joint_names), dtype=bool)
        if self.gravity_load is not None:
            tied = self.gravity_load >= MIN_GRAVITY_SHARE * float(np.max(self.gravity_load))
        loose = [
            f"{name} ({100 * share:.2g} %)"
            for name, share, by_gravity in zip(
                self.joint_names, self.shared_share, tied, strict=True
            )
            if share < MIN_SHARED_SHARE and not by_gravity
        ]
        if self.scale == "mass" and loose:
            out.append(
                f"the gains of {', '.join(loose)}: barely tied to the common scale (the share "
                "of the joint's torque from parameters shared with other joints); an "
                "unmodelled torque there (stiction) moves them: give actuator.kp"
            )
        if self.scale == "mass" and self.gravity_load is not None:
            top = float(np.max(self.gravity_load))
            free = [
                f"{name} ({load:.2g} N*m rms)"
                for name, load in zip(self.joint_names, self.gravity_load, strict=True)
                if load < MIN_GRAVITY_SHARE * top
            ]
            if free:
                out.append(
                    f"the gains of {', '.join(free)}: these joints carry (almost) none of the "
                    "URDF's gravity load that fixes the scale, only the shared inertias tie "
                    "their gains to it: give actuator.kp"
                )
        if self.forcerange is None:
            out.append("saturation: not checked (actuator.forcerange not given)")
        return out

    def summary(self) -> dict:
        """JSON-ready values (SI units) for ``result.json``."""
        return {
            "kind": "position",
            "law": "tau = clip(kp (q_cmd(t - d) - q) - kd dq, +-forcerange)",
            "joints": list(self.joint_names),
            "kp": self.kp.tolist(),
            "kp_std": [None if not np.isfinite(v) else float(v) for v in self.kp_std],
            "kp_given": self.scale == "kp",
            "kd_plus_fv": self.damping.tolist(),
            "kd_plus_fv_std": [None if not np.isfinite(v) else float(v) for v in self.damping_std],
            "delay_s": self.delay_s,
            "delay_samples": self.delay_samples,
            "delay_estimated": self.delay_auto,
            "delay_scan": {
                "samples": list(self.delay_candidates),
                "relative_residual": list(self.delay_residuals),
            },
            "scale_from": self.scale,
            "scale_note": self.scale_note,
            "gravity_load": None if self.gravity_load is None else self.gravity_load.tolist(),
            "forcerange": None if self.forcerange is None else self.forcerange.tolist(),
            "saturated_samples": dict(
                zip(self.joint_names, self.n_saturated.tolist(), strict=True)
            ),
            "excluded_samples": self.n_excluded,
            "relative_residual": self.relative_residual,
            "shared_torque_share": self.shared_share.tolist(),
            "undetermined": self.undetermined(),
        }

    def line(self) -> str:
        """One line for the terminal."""
        how = "identified, scale from the URDF's gravity load" if self.scale == "mass" else "given"
        kp = ", ".join(_pm(k, s) for k, s in zip(self.kp, self.kp_std, strict=True))
        damping = ", ".join(_pm(d, s) for d, s in zip(self.damping, self.damping_std, strict=True))
        saturated = (
            "not checked (no actuator.forcerange)"
            if self.forcerange is None
            else f"{self.n_saturated.tolist()}, {self.n_excluded} samples excluded"
        )
        return (
            f"position servos: kp [{kp}] N*m/rad ({how}); kd + fv [{damping}] N*m*s/rad (not "
            f"separable); delay {self.delay_samples:.3g} samples = {1e3 * self.delay_s:.4g} ms "
            f"({'scanned' if self.delay_auto else 'given'}); saturated samples {saturated}"
        )

    def mjcf_servos(self) -> dict[str, dict[str, float | None]]:
        """``{joint: {"kp", "forcerange"}}`` of the identified MJCF's ``<position>`` actuators
        (:func:`ident.identify.model_files.mjcf.identified_mjcf`)."""
        return {
            name: {
                "kp": float(self.kp[j]),
                "forcerange": None if self.forcerange is None else float(self.forcerange[j]),
            }
            for j, name in enumerate(self.joint_names)
        }

    def lines(self) -> list[str]:
        """Markdown of the fit: a table per joint, then the delay, saturation and what the data
        do not fix (the report and the terminal read this one text)."""
        how = "identified" if self.scale == "mass" else "given"
        rows = [
            f"| {name} | {_pm(k, ks)} | {_pm(d, ds)} | {n} |"
            for name, k, ks, d, ds, n in zip(
                self.joint_names,
                self.kp,
                self.kp_std,
                self.damping,
                self.damping_std,
                self.n_saturated,
                strict=True,
            )
        ]
        delay = "scanned and refined, smallest residual" if self.delay_auto else "given"
        return [
            "## Position servos",
            "",
            "Torque from the servo's law `tau = clip(kp (q_cmd(t - d) - q) - kd dq, "
            f"+-forcerange)`; kp {how}. Relative residual of the servo fit "
            f"{100 * self.relative_residual:.3g} %.",
            "",
            "| joint | kp [N*m/rad] ± σ | kd + fv [N*m*s/rad] ± σ | saturated samples |",
            "| --- | ---: | ---: | ---: |",
            *rows,
            "",
            f"- delay d = {self.delay_samples:.3g} samples = {1e3 * self.delay_s:.4g} ms "
            f"({delay}).",
            f"- samples excluded (saturated, or between saturations): {self.n_excluded}.",
            *[f"- not determined: {text}." for text in self.undetermined()],
            "",
        ]


def _pm(value: float, std: float) -> str:
    """``value ± std`` (``value`` alone when the std is not finite: given)."""
    return f"{value:.5g}" if not np.isfinite(std) else f"{value:.5g} ± {std:.2g}"


def _values(values: FloatArray, unit: str) -> str:
    return "[" + ", ".join(f"{v:.5g}" for v in values) + f"] {unit}"


def _per_joint_option(value: object, nv: int, key: str, source: str) -> FloatArray | None:
    """``actuator.<key>`` as one value per joint (nv,), or None when not given."""
    if value is None:
        return None
    try:
        return per_joint(value, nv)  # type: ignore[arg-type]
    except ConfigError as e:
        raise ConfigError(f"{source}: actuator.{key}: {e} (one per joint)") from e


def _equal_kp(
    groups: list[list[str]] | None, joints: tuple[str, ...], source: str
) -> tuple[tuple[int, ...], ...]:
    """``actuator.equal_kp``'s joint names as indices into ``joints``."""
    unknown = [n for group in groups or [] for n in group if n not in joints]
    if unknown:
        raise ConfigError(
            f"{source}: actuator.equal_kp: {', '.join(unknown)} is not a joint of the log "
            f"({', '.join(joints)}); name the joints whose servos share one gain"
        )
    return tuple(tuple(joints.index(n) for n in group) for group in groups or [])


def _runs(mask: BoolArray) -> list[tuple[int, int]]:
    """``[start, stop)`` of every run of True in ``mask`` (n,)."""
    edges = np.diff(np.concatenate([[0], mask.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _kept(log: RobotLog, keep: BoolArray, min_run: int) -> RobotLog:
    """``log`` without the samples ``~keep`` (n_samples,): each run of kept samples of at
    least ``min_run`` samples becomes a segment of its own (the shorter ones are dropped)."""
    if keep.all():
        return log
    index: list[npt.NDArray[np.intp]] = []
    segments, start = [], 0
    for a, b in log.segments:
        for lo, hi in _runs(keep[a:b]):
            if hi - lo >= min_run:
                index.append(np.arange(a + lo, a + hi))
                segments.append((start, start + hi - lo))
                start += hi - lo
    if not index:
        raise DataError(
            f"every stretch of the log between saturated samples is shorter than {min_run} "
            "samples: the servos saturate too often to identify (check actuator.forcerange, or "
            "log a gentler motion)"
        )
    i = np.concatenate(index)
    return dataclasses.replace(
        log,
        t=log.t[i],
        q=log.q[i],
        tau=log.tau[i],
        dq=None if log.dq is None else log.dq[i],
        ddq=None if log.ddq is None else log.ddq[i],
        q_cmd=None if log.q_cmd is None else log.q_cmd[i],
        segments=tuple(segments),
    )


def between_delays(
    red0: ReducedObservations, red1: ReducedObservations, gap: ReducedObservations, f: float
) -> ReducedObservations:
    """The reduction at the delay ``k + f`` (``0 <= f <= 1``) from those at ``k`` and ``k + 1``.

    The error at a fraction of a sample mixes the two shifts, ``e = (1 - f) e_k + f e_k+1``
    (:func:`~ident.dynamics.actuators.servo_error`), and every step of the reduction (filter,
    decimation, rows kept, QR) is linear in ``e`` with the same ``W``. Any quadratic form
    ``Q`` (``||y||^2``, the squared residual outside ``W``'s columns, or ``||W b - y||^2`` for
    any ``b``) then mixes as ``Q(y) = (1 - f) Q(y_k) + f Q(y_k+1) - f (1 - f) Q(y_k - y_k+1)``.
    So the rows of both reductions weighted by ``sqrt(1 - f)`` and ``sqrt(f)`` and merged
    (:meth:`ReducedObservations.merge`: the normal equations ``R^T R``, ``R^T z``), with
    ``||y||^2`` from that identity and the residual ``||y||^2 - ||z||^2`` (the part of ``z``
    a rank-deficient ``R`` does not reach is residual too), are the reduction at ``k + f`` up
    to round-off (the fit's quadratic form ``||R b - kp z||^2 + kp^2 rho``), without the
    log's regressor again.

    ``red0``, ``red1``: the reductions at ``k`` and ``k + 1`` (same rows); ``gap``: that of
    ``e_k - e_k+1``.
    """
    a, b = 1.0 - f, f
    part0 = dataclasses.replace(red0, R=np.sqrt(a) * red0.R, z=np.sqrt(a) * red0.z)
    part1 = dataclasses.replace(red1, R=np.sqrt(b) * red1.R, z=np.sqrt(b) * red1.z)
    merged = part0.merge(part1)  # its residual and ||y||^2 are replaced below
    z, _ = _reached(merged)
    rho0, rho1, rho_gap = (_reached(red)[1] + red.rho for red in (red0, red1, gap))
    return ReducedObservations(
        R=merged.R,
        z=z,
        rho=np.maximum(a * rho0 + b * rho1 - a * b * rho_gap, 0.0),
        yty=np.maximum(a * red0.yty + b * red1.yty - a * b * gap.yty, 0.0),
        n_rows=red0.n_rows.copy(),
    )


def _reached(red: ReducedObservations) -> tuple[FloatArray, FloatArray]:
    """``z`` (n_groups, n) projected on the column space of each ``R`` (what ``R b`` can
    reach; singular values above ``n eps`` of the largest) and the squared norm of the rest
    (n_groups,): residual a rank-deficient group's reduction keeps in ``z``."""
    U, sv, _ = np.linalg.svd(red.R)
    reached = sv > sv[:, :1] * red.n_params * np.finfo(float).eps
    Ur = U * reached[:, None, :]
    z = np.einsum("gij,gkj,gk->gi", Ur, Ur, red.z)
    return z, np.einsum("gi,gi->g", red.z - z, red.z - z)


@dataclass(frozen=True, eq=False)
class _ServoProblem:
    """One log's servo fit for any delay and set of kept samples (:func:`servo_log`)."""

    log: RobotLog
    pp: PreprocessConfig
    columns: BaseColumns
    identify_fraction: float
    scale: Scale
    method: str
    names: tuple[str, ...]  # the base parameters, the first len(names) entries of u

    @property
    def min_run(self) -> int:
        """Shortest stretch of kept samples a segment is made of: the trimmed edges (where
        the filters' transients are, as at any segment's ends), then enough samples for the
        zero-phase filters' padding and a few decimated rows."""
        return 2 * self.pp.trim_samples + 64 + 4 * preprocess.decimation_step(self.pp)

    def error(self, delay: float) -> FloatArray:
        """``e = q_cmd(t - d) - q`` (n_samples, nv) for ``d = delay`` samples."""
        assert self.log.q_cmd is not None  # servo_log checks
        return servo_error(self.log.q, self.log.q_cmd, delay, self.log.segments)

    def reduce(self, e: FloatArray, keep: BoolArray) -> ReducedObservations:
        """The identification rows of the kept samples reduced per joint with ``e``
        (n_samples, nv) as the torque (a servo error, or a difference of two)."""
        log = _kept(dataclasses.replace(self.log, tau=e), keep, self.min_run)
        n_base = self.columns.order.size
        chunked = log_chunks.plan_log(
            log,
            self.pp,
            self.columns,
            identify_fraction=self.identify_fraction,
            chunk_samples=log_chunks.segment_chunk_samples(log, self.pp, n_base),
        )
        return log_chunks.merged_rows(*log_chunks.reduce_log(chunked))

    def fit(self, delay: float, keep: BoolArray) -> _Fit:
        """The scaled fit on the identification rows of the kept samples, ``e`` as torque."""
        return scaled_fit(self.reduce(self.error(delay), keep), self.scale, self.method)

    def scan(
        self, delays: tuple[float, ...], keep: BoolArray, refine: bool = False
    ) -> tuple[float, dict[float, _Fit]]:
        """Every delay's fit and the delay of the smallest residual; with ``refine`` (whole
        ``delays``), that delay to a fraction of a sample: the residual's minimum between the
        best whole delay's neighbours (bounded Brent to :data:`DELAY_TOLERANCE` samples, at
        most :data:`MAX_DELAY_REFINE` fits), its fit added to the scan's. The fits between
        two whole delays come from their reductions (:func:`between_delays`): one more
        reduction per interval, of the difference of their errors, and none per fit."""
        reds = {float(d): self.reduce(self.error(d), keep) for d in delays}
        with one_blas_thread():  # small solves, SVDs: threads only spin (ident.blas)
            fits = {d: scaled_fit(red, self.scale, self.method) for d, red in reds.items()}
        best = min(fits, key=lambda d: fits[d].residual_ss)
        if not refine or len(fits) < 2:
            return best, fits
        lo, hi = max(best - 1.0, min(fits)), min(best + 1.0, max(fits))
        gaps = {
            k: self.reduce(self.error(k) - self.error(k + 1.0), keep) for k in np.arange(lo, hi)
        }
        tried: dict[float, _Fit] = {}

        def residual(d: float) -> float:
            k = float(min(np.floor(d), hi - 1.0))
            red = between_delays(reds[k], reds[k + 1.0], gaps[k], float(d) - k)
            tried[float(d)] = scaled_fit(red, self.scale, self.method)
            return tried[float(d)].residual_ss

        options = {"xatol": DELAY_TOLERANCE, "maxiter": MAX_DELAY_REFINE}
        with one_blas_thread():
            found = scipy.optimize.minimize_scalar(residual, bounds=(lo, hi), method="bounded",
                                                   options=options)  # fmt: skip
        d = float(found.x)
        fit = tried[d] if d in tried else self.fit(d, keep)
        if fit.residual_ss < fits[best].residual_ss:
            fits[d], best = fit, d
        return best, dict(sorted(fits.items()))

    def velocities(self) -> FloatArray:
        """``dq`` [rad/s] (n_samples, nv): the logged ones, else central differences of ``q``
        per segment (for the saturation test only)."""
        if self.log.dq is not None:
            return self.log.dq
        dq = np.zeros_like(self.log.q)
        for a, b in self.log.segments:
            if b - a >= 3:
                dq[a:b] = derivative(self.log.q[a:b], self.log.sampling_rate_hz)
        return dq


def _delays(act: ActuatorSection, rate_hz: float) -> tuple[float, ...]:
    """The delays to fit [samples]: the given one, or every whole one within
    ``max_delay_s`` (the best then refined to a fraction, :meth:`_ServoProblem.scan`)."""
    if act.delay == "auto":
        return tuple(float(d) for d in range(int(np.floor(act.max_delay_s * rate_hz + 1e-9)) + 1))
    return (float(act.delay) * rate_hz,)


def servo_fit_count(act: ActuatorSection, rate_hz: float) -> int:
    """The most accumulations of the log :func:`servo_log` makes (0 for a motor): every delay
    scanned, then three per further saturation round, and the refinement of each scan's
    best delay when it is scanned (for the job's estimate)."""
    if act.kind != "position":
        return 0
    rounds = MAX_SATURATION_ROUNDS - 1 if act.forcerange is not None else 0
    refine = 2 if act.delay == "auto" else 0  # the reductions of the two intervals' gaps
    return len(_delays(act, rate_hz)) + 3 * rounds + refine * (rounds + 1)


def _fit_with_saturation(
    problem: _ServoProblem,
    delays: tuple[float, ...],
    forcerange: FloatArray | None,
    refine: bool = False,
) -> tuple[float, dict[float, _Fit], BoolArray, BoolArray]:
    """The delay, the fits of the last scan, the kept samples (n,) and the saturated ones
    (n, nv): scan, exclude the saturated samples, again until the set stops changing (at most
    :data:`MAX_SATURATION_ROUNDS` scans; after the first, of the best delay and its two
    neighbours only)."""
    n, nv = problem.log.q.shape
    keep = np.ones(n, dtype=bool)
    saturated = np.zeros((n, nv), dtype=bool)
    dq = problem.velocities() if forcerange is not None else None
    if forcerange is not None:
        keep = _first_keep(problem, delays[len(delays) // 2], forcerange)
    scanned = delays
    for _ in range(MAX_SATURATION_ROUNDS):
        delay, fits = problem.scan(scanned, keep, refine)
        # the next rounds move the kept samples a little: the best delay's neighbours suffice
        scanned = tuple(d for d in delays if abs(d - round(delay)) <= 1)
        if forcerange is None or dq is None:
            break
        u = fits[delay].u
        damping = np.nan_to_num(_damping(problem, u)[0])
        kp = u[len(problem.names) :]
        saturated = saturated_samples(problem.error(delay), dq, kp, damping, forcerange)
        unsaturated = np.asarray(~saturated.any(axis=1), dtype=bool)
        if np.array_equal(unsaturated, keep):
            break
        keep = unsaturated
    return delay, fits, keep, saturated


def _first_keep(problem: _ServoProblem, delay: float, forcerange: FloatArray) -> BoolArray:
    """The samples (n,) the first fit uses when the servo may saturate: a saturated sample's
    error is large (the servo cannot follow), and it would pull the fit far off (its force is
    the range, not ``kp e``). With the gains given: where ``|kp e| < forcerange`` on every
    joint; else where every joint's ``|e|`` is at most its :data:`FIRST_FIT_QUANTILE`. The
    next fits use the saturation test of the previous one (:func:`_fit_with_saturation`)."""
    e = np.abs(problem.error(delay))
    if problem.scale.kind == "kp":
        kp = problem.scale.offset[len(problem.names) :]
        return np.all(kp * e < forcerange, axis=1)
    return np.all(e <= np.quantile(e, FIRST_FIT_QUANTILE, axis=0), axis=1)


def _damping(problem: _ServoProblem, u: FloatArray, cov: FloatArray | None = None) -> tuple:
    """``kd + fv`` per joint (the ``fv{j}`` base parameters of ``u``; NaN where the base
    parameters have none) and their standard deviations (NaN without ``cov``)."""
    nv = problem.log.q.shape[1]
    names = problem.names
    index = [names.index(f"fv{j + 1}") if f"fv{j + 1}" in names else -1 for j in range(nv)]
    value = np.array([u[i] if i >= 0 else np.nan for i in index])
    std = np.full(nv, np.nan)
    if cov is not None:
        std = np.array([np.sqrt(max(cov[i, i], 0.0)) if i >= 0 else np.nan for i in index])
    return value, std


def servo_log(
    cfg: IdentifyConfig, model: pin.Model, log: RobotLog, source: str = "config"
) -> tuple[IdentifyConfig, RobotLog, ServoFit]:
    """A position servo's log made an identification's: ``tau = kp e`` (module docstring).

    Parameters
    ----------
    cfg :
        The identify config (``actuator.kind: position``).
    model :
        The robot's Pinocchio model.
    log :
        The log read, with its commanded positions ``q_cmd`` (and no torque).
    source :
        Config file name for messages.

    Returns
    -------
    :
        ``cfg`` with its automatic preprocessing settings resolved on the whole log (so that
        the identification does not choose them again on a stretch between saturations),
        the log to identify (torque ``kp e``, excluded samples cut out, a record of the
        servo's step) and the fit.

    Raises
    ------
    ConfigError, DataError, NotIdentifiable
        A per-joint option of the wrong length, no commanded positions, a scale the motion
        does not fix, too few rows.
    """
    if log.q_cmd is None:
        raise DataError(f"{source}: log.command: no commanded positions were read.")
    act, nv = cfg.actuator, model.nv
    pp, records, _ = preprocess.resolve_for_log(cfg.preprocess, log)
    pp = _servo_preprocess(pp)
    pm = build_parameter_model(model, cfg.model.extra_terms(nv, source))
    forcerange = _per_joint_option(act.forcerange, nv, "forcerange", source)
    columns = BaseColumns(chain_from_model(model), pm)
    scale = _scale(act, pm, columns, log, source)
    problem = _ServoProblem(
        log,
        pp,
        columns,
        cfg.validation.identify_fraction,
        scale,
        cfg.estimation.least_squares_method,
        tuple(pm.base_names),
    )
    delays = _delays(act, log.sampling_rate_hz)
    auto = act.delay == "auto"
    delay, fits, keep, saturated = _fit_with_saturation(problem, delays, forcerange, auto)
    fit = _servo_fit(problem, delay, fits, (keep, saturated), forcerange, auto)
    _check_gravity_carried(problem.scale, fit.kp * problem.error(delay)[keep], fit, source)
    all_records = (*log.records, *records, _record(fit))
    out = _kept(dataclasses.replace(log, tau=fit.kp * problem.error(delay), records=all_records),
                keep, problem.min_run)  # fmt: skip
    return cfg.model_copy(update={"preprocess": pp}), out, fit


def _check_gravity_carried(scale: Scale, torque: FloatArray, fit: ServoFit, source: str) -> None:
    """With the scale from the URDF's gravity load, each loaded joint's identified servo
    torque ``torque`` (n_kept, nv) [N*m] must carry that load: far below it (less than
    1 / :data:`MAX_GRAVITY_OVER_TORQUE` of it, rms), the fit put the scale in a direction the
    motion does not see (the links' inertias mimicking the gravity of a slow periodic
    motion) and every gain went to 0: :class:`DataError` naming the joints."""
    if scale.own_load is None:
        return
    servo = np.sqrt(np.mean(torque**2, axis=0))
    low = [
        f"{name} ({t:.2g} N*m rms for a gravity load of {g:.2g}, kp {k:.3g} N*m/rad)"
        for name, t, g, k in zip(fit.joint_names, servo, scale.own_load, fit.kp, strict=True)
        if g > MAX_GRAVITY_OVER_TORQUE * t
    ]
    if low:
        raise DataError(
            f"{source}: actuator.scale_from: mass: the identified servo torque of "
            f"{', '.join(low)} is far below the URDF's gravity load it carries: the motion does "
            "not tell the gravity from the links' inertias (too slow, or periodic at one "
            "rate); log an excitation with a few Hz in it and postures that load gravity, or "
            "give the servos' gain actuator.kp [N*m/rad]"
        )


def _scale(
    act: ActuatorSection, pm: ParameterModel, columns: BaseColumns, log: RobotLog, source: str
) -> Scale:
    """What fixes the scale (``actuator.scale_from``): the gains given, or the URDF's gravity
    load on the log's postures (every :data:`GRAVITY_POSTURE_STEP`-th), ``equal_kp`` tied."""
    kp = _per_joint_option(act.kp, pm.terms.n_joints, "kp", source)
    if act.scale == "kp" and kp is not None:
        return kp_scale(pm, kp)
    groups = _equal_kp(act.equal_kp, log.joint_names, source)
    return mass_scale(pm, columns, log.q[::GRAVITY_POSTURE_STEP], groups)


def _servo_preprocess(pp: PreprocessConfig) -> PreprocessConfig:
    """``pp`` with the positions' low-pass as the torques' when none is given: ``kp e`` is a
    function of the measured positions (``e = q_cmd(t - d) - q``), so filtered alike the
    servo's law holds in the band the regressor sees, and the encoder's ticks in ``q`` stay
    out of the residual (unfiltered, they dominate it and hide the delay; measured on the
    SO-101-like arm with 4096 ticks: the wrist's gain 3 % low, the delay's residual minimum
    +-20 % instead of +-50-80 %)."""
    lowpass = preprocess.position_filter(pp)
    if pp.torque_lowpass is not None or lowpass is None:
        return pp
    return pp.model_copy(update={"torque_lowpass": lowpass})


def _servo_fit(
    problem: _ServoProblem,
    delay: float,
    fits: dict[float, _Fit],
    samples: tuple[BoolArray, BoolArray],
    forcerange: FloatArray | None,
    auto: bool,
) -> ServoFit:
    """The :class:`ServoFit` of the chosen ``delay``'s fit; ``samples``: the kept (n,) and
    saturated (n, nv) ones."""
    keep, saturated = samples
    fit = fits[delay]
    p = len(problem.names)
    kp = fit.u[p:]
    kp_std = np.sqrt(np.clip(np.diag(fit.covariance)[p:], 0.0, None))
    if problem.scale.kind == "kp":
        kp_std = np.full(kp.size, np.nan)  # given
    damping, damping_std = _damping(problem, fit.u, fit.covariance)
    kept = _kept(problem.log, keep, problem.min_run).n_samples
    return ServoFit(
        joint_names=problem.log.joint_names,
        kp=kp,
        kp_std=kp_std,
        damping=damping,
        damping_std=damping_std,
        delay_samples=delay,
        sampling_rate_hz=problem.log.sampling_rate_hz,
        delay_auto=auto,
        delay_candidates=tuple(fits),
        delay_residuals=tuple(f.relative_residual for f in fits.values()),
        scale=problem.scale.kind,
        scale_note=problem.scale.note,
        forcerange=forcerange,
        n_saturated=saturated.sum(axis=0).astype(np.int64),
        n_excluded=problem.log.n_samples - kept,
        relative_residual=fit.relative_residual,
        shared_share=fit.shared,
        gravity_load=problem.scale.gravity_load,
    )


def _record(fit: ServoFit) -> dict:
    """The processing record of the servo's step (the report's table, ``result.json``)."""
    how = "identified" if fit.scale == "mass" else "given"
    return {
        "step": "actuator",
        "detail": f"position servo: tau = kp (q_cmd(t - d) - q), kp {how} "
        f"{_values(fit.kp, 'N*m/rad')}, d = {fit.delay_samples:.3g} samples "
        f"({1e3 * fit.delay_s:.4g} ms, {'scanned' if fit.delay_auto else 'given'}); the "
        f"servo's kd enters the viscous column (fv{{j}} is kd + fv); scale fixed by "
        f"{fit.scale_note}; {fit.n_excluded} samples excluded (saturated: "
        f"{'not checked' if fit.forcerange is None else fit.n_saturated.tolist()})",
        "delay_s": fit.delay_s,
    }
