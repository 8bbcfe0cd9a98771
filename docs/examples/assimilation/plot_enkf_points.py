"""
An ensemble smoother beside 4D-Var
==================================

The problem of the 4D-Var example (Galewsky's bump sought from h at points every three
hours) solved by an ensemble of forecasts instead of a gradient: ES-MDA, the ensemble
smoother with multiple data assimilation (Emerick & Reynolds 2013, Computers & Geosciences
55, 3, eqs. 5–8). The members run together in the same kernel launches
(``swe_sphere.Simulation`` with ``members``).
"""

# %%
# The problem and the prior ensemble
# ----------------------------------
# The same truth, observations and background as the 4D-Var example (``_assimilation.setting``:
# ne 4, 12 hours, 150 points every 3 hours, σ = 0.1 m). N = 32 initial heights are drawn from
# the 4D-Var example's background, h0_k = h_b + G z_k with z_k ~ N(0, I) (B = G Gᵀ: L = 1000 km,
# σ_b = 3 m, L_h = 100 m, correlations along the jet's height contours); the wind is the
# balanced jet's.
import matplotlib.pyplot as plt
import numpy as np
from _assimilation import background_root, gaspari_cohn, relative_error, setting, unit_xyz

from swe_sphere import Simulation

NE, HOURS, POINTS, MEMBERS, UPDATES = 4, 12.0, 150, 32, 4
s = setting(NE, 4, HOURS, 3.0, POINTS, sigma=0.1, seed=0)
grid, first, H = s.grid, s.grid.first, s.cost.operator
h_true, h_b = s.truth[2][first], s.guess[2][first]
error = relative_error(grid, h_true, h_b)  # 1 for the background, 0 for the truth
rng = np.random.default_rng(100)
G = background_root(grid, 1.0e6, 3.0, h_b, 100.0)
X = h_b[:, None] + G @ rng.standard_normal((grid.nunique, MEMBERS))  # (n_unique, N) initial heights


def forecast(X):
    """The predicted observations (M·K, N) of the members' initial heights X (n_unique, N)."""
    states = np.repeat(s.guess[None], X.shape[1], axis=0)
    states[:, 2] = X.T[:, grid.gid]  # each unique node's value to every element copy of it
    ensemble = Simulation(s.scene, members=X.shape[1], initial=states, progress=False)
    predicted = []
    for k in s.cost.at_steps:
        ensemble.run(None, until_step=k)
        predicted.append(np.stack([H(h) for h in ensemble.states()[:, 2]], axis=1))
    return np.concatenate(predicted)


# %%
# The updates
# -----------
# Each of the four updates runs the ensemble over the window, reads its heights at the points,
# and moves every member with all the observations at once:
#
# .. code-block:: text
#
#     h₀,k ← h₀,k + C_xy (C_yy + α R)⁻¹ (y + √α σ ε_k − H(h_k)),    R = σ² I,
#
# C_xy and C_yy the ensemble's covariances (of h0 with the predicted observations, and of
# those among themselves), tapered by Gaspari & Cohn's (1999) function of distance with a
# half-width of 1000 km, and α = 4, the number of updates (Σ 1/α = 1).
y = np.concatenate([s.cost.values[k] for k in s.cost.at_steps])
times = len(s.cost.at_steps)
nodes, points = unit_xyz(grid.lat[first], grid.lon[first]), unit_xyz(H.lat, H.lon)
c = 1.0e6 / grid.radius  # the half-width on the unit sphere
rho_xy = np.tile(gaspari_cohn(np.linalg.norm(nodes[:, None] - points[None], axis=2), c), (1, times))
rho_yy = np.tile(gaspari_cohn(np.linalg.norm(points[:, None] - points[None], axis=2), c), (times, times))


def spread(X):
    """The area-weighted RMS of the members' standard deviation of h(0) (m)."""
    return float(np.sqrt(np.sum(grid.area * X.var(axis=1, ddof=1)) / grid.area.sum()))


errors, spreads, alpha = [error(X.mean(axis=1))], [spread(X)], float(UPDATES)
for _ in range(UPDATES):
    Y = forecast(X)
    A, D = X - X.mean(axis=1, keepdims=True), Y - Y.mean(axis=1, keepdims=True)
    Cyy = (D @ D.T) / (MEMBERS - 1) * rho_yy + alpha * 0.1**2 * np.eye(y.size)
    Cxy = (A @ D.T) / (MEMBERS - 1) * rho_xy
    perturbed = y[:, None] + np.sqrt(alpha) * 0.1 * rng.standard_normal((y.size, MEMBERS))
    X = X + Cxy @ np.linalg.solve(Cyy, perturbed - Y)
    errors.append(error(X.mean(axis=1)))
    spreads.append(spread(X))
for i, (e, sp) in enumerate(zip(errors, spreads)):
    print(f"{'background' if i == 0 else f'update {i}':>10}: l2 error / bump {e:.3f}, spread {sp:.3f} m")

# %%
# Error and spread against the updates
# ------------------------------------
# The ensemble mean's error of h(0) relative to the bump (1: the background) and the
# ensemble's spread. The first update takes most of what the data give; 32 members (fewer
# than the observations) leave the smoother short of 4D-Var's gradient on the same data
# (the 4D-Var example's error), and its spread says how sure it is.
fig, ax = plt.subplots(figsize=(7, 4))
ax.plot(range(UPDATES + 1), errors, "o-", label="l2 error of the mean h(0) / bump")
ax.set(xlabel="ES-MDA update", ylabel="relative l2 error", title=f"ES-MDA, {MEMBERS} members")
ax.grid(True, alpha=0.3)
twin = ax.twinx()
twin.plot(range(UPDATES + 1), spreads, "s--", color="tab:orange", label="spread of h(0)")
twin.set_ylabel("spread of h(0) (m)")
fig.legend(loc="upper right", bbox_to_anchor=(0.88, 0.88))

# %%
# The mean increment
# ------------------
# The ensemble mean's h(0) − h_b after the last update, beside the truth's bump.
lat, lon = np.degrees(grid.lat[first]), np.degrees(grid.lon[first])
lon = np.where(lon > 180.0, lon - 360.0, lon)
north = lat > 0
fig, axes = plt.subplots(2, 1, figsize=(10, 6.5), sharex=True)
levels = np.linspace(-120.0, 120.0, 25)
for ax, field, title in ((axes[0], h_true - h_b, "the truth's bump"), (axes[1], X.mean(axis=1) - h_b, "ES-MDA mean")):
    filled = ax.tricontourf(lon[north], lat[north], field[north], levels=levels, cmap="RdBu_r", extend="both")
    ax.set(ylabel="latitude (°)", title=f"h(0) − h_b: {title}")
axes[1].set_xlabel("longitude (°)")
fig.colorbar(filled, ax=axes, label="m")
