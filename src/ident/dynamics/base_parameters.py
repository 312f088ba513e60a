"""Base (identifiable) parameters of an observation matrix, found numerically.

The standard parameters ``P`` of a robot are not all identifiable from joint torques: some
columns of the stacked observation matrix ``W`` are zero (the parameter has no effect:
*unidentifiable*), others are linear combinations of earlier ones (*identifiable in linear
combination*). With ``independent`` columns ``W_b`` and ``dependent`` columns
``W_d = W_b K``,

    W P = W_b (P_b + K P_d) = W_b beta,

so the base parameters are ``beta = P_b + K P_d`` (Gautier 1990; Khalil and Dombre 2002).

Two methods choose the independent columns:

``"sequential"``
    The paper's numerical method (its reference [40]): columns are taken in order; a
    zero-norm column is unidentifiable; a column that does not raise the rank of the
    independent columns kept so far is in linear combination; otherwise it is independent.
    Implemented with Gram-Schmidt (re-orthogonalized), so the rank test of one column costs
    one projection.
``"qr"``
    QR with column pivoting (LAPACK ``geqp3``): the independent columns are the first ``rank``
    pivots, listed in the original column order. The columns kept favour the best
    conditioned ``W_b``, not the parameter order.

Tolerances are relative, and the rank is decided on column-normalized ``W`` (see
:func:`compute_base_parameters`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.linalg

from ident.dynamics.chain import FloatArray, IntArray, KinematicChain
from ident.errors import DataError, IdentWarning

__all__ = [
    "METHODS",
    "NEAR_DEPENDENCE_FLOOR",
    "RANK_RTOL",
    "BaseParameters",
    "compute_base_parameters",
    "nearly_aligned_axes",
    "torque_shares",
]

METHODS = ("qr", "sequential")

#: The one rank tolerance of every command (``verify``, ``run``, ``identify``, the excitation
#: objective), relative to the scale of the data: a column is independent when the part of its
#: *normalized* column orthogonal to the independent ones exceeds ``RANK_RTOL``.
#:
#: Why 1e-3: a joint axis misaligned by ``delta`` radians from parallel (or perpendicular) to
#: another leaves the column that would combine with the other's at about ``delta`` from their
#: span (measured: 4.1e-6 for the 3.7e-6 rad of the xArm7's ``rpy="1.5708"``). URDF angles
#: rounded to 4-5 digits misalign axes by up to ~2e-4 rad, and such a column cannot be
#: estimated from noisy torques (its standard deviation is ~1/delta times a clean one's: WLS
#: splits one base parameter into a +-huge pair). Genuinely independent columns of real robots
#: score above 0.4 on random states (UR5, Panda, xArm7, TIAGo, TX40, with friction and rotor
#: inertia), structurally dependent ones below 1e-11 (11-digit angles), so 1e-3 sits far from
#: both and treats axes within ~1e-3 rad of parallel or perpendicular as exactly so.
#: A column is zero (unidentifiable) at round-off, below ``max(W.shape) * eps`` times the
#: largest column norm, so a parameter in small units is not mistaken for one.
RANK_RTOL = 1e-3

#: Scores (see :attr:`BaseParameters.scores`) above this and at most the rank tolerance are
#: *nearly* dependent: merged into the base parameters, and named in a warning. Below it, the
#: dependence is exact up to round-off (11-digit URDF angles leave ~1e-11).
NEAR_DEPENDENCE_FLOOR = 1e-9

# Entries of K (in normalized-column units) below this are printed as absent.
_EXPRESSION_CUTOFF = 1e-9


@dataclass(frozen=True, eq=False)  # arrays: no field-wise ==, made read-only
class BaseParameters:
    """Base parameters of an observation matrix: which columns, and how they combine.

    Attributes
    ----------
    names :
        Names of the considered columns (standard parameters), length ``n_params``.
    independent :
        Indices of the independent columns, increasing, shape (n_independent,).
    dependent :
        Indices of the columns in linear combination, increasing, shape (n_dependent,).
    unidentifiable :
        Indices of the zero columns, increasing, shape (n_unidentifiable,).
    K :
        Combination matrix, shape (n_independent, n_dependent), in the units of the
        parameters: ``beta = P[independent] + K @ P[dependent]``.
    rank :
        Numerical rank of ``W`` (= n_independent).
    tolerance :
        Relative tolerance used (on normalized columns; see :func:`compute_base_parameters`).
    method :
        ``"qr"`` or ``"sequential"``.
    scores :
        For every considered column, shape (n_params,): the norm of its part orthogonal to
        the independent columns chosen before it, relative to its own norm (``|R_kk|`` of the
        pivoted QR for ``"qr"``); 0 for zero columns. Independent columns score above
        ``tolerance``, dependent ones below; the gap shows how clear the decision was.
    """

    names: tuple[str, ...]
    independent: IntArray
    dependent: IntArray
    unidentifiable: IntArray
    K: FloatArray
    rank: int
    tolerance: float
    method: str
    scores: FloatArray
    _K_normalized: FloatArray

    def __post_init__(self) -> None:
        for name in ("independent", "dependent", "unidentifiable", "K", "scores", "_K_normalized"):
            value = np.array(getattr(self, name), copy=True)
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def nearly_dependent(self) -> IntArray:
        """Dependent columns that are only *nearly* in the span of the independent ones.

        Their score is above :data:`NEAR_DEPENDENCE_FLOOR` (not round-off) and at most
        :attr:`tolerance`: typically joint axes parallel or perpendicular up to the rounding of
        the URDF's angles. They are merged into the base parameters like exact dependents.
        """
        scores = self.scores[self.dependent]
        near = (scores > NEAR_DEPENDENCE_FLOOR) & (scores <= self.tolerance)
        return np.asarray(self.dependent[near], dtype=np.intp)

    def near_dependence_note(self) -> str:
        """One sentence naming the nearly dependent parameters, or ``""`` when there are none."""
        near = self.nearly_dependent
        if near.size == 0:
            return ""
        listed = ", ".join(f"{self.names[j]} ({self.scores[j]:.1e})" for j in near)
        return (
            f"parameter(s) {listed} are nearly, not exactly, combinations of others (the "
            f"number: the part of the column outside the others' span, about the misalignment "
            f"in rad of joint axes meant to be parallel or perpendicular, e.g. URDF angles "
            f'rounded to 4-5 digits such as rpy="1.5708"); below the rank tolerance '
            f"{self.tolerance:g}, so they are merged into the base parameters as if the axes "
            f"were exactly aligned"
        )

    @property
    def n_params(self) -> int:
        """Number of considered (standard) parameters."""
        return len(self.names)

    @property
    def base_names(self) -> tuple[str, ...]:
        """Names of the base parameters: the independent parameter's name, suffixed ``R``
        when other parameters are combined into it."""
        combined = np.any(np.abs(self._K_normalized) > _EXPRESSION_CUTOFF, axis=1)
        return tuple(
            self.names[i] + ("R" if combined[k] else "") for k, i in enumerate(self.independent)
        )

    @property
    def projection(self) -> FloatArray:
        """Matrix ``T`` of shape (n_independent, n_params) with ``beta = T @ P``."""
        out = np.zeros((len(self.independent), self.n_params))
        out[np.arange(len(self.independent)), self.independent] = 1.0
        out[:, self.dependent] = self.K
        return out

    def project(self, params: FloatArray) -> FloatArray:
        """Base parameters of standard parameters.

        Parameters
        ----------
        params :
            Standard parameters, shape (..., n_params), in the order of :attr:`names`.

        Returns
        -------
        :
            ``beta = P[independent] + K @ P[dependent]``, shape (..., n_independent).
        """
        params = np.asarray(params, dtype=float)
        if params.shape[-1] != self.n_params:
            raise DataError(
                f"params must have {self.n_params} entries on the last axis, "
                f"got shape {params.shape}"
            )
        return params[..., self.independent] + params[..., self.dependent] @ self.K.T

    def base_columns(self, W: FloatArray) -> FloatArray:
        """Independent columns ``W[:, independent]`` of an observation matrix (n_rows, n_params)."""
        W = np.asarray(W)
        if W.shape[-1] != self.n_params:
            raise DataError(f"W must have {self.n_params} columns, got shape {W.shape}")
        return W[..., self.independent]

    def expressions(self, precision: int = 4) -> list[str]:
        """Readable base parameters, for example ``"Iyy1 + 0.6 mcx1 + 0.09 m1"``.

        Coefficients are printed with ``precision`` significant digits; combinations
        whose coefficient is below 1e-9 in normalized-column units are numerical noise and
        are left out of the text (not of :attr:`K`).
        """
        lines = []
        for k, i in enumerate(self.independent):
            text = self.names[i]
            for d, j in enumerate(self.dependent):
                if abs(self._K_normalized[k, d]) <= _EXPRESSION_CUTOFF:
                    continue
                coefficient = self.K[k, d]
                sign = "-" if coefficient < 0 else "+"
                magnitude = f"{abs(coefficient):.{precision}g}"
                term = self.names[j] if magnitude == "1" else f"{magnitude} {self.names[j]}"
                text += f" {sign} {term}"
            lines.append(text)
        return lines

    def counts(self) -> dict[str, int]:
        """``rank``, ``n_independent``, ``n_dependent``, ``n_unidentifiable``, ``n_params``."""
        return {
            "rank": self.rank,
            "n_independent": len(self.independent),
            "n_dependent": len(self.dependent),
            "n_unidentifiable": len(self.unidentifiable),
            "n_params": self.n_params,
        }


def _sequential(
    normalized: FloatArray, candidates: IntArray, tol: float
) -> tuple[list, list, dict]:
    """Gram-Schmidt in column order: (independent, dependent, scores)."""
    basis = np.zeros((normalized.shape[0], 0))
    independent, dependent, scores = [], [], {}
    for j in candidates:
        residual = normalized[:, j].copy()
        for _ in range(2):  # re-orthogonalize: one pass loses orthogonality
            residual -= basis @ (basis.T @ residual)
        score = float(np.linalg.norm(residual))
        scores[j] = score
        if score > tol:
            independent.append(j)
            basis = np.column_stack([basis, residual / score])
        else:
            dependent.append(j)
    return independent, dependent, scores


def _pivoted_qr(
    normalized: FloatArray, candidates: IntArray, tol: float
) -> tuple[list, list, dict]:
    """QR with column pivoting: (independent, dependent, scores)."""
    _, r, pivots = scipy.linalg.qr(normalized[:, candidates], mode="economic", pivoting=True)
    diagonal = np.abs(np.diag(r))
    rank = int(np.sum(diagonal > tol * diagonal[0])) if diagonal.size else 0
    scores = {j: 0.0 for j in candidates}
    for k, p in enumerate(pivots[: diagonal.size]):
        scores[candidates[p]] = float(diagonal[k])
    chosen = {int(candidates[p]) for p in pivots[:rank]}
    independent = [j for j in candidates if j in chosen]
    dependent = [j for j in candidates if j not in chosen]
    return independent, dependent, scores


def compute_base_parameters(
    W: FloatArray,
    names: Sequence[str],
    *,
    method: str = "qr",
    rtol: float | None = None,
) -> BaseParameters:
    """Find the base parameters of a stacked observation matrix.

    Parameters
    ----------
    W :
        Observation matrix, shape (n_rows, n_params), rows stacked over samples and joints.
    names :
        Names of the ``n_params`` columns.
    method :
        ``"qr"`` (column pivoting) or ``"sequential"`` (the paper's method).
    rtol :
        Relative tolerance of both decisions; default :data:`RANK_RTOL` for the rank and
        ``max(W.shape) * eps`` for zero columns.

    Returns
    -------
    :
        The classification of the columns and the combination matrix ``K``.

    Notes
    -----
    Column units differ (kg, kg*m, kg*m^2 parameters give columns in m/s^2, m/s^2 and 1/s^2
    times lever arms), and their norms differ by orders of magnitude; identifiability does not
    depend on those units (scaling a parameter scales its column). So:

    1. A column is *unidentifiable* when its norm is at most ``max(W.shape) * eps`` (or
       ``rtol`` when given) times the largest column norm (it is zero up to the round-off of
       the computation that produced it).
    2. The other columns are divided by their norms, and the rank decisions are made on this
       normalized matrix with ``rtol``: a column is independent when its part orthogonal to
       the independent columns before it has a norm above ``rtol`` (sequential), or when
       ``|R_kk| > rtol * |R_00|`` (pivoted QR; ``|R_00| = 1``).

    The rank then equals ``numpy.linalg.matrix_rank`` of the normalized matrix, and is the same
    for both methods unless a singular value sits at the tolerance. Raises :class:`DataError`
    for a non-2-D or non-finite ``W``, a wrong number of names, or an unknown method.
    """
    W, names = _checked_observation_matrix(W, names, method)
    tol = RANK_RTOL if rtol is None else float(rtol)
    zero_tol = float(max(W.shape) * np.finfo(float).eps) if rtol is None else tol
    normalized, norms, nonzero = _normalized_columns(W, zero_tol)
    search = _sequential if method == "sequential" else _pivoted_qr
    found = search(normalized, np.flatnonzero(nonzero), tol)
    base = _classified(names, normalized, norms, nonzero, found, tol, method)
    note = base.near_dependence_note()
    if note:
        warnings.warn(note[0].upper() + note[1:] + ".", IdentWarning, stacklevel=2)
    return base


def _classified(
    names: tuple[str, ...],
    normalized: FloatArray,
    norms: FloatArray,
    nonzero: np.ndarray,
    found: tuple[list[int], list[int], dict[int, float]],
    tol: float,
    method: str,
) -> BaseParameters:
    """The :class:`BaseParameters` of a column search's (independent, dependent, scores) on
    the normalized matrix (n_rows, n_params) with column ``norms`` and ``nonzero`` mask."""
    independent, dependent, score_map = found
    independent_idx = np.array(independent, dtype=np.intp)
    dependent_idx = np.array(dependent, dtype=np.intp)
    K, k_normalized = _combination_matrix(normalized, norms, independent_idx, dependent_idx)
    scores = np.zeros(len(names))
    for j, score in score_map.items():
        scores[j] = score
    return BaseParameters(
        names=names,
        independent=independent_idx,
        dependent=dependent_idx,
        unidentifiable=np.flatnonzero(~nonzero).astype(np.intp),
        K=K,
        rank=int(independent_idx.size),
        tolerance=tol,
        method=method,
        scores=scores,
        _K_normalized=k_normalized,
    )


def _checked_observation_matrix(
    W: FloatArray, names: Sequence[str], method: str
) -> tuple[FloatArray, tuple[str, ...]]:
    """``W`` as a float array (n_rows, n_params) and the names as a tuple, after checking
    them and ``method``. Raises :class:`DataError`."""
    W = np.asarray(W, dtype=float)
    names = tuple(names)
    if W.ndim != 2:
        raise DataError(f"W must be 2-D (n_rows, n_params), got shape {W.shape}")
    if W.shape[1] != len(names):
        raise DataError(f"W has {W.shape[1]} columns but {len(names)} names were given")
    if not np.all(np.isfinite(W)):
        raise DataError("W contains NaN or inf; check the states used to build it")
    if method not in METHODS:
        raise DataError(f"unknown base-parameter method {method!r}; use one of {METHODS}")
    return W, names


def _normalized_columns(
    W: FloatArray, zero_tol: float
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_]]:
    """The columns of ``W`` (n_rows, n_params) divided by their norms.

    Returns the normalized matrix (zero columns where ``nonzero`` is False), the column
    norms (n_params,) in the columns' units, and ``nonzero`` (n_params,): the norm is above
    ``zero_tol`` times the largest one.
    """
    norms = np.linalg.norm(W, axis=0)
    largest = float(norms.max()) if norms.size else 0.0
    nonzero = norms > zero_tol * largest
    normalized = np.zeros_like(W)
    normalized[:, nonzero] = W[:, nonzero] / norms[nonzero]
    return normalized, norms, nonzero


def _combination_matrix(
    normalized: FloatArray, norms: FloatArray, independent: IntArray, dependent: IntArray
) -> tuple[FloatArray, FloatArray]:
    """``K`` with ``W_d = W_b K`` (n_base, n_dependent), in parameter units, and the same on
    the normalized columns: least squares on the normalized columns, then scaled back by
    the column ``norms``."""
    k_normalized: FloatArray
    if independent.size and dependent.size:
        solution = np.linalg.lstsq(
            normalized[:, independent], normalized[:, dependent], rcond=None
        )[0]
        k_normalized = np.asarray(solution, dtype=np.float64)
    else:
        k_normalized = np.zeros((independent.size, dependent.size))
    K = k_normalized / norms[independent, None] * norms[None, dependent]
    return K, k_normalized


def torque_shares(W_base: FloatArray, beta: FloatArray) -> FloatArray:
    """Share of the torques each base parameter explains: ``|beta_i| ||W_i|| / ||W beta||``.

    Unit-free; on random states of a robot's motion it does not depend on a trajectory.
    Parameters with a share of at least 1e-2 are a stage's *major* parameters.

    Parameters
    ----------
    W_base :
        Base observation matrix, shape (n_rows, n_base).
    beta :
        Base parameter values, shape (n_base,).

    Returns
    -------
    :
        Shape (n_base,); zeros-safe (a zero torque norm divides by 1).
    """
    beta = np.asarray(beta, dtype=float)
    total = float(np.linalg.norm(W_base @ beta))
    return np.abs(beta) * np.linalg.norm(W_base, axis=0) / (total if total > 0 else 1.0)


def nearly_aligned_axes(
    chain: KinematicChain, *, tolerance: float = RANK_RTOL
) -> list[tuple[str, str, float, float]]:
    """Joint axes that are parallel or perpendicular to within ``tolerance`` rad, not exactly.

    Each joint's axis is compared with its parent joint's (the angle between them does not
    depend on the parent's position) and a first joint's axis with gravity. A deviation
    between :data:`NEAR_DEPENDENCE_FLOOR` and ``tolerance`` is what URDF angles rounded to 4-5
    digits give (``rpy="1.5708"``: 3.7e-6 rad); the base parameters then treat the axes as
    exactly aligned (:data:`RANK_RTOL`), and this list says which.

    Parameters
    ----------
    chain :
        The kinematic chain.
    tolerance :
        Largest deviation reported [rad].

    Returns
    -------
    :
        ``(joint, other, deviation_rad, nominal_deg)`` per pair, ``other`` a joint name or
        ``"gravity"``, ``nominal_deg`` 0 (parallel) or 90 (perpendicular).
    """
    out = []
    g = np.asarray(chain.gravity, dtype=float)
    for i, name in enumerate(chain.body_names):
        axis = chain.placements[i, :3, :3] @ chain.axes[i]  # in the parent joint's frame
        p = int(chain.parents[i])
        if p >= 0:
            other, reference = chain.body_names[p], chain.axes[p]
        elif np.linalg.norm(g) > 0:
            other, reference = "gravity", g / np.linalg.norm(g)
        else:
            continue
        # angle in [0, pi/2] between the lines, accurate near 0 and pi/2
        angle = float(
            np.arctan2(np.linalg.norm(np.cross(axis, reference)), abs(float(axis @ reference)))
        )
        for nominal in (0.0, np.pi / 2):
            deviation = abs(angle - nominal)
            if NEAR_DEPENDENCE_FLOOR < deviation <= tolerance:
                out.append((name, other, deviation, float(np.degrees(nominal))))
    return out
