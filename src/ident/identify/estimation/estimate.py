"""Linear least-squares estimation of base parameters: OLS and WLS with standard deviations.

The identification model is linear in the parameters, ``tau = W x + e``. This module solves it
by a QR factorisation of the observation matrix (never by the normal equations) and returns an
:class:`Estimate` with the parameter standard deviations ``sqrt(diag(sigma^2 (W^T W)^-1))``
computed from the triangular factor.

Weighted least squares (WLS) follows Gautier's IDIM-WLS: a first OLS pass estimates one error
variance per group of rows (per joint); the rows of each group are then scaled by ``1/sigma_j``
(row scaling, no dense diagonal matrix) and the scaled system is solved again.

References
----------
M. Gautier, "Dynamic identification of robots with power model", ICRA 1997;
M. Gautier and W. Khalil, "Exciting trajectories for the identification of base inertial
parameters of robots", IJRR 1992.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import scipy.linalg

from ident.errors import DataError, NotIdentifiable
from ident.identify.estimation.observations import ReducedObservations

__all__ = ["Estimate", "least_squares", "least_squares_reduced", "rank_report"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

METHODS = ("ols", "wls")

# A joint's residual standard deviation below this fraction of its torque RMS counts as zero
# (noise-free data): WLS then keeps the pooled OLS weight for that joint.
_ZERO_SIGMA_RTOL = 1e-10


@dataclass(frozen=True, eq=False)  # arrays: no field-wise ==, made read-only
class Estimate:
    """Outcome of a least-squares parameter estimate; check ``success`` before use.

    Attributes
    ----------
    x :
        Estimated parameters, SI units, shape (n_params,).
    names :
        Parameter names, length n_params.
    std :
        Standard deviations of ``x``, shape (n_params,).
    relative_std :
        ``100 * std / |x|`` [%], ``inf`` where ``x == 0``, shape (n_params,).
    method :
        ``"ols"`` or ``"wls"``.
    residual_rms :
        RMS of the unweighted residual ``tau - W x`` per row group (joint) [N*m],
        shape (n_groups,).
    relative_residual :
        ``||tau - W x|| / ||tau||`` over all rows (unweighted).
    sigma :
        Per-group noise standard deviation used for the weights [N*m], shape (n_groups,);
        for OLS the pooled value repeated.
    condition_number :
        2-norm condition number of the (unweighted) observation matrix ``W``.
    n_samples :
        Number of samples (``n_observations / rows_per_sample`` for a full sample-major
        stack; the number of observation rows when rows are grouped by ``groups``).
    success :
        False if the estimate is unusable (message says why).
    message :
        What happened, including any WLS fallback.
    n_observations :
        Number of observation rows ``m`` of ``W``.
    covariance :
        Parameter covariance matrix, shape (n_params, n_params).
    theta :
        Standard parameters behind ``x`` (``x = K theta``), shape (n_std,), when the estimator
        works on them (:mod:`ident.identify.estimators`); empty otherwise.
    consistency :
        Per-body physical consistency of ``theta``
        (:class:`~ident.identify.estimation.consistency.BodyConsistency`); empty without ``theta``.
    group_residual_ss :
        Squared residual per row group ``||W_j x - y_j||^2`` [N^2*m^2], shape (n_groups,).
    regularization :
        Weight of the prior toward the nominal parameters (0: none).
    distance_to_nominal :
        Scaled distance ``||D (theta - theta_nominal)||`` (see
        :class:`~ident.identify.estimators.ParameterStructure`), NaN without ``theta``.
    """

    x: FloatArray
    names: tuple[str, ...]
    std: FloatArray
    relative_std: FloatArray
    method: str
    residual_rms: FloatArray
    relative_residual: float
    sigma: FloatArray
    condition_number: float
    n_samples: int
    success: bool
    message: str
    n_observations: int = 0
    covariance: FloatArray = field(default_factory=lambda: np.zeros((0, 0)))
    theta: FloatArray = field(default_factory=lambda: np.zeros(0))
    consistency: tuple = ()
    group_residual_ss: FloatArray = field(default_factory=lambda: np.zeros(0))
    regularization: float = 0.0
    distance_to_nominal: float = float("nan")

    @property
    def consistent(self) -> bool | None:
        """Every body consistent (None when the estimate carries no standard parameters)."""
        if not self.consistency:
            return None
        return all(c.consistent for c in self.consistency)

    def __post_init__(self) -> None:
        for name in (
            "x",
            "std",
            "relative_std",
            "residual_rms",
            "sigma",
            "covariance",
            "theta",
            "group_residual_ss",
        ):
            value = getattr(self, name)
            if isinstance(value, np.ndarray):
                value.flags.writeable = False

    def predict(self, W: FloatArray) -> FloatArray:
        """Predicted stacked torques ``W @ x`` [N*m], shape (m,)."""
        return np.asarray(W, dtype=float) @ self.x


def _as_groups(
    tau: FloatArray, m: int, rows_per_sample: int | None, groups: npt.ArrayLike | None
) -> tuple[FloatArray, IntArray, int, int]:
    """Flatten ``tau`` and give the group (joint) index of every row."""
    tau = np.asarray(tau, dtype=float)
    if tau.ndim == 2:
        if rows_per_sample is not None and rows_per_sample != tau.shape[1]:
            raise DataError(
                f"tau has {tau.shape[1]} columns but rows_per_sample={rows_per_sample}; "
                "pass tau as (n_samples, n_rows) or stacked (n_samples*n_rows,)."
            )
        rows_per_sample = tau.shape[1]
        tau = tau.reshape(-1)  # sample-major: rows are (sample, joint)
    elif tau.ndim != 1:
        raise DataError(f"tau must be 1-D or 2-D, got shape {tau.shape}.")
    if tau.shape[0] != m:
        raise DataError(
            f"W has {m} rows but tau has {tau.shape[0]} values; they must describe the same "
            "stacked observations."
        )
    if groups is not None:
        group_of_row = np.asarray(groups, dtype=np.int64).reshape(-1)
        if group_of_row.shape[0] != m:
            raise DataError(f"groups has {group_of_row.shape[0]} entries, W has {m} rows.")
        if group_of_row.min(initial=0) < 0:
            raise DataError("groups must be non-negative row-group (joint) indices.")
        n_groups = int(group_of_row.max(initial=-1)) + 1
        return tau, group_of_row, n_groups, m
    rows_per_sample = 1 if rows_per_sample is None else int(rows_per_sample)
    if rows_per_sample < 1 or m % rows_per_sample:
        raise DataError(f"W has {m} rows, not a multiple of rows_per_sample={rows_per_sample}.")
    group_of_row = np.tile(np.arange(rows_per_sample, dtype=np.int64), m // rows_per_sample)
    return tau, group_of_row, rows_per_sample, m // rows_per_sample


RANK_ADVICE = (
    "Reduce to base parameters, drop the parameter(s), or record a motion that excites them."
)


def rank_report(
    W: FloatArray, names: tuple[str, ...] | list[str], *, advice: str = RANK_ADVICE
) -> str | None:
    """Describe why ``W`` is rank deficient, or return None if it has full column rank.

    Columns are first compared with the largest column norm: a column whose norm is below
    ``max(m, n) * eps`` times it has no effect (the parameter is not excited). The remaining
    columns are scaled to unit norm and a null space is read from the SVD of their triangular
    factor: the parameters with non-negligible weight in a null vector appear only in a linear
    combination. They are named once (the union over the null space, in column order) with the
    null-space dimension, so the sentence stays short however many directions are missing.

    Parameters
    ----------
    W :
        Observation matrix, shape (m, n_params).
    names :
        Parameter names, length n_params.
    advice :
        Sentence appended after the diagnosis (default :data:`RANK_ADVICE`; ``""`` for none).

    Returns
    -------
    :
        One sentence naming the parameters (plus ``advice``), or None if ``W`` has full
        column rank.
    """
    W = np.asarray(W, dtype=float)
    m, n = W.shape
    norms = np.linalg.norm(W, axis=0)
    scale = norms.max(initial=0.0)
    tol = max(m, n) * np.finfo(float).eps
    dead = norms <= tol * scale if scale > 0 else np.ones(n, dtype=bool)
    parts: list[str] = []
    if dead.any():
        dead_names = [names[i] for i in np.flatnonzero(dead)]
        parts.append(
            f"parameter(s) {', '.join(dead_names)} have no effect on the torques "
            "(not excited by the motion, or removed by the velocity threshold)"
        )
    live = np.flatnonzero(~dead)
    clause = _combination_clause(W[:, live] / norms[live], live, n, tol, names) if live.size else ""
    if clause:
        parts.append(clause)
    if not parts:
        return None
    return "; ".join(parts) + "." + (f" {advice}" if advice else "")


def _combination_clause(
    Wn: FloatArray,
    live: npt.NDArray[np.intp],
    n: int,
    tol: float,
    names: tuple[str, ...] | list[str],
) -> str:
    """The clause of :func:`rank_report` naming the parameters in a linear combination, from
    the unit-norm columns ``Wn`` (m, len(live)) of the excited parameters ``live``; "" for
    none."""
    R = scipy.linalg.qr(Wn, mode="r", check_finite=False)[0][: live.size]
    _, s, Vt = np.linalg.svd(R)
    null = Vt[s <= tol * max(s[0], 1.0) * 10.0]
    if not null.shape[0]:
        return ""
    # one clause for the whole null space: the union of its supports, in column order
    involved = np.zeros(n, dtype=bool)
    for v in null:
        involved[live[np.abs(v) > 1e-6 * np.abs(v).max()]] = True
    members = np.flatnonzero(involved)
    clause = (
        "parameters "
        + ", ".join(names[i] for i in members)
        + " enter the torques only in a linear combination"
    )
    if null.shape[0] > 1:
        clause += (
            f" ({null.shape[0]} independent combinations of these {members.size} are undetermined)"
        )
    return clause


def _covariance_unit(R: FloatArray) -> FloatArray:
    """``(W^T W)^-1 = R^-1 R^-T`` from the triangular factor (no normal equations)."""
    R_inv = scipy.linalg.solve_triangular(R, np.eye(R.shape[0]), check_finite=False)
    return R_inv @ R_inv.T


def least_squares(
    W: FloatArray,
    tau: FloatArray,
    names: tuple[str, ...] | list[str],
    *,
    method: str = "ols",
    rows_per_sample: int | None = None,
    groups: npt.ArrayLike | None = None,
    wls_passes: int = 2,
) -> Estimate:
    """Estimate ``x`` in ``tau = W x + e`` by ordinary or weighted least squares.

    Parameters
    ----------
    W :
        Observation matrix, sample-major stacked, shape (n_samples * n_rows, n_params).
    tau :
        Measured torques [N*m], shape (n_samples, n_rows) or stacked (n_samples * n_rows,).
    names :
        Parameter names, length n_params.
    method :
        ``"ols"``: one noise variance ``sigma^2 = ||r||^2 / (m - n)``, covariance
        ``sigma^2 (W^T W)^-1``. ``"wls"``: per-group variances from an OLS pass,
        ``sigma_j^2 = ||r_j||^2 / (m_j (m - n) / m)`` (the degrees of freedom shared in
        proportion to the rows), rows scaled by ``1 / sigma_j``, covariance
        ``sigma_w^2 (W_s^T W_s)^-1`` with ``sigma_w^2`` the variance of the scaled residual
        (about 1). With equal per-group variances WLS equals OLS exactly.
    rows_per_sample :
        Rows per sample (joints) when ``tau`` is stacked; inferred from a 2-D ``tau``.
    groups :
        Optional group (joint) index of every row, shape (m,), for stacks where rows were
        removed per joint (velocity threshold); overrides ``rows_per_sample`` for grouping.
    wls_passes :
        WLS only: number of weighted solves. Pass 1 takes the variances from the OLS residual
        (Gautier's IDIM-WLS); each further pass re-estimates them from the previous WLS
        residual, which the noisiest joint no longer contaminates (iterated feasible GLS).

    Returns the :class:`Estimate`. Raises :class:`DataError` on shape mismatch, non-finite
    values, or too few rows (``m <= n_params``); :class:`NotIdentifiable` if ``W`` is rank
    deficient, the message naming the parameter(s) with no effect or in a linear combination.

    Notes
    -----
    WLS with a zero residual variance on a group (noise-free data, ``sigma_j`` below
    ``1e-10`` times that group's torque RMS) does not divide by zero: that group keeps the
    pooled OLS weight and ``message`` says so. If every group is noise free the result is
    the OLS solution.
    """
    if method not in METHODS:
        raise DataError(f"method={method!r} is not one of {', '.join(METHODS)}.")
    W, names = _checked_matrix(W, names)
    m = W.shape[0]
    tau_flat, group_of_row, n_groups, n_samples = _as_groups(tau, m, rows_per_sample, groups)
    _check_finite(W, tau_flat, names)
    # one implementation of the formulas: the rows reduced per group (a QR each), then
    # least_squares_reduced (same estimate, standard deviations and residuals)
    obs = ReducedObservations.from_rows(W, tau_flat, group_of_row, n_groups)
    return least_squares_reduced(
        obs, names, method=method, wls_passes=wls_passes, n_samples=n_samples
    )


def _solve(
    obs: ReducedObservations, names: tuple[str, ...]
) -> tuple[FloatArray, FloatArray, float]:
    """The least-squares solution (n_params,) of the reduced rows, their stacked triangular
    factor and its condition number; raises :class:`NotIdentifiable` (naming the parameters,
    :func:`rank_report`) when it is singular."""
    R_all = obs.R.reshape(-1, obs.n_params)  # same column norms and singular values as W
    R, z = obs.stacked()
    x = scipy.linalg.solve_triangular(R, z, check_finite=False)
    s = np.linalg.svd(R, compute_uv=False)
    condition_number = float(s[0] / s[-1]) if s[-1] > 0 else float("inf")
    if not np.isfinite(condition_number) or condition_number > 1.0 / np.finfo(float).eps:
        singular = f"observation matrix is singular (cond={condition_number})."
        raise NotIdentifiable(rank_report(R_all, names) or singular)
    return x, R, condition_number


def _noise_model(
    obs: ReducedObservations,
    method: str,
    x: FloatArray,
    R: FloatArray,
    ss_group: FloatArray,
    wls_passes: int,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, str]:
    """(x, covariance, sigma per group, residual sum of squares per group, message) of OLS
    (one pooled sigma) or WLS (:func:`_wls`), from the OLS solution ``x`` and its residuals."""
    dof = int(obs.n_rows.sum()) - obs.n_params
    sigma_pooled = float(np.sqrt(ss_group.sum() / dof))
    if method == "ols":
        cov = sigma_pooled**2 * _covariance_unit(R)
        return x, cov, np.full(obs.n_groups, sigma_pooled), ss_group, "ok"
    return _wls(obs, x, ss_group, sigma_pooled, wls_passes)


def _checked_matrix(
    W: FloatArray, names: tuple[str, ...] | list[str]
) -> tuple[FloatArray, tuple[str, ...]]:
    """``W`` as a 2-D float array (m, n_params) and its n_params column ``names`` as a tuple;
    raises :class:`DataError` otherwise."""
    W = np.asarray(W, dtype=float)
    if W.ndim != 2:
        raise DataError(f"W must be 2-D (rows, parameters), got shape {W.shape}.")
    n = W.shape[1]
    names = tuple(names)
    if len(names) != n:
        raise DataError(f"{len(names)} names for {n} columns of W.")
    return W, names


def _check_finite(W: FloatArray, tau_flat: FloatArray, names: tuple[str, ...]) -> None:
    """Raise :class:`DataError` naming the columns of ``W`` or the torques with NaN/inf."""
    if not np.all(np.isfinite(W)):
        bad = sorted({names[j] for j in np.flatnonzero(~np.isfinite(W).all(axis=0))})
        raise DataError(f"observation matrix has NaN/inf in the column(s) of {', '.join(bad)}.")
    if not np.all(np.isfinite(tau_flat)):
        raise DataError("measured torques contain NaN/inf values; clean or trim the log.")


def _wls(
    obs: ReducedObservations,
    x: FloatArray,
    ss_group: FloatArray,
    sigma_pooled: float,
    passes: int,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, str]:
    """WLS passes from the OLS solution ``x`` (:func:`least_squares`, ``method="wls"``):
    ``(x, covariance, sigma per group, residual sum of squares per group, message)``."""
    n_groups, n = obs.n_groups, obs.n_params
    rows_in_group = obs.n_rows.astype(float)
    m = int(obs.n_rows.sum())
    dof = m - n
    zero = np.zeros(n_groups, dtype=bool)
    with np.errstate(invalid="ignore", divide="ignore"):
        tau_rms = np.sqrt(obs.yty / rows_in_group)
    for _ in range(passes):
        with np.errstate(invalid="ignore", divide="ignore"):
            sigma = np.sqrt(ss_group / (rows_in_group * dof / m))
        zero = ~(sigma > _ZERO_SIGMA_RTOL * tau_rms) & (rows_in_group > 0)
        if zero.any():
            sigma = np.where(zero, sigma_pooled if sigma_pooled > 0 else 1.0, sigma)
        sigma = np.where(rows_in_group > 0, sigma, np.nan)
        # empty groups carry no rows: any finite weight leaves the solution unchanged
        weight = np.where(rows_in_group > 0, 1.0 / sigma, 0.0)
        Rs, zs = obs.stacked(weight)
        x = scipy.linalg.solve_triangular(Rs, zs, check_finite=False)
        ss_group = obs.residual_ss(x)
    message = "ok"
    if zero.any():
        message = (
            "WLS: zero residual variance on group(s) "
            + ", ".join(str(j) for j in np.flatnonzero(zero))
            + " (noise-free data); used the pooled OLS weight there."
        )
    sigma_w2 = float(np.sum(weight**2 * ss_group) / dof)
    cov = sigma_w2 * _covariance_unit(Rs)
    # the per-group std the covariance assumes: sigma_j * sigma_w (sigma_w ~ 1)
    sigma = sigma * np.sqrt(sigma_w2) if sigma_w2 > 0 else sigma
    return x, cov, sigma, ss_group, message


def _checked(
    obs: ReducedObservations, names: tuple[str, ...] | list[str], method: str
) -> tuple[str, ...]:
    """``names`` as a tuple, after the checks of :func:`least_squares_reduced`."""
    if method not in METHODS:
        raise DataError(f"method={method!r} is not one of {', '.join(METHODS)}.")
    n = obs.n_params
    names = tuple(names)
    if len(names) != n:
        raise DataError(f"{len(names)} names for {n} columns of W.")
    if not (np.all(np.isfinite(obs.R)) and np.all(np.isfinite(obs.z))):
        raise DataError("reduced observations contain NaN/inf; clean or trim the log.")
    obs.check_enough_rows()
    problem = rank_report(obs.R.reshape(-1, n), names)
    if problem is not None:
        raise NotIdentifiable(problem)
    return names


def least_squares_reduced(
    observations: ReducedObservations,
    names: tuple[str, ...] | list[str],
    *,
    method: str = "ols",
    wls_passes: int = 2,
    n_samples: int | None = None,
) -> Estimate:
    """:func:`least_squares` on rows already reduced per group (joint).

    Gives the same estimate, standard deviations, per-group sigma, residuals and condition
    number as :func:`least_squares` on the rows (up to round-off), from
    :class:`~ident.identify.estimation.observations.ReducedObservations` whose size does not depend
    on the number of rows: ``||W_j x - y_j||^2 = ||R_j x - z_j||^2 + rho_j``.

    Parameters
    ----------
    observations, names :
        The reduced rows, one group per joint; parameter names, length n_params.
    method, wls_passes :
        As in :func:`least_squares`.
    n_samples :
        Reported ``n_samples`` (default: the number of rows, as :func:`least_squares` with
        ``groups``).

    Raises :class:`DataError`, :class:`NotIdentifiable` as :func:`least_squares`.
    """
    obs = observations
    names = _checked(obs, names, method)
    m = int(obs.n_rows.sum())
    x, R, condition_number = _solve(obs, names)
    ss_group = obs.residual_ss(x)
    x, cov, sigma, ss_group, message = _noise_model(obs, method, x, R, ss_group, wls_passes)
    std = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        relative_std = np.where(x != 0.0, 100.0 * std / np.abs(x), np.inf)
        residual_rms = np.sqrt(ss_group / obs.n_rows.astype(float))
    tau_norm = float(np.sqrt(obs.yty.sum()))
    relative_residual = float(np.sqrt(ss_group.sum()) / tau_norm) if tau_norm > 0 else float("inf")
    success = bool(np.all(np.isfinite(x)) and np.all(np.isfinite(std)))
    if not success:
        message = "non-finite estimate or standard deviation; check the data scaling."
    return Estimate(
        x=x,
        names=names,
        std=std,
        relative_std=relative_std,
        method=method,
        residual_rms=residual_rms,
        relative_residual=relative_residual,
        sigma=sigma,
        condition_number=condition_number,
        n_samples=m if n_samples is None else int(n_samples),
        success=success,
        message=message,
        n_observations=m,
        covariance=cov,
        group_residual_ss=ss_group,
    )
