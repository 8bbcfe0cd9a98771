"""
The frontier: error against cost
================================

Which grid and stepper reach an accuracy cheapest? ``swe_sphere.studies.frontier`` runs a
sweep on every grid of a ladder (every ne × every np), each stepper at a fraction of its own
measured stability limit, and scores each run by its error at the last day and its CPU
seconds per simulated day. A run is on the front when no other is at least as cheap and as
accurate and better in one. The command line does the same with ``swe-sphere frontier``.
"""

# %%
# Plan and run
# ------------
# Williamson's case 2 for one day on ne 2 and 4, np 3 and 4; RK4 at 0.8 of its limit (the
# default fraction) and KGU35 at 0.5 of its. The runs go to a temporary folder; the rows come
# back, one a run.
import tempfile

import matplotlib.pyplot as plt

from swe_sphere.studies import frontier

plan = frontier.plan("tc2_steady", ne=[2, 4], np_=[3, 4], steppers=["rk4", "kgu35@0.5"], days=1)
with tempfile.TemporaryDirectory() as folder:
    rows, paths = plan.run(folder, device="cpu")
for row in sorted(rows, key=lambda r: r["cost_per_day"]):
    star = "*" if row["on_front"] else " "
    print(f"{star} {row['label']:>14}  error {row['error']:.3e}  {row['cost_per_day']:.4f} s a day")
cheapest = frontier.cheapest_for(rows, 1e-3)
print(f"the cheapest run with an error <= 1e-3: {cheapest['label'] if cheapest else None}")

# %%
# Error against cost
# ------------------
# The front joins the runs no other beats in both. On this small problem the grid decides the
# error (np 4 far below np 3 at the same nodes) and the stepper the cost; at a target error,
# read off the front the cheapest way to reach it. Costs are CPU seconds of the time loop on
# this machine, so the points move with the machine and its load; the errors do not.
fig, ax = plt.subplots(figsize=(8, 5))
for stepper, marker in (("rk4", "o"), ("kgu35", "s")):
    mine = [r for r in rows if r["stepper"] == stepper and r["stable"]]
    ax.loglog([r["cost_per_day"] for r in mine], [r["error"] for r in mine], marker, ls="", label=stepper)
front = sorted((r for r in rows if r["on_front"]), key=lambda r: r["cost_per_day"])
ax.loglog([r["cost_per_day"] for r in front], [r["error"] for r in front], "k-", lw=1, label="the front")
for r in front:  # the front's runs named; the others by their colour and place
    ax.annotate(
        f"ne{r['ne']} np{r['np']} {r['stepper']}",
        (r["cost_per_day"], r["error"]),
        fontsize=8,
        xytext=(4, 4),
        textcoords="offset points",
    )
ax.set(xlabel="CPU s per simulated day", ylabel="normalized l2 error of h at day 1", title="TC2: the frontier")
ax.grid(True, which="both", alpha=0.3)
ax.legend()
