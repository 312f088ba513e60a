import base64
import re

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from report_data import minimal_run_data

import ident.report.plots as plots
from ident.report.html import markdown_to_html
from ident.report.plots import convergence_png, envelope, estimate_png, trajectory_png

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
    assert '<h1 id="title">Title</h1>' in body
    assert "<em>it</em>" in body
    assert "<strong>bold</strong>" in body
    assert "<code>x&lt;y</code>" in body
    assert '<a href="replay.html">replay</a>' in body
    assert '<th>name</th><th style="text-align: right">value</th>' in body
    assert '<td>m4</td><td style="text-align: right">1.5</td>' in body
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


# ----------------------------------------------------------------------------- run report

import json  # noqa: E402

import pytest  # noqa: E402

from ident.errors import IdentError  # noqa: E402
from ident.identify.assessment.metrics import error_measures  # noqa: E402
from ident.report.run_report import render_markdown, write_report  # noqa: E402


def test_error_measures_handle_zero_true_values():
    true = np.array([2.0, 0.0, -4.0, 1e-20])
    x = np.array([2.5, 0.01, -4.0, 0.0])
    std = np.array([0.1, 0.01, 0.0, 1.0])
    m = error_measures(x, std, true)
    assert m["rel_error_percent"][0] == pytest.approx(25.0)
    assert m["rel_error_percent"][1] is None  # true is zero: no relative error
    assert m["rel_error_percent"][3] is None  # zero up to round-off
    assert m["normalized_error"][2] is None  # std = 0
    assert m["error_sum_percent"] == pytest.approx(25.0)
    assert m["error_sum_best_percent"] == 0.0
    assert m["within_3std"] == pytest.approx(0.75)
    assert m["max_rel_error"] == pytest.approx(0.25)
    assert "torque_share" not in m
    json.dumps(m, allow_nan=False)


def test_error_measures_in_torque_units():
    true = np.array([1.0, 1e-8])
    x = np.array([1.0 + 1e-12, 2e-8])  # the tiny parameter is 100 % off
    norms = np.array([1.0, 2.0])
    m = error_measures(x, np.ones(2), true, norms, 1.0)
    assert m["torque_share"] == pytest.approx([1.0, 2e-8])
    assert m["torque_error"] == pytest.approx([1e-12, 2e-8])
    assert m["max_torque_error"] == pytest.approx(2e-8)
    assert m["max_rel_error"] == pytest.approx(1e-12)  # only the significant parameter
    assert m["rel_error_percent"][1] == pytest.approx(100.0)


def test_markdown_says_plainly_when_nothing_was_identified():
    md = render_markdown(
        minimal_run_data({}, {"ols": "not identifiable on this trajectory: m1 ..."})
    )
    assert "**Elite 1, ols**: not identifiable" in md
    assert "No estimate" in md
    assert "nan" not in md.lower()
    assert "None" not in md.split("## Configuration snapshot")[0]


def test_markdown_tables_of_an_estimate():
    est = {
        "x": [1.1],
        "std": [0.1],
        "condition_number": 3.0,
        "residual_rms": [0.2],
        "relative_residual": 0.01,
        "message": "ok",
        **error_measures(np.array([1.1]), np.array([0.1]), np.array([1.0])),
    }
    md = render_markdown(minimal_run_data({"ols": est}, {}))
    assert "| `m1` (alone) | kg | 1 | 1.1 | 0.1 | 9.09 | 10 | 1 | — |  |" in md
    assert "## Summary" in md.split("## Identified")[0]
    assert "Standard parameters identifiable alone" in md
    assert "| paper (its 6R robot, DH frames) | 15 | 7 | 8 |" in md
    assert "no DH table" in md  # this stage has no DH-frame comparison


def test_write_report_needs_result_json(tmp_path):
    with pytest.raises(IdentError, match="no result.json"):
        write_report(tmp_path)
    (tmp_path / "result.json").write_text('{"format": "other"}')
    with pytest.raises(IdentError, match="format"):
        write_report(tmp_path)


def _png_size(png: bytes) -> tuple[int, int]:
    import io

    from PIL import Image

    return Image.open(io.BytesIO(png)).size


def test_wide_parameter_figures_are_split_into_panels_under_1210_px():
    """A 7-link arm with friction (84 parameters) used to give a 2300 px wide figure whose
    labels shrank to 5 px in a 1400 px window: now panels are stacked, never wider than
    MAX_WIDTH_IN at the report's dpi, cut where the link changes."""
    from ident.report.plots import DPI, MAX_PER_PANEL, MAX_WIDTH_IN, panel_chunks, parameters_png

    kinds = ("m", "mcx", "mcy", "mcz", "Ixx", "Ixy", "Iyy", "Ixz", "Iyz", "Izz", "fv", "fs")
    names = [f"{k}{link}" for link in range(1, 8) for k in kinds]
    chunks = panel_chunks(names)
    assert [i for c in chunks for i in c] == list(range(len(names)))
    assert all(len(c) <= MAX_PER_PANEL for c in chunks)
    # every cut falls between two links (12 parameters per link: 24 per panel)
    assert all(names[c[0]] == f"m{1 + c[0] // 12}" for c in chunks)
    # grouped base parameters ("Izz2R") belong to their link too
    grouped = [n + ("R" if n.startswith("I") else "") for n in names]
    assert panel_chunks(grouped) == chunks
    rng = np.random.default_rng(0)
    ref = rng.normal(size=len(names))
    png = parameters_png(names, ref * 1.01, 0.01 * np.abs(ref), ref)
    width, height = _png_size(png)
    assert width <= MAX_WIDTH_IN * DPI
    assert height > 3 * 4.2 * DPI  # stacked panels, not squeezed into one
    small_w, small_h = _png_size(parameters_png(names[:10], ref[:10], ref[:10] * 0, ref[:10]))
    assert small_h < 4.5 * DPI  # a short list stays one panel
    wide = estimate_png(names, ref, {"ols": (ref * 1.01, 0.01 * np.abs(ref))})
    assert _png_size(wide)[0] <= MAX_WIDTH_IN * DPI
    t = np.linspace(0, 1, 50)
    q = np.zeros((50, 3))
    path = np.zeros((50, 3))
    assert _png_size(trajectory_png(t, q, q, ["a", "b", "c"], path=path))[0] <= MAX_WIDTH_IN * DPI


