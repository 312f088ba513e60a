"""Report of ``ident identify``: report.md, report.html, result.json, parameters.csv, plots,
the identified model (URDF, MJCF, joint extras; :mod:`ident.identify.model_files.files`).

Everything is written into an existing run folder through atomic writes; the HTML page embeds
its figures (base64 PNG, readable offline). ``result.json`` holds no times, so the same config
gives the same file; timings go to ``run.json`` (the caller's run folder state).

This module writes the files; ``result.json``'s entries are assembled by
:mod:`ident.report.identify_result`, ``report.md``'s sections by
:mod:`ident.report.identify_sections`.
"""

from __future__ import annotations

import csv
import io
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ident.fileio import atomic_write_bytes, atomic_write_text
from ident.identify.assessment.metrics import parameter_unit
from ident.identify.assessment.rollout import identify_rollout
from ident.identify.model_files.files import save_identified_model
from ident.identify.model_files.urdf_update import UrdfUpdate, update_urdf_inertials
from ident.identify.pipeline.real import IdentifyResult
from ident.identify.refinement.rollout_refinement import refinement_entry
from ident.report.identify_result import (
    _robot_file,
    friction_models_entry,
    joint_torque_units,
    result_dict,
)
from ident.report.identify_sections import _markdown, friction_models_lines

__all__ = [
    "friction_models_entry",
    "friction_models_lines",
    "identified_urdf",
    "joint_torque_units",
    "result_dict",
    "save_identify_data",
    "torque_png",
    "write_identify_report",
    "write_measured_replay",
]

_PLOT_LABELS = ("identified", "reference")


def _urdf_text(result: IdentifyResult) -> str:
    """The URDF of the identified robot (the file's text; generated for a DH description)."""
    if result.config.robot.urdf is not None:
        return Path(result.config.robot.urdf).read_text(encoding="utf-8")
    from ident.model.selection import load_robot

    return str(load_robot(result.config.robot).urdf_text)


def torque_png(result: IdentifyResult) -> bytes:
    """Measured vs predicted torque per joint on the held-out part, as PNG bytes."""
    from ident.report.plots import torque_png as plot

    return plot(
        result.t_validate,
        result.tau_validate,
        {k: result.predictions[k].tau_pred for k in _PLOT_LABELS if k in result.predictions},
        result.joint_names,
        excluded=~result.keep_validate,
        xlabel="time [s] (held-out part; crosses: below the velocity threshold, not compared)",
        units=joint_torque_units(result),
    )


def identified_urdf(result: IdentifyResult) -> UrdfUpdate:
    """The cautious URDF copy (``urdf_update.cautious``, ``<urdf>_cautious.urdf``): the standard
    parameters that base parameters determine alone, where their relative std is below
    ``urdf_update.max_relative_std_pct`` and the link stays consistent. The relative std is
    the result's one standard deviation (:attr:`IdentifyResult.parameter_std`)."""
    pm = result.parameters
    est = result.estimate
    rel = result.parameter_std.relative_std  # the one σ (default interval method)
    identified = {}
    for k, i in enumerate(pm.base.independent):
        alone = not pm.base_names[k].endswith("R") and pm.inertial_index[i] >= 0
        if alone:
            identified[pm.names[i]] = (float(est.x[k]), float(rel[k]))
    from ident.dynamics.parameters import parameters_from_model
    from ident.model.selection import load_robot

    robot = load_robot(result.config.robot)  # the robot the identification used (chain, locks)
    return update_urdf_inertials(
        robot.urdf_text,
        result.joint_names,
        parameters_from_model(robot.model),
        identified,
        max_relative_std_pct=result.config.urdf_update.max_relative_std_pct,
        model=robot.model,  # its links fused through fixed and locked joints
    )


def write_measured_replay(
    result: IdentifyResult,
    folder: str | Path,
    *,
    replay: bool = True,
    package_dirs: Sequence[str | Path] = (),
) -> str:
    """Write the measured motion: ``trajectory.csv``, ``robot.urdf`` and ``replay.html``.

    ``trajectory.csv`` (format of :mod:`ident.trajectory`) and ``robot.urdf`` (a copy of the
    URDF used) let ``ident replay RUN_DIR`` show the run folder; ``replay.html`` is the static
    meshcat page (:func:`ident.viz.replay.replay_html`). ``package_dirs`` are searched for the
    URDF's ``package://`` meshes (``--package-dir``), then the original URDF's folder and its
    parent. A failing replay never raises: the returned one-line note says what happened, for
    the report and ``run.json``.
    """
    import warnings

    from ident.trajectory import trajectory_to_csv

    folder = Path(folder)
    motion = result.motion
    if motion is None:
        return f"no replay: {result.motion_note or 'no measured motion'}."
    atomic_write_text(folder / "trajectory.csv", trajectory_to_csv(motion))
    urdf_path = atomic_write_text(folder / "robot.urdf", _urdf_text(result))
    what = (
        f"measured motion, {motion.n_samples} samples at "
        f"{(motion.n_samples - 1) / (motion.t[-1] - motion.t[0]):.3g} Hz, "
        f"{motion.t[-1] - motion.t[0]:.2f} s"
    )
    if not replay:
        return f"replay skipped (--no-replay); {what} in trajectory.csv."
    try:
        from ident.viz.replay import replay_html, run_robot_selection

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            source = _robot_file(result).resolve().parent
            page = replay_html(
                # the identified chain: locked joints at their values, robot.package_dirs
                run_robot_selection(folder, result.config.robot, package_dirs),
                [motion],
                labels=[f"{result.config.name}: {what}"],
                package_dirs=[source, source.parent],
                package_hint="robot.package_dirs in the config (or --package-dir)",
            )
    except Exception as e:  # the replay is a convenience: a failure must not lose the result
        return f"no replay: {type(e).__name__}: {e}"
    atomic_write_text(folder / "replay.html", page)
    # e.g. missing meshes -> stick figure; name the copy, not this folder's absolute path
    notes = [str(w.message).replace(str(urdf_path), urdf_path.name).rstrip(".") for w in caught]
    return f"replay.html written ({what})" + "".join(f"; {n}" for n in notes) + "."


