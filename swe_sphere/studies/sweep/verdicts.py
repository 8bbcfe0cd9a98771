"""The sweep's table and verdicts: every run's row with every column (``COLUMN_ATTRS``, Δt as
multiples of the explicit limits, the cost on the clock it is ranked by), and per criterion,
threshold and stepper the cheapest stable run whose temporal error is within that fraction of
the spatial error ("sufficient accuracy", Evans, Taylor & Drake 2010: ≤ 10 %); beside each
spatial error the reference's own error (``reference.floor``), and a spatial error within
``FLOOR_MARGIN`` of it flagged: its verdicts are provisional."""

from __future__ import annotations

import math

from ...grid.quality import REGIONS

SUFFICIENT = 0.1  # temporal error ≤ 10 % of the spatial error
# the sweep info's spatial errors → the keys of the reference's own errors beside them
FLOOR_OF = {
    "spatial_error": "reference_floor",
    "spatial_error_vorticity": "reference_floor_vorticity",
    "spatial_error_divergence": "reference_floor_divergence",
}
FLOOR_MARGIN = 2.0  # a spatial error within this factor of the reference's own error is not the run's alone


def run_name(row: dict) -> str:
    """A row's run: its stepper, and under step control its tolerance ("bs32@rtol=1e-05")."""
    tol = row.get("tolerance", math.nan)
    return row["stepper"] + (f"={tol:g}" if math.isfinite(tol) else "")


def outcome(row: dict) -> str:
    """A finished run in a few words: its errors and CPU time, or why it is unstable
    (under step control its steps, rejected ones and mean Δt first)."""
    if math.isfinite(row.get("tolerance", math.nan)):
        head = f"{row['steps']} steps, {row['rejected_steps']} rejected, mean dt {row['dt']:.4g} s; "
        return head + outcome({**row, "tolerance": math.nan})
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
    "stepper": (None, "time stepper (STEPPER@KEY: steps chosen step to step, by the tolerance KEY)"),
    "tolerance": ("1", "the controlled run's rtol, balance or Courant number (NaN: a fixed dt)"),
    "dt": ("s", "time step (under step control the mean)"),
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
    "steps": ("1", "time steps taken (under step control the accepted ones)"),
    "rejected_steps": ("1", "steps rejected by the error control (NaN: a fixed dt)"),
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
    "tolerance",
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


def cheapest_sufficient(rows, spatial_error) -> dict:
    """Per stepper, the cheapest (``cost_time``) stable run whose temporal error ≤ 10 % of the spatial error."""
    best = {
        s: _cheapest(rows, s, "temporal_error", SUFFICIENT * spatial_error)
        for s in dict.fromkeys(r["stepper"] for r in rows)
    }
    return {s: r for s, r in best.items() if r is not None}
