"""The fleet's drift report: each unit's friction against the fleet, and against its own past
window by window (a friction-rise test with a stated false-alarm rate).

**Across units** (:func:`unit_outliers`). The fleet's friction ``fv_j``, ``fs_j`` is the median
over the units; a unit's deviation is ``r_uj = x_uj / median_j - 1``. Units of one model differ
by manufacture, so a deviation is judged against the fleet's own spread: ``s_j`` = 1.4826 times
the median absolute deviation of ``r_.j`` (the standard deviation of a normal population),
plus the unit's estimation variance. ``T_u = sum_j r_uj^2 / (s_j^2 + var_uj)`` is then
``chi^2(k)`` (``k`` friction parameters) for a unit drawn from that population, and the unit is
flagged when ``T_u`` exceeds the ``chi^2(k)`` quantile of ``alpha``: a false-alarm rate of
``alpha`` per unit (for a normal population; the spread's own sampling error is not counted).

**Across time** (:func:`window_tests`). With the shared parameters fixed at the fleet's, a
window's rows give the unit's local parameters ``phi_w`` (friction and offsets, per joint:
the rows of different joints share no local column), covariance ``N_w^-1 kappa_j
sigma_j^2``. The unit's *baseline* ``phi_0`` comes from its windows that start within the
first ``baseline_s`` seconds of its motion (a baseline window is compared with the baseline
without it). A friction rise by a factor ``1 + s`` moves ``d = phi_w - phi_0`` along ``g``
(``phi_0``'s friction entries); with ``D = C_w + C_0`` (the two estimates are independent) and
the offsets left free (the friction entries' marginal), ``s = h^T d`` with ``h = D^-1 g / g^T
D^-1 g`` (GLS), ``var(s) = h^T D h``.

**The rise's own scale, per unit** (:func:`_calibration`). ``D`` holds the fleet's noise
factor ``kappa_j``, a median over the units; a unit's own factor is not the fleet's: on the
simulated UR5 the units' scatter ratios on the joints whose noise is mostly the encoder's
quantization (through ``ddq``) vary 2-3 times more between units than a common factor allows
(the share of quantization in a joint's residual, and how much of it reaches the friction,
depend on the unit's motion), so with one factor for all ``z = s / std(s)`` is a scale mixture
of normals: its standard deviation above 1 (the median unit's factor is below the mean of the
units'), its tail heavier, the false-alarm rate above ``alpha``. So the rise's variance is
measured on the unit's own reference windows ``r`` (the baseline's, without the tested
window), in the test's own direction: ``y_r = h^T phi_r`` are independent with variances
``rho v_r``, ``v_r = h^T C_r h``, and ``sum_r (y_r - y)^2 / v_r`` (``y`` their
``1 / v_r``-weighted mean) is ``rho chi^2(df)``, ``df`` = reference windows - 1. That scatter
is independent of the reference's pool (the deviations from a weighted mean are uncorrelated
with it when the windows' rows are alike, as a routine motion's are) and of the tested window,
so ``t = s / (std(s) sqrt(rho))`` is Student-t with ``df`` degrees of freedom without a change:
exactly, for Gaussian noise, with the unit's factor and the fleet's estimation noise both
accounted for. ``z`` is ``t``'s normal score (the standard normal quantile of its probability),
standard normal without a change, and the alarm is ``z > z_alpha`` (``z_alpha`` the standard
normal quantile of ``1 - alpha``): at most ``alpha`` of the change-free windows alarm, the
windows after the baseline as well as the baseline's own (sharing a baseline and its ``rho``
makes a unit's windows' alarms correlated, not more frequent). The price: a rise must exceed
the t quantile instead of the normal one (2.33 -> 3.75 standard deviations at ``df`` 4, 2.82
at 9); a window with fewer than two reference windows is not tested. Where one factor per
joint suffices, the fleet's kappa alone with a per-joint Student-t gives no exact law: the
joints' factors estimated apart reweigh the joints by their own noise (tails heavier than t).

**The windows' noise factor** (:func:`window_factors`). ``C_w = N_w^-1 sigma_j^2`` holds for
independent rows; the rows' noise is not independent: the low-pass correlates neighbouring
rows (for the default 20 Hz cut-off and 50 rows/s, white torque noise gives sums of rows 1.39
times the variance of independent ones), and the part of the residual that comes from
differentiated position noise (the encoder's quantization in ``ddq``) has almost no power at
the motion's slow frequencies, so it moves the friction far less than its share of
``sigma_j`` says. So the windows' scatter is measured: per unit and joint, ``Q = sum_w
(phi_w - phi) C_w^-1 (phi_w - phi)`` (``phi`` the windows' pooled estimate) is ``kappa_j
chi^2(k (W - 1))`` for ``W`` windows and ``k`` local parameters of the joint, and ``kappa_j``
is the median over the units of ``Q`` over that law's median (one unit's change does not move
it; each unit's ratio has median ``kappa_j`` whatever its ``W``, so the median over the units
is consistent where the units share a factor). In the tests ``kappa_j`` sets the joints'
relative weights; the scale is the unit's own (above).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.special import ndtri_exp
from scipy.stats import chi2, norm
from scipy.stats import t as student_t

from ident.identify.streaming.fleet import FleetColumns, FleetSolution, WindowSums

__all__ = [
    "WindowTest",
    "fleet_window_tests",
    "rise_threshold",
    "unit_outliers",
    "window_factors",
    "window_local",
    "window_tests",
]

FloatArray = npt.NDArray[np.float64]

#: Fewest rows of a joint in a window for its local parameters to be tested.
MIN_ROWS = 20


def unit_outliers(sol: FleetSolution, cols: FleetColumns, alpha: float) -> list[dict]:
    """Per unit: its friction's relative deviation from the fleet's median per parameter, the
    statistic ``T_u``, its threshold and the flag (module docstring)."""
    fric = np.array([k in ("fv", "fs") for k in cols.kind])
    X = np.array([u.x[fric] for u in sol.units])  # (n_units, k)
    V = np.array([u.std[fric] ** 2 for u in sol.units])
    med = np.median(X, axis=0)
    r = X / np.where(med != 0, med, 1.0) - 1.0
    rv = V / np.where(med != 0, med, 1.0) ** 2
    spread = 1.4826 * np.median(np.abs(r - np.median(r, axis=0)), axis=0)
    T = np.sum(r * r / np.maximum(spread**2 + rv, 1e-30), axis=1)  # identical units: no 0/0
    threshold = float(chi2.isf(alpha, int(fric.sum())))
    names = [cols.names[i] for i in cols.local[fric]]
    return [
        {
            "deviation_pct": dict(zip(names, (100 * r[u]).round(3).tolist(), strict=True)),
            "mean_deviation_pct": float(100 * r[u].mean()),
            "statistic": float(T[u]),
            "threshold": threshold,
            "flagged": bool(T[u] > threshold),
        }
        for u in range(len(sol.units))
    ] + [{"fleet_spread_pct": dict(zip(names, (100 * spread).round(3).tolist(), strict=True))}]


def window_local(
    w: WindowSums, x_S: FloatArray, sigma: FloatArray, cols: FleetColumns
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
    """``(phi, C, ok)`` of a window's (or a sum of windows') rows: local parameters (l,),
    their covariance (l, l) and which entries were estimated (their joint has at least
    :data:`MIN_ROWS` rows and a well-posed block); NaN / 0 elsewhere."""
    L = cols.local.size
    phi, C = np.full(L, np.nan), np.zeros((L, L))
    ok = np.zeros(L, dtype=bool)
    b = w.c - w.A[:, cols.shared] @ x_S
    N = w.A[:, cols.local]
    for j in np.unique(cols.owner):
        i = np.flatnonzero(cols.owner == j)
        if w.n[j] < MIN_ROWS or not np.isfinite(sigma[j]):
            continue
        block = N[np.ix_(i, i)]
        d = np.sqrt(np.clip(np.diag(block), 0.0, None))
        if np.any(d == 0) or np.linalg.cond(block / np.outer(d, d)) > 1e8:
            continue
        inv = np.linalg.inv(block)
        phi[i], C[np.ix_(i, i)], ok[i] = inv @ b[i], inv * sigma[j] ** 2, True
    return phi, C, ok


def window_factors(
    windows: list[list[WindowSums]], sol: FleetSolution, cols: FleetColumns
) -> tuple[FloatArray, npt.NDArray[np.intp]]:
    """Per joint: the factor ``kappa_j`` by which the windows' local parameters scatter more
    than their white-noise covariance says, and the units it comes from (module docstring),
    both (nv,); ``kappa_j`` NaN where no unit has two windows that estimate joint ``j``.

    Per unit and joint, ``Q = sum_w (phi_w - phi) C_w^-1 (phi_w - phi)`` over the windows
    that estimate the joint (``phi`` their pooled estimate) is ``kappa chi^2(k (W - 1))``
    (``k`` local parameters of the joint, ``W`` windows); ``kappa_j`` is the median over the
    units of ``Q`` over that law's median (a median: one unit's change does not move it).
    """
    nv = cols.columns.chain.n_joints
    ratios: list[list[float]] = [[] for _ in range(nv)]
    for wins, unit in zip(windows, sol.units, strict=True):
        est = [window_local(w, sol.x, unit.sigma, cols) for w in wins]
        for j in range(nv):
            i = np.flatnonzero(cols.owner == j)
            use = [(phi[i], C[np.ix_(i, i)]) for phi, C, ok in est if ok[i].all()]
            if len(use) < 2:
                continue
            Q = _scatter(use)
            ratios[j].append(Q / float(chi2.median(i.size * (len(use) - 1))))
    kappa = np.array([np.median(r) if r else np.nan for r in ratios])
    return kappa, np.array([len(r) for r in ratios], dtype=np.intp)


def _scatter(est: list[tuple[FloatArray, FloatArray]]) -> float:
    """``sum_w (phi_w - phi) C_w^-1 (phi_w - phi)`` of estimates ``(phi_w, C_w)``, ``phi``
    their inverse-covariance weighted mean (:func:`window_factors`)."""
    P = [np.linalg.inv(C) for _, C in est]
    rhs = np.sum([p @ phi for p, (phi, _) in zip(P, est, strict=True)], axis=0)
    pooled = np.linalg.solve(np.sum(P, axis=0), rhs)
    return sum(
        float((phi - pooled) @ p @ (phi - pooled)) for p, (phi, _) in zip(P, est, strict=True)
    )


def _sum(windows: list[WindowSums]) -> WindowSums:
    """The rows of several windows as one."""
    return WindowSums(
        A=np.sum([w.A for w in windows], axis=0),
        c=np.sum([w.c for w in windows], axis=0),
        n=np.sum([w.n for w in windows], axis=0),
        t0=windows[0].t0,
        t1=windows[-1].t1,
        log=windows[0].log,
    )


def _minus(a: WindowSums, b: WindowSums) -> WindowSums:
    """The rows of ``a`` without those of ``b`` (a baseline without one of its windows)."""
    return WindowSums(A=a.A - b.A, c=a.c - b.c, n=a.n - b.n, t0=a.t0, t1=a.t1, log=a.log)


@dataclass(frozen=True)
class WindowTest:
    """One window's rise test: ``time_s`` its start in the unit's motion time [s], ``rise``
    the relative friction rise ``s`` (NaN when not tested), ``std`` its standard deviation
    (calibrated on the unit's baseline windows), ``z`` the statistic (the normal score of the
    rise's Student-t probability: standard normal without a change), ``df`` the calibration's
    degrees of freedom (0 when not tested), ``per_joint`` the per-joint rises (NaN where not
    tested)."""

    time_s: float
    duration_s: float
    rise: float
    std: float
    z: float
    per_joint: tuple[float, ...]
    baseline: bool
    df: int = 0


def _rise(d: FloatArray, D: FloatArray, g: FloatArray) -> tuple[float, FloatArray]:
    """GLS scale ``s`` of ``d ~ s g`` under covariance ``D`` and the functional ``h`` with
    ``s = h^T d`` (``var(s) = h^T D h = 1 / g^T D^-1 g``); NaN when ``g`` carries no
    information."""
    scale = np.sqrt(np.clip(np.diag(D), 1e-300, None))
    Ds = D / np.outer(scale, scale)
    Pg = np.linalg.solve(Ds, g / scale) / scale
    info = float(g @ Pg)
    if not info > 0:
        return float("nan"), np.full(g.size, np.nan)
    return float(Pg @ d) / info, Pg / info


Estimate = tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]


def _test(
    ref: Estimate, refs: list[Estimate], est: Estimate, cols: FleetColumns
) -> tuple[float, float, float, int, tuple[float, ...]]:
    """``(s, std, z, df, per-joint s)`` of a window's estimate ``est`` against the reference
    ``ref`` (the pool of the windows ``refs``; module docstring): ``s`` the GLS rise with the
    fleet's noise, ``std`` its standard deviation times ``sqrt(rho)``, the unit's own factor
    in that direction measured on ``refs`` (:func:`_calibration`), ``z`` the normal score of
    ``s / std``'s Student-t probability with ``df`` degrees of freedom."""
    (phi0, C0, _), (phi, C, _) = ref, est
    fric = np.array([k in ("fv", "fs") for k in cols.kind]) & np.isfinite(phi) & np.isfinite(phi0)
    nan = float("nan")
    if not fric.any():
        return nan, nan, nan, 0, ()
    i = np.flatnonzero(fric)
    d, D, g = (phi - phi0)[i], (C + C0)[np.ix_(i, i)], phi0[i]
    s, h = _rise(d, D, g)
    per_joint = []
    for j in sorted(set(cols.owner.tolist())):
        k = np.flatnonzero(cols.owner[i] == j)
        per_joint.append(_rise(d[k], D[np.ix_(k, k)], g[k])[0] if k.size else nan)
    rho, df = _calibration(h, i, refs)
    if not (np.isfinite(s) and rho > 0):
        return nan, nan, nan, 0, tuple(per_joint)
    std = float(np.sqrt(h @ D @ h * rho))
    return s, std, float(-ndtri_exp(student_t.logsf(s / std, df))), df, tuple(per_joint)


def _calibration(h: FloatArray, i: npt.NDArray[np.intp], refs: list[Estimate]) -> tuple[float, int]:
    """``(rho, df)``: the reference windows' rise functional ``y_r = h^T phi_r[i]`` (variance
    ``v_r = h^T C_r h`` with the fleet's noise) scattered about its weighted mean, ``rho =
    sum_r (y_r - y) ^2 / v_r / df`` with ``df`` = those windows - 1 (module docstring);
    ``(NaN, 0)`` with fewer than two."""
    y, v = [], []
    for phi, C, _ in refs:
        if np.all(np.isfinite(phi[i])):
            y.append(float(h @ phi[i]))
            v.append(float(h @ C[np.ix_(i, i)] @ h))
    y_, v_ = np.array(y), np.array(v)
    if y_.size < 2 or not np.all(v_ > 0):
        return float("nan"), 0
    mean = np.sum(y_ / v_) / np.sum(1 / v_)
    return float(np.sum((y_ - mean) ** 2 / v_)) / (y_.size - 1), y_.size - 1


def window_tests(
    windows: list[WindowSums],
    x_S: FloatArray,
    sigma: FloatArray,
    cols: FleetColumns,
    baseline_s: float,
    offsets: list[float],
) -> list[WindowTest]:
    """Every window of one unit tested against the unit's baseline (module docstring).

    ``offsets``: per log of the unit, its start in the unit's motion time [s] (the logs one
    after the other); ``sigma`` (nv,) the unit's noise per joint [N*m] (the fleet solve's
    times ``sqrt(kappa_j)``). A window is not tested (NaN) when fewer than two baseline
    windows other than itself estimate its friction (nothing to calibrate on).
    """
    start = [offsets[w.log] + w.t0 for w in windows]
    base = [w for w, t in zip(windows, start, strict=True) if t < baseline_s] or windows[:1]
    total = _sum(base)
    whole = window_local(total, x_S, sigma, cols)
    each = {id(b): window_local(b, x_S, sigma, cols) for b in base}
    out = []
    for w, t in zip(windows, start, strict=True):
        in_base = id(w) in each
        refs = [e for b, e in each.items() if b != id(w)]
        s = std = z = float("nan")
        df = 0
        per_joint: tuple[float, ...] = ()
        if len(refs) >= 2:  # the rise's own scatter needs two reference windows
            ref = window_local(_minus(total, w), x_S, sigma, cols) if in_base else whole
            est = each[id(w)] if in_base else window_local(w, x_S, sigma, cols)
            s, std, z, df, per_joint = _test(ref, refs, est, cols)
        out.append(WindowTest(t, w.t1 - w.t0, s, std, z, per_joint, in_base, df))
    return out


def fleet_window_tests(
    windows: list[list[WindowSums]],
    offsets: list[list[float]],
    sol: FleetSolution,
    cols: FleetColumns,
    baseline_s: float,
    kappa: FloatArray,
) -> list[list[WindowTest]]:
    """:func:`window_tests` of every unit, with the noise ``kappa_j sigma_uj^2`` per joint
    (``kappa`` (nv,) of :func:`window_factors`; NaN counts as 1)."""
    scale = np.sqrt(np.nan_to_num(kappa, nan=1.0))
    return [
        window_tests(w, sol.x, u.sigma * scale, cols, baseline_s, off)
        for w, u, off in zip(windows, sol.units, offsets, strict=True)
    ]


def rise_threshold(alpha: float) -> float:
    """The one-sided alarm threshold on ``z``: the standard normal quantile of ``1 - alpha``
    (``z`` is a normal score: the Student-t law of the calibrated rise is in it)."""
    return float(norm.isf(alpha))
