"""A fleet of robots of one model identified jointly: one rigid-body model shared, per-unit
friction and offsets.

**Columns.** The base columns of the robot's model (:class:`~ident.identify.estimation.
accumulate.BaseColumns`: the rigid-body base parameters, the rotor inertias, the per-joint
viscous ``fv``, Coulomb ``fs`` and offset ``off`` columns) are split in two: the *local*
columns (``fv``, ``fs``, ``off`` of every joint, not regrouped) are each unit's own, the
others (*shared*) are the fleet's. Unit ``u``'s rows are ``tau = Y_S x_S + Y_L x_L^u``.

**Rows, chunk by chunk** (:func:`chunk_equations`). A chunk of raw samples (with a margin on
both sides for the filters) is low-passed (zero-phase Butterworth, positions and torques alike,
so both describe the same instants), differentiated (central differences), and only every
``decimation``-th sample becomes a row: the regressor, the costly part, is evaluated at the
row rate (the cut-off sits below the row rate's Nyquist frequency, so the rows' noise is close
to white). Rows of a joint slower than ``velocity_threshold`` are left out (Coulomb's sign).
The rows are summed into per-joint normal equations
(:class:`~ident.identify.streaming.normal.NormalEquations`); nothing per sample outlives a
chunk.

**The joint solve** (:func:`solve_fleet`): weighted least squares over every unit's rows, each
unit and joint weighted by ``1 / sigma_uj^2`` (noise from its residual, two passes). The normal
matrix is block-arrow shaped (a shared block, one local block per unit, no unit-unit terms), so
the local blocks are eliminated (Schur complement): ``S = sum_u (A_SS - A_SL A_LL^-1 A_LS)``,
``r = sum_u (c_S - A_SL A_LL^-1 c_L)``, ``x_S = S^-1 r``, ``x_L^u = A_LL^-1 (c_L - A_LS x_S)``;
the covariances ``C_SS = S^-1``, ``C_LL^u = A_LL^-1 + K_u^T C_SS K_u`` (``K_u = A_LL^-1
A_LS``). Cost: linear in the number of units (one small factorization each), not cubic.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin
from scipy import signal

from ident.dynamics.chain import chain_from_model
from ident.dynamics.parameter_model import build_parameter_model
from ident.errors import DataError
from ident.identify.config import ModelConfig
from ident.identify.estimation.accumulate import BaseColumns
from ident.identify.streaming.normal import NormalEquations, scaled_inverse, weighted_sums
from ident.signals import central_differences, decay_length

__all__ = [
    "LOCAL_KINDS",
    "ChunkSettings",
    "FleetColumns",
    "FleetSolution",
    "UnitSolution",
    "WindowSums",
    "chunk_equations",
    "fleet_columns",
    "schur_solve",
    "scaled_covariances",
    "solve_fleet",
    "window_sums",
]

FloatArray = npt.NDArray[np.float64]

#: The per-unit kinds of extra columns (:data:`ident.dynamics.friction.KINDS`).
LOCAL_KINDS = ("fv", "fs", "off")
_LOCAL_NAME = re.compile(r"^(fv|fs|off)(\d+)$")


@dataclass(frozen=True)
class ChunkSettings:
    """How raw samples become rows (module docstring; SI).

    ``cutoff_hz``: low-pass cut-off [Hz]; ``decimation``: raw samples per row;
    ``velocity_threshold``: [rad/s]; ``order``: Butterworth order.
    """

    cutoff_hz: float = 20.0
    decimation: int = 20
    # rows near a velocity reversal are left out: a real joint's friction there is not
    # Coulomb's step (Stribeck, stiction), and sign(dq) is uncertain where dq ~ 0
    velocity_threshold: float = 0.2
    order: int = 4

    def margin(self, fs: float) -> int:
        """Raw samples added on each side of a chunk for the zero-phase filters: twice the
        impulse response's decay below 1e-9 of its peak (the Coulomb column is filtered from
        a velocity that is itself filtered, :func:`chunk_equations`)."""
        return 2 * decay_length(_sos(self, fs), rtol=1e-9) + 2


class FleetColumns:
    """The model's base columns split into shared and per-unit (local) ones.

    Attributes
    ----------
    columns :
        The :class:`BaseColumns`.
    names :
        Base parameter names in the kernels' column order (``columns.order``), length p:
        every vector and matrix of the fleet is in this order.
    local :
        Indices (into :attr:`names`) of the local columns (``fv``, ``fs``, ``off``), (l,).
    shared :
        Indices of the others, shape (s,).
    owner :
        The joint (0-based) of each local column, shape (l,).
    kind :
        ``fv``, ``fs`` or ``off`` of each local column.
    """

    def __init__(self, columns: BaseColumns, base_names: tuple[str, ...]) -> None:
        # the kernels' column order throughout (no reordering of the rows)
        self.columns = columns
        self.names = tuple(base_names[i] for i in columns.order)
        local, owner, kind = [], [], []
        for i, name in enumerate(self.names):
            m = _LOCAL_NAME.match(name)
            if m is not None:
                local.append(i)
                kind.append(m.group(1))
                owner.append(int(m.group(2)) - 1)
        if not local:
            raise DataError("the fleet model has no per-unit column (fv, fs or off).")
        self.local = np.array(local, dtype=np.intp)
        self.shared = np.setdiff1d(np.arange(len(self.names)), self.local)
        self.owner = np.array(owner, dtype=np.intp)
        self.kind = tuple(kind)
        fs = np.array([k == "fs" for k in kind])
        # the Coulomb columns (indices into names) and their joints
        self.coulomb, self.coulomb_owner = self.local[fs], self.owner[fs]

    @property
    def p(self) -> int:
        """Number of base columns."""
        return len(self.names)

    def rows(self, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
        """Regressor rows in :attr:`names`' (the kernels') order, shape (n, nv, p)."""
        return self.columns(q, dq, ddq)[:, :, : self.p]


def fleet_columns(
    model: pin.Model, rotor_inertia: bool = True, offset: bool = True, source: str = "config"
) -> FleetColumns:
    """The fleet's columns of a Pinocchio model: viscous and Coulomb friction on every joint,
    offsets and rotor inertias as asked (``source`` names the config in errors)."""
    terms = ModelConfig(
        viscous=True, coulomb=True, rotor_inertia=rotor_inertia, offset=offset
    ).extra_terms(model.nv, source)
    pm = build_parameter_model(model, terms, rng=0)
    return FleetColumns(BaseColumns(chain_from_model(model), pm), pm.base_names)


@dataclass(frozen=True, eq=False)
class WindowSums:
    """A window's (chunk's) rows, reduced to what the drift test needs.

    ``A`` (l, p): row ``i`` is the owner joint's normal-equation row of local column ``i``
    (a local column has rows only on its joint); ``c`` (l,); ``n`` (nv,) rows per joint;
    ``t0``, ``t1`` the window's first and last sample times [s]; ``log`` its log's index.
    """

    A: FloatArray
    c: FloatArray
    n: FloatArray
    t0: float
    t1: float
    log: int


@functools.lru_cache(maxsize=16)
def _sos(settings: ChunkSettings, fs: float) -> FloatArray:
    """The low-pass filter's second-order sections (cached: one design per run)."""
    return signal.butter(settings.order, settings.cutoff_hz, fs=fs, output="sos")


