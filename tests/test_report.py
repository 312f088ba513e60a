import base64
import re

import numpy as np

from ident.report.html import markdown_to_html
from ident.report.plots import convergence_png, estimate_png, trajectory_png

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _body(page):
    return page[page.index("<body>") : page.index("</body>")]


def test_markdown_subset_to_html():
    md = (
        "# Title\n\nSome *it* and **bold** `x<y` [replay](replay.html)\n\n"
        "| name | value |\n|---|--:|\n| m4 | 1.5 |\n| a\\|b | 2 |\n\n"
        "- one\n- two\n\n> **warning**: noise-free\n\n```\nraw <b>\n```\n"
    )
    body = _body(markdown_to_html(md, title="R"))
    assert "<h1>Title</h1>" in body
    assert "<em>it</em>" in body
    assert "<strong>bold</strong>" in body
    assert "<code>x&lt;y</code>" in body
    assert '<a href="replay.html">replay</a>' in body
    assert "<th>name</th><th>value</th>" in body
    assert "<td>m4</td><td>1.5</td>" in body
    assert "<td>a|b</td>" in body
    assert "<ul><li>one</li><li>two</li></ul>" in body
    assert "<blockquote><p><strong>warning</strong>: noise-free</p></blockquote>" in body
    assert "<pre><code>raw &lt;b&gt;</code></pre>" in body


def test_html_is_escaped_and_javascript_links_dropped():
    body = _body(markdown_to_html("<script>alert(1)</script> [x](javascript:alert(1))", title="t"))
    assert "<script>" not in body
    assert "<a " not in body


def test_images_are_embedded_or_marked_missing(tmp_path):
    png = convergence_png([np.arange(5.0)[::-1] + 1])
    (tmp_path / "figures").mkdir()
    (tmp_path / "figures" / "disk.png").write_bytes(png)
    md = "![a](figures/mem.png)\n\n![b](figures/disk.png)\n\n![c](figures/none.png)\n"
    page = markdown_to_html(md, title="t", images={"figures/mem.png": png}, base_dir=tmp_path)
    blobs = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert [base64.b64decode(b) for b in blobs] == [png, png]
    assert "missing figure: figures/none.png" in page
    assert "http" not in _body(page)  # nothing fetched from the network


def test_plots_are_deterministic_pngs():
    t = np.linspace(0.0, 10.0, 100)
    q = np.sin(np.outer(t, [1.0, 2.0]))
    dq = np.cos(np.outer(t, [1.0, 2.0]))
    kwargs = dict(
        q_limits=np.array([[-2.0, 2.0], [-1.5, 1.5]]),
        dq_limits=np.array([3.0, 3.0]),
        path=np.c_[np.cos(t), np.sin(t), 0.1 * t],
    )
    a = trajectory_png(t, q, dq, ["j1", "j2"], **kwargs)
    b = trajectory_png(t, q, dq, ["j1", "j2"], **kwargs)
    assert a.startswith(PNG_MAGIC)
    assert a == b
    assert trajectory_png(t, q, dq, ["j1", "j2"]).startswith(PNG_MAGIC)
    conv = convergence_png([np.array([5.0, 3.0, 2.0]), np.array([4.0, 1.0])])
    assert conv.startswith(PNG_MAGIC)
    assert convergence_png([]).startswith(PNG_MAGIC)
    est = estimate_png(["a", "b"], np.zeros(2), {"ols": (np.ones(2), np.array([1.0, 0.0]))})
    assert est.startswith(PNG_MAGIC)
