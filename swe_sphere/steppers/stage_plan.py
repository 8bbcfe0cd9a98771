"""An explicit Butcher table as recorded stages: each stage's combinations of the state, the
stored stages and the tendency (``stage_form``), written so that a constant state is kept to the
bit (``constant_keeping``; ``whole_partials`` under the float32 state) with the fewest buffers;
read by the engine (``runge_kutta``) and the multirate steppers. Split from ``butcher``, whose
tables it takes as given (checked there).
"""

from __future__ import annotations

import itertools
from fractions import Fraction


def _solve(columns, target):
    """Coefficients x with Σ x_m columns[m] = target exactly (Fractions), or None."""
    n, m = len(target), len(columns)
    rows = [[columns[k][i] for k in range(m)] + [target[i]] for i in range(n)]
    pivots, rank = [], 0
    for col in range(m):
        pivot = next((r for r in range(rank, n) if rows[r][col]), None)
        if pivot is None:
            continue
        rows[rank], rows[pivot] = rows[pivot], rows[rank]
        rows[rank] = [x / rows[rank][col] for x in rows[rank]]
        for r in range(n):
            if r != rank and rows[r][col]:
                f = rows[r][col]
                rows[r] = [x - f * y for x, y in zip(rows[r], rows[rank])]
        pivots.append(col)
        rank += 1
    if any(rows[r][m] for r in range(rank, n)):
        return None
    x = [Fraction(0)] * m
    for r, col in enumerate(pivots):
        x[col] = rows[r][m]
    return x


def _in_span(v, vectors) -> bool:
    return _solve(vectors, v) is not None


def _express(target, k: int, sources: dict):
    """``target`` as Σ α·sources + q·e_k: links [(terms)], the first with at most two
    arrays and q (for the DSS of F_k), each later one adding one array to the first's
    output; as few arrays as the sources allow, x first."""
    names = list(sources)
    unit = [Fraction(int(i == k)) for i in range(len(target))]
    for size in (1, 2):
        for pick in itertools.combinations(names, size):
            x = _solve([sources[p] for p in pick] + [unit], target)
            if x is not None:
                return [[(a, p) for a, p in zip(x, pick) if a] + ([(x[-1], "k")] if x[-1] else [])]
    x = _solve([sources[p] for p in names] + [unit], target)  # every target lies in the sources' span
    arrays = [(a, p) for a, p in zip(x, names) if a]
    return [arrays[:2] + ([(x[-1], "k")] if x[-1] else [])] + [[(Fraction(1), None), t] for t in arrays[2:]]


