"""The run folder of ``ident run``: saved data, then the report made from it.

:func:`save_run` writes the data of a :class:`~ident.run.pipeline.RunResult`:

- ``result.json``: every number of the report, machine-readable (no times: the same config
  and seed give a byte-identical file; non-finite numbers are ``null``);
- ``config.yaml``: the effective config (after ``--quick`` / ``--seed``);
- ``robot.urdf``: the robot's URDF text (for the replay);
- ``trajectory.csv``: the chosen elite (``ident.trajectory`` format: t, q, dq, ddq of the
  commanded motion, all joints, and the simulated measured torques tau);
- ``elites/elite_<k>.csv`` (same format) and ``elites/elite_<k>_path.csv`` (t, x, y, z of
  the traced point [m]) for every reported elite.

:func:`write_report` reads only those files back and writes ``figures/*.png``,
``report.md`` and ``report.html`` (figures embedded); ``ident report RUN_DIR`` calls it, so a
report can always be regenerated from the saved data. :func:`write_replay` writes
``replay.html`` (``ident.viz.replay``).

Error measures (per base parameter, true = projection of the true standard parameters):
absolute error ``x - true``; relative error ``|x - true| / |true|`` [%] where ``|true|`` is
above ``1e-9`` times the largest ``|true|`` (otherwise the true value is zero up to
round-off and only the absolute error is shown); normalized error ``(x - true) / std``.
Unit-free measures on the trajectory's base matrix ``W_b``: the *torque share*
``|true_i| ||W_i|| / ||W_b true||`` of a parameter (how much of the torque it explains) and its
*torque error* ``|x_i - true_i| ||W_i|| / ||W_b true||``. ``max_torque_error`` is the largest
torque error; ``max_rel_error`` the largest relative error among the parameters with a torque
share of at least 1e-4. (The paper robot has base parameters of 1e-7 of the largest, products
of its 1e-6 kg*m first moments: their relative error is limited by ``cond(W_b) * eps`` over
their share, not by the method.)
``error_sum`` is the sum of the relative errors [%] (the paper's "Error(22)"),
``error_sum_best`` the same without the two largest (the paper's "Error(20)" for 22 base
parameters).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import yaml

from ident.errors import IdentError
from ident.fileio import atomic_write_bytes, atomic_write_text
from ident.trajectory import JointTrajectory, read_trajectory_csv, trajectory_to_csv

__all__ = [
    "FORMAT",
    "error_measures",
    "result_to_dict",
    "save_run",
    "write_replay",
    "write_report",
]

FloatArray = npt.NDArray[np.float64]
FORMAT = "ident-run/1"
ZERO_RTOL = 1e-9
SIGNIFICANT_SHARE = 1e-4
MAJOR_SHARE = 1e-2
PAPER_COUNTS = {"wrist": (15, 7, 8), "arm": (20, 2, 8)}
PAPER_COUNTS_NOTE = (
    "The paper reports wrist 15 independent / 7 in combination / 8 unidentifiable and arm "
    "20 / 2 / 8 (section 4.1); docs/paper-notes.md explains the differences."
)
#: The paper's named lists (section 4.1), in its spelling mapped to ours ("mx5" = mcx5,
#: "mm6" = m6). Wrist: 15 independent and 7 in combination (Iyz6 is in both lists, so 21
#: distinct names). Arm: 22 identified names, not split into independent and combined.
PAPER_NAMES: dict[str, dict[str, tuple[str, ...]]] = {
    "wrist": {
        "independent": tuple(
            "Iyy4 Ixz4 mcx5 Ixx5 Iyy5 Izz5 Ixy5 Ixz5 Iyz5 mcx6 mcy6 Iyy6 Izz6 Ixz6 Iyz6".split()
        ),
        "dependent": tuple("mcy4 mcy5 mcz5 m6 mcz6 Ixx6 Iyz6".split()),
    },
    "arm": {
        "identified": tuple(
            "mcy1 Iyy1 m2 mcx2 mcy2 mcz2 Iyy2 Izz2 Ixz2 Iyz2 m3 mcx3 mcy3 mcz3 Ixx3 Iyy3 "
            "Izz3 Ixy3 Ixz3 Iyz3 Ixz1 Ixx2".split()
        ),
    },
}
_CLASS_LABEL = {
    "independent": "independent",
    "dependent": "in combination",
    "unidentifiable": "unidentifiable",
    "identified": "identified (independent or in combination)",
}


# ----------------------------------------------------------------------------- numbers


def _num(value: Any) -> Any:
    """JSON-safe number: non-finite -> None; numpy scalars -> Python."""
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    value = float(value)
    return value if math.isfinite(value) else None


def _arr(a: Any) -> Any:
    a = np.asarray(a)
    if a.ndim == 0:
        return _num(a)
    return [_arr(v) for v in a]


def error_measures(
    x: FloatArray,
    std: FloatArray,
    true: FloatArray,
    column_norms: FloatArray | None = None,
    true_torque_norm: float | None = None,
    reference_share: FloatArray | None = None,
) -> dict[str, Any]:
    """Errors of an estimate against the true values (see the module docstring).

    Parameters
    ----------
    x, std, true :
        Estimate, its standard deviations and the true values, shape (n,).
    column_norms :
        Norms of the base observation matrix columns ``||W_b[:, i]||`` on the trajectory,
        shape (n,); with ``true_torque_norm = ||W_b @ true||`` they give unit-free measures.
    true_torque_norm :
        See ``column_norms``.
    reference_share :
        Torque share of each parameter on the stage's reference motion (trajectory
        independent, :attr:`ident.run.pipeline.StageInfo.reference_share`), shape (n,).

    Returns
    -------
    :
        ``abs_error`` (n,), ``rel_error_percent`` (n, None where true ~ 0),
        ``normalized_error`` (n, None where std = 0), ``error_sum_percent``,
        ``error_sum_best_percent``, ``within_3std`` (share of parameters with
        ``|x - true| <= 3 std``), and, with the column norms: ``torque_share`` (n,)
        ``|true_i| ||W_i|| / ||W_b true||``, ``torque_error`` (n,)
        ``|x_i - true_i| ||W_i|| / ||W_b true||``, ``max_torque_error`` and
        ``max_rel_error`` (the largest relative error of the parameters whose torque share is
        at least ``SIGNIFICANT_SHARE``), ``error_sum_significant_percent`` (the sum of their
        relative errors [%]); without them ``max_rel_error`` is over the
        parameters whose ``|true|`` is at least that fraction of the largest. With
        ``reference_share``: ``max_rel_error_major``, the largest relative error of the
        stage's *major* parameters (reference share at least ``MAJOR_SHARE``), the same set
        whatever the trajectory, so trajectories can be compared.
    """
    x, std, true = (np.asarray(a, dtype=float) for a in (x, std, true))
    err = x - true
    scale = float(np.max(np.abs(true), initial=0.0))
    nonzero = np.abs(true) > ZERO_RTOL * scale
    rel = np.full(true.shape, np.nan)
    rel[nonzero] = np.abs(err[nonzero]) / np.abs(true[nonzero])
    with np.errstate(divide="ignore", invalid="ignore"):
        normalized = np.where(std > 0, err / std, np.nan)
    within = np.abs(err) <= 3.0 * std
    rel_sorted = np.sort(100.0 * rel[nonzero])
    out = {
        "abs_error": _arr(err),
        "rel_error_percent": _arr(100.0 * rel),
        "normalized_error": _arr(normalized),
        "error_sum_percent": _num(rel_sorted.sum()),
        "error_sum_best_percent": _num(rel_sorted[: max(0, rel_sorted.size - 2)].sum()),
        "within_3std": _num(float(np.mean(within)) if within.size else 0.0),
    }
    if column_norms is not None and true_torque_norm is not None and true_torque_norm > 0:
        norms = np.asarray(column_norms, dtype=float)
        share = np.abs(true) * norms / true_torque_norm
        torque_error = np.abs(err) * norms / true_torque_norm
        significant = share >= SIGNIFICANT_SHARE
        out["torque_share"] = _arr(share)
        out["torque_error"] = _arr(torque_error)
        out["max_torque_error"] = _num(float(torque_error.max(initial=0.0)))
        out["error_sum_significant_percent"] = _num(
            float(np.sum(100.0 * np.abs(err[significant]) / np.abs(true[significant])))
        )
    else:
        significant = np.abs(true) >= SIGNIFICANT_SHARE * scale
    out["max_rel_error"] = _num(
        float(np.max(np.abs(err[significant]) / np.abs(true[significant]), initial=0.0))
    )
    if reference_share is not None:
        major = (np.asarray(reference_share, dtype=float) >= MAJOR_SHARE) & nonzero
        out["max_rel_error_major"] = _num(
            float(np.max(np.abs(err[major]) / np.abs(true[major]), initial=0.0))
        )
    return out


# ----------------------------------------------------------------------------- saving


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
        "robot": {
            "name": result.robot_name,
            "joint_names": list(result.joint_names),
            "q_limits": _arr(result.q_limits),
            "dq_limits": _arr(result.dq_limits),
            "ddq_limits": _arr(result.ddq_limits),
        },
        "excitation": {
            "family": config.excitation.family,
            "criterion": config.excitation.criterion,
            "variable_names": list(result.variable_names),
            "bounds": _arr(result.bounds),
            "traced_frame": result.traced_frame,
            "moving_joints": list(result.moving_joints),
        },
        "warnings": list(result.warnings),
    }
    stage = result.stage
    if stage is not None:
        counts = stage.counts
        out["stage"] = {
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
    out["initial_elites"] = {
        "x": None if result.initial_elites is None else _arr(result.initial_elites),
        "message": result.elite_search_message,
    }
    out["optimization"] = {
        "n_runs_finished": len(result.runs),
        "runs": [
            {
                "index": r.index,
                "best_fitness": _num(r.fun),
                "x": _arr(r.x),
                "history": _arr(r.history),
                "mutation_iterations": list(r.mutation_iterations),
                "nit": r.nit,
                "nfev": r.nfev,
                "message": r.message,
                "archive": {"x": _arr(r.archive_x), "fitness": _arr(r.archive_fun)},
            }
            for r in result.runs
        ],
    }
    elites = []
    for e in result.elites:
        estimates = {}
        for method, est in e.estimates.items():
            entry = {
                "x": _arr(est.x),
                "std": _arr(est.std),
                "relative_std_percent": _arr(est.relative_std),
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
                        est.std,
                        stage.true_base,
                        e.base_column_norms,
                        e.true_torque_norm,
                        stage.reference_share,
                    )
                )
            estimates[method] = entry
        elites.append(
            {
                "rank": e.rank,
                "x": _arr(e.x),
                "fitness": _num(e.fitness),
                "objective": {k: _num(v) for k, v in e.details.items()},
                "estimates": estimates,
                "failures": dict(e.failures),
                "trajectory_csv": f"elites/elite_{e.rank}.csv",
                "path_csv": None if e.traced_points is None else f"elites/elite_{e.rank}_path.csv",
            }
        )
    out["elites"] = elites
    out["chosen_elite"] = 1 if elites else None
    return out


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


def classify(name: str, independent: Any, dependent: Any, unidentifiable: Any) -> str:
    """``independent``, ``dependent`` or ``unidentifiable`` (``?`` if in none)."""
    for label, group in (
        ("independent", independent),
        ("dependent", dependent),
        ("unidentifiable", unidentifiable),
    ):
        if name in group:
            return label
    return "?"


def _paper_comparison(stage: Any) -> list[dict[str, Any]] | None:
    """Per standard parameter of the stage: its class in the paper's lists, ours in DH frames
    and ours in body frames (``None`` for a stage without the paper's lists)."""
    lists = PAPER_NAMES.get(stage.name)
    if lists is None:
        return None
    dh = stage.dh_frames
    names = dh.standard_names if dh is not None else stage.standard_names
    rows = []
    for name in names:
        paper = [label for label, group in lists.items() if name in group]
        rows.append(
            {
                "name": name,
                "paper": paper or ["not listed"],
                "dh": None
                if dh is None
                else classify(name, dh.independent, dh.dependent, dh.unidentifiable),
                "body": classify(name, stage.independent, stage.dependent, stage.unidentifiable),
            }
        )
    return rows


def _paper_counts(stage_name: str) -> dict[str, int] | None:
    if stage_name not in PAPER_COUNTS:
        return None
    keys = ("independent", "dependent", "unidentifiable")
    return dict(zip(keys, PAPER_COUNTS[stage_name], strict=True))


def _joint_trajectory(result: Any, elite: Any) -> JointTrajectory:
    return JointTrajectory(
        t=np.array(elite.t, dtype=float),
        q=np.array(elite.q, dtype=float),
        dq=np.array(elite.dq, dtype=float),
        ddq=np.array(elite.ddq, dtype=float),
        joint_names=tuple(result.joint_names),
        tau=np.array(elite.tau, dtype=float),
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
        if elite.rank == 1:
            atomic_write_text(run_dir / "trajectory.csv", csv)
    # result.json last: its presence means the data files above are complete
    text = json.dumps(data, indent=1, allow_nan=False) + "\n"
    atomic_write_text(run_dir / "result.json", text)


def write_replay(run_dir: str | Path) -> str:
    """Write ``replay.html`` for the chosen elite; return a one-line note of what happened.

    The traced point is the excitation family's (``result.json`` ``excitation.traced_frame``:
    the flange for the paper's wrist family, the wrist centre for its arm family); for a
    family without one (joint space), the wrist centre for the arm stage (the point the arm
    positions) and the replay's default (the flange) otherwise. The note names the frame.
    Never raises for a missing or failing replay module: the report says so instead.
    """
    run_dir = Path(run_dir)
    trajectory_path = run_dir / "trajectory.csv"
    if not trajectory_path.is_file():
        return "no replay: the run has no chosen trajectory."
    try:
        from ident.viz.replay import replay_html
    except ImportError as e:
        return f"no replay: ident.viz.replay is not available ({e})."
    trajectory = read_trajectory_csv(trajectory_path)
    traced_frame, label = None, "elite 1"
    try:
        data = json.loads((run_dir / "result.json").read_text(encoding="utf-8"))
        traced_frame = data["excitation"].get("traced_frame")
        stage = data["config"]["stage"]
        label = f"elite 1 of {data.get('name')} ({stage} stage)"
        if traced_frame is None and stage == "arm":
            traced_frame = "wrist_centre"
    except (OSError, ValueError, KeyError, TypeError):
        pass
    page, problem = None, ""
    for frame in dict.fromkeys((traced_frame, None)):  # the family's traced point, else default
        try:
            page = replay_html(
                run_dir / "robot.urdf", [trajectory], traced_frame=frame, labels=[label]
            )
            break
        except Exception as e:  # the replay is a convenience: a failure must not lose the run
            problem = f"no replay: {type(e).__name__}: {e}"
    if page is None:
        return problem
    atomic_write_text(run_dir / "replay.html", page)
    return f"replay.html written (traced frame: {frame or _default_frame(run_dir)})."


def _default_frame(run_dir: Path) -> str:
    """Name of the frame the replay traces by default for the run's robot."""
    try:
        import pinocchio as pin

        from ident.viz.replay import default_traced_frame

        return default_traced_frame(pin.buildModelFromUrdf(str(run_dir / "robot.urdf")))
    except Exception:  # only a label: never fail the replay for it
        return "default"


# ----------------------------------------------------------------------------- report


def _load(run_dir: Path) -> dict[str, Any]:
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
    if data.get("format") != FORMAT:
        raise IdentError(f"{path}: format {data.get('format')!r} is not {FORMAT!r}.")
    return data


def _fmt(value: Any, digits: int = 4) -> str:
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    value = float(value)
    if value == 0.0:
        return "0"
    if 1e-3 <= abs(value) < 1e5:
        return f"{value:.{digits}g}"
    return f"{value:.{digits - 1}e}"


def _table(header: list[str], rows: list[list[str]], left: tuple[int, ...] = ()) -> list[str]:
    """A Markdown pipe table; columns in ``left`` are left-aligned (text), others default."""
    seps = [":---" if k in left else "---" for k in range(len(header))]
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(seps) + "|"]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in rows]
    return lines + [""]


