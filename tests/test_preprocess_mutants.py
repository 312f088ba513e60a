"""Preprocessing (ident.identify.estimation.preprocess) at its boundaries, against scipy and closed
forms.

What a user relies on: the filter is scipy's zero-phase Butterworth and refuses exactly the
logs scipy cannot pad; the decimation's passband is centred on 0 dB; the automatic settings
follow the documented rule (cutoff = 5 x band capped at fs/4, >= 4 samples per cutoff period,
stages of at most 10); the records the report prints state the numbers of what was done; the
errors name the setting and the fix. (Raised the mutation score of the module; see
benchmarks/mutation.py.)
"""

import numpy as np
import pytest
from scipy import signal

from ident.errors import ConfigError, DataError
from ident.identify.config import FilterConfig, PreprocessConfig
from ident.identify.estimation.preprocess import (
    DecimationStream,
    antialias_sos,
    decimate,
    decimation_factors,
    decimation_step,
    differentiate,
    excitation_band,
    lowpass,
    position_filter,
    resolve_defaults,
    trim,
    velocity_mask,
)

RIPPLE_DB = 0.05  # scipy.signal.decimate's Chebyshev I ripple


# ------------------------------------------------------------------------------- low-pass


@pytest.mark.parametrize("order", [2, 4, 6])
def test_lowpass_equals_scipy_down_to_the_shortest_log_scipy_pads(order):
    # scipy's default padding of sosfiltfilt: 3 (2 n_sections + 1) samples; a log must be longer
    fs, fc = 500.0, 12.0
    sos = signal.butter(order, fc, fs=fs, output="sos")
    padlen = 3 * (2 * len(sos) + 1)
    x = np.random.default_rng(order).normal(size=(padlen + 1, 2))
    y, record = lowpass(x, fs, fc, order, what="tau")
    np.testing.assert_allclose(y, signal.sosfiltfilt(sos, x, axis=0), rtol=1e-10, atol=1e-12)
    assert record == {
        "step": "low-pass tau",
        "detail": f"zero-phase Butterworth, order {order}, cutoff 12 Hz "
        "(-3 dB designed, -6 dB after sosfiltfilt) at 500 Hz",
        "cutoff_hz": 12.0,
        "order": order,
    }
    with pytest.raises(DataError) as err:
        lowpass(x[:padlen], fs, fc, order, what="tau")
    assert str(err.value) == (
        f"tau: {padlen} samples are too few for the order-{order} zero-phase filter "
        f"(needs more than {padlen})."
    )


@pytest.mark.parametrize("cutoff", [0.0, -1.0, 250.0])
def test_lowpass_refuses_a_cutoff_outside_zero_to_nyquist(cutoff):
    with pytest.raises(ConfigError) as err:
        lowpass(np.zeros((100, 1)), 500.0, cutoff)
    assert str(err.value) == (
        f"cutoff_hz = {cutoff:g} Hz is not below the Nyquist frequency 250 Hz of the sampling "
        "rate 500 Hz; choose a cutoff below 250 Hz."
    )
    y, _ = lowpass(np.ones((100, 1)), 500.0, 249.0)  # just below Nyquist: accepted
    np.testing.assert_allclose(y, 1.0, atol=1e-9)


# ------------------------------------------------------------------- differentiate, trim


def test_differentiate_three_samples_and_its_record():
    # a parabola is differentiated exactly even from the minimum of 3 samples (one-sided ends)
    fs = 10.0
    t = np.arange(3) / fs
    q = (2.0 * t**2 + t)[:, None]
    dq, ddq, record = differentiate(q, fs)
    np.testing.assert_allclose(dq[:, 0], 4.0 * t + 1.0, atol=1e-12)
    np.testing.assert_allclose(ddq[:, 0], 4.0, atol=1e-9)
    assert record == {
        "step": "differentiate",
        "detail": "central differences (np.gradient) to dq, ddq",
    }
    with pytest.raises(DataError) as err:
        differentiate(q[:2], fs)
    assert str(err.value) == "need at least 3 samples to differentiate, got 2."


