"""The sweep's runs: for each (stepper, Δt) the scene run on one grid (``Sweep``), recorded
the time of its time loop (compilation and start-up measured apart, in a warm-up run per
stepper), RHS evaluations, solver iterations, the cost in RHS-evaluation equivalents
(``rhs_time``), stability, the total error at the last day against the truth
(``scoring.truth``; none where ``scoring.unscored`` says so), the temporal error against a
same-grid small-Δt run (RK4 at a quarter of the smallest Δt swept, made once and reused) and
the drift of the invariants; each read back from the run cache (``store``) where made with
the same settings, the others spread over a ``concurrent.futures`` executor
(``swe_sphere.core.workers``), the warm-ups first, one line logged per finished run."""

from __future__ import annotations

import dataclasses
import json
import math
import os
import signal
import time
from concurrent.futures import as_completed
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import warp as wp

from ...cases.reference import FLOORS, floor
from ...cases.scoring import instability, truth, unscored
from ...config.control import tolerance
from ...config.scene import Scene
from ...core.clock import Clock
from ...core.constants import DAY
from ...core.errors import BlowUp, Interrupted, OutputError
from ...core.workers import InProcess
from ...grid.quality import REGIONS
from ...io.output_files import atomic_path
from ...model.diagnostics import max_signal_rate
from ...simulation.checkpoint import branch_attrs
from ...simulation.simulation import Simulation
from ...steppers import STEPPERS
from .store import canonical, code_version, file_sha256, read_npz, run_key, stale, start_key, write_npz
from .verdicts import FLOOR_OF, outcome

# the small-Δt run's, against the truth: h + hs in total and by region (``quality.REGIONS``), the vorticity, the
# divergence in total and by region
SPATIAL = (
    "total_error",
    *(f"total_error_{k}" for k in REGIONS),
    "total_error_vorticity",
    "total_error_divergence",
    *(f"total_error_divergence_{k}" for k in REGIONS),
)


def dt_for_day(dt: float, run_days: float) -> float:
    """The largest Δt ≤ dt that divides a day (or ``run_days``, if shorter: the run,
    or a time filter's snapshot interval)."""
    return Clock(dt).fitted(min(1.0, run_days)).dt


def start_state(scene: Scene, directory, device: str, log=print) -> np.ndarray | None:
    """The whole-grid initial state (3, nnodes) of a scene with a digital-filter start
    (``Scene.initialization``), filtered once for a whole sweep and kept in
    ``directory/runs/start_dfi<cutoff>h<span>h.npz`` with its key (read back, and
    ``log``ged so, when it is there with the key this start would have); None
    for a scene that starts from its case's initial state."""
    f = scene.digital_filter
    if f is None:
        return None
    path = Path(directory) / "runs" / f"start_dfi{f.cutoff_hours:g}h{f.span_hours:g}h.npz"
    key = start_key(scene, device)
    kept, why = read_npz(path, key)
    if kept is not None:
        log(f"start state: reused {path} (made earlier with the same settings)")
        return kept["x"]
    if why:
        log(f"start state: made again ({path}: {why})")
    sim = Simulation(
        dataclasses.replace(scene, days=scene.dt / DAY, output_every_days=scene.dt / DAY), device, progress=False
    )
    x = np.stack(sim.fields())
    path.parent.mkdir(parents=True, exist_ok=True)
    write_npz(path, key, x=x)
    return x


def explicit_limits(scene: Scene, device: str, start: np.ndarray | None = None) -> dict:
    """The Δt at which the gravity-wave and the advective Courant numbers of the
    initial state (``start``, see ``Simulation``; None: the scene's) are 1
    (``dt_gravity``, ``dt_advective``), on the scene's grid, and
    leapfrog's measured stability limit there (``dt_leapfrog``: (|v| + sqrt(g h)) Δt/Δx
    = ``courant_limit`` of the leapfrog stepper, 0.58), to quote multiples as papers
    whose explicit reference is leapfrog do (presumably Evans, Taylor & Drake 2010)."""
    sim = Simulation(
        dataclasses.replace(scene, days=scene.start_day + scene.dt / DAY), device, progress=False, start=start
    )
    c = sim.courant()
    speed = max_signal_rate(sim.grid, *sim.fields(), sim.g)
    return {
        "dt_gravity": scene.dt / c["courant_gravity"],
        "dt_advective": scene.dt / c["courant_advective"],
        "dt_leapfrog": STEPPERS["leapfrog"].courant_limit / speed,
    }


