"""
ν fitted to a spectral reference
================================

The ∇⁴ hyperviscosity's coefficients are a choice (HOMME scales ν with the grid spacing; this
model takes them from an e-folding time). With ``swe_sphere.gradient(..., parameters=True)``
they can be fitted instead: here the factors on the scene's own ν (wind) and ν_s (surface)
that bring TC5's h + hs closest, after a day, to the bundled T341 spectral reference.
"""

# %%
# The cost
# --------
# TC5 on ne 4 np 4 (its stepper and Δt at that grid) for one day, a day the reference stores.
# The unknowns are p = (log s, log s_s): ν = ν_div = s ν₀ and ν_s = s_s ν₀ₛ, ν₀ and ν₀ₛ the
# scene's own. The cost is half the mean square misfit of h + hs against the reference's,
#
# .. code-block:: text
#
#     J(p) = ½ (1 / 4πa²) ∫ (h(T; p) + hs − (h + hs)_ref(T))² dA
#
# and one ``gradient`` call gives J with ∂J/∂ν and ∂J/∂ν_s, so dJ/dp = (s ν₀ ∂J/∂ν, s_s ν₀ₛ ∂J/∂ν_s).
import dataclasses
import math

import matplotlib.pyplot as plt
import numpy as np
import scipy.optimize

import swe_sphere
from swe_sphere.cases.reference import Reference, reference_path

NE, DAYS, TRUNCATION = 4, 1.0, "T341"
scene = swe_sphere.load_scene("tc5_mountain", ne=NE, np_=4, days=DAYS)
steps = round(DAYS * 86400.0 / scene.dt)
sim = swe_sphere.Simulation(scene, progress=False)  # built, not run: its grid and surface height
grid, hs = sim.grid, sim.hs
surface = Reference(reference_path(scene.make_case(), TRUNCATION)).at(DAYS, grid.lat, grid.lon)["h_surface"]
misfit = swe_sphere.HeightMisfit(surface - hs)  # the misfit of h against (h + hs)_ref − hs
total = grid.spheremp.sum()  # 4πa²
norm = math.sqrt(float(np.sum(grid.spheremp * surface**2)))


def with_nu(s, s_s):
    """The scene with ν = ν_div scaled by s and ν_s by s_s."""
    return dataclasses.replace(scene, nu=s * scene.nu, nu_div=s * scene.nu_div, nu_s=s_s * scene.nu_s)


def cost(p):
    """(J (m²), dJ/dp, Williamson's normalised l2 of h + hs) at p = (log s, log s_s)."""
    s, s_s = np.exp(p)
    g = swe_sphere.gradient(with_nu(s, s_s), steps, misfit, parameters=True)
    dJ = np.array([s * scene.nu * g.d_nu, s_s * scene.nu_s * g.d_nu_s]) / total
    return g.cost / total, dJ, math.sqrt(2.0 * g.cost) / norm


# %%
# The landscape and the fit
# -------------------------
# J along s = s_s (one gradient each), then L-BFGS-B over both factors, each in [0.05, 20].
# On this coarse grid the fit takes the wind's ∇⁴ down to its bound and raises the
# surface's: the scene's rule damps a grid this coarse harder than T341's own diffusion does
# the fields it resolves. The fit is of this grid and day; at ne 16 (``NE``) it is another.
ladder = [0.25, 0.5, 1.0, 2.0, 4.0, 8.0]
landscape = [cost(np.log([s, s])) for s in ladder]
bounds = [(math.log(0.05), math.log(20.0))] * 2
result = scipy.optimize.minimize(
    lambda p: cost(p)[:2], np.zeros(2), jac=True, method="L-BFGS-B", bounds=bounds, options={"maxiter": 15}
)
s, s_s = np.exp(result.x)
start, fit = cost(np.zeros(2)), cost(result.x)
print(f"scene's ν = {scene.nu:.3e}, ν_s = {scene.nu_s:.3e} m⁴ s⁻¹: J {start[0]:.4e} m², l2 {start[2]:.4e}")
print(f"fitted  ν = {s * scene.nu:.3e}, ν_s = {s_s * scene.nu_s:.3e} m⁴ s⁻¹: J {fit[0]:.4e} m², l2 {fit[2]:.4e}")
print(f"{result.nit} iterations, {result.nfev} gradients; scipy: {result.message}")

fig, ax = plt.subplots(figsize=(7.5, 4.5))
ax.loglog([s * scene.nu for s in ladder], [row[0] for row in landscape], "o-", label="J along ν = ν_s (s = s_s)")
ax.loglog([scene.nu], [start[0]], "ks", ms=8, label="the scene's ν (its e-folding rule)")
ax.loglog([s * scene.nu], [fit[0]], "r*", ms=14, label=f"the fit (ν_s = {s_s * scene.nu_s:.2e})")
ax.set(xlabel="ν (m⁴ s⁻¹)", ylabel="J (m²)", title=f"TC5 ne{NE} np4, day {DAYS:g}, against {TRUNCATION}")
ax.grid(True, which="both", alpha=0.3)
ax.legend()
