"""Excitation objective: paper eq. 15 (or D-optimality) on the stage's base observation matrix.

For a design ``x`` the family gives a trajectory; the stage's observation matrix ``W`` stacks
the regressor rows of the stage's joints (``stage.torque_rows``) over the samples, restricted to
the stage's independent base columns ``W_b``. The criterion is computed from the small Gram
matrix ``G = W_b^T W_b`` accumulated sample by sample (never the tall matrix, never its SVD),
see :func:`singular_values_from_gram`.

Scaling (``scaled=True``, the default; see ``docs/excitation.md``): as printed, eq. 15
``cond(W_b) + 1/sigma_min(W_b) + sigma_max(W_b)`` depends on the units of the parameters and
grows with the number of samples, so it can reward weak excitation. We evaluate it on

    W~ = W_b S / sqrt(n_samples * n_rows)

- rows: divided by ``sqrt(n_samples * n_rows)`` so that ``W~^T W~`` is the mean over the rows
  (independent of the sampling rate and of the period);
- columns: ``S = diag(s)`` with ``s_j = 1 / rms_j`` where ``rms_j`` is the RMS of base column
  ``j`` over a rich reference motion (random states spanning the joint position, velocity and
  acceleration limits). A scaled column is then the torque signature of the parameter relative
  to what the robot can produce at full capability: dimensionless and ~1 for strong excitation.

With this scaling, ``sigma_min`` drops when the motion is slowed down, so the criterion does
not prefer a slower version of the same path (``tests/test_objective.py`` shows it; it also
shows that the unscaled form may). ``scaled=False`` gives the printed form on the raw SI matrix.

Constraint violations add the graded penalty of :func:`ident.excitation.constraints.penalty`;
a non-finite or rank-deficient criterion is replaced by ``CRITERION_CAP``, so the fitness is
always finite.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from ident.excitation.constraints import JointLimits, penalty
from ident.excitation.family import (
    ConstraintViolations,
    ExcitationFamily,
    FloatArray,
    TrajectoryBatch,
    check_design,
)

__all__ = [
    "CRITERION_CAP",
    "DEFAULT_PENALTY_WEIGHT",
    "ExcitationObjective",
    "ObjectiveDetails",
    "criterion_from_gram",
    "select_base_columns",
    "singular_values_from_gram",
]

Criterion = Literal["paper", "logdet"]
CRITERION_CAP = 1e10
DEFAULT_PENALTY_WEIGHT = 1e10


@dataclass(frozen=True)
class ObjectiveDetails:
    """Everything the objective knows about one particle.

    Attributes
    ----------
    fitness :
        Criterion (capped) plus penalty.
    criterion :
        Value of the chosen criterion (capped at ``CRITERION_CAP``).
    cond, sigma_min, sigma_max :
        Condition number and extreme singular values of the (scaled) base observation matrix.
    logdet :
        ``log det(W~^T W~)`` (``-inf`` when singular).
    penalty :
        Constraint penalty.
    feasible :
        True when no constraint is violated.
    violations :
        ``{constraint: magnitude}`` of the violated constraints.
    """

    fitness: float
    criterion: float
    cond: float
    sigma_min: float
    sigma_max: float
    logdet: float
    penalty: float
    feasible: bool
    violations: dict[str, float] = field(default_factory=dict)


def singular_values_from_gram(gram: FloatArray) -> FloatArray:
    """Singular values of ``W`` from its Gram matrix ``G = W^T W``, accurately.

    ``sqrt(eigvalsh(G))`` loses ``sigma_min`` to round-off when ``cond(W)`` exceeds ~1e4
    (relative error ``eps * cond(W)^2``). Most of that ill-conditioning is column scaling, so
    the Gram matrix is equilibrated first, ``G~ = D G D`` with ``D = diag(G)^(-1/2)``, factored
    ``G~ = R~^T R~`` (Cholesky), and the singular values are those of the small triangular
    ``R = R~ D^-1`` (``W = Q R``): relative error about ``eps * cond(W D)^2`` instead. Where the
    Cholesky factorization fails (numerically singular ``G``) ``sqrt(eigvalsh(G))`` is used,
    with eigenvalues below ``k * eps * lambda_max`` set to 0.

    Parameters
    ----------
    gram :
        Finite Gram matrices, shape (n_batch, k, k).

    Returns
    -------
    :
        Singular values, descending, shape (n_batch, k).
    """
    diag = np.einsum("bii->bi", gram)
    positive = np.all(diag > 0.0, axis=1)
    inv = np.where(positive[:, None], 1.0 / np.sqrt(np.where(diag > 0.0, diag, 1.0)), 1.0)
    equilibrated = gram * inv[:, :, None] * inv[:, None, :]
    out = np.empty(diag.shape)
    done = np.zeros(gram.shape[0], dtype=bool)
    if np.all(positive):
        # the whole batch at once (the same LAPACK calls per matrix); one failing Cholesky
        # factorization fails the batch: then the per-matrix loop below sorts them out
        try:
            lower = np.linalg.cholesky(equilibrated)
        except np.linalg.LinAlgError:
            pass
        else:
            upper = np.swapaxes(lower, -1, -2) / inv[:, None, :]
            return np.asarray(np.linalg.svd(upper, compute_uv=False), dtype=np.float64)
    for b in np.flatnonzero(positive):
        try:
            lower = np.linalg.cholesky(equilibrated[b])
        except np.linalg.LinAlgError:
            continue
        out[b] = np.linalg.svd(lower.T / inv[b][None, :], compute_uv=False)
        done[b] = True
    rest = np.flatnonzero(~done)
    if rest.size:
        lam = np.linalg.eigvalsh(gram[rest])[:, ::-1]
        # eigenvalues at round-off level of a singular G are zero (rank tolerance k * eps)
        noise = gram.shape[1] * np.finfo(float).eps * np.maximum(lam[:, :1], 0.0)
        out[rest] = np.sqrt(np.where(lam > noise, lam, 0.0))
    return out


def criterion_from_gram(
    gram: FloatArray, criterion: Criterion = "paper"
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Singular-value criteria from Gram matrices.

    Parameters
    ----------
    gram :
        ``W^T W``, shape (n_batch, k, k).
    criterion :
        ``"paper"``: ``cond + 1/sigma_min + sigma_max`` (eq. 15); ``"logdet"``:
        ``-log det(W^T W)`` (D-optimality, minimized).

    Returns
    -------
    :
        ``value`` (capped at ``CRITERION_CAP``, finite), ``cond``, ``sigma_min``,
        ``sigma_max``, ``logdet``, each of shape (n_batch,).
    """
    if criterion not in ("paper", "logdet"):
        raise ValueError(f"criterion must be 'paper' or 'logdet', got {criterion!r}")
    gram = np.asarray(gram, dtype=float)
    finite = np.all(np.isfinite(gram), axis=(1, 2))
    sigma = singular_values_from_gram(np.where(finite[:, None, None], gram, 0.0))
    sigma_min, sigma_max = sigma[:, -1], sigma[:, 0]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        cond = np.where(sigma_min > 0.0, sigma_max / sigma_min, np.inf)
        logdet = np.where(
            sigma_min > 0.0, 2.0 * np.sum(np.log(np.maximum(sigma, 1e-300)), axis=1), -np.inf
        )
        value = cond + 1.0 / sigma_min + sigma_max if criterion == "paper" else -logdet
    value = np.where(finite & np.isfinite(value), value, CRITERION_CAP)
    value = np.minimum(value, CRITERION_CAP)
    cond = np.where(finite, cond, np.inf)
    return value, cond, sigma_min, sigma_max, logdet


