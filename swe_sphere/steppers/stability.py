"""A stepper's stability limit read against a state's Courant numbers (``Stepper.courant_limit``
and ``advective_courant_limit``: the limit measured, or a table's from its stability polynomial)
and the one-line warning where Δt passes it: a run's ``Simulation.stability_warning`` and
``largest_dt_within_limit``, for each member (``members.members.Members``)."""

from __future__ import annotations

import math


def stability_limit(stepper, c: dict) -> tuple[float, str, float, str] | None:
    """(limit, what it limits, its value at the run's dt for the Courant numbers ``c`` (a
    ``model.diagnostics.courant_numbers`` dict), its source) of ``stepper``'s stability limit,
    measured or a table's from its stability polynomial (``Stepper.courant_limit`` on
    (|v| + √(gh)) Δt/Δx for explicit steppers, ``advective_courant_limit`` on |v| Δt/Δx for IMEX
    and multirate), or None without one."""
    if stepper.courant_limit is not None:  # the instance's: a table's limit is its own (``TableauRK``)
        speed = c["courant_advective"] + (0.0 if math.isnan(c["courant_gravity"]) else c["courant_gravity"])
        return stepper.courant_limit, "a Courant number (|v| + sqrt(g h)) dt/dx", speed, stepper.courant_limit_source
    if stepper.advective_courant_limit is not None:
        source = "its explicit advection's, measured on TC5, TC6 and Galewsky"
        return stepper.advective_courant_limit, "an advective Courant number |v| dt/dx", c["courant_advective"], source
    return None


def stability_line(stepper, options: dict, limit: tuple | None, dt: float) -> str | None:
    """The one-line warning of a ``stability_limit`` ``limit`` of ``stepper`` (its scene's
    ``options`` name a table) at ``dt`` (s), None where the limit is kept or there is none."""
    if limit is None or limit[2] <= limit[0]:
        return None
    limit, what, speed, source = limit
    name = stepper.label(options)  # a table by its name
    if limit == 0:
        return (
            f"warning: {name} is stable on no stretch of the imaginary axis (its stability polynomial "
            "has |R(iy)| > 1 for every y > 0): waves grow at every dt, held back only by hyperviscosity; it "
            "may blow up (three-stage third-order tables are stable to y = 1.73)"
        )
    return (
        f"warning: dt = {dt:g} s gives {what} of {speed:.3g}, above "
        f"{name}'s stability limit of about {limit:.3g} ({source}); it may blow up "
        f"(dt <= {dt * limit / speed:.4g} s keeps below)"
    )