def test_trim_boundaries_and_record():
    a = np.arange(5.0)
    (kept,), record = trim([a], 2)  # 2 x 2 < 5: one sample left
    np.testing.assert_array_equal(kept, [2.0])
    assert record == {"step": "trim", "detail": "dropped 2 samples at each end (5 -> 1)"}
    (same,), record = trim([a], 0)
    assert same is a
    assert record["detail"] == "dropped 0 samples at each end (5 -> 5)"
    with pytest.raises(DataError) as err:
        trim([np.arange(4.0)], 2)
    assert str(err.value) == "trim_samples = 2 removes all 4 samples; lower it."


# ---------------------------------------------------------------------------- decimation


@pytest.mark.parametrize("factor", [2, 5, 10])
def test_antialias_filter_passband_is_centred_on_0_db(factor):
    sos = antialias_sos(factor)
    # scipy.signal.decimate's design (Chebyshev I, order 8, 0.05 dB, edge 0.8 / factor)
    reference = signal.cheby1(8, RIPPLE_DB, 0.8 / factor, output="sos")
    np.testing.assert_allclose(sos[:, 3:], reference[:, 3:], rtol=1e-12)  # same poles
    np.testing.assert_allclose(sos[1:], reference[1:], rtol=1e-12)  # one section rescaled
    w = np.linspace(0.0, 0.8 / factor, 400) * np.pi
    _, h = signal.sosfreqz(sos, worN=w)
    gain_db = 20 * np.log10(np.abs(h))
    # DC at the ripple's minimum, -0.025 dB; the peaks at +0.025 dB; the band edge as DC
    assert gain_db[0] == pytest.approx(-RIPPLE_DB / 2, abs=1e-9)
    assert gain_db.max() == pytest.approx(RIPPLE_DB / 2, abs=2e-4)
    assert gain_db.min() == pytest.approx(-RIPPLE_DB / 2, abs=1e-6)
    assert gain_db[-1] == pytest.approx(-RIPPLE_DB / 2, abs=1e-6)


def test_decimate_constant_exactly_and_the_shortest_stage():
    # a constant stays constant at every sample (odd padding), scaled by the DC gain of the
    # two passes per stage: 10^(-0.05/20) per stage
    n = 28  # an order-8 filter (4 sections) needs more than 3 (2 x 4 + 1) = 27 samples
    x = np.full((n, 2), 3.0)
    (y,), fs, record = decimate([x], [2], 100.0)
    assert fs == 50.0
    assert y.shape == (14, 2)
    np.testing.assert_allclose(y, 3.0 * 10 ** (-RIPPLE_DB / 20), rtol=1e-10)
    assert record == {
        "step": "decimate",
        "detail": "zero-phase decimation by 2 (Chebyshev I order 8, ripple centred on 0 dB, "
        "forward-backward) of torques and regressor rows alike: 28 -> 14 samples, "
        "100 -> 50 Hz",
    }
    with pytest.raises(DataError) as err:
        decimate([x[:27]], [2], 100.0)
    assert str(err.value) == (
        "decimation by 2: only 27 samples left, too few for the zero-phase anti-aliasing "
        "filter; use a longer log or less decimation."
    )


def test_decimation_stream_equals_decimate_in_stages():
    """Rows pushed a block at a time, as a chunk's regressor: equal to the whole array's
    decimation; the second stage's too-short error is decimate's."""
    x = np.random.default_rng(5).normal(size=(200_003, 4)).cumsum(axis=0)
    (whole,), _, _ = decimate([x], [10, 1, 2], 1000.0)
    stream = DecimationStream([10, 1, 2], 4)
    parts = [stream.push(x[a : a + 2048]) for a in range(0, x.shape[0], 2048)]
    y = np.concatenate([*parts, stream.finish()])
    assert y.shape == whole.shape
    np.testing.assert_allclose(y, whole, rtol=0, atol=1e-13 * np.abs(whole).max())
    assert not DecimationStream([], 4).stages  # no factor: rows pass as they are
    short = DecimationStream([2, 2], 1)
    short.push(np.ones((53, 1)))  # 27 rows after the first stage: too few for the second
    with pytest.raises(DataError) as err:
        short.finish()
    with pytest.raises(DataError) as ref:
        decimate([np.ones((53, 1))], [2, 2], 100.0)
    assert str(err.value) == str(ref.value)


