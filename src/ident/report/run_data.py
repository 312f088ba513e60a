"""The data files of an ``ident run`` folder, written from a RunResult and read back.

:func:`save_run` writes the data of a :class:`~ident.run.pipeline.RunResult`:

- ``result.json``: every number of the report, machine-readable (no times: the same config
  and seed give a byte-identical file; non-finite numbers are ``null``); the error measures
  of :mod:`ident.identify.assessment.metrics` per elite and estimator;
- ``config.yaml``: the effective config (after ``--quick`` / ``--seed``);
- ``robot.urdf``: the robot's URDF text (for the replay);
- ``trajectory.csv``: the chosen elite (``ident.trajectory`` format: t, q, dq, ddq of the
  commanded motion, all joints, and the simulated measured torques tau);
- ``elites/elite_<k>.csv`` (same format) and ``elites/elite_<k>_path.csv`` (t, x, y, z of
  the traced point [m]) for every reported elite;
- ``validation.csv`` when the result has a validation trajectory (t, measured torques,
  predicted torques per estimator).

:func:`save_run_model` then writes the identified model of a simulated log's identification
(``<urdf>_identified.urdf``, ``.xml``, ``_joint_extras.json``) and adds its ``model`` entry
to ``result.json``.

:func:`write_replay` writes ``replay.html`` (``ident.viz.replay``); :func:`load_run` reads
``result.json`` back for the report.
"""

from __future__ import annotations

import dataclasses
import json
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ident.config import short_repr
from ident.errors import IdentError
from ident.fileio import atomic_write_text
from ident.identify.assessment.metrics import MAJOR_SHARE, _arr, _num, error_measures
from ident.identify.assessment.rollout import rollout_text
from ident.identify.estimation.uncertainty import interval_coverage, parameter_std
from ident.report.paper import _paper_comparison, _paper_counts
from ident.report.run_verdict import verdict_entry
from ident.run.rundir import RUNNING, write_result_json
from ident.trajectory import JointTrajectory, read_trajectory_csv, trajectory_to_csv

__all__ = ["FORMAT", "load_run", "result_to_dict", "save_run", "save_run_model", "write_replay"]

FORMAT = "ident-run/1"
# the top-level fields every result.json of this format has (save_run writes them all)
_REQUIRED_KEYS = ("status", "config", "robot", "excitation", "initial_elites", "optimization",
                  "elites")  # fmt: skip


def _joint_units(result: Any) -> list[str]:
    """Torque unit of each joint of the run: ``"N"`` (prismatic) or ``"N*m"``, from the URDF."""
    from ident.identify.assessment.sanity import joint_units
    from ident.robot.urdf_load import model_from_text

    model = model_from_text(str(result.urdf_text), "robot.urdf")
    units = dict(zip(model.names[1:], joint_units(model), strict=True))
    return [units.get(name, "N*m") for name in result.joint_names]


def result_to_dict(result: Any) -> dict[str, Any]:
    """The machine-readable content of ``result.json`` (see :func:`save_run`)."""
    config = result.config
    out: dict[str, Any] = {
        "format": FORMAT,
        "status": result.status,
        "message": result.message,
        "name": config.name,
        "seed": config.seed,
        "config": json.loads(config.model_dump_json()),
        "robot": _robot_entry(result),
        "excitation": _excitation_entry(result),
        "warnings": list(result.warnings),
    }
    stage = result.stage
    if stage is not None:
        out["stage"] = _stage_entry(stage)
    out["initial_elites"] = {
        "x": None if result.initial_elites is None else _arr(result.initial_elites),
        "message": result.elite_search_message,
    }
    out["optimization"] = {
        "n_runs_finished": len(result.runs),
        "runs": [_run_entry(r) for r in result.runs],
    }
    elites = [_elite_entry(e, stage) for e in result.elites]
    out["elites"] = elites
    out["chosen_elite"] = _chosen_elite(result, elites)
    # optional results of later pipeline steps (read with defaults: older results lack them)
    for key in ("consistency", "safety"):
        entry = _plain(getattr(result, key, None))
        if entry is not None:
            out[key] = entry
    validation = _validation_entry(result)
    if validation is not None:
        out["validation"] = validation
    # the one verdict every renderer shows, on the elite trajectory.csv executes
    out["executed_elite"] = result.executed_rank
    out["verdict"] = verdict_entry(result, out)
    return out


