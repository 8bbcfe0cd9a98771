"""What a replaced path justified, kept runnable (not kept current): each study measured a layout or
an algorithm against the one the package took instead. One subcommand a study, each written to
``results/replaced_paths/<study>/<stem>.json``::

    python benchmarks/archive/replaced_paths.py STUDY [its options]   # STUDY --help: its options

``across_elements``
~~~~~~~~~~~~~~~~~~~
The element index innermost (issue 99, item 2's "vectorisation across elements"), measured
before it is built: two element passes in today's CPU layout against a layout with W elements a
vector, both in one process, interleaved.

- **rows** (today's): a thread an element, its fields as np GLL rows (``operators.row_vectors``),
  every derivative sweep ``along`` a row (``operators.row_derivatives``, the rolled form of np ≥ 5);
- **across**: a thread W elements, every node value a vector of those W elements' values, each
  sweep a sum of dvv's scalars times such vectors, through a scratch array between the passes.

The passes: one field's **weak Laplacian** −Σ ∂ᵀ(G ∇_ref f) (the ∇⁴'s element pass, the arithmetic
of ``kernels.hyperviscosity_element.laplacian_element`` for one field, written here on rows; across, the
package's ``weak_laplacian_across``, which the ∇⁴ runs at np ≥ 5 since it was measured here), and
the **tendency** of `galewsky`'s terms (continuity, momentum advection, Coriolis, the pressure
gradient; mass-weighted): rows the package's own ``kernels.tendencies.tendency_element``, across
the same sums and its pointwise end (``tendencies.finish``, generic over the value type). The
same products summed in the same order at every node: the run says whether the bits agree, and
how far apart the two are (the largest difference over the largest value).
Random fields, metric and dvv (the arithmetic, not the operator, is timed: depths and metdet
kept positive); for each ``--case NP,NE,W``, ``--rounds`` rounds of about 2 M node updates each
layout in turn, the median CPU ns a node (``time.process_time``, one thread) and the ratio.
Figures to ``benchmarks/results/replaced_paths/across_elements/across_elements[_STEM].json``::

    SWE_SPHERE_THREADS=1 taskset -c 0 python benchmarks/archive/replaced_paths.py across_elements --case 8,12,16 8,25,16 6,25,16 4,30,16 8,12,8 8,12,4

``dss_by_element``
~~~~~~~~~~~~~~~~~~
The DSS by element on GLL rows (``kernels.dss.dss_update_elements``, the CPU's
form since issue 99) against the node gather it replaced (``dss_rows``/``dss_update``): a step's
CPU cost, both in one process, interleaved.

For each ``--scene`` on its own grid (or ``--ne``/``--np``), at its own stepper and Δt, two models:
one as shipped and one built with the node gather (``Topology.element_rows`` False); each stepped
``--steps`` steps a round, ``--rounds`` rounds taken in turn so that a change of load hits both
alike; the median CPU ms a step (``time.process_time``, one thread) and the ratio. The two give
the same bits (tests/grid/test_dss_by_element.py); the run checks it on the states after the
rounds. Figures to ``benchmarks/results/replaced_paths/dss_by_element/dss_by_element[_STEM].json``::

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/archive/replaced_paths.py dss_by_element --scene galewsky tc5_mountain
"""

# no `from __future__ import annotations`: Warp reads the kernels' annotations as objects
import argparse
import os
import statistics
import sys
import time
from pathlib import Path
from unittest import mock

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import interleaved, positive, recorded, section, studies  # noqa: E402  (after the path: benchmarks/ first)

from swe_sphere import Simulation  # noqa: E402
from swe_sphere.grid.topology import Topology  # noqa: E402
from swe_sphere.kernels.hyperviscosity_across import weak_laplacian_across  # noqa: E402
from swe_sphere.kernels.operators import CPU_FAST, covariant_inverse, dvv_matrix, row_derivatives, times  # noqa: E402
from swe_sphere.kernels.tendencies import finish, tendency_element  # noqa: E402

STUDIES = (
    "across_elements",
    "dss_by_element",
)  # the subcommands, a section of this docstring each


