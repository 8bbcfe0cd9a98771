"""Rooflines of the step's kernels, per launch: flops and compulsory bytes against this core's peak
and stream triad. One subcommand a study, each written to ``results/roofline/<study>/<stem>.json``::

    python benchmarks/micro/step/roofline.py STUDY [its options]   # STUDY --help: its options

``kernel_roofline``
~~~~~~~~~~~~~~~~~~~
A roofline of the element kernels (issue 99, item 2): each launch of one RHS (the tendency
and its DSS) and of one forward-Euler ∇⁴ substep (the two weak Laplacians and the DSS that
applies it), per element-local node: flops and compulsory bytes, CPU ns, GFLOP/s and GB/s, and
their fractions of this core's double-precision peak and of the stream triad (in cache and
from DRAM) measured in the same run; TC5 and Galewsky terms at each ``--ne``/``--np`` grid.

The model's own recorded launches are timed (``model.rhs(x, F)``'s, as ``launches.recorded``
keeps them, and ``model.hv.build(y, coef)``'s, coef = −Δt/n of the scene's step), each
``--inner`` times a round, every launch of every grid in turn, ``--rounds`` rounds (load changes
hit them alike); the medians of ``time.process_time`` a call (``results.timed``). Short
samples and many rounds: on a shared machine a sample in which the process was preempted comes
back with its caches cold, and the median leaves it out (10 calls a sample, 15 rounds: the same
launch of the two scenes differed by up to 60 %; 2 calls, 41 rounds: by 4–16 %). Beside
them the whole RHS (``model.rhs``, its replay with its host work) and the whole substep (its three
launches in turn), whose flops and bytes are the sums of their launches'.

How each figure is counted:

* bytes a node: every array a launch reads or writes, once (``core.tally.array_bytes`` of its
  arguments, a struct's fields included: the compulsory traffic), less the arguments its
  compiled form does not read (``UNREAD``: the tendency's ``forcing`` without topography, the
  ∇⁴'s ``delta`` with ν_div = ν, an unweighted gather's ``spheremp``, the ghost buffer on one
  rank, the first Laplacian's DSS arguments). An array both read and written (the substep's
  state) counts once; the DSS table counts whole (its −1 padding included).
* flops a node, from the kernels' code (``FLOPS``; an FMA = 2, an add, a multiply or a divide
  = 1, a sign flip 0): a one-direction derivative at a node is np FMAs (``operators.along``).
  ``tendency`` (kernels/tendencies.py ``tendency_element``): the fluxes 9 (continuity: metdet·h,
  the two contravariant fluxes), the Bernoulli function 4 and the covariant wind 8 (metdet ·
  adj(D⁻¹)ᵀv: momentum advection), + g h 2 (pressure gradient); six sweeps, 12 np; the divergence's
  two sweeps added 1; ``finish`` 1 (÷ metdet) + 6 (Dinvᵀ∇E) + 4 (ζ + f: −, ÷, two +) + 4 (k×v) +
  2 (topography): TC5 12 np + 41, Galewsky 12 np + 39. ``dss`` (kernels/dss.py, weighted, 3 rows): an FMA a
  row and copy, then × rspheremp: 3(2c + 1), c the mean number of copies in a node's table row
  (counted from the table). ``laplacian first`` (kernels/hyperviscosity_element.py
  ``laplacian_element``): X formed twice (the Laplacian's and the pointwise part's: 3 + 3 + 3 + 1
  each) 20; four weak Laplacians of 4 sweeps each, 8 np + 7 a field (the flux's two 2×2
  products 6, the two transposed sweeps added 1): 32 np + 28; ``scale_first`` 22 (P's dot 5,
  three rows of 5, c₃w 1, ν_s 1): 32 np + 70. ``laplacian second``: the first DSS gathered
  (unweighted, 4 rows: 4c adds, 4 ×), the same four weak Laplacians, ``shift_second`` 7:
  32 np + 4c + 39. ``dss_apply``: the gather 4c + 4, the two projections back to (east, north)
  5 + 5, three FMA updates 6: 4c + 20.
* the peak: the nominal figure of the core (``--clock-ghz`` × 8 float64 lanes of AVX-512 × 2
  flops an FMA × ``--fma-units``: 2.8 × 8 × 2 × 2 = 89.6 GFLOP/s for the Ice Lake Xeon this was
  written on), printed with the rate of a one-thread BLAS dgemm (numpy, ``--dgemm`` square)
  measured in the rounds beside it; ``% peak`` is of the nominal figure. (Warp's clang builds
  these kernels with 256-bit vectors on this core, no 512-bit instruction in their objects: their
  own ceiling is half the nominal; benchmarks/README.md, the element kernels' verdict.)
* the triad: ``rhs_throughput.triad_bandwidth`` (numpy a = b + s·c, 5 passes of 8 bytes an
  element), one thread, in cache (``--triad-cache`` elements, 3 arrays: 12 MB by default, inside
  the L3, as a launch's arrays at these grids are) and from DRAM (``--triad-dram``: 480 MB), a
  median a round, in the same rounds; for scale an L2-resident one (``--triad-l2``: 0.96 MB).

What it says: a kernel near the peak is bound by its arithmetic, one near the in-cache triad (its
arrays fit the L3 at these grids) by bandwidth, one far below both by neither: by its
instructions (the gathers through the DSS table, the loads and shuffles of its rows, the
divides), by latency, or by the loop Warp's CPU backend makes of it.

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 python benchmarks/micro/step/roofline.py kernel_roofline \
        --ne 30 12 --np 4 8 --rounds 41 --inner 2

``--precisions float64 float32`` adds each grid's model with a float32 tendency (the tendency's
kernel and the DSS reading it in float32; its % peak of float32's 16 lanes, twice float64's).
Written to ``results/roofline/kernel_roofline/kernel_roofline.json`` (``--results``: another stem).

``helmholtz_roofline``
~~~~~~~~~~~~~~~~~~~~~~
A roofline of the Helmholtz product (M + cK) y and of the CG iteration, per launch.

For each grid (TC5 at np4) and thread count, in one interleaved run: every
launch of a CG iteration in float64 and in float32 (``HelmholtzCG``):
``helmholtz_gradient``, ``helmholtz_divergence`` (with the DSS of the gradient
inside), ``helmholtz_assemble``, the vector update ``cg_update`` and, for scale,
a launch over one node (the launch overhead). Per launch: the bytes it must move
(each array it reads or writes counted once: the compulsory traffic) and the flops
a node (an FMA is 2), both from the kernels' code; the median time; the bytes'
rate; and the same bytes at this machine's stream-triad rate measured alongside
(numpy, a working set inside the L3 cache and one far outside it).

Then a whole solve of the semi-implicit Schur complement (``HelmholtzSolver.solve``, as the
steppers call it: its right-hand side, the CG from zero, the mean's correction and the
back-substitution; a replayed graph on one thread) at five tolerances, and a
least-squares line through (CG iterations k, ms): its slope is an iteration's cost and
its intercept the solve's fixed cost, also given in iterations (the target: a solve of
k iterations costs ≤ k + 1 products).

What it says: a launch at the triad's rate is bound by bandwidth; one far below
it, whose float32 form (half the bytes) is no faster, by the instructions around
its gathers (``gid``, the DSS table) and its branches; one whose time stays as
the grid shrinks, by launch overhead.

    SWE_SPHERE_THREADS=1 python benchmarks/micro/step/roofline.py helmholtz_roofline --clock cpu
    SWE_SPHERE_THREADS=2 python benchmarks/micro/step/roofline.py helmholtz_roofline --clock wall --threads 2
    SWE_SPHERE_THREADS=1 python benchmarks/micro/step/roofline.py helmholtz_roofline --clock cpu --ne 30 --solve-only
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py, the shared module
from results import positive, recorded, section, studies, timed  # noqa: E402  (after the path: benchmarks/ first)

# isort: split
import rhs_throughput  # noqa: E402  (benchmarks/: the triad)

from swe_sphere import Simulation, load_scene  # noqa: E402
from swe_sphere.core.parallel import SplitLaunch  # noqa: E402
from swe_sphere.core.tally import array_bytes  # noqa: E402
from swe_sphere.model.helmholtz_cg import HelmholtzCG  # noqa: E402

STUDIES = (
    "kernel_roofline",
    "helmholtz_roofline",
)  # the subcommands, a section of this docstring each


SCENES = {"tc5": "tc5_mountain", "galewsky": "galewsky"}  # Galewsky: TC5's terms less topography
TERMS = ("continuity", "momentum_advection", "coriolis", "pressure_gradient", "topography")

# The arguments a launch's compiled form does not read (a struct's field as "arg.field"), by kernel
# key (the tendency's without its terms); the tendency's {argument: the term without which it is unread}.
GHOST = ("d.ghost",)  # one rank: no neighbours' copies
UNREAD = {
    "tendency": {"forcing": "topography", "fcor": "coriolis"},
    "dss": ("d.spheremp", *GHOST),
    "laplacian_element__first": ("x", "d.table", "d.spheremp", "d.rspheremp", "Y", "delta", *GHOST),
    "laplacian_element__second": ("d.spheremp", "hs", "delta", *GHOST),
    "dss_apply": ("d.spheremp", *GHOST),
}
NAMES = {
    "tendency": "tendency",
    "dss": "dss",
    "laplacian_element__first": "laplacian first",
    "laplacian_element__second": "laplacian second+DSS",
    "dss_apply": "dss_apply",
}


def flops(kernel: str, np_: int, copies: float, terms: tuple) -> float:
    """Flops a node of ``kernel`` (its key, the tendency's without its terms), counted from its code (the module
    docstring); ``copies`` the mean table entries a node, ``terms`` the scene's."""
    cont, adv, cor, pg, topo = (t in terms for t in TERMS)
    grad = adv or pg
    if kernel == "tendency":
        fluxes = 9 * cont + 12 * adv + 2 * pg
        sweeps = 2 * np_ * 2 * (cont + grad + adv) + cont  # the divergence's two sweeps added
        end = cont + 6 * grad + (3 * adv + cor) + 4 * (adv or cor) + 2 * topo + 3  # + 3: times the element mass
        return fluxes + sweeps + end
    if kernel == "dss":  # unweighted: the tendency wrote spheremp·F
        return 3 * (copies + 1)
    laplacians = 4 * (8 * np_ + 7)
    if kernel == "laplacian_element__first":
        return 20 + laplacians + 22
    if kernel == "laplacian_element__second":
        return 4 * copies + 4 + laplacians + 7
    if kernel == "dss_apply":
        return 4 * copies + 20
    raise ValueError(f"no flop count for kernel {kernel}")


