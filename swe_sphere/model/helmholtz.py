"""The Helmholtz solve of the semi-implicit stepper, the JFNK preconditioner and the IMEX
stepper: (I − aL) z = s·r for the linear gravity-wave operator L about a mean depth H
(``model.gravity_wave.GravityWaveOperator``), inverted through its Schur complement, the
Helmholtz equation for the height (``HelmholtzSolver``), whose CG is ``helmholtz_cg``'s, started
from ``guess_history``'s projection; ``HelmholtzOptions`` are its scene options."""

from __future__ import annotations

import warnings
from contextlib import nullcontext
from dataclasses import dataclass
from types import MappingProxyType

import warp as wp

from ..core.errors import ArgumentError, StepFailure
from ..core.graphs import captured
from ..kernels import gravity_wave as gk
from ..kernels import helmholtz as hk
from ..kernels import helmholtz_cg as cgk
from .gravity_wave import GravityWaveOperator, check_mean_depth
from .guess_history import GuessHistory, HistoryWork
from .helmholtz_cg import SINGLE_FLOOR, SINGLE_TOL, HelmholtzCG
from .precision import precision_dtype

f64 = wp.float64
# the solve's words before ``[numerics] precision``'s (``precision.PRECISIONS``), each taken after a
# one-line DeprecationWarning
OLD_PRECISIONS = {"double": "float64", "mixed": "float32"}
SOLVE_PRECISIONS = ("float64", "float32")  # of ``precision.PRECISIONS``, the CG's float types
TIGHTEST = 1e-12  # the tightest relative residual ``tighten`` sets
KEPT_COEFFICIENTS = 4  # the a's whose guess histories and solve graphs a solver keeps (``_use``)
MAX_GUESS_HISTORY = (
    32  # past solutions a solve's start is projected on (``GuessHistory``); k vectors cost 2k of memory and k dots
)


def check_precision(precision: str) -> str:
    """``precision`` in ``[numerics] precision``'s words (``precision.PRECISIONS``): "float64", or
    "float32" (the CG's passes in float32, refined in float64); an old word ("double", "mixed",
    ``OLD_PRECISIONS``) as its new one, after a one-line ``DeprecationWarning``. ``ArgumentError``
    (a ValueError) 'precision must be one of float64, float32 ...' otherwise."""
    if isinstance(precision, str) and precision in OLD_PRECISIONS:
        new = OLD_PRECISIONS[precision]
        warnings.warn(f'precision "{precision}" is deprecated: "{new}", as [numerics] precision', DeprecationWarning, 3)
        precision = new
    if precision not in SOLVE_PRECISIONS:  # a solve's own words: the state's float type is not its
        raise ArgumentError(f"precision must be one of {', '.join(SOLVE_PRECISIONS)} (got {precision!r})")
    return precision


@dataclass(frozen=True)
class HelmholtzOptions:
    """The options of a Helmholtz solve (the scene tables ``[semi_implicit]``, ``[imex]``
    and an IMEX ``[tableau]`` hold them among their own): ``tol``, the CG's relative
    residual ‖r‖ ≤ tol‖b‖, in (0, 1); ``maxiter`` ≥ 1, the CG iterations a solve may take
    (past it the step fails, ``HelmholtzSolver.iterations``); ``mean_depth`` H (m, ≥ 0;
    0: the initial state's, ``model.gravity_wave.reference_depth``); ``precision`` ("float64", or
    "float32": float32 CG passes refined in float64 to ``tol``; ``check_precision``, the old
    "double" and "mixed" deprecated);
    ``guess_history`` (0..``MAX_GUESS_HISTORY``: past solutions a solve starts from the
    projection on, ``GuessHistory``; 0: from the last solution, or zero). Raises
    ValueError '<option> must ...'."""

    tol: float = 1e-6
    maxiter: int = 500
    mean_depth: float = 0.0
    precision: str = "float64"
    guess_history: int = 8

    def __post_init__(self):
        object.__setattr__(self, "precision", check_precision(self.precision))  # frozen: the word as new
        if not 0 < self.tol < 1:
            raise ValueError(f"tol must be in (0, 1) (got {self.tol})")
        if self.maxiter < 1:
            raise ValueError(f"maxiter must be >= 1 (got {self.maxiter})")
        check_mean_depth(self.mean_depth)
        if not 0 <= self.guess_history <= MAX_GUESS_HISTORY:
            raise ValueError(f"guess_history must be in 0..{MAX_GUESS_HISTORY} (got {self.guess_history})")