def rhs_span(run_time: float) -> float:
    """The length (s) of ``rhs_time``'s batches for a run that took ``run_time`` s: 0.2 s, or
    a tenth of the run where that is shorter (at least 2 ms), so that timing the unit
    (2 clocks × 5 batches) never costs more than the run it describes."""
    return min(0.2, max(2e-3, run_time / 10))


def rhs_time(sim: Simulation, span: float = 0.2, rounds: int = 5, clock=time.perf_counter) -> float:
    """The time (s) on ``clock`` (wall: ``time.perf_counter``; CPU: ``time.process_time``)
    of one RHS evaluation of ``sim``'s model on its last good state,
    the median over ``rounds`` of batches of about ``span`` seconds each: the unit of a
    run's cost in RHS-evaluation equivalents (wall time / this, as
    ``benchmarks/studies/implicit_cost.py`` counts them), measured in the run's own process
    just after it, so that it shares the run's threads and, roughly, the machine's
    load. The batches last long enough to be preempted as the run was: on a loaded
    machine a single millisecond-long call often runs within one time slice, and
    its time understates the run's unit (``rhs_span`` sizes them to the run)."""
    model, x = sim.model, sim.last_good
    f = model.new_state()

    def batch(n):
        wp.synchronize_device(model.device)
        t0 = clock()
        for _ in range(n):
            model.rhs(x, f)
        wp.synchronize_device(model.device)
        return (clock() - t0) / n

    batch(1)  # records the launches (the first call of a buffer pair)
    n = max(1, math.ceil(span / max(batch(1), 1e-6)))  # the CPU clock may tick coarser than one call
    return float(np.median([batch(n) for _ in range(rounds)]))


