"""The report's "Identified model" section: which file is which, reload parity, held-out fit.

One renderer for ``ident identify`` and ``ident run`` reports, from the ``model`` entry of
``result.json`` (:func:`ident.identify.model_files.files.save_identified_model`).
"""

from __future__ import annotations

from typing import Any

from ident.report.format import pct

__all__ = ["model_section"]


def model_section(
    model: dict[str, Any] | None, cautious: str | None = None, *, where: str = ""
) -> list[str]:
    """Markdown lines of the section.

    Parameters
    ----------
    model :
        The ``model`` entry of ``result.json``, or None (no model attempted).
    cautious :
        File name of the cautious copy when it was written (``urdf_update.cautious``).
    where :
        Words saying which identification the model comes from (e.g. the run's elite).
    """
    lines = ["## Identified model", ""]
    if model is None or not model["written"]:
        note = "not written" if model is None else model["note"]
        return lines + [f"No model file: {note}.", ""]
    files, parity = model["files"], model["reload_parity"]
    held = model["held_out_relative_residual"] or {}
    lines += _file_lines(model, cautious, where)
    reload = (
        f"{parity['urdf']:.2g} (URDF), {parity['mjcf']:.2g} (MJCF), "
        f"{parity['n_states']} random states"
        if parity
        else f"not computed ({model['note']})"
    )
    fits = ", ".join(f"{k} {pct(100 * v)}" for k, v in held.items() if v is not None)
    law = model.get("friction_law")
    if law is not None:
        res = law["held_out_relative_residual"]
        lines.append(
            f"- The friction is the **{law['model']}** law, in `{files['joint_extras']}` "
            "(`friction_law`: formula, units, parameters per joint); the URDF's and MJCF's "
            "damping/friction hold its closest viscous + Coulomb curve, a MuJoCo user adds the "
            "rest as `qfrc_applied` (docs/friction.md). Held out, these bodies with the law: "
            f"{pct(100 * res[law['model']])}, with viscous + Coulomb: "
            f"{pct(100 * res['viscous_coulomb'])}."
        )
        if parity and parity.get("friction_law") is not None:
            reload += f"; the law read back from the file: {parity['friction_law']:.2g}"
    return lines + [
        "",
        "Reloaded (Pinocchio RNEA of the URDF, MuJoCo inverse dynamics of the MJCF), largest "
        f"relative torque difference to the estimate: {reload}. Held-out relative residual: "
        f"{fits or '-'}. The files and the mapping to MuJoCo: docs/model-files.md.",
        "",
    ]


def _file_lines(model: dict[str, Any], cautious: str | None, where: str) -> list[str]:
    """One bullet per file of the model (see :func:`model_section`)."""
    files = model["files"]
    # a list, not a table: a file name in a narrow table column would break mid-word
    lines = [
        f"- `{files['urdf']}`: **the identified model**: your URDF with every moving link's "
        f"inertial from the physically consistent {model['method']} estimate{where} (prior "
        "toward the URDF on the directions the log does not see) and the joints' "
        "damping/friction.",
        f"- `{files['mjcf']}`: the same model as MJCF, joint extras as `armature`, `damping`, "
        "`frictionloss` (no geometry: loads without meshes).",
        f"- `{files['joint_extras']}`: every per-joint extra: rotor inertia, friction, offsets.",
    ]
    if cautious is not None:
        lines.append(
            f"- `{cautious}`: the cautious copy: only the well-identified standard parameters "
            "changed, nominal values elsewhere (section below)."
        )
    return lines
