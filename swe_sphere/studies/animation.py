"""A field of a run file over its output times as one animation: ``swe-sphere plot --animate``
(a GIF written as matplotlib's ``PillowWriter`` writes one, by Pillow, each frame drawn over the
map's background drawn once: ``drawn_frames``; an MP4 by matplotlib's ``FFMpegWriter`` where
``ffmpeg`` is on PATH), each frame drawn as ``plotting.plot_map`` draws a map, on one colour scale."""

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
    MAP_FIELDS,
    band_rows,
    check_outdir,
    check_view,
    draw_map,
    figure_size,
    latitude_band,
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
    (``animation_name``; of an ensemble's file, of ``member``), 800 pixels wide or ``width``. Every input is checked before
    anything is written: ``ValueError`` (one line) for an unknown field or format, a day the run
    does not store, fewer than two frames, a run file it cannot read; ``OutputError`` for a file
    that exists (unless ``overwrite``) or would replace the input. Returns the file's path."""
    from matplotlib.animation import FFMpegWriter

    check_format(fmt)
    check_view(member, [field])
    if field not in MAP_FIELDS:
        raise ValueError(f"unknown field {field!r} (known: {', '.join(MAP_FIELDS)})")
    outdir = check_outdir(outdir, lat_range)
    ds = open_run(run_path, member)
    try:
        grid = run_grid(ds)
        frames = [float(d) for d in (days_of(ds) if not days else days)]
        for day in frames:
            if not math.isfinite(day):
                raise ValueError(f"day must be finite (got {day})")
            time_index(ds, day)  # a day the run does not store: one line
        if len(frames) < 2:
            raise ValueError(f"{run_path}: an animation needs two output times or more (got {len(frames)})")
        path = outdir / animation_name(named_after(run_path, member), field, fmt, lat_range)
        check_distinct([path], [run_path])
        if outdir.is_dir():  # a folder still to be made holds none
            check_target(path, overwrite)
        long_name, units, scale, cmap, symmetric = MAP_FIELDS[field]
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
    # title's day alone (FuncAnimation drew each frame three times, each with the constrained layout)
    title.set_text(f"{long_name}, {scene}, day {frames[0]:g}")
    fig.canvas.draw()
    fig.set_layout_engine(None)  # not "none", whose placeholder engine has savefig draw a frame twice
    titles = [f"{long_name}, {scene}, day {day:g}" for day in frames]
    outdir.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + f".part.{fmt}")
    try:
        if fmt == "gif":
            write_gif(tmp, drawn_frames(fig, ax, image, title, values, titles), fps)
        else:  # ffmpeg reads each frame as matplotlib's writer draws it, the whole figure
            writer = FFMpegWriter(fps=fps)
            with writer.saving(fig, tmp, fig.dpi):
                for data, text in zip(values, titles):
                    image.set_data(data)
                    title.set_text(text)
                    writer.grab_frame()
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    tmp.replace(path)
    return path


def drawn_frames(fig, ax, image, title, values, titles):
    """The frames of an animation of the map ``ax`` of ``fig`` (drawn once, its layout kept): for each
    of ``values`` and ``titles``, the RGBA pixels (h, w, 4) of the figure with ``image`` showing those
    values and ``title`` that text, the bits a full draw of the figure makes. The axes' labels and
    tick labels, the colour bar and the rest are drawn once, into a background kept; a frame restores
    it and draws, in ``Axes.draw``'s order, the image, what a full draw puts over it (the tick marks,
    then the axes' frame) and the title. The pixels those touch are touched by nothing else (the tick
    labels stand a pad off the tick marks, the colour bar a pad off the axes), so the order in which
    the two sets are drawn does not change a bit; laying out the tick labels again, each frame, was
    most of a frame's drawing."""
    canvas = fig.canvas
    moving = []
    for child in sorted(ax.get_children(), key=lambda artist: artist.get_zorder()):  # ``Axes.draw``'s order
        if child is image or child is title or child in ax.spines.values():
            moving.append(child)
        elif child in (ax.xaxis, ax.yaxis):  # below the frame: the axes' zorder 1.5 to its 2.5
            moving += [line for tick in drawn_ticks(child) for line in (tick.gridline, tick.tick1line, tick.tick2line)]
    moving = [artist for artist in moving if artist.get_visible()]
    for artist in moving:
        artist.set_visible(False)
    try:
        canvas.draw()
        background = canvas.copy_from_bbox(fig.bbox)
    finally:
        for artist in moving:
            artist.set_visible(True)
    renderer = canvas.get_renderer()
    for data, text in zip(values, titles):
        canvas.restore_region(background)
        image.set_data(data)
        title.set_text(text)
        for artist in moving:
            artist.draw(renderer)
        yield np.asarray(canvas.buffer_rgba())


def drawn_ticks(axis) -> list:
    """The ticks of ``axis`` (major, then minor) a draw of it draws: those at its locations within its view (as
    ``matplotlib.axis.Axis`` picks them)."""
    low, high = sorted(axis.get_view_interval())
    close = 1e-10 * max(abs(low), abs(high), 1.0)
    ticks = [*axis.get_major_ticks(len(axis.get_majorticklocs())), *axis.get_minor_ticks(len(axis.get_minorticklocs()))]
    return [tick for tick in ticks if low - close <= tick.get_loc() <= high + close]


def write_gif(path, frames, fps: int) -> Path:
    """The RGBA ``frames`` as the GIF ``path``, ``fps`` a second, looping, as matplotlib's ``PillowWriter``
    writes them (the same bytes): a frame without transparency as RGB, Pillow's quantizing."""
    from PIL import Image

    images = []
    for rgba in frames:
        height, width = rgba.shape[:2]
        im = Image.frombytes("RGBA", (width, height), rgba.tobytes())
        images.append(im if im.getextrema()[3][0] < 255 else im.convert("RGB"))
    images[0].save(path, format="GIF", save_all=True, append_images=images[1:], duration=int(1000 / fps), loop=0)
    return Path(path)
