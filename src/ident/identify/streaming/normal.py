"""Per-joint normal equations with exponential forgetting, their weighted solution and its
sandwich covariance.

A streaming estimate never keeps its rows: it keeps, per joint ``j``, the weighted sums

``A_j = sum_k w_k x_kj x_kj^T``, ``c_j = sum_k w_k x_kj y_kj``, ``yy_j = sum_k w_k y_kj^2``,
``B_j = sum_k w_k^2 x_kj x_kj^T``, ``sw_j = sum_k w_k``, ``sw2_j = sum_k w_k^2``

over its rows ``k`` (``x`` the regressor row, ``y`` the torque it explains). Forgetting is
exponential *per block*: before a block's rows are added every sum is multiplied by ``gamma``
(the ``w^2`` sums by ``gamma^2``), so a row ``b`` blocks old weighs ``gamma^b``; with
``gamma = exp(-T_block / tau)`` the memory is ``tau`` seconds. ``gamma = 1`` is no forgetting:
the sums are the ordinary normal equations and the solution is batch least squares.

**The solution** (:meth:`NormalEquations.solve`) is weighted least squares with per-joint noise
``sigma_j`` estimated from the residuals (two passes, as :mod:`ident.identify.estimation.estimate`
does on reduced rows): ``x = A_v^-1 c_v`` with ``A_v = sum_j A_j / sigma_j^2``.

**Its covariance** under forgetting is not ``A_v^-1``: with independent noise of variance
``sigma_j^2`` the estimate's covariance is the sandwich ``A_v^-1 B_v A_v^-1``
(``B_v = sum_j B_j / sigma_j^2``), which is ``A_v^-1`` for ``gamma = 1``. The noise variance
comes from the weighted residual ``S_j = yy_j - 2 x^T c_j + x^T A_j x`` with its exact
expectation: ``E[sum_k w_k r_k^2] = sigma^2 (sum_k w_k - tr(A^-1 B))``, the forgetting
counterpart of ``n - p``. The effective sample count ``(sum w)^2 / sum w^2`` (per joint, in
rows) says how many independent rows the forgetting window is worth: ``(1 + gamma) /
(1 - gamma)`` blocks' rows in the steady state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.errors import NotIdentifiable
from ident.identify.estimation.observations import ReducedObservations

__all__ = [
    "Epochs",
    "NormalEquations",
    "Solution",
    "reduced_observations",
    "scaled_inverse",
    "split_equations",
    "weighted_sums",
]

FloatArray = npt.NDArray[np.float64]

#: Relative eigenvalue below which a direction of ``A_v`` counts as undetermined.
RANK_TOL = 1e-10
#: Rows from which :meth:`NormalEquations.add_rows` sums joint by joint (BLAS), below which
#: in one stacked product (a stream's few rows a block: fewer calls).
_BLAS_ROWS = 64


@dataclass(frozen=True, eq=False)
class Solution:
    """A weighted least-squares solution of :class:`NormalEquations` (SI).

    Attributes
    ----------
    x :
        Parameters, shape (p,).
    covariance :
        Sandwich covariance of ``x``, shape (p, p).
    sigma :
        Per-joint noise standard deviation [N*m], shape (nv,) (NaN for a joint without rows).
    n_eff :
        Effective number of rows ``(sum w)^2 / sum w^2`` summed over the joints.
    residual_ss :
        Weighted residual sum of squares per joint [(N*m)^2], shape (nv,).
    """

    x: FloatArray
    covariance: FloatArray
    sigma: FloatArray
    n_eff: float
    residual_ss: FloatArray

    @property
    def std(self) -> FloatArray:
        """Standard deviations of ``x``, shape (p,)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))


