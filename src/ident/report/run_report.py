"""The report of an ``ident run`` folder, written from its saved data only.

:func:`write_report` reads ``result.json`` (:mod:`ident.report.run_data`) and writes
``figures/*.png``, ``report.md`` and ``report.html`` (figures embedded); ``ident report
RUN_DIR`` calls it, so a report can always be regenerated from the saved data.

Order of the report: the headline block (:mod:`ident.report.headline`: verdict, worst error
of the major parameters, torque residual, condition number, checks, warnings), the plots
(identified vs true with ±3σ bars; measured vs predicted torque on the validation
trajectory when the run has one), the parameter table with units and σ [%], the comparison
with the paper (Tables 2-3 side by side, base-parameter counts), then the details
(procedure, optimization, elites, base-parameter expressions, configuration). Every number
comes from ``result.json``; the measures are computed by :mod:`ident.identify.assessment.metrics`
when the run is saved.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ident.fileio import atomic_write_bytes, atomic_write_text
from ident.identify.assessment.metrics import MAJOR_SHARE, error_measures, parameter_unit
from ident.identify.assessment.rollout import rollout_text
from ident.identify.assessment.verdict import VERDICT_RULE, VERDICT_RULE_REAL, Verdict
from ident.identify.refinement.rollout_refinement import refinement_text
from ident.report.format import fmt as _fmt
from ident.report.format import pct, percent
from ident.report.format import table as _table
from ident.report.headline import NOT_CHECKED, Headline, headline_markdown
from ident.report.model_section import model_section
from ident.report.paper import _base_section, _dh_section, paper_box_note, paper_tables_section
from ident.report.run_data import FORMAT, load_run, result_to_dict, save_run, write_replay
from ident.report.run_verdict import executed_elite, headline_method, stored_verdict
from ident.report.safety_section import safety_figures, safety_headline, safety_section
from ident.trajectory import read_trajectory_csv

__all__ = [
    "FORMAT",
    "error_measures",
    "render_markdown",
    "result_to_dict",
    "save_run",
    "write_replay",
    "write_report",
]


def _figures(run_dir: Path, data: dict[str, Any]) -> dict[str, bytes]:
    """The report's figures {relative path: PNG bytes} from the run folder and result.json."""
    from ident.report.plots import convergence_png, torque_png

    figures: dict[str, bytes] = {}
    runs = data["optimization"]["runs"]
    stage_name = data.get("stage", {}).get("name", "")
    histories = [
        np.array([np.nan if v is None else v for v in r["history"]], dtype=float) for r in runs
    ]
    figures["figures/convergence.png"] = convergence_png(
        histories,
        title=f"Convergence of {optimizer_name(data)} ({stage_name} stage): all runs and their "
        "mean",
        mutations=[r["mutation_iterations"] for r in runs],
    )
    traj_path = run_dir / "trajectory.csv"
    elite = executed_elite(data)
    if elite is not None and traj_path.is_file():
        figures["figures/trajectory.png"] = _trajectory_figure(run_dir, data, elite, stage_name)
        if elite["estimates"] and "stage" in data:
            figures.update(_estimate_figures(data, elite))
    figures.update(safety_figures(data))
    val_path = run_dir / "validation.csv"
    if val_path.is_file():
        figures["figures/validation.png"] = _validation_png(val_path, torque_png)
    return figures


def _trajectory_figure(
    run_dir: Path, data: dict[str, Any], elite: dict[str, Any], stage_name: str
) -> bytes:
    """Executed trajectory of the moving joints (trajectory.csv) with their limits, and the
    elite's Cartesian path when its CSV exists."""
    from ident.report.plots import trajectory_png

    traj = read_trajectory_csv(run_dir / "trajectory.csv")
    moving = data["excitation"]["moving_joints"] or list(range(len(traj.joint_names)))
    robot = data["robot"]
    q_lim = np.array(
        [[np.inf if v is None else v for v in row] for row in robot["q_limits"]], dtype=float
    )
    dq_lim = np.array([np.inf if v is None else v for v in robot["dq_limits"]], dtype=float)
    path = None
    path_csv = elite.get("path_csv")
    if path_csv and (run_dir / path_csv).is_file():
        path = np.loadtxt(run_dir / path_csv, delimiter=",", skiprows=1, ndmin=2)[:, 1:4]
    return trajectory_png(
        traj.t,
        traj.q[:, moving],
        traj.dq[:, moving],
        [traj.joint_names[j] for j in moving],
        q_limits=q_lim[moving],
        dq_limits=dq_lim[moving],
        path=path,
        title=f"Executed trajectory, elite {elite['rank']} ({stage_name} stage)",
    )


