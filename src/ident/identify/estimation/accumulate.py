"""Accumulation of a log's observation rows in bounded memory: chunks reduced as they come.

The one path of every identification
(:func:`ident.identify.pipeline.core.identify_measurements`): a log segment is processed in
chunks of decimated samples (a whole segment is one chunk unless
:func:`~ident.identify.estimation.log_chunks.use_chunks` says otherwise; the regressor of every
sample of one hour at 1 kHz of a 7-joint arm would be 14 GB); each chunk

1. takes its raw samples plus margins on both sides (``margin_samples``: long enough for the
   impulse responses of the zero-phase low-pass and of the decimation filters to decay below
   round-off, so that the kept samples equal those of the whole-log processing to ~1e-12;
   chunks that touch an end of the segment take the end as the whole-log path does, with the
   same padding);
2. low-passes and differentiates its positions (:mod:`ident.identify.estimation.preprocess`), then,
a
   :data:`ROW_BLOCK` of samples at a time, computes the rigid-body regressor (the numba kernel
   of :mod:`ident.dynamics.regressor`), the extra columns (:mod:`ident.dynamics.friction`) and
   the base columns and pushes them with the torques through the decimation filters
   (:class:`~ident.identify.estimation.preprocess.DecimationStream`: the full-rate regressor of a
   chunk never exists whole), keeping its own decimated samples (:func:`decimated_rows`);
3. applies the velocity threshold and reduces its identification rows at once into a
   :class:`~ident.identify.estimation.observations.ReducedObservations` (per-joint triangular
   factors), merged into the running one.

Nothing per sample outlives a chunk except the held-out part's torques and predictions
(``(n_validate, nv)`` each, for the report's plots), so memory is set by the chunk size
(``log_chunks.chunk_bytes``, ``log_chunks.default_chunk_samples``) and time is linear in the
log length. The estimators (:mod:`ident.identify.estimators`) and the essential-parameter
reduction work on the reduction alone. Several segments (gaps, windows) and several logs merge
their reductions; ``scheduler=`` hands the chunks to a Dask cluster
(:mod:`ident.identify.estimation.log_chunks` runs the chunks; this module processes one).

Chunk reduction, per joint: one Gram product of ``[W | y]`` (BLAS ``syrk``) and the Cholesky
factor of its column-scaled form. When LAPACK's estimate of the scaled ``W`` block's condition
number is at most :data:`GRAM_MAX_COND` (1e3), that factor is the reduction (``R = R_s D``,
``z``; ``rho`` from the residual of the chunk's own fit, not by a subtraction): the normal
equations then differ from a QR's by ~1e-13 relative to ``W``'s column norms and an estimate by
~1e-11 relative (measured: up to ~2.5e-14 times that condition number). Otherwise (the Gram
squares the condition number: a chunk of a wrist stage reaches 5e10) the rows are reduced by
CholeskyQR2 (a second Gram product and a triangular solve; as accurate as Householder QR for
condition numbers below ~1e7 after equilibration), and by Householder QR when the Gram matrix
is not positive definite (rows that do not excite some columns). The choice is made per chunk
and joint from that chunk's rows; the merged normal equations keep the bound (a perturbation
``F`` of a chunk's Gram matrix ``G`` with ``|x^T F x| <= delta x^T G x`` sums to one of the
same ``delta`` for the sum, whatever the other chunks).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.linalg
from numba import njit
from scipy import signal
from scipy.linalg import lapack

from ident.dynamics.chain import KinematicChain
from ident.dynamics.friction import extra_columns
from ident.dynamics.gram import selected_rows
from ident.dynamics.parameter_model import ParameterModel
from ident.errors import DataError
from ident.identify.config import PreprocessConfig
from ident.identify.estimation import preprocess
from ident.identify.estimation.essential import EssentialResult, backward_elimination
from ident.identify.estimation.estimate import Estimate, least_squares_reduced
from ident.identify.estimation.observations import ReducedObservations, reduce_rows
from ident.identify.estimation.reference import ReferenceWeights
from ident.signals import decay_length

__all__ = [
    "ROW_BLOCK",
    "BaseColumns",
    "Chunk",
    "ChunkPlan",
    "decimated_rows",
    "essential_reduced",
    "estimate_reduced",
    "iter_chunks",
    "margin_samples",
    "reduce_chunk",
    "regressor_bytes",
]


FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class ChunkPlan:
    """How a segment is cut: sizes in raw samples of the segment.

    Attributes
    ----------
    n_samples :
        Raw samples of the segment.
    n_edge :
        ``preprocess.trim_samples``.
    step :
        Product of the decimation factors (raw samples per decimated sample).
    n_decimated :
        Decimated samples of the whole segment (as the in-memory path).
    chunk_decimated :
        Decimated samples a chunk keeps.
    signal_margin :
        Raw samples added on both sides for the low-pass and the differentiation.
    decimation_margin :
        Trimmed samples added on both sides for the decimation filters (multiple of ``step``).
    """

    n_samples: int
    n_edge: int
    step: int
    n_decimated: int
    chunk_decimated: int
    signal_margin: int
    decimation_margin: int

    def ranges(self, start: int = 0, stop: int | None = None) -> list[tuple[int, int]]:
        """Decimated index ranges ``[d0, d1)`` of the chunks covering ``[start, stop)``."""
        stop = self.n_decimated if stop is None else stop
        edges = list(range(start, stop, self.chunk_decimated)) + [stop]
        return [(a, b) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


@functools.lru_cache(maxsize=64)
def _lowpass_decay(order: int, cutoff_hz: float, sampling_rate_hz: float) -> int:
    """:func:`decay_length` of a Butterworth low-pass [samples] (cached: a log of many
    segments plans each with the same filters)."""
    sos = signal.butter(order, cutoff_hz, fs=sampling_rate_hz, output="sos")
    return decay_length(sos)


@functools.lru_cache(maxsize=64)
def _antialias_decay(factor: int) -> int:
    """:func:`decay_length` of the decimation filter of ``factor`` [samples] (cached)."""
    return decay_length(preprocess.antialias_sos(factor))


def margin_samples(pp: PreprocessConfig, sampling_rate_hz: float) -> tuple[int, int]:
    """``(signal_margin, decimation_margin)`` in raw samples for the settings ``pp``."""
    signal_margin = 4  # np.gradient twice: two neighbours, edge formulas one further
    for flt in (preprocess.position_filter(pp), pp.torque_lowpass):
        if flt is not None:
            decay = _lowpass_decay(flt.order, flt.cutoff_hz, sampling_rate_hz)
            signal_margin = max(signal_margin, 2 * decay + 4)
    decimation_margin, scale = 0, 1
    for factor in preprocess.decimation_factors(pp):
        if factor == 1:
            continue
        decimation_margin += scale * (2 * _antialias_decay(factor) + 2)
        scale *= factor
    step = preprocess.decimation_step(pp)
    decimation_margin = step * int(np.ceil(decimation_margin / step))
    return signal_margin, decimation_margin


def make_plan(
    n_samples: int, pp: PreprocessConfig, sampling_rate_hz: float, chunk_samples: int
) -> ChunkPlan:
    """The chunking of a segment of ``n_samples`` raw samples (see :class:`ChunkPlan`)."""
    step = preprocess.decimation_step(pp)
    n_trim = n_samples - 2 * pp.trim_samples
    if n_trim <= 0:
        raise DataError(f"trim_samples = {pp.trim_samples} removes all {n_samples} samples.")
    n_dec = preprocess.decimated_length(n_trim, preprocess.decimation_factors(pp))
    signal_margin, decimation_margin = margin_samples(pp, sampling_rate_hz)
    return ChunkPlan(
        n_samples=n_samples,
        n_edge=pp.trim_samples,
        step=step,
        n_decimated=n_dec,
        chunk_decimated=max(1, chunk_samples // step),
        signal_margin=signal_margin,
        decimation_margin=decimation_margin,
    )


@dataclass(frozen=True, eq=False)
class Chunk:
    """Decimated samples ``[start, stop)`` of a segment: torques, base regressor, velocities."""

    start: int
    stop: int
    tau: FloatArray  # (n, nv) [N*m]
    Yb: FloatArray  # (n, nv, n_base)
    dq: FloatArray  # (n, nv) [rad/s]


def iter_chunks(
    plan: ChunkPlan,
    q: FloatArray,
    tau: FloatArray,
    sampling_rate_hz: float,
    pp: PreprocessConfig,
    columns: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
    ranges: list[tuple[int, int]],
    states: tuple[FloatArray, FloatArray] | None = None,
) -> Iterator[Chunk]:
    """Process the decimated ranges of one segment (raw ``q``, ``tau``: (n_samples, nv)).

    ``columns(q, dq, ddq)`` gives the regressor columns to keep, shape (n, nv, p).
    ``states``: the segment's measured ``(dq, ddq)`` (n_samples, nv) [rad/s, rad/s^2] (a
    simulator's states), used as they are: ``q`` is then neither low-passed nor differentiated.
    """
    fs = sampling_rate_hz
    n, n_edge, step = plan.n_samples, plan.n_edge, plan.step
    n_trim = n - 2 * n_edge
    position, factors = preprocess.position_filter(pp), preprocess.decimation_factors(pp)
    for d0, d1 in ranges:
        s = max(0, d0 * step - plan.decimation_margin)  # trimmed indices, multiple of step
        e = min(n_trim, d1 * step + plan.decimation_margin)
        r0 = max(0, s + n_edge - plan.signal_margin)  # raw indices
        r1 = min(n, e + n_edge + plan.signal_margin)
        q_c, tau_c = q[r0:r1], tau[r0:r1]
        if position is not None and states is None:
            q_c, _ = preprocess.lowpass(q_c, fs, position.cutoff_hz, position.order)
        if pp.torque_lowpass is not None:
            tau_c, _ = preprocess.lowpass(
                tau_c, fs, pp.torque_lowpass.cutoff_hz, pp.torque_lowpass.order, what="tau"
            )
        if states is None:
            dq_c, ddq_c, _ = preprocess.differentiate(q_c, fs)
        else:
            dq_c, ddq_c = states[0][r0:r1], states[1][r0:r1]
        a, b = s + n_edge - r0, e + n_edge - r0
        q_c, dq_c, ddq_c, tau_c = q_c[a:b], dq_c[a:b], ddq_c[a:b], tau_c[a:b]
        k0 = d0 - s // step  # the chunk's own decimated rows, after the margin's
        kept = (k0, k0 + (d1 - d0))
        tau_d, Yb_d, dq_d = decimated_rows(columns, q_c, dq_c, ddq_c, tau_c, factors, kept)
        yield Chunk(start=d0, stop=d1, tau=tau_d, Yb=Yb_d, dq=dq_d)


#: Samples whose regressor rows are computed at once (then streamed through the decimation
#: filters): 3.4 MB for 7 joints and 60 columns, whatever the chunk's length.
ROW_BLOCK = 1024


def decimated_rows(
    columns: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    tau: FloatArray,
    factors: list[int],
    kept: tuple[int, int] | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``preprocess.decimate([tau, columns(q, dq, ddq), dq], factors)`` (shapes (n, nv),
    (n, nv, p), (n, nv) decimated; only the decimated rows ``kept = (k0, k1)`` when given),
    the regressor computed and filtered :data:`ROW_BLOCK` samples at a time
    (:class:`~ident.identify.estimation.preprocess.DecimationStream`), never whole.

    Columns zero throughout the first block are left out of the filtering (about half of a
    serial arm's: a joint's row has no term of the bodies before it); filtering zeros gives
    zeros. Should one of them not be zero later (a joint held still, then moving), the chunk is
    processed again with every column.
    """
    for every_column in (False, True):
        out = _streamed_rows(columns, (q, dq, ddq), tau, factors, every_column, kept)
        if out is not None:
            return out
    raise AssertionError("unreachable: every column is filtered on the second pass")


