"""The levels of a peer study (``peer_dinosaur.py``, ``peer_homme.py``): the peer's best Δt at each
truncation (``best_step``), the table's summary, and each peer row beside the cheapest swe_sphere
row at least as accurate (``levels``)."""

from __future__ import annotations

import math
import statistics
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from peer_dinosaur import Study


def best_step(measure, reference_dt: float, steps: list[float], tolerance: float, st: Study, clock: str) -> dict:
    """The peer's largest Δt that keeps its error within ``tolerance`` (relative) of its error at
    ``reference_dt``: ``measure(dt)`` (→ (name, row)) at the reference, then at each of ``steps``
    above it, upwards, up to the first that blows up (a non-finite error or a failed run) or loses
    more than ``tolerance``. Returns the search: the reference's Δt and error, each tried step's Δt,
    error, cost a day on ``clock``, load and verdict, and the best Δt and its figures."""
    name, row = measure(reference_dt)
    e_ref = row[f"l2_{st.field}"]
    tried = []

    def note(dt: float, row: dict, verdict: str) -> None:
        cost = row.get(f"{clock}_per_day", [math.nan])[-1]
        tried.append(
            {
                "dt": dt,
                f"l2_{st.field}": row[f"l2_{st.field}"],
                f"{clock}_per_day": cost,
                "load": row["load"][-1],
                "verdict": verdict,
            }
        )

    if not math.isfinite(e_ref):
        raise RuntimeError(f"{name}: the reference step blew up; give a smaller --reference-dt")
    note(reference_dt, row, "reference")
    best = reference_dt
    for dt in sorted(x for x in set(steps) if x > reference_dt):
        _, row = measure(dt)
        e = row[f"l2_{st.field}"]
        if not math.isfinite(e) or e > 1e3 * e_ref:
            note(dt, row, "blew up")
            break
        if e > (1 + tolerance) * e_ref:
            note(dt, row, f"lost {e / e_ref - 1:.2%}")
            break
        note(dt, row, f"kept ({e / e_ref - 1:+.2%})")
        best = dt
    best_row = next(t for t in tried if t["dt"] == best)
    print(
        f"  best step {best:g} s: {st.field_name} l2 {best_row[f'l2_{st.field}']:.4g} ({e_ref:.4g} at "
        f"{reference_dt:g} s), {best_row[f'{clock}_per_day']:.3g} {clock} s a simulated day; stopped: "
        + (tried[-1]["verdict"] if tried[-1]["dt"] != best else "no larger step given")
    )
    return {
        "reference_dt": reference_dt,
        "reference_l2": e_ref,
        "tolerance": tolerance,
        "tried": tried,
        "best_dt": best,
        f"best_l2_{st.field}": best_row[f"l2_{st.field}"],
    }


def summary(table: dict, st: Study, clock: str = "cpu") -> None:
    """Print the table, one line a model, each row's median cost on ``clock`` ("cpu" or "wall") added to it."""
    print(f"model | dt s | {st.field_name} l2 | vorticity l2 | h l2 | {clock} s / simulated day (median) | load")
    for name, row in table.items():
        costs = row.get(f"{clock}_per_day", [])
        row[f"{clock}_per_day_median"] = statistics.median(costs) if costs else math.nan
        print(
            f"{name} | {row['dt']:g} | {row[f'l2_{st.field}']:.3g} | {row['l2_vorticity']:.3g} | {row['l2_h']:.3g} | "
            f"{row[f'{clock}_per_day_median']:.3g} | {min(row['load']):.1f}-{max(row['load']):.1f}"
            + (f" | failed: {row['failed']}" if "failed" in row else "")
        )
        if "t213_vs_t341" in row:
            print(f"  (T213 reference against T341 at {name}'s points: {st.field_name} l2 {row['t213_vs_t341']:.3g})")


def levels(table: dict, peers: dict, st: Study, clock: str = "cpu") -> list[dict]:
    """Per peer row the summary compares against (``peers``: truncation -> row name; at its best
    step under ``--best-step``), the cheapest swe_sphere row (median cost on ``clock``) whose error
    in the study's field (eq. 83, the same measure for both) is at most the peer's, and the cost
    ratio ours / the peer's; printed and returned."""
    key, cost = f"l2_{st.field}", f"{clock}_per_day_median"
    swe = {n: r for n, r in table.items() if n.startswith("swe_sphere ") and math.isfinite(r[key])}
    print(f"Dinosaur level ({st.field_name} l2) | its {clock} s a day | cheapest swe_sphere row reaching it | ratio")
    out = []
    for t, name in peers.items():
        peer = table[name]
        if not math.isfinite(peer[key]):
            continue
        reach = sorted((r[cost], n) for n, r in swe.items() if r[key] <= peer[key] and math.isfinite(r[cost]))
        level = {"truncation": t, "peer": name, "peer_dt": peer["dt"], key: peer[key], "peer_cost": peer[cost]}
        if reach:
            c, n = reach[0]
            level.update(swe=n, swe_l2=swe[n][key], swe_cost=c, ratio=c / peer[cost])
            print(
                f"{name} ({peer[key]:.4g}) | {peer[cost]:.3g} | {n} ({swe[n][key]:.4g} @ {c:.3g}) | {c / peer[cost]:.3g}x"
            )
        else:
            near = min(swe, key=lambda n: swe[n][key], default=None)
            tail = f"none (the nearest: {near}, {swe[near][key]:.4g})" if near else "none"
            print(f"{name} ({peer[key]:.4g}) | {peer[cost]:.3g} | {tail} | -")
        out.append(level)
    return out
