"""swe_sphere against HOMME's own shallow-water model ``sweqx``: whole process, one core each.

TC5 (zonal flow over a mountain) at ne30 np4, leapfrog-trapezoidal, Δt 90 s, one
day: HOMME runs the kit's 1-day timing namelist (``namelists/swtc5_ne30_1day_timing.nl``,
one MPI rank: ``/usr/bin/mpirun --allow-run-as-root -np 1 sweqx < namelist``),
swe_sphere the scene that matches it::

    SWE_SPHERE_THREADS=1 OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \\
    swe-sphere run tc5_mountain --ne 30 --stepper leapfrog_trapezoidal --dt 90 --days 1 --device cpu \\
        -s hyperviscosity.nu=1.5e15 -s hyperviscosity.nu_div=1.5e15 -s hyperviscosity.nu_s=1.5e15

The ν are the namelist's (``nu = nu_s = 1.5e15``, ``nu_div`` defaults to ``nu`` in
HOMME); the scene's own 3-hour e-folding rule gives 1.44e14 at ne30, and all three
are set because an explicit ``nu`` alone leaves ``nu_div`` and ``nu_s`` on that rule.
Both keep one ∇⁴ application per step (HOMME ``hypervis_subcycle = 1``; swe_sphere
finds forward Euler stable at this ν and Δt and does not subcycle).

Each round runs both, in alternating order (so drift in the load hits both alike),
and takes each process's CPU clock from ``os.wait4`` (user + system, its waited-for
children included: for HOMME, ``mpirun`` and the rank it starts), which a busy
machine inflates far less than the wall clock; both are whole processes, start-up
and output included (swe_sphere: interpreter, imports, grid, the kernel cache
loaded, outputs at days 0 and 1 and their scores against T213; HOMME: MPI start,
grid, interpolated output at day 0). A short swe_sphere run first fills Warp's
kernel cache (``WARP_CACHE_PATH``), so no round pays compilation.

The table: per round the CPU seconds of each and their ratio, then the medians and
the ratio of the medians, the wall seconds, and the 1-minute load average at the
end of each round, then HOMME's own timers (GPTL, wall) of the last round. Unless
``--no-l2``, one more HOMME run with output at day 1 (the namelist's
``output_frequency`` set to 1, not timed) gives HOMME's normalized l2 of h + hs
against the bundled T213 reference at days 0 and 1, beside swe_sphere's day 1
from its own summary. HOMME's Earth is larger (``rearth`` 6.376e6 m, the
reference's and swe_sphere's 6.37122e6 m), so its l2 is 5.6e-5 at day 0 already:
the figures are not a comparison of accuracy.

HOMME comes from a build kit, ``--kit DIR`` (``build.sh``, ``namelists/`` and HOMME's
source tarball; by default looked for beside the checkout, not part of the repository):
``--homme PATH`` names a built ``sweqx``, else the script uses
``BUILD/build/src/sweqx/sweqx`` and builds it there with the kit's ``build.sh``
when absent (Debian packages, root, 3–5 minutes on 2 cores; ``--build-dir``,
default ``~/.cache/swe_sphere/homme``). Where it cannot, it prints one line with
the reason and exits 0.

    python benchmarks/peers/peer_homme.py [--rounds 3] [--homme PATH] [--no-l2]

**Galewsky** (``--case galewsky``; figures in ``benchmarks/results/peer_homme/peer_homme_galewsky.json``):
HOMME's own Galewsky et al. (2004) set-up, test case ``swsj1`` (``shallow_water_mod``'s
``sj1_init_state``): the jet u0 = 80 m/s between π/7 and 5π/14, h from gradient-wind balance
(a 200-point Gauss integral at each node) shifted to a mean depth of 10 km (the mean of the
balanced h by the GLL quadrature; the project's by the trapezoid rule in latitude), plus the
120 m bump at 45°N, α = 1/3, β = 1/15, longitudes in (−π, π]: the project's ``cases.Galewsky``.
Its constants are Williamson's Ω and g, but its radius is ``rearth`` 6.376e6 m, and the set-up
takes the radius from ``physical_constants``' ``rearth0`` whatever the namelist says, so
the runs keep HOMME's radius (``--rearth`` sets the namelist's for the dynamics only, leaving
the balance at 6.376e6 m); its day-0 h is printed against ours at its points
(``start_h_l2``). The namelists are made from the kit's ne16 TC5 one (``namelist_with``):
``--runs neNE/STEPPER/DT``, STEPPER ``rkN`` (``integration = "runge_kutta"``,
``rk_stage_user = N``: N-stage second-order SSP Runge–Kutta, the ∇⁴ inside every stage) or
``lft`` (leapfrog-trapezoidal, the TC5 namelists'), ``nu = nu_s`` (``nu_div`` = ``nu``) the
scene's 3-hour rule at ne and np 4 (``config.hyperviscosity.efold_nu``: 1.76e15 m⁴ s⁻¹ at ne16, the
∇⁴ coefficient as swe_sphere's), 6 days, output of ζ (``zeta``: HOMME's ``vorticity_sphere``
+ DSS) and h at days 0 and 6, interpolated by HOMME to a Gaussian ``--nlat`` × 2 ``--nlat``
grid. Scored as ``peer_dinosaur`` scores every model (``peer_dinosaur.scores``: the T341
reference at HOMME's output points, Gauss weights; cos-latitude weights also printed).
Cost: CPU s of the whole process (``os.wait4``) of a 1-day and a 6-day run, (T₆ − T₁)/5: a
simulated day past the first, without start-up (HOMME's ``swsj1`` start-up alone is about
3 CPU minutes at ne16: the balance integral's Gauss points in ``longdouble_kind``, for every
element). swe_sphere's ``--swe`` runs (``peer_dinosaur.run_swe``: its step loop's CPU clock
between day 1 and day 6, one thread pinned to core 0), interleaved with HOMME's::

    python benchmarks/peers/peer_homme.py --case galewsky [--runs ne16/rk3/150] [--swe ne16/np4/kgu35,150]
"""