def _figures(run_dir: Path, data: dict[str, Any]) -> dict[str, bytes]:
    from ident.report.plots import convergence_png, estimate_png, trajectory_png

    figures: dict[str, bytes] = {}
    runs = data["optimization"]["runs"]
    stage_name = data.get("stage", {}).get("name", "")
    histories = [
        np.array([np.nan if v is None else v for v in r["history"]], dtype=float) for r in runs
    ]
    figures["figures/convergence.png"] = convergence_png(
        histories,
        title=f"Convergence of eMuPSO ({stage_name} stage): all runs and their mean",
        mutations=[r["mutation_iterations"] for r in runs],
    )
    traj_path = run_dir / "trajectory.csv"
    if data["elites"] and traj_path.is_file():
        traj = read_trajectory_csv(traj_path)
        moving = data["excitation"]["moving_joints"] or list(range(len(traj.joint_names)))
        robot = data["robot"]
        q_lim = np.array(
            [[np.inf if v is None else v for v in row] for row in robot["q_limits"]], dtype=float
        )
        dq_lim = np.array([np.inf if v is None else v for v in robot["dq_limits"]], dtype=float)
        path = None
        path_csv = data["elites"][0].get("path_csv")
        if path_csv and (run_dir / path_csv).is_file():
            path = np.loadtxt(run_dir / path_csv, delimiter=",", skiprows=1, ndmin=2)[:, 1:4]
        figures["figures/trajectory.png"] = trajectory_png(
            traj.t,
            traj.q[:, moving],
            traj.dq[:, moving],
            [traj.joint_names[j] for j in moving],
            q_limits=q_lim[moving],
            dq_limits=dq_lim[moving],
            path=path,
            title=f"Excitation trajectory of elite 1 ({stage_name} stage)",
        )
        estimates = data["elites"][0]["estimates"]
        if estimates and "stage" in data:
            true = np.array(data["stage"]["true_base"], dtype=float)
            figures["figures/estimate.png"] = estimate_png(
                data["stage"]["base_names"],
                true,
                {
                    m: (np.array(e["x"], dtype=float), np.array(e["std"], dtype=float))
                    for m, e in estimates.items()
                },
                title="Elite 1: (identified - true) / std per base parameter",
            )
    return figures


