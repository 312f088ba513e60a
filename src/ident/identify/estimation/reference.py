"""Published reference base parameters (figaroh CSV) as linear expressions in our parameters.

A reference file has no header; each line is ``expression, OLS value, OLS relative std [%],
WLS value, WLS relative std [%]``, the expression a sum of ``coefficient*name`` terms such as
``Izz1 + 1.0*Ia1 + 0.07*mz3``. Its first term is the independent parameter whose regressor column
carries the base parameter. figaroh's first moments ``mx, my, mz`` are our ``mcx, mcy, mcz``.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.dynamics.chain import KinematicChain
from ident.dynamics.friction import (
    ExtraTerms,
    extra_columns,
    extra_names,
    figaroh_coupling_columns,
)
from ident.dynamics.gram import selected_rows
from ident.dynamics.parameter_model import ParameterModel
from ident.errors import DataError
from ident.identify.estimation.estimate import Estimate
from ident.identify.estimation.uncertainty import ParameterStd

__all__ = [
    "ReferenceParameter",
    "ReferenceWeights",
    "expression_to_vector",
    "parse_expression",
    "read_reference",
    "reference_weights",
]

FloatArray = npt.NDArray[np.float64]

_RENAME = {"mx": "mcx", "my": "mcy", "mz": "mcz"}
_TERM = re.compile(r"^(?:(?P<coef>[0-9.eE+-]+)\s*\*\s*)?(?P<name>[A-Za-z_]+[0-9]+)$")


@dataclass(frozen=True)
class ReferenceParameter:
    """One published base parameter.

    Attributes
    ----------
    expression :
        The expression as published.
    terms :
        ``{our parameter name: coefficient}``.
    lead :
        Our name of the first (independent) term.
    ols, ols_relative_std, wls, wls_relative_std :
        Published values (SI) and relative standard deviations [%].
    """

    expression: str
    terms: dict[str, float]
    lead: str
    ols: float
    ols_relative_std: float
    wls: float
    wls_relative_std: float

    def value(self, column: str) -> tuple[float, float]:
        """``(value, relative std %)`` of the ``"ols"`` or ``"wls"`` column."""
        if column == "ols":
            return self.ols, self.ols_relative_std
        return self.wls, self.wls_relative_std


def _rename(name: str) -> str:
    match = re.match(r"^([A-Za-z_]+?)([0-9]+)$", name)
    if not match:
        return name
    stem, number = match.groups()
    return _RENAME.get(stem, stem) + number


def parse_expression(expression: str) -> dict[str, float]:
    """Parse ``"Izz1 + 1.0*Ia1 - 0.05*m3"`` into ``{"Izz1": 1.0, "Ia1": 1.0, "m3": -0.05}``.

    Raises
    ------
    DataError
        For a term that is not ``[coefficient*]name``.
    """
    text = expression.replace(" ", "")
    # split at signs that are not part of a number's exponent (2.5e-3)
    pieces = re.split(r"(?<![0-9][eE])([+-])", text)
    terms: dict[str, float] = {}
    sign = "+"
    for piece in pieces:
        if piece in ("+", "-"):
            sign = piece
            continue
        if not piece:
            continue
        match = _TERM.match(piece)
        if not match:
            raise DataError(f"cannot parse term '{piece}' of reference expression '{expression}'.")
        coefficient = float(match.group("coef") or 1.0) * (-1.0 if sign == "-" else 1.0)
        name = _rename(match.group("name"))
        terms[name] = terms.get(name, 0.0) + coefficient
    return terms


_MAX_REFERENCE_BYTES = 16 << 20  # a table of base parameters is a few kB


def read_reference(path: str | Path) -> list[ReferenceParameter]:
    """Read a figaroh base-parameter CSV.

    Raises
    ------
    DataError
        Naming the file and line for a malformed line.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: not a regular file; give the reference CSV.")
    if path.stat().st_size > _MAX_REFERENCE_BYTES:
        raise DataError(
            f"{path}: {path.stat().st_size} bytes, more than the "
            f"{_MAX_REFERENCE_BYTES >> 20} MB a reference parameter table can need."
        )
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise DataError(
            f"{path}: not UTF-8 text (byte {e.start}); save the reference CSV as UTF-8."
        ) from e
    except OSError as e:
        raise DataError(f"{path}: cannot read the reference CSV ({e.strerror}).") from e
    out = []
    for k, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        fields = line.rsplit(",", 4)
        if len(fields) != 5:
            raise DataError(
                f"{path}: line {k} has {len(fields)} fields; expected expression, OLS value, "
                "OLS rel. std, WLS value, WLS rel. std."
            )
        try:
            numbers = [float(v) for v in fields[1:]]
        except ValueError as e:
            raise DataError(f"{path}: line {k}: non-numeric value ({e}).") from e
        terms = parse_expression(fields[0])
        out.append(
            ReferenceParameter(
                expression=fields[0].strip(),
                terms=terms,
                lead=next(iter(terms)),
                ols=numbers[0],
                ols_relative_std=numbers[1],
                wls=numbers[2],
                wls_relative_std=numbers[3],
            )
        )
    return out


