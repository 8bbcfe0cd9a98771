"""The tracers' ∇⁴ inside every stage (issue 125; ``tracers.stage_hyperviscosity``, HOMME's
``advance_nonstag_rk``): the same operator as the split ∇⁴, the limiter's bounds met, a restart
bitwise, bad values refused in one line (q = 1 and the masses kept: tests/model/test_tracers.py's
``test_q_one_stays_one_and_each_tracer_mass_is_conserved``)."""

import numpy as np
import pytest
import xarray as xr

from swe_sphere import Simulation
from swe_sphere.cases.tracers import TRACER_FIELDS
from swe_sphere.cli import main
from swe_sphere.config.scene import SceneError, load_scene, with_days
from swe_sphere.core.errors import ArgumentError
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.steppers.butcher import TABLES, real_axis_limit

from helpers import DEFORMATIONAL_FLOW, cached_grid, make_sim
from roundoff import bound, mass_change_bound, within

ONE_AND_HILLS = {"names": ["one", "hills"], "initial": ["constant", "gaussian_hills"]}


def _tc5_model(stage: bool, per_element: bool = True):
    """TC5 ne3 np4's model with its ν, ν_s and topography, two tracers (q = 1 and the hills), and its
    initial state."""
    scene = load_scene("tc5_mountain", ne=3, np_=4, stepper="ssprk3")
    grid, case = cached_grid(3, 4), scene.make_case()
    hv = {"nu": scene.nu, "nu_div": scene.nu_div, "nu_s": scene.nu_s}
    model = ShallowWater.from_case(
        grid, case, scene.terms, tracers=2, threads=1, per_element=per_element, stage_hyperviscosity=stage, **hv
    )
    u, v, h = case.initial(grid.lat, grid.lon)
    q = TRACER_FIELDS["gaussian_hills"](grid.lat, grid.lon)
    return model, model.new_state(u, v, h, masses=np.stack([h, h * q]))


@pytest.mark.parametrize("per_element", [True, False])
def test_the_stage_hyperviscosity_is_the_split_operator_in_the_right_hand_side(per_element):
    """F with the ∇⁴ in the stages less F without it is −ν_s ∇⁴ of h + hs and of each q(h + hs),
    the operator the split ∇⁴ applies: one forward-Euler substep of it over a short dt (here one
    substep, (x' − x) / dt = −B x) agrees in the depth's and the tracers' rows to the rounding that
    difference leaves (a few ε |x| / (dt |B x|)), both layouts and topography (TC5); the wind's
    rows are untouched (its ν stays split)."""
    staged, x = _tc5_model(True, per_element)
    split, _ = _tc5_model(False, per_element)
    with_hv, without = (staged.new_state() for _ in range(2))
    staged.rhs(x, with_hv)
    split.rhs(x, without)
    dt = 300.0  # s: one substep (``forward_euler_substeps``)
    assert split.hv.plan(dt) == (1, False)
    after = staged.new_state()
    after.assign(x)
    split.hv.apply(after, dt)
    expected = (after.numpy() - x.numpy()) / dt
    got = with_hv.numpy() - without.numpy()
    assert np.array_equal(got[:2], np.zeros_like(got[:2]))
    for row in (2, 3, 4):
        scale = np.abs(expected[row]).max()
        assert scale > 1e-9  # the ∇⁴ acts on this row
        # x' − x rounds x' by ε |x|, which the difference divides by dt; the operators' own roundings are less
        limit = 4 * np.finfo(float).eps * np.abs(x.numpy()[row]).max() / (dt * scale)
        within(np.abs(got[row] - expected[row]).max() / scale, limit, f"row {row}'s stage ∇⁴ against the split one")


@pytest.mark.roundoff
def test_the_limiter_meets_its_bounds_with_the_stage_hyperviscosity(tmp_path):
    """The deformational flow on ne4 np4 for a day and a half (Δt 1800 s, SSPRK(4,3), HOMME's ν_s
    in every stage, limited with each stage's transport as HOMME's advance_nonstag_rk does):
    the bells and the cylinders stay within their initial range to round-off (a few roundings of
    max|q| a step, as with the split ∇⁴), q = 1 within round-off, each mass kept."""
    tracers = {"names": ["bells", "cylinders", "one"], "initial": ["cosine_bells", "slotted_cylinders", "constant"]}
    over = {
        **DEFORMATIONAL_FLOW,
        "output.every_days": 1.5,
        "tracers.limiter": "optimization",
        "tracers.stage_hyperviscosity": True,
        "time.stepper": "ssprk43",
    }
    scene = load_scene("tc2_steady", ne=4, np_=4, days=1.5, dt=1800.0, overrides=over, tracers=tracers)
    assert scene.tracer_stage_hyperviscosity and scene.as_dict()["tracer_stage_hyperviscosity"] is True
    sim = make_sim(scene)
    sim.run(tmp_path / "flow.nc")
    with xr.open_dataset(tmp_path / "flow.nc", decode_times=False) as ds:
        steps = int(ds.steps[-1])
        for name in tracers["names"]:
            q0, q = ds[name].values[0], ds[name].values[-1]
            span = q0.max() - q0.min() or 1.0
            outside = max(q0.min() - q.min(), q.max() - q0.max(), 0.0) / span
            within(outside, bound(8 * steps, np.abs(q0).max() / span), f"{name} beyond its initial range")
            change = float(np.abs(ds[f"{name}_mass_change"]).max())
            within(change, mass_change_bound(8 * steps, sim.grid.nnodes), f"{name}'s mass change")
        assert np.abs(ds.bells.values[-1] - ds.bells.values[0]).max() > 1e-3  # the bells were moved and back


