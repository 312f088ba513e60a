"""The headline block that opens every report: verdict, worst error, residual, checks.

The same block for ``ident run`` (simulated, true values known) and ``ident identify`` (a
real robot): a reader learns in the first screen whether the parameters were identified,
how badly the worst major parameter is off, how well the torques are predicted on data not
used to identify, how ill-conditioned the problem is, whether the result is physically
consistent and the trajectory safe (``not checked`` when the result does not say), and the
warnings.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

from ident.identify.assessment.verdict import Verdict
from ident.report.format import table

__all__ = ["Headline", "headline_markdown"]

NOT_CHECKED = "not checked"


@dataclass(frozen=True)
class Headline:
    """Pre-formatted facts of the headline block (strings, units included)."""

    verdict: Verdict
    rule: str
    worst: str
    worst_label: str
    residual: str
    residual_label: str
    condition: str
    consistency: str = NOT_CHECKED
    safety: str = NOT_CHECKED
    warnings: Sequence[str] = field(default_factory=tuple)
    extra: Sequence[tuple[str, str]] = field(default_factory=tuple)


def headline_markdown(h: Headline) -> list[str]:
    """``## Summary``: a two-column table of the facts, the verdict rule and the warnings."""
    rows = [
        ["Verdict", f"**{h.verdict.label}** ({h.verdict.reason})"],
        [h.worst_label, h.worst],
        [h.residual_label, h.residual],
        ["Condition number", h.condition],
        ["Physical consistency", h.consistency],
        ["Trajectory safety", h.safety],
        *[[k, v] for k, v in h.extra],
        ["Warnings", f"{len(h.warnings)} (below)" if h.warnings else "none"],
    ]
    md = ["## Summary", ""]
    md += table(["", "result"], rows, left=(0, 1))
    md += [f"Verdict rule: {h.rule}.", ""]
    for w in h.warnings:
        md += [f"> **Warning: {w}**", ""]
    return md
