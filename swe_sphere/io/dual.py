"""The GLL dual mesh: one control-volume polygon per unique GLL node, its area the node's
assembled ``spheremp``.

The run file's fields are point values at the GLL nodes; tools that average, integrate or
remap want cells. Each unique node gets the cell whose spherical area is its quadrature
weight ``grid.area`` (assembled spheremp, m²), so a tool's area-weighted sum over these
cells is the model's own GLL quadrature. Construction after HOMME's control volumes
(``surfaces_mod``, ``InitControlVolumes``): in each element the cell boundaries start on
the product grid at the running sums of the GLL weights, t₀ = −1, t_k = −1 + Σ_{m<k} w_m
(each t_k lies between GLL points k−1 and k), which gives the reference cell of node
(i, j) the area w_i·w_j. Mapped to the sphere and joined by great circles (the points on
element edges dropped), those cells miss spheremp by 0.5 % (ne4) to 0.08 % (ne30) inside
the cube's faces, 3 % to 0.4 % along its edges and 49 % at its 8 corners, whose
triangles cut off three corners of the product-grid hexagon. HOMME keeps squares and
triangles and iterates on the vertices, but its local iteration does not converge at
the four cells round an element's centre (so it adds pentagons there: E3SM's
"np4_pentagons" grids); here one global, damped Newton iteration (Levenberg–Marquardt,
``dual_mesh``) moves all vertices at once and reaches the areas to RTOL with squares and
triangles only. The cells come out convex on every grid tried (ne ≤ 4 for np 2..8; ne 5, 6,
8, 30, 60, 120 at np4; the refined and stretched meshes of the tests) but ne = 2 np = 2 (2
cells star-shaped from their node, hence simple).

Any conforming quadrilateral mesh (``grid.mesh``: a ``.g`` file, a stretched cube, the cube
through the element-local map) is built the same way: the start is placed by the grid's own
map (``CubedSphere.reference_to_sphere``), and a mesh corner shared by k elements (3 to 7)
gets a cell of k vertices.

Topology: the dual of the sub-cell mesh (``ugrid.subcell_quads``). Dual vertex q sits in
sub-cell q (starting at reference point (t_{i+1}, t_{j+1}) of the sub-cell between GLL
nodes i, i+1 and j, j+1); the cell of node g joins the vertices of the sub-cells round g,
counter-clockwise seen from outside: 4 of them, as many as the elements round a mesh corner
(3 at the 8 cube corners).
"""

from __future__ import annotations

import functools
import time

import numpy as np
from threadpoolctl import threadpool_limits

from ..core import cache
from ..core.constants import EARTH
from ..core.runtime import init_warp
from ..grid.cubed_sphere import CubedSphere, lat_lon
from ..mesh.mesh import Mesh
from .dual_solve import amg_preconditioner, small_pages
from .ugrid import NOT_A_FIELD, subcell_quads, write_topology

