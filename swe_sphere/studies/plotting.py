"""Pictures of a run: lat-lon maps of its fields (``plot_map``), its invariants and errors
against time (``plot_series``), its spectrum and zonal means; maps drawn from the
spectral-element solution itself, each element's GLL polynomial evaluated
(``remap.Remapper``) at the centres of a regular lat-lon grid finer than the GLL spacing and
shown cell by cell on a plain longitude-latitude projection (no gaps, no seams at the cube
edges, the date line or the poles), through matplotlib's Agg canvas (``figures``: no pyplot,
headless); a field over the output times as a GIF or MP4 (``animate_run``, matplotlib's own
writers); ``open_run`` and ``open_reference`` give a run's fields at its nodes, and the line
plots (``line_plot``, ``sweep_plot``, ``label_log_axis``) are ``figures``'s, importable here."""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.ticker import MaxNLocator

from ..cases.library import make_case
from ..cases.reference import Reference, cases_of, locate
from ..core.constants import EARTH, PLANET_KEYS, Planet
from ..io.initial_state import SCENE_CASES
from ..io.output_files import check_distinct, check_target
from ..io.remap import Remapper, member_label, member_view, open_netcdf, run_grid
from ..io.run_file import member_statistics
from ..mesh.records import from_json
from .analysis import (
    DAY_TOL,
    DERIVED,
    days_of,
    field_at_nodes,
    map_field,
    run_name,
)
from .figures import DPI, draw_lines, new_figure, png_bytes, save_png

# importable from here as before the line plots had a module of their own
from .figures import error_label as error_label
from .figures import label_log_axis as label_log_axis
from .figures import line_plot as line_plot
from .figures import sweep_plot as sweep_plot

INVARIANTS = ("mass_change", "total_energy_change", "potential_enstrophy_change")
FIGSIZE = (12.0, 6.0)  # map: 1200 × 600 pixels
SERIES_FIGSIZE = (12.0, 5.0)  # 1200 × 500 pixels
MAP_WIDTHS = (400, 4000)  # pixels: a map's width may be chosen in this range (``figure_size``)


# -- reading -----------------------------------------------------------------
def open_run(path, member=None) -> xr.Dataset:
    """A swe_sphere run file, times as model days (``decode_times=False``). An ensemble's (a
    ``member`` dimension, ``swe-sphere run --members``) is read as one run: ``member`` k (its
    fields and series), "mean" (each field's ensemble mean, the series' mean over the members)
    or "spread" (each field's spread, hs zero so that h + hs is h's; the series' standard
    deviation). Raises ``SceneError`` (a ValueError) / ``ValueError`` (one line) for a missing
    or unreadable file, an ensemble's file without ``member`` or another member, or a
    ``member`` for a single run's file."""
    path = Path(path)
    ds = open_netcdf(path)
    if "ncol" not in ds.dims:
        ds.close()
        raise ValueError(f"{path}: not a swe_sphere run file (no ncol dimension)")
    members = ds.sizes.get("member")
    if (members is None) != (member is None):
        ds.close()
        if members is None:
            raise ValueError(f"{path}: a single run's file (--member is for an ensemble's)")
        raise ValueError(
            f"{path}: an ensemble's run file ({members} members): name --member K (0 to {members - 1}), mean or spread"
        )
    if member is not None:
        ds = member_view(ds, path, member, members)
    ds.attrs.setdefault("_path", str(path))
    return ds


@dataclass
class _SpectralReference:
    """A spectral reference file (T213 or T341, ``reference.Reference``) as a comparison source."""

    ref: object
    label: str

    def check(self, field: str, day: float) -> None:
        if field in DERIVED:
            raise ValueError(f"{self.label} has no {field} (the spectral references hold h_surface, u, v)")
        if np.min(np.abs(self.ref.days - day), initial=np.inf) > DAY_TOL:
            raise ValueError(f"day {day:g} not in {self.label} (stored: {', '.join(f'{d:g}' for d in self.ref.days)})")

    def values(self, field: str, day: float, lat, lon, remapper=None) -> np.ndarray:
        r = self.ref.at(day, lat, lon)
        return np.hypot(r["u"], r["v"]) if field == "speed" else r[field]


