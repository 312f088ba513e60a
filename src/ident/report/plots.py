"""Report figures as PNG bytes (matplotlib, Agg canvas, no display and no global state).

Figures are built on :class:`matplotlib.figure.Figure` directly, never through ``pyplot``,
so no backend is selected globally and nothing leaks between calls.

- :func:`convergence_png`: best fitness per iteration of every optimizer run and their mean
  (the paper's Figure 2).
- :func:`trajectory_png`: Cartesian path of the traced point, joint positions and joint
  velocities with their limits (the paper's Figures 3-4).
- :func:`estimate_png`: estimation error of every base parameter in units of its reported
  standard deviation, per estimator.
- :func:`clearance_png` and :func:`limits_png`: the dense safety check of a trajectory, the
  smallest clearance against the margin and the velocity / acceleration / torque ratios
  against 1.
"""

from __future__ import annotations

import io
import re
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
import numpy.typing as npt

__all__ = [
    "clearance_png",
    "convergence_png",
    "estimate_png",
    "figure_png",
    "limits_png",
    "panel_chunks",
    "parameters_png",
    "torque_png",
    "trajectory_png",
]

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

FloatArray = npt.NDArray[np.float64]

#: Resolution of the report figures [dots per inch].
DPI = 110
#: Widest figure [in]: 11 in x 110 dpi = 1210 px, shown at 100 % in a 1400 px browser window
#: (the report's text column is 80 em = 1280 px wide), so labels keep their size.
MAX_WIDTH_IN = 11.0
#: Most parameters on one panel of a parameter figure (0.32 in each: 28 fill 11 in).
MAX_PER_PANEL = 28
#: Buckets of a long time series drawn as its envelope (:func:`envelope`): at least one per
#: pixel column of the widest axes (an 11 in figure at 110 dpi is 1210 px, an axes less).
ENVELOPE_BUCKETS = 1250
#: Most points of the Cartesian path panel (a smooth curve: a stride keeps its shape).
MAX_PATH = 4000


def _figure(width: float, height: float, wspace: float | None = None) -> Figure:
    """A figure of ``width`` x ``height`` [in] (width capped at :data:`MAX_WIDTH_IN`) under
    matplotlib's constrained layout; ``wspace``: its gap between panels (a fraction of the
    figure's width; matplotlib's default when ``None``)."""
    from matplotlib.figure import Figure
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    engine = ConstrainedLayoutEngine() if wspace is None else ConstrainedLayoutEngine(wspace=wspace)
    return Figure(figsize=(min(width, MAX_WIDTH_IN), height), layout=engine)


def _link(name: str) -> str:
    """The last number in a parameter name (its link or joint): ``Ixx3`` and ``Izz3R`` -> ``3``."""
    numbers = re.findall(r"\d+", name)
    return numbers[-1] if numbers else ""