def stage_form(A, b, c, d=None, whole_partials: bool = False) -> tuple[tuple, tuple]:
    """(buffers, stages) for the explicit table (A, b, c) (Fractions): the buffers'
    names, and per stage (c, the buffer whose RHS F is evaluated, updates), each
    update (out, terms) with out = Σ a·src over two or three (a, src) terms, in
    order (a later one reads an earlier one's output); src "k" (F) takes a
    ``Fraction`` q of Δt (F times qΔt), once a combination, and at most two are
    arrays (``ShallowWater.rhs_update``); "x" is the state, overwritten by the last
    update. x(n+1) = x(n) + Δt Σ b_j K_j, K_i = F(Y_i), Y_i = x(n) + Δt Σ_j a_ij K_j.

    Every buffer holds a combination of e_0 = x(n) and e_j = Δt K_j. After stage j
    the buffers must span the part in e_0..e_j of every combination still to be
    formed (the later Y_i and x(n+1)), and one must hold Y_{j+1} itself. Stage j
    keeps the buffers that lie in that span (and x(n), kept to the end), writes
    Y_{j+1} and whatever else the span lacks (each from the buffers before it and
    F_j, straight from F_j's DSS; with more than two arrays a chain of updates),
    and the others become free for its outputs, in the order that needs the
    fewest buffers: a table whose stages read few earlier stages writes as few
    combinations as its Shu–Osher form (ssprk3's, kgu35's; RK4 one fewer than
    its accumulator form). The state x is overwritten last, with x(n+1).

    With the weights d = b − b̂ of an embedded pair (``Table.estimate``) the error
    estimate e = Δt Σ d_j K_j is one more combination to come, written by the last
    stage into the buffer "e" (the last of the buffers) before x(n+1), no RHS of its
    own; without d the form is the one of before there were pairs (the same bits).

    The arrays' weights are floats that keep a constant state exactly (``constant_keeping``:
    each combination's x(n) part exactly its exact one, 1 for every Y_i and x(n+1)).

    ``whole_partials`` (the float32 state's stages, ``runge_kutta.ExplicitRK``): each partial sum
    of a chain holds the whole combination's x(n) part (``_whole_partials``), and each link's
    weights keep it, so that a constant state stays constant through every link however each
    is rounded; False: partial sums of the combination's first terms (the float64 bits)."""
    s, n = len(b), len(b) + 1
    Y = [[Fraction(1), *A[i]] for i in range(s)]
    Z = [Fraction(1), *b]
    ends = [Z] if d is None else [[Fraction(0), *d], Z]  # what the last stage writes, the estimate first
    content = {"x": [Fraction(int(i == 0)) for i in range(n)]}  # live buffers, in creation order
    free, created, holder, stages = [], [], "x", []
    for j in range(s):
        k, last = j + 1, j == s - 1
        cut = [[*t[: k + 1], *[Fraction(0)] * (n - k - 1)] for t in (*Y[k:], *ends)]  # what is to come, in e_0..e_k
        kept = [
            name for name, v in content.items() if name == "x" or _in_span(v, [*cut, content["x"]])
        ]  # x is kept anyway
        if last:  # the estimate before x(n+1), which overwrites the x it may read
            writes = [(t, _express(t, k, content)) for t in ends]
        else:
            writes = _writes(Y[k], cut[1:], k, content, kept)
        dying = [name for name in content if name not in kept] + free
        order, outs, pool = _fewest_buffers(writes, dying, Z if last else None)
        for w in order:  # name the fresh buffers
            if outs[w].startswith("new"):
                outs[w] = f"s{len(created) + 1}"
                created.append(outs[w])
        updates = []
        for w in order:
            target, links = writes[w]
            out = outs[w]
            chain = _whole_partials(links, out, target[0], content) if whole_partials and len(links) > 1 else None
            if chain is not None:
                updates += [(out, terms) for terms in chain]
                continue
            arrays = [(a, src) for link in links for a, src in link if src not in ("k", None)]
            weights = iter(constant_keeping([a for a, _ in arrays], [content[src][0] for _, src in arrays]))
            for link in links:
                terms = ((a if src == "k" else 1.0 if src is None else next(weights), src or out) for a, src in link)
                updates.append((out, tuple(terms)))
        stages.append((float(c[j]), holder, tuple(updates)))
        content = {**{name: content[name] for name in kept}, **{outs[w]: writes[w][0] for w in order}}
        free = [name for name in pool if name not in content]
        holder = None if last else next(name for name, v in content.items() if v == Y[k])
    return tuple(created) + (() if d is None else ("e",)), tuple(stages)


def constant_keeping(weights, scales) -> list[float]:
    """The exact ``weights`` a_m (``Fraction``s) of a combination Σ a_m src_m as floats whose
    Σ a_m s_m, in exact arithmetic, is the exact weights' (``scales`` s_m: each source's
    multiple of x(n), ``stage_form``'s e_0 part): a combination that keeps a constant state
    exactly (x(n) = C and F = 0 give Y_i = C and x(n+1) = C) keeps it with its float weights
    too. Each weight rounded, then, where their sum misses, the smallest in size whose
    remainder is a float takes it (moved by the others' rounding errors: 1 ulp for rk4's
    1/3, at most 14 of its own for the built-in tables' chained combinations), else all as
    rounded.
    Rounded alone, fl(1/3) + fl(2/3) = 1 − 2⁻⁵⁴ (ssprk3's and rk4's last combinations), which
    biases x(n+1) low by a part in 2⁵⁴ a step: TC5's mass drifted −4.7e-17 a step."""
    floats = [float(a) for a in weights]
    total = sum(a * s for a, s in zip(weights, scales))
    if sum(Fraction(f) * s for f, s in zip(floats, scales)) == total:
        return floats
    for m in sorted((m for m, s in enumerate(scales) if s), key=lambda m: abs(weights[m] * scales[m])):
        rest = total - sum(Fraction(f) * s for i, (f, s) in enumerate(zip(floats, scales)) if i != m)
        if Fraction(float(rest / scales[m])) == rest / scales[m]:
            return [float(rest / scales[m]) if i == m else f for i, f in enumerate(floats)]
    return floats


