"""Intervals that cover: covariances of a least-squares estimate robust to correlated residuals.

The ordinary covariance ``sigma^2 (W^T W)^-1`` of :mod:`ident.identify.estimation.estimate` assumes
independent residuals. A log's residuals are not: the zero-phase low-pass filters, the
differentiation of quantized encoders, closed-loop errors and unmodelled dynamics make
neighbouring samples share their error, and the ordinary standard deviations come out too
small (errors up to 7-9 ordinary sigma on simulated UR5 and Panda logs whose truth is
known). Two
covariances that do not assume independence are computed here, both from the *block normal
equations* of the identification rows (:class:`BlockEquations`: for consecutive blocks of
decimated samples ``b``, ``A_b = sum_j w_j^2 W_bj^T W_bj`` and ``c_b = sum_j w_j^2 W_bj^T
y_bj``, with the estimate's per-joint weights ``w_j = 1 / sigma_j``; blocks are filled chunk
by chunk by :func:`ident.identify.estimation.log_chunks.block_equations`, so memory does not grow
with the log):

``hac``
    Heteroscedasticity- and autocorrelation-consistent sandwich (Newey-West):
    ``C = A^-1 B A^-1`` with ``A = sum_b A_b`` and ``B = G_0 + sum_{l>=1} k(l / S) (G_l +
    G_l^T)``, ``G_l = sum_b s_b s_{b-l}^T`` the autocovariances of the block scores
    ``s_b = c_b - A_b x`` (residual times regressor, summed over the block's samples and
    joints), Bartlett kernel ``k(u) = max(0, 1 - u)``, times ``n_b / (n_b - n)`` (``n_b``
    blocks, ``n`` parameters: the usual degrees-of-freedom correction).
    **Bandwidth rule** (Andrews 1991, AR(1) plug-in for the Bartlett kernel): each score
    component, standardized, is fitted an AR(1) coefficient ``rho_a`` (clipped to
    ``[-0.97, 0.97]``, innovation variance ``v_a = 1 - rho_a^2``);
    ``alpha = sum_a 4 rho_a^2 v_a^2 / ((1 - rho_a)^6 (1 + rho_a)^2) / sum_a v_a^2 /
    (1 - rho_a)^4`` and ``S = 1.1447 (alpha n_b)^(1/3)`` blocks,
    at least 1 and at most ``n_b / 4``.
``bootstrap``
    Moving-block bootstrap over trajectory segments, re-estimating: ``n_boot`` resamples draw
    ``ceil(n_b / L)`` runs of ``L = ceil(S)`` consecutive blocks (circularly, start uniform),
    sum the block normal equations with the resulting multiplicities ``m_b`` and solve
    ``(sum_b m_b A_b) x* = sum_b m_b c_b``; the covariance is that of the ``x*`` about their
    mean. The weights ``w_j`` are kept fixed.

The default is ``bootstrap`` (:data:`DEFAULT_METHOD`): in ``benchmarks/bench_coverage.py``
(20 MuJoCo seeds each of the UR5 and Panda, docs/uncertainty.md) its 95 % intervals hold the
true base parameters 95.7 % (UR5) and 94.8 % (Panda) of the time, where the HAC ones hold
them about 90 % of the time
(a Bartlett kernel with a bandwidth of ~80 samples on ~1900 leaves few effective degrees of
freedom for ~50 parameters: its long-run variance comes out low) and the ordinary ones 57-59 %.
Both are reported; where their standard deviations differ by more than
:data:`DISAGREE_RATIO` the parameter is flagged.

**One standard deviation everywhere.** Every consumer of a base parameter's standard
deviation (the verdict's worst relative σ, the high-σ and negative-parameter warnings, the
cautious URDF copy's ``urdf_update.max_relative_std_pct``, the reports' σ columns and
``result.json``, the run report's "within 3σ") reads :func:`parameter_std`: the default
method's standard deviation, or the ordinary one, with a note saying so, when the log has too
few blocks for the bootstrap (:class:`ParameterStd`).

Prediction intervals on held-out torques: ``tau_hat_kj +- z sqrt(r_kj^T C r_kj +
sigma_j^2)`` with ``r_kj`` the base regressor row of sample k, joint j, and ``sigma_j`` the
RMS of the identification residual of joint j (:func:`prediction_std`).

References
----------
W. K. Newey and K. D. West, "A simple, positive semi-definite, heteroskedasticity and
autocorrelation consistent covariance matrix", Econometrica 1987;
D. W. K. Andrews, "Heteroskedasticity and autocorrelation consistent covariance matrix
estimation", Econometrica 1991;
H. R. Kuensch, "The jackknife and the bootstrap for general stationary observations",
Annals of Statistics 1989.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt
import scipy.linalg
import scipy.stats

from ident.errors import DataError

__all__ = [
    "DEFAULT_METHOD",
    "DISAGREE_RATIO",
    "METHODS",
    "ORDINARY_NOTE",
    "BlockEquations",
    "ParameterStd",
    "Uncertainty",
    "andrews_bandwidth",
    "block_bootstrap",
    "bootstrap_counts",
    "coverage_summary",
    "interval_coverage",
    "hac_covariance",
    "parameter_std",
    "parameter_uncertainty",
    "prediction_std",
    "z_value",
]

FloatArray = npt.NDArray[np.float64]

#: Interval methods, the default first.
METHODS = ("bootstrap", "hac")
#: The method the report's intervals use (the one that covers in benchmarks/bench_coverage.py).
DEFAULT_METHOD = "bootstrap"
#: Standard deviations of the two methods that differ by more than this factor are flagged.
DISAGREE_RATIO = 1.5
_MAX_RHO = 0.97


def z_value(level: float) -> float:
    """Two-sided normal quantile of a confidence ``level`` in (0, 1) (1.96 for 0.95)."""
    if not 0.0 < level < 1.0:
        raise DataError(f"confidence level {level} must lie in (0, 1).")
    return float(scipy.stats.norm.ppf(0.5 + 0.5 * level))


@dataclass(frozen=True, eq=False)
class BlockEquations:
    """Weighted normal equations of consecutive blocks of identification rows.

    Attributes
    ----------
    A :
        ``sum_j w_j^2 W_bj^T W_bj`` per block, shape (n_blocks, n, n).
    c :
        ``sum_j w_j^2 W_bj^T y_bj`` per block, shape (n_blocks, n).
    n_rows :
        Rows (samples x joints) per block, shape (n_blocks,).
    block_samples :
        Decimated samples per block (the last block of a chunk may have fewer).
    """

    A: FloatArray
    c: FloatArray
    n_rows: npt.NDArray[np.int64]
    block_samples: int

    def __post_init__(self) -> None:
        if self.A.ndim != 3 or self.c.shape != self.A.shape[:2]:
            raise DataError(f"A {self.A.shape} and c {self.c.shape}: need (b, n, n), (b, n).")

    @property
    def n_blocks(self) -> int:
        """Number of blocks."""
        return int(self.A.shape[0])

    @classmethod
    def from_samples(
        cls,
        Yb: FloatArray,
        tau: FloatArray,
        keep: npt.NDArray[np.bool_],
        weights: FloatArray,
        block_samples: int,
    ) -> BlockEquations:
        """Blocks of ``block_samples`` consecutive samples of rows ``Yb`` (n_samples, nv, n),
        torques ``tau`` (n_samples, nv) [N*m], kept rows ``keep`` (n_samples, nv) and
        per-joint weights ``weights`` (nv,) [1/(N*m)]."""
        n_samples, _, n = Yb.shape
        step = max(1, int(block_samples))
        w2 = np.where(keep, np.asarray(weights, dtype=float)[None, :] ** 2, 0.0)
        n_blocks = -(-n_samples // step)
        A = np.empty((n_blocks, n, n))
        c = np.empty((n_blocks, n))
        n_rows = np.empty(n_blocks, dtype=np.int64)
        # block by block: memory of one block's rows, not of the chunk's (the chunk's weighted
        # and padded copies took ~100 MB for five minutes of a 7-joint arm at 1 kHz)
        for b in range(n_blocks):
            rows = slice(b * step, (b + 1) * step)
            W = Yb[rows].reshape(-1, n)
            Ww = W * w2[rows].reshape(-1, 1)  # dropped rows weigh 0
            A[b] = Ww.T @ W
            c[b] = Ww.T @ tau[rows].reshape(-1)
            n_rows[b] = np.count_nonzero(keep[rows])
        return cls(A=A, c=c, n_rows=n_rows, block_samples=step)

    @classmethod
    def concatenate(cls, parts: list[BlockEquations]) -> BlockEquations:
        """The blocks of ``parts`` one after another (in time order)."""
        if not parts:
            raise DataError("no blocks to concatenate.")
        return cls(
            A=np.concatenate([p.A for p in parts]),
            c=np.concatenate([p.c for p in parts]),
            n_rows=np.concatenate([p.n_rows for p in parts]),
            block_samples=parts[0].block_samples,
        )

    def nonempty(self) -> BlockEquations:
        """The blocks with at least one row."""
        keep = self.n_rows > 0
        if keep.all():
            return self
        return BlockEquations(
            A=self.A[keep],
            c=self.c[keep],
            n_rows=self.n_rows[keep],
            block_samples=self.block_samples,
        )

    def solve(self, multiplicity: FloatArray | None = None) -> FloatArray:
        """``x`` of ``(sum_b m_b A_b) x = sum_b m_b c_b`` (``m_b = 1`` by default), (n,)."""
        if multiplicity is None:
            A, c = self.A.sum(axis=0), self.c.sum(axis=0)
        else:
            A, c = np.tensordot(multiplicity, self.A, axes=1), multiplicity @ self.c
        return np.asarray(scipy.linalg.solve(A, c, assume_a="pos", check_finite=False))


def andrews_bandwidth(scores: FloatArray) -> float:
    """Bartlett-kernel bandwidth ``S`` [blocks] of Andrews' AR(1) plug-in (module docstring).

    ``scores`` (n_blocks, n): the block scores; returns ``S`` in ``[1, n_blocks / 4]``.
    """
    s = np.asarray(scores, dtype=float)
    n_b = s.shape[0]
    if n_b < 8:
        return 1.0
    scale = np.sqrt(np.mean(s**2, axis=0))
    used = scale > 0
    z = s[:, used] / scale[used]
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.sum(z[1:] * z[:-1], axis=0) / np.sum(z[:-1] ** 2, axis=0)
    rho = np.clip(np.nan_to_num(rho), -_MAX_RHO, _MAX_RHO)
    sig4 = (1.0 - rho**2) ** 2  # innovation variance^2 of a unit-variance AR(1)
    num = np.sum(4.0 * rho**2 * sig4 / ((1.0 - rho) ** 6 * (1.0 + rho) ** 2))
    den = np.sum(sig4 / (1.0 - rho) ** 4)
    alpha = num / den if den > 0 else 0.0
    S = 1.1447 * (alpha * n_b) ** (1.0 / 3.0)
    return float(np.clip(S, 1.0, max(1.0, n_b / 4.0)))


def hac_covariance(
    blocks: BlockEquations, bandwidth: float | None = None
) -> tuple[FloatArray, FloatArray, float]:
    """Newey-West covariance of the weighted least-squares solution of ``blocks``.

    Returns ``(x, C, S)``: the solution (n,), its covariance (n, n) and the bandwidth used
    [blocks] (:func:`andrews_bandwidth` when ``bandwidth`` is None). Module docstring.
    """
    b = blocks.nonempty()
    n = b.A.shape[1]
    if b.n_blocks <= n:
        raise DataError(f"{b.n_blocks} blocks for {n} parameters: too few for a covariance.")
    x = b.solve()
    scores = b.c - np.einsum("bpq,q->bp", b.A, x)
    S = andrews_bandwidth(scores) if bandwidth is None else float(bandwidth)
    B = scores.T @ scores
    for lag in range(1, int(np.ceil(S))):
        weight = 1.0 - lag / S
        if weight <= 0:
            break
        G = scores[lag:].T @ scores[:-lag]
        B += weight * (G + G.T)
    A_inv = np.linalg.inv(b.A.sum(axis=0))
    C = A_inv @ B @ A_inv * (b.n_blocks / (b.n_blocks - n))
    return x, 0.5 * (C + C.T), S


def bootstrap_counts(
    n_blocks: int, block_length: int, n_boot: int, rng: np.random.Generator | int | None
) -> FloatArray:
    """Multiplicity of every block in each moving-block resample, shape (n_boot, n_blocks).

    Each resample draws ``ceil(n_blocks / L)`` runs of ``L = block_length`` (clipped to
    ``[1, n_blocks]``) consecutive blocks, circularly, with uniform starts.
    """
    length = int(np.clip(block_length, 1, n_blocks))
    n_runs = int(np.ceil(n_blocks / length))
    gen = np.random.default_rng(rng)
    starts = gen.integers(0, n_blocks, size=(n_boot, n_runs))
    index = (starts[:, :, None] + np.arange(length)[None, None, :]) % n_blocks
    counts = np.zeros((n_boot, n_blocks))
    np.add.at(counts, (np.arange(n_boot)[:, None], index.reshape(n_boot, -1)), 1.0)
    return counts


def block_bootstrap(
    blocks: BlockEquations,
    block_length: int,
    *,
    n_boot: int = 400,
    rng: np.random.Generator | int | None = None,
) -> FloatArray:
    """Re-estimates on moving-block resamples, shape (n_boot, n) (module docstring).

    ``block_length``: consecutive blocks per run (>= 1); ``rng``: generator or seed.
    """
    b = blocks.nonempty()
    n_b = b.n_blocks
    counts = bootstrap_counts(n_b, block_length, n_boot, rng)
    n = b.A.shape[1]
    A = (counts @ b.A.reshape(n_b, -1)).reshape(n_boot, n, n)
    c = counts @ b.c
    return np.asarray(np.linalg.solve(A, c[:, :, None])[:, :, 0], dtype=float)


@dataclass(frozen=True, eq=False)
class Uncertainty:
    """Standard deviations of the base parameters by interval method.

    Attributes
    ----------
    names :
        Base parameter names, length n.
    x :
        The estimate the intervals are centred on, shape (n,).
    covariance :
        ``{"ordinary" | "hac" | "bootstrap": (n, n)}``.
    bandwidth :
        HAC bandwidth [blocks] (the bootstrap's run length is its ceiling).
    block_samples :
        Decimated samples per block.
    n_blocks :
        Blocks with rows.
    n_boot :
        Bootstrap resamples.
    x_blocks :
        The weighted least-squares solution of the blocks, shape (n,): equal to ``x`` for
        a least-squares estimate up to the final WLS re-weighting (a check of the blocks).
    method :
        The default method (:data:`DEFAULT_METHOD`).
    """

    names: tuple[str, ...]
    x: FloatArray
    covariance: dict[str, FloatArray]
    bandwidth: float
    block_samples: int
    n_blocks: int
    n_boot: int
    x_blocks: FloatArray
    method: str = DEFAULT_METHOD

    def std(self, method: str | None = None) -> FloatArray:
        """Standard deviations of ``method`` (default :attr:`method`), shape (n,)."""
        C = self.covariance[method or self.method]
        return np.sqrt(np.clip(np.diag(C), 0.0, None))

    def interval(self, level: float = 0.95, method: str | None = None) -> FloatArray:
        """``[lower, upper]`` per parameter at confidence ``level``, shape (n, 2)."""
        half = z_value(level) * self.std(method)
        return np.column_stack([self.x - half, self.x + half])

    def disagreeing(self) -> tuple[str, ...]:
        """Parameters whose HAC and bootstrap standard deviations differ by more than
        :data:`DISAGREE_RATIO` (either way)."""
        a, b = self.std("hac"), self.std("bootstrap")
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = np.maximum(a / b, b / a)
        return tuple(n for n, r in zip(self.names, ratio, strict=True) if r > DISAGREE_RATIO)


#: What :attr:`ParameterStd.note` says when the ordinary standard deviation is used.
ORDINARY_NOTE = (
    "ordinary standard deviations (independent residuals; 2-8x too small on correlated "
    "residuals, docs/uncertainty.md): {why}"
)


@dataclass(frozen=True, eq=False)
class ParameterStd:
    """The standard deviation of the base parameters every consumer reads.

    Attributes
    ----------
    std :
        Standard deviations (SI, the parameters' units), shape (n,).
    relative_std :
        ``100 std / |x|`` [%], ``inf`` where ``x = 0``, shape (n,).
    method :
        ``"bootstrap"`` (:data:`DEFAULT_METHOD`), ``"hac"`` or ``"ordinary"``.
    covariance :
        The covariance the standard deviations come from, shape (n, n): the one to use for
        the standard deviation of a combination ``w @ x`` (``sqrt(w @ C @ w)``).
    note :
        Empty for a calibrated method; else why the ordinary standard deviation is used.
    """

    std: FloatArray
    relative_std: FloatArray
    method: str
    covariance: FloatArray
    note: str = ""

    @property
    def calibrated(self) -> bool:
        """Whether the standard deviations account for correlated residuals."""
        return self.method != "ordinary"


def parameter_std(estimate: Any, unc: Uncertainty | None) -> ParameterStd:
    """The one standard deviation of an ``estimate`` (module docstring).

    ``estimate``: an :class:`~ident.identify.estimation.estimate.Estimate` (``x``, ``std``,
    ``relative_std``, shape (n,)). ``unc``'s default method when ``unc`` was computed for this
    very estimate (``unc.x`` equal to ``estimate.x``); else the estimate's ordinary standard
    deviations with the reason in the note (``unc`` None: no bootstrap, too few blocks).
    """
    x = np.asarray(estimate.x, dtype=float)
    if unc is not None and unc.x.shape == x.shape and np.array_equal(unc.x, x):
        std = unc.std()
        with np.errstate(divide="ignore", invalid="ignore"):
            rel = np.where(x != 0.0, 100.0 * std / np.abs(x), np.inf)
        return ParameterStd(
            std=std, relative_std=rel, method=unc.method, covariance=unc.covariance[unc.method]
        )
    why = (
        "no block-bootstrap covariance (too few blocks of identification rows for it)"
        if unc is None
        else "no calibrated interval for this estimate"
    )
    return ParameterStd(
        std=np.asarray(estimate.std, dtype=float),
        relative_std=np.asarray(estimate.relative_std, dtype=float),
        method="ordinary",
        # an estimate without a covariance (a summary) gives the diagonal of its std
        covariance=np.asarray(
            getattr(estimate, "covariance", None)
            if getattr(estimate, "covariance", None) is not None
            else np.diag(np.asarray(estimate.std, dtype=float) ** 2),
            dtype=float,
        ),
        note=ORDINARY_NOTE.format(why=why),
    )


def parameter_uncertainty(
    blocks: BlockEquations,
    names: tuple[str, ...],
    x: FloatArray,
    ordinary: FloatArray,
    *,
    n_boot: int = 400,
    rng: np.random.Generator | int | None = 0,
) -> Uncertainty:
    """HAC and block-bootstrap covariances of an estimate ``x`` (n,) from its ``blocks``.

    ``ordinary`` (n, n) is the estimate's ordinary covariance, kept for comparison.
    """
    x_blocks, C_hac, S = hac_covariance(blocks)
    boot = block_bootstrap(blocks, int(np.ceil(S)), n_boot=n_boot, rng=rng)
    C_boot = np.cov(boot, rowvar=False)
    return Uncertainty(
        names=tuple(names),
        x=np.asarray(x, dtype=float),
        covariance={"ordinary": np.asarray(ordinary), "hac": C_hac, "bootstrap": C_boot},
        bandwidth=S,
        block_samples=blocks.block_samples,
        n_blocks=blocks.nonempty().n_blocks,
        n_boot=n_boot,
        x_blocks=x_blocks,
    )


def prediction_std(Yb: FloatArray, covariance: FloatArray, sigma: FloatArray) -> FloatArray:
    """Standard deviation of a held-out torque about its prediction [N*m], (n_samples, nv).

    ``sqrt(r^T C r + sigma_j^2)`` for the base rows ``Yb`` (n_samples, nv, n), the parameter
    covariance ``C`` (n, n) and the per-joint residual RMS ``sigma`` (nv,) [N*m].
    """
    # C = V diag(e) V^T (symmetric, PSD up to round-off): r^T C r = ||diag(sqrt(e)) V^T r||^2
    e, V = np.linalg.eigh(0.5 * (covariance + covariance.T))
    F = V * np.sqrt(np.clip(e, 0.0, None))[None, :]
    P = Yb @ F
    P *= P  # in place: one temporary of the rows' size, not two
    var = P.sum(axis=-1)
    return np.sqrt(np.clip(var, 0.0, None) + np.asarray(sigma, dtype=float)[None, :] ** 2)


def coverage_summary(
    unc: Uncertainty,
    *,
    level: float = 0.95,
    truth: FloatArray | None = None,
    held_out: tuple[FloatArray, dict[str, FloatArray], npt.NDArray[np.bool_]] | None = None,
) -> dict:
    """What the report says of the intervals (JSON-ready).

    Parameters
    ----------
    unc :
        The covariances.
    level :
        Confidence level of the intervals.
    truth :
        True base parameters (simulation), shape (n,): the fraction inside each method's
        interval is reported.
    held_out :
        ``(residual, std, keep)``: held-out torque errors (n_val, nv) [N*m], their standard
        deviation per method (:func:`prediction_std`) and the rows above the velocity
        threshold (n_val, nv): the fraction of kept rows inside each method's prediction
        interval (a calibration check that needs no truth).
    """
    z = z_value(level)
    methods = ("ordinary", *METHODS)
    out: dict = {
        "method": unc.method,
        "level": level,
        "bandwidth_blocks": unc.bandwidth,
        "block_samples": unc.block_samples,
        "n_blocks": unc.n_blocks,
        "n_boot": unc.n_boot,
        "disagreeing": list(unc.disagreeing()),
        "truth_inside": None,
        "held_out_inside": None,
    }
    if truth is not None:
        error = np.abs(unc.x - np.asarray(truth, dtype=float))
        out["truth_inside"] = {m: float(np.mean(error <= z * unc.std(m))) for m in methods}
    if held_out is not None:
        residual, std, keep = held_out
        out["held_out_inside"] = {
            m: float(np.mean((np.abs(residual) <= z * std[m])[keep])) for m in methods if m in std
        }
    return out


def interval_coverage(unc: Uncertainty, truth: npt.ArrayLike, level: float = 0.95) -> float:
    """Fraction of the true values ``truth`` (n,) inside the default method's intervals."""
    lo_hi = unc.interval(level)
    t = np.asarray(truth, dtype=float)
    return float(np.mean((lo_hi[:, 0] <= t) & (t <= lo_hi[:, 1])))