def panel_chunks(names: Sequence[str], max_per_panel: int = MAX_PER_PANEL) -> list[list[int]]:
    """Split parameter positions into panels of at most ``max_per_panel``, between links.

    Panels are filled in order; a panel ends at the last change of link (last number in the
    name) that keeps it at least half full, else at ``max_per_panel``. One panel when
    everything fits.

    Returns
    -------
    :
        Consecutive lists of positions into ``names`` covering ``range(len(names))``.
    """
    n = len(names)
    if n <= max_per_panel:
        return [list(range(n))]
    chunks: list[list[int]] = []
    start = 0
    while start < n:
        stop = min(n, start + max_per_panel)
        if stop < n:
            cuts = [
                k
                for k in range(start + max(1, max_per_panel // 2), stop + 1)
                if _link(names[k - 1]) != _link(names[k])
            ]
            stop = cuts[-1] if cuts else stop
        chunks.append(list(range(start, stop)))
        start = stop
    return chunks


def envelope(
    x: npt.ArrayLike, y: npt.ArrayLike, buckets: int = ENVELOPE_BUCKETS
) -> tuple[FloatArray, FloatArray]:
    """The points of a long curve that its line drawing shows: per bucket of consecutive
    samples, the first, the lowest, the highest and the last (in sample order).

    A line through these points covers the same pixels as the full curve when the buckets
    are at least as many as the axes' pixel columns (each column shows a vertical run from
    the lowest to the highest value, joined to its neighbours at the ends), so a peak or a
    limit excursion is never lost, at a few thousand points instead of one per 1 kHz sample:
    matplotlib's layout, legend placement and rasterization cost grows with the points.

    Parameters
    ----------
    x, y :
        The curve, shape (n,) each.
    buckets :
        Number of buckets; curves of at most ``4 * buckets`` points, or with a non-finite
        value (a gap the line must keep), are returned whole.

    Returns
    -------
    :
        ``(x, y)`` of the kept points, shape (m,) each, m <= 4 * buckets.
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    n = y.shape[0]
    if n <= 4 * buckets or not np.all(np.isfinite(y)):
        return x, y
    edges = np.linspace(0, n, buckets + 1).astype(np.intp)
    starts, stops = edges[:-1], edges[1:] - 1
    # per bucket, the position of its lowest and highest sample (reduceat over each bucket)
    order = np.arange(n)
    low = _bucket_arg(y, starts, order, np.minimum)
    high = _bucket_arg(y, starts, order, np.maximum)
    keep = np.unique(np.concatenate([starts, low, high, stops]))
    return x[keep], y[keep]


def _bucket_arg(
    y: FloatArray, starts: npt.NDArray[np.intp], order: npt.NDArray[np.intp], ufunc: Any
) -> npt.NDArray[np.intp]:
    """Per bucket starting at ``starts``, the first position of its ``ufunc``-extreme value."""
    extreme = ufunc.reduceat(y, starts)
    bucket = np.repeat(np.arange(starts.size), np.diff(np.append(starts, y.size)))
    hit = y == extreme[bucket]
    first = np.full(starts.size, y.size, dtype=np.intp)
    np.minimum.at(first, bucket[hit], order[hit])
    return first


def figure_png(fig: object, dpi: int = DPI) -> bytes:
    """Render a matplotlib ``Figure`` to PNG bytes (no timestamp in the metadata)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})  # type: ignore[attr-defined]
    return buffer.getvalue()


def convergence_png(
    histories: Sequence[npt.ArrayLike],
    *,
    title: str = "Convergence",
    ylabel: str = "best fitness",
    mutations: Sequence[Sequence[int]] | None = None,
) -> bytes:
    """Best objective value per iteration of every run, and their mean (paper Figure 2).

    Parameters
    ----------
    histories :
        One array per run, best fitness after each iteration (index 0: initial swarm),
        shape (nit_k + 1,). Shorter runs are extended with their last value for the mean.
    title, ylabel :
        Labels.
    mutations :
        Per run, the iterations whose population came from a mutation (eq. 8); drawn as
        markers on the run's curve.

    Returns
    -------
    :
        PNG bytes.
    """
    fig = _figure(7.0, 4.0)
    ax = fig.add_subplot()
    runs = [a for a in (np.asarray(h, dtype=float) for h in histories) if a.size]
    if runs:
        length = max(len(h) for h in runs)
        padded = np.array([np.pad(h, (0, length - len(h)), mode="edge") for h in runs])
        for k, h in enumerate(runs):
            (line,) = ax.plot(np.arange(len(h)), h, lw=1.2, label=f"run {k + 1}")
            its = [
                i
                for i in (mutations[k] if mutations and k < len(mutations) else ())
                if 0 <= i < len(h)
            ]
            if its:
                ax.plot(its, h[its], "v", color=line.get_color(), ms=6)
        if mutations and any(len(m) for m in mutations):
            ax.plot([], [], "kv", ms=6, label="mutation")
        ax.plot(np.arange(length), padded.mean(axis=0), "k--", lw=2.0, label="mean")
        finite = padded[np.isfinite(padded)]
        if finite.size and finite.min() > 0 and finite.max() / finite.min() > 50:
            ax.set_yscale("log")
        ax.legend(fontsize="small", ncols=2)
    else:
        ax.text(0.5, 0.5, "no finished run", ha="center", va="center", transform=ax.transAxes)
    ax.set_xlabel("iteration")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    return figure_png(fig)


