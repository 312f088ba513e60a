"""``report.md`` of ``ident identify``, section by section: the title, the summary table
(:func:`_headline`), the processing steps and residuals, the held-out validation, the friction
models, the base parameters, the essential ones, the simulator's truth, the cautious URDF copy,
the physical consistency and the timings (:func:`_markdown` puts them in order).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ident.identify.assessment.metrics import MAJOR_SHARE, error_measures, parameter_unit
from ident.identify.assessment.rollout import rollout_text
from ident.identify.assessment.verdict import (
    VERDICT_RULE,
    VERDICT_RULE_REAL,
    Verdict,
    truth_from_config,
)
from ident.identify.estimators.summary import consistency_summary
from ident.identify.model_files.urdf_update import UrdfUpdate
from ident.identify.pipeline.real import IdentifyResult
from ident.identify.refinement.rollout_refinement import refinement_text
from ident.report.format import pct, percent
from ident.report.headline import Headline, headline_markdown
from ident.report.identify_result import _robot_file, joint_torque_units, verdict_entry
from ident.report.model_section import model_section
from ident.report.uncertainty_section import (
    interval_cell,
    model_intervals_markdown,
    uncertainty_markdown,
)

__all__ = ["friction_models_lines"]


def _num(value: float | None, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    return f"{value:.{digits}g}"


def friction_models_lines(result: IdentifyResult) -> list[str]:
    """Markdown of the friction-model comparison (empty without one)."""
    comparison = result.friction
    if comparison is None:
        return []
    where = "held-out" if comparison.on_held_out else "identification (no held-out part)"
    lines = [
        "## Friction models",
        "",
        f"Each model fitted with the rest of the parameters (`docs/friction.md`), ranked by the "
        f"{where} relative residual. Winner: **{comparison.winner}**, "
        f"{100 * comparison.improvement():.2f} % below `{comparison.baseline}`.",
        "",
        "| model | held-out relative residual [%] | fit relative residual [%] |",
        "| --- | --- | --- |",
    ]
    lines += [
        f"| {f.model} | {_num(100 * f.held_out_residual, 4)} | {_num(100 * f.fit_residual, 4)} |"
        for f in comparison.fits
    ]
    refused = [f for f in comparison.fits if f.ambiguous]
    if refused:
        lines += [""] + [f"- `{f.model}` is not picked: {f.ambiguous}." for f in refused]
    return [*lines, ""]


def _markdown(
    result: IdentifyResult,
    urdf: UrdfUpdate,
    urdf_name: str | None,
    replay_note: str = "",
    model: dict | None = None,
    rollout: dict | None = None,
    refinement: dict | None = None,
) -> str:
    """report.md of an identification: its sections in order."""
    units = joint_torque_units(result)
    lines = [
        *_title_lines(result, replay_note),
        *headline_markdown(_headline(result, urdf, model, rollout, refinement)),
        *model_section(model, urdf_name),
        *model_intervals_markdown(result),
        "## Identified vs reference parameters",
        "",
        "![Identified base parameters: relative deviation from the reference (or the URDF's "
        "nominal values) with ±3σ bars](figures/parameters.png)",
        "",
        "![measured vs predicted torque](figures/torque_validation.png)",
        "",
        *_processing_section(result, units),
    ]
    lines += _held_out_section(result, result.joint_names, units)
    lines += ["", *friction_models_lines(result)]
    lines += [] if result.actuator is None else result.actuator.lines()
    lines += _base_parameter_section(result, units)
    lines += _essential_section(result)
    lines += _truth_section(result)
    lines += uncertainty_markdown(result)
    lines += _urdf_section(urdf, urdf_name)
    lines += _consistency_section(result)
    lines += ["", "## Timings", "", "| stage | seconds |", "| --- | --- |"]
    lines += [f"| {k} | {v:.3f} |" for k, v in result.timings.items()]
    return "\n".join(lines) + "\n"


def _title_lines(result: IdentifyResult, replay_note: str) -> list[str]:
    """Title and the paragraph naming the config, URDF, estimator and replay."""
    pm, est = result.parameters, result.estimate
    return [
        f"# Identification of `{result.config.name}` from a measured log",
        "",
        f"Config: `{result.config.source}`. URDF: `{_robot_file(result).name}`. "
        f"Estimator: **{est.method.upper()}** on {est.n_observations} rows "
        f"({len(pm.base_names)} base parameters). "
        + (
            "Motion replay: [replay.html](replay.html) (the measured motion, opens offline in a "
            f"browser; `ident replay` on this folder shows it live). {replay_note}"
            if replay_note.startswith("replay.html written")
            else f"Motion replay: not available. {replay_note}"
        ),
        "",
    ]


def _processing_section(result: IdentifyResult, units: Sequence[str]) -> list[str]:
    """The processing steps, and the residual RMS and σ per joint on the identification part
    (in the joint's torque ``units``)."""
    est = result.estimate
    lines = ["## Processing", "", "| step | what |", "| --- | --- |"]
    lines += [f"| {r['step']} | {r['detail']} |" for r in result.records]
    lines += [
        "",
        "## Residuals on the identification part",
        "",
        "| joint | residual RMS | sigma used |",
        "| --- | --- | --- |",
    ]
    lines += [
        f"| {n} | {_num(est.residual_rms[j])} {units[j]} | {_num(est.sigma[j])} {units[j]} |"
        for j, n in enumerate(result.joint_names)
    ]
    return lines


def _base_parameter_section(result: IdentifyResult, units: Sequence[str]) -> list[str]:
    """Markdown of the base parameters: value, σ, interval, reference and URDF nominal."""
    sd = result.parameter_std
    pm, est = result.parameters, result.estimate
    lines = [
        "## Base parameters",
        "",
        result.reference_note,
        "",
        f"σ: the {sd.method} standard deviation, the one the verdict, the warnings and the "
        "cautious URDF copy use (docs/uncertainty.md)" + (f"; {sd.note}." if sd.note else "."),
        "",
        "| # | base parameter | unit | value | σ [%] | 95 % interval | reference | ref. σ [%] | "
        "URDF nominal | expression |",
        "| ---: | :--- | :--- | ---: | ---: | ---: | ---: | ---: | ---: | :--- |",
    ]
    by_ours = {row["ours"]: row for row in result.comparison if row["ours"]}
    expressions = pm.base.expressions()
    for k, name in enumerate(pm.base_names):
        row = by_ours.get(name)
        ref = _num(row["reference_value"]) if row else "-"
        ref_std = _num(row["reference_relative_std_pct"], 3) if row else "-"
        nominal = float(pm.base.projection[k] @ pm.nominal)
        # round-off of the structural K times nominal inertias (friction has no nominal value)
        nominal = 0.0 if abs(nominal) < 1e-12 else nominal
        lines.append(
            f"| {k + 1} | {name} | {parameter_unit(name, units) or '-'} | {_num(est.x[k])} | "
            f"{_num(sd.relative_std[k], 3)} | {interval_cell(result, k)} | {ref} | "
            f"{ref_std} | {_num(nominal)} | `{expressions[k]}` |"
        )
    sums = [row for row in result.comparison if row["match"] == "coupling basis"]
    if sums:
        lines += [
            "",
            "Coupled wrist, reference basis (sums of our parameters):",
            "",
            f"| reference | value | ref. rel. std [%] | ours | value | rel. std [%] "
            f"({sums[0].get('std_method', 'ordinary')} σ) |",
            "| --- | --- | --- | --- | --- | --- |",
        ]
        lines += [
            f"| {r['reference']} | {_num(r['reference_value'])} | "
            f"{_num(r['reference_relative_std_pct'], 3)} | {r['ours']} | {_num(r['value'])} | "
            f"{_num(r['relative_std_pct'], 3)} |"
            for r in sums
        ]
    unmatched = [row["reference"] for row in result.comparison if row["match"] == "none"]
    if unmatched:
        lines += [
            "",
            "Reference parameters without a counterpart here: "
            + ", ".join(f"`{u}`" for u in unmatched),
        ]
    return lines


def _held_out_section(
    result: IdentifyResult, names: Sequence[str], units: Sequence[str]
) -> list[str]:
    """Markdown of the held-out validation: RMSE and relative residual per joint and model."""
    lines = [
        "",
        "## Held-out validation",
        "",
        "Torque prediction on the last part of the log, never used to identify. Errors on the "
        "rows above the velocity threshold (the rows the model was identified on; at standstill "
        "the Coulomb term `sign(dq)` follows noise). The dataset's reference values were "
        "identified on the whole log, held-out part included.",
        "",
        "| parameters | "
        + " | ".join(f"RMSE {n} [{u}]" for n, u in zip(names, units, strict=True))
        + " | relative residual [%] | all samples: relative residual [%] |",
        "| --- |" + " --- |" * (len(names) + 2),
    ]
    for label, p in result.predictions.items():
        lines.append(
            f"| {label} | "
            + " | ".join(_num(v) for v in p.metrics.rmse)
            + f" | {_num(100 * p.metrics.total_relative_residual, 3)} | "
            f"{_num(100 * p.metrics_all.total_relative_residual, 3)} |"
        )
    lines += [
        "",
        "| parameters | " + " | ".join(f"rel. residual {n} [%]" for n in names) + " |",
        "| --- |" + " --- |" * len(names),
    ]
    for label, p in result.predictions.items():
        lines.append(
            f"| {label} | "
            + " | ".join(_num(100 * v, 3) for v in p.metrics.relative_residual)
            + " |"
        )
    return lines


def _essential_section(result: IdentifyResult) -> list[str]:
    """Markdown of the essential-parameter reduction (empty without one)."""
    ess = result.essential
    if ess is None:
        return []
    pm = result.parameters
    lines: list[str] = []
    lines += [
        "",
        "## Essential parameters",
        "",
        f"{len(ess.kept)} of {len(pm.base_names)} kept; relative residual "
        f"{ess.estimate.relative_residual:.4f}; stopped because {ess.stop_reason}.",
        "",
        "The relative std of this section is the ordinary one of each reduced least-squares "
        "solve: the backward-elimination rule re-solves the reduced problem at every step "
        "and ranks by that σ, as the published rule does. The base-parameter table's σ is "
        "the calibrated one.",
        "",
        "| parameter | value | rel. std [%] (ordinary σ) |",
        "| --- | --- | --- |",
    ]
    lines += [
        f"| {n} | {_num(v)} | {_num(s, 3)} |"
        for n, v, s in zip(
            ess.estimate.names, ess.estimate.x, ess.estimate.relative_std, strict=True
        )
    ]
    if result.reference_essential:
        ref_rows = result.reference_essential
        in_both = [r for r in ref_rows if r["in_our_essential_set"]]
        ours_only = set(ess.estimate.names) - {
            m for r in ref_rows if r["ours"] for m in r["ours"].split(" + ")
        }
        lines += [
            "",
            f"Reference essential set: {len(ref_rows)} parameters, {len(in_both)} of them "
            "also essential here; not essential here: "
            + (
                ", ".join(f"`{r['reference']}`" for r in ref_rows if not r["in_our_essential_set"])
                or "none"
            )
            + "; essential here only: "
            + (", ".join(sorted(ours_only)) or "none")
            + ".",
        ]
    if ess.dropped:
        lines += [
            "",
            "Dropped, in order: "
            + ", ".join(f"{d['name']} ({d['relative_std_pct']:.3g} %)" for d in ess.dropped),
        ]
    return lines


def _truth_section(result: IdentifyResult) -> list[str]:
    """The major parameters against the simulator's truth (``validation.truth``), if any."""
    truth = truth_from_config(result.config.validation.truth)
    est = result.estimate
    if truth is None or tuple(est.names) != truth.names:
        return []
    sd = result.parameter_std
    m = error_measures(est.x, sd.std, truth.values, reference_share=truth.reference_share)
    lines = [
        "",
        "## Major parameters against the simulator's truth",
        "",
        "The log was simulated (`validation.truth`, written by `ident run`): the verdict judges "
        f"the base parameters with a reference torque share >= {100 * MAJOR_SHARE:g} % (the "
        "run's major parameters) by their error against the true values.",
        "",
        "| base parameter | true | identified | σ [%] | error [%] |",
        "| :--- | ---: | ---: | ---: | ---: |",
    ]
    for k, major in enumerate(m["major"]):
        if major:
            lines.append(
                f"| {est.names[k]} | {_num(float(truth.values[k]))} | {_num(float(est.x[k]))} | "
                f"{_num(float(sd.relative_std[k]), 3)} | "
                f"{_num(m['rel_error_percent'][k], 3)} |"
            )
    return lines


def _urdf_section(urdf: UrdfUpdate, urdf_name: str | None) -> list[str]:
    """Per link: the parameters written, kept nominal (and why), and the consistency check."""
    threshold = f"{urdf.max_relative_std_pct:g} %"
    copy = (
        f"`{urdf_name}` is a copy of the URDF"
        if urdf_name is not None
        else "The cautious copy (`urdf_update.cautious: true` writes it as `<urdf>_cautious.urdf`; "
        "not written here) is the URDF"
    )
    lines = [
        "",
        "## Cautious URDF copy",
        "",
        f"{copy} in which a standard inertial parameter is replaced "
        f"only if a base parameter determines it alone, its relative std is below {threshold} "
        "(config `urdf_update.max_relative_std_pct`), and its link stays physically consistent "
        "(mass > 0, inertia about the centre of mass positive semi-definite, triangle "
        "inequality); otherwise the link keeps the URDF's values. Parameters are about the "
        "joint-frame origin (the URDF stores the centre of mass and the inertia about it).",
        "",
        f"| link | written | kept nominal: rel. std >= {threshold} | kept nominal: not determined "
        "alone | result |",
        "| --- | --- | --- | --- | --- |",
    ]
    for link in urdf.links:
        written = ", ".join(link.written) or "-"
        uncertain = ", ".join(f"{k} ({_num(v, 3)} %)" for k, v in link.uncertain.items()) or "-"
        if link.rejected:
            uncertain = (uncertain + "; " if uncertain != "-" else "") + (
                ", ".join(link.rejected) + " (would make the link inconsistent)"
            )
        state = {
            "updated": "updated, consistent",
            "nominal": "nominal (nothing to write)",
            "nominal (inconsistent)": f"nominal: with the identified values, {link.problem}",
        }[link.status]
        lines.append(
            f"| {link.link} | {written} | {uncertain} | {', '.join(link.not_determined) or '-'} "
            f"| {state} |"
        )
    if urdf.written:
        lines += [
            "",
            "| parameter | URDF | identified | rel. std [%] |",
            "| --- | --- | --- | --- |",
        ]
        lines += [
            f"| {k} | {_num(a)} | {_num(b)} | {_num(link.relative_std_pct[k], 3)} |"
            for link in urdf.links
            for k, (a, b) in link.written.items()
        ]
    else:
        lines += [
            "",
            "Nothing was written: the copy has the URDF's inertial parameters (the base "
            "parameters above are what the data support).",
        ]
    return lines


def _consistency_section(result: IdentifyResult) -> list[str]:
    """Per estimator and link: physically consistent or not (data from
    :func:`~ident.identify.estimators.summary.consistency_summary`)."""
    summary = consistency_summary(result)
    if summary is None:
        return []
    estimators = summary["estimators"]
    links = [c["link"] for c in next(iter(estimators.values()))["links"]]
    lines = [
        "",
        "## Physical consistency",
        "",
        "Per link: consistent (mass > 0, inertia about the centre of mass positive "
        "semi-definite, triangle inequality) and the smallest eigenvalue of the 4x4 "
        "pseudo-inertia. OLS/WLS estimate base parameters only: their links are the standard "
        "parameters closest to the URDF's with the same base values. Residuals are relative "
        "(identification rows; held-out rows above the velocity threshold).",
        "",
        "| estimator | relative residual [%] | held-out relative residual [%] | "
        "distance to URDF | " + " | ".join(links) + " |",
        "| --- | --- | --- | --- | " + " | ".join("---" for _ in links) + " |",
    ]
    for name, e in estimators.items():
        cells = [
            ("yes" if c["consistent"] else "**no**")
            + f" ({_num(c['min_pseudo_inertia_eigenvalue'], 3)})"
            for c in e["links"]
        ]
        lines.append(
            f"| {name} | {_num(percent(e['relative_residual']), 3)} | "
            f"{_num(percent(e['held_out_relative_residual']), 3)} "
            f"| {_num(e['distance_to_nominal'], 3)} | " + " | ".join(cells) + " |"
        )
    model = summary["model"]
    priors = [(summary["method"], summary["regularization"], summary["seconds"], "")]
    if model is not None:
        priors.append(
            (model["method"], model["regularization"], model["seconds"], " (the identified model)")
        )
    for method, reg, seconds, role in priors:
        if reg is None:
            continue
        how = f"chosen on the {reg['chosen_on']}" if reg["chosen_on"] else "from the config"
        lines += [
            "",
            f"{method}{role}: prior weight {reg['weight']:g} toward the URDF ({how}) on "
            + (
                "the directions the data do not see"
                if reg["directions"] == "unseen"
                else "every inertial direction"
            )
            + "; friction "
            + (
                "held at the WLS values where positive"
                if reg["friction"] == "least_squares"
                else "estimated with the constraints"
            )
            + f"; {seconds:.2f} s.",
        ]
    return lines


def _headline(
    result: IdentifyResult,
    urdf: UrdfUpdate,
    model: dict | None = None,
    rollout: dict | None = None,
    refinement: dict | None = None,
) -> Headline:
    """The headline facts of an identification from a log, from its verdict entry (the one
    :func:`result_dict` writes; :mod:`ident.identify.assessment.verdict`)."""
    est = result.estimate
    v = verdict_entry(result)
    truth = v["rule"] == "truth"
    return Headline(
        verdict=Verdict(v["label"], v["reason"], v["rule"]),
        rule=VERDICT_RULE if truth else VERDICT_RULE_REAL,
        worst=(
            pct(v["worst_error_percent"]) + f" ({v['worst_error_name']}; against the "
            "simulator's truth, validation.truth)"
            if truth
            else "— (a real log: no true values; see the relative std below)"
        ),
        worst_label="Worst error, major parameters",
        residual=_headline_residual(result, v),
        residual_label="Torque residual, held-out data",
        condition=f"{est.condition_number:.4g} (base observation matrix, {est.method.upper()})",
        consistency=_headline_consistency(result, urdf, model, v),
        safety="not checked (a measured log: the motion was already executed)",
        warnings=list(v["warnings"]),
        extra=[
            *_headline_extra(result, v),
            ("MJCF rollout", rollout_text(rollout)),
            *_refinement_row(refinement),
        ],
    )


def _headline_residual(result: IdentifyResult, v: dict) -> str:
    """The verdict's torque residual, where it was measured, and the other estimators'."""
    residual = v["residual"]
    judged = v["method"] if v["method"] in result.predictions else "identified"
    others = ", ".join(
        f"{label}: {pct(100 * p.metrics.total_relative_residual)}"
        for label, p in result.predictions.items()
        if label != judged
    )
    where = (
        "held-out part of the log"
        if v["residual_where"] == "held-out data"
        else ("identification rows (no held-out part)")
    )
    return (
        "—"
        if residual is None
        else f"{pct(100 * residual)} on the {where}, {judged}" + (f" ({others})" if others else "")
    )


def _headline_consistency(
    result: IdentifyResult, urdf: UrdfUpdate, model: dict | None, v: dict
) -> str:
    """Physical consistency of the links, the identified model's files and the cautious copy."""
    written = [link for link in urdf.links if link.status == "updated"]
    rejected = [link for link in urdf.links if link.status == "nominal (inconsistent)"]
    if v["n_links"]:
        n_bad = v["n_inconsistent"] or 0
        consistency = (
            f"{v['method']}: {v['n_links'] - n_bad} of {v['n_links']} links physically "
            "consistent (see the consistency section)"
        )
        if n_bad:
            consistency = "**violated**, " + consistency
    else:
        consistency = "not checked"
    if model is not None:  # the model estimator's contract, never its name, says it
        consistency += (
            f"; identified model ({model['method']}, every link consistent): "
            f"`{model['files']['urdf']}`, `{model['files']['mjcf']}`"
            if model["written"]
            else f"; {model['note']}"
        )
    if result.config.urdf_update.cautious and (written or rejected):
        consistency += (
            f"; cautious copy: {len(written)} links updated and consistent, {len(rejected)} "
            "kept nominal because the identified values are inconsistent"
        )
    return consistency


def _headline_extra(result: IdentifyResult, v: dict) -> list[tuple[str, str]]:
    """The headline's extra rows: the least-squares message, the fit and the worst σ."""
    est = result.estimate
    return [
        (
            "Least squares",
            est.message
            if not v["warnings"]
            else f"{est.message}; the result is NOT ok (warnings below)",
        ),
        ("Fit on the identification rows", f"relative residual {pct(100 * est.relative_residual)}"),
        (
            f"Worst relative std, parameters carrying >= {100 * MAJOR_SHARE:g} % of the torques",
            "—"
            if v["worst_std_percent"] is None
            else f"σ {pct(v['worst_std_percent'])} ({v['worst_std_name']}; "
            f"{v.get('std_method') or 'ordinary'} σ)",
        ),
    ]


def _refinement_row(entry: dict | None) -> list[tuple[str, str]]:
    """The summary's row of result.json's ``refinement`` entry (none when not asked for)."""
    text = refinement_text(entry)
    return [] if text is None else [("MJCF refinement", text)]
