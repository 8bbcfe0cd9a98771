"""The tests' fixtures and hooks (pytest's); helpers shared by name are in helpers.py."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path


def _bytecode_cache() -> Path:
    """Where the suite's processes keep the modules they import compiled: the developer's
    ``PYTHONPYCACHEPREFIX``, else a folder of the user's cache (``$XDG_CACHE_HOME``, else
    ``~/.cache``), never the checkout. It outlives the session: Python checks each file against
    its source's time and size, as it does a ``__pycache__`` beside the source."""
    if sys.pycache_prefix:
        return Path(sys.pycache_prefix)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "swe_sphere-tests" / "pycache"


# Under PYTHONDONTWRITEBYTECODE (set in this project's machine image) each process compiled every
# module it imported from its source, and pytest rewrote every test module's asserts again, in
# each worker on every run: collecting tests/ took 8.6 s, 3.5 s from this cache (-n 0, 2026-11-27).
# Set here, before the imports below, for this process (its test modules, swe_sphere); for the
# subprocesses by ``compiled_once``.
BYTECODE = _bytecode_cache()
sys.pycache_prefix, sys.dont_write_bytecode = str(BYTECODE), False

import numpy as np  # noqa: E402
import pytest  # noqa: E402
import warp as wp  # noqa: E402

import roundoff  # noqa: E402

wp.config.quiet = True  # Warp < 1.10; newer Warp reads log_level instead
if hasattr(wp, "LOG_WARNING"):
    wp.config.log_level = wp.LOG_WARNING
# Warp's default device is CUDA where there is one, while the tests build their models on the
# CPU unless they name CUDA and their helpers allocate on the default device: on a GPU machine
# a helper's CUDA array in a CPU model's launch crashed the process (tests/adjoint, H100, 2026-11-26)
wp.set_device("cpu")

from swe_sphere.core.backend import DEVICE_ENV, THREADS_ENV  # noqa: E402
from swe_sphere.core.workers import cpus  # noqa: E402

from helpers import TINY, cached_grid  # noqa: E402  (after Warp is quietened: it imports swe_sphere)

# and a run that names no device (the CLI's and the docs' commands, in this process and the
# subprocesses) on the CPU too, unless the developer asks for another: on a GPU machine the
# suite's CPU results stay the CPU's (the CUDA tests name CUDA)
os.environ.setdefault(DEVICE_ENV, "cpu")


