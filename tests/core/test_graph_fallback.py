"""A GPU user's first run cannot fail on an untested path: graphs
checked on first use, and every failure of a capture, its conditional nodes or
device totals, a replay or a check falls back to plain launches with one line.

Each failure is injected into the capture path of Warp's CPU graphs (one thread a
launch, ``--graphs on``), as it would come on a GPU: the run ends with the bits,
RHS evaluations and solver iterations of a plain run (``--graphs off``) and
exactly one warning line naming the feature. The CUDA twins run the same
injections with CUDA graphs (skipped without a CUDA device;
``benchmarks/gpu/gpu_session.sh tests`` runs them first).
"""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core import runtime
from swe_sphere.core.backend import Backend
from swe_sphere.core.constants import DAY
from swe_sphere.members import units
from swe_sphere.model.helmholtz import HelmholtzCG
from swe_sphere.simulation.simulation import Simulation

from helpers import ON_CUDA, cli_main, cli_one_line, one_line

DEVICES = ["cpu", ON_CUDA]
STEPS = 8


@pytest.fixture(autouse=True)
def plain_environment(one_thread, monkeypatch):
    """CPU launches on one thread (conftest's ``one_thread``); no graphs mode from the environment."""
    monkeypatch.delenv("SWE_SPHERE_GRAPHS", raising=False)


def tc5(stepper, dt_factor=1):
    """TC5 (every term, ∇⁴ included) on ne 2 np 4 for ``STEPS`` steps of ``dt_factor`` × its Δt."""
    scene = load_scene("tc5_mountain", ne=2, np_=4, stepper=stepper)
    dt = scene.dt * dt_factor
    return dataclasses.replace(scene, dt=dt, days=STEPS * dt / DAY, output_every_days=STEPS * dt / DAY)


def run(scene, device, graphs, check_every=3):
    """(state, RHS evaluations, stepper steps, iterations, the Simulation) of a run with ``graphs``."""
    sim = Simulation(scene, device, progress=False, graphs=graphs)
    sim.check_every = check_every
    result = sim.run(None)
    return sim.x.numpy(), result.rhs_evals, sim.stepper.steps, result.iterations, sim


def raising(real, what, when=lambda: True):
    """``real`` that raises RuntimeError("injected <what>") when ``when()``, from a frame
    named as ``real`` (as a failure inside it would be, which ``graphs.feature`` reads)."""

    def call(*a, **k):
        if when():
            raise RuntimeError(f"injected {what}")
        return real(*a, **k)

    call.__code__ = call.__code__.replace(co_name=real.__name__)
    return call


def capturing():
    """Whether a graph is being captured (on any device)."""
    return any(wp.get_device(d).is_capturing for d in ("cpu", *(["cuda"] if wp.is_cuda_available() else [])))


def capturing_a_step():
    """Whether a whole step is being captured (``GraphedSteps._checked``), not a solve alone."""
    return capturing() and any(f.function == "_checked" for f in inspect.stack())


def later():
    """True from the second call on (the first: the check's replay, which passes)."""
    calls = [0]

    def when():
        calls[0] += 1
        return calls[0] > 1

    return when


def conditional_nodes(when):
    return lambda mp: mp.setattr(wp, "capture_while", raising(wp.capture_while, "error", when))


def device_totals(when):
    return lambda mp: mp.setattr(HelmholtzCG, "totals", raising(HelmholtzCG.totals, "error", when))