def compulsory_bytes(launch, unread) -> int:
    """Bytes of the distinct arrays among ``launch``'s arguments (``array_bytes``: each once, a
    struct's fields included), less the arguments named in ``unread`` ("arg" or "arg.field")
    unless another argument that is read holds the same array."""
    launch = launch.whole if isinstance(launch, SplitLaunch) else launch
    arrays = []
    for var, value in zip(launch.kernel.adj.args, launch.fwd_args):
        fields = getattr(getattr(value, "_cls", None), "vars", None)
        if fields:
            arrays += [getattr(value, f) for f in fields if f"{var.label}.{f}" not in unread]
        elif var.label not in unread:
            arrays.append(value)
    return sum(array_bytes(arrays).values())


class Grid:
    """One scene on one grid: its model's recorded launches of an RHS and a ∇⁴ substep, each
    with its name, flops and bytes a node; ``parts`` name → a call to time."""

    def __init__(self, scene: str, ne: int, np_: int, precision: str = "float64"):
        self.scene, self.ne, self.np, self.precision = scene, ne, np_, precision
        sim = Simulation(
            SCENES[scene], "cpu", progress=False, ne=ne, np=np_, days=1.0, graphs=False, precision=precision
        )
        m, x = sim.model, sim.x
        if not m.operators.per_element or m.hv is None or m.nu_div != m.nu:
            raise SystemExit(f"{scene} ne{ne} np{np_}: not the CPU element layout with a ∇⁴ of ν_div = ν")
        self.N = m.N
        self.copies = float((m.topology.table.numpy() >= 0).sum()) / m.N
        F, y = wp.zeros_like(x), wp.clone(x)
        m.rhs(x, F)
        rhs = [launch for launch in m.launches.recorded(m.rhs_key(x, F)) if hasattr(launch, "kernel")]
        n = m.hv.plan(sim.scene.dt)[0]
        hv = [launch for launch in m.hv.build(y, -sim.scene.dt / n) if hasattr(launch, "kernel")]
        missing = [t for t in TERMS if t not in m.terms]
        self.rows = {}  # name → (flops, bytes) a node
        self.parts = {}  # name → a call
        for group, launches in (("rhs", rhs), ("∇⁴ substep", hv)):
            total = [0.0, 0]
            for launch in launches:
                key = launch.kernel.key.removesuffix("_float32")  # a float32 kernel's: its flops are its type's
                kernel = "tendency" if key.startswith("tendency__") else key
                unread = UNREAD[kernel]
                if isinstance(unread, dict):
                    unread = tuple(arg for arg, term in unread.items() if term in missing)
                row = (flops(kernel, np_, self.copies, m.terms), compulsory_bytes(launch, unread) / m.N)
                self.rows[NAMES[kernel]] = row
                self.parts[NAMES[kernel]] = launch.launch
                total = [total[0] + row[0], total[1] + row[1]]
            self.rows[f"{group} (all)"] = tuple(total)
        self.parts["rhs (all)"] = lambda: m.rhs(x, F)
        self.parts["∇⁴ substep (all)"] = lambda: [launch.launch() for launch in hv]
        self.model = m  # keeps the arrays alive


