"""``result.json`` of ``ident identify``: the identification as JSON-ready data, no times (the
same config gives the same file; timings go to ``run.json``).

:func:`result_dict` assembles the entries: the base parameters, the essential ones, the
cautious URDF copy link by link, the friction models, the verdict and the evidence it used.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ident.dynamics.friction_models import get_friction_model
from ident.identify.assessment.verdict import identify_verdict, log_evidence, truth_from_config
from ident.identify.estimators.summary import consistency_summary
from ident.identify.model_files.urdf_update import UrdfUpdate
from ident.identify.pipeline.real import IdentifyResult
from ident.report.uncertainty_section import model_intervals_json, uncertainty_json

__all__ = ["friction_models_entry", "joint_torque_units", "result_dict", "verdict_entry"]


def _finite(value: float) -> float | None:
    return float(value) if np.isfinite(value) else None


def _robot_file(result: IdentifyResult) -> Path:
    """The robot file of the identification (a URDF, or a DH description)."""
    return Path(result.config.robot.path)


def joint_torque_units(result: IdentifyResult) -> tuple[str, ...]:
    """Unit of each joint's torque, residuals and errors: ``"N*m"`` for a revolute joint,
    ``"N"`` for a prismatic one (:func:`ident.identify.assessment.sanity.joint_units` of the robot
    the config selects, the robot that was identified)."""
    from ident.identify.assessment.sanity import joint_units
    from ident.model.selection import load_robot

    model = load_robot(result.config.robot, source=result.config.source or "config").model
    return joint_units(model)


def result_dict(
    result: IdentifyResult,
    urdf: UrdfUpdate | None = None,
    replay_note: str | None = None,
    model: dict | None = None,
    *,
    rollout: dict | None = None,
    refinement: dict | None = None,
) -> dict:
    """JSON-ready summary of the identification (no times); ``model``, ``rollout``,
    ``refinement``: the model's entry, its MJCF's rollout check and refinement."""
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
    checks = {"replay": replay_note, "model": model, "rollout": rollout, "refinement": refinement}
    out.update({k: v for k, v in checks.items() if v is not None})  # in this order in the file
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
