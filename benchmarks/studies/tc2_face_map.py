"""TC2 on refined meshes through either map: is a refined mesh as accurate as the uniform cube of
its base spacing once its elements get the equiangular map (HOMME ``cubed_sphere_map = 0``)?

Williamson's TC2 (steady, exact solution; the ``tc2_steady`` scene: no ∇⁴), np 4, SSP-RK3 at one
Δt for every grid (``--dt``, default 90 s: stable on the finest mesh), ``--days`` days (default 5),
one process, one compute thread; with ``--homme`` in HOMME's ``swtc2.nl`` settings instead
(leapfrog-trapezoidal, tensor ∇⁴ s = 3.2 with each mesh's ν, HOMME's radius: ``peer_homme_rrm``). On: the uniform ne10 cube (built-in equiangular map, the
element-local map, and the project's ``.g`` of it through the equiangular map: a check, the
built-in cube's errors to round-off), and the same cube turned as ``refine`` turns it onto the
box (``--stretch-factor 1 --target-lat 30 --target-lon 270``: TC2's flow crosses it otherwise);
E3SM's ``mountain_10_x2.g`` (``--mountain``, default beside
the checkout in ``shared/meshes``, skipped where absent); the project's own ×2 and ×4 refinements
of ne10 over TC5's mountain (``swe-sphere mesh --refine-box 10 50 246.7 293.3 --levels 1|2``),
smoothed (the default) and unsmoothed (``--smoothing 0``: every node on the turned cube's
equiangular lattice); each file through both maps (``grid.map``), or the one line a map refuses
it with. Printed: the error of the GLL gradient of the exact h before any step (the spatial
truncation each map starts from: ``peer_homme_rrm.gradient_error``), the normalized l1, l2, l∞
of h each day (Williamson 1992), the relative mass change, the CPU seconds of each run
(``time.process_time``), and for each refined mesh the l2 of
h at the last day by region (``grid.quality.element_regions``: fine, transition, coarse by the
elements' Dinv-based size; ``cases.scoring.regional_l2``), on the refined mesh through both maps
and on the ne10 cubes (built in, element-local, turned) at the same places (each cube element in the region of the nearest
refined-mesh element centroid). With ``--sweqx PATH`` (and ``--homme``), HOMME's own
``sweqx`` in the same settings on the ne10 cube with ``cubed_sphere_map = 0`` and on the
mountain mesh with 0 and 2 (``homme_maps``).

    SWE_SPHERE_THREADS=1 python benchmarks/studies/tc2_face_map.py [--days 5] [--dt 90] [--homme [--sweqx PATH]]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import recorded  # noqa: E402  (after the path: benchmarks/ first)

# isort: split
from peer_homme import MPIRUN, default_kit, run_homme  # noqa: E402  (benchmarks/)
from peer_homme_rrm import (  # noqa: E402
    BOX,
    check_as_given,
    gradient_error,
    homme_scene,
    homme_scores,
    kit_namelist,
)

from swe_sphere import (  # noqa: E402
    SceneError,  # noqa: E402
    Simulation,  # noqa: E402
    load_scene,  # noqa: E402
)
from swe_sphere.cases.scoring import regional_l2  # noqa: E402
from swe_sphere.grid.quality import REGIONS, element_regions, element_sizes  # noqa: E402

HOMME_SWTC2 = {"nu": 1e-9, "hypervis_scaling": 3.2, "hypervis_subcycle": 2}  # swtc2.nl's ∇⁴ (``peer_homme_rrm``)
MOUNTAIN = REPO.parent / "shared" / "meshes" / "mountain_10_x2.g"


def write_mesh(path: Path, *options: str) -> Path:
    cmd = [sys.executable, "-m", "swe_sphere.cli", "mesh", "--ne", "10", *options, "--output", str(path)]
    subprocess.run([*cmd, "--overwrite"], check=True, cwd=REPO, capture_output=True)
    return path


def run(grid: dict, dt: float, days: float, homme: Path | None):
    """(the Simulation after the run, its history, CPU s) of TC2 on the grid of ``grid`` (the
    ``grid.*`` overrides): the scene's settings, or with ``homme`` (a folder for the scene file)
    HOMME's ``swtc2.nl`` (``peer_homme_rrm.homme_scene``)."""
    scene = load_scene("tc2_steady", dt=dt, days=days, overrides={"output.every_days": 1.0, **grid})
    if homme is not None:
        scene = load_scene(homme_scene(homme, grid, scene.nelem, HOMME_SWTC2, dt, days))
        check_as_given("\n".join(scene.notes), HOMME_SWTC2["nu"])
    start = time.process_time()
    sim = Simulation(scene, "cpu", progress=False)
    result = sim.run(None)
    return sim, result.history, time.process_time() - start


def homme_maps(sweqx: Path, mountain: Path, days: int, folder: Path) -> None:
    """HOMME's ``sweqx`` in ``swtc2.nl`` on the ne10 cube with ``cubed_sphere_map = 0`` and on
    ``mountain`` with 0 and 2: its l2 of h each day. HOMME takes map 2 on any mesh file
    (``namelist_mod.F90``: "must use element_local for var-res grids"), so the two agree."""
    base = kit_namelist(default_kit())
    for label, grid in (
        ("ne10, map 0", "ne = 10\ncubed_sphere_map = 0"),
        (f"{mountain.name}, map 0", f"mesh_file = '{mountain}'\ncubed_sphere_map = 0"),
        (f"{mountain.name}, map 2", f"mesh_file = '{mountain}'\ncubed_sphere_map = 2"),
    ):
        text = re.sub(r"(?m)^\s*(cubed_sphere_map|ne)\s*=.*$", "", base)
        text = re.sub(r"(?m)^\s*mesh_file\s*=.*$", grid, text)
        text = re.sub(r"(?m)^\s*ndays\s*=.*$", f"ndays = {days}", text)
        cpu, _, out = run_homme(sweqx, text, folder / re.sub(r"\W+", "_", label))
        errors = "  ".join(f"{homme_scores(out, d)['l2']:.3e}" for d in range(1, days + 1))
        print(f"HOMME {label:28s} l2 h day 1..{days}: {errors}  CPU {cpu:.1f} s")