@dataclass
class _Run:
    """Another run file as a comparison source, interpolated by its own GLL polynomials."""

    ds: xr.Dataset
    label: str
    _last: tuple = ()  # (lat, lon, Remapper) of the last points it was asked for

    def check(self, field: str, day: float) -> None:
        field_at_nodes(self.ds, field, day)

    def values(self, field: str, day: float, lat, lon, remapper=None) -> np.ndarray:
        """``field`` at ``day`` at the points ``lat``, ``lon`` (radians). ``remapper``: one to those
        points (the map's, ``plot_remapper``'s), used where the run is on its grid; the last points'
        kept for the next field or day (the run's nodes, each map's l2): a ``Remapper`` of the
        plotting grid took 0.4 s at ne16 np4, 0.8 at ne2 np8, and gives the same bits again."""
        grid = run_grid(self.ds)
        if remapper is None or remapper.grid is not grid:
            last_lat, last_lon, remapper = self._last or (None, None, None)
            if (
                remapper is None
                or remapper.grid is not grid
                or not (np.array_equal(lat, last_lat) and np.array_equal(lon, last_lon))
            ):
                remapper = Remapper(grid, lat, lon)
                self._last = (np.array(lat), np.array(lon), remapper)
        return remapper(field_at_nodes(self.ds, field, day))


def open_reference(path, case=None):
    """A comparison source for ``--diff``: another run file (has ``ncol``) or a
    reference file, given as a path, a bundled reference's file name or, with the
    run's case object, its truncation ("T341"), as ``case.reference`` takes them
    (``reference.locate``). Raises ``SceneError`` (a ValueError)/``ValueError``."""
    path = locate(str(path), case)
    with open_netcdf(path) as probe:
        is_run = "ncol" in probe.dims
    if is_run:
        ds = open_run(path)
        run_grid(ds)  # validates ne/np against lat/lon
        return _Run(ds, path.name)
    return _SpectralReference(Reference(path), path.name)


def plot_resolution(grid) -> float:
    """Spacing (degrees) of the cell-centre grid maps are drawn on: 0.5°, or 0.25° when the
    mean GLL spacing 90/(ne (np−1)) is below 1° (on a mesh of F elements, ne = √(F/6): the
    uniform cube's of as many elements)."""
    return 0.5 if 90.0 / (math.sqrt(grid.nelem_total / 6) * (grid.np - 1)) >= 1.0 else 0.25


@functools.lru_cache(maxsize=2)
def plot_remapper(grid, res: float, rows: tuple[int, int] | None = None) -> Remapper:
    """Remapper of a run's grid (``run_grid``'s, built once a process) to the cell centres
    of the ``res``-degree plotting grid, (nlat, nlon), or of its rows ``start`` to ``stop`` − 1 alone
    (``rows`` (start, stop): a latitude band's, ``band_rows``; on the cube the same bits as those rows
    of the whole grid's, on a mesh the same values to round-off)."""
    lat_c, lon_c = _centres(*plot_edges(res))
    return Remapper(grid, lat_c if rows is None else lat_c[rows[0] : rows[1]], lon_c)


def band_rows(rows: np.ndarray) -> tuple[int, int]:
    """(start, stop) of the consecutive rows ``latitude_band`` keeps, as ``plot_remapper`` takes them."""
    return int(rows[0]), int(rows[-1]) + 1


def plot_edges(res: float) -> tuple[np.ndarray, np.ndarray]:
    """Cell edges (degrees) of the global plotting grid: lat −90..90, lon 0..360."""
    return np.linspace(-90.0, 90.0, round(180 / res) + 1), np.linspace(0.0, 360.0, round(360 / res) + 1)


def _centres(lat_e, lon_e):
    """Cell centres (radians) as broadcastable (nlat, 1), (1, nlon)."""
    return np.radians(0.5 * (lat_e[1:] + lat_e[:-1]))[:, None], np.radians(0.5 * (lon_e[1:] + lon_e[:-1]))[None, :]


def check_lat_range(lat_range) -> tuple[float, float]:
    """(south, north) degrees with −90 ≤ south < north ≤ 90, else ``ValueError``."""
    south, north = (float(x) for x in lat_range)
    if not (-90 <= south < north <= 90):
        raise ValueError(f"latitude range must satisfy -90 <= south < north <= 90 (got {south:g} {north:g})")
    return south, north


def latitude_band(lat_edges, lat_range) -> tuple[np.ndarray, np.ndarray]:
    """(the edges clipped to the band ``lat_range`` (south, north) degrees, the indices of the rows
    of cells it keeps): a map's or an animation's band (``check_lat_range``'s errors)."""
    south, north = check_lat_range(lat_range)
    rows = np.flatnonzero((lat_edges[1:] > south) & (lat_edges[:-1] < north))
    return np.clip(lat_edges[rows[0] : rows[-1] + 2], south, north), rows


