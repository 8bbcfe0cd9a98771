"""A run over MPI ranks on the ranks' own devices: the halo exchange staged through host
buffers (the path a GPU run takes, its copies real on the CPU), the rank → device rule and its
one-line refusals, and two ranks sharing one CUDA device against one rank (skipped, saying why,
where no CUDA device is present). Ranks are real processes under the mpich wheel's ``mpiexec``,
as in ``test_mpi.py``."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from test_mpi import launches, mpirun, mpirun_python, needs_mpi, over_ranks  # noqa: F401 (fixtures)

from helpers import one_line, requires_cuda

# one worker runs the MPI tests one after another (as test_mpi.py's)
pytestmark = pytest.mark.xdist_group("mpi")
HALO = str(Path(__file__).with_name("mpi_halo.py"))


def staged_facts(tmp_path: Path, ranks: int, device: str) -> list[dict]:
    proc = mpirun_python(ranks, [HALO, device, "facts.json"], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    return json.loads((tmp_path / "facts.json").read_text())


# the script on 2 and 3 ranks, launched with test_mpi's (``launches``: a rank's start costs more than the script)
OVER_RANKS = {
    f"test_the_exchange_goes_through_host_buffers_with_the_same_bits[{r}]": (
        lambda d, r=r: {r: [[HALO, "cpu", str(d / "facts.json")]]}
    )
    for r in (2, 3)
}


@pytest.mark.usefixtures("needs_mpi")
@pytest.mark.parametrize("ranks", [1, 2, 3])
def test_the_exchange_goes_through_host_buffers_with_the_same_bits(tmp_path, ranks, request):
    """On 1, 2 and 3 ranks a DSS and a scatter of unique-node values have the one process's
    bits, and with neighbours the values came through host buffers that are allocations of
    their own (real copies: the CPU device stands in for a card), which hold what the device
    receive buffers hold: the DSS copies and the owners' values."""
    if ranks == 1:  # mpiexec -n 1: no communicator
        facts = staged_facts(tmp_path, ranks, "cpu")
    else:
        folder, _ = request.getfixturevalue("over_ranks")
        facts = json.loads((folder / "facts.json").read_text())
    assert [f["device"] for f in facts] == ["cpu"] * ranks
    assert all(f["dss"] and f["scatter"] for f in facts), facts
    if ranks == 1:
        assert facts[0]["neighbours"] == 0 and "copies" not in facts[0]
        return
    assert all(f["neighbours"] == ranks - 1 for f in facts), facts  # ne3 cut in 2 or 3: all touch
    for name in ("copies", "owned"):
        assert all(f[name][0] and f[name][1] for f in facts if name in f), facts
    assert all(f["copies"][2] > 0 for f in facts) and sum(f["owned"][2] for f in facts if "owned" in f) > 0
    # one node: ranks 0 and 2 share a key, rank 1 holds its own (the memory guard's count on a GPU)
    assert [f["peers"] for f in facts] == {2: [1, 1], 3: [2, 1, 2]}[ranks]


@pytest.mark.usefixtures("needs_mpi")
def test_a_rank_that_cannot_open_its_device_stops_every_rank_in_one_line(tmp_path):
    """Rank 1 alone asks for a device its node does not have (SWE_SPHERE_DEVICE, given to it
    alone by mpiexec): both ranks stop before anything is built, rank 0 saying which rank and
    why in one line, exit 2, no output."""
    args = ["run", "tc2_steady", "--ne", "2", "--days", "0.1", "--no-progress", "--output", "o.nc"]
    cli = [sys.executable, "-m", "swe_sphere.cli"]
    more = [":", "-n", "1", "-env", "SWE_SPHERE_DEVICE", "cuda:63", *cli, *args]  # rank 1's
    proc = mpirun(1, [*args, *more], tmp_path, cli)
    one_line(proc.returncode, proc.stderr, 2, "rank 1 of 2 on ")
    assert "device cuda:63 is not available on this machine (set SWE_SPHERE_DEVICE=cpu or unset it)" in proc.stderr
    assert not (tmp_path / "o.nc").exists()


def assert_same_fields(one: Path, two: Path, rel: float = 0.0) -> None:
    """Every variable of two run files but the wall time the same bits (``rel`` 0); else the
    state's wind and depth each within ``rel`` of their largest value (the diagnostics derived from
    them scale with fields near zero, galewsky's divergence). The second run's on 2 ranks."""
    with xr.open_dataset(one, decode_times=False) as a, xr.open_dataset(two, decode_times=False) as b:
        assert set(a.data_vars) == set(b.data_vars) and {"u", "v", "h"} <= set(a.data_vars)
        assert b.attrs.get("mpi_ranks", 2) == 2  # an ensemble's file does not say
        if rel == 0.0:
            for name in a.data_vars:
                if name != "wall_time" and a[name].dtype.kind == "f":
                    assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name
            return
        wind = max(np.abs(a[k].values - b[k].values).max() for k in "uv") / max(np.abs(a[k].values).max() for k in "uv")
        depth = np.abs(a.h.values - b.h.values).max() / np.abs(a.h.values).max()
        print(f"2 ranks against 1: wind {wind:.2e}, depth {depth:.2e}")
        assert max(wind, depth) <= rel, (wind, depth)


