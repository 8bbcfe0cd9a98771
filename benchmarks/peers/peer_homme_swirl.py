"""The transport test beside HOMME's own run of it: ``sweqx``'s swirl test (issue 125).

HOMME's ``test/sw_conservative/swirl.sh`` runs Nair & Lauritzen (2010)'s nondivergent
deformational flow (``test_case = 'swirl'``, ``sub_case = 4``: T = 12 days, with the background
rotation) in its shallow-water model, each tracer a level of its own: cosine bells (1), Gaussian
hills (2), slotted cylinders (3), a constant density (4, ``kmass_swirl``; levels 5 and 6 the
terminator chemistry's Cl and Cl2 where ``SWEQX_PLEV`` ≥ 6, as swirl.sh builds it; ≥ 4 needed,
else the limiter stops the run). Its settings: ``integration = "runge_kutta"`` with
``rk_stage_user = 3`` (``rk_mod.RkInit``: SSPRK(3,2), two Euler steps of Δt/2, a third averaged
with a third of the start), ``limiter_option = 8`` (Guba et al. 2014, in every stage, bounds from
that stage's own input over the element and its neighbours), ``nu = nu_s`` on q = p/p_density
in every stage's right-hand side (none on the density), and the error norms HOMME prints every 12
hours (``swirl_errors``: p_k/p_density against the initial field at the GLL nodes, Williamson's
normalised l1, l2, l∞ with ``spheremp`` weights, the same formula as ``transport.scores``).

Each ``--runs`` entry ne/Δt/ν/limiter is run by HOMME (one MPI rank: ``/usr/bin/mpirun
--allow-run-as-root -np 1 sweqx < input.nl``, the namelist swirl.sh makes from ``swtc1.nl``)
and by swe_sphere (``benchmarks/studies/transport/deformational_flow.toml`` at the same ne, Δt,
ν_s and limiter: "optimization" for 8, "none" for 0) under each ``--steppers`` (``ssprk32``:
HOMME's SSPRK(3,2) as a ``tableau``; ``ssprk43``: the scene's), and the day-12 l2 of the bells,
hills and cylinders are printed beside each other and swirl.sh's recorded figures, with each
run's CPU seconds (HOMME: the whole process, ``os.wait4``; swe_sphere: the run in this process,
one thread; ``--no-homme``: swe_sphere's alone, as for the ν sweep of transport.md), with the
tracers' ν_s ∇⁴ split after each step (``--hyperviscosity step``, the scene's) and/or inside every
stage as HOMME applies it (``stages``: ``tracers.stage_hyperviscosity``)::

    python benchmarks/peers/peer_homme_swirl.py --homme BUILD/src/sweqx/sweqx \\
        --runs 10/720/4.6e15/8 20/240/2.8e14/8 --keep DIR

``--homme``: a ``sweqx`` built by the HOMME kit (``shared/peers/homme/build.sh``) with its CMake
cache's ``SWEQX_PLEV`` set to 6. Its ``set_prescribed_velocity`` computes the same wind once per
level and ``swirl_velocity`` once more per level inside (nlev² evaluations per node per call):
computed once and copied to every level, the ne10 run printed the same norms to every digit at
every 12 hours and took 63 s of CPU instead of 254 (2026-11-30). ``--keep DIR``: HOMME's run
folders and swe_sphere's run files; a HOMME folder whose output holds day 12's norms, or a run file
already there, is read again, not rerun.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # benchmarks/: results.py, the shared module
from results import quiet_warp, recorded  # noqa: E402  (after the path: benchmarks/ first)

# isort: split
from peer_homme import MPIRUN, run_homme  # noqa: E402  (benchmarks/peers/)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies" / "transport"))
from transport import HOMME_L2, SCENE, scores  # noqa: E402  (benchmarks/studies/transport/)

from swe_sphere import Simulation, load_scene  # noqa: E402

TRACERS = ("bells", "hills", "cylinders")  # HOMME's levels 1, 2, 3
LIMITERS = {8: "optimization", 0: "none"}  # HOMME's limiter_option: the scene's tracers.limiter
# HOMME's rk_stage_user = 3 (rk_mod.RkInit: beta = 1/2, 1/2, 1/3; alpha = 1, 1, 2/3; alpha0 = 0, 0, 1/3)
SSPRK32 = dict(
    name="ssprk32",
    description="SSPRK(3,2), HOMME's rk_stage_user = 3: two Euler steps of dt/2, a third averaged with the start",
    order=2,
    A=[[0, 0, 0], ["1/2", 0, 0], ["1/2", "1/2", 0]],
    b=["1/3", "1/3", "1/3"],
    c=[0, "1/2", 1],
)
STEPPERS = ("ssprk32", "ssprk43")
RECORDED_AT = {10: (720.0, 4.6e15), 20: (240.0, 2.8e14)}  # swirl.sh's settings of its recorded l2 (HOMME_L2)

# swirl.sh's namelist: swtc1.nl with swirl.sh's substitutions (output every 30 h, errors every 12 h)
NAMELIST = """&ctl_nl
NThreads = 1
partmethod = 4
topology = "cube"
test_case = 'swirl'   sub_case = 4
ne = {ne}
ndays = 12
statefreq = {statefreq}
restartfreq = -1
runtype = 0
tstep = {dt}
integration = "runge_kutta"
rk_stage_user = 3
LFTfreq = 0
smooth = 0
limiter_option = {limiter}
nu= {nu}
nu_s= {nu}
hypervis_order = 2
hypervis_subcycle = 1
/
&solver_nl
precon_method = "block_jacobi"
maxits = 100
tol = 1.e-12
/
&filter_nl
filter_freq = 0
/
&analysis_nl
output_start_time = 0
output_end_time = 1200000
output_frequency = 30
output_timeunits = 2  interp_type=1
output_varnames1 = 'geop'
output_type = 'netcdf'
io_stride = 4
/
"""


def parse_run(text: str) -> tuple[int, float, float, int]:
    """(ne, Δt s, ν m⁴ s⁻¹, limiter) of a ``--runs`` entry ne/Δt/ν/limiter; bad entries raise ValueError."""
    parts = text.split("/")
    if len(parts) != 4:
        raise ValueError(f"--runs {text}: not ne/dt/nu/limiter")
    ne, dt, nu, limiter = int(parts[0]), float(parts[1]), float(parts[2]), int(parts[3])
    if ne < 1 or dt <= 0 or nu < 0 or limiter not in LIMITERS or (12 * 86400) % dt or (12 * 3600) % dt:
        raise ValueError(f"--runs {text}: ne >= 1, dt > 0 dividing 12 h, nu >= 0, limiter one of {sorted(LIMITERS)}")
    return ne, dt, nu, limiter


def homme_norms(text: str) -> dict:
    """{tracer: {l1, l2, linf}} of HOMME's day-12 lines (``swirl_errors``: "k= K 12.00 days l1,l2,linf= ...")."""
    found = {
        int(k): tuple(map(float, v.split())) for k, v in re.findall(r"k=\s*(\d+)\s+12\.00 days\s+l1,l2,linf=(.*)", text)
    }
    return {name: dict(zip(("l1", "l2", "linf"), found[k + 1], strict=True)) for k, name in enumerate(TRACERS)}