def pytest_configure(config):
    """Under pytest-xdist, each worker's CPU threads (``SWE_SPHERE_THREADS``, unless set) are
    its share of the CPUs, not all of them each (more threads than CPUs made ne16 3.9x
    slower: ``Backend.threads``). Subprocesses the tests start inherit it."""
    workers = os.environ.get("PYTEST_XDIST_WORKER_COUNT")
    if workers and THREADS_ENV not in os.environ:
        os.environ[THREADS_ENV] = str(max(1, cpus() // int(workers)))


# The default run's longest work units (an xdist group, or a module), longest first: CPU s on
# 2026-11-25 (mpi 131, the README's examples 61, methods.md's 47, test_multirate 44, ...); on
# 2026-11-28 with a warm Warp kernel cache (-n 0): mpi 128, the README's 40, methods.md's 31,
# test_multirate 30, reference.md's 26, test_sweep 24. xdist hands out units in the order of
# their test counts, which put the pages' one test each last: one worker then ran the README's
# examples alone for the last minute and a half. On a cold cache (a fresh CI machine) three
# modules that take seconds warm are the longest of all, compiling: io/test_dual 263 s (uxarray's
# numba), core/test_cuda_compile 219 s (the PTX of 131 modules), grid/test_mesh_cuda_compile 132 s
# (wall, -n 0 on one core shared with another process, 2026-11-28); they go first too, so that no
# worker starts one of them last (warm CPU s: 10, 1 and 0.3). Summed s of the default run (-n 2, idle,
# 2026-11-28, after the suite's cuts): mpi 63, the README's 44, test_multirate 32, methods.md's 30,
# reference.md's 20, test_plotting 20, test_multirate_gradient 17, experiments.md's 14; after the
# plots' cuts (2026-11-29, idle): mpi 55, test_multirate 33, the README's 31, methods.md's 20.
HEAVY_FIRST = (
    "tests/io/test_dual.py",
    "tests/core/test_cuda_compile.py",
    "mpi",
    "tests/grid/test_mesh_cuda_compile.py",
    "tests/steppers/test_multirate.py",
    "docs-readme",
    "docs-methods",
    "docs-reference",
    "tests/studies/test_plotting.py",
    "tests/adjoint/test_multirate_gradient.py",
    "docs-experiments",
)


def pytest_xdist_make_scheduler(config, log):
    """Under ``--dist loadgroup``, one worker runs a test module's tests, or a group's where
    they name one (``xdist_group``, e.g. the MPI tests): a module's tests share the runs it
    caches (``functools.cache``, module fixtures), which two workers would each compute."""
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class ModuleOrGroup(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            scope = super()._split_scope(nodeid)
            return nodeid.split("::")[0] if scope == nodeid else scope

        def _assign_work_unit(self, node) -> None:
            for scope in reversed(HEAVY_FIRST):  # the longest work units first, so no worker ends alone
                if scope in self.workqueue:
                    self.workqueue.move_to_end(scope, last=False)
            super()._assign_work_unit(node)

    return ModuleOrGroup(config, log)


@pytest.fixture(autouse=True, scope="session")
def sigint_raises():
    """Some tests send SIGINT to their own process. A runner started in the background
    (bash ``cmd &``) inherits SIGINT ignored, and the run would then never see it (an
    endless step waits forever): Python's own handler for the session."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


@pytest.fixture(autouse=True, scope="session")
def private_cache(tmp_path_factory):
    """The grid cache (``core.cache``) of the session in a folder of its own, not the user's
    (subprocesses inherit it)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path_factory.mktemp("cache")))
        yield


@pytest.fixture(autouse=True, scope="session")
def compiled_once():
    """The subprocesses the tests start (the command line, the pages' examples, MPI ranks) read
    the modules they import compiled in the suite's cache (``BYTECODE``: ``PYTHONPYCACHEPREFIX``),
    not the checkout: under ``PYTHONDONTWRITEBYTECODE`` each compiled every module again, 0.37 s
    of a tiny run's 1.28 s; a cache of the session's own compiled them all (numpy, xarray, Warp
    too: a prefix hides their ``__pycache__``) once a session."""
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("PYTHONDONTWRITEBYTECODE", raising=False)
        mp.setenv("PYTHONPYCACHEPREFIX", str(BYTECODE))  # Python makes it, writing each file atomically
        yield


@pytest.fixture(scope="session")
def grid_factory():
    """``grid_factory(ne, np)`` → a cached, read-only CubedSphere."""
    return cached_grid


@pytest.fixture(scope="session")
def small_grid():
    """ne = 2, np = 4: 24 elements, 384 element-local nodes."""
    return cached_grid(2, 4)


@pytest.fixture(scope="session")
def tc5_run_file(tmp_path_factory):
    """``swe-sphere run tc5_mountain`` at ne = 2 np = 4 for 1 day (its default stepper,
    hyperviscosity, topography; outputs at days 0 and 1), once a session (read-only)."""
    from swe_sphere.cli import main

    out = tmp_path_factory.mktemp("tc5") / "tc5.nc"
    assert main(["run", "tc5_mountain", *TINY, "--days", "1", "--output", str(out)]) == 0
    return out


PAUSED_RUN = Path(__file__).with_name("paused_run.py")


@pytest.fixture
def paused(tmp_path_factory):
    """``paused(where, cwd, *args, launcher=(), env=None)``: ``swe-sphere args``
    started under ``launcher`` (e.g. mpiexec -n 2) in ``cwd``, returned once it is
    held at ``where`` (see paused_run.py); stdout and stderr piped; ``proc.go()``
    lets it go on without a signal. Killed at the end of the test if still running."""
    procs = []

    def start(where, cwd, *args, launcher=(), env=None):
        marker = tmp_path_factory.mktemp("paused") / "marker"
        proc = subprocess.Popen(
            [*map(str, launcher), sys.executable, str(PAUSED_RUN), where, str(marker), *map(str, args)],
            cwd=cwd,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "SWE_SPHERE_THREADS": "1", **(env or {})},
            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # even if our runner ignores SIGINT
        )
        procs.append(proc)
        proc.go = lambda: marker.with_suffix(".go").touch()
        deadline = time.monotonic() + 300
        while not marker.exists():  # polled for an event, not a guessed duration
            if proc.poll() is not None or time.monotonic() > deadline:
                proc.kill()
                raise AssertionError(f"never held at {where}: {proc.communicate()}")
            time.sleep(0.05)
        return proc

    yield start
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()


def pytest_terminal_summary(terminalreporter, config):
    """Under ``-m roundoff``: each round-off comparison's measured value and bound (tests/roundoff.py)."""
    if "roundoff" not in (config.option.markexpr or "") or not roundoff.RECORDS:
        return
    target = "generic" if os.environ.get("SWE_SPHERE_CPU_GENERIC", "") not in ("", "0") else "default"
    terminalreporter.section(
        f"round-off: measured / bound (Warp CPU target: {target}, {wp.config.cpu_compiler_flags!r})"
    )
    for test, what, measured, limit in roundoff.RECORDS:
        terminalreporter.write_line(f"{measured:9.2e} / {limit:9.2e} = {measured / limit:5.3f}  {test} {what}")


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


@pytest.fixture
def one_thread(monkeypatch):
    """CPU launches on one thread (a CPU graph replays in one; split launches run plain)."""
    monkeypatch.setenv(THREADS_ENV, "1")


@pytest.fixture
def graph_launches(monkeypatch):
    """[n]: the number of ``wp.capture_launch`` calls since the test began."""
    count, real = [0], wp.capture_launch

    def launch(*a, **k):
        count[0] += 1
        return real(*a, **k)

    monkeypatch.setattr(wp, "capture_launch", launch)
    return count


@pytest.fixture
def tally():
    """``swe_sphere.core.tally``'s count of launches and host reads, wrapped around Warp for this test only."""
    from swe_sphere.core.tally import Tally, instrumented

    t = Tally()
    with instrumented(t):
        yield t


@pytest.fixture(scope="module")
def old_file(tmp_path_factory):
    """A run file as written before vorticity existed: no vorticity values (NaN)."""
    from swe_sphere.io.run_file import RunWriter

    grid = cached_grid(2, 3)
    out = tmp_path_factory.mktemp("old") / "old.nc"
    attrs = {"scene": {"name": "synthetic", "ne": 2, "np": 3}}
    w = RunWriter(out, grid, np.zeros(grid.nnodes), attrs, ["mass_change"])
    h = 1000 + 100 * np.sin(grid.lat)
    w.append(0.0, np.cos(grid.lat), 0 * grid.lat, h, {"mass_change": 0.0})
    w.close()
    return out
