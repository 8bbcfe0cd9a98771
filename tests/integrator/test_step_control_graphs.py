"""A controlled run's tries replayed as graphs (``integrator.core.Unit.try_step``, ``integrator.control.StepControl``).

The controller's Δt are those of its grid (``on_grid``), so a few recur and each keeps a graph
keyed by it (``GraphCapture.graph_key``; an FSAL pair's key also says whether its first stage was
written ahead at that Δt). Warp replays graphs on a CPU too (one thread a launch), so the path
runs here as on CUDA, where it is the default: the same bits as plain launches, rejected tries
included, and one host read a try (the error norm's), a second where the Courant numbers' pass
is taken. The IMEX pairs' tries stay plain (their solver copies guess histories on the host's
decision under a checkpoint). The CUDA twins skip without a CUDA device.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from swe_sphere.config.scene import load_scene
from swe_sphere.integrator.core import Unit
from swe_sphere.simulation.simulation import Simulation

from helpers import ON_CUDA

DEVICES = ["cpu", ON_CUDA]
NE = {"cpu": 2, "cuda": 4}
# (stepper, control): FSAL pairs with the last stage carried over (rk43, bs32), a pair without
# (ssprk43), an IMEX pair (plain tries), an explicit stepper under CFL control
CASES = [("rk43", "error"), ("bs32", "error"), ("ssprk43", "error"), ("ark324", "error"), ("ssprk3", "cfl")]


def build(name: str, control: str, device: str, graphs: bool, every: float = 0.25, days=None) -> Simulation:
    """TC5 on ne 2 (CPU) or 4 (CUDA) np 4 under ``control``: half a day at rtol 1e-5, or two
    days at a Courant number 1 (or ``days``); output every ``every`` days (steps landed off the
    grid), the first step 5× the scene's Δt (tries rejected under error control), with or
    without graphs."""
    keys, length = ({"time.rtol": 1e-5}, 0.5) if control == "error" else ({"time.cfl": 1.0}, 2.0)
    days = length if days is None else days
    overrides = {"time.control": control, "output.every_days": min(every, days), **keys}
    scene = load_scene("tc5_mountain", ne=NE[device], np_=4, stepper=name, days=days, overrides=overrides)
    scene = load_scene(
        "tc5_mountain", ne=NE[device], np_=4, stepper=name, days=days, dt=5 * scene.dt, overrides=overrides
    )
    return Simulation(scene, device, progress=False, graphs=graphs)


def controlled(name: str, control: str, device: str, graphs: bool) -> Simulation:
    """``build``'s run, done."""
    sim = build(name, control, device, graphs)
    sim.run(None)
    return sim


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name, control", CASES)
def test_controlled_tries_replayed_as_graphs_are_the_bits_of_plain_ones(
    one_thread, graph_launches, name, control, device
):
    """The same state, steps, Δt and error norms as plain launches; rejected tries under error
    control; every explicit run keeps graphs (at least one Δt and, for an FSAL pair, its first
    stage written ahead), replayed by most steps, and compares one graph with plain launches a
    family (``GraphCapture.graph_family``: two for an FSAL pair, its first stage evaluated or not),
    not one a Δt; the IMEX pair's steps none."""
    plain = controlled(name, control, device, False)
    assert graph_launches[0] == 0
    graphed = controlled(name, control, device, True)
    np.testing.assert_array_equal(graphed.x.numpy(), plain.x.numpy())
    assert graphed.control.history == plain.control.history
    a, b = graphed.control, plain.control
    assert (a.accepted, a.rejected, a.courant_passes) == (b.accepted, b.rejected, b.courant_passes)
    assert a.accepted >= 8 and (a.rejected > 0 or control == "cfl"), (a.accepted, a.rejected)
    tries, kept, checked = a.accepted + a.rejected, graphed.graphs_kept, graphed.graphs_checked
    if name == "ark324":  # its solves' own graphs replay, not its steps
        assert kept == checked == 0
    else:
        assert graph_launches[0] >= tries / 2, (kept, graph_launches)
        assert checked == (2 if name in ("rk43", "bs32") else 1) < kept, (checked, kept)


