"""Signal primitives shared by every measurement path: one low-pass filter, one differentiator.

The ideal measurement (encoder positions differentiated), the preprocessing of a measured log
and the chunked path all call these, so a log and a simulation are filtered and differentiated
the same way. Signals are uniformly sampled, samples on axis 0.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy import signal

__all__ = ["central_differences", "zero_phase_lowpass"]

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
    return np.asarray(signal.sosfiltfilt(sos, x, axis=0), dtype=float)


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
