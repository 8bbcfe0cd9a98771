"""Helpers shared by the tests (imported by name; pytest's fixtures and hooks are in conftest.py):
tiny-grid CLI arguments and the calls that run the command line in this process
(``cli_main``, ``cli_ok``, ``cli_one_line``, ``one_line``, ``console_script``), the CUDA marks,
the session's cached grids and runs (``cached_grid``, ``tc6_final``, ``tc6_error``),
``make_sim``, ``run``, ``watched_run`` and ``assert_same_runs``, the transport test's overrides
(``DEFORMATIONAL_FLOW``), a TC2 scene file
(``write_tc2_scene``), a file's ``digest`` and a sweep without its figures (``without_sweep_figures``)."""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import math
import shutil
import struct
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import warp as wp
import xarray as xr

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import BlowUp
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.simulation.simulation import Simulation

TINY = ("--ne", "2", "--np", "4", "--device", "cpu", "--no-progress")
# a sweep of two ssprk3 runs of TC2 at ne 2 over one day (append --output DIR and options)
TINY_SWEEP = (
    "sweep",
    "tc2_steady",
    "--ne",
    "2",
    "--days",
    "1",
    "--steppers",
    "ssprk3",
    "--dt",
    "1800,3600",
    "--device",
    "cpu",
)
EIGHTH_DAY = ("--dt", "1800", "--days", "0.125", "-s", "output.every_days=0.125")  # 6 steps, outputs at 0 and 0.125


NEEDS_CUDA = (pytest.mark.gpu, pytest.mark.skipif(not wp.is_cuda_available(), reason="needs a CUDA device"))
ON_CUDA = pytest.param("cuda", marks=NEEDS_CUDA)  # a device parameter skipped cleanly without CUDA


def rows_apart(a, b) -> list[float]:
    """Per row r of two states (rows, ...): max |a[r] − b[r]| over max |b[r]|, the relative
    distance the CUDA-against-CPU tests bound (sums in another order, NVRTC's FMA contraction)."""
    return [float(np.abs(a[r] - b[r]).max() / np.abs(b[r]).max()) for r in range(b.shape[0])]


def requires_cuda(func):
    """Mark a test as a GPU test that is skipped cleanly without CUDA."""
    for mark in reversed(NEEDS_CUDA):
        func = mark(func)
    return func


@functools.cache
def cached_grid(ne: int, np_: int) -> CubedSphere:
    """One CubedSphere per (ne, np) for the whole session (treat as read-only)."""
    return CubedSphere(ne, np_)


def make_sim(scene):
    """A CPU Simulation of ``scene`` without a progress bar."""
    return Simulation(scene, "cpu", progress=False)


# Nair & Lauritzen's deformational flow on tc2_steady's grid: the wind prescribed, the continuity
# alone carrying the tracers, HOMME's ν_s on them (benchmarks/studies/transport's scene)
DEFORMATIONAL_FLOW = {
    "case.name": "deformational_flow",
    "terms": ["continuity", "forcing", "hyperviscosity"],
    "hyperviscosity.nu": 0.0,
    "hyperviscosity.nu_div": 0.0,
    "hyperviscosity.nu_s": 4.6e15,
}

RUN_TIMES = ("wall_time", "cpu_time")  # a run file's measured series: differ between any two runs


def members_run(scene, members=None, initial=None, **kw) -> Simulation:
    """A run of ``members`` (None: the scene's [ensemble] ``members``) from ``initial``, without a
    progress bar: ``Simulation(scene, members=members, initial=initial, ...)``, what the deprecated
    ``Ensemble(scene, members, initial)`` makes."""
    return Simulation(scene, members=members, initial=initial, **{"progress": False, **kw})


def members_from_checkpoint(path, **kw) -> Simulation:
    """A members' restart file continued (``Simulation.from_checkpoint(path, members=True)``), no bar."""
    return Simulation.from_checkpoint(path, members=True, **{"progress": False, **kw})


def take_steps(sim: Simulation, n: int):
    """``n`` more steps of ``sim`` at its fixed Δt (``advance`` by their days, the scene lengthened
    past its end); ``advance``'s ``RunResult``."""
    return sim.advance(n * sim.scene.dt / DAY)


def watched_run(scene, path, *, device="cpu", check_every=1, graphs=False, setup=None, **kwargs):
    """Run ``scene`` on ``device`` to ``path`` (``Simulation.run``'s ``kwargs``) with
    a callback every 10 steps and a log, checked every ``check_every`` steps, steps
    as graphs or not, ``setup(sim)`` called before: (result, BlowUp message or None,
    run file without its timings, final state, what the callbacks and log saw).
    ``assert_same_runs`` compares two."""
    sim = Simulation(scene, device, progress=False)
    sim.check_every, sim.graphs = check_every, graphs
    if setup is not None:
        setup(sim)
    seen = []
    sim.add_callback(lambda s: seen.append((s.step, s.x.numpy().copy())), every_steps=10)
    try:
        result, message = sim.run(path, log=seen.append, **kwargs), None
    except BlowUp as err:
        result, message = err.result, str(err)
    with xr.open_dataset(path) as ds:
        ds = ds.drop_vars([v for v in RUN_TIMES if v in ds]).load()
    del ds.attrs["history"]  # its time stamp
    return result, message, ds, sim.x.numpy(), seen


