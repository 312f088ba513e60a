"""Held-out validation: torque prediction error per joint.

The log is split in time (the first part identifies, the rest validates); a parameter set is
judged by how well it predicts the torques it never saw.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ident.errors import ConfigError

__all__ = ["PredictionMetrics", "held_out_warnings", "prediction_metrics", "time_split"]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class PredictionMetrics:
    """Prediction error of a model on a set of samples.

    Attributes
    ----------
    rmse :
        Per joint ``sqrt(mean((tau - tau_pred)^2))`` [N*m], shape (nv,).
    relative_residual :
        Per joint ``||tau_j - tau_pred_j|| / ||tau_j||``, shape (nv,).
    total_relative_residual :
        ``||tau - tau_pred|| / ||tau||`` over all joints.
    r2 :
        Per joint coefficient of determination ``1 - SSE / SST``, shape (nv,).
    n_samples :
        Number of samples.
    """

    rmse: FloatArray
    relative_residual: FloatArray
    total_relative_residual: float
    r2: FloatArray
    n_samples: int

    def as_dict(self) -> dict:
        """JSON-ready dict."""
        return {
            "rmse": self.rmse.tolist(),
            "relative_residual": self.relative_residual.tolist(),
            "total_relative_residual": self.total_relative_residual,
            "r2": self.r2.tolist(),
            "n_samples": self.n_samples,
        }


def prediction_metrics(
    tau: FloatArray, tau_pred: FloatArray, mask: npt.NDArray[np.bool_] | None = None
) -> PredictionMetrics:
    """Compare measured and predicted torques.

    Parameters
    ----------
    tau, tau_pred :
        Measured and predicted torques [N*m], shape (n_samples, nv).
    mask :
        Optional (n_samples, nv) selection of the (sample, joint) entries to compare, e.g. the
        velocity threshold; unselected entries count neither in the error nor in the norms.

    Returns
    -------
    :
        The :class:`PredictionMetrics` (``n_samples``: selected entries / nv, rounded down,
        when masked).
    """
    tau = np.asarray(tau, dtype=float)
    r = tau - np.asarray(tau_pred, dtype=float)
    if mask is not None:
        mask = np.asarray(mask, dtype=bool)
        tau = np.where(mask, tau, 0.0)
        r = np.where(mask, r, 0.0)
        count = np.maximum(mask.sum(axis=0), 1)
        mean = tau.sum(axis=0) / count
        sst = np.sum(np.where(mask, (tau - mean) ** 2, 0.0), axis=0)
        norm_tau = np.linalg.norm(tau, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            relative = np.where(norm_tau > 0, np.linalg.norm(r, axis=0) / norm_tau, np.inf)
            r2 = np.where(sst > 0, 1.0 - np.sum(r**2, axis=0) / sst, np.nan)
        total = float(np.linalg.norm(r) / np.linalg.norm(tau)) if np.any(tau) else float("inf")
        return PredictionMetrics(
            rmse=np.sqrt(np.sum(r**2, axis=0) / count),
            relative_residual=relative,
            total_relative_residual=total,
            r2=r2,
            n_samples=int(mask.sum() // max(mask.shape[1], 1)),
        )
    norm_tau = np.linalg.norm(tau, axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        relative = np.where(norm_tau > 0, np.linalg.norm(r, axis=0) / norm_tau, np.inf)
        sst = np.sum((tau - tau.mean(axis=0)) ** 2, axis=0)
        r2 = np.where(sst > 0, 1.0 - np.sum(r**2, axis=0) / sst, np.nan)
    total = float(np.linalg.norm(r) / np.linalg.norm(tau)) if np.any(tau) else float("inf")
    return PredictionMetrics(
        rmse=np.sqrt(np.mean(r**2, axis=0)),
        relative_residual=relative,
        total_relative_residual=total,
        r2=r2,
        n_samples=int(tau.shape[0]),
    )


def time_split(n_samples: int, identify_fraction: float) -> tuple[slice, slice]:
    """Split ``range(n_samples)`` in time: the first part identifies, the rest validates.

    Parameters
    ----------
    n_samples :
        Number of samples.
    identify_fraction :
        Fraction in (0, 1]; 1 means no held-out part.

    Returns
    -------
    :
        ``(identify, validate)`` slices; ``validate`` is empty when the fraction is 1.

    Raises
    ------
    ConfigError
        If the fraction is outside (0, 1] or leaves an empty identification part.
    """
    if not 0.0 < identify_fraction <= 1.0:
        raise ConfigError(f"validation.identify_fraction = {identify_fraction} must be in (0, 1].")
    n_id = int(round(identify_fraction * n_samples))
    if n_id < 1:
        raise ConfigError(
            f"validation.identify_fraction = {identify_fraction} leaves no sample to identify "
            f"from {n_samples}."
        )
    return slice(0, n_id), slice(n_id, n_samples)


def held_out_warnings(
    identified: float,
    nominal: float | None,
    *,
    max_relative_residual: float | None = None,
    in_sample: bool = False,
    n_rows: int | None = None,
    n_params: int | None = None,
) -> list[str]:
    """Plain-language warnings about the identified parameters' held-out prediction.

    Parameters
    ----------
    identified :
        Held-out total relative residual of the identified parameters.
    nominal :
        The same for the URDF's nominal parameters (None: not compared).
    max_relative_residual :
        Optional bound on ``identified`` (config ``validation.max_relative_residual``).
    in_sample :
        True when there is no held-out part (the numbers are on the identification rows).
    n_rows, n_params :
        Identification rows and parameters, quoted in the message (optional).

    Returns
    -------
    :
        One sentence per problem; empty when the prediction is acceptable.
    """
    where = "on the identification rows (no held-out part)" if in_sample else "held-out"
    rows = (
        f" ({n_rows} identification rows for {n_params} parameters)"
        if n_rows is not None and n_params is not None
        else ""
    )
    out: list[str] = []
    if nominal is not None and np.isfinite(nominal) and not identified < nominal:
        out.append(
            f"{where} relative residual of the identified parameters {identified:.4g} is not "
            f"better than the URDF's nominal parameters' ({nominal:.4g}): the log does not "
            f"determine the parameters well{rows}; use a longer log or a motion that excites "
            "every joint, and do not use these values."
        )
    if max_relative_residual is not None and not identified <= max_relative_residual:
        out.append(
            f"{where} relative residual {identified:.4g} exceeds "
            f"validation.max_relative_residual = {max_relative_residual:g}{rows}."
        )
    return out


@dataclass(frozen=True, eq=False)
class ModelPrediction:
    """A parameter set judged on the held-out part."""

    label: str
    metrics: PredictionMetrics  # rows above the velocity threshold (as identified)
    metrics_all: PredictionMetrics  # every held-out sample, standstill included
    tau_pred: FloatArray
