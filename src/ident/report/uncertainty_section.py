"""The identify report's intervals and what the data cannot see (rendering only).

Everything shown is computed by :mod:`ident.identify.estimation.uncertainty` and
:mod:`ident.identify.assessment.identifiability` in the identification core and read from the
:class:`~ident.identify.pipeline.core.IdentifyResult`.
"""

from __future__ import annotations

from typing import Any

from ident.identify.estimation.uncertainty import z_value

__all__ = [
    "interval_cell",
    "model_intervals_json",
    "model_intervals_markdown",
    "uncertainty_json",
    "uncertainty_markdown",
]

_LABELS = {
    "ordinary": "ordinary (independent residuals)",
    "hac": "HAC (Newey-West)",
    "bootstrap": "moving-block bootstrap",
}


def interval_cell(result: Any, k: int, level: float = 0.95) -> str:
    """``[lo, hi]`` of base parameter ``k`` by the default method, or ``-``."""
    unc = result.uncertainty
    if unc is None:
        return "-"
    lo, hi = unc.interval(level)[k]
    return f"[{lo:.4g}, {hi:.4g}]"


def uncertainty_json(result: Any) -> dict | None:
    """``result.json``'s ``uncertainty`` entry: the summary, per-parameter intervals and
    standard deviations by method, and the standard parameters the data cannot separate."""
    unc = result.uncertainty
    ident = result.identifiability
    out: dict = {}
    if unc is not None:
        out = dict(result.uncertainty_summary or {})
        out["parameters"] = [
            {
                "name": name,
                "interval_95": [float(v) for v in unc.interval(0.95)[k]],
                "std": {m: float(unc.std(m)[k]) for m in unc.covariance},
            }
            for k, name in enumerate(unc.names)
        ]
    if ident is not None:
        out["identifiability"] = {
            "only_in_combination": {
                n: list(e)
                for n, kind, e in zip(ident.names, ident.kind, ident.enters, strict=True)
                if kind == "combination"
            },
            "not_seen": list(ident.of_kind("none")),
        }
        if unc is not None:  # the standard parameters the data determine alone
            value, std = ident.standard_values(unc.x, unc.covariance[unc.method])
            half = z_value(0.95) * std
            out["identifiability"]["alone"] = [
                {
                    "name": n,
                    "value": float(value[i]),
                    "interval_95": [float(value[i] - half[i]), float(value[i] + half[i])],
                }
                for i, n in enumerate(ident.names)
                if ident.kind[i] == "alone"
            ]
    return out or None


def uncertainty_markdown(result: Any) -> list[str]:
    """The report's section: method, coverage lines, disagreeing methods, unseen parameters."""
    unc = result.uncertainty
    summary = result.uncertainty_summary
    lines = ["", "## Intervals and what the data cannot see", ""]
    if unc is None or summary is None:
        lines.append("Intervals: not available (too few identification rows for them).")
    else:
        lines += [
            f"Intervals (95 %) use the **{_LABELS[unc.method]}** covariance: residuals of "
            "neighbouring samples are correlated (filters, differentiation, closed loop), "
            "which the ordinary covariance ignores. Bandwidth / bootstrap run length "
            f"{unc.bandwidth:.0f} blocks of {unc.block_samples} decimated sample(s) "
            f"({unc.n_blocks} blocks, {unc.n_boot} bootstrap resamples; "
            "docs/uncertainty.md).",
            "",
            "| method | held-out torques inside 95 % prediction interval |"
            + (" true base parameters inside 95 % interval |" if summary["truth_inside"] else ""),
            "| :--- | ---: |" + (" ---: |" if summary["truth_inside"] else ""),
        ]
        held = summary["held_out_inside"] or {}
        truth = summary["truth_inside"] or {}
        for m in ("ordinary", "hac", "bootstrap"):
            mark = " (used)" if m == unc.method else ""
            cells = [f"{100 * held[m]:.1f} %" if m in held else "-"]
            if truth:
                cells.append(f"{100 * truth[m]:.1f} %")
            lines.append(f"| {_LABELS[m]}{mark} | " + " | ".join(cells) + " |")
        if summary["disagreeing"]:
            lines += [
                "",
                "HAC and bootstrap standard deviations differ by more than 1.5x for: "
                + ", ".join(summary["disagreeing"])
                + " (trust the larger).",
            ]
    ident = result.identifiability
    if ident is not None:
        groups: dict[str, list[str]] = {}  # base parameters entered -> standard parameters
        for name, kind, enters in zip(ident.names, ident.kind, ident.enters, strict=True):
            if kind == "combination":
                key = ", ".join(e.split(" = ")[0] for e in enters)
                groups.setdefault(key, []).append(name)
        combined = [f"{', '.join(v)}: only in combination, in {k}" for k, v in groups.items()]
        unseen = ident.of_kind("none")
        lines += [
            "",
            f"Standard parameters: {len(ident.of_kind('alone'))} determined alone by the data, "
            f"{len(ident.of_kind('combination'))} only in combination, "
            f"{len(ident.of_kind('none'))} not seen. A written model's values of the last two "
            "kinds come from the prior (the URDF's nominal values) along what the data do not "
            "see, not from the data (the base parameters' expressions are in the table above):",
            "",
            *[f"- {line}" for line in combined],
            *([f"- not seen at all: {', '.join(unseen)}"] if unseen else []),
        ]
    return lines


