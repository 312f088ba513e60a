"""Report of ``ident identify``: report.md, report.html, result.json, parameters.csv, plots,
the identified model (URDF, MJCF, joint extras; :mod:`ident.identify.model_files.files`).

Everything is written into an existing run folder through atomic writes; the HTML page embeds
its figures (base64 PNG, readable offline). ``result.json`` holds no times, so the same config
gives the same file; timings go to ``run.json`` (the caller's run folder state).
"""

from __future__ import annotations

import csv
import io
import json
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ident.dynamics.friction_models import get_friction_model
from ident.fileio import atomic_write_bytes, atomic_write_text
from ident.identify.assessment.metrics import MAJOR_SHARE, error_measures, parameter_unit
from ident.identify.assessment.rollout import identify_rollout, rollout_text
from ident.identify.assessment.verdict import (
    VERDICT_RULE,
    VERDICT_RULE_REAL,
    Verdict,
    identify_verdict,
    log_evidence,
    truth_from_config,
)
from ident.identify.estimators.summary import consistency_summary
from ident.identify.model_files.files import save_identified_model
from ident.identify.model_files.urdf_update import UrdfUpdate, update_urdf_inertials
from ident.identify.pipeline.real import IdentifyResult
from ident.report.format import pct, percent
from ident.report.headline import Headline, headline_markdown
from ident.report.model_section import model_section
from ident.report.uncertainty_section import (
    interval_cell,
    model_intervals_json,
    model_intervals_markdown,
    uncertainty_json,
    uncertainty_markdown,
)

__all__ = [
    "identified_urdf",
    "joint_torque_units",
    "result_dict",
    "save_identify_data",
    "torque_png",
    "write_identify_report",
    "write_measured_replay",
]

_PLOT_LABELS = ("identified", "reference")


def _num(value: float | None, digits: int = 4) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if isinstance(value, float) and math.isinf(value):
        return "inf"
    return f"{value:.{digits}g}"


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _robot_file(result: IdentifyResult) -> Path:
    """The robot file of the identification (a URDF, or a DH description)."""
    return Path(result.config.robot.path)


def _urdf_text(result: IdentifyResult) -> str:
    """The URDF of the identified robot (the file's text; generated for a DH description)."""
    if result.config.robot.urdf is not None:
        return Path(result.config.robot.urdf).read_text(encoding="utf-8")
    from ident.model.selection import load_robot

    return str(load_robot(result.config.robot).urdf_text)


def joint_torque_units(result: IdentifyResult) -> tuple[str, ...]:
    """Unit of each joint's torque, residuals and errors: ``"N*m"`` for a revolute joint,
    ``"N"`` for a prismatic one (:func:`ident.identify.assessment.sanity.joint_units` of the robot
    the config selects, the robot that was identified)."""
    from ident.identify.assessment.sanity import joint_units
    from ident.model.selection import load_robot

    model = load_robot(result.config.robot, source=result.config.source or "config").model
    return joint_units(model)


def torque_png(result: IdentifyResult) -> bytes:
    """Measured vs predicted torque per joint on the held-out part, as PNG bytes."""
    from ident.report.plots import torque_png as plot

    return plot(
        result.t_validate,
        result.tau_validate,
        {k: result.predictions[k].tau_pred for k in _PLOT_LABELS if k in result.predictions},
        result.joint_names,
        excluded=~result.keep_validate,
        xlabel="time [s] (held-out part; crosses: below the velocity threshold, not compared)",
        units=joint_torque_units(result),
    )


