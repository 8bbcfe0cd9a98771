"""TC2 on regionally refined and stretched meshes: swe_sphere beside HOMME's ``sweqx`` on the same ``.g`` files.

HOMME's regression ``swtc2`` (``test/reg_test/namelists/swtc2.nl`` in the kit's
``homme_src.tar.gz``): Williamson TC2 (α = 0) on ``mountain_10_x2.g`` (ne10 base refined 2×
over the TC5 mountain, 780 elements, element-local map), leapfrog-trapezoidal (``LFTfreq = 1``)
at Δt 90 s, tensor ∇⁴ with ``hypervis_scaling = 3.2``, ``nu = nu_s = 1e-9`` (``nu_div``
defaults to ``nu``), ``hypervis_subcycle = 2``, 1 day, np 4 (the kit's build). swe_sphere runs
the same: a scene file per grid and np (``homme_scene``), e.g. on ``mountain_10_x2.g``::

    terms = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "hyperviscosity"]
    [case]
    name = "tc2_steady"
    [grid]
    ne = 0
    mesh_file = "PATH/mountain_10_x2.g"
    np = 4
    [planet]
    radius = 6376000.0
    [time]
    stepper = "leapfrog_trapezoidal"
    dt = 90.0
    days = 1.0
    [hyperviscosity]
    nu = 3.1635e14          # nu_div and nu_s alike
    scaling = 3.2
    subcycle = 2

run as ``SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 swe-sphere run FILE.toml --device cpu``.

**HOMME's ν in ours.** HOMME's tensor (``cube_mod::metric_atomic``) is V = (D E) diag(λ*² μ)
(D E)ᵀ with μ the eigenvalues of the unit-sphere metric inverse and λ* = μ^(−s/4)·a²: along an
element direction whose unit-sphere D has singular value d₁ the ∇⁴ coefficient is
``nu``·a⁴·d₁^s (``nu`` in 1/s). swe_sphere's is ν·(d/d_ref)^s with d = a·d₁ and d_ref =
πa/(4 ne_mean), ne_mean = √(F/6) for F elements (``grid.quality.reference_spacing``), so the
two are equal when

    ν = nu · a⁴ · (π / (4 √(F/6)))^s      (m⁴ s⁻¹)

3.16e14 m⁴ s⁻¹ on ``mountain_10_x2.g`` (F = 780), 4.81e14 on the ne10 cube (F = 600), with
a = 6.376e6 m. The grid, planet, Δt and ν are the scene file's own, so that they are taken as
given: the scene's ν and Δt are for its file's grid and planet, and any other way of choosing the
grid or radius (``--mesh``, ``--ne``, ``-s grid...``, ``-s planet.radius``) rescales them
(``config.hyperviscosity.resolve_hyperviscosity``, ``config.step_rule.scene_dt``); the script
checks that no run scaled either and that each run's header gives HOMME's ``nu`` back (``check_as_given``). Both
codes run on HOMME's planet (``rearth`` 6.376e6 m, Williamson's Ω and g) and each scores h
against TC2's exact (steady) solution on it with the GLL quadrature (HOMME's ``tc2_errors``,
printed every ``statefreq`` steps: the normalized l1, l2, l∞ of the geopotential, which are
those of h).

**Tables.** (1) Cost on ``mountain_10_x2.g``: per round each code runs 1 day and ``--days`` N
days (alternating which goes first, so drift in the load hits both alike), CPU seconds of the
whole process from ``os.wait4`` (user + system, children included: ``mpirun`` and its rank for
HOMME), and the CPU per simulated day past the first, (T_N − T_1)/(N − 1), which leaves out
start-up (swe_sphere's interpreter, imports and kernel cache; HOMME's MPI start and lat-lon
interpolation set-up); medians over rounds and their ratio, the 1-minute load
average; and the error of h each day of the last round's N-day runs. A short run first fills
Warp's kernel cache. (2) Accuracy at day 1, both codes, np 4,
the same settings on: the uniform ne10 cube with the equiangular map (HOMME
``cubed_sphere_map = 0``) and with the element-local map (``cubed_sphere_map = 2``, what every
``.g`` file gets), ``mountain_10_x2.g``, the project's own ×2 and ×4 refinements of ne10 over
the TC5 mountain (10..50° N, 246.7..293.3° E; ``swe-sphere mesh --refine-box``) and
Schmidt-stretched ne10 cubes (c = 2 and 4 toward 30° N, 270° E), all written as ``.g`` for both
codes: l1, l2, l∞ of h and mass change, each code's l2 over its ne10 equiangular and
element-local ones. (3) swe_sphere's
error by region on the refined meshes against the ne10 cubes at the same places (each node in
the region of the nearest refined-mesh element: fine, transition (Dinv-based distortion > 2),
the coarse elements next to the transition, the other coarse ones): RMS of h − h_exact (m) and
of |v − v_exact| (m/s). (4) The map's share without time stepping: the error of the GLL
gradient of TC2's exact h on the uniform ne10 cube with either map, np 4 and 6. (5) Unless
``--no-np``: swe_sphere's day-1 l2 of h in np (3..7) on ``mountain_10_x2.g``, the own ×2 mesh
and the stretched cubes, with no ∇⁴ and Δt 45 s (the ∇⁴ rule's ν does not fall with np and
would set the floor; Δt 45 s keeps np 7 on the c = 4 cube stable and the time error below the
space error), and np 8 with HOMME's settings: the configuration of HOMME's regression baseline.

HOMME comes as for ``peer_homme.py`` (``--homme``, ``--kit``, ``--build-dir``); the mesh from
``--mesh`` (E3SM's ``components/homme/test/mesh_files/mountain_10_x2.g``; default: a
``meshes/`` folder beside the kit). Where either cannot be
had, one line with the reason and exit 0.

    python benchmarks/peers/peer_homme_rrm.py [--rounds 5] [--days 4] [--homme PATH] [--no-np]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import statistics
import sys
import tarfile
import tempfile
from pathlib import Path

import netCDF4
import numpy as np
import xarray as xr
from peer_homme import ONE_CORE, SWE_CHILD, Skip, add_homme_options, default_kit, find_sweqx, run_homme, timed

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import recorded

from swe_sphere import CubedSphere
from swe_sphere.core.constants import EARTH
from swe_sphere.grid.quality import element_sizes
from swe_sphere.mesh.cube import cube_mesh
from swe_sphere.mesh.mesh import read_exodus

REPO = Path(__file__).resolve().parents[2]
NAMELIST = "test/reg_test/namelists/swtc2.nl"
HOMME_RADIUS = 6.376e6  # HOMME's rearth (physical_constants.F90); Williamson's Ω and g as ours
BOX = ("10", "50", "246.7", "293.3")  # TC5's mountain: its latitudes and its widest longitudes (270 ± 23.3°)
TARGET = ("30", "270")  # the stretched cubes' target (lat, lon): the TC5 mountain
TERMS = ["continuity", "momentum_advection", "coriolis", "pressure_gradient", "hyperviscosity"]  # tc2_steady's + ∇⁴


class Grid:
    """One grid of the study: its label, its [grid] table as ``grid.*`` values (``homme_scene``),
    HOMME's namelist lines in place of ``mesh_file``, and its element count F."""

    def __init__(self, label: str, scene: dict, homme: str, nelem: int, mesh: Path | None = None):
        self.label, self.scene, self.homme, self.nelem, self.mesh = label, scene, homme, nelem, mesh

    @classmethod
    def cube(cls, ne: int, element_local: bool) -> Grid:
        scene = {"grid.ne": ne, **({"grid.map": "element_local"} if element_local else {})}
        name = f"ne{ne} {'element-local' if element_local else 'equiangular'}"
        return cls(name, scene, f"ne = {ne}\ncubed_sphere_map = {2 if element_local else 0}", 6 * ne * ne)

    @classmethod
    def file(cls, label: str, path: Path) -> Grid:
        with netCDF4.Dataset(path) as f:
            nelem = len(f.dimensions["num_elem"])
        return cls(label, {"grid.ne": 0, "grid.mesh_file": str(path)}, f"mesh_file = '{path}'", nelem, path)


