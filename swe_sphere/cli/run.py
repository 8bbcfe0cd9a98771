"""``swe-sphere run``: a scene, or the continuation or branch of a restart file; the
output's default name and the refusals made before anything is built."""

from __future__ import annotations

import contextlib
import math
import os
import sys
import warnings
from pathlib import Path

from ..core.errors import BlowUp, CheckpointError, OutputError, SceneError
from .exits import EXIT_BLOWUP, hold_signals
from .report import header, summary
from .values import degree_band, netcdf_output, restart_precision, scene_overrides, varied


def _continued(args, device, comm, members: int | None):
    """The Simulation of ``run --continue``: a continuation, of one run or of ``members``
    (keeping the restart file's restart interval, control and output times), or with another
    --stepper or --dt a branch of one run (``Simulation.from_checkpoint``); refuses a changed
    scene or grid, any -s, and a continuation of no step (at its end day, or at the --days
    given)."""
    from ..config.scene import load_scene, with_days
    from ..simulation import checkpoint
    from ..simulation.simulation import Simulation

    # the whole state on rank 0 only; an ensemble's on every rank (each steps its own members)
    ck = checkpoint.read_on_root(args.continue_from, None if members else comm)
    for flag, value, have in (("--ne", args.ne, ck.scene.ne), ("--np", args.np, ck.scene.np)):
        if value is not None and value != have:
            raise CheckpointError(
                f"{args.continue_from} is a run with {flag.lstrip('-')} = {have}; it cannot continue with {flag} {value}"
            )
    if args.mesh is not None:
        raise CheckpointError(
            f"{args.continue_from} is a run on {ck.scene.grid_text}; it continues on its own mesh, not on --mesh {args.mesh}"
        )
    restart_precision(args.precision, ck.scene, args.continue_from)
    if args.set:
        raise CheckpointError(
            f"-s {args.set[0]}: a checkpointed scene continues as it was written (-s cannot change it)"
        )
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
    if args.stepper is None and args.dt is None:  # not a branch: 0 steps would leave an empty file
        end = ck.scene if args.days is None else with_days(ck.scene, args.days)
        if args.days is None and ck.day >= end.days:
            raise CheckpointError(
                f"{args.continue_from} is already at its run's end day {ck.scene.days:g}: give --days for the new end day"
            )
        if end.days == ck.day:
            raise CheckpointError(
                f"{args.continue_from}: the checkpoint is already at day {ck.day:g} (--days is the "
                "model day the continued run ends at: give a later one)"
            )
    kw = {"days": args.days, "progress": not args.no_progress, "comm": comm, "graphs": args.graphs}
    branch = {"members": True} if members else {"stepper": args.stepper, "dt": args.dt}
    return Simulation.from_checkpoint(ck, device, **kw, **branch)


def default_output(scene, members: int | None = None) -> Path:
    """The run file's default name, in the working folder:
    ``<scene>_<grid>np<np>_<stepper>[_a<radius>][_omega<Ω>][_g<gravity>][_<days>d][_dt<dt>][_float32].nc``,
    where the planet's values (SI units) appear when they are not the scene file's, the
    run length when it is not the scene file's, Δt when one was given (``--dt``,
    ``-s time.dt``) that is not the one the scene would take itself for that grid and
    length, and a float32 tendency (``Scene.precision``). Runs of a scene that differ in these get different files, so a page's
    commands run in order do not meet "output file exists". ``<grid>``: ``ne<ne>``, or
    the mesh's label (``Scene.grid_label``: the mesh file's stem, ``ne4c2.5``, …). The scene file's own
    values are the scene's (``Scene.own_planet``, ``own_days``, ``own_dt``): it is loaded once. An
    ensemble's (``members``) ends in ``_<members>members``."""
    parts = [f"{scene.name}_{scene.grid_label}np{scene.np}_{scene.stepper}"]
    planet = scene.planet if scene.own_planet is None else scene.own_planet  # None: nothing of its own
    for key, tag in (("radius", "a"), ("omega", "omega"), ("gravity", "g")):
        if scene.planet[key] != planet[key]:
            parts.append(f"{tag}{scene.planet[key]:g}")
    if scene.days != (scene.days if scene.own_days is None else scene.own_days):
        parts.append(f"{scene.days:g}d")
    if scene.dt != scene.own_dt:
        parts.append(f"dt{scene.dt:g}")
    if scene.precision != "float64":
        parts.append(scene.precision)
    if members is not None:
        parts.append(f"{members}members")
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


