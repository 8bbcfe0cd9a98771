"""Steps that choose themselves (``integrator.control.StepControl``) on TC2 (exact solution),
ne 4, under ``control = "error"`` with bs32: the error against the exact solution falls with
rtol, the run ends exactly at its day, and a run stopped at a day and continued from the
stepper's and the control's state gives the same bits as one that did not stop. The default
Courant cap: it keeps TC5 at a loose tolerance stable, and where it does not bind the steps are
the error controller's alone, bit for bit."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import BlowUp
from swe_sphere.core.tally import Tally, instrumented
from swe_sphere.integrator.control import CAP_EVERY, DT_GRID, StepControl
from swe_sphere.model.diagnostics import courant_numbers
from swe_sphere.steppers.control import ATOL_FLOOR, BALANCE_EVERY

from helpers import assert_same_runs, make_sim, watched_run


def _sim(rtol, days=1.0, **keys):
    overrides = {"time.control": "error", "time.rtol": rtol, **{f"time.{k}": v for k, v in keys.items()}}
    sim = make_sim(load_scene("tc2_steady", ne=4, days=days, stepper="bs32", overrides=overrides))
    return sim, StepControl(sim.scene.control, sim.core.units[0], sim.scene.start_day)


def _run(sim, control, t, target):
    while t < target:
        t, _ = control.step(sim.x, t, target)
    return t


def _l2_h(sim, t):
    return sim.members.diagnose(t)["l2_h"]


def test_the_error_falls_with_rtol_and_the_run_ends_at_its_day():
    """The error controller alone (no Courant cap: the default one binds at rtol 1e-2 and 1e-3
    here, ``test_the_default_cap_...``): against the exact solution the error falls from rtol
    1e-2 to 1e-3 (3.79e-4 to 1.66e-4 in l2 of h: by 1e-3 the grid's own error, 1.66e-4, is all
    of it); against a run at rtol 1e-7 (the time-converged state of this grid) the largest h
    difference falls with rtol (0.27 m at 1e-4, 4.5e-3 m at 1e-6)."""
    runs = {}
    for rtol in (1e-2, 1e-3, 1e-4, 1e-6, 1e-7):
        sim, control = _sim(rtol, cfl=False)
        assert _run(sim, control, 0.0, DAY) == DAY  # landed exactly
        assert sum(dt for _, dt, _ in control.history) == pytest.approx(DAY, rel=1e-13)
        assert all(err <= 1.0 for _, _, err in control.history)
        runs[rtol] = (_l2_h(sim, DAY), sim.x.numpy()[2], control.accepted)
    assert runs[1e-3][0] < runs[1e-2][0] / 2
    assert runs[1e-3][0] == pytest.approx(1.66e-4, rel=0.01)
    far, near = (np.abs(runs[r][1] - runs[1e-7][1]).max() for r in (1e-4, 1e-6))
    assert near < far / 20 and runs[1e-6][2] > runs[1e-4][2]


def test_a_stopped_run_continues_bitwise():
    whole, control = _sim(1e-5)
    _run(whole, control, 0.0, DAY)
    first, control1 = _sim(1e-5)
    _run(first, control1, 0.0, 0.5 * DAY)  # an output time: the step before it is cut to land
    state, stepper_state, x = control1.state(), first.stepper.state(), first.x.numpy()
    second, control2 = _sim(1e-5)
    second.x.assign(x)
    second.stepper.restore(stepper_state)
    control2.restore(state)
    _run(second, control2, 0.5 * DAY, DAY)
    assert control2.accepted > control1.accepted
    # stopping at day 0.5 cuts one step there; the whole run's steps near it differ, so compare
    # the continued run with one stopped at the same day in one process
    again, control3 = _sim(1e-5)
    t = _run(again, control3, 0.0, 0.5 * DAY)
    _run(again, control3, t, DAY)
    assert np.array_equal(second.x.numpy(), again.x.numpy())
    assert control2.state() == control3.state()


def test_a_step_below_dt_min_stops_as_a_blow_up():
    sim, control = _sim(1e-12, dt_min=100.0)
    with pytest.raises(BlowUp, match=r"^step 1 at day 0: the controller's dt .* fell below time.dt_min = 100 s"):
        _run(sim, control, 0.0, DAY)


def test_cfl_control_steps_at_the_requested_courant_number():
    """TC2 ne 2, ssprk3 under ``control = "cfl"`` at cfl 1.2 from a step a third of it: the
    step grows by at most 1.1 a step, then holds the signal's Courant number (advective +
    gravity-wave, as ``courant_numbers`` gives them) at the target, at most one notch of the
    controller's Δt grid (2^(−1/16)) below it."""
    overrides = {"time.control": "cfl", "time.cfl": 1.2}
    sim = make_sim(load_scene("tc2_steady", ne=2, days=10.0, stepper="ssprk3", dt=2000.0, overrides=overrides))
    control = StepControl(sim.scene.control, sim.core.units[0], sim.scene.start_day)
    t = 0.0
    for _ in range(20):
        t, _ = control.step(sim.x, t, 10 * DAY)
    dts = [dt for _, dt, _ in control.history]
    assert all(b <= 1.1 * a for a, b in zip(dts, dts[1:])) and dts[-1] > 2.5 * dts[0]
    u, v, h = sim.fields()
    courant = control.cfl.courant(courant_numbers(sim.grid, u, v, h, dts[-1], sim.g))
    assert 1.2 * 2 ** (-1 / DT_GRID) * (1 - 1e-3) <= courant <= 1.2 * (1 + 1e-3)
    assert dts[-1] == dts[-2]  # TC2 is steady: the same step again


