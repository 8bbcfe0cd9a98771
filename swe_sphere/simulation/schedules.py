"""Which steps of a run do what: output times, restart files, intervals of whole steps."""

from __future__ import annotations

import math

from ..config.scene import Scene
from ..core.constants import DAY


def steps_of(scene: Scene, days: float, what: str) -> int:
    """The whole number of steps in ``days``; ValueError naming ``what`` unless dt divides it."""
    per = round(days * DAY / scene.dt) if isinstance(days, (int, float)) and math.isfinite(days) else 0
    if per < 1 or abs(per * scene.dt - days * DAY) > 1e-6 * scene.dt:
        raise ValueError(
            f"{what} must be a positive multiple of dt = {scene.dt:g} s = {scene.dt / DAY:.6g} days (got {days!r} days)"
        )
    return per


def output_steps(scene: Scene, every_days: float | None = None) -> set[int]:
    """Steps with an output: every output interval (default the scene's
    ``output.every_days``) from step 0 (t = 0, or a branch's day), and the last."""
    every_days = scene.output_every_days if every_days is None else every_days
    every = every_days * DAY / scene.dt
    n_out = math.floor(scene.run_days / every_days + 1e-9)
    return {min(scene.nsteps, round(k * every)) for k in range(n_out + 1)} | {scene.nsteps}


def restart_steps(scene: Scene, every_days: float) -> set[int]:
    """Steps at which a run with ``--restart-every every_days`` writes its restart
    file (and the last step). Raises ValueError unless dt divides the interval."""
    per = steps_of(scene, every_days, "restart interval")
    return set(range(per, scene.nsteps + 1, per)) | {scene.nsteps}


def next_multiple(step: int, every: int) -> int:
    """The first multiple of ``every`` after ``step``."""
    return (step // every + 1) * every
