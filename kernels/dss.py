"""Direct stiffness summation (HOMME ``bndry_exchangev`` + ``rspheremp`` scaling), gather form.

Every element-local copy of a unique node gathers the sum over all copies, so
the kernel needs no atomics and gives the same bits on CPU and CUDA. Copies
held by other processes arrive in a ghost buffer (``pack`` on the sender,
``swe_sphere.grid.topology`` exchanges), and the sum runs over all copies in one
global order, so the bits do not depend on which process holds which copy.
"""

import functools
from typing import Any

import warp as wp

from . import operators
from .operators import suffix

f64 = wp.float64
vec6 = wp.types.vector(length=6, dtype=f64)  # the coefficients of two combinations (``dss_update``)
wp.set_module_options({"enable_backward": False})


@wp.struct
class Copies:
    """Where the DSS finds a node's copies (``Topology.dss_copies``): ``table``
    (N, copies) their indices in the summation order, −1-padded, c < nlocal
    local, c ≥ nlocal another process's in ``ghost`` (``pack``'s layout);
    spheremp (nlocal + ghosts,) the element mass of each copy and rspheremp
    (N,) the inverse assembled mass (m², m⁻²)."""

    table: wp.array2d(dtype=wp.int32)
    nlocal: int
    ghost: wp.array(dtype=f64)
    spheremp: wp.array(dtype=f64)
    rspheremp: wp.array(dtype=f64)


@functools.cache
def copy_value(rows: int, weighted: bool, ghosts: bool, dtype=f64):
    """A ``wp.func`` (x, d: ``Copies``, c, r) → (spheremp[c] if ``weighted`` else 1)·x[r, c], one
    copy's term of the DSS, in float64 whatever x's ``dtype`` (a float32 tendency's copies are
    summed in float64: ``ShallowWater``'s precision); with ``ghosts`` a copy c ≥ ``nlocal`` is
    another process's, read from ghost[(c − nlocal)·rows + r] (``pack``'s layout)."""
    R, W, G = int(rows), bool(weighted), bool(ghosts)

    def value(x: wp.array2d(dtype=dtype), d: Copies, c: int, r: int):
        v = f64(0.0)
        if wp.static(G):
            if c >= d.nlocal:
                v = d.ghost[(c - d.nlocal) * R + r]
            else:
                v = f64(x[r, c])
        else:
            v = f64(x[r, c])
        if wp.static(W):
            v = d.spheremp[c] * v
        return v

    value.__qualname__ = value.__name__ = f"copy_value_{R}_{'w' if W else 'u'}{'_ghosts' if G else ''}" + suffix(dtype)
    return wp.func(value)


@functools.cache
def copies_sum(rows: int, weighted: bool, copies: int, ghosts: bool = False, dtype=f64):
    """A ``wp.func`` (x, d: ``Copies``, p) → the vector of ``rows`` values Σ_copies c of p's node
    (spheremp[c] if ``weighted`` else 1) · x[r, c] (``copy_value``), summed in the table's order
    (``copies`` its columns), so every copy of the node gets the same bits: ``gather``'s sum and
    ``gather_rows``' at the corners. A vector of one value for no rows (a launch of none)."""
    R, W, C, G = int(rows), bool(weighted), int(copies), bool(ghosts)
    fields = wp.types.vector(length=max(R, 1), dtype=f64)
    value = copy_value(R, W, G, dtype)

    def sum_copies(x: wp.array2d(dtype=dtype), d: Copies, p: int):
        s = fields()
        for k in range(C):
            c = d.table[p, k]
            if c >= 0:
                for r in range(R):
                    s[r] += value(x, d, c, r)
        return s

    sum_copies.__qualname__ = sum_copies.__name__ = (
        f"copies_sum_{R}_{'w' if W else 'u'}_{C}{'_ghosts' if G else ''}" + suffix(dtype)
    )
    return wp.func(sum_copies)


