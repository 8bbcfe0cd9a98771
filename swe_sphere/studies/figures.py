"""Figures and line plots: an Agg ``Figure`` without pyplot (``new_figure``), its PNG written
through a temporary name (``save_png``) or as bytes, x-y lines on linear or log axes
(``line_plot``, ``draw_lines``, ``label_log_axis``) and the sweep's error against cost or Δt per
stepper (``sweep_plot``, for ``swe_sphere.studies.sweep``); ``plotting`` draws a run's maps and
series with them."""

from __future__ import annotations

import contextlib
import io
import math
from pathlib import Path

import numpy as np

DPI = 100  # dots per inch of every figure: its pixels are figsize × DPI
_MATHTEXT: list = []  # the mathtext parser every figure's renderer shares (``new_figure``)


def new_figure(figsize):
    """An empty matplotlib ``Figure`` of ``figsize`` inches at ``DPI`` on an Agg canvas (no pyplot)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=DPI, layout="constrained")
    renderer = FigureCanvasAgg(fig).get_renderer()  # the one its PNG is drawn with: figsize and DPI alike
    # the mathtext (a log axis' 10⁻⁵) parsed once a process, not once a figure: the parser keeps what
    # it parsed, but each renderer had a parser of its own (9 ms a label, a sixth of a sweep figure)
    if not _MATHTEXT:
        _MATHTEXT.append(renderer.mathtext_parser)
    renderer.mathtext_parser = _MATHTEXT[0]
    return fig


def png_bytes(fig) -> bytes:
    """The PNG of ``fig`` (the bytes ``save_png`` writes; Agg draws the same figure to the same bytes)."""
    buf = io.BytesIO()
    with laid_out(fig):
        fig.savefig(buf, format="png", dpi=DPI)
    return buf.getvalue()


@contextlib.contextmanager
def laid_out(fig):
    """``fig`` with its layout engine's positions computed and the engine set aside while the
    block runs (put back after): a ``savefig`` in it draws the figure once, to the same pixels.
    matplotlib's ``savefig`` with a layout engine draws twice, the first time with the output
    switched off to make the layout, the second the picture: on the Agg canvas the first draw,
    which lays out every tick label again, was about a fourth of a map's cost and the series'."""
    engine = fig.get_layout_engine()
    if engine is None or not fig.axes:
        yield fig
        return
    for ax in fig.axes:  # as ``Figure.draw`` does before the layout (inset axes too)
        for each in (ax, *(c for c in ax.get_children() if hasattr(c, "apply_aspect"))):
            locator = each.get_axes_locator()
            each.apply_aspect(locator(each, fig.canvas.get_renderer()) if locator else None)
    try:
        engine.execute(fig)
    except ValueError:  # as ``Figure.draw``: a layout that cannot be made leaves the positions
        pass
    fig.set_layout_engine(None)
    try:
        yield fig
    finally:
        fig.set_layout_engine(engine)


def save_png(fig, path, png: bytes | None = None) -> Path:
    """Write ``fig`` as the PNG ``path`` (figsize × ``DPI`` pixels) through a temporary name; returns the path.
    ``png``: the figure already drawn (``png_bytes``'s), written as it is rather than drawn again."""
    path = Path(path)
    tmp = path.with_name(path.name + ".part.png")
    try:
        if png is not None:
            tmp.write_bytes(png)
        else:
            with laid_out(fig):
                fig.savefig(tmp, dpi=DPI)  # no bbox_inches: the pixel size is figsize × DPI
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    tmp.replace(path)
    return path


def label_log_axis(axis) -> None:
    """Label the log-scale ``axis`` (a matplotlib ``Axis``) in plain numbers (0.5, 1, 2,
    5, 10): the decades, and the minor ticks at 2 and 5 × 10^k where the axis spans
    under two decades, so that one within a decade has more than one label and the
    minor labels never crowd (matplotlib's own wrote 2×10⁰, 3×10⁰, ... into each other)."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    def minor(value, _):
        low, high = sorted(axis.get_view_interval())
        return f"{value:g}" if high < 100 * low and f"{value:.0e}"[0] in "25" else ""

    axis.set_major_locator(LogLocator(base=10))
    axis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
    axis.set_minor_locator(LogLocator(base=10, subs=tuple(range(2, 10))))
    axis.set_minor_formatter(FuncFormatter(minor))


def draw_lines(ax, lines, *, logx=False, logy=False, markers=True, xlabel="", ylabel="", title=""):
    drawn = 0
    for label, x, y in lines:
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        ok = np.isfinite(x) & np.isfinite(y) & ((y > 0) if logy else True) & ((x > 0) if logx else True)
        if not ok.any():
            continue
        ax.plot(x[ok], y[ok], marker="o" if markers else None, markersize=3, linewidth=1.2, label=label)
        drawn += 1
    if logx and drawn:
        ax.set_xscale("log")
        label_log_axis(ax.xaxis)
    if logy and drawn:
        ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title, fontsize=11)
    ax.grid(True, which="major", alpha=0.3)
    if drawn:
        ax.legend(fontsize=8)
    return drawn


def line_plot(
    path, lines, *, xlabel="", ylabel="", title="", logx=False, logy=False, markers=True, figsize=(8.0, 5.0)
) -> Path:
    """Generic x-y line figure to the PNG ``path`` (figsize × 100 dpi pixels).

    ``lines``: iterable of ``(label, x, y)``; non-finite points (and non-positive ones
    on a log axis) are left out. For sweeps: error against wall time, Δt, ..."""
    fig = new_figure(figsize)
    ax = fig.add_subplot()
    if not draw_lines(ax, lines, logx=logx, logy=logy, markers=markers, xlabel=xlabel, ylabel=ylabel, title=title):
        ax.text(0.5, 0.5, "no data", ha="center", va="center", transform=ax.transAxes)
    return save_png(fig, path)


def error_label(y: str) -> str:
    """The axis label of a sweep's error column (``scoring.Scorer.total_errors``' l2 norms):
    "total_error" → "total error: normalized l2 of h + hs", "temporal_error_vorticity" →
    "temporal error: normalized l2 of vorticity"; another column as it is named."""
    kind, sep, field = y.partition("_error")
    if not sep:
        return y.replace("_", " ")
    return f"{kind} error: normalized l2 of {field.lstrip('_').replace('_', ' ') or 'h + hs'}"


def sweep_plot(
    path,
    rows,
    x: str,
    *,
    xlabel: str = "",
    floor: float | None = None,
    y: str = "temporal_error",
    figsize=(8.0, 5.0),
    title: str = "",
) -> Path:
    """Sweep figure (``swe_sphere.studies.sweep``): ``y`` against ``x`` per stepper, log-log, for the
    stable runs of ``rows`` (dicts with ``stepper``, ``stable``, ``x``, ``y``); unstable runs
    are crosses along the top edge at their x. ``floor``: the spatial error, drawn as a
    dashed line, with the sufficient-accuracy level 0.1 × floor dotted for a temporal error.
    ``title``: what was swept (e.g. "tc5_mountain ne8 np4, 5 days"), before the axes' names."""
    steppers = list(dict.fromkeys(r["stepper"] for r in rows))
    lines = []
    for st in steppers:
        # joined in order of Δt, so a line reads as the stepper's cost-accuracy path
        pts = [
            (float(r[x]), float(r[y]))
            for r in sorted(rows, key=lambda r: r.get("dt", 0.0))
            if r["stepper"] == st and r.get("stable", True)
        ]
        lines.append((st, [p[0] for p in pts], [p[1] for p in pts]))
    fig = new_figure(figsize)
    ax = fig.add_subplot()
    drawn = draw_lines(
        ax,
        lines,
        logx=True,
        logy=True,
        xlabel=xlabel or x,
        ylabel=error_label(y),
        title=f"{title + ': ' if title else ''}{y.replace('_', ' ')} against {xlabel or x}",
    )
    if floor is not None and math.isfinite(floor) and floor > 0:
        ax.axhline(floor, color="0.4", linestyle="--", linewidth=1, label="spatial error")
        if y.startswith("temporal"):
            ax.axhline(0.1 * floor, color="0.4", linestyle=":", linewidth=1, label="sufficient accuracy (10 %)")
        ax.set_yscale("log")
        ax.legend(fontsize=8)
    unstable = [(r["stepper"], float(r[x])) for r in rows if not r.get("stable", True) and float(r[x]) > 0]
    if unstable:  # crosses along the top edge, coloured as their stepper's line
        colours = {line.get_label(): line.get_color() for line in ax.get_lines()}
        top = ax.get_xaxis_transform()
        for st, xv in unstable:
            ax.plot([xv], [0.97], marker="x", color=colours.get(st, "k"), transform=top, clip_on=False)
        ax.plot([], [], "kx", label="unstable (at its x)")
        ax.legend(fontsize=8)
    xs = {v for _, xv, _ in lines for v in xv if math.isfinite(v) and v > 0} | {xv for _, xv in unstable}
    if len(xs) == 1:  # one Δt (or cost) only: a factor of 2 either side, not matplotlib's zero-width log axis
        (x0,) = xs
        ax.set_xlim(x0 / 2, x0 * 2)
    if not drawn:
        ax.text(0.5, 0.5, "no stable run", ha="center", va="center", transform=ax.transAxes)
    return save_png(fig, path)