def _streamed_rows(
    columns: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
    states: tuple[FloatArray, FloatArray, FloatArray],
    tau: FloatArray,
    factors: list[int],
    every_column: bool,
    kept: tuple[int, int] | None,
) -> tuple[FloatArray, FloatArray, FloatArray] | None:
    """:func:`decimated_rows`, filtering the regressor columns nonzero in the first block (all
    when ``every_column``); None if another one is nonzero later."""
    q, dq, ddq = states
    n, nv = tau.shape
    k0, k1 = kept if kept is not None else (0, preprocess.decimated_length(n, factors))
    tau_d, dq_d = np.empty((k1 - k0, nv)), np.empty((k1 - k0, nv))
    at = -k0  # output row of the next decimated row
    for lo in range(0, n, ROW_BLOCK):
        hi = min(n, lo + ROW_BLOCK)
        Y = columns(q[lo:hi], dq[lo:hi], ddq[lo:hi])
        flat = Y.reshape(hi - lo, -1)
        if lo == 0:
            p = Y.shape[2]
            filtered = np.ones(flat.shape[1], dtype=bool) if every_column else flat.any(axis=0)
            active, idle = np.flatnonzero(filtered), np.flatnonzero(~filtered)
            stream = preprocess.DecimationStream(factors, 2 * nv + active.size)
            block = np.empty((min(n, ROW_BLOCK), 2 * nv + active.size))
            Yb = np.zeros((k1 - k0, nv * p))  # the idle columns stay zero
        rows = block[: hi - lo]  # [tau | active regressor columns | dq]
        if not _gather(tau[lo:hi], flat, dq[lo:hi], active, idle, rows):
            return None
        at = _scatter(stream.push(rows), at, tau_d, Yb, dq_d, active)
    _scatter(stream.finish(), at, tau_d, Yb, dq_d, active)
    return tau_d, Yb.reshape(-1, nv, p), dq_d