from __future__ import annotations

import argparse
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import recorded

REPO = Path(__file__).resolve().parents[2]
NAMELIST = "namelists/swtc5_ne30_1day_timing.nl"
MPIRUN = (
    "/usr/bin/mpirun"  # Debian's OpenMPI, which HOMME is built against (the mpich wheel's rejects --allow-run-as-root)
)
GALEWSKY_DAYS = 6
GALEWSKY_BASE = "namelists/swtc5_ne16_dt160.nl"  # the kit's namelist the Galewsky ones are made from
GALEWSKY_RUNS = ("ne16/rk3/150",)  # HOMME's default runs (parse_homme)
GALEWSKY_SWE = ("ne16/np4/kgu35,150",)  # swe_sphere's (peer_dinosaur.parse_swe)
HOMME_RADIUS = 6.376e6  # HOMME's rearth (physical_constants.F90)
NU = "1.5e15"  # the namelist's nu = nu_s; HOMME's nu_div defaults to nu
SWE_ARGS = [
    "run",
    "tc5_mountain",
    "--ne",
    "30",
    "--stepper",
    "leapfrog_trapezoidal",
    "--dt",
    "90",
    "--device",
    "cpu",
    "-s",
    f"hyperviscosity.nu={NU}",
    "-s",
    f"hyperviscosity.nu_div={NU}",
    "-s",
    f"hyperviscosity.nu_s={NU}",
    "--no-progress",
    "--overwrite",
]
SWE_CHILD = "import sys; from swe_sphere.cli import main; sys.exit(main(sys.argv[1:]))"
ONE_CORE = {"SWE_SPHERE_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


class Skip(Exception):
    """HOMME cannot be had here: the message says why."""


def default_kit() -> Path:
    """``shared/peers/homme`` beside the main checkout (the folder holding the git
    common directory, so a worktree finds the same kit), else beside this repository."""
    common = subprocess.run(
        ["git", "-C", str(REPO), "rev-parse", "--path-format=absolute", "--git-common-dir"],
        capture_output=True,
        text=True,
    )
    main_checkout = Path(common.stdout.strip()).parent if common.returncode == 0 else REPO
    return main_checkout.parent / "shared" / "peers" / "homme"


def add_homme_options(ap: argparse.ArgumentParser) -> None:
    """``--homme``, ``--kit`` and ``--build-dir``: where ``find_sweqx`` looks for HOMME."""
    ap.add_argument(
        "--homme", type=Path, help="a built sweqx (default: BUILD_DIR/build/src/sweqx/sweqx, built when absent)"
    )
    ap.add_argument("--kit", type=Path, default=default_kit(), help="the HOMME kit (default: %(default)s)")
    ap.add_argument(
        "--build-dir",
        type=Path,
        default=Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "swe_sphere" / "homme",
        help="where the kit builds HOMME (default: %(default)s)",
    )


def find_sweqx(args) -> Path:
    """The ``sweqx`` to time: ``--homme``, or the build folder's, built there when absent."""
    if not (args.kit / NAMELIST).is_file():
        raise Skip(f"no HOMME kit with {NAMELIST} at {args.kit} (--kit)")
    sweqx = args.homme or args.build_dir / "build" / "src" / "sweqx" / "sweqx"
    if not args.homme and not sweqx.is_file():
        print(
            f"building HOMME into {args.build_dir} with {args.kit / 'build.sh'} (3-5 min on 2 cores) ...",
            file=sys.stderr,
            flush=True,
        )
        # /usr/bin first: the kit's CMake cache names the bare wrappers (mpicc, mpif90), and an mpich wheel's
        # mpicc earlier on PATH links MPICH's libmpi.so.12 into sweqx beside OpenMPI's, which then cannot start
        env = dict(os.environ, PATH=f"/usr/bin:/bin:{os.environ.get('PATH', '')}")
        p = subprocess.run(
            ["bash", str(args.kit / "build.sh"), str(args.build_dir)], env=env, capture_output=True, text=True
        )
        if p.returncode != 0 or not sweqx.is_file():
            last = (p.stderr.strip() or p.stdout.strip() or "no output").splitlines()[-1]
            raise Skip(f"HOMME build failed (exit {p.returncode}): {last}")
    if not os.access(sweqx, os.X_OK):
        raise Skip(f"{sweqx}: not an executable")
    if not Path(MPIRUN).is_file():
        raise Skip(f"{MPIRUN} (Debian's OpenMPI, which HOMME is built against) not found")
    return sweqx


def timed(cmd, cwd, env=None, stdin=None) -> tuple[float, float, str]:
    """Run ``cmd`` to its end: (CPU s of the process and its waited-for children, wall s, stdout + stderr)."""
    with tempfile.TemporaryFile("w+") as log:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=stdin, stdout=log, stderr=subprocess.STDOUT)
        _, status, ru = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)  # reaped by wait4: tell Popen, so it does not wait again
        log.seek(0)
        text = log.read()
    if p.returncode != 0:
        raise RuntimeError(f"{cmd[0]} exited {p.returncode}:\n{text[-3000:]}")
    return ru.ru_utime + ru.ru_stime, wall, text


