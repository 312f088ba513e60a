"""Quality measures of an estimate: errors against true values, parameter units.

Pure functions of arrays (no files, no printing); the report writers call them and only
format the numbers.

Errors (per base parameter, ``true`` = projection of the true standard parameters):
absolute error ``x - true``; relative error ``|x - true| / |true|`` [%] where ``|true|`` is
above ``ZERO_RTOL`` times the largest ``|true|`` (otherwise the true value is zero up to
round-off and only the absolute error exists); normalized error ``(x - true) / std``.

Torque share: on a base observation matrix ``W_b``, ``|true_i| ||W_i|| / ||W_b true||``, the
part of the torques a parameter explains. A parameter with a tiny share is barely observable
whatever the estimator (the paper robot has base parameters of 1e-7 of the largest, products
of its 1e-6 kg*m first moments), so the summaries leave such parameters out:

- *major* parameters: reference torque share (the stage's reference motion, the same set
  for every trajectory) of at least ``MAJOR_SHARE`` (1 %); the verdict
  (:mod:`ident.identify.assessment.verdict`) and the worst error are about them;
- *significant* parameters: torque share of at least ``SIGNIFICANT_SHARE`` (1e-4); the
  paper-style error sums add their relative errors [%]: ``Error(n)`` over the ``n``
  significant parameters, ``Error(n-2)`` without the two largest (our reading of the paper's
  Error(22) and Error(20): "cumulative errors ... for all 22 identified parameters" and "for
  the best 20").
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "MAJOR_SHARE",
    "SIGNIFICANT_SHARE",
    "error_measures",
    "parameter_unit",
]

FloatArray = npt.NDArray[np.float64]

ZERO_RTOL = 1e-9
SIGNIFICANT_SHARE = 1e-4
MAJOR_SHARE = 1e-2


def _num(value: Any) -> Any:
    """JSON-safe number: non-finite -> None; numpy scalars -> Python."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    value = float(value)
    return value if math.isfinite(value) else None


def _arr(a: Any) -> Any:
    a = np.asarray(a)
    if a.ndim == 0:
        return _num(a)
    return [_arr(v) for v in a]


def error_measures(
    x: FloatArray,
    std: FloatArray,
    true: FloatArray,
    column_norms: FloatArray | None = None,
    true_torque_norm: float | None = None,
    reference_share: FloatArray | None = None,
) -> dict[str, Any]:
    """Errors of an estimate against the true values (see the module docstring).

    Parameters
    ----------
    x, std, true :
        Estimate, its standard deviations and the true values, shape (n,).
    column_norms :
        Norms of the base observation matrix columns ``||W_b[:, i]||`` on the trajectory,
        shape (n,); with ``true_torque_norm = ||W_b @ true||`` [N*m] they give unit-free
        measures.
    true_torque_norm :
        See ``column_norms``.
    reference_share :
        Torque share of each parameter on the stage's reference motion (trajectory
        independent), shape (n,).

    Returns
    -------
    :
        JSON-ready dict (non-finite -> None): ``abs_error`` (n,), ``rel_error_percent`` (n,
        None where true ~ 0), ``normalized_error`` (n, None where std = 0),
        ``error_sum_percent`` and ``error_sum_best_percent`` (sums over every parameter with
        a non-zero true value, with and without the two largest), ``within_3std`` (share of
        parameters with ``|x - true| <= 3 std``); with the column norms ``torque_share``,
        ``torque_error`` (n,), ``max_torque_error``; ``significant`` (n, bool),
        ``paper_error_sum_percent`` / ``paper_error_sum_best_percent`` / ``n_significant``
        (the paper-style sums over the significant parameters), ``max_rel_error`` (fraction,
        over the significant parameters); with ``reference_share``: ``major`` (n, bool),
        ``max_rel_error_major`` (fraction), ``max_rel_error_major_percent`` and
        ``worst_major`` (the name index of the worst major parameter).
    """
    x, std, true = (np.asarray(a, dtype=float) for a in (x, std, true))
    err = x - true
    scale = float(np.max(np.abs(true), initial=0.0))
    nonzero = np.abs(true) > ZERO_RTOL * scale
    rel = np.full(true.shape, np.nan)
    rel[nonzero] = np.abs(err[nonzero]) / np.abs(true[nonzero])
    out = _parameter_errors(err, std, rel, nonzero)
    if column_norms is not None and true_torque_norm is not None and true_torque_norm > 0:
        share = np.abs(true) * np.asarray(column_norms, dtype=float) / true_torque_norm
        out.update(_torque_errors(err, share, true_torque_norm, column_norms))
        significant = (share >= SIGNIFICANT_SHARE) & nonzero
    elif reference_share is not None:
        significant = (np.asarray(reference_share, dtype=float) >= SIGNIFICANT_SHARE) & nonzero
    else:
        significant = (np.abs(true) >= SIGNIFICANT_SHARE * scale) & nonzero
    out.update(_paper_error_sums(rel, significant))
    if reference_share is not None:
        major = (np.asarray(reference_share, dtype=float) >= MAJOR_SHARE) & nonzero
        out.update(_major_errors(rel, major))
    return out