def dgemm_rate(n: int) -> float:
    """GFLOP/s of one n×n float64 product by numpy's BLAS on one thread (2n³ flops), one call."""
    a, b = np.random.default_rng(0).random((2, n, n))
    with threadpool_limits(limits=1, user_api="blas"):
        start = time.process_time()
        a @ b
        return 2 * n**3 / (time.process_time() - start) / 1e9


def parse_kernel(argv: list[str]) -> argparse.Namespace:
    p = argparse.ArgumentParser(prog="roofline.py kernel_roofline", description=section(__doc__, "kernel_roofline"))
    p.add_argument("--ne", type=positive(int), nargs="+", default=[30, 12], help="grids, paired with --np")
    p.add_argument("--np", type=positive(int, 1), nargs="+", default=[4, 8], help="one per --ne")
    p.add_argument("--scenes", nargs="+", choices=sorted(SCENES), default=["tc5", "galewsky"])
    p.add_argument("--rounds", type=positive(int), default=41, help="interleaved rounds (medians)")
    p.add_argument(
        "--inner",
        type=positive(int),
        default=2,
        help="calls of a launch a round (few: a sample a preemption spoils is left out by the median)",
    )
    p.add_argument("--clock-ghz", type=positive(float), default=2.8, help="the nominal peak's clock")
    p.add_argument("--fma-units", type=positive(int), default=2, help="AVX-512 FMA units of the core")
    p.add_argument("--dgemm", type=positive(int), default=2000, help="the measured peak's matrix order")
    p.add_argument("--triad-l2", type=positive(int), default=40_000, help="elements of the L2 triad (for scale)")
    p.add_argument("--triad-cache", type=positive(int), default=500_000, help="elements of the in-cache (L3) triad")
    p.add_argument("--triad-dram", type=positive(int), default=20_000_000, help="elements of the DRAM triad")
    p.add_argument(
        "--precisions",
        nargs="+",
        choices=["float64", "float32"],
        default=["float64"],
        help="the models' precisions (float32: a float32 tendency; its peak twice float64's lanes)",
    )
    p.add_argument("--results", help="results/roofline/kernel_roofline/<STEM>.json (default: kernel_roofline)")
    args = p.parse_args(argv)
    if len(args.ne) != len(args.np):
        p.error(f"--ne and --np pair up: {len(args.ne)} ne against {len(args.np)} np")
    return args


