"""``swe-sphere plot`` and ``swe_sphere.studies.plotting``: PNG maps (right pixel size, not
blank, units on the colour bar), differences to a T213 reference or another run with
the normalized l2 the run itself reports, the time-series figure, the generic line
plot, and bad input (exit 2, one line, nothing written)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from swe_sphere import cli
from swe_sphere.cases.reference import find_reference
from swe_sphere.cli import main
from swe_sphere.studies import analysis, figures, plotting

from helpers import EIGHTH_DAY, TINY, cli_main, cli_one_line, png_size

TC5_REF = find_reference("tc5_mountain")


def distinct_colours(path: Path) -> int:
    import matplotlib.image

    img = (matplotlib.image.imread(path)[..., :3] * 255).round().astype(np.uint32)
    return len(np.unique(img[..., 0] << 16 | img[..., 1] << 8 | img[..., 2]))


@pytest.fixture
def run_file(tc5_run_file):
    return tc5_run_file


def test_cli_fields_are_the_plotting_fields():
    assert cli.PLOT_FIELDS == tuple(analysis.MAP_FIELDS)


def test_plot_cli_writes_maps_and_series(run_file, tmp_path, capsys):
    outdir = tmp_path / "figs"
    fields = ("h_surface", "vorticity", "divergence", "speed")
    code, out, err = cli_main(capsys, "plot", run_file, "--field", *fields, "--day", "0", "1", "--output", outdir)
    assert code == 0, err
    names = sorted(p.name for p in outdir.iterdir())
    expected = sorted([f"tc5_{f}_day{d}.png" for f in fields for d in (0, 1)] + ["tc5_series.png"])
    assert names == expected
    assert sorted(Path(line).name for line in out.split()) == expected
    for name in names:
        path = outdir / name
        assert path.stat().st_size > 10_000, name
        assert png_size(path) == ((1200, 500) if name.endswith("series.png") else (1200, 600)), name
        assert distinct_colours(path) > 100, name  # a picture, not a blank canvas


def test_a_series_written_over_another_is_drawn_once_as_a_fresh_plot_draws_it(run_file, tmp_path, capsys, monkeypatch):
    """The series figure drawn to compare with a file there is the one written over it, not drawn
    again: a second draw costs as much as the first, and under the constrained layout its pixels
    need not be the first's (tc5 ne2 np8's 5 days: the legend's "best" place moved), so a later
    plot found the file changed and refused it without --overwrite. The fresh plot is the plain
    ``plot RUN``: h_surface at the last day and the series, into the current folder (what
    test_plot_default_is_h_surface_at_the_last_day checked with a plot of its own)."""
    from matplotlib.figure import Figure

    fresh, out = tmp_path / "fresh", tmp_path / "out"
    fresh.mkdir()
    monkeypatch.chdir(fresh)
    code, _, err = cli_main(capsys, "plot", run_file)
    assert code == 0, err
    assert sorted(p.name for p in fresh.iterdir()) == ["tc5_h_surface_day1.png", "tc5_series.png"]
    out.mkdir()
    (out / "tc5_series.png").write_bytes(b"another picture")
    drawn, savefig = [], Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda fig, *a, **k: drawn.append(fig) or savefig(fig, *a, **k))
    assert cli_main(capsys, "plot", run_file, "--output", out, "--overwrite")[0] == 0
    assert len(drawn) == 2 and len(set(map(id, drawn))) == 2  # the map and the series, once each
    assert (out / "tc5_series.png").read_bytes() == (fresh / "tc5_series.png").read_bytes()
    # another field into the folder (no --overwrite): the same series kept as it is, byte for byte
    # (tests/cli/test_messages.py's plot --diff after a plot, the other way in)
    code, _, err = cli_main(capsys, "plot", run_file, "--field", "u", "--output", out)
    assert code == 0, err
    assert sorted(p.name for p in out.iterdir()) == ["tc5_h_surface_day1.png", "tc5_series.png", "tc5_u_day1.png"]
    assert (out / "tc5_series.png").read_bytes() == (fresh / "tc5_series.png").read_bytes()


def test_plot_map_values_and_colour_bar_units(run_file):
    """The values and labels ``plot_map`` returns. Its figures are drawn, not written (no path):
    writing a PNG costs more than the map, and the CLI tests here write each field's (and
    tests/studies/test_maps.py ``plot_map``'s own, given a path)."""
    ds = plotting.open_run(run_file)
    with ds:
        info = plotting.plot_map(ds, "h_surface", 1.0)
        nodes = ds.h.isel(time=1).values + ds.hs.values
        # the drawn field (GLL interpolant at cell centres) stays within the node range up to
        # the interpolant's small over/undershoot
        span = nodes.max() - nodes.min()
        assert nodes.min() - 0.02 * span < info["min"] < nodes.min() + 0.05 * span
        assert nodes.max() - 0.05 * span < info["max"] < nodes.max() + 0.02 * span
        info = plotting.plot_map(ds, "vorticity", 1.0)
        assert abs(info["max"]) < 1e-3 and info["max"] > 0 > info["min"]  # s-1, both signs
        # drawn scaled, labelled so, with the contour interval stated (2e-5 s-1)
        assert info["colorbar_label"] == "vorticity (10$^{-5}$ s$^{-1}$); contours every 2 × 10$^{-5}$ s$^{-1}$"
        assert "day 1" in info["title"] and "tc5_mountain ne2 np4" in info["title"]
        info = plotting.plot_map(ds, "divergence", 1.0)
        assert abs(info["max"]) < 1e-4 and info["max"] > 0 > info["min"]
        assert info["colorbar_label"] == "divergence (10$^{-6}$ s$^{-1}$)"
        infos = {f: plotting.plot_map(ds, f, 0.0) for f in ("h", "u", "speed")}
    interval = infos["h"]["contour_interval"]  # about 14 round levels over the drawn range
    assert 10 <= (infos["h"]["max"] - infos["h"]["min"]) / interval <= 15 and interval in (100.0, 200.0, 250.0, 500.0)
    labels = {f: info["colorbar_label"] for f, info in infos.items()}
    assert labels == {
        "h": f"h (m); contours every {interval:g} m",
        "u": "u (m s$^{-1}$)",
        "speed": "speed (m s$^{-1}$)",
    }