def expression_to_vector(terms: dict[str, float], names: tuple[str, ...]) -> FloatArray | None:
    """Coefficient vector over ``names`` of an expression, or None if a name is unknown."""
    vector = np.zeros(len(names))
    index = {n: i for i, n in enumerate(names)}
    for name, coefficient in terms.items():
        if name not in index:
            return None
        vector[index[name]] = coefficient
    return vector


def coupling_convention_map(pm: ParameterModel) -> dict[str, list[str]]:
    """Our parameters summing to a reference (figaroh-basis) parameter of the coupled wrist."""
    pair = pm.terms.coupled_wrist
    if pair is None:
        return {}
    a, b = (j + 1 for j in pair)
    out = {}
    for kind, motor in (("fv", f"fvm{b}"), ("Ia", f"Iam{b}")):
        for j in (a, b):
            if f"{kind}{j}" in pm.names:
                out[f"{kind}{j}"] = [f"{kind}{j}", motor]
    return out


def compare_with_reference(
    pm: ParameterModel,
    est: Estimate,
    sd: ParameterStd,
    reference: list[ReferenceParameter],
    column: str,
) -> tuple[list[dict], str]:
    """Match reference base parameters to ours: same expression, or a documented sum.

    ``sd``: the estimate's one standard deviation
    (:func:`ident.identify.estimation.uncertainty.parameter_std`); the ``relative_std_pct`` of every
    row, a sum's included (``sqrt(w @ C @ w)``), comes from it and ``std_method`` names it. The
    reference's own column is whatever the reference printed (an ordinary σ for a published OLS/WLS
    table)."""
    coupled = coupling_convention_map(pm)
    rows = []
    for ref in reference:
        ref_value, ref_rel = ref.value(column)
        row = {
            "reference": ref.expression,
            "reference_value": ref_value,
            "reference_relative_std_pct": ref_rel,
            "ours": None,
            "value": None,
            "relative_std_pct": None,
            "std_method": sd.method,
            "match": "none",
            "nominal": None,
        }
        row.update(_match(pm, est, sd, ref, coupled))
        rows.append(row)
    note = (
        f"Reference values: the '{column}' column. Values are compared where the reference "
        "expression equals one of our base parameters (coefficients within 2e-4, the "
        "reference prints 4-5 digits). The coupled wrist uses another basis in the reference "
        "(see ident.dynamics.friction): its fv/Ia of the wrist joints equal our sums "
        "'fv_j + fvm', 'Ia_j + Iam'."
    )
    return rows, note


