"""Command line: ``swe-sphere run | list | plot | remap | sweep | stability``.

Exit status: 0 success, 2 bad input (one line naming the field or value, no
output file), 3 blow-up (message with step, model time and place; the output
file keeps every good output time).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path

EXIT_BAD_INPUT, EXIT_BLOWUP = 2, 3


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # one line, exit 2
        self.exit(EXIT_BAD_INPUT, f"swe-sphere: error: {message}\n")


PLOT_FIELDS = ("h", "h_surface", "u", "v", "speed", "vorticity")  # = plotting.MAP_FIELDS (not imported: matplotlib)


def _parser() -> argparse.ArgumentParser:
    p = _Parser(prog="swe-sphere", description="Spectral-element shallow-water model on the cubed sphere.")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)
    r = sub.add_parser("run", help="run a scene (a TOML file under testcases/, or its name)")
    r.add_argument("scene", help="scene file, e.g. testcases/tc5_mountain.toml, or a bundled scene name")
    r.add_argument("--ne", type=int, help="elements along a cube edge")
    r.add_argument("--np", type=int, help="GLL points per element direction (2..8)")
    r.add_argument("--dt", type=float, help="time step in seconds")
    r.add_argument("--days", type=float, help="run length in days")
    r.add_argument("--stepper", help="time stepper (see `swe-sphere list`)")
    r.add_argument("--device", choices=("cpu", "cuda"), help="Warp device (default: cuda when present, else cpu)")
    r.add_argument("--output", type=Path, help="netCDF output file (default: <scene>_ne<ne>np<np>_<stepper>.nc)")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    sub.add_parser("list", help="list bundled scenes, steppers and terms")
    pl = sub.add_parser("plot", help="PNG lat-lon maps of a run file's fields and its invariants/errors against time")
    pl.add_argument("run", type=Path, help="run file (netCDF written by `swe-sphere run`)")
    pl.add_argument("--field", nargs="+", choices=PLOT_FIELDS, default=["h_surface"], help="field(s) to map (default h_surface = h + hs)")
    pl.add_argument("--day", nargs="+", type=float, help="model day(s) to map, each an output time (default: the last)")
    pl.add_argument("--diff", type=Path, metavar="REFERENCE", help="map the difference to another run file or a T213 reference file")
    pl.add_argument("--output", type=Path, default=Path("."), metavar="DIR", help="folder for the PNGs (default: .)")
    pl.add_argument("--lat-range", nargs=2, type=float, metavar=("SOUTH", "NORTH"), help="map only this latitude band (degrees)")
    rm = sub.add_parser("remap", help="a run file on a regular lat-lon grid (CF netCDF), by GLL interpolation")
    rm.add_argument("run", type=Path, help="run file (netCDF written by `swe-sphere run`)")
    rm.add_argument("--resolution", type=float, default=1.0, help="grid spacing in degrees; must divide 180 (default 1.0)")
    rm.add_argument("--output", type=Path, help="netCDF output file (default: <run>_latlon<resolution>.nc)")
    sw = sub.add_parser("sweep", help="error against dt against wall time for several steppers (resumable)")
    sw.add_argument("scene", help="scene file or bundled scene name")
    sw.add_argument("--steppers", default="leapfrog,ssprk3,semi_implicit,implicit", help="comma-separated stepper names")
    group = sw.add_mutually_exclusive_group()
    group.add_argument("--dt", help="comma-separated time steps in seconds")
    group.add_argument("--courant", help="comma-separated multiples of the explicit gravity-wave limit (default 0.5,1,2,5,10,30,60,100)")
    sw.add_argument("--ne", type=int, help="elements along a cube edge")
    sw.add_argument("--np", type=int, help="GLL points per element direction (2..8)")
    sw.add_argument("--days", type=float, help="run length in days")
    sw.add_argument("--device", choices=("cpu", "cuda"), help="Warp device (default: cuda when present, else cpu)")
    sw.add_argument("--output", type=Path, default=Path("sweep"), help="directory for results (default ./sweep); reruns resume")
    st = sub.add_parser("stability", help="largest stable dt of each stepper on the hard cases, by bisection")
    st.add_argument("cases", nargs="*", help="case labels (default: all hard cases; see `swe-sphere stability --help`)")
    st.add_argument("--steppers", default="leapfrog,ssprk3,semi_implicit,implicit", help="comma-separated stepper names")
    st.add_argument("--ne", type=int, default=8, help="coarse grid for cases that do not fix one (default 8)")
    st.add_argument("--np", type=int, help="GLL points (default: the scene's)")
    st.add_argument("--device", choices=("cpu", "cuda"), help="Warp device (default: cuda when present, else cpu)")
    st.add_argument("--output", type=Path, default=Path("."), help="directory for stability.csv and stability.nc")
    return p


def _quiet_warp_init(wp) -> None:
    """Initialise Warp with the process's stderr closed: its native code prints a
    CUDA-driver warning there on machines without a GPU, below Python's reach."""
    sys.stderr.flush()
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        wp.init()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)


