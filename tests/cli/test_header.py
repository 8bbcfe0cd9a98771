"""``swe-sphere run``'s header: what it says of the grid."""

from __future__ import annotations

import re
from pathlib import Path

from swe_sphere.cli import main

from cli_helpers import (
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
)
from helpers import cli_main, cli_one_line


def test_a_mesh_run_gives_one_smallest_spacing_and_says_it_is_the_one_dt_scales_with(capsys):
    """A mesh run's header gave two "smallest spacings" (the grid line's GLL node distance and
    the mesh line's Dinv-based one); dt scales with the Dinv-based one (``quality.smallest_dx``)."""
    assert main(["mesh", "--ne", "2", "-o", "m.g"]) == 0
    code, out, err = cli_main(
        capsys, "run", "tc2_steady", "--mesh", "m.g", "--days", "0.25", "--device", "cpu", "--no-progress"
    )
    assert code == 0, err
    (line,) = [line for line in out.splitlines() if line.startswith(("grid", "mesh")) and "spacing" in line]
    assert line.startswith("mesh        node spacing (Dinv-based, the one dt scales with on a mesh) "), line
    grid = next(line for line in out.splitlines() if line.startswith("grid "))
    assert grid.endswith("unique nodes"), grid


def test_a_cube_run_gives_its_smallest_spacing_on_the_grid_line(capsys):
    code, out, err = cli_main(capsys, "run", "tc2_steady", "--ne", "2", "--days", "0.25", "--device", "cpu")
    grid = next(line for line in out.splitlines() if line.startswith("grid "))
    assert code == 0 and re.search(r", min node spacing [0-9.]+ km$", grid), grid
    assert "Dinv" not in out


def test_grid_keys_a_mesh_file_would_drop_are_refused(capsys):
    """`--mesh m.g -s grid.stretch_factor=2` ran the mesh as it is, the stretch dropped unread
    (likewise grid.cube, grid.ne); grid.np still applies."""
    assert main(["mesh", "--ne", "2", "-o", "m.g"]) == 0
    run = ["run", "tc2_steady", "--mesh", "m.g", "--days", "0.25", "--device", "cpu", "--no-progress"]
    for key, value in (("stretch_factor", "2"), ("cube", "equidistant"), ("ne", "4")):
        cli_one_line(capsys, [*run, "-s", f"grid.{key}={value}"], 2, f"grid.{key} = ", "mesh m.g", "replaces")
    assert sorted(p.name for p in Path().iterdir()) == ["m.g"]
    assert cli_main(capsys, *run, "-s", "grid.np=3")[0] == 0


def test_a_run_shorter_than_its_output_interval_says_the_two_times_its_file_holds(capsys):
    """``--days 0.25`` of a scene writing every day said "every 1 days" of a file that holds the
    start and the end alone (and then beside them: issue 127, item 15); a run as long as its
    interval, or longer, keeps "every"."""
    import xarray as xr

    code, out, err = cli_main(capsys, "run", "tc2_steady", "--ne", "2", "--days", "0.25", "--device", "cpu")
    (line,) = [line for line in out.splitlines() if line.startswith("output ")]
    assert code == 0 and line.endswith("(at the start and at day 0.25: the run is shorter than its 1-day interval)"), (
        line
    )
    output = Path(line.split()[1])
    with xr.open_dataset(output) as ds:
        assert ds.sizes["time"] == 2
    code, out, err = cli_main(capsys, "run", "tc2_steady", "--ne", "2", "--days", "1", "--device", "cpu", "--overwrite")
    assert code == 0 and f"output      {output.name.replace('0.25d', '1d')} (every day)" in out.splitlines(), out
