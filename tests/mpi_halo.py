"""Run by ``test_mpi_devices.py`` under ``mpiexec``: a DSS and a scatter of unique-node values
over the ranks, each rank's device picked by ``pick_device`` (``python mpi_halo.py DEVICE
OUT.json``), against the one-process results on the same device. Rank 0 saves, for each rank,
whether its results have the one process's bits and whether its exchanges went through host
buffers distinct from the device ones that hold what was received."""

from __future__ import annotations

import json
import sys

import numpy as np
import warp as wp

from swe_sphere.core import mpi
from swe_sphere.core.backend import Backend, pick_device
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.topology import Topology


def run(launches) -> None:
    for launch in launches:
        launch.launch()


def staged(comm, device: str) -> dict:
    """This rank's facts: its device, whether its DSS and scatter have one process's bits, and for
    each halo with neighbours whether its host buffers are allocations apart from the device
    ones, whether the host receive buffer holds what the device one received, and how many."""
    device = pick_device(device, comm=comm)
    backend = Backend.of(device)
    grid = CubedSphere(3, 4)
    rng = np.random.default_rng(3)  # the same draws on every rank
    x, u = rng.standard_normal((3, grid.nnodes)), rng.standard_normal((2, grid.nunique))
    whole = wp.zeros((3, grid.nnodes), dtype=wp.float64, device=device)
    run(Topology(grid, backend).dss(wp.array(x, dtype=wp.float64, device=device), True, whole))
    t = Topology(grid, backend, 1, comm)
    out = wp.zeros((3, t.N), dtype=wp.float64, device=device)
    run(t.dss(wp.array(x[:, t.nodes], dtype=wp.float64, device=device), True, out))
    mine = u[:, grid.gid[t.nodes[t.first.numpy()]]]  # the unique nodes this rank owns
    scattered = wp.zeros((3, t.N), dtype=wp.float64, device=device)
    run(t.scatter(wp.array(mine.ravel(), dtype=wp.float64, device=device), scattered, 1, rows=2))
    facts = {
        "device": device,
        "dss": bool(np.array_equal(out.numpy(), whole.numpy()[:, t.nodes])),
        "scatter": bool(np.array_equal(scattered.numpy()[1:], u[:, grid.gid[t.nodes]])),
        "neighbours": len(t.neighbours),
    }
    for name, halo, rows in (("copies", t.copies, 3), ("owned", t.owned, 2)):
        if halo.host_recv is not None:  # [distinct allocations, host values = device values, values received]
            n = halo.size * rows
            host, received = halo.host_recv.numpy()[:n], halo.recv_buffer.numpy()[:n]
            distinct = halo.host_recv.ptr != halo.recv_buffer.ptr and halo.host_send.ptr != halo.send_buffer.ptr
            facts[name] = [bool(distinct), bool(np.array_equal(host, received) and np.all(received != 0)), n]
    return facts


if __name__ == "__main__":
    comm = mpi.world()  # None on one rank
    facts = [staged(comm, sys.argv[1])]
    if comm is not None:  # and the ranks of this node with this rank's parity (``mpi.node_peers``)
        facts[0]["peers"] = mpi.node_peers(comm, comm.rank % 2)
        facts = comm.gather(facts[0], root=0)
    if facts is not None:
        with open(sys.argv[2], "w") as f:
            json.dump(facts, f)