def select_base_columns(w: FloatArray, names: Sequence[str] | None = None) -> tuple[int, ...]:
    """Independent columns of an observation matrix (QR with column pivoting).

    Delegates to :func:`ident.dynamics.base_parameters.compute_base_parameters` with
    ``method="qr"`` (columns normalized first, so the choice does not depend on the units of
    the parameters) and its one rank tolerance
    (:data:`ident.dynamics.base_parameters.RANK_RTOL`), the same reduction the identification
    uses.

    Parameters
    ----------
    w :
        Observation matrix, shape (n_rows, n_cols).
    names :
        Column labels (only used in messages); default ``c0, c1, ...``.

    Returns
    -------
    :
        Sorted indices of the independent (base) columns.
    """
    import scipy.linalg

    from ident.dynamics.base_parameters import compute_base_parameters

    labels = tuple(names) if names is not None else tuple(f"c{i}" for i in range(w.shape[1]))
    if w.shape[0] > w.shape[1]:
        # W = Q R with orthonormal Q: R has the same column norms and inner products, hence
        # the same pivots and rank, at the cost of a small matrix
        w = scipy.linalg.qr(w, mode="r")[0][: w.shape[1]]
    base = compute_base_parameters(w, labels, method="qr")
    return tuple(sorted(int(i) for i in base.independent))


