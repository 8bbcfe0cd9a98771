"""The frontier figures of docs/efficiency.md with the peers' points: frontier_<case>.png from
frontier_<case>.csv (the merged ladders' rows) and peers_<case>.csv, which this script writes
from the peer benchmarks' results (for Galewsky ``benchmarks/results/peer_dinosaur_galewsky_np56.json``:
Dinosaur and swe_sphere's np 5-6 runs beyond the ladder, in one run at low load, with
``peer_dinosaur_galewsky_np6_ne26.json``, and HOMME's ``sweqx`` from
``peer_homme_galewsky{,_lft,_lft240}.json``; ``peer_dinosaur_tc5.json`` and ``peer_dinosaur_tc5_dt{600,300,150}.json`` for TC5: each peer
run's error in the frontier's quantity and its median CPU seconds a simulated day) and, for Galewsky, pySEs's point as
issue 63 measured it (not rerun: a cited figure, labelled so). The figure is the frontier's own
(``studies.frontier.frontier_figure``); peers_<case>.csv is what ``swe-sphere frontier --peers``
reads, so a user's frontier can show the same points.

    python docs/efficiency/frontier_figures.py            # galewsky and tc5, in docs/efficiency/
"""

import argparse
import csv
import json
from pathlib import Path

import pandas as pd

from swe_sphere.studies import frontier

HERE = Path(__file__).resolve().parent
RESULTS = HERE.parents[1] / "benchmarks" / "results"
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
        runs = json.loads((RESULTS / name).read_text())["figures"]["runs"]
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


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("cases", nargs="*", help=f"any of {', '.join(CASES)} (default: all)")
    args = ap.parse_args()
    unknown = set(args.cases) - set(CASES)
    if unknown:
        ap.error(f"unknown case(s): {', '.join(sorted(unknown))} (known: {', '.join(CASES)})")
    for case in args.cases or CASES:
        points = peers(case)
        peer_file = HERE / f"peers_{case}.csv"
        with peer_file.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=frontier.PEER_COLUMNS)
            writer.writeheader()
            writer.writerows(
                {**p, "error": f"{p['error']:.4g}", "cost_per_day": f"{p['cost_per_day']:.4g}"} for p in points
            )
        df = pd.read_csv(HERE / f"frontier_{case}.csv")
        attrs = df.iloc[0][["scene", "days", "error_of", "reference", "cost_clock"]].to_dict()
        png = frontier.frontier_figure(
            HERE / f"frontier_{case}.png", df.to_dict("records"), attrs, frontier.read_peers(peer_file)
        )
        print(f"wrote {peer_file.name} ({len(points)} points) and {png.name}")


if __name__ == "__main__":
    main()
