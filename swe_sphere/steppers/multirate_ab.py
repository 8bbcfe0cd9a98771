"""Multirate Adams–Bashforth 3 (MRAB3) on the element levels of local time stepping.

The assembled tendency splits exactly by element level, F = Σ_k f_k, f_k = M⁻¹ DSS(the
level-k elements' contributions) (``ShallowWater.rhs_part``; ``local``'s module docstring).
Over a coarse step [t_n, t_n + Δt] level k steps h_k = Δt/2^k (K the finest level). Each
level keeps its last three tendencies at its own step times, f_k(t_j), f_k(t_j − h_k),
f_k(t_j − 2h_k), and on [t_j, t_j + h_k] its tendency is the quadratic p_k through them
(extrapolated: Adams–Bashforth 3). The state at any time t of the step is
y(t) = y_n + Σ_k ∫_{t_n}^{t} p_k, each level's quadratic integrated exactly (Lagrange basis
integrals; over a whole step of the level that is AB3's h_k (23 f⁰ − 16 f¹ + 5 f²)/12).
The step walks the finest sub-steps t_j = t_n + j h_K: at t_j every level whose step starts
there evaluates f_k(y(t_j)) and shifts its history, then y gains every level's integral over
[t_j, t_j + h_K]. Gear & Wells 1984 (BIT 24:484, multirate linear multistep methods: the
slow part's history extrapolated over the fast steps); Mikida, Klöckner & Bodony 2019
(J. Comput. Phys. 394:345: multirate AB for DG, the states built from each rate's
polynomial integrated exactly over the fastest step); one evaluation of level k every h_k,
so a coarse step evaluates level-k elements 2^k times: the levels' bound exactly. Order 3
(each level's quadratic is third order where it is extrapolated over at most its own step).

The sums. Level k's integral is needed between its step boundaries only where a finer level
reads the state. Its nodes (those its elements touch) split by unique node: A_k, touched by an
element of a finer level too, and B_k, the rest. At each finest sub-step j, x[A_k] gains
Δt Σ_i w[j, k, i] f_k⁽ⁱ⁾ (``ab3_weights``); at the last finest sub-step of each level-k step
(j ≡ m − 1 mod m, m = 2^(K−k)), x[B_k] gains the whole step's Δt Σ_i W[k, i] f_k⁽ⁱ⁾, W the
exact sum of the step's sub-step weights (``ab3_step_weights``: AB3's). Exact: a B_k node is
touched only by elements of level k or coarser, which evaluate only at level-k step
boundaries (their step starts are multiples of h_k), so between them nothing reads it. The
finest level's nodes are all B_K, summed each sub-step. A node's copies fall on one side, so
they keep one value. Regrouped, the sums change the state in its last bits only; they cost in
proportion to the nodes summed (the benchmarks notebook (git show 5fa9286:benchmarks/README.md), "Where a step goes").

With one level it is the global AB3 step: y_{n+1} = y_n + Δt (23 F_n − 16 F_{n−1} + 5 F_{n−2})/12
through ``ShallowWater.rhs`` (the whole grid's, not a part's).

The start. AB3 needs two coarse steps of history: the first two coarse steps take 2^K steps
each of the explicit Runge–Kutta table ``inner`` at the finest step h_K, the first stage's F
the sum of the levels' f_k at the sub-step's start, so each level records f_k at its own
step times on the way. Their order (4 for RK4, 3 for SSPRK3) keeps the method's.

Mass. f_k's depth row integrates to the flux of h v through level k's boundary at level k's
times; its neighbour level integrates the same interface flux with its own polynomial, so a
step changes the mass by the difference of two third-order integrations of one flux:
zero to the method's order, not to round-off (tests/steppers/test_local.py bounds it on TC2
by a hundredth of the depth's error and checks that it falls at the method's order).
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import warp as wp

from .butcher import built_in_table
from .stage_plan import stage_form, stage_terms

f64 = wp.float64
HISTORY = 3  # tendencies a level keeps: AB3's
START_STEPS = HISTORY - 1  # coarse steps of the Runge–Kutta start


def _antiderivatives(s: Fraction) -> tuple[Fraction, Fraction, Fraction]:
    """∫_0^s of the Lagrange basis on the nodes 0, −1, −2 (the newest first):
    L0 = (s+1)(s+2)/2, L1 = −s(s+2), L2 = s(s+1)/2."""
    return (s**3 / 6 + 3 * s**2 / 4 + s, -(s**3) / 3 - s**2, s**3 / 6 + s**2 / 4)


def ab3_weights(levels: int) -> np.ndarray:
    """(2^K, K + 1, 3) float: entry [j, k, i] the integral over the finest sub-step
    [t_j, t_j + h_K] of level k's Lagrange basis function i (i = 0 the newest of its three
    tendencies), in units of Δt: h_k/Δt ∫_a^b L_i, a and b the sub-step's ends in level k's
    own step. Over a level's whole step the rows sum to AB3's (23, −16, 5)/12 · h_k/Δt."""
    K = levels - 1
    out = np.zeros((2**K, levels, HISTORY))
    for j in range(2**K):
        for k in range(levels):
            m = 2 ** (K - k)  # finest sub-steps a level-k step
            a, b = Fraction(j % m, m), Fraction(j % m + 1, m)
            lo, hi = _antiderivatives(a), _antiderivatives(b)
            out[j, k] = [float(Fraction(1, 2**k) * (y - x)) for x, y in zip(lo, hi)]
    return out


def ab3_step_weights(levels: int) -> np.ndarray:
    """(K + 1, 3) float: entry [k, i] the integral over a whole level-k step of its
    Lagrange basis function i, in units of Δt: AB3's (23, −16, 5)/12 · h_k/Δt, the exact
    sum (in fractions) of the level's sub-step weights ``ab3_weights``."""
    out = np.zeros((levels, HISTORY))
    for k in range(levels):
        ends = _antiderivatives(Fraction(0)), _antiderivatives(Fraction(1))
        out[k] = [float(Fraction(1, 2**k) * (y - x)) for x, y in zip(*ends)]
    return out