def write_report(run_dir: str | Path) -> Path:
    """Write ``figures/*.png``, ``report.md`` and ``report.html`` from the saved data.

    Returns
    -------
    :
        Path of ``report.html``.

    Raises
    ------
    IdentError
        If ``result.json`` is missing or damaged.
    """
    from ident.report.html import markdown_to_html
    from ident.run.rundir import RUN_STATE_FILE

    run_dir = Path(run_dir)
    data = _load(run_dir)
    figures = _figures(run_dir, data)
    for name, png in figures.items():
        atomic_write_bytes(run_dir / name, png)
    state = {}
    if (run_dir / RUN_STATE_FILE).is_file():
        try:
            state = json.loads((run_dir / RUN_STATE_FILE).read_text(encoding="utf-8"))
        except json.JSONDecodeError:
            state = {}
    markdown = render_markdown(
        data, figures=set(figures), run_state=state, has_replay=(run_dir / "replay.html").is_file()
    )
    atomic_write_text(run_dir / "report.md", markdown)
    page = markdown_to_html(
        markdown, title=f"ident run {data.get('name', '')}", images=figures, base_dir=run_dir
    )
    return atomic_write_text(run_dir / "report.html", page)


def render_markdown(
    data: dict[str, Any],
    *,
    figures: set[str] | frozenset[str] = frozenset(),
    run_state: dict[str, Any] | None = None,
    has_replay: bool = False,
) -> str:
    """The report text (Markdown) from the content of ``result.json``."""
    md: list[str] = []
    config = data["config"]
    stage = data.get("stage")
    stage_name = stage["name"] if stage else config["stage"]
    md += [f"# ident run: {data.get('name')} ({stage_name} stage)", ""]
    if data["status"] != "complete":
        md += [f"> **Incomplete run**: {data['message']}. Only what finished is reported.", ""]
    for warning in data.get("warnings", []):
        md += [f"> **Warning**: {warning}", ""]
    state = run_state or {}
    md += [
        f"- Robot: `{data['robot']['name']}` ({len(data['robot']['joint_names'])} joints), "
        f"config `{config['robot']}`",
        f"- Stage: **{stage_name}**, excitation family `{config['excitation']['family']}`, "
        f"criterion `{config['excitation']['criterion']}`, "
        f"{config['excitation']['n_samples']} samples per period",
        f"- Seed: **{data['seed']}**",
        f"- Procedure: initial elites ({config['elites']['n_particles']} particles until "
        f"{config['elites']['n_elites']} elites), then {config['emupso']['n_runs']} eMuPSO runs "
        f"of {config['emupso']['n_particles']} particles x {config['emupso']['maxiter']} "
        f"iterations, G = {config['emupso']['stagnation']}",
        f"- Measurement noise: torque std {config['measurement']['torque_noise_std']} N*m, "
        f"encoder {config['measurement']['encoder_counts_per_rev'] or 'exact'}",
    ]
    if state.get("wall_time_s") is not None:
        md.append(f"- Wall time: {state['wall_time_s']:.1f} s (started {state.get('started_at')})")
    if has_replay:
        md.append("- Motion replay: [replay.html](replay.html) (opens offline in a browser)")
    else:
        md.append("- Motion replay: not available (see run.json / the run's output)")
    md += ["- Data: `result.json`, `trajectory.csv`, `elites/`, `config.yaml`, `robot.urdf`", ""]

    md += _base_section(stage) if stage else []
    md += _optimization_section(data, figures)
    md += _elites_section(data, stage)
    if data["elites"] and stage:
        md += _identification_section(data, stage, figures)
    md += [
        "## Configuration snapshot",
        "",
        "```",
        yaml.safe_dump(config, sort_keys=False).rstrip(),
        "```",
        "",
    ]
    return "\n".join(md)


