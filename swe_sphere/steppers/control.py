"""Error control's parts apart from the stepper: the error norm of an embedded pair's
estimate and the step-size controllers (Söderlind's digital filters).

``ErrorNorm``: the weighted RMS norm of a step's error estimate e (``error_estimate``
of an embedded pair, ``runge_kutta``) over the unique nodes and the fields u, v, h,

    ‖e‖ = sqrt( mean over nodes n and fields f of (e / (atol_f + rtol·max(|x_n|, |x_{n+1}|)))² ),

(Hairer, Nørsett & Wanner 1993, *Solving ODEs I*, §II.4, eq. 4.11; ARKODE's and
OrdinaryDiffEq's), so that ‖e‖ ≤ 1 is a step within tolerance. One global reduction:
the per-node terms (``kernels.error_norm``) gathered from every rank into the whole grid's
order of the unique nodes (their global ids) and added there by one ``np.sum``: the same
terms in the same order on any rank count, so the same bits. (``math.fsum``, the correctly
rounded sum, gave that too at 5 ms a norm at ne30, 40 % of a bs32 step; the ordered sum
takes 0.05 ms: benchmarks/studies/control_ne30.py control_overhead.) On one rank the sum is ``np.sum``'s own
pairwise summation taken apart (``PairwiseSum``): its leaves of at most 128 terms added on the
device, a few thousand leaf sums read and added on the host along numpy's tree, the same bits
as ``np.sum`` of every term without reading them (1.5 MB a norm at ne60: on an H100 the read
and the host's sum cost 1.4 bare steps, issue 83).

``Controller``: the next step from this step's norm and the accepted history
(Söderlind 2003, ACM TOMS 29, 1, "Digital filters in adaptive time-stepping"),

    Δt' = Δt · safety · ε_n^(−k1/k) · ε_{n−1}^(−k2/k) · ε_{n−2}^(−k3/k) · (Δt_n/Δt_{n−1})^k4,

ε the norms of the accepted steps, k = min(p, p̂) + 1 (the pair's orders), the factor
held within [shrink, grow]; a step with ε > 1 is rejected and retried at
Δt·max(shrink, safety·ε^(−1/k)). The coefficient sets (``CONTROLLERS``) are SUNDIALS
ARKODE's (``SUNAdaptController_Soderlind``: I, PI, PID, H211) and Ranocha, Dalcin,
Parsani & Ketcheson's (2022, Commun. Appl. Math. Comput. 4, 1191) PID sets tuned for
``bs32``, ``ssprk43`` and ``rdpk3sp35``.

``Balance``: the absolute tolerances of the balanced mode, held to a fraction of the spatial
error's rate (``SpatialRate``).

``CflController``: the next step from the Courant numbers of this one, as the model's
diagnostics compute them (``model.diagnostics.courant_numbers``), toward a target, growing
at most ``max_change`` a step (WRF's ``target_cfl``, Oceananigans' ``TimeStepWizard``); alone,
or as a cap on the error controller's proposal (``capped``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ..core.parallel import record
from ..grid.gll import truncation
from ..kernels import error_norm

f64 = wp.float64

# (k1, k2, k3, k4): the exponents of ε_n, ε_{n−1}, ε_{n−2} (over k, negated) and of Δt_n/Δt_{n−1}
CONTROLLERS = {
    "i": (1.0, 0.0, 0.0, 0.0),  # elementary: ARKODE's default since v7.3.0, SciPy's
    "pi": (0.8, -0.31, 0.0, 0.0),  # ARKODE's PI
    "pid": (0.58, -0.21, 0.1, 0.0),  # ARKODE's PID
    "h211": (0.25, 0.25, 0.0, -0.25),  # Söderlind's H211b, b = 4 (his Table 1): β1 = β2 = α2 = 1/b
    "pid_bs32": (0.60, -0.20, 0.0, 0.0),  # Ranocha et al. 2022, for BS3
    "pid_ssprk43": (0.55, -0.27, 0.05, 0.0),  # for SSPRK43
    "pid_rdpk3sp35": (0.70, -0.23, 0.0, 0.0),  # for RDPK3SpFSAL35
}


# numpy's pairwise summation (``pairwise_sum``, numpy/_core/src/umath/loops_utils.h.src): a run of
# at most PAIRWISE_LEAF terms is a leaf; a longer one is split at half its length rounded down to a
# multiple of PAIRWISE_UNROLL, the halves' sums added
PAIRWISE_LEAF = 128
PAIRWISE_UNROLL = 8


class PairwiseSum:
    """``np.sum`` of n float64 terms (a contiguous array) in its own order, its leaves apart:
    ``starts``, ``lengths`` (int32, one a leaf, in order) for ``kernels.error_norm.pairwise_leaves``
    to add on the device; ``total(leaf_sums)`` adds the leaves' sums (m,) on the host along numpy's
    tree, a level of additions at a time (about log2(n / 96) numpy passes). Bit for bit
    ``np.sum`` of the terms (tests/steppers/test_control.py holds it to that)."""

    def __init__(self, n: int):
        starts, lengths, leaves, joins = [], [], [], []  # joins: (height, node, left, right), nodes numbered in turn

        def node(start: int, count: int) -> tuple[int, int]:  # (its number, its height)
            if count <= PAIRWISE_LEAF:
                starts.append(start)
                lengths.append(count)
                leaves.append(len(leaves) + len(joins))
                return leaves[-1], 0
            half = count // 2
            half -= half % PAIRWISE_UNROLL
            (left, hl), (right, hr) = node(start, half), node(start + half, count - half)
            joins.append((max(hl, hr) + 1, len(leaves) + len(joins), left, right))
            return joins[-1][1], joins[-1][0]

        self.root, _ = node(0, int(n))
        self.starts, self.lengths = np.array(starts, dtype=np.int32), np.array(lengths, dtype=np.int32)
        self.leaves = np.array(leaves, dtype=np.intp)  # each leaf's node
        self.levels = []  # (node, left, right) index arrays a height, lowest first
        for height in sorted({h for h, *_ in joins}):
            rows = [row[1:] for row in joins if row[0] == height]
            self.levels.append(tuple(np.array(col, dtype=np.intp) for col in zip(*rows)))
        self._values = np.empty(len(leaves) + len(joins))

    def total(self, leaf_sums) -> float:
        """The sum of the terms from their leaves' sums (m,), in numpy's order."""
        v = self._values
        v[self.leaves] = leaf_sums
        for out, left, right in self.levels:
            v[out] = v[left] + v[right]
        return float(v[self.root])


class ErrorNorm:
    """The weighted RMS norm (dimensionless) of error estimates e (3, N) on ``topology``'s
    element-local nodes, rows u, v (m s⁻¹) and h (m): ``rtol`` (> 0) relative,
    ``atol_wind`` (m s⁻¹) and ``atol_h`` (m) absolute tolerances. With ``check_depth``
    (h a depth: a scene with a pressure gradient) a step that ends with h ≤ 0 anywhere has
    the norm +inf, and one with a non-finite value NaN or inf: a finite norm is a state the
    bad-node check (``model.bad_nodes``) passes. ``atol`` (3,) the device array of the
    absolute tolerances (u, v, h), which a caller may set between norms (``Balance``).
    ValueError for a negative tolerance, or rtol 0 with an atol 0."""

    def __init__(self, topology, rtol: float, atol_wind: float = 1e-3, atol_h: float = 1e-2, check_depth: bool = False):
        if not rtol >= 0 or (rtol == 0 and not min(atol_wind, atol_h) > 0):
            raise ValueError(f"rtol must be > 0, or 0 with every atol > 0 (got {rtol!r}, {atol_wind!r}, {atol_h!r})")
        for key, value in (("atol_wind", atol_wind), ("atol_h", atol_h)):
            if not value >= 0:
                raise ValueError(f"{key} must be ≥ 0 (got {value!r}, {'m/s' if key == 'atol_wind' else 'm'})")
        self.topology, self.rtol, self.check_depth = topology, float(rtol), int(bool(check_depth))
        self.block = 64 if topology.backend.host else 1
        self._launches: dict[tuple, tuple] = {}  # (e, x0, x1) addresses: the recorded launch, its arrays
        self.atol = wp.array(np.array([atol_wind, atol_wind, atol_h]), dtype=f64, device=topology.device)
        self._terms = wp.zeros(topology.nunique, dtype=f64, device=topology.device)
        self.count = 3 * int(round(topology.sum(float(topology.nunique))))  # the terms over every rank
        self._order = self._sum = None  # one rank holds its unique nodes in the global ids' order (ascending)
        if topology.distributed:  # the order of the ranks' nodes gathered one after another
            grid = topology.grid
            self._order = np.argsort(np.concatenate(topology.comm.allgather(grid.gid[grid.first])), kind="stable")
            self._read = topology.backend.reader(self._terms)
        else:  # np.sum's leaves on the device, their sums read
            self._sum = PairwiseSum(topology.nunique)
            device = topology.device
            starts = wp.array(self._sum.starts, dtype=wp.int32, device=device)
            lengths = wp.array(self._sum.lengths, dtype=wp.int32, device=device)
            leaves = wp.zeros(len(self._sum.starts), dtype=f64, device=device)
            args = [self._terms, starts, lengths, leaves]
            self._leaves = record(
                error_norm.pairwise_leaves,
                len(leaves),
                args,
                device=device,
                threads=topology.threads,
                nodes_per_index=PAIRWISE_LEAF,
            )
            self._read = topology.backend.reader(leaves)

    def __call__(self, e, x0, x1) -> float:
        """‖e‖ with the weights of the states x0 (the step's start) and x1 (its end), (3, N) each;
        the same value on every rank, and the same bits on any number of ranks: ``launch``
        then ``read``."""
        self.launch(e, x0, x1)
        return self.read()

    def launch(self, e, x0, x1) -> None:
        """Queue the norm's passes over e, x0 and x1 and its read (``core.backend.HostRead``):
        on CUDA the host goes on (a next step may be launched behind it) until ``read``."""
        t = self.topology
        key = (e.ptr, x0.ptr, x1.ptr)
        if key not in self._launches:
            args = [e, x0, x1, t.first, self.atol, f64(self.rtol), self.check_depth, self.block, self._terms]
            dim = -(-t.nunique // self.block)
            launch = record(
                error_norm.weighted_squares, dim, args, device=t.device, threads=t.threads, nodes_per_index=self.block
            )  # split over the CPU threads as the model's launches
            self._launches[key] = (launch, (e, x0, x1))
        self._launches[key][0].launch()
        if self._sum is not None:
            self._leaves.launch()
        self._read.start()

    def read(self) -> float:
        """The norm ``launch`` queued (waits for its read alone)."""
        values = self._read.values()
        if self._sum is not None:
            return math.sqrt(self._sum.total(values) / self.count)
        terms = np.concatenate(self.topology.comm.allgather(values))[self._order]
        return math.sqrt(float(np.sum(terms)) / self.count)


COURANT_BLOCK = 64


class CourantMax:
    """The largest advective and gravity-wave Courant numbers of states x (3, N) on
    ``topology``'s nodes at a Δt, reduced on the device to a slot a block of nodes and over the
    ranks by a maximum (exact: the same numbers on any rank or thread count), and whether a
    node is bad; as ``model.diagnostics.courant_numbers`` computes them on the gathered state,
    to round-off, without the gather (1.1 ms a step at ne30, 12 % of an ssprk3 step).
    ``dx`` (N,) the nodes' spacing (m), ``g`` (m s⁻²); ``gravity_waves`` False: the
    gravity-wave number NaN (h is a tracer), and h ≤ 0 no bad node."""

    def __init__(self, topology, dx, g: float, gravity_waves: bool):
        self.topology, self.g, self.gravity_waves = topology, float(g), bool(gravity_waves)
        device = topology.device
        self.rdx2 = wp.array(1.0 / np.asarray(dx, dtype=np.float64) ** 2, dtype=f64, device=device)
        # a slot a block of COURANT_BLOCK nodes on either device (maxima: the same numbers however
        # the nodes are blocked): on CUDA a slot a node made the pass's read 3 N numbers, 8 MB at ne60
        self.block = COURANT_BLOCK
        self._out = wp.zeros((3, -(-topology.N // self.block)), dtype=f64, device=device)
        self._read = topology.backend.reader(self._out)
        self._launches: dict[int, tuple] = {}

    def __call__(self, x, dt: float) -> tuple[dict, bool]:
        """(``courant_numbers``' dict of x at ``dt`` (s), whether x has a bad node): ``launch``
        then ``read``."""
        self.launch(x)
        return self.read(dt)

    def launch(self, x) -> None:
        """Queue the pass over x and its read (``core.backend.HostRead``): on CUDA the host goes
        on (a next step may be launched behind it) until ``read``. x is read as it is when the
        pass runs, in the stream's order."""
        t = self.topology
        if x.ptr not in self._launches:
            args = [x, self.rdx2, f64(self.g), int(self.gravity_waves), self.block, self._out]
            n = self._out.shape[1]
            launch = record(
                error_norm.courant_squares, n, args, device=t.device, threads=t.threads, nodes_per_index=self.block
            )
            self._launches[x.ptr] = (launch, x)
        self._launches[x.ptr][0].launch()
        self._read.start()

    def read(self, dt: float) -> tuple[dict, bool]:
        """The numbers at ``dt`` (s) of the pass ``launch`` queued, and whether its state has a
        bad node (waits for its read alone)."""
        t = self.topology
        adv, grav, bad = (t.max(float(v)) for v in self._read.values().max(axis=1))
        numbers = {"courant_advective": math.sqrt(adv) * dt}
        numbers["courant_gravity"] = math.sqrt(grav) * dt if self.gravity_waves else math.nan
        return numbers, bad > 0


class SpatialRate:
    """An a-posteriori estimate of how fast the spatial discretization's error grows, for the
    balanced step control: of a tendency F (3, N) at a state x (3, N) on ``topology``'s
    element-local nodes, per row (u, v, h) the RMS of F's highest-mode tail, F − (T ⊗ T) F
    element by element (``grid.gll.truncation``: the part of F beyond the np − 1 projection,
    Mavriplis 1994's estimate of a spectral element's truncation error), over the RMS of x's
    row (u and v together): s⁻¹, relative. ``scales(F, x)`` returns the largest of the three
    times each row's RMS, (3,) in x's units a second: the rate at which errors as large as the
    grid's own arise, which a balanced step's error estimate over Δt is held to a fraction of.
    RMS weighted by spheremp, the sums ``Topology.whole_sums``' (the same bits on any rank
    count). A row
    of x that is zero everywhere takes the largest rate times 0. About 1 ms at ne30 (one thread),
    every ``BALANCE_EVERY`` steps."""

    def __init__(self, topology):
        grid = topology.grid
        self.topology, self.np = topology, grid.np
        T = truncation(grid.np)
        self.TT = np.kron(T, T).T  # (T ⊗ T)ᵀ on an element's n² nodes (either layout: it treats both axes alike)
        self.weight = np.asarray(grid.spheremp, dtype=np.float64)
        self.area = float(topology.whole_sums(self.weight[None])[0])  # Σ spheremp: the sphere's area (m²)
        self.last = math.nan  # the last ``scales``' largest relative rate (s⁻¹)

    def scales(self, F: np.ndarray, x: np.ndarray) -> np.ndarray:
        n, w = self.np, self.weight
        f = np.asarray(F, dtype=np.float64).reshape(-1, n * n)  # (rows · elements, n²)
        tail = (f - f @ self.TT).reshape(3, -1)  # F − (T ⊗ T) F, element by element
        x = np.asarray(x, dtype=np.float64)
        rows = [w * (tail[0] ** 2 + tail[1] ** 2), w * tail[2] ** 2, w * (x[0] ** 2 + x[1] ** 2), w * x[2] ** 2]
        sums = self.topology.whole_sums(rows)
        tails, states = sums[:2], sums[2:]  # (wind, h) each
        rate = self.last = float(np.max(np.sqrt(np.divide(tails, states, out=np.zeros(2), where=states > 0))))
        rms = np.sqrt(states / np.array([2.0 * self.area, self.area]))  # a wind component's, h's
        return rate * rms[[0, 0, 1]]


# under "balanced", the spatial error's rate is estimated again after this many accepted steps
# (one RHS evaluation and a pass over the state: 1/16 of an RHS a step), and no absolute
# tolerance falls below ATOL_FLOOR (each row's units, m s⁻¹ and m: the round-off of a state)
BALANCE_EVERY = 16
ATOL_FLOOR = 1e-12


class Balance:
    """The balanced mode's tolerances (``control = "balanced"``) for ``norm`` (an ``ErrorNorm``
    with rtol 0) on ``unit``'s model and grid (its ``model`` and state ``x``: the step control's
    ``integrator.core.Unit``), held to ``fraction`` (``SceneControl.balance``).
    ``tolerances(x0, t, dt)`` before a try's norm: every ``BALANCE_EVERY`` accepted steps the
    scales σ (3,) of ``SpatialRate`` from F(x0) at the step's start t (s), one RHS evaluation;
    then atol_r = max(fraction · Δt · σ_r, ``ATOL_FLOOR``): the step's error estimate held to
    ``fraction`` of the spatial error the grid makes over Δt, on every row alike (σ is the
    largest row's relative rate times each row's RMS). Why rates and not the errors
    themselves: both errors grow with time and are carried by the same flow (Galewsky ne30's
    spatial error grows 150-fold from day 1 to day 6 while the state's highest-mode tail does not
    triple), so balancing what each step adds balances their sums as far as the flow carries
    them alike; a step's estimate being a local error, the mode is per unit step (Δt in the
    tolerance). ``state``/``restore``: σ and the steps since its estimate (a restart continues
    bitwise)."""

    def __init__(self, fraction: float, unit, norm: ErrorNorm):
        self.fraction, self.model, self.norm = float(fraction), unit.model, norm
        self.rate = SpatialRate(unit.model.topology)
        self.F = wp.zeros_like(unit.x)
        self.sigma, self.since = None, 0

    def tolerances(self, x0, t: float, dt: float) -> None:
        if self.sigma is None or self.since >= BALANCE_EVERY:
            self.model.set_time(t)  # a forcing's F at the step's start
            self.model.rhs(x0, self.F)
            self.sigma, self.since = self.rate.scales(self.F.numpy(), x0.numpy()), 0
        self.norm.atol.assign(np.maximum(self.fraction * dt * self.sigma, ATOL_FLOOR))

    def state(self) -> dict:
        return {"sigma": None if self.sigma is None else [float(v) for v in self.sigma], "since": self.since}

    def restore(self, state: dict) -> None:
        self.sigma = None if state["sigma"] is None else np.array(state["sigma"], dtype=np.float64)
        self.since = int(state["since"])


@dataclass
class Controller:
    """A step-size controller for a pair of orders p, p̂ (``order`` k = min(p, p̂) + 1):
    ``coefficients`` (k1, k2, k3, k4) or a name of ``CONTROLLERS``, ``safety`` (0.9),
    the bounds of a step's change ``shrink`` (0.2) and ``grow`` (10; Diffrax's).
    ``propose(dt, err)`` → (accepted, next Δt); ``state()``/``restore()`` its history.
    ValueError for an unknown name or bounds that do not hold 1 inside."""

    order: int
    coefficients: tuple | str = "i"
    safety: float = 0.9
    shrink: float = 0.2
    grow: float = 10.0
    errors: list = field(default_factory=lambda: [1.0, 1.0])  # ε_{n−1}, ε_{n−2} (1 before any step: ARKODE's)
    dts: list = field(default_factory=list)  # the last accepted Δt

    def __post_init__(self):
        if isinstance(self.coefficients, str):
            if self.coefficients not in CONTROLLERS:
                raise ValueError(f"controller must be one of {', '.join(CONTROLLERS)} (got {self.coefficients!r})")
            self.coefficients = CONTROLLERS[self.coefficients]
        if not (0 < self.shrink < 1 < self.grow and 0 < self.safety <= 1 and self.order >= 1):
            raise ValueError(
                f"need 0 < shrink < 1 < grow, 0 < safety ≤ 1 and order ≥ 1 "
                f"(got shrink {self.shrink}, grow {self.grow}, safety {self.safety}, order {self.order})"
            )

    def propose(self, dt: float, err: float) -> tuple[bool, float]:
        """(accepted, the next Δt, s) for a step of ``dt`` whose error norm is ``err``:
        accepted when err ≤ 1 (the history then moves on), else the retry's Δt (a NaN norm:
        ``shrink``)."""
        k = self.order
        if not err <= 1.0:  # a NaN norm too (max(nan, ...) is nan, and nan > 1 is false)
            return False, dt * (self.shrink if math.isnan(err) else max(self.shrink, self.safety * err ** (-1.0 / k)))
        err = max(err, 1e-10)  # a zero estimate grows the step by ``grow``
        k1, k2, k3, k4 = self.coefficients
        e1, e2 = self.errors
        factor = self.safety * err ** (-k1 / k) * e1 ** (-k2 / k) * e2 ** (-k3 / k)
        if k4 and self.dts:
            factor *= (dt / self.dts[-1]) ** k4
        self.errors, self.dts = [err, e1], [dt]
        return True, dt * min(self.grow, max(self.shrink, factor))

    def state(self) -> dict:
        """The history, as numbers (a restart file's)."""
        return {"errors": list(self.errors), "dts": list(self.dts)}

    def restore(self, state: dict) -> None:
        """Continue from ``state()``: the same proposals as the controller it came from."""
        self.errors, self.dts = [float(v) for v in state["errors"]], [float(v) for v in state["dts"]]


@dataclass(frozen=True)
class CflController:
    """The step that brings a Courant number to ``cfl`` (> 0): with ``gravity_waves`` the
    signal's, advective + gravity-wave (what an explicit stepper's ``courant_limit`` is
    stated in), else the advective one alone (what limits a stepper whose gravity waves are
    implicit, ``advective_courant_limit``). A step grows at most ``max_change`` (> 1) times
    the last; it shrinks to the target at once (a Courant number above it is a stability
    risk now, not a trend to follow). ValueError for cfl ≤ 0 or max_change ≤ 1."""

    cfl: float
    gravity_waves: bool = True
    max_change: float = 1.1  # Oceananigans' TimeStepWizard

    def __post_init__(self):
        if not (self.cfl > 0 and self.max_change > 1):
            raise ValueError(f"need cfl > 0 and max_change > 1 (got cfl {self.cfl}, max_change {self.max_change})")

    def courant(self, numbers: dict) -> float:
        """The Courant number the target is on, from ``courant_numbers``' dict
        (``courant_advective``, ``courant_gravity``: NaN without a pressure gradient)."""
        gravity = numbers["courant_gravity"]
        counts = self.gravity_waves and not math.isnan(gravity)
        return numbers["courant_advective"] + (gravity if counts else 0.0)

    def propose(self, dt: float, numbers: dict) -> float:
        """The next Δt (s) after a step of ``dt`` whose state has the Courant numbers
        ``numbers`` at ``dt`` (``courant_numbers(..., dt, ...)``)."""
        c = self.courant(numbers)
        grown = dt * self.max_change
        return grown if c <= 0 else min(grown, dt * self.cfl / c)


def capped(dt_error: float, dt_cfl: float | None) -> float:
    """The error controller's next Δt held at the CFL controller's (None: no cap)."""
    return dt_error if dt_cfl is None else min(dt_error, dt_cfl)
