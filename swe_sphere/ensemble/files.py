"""An ensemble's restart file: its members, steppers, drops, control and counts put back
(``Ensemble.from_checkpoint``)."""

from __future__ import annotations

import numpy as np

from ..simulation.restart import restore_run
from .units import held_state, unit_members


def resume(ens, ck) -> None:
    """Put the restart file ``ck``'s (a ``simulation.checkpoint.Checkpoint`` of ``ens.members``
    members) states and stepper histories into ``ens``'s units, its dropped members, step
    control, step count, counters (``simulation.restart.restore_run``, a run's) and initial
    states' description. ``CheckpointError`` where its stepper state does not fit the
    ensemble's steppers."""
    n = ck.x.shape[1] // ck.members

    def restore() -> None:
        for u, k in zip(ens.units, unit_members(ens.layout, ens.held)):
            nodes = (k[:, None] * n + np.arange(n)).ravel()  # the unit's members' columns of the file's arrays
            u.x.assign(ck.x[:, nodes])
            prefix = None if ens.layout == "shared" else f"member{k[0]}_"
            u.stepper.restore(held_state(ck.stepper_state, nodes, prefix))

    restore_run(ens.run_state, ck, restore)
    ens.mark_dropped({int(k): step for k, step in ck.initial.get("dropped", {}).items()})  # their last good states
    ens.initial = ck.initial.get("initial_states", ens.initial)
