"""An ensemble's run and restart files (``Ensemble.run``, ``swe-sphere run --members``): each
member's fields have the bits of its single run's file, the ensemble mean and spread are those of
the members, a blow-up keeps the good output times, a restart file (written on a schedule or at a
signal) continues bitwise, and the command line refuses what does not go together with one line,
exit 2 and no file."""

from __future__ import annotations

import os
import signal

import netCDF4
import numpy as np
import pytest

import swe_sphere
from swe_sphere.core.errors import BlowUp, CheckpointError, Interrupted, OutputError, SceneError
from swe_sphere.ensemble import Perturbation
from swe_sphere.simulation.simulation import Simulation

from helpers import cli_main, digest, members_from_checkpoint, members_run, take_steps, write_tc2_scene

SMALL = {"ne": 2, "np": 4, "dt": 900.0, "days": 0.5, "output.every_days": 0.25}


def read(path, *names):
    with netCDF4.Dataset(path) as ds:
        return [ds[name][:].filled(np.nan) if np.ma.isMaskedArray(ds[name][:]) else ds[name][:] for name in names]


def test_each_member_in_the_file_is_its_single_run_s(tmp_path):
    ens = members_run("galewsky", 3, Perturbation(2.0, seed=5), device="cpu", **SMALL)
    starts = ens.states()
    ens.run(tmp_path / "ens.nc")
    time, h, u, zeta, mass = read(tmp_path / "ens.nc", "time", "h", "u", "vorticity", "mass")
    assert list(time) == [0.0, 0.25, 0.5] and h.shape == (3, 3, ens.grid.nunique)
    for k in range(3):
        sim = Simulation("galewsky", "cpu", progress=False, start=starts[k], **SMALL)
        sim.run(tmp_path / f"{k}.nc")
        h1, u1, zeta1, mass1 = read(tmp_path / f"{k}.nc", "h", "u", "vorticity", "mass")
        assert np.array_equal(h[:, k], h1) and np.array_equal(u[:, k], u1) and np.array_equal(zeta[:, k], zeta1), k
        assert np.array_equal(mass[:, k], mass1), k


def test_each_member_s_errors_are_its_single_run_s(tmp_path):
    """TC2's exact solution: Williamson's norms of every member, as its single run's file has them."""
    kw = {**SMALL, "dt": 1800.0}
    starts = members_run("tc2_steady", 2, Perturbation(1.0, seed=2), device="cpu", **kw).states()
    members_run("tc2_steady", 2, starts, device="cpu", **kw).run(tmp_path / "ens.nc")
    names = ("l1_h", "l2_h", "linf_h", "l2_wind", "l2_vorticity", "l2_divergence")
    errors = read(tmp_path / "ens.nc", *names)
    assert errors[1][0, 0] > 1e-4  # 1 m of noise against the exact h
    for k in range(2):
        Simulation("tc2_steady", "cpu", progress=False, start=starts[k], **kw).run(tmp_path / f"{k}.nc")
        for name, ours, theirs in zip(names, errors, read(tmp_path / f"{k}.nc", *names)):
            assert np.array_equal(ours[:, k], theirs), (name, k)


def test_the_mean_and_spread_are_the_members(tmp_path):
    ens = members_run("galewsky", 4, Perturbation(3.0, seed=1), device="cpu", **SMALL)
    ens.run(tmp_path / "ens.nc")
    h, mean, spread, rms, area = read(tmp_path / "ens.nc", "h", "h_mean", "h_spread", "h_spread_rms", "area")
    assert np.array_equal(mean, h.mean(axis=1)) and np.array_equal(spread, h.std(axis=1, ddof=1))
    assert rms[0] > 2.0  # 3 m of white noise, smoothed by nothing yet
    assert rms[-1] == ens.h_spread_rms()
    assert rms[-1] == pytest.approx(np.sqrt(np.sum(area * spread[-1] ** 2) / area.sum()), rel=1e-14)
    with netCDF4.Dataset(tmp_path / "ens.nc") as ds:
        assert ds["member"].standard_name == "realization" and list(ds["member"][:]) == [0, 1, 2, 3]
        assert ds["h_spread"].cell_methods == "realization: standard_deviation"
        assert ds["h"].dimensions == ("time", "member", "ncol") and ds.members == 4


