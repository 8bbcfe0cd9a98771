"""Command line: ``swe-sphere run | list | plot | remap | sweep | stability | mesh``.

Exit status: 0 success; 2 bad input (one line naming the field or value, no
output file); 3 blow-up, solver failure or too little memory (message with
step, model time and place; the output file keeps every good output time);
130 / 143 interrupted by SIGINT / SIGTERM (output so far and a restart file
kept; also for a signal once the outputs are complete); 1 an internal error. Every failure is one line on stderr; ``--debug``
(or SWE_SPHERE_DEBUG=1) shows the traceback instead.
"""

from __future__ import annotations

import argparse
import errno
import math
import os
import sys
import time
from pathlib import Path

from .core.errors import BlowUp, CheckpointError, Interrupted, OutputError, ResourceError, SceneError, StepFailure

EXIT_INTERNAL, EXIT_BAD_INPUT, EXIT_BLOWUP = 1, 2, 3


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
    "tc2_steady_alpha_pi4_100d",
    "tc6_inviscid_ne30",
)  # = the labels of stability.HARD_CASES (not imported: Warp)


def _path(text: str) -> Path:
    """A path argument; '' is refused (``Path('')`` is the current folder)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("empty path")
    return Path(text)


def _parser() -> argparse.ArgumentParser:
    from .core.runtime import package_version

    Path = _path  # every path option below (type=Path) refuses an empty path
    p = _Parser(prog="swe-sphere", description="Spectral-element shallow-water model on the cubed sphere.")
    p.add_argument("--debug", action="store_true", help="show the traceback of a failure")
    common = _Parser(add_help=False)  # --debug after the command too, without resetting one given before it
    common.add_argument(
        "--debug", action="store_true", default=argparse.SUPPRESS, help="show the traceback of a failure"
    )
    p.add_argument("--version", action="version", version=f"swe-sphere {package_version()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("run", help="run a scene (a TOML file under testcases/, or its name)", parents=[common])
    r.add_argument("scene", nargs="?", help="scene file, e.g. testcases/tc5_mountain.toml, or a bundled scene name")
    r.add_argument("--ne", type=int, help="elements along a cube edge")
    r.add_argument("--np", type=int, help="GLL points per element direction (2..8)")
    r.add_argument(
        "--mesh",
        type=Path,
        metavar="FILE.g",
        help="run on this Exodus II mesh (HOMME's mesh_file, ne = 0) instead of the scene's grid",
    )
    r.add_argument("--dt", type=float, help="time step in seconds")
    r.add_argument("--days", type=float, help="run length in days")
    r.add_argument("--stepper", help="time stepper (see `swe-sphere list`)")
    r.add_argument("--device", choices=("cpu", "cuda"), help="Warp device (default: cuda when present, else cpu)")
    r.add_argument(
        "--output",
        type=Path,
        help="netCDF output file (default: <scene>_ne<ne>np<np>_<stepper>.nc, with _<days>d, _dt<dt> and the "
        "planet where they are not the scene's)",
    )
    r.add_argument("--no-progress", action="store_true", help="no progress bar (there is one only on a terminal)")
    r.add_argument(
        "-s",
        "--set",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a scene value, e.g. -s hyperviscosity.nu=5e14 (TOML value; validated like the file)",
    )
    r.add_argument("--overwrite", action="store_true", help="replace an existing output (and restart) file")
    r.add_argument(
        "--restart-every",
        type=float,
        metavar="DAYS",
        help="write a restart file <output stem>.restart.nc every DAYS model days and at the end",
    )
    r.add_argument(
        "--continue",
        dest="continue_from",
        type=Path,
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
    r.add_argument(
        "--graphs",
        help="steps as captured graphs: auto (on CUDA; the default, or env SWE_SPHERE_GRAPHS), on "
        "(also on a CPU), off (plain launches); a graph that fails or differs from plain launches "
        "falls back to them with one line",
    )
    sub.add_parser("list", help="list bundled scenes, steppers and terms", parents=[common])
    pl = sub.add_parser(
        "plot", help="PNG lat-lon maps of a run file's fields and its invariants/errors against time", parents=[common]
    )
    pl.add_argument("run", type=Path, help="run file (netCDF written by `swe-sphere run`)")
    pl.add_argument(
        "--field",
        nargs="+",
        choices=PLOT_FIELDS,
        help="field(s) to map or zonally average (default h_surface = h + hs)",
    )
    pl.add_argument("--day", nargs="+", type=float, help="model day(s) to map, each an output time (default: the last)")
    pl.add_argument(
        "--diff",
        type=Path,
        metavar="REFERENCE",
        help="map the difference to another run file or a reference: a file or a bundled truncation (T213, T341)",
    )
    pl.add_argument("--output", type=Path, default=Path("."), metavar="DIR", help="folder for the PNGs (default: .)")
    pl.add_argument(
        "--lat-range", nargs=2, type=float, metavar=("SOUTH", "NORTH"), help="map only this latitude band (degrees)"
    )
    pl.add_argument("--force", action="store_true", help="--diff against a run of another case or grid")
    pl.add_argument("--overwrite", action="store_true", help="replace existing PNGs")
    pl.add_argument(
        "--spectrum",
        action="store_true",
        help="instead of maps: the kinetic-energy spectrum by spherical-harmonic degree (rotational, divergent, total; PNG and CSV)",
    )
    pl.add_argument(
        "--zonal-mean",
        action="store_true",
        help="instead of maps: the zonal mean of each --field against latitude (PNG)",
    )
    rm = sub.add_parser(
        "remap", help="a run file on a regular lat-lon grid (CF netCDF), by GLL interpolation", parents=[common]
    )
    rm.add_argument("run", type=Path, help="run file (netCDF written by `swe-sphere run`)")
    rm.add_argument(
        "--resolution", type=float, default=1.0, help="grid spacing in degrees; must divide 180 (default 1.0)"
    )
    rm.add_argument("--output", type=Path, help="netCDF output file (default: <run>_latlon<resolution>.nc)")
    rm.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    sw = sub.add_parser(
        "sweep", help="error against dt against wall time for several steppers (resumable)", parents=[common]
    )
    sw.add_argument("scene", nargs="?", help="scene file or bundled scene name (none with --from)")
    sw.add_argument(
        "--from",
        dest="branch_from",
        type=Path,
        metavar="RESTART.nc",
        help="start every run (and the small-dt reference run) from this restart file's state and day, with "
        "its scene and grid; --days sets the end day",
    )
    sw.add_argument("--steppers", help="comma-separated stepper names (default rk4,kgu35,imex,implicit)")
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
        "instead of every --steppers x --courant",
    )
    sw.add_argument("--ne", type=int, help="elements along a cube edge")
    sw.add_argument("--np", type=int, help="GLL points per element direction (2..8)")
    sw.add_argument("--days", type=float, help="run length in days")
    sw.add_argument(
        "-s",
        "--set",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a scene value in every run, e.g. -s case.initialization=dfi (as for run)",
    )
    sw.add_argument("--device", choices=("cpu", "cuda"), help="Warp device (default: cuda when present, else cpu)")
    sw.add_argument(
        "--cost",
        choices=("cpu", "wall"),
        default="cpu",
        help="the clock that ranks the runs: process CPU time (default; reproducible with SWE_SPHERE_THREADS=1 "
        "OPENBLAS_NUM_THREADS=1 on a loaded machine) or wall time",
    )
    sw.add_argument(
        "--output",
        type=Path,
        help="directory for results (default ./sweep_<scene>_<grid>np<np>_<days>d, e.g. sweep_tc5_mountain_ne16np4_15d); "
        "a rerun reuses the runs made there with the same settings",
    )
    sw.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the results (sweep.csv, sweep.nc, verdicts.csv, PNGs) of an earlier sweep in --output",
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
    st = sub.add_parser(
        "stability", help="largest stable dt of each stepper on the hard cases, by bisection", parents=[common]
    )
    st.add_argument("cases", nargs="*", help=f"case labels, any of {', '.join(STABILITY_CASES)} (default: all)")
    st.add_argument(
        "--steppers", default="leapfrog,ssprk3,semi_implicit,implicit", help="comma-separated stepper names"
    )
    st.add_argument("--ne", type=int, default=8, help="coarse grid for cases that do not fix one (default 8)")
    st.add_argument(
        "--mesh",
        type=Path,
        metavar="FILE.g",
        help="every case on this Exodus II mesh instead of the ne cube (not the cases that fix their grid)",
    )
    st.add_argument("--np", type=int, help="GLL points (default: the scene's)")
    st.add_argument("--days", type=float, help="run length for cases that do not fix one (default: the scene's)")
    st.add_argument(
        "-s",
        "--set",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help="override a scene value in every case, e.g. -s hyperviscosity.efold_hours=6 (as for run)",
    )
    st.add_argument("--device", choices=("cpu", "cuda"), help="Warp device (default: cuda when present, else cpu)")
    st.add_argument(
        "--output",
        type=Path,
        help="directory for stability.csv and stability.nc (default: stability_<cases, or all>_ne<ne> or "
        "_<the mesh file's stem>, made if missing)",
    )
    st.add_argument(
        "--overwrite", action="store_true", help="replace an earlier stability.csv and stability.nc in --output"
    )
    st.add_argument("--workers", type=int, default=1, help=WORKERS_HELP)
    me = sub.add_parser(
        "mesh",
        help="write an Exodus II .g mesh (as HOMME reads): the cube, a stretched cube, or the cube refined over a box",
        parents=[common],
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
    me.add_argument("--output", "-o", type=Path, required=True, help="the .g file to write")
    me.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    return p


def _cmd_mesh(args) -> int:
    from .grid.cubed_sphere import CubedSphere
    from .grid.mesh import write_exodus
    from .grid.quality import element_sizes
    from .grid.refine import Box, make_mesh
    from .io.run_file import check_target

    check_target(args.output, args.overwrite)
    box = None if args.refine_box is None else Box(*args.refine_box)
    mesh = make_mesh(
        args.ne,
        stretch_factor=args.stretch_factor,
        target_lat=args.target_lat,
        target_lon=args.target_lon,
        box=box,
        levels=args.levels,
        smoothing=args.smoothing,
    )
    write_exodus(args.output, mesh)
    sizes = element_sizes(CubedSphere(0, 4, 1.0, mesh=mesh)).summary()
    print(
        f"{args.output}: {mesh.name}: {mesh.nelem} elements, {mesh.nnodes} nodes; at np 4 the largest "
        f"Dinv-based distortion {sizes['distortion_max']:.2f}, area ratio {sizes['area_ratio']:.3g}"
    )
    return 0


def _cmd_list() -> int:
    import re

    from .config.scene import list_scenes, load_scene
    from .model.shallow_water import TERMS
    from .steppers import STEPPERS

    print("scenes:")
    for path in list_scenes():
        s = load_scene(path)
        print(f"  {path.stem:32s} {s.description}")
        stepper = STEPPERS[s.stepper].label(s.stepper_options)
        print(f"  {'':32s} ne={s.ne} np={s.np} {stepper} dt={s.dt:g}s {s.days:g} days; terms: {', '.join(s.terms)}")
    print("steppers:")
    for name, cls in STEPPERS.items():
        summary = " ".join(cls.__doc__.split("\n\n")[0].split())  # the first paragraph, unwrapped
        summary = summary.replace("``", "")  # reST literals read as plain text on a terminal
        sentence = re.split(r"\.\s+(?=[A-Z])", summary)[0].rstrip(".")  # the first sentence, whole ("eq. 2" kept)
        print(f"  {name:32s} {sentence}.")
    print("terms:")
    print("  " + ", ".join(TERMS))
    return 0


def _warp_device(requested):
    from .core.backend import pick_device

    return pick_device(requested)


def _numbers(text: str, name: str) -> list[float]:
    """``--name 1,2.5`` → [1.0, 2.5]; the sweep's plan checks the values."""
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--{name} must be comma-separated numbers (got {text!r})") from None