def _estimate_figures(data: dict[str, Any], elite: dict[str, Any]) -> dict[str, bytes]:
    """The elite's estimation errors in σ per estimator, and the headline estimator's
    identified vs true base parameters."""
    from ident.report.plots import estimate_png, parameters_png

    rank, estimates = elite["rank"], elite["estimates"]
    true = np.array(data["stage"]["true_base"], dtype=float)
    figures = {
        "figures/estimate.png": estimate_png(
            data["stage"]["base_names"],
            true,
            {
                m: (np.array(e["x"], dtype=float), np.array(e["std"], dtype=float))
                for m, e in estimates.items()
            },
            title=f"Elite {rank}: (identified - true) / std per base parameter",
        )
    }
    method = headline_method(elite)
    est = estimates[method]
    figures["figures/parameters.png"] = parameters_png(
        data["stage"]["base_names"],
        np.array([np.nan if v is None else v for v in est["x"]], dtype=float),
        np.array([np.nan if v is None else v for v in est["std"]], dtype=float),
        true,
        highlight=est.get("major"),
        include=est.get("significant"),
        title=f"Elite {rank}, {(method or '').upper()}: identified vs true",
    )
    return figures


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
        md += [f"No {optimizer_name(data)} run finished.", ""]
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
        f"first; elite {data.get('executed_elite') or 1} is the executed trajectory (the best "
        "that passed the safety check, in trajectory.csv). Condition numbers: of the scaled base "
        "observation matrix the objective uses (eq. 15), and of the SI base matrix of the "
        "estimate. Error sums: sums of the relative errors [%] of all base parameters with a "
        "non-zero true value (Error(all), the paper's Error(22)), over the parameters that explain "
        "at least 1e-4 of the stage's torques (Error(share >= 1e-4)) and without the two "
        "largest (Error(all-2), the paper's Error(20)). Major parameters: those that explain "
        "at least 1 % of the stage's torques when the robot moves at full capability (random "
        "states within the position, velocity and acceleration limits; the same set for "
        "every trajectory of the stage, see "
        "`reference_torque_share` in result.json).",
        "",
    ]
    md += _design_variable_note(data["config"]["excitation"])
    header = ["", *[f"elite {e['rank']}" for e in elites]]
    md += _table(header, _elite_rows(data))
    for e in elites:
        for m, message in e["failures"].items():
            md += [f"> **Elite {e['rank']}, {m}**: {message}", ""]
    return md


def _design_variable_note(excitation: dict[str, Any]) -> list[str]:
    """Units of the design variables of the paper's and the joint Fourier families."""
    if excitation["family"].startswith("paper_"):
        unit = excitation.get("options", {}).get("length_unit", 1e-3)
        what = "mm" if unit == 1e-3 else f"units of {unit:g} m"
        return [
            f"Design variables as in Tables 2-3: a0, d0, e0, f0 in {what}; b0, c0 in {what} "
            "per second.",
            "",
        ]
    if excitation["family"] == "joint_fourier":
        return [
            "Design variables of the joint-space Fourier series (docs/excitation.md): q0 "
            "(mean position) in rad, the a, b coefficients of harmonics 2..N in rad/s "
            "(harmonic 1 follows from rest at both ends).",
            "",
        ]
    return []


