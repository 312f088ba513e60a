"""Time as it comes: checks, gaps, windows and resampling of logged time stamps.

Controllers rarely log on a perfect clock: steps jitter (a 1 kHz loop logging 0.7 to 1.3 ms),
samples are dropped (gaps), and only parts of a log are worth identifying (windows). Filtering,
differentiation and decimation assume a uniform grid, so a log is cut into *segments* without
gaps, and each non-uniform segment is resampled onto a uniform grid once, here.

Resampling method
-----------------
Not-a-knot cubic spline through the samples (``scipy.interpolate.make_interp_spline``, k=3),
evaluated on the uniform grid ``t0, t0 + h, ...`` (``h`` = the median step unless a rate is
given). For a signal with a bounded fourth derivative the interpolation error is at most
``5/384 * h_max^4 * max|x''''|`` (de Boor); for a sinusoid of frequency ``f`` and amplitude
``A`` that is ``A * 5/384 * (2 pi f h_max)^4``: with ``f = fs/20`` and steps up to 1.25 times
the nominal (+-25 % jitter) about ``3e-4 A``, and ``1e-7 A`` at ``f = fs/100``, the band an
identification uses. Noise is interpolated as well (a spline does not filter); the low-pass
that follows does. A jump is not band-limited: the Coulomb torque's step at a velocity
reversal is smeared over one step and rings for two or three, so drop the rows near zero
velocity (``preprocess.velocity_threshold``); with it a log with +-25 % jitter identifies as
well as its uniformly sampled twin (tests/test_logs_examples.py).

A gap is a step longer than ``gap_factor`` times the median step (default 5) or than
``max_gap_s`` when given; each side becomes its own segment and no sample is invented in it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.interpolate import make_interp_spline

from ident.errors import DataError

__all__ = [
    "TimingSummary",
    "find_segments",
    "is_uniform",
    "resample",
    "summarize_time",
    "velocity_mismatch",
    "windows_to_segments",
]

FloatArray = npt.NDArray[np.float64]
Segment = tuple[int, int]  # sample indices [start, stop)

# Relative spread of the steps below which a time column counts as uniform.
UNIFORM_RTOL = 1e-3
GAP_FACTOR = 5.0


def check_increasing(t: FloatArray, source: str, line_numbers: npt.ArrayLike | None = None) -> None:
    """Raise DataError naming the first sample where ``t`` does not increase."""
    dt = np.diff(t)
    bad = np.flatnonzero(~(dt > 0))
    if bad.size:
        k = int(bad[0])
        where = (
            f"line {int(np.asarray(line_numbers)[k + 1])}"
            if line_numbers is not None
            else f"sample {k + 1}"
        )
        raise DataError(
            f"{source} is not strictly increasing at {where} ({t[k]:g} s then {t[k + 1]:g} s); "
            "sort or clean the log."
        )


def is_uniform(t: FloatArray, rtol: float = UNIFORM_RTOL) -> bool:
    """True when every step is within ``rtol`` of the median step."""
    dt = np.diff(t)
    if dt.size == 0:
        return True
    step = float(np.median(dt))
    return bool(np.max(np.abs(dt - step)) <= rtol * step)


def find_segments(
    t: FloatArray, *, gap_factor: float = GAP_FACTOR, max_gap_s: float | None = None
) -> list[Segment]:
    """Split at steps longer than ``max_gap_s`` (or ``gap_factor`` median steps).

    Parameters
    ----------
    t :
        Strictly increasing time [s], shape (n_samples,).

    Returns
    -------
    :
        ``[(start, stop), ...]`` sample index ranges without gaps, in time order.
    """
    dt = np.diff(t)
    if dt.size == 0:
        return [(0, t.size)]
    limit = max_gap_s if max_gap_s is not None else gap_factor * float(np.median(dt))
    cuts = np.flatnonzero(dt > limit) + 1
    bounds = [0, *cuts.tolist(), t.size]
    return [(a, b) for a, b in zip(bounds[:-1], bounds[1:], strict=True) if b > a]


def windows_to_segments(
    t: FloatArray, segments: list[Segment], windows: list[tuple[float | None, float | None]]
) -> list[Segment]:
    """Intersect segments with time windows ``[(start_s, end_s), ...]`` (None: open end).

    Times are those of ``t`` (the log's time relative to its first sample). An empty list of
    windows keeps the segments.
    """
    if not windows:
        return list(segments)
    out: list[Segment] = []
    for start_s, end_s in windows:
        lo = -np.inf if start_s is None else start_s
        hi = np.inf if end_s is None else end_s
        i0 = int(np.searchsorted(t, lo, side="left"))
        i1 = int(np.searchsorted(t, hi, side="right"))
        for a, b in segments:
            a2, b2 = max(a, i0), min(b, i1)
            if b2 > a2:
                out.append((a2, b2))
    return out


def resample(
    t: FloatArray, x: FloatArray, sampling_rate_hz: float | None = None
) -> tuple[FloatArray, FloatArray]:
    """Resample ``x(t)`` onto a uniform grid by a not-a-knot cubic spline (module docstring).

    Parameters
    ----------
    t :
        Strictly increasing time [s], shape (n_samples,).
    x :
        Signals, shape (n_samples, ...).
    sampling_rate_hz :
        Rate of the grid [Hz]; default the inverse of the median step.

    Returns
    -------
    :
        Uniform time ``t0 + k / rate`` within ``[t0, t_end]`` and the resampled signals.
    """
    if t.size < 4:
        raise DataError(f"need at least 4 samples to resample, got {t.size}.")
    rate = sampling_rate_hz if sampling_rate_hz is not None else 1.0 / float(np.median(np.diff(t)))
    n = int(np.floor((t[-1] - t[0]) * rate * (1.0 + 1e-12))) + 1
    grid = t[0] + np.arange(n) / rate
    spline = make_interp_spline(t, x, k=3, axis=0)
    return grid, spline(grid)


@dataclass(frozen=True)
class TimingSummary:
    """What a time column looks like (for ``ident logs inspect`` and the records)."""

    n_samples: int
    duration_s: float
    rate_hz: float  # inverse of the median step
    jitter_pct: float  # largest deviation of a step from the median [% of the median]
    jitter_std_pct: float  # standard deviation of the steps [% of the median]
    n_gaps: int
    longest_gap_s: float
    uniform: bool

    def text(self) -> str:
        """One line."""
        gaps = (
            f"{self.n_gaps} gap(s), longest {self.longest_gap_s:.4g} s"
            if self.n_gaps
            else "no gaps"
        )
        return (
            f"{self.n_samples} samples over {self.duration_s:.4g} s, {self.rate_hz:.6g} Hz "
            f"(median step), jitter max {self.jitter_pct:.3g} % / std "
            f"{self.jitter_std_pct:.3g} % of the step, {gaps}"
            + ("" if self.uniform else ", non-uniform")
        )


def summarize_time(t: FloatArray, *, gap_factor: float = GAP_FACTOR) -> TimingSummary:
    """Rate, jitter and gaps of a time column [s], shape (n_samples,)."""
    dt = np.diff(t)
    if dt.size == 0:
        return TimingSummary(int(t.size), 0.0, float("nan"), 0.0, 0.0, 0, 0.0, True)
    step = float(np.median(dt))
    gaps = dt > gap_factor * step
    inside = dt[~gaps] if (~gaps).any() else dt
    return TimingSummary(
        n_samples=int(t.size),
        duration_s=float(t[-1] - t[0]),
        rate_hz=1.0 / step if step > 0 else float("inf"),
        jitter_pct=float(100.0 * np.max(np.abs(inside - step)) / step) if step > 0 else 0.0,
        jitter_std_pct=float(100.0 * np.std(inside) / step) if step > 0 else 0.0,
        n_gaps=int(gaps.sum()),
        longest_gap_s=float(dt[gaps].max()) if gaps.any() else 0.0,
        uniform=is_uniform(t),
    )


def velocity_mismatch(dq_logged: FloatArray, dq_derived: FloatArray) -> FloatArray:
    """Per joint ``||dq_logged - dq_derived|| / ||dq_derived||``, shape (n_joints,).

    Both [rad/s], shape (n_samples, n_joints); a logged velocity on another side, unit or sign
    than the positions shows up as a mismatch near or above 1.
    """
    num = np.linalg.norm(dq_logged - dq_derived, axis=0)
    den = np.linalg.norm(dq_derived, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(den > 0, num / den, np.inf)
