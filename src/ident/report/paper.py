"""The paper's published results for the wrist and arm stages, and their report sections.

Counts and named lists of section 4.1 (which standard parameters are identifiable alone, in
combination, not at all) and Tables 2-3 (fitness, condition number, Error(20), Error(22) of
the six elites of each stage), transcribed from the paper's text: A. Umar, Z. Shi, L. Zheng,
A. Khlil, Z. I. B. Farouk, "Parameter Estimation for Industrial Robot Manipulators Using an
Improved Particle Swarm Optimization Algorithm with Gaussian Mutation and Archived Elite
Learning", Advances in Science, Technology and Engineering Systems Journal 5(6), 1436-1457,
2020, doi:10.25046/aj0506174.
"""

from __future__ import annotations

from typing import Any

from ident.report.format import fmt as _fmt
from ident.report.format import table as _table

__all__ = [
    "PAPER_BOX_NOTES",
    "PAPER_COUNTS",
    "PAPER_NAMES",
    "PAPER_TABLES",
    "classify",
    "paper_box_note",
    "paper_tables_section",
]

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
    """The stage's base parameters in DH frames, and where the paper's names fall in them."""
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
    md += _paper_class_table(comparison)
    if stage["name"] == "wrist":
        md += [
            "The paper lists Iyz6 both as independent and in combination and does not list "
            "Ixy6 (21 distinct names for 22 identified parameters): one of the two Iyz6 is "
            "probably Ixy6.",
            "",
        ]
    md += _per_parameter_table(comparison)
    md += [
        'docs/paper-notes.md ("Base parameters of the paper\'s stages") explains each difference.',
        "",
    ]
    return md


def _paper_class_table(comparison: list[dict[str, Any]]) -> list[str]:
    """Per class of the paper (rows), its names in each of our DH-frame classes (columns)."""
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
    md = [
        "Where the paper's names fall in our DH-frame classes (the paper's lists of section "
        "4.1; `mx5` read as mcx5, `mm` as m; parameters the paper does not list are its "
        "unidentifiable ones, which it does not name). Which member of a combination is "
        "called independent depends on the column order and the method, so compare "
        "independent + in combination (identified) against unidentifiable first:",
        "",
    ]
    return md + _table(
        ["", "ours: independent", "ours: in combination", "ours: unidentifiable"],
        rows,
        left=(0, 1, 2, 3),
    )


