"""One run over several MPI ranks (``mpiexec -n N swe-sphere run``): explicit steppers give
the same bits on 1, 2 and 3 ranks, the semi-implicit, JFNK and IMEX steppers agree with one
rank to 1e-12 (the order of their inner products' sums), and a run on N ranks continues on M.

The ranks run as real processes under the mpich wheel's ``mpiexec`` (the test
extra installs mpich and mpi4py); the tests skip, saying why, only where mpiexec
or mpi4py is not installed. Where they are, MPI must run: a probe that fails or
does not finish fails the tests.
"""

from __future__ import annotations

import dataclasses
import functools
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS as STEPPER_REGISTRY

import roundoff
from helpers import cached_grid, one_line

# one worker runs the MPI tests one after another: each starts up to 4 ranks on this
# machine, and two such jobs at once would share its CPUs with each other as well
pytestmark = pytest.mark.xdist_group("mpi")


HERE = Path(__file__).resolve().parent


def _beside_python(name: str) -> str | None:
    beside = Path(sys.executable).with_name(name)
    return str(beside) if beside.is_file() else shutil.which(name)


@functools.cache
def mpi_failure() -> str | None:
    """Why ``mpiexec -n 2`` did not run an allreduce here (None: it did)."""
    code = "from mpi4py import MPI; c = MPI.COMM_WORLD; s = c.allreduce(c.rank + 1); c.rank or print(s)"  # one writer: no interleaving
    try:
        proc = subprocess.run(
            [_beside_python("mpiexec"), "-n", "2", sys.executable, "-c", code],
            capture_output=True,
            text=True,
            timeout=300,
        )
    except (OSError, subprocess.TimeoutExpired) as err:
        return f"mpiexec -n 2 did not run: {err}"
    if proc.returncode != 0 or proc.stdout.split() != ["3"]:
        return f"mpiexec -n 2 failed (exit {proc.returncode}): {(proc.stderr or proc.stdout).strip()[-300:]}"
    return None


def check_mpi() -> None:
    """Skip where mpiexec or mpi4py is not installed (saying so); fail where they are
    and MPI does not run."""
    if _beside_python("mpiexec") is None or importlib.util.find_spec("mpi4py") is None:
        pytest.skip("mpiexec or mpi4py is not installed (pip install -e .[test] installs mpich and mpi4py)")
    assert _beside_python("swe-sphere") is not None, (
        "the swe-sphere console script is not installed (pip install -e .[test])"
    )
    failure = mpi_failure()
    assert failure is None, failure


@pytest.fixture
def needs_mpi():
    """``check_mpi`` before the test."""
    check_mpi()


# MPICH's waits spin, yielding by sched_yield after 1000 polls: 3 ranks on this 2-core machine
# (and the other xdist worker) spent a third of their CPU spinning. With heavy yield a waiting
# rank sleeps instead (nanosleep): rk43's 315 balanced steps on 3 ranks took 5.8-6.6 s of wall
# and 5.4-6.1 s of CPU, against 6.8-8.2 s and 8.1-9.5 s (2026-11-28); the same bits. The
# developer's own setting wins.
MPICH_ENV = {"MPIR_CVAR_ENABLE_HEAVY_YIELD": "1"}