def chunk_equations(
    q: FloatArray,
    tau: FloatArray,
    fs: float,
    span: tuple[int, int, int, int],
    cols: FleetColumns,
    settings: ChunkSettings,
) -> NormalEquations:
    """Per-joint normal equations of one chunk's rows (module docstring).

    ``q``, ``tau`` (n, nv): raw samples [rad, N*m] of the chunk with its margins;
    ``span = (a, b, lo, hi)``: rows are taken at the samples ``a + i * decimation`` of
    ``[a, b)`` with ``lo <= k < hi`` (the segment's samples far enough from its ends for the
    filter), indices into ``q``.
    """
    a, b, lo, hi = span
    d = settings.decimation
    idx = np.arange(a, b, d)
    idx = idx[(idx >= lo) & (idx < hi)]
    eq = NormalEquations(q.shape[1], cols.p)
    if idx.size == 0:
        return eq
    nv = q.shape[1]
    # positions and torques through one filter call, each signal a contiguous row (faster)
    both = signal.sosfiltfilt(_sos(settings, fs), np.concatenate([q.T, tau.T]), axis=1)
    qf, tf = both[:nv].T, both[nv:].T
    dq, ddq = central_differences(qf, fs)
    X = cols.rows(qf[idx], dq[idx], ddq[idx])
    # The torque's Coulomb step at a reversal went through the low-pass: spread over ~1 /
    # cutoff_hz, ringing beyond the velocity threshold. The column goes through the same
    # filter (sign(dq) filtered), so that rows and torques describe the same signal; with the
    # bare sign the 20 x 600 s UR5 fleet's friction was biased by up to 4 standard
    # deviations (82 % of its 95 % intervals held the truth)
    sign = signal.sosfiltfilt(_sos(settings, fs), np.sign(dq[:, cols.coulomb_owner]).T, axis=1)
    X[:, cols.coulomb_owner, cols.coulomb] = sign.T[idx]
    keep = np.abs(dq[idx]) >= settings.velocity_threshold
    eq.add_rows(X, tf[idx], keep)
    return eq