def identified_urdf(result: IdentifyResult) -> UrdfUpdate:
    """The cautious URDF copy (``urdf_update.cautious``, ``<urdf>_cautious.urdf``): the standard
    parameters that base parameters determine alone, where their relative std is below
    ``urdf_update.max_relative_std_pct`` and the link stays consistent. The relative std is
    the result's one standard deviation (:attr:`IdentifyResult.parameter_std`)."""
    pm = result.parameters
    est = result.estimate
    rel = result.parameter_std.relative_std  # the one σ (default interval method)
    identified = {}
    for k, i in enumerate(pm.base.independent):
        alone = not pm.base_names[k].endswith("R") and pm.inertial_index[i] >= 0
        if alone:
            identified[pm.names[i]] = (float(est.x[k]), float(rel[k]))
    from ident.dynamics.parameters import parameters_from_model
    from ident.model.selection import load_robot

    robot = load_robot(result.config.robot)  # the robot the identification used (chain, locks)
    return update_urdf_inertials(
        robot.urdf_text,
        result.joint_names,
        parameters_from_model(robot.model),
        identified,
        max_relative_std_pct=result.config.urdf_update.max_relative_std_pct,
        model=robot.model,  # its links fused through fixed and locked joints
    )


def write_measured_replay(
    result: IdentifyResult,
    folder: str | Path,
    *,
    replay: bool = True,
    package_dirs: Sequence[str | Path] = (),
) -> str:
    """Write the measured motion: ``trajectory.csv``, ``robot.urdf`` and ``replay.html``.

    ``trajectory.csv`` (format of :mod:`ident.trajectory`) and ``robot.urdf`` (a copy of the
    URDF used) let ``ident replay RUN_DIR`` show the run folder; ``replay.html`` is the static
    meshcat page (:func:`ident.viz.replay.replay_html`). ``package_dirs`` are searched for the
    URDF's ``package://`` meshes (``--package-dir``), then the original URDF's folder and its
    parent. A failing replay never raises: the returned one-line note says what happened, for
    the report and ``run.json``.
    """
    import warnings

    from ident.trajectory import trajectory_to_csv

    folder = Path(folder)
    motion = result.motion
    if motion is None:
        return f"no replay: {result.motion_note or 'no measured motion'}."
    atomic_write_text(folder / "trajectory.csv", trajectory_to_csv(motion))
    urdf_path = atomic_write_text(folder / "robot.urdf", _urdf_text(result))
    what = (
        f"measured motion, {motion.n_samples} samples at "
        f"{(motion.n_samples - 1) / (motion.t[-1] - motion.t[0]):.3g} Hz, "
        f"{motion.t[-1] - motion.t[0]:.2f} s"
    )
    if not replay:
        return f"replay skipped (--no-replay); {what} in trajectory.csv."
    try:
        from ident.viz.replay import replay_html, run_robot_selection

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            source = _robot_file(result).resolve().parent
            page = replay_html(
                # the identified chain: locked joints at their values, robot.package_dirs
                run_robot_selection(folder, result.config.robot, package_dirs),
                [motion],
                labels=[f"{result.config.name}: {what}"],
                package_dirs=[source, source.parent],
                package_hint="robot.package_dirs in the config (or --package-dir)",
            )
    except Exception as e:  # the replay is a convenience: a failure must not lose the result
        return f"no replay: {type(e).__name__}: {e}"
    atomic_write_text(folder / "replay.html", page)
    # e.g. missing meshes -> stick figure; name the copy, not this folder's absolute path
    notes = [str(w.message).replace(str(urdf_path), urdf_path.name).rstrip(".") for w in caught]
    return f"replay.html written ({what})" + "".join(f"; {n}" for n in notes) + "."


