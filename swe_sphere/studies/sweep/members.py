"""A sweep over the members of an ensemble (`swe-sphere sweep --members N --perturbation M`):
every (stepper, Δt) run made from each of N starts, the case's state with h + M metres of
seeded white noise (``ensemble.Perturbation``, member k the start an ensemble's member k has),
so that each run's error comes with its spread over the starts (issue 85: a time integrator's
error as a spread over members). Member k's sweep is a sweep of its own under
``member<k>/`` (its runs, reference run and files, its runs' keys naming its start); the Δt
values are the unperturbed scene's, the same for every member. ``members.csv`` then holds, for
each run, the members' mean and sample standard deviation of its errors and cost."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np

from ...core.arguments import integer_argument, number_argument
from ...ensemble.initial import Perturbation
from ...grid.cubed_sphere import CubedSphere
from ...io.output_files import atomic_path
from .report import format_summary, write_outputs
from .verdicts import table

# the columns of a run's row ``members.csv`` takes the members' mean and spread of
SPREAD = ("total_error", "temporal_error", "total_energy_change", "cost_time", "rhs_equivalents")


@dataclasses.dataclass(frozen=True)
class Members:
    """``count`` N ≥ 2 starts: the case's state with h + ``perturbation`` (m, > 0) white noise
    seeded by ``seed`` (``ensemble.Perturbation``). ``ValueError`` naming the option for
    another count, amplitude or seed."""

    count: int
    perturbation: float
    seed: int = 0

    def __post_init__(self):
        integer_argument("--members", self.count, 2)
        number_argument("--perturbation", self.perturbation, "m", positive=True)
        integer_argument("--seed", self.seed, 0)

    def starts(self, scene) -> np.ndarray:
        """(N, 3, n) the members' starts on ``scene``'s grid."""
        grid = CubedSphere(scene.ne, scene.np, scene.make_case().planet.a, mesh=scene.make_mesh())
        state = np.stack(scene.make_case().initial(grid.lat, grid.lon))
        return Perturbation(self.perturbation, self.seed).apply(grid, state, self.count)

    def key(self, k: int) -> dict:
        """What names member k's start in its runs' keys."""
        return {"member": k, "members": self.count, "perturbation": self.perturbation, "seed": self.seed}


def run_members(resolved, members: Members, pool, cost: str, overwrite: bool, log) -> tuple[list, list, list]:
    """(rows by member, info by member, paths) of ``resolved`` (a ``ResolvedPlan`` of a start of
    the scene's own) made from each of ``members``' starts under ``member<k>/``, then
    ``members.csv`` (``spread_rows``) in the sweep's folder."""
    starts = members.starts(resolved.plan.base)
    rows, infos, paths = [], [], []
    for k, start in enumerate(starts):
        folder = resolved.directory / f"member{k}"
        log(f"member      {k} of {members.count}: h + {members.perturbation:g} m of noise (seed {members.seed})")
        one = dataclasses.replace(resolved, directory=folder, start=start, start_id=members.key(k))
        made, info = one.sweep(log).run(pool)
        made = table(made, resolved.limits, cost)
        paths += write_outputs(made, info, resolved.limits, folder, overwrite=overwrite)
        rows.append(made)
        infos.append(info)
    log(format_summary(rows[0], infos[0]))
    spread = spread_rows(rows)
    path = resolved.directory / "members.csv"
    with atomic_path(path, overwrite=overwrite) as tmp:
        _write_csv(tmp, spread)
    paths.append(path)
    log(format_spread(spread, members))
    return rows, infos, paths


def spread_rows(rows: list) -> list[dict]:
    """A row a run (stepper, Δt) of the members' rows ``rows`` (a list a member): its stepper,
    Δt, the members it was stable in, and each ``SPREAD`` column's mean and sample standard
    deviation over those members (NaN with fewer than two)."""
    out = []
    for first in rows[0]:
        mine = [
            next(r for r in member if (r["stepper"], r["dt"]) == (first["stepper"], first["dt"])) for member in rows
        ]
        stable = [r for r in mine if r.get("stable", True)]
        row = {"stepper": first["stepper"], "dt": first["dt"], "members": len(mine), "stable": len(stable)}
        for column in SPREAD:
            values = np.array([float(r.get(column, math.nan)) for r in stable])
            row[f"{column}_mean"] = float(values.mean()) if values.size else math.nan
            row[f"{column}_spread"] = float(values.std(ddof=1)) if values.size > 1 else math.nan
        out.append(row)
    return out


def format_spread(spread: list[dict], members: Members) -> str:
    """The members' table as the sweep prints it."""
    head = f"{'stepper':22s} {'dt [s]':>9s} {'stable':>7s} {'total err (mean ± sd)':>24s} {'time err (mean ± sd)':>24s}"
    lines = [f"over {members.count} members (h + {members.perturbation:g} m, seed {members.seed}):", head]
    for r in spread:
        total = f"{r['total_error_mean']:.4g} ± {r['total_error_spread']:.2g}"
        temporal = f"{r['temporal_error_mean']:.4g} ± {r['temporal_error_spread']:.2g}"
        lines.append(
            f"{r['stepper']:22s} {r['dt']:9.4g} {r['stable']:>3d}/{r['members']:<3d} {total:>24s} {temporal:>24s}"
        )
    return "\n".join(lines)


def _write_csv(path: Path, rows: list[dict]) -> None:
    import pandas as pd

    pd.DataFrame(rows).to_csv(path, index=False)