def _largest_dropped_sum(values: FloatArray) -> tuple[Any, Any]:
    """The sum of ``values`` and the sum without its two largest entries (JSON-safe)."""
    ordered = np.sort(values)
    return _num(ordered.sum()), _num(ordered[: max(0, ordered.size - 2)].sum())


def _parameter_errors(
    err: FloatArray, std: FloatArray, rel: FloatArray, nonzero: npt.NDArray[np.bool_]
) -> dict[str, Any]:
    """Absolute, relative [%] and normalized errors of every parameter and their sums."""
    with np.errstate(divide="ignore", invalid="ignore"):
        normalized = np.where(std > 0, err / std, np.nan)
    within = np.abs(err) <= 3.0 * std
    total, best = _largest_dropped_sum(100.0 * rel[nonzero])
    return {
        "abs_error": _arr(err),
        "rel_error_percent": _arr(100.0 * rel),
        "normalized_error": _arr(normalized),
        "error_sum_percent": total,
        "error_sum_best_percent": best,
        "within_3std": _num(float(np.mean(within)) if within.size else 0.0),
    }


def _torque_errors(
    err: FloatArray, share: FloatArray, true_torque_norm: float, column_norms: Any
) -> dict[str, Any]:
    """Each parameter's share of the true torques and its error's, on the trajectory."""
    torque_error = np.abs(err) * np.asarray(column_norms, dtype=float) / true_torque_norm
    return {
        "torque_share": _arr(share),
        "torque_error": _arr(torque_error),
        "max_torque_error": _num(float(torque_error.max(initial=0.0))),
    }


def _paper_error_sums(rel: FloatArray, significant: npt.NDArray[np.bool_]) -> dict[str, Any]:
    """The paper-style sums of relative errors [%] over the significant parameters."""
    total, best = _largest_dropped_sum(100.0 * rel[significant])
    return {
        "significant": [bool(s) for s in significant],
        "n_significant": int(significant.sum()),
        "paper_error_sum_percent": total,
        "paper_error_sum_best_percent": best,
        # kept for result.json readers: the sum over the significant parameters
        "error_sum_significant_percent": total,
        "max_rel_error": _num(float(np.max(rel[significant], initial=0.0))),
    }


def _major_errors(rel: FloatArray, major: npt.NDArray[np.bool_]) -> dict[str, Any]:
    """The worst relative error among the major parameters (what the verdict judges)."""
    worst = float(np.max(rel[major], initial=0.0))
    return {
        "major": [bool(m) for m in major],
        "max_rel_error_major": _num(worst),
        "max_rel_error_major_percent": _num(100.0 * worst),
        "worst_major": int(np.flatnonzero(major)[np.argmax(rel[major])]) if major.any() else None,
    }


# joint-space parameters of joint k (1-based): fv3, fs3, fc3, off3, Ia3 (and base names fv3R)
_JOINT_PARAMETER = re.compile(r"^(fv|fs|fc|off|Ia)(\d+)")
_PRISMATIC_UNITS = {"fv": "N*s/m", "fs": "N", "fc": "N", "off": "N", "Ia": "kg"}
_UNITS = (
    (re.compile(r"^(fv|fvm)\d"), "N*m*s/rad"),
    (re.compile(r"^(fs|fsm|fc|fcm)\d"), "N*m"),
    (re.compile(r"^off\d"), "N*m"),
    (re.compile(r"^(Ia|Iam)\d"), "kg*m^2"),
    (re.compile(r"^I(xx|xy|xz|yy|yz|zz)\d"), "kg*m^2"),
    (re.compile(r"^(mc[xyz]|m[xyz])\d"), "kg*m"),
    (re.compile(r"^(m|mm)\d"), "kg"),
)


def parameter_unit(name: str, joint_units: Sequence[str] = ()) -> str:
    """SI unit of a named (standard or base) parameter, e.g. ``Ixx5R`` -> ``kg*m^2``.

    A base parameter has the unit of the standard parameter it is named after (its
    combination's coefficients carry the rest). Names: ``m``, ``mcx``..``mcz``,
    ``Ixx``..``Izz``, rotor inertia ``Ia``/``Iam``, viscous ``fv``/``fvm``, Coulomb
    ``fs``/``fc``, offset ``off``, each followed by the joint number; ``""`` when unknown.

    ``joint_units`` (the torque unit of each joint, ``"N"`` for a prismatic joint, see
    :func:`ident.identify.assessment.sanity.joint_units`) gives the joint-space parameters of a
    prismatic joint their own units: ``fv`` in N*s/m, ``fs``/``off`` in N, ``Ia`` (reflected rotor
    mass) in kg. Motor-side parameters (``Iam``, ``fvm``, ``fsm``) belong to rotary motors.
    """
    joint = _JOINT_PARAMETER.match(name)
    if joint and joint_units:
        j = int(joint.group(2)) - 1
        if 0 <= j < len(joint_units) and joint_units[j] == "N":
            return _PRISMATIC_UNITS[joint.group(1)]
    for pattern, unit in _UNITS:
        if pattern.match(name):
            return unit
    return ""
