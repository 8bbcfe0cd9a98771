"""Tables and figures of docs/explanation/efficiency/*.md from the sweeps' own files.

Reads each sweep directory's ``sweep.csv`` and ``verdicts.csv`` (written by
``swe-sphere sweep``) and prints, as Markdown, the main table (per case, grid
and criterion: the cheapest run (least cost) within 10 % of the spatial
error (the reference's own error, its floor, beside the spatial error where
known), with its RHS evaluations and Helmholtz CG iterations, and the
largest Δt at which Crank–Nicolson stays within 10 % and 50 %) and one table
per sweep (the cheapest qualifying run of each stepper per criterion). With
``--figures DIR`` it also draws, per sweep, the temporal error against
Δt/Δt_g for each criterion (``DIR/<sweep>_temporal_error.png``; DIR is made if
missing). A folder that is not a sweep's, or a --figures path that is not a folder,
is refused in one line (exit 2) before anything is printed.

    python docs/explanation/efficiency/tables.py study/tc5_ne8 study/tc5_ne16 --figures docs/explanation/efficiency
    python docs/explanation/efficiency/tables.py study/tc5_epi_ne30 --family epi2,epi3   # the family against the rest
    python docs/explanation/efficiency/tables.py study/tc5_x2 --regions   # every run's errors by region (a refined mesh)
    python docs/explanation/efficiency/tables.py study/tc5_x2 --temporal-regions   # temporal errors by region over spatial
"""

import argparse
import math
import re
from pathlib import Path

import pandas as pd

from swe_sphere.grid.quality import REGIONS
from swe_sphere.studies.plotting import label_log_axis
from swe_sphere.studies.sweep import CRITERIA as SWEEP_CRITERIA

CRITERIA = list(SWEEP_CRITERIA)  # the verdicts' criteria, in their order
SHORT = {
    "balanced flow (filtered vorticity)": "filtered vorticity",
    "total h+hs": "total h+hs",
    "balanced flow (vorticity)": "vorticity",
    "balanced flow (filtered h+hs)": "filtered h+hs",
    "gravity waves (divergence)": "divergence",
}


def cell(r):
    if pd.isna(r["dt"]):
        return "—"
    return f"{r.dt_over_gravity_limit:.2g}× ({r.dt_over_leapfrog_limit:.2g}×) · {r.cost_time:.1f} s · {work(r)}"


def work(r) -> str:
    """The exact counts (RHS evaluations, and Helmholtz CG iterations where the stepper
    solves one) and the cost in RHS-equivalents (``cost_time`` over one RHS on that clock)."""
    its = (
        f" + {r.helmholtz_iterations / 1000:.3g}k CG"
        if pd.notna(r.get("helmholtz_iterations")) and r.helmholtz_iterations > 0
        else ""
    )
    eq = f" = {r.rhs_equivalents / 1000:.3g}k RHS-eq" if pd.notna(r.get("rhs_equivalents")) else ""
    return f"{int(r.rhs_evals)} RHS{its}{eq}"


def spatial_cell(w) -> str:
    """A criterion's spatial error (its rows of verdicts.csv ``w``), with the
    reference's own error beside it where known (``sweep.floor_note``)."""
    r = w.iloc[0]
    floor = r.get("reference_floor")  # NaN where unknown; absent from sweeps made before the floors
    return f"{r.spatial_error:.3g}" + (f" (floor {floor:.2g})" if pd.notna(floor) else "")


def per_stepper(d: Path, threshold: float) -> str:
    v = pd.read_csv(d / "verdicts.csv")
    v = v[v.threshold == threshold]
    crit = [c for c in CRITERIA if c in set(v.criterion)]
    steppers = list(dict.fromkeys(v.stepper))
    out = ["| stepper | " + " | ".join(SHORT[c] for c in crit) + " |", "|---|" + "---|" * len(crit)]
    out.append("| *spatial error* | " + " | ".join(f"*{spatial_cell(v[v.criterion == c])}*" for c in crit) + " |")
    for s in steppers:
        row = [cell(v[(v.criterion == c) & (v.stepper == s)].iloc[0]) for c in crit]
        out.append(f"| {s} | " + " | ".join(row) + " |")
    return "\n".join(out)


