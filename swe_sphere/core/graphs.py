"""Captured graphs that cannot fail a run: checked on first use, plain launches on any trouble.

A step, or a Helmholtz solve or FGMRES cycle inside one, may run as a graph
captured once (``wp.ScopedCapture``) and replayed (``wp.capture_launch``): on
CUDA a CUDA graph, one host call instead of one a launch, its loops conditional
nodes (``wp.capture_while``); on a CPU Warp's graph, replayed in one thread.
These paths are the default on CUDA, where no test may have run them, so:

- ``GraphedSteps`` checks the first replay of each step's graph against the same
  step launched plainly (the state, stepper state and device counters compared
  bit for bit) and keeps the plain result;
- an exception in a capture or replay (of a step, a solve's conditional nodes,
  its device totals), or a check that differs, turns the run's ``GraphGuard``
  off: one warning line naming the feature, then plain launches for the rest of
  the run, continued from the state of the plain step (no step lost, the bits of
  a plain run).

A capture executes nothing (CUDA records, Warp's CPU capture records its
operations), so a capture that raises leaves the device arrays as they were.

The mode (``graphs_mode``): "off" plain launches throughout; "on" graphs on any
device; "auto" (the default; environment ``SWE_SPHERE_GRAPHS``) whole steps as
graphs on CUDA only, the solvers' own graphs where they can (as "on").
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass

import numpy as np
import warp as wp

from ..kernels import bits
from .backend import Backend
from .errors import SceneError

MODES = ("off", "on", "auto")
ENV = "SWE_SPHERE_GRAPHS"
# traceback frames that name the feature that failed in a capture or replay (the innermost wins)
FEATURES = {
    "capture_while": "conditional nodes (wp.capture_while)",
    "capture_if": "conditional nodes (wp.capture_if)",
    "totals": "device totals",
    "device_sums": "device totals",
}


def graphs_mode(value, what: str = "graphs") -> str:
    """ "off", "on" or "auto" from ``value`` (one of them, or a bool: True "on",
    False "off"). Raises ``SceneError`` (a ValueError) naming ``what`` and the value."""
    if isinstance(value, bool):
        return "on" if value else "off"
    if not isinstance(value, str) or value not in MODES:
        raise SceneError(f"{what} must be one of {', '.join(MODES)} (got {value!r})")
    return value


def default_mode() -> str:
    """The mode of ``SWE_SPHERE_GRAPHS``, else "auto"; ValueError naming a bad value."""
    return graphs_mode(os.environ.get(ENV, "auto"), ENV)


def _stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


class GraphGuard:
    """Whether a model's launches may be captured as graphs: ``enabled`` until
    ``fail`` turns it off for good with one warning line (``warn(line)``, default
    stderr); the model's solvers and ``GraphedSteps`` consult it."""

    def __init__(self, warn=_stderr):
        self.enabled, self.warn, self.failure = True, warn, None

    def fail(self, what: str) -> None:
        """Turn graphs off; warn once "swe-sphere: <what>; running without graphs"."""
        self.enabled = False
        if self.failure is None:
            self.failure = what
            self.warn(f"swe-sphere: {what}; running without graphs")


def failed(err: BaseException) -> str:
    """ " failed in <feature>: <first line>" of an exception raised in a capture or
    replay (the feature by the innermost frame of its traceback that ``FEATURES``
    names), or " failed: <first line>"."""
    name, tb = "", err.__traceback__
    while tb is not None:
        name = FEATURES.get(tb.tb_frame.f_code.co_name, name)
        tb = tb.tb_next
    text = (str(err).strip().splitlines() or [type(err).__name__])[0]
    return f" failed in {name}: {text}" if name else f" failed: {text}"


def captured(graphs: dict, key, fn, device, guard: GraphGuard | None, what: str) -> None:
    """fn() as the graph captured under ``key`` in ``graphs`` on its first call and
    replayed after; inline (plain launches) while a caller captures (its graph holds
    fn's launches) or ``guard`` is off. A capture or replay that raises turns the
    guard off (one line naming ``what`` and the feature) and fn() runs inline: the
    capture executed nothing, and a replay that raises is refused before it runs."""
    dev = wp.get_device(device)
    if dev.is_capturing or (guard is not None and not guard.enabled):
        fn()
        return
    try:
        graph = graphs.get(key)
        if graph is None:
            with wp.ScopedCapture(device=dev) as capture:
                fn()
            graph = graphs[key] = capture.graph
        wp.capture_launch(graph)
    except Exception as err:
        if guard is None:
            raise
        graphs.clear()
        guard.fail(f"{Backend.of(dev).graph_name} of {what}{failed(err)}")
        fn()


@dataclass
class _Snapshot:
    """What a step changes: x, the stepper's ``state()`` and its device arrays."""

    x: wp.array
    state: dict
    arrays: list
    carried: object  # ``GraphCapture.carried``


