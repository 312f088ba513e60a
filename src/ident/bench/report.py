"""Campaign folder writer: CSVs, the paper's Tables 4-9 beside ours, figures, Markdown/HTML.

One of the few modules that write files (through :mod:`ident.fileio`, atomically). Layout::

    <folder>/runs.csv            one row per run: function, method, run, error, f, nfev, ...
    <folder>/curves.csv          best-so-far error at evaluation counts, per run (long format)
    <folder>/stats.csv           Tables 4-6: min / mean / std of the error, ours and the paper's
    <folder>/wilcoxon.csv        Table 8: best-by-mean and p-values, ours and the paper's
    <folder>/summary.csv         Tables 7 and 9: wins/ties/losses, ours and the paper's
    <folder>/figures/*.png       convergence plots like Figures 5-7
    <folder>/campaign.json       config, wall time, workers
    <folder>/report.md, report.html
"""

from __future__ import annotations

import csv
import io
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from ident.bench.campaign import (
    CampaignConfig,
    CampaignResult,
    RunRecord,
    summary_stats,
    wilcoxon_table,
    win_tie_loss,
)
from ident.bench.functions import get_function
from ident.bench.paper_tables import (
    PAPER_ALGORITHMS,
    PAPER_TABLE7,
    PAPER_TABLE9,
    PAPER_WILCOXON,
    paper_value,
)
from ident.fileio import atomic_write_bytes, atomic_write_text

__all__ = ["disagreements", "load_campaign", "render_markdown", "write_campaign"]

GROUP_TITLES = {
    "unimodal": ("Table 4", "Figure 5", "unimodal"),
    "multimodal": ("Table 5", "Figure 6", "multimodal"),
    "fixed": ("Table 6", "Figure 7", "constant-dimension"),
}
LABELS = {"emupso": "eMuPSO", "pso": "PSO", "woa": "WOA", "gwo": "GWO", "goa": "GOA", "de": "DE"}
SOLVED = 1e-8  # errors below this count as "solved" when comparing magnitudes


def _g(x: float | None, digits: int = 3) -> str:
    if x is None:
        return "—"
    if isinstance(x, float) and math.isnan(x):
        return "NaN"
    if x == 0:
        return "0"
    return f"{x:.{digits}g}"


