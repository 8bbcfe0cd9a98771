"""A simulation's restarts: continued from a restart file, bitwise as if never stopped, or
branched from it (another stepper or Δt); its state and history restored; a restart file
written: ``continued`` (what ``Simulation.from_checkpoint`` builds from), ``restore_run`` and
``write_restart``, functions of the run state and arrays they are given."""

from __future__ import annotations

from pathlib import Path

from ..config.scene import with_days
from ..core.arguments import path_argument
from ..core.errors import CheckpointError
from ..io import restart_file
from . import checkpoint as ckpt
from .build import ON_ROOT


def continued(checkpoint, days, stepper=None, dt=None, comm=None, members: bool = False) -> tuple:
    """What ``Simulation.from_checkpoint`` (``members``: an ensemble's file) builds
    from: (the checkpoint read, the scene, the constructor's ``start`` and ``initial_diagnostics``,
    and whether it continues the file rather than branch from it: its stepper's history then
    restored, ``restore_history``). ``CheckpointError`` (one line) for a path that is not one, a
    file ``checkpoint.read`` refuses, one of the other kind (an ensemble's, a single run's), or a
    continuation whose run to ``days`` ends before the checkpoint's day."""
    if isinstance(checkpoint, ckpt.Checkpoint):
        ck = checkpoint
    else:  # an ensemble's members' states on every rank (each steps its own)
        path_argument("checkpoint", checkpoint, "a restart file's path (str or os.PathLike)", CheckpointError)
        ck = ckpt.read(checkpoint) if members else ckpt.read_on_root(checkpoint, comm)
    if members and ck.members is None:
        raise CheckpointError(f"{ck.path}: a single run's restart file (continue it with members=False)")
    if not members and ck.members is not None:
        raise CheckpointError(
            f"{ck.path or 'the checkpoint'} is an ensemble's restart file ({ck.members} members): continue it "
            "with Simulation.from_checkpoint(..., members=True) (swe-sphere run --continue does)"
        )
    start = ON_ROOT if ck.x is None else ck.x  # ranks > 0 of ``read_on_root`` have no arrays
    if (stepper is not None and stepper != ck.scene.stepper) or (dt is not None and dt != ck.scene.dt):
        return ck, ckpt.branch(ck, stepper=stepper, dt=dt, days=days), start, None, False
    # the scene that continues it to ``days``, the state handed out with its t = 0 diagnostics; no second
    # digital filter
    scene = ck.scene if days is None else with_days(ck.scene, days)
    if scene.days < ck.day:
        raise CheckpointError(f"the run length {scene.days:g} days ends before the checkpoint (day {ck.day:g})")
    return ck, scene, start, ck.initial, True


def restore_run(run, ck: ckpt.Checkpoint, restore) -> None:
    """Continue ``run`` (a ``run_state.RunState``: a ``Simulation``'s) from
    the checkpoint ``ck``: its steppers' histories (``restore()``; ``CheckpointError`` where they
    do not fit), then its step, counters and step control, as if never stopped."""
    try:
        restore()
    except ValueError as err:
        raise CheckpointError(f"checkpoint does not fit the stepper: {err}") from None
    run.core.step = ck.step
    run.counters.update(ck.counters)  # an ensemble's file from before ensembles counted as runs: its wall time alone
    if run.control is not None and ck.control is not None:  # the steps go on as if never stopped
        run.control.restore(ck.control)


def write_restart(path, run, x, state: dict, initial: dict, grid, **kept) -> Path:
    """The restart file ``path`` (``io.restart_file.write``) of ``run``'s step (a
    ``run_state.RunState``: its scene, step, counters and step control) with the whole state
    ``x``, the stepper's ``state``, ``initial`` and ``grid``; ``kept`` as ``restart_file.write``
    takes them (``overwrite``, ``restart_every``, an ensemble's ``members``). Rank 0's."""
    control = None if run.control is None else run.control.state()
    return restart_file.write(
        path, run.scene, run.step, x, state, run.counters, initial, grid=grid, control=control, **kept
    )