def result_dict(
    result: IdentifyResult,
    urdf: UrdfUpdate | None = None,
    replay_note: str | None = None,
    model: dict | None = None,
    *,
    rollout: dict | None = None,
) -> dict:
    """JSON-ready summary of the identification (no times); ``model``: the identified model's
    entry (:func:`~ident.identify.model_files.files.save_identified_model`), ``rollout`` its
    MJCF's rollout check (:func:`~ident.identify.assessment.rollout.identify_rollout`)."""
    pm = result.parameters
    est = result.estimate
    sd = result.parameter_std
    out = {
        "name": result.config.name,
        "method": est.method,
        "n_base_parameters": len(pm.base_names),
        "n_identification_rows": est.n_observations,
        "sampling_rate_after_decimation_hz": result.sampling_rate_hz,
        "relative_residual": est.relative_residual,
        "condition_number": est.condition_number,
        "residual_rms": dict(zip(result.joint_names, est.residual_rms.tolist(), strict=True)),
        "sigma": dict(zip(result.joint_names, est.sigma.tolist(), strict=True)),
        # residual_rms, sigma and the held-out errors: N*m per revolute joint, N per prismatic
        "joint_units": dict(zip(result.joint_names, joint_torque_units(result), strict=True)),
        "message": est.message,
        "status": result.status,
        "warnings": list(result.warnings),
        # std / relative_std_pct: the one σ every part of the result uses (std_method)
        "std_method": sd.method,
        "std_note": sd.note,
        "base_parameters": _base_parameters_entry(result),
        "unidentifiable": [pm.names[i] for i in pm.base.unidentifiable],
        "essential": _essential_entry(result),
        "validation": {
            label: {
                "above_velocity_threshold": p.metrics.as_dict(),
                "all_samples": p.metrics_all.as_dict(),
            }
            for label, p in result.predictions.items()
        },
        "reference_comparison": _finite_rows(result.comparison),
        "reference_note": result.reference_note,
        "reference_essential": _finite_rows(result.reference_essential),
        "processing": list(result.records),
    }
    if replay_note is not None:
        out["replay"] = replay_note
    if model is not None:
        out["model"] = model
    if rollout is not None:
        out["rollout"] = rollout
    if urdf is not None:
        out["urdf"] = _cautious_entry(result, urdf)
    out["consistency"] = consistency_summary(result)
    out["uncertainty"] = uncertainty_json(result)
    out["model_intervals"] = model_intervals_json(result)
    out["verdict"] = verdict_entry(result)
    if result.friction is not None:
        out["friction_models"] = friction_models_entry(result)
    if result.actuator is not None:  # a position servo's gains, delay, saturation
        out["actuator"] = result.actuator.summary()
    return out


def _base_parameters_entry(result: IdentifyResult) -> list[dict]:
    """One entry per base parameter: expression, value, the one σ, the ordinary σ, nominal."""
    pm = result.parameters
    est = result.estimate
    sd = result.parameter_std
    expressions = pm.base.expressions()
    return [
        {
            "name": name,
            "expression": expr,
            "value": float(est.x[k]),
            "std": float(sd.std[k]),
            "relative_std_pct": _finite(sd.relative_std[k]),
            "ordinary_std": float(est.std[k]),
            "nominal": float(pm.base.projection[k] @ pm.nominal),
        }
        for k, (name, expr) in enumerate(zip(pm.base_names, expressions, strict=True))
    ]


def _essential_entry(result: IdentifyResult) -> dict | None:
    """The essential-parameter estimate (None when not computed)."""
    essential = result.essential
    if essential is None:
        return None
    return {
        "names": list(essential.estimate.names),
        "values": essential.estimate.x.tolist(),
        "relative_std_pct": [_finite(v) for v in essential.estimate.relative_std],
        "relative_residual": essential.estimate.relative_residual,
        "dropped": list(essential.dropped),
        "stop_reason": essential.stop_reason,
    }


def _finite_rows(rows: Sequence[dict]) -> list[dict]:
    """``rows`` with every float made JSON-safe (non-finite -> None, :func:`_finite`)."""
    return [
        {k: (_finite(v) if isinstance(v, float) else v) for k, v in row.items()} for row in rows
    ]


def _cautious_entry(result: IdentifyResult, urdf: UrdfUpdate) -> dict:
    """The ``urdf`` entry of ``result.json``: the cautious copy, link by link."""
    return {
        "file": f"{_robot_file(result).stem}_cautious.urdf"
        if result.config.urdf_update.cautious
        else None,
        "max_relative_std_pct": urdf.max_relative_std_pct,
        "written": {k: list(v) for k, v in urdf.written.items()},
        "uncertain": {k: _finite(v) for k, v in urdf.uncertain.items()},
        "not_determined": list(urdf.not_determined),
        "inconsistent_links": urdf.inconsistent_links,
        "links": [
            {
                "link": link.link,
                "joint": link.joint,
                "status": link.status,
                "written": {k: list(v) for k, v in link.written.items()},
                "uncertain": {k: _finite(v) for k, v in link.uncertain.items()},
                "rejected": {k: list(v) for k, v in link.rejected.items()},
                "not_determined": list(link.not_determined),
                "problem": link.problem,
            }
            for link in urdf.links
        ],
    }


