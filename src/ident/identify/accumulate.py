"""Identification of logs of any length in bounded memory: chunks reduced as they come.

The in-memory path builds the regressor of every sample, ``(n_samples, nv, n_params)``
floats: 14 GB for one hour at 1 kHz of a 7-joint arm. Here a log segment is processed in
chunks of decimated samples; each chunk

1. takes its raw samples plus margins on both sides (``margin_samples``: long enough for the
   impulse responses of the zero-phase low-pass and of the decimation filters to decay below
   round-off, so that the kept samples equal those of the whole-log processing to ~1e-12;
   chunks that touch an end of the segment take the end as the whole-log path does, with the
   same padding);
2. low-passes and differentiates (:mod:`ident.identify.preprocess`), computes the rigid-body
   regressor (the numba kernel of :mod:`ident.dynamics.regressor`), the extra columns
   (:mod:`ident.dynamics.friction`) and the base columns, decimates them with the torques, and
   keeps its own decimated samples;
3. applies the velocity threshold and reduces its identification rows at once into a
   :class:`~ident.identify.observations.ReducedObservations` (per-joint triangular factors),
   merged into the running one.

Nothing per sample outlives a chunk except the held-out part's torques and predictions
(``(n_validate, nv)`` each, for the report's plots), so memory is set by the chunk size and
time is linear in the log length. The estimate (OLS/WLS with the same formulas as
:func:`ident.identify.estimate.least_squares`) and the essential-parameter reduction work on
the reduction alone. Several segments (gaps, windows) and several logs merge their reductions;
``scheduler=`` hands the chunks to a Dask cluster.

Chunk reduction: CholeskyQR2 of the column-equilibrated ``[W | y]`` (two Gram products and a
triangular solve, BLAS 3; as accurate as Householder QR for condition numbers below ~1e7 after
equilibration), falling back to Householder QR when the Gram matrix is not positive definite.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.linalg
from scipy import signal

from ident.dynamics.chain import KinematicChain
from ident.dynamics.friction import extra_columns
from ident.errors import DataError, NotIdentifiable
from ident.identify import preprocess
from ident.identify.config import PreprocessConfig
from ident.identify.essential import backward_elimination
from ident.identify.estimate import Estimate, least_squares_reduced
from ident.identify.observations import ReducedObservations

__all__ = [
    "Chunk",
    "ChunkPlan",
    "estimate_reduced",
    "essential_reduced",
    "iter_chunks",
    "margin_samples",
    "reduce_chunk",
    "regressor_bytes",
]

#: How long to wait for a --scheduler before giving up (here and in ``ident bench``).
DASK_CONNECT_TIMEOUT = "10s"

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

# Longest stretch of a chunked log shown in the replay [s].
MOTION_MAX_S = 600.0
# Impulse responses are followed until they fall below this fraction of their peak.
_DECAY_RTOL = 1e-14


def _decay_length(sos: FloatArray, max_len: int = 2_000_000) -> int:
    """Samples after which the impulse response of ``sos`` stays below ``_DECAY_RTOL`` of its
    peak (the transient a chunk edge leaves in a filtered signal)."""
    n = 1024
    while True:
        x = np.zeros(n)
        x[0] = 1.0
        h = np.abs(signal.sosfilt(sos, x))
        above = np.flatnonzero(h > _DECAY_RTOL * h.max())
        if above[-1] < n // 2 or n >= max_len:
            return int(above[-1]) + 1
        n *= 4


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


def margin_samples(pp: PreprocessConfig, sampling_rate_hz: float) -> tuple[int, int]:
    """``(signal_margin, decimation_margin)`` in raw samples for the settings ``pp``."""
    signal_margin = 4  # np.gradient twice: two neighbours, edge formulas one further
    for flt in (pp.lowpass, pp.torque_lowpass):
        if flt is not None:
            sos = signal.butter(flt.order, flt.cutoff_hz, fs=sampling_rate_hz, output="sos")
            signal_margin = max(signal_margin, 2 * _decay_length(sos) + 4)
    decimation_margin, scale = 0, 1
    for factor in pp.decimation:
        if factor == 1:
            continue
        decimation_margin += scale * (2 * _decay_length(preprocess._antialias_sos(factor)) + 2)
        scale *= factor
    step = int(np.prod(pp.decimation)) if pp.decimation else 1
    decimation_margin = step * int(np.ceil(decimation_margin / step))
    return signal_margin, decimation_margin


def make_plan(
    n_samples: int, pp: PreprocessConfig, sampling_rate_hz: float, chunk_samples: int
) -> ChunkPlan:
    """The chunking of a segment of ``n_samples`` raw samples (see :class:`ChunkPlan`)."""
    step = int(np.prod(pp.decimation)) if pp.decimation else 1
    n_trim = n_samples - 2 * pp.trim_samples
    if n_trim <= 0:
        raise DataError(f"trim_samples = {pp.trim_samples} removes all {n_samples} samples.")
    n_dec = n_trim
    for factor in pp.decimation:
        n_dec = -(-n_dec // factor)  # x[::f] keeps ceil(n / f)
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
) -> Iterator[Chunk]:
    """Process the decimated ranges of one segment (raw ``q``, ``tau``: (n_samples, nv)).

    ``columns(q, dq, ddq)`` gives the regressor columns to keep, shape (n, nv, p).
    """
    fs = sampling_rate_hz
    n, n_edge, step = plan.n_samples, plan.n_edge, plan.step
    n_trim = n - 2 * n_edge
    for d0, d1 in ranges:
        s = max(0, d0 * step - plan.decimation_margin)  # trimmed indices, multiple of step
        e = min(n_trim, d1 * step + plan.decimation_margin)
        r0 = max(0, s + n_edge - plan.signal_margin)  # raw indices
        r1 = min(n, e + n_edge + plan.signal_margin)
        q_c, tau_c = q[r0:r1], tau[r0:r1]
        if pp.lowpass is not None:
            q_c, _ = preprocess.lowpass(q_c, fs, pp.lowpass.cutoff_hz, pp.lowpass.order)
        if pp.torque_lowpass is not None:
            tau_c, _ = preprocess.lowpass(
                tau_c, fs, pp.torque_lowpass.cutoff_hz, pp.torque_lowpass.order, what="tau"
            )
        dq_c, ddq_c, _ = preprocess.differentiate(q_c, fs)
        a, b = s + n_edge - r0, e + n_edge - r0
        q_c, dq_c, ddq_c, tau_c = q_c[a:b], dq_c[a:b], ddq_c[a:b], tau_c[a:b]
        Yb = columns(q_c, dq_c, ddq_c)
        bank, _, _ = preprocess.decimate([tau_c, Yb, dq_c], pp.decimation, fs)
        k0 = d0 - s // step
        k1 = k0 + (d1 - d0)
        yield Chunk(
            start=d0,
            stop=d1,
            tau=bank[0][k0:k1],
            Yb=bank[1][k0:k1],
            dq=bank[2][k0:k1],
        )


def regressor_bytes(n_samples: int, nv: int, n_columns: int) -> int:
    """Bytes of the in-memory path's regressor arrays (rigid + extra + base, decimation copy)."""
    return 8 * n_samples * nv * n_columns * 3