@dataclass
class _Entry:
    graph: object
    stats: object  # the captured step's StepStats, returned by each replay


class GraphedSteps:
    """Steps of a ``capturable`` stepper replayed as graphs (``Simulation`` holds one).

    ``step(stepper, model, x, watch)`` advances x by one step of ``stepper`` (and,
    with ``watch``, ``model.bad_nodes.watch(x)``) and returns its ``StepStats``. A step whose
    ``graph_key`` (a ``capturable`` stepper's, ``steppers.capabilities.GraphCapture``) was seen before runs as a graph: the key's first step
    runs plain (loading modules and allocating what its launches need, none of
    which a capture may do); its second runs plain (the solvers' own graphs off),
    is captured, replayed from the state before it and compared bit for bit
    (``_checked``); the later ones replay (one that raises: plain, as in
    ``captured``). Keys of one ``graph_family`` (a controlled run's Δt: the same
    launches with other arguments) check only the family's first graph; the others are
    captured at their second step and replayed, not compared. The key holds the stepper and x's
    address, so a branch, a new dt or another state array captures anew; a
    restore assigns arrays in place, which a graph follows. Whole steps are
    graphs with ``mode`` "on", or "auto" on CUDA, on one CPU thread a launch and
    one process; ``guard`` (the model's) off: plain launches.
    """

    def __init__(self, backend: Backend, guard: GraphGuard, mode: str = "auto"):
        self.backend, self.device, self.guard = backend, backend.device, guard
        self._graphs: dict = {}  # (stepper, graph_key, watch, x's address) → _Entry, or None: seen once
        self._families: set = set()  # (stepper, graph_family, watch, x's address) whose first graph was checked
        self.checked = 0  # the graphs compared with plain launches (``_checked``), kept or not
        self.mode = mode

    @property
    def mode(self) -> str:
        return self._mode

    @mode.setter
    def mode(self, value) -> None:
        self._mode = graphs_mode(value)
        if self._mode == "off":
            self.guard.enabled = False
        elif self.guard.failure is None:
            self.guard.enabled = True

    @property
    def active(self) -> bool:
        """Whether whole steps may run as graphs."""
        on = self._mode == "on" or (self._mode == "auto" and self.backend.graphs_pay)
        return on and self.guard.enabled

    @property
    def kept(self) -> int:
        """The step graphs checked and kept (replayed by the steps of their key)."""
        return sum(entry is not None for entry in self._graphs.values())

    def step(self, stepper, model, x, watch: bool):
        key = None
        if self.active and stepper.capturable and model.threads == 1 and not model.topology.distributed:
            key = stepper.graph_key()  # a ``steppers.capabilities.GraphCapture``'s
        if key is None:
            return self._plain(stepper, model, x, watch)
        family = stepper.graph_family()
        family = None if family is None else (stepper, family, watch, x.ptr)
        key = (stepper, key, watch, x.ptr)
        entry = self._graphs.get(key)
        if entry is not None:
            try:
                wp.capture_launch(entry.graph)
            except Exception as err:  # refused before it ran (as in ``captured``): the step runs plain
                self._graphs.clear()
                self._families.clear()
                self.guard.fail(f"{self.backend.graph_name} of the {stepper.name} step{failed(err)}")
                return self._plain(stepper, model, x, watch)
            return stepper.replayed(entry.stats)
        if key not in self._graphs:
            self._graphs[key] = None
            return self._plain(stepper, model, x, watch)
        if family in self._families:
            return self._captured(key, stepper, model, x, watch)
        stats = self._checked(key, stepper, model, x, watch)
        if family is not None and self._graphs.get(key) is not None:
            self._families.add(family)
        return stats

    def _captured(self, key, stepper, model, x, watch: bool):
        """The key's second step, of a family whose first graph was checked (``GraphCapture.graph_family``:
        the same launches, other arguments): captured and replayed, not compared (as a later replay;
        a capture or replay that raises: plain, as in ``captured``)."""
        state, carried = stepper.state(), stepper.carried()  # the capture moves the host's side on
        try:
            with wp.ScopedCapture(device=self.device, force_module_load=False) as capture:
                stats = self._plain(stepper, model, x, watch)  # records the launches, runs none
            wp.capture_launch(capture.graph)
        except Exception as err:  # the capture ran nothing, a refused replay nothing: x as before
            self._graphs.clear()
            self._families.clear()
            self.guard.fail(f"{self.backend.graph_name} of the {stepper.name} step{failed(err)}")
            stepper.restore(state)
            stepper.resume(carried)
            return self._plain(stepper, model, x, watch)
        self._graphs[key] = _Entry(capture.graph, stats)
        return stats

    @staticmethod
    def _plain(stepper, model, x, watch: bool):
        stats = stepper.step(x)
        if watch:
            model.bad_nodes.watch(x)
        return stats

    def _checked(self, key, stepper, model, x, watch: bool):
        """The key's second step: plain (the solvers' graphs off, as a run without graphs),
        then from the state before it captured and replayed, the two compared bit for bit.
        Equal: the graph is kept for the key's later steps. Else, or when the capture or
        replay raises: the plain step's result stands and the guard fails (one line)."""
        self.checked += 1
        arrays = [*stepper.device_arrays(), *([model.bad_nodes.watched] if watch else [])]
        before = self._snapshot(stepper, x, arrays)
        self.guard.enabled = False
        try:
            stats = self._plain(stepper, model, x, watch)
        finally:
            self.guard.enabled = True
        plain = self._snapshot(stepper, x, arrays)
        self._restore(before, stepper, x, arrays)
        what = f"{self.backend.graph_name} of the {stepper.name} step"
        try:  # modules are loaded by the key's first step: loading all of them (Warp's default
            # before CUDA 12.3) would compile every kernel the package defines
            with wp.ScopedCapture(device=self.device, force_module_load=False) as capture:
                graphed = self._plain(stepper, model, x, watch)
            wp.capture_launch(capture.graph)
        except Exception as err:
            self._fall_back(plain, stepper, x, arrays, what + failed(err))
            return stats
        if graphed != stats or not _same(plain, self._snapshot(stepper, x, arrays)):
            self._fall_back(plain, stepper, x, arrays, f"{what} differs from plain launches")
            return stats
        self._graphs[key] = _Entry(capture.graph, graphed)
        return graphed

    def _fall_back(self, plain: _Snapshot, stepper, x, arrays, what: str) -> None:
        self._restore(plain, stepper, x, arrays)
        self._graphs.clear()
        self._families.clear()
        self.guard.fail(what)

    @staticmethod
    def _snapshot(stepper, x, arrays) -> _Snapshot:
        return _Snapshot(wp.clone(x), stepper.state(), [wp.clone(a) for a in arrays], stepper.carried())

    @staticmethod
    def _restore(snap: _Snapshot, stepper, x, arrays) -> None:
        wp.copy(x, snap.x)
        stepper.restore(snap.state)
        for a, saved in zip(arrays, snap.arrays):
            wp.copy(a, saved)
        stepper.resume(snap.carried)


