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
