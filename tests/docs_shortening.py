"""``swe-sphere`` as the executed-docs test runs it (tests/test_docs_examples.py puts a
``swe-sphere`` that runs this file first on PATH): the command line of README.md and
docs/*.md shortened to a tiny grid and a few runs, then the real command-line tool.

What changes, and why it keeps the pages' order meaningful:

- ``--ne N`` of ``run``, ``sweep`` and ``stability`` becomes ``small_ne(N)``: 2 for
  N ≤ 8 and one more a doubling (16 → 3, 30 → 4, 60 → 5), so that runs a page tells
  apart by their grid (``run tc5_mountain_homme`` and ``… --ne 60``) still write
  different default files; at np above 4 (``--np``, else the scene's) fewer, about the
  GLL points of np 4's (``small_ne(N, np)``: Galewsky's ne12 np8 → ne2 np8, 654 steps for
  6 days where ne3 took 978 at 2.6x the CPU; ``… --ne 30 --np 8`` → ne2, 1.6 s of CPU
  where ne4 took 4.9; the np tells its files apart); a command without ``--ne`` gets that of its scene's grid
  (``stability``: of its default ne 8), but for a run on a mesh file (``--mesh``,
  ``-s grid.mesh_file=…``, a scene whose ``[grid]`` names one) or from a restart file
  (``--continue``, ``--from``), whose grid is the file's. A ``--dt`` given with a known grid grows as the grid coarsens
  (``coarser_dt``: the same Courant number).
- A default file name in any argument (``…_ne8np4_ssprk3.nc``) says the shortened grid.
- A sweep makes one run: the first of ``--runs``, or the first of ``--steppers`` at the
  first of ``--courant`` (``--dt``); ``stability`` bisects the first of ``--steppers`` on
  the first of its cases of the fewest GLL points (each case's bisection is the same code on
  another scene; Galewsky's np 8 cost twice TC6's np 4, reference.md's ark324), into the
  folder the whole suite writes by default (``stability_<cases>_ne<N>``);
  ``--workers`` is dropped (each worker process imports the model again, which costs
  more than a tiny run); a sweep over N perturbed members (``--members N --perturbation M``)
  sweeps two (each member's sweep is the same code from another start, and two make
  members.csv's spread; reference.md's four cost 7 s).
- A frontier keeps the first of its ``--ne`` (shortened as a run's) and ``--steppers`` and two of
  its ``--np`` (each grid is a sweep of its own: docs/explanation/efficiency/frontier.md's ladders at ne 12–24 and np
  7–8 ran for over 15 minutes at their own grids).
- ``mesh --levels N`` refines one level (2x, not 2^N x): the refinement, its transitions
  and the run on the file stay; the 4x mesh's cells took 12 s of CPU to build and its run
  935 steps, the 2x mesh's a fraction of a second and 468 (README's ne10 box, load 12).
- The run lengths stay: at these grids a 15-day run costs a fraction of a second
  above the process's start-up, and the pages' days carry meaning (the reference's
  stored days, restart days, the time filter's window).
"""

from __future__ import annotations

import json
import math
import re
import sys
import traceback

GRID_COMMANDS = ("run", "sweep", "stability")
FILE_GRID = ("--continue", "--from", "--mesh")  # the grid is the file's
COARSE_NE = 8  # `stability --ne`'s default, the usual coarse grid
DAY = 86400.0  # s
EACH = "--each"  # this file's first argument for a page's commands and Python blocks run in one process (``run_each``)


def small_ne(ne: int, np_: int = 4) -> int:
    """The shortened grid of ``ne``: 2 for ne ≤ 8, one more a doubling (16 → 3, 30 → 4,
    60 → 5), so that the grids a page tells apart stay apart; at ``np_`` above 4, as many
    elements as keep about that grid's GLL points (ne · (np − 1)), 2 at least (ne12 np8: 2)."""
    small = 2 + max(0, round(math.log2(ne / 8)))
    return small if np_ <= 4 else max(2, round(small * 3 / (np_ - 1)))


def coarser_dt(dt: float, ne: int, np_: int = 4) -> float:
    """A Δt (s) given for grid ``ne`` (at ``np_``) on the grid ``small_ne(ne, np_)``: as many
    times longer as the grid is coarser (the same Courant number), then the nearest that
    divides the day (a given Δt the page chose to divide its output interval still does)."""
    return DAY / max(1, round(DAY / dt * small_ne(ne, np_) / ne))


def scene_ne(scene: str) -> int:
    """The ne of a scene file or bundled scene's grid (8, the usual coarse grid, where the
    scene does not load: the real command then says why in one line)."""
    from swe_sphere.config.scene import load_scene
    from swe_sphere.core.errors import SweSphereError

    try:
        return load_scene(scene).ne
    except SweSphereError:
        return COARSE_NE


def scene_np(case: str, unknown: int = 8) -> int:
    """The np of a stability case's or a run's scene (its name or file; ``unknown`` where it
    names none, by default 8, the largest: the real command then runs it or says why in one
    line)."""
    from swe_sphere.config.scene import load_scene
    from swe_sphere.core.errors import SweSphereError

    try:
        return load_scene(case).np
    except SweSphereError:
        return unknown


KEPT = {  # per command: option → how many of its comma-separated values stay
    "sweep": {"--runs": 1, "--steppers": 1, "--courant": 1, "--dt": 1},
    "stability": {"--steppers": 1},
    "frontier": {"--ne": 1, "--np": 2, "--steppers": 1},
}