def kernel_rows(args, grids: list, ms: dict, peak: float, l3: float, dram: float) -> list[dict]:
    """Print and return each grid's launches per element-local node: flop and bytes, ns, GFLOP/s
    against ``peak`` (the type's), GB/s against the triads in cache ``l3`` and from ``dram``."""
    head = (
        f"{'scene':<9} {'type':<7} {'kernel':<22} {'ne':>3} {'np':>2} {'flop/node':>9} {'B/node':>6} {'flop/B':>6} "
        f"{'ns/node':>8} {'GFLOP/s':>7} {'% peak':>6} {'GB/s':>6} {'% L3 triad':>10} {'% DRAM triad':>12}"
    )
    print(f"\nper element-local node; medians of {args.rounds} rounds\n{head}\n{'-' * len(head)}")
    rows = []
    for g, grid in enumerate(grids):
        own = peak * (2 if grid.precision == "float32" else 1)  # the type's lanes: float32 twice float64's
        for k, (fl, nbytes) in grid.rows.items():
            ns = statistics.median(ms[(g, k)]) * 1e6 / grid.N
            gflops, gbs = fl / ns, nbytes / ns
            print(
                f"{grid.scene:<9} {grid.precision:<7} {k:<22} {grid.ne:>3} {grid.np:>2} {fl:>9.1f} {nbytes:>6.1f} "
                f"{fl / nbytes:>6.2f} {ns:>8.2f} {gflops:>7.2f} {100 * gflops / own:>6.1f} {gbs:>6.2f} {100 * gbs / l3:>10.1f} "
                f"{100 * gbs / dram:>12.1f}"
            )
            rows.append(
                {
                    "scene": grid.scene,
                    "precision": grid.precision,
                    "kernel": k,
                    "ne": grid.ne,
                    "np": grid.np,
                    "nodes": grid.N,
                    "copies": round(grid.copies, 4),
                    "flops_per_node": fl,
                    "bytes_per_node": nbytes,
                    "ns_per_node": round(ns, 3),
                    "gflops": round(gflops, 3),
                    "percent_peak": round(100 * gflops / own, 2),
                    "gbs": round(gbs, 3),
                    "percent_triad_cache": round(100 * gbs / l3, 1),
                    "percent_triad_dram": round(100 * gbs / dram, 1),
                }
            )
        print()
    return rows


