"""What the model asks of the device, counted: kernel launches, their bytes, memsets
and copies, and host reads (the measure of ``benchmarks/gpu/gpu_model.py`` and of
the tests that a step needs no host round trip).

``instrumented(tally)`` wraps Warp's launch entry points (recorded
``wp.Launch.launch`` and direct ``wp.launch``), its memsets and copies
(``zero_``, ``fill_``, ``assign``, ``wp.copy``) and its read-back
``wp.array.numpy`` and the wait for an event (``wp.synchronize_event``: a read into page-locked
memory, ``core.backend.HostRead``) for as long as the context lasts; a ``Tally`` counts what
passes while its ``counting()`` context is active. A ``.numpy()`` of a CUDA
array waits for the device (a host synchronisation) and cannot be part of a
CUDA graph: a step that reads none can be captured as one.
"""

from __future__ import annotations

import collections
import contextlib

import warp as wp


def array_bytes(args) -> dict:
    """{address: bytes} of each distinct array among a launch's arguments, those
    inside a ``wp.struct`` argument (``kernels.dss.Copies``) included."""

    def fields(arg):  # a Warp struct's field names (Warp 1.19), else None
        return getattr(getattr(arg, "_cls", None), "vars", None)

    arrays = [a for arg in args for a in ((getattr(arg, f) for f in fields(arg)) if fields(arg) else (arg,))]
    return {a.ptr: a.capacity for a in arrays if isinstance(a, wp.array)}


class Tally:
    """Launches (by kernel key), bytes (each distinct array argument's capacity once
    a launch), memsets/copies and host reads (``syncs``: ``.numpy()`` read-backs and
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
            seen = array_bytes(args)
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
        "wp.launch": wp.launch,
        "wp.copy": wp.copy,
        "wp.synchronize_event": wp.synchronize_event,
        **{name: getattr(wp.array, name) for name in ("zero_", "fill_", "assign", "numpy")},
    }

    def record_launch(self, *a, **k):
        tally.kernel(self.kernel, self.fwd_args or [])
        return real["launch"](self, *a, **k)

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
    wp.synchronize_event = synchronize_event
    for name, factor in (("zero_", 1), ("fill_", 1), ("assign", 2)):
        setattr(wp.array, name, memop(name, factor))
    try:
        yield tally
    finally:
        wp.Launch.launch, wp.launch, wp.copy = real["launch"], real["wp.launch"], real["wp.copy"]
        wp.synchronize_event = real["wp.synchronize_event"]
        for name in ("zero_", "fill_", "assign", "numpy"):
            setattr(wp.array, name, real[name])