def _elite_rows(data: dict[str, Any]) -> list[list[str]]:
    """Rows of the elite table: design variables, fitness, then per estimator the condition
    numbers and error sums (one column per elite)."""
    elites = data["elites"]
    names = data["excitation"]["variable_names"]
    rows = [[f"`{n}`", *[_fmt(e["x"][i]) for e in elites]] for i, n in enumerate(names)]
    rows.append(["fitness", *[_fmt(e["fitness"]) for e in elites]])
    rows.append(["cond (scaled, objective)", *[_fmt(e["objective"].get("cond")) for e in elites]])
    methods = list(data["config"]["estimation"]["methods"])

    def row(label: str, method: str, key: str, scale: Any = None) -> list[str]:
        values = [e["estimates"].get(method, {}).get(key) for e in elites]
        return [label, *[_fmt(v if scale is None else scale(v)) for v in values]]

    for m in methods:
        rows.append(row(f"cond (SI, {m})", m, "condition_number"))
    for m in methods:
        rows.append(row(f"Error(all) {m} [%]", m, "error_sum_percent"))
        rows.append(row(f"Error(share >= 1e-4) {m} [%]", m, "error_sum_significant_percent"))
        rows.append(
            row(f"max rel. error, major parameters, {m} [%]", m, "max_rel_error_major", percent)
        )
        rows.append(row(f"Error(all-2) {m} [%]", m, "error_sum_best_percent"))
    return rows


# ----------------------------------------------------------------------------- page


def optimizer_name(data: dict[str, Any]) -> str:
    """The configured optimizer as the reports name it (``eMuPSO`` for ``emupso``)."""
    name = str(data.get("config", {}).get("optimizer", "emupso"))
    return "eMuPSO" if name == "emupso" else name.upper() if len(name) <= 4 else name


def evaluation_budget(data: dict[str, Any]) -> str:
    """The optimizer's evaluation budget of the run's config, as the reports and the terminal
    print it: ``runs x populations x particles = evaluations`` (a run evaluates its initial
    population, then one per iteration)."""
    o = data.get("config", {}).get("emupso", {})
    runs, iterations, particles = int(o["n_runs"]), int(o["maxiter"]), int(o["n_particles"])
    return (
        f"{runs} run(s) x {iterations + 1} populations (initial + {iterations} iterations) x "
        f"{particles} particles = {runs * (iterations + 1) * particles} evaluations"
    )


def _check_text(entry: Any) -> str:
    """A consistency / safety entry of result.json as text (``not checked`` when absent)."""
    if entry is None:
        return NOT_CHECKED
    if isinstance(entry, str):
        return entry
    if isinstance(entry, dict):
        ok = entry.get("ok", entry.get("consistent", entry.get("safe")))
        note = entry.get("message") or entry.get("summary") or ""
        state = "ok" if ok else "**violated**" if ok is not None else ""
        not_run = len(entry.get("checks_not_run") or [])
        if ok and not_run:  # never "ok" while a limit it needed was unknown
            state = f"{not_run} check{'s' if not_run != 1 else ''} not run"
        return ", ".join(s for s in (state, note) if s) or json.dumps(entry)[:200]
    return str(entry)


def _safety_text(data: dict[str, Any]) -> str:
    """The headline's safety line: the run's verdict, the executed elite, its clearance."""
    text = _check_text(data.get("safety"))
    executed = safety_headline(data)
    if executed is None:
        return text
    if text == NOT_CHECKED:
        return executed
    safety = data.get("safety")
    entry: dict[str, Any] = safety if isinstance(safety, dict) else {}
    ok = entry.get("ok")
    state = "ok" if ok else "**violated**" if ok is not None else text
    not_run = len(entry.get("checks_not_run") or [])
    if ok and not_run:  # never "ok" while a limit it needed was unknown
        plural = "s" if not_run != 1 else ""
        state = f"checked constraints hold, **{not_run} check{plural} not run**"
    return f"{state}: {executed}"


def _consistency_text(data: dict[str, Any], v: dict[str, Any]) -> str:
    """The headline's consistency line: the verdict's link count, else result.json's entry."""
    if v.get("n_links"):
        n_bad = int(v.get("n_inconsistent") or 0)
        text = (
            f"{v.get('method') or ''}: {v['n_links'] - n_bad} of {v['n_links']} links "
            "physically consistent"
        )
        return text if n_bad == 0 else f"**violated**, {text}"
    return _check_text(data.get("consistency"))


