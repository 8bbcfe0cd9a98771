"""The command line's flags: one parser, a function a subcommand, and the parent
parsers for what several share (``--debug``; the scene flags; ``--overwrite``)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from .exits import EXIT_BAD_INPUT


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        self.exit(EXIT_BAD_INPUT, f"swe-sphere: error: {message}\n")


WORKERS_HELP = (
    "runs at once in as many processes, the CPUs shared among them (default 1); under mpiexec -n N "
    "the N - 1 ranks after rank 0 run them, on any number of nodes"
)
PLOT_FIELDS = (
    "h",
    "h_surface",
    "u",
    "v",
    "speed",
    "vorticity",
    "divergence",
)  # = analysis.MAP_FIELDS (not imported: xarray)


STABILITY_CASES = (
    "tc5_mountain",
    "tc6_rossby_haurwitz",
    "galewsky",
    "tc7_era_january",
    "tc2_steady_alpha_pi4_100d",
    "tc6_inviscid_ne30",
)  # = the labels of stability.HARD_CASES (not imported: Warp)
STABILITY_NE = 8  # the stability suite's grid for the cases that do not fix one
PRECISIONS = ("float64", "float32", "float32_state")  # = config.resolve.PRECISIONS (not imported: Warp)
PRECISION_HELP = (
    "the RHS tendency's floating-point type, the state float64 (the scene's numerics.precision; "
    "default float64); float32 is refused with implicit, epi2 and epi3; float32_state holds a step's "
    "state and stages in float32 too, with the explicit Runge-Kutta steppers and a fixed dt"
)


def path(text: str) -> Path:
    """A path argument; '' is refused (``Path('')`` is the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty path")
    return Path(text)


def positive(text: str) -> float:
    """A number argument that must be finite and > 0 (a step, a length): argparse's one line
    names the option ("dt must be > 0 (got inf)" read as if inf were not > 0)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a finite number > 0 (got {text})")
    return value


def _scene_flags() -> argparse.ArgumentParser:
    """The flags that change the scene, shared by run, sweep and stability (a parent
    parser: its actions are shared, so none of its defaults may be set per command)."""
    s = _Parser(add_help=False)
    s.add_argument(
        "--ne",
        type=int,
        help=f"elements along a cube edge (stability: of the cases that do not fix their grid, default {STABILITY_NE})",
    )
    s.add_argument("--np", type=int, help="GLL points per element direction (2..8; default: the scene's)")
    s.add_argument("--days", type=positive, help="run length in days (default: the scene's)")
    s.add_argument(
        "-s",
        "--set",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a scene value (in every run of a sweep or suite), e.g. -s hyperviscosity.nu=5e14 "
        "(TOML value; validated like the file)",
    )
    s.add_argument(
        "--device",
        choices=("cpu", "cuda"),
        help="Warp device (default: SWE_SPHERE_DEVICE where set, else cuda when present, else cpu)",
    )
    s.add_argument("--precision", choices=PRECISIONS, help=PRECISION_HELP)
    return s


def _overwrite() -> argparse.ArgumentParser:
    o = _Parser(add_help=False)
    o.add_argument(
        "--overwrite", action="store_true", help="replace what the command writes where it exists (refused otherwise)"
    )
    return o


def parser() -> argparse.ArgumentParser:
    from ..core.runtime import package_version

    p = _Parser(prog="swe-sphere", description="Spectral-element shallow-water model on the cubed sphere.")
    p.add_argument("--debug", action="store_true", help="show the traceback of a failure")
    common = _Parser(add_help=False)  # --debug after the command too, without resetting one given before it
    common.add_argument(
        "--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of a failure"
    )
    p.add_argument("--version", action="version", version=f"swe-sphere {package_version()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    scene, overwrite = _scene_flags(), _overwrite()
    _run(sub, [common, scene, overwrite])
    sub.add_parser("list", help="list bundled scenes, steppers and terms", parents=[common])
    _plot(sub, [common, overwrite])
    _remap(sub, [common, overwrite])
    _sweep(sub, [common, scene, overwrite])
    _frontier(sub, [common, overwrite])
    _stability(sub, [common, scene, overwrite])
    _mesh(sub, [common, overwrite])
    return p


def _member_starts(p, sweep: bool) -> None:
    """How the members of ``run --members N`` (an ensemble) or ``sweep --members N`` (a sweep from
    each member's start) start: --perturbation (with --seed and --perturbation-degrees), --vary or
    --initial."""
    whose = "member k's sweep is of its scenes with its" if sweep else "each member's"
    p.add_argument(
        "--perturbation",
        type=float,
        metavar="METRES",
        help="with --members: member k starts from the case's state with h + METRES of white noise (seeded, one "
        "draw a unique node" + ("" if sweep else "; default 0: every member the same start") + ")",
    )
    p.add_argument("--seed", type=int, help="with --members and --perturbation: the noise's seed (default 0)")
    p.add_argument(
        "--perturbation-degrees",
        metavar="L_MIN,L_MAX",
        help="with --perturbation: the noise of the spherical harmonics of degrees L_MIN to L_MAX alone (each "
        "degree the same variance, an area-weighted RMS of METRES) instead of white noise",
    )
    p.add_argument(
        "--vary",
        action="append",
        metavar="KEY=V1,V2,...",
        help=f"with --members: {whose} own value of a case parameter (case.NAME), planet.omega, planet.gravity "
        "or hyperviscosity.nu (.nu_div, .nu_s), one a member (e.g. case.hhat=60,120,180), "
        + ("its reference run too" if sweep else "each member the single run of its scene")
        + "; repeatable, each KEY once",
    )
    p.add_argument(
        "--initial",
        type=path,
        metavar="ENSEMBLE.nc",
        help="with --members: member k starts from member k of an ensemble's run file at its last time"
        + (
            ""
            if sweep
            else "; without: the scene starts from a reanalysis file's state (a lat-lon netCDF file of height "
            "and wind, swe_sphere.io.reanalysis)"
        ),
    )


def _run_members(r) -> None:
    """``run``'s options of an ensemble: ``--members``, the members' starts, ``--blow-up``, ``--layout``."""
    r.add_argument(
        "--members",
        type=int,
        metavar="N",
        help="an ensemble: N members of the scene advanced together (any stepper; under step control one dt for "
        "every member), in the same launches "
        "on CUDA for an explicit stepper, else each on a model of its own in turn (--layout); one run file with "
        "a member dimension, each field's ensemble mean and spread; give the members their starts (--perturbation, "
        "--vary or --initial), else they are alike",
    )
    _member_starts(r, sweep=False)
    r.add_argument(
        "--blow-up",
        choices=("stop", "drop"),
        help="with --members: a member's blow-up stops every member (stop: the default) or drops it, the "
        "others going on (drop: its fields NaN from then on; the members in turn)",
    )
    r.add_argument(
        "--layout",
        choices=("shared", "in_turn"),
        help="with --members: the members in the same launches (shared: the default on CUDA) or each on a "
        "model of its own (in_turn: the default on a CPU, and for any stepper but an explicit one or members "
        "whose g or nu differ)",
    )


def _run(sub, parents) -> None:
    r = sub.add_parser("run", help="run a scene (a TOML file under testcases/, or its name)", parents=parents)
    r.add_argument(
        "scene",
        nargs="?",
        help="scene file, e.g. testcases/tc5_mountain.toml, a bundled scene name, or a reanalysis file (FILE.nc: "
        "its 500 hPa-like state with case 7's settings)",
    )
    r.add_argument("--level", type=float, metavar="HPA", help="a reanalysis file's pressure level (case.level)")
    r.add_argument(
        "--time",
        metavar="WHEN",
        help="a reanalysis file's time: a date (2021-01-15T00), NAME=VALUE of another dimension (month=1) or a "
        "value of the one dimension left (case.time)",
    )
    r.add_argument(
        "--truncation",
        type=int,
        metavar="L",
        help="a reanalysis file's triangular truncation T L, a sharp cut (case.truncation; default: what the file "
        "and the grid resolve, tapered)",
    )
    r.add_argument(
        "--mesh",
        type=path,
        metavar="FILE.g",
        help="run on this Exodus II mesh (HOMME's mesh_file, ne = 0) instead of the scene's grid",
    )
    r.add_argument("--dt", type=positive, help="time step in seconds")
    r.add_argument("--stepper", help="time stepper (see `swe-sphere list`)")
    r.add_argument(
        "--output",
        type=path,
        help="netCDF output file (default: <scene>_ne<ne>np<np>_<stepper>.nc, with _<days>d, _dt<dt> and the "
        "planet where they are not the scene's)",
    )
    r.add_argument(
        "--no-progress",
        action="store_true",
        help="no progress bar (there is one only on a terminal), nor progress lines off one",
    )
    r.add_argument(
        "--progress-every",
        type=float,
        metavar="SECONDS",
        help="off a terminal (stderr a pipe or file: nohup, CI), where no bar is drawn: a line of the model day, "
        "the share done and the time left on stdout every SECONDS of wall time (default 30; 0: none)",
    )
    r.add_argument(
        "--restart-every",
        type=float,
        metavar="DAYS",
        help="write a restart file <output stem>.restart.nc every DAYS model days and at the end",
    )
    r.add_argument(
        "--continue",
        dest="continue_from",
        type=path,
        metavar="CHECKPOINT",
        help="continue a restart file (bitwise as if never stopped); --days sets the new end day; with another "
        "--stepper or --dt, a new run from its state (multistep steppers start afresh)",
    )
    r.add_argument("--compress", action="store_true", help="store fields as float32 with zlib (smaller, not bitwise)")
    r.add_argument(
        "--no-cells",
        action="store_true",
        help="leave the GLL control volumes (cell bounds, the UGRID dual mesh) out of the run file: "
        "the scene's output.cells = false",
    )
    _run_members(r)
    r.add_argument(
        "--graphs",
        help="steps as captured graphs: auto (on CUDA; the default, or env SWE_SPHERE_GRAPHS), on "
        "(also on a CPU), off (plain launches); a graph that fails or differs from plain launches "
        "falls back to them with one line",
    )


def _plot(sub, parents) -> None:
    pl = sub.add_parser(
        "plot", help="PNG lat-lon maps of a run file's fields and its invariants/errors against time", parents=parents
    )
    pl.add_argument("run", type=path, help="run file (netCDF written by `swe-sphere run`)")
    pl.add_argument(
        "--field",
        nargs="+",
        metavar="FIELD",
        help=f"field(s) to map or zonally average: {', '.join(PLOT_FIELDS)} or a passive tracer of the run "
        "(its [tracers] names) (default h_surface = h + hs)",
    )
    pl.add_argument("--day", nargs="+", type=float, help="model day(s) to map, each an output time (default: the last)")
    pl.add_argument(
        "--diff",
        type=path,
        metavar="REFERENCE",
        help="map the difference to another run file or a reference: a file or a bundled truncation (T213, T341)",
    )
    pl.add_argument(
        "--output",
        type=path,
        default=Path("."),
        metavar="DIR",
        help="folder for the PNGs (default: .); with --animate a name ending .gif or .mp4 is the file",
    )
    pl.add_argument(
        "--lat-range", nargs=2, type=float, metavar=("SOUTH", "NORTH"), help="map only this latitude band (degrees)"
    )
    pl.add_argument("--force", action="store_true", help="--diff against a run of another case or grid")
    pl.add_argument(
        "--member",
        metavar="K|mean|spread",
        help="an ensemble's run file (run --members): plot member K (0 to N-1), the ensemble mean or its spread",
    )
    pl.add_argument(
        "--spectrum",
        action="store_true",
        help="instead of maps: the kinetic-energy spectrum by spherical-harmonic degree (rotational, divergent, total; PNG and CSV)",
    )
    pl.add_argument(
        "--animate",
        nargs="?",
        const="gif",
        choices=("gif", "mp4"),
        help="instead of maps: one --field over the run's output times (or the --day list) as a GIF "
        "(matplotlib's PillowWriter), or an MP4 where ffmpeg is on PATH; one colour scale over every frame",
    )
    pl.add_argument(
        "--width",
        type=int,
        metavar="PIXELS",
        help="a map's width in pixels, its height half (400..4000; default 1200, --animate's 800)",
    )
    pl.add_argument(
        "--zonal-mean",
        action="store_true",
        help="instead of maps: the zonal mean of each --field against latitude (PNG)",
    )


def _remap(sub, parents) -> None:
    rm = sub.add_parser(
        "remap", help="a run file on a regular lat-lon grid (CF netCDF), by GLL interpolation", parents=parents
    )
    rm.add_argument("run", type=path, help="run file (netCDF written by `swe-sphere run`)")
    rm.add_argument(
        "--resolution", type=float, default=1.0, help="grid spacing in degrees; must divide 180 (default 1.0)"
    )
    rm.add_argument("--output", type=path, help="netCDF output file (default: <run>_latlon<resolution>.nc)")


def _sweep(sub, parents) -> None:
    sw = sub.add_parser(
        "sweep", help="error against dt against wall time for several steppers (resumable)", parents=parents
    )
    sw.add_argument("scene", nargs="?", help="scene file or bundled scene name (none with --from)")
    sw.add_argument(
        "--from",
        dest="branch_from",
        type=path,
        metavar="RESTART.nc",
        help="start every run (and the small-dt reference run) from this restart file's state and day, with "
        "its scene and grid; --days sets the end day",
    )
    sw.add_argument("--steppers", help="comma-separated stepper names (default rk4,kgu35,imex,implicit)")
    sw.add_argument(
        "--members",
        type=int,
        metavar="N",
        help="with one start (--perturbation, --initial or --vary): every run made from each of N starts, an "
        "ensemble's members', each member's sweep under member<k>/ and each run's errors' mean and spread over "
        "them in members.csv",
    )
    _member_starts(sw, sweep=True)
    group = sw.add_mutually_exclusive_group()
    group.add_argument("--dt", help="comma-separated time steps in seconds")
    group.add_argument(
        "--courant",
        help="comma-separated multiples of the explicit gravity-wave limit (default 0.5,1,2,5,10,30,60,100)",
    )
    group.add_argument(
        "--runs",
        metavar="STEPPER@COURANT,...",
        help="only these (stepper, multiple of the gravity-wave limit) runs, e.g. rk4@1,imex@5,implicit@20, "
        "instead of every --steppers x --courant; STEPPER@rtol=1e-5, @rtol_per_day=1e-4 (per unit step), "
        "@balance=0.1 or @cfl=1.5: a run whose steps are chosen step to step (time.control error, balanced or cfl)",
    )
    sw.add_argument(
        "--cost",
        choices=("cpu", "wall"),
        default="cpu",
        help="the clock that ranks the runs: process CPU time (default; reproducible with SWE_SPHERE_THREADS=1 "
        "OPENBLAS_NUM_THREADS=1 on a loaded machine) or wall time",
    )
    sw.add_argument(
        "--output",
        type=path,
        help="directory for results (default ./sweep_<scene>_<grid>np<np>_<days>d, e.g. sweep_tc5_mountain_ne16np4_15d); "
        "a rerun reuses the runs made there with the same settings",
    )
    sw.add_argument(
        "--filter-days",
        type=float,
        metavar="DAYS",
        help="also score the balanced flow: Lanczos low-pass in time with this cutoff period (runs go on past --days by the half window)",
    )
    sw.add_argument(
        "--filter-window",
        type=float,
        metavar="DAYS",
        help="the filter's half window around the last day (default 1.5 x --filter-days)",
    )
    sw.add_argument(
        "--filter-every", type=float, default=3.0, metavar="HOURS", help="the filter's snapshot interval (default 3 h)"
    )
    sw.add_argument("--workers", type=int, default=1, help=WORKERS_HELP)


def _frontier(sub, parents) -> None:
    fr = sub.add_parser(
        "frontier",
        help="error against cost over grids (ne x np) and steppers: the Pareto front (resumable)",
        parents=parents,
    )
    fr.add_argument("scene", help="scene file or bundled scene name")
    fr.add_argument("--ne", required=True, help="comma-separated elements along a cube edge, e.g. 8,16,30")
    fr.add_argument("--np", required=True, help="comma-separated GLL points per element direction (2..8), e.g. 3,4,6")
    fr.add_argument(
        "--steppers",
        metavar="STEPPER[@FRACTION],...",
        help="explicit steppers, each at a fraction of its stability limit (default kgu35,fbrk32 at 0.8)",
    )
    fr.add_argument("--error", choices=("h", "vorticity", "divergence"), help="the error scored (default: the case's)")
    fr.add_argument(
        "--reference", help='what the runs are scored against: "T213", "T341" or a file (default: the scene\'s)'
    )
    fr.add_argument("--days", type=float, help="run length in days (default: the scene's)")
    fr.add_argument(
        "-s",
        "--set",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a scene value in every run",
    )
    fr.add_argument(
        "--device",
        choices=("cpu", "cuda"),
        help="Warp device (default: SWE_SPHERE_DEVICE where set, else cuda when present, else cpu)",
    )
    fr.add_argument("--precision", choices=PRECISIONS, help=PRECISION_HELP)
    fr.add_argument(
        "--cost", choices=("cpu", "wall"), default="cpu", help="the clock that costs the runs (default cpu)"
    )
    fr.add_argument("--target", help="comma-separated errors: the cheapest configuration that reaches each")
    fr.add_argument(
        "--peers",
        type=path,
        metavar="FILE",
        help="other models' points for frontier.png: CSV or JSON of model, label, error, cost_per_day",
    )
    fr.add_argument(
        "--output",
        type=path,
        help="directory for results (default ./frontier_<scene>_<days>d); a rerun reuses its runs",
    )
    fr.add_argument("--workers", type=int, default=1, help=WORKERS_HELP)


def _stability(sub, parents) -> None:
    st = sub.add_parser(
        "stability", help="largest stable dt of each stepper on the hard cases, by bisection", parents=parents
    )
    st.add_argument("cases", nargs="*", help=f"case labels, any of {', '.join(STABILITY_CASES)} (default: all)")
    st.add_argument(
        "--steppers", default="leapfrog,ssprk3,semi_implicit,implicit", help="comma-separated stepper names"
    )
    st.add_argument(
        "--mesh",
        type=path,
        metavar="FILE.g",
        help="every case on this Exodus II mesh instead of the ne cube (not the cases that fix their grid)",
    )
    st.add_argument(
        "--output",
        type=path,
        help="directory for stability.csv and stability.nc (default: stability_<cases, or all>_ne<ne> or "
        "_<the mesh file's stem>, made if missing)",
    )
    st.add_argument("--workers", type=int, default=1, help=WORKERS_HELP)


def _mesh(sub, parents) -> None:
    me = sub.add_parser(
        "mesh",
        help="write an Exodus II .g mesh (as HOMME reads): the cube, a stretched cube, or the cube refined over a box",
        parents=parents,
    )
    me.add_argument("--ne", type=int, required=True, help="elements along a cube face's edge (the base cube)")
    me.add_argument("--stretch-factor", type=float, help="Schmidt stretch c >= 1 toward the target (FV3's stretch_fac)")
    me.add_argument("--target-lat", type=float, help="the stretch's target latitude, degrees (default 90)")
    me.add_argument("--target-lon", type=float, help="the stretch's target longitude, degrees east (default 0)")
    me.add_argument(
        "--refine-box",
        nargs=4,
        type=float,
        metavar=("LAT_MIN", "LAT_MAX", "LON_MIN", "LON_MAX"),
        help="refine the cube over this latitude-longitude box (degrees), within one cube face's reach",
    )
    me.add_argument("--levels", type=int, help="levels of 2x refinement in the box (default 1: 2x; 2: 4x)")
    me.add_argument("--smoothing", type=int, help="Laplacian smoothing sweeps at most (default 100)")
    me.add_argument("--output", "-o", type=path, required=True, help="the .g file to write")