def _steppers(text: str) -> list[str]:
    from .steppers import STEPPERS

    steppers = [s for s in text.split(",") if s]
    if not steppers:
        raise ValueError(f"--steppers names no stepper (got {text!r})")
    for s in steppers:
        if s not in STEPPERS:
            raise ValueError(f"unknown stepper {s!r} (known: {', '.join(STEPPERS)})")
    return steppers


def _runs(text: str) -> list[tuple[str, float]]:
    """``--runs rk4@1,imex@5`` → [("rk4", 1.0), ("imex", 5.0)]."""
    pairs = []
    for item in text.split(","):
        name, sep, factor = item.strip().partition("@")
        if not sep:
            raise ValueError(f"--runs needs STEPPER@COURANT pairs (got {item.strip()!r})")
        stepper = _steppers(name.strip())[0]
        try:
            multiple = float(factor)
        except ValueError:
            multiple = math.nan
        if not (math.isfinite(multiple) and multiple > 0):  # the multiple of the gravity-wave limit
            raise ValueError(
                f"--runs {item.strip()}: {factor.strip()!r} is not a number > 0 (a multiple of the gravity-wave "
                f"limit, e.g. {stepper}@0.5)"
            )
        pairs.append((stepper, multiple))
    return pairs


def _cmd_sweep(args) -> int:
    from .core.workers import executor
    from .studies import sweep

    runs = _runs(args.runs) if args.runs is not None else None
    plan = sweep.plan(
        args.scene,
        steppers=None if args.steppers is None else _steppers(args.steppers),
        dts=None if args.dt is None else _numbers(args.dt, "dt"),
        courant=None if args.courant is None else _numbers(args.courant, "courant"),
        runs=runs,
        ne=args.ne,
        np_=args.np,
        days=args.days,
        overrides=_overrides(args.set),
        restart=args.branch_from,
        filter_days=args.filter_days,
        filter_every=args.filter_every,
        filter_window=args.filter_window,
    )
    device = _warp_device(args.device)
    with executor(args.workers) as pool:
        if pool is None:  # an MPI worker rank: its share is done
            return 0
        plan.run(args.output or plan.default_output, device, pool=pool, cost=args.cost, overwrite=args.overwrite)
    return 0


