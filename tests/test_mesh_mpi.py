"""A run on a file-like mesh over several MPI ranks has the same bits as on one: the elements
cut along the curve through their centroids, the DSS summing every copy in the one global order
(real processes under ``mpiexec``; skipped, saying why, where MPI is not installed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi_mesh import final_state
from test_mpi import assert_continues_on_three, assert_same_bits, mpirun, mpirun_python, needs_mpi  # noqa: F401 (a fixture)

from swe_sphere.cli import main
from swe_sphere.grid.refine import Box, refined_cube
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import write_exodus

# one worker runs the MPI tests one after another: each starts up to 4 ranks on this
# machine, and two such jobs at once would share its CPUs with each other as well
pytestmark = pytest.mark.xdist_group("mpi")


@pytest.mark.usefixtures("needs_mpi")
@pytest.mark.parametrize("ranks", [2, 3])
def test_a_run_on_a_mesh_has_the_same_bits_on_any_rank_count(tmp_path, ranks):
    one = final_state()
    script = Path(__file__).with_name("mpi_mesh.py")
    proc = mpirun_python(ranks, [str(script), "out.npz"], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    with np.load(tmp_path / "out.npz") as out:
        assert out["ranks"] == ranks
        assert np.array_equal(out["state"], one)
    assert np.abs(one[2]).max() > 0  # a state, not zeros


@pytest.mark.usefixtures("needs_mpi")
def test_a_run_on_a_mesh_file_has_the_same_bits_on_3_ranks(tmp_path, monkeypatch, capsys):
    """`swe-sphere run --mesh` on the project-written ne2 cube: the run file of 3 ranks (the
    mesh's print_cfl figures gathered on rank 0) is the one process's (this one), bit for bit."""
    write_exodus(tmp_path / "cube2.g", cube_mesh(2))
    args = ["run", "tc5_mountain", "--mesh", "cube2.g", "--days", "0.25", "--no-progress", "--device", "cpu"]
    monkeypatch.chdir(tmp_path)
    assert main([*args, "--output", "r1.nc"]) == 0
    assert "worst element 18 " in capsys.readouterr().out
    proc = mpirun_python(3, ["-m", "swe_sphere.cli", *args, "--output", "r3.nc"], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "worst element 18 " in proc.stdout
    assert_same_bits(tmp_path / "r1.nc", tmp_path / "r3.nc")


@pytest.mark.usefixtures("needs_mpi")
# mrab3 also stops on 2 ranks and continues on 3: 12 s, over the default run's share (slow)
@pytest.mark.parametrize("method", ["mis4a", pytest.param("mrab3", marks=pytest.mark.slow)])
def test_local_time_stepping_has_the_same_bits_on_any_rank_count(tmp_path, method):
    """lts on the ne4 cube refined 2x over TC5's mountain (two levels, 66 and 58 elements),
    each rank stepping its share of both levels: 3 ranks give the one process's run file bit
    for bit; MRAB3 (its levels' histories in the restart file) stopped halfway on 2 ranks and
    continued on 3 ends with the one process's bits."""
    mesh = write_exodus(tmp_path / "r4.g", refined_cube(4, Box(15.0, 45.0, 255.0, 285.0), 1))
    args = ["tc5_mountain", "--mesh", str(mesh), "--stepper", "lts", "-s", f"lts.method={method}", "--dt", "720"]
    args += ["--no-progress"]
    assert main(["run", *args, "--days", "0.25", "--output", str(tmp_path / "r1.nc")]) == 0
    proc = mpirun(3, ["run", *args, "--days", "0.25", "--output", "r3.nc"], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert "levels 2: 66, 58 elements" in proc.stdout
    assert_same_bits(tmp_path / "r1.nc", tmp_path / "r3.nc")
    if method == "mrab3":
        assert_continues_on_three(tmp_path, args, 0.25)
