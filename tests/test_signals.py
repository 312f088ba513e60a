"""ident.signals.sosfiltfilt: scipy's sosfiltfilt(sos, x, axis=0)[::step], compiled."""

import numpy as np
import pytest
from scipy import signal

from ident.signals import sosfiltfilt


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