def _cmd_stability(args) -> int:
    from .core.workers import executor
    from .io.run_file import check_results, folder_lock
    from .studies.stability import HARD_CASES, OUTPUTS, format_table, run_suite, suite_scenes, write_table

    known = {c[0]: c for c in HARD_CASES}
    for label in args.cases:
        if label not in known:
            raise ValueError(f"unknown stability case {label!r} (known: {', '.join(known)})")
    steppers = _steppers(args.steppers)
    if args.ne < 1:
        raise SceneError(f"--ne must be an integer >= 1 (got {args.ne})")
    device = _warp_device(args.device)
    cases = [known[c] for c in args.cases] if args.cases else list(HARD_CASES)
    if args.mesh is not None:
        fixed = [label for label, _, _, ne in cases if ne is not None]
        if fixed:
            raise SceneError(f"stability case {fixed[0]} fixes its grid: not with --mesh (name the other cases)")
    ne = None if args.mesh is not None else args.ne
    given = dict(ne=ne, np_=args.np, days=args.days, mesh=args.mesh, overrides=_overrides(args.set))
    suite_scenes(cases, steppers, **given)  # every value refused before --output's folder is made
    # a folder of its own per suite, so that a page's suites run in order do not meet each other's files
    grid = f"ne{args.ne}" if args.mesh is None else args.mesh.stem
    output = args.output or Path(f"stability_{'_'.join(args.cases) or 'all'}_{grid}")
    with executor(args.workers) as pool:
        if pool is None:  # an MPI worker rank: its share is done
            return 0
        with folder_lock(output, "stability.lock"):  # a second suite into this folder is refused now, not at its end
            check_results(output, OUTPUTS, args.overwrite)  # an earlier suite's results: refused now, not at the end
            results = run_suite(cases, steppers, device, **given, pool=pool)
            print(format_table(results))
            for path in write_table(results, output, overwrite=args.overwrite):
                print(f"wrote {path}")
    return 0


def _overrides(pairs) -> dict:
    """``-s section.key=value`` pairs → {"section.key": value} (TOML values; a bare word is a string)."""
    import tomllib

    out = {}
    for pair in pairs:
        key, sep, text = pair.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"-s needs SECTION.KEY=VALUE (got {pair!r})")
        try:
            value = tomllib.loads(f"v = {text.strip()}")["v"]
        except tomllib.TOMLDecodeError:
            value = text.strip()
        out[key] = value
    return out