def run_swe(days: str, out: Path) -> tuple[float, float, str]:
    env = dict(os.environ, **ONE_CORE)
    return timed([sys.executable, "-c", SWE_CHILD, *SWE_ARGS, "--days", days, "--output", str(out)], REPO, env)


def run_homme(sweqx: Path, namelist_text: str, rundir: Path) -> tuple[float, float, str]:
    shutil.rmtree(rundir, ignore_errors=True)
    (rundir / "movies").mkdir(parents=True)
    (rundir / "input.nl").write_text(namelist_text)
    env = dict(os.environ, **ONE_CORE)
    with open(rundir / "input.nl") as nl:
        return timed([MPIRUN, "--allow-run-as-root", "-np", "1", str(sweqx)], rundir, env, nl)


def homme_timers(rundir: Path) -> dict[str, tuple[int, float]]:
    """HOMME's own GPTL timers of a run (``HommeSWTime_stats``): name -> (calls, wall s)."""
    text = (rundir / "HommeSWTime_stats").read_text()
    return {
        m[1]: (int(float(m[2])), float(m[3]))
        for m in re.finditer(r'(?m)^"(\w+)"\s+\S+\s+\d+\s+\d+\s+(\S+)\s+(\S+)', text)
    }


def homme_movie(movie: Path, day: float, names: tuple[str, ...]) -> dict:
    """One output time of HOMME's interpolated output (``movies/<test_case>1.nc``): the fields
    ``names`` at ``day`` (level 1, float64, (nlat, nlon)), with ``lat``, ``lon`` (radians,
    (nlat, nlon)) and ``weights``, the Gauss weights × 2π/nlon (sum 4π): the grid is Gaussian
    (``interp_gridtype = 2``), so these are the area weights of its points. RuntimeError when
    ``day`` is not stored or the latitudes are not an ascending Gaussian grid."""
    import netCDF4

    with netCDF4.Dataset(movie) as f:
        days = np.asarray(f["time"][:], dtype=np.float64)
        it = int(np.argmin(np.abs(days - day)))
        if abs(days[it] - day) > 1e-6:
            raise RuntimeError(f"{movie}: no day {day:g} (times {days})")
        lat = np.radians(np.asarray(f["lat"][:], dtype=np.float64))
        lon = np.radians(np.asarray(f["lon"][:], dtype=np.float64))
        out = {name: np.asarray(f[name][it, 0], dtype=np.float64) for name in names}
    mu, w = np.polynomial.legendre.leggauss(lat.size)  # nodes ascending, as HOMME's latitudes
    if not np.allclose(np.arcsin(mu), lat, atol=1e-9):
        raise RuntimeError(f"{movie}: latitudes are not an ascending Gaussian grid")
    out["lat"], out["lon"] = np.meshgrid(lat, lon, indexing="ij")
    out["weights"] = np.broadcast_to(w[:, None] * 2 * math.pi / lon.size, out["lat"].shape).copy()
    return out