def cheapest(d: Path, threshold: float) -> list:
    """Per criterion the sweep scored: (criterion, spatial error, its table cell
    (``spatial_cell``), the cheapest qualifying run of any stepper, or None)."""
    v = pd.read_csv(d / "verdicts.csv")
    v = v[v.threshold == threshold]
    rows = []
    for c in CRITERIA:
        w = v[v.criterion == c]
        if w.empty:
            continue
        ok = w[w.dt.notna()]
        rows.append((c, w.spatial_error.iloc[0], spatial_cell(w), ok.loc[ok.cost_time.idxmin()] if len(ok) else None))
    return rows


COLUMN = {criterion: column for criterion, (column, _) in SWEEP_CRITERIA.items()}


def largest(s, stepper, criterion, limit):
    """The largest Δt/Δt_g of a stable run of ``stepper`` within ``limit`` (None if none)."""
    ok = s[(s.stepper == stepper) & s.stable.astype(bool) & (s[COLUMN[criterion]] <= limit)]
    return None if ok.empty else ok.dt_over_gravity_limit.max()


def closest(s, criterion, spatial) -> str:
    """Where no run qualifies: the stable run nearest to it, as "stepper at Δt/Δt_g: % of the spatial error"."""
    ok = s[s.stable.astype(bool) & s[COLUMN[criterion]].notna()]
    r = ok.loc[ok[COLUMN[criterion]].idxmin()]
    return f"{r.stepper} at {r.dt_over_gravity_limit:.2g}×: {100 * r[COLUMN[criterion]] / spatial:.0f} %"


def summary(dirs) -> str:
    out = [
        "| case | ne | criterion | spatial error | cheapest at ≤ 10 % | Δt/Δt_g (Δt/Δt_lf) | CPU s | work | CN: largest Δt/Δt_g at ≤ 10 % (≤ 50 %) |",
        "|---|---:|---|---:|---|---|---:|---:|---|",
    ]
    for d in dirs:
        s = pd.read_csv(d / "sweep.csv")
        case, ne = case_and_grid(d)
        for c, spatial, shown, best in cheapest(d, 0.1):
            big = [largest(s, "implicit", c, t * spatial) for t in (0.1, 0.5)]
            impc = " ".join(
                ("—" if b is None else f"{b:.2g}×") if i == 0 else f"({'—' if b is None else f'{b:.2g}×'})"
                for i, b in enumerate(big)
            )
            if best is None:
                out.append(
                    f"| {case} | {ne} | {SHORT[c]} | {shown} | — (nearest: {closest(s, c, spatial)}) | | | | {impc} |"
                )
                continue
            out.append(
                f"| {case} | {ne} | {SHORT[c]} | {shown} | {best.stepper} | {best.dt_over_gravity_limit:.2g}× ({best.dt_over_leapfrog_limit:.2g}×) | {best.cost_time:.1f} | {work(best)} | {impc} |"
            )
    return "\n".join(out)


def by_region(d: Path) -> str:
    """Every run of the sweep ``d``, each stepper's by Δt: Δt/Δt_g, the l2 error of h + hs
    against the truth in total and by region (``quality.REGIONS``; the spatial error's first),
    the filtered vorticity's temporal error over its spatial error, the CPU time per simulated
    day and the cost in RHS-equivalents; an unstable run says where it blew up."""
    s, v = pd.read_csv(d / "sweep.csv"), pd.read_csv(d / "verdicts.csv")
    ref = v[v.criterion == "balanced flow (filtered vorticity)"].spatial_error.iloc[0]
    info = pd.read_csv(d / "sweep.csv", nrows=1)
    out = [
        "| stepper | Δt/Δt_g | l2 h+hs | "
        + " | ".join(REGIONS)
        + " | filtered vorticity: time / space | CPU s/day | RHS-eq |",
        "|---|---:|---:|" + "---:|" * len(REGIONS) + "---:|---:|---:|",
    ]
    spatial = _spatial_by_region(d)
    out.append("| *spatial error* | | " + " | ".join(f"*{e:.3g}*" for e in spatial) + f" | *{ref:.3g}* | | |")
    days = float(info.days.iloc[0])
    for stepper, g in s.groupby("stepper", sort=False):
        for r in g.sort_values("dt").itertuples():
            head = f"| {stepper} | {r.dt_over_gravity_limit:.3g} |"
            if not r.stable:
                out.append(f"{head} {r.reason.split(':')[0]} |" + " |" * (len(REGIONS) + 3))
                continue
            errors = " | ".join(f"{getattr(r, f'total_error_{k}'):.3g}" for k in REGIONS)
            time_space = r.temporal_error_filtered_vorticity / ref
            out.append(
                f"{head} {r.total_error:.3g} | {errors} | {time_space:.0%} | {r.cost_time / days:.2f} | {r.rhs_equivalents / 1000:.3g}k |"
            )
    return "\n".join(out)