def our_nu(homme_nu: float, scaling: float, nelem: int) -> float:
    """ν (m⁴ s⁻¹) of swe_sphere's tensor ∇⁴ equal to HOMME's ``nu`` (1/s) with
    ``hypervis_scaling`` s on a mesh of ``nelem`` elements (the module docstring)."""
    return homme_nu * HOMME_RADIUS**4 * (math.pi / (4 * math.sqrt(nelem / 6))) ** scaling


def homme_scene(folder: Path, grid: dict, nelem: int, hv: dict | None, dt: float, days: float) -> Path:
    """A new scene file in ``folder``: TC2 in HOMME's ``swtc2.nl`` settings on ``grid`` (the
    [grid] table as ``grid.*`` values, np included; default np 4) of ``nelem`` elements, on
    HOMME's planet, leapfrog-trapezoidal at ``dt`` (s) for ``days``; ``hv`` HOMME's ∇⁴ (``nu``
    in 1/s, ``hypervis_scaling``, ``hypervis_subcycle``) as ``our_nu``, or None for no ∇⁴
    (tc2_steady's terms). The grid and planet are the file's own, so that its ν and Δt are
    taken as given: a scene's are for its file's grid and radius, and any other way of setting
    them (``-s grid...``, ``--mesh``, ``-s planet.radius``) rescales both."""
    lines = [f"{key.split('.')[1]} = {json.dumps(value)}" for key, value in grid.items()]
    text = f"""terms = {json.dumps(TERMS if hv is not None else TERMS[:-1])}
[case]
name = "tc2_steady"
[grid]
{chr(10).join(lines)}
[planet]
radius = {HOMME_RADIUS!r}
[time]
stepper = "leapfrog_trapezoidal"
dt = {float(dt)!r}
days = {float(days)!r}
[output]
every_days = 1.0
"""
    if hv is not None:
        nu = our_nu(hv["nu"], hv["hypervis_scaling"], nelem)
        text += f"""[hyperviscosity]
nu = {nu!r}
nu_div = {nu!r}
nu_s = {nu!r}
scaling = {float(hv["hypervis_scaling"])!r}
subcycle = {int(hv["hypervis_subcycle"])!r}
"""
    path = folder / f"swtc2_{nelem}_{len(list(folder.glob('swtc2_*')))}.toml"
    path.write_text(text)
    return path


