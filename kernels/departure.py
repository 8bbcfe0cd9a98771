"""The float32 state and the float64 one (``precision = "float32_state"``): u, v and the depth's
departure h − H₀ from a reference depth H₀ (m) in float32, which a step's stages carry, and
u, v, h in float64, which the clock's loop, the diagnostics and the files read between steps.

The departure keeps float32's 24 bits for h's variation, not for its mean (a step changes a 10 km
depth by centimetres: float32's spacing at 10 km is 1 mm, at a 100 m departure 8 µm), as
SpeedyWeather and the IFS store their state (Klöwer et al. 2022, J. Adv. Model. Earth Syst. 14,
e2021MS002684). The step's increment comes back to the float64 state either rounded with the
state (``from_departure``: the state is the float32 one) or compensated (``add_increment``: the
float32 step's increment y(n+1) − y(n), exact in float64, added to the float64 state, whose low
bits carry what float32 rounded off, as Kahan's compensated sum carries it: Klöwer et al. 2022's
compensated time integration).

The global mass fixer's kernels (``model.mass_fixer``): each element's mass Σ spheremp·h
(``element_mass``) and the depth moved by the mass lost (``restore_mass``).

Each reads its arrays as lanes (``model.launches.LaunchRecorder.run_lanes``): vectors of W
consecutive nodes (``kernels.operators.row_vectors``), an element's np² on the per-element layout
(one vector loop a CPU thread: 3.7–5× the scalar loop's speed at np 4), one node on the per-node
layout (a node a CUDA thread); the same bits either way. Pointwise over (rows, N/W), ``offset`` in
lanes; row 2 is h.
"""

from typing import Any

import warp as wp

f32 = wp.float32
f64 = wp.float64


@wp.func
def reference(r: int, h0: f64):
    """What row r's departure is taken from: H₀ (m) for the depth (row 2), 0 for the wind."""
    return wp.where(r == 2, h0, f64(0.0))


@wp.kernel(enable_backward=False)
def to_departure(x: wp.array2d(dtype=Any), h0: f64, y: wp.array2d(dtype=Any), offset: int):
    """y = x − (0, 0, H₀), rounded once to float32 (x float64 lanes, y float32's)."""
    r, k = wp.tid()
    p = k + offset
    y[r, p] = y.dtype(x[r, p] - x.dtype(reference(r, h0)))


@wp.kernel(enable_backward=False)
def from_departure(y: wp.array2d(dtype=Any), h0: f64, x: wp.array2d(dtype=Any), offset: int):
    """x = y + (0, 0, H₀) in float64: the float32 state's value."""
    r, k = wp.tid()
    p = k + offset
    x[r, p] = x.dtype(y[r, p]) + x.dtype(reference(r, h0))


@wp.kernel(enable_backward=False)
def add_increment(y: wp.array2d(dtype=Any), h0: f64, x: wp.array2d(dtype=Any), offset: int):
    """x += y − ``to_departure``(x): the float32 step's increment, from y(n) as ``to_departure``
    took it of this x (the same bits), added in float64."""
    r, k = wp.tid()
    p = k + offset
    v = x[r, p]
    before = x.dtype(y.dtype(v - x.dtype(reference(r, h0))))
    x[r, p] = v + (x.dtype(y[r, p]) - before)


@wp.kernel(enable_backward=False)
def element_mass(
    h: wp.array(dtype=Any), spheremp: wp.array(dtype=Any), lanes: int, slot: int, out: wp.array2d(dtype=f64),
    offset: int,
):  # fmt: skip
    """out[slot, e] = Σ spheremp·h (m³) over element e's ``lanes`` lanes (its np² nodes), in
    node order: the same bits for an element whatever the ranks and the layout (HOMME
    ``global_integral``'s element sums); h float64, or a float32 state's h − H₀ read in float64
    (its mass less H₀·area: the fixer takes differences). Dim nelem (``offset`` in elements)."""
    e = wp.tid() + offset
    s = f64(0.0)
    for p in range(e * lanes, (e + 1) * lanes):
        w = spheremp[p]
        s += wp.dot(w, type(w)(h[p]))
    out[slot, e] = s


@wp.kernel(enable_backward=False)
def restore_mass(h: wp.array(dtype=Any), totals: wp.array2d(dtype=f64), area: f64, lanes: int, offset: int):
    """h += (totals[0, m] − totals[1, m]) / area in member m (h's lanes ``lanes`` a member, member
    after member): the mass lost between its two totals (m³) spread over its sphere's area (m²)
    by weight spheremp, a uniform depth (every copy of a node moved alike: h stays continuous).
    Dim N/W."""
    p = wp.tid() + offset
    m = p // lanes
    v = h[p]
    h[p] = v + type(v)(type(v[0])((totals[0, m] - totals[1, m]) / area))  # rounded once to h's float type