def assert_same_runs(a, b):
    """Two ``watched_run``s agree to the bit (timings aside)."""
    (ra, ma, da, xa, sa), (rb, mb, db, xb, sb) = a, b
    assert ma == mb
    assert (ra.steps, ra.rhs_evals, ra.iterations) == (rb.steps, rb.rhs_evals, rb.iterations)
    xr.testing.assert_identical(da, db)
    np.testing.assert_array_equal(xa, xb)
    assert len(sa) == len(sb)
    for u, v in zip(sa, sb):
        if isinstance(u, str):
            assert u == v
        else:
            assert u[0] == v[0]
            np.testing.assert_array_equal(u[1], v[1])


def run(scene):
    """(RunResult, Simulation, wall seconds); a blow-up returns its partial result."""
    sim = make_sim(scene)
    t0 = time.perf_counter()
    try:
        result = sim.run()
    except BlowUp as err:
        result = err.result
    return result, sim, time.perf_counter() - t0


@functools.cache
def tc6_inviscid(days: float, case: str = "tc6_rossby_haurwitz"):
    """TC6 (or ``case``) at ne = 4 np = 4 for ``days``, without hyperviscosity, one output
    at the end (the temporal-order tests' case)."""
    scene = load_scene(case, ne=4, np_=4, days=days)
    terms = tuple(t for t in scene.terms if t != "hyperviscosity")
    return dataclasses.replace(scene, terms=terms, nu=0.0, output_every_days=days)


@functools.cache
def tc6_final(days: float, stepper: str, nsteps: int, options: tuple = (), case: str = "tc6_rossby_haurwitz"):
    """``tc6_inviscid(days, case)`` in ``nsteps`` steps of ``stepper`` with ``options``
    ((key, value) pairs), once a session: (final state (3, N) u, v, h, RunResult, wall s)."""
    scene = dataclasses.replace(
        tc6_inviscid(days, case), stepper=stepper, dt=days * DAY / nsteps, stepper_options=dict(options)
    )
    assert scene.nsteps == nsteps and abs(scene.nsteps * scene.dt - days * DAY) < 1e-6
    result, sim, wall = run(scene)
    assert result.blowup is None, result.blowup
    return sim.x.numpy().copy(), result, wall


def tc6_error(
    days: float, ref_steps: int, stepper: str, nsteps: int, options: tuple = (), case: str = "tc6_rossby_haurwitz"
):
    """Normalised l2 distance of the whole state (u, v, h) after ``days`` to rk4 in
    ``ref_steps`` steps (of TC6 or ``case``), with the run's RunResult and wall seconds."""
    ref = tc6_final(days, "rk4", ref_steps, (), case)[0]
    x, result, wall = tc6_final(days, stepper, nsteps, options, case)
    w = cached_grid(4, 4).spheremp
    return math.sqrt(w @ ((x - ref) ** 2).sum(0) / (w @ (ref**2).sum(0))), result, wall


def cli_main(capsys, *args):
    """``swe_sphere.cli.main(args)`` in this process → (exit status, stdout, stderr);
    argparse's own exits (SystemExit) give their status."""
    from swe_sphere.cli import main

    try:
        code = main([str(a) for a in args])
    except SystemExit as exc:
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def cli_ok(*args) -> bool:
    """``swe_sphere.cli.main(args)`` in this process returned 0 (its output left to the terminal)."""
    from swe_sphere.cli import main

    return main([str(a) for a in args]) == 0


def one_line(code: int, err: str, expected: int, *words: str) -> str:
    """Assert a failure's form: exit status ``expected``, one non-blank line on stderr
    holding every one of ``words``, no traceback; returns the line."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == expected, (code, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    for word in words:
        assert word in lines[0], (word, lines[0])
    return lines[0]


def cli_one_line(capsys, args, expected: int, *words: str) -> str:
    """``cli_main`` then ``one_line``: the line of a command refused in this process."""
    code, _, err = cli_main(capsys, *args)
    return one_line(code, err, expected, *words)


def console_script() -> str:
    """The installed ``swe-sphere`` console script (beside the interpreter, else on PATH)."""
    beside = Path(sys.executable).with_name("swe-sphere")
    script = str(beside) if beside.is_file() else shutil.which("swe-sphere")
    assert script is not None, "the swe-sphere console script is not installed (pip install -e .[test])"
    return script


TC2_SCENE = """
description = "TC2 for a test"
terms = ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]

[case]
name = "tc2_steady"

[grid]
ne = {ne}
np = 4

[time]
stepper = "{stepper}"
dt = {dt!r}
days = {days!r}
{tables}
"""


def write_tc2_scene(path, *, stepper="ssprk3", ne=2, dt=3600.0, days=1.0, tables=""):
    """Write a TC2 scene file (``tables``: extra TOML, e.g. a stepper's options); returns its path."""
    path.write_text(TC2_SCENE.format(ne=ne, stepper=stepper, dt=dt, days=days, tables=tables))
    return path


def digest(path) -> str:
    """The file's sha256 (hex): a file left untouched has the same."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) from the PNG header."""
    data = Path(path).read_bytes()[:24]
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def without_sweep_figures(monkeypatch) -> None:
    """A sweep's five figures (``report.PLOTS``) left empty files at their names: for a test of
    a sweep's runs, rows, reuse or refusals, not its figures, which cost 1.3 s of CPU a sweep
    (warm, 2026-11-28; a frontier's sweep each grid). test_sweep.py's ``swept`` (their sizes)
    and its large-steps test (no zero-width log axis) draw them."""
    from swe_sphere.studies.sweep import report

    def placeholder(path, *args, **kwargs) -> Path:
        Path(path).write_bytes(b"")
        return Path(path)

    monkeypatch.setattr(report, "sweep_plot", placeholder)