@functools.cache
def gather(rows: int, weighted: bool, copies: int, ghosts: bool = False, dtype=f64):
    """A ``wp.func`` (x, d: ``Copies``, p) → the vector of ``rows`` values
    rspheremp[p] · Σ_copies c of p's node (spheremp[c] if ``weighted`` else 1)
    · x[r, c]: the DSS at node p, summed in the table's order, so every copy
    gets the same bits. The copies come from one table row per node (no CSR
    indirection) and the row sums stay in registers: 2.6× faster on the CPU
    than a CSR gather. ``copies``: the table's columns.

    With ``ghosts``, a copy c ≥ ``nlocal`` is another process's, read from
    ghost[(c − nlocal)·rows + r]. Without, ghost and nlocal are not read. x of ``dtype``, the
    sums float64 (``copy_value``)."""
    R, W, C, G = int(rows), bool(weighted), int(copies), bool(ghosts)
    summed = copies_sum(R, W, C, G, dtype)

    def gather_copies(x: wp.array2d(dtype=dtype), d: Copies, p: int):
        s = summed(x, d, p)
        rs = d.rspheremp[p]
        for r in range(R):
            s[r] = rs * s[r]
        return s

    gather_copies.__qualname__ = gather_copies.__name__ = (
        f"gather_{R}_{'w' if W else 'u'}_{C}{'_ghosts' if G else ''}" + suffix(dtype)
    )
    return wp.func(gather_copies)


@functools.cache
def dss_rows(rows: int, weighted: bool, copies: int, ghosts: bool = False, dtype=f64):
    """The DSS kernel for ``rows`` rows and ``copies`` columns of the
    ``dss_table`` (its own Warp module, kernel key ``dss``):
    out[r, p] = rspheremp[p] · Σ_copies c of p's node (spheremp[c] if weighted
    else 1) · x[r, c] (``gather``). ``weighted`` for a strong-form field
    (mass-weighted average: continuous result, area integral kept); unweighted
    for a weak form already integrated against the test functions. Arguments:
    x, d (``Copies``), out, block, offset; ``out`` must not alias ``x``.
    Dim N/block: ``block`` consecutive nodes a thread (``Topology.gathering``),
    ``offset`` in blocks.
    ``ghosts``: copies held by other processes, and x's ``dtype``, as in ``gather``."""
    sum_copies = gather(rows, weighted, copies, ghosts, dtype)

    def dss(x: wp.array2d(dtype=dtype), d: Copies, out: wp.array2d(dtype=f64), block: int, offset: int):
        start = (wp.tid() + offset) * block
        for p in range(start, start + block):
            s = sum_copies(x, d, p)
            for r in range(wp.static(rows)):
                out[r, p] = s[r]

    dss.__qualname__ = "dss" + suffix(dtype)  # the kernel's key, as the generic kernel's
    return wp.kernel(dss, enable_backward=False, module="unique")


@functools.cache
def dss_rows_at(rows: int, weighted: bool, copies: int, ghosts: bool = False, dtype=f64):
    """``dss_rows`` at the listed nodes only: out[r, p] = the DSS of x at p (``gather``)
    for p = nodes[i], i the thread index + offset; out's other nodes are not written (a
    local time step's level: the copies of the nodes its elements touch,
    ``Topology.dss_at``). Arguments: x, d (``Copies``), nodes (int32), out, offset.
    ``ghosts``: copies held by other processes, and x's ``dtype``, as in ``gather``. ``out`` must
    not alias ``x``."""
    sum_copies = gather(rows, weighted, copies, ghosts, dtype)

    def dss_at(
        x: wp.array2d(dtype=dtype), d: Copies, nodes: wp.array(dtype=wp.int32), out: wp.array2d(dtype=f64), offset: int
    ):
        p = nodes[wp.tid() + offset]
        s = sum_copies(x, d, p)
        for r in range(wp.static(rows)):
            out[r, p] = s[r]

    dss_at.__qualname__ = "dss_at" + suffix(dtype)
    return wp.kernel(dss_at, enable_backward=False, module="unique")


def state_suffix(state) -> str:
    """What a DSS update's key adds for its terms' and outputs' float type: nothing for float64."""
    return "" if state is f64 else "__state" + suffix(state)


def assembled_suffix(assembled: int) -> str:
    """What a DSS update's key adds for its last ``assembled`` rows written as the DSS itself."""
    return f"__assembled{assembled}" if assembled else ""