CUDA_RUNS = {  # run on one card: 1 rank, then 2 ranks sharing it
    "tc5": (["tc5_mountain", "--ne", "4", "--days", "0.25"], 0.0),
    # the tendency in float32 (issue 114): H0 and the rounding the same on every rank (2 CPU ranks: the same bits)
    "tc5_float32": (["tc5_mountain", "--ne", "4", "--days", "0.25", "--precision", "float32"], 0.0),
    "kgu35": (["galewsky", "--ne", "4", "--stepper", "kgu35", "--days", "0.25"], 0.0),
    "members": (["galewsky", "--ne", "4", "--days", "0.25", "--members", "4", "--perturbation", "1"], 0.0),
    # its Helmholtz CG's inner products summed in another order over 2 ranks, so its solves may stop
    # an iteration apart: within their tolerance (1e-10 here) of each other, not the same bits (on
    # 2 CPU ranks: wind 4e-13, depth 4e-14; at the default 1e-6, depth 4e-11)
    "imex": (["galewsky", "--ne", "4", "--stepper", "imex", "-s", "imex.tol=1e-10", "--days", "0.25"], 1e-10),
}


@requires_cuda
@pytest.mark.usefixtures("needs_mpi")
def test_the_exchange_through_pinned_buffers_on_one_card(tmp_path):
    """Two ranks sharing cuda:0 (the rank → device rule on one card): a DSS and a scatter with
    the one process's CUDA bits, received through page-locked host buffers."""
    facts = staged_facts(tmp_path, 2, "cuda")
    assert [f["device"] for f in facts] == ["cuda:0", "cuda:0"]
    assert all(f["dss"] and f["scatter"] and f["copies"][:2] == [True, True] for f in facts), facts


@requires_cuda
@pytest.mark.usefixtures("needs_mpi")
@pytest.mark.parametrize("name", list(CUDA_RUNS))
def test_two_ranks_on_one_card_give_one_rank_s_run(tmp_path, name):
    """``mpiexec -n 2 swe-sphere run ... --device cuda`` on a one-GPU machine writes the run file
    of one rank on it (whose steps are CUDA graphs; the ranks' are plain launches): bit for bit
    for the explicit runs and an ensemble's members, to round-off for IMEX."""
    args, rel = CUDA_RUNS[name]
    for ranks in (1, 2):
        proc = mpirun(ranks, ["run", *args, "--device", "cuda", "--no-progress", "--output", f"r{ranks}.nc"], tmp_path)
        assert proc.returncode == 0, proc.stderr[-2000:]
    assert_same_fields(tmp_path / "r1.nc", tmp_path / "r2.nc", rel)


@requires_cuda
@pytest.mark.usefixtures("needs_mpi")
def test_a_gradient_on_two_ranks_of_one_card(tmp_path, monkeypatch):
    """``test_mpi``'s gradients (TC5 rk4, a history of Δt, mri) on CUDA: 2 ranks sharing the card
    against 1, to round-off (on the CPU the same bits)."""
    script = str(Path(__file__).with_name("mpi_gradient.py"))
    monkeypatch.setenv("SWE_SPHERE_DEVICE", "cuda")  # the device its gradients take (none named)
    for ranks in (1, 2):
        proc = mpirun_python(ranks, [script, f"g{ranks}.npz"], tmp_path)
        assert proc.returncode == 0, proc.stderr[-2000:]
    with np.load(tmp_path / "g1.npz") as one, np.load(tmp_path / "g2.npz") as two:
        assert two["ranks"] == 2
        for key in one.files:
            if key != "ranks":
                scale = max(np.abs(one[key]).max(), 1e-300)
                assert np.abs(two[key] - one[key]).max() <= 1e-12 * scale, key


@requires_cuda
@pytest.mark.usefixtures("needs_mpi")
def test_the_memory_guard_counts_the_ranks_on_each_gpu(tmp_path):
    """Two ranks on the one card: the guard weighs both ranks' shares against its memory, by
    every rank alike before anything is built (ne = 100000: a petabyte), one line, exit 3."""
    proc = mpirun(2, ["run", "tc2_steady", "--ne", "100000", "--device", "cuda", "--output", "o.nc"], tmp_path)
    one_line(
        proc.returncode, proc.stderr, 3, "over 2 MPI ranks (2 on cuda:0 of this node) needs about", "of GPU memory"
    )