class NormalEquations:
    """The per-joint sums of the module docstring for ``nv`` joints and ``p`` unknowns."""

    def __init__(self, nv: int, p: int) -> None:
        self.A = np.zeros((nv, p, p))
        self.B = np.zeros((nv, p, p))
        self.c = np.zeros((nv, p))
        self.yy = np.zeros(nv)
        self.sw = np.zeros(nv)
        self.sw2 = np.zeros(nv)
        self.n_rows = 0  # rows added (unweighted), all joints

    @property
    def nv(self) -> int:
        """Number of joints (row groups)."""
        return int(self.A.shape[0])

    @property
    def p(self) -> int:
        """Number of unknowns."""
        return int(self.A.shape[1])

    def copy(self) -> NormalEquations:
        """An independent copy."""
        out = NormalEquations(self.nv, self.p)
        out.iadd(self)
        out.n_rows = self.n_rows
        return out

    def decay(self, gamma: float) -> None:
        """Multiply the weights of every row so far by ``gamma`` (0 < gamma <= 1)."""
        if gamma == 1.0:
            return
        self.A *= gamma
        self.c *= gamma
        self.yy *= gamma
        self.sw *= gamma
        self.B *= gamma * gamma
        self.sw2 *= gamma * gamma

    def add_rows(self, X: FloatArray, y: FloatArray, keep: npt.NDArray[np.bool_]) -> None:
        """Add rows with weight 1: ``X`` (n, nv, p), ``y`` (n, nv), ``keep`` (n, nv) (False:
        the row is left out, e.g. a joint below its velocity threshold)."""
        m = keep.astype(float)
        if X.shape[0] >= _BLAS_ROWS:
            # one BLAS product per joint: numpy's stacked matmul does not call BLAS, and was
            # 17 times slower on 3000 rows of 58 columns (a fleet's chunk)
            for j in range(X.shape[1]):
                W = X[keep[:, j], j, :]
                A_j = W.T @ W
                self.A[j] += A_j
                self.B[j] += A_j
                self.c[j] += W.T @ y[keep[:, j], j]
        else:
            Xt = np.ascontiguousarray((X * m[:, :, None]).transpose(1, 2, 0))  # (nv, p, n)
            A = Xt @ X.transpose(1, 0, 2)
            self.A += A
            self.B += A
            self.c += np.einsum("jpn,nj->jp", Xt, y)
        self.yy += np.einsum("nj,nj->j", m, y * y)
        count = m.sum(axis=0)
        self.sw += count
        self.sw2 += count
        self.n_rows += int(count.sum())

    def iadd(self, other: NormalEquations, weight: float = 1.0) -> None:
        """Add ``other``'s sums, its rows weighted by ``weight`` (its ``w^2`` sums by
        ``weight^2``)."""
        self.A += weight * other.A
        self.c += weight * other.c
        self.yy += weight * other.yy
        self.sw += weight * other.sw
        self.B += weight * weight * other.B
        self.sw2 += weight * weight * other.sw2
        self.n_rows += other.n_rows

    def n_eff(self) -> float:
        """Effective number of rows ``sum_j (sum w)^2 / sum w^2``."""
        ok = self.sw2 > 0
        return float(np.sum(self.sw[ok] ** 2 / self.sw2[ok]))

    def residual_ss(self, x: FloatArray) -> FloatArray:
        """Weighted residual sum of squares per joint at ``x`` (p,), shape (nv,)."""
        return self.yy - 2.0 * self.c @ x + np.einsum("p,jpq,q->j", x, self.A, x)

    def solve(self, passes: int = 2) -> Solution:
        """Weighted least squares with per-joint noise from the residuals (module docstring).

        Raises
        ------
        NotIdentifiable
            When the rows leave a direction of the unknowns undetermined.
        """
        rows = self.sw > 0
        v = rows.astype(float)  # first pass: every joint with rows weighs 1
        for _ in range(passes):
            x, Ainv = _weighted_solve(self, v)
            ss = np.clip(self.residual_ss(x), 0.0, None)
            # each joint's share of the leverage: E[S_j] = sigma_j^2 (sw_j - tr(A_v^-1 v_j B_j))
            lev = v * np.einsum("pq,jqp->j", Ainv, self.B)
            dof = np.where(rows, np.maximum(self.sw - lev, 1e-12 * np.maximum(self.sw, 1.0)), 1.0)
            var = np.where(rows, ss / dof, np.nan)
            floor = 1e-12 * np.nanmax(np.where(rows, var, 0.0)) + 1e-300
            v = np.where(rows, 1.0 / np.maximum(np.nan_to_num(var), floor), 0.0)
        x, Ainv = _weighted_solve(self, v)
        Bv = np.einsum("j,jpq->pq", v, self.B)
        cov = Ainv @ Bv @ Ainv
        return Solution(
            x=x,
            covariance=0.5 * (cov + cov.T),
            sigma=np.sqrt(var),
            n_eff=self.n_eff(),
            residual_ss=np.clip(self.residual_ss(x), 0.0, None),
        )


