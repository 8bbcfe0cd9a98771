"""
A sweep: the error against the time step
========================================

What a time integrator costs in accuracy: ``swe_sphere.studies.sweep`` runs one scene with
several steppers at several Δt on one grid and scores each run twice, by its total error
(against the case's exact solution) and by its temporal error (against a run of the same
grid at a quarter of the smallest Δt). The command line does the same with ``swe-sphere
sweep``.
"""

# %%
# Plan and run the sweep
# ----------------------
# Williamson's case 2 (steady geostrophic flow, exact solution known) on ne 4 np 4 for one
# day; three explicit steppers, each at 0.25, 0.5, 1 and 1.5 times the explicit gravity-wave limit
# Δt_g (``courant``; a multiple runs at the largest Δt at or below it that divides the day).
# ``plan`` checks the options and runs nothing; ``Plan.run`` makes the runs and writes the
# sweep's tables and figures into a folder (a temporary one here).
import tempfile

import matplotlib.pyplot as plt

from swe_sphere.studies import sweep

STEPPERS = ["ssprk3", "rk4", "kgu35"]
plan = sweep.plan("tc2_steady", ne=4, np_=4, days=1, steppers=STEPPERS, courant=[0.25, 0.5, 1, 1.5])
with tempfile.TemporaryDirectory() as folder:
    rows, info, paths = plan.run(folder)
print(f"spatial error of h (the grid's own): {info['spatial_error']:.3e}")

# %%
# Temporal error against Δt
# -------------------------
# Each stepper's temporal error falls with Δt at its order (3 for SSP-RK3, 4 for RK4, 3 for
# KGU35 on a nonlinear problem); all of them lie far below the grid's spatial error (the
# reference run's error against the exact solution, dotted), so on this coarse grid the
# total error is the grid's and the cheapest stable run wins. A stepper missing at the
# largest multiple was unstable there.
fig, ax = plt.subplots(figsize=(7.5, 4.5))
for stepper in STEPPERS:
    mine = sorted((r for r in rows if r["stepper"] == stepper and r["stable"]), key=lambda r: r["dt"])
    ax.loglog([r["dt"] for r in mine], [r["temporal_error"] for r in mine], "o-", label=stepper)
ax.axhline(info["spatial_error"], color="grey", ls=":", label="spatial error of the grid")
ax.set(
    xlabel="Δt (s)",
    ylabel="normalized l2 error of h",
    title="TC2, ne4 np4, 1 day: temporal error (against RK4 at a quarter of the smallest Δt)",
)
ax.grid(True, which="both", alpha=0.3)
ax.legend()
