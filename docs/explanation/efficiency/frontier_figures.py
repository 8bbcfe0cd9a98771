"""The frontier figures of docs/explanation/efficiency/frontier.md with the peers' points: frontier_<case>.png from
frontier_<case>.csv (the merged ladders' rows) and peers_<case>.csv, which this script writes
from the peer benchmarks' results (for Galewsky ``benchmarks/results/peer_dinosaur/peer_dinosaur_galewsky_np56.json``:
Dinosaur and swe_sphere's np 5-6 runs beyond the ladder, in one run at low load, with
``peer_dinosaur_galewsky_np6_ne26.json``, and HOMME's ``sweqx`` from
``peer_homme_galewsky{,_lft,_lft240}.json``; ``peer_dinosaur_tc5.json`` and ``peer_dinosaur_tc5_dt{600,300,150}.json`` for TC5;
``peer_dinosaur_tc6.json`` and ``peer_dinosaur_tc6_fine.json`` for TC6: each peer
run's error in the frontier's quantity and its median CPU seconds a simulated day) and, for Galewsky, pySEs's point as
issue 63 measured it (not rerun: a cited figure, labelled so). The figure is the frontier's own
(``studies.frontier.frontier_figure``); peers_<case>.csv is what ``swe-sphere frontier --peers``
reads, so a user's frontier can show the same points. TC2, TC6 and TC7 have no peers' points: their
figures are the frontier's alone.

``--merge CASE FRONTIER_CSV...`` first folds sub-ladders' ``frontier.csv`` files (``swe-sphere
frontier``'s, each a rectangular ladder) into frontier_<case>.csv: a row replaces the row of the
same label (ne/np/stepper), the others are added, the rows are ordered by ne, np and stepper,
and ``on_front`` is recomputed over all of them (``frontier.pareto_front``).

    python docs/explanation/efficiency/frontier_figures.py            # every case, in docs/explanation/efficiency/
    python docs/explanation/efficiency/frontier_figures.py --merge tc5 fr/tc5_np6/frontier.csv   # then tc5's figure
"""

import argparse
import csv
import json
from pathlib import Path

import pandas as pd

from swe_sphere.studies import frontier

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parents[2] / "benchmarks" / "results"  # a folder per script (its studies and run sets in folders below)
DINOSAUR = "Dinosaur 1.5.1, imex_rk_sil3 + filter"
HOMME = "HOMME sweqx (E3SM 75e17cce), ne16 np4"
# case: (the frontier's field in the peer benchmark's rows, its results files: (file, the
# legend's model, the point's label from the run's setting t (the key's last word) and Δt dt,
# the keys of the rows taken)); TC5 also at shorter Δt. Galewsky's swe_sphere np 5-6 runs
# beside Dinosaur lie beyond the frontier's ladder.
SWE = "swe_sphere kgu35, np 5-6 runs beside Dinosaur"
CASES = {
    "galewsky": (
        "l2_vorticity",
        # Dinosaur from the np 5-6 run (load 1.4-2.0), beside the swe_sphere points it is compared with
        [("peer_dinosaur_galewsky_np56.json", DINOSAUR, "{t}", "dinosaur ")]
        + [(f"peer_dinosaur_galewsky_{stem}.json", SWE, "{t}", "swe_sphere ") for stem in ("np56", "np6_ne26")]
        + [(f"peer_homme_galewsky{stem}.json", HOMME, "{t}", "homme ") for stem in ("", "_lft", "_lft240")],
    ),
    "tc5": (
        "l2_h_surface",
        [("peer_dinosaur_tc5.json", DINOSAUR + ", Galewsky's Δt", "{t}", "dinosaur ")]
        + [
            (f"peer_dinosaur_tc5_dt{dt}.json", "Dinosaur, shorter Δt", "{t} {dt:g} s", "dinosaur ")
            for dt in (600, 300, 150)
        ],
    ),
    "tc6": (
        "l2_h_surface",
        # Dinosaur from the first run; the second's swe_sphere rows lie beyond the ladder (ne16 np6,
        # ne24 np4-5, the scene's ne30 np4)
        [("peer_dinosaur_tc6.json", DINOSAUR, "{t}", "dinosaur ")]
        + [("peer_dinosaur_tc6_fine.json", "swe_sphere kgu35, runs beside Dinosaur", "{t}", "swe_sphere ")],
    ),
    "tc2": ("l2_h_surface", []),  # no peer has run it
    "tc7": ("l2_h_surface", []),  # case 7 (tc7_era_january): no peer has run it
}
CITED = {  # issue 63's table, not rerun here: (model, label, error, CPU s a simulated day)
    "galewsky": [("pySEs 0.1.3, issue 63's figure (not rerun)", "ne16 np4", 0.76, 18.9)],
}


