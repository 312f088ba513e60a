"""What the data cannot see: each standard parameter alone, in a combination, or not at all.

The base parameters ``beta = T theta`` (``T``: the projection of
:class:`~ident.dynamics.base_parameters.BaseParameters`, shape (n_base, n_std)) are what joint
torques determine. A standard parameter ``theta_i`` is

``alone``
    when some linear combination of the base parameters equals it: the unit vector ``e_i``
    lies in the row space of ``T`` (its distance to that space, on the column-normalized
    ``T``, is below ``1e-9``). Its value comes from the data.
``combination``
    when it enters some base parameter but is not determined alone: the data fix only the
    combinations listed (``"Iyy2R = Iyy2 + 0.18 m3 + ..."``); its value in a written model
    (standard completion or constrained estimate) comes partly from the prior (the nominal
    URDF / CAD values).
``none``
    when no base parameter contains it (zero column): its value is the prior's alone.

A wrong CAD model (a mass 4x off, centres of mass outside the link) changes none of the base
parameters the data determine; it changes every ``combination`` and ``none`` value a written
model holds. :func:`standard_identifiability` names them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

__all__ = ["KINDS", "Identifiability", "standard_identifiability"]

FloatArray = npt.NDArray[np.float64]

#: The three answers, in report order.
KINDS = ("alone", "combination", "none")
_RTOL = 1e-9


@dataclass(frozen=True, eq=False)
class Identifiability:
    """Per standard parameter: ``kind`` (one of :data:`KINDS`) and the base parameters it
    enters (their names and expressions; empty for ``none``).

    Attributes
    ----------
    names :
        Standard parameter names, length n_std.
    kind :
        One of :data:`KINDS` per parameter.
    enters :
        Per parameter, the expressions (``"name = expression"``) of the base parameters it
        enters.
    weights :
        ``theta_i = weights[i] @ beta`` for every parameter determined ``alone`` (a row of
        the pseudo-inverse of ``T``); NaN rows for the others, shape (n_std, n_base).
    """

    names: tuple[str, ...]
    kind: tuple[str, ...]
    enters: tuple[tuple[str, ...], ...]
    weights: FloatArray

    def standard_values(
        self, beta: npt.ArrayLike, covariance: npt.ArrayLike
    ) -> tuple[FloatArray, FloatArray]:
        """Values and standard deviations of the standard parameters determined alone, from
        base parameters ``beta`` (n_base,) and their covariance (n_base, n_base); NaN for the
        others (their values come from the prior), shapes (n_std,)."""
        W = self.weights
        C = np.asarray(covariance, dtype=float)
        value = W @ np.asarray(beta, dtype=float)
        std = np.sqrt(np.clip(np.einsum("ip,pq,iq->i", W, C, W), 0.0, None))
        return value, std

    def of_kind(self, kind: str) -> tuple[str, ...]:
        """Names of the parameters of ``kind``."""
        return tuple(n for n, k in zip(self.names, self.kind, strict=True) if k == kind)

    def lines(self) -> list[str]:
        """One line per parameter not determined alone: what the data see of it."""
        out = []
        for name, kind, enters in zip(self.names, self.kind, self.enters, strict=True):
            if kind == "combination":
                out.append(f"{name}: only in combination, in {'; '.join(enters)}")
            elif kind == "none":
                out.append(f"{name}: not seen by the data (value from the prior)")
        return out


def standard_identifiability(
    projection: npt.ArrayLike,
    names: tuple[str, ...] | list[str],
    base_names: tuple[str, ...] | list[str],
    expressions: list[str] | None = None,
) -> Identifiability:
    """Classify every standard parameter (module docstring).

    Parameters
    ----------
    projection :
        ``T`` of ``beta = T theta``, shape (n_base, n_std).
    names, base_names :
        Standard and base parameter names.
    expressions :
        Readable base parameters (:meth:`BaseParameters.expressions`), default the names.
    """
    T = np.asarray(projection, dtype=float)
    scale = np.linalg.norm(T, axis=0)
    Tn = T / np.where(scale > 0, scale, 1.0)
    # orthonormal basis of the row space of T (column space of T^T)
    U, s, _ = np.linalg.svd(Tn.T, full_matrices=False)
    rank = int(np.sum(s > max(Tn.shape) * np.finfo(float).eps * (s[0] if s.size else 0.0)))
    Q = U[:, :rank]  # (n_std, rank)
    outside = 1.0 - np.einsum("ij,ij->i", Q, Q)  # squared distance of e_i to the row space
    expressions = list(base_names) if expressions is None else list(expressions)
    kinds, enters = [], []
    for i in range(T.shape[1]):
        rows = np.flatnonzero(np.abs(Tn[:, i]) > _RTOL)
        if rows.size == 0:
            kinds.append("none")
        elif outside[i] <= _RTOL:
            kinds.append("alone")
        else:
            kinds.append("combination")
        enters.append(
            tuple(
                f"{base_names[k]} = {expressions[k]}"
                if expressions[k] != base_names[k]
                else str(base_names[k])
                for k in rows
            )
        )
    weights = np.linalg.pinv(T).copy()  # (n_std, n_base): T^+ T projects on the row space
    weights[[k != "alone" for k in kinds]] = np.nan
    return Identifiability(
        names=tuple(names), kind=tuple(kinds), enters=tuple(enters), weights=weights
    )