def homme_l2(movie: Path, day: float) -> float:
    """Normalized l2 of h + hs at ``day`` in HOMME's interpolated output against T213.

    ``geop`` is already h + hs in m (HOMME writes (p + phis + pmean)/g; the kit's
    ``extract_day.py``)."""
    from swe_sphere.cases.reference import Reference, find_reference

    f = homme_movie(movie, day, ("geop",))
    ref = Reference(find_reference("tc5_mountain")).at(day, f["lat"], f["lon"])["h_surface"]
    w, h_surface = f["weights"], f["geop"]
    return math.sqrt(np.sum(w * (h_surface - ref) ** 2) / np.sum(w * ref**2))


def swe_l2(text: str) -> float:
    """swe_sphere's day-1 h + hs l2 against T213, from its summary line ``vs T213 h+hs l1 .. l2 ..``."""
    m = re.search(r"vs T213 h\+hs l1 \S+\s+l2 (\S+)", text)
    return float(m.group(1)) if m else math.nan


def homme_stepper(name: str) -> dict:
    """HOMME's namelist settings of a stepper: ``lft`` leapfrog-trapezoidal (``integration =
    "explicit"``, ``LFTfreq = 1``: ``advance_nonstag``, the ∇⁴ once a step after the dynamics),
    ``rkN`` the N-stage second-order SSP Runge–Kutta (``integration = "runge_kutta"``,
    ``rk_stage_user = N``: ``advance_nonstag_rk`` with ``rk_mod.RkInit``, the ∇⁴ inside every
    stage's tendency). ValueError for any other name."""
    if name == "lft":
        return {"integration": '"explicit"', "LFTfreq": 1, "rk_stage_user": 0}
    m = re.fullmatch(r"rk(\d+)", name)
    if not m or int(m[1]) < 2:
        raise ValueError(f"HOMME stepper {name!r}: expected lft or rkN with N >= 2")
    return {"integration": '"runge_kutta"', "rk_stage_user": int(m[1])}


def parse_homme(config: str) -> tuple[int, str, float]:
    """``"ne16/rk3/150"`` → (16, ``"rk3"``, 150.0): HOMME's ne, stepper (``homme_stepper``) and
    Δt (s, a whole number of steps a day). ValueError otherwise."""
    try:
        ne, stepper, dt = config.split("/")
        homme_stepper(stepper)
        ne, dt = int(ne.removeprefix("ne")), float(dt)
    except ValueError:
        raise ValueError(f"HOMME run {config!r}: expected neNE/STEPPER/DT, STEPPER lft or rkN") from None
    if abs(86400 / dt - round(86400 / dt)) > 1e-9:
        raise ValueError(f"HOMME run {config!r}: Δt must divide a day")
    return ne, stepper, dt


