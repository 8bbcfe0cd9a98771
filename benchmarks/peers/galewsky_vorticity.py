"""Why pySEs is more accurate than us on Galewsky at ne16 np4 (issue 63, item 3): the grid.

pySEs's "quasi-uniform" cube is the gnomonic equidistant cube (its element corners equally
spaced on the cube's faces: ``mesh.equidistant``), ours the equiangular one. With the same
operators, the discrete vorticity of the exact wind at t = 0 is then pySEs's on its cube and ours
on ours, and the jet, along the cube edges (35–45° N) where the equidistant cube is about 1.5×
finer, is resolved better there; TC2's smooth flow worse.

Printed, side by side for each cube (``[grid] cube``) at ``--ne`` (default 16), np 4:
- the t = 0 vorticity error: the model's vorticity + DSS of the case's exact wind at the nodes
  against the analytic ζ (normalized l2, area integral with ``spheremp``), for Galewsky's jet
  and TC2's flow;
- unless ``--no-runs``: Galewsky's day-6 vorticity error against the T341 reference
  (``ref_l2_vorticity``: the model's vorticity of v − v_ref, normalized by the reference's
  velocity-gradient scale) at pySEs's settings of issue 63 (kgu35, Δt 150 s, ν = 1.76e15 m⁴/s,
  the 3 h e-folding rule at ne16), and the CPU seconds of each run (``time.process_time``);
- where pySEs is installed (``--pyses``, default ~/.venvs/pyses/bin/python; install line
  ``python -m venv ~/.venvs/pyses && ~/.venvs/pyses/bin/pip install pyses jax``), in a
  subprocess: pySEs's own t = 0 errors (its grid, ``horizontal_vorticity``, its projection), the
  range of its node longitudes and the mean depth of its own Galewsky h — the two ways its
  set-up is another case (the bump's western half lost to longitudes in [0, 2π); h(−π/2) =
  10 km rather than the mean).

    SWE_SPHERE_THREADS=1 python benchmarks/peers/galewsky_vorticity.py [--ne 16] [--no-runs]
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import swe_sphere  # noqa: E402
from swe_sphere import (
    CubedSphere,  # noqa: E402
    ShallowWater,  # noqa: E402
)

wp.config.quiet = True  # Warp < 1.10; newer Warp reads log_level (as tests/conftest.py)
if hasattr(wp, "LOG_WARNING"):
    wp.config.log_level = wp.LOG_WARNING

CUBES = ("equiangular", "equidistant")
TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]

# pySEs's side, run by its own interpreter: its grid and operators on the same winds.
PYSES = r"""
import json, math, sys
import numpy as np
import jax
jax.config.update("jax_enable_x64", True)
from pyses.grids import init
from pyses.operations_2d.operators import horizontal_vorticity
from pyses.operations_2d.local_assembly import project_scalar_wrapper
from pyses.analytic_initialization import galewsky_init as gi
ne = int(sys.argv[1])
grid, dims = init.init_quasi_uniform_grid(ne, 4)
a, om, g = 6.37122e6, 7.292e-5, 9.80616
lat, lon = (np.asarray(grid["physical_coords"][..., k]) for k in (0, 1))
w = np.asarray(grid["mass_matrix"])
cfg = gi.init_galewsky_config({"radius_earth": a, "angular_freq_earth": om, "gravity": g})
u = np.asarray(gi.eval_galewsky_u(lat, cfg))
lat0, lat1 = cfg["phi0"], cfg["phi1"]
inside = (lat > lat0) & (lat < lat1)
q = np.where(inside, (lat - lat0) * (lat - lat1), 1.0)
dudphi = np.where(inside, -u * (2 * lat - lat0 - lat1) / q**2, 0.0)
u0 = 2 * math.pi * a / (12 * 86400)
out = {"lon_min": float(lon.min()), "lon_max": float(lon.max())}
for name, (uu, zt) in {"jet": (u, -(dudphi - u * np.tan(lat)) / a),
                       "tc2": (u0 * np.cos(lat), 2 * u0 / a * np.sin(lat))}.items():
    z = np.asarray(project_scalar_wrapper(horizontal_vorticity(np.stack([uu, 0 * uu], -1), grid, a=a), grid, dims))
    out[name] = math.sqrt(np.sum(w * (z - zt) ** 2) / np.sum(w * zt**2))
