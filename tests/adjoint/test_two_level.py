"""Two-level checkpointing (``revolve.two_level``, ``gradient(..., disk=...)``): the forward
steps against the formula, the states held, the same gradient bits as in memory alone, the
states' file gone afterwards."""

from __future__ import annotations

import functools
import os

import numpy as np
import pytest

from swe_sphere.adjoint import HeightMisfit, gradient
from swe_sphere.adjoint.gradient import scene_model
from swe_sphere.adjoint.revolve import griewank_steps, two_level, two_level_steps
from swe_sphere.config.scene import load_scene
from swe_sphere.core.errors import ArgumentError


class State:
    """A counted state: ``live`` the instances alive, ``most`` the most at once."""

    live = most = 0

    def __init__(self, k):
        self.k = k
        State.live += 1
        State.most = max(State.most, State.live)

    def __del__(self):
        State.live -= 1


class Tier(dict):
    def save(self, j, x):
        self[j] = x.k

    def load(self, j):
        return State(self[j])


@pytest.mark.parametrize(
    ("n", "snapshots", "interval"), [(10, 3, 3), (7, 1, 2), (12, 4, 5), (5, 9, 9), (60, 5, 13), (9, 2, 1)]
)
def test_two_level_reverses_every_step_once_in_order_with_the_formulas_steps(n, snapshots, interval):
    seen, ends = [], []

    def advance(x, k, steps):
        assert steps >= 1 and x.k == k
        x.k += steps

    x = State(0)
    State.live, State.most = 0, 0  # x0 (advanced to x(n), the final state) not counted
    tier = Tier()
    taken = two_level(
        n, snapshots, interval, x, advance, lambda x, k: seen.append((k, x.k)), lambda x: State(x.k), tier, ends.append
    )
    assert ends == [x] and x.k == n
    assert seen == [(k, k) for k in reversed(range(n))]
    assert tier == {j: j * interval for j in range(-(-n // interval))}
    assert taken == two_level_steps(n, snapshots, interval)
    # states held at once by the sweeps, the loaded one included; where a segment is longer
    # than the snapshots, revolve's work copy besides (``sweep``'s count, Griewank & Walther's)
    assert State.most <= snapshots + (interval > snapshots)


def test_two_level_steps_formula():
    assert two_level_steps(1284, 30, 30) == 2 * 1284 - 43 == 2525  # 42 segments of 30, one of 24
    assert two_level_steps(1284, 30, 30) == 1284 + 42 * 29 + 23
    assert two_level_steps(60, 5, 13) == 60 + 4 * griewank_steps(13, 5) + griewank_steps(8, 5)
    assert two_level_steps(48, 4, 1) == 48  # every state on the disk: each step once
    for n in range(1, 40):
        for k in range(1, 8):
            assert two_level_steps(n, k, k) == 2 * n - -(-n // k)


@functools.cache
def tc5():
    """TC5 at ne 4 np 4, rk4, Δt 900 s (every term, the ∇⁴)."""
    scene = load_scene("testcases/tc5_mountain.toml", ne=4, np_=4, dt=900.0, stepper="rk4")
    x0 = scene_model(scene)[2]
    return scene, HeightMisfit(x0[2] + 10.0), gradient(scene, 30, HeightMisfit(x0[2] + 10.0), parameters=True)


@pytest.mark.parametrize(("snapshots", "interval"), [(3, None), (2, 5), (4, 7), (30, None), (5, 1), (3, 40)])
def test_a_two_level_gradient_is_the_same_bits_as_in_memory(tmp_path, snapshots, interval):
    scene, cost, every = tc5()
    g = gradient(scene, 30, cost, snapshots=snapshots, disk=tmp_path, disk_interval=interval, parameters=True)
    for a, b in [(g.grad, every.grad), (g.final, every.final), (g.d_hs, every.d_hs)]:
        np.testing.assert_array_equal(a, b)
    assert (g.cost, g.d_nu, g.d_nu_s) == (every.cost, every.d_nu, every.d_nu_s)
    K = interval or snapshots
    assert g.forward_steps == two_level_steps(30, snapshots, K)
    assert g.disk_bytes == -(-30 // K) * 3 * 1536 * 8  # ⌈n/K⌉ states of 3 × N float64
    assert os.listdir(tmp_path) == []


def test_the_states_file_is_gone_after_an_error_and_bad_disks_are_refused(tmp_path):
    scene, cost, _ = tc5()
    seen = []

    def failing(x, area):
        seen.append(os.listdir(tmp_path))
        raise RuntimeError("cost failed")

    fds = len(os.listdir("/proc/self/fd")) if os.path.isdir("/proc/self/fd") else None
    with pytest.raises(RuntimeError, match="cost failed"):
        gradient(scene, 6, failing, snapshots=2, disk=tmp_path)
    assert seen == [[]] and os.listdir(tmp_path) == []  # the file has no name, then is closed
    if fds is not None:
        assert len(os.listdir("/proc/self/fd")) == fds
    with pytest.raises(ValueError, match="an existing folder"):
        gradient(scene, 2, cost, disk=tmp_path / "absent")
    with pytest.raises(ArgumentError, match="disk_interval needs a disk"):
        gradient(scene, 2, cost, disk_interval=2)
    with pytest.raises(ArgumentError, match="disk_interval must be an integer >= 1"):
        gradient(scene, 2, cost, disk=True, disk_interval=0)