def mpirun(ranks: int, args: list[str], cwd: Path, program: list[str] | None = None) -> subprocess.CompletedProcess:
    """``mpiexec -n ranks swe-sphere args`` (or ``program args``), one thread per rank."""
    env = {**MPICH_ENV, **os.environ, "SWE_SPHERE_THREADS": "1"}
    return subprocess.run(
        [_beside_python("mpiexec"), "-n", str(ranks), *(program or [_beside_python("swe-sphere")]), *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )


def mpirun_python(ranks: int, args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return mpirun(ranks, args, cwd, [sys.executable])


FIELDS = ("u", "v", "h", "vorticity", "mass", "total_energy", "potential_enstrophy")


def assert_same_bits(a: Path, b: Path) -> None:
    """The fields and every diagnostic series (errors against exact solutions and
    the T213 reference included), timings aside, are the same bits."""
    with xr.open_dataset(a, decode_times=False) as x, xr.open_dataset(b, decode_times=False) as y:
        assert x.sizes["time"] == y.sizes["time"] >= 2
        assert set(FIELDS) <= set(x.data_vars) and set(x.data_vars) == set(y.data_vars)
        for name in [*x.data_vars, "lat", "lon"]:  # the grid's (area, mesh) too
            if name != "wall_time":
                assert np.array_equal(x[name].values, y[name].values, equal_nan=x[name].dtype.kind == "f"), name
        assert y.attrs["mpi_ranks"] > x.attrs["mpi_ranks"] == 1


def test_each_output_time_gathers_a_state_once(tmp_path, monkeypatch):
    """An output time gathers the state's u, v, h, vorticity and divergence on rank 0
    in one ``Topology.gather`` (a collective Gatherv over the ranks), which the
    diagnostics and the file share, plus one gather for the wind-error split (the
    vorticity and divergence of the error against the exact wind and of the exact wind);
    the run's Courant numbers come from its first output time's gather. Counted on
    one process, where each call stands for the collective."""
    from swe_sphere.config.scene import load_scene
    from swe_sphere.core.constants import DAY

    from helpers import make_sim

    dt = 1800.0
    scene = load_scene("tc2_steady", ne=2, np_=4, dt=dt, days=4 * dt / DAY, stepper="ssprk3")
    sim = make_sim(dataclasses.replace(scene, output_every_days=2 * dt / DAY))  # outputs at steps 0, 2, 4
    shapes, real = [], sim.topology.gather
    monkeypatch.setattr(sim.topology, "gather", lambda a: shapes.append(np.shape(a)) or real(a))
    sim.run(tmp_path / "run.nc")
    n = sim.topology.N
    assert shapes == [(5, n), (4, n)] * 3
    shapes.clear()
    sim.run(None)  # at the end already: one output time, no file (no divergence)
    assert shapes == [(4, n), (4, n)]


# two passive tracers, q = 1 and a latitude marker, with the limiter
LIMITED_TRACERS = ["-s", 'tracers.names=["one", "marker"]', "-s", 'tracers.initial=["constant", "latitude"]']
LIMITED_TRACERS += ["-s", 'tracers.limiter="optimization"']
EXPLICIT_RUNS = [  # (scene, its options): each of these runs has the same bits on 1, 2 and 3 ranks
    ("tc2_steady", ["--stepper", "rk4", "--days", "0.25"]),
    ("tc2_steady", ["--stepper", "kgu35", "--days", "0.25"]),
    ("tc5_mountain", ["--stepper", "fbrk32", "--days", "0.1"]),  # the continuity and momentum halves, topography
    ("tc5_mountain", ["--stepper", "leapfrog_trapezoidal", "--days", "0.1"]),  # with hyperviscosity and topography
    ("tc5_mountain", ["--stepper", "split_explicit", "--days", "0.1"]),  # the fast/slow split, its mean depth
    ("tc5_mountain", ["--stepper", "mri", "-s", "mri.method=mri_gark_erk33a", "--days", "0.1"]),  # L z in one pass
    ("tc4_forced_low", ["--days", "0.25"]),  # ssprk3 with the time-dependent forcing
    (  # passive tracers: their rows in the tendency, the DSS and the stages, their ∇⁴ (q·hs), their q and
        # masses, the limiter (its neighbours' bounds exchanged)
        "galewsky",
        ["--stepper", "ssprk3", "--days", "0.1", *LIMITED_TRACERS],
    ),
    (  # and their ∇⁴ inside every stage (tracers.stage_hyperviscosity), its Laplacians' DSS over the
        # ranks; a Δt whose ν_s Δt λ (3.2) ssprk43's stages hold (5.15; the scene's 785 s: 6.9)
        "galewsky",
        ["--stepper", "ssprk43", "--dt", "360", "--days", "0.1", *LIMITED_TRACERS]
        + ["-s", "tracers.stage_hyperviscosity=true"],
    ),
    ("tc7_era_july", ["--days", "0.1"]),  # a reanalysis start (ERA-Interim's July), synthesised at each rank's nodes
    ("tc5_mountain", ["--stepper", "kgu35", "--days", "0.1", "--precision", "float32"]),  # a float32 tendency
    # the float32 state, kept between steps (the default): its fixer's mass taken once, the ∇⁴ on it in place
    ("tc5_mountain", ["--stepper", "rk4", "--days", "0.1", "--precision", "float32_state"]),
    (  # the float32 state's increments added to a float64 state between steps (compensated)
        "tc5_mountain",
        ["--stepper", "rk4", "--days", "0.1", "--precision", "float32_state", "-s", "numerics.compensated=true"],
    ),
    (  # a digital-filter start; T213 errors at day 1
        "tc5_mountain",
        ["--stepper", "rk4", "--dt", "3600", "--days", "1", "-s", "case.initialization=dfi"]
        + ["-s", "dfi.cutoff_hours=6", "-s", "dfi.span_hours=12"],
    ),
    (  # steps that choose themselves: the error norm's sum in the whole grid's node order (its series
        # in the run file), a rejected step, the CFL cap's Courant numbers (it binds from step 2)
        "tc5_mountain",
        ["--stepper", "bs32", "--days", "0.1", "-s", "time.control=error", "-s", "time.rtol=1e-5"]
        + ["-s", "time.cfl=0.1"],
    ),
    (  # the balanced mode: the spatial rate's sums in the whole grid's node order, set every 16 steps
        # (28 steps and 4 rejected to day 0.1: set again at step 16; day 0.5 took 315 steps, 6.8 s of 3 ranks)
        "tc5_mountain",
        ["--stepper", "rk43", "--days", "0.1", "-s", "time.control=balanced", "-s", "time.balance=0.01"],
    ),
]


def explicit_argv(folder: Path, i: int, ranks: int) -> list[str]:
    """``swe-sphere`` arguments of EXPLICIT_RUNS[i] on ``ranks`` ranks, its run file in ``folder``."""
    scene, extra = EXPLICIT_RUNS[i]
    return ["run", scene, "--ne", "2", *extra, "--no-progress", "--output", str(folder / f"{i}_r{ranks}.nc")]


def continue_on_three(folder: Path, args: list[str], days: float) -> dict[int, list[list[str]]]:
    """The commands (by rank count) of ``swe-sphere run ARGS`` stopped at days/2 on 2 ranks (a
    restart file there) and continued on 3 to ``days``, their files in ``folder``."""
    half = str(days / 2)
    stop = ["run", *args, "--days", half, "--restart-every", half, "--output", str(folder / "half.nc")]
    rest = ["run", "--continue", str(folder / "half.restart.nc"), "--days", str(days)]
    return {2: [stop], 3: [[*rest, "--output", str(folder / "rest.nc")]]}


def assert_continued(folder: Path, args: list[str], days: float) -> None:
    """The run of ``continue_on_three`` (its commands run: a restart file at days/2) ends with the
    fields of one uninterrupted 1-rank run."""
    assert (folder / "half.restart.nc").is_file()
    assert main(["run", *args, "--days", str(days), "--output", str(folder / "whole.nc")]) == 0
    with (
        xr.open_dataset(folder / "whole.nc", decode_times=False) as whole,
        xr.open_dataset(folder / "rest.nc", decode_times=False) as rest,
    ):
        for name in ("u", "v", "h"):
            assert np.array_equal(whole[name].values[-1], rest[name].values[-1]), name


LEAPFROG = ["tc2_steady", "--ne", "2", "--stepper", "leapfrog", "--dt", "1800", "--no-progress"]  # continued
# the float32 state kept between steps (float32_state's default), continued
KEPT = ["galewsky", "--ne", "2", "--np", "4", "--dt", "1800", "--precision", "float32_state", "--no-progress"]
ERA = HERE.parent / "testcases" / "data" / "eraint_july_500hPa.nc"  # a reanalysis file, copied and then deleted
# on every rank once all have ended the run (rank 0 still reads the file after the loop: its summary's case)
GONE = "import pathlib, sys\nfrom mpi4py import MPI\nMPI.COMM_WORLD.Barrier()\npathlib.Path(sys.argv[1]).unlink(missing_ok=True)\n"


def reanalysis_commands(folder: Path) -> dict[int, list[list[str]]]:
    """A run from a copy of ERA-Interim's July file stopped at day 0.25 on 2 ranks, the copy deleted,
    and its restart file continued on 3 (``continue_on_three``)."""
    shutil.copy(ERA, folder / "july.nc")
    (folder / "gone.py").write_text(GONE)
    commands = continue_on_three(folder, [str(folder / "july.nc"), *REANALYSIS], 0.5)
    commands[2].append([str(folder / "gone.py"), str(folder / "july.nc")])
    return commands


REANALYSIS = ["--ne", "2", "--dt", "1800", "--no-progress"]
BRANCH = ["--stepper", "rk4", "--days", "0.5", "--ne", "2", "--no-progress"]  # from the spin's restart file
ENSEMBLE = ["run", "galewsky", "--ne", "2", "--np", "4", "--dt", "900", "--days", "0.5", "--members", "3"]
ENSEMBLE += ["--vary", "case.hhat=60,120,180", "--restart-every", "0.25"]
ENSEMBLE += ["-s", 'output.streams=[{name="q", every_days=0.125, fields=["h"]}]']  # rank 0 writes it, as the run file
# passive tracers: each member's own rows of mass hq, split by member as u, v and h (issue 125)
MEMBER_TRACERS = ["-s", 'tracers.names=["one", "marker"]', "-s", 'tracers.initial=["constant", "latitude"]']
ENSEMBLES = {  # its layouts: shared, and in turn (each member its own model: semi-implicit, g per member)
    "shared": ["--layout", "shared", *MEMBER_TRACERS],
    "in-turn": ["--stepper", "semi_implicit", "--vary", "planet.gravity=9.8,9.7,9.6"],
    "in-turn-tracers": ["--layout", "in_turn", *MEMBER_TRACERS],
}


def branch_commands(folder: Path) -> dict[int, list[list[str]]]:
    """TC4 spun up to day 0.25 in this process (its restart file), and its branch on 2 ranks."""
    spin = ["run", "tc4_forced_low", "--ne", "2", "--no-progress", "--days", "0.25", "--restart-every", "0.25"]
    assert main([*spin, "--output", str(folder / "spin.nc")]) == 0
    return {2: [["run", "--continue", str(folder / "spin.restart.nc"), *BRANCH, "--output", str(folder / "b2.nc")]]}


def ensemble_commands(folder: Path, layout: str) -> dict[int, list[list[str]]]:
    """An ensemble's run over 2 ranks, and its restart file continued on 3."""
    more = ["run", "--continue", str(folder / "two.restart.nc"), "--days", "0.75", "--output", str(folder / "c3.nc")]
    return {2: [[*ENSEMBLE, *ENSEMBLES[layout], "--output", str(folder / "two.nc")]], 3: [more]}


def solver_commands(folder: Path) -> dict[int, list[list[str]]]:
    """The solving steppers on 3 ranks (tests/mpi_steppers.py), with a semi-implicit run to DAYS
    made in this process and continued from its restart file there; JFNK by the command line on 2."""
    from mpi_steppers import DAYS, scene

    Simulation(scene("semi_implicit", DAYS), "cpu", progress=False).run(folder / "half.nc", restart_every=DAYS)
    three = [str(HERE / "mpi_steppers.py"), str(folder / "three.npz"), str(folder / "half.restart.nc")]
    implicit = ["run", "tc5_mountain", "--ne", "2", "--stepper", "implicit", "--days", str(DAYS), "--no-progress"]
    return {3: [three], 2: [[*implicit, "--output", str(folder / "two.nc")]]}


# each test's commands on 2 and 3 ranks (``swe-sphere`` arguments, or a test script's path and its
# arguments), its files in a folder of its own; the selected tests' run (``launches``)
OVER_RANKS = {
    "test_explicit_runs_same_bits_on_1_2_3_ranks": lambda d: {
        r: [explicit_argv(d, i, r) for i in range(len(EXPLICIT_RUNS))] for r in (2, 3)
    },
    "test_run_on_two_ranks_continues_on_three": lambda d: continue_on_three(d, LEAPFROG, 0.5),
    "test_a_kept_float32_state_continues_on_three": lambda d: continue_on_three(d, KEPT, 0.5),
    "test_a_branch_on_two_ranks_has_the_bits_of_one": branch_commands,
    "test_a_reanalysis_run_continues_on_three_without_its_file": reanalysis_commands,
    **{
        f"test_an_ensemble_s_members_over_ranks_keep_their_bits[{layout}]": functools.partial(
            ensemble_commands, layout=layout
        )
        for layout in ENSEMBLES
    },
    "test_solver_steppers_agree_with_one_rank": solver_commands,
    "test_a_gradient_is_the_same_bits_on_one_two_and_three_ranks": lambda d: {
        r: [[str(HERE / "mpi_gradient.py"), str(d / f"g{r}.npz")]] for r in (2, 3)
    },
}

# the commands of OVER_RANKS in one process a rank, one after another: a rank's start (imports,
# Warp's kernels) costs more than most of these runs (about 3 s of this 2-core machine a launch,
# thirteen launches of these tests before); each command's exit status and rank 0's output for its test
RUN_EACH = """
import contextlib, io, json, os, runpy, sys
from mpi4py import MPI
from swe_sphere.cli import main
commands, path, said = json.loads(sys.argv[1]), sys.argv[2], []
for args in commands:
    with contextlib.redirect_stdout(io.StringIO()) as out:
        if args[0].endswith(".py"):  # a test's script, as ``python SCRIPT ARGS`` runs it
            sys.argv[:] = args
            sys.path.insert(0, os.path.dirname(args[0]))
            runpy.run_path(args[0], run_name="__main__")
            code = 0
        else:
            code = main(args)
    said.append([code, out.getvalue()])
if MPI.COMM_WORLD.rank == 0:
    with open(path, "w") as f:
        json.dump(said, f)
"""


# the launches' outputs, once a session: the first module that asks runs the commands of every selected test
LAUNCHED = pytest.StashKey[dict]()


def commands_over_ranks(item):
    """The command builder of a selected test in its module's OVER_RANKS (this module's, test_mesh_mpi's,
    test_mpi_devices'), or None."""
    return getattr(getattr(item, "module", None), "OVER_RANKS", {}).get(item.name)


@pytest.fixture(scope="module")
def launches(request, tmp_path_factory) -> dict:
    """The commands of the selected tests of the modules' OVER_RANKS, one launch on 2 ranks, then
    one on 3 (a run stopped on 2 continues on 3), for every module that imports this fixture at
    once: {test's node id: (its folder, {ranks: [(exit status, rank 0's output) a command]})}."""
    if LAUNCHED in request.config.stash:
        return request.config.stash[LAUNCHED]
    check_mpi()
    root = tmp_path_factory.mktemp("over_ranks")
    selected = [(item.nodeid, commands_over_ranks(item)) for item in request.session.items]
    selected = [(test, build) for test, build in selected if build is not None]
    commands = {}
    for k, (test, build) in enumerate(selected):
        (root / str(k)).mkdir()
        commands[test] = build(root / str(k))
    said = {test: (root / str(k), {}) for k, (test, _) in enumerate(selected)}
    for ranks in (2, 3):
        order = [(test, args) for test, by_ranks in commands.items() for args in by_ranks.get(ranks, [])]
        if not order:
            continue
        proc = mpirun(
            ranks, [json.dumps([args for _, args in order]), "said.json"], root, [sys.executable, "-c", RUN_EACH]
        )
        assert proc.returncode == 0, proc.stderr[-2000:]
        for (test, _), result in zip(order, json.loads((root / "said.json").read_text()), strict=True):
            said[test][1].setdefault(ranks, []).append(tuple(result))
    request.config.stash[LAUNCHED] = said
    return said


@pytest.fixture
def over_ranks(launches, request) -> tuple[Path, dict[int, list[str]]]:
    """The test's folder and its commands' outputs by rank count (``launches``), each of which exited 0."""
    folder, said = launches[request.node.nodeid]
    for ranks, results in said.items():
        for code, out in results:
            assert code == 0, f"exit status {code} on {ranks} ranks\n{out[-2000:]}"
    return folder, {ranks: [out for _, out in results] for ranks, results in said.items()}


def test_explicit_runs_same_bits_on_1_2_3_ranks(over_ranks):
    folder, said = over_ranks
    for i in range(len(EXPLICIT_RUNS)):
        assert main(explicit_argv(folder, i, 1)) == 0, EXPLICIT_RUNS[i]
    for ranks in (2, 3):
        assert len(said[ranks]) == len(EXPLICIT_RUNS)
        assert all(out.count(f"ranks       {ranks} MPI ranks") == out.count("summary") == 1 for out in said[ranks])
        for i, run in enumerate(EXPLICIT_RUNS):
            try:
                assert_same_bits(folder / f"{i}_r1.nc", folder / f"{i}_r{ranks}.nc")
            except AssertionError as e:
                raise AssertionError(f"{run} on {ranks} ranks: {e}") from e


def test_run_on_two_ranks_continues_on_three(over_ranks):
    """Leapfrog (its x(n-1) in the restart file) stopped after half the run on 2 ranks and
    continued on 3 ends with the bits of an uninterrupted 1-rank run."""
    folder, _ = over_ranks
    assert_continued(folder, LEAPFROG, 0.5)


def test_a_kept_float32_state_continues_on_three(over_ranks):
    """Issue 128: a run that keeps the float32 state between steps (``model.held``), stopped on 2
    ranks (its h − H₀ bits and its fixer's mass in the restart file) and continued on 3, ends
    with the bits of an uninterrupted 1-rank run (Galewsky ne2 np4, its ssprk3 and ∇⁴)."""
    folder, _ = over_ranks
    assert_continued(folder, KEPT, 0.5)


def test_a_reanalysis_run_continues_on_three_without_its_file(over_ranks):
    """Issue 127, item 13: a run from a reanalysis file stopped on 2 ranks continues on 3 with the file
    deleted (the restart file keeps its analysed state), ending with the bits of an uninterrupted
    1-rank run from the bundled file it was copied from."""
    folder, _ = over_ranks
    assert not (folder / "july.nc").exists()
    assert_continued(folder, [str(ERA), *REANALYSIS], 0.5)


@pytest.mark.usefixtures("needs_mpi")
def test_the_run_files_cells_are_built_on_rank_0_alone(tmp_path, monkeypatch):
    """Rank 0 writes the run file, so it alone builds its cells (``dual.dual_mesh``) into an
    empty grid cache; the other ranks neither build nor read them."""
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "cache"))
    code = (
        "import sys\n"
        "from mpi4py import MPI\n"
        "from swe_sphere.io import dual\n"
        "real = dual.dual_mesh\n"
        "def counted(grid):\n"
        "    open(f'built-{MPI.COMM_WORLD.rank}', 'w').close()\n"
        "    return real(grid)\n"
        "dual.dual_mesh = counted\n"
        "from swe_sphere.cli import main\n"
        "sys.exit(main(['run', 'tc2_steady', '--ne', '3', '--days', '0.1', '--no-progress', '--output', 'o.nc']))\n"
    )
    proc = mpirun_python(2, ["-c", code], tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert sorted(p.name for p in tmp_path.glob("built-*")) == ["built-0"]
    assert len(list((tmp_path / "cache").iterdir())) == 1


@pytest.mark.usefixtures("needs_mpi")
def test_unreadable_restart_file_refused_by_every_rank_in_one_line(tmp_path):
    """Rank 0 alone reads a restart file (the others get its parts from it); when it
    cannot, every rank refuses: one line, exit 2, no output, no hang."""
    (tmp_path / "junk.nc").write_text("junk")
    proc = mpirun(2, ["run", "--continue", "junk.nc", "--output", "o.nc", "--no-progress"], tmp_path)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.count("junk.nc: not a readable netCDF file") == 1 and len(proc.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "o.nc").exists()


@pytest.mark.usefixtures("needs_mpi")
@pytest.mark.parametrize(
    "args, says",
    [
        (["sweep", "tc2_steady", "--ne", "0", "--days", "1", "--runs", "rk4@1"], "ne must be an integer >= 1"),
        (["stability", "nocase"], "unknown stability case 'nocase'"),
    ],
)
def test_a_study_s_bad_input_under_mpiexec_is_one_line(tmp_path, args, says):
    """Every rank of a sweep or a stability suite under mpiexec refuses bad input alike: rank 0
    says it, once (it was said once a rank), exit 2, nothing written."""
    proc = mpirun(2, [*args, "--output", "out"], tmp_path)
    assert proc.returncode == 2, proc.stderr[-2000:]
    assert proc.stderr.count(says) == 1 and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert list(tmp_path.iterdir()) == []


@pytest.mark.usefixtures("needs_mpi")
def test_sigint_on_two_ranks_is_one_line(tmp_path, paused):
    """Ctrl-C (to mpiexec, which passes it on) reaches every rank, held after step 3,
    which stop at one step together: rank 0 alone says so (it said so once a rank),
    and no MPI_Abort is needed (exit 130)."""
    import signal

    proc = paused(
        "step:3",
        tmp_path,
        "run",
        "tc5_mountain",
        "--ne",
        "4",
        "--days",
        "200",
        "--no-progress",
        "--output",
        "o.nc",
        launcher=[_beside_python("mpiexec"), "-n", "2"],
        env={key: os.environ.get(key, value) for key, value in MPICH_ENV.items()},  # as mpirun's
    )
    proc.send_signal(signal.SIGINT)
    err = proc.communicate(timeout=120)[1]
    assert proc.returncode == 130, err[-2000:]
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("swe-sphere: interrupted by SIGINT at step 3 "), err[-2000:]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.nc", "o.restart.nc"]


@pytest.mark.usefixtures("needs_mpi")
def test_blow_up_on_two_ranks_is_one_line(tmp_path):
    """Every rank finds the blow-up (the bad node is sought over all of them); rank 0
    alone says so, as it alone gives the stability warning: two lines, not four."""
    proc = mpirun(
        2,
        [
            "run",
            "tc2_steady",
            "--ne",
            "2",
            "--stepper",
            "ssprk3",
            "--dt",
            "14400",
            "--days",
            "10",
            "--no-progress",
            "--output",
            "o.nc",
        ],
        tmp_path,
    )
    assert proc.returncode == 3, proc.stderr[-2000:]
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 2 and "warning: dt = 14400 s" in lines[0] and "blow-up at step 4" in lines[1], proc.stderr[
        -2000:
    ]
    assert (tmp_path / "o.nc").is_file()


CHECKED_EVERY = """
import sys
from swe_sphere.simulation import simulation
from swe_sphere.cli import main

EVERY = int(sys.argv[1])
run = simulation.Simulation.run

def run_checked_every(self, *args, **kwargs):  # a GPU's blocks of steps between reads of the check, on the CPU
    self.check_every = EVERY
    return run(self, *args, **kwargs)

simulation.Simulation.run = run_checked_every
sys.exit(main(["run", *sys.argv[2:]]))
"""


@pytest.mark.usefixtures("needs_mpi")
def test_blow_up_inside_a_block_on_two_ranks(tmp_path, monkeypatch, capsys):
    """Leapfrog at dt = 3600 s on TC2 ne = 2 blows up at step 17. On two ranks with the
    check read every 5 steps (``Simulation.check_every``), the block 16-20 is re-run
    from step 15, leapfrog's x(n-1) restored on every rank: the same lines and the
    same run file (outputs 0 and the last good step 16) as one rank (this process) checking
    every step."""
    from swe_sphere.simulation import simulation

    args = ["tc2_steady", "--ne", "2", "--stepper", "leapfrog", "--dt", "3600", "--days", "2", "--no-progress"]
    run = simulation.Simulation.run

    def run_checked_every_step(self, *a, **kw):
        self.check_every = 1
        return run(self, *a, **kw)

    monkeypatch.setattr(simulation.Simulation, "run", run_checked_every_step)
    monkeypatch.chdir(tmp_path)
    assert main(["run", *args, "--output", "r.nc"]) == 3
    one = capsys.readouterr().err
    (tmp_path / "r.nc").rename(tmp_path / "r1.nc")
    two = mpirun(2, ["5", *args, "--output", "r.nc"], tmp_path, [sys.executable, "-c", CHECKED_EVERY])
    assert two.returncode == 3, two.stderr[-2000:]
    assert one == two.stderr and "swe-sphere: blow-up at step 17 (model time 0.7083 days)" in one, (
        f"{one}\n{two.stderr[-2000:]}"
    )
    assert_same_bits(tmp_path / "r1.nc", tmp_path / "r.nc")
    with xr.open_dataset(tmp_path / "r.nc", decode_times=False) as ds:
        assert list(ds.steps.values) == [0, 16]


@pytest.mark.roundoff
def test_solver_steppers_agree_with_one_rank(over_ranks, rng):
    """Semi-implicit, JFNK, IMEX and an IMEX Butcher pair (``tableau``, ARK3(2)4L[2]SA) on 3
    ranks (their Krylov inner products summed over ranks) end at one rank's state up to
    round-off (measured for the first three: 1e-14, 2e-13, 1e-14 of the wind), JFNK with
    float32 Helmholtz preconditioner solves too (``precision = "float32"``), and so do a
    semi-implicit run (its warm Helmholtz guess in the restart file) written on one rank
    and continued on 3, and the exponential steppers (wind 3.9e-11 and 2.9e-11: after a
    step on 3 ranks the state is 3e-16 from one rank's, but a forward-difference J·v
    turns the round-off of F at a state a bit away into ~√ε of J·v, and nothing, as
    Newton does for JFNK, converges it away). The JFNK run on 2 ranks goes through the
    command line.

    The bound is each run's own round-off floor: how far one rank ends from a start one
    rounding away (every node ±ε). On R ranks a global sum adds R partial sums, at most
    R roundings more, in every RHS evaluation and solver iteration (``ops``), each
    ending no farther than a rounding of the start: |R ranks − 1| ≤ R · ops · floor.

    IMEX with float32 solves agrees to its solves' tolerance, not to round-off: the ranks'
    float32 sums differ at float32's round-off, which the float64 refinement removes
    only down to ``tol`` of the increment; each solve may then end 2 tol of the run's
    change apart (at the default tol = 1e-6 measured 2.1e-13 of the wind on -march=native,
    6.1e-11 on Warp's generic CPU target; run here at tol = 1e-10)."""
    from mpi_steppers import STEPPERS, continued_state, final_states

    runs = {}
    one = final_states(runs=runs)
    ops = {name: n for name, (n, _) in runs.items()}
    floors = {
        name: max(roundoff.state_difference(x, one[name]))
        for name, x in final_states(nudge=lambda x, grid: roundoff.nudged(x, grid, rng)).items()
    }
    ops["continued"], floors["continued"] = (
        ops["semi_implicit"],
        floors["semi_implicit"],
    )  # the same run, one DAYS later
    tmp_path, _ = over_ranks
    one["continued"] = continued_state(tmp_path / "half.restart.nc")
    with np.load(tmp_path / "three.npz") as three:
        assert three["ranks"] == 3
        for name, state in one.items():
            wind, h = roundoff.state_difference(three[name], state)
            print(
                f"\n{name}: 3 ranks against 1: wind {wind:.2e}, depth {h:.2e} (floor {floors[name]:.2e}, {ops[name]} RHS and iterations)"
            )
            limit = 3 * ops[name] * floors[name]
            if name == "imex_mixed":
                stepper, options = STEPPERS[name]
                limit = 2 * STEPPER_REGISTRY[stepper].make_options(**options).tol * ops[name] * runs[name][1]
            roundoff.within(max(wind, h), limit, f"{name}: |3 ranks − 1| (wind, depth)")
    with xr.open_dataset(tmp_path / "two.nc", decode_times=False) as two:
        unique = one["implicit"][:, cached_grid(2, 4).first]  # the run file's columns
        wind, h = roundoff.state_difference(np.stack([two[n].values[-1] for n in ("u", "v", "h")]), unique)
        assert two.attrs["mpi_ranks"] == 2
        roundoff.within(max(wind, h), 2 * ops["implicit"] * floors["implicit"], "implicit: |2 ranks − 1| (wind, depth)")


def test_a_gradient_is_the_same_bits_on_one_two_and_three_ranks(over_ranks):
    """A run's gradient over ranks (``adjoint.gradient(..., comm=)``, issue 66's "Checks"): a
    cost of h at 40 points observed at three of TC5's six rk4 steps, reversed from two
    snapshots, and the same along a history of three Δt and by mri; their values, final states and gradients with
    respect to the initial state, ν, ν_s, hs, g and Ω are the same bits on 2 and 3 ranks as
    in one process."""
    from mpi_gradient import whole_gradient

    one = whole_gradient()
    for name in ("rk4", "history", "mri"):
        assert np.all(np.abs(one[f"grad_{name}"]).max(axis=1) > 0), name  # every row moved
        assert np.all(one[f"numbers_{name}"][-4:] != 0), name  # ν, ν_s, g and Ω moved
    tmp_path, _ = over_ranks
    for ranks in (2, 3):
        with np.load(tmp_path / f"g{ranks}.npz") as many:
            assert many["ranks"] == ranks
            for key, value in one.items():
                np.testing.assert_array_equal(many[key], value, err_msg=f"{key} on {ranks} ranks")


@pytest.mark.usefixtures("needs_mpi")
def test_memory_guard_counts_the_ranks_on_the_node(tmp_path):
    """Over ranks the guard weighs the share of the ranks on this node (each holds its
    own elements): here both ranks share the node, so ne = 100000 (a petabyte) is
    refused, by every rank alike (none waits for the others), before anything is
    built: one line, exit 3."""
    proc = mpirun(2, ["run", "tc2_steady", "--ne", "100000", "--output", "o.nc", "--no-progress"], tmp_path)
    one_line(
        proc.returncode, proc.stderr, 3, "ne=100000 np=4 with ssprk3 over 2 MPI ranks (2 on this node) needs about"
    )
    assert not (tmp_path / "o.nc").exists()


FAIL_ON_RANK_0 = """
import sys
from mpi4py import MPI
from swe_sphere.simulation import simulation
from swe_sphere.cli import main

def run(self, *args, **kwargs):  # rank 0 alone fails, as when its output's disk fills
    raise OSError(28, "No space left on device")

if MPI.COMM_WORLD.rank == 0:
    simulation.Simulation.run = run
sys.exit(main(["run", "tc2_steady", "--ne", "2", "--days", "0.1", "--no-progress", "--output", "o.nc"]))
"""


@pytest.mark.usefixtures("needs_mpi")
def test_failure_on_rank_0_alone_ends_the_job_with_its_status(tmp_path):
    """Rank 1 steps on and waits for rank 0 in the next collective; rank 0 ends the job
    (MPI_Abort with its exit status, 3) instead of leaving it hanging (the 300 s timeout)."""
    proc = mpirun_python(2, ["-c", FAIL_ON_RANK_0], tmp_path)
    assert proc.returncode == 3, (proc.returncode, proc.stderr[-2000:])
    assert proc.stderr.count("swe-sphere: No space left on device") == 1, (proc.returncode, proc.stderr[-2000:])
    assert not (tmp_path / "o.nc").exists()


FAIL_ON_RANK_1 = """
import sys
from mpi4py import MPI
from swe_sphere.simulation import simulation
from swe_sphere.cli import main

WHERE = sys.argv[1]
run, init = simulation.Simulation.run, simulation.Simulation.__init__

def failing_run(self, *args, **kwargs):  # rank 1 alone fails at the start of step 11, rank 0 already inside it
    step = self.stepper.step
    def failing_step(x):
        if self.step + 1 == 11:
            raise MemoryError()
        return step(x)
    self.stepper.step = failing_step
    return run(self, *args, **kwargs)

def failing_init(self, *args, **kwargs):  # rank 1 alone fails in the setup, before any file is opened
    raise MemoryError()

if MPI.COMM_WORLD.rank == 1:
    if WHERE == "loop":
        simulation.Simulation.run = failing_run
    else:
        simulation.Simulation.__init__ = failing_init
sys.exit(main(["run", "tc2_steady", "--ne", "2", "--days", "0.5", "-s", "output.every_days=0.1", "--no-progress",
               "--output", "o.nc", "--restart-every", "0.2"]))
"""


@pytest.mark.usefixtures("needs_mpi")
@pytest.mark.parametrize("where", ["loop", "setup"])
def test_failure_on_rank_1_alone_ends_the_job_and_keeps_the_output(tmp_path, where):
    """Rank 1 fails alone (out of memory) while rank 0 waits for it in a collective: rank 1
    prints its line and reports to rank 0, which closes its output with every completed
    output time (0, 0.1, 0.2 days of a 0.025-day step; the failure is in step 11) and ends
    the job with rank 1's status (3) instead of hanging (the 300 s timeout). The restart
    file of day 0.2 (step 8) is whole; a failure in the setup leaves no file at all."""
    program = [sys.executable, "-c", FAIL_ON_RANK_1, where]
    proc = mpirun(2, [], tmp_path, program)
    assert proc.returncode == 3, (proc.returncode, proc.stderr[-2000:])
    assert proc.stderr.count("swe-sphere: rank 1 of 2: out of memory\n") == 1, proc.stderr[-2000:]
    assert proc.stderr.count("swe-sphere:") == 1, proc.stderr[-2000:]  # rank 0 says nothing of its own
    if where == "setup":
        assert sorted(p.name for p in tmp_path.iterdir()) == []
        return
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.nc", "o.restart.nc"]
    with xr.open_dataset(tmp_path / "o.nc", decode_times=False) as ds:
        assert np.allclose(ds.time.values, [0, 0.1, 0.2], rtol=0, atol=1e-12)
        assert ds.attrs["failed"] == "rank 1 of 2: out of memory"
        assert np.isfinite(ds.h.values).all() and ds.h.shape == (3, 218)
    with xr.open_dataset(tmp_path / "o.restart.nc", decode_times=False) as ck:
        assert ck.attrs["step"] == 8


def test_a_branch_on_two_ranks_has_the_bits_of_one(over_ranks):
    """``run --continue R --stepper rk4`` (a branch, TC4's time-dependent forcing read
    at the branch's clock) on 2 ranks gives the 1-rank branch's bits."""
    folder, said = over_ranks
    assert main(["run", "--continue", str(folder / "spin.restart.nc"), *BRANCH, "--output", str(folder / "b1.nc")]) == 0
    assert "branch      from" in said[2][0]
    assert_same_bits(folder / "b1.nc", folder / "b2.nc")
    with xr.open_dataset(folder / "b2.nc", decode_times=False) as ds:
        assert ds.attrs["branched_from_day"] == 0.25 and ds.time.values[0] == 0.25 and ds.time.values[-1] == 0.5


@pytest.mark.parametrize("layout", ENSEMBLES)
def test_an_ensemble_s_members_over_ranks_keep_their_bits(over_ranks, layout):
    """``run --members 3`` over 2 ranks (members 0, 1 on rank 0, member 2 on rank 1): the run and
    restart files of one process, bit for bit; its restart file continued on 3 ranks (one member
    a rank) as on one. In the same launches, and in turn (each member its own model: a
    semi-implicit stepper, g per member; the stepper states gathered under each member's name);
    with tracers, each member's masses hq split with it (shared, and in turn)."""
    tmp_path, said = over_ranks
    assert main([*ENSEMBLE, *ENSEMBLES[layout], "--output", str(tmp_path / "one.nc")]) == 0
    assert "over 2 MPI ranks (2 on rank 0)" in said[2][0]
    with (
        xr.open_dataset(tmp_path / "one.nc", decode_times=False) as a,
        xr.open_dataset(tmp_path / "two.nc", decode_times=False) as b,
    ):
        assert set(a.data_vars) == set(b.data_vars) and a.sizes["member"] == 3 and a.sizes["time"] == 2
        for name in a.data_vars:
            if name != "wall_time":
                assert np.array_equal(a[name].values, b[name].values, equal_nan=a[name].dtype.kind == "f"), name
    with xr.open_dataset(tmp_path / "one.q.nc", decode_times=False) as a, xr.open_dataset(tmp_path / "two.q.nc") as b:
        assert a.sizes["time"] == 5 and np.array_equal(a.h.values, b.h.values)
    with xr.open_dataset(tmp_path / "one.restart.nc") as a, xr.open_dataset(tmp_path / "two.restart.nc") as b:
        masses = [k for k in ("one_mass", "marker_mass") if k in a]  # the tracers' hq, where the members carry them
        assert len(masses) == (2 if MEMBER_TRACERS[1] in ENSEMBLES[layout] else 0)
        assert all(np.array_equal(a[k].values, b[k].values) for k in ("u", "v", "h", *masses))
    more = ["run", "--continue", str(tmp_path / "two.restart.nc"), "--days", "0.75"]
    assert main([*more, "--output", str(tmp_path / "c1.nc")]) == 0
    with (
        xr.open_dataset(tmp_path / "c1.nc", decode_times=False) as a,
        xr.open_dataset(tmp_path / "c3.nc", decode_times=False) as b,
    ):
        # the restart day is the first file's last time: not written again
        assert list(a.time.values) == [0.75] and np.array_equal(a.h.values, b.h.values)
        assert all(np.array_equal(a[k].values, b[k].values) for k in ("one", "marker") if k in a)