def _match(
    pm: ParameterModel,
    est: Estimate,
    sd: ParameterStd,
    reference: ReferenceParameter,
    coupled: dict[str, list[str]],
) -> dict[str, Any]:
    """The fields of ``reference``'s comparison row that name our matching base parameter
    (``ours``, ``value``, ``relative_std_pct``, ``match``, and ``nominal`` for the same
    expression), or ``{}`` when none matches: a sum of ours for a coupled-wrist parameter
    (``coupled``, :func:`coupling_convention_map`), else the base parameter whose expression
    equals the reference's (coefficients within 2e-4)."""
    base_names = pm.base_names
    if reference.lead in coupled:
        members = [base_names.index(n) for n in coupled[reference.lead] if n in base_names]
        if len(members) != len(coupled[reference.lead]):
            return {}
        weights = np.zeros(len(base_names))
        weights[members] = 1.0
        value = float(weights @ est.x)
        std = float(np.sqrt(weights @ sd.covariance @ weights))
        return {
            "ours": " + ".join(coupled[reference.lead]),
            "value": value,
            "relative_std_pct": 100.0 * std / abs(value) if value else float("inf"),
            "match": "coupling basis",
        }
    vector = expression_to_vector(reference.terms, pm.names)
    if vector is None:
        return {}
    projection = pm.base.projection
    for k in range(projection.shape[0]):
        scale = np.max(np.abs(projection[k]))
        if np.allclose(projection[k], vector, atol=2e-4 * max(scale, 1.0), rtol=1e-3):
            return {
                "ours": base_names[k],
                "value": float(est.x[k]),
                "relative_std_pct": float(sd.relative_std[k]),
                "match": "same expression",
                "nominal": float(projection[k] @ pm.nominal),
            }
    return {}


@dataclass(frozen=True, eq=False)
class ReferenceWeights:
    """The reference's base parameters as weights of our regressor columns.

    The reference's base parameter ``k`` multiplies the column of its first (independent)
    term; the coupled-wrist terms use the reference's own basis
    (:func:`~ident.dynamics.friction.figaroh_coupling_columns`).

    Attributes
    ----------
    rigid, extra :
        Weights of the rigid-body and of the extra (friction, rotor, offset) columns.
    wrist :
        Weights of the figaroh coupled-wrist columns ``Iam, fvm, fsm``, shape (3,).
    missing :
        Reference parameters without a column here (they contribute nothing).
    """

    rigid: FloatArray
    extra: FloatArray
    wrist: FloatArray
    missing: tuple[str, ...]

    def torques(
        self,
        chain: KinematicChain,
        terms: ExtraTerms,
        q: FloatArray,
        dq: FloatArray,
        ddq: FloatArray,
    ) -> FloatArray:
        """Torques [N*m] (n, nv) the reference predicts on the states (n, nv)."""
        n, nv = dq.shape
        tau = np.zeros((n, nv))
        cols = np.flatnonzero(self.rigid)
        if cols.size:
            Y = selected_rows(chain, q, dq, ddq, columns=cols).reshape(n, nv, cols.size)
            tau += Y @ self.rigid[cols]
        if np.any(self.extra):
            tau += extra_columns(terms, dq, ddq) @ self.extra
        if terms.coupled_wrist is not None:
            tau += figaroh_coupling_columns(dq, ddq, terms.coupled_wrist) @ self.wrist
        return tau


def reference_weights(
    pm: ParameterModel, reference: list[ReferenceParameter], values: FloatArray
) -> ReferenceWeights:
    """The column weights (:class:`ReferenceWeights`) of the reference's base parameters."""
    index = {n: i for i, n in enumerate(pm.names)}
    wrist = ("Iam", "fvm", "fsm")
    weights_rigid = np.zeros(10 * pm.terms.n_joints)
    weights_extra = np.zeros(len(extra_names(pm.terms)))
    weights_wrist = np.zeros(3)
    missing = []
    for ref, value in zip(reference, values, strict=True):
        stem = ref.lead.rstrip("0123456789")
        if pm.terms.coupled_wrist is not None and stem in wrist:
            weights_wrist[wrist.index(stem)] += value
        elif ref.lead in index:
            i = index[ref.lead]
            if pm.inertial_index[i] >= 0:
                weights_rigid[pm.inertial_index[i]] += value
            else:
                weights_extra[pm.extra_index[i]] += value
        else:
            missing.append(ref.lead)
    return ReferenceWeights(weights_rigid, weights_extra, weights_wrist, tuple(missing))