def _csv(rows: list[list[Any]]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerows(rows)
    return buf.getvalue()


def _label(m: str) -> str:
    return LABELS.get(m, m)


def _table_id(key: str) -> str | None:
    return get_function(key).table_id


def _paper_best(table_id: str | None) -> str | None:
    row = PAPER_WILCOXON.get(table_id or "")
    if row is None:
        return None
    for m, p in zip(PAPER_ALGORITHMS, row, strict=True):
        if p is None:
            return m
    return None


def _groups(result: CampaignResult) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for f in result.config.function_keys():
        out.setdefault(get_function(f).group, []).append(f)
    return out


# ---------------------------------------------------------------------------------------------
# comparisons


def disagreements(result: CampaignResult) -> list[str]:
    """Plain-language list of where our results and the paper's disagree.

    Compared: the best-by-mean algorithm (Table 8's "NA"), and each mean error (Tables 4-6),
    flagged when ours and the paper's differ by more than two orders of magnitude, unless both
    are below 1e-8 ("solved"). Paper values that are NaN or below -1e-8 are not comparable (the
    paper subtracted a rounded or wrong ``f_min``) and are listed as such.
    """
    out: list[str] = []
    wt = wilcoxon_table(result)
    for f in result.config.function_keys():
        bf = get_function(f)
        tid = bf.table_id
        if tid is None:
            continue
        ours_best = wt[f][0]
        pb = _paper_best(tid)
        if pb is not None and pb in result.config.methods and pb != ours_best:
            out.append(
                f"{bf.label}: best by mean is {_label(ours_best)} here, {_label(pb)} in the paper."
            )
        bad: list[str] = []
        uncomparable: list[str] = []
        for m in result.config.methods:
            pv = paper_value(tid, "Ave", m)
            if pv is None:
                continue
            ours = float(np.mean(result.errors(f, m)))
            if math.isnan(pv) or pv < -SOLVED:
                uncomparable.append(f"{_label(m)} {_g(pv)}")
                continue
            a, b = max(abs(ours), SOLVED), max(abs(pv), SOLVED)
            if abs(math.log10(a) - math.log10(b)) > 2:
                bad.append(f"{_label(m)} {_g(ours)} vs {_g(pv)}")
        if bad:
            out.append(f"{bf.label}: mean error differs by >100x: " + "; ".join(bad) + ".")
        if uncomparable:
            out.append(
                f"{bf.label}: paper means not comparable (f - f_min(paper) < 0 or NaN): "
                + "; ".join(uncomparable)
                + "."
            )
    return out


# ---------------------------------------------------------------------------------------------
# figures


def convergence_figures(result: CampaignResult) -> dict[str, bytes]:
    """PNG per group (like Figures 5-7): mean best-so-far error vs evaluations, log scale."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figs: dict[str, bytes] = {}
    for group, keys in _groups(result).items():
        n = len(keys)
        ncol = min(4, n)
        nrow = math.ceil(n / ncol)
        fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol, 2.8 * nrow), squeeze=False)
        for ax, f in zip(axes.flat, keys, strict=False):
            curves = {}
            for m in result.config.methods:
                runs = result.runs(f, m)
                curves[m] = (runs[0].curve_nfev, np.mean([r.curve_error for r in runs], axis=0))
            positive = np.concatenate([c[c > 0] for _, c in curves.values()])
            floor = positive.min() / 10.0 if positive.size else 1e-300
            for m, (nfev, curve) in curves.items():
                ax.plot(nfev, np.maximum(curve, floor), label=_label(m), lw=1.2)
            ax.set_yscale("log")
            ax.set_title(get_function(f).label, fontsize=9)
            ax.tick_params(labelsize=7)
            ax.set_xlabel("evaluations", fontsize=7)
        for ax in list(axes.flat)[n:]:
            ax.axis("off")
        axes.flat[0].set_ylabel("mean error f - f*", fontsize=7)
        axes.flat[0].legend(fontsize=7)
        fig.tight_layout()
        buf = io.BytesIO()
        fig.savefig(buf, format="png", dpi=90)
        plt.close(fig)
        figs[f"figures/convergence_{group}.png"] = buf.getvalue()
    return figs


# ---------------------------------------------------------------------------------------------
# markdown


def _md_table(header: list[str], rows: list[list[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(["---"] * len(header)) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return lines + [""]


def render_markdown(result: CampaignResult, figures: list[str]) -> str:
    """The campaign report as Markdown (the HTML page is converted from it)."""
    L = _md_header(result)
    for group, keys in _groups(result).items():
        L += _md_error_table(result, group, keys)
    L += _md_wilcoxon_table(result)
    for kind, tname, published in (
        ("min", "Table 7", PAPER_TABLE7),
        ("wilcoxon", "Table 9", PAPER_TABLE9),
    ):
        L += _md_win_tie_loss(result, kind, tname, published)
    L += _md_disagreements(result)
    L += ["## Convergence (like Figures 5-7)", ""]
    for fig in figures:
        L += [f"![{fig}]({fig})", ""]
    L += [
        "Mean over the runs of the best-so-far error; a mean error of 0 (or below, from "
        "rounding) is drawn one decade below the smallest positive value of its panel.",
        "",
    ]
    return "\n".join(L)


def _md_header(result: CampaignResult) -> list[str]:
    """Title, the campaign's settings and timing, and how to read it against the paper."""
    cfg = result.config
    n_runs = len(result.records)
    mean_run = float(np.mean([r.seconds for r in result.records]))
    where = (
        f"dask scheduler `{result.scheduler}`"
        if result.scheduler
        else f"{result.workers} local worker process(es)"
    )
    L: list[str] = [f"# Benchmark campaign `{cfg.name}`", ""]
    L += [
        f"- Methods: {', '.join(_label(m) for m in cfg.methods)}; functions: "
        f"{len(cfg.function_keys())}"
        f" ({cfg.functions if isinstance(cfg.functions, str) else 'list'}).",
        f"- Budget per run: **{cfg.max_nfev} evaluations** (population {cfg.popsize}, "
        f"{cfg.maxiter} iterations after the initial population); {cfg.runs} runs per "
        f"function and method, seed {cfg.seed} (per-run seeds from `SeedSequence`).",
        f"- Method options beyond the defaults: `{json.dumps(cfg.method_options)}`.",
        f"- {n_runs} runs in **{result.wall_seconds:.1f} s** wall time on {where} "
        f"(mean {mean_run * 1e3:.1f} ms per run).",
        "",
        "## How to read this against the paper",
        "",
        "- Errors are `f(x_best) - f*` with the exact `f*` of each function's registry entry "
        "(`ident.bench.functions`). The paper's Tables 4-6 report `f - f_min(paper)` with the "
        "appendix's rounded or wrong `f_min`: its negative entries (e.g. Test-tube -2.04e-08, "
        "Shekel 7 -20.8, Hartmann 3 -1.78e-05) and its constant offsets (Modified Rosenbrock "
        "3.404, Langerman 0.303) come from that constant, not from the optimizers. Such paper "
        "values are shown but not compared.",
        '- 2-D functions are run in 2-D (the paper\'s "Dim 30" for them is not meaningful: they '
        "read two variables); the paper's evaluation budget is not stated, ours is above.",
        "- The paper's NaN rows (DE on Easom, Pen Holder, Egg Holder, Paviani) come from "
        "evaluating its formulas at singular points; our definitions are NaN-free on the boxes.",
        "- Table 7 counts wins/ties/losses of the minimum error, Table 9 of the Wilcoxon test "
        f"at {cfg.alpha:g} (definitions in `ident.bench.campaign`).",
        "",
    ]
    return L


def _md_error_table(result: CampaignResult, group: str, keys: list[str]) -> list[str]:
    """Tables 4-6: min, mean and standard deviation of the errors of each function of a group
    and each method, ours beside the paper's."""
    methods = result.config.methods
    tname, _, gname = GROUP_TITLES.get(group, ("Table", "Figure", group))
    L = [f"## {tname}: {gname} functions (ours / paper)", ""]
    header = ["Function", "Stat"] + [f"{_label(m)} ours / paper" for m in methods]
    rows = []
    for f in keys:
        tid = _table_id(f)
        stats = {m: summary_stats(result.errors(f, m)) for m in methods}
        for k, stat in enumerate(("Min", "Ave", "StDev")):
            cells = [
                f"{_g(stats[m][k])} / {_g(paper_value(tid, stat, m)) if tid else '—'}"
                for m in methods
            ]
            rows.append([get_function(f).label if k == 0 else "", stat, *cells])
    return L + _md_table(header, rows)


def _md_wilcoxon_table(result: CampaignResult) -> list[str]:
    """Table 8: Wilcoxon p-values of each method against the best by mean (NA for the best),
    ours beside the paper's."""
    methods = result.config.methods
    L = ["## Table 8: Wilcoxon signed-rank p-values against the best by mean (ours / paper)", ""]
    header = ["Function", "best ours / paper"] + [_label(m) for m in methods]
    rows = []
    for f, (best, row) in wilcoxon_table(result).items():
        tid = _table_id(f)
        cells = []
        for m in methods:
            ours = "NA" if row[m] is None else _g(row[m])
            pv = paper_value(tid, "p", m) if tid else None
            paper = "NA" if tid and _paper_best(tid) == m else _g(pv)
            cells.append(f"{ours} / {paper}")
        pb = _paper_best(tid)
        rows.append(
            [get_function(f).label, f"{_label(best)} / {_label(pb) if pb else '—'}", *cells]
        )
    L += _md_table(header, rows)
    L += ["NA marks the best-by-mean algorithm; a paper best of — means the paper's row has no "
          "NA entry (its Table 8 omits it on several rows).", ""]  # fmt: skip
    return L


def _md_win_tie_loss(
    result: CampaignResult, kind: str, tname: str, published: dict[str, Any]
) -> list[str]:
    """Table 7 (``kind="min"``) or 9 (``"wilcoxon"``): wins/ties/losses per function group,
    ours beside the paper's ``published`` counts."""
    cfg = result.config
    what = "minimum error" if kind == "min" else "Wilcoxon test"
    L = [f"## {tname}: wins/ties/losses by {what} (ours / paper)", ""]
    wtl = win_tie_loss(result, kind)  # type: ignore[arg-type]
    rows = []
    for g, per in wtl.items():
        cells = []
        for m in cfg.methods:
            ours = "/".join(str(c) for c in per[m])
            j = PAPER_ALGORITHMS.index(m) if m in PAPER_ALGORITHMS else None
            pp = published.get(g)
            cells.append(f"{ours} / {pp[j] if pp and j is not None else '—'}")
        rows.append([g, *cells])
    L += _md_table(["Group"] + [_label(m) for m in cfg.methods], rows)
    if cfg.functions != "table":
        L += ["The paper's counts are over its 12 functions per group; ours over the "
              "functions of this config only.", ""]  # fmt: skip
    return L


def _md_disagreements(result: CampaignResult) -> list[str]:
    """Where our results disagree with the paper's (:func:`disagreements`), and the criteria."""
    L = ["## Where we disagree with the paper", ""]
    dis = disagreements(result)
    L += [f"- {d}" for d in dis] if dis else ["- No disagreement by the criteria below."]
    L += [
        "",
        "Criteria: a different best-by-mean algorithm, or a mean error more than 100x apart "
        f"(values below {SOLVED:g} count as solved).",
        "",
    ]
    return L


# ---------------------------------------------------------------------------------------------
# writer


def write_campaign(result: CampaignResult, folder: str | Path) -> list[Path]:
    """Write every file of the campaign folder (see module docstring); returns their paths."""
    folder = Path(folder)
    cfg = result.config
    runs, curves = _runs_rows(result)
    written = [
        atomic_write_text(folder / "runs.csv", _csv(runs)),
        atomic_write_text(folder / "curves.csv", _csv(curves)),
        atomic_write_text(folder / "stats.csv", _csv(_stats_rows(result))),
        atomic_write_text(folder / "wilcoxon.csv", _csv(_wilcoxon_rows(result))),
        atomic_write_text(folder / "summary.csv", _csv(_summary_rows(result))),
    ]
    figs = convergence_figures(result)
    for name, png in figs.items():
        written.append(atomic_write_bytes(folder / name, png))
    meta = {
        "config": cfg.model_dump(),
        "maxiter": cfg.maxiter,
        "wall_seconds": result.wall_seconds,
        "workers": result.workers,
        "scheduler": result.scheduler,
        "n_runs": len(result.records),
    }
    written.append(atomic_write_text(folder / "campaign.json", json.dumps(meta, indent=2) + "\n"))
    md = render_markdown(result, list(figs))
    written.append(atomic_write_text(folder / "report.md", md))
    from ident.report.html import markdown_to_html

    page = markdown_to_html(md, title=f"ident bench: {cfg.name}", images=figs)
    written.append(atomic_write_text(folder / "report.html", page))
    return written


def _runs_rows(result: CampaignResult) -> tuple[list[list[Any]], list[list[Any]]]:
    """Rows (header first) of runs.csv (one per run) and curves.csv (one per curve point)."""
    runs: list[list[Any]] = [
        ["function", "table_id", "method", "run", "error", "f", "nfev", "nit", "seconds",
         "n_nonfinite"]
    ]  # fmt: skip
    curves: list[list[Any]] = [["function", "method", "run", "nfev", "error"]]
    for r in result.records:
        runs.append([r.function, _table_id(r.function) or "", r.method, r.run, repr(r.error),
                     repr(r.fun), r.nfev, r.nit, f"{r.seconds:.6f}", r.n_nonfinite])  # fmt: skip
        curves += [
            [r.function, r.method, r.run, int(n), repr(float(e))]
            for n, e in zip(r.curve_nfev, r.curve_error, strict=True)
        ]
    return runs, curves


def _stats_rows(result: CampaignResult) -> list[list[Any]]:
    """Rows (header first) of stats.csv: min, mean, std of the errors per function and method,
    next to the paper's."""
    stats: list[list[Any]] = [
        ["function", "table_id", "method", "min", "mean", "std", "paper_min", "paper_mean",
         "paper_std"]
    ]  # fmt: skip
    for f in result.config.function_keys():
        tid = _table_id(f)
        for m in result.config.methods:
            s = summary_stats(result.errors(f, m))
            p = [paper_value(tid, k, m) if tid else None for k in ("Min", "Ave", "StDev")]
            stats.append([f, tid or "", m, *map(repr, s), *("" if v is None else v for v in p)])
    return stats


def _wilcoxon_rows(result: CampaignResult) -> list[list[Any]]:
    """Rows (header first) of wilcoxon.csv: the p-value of each method against the best, next
    to the paper's."""
    wil: list[list[Any]] = [
        ["function", "table_id", "best", "paper_best", "method", "p", "paper_p"]
    ]
    for f, (best, row) in wilcoxon_table(result).items():
        tid = _table_id(f)
        for m in result.config.methods:
            pv = paper_value(tid, "p", m) if tid else None
            ours = "NA" if row[m] is None else repr(row[m])
            paper_p = "" if pv is None else pv
            wil.append([f, tid or "", best, _paper_best(tid) or "", m, ours, paper_p])
    return wil


def _summary_rows(result: CampaignResult) -> list[list[Any]]:
    """Rows (header first) of summary.csv: wins, ties, losses per group and method of the
    paper's tables 7 (min) and 9 (Wilcoxon), next to the paper's."""
    summ: list[list[Any]] = [["table", "group", "method", "wins", "ties", "losses", "paper"]]
    for kind, tname, paper in (("min", "7", PAPER_TABLE7), ("wilcoxon", "9", PAPER_TABLE9)):
        for g, per in win_tie_loss(result, kind).items():  # type: ignore[arg-type]
            for m in result.config.methods:
                j = PAPER_ALGORITHMS.index(m) if m in PAPER_ALGORITHMS else None
                pp = paper.get(g)
                summ.append([tname, g, m, *per[m], pp[j] if pp and j is not None else ""])
    return summ


def load_campaign(folder: str | Path) -> CampaignResult:
    """Read a campaign folder back (``campaign.json``, ``runs.csv``, ``curves.csv``).

    Lets the tables, figures and report be re-rendered without rerunning the campaign:
    ``write_campaign(load_campaign(old), new_folder)``.
    """
    folder = Path(folder)
    meta = json.loads((folder / "campaign.json").read_text(encoding="utf-8"))
    cfg = CampaignConfig.model_validate(meta["config"])
    curves: dict[tuple[str, str, int], tuple[list[int], list[float]]] = {}
    with open(folder / "curves.csv", newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            key = (row["function"], row["method"], int(row["run"]))
            n, e = curves.setdefault(key, ([], []))
            n.append(int(row["nfev"]))
            e.append(float(row["error"]))
    records = []
    with open(folder / "runs.csv", newline="", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            key = (row["function"], row["method"], int(row["run"]))
            n, e = curves.get(key, ([], []))
            records.append(
                RunRecord(
                    function=key[0],
                    method=key[1],
                    run=key[2],
                    error=float(row["error"]),
                    fun=float(row["f"]),
                    nfev=int(row["nfev"]),
                    nit=int(row["nit"]),
                    seconds=float(row["seconds"]),
                    n_nonfinite=int(row["n_nonfinite"]),
                    curve_nfev=np.array(n, dtype=np.int64),
                    curve_error=np.array(e),
                )
            )
    return CampaignResult(
        config=cfg,
        records=tuple(records),
        wall_seconds=float(meta["wall_seconds"]),
        workers=int(meta["workers"]),
        scheduler=meta.get("scheduler"),
    )