def _scatter(
    rows: FloatArray,
    at: int,
    tau: FloatArray,
    Yb: FloatArray,
    dq: FloatArray,
    active: npt.NDArray[np.int64],
) -> int:
    """Write decimated rows ``[tau | active columns | dq]`` from row ``at`` of the outputs
    (rows outside them dropped: the margins'); the next row."""
    nv, m = tau.shape[1], rows.shape[0]
    a, b = max(at, 0), min(at + m, tau.shape[0])
    if b > a:
        part = rows[a - at : b - at]
        tau[a:b] = part[:, :nv]
        Yb[a:b, active] = part[:, nv:-nv]
        dq[a:b] = part[:, -nv:]
    return at + m


@njit(cache=True, nogil=True)
def _gather(  # noqa: PLR0913
    tau: FloatArray,
    Y: FloatArray,
    dq: FloatArray,
    active: npt.NDArray[np.int64],
    idle: npt.NDArray[np.int64],
    out: FloatArray,
) -> bool:
    """``out[r] = [tau[r], Y[r, active], dq[r]]`` (one pass over the rows, no temporaries);
    False as soon as a column of ``Y[:, idle]`` is not zero."""
    nv, n_active = tau.shape[1], active.size
    for r in range(Y.shape[0]):
        for c in range(idle.size):
            if Y[r, idle[c]] != 0.0:
                return False
        for j in range(nv):
            out[r, j] = tau[r, j]
        for c in range(n_active):
            out[r, nv + c] = Y[r, active[c]]
        for j in range(nv):
            out[r, nv + n_active + j] = dq[r, j]
    return True


