"""The ∇⁴'s weak Laplacians with several elements a vector (``kernels.hyperviscosity_across.laplacian_across``,
the CPU's form at np ≥ 5) give the rows' bits (``laplacian_element``, one element a thread): the
operator and a few applications, forward Euler and RKL1, on cubes whose element count is not a
multiple of the lanes (the rest on rows), split over two threads, and on an icosahedral mesh;
in float32 too."""

from __future__ import annotations

from unittest import mock

import numpy as np
import pytest
import warp as wp

from swe_sphere.cases.library import make_case
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.kernels import hyperviscosity_across as hv_kernels
from swe_sphere.kernels import operators
from swe_sphere.model.hyperviscosity import Hyperviscosity
from swe_sphere.model.shallow_water import ShallowWater

from helpers import cached_grid
from meshes import icosahedral_mesh

GRIDS = {
    "cube ne2 np5": (lambda: cached_grid(2, 5), 1),  # 24 elements: a block of 16, 8 on rows
    "cube ne3 np6": (lambda: cached_grid(3, 6), 1),
    "cube ne2 np7": (lambda: cached_grid(2, 7), 1),
    "cube ne4 np8, two threads": (lambda: cached_grid(4, 8), 2),  # 6 blocks in two ranges
    "icosahedral np5 (valence 3-6)": (lambda: CubedSphere(0, 5, mesh=icosahedral_mesh(1)), 1),
}


def model(g, lanes: int, threads: int, divergent: bool, precision: str = "float64") -> ShallowWater:
    """TC5's ∇⁴ on g with ``lanes`` elements a vector (0: the rows); ``divergent``: with
    ν_div ≠ ν (the ∇δ term) and the tensor's second Laplacian (``hypervis_scaling``); in
    ``precision`` (float32: the free surface from H₀ = 5 km)."""
    c = make_case("tc5_mountain")
    extra = {"nu_div": 2.5e15, "hypervis_scaling": 3.2} if divergent else {}
    with mock.patch.object(Hyperviscosity, "across_elements", lanes):
        return ShallowWater(
            g,
            ["hyperviscosity"],
            c.fcor(g.lat, g.lon),
            c.hs(g.lat, g.lon),
            nu=1e15,
            device="cpu",
            threads=threads,
            precision=precision,
            depth=5.0e3 if precision == "float32" else None,
            **extra,
        )


def outputs(m: ShallowWater) -> list[np.ndarray]:
    """B x of TC5's state, then the state after the ∇⁴ applied by forward Euler and by RKL1."""
    c = make_case("tc5_mountain")
    x = m.new_state(*np.array(c.initial(m.grid.lat, m.grid.lon)))
    out = wp.zeros_like(x)
    m.hv.operator(x, out)
    got = [out.numpy()]
    m.hv.rkl1(x, 3600.0, 3)
    got.append(x.numpy())
    for _ in range(2):
        m.hyperviscosity(x, 600.0)
    got.append(x.numpy())
    return got


@pytest.mark.parametrize("divergent", [False, True], ids=["nu_div = nu", "nu_div != nu, tensor"])
@pytest.mark.parametrize("name", list(GRIDS))
def test_across_gives_the_rows_bits(name, divergent):
    make, threads = GRIDS[name]
    g = make()
    across, rows = model(g, 16, threads, divergent), model(g, 0, threads, divergent)
    assert across.hv.lanes == 16 and rows.hv.lanes == 0
    for got, want in zip(outputs(across), outputs(rows)):
        assert np.array_equal(got.view(np.int64), want.view(np.int64))


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("np_", [6, 8])
@pytest.mark.parametrize("divergent", [False, True], ids=["nu_div = nu", "nu_div != nu, tensor"])
def test_across_gives_the_rows_bits_in_float32(divergent, np_, threads):
    """A float32 ∇⁴ (``ShallowWater``'s precision; 16 float32 elements a vector, one AVX-512
    register) across elements has its rows' bits too: cube ne3 np6 (lane by lane), and ne4 np8
    (``hyperviscosity_across.shuffled``: 16 × 16 transposes) on one and two threads."""
    g = cached_grid(3 if np_ == 6 else 4, np_)
    across, rows = model(g, 16, threads, divergent, "float32"), model(g, 0, threads, divergent, "float32")
    assert across.hv.lanes == 16 and rows.hv.lanes == 0 and across.hv.hv_L.dtype == wp.float32
    for got, want in zip(outputs(across), outputs(rows)):
        assert np.array_equal(got.view(np.int64), want.view(np.int64))


def test_where_the_rows_stay():
    """np ≤ 4, fewer elements than the lanes, and the switch off keep the rows; the kernel
    refuses np < 5."""
    assert model(cached_grid(2, 4), 16, 1, False).hv.lanes == 0
    assert model(cached_grid(1, 6), 16, 1, False).hv.lanes == 0  # 6 elements
    assert model(cached_grid(2, 6), 1, 1, False).hv.lanes == 0
    with pytest.raises(ValueError, match="np >= 5"):
        hv_kernels.laplacian_across(False, False, 4, 16)


def test_across_layout():
    """G[k, b np² + n, w] = a[k, (W b + w) np² + n], the elements past the last block left out,
    or with pad in a last block whose lanes past the last element repeat it."""
    np_, lanes, nelem = 5, 4, 9
    a = np.arange(2 * nelem * np_**2, dtype=float).reshape(2, nelem * np_**2)
    g = operators.across_layout(a, lanes, np_)
    assert g.shape == (2, 2 * np_**2, lanes)
    assert g[1, np_**2 + 7, 3] == a[1, (lanes + 3) * np_**2 + 7]
    padded = operators.across_layout(a, lanes, np_, pad=True)
    assert padded.shape == (2, 3 * np_**2, lanes)
    assert np.array_equal(padded[:, : 2 * np_**2], g)
    assert np.array_equal(padded[0, 2 * np_**2 + 7], np.full(lanes, a[0, 8 * np_**2 + 7]))
