"""Galewsky et al. (2004) and Williamson et al. (1992) cases 5 and 6 in Dinosaur beside swe_sphere:
Galewsky's day-6 vorticity error or TC5's day-15 h + hs error against T341, and CPU seconds a
simulated day, one thread each, in one run (``--case galewsky``, the default, ``tc5`` or ``tc6``:
Rossby–Haurwitz wave 4's day-14 h + hs, no mountain, started as the others from the project's
state at the peer's nodes).

Dinosaur (Google's JAX spectral core, PyPI ``dinosaur`` 1.5) is a peer, not a dependency: it runs
in a virtual environment of its own, made once with::

    python -m venv ~/.venvs/dinosaur && ~/.venvs/dinosaur/bin/pip install dinosaur jax

(``--python`` names that environment's interpreter; where it cannot import dinosaur the script
prints one line and exits 0). The measured versions: dinosaur 1.5.1, jax/jaxlib 0.10.2.

**The peer's run.** Float64 (``jax_enable_x64``; ``--precision float32``: both models in float32, the peer's JAX without x64 and swe_sphere's float32 tendency, except a ``--swe`` row that names its own ``numerics.precision=float32_state``), one layer, ``ShallowWaterEquations`` (no
orography on Galewsky; on TC5 below), ``imex_rk_sil3`` (Whitaker & Kar 2013: the gravity-wave terms implicit) and the filter
Dinosaur's own shallow-water tests and examples pair with it, ``exponential_step_filter(grid, dt)``
at its defaults (τ = 0.010938 in Dinosaur's units of 1/(2Ω), i.e. 75 s; order 18, cutoff 0: each
step multiplies a mode of total wavenumber l by exp(−(dt/τ)(l/L)^36)); no other diffusion.
Transforms: ``FastSphericalHarmonics`` with ``fourier_method="fft"`` (``--transforms real``:
Dinosaur's default ``RealSphericalHarmonics``, matrix products). Grids: Dinosaur's ``T42``
(64 × 128 Gaussian), ``T85`` (128 × 256), ``T170`` (256 × 512), Δt 1200, 600, 600 s
(``--truncations ... T213``: 320 × 640, 300 s, about 80 CPU s a simulated day). Constants:
Dinosaur's defaults, which are Williamson's (a = 6.37122e6 m, Ω = 7.292e-5 s⁻¹, g = 9.80616).

**The same initial state.** Dinosaur's own Galewsky (``shallow_water_states.barotropic_instability_tc``)
is not used: it draws the bump's latitude at random, and passes sin(latitude) as the latitude of
the bump (``get_height(*grid.nodal_mesh, ...)``; ``nodal_mesh`` is (longitude, sin latitude)).
Instead this script evaluates the project's ``cases.Galewsky`` (jet u0 = 80 m/s between π/7
and π/2 − π/7, h in gradient-wind balance with mean depth 10 km, the 120 m bump at 45°N, α = 1/3,
β = 1/15, longitudes taken to (−π, π]) at the peer's Gaussian nodes and hands u, v = 0 and h to it;
the peer turns them into its spectral vorticity, divergence and geopotential (its own
``uv_nodal_to_vor_div_modal`` and ``to_modal``), the mean depth its reference geopotential.

**TC5** (``--case tc5``): the project's ``cases.Mountain`` (u0 = 20 m/s, h0 = 5960 m, the
2000 m cone of radius π/9 at (30°N, 270°E)) at the peer's nodes: u, v = 0, the fluid depth
h = surface − hs to its potential g (h − H) (H: h's mean over the sphere, Gauss-weighted) and
the cone g hs to ``ShallowWaterEquations``' ``orography`` (modal geopotential, nondimensional:
``to_modal`` of g hs in Dinosaur's units, as its own ``shallow_water_test._get_mountain``; the
equations add it to the potential in the pressure gradient only). Its h + hs is the modal
potential + orography, clipped of the top wavenumber as its tendencies are. A day-0 check is
printed per truncation: ``start_h_surface_l2`` (its h + hs at t = 0 against ours at its nodes;
about 1e-9) and ``orography_l2`` (its truncated cone against the exact one).
swe_sphere's rows: ``tc5_mountain`` with ``kgu35`` at 0.8 of its limit, at the Δt the frontier
(``swe-sphere frontier``) makes on each grid (86400 / a whole number), ν by the scene's rule.

**Scoring, the project's code for every model.** Galewsky: day-6 relative vorticity, normalized l2
(Williamson et al. 1992 eq. 83: sqrt(Σ w (ζ − ζT)²) / sqrt(Σ w ζT²)) against the bundled T341
reference (``cases.reference.Reference.at``: the spherical-harmonic coefficients synthesised
exactly at each model's own points), with each model's own quadrature: the peer's Gauss weights
× 2π/nlon at its nodes; swe_sphere's assembled ``spheremp`` (the run file's ``area``) at its
unique nodes, with the vorticity its run file writes (the model's operator + DSS). The same for
h (``l2 h``) and h + hs (``l2 h_surface``: TC5's score, at day 15, against the reference's h + hs;
swe_sphere's h + the exact hs at its nodes). swe_sphere's own scorer (``ref_l2_vorticity``: the
vorticity of the wind error by the model's operator, over sqrt(∫ ζT² + δT²); on TC5
``ref_l2_h_surface``) is printed beside it. A sanity line: the T213 reference
scored the same way at the finest peer grid's points (the reference's own distance from T341).

**Cost, one clock.** Every model runs as a child process pinned to core 0 (``taskset -c 0``) with
one thread (``XLA_FLAGS=--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1``;
``SWE_SPHERE_THREADS=1``), in the order given, the models interleaved. The peer's figure: CPU
seconds (``time.process_time``) of its whole time loop (``jax.lax.scan`` of the filtered
steps, compiled ahead of time, compilation excluded) / days. swe_sphere's: its run's own step-loop
CPU clock (``simulation.summary.Ledger``: output and scoring excluded) between day 1 and the
last, / (days − 1) (the first day's first step, with its launch recording, left out). ``galewsky``'s
default runs are the shipped scene (ne12 np8 kgu35 at its Δt, 0.7 of its limit) and ne10 and ne16
np8 at the same 0.7, with the scene's ν (the 3-hour e-folding rule), output every day, ``-s
case.reference=T341``. ``--swe`` names swe_sphere's runs, ``neNE/npNP/STEPPER`` (the scene's Δt),
``neNE/npNP/STEPPER,DT`` (``DT`` s or ``86400/N``) or ``neNE/npNP/STEPPER@F`` (86400/N at or below F
of the stepper's measured limit on that grid, ``at_limit``; ``--list`` prints the rows so resolved),
then any of the stepper's (or the scene's) options as ``swe-sphere run -s`` takes them, comma-separated
``SECTION.KEY=VALUE``: ``ne12/np8/imex,86400/180,imex.scheme=ars232``. A run that fails (a blow-up,
a refused Δt) is a row that says so, its error NaN.

**The peer at its own best step** (``--best-step``; issue 81): per truncation, Dinosaur at a
reference Δt (``--reference-dt``: half ``GRIDS``' by default), then at each of ``--peer-steps``
above it (Δt that divide a day: 450 … 7200 s), upwards, up to the first that blows up or loses
more than ``--tolerance`` (1 %) of the reference's error (an error that drops is kept); the best
step is the last kept. Every tried step is a row (``dinosaur T170 900 s``) with its error and cost;
the results file keeps the search (``best_step``: each step's Δt, error, cost, load, verdict), and
later ``--rounds`` rerun only the best step. **The summary's last table** gives, per Dinosaur level
(its best step's, or each Δt's without ``--best-step``), the cheapest ``--swe`` row whose error is
at or below it, the same eq. 83 measure for both, and the cost ratio ours / Dinosaur's (``levels``
in the results file).

Figures, one command each: ``benchmarks/results/peer_dinosaur/peer_dinosaur.json`` (Galewsky, Dinosaur at
``GRIDS``' steps; ``python benchmarks/peers/peer_dinosaur.py``), ``peer_dinosaur_tc5.json`` (TC5;
``--case tc5``), ``peer_dinosaur_tc6.json`` (TC6; ``--case tc6``); Galewsky with Dinosaur at its best
step, ``peer_dinosaur_best_step.json``::

    python benchmarks/peers/peer_dinosaur.py --best-step --truncations T42 T85 T170 --swe ne8/np8/kgu35,86400/366 \
        ne12/np6/kgu35,86400/262 ne16/np5/kgu35,86400/238 ne10/np8/kgu35,86400/457 ne12/np8/kgu35 \
        ne12/np8/imex,86400/180 ne24/np6/kgu35,86400/524 ne26/np6/kgu35,86400/568 --results peer_dinosaur_best_step

T213 (``peer_dinosaur_best_step_t213.json``; its reference step the default 300 s, not half of it, to save
time), and the best steps' costs again in two rounds (``peer_dinosaur_best_step_rounds.json``)::

    python benchmarks/peers/peer_dinosaur.py --best-step --truncations T213 --reference-dt 300 \
        --swe ne30/np6/kgu35,86400/655 --results peer_dinosaur_best_step_t213
    python benchmarks/peers/peer_dinosaur.py --truncations T42 T85 T170 --peer-dt 7200 2400 900 --swe ne16/np5/kgu35,86400/238 \
        ne12/np8/kgu35 ne26/np6/kgu35,86400/568 --rounds 2 --results peer_dinosaur_best_step_rounds

**On a GPU** (``--device cuda``, issue 67: the peer on the same card in the same call): the peer
under JAX on CUDA (``JAX_PLATFORMS=cuda``, no preallocation), swe_sphere's runs with
``device="cuda"``, each figure the wall seconds of the same loop (the peer's compiled
``jax.lax.scan``, compilation excluded; swe_sphere's step loop from day 1), still one host core.
The GPU machine's image has JAX with its CUDA plugin; Dinosaur and what it imports beyond the
image travel as wheels (``benchmarks/gpu/gpu_session.sh`` part ``dinosaur``; ``--python python3``).

    python benchmarks/peers/peer_dinosaur.py [--case galewsky|tc5|tc6] [--truncations T42 T85 T170]
        [--swe ne16/np4/fbrk32,86400/214 ne16/np4/kgu35,400 ne12/np8/imex,480,imex.scheme=ars232 ...]
        [--peer-dt DT ... | --best-step [--reference-dt DT ...] [--peer-steps DT ...] [--tolerance 0.01]]
        [--rounds 1] [--python ~/.venvs/dinosaur/bin/python] [--device cpu|cuda]
"""

