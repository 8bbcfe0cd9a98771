"""Restart files, interrupts and exclusive outputs.

A continued run is bitwise the uninterrupted one for every registered stepper
(and BDF2); a checkpoint of another grid, scene or version is refused with one
line; SIGINT / SIGTERM sent to a real ``swe-sphere run`` leave a valid output
and a restart file that continues bitwise; outputs are never overwritten
without --overwrite, never written through a symlink, and never by two writers.
"""

from __future__ import annotations

import dataclasses
import json
import os
import signal
import subprocess
import sys

import netCDF4
import numpy as np
import pytest
import xarray as xr

from swe_sphere import __version__
from swe_sphere.cli import main
from swe_sphere.config.scene import load_scene
from swe_sphere.core.constants import DAY
from swe_sphere.core.errors import OutputError
from swe_sphere.grid.topology import Topology
from swe_sphere.io.output_files import ExclusiveFile
from swe_sphere.members.members import Members
from swe_sphere.simulation import checkpoint as ckpt
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers import STEPPERS

from helpers import EIGHTH_DAY, TINY, cli_main, cli_one_line, make_sim, requires_cuda, write_tc2_scene

# and a Butcher table's IMEX pair (its default is an explicit table), read back from the restart file's JSON;
# and the float32 Helmholtz solves
VARIANTS = (
    [(name, {}) for name in STEPPERS]
    + [("implicit", {"method": "bdf2"}), ("tableau", load_scene("ark324l2sa").stepper_options)]
    + [("lts", {"method": "mrab3"})]  # one level on the cube: AB3, its start and histories
    + [(name, {"precision": "float32"}) for name in ("semi_implicit", "imex", "implicit")]
    + [("mri", {"method": "mri_gark_erk33a", "inner": "fbrk32"}), ("mri", {"method": "mis4a", "inner": "rk4"})]
)
IDS = [n + "".join(f"-{v}" for v in o.values() if not isinstance(v, list)) for n, o in VARIANTS]
DT = 1800.0


def tc2(stepper, options=None, steps=6, every_steps=None):
    """TC2 on ne = 2 np = 4, ``steps`` steps of 30 min (output every ``every_steps``)."""
    scene = load_scene("tc2_steady", ne=2, np_=4, dt=DT, days=steps * DT / DAY, stepper=stepper)
    every = (every_steps or steps) * DT / DAY
    return dataclasses.replace(scene, stepper_options=dict(options or {}), output_every_days=every)


@pytest.mark.parametrize("name, options", VARIANTS, ids=IDS)
def test_continued_run_is_bitwise_the_uninterrupted_one(tmp_path, name, options):
    """6 steps straight against 3 steps + restart file + a fresh Simulation from it
    for 3 more: the final state, the last output record and its diagnostics
    (relative changes against the original t = 0) are the same bits."""
    whole = make_sim(tc2(name, options, 6, 3))
    whole.run(tmp_path / "whole.nc")
    half = make_sim(tc2(name, options, 3, 3))
    r = half.run(tmp_path / "half.nc", restart_every=3 * DT / DAY)
    assert r.checkpoint == tmp_path / "half.restart.nc" and r.checkpoint.is_file()
    cont = Simulation.from_checkpoint(r.checkpoint, "cpu", days=6 * DT / DAY, progress=False)
    assert cont.step == 3 and cont.scene == whole.scene
    cont.run(tmp_path / "cont.nc")
    np.testing.assert_array_equal(cont.x.numpy(), whole.x.numpy())
    with (
        xr.open_dataset(tmp_path / "whole.nc", decode_times=False) as a,
        xr.open_dataset(tmp_path / "cont.nc", decode_times=False) as b,
    ):
        assert list(b.time.values) == [6 * DT / DAY]  # its first time, 3 DT, is the first file's last
        assert b.attrs["continued_from_day"] == 3 * DT / DAY
        for v in ("h", "u", "v", "vorticity", "mass_change", "total_energy_change", "l2_h", "rhs_evals", "steps"):
            np.testing.assert_array_equal(
                b[v].sel(time=6 * DT / DAY).values, a[v].sel(time=6 * DT / DAY).values, err_msg=v
            )


@requires_cuda
@pytest.mark.parametrize("name, options", VARIANTS, ids=IDS)
def test_continued_run_is_bitwise_on_cuda(tmp_path, name, options):
    whole = Simulation(tc2(name, options, 6), "cuda", progress=False)
    whole.run(None)
    half = Simulation(tc2(name, options, 3), "cuda", progress=False)
    r = half.run(tmp_path / "half.nc", restart_every=3 * DT / DAY)
    cont = Simulation.from_checkpoint(r.checkpoint, "cuda", days=6 * DT / DAY, progress=False)
    cont.run(None)
    np.testing.assert_array_equal(cont.x.numpy(), whole.x.numpy())