def test_decimate_keeps_every_factor_th_sample_from_the_first():
    # a slow ramp: the filtered samples kept are those at 0, 4, 8, ... (ramp values at those
    # times, to the passband gain), not shifted by one
    t = np.arange(400.0)
    x = np.column_stack([np.sin(2 * np.pi * t / 400.0), t / 400.0])
    (y,), fs, _ = decimate([x], [4], 1000.0)
    assert fs == 250.0
    assert y.shape == (100, 2)
    inner = slice(10, -10)  # a sample late would be off by 4e-3 (sine) and 2.5e-3 (ramp)
    dc = 10 ** (-RIPPLE_DB / 20)
    np.testing.assert_allclose(y[inner], dc * x[::4][inner], atol=5e-4)


def test_decimate_factor_one_and_no_factor_leave_the_data():
    x = np.arange(30.0).reshape(10, 3)
    (y,), fs, record = decimate([x], [1, 1], 100.0)
    assert y is x
    assert fs == 100.0
    assert "by 1 x 1 " in record["detail"]
    (y,), fs, record = decimate([x], [], 100.0)
    assert y is x
    assert "decimation by 1 " in record["detail"]
    assert record["detail"].endswith("10 -> 10 samples, 100 -> 100 Hz")


def test_decimate_stages_divide_the_rate_in_turn():
    x = np.random.default_rng(1).normal(size=(3000, 2, 2))
    (y,), fs, record = decimate([x], [5, 3], 3000.0)
    assert fs == 200.0
    assert y.shape == (200, 2, 2)
    assert "5 x 3" in record["detail"]
    assert record["detail"].endswith("3000 -> 200 samples, 3000 -> 200 Hz")


# -------------------------------------------------------------------------- velocity mask


def test_velocity_mask_keeps_a_speed_equal_to_its_threshold_and_says_so():
    dq = np.array([[0.1, -0.2], [-0.1, 0.05], [0.0999, 0.3]])
    keep, record = velocity_mask(dq, np.array([0.1, 0.2]))
    np.testing.assert_array_equal(keep, [[True, True], [True, False], [False, True]])
    assert record == {
        "step": "velocity threshold",
        "detail": "dropped the rows of joint j where abs(dq_j) < threshold_j [0.1, 0.2] rad/s; "
        "kept per joint [2, 2] of 3",
        "kept": [2, 2],
    }
    keep, record = velocity_mask(dq, None)
    assert keep.shape == (3, 2)
    assert keep.all()
    assert record == {"step": "velocity threshold", "detail": "none (all samples kept)"}
    with pytest.raises(ConfigError) as err:
        velocity_mask(dq, [0.1, 0.1, 0.1])
    assert str(err.value) == (
        "preprocess.velocity_threshold has 3 values, the robot has 2 joints; give one per "
        "joint [rad/s]."
    )


# ------------------------------------------------------------------------ excitation band


def test_excitation_band_of_a_sinusoid_and_of_still_joints():
    fs, n = 100.0, 2000  # bins of 0.05 Hz
    t = np.arange(n) / fs
    q = np.column_stack([np.sin(2 * np.pi * 2.0 * t), np.sin(2 * np.pi * 0.5 * t), 0 * t])
    band = excitation_band(q, fs)
    # the fastest joint's 2 Hz line, a few bins of window leakage above it; never the still one
    assert 2.0 <= band <= 2.3
    assert excitation_band(q[:, 1:], fs) <= 0.8
    # less energy, a lower band edge
    assert excitation_band(q[:, :1], fs, energy=0.5) == pytest.approx(2.0, abs=0.06)
    # nothing moves: the first bin above 0 Hz (fs / n)
    assert excitation_band(np.zeros((n, 2)), fs) == pytest.approx(fs / n)


