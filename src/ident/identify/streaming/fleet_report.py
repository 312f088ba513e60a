"""The files of an ``ident fleet`` run: ``result.json`` (the shared parameters, every unit's
friction and offsets with 95 % intervals, the run's throughput), the drift report
(``drift.json``, ``drift.md``) and ``windows.csv`` (every unit's windows: friction rise, its
test).

Intervals: ``x +- 1.96 std`` with ``std`` from the weighted least-squares covariance for rows
whose noise variance counts ``max(1, kappa_j)`` times the residual's per joint
(:func:`~ident.identify.streaming.fleet.scaled_covariances`; ``kappa_j`` the windows' noise
factor, :func:`~ident.identify.streaming.fleet_drift.window_factors`: the rows' noise,
correlated from row to row). Never below the residual's own: an error common to every window
cancels in the windows' scatter but not in the pooled estimate (simulated UR5 units: with
``kappa_j`` below 1 as measured, 79 % of the intervals held the truth; with the floor, 96 %).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.identify.estimation.uncertainty import z_value
from ident.identify.streaming.fleet import FleetColumns, FleetSolution, scaled_covariances
from ident.identify.streaming.fleet_drift import (
    WindowTest,
    fleet_window_tests,
    rise_threshold,
    unit_outliers,
    window_factors,
)
from ident.identify.streaming.fleet_run import FleetSums

__all__ = ["FleetReport", "MIN_UNITS_ACROSS", "fleet_report"]

FloatArray = npt.NDArray[np.float64]
_Z95 = z_value(0.95)  # the 95 % intervals' half-width in standard deviations
#: Fewest units for the test across units (the fleet's spread is a median absolute deviation).
MIN_UNITS_ACROSS = 5


@dataclass(frozen=True)
class FleetReport:
    """The run's content: ``result`` (result.json), ``drift`` (drift.json), ``markdown``
    (drift.md), ``windows_csv`` (windows.csv)."""

    result: dict
    drift: dict
    markdown: str
    windows_csv: str


def _params(names: list[str], x: FloatArray, s: FloatArray) -> dict:
    """``{name: {value, std, interval_95}}`` (SI)."""
    return {
        n: {
            "value": float(v),
            "std": float(e),
            "interval_95": [float(v - _Z95 * e), float(v + _Z95 * e)],
        }
        for n, v, e in zip(names, x, s, strict=True)
    }


def _trend(tests: list[WindowTest]) -> dict:
    """Weighted straight line through the windows' rises: slope [% per hour of motion]."""
    t = [(w.time_s / 3600, w.rise, w.std) for w in tests if np.isfinite(w.z) and w.std > 0]
    if len(t) < 3:
        return {"status": "not run", "reason": f"{len(t)} tested window(s); needs 3"}
    h, s, e = (np.array(c) for c in zip(*t, strict=True))
    G = np.column_stack([np.ones_like(h), h]) / e[:, None]
    cov = np.linalg.inv(G.T @ G)
    coef = cov @ G.T @ (s / e)
    return {
        "status": "run",
        "slope_pct_per_hour": float(100 * coef[1]),
        "slope_std_pct_per_hour": float(100 * np.sqrt(cov[1, 1])),
    }


def _unit_drift(name: str, tests: list[WindowTest], threshold: float) -> dict:
    """One unit's windows: alarms, the first one, the trend."""
    alarms = [w for w in tests if np.isfinite(w.z) and w.z > threshold]
    untested = sum(not np.isfinite(w.z) for w in tests)
    return {
        "unit": name,
        "windows": len(tests),
        "windows_not_tested": untested,
        "alarms": len(alarms),
        "first_alarm_s": alarms[0].time_s if alarms else None,
        "largest_rise_pct": max((100 * w.rise for w in tests if np.isfinite(w.z)), default=None),
        "trend": _trend(tests),
    }


def _across(sol: FleetSolution, cols: FleetColumns, names: list[str], alpha: float) -> dict:
    """The test across units, or its reason for not running."""
    if len(names) < MIN_UNITS_ACROSS:
        return {
            "status": "not run",
            "reason": f"{len(names)} unit(s); the fleet's spread needs at least {MIN_UNITS_ACROSS}",
        }
    rows = unit_outliers(sol, cols, alpha)
    spread = rows.pop()
    return {
        "status": "run",
        "false_alarm_per_unit": alpha,
        **spread,
        "units": [{"unit": n, **r} for n, r in zip(names, rows, strict=True)],
    }


def _windows_csv(names: list[str], tests: list[list[WindowTest]], threshold: float) -> str:
    lines = ["unit,start_s,duration_s,baseline,rise_pct,rise_std_pct,z,df,alarm,per_joint_rise_pct"]
    for n, unit in zip(names, tests, strict=True):
        for w in unit:
            joints = " ".join(f"{100 * r:.3f}" for r in w.per_joint)
            alarm = bool(np.isfinite(w.z) and w.z > threshold)
            lines.append(
                f"{n},{w.time_s:.3f},{w.duration_s:.3f},{w.baseline},{100 * w.rise:.4f},"
                f"{100 * w.std:.4f},{w.z:.3f},{w.df},{alarm},{joints}"
            )
    return "\n".join(lines) + "\n"


