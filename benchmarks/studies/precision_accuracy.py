"""The accuracy of ``--precision float32`` (issue 114, item 5): each row a scene and grid run
twice, float64 and float32, the same in everything else, one after the other in one process.

    SWE_SPHERE_THREADS=1 python benchmarks/studies/precision_accuracy.py [--rows ROW|GROUP ...] [--keep DIR] [--precision P]

Rows (``--rows``; groups ``galewsky``, ``tc5``, ``tc6``, ``tc2``, ``tc2_np4``, ``tc2_np8``, ``all``,
the default): Galewsky to day 6 at the grids that reach Dinosaur's T42, T85, T170 and T213 errors
(docs/explanation/efficiency.md, "Against other models": ne16 np5, ne11 np8, ``galewsky`` as shipped ne12
np8, ne25 np6, ne28 np6), against T341, its day-6 vorticity l2 (Williamson eq. 83); TC5 (day
15) and TC6 (day 14) at their scenes' grids (ne30 np4), against T341, h + hs l2; TC2 at np 4 (ne
4, 8, 16, 32) and np 8 (ne 2, 4, 8, 16), 5 days against its exact solution, h l2, with ``rk4``
and the scene's Δt scaled to the grid (tests/model/test_convergence.py's rule: the time error
far below the spatial one). Each run at the scene's own rules otherwise (Δt, ν, the ∇⁴'s
schedule follow ``--ne`` and ``--np``).

Per row: each precision's error (the scene's measure at the last day, as the run's summary
prints it, and the others it prints); |e32 − e64| / e64; the field difference
‖f32 − f64‖₂ / ‖f_ref‖₂ (area-weighted, f the measure's field: the vorticity, h + hs or h; f_ref
the reference's or exact field at the nodes), and that over e64 (the share of the error the
precision changes); mass, energy and potential enstrophy relative change over the run; the
time loop's wall ms a step after the first output (the run file's ``wall_time``: Warp's compile of
a new kernel, in the first step, left out), its whole loop's wall s and the process's CPU s of each
run (set-up and compile included). Verdict: "float32 holds" where |e32 − e64| ≤ 10 %
of e64. Printed as a markdown table; figures to ``results/precision_accuracy/precision_accuracy.json``.

``--precision`` sets another against float64 in the float32 column's place (issue 128):
"float32_state" (a step's state and stages in float32, the float32 state kept from step to step)
or "float32_state_compensated" (``numerics.compensated = true``: a float64 state between steps,
each step's float32 increment added to it); ``--no-mass-fixer`` runs it with
``numerics.mass_fixer = false`` (the float32 state's mass left to drift).

``--table STEM ...`` runs nothing: it prints the markdown table of the results files
``results/precision_accuracy/STEM.json``: files of one precision and fixer, the table of all
their rows in turn (as one run of them prints it); files of several, one table of the rows they
share, each run set against float64 (the first file's). docs/explanation/precision.md's tables
are these (the second's files: the float32 state kept and compensated, each with and without
its fixer)::

    python benchmarks/studies/precision_accuracy.py --table precision_accuracy_galewsky precision_accuracy_scenes precision_accuracy_tc2
    python benchmarks/studies/precision_accuracy.py --table float32_state_default float32_state_default_nofixer float32_state_compensated float32_state_compensated_nofixer
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

import swe_sphere
from swe_sphere.cases.reference import Reference, reference_path

# name: (scene, ne, np, stepper or None (the scene's), label)
GALEWSKY = {
    "galewsky_t42": ("galewsky", 16, 5, None, "T42"),
    "galewsky_t85": ("galewsky", 11, 8, None, "T85"),
    "galewsky_shipped": ("galewsky", 12, 8, None, "T85 (as shipped)"),
    "galewsky_t170": ("galewsky", 25, 6, None, "T170"),
    "galewsky_t213": ("galewsky", 28, 6, None, "T213"),
}
TC2_NP4 = {f"tc2_ne{ne}np4": ("tc2_steady", ne, 4, "rk4", "") for ne in (4, 8, 16, 32)}
TC2_NP8 = {f"tc2_ne{ne}np8": ("tc2_steady", ne, 8, "rk4", "") for ne in (2, 4, 8, 16)}
ROWS = {
    **GALEWSKY,
    "tc5": ("tc5_mountain", None, None, None, ""),
    "tc6": ("tc6_rossby_haurwitz", None, None, None, ""),
    **TC2_NP4,
    **TC2_NP8,
}
GROUPS = {
    "galewsky": list(GALEWSKY),
    "tc2_np4": list(TC2_NP4),
    "tc2_np8": list(TC2_NP8),
    "tc2": [*TC2_NP4, *TC2_NP8],
    "all": list(ROWS),
}
# the measure: (its series in the run file, the field, the truth's key; None: the exact solution)
MEASURE = {
    "galewsky": ("ref_l2_vorticity_eq83", "vorticity", "vorticity"),
    "tc5_mountain": ("ref_l2_h_surface", "h_surface", "h_surface"),
    "tc6_rossby_haurwitz": ("ref_l2_h_surface", "h_surface", "h_surface"),
    "tc2_steady": ("l2_h", "h", None),
}
OTHERS = ("ref_l2_h_surface", "ref_l2_wind", "ref_l2_vorticity_eq83", "l2_h", "l2_wind")
INVARIANTS = ("mass_change", "total_energy_change", "potential_enstrophy_change")
HOLDS = 0.10  # |e32 − e64| / e64 at most
# the precisions set against float64 (``--precision``): the mixed float32, the float32 state
# (``model.precision``: kept between steps), and its increments added to a float64 state between
# steps (numerics.compensated true)
LOWER = ("float32", "float32_state", "float32_state_compensated")


def expand(names: list[str]) -> list[str]:
    """Row names from row and group names, in order, each once."""
    out = []
    for name in names:
        for row in GROUPS.get(name, [name]):
            if row not in out:
                out.append(row)
    return out


def one_run(scene: str, ne, np_, stepper, precision: str, keep: str | None, name: str, fixer: bool = True):
    """(the run file's dataset, CPU s of the call) of a scene at a precision (``LOWER``'s label:
    "float32_state_compensated", float32_state with ``numerics.compensated = true``); ``fixer``
    False: a float32 state's without its mass fixer."""
    overrides = {"precision": precision.removesuffix("_compensated")}
    numerics = {"compensated": True} if precision.endswith("_compensated") else {}
    if not fixer and overrides["precision"] == "float32_state":
        numerics["mass_fixer"] = False
    if numerics:
        overrides["numerics"] = numerics
    overrides |= {k: v for k, v in (("ne", ne), ("np", np_), ("stepper", stepper)) if v is not None}
    if MEASURE[scene][2] is not None:
        overrides["case"] = {"reference": "T341"}
    output = None if keep is None else os.path.join(keep, f"{name}_{precision}.nc")
    clock = time.process_time()
    ds = swe_sphere.run(scene, output_file=output, overwrite=True, **overrides)
    return ds, time.process_time() - clock