def check_as_given(header: str, homme_nu: float | None) -> None:
    """Raises ``RuntimeError`` unless the run of ``header`` (its header, or its scene's notes)
    took its scene's Δt and ν as given (no note of either scaled to the grid) and, with
    ``homme_nu``, gives HOMME's ``nu`` (1/s) back to the three digits it prints."""
    if re.search(r"\b(dt|nu) scaled", header):
        raise RuntimeError(f"the run scaled the scene's dt or nu:\n{header[-2000:]}")
    if homme_nu is not None:
        back = re.search(r"hypervis_scaling = \S+, nu = ([^)\s]+)\)", header)
        if not back or not math.isclose(float(back[1]), homme_nu, rel_tol=2e-3):
            raise RuntimeError(f"the run's HOMME nu is {back and back[1]}, not the namelist's {homme_nu:g}")


def swe_command(folder: Path, grid: Grid, np_: int, days: float, out: Path, hv: dict | None, dt: float = 90.0):
    """The ``swe-sphere run`` arguments of TC2 on ``grid`` at np ``np_`` (a scene file written in
    ``folder``, ``homme_scene``); ``hv`` HOMME's ∇⁴ or None for none."""
    scene = homme_scene(folder, {**grid.scene, "grid.np": np_}, grid.nelem, hv, dt, days)
    return ["run", str(scene), "--device", "cpu", "--output", str(out), "--overwrite", "--no-progress"]


def run_swe(args: list[str]) -> tuple[float, float, str]:
    return timed([sys.executable, "-c", SWE_CHILD, *args], REPO, dict(os.environ, **ONE_CORE))


def swe_scores(text: str, hv: dict | None) -> dict:
    """l1, l2, linf of h and the mass change from a run's summary; checks that the run took its
    Δt and ν as given and, with ``hv``, that its header's HOMME ``nu`` is the namelist's (the ν
    conversion; ``check_as_given``)."""
    m = re.search(r"error h\s+l1 (\S+)\s+l2 (\S+)\s+linf (\S+)", text)
    mass = re.search(r"mass\s+\S+\s+relative change (\S+)", text)
    if not (m and mass):
        raise RuntimeError(f"no TC2 errors in swe_sphere's summary:\n{text[-2000:]}")
    check_as_given(text, None if hv is None else hv["nu"])
    return {"l1": float(m[1]), "l2": float(m[2]), "linf": float(m[3]), "mass": float(mass[1])}


def homme_namelist(base: str, grid: Grid, days: int) -> str:
    text = re.sub(r"(?m)^\s*mesh_file\s*=.*$", grid.homme, base)
    return re.sub(r"(?m)^\s*ndays\s*=.*$", f"ndays = {days}", text)


