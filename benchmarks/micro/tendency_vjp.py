"""The tendency's vector–Jacobian product by Warp's automatic differentiation against the
hand-written transpose (issue 82, item 1): is it right, and what does it cost?

    SWE_SPHERE_THREADS=1 python benchmarks/micro/tendency_vjp.py [--ne 2 3 4] [--np 4 8]
        [--terms all | T,T ...] [--time 12:8 30:4] [--rounds 15] [--no-compile]

Warp's side (tests/adjoint/warp_vjp.py): the CPU's forward kernel ``tendency_element`` compiled
again with ``enable_backward=True`` (and ``wp.config.enable_vector_component_overwrites`` for
its compilation) and launched with ``adjoint=True``; the hand-written side:
``kernels.tendency_adjoint.element`` (k̄ one array). Both give x̄ = Tᵀ(x) W k̄ before the DSS
they share, and f̄ (the topographic forcing's adjoint).

1. Agreement, for every term set (default: all 31 non-empty sets of the five tendency terms),
   np and ne, random states, Coriolis, surface height and cotangents: max |x̄_warp − x̄_hand| /
   (ε S), S the size of each entry's sum (Σ |W k̄| |∂T/∂x| over its element, ``sum_sizes``),
   against the bound 2·depth (each side ≤ depth·ε·S, ``sum_depth``); f̄ max difference; and the
   dot-product test ⟨J v, w⟩ = ⟨v, Jᵀ w⟩ for both transposes, J v = (T(x + v) − T(x − v))/2
   exact in exact arithmetic (T is quadratic in x), as |gap| / (ε·size of the two sides' sums).
   Then the per-node kernel's autodiff (run-time GLL loop bound), all terms: its relative error.
2. CPU time on one thread (``time.process_time``, medians of ``--rounds`` interleaved rounds,
   one call each per round): the forward tendency kernel, the hand-written transpose, Warp's
   backward kernel alone and with what it needs besides (adj_x and f̄ zeroed, adj_tend = W k̄).
3. Compile times (a fresh Warp kernel cache in a child process): the forward kernel, the
   hand-written transpose, Warp's backward, all terms at each np.
"""

from __future__ import annotations

import argparse
import itertools
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded

sys.path.insert(
    0, str(Path(__file__).resolve().parents[2] / "tests" / "adjoint")
)  # not the root: it would shadow the package

import warp_vjp as V  # noqa: E402

from swe_sphere.kernels import tendencies  # noqa: E402

TERMS = tendencies.TENDENCY_TERMS
SHORT = {"continuity": "C", "momentum_advection": "A", "coriolis": "F", "pressure_gradient": "P", "topography": "T"}


def all_term_sets():
    return [s for n in range(1, len(TERMS) + 1) for s in itertools.combinations(TERMS, n)]


def dot_gap(m, x, v, w):
    """(hand, Warp): |⟨J v, w⟩ − ⟨v, Jᵀ w⟩| / (ε · size), size the sums' on both sides: the
    tendency's at x ± v through |J(y)| |y| + |forcing| against |w|, and |v| against |Jᵀ| |w|."""
    jv = 0.5 * (V.tendency(m, x + v) - V.tendency(m, x - v))
    kbar = w / m.grid.spheremp  # the cotangent w itself reaches the kernels' W k̄
    vjp = V.TendencyVJP(m, x, kbar)
    a, b, _, _ = vjp.both()
    forcing = np.zeros((3, m.N))
    if m.topo_forcing is not None:
        forcing[:2] = np.abs(m.topo_forcing.numpy())
    size = sum(0.5 * np.sum(V.sum_sizes(m, y, kbar) * np.abs(y) + np.abs(w) * forcing) for y in (x + v, x - v))
    size += np.sum(np.abs(v) * V.sum_sizes(m, x, kbar))
    left = math.fsum((jv * w).ravel())
    return [abs(left - math.fsum((v * t).ravel())) / (V.EPS * size) if size else 0.0 for t in (a, b)]


