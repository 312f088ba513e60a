"""Intervals on the written model's standard parameters: a bootstrap of the constrained fit.

The identified model (``<urdf>_identified.urdf``) holds the standard parameters ``theta`` of a
physically consistent estimate (``lmi`` by default, :mod:`ident.identify.estimators`). Its
spread is that of the moving-block bootstrap of :mod:`ident.identify.estimation.uncertainty`,
carried through the constrained estimator: each of ``n_boot`` resamples (the same run length ``L``
as the base parameters' bootstrap) sums the block normal equations with its multiplicities ``m_b``,
``A* = sum_b m_b A_b`` and ``c* = sum_b m_b c_b``, turns them into one group of reduced rows (``R =
chol(A*)``, upper, and ``z = R^-T c*``, so ``||R x - z||^2`` is the weighted least-squares cost up
to a constant) and re-solves the same estimator with the same prior weight and options. The interval
of each standard parameter is ``theta_i +- z_level std_i``, ``std_i`` the standard deviation of its
re-estimates.

What the intervals say depends on what the data see
(:mod:`ident.identify.assessment.identifiability`): for a standard parameter a base parameter
determines alone, it is an interval on that parameter; for one the data see only in a combination,
or not at all, the re-estimates move only as the prior lets them (toward the URDF's nominal values
along the unseen directions), so its interval is the spread of the written value, not an interval on
the true one.

Cost: ``n_boot`` constrained solves (``urdf_update.model_bootstrap``, default
:data:`DEFAULT_N_BOOT`; ``0`` switches it off), each about as long as the model's own solve.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt
import scipy.linalg

from ident.errors import DataError
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimation.uncertainty import BlockEquations, bootstrap_counts, z_value

if TYPE_CHECKING:  # annotations only: the estimators (cvxpy) are imported when needed
    from ident.identify.estimators.problem import EstimationProblem
    from ident.identify.estimators.registry import Estimator

__all__ = [
    "DEFAULT_N_BOOT",
    "ModelIntervals",
    "estimated_seconds",
    "model_intervals",
    "parametric_resolves",
    "resampled_observations",
    "spread_about",
]

FloatArray = npt.NDArray[np.float64]

#: Re-solves of the constrained fit by default (``urdf_update.model_bootstrap``).
DEFAULT_N_BOOT = 30
#: Seconds of one LMI re-solve per joint squared (measured: 0.02 s for the 2-joint rp2 arm,
#: 0.06 s for the 6-joint TX40 log; an order of magnitude, for the printed estimate).
SECONDS_PER_SOLVE_JOINT2 = 0.004


def estimated_seconds(n_boot: int, nv: int) -> float:
    """Rough wall time [s] of ``n_boot`` re-solves for an ``nv``-joint robot."""
    return float(n_boot) * SECONDS_PER_SOLVE_JOINT2 * max(nv, 1) ** 2


@dataclass(frozen=True, eq=False)
class ModelIntervals:
    """Bootstrap intervals of the written model's standard parameters.

    Attributes
    ----------
    method :
        The constrained estimator re-solved (e.g. ``"lmi"``).
    names :
        Standard parameter names, length n_std.
    theta :
        The written values (SI), shape (n_std,).
    samples :
        The successful re-estimates, shape (n_ok, n_std).
    n_boot :
        Resamples drawn (``n_ok <= n_boot``: a failed solve is left out and counted).
    block_length :
        Blocks per run of the moving-block bootstrap.
    seconds :
        Wall time of the re-solves [s].
    """

    method: str
    names: tuple[str, ...]
    theta: FloatArray
    samples: FloatArray
    n_boot: int
    block_length: int
    seconds: float

    @property
    def n_failed(self) -> int:
        """Resamples whose constrained solve failed."""
        return int(self.n_boot - self.samples.shape[0])

    @property
    def std(self) -> FloatArray:
        """Standard deviation of the re-estimates, shape (n_std,)."""
        return np.asarray(np.std(self.samples, axis=0, ddof=1), dtype=float)

    def interval(self, level: float = 0.95) -> FloatArray:
        """``[lower, upper]`` per standard parameter, shape (n_std, 2)."""
        half = z_value(level) * self.std
        return np.column_stack([self.theta - half, self.theta + half])


def resampled_observations(blocks: BlockEquations, multiplicity: FloatArray) -> ReducedObservations:
    """One group of reduced rows with the normal equations ``sum_b m_b (A_b, c_b)`` of the
    blocks (weights already applied), ``multiplicity`` shape (n_blocks,)."""
    A = np.tensordot(multiplicity, blocks.A, axes=1)
    return _reduced(A, multiplicity @ blocks.c, float(multiplicity @ blocks.n_rows))


def _reduced(A: FloatArray, c: FloatArray, n_rows: float) -> ReducedObservations:
    """One group of reduced rows with normal equations ``(A, c)``, shapes (n, n) and (n,)."""
    R = scipy.linalg.cholesky(0.5 * (A + A.T), lower=False, check_finite=False)
    z = scipy.linalg.solve_triangular(R, c, trans="T", lower=False, check_finite=False)
    zz = float(z @ z)
    return ReducedObservations(
        R=R[None],
        z=z[None],
        rho=np.zeros(1),
        yty=np.array([zz]),
        n_rows=np.array([int(round(n_rows))], dtype=np.int64),
    )


def model_intervals(
    identification: Any,
    blocks: BlockEquations,
    block_length: int,
    *,
    n_boot: int = DEFAULT_N_BOOT,
    rng: np.random.Generator | int | None = 0,
) -> ModelIntervals:
    """Re-solve ``identification``'s constrained estimator on ``n_boot`` moving-block
    resamples of ``blocks`` (module docstring).

    Parameters
    ----------
    identification :
        The :class:`~ident.identify.estimators.ConsistentIdentification` of the written model
        (its ``problem`` carries the weights, prior weight and options; its ``constrained``
        estimate the written ``theta``).
    blocks :
        Block normal equations built with the problem's per-joint weights
        (:func:`ident.identify.estimation.log_chunks.block_equations`), base-parameter columns.
    block_length :
        Blocks per bootstrap run (the base parameters' ``ceil(bandwidth)``).
    n_boot :
        Resamples (>= 2).
    rng :
        Generator or seed.

    Raises
    ------
    DataError
        Without a constrained estimate, or fewer than two successful re-solves.
    """
    from ident.identify.estimators import get_repeated_estimator  # cvxpy: only when needed

    est = identification.constrained
    if est is None or est.theta is None:
        raise DataError("no constrained estimate to bootstrap.")
    if n_boot < 2:
        raise DataError(f"model bootstrap: {n_boot} resamples; need at least 2.")
    b = blocks.nonempty()
    counts = bootstrap_counts(b.n_blocks, block_length, n_boot, rng)
    estimator = get_repeated_estimator(identification.method)  # one program, re-solved
    t0 = time.perf_counter()
    samples = _resolved_samples(estimator, identification.problem, b, counts)
    if len(samples) < 2:
        raise DataError(f"model bootstrap: {len(samples)} of {n_boot} re-solves succeeded.")
    return ModelIntervals(
        method=str(identification.method),
        names=tuple(identification.structure.names),
        theta=np.asarray(est.theta, dtype=float),
        samples=np.array(samples),
        n_boot=int(n_boot),
        block_length=int(block_length),
        seconds=time.perf_counter() - t0,
    )


def _resolved_samples(
    estimator: Estimator, problem: EstimationProblem, blocks: BlockEquations, counts: FloatArray
) -> list[FloatArray]:
    """The standard parameters of ``estimator`` re-solved on each resample of the non-empty
    ``blocks`` (``counts`` its multiplicities, shape (n_boot, n_blocks)), ``problem`` the written
    model's problem; a resample that does not see
    every base parameter or whose solve fails is left out."""
    n = blocks.A.shape[1]
    # every resample's normal equations in one product (one pass over the blocks)
    A_all = (counts @ blocks.A.reshape(blocks.n_blocks, -1)).reshape(len(counts), n, n)
    c_all, rows_all = counts @ blocks.c, counts @ blocks.n_rows
    samples = []
    for A, c, rows in zip(A_all, c_all, rows_all, strict=True):
        theta = _resolve(estimator, problem, A, c, float(rows))
        if theta is not None:
            samples.append(theta)
    return samples


def _resolve(
    estimator: Estimator, problem: EstimationProblem, A: FloatArray, c: FloatArray, rows: float
) -> FloatArray | None:
    """``estimator``'s standard parameters on the normal equations ``(A, c)`` (n, n), (n,)
    (weights applied) in ``problem``'s columns; None when ``A`` is singular (a resample that
    does not see every parameter) or the solve fails."""
    try:
        obs = _reduced(A, c, rows)
    except np.linalg.LinAlgError:
        return None
    fit = estimator(dataclasses.replace(problem, observations=obs, weights=np.ones(1)))
    if fit.success and fit.theta is not None:
        return np.asarray(fit.theta, dtype=float)
    return None


def parametric_resolves(
    estimator: Estimator,
    problem: EstimationProblem,
    A: FloatArray,
    B: FloatArray,
    theta: FloatArray,
    *,
    n_boot: int,
    rows: float,
    rng: np.random.Generator | int | None = 0,
) -> FloatArray:
    """A parametric bootstrap of a constrained fit: ``estimator`` re-solved on ``n_boot``
    draws of the normal equations ``(A, A theta + e)``, ``e ~ N(0, B)``, shape (n_ok, n).

    ``A`` (n, n) are the fit's weighted normal equations in ``problem``'s columns (standard
    parameters, no base map), ``B`` (n, n) the covariance of their right-hand side (``A`` for
    white noise of the weights' variance; the sandwich's middle under forgetting), ``theta``
    (n,) the constrained estimate: the data drawn as if it were the truth, so the re-solves
    spread as a realizable estimate does about a realizable truth, constraints included (the
    least squares' covariance, ``A^-1 B A^-1``, is that of the unconstrained solution). Where
    the rows leave no resample of blocks (a stream keeps only sums), this is the bootstrap
    of :func:`model_intervals`: the same re-solve of the same estimator.
    """
    gen = np.random.default_rng(rng)
    w, V = np.linalg.eigh(0.5 * (B + B.T))
    root = V * np.sqrt(np.clip(w, 0.0, None))  # root @ root.T = B (B may be singular)
    mean = A @ theta
    samples = [
        _resolve(estimator, problem, A, mean + root @ gen.normal(size=mean.size), rows)
        for _ in range(n_boot)
    ]
    ok = [s for s in samples if s is not None]
    return np.array(ok).reshape(len(ok), theta.size)


def spread_about(samples: FloatArray, theta: FloatArray) -> FloatArray:
    """The re-estimates' second moment about the estimate, ``mean (s - theta)(s - theta)^T``
    (n, n) of ``samples`` (k, n): their spread and their bias together (a constrained fit's
    re-solves about a truth on or near a constraint are biased; an interval
    ``theta +- z sqrt(diag)`` keeps the bias in)."""
    err = np.asarray(samples, dtype=float) - np.asarray(theta, dtype=float)
    return np.asarray(err.T @ err / max(err.shape[0], 1), dtype=float)