def _fail(message: str, code: int) -> int:
    print(f"swe-sphere: error: {message}", file=sys.stderr)
    return code


def _cmd_list() -> int:
    from .config import list_scenes, load_scene
    from .model import TERMS
    from .steppers import STEPPERS

    print("scenes:")
    for path in list_scenes():
        s = load_scene(path)
        print(f"  {path.stem:32s} {s.description}")
        print(f"  {'':32s} ne={s.ne} np={s.np} {s.stepper} dt={s.dt:g}s {s.days:g} days; terms: {', '.join(s.terms)}")
    print("steppers:")
    for name, cls in STEPPERS.items():
        print(f"  {name:32s} {cls.__doc__.split(chr(10))[0]}")
    print("terms:")
    print("  " + ", ".join(TERMS))
    return 0


def _warp_device(requested):
    """Initialise Warp quietly; return the device name, or None if CUDA was asked for and is absent."""
    import warp as wp

    wp.config.log_level = wp.LOG_ERROR  # no init banner or per-module load lines
    _quiet_warp_init(wp)
    from .model import default_device

    device = requested or default_device()
    return None if device == "cuda" and not wp.is_cuda_available() else device


def _numbers(text: str, name: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"--{name} must be comma-separated numbers (got {text!r})") from None
    if not values or not all(math.isfinite(v) and v > 0 for v in values):
        raise ValueError(f"--{name} values must be > 0 (got {text!r})")
    return values


def _cmd_sweep(args) -> int:
    from .config import SceneError, load_scene
    from .steppers import STEPPERS

    steppers = [s for s in args.steppers.split(",") if s]
    try:
        for s in steppers:
            if s not in STEPPERS:
                raise ValueError(f"unknown stepper {s!r} (known: {', '.join(STEPPERS)})")
        scenes = {s: load_scene(args.scene, ne=args.ne, np=args.np, days=args.days, stepper=s) for s in steppers}
        dts = _numbers(args.dt, "dt") if args.dt else None
        factors = _numbers(args.courant or "0.5,1,2,5,10,30,60,100", "courant") if dts is None else None
        args.output.mkdir(parents=True, exist_ok=True)
    except (SceneError, ValueError) as err:
        return _fail(str(err), EXIT_BAD_INPUT)
    except OSError as err:
        return _fail(f"cannot create output directory {args.output}: {err.strerror}", EXIT_BAD_INPUT)
    device = _warp_device(args.device)
    if device is None:
        return _fail("device cuda is not available on this machine (use --device cpu)", EXIT_BAD_INPUT)
    from .sweep import Sweep, dt_for_day, explicit_limits, format_summary, table, write_outputs

    base = next(iter(scenes.values()))
    limits = explicit_limits(base, device)
    if dts is None:
        dts = sorted({dt_for_day(f * limits["dt_gravity"], base.days) for f in factors})
    for dt in dts:
        if abs(round(base.days * 86400 / dt) * dt - base.days * 86400) > 1e-6 * dt:
            return _fail(f"dt = {dt:g} s does not divide the run length of {base.days:g} days", EXIT_BAD_INPUT)
    print(
        f"sweep {base.name} ne={base.ne} np={base.np}, {base.days:g} days; explicit limits: gravity-wave dt = "
        f"{limits['dt_gravity']:.1f} s, advective dt = {limits['dt_advective']:.1f} s; dt = {', '.join(f'{d:.4g}' for d in dts)}"
    )
    rows, info = Sweep(scenes, dts, args.output, device).run()
    rows = table(rows, limits)
    print(format_summary(rows, info))
    for path in write_outputs(rows, info, limits, args.output):
        print(f"wrote {path}")
    return 0


def _cmd_stability(args) -> int:
    from .stability import HARD_CASES, format_table, run_suite, write_table
    from .steppers import STEPPERS

    known = {c[0]: c for c in HARD_CASES}
    for label in args.cases:
        if label not in known:
            return _fail(f"unknown stability case {label!r} (known: {', '.join(known)})", EXIT_BAD_INPUT)
    steppers = [s for s in args.steppers.split(",") if s]
    for s in steppers:
        if s not in STEPPERS:
            return _fail(f"unknown stepper {s!r} (known: {', '.join(STEPPERS)})", EXIT_BAD_INPUT)
    if not args.output.is_dir():
        return _fail(f"output directory does not exist: {args.output}", EXIT_BAD_INPUT)
    device = _warp_device(args.device)
    if device is None:
        return _fail("device cuda is not available on this machine (use --device cpu)", EXIT_BAD_INPUT)
    cases = [known[c] for c in args.cases] if args.cases else list(HARD_CASES)
    results = run_suite(cases, steppers, device, ne=args.ne, np=args.np)
    print(format_table(results))
    for path in write_table(results, args.output):
        print(f"wrote {path}")
    return 0


