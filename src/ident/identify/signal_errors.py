"""Errors of the measured torque signal: a constant delay, a gain per joint, an offset.

Model of the measured torque of joint ``j`` (``Y`` the regressor at the positions' times,
``theta`` the parameters, ``d`` the delay [s], ``g_j`` the gain, ``o_j`` the offset [N*m])::

    tau_meas_j(t) = g_j (Y_j(t) theta) (t - d) + o_j

**Delay.** The torque is resampled at ``t + d`` (linear interpolation; samples whose ``t + d``
falls outside the log are dropped) and the linear least-squares fit of ``Y`` to it is redone;
:func:`estimate_delay` scans ``d`` on a grid and refines the best point by a bounded
golden-section search (``scipy.optimize.minimize_scalar``, Brent's method) of the relative
residual. The regressor is computed once: only the torque moves.

**Gain.** The gains and the parameters are known together up to one common scale, so one
reference is needed: the gain of one joint (here: ``g_r`` known). With ``h_j = 1 / g_j`` the
model is linear in ``(theta, h)``::

    Y_r theta = g_r^-1 tau_meas_r,      Y_j theta - h_j tau_meas_j = 0   (j != r)

one least-squares solve (:func:`estimate_gains`). The joints share the rigid-body parameters,
which is what makes the ``h_j`` identifiable; a joint whose row depends only on its own
parameters is not (its column is then rank deficient: DataError). With an offset column in
``Y`` (``off_j``), the offset is ``o_j = g_j theta_off_j``. A payload of known mass as the
reference is not implemented here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize_scalar

from ident.errors import DataError

__all__ = ["DelayEstimate", "GainEstimate", "delay_residual", "estimate_delay", "estimate_gains"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def delay_residual(
    delay_s: float,
    t: FloatArray,
    tau: FloatArray,
    Y: FloatArray,
    keep: BoolArray | None = None,
    *,
    margin_s: float = 0.0,
) -> float:
    """Relative residual ``||r|| / ||tau||`` of the fit of ``Y`` to the torque advanced by
    ``delay_s``.

    Parameters
    ----------
    delay_s :
        Delay of the torque behind the positions [s] (negative: ahead).
    t :
        Sample times [s], increasing, shape (n,).
    tau :
        Measured torques [N*m], shape (n, nv).
    Y :
        Regressor at ``t``, shape (n, nv, p).
    keep :
        Entries used, shape (n, nv); None: all.
    margin_s :
        Samples within ``margin_s`` of either end are never used, so that every delay of the
        search fits the same rows [s].
    """
    n, nv = tau.shape
    shifted = np.column_stack([np.interp(t + delay_s, t, tau[:, j]) for j in range(nv)])
    inside = (t >= t[0] + margin_s) & (t <= t[-1] - margin_s)
    inside &= (t + delay_s >= t[0]) & (t + delay_s <= t[-1])
    mask = np.broadcast_to(inside[:, None], (n, nv))
    if keep is not None:
        mask = mask & keep
    rows = mask.reshape(-1)
    A = Y.reshape(n * nv, -1)[rows]
    y = shifted.reshape(-1)[rows]
    r = y - A @ np.linalg.lstsq(A, y, rcond=None)[0]
    return float(np.linalg.norm(r) / np.linalg.norm(y))


@dataclass(frozen=True, eq=False)
class DelayEstimate:
    """A delay estimate.

    Attributes
    ----------
    delay_s :
        The delay of the torque behind the positions [s].
    residual :
        Relative residual at ``delay_s``.
    scan_delays_s, scan_residuals :
        The grid scanned and its residuals, shape (n_grid,).
    """

    delay_s: float
    residual: float
    scan_delays_s: FloatArray
    scan_residuals: FloatArray


def estimate_delay(
    t: FloatArray,
    tau: FloatArray,
    Y: FloatArray,
    *,
    max_delay_s: float,
    keep: BoolArray | None = None,
    n_grid: int = 21,
    tol_s: float = 1e-5,
) -> DelayEstimate:
    """The constant delay of the torque behind the positions, in ``[-max_delay_s, max_delay_s]``.

    A scan of ``n_grid`` delays, then a bounded golden-section search (to ``tol_s`` [s]) between
    the neighbours of the best one (module docstring). Shapes as in :func:`delay_residual`.

    Raises
    ------
    DataError
        If ``max_delay_s`` is not positive or not below a quarter of the log.
    """
    t = np.asarray(t, dtype=float)
    if not 0.0 < max_delay_s < 0.25 * (t[-1] - t[0]):
        raise DataError(
            f"max_delay_s = {max_delay_s:g} s: give a delay bound > 0 and below a quarter of "
            f"the log ({t[-1] - t[0]:g} s)."
        )
    grid = np.linspace(-max_delay_s, max_delay_s, n_grid)

    def cost(d: float) -> float:
        return delay_residual(d, t, tau, Y, keep, margin_s=max_delay_s)

    scan = np.array([cost(d) for d in grid])
    best = int(np.argmin(scan))
    lo, hi = grid[max(best - 1, 0)], grid[min(best + 1, n_grid - 1)]
    result = minimize_scalar(cost, bounds=(lo, hi), method="bounded", options={"xatol": tol_s})
    delay = float(result.x) if result.fun <= scan[best] else float(grid[best])
    return DelayEstimate(
        delay_s=delay,
        residual=min(float(result.fun), float(scan[best])),
        scan_delays_s=grid,
        scan_residuals=scan,
    )


@dataclass(frozen=True, eq=False)
class GainEstimate:
    """Torque gains per joint and the parameters, given one joint's gain.

    Attributes
    ----------
    gains :
        ``g_j`` per joint (the reference joint's as given), shape (nv,).
    theta :
        Parameters of the columns of ``Y`` in true torque units, shape (p,).
    """

    gains: FloatArray
    theta: FloatArray


def estimate_gains(
    Y: FloatArray,
    tau: FloatArray,
    *,
    reference_joint: int,
    reference_gain: float = 1.0,
    keep: BoolArray | None = None,
) -> GainEstimate:
    """Per-joint torque gains with the gain of ``reference_joint`` (0-based) known.

    Parameters
    ----------
    Y :
        Regressor, shape (n, nv, p).
    tau :
        Measured torques [N*m or the logged unit], shape (n, nv).
    reference_joint, reference_gain :
        The joint whose gain is known, and that gain.
    keep :
        Entries used, shape (n, nv); None: all.

    Raises
    ------
    DataError
        If the joints' gains are not identifiable from these rows (rank deficient).
    """
    n, nv, p = Y.shape
    others = [j for j in range(nv) if j != reference_joint]
    A = np.zeros((n, nv, p + len(others)))
    A[:, :, :p] = Y
    y = np.zeros((n, nv))
    y[:, reference_joint] = tau[:, reference_joint] / reference_gain
    for k, j in enumerate(others):
        A[:, j, p + k] = -tau[:, j]
    rows = np.ones(n * nv, bool) if keep is None else np.asarray(keep, bool).reshape(-1)
    A2, y2 = A.reshape(n * nv, -1)[rows], y.reshape(-1)[rows]
    scale = np.maximum(np.linalg.norm(A2, axis=0), 1e-300)
    x, _, rank, _ = np.linalg.lstsq(A2 / scale, y2, rcond=None)
    if rank < A2.shape[1]:
        raise DataError(
            f"torque gains: the rows determine {rank} of {A2.shape[1]} unknowns; a joint's "
            "gain is not separable from its own parameters with these rows."
        )
    x = x / scale
    gains = np.full(nv, float(reference_gain))
    gains[others] = 1.0 / x[p:]
    return GainEstimate(gains=gains, theta=x[:p])
