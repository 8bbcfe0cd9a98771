"""The element index innermost (issue 99, item 2's "vectorisation across elements"), measured
before it is built: one field's weak Laplacian −Σ ∂ᵀ(G ∇_ref f) (the ∇⁴'s element pass, the
`kernels.hyperviscosity.laplacian_element` arithmetic for one field) in today's CPU layout
against a layout with W elements a vector, both in one process, interleaved.

- **rows** (today's): a thread an element, its field as np GLL rows (``operators.row_vectors``),
  every derivative sweep ``along`` a row (``operators.row_derivatives``, the rolled form of np ≥ 5);
- **across**: a thread W elements, every node value a vector of those W elements' values, each
  sweep a sum of dvv's scalars times such vectors, fx and fy through a scratch array.

The same products summed in the same order at every node, so the two give the same bits (the
run checks it). Random fields, metric and dvv (the arithmetic, not the operator, is timed); for
each ``--case NP,NE,W``, ``--rounds`` rounds of about 2 M node updates each layout in turn, the
median CPU ns a node (``time.process_time``, one thread) and the ratio. Figures to
``benchmarks/results/across_elements[_STEM].json``::

    SWE_SPHERE_THREADS=1 taskset -c 0 python benchmarks/across_elements.py --case 8,12,16 8,25,16 6,25,16 4,30,16 8,12,8 8,12,4
"""


# no `from __future__ import annotations`: Warp reads the kernels' annotations as objects
import argparse
import os
import statistics
import time

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402

wp.config.quiet = True

from results import positive, recorded  # noqa: E402  (benchmarks/, the script's directory)

from swe_sphere.kernels.operators import CPU_FAST, dvv_matrix, row_derivatives  # noqa: E402

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


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--case",
        type=case,
        nargs="+",
        default=[(8, 12, 16), (8, 25, 16), (6, 25, 16), (4, 30, 16), (8, 12, 8), (8, 12, 4)],
    )
    p.add_argument("--rounds", type=positive(int), default=15)
    p.add_argument("--results", default=None, help="the results file's stem (default: the script's)")
    return p.parse_args()


def kernels(NP: int, W: int):
    """The two launches' kernels at np ``NP``, ``W`` elements a vector (module "unique",
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

    def across(
        F: wp.array2d(dtype=vw),
        g: wp.array3d(dtype=vw),
        dvv: mat,
        fx: wp.array2d(dtype=vw),
        fy: wp.array2d(dtype=vw),
        L: wp.array2d(dtype=vw),
        n0: int,
    ):
        b = wp.tid()
        for j in range(n0, n0 + NP):  # n0 = 0 at run time: only the sums over m unrolled (compile time)
            for i in range(n0, n0 + NP):
                a = vw()
                c = vw()
                for m in range(NP):
                    a += dvv[i, m] * F[b, j * NP + m]
                for m in range(NP):
                    c += dvv[j, m] * F[b, m * NP + i]
                n = j * NP + i
                fx[b, n] = wp.cw_mul(g[0, b, n], a) + wp.cw_mul(g[1, b, n], c)
                fy[b, n] = wp.cw_mul(g[1, b, n], a) + wp.cw_mul(g[2, b, n], c)
        for j in range(n0, n0 + NP):
            for i in range(n0, n0 + NP):
                s = vw()
                t = vw()
                for m in range(NP):
                    s += dvv[m, i] * fx[b, j * NP + m]
                for m in range(NP):
                    t += dvv[m, j] * fy[b, m * NP + i]
                L[b, j * NP + i] = -(s + t)

    made = []
    for k in (rows, across):
        k.__name__ = k.__qualname__ = f"{k.__name__}_np{NP}_w{W}"
        made.append(wp.kernel(k, enable_backward=False, module="unique", module_options=CPU_FAST))
    return vec, vw, made


def measure(NP: int, ne: int, W: int, rounds: int) -> dict:
    """One case's two layouts, interleaved: CPU ns a node (medians), the ratio, and the bits."""
    vec, vw, (k_rows, k_across) = kernels(NP, W)
    nelem, nodes = 6 * ne * ne, NP * NP
    rng = np.random.default_rng(0)
    f = rng.standard_normal((nelem, NP, NP))  # [element, j, i]
    G = rng.standard_normal((3, nelem, NP, NP))
    dvv = dvv_matrix(rng.standard_normal((NP, NP)))
    src, g = wp.array(f.reshape(-1, NP), dtype=vec), wp.array(G.reshape(3, -1, NP), dtype=vec)
    L = wp.zeros(nelem * NP, dtype=vec)
    nb = nelem // W  # element e = W b + w at lane w of vector b
    Fa = wp.array(f[: nb * W].reshape(nb, W, nodes).transpose(0, 2, 1).copy(), dtype=vw)
    ga = wp.array(G[:, : nb * W].reshape(3, nb, W, nodes).transpose(0, 1, 3, 2).copy(), dtype=vw)
    fx, fy, La = (wp.zeros((nb, nodes), dtype=vw) for _ in range(3))
    launches = {
        "rows": lambda: wp.launch(k_rows, dim=nelem, inputs=[src, g, dvv, L], device="cpu"),
        "across": lambda: wp.launch(k_across, dim=nb, inputs=[Fa, ga, dvv, fx, fy, La, 0], device="cpu"),
    }
    for go in launches.values():
        go()
    lr = L.numpy().reshape(nelem, nodes)[: nb * W]
    la = La.numpy().transpose(0, 2, 1).reshape(nb * W, nodes)
    reps = max(1, round(2e6 / (nelem * nodes)))
    ns = {name: [] for name in launches}
    for _ in range(rounds):
        for name, go in launches.items():
            t = time.process_time()
            for _ in range(reps):
                go()
            ns[name].append((time.process_time() - t) / reps / ((nelem if name == "rows" else nb * W) * nodes) * 1e9)
    r, a = statistics.median(ns["rows"]), statistics.median(ns["across"])
    return {
        "np": NP,
        "ne": ne,
        "W": W,
        "rows_ns": r,
        "across_ns": a,
        "ratio": a / r,
        "bitwise": bool(np.array_equal(lr, la)),
    }


def main() -> None:
    args = arguments()
    with recorded(__file__, args.results) as figures:
        print(f"load average at the start: {os.getloadavg()}")
        out = [measure(*c, args.rounds) for c in args.case]
        print(f"\none field's weak Laplacian, CPU ns a node, medians of {args.rounds} interleaved rounds, one thread")
        print(f"{'np':>3} {'ne':>4} {'W':>3} {'rows':>7} {'across':>7} {'ratio':>6} {'bitwise':>8}")
        for o in out:
            print(
                f"{o['np']:>3} {o['ne']:>4} {o['W']:>3} {o['rows_ns']:7.2f} {o['across_ns']:7.2f} "
                f"{o['ratio']:6.3f} {str(o['bitwise']):>8}"
            )
        figures["cases"] = out
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