def test_continuing_hands_each_whole_grid_array_out_once(tmp_path, monkeypatch):
    """``from_checkpoint`` distributes the state once (as the start state) and each
    stepper array once: every ``Topology.distribute`` is a collective Scatterv over
    the ranks, and the whole state was handed out twice. It does not diagnose the
    start state either (gathers, the reference at day 0): the checkpoint has its t = 0 figures."""
    r = make_sim(tc2("leapfrog", steps=2)).run(None, restart_file=tmp_path / "r.nc", restart_every=2 * DT / DAY)
    handed, diagnosed = [], []
    real, real_diagnose = Topology.distribute, Members.diagnose
    monkeypatch.setattr(
        Topology, "distribute", lambda self, whole, rows, what: handed.append(what) or real(self, whole, rows, what)
    )
    monkeypatch.setattr(Members, "diagnose", lambda self, t, *a: diagnosed.append(t) or real_diagnose(self, t, *a))
    cont = Simulation.from_checkpoint(r.checkpoint, "cpu", days=4 * DT / DAY, progress=False)
    assert handed == ["start state", "leapfrog stepper state 'previous'"]
    assert diagnosed == []
    ck = ckpt.read(r.checkpoint)
    assert cont.step == 2 and np.array_equal(cont.x.numpy(), ck.x) and cont.initial == ck.initial


def test_checkpoint_contents_and_refusals(tmp_path):
    sim = make_sim(tc2("leapfrog", steps=2))
    r = sim.run(tmp_path / "run.nc", restart_every=2 * DT / DAY)
    with netCDF4.Dataset(r.checkpoint) as ds:
        assert ds.swe_sphere_version == __version__
        assert ds.step == 2 and ds.stepper_steps == 2
        assert ds["stepper_previous"].shape == (3, sim.model.N)
        assert ds.Conventions == "CF-1.8" and ds.title and ds.history
        for name, units in (("u", "m s-1"), ("v", "m s-1"), ("h", "m")):  # the state as named fields
            assert ds[name].shape == (sim.model.N,) and ds[name].units == units and ds[name].long_name, name
        assert all(ds[name].long_name for name in ds.variables)
        assert json.loads(ds.scene)["stepper"] == "leapfrog"
    # another version
    bad = tmp_path / "old.restart.nc"
    bad.write_bytes(r.checkpoint.read_bytes())
    with netCDF4.Dataset(bad, "a") as ds:
        ds.swe_sphere_version = "0.0.1"
    with pytest.raises(ckpt.CheckpointError, match=f"written by swe_sphere 0.0.1; this is {__version__}"):
        ckpt.read(bad)
    # a run file is not a checkpoint; a text file is not netCDF
    with pytest.raises(ckpt.CheckpointError, match="not a swe_sphere checkpoint"):
        ckpt.read(tmp_path / "run.nc")
    (tmp_path / "junk.nc").write_text("junk")
    with pytest.raises(ckpt.CheckpointError, match="not a readable netCDF file"):
        ckpt.read(tmp_path / "junk.nc")
    # a state of another grid does not fit
    other = make_sim(dataclasses.replace(tc2("leapfrog"), ne=3))
    with pytest.raises(
        ckpt.CheckpointError, match=r"^checkpoint state has shape \(3, 384\), the grid needs \(3, 864\)$"
    ):
        other.restore(ckpt.read(r.checkpoint))


def test_cli_restart_every_and_continue(tmp_path, capsys):
    """Through the CLI: a 2-day run with a restart file every day, cut at day 1 and
    continued to day 2, ends on the same bits; a changed grid or scene is refused
    with one line, exit 2 (another stepper or dt is a branch: tests/simulation/test_branch.py)."""
    scene = write_tc2_scene(tmp_path / "s.toml", stepper="leapfrog_trapezoidal", ne=2, dt=DT, days=2.0)
    args = ["run", str(scene), "--device", "cpu", "--no-progress"]
    assert main([*args, "--output", str(tmp_path / "full.nc")]) == 0
    assert main([*args, "--days", "1", "--output", str(tmp_path / "cut.nc"), "--restart-every", "1"]) == 0
    ck = tmp_path / "cut.restart.nc"
    capsys.readouterr()
    assert main(["run", "--continue", str(ck), "--days", "2", "--no-progress", "--device", "cpu"]) == 0
    out = capsys.readouterr().out
    assert "from " + str(ck) in out and "compile" in out and "ms/step" in out
    with (
        xr.open_dataset(tmp_path / "full.nc", decode_times=False) as a,
        xr.open_dataset(tmp_path / "cut_continued.nc", decode_times=False) as b,
    ):
        np.testing.assert_array_equal(a.h.sel(time=2).values, b.h.sel(time=2).values)
        np.testing.assert_array_equal(a.u.sel(time=2).values, b.u.sel(time=2).values)
    for extra, word in ((["--ne", "3"], "ne = 2"), (["--np", "3"], "np = 4"), (["tc2_steady"], "another scene")):
        code = main(["run", "--continue", str(ck), *extra, "--output", str(tmp_path / "x.nc"), "--device", "cpu"])
        err = capsys.readouterr().err
        assert code == 2 and word in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x.nc").exists()