def _per_parameter_table(comparison: list[dict[str, Any]]) -> list[str]:
    """Per parameter: the paper's class, ours in DH frames and ours in body frames."""
    md = [
        "Per parameter (paper / ours in DH frames / ours in body frames, where the estimate's "
        "names can differ only because of the frames):",
        "",
    ]
    return md + _table(
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


#: Tables 2 (wrist) and 3 (arm) of the paper: per elite 1..6, as printed.
PAPER_TABLES: dict[str, dict[str, Any]] = {
    "wrist": {
        "table": 2,
        "fitness": (418.354, 401.380, 357.993, 351.894, 349.889, 297.128),
        "cond": (154.591, 152.878, 156.902, 157.041, 155.063, 154.087),
        "error20": (10.8120, 188.679, 14.5859, 99.1558, 86.8486, 25.3959),
        "error22": (2220.44, 16789.5, 529.495, 4568.45, 8777.48, 44.3582),
    },
    "arm": {
        "table": 3,
        "fitness": (293.392, 199.588, 145.3132, 103.235, 70.9066, 64.7651),
        "cond": (53.5757, 44.7731, 26.41273, 17.8764, 13.4862, 11.8133),
        "error20": (0.00270, 0.00286, 0.035218, 0.01955, 0.03211, 0.00822),
        "error22": (0.00460, 0.00766, 0.074774, 0.03507, 0.08359, 0.01544),
    },
}

PAPER_ERROR_READING = (
    "Error(22) and Error(20) are the paper's \"cumulative errors ... for all 22 identified "
    'parameters" and "for the best 20"; we read them as the sum of the relative errors '
    "|identified - true| / |true| [%] over the identified base parameters, and the same sum "
    "without the two largest terms. Ours, Error(n) and Error(n-2), sum over our n "
    "significant base parameters (torque share >= 1e-4; a parameter whose true value is "
    "1e-11 of the largest is left out, its relative error measures round-off, not the method)."
)
PAPER_DIFFERENCES = (
    "Fitness: eq. 15 on our column-scaled base observation matrix; the paper does not state "
    "its scaling, so the values compare in trend (lower is better), not in size.",
    "Condition number: ours is of the same scaled base matrix the objective uses; the "
    "paper's matrix and units are not stated.",
    "Error sums: we sum over n significant base parameters of our own reduction (n = 22 only "
    "if our base set had 22 members), and the paper does not state whether its errors are "
    "fractions or percent.",
    "Elites: ours come from our own optimization runs, so row k pairs the k-th elite of each, "
    "not the same trajectory.",
)


#: Per paper stage: what the paper's own +-10 box gives and the config for a good result.
PAPER_BOX_NOTES = {
    "wrist": (
        "expected: the paper's ±10 Cartesian box moves the flange by a few centimetres and "
        "excites the wrist badly (the paper's own Table 2 is beside ours below). "
        "`configs/wrist-box.yaml` keeps the paper's series in a box sized to the wrist "
        "(condition number about 14x lower); `configs/wrist-fourier.yaml` (joint-space "
        'Fourier) identifies the wrist best (docs/excitation.md, "The paper\'s box")'
    ),
    "arm": (
        "expected: the paper's ±10 Cartesian box puts the wrist centre at the base's height, "
        "so its trajectories go through the pedestal and the floor and no elite passes the "
        "safety check; the paper's own Table 3 is beside ours below. "
        "`configs/arm-box.yaml` keeps the paper's series in a box sized to the workspace, "
        "safe; `configs/arm-fourier.yaml` (joint-space Fourier) identifies the arm best "
        '(docs/excitation.md, "The paper\'s box")'
    ),
}


def paper_box_note(data: dict[str, Any]) -> str | None:
    """The summary's "Paper's box" line for a run of the paper's own excitation, else None.

    A paper config is the paper's stage (wrist, arm) with its Cartesian family
    (``paper_wrist``, ``paper_arm``) in the family's own ±10 box (``excitation.bounds``
    unset), as ``configs/wrist.yaml`` and ``configs/arm.yaml``.
    """
    stage = (data.get("stage") or {}).get("name") or data["config"].get("stage")
    excitation = data["config"]["excitation"]
    if stage not in PAPER_BOX_NOTES or excitation.get("family") != f"paper_{stage}":
        return None
    if excitation.get("bounds"):
        return None  # a box of the user's (configs/*-box.yaml)
    return PAPER_BOX_NOTES[stage]


def paper_tables_section(data: dict[str, Any], method: str | None) -> list[str]:
    """Tables 2-3's fitness, condition number, Error(20), Error(22) beside ours, per elite."""
    stage = data.get("stage") or {}
    paper = PAPER_TABLES.get(stage.get("name", ""))
    if paper is None:
        return []
    elites = data["elites"]
    n_rows = max(len(elites), len(paper["fitness"]))
    rows = []
    n_sig = None
    for k in range(n_rows):
        e = elites[k] if k < len(elites) else None
        est = (e or {}).get("estimates", {}).get(method or "", {})
        if est.get("n_significant") is not None:
            n_sig = est["n_significant"]
        p = {key: paper[key][k] if k < len(paper[key]) else None for key in paper if key != "table"}
        rows.append(
            [
                str(k + 1),
                _fmt(p["fitness"]),
                _fmt(e["fitness"]) if e else "—",
                _fmt(p["cond"]),
                _fmt(e["objective"].get("cond")) if e else "—",
                _fmt(p["error20"]),
                _fmt(est.get("paper_error_sum_best_percent")),
                _fmt(p["error22"]),
                _fmt(est.get("paper_error_sum_percent")),
            ]
        )
    n = "n" if n_sig is None else str(n_sig)
    n2 = "n-2" if n_sig is None else str(max(0, n_sig - 2))
    md = [
        f"### Table {paper['table']} of the paper beside this run ({(method or '').upper()})",
        "",
    ]
    md += _table(
        [
            "elite",
            "fitness, paper",
            "fitness, ours",
            "cond, paper",
            "cond, ours",
            "Error(20), paper",
            f"Error({n2}), ours [%]",
            "Error(22), paper",
            f"Error({n}), ours [%]",
        ],
        rows,
    )
    md += [PAPER_ERROR_READING, ""]
    md += [f"- {d}" for d in PAPER_DIFFERENCES] + [""]
    return md
