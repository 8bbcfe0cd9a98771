"""Digital-filter initialisation (Lynch & Huang 1992): ``[case] initialization = "dfi"``.

The backward integration rests on an exact symmetry of the discrete equations
(time reversal: v → −v, f → −f); the filter conserves mass to round-off, leaves
a steady state alone up to its discretisation's own imbalance, removes TC5's
impulsive-start gravity waves, is made once per sweep and never again on a
restart; bad options exit 2 with one line.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import xarray as xr

from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.members import units
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers.initialization import DigitalFilter, digital_filter
from swe_sphere.studies.sweep import Sweep, start_state

import roundoff
from helpers import cli_one_line, make_sim


def _filter(sim, f):
    """``digital_filter`` of a simulation's initial state (one rank)."""
    return digital_filter(
        f,
        sim.x.numpy().copy(),
        grid=sim.grid,
        terms=sim.scene.terms,
        fcor=sim.fcor,
        hs=sim.hs,
        g=sim.g,
        topology=sim.topology,
    )


def test_time_reversal_is_an_exact_symmetry_of_the_discrete_rhs(rng):
    """F(P x; −f) = −P F(x; f), P = diag(−1, −1, 1), to the last bit, on TC5 ne2 with
    a random perturbation: why the backward run may be a forward run of the reversed model."""
    sim = make_sim(load_scene("tc5_mountain", ne=2, days=1))
    terms = tuple(t for t in sim.scene.terms if t != "hyperviscosity")
    x = sim.x.numpy() * (1 + 0.1 * rng.standard_normal(sim.x.shape))  # any state (not even continuous)
    P = np.array([-1.0, -1.0, 1.0])[:, None]
    out = []
    for sign, state in ((1.0, x), (-1.0, P * x)):
        model = ShallowWater(sim.grid, terms, sign * sim.fcor, sim.hs, g=sim.g, device="cpu")
        tend = model.new_state()
        model.rhs(model.new_state(*state), tend)
        out.append(tend.numpy())
    assert np.abs(out[0]).max() > 0
    np.testing.assert_array_equal(out[1], -P * out[0])


def filter_mass_bound(r, nnodes: int) -> float:
    """Round-off of a filtered state's relative mass: an update of the depth per RK4 RHS
    evaluation of either run (each state's mass error at most that, Σ|w| ≈ 1) and one
    rounding per state added to the weighted sum."""
    return roundoff.mass_change_bound(r.rhs_evals + 2 * r.steps, nnodes)


@pytest.mark.roundoff
def test_steady_state_is_kept_to_its_discretisation_error():
    """TC2 (steady) with a 12 h cutoff over ±12 h: the weights sum to 1 and mass is
    kept to round-off; h and the wind change by the discrete state's own imbalance
    only, which shrinks with the grid's truncation error: max |Δh| / max h 2.6e-4
    at ne4, 2.9e-5 at ne8 (order 3.2), max |Δv| / max |v| 1.0e-3, 9.0e-5."""
    f = DigitalFilter(span_hours=24.0, cutoff_hours=12.0)
    dt, n = f.steps(1e-3)
    assert f.weights(dt, n).sum() == pytest.approx(
        1.0, abs=roundoff.bound(2 * n + 1)
    )  # 2n + 1 weights of |w| ≤ 1 summed
    change = {}
    for ne in (4, 8):
        sim = make_sim(load_scene("tc2_steady", ne=ne, days=1))
        x0 = sim.x.numpy().copy()
        r = _filter(sim, f)
        roundoff.within(abs(r.mass_change), filter_mass_bound(r, sim.grid.nnodes), f"|mass change| ne {ne}")
        change[ne] = (np.abs(r.x[2] - x0[2]).max() / x0[2].max(), np.abs(r.x[:2] - x0[:2]).max() / np.abs(x0[:2]).max())
    assert change[8][0] < 4e-5 and change[8][1] < 1.2e-4  # measured 2.9e-5, 9.0e-5
    assert change[4][0] / change[8][0] > 6 and change[4][1] / change[8][1] > 6  # measured 9.0, 11.3