def trajectory_png(
    t: FloatArray,
    q: FloatArray,
    dq: FloatArray,
    joint_labels: Sequence[str],
    *,
    q_limits: FloatArray | None = None,
    dq_limits: FloatArray | None = None,
    path: FloatArray | None = None,
    title: str = "Excitation trajectory",
) -> bytes:
    """Cartesian path, joint positions and joint velocities (paper Figures 3-4).

    Parameters
    ----------
    t :
        Time [s], shape (n_samples,).
    q, dq :
        Joint positions [rad] and velocities [rad/s] of the plotted joints,
        shape (n_samples, n_joints).
    joint_labels :
        Legend labels, length n_joints.
    q_limits :
        Position limits [rad], shape (n_joints, 2) (lower, upper), drawn dashed.
    dq_limits :
        Velocity limits [rad/s], shape (n_joints,), drawn dashed at +-limit.
    path :
        Cartesian path of the traced point [m], shape (n_samples, 3); panel (a) is omitted
        when ``None``.
    title :
        Figure title.

    Returns
    -------
    :
        PNG bytes.
    """
    n_panels = 3 if path is not None else 2
    # a 3D axes draws its z label outside the box the layout spaces panels by: a wider gap
    fig = _figure(5.0 * n_panels, 4.2, wspace=None if path is None else 0.08)
    fig.suptitle(title)
    colors = [f"C{k}" for k in range(len(joint_labels))]
    panel = 1
    if path is not None:
        _path_panel(fig.add_subplot(1, n_panels, panel, projection="3d"), path)
        panel += 1
    for values, limits, symmetric, label, letter, what in (
        (q, q_limits, False, "position [rad]", "b", "positions"),
        (dq, dq_limits, True, "velocity [rad/s]", "c", "velocities"),
    ):
        ax = fig.add_subplot(1, n_panels, panel)
        panel += 1
        _joint_curves(ax, t, values, limits, symmetric, joint_labels, colors)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"joint {label}")
        letter = letter if path is not None else chr(ord(letter) - 1)
        ax.set_title(f"({letter}) joint {what} (dashed: limits)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small")
    return figure_png(fig)