def _equal(u, v) -> bool:
    """Host values: arrays the same shape, dtype and bytes (NaNs and signed zeros as bits);
    scalars the same ``repr`` (a float's round-trips exactly)."""
    if not isinstance(u, (np.ndarray, wp.array)):
        return repr(u) == repr(v)
    u, v = (np.ascontiguousarray(a.numpy() if isinstance(a, wp.array) else a) for a in (u, v))
    return u.shape == v.shape and u.dtype == v.dtype and u.tobytes() == v.tobytes()


def _bytes(a: wp.array) -> tuple[wp.array, wp.array]:
    """(a's bytes as a uint8 array over its memory, the contiguous array they are of: a, or a's
    copy where a is strided; keep it alive while the bytes are used)."""
    whole = a if a.is_contiguous else wp.clone(a)
    size = whole.size * wp.types.type_size_in_bytes(whole.dtype)
    return wp.array(ptr=whole.ptr, dtype=wp.uint8, shape=(size,), device=whole.device), whole


def _same(a: _Snapshot, b: _Snapshot) -> bool:
    """Whether two snapshots hold the same bits."""
    if a.state.keys() != b.state.keys():
        return False
    return same_bits([(a.x, b.x), *zip(a.arrays, b.arrays), *((a.state[k], b.state[k]) for k in a.state)])


def same_bits(pairs) -> bool:
    """Whether each pair (u, v) holds the same bits: two Warp arrays the same shape, dtype,
    device and bytes (NaNs and signed zeros as bits), compared on their device
    (``kernels.bits.differ``) with one flag read a device; numpy arrays likewise on the host;
    other values the same ``repr``. ``GraphedSteps``' check: it brought every state and stepper
    array to the host and compared them there, 23–87 ms a check at TC5 ne60 on an H100 (cProfile)."""
    flags, held = {}, []
    for u, v in pairs:
        if not (isinstance(u, wp.array) and isinstance(v, wp.array)):
            if not _equal(u, v):
                return False
            continue
        if u.shape != v.shape or u.dtype != v.dtype or u.device != v.device:
            return False
        if u.size == 0:
            continue
        flag = flags.get(u.device.alias)
        if flag is None:
            flag = flags[u.device.alias] = wp.zeros(1, dtype=wp.int32, device=u.device)
        (bu, whole_u), (bv, whole_v) = _bytes(u), _bytes(v)
        held += [whole_u, whole_v]  # the memory the byte views point into, alive until the reads
        wp.launch(bits.differ, dim=bu.shape[0], inputs=[bu, bv, flag], device=u.device)
    return all(int(flag.numpy()[0]) == 0 for flag in flags.values())
