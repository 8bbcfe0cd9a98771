"""The Helmholtz solve of the semi-implicit stepper, the JFNK preconditioner and the
IMEX stepper: (I − aL) z = s·r for the linear gravity-wave operator

    L_v = −g G h,    L_h = −H D v

about a mean depth H (``model.gravity_wave.GravityWaveOperator``, G = DSS∘grad and
D = DSS∘div the model's own strong operators). ``HelmholtzSolver.solve``
inverts (I − aL) for any a through its Schur complement, the Helmholtz
equation for the height (HOMME ``advance_si_nonstag``; Lott, Woodward &
Evans 2015 for its use as a preconditioner):

    (I − a²gH DG) z_h = r_h − aH D r_v,    z_v = r_v − a g G z_h.

On unique nodes, multiplied by the assembled mass M, the Helmholtz operator
is M + c K with K = −M D G (c = a²gH): K is symmetric positive
semi-definite (the SE divergence and gradient are adjoint under the GLL
quadrature; Taylor & Fournier 2010), K·1 = 0, so M + cK is SPD.
``helmholtz_matrix`` assembles K once per grid as a scipy sparse matrix by
probing the model's element kernels (it is the matrix-free operator, to
round-off; the tests' check of the operators and of a solve). The solve is the
compiled matrix-free CG of ``kernels.helmholtz`` (Chronopoulos–Gear, one
reduction an iteration, mass preconditioner), vectors in Warp arrays, the
operator in three element launches split over the CPU threads (per node on
CUDA); the same code on CPU, CUDA and any number of MPI ranks. The solve runs
on the device with no host read: its scalar recurrences, convergence test and
loop (``wp.capture_while``), the refinement of "mixed" precision and the area
shift; with one rank a solve is one graph (a CUDA graph; Warp's CPU graph on one
CPU thread). Its iterations and a failure are counted on the device and read
once, by ``HelmholtzSolver.iterations`` (a step's one host read, or, under
``Simulation.run``, a block's: ``Stepper.deferred``); over several ranks
each inner product's per-rank sums are added on the host (``Topology.allreduce``).
The operator's bits depend on neither threads nor ranks (its DSS is a gather in
the global order), so a run on N ranks differs from one on one rank only by the
order of the inner products' sums.

Why no other solver (TC5 ne30, ``benchmarks/implicit_cost.py``): scipy's CG on the
assembled K was 15 % cheaper a step on one thread but dearer on two, runs on one rank
only, and a solver chosen by the thread count would change a run's bits with it; CG
with a pyamg V-cycle, the preconditioners of ``benchmarks/helmholtz_preconditioners.py``
and K as a Warp CSR or ``warp.sparse`` matrix (2.8–3.8× the matrix-free product's time)
were dearer.

The height's area integral is set to that of the right-hand side after the
solve (the exact solution has it, since ∫D v = 0), so a loose solve still
keeps mass to round-off.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
import warp as wp

from ..core.errors import StepFailure
from ..core.graphs import captured
from ..kernels import gravity_wave as gk
from ..kernels import helmholtz as hk
from ..kernels import operators
from ..model.gravity_wave import GravityWaveOperator, check_mean_depth
from ..model.shallow_water import ShallowWater

if TYPE_CHECKING:
    import scipy.sparse as sp

f64 = wp.float64
PRECISIONS = ("double", "mixed")
MAX_GUESS_HISTORY = (
    32  # past solutions a solve's start is projected on (``GuessHistory``); k vectors cost 2k of memory and k dots
)


def check_precision(precision: str) -> None:
    """ValueError 'precision must ...' unless one of ``PRECISIONS``."""
    if precision not in PRECISIONS:
        raise ValueError(f"precision must be one of {', '.join(PRECISIONS)} (got {precision!r})")


@dataclass(frozen=True)
class HelmholtzOptions:
    """The options of a Helmholtz solve (the scene tables ``[semi_implicit]``, ``[imex]``
    and an IMEX ``[tableau]`` hold them among their own): ``tol``, the CG's relative
    residual ‖r‖ ≤ tol‖b‖, in (0, 1); ``maxiter`` ≥ 1, the CG iterations a solve may take
    (past it the step fails, ``HelmholtzSolver.iterations``); ``mean_depth`` H (m, ≥ 0;
    0: the initial state's, ``model.gravity_wave.reference_depth``); ``precision`` (one of
    ``PRECISIONS``: "double", or "mixed", float32 CG passes refined in float64 to ``tol``);
    ``guess_history`` (0..``MAX_GUESS_HISTORY``: past solutions a solve starts from the
    projection on, ``GuessHistory``; 0: from the last solution, or zero). Raises
    ValueError '<option> must ...'."""

    tol: float = 1e-6
    maxiter: int = 500
    mean_depth: float = 0.0
    precision: str = "double"
    guess_history: int = 8

    def __post_init__(self):
        check_precision(self.precision)
        if not 0 < self.tol < 1:
            raise ValueError(f"tol must be in (0, 1) (got {self.tol})")
        if self.maxiter < 1:
            raise ValueError(f"maxiter must be >= 1 (got {self.maxiter})")
        check_mean_depth(self.mean_depth)
        if not 0 <= self.guess_history <= MAX_GUESS_HISTORY:
            raise ValueError(f"guess_history must be in 0..{MAX_GUESS_HISTORY} (got {self.guess_history})")


class HistoryWork(NamedTuple):
    """The work arrays a solver's ``GuessHistory``s share: the solve's start y0 and its
    product w0 (nunique,), the partial sums (k + 4, chunks), the projection's coefficients
    (k,) and the increment's sums (k + 4,)."""

    y0: wp.array
    w0: wp.array
    partial: wp.array
    alpha: wp.array
    sums: wp.array