def _weighted_solve(eq: NormalEquations, v: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``x = A_v^-1 c_v`` and ``A_v^-1`` for the joint weights ``v`` (nv,)."""
    A, c = weighted_sums(eq, v)
    Ainv = scaled_inverse(A, "the unknowns", rank_tol=RANK_TOL)
    return Ainv @ c, Ainv


def weighted_sums(eq: NormalEquations, v: FloatArray) -> tuple[FloatArray, FloatArray]:
    """``(A_v, c_v)``: the per-joint normal equations summed with joint weights ``v`` (nv,),
    shapes (p, p) and (p,)."""
    return np.einsum("j,jpq->pq", v, eq.A), v @ eq.c


def scaled_inverse(A: FloatArray, what: str, rank_tol: float = 0.0) -> FloatArray:
    """``A^-1`` of a symmetric positive definite ``A`` (p, p) through its unit-diagonal
    scaling, which keeps it accurate when the unknowns' units differ by orders of magnitude.

    Raises
    ------
    NotIdentifiable
        Naming ``what``: a column without rows, or a direction left undetermined (Cholesky
        fails, or with ``rank_tol`` the scaled factor's smallest squared pivot is below it).
    """
    d = np.sqrt(np.clip(np.diag(A), 0.0, None))
    if np.any(d == 0.0):
        raise NotIdentifiable(f"{what}: {int(np.sum(d == 0.0))} column(s) have no row.")
    undetermined = NotIdentifiable(f"{what}: the rows leave a direction undetermined.")
    try:
        L = np.linalg.cholesky(A / np.outer(d, d))
    except np.linalg.LinAlgError:
        raise undetermined from None
    # unit diagonal: min(diag L)^2 bounds the smallest eigenvalue from above (within a factor)
    if np.min(np.diag(L)) ** 2 <= rank_tol:
        raise undetermined
    Linv = np.linalg.inv(L)
    return (Linv.T @ Linv) / np.outer(d, d)


def split_equations(
    before: NormalEquations, after: NormalEquations, split: npt.ArrayLike
) -> NormalEquations:
    """One problem of two stretches that share every unknown except ``split``.

    Unknowns ``[x (p), x_after[split] (s)]``: ``before``'s rows see ``x``, ``after``'s see
    ``x`` with its ``split`` entries replaced by the new ones (e.g. a payload that changed while
    the friction did not). Both must have the same ``nv`` and ``p``.
    """
    return Epochs([before, after], [np.asarray(split, dtype=np.intp)]).extended()[0]


class Epochs:
    """Stretches of rows (epochs) separated by changes: epoch ``k + 1`` shares every unknown
    with epoch ``k`` except ``splits[k]``. The current parameters are the last epoch's.

    The reference of a stream after a change: the rows before it still determine the unknowns
    that did not change, so the new payload is known from the first rows after it.
    """

    def __init__(self, epochs: list[NormalEquations], splits: list[npt.NDArray[np.intp]]) -> None:
        self.epochs, self.splits = epochs, splits

    def copy(self) -> Epochs:
        """An independent copy."""
        return Epochs([e.copy() for e in self.epochs], list(self.splits))

    @property
    def last(self) -> NormalEquations:
        """The current epoch's sums."""
        return self.epochs[-1]

    def add(self, block: NormalEquations, gamma: float = 1.0) -> None:
        """Forget by ``gamma``, then add ``block`` to the current epoch; an old epoch whose
        weight fell below 1 % of the whole is dropped."""
        for e in self.epochs:
            e.decay(gamma)
        self.last.iadd(block)
        total = sum(float(e.sw.sum()) for e in self.epochs)
        while len(self.epochs) > 1 and self.epochs[0].sw.sum() < 0.01 * total:
            self.epochs.pop(0)
            self.splits.pop(0)

    def extended(self) -> tuple[NormalEquations, FloatArray]:
        """The one problem of every epoch ``E`` (unknowns: the first epoch's, then each
        change's new ones) and ``M`` (p, q) mapping its unknowns to the current parameters."""
        first = self.epochs[0]
        p = first.p
        q = p + sum(s.size for s in self.splits)
        out = NormalEquations(first.nv, q)
        M = np.eye(p, q)
        col = p
        for k, e in enumerate(self.epochs):
            if k > 0:
                split = self.splits[k - 1]
                M[split, :] = 0.0
                M[split, col + np.arange(split.size)] = 1.0
                col += split.size
            out.A += M.T @ e.A @ M
            out.B += M.T @ e.B @ M
            out.c += e.c @ M
            out.yy += e.yy
            out.sw += e.sw
            out.sw2 += e.sw2
            out.n_rows += e.n_rows
        return out, M

    def solve(self) -> Solution:
        """The current parameters' solution (p-space: ``M x``, ``M C M^T``)."""
        eq, M = self.extended()
        sol = eq.solve()
        return Solution(x=M @ sol.x, covariance=M @ sol.covariance @ M.T, sigma=sol.sigma,
                        n_eff=sol.n_eff, residual_ss=sol.residual_ss)  # fmt: skip


def reduced_observations(eq: NormalEquations) -> ReducedObservations:
    """The sums as :class:`~ident.identify.estimation.observations.ReducedObservations` (per
    joint ``R_j^T R_j = A_j``, ``R_j^T z_j = c_j``), for the estimators that take reduced rows
    (the consistent ``lmi``); ``n_rows`` is the weighted row count ``sum w`` rounded."""
    nv, p = eq.nv, eq.p
    R = np.zeros((nv, p, p))
    z = np.zeros((nv, p))
    for j in range(nv):
        w, V = np.linalg.eigh(eq.A[j])
        ok = w > RANK_TOL * max(w[-1], 0.0)
        s = np.sqrt(np.where(ok, w, 0.0))
        R[j] = s[:, None] * V.T
        z[j] = np.where(ok, (V.T @ eq.c[j]) / np.where(ok, s, 1.0), 0.0)
    rho = np.clip(eq.yy - np.sum(z * z, axis=1), 0.0, None)
    return ReducedObservations(
        R=R, z=z, rho=rho, yty=eq.yy.copy(), n_rows=np.rint(eq.sw).astype(np.int64)
    )