def homme_scores(text: str, day: float) -> dict:
    """HOMME's own TC2 errors at ``day`` (``tc2_errors``' stdout line) and its mass change."""
    rows = re.findall(r"(?m)^\s*(\S+) days\s+l1,l2,linf=\s*(\S+)\s+(\S+)\s+(\S+)", text)
    last = [r for r in rows if abs(float(r[0]) - day) < 1e-3]
    mass = re.findall(r"M-M0/M0\s*=\s*(\S+)", text)
    if not last or not mass:
        raise RuntimeError(f"no day-{day:g} TC2 errors in HOMME's output:\n{text[-2000:]}")
    return {"l1": float(last[-1][1]), "l2": float(last[-1][2]), "linf": float(last[-1][3]), "mass": float(mass[-1])}


def homme_settings(namelist: str) -> dict:
    def value(key):
        m = re.search(rf"(?m)^\s*{key}\s*=\s*(\S+)", namelist)
        if not m:
            raise RuntimeError(f"swtc2.nl has no {key}")
        return float(m[1])

    hv = {k: value(k) for k in ("nu", "hypervis_scaling")}
    hv["hypervis_subcycle"] = int(value("hypervis_subcycle"))
    if value("tstep") != 90 or value("LFTfreq") != 1 or value("nu_s") != hv["nu"]:
        raise RuntimeError("swtc2.nl is not the setup this script mirrors (tstep 90, LFTfreq 1, nu_s = nu)")
    return hv


def kit_namelist(kit: Path) -> str:
    tarball = kit / "homme_src.tar.gz"
    if not tarball.is_file():
        raise Skip(f"no {tarball} (--kit)")
    with tarfile.open(tarball) as tar:
        member = next((m for m in tar if m.name.endswith(NAMELIST)), None)
        if member is None:
            raise Skip(f"{tarball} has no {NAMELIST}")
        return tar.extractfile(member).read().decode()


def write_meshes(tmp: Path) -> list[Grid]:
    """The project's own meshes as ``.g`` (``swe-sphere mesh``): ×2 and ×4 over ``BOX``, and
    stretched cubes c = 2 and 4 toward ``TARGET``, all on the ne10 cube."""
    grids = []
    for label, extra in (
        ("own x2 (ne10 base)", ["--refine-box", *BOX, "--levels", "1"]),
        ("own x4 (ne10 base)", ["--refine-box", *BOX, "--levels", "2"]),
        ("stretched c=2 (ne10)", ["--stretch-factor", "2", "--target-lat", TARGET[0], "--target-lon", TARGET[1]]),
        ("stretched c=4 (ne10)", ["--stretch-factor", "4", "--target-lat", TARGET[0], "--target-lon", TARGET[1]]),
    ):
        path = tmp / (re.sub(r"\W+", "_", label).strip("_") + ".g")
        run_swe(["mesh", "--ne", "10", *extra, "--output", str(path), "--overwrite"])
        grids.append(Grid.file(label, path))
    return grids


def regions(refined: Grid, outputs: dict, a: float = HOMME_RADIUS) -> list[tuple[str, list[float], list[float]]]:
    """(label, RMS of h − h_exact in m, RMS of |v − v_exact| in m/s) at day 1 over the regions
    of ``refined`` (fine, transition, coarse next to it, coarse), on each grid of ``outputs``
    (label -> run file). TC2 is steady, so the run's day-0 state is the exact solution at its
    nodes; a node is in the region of the nearest element centroid of the refined mesh."""
    mesh = read_exodus(refined.mesh)
    sizes = element_sizes(CubedSphere(0, 4, a, mesh=mesh))
    transition = sizes.distortion > 2
    fine = (sizes.area < 0.5 * sizes.area.max()) & ~transition
    near = ~fine & ~transition & np.isin(mesh.quads, mesh.quads[transition]).any(axis=1)
    kind = np.select([fine, transition, near], [0, 1, 2], 3)
    centroids = mesh.centroids()
    rows = []
    for label, path in outputs.items():
        with xr.open_dataset(path, decode_times=False) as ds:
            h, u, v, w = (ds[name].values for name in ("h", "u", "v", "area"))
            lat, lon = np.radians(ds.lat.values), np.radians(ds.lon.values)
        xyz = np.stack([np.cos(lat) * np.cos(lon), np.cos(lat) * np.sin(lon), np.sin(lat)], axis=1)
        where = kind[np.argmax(xyz @ centroids.T, axis=1)]
        e_h, e_v = w * (h[-1] - h[0]) ** 2, w * ((u[-1] - u[0]) ** 2 + (v[-1] - v[0]) ** 2)
        rms = [[math.sqrt(e[where == k].sum() / w[where == k].sum()) for k in range(4)] for e in (e_h, e_v)]
        rows.append((label, *rms))
    return rows


