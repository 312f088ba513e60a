"""The estimates of one identification: the estimators on the reduced rows, the essential
parameters, the vectors predicted on the held-out rows, the reference comparisons and the
warnings of the result.

Steps of :func:`ident.identify.pipeline.core.identify_measurements`, apart so that the core
reads as the sequence of its steps; nothing here reads a log or writes a file.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

from ident.dynamics.parameter_model import ParameterModel
from ident.errors import DataError, NotIdentifiable
from ident.identify.assessment import sanity
from ident.identify.config import IdentifyConfig
from ident.identify.estimation import accumulate, log_chunks
from ident.identify.estimation.essential import EssentialResult
from ident.identify.estimation.estimate import Estimate, rank_report
from ident.identify.estimation.log_chunks import merged_rows
from ident.identify.estimation.observations import ReducedObservations
from ident.identify.estimation.reference import (
    ReferenceWeights,
    compare_with_reference,
    read_reference,
)
from ident.identify.estimation.uncertainty import (
    ParameterStd,
    Uncertainty,
    parameter_std,
)
from ident.identify.estimation.validation import (
    ModelPrediction,
    held_out_warnings,
)
from ident.identify.estimators import (
    ConsistentIdentification,
    consistent_identification_reduced,
)

__all__ = [
    "essential_result",
    "held_out_vectors",
    "all_warnings",
    "merged_rows",
    "reference_comparisons",
    "run_estimators",
]

FloatArray = npt.NDArray[np.float64]


def run_estimators(
    cfg: IdentifyConfig,
    model: pin.Model,
    pm: ParameterModel,
    first: ReducedObservations | None,
    last: ReducedObservations | None,
    red: ReducedObservations,
    ellipsoids: tuple,
    joints: list[str],
    source: str,
    *,
    method: str | None = None,
) -> ConsistentIdentification:
    """OLS, WLS and the configured estimator (or ``method``) on the reduced rows (``first``
    and ``last``: the identification rows in two parts, the last one choosing a prior's
    weight)."""
    est_cfg = cfg.estimation
    if first is None or last is None:  # too few samples to split: the weight is chosen on all
        first = last = red
    try:
        return consistent_identification_reduced(
            model,
            pm,
            first,
            last,
            method=method or est_cfg.method,
            weight=est_cfg.regularization.weight,
            ellipsoids=ellipsoids,
            options={"friction": est_cfg.friction},
        )
    except NotIdentifiable as e:
        explained = range(len(joints)) if pm.rows is None else pm.rows  # one group each
        names = tuple(joints[r] for r, n in zip(explained, red.n_rows, strict=True) if n == 0)
        if names:
            idle = ", ".join(names)
            why = rank_report(red.R.reshape(-1, red.n_params), pm.base_names, advice="") or e
            raise NotIdentifiable(
                f"{source}: the log does not determine every base parameter. No sample of "
                f"{idle} reaches its velocity threshold in the identification part (joint not "
                f"moving?): {why} Record a motion that moves {idle}, or lower its velocity "
                "threshold (preprocess.velocity_threshold).",
                idle_joints=names,
            ) from e
        raise NotIdentifiable(
            f"{source}: the log does not determine every base parameter: {e}"
        ) from e
    except DataError as e:
        raise DataError(f"{source}: {e}") from e


def essential_result(
    cfg: IdentifyConfig, red: ReducedObservations, pm: ParameterModel
) -> EssentialResult | None:
    ess = cfg.estimation.essential
    if not ess.enabled:
        return None
    return accumulate.essential_reduced(
        red,
        tuple(pm.base_names),
        method=cfg.estimation.least_squares_method,
        max_relative_std_pct=ess.max_relative_std_pct,
        max_residual_increase=ess.max_residual_increase,
    )


def held_out_vectors(
    est: Estimate,
    essential: EssentialResult | None,
    cons: ConsistentIdentification,
    pm: ParameterModel,
    model: ConsistentIdentification | None = None,
) -> dict[str, FloatArray]:
    """The base-parameter vectors predicted on the held-out rows, by label."""
    vectors = {"identified": est.x}
    for identification in (cons, model):
        if identification is not None and identification.constrained is not None:
            vectors[identification.method] = identification.constrained.x
    if essential is not None:
        x_ess = np.zeros(len(pm.base_names))
        x_ess[list(essential.kept)] = essential.estimate.x
        vectors["essential"] = x_ess
    vectors["URDF nominal"] = pm.base.project(pm.nominal)
    return vectors


def reference_comparisons(
    cfg: IdentifyConfig,
    pm: ParameterModel,
    fit: tuple[Estimate, ParameterStd],
    essential: EssentialResult | None,
    reference: ReferenceWeights | None,
) -> tuple[list[dict], str, list[dict]]:
    """Rows comparing with the reference's base and essential parameters, and the note;
    ``fit``: the estimate and its one standard deviation."""
    est, sd = fit
    ref_cfg = cfg.reference
    comparison: list[dict] = []
    note = ""
    if ref_cfg.base_parameters is not None:
        comparison, note = compare_with_reference(
            pm, est, sd, read_reference(ref_cfg.base_parameters), ref_cfg.column
        )
        if reference is not None and reference.missing:
            note += f" Reference parameters without a column here: {', '.join(reference.missing)}."
    rows_essential: list[dict] = []
    if ref_cfg.essential_parameters is not None:
        rows, _ = compare_with_reference(
            pm, est, sd, read_reference(ref_cfg.essential_parameters), ref_cfg.column
        )
        kept = set(essential.estimate.names) if essential is not None else set()
        for row in rows:
            members = row["ours"].split(" + ") if row["ours"] else []
            row["in_our_essential_set"] = bool(members) and all(m in kept for m in members)
            rows_essential.append(row)
    return comparison, note, rows_essential


def all_warnings(
    cfg: IdentifyConfig,
    model: pin.Model,
    pm: ParameterModel,
    estimated: tuple[Estimate, Uncertainty | None],
    cons: ConsistentIdentification,
    red: ReducedObservations,
    chunked: log_chunks.ChunkedLog,
    predictions: dict[str, ModelPrediction],
    held_out: tuple[FloatArray, npt.NDArray[np.bool_]],
) -> list[str]:
    """Held-out, sanity and consistency warnings of the result; ``estimated``: the
    least-squares estimate and its robust covariances (the warnings read
    :func:`~ident.identify.estimation.uncertainty.parameter_std`)."""
    est, unc = estimated
    sd = parameter_std(est, unc)
    identified = predictions["identified"]
    problems = held_out_warnings(
        identified.metrics.total_relative_residual,
        predictions["URDF nominal"].metrics.total_relative_residual,
        max_relative_residual=cfg.validation.max_relative_residual,
        in_sample=chunked.in_sample,
        n_rows=int(red.n_rows.sum()),
        n_params=len(pm.base_names),
    )
    problems += sanity.result_warnings(
        joint_names=tuple(str(model.names[i]) for i in range(1, model.njoints)),
        units=sanity.joint_units(model),
        names=pm.base_names,
        x=est.x,
        std=sd.std,
        relative_std=sd.relative_std,
        std_method=sd.method,
        projection=pm.base.projection,
        all_names=pm.names,
        column_norms=np.sqrt(np.einsum("gij,gij->j", red.R, red.R)),
        tau_norm=float(np.sqrt(red.yty.sum())),
        tau_validate=held_out[0],
        tau_pred=identified.tau_pred,
        keep_validate=held_out[1],
    )
    if not cons.contract.consistent:  # the estimator promises no consistency: check it
        problems += sanity.inconsistency_warnings(cons, cfg.estimation.least_squares_method)
    return list(problems)
