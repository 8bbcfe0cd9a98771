"""A sweep over the members of an ensemble (`swe-sphere sweep --members N` with `--perturbation
M`, `--initial FILE` or `--vary KEY=V1,...`): every (stepper, Δt) run made from each of N starts,
member k's the start an ensemble's member k has (``members.initial``: the case's state with h +
M metres of seeded white noise, member k of an ensemble's run file, or member k's own case
parameters, Ω, g or ν, its scenes then its own), so that each run's error comes with its spread
over the members (issue 85: a time integrator's error as a spread over members). Member k's
sweep is a sweep of its own under ``member<k>/`` (its runs, reference run and files, its runs'
keys naming its start); the Δt values are the sweep's scenes', the same for every member.
``members.csv`` then holds, for each run, the members' mean and sample standard deviation of
its errors and cost, and ``FIGURES`` draw the errors' mean and spread against Δt."""

from __future__ import annotations

import dataclasses
import hashlib
import math
from pathlib import Path

import numpy as np

from ...core.arguments import got, integer_argument, number_argument
from ...core.errors import ArgumentError
from ...grid.cubed_sphere import CubedSphere
from ...io.output_files import atomic_path
from ...members.initial import MemberFile, Perturbation, Variants, check_band, described, initial_states
from ..figures import members_plot
from .report import format_summary, write_outputs
from .verdicts import table

# the columns of a run's row ``members.csv`` takes the members' mean and spread of
SPREAD = ("total_error", "temporal_error", "total_energy_change", "cost_time", "rhs_equivalents")
# what a sweep over members writes in its folder besides each member's sweep: the table and its
# errors' figures (``figures.members_plot``), by column
FIGURES = {"total_error": "members_error_vs_dt.png", "temporal_error": "members_temporal_error_vs_dt.png"}
OUTPUTS = ("members.csv", *FIGURES.values())


@dataclasses.dataclass(frozen=True)
class Members:
    """``count`` N ≥ 2 members, started from ``initial`` as an ensemble's are: a ``Perturbation``
    (h + its amplitude, > 0 m, of seeded noise, white or of a band of degrees), a ``MemberFile`` (an ensemble's run file of
    N members) or ``Variants`` (each member's own case parameters, Ω, g or ν: member k's sweep is
    of its own scenes, its reference run too). ``ArgumentError`` naming the option for another
    count, a perturbation of 0 m or another kind of start."""

    count: int
    initial: object

    def __post_init__(self):
        integer_argument("--members", self.count, 2)
        if isinstance(self.initial, Perturbation):
            number_argument("--perturbation", self.initial.amplitude, "m", positive=True)
        elif not isinstance(self.initial, MemberFile | Variants):
            raise ArgumentError(
                f"members' initial must be a Perturbation, a MemberFile or Variants (got {got(self.initial)})"
            )

    def scenes(self, scenes: dict) -> list[dict]:
        """Each member's scenes (stepper name → ``Scene``) of the sweep's ``scenes``: theirs, or
        with ``Variants`` each at member k's values (``ArgumentError`` as ``Variants.scenes``)."""
        if not isinstance(self.initial, Variants):
            return [scenes] * self.count
        each = {name: self.initial.scenes(scene, self.count)[0] for name, scene in scenes.items()}
        return [{name: each[name][k] for name in scenes} for k in range(self.count)]

    def starts(self, scenes: dict) -> np.ndarray:
        """(N, 3, n) the members' starts on the grid of ``scenes`` (stepper name → ``Scene``),
        checked (``members.initial.initial_states``: ``ArgumentError`` naming ``initial``; a
        perturbation's band past the grid's degrees naming ``--perturbation-degrees``,
        ``members.initial.check_band``)."""
        scene = next(iter(scenes.values()))
        if isinstance(self.initial, Perturbation):  # noise past the grid's degrees would alias onto those it holds
            check_band(self.initial.degrees, scene, "--perturbation-degrees")
        case = scene.make_case()
        grid = CubedSphere(scene.ne, scene.np, case.planet.a, mesh=scene.make_mesh())
        variants = isinstance(self.initial, Variants)  # their cases start them
        cases = self.initial.scenes(scene, self.count)[1] if variants else None
        return initial_states(self.initial, grid, case, self.count, cases)

    def key(self, k: int, start: np.ndarray) -> dict:
        """What names member k's start ``start`` in its runs' keys: a perturbation's amplitude
        and seed, else the start's own SHA-256 (a file's member, or a variant's state; the
        variant's values are in its scene's key)."""
        if isinstance(self.initial, Perturbation):
            p = self.initial
            band = {} if p.degrees is None else {"degrees": list(p.degrees)}  # white noise's keys as before
            return {"member": k, "members": self.count, "perturbation": p.amplitude, "seed": p.seed, **band}
        digest = hashlib.sha256(np.ascontiguousarray(start, dtype=np.float64).tobytes()).hexdigest()
        return {"member": k, "members": self.count, "sha256": digest}

    def describe(self) -> str:
        """The members' starts in words, as the sweep's log says them."""
        return described(self.initial)


def run_members(resolved, members: Members, starts, pool, cost: str, overwrite: bool, log) -> tuple[list, list, list]:
    """(rows by member, info by member, paths) of ``resolved`` (a ``ResolvedPlan`` of a start of
    the scene's own) made from each of ``members``' ``starts`` (``Members.starts``) under
    ``member<k>/``, then ``members.csv`` (``spread_rows``) in the sweep's folder."""
    scenes = members.scenes(resolved.plan.scenes)
    rows, infos, paths = [], [], []
    for k, start in enumerate(starts):
        folder = resolved.directory / f"member{k}"
        log(f"member      {k} of {members.count} ({members.describe()})")
        plan = dataclasses.replace(resolved.plan, scenes=scenes[k])
        one = dataclasses.replace(resolved, plan=plan, directory=folder, start=start, start_id=members.key(k, start))
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
    first = infos[0]
    title = f"{first['case']} ne{first['ne']} np{first['np']}, {first['days']:g} days, {members.count} members"
    for column, name in FIGURES.items():
        paths.append(members_plot(resolved.directory / name, spread, column, title=title))
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
    lines = [f"over {members.count} members ({members.describe()}):", head]
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