def window_sums(eq: NormalEquations, cols: FleetColumns, t: tuple[float, float, int]) -> WindowSums:
    """The :class:`WindowSums` of a chunk's equations; ``t = (t0, t1, log index)``."""
    A = eq.A[cols.owner, cols.local, :]
    c = eq.c[cols.owner, cols.local]
    return WindowSums(A=A, c=c, n=eq.sw.copy(), t0=t[0], t1=t[1], log=t[2])


@dataclass(frozen=True, eq=False)
class UnitSolution:
    """One unit's local parameters.

    ``x`` (l,) local parameters (SI), ``covariance`` (l, l), ``sigma`` (nv,) noise per joint
    [N*m], ``n_rows`` (nv,) rows per joint.
    """

    x: FloatArray
    covariance: FloatArray
    sigma: FloatArray
    n_rows: FloatArray

    @property
    def std(self) -> FloatArray:
        """Standard deviations of ``x``, shape (l,)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))


@dataclass(frozen=True, eq=False)
class FleetSolution:
    """The joint solve: shared parameters ``x`` (s,) with ``covariance`` (s, s), and the
    units' :class:`UnitSolution` (in the units' order)."""

    x: FloatArray
    covariance: FloatArray
    units: tuple[UnitSolution, ...]


def schur_solve(
    units: list[NormalEquations], weights: list[FloatArray], cols: FleetColumns
) -> tuple[FloatArray, FloatArray, list[tuple[FloatArray, FloatArray]]]:
    """One weighted solve, per-joint weights ``weights[u]`` (nv,) for unit ``u``: ``x_S``,
    ``C_SS`` and per unit ``(x_L, C_LL)`` (module docstring)."""
    S_, L_ = cols.shared, cols.local
    s = S_.size
    S = np.zeros((s, s))
    r = np.zeros(s)
    parts = []
    for k, (eq, v) in enumerate(zip(units, weights, strict=True)):
        A, c = weighted_sums(eq, v)
        inv_LL = scaled_inverse(A[np.ix_(L_, L_)], f"unit {k}'s friction and offsets")
        K = inv_LL @ A[np.ix_(L_, S_)]  # (l, s)
        S += A[np.ix_(S_, S_)] - A[np.ix_(S_, L_)] @ K
        r += c[S_] - K.T @ c[L_]
        parts.append((inv_LL, K, c[L_]))
    C_SS = scaled_inverse(0.5 * (S + S.T), "the shared parameters")
    x_S = C_SS @ r
    out = []
    for inv_LL, K, c_L in parts:
        x_L = inv_LL @ c_L - K @ x_S
        C_LL = inv_LL + K @ C_SS @ K.T
        out.append((x_L, 0.5 * (C_LL + C_LL.T)))
    return x_S, C_SS, out


def _full(x_S: FloatArray, x_L: FloatArray, cols: FleetColumns) -> FloatArray:
    """A unit's parameter vector (p,) in :attr:`FleetColumns.names`' order."""
    x = np.empty(cols.p)
    x[cols.shared], x[cols.local] = x_S, x_L
    return x


def _joint_weights(
    eq: NormalEquations, var: FloatArray, factors: FloatArray | float = 1.0
) -> FloatArray:
    """Per-joint weights ``1 / (factors_j var_j)`` (nv,) of a unit's rows, 0 on joints without
    rows; ``var`` [N^2 m^2] (NaN where unknown) floored at 1e-12 of its largest value (a joint
    fitted exactly would otherwise weigh infinitely)."""
    v = np.nan_to_num(var)
    v = np.maximum(v, 1e-12 * v.max() + 1e-300)
    return np.where(eq.sw > 0, 1.0 / (factors * v), 0.0)


def solve_fleet(units: list[NormalEquations], cols: FleetColumns, passes: int = 2) -> FleetSolution:
    """Weighted least squares of every unit's rows, shared and local parameters (module
    docstring); ``passes`` re-weightings by the per-unit, per-joint residual variance
    ``S_uj / n_uj`` (the rows outnumber the parameters by far).

    Raises
    ------
    NotIdentifiable
        When the rows leave a shared or a unit's local direction undetermined.
    """
    weights = [(eq.sw > 0).astype(float) for eq in units]
    sigma = [np.full(eq.nv, np.nan) for eq in units]
    for _ in range(passes + 1):
        x_S, C_SS, local = schur_solve(units, weights, cols)
        for k, (eq, (x_L, _)) in enumerate(zip(units, local, strict=True)):
            ss = np.clip(eq.residual_ss(_full(x_S, x_L, cols)), 0.0, None)
            var = np.where(eq.sw > 0, ss / np.maximum(eq.sw, 1.0), np.nan)
            sigma[k] = np.sqrt(var)
            weights[k] = _joint_weights(eq, var)
    solutions = tuple(
        UnitSolution(x=x_L, covariance=C_LL, sigma=sig, n_rows=eq.sw.copy())
        for (x_L, C_LL), sig, eq in zip(local, sigma, units, strict=True)
    )
    return FleetSolution(x=x_S, covariance=C_SS, units=solutions)


def scaled_covariances(
    sol: FleetSolution, units: list[NormalEquations], cols: FleetColumns, factors: FloatArray
) -> FleetSolution:
    """``sol`` with its covariances for rows whose noise variance, per joint ``j``, counts
    ``factors[j]`` times its residual's (:func:`~ident.identify.streaming.fleet_drift.
    window_factors`: the rows' noise is correlated over a few rows, so each row is worth
    less than one independent row). The estimate is unchanged; the covariances are those of
    the weighted solve with weights ``1 / (factors_j sigma_uj^2)`` (exact when the factors
    are equal, the sandwich's first order otherwise)."""
    weights = [
        _joint_weights(eq, u.sigma**2, factors) for eq, u in zip(units, sol.units, strict=True)
    ]
    _, C_SS, local = schur_solve(units, weights, cols)
    out = tuple(
        UnitSolution(x=u.x, covariance=C_LL, sigma=u.sigma, n_rows=u.n_rows)
        for u, (_, C_LL) in zip(sol.units, local, strict=True)
    )
    return FleetSolution(x=sol.x, covariance=C_SS, units=out)
