"""A run's output writers: its run file and streams, and its restart files (the checkpointer)."""

from __future__ import annotations

import functools
import math
from pathlib import Path

from ..cases.scoring import truth
from ..core.runtime import package_version
from ..io.run_file import OUTPUT_FIELDS, RunWriter, history_line
from ..members.units import POLICIES
from .checkpoint import branch_attrs
from .schedules import at_marks, is_due, output_marks, restart_marks


def stream_path(output: Path, name: str) -> Path:
    """The run file of output stream ``name`` beside a run's output: ``run.nc`` → ``run.NAME.nc``."""
    output = Path(output)
    return output.with_name(f"{output.stem}.{name}{output.suffix or '.nc'}")


def restart_path(output: Path) -> Path:
    """The restart file beside a run's output: ``run.nc`` → ``run.restart.nc`` (a stream's name, always ``.nc``)."""
    return stream_path(output, "restart").with_suffix(".nc")


def opening(d, files, start, history: str | None, name: str, dfi, device: str) -> tuple:
    """(the Courant numbers of a single run's ``start`` (members: none), the members' first
    diagnostics (a single run: None, the files take them), the global attributes of the run's files
    ``files``, and what else ``RunFiles.open`` takes (members: ``members``, ``member_series``, which
    ``files`` gets)) of the run of members ``d`` (``members.members.Members``; ``start`` its
    ``gather_fields``): what ran (its title, ``history`` or ``name`` the caller, the package, the scene
    (JSON) and its case, grid, stepper, Δt and precision), where (on ``device`` over the
    MPI ranks), from which start (the digital filter ``dfi`` or None; members: ``initial_states``), its
    command line (``history``), a single run's Courant numbers at the start and a branch's origin."""
    s, run = d.run.scene, d.run
    attrs = {  # what ran, then e.g. which Butcher table ran and where
        "title": f"swe_sphere {'ensemble' if d.members else 'run'} of scene {s.name}",
        "history": history_line(history or f"{name} of scene {s.name}"),
        "source": f"swe_sphere {package_version()}",
        "swe_sphere_version": package_version(),
        "scene": s.as_dict(),
        **{k: getattr(s, k) for k in ("case", "ne", "np", "stepper", "dt", "precision")},
        **run.stepper.attrs(),
        "device": device,
    }
    again = {"continued_from_day": run.time} if run.step else {}
    if d.members:
        first = d.diagnose(run.seconds(run.step), whole=start)
        files.member_series = tuple(first)
        attrs |= {"ensemble_layout": d.layout, "members": d.members, "initial_states": d.initial_states}
        attrs |= {"blow_up_policy": POLICIES[d.blow_up], **again}
        return {}, first, attrs, {"members": d.members, "member_series": files.member_series}
    courant = d.bcast(d.courant_at(start.u, start.v, start.h, d.g[0]) if d.root else None)
    attrs |= {
        "mpi_ranks": d.topology.comm.size,
        "initialization": "none" if s.initialization is None else s.initialization["method"],
        "reference": truth(d.case, s.reference_file),  # what the error series are against
        # planet_radius (m), planet_omega (1/s), planet_gravity (m/s^2)
        **{f"planet_{k}": v for k, v in s.planet.items()},
        **(dfi.attrs(s.digital_filter) if dfi is not None else {}),
        **again,
        **branch_attrs(s),
        **{k: v for k, v in courant.items() if math.isfinite(v)},
    }
    return courant, None, attrs, {}


