"""A run on a file-like mesh over several MPI ranks has the same bits as on one: the elements
cut along the curve through their centroids, the DSS summing every copy in the one global order
(real processes under ``mpiexec``; skipped, saying why, where MPI is not installed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from mpi_mesh import final_state
from test_mpi import mpirun_python, needs_mpi  # noqa: F401 (a fixture)


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