def namelist_with(text: str, **values) -> str:
    """``text`` with each ``key = ...`` line of ``values`` set, keys absent added to ``&ctl_nl``."""
    for key, value in values.items():
        line = f"{key} = {value}"
        text, n = re.subn(rf"(?m)^\s*{key}\s*=.*$", lambda _: line, text)
        if n == 0:
            text = text.replace("&ctl_nl\n", f"&ctl_nl\n{line}\n", 1)
    return text


def galewsky_namelist(base: str, config: str, days: int, nu: float, rearth: float, nlat: int) -> str:
    """HOMME's ``swsj1`` (Galewsky) namelist from the kit's ne16 TC5 one (``base``): the run
    ``config`` (``parse_homme``) for ``days``, ``nu = nu_s = nu`` (m⁴ s⁻¹; ``nu_div`` defaults
    to ``nu``), one ∇⁴ a step, the radius ``rearth`` (m), a state line each day, output of
    ζ and h at day 0 and ``GALEWSKY_DAYS`` on the Gaussian ``nlat`` × 2 ``nlat`` grid."""
    ne, stepper, dt = parse_homme(config)
    return namelist_with(
        base,
        test_case="'swsj1'",
        ne=ne,
        ndays=days,
        tstep=f"{dt:g}",
        statefreq=round(86400 / dt),
        nu=f"{nu:.6e}",
        nu_s=f"{nu:.6e}",
        hypervis_subcycle=1,
        rearth=f"{rearth:.8g}",
        output_end_time=days,
        output_frequency=GALEWSKY_DAYS,
        output_varnames1="'zeta', 'geop'",
        interp_nlat=nlat,
        interp_nlon=2 * nlat,
        **homme_stepper(stepper),
    )


def homme_galewsky(sweqx: Path, base: str, config: str, args, rundir: Path) -> dict:
    """HOMME's Galewsky run ``config``: 1 and ``GALEWSKY_DAYS`` days, whole processes; its fields
    at the last day (``homme_movie``: ``vorticity`` its ``zeta``, ``h`` = ``h_surface`` its
    ``geop``) with their points and weights, Δt, ν (the scene's 3-hour rule at ne, np 4), the
    CPU s a simulated day past the first, (T₆ − T₁)/5, and ``start_h_l2``: its day-0 h against
    the project's Galewsky h at its points (its set-up's distance from ours)."""
    from swe_sphere.cases.library import make_case
    from swe_sphere.config.hyperviscosity import efold_nu
    from swe_sphere.core.constants import EARTH

    ne, _, dt = parse_homme(config)
    nu = efold_nu(3.0, ne, 4, EARTH.a)
    text = {d: galewsky_namelist(base, config, d, nu, args.rearth, args.nlat) for d in (1, GALEWSKY_DAYS)}
    cpu1 = run_homme(sweqx, text[1], rundir)[0]
    cpu = run_homme(sweqx, text[GALEWSKY_DAYS], rundir)[0]
    movie = rundir / "movies" / "swsj11.nc"
    run, start = homme_movie(movie, GALEWSKY_DAYS, ("zeta", "geop")), homme_movie(movie, 0.0, ("geop",))
    h0 = make_case("galewsky").initial(start["lat"], start["lon"])[2]
    w = start["weights"]
    run.update(vorticity=run.pop("zeta"), h=run["geop"], h_surface=run.pop("geop"), dt=dt, nu=nu)
    run["start_h_l2"] = math.sqrt(np.sum(w * (start["geop"] - h0) ** 2) / np.sum(w * h0**2))
    run["cpu_per_day"] = (cpu - cpu1) / (GALEWSKY_DAYS - 1)
    run["namelist"] = text[GALEWSKY_DAYS]
    return run