def _spatial_by_region(d: Path) -> list:
    """The small-Δt run's l2 of h + hs in total and by region (sweep.nc's attributes)."""
    return [_attrs(d)["spatial_error"]] + [_attrs(d)[f"spatial_error_{k}"] for k in REGIONS]


def _attrs(d: Path) -> dict:
    """sweep.nc's global attributes (the spatial errors, the explicit limits)."""
    import xarray as xr

    with xr.open_dataset(d / "sweep.nc") as ds:
        return dict(ds.attrs)


def reach(multiples, ratios, threshold: float = 0.1) -> tuple[float, bool]:
    """(Δt/Δt_g at which a temporal error over its spatial error, ``ratios`` at the steps
    ``multiples`` (increasing), reaches ``threshold``, and whether it was interpolated):
    log-log between the two runs that bracket it, at their order; else extrapolated at the
    order of the two runs nearest it. NaN with fewer than two runs."""
    pts = [(m, r) for m, r in zip(multiples, ratios) if math.isfinite(r) and r > 0]
    if len(pts) < 2:
        return math.nan, False
    pairs = list(zip(pts, pts[1:]))
    inside = [p for p in pairs if p[0][1] <= threshold <= p[1][1]]
    ((m0, r0), (m1, r1)) = inside[0] if inside else pairs[-1] if pts[-1][1] < threshold else pairs[0]
    order = math.log(r1 / r0) / math.log(m1 / m0)
    return m0 * (threshold / r0) ** (1 / order), bool(inside)


# (label, temporal-error column and spatial-error attribute of sweep.nc without "_error"): in total and by region
TEMPORAL_BY_REGION = [
    (f"{what}{' ' + k if k else ''}", f"{part}{'_' + k if k else ''}")
    for what, part in (("h+hs", ""), ("div", "_divergence"))
    for k in ("", *REGIONS)
]


