"""A simulation's restarts: continued from a restart file, bitwise as if never stopped, or
branched from it (another stepper or Δt); its state and history restored; a restart file
written: ``continued`` (what ``Simulation.from_checkpoint`` builds from), and ``Restarts``, the methods
``restore``, ``restore_history``, ``restore_members`` and ``write_checkpoint`` of a ``Simulation`` (which is one)."""

from __future__ import annotations

from pathlib import Path

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
    file ``checkpoint.read`` refuses, or one of the other kind (an ensemble's, a single run's)."""
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
    # the state handed out with its t = 0 diagnostics; no second digital filter
    return ck, ckpt.continued_scene(ck, days), start, ck.initial, True


class Restarts:
    """A ``Simulation``'s state and history restored from a checkpoint, and its restart file
    written (its attributes the simulation's: ``x``, ``stepper``, ``step``, ``counters``,
    ``initial``, ``control``, ``topology``, ...)."""

    def restore(self, ck: ckpt.Checkpoint) -> None:
        """Set the state, stepper history, counters and t = 0 invariants from a checkpoint (a
        single run's; ``CheckpointError`` for a state of another grid)."""
        try:
            # ck.x on rank 0 only (``checkpoint.read_on_root``)
            x = self.topology.distribute(ck.x, 3, "checkpoint state")
        except ValueError as err:
            raise CheckpointError(str(err)) from None
        self.x.assign(x)
        self.restore_history(ck)

    def restore_history(self, ck: ckpt.Checkpoint) -> None:
        """The stepper history, counters, step control and t = 0 invariants of a checkpoint (the state
        is already ``ck.x``)."""
        restore_run(self.run_state, ck, lambda: self.stepper.restore(ck.stepper_state))
        self.initial = ck.initial

    def restore_members(self, ck: ckpt.Checkpoint) -> None:
        """An ensemble's ``restore_history``: every member's state and stepper history (``Members.restore``)."""
        restore_run(self.run_state, ck, lambda: self.ensemble.restore(ck))

    def write_checkpoint(self, path, *, overwrite: bool = True, restart_every: float | None = None) -> Path:
        """Write a restart file of the current step (see ``checkpoint``): whole-grid
        fields, gathered from every rank (call on all), written by rank 0;
        ``restart_every`` (days) recorded for a continuation to keep. Members: every member's
        state and its stepper's history, the member count, the layout and the variants."""
        kept = {"overwrite": overwrite, "restart_every": restart_every}
        if self.ensemble is not None:
            parts = self.ensemble.restart_parts()
            if parts is None:
                return Path(path)
            x, state, initial, grid = parts
            return write_restart(path, self.run_state, x, state, initial, grid, members=self.members, **kept)
        x, state = self.topology.gather(self.x.numpy()), self.stepper.state()
        if not self.root:
            return Path(path)
        return write_restart(path, self.run_state, x, state, self.initial, self.grid, **kept)


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
