"""Round-off bounds that scale with what they accumulate (the ``roundoff`` tests).

A quantity that is zero or equal in exact arithmetic (a mass change, two layouts'
or rank counts' states, a table against a built-in) differs by round-off, whose
size depends on the CPU: its FMA contraction and vector width change which
products are rounded and the order of sums. A bound tuned to one machine fails
on the next, so each bound here is a count of roundings times ε times the size
of what is rounded, ``roundings · ε · scale`` (ε = 2.2e-16, float64's machine
epsilon), with the count argued where the bound is used. Worst-case counts add
(no √n random walk), so the bound holds on any CPU. Where a solver amplifies
round-off (Krylov iterations, forward-difference J·v), ε is replaced by the run's
own round-off floor, measured in the test: how far the same run ends from a start
one rounding away (``nudged``). A real defect (a term that does not conserve, a
wrong coefficient, a missing halo) is orders of magnitude above either.
``within`` asserts and records each comparison; ``pytest -m roundoff`` prints the
records (measured, bound) at the end.
"""

from __future__ import annotations

import math
import os

import numpy as np

EPS = float(np.finfo(np.float64).eps)

RECORDS: list[tuple[str, str, float, float]] = []  # (test, what, measured, bound), for the terminal summary


def bound(roundings: float, scale: float = 1.0) -> float:
    """``roundings`` roundings of at most ε·``scale`` each, added: roundings · ε · scale."""
    return roundings * EPS * scale


def mass_change_bound(updates: int, nnodes: int) -> float:
    """What a relative mass change Σ spheremp·h / Σ spheremp·h₀ − 1 can hold in
    round-off: each update of the depth rounds every node by ≤ ε|h| (h > 0, so
    ≤ ε of the mass), ``updates`` of them added; and the two integrals, numpy's
    pairwise sums of ``nnodes`` positive terms, ≤ ⌈log2 nnodes⌉ ε each."""
    return bound(updates + 2 * math.ceil(math.log2(nnodes)))


def operator_roundings(np_: int, passes: int = 1) -> int:
    """Roundings a node may differ by between a kernel and the numpy reference of the
    same operator (the same sums in another order, FMA contraction), relative to the
    largest value. Per pass (a derivative with its metric, a DSS, an update): a
    derivative Σ_m dvv[i,m] f_m rounds ≤ 2np times Σ_m |dvv[i,m] f_m| ≤ (np²/2) max |f|:
    np³ ε of max |f| (the 2×2 metric products and the DSS's ≤ 4 copies add far less
    than this worst case leaves; measured ≤ np² at np = 4 and 7)."""
    return np_**3 * passes


def operations(d) -> int:
    """RHS evaluations and solver iterations (Newton, GMRES, CG, Krylov, ...) of a
    ``RunResult`` or of one of its outputs (``rhs_evals``, ``<solver>_iterations``):
    the updates a stepper's depth may take round-off from, one each."""
    if not isinstance(d, dict):
        d = {"rhs_evals": d.rhs_evals, **{f"{k}_iterations": v for k, v in d.iterations.items()}}
    return int(d["rhs_evals"] + sum(v for k, v in d.items() if k.endswith("_iterations")))


def mass_kept(history: list[dict], nnodes: int, updates=operations) -> None:
    """Every output of a run (``RunResult.history``) keeps its mass to round-off:
    |mass change| ≤ ``mass_change_bound(updates(output), nnodes)``, ``updates`` the
    depth's updates up to that output (default: ``operations``). Records the output
    nearest its bound."""

    def limit(d):
        return mass_change_bound(updates(d), nnodes)

    worst = max(history, key=lambda d: (abs(d["mass_change"]) / limit(d), d["steps"]))  # ties (all zero): the last
    within(
        abs(worst["mass_change"]), limit(worst), f"|mass change| at step {worst['steps']} ({updates(worst)} updates)"
    )


def run_file_history(ds) -> list[dict]:
    """A run file's (or a sweep table's) outputs as ``mass_kept``'s history: mass_change,
    rhs_evals, steps and the solvers' iterations (a sweep's NaN where a stepper has no such solver: 0)."""
    names = ["mass_change", "rhs_evals", "steps", *(k for k in ds.keys() if str(k).endswith("_iterations"))]
    return [
        dict(zip(names, (float(v) if k == "mass_change" else int(np.nan_to_num(v)) for k, v in zip(names, row))))
        for row in zip(*(ds[k] for k in names))
    ]


def nudged(x: np.ndarray, grid, rng) -> np.ndarray:
    """An element-local state (3, N) with each unique node's values moved by ±ε relative
    (a rounding of every node; still continuous): the start of a run's round-off floor."""
    return x * (1 + EPS * rng.choice((-1.0, 1.0), (3, grid.nunique))[:, grid.gid])


def state_difference(a: np.ndarray, ref: np.ndarray) -> tuple[float, float]:
    """max |Δ wind| / max |wind| and max |Δh| / max |h| of two (u, v, h) states (``ref``'s maxima)."""
    wind = np.hypot(a[0] - ref[0], a[1] - ref[1]).max() / np.hypot(ref[0], ref[1]).max()
    return float(wind), float(np.abs(a[2] - ref[2]).max() / np.abs(ref[2]).max())


def within(measured: float, limit: float, what: str = "") -> None:
    """Assert ``measured`` ≤ ``limit`` (NaN fails) and record both for ``-m roundoff``'s summary."""
    test = os.environ.get("PYTEST_CURRENT_TEST", "?").split(" (")[0]
    RECORDS.append((test, what, float(measured), float(limit)))
    assert measured <= limit, f"{what}: {measured:.3e} > round-off bound {limit:.3e} ({measured / limit:.2f}x)"