def _continued(args, device, comm):
    """The Simulation of ``run --continue``: a continuation (keeping the restart file's
    ``--restart-every`` unless given: ``args.restart_every`` set), or with another
    --stepper or --dt a branch (``Simulation.from_checkpoint``); refuses a changed
    scene or grid, and a continuation at its end day without --days."""
    from .config.scene import load_scene
    from .simulation import checkpoint
    from .simulation.simulation import Simulation

    ck = checkpoint.read_on_root(args.continue_from, comm)  # the whole state on rank 0 only
    for flag, value, have in (("--ne", args.ne, ck.scene.ne), ("--np", args.np, ck.scene.np)):
        if value is not None and value != have:
            raise CheckpointError(
                f"{args.continue_from} is a run with {flag.lstrip('-')} = {have}; it cannot continue with {flag} {value}"
            )
    if args.mesh is not None:
        raise CheckpointError(
            f"{args.continue_from} is a run on {ck.scene.grid_text}; it continues on its own mesh, not on --mesh {args.mesh}"
        )
    if args.set:
        raise CheckpointError("-s cannot change a checkpointed scene")
    if args.no_cells and ck.scene.output_cells:
        raise CheckpointError("--no-cells cannot change a checkpointed scene (its output.cells is true)")
    if args.scene is not None:
        given = load_scene(args.scene, ne=args.ne, np_=args.np)
        mine = {k: v for k, v in ck.scene.as_dict().items() if k not in ("days", "notes", "branch")}
        theirs = {k: v for k, v in given.as_dict().items() if k not in ("days", "notes", "branch")}
        if mine != theirs:
            differ = ", ".join(k for k in mine if mine[k] != theirs.get(k))
            raise CheckpointError(
                f"{args.continue_from} is a run of another scene than {args.scene} (differs in: {differ})"
            )
    continued = args.stepper is None and args.dt is None  # not a branch (which refuses a length of 0 days itself)
    if (
        continued and args.days is None and ck.step >= ck.scene.nsteps
    ):  # else 0 steps, and a file that blocks the real one
        raise CheckpointError(
            f"{args.continue_from} is already at its run's end day {ck.scene.days:g}: give --days for the new end day"
        )
    if (
        continued and args.restart_every is None
    ):  # a run that wrote restart files goes on writing them, as if never stopped
        args.restart_every = ck.restart_every
    return Simulation.from_checkpoint(
        ck,
        device,
        days=args.days,
        stepper=args.stepper,
        dt=args.dt,
        progress=not args.no_progress,
        comm=comm,
        graphs=args.graphs,
    )


def _default_output(name, given: dict, scene) -> Path:
    """The run file's default name, in the working folder:
    ``<scene>_<grid>np<np>_<stepper>[_a<radius>][_omega<Ω>][_g<gravity>][_<days>d][_dt<dt>].nc``,
    where the planet's values (SI units) appear when they are not the scene file's, the
    run length when it is not the scene file's, and Δt when one was given (``--dt``,
    ``-s time.dt``) that is not the one the scene would take itself for that grid and
    length. Runs of a scene that differ in these get different files, so a page's
    commands run in order do not meet "output file exists". ``<grid>``: ``ne<ne>``, or
    the mesh's label (``Scene.grid_label``: the mesh file's stem, ``ne4c2.5``, …). ``name``: the scene as
    given; ``given``: ``load_scene``'s keywords that made ``scene``."""
    from .config.scene import load_scene

    overrides = given["overrides"]
    parts = [f"{scene.name}_{scene.grid_label}np{scene.np}_{scene.stepper}"]
    try:
        own = load_scene(name)  # the file as it is
    except SceneError:  # a file that loads only with the overrides: nothing of its own to differ from
        own = scene
    for key, tag in (("radius", "a"), ("omega", "omega"), ("gravity", "g")):
        if scene.planet[key] != own.planet[key]:
            parts.append(f"{tag}{scene.planet[key]:g}")
    if scene.days != own.days:
        parts.append(f"{scene.days:g}d")
    if given["dt"] is not None or "time.dt" in overrides:
        try:  # the dt it would take itself, all else as given
            unset = {k: v for k, v in overrides.items() if k != "time.dt"}
            chosen = load_scene(name, **{**given, "dt": None, "overrides": unset}).dt
        except SceneError:  # none that fits the output interval: the dt given is its own
            chosen = None
        if scene.dt != chosen:
            parts.append(f"dt{scene.dt:g}")
    return Path("_".join(parts) + ".nc")


def _refuse_a_blown_up_run(output: Path) -> None:
    """Raise ``OutputError`` when ``output`` holds a run that blew up (its ``blowup``
    attribute): the line says so, so that the user who reruns with a fix sees why
    the file is there and how to replace it."""
    import netCDF4

    if not output.is_file() or output.is_symlink():
        return
    try:
        with netCDF4.Dataset(output) as ds:
            blowup = getattr(ds, "blowup", None)
    except OSError:  # not netCDF: check_target's own refusal
        return
    if blowup is not None:
        raise OutputError(
            f"output file exists: {output}, a run that ended in a {str(blowup).partition(': ')[0]} (--overwrite "
            "replaces it, --output names another)"
        )


