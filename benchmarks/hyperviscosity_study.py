"""Error against the T213 reference as a function of the hyperviscosity coefficients.

Runs a scene on one grid for each (ν, ν_div, ν_s) given (m⁴ s⁻¹, used as
given, not rescaled) and prints the normalized l2 error of h + hs and of the
wind against the T213 reference at every day the reference stores, and of the
relative vorticity at the end (where grid-scale noise shows first). One JSON
line per run is appended to --out (runs already there are skipped, so the
study can be resumed or extended).

    SWE_SPHERE_THREADS=1 python benchmarks/hyperviscosity_study.py tc6_rossby_haurwitz --ne 30 \\
        --nus 1.5e15 1.5e14:1.5e15:1.5e14 0 --out tc6_ne30.jsonl

A value "nu" sets all three; "nu:nu_div:nu_s" sets them apart; 0 drops the term.
"""

import argparse
import dataclasses
import json
import math
from pathlib import Path

from swe_sphere.config import load_scene
from swe_sphere.constants import DAY
from swe_sphere.scoring import williamson_norms
from swe_sphere.simulation import BlowUp, Simulation


def parse_nus(spec: str) -> tuple:
    parts = [float(p) for p in spec.split(":")]
    return tuple(parts * 3) if len(parts) == 1 else tuple(parts)


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("scene")
    p.add_argument("--ne", type=int)
    p.add_argument("--np", type=int)
    p.add_argument("--days", type=float)
    p.add_argument("--stepper")
    p.add_argument("--dt", type=float)
    p.add_argument("--nus", nargs="+", required=True, help="nu or nu:nu_div:nu_s (m^4/s)")
    p.add_argument("--out", type=Path, required=True)
    args = p.parse_args()
    base = load_scene(args.scene, ne=args.ne, np=args.np, days=args.days, stepper=args.stepper, dt=args.dt)
    done = set()
    if args.out.exists():
        done = {tuple(json.loads(line)["key"]) for line in args.out.read_text().splitlines() if line.strip()}
    for spec in args.nus:
        nu, nu_div, nu_s = parse_nus(spec)
        key = (base.name, base.ne, base.np, base.stepper, base.dt, base.days, nu, nu_div, nu_s)
        if key in done:
            continue
        terms = tuple(t for t in base.terms if t != "hyperviscosity" or max(nu, nu_div, nu_s) > 0)
        scene = dataclasses.replace(base, terms=terms, nu=nu, nu_div=nu_div, nu_s=nu_s)
        sim = Simulation(scene, "cpu", progress=False)
        try:
            result = sim.run()
            blowup = None
        except BlowUp as err:
            result, blowup = err.result, str(err)
        days = {}
        for d in result.history:
            day = round(d["steps"] * scene.dt / DAY, 6)
            if math.isfinite(d.get("ref_l2_h_surface", math.nan)):
                days[day] = {"h": d["ref_l2_h_surface"], "wind": d["ref_l2_wind"]}
        vort = math.nan
        last = round(result.history[-1]["steps"] * scene.dt / DAY, 6)
        if blowup is None and sim.scorer.reference is not None and last in days:
            ref = sim.scorer.reference.at(last, sim.grid.lat, sim.grid.lon)
            vort = williamson_norms(sim.grid, sim.model.vorticity(sim.x), ref["vorticity"])["l2"]
        row = {"key": list(key), "vorticity_l2_end": vort, "nu": nu, "nu_div": nu_div, "nu_s": nu_s, "errors": days, "blowup": blowup, "wall": result.wall_time}
        with args.out.open("a") as f:
            f.write(json.dumps(row) + "\n")
        cells = "  ".join(f"d{k:g} {v['h']:.3e}/{v['wind']:.3e}" for k, v in days.items() if k > 0)
        print(f"{base.name} ne{base.ne} np{base.np} nu {nu:.3g} nu_div {nu_div:.3g} nu_s {nu_s:.3g}: {cells}"
              + f"  vort {vort:.3e}" + (f"  BLOWUP {blowup}" if blowup else "") + f"  ({result.wall_time:.0f} s)", flush=True)


if __name__ == "__main__":
    main()
