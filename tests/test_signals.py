"""ident.signals.sosfiltfilt: scipy's sosfiltfilt(sos, x, axis=0)[::step], compiled."""

import tracemalloc

import numpy as np
import pytest
from scipy import signal

from ident.signals import ZeroPhaseStream, sosfiltfilt


@pytest.mark.parametrize(
    "sos",
    [
        signal.cheby1(8, 0.05, 0.8 / 10, output="sos"),  # the decimation filter
        signal.butter(4, 0.02, output="sos"),  # a low-pass of the preprocessing
        signal.butter(3, 0.1, output="sos"),  # odd order: a first-order section (b2 = a2 = 0)
    ],
)
# (28, 2): one sample above the decimation filter's padding of 27, the extension reaches x[0]
@pytest.mark.parametrize(
    ("shape", "step"), [((500,), 1), ((400, 3), 10), ((301, 7, 5), 4), ((28, 2), 3)]
)
def test_equals_scipy_bit_for_bit(sos, shape, step):
    x = np.random.default_rng(0).normal(size=shape).cumsum(axis=0)
    np.testing.assert_array_equal(
        sosfiltfilt(sos, x, step), signal.sosfiltfilt(sos, x, axis=0)[::step]
    )


def test_zero_columns_stay_zero_and_the_rest_is_unchanged():
    sos = signal.cheby1(8, 0.05, 0.08, output="sos")
    x = np.random.default_rng(1).normal(size=(600, 6))
    x[:, [1, 4]] = 0.0
    x[3, 4] = 1e-300  # not zero throughout: filtered
    fast = sosfiltfilt(sos, x, 5, skip_zero_columns=True)
    np.testing.assert_array_equal(fast, signal.sosfiltfilt(sos, x, axis=0)[::5])
    assert not fast[:, 1].any()


def test_too_short_is_scipy_s_error():
    sos = signal.butter(4, 0.1, output="sos")
    with pytest.raises(ValueError, match="padlen"):
        sosfiltfilt(sos, np.zeros((15, 2)))  # 2 sections: padding 3 x 5 = 15 samples


@pytest.mark.parametrize("padlen", [0, 5, 399])
def test_a_given_padding_equals_scipy_s(padlen):
    sos = signal.butter(6, 0.05, output="sos")  # the replay motion's kind of filter
    x = np.random.default_rng(2).normal(size=(400, 3)).cumsum(axis=0)
    np.testing.assert_array_equal(
        sosfiltfilt(sos, x, 7, padlen=padlen),
        signal.sosfiltfilt(sos, x, axis=0, padlen=padlen)[::7],
    )


def _pushed(stream, x, sizes):
    """Push ``x`` in pieces of the given sizes (the rest in one), then finish."""
    out, pos = [], 0
    for k in sizes:
        out.append(stream.push(x[pos : pos + k]))
        pos += k
    out.append(stream.push(x[pos:]))
    out.append(stream.finish())
    return np.concatenate(out)


@pytest.mark.parametrize(
    "sos",
    [
        signal.cheby1(8, 0.05, 0.8 / 10, output="sos"),  # decimation, warm-up 1744 rows
        signal.butter(4, 0.02, output="sos"),
        signal.butter(3, 0.1, output="sos"),
    ],
)
@pytest.mark.parametrize(
    ("n", "step", "sizes"),
    [
        (60_000, 10, [1, 2, 30_000]),  # one row at a time while the start is unknown
        (60_000, 1, [2048] * 20),  # the regressor's row blocks
        (40_001, 7, [0, 39_999]),  # an empty piece; the last output row is the last sample
        (3000, 3, [100]),  # shorter than one block: the whole backward pass from the end
    ],
)
def test_stream_equals_the_whole_signal(sos, n, step, sizes):
    x = np.random.default_rng(3).normal(size=(n, 3)).cumsum(axis=0)  # a random walk: slow
    whole = sosfiltfilt(sos, x, step)
    stream = ZeroPhaseStream(sos, 3, step)
    y = _pushed(stream, x, sizes)
    assert y.shape == whole.shape
    if n < stream.block + stream.warm_up:
        np.testing.assert_array_equal(y, whole)  # one backward pass from the end, as scipy
    else:
        np.testing.assert_allclose(y, whole, rtol=0, atol=1e-13 * np.abs(whole).max())
    # the pieces do not matter, only the block
    np.testing.assert_array_equal(_pushed(ZeroPhaseStream(sos, 3, step), x, [n // 3, 5]), y)


def test_stream_buffer_grows_with_the_signal_not_the_filter():
    """A slow filter's block is long (here 219 372 rows + a 54 843-row warm-up): a signal
    shorter than it is filtered exactly as scipy does while the buffer grows past its first
    65 536 rows, and a filter whose decay is millions of rows (the anti-aliasing filter of a
    decimation by 10^6) takes for a 500-row signal what measuring its decay takes, not its
    block's 6 GB."""
    sos = signal.butter(4, 0.0005, output="sos")
    x = np.random.default_rng(5).normal(size=(150_000, 2)).cumsum(axis=0)
    stream = ZeroPhaseStream(sos, 2, 3)
    assert stream.block + stream.warm_up > len(x) > 2 * 65_536  # grown twice, one pass
    np.testing.assert_array_equal(_pushed(stream, x, [70_000, 1]), sosfiltfilt(sos, x, 3))
    slow = signal.cheby1(8, 0.05, 0.8 / 1e6, output="sos")
    short = np.random.default_rng(6).normal(size=(500, 36))
    tracemalloc.start()
    stream = ZeroPhaseStream(slow, 36, 1000)
    y = _pushed(stream, short, [200])
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert stream.block > 10_000_000
    # the impulse response measuring the decay (4.2e6 samples) ~120 MB; the whole block would
    # be 36 columns x 2.1e7 rows x 8 bytes = 6 GB
    assert peak < 200e6, peak
    np.testing.assert_array_equal(y, sosfiltfilt(slow, short, 1000))


def test_stream_warm_up_is_what_makes_it_exact():
    """With a warm-up shorter than the filter's decay, the blocks' starts show (the test
    above would catch a stream that skipped it)."""
    sos = signal.cheby1(8, 0.05, 0.8 / 10, output="sos")
    x = np.random.default_rng(4).normal(size=(50_000, 2)).cumsum(axis=0)
    whole = sosfiltfilt(sos, x, 10)
    stream = ZeroPhaseStream(sos, 2, 10)
    stream.warm_up = 50
    error = np.abs(_pushed(stream, x, []) - whole).max() / np.abs(whole).max()
    assert error > 1e-6


def test_stream_too_short_is_scipy_s_error():
    stream = ZeroPhaseStream(signal.butter(4, 0.1, output="sos"), 2)
    stream.push(np.zeros((10, 2)))
    stream.push(np.zeros((5, 2)))
    assert stream.n_rows == 15
    with pytest.raises(ValueError, match="padlen, which is 15"):
        stream.finish()