def _residual_text(v: dict[str, Any]) -> tuple[str, str]:
    """(label, text) of the headline's residual row, from the verdict's evidence."""
    where = v.get("residual_where") or ""
    residual = v.get("residual")
    text = pct(None if residual is None else 100 * residual)
    if where == "validation trajectory":
        return "Torque residual, validation trajectory", (
            text + " (a second trajectory, not used to identify)"
        )
    if where == "held-out data":
        nominal = v.get("nominal_residual")
        extra = "" if nominal is None else f"; URDF nominal {pct(100 * nominal)}"
        return "Torque residual, held-out data", (
            text + f" (the last part of the simulated log, not used to identify{extra})"
        )
    return "Torque residual, identification trajectory", (
        text + " (no validation trajectory in this run)"
    )


def _headline(data: dict[str, Any], stage: dict[str, Any] | None) -> Headline:
    v = stored_verdict(data)
    elite = executed_elite(data)
    method = v.get("method")
    est = elite["estimates"][method] if elite and method in elite["estimates"] else {}
    names = stage["base_names"] if stage else []
    worst = pct(v.get("worst_error_percent"))
    if v.get("worst_error_name"):
        n_major = sum(est.get("major") or [])
        worst += f" ({v['worst_error_name']}; {n_major} major parameters of {len(names)})"
    residual_label, residual_text = _residual_text(v)
    cond = "—"
    if elite:
        cond = (
            f"{_fmt(est.get('condition_number'))} (SI base matrix, {(method or '').upper()}); "
            f"{_fmt(elite['objective'].get('cond'))} (scaled, the excitation objective)"
        )
    extra = _headline_rows(data, v, elite, est, names)
    return Headline(
        verdict=Verdict(v["label"], v["reason"], v.get("rule", "truth")),
        rule=VERDICT_RULE if v.get("rule", "truth") == "truth" else VERDICT_RULE_REAL,
        worst=worst,
        worst_label="Worst error, major parameters",
        residual=residual_text,
        residual_label=residual_label,
        condition=cond,
        consistency=_consistency_text(data, v),
        safety=_safety_text(data),
        warnings=list(v.get("warnings") or []),
        extra=[(k, v) for k, v in extra],
    )


def _headline_rows(
    data: dict[str, Any],
    v: dict[str, Any],
    elite: dict[str, Any] | None,
    est: dict[str, Any],
    names: list[str],
) -> list[list[str]]:
    """The headline's extra rows: paper's box, optimizer, estimate, worst relative std,
    estimator note; ``v`` the stored verdict, ``est`` its estimator's entry of the elite."""
    method = v.get("method")
    configured = data["config"].get("optimizer")
    box = paper_box_note(data)
    extra = [["Paper's box", box]] if box else []
    extra += [
        [
            "Optimizer",
            optimizer_name(data) + (f" (config `optimizer: {configured}`)" if configured else ""),
        ]
    ]
    if method and elite:
        extra.append(
            [
                "Estimate",
                f"{method.upper()} on elite {elite['rank']} (fitness {_fmt(elite['fitness'])}), "
                f"{len(names)} base parameters, "
                f"{100 * (est.get('within_3std') or 0):.0f} % within 3σ of the true value "
                f"({est.get('std_method') or 'ordinary'} σ)"
                + (
                    f", {100 * est['within_95_interval']:.0f} % inside their 95 % interval "
                    f"({est['interval_method']}, docs/uncertainty.md)"
                    if est.get("within_95_interval") is not None
                    else ""
                ),
            ]
        )
    if v.get("worst_std_percent") is not None:
        extra.append(
            [
                "Worst relative std, torque-carrying parameters",
                f"σ {pct(v['worst_std_percent'])} ({v.get('worst_std_name')}; "
                f"{v.get('std_method') or 'ordinary'} σ)",
            ]
        )
    if est and est.get("message") not in (None, "ok"):
        extra.append(["Estimator note", str(est["message"])])
    extra.append(["MJCF rollout", rollout_text(data.get("rollout"))])  # or why not run
    refined = refinement_text(data.get("refinement"))  # None: not asked for
    if refined is not None:
        extra.append(["MJCF refinement", refined])
    return extra


