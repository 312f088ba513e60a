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

Stamps as they really go wrong (one rule for every reader, applied by :func:`clean_time`)
----------------------------------------------------------------------------------------
- NaN or infinite stamp: refused, naming the row (line or sample) and the count;
- duplicated stamp (a step of exactly 0): the later sample is dropped, with a warning naming
  the count and the first place;
- backwards jump (a negative step: a clock reset, two runs appended): the log is split there
  into segments, each kept in its own order (never sorted, never interleaved); every later
  part is moved to start after the previous part's end plus a gap, so segments stay apart and
  windows read the continued time; a warning names the count and the first place;
- a rate above :data:`MAX_RATE_HZ` or below :data:`MIN_RATE_HZ` (a time unit mistaken, e.g.
  ``unit: ns`` on a seconds column): refused, naming the rate and the unit to check.

Missing stamps (ROS messages without ``header.stamp``) are handled where they are read
(:mod:`ident.measure.readers.ros`): the topic uses the time each message was recorded, with
a warning.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.interpolate import make_interp_spline

from ident.errors import DataError

__all__ = [
    "MAX_RATE_HZ",
    "MIN_RATE_HZ",
    "CleanTime",
    "TimeAnomalies",
    "TimingSummary",
    "check_rate",
    "clean_time",
    "find_anomalies",
    "find_segments",
    "is_uniform",
    "place",
    "resample",
    "split_segments",
    "summarize_time",
    "velocity_mismatch",
    "windows_to_segments",
]

FloatArray = npt.NDArray[np.float64]
Segment = tuple[int, int]  # sample indices [start, stop)

# Relative spread of the steps below which a time column counts as uniform.
UNIFORM_RTOL = 1e-3
GAP_FACTOR = 5.0
# Sampling rates a controller log can have; outside: a time unit mistaken (ns read as s, ...).
MAX_RATE_HZ = 1e6
MIN_RATE_HZ = 1e-2
IntArray = npt.NDArray[np.int64]


def place(k: int, line_numbers: npt.ArrayLike | None) -> str:
    """``line N`` of the file when known, else ``sample k`` (0-based)."""
    if line_numbers is not None:
        return f"line {int(np.asarray(line_numbers)[k])}"
    return f"sample {k}"


@dataclass(frozen=True)
class TimeAnomalies:
    """Stamps that break a strictly increasing time column (0-based sample indices).

    ``first_*`` is the index of the offending sample (the later one of a step), None when
    there is none.
    """

    n_nonfinite: int = 0
    first_nonfinite: int | None = None
    n_duplicates: int = 0
    first_duplicate: int | None = None
    n_backwards: int = 0
    first_backwards: int | None = None
    largest_backwards_s: float = 0.0

    @property
    def any(self) -> bool:
        """True when the column has any anomaly."""
        return bool(self.n_nonfinite or self.n_duplicates or self.n_backwards)

    def text(self, line_numbers: npt.ArrayLike | None = None) -> str:
        """The anomalies with counts and first places, ``;``-separated ("" when none)."""
        parts = []
        if self.n_nonfinite:
            assert self.first_nonfinite is not None
            parts.append(
                f"{self.n_nonfinite} NaN/inf stamp(s), first at "
                f"{place(self.first_nonfinite, line_numbers)}"
            )
        if self.n_duplicates:
            assert self.first_duplicate is not None
            parts.append(
                f"{self.n_duplicates} duplicated stamp(s), first at "
                f"{place(self.first_duplicate, line_numbers)}"
            )
        if self.n_backwards:
            assert self.first_backwards is not None
            parts.append(
                f"{self.n_backwards} backwards jump(s) (largest {self.largest_backwards_s:.4g} s), "
                f"first at {place(self.first_backwards, line_numbers)}"
            )
        return "; ".join(parts)


def find_anomalies(t: FloatArray) -> TimeAnomalies:
    """Count NaN/inf stamps, duplicated stamps and backwards jumps of ``t`` [s], (n_samples,).

    Steps are taken between consecutive finite stamps.
    """
    t = np.asarray(t, dtype=float)
    bad = np.flatnonzero(~np.isfinite(t))
    # every stamp finite (a log as written): the steps of t itself, without the index of the
    # finite stamps and their copy (two arrays of the column's size, 58 MB for an hour at 1 kHz)
    idx = np.flatnonzero(np.isfinite(t)) if bad.size else None
    dt = np.diff(t if idx is None else t[idx])
    dup = np.flatnonzero(dt == 0) + 1
    back = np.flatnonzero(dt < 0) + 1

    def stamp(k: int) -> int:
        return int(k if idx is None else idx[k])

    return TimeAnomalies(
        n_nonfinite=int(bad.size),
        first_nonfinite=int(bad[0]) if bad.size else None,
        n_duplicates=int(dup.size),
        first_duplicate=stamp(dup[0]) if dup.size else None,
        n_backwards=int(back.size),
        first_backwards=stamp(back[0]) if back.size else None,
        largest_backwards_s=float(-dt[back - 1].min()) if back.size else 0.0,
    )


