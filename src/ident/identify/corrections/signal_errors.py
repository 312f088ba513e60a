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
reference is needed: the gain of one joint (``g_r`` known). :func:`estimate_gains` minimises
``sum_j ||tau_meas_j - g_j Y_j theta||^2`` by separable least squares over the gains. The joints
share the rigid-body parameters, which is what makes the gains identifiable: the parameters of
a joint's row must also act on the reference joint's row (take a shoulder joint as the
reference, whose row carries the gravity of the links beyond it; the vertical first joint of a
UR5 sees no gravity, and the gains measured against it are poorly determined). With an offset
column in ``Y`` (``off_j``), the offset is ``o_j = g_j theta_off_j``. A payload of known mass
as the reference: :mod:`ident.identify.payload.payload_gain`.

The homogeneous linear form ``Y_j theta - h_j tau_meas_j = 0`` (``h = 1 / g``) is one solve but
wrong: it is an errors-in-variables problem whose least-squares solution shrinks ``theta`` and
``h`` together wherever the reference row does not pin them (gains of 3 to 50 on a UR5 log
whose true gains were within 3 % of 1).
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares, minimize_scalar

from ident.blas import one_blas_thread
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
        Delay of the torque behind the positions [s] (negative: ahead); ``|delay_s|`` at most
        ``margin_s``.
    t :
        Sample times [s], increasing, shape (n,).
    tau :
        Measured torques [N*m], shape (n, nv).
    Y :
        Regressor at ``t``, shape (n, nv, p).
    keep :
        Entries used, shape (n, nv); None: all.
    margin_s :
        Samples within ``margin_s`` of either end are never used, so that every delay up to
        ``margin_s`` fits the same rows [s].
    """
    return _DelayProblem(t, tau, Y, keep, margin_s)(delay_s)


class _DelayProblem:
    """The fixed rows of a delay search, factored once: ``(delay_s) -> relative residual``."""

    def __init__(
        self,
        t: FloatArray,
        tau: FloatArray,
        Y: FloatArray,
        keep: BoolArray | None,
        margin_s: float,
    ) -> None:
        n, nv = tau.shape
        self.t, self.tau, self.margin_s = np.asarray(t, float), np.asarray(tau, float), margin_s
        inside = (self.t >= self.t[0] + margin_s) & (self.t <= self.t[-1] - margin_s)
        mask = np.broadcast_to(inside[:, None], (n, nv))
        if keep is not None:
            mask = mask & np.asarray(keep, bool)
        self.rows = mask.reshape(-1)
        with one_blas_thread():
            self.Q = np.linalg.qr(Y.reshape(n * nv, -1)[self.rows])[0]

    def __call__(self, delay_s: float) -> float:
        if abs(delay_s) > self.margin_s * (1.0 + 1e-12):
            raise DataError(f"delay {delay_s:g} s is beyond the margin {self.margin_s:g} s.")
        nv = self.tau.shape[1]
        shifted = np.column_stack(
            [np.interp(self.t + delay_s, self.t, self.tau[:, j]) for j in range(nv)]
        )
        y = shifted.reshape(-1)[self.rows]
        r = y - self.Q @ (self.Q.T @ y)
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

    cost = _DelayProblem(t, tau, Y, keep, max_delay_s)

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
        Parameters of the columns of ``Y`` in true torque units, shape (p,) (NaN for columns
        acting on none of the rows used).
    """

    gains: FloatArray
    theta: FloatArray


def estimate_gains(
    Y: FloatArray,
    tau: FloatArray,
    *,
    reference_joint: int,
    reference_gain: float = 1.0,
    joints: Sequence[int] | None = None,
    keep: BoolArray | None = None,
) -> GainEstimate:
    """Torque gains of ``joints`` with the gain of ``reference_joint`` (0-based) known.

    Minimises ``sum_j ||tau_j - g_j Y_j theta||^2`` (the residual in the measured unit, so that
    shrinking ``theta`` with the gains is never a way out) by variable projection over the
    ``nv - 1`` unknown gains: ``theta(g)`` is one least-squares solve on the rows ``g_j Y_j``;
    ``scipy.optimize.least_squares`` finds ``g`` from 1.

    Parameters
    ----------
    Y :
        Regressor, shape (n, nv, p), full column rank on the kept rows.
    tau :
        Measured torques [N*m or the logged unit], shape (n, nv).
    reference_joint, reference_gain :
        The joint whose gain is known, and that gain.
    joints :
        0-based joints whose gains are estimated (default: all); only the rows of these and of
        the reference joint are used, and only the columns acting on them. The other gains
        are reported as NaN.
    keep :
        Entries used, shape (n, nv); None: all.

    Raises
    ------
    DataError
        If ``Y`` is rank deficient on the kept rows.
    """
    nv = Y.shape[1]
    used = range(nv) if joints is None else {*joints, reference_joint}
    others = np.array([j for j in sorted(used) if j != reference_joint], dtype=np.intp)
    A, y, joint_of_row, acting = _gain_rows(Y, tau, used, keep)
    p = A.shape[1]

    def gains_of(x: FloatArray) -> FloatArray:
        g = np.full(nv, np.nan)
        g[reference_joint] = float(reference_gain)
        g[others] = x
        return g

    def solve(x: FloatArray) -> tuple[npt.NDArray[np.floating], npt.NDArray[np.floating]]:
        Ag = A * gains_of(x)[joint_of_row][:, None]
        theta, _, rank, _ = np.linalg.lstsq(Ag, y, rcond=None)
        if rank < p:
            raise DataError(f"torque gains: the regressor has rank {rank} < {p} on these rows.")
        return y - Ag @ theta, theta

    with one_blas_thread():
        result = least_squares(lambda x: solve(x)[0], np.ones(others.size), method="trf")
        theta = np.full(acting.size, np.nan)
        theta[acting] = solve(result.x)[1]
    return GainEstimate(gains=gains_of(result.x), theta=theta)


def _gain_rows(
    Y: FloatArray, tau: FloatArray, used: Collection[int], keep: BoolArray | None
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.intp], BoolArray]:
    """The kept rows of the ``used`` joints stacked: ``(A, y, joint_of_row, acting)``, the
    regressor rows on the columns acting on them, shape (m, p'), the measured torques, shape
    (m,), each row's joint, shape (m,), and which of the ``p`` columns of ``Y`` act, shape (p,)
    (``Y`` shape (n, nv, p), ``tau`` and ``keep`` shape (n, nv))."""
    n, nv, _ = Y.shape
    rows = np.ones((n, nv), bool) if keep is None else np.asarray(keep, bool).copy()
    rows[:, [j for j in range(nv) if j not in used]] = False
    rows = rows.reshape(-1)
    joint_of_row = np.tile(np.arange(nv), n)[rows]
    A = Y.reshape(n * nv, -1)[rows]
    acting = np.any(A != 0.0, axis=0)  # columns of the unused joints' own parameters drop
    y = np.asarray(tau, float).reshape(-1)[rows]
    return A[:, acting], y, joint_of_row, acting