def render_markdown(
    data: dict[str, Any],
    *,
    figures: set[str] | frozenset[str] = frozenset(),
    run_state: dict[str, Any] | None = None,
    has_replay: bool = False,
) -> str:
    """The report text (Markdown) from the content of ``result.json``."""
    config = data["config"]
    stage = data.get("stage")
    stage_name = stage["name"] if stage else config["stage"]
    md = _run_title(data, stage_name, has_replay)
    if data["status"] == "incomplete":  # "running": the folder is being written
        md += [f"> **Incomplete run**: {data['message']}. Only what finished is reported.", ""]
    md += headline_markdown(_headline(data, stage))
    if data["elites"] and stage:
        md += _parameter_section(data, stage, figures)
    else:
        md += ["No elite trajectory was identified.", ""]
    md += _paper_comparison(data, stage)
    md += _base_section(stage) if stage else []
    if data.get("model") is not None:  # a simulated log's identification: the model files
        md += model_section(
            data["model"], where=f" of elite {data['model']['elite']}'s simulated log"
        )
    md += ["## Details", ""]
    md += _run_facts(data, run_state or {})
    if "figures/trajectory.png" in figures:
        md += [
            "![Executed trajectory: Cartesian path, joint positions and "
            "velocities with limits](figures/trajectory.png)",
            "",
        ]
    md += safety_section(data, figures)
    md += _optimization_section(data, figures)
    md += _elites_section(data, stage)
    if data["elites"] and stage:
        md += _alone_section(data, stage, figures)
    if stage and stage.get("dh_frames"):
        md += _dh_section(stage, stage["dh_frames"])
    md += [
        "## Configuration snapshot",
        "",
        "```",
        yaml.safe_dump(config, sort_keys=False).rstrip(),
        "```",
        "",
    ]
    return "\n".join(md)


def _run_title(data: dict[str, Any], stage_name: str, has_replay: bool) -> list[str]:
    """Title and the paragraph naming the robot, stage, excitation, seed, noise and replay."""
    config = data["config"]
    return [
        f"# ident run: {data.get('name')} ({stage_name} stage)",
        "",
        f"Robot `{data['robot']['name']}`, {stage_name} stage, excitation "
        f"`{config['excitation']['family']}`, seed {data['seed']}, simulated torques with noise "
        f"std {config['measurement']['torque_noise_std']} N*m. "
        + (
            "Motion replay: [replay.html](replay.html)."
            if has_replay
            else "Motion replay: not available (see run.json)."
        ),
        "",
    ]


def _paper_comparison(data: dict[str, Any], stage: dict[str, Any] | None) -> list[str]:
    """The paper's Tables 2-3 next to ours, for the paper's wrist and arm stages."""
    md = ["## Comparison with the paper", ""]
    if stage and stage["name"] in ("wrist", "arm"):
        return md + paper_tables_section(data, headline_method(executed_elite(data)))
    return md + ["This stage is not one of the paper's (wrist, arm): Tables 2-3 do not apply.", ""]


def _run_facts(data: dict[str, Any], state: dict[str, Any]) -> list[str]:
    config = data["config"]
    md = [
        f"- Robot: `{data['robot']['name']}` ({len(data['robot']['joint_names'])} joints), "
        f"config `{config['robot']}`",
        f"- Excitation family `{config['excitation']['family']}`, criterion "
        f"`{config['excitation']['criterion']}`, {config['excitation']['n_samples']} samples "
        "per period",
        f"- Seed: **{data['seed']}**",
        f"- Procedure: initial elites ({config['elites']['n_particles']} particles until "
        f"{config['elites']['n_elites']} elites), then {config['emupso']['n_runs']} "
        f"{optimizer_name(data)} runs "
        f"of {config['emupso']['n_particles']} particles x {config['emupso']['maxiter']} "
        f"iterations, G = {config['emupso']['stagnation']}; budget {evaluation_budget(data)}",
        f"- Measurement noise: torque std {config['measurement']['torque_noise_std']} N*m, "
        f"encoder {config['measurement']['encoder_counts_per_rev'] or 'exact'}",
    ]
    traced = data["excitation"].get("traced_frame")
    if traced:
        md.append(f"- Traced point (path plot and replay): frame `{traced}`")
    if state.get("wall_time_s") is not None:
        md.append(f"- Wall time: {state['wall_time_s']:.1f} s (started {state.get('started_at')})")
    md += ["- Data: `result.json`, `trajectory.csv`, `elites/`, `config.yaml`, `robot.urdf`"]
    if state.get("exports"):  # controller files (docs/execute.md), written by ident run
        md.append("- Exports (`docs/execute.md`): " + "; ".join(map(str, state["exports"])))
    if state.get("export_limits"):  # limits the export targets tightened (docs/execute.md)
        md.append("- Limits tightened by the export targets: " + "; ".join(state["export_limits"]))
    md += [""]
    return md


