"""A sweep's processes: BLAS threads of a worker, a signal in a run or a pool, a folder changed under a sweep."""

import time
from pathlib import Path

import pytest

from swe_sphere.cli import main
from swe_sphere.core import workers as workers_mod
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.studies.sweep import runs

from helpers import TINY_SWEEP, cli_one_line, without_sweep_figures


def _blas_threads():
    import scipy.sparse.linalg  # noqa: F401  (what the Helmholtz CG loads)
    from threadpoolctl import threadpool_info

    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}), len(threadpool_info())


def test_a_sweep_worker_runs_blas_on_its_share_of_the_cores(monkeypatch):
    """Each of N workers runs numpy's and scipy's BLAS (the Helmholtz CG's inner
    products) on cpus // N threads, although a spawned worker loads neither
    library before its first run (a limit set earlier reaches no library)."""
    monkeypatch.delenv("SWE_SPHERE_THREADS", raising=False)
    monkeypatch.setattr(workers_mod, "cpus", lambda: 2)
    with workers_mod.executor(2) as pool:
        threads, libraries = pool.submit(_blas_threads).result()
    assert threads == [1] and libraries >= 2  # numpy's OpenBLAS and scipy's


def _signal_at_the_start_of(dt, monkeypatch):
    """Simulation.run of the run with this Δt gets SIGINT at its first output time
    (its handler notes it; the run stops after its first step)."""
    import signal

    real_run = Simulation.run

    def run(self, output=None, **kw):
        if self.scene.dt == dt:
            inner = kw["on_output"]
            kw["on_output"] = lambda step, x: inner(step, x) or signal.raise_signal(signal.SIGINT)
        return real_run(self, output, **kw)

    monkeypatch.setattr(Simulation, "run", run)


def test_an_interrupted_sweep_says_what_it_kept_and_a_rerun_reuses_it(tmp_path, capsys, monkeypatch):
    """SIGINT in the second of two runs: exit 130, one line saying the small-Δt run and
    1 of 2 runs are kept (not "no output was written"); the rerun reuses them. SIGINT
    in the small-Δt run: the line says it is not kept and will be made again."""
    without_sweep_figures(monkeypatch)
    out = tmp_path / "sweep"
    args = [
        *TINY_SWEEP,
        "--output",
        str(out),
    ]
    with monkeypatch.context() as m:
        _signal_at_the_start_of(3600.0, m)
        assert main(args) == 130
    err = capsys.readouterr().err
    assert err == (
        f"swe-sphere: interrupted by SIGINT: the reference run and 1 of 2 runs are kept in {out / 'runs'}; a rerun of "
        "the same command reuses them and makes the other 1\n"
    )
    assert sorted(p.name for p in (out / "runs").iterdir()) == ["reference_rk4_450.npz", "ssprk3_1800.json"]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "reference run: rk4, dt = 450 s: reused" in text and "[1/2] ssprk3 dt = 1800 s: reused" in text
    assert "runs: 1 reused, 1 made" in text

    other = tmp_path / "other"
    with monkeypatch.context() as m:
        _signal_at_the_start_of(450.0, m)
        assert main([*args[:-1], str(other)]) == 130
    err = capsys.readouterr().err
    assert err == (
        "swe-sphere: interrupted by SIGINT in the sweep's reference run (rk4, dt = 450 s) at model day 0, which is not "
        f"kept (a rerun of the same command makes it again); the runs already in {other / 'runs'} are kept\n"
    )
    assert list((other / "runs").iterdir()) == []


def _wait_for(started, path, most=60.0):
    """Say it has started (touch ``started``), then wait until ``path`` exists (it
    never will: a task that runs until it is ended)."""
    started.touch()
    t0 = time.perf_counter()
    while not path.exists() and time.perf_counter() - t0 < most:
        time.sleep(0.05)
    return "waited"


def test_a_signal_in_a_pool_ends_its_tasks_under_way_and_queued(tmp_path):
    """KeyboardInterrupt (a Ctrl-C in the main process) leaving ``executor(2)``'s block
    once both workers run a task (each waits for an event that never comes) ends
    both tasks and the one queued behind them (it would write a file), and leaves
    no worker behind."""
    import multiprocessing

    before = set(multiprocessing.active_children())
    started = [tmp_path / f"started{i}" for i in range(2)]
    with pytest.raises(KeyboardInterrupt):
        with workers_mod.executor(2) as pool:
            waiting = [pool.submit(_wait_for, s, tmp_path / "never") for s in started]
            queued = pool.submit(Path.touch, tmp_path / "queued")
            while not all(s.exists() for s in started):
                time.sleep(0.05)
            t0 = time.perf_counter()
            raise KeyboardInterrupt
    assert time.perf_counter() - t0 < 50  # not the 60 s the tasks would wait
    for future in (*waiting, queued):
        assert isinstance(future.exception(), KeyboardInterrupt)
    assert not (tmp_path / "queued").exists()
    assert set(multiprocessing.active_children()) == before


def _source_changed(m):
    """A run's process whose swe_sphere source is not the one the sweep started with (a
    worker started after an edit)."""
    m.setattr(runs, "code_version", lambda: {"version": "0", "source_sha256": "0123456789abcdef"})


def _reference_removed(m):
    """The reference run's file removed by another process once it was made."""
    warm_up = runs.Sweep.warm_up

    def removing(self, stepper):
        self.reference_path().unlink()
        return warm_up(self, stepper)

    m.setattr(runs.Sweep, "warm_up", removing)


@pytest.mark.parametrize(
    "change, words",
    [
        (
            _source_changed,
            ("the swe_sphere source changed while the sweep ran", "0123456789abcdef", "run the sweep again"),
        ),
        (
            _reference_removed,
            ("reference_rk4_450.npz: the sweep's reference run was removed while", "run the sweep again"),
        ),
    ],
    ids=["source", "reference"],
)
def test_a_sweep_whose_folder_changes_under_it_says_so_in_one_line(tmp_path, capsys, monkeypatch, change, words):
    """Runs that could not be told apart from another version's ended in "internal error:
    RuntimeError"; the default folder is the scene's, grid's and length's."""
    monkeypatch.chdir(tmp_path)
    with monkeypatch.context() as m:
        change(m)
        cli_one_line(capsys, TINY_SWEEP, 2, *words)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sweep_tc2_steady_ne2np4_1d"]