def _count_row(label: str, c: dict[str, int]) -> list[str]:
    return [label, str(c["independent"]), str(c["dependent"]), str(c["unidentifiable"])]


def _base_section(stage: dict[str, Any]) -> list[str]:
    c = stage["counts"]
    dh = stage.get("dh_frames")
    md = ["## Base parameters of the stage", ""]
    paper = stage.get("paper_counts")
    rows = [_count_row("this run, body frames (the estimate)", c)]
    if dh:
        rows.append(_count_row("this run, DH frames (the paper's frames)", dh["counts"]))
    if paper:
        rows.append(_count_row("paper (its 6R robot, DH frames)", paper))
    md += _table(["", "independent", "in linear combination", "unidentifiable"], rows)
    method = {"qr": "QR with column pivoting", "sequential": "the paper's sequential rank test"}
    md += [
        f"Reduction: {method.get(stage['base_method'], stage['base_method'])} on column-"
        "normalized random states of the stage's motion (structural); "
        f"{len(stage['base_names'])} base parameters. Torque rows: joints "
        f"{', '.join(str(r + 1) for r in stage['torque_rows'])}; {stage['known_bodies']}.",
        "",
        "**Frames.** The estimate uses parameters about Pinocchio's body (joint) frames, the "
        "project's convention (the URDF's inertials). Which *named* parameters are "
        "unidentifiable or combined depends on the frames (the rank does not); the paper's "
        "names are about its DH frames, so "
        + (
            "the comparison with the paper below uses the same random states with the "
            "regressor in DH frames (`W @ Robot.dh_to_model_parameters()`), columns in the "
            "paper's eq. 14 order, reduced by the paper's sequential rank test."
            if dh
            else "names cannot be compared with the paper's here: the robot has no DH table "
            "(loaded from a URDF)."
        ),
        "",
    ]
    if paper:
        md += [PAPER_COUNTS_NOTE, ""]
    md += [
        "### The estimate's base parameters (body frames)",
        "",
        f"- Unidentifiable: {', '.join(stage['unidentifiable']) or 'none'}",
        f"- In linear combination: {', '.join(stage['dependent']) or 'none'}",
        "",
    ]
    md += _expression_table(stage, "body frames, SI")
    if dh:
        md += _dh_section(stage, dh)
    return md


