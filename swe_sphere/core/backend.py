"""The backend: what a run does differently on a CPU and on a CUDA device, decided once.

On Oceananigans' pattern (its ``Architectures``: ``CPU()``, ``GPU()``), the device is
looked up once (``Backend.of``) and every choice that depends on it is an attribute or
method here: the node layout of the element kernels, the CPU threads a launch is split
over, the chunk of a fixed-order inner product, the host or kernel passes of the Krylov
solvers (``choose``), which graphs pay, how often the bad-state check is read back, and
whose memory a run must fit in. Nothing outside this module asks whether a device is a
CPU or a GPU.

``pick_device`` chooses the device itself: the one asked for, else ``SWE_SPHERE_DEVICE``'s,
else CUDA when present; over MPI ranks, each rank its node's GPU in turn (``rank_device``).
"""

from __future__ import annotations

import functools
import os
import re
from dataclasses import dataclass

import numpy as np
import warp as wp

from . import mpi
from .errors import ResourceError, SceneError
from .runtime import check_memory, gib, init_warp
from .workers import cpus

THREADS_ENV = "SWE_SPHERE_THREADS"
# the device of a run that names none (as JAX's JAX_PLATFORMS): a GPU machine's tests keep
# their CPU runs on the CPU with it, and a user keeps a shared GPU free
DEVICE_ENV = "SWE_SPHERE_DEVICE"
CPU_CHUNK = 256  # entries per partial sum of an inner product on the CPU
CUDA_CHUNKS = 4096  # partial sums an inner product aims at on CUDA, 8 to 32 entries each (measured on an H100)
DEVICE_TOTALS = 64  # partial sums a row that one GPU thread adds directly (``Topology.device_sums``)
# Steps between host reads of the bad-state check (``Simulation.check_every``). On a GPU a
# read waits for the device to drain its queue: ~10-50 µs, as long as a whole launch-bound
# ne30 step, so reading every step serialises the loop. On a CPU a step checked alone also
# copies the state aside and reads the check back through Python: 6 % of a leapfrog-trapezoidal
# step on 780 elements at np 4. 64 steps make either ~1 % of the time and bound the re-run
# that finds a blow-up's step to 64 steps (ClimaAtmos checks for NaN every 1024 steps,
# without the step).
CHECK_EVERY_STEPS = 64


def requested_threads() -> int | None:
    """``SWE_SPHERE_THREADS`` as an integer >= 1, or None when unset; ValueError naming it otherwise."""
    env = os.environ.get(THREADS_ENV, "").strip()
    if not env:
        return None
    try:
        n = int(env)
    except ValueError:
        raise ValueError(f"{THREADS_ENV} must be an integer >= 1 (got {env!r})") from None
    if n < 1:
        raise ValueError(f"{THREADS_ENV} must be >= 1 (got {env!r})")
    return n


def default_device() -> str:
    """The device a run takes when none is named: ``SWE_SPHERE_DEVICE`` where set (checked by
    ``pick_device``), else 'cuda' when Warp sees a CUDA device, else 'cpu'."""
    return os.environ.get(DEVICE_ENV, "").strip() or ("cuda" if init_warp().is_cuda_available() else "cpu")


def same_device(a: str, b: str) -> bool:
    """Whether the Warp device names ``a`` and ``b`` name one device ("cuda" and "cuda:0" do
    where device 0 is the current one)."""
    return a == b or wp.get_device(a) == wp.get_device(b)


def lives_on(array: wp.array, device: str) -> bool:
    """Whether ``array`` is in ``device``'s memory (a Warp device name: "cpu", "cuda", "cuda:N";
    "cuda" is the current CUDA device, on which no host array lives)."""
    where = array.device
    if device == where.alias:
        return True
    return not where.is_cpu and where == device


def rank_device(device: str, local_rank: int, gpus: int) -> str:
    """The device of the rank ``local_rank`` (0-based among its node's ranks) of a run over MPI
    ranks asked to run on ``device``, on a node where Warp sees ``gpus`` CUDA devices: bare
    "cuda" deals the node's ranks round-robin over its GPUs, ``cuda:(local_rank mod gpus)``
    (several ranks a GPU when there are more ranks than GPUs; one GPU a rank where the launcher
    already shows each rank its own, as Slurm's ``--gpus-per-task``: gpus 1, cuda:0); "cpu"
    and "cuda:N" (every rank on cuda:N) as given, and "cuda" too where gpus is 0 (refused by
    ``pick_device`` as absent). HOMMEXX and ClimaComms make the same choice."""
    if device != "cuda" or gpus < 1:
        return device
    return f"cuda:{local_rank % gpus}"


