"""The ∇⁴'s weak Laplacians with several elements a vector (``kernels.hyperviscosity.laplacian_across``,
the CPU's form at np ≥ 5) give the rows' bits (``laplacian_element``, one element a thread): the
operator and a few applications, forward Euler and RKL1, on cubes whose element count is not a
multiple of the lanes (the rest on rows), split over two threads, and on an icosahedral mesh."""

from __future__ import annotations

import numpy as np
import pytest

from swe_sphere.kernels import hyperviscosity as hv_kernels


def test_across_layout():
    """G[k, b np² + n, w] = a[k, (W b + w) np² + n], the elements past the last block left out."""
    np_, lanes, nelem = 5, 4, 9
    a = np.arange(2 * nelem * np_**2, dtype=float).reshape(2, nelem * np_**2)
    g = hv_kernels.across_layout(a, lanes, np_)
    assert g.shape == (2, 2 * np_**2, lanes)
    assert g[1, np_**2 + 7, 3] == a[1, (lanes + 3) * np_**2 + 7]


def test_across_wants_np_5():
    with pytest.raises(ValueError, match="np >= 5"):
        hv_kernels.laplacian_across(False, False, 4, 16)