def temporal_by_region(d: Path) -> str:
    """Every stable run of the sweep ``d`` (a refined mesh's), each stepper's by Δt: the
    temporal error of h + hs and of the divergence in total and by region, each over that
    region's spatial error; per stepper the Δt/Δt_g at which each reaches 10 % (``reach``; *
    extrapolated); then each region's share of the whole sphere's squared temporal error. The
    shares: the regions' weights w_R = ∫_R n² / ∫ n² (n² the normalizer, (h + hs)² or ζ² + δ²,
    of the small-Δt run, so the same in every run) solved by least squares from
    Σ_R w_R t_R² = t² over the runs, then w_R t_R² / t² (the largest misfit is printed: round-off).
    A mesh of one resolution has no regions: one line says so."""
    import numpy as np

    s, a = pd.read_csv(d / "sweep.csv"), _attrs(d)
    if not math.isfinite(a[f"spatial_error_{REGIONS[0]}"]):
        return "no temporal errors by region: the mesh has one resolution"
    s = s[s.stable == 1]
    out = [
        "| stepper | Δt/Δt_g | " + " | ".join(label for label, _ in TEMPORAL_BY_REGION) + " |",
        "|---|---:|" + "---:|" * len(TEMPORAL_BY_REGION),
        "| *spatial error* | | " + " | ".join(f"*{a[f'spatial_error{c}']:.3g}*" for _, c in TEMPORAL_BY_REGION) + " |",
    ]
    for stepper, g in s.groupby("stepper", sort=False):
        g = g.sort_values("dt")
        ratios = {c: list(g[f"temporal_error{c}"] / a[f"spatial_error{c}"]) for _, c in TEMPORAL_BY_REGION}
        for i, m in enumerate(g.dt_over_gravity_limit):
            out.append(
                f"| {stepper} | {m:.3g} | " + " | ".join(f"{ratios[c][i]:.3f}" for _, c in TEMPORAL_BY_REGION) + " |"
            )
        at = [reach(list(g.dt_over_gravity_limit), ratios[c]) for _, c in TEMPORAL_BY_REGION]
        out.append(f"| {stepper}: 10 % at | | " + " | ".join(f"{m:.2f}{'' if i else '*'}" for m, i in at) + " |")
    out += ["", "| stepper | Δt/Δt_g | " + " | ".join(f"{w} {k}" for w in ("h+hs", "div") for k in REGIONS) + " |"]
    out.append("|---|---:|" + "---:|" * 2 * len(REGIONS))
    shares, misfit = [], 0.0
    for part in ("", "_divergence"):
        squares = np.stack([s[f"temporal_error{part}_{k}"] ** 2 for k in REGIONS], axis=1)
        total = s[f"temporal_error{part}"].to_numpy() ** 2
        w = np.linalg.lstsq(squares, total, rcond=None)[0]
        misfit = max(misfit, float(np.abs(squares @ w / total - 1).max()))
        shares.append(squares * w / total[:, None])
    for i, r in enumerate(s.itertuples()):
        cells = " | ".join(f"{x:.2f}" for part in shares for x in part[i])
        out.append(f"| {r.stepper} | {r.dt_over_gravity_limit:.3g} | {cells} |")
    out.append(f"\n(the regions' share of the squared temporal error; the weights' largest misfit {misfit:.1e})")
    return "\n".join(out)


COLORS = dict(
    zip(
        [
            "leapfrog",
            "leapfrog_trapezoidal",
            "ssprk3",
            "rk4",
            "kgu35",
            "fbrk32",
            "semi_implicit",
            "imex",
            "implicit",
            "epi2",
            "epi3",
            "split_explicit",
            "mri",
        ],
        ["C0", "C1", "C2", "C3", "C7", "C8", "C4", "C5", "C6", "C9", "k", "m", "navy"],
    )
)


def versus(dirs, family) -> str:
    """Per sweep and criterion: the cheapest qualifying (≤ 10 %) run of the steppers in
    ``family`` against the cheapest of the others, and the ratio of their costs."""
    out = [
        "| sweep | criterion | spatial error | cheapest other | cheapest of " + ", ".join(family) + " | ratio |",
        "|---|---|---:|---|---|---:|",
    ]
    for d in dirs:
        v = pd.read_csv(d / "verdicts.csv")
        v = v[(v.threshold == 0.1) & v.dt.notna()]
        for c in CRITERIA:
            w = v[v.criterion == c]
            if w.empty:
                continue
            mine, rest = w[w.stepper.isin(family)], w[~w.stepper.isin(family)]
            a = None if rest.empty else rest.loc[rest.cost_time.idxmin()]
            b = None if mine.empty else mine.loc[mine.cost_time.idxmin()]
            show = lambda r: "—" if r is None else f"{r.stepper} @ {r.dt_over_gravity_limit:.3g}, {r.cost_time:.1f} s"  # noqa: E731
            ratio = "" if a is None or b is None else f"{b.cost_time / a.cost_time:.2f}×"
            out.append(f"| {d.name} | {SHORT[c]} | {w.spatial_error.iloc[0]:.3g} | {show(a)} | {show(b)} | {ratio} |")
    return "\n".join(out)