def _expression_table(entry: dict[str, Any], what: str) -> list[str]:
    return _table(
        ["base parameter", f"expression ({what})", "true value"],
        [
            [f"`{n}`", f"`{e}`", _fmt(t)]
            for n, e, t in zip(
                entry["base_names"], entry["base_expressions"], entry["true_base"], strict=True
            )
        ],
        left=(1,),
    )


def _dh_section(stage: dict[str, Any], dh: dict[str, Any]) -> list[str]:
    md = [
        "### Comparison with the paper (DH frames)",
        "",
        f"- Independent ({len(dh['independent'])}): {', '.join(dh['independent']) or 'none'}",
        f"- In linear combination ({len(dh['dependent'])}): {', '.join(dh['dependent']) or 'none'}",
        f"- Unidentifiable ({len(dh['unidentifiable'])}): "
        f"{', '.join(dh['unidentifiable']) or 'none'}",
        "",
    ]
    md += _expression_table(dh, "DH frames, SI")
    comparison = stage.get("paper_comparison")
    if not comparison:
        return md
    classes = ["independent", "dependent", "unidentifiable"]
    present = {p for row in comparison for p in row["paper"]}
    order = ("independent", "dependent", "identified", "not listed")
    paper_classes = [p for p in order if p in present]
    rows = []
    for pc in paper_classes:
        members = [r for r in comparison if pc in r["paper"]]
        rows.append(
            [
                f"paper: {_CLASS_LABEL.get(pc, pc)} ({len(members)})",
                *[
                    ", ".join(r["name"] for r in members if r["dh"] == cls) or "—"
                    for cls in classes
                ],
            ]
        )
    md += [
        "Where the paper's names fall in our DH-frame classes (the paper's lists of section "
        "4.1; `mx5` read as mcx5, `mm` as m; parameters the paper does not list are its "
        "unidentifiable ones, which it does not name). Which member of a combination is "
        "called independent depends on the column order and the method, so compare "
        "independent + in combination (identified) against unidentifiable first:",
        "",
    ]
    md += _table(
        ["", "ours: independent", "ours: in combination", "ours: unidentifiable"],
        rows,
        left=(0, 1, 2, 3),
    )
    if stage["name"] == "wrist":
        md += [
            "The paper lists Iyz6 both as independent and in combination and does not list "
            "Ixy6 (21 distinct names for 22 identified parameters): one of the two Iyz6 is "
            "probably Ixy6.",
            "",
        ]
    md += [
        "Per parameter (paper / ours in DH frames / ours in body frames, where the estimate's "
        "names can differ only because of the frames):",
        "",
    ]
    md += _table(
        ["parameter", "paper", "ours, DH frames", "ours, body frames"],
        [
            [
                f"`{r['name']}`",
                " and ".join(_CLASS_LABEL.get(p, p) for p in r["paper"]),
                _CLASS_LABEL.get(r["dh"], str(r["dh"])),
                _CLASS_LABEL.get(r["body"], r["body"]),
            ]
            for r in comparison
        ],
        left=(0, 1, 2, 3),
    )
    md += [
        'docs/paper-notes.md ("Base parameters of the paper\'s stages") explains each difference.',
        "",
    ]
    return md


