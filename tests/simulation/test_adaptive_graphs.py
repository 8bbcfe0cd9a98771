"""A controlled run's tries replayed as graphs (``Simulation.try_step``, ``adaptive.StepControl``).

The controller's Δt are those of its grid (``on_grid``), so a few recur and each keeps a graph
keyed by it (``Stepper.graph_key``; an FSAL pair's key also says whether its first stage was
written ahead at that Δt). Warp replays graphs on a CPU too (one thread a launch), so the path
runs here as on CUDA, where it is the default: the same bits as plain launches, rejected tries
included, and one host read a try (the error norm's), a second where the Courant numbers' pass
is taken. The IMEX pairs' tries stay plain (their solver copies guess histories on the host's
decision under a checkpoint). The CUDA twins skip without a CUDA device.
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.core.graphs import GraphedSteps
from swe_sphere.core.tally import Tally, instrumented
from swe_sphere.simulation.simulation import Simulation

from helpers import ON_CUDA

DEVICES = ["cpu", ON_CUDA]
NE = {"cpu": 2, "cuda": 4}
# (stepper, control): FSAL pairs with the last stage carried over (rk43, bs32), a pair without
# (ssprk43), an IMEX pair (plain tries), an explicit stepper under CFL control
CASES = [("rk43", "error"), ("bs32", "error"), ("ssprk43", "error"), ("ark324", "error"), ("ssprk3", "cfl")]


@pytest.fixture
def one_thread(monkeypatch):
    """CPU launches on one thread (a CPU graph replays in one; split launches run plain)."""
    monkeypatch.setenv("SWE_SPHERE_THREADS", "1")


@pytest.fixture
def graph_launches(monkeypatch):
    """[n]: the number of ``wp.capture_launch`` calls since the test began."""
    count, real = [0], wp.capture_launch

    def launch(*a, **k):
        count[0] += 1
        return real(*a, **k)

    monkeypatch.setattr(wp, "capture_launch", launch)
    return count


def controlled(name: str, control: str, device: str, graphs: bool) -> Simulation:
    """TC5 on ne 2 (CPU) or 4 (CUDA) np 4 under ``control``: half a day at rtol 1e-5, or two
    days at a Courant number 1; output every 0.25 days (steps landed off the grid), the first
    step 5× the scene's Δt (tries rejected under error control), run with or without graphs."""
    keys, days = ({"time.rtol": 1e-5}, 0.5) if control == "error" else ({"time.cfl": 1.0}, 2.0)
    overrides = {"time.control": control, "output.every_days": 0.25, **keys}
    scene = load_scene("tc5_mountain", ne=NE[device], np_=4, stepper=name, days=days, overrides=overrides)
    scene = load_scene(
        "tc5_mountain", ne=NE[device], np_=4, stepper=name, days=days, dt=5 * scene.dt, overrides=overrides
    )
    sim = Simulation(scene, device, progress=False, graphs=graphs)
    sim.run(None)
    return sim


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name, control", CASES)
def test_controlled_tries_replayed_as_graphs_are_the_bits_of_plain_ones(
    one_thread, graph_launches, monkeypatch, name, control, device
):
    """The same state, steps, Δt and error norms as plain launches; rejected tries under error
    control; every explicit run keeps graphs (at least one Δt and, for an FSAL pair, its first
    stage written ahead), replayed by most steps, and compares one graph with plain launches a
    family (``Stepper.graph_family``: two for an FSAL pair, its first stage evaluated or not),
    not one a Δt; the IMEX pair's steps none."""
    plain = controlled(name, control, device, False)
    assert graph_launches[0] == 0
    checks, real = [], GraphedSteps._checked

    def checked(self, key, *args):
        checks.append(key[1])
        return real(self, key, *args)

    monkeypatch.setattr(GraphedSteps, "_checked", checked)
    graphed = controlled(name, control, device, True)
    np.testing.assert_array_equal(graphed.x.numpy(), plain.x.numpy())
    assert graphed.control.history == plain.control.history
    a, b = graphed.control, plain.control
    assert (a.accepted, a.rejected, a.courant_passes) == (b.accepted, b.rejected, b.courant_passes)
    assert a.accepted >= 8 and (a.rejected > 0 or control == "cfl"), (a.accepted, a.rejected)
    tries = a.accepted + a.rejected
    print(name, control, "tries", tries, "graphs kept", graphed.graphs_kept, "replays", graph_launches[0])
    if name == "ark324":  # its solves' own graphs replay, not its steps
        assert graphed.graphs_kept == 0
    else:
        assert graphed.graphs_kept >= 1 and graph_launches[0] >= tries / 2, (graphed.graphs_kept, graph_launches)
        families = {key[:1] + key[2:] for key in checks}
        assert len(checks) == len(families) <= 2 < graphed.graphs_kept + (control == "cfl"), (checks, families)


