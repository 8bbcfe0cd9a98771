"""The machine a run meets: Warp initialised quietly, memory
estimated before anything large is allocated.

Memory figures are from ``benchmarks/micro/memory.py`` (since removed: ``git show
6b0c949:benchmarks/micro/memory.py``; a run's peak memory and the arrays it holds are now
``benchmarks/micro/precision_speed.py``'s ``--peak-ne`` and ``--arrays``) on tc5_mountain ne = 60
np = 4, leapfrog_trapezoidal: a run's resident memory above the import baseline is
about 1 020 bytes per element-local node (state, metric, model and stepper work
arrays, the host grid and its construction temporaries, output buffers). The
semi-implicit, implicit and exponential steppers add their own buffers (below).
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import time

from .errors import ResourceError

RUN_BYTES_PER_NODE = 1100  # measured 1 020 (the benchmarks notebook (git show 5fa9286:benchmarks/README.md), "Memory"), + 32 for the ∇⁴ work array, rounded up
STEPPER_BYTES_PER_NODE = {
    "semi_implicit": 400,  # ~10 more (k, N) rows and the Helmholtz CG's unique-node vectors
    "implicit": 1200,  # 13 (3, N) buffers, 6 unique-node vectors and a GMRES basis of 30
    # a KIOPS basis of 65 unique-node vectors (m_max = 64; 1.7 N entries each at np = 4) and 6 (3, N) buffers
    "epi2": 1200,
    "epi3": 1200,
}


@functools.cache
def package_version() -> str:
    """The installed swe_sphere's version ("0.0.0+unknown" in a source tree without
    installation), looked up on first use: importlib.metadata took half of a
    command's start before its signal handling."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("swe-sphere")
    except PackageNotFoundError:
        return "0.0.0+unknown"


def init_warp(verbose: bool = False):
    """Import and initialise Warp. Unless ``verbose``, without its banner, its
    per-module load lines and the CUDA-driver warning its native code prints to
    stderr on machines without a GPU (below Python's reach: fd 2 is closed
    around ``wp.init``). Returns the ``warp`` module."""
    import warp as wp

    if verbose:  # Warp's own load lines say "(compiled)"
        wp.init()
        return wp
    wp.config.quiet = True  # Warp < 1.10
    if hasattr(wp, "LOG_ERROR"):
        wp.config.log_level = wp.LOG_ERROR
    sys.stderr.flush()
    saved, null = os.dup(2), os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(null, 2)
        wp.init()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(null)
    if sys.stderr.isatty():
        _note_first_compilation(wp)
    return wp


def _note_first_compilation(wp) -> None:
    """Say once per process, on stderr, that Warp is compiling kernels: on a cold
    kernel cache that costs most of a small run (6.6 s of an 8.2 s ne4 run), which
    would otherwise pass without a word. Only on a terminal: a log gets the compile
    time in the run's summary, and a piped stderr keeps failures to one line.
    Hooks Warp's private code generation, which runs only on a cache miss; without
    it, no note."""
    try:
        from warp._src.context import Module
    except ImportError:
        return
    real = getattr(Module, "_run_codegen", None)
    # Warp changed, or hooked already in this process: init_warp runs more than once a run, and a
    # hook that has spoken and put Warp's method back must not be put in again
    global _compilation_hooked
    if real is None or _compilation_hooked:
        return
    _compilation_hooked = True

    def run_codegen(self, *args, **kwargs):
        Module._run_codegen = real  # once
        print(
            f"swe-sphere: compiling Warp kernels (first use; cached in {wp.config.kernel_cache_dir}) ...",
            file=sys.stderr,
            flush=True,
        )
        return real(self, *args, **kwargs)

    Module._run_codegen = run_codegen


_compilation_hooked = False  # whether this process has hooked Warp's code generation (at most once)


@contextlib.contextmanager
def compile_timer(acc: list):
    """Add the seconds spent loading (compiling on a cold cache) Warp modules to acc[0], by hooking
    Warp's private module load as ``_note_first_compilation`` hooks its code generation (a
    ``Simulation``'s ``compile_time``)."""
    try:
        from warp._src.context import Module  # private: without it, compilation counts as stepping
    except ImportError:
        yield
        return
    real, depth = Module.load, [0]

    def load(self, *args, **kwargs):
        depth[0] += 1
        t0 = time.perf_counter()
        try:
            return real(self, *args, **kwargs)
        finally:
            depth[0] -= 1
            if depth[0] == 0:
                acc[0] += time.perf_counter() - t0

    Module.load = load
    try:
        yield
    finally:
        Module.load = real


def available_memory() -> int:
    """Bytes the process may still allocate: MemAvailable (Linux), else physical memory."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_AVPHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return 1 << 62  # unknown: do not refuse


def run_bytes(ne: int, np_: int, stepper: str, *, nelem: int | None = None) -> int:
    """Estimated bytes of a run on the grid ne × np with ``stepper``; ``nelem``: the elements
    of a mesh (ne = 0 for a mesh file), else the cube's 6·ne²."""
    nodes = (6 * ne * ne if nelem is None else nelem) * np_ * np_
    return nodes * (RUN_BYTES_PER_NODE + STEPPER_BYTES_PER_NODE.get(stepper, 0))


def check_memory(need: int, what: str) -> None:
    """Raise ``ResourceError`` (one line) when ``need`` bytes exceed the host's
    available memory (``available_memory``); a run's arrays on a GPU are checked
    against its memory instead (``backend.Backend.check_memory``)."""
    have = available_memory()
    if need > have:
        raise ResourceError(f"{what} needs about {gib(need)} of memory; {gib(have)} is available")


def gib(n: int) -> str:
    """n bytes in GiB, three figures."""
    return f"{n / 2**30:.3g} GiB"
