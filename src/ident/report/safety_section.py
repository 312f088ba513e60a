"""The safety part of a run report: clearance and limit plots, the worst checks, the headline.

Everything comes from ``result.json``: the chosen elite (``chosen_elite``, the one the robot
may run; without one, elite 1, marked UNSAFE) and its ``safety_series`` (the dense check
reduced by :func:`ident.excitation.safety_series.safety_series` when the run was saved).
"""

from __future__ import annotations

from typing import Any

from ident.excitation.check import unchecked_checks
from ident.report.format import fmt as _fmt
from ident.report.format import table as _table

__all__ = ["chosen_elite", "safety_figures", "safety_headline", "safety_section"]

CLEARANCE_FIGURE = "figures/clearance.png"
LIMITS_FIGURE = "figures/limits.png"


def chosen_elite(data: dict[str, Any]) -> tuple[dict[str, Any] | None, bool]:
    """The elite the report shows for safety, and whether it is marked UNSAFE.

    ``chosen_elite`` of ``result.json`` when the run chose one; else elite 1, unsafe when the
    run was checked (``safety`` present) and chose none.
    """
    elites = data.get("elites") or []
    chosen = data.get("chosen_elite")
    if isinstance(chosen, int):
        for e in elites:
            if e.get("rank") == chosen:
                series = e.get("safety_series")
                return e, bool(series is not None and not series.get("usable", True))
    if not elites:
        return None, False
    elite = elites[0]
    series = elite.get("safety_series")
    unsafe = data.get("safety") is not None or (
        series is not None and not series.get("usable", True)
    )
    return elite, bool(unsafe)


def _label(data: dict[str, Any]) -> tuple[str, dict[str, Any] | None]:
    elite, unsafe = chosen_elite(data)
    if elite is None:
        return "", None
    label = f"elite {elite['rank']}" + (" (UNSAFE, not for the robot)" if unsafe else "")
    return label, elite.get("safety_series")


def safety_figures(data: dict[str, Any]) -> dict[str, bytes]:
    """``figures/clearance.png`` and ``figures/limits.png`` of the chosen elite (or nothing)."""
    from ident.report.plots import clearance_png, limits_png

    label, series = _label(data)
    if not series or not series.get("t"):
        return {}
    figures: dict[str, bytes] = {}
    if any(v is not None for v in series.get("min_clearance", [])):
        closest = None
        if series.get("closest_pair") and series.get("closest_time") is not None:
            closest = (
                series["closest_pair"],
                float(series["closest_time"]),
                float(series["closest_clearance"]),
            )
        figures[CLEARANCE_FIGURE] = clearance_png(
            series["t"],
            series["min_clearance"],
            clearance_m=series.get("clearance_m"),
            closest=closest,
            title=f"Clearance over time, {label}: smallest over the checked pairs",
        )
    figures[LIMITS_FIGURE] = limits_png(
        series["t"],
        {
            k: series[f"{k}_ratio"]
            for k in ("velocity", "acceleration", "torque")
            if f"{k}_ratio" in series
        },
        title=f"Limits, {label}: largest ratio over the joints",
    )
    return figures


def safety_section(data: dict[str, Any], figures: set[str] | frozenset[str]) -> list[str]:
    """``## Trajectory safety``: the plots and the worst checks of the chosen elite."""
    label, series = _label(data)
    if series is None:
        return []
    md = ["## Trajectory safety", ""]
    md += [
        f"Dense check of {label} at {_fmt(series.get('rate_hz'))} Hz "
        f"({series.get('n_checked')} samples, one period): {_verdict(series)}",
        "",
    ]
    if CLEARANCE_FIGURE in figures:
        md += [f"![Clearance over time, {label}]({CLEARANCE_FIGURE})", ""]
    if LIMITS_FIGURE in figures:
        md += [f"![Velocity, acceleration and torque against their limits]({LIMITS_FIGURE})", ""]
    rows = [
        [
            c["name"],
            "ok" if c["ok"] else "**violated**",
            _fmt(c["value"]),
            _fmt(c["limit"]),
            "—" if c["ratio"] is None else _fmt(c["ratio"]),
            _fmt(c["time"]),
        ]
        for c in series.get("worst_checks", [])
    ]
    if rows:
        md += ["Worst checks (failures first, then the worst of each kind):", ""]
        md += _table(
            ["check", "state", "worst value [SI]", "limit [SI]", "ratio", "time [s]"],
            rows,
            left=(0, 1),
        )
    md += _not_checked(series)
    return md


def _limits_not_run(series: dict[str, Any]) -> list[str]:
    """``"torque not checked on j1: the URDF gives effort 0"`` per limit check not run."""
    return [e["text"] for e in series.get("not_checked") or [] if "check" in e]


def _verdict(series: dict[str, Any]) -> str:
    """``every constraint holds.`` only when every limit was known; else the number of checks
    not run (listed below the table)."""
    not_run = len(_limits_not_run(series))
    if not series.get("usable"):
        held = "**constraints violated**"
    elif not_run:
        held = "every checked constraint holds"
    else:
        return "every constraint holds."
    if not_run:
        held += f"; **{not_run} check{'s' if not_run != 1 else ''} not run** (listed below)"
    return held + "."


def _not_checked(series: dict[str, Any]) -> list[str]:
    """The limit checks not run (unknown limits) and the pairs left out of the check and why
    (robot link pairs; environment pairs at a constant distance, judged once)."""
    md: list[str] = []
    not_run = _limits_not_run(series)
    if not_run:
        md += ["", "Checks not run (the limit is unknown, or its check is switched off):", ""]
        md += [f"- {line}" for line in not_run]
    entries = [e for e in series.get("not_checked") or [] if "pair" in e]
    if not entries:
        return md
    md += [
        "",
        "Not checked along the trajectory, or checked on stand-in geometry (the exact "
        "geometry is measured for every other pair, between the samples too):",
        "",
    ]
    md += _table(
        ["pair", "why"], [[e.get("pair", ""), e.get("reason", "")] for e in entries], left=(0, 1)
    )
    return md


def series_unchecked(series: dict[str, Any] | None) -> tuple[str, ...]:
    """The whole checks an elite's ``safety_series`` left out (``"self-collision not checked
    (...)"``), see :func:`ident.excitation.check.unchecked_checks`."""
    entries = (series or {}).get("not_checked") or []
    return unchecked_checks((e.get("pair", ""), e.get("reason", "")) for e in entries)


def safety_headline(data: dict[str, Any]) -> str | None:
    """``elite k executed; smallest clearance ... m (pair) at t = ... s`` (None: no series)."""
    elite, unsafe = chosen_elite(data)
    series = None if elite is None else elite.get("safety_series")
    if elite is None or series is None:
        return None
    if unsafe or not isinstance(data.get("chosen_elite"), int):
        text = f"no elite passed the check; elite {elite['rank']} shown, UNSAFE"
    else:
        text = f"elite {elite['rank']} executed"
    if series.get("closest_clearance") is not None:
        text += (
            f"; smallest clearance {series['closest_clearance'] * 1000:.1f} mm "
            f"({series['closest_pair']}, t = {series['closest_time']:.3f} s"
        )
        if series.get("clearance_m") is not None:
            text += f", margin {series['clearance_m'] * 1000:.0f} mm"
        text += ")"
    text += "".join(f"; {c}" for c in series_unchecked(series))
    return text