def _robot_entry(result: Any) -> dict[str, Any]:
    """``robot`` entry of ``result.json``: joint names, torque units and limits."""
    return {
        "name": result.robot_name,
        "joint_names": list(result.joint_names),
        "joint_units": _joint_units(result),
        "q_limits": _arr(result.q_limits),
        "dq_limits": _arr(result.dq_limits),
        "ddq_limits": _arr(result.ddq_limits),
    }


def _excitation_entry(result: Any) -> dict[str, Any]:
    """``excitation`` entry of ``result.json``: the family, criterion and design variables."""
    config = result.config
    return {
        "family": config.excitation.family,
        "criterion": config.excitation.criterion,
        "variable_names": list(result.variable_names),
        "bounds": _arr(result.bounds),
        "traced_frame": result.traced_frame,
        "moving_joints": list(result.moving_joints),
    }


def _stage_entry(stage: Any) -> dict[str, Any]:
    """``stage`` entry of ``result.json``: the stage's parameters and their base set."""
    counts = stage.counts
    return {
        "name": stage.name,
        "torque_rows": list(stage.rows),
        "standard_names": list(stage.standard_names),
        "true_standard": _arr(stage.true_standard),
        "base_method": stage.base_method,
        "known_bodies": stage.known_bodies_note,
        "counts": {
            "independent": counts[0],
            "dependent": counts[1],
            "unidentifiable": counts[2],
            "n_base": len(stage.base_names),
        },
        "paper_counts": _paper_counts(stage.name),
        "independent": list(stage.independent),
        "dependent": list(stage.dependent),
        "unidentifiable": list(stage.unidentifiable),
        "base_names": list(stage.base_names),
        "base_expressions": list(stage.base_expressions),
        "true_base": _arr(stage.true_base),
        "identifiable_alone": list(stage.alone),
        "reference_torque_share": None
        if stage.reference_share is None
        else _arr(stage.reference_share),
        "major_share": MAJOR_SHARE,
        "frames": "body",
        "dh_frames": _frame_base_dict(stage.dh_frames),
        "paper_comparison": _paper_comparison(stage),
    }


def _run_entry(run: Any) -> dict[str, Any]:
    """One optimizer run of ``optimization.runs``: its best point, history and archive."""
    return {
        "index": run.index,
        "best_fitness": _num(run.fun),
        "x": _arr(run.x),
        "history": _arr(run.history),
        "mutation_iterations": list(run.mutation_iterations),
        "nit": run.nit,
        "nfev": run.nfev,
        "message": run.message,
        "archive": {"x": _arr(run.archive_x), "fitness": _arr(run.archive_fun)},
    }


def _elite_entry(elite: Any, stage: Any) -> dict[str, Any]:
    """One entry of ``elites``: the elite's design, estimates and safety check."""
    unc = getattr(getattr(elite.log, "result", None), "uncertainty", None)
    estimates = {
        method: _estimate_entry(est, unc, elite, stage) for method, est in elite.estimates.items()
    }
    check = getattr(elite, "safety_check", None)
    return {
        "rank": elite.rank,
        "x": _arr(elite.x),
        "fitness": _num(elite.fitness),
        "objective": {k: _num(v) for k, v in elite.details.items()},
        "estimates": estimates,
        "failures": dict(elite.failures),
        "trajectory_csv": f"elites/elite_{elite.rank}.csv",
        "safety": None
        if check is None
        else {"usable": bool(check.usable), "summary": check.summary()},
        "path_csv": None if elite.traced_points is None else f"elites/elite_{elite.rank}_path.csv",
        "safety_series": _safety_series(check),
    }