def friction_models_entry(result: IdentifyResult) -> dict:
    """``model.friction``'s comparison: models by held-out residual, the winner, its gain."""
    comparison = result.friction
    assert comparison is not None
    return {
        "ranked_on": "held-out rows" if comparison.on_held_out else "identification rows",
        "winner": comparison.winner,
        "baseline": comparison.baseline,
        "improvement_over_baseline": comparison.improvement(),
        "models": [
            {
                "model": f.model,
                "held_out_relative_residual": f.held_out_residual,
                "fit_relative_residual": f.fit_residual,
                "success": f.success,
                "ambiguous": f.ambiguous or None,
                "parameters": {
                    label: values.tolist()
                    for label, values in zip(
                        (
                            *get_friction_model(f.model).linear,
                            *get_friction_model(f.model).nonlinear,
                        ),
                        np.concatenate([f.linear, f.nonlinear], axis=1).T,
                        strict=True,
                    )
                },
            }
            for f in comparison.fits
        ],
    }


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


def verdict_entry(result: IdentifyResult) -> dict:
    """The ``verdict`` entry of ``result.json``:
    :func:`~ident.identify.assessment.verdict.identify_verdict` and the evidence it used (the
    report's summary shows the same value)."""
    v = identify_verdict(result)
    e = log_evidence(result, truth=truth_from_config(result.config.validation.truth))
    return {
        **v.as_dict(),
        "method": e.method,
        "residual": _finite_or_none(e.residual),
        "residual_where": e.residual_where,
        "nominal_residual": _finite_or_none(e.nominal_residual),
        "worst_error_percent": _finite_or_none(e.worst_error_percent),
        "worst_error_name": e.worst_error_name,
        "worst_std_percent": _finite_or_none(e.worst_std_percent),
        "worst_std_name": e.worst_std_name,
        "std_method": e.std_method,
        "n_inconsistent": e.n_inconsistent,
        "n_links": e.n_links,
        "warnings": list(e.warnings),
    }


def _finite_or_none(value: float | None) -> float | None:
    return None if value is None else _finite(value)


def _markdown(
    result: IdentifyResult,
    urdf: UrdfUpdate,
    urdf_name: str | None,
    replay_note: str = "",
    model: dict | None = None,
    rollout: dict | None = None,
) -> str:
    """report.md of an identification: its sections in order."""
    units = joint_torque_units(result)
    lines = [
        *_title_lines(result, replay_note),
        *headline_markdown(_headline(result, urdf, model, rollout)),
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


def _parameters_csv(result: IdentifyResult) -> str:
    pm = result.parameters
    est = result.estimate
    sd = result.parameter_std
    units = joint_torque_units(result)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["name", "value", "unit", "std", "relative_std_pct", "expression"])
    for k, expr in enumerate(pm.base.expressions()):
        writer.writerow(
            [
                pm.base_names[k],
                repr(float(est.x[k])),
                parameter_unit(pm.base_names[k], units),
                repr(float(sd.std[k])),
                repr(float(sd.relative_std[k])),
                expr,
            ]
        )
    return buffer.getvalue()


def save_identify_data(result: IdentifyResult, folder: str | Path) -> list[Path]:
    """Save the estimate before anything that can fail afterwards (write-back, replay, report).

    ``parameters.csv`` and a first ``result.json`` (without the URDF write-back and the replay,
    which :func:`write_identify_report` adds when it rewrites it).
    """
    folder = Path(folder)
    return [
        atomic_write_text(folder / "parameters.csv", _parameters_csv(result)),
        atomic_write_text(
            folder / "result.json",
            json.dumps(result_dict(result, None, "not written yet"), indent=2, allow_nan=False)
            + "\n",
        ),
    ]


