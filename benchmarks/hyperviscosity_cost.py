"""What one ∇⁴ hyperviscosity evaluation costs beside one RHS and one RK4 step.

TC5 (all terms, the scene's ν), np = 4, per ``--ne``: one RHS (``model.rhs``),
one B evaluation (``model.hyperviscosity_operator``, B = ν∇⁴), the split
hyperviscosity at RK4's Δt (``model.hyperviscosity``: forward-Euler substeps
or RKL1, as the steppers call it) and one RK4 step, timed alternately (one call
of each per round, so load hits them alike). Each is timed two ways:

- wall: ``time.perf_counter``, what a run waits for;
- cpu: ``time.process_time``, the CPU seconds the process spent (all its
  threads), which a busy machine does not inflate.

Medians of ``--repeat`` rounds, the ratios B/RHS and step/RHS on both clocks,
then the CPU time of each recorded launch of B and of the RHS (each launch
alone, medians), so the ratio can be read off its parts.

    python benchmarks/hyperviscosity_cost.py                 # ne 8 16 30
    SWE_SPHERE_THREADS=1 nice -n 10 python benchmarks/hyperviscosity_cost.py --ne 16

Diagnosis (ISSUE: "one ∇⁴ evaluation costs ~11 RHS", 2026-11-22, 2-core VM at
load 4.4–4.8, 1 thread, nice 10): on the CPU clock B is 2.4–3.5 RHS and an
RK4 step ~10 RHS (ne 16: RHS 0.82 ms, B 2.83 ms, step 8.3 ms); the wall-clock
medians of the same calls were 1.0 / 4.4 / 14.8 ms. The 11× came from wall
clocks under load: a call of ~1 ms usually finishes inside one scheduler time
slice, a call of several ms is usually preempted and waits out other
processes' slices (more so at nice 10), so the longer call's median is inflated
more (the same effect as in ``helmholtz_cost.py``'s note). What remains is
work, not waste: B is, as HOMME's ``biharmonic_wk``, two DSS'd weak Laplacians,
each of four rows (the 3 Cartesian wind components and h + hs), and a weak
Laplacian of a row is a gradient and a divergence, 2·2·np multiply-adds a node,
so one Laplacian pass does 4·4·np = 64 a node at np = 4 against the tendency
kernel's 6·np = 24 (gradient of the Bernoulli function, divergence of the mass
flux, vorticity). Per launch at ne 16 (CPU ms): tendency 0.33 + DSS(3 rows)
0.22 = RHS 0.86; B = Laplacian 0.60 + DSS(4) 0.21 + Laplacian (with Y₁)
0.80 + DSS(4) 0.20 + apply 0.20 = 2.06. Work per node is O(np) (one thread per
element, ``dvv`` compiled in); nothing is recomputed per call (the weak
Laplacian's metric spheremp·Dinv Dinvᵀ, formed by both kernels every call
before, is now ``model.hv_metric``: B ~7 % less CPU, bits unchanged); two
DSS, as HOMME. An RK4 step = 4 RHS + B + 7 linear combinations (~0.3 ms each: 2 of
the 10 RHS-eq).

Since issue 22 (benchmarks/README.md, ne 30, load 2): B is four passes, the
pointwise parts of each Laplacian done on its weak form before the DSS and the
last DSS adding coef·Y₂ to the state (first 1.7–2.0 + DSS 0.5 + second 1.2–1.3 +
``dss_apply`` 0.8 ms): 2.7 RHS; the RK4 step's combinations are written by its
DSS: 7.0–7.6 RHS-eq.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import warp as wp
from threadpoolctl import threadpool_limits

from swe_sphere.config import load_scene
from swe_sphere.simulation import Simulation


def setup(ne: int):
    """TC5 at (ne, 4) with RK4 at the scene's Δt: model, stepper, state x, and the
    calls to time (each on its own arrays, recorded once here)."""
    scene = load_scene("tc5_mountain", ne=ne, np=4, stepper="rk4")
    sim = Simulation(scene, "cpu", progress=False)
    m, st, x = sim.model, sim.stepper, sim.x
    f, b, y, z = m.new_state(), m.new_state(), wp.clone(x), wp.clone(x)
    calls = {
        "rhs": lambda: m.rhs(x, f),
        "B": lambda: m.hyperviscosity_operator(x, b),
        "hv(dt)": lambda: m.hyperviscosity(y, st.dt),
        "rk4 step": lambda: st.step(z),
    }
    for call in calls.values():
        call()  # compile and record
    return m, st, calls, (x, f, b)


def interleaved(calls: dict, repeat: int) -> dict:
    """name → (median wall s, median CPU s), one call of each per round."""
    wall = {k: [] for k in calls}
    cpu = {k: [] for k in calls}
    for _ in range(repeat):
        for k, call in calls.items():
            w0, c0 = time.perf_counter(), time.process_time()
            call()
            cpu[k].append(time.process_time() - c0)
            wall[k].append(time.perf_counter() - w0)
    return {k: (statistics.median(wall[k]), statistics.median(cpu[k])) for k in calls}


def launch_cpu(launches, repeat: int) -> list[tuple[str, float]]:
    """(kernel name, median CPU s) of each launch run alone."""
    out = []
    for launch in launches:
        times = []
        for _ in range(repeat):
            c0 = time.process_time()
            launch.launch()
            times.append(time.process_time() - c0)
        out.append((launch.kernel.key, statistics.median(times)))
    return out


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ne", type=int, nargs="+", default=[8, 16, 30])
    parser.add_argument("--repeat", type=int, default=40, help="timed rounds (default 40)")
    args = parser.parse_args(argv)
    wp.config.quiet = True
    threadpool_limits(1)  # BLAS, as in Simulation.run
    print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}; SWE_SPHERE_THREADS={os.environ.get('SWE_SPHERE_THREADS', '(unset)')}")
    for ne in args.ne:
        m, st, calls, (x, f, b) = setup(ne)
        t = interleaved(calls, args.repeat)
        rhs_w, rhs_c = t["rhs"]
        print(f"\nne={ne} np=4 N={m.N} threads={m.threads} per_element={m.per_element} RK4 dt={st.dt:.1f} s "
              f"(hv: {m.hypervis_substeps(st.dt)} substeps / {m.hypervis_stages(st.dt)} RKL1 stages), median of {args.repeat}")
        print(f"  {'call':9s} {'wall ms':>9s} {'cpu ms':>9s} {'wall/RHS':>9s} {'cpu/RHS':>9s}")
        for k, (w, c) in t.items():
            print(f"  {k:9s} {1e3 * w:9.3f} {1e3 * c:9.3f} {w / rhs_w:9.2f} {c / rhs_c:9.2f}")
        print(f"  B/RHS wall {t['B'][0] / rhs_w:.2f} cpu {t['B'][1] / rhs_c:.2f}; step/RHS wall {t['rk4 step'][0] / rhs_w:.2f} cpu {t['rk4 step'][1] / rhs_c:.2f}")
        for name, key in (("RHS", ("rhs", m.terms, x.ptr, f.ptr)), ("B", next(k for k in m._recorded if k[0] == "hvop"))):
            parts = launch_cpu(m._recorded[key][0], args.repeat)
            print(f"  {name} launches (cpu ms, each alone): " + " + ".join(f"{k} {1e3 * s:.3f}" for k, s in parts) + f" = {1e3 * sum(s for _, s in parts):.3f}")
    print(f"\nload average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f}")


if __name__ == "__main__":
    main()