def fleet_report(
    names: list[str], sums: FleetSums, sol: FleetSolution, cols: FleetColumns, settings: dict
) -> FleetReport:
    """Every file's content; ``settings``: the ``fleet:`` section (``baseline_s``,
    ``false_alarm`` used)."""
    alpha, baseline = float(settings["false_alarm"]), float(settings["baseline_s"])
    kappa, kappa_units = window_factors(sums.windows, sol, cols)
    tests = fleet_window_tests(sums.windows, sums.log_offsets, sol, cols, baseline, kappa)
    threshold = rise_threshold(alpha)
    scaled = scaled_covariances(
        sol, sums.units, cols, np.maximum(np.nan_to_num(kappa, nan=1.0), 1.0)
    )
    shared = [cols.names[i] for i in cols.shared]
    local = [cols.names[i] for i in cols.local]
    result = {
        "units": len(names),
        "settings": settings,
        "window_noise_factor": _factors(kappa, kappa_units),
        "shared": _params(shared, sol.x, np.sqrt(np.diag(scaled.covariance))),
        "per_unit": [
            {
                "unit": n,
                "parameters": _params(local, u.x, u.std),
                "noise_std_nm": u.sigma.tolist(),
                "rows_per_joint": u.n_rows.tolist(),
            }
            for n, u in zip(names, scaled.units, strict=True)
        ],
        "throughput": _throughput(sums),
    }
    drift = {
        "across_units": _across(sol, cols, names, alpha),
        "across_time": {
            "test": (
                "one-sided z of the window's friction rise against the unit's baseline: the "
                "normal score of the rise over its standard deviation calibrated on the unit's "
                "own baseline windows (Student t, their number - 1 degrees of freedom); a window "
                "with fewer than 2 baseline windows other than itself is not tested"
            ),
            "false_alarm_per_window": alpha,
            "window_noise_factor": _factors(kappa, kappa_units),
            "threshold_z": threshold,
            "baseline_s": baseline,
            "units": [_unit_drift(n, t, threshold) for n, t in zip(names, tests, strict=True)],
        },
    }
    return FleetReport(
        result=result,
        drift=drift,
        markdown=_markdown(drift),
        windows_csv=_windows_csv(names, tests, threshold),
    )


def _factors(kappa: FloatArray, units: npt.NDArray[np.intp]) -> dict:
    """The windows' noise factor per joint, or why it was not estimated (then 1 is used)."""
    return {
        "per_joint": [None if not np.isfinite(k) else float(k) for k in kappa],
        "units_per_joint": units.tolist(),
        "status": "run"
        if np.isfinite(kappa).all()
        else "not run for joints without a unit "
        "of two windows that estimate them: 1 used (white rows)",
    }


def _throughput(sums: FleetSums) -> dict:
    per_core = sums.samples / max(sums.wall_s, 1e-9) / max(sums.cores, 1)
    return {
        "samples": sums.samples,
        "wall_s": sums.wall_s,
        "cores": sums.cores,
        "samples_per_s_per_core": per_core,
        "chunk_cpu_s": sums.chunk_cpu_s,
        "samples_per_cpu_s_of_the_chunks": sums.samples / max(sums.chunk_cpu_s, 1e-9),
    }


def _markdown(drift: dict) -> str:
    """drift.md: the two tests in words and tables."""
    across, time_ = drift["across_units"], drift["across_time"]
    out = ["# Fleet drift report", "", "## Friction against the fleet", ""]
    if across["status"] != "run":
        out.append(f"Not run: {across['reason']}.")
    else:
        out += [
            f"A unit is flagged when its friction's departure from the fleet's median, "
            f"measured in the fleet's own spread, exceeds the chi-square quantile of "
            f"{across['false_alarm_per_unit']:g} (false alarms per unit).",
            "",
            "| unit | mean deviation [%] | statistic | threshold | flagged |",
            "|---|---|---|---|---|",
        ]
        out += [
            f"| {u['unit']} | {u['mean_deviation_pct']:+.2f} | {u['statistic']:.3g} | "
            f"{u['threshold']:.3g} | {'**yes**' if u['flagged'] else 'no'} |"
            for u in across["units"]
        ]
    out += [
        "",
        "## Friction over time",
        "",
        f"Each window is tested against the unit's first {time_['baseline_s']:g} s of motion: "
        f"alarm when z > {time_['threshold_z']:.3f} (one-sided, "
        f"{time_['false_alarm_per_window']:g} false alarms per window; the windows' noise "
        f"factor per joint {_kappa_text(time_['window_noise_factor'])}).",
        "",
        "| unit | windows | not tested | alarms | first alarm [s] | trend [%/h] |",
        "|---|---|---|---|---|---|",
    ]
    for u in time_["units"]:
        tr = u["trend"]
        trend = (
            f"{tr['slope_pct_per_hour']:+.3g} +- {tr['slope_std_pct_per_hour']:.2g}"
            if tr["status"] == "run"
            else f"not run ({tr['reason']})"
        )
        first = "" if u["first_alarm_s"] is None else f"{u['first_alarm_s']:.0f}"
        out.append(
            f"| {u['unit']} | {u['windows']} | {u['windows_not_tested']} | {u['alarms']} | "
            f"{first} | {trend} |"
        )
    return "\n".join(out) + "\n"


def _kappa_text(factors: dict) -> str:
    """``1.31, 1.42, not run, ...``: the windows' noise factor per joint in words."""
    return ", ".join("not run" if k is None else f"{k:.2f}" for k in factors["per_joint"])