def normalized_l2(area, f, ref) -> float:
    """sqrt(Σ area (f − ref)²) / sqrt(Σ area ref²) (Williamson et al. 1992, eq. 83)."""
    return float(np.sqrt(np.sum(area * (f - ref) ** 2) / np.sum(area * ref**2)))


def draw_map(fig, ax, lon_edges, lat_edges, values, *, cmap, symmetric, label, contours=None):
    """``values`` (nlat, nlon), cells of a regular grid with the given edges (degrees), on a
    lon-lat axes with a colour bar labelled ``label``; ``contours``: levels (an int or a
    sequence) of black contour lines drawn over it (negative ones dashed), or None.
    Equal degrees in x and y when the edges span the globe's latitudes, else stretched."""
    vmin, vmax = float(np.nanmin(values)), float(np.nanmax(values))
    if symmetric:
        vmax = max(abs(vmin), abs(vmax)) or 1.0
        vmin = -vmax
    # a regular grid: imshow draws the same cells as pcolormesh, an order of magnitude faster
    extent = (lon_edges[0], lon_edges[-1], lat_edges[0], lat_edges[-1])
    mesh = ax.imshow(values, cmap=cmap, vmin=vmin, vmax=vmax, origin="lower", extent=extent, interpolation="nearest")
    if contours is not None and vmax > vmin:
        lon_c = 0.5 * (lon_edges[1:] + lon_edges[:-1])
        lat_c = 0.5 * (lat_edges[1:] + lat_edges[:-1])
        ax.contour(lon_c, lat_c, values, levels=contours, colors="k", linewidths=0.5)
    ax.set_xlim(lon_edges[0], lon_edges[-1])
    ax.set_ylim(lat_edges[0], lat_edges[-1])
    span = lat_edges[-1] - lat_edges[0]
    ax.set_aspect("equal" if span > 179 else "auto")
    ax.set_xticks(np.arange(0, 361, 60))
    step = 30 if span > 120 else 15 if span > 45 else 5
    ax.set_yticks(
        np.arange(-90, 91, step)[
            (np.arange(-90, 91, step) >= lat_edges[0]) & (np.arange(-90, 91, step) <= lat_edges[-1])
        ]
    )
    ax.set_xlabel("longitude (°E)")
    ax.set_ylabel("latitude (°N)")
    cbar = fig.colorbar(mesh, ax=ax, shrink=0.85, pad=0.02)
    cbar.set_label(
        label, **({"fontsize": 8} if fig.get_figheight() < 5 else {})
    )  # a small map: the label fits its height
    return mesh