def _assembled(assembled: int, rows: int, patterns: tuple) -> int:
    """``dss_update``'s ``assembled`` checked: ValueError unless one or two ``patterns``, and for
    A > 0 one, A ≤ ``rows``."""
    A = int(assembled)
    if not 1 <= len(patterns) <= 2:
        raise ValueError(f"one or two combinations (got {len(patterns)})")
    if A and (len(patterns) != 1 or not 0 < A <= rows):
        raise ValueError(f"rows assembled as they are need one update and at most its {rows} rows (got {A})")
    return A


@functools.cache
def combination(pattern: str, state=f64):
    """A ``wp.func`` (c, k, s0, s1, r, p) → Σ_i c[i]·term_i with the terms named by
    ``pattern``: "a" the next of the arrays s0, s1 at [r, p], "k" the value k: node values
    (float64), or GLL rows (``dss_update_elements``: k a row, the arrays row views, lane by lane
    the same bits). One to three terms, at most two "a" and one "k" (e.g. "ak", "aak", "aka",
    "a", "k").

    ``state`` float64: summed left to right as ``blas.axpby``/``axpbypcz`` do (the same bits).
    ``state`` float32 (the float32 state's stages): summed in float32, k and each weight rounded
    to float32 once, two arrays as (c₀ + c₁)·s1 + (c₀·(s0 − s1) + c_k·k), the weights' sum
    taken in float64 before it is rounded: where the stage form's weights keep a constant
    (``stage_plan.constant_keeping``: RK4's 1/3, 2/3 sum to 1 exactly) the float32 sum does too,
    s0 = s1 = C giving 1·C + 0 whatever fl₃₂(c₀) is. Rounded alone, fl₃₂(1/3) + fl₃₂(2/3) =
    1 + 3e-8: RK4 biased each step's state by a quarter of a float32 spacing (TC2 ne4 np4 a day,
    mass 3.2e-7 off without the fixer).

    The pattern "rkl" (terms a, a, k): an RKL1 stage, ``rkl_stage``, in float64 for either state."""
    if pattern == "rkl":
        return rkl_stage()
    if not 1 <= len(pattern) <= 3 or set(pattern) - {"a", "k"} or pattern.count("k") > 1 or pattern.count("a") > 2:
        raise ValueError(f"a combination is 1 to 3 terms of at most two arrays 'a' and one 'k' (got {pattern!r})")
    if state is not f64:
        return _combination_state(pattern, state)
    P = pattern + "a" * (3 - len(pattern))  # padded: the padding's terms are not compiled
    N = len(pattern)
    K1, K2 = P[1] == "k", P[2] == "k"
    A0, A1 = P[0] == "a", P[:2].count("a")  # term 0 an array; term 1 is s1 (A1 = 2) or s0

    def combine(c: wp.vec3d, k: Any, s0: wp.array2d(dtype=Any), s1: wp.array2d(dtype=Any), r: int, p: int):
        t = k
        if wp.static(A0):
            t = type(k)(s0[r, p])
        v = c[0] * t
        if wp.static(N > 1):
            t = k
            if wp.static(not K1):
                if wp.static(A1 == 2):
                    t = type(k)(s1[r, p])
                else:
                    t = type(k)(s0[r, p])
            v = v + c[1] * t
        if wp.static(N > 2):
            t = k
            if wp.static(not K2):
                t = type(k)(s1[r, p])
            v = v + c[2] * t
        return v

    combine.__qualname__ = combine.__name__ = f"combine_{pattern}"
    return wp.func(combine)


@wp.func
def rkl_weighted(t: Any, prev: Any, nu: Any):
    """RKL1's stage μ·t + ν·prev with μ = 1 − ν, as t + ν·(prev − t): no product of the state by
    μ and by ν that rounds alike at nearly every node (fl(5/3) + fl(−2/3) ≠ 1), so no bias in the
    mass (``model.hyperviscosity.Hyperviscosity.rkl1``). Scalars or rows, of one float type."""
    return t + nu * (prev - t)


