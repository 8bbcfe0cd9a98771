"""Probe (not used by the model): a per-element tendency kernel on the CPU.

The model's tendency is one fused kernel per node (``kernels.tendencies``),
which re-reads each element's row and column per node. This probe times, for
the same state and on one thread:

* the model's tendency kernel,
* ``fused_elem``: every term in one kernel, one thread per element, the
  element's fluxes computed once into local vectors (np² values each) and the
  derivatives taken from them (loops unrolled: np is a compile-time constant),
* the model's DSS launch,

and the largest difference from the model's tendency relative to the largest
single-term scale (they agree to round-off, not bit for bit).

    python benchmarks/probe_fused_rhs.py [--ne 30] [--np 4]
"""

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from swe_sphere.config import load_scene  # noqa: E402
from swe_sphere.grid import CubedSphere  # noqa: E402
from swe_sphere.kernels.operators import element_node  # noqa: E402
from swe_sphere.model import ShallowWater  # noqa: E402

f64 = wp.float64


def make_fused_elem(NP):
    NPP = NP * NP
    vecN = wp.types.vector(length=NPP, dtype=f64)

    @wp.kernel(module="unique")
    def fused_elem(x: wp.array2d(dtype=f64), D: wp.array2d(dtype=f64), Dinv: wp.array2d(dtype=f64), metdet: wp.array(dtype=f64),
                   fcor: wp.array(dtype=f64), forcing: wp.array2d(dtype=f64), dvv: wp.array2d(dtype=f64), g: f64,
                   tend: wp.array2d(dtype=f64), offset: int):
        e = wp.tid() + offset
        base = e * NPP
        f1 = vecN()
        f2 = vecN()
        E = vecN()
        c1 = vecN()
        c2 = vecN()
        for k in range(NPP):
            q = base + k
            u = x[0, q]
            v = x[1, q]
            h = x[2, q]
            Jh = metdet[q] * h
            f1[k] = Jh * (Dinv[0, q] * u + Dinv[1, q] * v)
            f2[k] = Jh * (Dinv[2, q] * u + Dinv[3, q] * v)
            E[k] = f64(0.5) * (u * u + v * v) + g * h
            c2[k] = D[1, q] * u + D[3, q] * v
            c1[k] = D[0, q] * u + D[2, q] * v
        for j in range(NP):
            for i in range(NP):
                div = f64(0.0)
                ex = f64(0.0)
                ee = f64(0.0)
                dv2 = f64(0.0)
                dv1 = f64(0.0)
                for m in range(NP):
                    a = dvv[i, m]
                    b = dvv[j, m]
                    div += a * f1[j * NP + m] + b * f2[m * NP + i]
                    ex += a * E[j * NP + m]
                    ee += b * E[m * NP + i]
                    dv2 += a * c2[j * NP + m]
                    dv1 += b * c1[m * NP + i]
                p = base + j * NP + i
                rJ = f64(1.0) / metdet[p]
                zf = (dv2 - dv1) * rJ + fcor[p]
                tend[0, p] = zf * x[1, p] - (Dinv[0, p] * ex + Dinv[2, p] * ee) + forcing[0, p]
                tend[1, p] = -zf * x[0, p] - (Dinv[1, p] * ex + Dinv[3, p] * ee) + forcing[1, p]
                tend[2, p] = -div * rJ
    return fused_elem


def median_time(fn, repeat=30):
    fn()
    ts = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return statistics.median(ts)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--ne", type=int, default=30)
    ap.add_argument("--np", type=int, default=4)
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.config.log_level = wp.LOG_ERROR
    ne, np_ = args.ne, args.np
    scene = load_scene("tc5_mountain", ne=ne, np=np_)
    grid = CubedSphere(ne, np_)
    case = scene.make_case()
    fcor, hs = case.fcor(grid.lat, grid.lon), case.hs(grid.lat, grid.lon)
    terms = [t for t in scene.terms if t != "hyperviscosity"]
    m = ShallowWater(grid, terms, fcor, hs, device="cpu", threads=1)
    x = m.new_state(*case.initial(grid.lat, grid.lon))
    out = wp.zeros_like(x)
    m.rhs(x, out)
    ref = m.tend.numpy().copy()
    N = grid.npts
    t_elem = wp.zeros_like(x)
    le = wp.launch(make_fused_elem(np_), grid.nelem, [x, m.D, m.Dinv, m.metdet, m.fcor, m.topo_forcing, m.dvv, f64(m.g), t_elem, 0], device="cpu", record_cmd=True)
    le.launch()
    per_term = []
    for t in terms:
        mt = ShallowWater(grid, [t], fcor, hs, device="cpu", threads=1)
        o = wp.zeros_like(x)
        mt.rhs(x, o)
        per_term.append(np.abs(mt.tend.numpy()).max(axis=1))
    scale = np.max(per_term, axis=0)
    scale = np.array([scale[:2].max(), scale[:2].max(), scale[2]])
    err = (np.abs(t_elem.numpy() - ref).max(axis=1) / scale).max()
    tendency, dss = m._recorded[("rhs", x.ptr, out.ptr)][0]
    t0, t2, t3 = (median_time(f) for f in (tendency.launch, le.launch, dss.launch))
    print(f"ne={ne} np={np_} N={N}, 1 thread, medians of 30 (ms):")
    print(f"  model tendency (per node) {1e3 * t0:7.3f}   per element {1e3 * t2:7.3f} (x{t0 / t2:.1f})   DSS {1e3 * t3:7.3f}")
    print(f"  RHS (tendency + DSS): now {N / (t0 + t3) / 1e6:.1f} Mpts/s; with the per-element kernel {N / (t2 + t3) / 1e6:.1f} Mpts/s")
    print(f"  max difference / largest single-term scale: {err:.1e}")


if __name__ == "__main__":
    main()