def regressor_bytes(n_samples: int, nv: int, n_columns: int) -> int:
    """Bytes of a log's full-rate regressor arrays (rigid + extra + base, decimation copy), the
    size :func:`use_chunks` compares with ``preprocess.max_regressor_mb``. Neither path holds
    them any more (:func:`decimated_rows`); the memory of a chunk is :func:`chunk_bytes`."""
    return 8 * n_samples * nv * n_columns * 3


#: Largest condition number estimate (LAPACK ``dpocon``, 1-norm) of a group's column-scaled
#: Gram matrix for which its Cholesky factor is kept as the group's reduction (module docstring).
GRAM_MAX_COND = 1e3


def _householder(A: FloatArray, n: int) -> tuple[FloatArray, FloatArray, float]:
    return reduce_rows(A[:, :n], A[:, n], n)


def _reduce_group(A: FloatArray, n: int) -> tuple[FloatArray, FloatArray, float, str]:
    """``(R, z, rho, method)`` of rows ``A = [W | y]`` (m, n + 1), ``method`` the one used:
    ``"gram"``, ``"cholesky_qr2"`` or ``"householder"`` (module docstring)."""
    m = A.shape[0]
    if m <= n + 1 or n == 0:
        return (*_householder(A, n), "householder")
    G = A.T @ A  # BLAS syrk, one pass over the rows
    d = np.sqrt(np.diag(G))
    d[d == 0] = 1.0
    Gs = G / np.outer(d, d)  # the Gram of the column-scaled rows
    try:
        Rw = scipy.linalg.cholesky(Gs[:n, :n], lower=False, check_finite=False)
    except np.linalg.LinAlgError:
        return (*_householder(A, n), "householder")
    # LAPACK's estimate of the 1-norm condition number of the scaled W block
    rcond, _ = lapack.dpocon(Rw, float(np.abs(Gs[:n, :n]).sum(axis=0).max()))
    if rcond * GRAM_MAX_COND < 1.0:
        return (*_cholesky_qr2(A, n, (Gs, d)), "cholesky_qr2")
    # z = Rw^-T W^T y, R = Rw D; rho from the residual of the chunk's fit (not ||y||^2 -
    # ||z||^2, a cancellation when the fit is close; y is not in the factored block, so an
    # exact fit, noise-free torques, factors as well)
    zs = scipy.linalg.solve_triangular(Rw, Gs[:n, n], trans="T", check_finite=False)
    x = scipy.linalg.solve_triangular(Rw, zs, check_finite=False) * (d[n] / d[:n])
    r = A[:, n] - A[:, :n] @ x
    return Rw * d[:n], zs * d[n], float(r @ r), "gram"