def sum_nodes(parts: list, device) -> tuple[list, list]:
    """(read, unread): for each level k, the element-local nodes (every copy; int32 device
    arrays) among those level k's part touches (``ElementPart.nodes``) that an element of a
    finer level also touches (read: none for the finest) and the rest (unread); a node's
    copies are all in one of the two, so they stay equal. [], [] for one level (``parts``
    [None])."""
    if parts == [None]:
        return [], []
    read, unread = [], []
    for k, part in enumerate(parts):
        nodes = part.nodes.numpy()
        finer = [p.nodes.numpy() for p in parts[k + 1 :]]
        mask = np.isin(nodes, np.concatenate(finer)) if finer else np.zeros(nodes.size, dtype=bool)
        read.append(wp.array(nodes[mask], dtype=wp.int32, device=device))
        unread.append(wp.array(nodes[~mask], dtype=wp.int32, device=device))
    return read, unread


class MultirateAB3:
    """The MRAB3 step (the module docstring) of ``model`` with coarse step ``dt`` (s) on the
    element ``parts`` (one ``model.parts.ElementPart`` a level, coarsest first; [None]: one
    level, the whole grid's ``rhs``). ``inner`` names the start's explicit table
    (``tables.EXPLICIT``); ``comb(out, *terms)`` and ``combine(out, terms)`` are the
    stepper's recorded linear combinations, ``at(c)`` sets the model time to t_n + c Δt.
    ``read`` and ``unread`` (``sum_nodes``): each level's A_k and B_k (the
    module docstring, "The sums")."""

    def __init__(self, model, dt: float, parts: list, inner: str, comb, combine, at):
        self.model, self.dt, self.parts = model, float(dt), parts
        self.comb, self.combine, self.at = comb, combine, at
        self.levels = len(parts)
        self.weights = ab3_weights(self.levels)
        self.step_weights = ab3_step_weights(self.levels)
        buffer = lambda: wp.zeros((3, model.topology.N), dtype=f64, device=model.topology.device)  # noqa: E731
        # each level's tendencies, the newest first; a level's buffers hold its nodes alone
        self.history = [[buffer() for _ in range(HISTORY)] for _ in parts]
        self.scratch = [buffer() for _ in parts]  # f_k off its own step times (the start)
        self.started = 0  # coarse steps of the start taken
        table = self.inner = built_in_table(inner)  # the start's
        names, self.form = stage_form(table.A_E, table.b_E, table.c)
        self.rk = {name: buffer() for name in names}
        self.F = buffer()  # the start's stage tendency
        self.read, self.unread = sum_nodes(parts, model.topology.device)
        self._sums: dict[tuple, list] = {}  # ``accumulate``'s recorded launches

    def substeps(self) -> int:
        """The finest sub-steps a coarse step, 2^K."""
        return 2 ** (self.levels - 1)

    def evaluations(self) -> list[int]:
        """Each level's evaluations a coarse step once started: 2^k."""
        return [2**k for k in range(self.levels)]

    def evaluate(self, k: int, y, out) -> None:
        """out = f_k(y), level k's tendency (3, N) (``rhs_part``; one level: ``rhs``)."""
        part = self.parts[k]
        if part is None:
            self.model.rhs(y, out)
        else:
            self.model.rhs_part(y, out, part)

    def _record(self, k: int, y) -> None:
        """Shift level k's history and evaluate its newest tendency at y."""
        _shift(self.history[k])
        self.evaluate(k, y, self.history[k][0])

    def _due(self, j: int):
        """The levels whose step starts at the finest sub-step j."""
        return [k for k in range(self.levels) if j % 2 ** (self.levels - 1 - k) == 0]

    def step(self, x) -> tuple[int, int]:
        """Advance x (3, N) in place over the coarse step (the dynamics alone). Returns the
        evaluations it took: (the coarsest level's, the finer levels'), or during the start
        (whole-grid evaluations: the parts' sum counted as one, 0)."""
        if self.started < START_STEPS:
            self._start_step(x)
            self.started += 1
            return len(self.form) * self.substeps(), 0
        n = self.substeps()
        for j in range(n):
            self.at(j / n)
            for k in self._due(j):
                self._record(k, x)
            for k in range(self.levels):
                self.accumulate(x, j, k)
        counts = self.evaluations()
        return counts[0], sum(counts[1:])

    def accumulate(self, x, j: int, k: int) -> None:
        """x += level k's integral over the finest sub-step j where a finer level reads it
        between level k's step boundaries, and over the whole level-k step elsewhere at the
        step's last sub-step (the module docstring, "The sums"): four-term combinations
        x + w0 f⁰ + w1 f¹ + w2 f² at listed nodes, recorded once per history order. One
        level: the whole grid's combination, the global AB3 step's."""
        h = self.history[k]
        key = (x.ptr, j, k, *(a.ptr for a in h))
        launches = self._sums.get(key)
        if launches is None:
            launches = self._sums[key] = self._sum_launches(x, j, k, h)
        for launch in launches:
            launch.launch()

    def _sum_launches(self, x, j: int, k: int, h: list) -> list:
        """The launches of ``accumulate(x, j, k)`` with level k's history h."""

        def terms(weights):
            return ((1.0, x), *((float(self.dt * w), a) for w, a in zip(weights, h)))

        if self.parts[k] is None:
            return [self.model.lincomb(x, terms(self.weights[j, k]))]
        sums = [(self.read[k], self.weights[j, k])]
        m = 2 ** (self.levels - 1 - k)  # finest sub-steps a level-k step
        if j % m == m - 1:
            sums.append((self.unread[k], self.step_weights[k]))
        record = self.model.launches.lincomb_at
        return [record(x, terms(w), nodes) for nodes, w in sums if nodes.shape[0]]

    def _start_step(self, x) -> None:
        """2^K steps of ``inner`` at h_K, the first stage's F the sum of the levels' f_k at
        the sub-step's start (recorded in the history at a level's own step times)."""
        n = self.substeps()
        tau = self.dt / n
        arrays = {"x": x, **self.rk}
        for j in range(n):
            due = self._due(j)
            for stage, (c, arg, updates) in enumerate(self.form):
                self.at((j + c) / n)
                if stage == 0:
                    for k in range(self.levels):
                        if k in due:
                            self._record(k, x)
                        else:
                            self.evaluate(k, x, self.scratch[k])
                    parts = [self.history[k][0] if k in due else self.scratch[k] for k in range(self.levels)]
                    self.combine(self.F, [(1.0, a) for a in parts])
                else:
                    self.model.rhs(arrays[arg], self.F)
                for out, terms in updates:
                    self.comb(arrays[out], *stage_terms(terms, arrays[out], arrays, self.F, tau))

    def replayed(self) -> None:
        """The host's part of a step that ran as a captured graph (``GraphCapture.replayed``):
        each level's history shifted 2^k times, as the step's evaluations shift it, and the
        start's progress counted."""
        for k, h in enumerate(self.history):
            for _ in range(2**k):
                _shift(h)
        self.started = min(self.started + 1, START_STEPS)

    def phase(self) -> tuple:
        """What the next step's launches depend on: the start's progress and each level's
        history order (its buffers rotate)."""
        return (self.started, *(tuple(a.ptr for a in h) for h in self.history))

    def state(self, save) -> dict:
        """The start's progress and each level's history (``save``: a whole-grid copy)."""
        out = {"mrab_started": self.started}
        for k, h in enumerate(self.history):
            for i, a in enumerate(h):
                out[f"mrab_f{k}_{i}"] = save(a)
        return out

    def restore(self, state, load, entry) -> None:
        """Set the progress and histories from ``state()`` (``load(array, state, key)``,
        ``entry(state, key)`` the stepper's; ValueError names a missing entry)."""
        self.started = int(entry(state, "mrab_started"))
        for k, h in enumerate(self.history):
            for i, a in enumerate(h):
                load(a, state, f"mrab_f{k}_{i}")


def _shift(history: list) -> None:
    """The oldest buffer becomes the newest's, to be written (the others one older)."""
    history.insert(0, history.pop())