# kind → (stepper, Δt factor, the injection (monkeypatch), the line's words). The CG's loops
# and totals fail in its own solve's graph (captured in the first step), or only inside a step's.
INJECTIONS = {
    "capture": (
        "ssprk3",
        1,
        lambda mp: mp.setattr(wp, "capture_begin", raising(wp.capture_begin, "capture failure")),
        "graph of the ssprk3 step failed: injected capture failure",
    ),
    "replay": (
        "leapfrog",
        1,
        lambda mp: mp.setattr(wp, "capture_launch", raising(wp.capture_launch, "replay failure")),
        "graph of the leapfrog step failed: injected replay failure",
    ),
    "a later replay": (
        "ssprk3",
        1,
        lambda mp: mp.setattr(wp, "capture_launch", raising(wp.capture_launch, "replay failure", later())),
        "graph of the ssprk3 step failed: injected replay failure",
    ),
    "conditional nodes": (
        "imex",
        4,
        conditional_nodes(capturing),
        "graph of the Helmholtz solve failed in conditional nodes (wp.capture_while): injected error",
    ),
    "conditional nodes in a step": (
        "imex",
        4,
        conditional_nodes(capturing_a_step),
        "graph of the imex step failed in conditional nodes (wp.capture_while): injected error",
    ),
    "device totals": (  # a solve is captured at its second call: imex's in its second step, before a step's
        "imex",
        4,
        device_totals(capturing),
        "graph of the Helmholtz solve failed in device totals: injected error",
    ),
    "device totals in a step": (
        "semi_implicit",
        2,
        device_totals(capturing_a_step),
        "graph of the semi_implicit step failed in device totals: injected error",
    ),
}


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("kind", INJECTIONS)
def test_a_failure_in_the_capture_path_falls_back_to_plain_launches(monkeypatch, capsys, kind, device):
    """A capture, a replay (the check's or a later one), a conditional node (the CG's
    ``wp.capture_while``) or a device total (the CG's inner products), in a solve's
    graph or a step's, that raises: one line naming it, then the
    run goes on with plain launches from a good state, to the bits, RHS evaluations,
    stepper steps and CG iterations of a plain run."""
    stepper, factor, inject, words = INJECTIONS[kind]
    scene = tc5(stepper, factor)
    plain = run(scene, device, "off")
    capsys.readouterr()
    inject(monkeypatch)
    graphed = run(scene, device, "on")
    err = capsys.readouterr().err
    kind = "CPU" if device == "cpu" else "CUDA"
    one_line(0, err, 0, f"swe-sphere: {kind} {words}; running without graphs")
    np.testing.assert_array_equal(graphed[0], plain[0])
    assert graphed[1:4] == plain[1:4] and graphed[2] == STEPS
    assert graphed[4].graphs == "on" and graphed[4].model.launches.guard.failure is not None


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("stepper", ["leapfrog", "ssprk3"])
def test_a_graph_that_differs_from_plain_launches_falls_back(monkeypatch, capsys, stepper, device):
    """A step graph whose replay differs from the plain step by one unit in the last place
    of one value (injected after the replay): found at its first replay's check, one
    line, and the run continues from the plain step's state and stepper history
    (leapfrog's x(n−1)) to the bits of a plain run; no graph replays after it."""
    scene = tc5(stepper)
    plain = run(scene, device, "off")
    sim = Simulation(scene, device, progress=False, graphs="on")
    sim.check_every = 3
    real, launches = wp.capture_launch, [0]

    def spoiled(graph, *a, **k):
        launches[0] += 1
        real(graph, *a, **k)
        x = sim.x.numpy()
        x[2, 0] = np.nextafter(x[2, 0], np.inf)
        sim.x.assign(x)

    monkeypatch.setattr(wp, "capture_launch", spoiled)
    capsys.readouterr()
    result = sim.run(None)
    one_line(
        0,
        capsys.readouterr().err,
        0,
        f"swe-sphere: {'CPU' if device == 'cpu' else 'CUDA'} graph of the {stepper} step "
        "differs from plain launches; running without graphs",
    )
    np.testing.assert_array_equal(sim.x.numpy(), plain[0])
    assert (result.rhs_evals, sim.stepper.steps, result.iterations) == plain[1:4]
    assert launches[0] == 1  # the check's replay alone


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("stepper", ["leapfrog", "imex"])
def test_checked_graphs_run_and_keep_the_bits_of_plain_launches(capsys, stepper, device):
    """No failure: every key's first replay checked equal, its graph kept and replayed
    (leapfrog, and IMEX with its CG's loops inside), the bits of plain launches, no line."""
    scene = tc5(stepper, 4 if stepper == "imex" else 1)
    plain = run(scene, device, "off")
    graphed = run(scene, device, "on")
    assert capsys.readouterr().err == ""
    np.testing.assert_array_equal(graphed[0], plain[0])
    assert graphed[1:4] == plain[1:4]
    assert graphed[4].graphs_kept >= 1 and graphed[4].model.launches.guard.failure is None


