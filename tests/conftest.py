"""Shared fixtures for the swe_sphere tests."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import warp as wp

wp.config.quiet = True  # Warp < 1.10; newer Warp reads log_level instead
if hasattr(wp, "LOG_WARNING"):
    wp.config.log_level = wp.LOG_WARNING

from swe_sphere.grid import CubedSphere  # noqa: E402

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


@pytest.fixture
def rng():
    return np.random.default_rng(20240611)