def test_diff_to_t213_carries_the_runs_own_normalized_l2(run_file, tmp_path, capsys):
    ds = plotting.open_run(run_file)
    with ds:
        ref = plotting.open_reference(TC5_REF)
        info = plotting.plot_map(ds, "h_surface", 1.0, diff=ref)
        # the same number the run wrote for day 1 (ref_l2_h_surface, measured 1.30e-3)
        assert info["l2"] == pytest.approx(float(ds.ref_l2_h_surface.values[1]), rel=1e-10)
        assert 1e-4 < info["l2"] < 1e-2
        assert info["min"] < 0 < info["max"]
    code, out, err = cli_main(capsys, "plot", run_file, "--day", "1", "--diff", TC5_REF, "--output", tmp_path / "cli")
    assert code == 0, err
    path = tmp_path / "cli" / "tc5_h_surface_day1_diff.png"
    assert png_size(path) == (1200, 600) and distinct_colours(path) > 100


def test_diff_to_itself_is_zero(run_file):
    ds = plotting.open_run(run_file)
    with ds:
        ref = plotting.open_reference(run_file)
        for field in ("h", "vorticity", "u"):
            info = plotting.plot_map(ds, field, 1.0, diff=ref)
            # the run interpolated to its own nodes: zero up to round-off
            assert info["l2"] < 1e-14 and max(abs(info["min"]), abs(info["max"])) < 1e-12 * (
                1e-5 if field == "vorticity" else 1e4
            )
        ref.ds.close()


def test_lat_range_draws_a_band(run_file, tmp_path, capsys):
    code, out, err = cli_main(
        capsys, "plot", run_file, "--field", "vorticity", "--lat-range", "0", "90", "--output", tmp_path
    )
    assert code == 0, err
    path = tmp_path / "tc5_vorticity_day1_lat0to90.png"
    assert png_size(path) == (1200, 600) and distinct_colours(path) > 100
    ds = plotting.open_run(run_file)
    with ds:
        band = plotting.plot_map(ds, "h", 1.0, lat_range=(-90, 0))
        whole = plotting.plot_map(ds, "h", 1.0)
        grid = plotting.run_grid(ds)
    # the shallowest water is over the mountain (30°N), outside the southern band
    assert whole["min"] < band["min"] - 500 and band["max"] <= whole["max"]
    # the band's rows alone remapped (``plot_remapper``): the whole map's rows, bit for bit
    rows = plotting.latitude_band(plotting.plot_edges(plotting.plot_resolution(grid))[0], (-90, 0))[1]
    image = [np.asarray(info["figure"].axes[0].images[0].get_array()) for info in (band, whole)]
    assert image[0].shape == (rows.size, image[1].shape[1]) and np.array_equal(image[0], image[1][rows])
    for bad in (("90", "0"), ("-100", "10")):
        code, out, err = cli_main(capsys, "plot", run_file, "--lat-range", *bad, "--output", tmp_path / "bad")
        assert code == 2 and "latitude range" in err and not (tmp_path / "bad").exists()