def gradient_error(grid, a: float = HOMME_RADIUS) -> float:
    """Relative l2 (GLL quadrature over the element copies) of the error of the element-wise GLL
    gradient of TC2's exact h on ``grid`` (a ``CubedSphere``), ∇h = Dinvᵀ (∂h/∂ξ, ∂h/∂η)
    (HOMME ``gradient_sphere``) against the analytic −2c sinφ cosφ / a northward (h = h₀ − c
    sin²φ): the spatial truncation error that TC2 starts from, before any time stepping."""
    u0 = 2 * math.pi * a / (12 * 86400)
    c = (a * EARTH.omega * u0 + u0**2 / 2) / EARTH.g
    n = grid.np
    h = (-c * np.sin(grid.lat) ** 2).reshape(grid.nelem, n, n)  # [element, j, i]
    dh_dxi = np.einsum("im,ejm->eji", grid.rule.dvv, h).ravel()
    dh_deta = np.einsum("jm,emi->eji", grid.rule.dvv, h).ravel()
    east = grid.Dinv[0] * dh_dxi + grid.Dinv[2] * dh_deta
    north = grid.Dinv[1] * dh_dxi + grid.Dinv[3] * dh_deta
    exact = -2 * c * np.sin(grid.lat) * np.cos(grid.lat) / a
    return math.sqrt(np.sum(grid.spheremp * (east**2 + (north - exact) ** 2)) / np.sum(grid.spheremp * exact**2))


def measure(args, base, sweqx, hv, mountain) -> dict:
    """The runs of both codes: ``--rounds`` timed rounds on ``mountain`` (1 and ``--days`` days, the
    order alternating), the day-1 scores on every grid, the refined meshes' regions, and (unless
    ``--no-np``) swe_sphere's convergence in np; a dict of what ``report_cost`` and
    ``report_errors`` print."""
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        run_swe(swe_command(tmp, mountain, 4, 0.0125, tmp / "warm.nc", hv))  # fills the kernel cache; not timed
        rows, got = [], {}
        for k in range(args.rounds):
            order = ("swe", "homme") if k % 2 == 0 else ("homme", "swe")
            for who in order:
                for days in (1, args.days):
                    if who == "swe":
                        got["swe", days] = run_swe(swe_command(tmp, mountain, 4, days, tmp / f"swe{days}.nc", hv))
                    else:
                        got["homme", days] = run_homme(sweqx, homme_namelist(base, mountain, days), tmp / "homme")
            rows.append(({key: v[:2] for key, v in got.items()}, os.getloadavg()[0]))
            print(
                f"round {k + 1}: {', '.join(f'{w} {d} d {v[0]:.2f} s' for (w, d), v in got.items())}", file=sys.stderr
            )
        scores = {mountain.label: (swe_scores(got["swe", 1][2], hv), homme_scores(got["homme", 1][2], 1.0))}
        (tmp / "swe1.nc").rename(tmp / "mountain.nc")
        with xr.open_dataset(tmp / f"swe{args.days}.nc", decode_times=False) as ds:
            days = [float(t) for t in ds.time.values[1:]]
            daily = [(d, *(float(ds[k].sel(time=d)) for k in ("l1_h", "l2_h", "linf_h"))) for d in days]
        daily = [(*row, homme_scores(got["homme", args.days][2], row[0])) for row in daily]

        grids = [Grid.cube(10, False), Grid.cube(10, True), *write_meshes(tmp)]
        files = {mountain.label: tmp / "mountain.nc"}
        for n, grid in enumerate(grids):
            files[grid.label] = tmp / f"grid{n}.nc"
            ours = swe_scores(run_swe(swe_command(tmp, grid, 4, 1, files[grid.label], hv))[2], hv)
            theirs = homme_scores(run_homme(sweqx, homme_namelist(base, grid, 1), tmp / "homme")[2], 1.0)
            scores[grid.label] = (ours, theirs)
            print(f"{grid.label}: l2 swe_sphere {ours['l2']:.4e}, HOMME {theirs['l2']:.4e}", file=sys.stderr)
        refined = [mountain, grids[2], grids[3]]
        split = {
            g.label: regions(g, {x: files[x] for x in ("ne10 equiangular", "ne10 element-local", g.label)})
            for g in refined
        }

        convergence = {}
        if args.np_study:
            for grid in (mountain, grids[2], grids[4], grids[5]):
                for np_ in range(3, 8):
                    text = run_swe(swe_command(tmp, grid, np_, 1, tmp / "np.nc", None, dt=45.0))[2]
                    convergence[grid.label, np_] = swe_scores(text, None)["l2"]
                print(f"{grid.label}: np 3..7 done", file=sys.stderr)
            regression = swe_scores(run_swe(swe_command(tmp, mountain, 8, 1, tmp / "np.nc", hv))[2], hv)

    return {
        "rows": rows,
        "daily": daily,
        "scores": scores,
        "grids": grids,
        "split": split,
        "convergence": convergence if args.np_study else None,
        "regression": regression if args.np_study else None,
    }