def pick_device(requested: str | None = None, *, verbose: bool = False, comm=None) -> str:
    """The Warp device to run on: ``requested`` ("cpu", "cuda" or "cuda:N"), else
    ``default_device()``'s. Raises ``SceneError`` (a ValueError; one line) for another name
    (naming ``SWE_SPHERE_DEVICE`` where the name is its), and when the CUDA device asked
    for is absent.

    With ``comm`` (an mpi4py communicator of several ranks; collective) each rank takes its
    own device by ``rank_device`` (its place among the ranks of its node, ``mpi.node_rank``),
    opens it and makes it Warp's default; when one rank cannot (no such device, or one it
    cannot open: a GPU in exclusive-process mode that another rank holds), or the ranks would
    run on CPUs and CUDA devices at once, every rank raises the same ``SceneError``, naming
    the first such rank and its node, so the run stops in one line, none waiting for another."""
    ranks = isinstance(getattr(comm, "size", None), int) and comm.size > 1  # else the caller's own check names comm
    try:
        device, error = _device(requested, verbose, mpi.node_rank(comm)[0] if ranks else None), None
    except SceneError as err:
        if not ranks:
            raise
        device, error = None, str(err)
    if ranks:
        _agree(comm, device, error)
    return device


def _device(requested: str | None, verbose: bool, local_rank: int | None) -> str:
    """``pick_device``'s device on one process (``local_rank`` None) or one rank."""
    device, what = (requested, "device") if requested is not None else (default_device(), DEVICE_ENV)
    if not re.fullmatch(r"cpu|cuda(:\d+)?", str(device)):
        raise SceneError(f"{what} must be 'cpu', 'cuda' or 'cuda:N' (got {device!r})")
    warp = init_warp(verbose)
    gpus = warp.get_cuda_device_count()
    if local_rank is not None:
        device = rank_device(device, local_rank, gpus)
    ordinal = int(device.partition(":")[2] or 0)
    if device.startswith("cuda") and ordinal >= gpus:
        fix = "use --device cpu" if requested is not None else f"set {DEVICE_ENV}=cpu or unset it"
        raise SceneError(f"device {device} is not available on this machine ({fix})")
    if local_rank is not None and device != "cpu":  # open it here, where a refusal can still be one line
        try:
            wp.zeros(1, device=device)
        except RuntimeError as err:
            raise SceneError(f"device {device} cannot be opened: {str(err).strip().splitlines()[0]}") from None
        wp.set_device(device)  # what names no device (or "cuda") is this rank's
    return device


def _agree(comm, device: str | None, error: str | None) -> None:
    """Raise on every rank of ``comm`` the first rank's ``error``, or a refusal where some ranks
    would run on a CPU and others on CUDA (their results could not have the same bits)."""
    where = f"rank {comm.rank} of {comm.size} on {mpi.processor_name()}"
    picks = comm.allgather((where, device, error))
    failed = [f"{at}: {err}" for at, _, err in picks if err is not None]
    if failed:
        raise SceneError(failed[0])
    kinds = {d.partition(":")[0]: f"{d} on {at}" for at, d, _ in picks}
    if len(kinds) > 1:
        raise SceneError(f"the ranks would run on a CPU and on CUDA ({kinds['cpu']}, {kinds['cuda']}): give --device")


