"""A log cut in chunk tasks, run on local threads or a Dask cluster, their reductions merged.

The driver of :mod:`ident.identify.estimation.accumulate` (which processes and reduces one
chunk): :func:`plan_log` cuts every segment of a log in chunk tasks (identification and
held-out parts), :func:`reduce_log` reduces the identification rows, :func:`predict_log`,
:func:`block_equations` and :func:`prediction_std_log` make further passes over the chunks for
the held-out prediction and the intervals. Tasks run in order on :func:`local_workers` threads
or, with ``scheduler=``, on a Dask cluster; the merges and the estimate do not depend on either.

Memory is set by the chunk size (:func:`chunk_bytes`, :func:`default_chunk_samples`), time is
linear in the log length.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import sys
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.blas import one_blas_thread
from ident.errors import DataError, IdentError
from ident.identify.config import PreprocessConfig
from ident.identify.estimation import preprocess
from ident.identify.estimation.accumulate import (
    GRAM_MAX_COND,
    ROW_BLOCK,
    BaseColumns,
    Chunk,
    ChunkPlan,
    iter_chunks,
    make_plan,
    margin_samples,
    reduce_chunk,
    regressor_bytes,
)
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimation.uncertainty import BlockEquations, prediction_std
from ident.identify.estimation.validation import time_split
from ident.measure.logs import RobotLog

__all__ = [
    "CHUNK_BUDGET_BYTES",
    "DASK_CONNECT_TIMEOUT",
    "connect_scheduler",
    "MAX_BLOCKS",
    "ChunkTask",
    "ChunkedLog",
    "block_equations",
    "chunk_bytes",
    "chunk_record",
    "default_chunk_samples",
    "local_workers",
    "map_large_blocks",
    "merged_rows",
    "plan_log",
    "predict_log",
    "prediction_std_log",
    "reduce_log",
    "release_free_memory",
    "segment_chunk_samples",
    "use_chunks",
]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


#: How long to wait for a --scheduler before giving up (here and in ``ident bench``).
DASK_CONNECT_TIMEOUT = "10s"


@dataclass(frozen=True, eq=False)
class _Task:
    """One chunk of one segment, self-contained (shipped to a Dask worker as is)."""

    plan: ChunkPlan
    q: FloatArray  # the segment's raw samples (a view locally)
    tau: FloatArray
    fs: float
    pp: PreprocessConfig
    columns: BaseColumns
    d0: int
    d1: int
    states: tuple[FloatArray, FloatArray] | None = None  # measured (dq, ddq) of the segment

    def chunk(self) -> tuple[Chunk, BoolArray]:
        """The chunk and its row mask (n, nv): above the velocity threshold, on the rows the
        model explains."""
        ranges = [(self.d0, self.d1)]
        (out,) = iter_chunks(
            self.plan, self.q, self.tau, self.fs, self.pp, self.columns, ranges, self.states
        )
        keep, _ = preprocess.velocity_mask(out.dq, self.pp.velocity_threshold)
        return out, keep & self.columns.rows[None, :]


#: A chunk task (public name, for code that processes a planned log's chunks itself).
ChunkTask = _Task


def _reduce_task(task: _Task) -> ReducedObservations:
    """The chunk's identification rows reduced, one group per joint the model explains."""
    c, keep = task.chunk()
    p = task.columns.order.size
    rows = task.columns.rows
    if rows.all():  # no copy of the chunk's rows
        return task.columns.to_base(reduce_chunk(c.Yb[:, :, :p], c.tau, keep))
    return task.columns.to_base(reduce_chunk(c.Yb[:, rows, :p], c.tau[:, rows], keep[:, rows]))


def _predict_task(
    task: _Task, vectors: dict[str, FloatArray]
) -> tuple[FloatArray, BoolArray, dict[str, FloatArray]]:
    c, keep = task.chunk()
    order = task.columns.order
    p = order.size
    out = {label: c.Yb[:, :, :p] @ x[order] for label, x in vectors.items()}
    if task.columns.reference is not None:
        out["reference"] = c.Yb[:, :, p]
    return c.tau, keep, out


def release_free_memory() -> None:
    """Give the C heap's free pages back to the system (glibc's ``malloc_trim``; nothing
    elsewhere). Called after each pass over the chunks."""
    if _LIBC:
        _LIBC[0].malloc_trim(0)


