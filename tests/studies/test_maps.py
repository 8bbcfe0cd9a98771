"""Maps from Python: ``swe_sphere.remap_dataset`` puts a run on a lat-lon grid
whose fields plot as maps, and the plotting functions return their figures."""

from __future__ import annotations

import os

import matplotlib
import numpy as np
import pytest
from matplotlib.figure import Figure

import swe_sphere
from swe_sphere.cli import main
from swe_sphere.studies import plotting

# The README's Python map example, run as written (the run file made by the fixture).
EXAMPLE = """
import matplotlib.pyplot as plt
import swe_sphere
ll = swe_sphere.remap_dataset("tc5.nc")   # the run on a 1-degree lat-lon grid
ll.h_surface.sel(time=1).plot()           # free-surface height at day 1: a lat-lon map
plt.savefig("tc5_day1.png")
"""


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("maps")
    assert (
        main(
            [
                "run",
                "tc5_mountain",
                "--ne",
                "2",
                "--np",
                "4",
                "--days",
                "1",
                "--device",
                "cpu",
                "--no-progress",
                "--output",
                str(d / "tc5.nc"),
            ]
        )
        == 0
    )
    return d


def test_remap_dataset_of_a_run_file_is_a_lat_lon_dataset(run_dir):
    ll = swe_sphere.remap_dataset(run_dir / "tc5.nc", resolution=2.0)
    day1 = ll.h.sel(time=1)
    assert day1.dims == ("lat", "lon") and day1.shape == (91, 180)
    assert ll.lat.values[[0, -1]].tolist() == [-90.0, 90.0] and ll.lon.values[[0, -1]].tolist() == [0.0, 358.0]
    assert ll.h_surface.attrs["units"] == "m" and ll.attrs["case"] == "tc5_mountain"
    # the flow is a few hundred metres around h0 + hs = 5960 m at most (TC5's mean depth)
    surface = ll.h_surface.sel(time=1).values
    assert 4500 < surface.min() < surface.max() < 6100
    np.testing.assert_array_equal(
        ll.mass_change.values, swe_sphere.remap_dataset(run_dir / "tc5.nc", 90).mass_change.values
    )


def test_remap_dataset_refuses_what_is_not_a_run(run_dir, tmp_path):
    with pytest.raises(swe_sphere.SceneError, match="file not found: .*nope.nc"):
        swe_sphere.remap_dataset(tmp_path / "nope.nc")
    (tmp_path / "text.nc").write_text("not netCDF")
    with pytest.raises(ValueError, match="text.nc: not a readable netCDF file"):
        swe_sphere.remap_dataset(tmp_path / "text.nc")
    with pytest.raises(ValueError, match="must divide 180"):
        swe_sphere.remap_dataset(run_dir / "tc5.nc", 7)


def test_the_readme_example_draws_a_lat_lon_map(run_dir, monkeypatch):
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    monkeypatch.chdir(run_dir)
    assert len(EXAMPLE.strip().splitlines()) <= 6
    try:
        exec(EXAMPLE, {})
        ax = plt.gcf().axes[0]
        (mesh,) = ax.collections
        assert mesh.get_array().shape == (181, 360)
        assert ax.get_xlabel().startswith("lon") and ax.get_ylabel().startswith("lat")
    finally:
        plt.close("all")
    assert os.path.getsize(run_dir / "tc5_day1.png") > 10_000


def test_plot_functions_return_their_figures(run_dir, tmp_path):
    with plotting.open_run(run_dir / "tc5.nc") as ds:
        info = plotting.plot_map(ds, "h_surface", 1.0)
        assert isinstance(info["figure"], Figure) and info["path"] is None
        assert info["figure"].axes[0].get_title() == info["title"]
        written = plotting.plot_map(ds, "u", 0.0, tmp_path / "u.png")
        assert isinstance(written["figure"], Figure) and written["path"] == tmp_path / "u.png"
        series = plotting.plot_series(ds)
        assert isinstance(series, Figure) and [a.get_title() for a in series.axes[:2]] == [
            "invariants",
            "error norms (ref_: against tc5_mountain_T213.nc)",
        ]
        assert isinstance(plotting.plot_series(ds, tmp_path / "s.png"), Figure)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.png", "u.png"]