# two streams beside the run file (every 0.25 days): h every 3 h, the wind and vorticity every 6 h
STREAMS = [
    {"name": "3h", "every_days": 0.125, "fields": ["h"]},
    {"name": "q", "every_days": 0.25, "fields": ["vorticity", "u"]},
]


def test_an_ensemble_writes_its_streams_as_a_run_does(tmp_path):
    """``[[output.streams]]`` (refused by ensembles before issue 100): RUN.NAME.nc each at its
    own times with its own fields, the members along the member axis; at a time the run file
    has too, the stream's values are the run file's, and each member's stream the bits of its
    single run's stream."""
    kw = {**SMALL, "output.streams": STREAMS}
    ens = members_run("galewsky", 2, Perturbation(2.0, seed=5), device="cpu", **kw)
    starts = ens.states()
    ens.run(tmp_path / "ens.nc")
    time, h, u, zeta, mass = read(tmp_path / "ens.nc", "time", "h", "u", "vorticity", "mass")
    t3, h3, mass3 = read(tmp_path / "ens.3h.nc", "time", "h", "mass")
    tq, uq, zq = read(tmp_path / "ens.q.nc", "time", "u", "vorticity")
    assert list(time) == [0.0, 0.25, 0.5] and list(t3) == [0.0, 0.125, 0.25, 0.375, 0.5] and list(tq) == list(time)
    assert h3.shape == (5, 2, ens.grid.nunique) and not np.array_equal(h3[1], h3[2])  # its own times
    assert np.array_equal(h3[::2], h) and np.array_equal(mass3[::2], mass)  # bitwise at the run file's times
    assert np.array_equal(uq, u) and np.array_equal(zq, zeta)
    with netCDF4.Dataset(tmp_path / "ens.3h.nc") as ds, netCDF4.Dataset(tmp_path / "ens.q.nc") as q:
        assert ds["h"].dimensions == ("time", "member", "ncol") and ds.members == 2
        assert "u" not in ds.variables and "h" not in q.variables and "h_spread" in ds.variables
    for k in range(2):
        sim = Simulation("galewsky", "cpu", progress=False, start=starts[k], **kw)
        sim.run(tmp_path / f"{k}.nc")
        (one,) = read(tmp_path / f"{k}.3h.nc", "h")
        assert np.array_equal(h3[:, k], one), k