def test_old_files_without_vorticity_still_plot(old_file, tmp_path, capsys):
    code, out, err = cli_main(capsys, "plot", old_file, "--field", "h", "u", "--output", tmp_path)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old_h_day0.png", "old_series.png", "old_u_day0.png"]
    assert png_size(tmp_path / "old_series.png") == (1200, 500)


def test_line_plot(tmp_path):
    x = np.array([1.0, 2.0, 4.0, 8.0])
    path = plotting.line_plot(
        tmp_path / "lines.png",
        [("a", x, 1 / x), ("b", x, 1 / x**2), ("empty", x, np.full(4, np.nan))],
        xlabel="wall time (s)",
        ylabel="l2 error",
        logx=True,
        logy=True,
        title="sweep",
    )
    assert path.is_file() and png_size(path) == (800, 500)
    assert png_size(plotting.line_plot(tmp_path / "big.png", [("a", x, x)], figsize=(6, 3))) == (600, 300)


def test_sweep_plot(tmp_path):
    rows = [
        {"stepper": st, "dt": dt, "wall_time": 100 / dt * k, "temporal_error": 1e-9 * dt**p, "stable": dt < 900}
        for st, k, p in (("ssprk3", 3, 3), ("leapfrog", 1, 2))
        for dt in (100.0, 200.0, 400.0, 800.0, 1600.0)
    ]
    path = plotting.sweep_plot(tmp_path / "s.png", rows, "wall_time", xlabel="wall time [s]", floor=1e-4)
    assert png_size(path) == (800, 500) and distinct_colours(path) > 20
    path = plotting.sweep_plot(tmp_path / "none.png", [{**r, "stable": False} for r in rows], "dt", floor=float("nan"))
    assert png_size(path) == (800, 500)


@pytest.mark.parametrize(
    "args,message",
    [
        (["missing.nc"], "not found"),
        (["RUN", "--day", "3"], "day 3 not in"),
        (["RUN", "--diff", "missing_ref.nc"], "not found"),
        (["RUN", "--diff", "REF", "--day", "0.5"], "day 0.5 not in"),
        (["RUN", "--field", "vorticity", "--diff", "REF"], "no vorticity"),
        (["RUN", "--field", "pv"], "unknown field 'pv'"),
        (["OLD", "--field", "divergence"], "no divergence"),
        (["RUN", "--field", "divergence", "--diff", "REF"], "no divergence"),
        (["OLD", "--field", "vorticity"], "no vorticity"),
        (["REF"], "not a swe_sphere run"),
    ],
)
def test_bad_input_exits_2_one_line_nothing_written(run_file, old_file, tmp_path, monkeypatch, capsys, args, message):
    monkeypatch.chdir(tmp_path)
    subst = {"RUN": str(run_file), "OLD": str(old_file), "REF": str(TC5_REF)}
    args = [subst.get(a, a) for a in args]
    cli_one_line(capsys, ["plot", *args, "--output", tmp_path / "figs"], 2, message)
    assert list(tmp_path.iterdir()) == []


def test_remapped_file_can_be_plotted_by_xarray_users(run_file, tmp_path):
    """The lat-lon file is plain CF: xarray's own plotting draws it."""
    out = tmp_path / "ll.nc"
    assert main(["remap", str(run_file), "--resolution", "2", "--output", str(out)]) == 0
    with xr.open_dataset(out, decode_times=False) as r:
        field = r.h_surface.isel(time=-1)
        assert field.dims == ("lat", "lon") and field.shape == (91, 180)
        fig = figures.new_figure((6, 3))
        ax = fig.add_subplot()
        field.plot(ax=ax)
        figures.save_png(fig, tmp_path / "xr.png")
    assert png_size(tmp_path / "xr.png") == (600, 300)


def test_tc2_plots_say_they_are_against_the_exact_solution(tmp_path, capsys, monkeypatch):
    """TC2's series panel said "against T213"; ``plot --diff T213`` said "reference file not found"."""
    monkeypatch.chdir(tmp_path)
    from swe_sphere.studies.plotting import open_run, plot_series

    assert (
        cli_main(
            capsys,
            "run",
            "tc2_steady",
            *TINY,
            *EIGHTH_DAY,
            "--output",
            "tc2.nc",
        )[0]
        == 0
    )
    ds = open_run(tmp_path / "tc2.nc")
    try:
        assert plot_series(ds).axes[1].get_title() == "error norms against the exact solution"
    finally:
        ds.close()
    cli_one_line(
        capsys,
        ["plot", "tc2.nc", "--diff", "T213"],
        2,
        "no T213 reference for this case: it is scored against its exact solution",
    )
    assert not list(tmp_path.glob("*.png"))


def test_sweep_error_axes_name_the_norm_and_field():
    from swe_sphere.studies.plotting import error_label

    assert error_label("total_error") == "total error: normalized l2 of h + hs"
    assert error_label("temporal_error_vorticity") == "temporal error: normalized l2 of vorticity"
    assert error_label("wall_time") == "wall time"


