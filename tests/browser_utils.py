"""Headless Debian Chromium driven by Playwright, for the replay's browser tests.

Never downloads a browser: Playwright starts ``/usr/bin/chromium`` (``apt-get install
chromium``). Outside CI a missing chromium skips the tests; under ``CI=true`` it fails them.
"""

from __future__ import annotations

import io
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

CHROMIUM = Path(os.environ.get("IDENT_CHROMIUM", "/usr/bin/chromium"))
# Renders WebGL with SwiftShader (CPU) through ANGLE: no GPU, no display needed.
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--disable-quic",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
]
VIEWPORT = {"width": 640, "height": 480}


def require_chromium() -> None:
    """Skip (or fail under CI=true) when Debian's chromium is not installed."""
    if CHROMIUM.is_file():
        return
    message = (
        f"{CHROMIUM} not found: install Debian's chromium with "
        "`apt-get install -y --no-install-recommends chromium` (never a browser download)"
    )
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(message)
    pytest.skip(message)


@pytest.fixture(scope="module")
def chromium() -> Iterator[object]:
    """A headless Chromium with a fresh user-data directory, shared by a test module."""
    require_chromium()
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="ident-chromium-") as user_data:
        with sync_playwright() as playwright:
            context = playwright.chromium.launch_persistent_context(
                user_data,
                executable_path=str(CHROMIUM),
                headless=True,
                args=CHROMIUM_ARGS,
                viewport=VIEWPORT,
                device_scale_factor=1,
            )
            try:
                yield context
            finally:
                context.close()


class PageLog:
    """JavaScript errors and network requests of a page."""

    def __init__(self, page: object) -> None:
        self.errors: list[str] = []
        self.requests: list[str] = []
        page.on("console", self._console)
        page.on("pageerror", lambda e: self.errors.append(f"pageerror: {e}"))
        page.on("request", lambda r: self.requests.append(r.url))

    def _console(self, message: object) -> None:
        if message.type == "error":
            self.errors.append(f"console.error: {message.text}")


def wait_for_robot(page: object, robot_path: str, n_meshes: int, timeout_ms: int = 20000) -> None:
    """Wait until the robot's meshes and the animation are loaded in the page's viewer."""
    entries = [p for p in robot_path.split("/") if p]
    page.wait_for_function(
        """([entries, n]) => {
            if (typeof viewer === "undefined") return false;
            let count = 0;
            viewer.scene_tree.find(entries).object.traverse(o => { if (o.isMesh) count++; });
            return count >= n && viewer.animator.actions.length > 0;
        }""",
        arg=[entries, n_meshes],
        timeout=timeout_ms,
    )


def freeze(page: object, time_s: float) -> None:
    """Pause the animation at ``time_s`` [s] of replay time and let the viewer render it."""
    page.evaluate(
        """async (t) => {
            viewer.animator.pause();
            viewer.animator.seek(t);
            viewer.set_dirty();
            await new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)));
        }""",
        time_s,
    )


def set_visible(page: object, path: str, visible: bool) -> None:
    """Show or hide a scene node (and its subtree) and render."""
    entries = [p for p in path.split("/") if p]
    page.evaluate(
        """async ([entries, visible]) => {
            viewer.scene_tree.find(entries).object.visible = visible;
            viewer.set_dirty();
            await new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)));
        }""",
        [entries, visible],
    )


def canvas_pixels(page: object) -> np.ndarray:
    """RGB pixels of the viewer's WebGL canvas, shape (height, width, 3)."""
    png = page.locator("#meshcat-pane canvas").first.screenshot()
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=np.int16)


def changed_mask(a: np.ndarray, b: np.ndarray, threshold: int = 12) -> np.ndarray:
    """Pixels whose colour differs by more than ``threshold`` in some channel."""
    return np.abs(a - b).max(axis=2) > threshold


