"""``--precision`` on run, sweep, stability and frontier: the scene's numerics.precision, in the
run's header, run file and restart file; a continuation in its own precision; the refusals made
before anything is written."""

from __future__ import annotations

import netCDF4
import pytest

from swe_sphere.studies import frontier

from cli_helpers import (
    in_tmp,  # noqa: F401  (the fixture: every test in a folder of its own)
    nc_files,
)
from helpers import TINY, cli_main, cli_one_line

RUN = ("run", "tc2_steady", *TINY, "--days", "0.1", "--restart-every", "0.1")


def _precision(path) -> tuple[str, str]:
    """(the global attribute precision, the scene's as the file's JSON holds it) of a run or restart file."""
    with netCDF4.Dataset(path) as ds:
        return ds.precision, ds.scene


def test_a_float32_run_records_its_precision_and_continues_in_it(capsys, tmp_path):
    code, out, err = cli_main(capsys, *RUN, "--precision", "float32", "--output", "r.nc")
    assert code == 0, err
    assert "precision   float32 (tendency and hyperviscosity; state float64)" in out.splitlines()
    for name in ("r.nc", "r.restart.nc"):
        attribute, scene = _precision(name)
        assert attribute == "float32" and '"precision": "float32"' in scene, (name, scene)
    before = nc_files(tmp_path)
    cont = ("run", "--continue", "r.restart.nc", "--days", "0.2", "--device", "cpu", "--no-progress")
    line = cli_one_line(capsys, [*cont, "--precision", "float64"], 2, "r.restart.nc is a run in float32")
    assert line.endswith("continues in it: no --precision float64"), line
    cli_one_line(capsys, [*cont, "--stepper", "implicit"], 2, 'numerics.precision = "float32" with stepper implicit')
    sweep = ("sweep", "--from", "r.restart.nc", "--days", "0.2", "--runs", "rk4@1", "--precision", "float64")
    cli_one_line(capsys, sweep, 2, "r.restart.nc is a run in float32 and continues in it")
    assert nc_files(tmp_path) == before
    code, out, err = cli_main(capsys, *cont, "--precision", "float32", "--output", "c.nc")
    assert code == 0, err
    assert "precision   float32 (tendency and hyperviscosity; state float64)" in out.splitlines()
    assert _precision("c.nc")[0] == "float32"


def test_a_run_is_float64_by_default(capsys):
    code, out, err = cli_main(capsys, *RUN)
    assert code == 0, err
    assert "precision   float64" in out.splitlines()
    name = "tc2_steady_ne2np4_ssprk3_0.1d"  # a float32 run's ends _float32 (cli.run.default_output)
    for path in (f"{name}.nc", f"{name}.restart.nc"):
        attribute, scene = _precision(path)
        assert attribute == "float64" and '"precision"' not in scene  # the scene's record as before the key
    line = cli_one_line(
        capsys,
        ["run", "--continue", f"{name}.restart.nc", "--days", "0.2", "--precision", "float32", "--device", "cpu"],
        2,
    )
    assert (
        line == f"swe-sphere: error: {name}.restart.nc is a run in float64 and continues in it: no --precision float32"
    )


@pytest.mark.parametrize(
    "command",
    [
        ("run", "tc2_steady", *TINY, "--stepper", "epi2"),
        ("sweep", "tc2_steady", "--ne", "2", "--days", "0.1", "--runs", "implicit@1"),
        ("stability", "tc5_mountain", "--steppers", "ssprk3,epi3"),
    ],
)
def test_the_flag_reaches_the_scene_and_its_refusals(capsys, tmp_path, command):
    """float32 with a stepper that differences the RHS: exit 2, one line naming the key, nothing written."""
    name = next(s for s in ("epi2", "implicit", "epi3") if any(s in c for c in command))
    cli_one_line(capsys, [*command, "--precision", "float32"], 2, f'numerics.precision = "float32" with stepper {name}')
    assert list(tmp_path.iterdir()) == []


def test_frontier_passes_the_flag_as_the_override(capsys, monkeypatch):
    """frontier's steppers are explicit ones (none refuses float32): its plan gets the override."""
    given = {}

    def plan(scene, **kw):
        given.update(kw["overrides"])
        raise ValueError("planned")

    monkeypatch.setattr(frontier, "plan", plan)
    args = ("frontier", "tc2_steady", "--ne", "2", "--np", "4", "-s", "output.every_days=0.5")
    cli_one_line(capsys, [*args, "--precision", "float32"], 2, "planned")
    assert given == {"output.every_days": 0.5, "numerics.precision": "float32"}
    line = cli_one_line(capsys, [*args, "--precision", "float64", "-s", "numerics.precision=float32"], 2)
    assert line.endswith("--precision float64 and -s numerics.precision=float32: give one of them"), line