def _optimization_section(data: dict[str, Any], figures: set[str] | frozenset[str]) -> list[str]:
    md = ["## Optimization", ""]
    ie = data["initial_elites"]
    n_elites = 0 if ie["x"] is None else len(ie["x"])
    md += [f"Initial elites: {n_elites} ({ie['message'] or 'not run'}).", ""]
    runs = data["optimization"]["runs"]
    if runs:
        md += _table(
            ["run", "best fitness", "iterations", "evaluations", "mutations at", "end"],
            [
                [
                    str(r["index"] + 1),
                    _fmt(r["best_fitness"]),
                    str(r["nit"]),
                    str(r["nfev"]),
                    ", ".join(str(i) for i in r["mutation_iterations"]) or "—",
                    r["message"],
                ]
                for r in runs
            ],
        )
    else:
        md += ["No eMuPSO run finished.", ""]
    if "figures/convergence.png" in figures:
        md += [
            "![Convergence: best fitness per iteration, all runs and their mean]"
            "(figures/convergence.png)",
            "",
        ]
    return md


def _elites_section(data: dict[str, Any], stage: dict[str, Any] | None) -> list[str]:
    elites = data["elites"]
    md = ["## Elite trajectories (like the paper's Tables 2-3)", ""]
    if not elites:
        return md + ["No elite trajectory was identified.", ""]
    md += [
        "Elites are the best distinct feasible members of all runs' archives, best fitness "
        "first; elite 1 is the chosen trajectory. Condition numbers: of the scaled base "
        "observation matrix the objective uses (eq. 15), and of the SI base matrix of the "
        "estimate. Error sums: sums of the relative errors [%] of all base parameters with a "
        "non-zero true value (Error(all), the paper's Error(22)), over the parameters that explain "
        "at least 1e-4 of the stage's torques (Error(share >= 1e-4)) and without the two "
        "largest (Error(all-2), the paper's Error(20)). Major parameters: those that explain "
        "at least 1 % of the stage's torques when the robot moves at full capability (random "
        "states within the limits; the same set for every trajectory of the stage, see "
        "`reference_torque_share` in result.json).",
        "",
    ]
    excitation = data["config"]["excitation"]
    if excitation["family"].startswith("paper_"):
        unit = excitation.get("options", {}).get("length_unit", 1e-3)
        what = "mm" if unit == 1e-3 else f"units of {unit:g} m"
        md += [
            f"Design variables as in Tables 2-3: a0, d0, e0, f0 in {what}; b0, c0 in {what} "
            "per second.",
            "",
        ]
    elif excitation["family"] == "joint_fourier":
        md += [
            "Design variables of the joint-space Fourier series (docs/excitation.md): q0 "
            "(mean position) in rad, the a, b coefficients of harmonics 2..N in rad/s "
            "(harmonic 1 follows from rest at both ends).",
            "",
        ]
    names = data["excitation"]["variable_names"]
    header = ["", *[f"elite {e['rank']}" for e in elites]]
    rows = [[f"`{n}`", *[_fmt(e["x"][i]) for e in elites]] for i, n in enumerate(names)]
    rows.append(["fitness", *[_fmt(e["fitness"]) for e in elites]])
    rows.append(["cond (scaled, objective)", *[_fmt(e["objective"].get("cond")) for e in elites]])
    methods = list(data["config"]["estimation"]["methods"])
    for m in methods:
        rows.append(
            [
                f"cond (SI, {m})",
                *[_fmt(e["estimates"].get(m, {}).get("condition_number")) for e in elites],
            ]
        )
    for m in methods:
        rows.append(
            [
                f"Error(all) {m} [%]",
                *[_fmt(e["estimates"].get(m, {}).get("error_sum_percent")) for e in elites],
            ]
        )
        rows.append(
            [
                f"Error(share >= 1e-4) {m} [%]",
                *[
                    _fmt(e["estimates"].get(m, {}).get("error_sum_significant_percent"))
                    for e in elites
                ],
            ]
        )
        rows.append(
            [
                f"max rel. error, major parameters, {m}",
                *[_fmt(e["estimates"].get(m, {}).get("max_rel_error_major")) for e in elites],
            ]
        )
        rows.append(
            [
                f"Error(all-2) {m} [%]",
                *[_fmt(e["estimates"].get(m, {}).get("error_sum_best_percent")) for e in elites],
            ]
        )
    md += _table(header, rows)
    for e in elites:
        for m, message in e["failures"].items():
            md += [f"> **Elite {e['rank']}, {m}**: {message}", ""]
    return md


