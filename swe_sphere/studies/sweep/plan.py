"""The plan of a sweep: ``plan(scene, ...)`` checks the options of `swe-sphere sweep` and turns
a scene into a ``Plan`` (the steppers' scenes, Δt values or multiples of the gravity-wave
limit, the time filter); ``Plan.resolve`` gives the Δt values and notes on a device
(``ResolvedPlan``), and ``Plan.run`` is what the command runs: the runs (``runs.Sweep``), the
summary and the files (``report``)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...config.control import TOLERANCES, resolve_control, tolerance_table
from ...config.scene import Scene, load_scene
from ...core.backend import pick_device
from ...core.clock import Clock
from ...core.constants import DAY
from ...io.output_files import check_results, folder_lock
from ...simulation import checkpoint
from ...steppers.timefilter import TimeFilter
from .members import OUTPUTS as MEMBER_OUTPUTS
from .members import run_members
from .report import OUTPUTS, format_summary, write_outputs
from .runs import Sweep, dt_for_day, explicit_limits, start_state
from .verdicts import table

# The reference RK4 run's Δt is at most this multiple of the gravity-wave limit, also
# when every swept Δt is large: RK4 is stable to ≈ 1.7 and its time error there is nil
REFERENCE_MAX_GRAVITY_COURANT = 0.25
# best of the solver families (IMEX, Crank-Nicolson JFNK): a default sweep answers its question
DEFAULT_STEPPERS = ("rk4", "kgu35", "imex", "implicit")
DEFAULT_COURANT = (0.5, 1, 2, 5, 10, 30, 60, 100)  # multiples of the gravity-wave limit


def _positive(values, flag: str) -> tuple[float, ...]:
    """``values`` as a tuple of floats; ValueError (naming ``flag``) for none, or one not finite and > 0."""
    values = tuple(float(v) for v in values)
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise ValueError(f"{flag} values must be > 0 (got {', '.join(f'{v:g}' for v in values) or 'none'})")
    return values


def _check_whole(dt: float, days: float, what: str, source: str = "--dt") -> None:
    """``SceneError`` unless ``days`` is a whole number of steps of ``dt`` (s): the clock's one
    whole-step rule and its refusal (``Clock.steps``: ``what`` of ``days`` days, dt from ``source``,
    the nearest intervals that are)."""
    Clock(dt, source=source).steps(days, what)


@dataclass(frozen=True)
class Plan:
    """A sweep as asked for (``plan``): its scenes and steps, before the start state
    and the explicit limits that turn multiples of the gravity-wave limit into Δt.

    Attributes
    ----------
    scenes : dict[str, Scene]
        Stepper name → its resolved scene; one case and grid.
    dts : tuple[float, ...] or None
        The Δt values (s) given; None where they come from ``multiples``.
    multiples : tuple[float, ...] or None
        Multiples of the gravity-wave limit (Courant number 1) to sweep.
    runs : tuple[tuple[str, float], ...] or None
        Only these (stepper, multiple) runs; None: every stepper × every Δt.
    controlled : tuple[str, ...]
        The names of the runs whose steps are chosen step to step ("bs32@rtol=1e-05"),
        each a key of ``scenes`` (its scene's ``control`` set), run once from its scene's Δt.
    time_filter : TimeFilter or None
        The Lanczos low-pass the runs are also scored by.
    overrides : dict
        The ``section.key`` settings applied to every scene, for the record.
    restart : Path or None
        The restart file every run branches from, as given.
    checkpoint : Checkpoint or None
        Its contents (``checkpoint.read``).
    given : bool
        The ``multiples`` were given (``courant`` or ``runs``): one whose Δt is longer than the
        run is refused (``resolve``); the defaults' are capped at the run.
    """

    scenes: dict
    dts: tuple | None
    multiples: tuple | None
    runs: tuple | None
    controlled: tuple
    time_filter: TimeFilter | None
    overrides: dict
    restart: Path | None
    checkpoint: object | None
    given: bool = False

    @property
    def base(self) -> Scene:
        """The first stepper's scene: the case, grid and days every run shares."""
        return next(iter(self.scenes.values()))

    @property
    def default_output(self) -> Path:
        """The results' folder when none is given, in the working folder:
        ``sweep_<scene>_<grid>np<np>_<days>d`` (``<grid>``: ``Scene.grid_label``), with
        ``_from<restart file stem>`` for a branch, so that a page's sweeps of other
        cases, grids or lengths do not meet in one folder, and a rerun finds its runs."""
        b = self.base
        name = f"sweep_{b.name}_{b.grid_label}np{b.np}_{b.days:g}d"
        if self.restart is not None:
            name += f"_from{Path(self.restart).name.removesuffix('.nc').removesuffix('.restart')}"
        return Path(name)

    @property
    def span(self) -> float:
        """What every Δt must divide (days): the run length, or the filter's snapshot interval."""
        return self.base.run_days if self.time_filter is None else self.time_filter.every_hours / 24

    def resolve(self, directory, device: str | None = None, log=print) -> ResolvedPlan:
        """The runs to make: the start state (the restart file's, or ``start_state``:
        a digital-filter start made once under ``directory/runs``, ``log``ged), the
        explicit limits on ``device`` ("cpu" or "cuda"; None: ``SWE_SPHERE_DEVICE``, else CUDA when present,
        ``pick_device``; ``explicit_limits``), each multiple's Δt (the
        largest at or below it that divides ``span`` and a day: ``dt_for_day``) and
        the notes `swe-sphere sweep` prints before its runs. Raises SceneError for a
        Δt of which the run length is not whole steps (``Clock.steps``)."""
        base, ck, f, span = self.base, self.checkpoint, self.time_filter, self.span
        device = pick_device(device)
        start = ck.x if ck is not None else start_state(base, directory, device, log)
        limits = explicit_limits(base, device, start)
        dts, pairs, notes = self.dts, self.runs, []
        if dts is None:
            g = limits["dt_gravity"]
            if self.given and f is None:  # a time filter caps Δt at its snapshot interval instead
                _check_multiples(self.multiples, g, span, pairs)
            dt_of = {m: dt_for_day(m * g, span) for m in self.multiples}
            dts = tuple(sorted(set(dt_of.values())))
            asked = {m: "/".join(f"{s}@{m:g}" for s, k in pairs if k == m) if pairs else f"{m:g}" for m in dt_of}
            pairs = tuple((s, dt_of[m]) for s, m in pairs) if pairs is not None else None
            capped = [m for m in dt_of if f is not None and _longer(m, g, span)]
            if capped:  # Δt must divide the filter's snapshot interval
                notes.append(
                    f"note        --courant {','.join(f'{m:g}' for m in capped)}: dt capped at the filter's "
                    f"{f.every_hours:g} h snapshot interval ({span * DAY / g:.3g} x the "
                    "gravity-wave limit); --filter-every sets it"
                )
            rounded = [
                f"{asked[m]} runs at {dt_of[m] / g:.3g}"
                for m in dt_of
                if m not in capped and dt_of[m] < m * g * (1 - 1e-3)
            ]
            if rounded:  # the multiple that ran, not the one asked for
                notes.append(
                    f"note        {'--runs' if pairs else '--courant'} {', '.join(rounded)} x the gravity-wave limit "
                    f"(each dt the largest at or below its multiple that divides {min(span, 1.0):g} days)"
                )
            for dt in dts:
                _check_whole(dt, base.run_days, "the run length", "a multiple of the gravity-wave limit")
        if self.controlled:  # each run once, from its scene's Δt
            pairs = (*(pairs or ()), *((name, self.scenes[name].dt) for name in self.controlled))
        chosen = ", ".join(f"{name} (first dt {self.scenes[name].dt:.4g} s)" for name in self.controlled)
        notes.append(
            f"sweep {base.name} {base.grid_text}, {f'day {base.start_day:g} to ' if ck else ''}"
            f"{base.days:g} days; explicit limits: gravity-wave dt = {limits['dt_gravity']:.1f} s, advective dt = "
            f"{limits['dt_advective']:.1f} s"
            + (f"; dt = {', '.join(f'{d:.4g}' for d in dts)}" if dts else "")
            + (f"; steps chosen step to step: {chosen}" if chosen else "")
        )
        if ck is not None:
            b = base.branch
            notes.append(
                f"start       the state of {self.restart} at day {b['day']:g} (step {b['step']} of {b['stepper']}, "
                f"dt = {b['dt']:g} s), for every run and the reference run; each stepper starts there afresh"
            )
        elif start is not None:
            notes.append(
                f"start       digital-filter initialization (cutoff {base.digital_filter.cutoff_hours:g} h, span "
                f"{base.digital_filter.span_hours:g} h), the same state for every run; the spectral reference starts "
                "impulsively, so the spatial error (and the verdicts' thresholds) include the gravity waves it keeps"
            )
        return ResolvedPlan(self, Path(directory), device, list(dts), pairs, start, limits, notes)

    def run(
        self,
        directory,
        device: str | None = None,
        *,
        pool=None,
        cost: str = "cpu",
        overwrite: bool = False,
        log=print,
        members=None,
    ):
        """What `swe-sphere sweep` runs: under a lock on ``directory`` (``folder_lock``;
        an earlier sweep's results refused unless ``overwrite``), ``resolve`` and ``log``
        its notes, make or reuse every run (``Sweep.run`` on ``pool``), ``log`` the
        summary (``format_summary``) and write ``OUTPUTS`` (``write_outputs``).

        Parameters
        ----------
        directory : str or path
            The results' folder (created), its runs kept under ``runs/`` and reused
            where made with the same settings.
        device : {"cpu", "cuda"}, optional
            Warp device (default: ``SWE_SPHERE_DEVICE`` where set, else CUDA when present).
        pool : concurrent.futures.Executor, optional
            Runs the runs (``core.workers.executor``); None: one after another, here.
        cost : {"cpu", "wall"}
            The clock the runs are ranked by (``table``).
        overwrite : bool
            Replace an earlier sweep's results in ``directory``.
        log : callable
            Called with each line to show.
        members : members.Members, optional
            N members' starts (perturbed, from an ensemble's file, or varied scenes): the
            sweep made from each under ``member<k>/``, and ``members.csv`` the runs' errors'
            mean and spread over them (``members.run_members``, whose (rows, infos, paths)
            by member it returns).

        Returns
        -------
        rows : list[dict]
            ``table``'s rows, ranked by ``cost`` ("cpu" or "wall").
        info : dict
            ``Sweep.run``'s summary: the spatial errors, the reference, the record.
        paths : list[Path]
            The files written.

        Raises
        ------
        OutputError
            Another sweep holds ``directory``, or its results exist (without ``overwrite``).
        SceneError
            A Δt of which the run length is not whole steps (``Clock.steps``).
        ValueError
            An unknown ``cost``; ``members`` with a restart file's or a digital filter's start,
            or whose starts are refused (``Members.starts``: an ``ArgumentError``).
        BlowUp
            The small-Δt reference run failed.
        Interrupted
            SIGINT or SIGTERM; what is kept is said.
        """
        if members is not None and (self.checkpoint is not None or self.base.digital_filter is not None):
            raise ValueError("--members: the members start from the case's state (not with --from or a dfi start)")
        starts = None if members is None else members.starts(self.scenes)  # refused before a folder is made
        with folder_lock(directory, "sweep.lock"):  # a second sweep into this folder is refused now, not at its end
            check_results(directory, OUTPUTS, overwrite)  # an earlier sweep's results: refused now, not at the end
            for k in range(0 if members is None else members.count):
                check_results(Path(directory) / f"member{k}", OUTPUTS, overwrite)
            check_results(directory, MEMBER_OUTPUTS if members is not None else (), overwrite)
            resolved = self.resolve(directory, device, log)
            for line in resolved.notes:
                log(line)
            if members is not None:  # a sweep a member, then their spread
                return run_members(resolved, members, starts, pool, cost, overwrite, log)
            rows, info = resolved.sweep(log).run(pool)
            rows = table(rows, resolved.limits, cost)
            log(format_summary(rows, info))
            paths = write_outputs(rows, info, resolved.limits, directory, overwrite=overwrite)
            for path in paths:
                log(f"wrote {path}")
        return rows, info, paths


@dataclass(frozen=True)
class ResolvedPlan:
    """A ``Plan`` resolved on a device (``Plan.resolve``): the Δt values (s, ascending),
    the (stepper, Δt) runs (None: every stepper × every Δt), the start state (3, nnodes)
    or None, the explicit limits (``explicit_limits``) and the notes (lines of text)."""

    plan: Plan
    directory: Path
    device: str
    dts: list
    pairs: tuple | None
    start: np.ndarray | None
    limits: dict
    notes: list
    start_id: dict | None = None  # a member's start (``members``): in its runs' keys

    def sweep(self, log=print) -> Sweep:
        """The ``Sweep`` of these runs, its small-Δt reference at most
        ``REFERENCE_MAX_GRAVITY_COURANT`` × the gravity-wave limit."""
        p = self.plan
        return Sweep(
            p.scenes,
            self.dts,
            self.directory,
            self.device,
            log=log,
            time_filter=p.time_filter,
            start=self.start,
            start_id=self.start_id,
            pairs=None if self.pairs is None else list(self.pairs),
            overrides=p.overrides,
            reference_dt_max=REFERENCE_MAX_GRAVITY_COURANT * self.limits["dt_gravity"],
        )


def plan(
    scene=None,
    *,
    steppers=None,
    dts=None,
    courant=None,
    runs=None,
    ne: int | None = None,
    np_: int | None = None,
    days: float | None = None,
    overrides: dict | None = None,
    restart=None,
    filter_days: float | None = None,
    filter_every: float = 3.0,
    filter_window: float | None = None,
) -> Plan:
    """The sweep `swe-sphere sweep` would run with these options, validated; no run
    is made and no file written (``Plan.run`` makes them).

    Parameters
    ----------
    scene : str or path, optional
        Scene file or bundled scene name (``load_scene``); none with ``restart``.
    steppers : sequence of str, optional
        Stepper names (default ``DEFAULT_STEPPERS``); none with ``runs``.
    dts : sequence of float, optional
        Time steps (s).
    courant : sequence of float, optional
        Multiples of the gravity-wave limit (default ``DEFAULT_COURANT``).
    runs : sequence of (str, float or str), optional
        Only these (stepper, multiple of the gravity-wave limit) runs; a str in place of
        the multiple, "rtol=1e-5", "rtol_per_day=1e-4" (rtol per unit step), "balance=0.1"
        or "cfl=1.5", makes a run whose steps are chosen step to step (``TOLERANCES``: [time]
        control "error", "balanced" or "cfl" with that key), named "bs32@rtol=1e-05", from
        the scene's Δt. At most one
        of ``dts``, ``courant`` and ``runs``.
    ne, np_ : int, optional
        Elements along a cube edge and GLL points per element direction (default: the scene's).
    days : float, optional
        The last model day (default: the scene's, or the restart file's).
    overrides : dict, optional
        ``{"section.key": value}`` applied to every scene (``-s``).
    restart : str or path, optional
        A restart file: every run branches from its state, scene and grid (``--from``).
    filter_days, filter_every, filter_window : float, optional
        Also score the time-filtered flow (``TimeFilter``: cutoff period in days,
        snapshot interval in hours, half window in days); every Δt then divides
        the snapshot interval, and the run length is a multiple of it.

    Returns
    -------
    Plan

    Raises
    ------
    ValueError
        Options that conflict, none or non-positive values, a bad filter
        (messages name the options as `swe-sphere sweep` spells them).
    SceneError
        A bad scene, override or stepper (``load_scene``); a Δt of which the run length or
        the filter's snapshot interval is not whole steps (``Clock.steps``, naming ``--dt``).
    CheckpointError
        An unreadable restart file, or a branch it cannot make.

    Examples
    --------
    >>> p = plan("tc2_steady", ne=2, days=1, runs=[("rk4", 1), ("imex", 4)])  # doctest: +SKIP
    >>> rows, info, paths = p.run("sweep", "cpu")  # doctest: +SKIP
    """
    runs, controlled, steppers = _runs(runs, steppers, dts, courant)
    overrides = dict(overrides or {})
    scenes, ck = _scenes(scene, steppers, ne=ne, np_=np_, days=days, overrides=overrides, restart=restart)
    scenes |= {
        _name(s, key, value): _controlled(scene, s, key, value, ne=ne, np_=np_, days=days, overrides=overrides, ck=ck)
        for s, key, value in controlled
    }
    given = courant is not None or runs is not None
    dts, multiples = _steps(dts, courant, runs)
    time_filter = _time_filter(next(iter(scenes.values())).run_days, dts, filter_days, filter_every, filter_window)
    names = tuple(dict.fromkeys(_name(*c) for c in controlled))
    restart = None if ck is None else Path(restart)
    return Plan(scenes, dts, multiples, runs, names, time_filter, overrides, restart, ck, given)


def _longer(multiple: float, dt_gravity: float, span: float) -> bool:
    """Whether ``multiple`` × ``dt_gravity`` (s) is a Δt longer than ``span`` days (a hair over is not)."""
    return multiple * dt_gravity > span * DAY * (1 + 1e-9)


def _check_multiples(multiples, dt_gravity: float, span: float, pairs) -> None:
    """Refuse (ValueError, one line) a multiple of the gravity-wave limit ``dt_gravity`` (s)
    whose Δt is longer than the run of ``span`` days: it could only run as one step of the run
    (``rk4@1e9``). ``pairs``: the (stepper, multiple) runs of ``--runs`` (None: ``--courant``),
    for the message."""
    too_long = [m for m in multiples if _longer(m, dt_gravity, span)]
    if not too_long:
        return
    m = max(too_long)
    what = f"--runs {'/'.join(s for s, k in pairs if k == m)}@{m:g}" if pairs else f"--courant {m:g}"
    raise ValueError(
        f"{what}: {m:g} x the gravity-wave limit ({dt_gravity:.4g} s) is a dt of {m * dt_gravity:.3g} s, longer "
        f"than the run of {span:g} days; give a multiple of at most {span * DAY / dt_gravity:.3g}"
    )


def _name(stepper: str, key: str, value: float) -> str:
    """A controlled run's name: "bs32@rtol=1e-05"."""
    return f"{stepper}@{key}={value:g}"


def _tolerance(stepper: str, text: str) -> tuple[str, str, float]:
    """``runs``'s "KEY=VALUE" in place of a multiple → (stepper, key, value); ValueError naming
    the run for a key not in ``TOLERANCES`` or a value that is not a number > 0."""
    key, sep, given = (part.strip() for part in text.partition("="))
    if not sep or key not in TOLERANCES:
        raise ValueError(
            f"--runs {stepper}@{text}: a run's steps are chosen by {', '.join(f'{k}=VALUE' for k in TOLERANCES)} "
            f"(e.g. {stepper}@rtol=1e-5), or it names a multiple of the gravity-wave limit"
        )
    try:
        value = float(given)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"--runs {stepper}@{text}: {given!r} is not a number > 0")
    return stepper, key, value


