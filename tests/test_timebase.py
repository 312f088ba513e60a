"""Time stamps as controllers log them: resampling error on known jitter, gaps, windows."""

import numpy as np
import pytest

from ident.errors import DataError
from ident.measure import timebase

FS = 1000.0
FREQS = np.array([1.0, 3.7, 11.0, 23.0])  # Hz, up to fs/43
AMPS = np.array([1.0, 0.5, 0.2, 0.05])


def _signal(t):
    return np.sin(2 * np.pi * np.outer(t, FREQS) + np.arange(4)) @ AMPS


def test_resampling_error_on_jittered_sum_of_sines():
    rng = np.random.default_rng(0)
    steps = (1.0 + rng.uniform(-0.25, 0.25, 4999)) / FS
    t = np.concatenate([[0.0], np.cumsum(steps)])
    tg, xg = timebase.resample(t, _signal(t)[:, None], FS)
    np.testing.assert_allclose(np.diff(tg), 1.0 / FS, rtol=1e-9)
    error = np.max(np.abs(xg[:, 0] - _signal(tg)))
    # the documented bound: A 5/384 (2 pi f h_max)^4, summed over the components
    bound = np.sum(AMPS * 5.0 / 384.0 * (2 * np.pi * FREQS * 1.25 / FS) ** 4)
    assert error < bound
    assert error < 1e-5
    # linear interpolation would be far worse: the spline is what the bound says
    linear = np.max(np.abs(np.interp(tg, t, _signal(t)) - _signal(tg)))
    assert linear > 100 * error


def test_uniform_check_and_increasing():
    t = np.arange(100) / FS
    assert timebase.is_uniform(t)
    t2 = t.copy()
    t2[50:] += 0.2e-3
    assert not timebase.is_uniform(t2)
    t2[10] = t2[9]
    with pytest.raises(DataError, match="not strictly increasing at sample 10"):
        timebase.check_increasing(t2, "log")


def test_gaps_split_and_windows_select():
    t = np.concatenate([np.arange(100), 200 + np.arange(50)]) / FS
    segments = timebase.find_segments(t)
    assert segments == [(0, 100), (100, 150)]
    assert timebase.find_segments(t, max_gap_s=1.0) == [(0, 150)]
    windows = timebase.windows_to_segments(t, segments, [(0.01, 0.05), (0.21, None)])
    assert windows == [(10, 51), (110, 150)]
    assert timebase.windows_to_segments(t, segments, []) == segments
    summary = timebase.summarize_time(t)
    assert summary.n_gaps == 1
    assert summary.longest_gap_s == pytest.approx(0.101)
    assert summary.rate_hz == pytest.approx(FS)


def test_velocity_mismatch_flags_wrong_unit():
    t = np.arange(1000) / FS
    q = np.sin(2 * np.pi * t)[:, None] * [1.0, 1.0]
    dq_true = 2 * np.pi * np.cos(2 * np.pi * t)[:, None] * [1.0, 1.0]
    logged = dq_true * [1.0, 180 / np.pi]  # joint 2 logged in deg/s
    dq = np.gradient(q, 1 / FS, axis=0)
    mismatch = timebase.velocity_mismatch(logged, dq)
    assert mismatch[0] < 1e-3
    assert mismatch[1] > 10


def test_velocity_mismatch_of_a_still_joint_is_not_a_unit_error():
    t = np.arange(1000) / FS
    moving = np.sin(2 * np.pi * t)
    q = np.column_stack([moving, np.full_like(t, 0.3), np.full_like(t, -1.0)])
    dq = np.gradient(q, 1 / FS, axis=0)
    logged = dq.copy()
    logged[:, 1] += 1e-5 * np.cos(50 * t)  # velocity noise on a joint that does not move
    logged[:, 2] = 2 * np.pi * np.cos(2 * np.pi * t)  # joint 1's velocity in joint 3's column
    mismatch = timebase.velocity_mismatch(logged, dq)
    assert mismatch[0] < 1e-3
    assert np.isnan(mismatch[1])  # still: nothing to compare, no "check the unit" warning
    assert mismatch[2] == np.inf  # a velocity where the positions do not move: flagged