def _cli_run(path, *extra, days=1.0):
    from swe_sphere.cli import main

    args = ["run", "tc2_steady", "--ne", "4", "--stepper", "bs32", "--days", str(days), "-s", "time.control=error"]
    args += ["-s", "output.every_days=0.25", "--output", str(path), "--no-cells", "--no-progress", "--device", "cpu"]
    return main([*args, *map(str, extra)])


def _series(path, *names):
    import netCDF4

    with netCDF4.Dataset(path) as ds:
        return [np.asarray(ds[n][:]) for n in names]


def test_the_cli_run_lands_on_its_output_times_and_records_the_control(tmp_path):
    """Through ``swe-sphere run``: the run file's times are the output times (the steps cut to
    land on them), its l2 error of h falls from rtol 1e-2 to 1e-3 (3.89e-4 to 1.66e-4; 4.1e-4
    at 1e-2 without the landings at 0.25, 0.5, 0.75), and a first step of 20000 s is rejected
    and recorded."""
    l2 = {}
    for rtol in (1e-2, 1e-3):  # the error controller alone: the default Courant cap binds at both
        assert _cli_run(tmp_path / f"r{rtol}.nc", "-s", f"time.rtol={rtol}", "-s", "time.cfl=false") == 0
        time, err, dt = _series(tmp_path / f"r{rtol}.nc", "time", "l2_h", "dt")
        assert time.tolist() == [0.0, 0.25, 0.5, 0.75, 1.0]
        assert np.isnan(dt[0]) and (dt[1:] > 0).all()
        l2[rtol] = err[-1]
    assert l2[1e-2] == pytest.approx(3.26e-4, rel=0.01) and l2[1e-3] == pytest.approx(1.66e-4, rel=0.01)
    assert _cli_run(tmp_path / "big.nc", "-s", "time.rtol=1e-3", "--dt", 20000) == 0
    rejected, err, steps = _series(tmp_path / "big.nc", "rejected_steps", "error_estimate", "steps")
    assert rejected[0] == 0 and rejected[-1] >= 1 and (err[1:] <= 1).all() and steps[-1] > 4


def test_a_controlled_run_s_courant_numbers_are_at_the_controller_s_dt():
    """The Courant numbers a controlled run reports (its run file's at each output time, its log's,
    its summary's) are those of the step the controller goes on with (``StepControl.dt``), not of
    the scene's first Δt (1200 s here; the controller ends the half day at about 965 s)."""
    sim, control = _sim(1e-5, days=0.5)
    _run(sim, control, 0.0, 0.5 * DAY)
    sim.control = control
    u, v, h = sim.fields()
    expected = courant_numbers(sim.grid, u, v, h, control.dt, sim.g, True)
    assert abs(control.dt / sim.scene.dt - 1) > 0.1 and sim.courant() == pytest.approx(expected, rel=1e-12)