@pytest.mark.parametrize("device", DEVICES)
def test_a_capture_failing_at_a_new_dt_falls_back_to_plain_launches(one_thread, monkeypatch, capsys, device):
    """The replay of a new Δt's graph raising, once both of ``rk43``'s families were checked (the
    capture moved the stepper's host side on, its device side not): one line, then plain
    launches from the step before for the rest of the run, the bits of a plain run."""
    plain = controlled("rk43", "error", device, False)
    sim = build("rk43", "error", device, True)
    real_capture, real_launch, state = wp.ScopedCapture, wp.capture_launch, {"captured": False, "raised": 0}

    def capture(*a, **k):
        state["captured"] = sim.graphs_checked == 2
        return real_capture(*a, **k)

    def launch(graph, *a, **k):
        if state["captured"] and not state["raised"]:
            state["raised"] += 1
            raise RuntimeError("a refused replay")
        return real_launch(graph, *a, **k)

    monkeypatch.setattr(wp, "ScopedCapture", capture)
    monkeypatch.setattr(wp, "capture_launch", launch)
    capsys.readouterr()
    sim.run(None)
    assert state["raised"] == 1
    np.testing.assert_array_equal(sim.x.numpy(), plain.x.numpy())
    assert sim.control.history == plain.control.history and sim.graphs_kept == 0
    warnings = capsys.readouterr().err.splitlines()
    name = sim.model.backend.graph_name
    assert warnings == [f"swe-sphere: {name} of the rk43 step failed: a refused replay; running without graphs"]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("name, control", [("rk43", "error"), ("ssprk3", "cfl")])
def test_a_graphed_try_reads_the_host_once(one_thread, tally, monkeypatch, name, control, device):
    """Host reads (``.numpy()``, each a device synchronisation) in a controlled run with graphs,
    output at its end only: none in a try's step once its graph is kept, and between one try
    and the next one read (the norm's) plus one where the Courant numbers' pass is taken
    (under error control only every few steps; under CFL control every step). Without tries
    launched ahead (CUDA's default: their reads, ``test_cuda_control.py``)."""
    inside, between = [], []
    sim = build(name, control, device, True, every=math.inf)
    sim.control.lookahead = False
    real_try = Unit.try_step
    last = {}

    def try_step(self, x):
        syncs, passes = tally.syncs, sim.control.courant_passes
        if last:
            between.append((syncs - last["syncs"], passes - last["passes"]))
        stats = real_try(self, x)
        inside.append(tally.syncs - syncs)
        last.update(syncs=tally.syncs, passes=passes)
        return stats

    monkeypatch.setattr(Unit, "try_step", try_step)
    with tally.counting():
        sim.run(None)
    tries = sim.control.accepted + sim.control.rejected
    assert len(inside) == tries and len(between) == tries - 1
    assert sim.graphs_kept >= 1 and inside.count(0) >= tries // 2, inside
    assert all(reads == (control == "error") + passes for reads, passes in between), between
    if control == "error":
        assert 0 < sum(p for _, p in between) < tries / 2, between
    else:
        assert all(p == 1 for _, p in between), between


@pytest.mark.parametrize("device", DEVICES)
def test_a_graphed_controlled_run_continues_bitwise(tmp_path, one_thread, device):
    """``rk43`` under error control with graphs, half a day straight against a quarter day, its
    restart file and a fresh ``Simulation`` from it with graphs for the rest: the same bits, steps
    and Δt (the continuation's first step evaluates its first stage, as after any restore)."""
    whole = controlled("rk43", "error", device, True)
    half = build("rk43", "error", device, True, days=0.25)
    result = half.run(None, restart_every=0.25, restart_file=tmp_path / "half.restart.nc")
    cont = Simulation.from_checkpoint(result.checkpoint, device, days=0.5, progress=False, graphs=True)
    cont.run(None)
    np.testing.assert_array_equal(cont.x.numpy(), whole.x.numpy())
    assert cont.control.accepted == whole.control.accepted and cont.graphs_kept >= 1
    assert [dt for _, dt, _ in cont.control.history] == [dt for _, dt, _ in whole.control.history][
        -len(cont.control.history) :
    ]