def write_identify_report(
    result: IdentifyResult,
    folder: str | Path,
    *,
    replay: bool = True,
    replay_note: str | None = None,
) -> list[Path]:
    """Write every report file of an identification into ``folder``.

    Parameters
    ----------
    result :
        The identification.
    folder :
        Existing run folder.
    replay :
        Write ``replay.html`` (the measured motion); ``trajectory.csv`` and ``robot.urdf`` are
        written either way.
    replay_note :
        The note of an earlier :func:`write_measured_replay` call; None: call it here.

    Returns
    -------
    :
        Paths written (report files; the replay's files are not listed).
    """
    folder = Path(folder)
    if replay_note is None:
        replay_note = write_measured_replay(result, folder, replay=replay)
    # the identified model first (saved before the report, which can fail afterwards)
    model = save_identified_model(result, folder)
    rollout = identify_rollout(result, folder, model)  # the MJCF against the URDF nominal
    urdf = identified_urdf(result)  # the cautious copy: its table is in the report either way
    urdf_name = (
        _robot_file(result).stem + "_cautious.urdf" if result.config.urdf_update.cautious else None
    )
    written = _write_report_files(result, folder, urdf, urdf_name, replay_note, model, rollout)
    if model["written"]:
        written[:0] = [folder / name for name in model["files"].values()]
    return written


def _write_report_files(
    result: IdentifyResult,
    folder: Path,
    urdf: UrdfUpdate,
    urdf_name: str | None,
    replay_note: str,
    model: dict,
    rollout: dict | None = None,
) -> list[Path]:
    """Write the figures, the cautious URDF (when ``urdf_name``), parameters.csv, result.json,
    report.md and report.html; returns their paths."""
    from ident.report.html import markdown_to_html

    png = torque_png(result)
    params_png = parameters_figure(result)
    markdown = _markdown(result, urdf, urdf_name, replay_note, model, rollout)
    written = [
        atomic_write_bytes(folder / "figures" / "torque_validation.png", png),
        atomic_write_bytes(folder / "figures" / "parameters.png", params_png),
    ]
    if urdf_name is not None:
        written.append(atomic_write_text(folder / urdf_name, urdf.text))
    written += [
        atomic_write_text(folder / "parameters.csv", _parameters_csv(result)),
        atomic_write_text(
            folder / "result.json",
            json.dumps(
                result_dict(result, urdf, replay_note, model, rollout=rollout),
                indent=2,
                allow_nan=False,
            )
            + "\n",
        ),
        atomic_write_text(folder / "report.md", markdown),
        atomic_write_text(
            folder / "report.html",
            markdown_to_html(
                markdown,
                title=f"ident identify: {result.config.name}",
                images={
                    "figures/torque_validation.png": png,
                    "figures/parameters.png": params_png,
                },
            ),
        ),
    ]
    return written


def _headline(
    result: IdentifyResult, urdf: UrdfUpdate, model: dict | None = None, rollout: dict | None = None
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
        extra=[*_headline_extra(result, v), ("MJCF rollout", rollout_text(rollout))],
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


def parameters_figure(result: IdentifyResult) -> bytes:
    """Identified base parameters vs the dataset's reference (else the URDF's nominal)."""
    from ident.report.plots import parameters_png

    pm = result.parameters
    est = result.estimate
    ref = np.array([float(pm.base.projection[k] @ pm.nominal) for k in range(len(est.x))])
    label = "nominal"
    by_ours = {row["ours"]: row for row in result.comparison if row.get("ours")}
    if by_ours:
        label = "reference"
        ref = np.array(
            [
                by_ours[n]["reference_value"]
                if n in by_ours and by_ours[n].get("reference_value") is not None
                else np.nan
                for n in pm.base_names
            ],
            dtype=float,
        )
    ok = np.isfinite(ref)
    return parameters_png(
        list(pm.base_names),
        est.x,
        result.parameter_std.std,
        np.where(ok, ref, 0.0),
        include=ok,
        reference_label=label,
        title=f"{est.method.upper()}: identified vs {label}",
    )
