"""The verdict of an ``ident run`` and what it judges: the executed elite, its estimate.

The verdict is decided once, by :func:`ident.identify.assessment.verdict.decide_verdict`, when the
run's ``result.json`` is written (:func:`verdict_entry`), and every renderer (terminal, report.md,
report.html, ``ident report``) reads that entry (:func:`stored_verdict`). It judges the *executed*
elite, the one ``trajectory.csv`` runs (``executed_elite`` in ``result.json``), and the estimator
the report leads with (WLS when it ran). A run measured by a simulated log is judged by
:func:`~ident.identify.assessment.verdict.log_evidence` on that log's identification with the
simulator's truth, the same evidence ``ident identify`` gathers on the saved log.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ident.identify.assessment.verdict import (
    Evidence,
    Truth,
    Verdict,
    decide_verdict,
    log_evidence,
)
from ident.report.safety_section import series_unchecked

__all__ = [
    "executed_elite",
    "headline_method",
    "run_warnings",
    "stored_verdict",
    "validation_residual",
    "verdict_entry",
]


def executed_elite(data: dict[str, Any]) -> dict[str, Any] | None:
    """The ``result.json`` entry of the executed elite (elite 1 in files that do not say)."""
    elites = data.get("elites") or []
    if not elites:
        return None
    rank = data.get("executed_elite", data.get("chosen_elite"))
    for e in elites:
        if isinstance(rank, int) and e.get("rank") == rank:
            return e
    return elites[0]


def headline_method(elite: dict[str, Any] | None) -> str | None:
    """The estimator the headline reports: WLS when it ran, else the first one."""
    if not elite or not elite["estimates"]:
        return None
    return "wls" if "wls" in elite["estimates"] else next(iter(elite["estimates"]))


def validation_residual(data: dict[str, Any], method: str | None) -> float | None:
    """The relative residual on the run's validation trajectory, when it has one."""
    val = data.get("validation")
    if not isinstance(val, dict):
        return None
    by_method = val.get("estimates", val)
    entry = by_method.get(method) if method and isinstance(by_method, dict) else None
    if not isinstance(entry, dict) or entry.get("relative_residual") is None:
        return None
    return float(entry["relative_residual"])


def run_warnings(data: dict[str, Any], elite: dict[str, Any] | None) -> list[str]:
    """The run's warnings without those of the executed elite's log identification."""
    warnings = list(data.get("warnings", []))
    if data.get("status") == "incomplete":  # "running": the folder is being written
        warnings.insert(0, f"incomplete run: {data.get('message')}")
    if elite:
        warnings += [f"elite {elite['rank']}, {m}: {msg}" for m, msg in elite["failures"].items()]
    return warnings


def _safe(data: dict[str, Any]) -> bool | None:
    safety = data.get("safety")
    ok = safety.get("ok") if isinstance(safety, dict) else None
    return None if ok is None else bool(ok)


def _dict_evidence(data: dict[str, Any]) -> Evidence:
    """The evidence of a run from ``result.json`` alone (truth known)."""
    elite = executed_elite(data)
    method = headline_method(elite)
    warnings = tuple(run_warnings(data, elite))
    if elite is None or method is None:
        return Evidence(
            estimated=False,
            residual_where="no estimate",
            warnings=warnings,
            safe=_safe(data),
            truth=True,
        )
    est = elite["estimates"][method]
    residual = validation_residual(data, method)
    where = "validation trajectory"
    if residual is None:
        residual, where = est.get("relative_residual"), "identification trajectory"
    worst = est.get("max_rel_error_major_percent")
    if worst is None and est.get("max_rel_error_major") is not None:
        worst = 100.0 * est["max_rel_error_major"]
    names = (data.get("stage") or {}).get("base_names") or []
    i = est.get("worst_major")
    return Evidence(
        residual=residual,
        residual_where=where,
        worst_error_percent=worst,
        worst_error_name=names[i] if isinstance(i, int) and i < len(names) else None,
        warnings=warnings,
        safe=_safe(data),
        truth=True,
    )


def verdict_entry(result: Any, data: dict[str, Any]) -> dict[str, Any]:
    """The ``verdict`` entry of ``result.json`` (label, reason, rule, elite, method, warnings).

    ``data`` is the rest of ``result.json`` (:func:`ident.report.run_data.result_to_dict`).
    """
    elite = executed_elite(data)
    method = headline_method(elite)
    outcome = None
    if elite is not None:
        outcome = next((e for e in result.elites if e.rank == elite["rank"]), None)
    # the log's identification (None for an ideal measurement or a log that did not identify)
    identified = getattr(getattr(outcome, "log", None), "result", None)
    stage = result.stage
    if identified is not None and stage is not None and stage.reference_share is not None:
        truth = Truth(
            names=tuple(stage.base_names),
            values=np.asarray(stage.true_base, dtype=float),
            reference_share=np.asarray(stage.reference_share, dtype=float),
        )
        evidence = log_evidence(
            identified, truth=truth, safe=_safe(data), extra_warnings=run_warnings(data, elite)
        )
    else:
        evidence = _dict_evidence(data)
    entry = _entry(decide_verdict(evidence), evidence, elite, method)
    if stage is not None and stage.name == "payload":  # what the label is about
        entry["reason"] += (
            "; it judges the design on the bare last body's 10 parameters: the payload itself "
            "comes from `ident payload` on a log with it"
        )
    # the certificate's checks left out (self-collision off), said with the label
    entry["reason"] += "".join(
        f"; {c}" for c in series_unchecked((elite or {}).get("safety_series"))
    )
    return entry


def _entry(
    v: Verdict, e: Evidence, elite: dict[str, Any] | None, method: str | None
) -> dict[str, Any]:
    return {
        **v.as_dict(),
        "elite": None if elite is None else elite["rank"],
        "method": method,
        "residual": _finite(e.residual),
        "residual_where": e.residual_where,
        "nominal_residual": _finite(e.nominal_residual),
        "worst_error_percent": _finite(e.worst_error_percent),
        "worst_error_name": e.worst_error_name,
        "worst_std_percent": _finite(e.worst_std_percent),
        "worst_std_name": e.worst_std_name,
        "std_method": e.std_method,
        "n_inconsistent": e.n_inconsistent,
        "n_links": e.n_links,
        "warnings": list(e.warnings),
    }


def _finite(value: float | None) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def stored_verdict(data: dict[str, Any]) -> dict[str, Any]:
    """The verdict entry of a ``result.json`` (decided again from the file when an older
    file has none)."""
    entry = data.get("verdict")
    if isinstance(entry, dict) and "label" in entry:
        return entry
    evidence = _dict_evidence(data)
    elite = executed_elite(data)
    return _entry(decide_verdict(evidence), evidence, elite, headline_method(elite))
