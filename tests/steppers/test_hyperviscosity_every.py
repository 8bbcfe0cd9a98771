"""The ∇⁴ every k steps (``[hyperviscosity] every``, issue 99): over kΔt after every k-th step
and not at the others, by the step's index, so that a continued run and a step's graph agree
(the gradient's steps taken again: tests/adjoint/test_adjoint.py); refused where it does not fit (one line, exit 2)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from swe_sphere.config.hyperviscosity import Span, auto_every
from swe_sphere.config.scene import load_scene
from swe_sphere.config.step_rule import sparse_dt
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import SceneError
from swe_sphere.model.hyperviscosity_plan import evaluations
from swe_sphere.simulation.simulation import Simulation

from helpers import cli_one_line, make_sim

DT = 1800.0


def tc5(every, steps=6, stepper="kgu35"):
    """TC5 on ne 2 np 4 (its ∇⁴ at the e-folding rule's ν), ``steps`` steps of 30 min."""
    return load_scene(
        "tc5_mountain",
        ne=2,
        np_=4,
        dt=DT,
        days=steps * DT / DAY,
        stepper=stepper,
        overrides={"hyperviscosity.every": every, "output.every_days": steps * DT / DAY},
    )


@pytest.mark.parametrize("k", [1, 3])
@pytest.mark.parametrize("stepper", ["kgu35", "fbrk32", "imex"])
def test_every_k_steps_is_k_steps_of_dynamics_then_the_hyperviscosity_over_k_dt(stepper, k):
    """k steps with every = k: the state of k steps without the ∇⁴ (every = 1000, none due yet)
    and then ``model.hyperviscosity`` over kΔt, to the bit (k = 1: every step, as without the
    key); after k − 1 steps, no ∇⁴."""
    sparse, bare = make_sim(tc5(k, stepper=stepper)), make_sim(tc5(1000, stepper=stepper))
    assert sparse.model.hv.every == k
    for s in (sparse, bare):
        for _ in range(k - 1):
            s.stepper.step(s.x)
    np.testing.assert_array_equal(sparse.x.numpy(), bare.x.numpy())
    sparse.stepper.step(sparse.x)
    bare.stepper.step(bare.x)
    before = bare.x.numpy().copy()
    bare.model.hyperviscosity(bare.x, k * DT)
    assert np.abs(bare.x.numpy() - before).max() > 1e-3  # the ∇⁴ did something
    np.testing.assert_array_equal(sparse.x.numpy(), bare.x.numpy())


def test_a_scene_s_model_and_stepper_stepped_by_hand_are_its_run():
    """``adjoint.gradient.scene_model``'s model, stepper and start, stepped by ``step`` (which counts
    the step), end a TC5 run with the ∇⁴ every 3 steps with the bits of the scene's run; ``advance``
    alone (the stepper's uncounted hook) never takes the ∇⁴, and ends elsewhere."""
    import warp as wp

    from swe_sphere.adjoint.gradient import scene_model

    scene = tc5(3)
    run = Simulation(scene, "cpu", progress=False)
    run.run(None)
    ends = {}
    for how in ("step", "advance"):
        model, stepper, x0 = scene_model(scene, "cpu")
        x = wp.array(x0, dtype=wp.float64, device="cpu")
        for _ in range(scene.nsteps):
            getattr(stepper, how)(x)
        ends[how] = x.numpy()
    assert scene.nsteps == 6 and stepper.steps == 0
    np.testing.assert_array_equal(ends["step"], run.x.numpy())
    assert np.abs(ends["advance"][2] - ends["step"][2]).max() > 1e-3


def test_every_one_leaves_the_scene_dict_as_before_the_key():
    """A restart file's scene (``as_dict``) holds the key only where k > 1: one written before it
    continues."""
    assert "hypervis_every" not in tc5(1).as_dict() and tc5(2).as_dict()["hypervis_every"] == 2


def test_the_graph_key_says_whether_the_step_takes_the_hyperviscosity():
    """Two graphs with every > 1: the steps that end with the ∇⁴ and those that do not."""
    sim = make_sim(tc5(3))
    keys = []
    for _ in range(6):
        keys.append(sim.stepper.graph_key())
        sim.stepper.step(sim.x)
    assert keys == [("step", DT, False), ("step", DT, False), ("step", DT, True)] * 2
    assert make_sim(tc5(1)).stepper.graph_key() == ("step", DT)


def test_a_continued_run_is_bitwise_the_uninterrupted_one(tmp_path):
    """Continued from a restart at step 4 of every = 3 (two steps before the next ∇⁴): the phase
    is the step's index, so the 8-step run's last state is the same bits."""
    whole = make_sim(dataclasses.replace(tc5(3, 8), output_every_days=4 * DT / DAY))
    whole.run(tmp_path / "whole.nc")
    half = make_sim(tc5(3, 4))
    r = half.run(tmp_path / "half.nc", restart_every=4 * DT / DAY)
    cont = Simulation.from_checkpoint(r.checkpoint, "cpu", days=8 * DT / DAY, progress=False)
    assert cont.step == 4 and cont.scene == whole.scene
    cont.run(tmp_path / "cont.nc")
    np.testing.assert_array_equal(cont.x.numpy(), whole.x.numpy())


@pytest.mark.parametrize(
    "overrides, words",
    [
        ({"hyperviscosity.every": 0}, ("hyperviscosity.every", ">= 1 or 'auto'", "got 0")),
        ({"hyperviscosity.every": "often"}, ("hyperviscosity.every", ">= 1 or 'auto'", "often")),
        ({"hyperviscosity.every": 2, "time.stepper": "leapfrog"}, ("hyperviscosity.every = 2", "leapfrog")),
        ({"hyperviscosity.every": 2, "time.control": "error"}, ("hyperviscosity.every = 2", "fixed dt")),
    ],
)
def test_a_misfit_every_is_one_line(overrides, words):
    """every < 1, a three-level scheme, or a controlled Δt: SceneError naming the key."""
    stepper = overrides.pop("time.stepper", "dp54")
    with pytest.raises(SceneError) as err:
        load_scene("tc5_mountain", ne=2, stepper=stepper, overrides=overrides)
    assert all(w in str(err.value) for w in words), str(err.value)


@pytest.mark.parametrize(
    "scene, grid, tau, every",
    [
        ("tc5_mountain", {}, 3, 8),  # τ 3 h: at most 30 min, 8.5 steps; 8 divides a day's 408
        ("tc6_rossby_haurwitz", {}, 6, 12),  # τ 6 h: 60 min, 12 steps of 300 s, dividing 288
        ("galewsky", {}, 3, 8),  # 11 steps; none of 6..11 divides 548, 8 the 6 days' 3288
        ("tc5_mountain", {"ne": 60}, 3, 17),  # 17 steps of 105.9 s, 17 divides 816
        ("galewsky", {"stepper": "leapfrog"}, 3, 1),  # a three-level scheme: every step
        ("galewsky", {"stepper": "dp54", "overrides": {"time.control": "error"}}, 3, 1),  # a controlled Δt
    ],
)
def test_auto_takes_the_most_steps_within_a_sixth_of_the_grid_scale_e_folding(scene, grid, tau, every):
    """``every = "auto"``: the largest k with kΔt ≤ τ/6 (τ the e-folding time at the grid's
    Nyquist degree), k ≥ half that dividing an output interval's or the run's steps if one does."""
    overrides = {"hyperviscosity.every": "auto", **grid.pop("overrides", {})}
    s = load_scene(scene, overrides=overrides, **grid)
    assert s.hypervis_every == every
    assert every * s.dt <= tau * 3600 / 6 * (1 + 1e-9)  # the scene's efold_hours
    assert any(f"every {every} steps" in n for n in s.notes) == (every > 1)


def short_tc5(every, steps: int):
    """TC5 on ne 2 np 4, ``steps`` steps of 100 s (τ/6 = 30 min holds 18) with its output
    interval of a day (864 steps, which 18 divides)."""
    days = steps * 100.0 / DAY
    return load_scene("tc5_mountain", ne=2, np_=4, dt=100.0, days=days, overrides={"hyperviscosity.every": every})


def test_auto_in_a_run_shorter_than_its_span_takes_the_hyperviscosity_once_at_its_end():
    """``every = "auto"`` in a run of fewer steps than τ/6 holds: k was 18 (the day's 864 steps
    divide by it), past a run of 5 or 12 steps, which then took no ∇⁴ at all (bitwise the state
    of none), its header saying "every 18 steps". k is now the run's steps: the ∇⁴ over the
    whole run at its end, bitwise ``model.hyperviscosity`` over 5Δt after 5 steps of dynamics, as
    a run of 18 steps takes it after its 18th (HOMME's ``advance_hypervis`` runs every step: no
    run of it goes without)."""
    for steps in (5, 12, 18):
        s = short_tc5("auto", steps)
        assert (s.nsteps, s.hypervis_every) == (steps, steps)
        assert f"hyperviscosity every {steps} steps: once, at the run's end" in " ".join(s.notes)
    assert short_tc5("auto", 20).hypervis_every == 18  # longer than the span: as before
    sparse, bare = make_sim(short_tc5("auto", 5)), make_sim(short_tc5(1000, 5))  # 1000: none due
    sparse.run()
    bare.run()
    undamped = bare.x.numpy().copy()
    bare.model.hyperviscosity(bare.x, 5 * 100.0)
    np.testing.assert_array_equal(sparse.x.numpy(), bare.x.numpy())
    # the ∇⁴'s change of h (m): 0.255 at its largest (0.139 with it every step; 0 before)
    assert 0.2 < np.abs(sparse.x.numpy()[2] - undamped[2]).max() < 0.3


def test_the_command_line_refuses_a_misfit_every(capsys, tmp_path):
    """``-s hyperviscosity.every=0``: one line, exit 2, nothing written."""
    line = cli_one_line(
        capsys,
        [
            "run",
            "tc5_mountain",
            "--ne",
            "2",
            "--days",
            "0.1",
            "-s",
            "hyperviscosity.every=0",
            "--output",
            str(tmp_path / "x.nc"),
        ],
        2,
        "hyperviscosity.every",
    )
    assert line and not list(tmp_path.iterdir())


def test_a_scaled_dt_takes_the_step_count_whose_divisors_take_the_hyperviscosity_less_often():
    """A dt the grid chose is shortened where more steps cost less a day with the ∇⁴'s k and plan
    they give (``sparse_dt``): TC5 ne8 np4's odd 109 steps a day (k = 1) become 110 (k = 2);
    galewsky ne24 np6's 499, a prime (k = 6, 2 RKL1 stages), 508 (k = 8, 2 stages). A dt given,
    ``every`` not "auto", or a mesh, is not touched; the scene's own dt for naming a run's file
    (``Scene.own_dt``) is the shortened one."""
    s = load_scene("galewsky", ne=24, np_=6)
    assert (s.dt, s.hypervis_every) == (DAY / 508, 8)
    assert "dt 173.146 s shortened to 170.079 s: more steps, the ∇⁴ less often (cheaper a day)" in s.notes
    assert load_scene("galewsky", ne=24, np_=6, overrides={"hyperviscosity.every": 1}).dt == DAY / 499
    given = load_scene("galewsky", ne=24, np_=6, dt=DAY / 499)
    assert (given.dt, given.hypervis_every, given.own_dt) == (DAY / 499, 6, DAY / 508)
    tc5_ne8 = load_scene("tc5_mountain", ne=8, np_=4)
    assert (tc5_ne8.dt, tc5_ne8.hypervis_every) == (DAY / 110, 2)
    assert load_scene("tc5_mountain", ne=30, np_=4).dt == DAY / 408  # 408 already takes k = 8
    stretched = {"grid.stretch_factor": 2.0, "grid.target_lat": 30.0, "grid.target_lon": 270.0}
    dense = {**stretched, "hyperviscosity.every": 1}
    assert (
        load_scene("tc5_mountain", ne=8, overrides=stretched).dt == load_scene("tc5_mountain", ne=8, overrides=dense).dt
    )


def test_the_shortened_dt_is_the_cheapest_whole_count_and_leaves_a_small_gain():
    """``sparse_dt`` itself: the least n'(1 + 0.9 e/k) over n' ≥ n whole steps of the intervals'
    common interval, k ``auto_every``'s and e the ∇⁴'s evaluations over kΔt (``evaluations``);
    n kept where the best saves < 2 % or dt is not a whole count of it."""
    span = 1800.0  # s: k·dt at most 30 min
    assert auto_every(span, DAY / 499, (499, 2994)) == 6  # 2994 = 2·3·499: 6 the largest of 5..10
    assert auto_every(span, DAY / 500, (500, 3000)) == 10
    soft = 1e-6  # ν λ (s⁻¹): one forward-Euler substep over 30 min (ν λ kΔt = 0.0018)
    # a day: 499 (k 6) 499·(1 + 0.9/6) = 573.9; 500 (k 10) 500·1.09 = 545
    assert sparse_dt(DAY / 499, (6.0, 1.0), 1.0, 6.0, Span(span, 6 * span, soft, 1)) == DAY / 500
    assert (
        sparse_dt(DAY / 416, (6.0, 1.0), 1.0, 6.0, Span(span, 6 * span, soft, 1)) == DAY / 416
    )  # k 8 already: nothing pays 2 %
    assert (
        sparse_dt(DAY / 499.5, (6.0, 1.0), 1.0, 6.0, Span(span, 6 * span, soft, 1)) == DAY / 499.5
    )  # not whole steps of a day
    # stiff, ν λ = 3e-3 s⁻¹: k 6 over 17.3 min takes 2 RKL1 stages, k 10 over 28.8 min 3
    stiff = 3e-3
    assert evaluations(stiff * 6 * DAY / 499, 1) == (2, True) and evaluations(stiff * 10 * DAY / 500, 1) == (3, True)
    # 499: 499·(1 + 0.9·2/6) = 648.7; 500: 500·(1 + 0.9·3/10) = 635; 508 (k 8, 2 stages): 622.3, the least
    assert sparse_dt(DAY / 499, (6.0, 1.0), 1.0, 6.0, Span(span, 6 * span, stiff, 1)) == DAY / 508
