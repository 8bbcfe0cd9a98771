"""Checkpoints: everything a run needs to continue bitwise (HOMME's restart, Oceananigans'
``Checkpointer``), read from a restart file (``restart_file``: its layout, checks and writer)
with its scene. Restored into a fresh ``Simulation`` of the same scene it is just another
initial state: the continued run is bitwise the uninterrupted one. A checkpoint also starts
other runs (``branch``: ``swe-sphere run --continue R --stepper S --dt DT``, ``sweep --from R``).

A simulation's restarts: continued from a restart file, bitwise as if never stopped, or
branched from it (another stepper or Δt); its state and history restored; a restart file
written: ``from_checkpoint`` (``Simulation.from_checkpoint``, from what ``continued`` reads),
``restore_run`` and ``write_restart``, functions of the run state and arrays they are given.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..config.scene import Scene, branched, scene_from_dict, with_days
from ..core.arguments import path_argument
from ..core.errors import CheckpointError, SceneError
from ..core.mpi import from_root
from ..io import restart_file
from ..members.initial import ON_ROOT, Variants


@dataclass
class Checkpoint:
    """A read checkpoint: the scene, the step reached and what continues from it."""

    scene: Scene
    step: int
    x: np.ndarray  # (3, N) element-local u, v, h
    stepper_state: dict
    counters: dict  # rhs_evals, wall_time, iterations (dict)
    initial: dict  # diagnostics at t = 0
    version: str
    path: Path | None = None  # the file read (absolute)
    sha256: str | None = None  # SHA-256 (hex) of the file's bytes
    restart_every: float | None = None  # days: the interval the run wrote restart files at (None: at a signal only)
    control: dict | None = None  # under step control ``StepControl.state()`` (its ``day``: the time reached)
    members: int | None = None  # an ensemble's member count (x every member's, side by side); None: one run
    analysed: bool = False  # the file keeps a reanalysis start's analysed state (``restart_file.ANALYSED``)
    departure: np.ndarray | None = None  # a kept float32 state's h − H₀ as the run held it (N,; ``model.held``)

    @property
    def day(self) -> float:
        """The model day reached (days from t = 0)."""
        return self.scene.day(self.step) if self.control is None else self.control["day"]


def run_scene(ck: Checkpoint) -> Scene:
    """The scene a run from checkpoint ``ck`` builds its case from: ``ck.scene``, a reanalysis
    start's case reading the analysed state the file keeps (``restart_file.case_params``), so
    the run needs no input file."""
    params = restart_file.case_params(ck.scene.case_params, ck.path, ck.analysed)
    return ck.scene if params == ck.scene.case_params else replace(ck.scene, case_params=params)


def branch(ck: Checkpoint, *, stepper: str | None = None, dt: float | None = None, days: float | None = None) -> Scene:
    """The scene of a new run from checkpoint ``ck``'s state with ``stepper`` and ``dt`` (s;
    None: the checkpoint's), to model day ``days`` (from t = 0; None: the checkpoint scene's):
    ``config.scene.branched`` of its scene (``run_scene``) at its day, ``Scene.branch``
    recording the source (its path and SHA-256, step, day, stepper and dt). Raises
    ``SceneError`` as ``branched``."""
    record = {"restart": None if ck.path is None else str(ck.path), "sha256": ck.sha256, "step": ck.step}
    return branched(run_scene(ck), record | {"day": ck.day}, stepper, dt, days)


def branch_attrs(scene: Scene) -> dict:
    """The global attributes of a branched run's files (``Scene.branch``): ``branched_from``
    (the restart file's path), ``branched_from_sha256``, ``_step``, ``_day``, ``_stepper``,
    ``_dt`` (those known); {} for a scene that did not branch."""
    b = scene.branch or {}
    return {"branched_from" + ("" if k == "restart" else f"_{k}"): v for k, v in b.items() if v is not None}


def read_on_root(path, comm) -> Checkpoint:
    """``read`` on rank 0 of ``comm`` (None or one rank: ``read``; None for an ensemble's file,
    its members' states on every rank, each stepping its own): the other ranks
    get the checkpoint without its whole-grid arrays (x and the stepper's arrays
    None), which rank 0 hands out (``Topology.distribute``), so no other rank holds
    the whole state. Raises ``CheckpointError`` for a ``path`` that is not one, and what
    ``read`` raises, on every rank."""
    path_argument("checkpoint", path, "a restart file's path (str or os.PathLike)", CheckpointError)
    if comm is None or comm.size == 1:
        return read(path)
    ck = from_root(comm, lambda: read(path))
    bare = {} if ck is None else {k: None if isinstance(v, np.ndarray) else v for k, v in ck.stepper_state.items()}
    light = comm.bcast(None if ck is None else replace(ck, x=None, departure=None, stepper_state=bare), root=0)
    return ck if comm.rank == 0 else light


def read(path) -> Checkpoint:
    """Read a checkpoint (``restart_file.read``) and its scene. Raises ``CheckpointError`` (one line)."""
    stored = restart_file.read(path)
    try:
        scene = scene_from_dict(stored.pop("scene"))
    except (KeyError, ValueError, TypeError) as err:
        raise CheckpointError(f"{Path(path)}: damaged checkpoint ({type(err).__name__}: {err})") from None
    return Checkpoint(scene, **stored)


def continued(checkpoint, days, stepper=None, dt=None, comm=None, members: bool = False) -> tuple:
    """What ``Simulation.from_checkpoint`` (``members``: an ensemble's file) builds
    from: (the checkpoint read, the scene, the constructor's ``start`` and ``initial_diagnostics``,
    and whether it continues the file rather than branch from it: its stepper's history then
    restored, ``Simulation.restore``). ``CheckpointError`` (one line) for a path that is not one, a
    file ``checkpoint.read`` refuses, one of the other kind (an ensemble's, a single run's), or a
    continuation whose run to ``days`` ends before the checkpoint's day."""
    ck = checkpoint if isinstance(checkpoint, Checkpoint) else read_on_root(checkpoint, None if members else comm)
    if members and ck.members is None:
        raise CheckpointError(f"{ck.path}: a single run's restart file (continue it with members=False)")
    if not members and ck.members is not None:
        raise CheckpointError(
            f"{ck.path or 'the checkpoint'} is an ensemble's restart file ({ck.members} members): continue it "
            "with Simulation.from_checkpoint(..., members=True) (swe-sphere run --continue does)"
        )
    start = ON_ROOT if ck.x is None else ck.x  # ranks > 0 of ``read_on_root`` have no arrays
    asked = (("stepper", stepper, ck.scene.stepper), ("dt", dt, ck.scene.dt))  # (name, given, the file's)
    other = [f"{k} = {v!r}" for k, v, own in asked if v not in (None, own)]
    if other and members:  # the command line's rule (run --continue with --stepper or --dt) too
        raise SceneError(
            f"{' and '.join(other)}: an ensemble continues with its own stepper and dt (no branches yet; "
            f"the file's: {ck.scene.stepper}, dt = {ck.scene.dt:g} s)"
        )
    if other:
        return ck, branch(ck, stepper=stepper, dt=dt, days=days), start, None, False
    # the scene that continues it to ``days``, the state handed out with its t = 0 diagnostics; no second
    # digital filter
    scene = run_scene(ck) if days is None else with_days(run_scene(ck), days)
    if scene.days < ck.day:
        raise CheckpointError(f"the run length {scene.days:g} days ends before the checkpoint (day {ck.day:g})")
    return ck, scene, start, ck.initial, True


def restore_run(run, ck: Checkpoint, restore) -> None:
    """Continue ``run`` (a ``run_state.RunState``: a ``Simulation``'s) from
    the checkpoint ``ck``: its steppers' histories (``restore()``; ``CheckpointError`` where they
    do not fit), then its step, counters and step control, as if never stopped."""
    try:
        restore()
    except CheckpointError:  # already one line (a state of another grid)
        raise
    except ValueError as err:
        raise CheckpointError(f"checkpoint does not fit the stepper: {err}") from None
    run.core.step = ck.step
    run.counters.update(ck.counters)  # an ensemble's file from before ensembles counted as runs: its wall time alone
    if run.control is not None and ck.control is not None:  # the steps go on as if never stopped
        run.control.restore(ck.control)


def write_restart(path, run, x, state: dict, initial: dict, grid, departure=None, **kept) -> Path:
    """The restart file ``path`` (``io.restart_file.write``) of ``run``'s step (a
    ``run_state.RunState``: its scene, step, counters and step control) with the whole state
    ``x``, the stepper's ``state``, ``initial``, ``grid`` and a kept float32 state's ``departure``
    (None: none); ``kept`` as ``restart_file.write`` takes them (``overwrite``, ``restart_every``,
    an ensemble's ``members``). Rank 0's."""
    control = None if run.control is None else run.control.state()
    return restart_file.write(
        path,
        run.scene,
        run.step,
        x,
        state,
        run.counters,
        initial,
        grid=grid,
        control=control,
        departure=departure,
        **kept,
    )


def from_checkpoint(
    cls,
    checkpoint,
    device: str | None = None,
    *,
    days: float | None = None,
    stepper: str | None = None,
    dt: float | None = None,
    progress: bool = True,
    comm=None,
    graphs: str | bool | None = None,
    members: bool = False,
    per_element: bool | None = None,
    threads: int | None = None,
):
    """A simulation that continues a restart file, bitwise as if never stopped.

    With another ``stepper`` or ``dt`` than the checkpoint's it is a branch
    (``checkpoint.branch``): a new run from the checkpoint's state, its stepper's
    history dropped (multistep steppers start as at t = 0), its counters from zero
    and its invariants' changes against that state, steps counted from the
    checkpoint's day (a single run's file alone).

    Parameters
    ----------
    checkpoint : str, path or checkpoint.Checkpoint
        The restart file (read on rank 0 only, ``checkpoint.read_on_root``; an ensemble's on
        every rank, each stepping its members).
    device : {"cpu", "cuda"}, optional
        Warp device.
    days : float, optional
        The new last model day, from t = 0 (default: the checkpointed scene's).
    stepper : str, optional
        Another stepper: a branch.
    dt : float, optional
        Another time step (s): a branch.
    members : bool
        The file is an ensemble's (its members, layout, blow-up policy and variants the
        file's); False: a single run's.
    progress, comm, graphs, per_element, threads
        As for the constructor.

    Returns
    -------
    Simulation
        At the checkpoint's step, its restart interval (``restart_every``) the file's.

    Raises
    ------
    CheckpointError
        ``checkpoint`` not a path or a ``Checkpoint``, an unreadable or damaged restart file,
        one of the other kind (``members``), or a ``days`` before its step.
    SceneError
        A branch it cannot make (unknown stepper, dt <= 0, a length not whole steps), or any
        branch of an ensemble's file (``members``: it continues with its own stepper and dt,
        as ``swe-sphere run --continue`` refuses ``--stepper`` and ``--dt`` for it).
    """
    ck, scene, start, initial, whole = continued(checkpoint, days, stepper, dt, comm, members=members)
    kw = {"progress": progress, "comm": comm, "graphs": graphs}
    if members:
        # the file's states, or its Variants (the members' own scenes), its layout and blow-up policy
        variants, kept = ck.initial.get("variants"), ck.initial
        # u, v, h and the tracers' masses hq, a member's
        states = ck.x.reshape(len(ck.x), ck.members, -1).transpose(1, 0, 2) if variants is None else Variants(variants)
        both = {"layout": kept.get("layout", "shared"), "blow_up": kept.get("blow_up", "stop"), "threads": threads}
        sim = cls(scene, device=device, members=ck.members, initial=states, per_element=per_element, **kw, **both)
        sim.restore(ck)
    else:
        sim = cls(scene, device=device, start=start, initial_diagnostics=initial, **kw)
        if whole:  # a continuation: the stepper's history, the counters and the step control as they were
            sim.restore(ck, state=False)
    if whole:
        sim.restart_every = ck.restart_every  # the interval it wrote restart files at, kept
    if not isinstance(checkpoint, Checkpoint):
        sim.inputs = (Path(checkpoint),)
    return sim
