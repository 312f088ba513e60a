"""Gram matrices ``W^T W`` of observation matrices, without the regressor tensor.

The excitation objective needs the singular values of the (base) observation matrix of
every candidate trajectory; they follow from the small Gram matrix ``G = W^T W`` (the squared
singular values are its eigenvalues). The compiled kernel computes the regressor sample by
sample, keeps only the requested rows and columns (weighted), writes them into a buffer of a
few hundred samples, and BLAS accumulates ``G += B^T B``: the (n_samples, nv, 10 n) tensor is
never built.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ident.blas import one_blas_thread
from ident.dynamics.chain import FloatArray, KinematicChain
from ident.dynamics.regressor import joint_torque_regressor
from ident.errors import DataError

__all__ = ["regressor_gram", "selected_rows"]

_CHUNK = 512  # samples per buffer: 512 * 6 rows * 60 columns * 8 B = 1.5 MB


def _indices(values: Sequence[int] | np.ndarray | None, size: int, label: str) -> np.ndarray:
    if values is None:
        return np.arange(size, dtype=np.int64)
    out = np.array(values, dtype=np.int64).reshape(-1)  # a writeable copy: one kernel type
    if out.size == 0 or out.min() < 0 or out.max() >= size:
        raise DataError(f"{label} must be non-empty indices in [0, {size}), got {out.tolist()}")
    return out


def _states(
    chain: KinematicChain, q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    arrays = [np.asarray(x, dtype=np.float64) for x in (q, dq, ddq)]
    shape = arrays[0].shape
    for label, x in zip(("q", "dq", "ddq"), arrays, strict=True):
        if x.shape != shape or x.ndim not in (2, 3) or x.shape[-1] != chain.n_joints:
            raise DataError(
                f"{label} must have shape (n_samples, {chain.n_joints}) or "
                f"(n_batch, n_samples, {chain.n_joints}) like q, got {x.shape}"
            )
    return tuple(np.ascontiguousarray(x) for x in arrays)  # type: ignore[return-value]


def selected_rows(
    chain: KinematicChain,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    *,
    rows: Sequence[int] | np.ndarray | None = None,
    columns: Sequence[int] | np.ndarray | None = None,
    row_weights: FloatArray | None = None,
    out: FloatArray | None = None,
) -> FloatArray:
    """Stacked observation matrix of selected regressor rows and columns.

    Parameters
    ----------
    chain :
        Kinematic chain.
    q, dq, ddq :
        States, shape (n_samples, nq).
    rows :
        Joints (rows of the regressor) kept; default all.
    columns :
        Parameter columns kept; default all ``10 * n``.
    row_weights :
        Weight of every joint row, shape (nv,) (e.g. 1 / torque noise std [1/(N*m)]);
        default 1.
    out :
        Written in place and returned when given: shape (n_samples * len(rows),
        len(columns)), any strides (a view into a larger array saves a copy).

    Returns
    -------
    :
        ``W`` of shape (n_samples * len(rows), len(columns)), sample-major:
        ``W[k * len(rows) + r, c] = row_weights[rows[r]] * Y_k[rows[r], columns[c]]``.
    """
    from ident.dynamics import _kernels

    q, dq, ddq = _states(chain, q, dq, ddq)
    if q.ndim != 2:
        raise DataError(f"q must have shape (n_samples, {chain.n_joints}), got {q.shape}")
    rows_i, cols_i, weights = _selection(chain, rows, columns, row_weights)
    shape = (q.shape[0] * rows_i.size, cols_i.size)
    if out is None:
        out = np.empty(shape)
    elif out.shape != shape:
        raise ValueError(f"out must have shape {shape}, got {out.shape}")
    if chain.coupled:  # mimic joints: the projected regressor (rows summed), then selected
        y = joint_torque_regressor(chain, q, dq, ddq)[:, rows_i][:, :, cols_i]
        out[...] = (weights[:, None] * y).reshape(shape)
        return out
    arrays = (*_kernels.chain_arrays(chain), *_kernels.states(q, dq, ddq))
    _kernels.selected_rows_into(*arrays, 0, q.shape[0], rows_i, cols_i, weights, out)
    return out


def _selection(
    chain: KinematicChain,
    rows: Sequence[int] | np.ndarray | None,
    columns: Sequence[int] | np.ndarray | None,
    row_weights: FloatArray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = chain.n_joints
    rows_i = _indices(rows, n, "rows")
    cols_i = _indices(columns, 10 * chain.n_bodies, "columns")
    if row_weights is None:
        weights = np.ones(rows_i.size)
    else:
        w = np.asarray(row_weights, dtype=np.float64).reshape(-1)
        if w.shape != (n,):
            raise DataError(f"row_weights must have shape ({n},) (one per joint), got {w.shape}")
        weights = np.ascontiguousarray(w[rows_i])
    return rows_i, cols_i, weights


def regressor_gram(
    chain: KinematicChain,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    *,
    rows: Sequence[int] | np.ndarray | None = None,
    columns: Sequence[int] | np.ndarray | None = None,
    row_weights: FloatArray | None = None,
) -> FloatArray:
    """Gram matrix ``W^T W`` of the weighted observation matrix of selected rows and columns.

    Parameters
    ----------
    chain :
        Kinematic chain.
    q, dq, ddq :
        States, shape (n_samples, nq), or (n_batch, n_samples, nq) for a batch of
        trajectories (e.g. all particles of a swarm).
    rows, columns, row_weights :
        As in :func:`selected_rows`.

    Returns
    -------
    :
        ``G = sum_k B_k^T B_k`` with ``B_k = w[rows, None] * Y_k[rows][:, columns]``,
        shape (n_cols, n_cols), or (n_batch, n_cols, n_cols) for batched input.
    """
    from ident.dynamics import _kernels

    q, dq, ddq = _states(chain, q, dq, ddq)
    rows_i, cols_i, weights = _selection(chain, rows, columns, row_weights)
    batched = q.ndim == 3
    if not batched:
        q, dq, ddq = q[None], dq[None], ddq[None]
    arrays = _kernels.chain_arrays(chain)
    n_batch, n_samples = q.shape[:2]
    chunk = min(_CHUNK, max(n_samples, 1))
    buffer = np.empty((chunk * rows_i.size, cols_i.size))
    out = np.zeros((n_batch, cols_i.size, cols_i.size))
    with one_blas_thread():  # small products: a second thread only spins (ident.blas)
        for b in range(n_batch):
            sample_states = _kernels.states(q[b], dq[b], ddq[b])
            for start in range(0, n_samples, chunk):
                stop = min(start + chunk, n_samples)
                block = buffer[: (stop - start) * rows_i.size]
                if chain.coupled:
                    states = (q[b, start:stop], dq[b, start:stop], ddq[b, start:stop])
                    selected_rows(chain, *states, rows=rows_i, columns=cols_i, out=block)
                    block *= np.tile(weights, stop - start)[:, None]
                else:
                    _kernels.selected_rows_into(
                        *arrays, *sample_states, start, stop, rows_i, cols_i, weights, block
                    )
                out[b] += block.T @ block
    return out if batched else out[0]