def _estimate_entry(est: Any, unc: Any, elite: Any, stage: Any) -> dict[str, Any]:
    """One estimator's entry of an elite: the estimate, its σ and (with a stage) its errors."""
    sd = parameter_std(est, unc)  # the one σ (a simulated log's bootstrap)
    entry = {
        "x": _arr(est.x),
        "std": _arr(sd.std),
        "relative_std_percent": _arr(sd.relative_std),
        "std_method": sd.method,
        "condition_number": _num(est.condition_number),
        "residual_rms": _arr(est.residual_rms),
        "relative_residual": _num(est.relative_residual),
        "sigma": _arr(est.sigma),
        "n_samples": int(est.n_samples),
        "message": est.message,
    }
    if stage is not None:
        entry.update(
            error_measures(
                est.x,
                sd.std,
                stage.true_base,
                elite.base_column_norms,
                elite.true_torque_norm,
                stage.reference_share,
            )
        )
        if sd.calibrated and unc is not None:  # a simulated log's
            entry["within_95_interval"] = interval_coverage(unc, stage.true_base)
            entry["interval_method"] = unc.method
    return entry


def _chosen_elite(result: Any, elites: list[dict[str, Any]]) -> Any:
    """Rank of the elite the robot may run (the best one that passed the check)."""
    plan = getattr(result, "executable", None)
    if plan is not None:
        return plan.elite
    return 1 if elites else None


def _safety_series(report: Any) -> dict[str, Any] | None:
    """The compact safety time series of an elite's dense check (None when unchecked)."""
    if report is None:
        return None
    from ident.excitation.safety_series import safety_series

    return safety_series(report)


def _frame_base_dict(info: Any) -> dict[str, Any] | None:
    """``result.json`` entry of a :class:`~ident.run.pipeline.FrameBaseInfo` (or None)."""
    if info is None:
        return None
    counts = info.counts
    return {
        "frames": info.frames,
        "method": info.method,
        "column_order": "eq. 14 (m, mcx, mcy, mcz, Ixx, Iyy, Izz, Ixy, Ixz, Iyz per body)",
        "counts": {
            "independent": counts[0],
            "dependent": counts[1],
            "unidentifiable": counts[2],
            "n_base": len(info.base_names),
        },
        "standard_names": list(info.standard_names),
        "true_standard": _arr(info.true_standard),
        "independent": list(info.independent),
        "dependent": list(info.dependent),
        "unidentifiable": list(info.unidentifiable),
        "base_names": list(info.base_names),
        "base_expressions": list(info.base_expressions),
        "true_base": _arr(info.true_base),
    }


def _joint_trajectory(result: Any, elite: Any) -> JointTrajectory:
    """An elite's commanded motion and, when they were measured, its torques: an elite whose
    simulation failed has no ``tau_*`` columns (its ``failures`` say why), never NaN ones
    that the run's own readers would refuse."""
    tau = None if elite.tau is None else np.array(elite.tau, dtype=float)
    return JointTrajectory(
        t=np.array(elite.t, dtype=float),
        q=np.array(elite.q, dtype=float),
        dq=np.array(elite.dq, dtype=float),
        ddq=np.array(elite.ddq, dtype=float),
        joint_names=tuple(result.joint_names),
        tau=tau if tau is not None and np.isfinite(tau).all() else None,
    )


def save_run(result: Any, run_dir: str | Path) -> None:
    """Write the data files of a run (see the module docstring) into ``run_dir``."""
    run_dir = Path(run_dir)
    data = result_to_dict(result)
    atomic_write_text(
        run_dir / "config.yaml",
        yaml.safe_dump(data["config"], sort_keys=False, default_flow_style=None),
    )
    atomic_write_text(run_dir / "robot.urdf", result.urdf_text)
    for elite in result.elites:
        csv = trajectory_to_csv(_joint_trajectory(result, elite))
        atomic_write_text(run_dir / "elites" / f"elite_{elite.rank}.csv", csv)
        if elite.traced_points is not None:
            rows = np.column_stack([elite.t, elite.traced_points])
            lines = ["t,x,y,z"] + [",".join(f"{v:.17g}" for v in row) for row in rows]
            atomic_write_text(
                run_dir / "elites" / f"elite_{elite.rank}_path.csv", "\n".join(lines) + "\n"
            )
    plan = getattr(result, "executable", None)
    if plan is not None and plan.trajectory is not None:
        # what the controller runs: approach, periods, return, checked as a whole
        atomic_write_text(run_dir / "trajectory.csv", trajectory_to_csv(plan.trajectory))
    validation = getattr(result, "validation", None)
    if validation is not None and _validation_entry(result) is not None:
        atomic_write_text(run_dir / "validation.csv", _validation_csv(result, validation))
    # result.json last: its presence means the data files above are complete; the run is
    # "running" until RunDir.finish marks it (with run.json) after its last file
    if data["status"] == "complete":
        data.update(status=RUNNING, message="saving the run's files")
    write_result_json(run_dir / "result.json", data)