def _path_panel(ax3: Any, path: FloatArray) -> None:
    """Panel (a) of :func:`trajectory_png`: the Cartesian path (n_samples, 3) [m], its start."""
    path = np.asarray(path, dtype=float)
    # a smooth 1 kHz path: every k-th point and the last draw the same curve
    stride = max(1, len(path) // MAX_PATH)
    drawn = np.vstack([path[:-1:stride], path[-1:]])
    ax3.plot(drawn[:, 0], drawn[:, 1], drawn[:, 2], lw=1.2)
    ax3.scatter(*path[0], color="k", s=12, label="start")
    ax3.set_xlabel("x [m]")
    ax3.set_ylabel("y [m]")
    ax3.set_zlabel("z [m]")
    ax3.set_title("(a) Cartesian path")


def _joint_curves(
    ax: Axes,
    t: FloatArray,
    values: FloatArray,
    limits: FloatArray | None,
    symmetric: bool,
    joint_labels: Sequence[str],
    colors: list[str],
) -> None:
    """One curve per joint of ``values`` (n_samples, n_joints) over ``t`` [s], its limits
    dashed: (n_joints, 2) (lower, upper), or (n_joints,) drawn at +-limit when ``symmetric``."""
    for k, name in enumerate(joint_labels):
        ax.plot(*envelope(t, values[:, k]), color=colors[k], lw=1.2, label=name)
        if limits is not None:
            lim = np.asarray(limits, dtype=float)[k]
            low, high = (-abs(float(lim)), abs(float(lim))) if symmetric else lim
            for value in (low, high):
                if np.isfinite(value):
                    ax.axhline(value, color=colors[k], ls="--", lw=0.8, alpha=0.7)


def estimate_png(
    names: Sequence[str],
    true: FloatArray,
    estimates: Mapping[str, tuple[FloatArray, FloatArray]],
    *,
    title: str = "Estimation error in standard deviations",
) -> bytes:
    """Error of each base parameter divided by its standard deviation, per estimator.

    Parameters
    ----------
    names :
        Base parameter names, length n.
    true :
        True base parameters, shape (n,).
    estimates :
        ``{method: (x, std)}`` with arrays of shape (n,).

    Returns
    -------
    :
        PNG bytes; bars within the grey +-3 band are consistent with the reported std.
    """
    n = len(names)
    chunks = panel_chunks(names)
    per = max(len(c) for c in chunks)
    fig = _figure(max(6.0, 0.35 * per + 2.0), 4.0 * len(chunks))
    axes = fig.subplots(len(chunks), 1, squeeze=False)[:, 0]
    width = 0.8 / max(1, len(estimates))
    z_all = {}
    for method, (x, std) in estimates.items():
        x, std = np.asarray(x, dtype=float), np.asarray(std, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            z_all[method] = np.where(std > 0, (x - true) / std, 0.0)
    for p_k, (ax, chunk) in enumerate(zip(axes, chunks, strict=True)):
        pos = np.arange(len(chunk))
        for k, (method, z) in enumerate(z_all.items()):
            offset = (k - (len(estimates) - 1) / 2) * width
            ax.bar(pos + offset, z[chunk], width, label=method)
        ax.axhspan(-3, 3, color="0.9", zorder=0)
        ax.axhline(0, color="k", lw=0.8)
        ax.set_xticks(pos, [names[i] for i in chunk], rotation=60, ha="right")
        ax.set_xlim(-0.6, max(per, 1) - 0.4)  # same bar width on every panel
        ax.set_ylabel("(identified - true) / std")
        if p_k == 0:
            ax.set_title(title + (f" ({len(chunks)} panels, {n} parameters)" if n > per else ""))
            ax.legend(fontsize="small")
    return figure_png(fig)


def parameters_png(
    names: Sequence[str],
    x: FloatArray,
    std: FloatArray,
    reference: FloatArray,
    *,
    highlight: Sequence[bool] | None = None,
    include: Sequence[bool] | None = None,
    reference_label: str = "true",
    bands: Sequence[float] = (5.0, 20.0),
    title: str = "Identified vs true",
) -> bytes:
    """Relative deviation of each parameter from its reference, with ±3σ bars [%].

    Parameters
    ----------
    names :
        Parameter names, length n (only those with a non-zero reference are drawn).
    x, std, reference :
        Estimate, its standard deviations and the reference (true or nominal) values, same
        unit per entry, shape (n,).
    include, highlight :
        Parameters drawn at all (e.g. the significant ones), and those drawn in the strong
        colour (the major ones), length n; None: all.
    reference_label, bands :
        What the reference is, for the axis label ("true", "nominal", "reference");
        deviations [%] drawn as dashed lines (the verdict's thresholds).

    Returns
    -------
    :
        PNG bytes. The y axis is symmetric-logarithmic (linear within ±1 %), so 0.01 % and
        500 % errors are both readable; a bar reaching across zero means "consistent with
        the reference within 3σ".
    """
    x, std, ref = (np.asarray(a, dtype=float) for a in (x, std, reference))
    keep = _drawn_parameters(ref, include)
    strong = np.ones(len(names), bool) if highlight is None else np.asarray(highlight, bool)
    n = len(keep)
    chunks = panel_chunks([names[int(i)] for i in keep]) if n else [[]]
    per = max(len(c) for c in chunks)
    fig = _figure(max(7.0, 0.32 * per + 2.5), 4.2 * len(chunks))
    axes = fig.subplots(len(chunks), 1, squeeze=False)[:, 0]
    heading = title + f" (bars ±3σ; dashed ±{', ±'.join(f'{b:g}' for b in bands)} %)"
    if n:
        dev = 100.0 * (x[keep] - ref[keep]) / np.abs(ref[keep])
        bar = 300.0 * std[keep] / np.abs(ref[keep])
        labels = [names[int(i)] for i in keep]
        legend = highlight is not None
        _deviation_panels(axes, chunks, labels, dev, bar, strong[keep], bands, per, legend)
    else:
        note = "no parameter with a reference value"
        axes[0].text(0.5, 0.5, note, ha="center", transform=axes[0].transAxes)
    for ax in axes:
        ax.set_ylabel(f"(identified - {reference_label}) / |{reference_label}| [%]")
        ax.grid(alpha=0.3, axis="y")
    if len(chunks) > 1:
        heading += f"\n{n} parameters in {len(chunks)} panels, split between links"
    axes[0].set_title(heading)
    return figure_png(fig)


def _drawn_parameters(ref: FloatArray, include: Sequence[bool] | None) -> npt.NDArray[np.intp]:
    """Positions of the parameters drawn: a non-zero reference ``ref`` (n,), and ``include``."""
    scale = float(np.max(np.abs(ref), initial=0.0))
    drawn = np.abs(ref) > 1e-9 * scale
    if include is not None:
        drawn &= np.asarray(include, bool)
    return np.flatnonzero(drawn)


def _deviation_panels(
    axes: Any,
    chunks: list[list[int]],
    labels: list[str],
    dev: FloatArray,
    bar: FloatArray,
    strong: npt.NDArray[np.bool_],
    bands: Sequence[float],
    per: int,
    legend: bool,
) -> None:
    """One :func:`_deviation_panel` per chunk (indices into the drawn parameters' ``labels``,
    deviations ``dev`` [%], ±3σ bars ``bar`` [%], ``strong`` colour); legend on the first."""
    for p_k, (ax, chunk) in enumerate(zip(axes, chunks, strict=True)):
        _deviation_panel(
            ax,
            [labels[i] for i in chunk],
            dev[chunk],
            bar[chunk],
            strong[chunk],
            bands=bands,
            n_slots=per,
            legend=legend and p_k == 0,
        )


def _deviation_panel(
    ax: Axes,
    labels: list[str],
    dev: FloatArray,
    bar: FloatArray,
    strong: npt.NDArray[np.bool_],
    *,
    bands: Sequence[float],
    n_slots: int,
    legend: bool,
) -> None:
    """One panel of :func:`parameters_png`: deviations ``dev`` [%] with ±``bar`` [%] (3σ),
    shape (k,), major parameters (``strong``) in the strong colour, dashed ``bands`` [%],
    symmetric-log y axis, ``n_slots`` x positions (the same spacing on every panel)."""
    pos = np.arange(len(labels))
    for mask, color, label in (
        (strong, "C3", "major (torque share >= 1 %)"),
        (~strong, "0.55", "minor"),
    ):
        if mask.any():
            ax.errorbar(
                pos[mask],
                dev[mask],
                yerr=bar[mask],
                fmt="o",
                ms=4,
                color=color,
                ecolor=color,
                capsize=2,
                label=label if legend else None,
            )
    for b in bands:
        ax.axhline(b, color="0.4", ls="--", lw=0.7)
        ax.axhline(-b, color="0.4", ls="--", lw=0.7)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_xticks(pos, labels, rotation=60, ha="right")
    ax.set_xlim(-0.6, n_slots - 0.4)  # same spacing on every panel
    if legend:
        ax.legend(fontsize="small", loc="best")


def torque_png(
    t: FloatArray,
    tau: FloatArray,
    predictions: Mapping[str, FloatArray],
    joint_labels: Sequence[str],
    *,
    excluded: npt.NDArray[np.bool_] | None = None,
    xlabel: str = "time [s]",
    units: Sequence[str] | None = None,
) -> bytes:
    """Measured vs predicted joint torques, one panel per joint.

    Parameters
    ----------
    t :
        Time [s], shape (n_samples,).
    tau :
        Measured torques [N*m], shape (n_samples, nv).
    predictions :
        Predicted torques by label, each shape (n_samples, nv); the first is drawn solid red.
    joint_labels :
        Panel labels, length nv.
    excluded :
        Samples not used in the error measures (e.g. below a velocity threshold), shape
        (n_samples, nv), drawn as grey crosses.
    units :
        Torque unit per joint (``"N"`` for a prismatic joint); default ``"N*m"`` for all.

    Returns
    -------
    :
        PNG bytes.
    """
    tau = np.asarray(tau, dtype=float)
    nv = tau.shape[1]
    fig = _figure(11.0, 1.6 * nv + 0.6)
    axes = fig.subplots(nv, 1, sharex=True, squeeze=False)[:, 0]
    styles = [("C3", "-"), ("C0", "--"), ("C2", ":"), ("C1", "-.")]
    for j, ax in enumerate(axes):
        ax.plot(*envelope(t, tau[:, j]), color="k", lw=1.2, label="measured")
        for (label, pred), (color, ls) in zip(predictions.items(), styles, strict=False):
            ax.plot(*envelope(t, np.asarray(pred)[:, j]), color=color, ls=ls, lw=1.0, label=label)
        if excluded is not None and np.asarray(excluded)[:, j].any():
            ex = np.asarray(excluded)[:, j]
            ax.plot(t[ex], tau[ex, j], "x", color="0.6", ms=3, label="not compared")
        ax.set_ylabel(f"{joint_labels[j]}\n[{'N*m' if units is None else units[j]}]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=7, ncol=5)
    axes[-1].set_xlabel(xlabel)
    return figure_png(fig, dpi=90)


def _array(values: Sequence[float | None]) -> FloatArray:
    """A JSON series (``None`` for non-finite) as floats (``nan``)."""
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def clearance_png(
    t: Sequence[float | None],
    min_clearance: Sequence[float | None],
    *,
    clearance_m: float | None,
    closest: tuple[str, float, float] | None = None,
    title: str = "Clearance over time",
) -> bytes:
    """Smallest clearance over the checked pairs per sample, with the required margin.

    Parameters
    ----------
    t :
        Times [s], length n.
    min_clearance :
        Smallest clearance over the link pairs and obstacles at each time [m], length n.
    clearance_m :
        Required clearance [m], drawn dashed (``None``: not drawn).
    closest :
        ``(pair, time [s], clearance [m])`` of the smallest clearance overall, marked and named.
    title :
        Figure title.
    """
    fig = _figure(7.0, 3.6)
    ax = fig.add_subplot(1, 1, 1)
    ax.plot(
        *envelope(_array(t), 1000.0 * _array(min_clearance)),
        lw=1.2,
        color="C0",
        label="min clearance",
    )
    if clearance_m is not None:
        ax.axhline(1000.0 * clearance_m, color="C3", ls="--", lw=1.0, label="required margin")
    ax.axhline(0.0, color="k", lw=0.6)
    if closest is not None:
        pair, when, value = closest
        ax.plot([when], [1000.0 * value], "o", color="C3", ms=6, label=f"closest: {pair}")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("clearance [mm]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return figure_png(fig)


def limits_png(
    t: Sequence[float | None],
    ratios: Mapping[str, Sequence[float | None]],
    *,
    title: str = "Limits",
) -> bytes:
    """Largest ``|value| / limit`` over the joints per sample, per quantity, against 1.

    Parameters
    ----------
    t :
        Times [s], length n.
    ratios :
        ``{"velocity": ..., "acceleration": ..., "torque": ...}``, each of length n (0 where
        no limit is known).
    title :
        Figure title.
    """
    fig = _figure(7.0, 3.6)
    ax = fig.add_subplot(1, 1, 1)
    times = _array(t)
    for k, (name, values) in enumerate(ratios.items()):
        ax.plot(*envelope(times, _array(values)), lw=1.2, color=f"C{k}", label=f"{name} / limit")
    ax.axhline(1.0, color="C3", ls="--", lw=1.0, label="limit")
    ax.set_ylim(bottom=0.0)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("largest |value| / limit over the joints")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small")
    return figure_png(fig)
