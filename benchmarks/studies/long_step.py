"""The long step (issue 81): how far past the explicit limit an IMEX step keeps a case's accuracy,
and what such a step costs, part by part, against the explicit step it would replace.

``--parts accuracy``: each run of ``--runs`` (``STEPPER@DT``, DT in s or ``86400/N``; with
``:key=value`` stepper options, e.g. ``imex@86400/90:scheme=ars232``, and ``:table.key=value`` the
scene's, e.g. ``kgu35@86400/548:hyperviscosity.every=12``) of ``--scene`` (default
``galewsky``, its own grid unless ``--ne``/``--np``) for ``--days``, scored at the last day by
Williamson et al. (1992) eq. 83 at the model's own unique nodes with its assembled ``spheremp``
(the run file's ``area``) against the bundled T341 reference (``cases.reference``): relative
vorticity and h + hs, the scorer of ``benchmarks/peers/peer_dinosaur.py``. Beside each: steps a day,
the Helmholtz CG iterations a step, CPU seconds of the step loop a simulated day (the run's own
ledger, day 1 to the last), or the day it blew up.

``--parts cost``: on the same grid, CPU milliseconds (medians of ``--rounds`` interleaved
rounds) of what a long step is made of: one RHS F(x) (the tendency and its DSS), one product
of the Helmholtz operator M + cK (``model.helmholtz_cg``: its three element launches; also in
float32, the kernels of the float32 solve: what cheaper arithmetic saves on this CPU), one
forward-Euler ∇⁴ substep, and a whole step of each run (replayed outside graphs).

``--parts direct``: the sparse direct alternative to the CG (the issue's "a direct
factorisation of the Helmholtz matrix per Δt"): M + cK assembled (``solvers.helmholtz_matrix``),
c = (γΔt)² g H of ARS(3,4,3) (γ = 0.4359) at the largest IMEX Δt of ``--runs``, factorised by
SuperLU (``scipy.sparse.linalg.splu``, its symmetric mode, two orderings): its nonzeros, the
factorisation's CPU seconds and one solve's milliseconds against a CG solve from zero to
1e-6 (``HelmholtzCG.solve``, the model's compiled CG).

One thread (``SWE_SPHERE_THREADS=1``; BLAS limited to one), CPU clock; figures to
``benchmarks/results/long_step/long_step[_STEM].json``::

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 python benchmarks/studies/long_step.py --parts cost direct accuracy \\
        --runs kgu35@86400/548 imex@86400/274 imex@86400/137 imex@86400/90 imex@86400/80 imex@86400/70
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("SWE_SPHERE_THREADS", "1")

import numpy as np  # noqa: E402
import warp as wp  # noqa: E402
from threadpoolctl import threadpool_limits  # noqa: E402

wp.config.quiet = True

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import DAY, recorded, timed  # noqa: E402  (after the path: benchmarks/ first)

# isort: split

from swe_sphere import (  # noqa: E402
    ArgumentError,
    BlowUp,
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)
from swe_sphere.cases.reference import Reference, reference_path, stored_days  # noqa: E402
from swe_sphere.model.helmholtz_cg import HelmholtzCG  # noqa: E402

ARS343_GAMMA = 0.4358665215084590  # ARS(3,4,3)'s diagonal (Ascher, Ruuth & Spiteri 1997, §2.7)


def parse_run(text: str) -> tuple[str, float, dict]:
    """``"imex@86400/90:scheme=ars232"`` → ("imex", 960.0, {"scheme": "ars232"}). ValueError."""
    head, *opts = text.split(":")
    stepper, _, dt = head.partition("@")
    num, _, den = dt.partition("/")
    try:
        seconds = float(num) / float(den) if den else float(num)
        options = {k: _value(v) for k, v in (o.split("=", 1) for o in opts)}
    except ValueError:
        raise ValueError(f"--runs {text!r}: expected STEPPER@DT[:key=value...]") from None
    return stepper, seconds, options


def _value(v: str):
    for kind in (int, float):
        try:
            return kind(v)
        except ValueError:
            pass
    return v


def simulation(args, stepper: str, dt: float, options: dict, days: float, **kw) -> Simulation:
    """The scene with this stepper, Δt and options (a table named as the stepper; a dotted key
    ``table.key`` the scene's table's; ``terms`` the scene's terms, joined by "+"), on the CPU."""
    grid = {k: v for k, v in (("ne", args.ne), ("np", args.np)) if v}
    tables = {}
    for key, value in options.items():
        if key == "terms":
            tables["terms"] = value.split("+")
            continue
        table, _, name = key.rpartition(".")
        tables.setdefault(table or stepper, {})[name] = value
    return Simulation(
        args.scene, "cpu", progress=False, stepper=stepper, dt=dt, days=days, graphs=False, **grid, **tables, **kw
    )


def l2(w, f, f_true) -> float:
    """Williamson et al. (1992) eq. 83 with quadrature weights ``w``."""
    return float(np.sqrt(np.sum(w * (f - f_true) ** 2) / np.sum(w * f_true**2)))


def accuracy(args, runs, figures: dict) -> None:
    import netCDF4

    reference = None
    print(f"\n## accuracy: {args.scene}, day {args.days:g}, eq. 83 against {args.reference}")
    print(f"{'run':>30} {'dt s':>8} {'steps/day':>9} {'vort l2':>8} {'h+hs l2':>9} {'CG/step':>7} {'CPU s/day':>9}")
    rows = []
    for text, (stepper, dt, options) in runs:
        sim = simulation(args, stepper, dt, options, args.days, output={"every_days": 1.0})
        reference = reference or Reference(reference_path(sim.case, args.reference))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "run.nc"
            try:
                result = sim.run(path)
            except BlowUp as e:  # the run's own line: step, day, where
                print(f"{text:>30} {dt:8.1f} {DAY / dt:9.1f}  blew up: {e}")
                rows.append({"run": text, "dt": dt, "blowup": str(e)})
                continue
            if result.blowup:
                print(f"{text:>30} {dt:8.1f} {DAY / dt:9.1f}  blew up: {result.blowup}")
                rows.append({"run": text, "dt": dt, "blowup": result.blowup})
                continue
            with netCDF4.Dataset(path) as ds:
                lat, lon, area, hs = (np.asarray(ds[k][...], dtype=np.float64) for k in ("lat", "lon", "area", "hs"))
                zeta, h = (np.asarray(ds[k][-1], dtype=np.float64) for k in ("vorticity", "h"))
        ref = reference.at(args.days, np.radians(lat), np.radians(lon))
        history = {round(rec["steps"] * dt / DAY, 6): rec for rec in result.history}
        cpu = (history[args.days]["cpu_time"] - history[1.0]["cpu_time"]) / (args.days - 1.0)
        cg = result.iterations.get("helmholtz", 0) / max(result.steps, 1)
        row = {
            "run": text,
            "dt": dt,
            "vorticity_l2": l2(area, zeta, ref["vorticity"]),
            "h_surface_l2": l2(area, h + hs, ref["h_surface"]),
            "cg_per_step": cg,
            "cpu_per_day": cpu,
        }
        rows.append(row)
        print(
            f"{text:>30} {dt:8.1f} {DAY / dt:9.1f} {row['vorticity_l2']:8.4f} {row['h_surface_l2']:9.3e} "
            f"{cg:7.1f} {cpu:9.2f}"
        )
    figures["accuracy"] = rows


def cost(args, runs, figures: dict) -> None:
    base = simulation(args, "kgu35", runs[0][1][1], {}, 1.0)
    m, x = base.model, base.x
    F = wp.zeros_like(x)
    cg, cg32 = HelmholtzCG(m), HelmholtzCG(m, dtype=wp.float32)  # the float32 solve's CG
    u = np.random.default_rng(0).random(m.topology.nunique)
    cg.u.assign(u)
    cg32.u.assign(u.astype(np.float32))
    y = wp.clone(x)
    hv_dt = runs[0][1][1]  # one forward-Euler substep at the explicit Δt (``Hyperviscosity.plan``)
    assert m.hv.plan(hv_dt) == (1, False), "the first run's Δt must take one ∇⁴ substep"
    parts = {
        "rhs": lambda: m.rhs(x, F),
        "helmholtz product": lambda: cg.apply(cg.u, cg.w, 1e10),
        "helmholtz product, float32": lambda: cg32.apply(cg32.u, cg32.w, 1e10),
        "hyperviscosity substep": lambda: m.hv.apply(y, hv_dt),
    }
    steppers = {}
    for text, (stepper, dt, options) in runs:
        sim = simulation(args, stepper, dt, options, 1.0)
        for _ in range(3):  # recorded, compiled, the solvers' histories filled
            sim.try_step(sim.x)
        steppers[text] = sim
        parts[f"step {text}"] = lambda sim=sim: sim.try_step(sim.x)
    for fn in parts.values():
        fn()
    ms = {k: [] for k in parts}
    for _ in range(args.rounds):  # interleaved: load changes hit every part alike
        for k, fn in parts.items():
            ms[k].append(timed(fn, args.reps if not k.startswith("step") else max(1, args.reps // 4), 1))
    med = {k: statistics.median(v) for k, v in ms.items()}
    rhs = med["rhs"]
    print(f"\n## cost: {args.scene} ne{m.grid.ne} np{m.grid.np}, CPU ms (medians of {args.rounds} rounds), one thread")
    print(f"{'part':>42} {'ms':>8} {'RHS':>6} {'ms per explicit Δt':>18}")
    dt0 = runs[0][1][1]
    for k, v in med.items():
        per = ""
        if k.startswith("step"):
            per = f"{v * dt0 / steppers[k[5:]].scene.dt:18.2f}"
        print(f"{k:>42} {v:8.3f} {v / rhs:6.2f} {per}")
    hv = m.hv
    print(f"(∇⁴: ν {hv.nu_max:.3g} m⁴/s; a step of Δt takes {{Δt: evaluations, RKL1}}: ", end="")
    print({round(sim.scene.dt, 1): sim.model.hv.plan(sim.scene.dt) for sim in steppers.values()}, ")")
    figures["cost_ms"] = med


def direct(args, runs, figures: dict) -> None:
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla

    from swe_sphere.model.gravity_wave import reference_depth
    from swe_sphere.solvers.helmholtz_matrix import helmholtz_matrix

    imex = [dt for _, (stepper, dt, _) in runs if stepper != "kgu35"] or [runs[0][1][1]]
    dt = max(imex)
    sim = simulation(args, "kgu35", runs[0][1][1], {}, 1.0)
    m = sim.model
    area = m.topology.area
    H = reference_depth(m.topology.mean(sim.x.numpy()[2]))
    c = (ARS343_GAMMA * dt) ** 2 * m.g * H
    t = time.process_time()
    K = helmholtz_matrix(m)
    A = (sp.diags(area) + c * K).tocsc()
    assembled = time.process_time() - t
    b = A @ np.random.default_rng(1).standard_normal(A.shape[0])
    out = {"n": A.shape[0], "nnz": int(A.nnz), "c": c, "dt": dt, "assemble_s": assembled}
    print(f"\n## direct: M + cK at Δt {dt:.1f} s (c = {c:.3g} m²), {A.shape[0]} unknowns, {A.nnz} nonzeros")
    for ordering in ("MMD_AT_PLUS_A", "COLAMD"):
        t = time.process_time()
        lu = spla.splu(A, permc_spec=ordering, options={"SymmetricMode": True})
        factor = time.process_time() - t
        solve = timed(lambda lu=lu: lu.solve(b), 3, 3)
        res = float(np.linalg.norm(A @ lu.solve(b) - b) / np.linalg.norm(b))
        fill = int(lu.L.nnz + lu.U.nnz)
        out[ordering] = {"factor_s": factor, "solve_ms": solve, "fill": fill, "residual": res}
        print(f"  SuperLU {ordering:>14}: L+U {fill} nonzeros, factor {factor:.1f} s, solve {solve:.1f} ms ({res:.1e})")
    cg = HelmholtzCG(m)
    cg.b.assign(b)

    def cg_solve():
        cg.solve(c, 1e-6, 1000, warm=False)

    ms = timed(cg_solve, 3, 3)
    iters = cg.stats.numpy()[0] / 10.0  # 1 + 3 × 3 solves counted
    print(f"  the model's CG from zero to 1e-6: {iters:.0f} iterations, {ms:.1f} ms")
    out["cg"] = {"solve_ms": ms, "iterations": iters}
    figures["direct"] = out


def arguments():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default="galewsky")
    p.add_argument("--ne", type=int, default=0)
    p.add_argument("--np", type=int, default=0)
    p.add_argument("--days", type=float, default=6.0)
    p.add_argument("--runs", nargs="+", default=["kgu35@86400/548", "imex@86400/137", "imex@86400/90"])
    p.add_argument("--parts", nargs="+", default=["cost"], choices=("cost", "direct", "accuracy"))
    p.add_argument("--reference", default="T341")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--reps", type=int, default=20)
    p.add_argument("--results", default=None, help="results stem (default long_step)")
    return p.parse_args()


def main() -> None:
    args = arguments()
    if "accuracy" in args.parts:  # its day, checked before the other parts' runs
        path = reference_path(load_scene(args.scene).make_case(), args.reference)
        days = [] if path is None else stored_days(path)
        if not np.isclose(days, args.days).any():
            raise ArgumentError(f"--days {args.days:g}: not a day {args.reference} stores for {args.scene} ({days})")
    runs = [(text, parse_run(text)) for text in args.runs]
    with recorded(__file__, args.results) as figures, threadpool_limits(limits=1):
        print(f"load average at the start: {os.getloadavg()}")
        for part in args.parts:
            {"cost": cost, "direct": direct, "accuracy": accuracy}[part](args, runs, figures)
        print(f"load average at the end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
