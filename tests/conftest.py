"""Shared fixtures for the swe_sphere tests."""

from __future__ import annotations

import dataclasses
import functools
import time

import numpy as np
import pytest
import warp as wp

wp.config.quiet = True  # Warp < 1.10; newer Warp reads log_level instead
if hasattr(wp, "LOG_WARNING"):
    wp.config.log_level = wp.LOG_WARNING

from swe_sphere.config import load_scene  # noqa: E402
from swe_sphere.grid import CubedSphere  # noqa: E402
from swe_sphere.simulation import BlowUp, Simulation  # noqa: E402

def requires_cuda(func):
    """Mark a test as a GPU test that is skipped cleanly without CUDA."""
    return pytest.mark.gpu(pytest.mark.skipif(not wp.is_cuda_available(), reason="needs a CUDA device")(func))


@functools.lru_cache(maxsize=None)
def cached_grid(ne: int, np_: int) -> CubedSphere:
    """One CubedSphere per (ne, np) for the whole session (treat as read-only)."""
    return CubedSphere(ne, np_)


@pytest.fixture(scope="session")
def grid_factory():
    """``grid_factory(ne, np)`` → a cached, read-only CubedSphere."""
    return cached_grid


@pytest.fixture(scope="session")
def small_grid():
    """ne = 2, np = 4: 24 elements, 384 element-local nodes."""
    return cached_grid(2, 4)


def make_sim(scene):
    """A CPU Simulation of ``scene`` without a progress bar."""
    return Simulation(scene, "cpu", progress=False)


def run(scene):
    """(RunResult, Simulation, wall seconds); a blow-up returns its partial result."""
    sim = make_sim(scene)
    t0 = time.perf_counter()
    try:
        result = sim.run()
    except BlowUp as err:
        result = err.result
    return result, sim, time.perf_counter() - t0


@functools.lru_cache(maxsize=None)
def tc6_inviscid(days: float):
    """TC6 at ne = 4 np = 4 for ``days``, without hyperviscosity, one output at the end
    (the temporal-order tests' case)."""
    scene = load_scene("tc6_rossby_haurwitz", ne=4, np=4, days=days)
    terms = tuple(t for t in scene.terms if t != "hyperviscosity")
    return dataclasses.replace(scene, terms=terms, nu=0.0, output_every_days=days)


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)


TC2_SCENE = """
description = "TC2 for a test"
terms = ["continuity", "momentum_advection", "coriolis", "pressure_gradient"]

[case]
name = "tc2_steady"

[grid]
ne = {ne}
np = 4

[time]
stepper = "{stepper}"
dt = {dt!r}
days = {days!r}
{tables}
"""


def write_tc2_scene(path, *, stepper="ssprk3", ne=2, dt=3600.0, days=1.0, tables=""):
    """Write a TC2 scene file (``tables``: extra TOML, e.g. a stepper's options); returns its path."""
    path.write_text(TC2_SCENE.format(ne=ne, stepper=stepper, dt=dt, days=days, tables=tables))
    return path