def _householder(A: FloatArray, n: int) -> tuple[FloatArray, FloatArray, float]:
    from ident.identify.observations import _reduce

    return _reduce(A[:, :n], A[:, n], n)


def _cholesky_qr2(A: FloatArray, n: int) -> tuple[FloatArray, FloatArray, float]:
    """``(R, z, rho)`` of rows ``A = [W | y]`` (m, n + 1) by CholeskyQR2 (module docstring)."""
    m = A.shape[0]
    R = np.zeros((n, n))
    z = np.zeros(n)
    if m == 0:
        return R, z, 0.0
    if m <= n + 1:
        return _householder(A, n)
    norms = np.linalg.norm(A, axis=0)
    scale = np.where(norms > 0, norms, 1.0)
    As = A / scale
    try:
        R1 = scipy.linalg.cholesky(As.T @ As, lower=False, check_finite=False)
        # Q1 = As R1^-1 through the small inverse: one GEMM (a triangular solve with this many
        # right-hand sides is 10x slower); the second pass restores orthogonality
        R1_inv = scipy.linalg.solve_triangular(R1, np.eye(R1.shape[0]), check_finite=False)
        Q1 = As @ R1_inv
        R2 = scipy.linalg.cholesky(Q1.T @ Q1, lower=False, check_finite=False)
    except np.linalg.LinAlgError:
        return _householder(A, n)
    Rf = (R2 @ R1) * scale  # undo the column scaling: A = Q (R2 R1 D)
    if not np.all(np.isfinite(Rf)):
        return _householder(A, n)
    return Rf[:n, :n].copy(), Rf[:n, n].copy(), float(Rf[n, n] ** 2)