def _file_names(args: list[str]) -> list[str]:
    """``args`` with each default file name's grid (``_ne<N>np<P>``) shortened."""
    return [re.sub(r"_ne(\d+)np(\d+)", lambda m: f"_ne{small_ne(int(m[1]), int(m[2]))}np{m[2]}", a) for a in args]


def shorten(argv: list[str]) -> list[str]:
    """``swe-sphere``'s arguments (the subcommand first) shortened as the module says."""
    if argv[:1] == ["mesh"] and "--levels" in argv[:-1]:
        argv = list(argv)
        argv[argv.index("--levels") + 1] = "1"
    if not argv or argv[0] not in (*GRID_COMMANDS, "frontier"):
        return _file_names(argv)
    command, args = argv[0], list(argv[1:])
    if "--workers" in args:
        i = args.index("--workers")
        del args[i : i + 2]
    cases = []
    if command == "stability":  # its first case: the cases are the arguments before the first option
        cases = args[: next((i for i, a in enumerate(args) if a.startswith("-")), len(args))]
        if "--np" not in args[:-1]:  # the cases' own np: the first of the fewest points
            cases_np = [scene_np(case) for case in cases]
            args[0] = cases[cases_np.index(min(cases_np))]
        del args[1 : len(cases)]
    if command == "sweep" and "--perturbation" in args and "--members" in args[:-1]:
        i = args.index("--members") + 1
        args[i] = str(min(int(args[i]), 2)) if args[i].isdigit() else args[i]
    for option, n in KEPT.get(command, {}).items():
        if option in args[:-1]:
            i = args.index(option) + 1
            args[i] = ",".join(args[i].split(",")[:n])
    np_ = 4  # a frontier's: its --np is a list, each grid's ne shortened alike
    if command != "frontier":
        if "--np" in args[:-1]:
            np_ = int(args[args.index("--np") + 1])
        elif args and not args[0].startswith("-"):
            np_ = scene_np(args[0], unknown=4)  # a grid as np 4's where the scene does not load
    if "--ne" in args[:-1]:  # a frontier's one grid too (each grid is a sweep of its own)
        i = args.index("--ne") + 1
        ne = int(args[i])
        args[i] = str(small_ne(ne, np_))
    elif command == "frontier":  # its own ladder's grids
        ne = None
    elif command == "stability":
        ne = COARSE_NE
        args += ["--ne", str(small_ne(ne, np_))]
    elif (
        args
        and not args[0].startswith("-")
        and not set(FILE_GRID) & set(args)
        and not _mesh_file(args)
        and (ne := scene_ne(args[0]))  # 0: a scene on a mesh file
    ):
        args += ["--ne", str(small_ne(ne, np_))]
    else:
        ne = None  # the file's grid, not known here: its Δt stays
    if command == "frontier":
        return [command, *args]
    if len(cases) > 1 and not {"--output", "--mesh"} & set(args):  # the folder the whole suite writes by default
        args += ["--output", f"stability_{'_'.join(cases)}_ne{args[args.index('--ne') + 1]}"]
    if ne is not None and "--dt" in args[:-1]:
        i = args.index("--dt") + 1
        args[i] = ",".join(str(coarser_dt(float(dt), ne, np_)) for dt in args[i].split(","))
    return [command, *_file_names(args)]


def _mesh_file(args: list[str]) -> bool:
    """Whether ``args`` set the grid to a mesh file by ``-s grid.mesh_file=...``."""
    return any(a.startswith("grid.mesh_file=") and args[i - 1] in ("-s", "--set") for i, a in enumerate(args) if i)


def run_each(items: list[list[str] | str]) -> int:
    """A page's plain ``swe-sphere`` commands (each a list: its arguments, as the page writes them)
    and Python blocks (each a string: its source) one after the other in this process, until one
    fails: its exit status, else 0. A command is shortened and given to ``main`` as a caller's
    arguments (the console script's ``main()`` ends the process when its command is done); a block
    runs as ``python -c`` runs it, in a namespace of its own (it sees no name another block made).
    The model's imports and kernels load once for a page's commands and blocks in a row (a
    process's start is seconds of CPU on a busy machine: 1.2 s of CPU to a tiny run's first
    step, 0.06 s for the next run in the same process, 2026-11-27)."""
    from swe_sphere.cli import main

    for item in items:
        if isinstance(item, str):
            sys.argv[1:] = []  # a block's arguments, as `python -c` has them
            code, what = _run_block(item), "a Python block (its traceback above)"
        else:
            sys.argv[1:] = argv = shorten(item)
            try:
                code = main(argv)
            except SystemExit as stop:  # the argument parser's
                code = stop.code
            what = f"swe-sphere {' '.join(item)}"
        if code:
            print(f"{what}: exit status {code}", file=sys.stderr)
            return code if isinstance(code, int) else 2
    return 0


def _run_block(source: str) -> int | str | None:
    """The exit status of Python ``source`` run as a main program: its ``sys.exit`` code, 1
    (its traceback printed) where it raised, else 0."""
    try:
        exec(compile(source, "<string>", "exec"), {"__name__": "__main__"})
    except SystemExit as stop:
        return stop.code
    except Exception:
        traceback.print_exc()
        return 1
    return 0


if __name__ == "__main__":
    if sys.argv[1:2] == [EACH]:  # tests/test_docs_examples.py: commands and Python blocks in a row, as JSON
        sys.exit(run_each(json.loads(sys.argv[2])))
    sys.argv[1:] = shorten(sys.argv[1:])
    from swe_sphere.cli import main

    sys.exit(main())