# ---------------------------------------------------------------------- automatic settings


def test_auto_settings_cut_at_five_times_the_band_and_decimate_in_stages_of_ten():
    q = np.zeros((100, 1))
    pp = PreprocessConfig(excitation_band_hz=1.0)  # a configured band: q is not analysed
    settings, records, warnings = resolve_defaults(pp, q, 5000.0)
    assert settings.lowpass == FilterConfig(cutoff_hz=5.0, order=4)
    # >= 4 samples per period of 5 Hz: at most 5000 / 20 = 250 -> 10 x 10 x 2 = 200
    assert settings.decimation == [10, 10, 2]
    assert records == [
        {
            "step": "auto settings",
            "detail": "low-pass cutoff 5 Hz = min(5 x excitation band 1 Hz (configured), fs/4)",
        },
        {
            "step": "auto settings",
            "detail": "decimation 10 x 10 x 2: keeps at least 4 samples per period of 5 Hz "
            "(5000 -> 25 Hz)",
        },
    ]
    assert position_filter(settings) == FilterConfig(cutoff_hz=5.0, order=4)
    assert decimation_factors(settings) == [10, 10, 2]
    assert decimation_step(settings) == 200
    assert warnings == []  # filtered, nothing above fs/4


def preprocess_unfiltered_warning():
    return (
        "positions are not low-pass filtered (preprocess.lowpass: null): accelerations from "
        "raw encoder steps amplify noise; remove the line to get a filter chosen from the "
        "excitation band."
    )


@pytest.mark.parametrize(
    ("pp", "lowpass_hz", "factors"),
    [
        # a fast band: the cutoff is capped at fs/4 and nothing is decimated
        (PreprocessConfig(excitation_band_hz=60.0), 250.0, []),
        # the configured filter sets the rate: 4 x 20 Hz -> 1000 // 80 = 12 -> [10]
        (PreprocessConfig(excitation_band_hz=1.0, lowpass={"cutoff_hz": 20.0}), 20.0, [10]),
        # unfiltered: the rate follows 5 x band: 1000 // (4 x 5 x 2) = 25 -> [10, 2]
        (PreprocessConfig(excitation_band_hz=2.0, lowpass=None), None, [10, 2]),
        # a rate just at 4 samples per cutoff period: 1000 // 250 = 4 -> [4]
        (PreprocessConfig(excitation_band_hz=12.5), 62.5, [4]),
    ],
)
def test_auto_decimation_follows_the_cutoff(pp, lowpass_hz, factors):
    settings, _, warnings = resolve_defaults(pp, np.zeros((100, 1)), 1000.0)
    if lowpass_hz is None:
        assert settings.lowpass is None
        assert warnings == [preprocess_unfiltered_warning()]
    else:
        assert settings.lowpass.cutoff_hz == pytest.approx(lowpass_hz)
    assert settings.decimation == factors
    assert decimation_step(settings) == int(np.prod(factors))