def galewsky(args, sweqx: Path, figures: dict) -> int:
    """``--case galewsky``: HOMME's ``--runs`` and swe_sphere's ``--swe``, interleaved, each
    scored against T341 at its own points (``peer_dinosaur.scores``) and costed a simulated day;
    the table, and the figures in ``figures`` (``peer_dinosaur``'s layout)."""
    from peer_dinosaur import STUDIES, run_swe, scores
    from peer_levels import summary
    from results import interleave

    from swe_sphere.cases.library import make_case
    from swe_sphere.cases.reference import Reference, reference_path

    t341 = Reference(reference_path(make_case("galewsky"), "T341"))
    base = (args.kit / GALEWSKY_BASE).read_text()
    print(f"galewsky day {GALEWSKY_DAYS}, vorticity l2 (eq. 83) against T341 at each model's points; one thread each")
    print(
        f"HOMME: {MPIRUN} -np 1 {sweqx}, swsj1, rearth {args.rearth:g} m, output {args.nlat} x {2 * args.nlat} Gaussian"
    )
    table: dict[str, dict] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        order = interleave([("homme", c) for c in args.runs], [("swe", c) for c in args.swe])
        for rnd, (kind, config) in ((r, k) for r in range(args.rounds or 1) for k in order):
            load = os.getloadavg()[0]
            if kind == "homme":
                name, run = f"homme {config}", homme_galewsky(sweqx, base, config, args, tmp / "homme")
            else:
                name, run = f"swe_sphere {config}", run_swe("galewsky", config, tmp)
            l2s = scores(run, t341, GALEWSKY_DAYS)
            row = table.setdefault(name, {f"l2_{k}": v for k, v in l2s.items()} | {"dt": float(run["dt"])})
            row.setdefault("cpu_per_day", []).append(float(run["cpu_per_day"]))
            row.setdefault("load", []).append(load)
            if kind == "homme":
                cos = scores(dict(run, weights=np.cos(run["lat"])), t341, GALEWSKY_DAYS)["vorticity"]
                row.update(nu=run["nu"], start_h_l2=run["start_h_l2"], l2_vorticity_cos_weights=cos)
                figures.setdefault("namelists", {})[config] = run["namelist"]
            extra = {k: row[k] for k in ("nu", "start_h_l2", "l2_vorticity_cos_weights") if k in row}
            print(
                f"round {rnd + 1} {name}: vorticity l2 {l2s['vorticity']:.4g}, h l2 {l2s['h']:.4g}; "
                + "".join(f"{k} {v:.4g}; " for k, v in extra.items())
                + f"{run['cpu_per_day']:.3g} CPU s a simulated day (load {load:.2f})"
            )
    summary(table, STUDIES["galewsky"])
    figures.update(case="galewsky", field="vorticity", days=GALEWSKY_DAYS, rearth=args.rearth, runs=table)
    return 0


