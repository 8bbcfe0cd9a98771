"""Multi-core execution of recorded Warp CPU launches.

Warp runs a CPU launch as one serial loop over its threads. Every kernel the
model records takes a trailing ``offset: int`` (its node index is
``wp.tid() + offset``, or ``p + offset`` for the last of a 2-D tid), so a
launch over N nodes can run as ``parts`` launches over disjoint node ranges,
cut at element boundaries. A ``SplitLaunch`` runs the first range on the
calling thread and the others on a shared pool of worker threads (Warp's CPU
entry point is a ``ctypes.CFUNCTYPE`` call, which releases the GIL), and
returns when all are done: the next launch may read any node the previous one
wrote. Every kernel writes only its own nodes and reads only nodes written by
earlier launches (the DSS is a gather), so the results are the same bits as
one serial launch.

The number of threads: ``backend.Backend.threads`` (``SWE_SPHERE_THREADS`` if set,
else the CPUs this process may run on; 1 on CUDA devices: nothing is split there).
"""

from __future__ import annotations

import copy
import ctypes
import functools
import os
import threading
from concurrent.futures import ThreadPoolExecutor

import warp as wp

from .backend import Backend, lives_on

MIN_POINTS_PER_PART = 2048  # below this a split costs more in hand-offs than it gains

_pools: dict[int, ThreadPoolExecutor] = {}
_pools_lock = threading.Lock()


def _pool(workers: int) -> ThreadPoolExecutor:
    """The process's pool of ``workers`` threads (created on first use)."""
    pool = _pools.get(workers)
    if pool is None:
        with _pools_lock:
            pool = _pools.get(workers)
            if pool is None:
                pool = _pools[workers] = ThreadPoolExecutor(workers, thread_name_prefix="swe-sphere-cpu")
    return pool


def _forget_pools_after_fork():  # a forked child has none of its parent's threads
    global _pools_lock
    _pools.clear()
    _pools_lock = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pools_after_fork)


class DirectLaunch:
    """A recorded CPU launch over one node range called straight through Warp's CPU entry
    point with its argument struct built once (``wp.Launch.launch`` packs a new struct from
    every argument on each call: about 1 µs an argument). ``kernel``, ``fwd_args``,
    ``set_param_by_name`` and ``launch()`` as on the ``wp.Launch`` it wraps (``whole``).

    ``launch()`` takes Warp's own path while the device captures a graph (``wp.ScopedCapture``,
    ``Device.is_capturing``: Warp records the launch then) and for what the direct call does not
    cover (cooperative CPU blocks, adjoints, Warp internals other than 1.19's); ``run`` is the
    direct call alone, for a ``SplitLaunch``'s worker threads."""

    def __init__(self, launch: wp.Launch):
        self.whole, self.kernel, self.device = launch, launch.kernel, launch.device
        self.run, self._args = launch.launch, None
        hooks = launch.hooks
        if launch.block_dim > 1 or hooks.forward is None or launch.adjoint:
            return
        try:  # Warp internals (1.19): Warp's own path if they change
            self._labels = {a.label: k for k, a in enumerate(self.kernel.adj.args)}
            fields = [(a.label, type(p)) for a, p in zip(self.kernel.adj.args, launch.params[1:])]
            args = type("ArgsStruct", (ctypes.Structure,), {"_fields_": fields})()
            for (name, _), value in zip(fields, launch.params[1:]):
                setattr(args, name, value)
            self.run = functools.partial(hooks.forward, ctypes.byref(launch.bounds), ctypes.byref(args))
            self._args = args
        except (AttributeError, TypeError):
            self.run = launch.launch

    @property
    def fwd_args(self):
        """The launch's arguments as given (``wp.Launch.fwd_args``)."""
        return self.whole.fwd_args

    def set_param_by_name(self, name: str, value) -> None:
        """Change one argument of the recorded launch (``wp.Launch.set_param_by_name``)."""
        self.whole.set_param_by_name(name, value)
        if self._args is not None:
            setattr(self._args, name, self.whole.params[self._labels[name] + 1])

    def launch(self) -> None:
        if not self.device.is_capturing:
            self.run()
        else:  # a capture in progress records Warp's launches only
            self.whole.launch()


class SplitLaunch:
    """A recorded launch run as ``len(starts) - 1`` disjoint node ranges on as many
    threads (each shifted by ``start``). ``kernel`` and ``launch()`` as on ``wp.Launch``.

    ``per_part`` maps a kernel argument name to one value per range (e.g. a
    private output slot where a kernel would otherwise race)."""

    def __init__(
        self, launch: wp.Launch, rows: int | None, starts: list[int], per_part: dict | None = None, start: int = 0
    ):
        self.kernel, self.whole = launch.kernel, launch
        self.parts = []
        for k in range(len(starts) - 1):
            part = copy.copy(launch)
            part.params = list(launch.params)
            part.fwd_args = list(launch.fwd_args) if launch.fwd_args is not None else None
            n = starts[k + 1] - starts[k]
            part.set_dim(n if rows is None else (rows, n))
            part.set_param_by_name("offset", starts[k] + start)
            for name, values in (per_part or {}).items():
                part.set_param_by_name(name, values[k])
            self.parts.append(DirectLaunch(part))
        self._workers = len(self.parts) - 1

    def set_param_by_name(self, name: str, value) -> None:
        """Change one (non-array) argument of every range, as ``wp.Launch.set_param_by_name``."""
        for part in self.parts:
            part.set_param_by_name(name, value)

    def launch(self) -> None:
        first, *rest = self.parts
        pool = _pool(self._workers)
        futures = [pool.submit(p.run) for p in rest]
        first.run()
        for f in futures:
            f.result()