def test_tc5_gravity_waves_are_removed():
    """TC5 ne8 (cutoff 24 h, span 48 h): rms ∂h/∂t at t = 0 drops 10.5x (2.03e-3 → 1.92e-4
    m/s); at day 1 (RK4, 900 s) the rms divergence drops from 4.72e-7 to 3.88e-7 s⁻¹
    (1.22x: the rest is the balanced flow's, over the mountain) and rms ∂h/∂t from
    1.54e-3 to 1.42e-4 m/s (10.8x). Mass is kept to round-off (measured 0.0)."""
    days = 1.0
    day1, before = {}, None
    for init in ("none", "dfi"):
        scene = load_scene(
            "tc5_mountain",
            ne=8,
            days=days,
            dt=900.0,
            stepper="rk4",
            overrides={"case.initialization": init, "dfi.cutoff_hours": 24.0, "dfi.span_hours": 48.0},
        )
        sim = make_sim(scene)
        if init == "dfi":
            assert sim.dfi.dhdt_rms[0] / sim.dfi.dhdt_rms[1] > 9.5
            roundoff.within(abs(sim.dfi.mass_change), filter_mass_bound(sim.dfi, sim.grid.nnodes), "|mass change|")
            roundoff.within(
                abs(sim.initial["mass"] / before.initial["mass"] - 1),
                filter_mass_bound(sim.dfi, sim.grid.nnodes),
                "|initial mass / unfiltered − 1|",
            )
        sim.run(None)
        tend = sim.model.new_state()
        sim.model.rhs(sim.x, tend)
        day1[init] = (
            math.sqrt(sim.topology.mean(sim.divergence() ** 2)),
            math.sqrt(sim.topology.mean(tend.numpy()[2] ** 2)),
        )
        before = sim
    div, dhdt = (day1["none"][k] / day1["dfi"][k] for k in (0, 1))
    assert 1.18 < div < 1.26, div  # measured 1.216
    assert dhdt > 9, dhdt  # measured 10.8


def test_run_file_records_the_start_and_a_restart_does_not_redo_it(tmp_path, capsys, monkeypatch):
    """TC5 ne2 with a 6 h cutoff: the run file says how it started (dfi_* attributes),
    the header and summary say so; continued from its restart file the run is bitwise
    the uninterrupted one and the filter is not run again."""
    calls = []
    real = units.digital_filter
    monkeypatch.setattr(units, "digital_filter", lambda *a, **k: calls.append(1) or real(*a, **k))
    args = [
        "run",
        "tc5_mountain",
        "--ne",
        "2",
        "--dt",
        "3600",
        "--stepper",
        "rk4",
        "--device",
        "cpu",
        "--no-progress",
        "-s",
        'case.initialization="dfi"',
        "-s",
        "dfi.cutoff_hours=6",
        "-s",
        "dfi.span_hours=12",
    ]
    assert main([*args, "--days", "2", "--output", str(tmp_path / "full.nc")]) == 0
    out = capsys.readouterr().out
    assert (
        "initial     digital filter (Lynch & Huang 1992): cutoff 6 h, span +-6 h" in out
        and "digital-filter start:" in out
    )
    assert main([*args, "--days", "1", "--output", str(tmp_path / "cut.nc"), "--restart-every", "1"]) == 0
    assert len(calls) == 2
    capsys.readouterr()
    assert (
        main(["run", "--continue", str(tmp_path / "cut.restart.nc"), "--days", "2", "--no-progress", "--device", "cpu"])
        == 0
    )
    assert "continued (not redone)" in capsys.readouterr().out
    assert len(calls) == 2
    with (
        xr.open_dataset(tmp_path / "full.nc", decode_times=False) as a,
        xr.open_dataset(tmp_path / "cut_continued.nc", decode_times=False) as b,
    ):
        assert a.attrs["initialization"] == b.attrs["initialization"] == "dfi"
        assert a.attrs["dfi_cutoff_hours"] == 6.0 and a.attrs["dfi_steps"] > 0 and "dfi_steps" not in b.attrs
        assert a.attrs["dfi_dhdt_rms_after"] < a.attrs["dfi_dhdt_rms_before"]
        for v in ("h", "u", "v"):
            np.testing.assert_array_equal(a[v].sel(time=2).values, b[v].sel(time=2).values)


def test_sweep_filters_once_and_every_run_starts_there(tmp_path, monkeypatch):
    """A 2-stepper x 2-dt sweep (and its reference run and warm-ups) on TC5 ne2: one
    filter, its state kept in runs/, every run tagged; a second sweep reads it back."""
    calls = []
    real = units.digital_filter
    monkeypatch.setattr(units, "digital_filter", lambda *a, **k: calls.append(1) or real(*a, **k))
    over = {"case.initialization": "dfi", "dfi.cutoff_hours": 6.0, "dfi.span_hours": 12.0}
    scenes = {s: load_scene("tc5_mountain", ne=2, days=0.25, stepper=s, overrides=over) for s in ("rk4", "ssprk3")}
    base = scenes["rk4"]
    start = start_state(base, tmp_path, "cpu")
    ref = make_sim(base)  # the filter run directly: the same state
    np.testing.assert_array_equal(start, np.stack(ref.fields()))
    rows, info = Sweep(scenes, [900.0, 1800.0], tmp_path, "cpu", log=lambda *a: None, start=start).run()
    assert len(calls) == 2 and len(rows) == 4 and all(r["stable"] for r in rows)
    assert info["dfi_cutoff_hours"] == 6.0
    names = sorted(p.name for p in (tmp_path / "runs").iterdir())
    assert "start_dfi6h12h.npz" in names and all("_dfi6h12h" in n for n in names)
    np.testing.assert_array_equal(start_state(base, tmp_path, "cpu"), start)
    assert len(calls) == 2
    # a run from the start state is the filtered scene's run
    plain = dataclasses.replace(base, initialization=None)
    a, b = Simulation(plain, "cpu", progress=False, start=start), make_sim(base)
    a.run(None), b.run(None)
    np.testing.assert_array_equal(a.x.numpy(), b.x.numpy())