def save_run_model(result: Any, run_dir: str | Path) -> dict[str, Any] | None:
    """Write the identified model of the executed elite's log and record it in ``result.json``.

    After :func:`save_run` (the data are saved first). The model is the physically consistent
    estimate of the log the simulator wrote for the elite ``trajectory.csv`` executes
    (:func:`ident.identify.model_files.files.save_identified_model`); its entry, with ``elite``, is
    added to ``result.json`` as ``model``, and the MJCF's rollout check against the simulator's
    truth as ``rollout`` (:func:`ident.identify.assessment.rollout.run_rollout`; "not run" and
    why without a model), and with a model its ``refinement`` entry
    (:func:`ident.identify.refinement.rollout_refinement.refinement_entry`). None (nothing written)
    for a run without a simulated log
    (``measurement.source: ideal``) or without elites.
    """
    from ident.identify.assessment.rollout import run_rollout
    from ident.identify.model_files.files import save_identified_model
    from ident.identify.refinement.rollout_refinement import refinement_entry

    run_dir = Path(run_dir)
    rank = result.executed_rank
    elite = next((e for e in result.elites if e.rank == rank), None)
    outcome = getattr(elite, "log", None)
    entry = None
    if outcome is not None and outcome.result is not None:  # a log, and it identified
        entry = {"elite": rank, **save_identified_model(outcome.result, run_dir)}
    data = load_run(run_dir)
    if entry is not None:
        data["model"] = entry
    payload = getattr(result.config.measurement, "payload", None)
    data["rollout"] = run_rollout(outcome, payload, run_dir, entry)  # MJCF vs the truth
    # refinement: rollout rewrites the MJCF's joint extras when accepted
    if entry is not None and outcome is not None:
        data["refinement"] = refinement_entry(outcome.result, run_dir, entry, data["rollout"])
    write_result_json(run_dir / "result.json", data)
    return entry


def write_replay(run_dir: str | Path) -> str:
    """Write ``replay.html`` for the chosen elite; return a one-line note of what happened.

    The traced point is :func:`ident.viz.environment.run_traced_frame` (the excitation
    family's; for a family without one, the wrist centre for the arm stage and the replay's
    default, the flange, otherwise), as for ``ident replay RUN``. The floor and obstacles of
    the config's ``safety`` section are drawn, and the moment of the elite's smallest
    clearance is marked and named in the title. The note names the frame.
    Never raises for a missing or failing replay module: the report says so instead.
    """
    run_dir = Path(run_dir)
    try:
        from ident.viz.environment import (
            run_clearance_mark,
            run_environment,
            run_traced_frame,
        )

        # the page is drawn by _replay_page; a replay module that cannot load is a note here
        from ident.viz.replay import replay_html, run_robot_selection  # noqa: F401
    except ImportError as e:
        return f"no replay: ident.viz.replay is not available ({e})."
    data = _result_or_empty(run_dir)
    traced_frame = run_traced_frame(data)
    config = data.get("config")
    # one period of the elite the robot may run; without one, elite 1, marked unsafe
    chosen = data.get("chosen_elite")
    rank = chosen if isinstance(chosen, int) else 1
    trajectory_path = run_dir / "elites" / f"elite_{rank}.csv"
    if not trajectory_path.is_file():
        return "no replay: the run has no elite trajectory."
    try:
        trajectory = read_trajectory_csv(trajectory_path)
    except IdentError as e:  # the run's own file: a note, never the run's failure
        return f"no replay: {e}"
    environment = run_environment(data)
    mark = run_clearance_mark(data, rank)
    label, title = _replay_captions(data, run_dir, rank, mark)
    robot = config.get("robot") if isinstance(config, dict) else None
    frames = tuple(dict.fromkeys((traced_frame, None)))  # the family's traced point, else default
    page, frame, caught, problem = _replay_page(
        run_dir, robot if isinstance(robot, dict) else None, trajectory, frames,
        label=label, environment=environment, mark=mark, title=title,
    )  # fmt: skip
    if page is None:
        return problem
    atomic_write_text(run_dir / "replay.html", page)
    copy = str(run_dir / "robot.urdf")  # name the copy, not this folder's absolute path
    notes = "".join(f"; {str(w.message).replace(copy, 'robot.urdf').rstrip('.')}" for w in caught)
    return f"replay.html written (traced frame: {frame or _default_frame(run_dir)}){notes}."


