"""What a run found: the typed results :func:`ident.run.pipeline.run_pipeline` returns.

Plain frozen dataclasses of arrays and numbers (SI, samples on axis 0); the report writer turns
them into files, nothing here computes.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.run.config import RunConfig

__all__ = [
    "BaseParameterSet",
    "EliteOutcome",
    "FrameBaseInfo",
    "OptimizerRun",
    "Progress",
    "ProgressCallback",
    "RunInterrupted",
    "RunResult",
    "StageInfo",
    "base_set_fields",
]

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Progress:
    """A progress report of :func:`run_pipeline`.

    Attributes
    ----------
    phase :
        ``"elites"`` (an iteration of the initial elite search), ``"elites_done"`` (the
        elites were found; ``payload`` holds them), ``"optimize"`` (an eMuPSO iteration),
        ``"run_done"`` (an eMuPSO run finished; ``payload`` is its :class:`OptimizerRun`),
        ``"identify"`` (an elite was measured and identified), ``"retry"`` (every elite was
        a little inside the safety margin: the optimizer runs again at a wider one; ``payload``
        says so in one sentence).
    step, total :
        Progress within the phase (for ``optimize``: iterations over all runs).
    run :
        0-based index of the eMuPSO run, or ``None``.
    best :
        Best value so far in the phase (violation for ``elites``, fitness otherwise).
    payload :
        Phase-specific data.
    """

    phase: str
    step: int
    total: int
    run: int | None = None
    best: float = float("nan")
    payload: Any = None


ProgressCallback = Callable[[Progress], Any]


@dataclass(frozen=True, eq=False)
class OptimizerRun:
    """One finished eMuPSO run.

    Attributes
    ----------
    index :
        0-based run index.
    x, fun :
        Best design and its fitness.
    history :
        Best fitness after each iteration, index 0 the initial swarm, shape (nit + 1,).
    mutation_iterations :
        Iterations whose population came from a mutation.
    archive_x, archive_fun :
        The run's elite archive, shapes (k, n_vars) and (k,).
    nit, nfev :
        Iterations and objective evaluations.
    message :
        Why the run ended.
    """

    index: int
    x: FloatArray
    fun: float
    history: FloatArray
    mutation_iterations: tuple[int, ...]
    archive_x: FloatArray
    archive_fun: FloatArray
    nit: int
    nfev: int
    message: str


@dataclass(frozen=True, eq=False)
class BaseParameterSet:
    """A stage's standard parameters split by a base-parameter reduction.

    Attributes
    ----------
    standard_names :
        Names of the stage's standard parameters, in the column order used.
    true_standard :
        Their true values (SI), shape (n_cols,).
    independent, dependent, unidentifiable :
        Names of the standard parameters in each class.
    base_names, base_expressions :
        Names of the base parameters (the independent standard parameter each starts from)
        and their readable expressions in the standard ones.
    true_base :
        True base parameters (projection of ``true_standard``), shape (n_base,).
    """

    standard_names: tuple[str, ...]
    true_standard: FloatArray
    independent: tuple[str, ...]
    dependent: tuple[str, ...]
    unidentifiable: tuple[str, ...]
    base_names: tuple[str, ...]
    base_expressions: tuple[str, ...]
    true_base: FloatArray

    @property
    def counts(self) -> tuple[int, int, int]:
        """(independent, in linear combination, unidentifiable)."""
        return len(self.independent), len(self.dependent), len(self.unidentifiable)


def base_set_fields(base: Any, names: tuple[str, ...], true_standard: FloatArray) -> dict[str, Any]:
    """The :class:`BaseParameterSet` fields of a ``BaseParameters`` reduction of ``names``."""
    return {
        "standard_names": names,
        "true_standard": true_standard,
        "independent": tuple(names[i] for i in base.independent),
        "dependent": tuple(names[i] for i in base.dependent),
        "unidentifiable": tuple(names[i] for i in base.unidentifiable),
        "base_names": tuple(base.base_names),
        "base_expressions": tuple(base.expressions()),
        "true_base": np.asarray(base.project(true_standard), dtype=float),
    }


@dataclass(frozen=True, eq=False)
class FrameBaseInfo(BaseParameterSet):
    """Base parameters of the stage in another parameterization (the paper's DH frames).

    Only for the comparison with the paper: the estimate uses :class:`StageInfo`'s body-frame
    base parameters. Columns are taken in the paper's eq. 14 order per body
    (``m, mcx, mcy, mcz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz``) and reduced by the paper's
    sequential rank test, so the kept names are those the paper's procedure would keep.

    Attributes
    ----------
    frames :
        ``"DH"``.
    method :
        Base-parameter method (``"sequential"``).

    The :class:`BaseParameterSet` fields hold the DH-frame names and true values.
    """

    frames: str
    method: str


@dataclass(frozen=True, eq=False)
class StageInfo(BaseParameterSet):
    """The stage's parameters: standard columns, base parameters, true values.

    Attributes
    ----------
    name :
        The stage's name (``whole``, ``payload``, ``wrist``, ``arm`` or a config's own).
    rows :
        Torque rows (joint indices, 0-based) of the stage.
    columns :
        Indices of the stage's standard parameters in the robot's parameter vector (the
        :class:`BaseParameterSet` fields hold their names and true values, body frames).
    alone :
        Per base parameter: True if it is a standard parameter identifiable alone.
    base_method :
        ``qr`` or ``sequential``.
    known_bodies_note :
        How bodies outside the stage were handled.
    base :
        The ``BaseParameters`` object (``base_columns(W)``, ``project(params)``).
    dh_frames :
        The same stage's base parameters about the paper's DH frames
        (:class:`FrameBaseInfo`), for robots built from a DH config; else ``None``.
    reference_share :
        Per base parameter, ``|true_i| ||W_i|| / ||W_b true||`` on the random states of the
        stage's motion (the robot at full capability): the share of the stage's torques a
        parameter explains, independent of the trajectory and unit-free, shape (n_base,).
        Parameters with a share of at least 1e-2 are the stage's *major* parameters.
    """

    name: str
    rows: tuple[int, ...]
    columns: tuple[int, ...]
    alone: tuple[bool, ...]
    base_method: str
    known_bodies_note: str
    base: Any = None
    dh_frames: FrameBaseInfo | None = None
    reference_share: FloatArray | None = None


@dataclass(frozen=True, eq=False)
class EliteOutcome:
    """A reported elite: its trajectory, measurements and estimates.

    Attributes
    ----------
    rank :
        1-based rank by fitness (1 = best = chosen).
    x :
        Design vector, shape (n_vars,).
    fitness :
        Objective value (eq. 15 + penalties).
    details :
        Objective details of this design (condition number, singular values, ...).
    t, q, dq, ddq :
        Commanded trajectory, shapes (n_samples,), (n_samples, nq) x 3.
    traced_points :
        Cartesian path of the traced point [m], shape (n_samples, 3), or None.
    tau :
        Measured (simulated, noisy) torques [N*m], shape (n_samples, nv); None when the
        simulation of the elite failed (``failures`` says why: nothing was measured).
    estimates :
        ``{method: Estimate}`` for the estimators that succeeded.
    failures :
        ``{method: message}`` for the estimators that could not run (rank deficiency, ...).
    base_column_norms :
        ``||W_b[:, i]||`` of the base observation matrix on the measured states, shape (n_base,).
    true_torque_norm :
        ``||W_b @ true_base||`` [N*m]: the norm of the torques the stage's base parameters
        explain.
    """

    rank: int
    x: FloatArray
    fitness: float
    details: dict[str, float]
    t: FloatArray
    q: FloatArray
    dq: FloatArray
    ddq: FloatArray
    traced_points: FloatArray | None
    tau: FloatArray | None
    estimates: dict[str, Any]
    failures: dict[str, str]
    base_column_norms: FloatArray | None = None
    true_torque_norm: float | None = None
    log: Any = None  # measurement.source mujoco: the LogOutcome (simulated log + identification)
    safety_check: Any = None  # the dense SafetyReport of one period (ident.excitation.check)


@dataclass(frozen=True, eq=False)
class RunResult:
    """Everything a run found; the report writer turns it into files.

    ``status`` is ``complete`` or ``incomplete`` (interrupted or failed; ``message`` says
    where, and only what finished is filled in).
    """

    config: RunConfig
    status: str
    message: str
    robot_name: str
    joint_names: tuple[str, ...]
    q_limits: FloatArray
    dq_limits: FloatArray
    ddq_limits: FloatArray
    urdf_text: str
    variable_names: tuple[str, ...]
    bounds: FloatArray
    traced_frame: str | None
    moving_joints: tuple[int, ...]
    stage: StageInfo | None = None
    initial_elites: FloatArray | None = None
    elite_search_message: str = ""
    runs: tuple[OptimizerRun, ...] = ()
    elites: tuple[EliteOutcome, ...] = ()
    warnings: tuple[str, ...] = field(default_factory=tuple)
    executable: Any = None  # the run.safety_check.ExecutablePlan (trajectory.csv), or None
    safety: dict[str, Any] | None = None  # {"ok": bool, "message": str} for the report

    @property
    def executed_rank(self) -> int | None:
        """Rank of the elite the report judges: the one ``trajectory.csv`` executes (the
        executable plan's), else elite 1 (then judged ``unsafe`` when the plan has none);
        None without elites."""
        if not self.elites:
            return None
        plan = self.executable
        rank = getattr(plan, "elite", None)
        return rank if isinstance(rank, int) and 1 <= rank <= len(self.elites) else 1


class RunInterrupted(Exception):
    """A run stopped early (Ctrl-C or an error); ``partial`` holds what had finished."""

    def __init__(self, partial: RunResult, cause: BaseException) -> None:
        super().__init__(partial.message)
        self.partial = partial
        self.cause = cause
