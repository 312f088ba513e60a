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

:class:`ZeroPhaseStream` is the same filter for a signal that arrives in pieces of rows (a long
log's regressor, computed a block at a time): its memory is set by its block, not by the
signal's length.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from numba import njit
from scipy import signal

__all__ = [
    "ZeroPhaseStream",
    "central_differences",
    "decay_length",
    "derivative",
    "padding",
    "sosfiltfilt",
    "zero_phase_lowpass",
]

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
    sos: npt.ArrayLike,
    x: npt.ArrayLike,
    step: int = 1,
    *,
    skip_zero_columns: bool = False,
    padlen: int | None = None,
) -> FloatArray:
    """Forward-backward filtering along axis 0, every ``step``-th sample of the result.

    Equal to ``scipy.signal.sosfiltfilt(sos, x, axis=0, padlen=padlen)[::step]`` (to
    round-off; the same operations in the same order, see the module docstring).

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
    padlen :
        Rows of the odd extension on each side; default scipy's (:func:`padding`).

    Returns
    -------
    :
        Shape (ceil(n_samples / step), ...).
    """
    sos = np.ascontiguousarray(sos, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    n = x.shape[0]
    edge = padding(sos) if padlen is None else padlen
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


def padding(sos: FloatArray) -> int:
    """Rows of scipy's odd extension on each side (``sosfiltfilt``'s default ``padlen``:
    three times the taps, a section with zero ``b2`` and ``a2`` counting one less)."""
    ntaps = 2 * sos.shape[0] + 1 - min(int((sos[:, 2] == 0).sum()), int((sos[:, 5] == 0).sum()))
    return 3 * ntaps


def decay_length(sos: npt.ArrayLike, rtol: float = 1e-14, max_len: int = 2_000_000) -> int:
    """Samples after which the impulse response of ``sos`` stays below ``rtol`` of its peak
    (how far the transient of a wrong start reaches into a filtered signal)."""
    n = 1024
    while True:
        x = np.zeros(n)
        x[0] = 1.0
        h = np.abs(signal.sosfilt(sos, x))
        above = np.flatnonzero(h > rtol * h.max())
        if above[-1] < n // 2 or n >= max_len:
            return int(above[-1]) + 1
        n *= 4


#: Rows a :class:`ZeroPhaseStream`'s buffer starts with (it doubles up to its block's size).
_FIRST_BUFFER_ROWS = 1 << 16


class ZeroPhaseStream:
    """:func:`sosfiltfilt` ``(sos, x, step)`` of a signal ``x`` (n, c) pushed in pieces of rows.

    The forward pass runs as rows arrive, its state carried from piece to piece: exactly
    scipy's. The backward pass needs the rows after each output, so it runs on blocks of
    ``block`` rows once :func:`decay_length` more forward rows (the warm-up) exist, starting
    from the steady state of the last of them (``sosfilt_zi`` times its value): the start's
    error has decayed below 1e-14 of the filter's response by the block. The last block starts
    from the end of the odd extension, as scipy does (bit for bit there, and everywhere when
    the signal has fewer than ``block`` + warm-up rows). Memory: at most ``block`` + warm-up rows
    of ``c`` columns whatever the signal's length (for a shorter signal, at most twice its rows
    or 65 536); the result depends on ``block``, never on how the rows were split into pieces.

    >>> stream = ZeroPhaseStream(signal.butter(4, 0.1, output="sos"), n_columns=2, step=5)
    >>> x = np.random.default_rng(0).normal(size=(100_000, 2))
    >>> y = np.concatenate([stream.push(x[:30_000]), stream.push(x[30_000:]), stream.finish()])
    >>> bool(np.abs(y - sosfiltfilt(signal.butter(4, 0.1, output="sos"), x, 5)).max() < 1e-13)
    True
    """

    def __init__(self, sos: npt.ArrayLike, n_columns: int, step: int = 1, block: int = 0):
        self.sos = np.ascontiguousarray(sos, dtype=np.float64)
        self.zi = np.ascontiguousarray(signal.sosfilt_zi(self.sos))
        self.step = step
        self.edge = padding(self.sos)
        self.warm_up = decay_length(self.sos)
        # 4 warm-ups per block: the backward pass runs over 1.25 times the rows
        self.block = block or max(2048, 4 * self.warm_up)
        n_sections = self.sos.shape[0]
        self._z0 = np.zeros((n_sections, n_columns))
        self._z1 = np.zeros((n_sections, n_columns))
        # forward output of rows [emitted, emitted + fill) of the signal; grown as rows come
        # (:meth:`_grow`), so a short signal never allocates a long filter's whole block
        self._capacity = self.block + self.warm_up + self.edge
        self._buffer = np.empty((min(self._capacity, _FIRST_BUFFER_ROWS), n_columns))
        self._fill = 0
        self._emitted = 0
        self._received = 0
        self._head: list[FloatArray] = []  # rows held until the odd extension's start is known
        self._tail = np.empty((0, n_columns))  # the last edge + 1 rows, for the end's extension

    @property
    def n_rows(self) -> int:
        """Rows pushed so far."""
        return self._received + sum(len(h) for h in self._head)

    def push(self, x: FloatArray) -> FloatArray:
        """Filter the rows ``x`` (k, c); the output rows (every ``step``-th) now final."""
        x = np.asarray(x, dtype=np.float64)
        if not self._received and self.n_rows + len(x) <= self.edge:
            self._head.append(x.copy())
            return self._none()
        if self._head:
            x = np.concatenate([*self._head, x])
            self._head = []
        if not self._received:
            self._start(x)
        self._tail = np.concatenate([self._tail, x[-(self.edge + 1) :]])[-(self.edge + 1) :]
        self._received += len(x)
        return self._forward(x, flush=False)

    def finish(self) -> FloatArray:
        """The remaining output rows: the end's odd extension and the last backward pass.

        Raises
        ------
        ValueError
            If the signal has no more rows than the padding (scipy's error).
        """
        if not self._received:
            raise ValueError(
                "The length of the input vector x must be greater than padlen, which is "
                f"{self.edge}."
            )
        last, before = self._tail[-1], self._tail[-2::-1][: self.edge]
        return self._forward(2.0 * last - before, flush=True)

    def _none(self) -> FloatArray:
        return np.empty((0, self._buffer.shape[1]))

    def _start(self, x: FloatArray) -> None:
        """The forward state after the start's odd extension ``2 x[0] - x[edge - r]``."""
        head = 2.0 * x[0] - x[self.edge : 0 : -1]
        self._z0[:] = self.zi[:, :1] * head[0]
        self._z1[:] = self.zi[:, 1:] * head[0]
        _forward_rows(self.sos, self._z0, self._z1, head, head)

    def _forward(self, x: FloatArray, flush: bool) -> FloatArray:
        """Forward-filter ``x`` into the buffer, emitting each block that has its warm-up;
        ``flush``: ``x`` is the end's extension, and everything left is emitted."""
        out = [self._none()]
        full = self.block + self.warm_up
        pos = 0
        while pos < len(x):
            if self._fill == len(self._buffer):
                self._grow()
            k = min(len(x) - pos, len(self._buffer) - self._fill)
            into = self._buffer[self._fill : self._fill + k]
            _forward_rows(self.sos, self._z0, self._z1, x[pos : pos + k], into)
            self._fill += k
            pos += k
            while self._fill >= full and not flush:
                out.append(self._backward(full - 1, self.block))
        if flush:
            out.append(self._backward(self._fill - 1, self._received - self._emitted))
        return np.concatenate(out)

    def _grow(self) -> None:
        """Double the buffer's rows (at most ``block`` + warm-up + edge), keeping its rows."""
        rows = min(self._capacity, 2 * len(self._buffer))
        grown = np.empty((rows, self._buffer.shape[1]))
        grown[: self._fill] = self._buffer[: self._fill]
        self._buffer = grown

    def _backward(self, last: int, n_rows: int) -> FloatArray:
        """Backward pass over buffer rows ``last`` down to 0; the output of its first
        ``n_rows`` rows (signal rows ``emitted ...``), which then leave the buffer."""
        first, step = self._emitted, self.step
        n_out = len(range(-(-first // step) * step, first + n_rows, step))
        out = np.empty((n_out, self._buffer.shape[1]))
        _backward_rows(self.sos, self.zi, self._buffer, last, n_rows, first, step, out)
        left = self._fill - n_rows
        self._buffer[:left] = self._buffer[n_rows : self._fill]
        self._fill = left
        self._emitted += n_rows
        return out


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
    dq = derivative(q, sampling_rate_hz)
    return dq, derivative(dq, sampling_rate_hz)


def derivative(x: npt.ArrayLike, sampling_rate_hz: float) -> FloatArray:
    """One step of :func:`central_differences`: the derivative of uniformly sampled ``x``
    (n_samples >= 3, ...) along axis 0, same shape (a caller that needs ``dq`` and ``ddq`` one
    at a time, freeing each before the next, calls it twice)."""
    return np.gradient(x, 1.0 / sampling_rate_hz, axis=0, edge_order=2)


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


@njit(cache=True, nogil=True)
def _forward_rows(
    sos: FloatArray, z0s: FloatArray, z1s: FloatArray, x: FloatArray, out: FloatArray
) -> None:
    """The rows of ``x`` (k, c) filtered forward into ``out`` (k, c; may be ``x``), states
    carried; each row is copied, then filtered while in cache."""
    for r in range(x.shape[0]):
        v = out[r]
        for c in range(v.size):
            v[c] = x[r, c]
        _filter_row(sos, z0s, z1s, v)


@njit(cache=True, nogil=True)
def _backward_rows(  # noqa: PLR0913
    sos: FloatArray,
    zi0: FloatArray,
    buf: FloatArray,
    last: int,
    n_rows: int,
    first: int,
    step: int,
    out: FloatArray,
) -> None:
    """Backward pass over ``buf`` rows ``last`` down to 0 (not modified), from the state
    ``zi0 * buf[last]``; row ``r < n_rows`` is signal row ``first + r``, written to ``out``
    when a multiple of ``step`` (``out[0]`` the first such row)."""
    n_sections, cols = sos.shape[0], buf.shape[1]
    z0s = np.empty((n_sections, cols))
    z1s = np.empty((n_sections, cols))
    for s in range(n_sections):
        for c in range(cols):
            z0s[s, c] = zi0[s, 0] * buf[last, c]
            z1s[s, c] = zi0[s, 1] * buf[last, c]
    v = np.empty(cols)
    out0 = (first + step - 1) // step
    for r in range(last, -1, -1):
        for c in range(cols):
            v[c] = buf[r, c]
        _filter_row(sos, z0s, z1s, v)
        i = first + r
        if r < n_rows and i % step == 0:
            for c in range(cols):
                out[i // step - out0, c] = v[c]