def _bound_arenas(workers: int) -> None:
    """At most ``workers`` glibc malloc arenas in this process (``mallopt(M_ARENA_MAX)``).

    Each worker thread would otherwise get an arena of its own, which keeps the chunk buffers
    it freed (tens of MB each, below glibc's mmap threshold) even after ``malloc_trim``:
    measured on an hour at 1 kHz, every pass over the chunks left 60-100 MB more resident
    (690 -> 930 MB over four passes; 690 -> 840 MB with the arenas bounded), at the same speed.
    """
    if _LIBC:
        _LIBC[0].mallopt(_M_ARENA_MAX, max(2, workers))


_M_ARENA_MAX = -8  # glibc's malloc.h
_M_MMAP_THRESHOLD = -3

#: Blocks of at least this many bytes are mapped for themselves, and handed back to the system
#: when freed (:func:`map_large_blocks`).
MMAP_THRESHOLD_BYTES = 16 << 20


def map_large_blocks() -> None:
    """Allocate blocks of :data:`MMAP_THRESHOLD_BYTES` and more outside the C heap, each
    mapped for itself and unmapped when freed (glibc's ``M_MMAP_THRESHOLD``, fixed; nothing
    elsewhere).

    glibc raises its threshold to the size of every mapped block freed, up to 32 MB: once an
    array of a long log's length (29 MB for an hour at 1 kHz: its time, a step or spectrum
    temporary) was freed, the next ones came from the heap and stayed resident through the
    identification, beside the chunks (measured on the hour's long CSV: ~80 MB at the report).
    From 16 MB up: no chunk array is that large (a chunk's regressor rows are ~10 MB), so the
    passes over the chunks map nothing more (a threshold of 8 MB mapped and unmapped a block
    every few rows: +20 % of CPU).
    """
    if _LIBC:
        _LIBC[0].mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)


def _load_libc() -> list:
    """glibc, when this process runs on it (a list: empty elsewhere)."""
    if not sys.platform.startswith("linux"):
        return []
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
    except OSError:
        return []
    return [libc] if hasattr(libc, "malloc_trim") and hasattr(libc, "mallopt") else []


_LIBC = _load_libc()


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
    """``[fn(task, *extra) for task in tasks]`` (:func:`_results`)."""
    return list(_results(fn, tasks, scheduler, *extra))


def _results(fn: Callable, tasks: list, scheduler: str | None, *extra: object) -> Iterator:
    """``fn(task, *extra)`` for each task, yielded in task order (so the merges and the
    estimate do not depend on the thread count): locally on :func:`local_workers` threads, or
    on a Dask scheduler."""
    if scheduler is None:
        workers = min(local_workers(), len(tasks))
        if workers <= 1:
            yield from (fn(task, *extra) for task in tasks)
            return
        _bound_arenas(workers)
        try:
            with one_blas_thread(), ThreadPoolExecutor(workers) as pool:
                yield from pool.map(lambda task: fn(task, *extra), tasks)
        finally:
            release_free_memory()
        return
    client = connect_scheduler(scheduler, "--scheduler", "drop --scheduler")
    try:
        futures = client.map(fn, tasks, *[[x] * len(tasks) for x in extra], pure=False)
        yield from client.gather(futures)
    finally:
        client.close()