def test_checkpoint_from_before_a_defaulted_scene_key_continues_bitwise(tmp_path):
    """A restart file written before a scene key with a default existed (its
    scene lacks ``initialization``) continues bitwise; an unknown key, or a
    missing key without a default, is refused as a damaged checkpoint."""
    whole = make_sim(tc2("ssprk3", steps=4, every_steps=2))
    whole.run(tmp_path / "whole.nc")
    r = make_sim(tc2("ssprk3", steps=2)).run(tmp_path / "half.nc", restart_every=2 * DT / DAY)

    def rewrite(edit):
        with netCDF4.Dataset(r.checkpoint, "a") as ds:
            scene = json.loads(ds.scene)
            edit(scene)
            ds.scene = json.dumps(scene)

    rewrite(lambda scene: scene.pop("initialization"))
    cont = Simulation.from_checkpoint(r.checkpoint, "cpu", days=4 * DT / DAY, progress=False)
    assert cont.scene == whole.scene
    cont.run(tmp_path / "cont.nc")
    np.testing.assert_array_equal(cont.x.numpy(), whole.x.numpy())
    for edit, key in ((lambda scene: scene.update(spin=1.0), "spin"), (lambda scene: scene.pop("dt"), "dt")):
        rewrite(edit)
        with pytest.raises(ckpt.CheckpointError, match=f"damaged checkpoint .*scene keys differ .*: {key}\\)$"):
            ckpt.read(r.checkpoint)
        rewrite(lambda scene: scene.pop("spin", None) or scene.setdefault("dt", DT))


# -- signals, through a real process -------------------------------------------


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)], ids=["SIGINT", "SIGTERM"])
def test_signal_keeps_output_and_a_restart_file_that_continues_bitwise(tmp_path, paused, sig, code):
    """``swe-sphere run`` (TC2, ne = 2, leapfrog, 60 s steps for 20 days, progress bar
    on) gets ``sig`` between its steps 5 and 6: it stops after step 5 with its output
    and a restart file, one line; the restart continues bitwise."""
    scene = write_tc2_scene(tmp_path / "long.toml", stepper="leapfrog", ne=2, dt=60.0, days=20.0)
    out = tmp_path / "long.nc"
    proc = paused("step:5", tmp_path, "run", scene, "--device", "cpu", "--output", out)
    proc.send_signal(sig)
    stderr = proc.communicate(timeout=120)[1]
    lines = [line for line in stderr.splitlines() if line.strip() and "step/s" not in line and "%|" not in line]
    assert proc.returncode == code, stderr
    assert len(lines) == 1 and f"interrupted by {sig.name} at step 5" in lines[0] and "Traceback" not in stderr, stderr
    ck = tmp_path / "long.restart.nc"
    assert out.is_file() and ck.is_file() and not (tmp_path / "long.nc.part").exists()
    with xr.open_dataset(out, decode_times=False) as ds:
        step = int(ds.attrs["interrupted_at_step"])
        assert ds.attrs["interrupted"] == sig.name and step == 5
        assert ds.attrs["interrupted_at_day"] == pytest.approx(step * 60.0 / DAY)
        assert float(ds.time[-1]) == pytest.approx(step * 60.0 / DAY)
        h_last = ds.h.values[-1]
    # continue 30 more steps, and run the same 30 + step straight: the same bits
    end_days = (step + 30) * 60.0 / DAY
    cont = Simulation.from_checkpoint(ck, "cpu", days=end_days, progress=False)
    np.testing.assert_array_equal(cont.grid.to_unique(cont.x.numpy()[2]), h_last)
    cont.run(None)
    straight = make_sim(load_scene(tmp_path / "long.toml", days=end_days))
    straight.run(None)
    np.testing.assert_array_equal(cont.x.numpy(), straight.x.numpy())


