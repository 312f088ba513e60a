"""Plain-language warnings about an identification result that a user must see.

Each check returns sentences for the result's ``warnings`` (printed by ``ident identify``,
written to the report and ``result.json``). Residuals are quoted in each joint's own unit
(N*m for revolute joints, N for prismatic ones). The checks:

- a joint whose held-out prediction is worse than predicting zero torque (relative residual
  above 1);
- a joint whose torques are at the noise level: the part the model explains has less than
  half the RMS of the residual (signal-to-noise below 0.5), so its parameters rest on noise;
- a base parameter that is one standard parameter alone and physically cannot be negative
  (mass ``m``, diagonal inertia ``Ixx Iyy Izz``, rotor inertia ``Ia``, viscous ``fv`` and Coulomb
  ``fs`` friction) estimated below zero by more than two standard deviations (the full
  pseudo-inertia check of a body is separate);
- a base parameter that carries at least ``min_contribution`` of the torques but whose
  relative standard deviation exceeds ``max_relative_std_pct``: a significant term the log
  does not determine (parameters too small to matter are left to the essential-parameter
  reduction);
- links that the least-squares estimate makes physically impossible (mass not positive, inertia
  about the centre of mass not positive semi-definite or violating the triangle inequality)
  when no physically consistent parameters fit the torques as well
  (:func:`inconsistency_warnings`).

The standard deviations are the result's one standard deviation (the default interval
method's, :func:`ident.identify.estimation.uncertainty.parameter_std`), named in the sentences.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

__all__ = ["MAX_RELATIVE_STD_PCT", "inconsistency_warnings", "joint_units", "result_warnings"]

FloatArray = npt.NDArray[np.float64]

MAX_RELATIVE_STD_PCT = 50.0  # [%]
MIN_CONTRIBUTION = 0.01  # fraction of the torque norm
MIN_SNR = 0.5
MAX_CONSISTENT_INCREASE = 0.02  # relative residual, best consistent fit vs least squares
# Standard parameters that cannot be negative (prefixes of the parameter names).
NON_NEGATIVE = ("m", "Ixx", "Iyy", "Izz", "Ia", "fv", "fs")


def joint_units(model: pin.Model) -> tuple[str, ...]:
    """Torque unit of every joint: ``"N"`` for prismatic joints, ``"N*m"`` otherwise."""
    units = []
    for j in range(1, model.njoints):
        short = model.joints[j].shortname()
        units.append("N" if "Prismatic" in short or short.startswith("JointModelP") else "N*m")
    return tuple(units)


def _stem(name: str) -> str:
    return name.rstrip("0123456789")


def result_warnings(
    *,
    joint_names: tuple[str, ...],
    units: tuple[str, ...],
    names: tuple[str, ...],
    x: FloatArray,
    std: FloatArray,
    relative_std: FloatArray,
    projection: FloatArray,
    all_names: tuple[str, ...],
    column_norms: FloatArray,
    tau_norm: float,
    tau_validate: FloatArray,
    tau_pred: FloatArray,
    keep_validate: npt.NDArray[np.bool_],
    max_relative_std_pct: float = MAX_RELATIVE_STD_PCT,
    min_contribution: float = MIN_CONTRIBUTION,
    std_method: str = "ordinary",
) -> list[str]:
    """The warnings of the module docstring.

    Parameters
    ----------
    joint_names, units :
        Per joint: name and torque unit (:func:`joint_units`).
    names, x, std, relative_std :
        Base parameters: names, estimates (SI), standard deviations, relative std [%]: the
        result's one standard deviation
        (:func:`ident.identify.estimation.uncertainty.parameter_std`).
    projection :
        Base parameters as combinations of the standard ones, shape (n_base, n_all).
    all_names :
        Names of the standard (and extra) parameters, length n_all.
    column_norms :
        Norm of each base parameter's column of the identification rows, shape (n_base,).
    tau_norm :
        Norm of the identification torques (all rows).
    tau_validate, tau_pred :
        Held-out measured and predicted torques, shape (n, nv).
    keep_validate :
        Held-out rows above the velocity threshold, shape (n, nv).
    std_method :
        The interval method of ``std`` (named in the warnings).
    """
    return [
        *_joint_warnings(joint_names, units, tau_validate, tau_pred, keep_validate),
        *_negative_parameter_warnings(x, std, projection, all_names, std_method),
        *_uncertain_parameter_warnings(
            names,
            x,
            relative_std,
            column_norms,
            tau_norm,
            max_relative_std_pct=max_relative_std_pct,
            min_contribution=min_contribution,
            std_method=std_method,
        ),
    ]


def _joint_warnings(
    joint_names: tuple[str, ...],
    units: tuple[str, ...],
    tau_validate: FloatArray,
    tau_pred: FloatArray,
    keep_validate: npt.NDArray[np.bool_],
) -> list[str]:
    """Joints whose held-out prediction is worse than zero torque, or at the noise level."""
    out: list[str] = []
    for j, (joint, unit) in enumerate(zip(joint_names, units, strict=True)):
        rows = keep_validate[:, j]
        if not rows.any():
            continue
        tau_j, r_j = tau_validate[rows, j], tau_validate[rows, j] - tau_pred[rows, j]
        rms, rmse = float(np.sqrt(np.mean(tau_j**2))), float(np.sqrt(np.mean(r_j**2)))
        if rms > 0 and rmse / rms > 1.0:
            out.append(
                f"joint {joint}: held-out prediction is worse than predicting zero torque "
                f"(residual RMS {rmse:.3g} {unit} > torque RMS {rms:.3g} {unit}); do not use "
                "the parameters of this joint's chain without a better log."
            )
        elif rmse > 0 and np.sqrt(max(rms**2 - rmse**2, 0.0)) < MIN_SNR * rmse:
            out.append(
                f"joint {joint}: torques at the noise level (torque RMS {rms:.3g} {unit}, "
                f"residual RMS {rmse:.3g} {unit}); its parameters rest on noise: move the "
                "joint more, or remove its friction/offset terms."
            )
    return out


def _negative_parameter_warnings(
    x: FloatArray,
    std: FloatArray,
    projection: FloatArray,
    all_names: tuple[str, ...],
    std_method: str,
) -> list[str]:
    """Base parameters that are one non-negative standard parameter alone, estimated below
    zero by more than two standard deviations."""
    out: list[str] = []
    for k in range(len(x)):
        row = projection[k]
        members = np.flatnonzero(np.abs(row) > 1e-9 * np.abs(row).max())
        if members.size == 1 and _stem(all_names[members[0]]) in NON_NEGATIVE:
            value = x[k] * row[members[0]]
            if value + 2.0 * std[k] * abs(row[members[0]]) < 0.0:
                out.append(
                    f"{all_names[members[0]]} = {value:.4g} is negative (standard deviation "
                    f"{std[k]:.3g}, {std_method}): physically impossible; the log or the model "
                    "is wrong (joint not moving, wrong sign or unit of a signal, missing "
                    "friction term)."
                )
    return out


def _uncertain_parameter_warnings(
    names: tuple[str, ...],
    x: FloatArray,
    relative_std: FloatArray,
    column_norms: FloatArray,
    tau_norm: float,
    *,
    max_relative_std_pct: float,
    min_contribution: float,
    std_method: str,
) -> list[str]:
    """One warning listing the base parameters that carry a significant part of the torques
    with a relative standard deviation above ``max_relative_std_pct``."""
    contribution = np.abs(x) * column_norms / tau_norm if tau_norm > 0 else np.zeros_like(x)
    bad = [
        k
        for k in range(len(names))
        if contribution[k] >= min_contribution and relative_std[k] > max_relative_std_pct
    ]
    if not bad:
        return []
    listed = ", ".join(
        f"{names[k]} ({relative_std[k]:.0f} %, {100 * contribution[k]:.1f} % of the torques)"
        for k in bad[:6]
    ) + (f" and {len(bad) - 6} more" if len(bad) > 6 else "")
    return [
        f"base parameter(s) {listed} carry a significant part of the torques but have a "
        f"relative standard deviation ({std_method}) above {max_relative_std_pct:g} %: the "
        "log does not "
        "separate them; use a richer excitation before trusting them."
    ]


def inconsistency_warnings(
    consistent: Any, method: str, rtol: float = MAX_CONSISTENT_INCREASE
) -> list[str]:
    """One warning when no physically consistent parameters fit the log as the estimate does.

    The least-squares estimate determines base parameters only. Its links are checked on the
    standard parameters closest to the nominal ones that reproduce it (what a URDF write-back
    would hold); when one is impossible, the best *consistent* fit is computed (the ``lmi``
    estimator, WLS-weighted, with only its small prior floor). If that fit's relative residual
    exceeds the estimate's by more than ``rtol``, no physical body explains the torques as
    well: the warning names the links and the cost. Otherwise the impossibility is one of the
    completions only (the data do not decide it) and the report's consistency section shows
    it; ``estimation.method: lmi`` gives consistent parameters at no cost in fit.

    Parameters
    ----------
    consistent :
        The :class:`~ident.identify.estimators.ConsistentIdentification` of the rows.
    method :
        The least-squares estimator (``"ols"`` or ``"wls"``).
    rtol :
        Relative increase of the residual that counts as a worse fit.

    Returns
    -------
    :
        Empty, or one sentence.
    """
    from ident.identify.estimators import get_estimator  # cvxpy: imported only when needed

    estimate = consistent.estimates[method]
    bad = [c for c in estimate.consistency if not c.consistent]
    if not bad:
        return []
    problem = consistent.problem
    sigma = np.asarray(consistent.estimates["wls"].sigma, dtype=float)
    weights = np.where(problem.observations.n_rows > 0, 1.0 / sigma, 0.0)
    best = get_estimator("lmi")(dataclasses.replace(problem, weights=weights, regularization=0.0))
    increase = best.relative_residual / estimate.relative_residual - 1.0
    if not best.success or increase <= rtol:
        return []
    listed = "; ".join(f"{c.body}: {c.problems[0]}" for c in bad[:3]) + (
        f"; and {len(bad) - 3} more" if len(bad) > 3 else ""
    )
    return [
        f"no physically consistent parameters fit the torques as well as {method.upper()}: "
        f"the best consistent fit has relative residual {best.relative_residual:.4g} "
        f"({100 * increase:+.1f} % over {estimate.relative_residual:.4g}); {method.upper()}'s "
        f"parameters make {len(bad)} of {len(estimate.consistency)} links impossible "
        f"({listed}). The model misses a term (friction, offset, coupling) "
        "or a signal has a wrong sign, unit or delay."
    ]