@dataclass(frozen=True)
class Backend:
    """The device-dependent choices of a run on the Warp device ``device`` ("cpu",
    "cuda", "cuda:0"): ``host`` is True on a CPU device, whose arrays are host memory
    (numpy views of them are zero-copy). Build it with ``Backend.of``."""

    device: str
    host: bool

    @classmethod
    def of(cls, device) -> Backend:
        """The backend of a Warp device (a name or ``wp.Device``)."""
        return cls(str(device), bool(wp.get_device(device).is_cpu))

    # -- layout ---------------------------------------------------------------
    @property
    def per_element(self) -> bool:
        """Whether the element kernels run an element (np² nodes) a thread (a CPU, where
        Warp's cost per thread dominates) rather than a node a thread (CUDA)."""
        return self.host

    def nodes_per_thread(self, np_: int) -> int:
        """Consecutive nodes one thread of a node-wise gathering kernel takes: an
        element's np² on a CPU (``Topology.gathering``), one on CUDA."""
        return np_ * np_ if self.host else 1

    # -- CPU threads ------------------------------------------------------------
    def threads(self) -> int:
        """Threads for CPU launches: ``SWE_SPHERE_THREADS``, else the usable CPUs, never
        more than those (more threads than CPUs made ne16 3.9x slower); 1 on CUDA.
        ValueError for a bad ``SWE_SPHERE_THREADS``."""
        if not self.host:
            return 1
        return min(requested_threads() or cpus(), cpus())

    def threads_note(self) -> str | None:
        """A one-line note when ``SWE_SPHERE_THREADS`` asks for more threads than ``threads`` gives."""
        n = requested_threads() if self.host else None
        if n is None or n <= cpus():
            return None
        return f"{THREADS_ENV}={n} is more than the {cpus()} CPUs this process may run on: {cpus()} threads"

    def launch_parts(self, threads: int) -> int:
        """The most node ranges a recorded launch is split into (``parallel.record``):
        ``threads`` on a CPU (Warp runs a CPU launch as one serial loop), 1 on CUDA."""
        return threads if self.host else 1

    # -- reductions -------------------------------------------------------------
    def reduction_chunk(self, n: int) -> int:
        """Entries per partial sum of an inner product over n entries (the chunked,
        fixed-order reductions of ``kernels.helmholtz`` and ``kernels.krylov``): on a
        CPU ``CPU_CHUNK`` (so the bits do not depend on the threads); on CUDA about
        n / ``CUDA_CHUNKS``, within 8–32. A GPU thread sums a chunk in a serial loop,
        latency-bound: on an H100 at ne30, chunks of 256 made a pcg iteration cost 40
        RHS, of 32 twice what chunks of 12 cost; at ne120 chunks of 190 cost 1.8×
        chunks of 32. ``Topology.device_sums`` adds the partial sums on the device."""
        if self.host:
            return CPU_CHUNK
        return min(32, max(8, -(-int(n) // CUDA_CHUNKS)))

    def direct_totals(self, n: int) -> bool:
        """Whether one thread adds a row of n partial sums directly; else they are first
        added in chunks of about √n (on CUDA above ``DEVICE_TOTALS``: a GPU thread's
        serial loop is latency-bound)."""
        return self.host or n <= DEVICE_TOTALS

    def inner(self, a: wp.array, b: wp.array) -> float:
        """Σ a·b of two device arrays of one shape on this process: numpy's dot on
        zero-copy views on a CPU (as ``np.linalg.norm``), Warp's ``array_inner`` on CUDA."""
        if self.host:
            return float(a.numpy().ravel().dot(b.numpy().ravel()))
        return float(wp.utils.array_inner(a.flatten(), b.flatten()))

    # -- the Krylov solvers' vector work ------------------------------------------
    def choose(self, host, kernel):
        """One of a pair of implementations of the same passes: ``host`` (numpy/BLAS on
        zero-copy views: Warp's CPU kernels are 7–15× slower at short vector passes) on
        a CPU, ``kernel`` (Warp kernels) on CUDA (``krylov.HostVectors`` and
        ``KernelVectors``, ``jacobian.HostPasses`` and ``KernelPasses``)."""
        return host if self.host else kernel

    # -- graphs and host reads ------------------------------------------------------
    @property
    def graph_name(self) -> str:
        """What a captured graph is called here, for messages."""
        return "CPU graph" if self.host else "CUDA graph"

    @property
    def graphs_pay(self) -> bool:
        """Whether whole steps run as graphs in the "auto" mode (``graphs.GraphedSteps``):
        on CUDA, where a graph is one host call instead of one a launch."""
        return not self.host

    def solver_graphs(self, threads: int) -> bool:
        """Whether a solver's loops can be captured as one graph on one rank: on CUDA
        with conditional graph nodes (driver ≥ 12.4), on a CPU with one thread a launch
        (a ``parallel.SplitLaunch`` is a Python pool; Warp replays a CPU graph in one thread)."""
        return threads == 1 if self.host else wp.is_conditional_graph_supported()

    # -- ranks and memory -----------------------------------------------------------
    def host_buffer(self, n: int) -> wp.array:
        """A zeroed float64 host array of n entries that MPI reads or writes for this device
        (``grid.halo``): page-locked on CUDA, so that copies to and from the device are DMAs
        queued on its stream; plain host memory on a CPU, where the copies are memcpys."""
        return wp.zeros(n, dtype=wp.float64, device="cpu", pinned=not self.host)

    def copier(self, dest: wp.array, src: wp.array, count: int):
        """A function of no arguments that copies the first ``count`` entries of the 1-D array ``src``
        into ``dest`` (one of them a ``host_buffer``): on a CPU numpy's ``copyto`` on views made once,
        a memcpy (``wp.copy`` took 15–20 µs of Python a call: a staged exchange on 2 ranks at ne30
        44 → 80 µs); on CUDA ``wp.copy``, queued on the device's current stream."""
        if self.host:
            return functools.partial(np.copyto, dest.numpy()[:count], src.numpy()[:count])
        return functools.partial(wp.copy, dest, src, count=count)

    def drain(self) -> None:
        """Wait until what was queued on this device's current stream has run (CUDA: kernels and
        copies are asynchronous); nothing on a CPU, where a launch or a copy returns when done."""
        if not self.host:
            wp.synchronize_stream(wp.get_device(self.device).stream)

    def sharing(self, comm) -> tuple[int, str]:
        """(ranks of ``comm`` whose arrays share this rank's memory, where that is) for the memory
        guard (collective): on a CPU the ranks on this node; on CUDA those on this node's GPU of
        this rank (a node of 8 GPUs and 8 ranks: 1)."""
        if self.host:
            return mpi.node_local_size(comm), "on this node"
        alias = wp.get_device(self.device).alias
        return mpi.node_peers(comm, alias), f"on {alias} of this node"

    def reader(self, a: wp.array) -> HostRead:
        """A ``HostRead`` of the device array ``a`` (this backend's)."""
        return HostRead(a, self.host)

    def check_memory(self, need: int, what: str, comm=None) -> None:
        """Raise ``ResourceError`` (one line) when ``need`` bytes (``what`` needs them) exceed the
        memory the run's arrays live in: a GPU's free memory on CUDA, else the host's available
        memory (``runtime.check_memory``); over the ranks of ``comm`` (each holding 1/size of
        ``need``), the share of the ranks on each node, or on CUDA on each GPU (``sharing``),
        raised on every rank where one must (collective; ``on_every_rank`` set: the console
        script says it once, from rank 0, without MPI_Abort)."""
        if comm is not None and comm.size > 1:
            local, where = self.sharing(comm)  # the ranks whose arrays share this rank's memory
            try:
                self.check_memory(need * local // comm.size, f"{what} over {comm.size} MPI ranks ({local} {where})")
                error = None
            except ResourceError as err:
                error = str(err)
            errors = [e for e in comm.allgather(error) if e is not None]  # every rank refuses if one node must
            if errors:
                err = ResourceError(errors[0])
                err.on_every_rank = True
                raise err
            return
        if self.host:
            check_memory(need, what)
            return
        dev = wp.get_device(self.device)
        if need > dev.free_memory:
            raise ResourceError(
                f"{what} needs about {gib(need)} of GPU memory; {gib(dev.free_memory)} free of "
                f"{gib(dev.total_memory)} on {dev}"
            )


class HostRead:
    """The values of a device array ``a`` brought to the host without holding the host up:
    ``start()`` queues the copy on the array's stream (on CUDA into page-locked host memory,
    an event recorded after it, so the host goes on launching what comes next), ``values()``
    waits for that event alone and returns a numpy view (valid until the next ``start``).
    ``host`` (a CPU device): ``a`` is host memory, nothing to copy, ``values()`` its
    zero-copy view once what was launched before has run (a CPU launch returns when done)."""

    def __init__(self, a: wp.array, host: bool):
        self.a = a
        self._pinned = self._event = None
        if not host:
            self._pinned = wp.empty(a.shape, dtype=a.dtype, device="cpu", pinned=True)
            self._event = wp.Event(a.device)
            self._view = self._pinned.numpy()  # made once: each ``numpy()`` costs the host ~10 µs a read

    def start(self) -> None:
        if self._pinned is not None:
            wp.copy(self._pinned, self.a)
            self.a.device.stream.record_event(self._event)

    def values(self):
        if self._pinned is None:
            return self.a.numpy()
        wp.synchronize_event(self._event)
        return self._view


__all__ = ["Backend", "HostRead", "default_device", "pick_device", "rank_device", "requested_threads"]