MESH = "mesh_dual"
CONNECTIVITY = "dual_face_nodes"
NODE_DIM, CORNER_DIM = "ndual_node", "nv"
MIN_CORNERS = 4  # the columns of the corner tables at least: a cube's (4 vertices a cell, 3 at its corners)
# the fit's tolerance on |cell area / (spheremp / a²) − 1| (a fit stopped at its floor above it keeps what it
# reached: FLOOR_ERROR); the fit's floor grows with the cells: 1e-12 at ne30, 1.4e-10 at ne240, where the steps
# along the nearly singular checkerboard stop being linear and 1e-10 was never reached
RTOL = 1e-9
MAX_ITERATIONS = 60  # a cap, above the steps of every grid tried (ne ≤ 6 at np 2..8, ne 8 to 120 at np 4)
MU_MIN, MU_MAX = 1e-12, 1e6  # Levenberg–Marquardt damping, relative to mean diag JJᵀ
# its first value: far from the areas (the starts; the worst cells' own fit), and for the global fit
# once the worst cells are fitted (max error 5e-3: nearly Gauss–Newton)
MU_FAR, MU_NEAR = 1e-3, 1e-6
CG_ITERATIONS = 20000  # a cap only: an inexact step is checked like any other
# (JJᵀ + μI)y = ρ solved to the relative residual CG_RTOL (inexact Newton): a step cuts max|ρ| by about
# as much (ne60: 2.2e-3, 6.8e-7, 3.5e-11), so two steps of the global fit reach RTOL at ne60 where three
# at 1e-3 cost a third more;
# from the twisted start to round-off (inexact steps stall there at ne = 2 np = 2)
CG_RTOL, CG_RTOL_EXACT = 1e-4, 1e-12
# the fewest unknowns (cells) whose systems are preconditioned by smoothed aggregation (``dual_solve.amg_preconditioner``), the
# others by their diagonal: the V-cycles' set-up and Python overhead cost more than Jacobi's extra iterations up to
# ne60 (194 402 cells, one thread: 3.41 s against 3.06 s for the cells, ne30 1.25 against 0.99), and half as much at
# ne120 (777 602: 15.9 s against 32.3 s; 13.8 s with its levels as CSR and point Gauss-Seidel, BUILD 9;
# 9.6 s with their block columns sorted in C and 4 kB pages, BUILD 10: 10.4 at load 2 on 2 cores; 7.5 s with the
# cells' areas, gradients and turns as Warp kernels, BUILD 11)
AMG_CELLS = 400_000
LOCAL_ERROR, LOCAL_RINGS = 0.05, 6  # cells fitted first, and the rings round them (``_fit_worst_first``)
# the steps allowed to the worst cells' fit and to the global fit after it (the cube: 5 and 2 at ne60), beyond
# which they have stalled (HOMME's mountain_10_x2.g: the convexity rule holds the worst cells' fit at 6e-3)
# and the global fit starts again from the start itself with μ = MU_FAR
NEAR_STEPS = 20
# a fit whose every cell is within FLOOR_ERROR of its area and that rejects FLOOR_TRIALS trial steps in a row
# (μ up a thousandfold) has reached its round-off floor on this grid, above RTOL: it stops there and keeps what
# it reached, since another start reaches the same floor (ne240 np4 at RTOL 1e-10 stops at 1.38e-10 after 87 s of
# one thread, where the far fit from the start took it past 25 minutes). No fit of the tests, nor of the cube at
# np4 and ne 8 to 240 (RTOL 1e-9), rejects a step below 6.9e-3.
FLOOR_ERROR, FLOOR_TRIALS = 1e-6, 3
TWIST = 0.1  # the chiral start's rotation (``_start_vertices``)
BUILD = 11  # the fit's version in the cache key: raised by any change that moves the cells' bits


class FitStopped(ArithmeticError):
    """A cell-area fit that stopped short of its tolerance: no trial step lowered the error, or its
    steps ran out. ``verts`` the vertices it reached, ``error`` their largest relative area error."""

    def __init__(self, message: str, verts: np.ndarray, error: float):
        super().__init__(message)
        self.verts, self.error = verts, float(error)


def control_points(rule) -> np.ndarray:
    """Running sums of the GLL weights (np + 1,): t₀ = −1, t_k = −1 + Σ_{m<k} w_m, t_np = 1;
    reference interval [t_k, t_{k+1}] (length w_k) is node k's (HOMME ``cv_pts``)."""
    t = np.concatenate([[-1.0], -1.0 + np.cumsum(rule.weights)])
    t[-1] = 1.0
    return t


def _start_vertices(grid: CubedSphere, twist: float) -> np.ndarray:
    """Unit vectors (nsub, 3) of the product-grid points (t_{i+1}, t_{j+1}) of every
    sub-cell, in the order of ``ugrid.subcell_quads``, placed by the grid's map; ``twist`` > 0
    turns each point counter-clockwise about its element's centre, (a, b) → (a − twist·b(1 − a²),
    b + twist·a(1 − b²)) in reference coordinates (element edges stay in place), which
    breaks the cube's mirror symmetries."""
    n = grid.np
    t = control_points(grid.rule)[1:-1]  # one per sub-cell interval, np − 1 of them
    e, j, i = (
        x.ravel() for x in np.meshgrid(np.arange(grid.nelem_total), np.arange(n - 1), np.arange(n - 1), indexing="ij")
    )
    a, b = t[i], t[j]
    return grid.reference_to_sphere(e, a - twist * b * (1 - a * a), b + twist * a * (1 - b * b))


def max_corners(grid: CubedSphere) -> int:
    """Columns of the corner tables of ``grid``'s cells: its largest node valence (the DSS
    table's width: 4 on a cube, up to 7 on a mesh), at least ``MIN_CORNERS``."""
    return max(MIN_CORNERS, grid.dss_table.shape[1])


