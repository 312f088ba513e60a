"""The identify report's intervals and what the data cannot see (rendering only).

Everything shown is computed by :mod:`ident.identify.uncertainty` and
:mod:`ident.identify.identifiability` in the identification core and read from the
:class:`~ident.identify.core.IdentifyResult`.
"""

from __future__ import annotations

from typing import Any

from ident.identify.uncertainty import z_value

__all__ = ["interval_cell", "uncertainty_json", "uncertainty_markdown"]

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