class HelmholtzSolver:
    """Solves of (I − aL) z = s·r for the linear gravity-wave operator L.

    With L_v = −g G h, L_h = −H D v (G = DSS∘grad and D = DSS∘div the model's own strong
    operators), (I − aL) is inverted for any a through its Schur complement, the Helmholtz
    equation for the height (HOMME ``advance_si_nonstag``; Lott, Woodward & Evans 2015 for its
    use as a preconditioner):

        (I − a²gH DG) z_h = r_h − aH D r_v,    z_v = r_v − a g G z_h.

    On unique nodes, multiplied by the assembled mass M, the Helmholtz operator is M + c K with
    K = −M D G (c = a²gH), SPD (``helmholtz_matrix``), solved by the compiled matrix-free CG
    (``helmholtz_cg.HelmholtzCG``). With one rank a solve is one graph (a CUDA graph; Warp's
    CPU graph on one CPU thread). Its iterations and a failure are counted on the device and
    read once, by ``iterations`` (a step's one host read, or, under ``Simulation.run``, a
    block's: ``Stepper.deferred``); over several ranks each inner product's per-rank sums are
    added on the host (``Topology.allreduce``). The height's area integral is set to that of
    the right-hand side after the solve (the exact solution has it, since ∫D v = 0), so a loose
    solve still keeps mass to round-off.

    Parameters: ``operator``, the ``GravityWaveOperator`` L (its model and its mean depth H,
    fixed by ``operator.set_depth``); ``options``, a ``HelmholtzOptions``: ``tol`` (relative
    residual of the CG, ‖r‖ ≤ tol‖b‖) and ``maxiter``; ``guess_history`` k > 0: start each CG
    from the projection onto past solutions (``GuessHistory``, one per a), with no product for
    its residual; ``precision``:
    "float64", or "float32" (the CG in float32, ``HelmholtzCG``, refined in float64
    to ``tol``, ``_refined``; float32 alone for a tol it reaches, as the JFNK
    preconditioner's 1e-2). On the CPU the float32 product is no faster than the
    float64 one (it is bound by its gathers, not its bytes:
    ``benchmarks/micro/step/roofline.py helmholtz_roofline``), so "float64" is every stepper's default. ``warm``:
    with k = 0, start each CG from the last solution (for a sequence of similar solves, as
    the semi-implicit steps), else from zero.

    ``solve(r, a, z, scale)``: z = (I − aL)⁻¹ (scale·r), enqueued on the device with nothing read
    back (with one rank a graph per (r, z, a, scale, H), captured on its first call:
    a CUDA graph, or Warp's CPU graph on one CPU thread; inline while a caller
    captures). ``iterations()``: the CG iterations of the solves since its last call
    — one host read — raising
    ``StepFailure`` when one of them did not reach ``tol`` within ``maxiter`` (the
    steppers call it once a step, JFNK once a GMRES solve).
    """

    def __init__(self, operator: GravityWaveOperator, options: HelmholtzOptions, warm: bool = False):
        self.operator = operator
        self.model = model = operator.model
        self.tol, self.maxiter, self.warm = float(options.tol), int(options.maxiter), bool(warm)
        dtype = precision_dtype(options.precision)
        dev, N, nu = model.topology.device, model.topology.N, model.topology.nunique
        self.Gh, self.Dv = wp.zeros((2, N), dtype=f64, device=dev), wp.zeros((1, N), dtype=f64, device=dev)
        self.b, self.y = wp.zeros(nu, dtype=f64, device=dev), wp.zeros(nu, dtype=f64, device=dev)
        self.stats = wp.zeros(
            3, dtype=f64, device=dev
        )  # iterations, failures, the first failure's residual (cgk.ITERATIONS …)
        self.cg = HelmholtzCG(model, f64, self.b, self.y, self.stats)
        self.low = None if dtype is f64 else HelmholtzCG(model, dtype, stats=self.stats)
        rec = model.launches.record
        self._shift = rec(cgk.add_mean_difference, nu, [self.y, self.cg.sums, f64(model.topology.total_area)])
        if self.low is not None:  # the refinement's conversions between the two solves and its test
            self._narrow = rec(cgk.converted(wp.float32), nu, [self.b, self.low.b])
            self._narrow_r = rec(cgk.converted(wp.float32), nu, [self.cg.r, self.low.b])
            self._widen = rec(cgk.add_converted, nu, [self.y, self.low.y])
            cg, low = self.cg, self.low
            self._check_first, self._check_next = (
                wp.launch(
                    cgk.refine_check,
                    1,
                    [
                        cg.sums,
                        first,
                        f64(self.tol**2),
                        self.maxiter,
                        cg.cs,
                        cg.ic,
                        low.cs,
                        low.ic,
                        f64(SINGLE_FLOOR**2),
                        self.stats,
                    ],
                    device=dev,
                    record_cmd=True,
                )
                for first in (1, 0)
            )
        # with one rank a solve is one graph per (r, z, a, scale, H), its loops conditional nodes
        # (``graphable``; so may a caller's graph hold it: a stepper's whole step): a CUDA
        # graph, or on one CPU thread Warp's CPU graph (the same bits, and no Python per launch:
        # the benchmarks notebook (git show 5fa9286:benchmarks/README.md), "Measurements behind the code"). Not over several CPU threads (``SplitLaunch`` is a Python pool), nor
        # with a CUDA driver below 12.4 (no conditional nodes: host loops, a read an iteration).
        self._graphs: dict[tuple, object] = {}
        self._uses: dict[tuple, int] = {}  # the calls of each graph key (``_run``)
        self._schur_launches: dict[tuple, tuple] = {}
        self.graphable = not model.topology.distributed and model.topology.backend.solver_graphs(model.launches.threads)
        # with ``history`` k > 0, the start of each solve: a GuessHistory per a (the basis is A's),
        # shared by a step's stages of one a (IMEX ARS's all): their span holds the last stage's
        # solution, today's warm start (TC5 ne8 ARS(3,4,3) @ 8 dt_g, CG iterations a solve:
        # 18.2 warm, per stage 19.5-19.7 with k = 2..8, shared 17.9 / 17.3 / 16.3 with k = 2 / 4 / 8)
        self.history = int(options.guess_history)
        self._histories: dict[float, GuessHistory] = {}
        self._history = None
        self._recent: dict[float, None] = {}  # the a's solved with, least recently used first (``_use``)
        self._saving = None  # ``checkpoint``'s, while a step may be rejected
        self._saved_y, self._spares = None, []  # the arrays checkpoints copy into, made once
        if self.history:
            self.history_work = HistoryWork(
                y0=wp.zeros(nu, dtype=f64, device=dev),
                w0=wp.zeros(nu, dtype=f64, device=dev),
                partial=wp.zeros((self.history + 4, self.cg.partial.shape[1]), dtype=f64, device=dev),
                alpha=wp.zeros(self.history, dtype=f64, device=dev),
                sums=wp.zeros(self.history + 4, dtype=f64, device=dev),
            )

    @property
    def H(self) -> float:
        """The operator's mean depth H (m; 0 until fixed)."""
        return self.operator.H

    @property
    def histories(self) -> MappingProxyType:
        """The guess histories (``GuessHistory``) kept, by the key of their sequence of solves
        (``solve``'s a, in s; ``solve_height``'s ``history``), read-only: empty with
        ``guess_history`` 0; at most ``KEPT_COEFFICIENTS`` a's, the least recently used
        dropped first (``_use``)."""
        return MappingProxyType(self._histories)

    @property
    def graph_count(self) -> int:
        """The solve graphs this solver holds: one per (r, z, a, scale, H) captured (0 where not
        ``graphable``)."""
        return len(self._graphs)

    # -- what carries over between solves (for bitwise restarts) ----------------------
    def state(self) -> dict:
        """The mean depth (0 until fixed); with ``history``, each sequence's basis, least
        recently used first (``helmholtz_histories`` of them: its a, its vectors in use and X,
        AX packed three a (3, N) array, element-local as a state); with ``warm`` the last
        solution (where a new sequence starts): a height, stored element-local in row 2 of a
        (3, N) array like a state."""
        s = {"mean_depth": self.H}
        if self.history:
            s["helmholtz_histories"] = len(self._histories)
            for n, (a, h) in enumerate(self._histories.items()):
                s |= {f"helmholtz_history{n}_a": a, f"helmholtz_history{n}_count": h.count()}
                s |= {f"helmholtz_history{n}_{m}": whole for m, whole in enumerate(h.whole())}
        if self.warm:  # whole-grid, gathered from every rank on rank 0 (call on all)
            topo = self.model.topology
            guess = wp.zeros((3, self.model.topology.N), dtype=f64, device=self.model.topology.device)
            for launch in topo.scatter(self.y, guess, 2):
                launch.launch()
            s["helmholtz_guess"] = topo.gather(guess.numpy())
        return s

    def restore(self, state: dict, entry) -> None:
        """Set what ``state()`` returned; ``entry(state, key)`` raises ValueError for a missing key."""
        self.operator.H = float(entry(state, "mean_depth"))
        if self.history:
            # in place: the solves' graphs (``_run``) hold the bases' arrays; a sequence the
            # state does not name is dropped, as it would not be there
            named = []
            for n in range(int(entry(state, "helmholtz_histories"))):
                a = float(entry(state, f"helmholtz_history{n}_a"))
                h = self._histories.get(a) or self._histories.setdefault(a, GuessHistory(self))
                h.set(
                    int(entry(state, f"helmholtz_history{n}_count")),
                    [entry(state, f"helmholtz_history{n}_{m}") for m in range(h.arrays)],
                    f"stepper state 'helmholtz_history{n}'",
                )
                named.append(a)
            for a in [a for a in self._histories if a not in named]:
                self._drop(a)
            self._histories = {a: self._histories[a] for a in named}
            self._recent = dict.fromkeys(named)
        if self.warm and (not self.history or "helmholtz_guess" in state):  # a history's: since 2026-11-26
            topo = self.model.topology
            guess = topo.distribute(
                entry(state, "helmholtz_guess"), 3, "stepper state 'helmholtz_guess'"
            )  # on rank 0 only when several ranks
            self.y.assign(guess[2][topo.first.numpy()])

    # -- the Schur complement (element-local) -------------------------------------------
    def solve(self, r, a: float, z, scale: float = 1.0, implicit=None) -> None:
        """z = (I − aL)⁻¹ (scale·r) through the Helmholtz equation; z may alias r. ``implicit``
        (a (3, N) array, may alias r, not z): also L z = (z − scale·r)/a, written by the
        back-substitution's pass (an IMEX stage's implicit tendency; the bits of
        ``blas.axpby(1/a, z, −scale/a, r)``). Nothing is read back: the iterations and a
        failure are counted on the device (``iterations``). With ``history``, the CG starts
        from the projection onto the past solutions of the solves with the same a
        (``GuessHistory``)."""
        a = float(a)
        tape = self.model.recorder  # a gradient's tape (``SteppingModel.recorder``): the solve written on it
        with nullcontext(True) if tape is None else tape.solving(self, r, a, z, scale, implicit) as run:
            if run:
                self._use(a)
                self._history = self._guesses(a)
                lz = None if implicit is None else implicit.ptr
                self._run(("solve", r.ptr, z.ptr, lz, a, scale, self.H), self._solve, r, a, z, scale, implicit)

    def _guesses(self, key):
        """The ``GuessHistory`` of the solves under ``key`` (made on first use), or None: no
        key, ``guess_history`` 0, or the one float32 solve from zero."""
        if key is None or not self.history or (self.low is not None and self.tol >= SINGLE_TOL):
            return None
        history = self._histories.get(key)
        made = history is None
        if made:
            history = self._histories[key] = GuessHistory(self)
        saving = self._saving
        if saving is not None and key not in saving["histories"]:  # copied before its solve changes it
            saving["histories"][key] = None if made else history.snapshot(self._spare(len(saving["histories"])))
        return history

    def _spare(self, n: int) -> tuple:
        """The n-th set of arrays a checkpoint copies a guess history into: made once, reused
        by every later checkpoint (one is open at a time; a try touches one a's history)."""
        while len(self._spares) <= n:
            self._spares.append(next(iter(self._histories.values())).spare())
        return self._spares[n]

    def _solve(self, r, a: float, z, scale: float, implicit=None) -> None:
        m = self.model
        if m.operators.per_element:  # the CPU's layout: two fused passes each side of the CG (_schur)
            rhs, back = self._schur(r, z, implicit)
            for launch, values in (
                (rhs[0], {"s": scale, "aH": a * self.H}),
                (back[-1], {"s": scale, "ag": a * m.g, "ia": 1.0 / a, "mis": -scale / a}),
            ):
                for name, value in values.items():
                    launch.set_param_by_name(name, f64(value))
            for launch in rhs:
                launch.launch()
            self._pcg(a * a * m.g * self.H)
            for launch in back:
                launch.launch()
            return
        m.operators.divergence(r, self.Dv)
        m.pointwise(gk.schur_height, r, self.Dv, f64(scale), f64(a * self.H), z)
        m.operators.assemble(z, 2, self.b)
        self._pcg(a * a * m.g * self.H)
        m.operators.scatter(self.y, z, 2)
        m.operators.gradient(z, 2, self.Gh)
        if implicit is None:
            m.pointwise(gk.schur_wind, r, self.Gh, f64(scale), f64(a * m.g), z)
        else:
            m.pointwise(
                gk.schur_wind_implicit, r, self.Gh, f64(scale), f64(a * m.g), z, f64(1.0 / a), f64(-scale / a), implicit
            )

    def _schur(self, r, z, implicit=None) -> tuple[list, list]:
        """The per-element layout's launches around the CG, recorded once per (r, z): the right-hand
        side b = Pᵀ W s (r_h − aH D̂ r_v) (``helmholtz_rhs``, ``helmholtz_assemble``), and the
        back-substitution z = (s·r_v − ag G y, P y) (``helmholtz_gradient``,
        ``helmholtz_back_substitution``, with ``implicit`` also L z) — four passes where the per-node
        form takes seven — in the float64 CG's work arrays; ``_solve`` sets s, aH, ag, ia and mis."""
        key = (r.ptr, z.ptr, None if implicit is None else implicit.ptr)
        launches = self._schur_launches.get(key)
        if launches is None:
            m, topo, cg = self.model, self.model.topology, self.cg
            rows, np_, halo, rec = m.operators.as_rows, m.topology.grid.np, topo.owned.recv_buffer, m.launches.record
            elements = dict(nodes_per_index=np_**2)
            rhs = [
                rec(
                    hk.helmholtz_rhs(np_),
                    m.topology.grid.nelem,
                    [
                        rows(r),
                        rows(cg.Dinv),
                        rows(cg.metdet),
                        rows(cg.spheremp),
                        cg.dvv,
                        f64(0.0),
                        f64(0.0),
                        rows(cg.z),
                    ],
                    **elements,
                ),
                *topo.exchange(cg.z),
                rec(
                    hk.helmholtz_assemble(topo.table.shape[1]),
                    cg.partial.shape[1],
                    [cg.z, topo.ghost, topo.N, topo.table, topo.first, self.y, self.b, cg.partial, cg.chunk],
                    nodes_per_index=cg.chunk,
                ),
            ]
            back = [
                *topo.exchange(self.y.reshape((1, topo.nunique)), unique=True),
                rec(
                    hk.helmholtz_gradient(np_),
                    m.topology.grid.nelem,
                    [self.y, halo, topo.gid, rows(cg.Dinv), rows(cg.spheremp), cg.dvv, rows(cg.wg)],
                    **elements,
                ),
                *topo.exchange(cg.wg),
                rec(
                    hk.helmholtz_back_substitution(np_, topo.table.shape[1], implicit is not None),
                    m.topology.grid.nelem,
                    [
                        cg.wg,
                        topo.ghost,
                        topo.N,
                        topo.table,
                        cg.rspheremp,
                        self.y,
                        halo,
                        topo.gid,
                        rows(r),
                        f64(0.0),
                        f64(0.0),
                        rows(z),
                        f64(0.0),
                        f64(0.0),
                        rows(z if implicit is None else implicit),
                    ],
                    **elements,
                ),
            ]
            launches = self._schur_launches[key] = (rhs, back)
        return launches

    def tighten(self, tol: float) -> None:
        """The CG's relative residual at most ``tol``, not below ``TIGHTEST`` (float64's reach
        on these systems); the graphs, which hold the old one, dropped."""
        self.tol = min(self.tol, max(float(tol), TIGHTEST))
        self._graphs.clear()

    def _use(self, a: float) -> None:
        """a's guess history and solve graphs made the most recently used; those of the least
        recently used other a's dropped past ``KEPT_COEFFICIENTS`` (a basis is its A's; a
        controlled run's Δt returns to a few values of its grid, ``integrator.control.on_grid``,
        and finds their bases and graphs again)."""
        if a in self._histories:
            self._histories[a] = self._histories.pop(a)
        self._recent[a] = self._recent.pop(a, None)
        while len(self._recent) > KEPT_COEFFICIENTS:
            self._drop(next(iter(self._recent)))

    def _drop(self, a: float) -> None:
        """Forget a's guess history and its solve graphs (which hold the history's arrays);
        kept aside while a checkpoint is open (``rollback`` brings them back)."""
        graphs = {key: g for key, g in self._graphs.items() if key[0] == "solve" and key[4] == a}
        dropped = (self._histories.pop(a, None), graphs)
        self._recent.pop(a, None)
        self._graphs = {key: g for key, g in self._graphs.items() if key not in graphs}
        self._uses = {key: n for key, n in self._uses.items() if key[0] != "solve" or key[4] != a}
        if self._saving is not None and a in self._saving["recent"]:
            self._saving["dropped"].setdefault(a, dropped)

    # -- a rejected step's rollback (``TrialSteps.checkpoint``) ---------------------------
    def checkpoint(self) -> dict:
        """What ``rollback`` needs to put the solver back as it is now: the mean depth, the
        last solution, the a's held in their order; a guess history is copied on the device
        the first time a solve uses it after (``_guesses``): nothing read back, and into
        arrays made once (``_spare``), so the time loop allocates nothing."""
        if self._saved_y is None:
            self._saved_y = wp.empty_like(self.y)
        wp.copy(self._saved_y, self.y)
        self._saving = {"H": self.H, "y": self._saved_y, "recent": list(self._recent)}
        self._saving |= {"histories": {}, "dropped": {}}
        return self._saving

    @property
    def checkpointed(self) -> bool:
        """Whether a ``checkpoint`` has been taken (its copies made as the solves go)."""
        return self._saving is not None

    def rollback(self, saving: dict) -> None:
        """Put back what ``checkpoint`` saved: the histories made since dropped, those dropped
        since brought back, the copies put back in place; the checkpoint ends."""
        self._saving = None
        self.operator.H = saving["H"]
        wp.copy(self.y, saving["y"])
        for a in [a for a in self._recent if a not in saving["recent"]]:
            self._drop(a)
        for a, (history, graphs) in saving["dropped"].items():
            if history is not None:
                self._histories[a] = history
            self._graphs |= graphs
        for a, snap in saving["histories"].items():
            if snap is None:
                self._histories.pop(a, None)
            else:
                self._histories[a].put_back(snap)
        self._recent = dict.fromkeys(saving["recent"])
        self._histories = {a: self._histories[a] for a in [*self._recent, *self._histories] if a in self._histories}

    def _run(self, key: tuple, fn, *args) -> None:
        """fn(*args) as a graph captured on the second call per ``key`` (the launch
        parameters it bakes in; the first runs inline) and replayed after, where ``graphable`` and the model's
        ``launches.guard`` allows (``graphs.captured``: a failure falls back with one line);
        inline while a caller captures and otherwise (the loops host loops testing the
        device flag)."""
        uses = self._uses[key] = self._uses.get(key, 0) + 1
        # captured from its second call on: a controlled run's Δt that is used once (and a fresh
        # history's first solve, another sequence of launches) costs no capture (ark324 at ne16:
        # 5 ms, a third of a step)
        if not self.graphable or uses < 2 or (self._history is not None and self._history.fresh):
            fn(*args)
            return
        captured(
            self._graphs,
            key,
            lambda: fn(*args),
            self.model.topology.device,
            self.model.launches.guard,
            "the Helmholtz solve",
        )

    def iterations(self) -> int:
        """The CG iterations of the solves since the last call (float32 ones counted alike),
        then zeroed: the one host read (and synchronisation) of the solves. Raises
        ``StepFailure`` if one of them did not reach ``tol`` within ``maxiter``."""
        its, failures, residual = self.stats.numpy()
        self.stats.zero_()
        if failures:
            raise StepFailure(
                f"Helmholtz CG did not converge in {self.maxiter} iterations (residual {residual:.3e} > {self.tol:.3e}; {int(failures)} of the solves since the last check)"
            )
        return int(its)

    # -- the Helmholtz solve on unique nodes, (M + cK) y = b: any device, threads and ranks --
    def apply(self, y, out, c: float) -> None:
        """out = (M + cK) y in float64 (``HelmholtzCG.apply``): the Helmholtz operator on
        unique-node vectors y, out (``nunique``,), y a height (m), out in m³ (M the assembled
        mass, m²); c = a²gH (m²) and K = −M D G the SPD stiffness (``helmholtz_matrix``)."""
        self.cg.apply(y, out, c)

    def solve_height(self, c: float, history: float | None = None) -> None:
        """The Helmholtz equation alone, (M + cK) y = b on unique nodes (``apply``'s), the
        right-hand side in ``b`` and the solution into ``y`` (both (``nunique``,) float64: m³,
        m), as ``solve`` solves it between its two Schur passes: to ``tol``, its area integral
        then set to b's, its iterations and a failure counted on the device (``iterations``),
        nothing read back and no graph. ``history``: the key of the sequence of solves
        (``histories``; ``solve`` uses its a) whose ``GuessHistory`` starts the CG and keeps
        this solution, with ``guess_history`` > 0; None: from zero, or from y with ``warm``."""
        self._history = self._guesses(history)
        self._pcg(c)

    def _pcg(self, c: float) -> None:
        """(M + cK) y = b to the relative residual ``tol`` in float64 (``precision``
        "float64"), or in float32 with float64 refinement ("float32"); then the area
        integral of y set to that of b (on the device). Iterations into ``stats``."""
        h = self._history
        fresh = h is not None and h.fresh  # no basis yet: from the last solution (warm), not from zero
        if h is not None and not fresh:
            h.guess()
        if self.low is None:
            self.cg.solve(c, self.tol, self.maxiter, self.warm, guessed=h is not None and not fresh)
        else:
            self._refined(c)
        if h is not None:
            h.store(fresh)
        self.cg.dots(self.b, self.cg.ones, self.cg.area, self.y, self.b, self.b)  # ∫z_h = ∫(right-hand side)
        self._shift.launch()

    def _refined(self, c: float) -> None:
        """Iterative refinement (Wilkinson; Carson & Higham 2018, SIAM J. Sci. Comput. 40,
        A817): r = b − Ay in float64, A e = r by the float32 CG from zero, y += e, until
        ‖r‖ ≤ tol‖b‖ (``refine_check`` on the device; the loop ``wp.capture_while``). A
        tolerance float32 reaches alone (≥ ``SINGLE_TOL``, the JFNK preconditioner's 1e-2)
        takes one float32 solve and no float64 product."""
        cg, low, y = self.cg, self.low, self.y
        if not self.warm:
            y.zero_()
        if self.tol >= SINGLE_TOL:  # one solve, from zero: y = e
            self._narrow.launch()  # low.b = b
            low.solve(c, self.tol, self.maxiter, False)
            y.zero_()
            self._widen.launch()
            return
        cg.residual(c)  # cg.r = b − Ay, and b·b
        self._check_first.launch()
        wp.capture_while(cg.go, self._refinement, c=c)

    def _refinement(self, c: float) -> None:
        """One pass: e from A e = r in float32 to max(tol‖b‖, SINGLE_FLOOR‖r‖) within the
        iterations left (both set by ``refine_check``), y += e, the new residual and its test."""
        self._narrow_r.launch()  # low.b = r
        self.low.solve(c, 0.0, 0, False)
        self._widen.launch()  # y += e
        self.cg.residual(c)
        self._check_next.launch()