def split_points(n: int, block: int, parts: int) -> list[int]:
    """Range boundaries 0 = s0 < s1 < ... < s_parts = n, cut at multiples of ``block``."""
    nblocks = n // block if n % block == 0 else None
    if nblocks is None:
        return [round(k * n / parts) for k in range(parts + 1)]
    return [round(k * nblocks / parts) * block for k in range(parts + 1)]


def array_key(a: wp.array) -> tuple:
    """What a recorded launch fixes of an array: its address, shape and strides (part of
    the key under which a model's launches are recorded and replayed)."""
    return (a.ptr, a.shape, a.strides)


def foreign_arrays(kernel, inputs, device) -> list[str]:
    """The arguments of a launch of ``kernel`` on ``device`` (a Warp device name or a
    ``Backend``) with ``inputs`` whose array, or an array field of whose struct, lives on
    another device, as "name (device)" ("name.field (device)" for a field): Warp passes an
    array's address to a launch as it is (``wp.config.launch_array_access_mode`` RELAXED), so a
    host array in a CUDA launch is an illegal memory access found only later, at a sync."""
    device = device.device if isinstance(device, Backend) else str(device)
    found = []
    for arg, value in zip(kernel.adj.args, inputs):
        if isinstance(value, wp.array):
            fields = [(arg.label, value)]
        elif wp.types.type_is_struct(arg.type) and value is not None:
            fields = [(f"{arg.label}.{name}", getattr(value, name)) for name in arg.type.vars]
        else:
            continue
        found += [f"{name} ({a.device})" for name, a in fields if isinstance(a, wp.array) and not lives_on(a, device)]
    return found


def check_devices(kernel, inputs, device) -> None:
    """ValueError naming ``foreign_arrays``' arguments, if any, before a launch is recorded."""
    found = foreign_arrays(kernel, inputs, device)
    if found:
        where = device.device if isinstance(device, Backend) else device
        raise ValueError(f"kernel {kernel.key!r} launched on {where} takes arrays elsewhere: {', '.join(found)}")


def record(
    kernel,
    dim,
    inputs,
    *,
    device,
    threads: int,
    block: int = 1,
    per_part=None,
    nodes_per_index: int = 1,
    start: int = 0,
):
    """Record ``kernel`` over ``dim`` (N, or (rows, N) with the node index last;
    or the element count, with ``nodes_per_index`` = np²); ``inputs`` without
    the trailing offset; ``device`` the run's ``Backend`` (or a Warp device, looked up). ``start``: the first index (the launch covers start ..
    start + n − 1 of the node or element index: a range of the elements). ValueError for an
    array (or a struct's array field) on another device than the launch's (``check_devices``). With ``threads`` > 1 on a CPU device and at least
    MIN_POINTS_PER_PART nodes per thread, returns a ``SplitLaunch`` over that
    many index ranges (cut at multiples of ``block``); otherwise one launch (``per_part``
    values of the first range): a ``DirectLaunch`` on a CPU, the ``wp.Launch`` on CUDA."""
    rows, n = (None, dim) if isinstance(dim, int) else dim
    backend = device if isinstance(device, Backend) else Backend.of(device)
    parts = min(backend.launch_parts(threads), n * nodes_per_index // MIN_POINTS_PER_PART)
    if n % block == 0:
        parts = min(parts, n // block)  # no empty range
    if parts <= 1:
        launch = record_one(kernel, dim, [*inputs, start], device=backend)
        for name, values in (per_part or {}).items():
            launch.set_param_by_name(name, values[0])
        return launch
    check_devices(kernel, inputs, backend)
    launch = wp.launch(kernel, dim, [*inputs, start], device=backend.device, record_cmd=True)
    return SplitLaunch(launch, rows, split_points(n, block, parts), per_part, start)


def record_one(kernel, dim, inputs, *, device):
    """Record ``kernel`` over ``dim`` with ``inputs`` as they are (no offset added), one launch:
    a ``DirectLaunch`` on a CPU, the ``wp.Launch`` on CUDA; ``device`` as ``record``'s.
    ValueError for an array elsewhere (``check_devices``)."""
    backend = device if isinstance(device, Backend) else Backend.of(device)
    check_devices(kernel, inputs, backend)
    launch = wp.launch(kernel, dim, inputs, device=backend.device, record_cmd=True)
    return DirectLaunch(launch) if backend.host else launch
