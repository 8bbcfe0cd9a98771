"""Step-size efficiency sweeps: error against Δt against wall time, per stepper.

``plan(scene, ...)`` turns a scene and the options of `swe-sphere sweep` into a ``Plan``
(the steppers' scenes, Δt values or multiples of the gravity-wave limit, the time
filter); ``Plan.run`` is what the command runs (``Plan.resolve``: the Δt values and
notes alone). Below it, ``Sweep`` makes the runs.

For each (stepper, Δt) the scene is run on one grid; recorded are the wall
time of the time loop (compilation and start-up measured apart, in a warm-up
run per stepper), RHS evaluations, solver iterations, the cost in RHS-evaluation
equivalents (the wall time over the time of one RHS evaluation measured in the
run's process just after it), stability, the total
error at the final time (against the exact solution where the case has one:
TC1–TC4, Läuter; else the spectral reference, the case's T213 file or the
scene's ``case.reference``; none, NaN, at a final day the reference does not
store: ``scoring.unscored`` says why) and the temporal error (against a same-grid run with a small Δt:
RK4 at a quarter of the smallest Δt swept, at most a quarter of the
gravity-wave limit, made once and reused), and the
drift of the invariants. Each run's result is written atomically as JSON
under ``DIR/runs/`` with its key: everything that makes the run (``Sweep.key``:
the resolved scene — case, grid, days, Δt, stepper and its options, overrides
applied —, the reference file's name and SHA-256, the time filter, the device
and ``code_version``; a run's key also names the small-Δt run its temporal error
is against). A rerun reuses a run, the small-Δt run and a digital-filter start
only where the stored key is the one it would make, says so, and makes the
others again, saying what changed. The runs are independent: ``Sweep.run(pool)``
spreads them over a ``concurrent.futures`` executor (``swe_sphere.core.workers``),
the warm-ups first, and logs one line per finished run.

"Sufficient accuracy" (Evans, Taylor & Drake 2010): temporal error ≤ 10 % of
the spatial error, the spatial error being the small-Δt run's total error.
Beside each spatial error the summary quotes the reference's own error, its
floor (``reference.floor``); a spatial error within ``FLOOR_MARGIN`` of it is
flagged: the reference cannot tell it from its own, so its verdicts are provisional.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
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

from ..cases.reference import FLOORS, floor
from ..cases.scoring import instability, truth, unscored
from ..config.scene import Scene, load_scene
from ..core.backend import pick_device
from ..core.constants import DAY
from ..core.errors import BlowUp, Interrupted, OutputError
from ..core.runtime import package_version
from ..core.workers import InProcess
from ..grid.quality import REGIONS
from ..io.run_file import atomic_path, check_results, command_line, folder_lock, history_line
from ..io.table_file import table_dataset, write_table_file
from ..model.diagnostics import max_signal_rate
from ..simulation import checkpoint
from ..simulation.checkpoint import branch_attrs
from ..simulation.simulation import Simulation
from ..steppers import STEPPERS
from ..steppers.timefilter import TimeFilter
from .plotting import sweep_plot

SUFFICIENT = 0.1  # temporal error ≤ 10 % of the spatial error
# The reference RK4 run's Δt is at most this multiple of the gravity-wave limit, also
# when every swept Δt is large: RK4 is stable to ≈ 1.7 and its time error there is nil
REFERENCE_MAX_GRAVITY_COURANT = 0.25
# the small-Δt run's, against the truth: h + hs in total and by region (``quality.REGIONS``), the vorticity, the
# divergence in total and by region
SPATIAL = (
    "total_error",
    *(f"total_error_{k}" for k in REGIONS),
    "total_error_vorticity",
    "total_error_divergence",
    *(f"total_error_divergence_{k}" for k in REGIONS),
)
# the sweep info's spatial errors → the keys of the reference's own errors beside them
FLOOR_OF = {
    "spatial_error": "reference_floor",
    "spatial_error_vorticity": "reference_floor_vorticity",
    "spatial_error_divergence": "reference_floor_divergence",
}
FLOOR_MARGIN = 2.0  # a spatial error within this factor of the reference's own error is not the run's alone


def dt_for_day(dt: float, run_days: float) -> float:
    """The largest Δt ≤ dt that divides a day (or ``run_days``, if shorter: the run,
    or a time filter's snapshot interval)."""
    span = min(1.0, run_days) * DAY
    return span / math.ceil(span / dt - 1e-9)


@functools.cache
def code_version() -> dict:
    """This installation's ``version`` and ``source_sha256``: the SHA-256 (16 hex
    digits) of the ``swe_sphere`` and ``swe_sphere.kernels`` packages' Python
    source, subpackages (``steppers``) included. A sweep reuses a run only when both
    are those it was made with: which edits change no number, only a person can tell."""
    digest = hashlib.sha256()
    for package in ("swe_sphere", "swe_sphere.kernels"):
        root = Path(importlib.util.find_spec(package).origin).parent
        for path in sorted(root.rglob("*.py")):  # subpackages too: the steppers
            digest.update(f"{package}/{path.relative_to(root).as_posix()}\0".encode())
            digest.update(path.read_bytes())
    return {"version": package_version(), "source_sha256": digest.hexdigest()[:16]}


def _canonical(value) -> str:
    """``value`` as JSON with sorted keys (tuples as lists): keys compare as these strings."""
    return json.dumps(value, sort_keys=True, default=str)


def changes(old, new, prefix: str = "") -> list[str]:
    """Where the key ``old`` (as stored) differs from ``new``, one item per setting,
    e.g. "scene.days 2.0 (now 1.0)"."""
    if isinstance(old, dict) and isinstance(new, dict):
        return [c for k in sorted(set(old) | set(new)) for c in changes(old.get(k), new.get(k), f"{prefix}{k}.")]
    return (
        []
        if _canonical(old) == _canonical(new)
        else [f"{prefix.rstrip('.')} {_canonical(old)} (now {_canonical(new)})"]
    )


def stale(stored: dict | None, key: dict) -> str | None:
    """Why a file whose key is ``stored`` (None: a file without one) cannot stand
    for one made with ``key``, in a few words; None when it can."""
    if stored is None:
        return "made by an earlier swe_sphere that did not record its settings"
    diff = changes(stored, key)
    if not diff:
        return None
    return "other settings: " + ", ".join(diff[:3]) + (f" and {len(diff) - 3} more" if len(diff) > 3 else "")


def _read_npz(path: Path, key: dict) -> tuple[dict | None, str | None]:
    """(arrays, None) of the .npz ``path`` made with ``key``; (None, why not) for a
    file made otherwise; (None, None) when there is none."""
    if not path.exists():
        return None, None
    with np.load(path) as data:
        arrays = {k: data[k] for k in data.files}
    why = stale(json.loads(str(arrays.pop("key"))) if "key" in arrays else None, key)
    return (None, why) if why else (arrays, None)


def _file_sha256(path: Path) -> str:
    with open(path, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def _write_npz(path: Path, key: dict, **arrays) -> None:
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as out:
            np.savez(out, key=np.array(_canonical(key)), **arrays)


PROSE = (
    "description",
    "notes",
    "log_every_steps",
)  # scene values that describe or report a run, not make it: in no key
# Scene values a digital-filter start does not depend on either (``initialization.digital_filter``
# leaves ∇⁴ out and takes its own steps): a sweep with another of them shares the start
NOT_IN_START = (
    *PROSE,
    "name",
    "days",
    "dt",
    "stepper",
    "stepper_options",
    "output_every_days",
    "reference",
    "nu",
    "nu_div",
    "nu_s",
    "hypervis_subcycle",
)


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
    key = json.loads(
        _canonical(
            {
                "scene": {k: v for k, v in scene.as_dict().items() if k not in NOT_IN_START},
                "device": device,
                "code": code_version(),
            }
        )
    )
    kept, why = _read_npz(path, key)
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
    _write_npz(path, key, x=x)
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


def rhs_time(sim: Simulation, span: float = 0.2, rounds: int = 5, clock=time.perf_counter) -> float:
    """The time (s) on ``clock`` (wall: ``time.perf_counter``; CPU: ``time.process_time``)
    of one RHS evaluation of ``sim``'s model on its last good state,
    the median over ``rounds`` of batches of about ``span`` seconds each: the unit of a
    run's cost in RHS-evaluation equivalents (wall time / this, as
    ``benchmarks/implicit_cost.py`` counts them), measured in the run's own process
    just after it, so that it shares the run's threads and, roughly, the machine's
    load. The batches last long enough to be preempted as the run was: on a loaded
    machine a single millisecond-long call often runs within one time slice, and
    its time understates the run's unit."""
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
            min(min(self.dts) / 4, self.reference_dt_max),
            self.base.run_days if self.time_filter is None else self.time_filter.every_hours / 24,
        )
        self.reference_scene = dataclasses.replace(self.base, stepper="rk4", stepper_options={}, dt=self.reference_dt)
        reference = self.base.reference_file
        # what the runs are scored against: in every key (a reference file's contents by their hash)
        self.scored_against = {
            "name": truth(self.base.make_case(), reference),
            "sha256": _file_sha256(reference) if reference is not None and reference.is_file() else None,
        }

    def key(self, scene: Scene, **more) -> dict:
        """What makes a run of ``scene`` (as stored in its file): the resolved scene
        (case, grid, days, Δt, stepper and its options, the overrides applied,
        the reference's path; not its ``PROSE``), what it is scored against
        (``truth``: the reference file's name and SHA-256), the time filter, the device,
        ``code_version`` and ``more`` (a swept run: the small-Δt run's Δt, which
        its temporal errors are against)."""
        f = self.time_filter
        scene = {k: v for k, v in scene.as_dict().items() if k not in PROSE}
        return json.loads(
            _canonical(
                {
                    "scene": scene,
                    "truth": self.scored_against,
                    "device": self.device,
                    "code": self.code,
                    "time_filter": None if f is None else dataclasses.asdict(f),
                    **more,
                }
            )
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
        run's start and at the target (at the end of a blow-up)."""
        f, target = self.time_filter, scene.days
        n_target = scene.nsteps
        weights = {}
        if f is not None:  # steps count from the scene's start (t = 0, or a branch's day)
            weights = {round((d - scene.start_day) * DAY / scene.dt): w for d, w in zip(f.days(target), f.weights)}
            scene = dataclasses.replace(scene, days=target + f.half_window_days, output_every_days=f.every_hours / 24)
        kept = {"x": None, "filtered": 0.0, "seen": 0}
        load0 = os.getloadavg()[0]

        def clocks():
            return {"load_average": (load0 + os.getloadavg()[0]) / 2}

        def on_output(step, x):
            if step == n_target:
                kept["x"] = x.numpy().copy()
                kept["clocks"] = clocks()
            if step in weights:
                kept["filtered"] = kept["filtered"] + weights[step] * x.numpy()
                kept["seen"] += 1

        sim = Simulation(scene, self.device, progress=False, start=self.start)
        try:
            result = sim.run(None, on_output=on_output)
        except BlowUp as err:
            return sim, err.result, {**err.result.history[-1], **clocks()}, None, None
        at_target = {**next(h for h in result.history if h["steps"] == n_target), **kept["clocks"]}
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
        kept, why = _read_npz(path, key)
        what = f"reference run: rk4, dt = {self.reference_dt:.6g} s"
        if kept is not None:
            self.log(f"{what}: reused {path.name} (made earlier with the same settings)")
            return self._reference(kept)
        self.log(what + (f" (made again: {path.name} had {why})" if why else ""))
        sim, result, _, x, filtered = self.simulate(scene)
        if x is None:
            raise BlowUp(f"the reference run (rk4, dt = {self.reference_dt:.6g} s) failed: {result.blowup}")
        errors = sim.scorer.total_errors(self.base.days * DAY, x)
        _write_npz(path, key, x=x, **errors, **({} if filtered is None else {"filtered": filtered}))
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
                f"at its start, {now} in the process of the {stepper} dt = {dt:.6g} s run): run the sweep again"
            )
        path = self.reference_path()
        ref, why = _read_npz(path, self.key(self.reference_scene))
        if ref is None:
            raise OutputError(
                f"{path}: the sweep's reference run was {'replaced (' + why + ')' if why else 'removed'} while the "
                f"sweep ran, by another process writing into {self.directory}: run the sweep again"
            )
        ref = self._reference(ref)
        scene = dataclasses.replace(self.scenes[stepper], dt=dt)
        sim, result, at, x, filtered = self.simulate(scene)
        row = {"stepper": stepper, "dt": dt, "setup_time": sim.setup_time, "startup_time": startup_time}
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
            rhs_time=rhs_time(sim),
            rhs_cpu_time=rhs_time(sim, clock=time.process_time),
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
        dt = min(self.dts)
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
        pool = pool or InProcess()
        case, reference = self.base.make_case(), self.base.reference_file
        why = unscored(case, self.base.days, reference)
        if why is not None:
            self.log(f"note: no total or spatial error at the end, so no verdicts: {why}")
        rows, made, warm_ups, ref, n = {}, {}, {}, None, len(self.pairs)

        def report(future):  # a made run's line, once it has finished
            stepper, dt, replaced = made.pop(future)
            rows[stepper, dt] = row = future.result()  # a run's error is raised here
            self.log(
                f"[{len(rows)}/{n}] {stepper} dt = {dt:.6g} s: {outcome(row)}"
                + (f"; replaces a run with {replaced}" if replaced else "")
            )

        try:
            ref = self.reference()
            todo = {}  # (stepper, Δt) → what its file held instead, if anything
            for stepper, dt in self.pairs:
                row, replaced = self.stored_run(stepper, dt)
                if row is None:
                    todo[stepper, dt] = replaced
                    continue
                rows[stepper, dt] = row
                self.log(f"[{len(rows)}/{n}] {stepper} dt = {dt:.6g} s: reused (made earlier with the same settings)")
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
        return [rows[pair] for pair in self.pairs], {
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
            "overrides": "; ".join(f"{k}={_canonical(v)}" for k, v in self.overrides.items()),
            "stepper_options": _canonical({s: scene.stepper_options for s, scene in self.scenes.items()}),
            "reference": self.scored_against["name"],
            "time_filter": "" if f is None else _canonical(dataclasses.asdict(f)),
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


def outcome(row: dict) -> str:
    """A finished run in a few words: its errors and CPU time, or why it is unstable."""
    if not row["stable"]:
        return f"unstable ({row['reason']}); CPU {row['cpu_time']:.3g} s"
    errors = [
        f"{k.replace('_', ' ')} {row[k]:.3e}"
        for k in ("total_error", "temporal_error")
        if math.isfinite(row.get(k, math.nan))
    ]
    return ", ".join(errors) + f"; CPU {row['cpu_time']:.3g} s"


# sweep.csv's columns, in order, and sweep.nc's variables: (units, long_name) each (units None: a string)
_ERR = "normalized l2 error (Williamson et al. 1992) at the last day"
COLUMN_ATTRS = {
    "stepper": (None, "time stepper"),
    "dt": ("s", "time step"),
    "dt_over_gravity_limit": ("1", "time step over the gravity-wave limit (Courant number 1)"),
    "dt_over_advective_limit": ("1", "time step over the advective limit"),
    "dt_over_leapfrog_limit": ("1", "time step over leapfrog's limit 0.58 (|v| + c) dt / dx = 1"),
    "stable": ("1", "1 if the run reached its last day without blowing up, else 0"),
    "wall_time": ("s", "wall time of the time loop to the target day"),
    "cpu_time": ("s", "process CPU time to the target day, all threads summed"),
    "load_average": ("1", "mean 1-minute load average at the run's start and target day"),
    "threads": ("1", "compute threads"),
    "cost_time": ("s", "the run's time on the clock the sweep ranks by (--cost)"),
    "startup_time": ("s", "time of the stepper's warm-up run (compilation)"),
    "setup_time": ("s", "time to build the simulation"),
    "steps": ("1", "time steps taken"),
    "rhs_evals": ("1", "right-hand-side evaluations"),
    "rhs_time": ("s", "wall time of one right-hand-side evaluation"),
    "rhs_cpu_time": ("s", "CPU time of one right-hand-side evaluation"),
    "rhs_equivalents": ("1", "cost_time over the time of one right-hand-side evaluation on the same clock"),
    **{
        f"{k}_iterations": ("1", f"cumulative {what}")
        for k, what in (
            ("newton", "Newton iterations"),
            ("gmres", "GMRES iterations"),
            ("precond", "applications of the JFNK preconditioner"),
            ("helmholtz", "Helmholtz-solve iterations"),
            ("krylov", "Krylov vectors of KIOPS"),
            ("substeps", "accepted KIOPS substeps"),
            ("rejected", "rejected KIOPS substeps"),
            ("fast", "fast (gravity-wave) evaluations of the multirate substeps"),
        )
    },
    "total_error": ("1", f"{_ERR} of h + hs against the truth"),
    **{
        f"total_error_{k}": ("1", f"{_ERR} of h + hs against the truth over the {k} region's elements") for k in REGIONS
    },
    "total_error_vorticity": ("1", f"{_ERR} of vorticity against the truth"),
    "total_error_divergence": ("1", f"{_ERR} of divergence against the truth"),
    **{
        f"total_error_divergence_{k}": ("1", f"{_ERR} of divergence against the truth over the {k} region's elements")
        for k in REGIONS
    },
    "temporal_error": ("1", f"{_ERR} of h + hs against the small-dt run"),
    **{
        f"temporal_error_{k}": ("1", f"{_ERR} of h + hs against the small-dt run over the {k} region's elements")
        for k in REGIONS
    },
    "temporal_error_wind": ("1", f"{_ERR} of the wind against the small-dt run"),
    "temporal_error_vorticity": ("1", f"{_ERR} of vorticity against the small-dt run"),
    "temporal_error_divergence": ("1", f"{_ERR} of divergence against the small-dt run"),
    **{
        f"temporal_error_divergence_{k}": (
            "1",
            f"{_ERR} of divergence against the small-dt run over the {k} region's elements",
        )
        for k in REGIONS
    },
    "temporal_error_filtered": ("1", f"{_ERR} of time-filtered h + hs against the small-dt run"),
    "temporal_error_filtered_vorticity": ("1", f"{_ERR} of time-filtered vorticity against the small-dt run"),
    "mass_change": ("1", "relative change of mass at the last day"),
    "total_energy_change": ("1", "relative change of total energy at the last day"),
    "potential_enstrophy_change": ("1", "relative change of potential enstrophy at the last day"),
    "reason": (None, "why the run is unstable (empty if stable)"),
}
COLUMNS = tuple(COLUMN_ATTRS)


COSTS = {"cpu": ("cpu_time", "rhs_cpu_time"), "wall": ("wall_time", "rhs_time")}  # --cost: (run's time, its RHS's time)


def table(rows, limits, cost: str = "cpu") -> list[dict]:
    """Rows with every column (NaN where not applicable), Δt as multiples of the
    limits, ``cost_time``: the run's time on the clock ``cost`` ranks by ("cpu":
    the process's CPU time, which a loaded machine barely changes with one compute
    and one BLAS thread; "wall"), and the cost in RHS-evaluation equivalents on
    that clock (``cost_time`` / one RHS timed on it: everything a step does — RHS
    evaluations, ∇⁴, Helmholtz and Krylov work — in units of the one operation
    every stepper shares; NaN for a run made before runs timed it).
    Raises ValueError for an unknown ``cost``."""
    if cost not in COSTS:
        raise ValueError(f"unknown cost clock {cost!r} (known: {', '.join(COSTS)})")
    run_time, unit_time = COSTS[cost]
    out = []
    for r in rows:
        row = {c: r.get(c, math.nan) for c in COLUMNS}
        row["cost_time"] = row[run_time]
        row["rhs_equivalents"] = row[run_time] / row[unit_time]
        row["dt_over_gravity_limit"] = r["dt"] / limits["dt_gravity"]
        row["dt_over_advective_limit"] = r["dt"] / limits["dt_advective"]
        row["dt_over_leapfrog_limit"] = r["dt"] / limits["dt_leapfrog"]
        out.append(row)
    return out


# criterion: (temporal-error column, spatial-error key of the sweep's info)
CRITERIA = {
    "total h+hs": ("temporal_error", "spatial_error"),
    "balanced flow (vorticity)": ("temporal_error_vorticity", "spatial_error_vorticity"),
    "balanced flow (filtered h+hs)": ("temporal_error_filtered", "spatial_error"),
    # the time filter also removes the waves' own vorticity (geostrophic adjustment),
    # and unlike filtered h+hs it barely feels the filter's leakage of the longest waves
    "balanced flow (filtered vorticity)": ("temporal_error_filtered_vorticity", "spatial_error_vorticity"),
    "gravity waves (divergence)": ("temporal_error_divergence", "spatial_error_divergence"),
}
THRESHOLDS = (0.1, 0.5)  # temporal error as a fraction of the spatial error
RUN_VERDICT_COLUMNS = (
    "dt",
    "dt_over_gravity_limit",
    "dt_over_advective_limit",
    "dt_over_leapfrog_limit",
    "cost_time",
    "wall_time",
    "cpu_time",
    "rhs_evals",
    "helmholtz_iterations",
    "rhs_equivalents",
)  # the qualifying run's
VERDICT_COLUMNS = (
    "criterion",
    "threshold",
    "stepper",
    *RUN_VERDICT_COLUMNS,
    "temporal_error",
    "spatial_error",
    "reference_floor",
)


def _cheapest(rows, stepper, column, limit):
    """The stable run of ``stepper`` with the least ``cost_time`` (``table``'s clock) whose
    ``column`` ≤ limit (None if none); a run without a time on that clock ranks last."""
    ok = [r for r in rows if r["stepper"] == stepper and r["stable"] and r.get(column, math.nan) <= limit]
    return min(ok, key=lambda r: r["cost_time"] if math.isfinite(r["cost_time"]) else math.inf, default=None)


def floor_note(info, spatial_key: str) -> str:
    """What to print beside the spatial error ``info[spatial_key]``: "" against an
    exact solution; else the reference's own error ("reference floor 1.0e-05
    (T213 vs T341, day 15)") or "floor unknown", and, for a spatial error within
    ``FLOOR_MARGIN`` of the floor, that the verdicts on it are provisional."""
    if FLOOR_OF[spatial_key] not in info:
        return ""
    known = info[FLOOR_OF[spatial_key]]
    if not math.isfinite(known):
        return "floor unknown"
    note = f"reference floor {known:.1e} ({info['reference_floor_source']})"
    if info[spatial_key] <= FLOOR_MARGIN * known:
        note += (
            f"; within {FLOOR_MARGIN:g}x of the floor: the reference cannot tell the run's spatial error from its own, "
            "so these verdicts are provisional"
        )
    return note


def verdicts(rows, info) -> list[dict]:
    """Per criterion (``CRITERIA``; the filtered one only where the sweep filtered),
    threshold (``THRESHOLDS``) and stepper: the cheapest (least ``cost_time``) stable
    run whose temporal error ≤ threshold × the spatial error of that criterion, with
    its Δt multiples, wall time, RHS evaluations and RHS-eq; dt NaN where no run
    qualifies. ``reference_floor``: the reference's own error beside the spatial
    error (``Sweep.run``'s info; NaN where unknown or against an exact solution)."""
    steppers = list(dict.fromkeys(r["stepper"] for r in rows))
    out = []
    for criterion, (column, spatial_key) in CRITERIA.items():
        spatial = info.get(spatial_key, math.nan)
        if not any(math.isfinite(r.get(column, math.nan)) for r in rows):
            continue
        for threshold in THRESHOLDS:
            for stepper in steppers:
                best = _cheapest(rows, stepper, column, threshold * spatial)
                v = {
                    "criterion": criterion,
                    "threshold": threshold,
                    "stepper": stepper,
                    "spatial_error": spatial,
                    "reference_floor": info.get(FLOOR_OF[spatial_key], math.nan),
                }
                v.update({c: math.nan for c in VERDICT_COLUMNS if c not in v})
                if best is not None:
                    v.update({c: best.get(c, math.nan) for c in RUN_VERDICT_COLUMNS}, temporal_error=best[column])
                out.append(v)
    return out


def format_verdicts(verdict_rows, info) -> str:
    """Per criterion a line with its spatial error and ``floor_note`` (``info``:
    ``Sweep.run``'s), then one line per threshold × stepper."""
    lines, criterion = [], None
    for v in verdict_rows:
        if v["criterion"] != criterion:
            criterion, note = v["criterion"], floor_note(info, CRITERIA[v["criterion"]][1])
            lines.append(f"  {criterion}: spatial error {v['spatial_error']:.3e}" + (f", {note}" if note else ""))
        head = f"    {v['criterion']:30s} <= {v['threshold']:3.0%} {v['stepper']:22s}"
        if not math.isfinite(v["dt"]):
            lines.append(f"{head} no run qualifies")
            continue
        lines.append(
            f"{head} dt = {v['dt']:.4g} s = {v['dt_over_gravity_limit']:.2f} x gravity-wave, {v['dt_over_advective_limit']:.2f} x "
            f"advective, {v['dt_over_leapfrog_limit']:.2f} x leapfrog limit; CPU {v['cpu_time']:.3g} s, wall {v['wall_time']:.3g} s, "
            f"{v['rhs_equivalents']:.0f} RHS-eq ({v['rhs_evals']:.0f} RHS)"
        )
    return "\n".join(lines)


def cheapest_sufficient(rows, spatial_error) -> dict:
    """Per stepper, the cheapest (``cost_time``) stable run whose temporal error ≤ 10 % of the spatial error."""
    best = {
        s: _cheapest(rows, s, "temporal_error", SUFFICIENT * spatial_error)
        for s in dict.fromkeys(r["stepper"] for r in rows)
    }
    return {s: r for s, r in best.items() if r is not None}


def format_summary(rows, info) -> str:
    """The table and, per stepper, the cheapest sufficiently accurate run and the
    verdicts (none where ``info`` says the run length is ``unscored``)."""
    head = (
        f"{'stepper':22s} {'dt [s]':>9s} {'dt/gw':>6s} {'dt/adv':>6s} {'stable':>6s} {'CPU [s]':>9s} {'wall [s]':>9s} {'load':>5s} {'RHS':>8s} {'RHS-eq':>8s} "
        f"{'Newton':>7s} {'GMRES':>7s} {'Helmh.':>7s} {'total err':>10s} {'time err':>10s} {'energy chg':>10s}"
    )
    lines = [head]
    for r in rows:
        lines.append(
            f"{r['stepper']:22s} {r['dt']:9.2f} {r['dt_over_gravity_limit']:6.2f} {r['dt_over_advective_limit']:6.2f} "
            f"{'yes' if r['stable'] else 'NO':>6s} {r['cpu_time']:9.2f} {r['wall_time']:9.2f} {r['load_average']:5.1f} {r['rhs_evals']:8.0f} {r['rhs_equivalents']:8.0f} "
            f"{r['newton_iterations']:7.0f} "
            f"{r['gmres_iterations']:7.0f} {r['helmholtz_iterations']:7.0f} {r['total_error']:10.3e} {r['temporal_error']:10.3e} "
            f"{r['total_energy_change']:10.2e}"
        )
    if "unscored" in info:
        lines.append(
            f"spatial error: none, so no run is judged sufficient and there are no verdicts ({info['unscored']})"
        )
        return "\n".join(lines)
    spatial, note = info["spatial_error"], floor_note(info, "spatial_error")
    lines.append(
        f"spatial error (RK4 at dt = {info['reference_dt']:.4g} s, against {info['reference']}): {spatial:.3e}"
        + (f", {note}" if note else "")
        + f"; sufficient accuracy: temporal error <= {SUFFICIENT * spatial:.3e}"
    )
    for quantity, part in (("h + hs", ""), ("divergence", "divergence_")):
        spatial_by_region = {
            k: info[f"spatial_error_{part}{k}"] for k in REGIONS if math.isfinite(info[f"spatial_error_{part}{k}"])
        }
        if not spatial_by_region:
            continue
        by_region = ", ".join(f"{k} {e:.3e}" for k, e in spatial_by_region.items())
        lines.append(f"  {quantity} by region (quality.element_regions): {by_region}")
        lines.append(f"    temporal error of {quantity} by region (/ that region's spatial error):")
        for r in (r for r in rows if r["stable"]):
            by_region = ", ".join(
                f"{k} {r[f'temporal_error_{part}{k}']:.3e} ({r[f'temporal_error_{part}{k}'] / e:.3f})"
                for k, e in spatial_by_region.items()
            )
            lines.append(f"      {r['stepper']:22s} dt = {r['dt']:.4g} s: {by_region}")
    best = cheapest_sufficient(rows, spatial)
    explicit = [best[s]["cost_time"] for s in best if STEPPERS[s].explicit]
    ref_time = min(explicit) if explicit else math.nan
    for stepper in dict.fromkeys(r["stepper"] for r in rows):
        if stepper not in best:
            lines.append(f"  {stepper:22s} no run reached sufficient accuracy")
            continue
        b = best[stepper]
        lines.append(
            f"  {stepper:22s} cheapest sufficient: dt = {b['dt']:.4g} s = {b['dt_over_gravity_limit']:.2f} x gravity-wave limit, "
            f"{b['dt_over_advective_limit']:.2f} x advective limit; CPU {b['cpu_time']:.2f} s, wall {b['wall_time']:.2f} s; "
            f"{b['cost_time'] / ref_time:.2f} x best explicit, "
            f"{b['rhs_equivalents']:.0f} RHS-eq"
        )
    lines.append(
        "verdicts: the cheapest run per criterion with temporal error <= 10 % / 50 % of that criterion's spatial error"
    )
    lines.append(format_verdicts(verdicts(rows, info), info))
    return "\n".join(lines)


RECORD = (
    "scene",
    "case",
    "ne",
    "np",
    "days",
    "overrides",
    "stepper_options",
    "reference",
    "time_filter",
    "device",
    "swe_sphere_version",
    "source_sha256",
)  # ``Sweep.record``'s keys: sweep.csv's last columns


def sweep_dataset(df, attrs: dict):
    """sweep.nc as an ``xarray.Dataset`` (``table_file.table_dataset``): one ``run``
    dimension (sweep.csv's rows), each of ``COLUMNS`` a variable on it with its units
    and long_name (``COLUMN_ATTRS``; ``stepper`` and ``reason`` text), ``attrs`` the
    global attributes, with CF's Conventions, title and history."""
    return table_dataset(
        df,
        "run",
        COLUMN_ATTRS,
        row_long_name="run of the sweep (row of sweep.csv)",
        title=f"swe_sphere sweep: {attrs['case']} ne{attrs['ne']} np{attrs['np']}, {attrs['days']:g} days",
        history=history_line(command_line("swe_sphere sweep")),
        attrs=attrs,
    )


PLOTS = (  # (x, y, file name, x label, spatial-error key): the frontier per criterion
    ("wall_time", "total_error", "error_vs_wall_time.png", "wall time [s]", "spatial_error"),
    ("dt", "total_error", "error_vs_dt.png", "dt [s]", "spatial_error"),
    ("dt", "temporal_error", "temporal_error_vs_dt.png", "dt [s]", "spatial_error"),
    (
        "wall_time",
        "total_error_vorticity",
        "error_vs_wall_time_vorticity.png",
        "wall time [s]",
        "spatial_error_vorticity",
    ),
    (
        "wall_time",
        "total_error_divergence",
        "error_vs_wall_time_divergence.png",
        "wall time [s]",
        "spatial_error_divergence",
    ),
)
OUTPUTS = ("sweep.csv", "sweep.nc", "verdicts.csv") + tuple(
    name for _, _, name, _, _ in PLOTS
)  # what write_outputs writes


def write_outputs(rows, info, limits, directory, *, overwrite: bool = False) -> list[Path]:
    """sweep.csv, sweep.nc (``sweep_dataset``: one ``run`` dimension), verdicts.csv and the PNGs (titled
    with the case, grid and days): ``OUTPUTS`` under ``directory``; returns the paths.
    What the sweep was made with (``info``'s ``RECORD`` keys: ``Sweep.record``) is in
    sweep.csv's last columns and, with the rest of ``info`` and ``limits``, in sweep.nc's
    attributes (integers as integers). Raises ``output.OutputError`` before writing
    anything if one of them exists (unless ``overwrite``)."""
    import pandas as pd

    directory = Path(directory)
    check_results(directory, OUTPUTS, overwrite)
    df = pd.DataFrame(rows, columns=list(COLUMNS))
    df["stable"] = df["stable"].astype(int)
    csv, nc, vcsv = (directory / name for name in OUTPUTS[:3])
    with atomic_path(csv, overwrite=overwrite) as tmp:
        df.assign(**{k: info[k] for k in RECORD}).to_csv(tmp, index=False)
    with atomic_path(vcsv, overwrite=overwrite) as tmp:
        pd.DataFrame(verdicts(rows, info), columns=list(VERDICT_COLUMNS)).to_csv(tmp, index=False)
    write_table_file(sweep_dataset(df, {**info, **limits}), nc, overwrite=overwrite)
    paths = [csv, nc, vcsv]
    title = f"{info['case']} ne{info['ne']} np{info['np']}, {info['days']:g} days"
    for x, y, name, label, spatial in PLOTS:
        paths.append(sweep_plot(directory / name, rows, x, y=y, xlabel=label, floor=info[spatial], title=title))
    return paths


# -- the plan: from a scene and options to the runs `swe-sphere sweep` makes ------------------------
# the explicit winners of docs/efficiency.md (RK4 on h + hs, kgu35 on the balanced flow) beside the
# best of the solver families (IMEX, Crank-Nicolson JFNK): a default sweep answers its question
DEFAULT_STEPPERS = ("rk4", "kgu35", "imex", "implicit")
DEFAULT_COURANT = (0.5, 1, 2, 5, 10, 30, 60, 100)  # multiples of the gravity-wave limit


def _positive(values, flag: str) -> tuple[float, ...]:
    """``values`` as a tuple of floats; ValueError (naming ``flag``) for none, or one not finite and > 0."""
    values = tuple(float(v) for v in values)
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise ValueError(f"{flag} values must be > 0 (got {', '.join(f'{v:g}' for v in values) or 'none'})")
    return values


def _check_divides(dt: float, days: float, what: str) -> None:
    """ValueError unless ``dt`` (s) is a whole number of steps in ``days``."""
    if abs(round(days * DAY / dt) * dt - days * DAY) > 1e-6 * dt:
        raise ValueError(f"dt = {dt:g} s does not divide {what}")


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
    time_filter : TimeFilter or None
        The Lanczos low-pass the runs are also scored by.
    overrides : dict
        The ``section.key`` settings applied to every scene, for the record.
    restart : Path or None
        The restart file every run branches from, as given.
    checkpoint : Checkpoint or None
        Its contents (``checkpoint.read``).
    """

    scenes: dict
    dts: tuple | None
    multiples: tuple | None
    runs: tuple | None
    time_filter: TimeFilter | None
    overrides: dict
    restart: Path | None
    checkpoint: object | None

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
        explicit limits on ``device`` ("cpu" or "cuda"; None: CUDA when present,
        ``pick_device``; ``explicit_limits``), each multiple's Δt (the
        largest at or below it that divides ``span`` and a day: ``dt_for_day``) and
        the notes `swe-sphere sweep` prints before its runs. Raises ValueError for a
        Δt that does not divide the run length."""
        base, ck, f, span = self.base, self.checkpoint, self.time_filter, self.span
        device = pick_device(device)
        start = ck.x if ck is not None else start_state(base, directory, device, log)
        limits = explicit_limits(base, device, start)
        dts, pairs, notes = self.dts, self.runs, []
        if dts is None:
            g = limits["dt_gravity"]
            dt_of = {m: dt_for_day(m * g, span) for m in self.multiples}
            dts = tuple(sorted(set(dt_of.values())))
            asked = {m: "/".join(f"{s}@{m:g}" for s, k in pairs if k == m) if pairs else f"{m:g}" for m in dt_of}
            pairs = tuple((s, dt_of[m]) for s, m in pairs) if pairs else None
            capped = [m for m in dt_of if f is not None and m * g > span * DAY * (1 + 1e-9)]
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
                _check_divides(dt, base.run_days, f"the run length of {base.run_days:g} days")
        notes.append(
            f"sweep {base.name} {base.grid_text}, {f'day {base.start_day:g} to ' if ck else ''}"
            f"{base.days:g} days; explicit limits: gravity-wave dt = {limits['dt_gravity']:.1f} s, advective dt = "
            f"{limits['dt_advective']:.1f} s; dt = {', '.join(f'{d:.4g}' for d in dts)}"
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
        self, directory, device: str | None = None, *, pool=None, cost: str = "cpu", overwrite: bool = False, log=print
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
            Warp device (default: CUDA when present).
        pool : concurrent.futures.Executor, optional
            Runs the runs (``core.workers.executor``); None: one after another, here.
        cost : {"cpu", "wall"}
            The clock the runs are ranked by (``table``).
        overwrite : bool
            Replace an earlier sweep's results in ``directory``.
        log : callable
            Called with each line to show.

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
        ValueError
            A Δt that does not divide the run length; an unknown ``cost``.
        BlowUp
            The small-Δt reference run failed.
        Interrupted
            SIGINT or SIGTERM; what is kept is said.
        """
        with folder_lock(directory, "sweep.lock"):  # a second sweep into this folder is refused now, not at its end
            check_results(directory, OUTPUTS, overwrite)  # an earlier sweep's results: refused now, not at the end
            resolved = self.resolve(directory, device, log)
            for line in resolved.notes:
                log(line)
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
    runs : sequence of (str, float), optional
        Only these (stepper, multiple of the gravity-wave limit) runs. At most one
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
        Options that conflict, none or non-positive values, a Δt that does not
        divide the run length or the filter's snapshot interval, a bad filter
        (messages name the options as `swe-sphere sweep` spells them).
    SceneError
        A bad scene, override or stepper (``load_scene``).
    CheckpointError
        An unreadable restart file, or a branch it cannot make.

    Examples
    --------
    >>> p = plan("tc2_steady", ne=2, days=1, runs=[("rk4", 1), ("imex", 4)])  # doctest: +SKIP
    >>> rows, info, paths = p.run("sweep", "cpu")  # doctest: +SKIP
    """
    if runs is not None and steppers is not None:
        raise ValueError("--runs names its own steppers: give --steppers or --runs, not both")
    if sum(x is not None for x in (dts, courant, runs)) > 1:
        raise ValueError("give one of --dt, --courant and --runs")
    if runs is not None:
        runs = tuple((s, m) for (s, _), m in zip(runs, _positive([m for _, m in runs], "--runs")))
        steppers = list(dict.fromkeys(s for s, _ in runs))
    steppers = list(DEFAULT_STEPPERS if steppers is None else steppers)
    if not steppers:
        raise ValueError("--steppers names no stepper")
    overrides = dict(overrides or {})
    ck = None
    if restart is not None:  # every run a branch from the restart file's state (``checkpoint.branch``)
        for flag, given in (("SCENE", scene), ("--ne", ne), ("--np", np_), ("-s", overrides)):
            if given:
                raise ValueError(
                    f"--from takes the scene and grid from the restart file: give --from or {flag}, not both"
                )
        ck = checkpoint.read(restart)
        scenes = {s: checkpoint.branch(ck, stepper=s, days=days) for s in steppers}
    elif scene is None:
        raise ValueError("sweep needs a SCENE (or --from RESTART.nc)")
    else:
        scenes = {s: load_scene(scene, ne=ne, np_=np_, days=days, stepper=s, overrides=overrides) for s in steppers}
    dts = None if dts is None else _positive(dts, "--dt")
    multiples = None
    if dts is None:
        multiples = (
            tuple(sorted({m for _, m in runs}))
            if runs
            else _positive(DEFAULT_COURANT if courant is None else courant, "--courant")
        )
    length = next(iter(scenes.values())).run_days  # from t = 0, or from the day of the restart file
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
        _check_divides(
            dt, time_filter.every_hours / 24, f"the filter's snapshot interval of {time_filter.every_hours:g} h"
        )
    for dt in dts or ():
        _check_divides(dt, length, f"the run length of {length:g} days")
    return Plan(scenes, dts, multiples, runs, time_filter, overrides, None if ck is None else Path(restart), ck)