@pytest.mark.parametrize(
    "scene, sets, message",
    [
        (
            "tc5_mountain",
            ['case.initialization="balanced"'],
            "case.initialization must be one of none, dfi (got 'balanced')",
        ),
        ("tc2_steady", ['case.initialization="dfi"'], "would spoil case tc2_steady's exact solution"),
        ("tc5_mountain", ['case.initialization="dfi"', "dfi.cutoff_hours=0"], "dfi.cutoff_hours must be > 0 (got 0.0)"),
        ("tc5_mountain", ['case.initialization="dfi"', "dfi.span_hours=-6"], "dfi.span_hours must be > 0"),
        (
            "tc5_mountain",
            ['case.initialization="dfi"', "dfi.span_hours=30"],
            "dfi.span_hours = 30 is too short for a cutoff of 24 h",
        ),
        ("tc5_mountain", ["dfi.window=3"], "unknown key dfi.window"),
    ],
)
def test_bad_options_exit_2_with_one_line(tmp_path, capsys, scene, sets, message):
    out = tmp_path / "run.nc"
    args = ["run", scene, "--ne", "2", "--days", "1", "--device", "cpu", "--output", str(out)]
    cli_one_line(capsys, [*args, *(a for s in sets for a in ("-s", s))], 2, message)
    assert not out.exists()


def test_cli_sweep_takes_the_start_as_an_override(tmp_path, capsys):
    """``sweep -s case.initialization=dfi``: the start is said, shared and recorded in sweep.nc."""
    out = tmp_path / "sweep"
    args = [
        "sweep",
        "tc5_mountain",
        "--ne",
        "2",
        "--days",
        "0.25",
        "--steppers",
        "rk4",
        "--dt",
        "1800",
        "--device",
        "cpu",
        "--output",
        str(out),
        "-s",
        "case.initialization=dfi",
        "-s",
        "dfi.cutoff_hours=6",
        "-s",
        "dfi.span_hours=12",
    ]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert (
        "start       digital-filter initialization (cutoff 6 h, span 12 h)" in text and "gravity waves it keeps" in text
    )
    assert (out / "runs" / "start_dfi6h12h.npz").is_file()
    with xr.open_dataset(out / "sweep.nc", decode_times=False) as ds:
        assert ds.attrs["dfi_cutoff_hours"] == 6.0 and ds.attrs["dfi_span_hours"] == 12.0


@pytest.mark.parametrize("rate", [4e-4, 4e-3])  # (|v| + sqrt(g h)) / Δx in s⁻¹: 70 and 692 RK4 steps each way
def test_the_default_digital_filters_response(rate):
    """The figures of the README ("A balanced start") and DigitalFilter's docstring:
    the 24 h cutoff over a 48 h span passes waves of 8, 12, 16, 24, 33, 48 h and
    3 days at −5e-4, −4.7e-3, 0.048, 0.50, 0.79, 0.94 and 0.987, never above 1
    for slower motions; Lynch & Huang's 6 h span and cutoff pass 4 h waves at 0.24."""
    from swe_sphere.steppers.timefilter import lanczos_weights, response

    def passes(f, hours):
        dt, n = f.steps(rate)
        return float(response(f.weights(dt, n), dt / (hours * 3600.0)))

    f = DigitalFilter()
    for hours, value, digits in (
        (8, -5e-4, 1),
        (12, -4.7e-3, 2),
        (16, 0.048, 2),
        (24, 0.50, 2),
        (33, 0.79, 2),
        (48, 0.94, 2),
        (72, 0.987, 3),
    ):
        assert passes(f, hours) == pytest.approx(
            value, abs=0.5 * 10 ** (math.floor(math.log10(abs(value))) - digits + 1)
        ), hours
    assert max(passes(f, hours) for hours in np.geomspace(24, 24 * 30, 200)) <= 1.0
    dt = 300.0  # Lynch & Huang's window (refused here: shorter than twice the cutoff) of 36 steps each way
    assert float(response(lanczos_weights(dt / (6 * 3600.0), 36), dt / (4 * 3600.0))) == pytest.approx(0.24, abs=0.005)
