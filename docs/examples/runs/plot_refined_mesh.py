"""
A stretched mesh: resolution where it is wanted
===============================================

A cubed sphere need not be uniform. The Schmidt transform stretches the cube's grid towards
a target point (here 30° N, 90° W: TC5's mountain), finer there and coarser at the
antipode, keeping every element's connectivity; ``swe-sphere mesh`` writes such a mesh (or a
cube refined over a latitude-longitude box) as an Exodus ``.g`` file, which any run takes
with ``mesh=``. The run's Δt and ∇⁴ scale to the mesh's smallest and mean node spacing.
"""

# %%
# Build and write the mesh
# ------------------------
# ``schmidt_cube(ne, stretch_factor, target_lat, target_lon)``: ne 4 with a stretch factor of
# 2 (the elements near the target half the size of the uniform cube's, those opposite twice).
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

import swe_sphere
from swe_sphere.mesh.mesh import write_exodus
from swe_sphere.mesh.schmidt import schmidt_cube

folder = tempfile.TemporaryDirectory()
mesh = Path(folder.name) / "stretched_4.g"
write_exodus(mesh, schmidt_cube(4, 2.0, target_lat=30.0, target_lon=270.0))

# %%
# Run TC2 on it
# -------------
# Williamson's case 2 (steady flow, exact solution known) for one day on the mesh and on the
# uniform ne 4 cube: the same number of elements, their sizes spread differently. The
# stretched run's error is the larger: it is mostly the error of the mesh's element-local
# map (each element's own bilinear map to the sphere, where the uniform cube uses the exact
# equiangular one), not of the resolution moved away from the flow's features; TC2's flow is
# smooth everywhere, so it gains nothing from a finer patch.
stretched = swe_sphere.run("tc2_steady", mesh=str(mesh), days=1)
uniform = swe_sphere.run("tc2_steady", ne=4, days=1)
for name, ds in (("stretched", stretched), ("uniform", uniform)):
    print(f"{name:>9}: l2 error of h at day 1 {float(ds['l2_h'].sel(time=1.0)):.3e}")

# %%
# The mesh seen from above its target
# -----------------------------------
# The element edges (each element's boundary GLL nodes) in an orthographic view centred on
# the target: the elements shrink towards the middle. ``Simulation`` builds the grid.
grid = swe_sphere.Simulation("tc2_steady", mesh=str(mesh), days=1, progress=False).grid
npts = 4  # the scene's np
lat = grid.lat.reshape(-1, npts, npts)
lon = grid.lon.reshape(-1, npts, npts)
p0, l0 = np.radians(30.0), np.radians(270.0)
x = np.cos(lat) * np.sin(lon - l0)
y = np.cos(p0) * np.sin(lat) - np.sin(p0) * np.cos(lat) * np.cos(lon - l0)
front = np.sin(p0) * np.sin(lat) + np.cos(p0) * np.cos(lat) * np.cos(lon - l0) > 0
fig, ax = plt.subplots(figsize=(6, 6))
ring = [(0, j) for j in range(npts)] + [(i, npts - 1) for i in range(npts)]
ring += [(npts - 1, j) for j in reversed(range(npts))] + [(i, 0) for i in reversed(range(npts))]
rows, cols = np.array(ring).T
for e in range(lat.shape[0]):
    if front[e][rows, cols].all():
        ax.plot(x[e][rows, cols], y[e][rows, cols], "k-", lw=0.6)
ax.add_patch(plt.Circle((0, 0), 1.0, fill=False, color="grey"))
ax.plot(0, 0, "r*", ms=12, label="target: 30° N, 90° W")
ax.set(aspect="equal", xlim=(-1.05, 1.05), ylim=(-1.05, 1.05), title="Schmidt-stretched ne4 cube, factor 2")
ax.set_axis_off()
ax.legend(loc="lower left")

# %%
# Where the error is
# ------------------
# TC2 is steady, so h at day 1 minus h at day 0 is the run's error, here at the unique nodes
# of both runs on one colour scale. On the uniform cube it is smallest and spread over the
# flow; on the stretched mesh it is largest where the elements are coarsest, opposite the
# target, and along the elements' edges, where the element-local map is least accurate.
fig, axes = plt.subplots(1, 2, figsize=(12, 4), sharey=True)
errors = {
    name: ds["h"].sel(time=1.0).values - ds["h"].sel(time=0.0).values
    for name, ds in (("stretched", stretched), ("uniform", uniform))
}
limit = 5.0 * np.ceil(max(np.abs(e).max() for e in errors.values()) / 5.0)  # m, a round scale
for ax, (name, ds) in zip(axes, (("stretched", stretched), ("uniform", uniform))):
    lon_n = np.where(ds["lon"].values > 180.0, ds["lon"].values - 360.0, ds["lon"].values)
    filled = ax.tricontourf(lon_n, ds["lat"].values, errors[name], levels=np.linspace(-limit, limit, 21), cmap="RdBu_r")
    ax.set(xlabel="longitude (°)", title=f"TC2 h(day 1) − h(day 0), {name} ne4 np4")
axes[0].set_ylabel("latitude (°)")
fig.colorbar(filled, ax=axes, label="m")
folder.cleanup()