@functools.cache
def rkl_stage():
    """A ``wp.func`` (c, k, s0, s1, r, p) → t + c₁·(s1 − t), t = c₀·s0 + c₂·k at [r, p] (k and
    the arrays as ``combination``'s), in float64 (k's type; a float32 state's values read into
    it): RKL1's stage μ·t + ν·Y_{j−2} with μ = 1 − ν (``model.hyperviscosity.Hyperviscosity.rkl1``)
    written as t + ν·(Y_{j−2} − t), c = (1, ν, coef), s0 = Y_{j−1}, s1 = Y_{j−2}: the ∇⁴'s
    ``dss_apply`` "rkl" arithmetic, a constant kept to the bit, no bias in the mass."""

    def rkl(c: wp.vec3d, k: Any, s0: wp.array2d(dtype=Any), s1: wp.array2d(dtype=Any), r: int, p: int):
        return rkl_weighted(c[0] * type(k)(s0[r, p]) + c[2] * k, type(k)(s1[r, p]), c[1])

    rkl.__qualname__ = rkl.__name__ = "combine_rkl"
    return wp.func(rkl)


def _combination_state(pattern: str, state):
    """``combination``'s float32 form (its docstring): the weights at the arrays' and k's places
    of ``pattern``, the arrays s0 (and s1), a combination of F alone k's multiple."""
    at = [i for i, t in enumerate(pattern) if t == "a"]
    IA, IB = (at + [0, 0])[:2]  # the first and second array's weight
    IK = pattern.find("k")
    ARRAYS, K = len(at), IK >= 0
    IK = max(IK, 0)

    def combine_state(c: wp.vec3d, k: Any, s0: wp.array2d(dtype=Any), s1: wp.array2d(dtype=Any), r: int, p: int):
        a = s0[r, p]
        kk = type(a)(k)
        if wp.static(ARRAYS == 0):
            return state(c[wp.static(IK)]) * kk
        if wp.static(ARRAYS == 1):
            v = state(c[wp.static(IA)]) * a
            if wp.static(K):
                v = v + state(c[wp.static(IK)]) * kk
            return v
        b = s1[r, p]
        d = state(c[wp.static(IA)]) * (a - b)
        if wp.static(K):
            d = d + state(c[wp.static(IK)]) * kk
        return state(c[wp.static(IA)] + c[wp.static(IB)]) * b + d

    combine_state.__qualname__ = combine_state.__name__ = f"combine_{pattern}" + suffix(state)
    return wp.func(combine_state)


@functools.cache
def dss_update(
    rows: int,
    copies: int,
    patterns: tuple,
    ghosts: bool = False,
    weighted: bool = True,
    dtype=f64,
    state=f64,
    assembled: int = 0,
):
    """The weighted DSS k of ``rows`` rows (``gather``; ``weighted`` False: the unweighted
    DSS of a weak form, as ``dss_rows``') not stored but used by
    one or two linear combinations, node by node (a Runge–Kutta stage's
    x + aΔt F written straight from the DSS of F's tendency):
    out0[r, p] = ``combination(patterns[0])``(c[0:3], k[r], s00, s01) and then
    out1[r, p] = ``combination(patterns[1])``(c[3:6], k[r], s10, s11), so out1's
    terms see out0's new values where they alias it. Arguments: x, d (as
    ``dss_rows``), c (6 coefficients),
    s00, s01, out0, s10, s11, out1 (rows, N) (the unused ones any such array),
    block, offset. Outputs and terms may alias each other, not x. Dim N/block
    (as ``dss_rows``). x of ``dtype`` (``gather``); the terms and outputs of ``state``
    (float32: the float32 state's stages, each combination summed in float32, ``combination``'s
    float32 form; ``precision = "float32_state"``), the rest float64. ``assembled`` A > 0: the
    last A rows of out0 take s00 + k, not the combination (a limited stage's tracer rows, their
    terms of the weighted DSS of the values less s00 in x: ``kernels.limiter.limit_stage``'s
    ``weigh`` and ``relative``; one update; k alone where the pattern has no array, "k")."""
    A = _assembled(assembled, rows, patterns)
    BASE = patterns[0] != "k"  # the assembled rows' s00, the state their terms are taken from
    sum_copies = gather(rows, bool(weighted), copies, ghosts, dtype)
    first = combination(patterns[0], state)
    second = combination(patterns[-1], state)
    TWO = len(patterns) == 2

    def dss_update(
        x: wp.array2d(dtype=dtype),
        d: Copies,
        c: vec6,
        s00: wp.array2d(dtype=state),
        s01: wp.array2d(dtype=state),
        out0: wp.array2d(dtype=state),
        s10: wp.array2d(dtype=state),
        s11: wp.array2d(dtype=state),
        out1: wp.array2d(dtype=state),
        block: int,
        offset: int,
    ):
        start = (wp.tid() + offset) * block
        for p in range(start, start + block):
            k = sum_copies(x, d, p)
            for r in range(wp.static(rows - A)):
                out0[r, p] = state(first(wp.vec3d(c[0], c[1], c[2]), k[r], s00, s01, r, p))
                if wp.static(TWO):
                    out1[r, p] = state(second(wp.vec3d(c[3], c[4], c[5]), k[r], s10, s11, r, p))
            if wp.static(A > 0):
                for r in range(wp.static(rows - A), wp.static(rows)):
                    if wp.static(BASE):
                        out0[r, p] = state(f64(s00[r, p]) + k[r])
                    else:
                        out0[r, p] = state(k[r])

    name = "dss_update__" + "__".join(patterns) + ("" if weighted else "__unweighted") + suffix(dtype)
    name += state_suffix(state) + assembled_suffix(A)
    dss_update.__qualname__ = dss_update.__name__ = name
    return wp.kernel(dss_update, enable_backward=False, module="unique")