def field(ds, key: str) -> np.ndarray:
    """The measure's field at the last output time (ncol,)."""
    if key == "h_surface":
        return (ds.h.isel(time=-1) + ds.hs).values
    return ds[key].isel(time=-1).values


def truth(ds, scene: str) -> np.ndarray:
    """The reference's (T341) or the exact solution's field of the measure at the nodes, last day."""
    day = float(ds.time[-1])
    lat, lon = np.radians(ds.lat.values), np.radians(ds.lon.values)
    case = swe_sphere.load_scene(scene).make_case()
    if MEASURE[scene][2] is None:
        return case.exact(lat, lon, day * 86400.0)[2]
    return Reference(reference_path(case, "T341")).at(day, lat, lon)[MEASURE[scene][2]]


def norm(ds, f) -> float:
    """sqrt(∫ f² dA) over the unique nodes (the run file's assembled ``area``)."""
    return math.sqrt(float(np.sum(ds.area.values * f * f)))


def row_figures(name: str, keep: str | None, low: str = "float32", fixer: bool = True) -> dict:
    """Both runs of a row, float64 and ``low`` (a ``LOWER``; ``fixer`` False: without its mass
    fixer), and its figures."""
    scene, ne, np_, stepper, label = ROWS[name]
    runs = {}
    for precision in ("float64", low):
        load = os.getloadavg()[0]
        ds, cpu = one_run(scene, ne, np_, stepper, precision, keep, name, fixer)
        last = ds.isel(time=-1)
        runs[precision] = {
            "ds": ds,
            "error": float(last[MEASURE[scene][0]]),
            "others": {k: float(last[k]) for k in OTHERS if k in ds and k != MEASURE[scene][0]},
            "invariants": {k: float(last[k]) for k in INVARIANTS},
            "loop_s": float(last["wall_time"]),
            # after the first output: Warp's compile of a new kernel (the first step) left out
            "ms_step": 1e3 * float(last["wall_time"] - ds.wall_time[1]) / float(last["steps"] - ds.steps[1]),
            "cpu_s": cpu,
            "load": load,
        }
    d64, d32 = runs["float64"]["ds"], runs[low]["ds"]
    f_ref = truth(d64, scene)
    f64, f32 = field(d64, MEASURE[scene][1]), field(d32, MEASURE[scene][1])
    ref_norm = norm(d64, f_ref)
    e64, e32 = runs["float64"]["error"], runs[low]["error"]
    field_diff = norm(d64, f32 - f64) / ref_norm
    scn = d64.attrs
    out = {
        "row": name,
        "scene": scene,
        "label": label,
        "ne": int(scn["ne"]),
        "np": int(scn["np"]),
        "stepper": scn["stepper"],
        "dt": float(scn["dt"]),
        "days": float(d64.time[-1]),
        "steps": int(d64.steps.isel(time=-1)),
        "measure": MEASURE[scene][0],
        "error_float64": e64,
        "low": low,
        "mass_fixer": fixer,
        f"error_{low}": e32,
        "error_float64_recomputed": norm(d64, f64 - f_ref) / ref_norm,
        "error_difference": abs(e32 - e64) / e64,
        "field_difference": field_diff,
        "field_difference_over_error": field_diff / e64,
        "holds": abs(e32 - e64) <= HOLDS * e64,
    }
    for precision, r in runs.items():
        out[precision] = {k: v for k, v in r.items() if k != "ds"}
    return out


