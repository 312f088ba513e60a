"""Compact time series of a dense safety check, for reports and plots.

A :class:`~ident.excitation.check.SafetyReport` holds every checked sample at >= 1 kHz: the
clearance of every pair, the velocity, acceleration and torque ratio of every joint. A report
needs one curve each: :func:`safety_series` reduces the columns (the smallest clearance over
the pairs, the largest ratio over the joints) and keeps at most ``max_points`` samples, always
including the sample of each series' extreme, so the plotted minimum clearance and the peak
ratios are the checked ones.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ident.excitation.check import ConstraintCheck, SafetyReport, is_limit_check
from ident.robot.limits import describe_unknown

__all__ = ["MAX_SERIES_POINTS", "check_entry", "safety_series", "worst_checks"]

MAX_SERIES_POINTS = 2000


def _decimation_index(n: int, must_keep: list[int], max_points: int) -> np.ndarray:
    """Sorted sample indices: an even spread of ``n`` samples plus ``must_keep``, <= max_points."""
    keep = sorted(set(must_keep))
    if n <= max_points:
        return np.arange(n)
    spread = np.linspace(0, n - 1, max(max_points - len(keep), 2)).round().astype(int)
    return np.unique(np.concatenate([spread, np.asarray(keep, dtype=int)]))


def _finite(values: np.ndarray) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


def check_entry(check: ConstraintCheck) -> dict[str, Any]:
    """One constraint check as JSON-ready data (non-finite numbers become ``None``)."""
    return {
        "name": check.name,
        "kind": check.kind,
        "value": _finite(np.array([check.value]))[0],
        "limit": _finite(np.array([check.limit]))[0],
        "time": _finite(np.array([check.time]))[0],
        "excess": _finite(np.array([check.excess]))[0],
        "ratio": _finite(np.array([check.ratio]))[0],
        "between": _finite(np.array([check.between]))[0],
        "ok": check.ok,
    }


def worst_checks(report: SafetyReport, n_max: int = 8) -> tuple[ConstraintCheck, ...]:
    """The checks a reader needs: every failure (worst first), then the worst of each kind.

    The worst of a kind is the smallest clearance, or the largest ``excess`` (position) or
    ``ratio`` (velocity, acceleration, torque). At most ``n_max`` checks.
    """
    out = list(report.failures())
    for kind in ("clearance", "position", "velocity", "acceleration", "torque"):
        of_kind = [c for c in report.checks if c.kind == kind and c not in out]
        if not of_kind:
            continue
        if kind == "clearance":
            out.append(min(of_kind, key=lambda c: c.value))
        elif kind == "position":
            out.append(max(of_kind, key=lambda c: c.excess))
        else:
            out.append(max(of_kind, key=lambda c: c.ratio))
    return tuple(out[:n_max])


def safety_series(report: SafetyReport, max_points: int = MAX_SERIES_POINTS) -> dict[str, Any]:
    """The safety time series of a check, reduced to one curve each and decimated.

    Parameters
    ----------
    report :
        A dense check (:func:`~ident.excitation.check.check_trajectory`).
    max_points :
        Largest number of samples kept per series.

    Returns
    -------
    :
        JSON-ready dict: ``t`` [s] (n,); ``min_clearance`` [m] (n,), the smallest clearance
        over the checked pairs at each sample (``None`` for every sample without pairs);
        ``closest_pair`` (the pair of the smallest clearance overall), ``clearance_m`` (the
        required margin [m]); ``velocity_ratio``, ``acceleration_ratio``, ``torque_ratio``
        (n,), the largest ``|value| / limit`` over the joints at each sample (0 where no
        limit is known); ``worst_checks`` (:func:`worst_checks` as dicts); ``usable``,
        ``rate_hz``; ``not_checked``, the pairs left out and why (``{pair, reason}``) and the
        limit checks not run (``{check, reason, text}``: the limit was unknown);
        ``checks_not_run``, how many of the latter.
    """
    t = np.asarray(report.t, dtype=float)
    n = t.shape[0]
    clearance = np.asarray(report.clearance, dtype=float).reshape(n, -1)
    has_pairs = clearance.shape[1] > 0
    min_clearance = clearance.min(axis=1) if has_pairs else np.full(n, np.nan)
    ratios = {
        name: (a.max(axis=1) if a.size else np.zeros(n))
        for name, a in (
            ("velocity_ratio", np.asarray(report.velocity_ratio, dtype=float).reshape(n, -1)),
            (
                "acceleration_ratio",
                np.asarray(report.acceleration_ratio, dtype=float).reshape(n, -1),
            ),
            ("torque_ratio", np.asarray(report.torque_ratio, dtype=float).reshape(n, -1)),
        )
    }
    extremes = [int(np.nanargmax(r)) for r in ratios.values() if n and np.any(np.isfinite(r))]
    if has_pairs and n and np.any(np.isfinite(min_clearance)):
        extremes.append(int(np.nanargmin(min_clearance)))
    index = _decimation_index(n, extremes, max_points)
    closest = report.min_clearance
    margins = [c.limit for c in report.checks if c.kind == "clearance"]
    return {
        "usable": bool(report.usable),
        "rate_hz": float(report.rate_hz),
        "n_checked": int(n),
        "t": _finite(t[index]),
        "min_clearance": _finite(min_clearance[index]),
        "closest_pair": None if closest is None else closest.name.removeprefix("clearance:"),
        "closest_time": None if closest is None else _finite(np.array([closest.time]))[0],
        "closest_clearance": None if closest is None else _finite(np.array([closest.value]))[0],
        "clearance_m": float(margins[0]) if margins else None,
        **{name: _finite(r[index]) for name, r in ratios.items()},
        "worst_checks": [check_entry(c) for c in worst_checks(report)],
        "not_checked": [_not_checked_entry(w, r) for w, r in report.not_checked],
        "checks_not_run": len(report.checks_not_run()),
    }


def _not_checked_entry(what: str, reason: str) -> dict[str, str]:
    """``{pair, reason}`` for a pair left out, ``{check, reason, text}`` for a limit check not
    run (``text``: ``"torque not checked on j1: the URDF gives effort 0"``)."""
    if is_limit_check(what):
        return {"check": what, "reason": reason, "text": describe_unknown(what, reason)}
    return {"pair": what, "reason": reason}
