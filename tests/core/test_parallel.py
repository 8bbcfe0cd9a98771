"""Multi-threaded CPU launches (``swe_sphere.core.parallel``): the same bits as one thread."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.cases.library import make_case
from swe_sphere.core import parallel
from swe_sphere.core.backend import Backend
from swe_sphere.core.workers import cpus
from swe_sphere.model.arguments import TERMS
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.steppers import STEPPERS, make_stepper

import roundoff
from helpers import cached_grid


@pytest.fixture
def small_parts(monkeypatch):
    """Split launches on a tiny grid (ne=3, np=4: 864 nodes)."""
    monkeypatch.setattr(parallel, "MIN_POINTS_PER_PART", 64)
    return cached_grid(3, 4)


def tc5_model(g, threads, per_element=None):
    c = make_case("tc5_mountain")
    m = ShallowWater(
        g,
        [t for t in TERMS if t != "forcing"],
        c.fcor(g.lat, g.lon),
        c.hs(g.lat, g.lon),
        nu=1e15,
        device="cpu",
        threads=threads,
        per_element=per_element,
    )
    return m, np.array(c.initial(g.lat, g.lon))


def test_split_points_cut_at_elements():
    assert parallel.split_points(864, 16, 2) == [0, 432, 864]
    assert parallel.split_points(864, 16, 5) == [0, 176, 352, 512, 688, 864]
    assert parallel.split_points(100, 16, 2) == [0, 50, 100]  # not whole elements: plain halves


def test_threads_env_and_validation(monkeypatch):
    monkeypatch.setenv("SWE_SPHERE_THREADS", "1")
    cpu = Backend.of("cpu")
    assert cpu.threads() == 1
    monkeypatch.setenv("SWE_SPHERE_THREADS", "3")
    assert cpu.threads() == min(3, cpus())  # never more than the CPUs
    monkeypatch.setenv("SWE_SPHERE_THREADS", "0")
    with pytest.raises(ValueError, match="SWE_SPHERE_THREADS must be >= 1"):
        cpu.threads()
    g = cached_grid(1, 2)
    z = np.zeros(g.nnodes)
    with pytest.raises(ValueError):
        ShallowWater(g, [], z, z, threads=0)


@pytest.mark.parametrize("threads", [2, 3])
def test_operators_bitwise_equal_to_one_thread(small_parts, threads, rng):
    g = small_parts
    res = {}
    for n in (1, threads):
        m, st = tc5_model(g, n)
        x = m.new_state(*st)
        out = wp.zeros_like(x)
        m.rhs(x, out)
        assert m.rhs_kernels(x, out) == [
            "tendency__continuity__momentum_advection__coriolis__pressure_gradient__topography__mass",
            "dss",
        ]
        if n > 1:
            assert all(isinstance(launch, parallel.SplitLaunch) for launch in m.launches.recorded(m.rhs_key(x, out)))
        m.hyperviscosity(x, 3600.0)
        grad, div = wp.zeros((2, m.N), dtype=wp.float64), wp.zeros((1, m.N), dtype=wp.float64)
        m.operators.gradient(x, 2, grad)
        m.operators.divergence(x, div)
        unique = wp.zeros(g.nunique, dtype=wp.float64)
        m.operators.assemble(x, 2, unique)
        back = wp.zeros((3, m.N), dtype=wp.float64)
        m.operators.scatter(unique, back, 1)
        bad = x.numpy().copy()  # numpy() is a view of a CPU array
        bad[1, [700, 800]] = np.nan  # the first bad node lies in the last part
        res[n] = [
            out.numpy(),
            x.numpy(),
            grad.numpy(),
            div.numpy(),
            unique.numpy(),
            back.numpy(),
            m.operators.vorticity(x),
        ]
        res[n].append(m.bad_nodes.first(wp.array(bad, dtype=wp.float64)))
    assert res[1][-1] == res[threads][-1] == 700
    names = ["rhs", "hyperviscosity", "gradient", "divergence", "assemble", "scatter", "vorticity"]
    for name, a, b in zip(names, res[1], res[threads]):
        assert np.array_equal(a, b), name


@pytest.mark.parametrize("name", STEPPERS)
def test_steps_bitwise_equal_to_one_thread(small_parts, name):
    g = small_parts
    final = {}
    for n in (1, 2):
        m, st = tc5_model(g, n)
        x = m.new_state(*st)
        stepper = make_stepper(name, m, 600.0)
        for _ in range(3):
            stepper.step(x)
        final[n] = x.numpy()
    assert np.array_equal(final[1], final[2])


@pytest.mark.roundoff
@pytest.mark.parametrize("name", STEPPERS)
def test_steps_same_with_per_node_kernels(small_parts, name, rng):
    """CUDA's per-node layout (run here on the CPU) steps to the CPU layout's
    state up to round-off (FMA contraction, summation order): 3 steps of 600 s. For the
    semi-implicit and IMEX solves this also holds the CPU layout's fused right-hand side
    and back-substitution (``HelmholtzSolver._schur``: no DSS before the assembly) to the
    per-node form's seven passes.

    The bound is the run's own round-off floor: how far the same layout ends from a
    start one rounding away (every node ±ε), ``floor``. The layouts round differently
    in every RHS evaluation and solver iteration (``ops``), by at most np roundings a
    node (a derivative's np terms summed in another order), each ending no farther
    than a rounding of the start: |per-node − per-element| ≤ np · ops · floor. The floor
    holds what the stepper makes of round-off: the exponential steppers' forward-
    difference J·v turn it into ~√ε of J·v (1e-9 of the wind here, as over MPI
    ranks, ``test_mpi``), the other steppers keep it near ε."""
    g = small_parts
    _, st = tc5_model(g, 2)

    def stepped(state, per_element):
        m, _ = tc5_model(g, 2, per_element)
        x = m.new_state(*state)
        stepper = make_stepper(name, m, 600.0)
        stats = [stepper.step(x) for _ in range(3)]
        return x.numpy(), sum(s.rhs_evals + sum(s.iterations.values()) for s in stats)

    ref, ops = stepped(st, True)
    diff = roundoff.state_difference(stepped(st, False)[0], ref)
    floor = roundoff.state_difference(stepped(roundoff.nudged(st, g, rng), True)[0], ref)
    print(f"\n{name}: |per-node − per-element| in wind, depth {diff}, floor {floor}, {ops} RHS and iterations")
    roundoff.within(max(diff), g.np * ops * max(floor), "|per-node − per-element| (wind, depth)")


def test_split_launches_work_in_a_forked_child(small_parts):
    """A fork after the worker threads exist gets fresh ones (no deadlock)."""
    import multiprocessing as mp

    m, st = tc5_model(small_parts, 2)
    x = m.new_state(*st)
    out = wp.zeros_like(x)
    m.rhs(x, out)  # starts the pool in the parent
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    p = ctx.Process(target=_child_rhs, args=(m, x, q))
    p.start()
    child = q.get(timeout=60)
    p.join(60)
    assert p.exitcode == 0
    assert np.array_equal(child, out.numpy())


def _child_rhs(m, x, q):
    out = wp.zeros_like(x)
    m.rhs(x, out)
    q.put(out.numpy().copy())


def test_a_launch_is_refused_arrays_on_another_device():
    """``parallel.record`` checks that every array a launch takes, and every array field of a
    struct it takes, lives on the launch's device: Warp passes a host array's address to a CUDA
    launch as it is, an illegal memory access reported only at a later sync (issue 83: the
    gradient's model held its arrays on the CPU while its topology launched on CUDA). A device
    name checked without a card: the launch is refused before Warp looks the device up."""
    from swe_sphere.kernels import blas, hyperviscosity, hyperviscosity_node

    x, out = wp.zeros((1, 4), dtype=wp.float64), wp.zeros((1, 4), dtype=wp.float64)
    inputs = [wp.float64(1.0), x, wp.float64(0.0), x, out, 1]
    card = Backend("cuda:0", host=False)
    assert parallel.foreign_arrays(blas.axpby, inputs, "cpu") == []
    assert parallel.foreign_arrays(blas.axpby, inputs, card) == ["x (cpu)", "y (cpu)", "out (cpu)"]
    with pytest.raises(ValueError, match=r"launched on cuda:0 takes arrays elsewhere: x \(cpu\), y \(cpu\)"):
        parallel.record(blas.axpby, 4, inputs, device=card, threads=1)
    frame = hyperviscosity.Frame()
    frame.east = wp.zeros((3, 4), dtype=wp.float64)
    kernel = hyperviscosity_node.laplacian_node(False, False)
    assert parallel.foreign_arrays(kernel, [None, None, None, None, frame], card) == ["f.east (cpu)"]
    assert parallel.foreign_arrays(kernel, [None, None, None, None, frame], "cpu") == []


def test_one_range_launch_called_directly():
    """A launch of one range on the CPU (``parallel.record`` with one thread) is a ``DirectLaunch``:
    Warp's entry point called with its argument struct built once, the bits of Warp's own launch,
    an argument set in place reaching it; while the CPU captures a graph it goes through Warp's
    launch, so the graph holds it (a direct call would run at once and be missing from the
    replay); ``core.tally`` counts it once."""
    from swe_sphere.core.tally import Tally, instrumented
    from swe_sphere.kernels import blas

    f64 = wp.float64
    x = wp.array(np.arange(8.0).reshape(2, 4) / 3.0, dtype=f64)
    y = wp.array(np.full((2, 4), 0.7), dtype=f64)
    out, warps = wp.zeros((2, 4), dtype=f64), wp.zeros((2, 4), dtype=f64)
    launch = parallel.record(blas.axpby, (2, 4), [f64(0.3), x, f64(1.1), y, out, 1], device="cpu", threads=1)
    assert isinstance(launch, parallel.DirectLaunch) and launch.kernel is blas.axpby
    launch.launch()
    wp.launch(blas.axpby, (2, 4), [f64(0.3), x, f64(1.1), y, warps, 1, 0], device="cpu")
    assert np.array_equal(out.numpy(), warps.numpy())
    assert np.array_equal(out.numpy(), 0.3 * x.numpy() + 1.1 * y.numpy())
    launch.set_param_by_name("a", f64(-2.0))
    launch.launch()
    assert np.array_equal(out.numpy(), -2.0 * x.numpy() + 1.1 * y.numpy())
    out.zero_()
    with wp.ScopedCapture(device="cpu") as capture:
        launch.launch()
    assert not out.numpy().any()  # recorded, not run
    wp.capture_launch(capture.graph)
    assert np.array_equal(out.numpy(), -2.0 * x.numpy() + 1.1 * y.numpy())
    tally = Tally()
    with instrumented(tally), tally.counting():
        launch.launch()
        with wp.ScopedCapture(device="cpu"):
            launch.launch()  # Warp's own path: still one launch
    assert dict(tally.launches) == {blas.axpby.key: 2}
