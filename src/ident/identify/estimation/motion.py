"""The measured joint motion of a log, decimated for replay and for ``trajectory.csv``.

``ident identify`` shows the motion the robot actually made (``replay.html``) and saves it in
the trajectory format of :mod:`ident.trajectory` (so ``ident replay RUN_DIR`` works on an
identify run folder). The signals are the processed ones: joint-side angles after the
transmission and zero offsets, low-passed, differentiated and trimmed, with the measured joint
torques. They are decimated to a rate at or below ``max_rate_hz``: the replay animates at
30 frames/s and interpolates between samples, so 50 Hz is enough and keeps the files small.

The anti-aliasing filter here is a zero-phase Butterworth (order 8, cut-off at 0.8 of the new
Nyquist frequency), not the identification's Chebyshev I filter
(:func:`ident.identify.estimation.preprocess.decimate`): a Butterworth filter is maximally flat,
with a gain of exactly 1 at 0 Hz, so angles keep their values. The Chebyshev filter's passband
ripple (+-0.58 % per stage) does not matter to the identification, which filters torques and
regressor alike, but on the TX40's angles two stages would move the arm by up to 0.047 rad.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy import signal

from ident.errors import DataError
from ident.signals import padding, sosfiltfilt
from ident.trajectory import JointTrajectory

__all__ = ["DEFAULT_REPLAY_RATE_HZ", "antialiased", "decimation_factor", "measured_motion"]

FloatArray = npt.NDArray[np.float64]

DEFAULT_REPLAY_RATE_HZ = 50.0
_ANTIALIAS_ORDER = 8
_ANTIALIAS_EDGE = 0.8  # cut-off as a share of the new Nyquist frequency


def decimation_factor(sampling_rate_hz: float, max_rate_hz: float) -> int:
    """Smallest integer factor that brings ``sampling_rate_hz`` to at most ``max_rate_hz``.

    5000 Hz -> 50 Hz: 100; a rate already at or below ``max_rate_hz``: 1.
    """
    if max_rate_hz <= 0:
        raise ValueError(f"max_rate_hz = {max_rate_hz} must be > 0")
    return max(1, math.ceil(sampling_rate_hz / max_rate_hz - 1e-9))


def _cutoff_hz(rate_hz: float) -> float:
    """Cut-off [Hz] of the anti-aliasing filter for the decimated rate ``rate_hz``."""
    return _ANTIALIAS_EDGE * 0.5 * rate_hz


def antialiased(
    x: FloatArray, sampling_rate_hz: float, max_rate_hz: float = DEFAULT_REPLAY_RATE_HZ
) -> FloatArray:
    """One signal (n, ...) of :func:`measured_motion`, decimated to at most ``max_rate_hz``
    (every ``decimation_factor``-th sample of its zero-phase anti-aliasing filter; ``x`` as it
    is when no decimation is needed). A caller may decimate its signals one at a time with it
    and free each full-rate one before computing the next (the replay motion of a long log).

    Raises
    ------
    DataError
        If the signal is too short for the anti-aliasing filter.
    """
    factor = decimation_factor(sampling_rate_hz, max_rate_hz)
    if factor == 1:
        return x
    cutoff = _cutoff_hz(sampling_rate_hz / factor)
    sos = signal.butter(_ANTIALIAS_ORDER, cutoff, fs=sampling_rate_hz, output="sos")
    # Odd extension over ~3 periods of the cut-off: the edge transient of the forward-backward
    # pass decays inside the padding (sosfiltfilt's default of 27 samples leaves errors of
    # 0.1 rad at the end of a log cut mid-motion).
    n = x.shape[0]
    padlen = min(n - 1, math.ceil(3.0 * sampling_rate_hz / cutoff))
    if n <= padding(sos):
        raise DataError(
            f"measured motion: {n} samples are too few for the anti-aliasing filter "
            f"(needs more than {padding(sos)})."
        )
    # ident's compiled filter: only every factor-th sample is written, no copies of x
    return sosfiltfilt(sos, x, factor, padlen=padlen)


def measured_motion(
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    tau: FloatArray,
    sampling_rate_hz: float,
    joint_names: tuple[str, ...],
    *,
    max_rate_hz: float = DEFAULT_REPLAY_RATE_HZ,
) -> tuple[JointTrajectory, dict]:
    """The processed log as a :class:`~ident.trajectory.JointTrajectory` at <= ``max_rate_hz``.

    Parameters
    ----------
    t :
        Time [s], shape (n,), uniform at ``sampling_rate_hz``.
    q, dq, ddq :
        Joint angles [rad], velocities [rad/s], accelerations [rad/s^2], shape (n, nv).
    tau :
        Measured joint torques [N*m], shape (n, nv).
    sampling_rate_hz :
        Rate of the inputs [Hz].
    joint_names :
        Names of the URDF's joints, in column order.
    max_rate_hz :
        Highest rate of the result [Hz].

    Returns
    -------
    :
        The decimated trajectory (time starts where the processed log starts) and a record for
        the report.

    Raises
    ------
    DataError
        If the log is too short for the anti-aliasing filter.
    """
    factor = decimation_factor(sampling_rate_hz, max_rate_hz)
    arrays = [antialiased(x, sampling_rate_hz, max_rate_hz) for x in (q, dq, ddq, tau)]
    q_d, dq_d, ddq_d, tau_d = arrays
    t_d = np.asarray(t[::factor], dtype=float)
    trajectory = JointTrajectory(
        t=t_d,
        q=np.ascontiguousarray(q_d),
        dq=np.ascontiguousarray(dq_d),
        ddq=np.ascontiguousarray(ddq_d),
        joint_names=tuple(joint_names),
        tau=np.ascontiguousarray(tau_d),
    )
    sizes = (q.shape[0], q_d.shape[0])
    return trajectory, _motion_record(sizes, t_d, sampling_rate_hz, factor)


def _motion_record(
    sizes: tuple[int, int], t_d: FloatArray, sampling_rate_hz: float, factor: int
) -> dict:
    """The report's record of :func:`measured_motion`: ``sizes[0]`` samples at
    ``sampling_rate_hz`` [Hz] decimated by ``factor`` to ``sizes[1]`` samples at the times
    ``t_d`` [s]."""
    fs = sampling_rate_hz / factor
    how = "no decimation needed"
    if factor > 1:
        how = (
            f"zero-phase Butterworth order {_ANTIALIAS_ORDER} at {_cutoff_hz(fs):g} Hz, then "
            f"every {factor}th sample"
        )
    return {
        "step": "measured motion",
        "detail": f"processed q, dq, ddq and measured torques, {how}: "
        f"{sizes[0]} -> {sizes[1]} samples, "
        f"{sampling_rate_hz:g} -> {fs:g} Hz, {t_d[0]:.3f}..{t_d[-1]:.3f} s "
        "(trajectory.csv and replay.html; not used to identify)",
    }
