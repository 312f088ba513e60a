import numpy as np
import pytest
from scipy import signal

from ident.errors import ConfigError, DataError
from ident.identify.estimation.preprocess import (
    decimate,
    differentiate,
    lowpass,
    trim,
    velocity_mask,
)


def test_lowpass_is_minus_6_db_at_cutoff_and_zero_phase():
    fs, fc = 1000.0, 20.0
    sos = signal.butter(4, fc, fs=fs, output="sos")
    _, h = signal.sosfreqz(sos, worN=[fc], fs=fs)
    assert 20 * np.log10(abs(h[0])) == pytest.approx(-3.0103, abs=1e-3)  # designed: -3 dB
    t = np.arange(20000) / fs
    x = np.sin(2 * np.pi * fc * t)
    y, record = lowpass(x[:, None], fs, fc, 4)
    middle = slice(5000, 15000)
    # forward-backward: gain |H|^2 = 1/2 (-6 dB), no phase lag
    assert np.max(np.abs(y[middle, 0] - 0.5 * x[middle])) < 1e-3
    assert record["cutoff_hz"] == fc
    slow = np.sin(2 * np.pi * 1.0 * t)
    y, _ = lowpass(slow[:, None], fs, fc, 4)
    assert np.max(np.abs(y[middle, 0] - slow[middle])) < 1e-6


def test_cutoff_above_nyquist_is_rejected():
    with pytest.raises(
        ConfigError, match=r"cutoff_hz = 300 Hz is not below the Nyquist frequency 250 Hz"
    ):
        lowpass(np.zeros((100, 2)), 500.0, 300.0)


def test_lowpass_too_short():
    with pytest.raises(DataError, match="too few"):
        lowpass(np.zeros((10, 1)), 500.0, 10.0)


def test_differentiate_exact_on_polynomials():
    fs = 200.0
    t = np.arange(50) / fs
    q = np.column_stack([3 * t**2 - t + 1, -2 * t**2])
    dq, ddq, _ = differentiate(q, fs)
    np.testing.assert_allclose(dq, np.column_stack([6 * t - 1, -4 * t]), atol=1e-10)
    np.testing.assert_allclose(
        ddq, np.column_stack([np.full_like(t, 6), np.full_like(t, -4)]), atol=1e-7
    )


def test_trim():
    (a, b), record = trim([np.arange(10.0), np.arange(20.0).reshape(10, 2)], 2)
    np.testing.assert_array_equal(a, np.arange(2.0, 8.0))
    assert b.shape == (6, 2)
    with pytest.raises(DataError, match="removes all"):
        trim([np.arange(4.0)], 2)


def test_decimate_is_linear_and_keeps_slow_signals():
    # The model tau = W x survives decimation only if decimation is linear and applied alike.
    rng = np.random.default_rng(0)
    fs = 1000.0
    t = np.arange(5000) / fs
    W = np.stack([np.sin(2 * np.pi * f * t) for f in (0.5, 1.3, 2.1)], axis=1)[:, None, :]
    W = np.repeat(W, 2, axis=1) + 0.01 * rng.normal(size=(5000, 2, 3))
    x = np.array([1.0, -2.0, 0.5])
    tau = W @ x
    (tau_d, W_d), fs_d, record = decimate([tau, W], [10, 5], fs)
    assert fs_d == 20.0
    assert tau_d.shape == (100, 2)
    assert W_d.shape == (100, 2, 3)
    np.testing.assert_allclose(W_d @ x, tau_d, atol=1e-12)
    slow = np.sin(2 * np.pi * 0.5 * t)
    (slow_d,), _, _ = decimate([slow], [10, 5], fs)
    # passband ripple of two zero-phase stages: within +-1.2 % (0.05 dB per pass, centred)
    np.testing.assert_allclose(slow_d[10:-10], slow[::50][10:-10], atol=1.2e-2)
    assert "10 x 5" in record["detail"]


def test_decimate_too_short():
    with pytest.raises(DataError, match="too few"):
        decimate([np.zeros(20)], [10], 100.0)


def test_velocity_mask():
    dq = np.array([[0.1, -0.01], [-0.2, 0.5], [0.0, -0.6]])
    keep, record = velocity_mask(dq, [0.05, 0.1])
    np.testing.assert_array_equal(keep, [[True, False], [True, True], [False, True]])
    assert record["kept"] == [2, 2]
    keep, _ = velocity_mask(dq, None)
    assert keep.all()
    with pytest.raises(ConfigError, match="velocity_threshold has 1 values"):
        velocity_mask(dq, [0.1])


def test_motion_decimation_factor():
    from ident.identify.estimation.motion import decimation_factor

    assert decimation_factor(5000.0, 50.0) == 100
    assert decimation_factor(1000.0, 50.0) == 20
    assert decimation_factor(1000.0, 30.0) == 34  # 29.4 Hz: never above the limit
    assert decimation_factor(40.0, 50.0) == 1


