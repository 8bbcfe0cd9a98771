"""
The first run: Williamson's case 5, flow over a mountain
========================================================

The bundled scene ``tc5_mountain`` (Williamson et al. 1992, case 5: a zonal flow meets a
conical mountain 2000 m high at 30° N, 90° W) run for a few days in Python, its height map
drawn from each element's own GLL polynomial, and its invariants and errors read off the
returned dataset. The command line does the same with ``swe-sphere run tc5_mountain`` and
``swe-sphere plot``.
"""

# %%
# Run the scene
# -------------
# ``swe_sphere.run`` takes a bundled scene's name (or a TOML file) and any of its values as
# keywords; here a coarse grid (ne 4: 4 × 4 elements on each of the cube's six faces, np 4 GLL
# points a direction) and two days, so that it runs in seconds. The scene's stepper, Δt and
# ∇⁴ coefficient scale to the grid by its own rules. The result is an ``xarray.Dataset`` on
# the unique GLL nodes (``ncol``) at each output time (model days).
import matplotlib.pyplot as plt

import swe_sphere
from swe_sphere.studies.plotting import plot_map, plot_series

ds = swe_sphere.run("tc5_mountain", ne=4, days=2)
print(ds)

# %%
# The height of the free surface
# ------------------------------
# ``plot_map`` draws one field at one output day on a regular latitude-longitude grid and
# returns the matplotlib figure (and the colour scale's range). ``h_surface`` is h + hs, the
# height of the free surface above the sphere (m); the mountain shows as the closed contours
# downstream of 90° W.
shown = plot_map(ds, "h_surface", 2.0)
plt.figure(shown["figure"])  # handed to pyplot, which shows it (and the gallery captures it)

# %%
# Mass, energy and enstrophy
# --------------------------
# The run stores the relative change of the invariants at every output time: the
# spectral-element method conserves mass to round-off, and total energy and potential
# enstrophy decay slowly under the ∇⁴ hyperviscosity. ``plot_series`` draws them beside the
# normalized errors against the case's reference solution.
plt.figure(plot_series(ds))
