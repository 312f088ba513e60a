"""Signal primitives shared by every measurement path: one low-pass filter, one differentiator.

The ideal measurement (encoder positions differentiated), the preprocessing of a measured log
and the chunked path all call these, so a log and a simulation are filtered and differentiated
the same way. Signals are uniformly sampled, samples on axis 0.

:func:`sosfiltfilt` is scipy's ``sosfiltfilt(sos, x, axis=0)`` (odd padding of its default
length, the steady-state initial conditions of ``sosfilt_zi``, the same recursion) compiled
for signals with many columns, samples on axis 0: the columns are the inner loop, nothing is
transposed or copied per column, and only every ``step``-th output sample is written (the
decimation of a long log's regressor filters hundreds of columns: scipy moves the axis and
copies the array on every pass).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit
from scipy import signal

__all__ = ["central_differences", "sosfiltfilt", "zero_phase_lowpass"]

FloatArray = npt.NDArray[np.float64]


def zero_phase_lowpass(
    x: npt.ArrayLike, sampling_rate_hz: float, cutoff_hz: float, order: int = 4
) -> FloatArray:
    """Zero-phase Butterworth low-pass filter along axis 0 (``sosfiltfilt``).

    Parameters
    ----------
    x :
        Signal, shape (n_samples, ...).
    sampling_rate_hz :
        Sampling rate [Hz].
    cutoff_hz :
        -3 dB frequency of the designed (one-pass) filter [Hz], below the Nyquist frequency;
        after the forward-backward pass the gain there is -6 dB.
    order :
        Butterworth order (the zero-phase result has twice this attenuation slope).

    Returns
    -------
    :
        The filtered signal, same shape.
    """
    sos = signal.butter(order, cutoff_hz, fs=sampling_rate_hz, output="sos")
    return sosfiltfilt(sos, x)


def sosfiltfilt(
    sos: npt.ArrayLike, x: npt.ArrayLike, step: int = 1, *, skip_zero_columns: bool = False
) -> FloatArray:
    """Forward-backward filtering along axis 0, every ``step``-th sample of the result.

    Equal to ``scipy.signal.sosfiltfilt(sos, x, axis=0)[::step]`` (to round-off; the same
    operations in the same order, see the module docstring).

    Parameters
    ----------
    sos :
        Second-order sections, shape (n_sections, 6), ``a0 = 1``.
    x :
        Signal, shape (n_samples, ...), n_samples above the padding ``3 (2 n_sections + 1)``
        (fewer when sections have zero ``b2`` and ``a2``, as scipy counts them).
    step :
        Keep samples ``0, step, 2 step, ...``.
    skip_zero_columns :
        Find the columns (of ``x`` flattened to (n_samples, -1)) that are zero throughout and
        leave them zero without filtering (exactly what filtering gives): a joint's regressor
        row has no term of the bodies before it, about half of a serial arm's columns.

    Returns
    -------
    :
        Shape (ceil(n_samples / step), ...).
    """
    sos = np.ascontiguousarray(sos, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    ntaps = 2 * sos.shape[0] + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    edge = 3 * ntaps
    if n <= edge:
        raise ValueError(
            f"The length of the input vector x must be greater than padlen, which is {edge}."
        )
    flat = x.reshape(n, -1)
    if not flat.flags.c_contiguous:
        flat = np.ascontiguousarray(flat)
    columns = (
        _nonzero_columns(flat) if skip_zero_columns else np.arange(flat.shape[1], dtype=np.int64)
    )
    out = np.zeros(((n + step - 1) // step, flat.shape[1]))
    if columns.size:
        zi = np.ascontiguousarray(signal.sosfilt_zi(sos))
        _sosfiltfilt(sos, zi, flat, columns, edge, step, out)
    return out.reshape(-1, *x.shape[1:])


def central_differences(q: npt.ArrayLike, sampling_rate_hz: float) -> tuple[FloatArray, FloatArray]:
    """Velocities and accelerations of uniformly sampled positions.

    Second-order central differences inside, second-order one-sided ones at both ends
    (``numpy.gradient(..., edge_order=2)``), applied twice: exact on polynomials of degree
    <= 2 (``dq``) and on degree <= 1 of ``dq`` (``ddq``).

    Parameters
    ----------
    q :
        Positions [rad or m], shape (n_samples, n_joints), n_samples >= 3.
    sampling_rate_hz :
        Sampling rate [Hz].

    Returns
    -------
    dq, ddq :
        Velocities and accelerations, each of the shape of ``q``.
    """
    step = 1.0 / sampling_rate_hz
    dq = np.gradient(q, step, axis=0, edge_order=2)
    ddq = np.gradient(dq, step, axis=0, edge_order=2)
    return dq, ddq


@njit(cache=True, nogil=True)
def _nonzero_columns(x: FloatArray) -> npt.NDArray[np.int64]:  # numba: (n, c) -> (k,)
    found = np.zeros(x.shape[1], dtype=np.bool_)
    for i in range(x.shape[0]):
        for c in range(x.shape[1]):
            if x[i, c] != 0.0:
                found[c] = True
    return np.flatnonzero(found)


@njit(cache=True, nogil=True, inline="always")
def _filter_row(sos: FloatArray, z0s: FloatArray, z1s: FloatArray, v: FloatArray) -> None:
    """One sample ``v`` (c,) of every column through the sections, in place; direct form II
    transposed with the states ``z0s``, ``z1s`` (n_sections, c), updated.

    Per column the arithmetic is scipy's, so the result is equal bit for bit; the loop over
    columns is innermost and runs on separate contiguous state arrays, which LLVM vectorizes
    (3x faster than one (n_sections, 2, c) state array, whose views it cannot prove apart).
    """
    for s in range(sos.shape[0]):
        b0, b1, b2, a1, a2 = sos[s, 0], sos[s, 1], sos[s, 2], sos[s, 4], sos[s, 5]
        z0 = z0s[s]
        z1 = z1s[s]
        for c in range(v.size):
            x_cur = v[c]
            x_new = b0 * x_cur + z0[c]
            z0[c] = b1 * x_cur - a1 * x_new + z1[c]
            z1[c] = b2 * x_cur - a2 * x_new
            v[c] = x_new


@njit(cache=True, nogil=True)
def _sosfiltfilt(  # noqa: PLR0913
    sos: FloatArray,
    zi0: FloatArray,
    x: FloatArray,
    columns: npt.NDArray[np.int64],
    edge: int,
    step: int,
    out: FloatArray,
) -> None:
    """Odd extension, forward pass, backward pass of ``x[:, columns]``; writes
    ``out[:, columns]`` (every ``step``-th sample).

    The forward pass reads each extended row as it goes (gather and filter in one sweep) into
    the buffer that the backward pass then filters in place, from its last row to its first.
    """
    n = x.shape[0]
    cols = columns.size
    n_sections = sos.shape[0]
    m = n + 2 * edge
    ext = np.empty((m, cols))  # the forward pass of scipy's odd extension (odd_ext)
    z0s = np.empty((n_sections, cols))
    z1s = np.empty((n_sections, cols))
    for s in range(n_sections):
        for c in range(cols):
            first = 2.0 * x[0, columns[c]] - x[edge, columns[c]]  # ext[0]
            z0s[s, c] = zi0[s, 0] * first
            z1s[s, c] = zi0[s, 1] * first
    for r in range(m):
        v = ext[r]
        if r < edge:
            for c in range(cols):
                v[c] = 2.0 * x[0, columns[c]] - x[edge - r, columns[c]]
        elif r < n + edge:
            for c in range(cols):
                v[c] = x[r - edge, columns[c]]
        else:
            i = r - n - edge
            for c in range(cols):
                v[c] = 2.0 * x[n - 1, columns[c]] - x[n - 2 - i, columns[c]]
        _filter_row(sos, z0s, z1s, v)
    for s in range(n_sections):
        for c in range(cols):
            z0s[s, c] = zi0[s, 0] * ext[m - 1, c]
            z1s[s, c] = zi0[s, 1] * ext[m - 1, c]
    # backward: row r of the buffer is original sample j = r - edge, kept at multiples of step
    for r in range(m - 1, -1, -1):
        v = ext[r]
        _filter_row(sos, z0s, z1s, v)
        j = r - edge
        if 0 <= j < n and j % step == 0:
            for c in range(cols):
                out[j // step, columns[c]] = v[c]
