"""The figures of ``swe-sphere plot --spectrum`` and ``--zonal-mean``: a run file's kinetic-energy
spectrum (``analysis.kinetic_energy_spectrum``) and zonal means (``analysis.zonal_mean``) at its
output times, as PNGs (and the spectrum's numbers as CSV)."""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from ..io.output_files import atomic_path, check_distinct, check_target
from .analysis import field_at_nodes, kinetic_energy_spectrum, map_field, zonal_mean
from .figures import draw_lines, new_figure, save_png
from .plotting import check_lat_range, check_outdir, check_view, days_to_plot, named_after, open_run, scene_label


def plot_spectrum(spectrum: xr.Dataset, path=None, title: str = ""):
    """E_rot, E_div and E against degree l, log-log, one colour per output time
    (E solid, E_rot dashed, E_div dotted; down to 1e-14 of the largest) of ``analysis.kinetic_energy_spectrum``'s
    Dataset; written to the PNG ``path`` (800 × 500 pixels) unless None.
    Returns the ``matplotlib.figure.Figure`` (Agg canvas, no pyplot)."""
    fig = new_figure((8.0, 5.0))
    ax = fig.add_subplot()
    l, top = spectrum["l"].values, float(spectrum["E"].max())
    for it, day in enumerate(spectrum["time"].values):
        colour = f"C{it % 10}"
        for name, style in (("E", "-"), ("E_rot", "--"), ("E_div", ":")):
            y = spectrum[name].isel(time=it).values
            ok = y > 0
            ax.loglog(l[ok], y[ok], linestyle=style, color=colour, linewidth=1.2, label=f"{name}, day {day:g}")
    if top > 0:  # 14 decades: below, the energy of a field at round-off (1e-30 of a symmetric flow's other parity)
        ax.set_ylim(bottom=max(ax.get_ylim()[0], 1e-14 * top))
    ax.set_xlabel("spherical-harmonic degree l")
    ax.set_ylabel("kinetic energy per unit mass (m$^2$ s$^{-2}$)")
    ax.set_title(f"{title + ': ' if title else ''}kinetic-energy spectrum", fontsize=11)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    if path is not None:
        save_png(fig, path)
    return fig


def plot_zonal_mean(mean: xr.DataArray, path=None, lat_range=None, title: str = ""):
    """``analysis.zonal_mean``'s (time, lat) profile against latitude, one line per
    output time, over ``lat_range`` (south, north degrees; default the globe);
    written to the PNG ``path`` (800 × 500 pixels) unless None. Returns the
    ``matplotlib.figure.Figure``."""
    fig = new_figure((8.0, 5.0))
    ax = fig.add_subplot()
    field = str(mean.name).removesuffix("_zonal_mean")
    long_name, units, scale = map_field(field)[:3]
    lines = [
        (f"day {day:g}", mean["lat"].values, mean.isel(time=it).values * scale)
        for it, day in enumerate(mean["time"].values)
    ]
    draw_lines(
        ax,
        lines,
        markers=False,
        xlabel="latitude (°N)",
        ylabel=f"{field} ({units})",
        title=f"{title + ': ' if title else ''}zonal mean of the {long_name}",
    )
    ax.set_xlim(*(check_lat_range(lat_range) if lat_range is not None else (-90, 90)))
    if path is not None:
        save_png(fig, path)
    return fig


def analysis_names(run_path, days, fields=(), spectrum=False, lat_range=None) -> list[Path]:
    """File names (no folder) of ``plot_analyses``: ``<run>_spectrum_day<D>[_<D>...].png``
    and ``.csv`` when ``spectrum``, ``<run>_<field>_zonal_mean_day<D>[_<D>...][_lat<S>to<N>].png``."""
    stem, when = Path(run_path).stem, "day" + "_".join(f"{d:g}" for d in days)
    band = f"_lat{lat_range[0]:g}to{lat_range[1]:g}" if lat_range is not None else ""
    names = [Path(f"{stem}_spectrum_{when}{ext}") for ext in (".png", ".csv")] if spectrum else []
    return names + [Path(f"{stem}_{field}_zonal_mean_{when}{band}.png") for field in fields]


def plot_analyses(
    run_path, days=None, outdir=".", *, spectrum=False, zonal_fields=(), lat_range=None, overwrite=False, member=None
) -> list[Path]:
    """``swe-sphere plot --spectrum`` and ``--zonal-mean``: the kinetic-energy
    spectrum (``analysis.kinetic_energy_spectrum``: a PNG, ``plot_spectrum``, and
    its numbers as CSV, columns day, l, E_rot, E_div, E in m² s⁻²) and the zonal
    means of ``zonal_fields`` (``plot_zonal_mean``, one PNG per field), at
    ``days`` (default: the last output time), in ``outdir`` (created if missing).

    Every input is checked before anything is written: ``SceneError`` (a ValueError) or
    ``ValueError`` (one line) for a missing file, a day not stored, a field the
    file lacks (vorticity and divergence for the spectrum); ``output.OutputError``
    for an output that exists (unless ``overwrite``) or would replace the run. ``member``: an
    ensemble's (``open_run``)."""
    check_view(member, zonal_fields, spectrum)
    outdir = check_outdir(outdir, lat_range)
    with open_run(run_path, member) as ds:
        days = days_to_plot(ds, days)
        for day in days:
            for field in [*zonal_fields, *(("vorticity", "divergence") if spectrum else ())]:
                field_at_nodes(ds, field, day)
        named = named_after(run_path, member)
        paths = [outdir / name for name in analysis_names(named, days, zonal_fields, spectrum, lat_range)]
        check_distinct(paths, [run_path])
        for path in paths if outdir.is_dir() else ():  # a folder still to be made holds none
            check_target(path, overwrite)
        outdir.mkdir(parents=True, exist_ok=True)
        label = scene_label(ds)
        if spectrum:
            spec = kinetic_energy_spectrum(ds, days)
            plot_spectrum(spec, paths[0], label)
            table = spec[["E_rot", "E_div", "E"]].to_dataframe().reset_index().rename(columns={"time": "day"})
            with atomic_path(paths[1], overwrite=overwrite) as tmp:
                table.to_csv(tmp, index=False, float_format="%.10e")
        for field, path in zip(zonal_fields, paths[2 if spectrum else 0 :]):
            plot_zonal_mean(zonal_mean(ds, field, days), path, lat_range, label)
    return paths