def _regressor(chain: Any, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
    """Joint-torque regressor (n_samples, nv, n_params) from ``ident.dynamics``."""
    from ident.dynamics.regressor import joint_torque_regressor

    return joint_torque_regressor(chain, q, dq, ddq)


def _gram_batch(
    chain: Any,
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
    rows: Sequence[int],
    columns: Sequence[int],
) -> FloatArray:
    """Gram matrices of the stacked observation matrices of a batch.

    The fused numba kernel :func:`ident.dynamics.gram.regressor_gram` (no regressor tensor).

    Parameters
    ----------
    q, dq, ddq :
        Shape (n_batch, n_samples, nq).
    rows, columns :
        Regressor rows (joints) and columns (parameters) kept.

    Returns
    -------
    :
        Shape (n_batch, len(columns), len(columns)).
    """
    from ident.dynamics.gram import regressor_gram

    return np.asarray(
        regressor_gram(chain, q, dq, ddq, rows=list(rows), columns=list(columns)), dtype=float
    )


def _chain_of(robot: Any) -> Any:
    chain = getattr(robot, "chain", None)
    if chain is None:
        from ident.dynamics.chain import chain_from_model

        chain = chain_from_model(robot.model)
    return chain


class ExcitationObjective:
    """Fitness of excitation designs for one identification stage, vectorized over a swarm.

    Parameters
    ----------
    robot :
        An :class:`ident.Robot` (uses ``chain`` or ``model``, ``joint_names`` and limits).
    stage :
        The identification stage: an object with ``torque_rows`` (joint rows of the regressor
        that are measured) and ``columns`` (indices of the stage's parameters in the standard
        parameter vector), e.g. :class:`ident.dynamics.stage.Stage`. ``None``: all rows, all
        columns.
    family :
        Excitation family giving the trajectories.
    criterion :
        ``"paper"`` (eq. 15) or ``"logdet"`` (D-optimality).
    penalty_weight :
        Weight of the constraint penalty (see :func:`ident.excitation.constraints.penalty`).
    base_columns :
        Base columns (indices into the standard parameter vector). Default: chosen once by QR
        with pivoting from a rich random-state observation matrix of the stage.
    column_scale :
        Scale ``s`` of each base column. Default: ``1 / RMS`` of the column over the reference
        motion (only used when ``scaled``).
    scaled :
        Evaluate the criterion on the scaled matrix (default) or on the raw one (eq. 15 as
        printed, for comparison).
    n_reference_samples :
        Random states of the reference motion.
    rng :
        Seed or generator of the reference motion.
    safety :
        A :class:`ident.excitation.safety.SafetyModel`: adds the cheap clearance and torque
        constraints (``clearance:<pair>``, ``torque:<joint>``, evaluated at
        ``safety.config.check_samples`` samples per trajectory) to the family's constraints,
        with the same penalty. ``None`` (default): the family's constraints only.
    """

    def __init__(
        self,
        robot: Any,
        stage: Any,
        family: ExcitationFamily,
        *,
        criterion: Criterion = "paper",
        penalty_weight: float = DEFAULT_PENALTY_WEIGHT,
        base_columns: Sequence[int] | None = None,
        column_scale: npt.ArrayLike | None = None,
        scaled: bool = True,
        n_reference_samples: int = 2000,
        rng: np.random.Generator | int | None = 0,
        safety: Any = None,
    ) -> None:
        if criterion not in ("paper", "logdet"):
            raise ValueError(f"criterion must be 'paper' or 'logdet', got {criterion!r}")
        self.robot = robot
        self.family = family
        self.criterion: Criterion = criterion
        self.penalty_weight = float(penalty_weight)
        self.scaled = bool(scaled)
        self.safety = safety
        self.chain = _chain_of(robot)
        nv = len(robot.joint_names)
        n_bodies = self.chain.n_bodies  # a mimic joint's body has parameters, no coordinate
        n_params = 10 * n_bodies
        rows = tuple(range(nv)) if stage is None else tuple(int(r) for r in stage.torque_rows)
        cols = tuple(range(n_params)) if stage is None else tuple(int(c) for c in stage.columns)
        self.rows = rows
        self.stage_columns = cols
        ref_q, ref_dq, ref_ddq = self._reference_states(n_reference_samples, rng)
        y = _regressor(self.chain, ref_q, ref_dq, ref_ddq)[:, list(rows)][:, :, list(cols)]
        w_ref = y.reshape(-1, len(cols))
        if base_columns is None:
            from ident.dynamics.parameters import parameter_names

            all_names = parameter_names(n_bodies)
            local = select_base_columns(w_ref, [all_names[c] for c in cols])
            self.columns = tuple(cols[i] for i in local)
        else:
            self.columns = tuple(int(c) for c in base_columns)
            local = tuple(cols.index(c) for c in self.columns)
        w_base = w_ref[:, list(local)]
        if column_scale is None:
            rms = np.sqrt(np.mean(w_base**2, axis=0))
            self.column_scale = 1.0 / rms
        else:
            self.column_scale = np.broadcast_to(
                np.asarray(column_scale, dtype=float), (len(self.columns),)
            ).copy()
        self.reference_rank = len(self.columns)

    @property
    def column_names(self) -> tuple[str, ...]:
        """Names of the base columns kept (standard parameter labels, e.g. ``"Ixx5"``)."""
        from ident.dynamics.parameters import parameter_names

        names = parameter_names(self.chain.n_bodies)
        return tuple(names[c] for c in self.columns)

    def _reference_states(
        self, n_samples: int, rng: np.random.Generator | int | None
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Random states of the moving joints within their limits; held joints held."""
        rng = np.random.default_rng(rng)
        limits = JointLimits.from_robot(self.robot)
        lower, upper = limits.finite_position_box()
        dq_max = np.where(np.isfinite(limits.dq_max), limits.dq_max, 1.0)
        ddq_max = np.where(np.isfinite(limits.ddq_max), limits.ddq_max, 10.0)
        nq = limits.nq
        moving = np.zeros(nq, dtype=bool)
        moving[list(self.family.moving_joints)] = True
        q = np.where(moving, rng.uniform(lower, upper, (n_samples, nq)), self.family.held_positions)
        dq = np.where(moving, rng.uniform(-dq_max, dq_max, (n_samples, nq)), 0.0)
        ddq = np.where(moving, rng.uniform(-ddq_max, ddq_max, (n_samples, nq)), 0.0)
        return q, dq, ddq

    def gram(self, q: FloatArray, dq: FloatArray, ddq: FloatArray) -> FloatArray:
        """Gram matrices of the (scaled, if ``scaled``) base observation matrices.

        Parameters
        ----------
        q, dq, ddq :
            Joint states, shape (n_particles, n_samples, nq).

        Returns
        -------
        :
            Shape (n_particles, n_base, n_base).
        """
        g = _gram_batch(self.chain, q, dq, ddq, self.rows, self.columns)
        if self.scaled:
            g = g * (np.outer(self.column_scale, self.column_scale) / (q.shape[1] * len(self.rows)))
        return g

    def _batch(self, x: npt.ArrayLike) -> tuple[TrajectoryBatch, ConstraintViolations]:
        """The family's trajectories and all their constraints (the safety terms included)."""
        x = check_design(x, len(self.family.variable_names))
        batch = self.family.trajectories(x)
        if self.safety is None:
            return batch, batch.violations
        from ident.excitation.safety import collision_violations, torque_violations

        extra = [
            collision_violations(self.safety, batch.q),
            torque_violations(self.safety, batch.q, batch.dq, batch.ddq),
        ]
        return batch, ConstraintViolations.concatenate(batch.violations, *extra)

    def _evaluate(
        self, x: npt.ArrayLike
    ) -> tuple[TrajectoryBatch, ConstraintViolations, tuple[FloatArray, ...], FloatArray]:
        batch, violations = self._batch(x)
        finite = np.all(
            np.isfinite(batch.q) & np.isfinite(batch.dq) & np.isfinite(batch.ddq), axis=(1, 2)
        )
        q, dq, ddq = batch.q, batch.dq, batch.ddq
        if not np.all(finite):  # keep the compiled kernel away from NaN
            bad = ~finite
            q, dq, ddq = q.copy(), dq.copy(), ddq.copy()
            q[bad] = self.family.held_positions
            dq[bad] = 0.0
            ddq[bad] = 0.0
        stats = criterion_from_gram(self.gram(q, dq, ddq), self.criterion)
        value = np.where(finite, stats[0], CRITERION_CAP)
        pen = penalty(violations, self.penalty_weight)
        pen = np.where(finite, pen, self.penalty_weight * 2.0)
        return batch, violations, (value, *stats[1:]), pen

    def __call__(self, x: npt.ArrayLike) -> FloatArray:
        """Fitness of each particle (lower is better), shape (n_particles,), always finite.

        Parameters
        ----------
        x :
            Designs, shape (n_particles, n_vars) (or (n_vars,) for one particle).
        """
        _, _, stats, pen = self._evaluate(x)
        return stats[0] + pen

    def details(self, x: npt.ArrayLike) -> list[ObjectiveDetails]:
        """Per-particle breakdown of the fitness (criterion, singular values, violations)."""
        batch, violations, (value, cond, smin, smax, logdet), pen = self._evaluate(x)
        feasible = violations.feasible()
        return [
            ObjectiveDetails(
                fitness=float(value[i] + pen[i]),
                criterion=float(value[i]),
                cond=float(cond[i]),
                sigma_min=float(smin[i]),
                sigma_max=float(smax[i]),
                logdet=float(logdet[i]),
                penalty=float(pen[i]),
                feasible=bool(feasible[i]),
                violations=violations.as_dict(i),
            )
            for i in range(batch.n_particles)
        ]

    def violation(self, x: npt.ArrayLike) -> FloatArray:
        """Total constraint violation of each particle (0 = compliant), shape (n_particles,).

        Only the trajectories and their constraints are computed (no regressor): this is the
        fitness of the paper's initial-elite search. The safety terms count when the objective
        has a safety model.
        """
        return self._batch(x)[1].total()