# -- exclusive outputs -----------------------------------------------------------


def test_output_is_never_overwritten_or_written_through_links(tmp_path, capsys):
    scene = write_tc2_scene(tmp_path / "s.toml", stepper="ssprk3", ne=2, dt=DT, days=0.25)
    run = ["run", str(scene), "--device", "cpu", "--no-progress", "--output"]
    out = tmp_path / "a.nc"
    out.write_text("precious")
    assert main([*run, str(out)]) == 2
    assert "output file exists" in capsys.readouterr().err and out.read_text() == "precious"
    assert main([*run, str(out), "--overwrite"]) == 0
    with xr.open_dataset(out, decode_times=False) as ds:
        assert ds.sizes["time"] == 2
    target = tmp_path / "target.nc"
    target.write_text("target")
    link = tmp_path / "link.nc"
    link.symlink_to(target)
    for extra in ([], ["--overwrite"]):
        assert main([*run, str(link), *extra]) == 2
        assert "symbolic link" in capsys.readouterr().err
    assert link.is_symlink() and target.read_text() == "target"
    fifo = tmp_path / "fifo.nc"
    os.mkfifo(fifo)
    assert main([*run, str(fifo), "--overwrite"]) == 2
    assert "not a regular file" in capsys.readouterr().err
    ro = tmp_path / "ro.nc"
    ro.write_text("ro")
    ro.chmod(0o444)
    if os.access(ro, os.W_OK):  # root may write it, and does
        assert main([*run, str(ro), "--overwrite"]) == 0
    else:
        assert main([*run, str(ro), "--overwrite"]) == 2
        assert "read-only" in capsys.readouterr().err and ro.read_text() == "ro"
    assert main([*run, str(tmp_path / "s.toml" / "o.nc")]) == 2  # a path no one can create, root included
    assert "output path's parent is not a directory" in capsys.readouterr().err
    # remap refuses an existing output too
    (tmp_path / "r.nc").write_text("keep")
    assert main(["remap", str(out), "--output", str(tmp_path / "r.nc")]) == 2
    assert (tmp_path / "r.nc").read_text() == "keep"


def test_a_part_left_by_sigkill_is_replaced_only_with_overwrite(tmp_path, capsys, paused):
    """SIGKILL cannot be caught: the run (killed after its first step) leaves ``.part``
    (and its lock file, no longer held). The next run to that path says so (exit 2)
    and replaces it with --overwrite."""
    scene = write_tc2_scene(tmp_path / "long.toml", stepper="leapfrog", ne=2, dt=60.0, days=20.0)
    out = tmp_path / "k.nc"
    proc = paused("step:1", tmp_path, "run", scene, "--device", "cpu", "--no-progress", "--output", out)
    proc.kill()
    proc.communicate(timeout=60)
    assert (tmp_path / "k.nc.part").exists() and not out.exists()
    short = write_tc2_scene(tmp_path / "short.toml", stepper="ssprk3", ne=2, dt=DT, days=0.25)
    run = ["run", str(short), "--device", "cpu", "--no-progress", "--output", str(out)]
    assert main(run) == 2
    err = capsys.readouterr().err
    assert "k.nc.part was left by a run that was killed (--overwrite" in err and len(err.strip().splitlines()) == 1
    assert main([*run, "--overwrite"]) == 0
    with xr.open_dataset(out, decode_times=False) as ds:
        assert ds.sizes["time"] == 2
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("k.nc")) == ["k.nc"]


def test_concurrent_writers(tmp_path, capsys):
    """While one writer holds ``a.nc.lock`` (and its O_EXCL ``a.nc.part``), a second
    run to ``a.nc`` gets one line and exit 2 and touches nothing; the first then
    finishes a valid file. Also with --overwrite, and from another process."""
    scene = write_tc2_scene(tmp_path / "s.toml", stepper="ssprk3", ne=2, dt=DT, days=0.25)
    out = tmp_path / "a.nc"
    first = make_sim(load_scene(scene))
    from swe_sphere.io.run_file import RunWriter

    writer = RunWriter(out, first.grid, first.hs, {"title": "first"}, ["mass"])
    for extra in ([], ["--overwrite"]):
        code = main(["run", str(scene), "--device", "cpu", "--no-progress", "--output", str(out), *extra])
        err = capsys.readouterr().err
        assert code == 2 and "another run is writing" in err and len(err.strip().splitlines()) == 1
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "swe_sphere.cli",
            "run",
            str(scene),
            "--device",
            "cpu",
            "--output",
            str(out),
            "--overwrite",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert (
        proc.returncode == 2
        and proc.stderr.strip() == f"swe-sphere: error: another run is writing {out} (it holds {out}.lock)"
    )
    writer.append(0.0, *first.fields(), {"mass": 1.0})
    writer.close()
    with xr.open_dataset(out, decode_times=False) as ds:
        assert ds.attrs["title"] == "first" and ds.sizes["time"] == 1
    with pytest.raises(OutputError, match="another run is writing"):
        with ExclusiveFile(tmp_path / "b.nc"):
            ExclusiveFile(tmp_path / "b.nc")