# -- by element, on GLL rows (the CPU) ----------------------------------------------------
# The node gathers above read every copy of every node through the table, an interior node's
# one copy too. On the CPU a thread takes an element and its rows (``operators.row_vectors``):
# its own copies are read as packed rows, the one other copy of each node inside an edge from
# ``Edges`` (a whole row where the neighbour's edge row runs lane for lane beside it), and the
# corners through the table. Summed as (0 + own) + other, an edge node's sum is the table
# order's, bit for bit (addition commutes), and a corner's is the table's: the same bits as
# ``gather``. Alone, the DSS update takes 0.55–0.74× the node gather's time (np 8 to 4, one
# thread); a step's saving is benchmarks/archive/replaced_paths.py dss_by_element's. Warp's CPU code indexes every
# array through its run-time strides (an integer multiply an access): rows cut the accesses.


@wp.struct
class Edges:
    """Where the element-row DSS (``gather_rows``) finds the other copy of an element's edge
    nodes (``Topology.edges``): ``other`` (nelem, 4(np − 2)), for the nodes inside the south
    (j = 0), north (j = np − 1), west (i = 0) and east (i = np − 1) edges in turn, ordered by
    i or j, the index of the node's other copy (``Copies``' indices: c ≥ nlocal another
    process's); ``aligned`` (nelem, 2): the row index (e·np + j) of the neighbour's row whose
    lanes 1 … np − 2 are the other copies of the south, north edge's, or −1."""

    other: wp.array2d(dtype=wp.int32)
    aligned: wp.array2d(dtype=wp.int32)


