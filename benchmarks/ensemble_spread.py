"""How a Galewsky ensemble's spread grows from a few metres of noise (issue 85's example): N
members of the ``galewsky`` scene (its grid, stepper and Δt), each from the case's jet and bump
with h + ``--amplitude`` m of seeded white noise (``swe_sphere.Perturbation``), run to day
``--days`` in the same launches (``swe_sphere.Simulation.run`` with ``members``), its run file written every
``--every`` days; then the figure: the spread's area-weighted RMS ``h_spread_rms`` against time
(log scale), and at the last day the ensemble mean of h and its spread (the members' standard
deviation) filled over the unique nodes of the northern hemisphere. Prints the RMS spread at each
output time and the e-folding time of its growth over the second half of the run.

    python benchmarks/ensemble_spread.py [--members 8] [--amplitude 1] [--days 6] [--every 0.25]
                                         [--output galewsky_spread.nc] [--figure docs/ensemble_spread.png]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import netCDF4
import numpy as np
from results import recorded

from swe_sphere import Simulation
from swe_sphere.core.runtime import init_warp
from swe_sphere.members.initial import Perturbation


def figure(path: Path, run: Path, title: str) -> None:
    """The spread's growth and the last day's mean and spread of h, from the run file ``run``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with netCDF4.Dataset(run) as ds:
        days, rms = ds["time"][:], ds["h_spread_rms"][:]
        lat, lon = ds["lat"][:], ds["lon"][:]
        mean, spread = ds["h_mean"][-1], ds["h_spread"][-1]
    fig = plt.figure(figsize=(11, 7.5))
    ax = fig.add_subplot(2, 1, 1)
    ax.semilogy(days, rms, "o-")
    ax.set(xlabel="model day", ylabel="RMS spread of h (m)", title=title)
    ax.grid(True, which="both", alpha=0.3)
    for k, (field, label, cmap) in enumerate(
        ((mean, "ensemble mean of h (m)", "viridis"), (spread, "spread of h (m)", "magma"))
    ):
        ax = fig.add_subplot(2, 2, 3 + k)
        north = (lat > 0) & (lat < 85)  # the jet and its instability (a Delaunay mesh of lon-lat: off the pole)
        filled = ax.tricontourf(lon[north], lat[north], field[north], levels=24, cmap=cmap)
        ax.set(xlabel="longitude (°)", ylabel="latitude (°)", title=f"{label}, day {days[-1]:g}")
        fig.colorbar(filled, ax=ax, shrink=0.8)
    fig.tight_layout()
    fig.savefig(path, dpi=90)


def main(args: argparse.Namespace, figures: dict) -> None:
    init_warp()
    every = {"output.every_days": args.every}
    t0 = time.perf_counter()
    start = Perturbation(args.amplitude, seed=args.seed)
    ens = Simulation("galewsky", members=args.members, initial=start, days=args.days, progress=False, **every)
    ens.run(args.output, overwrite=True)
    wall = time.perf_counter() - t0
    with netCDF4.Dataset(args.output) as ds:
        days, rms = np.asarray(ds["time"][:]), np.asarray(ds["h_spread_rms"][:])
    half = days >= days[-1] / 2
    rate = np.polyfit(days[half], np.log(rms[half]), 1)[0]  # per day
    s = ens.scene
    print(
        f"galewsky ne{s.ne} np{s.np} {s.stepper} dt {s.dt:.4g} s, {args.members} members, h + {args.amplitude:g} m "
        f"white noise (seed {args.seed}), {args.days:g} days in {wall:.1f} s wall"
    )
    for d, r in zip(days, rms):
        print(f"day {d:5.2f}  RMS spread of h {r:9.4f} m")
    efold = math.inf if rate <= 0 else 1 / rate
    print(f"growth over days {days[half][0]:g}-{days[-1]:g}: e-folding time {efold:.2f} days")
    figures.update(days=days.tolist(), h_spread_rms=rms.tolist(), efolding_days=efold, wall_s=wall)
    if args.figure:
        title = f"Galewsky, {args.members} members from h + {args.amplitude:g} m of white noise: the spread of h"
        figure(Path(args.figure), Path(args.output), title)
        print(f"figure written to {args.figure}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--members", type=int, default=8)
    parser.add_argument("--amplitude", type=float, default=1.0, help="m of white noise in h")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--days", type=float, default=6.0)
    parser.add_argument("--every", type=float, default=0.25, help="output interval (days)")
    parser.add_argument("--output", default="galewsky_spread.nc")
    parser.add_argument("--figure", default="docs/ensemble_spread.png")
    arguments = parser.parse_args()
    with recorded(__file__) as figures:
        main(arguments, figures)