def _parameters_csv(result: IdentifyResult) -> str:
    pm = result.parameters
    est = result.estimate
    sd = result.parameter_std
    units = joint_torque_units(result)
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["name", "value", "unit", "std", "relative_std_pct", "expression"])
    for k, expr in enumerate(pm.base.expressions()):
        writer.writerow(
            [
                pm.base_names[k],
                repr(float(est.x[k])),
                parameter_unit(pm.base_names[k], units),
                repr(float(sd.std[k])),
                repr(float(sd.relative_std[k])),
                expr,
            ]
        )
    return buffer.getvalue()


def save_identify_data(result: IdentifyResult, folder: str | Path) -> list[Path]:
    """Save the estimate before anything that can fail afterwards (write-back, replay, report).

    ``parameters.csv`` and a first ``result.json`` (without the URDF write-back and the replay,
    which :func:`write_identify_report` adds when it rewrites it).
    """
    folder = Path(folder)
    return [
        atomic_write_text(folder / "parameters.csv", _parameters_csv(result)),
        atomic_write_text(
            folder / "result.json",
            json.dumps(result_dict(result, None, "not written yet"), indent=2, allow_nan=False)
            + "\n",
        ),
    ]


def write_identify_report(
    result: IdentifyResult,
    folder: str | Path,
    *,
    replay: bool = True,
    replay_note: str | None = None,
) -> list[Path]:
    """Write every report file of an identification into ``folder``.

    Parameters
    ----------
    result :
        The identification.
    folder :
        Existing run folder.
    replay :
        Write ``replay.html`` (the measured motion); ``trajectory.csv`` and ``robot.urdf`` are
        written either way.
    replay_note :
        The note of an earlier :func:`write_measured_replay` call; None: call it here.

    Returns
    -------
    :
        Paths written (report files; the replay's files are not listed).
    """
    folder = Path(folder)
    if replay_note is None:
        replay_note = write_measured_replay(result, folder, replay=replay)
    # the identified model first (saved before the report, which can fail afterwards)
    model = save_identified_model(result, folder)
    rollout = identify_rollout(result, folder, model)  # the MJCF against the URDF nominal
    # refinement: rollout rewrites the MJCF (joint extras) when accepted; scored before
    refinement = refinement_entry(result, folder, model, rollout)
    urdf = identified_urdf(result)  # the cautious copy: its table is in the report either way
    urdf_name = (
        _robot_file(result).stem + "_cautious.urdf" if result.config.urdf_update.cautious else None
    )
    written = _write_report_files(
        result, folder, urdf, urdf_name, replay_note, model, (rollout, refinement)
    )
    if model["written"]:
        written[:0] = [folder / name for name in model["files"].values()]
    return written


def _write_report_files(
    result: IdentifyResult,
    folder: Path,
    urdf: UrdfUpdate,
    urdf_name: str | None,
    replay_note: str,
    model: dict,
    checks: tuple[dict | None, dict | None] = (None, None),
) -> list[Path]:
    """Write the figures, the cautious URDF (when ``urdf_name``), parameters.csv, result.json,
    report.md and report.html; returns their paths."""
    from ident.report.html import markdown_to_html

    png = torque_png(result)
    params_png = parameters_figure(result)
    rollout, refinement = checks  # the MJCF's rollout check and refinement entries
    markdown = _markdown(result, urdf, urdf_name, replay_note, model, rollout, refinement)
    written = [
        atomic_write_bytes(folder / "figures" / "torque_validation.png", png),
        atomic_write_bytes(folder / "figures" / "parameters.png", params_png),
    ]
    if urdf_name is not None:
        written.append(atomic_write_text(folder / urdf_name, urdf.text))
    written += [
        atomic_write_text(folder / "parameters.csv", _parameters_csv(result)),
        atomic_write_text(
            folder / "result.json",
            json.dumps(
                result_dict(
                    result, urdf, replay_note, model, rollout=rollout, refinement=refinement
                ),
                indent=2,
                allow_nan=False,
            )
            + "\n",
        ),
        atomic_write_text(folder / "report.md", markdown),
        atomic_write_text(
            folder / "report.html",
            markdown_to_html(
                markdown,
                title=f"ident identify: {result.config.name}",
                images={
                    "figures/torque_validation.png": png,
                    "figures/parameters.png": params_png,
                },
            ),
        ),
    ]
    return written


def parameters_figure(result: IdentifyResult) -> bytes:
    """Identified base parameters vs the dataset's reference (else the URDF's nominal)."""
    from ident.report.plots import parameters_png

    pm = result.parameters
    est = result.estimate
    ref = np.array([float(pm.base.projection[k] @ pm.nominal) for k in range(len(est.x))])
    label = "nominal"
    by_ours = {row["ours"]: row for row in result.comparison if row.get("ours")}
    if by_ours:
        label = "reference"
        ref = np.array(
            [
                by_ours[n]["reference_value"]
                if n in by_ours and by_ours[n].get("reference_value") is not None
                else np.nan
                for n in pm.base_names
            ],
            dtype=float,
        )
    ok = np.isfinite(ref)
    return parameters_png(
        list(pm.base_names),
        est.x,
        result.parameter_std.std,
        np.where(ok, ref, 0.0),
        include=ok,
        reference_label=label,
        title=f"{est.method.upper()}: identified vs {label}",
    )
