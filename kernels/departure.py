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

Pointwise over (rows, N) as ``blas``: ``block`` consecutive nodes a thread, ``offset`` in blocks;
row 2 is h.
"""

import warp as wp

f32 = wp.float32
f64 = wp.float64


@wp.func
def reference(r: int, h0: f64):
    """What row r's departure is taken from: H₀ (m) for the depth (row 2), 0 for the wind."""
    return wp.where(r == 2, h0, f64(0.0))


@wp.kernel(enable_backward=False)
def to_departure(
    x: wp.array2d(dtype=f64), h0: f64, y: wp.array2d(dtype=f32), block: int, offset: int
):  # fmt: skip
    """y = x − (0, 0, H₀), rounded once to float32. Dim (rows, N/block)."""
    r, k = wp.tid()
    s = reference(r, h0)
    start = (k + offset) * block
    for p in range(start, start + block):
        y[r, p] = f32(x[r, p] - s)


@wp.kernel(enable_backward=False)
def from_departure(
    y: wp.array2d(dtype=f32), h0: f64, x: wp.array2d(dtype=f64), block: int, offset: int
):  # fmt: skip
    """x = y + (0, 0, H₀) in float64: the float32 state's value. Dim (rows, N/block)."""
    r, k = wp.tid()
    s = reference(r, h0)
    start = (k + offset) * block
    for p in range(start, start + block):
        x[r, p] = f64(y[r, p]) + s


@wp.kernel(enable_backward=False)
def add_increment(
    y: wp.array2d(dtype=f32), h0: f64, x: wp.array2d(dtype=f64), block: int, offset: int
):  # fmt: skip
    """x += y − ``to_departure``(x): the float32 step's increment, from y(n) as ``to_departure``
    took it of this x (the same bits), added in float64. Dim (rows, N/block)."""
    r, k = wp.tid()
    s = reference(r, h0)
    start = (k + offset) * block
    for p in range(start, start + block):
        before = f64(f32(x[r, p] - s))
        x[r, p] = x[r, p] + (f64(y[r, p]) - before)


@wp.kernel(enable_backward=False)
def element_mass(
    x: wp.array2d(dtype=f64), spheremp: wp.array(dtype=f64), block: int, slot: int, out: wp.array2d(dtype=f64),
    offset: int,
):  # fmt: skip
    """out[slot, e] = Σ spheremp·h (m³) over element e's ``block`` = np² nodes, in their order:
    the same bits for an element whatever the ranks (HOMME ``global_integral``'s element sums).
    Dim nelem (``offset`` in elements)."""
    e = wp.tid() + offset
    s = f64(0.0)
    for p in range(e * block, (e + 1) * block):
        s += spheremp[p] * x[2, p]
    out[slot, e] = s


@wp.kernel(enable_backward=False)
def restore_mass(x: wp.array2d(dtype=f64), totals: wp.array(dtype=f64), area: f64, block: int, offset: int):
    """h += (totals[0] − totals[1]) / area: the mass lost between the two totals (m³) spread
    over the sphere's area (m²) by weight spheremp, a uniform depth (every copy of a node moved
    alike: h stays continuous). Dim (rows, N/block); rows other than h untouched."""
    r, k = wp.tid()
    if r == 2:
        d = (totals[0] - totals[1]) / area
        start = (k + offset) * block
        for p in range(start, start + block):
            x[2, p] = x[2, p] + d