def reduce_chunk(Yb: FloatArray, tau: FloatArray, keep: BoolArray) -> ReducedObservations:
    """Reduce the kept rows of one chunk, per joint.

    ``Yb`` (n, nv, p), ``tau`` (n, nv), ``keep`` (n, nv): row ``(k, j)`` enters group ``j``
    when ``keep[k, j]``.
    """
    nv, p = Yb.shape[1], Yb.shape[2]
    R = np.zeros((nv, p, p))
    z = np.zeros((nv, p))
    rho = np.zeros(nv)
    yty = np.zeros(nv)
    n_rows = np.zeros(nv, dtype=np.int64)
    for j in range(nv):
        rows = keep[:, j]
        Wj = Yb[rows, j, :]
        # joint j carries no term of the bodies before it: reduce only the columns it has
        # (the reduction of [0 W'] is [0 R']), a third of the work on average
        cols = np.flatnonzero(np.any(Wj != 0.0, axis=0))
        A = np.column_stack([Wj[:, cols], tau[rows, j]])
        k = cols.size
        Rj, z[j, :k], rho[j] = _cholesky_qr2(A, k)
        R[j][np.ix_(np.arange(k), cols)] = Rj
        yty[j] = float(A[:, k] @ A[:, k])
        n_rows[j] = int(rows.sum())
    return ReducedObservations(R=R, z=z, rho=rho, yty=yty, n_rows=n_rows)


def _subset(red: ReducedObservations, columns: list[int]) -> ReducedObservations:
    """The reduction of the same rows restricted to ``columns``: ``W_S = Q R[:, S]``."""
    from ident.identify.observations import _reduce

    k = len(columns)
    R = np.zeros((red.n_groups, k, k))
    z = np.zeros((red.n_groups, k))
    rho = np.zeros(red.n_groups)
    for j in range(red.n_groups):
        R[j], z[j], extra = _reduce(red.R[j][:, columns], red.z[j], k)
        rho[j] = red.rho[j] + extra
    return ReducedObservations(R=R, z=z, rho=rho, yty=red.yty.copy(), n_rows=red.n_rows.copy())


