"""Observation rows reduced to per-group triangular factors: least squares in bounded memory.

An identification solves ``tau = W x + e`` over millions of rows (samples x joints) for tens of
parameters. Nothing an estimator needs depends on the rows themselves once they are reduced,
per group of rows (a joint), to the triangular factor of a QR decomposition:

``W_j = Q_j R_j``, ``z_j = Q_j^T y_j`` and ``rho_j = ||y_j||^2 - ||z_j||^2``, so that for any x

``||W_j x - y_j||^2 = ||R_j x - z_j||^2 + rho_j``.

OLS and WLS (per-group weights) are then solved from the stacked factors, the residual of every
group follows for any estimate (constrained ones included), and chunks of a long log reduce
one at a time and merge (a tall-skinny QR), so memory does not grow with the log length.
Working on ``R`` rather than on the normal equations ``W^T W = R^T R`` keeps the condition
number of ``W`` instead of squaring it.

Shapes: ``n_groups`` row groups, ``n`` parameters.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.linalg

from ident.errors import DataError

__all__ = ["ReducedObservations", "reduce_rows"]

FloatArray = npt.NDArray[np.float64]


def reduce_rows(W: FloatArray, y: FloatArray, n: int) -> tuple[FloatArray, FloatArray, float]:
    """``(R, z, rho)`` of the rows ``W`` (m, n), ``y`` (m,): R (n, n) upper triangular, z (n,).

    One QR of ``[W | y]``: its triangle holds R, ``z = Q^T y`` in the last column and the
    norm of the least-squares residual in the corner, so ``rho`` needs no subtraction of
    large numbers. Fewer rows than parameters give a zero-padded R (the missing rows are
    zero), so a chunk of any size reduces to the same shapes.
    """
    R = np.zeros((n, n))
    z = np.zeros(n)
    if W.shape[0] == 0:
        return R, z, 0.0
    Rfull = scipy.linalg.qr(np.column_stack([W, y]), mode="r", check_finite=False)[0]
    k = min(Rfull.shape[0], n)
    R[:k] = Rfull[:k, :n]
    z[:k] = Rfull[:k, n]
    rho = float(Rfull[n, n] ** 2) if Rfull.shape[0] > n else 0.0
    return R, z, rho


@dataclass(frozen=True, eq=False)
class ReducedObservations:
    """Per-group QR reduction of stacked observation rows (see the module docstring).

    Attributes
    ----------
    R :
        Upper-triangular factors, shape (n_groups, n, n).
    z :
        ``Q_j^T y_j``, shape (n_groups, n).
    rho :
        Squared residual outside the column space of each group, ``||y_j||^2 - ||z_j||^2``,
        shape (n_groups,) [unit of y squared].
    yty :
        ``||y_j||^2``, shape (n_groups,).
    n_rows :
        Rows per group, shape (n_groups,).
    """

    R: FloatArray
    z: FloatArray
    rho: FloatArray
    yty: FloatArray
    n_rows: npt.NDArray[np.int64]

    def __post_init__(self) -> None:
        for name in ("R", "z", "rho", "yty", "n_rows"):
            getattr(self, name).flags.writeable = False

    @property
    def n_groups(self) -> int:
        """Number of row groups."""
        return int(self.R.shape[0])

    @property
    def n_params(self) -> int:
        """Number of parameters (columns of ``W``)."""
        return int(self.R.shape[1])

    @classmethod
    def from_rows(
        cls, W: npt.ArrayLike, y: npt.ArrayLike, groups: npt.ArrayLike, n_groups: int
    ) -> ReducedObservations:
        """Reduce observation rows.

        Parameters
        ----------
        W :
            Observation rows, shape (m, n).
        y :
            Measurements, shape (m,).
        groups :
            Group (joint) index of every row, shape (m,), values in ``[0, n_groups)``.
        n_groups :
            Number of groups (groups without rows are allowed and stay empty).
        """
        W = np.asarray(W, dtype=float)
        y = np.asarray(y, dtype=float).reshape(-1)
        groups = np.asarray(groups, dtype=np.int64).reshape(-1)
        if W.ndim != 2 or y.shape[0] != W.shape[0] or groups.shape[0] != W.shape[0]:
            raise DataError(
                f"W {W.shape}, y {y.shape} and groups {groups.shape} must have one row each."
            )
        if groups.size and (groups.min() < 0 or groups.max() >= n_groups):
            raise DataError(f"group indices must lie in [0, {n_groups}).")
        n = W.shape[1]
        R = np.zeros((n_groups, n, n))
        z = np.zeros((n_groups, n))
        rho = np.zeros(n_groups)
        yty = np.zeros(n_groups)
        n_rows = np.zeros(n_groups, dtype=np.int64)
        for j in range(n_groups):
            rows = groups == j
            R[j], z[j], rho[j] = reduce_rows(W[rows], y[rows], n)
            yty[j] = float(y[rows] @ y[rows])
            n_rows[j] = int(rows.sum())
        return cls(R=R, z=z, rho=rho, yty=yty, n_rows=n_rows)

    @classmethod
    def from_samples(cls, Y: npt.ArrayLike, tau: npt.ArrayLike) -> ReducedObservations:
        """Reduce per-sample rows: ``Y`` (n_samples, n_groups, n), ``tau`` (n_samples, n_groups).

        Row ``(k, j)`` (sample k, joint j) belongs to group j.
        """
        Y = np.asarray(Y, dtype=float)
        tau = np.asarray(tau, dtype=float)
        if Y.ndim != 3 or tau.shape != Y.shape[:2]:
            raise DataError(f"Y {Y.shape} and tau {tau.shape} must be (n, g, p) and (n, g).")
        n_samples, n_groups, n = Y.shape
        groups = np.broadcast_to(np.arange(n_groups), (n_samples, n_groups))
        return cls.from_rows(Y.reshape(-1, n), tau.reshape(-1), groups.reshape(-1), n_groups)

    def check_enough_rows(self) -> None:
        """Raise DataError when the rows do not outnumber the parameters (no least-squares
        fit and no residual to estimate the noise from), saying what to change."""
        m, n = int(self.n_rows.sum()), self.n_params
        if m <= n:
            raise DataError(
                f"too few observations: {m} rows for {n} parameters (need more than {n}); "
                "use a longer log, less decimation, or fewer parameters."
            )

    def merge(self, other: ReducedObservations) -> ReducedObservations:
        """The reduction of both sets of rows (order does not matter beyond round-off)."""
        if other.R.shape != self.R.shape:
            raise DataError(
                f"cannot merge reductions of shapes {self.R.shape} and {other.R.shape}."
            )
        n = self.n_params
        R = np.empty_like(self.R)
        z = np.empty_like(self.z)
        rho = np.empty_like(self.rho)
        zero = np.zeros((2, n))
        for j in range(self.n_groups):
            # each part's own residual enters as a row (0, ..., 0 | sqrt(rho)): the merged QR
            # then carries the total residual in its corner
            R[j], z[j], rho[j] = reduce_rows(
                np.vstack([self.R[j], other.R[j], zero]),
                np.concatenate([self.z[j], other.z[j], np.sqrt([self.rho[j], other.rho[j]])]),
                n,
            )
        return ReducedObservations(
            R=R, z=z, rho=rho, yty=self.yty + other.yty, n_rows=self.n_rows + other.n_rows
        )

    def residual_ss(self, x: npt.ArrayLike) -> FloatArray:
        """Squared residual ``||W_j x - y_j||^2`` of every group, shape (n_groups,)."""
        x = np.asarray(x, dtype=float)
        r = np.einsum("gij,j->gi", self.R, x) - self.z
        return np.einsum("gi,gi->g", r, r) + self.rho

    def stacked(self, weights: npt.ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
        """One triangular system ``(R, z)`` of all groups, rows of group j scaled by ``w_j``.

        ``min ||R x - z||`` then equals ``min sum_j w_j^2 ||W_j x - y_j||^2``; shapes (n, n)
        and (n,).
        """
        w = np.ones(self.n_groups) if weights is None else np.asarray(weights, dtype=float)
        Rs = (self.R * w[:, None, None]).reshape(-1, self.n_params)
        zs = (self.z * w[:, None]).reshape(-1)
        R, z, _ = reduce_rows(Rs, zs, self.n_params)
        return R, z
