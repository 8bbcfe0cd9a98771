"""
Case 7: a run from a reanalysis state
=====================================

Williamson et al. (1992) case 7 starts the shallow-water equations from an analysed 500 hPa
height and wind. The bundled scene ``tc7_era_july`` reads ERA-Interim's July-mean 500 hPa
state (``testcases/data/eraint_july_500hPa.nc``, 0.75°), analyses it into spherical
harmonics at the degree both the file and the grid resolve, and synthesises it at the
model's nodes; any lat-lon netCDF file of height and wind runs the same way
(``swe_sphere.run("state.nc")``).
"""

# %%
# The file and the run
# --------------------
# The state on its own grid, read with xarray; then the scene on ne 8 np 4 (its own grid is
# ne 30) for two days.
from importlib.resources import files

import matplotlib.pyplot as plt
import xarray as xr

import swe_sphere
from swe_sphere.studies.plotting import plot_map

state = xr.open_dataset(files("swe_sphere.testcases") / "data" / "eraint_july_500hPa.nc")
print(state)
ds = swe_sphere.run("tc7_era_july", ne=8, days=2)

# %%
# The 500 hPa height, days 0 and 2
# --------------------------------
# h + hs (here hs = 0) from each element's GLL polynomial: the summer hemisphere's weak
# gradients in the north, the winter jet's tight ones in the south.
for day in (0.0, 2.0):
    plt.figure(plot_map(ds, "h_surface", day)["figure"])

# %%
# The relative vorticity on day 2
# -------------------------------
# The analysed state's small scales: what the grid resolves of them, and what the ∇⁴ (a
# 6-hour e-folding time at the grid's Nyquist degree) leaves after two days.
plt.figure(plot_map(ds, "vorticity", 2.0)["figure"])
