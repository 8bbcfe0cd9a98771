"""Domain decomposition over MPI ranks: partition quality, halo traffic, time per step.

Prints, for each ``--ne`` (np = 4, TC5 terms with hyperviscosity, RK4 at the
scene's Δt, one CPU thread per rank):

1. The space-filling-curve partition for each rank count of ``--ranks`` (and of
   ``--model-ranks``, partition only): elements per rank, edge cut (element
   edges between ranks), neighbours per rank, ghost copies received per DSS and
   their bytes per assembled row (max and mean over ranks). No MPI needed.
2. For each rank count of ``--ranks`` (run under ``mpiexec -n R`` from here,
   counts alternated ``--repeat`` times, medians): ms per RK4 step, of which in
   the exchange (messages + waiting for the slower rank, ``halo.Exchange``),
   DSS exchanges per step, the speed-up over one rank, and one 3-row pack +
   exchange timed alone with the ranks in step and the device idle before it (the
   exchange's own cost: pack, copy to the host, messages, copy back), and the peak
   resident memory of rank 0 (which also holds the whole grid's output fields and the
   reference) and of the largest other rank (each builds only its elements). Rank counts above the
   machine's cores run oversubscribed: their times say nothing about scaling,
   only that the run works (the note says so beside them).

``--device cuda`` runs the ranks on CUDA (each its node's GPU in turn, ``pick_device``):
on a one-GPU machine they share the card, so the time a step says little about several
cards, while the bare exchange is what the multi-GPU model of docs/explanation/scaling.md needs.
Steps are launched plainly (no graphs: a run over ranks takes none), the device drained
before each clock read.

    python benchmarks/studies/scaling.py                          # ne 16 30 60 on 1 2 ranks
    python benchmarks/studies/scaling.py --ne 16 --ranks 1 2 3 4 6 --steps 20
    python benchmarks/studies/scaling.py --ne 256 --np 2 --ranks --model-ranks 96 384 1536   # partition only (docs/explanation/scaling.md)
    python benchmarks/studies/scaling.py --device cuda --ne 30 60 120 --ranks 1 2 --model-ranks --steps 50   # benchmarks/gpu/GPU.md

The figures and the model built from them: ``docs/explanation/scaling.md``.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import positive, recorded


def partition_table(ne: int, np_: int, ranks: list[int]) -> None:
    from swe_sphere import CubedSphere
    from swe_sphere.grid.partition import edge_cut
    from swe_sphere.grid.reductions import SerialComm
    from swe_sphere.grid.topology import Topology, rank_parts

    class RankOf(SerialComm):  # build one rank's tables without MPI
        def __init__(self, rank, size):
            self.rank, self.size = rank, size

    nelem = 6 * ne * ne
    print(f"\nne={ne} np={np_}: {nelem} elements, {nelem * np_ * np_} element-local nodes")
    print(
        f"{'ranks':>6s} {'elem/rank':>10s} {'edge cut':>9s} {'nbrs max':>9s} {'nbrs mean':>9s} {'ghosts max':>10s} "
        f"{'ghosts mean':>11s} {'kB/row max':>10s} {'ghost/local':>11s}"
    )
    for size in ranks:
        parts = rank_parts(ne, size)
        sample = range(size) if size <= 64 else np.linspace(0, size - 1, 32).astype(int)  # tables are O(N) per rank
        topos = [
            Topology(CubedSphere(ne, np_, elements=parts[r]), "cpu", 1, RankOf(int(r), size), parts=parts)
            for r in sample
        ]
        nbrs = [len(t.neighbours) for t in topos]
        ghosts = [t.halo_copies for t in topos]
        print(
            f"{size:6d} {nelem / size:10.1f} {edge_cut(ne, parts):9d} {max(nbrs):9d} {statistics.mean(nbrs):9.1f} "
            f"{max(ghosts):10d} {statistics.mean(ghosts):11.1f} {8 * max(ghosts) / 1e3:10.2f} "
            f"{statistics.mean(g / t.N for g, t in zip(ghosts, topos)):11.3f}"
        )


def worker(ne: int, steps: int, device: str) -> None:
    """Under mpiexec: time RK4 steps on this communicator on ``device``; rank 0 prints one JSON line."""
    import warp as wp

    wp.config.quiet = True
    from mpi4py import MPI

    from swe_sphere import Simulation, load_scene
    from swe_sphere.core.backend import pick_device
    from swe_sphere.grid import halo

    spent = [0.0, 0]
    real = halo.Exchange.launch

    def timed(self):
        t0 = time.perf_counter()
        real(self)
        spent[0] += time.perf_counter() - t0
        spent[1] += 1

    halo.Exchange.launch = timed
    comm = MPI.COMM_WORLD
    scene = load_scene("tc5_mountain", ne=ne, np_=4, stepper="rk4")
    device = pick_device(device, comm=comm if comm.size > 1 else None)
    sim = Simulation(scene, device, progress=False, comm=comm if comm.size > 1 else None)
    drain = sim.topology.backend.drain
    for _ in range(2):  # record launches, load kernels
        sim.stepper.step(sim.x)
    drain()
    comm.Barrier()
    spent[:] = [0.0, 0]
    t0 = time.perf_counter()
    for _ in range(steps):
        sim.stepper.step(sim.x)
    drain()
    comm.Barrier()
    wall = (time.perf_counter() - t0) / steps
    exch = comm.allreduce(spent[0], MPI.MAX) / steps
    exchanges = spent[1] / steps
    bare = []  # one 3-row exchange alone, all ranks in step: messages without the waiting for a slower rank
    launches = sim.topology._exchange(sim.x)
    for _ in range(50):
        drain()
        comm.Barrier()
        t0 = time.perf_counter()
        for launch in launches:
            launch.launch()
        drain()  # the copy back to the device done too
        bare.append(time.perf_counter() - t0)
    bare_us = 1e6 * statistics.median(bare) if launches else 0.0
    rss = comm.gather(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)  # peak RSS, MiB (Linux: KiB)
    if comm.rank == 0:
        print(
            json.dumps(
                {
                    "ms_step": 1e3 * wall,
                    "ms_exchange": 1e3 * exch,
                    "exchanges": exchanges,
                    "us_bare": bare_us,
                    "rss_rank0": rss[0],
                    "rss_others": max(rss[1:], default=0.0),
                }
            )
        )


def time_table(ne_list, ranks, steps, repeat, device) -> None:
    beside = Path(sys.executable).with_name(
        "mpiexec"
    )  # the mpich wheel's, else PATH's (the card's payload: gpu_session.sh)
    mpiexec = beside if beside.is_file() else shutil.which("mpiexec")
    if mpiexec is None:
        raise SystemExit("scaling.py: no mpiexec beside this Python or on PATH (pip install mpich mpi4py)")
    env = {**os.environ, "SWE_SPHERE_THREADS": "1"}
    cores = len(os.sched_getaffinity(0))
    for ne in ne_list:
        runs = {r: [] for r in ranks}
        for _ in range(repeat):
            for r in ranks:  # alternated so that the machine's load falls on all alike
                cmd = [str(mpiexec), "-n", str(r), sys.executable, __file__, "--worker", str(ne), str(steps), device]
                proc = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=3600)
                if proc.returncode != 0:
                    raise SystemExit(f"mpiexec -n {r} failed: {proc.stderr[-2000:]}")
                runs[r].append(json.loads(proc.stdout.strip().splitlines()[-1]))
        print(
            f"\nne={ne} np=4, RK4 TC5 on {device}, {steps} steps, medians of {repeat} (load average {os.getloadavg()[0]:.1f}, {cores} cores)"
        )
        print(
            f"{'ranks':>6s} {'ms/step':>9s} {'exchange ms':>11s} {'share':>6s} {'DSS/step':>8s} {'speed-up':>8s} {'bare exch us':>12s} {'MiB rank 0':>10s} {'others':>7s}"
        )
        base = statistics.median(x["ms_step"] for x in runs[ranks[0]]) * ranks[0]
        for r in ranks:
            step = statistics.median(x["ms_step"] for x in runs[r])
            exch = statistics.median(x["ms_exchange"] for x in runs[r])
            note = "  (oversubscribed: correctness only)" if r > cores and device == "cpu" else ""
            bare = statistics.median(x["us_bare"] for x in runs[r])
            rss0, rss = (max(x[k] for x in runs[r]) for k in ("rss_rank0", "rss_others"))
            print(
                f"{r:6d} {step:9.2f} {exch:11.2f} {exch / step:6.1%} {runs[r][0]['exchanges']:8.0f} {base / step:8.2f} {bare:12.1f}"
                f" {rss0:10.0f} {rss:7.0f}{note}"
            )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ne", type=positive(int), nargs="+", default=[16, 30, 60])
    p.add_argument("--ranks", type=int, nargs="*", default=[1, 2])
    p.add_argument("--model-ranks", type=int, nargs="*", default=[3, 6, 24])
    p.add_argument("--np", type=int, default=4, help="GLL points of the partition tables (the timed runs use 4)")
    p.add_argument("--steps", type=positive(int), default=10)
    p.add_argument("--repeat", type=positive(int), default=3)
    p.add_argument("--device", choices=["cpu", "cuda"], default="cpu", help="the ranks' device (default cpu)")
    p.add_argument("--results", help="results/scaling/<STEM>.json (default: the script's stem; a path: there)")
    p.add_argument("--worker", nargs=3, help=argparse.SUPPRESS)
    a = p.parse_args()
    if a.worker:
        worker(int(a.worker[0]), int(a.worker[1]), a.worker[2])
        return
    from swe_sphere.core.runtime import init_warp

    init_warp()  # quietly, before the first table: the topology would init Warp with its banner inside it
    with recorded(__file__, stem=a.results):
        for ne in a.ne:
            partition_table(ne, a.np, sorted(set(a.ranks) | set(a.model_ranks)))
        if a.ranks:
            time_table(a.ne, a.ranks, a.steps, a.repeat, a.device)


if __name__ == "__main__":
    main()