def _controlled(scene, stepper, key, value, *, ne, np_, days, overrides, ck) -> Scene:
    """The scene of a controlled run (``_tolerance``'s): ``stepper`` under [time] control
    ``tolerance_table(key, value)``; a branch of the restart file ``ck`` where
    given. Raises ``SceneError`` for a stepper that cannot (``resolve_control``)."""
    table = tolerance_table(key, value)
    if ck is None:
        more = {f"time.{k}": v for k, v in table.items()}
        return load_scene(scene, ne=ne, np_=np_, days=days, stepper=stepper, overrides={**overrides, **more})
    s = checkpoint.branch(ck, stepper=stepper, days=days)
    return dataclasses.replace(s, control=resolve_control(table, stepper, s.stepper_options, s.dt))


def _runs(runs, steppers, dts, courant) -> tuple[tuple | None, list, list | None]:
    """``plan``'s (stepper, multiple) runs, checked (None: none given), its controlled runs
    ((stepper, key, value): ``_tolerance``) and the steppers of the fixed-Δt runs (``runs``'s,
    where given). Raises ValueError for ``runs`` with ``steppers``, more than one of ``dts``,
    ``courant`` and ``runs``, a multiple not > 0 or a bad "KEY=VALUE"."""
    if runs is not None and steppers is not None:
        raise ValueError("--runs names its own steppers: give --steppers or --runs, not both")
    if sum(x is not None for x in (dts, courant, runs)) > 1:
        raise ValueError("give one of --dt, --courant and --runs")
    controlled = []
    if runs is None and steppers is not None and not steppers:
        raise ValueError("--steppers names no stepper")
    if runs is not None:
        if not runs:
            raise ValueError("--runs names no run")
        controlled = [_tolerance(s, m) for s, m in runs if isinstance(m, str)]
        fixed = [(s, m) for s, m in runs if not isinstance(m, str)]
        runs = tuple((s, m) for (s, _), m in zip(fixed, _positive([m for _, m in fixed], "--runs") if fixed else ()))
        steppers = list(dict.fromkeys(s for s, _ in runs))
    return runs, controlled, steppers