def homme(sweqx: Path, run: tuple, folder: Path) -> tuple[dict, float | None]:
    """HOMME's day-12 norms of ``run`` and its CPU seconds (None: read from an earlier run's folder)."""
    ne, dt, nu, limiter = run
    rundir = folder / f"homme_ne{ne}_dt{dt:g}_nu{nu:g}_lim{limiter}"
    out = rundir / "sweq.out"
    if out.is_file() and "12.00 days" in out.read_text():
        return homme_norms(out.read_text()), None
    text = NAMELIST.format(ne=ne, dt=f"{dt:g}", nu=f"{nu:g}", limiter=limiter, statefreq=int(12 * 3600 / dt))
    cpu, _, printed = run_homme(sweqx, text, rundir)
    out.write_text(printed)
    return homme_norms(printed), cpu


def ours(run: tuple, stepper: str, where: str, folder: Path) -> tuple[dict, float | None]:
    """swe_sphere's day-12 scores of ``run`` under ``stepper``, its ∇⁴ ``where`` ("step": split
    after each step; "stages": in every stage), and the run's CPU seconds (None: an earlier run
    file read again)."""
    ne, dt, nu, limiter = run
    over = {"output.every_days": 6.0, "tracers.limiter": LIMITERS[limiter]}
    if where == "stages":
        over["tracers.stage_hyperviscosity"] = True
    if nu:  # the scene's ν_s is ne10's, scaled as Δx^3.2: given so that ne's is nu
        over["hyperviscosity.nu_s"] = nu * (ne / 10) ** 3.2
    else:
        over["terms"] = ["continuity", "forcing"]
    if stepper == "ssprk32":
        over["tableau"] = SSPRK32
    scene = load_scene(SCENE, ne=ne, dt=dt, stepper="tableau" if stepper == "ssprk32" else stepper, overrides=over)
    suffix = "_stages" if where == "stages" else ""
    path = folder / f"swe_ne{ne}_dt{dt:g}_nu{nu:g}_lim{limiter}_{stepper}{suffix}.nc"
    cpu = None
    if not path.exists():  # a run file is renamed into place only when complete
        start = time.process_time()
        Simulation(scene, "cpu", progress=False).run(path)
        cpu = time.process_time() - start
    return scores(path, TRACERS), cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--homme", type=Path, help="a sweqx built with SWEQX_PLEV >= 4 (needed unless --no-homme)")
    ap.add_argument("--no-homme", action="store_true", help="swe_sphere's runs alone (a ν sweep)")
    ap.add_argument("--runs", nargs="+", default=["10/720/4.6e15/8", "20/240/2.8e14/8"], help="ne/dt/nu/limiter")
    ap.add_argument("--steppers", nargs="+", choices=STEPPERS, default=list(STEPPERS), help="swe_sphere's")
    ap.add_argument(
        "--hyperviscosity",
        nargs="+",
        choices=("step", "stages"),
        default=["step"],
        help="swe_sphere's tracer ∇⁴: split after each step (the scene's) or in every stage (HOMME's)",
    )
    ap.add_argument("--keep", type=Path, help="a folder for HOMME's run folders and swe_sphere's run files")
    ap.add_argument("--results", metavar="STEM", help="results/peer_homme_swirl/STEM.json")
    args = ap.parse_args()
    try:
        runs = [parse_run(r) for r in args.runs]
    except ValueError as e:
        ap.error(str(e))
    if not args.no_homme and (args.homme is None or not os.access(args.homme, os.X_OK) or not Path(MPIRUN).is_file()):
        ap.error(f"--homme {args.homme}: not an executable sweqx, or no {MPIRUN}")
    quiet_warp()
    os.environ.setdefault("SWE_SPHERE_THREADS", "1")
    with recorded(__file__, args.results) as figures, tempfile.TemporaryDirectory() as tmp:
        folder = args.keep or Path(tmp)
        folder.mkdir(parents=True, exist_ok=True)
        print("run                            model                     bells    hills    cylinders   CPU s")
        for run in runs:
            ne, dt, nu, limiter = run
            label = f"ne{ne} dt {dt:g} nu {nu:.3g} lim {limiter}"
            rows = {} if args.no_homme else {"HOMME": homme(args.homme, run, folder)}
            rows |= {
                f"swe_sphere {s}" + (" stages" if w == "stages" else ""): ours(run, s, w, folder)
                for w in args.hyperviscosity
                for s in args.steppers
            }
            recorded_l2 = HOMME_L2[ne] if (RECORDED_AT.get(ne), limiter) == ((dt, nu), 8) else None
            figures[label] = {
                model: {"l2": {n: got[n]["l2"] for n in TRACERS}, "cpu_s": cpu} for model, (got, cpu) in rows.items()
            }
            for model, (got, cpu) in rows.items():
                l2 = "  ".join(f"{got[n]['l2']:.4f}" for n in TRACERS)
                print(f"{label:30s} {model:25s} {l2}   {'(read)' if cpu is None else f'{cpu:.0f}'}")
            if recorded_l2:
                print(f"{label:30s} {'swirl.sh recorded':25s} " + "  ".join(f"{recorded_l2[n]:.4f}" for n in TRACERS))


if __name__ == "__main__":
    main()