def test_continue_at_the_end_day_without_days_is_refused(tmp_path, capsys, monkeypatch):
    """``--continue R.restart.nc`` of a finished run, no --days: it ran 0 steps, exit 0, and
    wrote R_continued.nc, which then blocked the real continuation. Now exit 2, nothing written."""
    monkeypatch.chdir(tmp_path)
    run = ["run", "tc2_steady", *TINY, "--dt", "1800", "--days", "0.25", "-s", "output.every_days=0.25"]
    assert cli_main(capsys, *run, "--restart-every", "0.25", "--output", "r.nc")[0] == 0
    before = sorted(p.name for p in tmp_path.iterdir())
    cli_one_line(
        capsys,
        ["run", "--continue", "r.restart.nc", "--device", "cpu", "--no-progress"],
        2,
        "r.restart.nc is already at its run's end day 0.25",
        "--days",
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert (
        cli_main(capsys, "run", "--continue", "r.restart.nc", "--days", "0.5", "--device", "cpu", "--no-progress")[0]
        == 0
    )
    assert (tmp_path / "r_continued.nc").is_file()


def test_a_scaled_dt_is_cut_to_divide_the_restart_interval_and_a_given_one_is_refused(tmp_path, capsys, monkeypatch):
    """--restart-every 0.2 at ne2, whose dt the scene scales (to divide the output interval and
    the run: 2356 s, 7.3 steps in 0.2 days): the dt is cut to divide 0.2 days too, a note says so, and the restart file is at the
    run's end; with a dt given that does not divide it, one line and nothing written."""
    monkeypatch.chdir(tmp_path)
    from swe_sphere.simulation import checkpoint

    run = ["run", "tc2_steady", *TINY, "--days", "0.6", "--restart-every", "0.2"]
    code, out, err = cli_main(capsys, *run, "--output", "r.nc")
    assert code == 0, err
    assert sum("to divide the restart interval of 0.2 days" in line for line in out.splitlines()) == 1, out
    ck = checkpoint.read(tmp_path / "r.restart.nc")
    per = 0.2 * DAY / ck.scene.dt
    assert abs(per - round(per)) < 1e-9 and ck.step == 3 * round(per) and ck.day == pytest.approx(0.6)
    cli_one_line(capsys, [*run, "--dt", "3240", "--output", "y.nc"], 2, "restart interval of 0.2 days")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.nc", "r.restart.nc"]


def test_a_continued_run_keeps_writing_restart_files(tmp_path, capsys, monkeypatch):
    """A run with --restart-every 0.125, continued without it: the continuation writes
    its restart file at its interval (the header says so), which continues again."""
    monkeypatch.chdir(tmp_path)
    from swe_sphere.simulation import checkpoint

    run = ["run", "tc2_steady", *TINY, *EIGHTH_DAY]
    assert cli_main(capsys, *run, "--restart-every", "0.125", "--output", "r.nc")[0] == 0
    assert checkpoint.read(tmp_path / "r.restart.nc").restart_every == 0.125
    code, out, err = cli_main(
        capsys, "run", "--continue", "r.restart.nc", "--days", "0.25", "--device", "cpu", "--no-progress"
    )
    assert code == 0, err
    assert "every 0.125 days and at the end" in out
    again = checkpoint.read(tmp_path / "r_continued.restart.nc")
    assert (again.step, again.restart_every) == (12, 0.125)
    # its restart file there already: refused as a given --restart-every's is, one line before any header
    (tmp_path / "r_continued.nc").unlink()
    code, out, err = cli_main(
        capsys, "run", "--continue", "r.restart.nc", "--days", "0.25", "--device", "cpu", "--no-progress"
    )
    assert code == 2 and out == "" and "output file exists: r_continued.restart.nc" in err
    assert (
        checkpoint.read(tmp_path / "r_continued.restart.nc").step == 12 and not (tmp_path / "r_continued.nc").exists()
    )