def plot_map(ds, field: str, day: float, path=None, diff=None, lat_range=None, width: int | None = None) -> dict:
    """Draw ``field`` of the run ``ds`` (from :func:`open_run`) at ``day`` (model days, an
    output time), and write it to the PNG ``path`` (1200 × 600 pixels, or ``width`` × ``width``/2) unless None. ``diff``: a source from :func:`open_reference`; then the map is
    run − reference with a symmetric colour map, and the title carries the normalized
    l2 of the difference over the run's nodes (area-weighted). ``lat_range`` (south, north)
    in degrees draws only that band (e.g. (0, 90) for Galewsky et al. 2004, Fig. 4).
    Height fields get contour lines (about 14 levels at a round interval), vorticity
    contours every 2e-5 s⁻¹; the colour bar's label states the interval.

    Returns ``{"figure", "path", "min", "max", "colorbar_label", "title", "contour_interval"}``
    (the interval in the colour bar's units, None without contours): the
    ``matplotlib.figure.Figure`` (Agg canvas: ``figure.savefig`` works, no pyplot
    needed), the PNG written (None without ``path``), min/max of the drawn values
    in file units; plus ``"l2"`` with diff. Raises ``ValueError`` (one line) for an
    unknown field, a day the run does not store, or a run file it cannot read."""
    grid = run_grid(ds)
    long_name, units, scale, cmap, symmetric = map_field(field, ds)
    nodes = field_at_nodes(ds, field, day)
    if diff is not None:
        diff.check(field, day)
    res = plot_resolution(grid)
    lat_e, lon_e = plot_edges(res)
    lat_c, lon_c = _centres(lat_e, lon_e)
    band = None
    if lat_range is not None:  # the band's rows alone remapped
        lat_e, rows = latitude_band(lat_e, lat_range)
        lat_c, band = lat_c[rows], band_rows(rows)
    remapper = plot_remapper(grid, res, band)
    values = remapper(nodes)
    if "_ensemble" in ds.attrs:  # a spread: the drawn members' (``member_view``), not its nodes' interpolated
        members = ds.attrs["_ensemble"]
        drawn = [remapper(field_at_nodes(members.isel(member=k), field, day)) for k in range(members.sizes["member"])]
        values = member_statistics(np.stack(drawn))[1]
    scene = scene_label(ds)
    info = {"path": None if path is None else Path(path)}
    if diff is None:
        title = f"{long_name}, {scene}, day {day:g}"
        shown = values
        draw_symmetric, draw_cmap, label = symmetric, cmap, f"{field} ({units})"
    else:
        ref_grid = diff.values(field, day, lat_c, lon_c, remapper)  # the map's remapper, where the grids are one
        lat_n, lon_n = np.radians(ds["lat"].values), np.radians(ds["lon"].values)
        ref_nodes = diff.values(field, day, lat_n, lon_n)
        l2 = normalized_l2(np.asarray(ds["area"].values), nodes, ref_nodes)
        info["l2"] = l2
        shown = values - ref_grid
        title = f"{long_name}: {scene} − {diff.label}, day {day:g}; normalized l2 = {l2:.3e}"
        draw_symmetric, draw_cmap, label = True, "RdBu_r", f"Δ {field} ({units})"
    info["min"], info["max"] = float(np.nanmin(shown)), float(np.nanmax(shown))
    fig = new_figure(FIGSIZE if width is None else figure_size(width))
    ax = fig.add_subplot()
    info["colorbar_label"], info["title"] = label, title
    contours = interval = None
    if diff is None and field in ("h", "h_surface"):  # about 14 levels at a round interval
        contours = MaxNLocator(nbins=14).tick_values(np.nanmin(shown), np.nanmax(shown))
        interval = float(contours[1] - contours[0])
    elif diff is None and field == "vorticity":
        top = np.ceil(np.nanmax(np.abs(shown * scale)) / 2) * 2
        contours, interval = [c for c in np.arange(-top, top + 1, 2.0) if c != 0], 2.0  # 2e-5 s-1, as Galewsky et al.
    if interval is not None:  # the interval is stated, so a reader can count the lines
        step = f"{interval:g} × {units}" if scale != 1 else f"{interval:g} {units}"  # "2 × 10⁻⁵ s⁻¹", not "2 10⁻⁵"
        label = info["colorbar_label"] = f"{label}; contours every {step}"
    info["contour_interval"] = interval
    draw_map(
        fig, ax, lon_e, lat_e, shown * scale, cmap=draw_cmap, symmetric=draw_symmetric, label=label, contours=contours
    )
    ax.set_title(title, fontsize=11)
    info["figure"] = fig
    if path is not None:
        save_png(fig, path)
    return info


def figure_size(width) -> tuple[float, float]:
    """A map's figure size (inches) ``width`` pixels wide, half as high; ``ValueError`` for a
    width that is not an integer in ``MAP_WIDTHS`` (pixels)."""
    low, high = MAP_WIDTHS
    if isinstance(width, bool) or not isinstance(width, int) or not low <= width <= high:
        raise ValueError(f"--width must be a whole number of pixels in {low}..{high} (got {width})")
    return width / DPI, width / 2 / DPI


def scene_label(ds) -> str:
    """The run file ``ds``'s scene and grid in a title: ``tc5_mountain ne4 np4``; a mesh file's run
    by the file's stem (its ne is 0), a mapped or stretched cube by its label (``mesh.records``)."""
    view = f", ensemble {ds.attrs['_member']}" if "_member" in ds.attrs else ""  # ``open_run``'s member
    try:
        s = json.loads(ds.attrs["scene"])
        record = from_json(s["ne"], s.get("mesh"))
        grid = f"ne{s['ne']}" if record is None else record.label
        return f"{s['name']} {grid} np{s['np']}{view}"
    except (KeyError, ValueError, TypeError):
        return run_name(ds) + view