def test_steps_are_refused_under_step_control_and_advance_lands_on_the_day():
    """``steps`` raised a plain ValueError naming ``until_step``, an argument the user never
    gives; ``advance`` was refused too, where an ensemble's landed on the day (issue 116: one
    driver): under step control it lands on the day asked, the run's steps the controller's."""
    from swe_sphere.core.errors import ArgumentError

    sim, _ = _sim(1e-5, days=0.125)
    with pytest.raises(ArgumentError, match="^Simulation.steps steps a fixed dt: under step control"):
        next(sim.steps(0.05))
    assert sim.step == 0
    sim.advance(0.05)
    assert sim.time == 0.05 and sim.control.accepted == sim.step > 1


def test_a_cli_continuation_is_bitwise_the_uninterrupted_run(tmp_path):
    """``--restart-every`` then ``--continue``: a run stopped at day 1 and continued to day 2
    holds at day 2 the bits of one run to day 2, its Δt and counts alike (both land on days
    0.25, 0.5, ... and 1)."""
    from swe_sphere.cli import main

    assert _cli_run(tmp_path / "whole.nc", "-s", "time.rtol=1e-4", "--restart-every", 0.5, days=2) == 0
    assert _cli_run(tmp_path / "first.nc", "-s", "time.rtol=1e-4", "--restart-every", 0.5, days=1) == 0
    args = ["run", "--continue", tmp_path / "first.restart.nc", "--days", 2, "--output", tmp_path / "second.nc"]
    assert main([*map(str, args), "--no-cells", "--no-progress", "--device", "cpu"]) == 0
    names = ("time", "h", "u", "dt", "steps", "rejected_steps", "error_estimate")
    whole, second = _series(tmp_path / "whole.nc", *names), _series(tmp_path / "second.nc", *names)
    assert second[0].tolist() == [1.25, 1.5, 1.75, 2.0]
    for a, b in zip(whole, second):
        np.testing.assert_array_equal(a[-4:], b)


def test_a_step_below_dt_min_stops_the_cli_run_as_a_blow_up(tmp_path, capsys):
    code = _cli_run(tmp_path / "r.nc", "-s", "time.rtol=1e-12", "-s", "time.dt_min=100")
    assert code == 3
    assert "fell below time.dt_min = 100 s" in capsys.readouterr().err
    (time,) = _series(tmp_path / "r.nc", "time")
    assert time.tolist() == [0.0]  # the good output kept


