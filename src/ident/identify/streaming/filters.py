"""Causal differentiation for a streaming estimate: Savitzky-Golay FIR filters with their
constant delay compensated.

A streaming estimator cannot run the zero-phase filters of the batch preprocessing (they need
the future). It fits, at every new sample, a polynomial of degree ``order`` to the last
``window`` positions (odd ``window = 2 D + 1``) and evaluates it and its two derivatives at the
window's *centre*: a linear-phase FIR filter, so its delay is exactly ``D`` samples at every
frequency. The torque goes through the degree-``order`` smoothing filter of the same window, so
``q``, ``dq``, ``ddq`` and ``tau`` all describe the instant ``D`` samples ago: the delay is
compensated by pairing, not by a guess, and the estimator lags the robot by ``D / rate``
(10 ms for the default 21 samples at 1 kHz). Filter states carry over from block to block
(the last ``window - 1`` samples are kept); no output is given for the first ``window - 1``
samples after a (re)start.

Rows are then taken every ``window`` samples (decimation by the window): the white torque and
position noise of two rows come from disjoint samples and are independent, which is what the
ordinary (sandwich) covariance of :mod:`ident.identify.streaming.normal` assumes.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy.signal import savgol_coeffs

__all__ = ["CausalDifferentiator"]

FloatArray = npt.NDArray[np.float64]


class CausalDifferentiator:
    """Streams ``(q, tau)`` blocks into delayed ``(q, dq, ddq, tau)`` at the decimated rows.

    Parameters
    ----------
    nv :
        Number of joints.
    rate_hz :
        Sampling rate [Hz].
    window :
        Odd number of samples of each fit (delay ``(window - 1) / 2`` samples).
    order :
        Polynomial degree (>= 2, < window).
    """

    def __init__(self, nv: int, rate_hz: float, window: int = 21, order: int = 3) -> None:
        dt = 1.0 / rate_hz
        self.window = window
        self.delay = (window - 1) // 2
        # use="dot": weights of the window's samples in time order, the fit evaluated at its
        # centre (savgol_coeffs' default pos)
        self.b = [savgol_coeffs(window, order, deriv=d, delta=dt, use="dot") for d in (0, 1, 2)]
        self.nv = nv
        self.reset()

    def reset(self) -> None:
        """Forget the past (a gap in the log): the next ``window - 1`` outputs are invalid."""
        self._history = np.zeros((0, 2 * self.nv))  # the last window - 1 samples of [q | tau]
        self._phase = 0  # samples since the start, modulo the window

    def push(
        self, q: FloatArray, tau: FloatArray
    ) -> tuple[npt.NDArray[np.intp], FloatArray, FloatArray, FloatArray, FloatArray]:
        """Filter one block ``q``, ``tau`` (n, nv) and return the rows it completes:
        ``(index, q, dq, ddq, tau)`` with ``index`` (m,) the rows' sample indices in this block
        (each row describes the instant ``delay`` samples before it) and the signals (m, nv).
        Only the rows' outputs are computed: one dot product of ``window`` samples each."""
        n, w = q.shape[0], self.window
        buf = np.vstack([self._history, np.hstack([q, tau])])
        h = self._history.shape[0]
        # rows every `window` samples from the first valid output (sample window - 1)
        first = (w - 1 - self._phase) % w
        index = np.arange(first, n, w, dtype=np.intp)
        index = index[h + index >= w - 1]
        self._phase = (self._phase + n) % w
        self._history = buf[-(w - 1) :] if w > 1 else buf[:0]
        if index.size == 0:
            empty = np.zeros((0, self.nv))
            return index, empty, empty, empty, empty
        windows = np.stack([buf[h + i - w + 1 : h + i + 1] for i in index])  # (m, w, 2 nv)
        smooth = np.einsum("k,mkc->mc", self.b[0], windows)
        dq = np.einsum("k,mkc->mc", self.b[1], windows[:, :, : self.nv])
        ddq = np.einsum("k,mkc->mc", self.b[2], windows[:, :, : self.nv])
        return index, smooth[:, : self.nv], dq, ddq, smooth[:, self.nv :]