class RunFiles:
    """The run files of a run (its ``run_state.RunState`` ``run``, its ``diagnostics``, ``grid`` and
    ``hs``) to ``output`` (``streams``: itself with the scene's ``output.fields``, then each
    ``[[output.streams]]`` (``stream_path``), each at its own output times, under step control with the
    control's series); without ``output`` none, the diagnostics still taken at the
    scene's output steps. Rank 0's ``RunWriter`` s (``open``), the step each wrote last (on every
    rank), their output times together (the ``schedule`` of an activity) and
    whether any holds the divergence; ``record`` diagnoses an output step (into ``history``, and
    ``on_output(step, x)``). An activity (``activities``): ``files(owner)`` records the run's step
    at the steps of ``schedule``. A run of members': ``diagnostics`` its
    ``members.Members`` (``gather_fields`` and ``diagnose`` over the member axis), ``series`` its
    per-time series and ``member_series`` (set after its first diagnostics) those of each member
    (time, member), the members along the member axis."""

    def __init__(self, run, diagnostics, grid, hs, output: Path | None, on_output=None):
        controlled, series = run.control is not None, ("steps", "wall_time")  # members': each member's apart
        if not diagnostics.members:  # a single run's
            solvers = [f"{k}_iterations" for k in run.stepper.solvers]
            # what the run file records of the step control at each output time (``SERIES_ATTRS``)
            control = ("dt", "rejected_steps", "error_estimate", "spatial_rate") if controlled else ()
            series = ["steps", "rhs_evals", *solvers, "wall_time", *run.initial, *control]
        s = self.scene = run.scene
        self.grid, self.hs, self.series = grid, hs, list(series)
        # the run files (None: none), each (path, fields, schedule): the run file itself with the scene's
        # ``output.fields``, then each ``[[output.streams]]`` with its own, each due at its own output steps
        # (``schedules.output_marks``; under step control its days)
        main = output_marks(s, s.output_every_days)  # the run file's times (without one, the diagnostics')
        marks = [] if output is None else [(Path(output), s.output_fields or OUTPUT_FIELDS, main)]
        for st in s.output_streams if output is not None else ():
            marks.append((stream_path(output, st["name"]), st["fields"], output_marks(s, st["every_days"])))
        self.streams = [(path, fields, at_marks(at, controlled)) for path, fields, at in marks]
        self.schedule = at_marks(main.union(*(at for _, _, at in marks)), controlled)
        self.divergence = any("divergence" in fields for _, fields, _ in self.streams)
        self.writers = []  # rank 0's RunWriters, one a stream (none on the other ranks)
        self.last = [None] * len(self.streams)  # the step each run file wrote last (on every rank)
        self.run, self.diagnostics = run, diagnostics
        self.member_series = ()  # an ensemble's, set once its first diagnostics name them
        self.on_output, self.history = on_output, []

    def open(self, attrs: dict, *, overwrite: bool, compress: bool, notify=None, **members) -> None:
        """Create the files (rank 0) with the global attributes ``attrs`` (``members``: an
        ensemble's ``members`` and ``member_series``, as ``RunWriter`` takes them), their cells the
        scene's; on failure none is left (``OutputError`` as ``RunWriter``'s). ``notify(line)``:
        told in one line when the run file's cells were built rather than read from the cache at
        some cost, or when their fit failed and the files were written without them
        (``RunWriter.cells_notes``; the run file's, not its streams')."""
        try:
            for i, (path, fields, _) in enumerate(self.streams):
                kw = {"overwrite": overwrite, "compress": compress, "fields": fields, "cells": self.scene.output_cells}
                kw["tracers"] = tuple(name for name, _ in self.scene.tracers)
                self.writers.append(RunWriter(path, self.grid, self.hs, attrs, self.series, **kw, **members))
                for line in self.writers[i].cells_notes(self.scene.grid_text) if notify is not None and i == 0 else ():
                    notify(line)
        except BaseException:
            self.abort()
            raise

    def _each(self, verb: str, **kw) -> None:
        """``RunWriter.<verb>(**kw)`` of every file rank 0 holds: ``set_attrs``, ``close``, and
        ``abort`` (drop the files: a failed run)."""
        for w in self.writers:
            getattr(w, verb)(**kw)

    set_attrs = functools.partialmethod(_each, "set_attrs")
    close = functools.partialmethod(_each, "close")
    abort = functools.partialmethod(_each, "abort")

    def record(self, x=None, whole=None, final: bool = False, write: bool = True, diagnosed=None) -> None:
        """Diagnose the run's step (``run.step``; state x, default the current one; ``whole`` its gathered
        fields and ``diagnosed`` their ``diagnose`` when the caller has them) and write it
        to the run files whose schedule holds it (``final``: to every one; ``write`` False:
        to none, the diagnostics kept in ``history`` alone). Call on every rank."""
        run, step, c, ctl, day = self.run, self.run.step, self.run.counters, self.run.control, self.run.time
        # once per output time, on every rank; day: the control's under it
        whole = self.diagnostics.gather_fields(x, divergence=self.divergence) if whole is None else whole
        d = self.diagnostics.diagnose(run.seconds(step), x, whole) if diagnosed is None else diagnosed
        d.update(steps=step, day=day, rhs_evals=c["rhs_evals"], wall_time=c["wall_time"], cpu_time=c["cpu_time"])
        if ctl is not None:
            d.update(dt=ctl.dt_last, rejected_steps=ctl.rejected, error_estimate=ctl.error_last)
            d.update(spatial_rate=math.nan if ctl.balance is None else ctl.balance.rate.last)
        d.update({f"{k}_iterations": c["iterations"].get(k, 0) for k in run.stepper.solvers})
        self.history.append(d)
        if self.on_output is not None:
            self.on_output(step, run.x if x is None else x)
        series = {k: d[k] for k in (*self.series, *self.member_series)}
        # to the files whose times hold it (``final``: every one) and that have not written it, marked as
        # written; rank 0 writes the fields DSS'd, element-local, s-1
        for i, (_, _, at) in enumerate(self.streams if write else ()):
            if (final or is_due(at, run)) and self.last[i] != step:
                self.last[i] = step
                if self.writers:  # rank 0's
                    more = {k: getattr(whole, k) for k in ("vorticity", "divergence", "masses")}
                    self.writers[i].append(day, whole.u, whole.v, whole.h, series, **more)

    def __call__(self, owner) -> None:
        self.record()

    def end(self, x=None, **attrs) -> None:
        """Close a run that stops early at its step (``run.step``; state x, default the current one):
        the step recorded where it is not yet, and the global ``attrs`` set (why it stopped)."""
        if not is_due(self.schedule, self.run) or any(at != self.run.step for at in self.last):  # some file lacks it
            self.record(x, final=True)
        self.set_attrs(**attrs)