def connect_scheduler(address: str, asked_by: str, instead: str) -> Any:
    """A ``distributed.Client`` of the Dask scheduler at ``address`` (the one connection of
    ``ident identify``, ``ident bench`` and ``ident fleet`` to a cluster).

    Raises
    ------
    IdentError
        dask.distributed missing (naming ``asked_by``, the option or setting that asked for
        it), or the scheduler unreachable within :data:`DASK_CONNECT_TIMEOUT` (naming how to
        start one, or ``instead``, how to do without it).
    """
    try:
        from distributed import Client
    except ImportError as e:
        raise IdentError(
            f"{asked_by} needs dask.distributed; install it with `pip install 'ident[dask]'`."
        ) from e
    try:
        return Client(address, timeout=DASK_CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as e:
        raise IdentError(
            f"cannot reach the dask scheduler at {address}: {e}; start one with "
            f"`dask scheduler` and `dask worker <address>`, or {instead}."
        ) from e


#: Memory a local worker gives to the samples of its chunk (:func:`default_chunk_samples`);
#: the blocks of :func:`chunk_bytes` come on top.
CHUNK_BUDGET_BYTES = 48 << 20


def chunk_bytes(extent: int, nv: int, n_columns: int, step: int) -> float:
    """Bytes a worker holds for a chunk of ``extent`` raw samples (with its margins).

    Per raw sample: ~4 arrays of the positions' size (filtered positions, ``dq``, ``ddq``, the
    differentiation's scratch) and, decimated by ``step``, the regressor's ``n_columns`` with
    the torques and velocities, twice (the chunk's and its consumer's copy). Whatever the
    extent: ~4 :data:`ROW_BLOCK` rows of every column (the regressor's row blocks and the
    decimation filters' buffers, :class:`~ident.identify.estimation.preprocess.DecimationStream`).
    Measured on an hour at 1 kHz of a 7-joint arm (57 base columns, step 20, chunks of 100 000
    samples, 131 000 with their margins): ~85 MiB a worker, this formula 82 MiB.
    """
    row = 8.0 * nv * (n_columns + 2)
    return extent * (8.0 * 4 * nv + 2 * row / step) + 4 * ROW_BLOCK * row


def default_chunk_samples(
    plan_margins: tuple[int, int], nv: int, n_columns: int, step: int = 1
) -> int:
    """Raw samples per chunk: a chunk with its margins holds about :data:`CHUNK_BUDGET_BYTES`
    of samples (:func:`chunk_bytes`), at least 1024 and at least the margins (so margins cost
    at most 2/3 of the work)."""
    per_sample = chunk_bytes(1, nv, n_columns, step) - chunk_bytes(0, nv, n_columns, step)
    extent = int(CHUNK_BUDGET_BYTES // per_sample)
    margins = sum(plan_margins)
    return max(1024, margins, extent - 2 * margins)


def use_chunks(log: RobotLog, pp: PreprocessConfig, n_columns: int) -> bool:
    """Whether a log is cut in chunks of ``preprocess.chunk_samples``: when asked
    (``preprocess.chunked``), or in ``auto`` for several segments or a regressor above
    ``preprocess.max_regressor_mb``. Otherwise each segment is one chunk (same code path)."""
    if pp.chunked != "auto":
        return pp.chunked == "always"
    n, nv = log.q.shape
    too_big = regressor_bytes(n, nv, n_columns) > pp.max_regressor_mb * 2**20
    return len(log.segments) > 1 or too_big


def segment_chunk_samples(log: RobotLog, pp: PreprocessConfig, n_base: int) -> int:
    """Raw samples per chunk: ``preprocess.chunk_samples`` (or an automatic size) when the
    log is chunked (:func:`use_chunks`), else the longest segment (each segment is one
    chunk)."""
    nv = log.q.shape[1]
    if not use_chunks(log, pp, 14 * nv):
        return max(b - a for a, b in log.segments)
    margins = margin_samples(pp, log.sampling_rate_hz)
    step = preprocess.decimation_step(pp)
    return pp.chunk_samples or default_chunk_samples(margins, nv, n_base, step)


def merged_rows(
    first: ReducedObservations | None, last: ReducedObservations | None
) -> ReducedObservations:
    """The two parts of :func:`reduce_log` merged; :class:`DataError` when they hold no more
    rows than parameters."""
    red = last if first is None else first if last is None else first.merge(last)
    assert red is not None  # plan_log raises without identification rows
    red.check_enough_rows()
    return red


@dataclass(frozen=True, eq=False)
class ChunkedLog:
    """A log cut in chunk tasks: the identification rows (in two parts, for the choice of a
    prior weight) and the held-out rows.

    Attributes
    ----------
    fit_tasks, first :
        Chunks of the identification parts, and per chunk whether it is in the first
        ``1 - validation_fraction`` of its segment's identification samples.
    val_tasks, t_validate :
        Chunks of the held-out parts (the identification part when a segment has none) and
        their decimated sample times [s], shape (n_validate,).
    chunk_samples, margins :
        Raw samples per chunk and :func:`margin_samples`.
    skipped :
        Segments too short to identify from, with the reason.
    in_sample :
        True when ``identify_fraction == 1`` (no held-out part).
    """

    fit_tasks: tuple[_Task, ...]
    first: tuple[bool, ...]
    val_tasks: tuple[_Task, ...]
    t_validate: FloatArray
    chunk_samples: int
    margins: tuple[int, int]
    skipped: tuple[str, ...]
    in_sample: bool


def plan_log(
    log: RobotLog,
    pp: PreprocessConfig,
    columns: BaseColumns,
    *,
    identify_fraction: float,
    chunk_samples: int,
    validation_fraction: float = 0.2,
) -> ChunkedLog:
    """Cut every segment of ``log`` in chunks of ``chunk_samples`` raw samples (a chunk never
    crosses the identification / validation boundary of its segment).

    Raises
    ------
    DataError
        If no segment is long enough to identify from.
    """
    fs = log.sampling_rate_hz
    fit: list[_Task] = []
    first: list[bool] = []
    val: list[_Task] = []
    val_time: list[FloatArray] = []
    skipped = []
    for a, b in log.segments:
        try:
            plan = make_plan(b - a, pp, fs, chunk_samples)
        except DataError as e:
            skipped.append(f"{(b - a) / fs:.3g} s ({e})")
            continue
        ident_part, val_part = time_split(plan.n_decimated, identify_fraction)
        args = (plan, log.q[a:b], log.tau[a:b], fs, pp, columns)
        states = None
        if log.dq is not None and log.ddq is not None:  # measured states: used as they are
            states = (log.dq[a:b], log.ddq[a:b])
        split = int(round((1.0 - validation_fraction) * ident_part.stop))
        for lo, hi in ((0, split), (split, ident_part.stop)):
            ranges = list(plan.ranges(lo, hi)) if hi > lo else []
            fit += [_Task(*args, d0, d1, states) for d0, d1 in ranges]
            first += [lo == 0] * len(ranges)
        part = val_part if val_part.stop > val_part.start else ident_part
        val += [_Task(*args, d0, d1, states) for d0, d1 in plan.ranges(part.start, part.stop)]
        val_time.append(log.t[a + plan.n_edge + plan.step * np.arange(part.start, part.stop)])
    if not fit:
        raise DataError("no log segment is long enough to identify from: " + "; ".join(skipped))
    return ChunkedLog(
        fit_tasks=tuple(fit),
        first=tuple(first),
        val_tasks=tuple(val),
        t_validate=np.concatenate(val_time),
        chunk_samples=chunk_samples,
        margins=margin_samples(pp, fs),
        skipped=tuple(skipped),
        in_sample=identify_fraction >= 1.0,
    )


def _merge_all(reductions: list[ReducedObservations]) -> ReducedObservations | None:
    """The merge of ``reductions`` in order, or None for none."""
    if not reductions:
        return None
    out = reductions[0]
    for r in reductions[1:]:
        out = out.merge(r)
    return out


def reduce_log(
    chunked: ChunkedLog, scheduler: str | None = None
) -> tuple[ReducedObservations | None, ReducedObservations | None]:
    """The identification rows reduced per joint, in two parts ``(first, last)`` (either None
    when empty); ``scheduler``: a Dask scheduler address, or None (this process)."""
    reductions = _run(_reduce_task, list(chunked.fit_tasks), scheduler)
    head = [r for r, f in zip(reductions, chunked.first, strict=True) if f]
    tail = [r for r, f in zip(reductions, chunked.first, strict=True) if not f]
    return _merge_all(head), _merge_all(tail)


def predict_log(
    chunked: ChunkedLog, vectors: dict[str, FloatArray], scheduler: str | None = None
) -> tuple[FloatArray, BoolArray, dict[str, FloatArray]]:
    """Held-out torques (n_validate, nv) [N*m], their velocity-threshold mask and the torques
    predicted by each base-parameter vector of ``vectors`` (and ``"reference"`` when the
    columns carry one)."""
    parts = _run(_predict_task, list(chunked.val_tasks), scheduler, vectors)
    tau_val = np.concatenate([p[0] for p in parts])
    keep_val = np.concatenate([p[1] for p in parts])
    labels = parts[0][2].keys()
    predictions = {k: np.concatenate([p[2][k] for p in parts]) for k in labels}
    return tau_val, keep_val, predictions


def chunk_record(chunked: ChunkedLog, red: ReducedObservations) -> dict:
    """The report's record of the accumulation."""
    skipped = chunked.skipped
    n_segments = len({id(t.q) for t in chunked.fit_tasks})
    n_chunks = len(chunked.fit_tasks) + len(chunked.val_tasks)
    m = chunked.margins
    return {
        "step": "chunked accumulation",
        "detail": f"{n_segments} segment(s) in {n_chunks} chunks of at most "
        f"{chunked.chunk_samples} raw samples (+ margins {m[0]} raw / {m[1]} trimmed samples "
        "for the filters); identification rows reduced per joint chunk by chunk (Cholesky of "
        f"the scaled Gram matrix where its condition number is at most {GRAM_MAX_COND:g}, QR "
        "elsewhere): "
        f"{int(red.n_rows.sum())} rows, no per-sample regressor kept"
        + (f"; skipped too-short segment(s): {'; '.join(skipped)}" if skipped else ""),
    }


#: Most blocks :func:`block_equations` keeps (memory: ``n_blocks * n_base^2`` floats).
MAX_BLOCKS = 2048


def _block_task(task: _Task, weights: FloatArray, block_samples: int) -> BlockEquations:
    c, keep = task.chunk()
    order = task.columns.order
    p = order.size
    rows = task.columns.rows  # the joints whose torque rows the model explains; others weigh 0
    w = np.zeros(rows.size)
    w[rows] = weights
    kernel = BlockEquations.from_samples(c.Yb[:, :, :p], c.tau, keep & rows, w, block_samples)
    A = np.empty_like(kernel.A)  # kernel order -> base order, on the blocks, not the rows
    A[:, order[:, None], order[None, :]] = kernel.A
    b = np.empty_like(kernel.c)
    b[:, order] = kernel.c
    return BlockEquations(A=A, c=b, n_rows=kernel.n_rows, block_samples=kernel.block_samples)


def block_equations(
    chunked: ChunkedLog,
    weights: FloatArray,
    scheduler: str | None = None,
    max_blocks: int = MAX_BLOCKS,
) -> BlockEquations:
    """The identification rows' weighted normal equations by consecutive blocks, in time
    order (a second pass over the chunks; :mod:`ident.identify.estimation.uncertainty`).

    ``weights``: per-joint row weights ``1 / sigma_j``, one per joint the model explains
    (``pm.rows``, all nv by default). Blocks hold
    ``ceil(n_identification_samples / max_blocks)`` decimated samples (1 on short logs) and
    never cross a chunk boundary, so at most ``max_blocks + n_chunks`` blocks are kept.
    """
    n_total = sum(t.d1 - t.d0 for t in chunked.fit_tasks)
    block_samples = max(1, -(-n_total // max_blocks))
    tasks = list(chunked.fit_tasks)
    # each chunk's blocks copied into place as it comes (never all chunks' parts and the
    # whole at once: 2 x 53 MB for 57 parameters)
    counts = [-(-(t.d1 - t.d0) // block_samples) for t in tasks]
    p = tasks[0].columns.order.size
    A, c = np.empty((sum(counts), p, p)), np.empty((sum(counts), p))
    n_rows = np.empty(sum(counts), dtype=np.int64)
    at = 0
    for part in _results(_block_task, tasks, scheduler, weights, block_samples):
        A[at : at + part.n_blocks], c[at : at + part.n_blocks] = part.A, part.c
        n_rows[at : at + part.n_blocks] = part.n_rows
        at += part.n_blocks
    return BlockEquations(A=A, c=c, n_rows=n_rows, block_samples=block_samples)


def _prediction_std_task(
    task: _Task, covariances: dict[str, FloatArray], sigma: FloatArray
) -> dict[str, FloatArray]:
    c, _ = task.chunk()
    order = task.columns.order
    p = order.size
    rows = task.columns.rows  # sigma (n_rows,) of the explained joints; the others are masked
    sigma_all = np.zeros(rows.size)
    sigma_all[rows] = sigma
    # the covariances in kernel order (y_base^T C y_base = y_kernel^T C[order][:, order]
    # y_kernel), not a base-order copy of the chunk's rows
    kernel = np.ix_(order, order)
    return {k: prediction_std(c.Yb[:, :, :p], C[kernel], sigma_all) for k, C in covariances.items()}


def prediction_std_log(
    chunked: ChunkedLog,
    covariances: dict[str, FloatArray],
    sigma: FloatArray,
    scheduler: str | None = None,
) -> dict[str, FloatArray]:
    """Standard deviation of every held-out torque about its prediction, per covariance
    label, shape (n_validate, nv) [N*m]
    (:func:`ident.identify.estimation.uncertainty.prediction_std`; same samples as
    :func:`predict_log`)."""
    parts = _run(_prediction_std_task, list(chunked.val_tasks), scheduler, covariances, sigma)
    return {k: np.concatenate([p[k] for p in parts]) for k in covariances}