@pytest.mark.parametrize("device", DEVICES)
def test_a_capture_failing_at_a_new_dt_falls_back_to_plain_launches(one_thread, monkeypatch, capsys, device):
    """A replay that raises in the capture of a checked family's new Δt (``GraphedSteps._captured``):
    one line, plain launches from the step before for the rest of the run, the bits of a plain run."""
    plain = controlled("rk43", "error", device, False)
    calls, real_captured, real_launch = [0], GraphedSteps._captured, wp.capture_launch

    def captured(self, *args):
        calls[0] += 1
        return real_captured(self, *args)

    def launch(graph, *a, **k):
        if calls[0] == 3:
            calls[0] += 1
            raise RuntimeError("a refused replay")
        return real_launch(graph, *a, **k)

    monkeypatch.setattr(GraphedSteps, "_captured", captured)
    monkeypatch.setattr(wp, "capture_launch", launch)
    capsys.readouterr()
    graphed = controlled("rk43", "error", device, True)
    assert calls[0] == 4, calls
    np.testing.assert_array_equal(graphed.x.numpy(), plain.x.numpy())
    assert graphed.control.history == plain.control.history
    assert graphed.control.accepted == plain.control.accepted and graphed.graphs_kept == 0
    warnings = capsys.readouterr().err.splitlines()
    assert warnings == [
        f"swe-sphere: {graphed.model.backend.graph_name} of the rk43 step failed: a refused replay; running without graphs"
    ]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name, control", [("rk43", "error"), ("ssprk3", "cfl")])
def test_a_graphed_try_reads_the_host_once(one_thread, monkeypatch, name, control, device):
    """Host reads (``.numpy()``, each a device synchronisation) in a controlled run's tries
    replayed as graphs: none in the step itself once its graph is kept, and the try's
    decision one read (the norm's) plus one where the Courant numbers' pass is taken
    (under error control only every few steps; under CFL control every step)."""
    tally, inside, deciding = Tally(), [], []
    real_try = Simulation.try_step

    def try_step(sim, x):
        before = tally.syncs
        stats = real_try(sim, x)
        inside.append(tally.syncs - before)
        return stats

    monkeypatch.setattr(Simulation, "try_step", try_step)
    from swe_sphere.simulation.adaptive import StepControl

    real_propose = StepControl._propose

    def propose(ctl, x, dt):
        before, passes = tally.syncs, ctl.courant_passes
        out = real_propose(ctl, x, dt)
        deciding.append((tally.syncs - before, ctl.courant_passes - passes))
        return out

    monkeypatch.setattr(StepControl, "_propose", propose)
    with instrumented(tally), tally.counting():
        sim = controlled(name, control, device, True)
    tries = sim.control.accepted + sim.control.rejected
    assert len(inside) == len(deciding) == tries
    assert sim.graphs_kept >= 1 and inside.count(0) >= tries // 2, inside
    reads = [n for n, _ in deciding]
    assert reads == [(control == "error") + passes for _, passes in deciding], deciding
    if control == "error":
        assert sum(p for _, p in deciding) < tries / 2, deciding


@pytest.mark.parametrize("device", DEVICES)
def test_a_graphed_controlled_run_continues_bitwise(tmp_path, one_thread, device):
    """``rk43`` under error control with graphs, half a day straight against a quarter day, its
    restart file and a fresh ``Simulation`` from it with graphs for the rest: the same bits, steps
    and Δt (the continuation's first step evaluates its first stage, as after any restore)."""
    whole = controlled("rk43", "error", device, True)
    overrides = {"time.control": "error", "output.every_days": 0.25, "time.rtol": 1e-5}
    scene = load_scene("tc5_mountain", ne=NE[device], np_=4, stepper="rk43", days=0.25, overrides=overrides)
    scene = load_scene(
        "tc5_mountain", ne=NE[device], np_=4, stepper="rk43", days=0.25, dt=5 * scene.dt, overrides=overrides
    )
    half = Simulation(scene, device, progress=False, graphs=True)
    result = half.run(None, restart_every=0.25, restart_file=tmp_path / "half.restart.nc")
    cont = Simulation.from_checkpoint(result.checkpoint, device, days=0.5, progress=False, graphs=True)
    cont.run(None)
    np.testing.assert_array_equal(cont.x.numpy(), whole.x.numpy())
    assert cont.control.accepted == whole.control.accepted and cont.graphs_kept >= 1
    assert [dt for _, dt, _ in cont.control.history] == [dt for _, dt, _ in whole.control.history][
        -len(cont.control.history) :
    ]