class Checkpointer:
    """The restart files of a run (its ``run_state.RunState`` ``run``, written by ``write``, a
    ``Simulation.write_checkpoint``; ``bcast(value)`` rank 0's value on every rank; ``root`` this rank is 0): ``path`` (default ``restart_path(output)``)
    every ``every_days`` (whole steps) and at the end, and on a signal. Without
    ``every_days`` and ``overwrite``, an existing default restart file is neither
    refused nor replaced (``kept``: no restart file on a signal). Raises ValueError
    for an interval that is not whole steps, or one with neither output nor path.
    An activity (``activities``): ``checkpointer(owner)`` saves at the steps of ``schedule``."""

    def __init__(self, run, write, bcast, root: bool, output, every_days: float | None, path, overwrite: bool):
        self.run, self.overwrite, self.kept, self.written = run, overwrite, None, None
        self.write = functools.partial(write, restart_every=every_days)  # the interval kept in every file
        if path is None and output is not None:
            path = restart_path(output)
            if every_days is None and not overwrite and bcast(root and path.exists()):
                path, self.kept = None, path
        self.path = path
        # steps, or under step control days (``schedules.restart_marks``)
        marks = set() if every_days is None else restart_marks(run.scene, every_days)
        self.schedule = at_marks(marks, run.control is not None)
        if every_days is not None and path is None:
            raise ValueError("a restart interval needs an output or restart file")

    def interrupted(self, abandoned: bool) -> None:
        """Save the restart file of a run stopped by a signal at its step (``run.step``), unless it has
        none, already saved this step, or the step was ``abandoned`` (the stepper's history
        is then half updated)."""
        if self.path is not None and not is_due(self.schedule, self.run) and not abandoned:
            self()

    def __call__(self, owner=None) -> None:
        """Write the restart file of the current step (call on every rank)."""
        self.written = self.write(self.path, overwrite=self.overwrite or self.written is not None)