def figure(d: Path, out: Path):
    """Temporal error against Δt/Δt_g per stepper, one panel per criterion, the 10 % line dashed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    s = pd.read_csv(d / "sweep.csv")
    s = s[s.stable.astype(bool)]
    v = pd.read_csv(d / "verdicts.csv")
    panels = [
        ("temporal_error", "total h+hs", "total h+hs"),
        ("temporal_error_filtered", "balanced flow (filtered h+hs)", "filtered h+hs (balanced flow)"),
        ("temporal_error_vorticity", "balanced flow (vorticity)", "vorticity (balanced flow)"),
        (
            "temporal_error_filtered_vorticity",
            "balanced flow (filtered vorticity)",
            "filtered vorticity (balanced flow)",
        ),
        ("temporal_error_divergence", "gravity waves (divergence)", "divergence (gravity waves)"),
    ]
    panels = [p for p in panels if p[0] in s and s[p[0]].notna().any()]
    fig, axes = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 3.2), sharex=True)
    for ax, (col, crit, title) in zip(axes, panels):
        for name, g in s.groupby("stepper", sort=False):
            g = g.sort_values("dt")
            ax.loglog(g.dt_over_gravity_limit, g[col], "o-", ms=3, label=name, color=COLORS[name])
        spatial = v[v.criterion == crit].spatial_error.iloc[0]
        ax.axhline(0.1 * spatial, ls="--", c="k", lw=0.8)
        ax.axhline(spatial, ls=":", c="k", lw=0.8)
        ax.set_title(title, fontsize=9)
        ax.set_xlabel("Δt / Δt_g")
        label_log_axis(ax.xaxis)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("temporal error (normalized l2)")
    axes[-1].legend(fontsize=7)
    fig.suptitle(f"{d.name}: temporal error; dotted: spatial error, dashed: 10 % of it", fontsize=10)
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)


def case_and_grid(d: Path) -> tuple[str, int]:
    """(case, ne) of the sweep folder ``d``: from its name ``<case>_ne<N>`` (the study's
    folders: "tc5_ne30"), else from its sweep.csv's ``case`` and ``ne`` columns. Raises
    ValueError (one line) when neither says."""
    named = re.fullmatch(r"(.+)_ne(\d+)", d.name)
    if named:
        return named[1], int(named[2])
    s = pd.read_csv(d / "sweep.csv")
    if {"case", "ne"} <= set(s.columns) and len(s):
        return str(s["case"].iloc[0]), int(s["ne"].iloc[0])
    raise ValueError(f"{d}: a sweep folder is named <case>_ne<N> (e.g. tc5_ne30), or its sweep.csv has case and ne")


def check(args) -> None:
    """Refuse (ValueError, one line) what would stop the tables half-printed: a folder that
    is not a sweep's, a case or grid not known, a --figures path that is not a folder
    (a missing one is made)."""
    for d in args.sweeps:
        missing = [name for name in ("sweep.csv", "verdicts.csv") if not (d / name).is_file()]
        if missing:
            raise ValueError(f"{d}: not a sweep folder (no {' or '.join(missing)}; `swe-sphere sweep` writes them)")
        case_and_grid(d)
    if args.figures is not None:
        if args.figures.exists() and not args.figures.is_dir():
            raise ValueError(f"--figures {args.figures}: not a folder")
        try:
            args.figures.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ValueError(f"--figures {args.figures}: cannot make the folder ({err.strerror})") from None


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument(
        "sweeps", nargs="+", type=Path, help="sweep directories (named <case>_ne<ne>, else case and ne from sweep.csv)"
    )
    p.add_argument("--figures", type=Path, metavar="DIR", help="also draw the temporal-error figures into DIR")
    p.add_argument(
        "--family",
        help="comma-separated steppers (e.g. epi2,epi3): also their cheapest qualifying run against the others'",
    )
    p.add_argument("--regions", action="store_true", help="also every run's errors by region (a refined mesh)")
    p.add_argument(
        "--temporal-regions",
        action="store_true",
        help="also every run's temporal errors by region over their spatial errors (a refined mesh)",
    )
    args = p.parse_args()
    try:
        check(args)
    except ValueError as err:
        p.exit(2, f"{p.prog}: error: {err}\n")
    print(summary(args.sweeps))
    if args.family:
        print("\n" + versus(args.sweeps, args.family.split(",")))
    for d in args.sweeps:
        print(f"\n### {d.name}\n")
        print(per_stepper(d, 0.1))
        if args.regions:
            print("\n" + by_region(d))
        if args.temporal_regions:
            print("\n" + temporal_by_region(d))
        if args.figures:
            figure(d, args.figures / f"{d.name}_temporal_error.png")


if __name__ == "__main__":
    main()