def table(rows: list[dict], low: str = "float32") -> list[str]:
    """The markdown table of the rows (float64 against ``low``)."""
    lines = [
        f"| scene, grid | stepper, Δt | measure | float64 | {low} | \\|Δ error\\| / error | "
        "‖f32 − f64‖ / ‖ref‖ (/ error) | mass change 64 / 32 | energy change 64 / 32 | "
        "enstrophy change 64 / 32 | CPU s (wall ms a step) 64 / 32 | verdict |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        a, b = r["float64"], r[low]
        label = f" ({r['label']})" if r["label"] else ""
        inv = [f"{a['invariants'][k]:+.1e} / {b['invariants'][k]:+.1e}" for k in INVARIANTS]
        lines.append(
            f"| {r['scene']} ne{r['ne']} np{r['np']}{label}, day {r['days']:g} | {r['stepper']}, {r['dt']:.1f} s "
            f"| {r['measure']} | {r['error_float64']:.4e} | {r[f'error_{low}']:.4e} "
            f"| {100 * r['error_difference']:.2g} % | {r['field_difference']:.2e} "
            f"({100 * r['field_difference_over_error']:.2g} %) | {' | '.join(inv)} "
            f"| {a['cpu_s']:.1f} ({a['ms_step']:.1f}) / {b['cpu_s']:.1f} ({b['ms_step']:.1f}) | {f'{low} holds' if r['holds'] else f'**{low} does not hold**'} |"
        )
    return lines


def label(rows: list[dict]) -> str:
    """A results file's run against float64, as a column names it: its precision ("kept" for the
    float32 state's default, "compensated"), ", no fixer" without its mass fixer."""
    low = rows[0]["low"]
    name = {"float32_state": "kept", "float32_state_compensated": "compensated"}.get(low, low)
    return name + ("" if rows[0].get("mass_fixer", True) else ", no fixer")


def combined_table(files: list[list[dict]]) -> list[str]:
    """The markdown table of the rows every file holds (the first file's order), each file's
    error, |Δ error| / error, field difference and mass change beside float64's (the first's)."""
    names = [label(rows) for rows in files]
    by_row = [{r["row"]: r for r in rows} for rows in files]
    shared = [r["row"] for r in files[0] if all(r["row"] in f for f in by_row)]
    both = " / ".join(names)
    lines = [
        f"| scene, grid, day | stepper, Δt | measure | float64 | {' | '.join(names)} | \\|Δ error\\| / error: {both} "
        f"| ‖f − f64‖ / ‖ref‖ (/ error): {both} | mass change: float64 / {both} |",
        "|---|---|---|---|" + "---|" * len(names) + "---|---|---|",
    ]
    for name in shared:
        rs = [f[name] for f in by_row]
        r = rs[0]
        label_ = f" ({r['label']})" if r["label"] else ""
        errors = " | ".join(f"{x['error_' + x['low']]:.4e}" for x in rs)
        moved = " / ".join(f"{100 * x['error_difference']:.2g} %" for x in rs)
        fields = " / ".join(f"{x['field_difference']:.2e} ({100 * x['field_difference_over_error']:.2g} %)" for x in rs)
        mass = " / ".join(f"{x[x['low']]['invariants']['mass_change']:+.1e}" for x in rs)
        lines.append(
            f"| {r['scene']} ne{r['ne']} np{r['np']}{label_}, day {r['days']:g} | {r['stepper']}, {r['dt']:.1f} s "
            f"| {r['measure']} | {r['error_float64']:.4e} | {errors} | {moved} | {fields} "
            f"| {r['float64']['invariants']['mass_change']:+.1e} / {mass} |"
        )
    return lines


def main() -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
    from results import RESULTS, recorded  # benchmarks/ is first on the path of a script run from it

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--rows", nargs="+", default=["all"], choices=[*GROUPS, *ROWS], metavar="ROW", help="rows or groups"
    )
    parser.add_argument("--keep", metavar="DIR", help="keep the run files there (ROW_PRECISION.nc)")
    parser.add_argument(
        "--precision", default="float32", choices=LOWER, help="the precision set against float64 (default %(default)s)"
    )
    parser.add_argument(
        "--no-mass-fixer",
        action="store_true",
        help="the float32 state without its mass fixer (numerics.mass_fixer = false)",
    )
    parser.add_argument("--results", metavar="STEM", help="results/STEM.json (default precision_accuracy)")
    parser.add_argument(
        "--table", nargs="+", metavar="STEM", help="print the table of these results files, run nothing"
    )
    args = parser.parse_args()
    if args.table:
        files = [json.loads((RESULTS / "precision_accuracy" / f"{stem}.json").read_text()) for stem in args.table]
        files = [f["figures"]["rows"] for f in files]
        same = len({label(rows) for rows in files}) == 1  # one precision and fixer: their rows in turn
        for line in table([r for rows in files for r in rows], files[0][0]["low"]) if same else combined_table(files):
            print(line)
        return
    os.environ.setdefault("SWE_SPHERE_THREADS", "1")  # read when the model is built
    if args.keep:
        os.makedirs(args.keep, exist_ok=True)
    with recorded(__file__, args.results) as figures:
        rows = []
        for name in expand(args.rows):
            rows.append(row_figures(name, args.keep, args.precision, not args.no_mass_fixer))
            r = rows[-1]
            print(
                f"{name}: {r['measure']} float64 {r['error_float64']:.6e} {args.precision} {r[f'error_{args.precision}']:.6e} "
                f"(|Δ| {100 * r['error_difference']:.3g} %), field Δ {r['field_difference']:.3e} "
                f"({100 * r['field_difference_over_error']:.3g} % of the error); ms a step "
                f"{r['float64']['ms_step']:.2f} / {r[args.precision]['ms_step']:.2f}; load {os.getloadavg()[0]:.2f}",
                flush=True,
            )
        print()
        for line in table(rows, args.precision):
            print(line)
        figures["rows"] = rows


if __name__ == "__main__":
    main()