def report_cost(args, sweqx, hv, mountain, runs: dict) -> None:
    """Print the settings, the rounds' CPU seconds and the daily error of h on ``mountain``."""
    rows, daily = runs["rows"], runs["daily"]
    print(
        f"TC2 (alpha 0), HOMME's swtc2.nl: leapfrog-trapezoidal dt 90 s, tensor hyperviscosity s = "
        f"{hv['hypervis_scaling']:g}, HOMME nu {hv['nu']:g} (ours: {our_nu(hv['nu'], hv['hypervis_scaling'], mountain.nelem):.4g} "
        f"m^4/s on {mountain.label}), subcycle {hv['hypervis_subcycle']}, np 4, radius {HOMME_RADIUS:g} m, one core each"
    )
    print(f"HOMME: /usr/bin/mpirun -np 1 {sweqx}")
    print(f"\n1. CPU s on {mountain.label}, whole process ({args.rounds} rounds, alternating order)")
    n = args.days
    print(
        f"{'round':>5} {'swe 1 d':>8} {f'swe {n} d':>8} {'swe /d':>7} {'HOMME 1 d':>10} {f'HOMME {n} d':>10} {'HOMME /d':>9} {'load':>5}"
    )
    table = []
    for k, (r, load) in enumerate(rows):
        s1, sn, h1, hn = r["swe", 1][0], r["swe", n][0], r["homme", 1][0], r["homme", n][0]
        table.append((s1, sn, (sn - s1) / (n - 1), h1, hn, (hn - h1) / (n - 1)))
        print(
            f"{k + 1:>5} {s1:>8.2f} {sn:>8.2f} {table[-1][2]:>7.2f} {h1:>10.2f} {hn:>10.2f} {table[-1][5]:>9.2f} {load:>5.2f}"
        )
    med = [statistics.median(t[i] for t in table) for i in range(6)]
    print(f"{'median':>5} {med[0]:>8.2f} {med[1]:>8.2f} {med[2]:>7.2f} {med[3]:>10.2f} {med[4]:>10.2f} {med[5]:>9.2f}")
    print(
        f"ratio of the medians (swe_sphere / HOMME): whole process 1 day {med[0] / med[3]:.3f}, "
        f"{n} days {med[1] / med[4]:.3f}, per simulated day past the first {med[2] / med[5]:.3f}"
    )

    print(f"\nerror of h each day on {mountain.label} (the last round's {n}-day runs)")
    print(
        f"{'day':>4} {'swe l1':>10} {'swe l2':>10} {'swe linf':>10} | {'HOMME l1':>10} {'HOMME l2':>10} {'HOMME linf':>10}"
    )
    for day, l1, l2, linf, h in daily:
        print(f"{day:>4g} {l1:>10.4e} {l2:>10.4e} {linf:>10.4e} | {h['l1']:>10.4e} {h['l2']:>10.4e} {h['linf']:>10.4e}")