def _parameter_section(
    data: dict[str, Any], stage: dict[str, Any], figures: set[str] | frozenset[str]
) -> list[str]:
    elite = executed_elite(data) or data["elites"][0]
    md = [f"## Identified vs true parameters (elite {elite['rank']}, executed)", ""]
    md += _held_out_summary(data)
    md += _parameter_figures(figures)
    if not elite["estimates"]:
        return md + ["> **No estimate**: every estimator failed on this trajectory (below).", ""]
    # residuals per torque row of the stage; older result.json files have no joint units
    all_units = data["robot"].get("joint_units") or ["N*m"] * len(data["robot"]["joint_names"])
    units = [all_units[r] for r in stage["torque_rows"]]
    for m, est in elite["estimates"].items():
        md += _estimate_summary(m, est, units)
        md += _table(
            [
                "base parameter",
                "unit",
                "true",
                "identified",
                "σ",
                "σ [%]",
                "error [%]",
                "error / σ",
                "torque share [%]",
                "major",
            ],
            _estimate_rows(est, stage),
            left=(0, 1, 9),
        )
    return md + _parameter_legend()


def _held_out_summary(data: dict[str, Any]) -> list[str]:
    """The verdict's residual, consistency and worst σ of a simulated log identified as a real
    one (empty otherwise)."""
    v = stored_verdict(data)
    if v.get("residual_where") != "held-out data" or v.get("residual") is None:
        return []
    label, text = _residual_text(v)
    return [
        f"{label}: {text}. Physical consistency: {_consistency_text(data, v)}. Worst "
        f"relative std of the parameters carrying >= {100 * MAJOR_SHARE:g} % of the "
        f"torques: {pct(v.get('worst_std_percent'))} ({v.get('worst_std_name')}; "
        f"{v.get('std_method') or 'ordinary'} σ).",
        "",
    ]


def _parameter_figures(figures: set[str] | frozenset[str]) -> list[str]:
    """The parameter and validation figures of the section (a note when no validation)."""
    md = []
    if "figures/parameters.png" in figures:
        md += [
            "![Identified vs true base parameters, relative deviation with ±3σ bars]"
            "(figures/parameters.png)",
            "",
        ]
    if "figures/validation.png" in figures:
        md += [
            "![Measured vs predicted torque on the validation trajectory](figures/validation.png)",
            "",
        ]
    else:
        md += [
            "Measured vs predicted torque on a validation trajectory: this run has no "
            "validation trajectory.",
            "",
        ]
    return md


def _estimate_summary(method: str, est: dict[str, Any], units: list[str]) -> list[str]:
    """Heading and one-paragraph fit summary of one estimator (residuals in joint ``units``)."""
    rms = zip(est["residual_rms"], units, strict=True)
    return [
        f"### {method.upper()}",
        "",
        f"Relative residual {pct(100 * (est['relative_residual'] or 0))}, RMS per joint "
        f"{', '.join(f'{_fmt(v)} {u}' for v, u in rms)}; condition number "
        f"{_fmt(est['condition_number'])}; {100 * (est['within_3std'] or 0):.0f} % of the "
        f"errors within 3σ ({est.get('std_method') or 'ordinary'} σ). "
        f"{'' if est['message'] == 'ok' else est['message']}",
        "",
    ]