def _identification_section(
    data: dict[str, Any], stage: dict[str, Any], figures: set[str] | frozenset[str]
) -> list[str]:
    elite = data["elites"][0]
    md = ["## Identified vs true parameters (elite 1)", ""]
    if "figures/trajectory.png" in figures:
        md += [
            "![Excitation trajectory of elite 1: Cartesian path, joint positions and "
            "velocities with limits](figures/trajectory.png)",
            "",
        ]
    if not elite["estimates"]:
        return md + ["> **No estimate**: every estimator failed on this trajectory (above).", ""]
    true = stage["true_base"]
    for m, est in elite["estimates"].items():
        md += [
            f"### {m.upper()}",
            "",
            f"Residual: relative {_fmt(est['relative_residual'])}, RMS per joint "
            f"{', '.join(_fmt(v) for v in est['residual_rms'])} N*m; condition number "
            f"{_fmt(est['condition_number'])}; {100 * (est['within_3std'] or 0):.0f} % of the "
            f"errors within 3 std; largest torque error {_fmt(est.get('max_torque_error'))}, "
            f"largest relative error of the parameters with a torque share >= 1e-4 "
            f"{_fmt(est.get('max_rel_error'))}; largest relative error of the stage's major "
            f"parameters (reference torque share >= {MAJOR_SHARE:g}) "
            f"{_fmt(est.get('max_rel_error_major'))}. "
            f"{'' if est['message'] == 'ok' else est['message']}",
            "",
        ]
        rows = []
        share = est.get("torque_share") or [None] * len(stage["base_names"])
        for i, name in enumerate(stage["base_names"]):
            rows.append(
                [
                    f"`{name}`" + (" (alone)" if stage["identifiable_alone"][i] else ""),
                    _fmt(true[i]),
                    _fmt(est["x"][i]),
                    _fmt(est["std"][i]),
                    _fmt(est["abs_error"][i]),
                    _fmt(est["rel_error_percent"][i]),
                    _fmt(est["normalized_error"][i], 3),
                    _fmt(share[i], 2),
                ]
            )
        md += _table(
            [
                "base parameter",
                "true",
                "identified",
                "std",
                "error",
                "rel. error [%]",
                "error / std",
                "torque share",
            ],
            rows,
        )
    alone = [i for i, a in enumerate(stage["identifiable_alone"]) if a]
    if alone:
        md += ["### Standard parameters identifiable alone", ""]
        rows = []
        for i in alone:
            cells = [f"`{stage['base_names'][i]}`", _fmt(true[i])]
            for est in elite["estimates"].values():
                cells += [_fmt(est["x"][i]), _fmt(est["std"][i]), _fmt(est["rel_error_percent"][i])]
            rows.append(cells)
        header = ["parameter", "true"]
        for m in elite["estimates"]:
            header += [f"{m} identified", f"{m} std", f"{m} rel. error [%]"]
        md += _table(header, rows)
    md += [
        "Parameters marked *(alone)* are standard parameters identifiable alone (no other "
        "parameter is combined into them): their row is also their standard-parameter "
        "estimate. A relative error is shown as — where the true value is zero up to "
        "round-off. Torque share: the part of the stage's torques the parameter explains on "
        "this trajectory; a parameter with a tiny share is barely observable, whatever the "
        "estimator.",
        "",
    ]
    if "figures/estimate.png" in figures:
        md += ["![Errors in standard deviations](figures/estimate.png)", ""]
    return md
