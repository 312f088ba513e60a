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
  reduction).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pinocchio as pin

__all__ = ["MAX_RELATIVE_STD_PCT", "joint_units", "result_warnings"]

FloatArray = npt.NDArray[np.float64]

MAX_RELATIVE_STD_PCT = 50.0  # [%]
MIN_CONTRIBUTION = 0.01  # fraction of the torque norm
MIN_SNR = 0.5
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
) -> list[str]:
    """The warnings of the module docstring.

    Parameters
    ----------
    joint_names, units :
        Per joint: name and torque unit (:func:`joint_units`).
    names, x, std, relative_std :
        Base parameters: names, estimates (SI), standard deviations, relative std [%].
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
    """
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
    for k in range(len(names)):
        row = projection[k]
        members = np.flatnonzero(np.abs(row) > 1e-9 * np.abs(row).max())
        if members.size == 1 and _stem(all_names[members[0]]) in NON_NEGATIVE:
            value = x[k] * row[members[0]]
            if value + 2.0 * std[k] * abs(row[members[0]]) < 0.0:
                out.append(
                    f"{all_names[members[0]]} = {value:.4g} is negative (standard deviation "
                    f"{std[k]:.3g}): physically impossible; the log or the model is wrong "
                    "(joint not moving, wrong sign or unit of a signal, missing friction term)."
                )
    contribution = np.abs(x) * column_norms / tau_norm if tau_norm > 0 else np.zeros_like(x)
    bad = [
        k
        for k in range(len(names))
        if contribution[k] >= min_contribution and relative_std[k] > max_relative_std_pct
    ]
    if bad:
        listed = ", ".join(
            f"{names[k]} ({relative_std[k]:.0f} %, {100 * contribution[k]:.1f} % of the torques)"
            for k in bad[:6]
        ) + (f" and {len(bad) - 6} more" if len(bad) > 6 else "")
        out.append(
            f"base parameter(s) {listed} carry a significant part of the torques but have a "
            f"relative standard deviation above {max_relative_std_pct:g} %: the log does not "
            "separate them; use a richer excitation before trusting them."
        )
    return out