def test_a_controlled_ensemble_lands_on_its_streams_days(tmp_path, one_thread):
    """Under step control the steps land on each stream's days too, as a run's do."""
    controlled = {"ne": 2, "np": 4, "days": 0.25, "stepper": "bs32", "time.control": "error"}
    kw = {**controlled, "output.every_days": 0.25, "output.streams": STREAMS[:1]}
    ens = members_run("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **kw)
    ens.run(tmp_path / "ens.nc")
    time, h = read(tmp_path / "ens.nc", "time", "h")
    t3, h3 = read(tmp_path / "ens.3h.nc", "time", "h")
    assert list(time) == [0.0, 0.25] and list(t3) == [0.0, 0.125, 0.25]
    assert np.array_equal(h3[[0, 2]], h) and not np.array_equal(h3[1], h3[2])
    assert np.array_equal(ens.grid.to_unique(ens.states()[:, 2]), h[-1])


def test_a_signal_writes_the_step_reached_to_every_stream(tmp_path):
    """Stopped by a signal, the run file and each stream end with the step reached, their
    global attributes saying so."""
    kw = {**SMALL, "output.streams": STREAMS}
    ens = members_run("galewsky", 2, Perturbation(1.0, seed=2), device="cpu", **kw)
    signalled = []

    def signal_at_10(ens):  # SIGINT once 10 steps are done: the ensemble stops at the block's end (10)
        if ens.step >= 10 and not signalled:
            signalled.append(ens.step)
            os.kill(os.getpid(), signal.SIGINT)

    ens.add_callback(signal_at_10, every_steps=5)
    with pytest.raises(Interrupted, match=r"^interrupted by SIGINT at step 10 "):
        ens.run(tmp_path / "ens.nc")
    times = {"ens.nc": [0.0, 10 / 96], "ens.3h.nc": [0.0, 10 / 96], "ens.q.nc": [0.0, 10 / 96]}
    for name, days in times.items():
        with netCDF4.Dataset(tmp_path / name) as ds:
            assert (ds.interrupted, ds.interrupted_at_step) == ("SIGINT", 10) and list(ds["time"][:]) == days, name
    (h,), (h3,) = read(tmp_path / "ens.nc", "h"), read(tmp_path / "ens.3h.nc", "h")
    assert np.array_equal(h3, h) and np.array_equal(h[-1], ens.grid.to_unique(ens.states()[:, 2]))


def test_the_command_line_runs_an_ensemble_with_its_streams(capsys, tmp_path):
    """``run --members`` of a scene file with ``[[output.streams]]``: its header names each stream."""
    scene = write_tc2_scene(
        tmp_path / "s.toml",
        dt=1800.0,
        days=0.25,
        tables='[[output.streams]]\nname = "hourly"\nevery_days = 0.041666666666666664\nfields = ["h"]\n',
    )
    out = tmp_path / "e.nc"
    code, said, err = cli_main(capsys, "run", scene, "--members", "2", "--perturbation", "1", "--output", out)
    assert code == 0, err
    assert f"stream      {tmp_path / 'e.hourly.nc'} (every 0.0416667 days: h)" in said
    time, h = read(tmp_path / "e.hourly.nc", "time", "h")
    assert np.allclose(time, np.arange(7) / 24, rtol=0, atol=1e-12) and h.shape[:2] == (7, 2)
    assert np.array_equal(h[-1], read(out, "h")[0][-1])


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_blow_up_keeps_the_good_output_times(tmp_path):
    good = members_run("tc2_steady", 3, device="cpu", ne=2, np=4, stepper="rk4", dt=1800.0).states()
    good[2, :2] *= 8  # unstable at this dt within a few steps (test_ensemble)
    ens = members_run("tc2_steady", 3, good, device="cpu", ne=2, np=4, stepper="rk4", dt=1800.0, days=5)
    with pytest.raises(BlowUp, match="member 2 of 3"):
        ens.run(tmp_path / "ens.nc")
    with netCDF4.Dataset(tmp_path / "ens.nc") as ds:
        assert "member 2 of 3 blew up" in ds.stopped
        times = ds["time"][:]
        assert len(times) >= 1 and times[-1] * 86400 < ens.step * 1800.0
        assert np.isfinite(ds["h"][:]).all()


@pytest.mark.parametrize("stepper", ["kgu35", "leapfrog"])  # leapfrog: a stepper history carried over
def test_a_restart_file_continues_bitwise(tmp_path, stepper):
    kw = {**SMALL, "stepper": stepper}
    whole = members_run("galewsky", 2, Perturbation(2.0, seed=2), device="cpu", **{**kw, "days": 0.75})
    whole.run(tmp_path / "whole.nc")
    first = members_run("galewsky", 2, Perturbation(2.0, seed=2), device="cpu", **kw)
    first.run(tmp_path / "first.nc", restart_every=0.25)
    rest = members_from_checkpoint(tmp_path / "first.restart.nc", days=0.75)
    assert rest.step == 48 and rest.members.initial_states == first.members.initial_states
    rest.run(tmp_path / "rest.nc")
    assert np.array_equal(rest.states(), whole.states())
    (h_whole,), (h_rest, t_rest) = (
        read(tmp_path / "whole.nc", "h"),
        read(tmp_path / "rest.nc", "h", "time"),
    )
    # the restart day is the first file's last time, not written again: the two files join without a repeat
    assert list(t_rest) == [0.75] and np.array_equal(h_rest, h_whole[3:])


def test_a_signal_stops_after_a_block_with_its_restart_file(tmp_path):
    ens = members_run("galewsky", 2, Perturbation(1.0, seed=3), device="cpu", **{**SMALL, "days": 1.0})
    signalled = []

    def signal_at_30(ens):  # SIGINT once 30 steps are done: as a run, the ensemble stops at the block's end (30)
        if ens.step >= 30 and not signalled:
            signalled.append(ens.step)
            os.kill(os.getpid(), signal.SIGINT)

    ens.add_callback(signal_at_30, every_steps=6)
    with pytest.raises(
        Interrupted, match=r"^interrupted by SIGINT at step 30 .*; restart file .*e\.restart\.nc$"
    ) as info:
        ens.run(tmp_path / "e.nc")
    assert info.value.signum == signal.SIGINT and info.value.checkpoint == tmp_path / "e.restart.nc"
    with netCDF4.Dataset(tmp_path / "e.nc") as ds:
        assert list(ds["time"][:]) == [0.0, 0.25, 0.3125] and "stopped" not in ds.ncattrs()
        assert (ds.interrupted, ds.interrupted_at_step, ds.interrupted_at_day) == ("SIGINT", 30, 0.3125)  # as a run's
    assert signalled == [30]
    rest = members_from_checkpoint(tmp_path / "e.restart.nc")
    take_steps(rest, 96 - 30)
    whole = members_run("galewsky", 2, Perturbation(1.0, seed=3), device="cpu", **{**SMALL, "days": 1.0})
    take_steps(whole, 96)
    assert np.array_equal(rest.states(), whole.states())


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_restart_file_is_continued_by_its_own_kind(tmp_path):
    ens = members_run("galewsky", 2, device="cpu", **SMALL)
    take_steps(ens, 4)
    ens.write_checkpoint(tmp_path / "e.restart.nc")
    with pytest.raises(CheckpointError, match="an ensemble's restart file \\(2 members\\)"):
        Simulation.from_checkpoint(tmp_path / "e.restart.nc", "cpu")
    sim = Simulation("galewsky", "cpu", progress=False, **SMALL)
    sim.write_checkpoint(tmp_path / "s.restart.nc")
    with pytest.raises(CheckpointError, match="a single run's restart file"):
        members_from_checkpoint(tmp_path / "s.restart.nc")
    with pytest.raises(CheckpointError, match="ends before the checkpoint"):
        members_from_checkpoint(tmp_path / "e.restart.nc", days=0.03125)


def test_the_command_line_runs_an_ensemble(capsys, tmp_path):
    out = tmp_path / "g.nc"
    code = cli_main(
        capsys, "run", "galewsky", "--ne", "2", "--dt", "900", "--days", "1", "--members", "2",
        "--perturbation", "1", "--seed", "4", "--output", str(out),
    )  # fmt: skip
    assert code[0] == 0, code
    assert "ensemble    2 members" in code[1] and "h spread" in code[1]
    # a single run's header and summary lines too: terms, the Courant numbers, the notes, the drift, the errors
    said = {line.split()[0] for line in code[1].splitlines() if line.strip()}
    assert {"terms", "Courant", "mass", "total_energy", "potential_enstrophy", "ref_l2_h_surface"} <= said, code[1]
    l2 = read(out, "ref_l2_h_surface")[0][-1]  # (members,) at the last time: the summary's range is theirs
    assert f"{min(l2):.3e} to {max(l2):.3e} over the members" in code[1], code[1]
    (h,) = read(out, "h")
    assert h.shape[1] == 2 and not np.array_equal(h[0, 0], h[0, 1])
    # ending on a day the T213 reference does not store: one line, not a "nan to nan" range a key
    half = ("run", "galewsky", "--ne", "2", "--dt", "900", "--days", "0.5", "--members", "2")
    code = cli_main(capsys, *half, "--output", tmp_path / "half.nc")
    assert code[0] == 0 and "reference             none at day 0.5: T213 stores days 0, 1, 2, 4, 5, 6" in code[1]
    assert "nan" not in code[1], code[1]


def test_the_command_line_continues_an_ensemble(capsys, tmp_path):
    first = tmp_path / "g.nc"
    run = ("run", "galewsky", "--ne", "2", "--dt", "900", "--days", "0.25", "--members", "2", "--perturbation", "1")
    assert cli_main(capsys, *run, "--restart-every", "0.25", "--output", first)[0] == 0
    restart = tmp_path / "g.restart.nc"
    for args, says in [
        (("--dt", "450"), "--dt 450: an ensemble continues with its own stepper, dt, layout and blow-up policy"),
        (("--blow-up", "drop"), "--blow-up drop: an ensemble continues with its own stepper, dt, layout and blow-up"),
        (("--members", "3"), "--members 3: "),
        (("--seed", "1"), "--seed: a continued ensemble's members start from its restart file"),
    ]:
        code, _, err = cli_main(capsys, "run", "--continue", restart, *args, "--output", tmp_path / "x.nc")
        assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err
    code, out, _ = cli_main(capsys, "run", "--continue", restart, "--days", "0.5", "--output", tmp_path / "more.nc")
    assert code == 0 and "continued   from" in out and "step 24 (day 0.25)" in out
    assert list(read(first, "time")[0]) == [0.0, 0.25] and list(read(tmp_path / "more.nc", "time")[0]) == [0.5]


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (("--seed", "3"), "--seed only with --members N"),
        (("--perturbation", "1"), "--perturbation only with --members N"),
        (("--layout", "shared"), "--layout only with --members N"),
        (("--members", "0"), "members must be an integer >= 1"),
        (("--members", "2", "--perturbation", "-1"), "perturbation amplitude"),
        (
            ("--members", "2", "--stepper", "bs32", "-s", "time.control=error", "--layout", "in_turn"),
            "its dt is controlled",
        ),
        (("--members", "2", "--perturbation-degrees", "1,8"), "--perturbation-degrees only with --perturbation M"),
        (("--members", "2", "--perturbation", "1", "--perturbation-degrees", "1,x"), "give L_MIN,L_MAX"),
        (("--members", "2", "--perturbation", "1", "--perturbation-degrees", "9,8"), "1 <= L_MIN <= L_MAX"),
        (("--perturbation-degrees", "1,8"), "--perturbation-degrees only with --members N"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(capsys, tmp_path, args, says):
    out = tmp_path / "g.nc"
    code, _, err = cli_main(capsys, "run", "galewsky", "--ne", "2", "--output", str(out), *args)
    assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err
    assert not list(tmp_path.iterdir())


def test_plot_and_remap_read_a_member_the_mean_or_the_spread(capsys, tmp_path):
    from swe_sphere.studies.analysis import field_at_nodes
    from swe_sphere.studies.plotting import open_run, plot_map

    run = tmp_path / "e.nc"
    members_run("galewsky", 2, Perturbation(1.0, seed=1), device="cpu", **SMALL).run(run)
    code, _, err = cli_main(capsys, "plot", run, "--output", tmp_path / "p")
    assert code == 2 and "an ensemble's run file (2 members): name --member K (0 to 1), mean or spread" in err
    assert not (tmp_path / "p").exists()
    for member, label in (("1", "member1"), ("mean", "mean"), ("spread", "spread")):
        code, out, _ = cli_main(capsys, "plot", run, "--member", member, "--output", tmp_path / "p")
        assert code == 0 and f"e_{label}_h_surface_day0.5.png" in out and f"e_{label}_series.png" in out
    code, _, err = cli_main(capsys, "plot", run, "--member", "2", "--output", tmp_path / "q")
    assert code == 2 and "--member must be 0 to 1, mean or spread (got '2')" in err
    for args, says in [
        (("--field", "speed"), "not of the speed"),
        (("--spectrum",), "not of its spread"),
        (("--diff", "T213", "--day", "0"), "a spread is not a state"),
    ]:
        code, _, err = cli_main(capsys, "plot", run, "--member", "spread", *args, "--output", tmp_path / "q")
        assert code == 2 and says in err and not (tmp_path / "q").exists()
    h, spread, hs = read(run, "h", "h_spread", "hs")
    with open_run(run, "1") as ds:
        assert np.array_equal(field_at_nodes(ds, "h_surface", 0.5), h[-1, 1] + hs)
    with open_run(run, "spread") as ds:  # h + hs's spread is h's
        assert np.array_equal(field_at_nodes(ds, "h_surface", 0.5), spread[-1])
    assert cli_main(capsys, "remap", run, "--resolution", "10", "--output", tmp_path / "l.nc")[0] == 0
    with netCDF4.Dataset(tmp_path / "l.nc") as ds:
        assert ds["h"].dimensions == ("time", "member", "lat", "lon") and ds["h_spread"].dimensions == (
            "time",
            "lat",
            "lon",
        )
        assert ds["mass"].dimensions == ("time", "member") and ds["member"].standard_name == "realization"
        # the mean and spread of the members remapped: the nodes' spread interpolated went below 0
        h = ds["h"][:]
        assert np.array_equal(ds["h_mean"][:], h.mean(axis=1))
        assert np.array_equal(ds["h_spread"][:], h.std(axis=1, ddof=1)) and ds["h_spread"][1:].min() > 0
    # the map of the spread too: the drawn members' spread, not the nodes' spread interpolated
    with open_run(run, "spread") as ds:
        drawn = plot_map(ds, "h", 0.5)
    with open_run(run, "0") as m0, open_run(run, "1") as m1:
        a, b = (plot_map(m, "h", 0.5)["figure"].axes[0].images[0].get_array() for m in (m0, m1))
    assert drawn["min"] >= 0 and np.allclose(drawn["figure"].axes[0].images[0].get_array(), abs(a - b) / np.sqrt(2))


def test_members_start_from_an_ensemble_s_run_file(capsys, tmp_path):
    """``MemberFile``: member k from the file's member k at its last time, the bits of the run that wrote it."""
    from swe_sphere.core.errors import ArgumentError
    from swe_sphere.ensemble import MemberFile

    first = members_run("galewsky", 2, Perturbation(1.0, seed=6), device="cpu", **SMALL)
    first.run(tmp_path / "e.nc")
    again = members_run("galewsky", 2, MemberFile(tmp_path / "e.nc"), device="cpu", **SMALL)
    assert (
        np.array_equal(again.states(), first.states()) and again.members.initial_states == f"from {tmp_path / 'e.nc'}"
    )
    at = members_run("galewsky", 2, MemberFile(tmp_path / "e.nc", day=0.25), device="cpu", **SMALL)
    assert not np.array_equal(at.states(), first.states())
    Simulation("galewsky", "cpu", progress=False, **SMALL).run(tmp_path / "one.nc")
    for members, initial, says in [
        (3, MemberFile(tmp_path / "e.nc"), "holds 2 members, the ensemble 3"),
        (2, MemberFile(tmp_path / "one.nc"), "not an ensemble's run file"),
        (2, MemberFile(tmp_path / "none.nc"), "not a readable netCDF file"),
        (2, MemberFile(tmp_path / "e.nc", day=0.3), "no output at day 0.3"),
    ]:
        with pytest.raises(ArgumentError, match=says):
            members_run("galewsky", members, initial, device="cpu", **SMALL)
    run = ("run", "galewsky", "--ne", "2", "--np", "4", "--dt", "900", "--days", "0.25")
    code, _, err = cli_main(
        capsys, *run, "--members", "3", "--initial", tmp_path / "e.nc", "--output", tmp_path / "x.nc"
    )
    assert code == 2 and "the file holds 2 members, the ensemble 3" in err and not (tmp_path / "x.nc").exists()
    code, _, err = cli_main(capsys, *run, "--members", "2", "--initial", tmp_path / "e.nc", "--seed", "1")
    assert code == 2 and "--seed and --initial: the members start from one of a perturbation, --initial's file" in err
    code, out, _ = cli_main(
        capsys, *run, "--members", "2", "--initial", tmp_path / "e.nc", "--output", tmp_path / "y.nc"
    )
    assert code == 0 and f"initial states from {tmp_path / 'e.nc'}" in out


def test_variants_from_the_command_line_with_each_member_s_exact_errors(capsys, tmp_path):
    """TC2 turned by α per member (``--vary case.alpha=...``): each member's errors against its own
    exact solution, as its single run's file has them."""
    import math

    out = tmp_path / "v.nc"
    run = ("run", "tc2_steady", "--ne", "2", "--dt", "1800", "--days", "0.25", "--members", "2")
    code, stdout, _ = cli_main(capsys, *run, "--vary", f"case.alpha=0,{math.pi / 4}", "--output", out)
    assert code == 0 and "variants: case.alpha = 0, 0.785398" in stdout
    (l2,) = read(out, "l2_h")
    for k, alpha in enumerate((0.0, math.pi / 4)):
        single = tmp_path / f"{k}.nc"
        assert cli_main(capsys, "run", "tc2_steady", "--ne", "2", "--dt", "1800", "--days", "0.25",
                        "-s", f"case.alpha={alpha}", "--output", single)[0] == 0  # fmt: skip
        assert np.array_equal(l2[:, k], read(single, "l2_h")[0]), k
    code, _, err = cli_main(capsys, *run, "--vary", "case.alpha=0,1", "--initial", out, "--output", tmp_path / "w.nc")
    assert code == 2 and "--initial and --vary: the members start from one of" in err


def test_a_scene_s_ensemble_table_runs_its_ensemble(capsys, tmp_path):
    """[ensemble] (here ``-s ensemble.…``): ``swe-sphere run`` runs the scene's members from its
    perturbation, as ``--members --perturbation --seed`` do, its band of degrees as
    ``--perturbation-degrees``; bad values one line, exit 2."""
    run = ("run", "galewsky", "--ne", "2", "--np", "4", "--dt", "900", "--days", "0.25")
    table = ("-s", "ensemble.members=2", "-s", "ensemble.perturbation=1.5", "-s", "ensemble.seed=7")
    assert cli_main(capsys, *run, *table, "--output", tmp_path / "a.nc")[0] == 0
    flags = ("--members", "2", "--perturbation", "1.5", "--seed", "7")
    assert cli_main(capsys, *run, *flags, "--output", tmp_path / "b.nc")[0] == 0
    (a,), (b,) = read(tmp_path / "a.nc", "h"), read(tmp_path / "b.nc", "h")
    assert a.shape[1] == 2 and np.array_equal(a, b)
    ens = members_run(
        "galewsky", initial=None, device="cpu", **SMALL, **{"ensemble.members": 2, "ensemble.perturbation": 1.5}
    )
    assert len(ens.members) == 2 and ens.members.initial_states == "perturbed: h + 1.5 m white noise, seed 0"
    band = ("-s", "ensemble.members=2", "-s", "ensemble.perturbation=1.5", "-s", "ensemble.degrees=[2, 6]")
    assert cli_main(capsys, *run, *band, "--output", tmp_path / "d.nc")[0] == 0
    degrees = ("--members", "2", "--perturbation", "1.5", "--perturbation-degrees", "2,6")
    assert cli_main(capsys, *run, *degrees, "--output", tmp_path / "e.nc")[0] == 0
    (d,), (e,) = read(tmp_path / "d.nc", "h"), read(tmp_path / "e.nc", "h")
    assert np.array_equal(d, e) and not np.array_equal(d, a)  # the table's band as the flags' one
    # swe_sphere.run runs the table's members too (it had run one state, the member dimension gone)
    table = {"ensemble": {"members": 2, "perturbation": 1.5, "seed": 7}}
    ds = swe_sphere.run("galewsky", device="cpu", ne=2, np=4, dt=900.0, days=0.25, **table)
    assert ds["h"].dims == ("time", "member", "ncol") and np.array_equal(ds["h"].values, a)
    with pytest.raises(SceneError, match=r"^initial: an \[ensemble\]'s members start from its perturbation"):
        swe_sphere.run("galewsky", device="cpu", ne=2, days=0.25, initial=lambda lat, lon: (lat, lat, lon), **table)
    for sets, says in [
        (("ensemble.members=2", "ensemble.degrees=[0, 6]"), "ensemble.degrees must be [l_min, l_max]"),
        (("ensemble.members=0",), "ensemble.members must be an integer >= 1"),
        (("ensemble.members=2", "ensemble.seed=-1"), "ensemble.seed must be an integer >= 0"),
        (("ensemble.seed=1",), "ensemble.members is missing"),
    ]:
        code, _, err = cli_main(capsys, *run, *(w for v in sets for w in ("-s", v)), "--output", tmp_path / "c.nc")
        assert code == 2 and says in err and not (tmp_path / "c.nc").exists()


@pytest.mark.filterwarnings("ignore::swe_sphere.members.initial.MembersAlike")  # members alike on purpose
def test_a_run_refuses_what_would_replace_its_inputs_or_its_own_names(tmp_path):
    """As a run's (``simulation.loop.open_files``): an output that is the scene file, even
    with ``overwrite``, is refused in one line and the file is left as it was; an activity under a
    run's own name is refused; an argument of another kind is named; nothing is written."""
    scene = write_tc2_scene(tmp_path / "tc2.toml", days=0.5)
    before = digest(scene)
    ens = members_run(scene, 2, device="cpu", ne=2)
    with pytest.raises(OutputError, match=r"^the output .*tc2.toml is the input .*tc2.toml; writing it would"):
        ens.run(scene, overwrite=True)
    assert digest(scene) == before
    ens.add_callback(lambda e: None, every_steps=1)
    ens.activities["checkpointer"] = ens.activities.pop(next(iter(ens.activities)))
    with pytest.raises(ValueError, match=r"^activities checkpointer: a run's own names \(choose another\)$"):
        ens.run(tmp_path / "ens.nc")
    del ens.activities["checkpointer"]
    with pytest.raises(SceneError, match=r"^compress must be"):
        ens.run(tmp_path / "ens.nc", compress="yes")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tc2.toml"] and ens.step == 0