def kernel_costs(args: argparse.Namespace, figures: dict) -> None:
    rhs_throughput.clock = time.process_time  # its triad's clock
    peak = args.clock_ghz * 8 * 2 * args.fma_units
    print(
        f"one process, SWE_SPHERE_THREADS={os.environ['SWE_SPHERE_THREADS']}, CPU clock; "
        f"load average {os.getloadavg()[0]:.2f}; {args.rounds} rounds of {args.inner} calls a launch"
    )
    grids = [
        Grid(scene, ne, np_, precision)
        for scene in args.scenes
        for ne, np_ in zip(args.ne, args.np)
        for precision in args.precisions
    ]
    machine = {
        "dgemm": lambda: dgemm_rate(args.dgemm),
        "triad L2": lambda: rhs_throughput.triad_bandwidth(1, args.triad_l2, 25) / 1e9,
        "triad in cache": lambda: rhs_throughput.triad_bandwidth(1, args.triad_cache, 9) / 1e9,
        "triad DRAM": lambda: rhs_throughput.triad_bandwidth(1, args.triad_dram, 3) / 1e9,
    }
    rates = {k: [] for k in machine}
    ms = {(g, k): [] for g in range(len(grids)) for k in grids[g].parts}
    for _ in range(args.rounds):  # interleaved: load changes hit every part alike
        for k, f in machine.items():
            rates[k].append(f())
        for g, grid in enumerate(grids):
            for k, f in grid.parts.items():
                ms[(g, k)].append(timed(f, args.inner, 1))
    rate = {k: statistics.median(v) for k, v in rates.items()}
    l3, dram = rate["triad in cache"], rate["triad DRAM"]
    print(
        f"peak (float64, one core): nominal {peak:.1f} GFLOP/s = {args.clock_ghz:g} GHz × 8 lanes (AVX-512) × 2 (FMA) × "
        f"{args.fma_units} FMA units; measured dgemm (numpy BLAS, n = {args.dgemm}, one thread) {rate['dgemm']:.1f} "
        f"GFLOP/s = {100 * rate['dgemm'] / peak:.0f} % of it"
    )
    print(
        f"stream triad (numpy a = b + s·c, 5 passes of 8 B, one thread): {l3:.1f} GB/s in cache "
        f"(L3, {24 * args.triad_cache / 1e6:.0f} MB), {dram:.1f} GB/s from DRAM ({24 * args.triad_dram / 1e6:.0f} MB); "
        f"for scale {rate['triad L2']:.1f} GB/s in L2 ({24 * args.triad_l2 / 1e6:.2f} MB)"
    )
    rows = kernel_rows(args, grids, ms, peak, l3, dram)
    print(f"load average at the end {os.getloadavg()[0]:.2f}")
    figures.update(
        peak_gflops=peak,
        dgemm_gflops=round(rate["dgemm"], 2),
        triad_l2_gbs=round(rate["triad L2"], 2),
        triad_cache_gbs=round(l3, 2),
        triad_dram_gbs=round(dram, 2),
    )
    figures["rows"] = rows