def command(args) -> int:
    from ..config.scene import resolve_path
    from ..core import mpi
    from ..core.backend import pick_device
    from ..core.clock import is_interval
    from ..core.graphs import default_mode, graphs_mode
    from ..io.output_files import check_distinct, check_target
    from ..io.run_file import close_open_runs
    from ..simulation.schedules import restart_marks
    from ..simulation.writers import restart_path

    scene, members, output = _new_run(args) if args.continue_from is None else _continuation(args)
    netcdf_output(output)  # after the scene's own refusals, as check_target
    args.progress_lines = _progress_lines(args)
    # the options' own refusals before the file system is looked at ("output file exists")
    args.graphs = graphs_mode(args.graphs, "--graphs") if args.graphs is not None else default_mode()  # the flag wins
    device = pick_device(args.device, comm=mpi.world())  # under mpiexec: each rank its own device
    if args.restart_every is not None:
        if not is_interval(args.restart_every):
            raise SceneError(f"--restart-every must be a number of days > 0 (got {args.restart_every!r})")
        if scene is not None:  # a continuation's: in _run
            restart_marks(scene, args.restart_every)  # its refusals before set-up
    params = scene.case_params if scene is not None else {}
    initial = params.get("path", params.get("initial_file"))  # a file case's initial state: an input too
    tracer_file = None if scene is None else scene.tracer_file  # [tracers] file: another input
    if args.continue_from is not None and restart_path(output).resolve() == args.continue_from.resolve():
        raise OutputError(
            f"--output {output}: its restart file would be {restart_path(output)}, the file --continue reads "
            "(give another --output, or none: <stem>_continued.nc)"
        )
    check_distinct(
        [output, restart_path(output)],
        [args.continue_from, args.scene and resolve_path(str(args.scene)), initial, args.initial, tracer_file],
    )
    if not args.overwrite:
        _refuse_a_blown_up_run(output)
    check_target(output, args.overwrite)
    if args.restart_every is not None:  # else written only on SIGINT/SIGTERM, and then not over an existing one
        check_target(restart_path(output), args.overwrite)
    comm = mpi.world()  # under mpiexec: one run over all ranks (its elements, or its members)
    with _output_lock(output, comm), mpi.watch_failures(comm, close_open_runs):  # a failure on one rank ends the job
        return _run(args, scene, members, output, device, comm)


def _new_run(args) -> tuple:
    """(the scene, its members or None, the output) of ``run SCENE``: an -s [ensemble] table takes
    --members as its member count."""
    from ..config.scene import load_scene
    from ..config.state_scene import start_overrides

    if args.scene is None:
        raise ValueError("run needs a SCENE (or --continue CHECKPOINT)")
    overrides = {**scene_overrides(args), **({"output.cells": False} if args.no_cells else {})}
    if args.members is not None and overrides.get("ensemble.members", args.members) != args.members:
        raise ValueError(
            f"--members {args.members} and -s ensemble.members={overrides['ensemble.members']}: give one of them"
        )
    if args.members is not None and any(k.startswith("ensemble.") for k in overrides):
        overrides.setdefault("ensemble.members", args.members)
    overrides |= start_overrides(args.initial if args.members is None else None, args.level, args.time, args.truncation)
    given = {"ne": args.ne, "np_": args.np, "dt": args.dt, "days": args.days, "stepper": args.stepper}
    # a dt the scene scales is cut to divide the restart interval too
    given |= {"mesh": args.mesh, "overrides": overrides, "restart_every": args.restart_every}
    scene = load_scene(args.scene, **given)
    members = args.members
    if members is None and scene.ensemble is not None:  # the scene's [ensemble]
        members = scene.ensemble["members"]
    _check_ensemble_options(args, members)
    if members is not None and args.perturbation_degrees is not None:
        degree_band(args.perturbation_degrees, scene)  # before anything is written
    return scene, members, args.output or default_output(scene, members)