from __future__ import annotations

import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
GRIDS = {"T42": (32, 1200.0), "T85": (64, 600.0), "T170": (128, 600.0), "T213": (160, 300.0)}  # gaussian_nodes, Δt s
ONE_THREAD = {
    "XLA_FLAGS": "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1",
    "SWE_SPHERE_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}
CHILD = Path(__file__).with_name("dinosaur_child.py")  # a run of either model, in a process of its own
DEFAULT_PYTHON = Path.home() / ".venvs" / "dinosaur" / "bin" / "python"
# ``--best-step``'s candidate steps of the peer, s: steps that divide a day (86400 / N)
DAY_STEPS = (300.0, 450.0, 600.0, 720.0, 900.0, 1200.0, 1440.0, 1800.0, 2400.0, 2880.0, 3600.0, 4320.0, 5400.0, 7200.0)


@dataclass(frozen=True)
class Study:
    """A case as this benchmark runs it: swe_sphere's scene, the day scored, the field scored
    (a key of ``scores``' dict), its name, swe_sphere's default configurations (``parse_swe``)
    and the results file's stem (``benchmarks/results/peer_dinosaur/<stem>.json``)."""

    scene: str
    days: float
    field: str
    field_name: str
    swe: tuple[str, ...]
    stem: str


STUDIES = {
    "galewsky": Study(
        "galewsky",
        6.0,
        "vorticity",
        "vorticity",
        # the shipped scene (ne12 np8, kgu35 at its Δt, 0.7 of its limit) and its neighbours in ne at
        # the scene's rule (0.7 of kgu35's limit on each grid: at 0.8 np 8 needs a second ∇⁴ substep)
        ("ne10/np8/kgu35@0.7", "ne12/np8/kgu35", "ne16/np8/kgu35@0.7"),
        "peer_dinosaur",
    ),
    # kgu35 at 0.8 of its limit (``at_limit``), Δt as the frontier makes it (86400 / a whole number): the TC5
    # frontier's front (docs/explanation/efficiency/frontier.md) and grids between its points (ne10 np4, ne12 np3 and
    # np4 about Dinosaur T42's error; ne16 np5 and ne24 np4)
    "tc5": Study(
        "tc5_mountain",
        15.0,
        "h_surface",
        "h + hs",
        tuple(
            f"{grid}/kgu35@0.8"
            for grid in (
                "ne8/np4",
                "ne12/np3",
                "ne10/np4",
                "ne12/np4",
                "ne16/np3",
                "ne16/np4",
                "ne24/np4",
                "ne16/np5",
                "ne16/np6",
            )
        ),
        "peer_dinosaur_tc5",
    ),
    # kgu35 at 0.8 of its limit (``at_limit``), the TC6 frontier's grids and Δt (docs/explanation/efficiency/frontier.md)
    "tc6": Study(
        "tc6_rossby_haurwitz",
        14.0,
        "h_surface",
        "h + hs",
        tuple(f"{grid}/kgu35@0.8" for grid in ("ne4/np6", "ne8/np4", "ne8/np5", "ne8/np6", "ne16/np4", "ne16/np5")),
        "peer_dinosaur_tc6",
    ),
}


def gaussian_grid(nodes: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Dinosaur's ``Grid.construct(gaussian_nodes=nodes)`` points: (lat, lon, weights), each
    (4 nodes, 2 nodes) (longitude first, as Dinosaur's nodal arrays); radians; Gauss–Legendre
    latitudes, longitudes 2πk/nlon from 0; weights the Gauss weights × 2π/nlon (sum 4π)."""
    sin_lat, w = np.polynomial.legendre.leggauss(2 * nodes)
    lon = 2 * math.pi * np.arange(4 * nodes) / (4 * nodes)
    lat2, lon2 = np.meshgrid(np.arcsin(sin_lat), lon)
    return lat2, lon2, np.broadcast_to(w * 2 * math.pi / lon.size, lat2.shape).copy()


def parse_swe(config: str) -> tuple[int, int, str, float | None, dict]:
    """``"ne16/np4/kgu35"`` (the scene's Δt, rescaled with ne), ``"ne16/np4/kgu35,864"`` (Δt 864 s;
    ``86400/100`` allowed), then any ``-s``-style overrides, comma-separated ``SECTION.KEY=VALUE``
    (TOML values, as ``swe-sphere run -s``; no commas inside a value), e.g.
    ``"ne12/np8/imex,960,imex.scheme=ars232"`` or ``"ne12/np8/imex,imex.tol=1e-8"`` → (ne, np,
    stepper, Δt s or None, {"SECTION.KEY": value}). Raises ValueError."""
    grid, *rest = config.split(",")
    dts = [r for r in rest if "=" not in r]
    try:
        if len(dts) > 1 or rest[: len(dts)] != dts:
            raise ValueError
        ne, np_, stepper = grid.split("/")
        num, _, den = dts[0].partition("/") if dts else ("", "", "")
        seconds = (float(num) / float(den) if den else float(num)) if dts else None
        parsed = int(ne.removeprefix("ne")), int(np_.removeprefix("np")), stepper, seconds
    except ValueError:
        raise ValueError(f"--swe {config!r}: expected neNE/npNP/STEPPER[,DT][,SECTION.KEY=VALUE...]") from None
    from swe_sphere.cli.values import overrides

    sets = overrides(r for r in rest if "=" in r)
    if any("." not in k for k in sets):
        raise ValueError(
            f"--swe {config!r}: an override is SECTION.KEY=VALUE (ne, np, stepper and Δt have their places)"
        )
    return (*parsed, sets)


def at_limit(study: str, config: str) -> tuple[str, float | None]:
    """``config`` with ``STEPPER@F`` (``neNE/npNP/STEPPER@F[,SECTION.KEY=VALUE...]``) written as
    ``STEPPER,86400/N``: the largest Δt that divides a day at or below F of the stepper's measured
    stability limit on that grid (``courant_limit`` as (|v| + sqrt(g h)) Δt / Δx on the scene's
    start state: ``studies.frontier.stable_dt`` of ``studies.sweep.explicit_limits``, the
    frontier's ``kgu35@0.8``), and that Δt's fraction of the limit; any other ``config`` as
    given, with its fraction where the stepper has a limit (else None). The limit is the
    scene's at that grid (overrides aside). Raises ValueError."""
    grid, *rest = config.split(",")
    head, at, fraction = grid.partition("@")
    if at and any("=" not in r for r in rest):
        raise ValueError(f"--swe {config!r}: STEPPER@F is its Δt; give one or the other")
    ne, np_, stepper, dt, _ = parse_swe(",".join([head, *rest]))
    from swe_sphere import STEPPERS, load_scene
    from swe_sphere.studies.frontier import stable_dt
    from swe_sphere.studies.sweep import explicit_limits

    if stepper not in STEPPERS:
        raise ValueError(f"--swe {config!r}: unknown stepper {stepper!r}")
    if STEPPERS[stepper].courant_limit is None:
        if at:
            raise ValueError(f"--swe {config!r}: {stepper} has no measured stability limit to run at a fraction of")
        return config, None
    try:
        f = float(fraction) if at else math.nan
    except ValueError:
        f = math.nan
    if at and not f > 0:
        raise ValueError(f"--swe {config!r}: STEPPER@F wants F a number > 0")
    scene = load_scene(STUDIES[study].scene, ne=ne, np_=np_, stepper=stepper)
    limit = stable_dt(stepper, explicit_limits(scene, "cpu"))
    if not at:
        return config, (scene.dt if dt is None else dt) / limit
    n = math.ceil(86400 / (f * limit))
    return ",".join([f"{head},86400/{n}", *rest]), 86400 / n / limit


# -- the parent: runs the children one at a time and scores them ----------------------------
def child_env(device: str = "cpu") -> dict:
    """The environment of a timed child: one thread, this checkout first on the path (before
    what the path held), JAX on ``device`` ("cpu" or "cuda", its memory taken as needed)."""
    path = os.pathsep.join(p for p in (str(REPO), os.environ.get("PYTHONPATH")) if p)
    jax = {"JAX_PLATFORMS": device, "XLA_PYTHON_CLIENT_PREALLOCATE": "false"}
    return {**os.environ, **ONE_THREAD, **jax, "PYTHONPATH": path}


def pinned(cmd: list[str]) -> list[str]:
    """``cmd`` pinned to core 0 where ``taskset`` exists."""
    return ["taskset", "-c", "0", *cmd] if shutil.which("taskset") else cmd


def run_child(python: str, args: list[str], device: str = "cpu") -> None:
    """Run ``dinosaur_child.py`` (``python`` its interpreter) with ``args`` (``device`` its
    JAX platform); raise with its last lines when it fails."""
    out = subprocess.run(pinned([python, str(CHILD), *args]), env=child_env(device), capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(args[:3])} failed:\n" + "\n".join(out.stderr.splitlines()[-15:]))


def run_peer(
    python: str,
    study: str,
    truncation: str,
    transforms: str,
    tmp: Path,
    dt: float | None = None,
    device: str = "cpu",
    precision: str = "float64",
) -> dict:
    """The peer at ``truncation`` (a key of ``GRIDS``) from the project's initial state of
    ``study``'s case at its nodes, at Δt ``dt`` s (None: ``GRIDS``'), under JAX on ``device`` in
    ``precision`` (float64: ``jax_enable_x64``; float32: JAX's default):
    its last day's fields (``peer_fields``), its start's (``start_`` + name), points, weights
    and CPU and wall seconds a simulated day."""
    from swe_sphere.cases.library import make_case

    st, (nodes, grid_dt) = STUDIES[study], GRIDS[truncation]
    dt = dt or grid_dt
    lat, lon, w = gaussian_grid(nodes)
    case = make_case(st.scene)
    u, v, h = case.initial(lat, lon)
    hs = case.hs(lat, lon)
    # the reference geopotential of the semi-implicit step: the case's mean depth, else h's
    mean_depth = getattr(case, "mean_depth", None) or float(np.sum(w * h) / np.sum(w))
    inp, out = tmp / f"{truncation}_in.npz", tmp / f"{truncation}_out.npz"
    state = dict(u=u, v=v, h=h, hs=hs, lat=lat, lon=lon, mean_depth=mean_depth)
    x64 = precision == "float64"
    np.savez(inp, truncation=int(truncation[1:]), nodes=nodes, dt=dt, days=st.days, x64=x64, **state)
    run_child(python, ["--peer-child", str(inp), str(out), transforms], device)
    r = dict(np.load(out))
    per_day = {"cpu_per_day": float(r["cpu"]) / st.days, "wall_per_day": float(r["wall"]) / st.days}
    r.update(lat=lat, lon=lon, weights=w, dt=dt, initial=(h, hs), **per_day)
    return r


def run_swe(study: str, config: str, tmp: Path, device: str = "cpu") -> dict:
    """swe_sphere's run of ``study`` in ``config`` on ``device`` (``swe_child``), as ``run_peer``'s dict."""
    out = tmp / f"{config.replace('/', '_').replace(',', '_')}.npz"
    run_child(sys.executable, ["--swe-child", study, config, str(out), device], device)
    r = dict(np.load(out))
    per_day = {k: float(r[k]) for k in ("cpu_per_day", "wall_per_day")}
    r.update(weights=r["area"], dt=float(r["dt"]), own=float(r["own"]), **per_day)
    return r


def l2(w, f, f_true) -> float:
    """Williamson et al. (1992) eq. 83 with quadrature weights ``w``."""
    return float(np.sqrt(np.sum(w * (f - f_true) ** 2) / np.sum(w * f_true**2)))


FIELDS = ("vorticity", "h", "h_surface")  # relative vorticity, fluid depth, free surface h + hs


def scores(run: dict, reference, day: float) -> dict:
    """The l2 (``l2``) of a run's ``FIELDS`` at ``day`` against ``reference`` at its own points."""
    r = reference.at(day, run["lat"], run["lon"])
    return {f: l2(run["weights"], run[f], r[f]) for f in FIELDS}


def start_check(run: dict) -> dict:
    """A peer's start against the project's state at its nodes: its h + hs's l2 from ours, and
    its (truncated) orography's from the exact hs (NaN without a mountain)."""
    h, hs = run["initial"]
    out = {"start_h_surface_l2": l2(run["weights"], run["start_h_surface"], h + hs)}
    peer_hs = run["start_h_surface"] - run["start_h"]
    out["orography_l2"] = l2(run["weights"], peer_hs, hs) if np.any(hs) else math.nan
    return out


def peer_available(python: str, device: str = "cpu") -> str | None:
    """Why the peer's interpreter cannot run Dinosaur under JAX on ``device``, or None when it can."""
    if shutil.which(python) is None:
        return f"no interpreter at {python} (see the docstring's install line)"
    probe = "import dinosaur, jax; jax.devices()"
    out = subprocess.run([python, "-c", probe], env=child_env(device), capture_output=True, text=True)
    return None if out.returncode == 0 else f"{python} cannot import dinosaur and jax on {device}"


def arguments():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=list(STUDIES), default="galewsky")
    ap.add_argument("--truncations", nargs="+", default=["T42", "T85", "T170"], choices=list(GRIDS))
    ap.add_argument(
        "--swe",
        nargs="*",
        help="swe_sphere runs, neNE/npNP/STEPPER[,DT][,SECTION.KEY=VALUE...] (default: the case's; none: none)",
    )
    ap.add_argument(
        "--peer-dt",
        type=float,
        nargs="+",
        help="the peer's Δt s, one for all truncations or one each (default: GRIDS')",
    )
    ap.add_argument(
        "--best-step",
        action="store_true",
        help="search each truncation's largest Δt (of --peer-steps) within --tolerance of its error at --reference-dt",
    )
    ap.add_argument(
        "--peer-steps",
        type=float,
        nargs="+",
        default=list(DAY_STEPS),
        help="--best-step's candidate Δt s, tried upwards from the reference (default: %(default)s)",
    )
    ap.add_argument(
        "--reference-dt",
        type=float,
        nargs="+",
        help="--best-step's reference Δt s, one for all truncations or one each (default: half GRIDS' Δt)",
    )
    ap.add_argument("--tolerance", type=float, default=0.01, help="--best-step's relative error loss (default: 1 %%)")
    ap.add_argument("--results", help="the results file's stem (default: the case's, e.g. peer_dinosaur_tc5)")
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--list", action="store_true", help="print swe_sphere's rows (Δt resolved) and run nothing")
    ap.add_argument("--transforms", choices=["fft", "real"], default="fft")
    ap.add_argument(
        "--precision",
        choices=["float64", "float32"],
        default="float64",
        help="both models' precision: the peer's JAX with or without x64, swe_sphere's numerics.precision "
        "(a float32 tendency) (default: %(default)s)",
    )
    ap.add_argument("--python", default=str(DEFAULT_PYTHON), help="the peer's interpreter (default: %(default)s)")
    ap.add_argument(
        "--device",
        choices=["cpu", "cuda"],
        default="cpu",
        help="both models' device; cuda: wall seconds (default: cpu)",
    )
    args = ap.parse_args()
    args.swe = list(STUDIES[args.case].swe) if args.swe is None else args.swe
    if args.precision != "float64":
        # a row that names its own precision keeps it (float32_state beside the mixed float32)
        args.swe = [
            config if "numerics.precision=" in config else f"{config},numerics.precision={args.precision}"
            for config in args.swe
        ]
    rows = []
    for config in args.swe:
        try:
            rows.append(at_limit(args.case, config))
        except ValueError as e:
            ap.error(str(e))
    args.swe = [config for config, _ in rows]
    if args.list:
        for config, fraction in rows:
            ne, np_, stepper, dt, _ = parse_swe(config)
            where = "" if fraction is None else f", {fraction:.3f} of {stepper}'s limit"
            print(f"{config}  (Δt {'the scene' + chr(39) + 's' if dt is None else f'{dt:.2f} s'}{where})")
        raise SystemExit(0)
    if args.best_step and args.peer_dt is not None:
        ap.error("--peer-dt and --best-step: the search chooses the peer's Δt")
    args.reference_dt = per_truncation(ap, "--reference-dt", args.reference_dt, args.truncations, 0.5)
    args.peer_dt = per_truncation(ap, "--peer-dt", args.peer_dt, args.truncations, 1.0)
    if any(x <= 0 for x in args.peer_steps) or args.tolerance <= 0:
        ap.error("--peer-steps and --tolerance must be > 0")
    return args


def per_truncation(ap, flag: str, given: list[float] | None, truncations: list[str], share: float) -> dict:
    """``flag``'s Δt per truncation: one for all or one each (default: ``share`` × ``GRIDS``')."""
    given = given or [share * GRIDS[t][1] for t in truncations]
    if len(given) not in (1, len(truncations)):
        ap.error(f"{flag}: one Δt, or one a truncation ({len(truncations)})")
    if any(x <= 0 for x in given):
        ap.error(f"{flag} must be > 0")
    return dict(zip(truncations, given * len(truncations) if len(given) == 1 else given))


def main() -> None:
    args = arguments()
    why = peer_available(args.python, args.device)
    if why is not None:
        print(f"peer_dinosaur: skipped: {why}")
        return
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
    from peer_levels import best_step, levels, summary
    from results import interleave, recorded

    from swe_sphere.cases.library import make_case
    from swe_sphere.cases.reference import Reference, reference_path

    st = STUDIES[args.case]
    case = make_case(st.scene)
    t341, t213 = Reference(reference_path(case, "T341")), Reference(reference_path(case, "T213"))
    order = interleave([("peer", t) for t in args.truncations], [("swe", c) for c in args.swe])
    with recorded(__file__, stem=args.results or st.stem) as figures, tempfile.TemporaryDirectory() as tmp:
        clock = "wall" if args.device == "cuda" else "cpu"  # a GPU run's CPU time is the host's waiting
        where = "one NVIDIA GPU" if args.device == "cuda" else "one thread"
        print(f"{st.scene} day {st.days:g}, l2 against T341 at each model's points; {where}, host core 0")
        print(
            f"peer: dinosaur, imex_rk_sil3 + exponential_step_filter defaults, {args.precision}, "
            f"{args.transforms} transforms"
        )
        table: dict[str, dict] = {}
        search: dict[str, dict] = {}  # truncation -> its best-step search (``best_step``)
        peers: dict[str, str] = {}  # truncation -> the name of its row the summary compares against

        refs = (t341, t213)

        def measure(rnd: int, kind: str, what: str, dt: float | None = None) -> tuple[str, dict]:
            return measure_run(args, Path(tmp), refs, table, clock, rnd, kind, what, dt)

        for rnd in range(args.rounds):
            for kind, what in order:
                if kind == "swe":
                    measure(rnd, kind, what)
                elif args.best_step and what not in search:
                    search[what] = best_step(
                        lambda dt, t=what: measure(rnd, "peer", t, dt),
                        args.reference_dt[what],
                        args.peer_steps,
                        args.tolerance,
                        st,
                        clock,
                    )
                    peers[what] = f"dinosaur {what} {search[what]['best_dt']:g} s"
                else:
                    dt = search[what]["best_dt"] if args.best_step else args.peer_dt[what]
                    peers[what] = measure(rnd, kind, what, dt)[0]
        summary(table, st, clock)
        figures["levels"] = levels(table, peers, st, clock)
        figures["device"] = args.device
        figures["case"] = st.scene
        figures["field"] = st.field
        figures["days"] = st.days
        if search:
            figures["best_step"] = search
        figures["runs"] = table


def measure_run(
    args, tmp: Path, refs, table: dict, clock: str, rnd: int, kind: str, what: str, dt: float | None = None
):
    """One run of round ``rnd``, the peer's (``kind`` "peer", ``what`` a truncation, at Δt ``dt``
    s, None: ``GRIDS``') or swe_sphere's (``what`` a ``parse_swe`` configuration), scored against
    ``refs`` (T341, T213), printed and added to ``table``: (its row's name, the row)."""
    st, (t341, t213) = STUDIES[args.case], refs
    load = os.getloadavg()[0]
    if kind == "peer":
        dt = dt or GRIDS[what][1]
        name = f"dinosaur {what} {dt:g} s"
    else:
        name, dt = f"swe_sphere {what}", parse_swe(what)[3]
    try:
        if kind == "peer":
            run = run_peer(args.python, args.case, what, args.transforms, tmp, dt, args.device, args.precision)
        else:
            run = run_swe(args.case, what, tmp, args.device)
    except RuntimeError as e:  # a blow-up the model refuses, a refused option: the row says so
        print(f"round {rnd + 1} {name}: failed (load {load:.2f}): {str(e).splitlines()[-1]}")
        row = table.setdefault(name, {f"l2_{f}": math.nan for f in FIELDS} | {"dt": dt or math.nan})
        row.update(failed=str(e).splitlines()[-1])
        row.setdefault("load", []).append(load)
        return name, row
    l2s = scores(run, t341, st.days)
    row = table.setdefault(name, dict(**{f"l2_{k}": v for k, v in l2s.items()}, dt=run["dt"]))
    row.setdefault(f"{clock}_per_day", []).append(run[f"{clock}_per_day"])
    row.setdefault("load", []).append(load)
    extra = start_check(run) if kind == "peer" else {f"own_ref_l2_{st.field}": run["own"]}
    row.update(extra)
    print(
        f"round {rnd + 1} {name} dt {run['dt']:g} s: vorticity l2 {l2s['vorticity']:.4g}, h l2 "
        f"{l2s['h']:.4g}, h + hs l2 {l2s['h_surface']:.4g}; "
        + ", ".join(f"{k} {v:.3g}" for k, v in extra.items())
        + f"; {run[f'{clock}_per_day']:.3g} {clock} s a simulated day (load {load:.2f})"
    )
    if kind == "peer" and what == args.truncations[-1] and not any("t213_vs_t341" in r for r in table.values()):
        r213 = dict(run, **t213.at(st.days, run["lat"], run["lon"]))
        row["t213_vs_t341"] = scores(r213, t341, st.days)[st.field]
    return name, row


if __name__ == "__main__":
    main()