def _estimate_rows(est: dict[str, Any], stage: dict[str, Any]) -> list[list[str]]:
    """One table row per base parameter: true, identified, σ, errors, torque share."""
    true = stage["true_base"]
    names = stage["base_names"]
    major = est.get("major") or [False] * len(names)
    share = est.get("torque_share") or [None] * len(names)
    return [
        [
            f"`{name}`" + (" (alone)" if stage["identifiable_alone"][i] else ""),
            parameter_unit(name) or "—",
            _fmt(true[i]),
            _fmt(est["x"][i]),
            _fmt(est["std"][i]),
            _fmt(_rel_std(est, i), 3),
            _fmt(est["rel_error_percent"][i], 3),
            _fmt(est["normalized_error"][i], 3),
            _fmt(None if share[i] is None else 100 * share[i], 2),
            "yes" if major[i] else "",
        ]
        for i, name in enumerate(names)
    ]


def _parameter_legend() -> list[str]:
    """What the columns of the parameter tables mean."""
    return [
        "Units SI; a base parameter has the unit of the parameter it is named after. "
        "σ: standard deviation of the estimate (the moving-block bootstrap's on a simulated "
        "log, the ordinary one otherwise: the method is named above, docs/uncertainty.md); "
        "σ [%] = σ / |identified|. Error [%] = "
        "|identified - true| / |true|, shown as — where the true value is zero up to "
        f"round-off. Major: torque share >= {100 * MAJOR_SHARE:g} % on the stage's reference "
        "motion (the same set for every trajectory); torque share: the part of the stage's "
        "torques the parameter explains on this trajectory. *(alone)*: a standard parameter "
        "identifiable alone.",
        "",
    ]


def _rel_std(est: dict[str, Any], i: int) -> float | None:
    rel = est.get("relative_std_percent")
    if rel is not None:
        return rel[i]
    x, s = est["x"][i], est["std"][i]
    return None if x in (None, 0) or s is None else 100 * abs(s / x)


def _alone_section(
    data: dict[str, Any], stage: dict[str, Any], figures: set[str] | frozenset[str]
) -> list[str]:
    elite = executed_elite(data) or data["elites"][0]
    md: list[str] = []
    true = stage["true_base"]
    alone = [i for i, a in enumerate(stage["identifiable_alone"]) if a]
    if alone and elite["estimates"]:
        md += ["### Standard parameters identifiable alone", ""]
        rows = []
        for i in alone:
            name = stage["base_names"][i]
            cells = [f"`{name}`", parameter_unit(name) or "—", _fmt(true[i])]
            for est in elite["estimates"].values():
                cells += [_fmt(est["x"][i]), _fmt(est["std"][i]), _fmt(est["rel_error_percent"][i])]
            rows.append(cells)
        header = ["parameter", "unit", "true"]
        for m in elite["estimates"]:
            header += [f"{m} identified", f"{m} σ", f"{m} error [%]"]
        md += _table(header, rows, left=(0, 1))
    if "figures/estimate.png" in figures:
        md += ["![Errors in standard deviations](figures/estimate.png)", ""]
    return md


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
    data = load_run(run_dir)
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


def _validation_png(path: Path, torque_png: Any) -> bytes:
    """Measured vs predicted torque from ``validation.csv`` (t, tau_<joint>, <label>_<joint>)."""
    header = path.read_text(encoding="utf-8").splitlines()[0].split(",")
    values = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    measured = [k for k, h in enumerate(header) if h.startswith("tau_")]
    joints = [header[k][4:] for k in measured]
    labels = dict.fromkeys(
        h.rsplit("_", 1)[0] for h in header[1:] if not h.startswith("tau_") and "_" in h
    )
    predictions = {}
    for label in labels:
        cols = [header.index(f"{label}_{j}") for j in joints if f"{label}_{j}" in header]
        if len(cols) == len(joints):
            predictions[label] = values[:, cols]
    return torque_png(
        values[:, 0],
        values[:, measured],
        predictions,
        joints,
        xlabel="time [s] (validation trajectory, not used to identify)",
    )
