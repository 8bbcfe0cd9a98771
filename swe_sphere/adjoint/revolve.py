"""Binomial checkpointing of a reverse sweep over n steps (Griewank 1992, Optim. Methods Softw.
1:35; Griewank & Walther 2000, ACM TOMS 26:19, "Algorithm 799: revolve").

A reverse sweep visits the states x(n−1), …, x(0) in that order, each once, while only
``snapshots`` states are held at any time (x(0) one of them): a state not held is recomputed
from the nearest one held before it. ``forward_steps(l, c)`` is the fewest forward steps that
reverse l steps from a held state with c more snapshots free, by the recursion
T(l, c) = min_m [m + T(l − m, c − 1) + T(m, c)], T(1, c) = 0, T(l, 0) = l(l − 1)/2, and
``griewank_steps`` its closed form, t = r·l − C(s + r, s + 1) with s = c + 1 snapshots and r
the least with C(s + r, s) ≥ l (Griewank & Walther 2000, Prop. 1): ``tests/adjoint`` checks
that the two agree and that ``sweep`` takes exactly that many. ``sweep`` splits by the closed
form (``split``: t is convex in l, its increments r nondecreasing, so m + t(l − m, c) +
t(m, c + 1) is convex in m and bisected), not the recursion, which costs O(l² c) (6.7 s of
Python for l = 1284, c = 29, more than the 6-day Galewsky ne16 run it would reverse).

``two_level`` adds a second, slower tier (Stumm & Walther 2009, SIAM J. Sci. Comput. 31:1946,
"MultiStage approaches for optimal offline checkpointing"; Aupy, Herrmann, Hovland & Robert
2016, SIAM J. Sci. Comput. 38:C232): a first forward pass writes x(0), x(K), x(2K), … to it,
then each segment of K steps, last first, is reversed from its state read back by ``sweep``
with ``snapshots`` states in memory; ``two_level_steps`` counts its forward steps.
"""

from __future__ import annotations

import functools
from math import comb


@functools.cache
def _plan(l: int, c: int) -> tuple[int, int]:
    """(T(l, c), the first split m achieving it; 0 where none is taken)."""
    if l <= 1:
        return 0, 0
    if c == 0:
        return l * (l - 1) // 2, 0
    if c >= l - 1:  # a snapshot for every state: each step once
        return l - 1, 1
    best = None
    for m in range(1, l):
        cost = m + _plan(l - m, c - 1)[0] + _plan(m, c)[0]
        if best is None or cost < best[0]:
            best = (cost, m)
    return best


def forward_steps(l: int, c: int) -> int:
    """T(l, c): the fewest forward steps of a sweep over l steps from a held state with c
    snapshots free (the recursion above; O(l² c) the first time, cached)."""
    return _plan(int(l), int(c))[0]


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


def sweep(n: int, snapshots: int, x0, advance, reverse, copy) -> int:
    """Run the reverse sweep over n steps from x0 with at most ``snapshots`` (≥ 1) states held,
    x0 one of them: ``reverse(x, k)`` is called for k = n − 1, …, 0 with x = x(k) (to be read,
    not changed); ``advance(x, m)`` steps x m ≥ 1 steps in place (a walk between two states
    held, in one call: a stepper's work array copied in and out once); ``copy(x)`` returns a new state equal to x
    (a held snapshot, or a work state). Returns the forward steps taken, T(n, snapshots − 1).
    ValueError for n < 1 or snapshots < 1."""
    if n < 1 or snapshots < 1:
        raise ValueError(f"a sweep needs n >= 1 steps and snapshots >= 1 (got {n}, {snapshots})")
    taken = 0

    def walk(x, steps):
        nonlocal taken
        if steps:
            advance(x, steps)
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
                reverse(walk(copy(xa), k - a), k)
        elif b - a > 1:
            m = a + split(b - a, free)
            stack.append((a, m, xa, free))  # after m..b−1, the steps before m
            stack.append((m, b, walk(copy(xa), m - a), free - 1))
            continue
        reverse(xa, a)
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
        advance(x0, min(interval, n - a))
    final(x0)
    taken = n
    for j in reversed(range(len(starts))):
        a = starts[j]

        def shifted(x, k, a=a):
            reverse(x, a + k)

        taken += sweep(min(interval, n - a), snapshots, tier.load(j), advance, shifted, copy)
    return taken