def test_a_restart_with_the_stage_hyperviscosity_is_bitwise(tmp_path):
    """Galewsky ne2 np4 with two tracers and ν_s in the stages, to day 0.25 at once and in two
    halves through a restart file: the same final state to the bit (the key rides the file)."""
    tracers = {**ONE_AND_HILLS, "stage_hyperviscosity": True}
    scene = load_scene("galewsky", ne=2, np_=4, days=0.25, output={"every_days": 0.125}, tracers=tracers)
    whole = make_sim(scene)
    whole.run(tmp_path / "whole.nc")
    half = make_sim(with_days(scene, 0.125))
    half.run(tmp_path / "half.nc", restart_every=0.125)
    rest = Simulation.from_checkpoint(tmp_path / "half.restart.nc", days=0.25, device="cpu", progress=False)
    assert rest.scene.tracer_stage_hyperviscosity
    rest.run(tmp_path / "rest.nc")
    assert np.array_equal(rest.x.numpy(), whole.x.numpy())


@pytest.mark.parametrize(
    "scene, tracers, words",
    [
        ("tc2_steady", {"stage_hyperviscosity": True}, ["tracers.stage_hyperviscosity", "hyperviscosity term"]),
        ("galewsky", {"stage_hyperviscosity": True, "hyperviscosity": False}, ["tracers.hyperviscosity = true"]),
        ("galewsky", {"stage_hyperviscosity": "yes"}, ["tracers.stage_hyperviscosity"]),
    ],
)
def test_a_bad_stage_hyperviscosity_is_refused_in_one_line(scene, tracers, words):
    """true without a ∇⁴ on the tracers (no hyperviscosity term, or tracers.hyperviscosity false),
    or a value not a boolean: one line naming the key. The default, false, is left out of the
    scene's record (a restart written before the key reads the same)."""
    with pytest.raises(SceneError) as err:
        load_scene(scene, ne=2, np_=4, tracers={**ONE_AND_HILLS, **tracers})
    assert "\n" not in str(err.value)
    for word in words:
        assert word in str(err.value)
    assert "tracer_stage_hyperviscosity" not in load_scene("galewsky", ne=2, np_=4, tracers=ONE_AND_HILLS).as_dict()


def test_the_model_refuses_a_stage_hyperviscosity_without_its_parts():
    """``ShallowWater``: stage_hyperviscosity without tracers or without the ∇⁴ term is refused."""
    grid = cached_grid(2, 4)
    zeros = np.zeros(grid.nnodes)
    with pytest.raises(ArgumentError, match="stage_hyperviscosity needs tracers"):
        ShallowWater(grid, ["continuity", "hyperviscosity"], zeros, zeros, nu=1e15, stage_hyperviscosity=True)
    with pytest.raises(ArgumentError, match="stage_hyperviscosity needs tracers"):
        ShallowWater(grid, ["continuity"], zeros, zeros, tracers=1, stage_hyperviscosity=True)


def test_the_real_axis_limits_of_the_tables():
    """``butcher.real_axis_limit``: forward Euler's 2, and for SSP-RK3, RK4 and SSPRK(4,3) the
    least x > 0 where R(−x) = ±1 (R from the table's b and A in floats, its roots by numpy:
    ≈ 2.513, 2.785, 5.149), where |R| first passes 1 for these tables."""
    assert real_axis_limit([[0]], [1]) == pytest.approx(2.0, abs=1e-9)
    for name, near in (("ssprk3", 2.513), ("rk4", 2.785), ("ssprk43", 5.149)):
        A, b = TABLES[name].floats()[:2]
        c = [1.0] + [float(b @ np.linalg.matrix_power(A, k - 1) @ np.ones(len(b))) for k in range(1, len(b) + 1)]
        R = np.polynomial.Polynomial([ck * (-1) ** k for k, ck in enumerate(c)])  # R(−x)
        roots = np.concatenate([(R - 1).roots(), (R + 1).roots()])
        edge = min(r.real for r in roots if abs(r.imag) < 1e-9 and r.real > 1e-9)
        assert edge == pytest.approx(near, abs=1e-3)
        assert real_axis_limit(TABLES[name].A_E, TABLES[name].b_E) == pytest.approx(edge, abs=1e-8), name


def test_a_stage_hyperviscosity_past_the_steppers_stability_is_refused(tmp_path, capsys):
    """ν_s in the stages with ν_s Δt λ past the stepper's real-axis limit: ``swe-sphere run``
    exits 2 with one line naming the key and writes no file; the scene's own ν_s runs."""
    out = tmp_path / "run.nc"
    args = ["run", "galewsky_marker", "--ne", "2", "--np", "4", "--days", "0.01", "--no-progress", "--output", str(out)]
    stage = ["-s", "tracers.stage_hyperviscosity=true"]
    assert main([*args, "-s", "hyperviscosity.nu_s=1e19", *stage]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "tracers.stage_hyperviscosity" in err[0] and "negative real axis" in err[0], err
    assert not out.exists()
    assert main([*args, *stage]) == 0 and out.exists()  # the scene's own ν_s: stable in the stages