def plot_series(ds, path=None):
    """Invariants' |relative change| and the error norms in the file against model day,
    two panels; written to the PNG ``path`` (1200 × 500 pixels) unless None.
    Returns the ``matplotlib.figure.Figure`` (Agg canvas, no pyplot)."""
    days = days_of(ds)
    fig = new_figure(SERIES_FIGSIZE)
    left, right = fig.subplots(1, 2, sharex=True)  # the run's span in both, however few points each has
    inv = [(k.replace("_change", ""), days, np.abs(ds[k].values)) for k in INVARIANTS if k in ds.variables]
    if not draw_lines(left, inv, logy=True, xlabel="day", ylabel="|relative change since t = 0|", title="invariants"):
        left.text(
            0.5,
            0.5,
            "no invariants in this file (or all exactly conserved)",
            ha="center",
            va="center",
            transform=left.transAxes,
        )
    norm_names = [
        f"{pre}{n}_{f}" for pre in ("", "ref_") for f in ("h", "h_surface", "wind") for n in ("l1", "l2", "linf")
    ]
    norms = [(k, days, ds[k].values) for k in norm_names if k in ds.variables]
    against = ds.attrs.get("reference", "")  # the run file's truth: "exact solution", a reference file's name or "none"
    title = (
        "error norms against the exact solution"
        if against == "exact solution"
        else f"error norms (ref_: against {against})"
    )
    if not draw_lines(right, norms, logy=True, xlabel="day", ylabel="normalized error", title=title):
        right.text(
            0.5,
            0.5,
            "no exact or reference solution for this case",
            ha="center",
            va="center",
            transform=right.transAxes,
        )
    if days.size > 1 and days[-1] > days[0]:
        left.set_xlim(days[0], days[-1])
    fig.suptitle(scene_label(ds), fontsize=12)
    if path is not None:
        save_png(fig, path)
    return fig


# -- the command ---------------------------------------------------------------
def map_name(run_path, field: str, day: float, diff: bool, lat_range=None) -> str:
    band = f"_lat{lat_range[0]:g}to{lat_range[1]:g}" if lat_range is not None else ""
    return f"{Path(run_path).stem}_{field}_day{day:g}{band}{'_diff' if diff else ''}.png"


def _run_identity(ds) -> tuple[str, dict, int, int]:
    """(case, case parameters, ne, np) of a run file (its ``scene`` attribute)."""
    try:
        scene = json.loads(ds.attrs["scene"])
        return scene["case"], scene.get("case_params", {}), int(scene["ne"]), int(scene["np"])
    except (KeyError, ValueError, TypeError):
        return ds.attrs.get("case", "?"), {}, int(ds.attrs.get("ne", 0)), int(ds.attrs.get("np", 0))


def _run_case(ds):
    """The case object of a run file on its planet (attributes ``planet_radius``,
    ``planet_omega``, ``planet_gravity``; Williamson's Earth in a file from before
    them), or None for a scene this version does not know."""
    case, params, _, _ = _run_identity(ds)
    try:
        return make_case(
            case,
            params,
            Planet.from_table({k: ds.attrs[f"planet_{k}"] for k in PLANET_KEYS if f"planet_{k}" in ds.attrs}),
            SCENE_CASES,
        )
    except ValueError:
        return None


def check_comparable(ds, diff) -> None:
    """Refuse (ValueError) a ``--diff`` against a run of another case (or case
    parameters) or grid, or against a reference that is not of the run's case
    (its title names another, or the case has no reference: ``reference.cases_of``)
    or planet (the references are of Williamson's Earth)."""
    case, params, ne, np_ = _run_identity(ds)
    if isinstance(diff, _Run):
        other = _run_identity(diff.ds)
        if (case, params) != other[:2]:

            def label(c, p):
                return c + "".join(f" {k}={v}" for k, v in p.items())

            raise ValueError(
                f"{diff.label} is a run of case {label(*other[:2])}, not {label(case, params)} (--force to compare anyway)"
            )
        if (ne, np_) != other[2:]:
            raise ValueError(
                f"{diff.label} is a run on ne={other[2]} np={other[3]}, not ne={ne} np={np_} (--force to compare anyway)"
            )
    elif (case_obj := _run_case(ds)) is not None:  # None: a scene this version does not know, nothing to check against
        if case_obj.planet != EARTH:
            raise ValueError(
                f"{diff.label} is a reference of Williamson's Earth, not of the run's planet "
                f"(radius {case_obj.planet.a:g} m) (--force to compare anyway)"
            )
        solves, own = cases_of(diff.ref.path, case_obj)
        if own is None or solves not in (None, own):
            raise ValueError(f"{diff.label} is not a reference of case {case} (--force to compare anyway)")


def check_outdir(outdir, lat_range) -> Path:
    """The output folder of ``plot``, refused (ValueError) if it is a file; ``lat_range`` checked."""
    outdir = Path(outdir)
    if lat_range is not None:
        check_lat_range(lat_range)
    if outdir.exists() and not outdir.is_dir():
        raise ValueError(f"output path is not a directory: {outdir}")
    return outdir


