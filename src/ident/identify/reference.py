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

import numpy as np
import numpy.typing as npt

from ident.errors import DataError

__all__ = ["ReferenceParameter", "expression_to_vector", "parse_expression", "read_reference"]

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


def read_reference(path: str | Path) -> list[ReferenceParameter]:
    """Read a figaroh base-parameter CSV.

    Raises
    ------
    DataError
        Naming the file and line for a malformed line.
    """
    path = Path(path)
    out = []
    for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1):
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