def element_gradient(model: ShallowWater) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """(Ĝ, P): the element gradient Ĝ (2N × N, 1/m: (u, v) components of each element's own
    gradient, before the DSS) and the scatter P (N × nunique, ones: unique → element-local copies).

    Ĝ comes from np² probes of ``model.gradient``, which leaves the element-local result in
    ``model.vec_work``: a unit value at one local node of every element gives a column of every
    element's matrix exactly. The whole grid on one process.
    """
    import scipy.sparse as sp  # here, as in helmholtz_matrix: a run needs no sparse matrix

    grid, N = model.grid, model.N
    npp = grid.np**2
    base = np.arange(grid.nelem) * npp
    x = wp.zeros((3, N), dtype=f64, device=model.device)
    G2 = wp.zeros((2, N), dtype=f64, device=model.device)
    nodes = np.arange(N)  # element-major: the rows of element e are e·np² … (e+1)·np² − 1
    rows, cols, vals = [], [], []
    unit = np.zeros((3, N))
    for k in range(npp):
        unit[2] = 0.0
        unit[2, base + k] = 1.0
        x.assign(unit)
        model.gradient(x, 2, G2)
        g = model.vec_work.numpy()
        for c in range(2):
            rows.append(c * N + nodes), cols.append(np.repeat(base + k, npp)), vals.append(g[c].copy())
    G_hat = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(2 * N, N))
    G_hat.eliminate_zeros()
    return G_hat, sp.csr_matrix((np.ones(N), (nodes, grid.gid)), shape=(N, grid.nunique))


def helmholtz_matrix(model: ShallowWater) -> sp.csr_matrix:
    """K = −M D G (nunique × nunique, dimensionless: M in m², D G in m⁻²) on unique nodes, symmetrised (its asymmetry is round-off, ~1e-15 relative).

    Built from the model's own element kernels: Ĝ and P from ``element_gradient``, and the
    element divergence D̂ from 2np² probes of ``model.divergence`` (its element-local result is
    left in ``model.scalar``); with W = diag(spheremp) and the DSS S = P M⁻¹ Pᵀ W,
    K = −Pᵀ W D̂ S Ĝ P. The whole grid on one process (the host solvers').
    """
    # here, not at the top: scipy.sparse costs every command's start 0.1 s of CPU, and only
    # the tests and benchmarks assemble K
    import scipy.sparse as sp

    grid, N = model.grid, model.N
    npp = grid.np**2
    base = np.arange(grid.nelem) * npp
    G_hat, P = element_gradient(model)
    x = wp.zeros((3, N), dtype=f64, device=model.device)
    D1 = wp.zeros((1, N), dtype=f64, device=model.device)
    nodes = np.arange(N)
    drow, dcol, dval = [], [], []
    unit = np.zeros((3, N))
    for k in range(npp):
        col = np.repeat(base + k, npp)  # the probed column of each row's element
        for c in range(2):
            unit[:] = 0.0
            unit[c, base + k] = 1.0
            x.assign(unit)
            model.divergence(x, D1)
            drow.append(nodes), dcol.append(c * N + col), dval.append(model.scalar.numpy()[0].copy())
    D_hat = sp.csr_matrix((np.concatenate(dval), (np.concatenate(drow), np.concatenate(dcol))), shape=(N, 2 * N))
    D_hat.eliminate_zeros()
    PtW = (P.T @ sp.diags(grid.spheremp)).tocsr()
    inv_area = sp.diags(np.tile(1.0 / grid.area, 2))
    G = inv_area @ sp.block_diag((PtW, PtW)) @ G_hat @ P  # (2 nunique, nunique): DSS'd gradient on unique nodes
    K = -(PtW @ D_hat @ sp.block_diag((P, P)) @ G)
    K = ((K + K.T) * 0.5).tocsr()
    K.eliminate_zeros()
    return K