def _cholesky_qr2(
    A: FloatArray, n: int, gram: tuple[FloatArray, FloatArray] | None = None
) -> tuple[FloatArray, FloatArray, float]:
    """``(R, z, rho)`` of rows ``A = [W | y]`` (m, n + 1) by CholeskyQR2 (module docstring).

    ``gram``: the Gram matrix of the column-scaled rows (n + 1, n + 1) and the scale (n + 1,)
    when already computed (one BLAS product less).
    """
    m = A.shape[0]
    R = np.zeros((n, n))
    z = np.zeros(n)
    if m == 0:
        return R, z, 0.0
    if m <= n + 1:
        return _householder(A, n)
    if gram is None:
        norms = np.linalg.norm(A, axis=0)
        scale = np.where(norms > 0, norms, 1.0)
        As = A / scale
        Gs = As.T @ As
    else:
        Gs, scale = gram
        As = A / scale
    try:
        R1 = scipy.linalg.cholesky(Gs, lower=False, check_finite=False)
        # Q1 = As R1^-1 by a triangular solve (backward stable; the second pass restores
        # orthogonality). Not through the explicit inverse: ``As @ inv(R1)`` adds a backward
        # error of eps * cond(R1), which on an ill-conditioned chunk (cond 5e10 in the last
        # fifth of a wrist period) moved the estimate by 1e-10 relative instead of 1e-14.
        Q1 = scipy.linalg.solve_triangular(R1, As.T, trans="T", check_finite=False).T
        R2 = scipy.linalg.cholesky(Q1.T @ Q1, lower=False, check_finite=False)
    except np.linalg.LinAlgError:
        return _householder(A, n)
    Rf = (R2 @ R1) * scale  # undo the column scaling: A = Q (R2 R1 D)
    if not np.all(np.isfinite(Rf)):
        return _householder(A, n)
    return Rf[:n, :n].copy(), Rf[:n, n].copy(), float(Rf[n, n] ** 2)


def reduce_chunk(
    Yb: FloatArray, tau: FloatArray, keep: BoolArray, methods: list[str] | None = None
) -> ReducedObservations:
    """Reduce the kept rows of one chunk, per joint.

    ``Yb`` (n, nv, p), ``tau`` (n, nv), ``keep`` (n, nv): row ``(k, j)`` enters group ``j``
    when ``keep[k, j]``. ``methods``, when given, receives the method of every joint
    (:data:`GRAM_MAX_COND`).
    """
    nv, p = Yb.shape[1], Yb.shape[2]
    R = np.zeros((nv, p, p))
    z = np.zeros((nv, p))
    rho = np.zeros(nv)
    yty = np.zeros(nv)
    n_rows = np.zeros(nv, dtype=np.int64)
    # joint j carries no term of the bodies before it: reduce only the columns it has (the
    # reduction of [0 W'] is [0 R']), a third of the work on average
    carried = np.any(Yb != 0.0, axis=0)  # (nv, p), one pass over the chunk
    for j in range(nv):
        rows = keep[:, j]
        every = bool(rows.all())
        Wj = Yb[:, j, :] if every else Yb[rows, j, :]
        cols = np.flatnonzero(carried[j] if every else np.any(Wj != 0.0, axis=0))
        k = cols.size
        A = np.empty((Wj.shape[0], k + 1))
        # copied run by run of consecutive columns (slices; a fancy index is ~10x slower)
        start = 0
        for run in np.split(cols, np.flatnonzero(np.diff(cols) != 1) + 1) if k else []:
            A[:, start : start + run.size] = Wj[:, run[0] : run[-1] + 1]
            start += run.size
        A[:, k] = tau[:, j] if every else tau[rows, j]
        yty[j] = float(A[:, k] @ A[:, k])
        n_rows[j] = A.shape[0]
        Rj, z[j, :k], rho[j], method = _reduce_group(A, k)
        R[j][np.ix_(np.arange(k), cols)] = Rj
        if methods is not None:
            methods.append(method)
    return ReducedObservations(R=R, z=z, rho=rho, yty=yty, n_rows=n_rows)