def test_auto_settings_without_band_analyse_the_positions():
    fs = 200.0
    t = np.arange(4000) / fs
    q = np.sin(2 * np.pi * 1.0 * t)[:, None]
    settings, records, _ = resolve_defaults(PreprocessConfig(decimation=[]), q, fs)
    band = excitation_band(q, fs)
    assert settings.lowpass.cutoff_hz == pytest.approx(5.0 * band)
    assert settings.decimation == []
    (record,) = records
    assert "(estimated: 99.9 % of the positions' power)" in record["detail"]
    # decimation alone asks for the band too
    settings, records, _ = resolve_defaults(PreprocessConfig(lowpass=None), q, fs)
    # unfiltered: >= 4 samples per period of 5 x band (about 20 Hz at 200 Hz: about 10)
    assert settings.decimation == [int(fs // (20.0 * band))]
    assert 8 <= settings.decimation[0] <= 10
    assert "decimation" in records[0]["detail"]


def test_unresolved_auto_settings_are_refused():
    pp = PreprocessConfig()
    with pytest.raises(ConfigError) as err:
        position_filter(pp)
    assert str(err.value) == "preprocess.lowpass: 'auto' is resolved by resolve_defaults first."
    with pytest.raises(ConfigError) as err:
        decimation_factors(pp)
    assert str(err.value) == (
        "preprocess.decimation: 'auto' is resolved by resolve_defaults first."
    )
    assert decimation_step(PreprocessConfig(decimation=[])) == 1
    assert decimation_step(PreprocessConfig(decimation=[3, 7])) == 21


# ------------------------------------------------------------------------- data warnings


def _band_limited(fs, n, seed=0):
    t = np.arange(n) / fs
    rng = np.random.default_rng(seed)
    return np.column_stack([np.sin(2 * np.pi * 0.5 * t), np.cos(2 * np.pi * 0.7 * t)]), rng


def test_alias_warning_threshold_is_a_fraction_of_the_power_above_fs_over_4():
    fs, n = 1000.0, 10000
    q, _ = _band_limited(fs, n)
    t = np.arange(n) / fs
    pp = PreprocessConfig(lowpass={"cutoff_hz": 5.0}, decimation=[])
    # power share of a 300 Hz line of amplitude a next to a unit sine: a^2 / (1 + a^2)
    small = q.copy()
    small[:, 0] += 0.5e-2 * np.sin(2 * np.pi * 300.0 * t)  # 2.5e-5 of the power: below 1e-4
    assert resolve_defaults(pp, small, fs)[2] == []
    big = q.copy()
    big[:, 0] += 2e-2 * np.sin(2 * np.pi * 300.0 * t)  # 4e-4 of the power: above
    (w,) = resolve_defaults(pp, big, fs)[2]
    assert w == (
        "joint(s) 1: positions have 0.04 % of their power above fs/4 = 250 Hz: the motion is "
        "too fast for the sampling rate (aliased) or the positions are noisy; log faster or "
        "check the encoder signal."
    )


def test_velocity_check_record_and_threshold():
    fs, n = 500.0, 5000
    q, _ = _band_limited(fs, n)
    dq, _, _ = differentiate(q, fs)
    pp = PreprocessConfig(lowpass=None, decimation=[])
    _, records, warnings = resolve_defaults(pp, q, fs, dq)
    assert warnings == [preprocess_unfiltered_warning()]  # unfiltered: compared as logged
    assert records == [
        {
            "step": "velocity check",
            "detail": "logged velocities vs differentiated positions, relative difference "
            "per joint [0.0, 0.0]",
        }
    ]
    # 15 % off on joint 1 is tolerated, 30 % on joint 2 is not (VELOCITY_MISMATCH 20 %)
    _, records, warnings = resolve_defaults(pp, q, fs, dq * [1.15, 1.3])
    assert records[-1]["detail"].endswith("per joint [0.15, 0.3]")
    assert warnings[1:] == [
        "joint(s) 2: logged velocities differ from the differentiated positions by 30 %: "
        "check the velocity columns' unit, sign, side (gear ratio) and their time alignment."
    ]
    # with a filter, both are filtered alike: the 30 % still shows, 15 % still passes
    filtered = PreprocessConfig(lowpass={"cutoff_hz": 20.0}, decimation=[])
    _, records, warnings = resolve_defaults(filtered, q, fs, dq * [1.15, 1.3])
    mismatch = [float(v) for v in records[-1]["detail"].split("[")[1].rstrip("]").split(",")]
    assert mismatch == pytest.approx([0.15, 0.3], abs=1e-3)
    assert warnings == [
        "joint(s) 2: logged velocities differ from the differentiated positions by 30 %: "
        "check the velocity columns' unit, sign, side (gear ratio) and their time alignment."
    ]
