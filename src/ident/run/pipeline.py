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
   (:mod:`ident.measure.ideal`).
5. **Estimate.** The measurements go through the identification core
   (:func:`ident.identify.pipeline.core.identify_measurements`, as a log does): the stage's rows on
   the *measured* states, reduced to the stage's base parameters (computed once, on random states of
   the stage, by the configured method), estimated by the registry's estimators of
   ``estimation.methods`` (:mod:`ident.run.elite_identification`). Bodies outside the stage are
   known: their contribution to the torques is computed from their true parameters and subtracted
   (for the wrist stage it is zero on the wrist rows, the wrist torques do not depend on the arm
   bodies; for the arm stage it is the wrist bodies'). With ``measurement.source: mujoco`` the
   simulator writes a log that is read and identified like a measured one
   (:mod:`ident.run.log_measurement`).

Random streams: one ``numpy.random.SeedSequence(config.seed)`` split into independent child
streams for the elite search, each eMuPSO run, and each elite's measurement noise, so the
result depends only on the config and the seed.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import numpy.typing as npt

from ident.blas import one_blas_thread
from ident.errors import IdentError, TrajectoryError
from ident.excitation.family import feasibility_advice
from ident.optim import minimize
from ident.optim.elites import find_feasible_elites, spawn_from_elites
from ident.run.config import RunConfig
from ident.run.elite_identification import identify_elite
from ident.run.examples import unsafe_run_advice
from ident.run.log_measurement import identify_elite_log, log_stage_info
from ident.run.problem import excitation_problem
from ident.run.results import (
    EliteOutcome,
    FrameBaseInfo,
    OptimizerRun,
    Progress,
    ProgressCallback,
    RunInterrupted,
    RunResult,
    StageInfo,
)
from ident.run.safety_check import check_elites, plan_executable, retry_margin
from ident.run.setup import RunSetup, prepare_run
from ident.run.stage_info import build_stage_info

__all__ = [  # the run's result types are re-exported: they are what run_pipeline returns
    "EliteOutcome",
    "FeasibleStart",
    "FrameBaseInfo",
    "OptimizerRun",
    "Progress",
    "RunInterrupted",
    "RunResult",
    "StageInfo",
    "build_stage_info",
    "feasible_start",
    "identify_elite",
    "run_pipeline",
]

FloatArray = npt.NDArray[np.float64]

_DISTINCT_TOL = 1e-3


_DETAIL_KEYS = ("fitness", "criterion", "cond", "sigma_min", "sigma_max", "logdet", "penalty")


def _details(objective: Any, x: FloatArray) -> list[dict[str, float]]:
    """Per-design objective details as plain floats."""
    return [
        {key: float(getattr(d, key)) for key in _DETAIL_KEYS if hasattr(d, key)}
        for d in objective.details(np.atleast_2d(x))
    ]


# --------------------------------------------------------------------------------------


@dataclasses.dataclass
class _State:
    """What a run has finished so far (kept when it stops), and the phase it is in."""

    phase: str = "initial elite search"
    runs: list[OptimizerRun] = dataclasses.field(default_factory=list)
    elites: FloatArray | None = None
    elite_message: str = ""
    outcomes: list[EliteOutcome] = dataclasses.field(default_factory=list)
    safety: list[Any] = dataclasses.field(default_factory=list)

    def partial(self, base: RunResult, message: str) -> RunResult:
        return _replace(
            base,
            status="incomplete",
            message=message,
            initial_elites=self.elites,
            elite_search_message=self.elite_message,
            runs=tuple(self.runs),
            elites=tuple(self.outcomes),
        )


def run_pipeline(
    config: RunConfig | RunSetup | FeasibleStart, *, progress: ProgressCallback | None = None
) -> RunResult:
    """Run the whole procedure of the config (see the module docstring).

    Parameters
    ----------
    config :
        A checked :class:`~ident.run.setup.RunSetup`, or a run config (its paths resolved, see
        :func:`ident.run.config.load_run_config`), which is then prepared here, or a
        :class:`FeasibleStart` (stage 1 done, see :func:`feasible_start`).
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
    notify = progress or (lambda _p: None)
    start = config if isinstance(config, FeasibleStart) else None
    setup = _setup_of(config)
    config = setup.config
    streams = np.random.SeedSequence(config.seed).spawn(4)
    problem = (
        start.problem
        if start is not None
        else excitation_problem(setup, np.random.default_rng(streams[3]))
    )
    stage_info, measure = _measurement_of(setup, problem)
    base = _base_result(setup, problem.bounds, stage_info)
    state = _State()
    try:
        plan = _run_stages(setup, start, problem, stage_info, measure, streams, state, notify)
    except (KeyboardInterrupt, Exception) as e:  # a crash too: keep what finished
        raise _interrupted(state, base, e) from e
    return _replace(
        state.partial(base, ""),
        status="complete",
        message="run complete",
        warnings=_run_warnings(config, state, plan),
        executable=plan,
        safety=_safety_entry(plan, state.safety),
    )


def _interrupted(state: _State, base: RunResult, cause: BaseException) -> RunInterrupted:
    """The :class:`RunInterrupted` of a run stopped by ``cause`` (Ctrl-C, an input error or a
    crash) during ``state.phase``: the finished part, marked incomplete with the reason."""
    if isinstance(cause, KeyboardInterrupt):
        message = f"interrupted (Ctrl-C) during the {state.phase}"
    elif isinstance(cause, IdentError):
        message = f"stopped during the {state.phase}: {cause}"
    else:  # a crash: keep what finished, then let it surface
        message = f"crashed during the {state.phase}: {type(cause).__name__}: {cause}"
    return RunInterrupted(state.partial(base, message), cause)


def _run_stages(
    setup: RunSetup,
    start: FeasibleStart | None,
    problem: Any,
    stage_info: StageInfo,
    measure: Any,
    streams: list[np.random.SeedSequence],
    state: _State,
    notify: ProgressCallback,
) -> Any:
    """The stages of a run after its set-up, each recording its results in ``state``: the
    initial elites (``start``'s when given), the optimizer runs, the chosen designs (optimized
    again with a wider margin when every elite is a little inside the margin between the
    checked samples), the measured and identified elites; returns the executable plan of the
    chosen design."""
    if start is None:
        _search_elites(setup, problem, streams[0], state, notify)
    else:
        state.elites, state.elite_message = start.elites, start.elite_message
    _optimize(setup, problem, streams[1], state, notify)
    chosen_x, chosen_f = _choose(setup, problem, state)
    problem, chosen_x, chosen_f, retry_note = _retry_at_wider_margin(
        setup, problem, streams[1], state, notify, chosen_x, chosen_f
    )
    _measure(setup, problem, stage_info, measure, chosen_x, chosen_f, streams[2], state, notify)
    state.phase = "executable trajectory"
    plan = plan_executable(
        setup.config, setup.robot, setup.family, setup.safety, chosen_x, state.safety
    )
    if retry_note:
        plan = dataclasses.replace(plan, message=retry_note + plan.message)
    return plan


def _safety_entry(plan: Any, reports: list[Any]) -> dict[str, Any]:
    """result.json's ``safety``: ``ok`` (the trajectory passed every check that ran), the
    checks that could not run (an unknown limit: ``"torque not checked on j1: ..."``) and the
    one-line message (which counts them too)."""
    report = plan.report if plan.report is not None else (reports[0] if reports else None)
    not_run = list(report.checks_not_run()) if report is not None else []
    return {"ok": plan.usable, "checks_not_run": not_run, "message": plan.message}


def _measurement_of(setup: RunSetup, problem: Any) -> tuple[StageInfo, Any]:
    """The stage's facts and the function that measures and identifies an elite: simulated
    states (ideal source) or a simulated log identified as a measured one (MuJoCo)."""
    if setup.config.measurement.source == "mujoco":
        with one_blas_thread():
            stage_info, _ = log_stage_info(setup.config, setup.robot)
        return stage_info, identify_elite_log
    return problem.stage_info, identify_elite


def _setup_of(config: RunConfig | RunSetup | FeasibleStart) -> RunSetup:
    """The checked setup of what :func:`run_pipeline` was given."""
    if isinstance(config, FeasibleStart):
        return config.setup
    if isinstance(config, RunSetup):
        return config
    return prepare_run(config)


def _retry_at_wider_margin(
    setup: RunSetup,
    problem: Any,
    stream: Any,
    state: _State,
    notify: ProgressCallback,
    chosen_x: FloatArray,
    chosen_f: FloatArray,
) -> tuple[Any, FloatArray, FloatArray, str]:
    """When every elite is a little inside the safety margin between the checked samples,
    optimize again with a wider margin in the optimizer (the certificate's stays).

    Returns the problem, the chosen designs and fitnesses, and a note for the safety message
    (empty when no retry ran). When nothing is feasible at the wider margin, the first result.
    """
    margin = None if setup.safety is None else retry_margin(state.safety, setup.safety.clearance_m)
    if margin is None or setup.safety is None:
        return problem, chosen_x, chosen_f, ""
    kept = 1e3 * setup.safety.clearance_m
    note = (
        f"no elite kept the {kept:g} mm margin between the checked samples; optimized again "
        f"with the optimizer's margin at {1e3 * margin:.3g} mm (the certificate's stays "
        f"{kept:g} mm). "
    )
    notify(Progress("retry", 0, 1, payload=note.strip()))
    first = (chosen_x, chosen_f, state.safety)
    tighter = _tighter_problem(problem, setup.safety.with_optimizer_margin(margin))
    _optimize(setup, tighter, stream, state, notify)  # new child streams
    try:
        chosen_x, chosen_f = _choose(setup, tighter, state)
    except TrajectoryError:  # nothing feasible at the wider margin: the first result
        chosen_x, chosen_f, state.safety = first
        return problem, chosen_x, chosen_f, note + "No optimized trajectory kept it. "
    return tighter, chosen_x, chosen_f, note


def _run_warnings(config: RunConfig, state: _State, plan: Any) -> tuple[str, ...]:
    """The run's own warnings: no elite identified, or no trajectory safe to execute."""
    warnings = []
    if all(not o.estimates for o in state.outcomes):
        warnings.append(
            "no elite trajectory identifies the stage's base parameters (see the failures "
            "per elite); the estimates are missing, not zero."
        )
    if not plan.usable:  # never reported as usable: the robot must not run it
        warnings.append(plan.message + unsafe_run_advice(config.safety is not None))
    return tuple(warnings)


def _tighter_problem(problem: Any, safety: Any) -> Any:
    """The same problem whose objective's safety terms use ``safety`` (a wider margin)."""
    import copy

    objective = copy.copy(problem.objective)
    objective.safety = safety
    return dataclasses.replace(problem, objective=objective)


@dataclasses.dataclass(frozen=True)
class FeasibleStart:
    """A run's first stage, done: its excitation problem and the initial feasible elites.

    ``ident run`` computes it before it creates the run folder, so that an excitation box
    holding no design that meets the constraints is an input error (one ``error:`` line naming
    the setting), not a run folder that stops. :func:`run_pipeline` continues from it with the
    same random streams, so the result equals that of ``run_pipeline(setup)``.
    """

    setup: RunSetup
    problem: Any
    elites: FloatArray  # (n_elites, n_variables) feasible designs
    elite_message: str


def feasible_start(setup: RunSetup, *, progress: ProgressCallback | None = None) -> FeasibleStart:
    """Stage 1 of :func:`run_pipeline`: the excitation problem and the initial feasible elites.

    Raises
    ------
    TrajectoryError
        When the elite search finds no design of the excitation bounds that meets every
        constraint; the message names the constraints violated most often and, where the
        family knows it, the setting and value that make the box infeasible.
    """
    streams = np.random.SeedSequence(setup.config.seed).spawn(4)
    problem = excitation_problem(setup, np.random.default_rng(streams[3]))
    state = _State()
    _search_elites(setup, problem, streams[0], state, progress or (lambda _p: None))
    assert state.elites is not None
    return FeasibleStart(setup, problem, state.elites, state.elite_message)


def _base_result(setup: RunSetup, bounds: FloatArray, stage_info: StageInfo) -> RunResult:
    """The run's fixed facts (robot, design variables, stage), before anything ran."""
    config, robot, family = setup.config, setup.robot, setup.family
    return RunResult(
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


def _search_elites(
    setup: RunSetup, problem: Any, stream: Any, state: _State, notify: ProgressCallback
) -> None:
    """1. The initial feasible elites (``state.elites``)."""
    state.phase = "initial elite search"
    cfg_e = setup.config.elites
    search = find_feasible_elites(
        problem.objective.violation,
        problem.bounds,
        n_particles=cfg_e.n_particles,
        n_elites=cfg_e.n_elites,
        rng=np.random.default_rng(stream),
        maxiter=cfg_e.maxiter,
        callback=lambda r: notify(Progress("elites", r.nit, cfg_e.maxiter, best=r.fun)),
    )
    state.elite_message = search.message
    if not search.success:
        raise TrajectoryError(
            _elite_failure(search, setup.family, problem.objective, problem.bounds)
        )
    state.elites = np.asarray(search.elites)
    notify(Progress("elites_done", search.nit, cfg_e.maxiter, best=0.0, payload=search.elites))


def _optimize(
    setup: RunSetup, problem: Any, stream: Any, state: _State, notify: ProgressCallback
) -> None:
    """2. The optimizer runs from the elites (``state.runs``)."""
    config = setup.config
    cfg_o = config.emupso
    run_streams = stream.spawn(cfg_o.n_runs)
    total = cfg_o.n_runs * cfg_o.maxiter
    label = "eMuPSO" if config.optimizer == "emupso" else config.optimizer
    for k in range(cfg_o.n_runs):
        state.phase = f"{label} run {k + 1} of {cfg_o.n_runs}"
        gen = np.random.default_rng(run_streams[k])
        x0 = spawn_from_elites(
            state.elites, cfg_o.n_particles, problem.bounds, cfg_o.sigma_fraction, gen
        )

        def on_iteration(r: Any, k: int = k) -> None:
            notify(Progress("optimize", k * cfg_o.maxiter + r.nit, total, run=k, best=r.fun))

        if config.optimizer == "emupso":
            options = {"stall_threshold": cfg_o.stagnation, **cfg_o.options}
        else:
            options = dict(config.optimizer_options)
        res = minimize(
            problem.objective,
            problem.bounds,
            method=config.optimizer,
            rng=gen,
            maxiter=cfg_o.maxiter,
            popsize=cfg_o.n_particles,
            callback=on_iteration,
            vectorized=True,
            x0=x0,
            **options,
        )
        run = _optimizer_run(k, res)
        state.runs.append(run)
        notify(Progress("run_done", k + 1, cfg_o.n_runs, run=k, best=run.fun, payload=run))


def _choose(setup: RunSetup, problem: Any, state: _State) -> tuple[FloatArray, FloatArray]:
    """3. The reported elites, and the dense safety check of each (``state.safety``)."""
    state.phase = "selection of the elites"
    n_report = setup.config.emupso.n_report_elites
    chosen_x, chosen_f = _select_elites(state.runs, problem.objective, problem.bounds, n_report)
    if chosen_x.shape[0] == 0:
        raise TrajectoryError(
            "no optimized trajectory satisfies the constraints (every archive member "
            "violates a joint limit, continuity or reachability); raise the penalty, "
            "widen the limits or narrow the excitation bounds."
        )
    # the dense check at the controller's rate decides which elites a robot may run
    state.phase = "dense safety check"
    state.safety = check_elites(setup.config, setup.robot, setup.family, setup.safety, chosen_x)
    return chosen_x, chosen_f


def _measure(
    setup: RunSetup,
    problem: Any,
    stage_info: StageInfo,
    measure: Any,
    chosen_x: FloatArray,
    chosen_f: FloatArray,
    stream: Any,
    state: _State,
    notify: ProgressCallback,
) -> None:
    """4-5. Measure and identify every reported elite (``state.outcomes``)."""
    details = _details(problem.objective, chosen_x)
    meas_streams = stream.spawn(chosen_x.shape[0])
    for i in range(chosen_x.shape[0]):
        state.phase = f"identification of elite {i + 1}"
        with one_blas_thread():
            outcome = measure(
                setup.config,
                setup.robot,
                setup.family,
                stage_info,
                i,
                chosen_x[i],
                float(chosen_f[i]),
                details[i],
                meas_streams[i],
            )
        outcome = dataclasses.replace(outcome, safety_check=state.safety[i])
        state.outcomes.append(outcome)
        notify(Progress("identify", i + 1, chosen_x.shape[0], best=outcome.fitness))


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
    violated: tuple[str, ...] = ()
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
        violated = tuple(names[j] for j in top)
        worst = "; constraints violated most often by random designs: " + ", ".join(
            f"{names[j]} ({100 * share[j]:.0f} %)" for j in top
        )
    except Exception:  # the message must not fail: keep what the search said
        pass
    return (
        f"initial elite search: {search.message}{worst}. No trajectory in the excitation "
        f"bounds meets the constraints: {feasibility_advice(family, violated)}."
    )