def _continuation(args) -> tuple:
    """(None: the restart file's scene, the restart file's members or None, the output) of ``run
    --continue R``; an ensemble's restart file continues as an ensemble."""
    from ..io.restart_file import glance

    stored = glance(args.continue_from)
    members = stored["members"]
    if args.members is not None and members != args.members:
        held = "a single run" if members is None else f"{members} members"
        raise SceneError(f"--members {args.members}: {args.continue_from} holds {held}")
    # another stepper or dt than the file's: a branch (the file's own: a continuation, as in Python)
    stepper, dt = (
        None if value == stored[key] else value for key, value in (("stepper", args.stepper), ("dt", args.dt))
    )
    _check_ensemble_options(args, members, (stepper, dt), (stored["stepper"], stored["dt"]))
    stem = args.continue_from.name.removesuffix(".nc").removesuffix(".restart")
    changes = "".join(f"_{v}" for v in (stepper, dt and f"dt{dt:g}") if v)  # a branch's
    name = f"{stem}_{'branch' + changes if changes else 'continued'}.nc"
    return None, members, args.output or args.continue_from.with_name(name)


def _progress_lines(args):
    """The run's ``ProgressLines`` (stdout, every ``--progress-every`` seconds of wall time) where
    no bar is drawn (stderr not a terminal) and --no-progress is not given, else None; a caller's
    ``main(argv)`` (its stdout its own) gets them only with --progress-every. ``SceneError`` for
    an interval that is not a number of seconds >= 0."""
    from .progress import PROGRESS_SECONDS, ProgressLines

    every = args.progress_every
    if every is not None and not (math.isfinite(every) and every >= 0):
        raise SceneError(f"--progress-every must be a number of seconds >= 0 (got {every:g})")
    if every is None:
        every = PROGRESS_SECONDS if args.console else 0
    if args.no_progress or not every or sys.stderr.isatty():
        return None
    return ProgressLines(lambda line: print(f"progress    {line}", flush=True), every)


def _check_ensemble_options(args, members: int | None, changed=(None, None), own=(None, None)) -> None:
    """``SceneError`` for the ensemble's options where they do not go together (before anything
    is built): --perturbation, --seed, --perturbation-degrees, --initial, --layout or --blow-up without an
    ensemble (``members``: --members, or the member count of the restart file continued),
    --perturbation-degrees without --perturbation, --initial with a perturbation, those with
    a continuation (its members start from the file), --layout, --blow-up, or a --stepper or --dt
    other than the file's (``changed``: those given that differ from ``own``, the restart file's
    stepper and dt; None where not) with an ensemble's continuation (no branches yet)."""
    starts = (
        ("--perturbation", args.perturbation),
        ("--seed", args.seed),
        ("--perturbation-degrees", args.perturbation_degrees),
        ("--initial", args.initial if members is not None else None),  # a single run's: a reanalysis file
    )
    given = [flag for flag, value in (*starts, ("--vary", args.vary)) if value is not None]
    if members is None:
        given += [f for f, v in (("--layout", args.layout), ("--blow-up", args.blow_up)) if v is not None]
        if given:
            raise SceneError(f"{' and '.join(given)} only with --members N (or a scene's [ensemble])")
        return
    if args.perturbation_degrees is not None and args.perturbation is None:
        raise SceneError("--perturbation-degrees only with --perturbation M (the noise's amplitude)")
    kinds = {"--initial": "--initial's file", "--vary": "their own values (--vary)"}
    if len({kinds.get(flag, "a perturbation") for flag in given}) > 1:
        raise SceneError(
            f"{' and '.join(given)}: the members start from one of a perturbation, --initial's file or --vary"
        )
    if args.continue_from is not None:
        if given:
            raise SceneError(f"{' and '.join(given)}: a continued ensemble's members start from its restart file")
        given = [
            f"{flag} {value:g}" if isinstance(value, float) else f"{flag} {value}"
            for flag, value in (
                ("--stepper", changed[0]),
                ("--dt", changed[1]),
                ("--layout", args.layout),
                ("--blow-up", args.blow_up),
            )
            if value is not None
        ]
        if given:
            raise SceneError(
                f"{' and '.join(given)}: an ensemble continues with its own stepper, dt, layout and blow-up policy "
                f"(no branches yet; the file's: {own[0]}, dt = {own[1]:g} s)"
            )


def _member_options(args, members: int | None, scene) -> dict:
    """``run --members N``'s (or a scene's [ensemble]) ``Simulation`` options: the members' count
    (None: the scene's), their start, layout and blow-up policy; {} for a single run."""
    from ..members.initial import MemberFile, Perturbation, Variants

    if members is None:
        return {}
    initial = None if args.initial is None else MemberFile(args.initial)
    if args.vary is not None:
        initial = Variants(varied(args.vary))
    degrees = None if args.perturbation_degrees is None else degree_band(args.perturbation_degrees, scene)
    if args.perturbation or args.seed is not None or degrees is not None:
        initial = Perturbation(0.0 if args.perturbation is None else args.perturbation, args.seed or 0, degrees)
    # members None: the scene's [ensemble] members (and, without a start given, its perturbation)
    return {"members": args.members, "initial": initial, "layout": args.layout, "blow_up": args.blow_up or "stop"}