def _cmd_run(args) -> int:
    from .config.scene import load_scene, resolve_path
    from .core import mpi
    from .core.graphs import default_mode, graphs_mode
    from .io.run_file import check_distinct, check_target, check_unlocked, close_open_runs
    from .simulation.writers import restart_path

    if args.continue_from is None:
        if args.scene is None:
            raise ValueError("run needs a SCENE (or --continue CHECKPOINT)")
        given = dict(
            ne=args.ne,
            np_=args.np,
            dt=args.dt,
            days=args.days,
            stepper=args.stepper,
            mesh=args.mesh,
            overrides={**_overrides(args.set), **({"output.cells": False} if args.no_cells else {})},
        )
        scene = load_scene(args.scene, **given)
        output = args.output or _default_output(args.scene, given, scene)
    else:
        scene = None  # the restart file's
        stem = args.continue_from.name.removesuffix(".nc").removesuffix(".restart")
        changes = "".join(
            f"_{v}" for v in (args.stepper, args.dt and f"dt{args.dt:g}") if v
        )  # a branch's (or a no-op's)
        output = args.output or args.continue_from.with_name(
            f"{stem}_{'branch' + changes if changes else 'continued'}.nc"
        )
    initial = scene.case_params.get("path") if scene is not None else None  # a file case's initial state: an input too
    check_distinct(
        [output, restart_path(output)], [args.continue_from, args.scene and resolve_path(str(args.scene)), initial]
    )
    if not args.overwrite:
        _refuse_a_blown_up_run(output)
    check_target(output, args.overwrite)
    check_unlocked(output)  # another run writing it now (with --overwrite): refused before the header
    if args.restart_every is not None:  # else written only on SIGINT/SIGTERM, and then not over an existing one
        check_target(restart_path(output), args.overwrite)
    args.graphs = graphs_mode(args.graphs, "--graphs") if args.graphs is not None else default_mode()  # the flag wins
    device = _warp_device(args.device)
    comm = mpi.world()  # under mpiexec: one run over all ranks
    with mpi.watch_failures(comm, close_open_runs):  # a failure on one rank alone ends the job
        return _run(args, scene, output, device, comm)


MAX_DISTORTION = 4.0  # HOMME's print_cfl warns of elements more distorted than this (dx_long / dx_short)


def _mesh_lines(sim) -> list[str]:
    """HOMME's ``print_cfl`` figures of a run's mesh (rank 0; [] on the others; call on every
    rank): the Dinv-based node spacing (``grid.quality``), the largest distortion (a warning
    line above ``MAX_DISTORTION``), the area ratio and the worst element's Courant numbers."""
    from .grid.quality import element_sizes
    from .model.diagnostics import worst_element_courant

    u, v, h = sim.fields()
    Dinv = sim.topology.gather(sim.topology.grid.Dinv)  # rank 0's whole grid is gathered, without a metric
    if not sim.root:
        return []
    sizes = element_sizes(sim.grid, Dinv)
    s, scene = sizes.summary(), sim.scene
    c = worst_element_courant(sim.grid, sizes, u, v, h, scene.dt, sim.g, "pressure_gradient" in scene.terms)
    grav = "" if math.isnan(c["courant_gravity"]) else f"gravity-wave {c['courant_gravity']:.3f}, "
    lines = [
        f"mesh        node spacing (Dinv-based) {s['dx_short_min'] / 1e3:.1f} to {s['dx_long_max'] / 1e3:.1f} km "
        f"(dx_short mean {s['dx_short_mean'] / 1e3:.1f} km), largest distortion {s['distortion_max']:.2f}, "
        f"area ratio {s['area_ratio']:.2f}",
        f"mesh        worst element {s['worst'] + 1} (dx_short {sizes.dx_short[s['worst']] / 1e3:.1f} km): Courant "
        f"{grav}advective {c['courant_advective']:.3f} (dt / dx_short)",
    ]
    if s["distortion_max"] > MAX_DISTORTION:
        e = int(sizes.distortion.argmax())
        lines.append(
            f"swe-sphere: warning: element {e + 1} is distorted {s['distortion_max']:.2f}x (dx_long / dx_short, above "
            f"HOMME's {MAX_DISTORTION:g}): its spacing is uneven and it sets a short explicit step"
        )
    return lines