def estimate_reduced(
    red: ReducedObservations,
    names: tuple[str, ...] | list[str],
    *,
    method: str = "ols",
    wls_passes: int = 2,
) -> Estimate:
    """OLS/WLS from a reduction: :func:`ident.identify.estimate.least_squares_reduced` (the
    formulas of :func:`ident.identify.estimate.least_squares`, rows grouped by joint).

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
) -> object:
    """:func:`ident.identify.essential.essential_parameters` on a reduction (same rule:
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


@dataclass(frozen=True, eq=False)
class ChunkedFit:
    """What the chunked identification returns to :func:`ident.identify.real.identify`.

    Arrays of the held-out part are concatenated over segments (decimated samples).
    """

    estimate: Estimate
    essential: object | None
    reduction: ReducedObservations
    t_validate: FloatArray
    tau_validate: FloatArray
    keep_validate: BoolArray
    predictions: dict[str, FloatArray]
    in_sample: bool
    sampling_rate_hz: float
    records: tuple[dict, ...]
    consistent: object | None = None  # ConsistentIdentification of the reduced rows


@dataclass(frozen=True, eq=False)
class _Task:
    """One chunk of one segment, self-contained (shipped to a Dask worker as is)."""

    plan: ChunkPlan
    q: FloatArray  # the segment's raw samples (a view locally)
    tau: FloatArray
    fs: float
    pp: PreprocessConfig
    chain: KinematicChain
    pm: object  # ParameterModel (gives the base columns)
    d0: int
    d1: int

    def chunk(self) -> Chunk:
        (out,) = iter_chunks(
            self.plan,
            self.q,
            self.tau,
            self.fs,
            self.pp,
            BaseColumns(self.chain, self.pm),
            [(self.d0, self.d1)],
        )
        return out


class BaseColumns:
    """The base regressor columns straight from the kernels, in *kernel order*: the rigid-body
    columns computed alone (``selected_rows``, no full regressor and no gather of it), then
    the extra columns. ``order[i]`` is the base parameter of kernel column ``i``."""

    def __init__(self, chain: KinematicChain, pm: object) -> None:
        independent = np.asarray(pm.base.independent)  # type: ignore[attr-defined]
        rigid = pm.inertial_index[independent] >= 0  # type: ignore[attr-defined]
        self.chain = chain
        self.terms = pm.terms  # type: ignore[attr-defined]
        self.rigid_columns = pm.inertial_index[independent[rigid]]  # type: ignore[attr-defined]
        self.extra_columns = pm.extra_index[independent[~rigid]]  # type: ignore[attr-defined]
        self.order = np.concatenate([np.flatnonzero(rigid), np.flatnonzero(~rigid)])

    def __call__(self, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
        from ident.dynamics.gram import selected_rows

        n, nv = dq.shape
        out = np.empty((n, nv, self.order.size))
        a = self.rigid_columns.size
        if a:
            # straight into the block of ``out`` (a strided view of it): no copy
            view = out[:, :, :a].reshape(n * nv, a)
            selected_rows(self.chain, q, dq, ddq, columns=self.rigid_columns, out=view)
        if self.extra_columns.size:
            out[:, :, a:] = extra_columns(self.terms, dq, ddq)[:, :, self.extra_columns]
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


def _reduce_task(task: _Task) -> ReducedObservations:
    c = task.chunk()
    keep, _ = preprocess.velocity_mask(c.dq, task.pp.velocity_threshold)
    return BaseColumns(task.chain, task.pm).to_base(reduce_chunk(c.Yb, c.tau, keep))


def _predict_task(
    task: _Task, vectors: dict[str, FloatArray]
) -> tuple[FloatArray, BoolArray, dict[str, FloatArray]]:
    c = task.chunk()
    keep, _ = preprocess.velocity_mask(c.dq, task.pp.velocity_threshold)
    order = BaseColumns(task.chain, task.pm).order
    return c.tau, keep, {label: c.Yb @ x[order] for label, x in vectors.items()}


def local_workers() -> int:
    """Threads for the chunks of a local run: one per core this process may use, at most 4.

    The heavy parts of a chunk (the regressor and filter kernels, compiled with ``nogil``;
    BLAS; large numpy operations) release the GIL, so threads share the work without copying
    the log.
    """
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, min(4, cores))


def _run(fn: Callable, tasks: list, scheduler: str | None, *extra: object) -> list:
    """``[fn(task, *extra) for task in tasks]``, locally (:func:`local_workers` threads, the
    results in task order, so the merges and the estimate do not depend on the thread count)
    or on a Dask scheduler."""
    if scheduler is None:
        workers = min(local_workers(), len(tasks))
        if workers <= 1:
            return [fn(task, *extra) for task in tasks]
        from concurrent.futures import ThreadPoolExecutor

        from threadpoolctl import threadpool_limits

        with threadpool_limits(limits=1, user_api="blas"), ThreadPoolExecutor(workers) as pool:
            return list(pool.map(lambda task: fn(task, *extra), tasks))
    from ident.errors import IdentError

    try:
        from distributed import Client
    except ImportError as e:
        raise IdentError(
            "--scheduler needs dask.distributed; install it with `pip install 'ident[dask]'`."
        ) from e
    try:
        client = Client(scheduler, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as e:
        raise IdentError(
            f"cannot reach the dask scheduler at {scheduler}: {e}; start one with "
            "`dask scheduler` and `dask worker <address>`, or drop --scheduler."
        ) from e
    try:
        futures = client.map(fn, tasks, *[[x] * len(tasks) for x in extra], pure=False)
        return client.gather(futures)
    finally:
        client.close()


def default_chunk_samples(plan_margins: tuple[int, int], nv: int, n_columns: int) -> int:
    """Raw samples per chunk: at least the margins (so margins cost at most 2/3 of the work),
    and about 128 MB of base regressor in all the chunks processed at once
    (:func:`local_workers`)."""
    budget = (128 << 20) // local_workers()
    by_memory = max(1024, budget // (8 * nv * max(n_columns, 1)))
    return max(by_memory, sum(plan_margins))


def fit_chunked(
    t: FloatArray,
    q: FloatArray,
    tau: FloatArray,
    segments: tuple[tuple[int, int], ...],
    sampling_rate_hz: float,
    pp: PreprocessConfig,
    chain: KinematicChain,
    pm: object,
    *,
    method: str,
    identify_fraction: float,
    essential: dict | None = None,
    chunk_samples: int | None = None,
    scheduler: str | None = None,
    consistent: Callable[[ReducedObservations, ReducedObservations], object] | None = None,
    validation_fraction: float = 0.2,
) -> ChunkedFit:
    """Identify from raw joint-side signals in chunks (module docstring).

    Parameters
    ----------
    t, q, tau :
        Time [s], positions, torques of the log (segments concatenated), shapes (n,),
        (n, nv), (n, nv).
    segments :
        ``(start, stop)`` ranges processed independently (gaps, windows, several logs); each
        is split in time, its first ``identify_fraction`` identifies.
    pm :
        The :class:`~ident.identify.real.ParameterModel`.
    essential :
        Keyword arguments of :func:`essential_reduced` (``max_relative_std_pct``,
        ``max_residual_increase``), or None to skip.
    chunk_samples :
        Raw samples per chunk (default :func:`default_chunk_samples`).
    scheduler :
        Dask scheduler address to run the chunks on, or None (this process).
    consistent :
        Called with the identification rows reduced in two parts (each segment's first
        ``1 - validation_fraction`` of its identification samples, and the rest), returns a
        :class:`~ident.identify.estimators.ConsistentIdentification`; a constrained estimate
        in it is predicted on the held-out part like the least-squares one.
    """
    from ident.identify.validation import time_split

    fs = sampling_rate_hz
    nv = q.shape[1]
    names = pm.base_names  # type: ignore[attr-defined]
    margins = margin_samples(pp, fs)
    size = chunk_samples or default_chunk_samples(margins, nv, len(names))
    fit_tasks: list[_Task] = []
    n_first: list[bool] = []  # per fit task: in the first part (else the last, see consistent)
    val_tasks: list[_Task] = []
    val_time: list[FloatArray] = []
    records: list[dict] = []
    skipped = []
    for a, b in segments:
        try:
            plan = make_plan(b - a, pp, fs, size)
        except DataError as e:
            skipped.append(f"{(b - a) / fs:.3g} s ({e})")
            continue
        ident_part, val_part = time_split(plan.n_decimated, identify_fraction)
        args = (plan, q[a:b], tau[a:b], fs, pp, chain, pm)
        split = int(round((1.0 - validation_fraction) * ident_part.stop))
        for lo, hi in ((0, split), (split, ident_part.stop)):
            ranges = list(plan.ranges(lo, hi)) if hi > lo else []
            fit_tasks += [_Task(*args, d0, d1) for d0, d1 in ranges]
            n_first += [lo == 0] * len(ranges)
        part = val_part if val_part.stop > val_part.start else ident_part
        val_tasks += [_Task(*args, d0, d1) for d0, d1 in plan.ranges(part.start, part.stop)]
        val_time.append(t[a + plan.n_edge + plan.step * np.arange(part.start, part.stop)])
    if not fit_tasks:
        raise DataError("no log segment is long enough to identify from: " + "; ".join(skipped))
    in_sample = identify_fraction >= 1.0
    reductions = _run(_reduce_task, fit_tasks, scheduler)
    halves: list[ReducedObservations | None] = []  # first and last part of the rows
    for first in (True, False):
        mine = [r for r, f in zip(reductions, n_first, strict=True) if f == first]
        half = mine[0] if mine else None
        for r in mine[1:]:
            half = half.merge(r)
        halves.append(half)
    head, tail = halves
    red = tail if head is None else head if tail is None else head.merge(tail)
    if red.n_rows.sum() <= red.n_params:
        raise DataError(
            f"too few observations: {int(red.n_rows.sum())} rows for {red.n_params} parameters."
        )
    try:
        est = estimate_reduced(red, names, method=method)
    except NotIdentifiable as e:
        idle = [j for j in range(nv) if red.n_rows[j] == 0]
        if idle:
            raise NotIdentifiable(
                f"no sample of joint(s) {', '.join(str(j + 1) for j in idle)} reaches its "
                f"velocity threshold (joint not moving?): {e}"
            ) from e
        raise
    ess = None
    vectors = {"identified": est.x}
    if essential is not None:
        ess = essential_reduced(red, tuple(names), method=method, **essential)
        x_ess = np.zeros(len(names))
        x_ess[list(ess.kept)] = ess.estimate.x  # type: ignore[attr-defined]
        vectors["essential"] = x_ess
    vectors["URDF nominal"] = pm.base.project(pm.nominal)  # type: ignore[attr-defined]
    cons = None
    if consistent is not None and head is not None and tail is not None:
        cons = consistent(head, tail)
        if cons.constrained is not None:  # type: ignore[attr-defined]
            vectors[cons.method] = cons.constrained.x  # type: ignore[attr-defined]
    parts = _run(_predict_task, val_tasks, scheduler, vectors)
    tau_val = np.concatenate([p[0] for p in parts])
    keep_val = np.concatenate([p[1] for p in parts])
    predictions = {k: np.concatenate([p[2][k] for p in parts]) for k in vectors}
    n_chunks = len(fit_tasks) + len(val_tasks)
    records.append(
        {
            "step": "chunked accumulation",
            "detail": f"{len(segments) - len(skipped)} segment(s) in {n_chunks} chunks of "
            f"{size} raw samples (+ margins {margins[0]} raw / {margins[1]} trimmed samples "
            "for the filters); identification rows reduced per joint (QR) chunk by chunk: "
            f"{int(red.n_rows.sum())} rows, no per-sample regressor kept"
            + (f"; skipped too-short segment(s): {'; '.join(skipped)}" if skipped else ""),
        }
    )
    step = int(np.prod(pp.decimation)) if pp.decimation else 1
    return ChunkedFit(
        estimate=est,
        essential=ess,
        reduction=red,
        t_validate=np.concatenate(val_time),
        tau_validate=tau_val,
        keep_validate=keep_val,
        predictions=predictions,
        in_sample=in_sample,
        sampling_rate_hz=fs / step,
        records=tuple(records),
        consistent=cons,
    )


def use_chunks(log: object, pp: PreprocessConfig, n_columns: int) -> bool:
    """Whether :func:`ident.identify.real.identify` takes the chunked path: when asked
    (``preprocess.chunked``), or in ``auto`` for several segments or a regressor above
    ``preprocess.max_regressor_mb``."""
    if pp.chunked != "auto":
        return pp.chunked == "always"
    n, nv = log.q.shape  # type: ignore[attr-defined]
    too_big = regressor_bytes(n, nv, n_columns) > pp.max_regressor_mb * 2**20
    return len(log.segments) > 1 or too_big  # type: ignore[attr-defined]


def identify_chunked(
    cfg: object,
    log: object,
    model: object,
    joints: list[str],
    *,
    source: str,
    rng: int,
    timings: dict[str, float],
    t0: float,
    scheduler: str | None = None,
    ellipsoids: tuple = (),
) -> dict:
    """The fields of an :class:`~ident.identify.real.IdentifyResult` by the chunked path.

    Same steps and records as the in-memory path (read, low-pass, differentiate, trim,
    regressor, decimate, velocity threshold, split, estimate, essential, held-out prediction),
    with the chunked accumulation in the middle, and the constrained estimate
    (``estimation.method``, ``ellipsoids``: the links' bounding ellipsoids or ``()``) on the
    reduction. The reference parameters' held-out prediction is not computed here (the
    comparison table is).
    """
    import time

    from ident.dynamics.chain import chain_from_model
    from ident.dynamics.friction import ExtraTerms
    from ident.dynamics.parameter_model import build_parameter_model
    from ident.errors import ConfigError
    from ident.identify import sanity
    from ident.identify.estimators import consistent_identification_reduced
    from ident.identify.motion import measured_motion
    from ident.identify.reference import compare_with_reference, read_reference
    from ident.identify.validation import ModelPrediction, held_out_warnings, prediction_metrics

    pp = cfg.preprocess  # type: ignore[attr-defined]
    fs = log.sampling_rate_hz  # type: ignore[attr-defined]
    records = list(log.records)  # type: ignore[attr-defined]
    t1 = time.perf_counter()
    try:
        terms = ExtraTerms.from_options(
            model.nv,  # type: ignore[attr-defined]
            rotor_inertia=cfg.model.rotor_inertia,  # type: ignore[attr-defined]
            viscous=cfg.model.viscous,  # type: ignore[attr-defined]
            coulomb=cfg.model.coulomb,  # type: ignore[attr-defined]
            offset=cfg.model.offset,  # type: ignore[attr-defined]
            coupled_wrist=cfg.model.coupled_wrist,  # type: ignore[attr-defined]
        )
    except ConfigError as e:
        raise ConfigError(f"{source}: {e}") from e
    pm = build_parameter_model(model, terms, rng=rng)  # type: ignore[arg-type]
    timings["base_parameters"] = time.perf_counter() - t1
    for flt, what in ((pp.lowpass, "q"), (pp.torque_lowpass, "tau")):
        if flt is not None:
            if not 0.0 < flt.cutoff_hz < 0.5 * fs:
                raise ConfigError(
                    f"{source}: preprocess.{'lowpass' if what == 'q' else 'torque_lowpass'}"
                    f".cutoff_hz = {flt.cutoff_hz:g} Hz is not below the Nyquist frequency "
                    f"{0.5 * fs:g} Hz; choose a lower cutoff."
                )
            records.append(
                {
                    "step": f"low-pass {what}",
                    "detail": f"zero-phase Butterworth, order {flt.order}, cutoff "
                    f"{flt.cutoff_hz:g} Hz at {fs:g} Hz (per chunk, margins included)",
                }
            )
    records.append({"step": "differentiate", "detail": "central differences (np.gradient)"})
    records.append(
        {"step": "trim", "detail": f"dropped {pp.trim_samples} samples at each end of a segment"}
    )
    t2 = time.perf_counter()
    ess_cfg = cfg.estimation.essential  # type: ignore[attr-defined]
    fit = fit_chunked(
        log.t,  # type: ignore[attr-defined]
        log.q,  # type: ignore[attr-defined]
        log.tau,  # type: ignore[attr-defined]
        log.segments,  # type: ignore[attr-defined]
        fs,
        pp,
        chain_from_model(model),  # type: ignore[arg-type]
        pm,
        method=cfg.estimation.least_squares_method,  # type: ignore[attr-defined]
        consistent=lambda first, last: consistent_identification_reduced(
            model,  # type: ignore[arg-type]
            pm,
            first,
            last,
            method=cfg.estimation.method,  # type: ignore[attr-defined]
            weight=cfg.estimation.regularization.weight,  # type: ignore[attr-defined]
            ellipsoids=ellipsoids,
            options={"friction": cfg.estimation.friction},  # type: ignore[attr-defined]
        ),
        identify_fraction=cfg.validation.identify_fraction,  # type: ignore[attr-defined]
        essential={
            "max_relative_std_pct": ess_cfg.max_relative_std_pct,
            "max_residual_increase": ess_cfg.max_residual_increase,
        }
        if ess_cfg.enabled
        else None,
        chunk_samples=pp.chunk_samples,
        scheduler=scheduler,
    )
    timings["estimate"] = time.perf_counter() - t2
    records += list(fit.records)
    if pp.decimation:
        records.append(
            {
                "step": "decimate",
                "detail": f"zero-phase decimation by {' x '.join(map(str, pp.decimation))} "
                "(Chebyshev I order 8, forward-backward) of torques and regressor rows alike, "
                f"{fs:g} -> {fit.sampling_rate_hz:g} Hz",
            }
        )
    predictions = {}
    for label, tau_pred in fit.predictions.items():
        predictions[label] = ModelPrediction(
            label,
            prediction_metrics(fit.tau_validate, tau_pred, fit.keep_validate),
            prediction_metrics(fit.tau_validate, tau_pred),
            tau_pred,
        )
    comparison: list[dict] = []
    note = ""
    reference_essential: list[dict] = []
    ref_cfg = cfg.reference  # type: ignore[attr-defined]
    if ref_cfg.base_parameters is not None:
        comparison, note = compare_with_reference(
            pm, fit.estimate, read_reference(ref_cfg.base_parameters), ref_cfg.column
        )
        note += " (Chunked path: the reference's held-out prediction is not computed.)"
    if ref_cfg.essential_parameters is not None:
        rows, _ = compare_with_reference(
            pm, fit.estimate, read_reference(ref_cfg.essential_parameters), ref_cfg.column
        )
        kept = set(fit.essential.estimate.names) if fit.essential is not None else set()  # type: ignore[attr-defined]
        for row in rows:
            members = row["ours"].split(" + ") if row["ours"] else []
            row["in_our_essential_set"] = bool(members) and all(m in kept for m in members)
            reference_essential.append(row)
    # the replay's measured motion: the first segment (at most its first MOTION_MAX_S),
    # processed in memory (a few (n, nv) arrays)
    motion, motion_note = None, ""
    a, b = log.segments[0]  # type: ignore[attr-defined]
    b = min(b, a + int(MOTION_MAX_S * fs))
    try:
        from ident.identify import preprocess as pre

        q = log.q[a:b]  # type: ignore[attr-defined]
        if pp.lowpass is not None:
            q, _ = pre.lowpass(q, fs, pp.lowpass.cutoff_hz, pp.lowpass.order)
        dq, ddq, _ = pre.differentiate(q, fs)
        motion, _ = measured_motion(
            log.t[a:b],  # type: ignore[attr-defined]
            q,
            dq,
            ddq,
            log.tau[a:b],  # type: ignore[attr-defined]
            fs,
            tuple(joints),
        )
    except (DataError, ConfigError) as e:
        motion_note = f"measured motion not available: {e}"
    problems = held_out_warnings(
        predictions["identified"].metrics.total_relative_residual,
        predictions["URDF nominal"].metrics.total_relative_residual,
        max_relative_residual=cfg.validation.max_relative_residual,  # type: ignore[attr-defined]
        in_sample=fit.in_sample,
        n_rows=int(fit.reduction.n_rows.sum()),
        n_params=len(pm.base_names),
    )
    red = fit.reduction
    problems += sanity.result_warnings(
        joint_names=tuple(joints),
        units=sanity.joint_units(model),  # type: ignore[arg-type]
        names=pm.base_names,
        x=fit.estimate.x,
        std=fit.estimate.std,
        relative_std=fit.estimate.relative_std,
        projection=pm.base.projection,
        all_names=pm.names,
        column_norms=np.sqrt(np.einsum("gij,gij->j", red.R, red.R)),
        tau_norm=float(np.sqrt(red.yty.sum())),
        tau_validate=fit.tau_validate,
        tau_pred=fit.predictions["identified"],
        keep_validate=fit.keep_validate,
    )
    cons = fit.consistent
    if cons is not None and cons.constrained is None:  # type: ignore[attr-defined]
        problems += sanity.inconsistency_warnings(cons, cfg.estimation.least_squares_method)  # type: ignore[attr-defined]
    timings["total"] = time.perf_counter() - t0
    return {
        "config": cfg,
        "log": log,
        "records": tuple(records),
        "parameters": pm,
        "estimate": fit.estimate,
        "essential": fit.essential,
        "t_validate": fit.t_validate,
        "tau_validate": fit.tau_validate,
        "keep_validate": fit.keep_validate,
        "predictions": predictions,
        "comparison": tuple(comparison),
        "reference_note": note,
        "joint_names": tuple(joints),
        "sampling_rate_hz": fit.sampling_rate_hz,
        "n_identify_rows": int(fit.reduction.n_rows.sum()),
        "timings": timings,
        "reference_essential": tuple(reference_essential),
        "motion": motion,
        "motion_note": motion_note,
        "warnings": tuple(problems),
        "consistent": cons,
    }