phi = np.linspace(-math.pi / 2, math.pi / 2, 4001)
h = np.asarray(gi.eval_galewsky_h(phi, 0 * phi + math.pi, cfg))  # far from the bump
out["mean_depth"] = float(0.5 * np.trapezoid(h * np.cos(phi), phi))
print(json.dumps(out))
"""


def grid_of(cube: str, ne: int) -> CubedSphere:
    """The np-4 grid of ``ne`` on the equiangular or the equidistant cube (a scene's ``grid.cube``)."""
    mesh = swe_sphere.load_scene("galewsky", ne=ne, overrides={"grid": {"cube": cube}}).make_mesh()
    return CubedSphere(ne, 4, mesh=mesh)


def jet_vorticity(case, lat):
    """ζ = −(1/a)(du/dφ − u tan φ) of Galewsky's jet u = (umax/en) exp(1/((φ−φ0)(φ−φ1)))."""
    u = case.jet(lat)
    inside = (lat > case.lat0) & (lat < case.lat1)
    q = np.where(inside, (lat - case.lat0) * (lat - case.lat1), 1.0)
    dudphi = np.where(inside, -u * (2 * lat - case.lat0 - case.lat1) / q**2, 0.0)
    return -(dudphi - u * np.tan(lat)) / case.planet.a


def start_errors(grid: CubedSphere) -> dict:
    """The t = 0 vorticity errors (normalized l2) of Galewsky's jet and TC2's flow on ``grid``."""
    out = {}
    for key, name, truth in (
        ("jet", "galewsky", jet_vorticity),
        ("tc2", "tc2_steady", lambda c, lat: 2 * c.u0 / c.planet.a * np.sin(lat)),
    ):
        case = swe_sphere.load_scene(name).make_case()
        model = ShallowWater(grid, TERMS, case.fcor(grid.lat, grid.lon), case.hs(grid.lat, grid.lon), device="cpu")
        u, v, _ = case.initial(grid.lat, grid.lon)
        zeta, zt = model.operators.vorticity(model.new_state(u, v)), truth(case, grid.lat)
        out[key] = math.sqrt(grid.integrate((zeta - zt) ** 2) / grid.integrate(zt**2))
    return out


def day6(cube: str, ne: int) -> tuple[float, float]:
    """(Galewsky's day-6 vorticity error against T341, CPU s) at pySEs's settings on ``cube``."""
    cpu = time.process_time()
    ds = swe_sphere.run(
        "galewsky", ne=ne, np=4, stepper="kgu35", dt=150.0, days=6.0, case={"reference": "T341"}, grid={"cube": cube}
    )
    return float(ds["ref_l2_vorticity"].sel(time=6.0)), time.process_time() - cpu


def pyses(python: Path, ne: int) -> dict | None:
    """pySEs's figures (``PYSES``) from its interpreter, or None where it is not installed."""
    if not python.exists():
        return None
    done = subprocess.run([str(python), "-c", PYSES, str(ne)], capture_output=True, text=True, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ne", type=int, default=16)
    parser.add_argument("--no-runs", action="store_true", help="only the t = 0 errors")
    parser.add_argument("--pyses", type=Path, default=Path.home() / ".venvs" / "pyses" / "bin" / "python")
    args = parser.parse_args()
    print(f"ne{args.ne} np4; t = 0: model vorticity + DSS of the exact wind vs analytic (normalized l2)")
    print(f"{'':28s}{'jet t=0':>12s}{'TC2 t=0':>12s}{'day-6 vs T341':>15s}{'CPU s':>8s}")
    for cube in CUBES:
        e = start_errors(grid_of(cube, args.ne))
        run = ("", "") if args.no_runs else tuple(f"{x:.3g}" for x in day6(cube, args.ne))
        print(f"swe_sphere {cube + ' cube':17s}{e['jet']:12.3e}{e['tc2']:12.3e}{run[0]:>15s}{run[1]:>8s}")
    p = pyses(args.pyses, args.ne)
    if p is None:
        print(f"pySEs: not installed at {args.pyses}")
        return
    print(f"{'pySEs (its own cube)':28s}{p['jet']:12.3e}{p['tc2']:12.3e}{'0.76 (issue 63)':>15s}")
    print(
        f"pySEs's own set-up: node longitudes in [{p['lon_min']:.3f}, {p['lon_max']:.3f}] rad (the bump "
        f"exp(-(lon/alpha)^2) keeps only its eastern half), mean depth {p['mean_depth']:.1f} m (Galewsky's: 10000)"
    )


if __name__ == "__main__":
    main()
