"""The tracers on the standard transport test (Lauritzen, Skamarock, Prather & Taylor 2012, GMD 5, 887).

Nair & Lauritzen (2010)'s nondivergent deformational flow (T = 12 days) carrying cosine
bells, Gaussian hills, slotted cylinders, the correlated pair and q = 1
(``deformational_flow.toml`` beside this script: SSPRK(4,3), whose Euler stages of Δt/2 let the limiter
hold the bounds), at each ``--ne`` and ``--np`` (4: HOMME's; Δt and ν scaled by the scene's rule from
ne10 np4's 720 s and 4.6e15 m⁴ s⁻¹, HOMME's swirl test's), or
``--flow divergent`` (their case 3, ``divergent_flow``: h moves too, and its l2 at T is scored),
scored at t = T against the initial fields: Williamson et al. (1992)'s normalised l1, l2, l∞, Lauritzen et al.'s over- and
undershoots φmax, φmin, each mass's relative change, and the l2 rates between grids; ``--limiter``
the tracers' limiter (Guba et al. 2014's "optimization", HOMME's limiter 8); the bells' filament
diagnostic l_f(τ) and the correlated pair's mixing diagnostics l_r, l_u, l_o at T/2 (``filaments``,
``mixing``). ``--maps
PNG``: the bells at T/2 and T (the finest grid's). ``--keep DIR``: the run files (``run_name``); one
already there, kept by an earlier call, is scored again, not rerun (delete it to rerun it), so that
grids run in separate calls are scored and their rates taken in one. ``--results STEM``: the
figures' file (a grid run on its own beside a longer run's).

    python benchmarks/studies/transport/transport.py --ne 10 20 30 --limiter optimization \\
        --maps docs/explanation/transport_bells.png
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))  # benchmarks/: results.py
from results import positive, quiet_warp, recorded

from swe_sphere import Simulation, load_scene, remap_dataset

SCENE = Path(__file__).with_name("deformational_flow.toml")
FLOWS = {"nondivergent": "deformational_flow", "divergent": "divergent_flow"}  # --flow: its case
# HOMME's own figures, its swirl test's recorded l2 with its limiter 8 (../shared/transport-tests.md)
HOMME_L2 = {
    10: {"bells": 0.347, "hills": 0.182, "cylinders": 0.437},
    20: {"bells": 0.120, "hills": 0.0458, "cylinders": 0.331},
}


def run_name(flow: str, ne: int, np_: int, limiter: str) -> str:
    """The run file's name in ``--keep``'s folder: the flow's case, the grid and the limiter."""
    return f"{FLOWS[flow]}_ne{ne}_np{np_}{'' if limiter == 'none' else '_' + limiter}.nc"


def scores(path: Path, names) -> dict:
    """{tracer: {l1, l2, linf, phi_max, phi_min, mass_change}} of run file ``path``'s last time
    against its first (the exact solution at t = T), area-weighted by the file's ``area``."""
    import xarray as xr

    with xr.open_dataset(path, decode_times=False) as ds:
        w = ds.area.values
        out = {}
        for name in names:
            q0, q = ds[name].isel(time=0).values, ds[name].isel(time=-1).values
            d, span = q - q0, (q0.max() - q0.min()) or 1.0
            out[name] = {
                "l1": float((w * np.abs(d)).sum() / (w * np.abs(q0)).sum()),
                "l2": float(math.sqrt((w * d * d).sum() / (w * q0 * q0).sum())),
                "linf": float(np.abs(d).max() / np.abs(q0).max()),
                "phi_max": float((q.max() - q0.max()) / span),
                "phi_min": float((q.min() - q0.min()) / span),
                "mass_change": float(ds[f"{name}_mass_change"][-1]),
            }
        return out


def depth_l2(path: Path) -> float:
    """h's normalised l2 at run file ``path``'s last time against its first: the divergent flow
    moves h and brings it back at t = T."""
    import xarray as xr

    with xr.open_dataset(path, decode_times=False) as ds:
        w, h0, h = ds.area.values, ds.h.isel(time=0).values, ds.h.isel(time=-1).values
    return float(math.sqrt((w * (h - h0) ** 2).sum() / (w * h0 * h0).sum()))


# the filament diagnostic's thresholds τ (Lauritzen et al. 2012 §3.3: 0.10, 0.15, ..., 1.0)
THRESHOLDS = tuple(round(0.1 + 0.05 * k, 2) for k in range(19))