def _steps(dts, courant, runs) -> tuple[tuple | None, tuple | None]:
    """``plan``'s Δt values (s; None: from multiples) and multiples of the gravity-wave
    limit (None: Δt values given; ``runs``'s, or ``courant``, or ``DEFAULT_COURANT``).
    Raises ValueError for a value not > 0."""
    dts = None if dts is None else _positive(dts, "--dt")
    multiples = None
    if dts is None:
        multiples = (
            tuple(sorted({m for _, m in runs}))
            if runs is not None
            else _positive(DEFAULT_COURANT if courant is None else courant, "--courant")
        )
    return dts, multiples


def _scenes(scene, steppers, *, ne, np_, days, overrides, restart) -> tuple[dict, object | None]:
    """``plan``'s scenes (stepper name → its resolved scene; ``DEFAULT_STEPPERS`` for
    ``steppers`` None) and the restart file's contents (``checkpoint.read``; None
    without ``restart``). Raises ValueError for a scene with ``restart`` or neither."""
    steppers = list(DEFAULT_STEPPERS if steppers is None else steppers)
    if restart is None and scene is None:
        raise ValueError("sweep needs a SCENE (or --from RESTART.nc)")
    if restart is None:
        return {s: load_scene(scene, ne=ne, np_=np_, days=days, stepper=s, overrides=overrides) for s in steppers}, None
    # every run a branch from the restart file's state (``checkpoint.branch``)
    for flag, given in (("SCENE", scene), ("--ne", ne), ("--np", np_), ("-s", overrides)):
        if given:
            raise ValueError(f"--from takes the scene and grid from the restart file: give --from or {flag}, not both")
    ck = checkpoint.read(restart)
    return {s: checkpoint.branch(ck, stepper=s, days=days) for s in steppers}, ck


def _time_filter(length: float, dts, filter_days, filter_every, filter_window) -> TimeFilter | None:
    """``plan``'s time filter (None without ``filter_days``), checked against the run's
    ``length`` (days), and the Δt values ``dts`` (s; None: multiples) checked against
    the filter's snapshot interval and ``length``: SceneError where one is not whole steps
    (``Clock.steps``)."""
    time_filter = None
    if filter_days is not None:
        time_filter = TimeFilter(filter_days, filter_every, filter_window)
        time_filter.days(length)  # the window must start within the run
        every = time_filter.every_hours / 24
        if abs(length / every - round(length / every)) > 1e-9:
            raise ValueError(
                f"the run length of {length:g} days is not a multiple of the filter's {time_filter.every_hours:g} h snapshots"
            )
    for dt in dts if time_filter is not None and dts else ():
        _check_whole(dt, time_filter.every_hours / 24, f"the filter's {time_filter.every_hours:g} h snapshot interval")
    for dt in dts or ():
        _check_whole(dt, length, "the run length")
    return time_filter
