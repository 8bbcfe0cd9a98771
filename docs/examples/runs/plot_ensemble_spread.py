"""
How an ensemble's spread grows
==============================

N members of Galewsky's jet, each from the case's jet and bump with 1 m of seeded white
noise in the height (``swe_sphere.Perturbation``), run together
(``swe_sphere.Simulation`` with ``members``: one driver, member k the bits of its single
run). The run file holds every member and their mean and spread; the spread's RMS shows how
fast small errors grow on the unstable jet.
"""

# %%
# Run the members
# ---------------
# Eight members on ne 4 (np 8, the scene's) for four days, a state every six hours, written
# to a run file (in a temporary folder). The command line does the same with ``swe-sphere run
# galewsky --members 8 --perturbation 1``.
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

from swe_sphere import Perturbation, Simulation

MEMBERS, DAYS = 8, 4.0
folder = tempfile.TemporaryDirectory()
path = Path(folder.name) / "galewsky_spread.nc"
ensemble = Simulation(
    "galewsky",
    members=MEMBERS,
    initial=Perturbation(1.0, seed=0),
    ne=4,
    days=DAYS,
    progress=False,
    **{"output.every_days": 0.25},
)
ensemble.run(path)
ds = xr.load_dataset(path, decode_times=False)  # time in model days
folder.cleanup()
print(ds[["h_mean", "h_spread", "h_spread_rms"]])

# %%
# The spread's growth
# -------------------
# ``h_spread_rms`` is the area-weighted RMS of the members' standard deviation of h. The
# white noise's grid-scale part is damped by the ∇⁴ within hours; then the spread that
# projects on the jet's instability grows exponentially. The e-folding time is fitted over
# the second half of the run.
days, rms = ds["time"].values, ds["h_spread_rms"].values
late = days >= days[-1] / 2
rate = np.polyfit(days[late], np.log(rms[late]), 1)[0]
print(f"e-folding time over days {days[late][0]:g}-{days[-1]:g}: {1 / rate:.2f} days")
fig, ax = plt.subplots(figsize=(7.5, 4))
ax.semilogy(days, rms, "o-", ms=3, label="RMS spread of h")
ax.semilogy(
    days[late],
    np.exp(np.polyval(np.polyfit(days[late], np.log(rms[late]), 1), days[late])),
    "k--",
    label=f"e-folding {1 / rate:.2f} days",
)
ax.set(xlabel="model day", ylabel="RMS spread of h (m)", title=f"Galewsky, {MEMBERS} members from h + 1 m of noise")
ax.grid(True, which="both", alpha=0.3)
ax.legend()

# %%
# The mean and the spread on the last day
# ---------------------------------------
# The ensemble mean of h and its spread at the unique nodes of the northern hemisphere: the
# spread sits where the jet is unstable.
lat, lon = ds["lat"].values, ds["lon"].values
north = (lat > 0) & (lat < 85)  # a triangulation in longitude-latitude: off the pole
fig, axes = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
for ax, name, label, cmap in (
    (axes[0], "h_mean", "ensemble mean of h", "viridis"),
    (axes[1], "h_spread", "spread of h", "magma"),
):
    filled = ax.tricontourf(lon[north], lat[north], ds[name].values[-1][north], levels=24, cmap=cmap)
    ax.set(ylabel="latitude (°)", title=f"{label}, day {days[-1]:g}")
    fig.colorbar(filled, ax=ax, label="m")
axes[1].set_xlabel("longitude (°)")
