"""A run on a file-like mesh over several MPI ranks has the same bits as on one: the elements
cut along the curve through their centroids, the DSS summing every copy in the one global order
(real processes under ``mpiexec``; skipped, saying why, where MPI is not installed)."""

from __future__ import annotations

import functools
from pathlib import Path

import numpy as np
import pytest
from mpi_mesh import final_state
from test_mpi import assert_continued, assert_same_bits, continue_on_three, launches, over_ranks  # noqa: F401 (fixtures)

from swe_sphere.cli import main
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import write_exodus

from meshes import refined_ne4

# one worker runs the MPI tests one after another: each starts up to 4 ranks on this
# machine, and two such jobs at once would share its CPUs with each other as well
pytestmark = pytest.mark.xdist_group("mpi")
MESH_SCRIPT = str(Path(__file__).parents[1] / "mpi_mesh.py")


def mesh_file_args(folder: Path) -> list[str]:
    """``swe-sphere run`` of TC5 on the project-written ne2 cube (written in ``folder``), its output aside."""
    if not (folder / "cube2.g").exists():
        write_exodus(folder / "cube2.g", cube_mesh(2))
    args = ["run", "tc5_mountain", "--mesh", str(folder / "cube2.g"), "--days", "0.25", "--no-progress"]
    return [*args, "--device", "cpu"]


def lts_args(folder: Path, method: str) -> list[str]:
    """lts (``method``) on the ne4 cube refined 2x over TC5's mountain (written in ``folder``), no days, no output."""
    if not (folder / "r4.g").exists():
        write_exodus(folder / "r4.g", refined_ne4())
    args = ["tc5_mountain", "--mesh", str(folder / "r4.g"), "--stepper", "lts", "-s", f"lts.method={method}"]
    return [*args, "--dt", "720", "--no-progress"]


def lts_commands(folder: Path, method: str) -> dict[int, list[list[str]]]:
    """The lts run on 3 ranks; MRAB3's also stopped halfway on 2 and continued on 3 (``continue_on_three``)."""
    args = lts_args(folder, method)
    three = [["run", *args, "--days", "0.25", "--output", str(folder / "r3.nc")]]
    if method != "mrab3":
        return {3: three}
    more = continue_on_three(folder, args, 0.25)
    return {2: more[2], 3: three + more[3]}


# each test's commands on 2 and 3 ranks, launched with test_mpi's (``launches``: a rank's start costs more than these runs)
OVER_RANKS = {
    **{
        f"test_a_run_on_a_mesh_has_the_same_bits_on_any_rank_count[{r}]": (
            lambda d, r=r: {r: [[MESH_SCRIPT, str(d / "out.npz")]]}
        )
        for r in (2, 3)
    },
    "test_a_run_on_a_mesh_file_has_the_same_bits_on_3_ranks": lambda d: {
        3: [[*mesh_file_args(d), "--output", str(d / "r3.nc")]]
    },
    **{
        f"test_local_time_stepping_has_the_same_bits_on_any_rank_count[{m}]": functools.partial(lts_commands, method=m)
        for m in ("mis4a", "mrab3")
    },
}


@pytest.mark.parametrize("ranks", [2, 3])
def test_a_run_on_a_mesh_has_the_same_bits_on_any_rank_count(request, ranks):
    """``mpi_mesh.py``'s run (TC6 on the icosahedral mesh, its nodes shared by 3 to 6 elements) on
    2 and 3 ranks ends with the one process's bits."""
    one = final_state()
    folder, _ = request.getfixturevalue("over_ranks")  # test_mpi's
    with np.load(folder / "out.npz") as out:
        assert out["ranks"] == ranks
        assert np.array_equal(out["state"], one)
    assert np.abs(one[2]).max() > 0  # a state, not zeros


def test_a_run_on_a_mesh_file_has_the_same_bits_on_3_ranks(request, capsys):
    """`swe-sphere run --mesh` on the project-written ne2 cube: the run file of 3 ranks (the
    mesh's print_cfl figures gathered on rank 0) is the one process's (this one), bit for bit."""
    folder, said = request.getfixturevalue("over_ranks")  # test_mpi's
    assert main([*mesh_file_args(folder), "--output", str(folder / "r1.nc")]) == 0
    assert "worst element 18 " in capsys.readouterr().out
    assert "worst element 18 " in said[3][0]
    assert_same_bits(folder / "r1.nc", folder / "r3.nc")


# mrab3 also stops on 2 ranks and continues on 3: 12 s, over the default run's share (slow)
@pytest.mark.parametrize("method", ["mis4a", pytest.param("mrab3", marks=pytest.mark.slow)])
def test_local_time_stepping_has_the_same_bits_on_any_rank_count(request, method):
    """lts on the ne4 cube refined 2x over TC5's mountain (two levels, 66 and 58 elements),
    each rank stepping its share of both levels: 3 ranks give the one process's run file bit
    for bit; MRAB3 (its levels' histories in the restart file) stopped halfway on 2 ranks and
    continued on 3 ends with the one process's bits."""
    folder, said = request.getfixturevalue("over_ranks")  # test_mpi's
    args = lts_args(folder, method)
    assert main(["run", *args, "--days", "0.25", "--output", str(folder / "r1.nc")]) == 0
    assert "levels 2: 66, 58 elements" in said[3][0]
    assert_same_bits(folder / "r1.nc", folder / "r3.nc")
    if method == "mrab3":
        assert_continued(folder, args, 0.25)