def kernel_roofline(argv: list[str]) -> None:
    """``kernel_roofline``: its options from ``argv``, its runs, its results file."""
    arguments = parse_kernel(argv)
    with recorded(__file__, arguments.results, study="kernel_roofline") as figures:
        kernel_costs(arguments, figures)


TYPES = {"f64": wp.float64, "f32": wp.float32}


def traffic(np_: int, copies: int, N: int, nu: int, size: int) -> dict:
    """Launch → (bytes, flops) of one launch: every array read or written once (index
    arrays int32), flops counted from the kernels (an FMA as 2)."""
    i4 = 4
    return {
        # y through gid; Dinv (4), spheremp; wg (2) written
        "gradient": (nu * size + N * i4 + N * (4 + 1 + 2) * size, N * (4 * np_ + 8)),
        # wg (2) over the DSS table; rspheremp, y through gid, Dinv (4), metdet, spheremp; z written
        "divergence": (
            N * copies * i4 + N * i4 + nu * size + N * (2 + 1 + 4 + 1 + 1 + 1) * size,
            N * (4 * np_ + 2 * copies + 15),
        ),
        # wz through first and its table rows; y read, out written
        "assemble": (nu * (1 + copies) * i4 + N * size + 2 * nu * size, nu * (copies + 2)),
        # p, s, x, r, u, w, minv read; p, s, x, r, u written
        "cg_update": (12 * nu * size, 13 * nu),
    }


def triad(n: int, clock, repeat: int = 20) -> float:
    """GB/s of numpy's a = b + s·c over n float64 (3 arrays of n), median of ``repeat``."""
    a, b, c = np.zeros(n), np.ones(n), np.ones(n)
    times = []
    for _ in range(repeat):
        t0 = clock()
        np.multiply(c, 1.5, out=a)
        np.add(a, b, out=a)
        times.append(clock() - t0)
    return 4 * 8 * n / statistics.median(times) / 1e9  # c read, a written, a and b read


def launches(cg: HelmholtzCG, c: float) -> dict:
    """Name → the recorded launch of one CG iteration's product (u → w) and update."""
    cg.apply(cg.u, cg.w, c)  # records and sets c
    ops = [op for op in cg._operator(cg.u, cg.w) if hasattr(op, "kernel")]  # no exchanges on one rank
    return {"gradient": ops[0], "divergence": ops[1], "assemble": ops[2], "cg_update": cg._update}


def solve_cost(sim: Simulation, clock, repeat: int) -> tuple[list, float, float]:
    """[(k, ms)] of whole cold solves (IMEX ARS(3,4,3)'s at 8 Δt_g) at five tolerances (median of ``repeat`` rounds of 5),
    and the line ms = fixed + k·per_iteration through them: (rows, per_iteration, fixed)."""
    gw = sim.stepper.helmholtz
    sim.stepper.step(sim.x)  # H fixed, the step's graphs made
    gw.iterations()
    gw.warm = False
    r, z = wp.clone(sim.x), wp.zeros_like(sim.x)
    a = 0.4358665 * 8.0 * sim.scene.dt / sim.courant()["courant_gravity"]  # ARS(3,4,3)'s γΔt at 8 Δt_g
    rows = []
    for i, tol in enumerate((1e-1, 1e-3, 1e-5, 1e-7, 1e-9)):
        gw.tol, scale = tol, 1.0 + 1e-3 * i  # a graph of its own per tolerance (its key holds the scale)
        gw.solve(r, a, z, scale)
        k = gw.iterations()
        times = []
        for _ in range(repeat):
            t0 = clock()
            for _ in range(5):
                gw.solve(r, a, z, scale)
            wp.synchronize_device(sim.model.device)
            times.append((clock() - t0) / 5)
        gw.iterations()
        rows.append((k, statistics.median(times) * 1e3))
    k, ms = np.array(rows).T
    per_iteration, fixed = np.polyfit(k, ms, 1)
    return rows, per_iteration, fixed


