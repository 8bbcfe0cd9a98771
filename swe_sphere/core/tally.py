"""What the model asks of the device, counted: kernel launches, their bytes, memsets
and copies, and host reads (the measure of ``benchmarks/gpu/gpu_model.py`` and of
the tests that a step needs no host round trip).

``instrumented(tally)`` wraps Warp's launch entry points (recorded
``wp.Launch.launch`` and direct ``wp.launch``), the recorded CPU launches the model calls straight
through (``parallel.DirectLaunch.launch``), its memsets and copies
(``zero_``, ``fill_``, ``assign``, ``wp.copy``) and its read-back
``wp.array.numpy`` and the wait for an event (``wp.synchronize_event``: a read into page-locked
memory, ``core.backend.HostRead``) for as long as the context lasts; a ``Tally`` counts what
passes while its ``counting()`` context is active. A ``.numpy()`` of a CUDA
array waits for the device (a host synchronisation) and cannot be part of a
CUDA graph: a step that reads none can be captured as one.
"""

from __future__ import annotations

import ast
import collections
import contextlib
import functools

import warp as wp

from .parallel import DirectLaunch


@functools.cache
def reads_writes(kernel) -> tuple:
    """(read, written) for each argument of ``kernel``, from its source (the tree Warp parsed,
    ``adj.tree``): written where a subscript of it is stored to (``a[i] = ...``; ``a[i] += ...``
    reads it too) or it is a ``wp.atomic_*``'s array; read where it appears otherwise (an
    expression, a call's argument: a ``wp.func`` that writes into an array it is passed counts as
    a read), but for its type or shape (``a.dtype``, ``a.shape``)."""
    written, read, not_read = set(), set(), set()
    for node in ast.walk(kernel.adj.tree):
        if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Store) and isinstance(node.value, ast.Name):
            written.add(node.value.id)
            not_read.add(id(node.value))
        elif isinstance(node, ast.Attribute) and node.attr in ("dtype", "shape"):
            not_read.add(id(node.value))  # not the array's values
        elif isinstance(node, ast.AugAssign) and isinstance(node.target, ast.Subscript):
            read.add(getattr(node.target.value, "id", None))
        elif isinstance(node, ast.Call) and getattr(node.func, "attr", "").startswith("atomic_") and node.args:
            written.add(getattr(node.args[0], "id", None))
    for node in ast.walk(kernel.adj.tree):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Load) and id(node) not in not_read:
            read.add(node.id)
    return tuple((v.label in read, v.label in written) for v in kernel.adj.args)


def array_bytes(args, kernel=None) -> dict:
    """{address: bytes} of each distinct array among a launch's arguments, those
    inside a ``wp.struct`` argument (``kernels.dss.Copies``) included: its capacity once for a
    read and once for a write where ``kernel``'s source says which its argument does
    (``reads_writes``: an array updated in place, or passed as a term and as the output, moves
    its bytes both ways), else (no kernel, a struct's fields) once."""

    def fields(arg):  # a Warp struct's field names (Warp 1.19), else None
        return getattr(getattr(arg, "_cls", None), "vars", None)

    flags = reads_writes(kernel) if kernel is not None else ()
    seen: dict = {}  # address: [capacity, read, written]
    for k, arg in enumerate(args):
        read, written = flags[k] if k < len(flags) else (False, False)
        for a in (getattr(arg, f) for f in fields(arg)) if fields(arg) else (arg,):
            if isinstance(a, wp.array):
                entry = seen.setdefault(a.ptr, [a.capacity, False, False])
                entry[1], entry[2] = entry[1] or read, entry[2] or written
    return {ptr: capacity * max(1, read + written) for ptr, (capacity, read, written) in seen.items()}


class Tally:
    """Launches (by kernel key), bytes (each distinct array argument's capacity once
    a launch for a read and once for a write: ``array_bytes``), memsets/copies and host reads (``syncs``: ``.numpy()`` read-backs and
    waits for an event) seen while ``counting()``."""

    def __init__(self):
        self.active = False
        self.reset()

    def reset(self):
        self.launches = collections.Counter()
        self.bytes = collections.Counter()
        self.memops = 0
        self.membytes = 0
        self.syncs = 0

    def kernel(self, kernel, args):
        if self.active:
            seen = array_bytes(args, kernel)
            self.launches[kernel.key] += 1
            self.bytes[kernel.key] += sum(seen.values())

    def memop(self, nbytes):
        if self.active:
            self.memops += 1
            self.membytes += nbytes

    def read(self):
        if self.active:
            self.syncs += 1

    @contextlib.contextmanager
    def counting(self):
        """Count from zero while the context lasts (the counts stay readable after)."""
        self.reset()
        self.active = True
        try:
            yield self
        finally:
            self.active = False

    def paused(self, fn):
        """fn, not counted while it runs (a step's own launches with its solves apart)."""

        def run(*args, **kw):
            was, self.active = self.active, False
            try:
                return fn(*args, **kw)
            finally:
                self.active = was

        return run

    @property
    def total_launches(self):
        return sum(self.launches.values()) + self.memops

    @property
    def total_bytes(self):
        return sum(self.bytes.values()) + self.membytes


@contextlib.contextmanager
def instrumented(tally: Tally):
    """Wrap Warp's launch, memset, copy and read-back entry points so that ``tally``
    sees them, for this process, until the context ends (then Warp's own again).
    The wrappers cost host time per launch: time nothing inside."""
    real = {
        "launch": wp.Launch.launch,
        "direct": DirectLaunch.launch,
        "wp.launch": wp.launch,
        "wp.copy": wp.copy,
        "wp.synchronize_event": wp.synchronize_event,
        **{name: getattr(wp.array, name) for name in ("zero_", "fill_", "assign", "numpy")},
    }

    def record_launch(self, *a, **k):
        tally.kernel(self.kernel, self.fwd_args or [])
        return real["launch"](self, *a, **k)

    def direct_launch(self):  # once: not again where it takes Warp's own path
        tally.kernel(self.kernel, self.fwd_args or [])
        return tally.paused(real["direct"])(self)

    def launch(kernel, dim=None, inputs=(), outputs=(), *a, **k):
        if not k.get("record_cmd"):
            tally.kernel(kernel, [*inputs, *outputs])
        return real["wp.launch"](kernel, dim, inputs, outputs, *a, **k)

    def copy(dest, src, *a, **k):
        tally.memop(2 * src.capacity)
        return real["wp.copy"](dest, src, *a, **k)

    def memop(name, factor):
        def method(self, *a, **k):
            tally.memop(factor * self.capacity)
            return real[name](self, *a, **k)

        return method

    def numpy(self):
        tally.read()
        return real["numpy"](self)

    def synchronize_event(event):
        tally.read()
        return real["wp.synchronize_event"](event)

    wp.Launch.launch, wp.launch, wp.copy, wp.array.numpy = record_launch, launch, copy, numpy
    DirectLaunch.launch = direct_launch
    wp.synchronize_event = synchronize_event
    for name, factor in (("zero_", 1), ("fill_", 1), ("assign", 2)):
        setattr(wp.array, name, memop(name, factor))
    try:
        yield tally
    finally:
        wp.Launch.launch, wp.launch, wp.copy = real["launch"], real["wp.launch"], real["wp.copy"]
        DirectLaunch.launch = real["direct"]
        wp.synchronize_event = real["wp.synchronize_event"]
        for name in ("zero_", "fill_", "assign", "numpy"):
            setattr(wp.array, name, real[name])