def _cmd_run(args) -> int:
    from .config import SceneError, load_scene
    from .output import check_writable

    try:
        scene = load_scene(args.scene, ne=args.ne, np=args.np, dt=args.dt, days=args.days, stepper=args.stepper)
        output = args.output or Path(f"{scene.name}_ne{scene.ne}np{scene.np}_{scene.stepper}.nc")
        check_writable(output)
    except (SceneError, ValueError) as err:
        return _fail(str(err), EXIT_BAD_INPUT)

    device = _warp_device(args.device)
    if device is None:
        return _fail("device cuda is not available on this machine (use --device cpu)", EXIT_BAD_INPUT)
    from .simulation import BlowUp, Simulation

    sim = Simulation(scene, device, progress=not args.no_progress)
    g = sim.grid
    c = sim.courant()
    print(f"scene       {scene.name}: {scene.description}")
    print(f"grid        ne={g.ne} np={g.np}: {g.nelem} elements, {g.nunique} unique nodes, min node spacing {g.dx.min() / 1e3:.1f} km")
    print(f"terms       {', '.join(scene.terms)}" + (f" (nu = {scene.nu:.3g} m^4/s, subcycle {scene.hypervis_subcycle})" if scene.nu else ""))
    print(f"stepper     {scene.stepper}, dt = {scene.dt:g} s, {scene.nsteps} steps to day {scene.days:g}, device {device}")
    grav = "" if math.isnan(c["courant_gravity"]) else f", gravity-wave {c['courant_gravity']:.3f}"
    print(f"Courant     advective {c['courant_advective']:.3f}{grav} (max over nodes at t = 0)")
    for note in scene.notes:
        print(f"note        {note}")
    print(f"output      {output} (every {scene.output_every_days:g} days)")
    print(f"setup       {sim.setup_time:.2f} s")
    try:
        result = sim.run(output)
    except BlowUp as err:
        print(f"swe-sphere: {err}; the last good state is in {output}", file=sys.stderr)
        return EXIT_BLOWUP
    _summary(result)
    return 0


def _summary(r) -> None:
    d = r.diagnostics
    print("summary")
    print(f"  wall time   {r.wall_time:.2f} s for {r.steps} steps ({1e3 * r.wall_time / max(r.steps, 1):.2f} ms/step), setup {r.setup_time:.2f} s")
    print(f"  RHS evals   {r.rhs_evals}")
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
    if "ref_l2_h_surface" in d:
        print(f"  vs T213 h+hs l1 {d['ref_l1_h_surface']:.3e}  l2 {d['ref_l2_h_surface']:.3e}  linf {d['ref_linf_h_surface']:.3e}")
        print(f"  vs T213 wind l1 {d['ref_l1_wind']:.3e}  l2 {d['ref_l2_wind']:.3e}  linf {d['ref_linf_wind']:.3e}")
    print(f"  output      {r.output}")


def _cmd_plot(args) -> int:
    try:
        from .plotting import plot_run

        written = plot_run(args.run, args.field, args.day, args.diff, args.output, args.lat_range)
    except (FileNotFoundError, ValueError) as err:
        return _fail(str(err), EXIT_BAD_INPUT)
    for path in written:
        print(path)
    return 0


def _cmd_remap(args) -> int:
    from .output import check_writable
    from .remap import latlon_grid, remap_file, run_grid

    import xarray as xr

    output = args.output or Path(f"{args.run.stem}_latlon{args.resolution:g}.nc")
    try:
        lat, lon = latlon_grid(args.resolution)
        if not args.run.is_file():
            raise ValueError(f"file not found: {args.run}")
        check_writable(output)
        try:
            ds = xr.open_dataset(args.run, decode_times=False)
        except Exception as exc:
            raise ValueError(f"{args.run}: not a readable netCDF file ({type(exc).__name__})") from None
        with ds:
            grid = run_grid(ds)
    except ValueError as err:
        return _fail(str(err), EXIT_BAD_INPUT)
    remap_file(args.run, args.resolution, output)
    print(f"{output}: ne={grid.ne} np={grid.np} -> {lat.size} x {lon.size} lat-lon points ({args.resolution:g} degrees)")
    return 0


def main(argv=None) -> int:
    args = _parser().parse_args(argv)
    if args.command == "list":
        return _cmd_list()
    if args.command == "stability":
        return _cmd_stability(args)
    if args.command == "sweep":
        return _cmd_sweep(args)
    if args.command == "plot":
        return _cmd_plot(args)
    if args.command == "remap":
        return _cmd_remap(args)
    return _cmd_run(args)


if __name__ == "__main__":
    sys.exit(main())
