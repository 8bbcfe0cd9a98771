"""Stability suite: the largest stable Δt of each stepper on the hard cases.

A run is stable when it finishes with finite fields, depth > 0 and the total
energy never more than 1 % above its initial value. The largest stable Δt is
found by bisection on the number of steps per day (Δt = 86400 s / n, so every
candidate divides the day and the output interval; a run or output interval of no whole number
of days: per the longest interval that divides it and them, ``span``), on a coarse grid. Under step control
([time] control) the Δt bisected is the first step, from which the controller chooses the
others: the largest first step from which the run still ends, with the steps it took.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

from ..cases.scoring import ENERGY_GROWTH_LIMIT, instability
from ..config.scene import Scene, load_scene
from ..core.clock import common_interval
from ..core.constants import DAY
from ..core.errors import BlowUp, SceneError
from ..core.workers import InProcess
from ..io.output_files import atomic_path, check_results
from ..io.run_file import command_line, history_line
from ..io.table_file import table_dataset, write_table_file
from ..simulation.simulation import Simulation

# The hard cases: (label, scene, days, grid override); None keeps the scene's value.
HARD_CASES = (
    ("tc5_mountain", "tc5_mountain", None, None),
    ("tc6_rossby_haurwitz", "tc6_rossby_haurwitz", None, None),
    ("galewsky", "galewsky", None, None),
    ("tc7_era_january", "tc7_era_january", None, None),  # Williamson's case 7: a real spectrum
    ("tc2_steady_alpha_pi4_100d", "tc2_steady_alpha_pi4", 100.0, None),
    ("tc6_inviscid_ne30", "tc6_rossby_haurwitz_inviscid", None, 30),  # HOMME's known failure
)


@dataclass
class StabilityResult:
    """Largest stable Δt (s) found for one (case, stepper), with every trial run."""

    case: str
    stepper: str
    ne: int
    np: int
    days: float
    dt_stable: float  # largest Δt found stable (nan if none)
    dt_unstable: float  # smallest Δt found unstable (nan if none up to one day)
    courant_gravity: float  # gravity-wave Courant number of dt_stable at t = 0
    courant_advective: float
    trials: list = field(default_factory=list)  # (dt, stable, reason, wall s)
    control: str = ""  # the scene's step control ("error", "balanced", "cfl"; "": a fixed dt)
    steps: float = math.nan  # the dt_stable run's steps (under control the accepted ones)
    rejected_steps: float = math.nan  # the dt_stable run's rejected steps (NaN: a fixed dt)
    dt_mean: float = math.nan  # the dt_stable run's mean step (s)


def run_is_stable(scene: Scene, device: str) -> tuple[bool, str, float, dict]:
    """Run a scene; return (stable, reason, wall time, its last history entry: ``steps``,
    ``day``, under step control ``rejected_steps``...)."""
    t0 = time.perf_counter()
    try:
        result = Simulation(scene, device, progress=False).run(None)
    except BlowUp as err:
        result = err.result
    reason = instability(result)
    return not reason, reason, time.perf_counter() - t0, result.history[-1] if result.history else {}


def span(scene: Scene) -> float:
    """The interval (s) every candidate Δt of ``scene`` divides: a day, or where the run or its
    output interval is no whole number of days, the longest interval that divides the day, the
    run and the output interval (where shorter than the run; ``core.clock.common_interval``)."""
    every = scene.output_every_days
    return common_interval(1.0, scene.days, *((every,) if every < scene.days else ())) * DAY


def largest_stable_dt(scene: Scene, device: str, *, tolerance: float = 0.05, log=print) -> StabilityResult:
    """Bracket and bisect the largest stable Δt of ``scene`` (its stepper, grid and length).

    Starts from the scene's Δt, doubles or halves it to bracket the limit (down
    to 1/16 of the scene's Δt: below that the case counts as unstable at every
    Δt, dt_stable NaN), then bisects on steps per ``span`` until the bracket is
    within ``tolerance`` (relative). Under step control the Δt is the first step (the
    result's ``steps``, ``rejected_steps`` and ``dt_mean``: the dt_stable run's).
    """
    trials, counts = [], {}
    whole = span(scene)

    def stable(n: int) -> bool:
        s = dataclasses.replace(scene, dt=whole / n)
        ok, reason, wall, counts[n] = run_is_stable(s, device)
        trials.append((s.dt, ok, reason, wall))
        steps = ""
        if ok and s.control is not None:
            c = counts[n]
            steps = f"; {c['steps']} steps ({c['rejected_steps']} rejected), mean dt {_mean_dt(s, c):.1f} s"
        first = "first " if s.control is not None else ""
        log(
            f"  {scene.name} {scene.stepper} {first}dt = {s.dt:9.2f} s: {'stable' if ok else 'unstable'} ({wall:.1f} s)"
            f"{steps} {reason}"
        )
        return ok

    n = max(1, scene.clock.steps_in(whole / DAY))  # steps a span, the scene's Δt rounded to a whole number of them
    lo = hi = None  # lo: largest n found unstable (largest unstable dt); hi: smallest stable n
    if stable(n):
        hi = n
        while hi > 1:
            m = max(1, hi // 2)
            if stable(m):
                hi = m
            else:
                lo = m
                break
    else:
        lo = n
        while hi is None:
            m = lo * 2
            if m > 16 * n:  # unstable down to 1/16 of the scene's dt: report no stable dt
                break
            if stable(m):
                hi = m
            else:
                lo = m
    while lo is not None and hi is not None and hi - lo > 1 and (hi - lo) / hi > tolerance:
        mid = (lo + hi) // 2
        if stable(mid):
            hi = mid
        else:
            lo = mid
    dt_stable = whole / hi if hi is not None else math.nan
    courant = {"courant_gravity": math.nan, "courant_advective": math.nan}
    run = {}
    if hi is not None:
        courant = Simulation(dataclasses.replace(scene, dt=dt_stable), device, progress=False).courant()
        c = counts[hi]
        run = {"steps": c["steps"], "dt_mean": _mean_dt(dataclasses.replace(scene, dt=dt_stable), c)}
        run["rejected_steps"] = c.get("rejected_steps", math.nan)
    return StabilityResult(
        case=scene.name,
        stepper=scene.stepper,
        ne=scene.ne,
        np=scene.np,
        days=scene.days,
        dt_stable=dt_stable,
        dt_unstable=whole / lo if lo is not None else math.nan,
        courant_gravity=courant["courant_gravity"],
        courant_advective=courant["courant_advective"],
        trials=trials,
        control="" if scene.control is None else scene.control.mode,
        **run,
    )


def _mean_dt(scene: Scene, last: dict) -> float:
    """The mean step (s) of a run of ``scene`` whose last history entry is ``last``."""
    return (last["day"] - scene.start_day) * DAY / max(last["steps"], 1)


def suite_scenes(cases, steppers, *, ne=None, np_=None, days=None, mesh=None, overrides=None) -> list[Scene]:
    """The scene of every (case, stepper) of ``run_suite``, in that order, named by the
    case's label. ``cases``: entries of ``HARD_CASES``; ``ne``/``np_`` override the grid
    and ``days`` the run length of cases that do not fix them, ``mesh`` (an Exodus .g
    path) the grid of every case (HOMME's ne = 0: with ``ne`` None); ``overrides``
    ({"section.key": value}, as ``load_scene``) apply to every case. Raises
    ``SceneError`` on a bad value, before anything runs or is written."""
    return [
        dataclasses.replace(
            load_scene(
                scene_name,
                ne=case_ne or ne,
                np_=np_,
                days=case_days or days,
                stepper=stepper,
                mesh=mesh,
                overrides=overrides,
            ),
            name=label,
        )
        for label, scene_name, case_days, case_ne in cases
        for stepper in steppers
    ]


def run_suite(
    cases, steppers, device, *, ne=None, np_=None, days=None, mesh=None, overrides=None, log=print, pool=None
) -> list[StabilityResult]:
    """Largest stable Δt for every (case, stepper) of ``suite_scenes`` (its arguments
    and errors). The bisections are independent: ``pool`` (a concurrent.futures
    executor, ``swe_sphere.core.workers``; None: here, one after another) runs them;
    results in (case, stepper) order."""
    pool = pool or InProcess()
    futures = []
    for scene in suite_scenes(cases, steppers, ne=ne, np_=np_, days=days, mesh=mesh, overrides=overrides):
        log(f"{scene.name}: {scene.stepper} on {scene.grid_text}, {scene.days:g} days")
        futures.append(pool.submit(largest_stable_dt, scene, device, log=log))
    return [f.result() for f in futures]


@dataclass(frozen=True)
class Suite:
    """A stability suite, every value checked (``plan``): its ``HARD_CASES`` entries, the
    steppers, ``suite_scenes``'s keywords and the folder its results go to by default."""

    cases: tuple
    steppers: tuple
    given: dict
    default_output: Path

    def run(self, device: str, *, log=print, pool=None) -> list[StabilityResult]:
        """``run_suite`` of this suite."""
        return run_suite(self.cases, self.steppers, device, **self.given, log=log, pool=pool)


def plan(labels, steppers, *, ne: int, np_=None, days=None, mesh=None, overrides=None) -> Suite:
    """The suite of the case ``labels`` (none: every hard case) and ``steppers``, on the
    ``ne`` cube or on ``mesh`` (an Exodus .g path; not with a case that fixes its grid);
    the other keywords as ``suite_scenes``. Its default folder is
    ``stability_<labels, or all>_ne<ne>`` or ``_<the mesh file's stem>``: one per suite, so
    that a page's suites run in order do not meet each other's files. Raises
    ``ValueError`` (an unknown label) or ``SceneError`` on a bad value, before anything
    runs or is written."""
    known = {c[0]: c for c in HARD_CASES}
    for label in labels:
        if label not in known:
            raise ValueError(f"unknown stability case {label!r} (known: {', '.join(known)})")
    if ne < 1:
        raise SceneError(f"--ne must be an integer >= 1 (got {ne})")
    cases = tuple(known[c] for c in labels) if labels else HARD_CASES
    if mesh is not None:
        fixed = [label for label, _, _, case_ne in cases if case_ne is not None]
        if fixed:
            raise SceneError(f"stability case {fixed[0]} fixes its grid: not with --mesh (name the other cases)")
    given = dict(ne=None if mesh is not None else ne, np_=np_, days=days, mesh=mesh, overrides=overrides)
    suite_scenes(cases, steppers, **given)  # every value refused before the output folder is made
    grid = f"ne{ne}" if mesh is None else Path(mesh).stem
    return Suite(cases, tuple(steppers), given, Path(f"stability_{'_'.join(labels) or 'all'}_{grid}"))


OUTPUTS = ("stability.csv", "stability.nc")  # what write_table writes
COLUMN_ATTRS = {  # stability.csv's columns: (units, None for text; long_name), stability.nc's variables
    "case": (None, "case label (a hard case of the suite)"),
    "stepper": (None, "time stepper"),
    "ne": ("1", "elements along a cube edge"),
    "np": ("1", "GLL points along an element edge"),
    "days": ("day", "run length"),
    "dt_stable": ("s", "largest time step found stable (under step control the first step; NaN if none)"),
    "dt_unstable": ("s", "smallest time step found unstable (NaN if none up to one day)"),
    "courant_gravity": ("1", "gravity-wave Courant number sqrt(g h) dt / dx of dt_stable at t = 0"),
    "courant_advective": ("1", "advective Courant number |v| dt / dx of dt_stable at t = 0"),
    "trials": ("1", "runs of the bisection"),
    "control": (None, 'step control of the runs ("error", "balanced", "cfl"; empty: a fixed dt)'),
    "steps": ("1", "steps of the dt_stable run (under step control the accepted ones)"),
    "rejected_steps": ("1", "steps the error control rejected in the dt_stable run (NaN: a fixed dt)"),
    "dt_mean": ("s", "mean time step of the dt_stable run"),
}


def write_table(results, directory, *, overwrite: bool = False) -> tuple:
    """Write ``OUTPUTS`` under ``directory``; return their paths: stability.csv, one row
    a (case, stepper), and stability.nc, the same rows on one ``row`` dimension
    (``table_file.table_dataset``: ``COLUMN_ATTRS``, ``case`` and ``stepper`` as
    character arrays, integers int32; ``ds.set_index(row=["case", "stepper"])`` labels
    the rows) with the stability criterion as a global attribute. Raises
    ``OutputError`` before writing either if one exists (unless ``overwrite``)."""
    import pandas as pd

    rows = [{k: v for k, v in dataclasses.asdict(r).items() if k != "trials"} for r in results]
    for row, r in zip(rows, results):
        row["trials"] = len(r.trials)
    df = pd.DataFrame(rows, columns=list(COLUMN_ATTRS))
    check_results(directory, OUTPUTS, overwrite)
    csv, nc = (directory / name for name in OUTPUTS)
    with atomic_path(csv, overwrite=overwrite) as tmp:
        df.to_csv(tmp, index=False)
    ds = table_dataset(
        df,
        "row",
        COLUMN_ATTRS,
        row_long_name="(case, stepper) of the suite (row of stability.csv)",
        title="swe_sphere stability suite: the largest stable time step of each stepper on the hard cases",
        history=history_line(command_line("swe_sphere stability")),
        attrs=dict(criterion=f"finite fields, depth > 0, total energy <= {1 + ENERGY_GROWTH_LIMIT} x initial"),
    )
    write_table_file(ds, nc, overwrite=overwrite)
    return csv, nc


def format_table(results) -> str:
    """The suite's table; where a run's steps are chosen step to step, its dt the first step
    and the dt_stable run's accepted and rejected steps and mean dt beside."""
    controlled = any(r.control for r in results)
    lines = [
        f"{'case':28s} {'stepper':22s} {'ne':>3s} {'np':>3s} {'days':>5s} {'dt stable':>10s} {'dt unstable':>11s} {'C_grav':>7s} {'C_adv':>6s}"
        + (f" {'control':>8s} {'steps':>7s} {'rejected':>8s} {'dt mean':>8s}" if controlled else "")
    ]
    for r in results:
        lines.append(
            f"{r.case:28s} {r.stepper:22s} {r.ne:3d} {r.np:3d} {r.days:5g} {r.dt_stable:10.1f} {r.dt_unstable:11.1f} "
            f"{r.courant_gravity:7.2f} {r.courant_advective:6.2f}"
            + (
                f" {r.control or 'fixed':>8s} {r.steps:7.0f} {r.rejected_steps:8.0f} {r.dt_mean:8.1f}"
                if controlled
                else ""
            )
        )
    if controlled:
        lines.append("under step control dt stable is the largest first step from which the run ends")
    return "\n".join(lines)
