"""
Galewsky's barotropically unstable jet
======================================

The ``galewsky`` scene (Galewsky, Scott & Polvani 2004, Tellus 56A, 429): a zonal jet at
45° N in balance, with a small bump in the height that sets off a barotropic instability.
Over a few days the jet rolls up into vortices; the relative vorticity shows it best.
"""

# %%
# Run it
# ------
# The scene's own grid is ne 12 np 8; here ne 6 (np 8) for the gallery, five days,
# a state a day. The scene's Δt and ∇⁴ coefficient follow the grid by its rules.
import matplotlib.pyplot as plt

import swe_sphere
from swe_sphere.studies.plotting import plot_map

ds = swe_sphere.run("galewsky", ne=6, days=5)

# %%
# The vorticity in the northern hemisphere
# ----------------------------------------
# ``plot_map`` with ``lat_range=(0, 90)`` draws the band of Galewsky et al.'s Fig. 4 (their
# day 6 at T341; a coarse grid rolls the jet up later and smoother). Contours every 2e-5 s⁻¹.
# sphinx_gallery_thumbnail_number = 2
for day in (1.0, 5.0):
    plt.figure(plot_map(ds, "vorticity", day, lat_range=(0, 90))["figure"])

# %%
# The jet's zonal mean
# --------------------
# ``swe_sphere.zonal_mean`` averages a field over longitude at each output time: the zonal
# wind's maximum stays near 45° N but weakens and broadens as the growing eddies take the
# jet's energy (and, on a grid this coarse, the ∇⁴ takes a share of it).
u = swe_sphere.zonal_mean(ds, "u")
fig, ax = plt.subplots(figsize=(7, 4))
for day in (0.0, 5.0):
    line = u.sel(time=day)
    ax.plot(line["lat"], line, label=f"day {day:g}")
ax.set(xlabel="latitude (°)", ylabel="zonal-mean u (m s⁻¹)", title="Galewsky's jet, ne6 np8")
ax.grid(True, alpha=0.3)
ax.legend()