def _replay_page(
    run_dir: Path,
    robot: dict[str, Any] | None,
    trajectory: JointTrajectory,
    frames: tuple[str | None, ...],
    *,
    label: str,
    environment: Any,
    mark: Any,
    title: str,
) -> tuple[str | None, str | None, list[warnings.WarningMessage], str]:
    """The replay page of ``trajectory`` (:func:`ident.viz.replay.replay_html`) tracing the
    first of ``frames`` that works (``None``: the replay's default frame), on the run's chain,
    locked joints and mesh folders (``robot``: the config's robot section).

    Returns the page (``None`` when every frame failed), the frame, the warnings of the page
    (e.g. meshes not found) and the note of the last failure. Never raises.
    """
    from ident.viz.replay import replay_html, run_robot_selection

    page, problem, frame = None, "", None
    caught: list[warnings.WarningMessage] = []
    for frame in frames:
        try:
            with warnings.catch_warnings(record=True) as caught:  # e.g. meshes not found
                warnings.simplefilter("always")
                page = replay_html(
                    # the run's chain, locked joints and mesh folders (robot.package_dirs)
                    run_robot_selection(run_dir, robot),
                    [trajectory],
                    traced_frame=frame,
                    labels=[label],
                    environment=environment,
                    marks=[mark],
                    title=title,
                    package_hint="robot.package_dirs in the config",
                )
            break
        except Exception as e:  # the replay is a convenience: a failure must not lose the run
            problem = f"no replay: {type(e).__name__}: {e}"
    return page, frame, caught, problem