@functools.cache
def gather_rows(rows: int, weighted: bool, copies: int, ghosts: bool, np_: int, dtype=f64):
    """A ``wp.func`` (xr, x, d: ``Copies``, g: ``Edges``, wr, rsr, e, j) → the (rows × np)
    matrix whose row r is row j of element e of the DSS of field r, rspheremp · Σ over copies c
    of (spheremp[c] if ``weighted`` else 1) · x[r, c] (the bits of ``gather``'s). xr: x as
    ``operators.row_vectors`` (rows, N/np); wr, rsr: spheremp's first N and rspheremp as rows
    (wr read if ``weighted``). ``ghosts`` and x's ``dtype`` as in ``gather`` (the rows float64).
    Each copy's index is read once for all the fields (a TC5 ne16 stage's DSS update, one
    thread: 114 → 84 µs for 3 rows, 152 → 112 for 4, against a field at a time)."""
    R, W, C, G, NP = int(rows), bool(weighted), int(copies), bool(ghosts), int(np_)
    NE = NP - 2
    vec = wp.types.vector(length=NP, dtype=f64)
    block = wp.types.matrix(shape=(max(R, 1), NP), dtype=f64)  # a launch of no rows (an RHS of no tendency term) too
    xvec = operators.row_type(NP, dtype)
    tag = f"{R}_{'w' if W else 'u'}_{C}{'_ghosts' if G else ''}_np{NP}" + suffix(dtype)

    value = copy_value(R, W, G, dtype)

    def own_row(xr: wp.array2d(dtype=xvec), wr: wp.array(dtype=vec), r: int, q: int):
        if wp.static(W):
            return wp.cw_mul(wr[q], vec(xr[r, q]))
        return vec(xr[r, q])

    own_row.__qualname__ = own_row.__name__ = f"own_row_{tag}"
    own = wp.func(own_row)

    corners = copies_sum(R, W, C, G, dtype)  # a corner's copies through the table

    def rows_sum(
        xr: wp.array2d(dtype=xvec),
        x: wp.array2d(dtype=dtype),
        d: Copies,
        g: Edges,
        wr: wp.array(dtype=vec),
        rsr: wp.array(dtype=vec),
        e: int,
        j: int,
    ):
        q = e * NP + j
        M = block()
        for r in range(R):
            M[r] = vec() + own(xr, wr, r, q)
        if j == 0 or j == NP - 1:
            side = wp.where(j == 0, 0, 1)
            a = g.aligned[e, side]
            if a >= 0:
                for r in range(R):
                    M[r] = M[r] + own(xr, wr, r, a)
            else:
                for i in range(1, NP - 1):
                    c = g.other[e, side * NE + i - 1]
                    for r in range(R):
                        M[r, i] += value(x, d, c, r)
            p = q * NP
            first = corners(x, d, p)
            last = corners(x, d, p + NP - 1)
            for r in range(R):
                M[r, 0] = first[r]
                M[r, NP - 1] = last[r]
        else:
            west = g.other[e, 2 * NE + j - 1]
            east = g.other[e, 3 * NE + j - 1]
            for r in range(R):
                M[r, 0] += value(x, d, west, r)
                M[r, NP - 1] += value(x, d, east, r)
        rs = rsr[q]
        for r in range(R):
            M[r] = wp.cw_mul(rs, M[r])
        return M

    rows_sum.__qualname__ = rows_sum.__name__ = f"gather_rows_{tag}"
    return wp.func(rows_sum)


@functools.cache
def dss_update_elements(
    rows: int,
    copies: int,
    patterns: tuple,
    ghosts: bool,
    weighted: bool,
    np_: int,
    dtype=f64,
    state=f64,
    assembled: int = 0,
):
    """``dss_update`` by element on GLL rows (``gather_rows``; the same bits), for the CPU, and
    with the one pattern "k" and c[0] = 1 ``dss_rows`` (1·k is k): arguments xr, x (x as rows
    and as it is), d (``Copies``), g (``Edges``), wr, rsr (spheremp's first N and rspheremp as
    rows), c, then s00, s01, out0, s10, s11, out1 as rows, offset; dim nelem. Outputs and terms
    may alias each other, not x. x of ``dtype`` (``gather_rows``), the terms and outputs of
    ``state`` and ``assembled`` as ``dss_update``'s, the rest float64."""
    A = _assembled(assembled, rows, patterns)
    BASE = patterns[0] != "k"  # as ``dss_update``'s
    R, NP = int(rows), int(np_)
    vec = wp.types.vector(length=NP, dtype=f64)
    xvec = operators.row_type(NP, dtype)
    svec = operators.row_type(NP, state)
    rows_dss = gather_rows(rows, weighted, copies, ghosts, np_, dtype)
    first = combination(patterns[0], state)
    second = combination(patterns[-1], state)
    TWO = len(patterns) == 2

    def dss_update(
        xr: wp.array2d(dtype=xvec),
        x: wp.array2d(dtype=dtype),
        d: Copies,
        g: Edges,
        wr: wp.array(dtype=vec),
        rsr: wp.array(dtype=vec),
        c: vec6,
        s00: wp.array2d(dtype=svec),
        s01: wp.array2d(dtype=svec),
        out0: wp.array2d(dtype=svec),
        s10: wp.array2d(dtype=svec),
        s11: wp.array2d(dtype=svec),
        out1: wp.array2d(dtype=svec),
        offset: int,
    ):
        e = wp.tid() + offset
        for j in range(NP):
            q = e * NP + j
            M = rows_dss(xr, x, d, g, wr, rsr, e, j)
            for r in range(wp.static(R - A)):  # wp.static: a constant, unrolled (R − A is not, 1.6× slower)
                k = M[r]
                out0[r, q] = svec(first(wp.vec3d(c[0], c[1], c[2]), k, s00, s01, r, q))
                if wp.static(TWO):
                    out1[r, q] = svec(second(wp.vec3d(c[3], c[4], c[5]), k, s10, s11, r, q))
            if wp.static(A > 0):
                for r in range(wp.static(R - A), R):
                    if wp.static(BASE):
                        out0[r, q] = svec(vec(s00[r, q]) + M[r])
                    else:
                        out0[r, q] = svec(M[r])

    name = "dss_update__" + "__".join(patterns) + ("" if weighted else "__unweighted")
    name = ("dss" if patterns == ("k",) else name) + suffix(dtype) + state_suffix(state)  # "k": the DSS's key
    name += assembled_suffix(A)
    dss_update.__qualname__ = dss_update.__name__ = name
    return wp.kernel(dss_update, enable_backward=False, module="unique")