def agreement(ne, np_, terms, seed):
    m = V.model(ne, np_, terms, seed)
    rng = np.random.default_rng(seed + 1)
    x, k = V.random_state(m, rng), rng.standard_normal((3, m.N))
    a, b, fa, fb = V.TendencyVJP(m, x, k).both()
    diff, size = np.abs(a - b), V.EPS * V.sum_sizes(m, x, k)
    ratio = float(np.max(np.divide(diff, size, out=np.zeros_like(diff), where=size > 0), initial=0.0))
    rel = float(diff.max() / max(np.abs(a).max(), np.finfo(float).tiny))  # x̄ = 0 with topography alone
    v, w = V.random_state(m, rng) - [[0.0], [0.0], [5000.0]], rng.standard_normal((3, m.N))
    return ratio, rel, float(np.abs(fa - fb).max()), *dot_gap(m, x, v, w)


def per_node_error(ne, np_):
    """Warp's adjoint of the per-node kernel (``tendencies.tendency``: GLL loop bound read at run
    time), all terms, against the hand-written transpose: max |difference| / max |x̄|."""
    m = V.model(ne, np_, TERMS)
    rng = np.random.default_rng(5)
    x, k = V.random_state(m, rng), rng.standard_normal((3, m.N))
    a = V.TendencyVJP(m, x, k).both()[0]
    kernel = V.with_backward(tendencies.tendency(TERMS))
    z = [wp.zeros((r, m.N), dtype=V.f64) for r in (3, 2, 3)]
    args = [
        wp.array(x, dtype=V.f64),
        m.operators.Dinv,
        m.operators.metdet,
        m.operators.fcor,
        m.topo_forcing,
        m.spheremp,  # read by the mass-weighted kernel only
        m.operators.dvv,
        np_,
        m.g,
        0.0,  # h0, unread in float64
        z[2],
        0,
    ]
    tb = wp.array(k * m.grid.spheremp, dtype=V.f64)
    adj = [z[0], None, None, None, z[1], None, None, 0, 0.0, 0.0, tb, 0]
    wp.launch(kernel, m.N, args, adj_inputs=adj, adjoint=True)
    return float(np.abs(a - z[0].numpy()).max() / np.abs(a).max())


def timings(ne, np_, rounds):
    m = V.model(ne, np_, TERMS)
    rng = np.random.default_rng(7)
    vjp = V.TendencyVJP(m, V.random_state(m, rng), rng.standard_normal((3, m.N)))
    fns = {"forward": vjp.forward, "hand": vjp.hand, "warp": vjp.warp, "warp_full": vjp.warp_full}
    for fn in fns.values():
        fn()
    times = {k: [] for k in fns}
    for _ in range(rounds):
        for k, fn in fns.items():
            t0 = time.process_time()
            fn()
            times[k].append(time.process_time() - t0)
    return {k: statistics.median(t) for k, t in times.items()}, m.grid.nelem * np_ * np_


COMPILE_CHILD = """
import sys, time, warp as wp
wp.config.kernel_cache_dir = sys.argv[1]
wp.config.quiet = True
sys.path.insert(0, sys.argv[2])
import warp_vjp as V
from swe_sphere.kernels import tendencies, tendency_adjoint
wp.init()
for np_ in map(int, sys.argv[3:]):
    out = []
    for make in (lambda: tendencies.tendency_element(tendencies.TENDENCY_TERMS, np_),
                 lambda: tendency_adjoint.element(tendencies.TENDENCY_TERMS, np_, 1)):
        t0 = time.perf_counter(); wp.load_module(make().module, device="cpu"); out.append(time.perf_counter() - t0)
    t0 = time.perf_counter(); V.autodiff_kernel(tendencies.TENDENCY_TERMS, np_); out.append(time.perf_counter() - t0)
    print("compile", np_, *out)
"""