def _result_or_empty(run_dir: Path) -> dict[str, Any]:
    """The run's result.json, or {} when it is missing, unreadable or not an object."""
    try:
        data = json.loads((run_dir / "result.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) else {}


def _replay_captions(data: dict[str, Any], run_dir: Path, rank: int, mark: Any) -> tuple[str, str]:
    """The replay's trajectory label (marked unsafe when no elite was chosen, under a safety
    check) and page title (naming the smallest clearance ``mark``, a ClearanceMark or None)."""
    config = data.get("config")
    stage = config.get("stage") if isinstance(config, dict) else None
    label = f"elite {rank} of {data.get('name')} ({stage} stage)" if data else "elite 1"
    if not isinstance(data.get("chosen_elite"), int) and data.get("safety") is not None:
        label += " - UNSAFE, not for the robot"
    title = f"ident replay: {data.get('name') or run_dir.name}, elite {rank}"
    if mark is not None:
        title += f", {mark.describe()}"
    return label, title


def _default_frame(run_dir: Path) -> str:
    """Name of the frame the replay traces by default for the run's robot."""
    try:
        from ident.inputs import read_urdf_text
        from ident.robot.urdf_load import model_from_text
        from ident.viz.replay import default_traced_frame

        path = run_dir / "robot.urdf"
        return default_traced_frame(model_from_text(read_urdf_text(path), str(path)))
    except Exception:  # only a label: never fail the replay for it
        return "default"


def load_run(run_dir: Path) -> dict[str, Any]:
    path = run_dir / "result.json"
    if not path.is_file():
        raise IdentError(
            f"{run_dir}: no result.json; the run did not get far enough to save results "
            "(see run.json for its status)."
        )
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise IdentError(f"{path}: not valid JSON ({e}); the run folder is damaged.") from e
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        found = data.get("format") if isinstance(data, dict) else type(data).__name__
        raise IdentError(f"{path}: format {found!r} is not {FORMAT!r}.")
    missing = [k for k in _REQUIRED_KEYS if k not in data]
    if missing:  # a hand-edited or truncated file: name the fields, not a KeyError
        raise IdentError(
            f"{path}: no {', '.join(missing)} (fields every {FORMAT} result.json has); the "
            "run folder is damaged: run 'ident run' again."
        )
    problem = _field_problem(data)
    if problem:  # the same for a field of the wrong shape, before any file is written
        raise IdentError(f"{path}: {problem}; the run folder is damaged: run 'ident run' again.")
    return data


# the entries the report reads, and their JSON type (None: may also be null)
_FIELD_TYPES: dict[str, tuple[type, bool]] = {
    "config": (dict, False),
    "robot": (dict, False),
    "excitation": (dict, False),
    "optimization": (dict, False),
    "elites": (list, False),
    "warnings": (list, True),
    "stage": (dict, True),
    "safety": (dict, True),
    "model": (dict, True),
    "rollout": (dict, True),
}


def _field_problem(data: dict[str, Any]) -> str:
    """What is wrong with the shape of a result.json's fields the report reads ('' if
    nothing): a field of another JSON type, an elite without its rank, a rollout entry the
    report cannot show (:func:`~ident.identify.assessment.rollout.rollout_text` reads it)."""
    for key, (kind, nullable) in _FIELD_TYPES.items():
        value = data.get(key)
        if (value is None and (nullable or key not in data)) or isinstance(value, kind):
            continue
        return f"{key} is {short_repr(value)}, not a JSON {'object' if kind is dict else 'list'}"
    for n, elite in enumerate(data["elites"]):
        if not isinstance(elite, dict) or not isinstance(elite.get("rank"), int):
            return f"elites[{n}] is {short_repr(elite)}, not an elite with its rank"
    if isinstance(data.get("model"), dict) and "elite" not in data["model"]:
        return "model has no elite (the elite whose simulated log it identifies)"
    try:
        rollout_text(data.get("rollout"))
    except (KeyError, TypeError, ValueError) as e:
        return f"rollout lacks or mistypes {e} (the MJCF rollout check's entry)"
    return ""


def _plain(entry: Any) -> Any:
    """A consistency / safety result as JSON-ready data (dataclass, dict, str or bool)."""
    if entry is None:
        return None
    if dataclasses.is_dataclass(entry) and not isinstance(entry, type):
        entry = dataclasses.asdict(entry)
    if isinstance(entry, dict):
        return {str(k): _plain_value(v) for k, v in entry.items()}
    return _plain_value(entry)


def _plain_value(v: Any) -> Any:
    if isinstance(v, (str, bool)) or v is None:
        return v
    if isinstance(v, dict):
        return {str(k): _plain_value(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain_value(x) for x in v]
    try:
        return _arr(v)
    except (TypeError, ValueError):
        return str(v)


def _validation_entry(result: Any) -> dict[str, Any] | None:
    """Prediction errors on the run's validation trajectory (``result.validation``: ``t``
    (n,), measured ``tau`` (n, n_rows) and ``tau_pred`` ``{method: (n, n_rows)}``)."""
    from ident.identify.estimation.validation import prediction_metrics

    val = getattr(result, "validation", None)
    if val is None:
        return None
    try:
        tau = np.asarray(val.tau, dtype=float)
        entries = {
            m: prediction_metrics(tau, np.asarray(pred, dtype=float)).as_dict()
            for m, pred in dict(val.tau_pred).items()
        }
    except (AttributeError, TypeError, ValueError):
        return None
    return {
        "n_samples": int(tau.shape[0]),
        "estimates": {
            m: {**e, "relative_residual": e["total_relative_residual"]} for m, e in entries.items()
        },
    }


def _validation_csv(result: Any, val: Any) -> str:
    """``validation.csv``: t, tau_<joint> (measured), <method>_<joint> (predicted)."""
    tau = np.asarray(val.tau, dtype=float)
    stage = result.stage
    rows = list(stage.rows) if stage is not None and len(stage.rows) == tau.shape[1] else None
    joints = (
        [result.joint_names[r] for r in rows]
        if rows is not None
        else list(result.joint_names[: tau.shape[1]])
    )
    cols = [np.asarray(val.t, dtype=float)[:, None], tau]
    header = ["t", *[f"tau_{j}" for j in joints]]
    for m, pred in dict(val.tau_pred).items():
        cols.append(np.asarray(pred, dtype=float))
        header += [f"{m}_{j}" for j in joints]
    body = np.column_stack(cols)
    lines = [",".join(header)] + [",".join(f"{v:.17g}" for v in row) for row in body]
    return "\n".join(lines) + "\n"