class HelmholtzSolver:
    """Solves of (I − aL) z = s·r for the linear gravity-wave operator L.

    Parameters: ``operator``, the ``GravityWaveOperator`` L (its model and its mean depth H,
    fixed by ``operator.set_depth``); ``options``, a ``HelmholtzOptions``: ``tol`` (relative
    residual of the CG, ‖r‖ ≤ tol‖b‖) and ``maxiter``; ``guess_history`` k > 0: start each CG
    from the projection onto past solutions (``GuessHistory``, one per a), with no product for
    its residual; ``precision``:
    "double", or "mixed" (the CG in float32, ``HelmholtzCG``, refined in float64
    to ``tol``, ``_refined``; float32 alone for a tol it reaches, as the JFNK
    preconditioner's 1e-2). On the CPU the float32 product is no faster than the
    float64 one (it is bound by its gathers, not its bytes:
    ``benchmarks/helmholtz_roofline.py``), so "double" is every stepper's default. ``warm``:
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
        precision = options.precision
        dev, N, nu = model.device, model.N, model.topology.nunique
        self.Gh, self.Dv = wp.zeros((2, N), dtype=f64, device=dev), wp.zeros((1, N), dtype=f64, device=dev)
        self.b, self.y = wp.zeros(nu, dtype=f64, device=dev), wp.zeros(nu, dtype=f64, device=dev)
        self.stats = wp.zeros(
            3, dtype=f64, device=dev
        )  # iterations, failures, the first failure's residual (hk.ITERATIONS …)
        self.cg = HelmholtzCG(model, f64, self.b, self.y, self.stats)
        self.low = None if precision == "double" else HelmholtzCG(model, wp.float32, stats=self.stats)
        rec = model.launches.record
        self._shift = rec(hk.add_mean_difference, nu, [self.y, self.cg.sums, f64(model.topology.total_area)])
        if self.low is not None:  # the refinement's conversions between the two solves and its test
            self._narrow = rec(hk.converted(wp.float32), nu, [self.b, self.low.b])
            self._narrow_r = rec(hk.converted(wp.float32), nu, [self.cg.r, self.low.b])
            self._widen = rec(hk.add_converted, nu, [self.y, self.low.y])
            cg, low = self.cg, self.low
            self._check_first, self._check_next = (
                wp.launch(
                    hk.refine_check,
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
        # benchmarks/README.md, "Measurements behind the code"). Not over several CPU threads (``SplitLaunch`` is a Python pool), nor
        # with a CUDA driver below 12.4 (no conditional nodes: host loops, a read an iteration).
        self._graphs: dict[tuple, object] = {}
        self._schur_launches: dict[tuple, tuple] = {}
        self.graphable = not model.topology.distributed and model.topology.backend.solver_graphs(model.threads)
        # with ``history`` k > 0, the start of each solve: a GuessHistory per a (the basis is A's),
        # shared by a step's stages of one a (IMEX ARS's all): their span holds the last stage's
        # solution, today's warm start (TC5 ne8 ARS(3,4,3) @ 8 dt_g, CG iterations a solve:
        # 18.2 warm, per stage 19.5-19.7 with k = 2..8, shared 17.9 / 17.3 / 16.3 with k = 2 / 4 / 8)
        self.history = int(options.guess_history)
        self._histories: dict[float, GuessHistory] = {}
        self._history = None
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

    # -- what carries over between solves (for bitwise restarts) ----------------------
    def state(self) -> dict:
        """The mean depth (0 until fixed) and, with ``history``, each sequence's basis
        (``helmholtz_histories`` of them: its a, its vectors in use and X, AX packed three
        a (3, N) array, element-local as a state), else with ``warm`` the last solution: a
        height, stored element-local in row 2 of a (3, N) array like a state."""
        s = {"mean_depth": self.H}
        if self.history:
            s["helmholtz_histories"] = len(self._histories)
            for n, (a, h) in enumerate(self._histories.items()):
                s |= {f"helmholtz_history{n}_a": a, f"helmholtz_history{n}_count": h.count()}
                s |= {f"helmholtz_history{n}_{m}": whole for m, whole in enumerate(h.whole())}
        elif self.warm:  # whole-grid, gathered from every rank on rank 0 (call on all)
            topo = self.model.topology
            guess = wp.zeros((3, self.model.N), dtype=f64, device=self.model.device)
            for launch in topo.scatter(self.y, guess, 2):
                launch.launch()
            s["helmholtz_guess"] = topo.gather(guess.numpy())
        return s

    def restore(self, state: dict, entry) -> None:
        """Set what ``state()`` returned; ``entry(state, key)`` raises ValueError for a missing key."""
        self.operator.H = float(entry(state, "mean_depth"))
        if self.history:
            # in place: the solves' graphs (``_run``) hold the bases' arrays; a sequence the
            # state does not name starts empty, as a new one would
            named = set()
            for n in range(int(entry(state, "helmholtz_histories"))):
                a = float(entry(state, f"helmholtz_history{n}_a"))
                h = self._histories.get(a) or self._histories.setdefault(a, GuessHistory(self))
                h.set(
                    int(entry(state, f"helmholtz_history{n}_count")),
                    [entry(state, f"helmholtz_history{n}_{m}") for m in range(h.arrays)],
                    f"stepper state 'helmholtz_history{n}'",
                )
                named.add(a)
            for a, h in self._histories.items():
                if a not in named:
                    h.hic.zero_()
        elif self.warm:
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
        self._history = None
        if self.history and not (
            self.low is not None and self.tol >= SINGLE_TOL
        ):  # not the one float32 solve from zero
            self._history = self._histories.get(a)
            if self._history is None:
                self._history = self._histories[a] = GuessHistory(self)
        lz = None if implicit is None else implicit.ptr
        self._run(("solve", r.ptr, z.ptr, lz, a, scale, self.H), self._solve, r, a, z, scale, implicit)

    def _solve(self, r, a: float, z, scale: float, implicit=None) -> None:
        m = self.model
        if m.per_element:  # the CPU's layout: two fused passes each side of the CG (_schur)
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
        m.divergence(r, self.Dv)
        m.pointwise(gk.schur_height, r, self.Dv, f64(scale), f64(a * self.H), z)
        m.assemble(z, 2, self.b)
        self._pcg(a * a * m.g * self.H)
        m.scatter(self.y, z, 2)
        m.gradient(z, 2, self.Gh)
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
            rows, np_, halo, rec = m.as_rows, m.grid.np, topo.owned.recv_buffer, m.launches.record
            elements = dict(nodes_per_index=np_**2)
            rhs = [
                rec(
                    hk.helmholtz_rhs(np_),
                    m.grid.nelem,
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
                    m.grid.nelem,
                    [self.y, halo, topo.gid, rows(cg.Dinv), rows(cg.spheremp), cg.dvv, rows(cg.wg)],
                    **elements,
                ),
                *topo.exchange(cg.wg),
                rec(
                    hk.helmholtz_back_substitution(np_, topo.table.shape[1], implicit is not None),
                    m.grid.nelem,
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

    def _run(self, key: tuple, fn, *args) -> None:
        """fn(*args) as a graph captured on the first call per ``key`` (the launch
        parameters it bakes in) and replayed after, where ``graphable`` and the model's
        ``graph_guard`` allows (``graphs.captured``: a failure falls back with one line);
        inline while a caller captures and otherwise (the loops host loops testing the
        device flag)."""
        if not self.graphable:
            fn(*args)
            return
        captured(self._graphs, key, lambda: fn(*args), self.model.device, self.model.graph_guard, "the Helmholtz solve")

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
    def _apply(self, y, out, c: float) -> None:
        """out = (M + cK) y in float64 (``HelmholtzCG.apply``)."""
        self.cg.apply(y, out, c)

    def _pcg(self, c: float) -> None:
        """(M + cK) y = b to the relative residual ``tol`` in float64 (``precision``
        "double"), or in float32 with float64 refinement ("mixed"); then the area
        integral of y set to that of b (on the device). Iterations into ``stats``."""
        h = self._history
        if h is not None:
            h.guess()
        if self.low is None:
            self.cg.solve(c, self.tol, self.maxiter, self.warm, guessed=h is not None)
        else:
            self._refined(c)
        if h is not None:
            h.store()
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
        wp.capture_while(cg.ic, self._refinement, c=c)

    def _refinement(self, c: float) -> None:
        """One pass: e from A e = r in float32 to max(tol‖b‖, SINGLE_FLOOR‖r‖) within the
        iterations left (both set by ``refine_check``), y += e, the new residual and its test."""
        self._narrow_r.launch()  # low.b = r
        self.low.solve(c, 0.0, 0, False)
        self._widen.launch()  # y += e
        self.cg.residual(c)
        self._check_next.launch()


class GuessHistory:
    """The start of a sequence of solves (M + cK) y = b with one c (``HelmholtzSolver``'s with
    ``history`` k): projection onto the past solutions (Fischer 1998, Comput. Methods Appl.
    Mech. Engrg. 163, 193, "method 2"; PETSc's ``KSPFischerGuess``). X (k, nunique) is an
    A-orthonormal basis of up to k vectors, AX their products; the start is y0 = Σ (Xⱼ·b) Xⱼ,
    the A-norm's best in their span, with A y0 = Σ (Xⱼ·b) AXⱼ and so no product (one fewer
    than a warm start). After the solve the increment y − y0 (A-orthogonal to X in exact
    arithmetic), A-orthonormalised against X, is appended, its product from the CG's residual
    (A y = b − r); with k vectors the basis restarts from the solution and its start
    (``kernels.helmholtz.history_coefficients``; Fischer's from the solution alone). The inner
    products are summed on the device in index order and over ranks by ``Topology``
    (``HelmholtzCG.totals``' way): the same bits on any threads, to round-off on any ranks.

    ``guess()``: y, w (and the copies y0, w0) of ``HelmholtzSolver``'s CG set to the start;
    ``store()``: the solution into the basis (launches, nothing read back). ``count()``:
    the vectors in use (a host read); ``whole()``/``set(count, arrays, what)``: X and AX
    as ``arrays`` whole-grid (3, nnodes_total) arrays, three vectors each (rows past 2k zero),
    for ``HelmholtzSolver.state``/``restore`` (ValueError naming ``what`` for a misshapen one)."""

    def __init__(self, gw: HelmholtzSolver):
        cg, topo, dev, k = gw.cg, gw.model.topology, gw.model.device, gw.history
        self.topology, self.k = topo, k
        self.X = wp.zeros((k, topo.nunique), dtype=f64, device=dev)
        self.AX = wp.zeros((k, topo.nunique), dtype=f64, device=dev)
        self.hic = wp.zeros(3, dtype=wp.int32, device=dev)  # kernels.helmholtz COUNT, MODE, SLOT
        self.hcs = wp.zeros(max(k + 1, 3), dtype=f64, device=dev)  # 1/‖·‖_A, the βⱼ
        self.arrays = (2 * k + 2) // 3
        rec, nchunks, chunk, nu = gw.model.launches.record, cg.partial.shape[1], cg.chunk, topo.nunique
        y, (y0, w0, partial, alpha, sums) = gw.y, gw.history_work
        self._guess = [
            rec(hk.history_dots, nchunks, [self.X, gw.b, self.hic, partial, chunk], nodes_per_index=chunk),
            *topo.device_sums(partial, k, alpha),
            alpha,
            rec(hk.history_guess, nu, [self.X, self.AX, alpha, self.hic, y, cg.w, y0, w0]),
        ]
        self._store = [
            rec(
                hk.history_increment_dots,
                nchunks,
                [self.X, y, y0, gw.b, cg.r, w0, self.hic, partial, chunk],
                nodes_per_index=chunk,
            ),
            *topo.device_sums(partial, k + 4, sums),
            sums,
            wp.launch(hk.history_coefficients, 1, [sums, k, self.hic, self.hcs], device=dev, record_cmd=True),
            rec(hk.history_store, nu, [self.X, self.AX, y, y0, gw.b, cg.r, w0, self.hic, self.hcs]),
        ]

    def _play(self, launches) -> None:
        for launch in launches:
            if isinstance(launch, wp.array):  # the totals summed over ranks between the launches
                self.topology.allreduce(launch)
            else:
                launch.launch()

    def guess(self) -> None:
        self._play(self._guess)

    def store(self) -> None:
        self._play(self._store)

    def count(self) -> int:
        return int(self.hic.numpy()[hk.COUNT])

    def _rows(self):
        return [self.X[j] for j in range(self.k)] + [self.AX[j] for j in range(self.k)]

    def whole(self) -> list:
        """X's and AX's rows scattered to element-local (3, N) arrays, gathered on rank 0 (call on all ranks)."""
        topo, rows, out = self.topology, self._rows(), []
        for m in range(self.arrays):
            a = wp.zeros((3, topo.N), dtype=f64, device=self.X.device)
            for row, v in enumerate(rows[3 * m : 3 * m + 3]):
                for launch in topo.scatter(v, a, row):
                    launch.launch()
            out.append(topo.gather(a.numpy()))
        return out

    def set(self, count: int, arrays: list, what: str) -> None:
        topo, rows = self.topology, self._rows()
        first = topo.first.numpy()
        for m, whole in enumerate(arrays):
            part = topo.distribute(whole, 3, what)
            for row, v in enumerate(rows[3 * m : 3 * m + 3]):
                v.assign(part[row][first])
        self.hic.assign(np.array([count, 0, 0], dtype=np.int32))


# the float32 CG's reach: a tolerance at or above SINGLE_TOL is solved in float32 alone;
# below it, refinement passes each reduce the float64 residual by SINGLE_FLOOR at most
# (float32's unit round-off 6e-8 times the growth of CG's recurrences)
SINGLE_TOL = 1e-3
SINGLE_FLOOR = 1e-4


class HelmholtzCG:
    """(M + cK) y = b on unique nodes (``nunique``,) by Chronopoulos–Gear CG (1989, J.
    Comput. Appl. Math. 25, 153) preconditioned by M⁻¹, matrix-free, in ``dtype``
    (float64, or float32 for the inner solves of ``HelmholtzSolver``'s "mixed"
    precision); inner products summed in float64 in a fixed order on any device,
    threads and ranks. ``b``, ``y``: the right-hand side and solution vectors
    (float64 ones may be given, shared with the caller); ``stats``: the float64
    device counters (``kernels.helmholtz.ITERATIONS``, ``FAILURES``, ``RESIDUAL``)
    the solve adds to, shared with the caller's other solves (its own if None).

    The whole solve runs on the device: the inner products' partial sums are added
    there (``Topology.device_sums``), the recurrences' scalars α, β, γ, δ, ‖r‖² and
    the convergence test are computed by one-thread kernels (``cg_check`` after an
    update, ``cg_alpha`` after a product) into device arrays the vector update reads,
    and on one rank the test between the two spares the converged iteration's product
    (k iterations cost k products, k + 1 from a warm start; over ranks k + 1 and one
    reduction an iteration, as Chronopoulos–Gear's order). The loop is
    ``wp.capture_while`` on a device flag: a host loop on the CPU (it reads the flag
    in place, no copy), a conditional node inside a CUDA graph (``HelmholtzSolver``
    captures the solve) — the same kernels, so the same bits on CPU threads and to
    round-off on CUDA. Over several MPI ranks the per-rank sums go through the host
    between the two (``Topology.allreduce``: one read an iteration); on one rank no
    value comes back to the host during a solve.

    ``apply(y, out, c)``: out = (M + cK) y. ``solve(c, tol, maxiter, warm)``: y to the
    relative residual tol from y (``warm``) or from zero; adds its iterations to
    ``stats`` and, past ``maxiter``, a failure (nothing is read back: the caller reads
    ``stats``, ``HelmholtzSolver.iterations``). ``residual(c)``: r = b − Ay and r·r into
    ``sums[2]``, b·b into ``sums[1]`` (refinement's)."""

    def __init__(self, model: ShallowWater, dtype=f64, b=None, y=None, stats=None):
        topo, dev, N, nu = model.topology, model.device, model.N, model.topology.nunique
        self.model, self.dtype = model, dtype
        z = lambda *shape: wp.zeros(shape, dtype=dtype, device=dev)  # noqa: E731
        self.b = z(nu) if b is None else b
        self.y = z(nu) if y is None else y
        self.wg, self.z = z(2, N), z(1, N)
        self.r, self.u, self.w, self.p, self.s = (z(nu) for _ in range(5))
        # the metric in the solve's type: the model's own arrays in float64, float32 copies else
        same = dtype is f64
        cast = lambda a: a if same else wp.array(a.numpy(), dtype=dtype, device=dev)  # noqa: E731
        self.Dinv, self.metdet = cast(model.Dinv), cast(model.metdet)
        self.spheremp, self.rspheremp = (
            cast(topo.spheremp[: topo.N]),
            cast(topo.rspheremp),
        )  # the local copies' masses (the ghosts' follow on a rank)
        self.dvv = model.dvv_rows if same else operators.dvv_matrix(model.grid.rule.dvv, dtype)
        self.minv = wp.array(1.0 / topo.area, dtype=dtype, device=dev)
        self.area, self.ones = wp.array(topo.area, dtype=dtype, device=dev), wp.ones(nu, dtype=dtype, device=dev)
        self.chunk = chunk = topo.backend.reduction_chunk(nu)
        self.partial = wp.zeros((3, (nu + chunk - 1) // chunk), dtype=f64, device=dev)
        # the device scalars: the inner products' totals, the recurrences' (hk.GAMMA …), the flag and counts (hk.GO …)
        self.sums = wp.zeros(3, dtype=f64, device=dev)
        self.cs = wp.zeros(8, dtype=f64, device=dev)
        self.ic = wp.zeros(3, dtype=wp.int32, device=dev)
        self.stats = wp.zeros(3, dtype=f64, device=dev) if stats is None else stats
        self._totals = topo.device_sums(self.partial, 3, self.sums)
        self._ops: dict[tuple, list] = {}
        self._div: dict[tuple, list] = {}  # each operator's divergence launch and the c it has
        self._inner = {}
        rec, nchunks = model.launches.record, self.partial.shape[1]
        update = [self.p, self.s, self.y, self.r, self.u, self.w, self.minv, self.partial, chunk]
        self._update = rec(hk.cg_update(dtype), nchunks, [self.cs, 0, *update], nodes_per_index=chunk)
        self._restart = rec(hk.cg_update(dtype), nchunks, [self.cs, 1, *update], nodes_per_index=chunk)
        self._first, self._check = (
            wp.launch(
                hk.cg_check,
                1,
                [self.sums, first, f64(0.0), 0, self.cs, self.ic, self.stats],
                device=dev,
                record_cmd=True,
            )
            for first in (1, 0)
        )
        self._alpha = wp.launch(hk.cg_alpha, 1, [self.sums, self.cs, self.ic], device=dev, record_cmd=True)
        # over ranks an iteration keeps Chronopoulos–Gear's one reduction (an allreduce costs more there
        # than the converged iteration's product, a 1/P share); on one rank the sums stay on the device
        self._one_reduction = topo.distributed

    def _operator(self, y, out) -> list:
        """Launches for out = (M + cK) y (unique-node vectors; c set by ``apply``), recorded once per pair."""
        key = (y.ptr, out.ptr)
        launches = self._ops.get(key)
        if launches is None:
            m, topo, dt = self.model, self.model.topology, self.dtype
            halo = topo.owned.recv_buffer
            y2 = y.reshape((1, topo.nunique))
            div = self.model.launches.record(
                hk.helmholtz_divergence(m.grid.np, topo.table.shape[1], dt),
                m.grid.nelem,
                [
                    self.wg,
                    topo.ghost,
                    topo.N,
                    topo.table,
                    self.rspheremp,
                    y,
                    halo,
                    topo.gid,
                    self.model.as_rows(self.Dinv),
                    self.model.as_rows(self.metdet),
                    self.model.as_rows(self.spheremp),
                    self.dvv,
                    dt(0.0),
                    self.model.as_rows(self.z),
                ],
                nodes_per_index=m.grid.np**2,
            )
            grad = self.model.launches.record(
                hk.helmholtz_gradient(m.grid.np, dt),
                m.grid.nelem,
                [
                    y,
                    halo,
                    topo.gid,
                    self.model.as_rows(self.Dinv),
                    self.model.as_rows(self.spheremp),
                    self.dvv,
                    self.model.as_rows(self.wg),
                ],
                nodes_per_index=m.grid.np**2,
            )
            assemble = self.model.launches.record(
                hk.helmholtz_assemble(topo.table.shape[1], dt),
                self.partial.shape[1],
                [self.z, topo.ghost, topo.N, topo.table, topo.first, y, out, self.partial, self.chunk],
                nodes_per_index=self.chunk,
            )
            launches = self._ops[key] = [
                *topo.exchange(y2, unique=True),
                grad,
                *topo.exchange(self.wg),
                div,
                *topo.exchange(self.z),
                assemble,
            ]
            self._div[key] = [div, None]
        return launches

    def _per_node(self, y, out) -> list:
        """The last launch of out = (M + cK) y in the per-node layout (CUDA's), recorded once
        per pair; ``apply`` runs the model's operators before it."""
        key = (y.ptr, out.ptr)
        launches = self._ops.get(key)
        if launches is None:
            topo = self.model.topology
            combine = self.model.launches.record(
                hk.helmholtz_combine,
                self.partial.shape[1],
                [self.z, topo.first, y, self.area, f64(0.0), out, self.partial, self.chunk],
                nodes_per_index=self.chunk,
            )
            launches = self._ops[key] = [combine]
            self._div[key] = [combine, None]
        return launches

    def apply(self, y, out, c: float) -> None:
        """out = (M + cK) y on unique nodes; partial[1] = out·y. Per element (the CPU's
        layout, and float32 on any device): the three fused element kernels. Per node
        (CUDA's, float64): the model's per-node gradient and divergence with their DSS,
        then ``helmholtz_combine`` — the element kernels run a thread per element, whose
        strided reads are slow on a GPU (benchmarks/README.md, "Measurements behind the code")."""
        m = self.model
        if m.per_element or self.dtype is not f64:
            launches = self._operator(y, out)
        else:
            launches = self._per_node(y, out)
            m.scatter(y, self.z, 0)
            m.gradient(self.z, 0, self.wg)
            m.divergence(self.wg, self.z)
        div = self._div[(y.ptr, out.ptr)]
        if div[1] != c:
            div[0].set_param_by_name("c", self.dtype(c))
            div[1] = c
        for launch in launches:
            launch.launch()

    def dots(self, a0, b0, a1, b1, a2, b2) -> None:
        """sums = (a0·b0, a1·b1, a2·b2) over all ranks, on the device (``totals``)."""
        key = tuple(a.ptr for a in (a0, b0, a1, b1, a2, b2))
        launch = self._inner.get(key)
        if launch is None:
            launch = self._inner[key] = self.model.launches.record(
                hk.inner3(self.dtype),
                self.partial.shape[1],
                [a0, b0, a1, b1, a2, b2, self.partial, self.chunk],
                nodes_per_index=self.chunk,
            )
        launch.launch()
        self.totals()

    def totals(self) -> None:
        """sums = the totals of ``partial``'s three rows over all ranks: added on the device in
        index order, then over ranks (``Topology.allreduce``; a host read only on several ranks)."""
        for launch in self._totals:
            launch.launch()
        self.model.topology.allreduce(self.sums)

    def residual(self, c: float) -> None:
        """r = b − Ay, u = M⁻¹r; sums = (r·u, b·b, r·r) over all ranks: one product (refinement's)."""
        self.apply(self.y, self.w, c)
        self._residual_update()
        self.totals()

    def _residual_update(self) -> None:
        """From w = Ay: r = b − w, u = M⁻¹ r, partial sums r·u, b·b and r·r (an update from r = b, u = 0)."""
        wp.copy(self.r, self.b)
        self.u.zero_()
        self._restart.launch()

    def solve(self, c: float, tol: float, maxiter: int, warm: bool, guessed: bool = False) -> None:
        """y = (M + cK)⁻¹ b to the relative residual ``tol``, from y (``warm``: one product
        more), from y with w = A y already set (``guessed``: a projected start,
        ``GuessHistory``) or from zero; tol ≤ 0 and maxiter ≤ 0: those ``refine_check``
        left on the device. k iterations cost k products on one rank (the test between an
        update and the next product), k + 1 over ranks (one reduction an iteration)."""
        if guessed:
            pass
        elif warm:
            self.apply(self.y, self.w, c)
        else:
            self.y.zero_()
            self.w.zero_()
        self._residual_update()  # r = b − Ay, u = M⁻¹r; r·u, b·b, r·r
        self.totals()
        self._first.set_param_by_name("tol2", f64(tol * tol if tol > 0 else 0.0))
        self._first.set_param_by_name("maxiter", int(maxiter))
        self._first.launch()  # the bound; go?
        if self._one_reduction:  # the first product and α ahead of the loop
            self._product(c)
        wp.capture_while(self.ic, self._iteration, c=c)

    def _product(self, c: float) -> None:
        """w = Au, δ = w·u over all ranks, α."""
        self.apply(self.u, self.w, c)
        self.totals()
        self._alpha.launch()

    def _iteration(self, c: float) -> None:
        """One CG iteration: the product, α, the update with the device's α and β, the test
        (over ranks: the update, the product, then the test and α on one reduction)."""
        if not self._one_reduction:
            self._product(c)
        self._update.launch()  # p, s, y, r, u; r·u, r·r
        if self._one_reduction:
            self.apply(self.u, self.w, c)  # and w·u, summed with them
        self.totals()
        self._check.launch()  # β; go?
        if self._one_reduction:
            self._alpha.launch()
