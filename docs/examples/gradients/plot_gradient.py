"""
A gradient: where the initial height matters
============================================

``swe_sphere.gradient`` gives the derivative of a cost of a run with respect to the initial
state (and, with ``parameters=True``, to ν, ν_s, hs, g and Ω) by one forward and one reverse
sweep: the adjoint of each step, exact to round-off. Here the cost is the height at one point
after a day of TC5, so the gradient is that height's sensitivity to h(0) everywhere.
"""

# %%
# The cost: h at one point at the end
# -----------------------------------
# ``PointHeights`` reads h at points (latitude and longitude in radians) from each element's
# GLL polynomial; ``HeightObservations`` makes a cost of the run from observations of it,
# J = ½ Σ (H h(k) − y_k)² / σ². With y = H h(T) − 1 m and σ = 1 m, dJ/dh(0) is the
# derivative of h at the point at day 1 with respect to h(0): its sensitivity.
import matplotlib.pyplot as plt
import numpy as np

import swe_sphere

scene = swe_sphere.load_scene("tc5_mountain", ne=6, np_=4, days=1.0)
steps = round(86400.0 / scene.dt)
sim = swe_sphere.Simulation(scene, progress=False)
sim.run(None)
grid = sim.grid
lat, lon = np.radians([40.0]), np.radians([-105.0])  # Boulder
H = swe_sphere.PointHeights(grid, lat, lon)
y = H(sim.states()[0, 2]) - 1.0  # states(): (members, 3, nodes), one member here
g = swe_sphere.gradient(scene, steps, swe_sphere.HeightObservations(H, {steps: y}, 1.0))
print(f"{scene.stepper}, {steps} steps of {scene.dt:g} s; J = {g.cost:.6f} (½ by construction)")

# %%
# The sensitivity map
# -------------------
# ``grad`` is in the mass inner product (δJ = Σ spheremp · grad · δx over the element-local
# nodes, spheremp the node's area weight), so ``grad[2]`` is dJ/dh(0) per unit area; times
# σ² / (H h − y) = 1 m it is ∂h(point, T)/∂h(0) per m² of the initial height, here drawn per
# 10⁶ km² at the unique nodes. It is largest not near the point but near its antipode
# (40° S, 75° E), a little west of it: gravity waves at √(gH) ≈ 240 m s⁻¹ cross half the
# sphere in about a day, and those from around the antipode all converge on the point. The
# westerly flow carries the pattern east while they travel.
first = grid.first
sens = g.grad[2][first] * 1.0 * 1e12  # × σ²/(H h − y) = 1 m; per 10⁶ km² (1e12 m²)
lat_n, lon_n = np.degrees(grid.lat[first]), np.degrees(grid.lon[first])
lon_n = np.where(lon_n > 180.0, lon_n - 360.0, lon_n)
limit = np.ceil(np.abs(sens).max() * 10.0) / 10.0  # a round colour scale
fig, ax = plt.subplots(figsize=(10, 5))
filled = ax.tricontourf(lon_n, lat_n, sens, levels=np.linspace(-limit, limit, 21), cmap="RdBu_r")
ax.plot(np.degrees(lon), np.degrees(lat), "k*", ms=12, label="the point (40° N, 105° W)")
ax.set(
    xlabel="longitude (°)",
    ylabel="latitude (°)",
    title="TC5, ne6 np4: the sensitivity of h at the point on day 1 to h(0)",
)
fig.colorbar(filled, ax=ax, label="m of h(point) per m of h(0) over 10⁶ km²")
ax.legend(loc="lower left")