def helmholtz_costs(argv: list[str]) -> None:
    """Each CG launch's time and traffic, and a whole solve's cost in iterations."""
    ap = argparse.ArgumentParser(
        prog="roofline.py helmholtz_roofline",
        description=section(__doc__, "helmholtz_roofline"),
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    ap.add_argument("--ne", type=int, nargs="+", default=[16, 30, 60])
    ap.add_argument("--repeat", type=int, default=15, help="rounds (each times every launch --inner times)")
    ap.add_argument("--inner", type=int, default=20)
    ap.add_argument("--clock", choices=("cpu", "wall"), default="cpu")
    ap.add_argument("--threads", type=int, default=int(os.environ.get("SWE_SPHERE_THREADS", "1")))
    ap.add_argument("--solve-only", action="store_true", help="only the whole solve's cost (no launch table)")
    args = ap.parse_args(argv)
    os.environ["SWE_SPHERE_THREADS"] = str(args.threads)
    clock = time.process_time if args.clock == "cpu" else time.perf_counter
    print(f"clock {args.clock}, {args.threads} thread(s), load average {os.getloadavg()[0]:.2f}")
    l3, dram = triad(500_000, clock), triad(40_000_000, clock, 5)
    print(f"stream triad (numpy): {l3:.1f} GB/s in cache (12 MB), {dram:.1f} GB/s from DRAM (960 MB)")
    for ne in args.ne:
        sim = Simulation(load_scene("tc5_mountain", ne=ne, stepper="imex"), "cpu", progress=False)
        m, topo = sim.model, sim.model.topology
        rows, per_iteration, fixed = solve_cost(sim, clock, args.repeat // 2 + 1)
        print(
            f"\nne {ne}: whole solves (CG iterations, ms): {', '.join(f'({k}, {ms:.2f})' for k, ms in rows)}; "
            f"an iteration {per_iteration:.3f} ms, fixed {fixed:.3f} ms = {fixed / per_iteration:.2f} iterations"
        )
        if args.solve_only:
            continue
        cgs = {name: (sim.stepper.helmholtz.cg if t is wp.float64 else HelmholtzCG(m, t)) for name, t in TYPES.items()}
        rng = np.random.default_rng(0)
        runs = {}
        for name, cg in cgs.items():
            cg.u.assign(rng.standard_normal(topo.nunique).astype(np.float32 if name == "f32" else np.float64))
            runs[name] = launches(cg, 1e9)
        tiny = wp.launch(_noop, 1, [wp.zeros(1, dtype=wp.float64)], device="cpu", record_cmd=True)
        times = {(name, k): [] for name in runs for k in runs[name]} | {("", "one-node launch"): []}
        for _ in range(args.repeat):
            for name, ls in runs.items():
                for k, launch in ls.items():
                    t0 = clock()
                    for _ in range(args.inner):
                        launch.launch()
                    times[(name, k)].append((clock() - t0) / args.inner)
            t0 = clock()
            for _ in range(args.inner):
                tiny.launch()
            times[("", "one-node launch")].append((clock() - t0) / args.inner)
        print(
            f"\nne {ne} np 4: N = {m.N} element-local nodes, {topo.nunique} unique, DSS table {topo.table.shape[1]} copies a node"
        )
        print(
            f"{'launch':<12} {'type':<4} {'ms':>7} {'MB':>6} {'GB/s':>6} {'B/node':>7} {'flop/node':>9} {'at L3 triad ms':>15} {'f32/f64':>8}"
        )
        for k in runs["f64"]:
            for name, t in TYPES.items():
                size = 8 if t is wp.float64 else 4
                nbytes, flops = traffic(4, topo.table.shape[1], m.N, topo.nunique, size)[k]
                ms = statistics.median(times[(name, k)]) * 1e3
                ratio = ms / (statistics.median(times[("f64", k)]) * 1e3)
                print(
                    f"{k:<12} {name:<4} {ms:7.3f} {nbytes / 1e6:6.2f} {nbytes / ms / 1e6:6.1f} {nbytes / m.N:7.1f} {flops / m.N:9.1f} "
                    f"{nbytes / l3 / 1e6:15.3f} {ratio:8.2f}"
                )
        print(f"one-node launch   {statistics.median(times[('', 'one-node launch')]) * 1e3:7.4f} ms")


@wp.kernel
def _noop(x: wp.array(dtype=wp.float64)):
    x[wp.tid()] = x[wp.tid()] + wp.float64(1.0)


def helmholtz_roofline(argv: list[str]) -> None:
    """``helmholtz_roofline``: its options from ``argv``, its runs, its results file."""
    with recorded(__file__, "helmholtz_roofline/helmholtz_roofline"):
        helmholtz_costs(argv)


if __name__ == "__main__":
    studies(__doc__, {name: globals()[name] for name in STUDIES})
