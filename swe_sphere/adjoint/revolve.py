"""Binomial checkpointing of a reverse sweep over n steps (Griewank 1992, Optim. Methods Softw.
1:35; Griewank & Walther 2000, ACM TOMS 26:19, "Algorithm 799: revolve").

A reverse sweep visits the states x(n−1), …, x(0) in that order, each once, while only
``snapshots`` states are held at any time (x(0) one of them): a state not held is recomputed
from the nearest one held before it. The fewest forward steps that reverse l steps with s
snapshots (the start's included) are t(l, s) = r·l − C(s + r, s + 1), r the least with
C(s + r, s) ≥ l (Griewank & Walther 2000, Prop. 1; ``griewank_steps``), the closed form of the
recursion T(l, c) = min_m [m + T(l − m, c − 1) + T(m, c)] (``tests/adjoint`` checks both and
that ``sweep`` takes that many). ``sweep`` splits by the closed form (``split``: t is convex in
l, so the split's cost is convex in m and bisected): the recursion costs O(l² c), 6.7 s of
Python for l = 1284, c = 29.

``two_level`` adds a second, slower tier (Stumm & Walther 2009, SIAM J. Sci. Comput. 31:1946;
Aupy, Herrmann, Hovland & Robert 2016, SIAM J. Sci. Comput. 38:C232): a first forward pass
writes x(0), x(K), x(2K), … to it, then each segment of K steps, last first, is reversed from
its state read back by ``sweep`` with ``snapshots`` states in memory.
"""

from __future__ import annotations

from math import comb


def griewank_steps(l: int, s: int) -> int:
    """Griewank & Walther's t(l, s) = r·l − C(s + r, s + 1), r least with C(s + r, s) ≥ l: the
    forward steps of the optimal reversal of l steps with s snapshots (the start's included)."""
    r = 0
    while comb(s + r, s) < l:
        r += 1
    return r * l - comb(s + r, s + 1)


def split(l: int, c: int) -> int:
    """An optimal first split m (1 ≤ m < l) of the reversal of l ≥ 2 steps from a held state
    with c ≥ 1 snapshots free: the least m minimizing m + T(l − m, c − 1) + T(m, c), by
    bisection on its forward difference with T from ``griewank_steps`` (O(log l · r))."""

    def cost(m):
        return m + griewank_steps(l - m, c) + griewank_steps(m, c + 1)

    lo, hi = 1, l - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cost(mid + 1) >= cost(mid):
            hi = mid
        else:
            lo = mid + 1
    return lo


def sweep(n: int, snapshots: int, x0, advance, reverse, copy, start: int = 0) -> int:
    """Run the reverse sweep over the n steps from x0 = x(``start``) with at most ``snapshots``
    (≥ 1) states held, x0 one of them: ``reverse(x, k)`` is called for k = start + n − 1, …, start
    with x = x(k) (to be read, not changed); ``advance(x, k, m)`` steps x = x(k) m ≥ 1 steps in
    place (a walk between two states held, in one call); ``copy(x)`` returns a new state equal
    to x (a held snapshot, or a work state). Returns the forward steps taken,
    ``griewank_steps(n, snapshots)``. ValueError for n < 1 or snapshots < 1."""
    if n < 1 or snapshots < 1:
        raise ValueError(f"a sweep needs n >= 1 steps and snapshots >= 1 (got {n}, {snapshots})")
    taken = 0

    def walk(x, a, steps):
        nonlocal taken
        if steps:
            advance(x, start + a, steps)
        taken += steps
        return x

    # The reversal of steps a..b−1 from xa = x(a) held with ``free`` snapshots more: split at m,
    # reverse m..b−1 from x(m) with one snapshot fewer, then a..m−1 the same way. A stack of
    # (a, b, xa, free), not recursion: every state held splits at m = a + 1, as deep as n.
    stack = [(0, n, x0, snapshots - 1)]
    while stack:
        a, b, xa, free = stack.pop()
        if b - a > 1 and free == 0:
            for k in range(b - 1, a, -1):
                reverse(walk(copy(xa), a, k - a), start + k)
        elif b - a > 1:
            m = a + split(b - a, free)
            stack.append((a, m, xa, free))  # after m..b−1, the steps before m
            stack.append((m, b, walk(copy(xa), a, m - a), free - 1))
            continue
        reverse(xa, start + a)
    return taken


def two_level_steps(n: int, snapshots: int, interval: int) -> int:
    """The forward steps of ``two_level``: n (the first pass, to x(n)) + Σ_j t(L_j, snapshots)
    over its segments, ⌊n/K⌋ of L = K = ``interval`` steps and one of n mod K where that is
    not 0 (t = ``griewank_steps``; with K ≤ snapshots, t(L, s) = L − 1: 2n − ⌈n/K⌉ in all)."""
    whole, rest = divmod(int(n), int(interval))
    return n + whole * griewank_steps(interval, snapshots) + (griewank_steps(rest, snapshots) if rest else 0)


def two_level(n: int, snapshots: int, interval: int, x0, advance, reverse, copy, tier, final) -> int:
    """The reverse sweep of ``sweep`` over n steps with a second tier: x0 is advanced in place to
    x(n) (then ``final(x)`` is called, before any ``reverse``), ``tier.save(j, x)`` storing
    x(jK) on the way (K = ``interval``, j = 0 … ⌈n/K⌉ − 1); then for j from the last down,
    ``tier.load(j)`` returns a new state equal to x(jK) and the segment's steps jK … min(jK +
    K, n) − 1 are reversed by ``sweep`` with at most ``snapshots`` states held (the loaded one
    included; where K > snapshots, ``sweep``'s work copy besides, from which it recomputes a
    stretch). ``reverse``, ``advance`` and ``copy`` as ``sweep``'s. Returns the forward steps
    taken, ``two_level_steps(n, snapshots, interval)``. ValueError for n, snapshots or
    interval < 1."""
    if n < 1 or snapshots < 1 or interval < 1:
        raise ValueError(f"a two-level sweep needs n, snapshots and interval >= 1 (got {n}, {snapshots}, {interval})")
    starts = range(0, n, interval)
    for j, a in enumerate(starts):
        tier.save(j, x0)
        advance(x0, a, min(interval, n - a))
    final(x0)
    return n + sum(
        sweep(min(interval, n - a), snapshots, tier.load(j), advance, reverse, copy, a)
        for j, a in reversed([*enumerate(starts)])
    )