@dataclass(frozen=True, eq=False)
class CleanTime:
    """A time column after the rule of the module docstring.

    Attributes
    ----------
    t :
        Strictly increasing time [s], shape (n_kept,); parts after a backwards jump moved
        to continue after the previous part (plus a gap).
    index :
        Rows of the input kept, in their order, shape (n_kept,).
    warnings :
        One sentence per anomaly handled (count and first place).
    """

    t: FloatArray
    index: IntArray
    warnings: tuple[str, ...] = ()


def clean_time(
    t: FloatArray,
    source: str,
    line_numbers: npt.ArrayLike | None = None,
    *,
    gap_factor: float = GAP_FACTOR,
    max_gap_s: float | None = None,
) -> CleanTime:
    """Apply the time rule (module docstring) to the time column ``t`` [s], (n_samples,).

    Parameters
    ----------
    t :
        Stamps as logged [s].
    source :
        File and column for messages (``run.csv: time column 't'``).
    line_numbers :
        File line of each sample, for messages (else sample indices are named).
    gap_factor, max_gap_s :
        The gap rule of :func:`find_segments`; parts after a backwards jump are moved apart by
        more than it, so they become separate segments.

    Raises
    ------
    DataError
        For NaN/inf stamps (naming the first row and the count), or fewer than 2 stamps left.
    """
    t = np.asarray(t, dtype=float)
    found = find_anomalies(t)
    _refuse_nonfinite(t, found, source, line_numbers)
    index = np.arange(t.size, dtype=np.int64)
    warnings = []
    if not found.any:  # nothing to clean: t itself, not a copy of it (t[index] is t)
        if t.size < 2:
            raise DataError(f"{source}: fewer than 2 distinct time stamps; the log has no timing.")
        return CleanTime(t=t, index=index)
    if found.n_duplicates:
        keep = np.concatenate([[True], np.diff(t) != 0])
        index = index[keep]
        k = found.first_duplicate
        assert k is not None
        warnings.append(
            f"{source}: {found.n_duplicates} duplicated time stamp(s) dropped (the later sample "
            f"of each pair), the first at {place(k, line_numbers)} (t = {t[k]:.9g} s)"
        )
    tk = t[index]
    if found.n_backwards:
        tk = _parts_apart(tk, gap_factor, max_gap_s)
        k = found.first_backwards
        assert k is not None
        warnings.append(
            f"{source}: time goes back {found.n_backwards} time(s) (largest jump "
            f"{found.largest_backwards_s:.4g} s), the first at {place(k, line_numbers)} "
            f"({t[k - 1] if k else t[k]:.9g} s then {t[k]:.9g} s); the log is split there "
            f"into {found.n_backwards + 1} segments, each in its own order"
        )
    if tk.size < 2:
        raise DataError(f"{source}: fewer than 2 distinct time stamps; the log has no timing.")
    return CleanTime(t=tk, index=index, warnings=tuple(warnings))


def _refuse_nonfinite(
    t: FloatArray, found: TimeAnomalies, source: str, line_numbers: npt.ArrayLike | None
) -> None:
    """Raise a DataError naming the count and the first NaN/inf stamp of ``t`` [s], if any
    (``found`` its anomalies)."""
    if found.n_nonfinite:
        k = found.first_nonfinite
        assert k is not None
        raise DataError(
            f"{source}: {found.n_nonfinite} time stamp(s) are NaN or infinite, the first at "
            f"{place(k, line_numbers)} ({t[k]}); remove or repair those rows."
        )


def _parts_apart(tk: FloatArray, gap_factor: float, max_gap_s: float | None) -> FloatArray:
    """The distinct stamps ``tk`` [s], (n,), with each part after a backwards jump moved to
    start a gap after the previous part's end: more than the gap rule of :func:`find_segments`
    (``gap_factor`` times the median forward step, ``max_gap_s``) and at least 1 s, so that
    every part becomes its own segment."""
    dt = np.diff(tk)
    cuts = np.flatnonzero(dt < 0) + 1
    forward = dt[dt > 0]
    step = float(np.median(forward)) if forward.size else 1.0
    gap = max(1.0, 2.0 * gap_factor * step, 2.0 * (max_gap_s or 0.0))
    shift = np.zeros(tk.size)
    bounds = [0, *cuts.tolist(), tk.size]
    offset = 0.0
    for a, b in zip(bounds[1:-1], bounds[2:], strict=True):
        offset += tk[a - 1] - tk[a] + gap  # part starts gap after the previous end
        shift[a:b] = offset
    return tk + shift


def check_rate(t: FloatArray, source: str, unit: str = "s") -> float:
    """The median rate [Hz] of the increasing time ``t`` [s]; refuse an implausible one.

    Raises
    ------
    DataError
        If the rate is above :data:`MAX_RATE_HZ` or below :data:`MIN_RATE_HZ` (the message
        names the unit to check).
    """
    dt = np.diff(t)
    rate = 1.0 / float(np.median(dt)) if dt.size else float("nan")
    if not (MIN_RATE_HZ <= rate <= MAX_RATE_HZ):
        raise DataError(
            f"{source}: read with unit {unit}, the stamps give a rate of {rate:.4g} Hz (median "
            f"step {1.0 / rate if rate else float('inf'):.4g} s), outside {MIN_RATE_HZ:g} to "
            f"{MAX_RATE_HZ:g} Hz; check log.time.unit (s, ms, us, ns) against the column."
        )
    return rate


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
    return _steps_uniform(dt, float(np.median(dt)), rtol)


