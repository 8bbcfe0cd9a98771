"""The tendency's vector lanes on the CPU: W elements a vector at np 4 (and 8) where it pays.

On the per-element layout an element's GLL row at np 4 is 4 values: a float32 row fills a
quarter of a 512-bit register, a float64 row half. ``TendencyLanes`` runs the tendency with the
element index innermost instead (``kernels.tendency_lanes.tendency_across``, as the ∇⁴'s
``laplacian_across`` at np ≥ 5): a thread a block of W elements, each node's value a vector of
theirs, the geometry held once in that layout, the state and the tendency in the node layout,
moved through a thread's scratch (float32's 16 × 16 blocks transposed in registers). ``LANES`` says where it runs, per float type,
from one thread's CPU clock at np 4 (``benchmarks/micro/precision_speed.py`` with
``float32:rows``, the rows timed beside the lanes): float32's tendency ran 1.2–1.8× faster on
16 lanes than on rows (TC5 ne30 and ne120); float64's 0.5–0.85× as fast on 8 or 16, so float64
keeps its rows (and its bits, which the lanes reproduce: tests/model/test_tendency_lanes.py).
At np 8 a float32 row fills half a register; the float32 state's lanes there move each
element's rows by four 16 × 16 transposes and divide once a node (``tendencies.finish``'s
determinant): Galewsky ne12 np8's tendency 0.212–0.218 ms a call on rows, 0.248 in lanes
dividing three times, 0.171–0.176 once (one thread, CPU clock, the least of 7 rounds of 50
calls, load 8–9). Moved lane by lane (np 6, or np 8's mixed float32 from its float64 state)
they ran slower than the rows (Galewsky ne12 np6, RHS 0.309 against 0.266 ms), and the mixed
float32 keeps its bits: neither runs in lanes.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..kernels import operators, tendency_lanes

# W, the elements a vector of the tendency at np 4 per float type; 0: the rows (one element a thread)
LANES = {wp.float32: 16, wp.float64: 0}


class TendencyLanes:
    """The lanes of ``model``'s tendency (a ``ShallowWater``): the geometry in the across layout
    (``operators.across_layout``, its last block padded), made on first use from the model's
    float64 values (``ElementOperators.values``) rounded once to the tendency's type, and each
    CPU thread's scratch (9, np²) of W-vectors.

    ``lanes`` W: ``width`` (None: ``LANES`` of the tendency's float type ``dtype``) on a CPU's
    per-element layout at np 4 (and the float32 state's at np 8) with any element, else 0: a rank's few elements too (one block, its
    lanes past them padded), so that every rank count has one arithmetic. Where they run (``applies``),
    the model keeps no float32 rows of metdet, fcor and −g∇hs (``precision.TendencyArrays``):
    the geometry is 8 rows of N values of the tendency's type (the metric's 4: D in float32, D⁻¹ formed
    from it; D⁻¹ in float64), besides spheremp."""

    def __init__(self, model, width: int | None, dtype, per_element: bool):
        self.model = m = model
        np_ = m.grid.np
        w = LANES.get(dtype, 0) if width is None else int(width)
        # a CPU's threads each have their scratch; on CUDA (per element or not) the lanes are not measured.
        # np 8: the float32 state's, whose rows move by 16 × 16 transposes (``tendency_lanes.across_views``)
        shuffled = (
            np_ == 8
            and m.state_dtype is not wp.float64
            and tendency_lanes.across_views(np_, w, dtype, True) == (16, 16)
        )
        ok = m.backend.host and per_element and (np_ == 4 or shuffled) and w > 1 and m.N > 0
        self.lanes, self.dtype = (w if ok else 0), dtype
        self._geometry = None
        if self.lanes:
            vw = wp.types.vector(length=self.lanes, dtype=dtype)
            slots = max(1, m.launches.threads)
            scratch = wp.zeros((slots, 9, np_**2), dtype=vw, device=m.device)
            self._per_part = {"S": [scratch[i] for i in range(slots)]}

    def applies(self, tracers: int) -> bool:
        """Whether a tendency with ``tracers`` rows of tracer mass runs in lanes: W > 0, no tracers
        (their rows ride ``tendencies.tendency_element``, and the dynamics' with them)."""
        return bool(self.lanes) and not tracers

    def blocks(self, runs) -> list[int]:
        """The blocks of W elements that hold the element ranges ``runs`` ((start, stop); None: every
        element), ascending: a part's elements with the others of their blocks, computed and not
        assembled (``ElementPart``)."""
        W, nelem = self.lanes, self.model.N // self.model.grid.np**2
        held = set()
        for run in runs:
            start, stop = (0, nelem) if run is None else run
            held.update(range(start // W, -(-stop // W)))
        return sorted(held)

    def geometry(self, departed: bool = False) -> list:
        """The metric (4, ·: D in float32, whose kernel forms D⁻¹ from it, D⁻¹ in float64), metdet, fcor,
        −g∇hs (2, ·; the metric's rows without topography: unread) and spheremp in the across layout,
        W-vectors of the tendency's type, from
        their float64 values (``ElementOperators.values``). ``departed``: for a float32 state's
        tendency, which takes metdet as det D (``tendency_lanes.tendency_across``'s determinant) and
        reads none: fcor's array stands in, and metdet's (4 B a node) is made only where a launch
        reads it (the mixed float32's, float64's)."""
        if departed and self.dtype is wp.float32:
            metric, _, fcor, *rest = self._common()
            return [metric, fcor, fcor, *rest]
        geometry = self._common()
        if geometry[1] is None:
            geometry[1] = self._across(self.model.operators.values("metdet"), 1)
        return geometry

    def _across(self, values, rows: int):
        """``values`` (rows, N) in the across layout (``operators.across_layout``, its last block padded),
        W-vectors of the tendency's type rounded once (as ``ElementOperators.rounded``); one row as (·)."""
        m, vw = self.model, wp.types.vector(length=self.lanes, dtype=self.dtype)
        values = operators.across_layout(np.reshape(values, (rows, -1)), self.lanes, m.grid.np, pad=True)
        out = wp.array(values, dtype=vw, device=m.device)
        return out if rows > 1 else out[0]

    def _common(self) -> list:
        """``geometry``'s arrays, made on first use, metdet None until a launch reads it."""
        if self._geometry is None:
            m, across = self.model, self._across
            ops = m.operators
            metric = across(ops.values("D" if self.dtype is wp.float32 else "Dinv"), 4)  # float32 inverts D
            # −g∇hs, read only with topography, as the rows
            forcing = across(ops.values("forcing"), 2) if "forcing" in ops.geometry else metric[0:2]
            self._geometry = [
                metric,
                None,  # metdet: ``geometry``'s, where a launch reads it
                across(ops.values("fcor"), 1),  # as it is now: a shared ensemble's members set theirs after the build
                forcing,
                across(m.spheremp[: m.N].numpy(), 1),
            ]
        return self._geometry

    def launch(self, x: wp.array2d, tend: wp.array2d, terms: tuple, weighted: bool, blocks: tuple[int, int]):
        """The recorded launch of the tendency of ``terms`` (``weighted``: times spheremp) of the
        state ``x`` (3, N; float64, or a float32 state's departure) into ``tend`` (3, N) over the
        blocks ``blocks`` (start, stop)."""
        m, t, W = self.model, self.model.tendency_arrays, self.lanes
        np_ = m.grid.np
        nn = np_ * np_
        departed = x.dtype is not wp.float64
        kernel = tendency_lanes.tendency_across(terms, np_, W, weighted, t.dtype, departed)
        xrow, trow = tendency_lanes.across_views(np_, W, t.dtype, departed)
        inputs = [
            operators.row_vectors(x, xrow),
            *self.geometry(departed),
            m.g,
            operators.row_type(xrow, x.dtype)(t.depth),
            t.dvv_rows,
            self._per_part["S"][0],
            operators.row_vectors(tend, trow),
            m.N // nn,
        ]
        start, stop = blocks
        return m.launches.record(
            kernel, stop - start, inputs, nodes_per_index=W * nn, per_part=self._per_part, start=start
        )