def _subset(red: ReducedObservations, columns: list[int]) -> ReducedObservations:
    """The reduction of the same rows restricted to ``columns``: ``W_S = Q R[:, S]``."""
    k = len(columns)
    R = np.zeros((red.n_groups, k, k))
    z = np.zeros((red.n_groups, k))
    rho = np.zeros(red.n_groups)
    for j in range(red.n_groups):
        R[j], z[j], extra = reduce_rows(red.R[j][:, columns], red.z[j], k)
        rho[j] = red.rho[j] + extra
    return ReducedObservations(R=R, z=z, rho=rho, yty=red.yty.copy(), n_rows=red.n_rows.copy())


def estimate_reduced(
    red: ReducedObservations,
    names: tuple[str, ...] | list[str],
    *,
    method: str = "ols",
    wls_passes: int = 2,
) -> Estimate:
    """OLS/WLS from a reduction: :func:`ident.identify.estimation.estimate.least_squares_reduced`
    (the formulas of :func:`ident.identify.estimation.estimate.least_squares`, rows grouped by
    joint).

    Raises
    ------
    DataError
        Too few rows.
    NotIdentifiable
        Rank deficiency (the message names the parameters).
    """
    return least_squares_reduced(red, names, method=method, wls_passes=wls_passes)


def essential_reduced(
    red: ReducedObservations,
    names: tuple[str, ...],
    *,
    method: str,
    max_relative_std_pct: float,
    max_residual_increase: float,
) -> EssentialResult:
    """:func:`ident.identify.estimation.essential.essential_parameters` on a reduction (same rule:
    backward elimination of the largest relative std while the residual stays within
    ``1 + max_residual_increase`` of the full set's)."""

    def fit(columns: list[int]) -> Estimate:
        return estimate_reduced(_subset(red, columns), [names[i] for i in columns], method=method)

    return backward_elimination(
        fit,
        names,
        max_relative_std_pct=max_relative_std_pct,
        max_residual_increase=max_residual_increase,
    )


class BaseColumns:
    """The base regressor columns straight from the kernels, in *kernel order*: the rigid-body
    columns computed alone (``selected_rows``, no full regressor and no gather of it), then
    the extra columns. ``order[i]`` is the base parameter of kernel column ``i``.

    With ``reference`` (:class:`~ident.identify.estimation.reference.ReferenceWeights`), one more
    column follows: the torques the reference's parameters predict, decimated like the rest.
    ``rows`` (nv,) marks the joints whose torque rows the model explains (``pm.rows``).
    """

    def __init__(
        self, chain: KinematicChain, pm: ParameterModel, reference: ReferenceWeights | None = None
    ) -> None:
        independent = np.asarray(pm.base.independent)
        rigid = pm.inertial_index[independent] >= 0
        self.chain = chain
        self.terms = pm.terms
        self.rigid_columns = pm.inertial_index[independent[rigid]]
        self.extra_columns = pm.extra_index[independent[~rigid]]
        self.order = np.concatenate([np.flatnonzero(rigid), np.flatnonzero(~rigid)])
        self.reference = reference
        self.rows = np.ones(chain.n_joints, dtype=bool)
        if pm.rows is not None:
            self.rows[:] = False
            self.rows[list(pm.rows)] = True

    def __call__(self, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
        n, nv = dq.shape
        p = self.order.size
        out = np.empty((n, nv, p + (self.reference is not None)))
        a = self.rigid_columns.size
        if a:
            # straight into the block of ``out`` (a strided view of it): no copy
            view = out[:, :, :a].reshape(n * nv, a)
            selected_rows(self.chain, q, dq, ddq, columns=self.rigid_columns, out=view)
        if self.extra_columns.size:
            out[:, :, a:p] = extra_columns(self.terms, dq, ddq)[:, :, self.extra_columns]
        if self.reference is not None:
            out[:, :, p] = self.reference.torques(self.chain, self.terms, q, dq, ddq)
        return out

    def to_base(self, red: ReducedObservations) -> ReducedObservations:
        """A reduction of kernel-order columns as one of base-order columns."""
        R = np.zeros_like(red.R)
        z = np.zeros_like(red.z)
        R[:, :, self.order] = red.R
        z[:] = red.z  # rows are unchanged, only the columns move
        return ReducedObservations(
            R=R, z=z, rho=red.rho.copy(), yty=red.yty.copy(), n_rows=red.n_rows.copy()
        )