def _seen(result: Any, name: str) -> str | None:
    """What the data see of standard parameter ``name``: alone, combination, none (None if
    unknown)."""
    ident = result.identifiability
    if ident is None or name not in ident.names:
        return None
    return str(ident.kind[list(ident.names).index(name)])


def model_intervals_json(result: Any) -> dict | None:
    """``result.json``'s ``model_intervals``: the bootstrap of the written model's constrained
    fit (:mod:`ident.identify.assessment.model_intervals`), every written standard parameter's
    value, σ and 95 % interval, and what the data see of it (no times: those are in
    ``run.json``)."""
    mi = result.model_intervals
    if mi is None:
        note = getattr(result, "model_intervals_note", "")
        return {"note": note} if note else None
    lo_hi = mi.interval(0.95)
    return {
        "method": mi.method,
        "n_boot": mi.n_boot,
        "n_failed": mi.n_failed,
        "block_length_blocks": mi.block_length,
        "level": 0.95,
        "parameters": [
            {
                "name": name,
                "value": float(mi.theta[i]),
                "std": float(mi.std[i]),
                "interval_95": [float(lo_hi[i, 0]), float(lo_hi[i, 1])],
                "seen": _seen(result, name),
            }
            for i, name in enumerate(mi.names)
        ],
    }


def model_intervals_markdown(result: Any) -> list[str]:
    """The model section's table of the written standard parameters with their intervals."""
    mi = result.model_intervals
    if mi is None:
        note = getattr(result, "model_intervals_note", "")
        return [f"Intervals of the written model: {note}.", ""] if note else []
    lo_hi = mi.interval(0.95)
    lines = [
        f"95 % intervals of the written standard parameters: {mi.n_boot} moving-block "
        f"bootstrap resamples (runs of {mi.block_length} blocks, as the base parameters'), "
        f"the {mi.method.upper()} fit re-solved on each"
        + (f" ({mi.n_failed} failed, left out)" if mi.n_failed else "")
        + "; value ± 1.96 σ of the re-estimates (docs/uncertainty.md). *Seen*: alone, the "
        "interval is on the parameter; in combination or not seen, the prior (the URDF) "
        "decides the value along what the data do not see, and the interval is the written "
        "value's spread, not an interval on the true one.",
        "",
        "| parameter | value | σ | 95 % interval | seen by the data |",
        "| :--- | ---: | ---: | ---: | :--- |",
    ]
    lines += [
        f"| {n} | {mi.theta[i]:.4g} | {mi.std[i]:.2g} | [{lo_hi[i, 0]:.4g}, {lo_hi[i, 1]:.4g}] "
        f"| {_seen(result, n) or '-'} |"
        for i, n in enumerate(mi.names)
    ]
    return [*lines, ""]