def report_errors(args, mountain, runs: dict) -> None:
    """Print the day-1 errors on every grid, the regions, the map's share and the np convergence."""
    scores, grids, split = runs["scores"], runs["grids"], runs["split"]
    convergence, regression = runs["convergence"], runs["regression"]
    print("\n2. day-1 error of h against TC2's exact solution, np 4, both codes, HOMME's settings")
    eq = scores["ne10 equiangular"]
    el = scores["ne10 element-local"]
    print(
        f"{'grid':>22} {'F':>5} | {'swe l1':>9} {'swe l2':>9} {'swe linf':>9} {'mass':>9} | "
        f"{'HOMME l1':>9} {'HOMME l2':>9} {'HOMME linf':>10} {'mass':>9} | {'l2 s/H':>6} "
        f"{'s/eq':>5} {'H/eq':>5} {'s/el':>5} {'H/el':>5}"
    )
    for grid in [grids[0], grids[1], mountain, *grids[2:]]:
        s, h = scores[grid.label]
        print(
            f"{grid.label:>22} {grid.nelem:>5} | {s['l1']:>9.3e} {s['l2']:>9.3e} {s['linf']:>9.3e} {s['mass']:>9.1e} | "
            f"{h['l1']:>9.3e} {h['l2']:>9.3e} {h['linf']:>10.3e} {h['mass']:>9.1e} | {s['l2'] / h['l2']:>6.3f} "
            f"{s['l2'] / eq[0]['l2']:>5.2f} {h['l2'] / eq[1]['l2']:>5.2f} {s['l2'] / el[0]['l2']:>5.2f} {h['l2'] / el[1]['l2']:>5.2f}"
        )

    print("\n3. swe_sphere's day-1 RMS error by region of each refined mesh, np 4: h (m) | wind (m/s)")
    head = f"{'fine':>9} {'transit.':>9} {'next':>9} {'coarse':>9}"
    print(f"{'regions of':>22} {'grid':>22} {head} | {head}")
    for label, parts in split.items():
        for grid_label, rms_h, rms_v in parts:
            print(
                f"{label:>22} {grid_label:>22} "
                + " ".join(f"{x:>9.3e}" for x in rms_h)
                + " | "
                + " ".join(f"{x:>9.3e}" for x in rms_v)
            )

    print("\n4. the map's share: relative l2 of the GLL gradient of TC2's exact h, uniform ne10 (no time stepping)")
    for np_ in (4, 6):
        eq_, el_ = (gradient_error(CubedSphere(10, np_, HOMME_RADIUS, mesh=m)) for m in (None, cube_mesh(10)))
        print(f"np {np_}: equiangular {eq_:.3e}, element-local {el_:.3e}, ratio {el_ / eq_:.2f}")

    if args.np_study:
        print("\n5. swe_sphere's day-1 l2 of h in np, no hyperviscosity, leapfrog-trapezoidal dt 45 s")
        labels = [mountain.label, grids[2].label, grids[4].label, grids[5].label]
        print(f"{'np':>3} " + " ".join(f"{x:>22}" for x in labels))
        for np_ in range(3, 8):
            print(f"{np_:>3} " + " ".join(f"{convergence[x, np_]:>22.3e}" for x in labels))
        print(
            f"np 8 on {mountain.label} with HOMME's settings (its regression's configuration): "
            f"l1 {regression['l1']:.3e} l2 {regression['l2']:.3e} linf {regression['linf']:.3e}"
        )


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=5, help="timed rounds, each 1 and N days of both (default 5)")
    ap.add_argument("--days", type=int, default=4, help="N, the longer timed run in days (default 4)")
    ap.add_argument("--mesh", type=Path, help="HOMME's mountain_10_x2.g (default: shared/meshes beside the kit)")
    ap.add_argument("--no-np", dest="np_study", action="store_false", help="skip the convergence in np")
    add_homme_options(ap)
    args = ap.parse_args(argv)
    if args.rounds < 1 or args.days < 2:
        ap.error("--rounds must be at least 1 and --days at least 2")
    mesh = args.mesh or default_kit().parents[1] / "meshes" / "mountain_10_x2.g"
    try:
        if not mesh.is_file():
            raise Skip(f"no {mesh} (--mesh)")
        base = kit_namelist(args.kit)
        sweqx = find_sweqx(args)
    except Skip as why:
        print(f"peer_homme_rrm: skipped: {why}")
        # exit 0 and no results file: `recorded` writes none on an exception, so the last one stays
        raise SystemExit(0) from None
    hv = homme_settings(base)
    mountain = Grid.file(mesh.name, mesh.resolve())

    runs = measure(args, base, sweqx, hv, mountain)
    report_cost(args, sweqx, hv, mountain, runs)
    report_errors(args, mountain, runs)
    return 0


if __name__ == "__main__":
    with recorded(__file__):
        code = main()
    sys.exit(code)
