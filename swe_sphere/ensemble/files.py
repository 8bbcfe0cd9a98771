"""An ensemble's restart file: its members, steppers, drops, control and counts put back
(``Ensemble.from_checkpoint``)."""

from __future__ import annotations

import numpy as np

from ..core.errors import CheckpointError
from .units import held_state, unit_members


def resume(ens, ck) -> None:
    """Put the restart file ``ck``'s (a ``simulation.checkpoint.Checkpoint`` of ``ens.members``
    members) states and stepper histories into ``ens``'s units, its dropped members, step
    control, step count, counters and initial states' description. ``CheckpointError`` where its
    stepper state does not fit the ensemble's steppers."""
    n = ck.x.shape[1] // ck.members
    try:
        for u, k in zip(ens.units, unit_members(ens.layout, ens.held)):
            nodes = (k[:, None] * n + np.arange(n)).ravel()  # the unit's members' columns of the file's arrays
            u.x.assign(ck.x[:, nodes])
            prefix = None if ens.layout == "shared" else f"member{k[0]}_"
            u.stepper.restore(held_state(ck.stepper_state, nodes, prefix))
    except ValueError as err:
        raise CheckpointError(f"checkpoint does not fit the stepper: {err}") from None
    ens.mark_dropped({int(k): step for k, step in ck.initial.get("dropped", {}).items()})  # their last good states
    if ens.control is not None and ck.control is not None:  # the steps go on as if never stopped
        ens.control.restore(ck.control)
    ens.step_count = ck.step
    ens.counters.update(ck.counters)  # a file from before ensembles counted as runs: its wall time alone
    ens.initial = ck.initial.get("initial_states", ens.initial)
