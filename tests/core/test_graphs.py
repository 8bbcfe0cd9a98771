"""Steps replayed as captured graphs (``Simulation.graphs``)
and the host reads inside a step (``swe_sphere.core.tally``).

Warp captures and replays graphs on a CPU too (its launches recorded and replayed
in C++, one thread), so the graph path runs here as on a GPU: with one thread a
launch a graphed run gives the same bits as launching step by step, reports a
blow-up or an unconverged solve inside a block as a check every step does, and
continues from a restart file bitwise. The same tests run on CUDA (CUDA graphs
against the ungraphed CUDA run; skipped without a CUDA device). A step that reads
the device back cannot be captured: the explicit steppers read nothing inside a
step, the semi-implicit and IMEX ones nothing while ``Simulation`` runs them (their
CG's counters read once a block, ``Stepper.deferred``).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.core.graphs import GraphedSteps, same_bits
from swe_sphere.core.tally import Tally, instrumented
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS

from helpers import ON_CUDA, assert_same_runs, watched_run, write_tc2_scene

# the capturable steppers (explicit, semi-implicit, IMEX), and "tableau", whose default table is explicit (a ``TableauRK``)
CAPTURABLE = [name for name, cls in STEPPERS.items() if cls.capturable] + ["tableau"]
DEVICES = ["cpu", ON_CUDA]
NE = {"cpu": 2, "cuda": 4}
STEPS = 12
SOLVER_DT = 4.0  # the implicit-type steppers' Δt in the read count, × TC5's
SOLVERS = ["semi_implicit", "imex"]  # the capturable steppers with a Helmholtz CG


def tc5(name, device, steps=STEPS, **kw):
    """TC5 (every term, ∇⁴ included) on ne 2 (CPU) or 4 (CUDA) np 4 for ``steps`` steps."""
    scene = load_scene("tc5_mountain", ne=NE[device], np_=4, stepper=name, **kw)
    return dataclasses.replace(scene, days=steps * scene.dt / DAY, output_every_days=steps * scene.dt / DAY)


def skip_without_conditional_nodes(name, device):
    """A solver stepper's step is a CUDA graph only where its CG's loop can be a conditional node."""
    if device == "cuda" and STEPPERS[name].solvers and not wp.is_conditional_graph_supported():
        pytest.skip("a CG's loop in a CUDA graph needs conditional nodes (CUDA driver and toolkit 12.4+)")


def long_steps(name, device, steps, **options):
    """``tc5`` at 2× (semi-implicit) or 4× (IMEX) TC5's Δt, the stepper's ``options``."""
    scene = tc5(name, device, steps)
    scene = dataclasses.replace(
        scene, dt=scene.dt * {"semi_implicit": 2, "imex": SOLVER_DT}[name], stepper_options=options
    )
    return dataclasses.replace(scene, days=steps * scene.dt / DAY, output_every_days=steps * scene.dt / DAY)


def stepped(scene, device, graphs, check_every):
    sim = Simulation(scene, device, progress=False)
    sim.graphs, sim.check_every = graphs, check_every
    result = sim.run(None)
    return sim.x.numpy(), result.rhs_evals, sim.stepper.steps, result.iterations


@pytest.mark.parametrize("device", DEVICES)
def test_the_graph_check_compares_bits_on_the_device(device):
    """``same_bits``, the check a captured step's first replay passes: two arrays equal bit for
    bit (a NaN against the same NaN too) are the same, while a sign of zero, another NaN
    payload, one unit in the last place, another shape or dtype differ; strided views compare
    by their own elements, host values by ``repr``."""
    rng = np.random.default_rng(3)
    base = rng.standard_normal((3, 50))
    base[0, 7], base[1, 3] = np.nan, 0.0

    def arr(a, dtype=wp.float64):
        return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)

    assert same_bits([(arr(base), arr(base)), (arr(base[:, ::2]), arr(base)[:, ::2]), (3, 3), ("rk4", "rk4")])
    spoiled = []
    for r, p, value in [(1, 3, -0.0), (0, 7, np.frombuffer(np.uint64(0x7FF8000000000001).tobytes())[0])]:
        other = base.copy()
        other[r, p] = value
        spoiled.append(other)
    other = base.copy()
    other[2, 49] = np.nextafter(other[2, 49], np.inf)
    spoiled.append(other)
    for other in spoiled:
        assert not same_bits([(arr(base), arr(base)), (arr(base), arr(other))])
    assert not same_bits([(arr(base), arr(base[:, :49]))])
    assert not same_bits([(arr(base), arr(base.astype(np.float32), wp.float32))])
    odd, even = slice(1, None, 2), slice(0, None, 2)  # (2, 49), one ulp off, is in the odd columns
    assert not same_bits([(arr(base)[:, odd], arr(spoiled[2])[:, odd])])
    assert same_bits([(arr(base)[:, even], arr(spoiled[2])[:, even])])
    assert not same_bits([(3, 3.0)])


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name", CAPTURABLE)
def test_graphed_steps_are_the_bits_of_plain_ones(one_thread, graph_launches, name, device):
    """12 steps of TC5 (its ∇⁴ two forward-Euler substeps a step on ne 2, leapfrog's three
    over 2Δt): graphed, in blocks of 5 checked steps (the flag's launch in the
    graph) and checked one by one, against plain launches: the same state, RHS
    count, stepper step count and solver iterations (semi-implicit, IMEX: the CG's
    loops inside the step's graph, its counters read once a block); all but each
    key's first two steps (plain, then captured) and the start (leapfrog's, the
    semi-implicit half step, IMEX's first step fixing H) ran as graphs."""
    skip_without_conditional_nodes(name, device)
    scene = tc5(name, device)
    plain = stepped(scene, device, False, 5)
    assert graph_launches[0] == 0  # "off": no graph, not even the solves' own (``HelmholtzSolver``)
    for every in (5, 1):
        graph_launches[0] = 0
        graphed = stepped(scene, device, True, every)
        np.testing.assert_array_equal(graphed[0], plain[0])
        assert graphed[1:] == plain[1:] == (graphed[1], STEPS, graphed[3])
        if name == "lts":  # one level on the uniform cube: the global step, no fine evaluation
            assert graphed[3] == {"fast": 0}, graphed[3]
        else:
            assert all(its > STEPS for its in graphed[3].values()), graphed[3]
        assert graph_launches[0] >= STEPS - 3, graph_launches[0]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("name", SOLVERS)
def test_graphed_solver_steps_at_long_steps_are_the_bits_of_plain_ones(
    one_thread, graph_launches, name, precision, device
):
    """16 semi-implicit (2× TC5's Δt) and IMEX ARS(3,4,3) (4×) steps, double and mixed
    precision (the refinement's loop around the float32 CG's: nested ``capture_while``
    inside the step's graph), graphed in blocks of 5: the state and Helmholtz
    iterations of plain steps checked one by one, bit for bit."""
    skip_without_conditional_nodes(name, device)
    scene = long_steps(name, device, 16, precision=precision)
    plain = stepped(scene, device, False, 1)
    graph_launches[0] = 0
    graphed = stepped(scene, device, True, 5)
    np.testing.assert_array_equal(graphed[0], plain[0])
    assert graphed[1:] == plain[1:] and plain[3]["helmholtz"] > 16 * 3
    assert graph_launches[0] >= 16 - 3


@pytest.mark.parametrize("name", SOLVERS)
def test_a_graphed_solver_step_reads_nothing_back_and_a_block_once(one_thread, tally, monkeypatch, name):
    """Host reads in a graphed run of 16 long steps checked every 5: none in any step of
    a block (graph or plain: the CG's counters stay on the device), and at the end of
    each block (2-4: the wall-time estimate's, 6-10, 11-15) the bad-state flag and the
    solvers' counters, one read each (``Stepper.counts``). The steps checked alone (1,
    5 and 16, left between blocks) read their counters as the step returns (one read,
    after ``GraphedSteps.step``: ``counts`` at 0, 4 and 15), the first also its mean
    depth inside the step (``set_depth``). Steps 3 and 16, the first graphs of a block's
    and of a lone step's key, are checked against a plain step (``graphs.GraphedSteps``),
    which reads. (Before: one read a step, the step's counters, and no graph.)"""
    sim = Simulation(long_steps(name, "cpu", 16), "cpu", progress=False)
    sim.graphs, sim.check_every = True, 5
    inside, reads = [], {"flag": [], "counts": []}
    take, counts, watched_bad = GraphedSteps.step, sim.stepper.counts, sim.model.bad_nodes.watched_bad

    def counted(what, fn):
        def call(*a):
            reads[what].append(sim.step)
            before = tally.syncs
            out = fn(*a)
            assert tally.syncs == before + 1, what
            return out

        return call

    def step(graphed, stepper, model, x, watch):  # a step, graphed or plain
        before = tally.syncs
        stats = take(graphed, stepper, model, x, watch)
        inside.append((watch, tally.syncs - before))
        return stats

    monkeypatch.setattr(GraphedSteps, "step", step)
    sim.stepper.counts, sim.model.bad_nodes.watched_bad = counted("counts", counts), counted("flag", watched_bad)
    with tally.counting():
        result = sim.run(None)
    assert result.steps == 16 and result.iterations["helmholtz"] > 16 * 3
    # each key's first graph checked (step 3 in a block, 16 alone): a plain step (CG host loops), compared
    assert inside[2][0] and inside[2][1] > 2 and not inside[15][0] and inside[15][1] > 1, inside
    assert inside[:2] + inside[3:15] == [(False, 1), *[(True, 0)] * 2, (False, 0), *[(True, 0)] * 10], inside
    assert reads == {"flag": [4, 10, 15], "counts": [0, 4, 4, 10, 15, 15]}


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name, maxiter", [("semi_implicit", 5), ("imex", 4)])
def test_an_unconverged_solve_inside_a_graphed_block_is_reported_as_with_a_check_every_step(
    tmp_path, one_thread, graph_launches, name, maxiter, device
):
    """A Helmholtz solve past ``maxiter`` in step 6, inside the block 6-10 of a check every
    5 steps (a callback at step 5 spoils the CG's warm-start guess, ``guess_history`` 0):
    found at the block's read of the counters, the block is re-run from step 5 one checked
    step at a time, and
    the message (step, model time), counters, run file and state are those of plain
    steps checked every step, graphed or not."""
    skip_without_conditional_nodes(name, device)
    scene = dataclasses.replace(
        tc5(name, "cpu"), stepper_options={"maxiter": maxiter, "guess_history": 0, "tol": 1e-6}
    )  # ne 2 on CUDA too: the iterations of the CPU to round-off; maxiter suits tol 1e-6

    def spoil(sim):
        gw = sim.stepper.helmholtz
        gw.y.assign(np.random.default_rng(1).standard_normal(gw.y.shape[0]) * 1e3)

    runs = [
        watched_run(
            scene,
            tmp_path / f"{every}{graphs}.nc",
            device=device,
            check_every=every,
            graphs=graphs,
            setup=lambda sim: sim.add_callback(spoil, every_steps=5),
        )
        for every, graphs in ((1, False), (5, False), (5, True))
    ]
    assert runs[0][1].startswith("step 6 failed (model time 0.2143 days): Helmholtz CG did not converge in ")
    assert graph_launches[0] > 0
    assert_same_runs(runs[0], runs[1])
    assert_same_runs(runs[0], runs[2])


@pytest.mark.parametrize("device", DEVICES)
def test_graphed_rkl1_hyperviscosity_is_the_bits_of_plain_steps(one_thread, graph_launches, device):
    """ssprk3 with 10× TC5's ν: the ∇⁴ as an RKL1 super-step (``Hyperviscosity.rkl1``:
    copies, and one recorded combination launched with each stage's coefficients)
    inside the graph, the same bits as launched one by one."""
    scene = tc5("ssprk3", device)
    scene = dataclasses.replace(scene, nu=10 * scene.nu, nu_div=10 * scene.nu_div, nu_s=10 * scene.nu_s)
    assert Simulation(scene, device, progress=False).model.hv.plan(scene.dt)[1]  # RKL1
    plain = stepped(scene, device, False, 5)
    graphed = stepped(scene, device, True, 5)
    np.testing.assert_array_equal(graphed[0], plain[0])
    assert graph_launches[0] >= STEPS - 3


@pytest.mark.parametrize("device", DEVICES)
def test_blow_up_inside_a_graphed_block_is_reported_as_with_a_check_every_step(
    tmp_path, one_thread, graph_launches, device
):
    """Leapfrog at dt = 3600 s on TC2 ne = 2 blows up at step 17, inside the block
    16-20 of a check every 5 steps replayed as graphs: the block is re-run from
    step 15 (its state and x(n-1) assigned in place, which the graphs follow), and
    the message (step, time, place), counters, run file and state are those of
    plain steps checked every step."""
    scene = load_scene(
        write_tc2_scene(
            tmp_path / "s.toml", stepper="leapfrog", dt=3600.0, days=2.0, tables="[output]\nlog_every_steps = 6"
        )
    )
    one = watched_run(scene, tmp_path / "one.nc", device=device)
    graphed = watched_run(scene, tmp_path / "graphed.nc", device=device, check_every=5, graphs=True)
    assert one[1].startswith("blow-up at step 17 (model time 0.7083 days): depth h = ")
    assert graph_launches[0] > 10
    assert_same_runs(one, graphed)


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name", ["leapfrog", "ssprk3", *SOLVERS])
def test_a_graphed_run_continues_from_its_restart_file_bitwise(
    tmp_path, monkeypatch, one_thread, graph_launches, name, device
):
    """12 graphed steps straight against 6 graphed steps, a restart file and a fresh
    graphed Simulation from it for 6 more (leapfrog: its x(n-1) restored, its
    start not re-run; the semi-implicit and IMEX mean depth and CG guess restored):
    the same final state as 12 plain steps."""
    skip_without_conditional_nodes(name, device)
    monkeypatch.delenv("SWE_SPHERE_GRAPHS", raising=False)
    plain = stepped(tc5(name, device), device, False, 5)[0]
    whole = stepped(tc5(name, device), device, True, 5)[0]
    half = Simulation(tc5(name, device, STEPS // 2), device, progress=False)
    half.graphs = True
    r = half.run(tmp_path / "half.nc", restart_every=half.scene.days)
    cont = Simulation.from_checkpoint(r.checkpoint, device, days=tc5(name, device).days, progress=False)
    assert cont.graphs == "auto"  # the default: whole steps as graphs on CUDA; a CPU one asks
    cont.graphs = True
    launches = graph_launches[0]
    cont.run(None)
    assert graph_launches[0] > launches
    np.testing.assert_array_equal(whole, plain)
    np.testing.assert_array_equal(cont.x.numpy(), plain)


def test_a_time_dependent_forcing_is_not_captured():
    """TC4's forcing reads the model time as a launch argument, which a graph would
    freeze: its explicit steps run plain (no graph key), TC5's are captured (keyed by their Δt)."""
    for case, captured in (("tc4_forced_low", False), ("tc5_mountain", True)):
        sim = Simulation(load_scene(case, ne=2, np_=4, stepper="ssprk3"), "cpu", progress=False)
        assert sim.stepper.graph_key() == (("step", sim.scene.dt) if captured else None), case


def test_capturable_steps_read_nothing_back(one_thread):
    """Host reads (``.numpy()`` read-backs, each a device synchronisation that ends a
    CUDA graph) inside one TC5 ne 2 step of every registered stepper, after two, as
    ``Simulation.run`` takes them (``Stepper.deferred``): none in a capturable step
    (explicit; semi-implicit and IMEX at 4× Δt, their CG's counters left on the
    device), and each of those has a graph key; the others (JFNK, exponential) read
    their solvers' results back (counts printed with -s; implicit 177 before the device
    FGMRES, 14 after with the CUDA backends; semi_implicit 21 and imex 32 before the device CG)."""
    tally, counts = Tally(), {}
    for name, cls in STEPPERS.items():
        scene = load_scene("tc5_mountain", ne=2, np_=4, stepper=name)
        if not cls.explicit and name != "tableau":
            scene = dataclasses.replace(scene, dt=scene.dt * SOLVER_DT)
        sim = Simulation(scene, "cpu", progress=False)
        sim.stepper.deferred = True
        for _ in range(2):
            sim.stepper.step(sim.x)
        with instrumented(tally), tally.counting():
            sim.stepper.step(sim.x)
        counts[name] = tally.syncs
        if sim.stepper.capturable:
            assert tally.syncs == 0 and sim.stepper.graph_key() is not None, (name, tally.syncs)
        else:  # no graph capture (``capabilities.GraphCapture``)
            assert not hasattr(sim.stepper, "graph_key"), name
    print("host reads in one step:", counts)
    assert counts["implicit"] > 0  # the count sees the solvers' reads
    assert {"semi_implicit", "imex", "ssprk3"} <= {name for name, cls in STEPPERS.items() if cls.capturable}