TERMS = ("continuity", "momentum_advection", "coriolis", "pressure_gradient")  # galewsky's

f64 = wp.float64


def case(text: str) -> tuple[int, int, int]:
    """``NP,NE,W``: np 2–8, ne ≥ 1, 1 ≤ W ≤ 6 ne² (the across layout takes the first W ⌊6 ne²/W⌋
    elements: a whole layout would pad the last vector)."""
    try:
        np_, ne, w = (int(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--case wants NP,NE,W (got {text!r})") from None
    if not (2 <= np_ <= 8 and ne >= 1 and 1 <= w <= 6 * ne * ne):
        raise argparse.ArgumentTypeError(f"--case {text}: np 2-8, ne >= 1 and W from 1 to 6 ne^2")
    return np_, ne, w


def across_arguments(argv: list[str]):
    p = argparse.ArgumentParser(
        prog="replaced_paths.py across_elements", description=section(__doc__, "across_elements")
    )
    p.add_argument(
        "--case",
        type=case,
        nargs="+",
        default=[(8, 12, 16), (8, 25, 16), (6, 25, 16), (4, 30, 16), (8, 12, 8), (8, 12, 4)],
    )
    p.add_argument("--rounds", type=positive(int), default=15)
    p.add_argument("--results", default=None, help="the results file's stem (default: across_elements)")
    return p.parse_args(argv)


def laplacian_kernels(NP: int, W: int):
    """The weak Laplacian's two kernels at np ``NP``, ``W`` elements a vector (module "unique",
    ``CPU_FAST`` as the ∇⁴'s element kernels)."""
    vec, mat, along, _ = row_derivatives(NP)
    vw = wp.types.vector(length=W, dtype=f64)

    def weak_rows(F: mat, G11: mat, G12: mat, G22: mat, dvv: mat, dvvT: mat, lo: int):
        out = mat()
        fx = mat()
        fy = mat()
        for k in range(lo, lo + NP):  # a run-time start, as the package's rolled rows
            j = k - lo
            a = along(F[j], dvvT)
            b = along(dvv[j], F)
            fx[j] = wp.cw_mul(G11[j], a) + wp.cw_mul(G12[j], b)
            fy[j] = wp.cw_mul(G12[j], a) + wp.cw_mul(G22[j], b)
        for k in range(lo, lo + NP):
            j = k - lo
            out[j] = -(along(fx[j], dvv) + along(dvvT[j], fy))
        return out

    weak_rows.__name__ = weak_rows.__qualname__ = f"weak_rows_np{NP}"
    lap = wp.func(weak_rows)

    def rows(src: wp.array(dtype=vec), g: wp.array2d(dtype=vec), dvv: mat, L: wp.array(dtype=vec)):
        base = wp.tid() * NP
        G11 = mat()
        G12 = mat()
        G22 = mat()
        X = mat()
        for j in range(NP):
            G11[j] = g[0, base + j]
            G12[j] = g[1, base + j]
            G22[j] = g[2, base + j]
            X[j] = src[base + j]
        Lr = lap(X, G11, G12, G22, dvv, wp.transpose(dvv), base)
        for j in range(NP):
            L[base + j] = Lr[j]

    sweeps = weak_laplacian_across(NP, W)  # the package's (the ∇⁴'s own with W elements a vector)
    NN = NP * NP

    def across(
        F: wp.array2d(dtype=vw),
        g: wp.array2d(dtype=vw),
        dvv: mat,
        X: wp.array(dtype=vw),
        fx: wp.array(dtype=vw),
        fy: wp.array(dtype=vw),
        L: wp.array2d(dtype=vw),
        n0: int,
    ):
        b = wp.tid()
        for n in range(n0, n0 + NN):  # the block into the scratch, as the ∇⁴'s kernel forms it there
            X[n] = F[b, n]
        sweeps(X, g, fx, fy, dvv, b * NN, n0)
        for n in range(n0, n0 + NN):
            L[b, n] = X[n]

    made = []
    for k in (rows, across):
        k.__name__ = k.__qualname__ = f"{k.__name__}_np{NP}_w{W}"
        made.append(wp.kernel(k, enable_backward=False, module="unique", module_options=CPU_FAST))
    return vec, vw, made


def tendency_across(NP: int, W: int):
    """The tendency of ``TERMS`` (mass-weighted) with W elements a vector: the fluxes, the
    Bernoulli function and the covariant wind into a scratch array s (5, ·), then the six
    sweeps of ``tendency_element`` (each its own sum, in its order) and ``finish``."""
    vw = wp.types.vector(length=W, dtype=f64)
    mat = row_derivatives(NP)[1]
    NN = NP * NP
    end = finish(TERMS, True)

    def tendency(
        x: wp.array2d(dtype=vw),
        Dinv: wp.array2d(dtype=vw),
        metdet: wp.array(dtype=vw),
        fcor: wp.array(dtype=vw),
        forcing: wp.array2d(dtype=vw),
        mass: wp.array(dtype=vw),
        g: f64,
        dvv: mat,
        s: wp.array2d(dtype=vw),
        tend: wp.array2d(dtype=vw),
        n0: int,
    ):
        base = wp.tid() * NN
        for p in range(base + n0, base + n0 + NN):
            u = x[0, p]
            v = x[1, p]
            h = x[2, p]
            Jh = times(metdet[p], h)
            s[0, p] = times(Jh, times(Dinv[0, p], u) + times(Dinv[1, p], v))
            s[1, p] = times(Jh, times(Dinv[2, p], u) + times(Dinv[3, p], v))
            E = f64(0.5) * (times(u, u) + times(v, v))
            c1, c2 = covariant_inverse(Dinv, metdet, u, v, p)  # the rows' form (D not read)
            s[3, p] = c1
            s[4, p] = c2
            s[2, p] = E + g * h
        for j in range(n0, n0 + NP):
            for i in range(n0, n0 + NP):
                d1 = vw()
                d2 = vw()
                bx = vw()
                by = vw()
                cx = vw()
                cy = vw()
                for m in range(NP):
                    d1 += dvv[i, m] * s[0, base + j * NP + m]
                for m in range(NP):
                    d2 += dvv[j, m] * s[1, base + m * NP + i]
                for m in range(NP):
                    bx += dvv[i, m] * s[2, base + j * NP + m]
                for m in range(NP):
                    by += dvv[j, m] * s[2, base + m * NP + i]
                for m in range(NP):
                    cx += dvv[i, m] * s[4, base + j * NP + m]
                for m in range(NP):
                    cy += dvv[j, m] * s[3, base + m * NP + i]
                end(
                    base + j * NP + i,
                    base + j * NP + i,
                    d1 + d2,
                    bx,
                    by,
                    cx,
                    cy,
                    x,
                    Dinv,
                    metdet,
                    fcor,
                    forcing,
                    mass,
                    tend,
                )

    tendency.__name__ = tendency.__qualname__ = f"tendency_across_np{NP}_w{W}"
    return wp.kernel(tendency, enable_backward=False, module="unique", module_options=CPU_FAST)


def layouts(NP: int, nelem: int, W: int):
    """Array makers from (..., nelem, NP, NP) numpy values [element, j, i]: ``rows`` (..., nelem
    NP) of GLL rows, ``across`` (..., nb NP²) of W-element vectors over the first nb W elements."""
    vec = row_derivatives(NP)[0]
    vw = wp.types.vector(length=W, dtype=f64)
    nb, nn = nelem // W, NP * NP  # element e = W b + w at lane w of vector b

    def rows(a):
        return wp.array(a.reshape(*a.shape[:-3], nelem * NP, NP), dtype=vec)

    def across(a):
        lead = a.shape[:-3]
        t = a[..., : nb * W, :, :].reshape(*lead, nb, W, nn)
        return wp.array(np.moveaxis(t, -2, -1).reshape(*lead, nb * nn, W).copy(), dtype=vw)

    def back(a, across_layout):  # an output as (..., elements, NP²) numpy values
        v = a.numpy()
        if not across_layout:
            return v.reshape(*v.shape[:-2], nelem, nn)[..., : nb * W, :]
        v = v.reshape(*v.shape[:-2], nb, nn, W)
        return np.moveaxis(v, -1, -2).reshape(*v.shape[:-3], nb * W, nn)

    return rows, across, back, nb


def measure_across(kind: str, NP: int, ne: int, W: int, rounds: int) -> dict:
    """One pass (``kind``: "laplacian" or "tendency") at one case in both layouts, interleaved:
    CPU ns a node (medians), the ratio, and whether the outputs are bitwise equal."""
    nelem, nn = 6 * ne * ne, NP * NP
    rows, across, back, nb = layouts(NP, nelem, W)
    rng = np.random.default_rng(0)
    dvv = dvv_matrix(rng.standard_normal((NP, NP)))
    if kind == "laplacian":
        _, vw, (k_rows, k_across) = laplacian_kernels(NP, W)
        f, G = rng.standard_normal((nelem, NP, NP)), rng.standard_normal((3, nelem, NP, NP))
        src, g, Fa, ga = rows(f), rows(G), across(f), across(G)
        L, La = wp.zeros(nelem * NP, dtype=src.dtype), wp.zeros((nb, nn), dtype=vw)
        X, fx, fy = (wp.zeros(nn, dtype=vw) for _ in range(3))  # one thread: one scratch
        Fa = Fa.reshape((nb, nn))
        go_rows = lambda: wp.launch(k_rows, dim=nelem, inputs=[src, g, dvv, L], device="cpu")  # noqa: E731
        go_across = lambda: wp.launch(k_across, dim=nb, inputs=[Fa, ga, dvv, X, fx, fy, La, 0], device="cpu")  # noqa: E731
        outs = (L, La.reshape((nb * nn,)))
    else:
        k_rows, k_across = tendency_element(TERMS, NP, True), tendency_across(NP, W)
        shape = (nelem, NP, NP)
        x = rng.standard_normal((3, *shape))
        x[2] = 5e3 + 1e3 * x[2]  # a depth, m
        values = [x, rng.standard_normal((4, *shape))]  # x, Dinv
        values += [1 + rng.random(shape), 1e-4 * rng.standard_normal(shape), np.zeros((2, *shape)), rng.random(shape)]
        r_in, a_in = [rows(v) for v in values], [across(v) for v in values]  # metdet, fcor, forcing, mass last
        t_rows, t_across = wp.zeros((3, nelem * NP), dtype=r_in[0].dtype), wp.zeros((3, nb * nn), dtype=a_in[0].dtype)
        scratch = wp.zeros((5, nb * nn), dtype=a_in[0].dtype)
        g = f64(9.80616)
        h0 = wp.types.vector(NP, f64)()  # the float32 tendency's reference depth, unread in float64
        go_rows = lambda: wp.launch(k_rows, dim=nelem, inputs=[*r_in, g, h0, dvv, t_rows, 0], device="cpu")  # noqa: E731
        go_across = lambda: wp.launch(  # noqa: E731
            k_across, dim=nb, inputs=[*a_in, g, dvv, scratch, t_across, 0], device="cpu"
        )
        outs = (t_rows, t_across)
    go_rows(), go_across()
    o_rows, o_across = back(outs[0], False), back(outs[1], True)
    bitwise = bool(np.array_equal(o_rows, o_across))
    apart = float(np.abs(o_rows - o_across).max() / np.abs(o_rows).max())
    reps = max(1, round(2e6 / (nelem * nn)))
    ns = {"rows": [], "across": []}
    for _ in range(rounds):
        for name, go, count in (("rows", go_rows, nelem), ("across", go_across, nb * W)):
            t = time.process_time()
            for _ in range(reps):
                go()
            ns[name].append((time.process_time() - t) / reps / (count * nn) * 1e9)
    r, a = statistics.median(ns["rows"]), statistics.median(ns["across"])
    return {
        "pass": kind,
        "np": NP,
        "ne": ne,
        "W": W,
        "rows_ns": r,
        "across_ns": a,
        "ratio": a / r,
        "bitwise": bitwise,
        "apart": apart,
    }


def across_elements(argv: list[str]) -> None:
    """``across_elements``: its options from ``argv``, its runs, its results file."""
    args = across_arguments(argv)
    with recorded(__file__, args.results, study="across_elements") as figures:
        print(f"load average at the start: {os.getloadavg()}")
        out = [measure_across(kind, *c, args.rounds) for c in args.case for kind in ("laplacian", "tendency")]
        print(f"\nCPU ns a node, medians of {args.rounds} interleaved rounds, one thread")
        print(
            f"{'pass':>10} {'np':>3} {'ne':>4} {'W':>3} {'rows':>7} {'across':>7} {'ratio':>6} {'bitwise':>8} {'apart':>8}"
        )
        for o in out:
            print(
                f"{o['pass']:>10} {o['np']:>3} {o['ne']:>4} {o['W']:>3} {o['rows_ns']:7.2f} {o['across_ns']:7.2f} "
                f"{o['ratio']:6.3f} {str(o['bitwise']):>8} {o['apart']:8.1e}"
            )
        figures["cases"] = out
        print(f"load average at the end: {os.getloadavg()}")


def dss_arguments(argv: list[str]):
    p = argparse.ArgumentParser(prog="replaced_paths.py dss_by_element", description=section(__doc__, "dss_by_element"))
    p.add_argument("--scene", nargs="+", default=["galewsky", "tc5_mountain"])
    p.add_argument("--ne", type=positive(int), default=None)
    p.add_argument("--np", type=positive(int), default=None)
    p.add_argument("--steps", type=positive(int), default=48, help="steps a round")
    p.add_argument("--rounds", type=positive(int), default=9)
    p.add_argument("--results", default=None, help="results stem (default dss_by_element)")
    return p.parse_args(argv)


def measure_dss(scene: str, grid: dict, steps: int, rounds: int) -> dict:
    """CPU ms a step of ``scene`` with the DSS by element and by node, interleaved."""
    sims = {"element": Simulation(scene, "cpu", progress=False, days=1.0, graphs=False, **grid)}
    with mock.patch.object(Topology, "element_rows", False):
        sims["node"] = Simulation(scene, "cpu", progress=False, days=1.0, graphs=False, **grid)
    assert sims["element"].model.topology.edges is not None and sims["node"].model.topology.edges is None
    for sim in sims.values():  # recorded and compiled
        for _ in range(steps):
            sim.stepper.step(sim.x)
    med = interleaved({k: (lambda s=sim: s.stepper.step(s.x), steps) for k, sim in sims.items()}, rounds)
    same = bool(np.array_equal(sims["element"].x.numpy(), sims["node"].x.numpy()))
    s = sims["element"].scene
    return {
        "scene": scene,
        "grid": f"ne{s.ne} np{s.np}",
        "stepper": s.stepper,
        "node_ms": med["node"],
        "element_ms": med["element"],
        "ratio": med["element"] / med["node"],
        "bitwise": same,
        "steps": steps * (rounds + 1),
    }


def dss_by_element(argv: list[str]) -> None:
    """``dss_by_element``: its options from ``argv``, its runs, its results file."""
    args = dss_arguments(argv)
    grid = {k: v for k, v in (("ne", args.ne), ("np", args.np)) if v}
    with (
        recorded(__file__, args.results, study="dss_by_element") as figures,
        threadpool_limits(limits=1),
    ):
        print(f"load average at the start: {os.getloadavg()}")
        rows = [measure_dss(scene, grid, args.steps, args.rounds) for scene in args.scene]
        print(f"\nCPU ms a step, medians of {args.rounds} interleaved rounds of {args.steps} steps, one thread")
        print(f"{'scene':>22} {'grid':>9} {'stepper':>8} {'node':>8} {'element':>8} {'ratio':>6} {'bitwise':>8}")
        for r in rows:
            print(
                f"{r['scene']:>22} {r['grid']:>9} {r['stepper']:>8} {r['node_ms']:8.3f} {r['element_ms']:8.3f} "
                f"{r['ratio']:6.3f} {str(r['bitwise']):>8}"
            )
        figures["steps"] = rows
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    studies(__doc__, {name: globals()[name] for name in STUDIES})
