"""The backend: every device-dependent choice made in ``core.backend``, and nowhere else."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from swe_sphere.core.backend import CHECK_EVERY_STEPS, CPU_CHUNK, DEVICE_TOTALS, Backend, rank_device
from swe_sphere.solvers.jacobian import HostPasses, KernelPasses
from swe_sphere.solvers.krylov import HostVectors, KernelVectors

ROOT = Path(__file__).resolve().parents[2]
# what asks a Warp device whether it is a CPU or a GPU, or whether CUDA has graph conditionals
DEVICE_QUESTIONS = {"is_cpu", "is_cuda", "is_conditional_graph_supported"}


def device_questions(path: Path) -> list[str]:
    """'file:line attribute' for each device question in one module's source."""
    tree = ast.parse(path.read_text(), filename=str(path))
    return [
        f"{path.relative_to(ROOT)}:{node.lineno} {node.attr}"
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute) and node.attr in DEVICE_QUESTIONS
    ]


def test_only_the_backend_asks_what_the_device_is():
    """Outside ``core/backend.py`` no module of the package or its kernels branches on the device."""
    modules = sorted((ROOT / "swe_sphere").rglob("*.py")) + sorted((ROOT / "kernels").rglob("*.py"))
    backend = ROOT / "swe_sphere" / "core" / "backend.py"
    assert backend in modules and len(device_questions(backend)) >= 2  # the scan sees what it looks for
    found = [q for path in modules if path != backend for q in device_questions(path)]
    assert found == []


def test_the_cpu_backend():
    cpu = Backend.of("cpu")
    assert cpu.host and cpu.per_element and not cpu.graphs_pay
    assert cpu.nodes_per_thread(4) == 16 and cpu.launch_parts(3) == 3
    assert cpu.reduction_chunk(10**6) == CPU_CHUNK  # the bits do not depend on the length or threads
    assert cpu.direct_totals(10**6) and cpu.graph_name == "CPU graph"
    assert cpu.choose(HostVectors, KernelVectors) is HostVectors
    assert cpu.choose(HostPasses, KernelPasses) is HostPasses


def test_the_cuda_backend_without_a_gpu(monkeypatch):
    """The choices a CUDA device gets (those that ask the driver nothing), on any machine."""
    monkeypatch.setenv("SWE_SPHERE_THREADS", "4")
    cuda = Backend("cuda:0", host=False)
    assert not cuda.per_element and cuda.graphs_pay
    assert cuda.threads() == 1 and cuda.threads_note() is None and cuda.launch_parts(4) == 1
    assert cuda.nodes_per_thread(4) == 1
    # about n / 4096 entries a partial sum, within 8 to 32
    assert [cuda.reduction_chunk(n) for n in (1000, 20 * 4096, 10**7)] == [8, 20, 32]
    assert cuda.direct_totals(DEVICE_TOTALS) and not cuda.direct_totals(DEVICE_TOTALS + 1)
    assert cuda.graph_name == "CUDA graph"
    assert cuda.choose(HostVectors, KernelVectors) is KernelVectors
    assert cuda.choose(HostPasses, KernelPasses) is KernelPasses


def test_a_model_takes_its_choices_from_its_backend():
    """The topology holds the backend; the solvers' vector work is the one it chooses."""
    from swe_sphere.simulation.simulation import Simulation

    sim = Simulation("tc5_mountain", "cpu", progress=False, ne=2, stepper="implicit")
    assert sim.topology.backend == Backend.of("cpu")
    assert isinstance(sim.stepper.fgmres.vectors, HostVectors)
    assert isinstance(sim.stepper.jacobian.passes, HostPasses)
    assert sim.model.operators.per_element and sim.check_every == CHECK_EVERY_STEPS == 64


@pytest.mark.parametrize("value", ["0", "two"])
def test_a_bad_thread_count_is_named(monkeypatch, value):
    monkeypatch.setenv("SWE_SPHERE_THREADS", value)
    with pytest.raises(ValueError, match=f"SWE_SPHERE_THREADS must be .*{value!r}"):
        Backend.of("cpu").threads()


def test_the_ranks_of_a_node_take_its_gpus_in_turn():
    """Bare "cuda" over MPI ranks: rank r of a node on cuda:(r mod the node's GPUs), so 8 ranks
    on 4 GPUs share each twice, 3 ranks on one card all take cuda:0, a launcher that shows each
    rank one GPU gets cuda:0 everywhere; "cpu" and "cuda:N" are every rank's as given, and
    "cuda" on a node without GPUs is left for ``pick_device`` to refuse as absent."""
    assert [rank_device("cuda", r, 4) for r in range(8)] == [f"cuda:{r % 4}" for r in range(8)]
    assert [rank_device("cuda", r, 1) for r in range(3)] == ["cuda:0"] * 3
    assert [rank_device("cuda", r, 8) for r in (0, 7)] == ["cuda:0", "cuda:7"]
    assert [rank_device(d, 5, 4) for d in ("cpu", "cuda:2", "cuda:0")] == ["cpu", "cuda:2", "cuda:0"]
    assert rank_device("cuda", 3, 0) == "cuda"


class OtherRank:
    """Rank 0 of 2 as ``pick_device`` meets it: ``allgather`` hands back this rank's pick beside
    rank 1's ``theirs`` (where, device, error)."""

    rank, size = 0, 2

    def __init__(self, theirs):
        self.theirs = theirs

    def allgather(self, mine):
        return [mine, self.theirs]


@pytest.mark.parametrize(
    "theirs, says",
    [
        (("rank 1 of 2 on b", None, "device cuda:3 is not available"), "rank 1 of 2 on b: device cuda:3 is not"),
        (("rank 1 of 2 on b", "cuda:0", None), "on a CPU and on CUDA (cpu on rank 0 of 2 on a, cuda:0 on rank 1"),
    ],
    ids=["another-rank-fails", "cpu-and-cuda"],
)
def test_every_rank_refuses_what_one_rank_meets(monkeypatch, theirs, says):
    """Over ranks a device refusal is collective: rank 0, whose own CPU is fine, raises the first
    failing rank's line (naming it and its node), or refuses ranks on a CPU and on CUDA at once."""
    from swe_sphere.core import mpi
    from swe_sphere.core.backend import pick_device
    from swe_sphere.core.errors import SceneError

    monkeypatch.setattr(mpi, "node_rank", lambda comm: (0, 2))
    monkeypatch.setattr(mpi, "processor_name", lambda: "a")
    with pytest.raises(SceneError, match=re.escape(says)):
        pick_device("cpu", comm=OtherRank(theirs))
    assert pick_device("cpu", comm=OtherRank(("rank 1 of 2 on b", "cpu", None))) == "cpu"
