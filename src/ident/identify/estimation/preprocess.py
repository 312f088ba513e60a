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

from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt
from scipy import signal
from scipy.linalg import blas

from ident.errors import ConfigError, DataError
from ident.identify.config import FilterConfig, PreprocessConfig
from ident.signals import (
    ZeroPhaseStream,
    central_differences,
    padding,
    sosfiltfilt,
    zero_phase_lowpass,
)

if TYPE_CHECKING:
    from ident.measure.logs import RobotLog

__all__ = [
    "DecimationStream",
    "antialias_sos",
    "check_differentiable",
    "decimate",
    "decimated_length",
    "decimation_factors",
    "decimation_step",
    "differentiate",
    "lowpass",
    "position_filter",
    "resolve_defaults",
    "trim",
    "velocity_mask",
]

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
    padlen = 3 * (2 * ((order + 1) // 2) + 1)  # sosfiltfilt's default padding
    if x.shape[0] <= padlen:
        raise DataError(
            f"{what}: {x.shape[0]} samples are too few for the order-{order} zero-phase filter "
            f"(needs more than {padlen})."
        )
    y = zero_phase_lowpass(x, sampling_rate_hz, cutoff_hz, order)
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
    check_differentiable(q.shape[0])
    dq, ddq = central_differences(q, sampling_rate_hz)
    return (
        dq,
        ddq,
        {"step": "differentiate", "detail": "central differences (np.gradient) to dq, ddq"},
    )


def check_differentiable(n_samples: int) -> None:
    """Raise :class:`DataError` when :func:`differentiate` cannot run on ``n_samples``."""
    if n_samples < 3:
        raise DataError(f"need at least 3 samples to differentiate, got {n_samples}.")


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
        sos = antialias_sos(factor)
        if n <= padding(sos):
            raise _too_few_to_decimate(factor, n)
        out = [
            sosfiltfilt(sos, a.reshape(n, -1), factor, skip_zero_columns=True).reshape(
                -1, *a.shape[1:]
            )
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


def decimated_length(n_samples: int, factors: list[int]) -> int:
    """Samples left of ``n_samples`` after decimating by ``factors`` in turn (``x[::f]``
    keeps ``ceil(n / f)``)."""
    for factor in factors:
        n_samples = -(-n_samples // factor)
    return n_samples


def _too_few_to_decimate(factor: int, n_samples: int) -> DataError:
    return DataError(
        f"decimation by {factor}: only {n_samples} samples left, too few for the zero-phase "
        "anti-aliasing filter; use a longer log or less decimation."
    )


class DecimationStream:
    """:func:`decimate` of rows pushed in pieces, in memory bounded whatever their number.

    One :class:`ident.signals.ZeroPhaseStream` per stage, each stage's output rows pushed into
    the next: equal to :func:`decimate` of all the rows to ~1e-14 of their scale.

    Parameters
    ----------
    factors :
        Decimation factors applied in sequence (1 skipped).
    n_columns :
        Columns of the rows (c).
    """

    def __init__(self, factors: list[int], n_columns: int) -> None:
        self.factors = [f for f in factors if f != 1]
        self.n_columns = n_columns
        self.stages = [ZeroPhaseStream(antialias_sos(f), n_columns, f) for f in self.factors]

    def push(self, x: FloatArray) -> FloatArray:
        """Decimate the rows ``x`` (k, c): the output rows now final (m, c), a new array."""
        if not self.stages:
            return np.array(x, dtype=np.float64)
        for stage in self.stages:
            x = stage.push(x)
        return x

    def finish(self) -> FloatArray:
        """The remaining output rows.

        Raises
        ------
        DataError
            If a stage has too few samples for its anti-aliasing filter (as :func:`decimate`).
        """
        out: FloatArray | None = None
        for factor, stage in zip(self.factors, self.stages, strict=True):
            if out is not None:
                out = stage.push(out)
            if stage.n_rows <= stage.edge:
                raise _too_few_to_decimate(factor, stage.n_rows)
            last = stage.finish()
            out = last if out is None else np.concatenate([out, last])
        return np.empty((0, self.n_columns)) if out is None else out


def antialias_sos(factor: int) -> FloatArray:
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


# Automatic settings (``lowpass: auto``, ``decimation: auto``): the position low-pass cuts at
# CUTOFF_PER_BAND times the excitation band (a 4th-order zero-phase Butterworth attenuates the
# band itself by less than 1e-5), and decimation keeps at least RATE_PER_CUTOFF samples per
# period of the cutoff (the anti-aliasing filter passes 0.8 of the new Nyquist frequency).
CUTOFF_PER_BAND = 5.0
RATE_PER_CUTOFF = 4.0
MAX_STAGE = 10
# Fraction of the positions' power above a quarter of the sampling rate that means aliasing.
ALIAS_POWER = 1e-4
# Relative mismatch of logged and differentiated velocities that is worth a warning.
VELOCITY_MISMATCH = 0.2


def excitation_band(q: FloatArray, sampling_rate_hz: float, energy: float = 0.999) -> float:
    """Frequency [Hz] below which ``energy`` of the detrended positions' power lies (largest
    over joints); ``q`` of shape (n_samples, n_joints)."""
    return _spectral_summary(q, sampling_rate_hz, energy)[0]


def _spectral_summary(
    q: FloatArray, sampling_rate_hz: float, energy: float = 0.999
) -> tuple[float, FloatArray]:
    """One pass over the joints' spectra (:func:`_spectra`): the :func:`excitation_band` and,
    per joint, the share of the power above fs/4 (NaN for a joint without power; the alias
    warning's figure), shape (n_joints,)."""
    freqs = np.fft.rfftfreq(q.shape[0], 1.0 / sampling_rate_hz)
    above = freqs > 0.25 * sampling_rate_hz
    band = 0.0
    high = []
    for power in _spectra(q):
        total = power.sum()
        with np.errstate(invalid="ignore", divide="ignore"):
            high.append(power[above].sum() / total)
        if total > 0:
            band = max(band, _energy_frequency(power, total, freqs, energy))
        del power  # not held while the next joint's spectrum is computed
    if band <= 0:
        band = float(freqs[1] if freqs.size > 1 else sampling_rate_hz / 4)
    return band, np.array(high, dtype=float)


def _energy_frequency(
    power: FloatArray, total: float, freqs: npt.NDArray[np.floating], energy: float
) -> float:
    """The frequency [Hz] of ``freqs`` below which ``energy`` of ``power`` (its sum
    ``total`` > 0) lies; both shape (n_bins,)."""
    cumulative = np.cumsum(power)
    cumulative /= total  # in place: one array of the spectrum's size, not two
    return float(freqs[np.searchsorted(cumulative, energy)])


def _spectra(q: FloatArray) -> Iterator[FloatArray]:
    """Power of each joint's detrended positions (``rfft`` bins, shape (n // 2 + 1,)),
    Blackman-Harris windowed (the ends of a log do not match: without a window their jump
    leaks power to every frequency). One joint at a time: an hour at 1 kHz is 29 MB a joint,
    where the whole spectrum at once took 1 GB of temporaries for 7 joints."""
    n = q.shape[0]
    window = signal.windows.blackmanharris(n)
    k = np.arange(n, dtype=np.float64) - 0.5 * (n - 1)  # sample index about its mean
    kk = float(k @ k)
    for j in range(q.shape[1]):
        # the least-squares line in closed form (scipy's detrend solves it with lstsq, whose
        # design matrix and workspace took ~200 MB a joint for an hour at 1 kHz)
        x = q[:, j] - q[:, j].mean()
        if kk > 0:
            x = blas.daxpy(k, x, a=-float(k @ x) / kk)  # x -= slope * k, in place
        x *= window
        spectrum = np.fft.rfft(x)
        del x  # the spectrum, its power and the caller's cumulative sum only, at once
        power = np.abs(spectrum)
        del spectrum
        power *= power
        yield power


def _stages(factor: int) -> list[int]:
    """Decimation factors of at most MAX_STAGE whose product is at most ``factor``."""
    out: list[int] = []
    while factor >= 2:
        stage = min(factor, MAX_STAGE)
        out.append(stage)
        factor //= stage
    return out


def position_filter(pp: PreprocessConfig) -> FilterConfig | None:
    """The low-pass of the positions of resolved settings (:func:`resolve_defaults`)."""
    if isinstance(pp.lowpass, str):
        raise ConfigError("preprocess.lowpass: 'auto' is resolved by resolve_defaults first.")
    return pp.lowpass


def decimation_factors(pp: PreprocessConfig) -> list[int]:
    """The decimation factors of resolved settings (:func:`resolve_defaults`)."""
    if isinstance(pp.decimation, str):
        raise ConfigError("preprocess.decimation: 'auto' is resolved by resolve_defaults first.")
    return list(pp.decimation)


def decimation_step(pp: PreprocessConfig) -> int:
    """Raw samples per decimated sample of resolved settings (product of the factors)."""
    return int(np.prod(decimation_factors(pp))) if decimation_factors(pp) else 1


def resolve_for_log(
    pp: PreprocessConfig, log: RobotLog
) -> tuple[PreprocessConfig, list[dict], list[str]]:
    """:func:`resolve_defaults` on the first segment of ``log``: the settings every segment
    of the log is then processed with, their records and warnings."""
    first = slice(*log.segments[0])
    return resolve_defaults(
        pp, log.q[first], log.sampling_rate_hz, None if log.dq is None else log.dq[first]
    )


def resolve_defaults(
    pp: PreprocessConfig,
    q: FloatArray,
    sampling_rate_hz: float,
    dq_logged: FloatArray | None = None,
) -> tuple[PreprocessConfig, list[dict], list[str]]:
    """The preprocessing settings with ``auto`` replaced, their records and warnings.

    Parameters
    ----------
    pp :
        The ``preprocess`` section (:class:`~ident.identify.config.PreprocessConfig`).
    q :
        Raw joint positions [rad], shape (n_samples, n_joints), uniformly sampled.
    sampling_rate_hz :
        Sampling rate [Hz].
    dq_logged :
        Logged velocities [rad/s] of the same shape, or None: checked against the
        differentiated (filtered) positions.

    Returns
    -------
    :
        ``(settings, records, warnings)``: a PreprocessConfig without ``auto``, records for
        the report and plain-language warnings for the result.
    """
    fs = sampling_rate_hz
    # the spectrum of every joint, once: the automatic settings and the alias warning
    estimated_band, high = _spectral_summary(q, fs)
    update, records = _auto_settings(pp, estimated_band, fs)
    cutoff = update.get("lowpass", pp.lowpass)
    cutoff_hz = cutoff.cutoff_hz if isinstance(cutoff, FilterConfig) else None
    warnings: list[str] = []
    if cutoff is None:
        warnings.append(
            "positions are not low-pass filtered (preprocess.lowpass: null): accelerations from "
            "raw encoder steps amplify noise; remove the line to get a filter chosen from the "
            "excitation band."
        )
    warnings += _alias_warnings(high, fs)
    if dq_logged is not None:
        record, problems = _velocity_check(q, dq_logged, fs, cutoff_hz)
        records.append(record)
        warnings += problems
    return pp.model_copy(update=update), records, warnings


def _auto_settings(
    pp: PreprocessConfig, estimated_band: float, fs: float
) -> tuple[dict[str, object], list[dict]]:
    """The ``auto`` low-pass and decimation chosen from the excitation band (the configured
    one, else ``estimated_band`` [Hz], :func:`excitation_band`), and records."""
    records: list[dict] = []
    band = pp.excitation_band_hz
    band_note = "configured"
    if band is None and (pp.lowpass == "auto" or pp.decimation == "auto"):
        band = estimated_band
        band_note = "estimated: 99.9 % of the positions' power"
    update: dict[str, object] = {}
    cutoff_hz = pp.lowpass.cutoff_hz if isinstance(pp.lowpass, FilterConfig) else None
    if pp.lowpass == "auto" and band is not None:
        cutoff_hz = min(CUTOFF_PER_BAND * band, 0.25 * fs)
        update["lowpass"] = FilterConfig(cutoff_hz=cutoff_hz, order=4)
        records.append(
            {
                "step": "auto settings",
                "detail": f"low-pass cutoff {cutoff_hz:.4g} Hz = min({CUTOFF_PER_BAND:g} x "
                f"excitation band {band:.4g} Hz ({band_note}), fs/4)",
            }
        )
    if pp.decimation == "auto" and band is not None:
        target = RATE_PER_CUTOFF * (cutoff_hz if cutoff_hz is not None else 5.0 * band)
        factors = _stages(int(fs // target)) if target > 0 else []
        update["decimation"] = factors
        records.append(
            {
                "step": "auto settings",
                "detail": f"decimation {' x '.join(map(str, factors)) or 'none'}: keeps at least "
                f"{RATE_PER_CUTOFF:g} samples per period of {target / RATE_PER_CUTOFF:.4g} Hz "
                f"({fs:g} -> {fs / max(1, int(np.prod(factors) if factors else 1)):.4g} Hz)",
            }
        )
    return update, records


def _alias_warnings(high: FloatArray, fs: float) -> list[str]:
    """A warning when positions carry power above fs/4 (aliased motion or noise): ``high``,
    each joint's share of its power there (:func:`_spectral_summary`)."""
    aliased = np.flatnonzero(high > ALIAS_POWER)
    if not aliased.size:
        return []
    return [
        f"joint(s) {', '.join(str(j + 1) for j in aliased)}: positions have "
        f"{100 * float(high[aliased].max()):.2g} % of their power above fs/4 = {fs / 4:g} Hz: "
        "the motion is too fast for the sampling rate (aliased) or the positions are noisy; "
        "log faster or check the encoder signal."
    ]


def _velocity_check(
    q: FloatArray, dq_logged: FloatArray, fs: float, cutoff_hz: float | None
) -> tuple[dict, list[str]]:
    """Logged velocities against the differentiated positions: the record and warnings."""
    from ident.measure.timebase import velocity_mismatch

    qf, dqf = q, dq_logged
    if cutoff_hz is not None and cutoff_hz < 0.5 * fs:
        qf, _ = lowpass(q, fs, cutoff_hz, 4)
        dqf, _ = lowpass(dq_logged, fs, cutoff_hz, 4, what="dq")
    dq, _, _ = differentiate(qf, fs)
    mismatch = velocity_mismatch(dqf, dq)
    shown = ", ".join("still" if np.isnan(m) else str(round(float(m), 4)) for m in mismatch)
    record = {
        "step": "velocity check",
        "detail": "logged velocities vs differentiated positions, relative difference "
        f"per joint [{shown}]",
    }
    bad = np.flatnonzero(mismatch > VELOCITY_MISMATCH)
    if not bad.size:
        return record, []
    return record, [
        f"joint(s) {', '.join(str(j + 1) for j in bad)}: logged velocities differ from "
        f"the differentiated positions by {100 * float(mismatch[bad].max()):.3g} %: check "
        "the velocity columns' unit, sign, side (gear ratio) and their time alignment."
    ]
