"""One step of a simulation's stepper, replayed as a captured graph where it can be."""

from __future__ import annotations

import warp as wp

from .steppers import StepStats


class StepRunner:
    """Takes the steps of ``stepper`` on the state array ``x`` (stepped in place, never
    replaced), and with ``graphs`` replays each step of a ``capturable`` stepper (the
    explicit ones; semi-implicit and IMEX after their first step, their Helmholtz CG's
    loops conditional nodes inside, on CUDA where Warp has them) as a graph captured
    of an earlier step with the same ``Stepper.graph_key`` (on CUDA a CUDA graph, one
    host call a step instead of one a launch; the same bits as launched one by one); a
    model with a time-dependent forcing runs plain. On a CPU it takes one thread a
    launch (SWE_SPHERE_THREADS=1; Warp replays a CPU graph in one thread) and one
    process; otherwise the steps run plain. ``graphs`` defaults to True on a GPU,
    False on a CPU."""

    def __init__(self, stepper, model, topology, x: wp.array, device: str):
        self.stepper, self.model, self.topology, self.x, self.device = stepper, model, topology, x, device
        self.graphs = wp.get_device(device).is_cuda
        self._graphs = {}  # (stepper, graph_key, watched, x's address) → (graph, StepStats), or None: seen once

    def _take_step(self, watch: bool):
        """One step of the stepper on x and, with ``watch``, the bad-state flag's launch
        (``ShallowWater.watch``; the solvers' device counters left for the block's
        read), else with its solvers' counters read (``Stepper.counts``: raises
        ``StepFailure``); its ``StepStats``. With ``graphs``, a step whose
        ``graph_key`` was seen before runs as a graph: the key's first step runs plain
        (recording its launches, loading their modules and allocating what they
        need, none of which a capture may do), its second is captured and launched,
        the later ones launched. The key holds the stepper and x, so another stepper
        (a branch), a dt (a new stepper) or state array captures anew; a restore
        assigns arrays in place, which a graph (their addresses) follows."""
        stats = self._graphed_step(watch)
        return stats if watch else StepStats(stats.rhs_evals, {**stats.iterations, **self.stepper.counts()})

    def _graphed_step(self, watch: bool):
        """``_take_step`` but the read of the solvers' counters."""
        stepper, model = self.stepper, self.model
        key = None
        if self.graphs and model.threads == 1 and not self.topology.distributed:
            key = stepper.graph_key()
        if key is not None:
            key = (stepper, key, watch, self.x.ptr)
            entry = self._graphs.get(key)
            if entry is not None:
                wp.capture_launch(entry[0])
                return stepper.replayed(entry[1])
            if key in self._graphs:
                # modules are loaded by the key's first step: loading all of them (Warp's
                # default before CUDA 12.3) would compile every kernel the package defines
                with wp.ScopedCapture(device=self.device, force_module_load=False) as capture:
                    stats = stepper.step(self.x)
                    if watch:
                        model.watch(self.x)
                self._graphs[key] = (capture.graph, stats)
                wp.capture_launch(capture.graph)
                return stats
            self._graphs[key] = None
        stats = stepper.step(self.x)
        if watch:
            model.watch(self.x)
        return stats