def arguments(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--case", choices=("tc5", "galewsky"), default="tc5", help="the comparison (default tc5)")
    ap.add_argument("--rounds", type=int, help="timed rounds, each one run of each (default 3 for tc5, 1 for galewsky)")
    add_homme_options(ap)
    ap.add_argument(
        "--no-l2", dest="l2", action="store_false", help="skip the untimed HOMME run that scores its day 1 against T213"
    )
    ap.add_argument("--runs", nargs="+", default=list(GALEWSKY_RUNS), help="galewsky: HOMME's runs, neNE/STEPPER/DT")
    ap.add_argument(
        "--swe", nargs="*", default=list(GALEWSKY_SWE), help="galewsky: swe_sphere's, neNE/npNP/STEPPER[,DT]"
    )
    ap.add_argument("--rearth", type=float, default=HOMME_RADIUS, help="galewsky: HOMME's radius, m (default its own)")
    ap.add_argument("--nlat", type=int, default=256, help="galewsky: HOMME's output latitudes (default %(default)s)")
    ap.add_argument("--results", help="the results file's stem (default peer_homme, or peer_homme_galewsky)")
    args = ap.parse_args(argv)
    if args.rounds is not None and args.rounds < 1:
        ap.error("--rounds must be at least 1")
    for config in args.runs:
        try:
            parse_homme(config)
        except ValueError as e:
            ap.error(str(e))
    args.results = args.results or ("peer_homme" if args.case == "tc5" else "peer_homme_galewsky")
    return args


def main(args: argparse.Namespace, figures: dict) -> int:
    try:
        sweqx = find_sweqx(args)
    except Skip as why:
        print(f"peer_homme: skipped: {why}")
        # exit 0 and no results file: `recorded` writes none on an exception, so the last one stays
        raise SystemExit(0) from None
    return galewsky(args, sweqx, figures) if args.case == "galewsky" else tc5(args, sweqx)


def tc5(args, sweqx: Path) -> int:
    """The TC5 comparison (the module docstring): ``--rounds`` timed rounds of one day each."""
    args.rounds = args.rounds or 3
    namelist = (args.kit / NAMELIST).read_text()

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        out = tmp / "swe.nc"
        run_swe("0.0125", out)  # 12 steps: fills the kernel cache; not timed
        for k in range(args.rounds):
            order = ("swe", "homme") if k % 2 == 0 else ("homme", "swe")
            got = {}
            for who in order:
                got[who] = run_swe("1", out) if who == "swe" else run_homme(sweqx, namelist, tmp / "homme")
            rows.append((got["swe"], got["homme"], os.getloadavg()[0]))
            timers = homme_timers(tmp / "homme")
            print(
                f"round {k + 1}: swe_sphere {got['swe'][0]:.2f} s CPU, HOMME {got['homme'][0]:.2f} s CPU",
                file=sys.stderr,
                flush=True,
            )
        if args.l2:
            day1 = re.sub(r"(?m)^(\s*output_frequency\s*=\s*)\d+", r"\g<1>1", namelist)
            run_homme(sweqx, day1, tmp / "homme")
            l2_homme = [homme_l2(tmp / "homme" / "movies" / "swtc51.nc", day) for day in (0.0, 1.0)]

    print(
        f"TC5 ne30 np4 leapfrog-trapezoidal dt 90 s, 1 day, nu {NU}, one core each, whole process "
        f"({args.rounds} rounds, alternating order)"
    )
    print(f"HOMME: {MPIRUN} -np 1 {sweqx} < {args.kit / NAMELIST}")
    print(
        f"{'round':>5} {'swe CPU s':>10} {'HOMME CPU s':>12} {'ratio':>7} {'swe wall s':>11} {'HOMME wall s':>13} {'load 1 min':>11}"
    )
    for k, (s, h, load) in enumerate(rows):
        print(f"{k + 1:>5} {s[0]:>10.2f} {h[0]:>12.2f} {s[0] / h[0]:>7.3f} {s[1]:>11.2f} {h[1]:>13.2f} {load:>11.2f}")
    med = [statistics.median(r[i][j] for r in rows) for i in (0, 1) for j in (0, 1)]
    print(f"{'median':>5} {med[0]:>10.2f} {med[2]:>12.2f} {med[0] / med[2]:>7.3f} {med[1]:>11.2f} {med[3]:>13.2f}")
    print(f"ratio of the medians (swe_sphere / HOMME, CPU): {med[0] / med[2]:.3f}")
    total, adv, rhs = (timers[name][1] for name in ("Total", "advance_nonstag", "compute_and_apply_rhs"))
    print(
        f"HOMME's timers (wall, last round): Total {total:.2f} s, time steps (advance_nonstag, {timers['advance_nonstag'][0]} calls) "
        f"{adv:.2f} s, of which RHS with its DSS and stage update (compute_and_apply_rhs, {timers['compute_and_apply_rhs'][0]} calls) "
        f"{rhs:.2f} s = {rhs / adv:.0%}, the rest (advance_hypervis: the ∇⁴ and its two DSS) {adv - rhs:.2f} s"
    )
    if args.l2:
        print(
            f"day-1 h+hs normalized l2 against T213: swe_sphere {swe_l2(rows[-1][0][2]):.3e}, HOMME {l2_homme[1]:.3e} "
            f"(HOMME at day 0: {l2_homme[0]:.3e}, from its Earth radius of 6.376e6 m against T213's 6.37122e6 m)"
        )
    return 0


if __name__ == "__main__":
    arguments_ = arguments()
    with recorded(__file__, stem=arguments_.results) as figures_:
        code = main(arguments_, figures_)
    sys.exit(code)