def cells(grid: CubedSphere) -> np.ndarray:
    """Dual vertices (sub-cell indices) of each unique node's cell, int32 (nunique,
    ``max_corners(grid)``), counter-clockwise seen from outside; cells of fewer vertices (the
    8 cube corners', a mesh corner's of valence below the largest) padded with −1.

    Round node g, the sub-cell after quad q (g its corner k) counter-clockwise is the
    quad holding the directed edge g → q[k−1] (each directed edge lies in one quad)."""
    quads = subcell_quads(grid).astype(np.int64)
    nsub, n = quads.shape[0], grid.nunique
    node = quads.ravel()
    key = node * n + np.roll(quads, -1, axis=1).ravel()  # directed edge node → next corner
    order = np.argsort(key)
    want = node * n + np.roll(quads, 1, axis=1).ravel()  # directed edge node → previous corner
    successor = order[np.searchsorted(key, want, sorter=order)]  # incidence (q, k) → next incidence round the node
    first = np.full(n, -1, dtype=np.int64)
    first[node[::-1]] = np.arange(4 * nsub)[::-1]  # one incidence of each node
    width = max_corners(grid)
    out = np.full((n, width), -1, dtype=np.int64)
    at = first.copy()
    for m in range(width):
        back = (m > 0) & (at == first)
        out[:, m] = np.where(back, -1, at // 4)
        at = np.where(back, first, successor[at])
    if not np.all(at == first) or not np.all(out[:, :3] >= 0):
        raise ValueError(f"the sub-cells round a node do not close in at most {width} steps")
    return out.astype(np.int32)


def _padded(corners: np.ndarray) -> np.ndarray:
    """``corners`` with each −1 replaced by the cell's last vertex (zero-length edges)."""
    out = corners.copy()
    for m in range(3, out.shape[1]):
        out[:, m] = np.where(out[:, m] < 0, out[:, m - 1], out[:, m])
    return out


def _fan(centre, verts, closed, gradients: bool):
    """``kernels.dual.fan_areas`` of the cells ``verts[closed]`` (closed: ``_padded``) fanned
    from ``centre`` (ncell, 3), on the CPU: (areas (ncell,), their gradients (ncell, nv, 3) by
    the vertices or None, whether each cell is star-shaped from its centre (ncell,) bool)."""
    n, nv = closed.shape
    area, grad, star = _launch(
        "fan_areas",
        [centre, verts, closed, int(gradients)],
        [(n, "f8"), ((n, nv) if gradients else (1, 1), "v3"), (n, "i4")],
    )
    return area, grad if gradients else None, star.astype(bool)


def _launch(name: str, inputs: list, outputs: list) -> list:
    """``kernels.dual``'s kernel ``name`` on the CPU, one thread a cell (the first output's length):
    ``inputs`` numpy arrays (points (k, 3) as float64 3-vectors, on their memory where that is
    contiguous and of the type; indices as int32) or ints; ``outputs`` (shape, "f8" | "v3" |
    "i4") made empty and returned as numpy views."""
    from ..kernels import dual as dual_kernels  # here, not at the top: reading a run file needs no Warp

    wp = init_warp()
    types = {"f8": wp.float64, "v3": wp.vec3d, "i4": wp.int32}

    def held(a):
        if not isinstance(a, np.ndarray):
            return a
        if np.issubdtype(a.dtype, np.floating):
            return wp.array(np.ascontiguousarray(a, dtype=np.float64), dtype=wp.vec3d, device="cpu", copy=False)
        return wp.array(np.ascontiguousarray(a, dtype=np.int32), dtype=wp.int32, device="cpu", copy=False)

    out = [wp.empty(shape, dtype=types[t], device="cpu") for shape, t in outputs]
    wp.launch(getattr(dual_kernels, name), outputs[0][0], [*map(held, inputs), *out], device="cpu")
    return [a.numpy() for a in out]


def spherical_areas(centre, verts, corners) -> np.ndarray:
    """Areas (ncell,) on the unit sphere of the cells ``verts[corners]`` (corners (ncell, nv),
    −1-padded, counter-clockwise; ``centre`` (ncell, 3) a point each cell is star-shaped from)."""
    return _fan(centre, verts, _padded(corners), False)[0]


def convex(verts, corners) -> np.ndarray:
    """Whether each cell ``verts[corners]`` (−1-padded) turns left at every vertex seen from
    outside, (ncell,) bool: ((b − a) × (c − b)) · b = a · (b × c) > 0 for consecutive
    vertices a, b, c (``kernels.dual.convex``)."""
    return _launch("convex", [verts, corners], [(corners.shape[0], "i4")])[0].astype(bool)


def star_shaped(centre, verts, corners) -> np.ndarray:
    """Whether each cell ``verts[corners]`` (−1-padded) is seen counter-clockwise from its
    point ``centre`` (ncell, 3): every fan triangle (centre, a, b) over consecutive vertices
    turns left from outside, (centre · (a × b) > 0), (ncell,) bool. Such a polygon is simple."""
    return _fan(centre, verts, _padded(corners), False)[2]


def _tangent_basis(p):
    """Two unit vectors (n, 3) each, orthogonal to each other and to the unit vectors ``p``."""
    ref = np.where((np.abs(p[:, 0]) < 0.9)[:, None], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    e1 = ref - np.einsum("ni,ni->n", ref, p)[:, None] * p
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    return e1, np.cross(p, e1)


def dual_mesh(grid: CubedSphere):
    """The control volumes of ``grid`` (the whole grid, any mesh) on the unit sphere:
    (vertices (nsub, 3) unit vectors, nsub = nelem·(np−1)²; corners (nunique,
    ``max_corners(grid)``) int32 counter-clockwise, −1-padded; relative area error
    max |area·a²/grid.area − 1|, at most ``RTOL``, or ``FLOOR_ERROR`` on a grid whose fit stops
    at its round-off floor above ``RTOL``).

    Levenberg–Marquardt on the 2·nsub tangent displacements of the vertices for the
    relative residual ρ = 1 − area/(spheremp/a²): minimum-norm steps δ = Jᵀ(JJᵀ + μI)⁻¹ρ
    (J the Jacobian of ρ, μ relative to JJᵀ's mean diagonal; μ shrinks tenfold after a step
    that lowers |ρ|, keeps every cell star-shaped from its node and keeps convex the cells
    that start convex, grows tenfold otherwise; without the convexity rule the cells of a
    refined mesh's distorted transition elements fold inward). Plain Gauss–Newton (μ = 0)
    stalls at ne = 2 np = 4 and ne = 4 np = 3: JJᵀ is nearly singular for the checkerboard of
    areas (on a uniform quad lattice Jᵀ of the ±1 checkerboard vanishes), the mode at which
    HOMME's local iteration fails too. JJᵀ is singular besides (moving a vertex keeps the
    total area: Jᵀ·(spheremp/a²) = 0), so ρ is projected off that direction, where it holds
    only round-off that 1/μ would amplify.

    The start's worst cells (the cube corners' triangles, half their area off) are fitted
    first with their neighbourhood (``_fit_worst_first``), so the global fit starts within
    5e-3 of every area, with μ = ``MU_NEAR``, and takes 2 steps at ne60 (3 at ne30) where it
    took 5 from the start itself. Where either stalls (``NEAR_STEPS``; on meshes the convexity
    rule can hold a cell), the global fit starts again from the start itself with μ = ``MU_FAR``.

    (JJᵀ + μI)y = ρ couples each node to its 8 neighbours, like a graph Laplacian: solved by
    conjugate gradients, inexactly (``CG_RTOL``), preconditioned by its diagonal or, from
    ``AMG_CELLS`` nodes on, by a V-cycle of pyamg's smoothed aggregation
    (``dual_solve.amg_preconditioner``): memory linear in the nodes, where one sparse LU a step grew as
    nodes^1.5 in fill and flops; the V-cycle's iterations stay at tens (ne120: 16 and 24),
    where Jacobi's grow with ne (ne120: 725 and 920).
    Where the fit stalls at a mirror-symmetric point (ne = 1 np = 3 and ne = 2 np = 2, whose
    24 dual vertices have one degree of freedom each under the cube's mirrors, too few for
    the 3 distinct targets), it starts again from ``_start_vertices`` twisted by ``TWIST``,
    its steps solved to round-off and its cells only star-shaped (2 of ne = 2 np = 2's are not
    convex). A fit that stops with every cell within ``FLOOR_ERROR`` of its area (``FLOOR_TRIALS``
    trial steps in a row rejected) has reached the floor of its steps on this grid: it ends there,
    not restarted (another start reaches the same floor, at ne240 and RTOL 1e-10 after 25 minutes).
    Raises ``ArithmeticError`` (``FitStopped``) if the areas are reached from no start."""
    corners = cells(grid)
    closed = _padded(corners)
    centre = np.stack([grid.to_unique(x) for x in grid.xyz], axis=1)
    target = grid.area / grid.radius**2
    start = _start_vertices(grid, 0.0)
    quads = subcell_quads(grid)
    colour = checkerboard(quads) if corners.shape[0] >= AMG_CELLS else None  # for the V-cycle only
    fit = functools.partial(_fit_to_floor, centre, corners=corners, closed=closed, target=target, colour=colour)
    try:
        near = _fit_worst_first(centre, start, corners, closed, target, quads, colour)
        verts, error = fit(near, cg_rtol=CG_RTOL, mu=MU_NEAR, keep_convex=True, steps=NEAR_STEPS)
    except ArithmeticError:  # the worst cells' fit, or the global fit after it, stalled above its floor
        try:
            verts, error = fit(start, cg_rtol=CG_RTOL, mu=MU_FAR, keep_convex=True)
        except ArithmeticError:
            twisted = _start_vertices(grid, TWIST)
            verts, error = fit(twisted, cg_rtol=CG_RTOL_EXACT, mu=MU_FAR, keep_convex=False)
    return verts, corners, error


def _fit_to_floor(*args, **kwargs) -> tuple[np.ndarray, float]:
    """``_fit``, or where it stops within ``FLOOR_ERROR`` (its round-off floor), what it reached."""
    try:
        return _fit(*args, **kwargs)
    except FitStopped as stop:
        if not stop.error <= FLOOR_ERROR:
            raise
        return stop.verts, stop.error


def checkerboard(quads) -> np.ndarray:
    """±1 (nunique,) alternating along every edge of the sub-cell mesh ``quads`` (nsub, 4) (the
    parity of each node's edge distance from node 0): a quadrilateral mesh of the sphere is
    bipartite, its cycles sums of its faces' 4-cycles. The checkerboard of ``dual_mesh``'s
    nearly singular mode. Raises ``ValueError`` if the mesh is not connected."""
    import scipy.sparse as sp  # here, not at the top: a cached run never builds cells
    from scipy.sparse.csgraph import shortest_path

    n = int(quads.max()) + 1
    edges = np.stack([quads.ravel(), np.roll(quads, -1, axis=1).ravel()])
    graph = sp.csr_matrix((np.ones(edges.shape[1]), edges), shape=(n, n))
    steps = shortest_path(graph, directed=False, unweighted=True, indices=0)
    if not np.isfinite(steps).all():
        raise ValueError("the sub-cell mesh is not connected")
    return 1.0 - 2.0 * (steps % 2)


def _fit_worst_first(centre, verts, corners, closed, target, quads, colour):
    """The start ``verts`` with the cells more than ``LOCAL_ERROR`` off their areas fitted
    first, with those within ``LOCAL_RINGS`` rings of them: ``_fit`` of that region's cells
    that have a free vertex (one whose 4 cells are all in the region; the others are held),
    each target scaled by the area over the targets' sum of its connected part of the region
    (cells joined by free vertices: moving a free vertex keeps that sum). The region's cells then share its deficit, 2e-4 of their areas about the
    cube's corners; else the global fit spends two steps (of five at ne60) spreading half of a
    cube corner's cell area. ``quads`` (nsub, 4): the 4 cells (nodes) of each dual vertex
    (``ugrid.subcell_quads``); ``colour`` (ncell,): their checkerboard (``checkerboard``), None
    below ``AMG_CELLS`` cells.
    Raises ``ArithmeticError`` where that fit stalls."""
    import scipy.sparse as sp  # here, not at the top: a cached run never builds cells (0.15 s of imports)
    from scipy.sparse.csgraph import connected_components

    area = _fan(centre, verts, closed, False)[0]
    inside = np.abs(1 - area / target) > LOCAL_ERROR
    if not inside.any():
        return verts
    for _ in range(LOCAL_RINGS):
        inside[quads[np.unique(closed[inside])].ravel()] = True
    free = inside[quads].all(axis=1)
    cells_ = np.flatnonzero(free[closed].any(axis=1))
    held = np.unique(closed[cells_])
    local = np.full(verts.shape[0], -1)
    local[held] = np.arange(held.size)
    part = np.where(corners[cells_] >= 0, local[corners[cells_]], -1)
    joined = quads[free][:, [0, 1, 2]], quads[free][:, [1, 2, 3]]  # the 4 cells of a free vertex, chained
    links = sp.coo_matrix((np.ones(joined[0].size), (joined[0].ravel(), joined[1].ravel())), shape=(area.size,) * 2)
    part_of = np.unique(connected_components(links, directed=False)[1][cells_], return_inverse=True)[1]
    ratio = np.bincount(part_of, area[cells_]) / np.bincount(part_of, target[cells_])
    t = target[cells_] * ratio[part_of]
    moved, _ = _fit_to_floor(
        centre[cells_],
        verts[held],
        part,
        local[closed[cells_]],
        t,
        None if colour is None else colour[cells_],
        CG_RTOL,
        MU_FAR,
        True,
        free[held],
        steps=NEAR_STEPS,
    )
    out = verts.copy()
    out[held] = moved
    return out


def _fit(
    centre, verts, corners, closed, target, colour, cg_rtol, mu, keep_convex, free=None, tol=None, steps=MAX_ITERATIONS
):
    """``dual_mesh``'s Levenberg–Marquardt iteration from ``verts`` to the areas ``target``
    (ncell,) within ``tol`` (relative), each step's linear system solved to the relative
    residual ``cg_rtol`` (``mu``: the first damping), each step kept only where the cells stay
    star-shaped from their nodes (and, with ``keep_convex``, those convex at the start stay
    convex); only the vertices ``free`` (nsub,) bool move (default all). ``colour`` (ncell,):
    the cells' checkerboard (``checkerboard``), for the V-cycle (None below ``AMG_CELLS`` cells).
    (vertices, max relative error); ``FitStopped`` if no step lowers the error (μ past ``MU_MAX``, or
    ``FLOOR_TRIALS`` trials in a row within ``FLOOR_ERROR``) or ``steps`` do not reach ``tol`` (None:
    ``RTOL``).

    A V-cycle serves the fit's later systems while μ stays at most ``MU_NEAR`` (built
    again where μ changes above it): the vertices move by a fraction of a cell, and that small
    a shift is below the spectrum that sets the iterations (the V-cycle forced at ne60: the
    near fit's second solve took 15 with the first's V-cycle or its own), where a larger one
    is not (the far fit from μ = 1e-3: 7, 20, 34, 46, 31 kept against 7, 7, 9, 13, 15 built
    each step); an older preconditioner costs iterations, never accuracy (CG's residual is the
    system's own), and its set-up costs as much as a solve."""
    import scipy.sparse as sp  # here, not at the top: a cached run never builds cells
    import scipy.sparse.linalg as spla

    n, nsub = target.size, verts.shape[0]
    rows = np.repeat(np.arange(n), 2 * closed.shape[1])
    cols = np.stack([2 * closed, 2 * closed + 1], axis=-1).ravel()
    eye = sp.identity(n, format="csr")
    area, grad, _ = _fan(centre, verts, closed, True)
    was_convex = convex(verts, corners)
    preconditioner, built_for = None, None
    tol = RTOL if tol is None else tol
    for _ in range(steps):
        rho = 1 - area / target
        error, norm = np.max(np.abs(rho)), np.linalg.norm(rho)
        if error <= tol:
            return verts, float(error)
        rho -= (rho @ target) / (target @ target) * target  # round-off: Jᵀ·target = 0
        e1, e2 = _tangent_basis(verts)
        g1 = np.einsum("cki,cki->ck", grad, e1[closed]) / target[:, None]
        g2 = np.einsum("cki,cki->ck", grad, e2[closed]) / target[:, None]
        if free is not None:
            g1, g2 = g1 * free[closed], g2 * free[closed]
        J = sp.csr_matrix((np.stack([g1, g2], axis=-1).ravel(), (rows, cols)), shape=(n, 2 * nsub))
        JJ = (J @ J.T).tocsr()
        scale = JJ.diagonal().mean()
        rejected = 0  # trial steps in a row
        while True:
            A = JJ + mu * scale * eye
            if n < AMG_CELLS:
                preconditioner = sp.diags(1 / A.diagonal())
            elif max(mu, MU_NEAR) != built_for:
                preconditioner, built_for = amg_preconditioner(A, colour), max(mu, MU_NEAR)
            y, _ = spla.cg(A, rho, rtol=cg_rtol, maxiter=CG_ITERATIONS, M=preconditioner)
            d = (J.T @ y).reshape(nsub, 2)
            trial = verts + d[:, :1] * e1 + d[:, 1:] * e2
            trial /= np.linalg.norm(trial, axis=1)[:, None]
            t_area, t_grad, star = _fan(centre, trial, closed, True)
            if (
                np.linalg.norm(1 - t_area / target) < norm
                and star.all()
                and (not keep_convex or convex(trial, corners)[was_convex].all())
            ):
                mu = max(mu / 10, MU_MIN)
                break
            mu, rejected = mu * 10, rejected + 1
            if mu > MU_MAX or (error <= FLOOR_ERROR and rejected >= FLOOR_TRIALS):
                raise FitStopped(f"dual mesh: no step lowers the cell-area error {error:.1e}", verts, error)
        verts, area, grad = trial, t_area, t_grad
    error = float(np.max(np.abs(1 - area / target)))
    raise FitStopped(f"dual mesh: cell areas off spheremp by {error:.1e} after {steps} steps", verts, error)


def cache_key(ne: int, np_: int, mesh: Mesh | None = None, radius: float = EARTH.a) -> dict:
    """What the unit-sphere cells are a function of (``core.cache`` key): the mesh (the
    uniform equiangular cube, or ``mesh``'s content hash ``Mesh.sha256``), the map, ne, np,
    the radius (m) of the grid they are fitted on (its spheremp / a², the targets, differ from
    another radius's in the last bits: ``unit_dual_mesh``) and ``BUILD``."""
    if mesh is None:
        return {"mesh": "cubed_sphere", "map": "equiangular", "ne": ne, "np": np_, "radius": radius, "build": BUILD}
    return {"mesh": mesh.sha256(), "map": mesh.map, "ne": ne, "np": np_, "radius": radius, "build": BUILD}


def cached_cells(ne: int, np_: int, mesh: Mesh | None = None, radius: float = EARTH.a, grid: CubedSphere | None = None):
    """``dual_mesh`` of the ne, np grid of radius ``radius`` (m; on ``mesh`` if given, as
    ``CubedSphere``), read from the cache (``core.cache``, entry ``dual_mesh``) or built and
    stored there: (vertices (nsub, 3) unit vectors, corners, error, CPU seconds of the build or
    None when read). ``grid``: that grid, whole, where the caller has it (a run's own); else it
    is built here (3 s of CPU at ne120). The cells are on the unit sphere whatever the radius,
    fitted to spheremp / a², which differ from a unit grid's by round-off (18 ε at ne30), so the
    radius is in the key. Built on one BLAS thread: the same bits on any host."""
    seconds = []

    def build():
        start = time.process_time()
        # one BLAS thread: the fit's CG takes 10⁵ inner products of 10⁵–10⁶ entries, which OpenBLAS
        # split over every core, its threads spinning between them (ne120 on a 16-core host: 423 s
        # of CPU for 71 s of wall; ne30 on 2 cores: 4.4× the CPU and 4.9× the wall of one thread),
        # and whose sums' order, hence the cells' bits, went with the host's core count
        with threadpool_limits(limits=1, user_api="blas"), small_pages():
            whole = grid if _is_whole(grid, ne, np_, mesh, radius) else CubedSphere(ne, np_, radius, mesh=mesh)
            verts, corners, error = dual_mesh(whole)
        seconds.append(time.process_time() - start)
        return {"vertices": verts, "corners": corners, "error": np.float64(error)}

    arrays, _ = cache.cached("dual_mesh", cache_key(ne, np_, mesh, radius), build)
    return arrays["vertices"], arrays["corners"], float(arrays["error"]), seconds[0] if seconds else None


def _is_whole(grid, ne: int, np_: int, mesh: Mesh | None, radius: float) -> bool:
    """Whether ``grid`` is the whole ``CubedSphere`` of these arguments (not an MPI rank's part,
    nor rank 0's ``GatheredGrid``, which holds no metric)."""
    whole = isinstance(grid, CubedSphere) and grid.nelem == grid.nelem_total
    return whole and (grid.ne, grid.np, grid.radius) == (ne, np_, radius) and grid.mesh is mesh


_MEMO, MEMO_SIZE = {}, 4  # this process's cells by their cache key, the last MEMO_SIZE grids'


def unit_dual_mesh(ne: int, np_: int, mesh: Mesh | None = None, radius: float = EARTH.a, grid=None):
    """``cached_cells``, once a process for each grid (every stream and run of a grid writes the
    same cells; ``clear_memo`` forgets them): the same tuple, its seconds those of the build.
    ``ArithmeticError`` where the fit fails (``dual_mesh``), raised again for that grid."""
    key = tuple(cache_key(ne, np_, mesh, radius).items())
    if key not in _MEMO:
        if len(_MEMO) >= MEMO_SIZE:
            del _MEMO[next(iter(_MEMO))]  # the oldest
        try:
            _MEMO[key] = cached_cells(ne, np_, mesh, radius, grid)
        except ArithmeticError as err:  # a fit that failed fails again: raised again, not fitted again a stream
            _MEMO[key] = err
    if isinstance(_MEMO[key], ArithmeticError):
        raise _MEMO[key]
    return _MEMO[key]


def clear_memo() -> None:
    """Forget this process's cells (``unit_dual_mesh``): the next call reads the cache again."""
    _MEMO.clear()


def write_dual_mesh(ds, grid: CubedSphere) -> float | None:
    """Add the control volumes of ``grid`` to an open ``netCDF4.Dataset`` ``ds`` whose
    ``lon``/``lat`` (degrees) are on the unique nodes ``ncol``: as the UGRID mesh
    ``mesh_dual`` whose faces are the nodes (``ncol``; fields on it are
    ``location = "face"``; its ``max_relative_area_error`` the cells' largest |area / spheremp − 1|), and as CF cell bounds ``lon_bnds``/``lat_bnds`` (ncol, nv) of
    ``lon``/``lat``, the cells of fewer vertices repeating their last vertex (as HOMME's SCRIP
    files do). Adds nv (4 on a cube, the largest node valence of a mesh) and ndual_node =
    nelem·(np−1)² (the dual vertices): 2.4 MB at ne30 np4, compressed. Returns the CPU seconds
    spent building the cells, None where they came from the cache (``unit_dual_mesh``)."""
    verts, corners, error, seconds = unit_dual_mesh(grid.ne, grid.np, grid.mesh, grid.radius, grid)
    ds.createDimension(NODE_DIM, verts.shape[0])
    ds.createDimension(CORNER_DIM, corners.shape[1])
    write_topology(
        ds,
        MESH,
        CONNECTIVITY,
        corners,
        ("ncol", CORNER_DIM),
        long_name="control volumes of the GLL nodes: one face a node, its area the node's spheremp",
        corners="corners (ndual_node indices) of each node's control volume, counter-clockwise from outside",
        node_coordinates="dual_lon dual_lat",
        face_coordinates="lon lat",
        # the fit's: at most RTOL, or the floor it stopped at (FLOOR_ERROR) on a grid where that is above
        max_relative_area_error=np.float64(error),
    )
    vlat, vlon = np.degrees(lat_lon(verts))
    for name, values, what in (
        ("dual_lon", vlon, "longitude (degrees east)"),
        ("dual_lat", vlat, "latitude (degrees north)"),
    ):
        var = ds.createVariable(name, "f8", (NODE_DIM,), zlib=True, shuffle=True)
        # no standard_name and plain degrees (not degrees_north/east): lat/lon stay the file's one
        # latitude and longitude for cf_xarray (``ds.cf["latitude"]``), with decode_coords="all" too
        var.setncatts(dict(units="degrees", long_name=f"{what} of the control volumes' corners", **NOT_A_FIELD))
        var[:] = values
    blat, blon = np.degrees(lat_lon(verts[_padded(corners)]))
    lon = ds["lon"][:][:, None]
    blon = lon + np.mod(blon - lon + 180.0, 360.0) - 180.0  # within 180° of the node's: no jump at 0°/360°
    for name, values in (("lon", blon), ("lat", blat)):
        ds[name].bounds = f"{name}_bnds"
        # CF: bounds carry no attributes; zlib: 1.6 times smaller (lossless)
        ds.createVariable(f"{name}_bnds", "f8", ("ncol", CORNER_DIM), zlib=True, shuffle=True)[:] = values
    return seconds