# ---------------------------------------------------------------------------------------------
# the time rule: NaN refused, duplicates dropped, backwards jumps split (one place, every reader


def test_backwards_jump_is_split_at_the_right_sample_and_named():
    # 1 kHz; at sample 600 the clock goes back 5 s (two runs appended)
    t = np.concatenate([10.0 + np.arange(600) / FS, 5.6 + np.arange(400) / FS])
    lines = np.arange(t.size) + 2  # a header on line 1
    cleaned = timebase.clean_time(t, "run.csv: time column 't'", lines)
    np.testing.assert_array_equal(cleaned.index, np.arange(t.size))  # nothing dropped
    assert np.all(np.diff(cleaned.t) > 0)  # never sorted: the parts follow each other
    np.testing.assert_array_equal(cleaned.t[:600], t[:600])
    np.testing.assert_allclose(np.diff(cleaned.t[600:]), 1.0 / FS, rtol=1e-9)  # own steps kept
    assert timebase.find_segments(cleaned.t) == [(0, 600), (600, 1000)]
    (warning,) = cleaned.warnings
    assert "time goes back 1 time(s) (largest jump 4.999 s)" in warning
    assert "first at line 602 (10.599 s then 5.6 s)" in warning
    assert "split there into 2 segments" in warning
    # without line numbers: the sample index
    (warning,) = timebase.clean_time(t, "x").warnings
    assert "first at sample 600" in warning


def test_parts_after_a_jump_stay_apart_under_a_large_gap_rule():
    t = np.concatenate([np.arange(100), np.arange(100) + 50.0]) / FS
    cleaned = timebase.clean_time(t, "x", gap_factor=500.0)  # gaps of 0.5 s still one segment
    segments = timebase.find_segments(cleaned.t, gap_factor=500.0)
    assert segments == [(0, 100), (100, 200)]


def test_duplicates_dropped_with_count_and_first_place():
    t = np.arange(20) / FS
    t = np.insert(t, [5, 5, 12], [t[4], t[4], t[11]])  # sample 4 three times, 11 twice
    cleaned = timebase.clean_time(t, "x")
    np.testing.assert_array_equal(cleaned.t, np.arange(20) / FS)
    assert cleaned.index.tolist() == [0, 1, 2, 3, 4, *range(7, 14), *range(15, 23)]
    (warning,) = cleaned.warnings
    assert "3 duplicated time stamp(s) dropped" in warning
    assert "first at sample 5 (t = 0.004 s)" in warning


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_stamps_refused_with_the_row(bad):
    t = np.arange(50) / FS
    t[[17, 30]] = bad
    with pytest.raises(
        DataError, match=r"2 time stamp\(s\) are NaN or infinite, the first at line 19"
    ):
        timebase.clean_time(t, "x", np.arange(50) + 2)
    summary = timebase.summarize_time(t)
    assert np.isfinite(summary.rate_hz)  # never "inf Hz"
    assert summary.rate_hz == pytest.approx(FS)
    assert summary.anomalies.n_nonfinite == 2
    assert "2 NaN/inf stamp(s), first at sample 17" in summary.text()


def test_summary_counts_every_anomaly():
    t = np.arange(100) / FS
    t[10] = t[9]  # duplicate
    t[50:] -= 0.2  # back
    summary = timebase.summarize_time(t)
    assert summary.rate_hz == pytest.approx(FS)
    assert not summary.uniform
    text = summary.text(np.arange(100) + 2)
    assert "1 duplicated stamp(s), first at line 12" in text
    assert "1 backwards jump(s) (largest 0.199 s), first at line 52" in text
    # all stamps equal: no rate, no inf
    flat = timebase.summarize_time(np.zeros(10))
    assert "no rate" in flat.text()
    assert "9 duplicated" in flat.text()


@pytest.mark.parametrize(("scale", "unit"), [(1e-9, "ns"), (1e6, "s")])
def test_implausible_rate_names_the_unit(scale, unit):
    t = np.arange(100) / FS * scale
    with pytest.raises(DataError, match=rf"read with unit {unit}.*check log.time.unit"):
        timebase.check_rate(t, "x", unit)
    assert timebase.check_rate(np.arange(100) / FS, "x") == pytest.approx(FS)