def filaments(path: Path, name: str = "bells") -> dict:
    """{τ: l_f} of run file ``path``'s tracer ``name`` at its middle output time (T/2): l_f(τ) =
    100 A(τ, T/2) / A(τ, 0), A(τ, t) the area (the file's ``area``) where q ≥ τ (Lauritzen et al.
    2012 eq. 17); 100 where the flow keeps the area, less where filaments fall below τ."""
    import xarray as xr

    with xr.open_dataset(path, decode_times=False) as ds:
        w = ds.area.values
        q0, half = ds[name].isel(time=0).values, ds[name].isel(time=ds.sizes["time"] // 2).values
        return {tau: float(100 * w[half >= tau].sum() / w[q0 >= tau].sum()) for tau in THRESHOLDS if (q0 >= tau).any()}


def mixing(path: Path, pair=("bells", "correlated")) -> dict:
    """Lauritzen et al. 2012 §3.4's mixing diagnostics of run file ``path``'s correlated pair at T/2:
    each node's (χ, ξ) = (bells, correlated) and its distance d to the initial relation ξ =
    −0.8 χ² + 0.9 over χ in its initial range, both axes scaled by their initial ranges; nodes
    between the relation and its chord are real mixing (l_r), the rest within the initial ranges
    range-preserving unmixing (l_u), those outside them overshooting (l_o); each l the
    area-weighted sum of d over its nodes over the total area."""
    import xarray as xr

    with xr.open_dataset(path, decode_times=False) as ds:
        w = ds.area.values
        half = ds.sizes["time"] // 2
        chi0, xi0 = (ds[n].isel(time=0).values for n in pair)
        chi, xi = (ds[n].isel(time=half).values for n in pair)
    lo, hi = chi0.min(), chi0.max()
    xlo, xhi = xi0.min(), xi0.max()
    curve = lambda c: -0.8 * c**2 + 0.9  # noqa: E731
    c = np.linspace(lo, hi, 4001)
    d = np.concatenate(  # in blocks of nodes: a block's distances to every sample of the curve at once
        [
            np.sqrt(((a[:, None] - c) / (hi - lo)) ** 2 + ((b[:, None] - curve(c)) / (xhi - xlo)) ** 2).min(axis=1)
            for a, b in zip(
                np.array_split(chi, -(-chi.size // 2048)), np.array_split(xi, -(-xi.size // 2048)), strict=True
            )
        ]
    )
    chord = curve(lo) + (curve(hi) - curve(lo)) * (chi - lo) / (hi - lo)
    inside = (chi >= lo) & (chi <= hi) & (xi >= xlo) & (xi <= xhi)
    real = inside & (xi >= chord) & (xi <= curve(np.clip(chi, lo, hi)))
    total = w.sum()
    return {
        "l_r": float((w * d)[real].sum() / total),
        "l_u": float((w * d)[inside & ~real].sum() / total),
        "l_o": float((w * d)[~inside].sum() / total),
    }


def maps(path: Path, png: Path, name: str = "bells", resolution: float = 0.5) -> None:
    """``name``'s field at t = 0, T/2 and T of run file ``path`` on a longitude-latitude map each:
    each element's GLL polynomial evaluated at the points of a regular ``resolution``° grid
    (``remap_dataset``), drawn cell by cell about them, so the globe is covered to its edges and
    poles (a triangulation of the nodes in the lon-lat plane left gaps at 360° and near the poles)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    field = remap_dataset(path, resolution)[name]
    half = resolution / 2
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.2), sharey=True, constrained_layout=True)
    for ax, k in zip(axes, range(3), strict=True):
        values = field.isel(time=k).values
        art = ax.imshow(
            np.concatenate([values, values[:, :1]], axis=1),  # lon 0 again at 360: the cells reach both edges
            extent=(-half, 360 + half, -90 - half, 90 + half),  # cells centred on the points
            origin="lower",
            interpolation="nearest",
            aspect="auto",
            cmap="viridis",
            vmin=-0.025,
            vmax=1.075,
        )
        ax.set_xlim(0, 360)
        ax.set_ylim(-90, 90)
        ax.set_title(f"{name} at day {float(field.time[k]):g}")
        ax.set_xlabel("longitude (°)")
        ax.set_xticks(np.arange(0, 361, 60))
        ax.set_yticks(np.arange(-90, 91, 30))
    axes[0].set_ylabel("latitude (°)")
    fig.colorbar(art, ax=axes, shrink=0.9, label="q", extend="both")
    fig.savefig(png, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ne", type=positive(int), nargs="+", default=[10])
    parser.add_argument("--np", type=positive(int), default=4, help="GLL points per element direction")
    parser.add_argument("--flow", choices=tuple(FLOWS), default="nondivergent", help="the prescribed wind")
    parser.add_argument("--days", type=positive(float), default=12.0, help="the run (T = 12: the whole test)")
    parser.add_argument("--maps", type=Path, default=None, help="a PNG of the bells at 0, T/2, T (the finest grid)")
    parser.add_argument("--keep", type=Path, default=None, help="a folder to keep the run files in")
    parser.add_argument(
        "--limiter", choices=("none", "optimization"), default="none", help="tracers.limiter (Guba et al. 2014's)"
    )
    parser.add_argument(
        "--results", metavar="STEM", help="results/transport/STEM.json (default: transport, or the variant's name)"
    )
    args = parser.parse_args()
    quiet_warp()
    # the default's file transport.json; a variant's names what differs (transport_optimization_np8)
    variant = [
        v
        for v, default in ((args.limiter, "none"), (args.flow, "nondivergent"), (f"np{args.np}", "np4"))
        if v != default
    ]
    stem = args.results or ("_".join(["transport", *variant]) if variant else None)
    with recorded(__file__, stem) as figures, tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        l2 = {}
        for ne in args.ne:
            over = {"output.every_days": args.days / 2, "tracers.limiter": args.limiter, "case.name": FLOWS[args.flow]}
            scene = load_scene(SCENE, ne=ne, np_=args.np, days=args.days, overrides=over)
            path = folder / run_name(args.flow, ne, args.np, args.limiter)
            if not path.exists():  # a run file is renamed into place only when complete
                Simulation(scene, "cpu", progress=False).run(path)
            names = [name for name, _ in scene.tracers]
            got = scores(path, names)
            figures[f"ne{ne}"] = got
            figures[f"filaments_ne{ne}"] = lf = filaments(path)
            figures[f"mixing_ne{ne}"] = mx = mixing(path)
            l2[ne] = {n: got[n]["l2"] for n in names}
            print(
                f"ne{ne} np{args.np} {args.flow} dt {scene.dt:g} s nu_s {scene.nu_s:.3g} m4/s, limiter {args.limiter}, "
                f"day {args.days:g}:"
            )
            if args.flow == "divergent":
                figures[f"h_l2_ne{ne}"] = l2[ne]["h"] = depth_l2(path)
                print(f"  h           l2 {l2[ne]['h']:.4g}")
            compared = HOMME_L2 if (args.flow, args.np) == ("nondivergent", 4) else {}
            for n in names:
                g = got[n]
                homme = compared.get(ne, {}).get(n)
                beside = "" if homme is None else f"  (HOMME {homme})"
                print(
                    f"  {n:11s} l1 {g['l1']:.4f} l2 {g['l2']:.4f} linf {g['linf']:.4f} "
                    f"phi_max {g['phi_max']:+.4f} phi_min {g['phi_min']:+.4f} mass {g['mass_change']:+.1e}{beside}"
                )
            shown = (0.1, 0.5, 0.9, 1.0)
            print("  bells' filaments l_f at T/2: " + ", ".join(f"tau {t:g} {lf[t]:.1f}" for t in shown if t in lf))
            print("  mixing at T/2: " + ", ".join(f"{k} {v:.2e}" for k, v in mx.items()))
        grids = sorted(l2)
        for a, b in zip(grids, grids[1:], strict=False):
            # q = 1's l2 is round-off (or 0): no rate
            rates = {
                n: math.log(l2[a][n] / l2[b][n]) / math.log(b / a) for n in l2[a] if min(l2[a][n], l2[b][n]) > 1e-12
            }
            figures[f"rate_ne{a}_ne{b}"] = rates
            print(f"l2 rate ne{a} -> ne{b}: " + ", ".join(f"{n} {r:.2f}" for n, r in rates.items()))
        if args.maps is not None:
            maps(folder / run_name(args.flow, grids[-1], args.np, args.limiter), args.maps)
            print(f"maps: {args.maps}", file=sys.stderr)  # a file written, not a figure


if __name__ == "__main__":
    main()
