"""``ident run``: config -> optimized excitation -> simulated measurements -> estimate.

The paper's procedure (section 4.1) for one stage, as one pure function
:func:`run_pipeline` (no printing, no files; progress through a callback):

1. **Initial elites.** A constraint-compliance PSO swarm (``elites.n_particles``) minimizes
   the total constraint violation of the excitation family until ``elites.n_elites``
   trajectories satisfy every constraint (:func:`ident.optim.elites.find_feasible_elites`).
2. **eMuPSO runs.** ``emupso.n_runs`` independent runs; each swarm of
   ``emupso.n_particles`` is spawned from the elites by Gaussian mutation and minimizes the
   excitation objective (eq. 15 with constraint penalties) for ``emupso.maxiter``
   iterations, mutating after ``emupso.stagnation`` (G) stagnant iterations.
3. **Reported elites.** The archives of all runs and the best point of each run are pooled;
   the feasible ones (no constraint violated), without near-duplicates (largest
   per-variable distance below 1e-3 of the range), sorted by fitness (best first), the best
   ``emupso.n_report_elites`` are kept. Elite 1 (lowest fitness) is the *chosen* trajectory.
4. **Measurements.** Along each reported elite, joint torques are simulated with Pinocchio's
   RNEA on the true parameters of the robot, with the configured noise
   (:mod:`ident.identify.measurements`).
5. **Estimate.** The stage's observation matrix on the *measured* states, reduced to the
   stage's base parameters (computed once, on random states of the stage, by the configured
   method), is solved by OLS and/or WLS (:func:`ident.identify.estimate.least_squares`).
   Bodies outside the stage are known: their contribution to the stage's torque rows is
   computed from their true parameters and subtracted (for the wrist stage it is zero, the
   wrist torques do not depend on the arm bodies; for the arm stage it is the wrist bodies').

Random streams: one ``numpy.random.SeedSequence(config.seed)`` split into independent child
streams for the elite search, each eMuPSO run, and each elite's measurement noise, so the
result depends only on the config and the seed.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.errors import IdentError, NotIdentifiable, TrajectoryError
from ident.run.config import RunConfig
from ident.run.setup import RunSetup, prepare_run

__all__ = [
    "EliteOutcome",
    "FrameBaseInfo",
    "OptimizerRun",
    "Progress",
    "RunInterrupted",
    "RunResult",
    "StageInfo",
    "identify_elite",
    "run_pipeline",
]

FloatArray = npt.NDArray[np.float64]

_DISTINCT_TOL = 1e-3
_N_STRUCTURE_SAMPLES = 500


@dataclass(frozen=True)
class Progress:
    """A progress report of :func:`run_pipeline`.

    Attributes
    ----------
    phase :
        ``"elites"`` (an iteration of the initial elite search), ``"elites_done"`` (the
        elites were found; ``payload`` holds them), ``"optimize"`` (an eMuPSO iteration),
        ``"run_done"`` (an eMuPSO run finished; ``payload`` is its :class:`OptimizerRun`),
        ``"identify"`` (an elite was measured and identified).
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


def _base_set_fields(
    base: Any, names: tuple[str, ...], true_standard: FloatArray
) -> dict[str, Any]:
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
        ``wrist`` or ``arm``.
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
        Measured (simulated, noisy) torques [N*m], shape (n_samples, nv).
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
    tau: FloatArray
    estimates: dict[str, Any]
    failures: dict[str, str]
    base_column_norms: FloatArray | None = None
    true_torque_norm: float | None = None


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


class RunInterrupted(Exception):
    """A run stopped early (Ctrl-C or an error); ``partial`` holds what had finished."""

    def __init__(self, partial: RunResult, cause: BaseException) -> None:
        super().__init__(partial.message)
        self.partial = partial
        self.cause = cause


# --------------------------------------------------------------------------------------
# Building blocks (heavy modules imported lazily: `import ident.run.pipeline` stays cheap)