def _run(args, scene, output, device, comm) -> int:
    from tqdm import tqdm

    from .core import mpi
    from .core.backend import Backend
    from .core.constants import EARTH
    from .core.workers import cpus, limit_threads
    from .simulation.schedules import restart_steps
    from .simulation.simulation import Simulation
    from .simulation.writers import restart_path, stream_path

    if comm is not None:
        limit_threads(max(1, cpus() // mpi.node_local_size(comm)))
    if args.continue_from is None:
        sim = Simulation(scene, device, progress=not args.no_progress, comm=comm, graphs=args.graphs)
    else:
        sim = _continued(args, device, comm)
    if not sim.root:  # rank 0 reports; the others' errors still reach stderr
        sys.stdout = open(os.devnull, "w")
    scene = sim.scene
    if args.restart_every is not None:
        restart_steps(scene, args.restart_every)  # checks the interval before the run
    c = sim.courant()
    dx = -sim.topology.max(-float(sim.topology.grid.dx.min()))
    mesh_lines = _mesh_lines(sim) if scene.mesh is not None else []  # every rank: it gathers the state
    print(f"scene       {scene.name}: {scene.description}")
    print(
        f"grid        {scene.grid_text}: {scene.nelem} elements, {sim.topology.grid.nunique} unique nodes, "
        f"min node spacing {dx / 1e3:.1f} km"
    )
    if scene.planet != EARTH.as_table():
        p = scene.planet
        print(
            f"planet      radius {p['radius']:g} m, omega {p['omega']:g} 1/s, gravity {p['gravity']:g} m/s^2 "
            f"(the Earth's: {EARTH.a:g} m, {EARTH.omega:g} 1/s, {EARTH.g:g} m/s^2)"
        )
    for line in mesh_lines:
        print(line, file=sys.stderr if line.startswith("swe-sphere: warning") else sys.stdout)
    print(
        f"terms       {', '.join(scene.terms)}"
        + (f" (nu = {scene.nu:.3g} m^4/s, subcycle {scene.hypervis_subcycle})" if scene.nu else "")
    )
    print(
        f"stepper     {sim.stepper.label(scene.stepper_options)}, dt = {scene.dt:g} s, {scene.nsteps} steps to day {scene.days:g}, device {device}"
    )
    for line in sim.stepper.describe():
        print(f"{scene.stepper:11s} {line}")
    if comm is not None:
        sizes = [len(p) for p in sim.topology.parts]
        print(
            f"ranks       {comm.size} MPI ranks: {min(sizes)}-{max(sizes)} elements each along a space-filling curve, "
            f"{sim.model.threads} CPU threads each"
        )
    if sim.step:
        print(f"continue    from {args.continue_from} at step {sim.step} (day {scene.day(sim.step):g})")
    elif args.continue_from is not None and scene.branch is not None:
        b = scene.branch
        print(
            f"branch      from {args.continue_from} at its step {b['step']} (day {b['day']:g}; {b['stepper']}, dt = {b['dt']:g} s): "
            f"{scene.stepper} starts there afresh"
        )
    grav = "" if math.isnan(c["courant_gravity"]) else f", gravity-wave {c['courant_gravity']:.3f}"
    print(f"Courant     advective {c['courant_advective']:.3f}{grav} (max over nodes at t = {scene.day(sim.step):g} d)")
    extra = [n for n in (sim.stability_warning(), Backend.of(device).threads_note()) if n]
    for note in (*scene.notes, *extra):
        if note.startswith("warning: "):
            if sim.root:  # once, not once a rank
                print(f"swe-sphere: {note}", file=sys.stderr)  # seen even with stdout redirected
        else:
            print(f"note        {note}")
    only = f": {', '.join(scene.output_fields)}" if scene.output_fields else ""
    print(f"output      {output} (every {scene.output_every_days:g} days{only})")
    for st in scene.output_streams:
        print(
            f"stream      {stream_path(output, st['name'])} (every {st['every_days']:g} days: {', '.join(st['fields'])})"
        )
    if scene.log_every_steps:
        print(
            f"log         every {scene.log_every_steps} steps: relative change of mass, energy, enstrophy since t = 0; max Courant numbers"
        )
    if args.restart_every is not None:
        print(f"restart     {restart_path(output)} (every {args.restart_every:g} days and at the end)")
    if sim.dfi is not None:
        print(f"initial     {sim.dfi.describe(scene.digital_filter)}")
    print(f"setup       {sim.setup_time:.2f} s")
    try:
        result = sim.run(
            output,
            overwrite=args.overwrite,
            restart_every=args.restart_every,
            compress=args.compress,
            history=" ".join(["swe-sphere", *(sys.argv[1:] if args.argv is None else args.argv)]),
            notify=lambda line: tqdm.write(f"swe-sphere: note: {line}", file=sys.stderr),  # above the bar
            log=lambda line: tqdm.write(f"log         {line}", file=sys.stdout),
        )
    except BlowUp as err:  # on every rank alike (the bad node is found over all of them)
        result, blowup = None, f"swe-sphere: {err}; the last good state is in {output}"
    if args.console:
        _hold_signals()  # the output is closed: a signal from now on is answered as the process ends
    if result is None:
        if sim.root:
            print(blowup, file=sys.stderr)
        return EXIT_BLOWUP
    _summary(result, sim)
    return 0


def _summary(r, sim) -> None:
    d = r.diagnostics
    steps, loop = r.steps - r.first_step, r.loop_time
    print("summary")
    print(
        f"  wall time   {loop:.2f} s for {steps} steps, setup {r.setup_time:.2f} s"
        + (f" (cumulative since t = 0: {r.wall_time:.2f} s)" if r.first_step else "")
    )
    if steps:
        rest = (
            f", then {1e3 * (loop - r.first_step_time) / (steps - 1):.2f} ms/step over {steps - 1} steps"
            if steps > 1
            else ""
        )
        print(
            f"  time        compile {r.compile_time:.2f} s (setup and loop), first step {r.first_step_time:.3f} s{rest}"
        )
    print(f"  RHS evals   {r.rhs_evals}")
    if sim.dfi is not None:
        print(
            f"  initial     digital-filter start: {sim.dfi.rhs_evals} RHS evals, {sim.dfi.wall_time:.2f} s (in setup); rms dh/dt "
            f"{sim.dfi.dhdt_rms[0]:.3e} -> {sim.dfi.dhdt_rms[1]:.3e} m/s"
        )
    elif sim.scene.initialization is not None:
        print("  initial     digital-filter start of the run continued (not redone)")
    for k, total in r.iterations.items():
        print(f"  {k:11s} {total} iterations, {total / max(r.steps, 1):.1f} per step")
    for k in ("mass", "total_energy", "potential_enstrophy"):
        if k in d:
            print(f"  {k:20s} {d[k]:.10e}  relative change {d[k + '_change']:+.3e}")
    cmax = {k: max(h[k] for h in r.history) for k in ("courant_advective", "courant_gravity")}
    grav = "" if math.isnan(cmax["courant_gravity"]) else f", gravity-wave {cmax['courant_gravity']:.3f}"
    print(f"  Courant     max over output times: advective {cmax['courant_advective']:.3f}{grav}")
    if "l2_h" in d:
        print(f"  error h     l1 {d['l1_h']:.3e}  l2 {d['l2_h']:.3e}  linf {d['linf_h']:.3e}")
        print(f"  error wind  l1 {d['l1_wind']:.3e}  l2 {d['l2_wind']:.3e}  linf {d['linf_wind']:.3e}")
        print(f"  error wind  l2 vorticity {d['l2_vorticity']:.3e}  l2 divergence {d['l2_divergence']:.3e}")
    if "ref_l2_h_surface" in d:
        # the reference stores a few days only: quote the last output time past the start it has
        name = sim.scene.reference_file.stem.rsplit("_", 1)[-1]  # the truncation, for the spectral files ("T213")
        vs = f"vs {name}"
        scored = [h for h in r.history if h["steps"] > 0 and math.isfinite(h["ref_l2_h_surface"])]
        if not scored:
            from .cases.reference import stored_days

            days = ", ".join(f"{day:g}" for day in stored_days(sim.scene.reference_file))
            print(f"  {vs:11s} none: no output time after t = 0 is one {name} stores (days {days})")
        else:
            d = scored[-1]
            at = (
                ""
                if d is r.history[-1]
                else f" (day {sim.scene.day(d['steps']):g}, its last output time {name} stores)"
            )
            print(
                f"  {vs} h+hs l1 {d['ref_l1_h_surface']:.3e}  l2 {d['ref_l2_h_surface']:.3e}  linf {d['ref_linf_h_surface']:.3e}{at}"
            )
            print(f"  {vs} wind l1 {d['ref_l1_wind']:.3e}  l2 {d['ref_l2_wind']:.3e}  linf {d['ref_linf_wind']:.3e}")
            print(f"  {vs} wind l2 vorticity {d['ref_l2_vorticity']:.3e}  l2 divergence {d['ref_l2_divergence']:.3e}")
    print(f"  output      {r.output}")
    if r.checkpoint is not None:
        print(f"  restart     {r.checkpoint}")


def _cmd_plot(args) -> int:
    from .studies.plotting import plot_analyses, plot_run

    fields = args.field or ["h_surface"]
    if args.spectrum or args.zonal_mean:
        if args.diff is not None or args.force:
            raise ValueError("--diff and --force compare maps: not with --spectrum or --zonal-mean")
        if not args.zonal_mean and (args.field or args.lat_range):
            raise ValueError(
                f"--{'field' if args.field else 'lat-range'} applies to maps and --zonal-mean, not --spectrum"
            )
        paths = plot_analyses(
            args.run,
            args.day,
            args.output,
            spectrum=args.spectrum,
            zonal_fields=fields if args.zonal_mean else (),
            lat_range=args.lat_range,
            overwrite=args.overwrite,
        )
    else:
        paths = plot_run(
            args.run,
            fields,
            args.day,
            args.diff,
            args.output,
            args.lat_range,
            force=args.force,
            overwrite=args.overwrite,
        )
    for path in paths:
        print(path)
    return 0


def _cmd_remap(args) -> int:
    from .io.remap import grid_name, latlon_grid, open_netcdf, remap_file, run_grid
    from .io.run_file import check_distinct, check_target

    output = args.output or Path(f"{args.run.stem}_latlon{args.resolution:g}.nc")
    lat, lon = latlon_grid(args.resolution)
    if not args.run.is_file():
        raise ValueError(f"file not found: {args.run}")
    check_distinct([output], [args.run])
    check_target(output, args.overwrite)
    with open_netcdf(args.run) as ds:
        grid = run_grid(ds)
    remap_file(args.run, args.resolution, output, overwrite=args.overwrite)
    print(f"{output}: {grid_name(grid)} -> {lat.size} x {lon.size} lat-lon points ({args.resolution:g} degrees)")
    return 0


# each command's function and the module it imports first, the one that brings Warp, numpy
# and the rest (``_import_uncollected``)
COMMANDS = {
    "list": (lambda args: _cmd_list(), "config.scene"),
    "stability": (_cmd_stability, "studies.stability"),
    "sweep": (_cmd_sweep, "studies.sweep"),
    "plot": (_cmd_plot, "studies.plotting"),
    "remap": (_cmd_remap, "io.remap"),
    "run": (_cmd_run, "simulation.simulation"),
    "mesh": (_cmd_mesh, "grid.refine"),
}


def _import_uncollected(module: str) -> None:
    """Import ``module`` (of this package) with the cyclic garbage collector off, then
    freeze what exists: the imports make objects that live to the end, none of them
    garbage, and the collector's passes over them cost a tenth of a second of CPU at every
    start; frozen, later collections skip them too. For the console script only: a
    caller's process would keep its own cyclic garbage of the moment forever."""
    import gc
    import importlib

    gc.disable()
    try:
        importlib.import_module(f".{module}", __package__)
    finally:
        gc.enable()
        gc.freeze()


def _classify(err: BaseException) -> tuple[int, str]:
    """(exit status, one-line message) of a failure."""
    import signal

    if isinstance(err, Interrupted):
        return 128 + err.signum, str(err)
    if isinstance(err, KeyboardInterrupt):  # outside the time loop (its handler stops after a step)
        signum = getattr(err, "signum", signal.SIGINT)
        return (
            128 + signum,
            f"interrupted by {signal.Signals(signum).name} outside the time loop; no output was written",
        )
    if isinstance(err, (BlowUp, StepFailure, ResourceError)):  # BlowUp: a sweep's reference run
        return EXIT_BLOWUP, str(err)
    if isinstance(err, MemoryError):
        return EXIT_BLOWUP, "out of memory" + (f" ({err})" if str(err) else "")
    if isinstance(err, (FileNotFoundError, IsADirectoryError, NotADirectoryError, PermissionError)) or (
        isinstance(err, OSError) and err.errno == errno.EROFS  # a folder to make on a read-only file system
    ):
        return EXIT_BAD_INPUT, f"{err.filename}: {err.strerror}" if err.filename else str(err)
    if isinstance(err, OSError):
        return EXIT_BLOWUP, f"{err.filename + ': ' if err.filename else ''}{err.strerror or err}"
    if isinstance(err, ValueError):
        return EXIT_BAD_INPUT, str(err)
    return EXIT_INTERNAL, f"internal error: {type(err).__name__}: {err} (run with --debug for the traceback)"


class _Terminated(KeyboardInterrupt):
    """SIGTERM outside the time loop, unwound like Ctrl-C (partial files dropped)."""

    signum = 15


def _on_sigterm(signum, frame):
    raise _Terminated()


_LATE: list[int] = []  # SIGINT/SIGTERM received after the console script's outputs were closed


def _hold_signals() -> None:
    """From now on SIGINT/SIGTERM are noted, not raised: the outputs are closed (or a
    failure is being reported), and ``_exit`` answers them."""
    import signal

    for sig in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            signal.signal(sig, lambda signum, frame: _LATE.append(signum))


def _exit(code: int):
    """End the console script with ``code``, or, after a successful command, with
    128 + signum and one line for a signal that came once its outputs were complete.
    Never returns. The interpreter's teardown is skipped (its atexit callbacks run):
    it takes about a second (garbage collection, Warp's modules) with the default
    signal dispositions back, so a Ctrl-C then ended the process silently with -2."""
    import atexit
    import signal

    def flush(stream):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe (`| head`): nothing more can be said
            pass

    _hold_signals()
    atexit._run_exitfuncs()
    flush(sys.stdout)  # may wait for a slow reader: a signal meanwhile is answered below
    if _LATE and code == 0:
        signum = min(_LATE)  # SIGINT before SIGTERM
        print(
            f"swe-sphere: interrupted by {signal.Signals(signum).name} after the command had finished; its output is complete",
            file=sys.stderr,
        )
        code = 128 + signum
    flush(sys.stderr)
    os._exit(code)


def main(argv=None) -> int:
    import _signal  # built in, nothing to import: SIGTERM as SIGINT from the first instruction on

    console = argv is None and _signal.getsignal(_signal.SIGTERM) == _signal.SIG_DFL  # not a caller's process
    if console:
        _signal.signal(_signal.SIGTERM, _on_sigterm)
    debug, args = os.environ.get("SWE_SPHERE_DEBUG", "") not in ("", "0"), None
    try:  # start-up (the imports of Warp and the rest) included: a signal there is one line too
        args = _parser().parse_args(argv)
        args.argv, args.console = argv, console
        debug = debug or args.debug
        command, module = COMMANDS[args.command]
        if console:
            _import_uncollected(module)
        code = command(args)
    except (Exception, KeyboardInterrupt) as err:
        if debug:
            raise
        if console:
            _hold_signals()  # a second Ctrl-C does not break the report
        code = _report(err, args)
    from .core import mpi

    if console and mpi.launched_size() == 1:  # an MPI rank's teardown finalises MPI
        _exit(code)
    return code


def _report(err: BaseException, args) -> int:
    """Print the one line of a failure (rank 0 for what every rank meets alike) and
    return its exit status; under MPI, end the job when one rank may have failed alone."""
    from .core import mpi

    code, message = _classify(err)
    comm = (
        mpi.world() if args is not None and args.command == "run" and not isinstance(err, mpi.MPIUnavailable) else None
    )  # one run over several MPI ranks
    # every rank refuses it, stops at one step, or finds too little memory, alike
    alike = code == EXIT_BAD_INPUT or isinstance(err, Interrupted) or getattr(err, "on_every_rank", False)
    if comm is None or comm.rank == 0 or not alike:
        where = f"rank {comm.rank} of {comm.size}: " if comm is not None and comm.rank else ""
        print(
            f"swe-sphere: {where}{'error: ' if code in (EXIT_BAD_INPUT, EXIT_INTERNAL) else ''}{message}",
            file=sys.stderr,
        )
    if comm is not None and comm.rank != 0 and not alike and code < 128:
        # perhaps this rank alone (a signal stops every rank at the same step): the others
        # cannot meet it again, so rank 0 closes its files and ends the job (mpi.watch_failures)
        sys.stderr.flush()
        mpi.report_failure(comm, code, f"{where}{message}")
    if comm is not None and comm.rank == 0 and not alike:
        # rank 0, the writer, may fail alone (its output): the others would wait for it
        # forever, so it ends the job, with its exit status, once its files are closed.
        # The process manager forwards stderr on its own time: aborting at once lost
        # the line now and then (exit 3, empty stderr), so give it a moment.
        sys.stderr.flush()
        time.sleep(0.5)
        comm.Abort(code)
    return code


if __name__ == "__main__":
    sys.exit(main())