@pytest.mark.parametrize("stepper", ["semi_implicit", "imex"])
def test_every_device_loop_tests_a_one_int_flag(monkeypatch, stepper):
    """``wp.capture_while``'s condition is one int32 wherever a solver loops on the device:
    uncaptured on CUDA, Warp (1.19) copies the whole condition array into a one-int host buffer
    and raises for a longer one (on an H200, the CG's three counters did, in every plain
    semi-implicit and IMEX step), while the CPU reads only its first int. Checked here on the
    CPU, plain and graphed, the solves' refinement loop (``precision = "float32"``) included."""
    seen = []

    def one_int(condition, body, stream=None, **kwargs):
        seen.append(condition.shape)
        return real(condition, body, stream=stream, **kwargs)

    real = wp.capture_while
    monkeypatch.setattr(wp, "capture_while", one_int)
    for graphs, options in (("off", {}), ("on", {}), ("off", {"precision": "float32"})):
        scene = dataclasses.replace(tc5(stepper, 4), stepper_options=options)
        run(scene, "cpu", graphs)
    assert seen and set(seen) == {(1,)}, set(seen)


def test_the_graph_mode_from_cli_environment_and_python(tmp_path, monkeypatch, capsys):
    """``--graphs`` and ``SWE_SPHERE_GRAPHS`` take off, on, auto (the default); another
    value is refused in one line naming it, exit 2, nothing written; the flag wins
    over the environment. In Python ``graphs=`` and ``sim.graphs`` (bools as on/off)."""
    out = tmp_path / "out.nc"
    args = [
        "run",
        "tc2_steady",
        "--ne",
        2,
        "--dt",
        3600,
        "--days",
        0.125,
        "--device",
        "cpu",
        "--no-progress",
        "--output",
        out,
    ]
    cli_one_line(capsys, [*args, "--graphs", "sometimes"], 2, "--graphs must be one of off, on, auto (got 'sometimes')")
    monkeypatch.setenv("SWE_SPHERE_GRAPHS", "yes")
    cli_one_line(capsys, args, 2, "SWE_SPHERE_GRAPHS must be one of off, on, auto (got 'yes')")
    assert not out.exists()
    code, _, err = cli_main(capsys, *args, "--graphs", "on")
    assert code == 0 and err == "", err
    monkeypatch.setenv("SWE_SPHERE_GRAPHS", "off")
    scene = tc5("ssprk3")
    assert Simulation(scene, "cpu", progress=False).graphs == "off"
    sim = Simulation(scene, "cpu", progress=False, graphs=True)
    assert sim.graphs == "on" and sim.model.launches.guard.enabled
    sim.graphs = False
    assert sim.graphs == "off" and not sim.model.launches.guard.enabled  # the solvers' own graphs too
    with pytest.raises(ValueError, match="graphs must be one of off, on, auto"):
        sim.graphs = "maybe"
    with pytest.raises(ValueError, match=r"graphs must be one of off, on, auto \(got 'x'\)"):
        Simulation(scene, "cpu", progress=False, graphs="x")


class FakeCuda:
    """What ``members.units.check_memory`` reads of a CUDA device."""

    is_cuda, is_cpu = True, False

    def __init__(self, free, total):
        self.free_memory, self.total_memory = free, total

    def __str__(self):
        return "cuda:0"


def test_memory_is_checked_on_the_device_that_runs(monkeypatch):
    """A CPU run is checked against the host's available memory; a CUDA run against the
    device's free memory (``wp.get_device(d).free_memory``), whatever the host has."""
    scene = load_scene("tc5_mountain", ne=30)
    need = runtime.run_bytes(30, 4, scene.stepper)
    monkeypatch.setattr(runtime, "available_memory", lambda: need // 2)
    with pytest.raises(runtime.ResourceError, match="of memory; .* is available"):
        units.check_memory(scene, None, Backend.of("cpu"))
    monkeypatch.setattr(wp, "get_device", lambda d=None: FakeCuda(2 * need, 4 * need))
    units.check_memory(scene, None, Backend.of("cuda"))  # the host's half is not the GPU's
    monkeypatch.setattr(runtime, "available_memory", lambda: 1 << 50)
    monkeypatch.setattr(wp, "get_device", lambda d=None: FakeCuda(need // 2, 4 * need))
    with pytest.raises(runtime.ResourceError, match=r"of GPU memory; .* free of .* on cuda"):
        units.check_memory(scene, None, Backend.of("cuda"))