def shown_labels(ax, axis="x") -> list[str]:
    """The tick labels drawn on ``ax``'s ``axis`` (major and minor) inside its view, in order."""
    ax.figure.canvas.draw()
    which = ax.xaxis if axis == "x" else ax.yaxis
    low, high = sorted(which.get_view_interval())
    ticks = [t for t in which.get_major_ticks() + which.get_minor_ticks() if low <= t.get_loc() <= high]
    return [t.label1.get_text() for t in sorted(ticks, key=lambda t: t.get_loc()) if t.label1.get_text()]


@pytest.mark.parametrize(
    "low, high, labels",
    [
        (0.6, 8.0, ["1", "2", "5"]),  # within a decade: more than the one decade label, none crowding
        (0.15, 0.9, ["0.2", "0.5"]),  # no decade inside at all
        (0.3, 15.0, ["0.5", "1", "2", "5", "10"]),
        (0.01, 100.0, ["0.01", "0.1", "1", "10", "100"]),  # four decades: the decades alone
    ],
)
def test_a_log_axis_is_labelled_in_plain_numbers_that_never_crowd(low, high, labels):
    """A Δt/Δt_g axis from 0.6 to 8 had one label (10⁰) and minor ones written into each other."""
    fig = figures.new_figure((3.2, 3.2))
    ax = fig.add_subplot()
    ax.plot([low, high], [1.0, 2.0])
    ax.set_xscale("log")
    ax.set_xlim(low, high)
    plotting.label_log_axis(ax.xaxis)
    assert shown_labels(ax) == labels


def test_the_series_panels_span_the_runs_days(run_file):
    """The error panel of a run whose reference stores only day 0 showed day 0 alone,
    centred on −0.04..0.04; both panels now span the run's output days."""
    with xr.open_dataset(run_file, decode_times=False) as ds:
        fig = plotting.plot_series(ds)
        days = ds.time.values
    left, right = fig.axes[:2]
    assert left.get_xlim() == right.get_xlim() == (days[0], days[-1])


def test_a_figure_is_laid_out_once_to_the_bytes_of_matplotlibs_savefig(run_file):
    """``figures.png_bytes`` and ``save_png`` make the constrained layout and draw once
    (``figures.laid_out``), where matplotlib's ``savefig`` draws twice, and every figure's renderer
    shares one mathtext parser (``new_figure``): the same PNG bytes as matplotlib's own savefig with
    a parser of the figure's own, of a map (a colour bar, equal aspect) and of the series (two log
    panels of 10⁻ᵏ labels, legends), each figure drawn fresh; the figure keeps its layout engine."""
    import io

    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.layout_engine import ConstrainedLayoutEngine

    def map_figure():
        return plotting.plot_map(ds, "vorticity", 1.0, lat_range=(0, 90))["figure"]

    with plotting.open_run(run_file) as ds:
        for make in (map_figure, lambda: plotting.plot_series(ds)):
            theirs, fig = io.BytesIO(), make()
            fig.canvas.get_renderer().mathtext_parser = RendererAgg(1, 1, figures.DPI).mathtext_parser  # its own
            fig.savefig(theirs, format="png", dpi=figures.DPI)
            fig = make()
            assert (
                fig.canvas.get_renderer().mathtext_parser
                is figures.new_figure((1, 1)).canvas.get_renderer().mathtext_parser
            )
            assert figures.png_bytes(fig) == theirs.getvalue()
            assert isinstance(fig.get_layout_engine(), ConstrainedLayoutEngine)


def test_a_title_names_a_mesh_run_by_its_mesh():
    """A run on a mesh file (its scene's ne 0) is titled by the file's stem, a stretched cube by its
    label, the equiangular cube by ne as before (``scene_label``), not "ne0"."""
    import json

    mesh = {"map": "element_local", "file": "/data/mountain_10_x2.g", "sha256": "0", "nelem": 24}
    stretched = {"map": "element_local", "stretch_factor": 2.5, "target_lat": 40.0, "target_lon": 270.0}
    for ne, record, said in ((0, mesh, "tc5_mountain mountain_10_x2 np4"), (4, stretched, "tc5_mountain ne4c2.5 np4")):
        scene = {"name": "tc5_mountain", "ne": ne, "np": 4, "mesh": record}
        assert plotting.scene_label(xr.Dataset(attrs={"scene": json.dumps(scene)})) == said
    cube = {"name": "tc5_mountain", "ne": 4, "np": 4}
    assert plotting.scene_label(xr.Dataset(attrs={"scene": json.dumps(cube)})) == "tc5_mountain ne4 np4"