@dataclass
class Sweep:
    """A sweep over ``scenes`` (stepper name → its resolved scene, same case and
    grid) × ``dts`` (s), results under ``directory``. With ``time_filter``
    (``timefilter.TimeFilter``) each run goes on for the filter's half window past
    the scenes' last day (the target) and is also scored by the time-filtered
    temporal error; wall time, RHS evaluations and iterations are those to the target.
    ``start``: the whole-grid state every run starts from (``start_state``: a
    digital-filter start made once), or None for the scenes' own. ``pairs``:
    the (stepper, Δt) runs to make, each Δt one of ``dts`` (None: every
    stepper × every Δt). ``overrides``: the ``-s`` settings the scenes were made
    with ({"section.key": value}), for the record (the scenes hold their effect).
    ``start_id``: what names a ``start`` the scenes do not (a sweep's member's,
    ``members.Members.key``), in every run's key; None: none.
    ``log``: called with each line to show (one per finished run). ``code``: the
    ``code_version`` every key of the sweep names, this process's at the start (the
    workers check theirs against it)."""

    scenes: dict
    dts: list
    directory: Path
    device: str
    log: object = print
    time_filter: object = None
    start: np.ndarray | None = None
    reference_dt_max: float = math.inf
    pairs: list | None = None
    overrides: dict = field(default_factory=dict)
    code: dict = field(default_factory=code_version)
    start_id: dict | None = None

    def __post_init__(self):
        self.directory = Path(self.directory)
        (self.directory / "runs").mkdir(parents=True, exist_ok=True)
        self.base = next(iter(self.scenes.values()))
        order = list(self.scenes)
        # a set: two --runs multiples that round to one Δt are one run, not two racing on its file
        self.pairs = sorted(
            set(self.pairs or [(s, dt) for s in self.scenes for dt in self.dts]),
            key=lambda p: (order.index(p[0]), p[1]),
        )
        # the small-Δt run: RK4 at a quarter of the smallest Δt, at most reference_dt_max
        self.reference_dt = dt_for_day(
            min(min(self.dts, default=math.inf) / 4, self.reference_dt_max),
            self.base.run_days if self.time_filter is None else self.time_filter.every_hours / 24,
        )
        self.reference_scene = dataclasses.replace(
            self.base, stepper="rk4", stepper_options={}, dt=self.reference_dt, control=None
        )
        reference = self.base.reference_file
        # what the runs are scored against: in every key (a reference file's contents by their hash)
        self.scored_against = {
            "name": truth(self.base.make_case(), reference),
            "sha256": file_sha256(reference) if reference is not None and reference.is_file() else None,
        }

    def key(self, scene: Scene, **more) -> dict:
        """What makes a run of ``scene`` in this sweep (``store.run_key``: scored against
        ``scored_against``, with the sweep's time filter, device and ``code``), with ``more``
        (a swept run: the small-Δt run's Δt, which its temporal errors are against)."""
        start = {} if self.start_id is None else {"start": self.start_id}  # an ensemble member's start
        return run_key(
            scene,
            truth=self.scored_against,
            device=self.device,
            code=self.code,
            time_filter=self.time_filter,
            **start,
            **more,
        )

    @property
    def tag(self) -> str:
        """File-name suffix of a filtered sweep's runs (they run longer), of a
        digital-filter start's or a branch's (``_from<restart file stem>``: they start elsewhere) and of runs scored against a
        reference file other than the case's own (``_ref<file stem>``: their total
        errors differ; files are told apart by name)."""
        f, d, ref, b = self.time_filter, self.base.digital_filter, self.base.reference_file, self.base.branch
        own = ref is None or ref.name == self.base.make_case().reference_file
        start = f"_dfi{d.cutoff_hours:g}h{d.span_hours:g}h" if d is not None else ""
        if b is not None:  # runs branched from a restart file start from its state, not the case's
            start = f"_from{Path(b['restart']).name.removesuffix('.nc').removesuffix('.restart')}"
        return (
            ("" if f is None else f"_lp{f.period_days:g}d{f.half_window_days:g}d{f.every_hours:g}h")
            + start
            + ("" if own else f"_ref{ref.stem}")
        )

    def simulate(self, scene):
        """Run ``scene`` (beyond its last day by the filter's half window, when
        filtering). Returns (simulation, RunResult, counters at the target day
        (its history entry), state at the target, filtered state or None); a blow-up
        gives its partial result and None states. The counters carry ``cpu_time``
        (``Simulation``'s: the process's CPU time in the time loop, its threads
        summed) and ``load_average``: the mean of the 1-minute load average at the
        run's start and at the target (at the end of a blow-up). An output is known by
        its step, or under step control (``Scene.control``) by its second from the start
        (the steps land on the output times)."""
        f, target, start = self.time_filter, scene.days, scene.start_day
        # an output's mark from its days from the start: its step (the clock's rounding), its second under control
        mark_of = (lambda days: round(days * DAY)) if scene.control else scene.clock.steps_in
        weights = {}
        if f is not None:  # outputs count from the scene's start (t = 0, or a branch's day)
            weights = {mark_of(d - start): w for d, w in zip(f.days(target), f.weights)}
            scene = dataclasses.replace(scene, days=target + f.half_window_days, output_every_days=f.every_hours / 24)
        sim = Simulation(scene, self.device, progress=False, start=self.start)
        mark = mark_of(target - start)
        kept = {"x": None, "filtered": 0.0, "seen": 0}
        load0 = os.getloadavg()[0]

        def clocks():
            return {"load_average": (load0 + os.getloadavg()[0]) / 2}

        def at(step, day):  # an output's mark
            return round((day - start) * DAY) if scene.control else step

        def on_output(step, x):
            now = at(step, sim.time)
            if now == mark:
                kept["x"] = x.numpy().copy()
                kept["clocks"] = clocks()
            if now in weights:
                kept["filtered"] = kept["filtered"] + weights[now] * x.numpy()
                kept["seen"] += 1

        try:
            result = sim.run(None, on_output=on_output)
        except BlowUp as err:
            return sim, err.result, {**err.result.history[-1], **clocks()}, None, None
        at_target = {**next(h for h in result.history if at(h["steps"], h["day"]) == mark), **kept["clocks"]}
        filtered = kept["filtered"] if f is not None and kept["seen"] == len(weights) else None
        return sim, result, at_target, kept["x"], filtered

    # -- reference ----------------------------------------------------------------
    def reference_path(self) -> Path:
        return self.directory / "runs" / f"reference_rk4_{self.reference_dt:.6g}{self.tag}.npz"

    def reference(self) -> dict:
        """The small-Δt run (RK4 at ``reference_dt``): final state ``x``, time-filtered
        state ``filtered`` (or None), ``dt`` and spatial errors (``SPATIAL``); read
        back from its file where that holds the run's key, else made (and written);
        ``log``ged either way."""
        scene, path = self.reference_scene, self.reference_path()
        key = self.key(scene)
        kept, why = read_npz(path, key)
        what = f"reference run: rk4, dt = {self.reference_dt:.6g} s"
        if kept is not None:
            self.log(f"{what}: reused {path.name} (made earlier with the same settings)")
            return self._reference(kept)
        self.log(what + (f" (made again: {path.name} had {why})" if why else ""))
        sim, result, _, x, filtered = self.simulate(scene)
        if x is None:
            raise BlowUp(f"the reference run (rk4, dt = {self.reference_dt:.6g} s) failed: {result.blowup}")
        errors = sim.scorer.total_errors(self.base.days * DAY, x)
        write_npz(path, key, x=x, **errors, **({} if filtered is None else {"filtered": filtered}))
        return self._reference({"x": x, "filtered": filtered, **errors})

    def _reference(self, arrays: dict) -> dict:
        return {
            "dt": self.reference_dt,
            "x": arrays["x"],
            "filtered": arrays.get("filtered"),
            **{k: float(arrays[k]) if k in arrays else math.nan for k in SPATIAL},
        }

    # -- one run ------------------------------------------------------------------
    def run_path(self, stepper: str, dt: float) -> Path:
        return self.directory / "runs" / f"{stepper}_{dt:.6g}{self.tag}.json"

    def label(self, stepper: str, dt: float) -> str:
        """A run in the log: "rk4 dt = 600 s", "bs32@rtol=1e-05 first dt = 600 s" (steps chosen step to step)."""
        return f"{stepper} {'first ' if self.scenes[stepper].control else ''}dt = {dt:.6g} s"

    def run_key(self, stepper: str, dt: float) -> dict:
        return self.key(dataclasses.replace(self.scenes[stepper], dt=dt), reference_dt=self.reference_dt)

    def stored_run(self, stepper: str, dt: float) -> tuple[dict | None, str | None]:
        """(row, None) when the run's file holds its key; (None, why not) when the
        file holds another run; (None, None) when there is none."""
        path = self.run_path(stepper, dt)
        if not path.exists():
            return None, None
        data = json.loads(path.read_text())
        why = stale(data.get("key"), self.run_key(stepper, dt))  # a file without a key: a row of an earlier version
        return (None, why) if why else (data["row"], None)

    def run_one(self, stepper: str, dt: float, startup_time: float) -> dict:
        """Make one (stepper, Δt) run (``startup_time``: its stepper's warm-up's, s),
        write its row and key; returns the row. Raises ``OutputError`` when this process's
        source is not the sweep's (a worker started after an edit) or the reference run's
        file no longer holds its key (another process wrote into the folder): the runs
        would mix two versions, and a rerun remakes what is stale."""
        now = code_version()["source_sha256"]
        if now != self.code["source_sha256"]:
            raise OutputError(
                f"the swe_sphere source changed while the sweep ran (source_sha256 {self.code['source_sha256']} "
                f"at its start, {now} in the process of the {self.label(stepper, dt)} run): run the sweep again"
            )
        path = self.reference_path()
        ref, why = read_npz(path, self.key(self.reference_scene))
        if ref is None:
            raise OutputError(
                f"{path}: the sweep's reference run was {'replaced (' + why + ')' if why else 'removed'} while the "
                f"sweep ran, by another process writing into {self.directory}: run the sweep again"
            )
        ref = self._reference(ref)
        scene = dataclasses.replace(self.scenes[stepper], dt=dt)
        sim, result, at, x, filtered = self.simulate(scene)
        row = {"stepper": stepper, "dt": dt, "setup_time": sim.setup_time, "startup_time": startup_time}
        if scene.control is not None:  # known by its stepper and key ("bs32@rtol"), Δt its mean
            key, row["tolerance"] = tolerance(scene.control)
            row.update(stepper=f"{scene.stepper}@{key}", rejected_steps=at["rejected_steps"])
            row["dt"] = (at["day"] - scene.start_day) * DAY / max(at["steps"], 1)
        reason = instability(result)
        stable = not reason
        row.update(
            stable=stable,
            reason=reason,
            wall_time=at["wall_time"],
            cpu_time=at["cpu_time"],
            load_average=at["load_average"],
            threads=sim.model.threads,
            steps=at["steps"],
            rhs_evals=at["rhs_evals"],
            rhs_time=rhs_time(sim, rhs_span(at["wall_time"])),
            rhs_cpu_time=rhs_time(sim, rhs_span(at["cpu_time"]), clock=time.process_time),
        )
        row.update({f"{k}_iterations": at[f"{k}_iterations"] for k in result.iterations})
        final = result.history[-1]
        for k in ("mass_change", "total_energy_change", "potential_enstrophy_change"):
            row[k] = final.get(k, math.nan)
        if stable:
            row.update(sim.scorer.total_errors(self.base.days * DAY, x))
            row.update(sim.scorer.temporal_errors(x, ref["x"]))
            if self.time_filter is not None:
                row.update(sim.scorer.filtered_errors(filtered, ref["filtered"]))
        with atomic_path(self.run_path(stepper, dt)) as tmp:
            tmp.write_text(json.dumps({"key": self.run_key(stepper, dt), "row": row}))
        return row

    def warm_up(self, stepper: str) -> float:
        """Compile and load every kernel a stepper uses (a two-step run); returns its time."""
        t0 = time.perf_counter()
        dt = self.scenes[stepper].dt if self.scenes[stepper].control else min(self.dts)
        span = 2 * dt / DAY
        scene = dataclasses.replace(
            self.scenes[stepper], dt=dt, days=self.base.start_day + span, output_every_days=span
        )
        try:
            Simulation(scene, self.device, progress=False, start=self.start).run(None)
        except BlowUp:  # unstable at this Δt (its own run will record it); every kernel has run once
            pass
        return time.perf_counter() - t0

    def run(self, pool=None) -> tuple[list[dict], dict]:
        """All runs, on ``pool`` (a concurrent.futures executor; None: here, one
        after another), each read back where its file holds its key (``stored_run``)
        or made; ``log``s one line per run as it is read back or finishes, then how
        many were reused. Returns the rows in (stepper, Δt) order and the sweep's
        summary (``record``, and ``unscored``: why there is no total or
        spatial error, when the truth cannot score the last day; ``reference``:
        what the runs are scored against, ``scoring.truth``; ``reference_dt``; with
        a reference file, ``reference_floor``, ``_vorticity``, ``_divergence``: its
        own error at the last day, NaN where unknown, and ``reference_floor_source``
        where known, e.g. "T213 vs T341, day 15"). SIGINT or SIGTERM (``Interrupted``
        or ``KeyboardInterrupt``) ends it with ``Interrupted`` saying what is kept."""
        case, reference = self.base.make_case(), self.base.reference_file
        why = unscored(case, self.base.days, reference)
        if why is not None:
            self.log(f"note: no total or spatial error at the end, so no verdicts: {why}")
        rows, ref = self._runs(pool or InProcess())
        return [rows[pair] for pair in self.pairs], self._info(ref, case, why)

    def _runs(self, pool) -> tuple[dict, dict]:
        """``run``'s runs on ``pool``: ((stepper, Δt) → row, the reference run)."""
        rows, made, warm_ups, ref, n = {}, {}, {}, None, len(self.pairs)

        def report(future):  # a made run's line, once it has finished
            stepper, dt, replaced = made.pop(future)
            rows[stepper, dt] = row = future.result()  # a run's error is raised here
            self.log(
                f"[{len(rows)}/{n}] {self.label(stepper, dt)}: {outcome(row)}"
                + (f"; replaces a run with {replaced}" if replaced else "")
            )

        try:
            ref = self.reference()
            todo = self._stored(rows)
            reused = len(rows)
            warm_ups = {pool.submit(self.warm_up, stepper): stepper for stepper in dict.fromkeys(s for s, _ in todo)}
            # every kernel compiled before a timed run starts
            startups = {stepper: future.result() for future, stepper in warm_ups.items()}
            for (stepper, dt), replaced in todo.items():
                future = pool.submit(self.run_one, stepper, dt, startups[stepper])
                made[future] = stepper, dt, replaced
                if future.done():  # made here and now (``InProcess``): said at once
                    report(future)
            for future in as_completed(list(made)):
                report(future)
        except (KeyboardInterrupt, Interrupted) as err:
            for future in [*warm_ups, *made]:
                future.cancel()
            raise self._interrupted(err, ref is not None, len(rows)) from None
        self.log(f"runs: {reused} reused, {n - reused} made (in {self.directory / 'runs'})")
        return rows, ref

    def _stored(self, rows: dict) -> dict:
        """Put the runs read back (``stored_run``) into ``rows``, ``log``ging each; returns
        the others: (stepper, Δt) → what its file held instead, if anything."""
        todo = {}
        for stepper, dt in self.pairs:
            row, replaced = self.stored_run(stepper, dt)
            if row is None:
                todo[stepper, dt] = replaced
                continue
            rows[stepper, dt] = row
            self.log(
                f"[{len(rows)}/{len(self.pairs)}] {self.label(stepper, dt)}: reused (made earlier with the same settings)"
            )
        return todo

    def _info(self, ref: dict, case, why: str | None) -> dict:
        """``run``'s summary of the sweep: ``record``, the reference run's spatial errors
        (``ref``), the reference file's floors (``case``: the scenes' case), the start the
        runs share and ``unscored`` (``why``, where not None)."""
        reference = self.base.reference_file
        d, b = (
            self.base.digital_filter,
            self.base.branch,
        )  # in the sweep's netCDF attributes: which start the runs share
        floors = {}
        if not case.exact_solution and reference is not None:
            own = floor(reference, self.base.days)
            floors = dict(zip(FLOOR_OF.values(), own or (math.nan,) * 3))
            if own is not None:
                floors["reference_floor_source"] = f"{FLOORS[reference.name][0]}, day {self.base.days:g}"
        return {
            **self.record(),
            "spatial_error": ref["total_error"],
            "spatial_error_vorticity": ref["total_error_vorticity"],
            "spatial_error_divergence": ref["total_error_divergence"],
            **{f"spatial_error_{k}": ref[f"total_error_{k}"] for k in REGIONS},
            **{f"spatial_error_divergence_{k}": ref[f"total_error_divergence_{k}"] for k in REGIONS},
            "reference_dt": ref["dt"],
            **floors,
            **(
                {}
                if d is None or b is not None
                else {"dfi_cutoff_hours": d.cutoff_hours, "dfi_span_hours": d.span_hours}
            ),
            **branch_attrs(self.base),
            **({} if why is None else {"unscored": why}),
        }

    def record(self) -> dict:
        """What the sweep is made with, for sweep.csv's columns and sweep.nc's
        attributes: ``scene`` (its name), ``case``, ``ne``, ``np``, ``days``,
        ``overrides`` ("section.key=value; ..."; "" for none), ``stepper_options``
        (JSON, stepper → its options), ``reference`` (``scoring.truth``),
        ``time_filter`` (JSON of its settings; "" for none), ``device``,
        ``swe_sphere_version`` and ``source_sha256`` (``code_version``)."""
        b, f, code = self.base, self.time_filter, self.code
        return {
            "scene": b.name,
            "case": b.case,
            "ne": b.ne,
            "np": b.np,
            "days": b.days,
            "overrides": "; ".join(f"{k}={canonical(v)}" for k, v in self.overrides.items()),
            "stepper_options": canonical({s: scene.stepper_options for s, scene in self.scenes.items()}),
            "reference": self.scored_against["name"],
            "time_filter": "" if f is None else canonical(dataclasses.asdict(f)),
            "device": self.device,
            "swe_sphere_version": code["version"],
            "source_sha256": code["source_sha256"],
        }

    def _interrupted(self, err: BaseException, reference_made: bool, kept: int) -> Interrupted:
        """The ``Interrupted`` that ends a sweep stopped by ``err`` (a signal), saying what is kept."""
        signum = getattr(err, "signum", signal.SIGINT)
        head, where = f"interrupted by {signal.Signals(signum).name}", self.directory / "runs"
        if not reference_made:
            at = (
                f" at model day {self.base.start_day + err.result.steps * self.reference_dt / DAY:.4g}"
                if isinstance(err, Interrupted)
                else ""
            )
            text = (
                f"{head} in the sweep's reference run (rk4, dt = {self.reference_dt:.6g} s){at}, which is not kept (a rerun "
                f"of the same command makes it again); the runs already in {where} are kept"
            )
        else:
            text = (
                f"{head}: the reference run and {kept} of {len(self.pairs)} runs are kept in {where}; a rerun of the same "
                f"command reuses them and makes the other {len(self.pairs) - kept}"
            )
        out = Interrupted(text)
        out.signum = signum
        return out