def stage_matrix(
    robot: Any,
    rows: tuple[int, ...],
    columns: tuple[int, ...],
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Stage observation matrix and the known torque contribution of the other bodies.

    Returns
    -------
    W :
        Shape (n_samples * n_rows, n_cols), sample-major.
    known :
        Torques of the parameters outside the stage on the stage's rows, with their true
        values [N*m], shape (n_samples, n_rows).
    """
    Y = stage_regressor(robot, rows, q, dq, ddq)
    params = np.asarray(robot.parameters(), dtype=float)
    other = np.setdiff1d(np.arange(Y.shape[2]), np.asarray(columns, dtype=int))
    known = Y[:, :, other] @ params[other]
    W = Y[:, :, list(columns)].reshape(-1, len(columns))
    return W, known


def stage_regressor(
    robot: Any, rows: tuple[int, ...], q: FloatArray, dq: FloatArray, ddq: FloatArray
) -> FloatArray:
    """Rows ``rows`` of the joint-torque regressor, shape (n_samples, n_rows, n_params)."""
    return np.asarray(robot.regressor(q, dq, ddq))[:, list(rows), :]


def dh_frame_base(
    robot: Any,
    rows: tuple[int, ...],
    columns: tuple[int, ...],
    q: FloatArray,
    dq: FloatArray,
    ddq: FloatArray,
) -> FrameBaseInfo | None:
    """Base parameters of a stage about the paper's DH frames (``None`` without a DH table).

    The regressor in the DH parameterization is ``Y @ robot.dh_to_model_parameters()``
    (docs/paper-notes.md, "Eq. 14: parameter order and frames"); its stage columns are put in
    the paper's eq. 14 order per body and reduced by the paper's sequential rank test.
    """
    if getattr(robot, "dh", None) is None:
        return None
    from ident.dynamics.base_parameters import compute_base_parameters
    from ident.robot.inertia import PAPER_ORDER, PINOCCHIO_ORDER

    M = np.asarray(robot.dh_to_model_parameters(), dtype=float)
    Y = stage_regressor(robot, rows, q, dq, ddq) @ M
    names_all = tuple(robot.parameter_names())
    # eq. 14 order within each body (the stage's columns are whole bodies, 10 each)
    to_paper = [PINOCCHIO_ORDER.index(label) for label in PAPER_ORDER]
    order = [c - c % 10 + to_paper[c % 10] for c in columns]
    if sorted(order) != sorted(columns):
        raise IdentError("the stage's parameter columns are not whole bodies of 10 parameters")
    W = Y[:, :, order].reshape(-1, len(order))
    names = tuple(names_all[c] for c in order)
    base = compute_base_parameters(W, names, method="sequential")
    true_standard = np.asarray(robot.parameters_dh(), dtype=float)[order]
    return FrameBaseInfo(
        frames="DH", method="sequential", **_base_set_fields(base, names, true_standard)
    )


def build_stage_info(robot: Any, stage: Any, family: Any, base_method: str, rng: Any) -> StageInfo:
    """Base parameters of the stage, from random states of the stage's motion.

    The states span the moving joints' position, velocity and acceleration limits, the held
    joints sit where the family holds them; the classification is structural (it holds for
    almost every motion of the stage), and a trajectory that does not excite a base
    parameter shows up as a rank-deficient estimate, reported per elite.
    """
    from ident.dynamics.base_parameters import compute_base_parameters

    names_all = tuple(robot.parameter_names())
    params = np.asarray(robot.parameters(), dtype=float)
    rows = tuple(int(r) for r in stage.torque_rows)
    columns = tuple(int(c) for c in stage.columns)
    q, dq, ddq = _structure_states(robot, family, rng)
    W, _ = stage_matrix(robot, rows, columns, q, dq, ddq)
    names = tuple(names_all[c] for c in columns)
    base = compute_base_parameters(W, names, method=base_method)
    fields = _base_set_fields(base, names, params[list(columns)])
    true_base, base_names = fields["true_base"], fields["base_names"]
    Wb = np.asarray(base.base_columns(W), dtype=float)
    total = float(np.linalg.norm(Wb @ true_base))
    reference_share = np.abs(true_base) * np.linalg.norm(Wb, axis=0) / (total if total > 0 else 1.0)
    # ident.dynamics.base_parameters suffixes "R" to a base parameter with others combined in
    alone = tuple(b == names[i] for b, i in zip(base_names, base.independent, strict=True))
    others = np.setdiff1d(np.arange(params.shape[0]), np.asarray(columns))
    known_note = (
        "all bodies are unknown in this stage"
        if others.size == 0
        else "the bodies outside the stage are known (identified in the other stage; here "
        "their true parameters): their torque contribution on the stage's rows is computed "
        "and subtracted before the estimate"
    )
    return StageInfo(
        name=str(stage.name),
        rows=rows,
        columns=columns,
        alone=alone,
        base_method=base_method,
        known_bodies_note=known_note,
        base=base,
        dh_frames=dh_frame_base(robot, rows, columns, q, dq, ddq),
        reference_share=reference_share,
        **fields,
    )


def _structure_states(
    robot: Any, family: Any, rng: Any
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Random states of the stage's motion: moving joints within their limits, others held."""
    from ident.excitation import JointLimits

    gen = np.random.default_rng(rng)
    limits = JointLimits.from_robot(robot)
    lower, upper = limits.finite_position_box()
    dq_max = np.where(np.isfinite(limits.dq_max), limits.dq_max, 1.0)
    ddq_max = np.where(np.isfinite(limits.ddq_max), limits.ddq_max, 10.0)
    n, nq = _N_STRUCTURE_SAMPLES, limits.nq
    moving = np.zeros(nq, dtype=bool)
    moving[list(family.moving_joints)] = True
    held = np.asarray(family.held_positions, dtype=float)
    q = np.where(moving, gen.uniform(lower, upper, (n, nq)), held)
    dq = np.where(moving, gen.uniform(-dq_max, dq_max, (n, nq)), 0.0)
    ddq = np.where(moving, gen.uniform(-ddq_max, ddq_max, (n, nq)), 0.0)
    return q, dq, ddq


_DETAIL_KEYS = ("fitness", "criterion", "cond", "sigma_min", "sigma_max", "logdet", "penalty")


def _details(objective: Any, x: FloatArray) -> list[dict[str, float]]:
    """Per-design objective details as plain floats."""
    return [
        {key: float(getattr(d, key)) for key in _DETAIL_KEYS if hasattr(d, key)}
        for d in objective.details(np.atleast_2d(x))
    ]


# --------------------------------------------------------------------------------------


def run_pipeline(
    config: RunConfig | RunSetup, *, progress: ProgressCallback | None = None
) -> RunResult:
    """Run the whole procedure of the config (see the module docstring).

    Parameters
    ----------
    config :
        A checked :class:`~ident.run.setup.RunSetup`, or a run config (its paths resolved, see
        :func:`ident.run.config.load_run_config`), which is then prepared here.
    progress :
        Called with a :class:`Progress` after every elite-search iteration, every eMuPSO
        iteration, every finished run and every identified elite. An exception raised in it
        (``KeyboardInterrupt`` included) stops the run like Ctrl-C does.

    Returns
    -------
    :
        The :class:`RunResult` (``status == "complete"``).

    Raises
    ------
    RunInterrupted
        On Ctrl-C or an error after the optimization started; ``partial`` holds the
        finished part (status ``incomplete``) and ``cause`` the original exception.
    IdentError
        For invalid input found before anything ran (robot, stage, family options).
    """
    from ident.excitation import ExcitationObjective
    from ident.optim import minimize
    from ident.optim.elites import find_feasible_elites, spawn_from_elites

    notify = progress or (lambda _p: None)
    setup = config if isinstance(config, RunSetup) else prepare_run(config)
    config, robot, stage, family = setup.config, setup.robot, setup.stage, setup.family
    streams = np.random.SeedSequence(config.seed).spawn(4)
    run_streams = streams[1].spawn(config.emupso.n_runs)
    with _small_blas():
        stage_info = build_stage_info(
            robot, stage, family, config.estimation.base_method, np.random.default_rng(streams[3])
        )
    # the objective scores the same base columns the estimate uses
    objective = ExcitationObjective(
        robot,
        stage,
        family,
        criterion=config.excitation.criterion,
        base_columns=[stage_info.columns[i] for i in stage_info.base.independent],
    )
    bounds = np.asarray(family.bounds, dtype=float)

    state: dict[str, Any] = {"runs": [], "elites": None, "elite_message": "", "outcomes": []}
    base = RunResult(
        config=config,
        status="incomplete",
        message="",
        robot_name=str(robot.name),
        joint_names=tuple(robot.joint_names),
        q_limits=np.column_stack([robot.q_lower, robot.q_upper]).astype(float),
        dq_limits=np.asarray(robot.dq_max, dtype=float),
        ddq_limits=np.asarray(
            getattr(robot, "ddq_max", np.full(len(robot.joint_names), np.inf)), dtype=float
        ),
        urdf_text=str(robot.urdf_text),
        variable_names=tuple(family.variable_names),
        bounds=bounds,
        traced_frame=getattr(family, "traced_frame", None),
        moving_joints=tuple(int(j) for j in family.moving_joints),
        stage=stage_info,
    )

    def partial(message: str) -> RunResult:
        return _replace(
            base,
            status="incomplete",
            message=message,
            initial_elites=state["elites"],
            elite_search_message=state["elite_message"],
            runs=tuple(state["runs"]),
            elites=tuple(state["outcomes"]),
        )

    phase = "initial elite search"
    try:
        # 1. initial elites
        cfg_e = config.elites
        search = find_feasible_elites(
            objective.violation,
            bounds,
            n_particles=cfg_e.n_particles,
            n_elites=cfg_e.n_elites,
            rng=np.random.default_rng(streams[0]),
            maxiter=cfg_e.maxiter,
            callback=lambda r: notify(Progress("elites", r.nit, cfg_e.maxiter, best=r.fun)),
        )
        state["elite_message"] = search.message
        if not search.success:
            raise TrajectoryError(_elite_failure(search, family, objective, bounds))
        state["elites"] = np.asarray(search.elites)
        notify(Progress("elites_done", search.nit, cfg_e.maxiter, best=0.0, payload=search.elites))

        # 2. eMuPSO runs
        cfg_o = config.emupso
        total = cfg_o.n_runs * cfg_o.maxiter
        for k in range(cfg_o.n_runs):
            phase = f"eMuPSO run {k + 1} of {cfg_o.n_runs}"
            gen = np.random.default_rng(run_streams[k])
            x0 = spawn_from_elites(
                search.elites, cfg_o.n_particles, bounds, cfg_o.sigma_fraction, gen
            )

            def on_iteration(r: Any, k: int = k) -> None:
                notify(Progress("optimize", k * cfg_o.maxiter + r.nit, total, run=k, best=r.fun))

            options = {"stall_threshold": cfg_o.stagnation, **cfg_o.options}
            res = minimize(
                objective,
                bounds,
                method="emupso",
                rng=gen,
                maxiter=cfg_o.maxiter,
                popsize=cfg_o.n_particles,
                callback=on_iteration,
                vectorized=True,
                x0=x0,
                **options,
            )
            run = _optimizer_run(k, res)
            state["runs"].append(run)
            notify(Progress("run_done", k + 1, cfg_o.n_runs, run=k, best=run.fun, payload=run))

        # 3. reported elites
        phase = "selection of the elites"
        chosen_x, chosen_f = _select_elites(state["runs"], objective, bounds, cfg_o.n_report_elites)
        if chosen_x.shape[0] == 0:
            raise TrajectoryError(
                "no optimized trajectory satisfies the constraints (every archive member "
                "violates a joint limit, continuity or reachability); raise the penalty, "
                "widen the limits or narrow the excitation bounds."
            )

        # 4-5. measurements and estimates
        details = _details(objective, chosen_x)
        meas_streams = streams[2].spawn(chosen_x.shape[0])
        for i in range(chosen_x.shape[0]):
            phase = f"identification of elite {i + 1}"
            with _small_blas():
                outcome = identify_elite(
                    config,
                    robot,
                    family,
                    stage_info,
                    i,
                    chosen_x[i],
                    float(chosen_f[i]),
                    details[i],
                    meas_streams[i],
                )
            state["outcomes"].append(outcome)
            notify(Progress("identify", i + 1, chosen_x.shape[0], best=outcome.fitness))
    except KeyboardInterrupt as e:
        raise RunInterrupted(partial(f"interrupted (Ctrl-C) during the {phase}"), e) from e
    except IdentError as e:
        raise RunInterrupted(partial(f"stopped during the {phase}: {e}"), e) from e
    except Exception as e:  # a crash: keep what finished, then let it surface
        raise RunInterrupted(
            partial(f"crashed during the {phase}: {type(e).__name__}: {e}"), e
        ) from e

    warnings = []
    if all(not o.estimates for o in state["outcomes"]):
        warnings.append(
            "no elite trajectory identifies the stage's base parameters (see the failures "
            "per elite); the estimates are missing, not zero."
        )
    result = partial("")
    return _replace(result, status="complete", message="run complete", warnings=tuple(warnings))


def _small_blas() -> Any:
    """Single-threaded BLAS for the small least-squares problems of the estimate.

    OpenBLAS threads a (1500 x 17) WLS solve; on a loaded 2-core machine that made it 15-50
    times slower than one thread (measured 41-160 ms vs 1.3-3.4 ms, docs/run.md). The
    objective's Gram-matrix kernel (numba) is not BLAS and is left alone.
    """
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


def _replace(result: RunResult, **changes: Any) -> RunResult:
    return dataclasses.replace(result, **changes)


def _optimizer_run(k: int, res: Any) -> OptimizerRun:
    archive = res.archive
    if archive is not None and len(archive):
        ax, af = np.asarray(archive.x, dtype=float), np.asarray(archive.fun, dtype=float)
    else:
        ax, af = np.asarray(res.x, dtype=float)[None, :], np.array([float(res.fun)])
    mut = getattr(res.history, "mutation_iterations", None)
    return OptimizerRun(
        index=k,
        x=np.asarray(res.x, dtype=float),
        fun=float(res.fun),
        history=np.asarray(res.history.best_fun, dtype=float),
        mutation_iterations=tuple(int(i) for i in (mut if mut is not None else ())),
        archive_x=ax,
        archive_fun=af,
        nit=int(res.nit),
        nfev=int(res.nfev),
        message=str(res.message),
    )


def _select_elites(
    runs: list[OptimizerRun], objective: Any, bounds: FloatArray, n: int
) -> tuple[FloatArray, FloatArray]:
    """Best distinct feasible points of all archives, best first (see module docstring)."""
    xs = np.vstack([np.vstack([r.archive_x, r.x[None, :]]) for r in runs])
    fs = np.concatenate([np.append(r.archive_fun, r.fun) for r in runs])
    order = np.argsort(fs, kind="stable")
    xs, fs = xs[order], fs[order]
    feasible = np.asarray(objective.violation(xs), dtype=float) <= 0.0
    span = bounds[:, 1] - bounds[:, 0]
    kept: list[int] = []
    for i in np.flatnonzero(feasible & np.isfinite(fs)):
        if all(np.max(np.abs(xs[i] - xs[j]) / span) > _DISTINCT_TOL for j in kept):
            kept.append(int(i))
        if len(kept) == n:
            break
    return xs[kept], fs[kept]


def _elite_failure(search: Any, family: Any, objective: Any, bounds: FloatArray) -> str:
    """A message naming the constraints that no candidate could meet."""
    worst = ""
    try:
        probe = np.random.default_rng(0).uniform(bounds[:, 0], bounds[:, 1], (50, bounds.shape[0]))
        batch = family.trajectories(probe)
        values = np.asarray(batch.violations.values)
        names = list(batch.violations.names)
        share = (values > 0).mean(axis=0)
        # an unreachable path causes the other violations: name it first
        root = np.array([n.startswith("reachability") for n in names])
        order = np.lexsort((-values.mean(axis=0), -share, ~root))
        top = [j for j in order if share[j] > 0][:5]
        worst = "; constraints violated most often by random designs: " + ", ".join(
            f"{names[j]} ({100 * share[j]:.0f} %)" for j in top
        )
    except Exception:  # the message must not fail: keep what the search said
        pass
    return (
        f"initial elite search: {search.message}{worst}. No trajectory in the excitation "
        "bounds meets the constraints: check that the Cartesian circle is reachable, "
        "narrow excitation.bounds, or relax the joint limits of the robot config."
    )


def identify_elite(
    config: RunConfig,
    robot: Any,
    family: Any,
    stage: StageInfo,
    index: int,
    x: FloatArray,
    fitness: float,
    details: dict[str, float],
    seed: Any,
) -> EliteOutcome:
    """Measure (simulate) one elite trajectory and estimate the stage's base parameters.

    Estimator failures (rank-deficient base matrix on this trajectory, ...) are recorded in
    ``failures`` with their message; they do not raise.
    """
    from ident.identify.estimate import least_squares
    from ident.identify.measurements import NoiseModel, simulate_measurements

    batch = family.trajectories(x[None, :])
    t = np.asarray(batch.t, dtype=float)
    q, dq, ddq = (np.asarray(a[0], dtype=float) for a in (batch.q, batch.dq, batch.ddq))
    traced = None if batch.traced_points is None else np.asarray(batch.traced_points[0])
    m = config.measurement
    std = m.torque_noise_std
    noise = NoiseModel(
        torque_std=tuple(std) if isinstance(std, list) else float(std),
        encoder_counts_per_rev=m.encoder_counts_per_rev,
        filter_cutoff_hz=m.filter_cutoff_hz,
    )
    meas = simulate_measurements(robot.model, t, q, dq, ddq, noise, rng=np.random.default_rng(seed))
    W, known = stage_matrix(robot, stage.rows, stage.columns, meas.q, meas.dq, meas.ddq)
    y = (meas.tau[:, list(stage.rows)] - known).reshape(-1)
    estimates: dict[str, Any] = {}
    failures: dict[str, str] = {}
    Wb = np.asarray(stage.base.base_columns(W), dtype=float)
    for method in config.estimation.methods:
        try:
            est = least_squares(
                Wb, y, stage.base_names, method=method, rows_per_sample=len(stage.rows)
            )
        except NotIdentifiable as e:
            failures[method] = f"not identifiable on this trajectory: {e}"
            continue
        except IdentError as e:
            failures[method] = str(e)
            continue
        if not est.success:
            failures[method] = est.message
            continue
        estimates[method] = est
    return EliteOutcome(
        rank=index + 1,
        x=x,
        fitness=fitness,
        details=details,
        t=t,
        q=q,
        dq=dq,
        ddq=ddq,
        traced_points=traced,
        tau=np.asarray(meas.tau),
        estimates=estimates,
        failures=failures,
        base_column_norms=np.linalg.norm(Wb, axis=0),
        true_torque_norm=float(np.linalg.norm(Wb @ stage.true_base)),
    )