def _ensemble_summary(sim, result, start: list, since: float) -> None:
    """``run --members N``'s summary: wall time, each invariant's and error's range over the
    members (``start`` their invariants at model day ``since``), the spread of h, the steps."""
    scene, steps, loop = sim.scene, result.steps - result.first_step, result.loop_time
    for line in sim.drops:  # collective
        if sim.root:
            print(f"swe-sphere: {line}", file=sys.stderr)
    print("summary")
    print(
        f"  wall time   {loop:.2f} s for {steps} steps ({1e3 * loop / max(steps, 1):.2f} ms/step, "
        f"{1e3 * loop / max(steps, 1) / len(sim.members):.3f} ms a member), setup {result.setup_time:.2f} s"
    )
    end, errors = sim.members.invariants(), sim.members.errors()  # collective, by member
    kept = [k for k in range(len(sim.members)) if k not in sim.dropped]  # a member dropped has no state to score
    invariant = start[0] if sim.case.h_is_depth else ["mass"]  # h a tracer (TC1): its mass alone, as a run's
    for key in invariant if kept else ():
        change = [end[k][key] / start[k][key] - 1 for k in kept]
        print(
            f"  {key:<21} relative change {min(change):+.3e} to {max(change):+.3e} since day {since:g}, over the members"
        )
    unscored = [key for key in errors[0] if kept and all(math.isnan(errors[k][key]) for k in kept)]
    for key in errors[0] if kept else ():
        values = [errors[k][key] for k in kept]
        if key not in unscored:
            print(f"  {key:<21} {min(values):.3e} to {max(values):.3e} over the members (the run file's, by member)")
    if unscored:  # a reference's errors at a day it does not store
        print(f"  {'reference':<21} {_unscored(scene)}")
    spread = sim.h_spread_rms()
    print(f"  h spread    {spread:.4g} m (area-weighted RMS of the members' standard deviation at day {scene.days:g})")
    if sim.control is not None:
        print(f"  steps       {sim.control.summary()}")
    print(f"  output      {result.output}")


def _ensemble_header(args, sim, output: Path, device) -> None:
    """``run --members N``'s header (before the run): the scene, grid, terms, stepper (its
    precision and control), the members and how they step, a continuation's step, the Courant numbers, notes,
    the output and restart files."""
    from ..members.initial import alike_line
    from ..members.units import POLICIES
    from ..model.diagnostics import courant_numbers
    from ..simulation.writers import restart_path
    from .report import (
        control_line,
        courant_line,
        precision_line,
        print_notes,
        print_output,
        print_streams,
        scene_notes,
        terms_line,
    )

    scene, ens = sim.scene, sim.members
    gravity_waves = "pressure_gradient" in scene.terms
    states = [x for k, x in enumerate(sim.states()) if k not in sim.dropped]  # a continued run's dropped: NaN
    courant = [courant_numbers(ens.grid, *x[:3], scene.dt, scene.planet["gravity"], gravity_waves) for x in states]
    print(f"scene       {scene.name}: {scene.description}")
    print(f"grid        {scene.grid_text}: {scene.nelem} elements, {ens.grid.nunique} unique nodes")
    print(terms_line(scene))
    print(
        f"stepper     {scene.stepper}, dt = {scene.dt:g} s, {scene.nsteps} steps to day {scene.days:g}, device {device}"
    )
    print(precision_line(scene))
    if scene.control is not None:
        print(f"control     {control_line(scene.control, scene.dt)}; one dt for every member")
    where = "in the same launches" if ens.layout == "shared" else "each on a model of its own, in turn"
    if ens.comm is not None:
        where += f", over {ens.comm.size} MPI ranks ({ens.held.size} on rank 0)"
    print(
        f"ensemble    {ens.members} member{'s' if ens.members != 1 else ''} {where}; initial states {ens.initial_states}; "
        f"a blow-up: {POLICIES[ens.blow_up]}"
    )
    if sim.step:
        print(f"continued   from {args.continue_from}, step {sim.step} (day {sim.time:g})")
    if courant:  # NaN gravity-wave numbers (h a tracer) stay NaN
        print(courant_line({k: max(c[k] for c in courant) for k in courant[0]}, sim.time, "nodes and members"))
    print_notes(scene_notes(scene, args.continue_from), ens.root)
    if ens.alike and ens.root:  # a run of N copies: say so before it, not only by a spread of 0 m after it
        print(f"swe-sphere: warning: {alike_line(ens.members)}", file=sys.stderr)
    print_output(scene, output)
    print_streams(scene, output)
    if args.restart_every is not None:  # as a run's header says it
        print(f"restart     {restart_path(output)} (every {args.restart_every:g} days and at the end)")