def test_the_default_cap_binds_at_a_loose_tolerance_and_nowhere_else():
    """TC2 ne 4, bs32: the default cap is 0.9 × bs32's measured Courant limit 1.11; at rtol 1e-2
    it sets the next Δt after 39 of 40 steps (the error controller alone takes 31 steps of up to
    5087 s, 2.3 × the capped 2233 s) and the error is the grid's (1.654e-4 in l2 of h, against
    3.79e-4 uncapped); at rtol 1e-5 it never binds and the run is the uncapped one, bit for bit,
    its Courant pass taken once in ``CAP_EVERY`` + 1 steps (the proposals far below the cap)."""
    capped, control = _sim(1e-2)
    assert control.cfl.cfl == pytest.approx(0.999) and control.cfl.max_change == math.inf
    _run(capped, control, 0.0, DAY)
    assert (control.accepted, control.capped) == (40, 39)
    assert _l2_h(capped, DAY) == pytest.approx(1.654e-4, rel=1e-3)
    u, v, h = capped.fields()
    assert control.cfl.courant(courant_numbers(capped.grid, u, v, h, control.dt_largest, capped.g)) <= 0.999
    for cfl in (None, False):
        keys = {} if cfl is None else {"cfl": cfl}
        sim, control = _sim(1e-5, **keys)
        _run(sim, control, 0.0, DAY)
        assert control.capped == 0
        if cfl is None:
            x, passes, steps = sim.x.numpy(), control.courant_passes, control.accepted
    assert np.array_equal(x, sim.x.numpy())
    assert passes == -(-steps // (CAP_EVERY + 1)), (passes, steps)  # the cap far: one pass in CAP_EVERY + 1 steps


def test_the_default_cap_keeps_a_loose_tolerance_stable():
    """TC5 ne 8, dp54 at rtol 10, a tolerance that asks nothing (as docs/explanation/efficiency/error_control.md's ne16
    blow-up at rtol 1e-2 with the pair's estimate of before its last stage was carried
    over): without a cap the controller lets the step past dp54's stability limit and the run
    stops at step 48, day 0.537, its step below dt_min (step 23, day 0.146, while the ∇⁴ over those
    steps took forward-Euler substeps where RKL1 now takes fewer stages); under the default cap (0.9 × 1.28) it
    runs its 1.5 days, 123 steps, none rejected. An explicit time.cfl is the cap instead, with
    the growth bound of a CFL target."""

    def tc5(**keys):
        overrides = {"time.control": "error", "time.rtol": 10.0, **{f"time.{k}": v for k, v in keys.items()}}
        sim = make_sim(load_scene("tc5_mountain", ne=8, np_=4, days=1.5, stepper="dp54", overrides=overrides))
        return sim, StepControl(sim.scene.control, sim.core.units[0], sim.scene.start_day)

    sim, control = tc5(cfl=False)
    with pytest.raises(BlowUp, match=r"^step 48 at day 0.5370.* fell below time.dt_min"):
        _run(sim, control, 0.0, 1.5 * DAY)
    sim, control = tc5()
    assert _run(sim, control, 0.0, 1.5 * DAY) == 1.5 * DAY
    assert (control.accepted, control.rejected) == (123, 0) and control.capped >= 120
    assert "the Courant cap 1.15 set the next dt after" in control.summary()
    _, control = tc5(cfl=0.5)
    assert (control.cfl.cfl, control.cfl.max_change) == (0.5, 1.1)


def _balanced(balance, days=1.0):
    overrides = {"time.control": "balanced", "time.balance": balance}
    sim = make_sim(load_scene("tc5_mountain", ne=4, days=days, stepper="rk43", overrides=overrides))
    return sim, StepControl(sim.scene.control, sim.core.units[0], sim.scene.start_day)


def test_a_balanced_run_follows_its_fraction_and_continues_bitwise():
    """``control = "balanced"`` on TC5 ne 4 (rk43): every try's absolute tolerances are the
    fraction × Δt × the spatial rate's scales (``Balance``), re-estimated every
    ``BALANCE_EVERY`` accepted steps; a smaller fraction takes more steps and comes nearer a
    run at a third of it; and a run stopped at day 0.5 (mid-way between two estimates) and
    continued from the control's state (a fresh simulation and control restored from it) gives
    the bits of the run that went on."""
    runs = {}
    for balance in (0.3, 0.03, 0.01):
        sim, control = _balanced(balance)
        assert _run(sim, control, 0.0, DAY) == DAY
        b = control.balance
        assert b.sigma.min() > 0 and b.since == (control.accepted - 1) % BALANCE_EVERY + 1
        atol = np.maximum(balance * control.dt_last * b.sigma, ATOL_FLOOR)
        np.testing.assert_array_equal(control.norm.atol.numpy(), atol)  # the last try's, which landed
        runs[balance] = (sim.x.numpy(), control.accepted)
    far, near = (np.abs(runs[b][0][2] - runs[0.01][0][2]).max() for b in (0.3, 0.03))
    assert runs[0.03][1] > runs[0.3][1] and near < far / 3, (near, far)
    whole, control = _balanced(0.03)
    t = _run(whole, control, 0.0, 0.5 * DAY)  # stopped at day 0.5: its state (copies) seeds a fresh run
    assert control.balance.since not in (0, BALANCE_EVERY)
    state, stepper_state, x = control.state(), whole.stepper.state(), whole.x.numpy().copy()
    second, control2 = _balanced(0.03)
    second.x.assign(x)
    second.stepper.restore(stepper_state)
    control2.restore(state)
    _run(second, control2, 0.5 * DAY, DAY)
    _run(whole, control, t, DAY)
    assert np.array_equal(second.x.numpy(), whole.x.numpy())
    assert control2.state() == control.state()


def test_the_run_file_records_the_balanced_mode_s_spatial_rate(tmp_path):
    """``spatial_rate`` at each output time: the balanced control's last estimate (NaN at the
    start, before any; finite and positive after), NaN under error control."""
    from swe_sphere.cli import main

    args = ["run", "tc2_steady", "--ne", "4", "--stepper", "bs32", "--days", "1", "-s", "output.every_days=0.25"]
    args += ["--no-cells", "--no-progress", "--device", "cpu"]
    assert main([*args, "-s", "time.control=balanced", "--output", str(tmp_path / "b.nc")]) == 0
    assert main([*args, "-s", "time.control=error", "--output", str(tmp_path / "e.nc")]) == 0
    (rate,) = _series(tmp_path / "b.nc", "spatial_rate")
    assert np.isnan(rate[0]) and np.all(rate[1:] > 0) and np.all(np.isfinite(rate[1:]))
    assert np.all(np.isnan(_series(tmp_path / "e.nc", "spatial_rate")[0]))


@pytest.mark.parametrize("mode", ["error", "balanced"])
def test_a_controlled_step_reads_the_device_once_a_try(tally, mode):
    """Issue 64's read-back, counted (``core.tally``: each ``.numpy()``, a host synchronisation
    on CUDA): TC5 ne4 under control started at 5x its Δt (steps rejected), one day. Each try
    reads once (the error norm's per-block sums), the Courant cap's pass once where it runs
    (skipped where it cannot bind: a few steps in a hundred), and the balanced mode's
    spatial-rate estimate twice (F and x) every ``BALANCE_EVERY`` accepted steps: nothing else."""
    overrides = {"time.control": mode, **({"time.rtol": 1e-4} if mode == "error" else {})}
    scene = load_scene("tc5_mountain", ne=4, days=1.0, stepper="rk43", overrides=overrides)
    sim = make_sim(dataclasses.replace(scene, dt=5 * scene.dt))
    control = StepControl(sim.scene.control, sim.core.units[0], sim.scene.start_day)
    with tally.counting():
        assert _run(sim, control, 0.0, DAY) == DAY
    tries = control.accepted + control.rejected
    estimates = 1 + (control.accepted - 1) // BALANCE_EVERY if mode == "balanced" else 0  # before steps 1, 17, …
    assert control.rejected > 0 and 0 < control.courant_passes < control.accepted / 10
    assert tally.syncs == tries + control.courant_passes + 2 * estimates


def test_per_unit_step_makes_the_error_follow_rtol_where_the_split_hyperviscosity_sets_it():
    """dp54 on TC5 (ne2, half a day), where the ∇⁴ step split after the pair's stages sets the
    error (first order), which the carried estimate sees as O(Δt²) a step: controlled per step
    (the default) the error falls as rtol^(1/2) (3.4x a decade from 1e-5, Δt ∝ rtol^(1/2): q =
    p/(p + 1), p = 1), per unit step (``time.per_unit_step``: ‖e‖ · 1 day / Δt) as rtol (12.1x
    a decade from 1e-2; Shampine 2005, J. Sci. Comput. 25:3). h against dp54 at rtol 1e-8 per
    step."""

    def h(rtol, per_unit_step):
        overrides = {"time.control": "error", "time.rtol": rtol, "time.per_unit_step": per_unit_step}
        sim = make_sim(load_scene("tc5_mountain", ne=2, days=0.5, stepper="dp54", overrides=overrides))
        sim.run(None)
        assert all(err <= 1.0 for _, _, err in sim.control.history)
        return sim.x.numpy()[2]

    ref = h(1e-8, False)

    def error(rtol, per_unit_step):
        return np.sqrt(np.mean((h(rtol, per_unit_step) - ref) ** 2) / np.mean(ref**2))

    per_step = error(1e-5, False) / error(1e-6, False)
    per_unit_step = error(1e-2, True) / error(1e-3, True)
    assert 2.5 < per_step < 4.5 and 8 < per_unit_step < 15, (per_step, per_unit_step)


def _imex_day(rtol, loose=False):
    """TC5 ne4 under error control with ark436 at ``rtol`` over a quarter day: (CG tolerance, accepted,
    rejected); ``loose``: the Helmholtz CG kept at its scene tolerance (1e-6)."""
    overrides = {"time.control": "error", "time.rtol": rtol}
    scene = load_scene("tc5_mountain", ne=4, days=1.0, stepper="ark436", overrides=overrides)
    sim = make_sim(scene)
    control = StepControl(scene.control, sim.core.units[0], scene.start_day)
    if loose:
        sim.stepper.helmholtz.tol = sim.stepper.options.tol
    _run(sim, control, 0.0, DAY / 4)
    return sim.stepper.helmholtz.tol, control.accepted, control.rejected


def test_an_imex_pair_s_helmholtz_solve_follows_the_tolerance():
    """Under error control an IMEX pair's CG solves to a hundredth of rtol (``ImexRK.follow_tolerance``):
    at the CG's own 1e-6 its error, which enters the estimate through the stages' L Y, made a
    tolerance of 1e-7 reject more tries than it accepted (161 for 142 steps); followed, one
    (37 steps)."""
    tol, accepted, rejected = _imex_day(1e-7)
    assert tol == pytest.approx(1e-9, rel=1e-12) and rejected <= 1
    tol, accepted_loose, rejected_loose = _imex_day(1e-7, loose=True)
    assert tol == 1e-6 and rejected_loose > 0.5 * accepted_loose and accepted_loose > 2 * accepted
    assert _imex_day(1e-4)[0] == 1e-6  # looser than the CG: as the scene says


def _per_unit_step(name, rtol, days, solver_tolerance_kept=False):
    """TC5 ne4 under error control per unit step (``time.per_unit_step``, rtol a day's) with
    ``name`` over ``days``: (the simulation, its control); ``solver_tolerance_kept``: the
    IMEX pair's CG at the per-step 0.01 rtol, as before it followed Δt / 1 day."""
    overrides = {"time.control": "error", "time.rtol": rtol, "time.per_unit_step": True}
    scene = load_scene("tc5_mountain", ne=4, days=days, stepper=name, overrides=overrides)
    sim = make_sim(scene)
    control = StepControl(scene.control, sim.core.units[0], scene.start_day)
    if solver_tolerance_kept:
        sim.stepper.helmholtz.tol = 0.01 * rtol
    _run(sim, control, 0.0, days * DAY)
    return sim, control


def test_per_unit_step_runs_the_jfnk_stepper_and_holds_an_imex_pair_s_cg_to_a_step_s_share():
    """Per unit step a step's error is held to Δt / 1 day of the tolerance. The JFNK stepper's
    first step (Heun's predictor, an estimate of TR's order: ``test_implicit``) now passes at a
    day's rtol 1e-4 (with forward Euler's second-order estimate its norm fell only linearly with
    Δt: 1579 → 0.71 s in five tries, below dt_min, a blow-up at step 1). An IMEX pair's CG solves to
    0.01 rtol × Δt / 1 day of its first step: at 0.01 rtol, ``ark324`` rejected 59 tries for 207
    steps over half a day here, now 1 for 164 (the JFNK stepper: 427 steps, 2 rejected, the
    shortest 11.4 s)."""
    sim, control = _per_unit_step("implicit", 1e-4, 0.1)
    assert control.accepted > 100 and control.rejected <= 2 and control.dt_smallest > 10.0
    sim, control = _per_unit_step("ark324", 1e-4, 0.5)
    first = sim.scene.dt
    assert sim.stepper.helmholtz.tol == pytest.approx(0.01 * 1e-4 * first / DAY, rel=1e-12)
    kept = _per_unit_step("ark324", 1e-4, 0.5, solver_tolerance_kept=True)[1]
    assert control.rejected <= 2 < 0.05 * kept.accepted < kept.rejected, (
        control.rejected,
        kept.rejected,
        kept.accepted,
    )


def test_a_run_with_tries_launched_ahead_is_bitwise_the_run_without(tmp_path):
    """``StepControl.lookahead`` (on by default on CUDA only) forced on a CPU: TC5 ne4 ``rk43`` at
    rtol 1e-4 started at 5× its Δt (steps rejected), outputs every 0.25 day (landings), a
    callback every 10 steps and a log (``watched_run``): the run file, the final state, the
    callbacks' and the log's states bitwise those of the run without it, the same steps, tries
    and RHS evaluations. Most steps are tries launched ahead; some were undone (a rejection, a
    new Δt), and none were launched before an output or a callback. The Courant cap's passes
    are those of the run without, most of them queued before the try launched ahead
    (``StepControl._cap_idle``), and few queued passes go unused."""
    overrides = {"time.control": "error", "time.rtol": 1e-4, "output.every_days": 0.25}
    scene = load_scene("tc5_mountain", ne=4, days=1.0, stepper="rk43", overrides=overrides)
    scene = dataclasses.replace(scene, dt=5 * scene.dt)
    sims, queued = [], []

    def ahead(sim):
        sim.control.lookahead = True
        sims.append(sim)
        launch = sim.control.courant.launch

        def counted(x):
            queued.append(sim.control.accepted)
            launch(x)

        sim.control.courant.launch = counted

    plain = watched_run(scene, tmp_path / "plain.nc", setup=sims.append)
    looked = watched_run(scene, tmp_path / "ahead.nc", setup=ahead)
    assert_same_runs(plain, looked)
    (first, sim) = sims
    ctl = sim.control
    assert ctl.courant_passes == first.control.courant_passes >= ctl.courant_queued > ctl.courant_passes / 2
    assert ctl.courant_queued <= len(queued) <= 1.5 * ctl.courant_queued, (len(queued), ctl.courant_queued)
    assert ctl.rejected > 0 and ctl.ahead is None
    assert ctl.accepted > ctl.ahead_taken > ctl.accepted / 2 and ctl.ahead_dropped > 0
    # a try is launched ahead only after a step that neither lands nor has a callback due
    landings, callbacks = 4, ctl.accepted // 10
    assert ctl.ahead_taken + ctl.ahead_dropped <= ctl.accepted - landings - callbacks


def test_a_step_taken_ahead_copies_no_more_than_a_step_without():
    """A try launched ahead keeps its start (x into ``xs``), and the step that takes it starts
    from there by swapping ``xs`` and ``x0`` (``last_good`` follows), not by a copy: steps of
    TC2 ne4 ``bs32`` at rtol 1e-6 held to one Δt (dt_min = dt_max = 400 s: no rejection, no
    try undone) make as many copies and memsets (``Tally.memops``) with tries launched ahead as
    without, and the same bits."""
    counts, states = [], []
    for lookahead in (False, True):
        sim, ctl = _sim(1e-6, cfl=False, dt_min=400.0, dt_max=400.0)
        ctl.lookahead = lookahead
        t = 0.0
        for _ in range(3):  # recorded and compiled outside the count
            t, _ = ctl.step(sim.x, t, DAY, quiet=True)
        rejected, taken, tally = ctl.rejected, ctl.ahead_taken, Tally()
        with instrumented(tally), tally.counting():
            for _ in range(8):
                t, _ = ctl.step(sim.x, t, DAY, quiet=True)
        assert ctl.rejected == rejected and ctl.ahead_taken - taken == (8 if lookahead else 0)
        ctl.settle(sim.x)
        assert sim.last_good is ctl.x0
        counts.append(tally.memops)
        states.append(sim.x.numpy())
    assert counts[1] == counts[0] > 0, counts
    np.testing.assert_array_equal(states[1], states[0])


def test_settling_undoes_the_try_launched_ahead_and_the_run_goes_on_bitwise():
    """``StepControl.settle`` (a run that stops, or a state about to be read): with a try
    launched ahead on the CPU, x and the stepper go back to the last accepted step's, bitwise
    those of control without lookahead (TC2 ne4 ``bs32`` at rtol 1e-6), and the steps after it
    too."""
    (a, plain), (b, ahead) = _sim(1e-6, cfl=False), _sim(1e-6, cfl=False)
    ahead.lookahead = True
    ta = tb = 0.0
    for n in range(8):
        ta, _ = plain.step(a.x, ta, DAY, quiet=True)
        tb, _ = ahead.step(b.x, tb, DAY, quiet=True)
        if n == 4:
            assert ahead.ahead is not None
            launched = b.x.numpy().copy()
            ahead.settle(b.x)
            assert ahead.ahead is None and not np.array_equal(launched, b.x.numpy())
        end = b.x if ahead.ahead is None else ahead.xs  # a try launched ahead goes on from xs
        assert ta == tb and (ahead.ahead is not None or a.stepper.steps == b.stepper.steps)
        np.testing.assert_array_equal(a.x.numpy(), end.numpy())
    assert ahead.ahead_taken > 0