@wp.kernel
def assemble(
    x: wp.array2d(dtype=f64),
    ghost: wp.array(dtype=f64),
    nlocal: int,
    row: int,
    spheremp: wp.array(dtype=f64),
    table: wp.array2d(dtype=wp.int32),
    first: wp.array(dtype=wp.int32),
    out: wp.array(dtype=f64),
    offset: int,
):
    """Unique-node vector out[g] = Σ_copies c of g spheremp[c]·x[row, c] (in the
    ``dss_table`` order of node first[g]): the assembled mass matrix times a
    continuous field (m² × units of x). A copy c ≥ ``nlocal`` is another
    process's, read from ghost[(c − nlocal)·rows + row] (``pack``'s layout of
    all x.shape[0] rows). Dim nunique."""
    g = wp.tid() + offset
    p = first[g]
    rows = x.shape[0]
    s = f64(0.0)
    for k in range(table.shape[1]):
        c = table[p, k]
        if c >= 0:
            v = f64(0.0)
            if c >= nlocal:
                v = ghost[(c - nlocal) * rows + row]
            else:
                v = x[row, c]
            s += spheremp[c] * v
    out[g] = s


@wp.kernel
def pack(x: wp.array2d(dtype=Any), rows: int, index: wp.array(dtype=wp.int32), buf: wp.array(dtype=f64), offset: int):
    """buf[k·rows + r] = x[r, index[k]] for r < rows: the copies another process
    needs, node by node (HOMME ``edgeVpack``); x float64 or float32 (the float32
    Helmholtz solve's), the buffer float64. Dim len(index)."""
    k = wp.tid() + offset
    p = index[k]
    for r in range(rows):
        buf[k * rows + r] = f64(x[r, p])


for _t in (f64, wp.float32):  # the model's fields and the float32 Helmholtz solve's vectors
    wp.overload(pack, {"x": wp.array2d(dtype=_t)})


@wp.kernel
def scatter(
    y: wp.array2d(dtype=f64),
    halo: wp.array(dtype=f64),
    gid: wp.array(dtype=wp.int32),
    row: int,
    out: wp.array2d(dtype=f64),
    offset: int,
):
    """Element-local out[row + r, p] = y[r, gid[p]] for r < rows = y.shape[0],
    from a unique-node vector of ``rows`` rows (rows, nunique). A node owned by
    another process (gid[p] ≥ nunique) is read from halo[(gid[p] − nunique)·rows + r]
    (``pack``'s layout). Dim N."""
    p = wp.tid() + offset
    g = gid[p]
    n = y.shape[1]
    for r in range(y.shape[0]):
        if g < n:
            out[row + r, p] = y[r, g]
        else:
            out[row + r, p] = halo[(g - n) * y.shape[0] + r]