def test_measured_motion_keeps_slow_angles_exactly():
    from ident.identify.estimation.motion import measured_motion

    fs = 5000.0
    t = 0.004 + np.arange(20000) / fs
    w = np.array([1.0, 2.0, 3.0]) * 2 * np.pi * 0.5  # 0.5, 1, 1.5 Hz
    q = 1.5 + np.sin(t[:, None] * w)  # an offset: a DC gain error would show
    dq = w * np.cos(t[:, None] * w)
    ddq = -(w**2) * np.sin(t[:, None] * w)
    tau = 10.0 * q
    traj, record = measured_motion(t, q, dq, ddq, tau, fs, ("a", "b", "c"))
    assert traj.joint_names == ("a", "b", "c")
    np.testing.assert_allclose(traj.t, t[::100])
    np.testing.assert_allclose(np.diff(traj.t), 0.02)
    exact = 1.5 + np.sin(traj.t[:, None] * w)
    # edges included (a log cut mid-motion): 2.5e-4 measured at the last sample
    np.testing.assert_allclose(traj.q, exact, atol=5e-4)
    inner = slice(10, -10)  # away from the forward-backward filter's edges: 1e-6 measured
    np.testing.assert_allclose(traj.q[inner], exact[inner], atol=1e-5)
    np.testing.assert_allclose(traj.dq[inner], (w * np.cos(traj.t[:, None] * w))[inner], atol=1e-4)
    np.testing.assert_allclose(traj.tau[inner], 10.0 * exact[inner], atol=1e-4)
    assert "20000 -> 200 samples" in record["detail"]
    assert "5000 -> 50 Hz" in record["detail"]


def test_measured_motion_too_short_log():
    from ident.identify.estimation.motion import measured_motion

    x = np.zeros((20, 2))
    with pytest.raises(DataError, match="measured motion: 20 samples are too few"):
        measured_motion(np.arange(20) / 5000.0, x, x, x, x, 5000.0, ("a", "b"))


# --- automatic settings and data warnings (preprocess.resolve_defaults) -----------------------

from ident.identify.config import PreprocessConfig  # noqa: E402
from ident.identify.estimation import preprocess  # noqa: E402


def _motion(fs=1000.0, seconds=20.0, f=0.5):
    t = np.arange(int(fs * seconds)) / fs
    q = np.column_stack([np.sin(2 * np.pi * f * t), 0.5 * np.cos(2 * np.pi * 2 * f * t)])
    dq = (
        2 * np.pi * f * np.column_stack([np.cos(2 * np.pi * f * t), -np.sin(2 * np.pi * 2 * f * t)])
    )
    return t, q, dq


def test_auto_settings_follow_the_excitation_band():
    _, q, _ = _motion()
    settings, records, warnings = preprocess.resolve_defaults(PreprocessConfig(), q, 1000.0)
    band = preprocess.excitation_band(q, 1000.0)
    assert 0.9 < band < 1.2  # the 1 Hz harmonic of joint 2
    assert settings.lowpass.cutoff_hz == pytest.approx(5.0 * band)
    factor = int(np.prod(settings.decimation))  # 1000 Hz -> >= 4 x cutoff, stages <= 10
    assert max(settings.decimation) <= 10
    assert 1000.0 / factor >= 4 * settings.lowpass.cutoff_hz
    assert factor >= 20
    assert [r["step"] for r in records] == ["auto settings", "auto settings"]
    assert "low-pass cutoff" in records[0]["detail"]
    assert warnings == []


def test_explicit_settings_are_kept_and_unfiltered_warns():
    _, q, _ = _motion()
    explicit = PreprocessConfig(lowpass={"cutoff_hz": 25.0}, decimation=[10, 10])
    settings, records, warnings = preprocess.resolve_defaults(explicit, q, 1000.0)
    assert settings == explicit
    assert records == []
    assert warnings == []
    _, _, warnings = preprocess.resolve_defaults(
        PreprocessConfig(lowpass=None, decimation=[]), q, 1000.0
    )
    (w,) = warnings
    assert w.startswith("positions are not low-pass filtered")


def test_aliased_positions_warn():
    t, q, _ = _motion()
    q = q.copy()
    q[:, 1] += 0.05 * np.sin(2 * np.pi * 400.0 * t)  # content near Nyquist
    _, _, warnings = preprocess.resolve_defaults(PreprocessConfig(), q, 1000.0)
    (w,) = warnings
    assert w.startswith("joint(s) 2: positions have")
    assert "aliased" in w


def test_logged_velocity_checked():
    _, q, dq = _motion()
    _, records, warnings = preprocess.resolve_defaults(PreprocessConfig(), q, 1000.0, dq)
    assert warnings == []
    assert records[-1]["step"] == "velocity check"
    wrong = dq * [1.0, 180.0 / np.pi]  # joint 2 logged in deg/s
    _, _, warnings = preprocess.resolve_defaults(PreprocessConfig(), q, 1000.0, wrong)
    (w,) = warnings
    assert w.startswith("joint(s) 2: logged velocities differ")
