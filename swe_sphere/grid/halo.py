"""What one rank sends to and receives from its neighbours, and the exchange itself.

A DSS (or a scatter of unique-node values) over MPI ranks is HOMME's ``edgeVpack`` →
``bndry_exchangeV`` → ``edgeVunpack``. Here the pack is a kernel on the run's device
(``kernels.dss.pack``) into a device send buffer, and the kernels after the exchange read
the device receive buffer directly; between them the values travel through host memory,
as HOMME's and ClimaComms' non-CUDA-aware paths do: the send buffer is copied to a host
buffer (page-locked on CUDA, so the copy is a DMA the driver need not stage), the host
buffers are exchanged by nonblocking point-to-point messages, and the receive buffer is
copied back to the device. On a CPU device the same copies are real memcpys between
distinct host arrays, so the path a GPU run takes is the one the CPU tests run, bit for bit.

Handing device buffers to MPI directly (CUDA-aware MPI) would save the two copies; the
``mpich`` wheel the package installs is not CUDA-aware, so that path is left until a
machine that has one can test it (docs/explanation/scaling.md, "GPUs").
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..core.backend import Backend

f64 = wp.float64
MAX_ROWS = 4  # most rows a DSS assembles at once (the hyperviscosity's Cartesian wind + h)


class Halo:
    """What one rank sends to and receives from each neighbour in one pattern
    (the DSS's element copies, or unique-node values from their owners):
    ``send_index`` (positions packed for the neighbours, in order; device int32, and
    ``send_index_np``), ``send_ranges``/``recv_ranges`` (each neighbour's slice, in
    entries), ``size`` (entries received), the device buffers ``send_buffer`` and
    ``recv_buffer`` and their host twins ``host_send``/``host_recv`` (``Backend.host_buffer``),
    each of up to ``rows`` float64 rows per entry (``MAX_ROWS``, or a state's with its tracers'),
    entry-major (``dss.pack``'s layout)."""

    def __init__(self, neighbours, send: list, recv: list, backend: Backend, rows: int = MAX_ROWS):
        self.neighbours = np.asarray(neighbours, dtype=np.int64)
        ends = np.cumsum([0, *map(len, send)]), np.cumsum([0, *map(len, recv)])
        self.send_ranges = list(zip(ends[0][:-1], ends[0][1:]))
        self.recv_ranges = list(zip(ends[1][:-1], ends[1][1:]))
        self.send_index_np = np.concatenate(send).astype(np.int32) if send else np.zeros(0, dtype=np.int32)
        self.size = int(ends[1][-1])
        device = backend.device
        self.send_index = wp.array(self.send_index_np, dtype=wp.int32, device=device)
        nsend, nrecv = max(1, self.send_index_np.size) * rows, max(1, self.size) * rows
        self.send_buffer = wp.zeros(nsend, dtype=f64, device=device)
        self.recv_buffer = wp.zeros(nrecv, dtype=f64, device=device)
        staged = bool(len(self.neighbours))  # one process allocates no host buffers (page-locked memory is scarce)
        self.host_send, self.host_recv = (backend.host_buffer(n) for n in (nsend, nrecv)) if staged else (None, None)
        self.exchanges: dict[int, Exchange] = {}


class Exchange:
    """One exchange of ``rows`` packed rows with the neighbouring ranks of ``comm`` (HOMME
    ``bndry_exchangeV``), staged through ``halo``'s host buffers; ``launch()`` returns with
    the received values queued for the device receive buffer, ahead of whatever is launched
    after it (run like a recorded launch, named "exchange" in launch lists). Messages carry
    ``tag``. Not capturable in a graph (a host wait and MPI calls): runs over several ranks
    launch plainly (``core.graphs``)."""

    def __init__(self, comm, halo: Halo, rows: int, tag: int, backend: Backend):
        self.comm, self.tag, self.backend = comm, tag, backend
        self.nsend, self.nrecv = halo.send_index_np.size * rows, halo.size * rows
        send, recv = halo.host_send.numpy(), halo.host_recv.numpy()  # views of host memory: zero-copy
        self.recvs = [(recv[a * rows : b * rows], int(s)) for s, (a, b) in zip(halo.neighbours, halo.recv_ranges)]
        self.sends = [(send[a * rows : b * rows], int(s)) for s, (a, b) in zip(halo.neighbours, halo.send_ranges)]
        self.to_host = backend.copier(halo.host_send, halo.send_buffer, self.nsend) if self.nsend else None
        self.to_device = backend.copier(halo.recv_buffer, halo.host_recv, self.nrecv) if self.nrecv else None
        self.kernel = type("exchange", (), {"key": "exchange"})  # named like a launch in launch lists

    def launch(self) -> None:
        from mpi4py import MPI

        if self.to_host is not None:
            self.to_host()
        # the pack and its copy done before MPI reads the host buffer, and the last exchange's
        # copy out of the host receive buffer done before a message may overwrite it
        self.backend.drain()
        requests = [self.comm.Irecv(buf, source=s, tag=self.tag) for buf, s in self.recvs]
        requests += [self.comm.Isend(buf, dest=s, tag=self.tag) for buf, s in self.sends]
        MPI.Request.Waitall(requests)
        if self.to_device is not None:  # on CUDA queued on the stream, ahead of the kernels that read the ghosts
            self.to_device()
