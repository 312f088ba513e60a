"""Signal processing of measured logs: filter, differentiate, trim, decimate, select.

Every step is a pure function that returns its result and a record (a small dict with the step
name and what it did, in words and numbers) for the report:

1. :func:`lowpass`: zero-phase Butterworth low-pass, ``butter(order, cutoff_hz, fs=fs,
   output="sos")`` + ``sosfiltfilt`` (the forward-backward pass squares the magnitude: -6 dB
   at ``cutoff_hz``, no phase lag);
2. :func:`differentiate`: central differences (``np.gradient``, second order inside, one-sided
   second-order at the ends) to ``dq`` and ``ddq``;
3. :func:`trim`: drop the first and last samples, where the filter and the one-sided differences
   are least accurate;
4. :func:`decimate`: zero-phase decimation (the anti-aliasing filter of
   ``scipy.signal.decimate``, order-8 Chebyshev I, ripple centred on 0 dB, applied forward
   and backward with ``sosfiltfilt``, then every ``factor``-th sample), applied alike to the
   torques and to the regressor rows, so that the linear model ``tau = W x`` holds after
   decimation;
5. :func:`velocity_mask`: per joint, mark the samples whose speed is below a threshold, where the
   Coulomb term ``sign(dq)`` is unreliable; the rows of that joint are then dropped.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
from scipy import signal

from ident.errors import ConfigError, DataError

__all__ = ["decimate", "differentiate", "lowpass", "trim", "velocity_mask"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def lowpass(
    x: FloatArray, sampling_rate_hz: float, cutoff_hz: float, order: int = 4, *, what: str = "q"
) -> tuple[FloatArray, dict]:
    """Zero-phase Butterworth low-pass filter along the sample axis.

    Parameters
    ----------
    x :
        Signal, shape (n_samples, ...).
    sampling_rate_hz :
        Sampling rate [Hz].
    cutoff_hz :
        -3 dB frequency of the designed (one-pass) filter [Hz]; must be below Nyquist.
    order :
        Butterworth order (the zero-phase result has twice this attenuation slope).
    what :
        Signal name, for the record and messages.

    Returns
    -------
    :
        Filtered signal (same shape) and its record.

    Raises
    ------
    ConfigError
        If ``cutoff_hz`` is not below the Nyquist frequency.
    DataError
        If the signal is too short for the forward-backward filter.
    """
    nyquist = 0.5 * sampling_rate_hz
    if not 0.0 < cutoff_hz < nyquist:
        raise ConfigError(
            f"cutoff_hz = {cutoff_hz:g} Hz is not below the Nyquist frequency {nyquist:g} Hz of "
            f"the sampling rate {sampling_rate_hz:g} Hz; choose a cutoff below {nyquist:g} Hz."
        )
    sos = signal.butter(order, cutoff_hz, fs=sampling_rate_hz, output="sos")
    padlen = 3 * (2 * len(sos) + 1)  # sosfiltfilt's default padding
    if x.shape[0] <= padlen:
        raise DataError(
            f"{what}: {x.shape[0]} samples are too few for the order-{order} zero-phase filter "
            f"(needs more than {padlen})."
        )
    y = signal.sosfiltfilt(sos, x, axis=0)
    record = {
        "step": f"low-pass {what}",
        "detail": f"zero-phase Butterworth, order {order}, cutoff {cutoff_hz:g} Hz "
        f"(-3 dB designed, -6 dB after sosfiltfilt) at {sampling_rate_hz:g} Hz",
        "cutoff_hz": cutoff_hz,
        "order": order,
    }
    return y, record


def differentiate(q: FloatArray, sampling_rate_hz: float) -> tuple[FloatArray, FloatArray, dict]:
    """Velocities and accelerations by central differences.

    Parameters
    ----------
    q :
        Joint positions [rad], shape (n_samples, n_joints), uniformly sampled.
    sampling_rate_hz :
        Sampling rate [Hz].

    Returns
    -------
    :
        ``dq`` [rad/s], ``ddq`` [rad/s^2] (each shape of ``q``) and the record. Exact on
        polynomials of degree <= 2 (``dq``) and on degree <= 1 of ``dq`` for ``ddq``.
    """
    if q.shape[0] < 3:
        raise DataError(f"need at least 3 samples to differentiate, got {q.shape[0]}.")
    step = 1.0 / sampling_rate_hz
    dq = np.gradient(q, step, axis=0, edge_order=2)
    ddq = np.gradient(dq, step, axis=0, edge_order=2)
    return (
        dq,
        ddq,
        {"step": "differentiate", "detail": "central differences (np.gradient) to dq, ddq"},
    )


def trim(arrays: list[FloatArray], n_edge: int) -> tuple[list[FloatArray], dict]:
    """Drop ``n_edge`` samples at both ends of every array (axis 0).

    Raises
    ------
    DataError
        If nothing would remain.
    """
    n = arrays[0].shape[0]
    if 2 * n_edge >= n:
        raise DataError(f"trim_samples = {n_edge} removes all {n} samples; lower it.")
    out = [a[n_edge : n - n_edge] if n_edge else a for a in arrays]
    return out, {
        "step": "trim",
        "detail": f"dropped {n_edge} samples at each end ({n} -> {n - 2 * n_edge})",
    }


def decimate(
    arrays: list[FloatArray], factors: list[int], sampling_rate_hz: float
) -> tuple[list[FloatArray], float, dict]:
    """Zero-phase decimation of several arrays alike (axis 0), in stages.

    Parameters
    ----------
    arrays :
        Arrays of shape (n_samples, ...), e.g. torques (n, nv) and regressor (n, nv, n_params).
    factors :
        Decimation factors applied in sequence (each <= 13 is advised by scipy).
    sampling_rate_hz :
        Input rate [Hz].

    Returns
    -------
    :
        Decimated arrays, the new sampling rate [Hz] and the record.

    Raises
    ------
    DataError
        If a stage has too few samples for its anti-aliasing filter.
    """
    fs = sampling_rate_hz
    n_in = arrays[0].shape[0]
    out = list(arrays)
    for factor in factors:
        if factor == 1:
            continue
        n = out[0].shape[0]
        sos = _antialias_sos(factor)
        if n <= 3 * (2 * len(sos) + 1):
            raise DataError(
                f"decimation by {factor}: only {n} samples left, too few for the zero-phase "
                "anti-aliasing filter; use a longer log or less decimation."
            )
        out = [
            signal.sosfiltfilt(sos, a.reshape(n, -1), axis=0)[::factor].reshape(-1, *a.shape[1:])
            for a in out
        ]
        fs /= factor
    return (
        out,
        fs,
        {
            "step": "decimate",
            "detail": f"zero-phase decimation by {' x '.join(str(f) for f in factors) or '1'} "
            "(Chebyshev I order 8, ripple centred on 0 dB, forward-backward) of torques and "
            f"regressor rows alike: {n_in} -> {out[0].shape[0]} samples, "
            f"{sampling_rate_hz:g} -> {fs:g} Hz",
        },
    )


def _antialias_sos(factor: int) -> FloatArray:
    """scipy.signal.decimate's filter (Chebyshev I, order 8, 0.05 dB ripple, edge 0.8 of the
    new Nyquist) as second-order sections, rescaled so that the passband ripple is centred on
    0 dB (an even-order Chebyshev I sits at the ripple's minimum at 0 Hz: the forward-backward
    pass of scipy's version scales slow signals by 0.989 per stage; here the passband gain
    stays within +-0.58 % per stage)."""
    ripple_db = 0.05
    sos = signal.cheby1(8, ripple_db, 0.8 / factor, output="sos")
    _, h = signal.sosfreqz(sos, worN=[0.0])
    sos[0, :3] *= 10.0 ** (-ripple_db / 40.0) / abs(h[0])
    return sos


def velocity_mask(
    dq: FloatArray, thresholds: list[float] | FloatArray | None
) -> tuple[BoolArray, dict]:
    """Per joint, keep the samples whose speed reaches the threshold.

    Parameters
    ----------
    dq :
        Joint velocities [rad/s], shape (n_samples, n_joints).
    thresholds :
        Per-joint speed thresholds [rad/s], shape (n_joints,), or None to keep everything.

    Returns
    -------
    :
        ``keep`` of shape (n_samples, n_joints): True where ``|dq_j| >= threshold_j``; and the
        record with the kept count per joint.

    Raises
    ------
    ConfigError
        If the number of thresholds differs from the number of joints.
    """
    n_samples, n_joints = dq.shape
    if thresholds is None:
        keep = np.ones((n_samples, n_joints), dtype=bool)
        return keep, {"step": "velocity threshold", "detail": "none (all samples kept)"}
    thresholds = np.asarray(thresholds, dtype=float)
    if thresholds.shape != (n_joints,):
        raise ConfigError(
            f"preprocess.velocity_threshold has {thresholds.size} values, the robot has "
            f"{n_joints} joints; give one per joint [rad/s]."
        )
    keep = np.abs(dq) >= thresholds
    kept = keep.sum(axis=0)
    return keep, {
        "step": "velocity threshold",
        "detail": "dropped the rows of joint j where abs(dq_j) < threshold_j "
        f"{[round(float(v), 4) for v in thresholds]} rad/s; kept per joint "
        f"{kept.tolist()} of {n_samples}",
        "kept": kept.tolist(),
    }