def days_to_plot(ds, days) -> list[float]:
    """``days`` as floats, or the run's last output time when none are given; the run's
    grid checked. ValueError for a run that is not one or holds no output time."""
    run_grid(ds)
    stored = days_of(ds)
    if stored.size == 0:
        raise ValueError(f"{run_name(ds)} holds no output time")
    return [float(stored[-1])] if not days else [float(d) for d in days]


def plot_run(
    run_path,
    fields=("h_surface",),
    days=None,
    diff_path=None,
    outdir=".",
    lat_range=None,
    *,
    force=False,
    overwrite=False,
    member=None,
    width=None,
) -> list[Path]:
    """``swe-sphere plot``: maps of ``fields`` at ``days`` (default: the last output
    time; ``width`` pixels wide, ``figure_size``) and the time-series figure, PNGs in ``outdir``
    (created if missing); of an ensemble's file, of ``member`` (``open_run``; the files' names end
    in ``io.remap.member_label``).

    Every input is checked before anything is written; raises ``SceneError`` (a ValueError) or
    ``ValueError`` (one line) for a missing file, an unknown field or a missing day,
    and (unless ``force``) a ``diff_path`` of another case or grid; ``output.OutputError``
    for a map PNG that exists (unless ``overwrite``) or would replace an input. The
    series figure depends on the run file alone: an existing one with the same
    picture is left as it is (so ``plot --diff`` or other fields after a plain
    ``plot`` go ahead); one with another picture is refused like a map."""
    check_view(member, fields, diff=diff_path is not None)
    outdir = check_outdir(outdir, lat_range)
    ds = open_run(run_path, member)
    named = named_after(run_path, member)
    diff = None
    try:
        days = days_to_plot(ds, days)
        diff = open_reference(diff_path, _run_case(ds)) if diff_path is not None else None
        if diff is not None and not force:
            check_comparable(ds, diff)
        for field in fields:
            for day in days:
                if np.isnan(field_at_nodes(ds, field, day)).all():  # a member dropped at a blow-up
                    raise ValueError(f"{run_path}: {field} holds no number at day {day:g} (a member dropped?)")
                if not math.isfinite(day):
                    raise ValueError(f"day must be finite (got {day})")
                if diff is not None:
                    diff.check(field, day)
        maps = [
            (field, day, outdir / map_name(named, field, day, diff is not None, lat_range))
            for field in fields
            for day in days
        ]
        series = outdir / f"{named.stem}_series.png"
        series_fig = plot_series(ds)
        # drawn here only to compare with a file there, and then written as drawn, not drawn again
        series_png = png_bytes(series_fig) if series.is_file() and not series.is_symlink() else None
        same = series_png is not None and series.read_bytes() == series_png
        pngs = [path for *_, path in maps] + [series]
        check_distinct(pngs, [run_path, diff_path])
        if outdir.is_dir():  # a folder still to be made holds none
            for path in pngs[:-1] if same else pngs:
                check_target(path, overwrite)
        outdir.mkdir(parents=True, exist_ok=True)
        written = [plot_map(ds, field, day, path, diff, lat_range, width)["path"] for field, day, path in maps]
        if not same:
            save_png(series_fig, series, series_png)
        return written + [series]
    finally:
        ds.close()
        if isinstance(diff, _Run):
            diff.ds.close()


# -- zonal means and kinetic-energy spectra (``swe_sphere.studies.analysis``) -----------
def check_view(member, fields=(), spectrum: bool = False, diff: bool = False) -> None:
    """``ValueError`` (one line) for what an ensemble's spread does not hold: the spread of the
    wind speed (not |spread of the wind|), a spectrum (of the spread of the wind) and a
    difference from a reference (a spread is not a state)."""
    if member != "spread":
        return
    if diff:
        raise ValueError("--member spread: --diff compares a state with a reference, and a spread is not a state")
    if "speed" in fields:
        raise ValueError("--member spread: the file holds the spread of u and v, not of the speed")
    if spectrum:
        raise ValueError("--member spread: a kinetic-energy spectrum is of a wind, not of its spread")


def named_after(run_path, member) -> Path:
    """The path a plot's files are named after: the run file's, its stem followed by
    ``io.remap.member_label`` for an ensemble's member, mean or spread."""
    path = Path(run_path)
    return path if member is None else path.with_name(f"{path.stem}_{member_label(member)}{path.suffix}")