def node_regions(sim, centroids: np.ndarray, regions: np.ndarray) -> np.ndarray:
    """Each element-local node's region: that of the refined-mesh element whose centroid is
    nearest its own element's centroid."""
    g = sim.grid
    c = g.xyz.reshape(3, g.nelem, g.np**2).mean(axis=2).T
    return np.repeat(regions[cKDTree(centroids).query(c)[1]], g.np**2)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--days", type=float, default=5.0)
    parser.add_argument("--dt", type=float, default=90.0)
    parser.add_argument("--mountain", type=Path, default=MOUNTAIN)
    parser.add_argument("--homme", action="store_true", help="HOMME's swtc2.nl settings (leapfrog, tensor ∇⁴)")
    parser.add_argument("--sweqx", type=Path, help="HOMME's sweqx: run it too (ne10 map 0, the mountain mesh map 0, 2)")
    args = parser.parse_args(argv)
    if args.sweqx is not None:  # before the swe_sphere runs: HOMME's needs both
        if not os.access(args.sweqx, os.X_OK) or not Path(MPIRUN).is_file():
            parser.error(f"--sweqx {args.sweqx}: needs an executable sweqx and {MPIRUN} (peer_homme.py)")
        if args.days != round(args.days):
            parser.error(f"--sweqx: HOMME runs whole days (got --days {args.days:g})")
    how = "HOMME swtc2 (leapfrog-trapezoidal, tensor ∇⁴ s 3.2)" if args.homme else "ssprk3, no ∇⁴"
    print(f"load average {os.getloadavg()[0]:.2f}; TC2 np4 {how}, dt {args.dt:g} s, {args.days:g} days")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = {"ne10.g": write_mesh(tmp / "ne10.g")}
        # the uniform cube turned as refine turns it onto the box (a stretch of 1 toward its centre)
        turned = ["--stretch-factor", "1", "--target-lat", "30", "--target-lon", "270"]
        files["ne10 turned"] = write_mesh(tmp / "ne10_turned.g", *turned)
        if args.mountain.is_file():
            files["mountain_10_x2.g"] = args.mountain
        for levels in (1, 2):
            for smoothing in ("", "0"):
                name = f"own x{2**levels}" + (" unsmoothed" if smoothing else "")
                extra = ["--smoothing", smoothing] if smoothing else []
                files[name] = write_mesh(
                    tmp / f"x{2**levels}{smoothing}.g", "--refine-box", *BOX, "--levels", str(levels), *extra
                )
        grids = {
            "ne10 equiangular (built in)": {"grid.ne": 10},
            "ne10 element-local": {"grid.ne": 10, "grid.map": "element_local"},
        }
        for name, path in files.items():
            for map_ in ("equiangular", "element_local"):
                if name != "ne10.g" or map_ == "equiangular":
                    grids[f"{name} {map_}"] = {"grid.ne": 0, "grid.mesh_file": str(path), "grid.map": map_}
        sims = {}
        print(
            f"{'grid':42s} {'F':>5s} {'day':>4s} {'l1 h':>10s} {'l2 h':>10s} {'linf h':>10s} {'mass':>10s} {'CPU s':>7s}"
        )
        for label, overrides in grids.items():
            try:
                sim, history, cpu = run(overrides, args.dt, args.days, tmp if args.homme else None)
            except SceneError as err:
                print(f"{label:42s} refused: {err}")
                continue
            sims[label] = sim
            grad = gradient_error(sim.grid, sim.grid.radius)
            for d in history:
                day = d["steps"] * args.dt / 86400
                if d["steps"] and abs(day - round(day)) < 1e-9:
                    mass = f"{d['mass_change']:10.1e}"
                    print(
                        f"{label:42s} {sim.grid.nelem:5d} {grad:8.2e} {day:4.0f} {d['l1_h']:10.3e} {d['l2_h']:10.3e} "
                        f"{d['linf_h']:10.3e} {mass} {cpu:7.1f}"
                    )
        if args.sweqx is not None and args.mountain.is_file():
            homme_maps(args.sweqx, args.mountain.absolute(), round(args.days), tmp)
        t = args.days * 86400
        print(f"\nl2 of h at day {args.days:g} by region (fine / transition / coarse), the refined mesh's regions")
        for name in files:
            key = f"{name} element_local"
            if name in ("ne10.g", "ne10 turned") or key not in sims:
                continue
            ref = sims[key].grid
            regions = element_regions(element_sizes(ref))
            centroids = ref.xyz.reshape(3, ref.nelem, ref.np**2).mean(axis=2).T
            counts = "/".join(str(int(np.sum(regions == k))) for k in range(len(REGIONS)))
            print(f"{name} (elements {counts})")
            cubes = ("ne10 equiangular (built in)", "ne10 element-local", "ne10 turned equiangular")
            for label in (f"{name} equiangular", key, *cubes):
                if label not in sims:
                    continue
                sim = sims[label]
                g = sim.grid
                h, he = sim.x.numpy()[2], sim.case.exact(g.lat, g.lon, t)[2]
                r = regional_l2(g, h, he, node_regions(sim, centroids, regions))
                print(f"  {label:40s} " + "  ".join(f"{r[k]:.3e}" for k in REGIONS))
    return 0


if __name__ == "__main__":
    with recorded(__file__):
        code = main()
    raise SystemExit(code)