def _steps_uniform(dt: FloatArray, step: float, rtol: float = UNIFORM_RTOL) -> bool:
    """:func:`is_uniform`'s rule on the steps ``dt`` (n,) [s] of a column, ``step`` their
    median [s]: every step within ``rtol`` of it."""
    return bool(_largest_deviation(dt, step) <= rtol * step)


def _largest_deviation(x: FloatArray, c: float) -> float:
    """``max |x - c|`` of ``x`` (n,) from its extremes, without the two temporaries of ``x``'s
    size: ``x - c`` rounds monotonically in ``x`` and ``c - x`` is its exact negative, so the
    result is the same, bit for bit."""
    return float(max(x.max() - c, c - x.min()))


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


def split_segments(segments: list[Segment], starts: list[int]) -> list[Segment]:
    """``segments`` cut at the sample indices ``starts`` (where a recording starts: an episode
    of a dataset), whatever the time between says."""
    out: list[Segment] = []
    for a, b in segments:
        bounds = [a, *sorted({int(c) for c in starts if a < c < b}), b]
        out += list(zip(bounds[:-1], bounds[1:], strict=True))
    return out


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
    anomalies: TimeAnomalies = TimeAnomalies()

    def text(self, line_numbers: npt.ArrayLike | None = None) -> str:
        """One line (anomalies with counts and first places at its end)."""
        gaps = (
            f"{self.n_gaps} gap(s), longest {self.longest_gap_s:.4g} s"
            if self.n_gaps
            else "no gaps"
        )
        rate = f"{self.rate_hz:.6g} Hz" if np.isfinite(self.rate_hz) else "no rate"
        anomalies = self.anomalies.text(line_numbers)
        return (
            f"{self.n_samples} samples over {self.duration_s:.4g} s, {rate} "
            f"(median step), jitter max {self.jitter_pct:.3g} % / std "
            f"{self.jitter_std_pct:.3g} % of the step, {gaps}"
            + ("" if self.uniform else ", non-uniform")
            + (f"; {anomalies}" if anomalies else "")
        )


def summarize_time(t: FloatArray, *, gap_factor: float = GAP_FACTOR) -> TimingSummary:
    """Rate, jitter, gaps and anomalies of a time column [s], shape (n_samples,).

    Rate, jitter and gaps are those of the forward steps between finite stamps; NaN/inf
    stamps, duplicates and backwards jumps are counted in :attr:`TimingSummary.anomalies`.
    """
    t = np.asarray(t, dtype=float)
    anomalies = find_anomalies(t)
    # copies only where stamps are dropped (a log as written has none to drop)
    finite = t[np.isfinite(t)] if anomalies.n_nonfinite else t
    dt = np.diff(finite)
    if anomalies.any:
        dt = dt[dt > 0]
    if dt.size == 0:
        return TimingSummary(int(t.size), 0.0, float("nan"), 0.0, 0.0, 0, 0.0, True, anomalies)
    step = float(np.median(dt))
    gaps = dt > gap_factor * step
    inside = dt[~gaps] if gaps.any() and (~gaps).any() else dt
    return TimingSummary(
        n_samples=int(t.size),
        duration_s=float(dt.sum()),
        rate_hz=1.0 / step,
        jitter_pct=float(100.0 * _largest_deviation(inside, step) / step),
        jitter_std_pct=float(100.0 * np.std(inside) / step),
        n_gaps=int(gaps.sum()),
        longest_gap_s=float(dt[gaps].max()) if gaps.any() else 0.0,
        # is_uniform(finite) of a column without anomalies, from the steps already taken
        uniform=not anomalies.any and _steps_uniform(dt, step),
        anomalies=anomalies,
    )


#: RMS of a joint's velocity [rad/s] below which it is taken as still (0.06 deg/s).
STILL_RMS = 1e-3


def velocity_mismatch(dq_logged: FloatArray, dq_derived: FloatArray) -> FloatArray:
    """Per joint ``||dq_logged - dq_derived|| / ||dq_derived||``, shape (n_joints,).

    Both [rad/s], shape (n_samples, n_joints); a logged velocity on another side, unit or sign
    than the positions shows up as a mismatch near or above 1. A still joint (both RMS below
    :data:`STILL_RMS`) has no motion to compare: NaN. A logged velocity on a joint whose
    positions do not move is ``inf`` (a column of another joint, or a wrong unit).
    """
    n = max(dq_derived.shape[0], 1)
    num = np.linalg.norm(dq_logged - dq_derived, axis=0)
    den = np.linalg.norm(dq_derived, axis=0)
    still = den / np.sqrt(n) < STILL_RMS
    logged_still = np.linalg.norm(dq_logged, axis=0) / np.sqrt(n) < STILL_RMS
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(den > 0, num / den, np.inf)
    return np.where(still, np.where(logged_still, np.nan, np.inf), ratio)
