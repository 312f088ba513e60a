"""Change detection: a generalized likelihood-ratio (GLR) test of the last blocks' rows
against the estimate from the rows before them.

The reference ``x_ref`` comes from the rows *before* the test window (forgetting, covariance
``C``, per-joint noise ``sigma_j``: :class:`~ident.identify.streaming.normal.Solution`). On the
window's rows (its unweighted normal equations ``A_j``, ``c_j``) the score of a parameter change
is ``G = sum_j (c_j - A_j x_ref) / sigma_j^2``: with no change it is Gaussian, zero mean,
covariance ``F + F C F`` (``F = sum_j A_j / sigma_j^2``: the window's own noise, plus the
reference's error seen through the window's rows; the two are independent because the reference
holds no row of the window). The GLR of "some parameter changed" is then

``T = G^T (F + F C F)^+ G  ~  chi^2(r)``

with ``r`` the rank of ``F`` (directions the window did not excite carry no test). A payload
step (mass, centre of mass, inertia) moves ``x``'s first 10 entries, a friction rise the
friction entries: both raise ``T``. The threshold is the ``chi^2(r)`` quantile of a per-test
false-alarm probability ``alpha = rate * T_block / 3600`` for a stated rate of false alarms per
hour of log, one test per block: by the union bound the false-alarm rate is at most ``rate``
(the overlapping windows' tests are positively correlated, so it is lower). The change's onset
is found by going back from the newest block while each block alone is significant (a split
that maximizes the statistic over the window is not sharp: the reference's own error enters
every split alike), each block's statistic scaled by the same ``kappa`` as the alarm's (below):
unscaled, blocks before a change passed for changed ones, and their rows, counted among those
after the change, biased its estimate.

**Model error.** The ``chi^2`` law holds for white noise. A model's error (a friction law a
little off, the filters' bias at high jerk) is not white: it comes and goes with the motion, and
a window where it is large looks like a change. The score's covariance is therefore scaled by
``kappa >= 1``, the 95th percentile of the windows' residual variance over its average
(:func:`variance_ratio`) over the last change-free windows: the test then asks for a change
larger than the model's own local misfit. ``kappa`` is 1 within sampling error for an exact
model, and is reported.
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
import numpy.typing as npt
from scipy.stats import chi2

from ident.identify.streaming.normal import NormalEquations, Solution

__all__ = [
    "alarm_threshold",
    "glr_statistic",
    "onset_block",
    "per_test_alpha",
    "variance_ratio",
]

FloatArray = npt.NDArray[np.float64]

#: Relative eigenvalue below which a direction of the window's information is not tested.
TEST_TOL = 1e-9


def per_test_alpha(rate_per_hour: float, block_s: float) -> float:
    """False-alarm probability of one test for ``rate_per_hour`` false alarms per hour with one
    test every ``block_s`` seconds (union bound)."""
    return rate_per_hour * block_s / 3600.0


@lru_cache(maxsize=256)
def alarm_threshold(alpha: float, dof: int) -> float:
    """The ``chi^2(dof)`` quantile exceeded with probability ``alpha``."""
    return float(chi2.isf(alpha, dof))


def glr_statistic(window: NormalEquations, ref: Solution) -> tuple[float, int]:
    """``(T, r)`` of the module docstring: the window's unweighted sums against ``ref``."""
    v = np.where(np.isfinite(ref.sigma) & (ref.sigma > 0), 1.0 / ref.sigma**2, 0.0)
    F = np.einsum("j,jpq->pq", v, window.A)
    G = v @ (window.c - window.A @ ref.x)
    d = np.sqrt(np.clip(np.diag(F), 0.0, None))
    live = d > 0
    if not np.any(live):
        return 0.0, 0
    # scaled to unit diagonal: the unknowns' units differ by orders of magnitude
    Fs = F[np.ix_(live, live)] / np.outer(d[live], d[live])
    Cs = ref.covariance[np.ix_(live, live)] * np.outer(d[live], d[live])
    S = Fs + Fs @ Cs @ Fs
    w, V = np.linalg.eigh(0.5 * (S + S.T))
    keep = w > TEST_TOL * w[-1]
    g = V[:, keep].T @ (G[live] / d[live])
    return float(np.sum(g * g / w[keep])), int(np.sum(keep))


def onset_block(
    blocks: Sequence[NormalEquations], ref: Solution, alpha: float = 0.01, kappa: float = 1.0
) -> int:
    """The first block of the changed rows: going back from the newest block, the earliest of
    the run of blocks each of which alone departs from ``ref`` at level ``alpha`` (the
    statistic scaled by the model-error factor ``kappa``, as the alarm's); the newest block
    when none does (a small change the window's sum revealed)."""
    s = len(blocks) - 1
    for b in range(len(blocks) - 1, -1, -1):
        T, r = glr_statistic(blocks[b], ref)
        if r == 0 or chi2.sf(T / kappa, r) >= alpha:
            break
        s = b
    return s


def variance_ratio(window: NormalEquations, ref: Solution) -> float:
    """The window's weighted residual sum of squares at ``ref.x`` over its expectation for
    white noise of the reference's variance: ``sum_j S_j / sigma_j^2`` over
    ``sum_j n_j + tr(F C)`` (the rows' noise plus the reference's own error seen through
    them); 1 on average for an exact model."""
    ok = np.isfinite(ref.sigma) & (ref.sigma > 0) & (window.sw > 0)
    if not np.any(ok):
        return float("nan")
    v = np.where(ok, 1.0 / np.where(ok, ref.sigma, 1.0) ** 2, 0.0)
    ss = float(v @ window.residual_ss(ref.x))
    F = np.einsum("j,jpq->pq", v, window.A)
    return ss / (float(np.sum(window.sw[ok])) + float(np.sum(F * ref.covariance)))
