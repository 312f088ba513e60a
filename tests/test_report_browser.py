"""Reports in a real headless Chromium at 1400x900: the headline block is on the first screen
and no table cell is clipped, for a run (wrist), a run with a joint-space Fourier excitation
(arm stage) and an identification (TX40 log)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from browser_utils import REPORT_VIEWPORT, chromium, report_layout  # noqa: F401
from typer.testing import CliRunner

from ident.cli import app

pytestmark = [pytest.mark.browser, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[1]
QUICK = ROOT / "tests" / "data" / "run" / "quick-wrist.yaml"


def _arm_fourier(tmp_path: Path) -> Path:
    """The quick wrist config on the arm stage (joint Fourier): a few seconds."""
    text = QUICK.read_text().replace(
        "robot: ../../../configs/paper6r.yaml", f"robot: {ROOT / 'configs' / 'paper6r.yaml'}"
    )
    path = tmp_path / "quick-arm.yaml"
    path.write_text(text.replace("stage: wrist", "stage: arm"))
    return path


def _only(folder: Path) -> Path:
    (run,) = [p for p in folder.iterdir() if p.is_dir()]
    return run


@pytest.fixture(scope="module")
def reports(tmp_path_factory) -> dict[str, Path]:
    runner = CliRunner()
    out: dict[str, Path] = {}
    base = tmp_path_factory.mktemp("reports")
    for kind, args in (
        ("wrist", ["run", str(QUICK), "--no-replay"]),
        ("arm-fourier", ["run", str(_arm_fourier(base)), "--no-replay"]),
        ("identify", ["identify", str(ROOT / "configs" / "tx40.yaml"), "--no-replay"]),
    ):
        folder = base / kind
        result = runner.invoke(app, [*args, "--out", str(folder)])
        assert result.exit_code in (0, 1), result.output
        out[kind] = _only(folder) / "report.html"
    yield out
    shutil.rmtree(base, ignore_errors=True)


@pytest.mark.parametrize("kind", ["wrist", "arm-fourier", "identify"])
def test_headline_on_first_screen_and_no_clipped_cell(chromium, reports, kind):  # noqa: F811
    layout = report_layout(chromium, reports[kind])
    assert layout["summary_bottom"] is not None, "no headline table after '## Summary'"
    assert layout["summary_bottom"] <= REPORT_VIEWPORT["height"], layout
    assert layout["clipped"] == [], layout["clipped"][:5]
    assert layout["wide_tables"] == 0


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
