"""A field of a run file over its output times as one animation: ``swe-sphere plot --animate``
(a GIF by matplotlib's ``PillowWriter``, an MP4 by its ``FFMpegWriter`` where ``ffmpeg`` is on
PATH), each frame drawn as ``plotting.plot_map`` draws a map, on one colour scale."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np

from ..io.output_files import check_distinct, check_target
from ..io.remap import run_grid
from .analysis import days_of, field_at_nodes, time_index
from .figures import new_figure
from .plotting import (
    band_rows,
    check_outdir,
    check_view,
    draw_map,
    figure_size,
    latitude_band,
    map_field,
    named_after,
    open_run,
    plot_edges,
    plot_remapper,
    plot_resolution,
    scene_label,
)

FORMATS = ("gif", "mp4")
ANIMATION_FIGSIZE = (8.0, 4.0)  # 800 x 400 pixels a frame: a GIF of a 6-day run's 25 frames in a few MB at most
ANIMATION_FPS = 4  # frames a second: a day a second at output every 0.25 days


def animation_name(run_path, field: str, fmt: str, lat_range=None) -> str:
    band = f"_lat{lat_range[0]:g}to{lat_range[1]:g}" if lat_range is not None else ""
    return f"{Path(run_path).stem}_{field}{band}.{fmt}"


def check_format(fmt: str) -> str:
    """``fmt`` ("gif" or "mp4"); ``ValueError`` (one line) for another, or for "mp4" without
    ``ffmpeg`` on PATH (matplotlib's ``FFMpegWriter`` runs it)."""
    if fmt not in FORMATS:
        raise ValueError(f"--animate {fmt}: give gif or mp4")
    if fmt == "mp4" and shutil.which("ffmpeg") is None:
        raise ValueError("--animate mp4: ffmpeg is not on PATH (matplotlib writes an MP4 through it); gif needs none")
    return fmt


def animate_run(
    run_path,
    field: str = "h_surface",
    days=None,
    outdir=".",
    lat_range=None,
    *,
    fmt: str = "gif",
    fps: int = ANIMATION_FPS,
    overwrite: bool = False,
    member=None,
    width: int | None = None,
) -> Path:
    """``swe-sphere plot --animate``: ``field`` of the run file ``run_path`` at ``days`` (default:
    every output time; at least two), one frame each, into ``outdir``/``<run>_<field>.<fmt>``
    (``animation_name``; of an ensemble's file, of ``member``), or into ``outdir`` itself where
    it is no folder and its name ends in ``.<fmt>`` (``p.gif``), 800 pixels wide or ``width``. Every input is checked before
    anything is written: ``ValueError`` (one line) for an unknown field or format, a day the run
    does not store, fewer than two frames, a run file it cannot read; ``OutputError`` for a file
    that exists (unless ``overwrite``) or would replace the input. Returns the file's path."""
    from matplotlib.animation import FFMpegWriter, PillowWriter

    check_format(fmt)
    check_view(member, [field])
    named = Path(outdir) if Path(outdir).suffix.lower() == f".{fmt}" and not Path(outdir).is_dir() else None
    outdir = check_outdir(outdir if named is None else named.parent, lat_range)
    ds = open_run(run_path, member)
    try:
        long_name, units, scale, cmap, symmetric = map_field(field, ds)  # a run's tracers too
        grid = run_grid(ds)
        frames = [float(d) for d in (days_of(ds) if not days else days)]
        for day in frames:
            if not math.isfinite(day):
                raise ValueError(f"day must be finite (got {day})")
            time_index(ds, day)  # a day the run does not store: one line
        if len(frames) < 2:
            raise ValueError(f"{run_path}: an animation needs two output times or more (got {len(frames)})")
        path = named or outdir / animation_name(named_after(run_path, member), field, fmt, lat_range)
        check_distinct([path], [run_path])
        if outdir.is_dir():  # a folder still to be made holds none
            check_target(path, overwrite)
        res = plot_resolution(grid)
        lat_e, lon_e = plot_edges(res)
        band = None
        if lat_range is not None:  # the band's rows alone remapped
            lat_e, rows = latitude_band(lat_e, lat_range)
            band = band_rows(rows)
        remapper = plot_remapper(grid, res, band)
        # the frames remapped together: one pass over the remapper's matrix, the same bits as one a frame
        values = remapper(np.stack([field_at_nodes(ds, field, day) for day in frames])) * scale
        scene = scene_label(ds)
    finally:
        ds.close()
    fig = new_figure(ANIMATION_FIGSIZE if width is None else figure_size(width))
    ax = fig.add_subplot()
    # one colour scale over every frame: the first frame drawn with the whole run's range
    low, high = float(np.nanmin(values)), float(np.nanmax(values))
    span = values[0].copy()
    span.flat[0], span.flat[-1] = low, high
    image = draw_map(fig, ax, lon_e, lat_e, span, cmap=cmap, symmetric=symmetric, label=f"{field} ({units})")
    title = ax.set_title("", fontsize=10)

    # the layout made once, on the first frame, and kept: the frames differ in their data and the
    # title's day alone. A draw a frame, the writer's: FuncAnimation drew each frame three times,
    # each with the constrained layout again (25 frames at ne3: 18 s of drawing, now about 5), and
    # the "none" placeholder engine had savefig draw a frame twice (None: once, the same bytes)
    title.set_text(f"{long_name}, {scene}, day {frames[0]:g}")
    fig.canvas.draw()
    fig.set_layout_engine(None)
    writer = PillowWriter(fps=fps) if fmt == "gif" else FFMpegWriter(fps=fps)
    outdir.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".part.{fmt}")
    try:
        with writer.saving(fig, tmp, fig.dpi):
            for k, day in enumerate(frames):
                image.set_data(values[k])
                title.set_text(f"{long_name}, {scene}, day {day:g}")
                writer.grab_frame()
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    tmp.replace(path)
    return path
