"""Number formatting and Markdown tables shared by the report writers.

Tables: text columns are left-aligned (``:---``), numeric columns right-aligned (``---:``),
decided per column from its cells, so ``report.md`` and ``report.html`` look alike.
"""

from __future__ import annotations

import re
from typing import Any

__all__ = ["fmt", "pct", "percent", "table"]

_NUMERIC = re.compile(r"^[-+]?(\d+(\.\d*)?|\.\d+)([eE][-+]?\d+)?( ?%)?$")


def fmt(value: Any, digits: int = 4) -> str:
    """A number for a report: 4 significant digits, ``—`` for missing, ``yes``/``no``."""
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    value = float(value)
    if value != value:
        return "—"
    if value in (float("inf"), float("-inf")):
        return "inf" if value > 0 else "-inf"
    if value == 0.0:
        return "0"
    if 1e-3 <= abs(value) < 1e5:
        return f"{value:.{digits}g}"
    return f"{value:.{digits - 1}e}"


def pct(value: Any, digits: int = 3) -> str:
    """A percentage [%] with its sign (``12.3 %``); ``—`` for missing."""
    text = fmt(value, digits)
    return text if text == "—" else f"{text} %"


def percent(fraction: float | None) -> float | None:
    """A fraction as a percentage (``None`` stays ``None``): a table uses one of the two."""
    return None if fraction is None else 100.0 * fraction


def _is_numeric(cell: str) -> bool:
    return cell in ("—", "-", "") or bool(_NUMERIC.match(cell.strip().replace("`", "")))


def table(header: list[str], rows: list[list[str]], left: tuple[int, ...] = ()) -> list[str]:
    """A Markdown pipe table, then a blank line.

    A column is right-aligned when every body cell is a number (or ``—``), left-aligned
    otherwise; ``left`` forces text alignment.
    """
    seps = []
    for k in range(len(header)):
        cells = [row[k] for row in rows if k < len(row)]
        numeric = k not in left and cells and all(_is_numeric(c) for c in cells)
        numeric = numeric and not all(c in ("—", "-", "") for c in cells)
        seps.append("---:" if numeric else ":---")
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(seps) + "|"]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in rows]
    return lines + [""]