def members_plot(path, spread, y: str = "total_error", *, figsize=(8.0, 5.0), title: str = "") -> Path:
    """Sweep-over-members figure (``studies.sweep.members``): per stepper, the members' mean of
    ``y`` against Δt, log-log, each point with a bar of ± one sample standard deviation over the
    members it was stable in (``spread`` the rows of members.csv: ``stepper``, ``dt``,
    ``<y>_mean``, ``<y>_spread``); a bar's lower end reaching zero is drawn down to the axis'
    foot (a log axis has no zero). ``title`` as ``sweep_plot``'s."""
    fig = new_figure(figsize)
    ax = fig.add_subplot()
    lines = [
        (st, [r["dt"] for r in spread if r["stepper"] == st], [r[f"{y}_mean"] for r in spread if r["stepper"] == st])
        for st in dict.fromkeys(r["stepper"] for r in spread)
    ]
    drawn = draw_lines(
        ax,
        lines,
        logx=True,
        logy=True,
        xlabel="dt [s]",
        ylabel=f"{error_label(y)} (members' mean ± sd)",
        title=f"{title + ': ' if title else ''}{y.replace('_', ' ')} over the members against dt",
    )
    colours = {line.get_label(): line.get_color() for line in ax.get_lines()}
    for r in spread:
        mean, sd = float(r[f"{y}_mean"]), float(r[f"{y}_spread"])
        if r["stepper"] in colours and math.isfinite(mean) and mean > 0 and math.isfinite(sd):
            low = mean - sd if mean > sd else mean * 1e-3  # below the axis' foot once the mean is at most one sd
            ax.errorbar([r["dt"]], [mean], yerr=[[mean - low], [sd]], color=colours[r["stepper"]], capsize=3, lw=1)
    if not drawn:
        ax.text(0.5, 0.5, "no stable run", ha="center", va="center", transform=ax.transAxes)
    return save_png(fig, path)