def robot_mask(page: object, visuals_path: str, time_s: float) -> tuple[np.ndarray, float]:
    """Pixels covered by the robot at ``time_s``: frame with the robot minus frame without.

    Returns the mask and the share of changed pixels between two renders of the same
    frame with nothing hidden (the negative control).
    """
    freeze(page, time_s)
    shown = canvas_pixels(page)
    again = canvas_pixels(page)
    set_visible(page, visuals_path, False)
    hidden = canvas_pixels(page)
    set_visible(page, visuals_path, True)
    return changed_mask(shown, hidden), float(changed_mask(shown, again).mean())


REPORT_VIEWPORT = {"width": 1400, "height": 900}


def report_layout(context: object, html_path: Path) -> dict:
    """Open a report at 1400x900: the bottom of its headline table [px] and clipped cells.

    Returns ``{"summary_bottom": float | None, "clipped": [cell texts], "wide_tables": n}``:
    a cell is clipped when its content is wider than the cell (``scrollWidth >
    clientWidth``), a table is too wide when it overflows its container.
    """
    page = context.new_page()
    page.set_viewport_size(REPORT_VIEWPORT)
    page.goto(html_path.resolve().as_uri())
    out = page.evaluate(
        """() => {
            const h = document.getElementById("summary");
            const t = h && h.nextElementSibling;
            const cells = [...document.querySelectorAll("th, td")];
            return {
                summary_bottom:
                    t && t.tagName === "TABLE" ? t.getBoundingClientRect().bottom : null,
                clipped: cells.filter(c => c.scrollWidth > c.clientWidth + 1)
                              .map(c => c.textContent.slice(0, 60)),
                wide_tables: [...document.querySelectorAll("table")]
                              .filter(t => t.scrollWidth > document.body.clientWidth + 1).length,
            };
        }"""
    )
    page.close()
    return out


#: JavaScript: per table cell, the words (runs of characters between spaces and hyphens, where
#: a line may legitimately break) whose characters lie on more than one line, measured with
#: Range.getClientRects on each character; per figure, its natural and rendered size.
_READABILITY_JS = """() => {
    const broken = [];
    for (const cell of document.querySelectorAll("th, td")) {
        const walker = document.createTreeWalker(cell, NodeFilter.SHOW_TEXT);
        for (let node = walker.nextNode(); node; node = walker.nextNode()) {
            const text = node.textContent;
            for (const m of text.matchAll(/[^\\s\\-\u2010-\u2014]+/g)) {
                if (m[0].length < 2) continue;
                const tops = new Set();
                for (let k = m.index; k < m.index + m[0].length; k++) {
                    const range = document.createRange();
                    range.setStart(node, k);
                    range.setEnd(node, k + 1);
                    for (const r of range.getClientRects()) {
                        if (r.width > 0) tops.add(Math.round(r.top));
                    }
                }
                if (tops.size > 1) broken.push(m[0]);
            }
        }
    }
    const page = document.documentElement.clientWidth;
    const figures = [...document.querySelectorAll("img")].map(img => {
        const r = img.getBoundingClientRect();
        return {alt: img.alt.slice(0, 60), natural: img.naturalWidth, shown: r.width,
                right: r.right, page: page};
    });
    return {broken_words: broken, figures: figures};
}"""


def report_readability(context: object, html_path: Path) -> dict:
    """Open a report at 1400x900 and measure what makes it hard to read.

    Returns ``{"broken_words": [words], "figures": [{alt, natural, shown, right, page}]}``:
    a word is broken when its characters are laid out on two lines or more (a word wrapped
    at a hyphen or a space is not); a figure is shown at 100 % when ``shown >= natural`` and
    fits when ``right <= page`` (all in CSS px at a device scale factor of 1).
    """
    page = context.new_page()
    page.set_viewport_size(REPORT_VIEWPORT)
    page.goto(html_path.resolve().as_uri())
    page.wait_for_load_state("load")
    out = page.evaluate(_READABILITY_JS)
    page.close()
    return out