def _unscored(scene) -> str:
    """An ensemble summary's words for a last day its reference does not store, as a run's say it."""
    if scene.reference_file is None:
        return f"none at day {scene.days:g}"
    from ..cases.reference import stored_days

    name = scene.reference_file.stem.rsplit("_", 1)[-1]  # the truncation ("T213")
    days = ", ".join(f"{day:g}" for day in stored_days(scene.reference_file))
    return f"none at day {scene.days:g}: {name} stores days {days}"


def _note(line: str) -> None:
    """A run's note on stderr, above its progress bar."""
    from tqdm import tqdm

    tqdm.write(f"swe-sphere: note: {line}", file=sys.stderr)


def _output_lock(output: Path, comm):
    """The writer's lock of ``output`` taken before the set-up and the header, on the rank
    that writes (rank 0; ``HeldLock``, which the run's writer takes over): every rank raises
    ``OutputError`` (one line) when another run writes ``output`` now."""
    from ..core.mpi import from_root
    from ..io.output_files import HeldLock

    return from_root(comm, lambda: HeldLock(output), OutputError) or contextlib.nullcontext()


def _run(args, scene, members, output, device, comm) -> int:
    """The run of ``command``, of one member or ``members``: built (or continued), its header,
    the loop writing ``output`` (and its restart files), its summary; a blow-up keeps the file's
    good times (exit ``EXIT_BLOWUP``)."""
    from tqdm import tqdm

    from ..core import mpi
    from ..core.workers import cpus, limit_threads
    from ..io.output_files import check_target
    from ..members.initial import MembersAlike
    from ..simulation.schedules import restart_marks
    from ..simulation.simulation import Simulation
    from ..simulation.writers import restart_path

    if comm is not None:
        limit_threads(max(1, cpus() // mpi.node_local_size(comm)))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MembersAlike)  # the header says it, as a command's warning
        if args.continue_from is None:
            kw = {"progress": not args.no_progress, "comm": comm, "graphs": args.graphs}
            sim = Simulation(scene, device, **kw, **_member_options(args, members, scene))
        else:
            sim = _continued(args, device, comm, members)
    if not sim.root:  # rank 0 reports; the others' errors still reach stderr
        sys.stdout = open(os.devnull, "w")
    if args.continue_from is not None:  # a continuation keeps its checkpoint's restart interval
        args.restart_every = sim.restart_every if args.restart_every is None else args.restart_every
        if args.restart_every is not None:  # a new run's: in ``command``
            restart_marks(sim.scene, args.restart_every)  # the checkpoint's scene, before the header
            check_target(restart_path(output), args.overwrite)  # where the interval is the checkpoint's own
    since, start = sim.time, sim.members.invariants() if members else None  # collective: the members' drift
    if members:
        _ensemble_header(args, sim, output, device)
    else:
        header(args, sim, output, device, comm)
    try:
        result = sim.run(
            output,
            overwrite=args.overwrite,
            restart_every=args.restart_every,
            compress=args.compress,
            history=" ".join(["swe-sphere", *(sys.argv[1:] if args.argv is None else args.argv)]),
            notify=_note,
            log=lambda line: tqdm.write(f"log         {line}", file=sys.stdout),
            progress_lines=args.progress_lines,
        )
    except BlowUp as err:  # on every rank alike (the bad node is found over all of them)
        kept = "the good output times are" if members else "the last good state is"
        result, blowup = None, f"swe-sphere: {err}; {kept} in {output}"
    if args.console:
        hold_signals()  # the output is closed: a signal from now on is answered as the process ends
    if result is None:
        if sim.root:
            print(blowup, file=sys.stderr)
        return EXIT_BLOWUP
    if members:
        _ensemble_summary(sim, result, start, since)
    else:
        summary(result, sim)
    return 0