def compile_times(nps):
    with tempfile.TemporaryDirectory() as cache:
        here = str(Path(__file__).resolve().parents[2] / "tests" / "adjoint")
        done = subprocess.run(
            [sys.executable, "-c", COMPILE_CHILD, cache, here, *map(str, nps)], capture_output=True, text=True
        )
    if done.returncode:
        raise RuntimeError(done.stderr[-2000:])
    rows = [line.split()[1:] for line in done.stdout.splitlines() if line.startswith("compile ")]
    return {int(r[0]): [float(t) for t in r[1:]] for r in rows}


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--ne", type=int, nargs="+", default=[2, 3, 4])
    p.add_argument("--np", type=int, nargs="+", default=[4, 8])
    p.add_argument("--terms", nargs="+", default=["all"], help="'all' (every non-empty set) or comma lists")
    p.add_argument("--time", nargs="*", default=["12:8", "30:4"], help="ne:np grids to time, all terms")
    p.add_argument("--rounds", type=int, default=15)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--no-compile", action="store_true", help="skip the compile times (a fresh cache)")
    args = p.parse_args()
    sets = all_term_sets() if args.terms == ["all"] else [tuple(t.split(",")) for t in args.terms]
    quiet_warp()
    with recorded(__file__) as figures:
        print(f"threads: SWE_SPHERE_THREADS={os.environ.get('SWE_SPHERE_THREADS')}, load {os.getloadavg()}")
        print("1. agreement: ratio = max |x̄_warp − x̄_hand| / (ε S) (bound 2·depth); dot gaps / (ε size)")
        print(
            f"{'np':>3} {'terms':>6} {'bound':>6} {'ratio':>6} {'rel diff':>9} {'f̄ diff':>7} {'dot hand':>8} {'dot warp':>8}"
        )
        rows, worst = [], 0.0
        for np_ in args.np:
            bound = 2 * V.sum_depth(np_)
            for terms in sets:
                got = [agreement(ne, np_, terms, args.seed + ne) for ne in args.ne]
                ratio, rel, fdiff, dh, dw = (max(g[i] for g in got) for i in range(5))
                name = "".join(SHORT[t] for t in terms)
                rows.append(
                    {"np": np_, "terms": name, "bound": bound, "ratio": ratio, "rel": rel, "f": fdiff, "dot": [dh, dw]}
                )
                worst = max(worst, ratio / bound, dh / bound, dw / bound)
                print(f"{np_:>3} {name:>6} {bound:>6} {ratio:>6.2f} {rel:>9.1e} {fdiff:>7.1e} {dh:>8.3f} {dw:>8.3f}")
        figures["agreement"] = rows
        figures["worst_over_bound"] = worst
        print(f"ne {args.ne}; worst ratio / bound: {worst:.3f} ({'within' if worst <= 1 else 'OUTSIDE'} the bound)")
        node = per_node_error(2, 4)
        figures["per_node_autodiff_rel_error"] = node
        print(f"per-node kernel's autodiff (run-time GLL loop), all terms, ne 2 np 4: relative error {node:.2f}")
        print(
            "2. CPU time on one thread, all terms (median of interleaved rounds), ns a point and ratio to the forward"
        )
        figures["times"] = {}
        for grid in args.time:
            ne, np_ = map(int, grid.split(":"))
            t, points = timings(ne, np_, args.rounds)
            figures["times"][grid] = t
            cells = "  ".join(f"{k} {1e9 * v / points:6.1f} ({v / t['forward']:.2f})" for k, v in t.items())
            print(
                f"ne{ne} np{np_}: {cells}; warp/hand {t['warp'] / t['hand']:.2f}, full {t['warp_full'] / t['hand']:.2f}"
            )
        if not args.no_compile:
            print("3. compile s (fresh cache, all terms): forward, hand-written transpose, Warp backward")
            c = compile_times(args.np)
            figures["compile_s"] = c
            for np_, (f, h, w) in c.items():
                print(f"np{np_}: forward {f:.1f}  hand {h:.1f}  warp {w:.1f}")
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
