"""The records of an identification's processing: what reading and preprocessing the log did,
what the velocity threshold kept and how the log was split in time.

Steps of :func:`ident.identify.pipeline.core.identify_measurements` (its ``records``, shown in
the report's processing table and saved in ``result.json``); the preprocessing's records check
its settings before any chunk runs.
"""

from __future__ import annotations

from ident.errors import ConfigError
from ident.identify.config import FilterConfig, IdentifyConfig, PreprocessConfig
from ident.identify.estimation import log_chunks, preprocess
from ident.identify.estimation.observations import ReducedObservations

__all__ = ["preprocess_records", "row_records"]


def preprocess_records(
    pp: PreprocessConfig, fs: float, nv: int, source: str, *, states: bool
) -> list[dict]:
    """The records of the processing every chunk does (checked before any chunk runs);
    ``states``: the log carries measured velocities and accelerations, used as they are."""
    records = []
    thresholds = pp.velocity_threshold
    if thresholds is not None and len(thresholds) != nv:
        raise ConfigError(
            f"{source}: preprocess.velocity_threshold has {len(thresholds)} values, the robot "
            f"has {nv} joints; give one per joint [rad/s]."
        )
    for key, flt, what in (
        ("lowpass", None if states else preprocess.position_filter(pp), "q"),
        ("torque_lowpass", pp.torque_lowpass, "tau"),
    ):
        if not isinstance(flt, FilterConfig):
            continue
        if not 0.0 < flt.cutoff_hz < 0.5 * fs:
            raise ConfigError(
                f"{source}: preprocess.{key}.cutoff_hz = {flt.cutoff_hz:g} Hz is not below the "
                f"Nyquist frequency {0.5 * fs:g} Hz; choose a lower cutoff."
            )
        records.append(
            {
                "step": f"low-pass {what}",
                "detail": f"zero-phase Butterworth, order {flt.order}, cutoff "
                f"{flt.cutoff_hz:g} Hz at {fs:g} Hz",
            }
        )
    records.append(
        {"step": "states", "detail": "measured q, dq, ddq used as they are"}
        if states
        else {"step": "differentiate", "detail": "central differences (np.gradient)"}
    )
    records.append(
        {"step": "trim", "detail": f"dropped {pp.trim_samples} samples at each end of a segment"}
    )
    factors = preprocess.decimation_factors(pp)
    if factors:
        step = preprocess.decimation_step(pp)
        records.append(
            {
                "step": "decimate",
                "detail": f"zero-phase decimation by {' x '.join(map(str, factors))} "
                "(Chebyshev I order 8, forward-backward) of torques and regressor rows alike, "
                f"{fs:g} -> {fs / step:g} Hz",
            }
        )
    return records


def row_records(
    cfg: IdentifyConfig, chunked: log_chunks.ChunkedLog, red: ReducedObservations
) -> list[dict]:
    """Records of the velocity threshold and of the time split."""
    thresholds = cfg.preprocess.velocity_threshold
    kept = red.n_rows.tolist()
    fraction = cfg.validation.identify_fraction
    return [
        {
            "step": "velocity threshold",
            "detail": "none (all samples kept)"
            if thresholds is None
            else "dropped the rows of joint j where abs(dq_j) < threshold_j "
            f"{[round(float(v), 4) for v in thresholds]} rad/s; identification rows kept per "
            f"joint {kept}",
            "kept": kept,
        },
        {
            "step": "time split",
            "detail": f"identify on the first {100 * fraction:.4g} % of each segment, validate "
            f"on the {chunked.t_validate.size} later samples"
            + (" (none: validated in sample)" if chunked.in_sample else "")
            + " (errors reported on the rows above the velocity threshold, as identified, "
            "and on all samples)",
        },
    ]
