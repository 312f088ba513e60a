"""Reports in a real headless Chromium at 1400x900: the headline block is on the first screen,
no table cell is clipped, no word in a table is broken across lines, every figure is shown at
100 % inside the window, and relative measures are in percent, for a run (quick wrist), the
paper's wrist config (its summary's "Paper's box" row), a run with a joint-space Fourier
excitation (arm stage), a URDF robot measured by MuJoCo (UR5) and an identification (TX40 log)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from browser_utils import (  # noqa: F401
    REPORT_VIEWPORT,
    chromium,
    report_layout,
    report_readability,
)
from test_report import unitless_labels_without_percent
from typer.testing import CliRunner

from ident.cli import app

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "tests" / "data" / "run" / "quick-wrist.yaml"
KINDS = ["wrist", "wrist-paper", "arm-fourier", "ur5-mujoco", "identify"]


def _only(folder: Path) -> Path:
    (run,) = [p for p in folder.iterdir() if p.is_dir()]
    return run


@pytest.fixture(scope="module")
def reports(tmp_path_factory, shipped_run) -> dict[str, Path]:
    """The report of each kind: the paper's wrist config, the arm's joint-space Fourier config
    and the MuJoCo-measured UR5 are the session's shared runs of the shipped configs
    (``configs/wrist.yaml``, ``arm-fourier.yaml``, ``ur5.yaml``: full settings, more elites
    in the tables than their quick versions); the quick wrist run and the identification are
    run here."""
    runner = CliRunner()
    out: dict[str, Path] = {}
    base = tmp_path_factory.mktemp("reports")
    for kind, args in (
        ("wrist", ["run", str(QUICK), "--no-replay"]),
        ("identify", ["identify", str(ROOT / "configs" / "tx40.yaml"), "--no-replay"]),
    ):
        folder = base / kind
        result = runner.invoke(app, [*args, "--out", str(folder)])
        assert result.exit_code in (0, 1), result.output
        out[kind] = _only(folder) / "report.html"
    for kind, name in (
        ("wrist-paper", "wrist"),
        ("arm-fourier", "arm-fourier"),
        ("ur5-mujoco", "ur5"),
    ):
        out[kind] = shipped_run(name) / "report.html"
    yield out
    shutil.rmtree(base, ignore_errors=True)


@pytest.mark.parametrize("kind", KINDS)
def test_headline_on_first_screen_and_no_clipped_cell(chromium, reports, kind):  # noqa: F811
    layout = report_layout(chromium, reports[kind])
    assert layout["summary_bottom"] is not None, "no headline table after '## Summary'"
    assert layout["summary_bottom"] <= REPORT_VIEWPORT["height"], layout
    assert layout["clipped"] == [], layout["clipped"][:5]
    assert layout["wide_tables"] == 0
    if kind == "wrist-paper":  # the paper's box, said in the summary, on the first screen
        summary = reports[kind].with_name("report.md").read_text(encoding="utf-8")
        assert "| Paper's box | expected:" in summary.split("Verdict rule:")[0]


def test_the_check_finds_a_clipped_cell(chromium, tmp_path):  # noqa: F811
    """Negative control: a cell that cannot wrap is reported as clipped."""
    page = tmp_path / "bad.html"
    page.write_text(
        '<html><body><h2 id="summary">S</h2><table><tr><td style="max-width: 5em; '
        'overflow: hidden; white-space: nowrap">' + "x" * 200 + "</td></tr></table></body></html>"
    )
    layout = report_layout(chromium, page)
    assert len(layout["clipped"]) == 1
    assert layout["summary_bottom"] < REPORT_VIEWPORT["height"]


@pytest.mark.parametrize("kind", KINDS)
def test_words_whole_figures_at_full_size_and_percent_tables(chromium, reports, kind):  # noqa: F811
    found = report_readability(chromium, reports[kind])
    assert found["broken_words"] == [], found["broken_words"][:10]
    assert found["figures"], "no figure in the report"
    for fig in found["figures"]:
        # shown at 100 % (not scaled down: labels keep their size) and inside the window
        assert fig["natural"] <= fig["shown"] + 1, fig
        assert fig["right"] <= fig["page"], fig
    markdown = reports[kind].with_name("report.md").read_text(encoding="utf-8")
    assert unitless_labels_without_percent(markdown) == []


def test_the_checks_find_a_broken_word_and_a_shrunk_figure(chromium, tmp_path):  # noqa: F811
    """Negative controls: the old cell style (``overflow-wrap: anywhere`` in a narrow column)
    breaks "transmission" mid-word; a 2300 px figure is scaled down to the page."""
    import base64
    import io

    from PIL import Image

    buffer = io.BytesIO()
    Image.new("RGB", (2300, 40), "white").save(buffer, format="PNG")
    data = base64.b64encode(buffer.getvalue()).decode("ascii")
    page = tmp_path / "bad.html"
    page.write_text(
        "<html><body style='max-width: 80em; margin: auto'><table><tr>"
        "<td style='overflow-wrap: anywhere; width: 1px'>transmission step</td>"
        "<td>" + "long text " * 300 + "</td></tr></table>"
        f'<img style="max-width: 100%" src="data:image/png;base64,{data}"></body></html>'
    )
    found = report_readability(chromium, page)
    assert "transmission" in found["broken_words"]
    (fig,) = found["figures"]
    assert fig["natural"] == 2300
    assert fig["shown"] < 1400