def peers(case: str) -> list[dict]:
    """The case's peer points (``frontier.PEER_COLUMNS``): the peers' from their benchmarks'
    results files, then the cited ones."""
    field, sources = CASES[case]
    out = []
    for name, model, label, prefix in sources:
        runs = json.loads(next(RESULTS.glob(f"**/{name}")).read_text())["figures"]["runs"]
        out += [
            {
                "model": model,
                "label": label.format(t=key.split()[-1], dt=row["dt"]),
                "error": row[field],
                "cost_per_day": row["cpu_per_day_median"],
            }
            for key, row in runs.items()
            if key.startswith(prefix)
        ]
    out += [dict(zip(frontier.PEER_COLUMNS, values)) for values in CITED.get(case, [])]
    return out


def merge(case: str, files) -> Path:
    """Fold the sub-ladders' frontier.csv ``files`` into frontier_<case>.csv (module docstring:
    same label replaced, others added, ordered by ne, np and stepper, ``on_front`` recomputed).
    Raises ValueError when a file's case, error or clock differs from the table's."""
    path = HERE / f"frontier_{case}.csv"
    old = pd.read_csv(path, keep_default_na=False, na_values=[""])
    new = [pd.read_csv(f, keep_default_na=False, na_values=[""]) for f in files]
    key = ["case", "error_of", "reference", "cost_clock"]
    for f, df in zip(files, new):
        if not df[key].drop_duplicates().equals(old[key].drop_duplicates().reset_index(drop=True)):
            raise ValueError(f"{f}: not the same case, error, reference and clock as {path.name}")
    df = pd.concat([old, *new], ignore_index=True).drop_duplicates("label", keep="last")
    order = {s: i for i, s in enumerate(dict.fromkeys(df["stepper"]))}
    df = df.sort_values(["ne", "np", "stepper"], key=lambda c: c.map(order) if c.name == "stepper" else c)
    df["on_front"] = frontier.pareto_front(df["cost_per_day"], df["error"]).astype(int)
    df[old.columns].to_csv(path, index=False)
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", help=f"any of {', '.join(CASES)} (default: all)")
    ap.add_argument("--merge", nargs="+", metavar=("CASE", "FRONTIER_CSV"), help="fold these into CASE's table first")
    args = ap.parse_args()
    if args.merge:
        if args.merge[0] not in CASES or len(args.merge) < 2:
            ap.error(f"--merge takes a case ({', '.join(CASES)}) and frontier.csv files")
        print(f"merged into {merge(args.merge[0], args.merge[1:]).name}")
    unknown = set(args.cases) - set(CASES)
    if unknown:
        ap.error(f"unknown case(s): {', '.join(sorted(unknown))} (known: {', '.join(CASES)})")
    for case in args.cases or ([args.merge[0]] if args.merge else CASES):
        points = peers(case)
        peer_file = HERE / f"peers_{case}.csv"
        if points:
            with peer_file.open("w", newline="") as f:
                writer = csv.DictWriter(f, fieldnames=frontier.PEER_COLUMNS)
                writer.writeheader()
                writer.writerows(
                    {**p, "error": f"{p['error']:.4g}", "cost_per_day": f"{p['cost_per_day']:.4g}"} for p in points
                )
        df = pd.read_csv(HERE / f"frontier_{case}.csv")
        attrs = df.iloc[0][["scene", "days", "error_of", "reference", "cost_clock"]].to_dict()
        png = frontier.frontier_figure(
            HERE / f"frontier_{case}.png",
            df.to_dict("records"),
            attrs,
            frontier.read_peers(peer_file) if points else (),
        )
        print(f"wrote {peer_file.name + ' (' + str(len(points)) + ' points) and ' if points else ''}{png.name}")


if __name__ == "__main__":
    main()
