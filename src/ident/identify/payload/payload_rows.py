"""The rows of a payload problem: a log's regressor columns ``[Y_n | E | Y_b | Y theta_arm]``,
processed and reduced per joint, with their per-joint block normal equations.

Every segment goes through the one preprocessing of every identification (low-pass,
differentiate, trim, decimate, velocity threshold:
:func:`ident.identify.estimation.accumulate.iter_chunks`, in chunks of bounded size) and is
reduced per joint (:func:`ident.identify.estimation.accumulate.reduce_chunk`). While the rows are
reduced, each chunk also yields per-joint *unweighted* block normal equations
``A_bj = sum_k Y_kj^T Y_kj``, ``c_bj = sum_k Y_kj^T y_kj`` (:func:`payload_rows`); once the
estimate's weights are known they are summed with them (:func:`weighted_blocks`) for the block
bootstrap of :mod:`ident.identify.payload.payload`.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import numpy.typing as npt

from ident.dynamics.chain import KinematicChain
from ident.dynamics.friction import ExtraTerms, extra_columns
from ident.dynamics.gram import selected_rows
from ident.errors import DataError
from ident.identify.config import PreprocessConfig
from ident.identify.estimation import accumulate, log_chunks, preprocess
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimation.uncertainty import BlockEquations
from ident.measure.logs import RobotLog

__all__ = [
    "CHUNK_SAMPLES",
    "PayloadColumns",
    "block_length",
    "decimated_samples",
    "merge_blocks",
    "payload_observations",
    "payload_rows",
    "weighted_blocks",
]

FloatArray = npt.NDArray[np.float64]

#: Raw samples per chunk of a log (bounded memory: the columns of one chunk are computed at the
#: log's rate, about 8 * nv * (10 + n_extra + 1) bytes a sample).
CHUNK_SAMPLES = 50_000


class PayloadColumns:
    """Regressor columns of a payload problem: ``[Y_n | E | Y_b | Y theta_arm]``, shape
    (n, nv, p+1).

    ``Y_n`` are the last body's 10 columns (zero when ``with_payload`` is False), ``E`` the
    extra columns of ``terms``, ``Y_b`` the rigid-body columns ``arm_index`` (the arm's base
    parameters' corrections, :mod:`ident.identify.payload.payload_arm`; none by default), and
    the last column the torque the arm's known parameters predict [N*m] (subtracted from the
    measured torque after decimation).
    """

    def __init__(
        self,
        chain: KinematicChain,
        terms: ExtraTerms,
        theta_arm: FloatArray,
        *,
        with_payload: bool = True,
        arm_index: npt.ArrayLike = (),
    ) -> None:
        self.chain = chain
        self.terms = terms
        self.theta_arm = np.asarray(theta_arm, dtype=float)
        self.with_payload = with_payload
        self.arm_index = np.asarray(arm_index, dtype=np.intp)
        n_bodies = self.theta_arm.size // 10
        self.last = np.arange(10 * (n_bodies - 1), 10 * n_bodies)

    def __call__(self, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
        n, nv = dq.shape
        Y = selected_rows(self.chain, q, dq, ddq).reshape(n, nv, -1)
        payload = Y[:, :, self.last] if self.with_payload else np.zeros((n, nv, 10))
        known = Y @ self.theta_arm
        return np.concatenate(
            [payload, extra_columns(self.terms, dq, ddq), Y[:, :, self.arm_index],
             known[:, :, None]], axis=2
        )  # fmt: skip


def decimated_samples(log: RobotLog, pp: PreprocessConfig) -> int:
    """Decimated samples of all the log's segments after trimming (the rows' time steps).

    Raises
    ------
    DataError
        A segment shorter than the trimming.
    """
    fs = log.sampling_rate_hz
    return sum(
        accumulate.make_plan(b - a, pp, fs, pp.chunk_samples or CHUNK_SAMPLES).n_decimated
        for a, b in log.segments
    )


def block_length(n_samples: int, max_blocks: int = log_chunks.MAX_BLOCKS) -> int:
    """Decimated samples per block for ``n_samples`` in all: ``ceil(n_samples / max_blocks)``
    (1 on short logs), the rule of :func:`ident.identify.estimation.log_chunks.block_equations`."""
    return max(1, -(-int(n_samples) // int(max_blocks)))


def payload_rows(
    log: RobotLog,
    pp: PreprocessConfig,
    columns: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
    block_samples: int,
) -> tuple[ReducedObservations, tuple[BlockEquations, ...]]:
    """The log's rows ``tau - Y theta_arm = [Y_n | E] x``, processed and reduced per joint,
    and their unweighted block normal equations per joint.

    Every segment goes through :func:`ident.identify.estimation.accumulate.iter_chunks` in chunks of
    at most :data:`CHUNK_SAMPLES` raw samples; rows below ``pp.velocity_threshold`` are dropped. The
    blocks (one :class:`~ident.identify.estimation.uncertainty.BlockEquations` per joint, weight 1,
    its blocks in time order) hold ``block_samples`` consecutive decimated samples and never cross a
    chunk or segment boundary. Memory: ``nv * n_blocks * (p^2 + p + 1) * 8`` bytes for ``p``
    columns, ``n_blocks <= n_samples / block_samples + n_chunks`` (with
    :func:`block_length` over all logs, at most ``MAX_BLOCKS + n_chunks`` = 2048 + chunks:
    about 110 MB for 7 joints and 31 columns; twice that while the chunks' blocks are joined).

    Raises
    ------
    DataError
        A segment shorter than the trimming.
    """
    red, parts = _reduce(log, pp, columns, block_samples)
    return red, tuple(BlockEquations.concatenate(p) for p in parts)


def _reduce(
    log: RobotLog,
    pp: PreprocessConfig,
    columns: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
    block_samples: int | None,
) -> tuple[ReducedObservations, list[list[BlockEquations]]]:
    """:func:`payload_rows`; no blocks when ``block_samples`` is None."""
    fs = log.sampling_rate_hz
    total: ReducedObservations | None = None
    parts: list[list[BlockEquations]] = [[] for _ in range(log.q.shape[1])]
    for a, b in log.segments:
        chunk = min(pp.chunk_samples or CHUNK_SAMPLES, b - a)
        plan = accumulate.make_plan(b - a, pp, fs, chunk)
        for c in accumulate.iter_chunks(
            plan, log.q[a:b], log.tau[a:b], fs, pp, columns, plan.ranges()
        ):
            keep, _ = preprocess.velocity_mask(c.dq, pp.velocity_threshold)
            rhs = c.tau - c.Yb[:, :, -1]
            red = accumulate.reduce_chunk(c.Yb[:, :, :-1], rhs, keep)
            total = red if total is None else total.merge(red)
            if block_samples is not None:
                for j, joint in enumerate(parts):
                    rows = slice(j, j + 1)
                    joint.append(
                        BlockEquations.from_samples(
                            c.Yb[:, rows, :-1], rhs[:, rows], keep[:, rows], np.ones(1),
                            block_samples,
                        )
                    )  # fmt: skip
    if total is None:
        raise DataError("the log has no samples.")
    return total, parts


def payload_observations(
    log: RobotLog,
    pp: PreprocessConfig,
    columns: Callable[[FloatArray, FloatArray, FloatArray], FloatArray],
) -> ReducedObservations:
    """The log's rows reduced per joint (:func:`payload_rows` without blocks).

    Raises
    ------
    DataError
        A segment shorter than the trimming.
    """
    return _reduce(log, pp, columns, None)[0]


def weighted_blocks(per_joint: tuple[BlockEquations, ...], weights: FloatArray) -> BlockEquations:
    """``A_b = sum_j w_j^2 A_bj``, ``c_b = sum_j w_j^2 c_bj`` of per-joint unweighted blocks
    (each joint's blocks aligned in time, :func:`payload_rows`) and per-joint row weights
    ``weights`` (nv,) [1/(N*m)]: the blocks
    :func:`~ident.identify.estimation.uncertainty.BlockEquations` ``.from_samples`` gives with those
    weights."""
    w2 = np.asarray(weights, dtype=float) ** 2
    if w2.shape != (len(per_joint),):
        raise DataError(f"{w2.size} weights for {len(per_joint)} joints.")
    A = np.zeros_like(per_joint[0].A)  # summed in place: one joint's size more in memory
    c = np.zeros_like(per_joint[0].c)
    for w, b in zip(w2, per_joint, strict=True):
        A += w * b.A
        c += w * b.c
    n_rows = np.sum([b.n_rows for b in per_joint], axis=0).astype(np.int64)
    return BlockEquations(A=A, c=c, n_rows=n_rows, block_samples=per_joint[0].block_samples)


def merge_blocks(
    first: tuple[BlockEquations, ...], second: tuple[BlockEquations, ...]
) -> tuple[BlockEquations, ...]:
    """Per-joint blocks of two logs, the second's after the first's."""
    return tuple(BlockEquations.concatenate([a, b]) for a, b in zip(first, second, strict=True))
