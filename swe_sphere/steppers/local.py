"""Local time stepping (``lts``): on a refined or stretched mesh, the small step only where
the elements are small.

Each element has a level k (``grid.levels``: from its Dinv-based size and the flow on it,
steps of Δt/2^k, neighbours at most one level apart), fixed from the initial state. The
assembled tendency splits exactly by element, F = f_0 + f_fine, f_P = M⁻¹ DSS(part P's
elements' contributions) (``ShallowWater.rhs_part``; exact because the GLL mass is
diagonal: Diaz & Grote 2009, SIAM J. Sci. Comput. 31:1985), and each part's evaluation runs
the kernels over its elements (merged into few ranges: ``LAUNCH_GAP``) and assembles only
the nodes they touch. The multirate
engine of ``multirate.Mri`` steps the split: the coarse level's f_0 is its slow part,
evaluated s times a step Δt, and the finer levels' f_fine (nonlinear) its fast part,
integrated in the inner solves by ``inner`` in steps of at most Δt/2^K (K the finest level;
each solve r ⌈d_r 2^K⌉ of them). Levels between the coarsest and the finest step with the
finest (two parts, not a recursion: exact in the levels' count only for two levels).
Or (``method = "mrab3"``) multirate Adams–Bashforth 3 on one part a level
(``multirate_ab``): level k evaluated once every Δt/2^k, so a coarse step costs exactly the
levels' bound in element evaluations, no overlap.

Mass. Each part's depth row is a DSS'd sum of its elements' divergences: its area integral
is the flux of h v through the part's boundary, which the other part's cancels only when
both are evaluated at the same state. The multirate solve evaluates f_0 at the slow stages
and f_fine at the inner stages, so a step changes the mass by the difference of the
interface flux integrated by the two methods: zero to the methods' order (both integrate
the same flux), not to round-off. TC2 on the ne4 cube refined 2× (two levels), one day of
MIS4a/RK4: 3.7e-10 of the mass at Δt = 900 s, 1.6e-11 at 450 s, a hundredth of the depth's
error or less (tests/steppers/test_local.py asserts it); TC5 there over 5 days at 1800 s,
8e-7 (the flow crosses the interface over the mountain). A flux-form coupling
(Constantinescu & Sandu 2007) would keep it to round-off; not done.

Hyperviscosity once a coarse step on the whole grid (``ShallowWater.hyperviscosity``, as
every stepper here; its substeps already follow the worst element).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial

import numpy as np
import warp as wp

from ..grid.levels import ElementLevels, element_levels, element_rates
from ..grid.quality import element_sizes
from ..model.parts import ElementPart
from .base import Stepper, StepStats, entry, gathered_copy, load_entry
from .capabilities import GraphCapture
from .multirate import Mri
from .multirate_ab import START_STEPS, MultirateAB3
from .runge_kutta import explicit_steppers
from .tables import MULTIRATE

LTS_INNER = ("ssprk3", "rk4")
MRAB3 = "mrab3"  # multirate Adams–Bashforth 3 (``multirate_ab``), beside the multirate tables
LTS_METHODS = (*MULTIRATE, MRAB3)
# elements of another level a level's kernels compute (and its DSS leaves out) rather than
# split a launch: a launch's fixed cost is that of about 30 elements' tendency at np 4 on one
# CPU thread (benchmarks/studies/lts.py level_cost), so at most this many between two of its ranges
LAUNCH_GAP = 16


@dataclass(frozen=True)
class LtsOptions:
    """Scene table ``[lts]`` (see ``Lts``): ``method`` (a table of ``tables.MULTIRATE``, or
    "mrab3"), ``inner`` ("ssprk3" | "rk4"), ``max_levels`` (≥ 1), ``substeps`` ("levels" or
    an integer ≥ 1), ``level_margin`` (≥ 1). ValueError names a bad one."""

    method: str = "mis4a"
    inner: str = "rk4"
    max_levels: int = 2
    substeps: int | str = "levels"
    level_margin: float = 1.0

    def __post_init__(self):
        if self.method not in LTS_METHODS:
            raise ValueError(f"method must be one of {', '.join(LTS_METHODS)} (got {self.method!r})")
        if self.inner not in LTS_INNER:
            raise ValueError(f"inner must be one of {', '.join(LTS_INNER)} (got {self.inner!r})")
        m = self.max_levels
        if isinstance(m, bool) or not isinstance(m, int) or m < 1:
            raise ValueError(f"max_levels must be an integer >= 1 (got {m!r})")
        margin = self.level_margin
        if isinstance(margin, bool) or not isinstance(margin, (int, float)) or not margin >= 1:
            raise ValueError(f"level_margin must be a number >= 1 (got {margin!r})")
        n = self.substeps
        if n != "levels" and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
            raise ValueError(f'substeps must be an integer >= 1 or "levels" (got {n!r})')

    def table(self) -> dict:
        """The multirate table's entries (``parse_mri``); MRAB3's name and order alone."""
        if self.method == MRAB3:
            return {"name": "MRAB3", "order": 3}
        return dict(MULTIRATE[self.method])


class LevelSplit:
    """The tendency split by element level: ``slow(x, out)`` = f_0(x), the coarsest level's
    elements; ``fast(x, out, forcing)`` = f_fine(x) + forcing, the finer levels' (through
    ``fine``, a (3, N) buffer of f_fine, and ``combine(out, *terms)``, the stepper's recorded
    combinations). ``slow``'s out keeps its values at the nodes level 0 does not touch
    (zero in a buffer that only it writes)."""

    def __init__(self, model, levels: ElementLevels, combine):
        self.model, self.levels, self.combine = model, levels, combine
        self.coarse = level_part(model, levels.level == 0)
        self.finer = level_part(model, levels.level >= 1)
        self.F = wp.zeros((3, model.topology.N), dtype=wp.float64, device=model.topology.device)

    def slow(self, x, out) -> None:
        self.model.rhs_part(x, out, self.coarse)

    def fast(self, x, out, forcing) -> None:
        self.model.rhs_part(x, self.F, self.finer)
        self.combine(out, (1.0, self.F), (1.0, forcing))


class Lts(Mri):
    """Local time stepping: element levels stepped by a multirate table or by multirate AB3.

    The element levels (``grid.levels``) from the initial state (``prepare``), the
    coarsest level's tendency the slow part and the finer levels' the fast part of the
    multirate engine of ``Mri`` (the module docstring). Options (scene table ``[lts]``):
    ``method``, the multirate table (``tables.MULTIRATE``: "mis2" and "mis3c" second order,
    Wensch, Knoth & Galant 2009 and Knoth & Wensch 2014; "mis4a" third order, Knoth &
    Wensch 2014, the default; "mri_gark_erk33a" third order, Sandu 2019); ``inner``, the
    fast part's integrator ("rk4", fourth order, the default; "ssprk3", third), each
    solve in ⌈d_r n⌉ steps; ``substeps`` n, "levels" (the default): 2^K, the finest
    level's step, or a number (fewer when the coarse step is below 2^K times the worst
    element's limit: the inner step need only be within the worst element's, as a global
    step is); ``max_levels``, at most this many levels (default 2); ``level_margin`` m ≥ 1
    (default 1): an element is coarser than the finest level only if m times its rate is
    within the level's limit (``grid.levels.element_levels``).
    A step's order is the lower of the table's and the inner method's.

    ``method = "mrab3"``: multirate Adams–Bashforth 3 (``multirate_ab.MultirateAB3``; Gear
    & Wells 1984, BIT 24:484; Mikida, Klöckner & Bodony 2019, J. Comput. Phys. 394:345),
    third order, one evaluation of level k every Δt/2^k (the coarse level's reported as RHS
    evaluations, the finer levels' as "fast"), the first two coarse steps ``inner``'s at
    Δt/2^K recording the levels' histories; ``substeps`` unused. With one level it is the
    global AB3 step (``max_levels = 1``): AB3's stability interval on the imaginary axis is
    about a quarter of RK4's (0.72 against 2.83, one evaluation a step against four), so its
    step is about a quarter of RK4's and the ∇⁴, once a step, is applied four times as often.
    Its coupled levels hold less than each element's own limit near the interfaces on a
    paved mesh: ``level_margin`` moves the elements nearest a level's limit finer
    (the earlier benchmarks notebook (benchmarks/README.md before the suite), "Local time stepping").

    On a mesh (and flow) with one level the step is ``inner``'s global explicit
    Runge–Kutta step, the same bits as that stepper (``describe`` says so). s slow
    evaluations of the coarse elements a step (reported as RHS evaluations) and the
    inner stages' evaluations of the fine ones ("fast"). On several MPI ranks each rank
    steps its share of every level, the same bits as on one (the levels are the whole
    grid's; a level's assembly sums every copy in the one global order); the simulation
    cuts each level along the curve (``size_levels``, ``partition.level_chunks``) so that
    every rank has an equal share of each. The run file's attributes
    ``lts_*`` give the table, the levels, the elements per level and the saving's bound.

    What it does not reach (measured in the earlier benchmarks notebook (benchmarks/README.md before the suite), "Local time stepping"): with
    MIS tables the coarse step stays near the global one, since the levels' coupling, not
    the fine substeps, sets it (the MIS4a slow table alone holds 0.72x RK4's interval on
    the imaginary axis), and a coarse step evaluates the fine elements s_inner Σ_r ⌈d_r 2^K⌉
    times (32 for MIS4a/RK4 at K = 2) where a global step at Δt/2^K does 4·2^K: the inner
    solves of MIS tables overlap (Σ d_r = 1.47). MRAB3 evaluates exactly the levels' bound,
    but its steps are short (AB3's stable step is a quarter of RK4's, and at equal accuracy
    its error constant holds it below that), so the ∇⁴ once a step and the levels' sub-step
    sums cost more than the evaluations it saves."""

    name = "lts"
    dense_hyperviscosity = "applies its ∇⁴ once a coarse step, its levels' phases keyed in its graphs"
    Options = LtsOptions
    solvers = ("fast",)

    def __init__(self, model, dt, options=None):
        if (options or LtsOptions()).method == MRAB3:  # no multirate table: the engine's buffers alone
            Stepper.__init__(self, model, dt, options)
            self.split, self.n_fast, self._combs = None, None, {}
        else:
            super().__init__(model, dt, options)
        self.levels: ElementLevels | None = None
        self.single = None  # the inner method's global stepper, with one level
        self.mrab: MultirateAB3 | None = None  # method "mrab3"'s engine, from the levels

    def _make_split(self):
        return None  # from the levels, at ``prepare``

    @classmethod
    def partition_levels(cls, whole_grid, options: dict) -> np.ndarray:
        """Each element's level from its size alone (``size_levels``): over several ranks
        each rank takes its share of every level, the work being Σ 2^level."""
        return size_levels(whole_grid(), options)

    @classmethod
    def label(cls, options: dict) -> str:
        o = cls.make_options(**options)
        if o.method == MRAB3:
            return f"{cls.name} MRAB3 (started by {o.inner}) max_levels={o.max_levels}"
        return f"{cls.name} {o.table()['name']} {o.inner} max_levels={o.max_levels} substeps={o.substeps}"

    def prepare(self, x) -> None:
        """Fix the element levels from x (3, N) unless fixed (or restored) before: the
        whole grid's, the same on every rank (each rank's element rates gathered on rank 0,
        which levels them over the whole grid and hands the levels out)."""
        if self.levels is None:
            model, topology = self.model, self.model.topology
            per = model.topology.grid.np**2
            whole = topology.whole_grid()
            rates = topology.gather(np.repeat(element_rates(model.topology.grid, x.numpy(), model.g), per))
            levels = None
            if rates is not None:
                o = self.options
                levels = element_levels(whole, rates[::per], o.max_levels, o.level_margin)
            self._set_levels(topology.bcast(levels))

    def _set_levels(self, levels: ElementLevels) -> None:
        self.levels, self.n_fast = levels, None
        if self.options.method == MRAB3:
            parts = [None]  # one level: the whole grid's rhs, the global AB3 step
            if levels.count > 1:
                parts = [level_part(self.model, levels.level == k) for k in range(levels.count)]
            self.mrab = MultirateAB3(
                self.model, self.dt, parts, self.options.inner, self._comb, self._combine, self._at
            )
            return
        for a in self.S:  # a part's f writes only the nodes it touches: none left from other levels
            a.zero_()
        if levels.count == 1:
            self.split, self.single = None, _explicit(self.options.inner)(self.model, self.dt)
        else:
            self.split, self.single = LevelSplit(self.model, levels, self._comb), None

    def set_phase(self, k: int) -> None:
        super().set_phase(k)
        if self.mrab is not None:
            self.mrab.started = min(k, START_STEPS)  # the start's coarse steps taken before step k

    def carried_arrays(self) -> list:
        """MRAB3's: each level's three tendencies, the newest first (none otherwise)."""
        return [] if self.mrab is None else [a for history in self.mrab.history for a in history]

    def substeps(self) -> int:
        """Fast steps a slow step: 2^K, the finest level's, or the ``substeps`` option's
        (MRAB3: 2^K)."""
        n = "levels" if self.mrab is not None else self.options.substeps
        return 2 ** (self.levels.count - 1) if n == "levels" else n

    def describe(self) -> list[str]:
        lv = self.levels
        if lv is None:
            return []
        evals = self.element_evaluations()
        if self.mrab is not None:
            if lv.count == 1:
                return [f"{lv.describe()}: one level, so the global AB3 step (started by {self.options.inner})"]
            return [
                f"{lv.describe()}",
                f"element evaluations a coarse step {evals['local']} against {evals['global']} for a global AB3 "
                f"step at the finest step dt/{self.substeps()} ({evals['global'] / evals['local']:.2f}x; the first "
                f"{START_STEPS} coarse steps {self.options.inner} at dt/{self.substeps()})",
            ]
        if lv.count == 1:
            return [f"{lv.describe()}: one level, so the global {self.options.inner} step"]
        return [
            f"{lv.describe()}",
            f"element evaluations a coarse step {evals['local']} against {evals['global']} for a global "
            f"{self.options.inner} step at the inner step dt/{self.substeps()} ({evals['global'] / evals['local']:.2f}x)",
        ]

    def element_evaluations(self) -> dict:
        """Element tendency evaluations a coarse step: ``local`` (this stepper's: the s slow
        stages on level 0, the inner stages on the finer levels) and ``global`` (``inner``
        over every element at the inner step, Δt/n, n = ``substeps()``)."""
        lv, n = self.levels, self.substeps()
        if self.mrab is not None:  # MRAB3 once started: level k 2^k times, against AB3 at dt/2^K
            return {"local": int(np.sum(2**lv.level)), "global": n * lv.level.size}
        per = len(self._form)
        fine = int(np.sum(lv.level >= 1))
        fast = per * sum(max(1, math.ceil(d * n - 1e-9)) for d in self.tab.d)
        return {"local": len(self.tab.d) * (lv.level.size - fine) + fast * fine, "global": per * n * lv.level.size}

    def attrs(self):
        t, lv = self.options.table(), self.levels
        out = {"lts_method": t["name"], "lts_order": int(t["order"]), "lts_inner": self.options.inner}
        if lv is not None:
            out |= {
                "lts_levels": lv.count,
                "lts_elements_per_level": ", ".join(map(str, lv.elements_per_level())),
                "lts_bound": lv.bound(),
            }
        return out

    def state(self):
        """The steps and the levels: (3, nnodes) of the whole grid, row 0 each node's
        element level (rows 1, 2 zero: the shape the restart file keeps stepper arrays in;
        on rank 0, None on the others)."""
        topology = self.model.topology
        a = np.zeros((3, self.N))
        if self.levels is not None:
            a[0] = np.repeat(self.levels.level[topology.elements], self.model.topology.grid.np**2)
        out = {**Stepper.state(self), "levels": topology.gather(a)}
        if self.mrab is not None:
            out |= self.mrab.state(partial(gathered_copy, self))
        return out

    def restore(self, state):
        Stepper.restore(self, state)
        topology, held = self.model.topology, entry(self, state, "levels")
        topology.distribute(held, 3, f"{self.name} stepper state 'levels'")  # its shape checked on every rank
        level = topology.bcast(None if held is None else np.asarray(held)[0, :: self.model.topology.grid.np**2])
        level = np.asarray(level).astype(np.int64)
        self._set_levels(ElementLevels(level, int(level.max()) + 1))
        if self.mrab is not None:
            self.mrab.restore(state, partial(load_entry, self), partial(entry, self))

    def graph_key(self):
        if self.levels is None or GraphCapture.graph_key(self) is None:
            return None
        return ("step", self.mrab.phase()) if self.mrab is not None else GraphCapture.graph_key(self)

    def replayed(self, stats):
        if self.mrab is not None:
            self.mrab.replayed()
        return super().replayed(stats)

    def _fast_at(self, theta: float) -> None:
        start, span = self._solve
        self._at(start + theta * span)

    def advance(self, x):
        if self.levels is None:
            self.prepare(x)
        if self.mrab is not None:
            slow, fast = self.mrab.step(x)
            self.model.hyperviscosity(x, self.dt)
            return StepStats(slow, {"fast": fast})
        if self.single is not None:
            self.single.steps, self.single.t0 = self.steps, self.t0
            return self.single.advance(x)
        if self.n_fast is None:
            self.n_fast = self._fast_steps(self.substeps())
        evals = self._advance(x)
        self.model.hyperviscosity(x, self.dt)
        return StepStats(evals, {"fast": self.fast_evaluations()})


def size_levels(grid, options: dict) -> np.ndarray:
    """(nelem,) int: each element's level from its size alone (its rate normDinv: one wave
    speed everywhere; ``grid.levels.element_levels``) with the ``[lts]`` ``options``'
    max_levels and level_margin, on ``grid`` (the whole grid): what a partition balanced
    level by level knows before the flow (``topology.rank_parts``). ValueError names a
    bad option."""
    o = Lts.make_options(**options)
    return element_levels(grid, element_sizes(grid).norm_dinv, o.max_levels, o.level_margin).level


def level_part(model, whole: np.ndarray):
    """The ``ElementPart`` of the elements held here among ``whole`` (nelem_total,) bool,
    a part of the whole grid's elements (``ElementPart.of``, ranges merged over
    ``LAUNCH_GAP``)."""
    return ElementPart.of(model, np.flatnonzero(whole[model.topology.elements]), LAUNCH_GAP, whole)


def _explicit(name: str) -> type[Stepper]:
    """The registered explicit Runge–Kutta stepper class ``name``."""
    return next(cls for cls in explicit_steppers() if cls.name == name)