def _whole_partials(links: list, out: str, whole: Fraction, content: dict) -> list[tuple] | None:
    """A chain's links (``_express``: Q₁ = a₀s₀ + a₁s₁ + qF, then Q_m = Q_(m−1) + a_m s_m) as
    links whose partial sums each hold the combination's x(n) part ``whole`` S: R_m = (S/P_m)·Q_m,
    P_m the x(n) part of Q_m (R₁'s weights the first link's times S/P₁, then R_m = (P_(m−1)/P_m)·R_(m−1)
    + (S/P_m)·a_m s_m), each link's weights kept as ``constant_keeping`` keeps them. A float32
    partial sum of part P_m ≠ S rounds C·P_m, which the next link does not give back (bs32's
    s3 = (x + 4s₁ + 4qF)/9 + 4s₂/9: C·5/9 rounded): a constant state drifted by a float32 spacing
    a step. The links' (terms) in order; None where the whole or a partial part is 0 (the
    chain summed as it is)."""
    first, *rest = links
    scale = {src: content[src][0] for link in links for _, src in link if src not in ("k", None)}
    parts = [sum(a * scale[src] for a, src in first if src != "k")]
    for (_, _), (a, src) in rest:
        parts.append(parts[-1] + a * scale[src])
    if whole == 0 or any(p == 0 for p in parts):
        return None
    arrays = [(a * whole / parts[0], src) for a, src in first if src != "k"]
    weights = iter(constant_keeping([a for a, _ in arrays], [scale[src] for _, src in arrays]))
    chain = [tuple((a * whole / parts[0] if src == "k" else next(weights), src) for a, src in first)]
    for m, ((_, _), (a, src)) in enumerate(rest, start=1):
        w = constant_keeping([parts[m - 1] / parts[m], a * whole / parts[m]], [whole, scale[src]])
        chain.append(((w[0], out), (w[1], src)))
    return chain


def _writes(y, rest, k: int, content: dict, kept: list) -> list:
    """What a stage that is not the last writes, (target, links) each: Y_(k+1) = ``y`` unless
    a kept buffer holds it, then each combination of ``rest`` outside the span of the kept
    buffers and the writes before it."""
    writes = []
    if not any(content[name] == y for name in kept):
        writes.append((y, _express(y, k, content)))
    for target in rest:
        if not _in_span(target, [content[name] for name in kept] + [w[0] for w in writes]):
            writes.append((target, _express(target, k, content)))
    return writes


def _fewest_buffers(writes: list, dying: list, last_x) -> tuple:
    """(order, outs, pool): the order of ``writes`` (every one of up to five writes tried)
    and their output buffers that take the fewest fresh buffers ("new1", …), reusing the
    ``dying`` ones that no later link reads; ``pool`` the dying left unused. In the last stage
    (``last_x`` the x(n+1) target) the outputs are "x" for x(n+1) and "e" for the estimate."""
    best = None
    for order in itertools.permutations(range(len(writes))) if len(writes) <= 5 else [range(len(writes))]:
        outs, pool, new = {}, list(dying), 0
        for pos, w in enumerate(order):
            later = {src for w2 in order[pos + 1 :] for link in writes[w2][1] for _, src in link}
            later |= {src for link in writes[w][1][1:] for _, src in link}
            if last_x is not None:
                outs[w] = "x" if writes[w][0] is last_x else "e"
                continue
            out = next((name for name in pool if name not in later), None)
            if out is None:
                new += 1
                out = f"new{new}"
            else:
                pool.remove(out)
            outs[w] = out
        if best is None or new < best[0]:
            best = (new, order, outs, pool)
    return best[1:]


def stage_terms(terms, dst, arrays: dict, K, tau: float) -> tuple:
    """The (coefficient, array) terms of one ``stage_form`` update into ``dst``: src "k" as
    (q·tau, K), None as dst itself, a name as that buffer of ``arrays``."""
    return tuple((float(a) * tau, K) if src == "k" else (a, dst if src is None else arrays[src]) for a, src in terms)