def unitless_labels_without_percent(markdown: str) -> list[str]:
    """Labels (table headers and row labels) of relative measures that do not say ``[%]``.

    Every relative measure in a report table is in percent, said in its label, so that no
    table mixes fractions (0.12) with percents (12 %). The summary table writes units inline.
    """
    bad = []
    lines = markdown.splitlines()
    in_summary = False
    for k, line in enumerate(lines):
        if line.startswith("## "):
            in_summary = line.strip() == "## Summary"
        is_table = line.startswith("|") and not re.match(r"^\|[\s:|-]+\|$", line)
        if not is_table or in_summary:
            continue
        cells = [c.strip() for c in line.strip("|").split("|")]
        header = k + 1 < len(lines) and re.match(r"^\|[\s:|-]+\|$", lines[k + 1])
        labels = cells if header else cells[:1]
        bad += [c for c in labels if re.search(r"\brel(ative|\.)", c) and "%" not in c]
    return bad


def test_relative_measures_in_tables_are_percent():
    est = {
        "x": [1.1],
        "std": [0.1],
        "condition_number": 3.0,
        "residual_rms": [0.2],
        "relative_residual": 0.01,
        "message": "ok",
        **error_measures(
            np.array([1.1]), np.array([0.1]), np.array([1.0]), reference_share=np.array([1.0])
        ),
    }
    md = render_markdown(minimal_run_data({"ols": est}, {}))
    assert "| max rel. error, major parameters, ols [%] | 10 |" in md
    assert unitless_labels_without_percent(md) == []
    # the check finds a fraction column
    assert unitless_labels_without_percent("| a | relative residual |\n|---|---|\n| x | 0.1 |") == [
        "relative residual"
    ]


def _summary(md: str) -> str:
    return md.split("## Summary")[1].split("\n## ")[0]


def test_summary_of_a_paper_config_says_its_box_is_expected_and_names_the_box_config():
    """configs/wrist.yaml (the paper's family in its own ±10 box) ends "not identified": the
    summary says it is expected and which config gives a good result; a box of the user's or
    another family gets no such line."""
    data = minimal_run_data({}, {})
    data["config"]["excitation"].update(family="paper_wrist", bounds=None)
    paper = _summary(render_markdown(data))
    assert "| Paper's box | expected:" in paper
    assert "`configs/wrist-box.yaml`" in paper
    data["stage"]["name"] = data["config"]["stage"] = "arm"
    data["config"]["excitation"]["family"] = "paper_arm"
    assert "`configs/arm-box.yaml`" in _summary(render_markdown(data))
    data["config"]["excitation"]["bounds"] = {"a0(1)": [-40.0, 40.0]}
    assert "Paper's box" not in render_markdown(data)
    assert "Paper's box" not in render_markdown(minimal_run_data({}, {}))  # joint_fourier


def test_envelope_keeps_every_buckets_extremes_and_ends_in_order():
    """A long series is drawn through each bucket's first, lowest, highest and last sample:
    compared with those points found one bucket at a time (a stride would lose the spike)."""
    rng = np.random.default_rng(5)
    n, buckets = 30_011, 50
    x = np.arange(n) * 1e-3
    y = np.cumsum(rng.normal(size=n))
    y[17_777] = 1e3  # one sample's spike, e.g. a limit excursion
    xd, yd = envelope(x, y, buckets)
    edges = np.linspace(0, n, buckets + 1).astype(int)
    expected = sorted(
        {
            i
            for a, b in zip(edges[:-1], edges[1:], strict=True)
            for i in (a, b - 1, a + np.argmin(y[a:b]), a + np.argmax(y[a:b]))
        }
    )
    np.testing.assert_array_equal(xd, x[expected])
    np.testing.assert_array_equal(yd, y[expected])
    assert yd.max() == 1e3
    # short series, and series with a gap (nan) the line must keep, are drawn whole
    for short in (y[:200], np.where(np.arange(n) == 5, np.nan, y)):
        assert envelope(x[: short.size], short, buckets)[1].size == short.size


def test_the_paths_z_label_does_not_cover_the_next_panels_y_label(monkeypatch):
    """The 3D path panel draws its z label outside the box the layout spaces panels by: the
    rendered label must stay left of panel (b)'s y label (they overlapped before the gap)."""
    figures = []
    monkeypatch.setattr(plots, "figure_png", lambda fig, dpi=plots.DPI: figures.append(fig))
    t = np.linspace(0.0, 12.0, 3000)
    q = np.column_stack([np.sin(t), -2.0 + np.cos(0.5 * t), 4.0 * np.sin(0.7 * t)])
    path = np.column_stack([1.7 + 0.05 * np.sin(t), 0.03 * np.cos(t), 0.44 + 0.01 * np.sin(2 * t)])
    trajectory_png(t, q, q, ["joint_4", "joint_5", "joint_6"], path=path)
    (fig,) = figures
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    renderer = canvas.get_renderer()
    z_label = fig.axes[0].zaxis.label.get_window_extent(renderer)
    y_label = fig.axes[1].yaxis.label.get_window_extent(renderer)
    assert z_label.x1 < y_label.x0
