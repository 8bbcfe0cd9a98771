"""HOMME's tensor hyperviscosity (``hyperviscosity.scaling = s``; Guba, Taylor, Ullrich, Overfelt &
Levy 2014): V from the metric inverse's eigen-decomposition, ν·V the effective ν ∝ Δx^s along each
element direction, normalised to 1 at the face-centre spacing d_ref of the uniform cube with as
many elements (``grid.quality.hypervis_tensor``).

The exact relations tested against the constant-ν operator: s = 0 gives V = I, so the tensor ∇⁴
is the constant-ν ∇⁴ (to round-off, both layouts); s = 4 gives V = (D Dᵀ)² / d_ref⁴ node by node,
the e-fold rule's ν ∝ Δx⁴ at each node's own spacing, and at the uniform cube's face centres, where
the equiangular map is conformal with D's singular value d_ref (up to the area correction), the V
the operator uses is (metdet / d_ref²)² I: the constant ν there."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp
from test_mpi import assert_same_bits, launches, over_ranks  # noqa: F401 (fixtures)

from swe_sphere.cli import main
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.quality import dinv_singular_values, hypervis_tensor, reference_spacing
from swe_sphere.mesh.schmidt import schmidt_cube
from swe_sphere.model.diagnostics import harmonic_state, hyperviscosity_rate
from swe_sphere.model.shallow_water import ShallowWater

from helpers import cli_one_line
from roundoff import bound, mass_change_bound, operator_roundings, within


def hv_model(grid, scaling, per_element=True, nu=1.0):
    z = np.zeros(grid.nnodes)
    return ShallowWater(
        grid, ["hyperviscosity"], z, z, nu=nu, device="cpu", per_element=per_element, hypervis_scaling=scaling
    )


def bump(grid, centre, sigma):
    """exp(−θ²/2σ²), θ the angle (rad) from the unit vector ``centre``: h of a state, no wind."""
    theta = np.arccos(np.clip(np.asarray(centre) @ grid.xyz, -1, 1))
    z = np.zeros(grid.nnodes)
    return z, z, np.exp(-((theta / sigma) ** 2) / 2)


def test_the_tensor_is_the_metric_inverse_to_the_power_1_minus_s_over_2():
    """Node by node: s = 0 gives V = I, s = 4 gives (D Dᵀ)² / d_ref⁴ (d_ref = πa/(4 ne)), to the
    round-off of a 2×2 eigen-decomposition and a few products (each ≤ 16 roundings of the result)."""
    grid = CubedSphere(4, 4)
    V0 = hypervis_tensor(grid, 0.0)
    within(float(np.abs(V0 - np.array([[1.0], [0.0], [1.0]])).max()), bound(16), "V(s=0) - I")
    D = grid.D.T.reshape(-1, 2, 2)
    DDt = D @ D.transpose(0, 2, 1) / reference_spacing(grid) ** 2
    W = DDt @ DDt
    V4 = hypervis_tensor(grid, 4.0)
    expected = np.stack([W[:, 0, 0], W[:, 0, 1], W[:, 1, 1]])
    within(float(np.abs(V4 - expected).max()), bound(16, float(np.abs(W).max())), "V(s=4) - (D Dt)^2 / d_ref^4")
    assert reference_spacing(grid) == math.pi * grid.radius / 16
    with pytest.raises(ValueError, match="scaling"):
        hypervis_tensor(grid, -1.0)


@pytest.mark.parametrize("per_element", [True, False])
def test_scaling_0_is_the_constant_nu_operator(per_element):
    """s = 0: the tensor ∇⁴ (its own metric, and on the per-node layout its own flux kernel)
    equals the constant-ν ∇⁴ on a harmonic state, both ν, ν_div ≠ ν and ν_s, to the round-off of
    the second pass's metric (Dinv I Dinvᵀ formed another way): ``operator_roundings`` of two
    passes of the largest |B x|."""
    grid = CubedSphere(4, 4)
    z = np.zeros(grid.nnodes)
    state = np.stack(
        [harmonic_state(grid, 5, kind)[row] for kind, row in (("rotational", 0), ("divergent", 1), ("height", 2))]
    )
    out = []
    for scaling in (None, 0.0):
        model = ShallowWater(
            grid,
            ["hyperviscosity"],
            z,
            z,
            nu=1e15,
            nu_div=2e15,
            nu_s=5e14,
            device="cpu",
            per_element=per_element,
            hypervis_scaling=scaling,
        )
        x = model.new_state(*state)
        b = wp.zeros_like(x)
        model.hv.operator(x, b)
        out.append(b.numpy())
    scale = float(np.abs(out[0]).max())
    within(float(np.abs(out[1] - out[0]).max()), bound(operator_roundings(4, 2), scale), "tensor s=0 - constant")


def test_scaling_4_is_the_constant_nu_at_the_cube_face_centres():
    """s = 4 on the uniform cube (ne 8, even: each face centre is an element corner): the V the
    operator uses (after its DSS and bilinear interpolation) at the six face centres is
    (metdet / d_ref²)² I to round-off (the equiangular map is conformal there; metdet / d_ref² is
    the area correction, 1 − 1.5e-9), so ν_eff = ν there; elsewhere the elements are smaller and
    a low-degree harmonic of h decays at the constant-ν rate times the area mean of V's isotropic
    part (0.80 at ne 8; measured within 2.5 % at l = 3 and 6)."""
    grid = CubedSphere(8, 4)
    model = hv_model(grid, 4.0)
    metric = model.hv.hv_tensor.numpy()
    iso = metric[3] / grid.spheremp  # tr V / 2
    d_ref = reference_spacing(grid)
    centres = np.concatenate([np.eye(3), -np.eye(3)])
    nodes = np.argmax(centres @ grid.xyz, axis=1)
    assert np.allclose(np.abs(grid.xyz[:, nodes].T), np.abs(centres), atol=1e-15)
    expected = (grid.metdet[nodes] / d_ref**2) ** 2
    within(float(np.abs(iso[nodes] - expected).max()), bound(32), "tr V / 2 at the face centres")
    assert np.abs(expected - 1).max() < 1e-8
    # isotropic there: the metric is metdet·(tr V/2)·Dinv Dinvᵀ = (tr V/2) · the constant operator's
    Dinv = grid.Dinv[:, nodes]
    g_const = grid.spheremp[nodes] * np.stack(
        [Dinv[0] ** 2 + Dinv[1] ** 2, Dinv[0] * Dinv[2] + Dinv[1] * Dinv[3], Dinv[2] ** 2 + Dinv[3] ** 2]
    )
    within(
        float(np.abs(metric[:3, nodes] - iso[nodes] * g_const).max() / np.abs(g_const).max()),
        bound(64),
        "tensor metric - constant metric at the face centres",
    )
    mean_iso = grid.integrate(iso) / grid.integrate(np.ones(grid.nnodes))
    assert 0.79 < mean_iso < 0.82
    constant = hv_model(grid, None)
    for l in (3, 6):
        state = harmonic_state(grid, l, "height")
        ratio = hyperviscosity_rate(model, state) / hyperviscosity_rate(constant, state)
        assert ratio == pytest.approx(mean_iso, rel=0.03), l


def test_the_damping_on_a_stretched_cube_scales_with_the_local_spacing_to_the_power_s():
    """A Schmidt cube (ne 8, c = 2) toward the north pole: a Gaussian bump of h (σ = 0.2 rad)
    at the target and at its antipode, where the stretch is stationary and isotropic (face
    centres), spacings d_t, d_a (1 / σ_max of Dinv there; d_a / d_t = 3.86 ≈ c²). Its damping
    rate r (``hyperviscosity_rate``) goes as d^s: ln(r_t / r_a) / ln(d_t / d_a) = s within 0.05
    for s = 3.2 and 4 (measured 3.185, 3.983), and 0 within 0.01 for constant ν (−0.005)."""
    grid = CubedSphere(8, 4, mesh=schmidt_cube(8, 2.0, 90.0, 0.0))
    north = np.array([0.0, 0.0, 1.0])
    large, small = dinv_singular_values(grid.Dinv)
    nodes = [int(np.argmax(grid.xyz.T @ north)), int(np.argmin(grid.xyz.T @ north))]
    assert np.allclose(large[nodes], small[nodes], rtol=1e-12)  # isotropic
    d_t, d_a = 1 / large[nodes]
    assert d_a / d_t == pytest.approx(3.86, rel=1e-3)
    for scaling, tolerance in ((None, 0.01), (3.2, 0.05), (4.0, 0.05)):
        model = hv_model(grid, scaling)
        r_t, r_a = (hyperviscosity_rate(model, bump(grid, c, 0.2)) for c in (north, -north))
        slope = math.log(r_t / r_a) / math.log(d_t / d_a)
        assert slope == pytest.approx(scaling or 0.0, abs=tolerance), (scaling, slope)


def test_scaling_4_gives_a_stretched_cube_the_uniform_cubes_hyperviscous_limit():
    """The ∇⁴ substeps follow the operator's largest eigenvalue λ (``biharmonic_radius``), the
    worst element's: on the ne 8 cube stretched by c = 2.5, constant ν's λ is 17.7× the uniform
    cube's (its smallest elements, ∝ Δx⁻⁴), while s = 4 keeps every element's ∇⁴ Courant number
    alike: λ within 5 % of its own on the uniform cube (measured 3 %); s = 3.2 between (1.79×)."""
    uniform = CubedSphere(8, 4, mesh=schmidt_cube(8, 1.0))
    stretched = CubedSphere(8, 4, mesh=schmidt_cube(8, 2.5, 40.0, 270.0))
    lam = {
        (c, s): hv_model(g, s).hv.biharmonic_radius()
        for c, g in ((1, uniform), (2.5, stretched))
        for s in (None, 3.2, 4.0)
    }
    assert lam[2.5, None] / lam[1, None] == pytest.approx(17.7, rel=0.02)
    assert lam[2.5, 4.0] / lam[1, 4.0] == pytest.approx(1.0, abs=0.05)
    assert 1.2 < lam[2.5, 3.2] / lam[1, 3.2] < lam[2.5, None] / lam[1, None] / 4


def test_the_tensor_hyperviscosity_keeps_mass():
    """20 forward-Euler ∇⁴ substeps of s = 3.2 on a stretched cube (per-node and per-element
    layouts) change the mass Σ spheremp·h by round-off only (``mass_change_bound``), while they
    change h itself by far more."""
    grid = CubedSphere(4, 4, mesh=schmidt_cube(4, 2.0, 40.0, 270.0))
    h0 = 5000 + 100 * harmonic_state(grid, 7, "height")[2]
    for per_element in (True, False):
        model = hv_model(grid, 3.2, per_element=per_element, nu=4e17)  # the 3 h e-folding rule at ne 4
        model.hypervis_subcycle = 20
        x = model.new_state(np.zeros(grid.nnodes), np.zeros(grid.nnodes), h0)
        mass0 = grid.integrate(x.numpy()[2])
        model.hyperviscosity(x, 3600.0)
        assert model.hv.plan(3600.0) == (20, False)
        h = x.numpy()[2]
        assert np.abs(h - h0).max() > 1.0
        within(abs(grid.integrate(h) / mass0 - 1), mass_change_bound(20, grid.nnodes), "mass change")


def test_the_tensor_kernels_compile_for_cuda(tmp_path):
    """The per-node (CUDA) layout's second pass of the tensor ∇⁴ (its own flux kernel, and the
    constant operator's second-pass kernel given the tensor's mass row) compiles to PTX for sm_90,
    GPU or not (as ``test_cuda_compile``)."""
    wp.init()
    context = wp._src.context if hasattr(wp, "_src") else wp.context  # as test_cuda_compile: no public query
    if not context.runtime.core.wp_is_cuda_compatibility_enabled():
        pytest.skip("this Warp build has no CUDA compiler (NVRTC)")
    grid = CubedSphere(2, 4)
    launched = {}
    real_launch = wp.launch

    def launch(kernel, *args, **kwargs):
        launched[kernel.key] = kernel.module
        return real_launch(kernel, *args, **kwargs)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(wp, "launch", launch)
        model = hv_model(grid, 3.2, per_element=False, nu=1e15)
        model.hyperviscosity(model.new_state(), 100.0)
    assert {"laplacian_flux__rows__tensor__np4", "laplacian_node__second__np4"} <= set(launched), sorted(launched)
    for key in ("laplacian_flux__rows__tensor__np4", "laplacian_node__second__np4"):
        paths = wp.compile_aot_module(launched[key], arch=90, module_dir=tmp_path / key, use_ptx=True)
        assert len(paths) == 1 and ".entry" in paths[0].read_text() and key in paths[0].read_text(), key


@pytest.mark.parametrize("value", ["-1", "4.5", "nan", '"high"'])
def test_a_bad_scaling_is_one_line_and_exit_2(capsys, tmp_path, value):
    out = tmp_path / "x.nc"
    cli_one_line(
        capsys,
        ["run", "tc5_mountain", "--ne", "2", "--days", "0.1", "-s", f"hyperviscosity.scaling={value}", "--output", out],
        2,
        "hyperviscosity.scaling",
    )
    assert not list(tmp_path.iterdir())


def test_a_scene_s_scaling_reaches_the_model_and_scales_its_nu_as_dx_to_the_s():
    """``hyperviscosity.scaling`` is the scene's ``hypervis_scaling`` (absent: None, constant ν,
    the default, the bits of before); explicit ν scales between grids as Δx^s, not Δx^3.2."""
    from swe_sphere.config.scene import load_scene, scene_from_dict

    plain = load_scene("tc5_mountain", ne=4)
    assert plain.hypervis_scaling is None and "hypervis_scaling" not in plain.as_dict()
    s = load_scene("tc5_mountain", ne=4, overrides={"hyperviscosity.scaling": 4.0})
    assert s.hypervis_scaling == 4.0 and scene_from_dict(s.as_dict()) == s
    assert any("hypervis_scaling = 4" in note for note in s.notes)
    both = [
        load_scene("tc5_mountain", ne=ne, overrides={"hyperviscosity.scaling": 3.0, "hyperviscosity.nu": 1e15})
        for ne in (4, 8)
    ]
    ratio = both[0].nu / both[1].nu  # the scene's own ne is its file's
    assert ratio == pytest.approx(2.0**3.0, rel=1e-12)


STRETCHED = ["run", "tc5_mountain", "--ne", "3", "--days", "0.25", "--no-progress", "-s", "hyperviscosity.scaling=3.2"]
STRETCHED += ["-s", "grid.stretch_factor=2.0", "--device", "cpu"]
# its run on 3 ranks, launched with test_mpi's (``launches``: a rank's start costs more than the run)
OVER_RANKS = {
    "test_a_tensor_run_on_a_stretched_cube_has_the_same_bits_on_3_ranks": lambda d: {
        3: [[*STRETCHED, "--output", str(d / "r3.nc")]]
    }
}


@pytest.mark.xdist_group("mpi")  # test_mpi's launches: on the worker that runs the MPI tests
def test_a_tensor_run_on_a_stretched_cube_has_the_same_bits_on_3_ranks(request, capsys):
    """The tensor V is made continuous by a DSS over the ranks before each element interpolates
    it: TC5 on a stretched ne 3 cube with s = 3.2 on 3 ranks is the one process's, bit for bit."""
    folder, said = request.getfixturevalue("over_ranks")  # test_mpi's
    assert main([*STRETCHED, "--output", str(folder / "r1.nc")]) == 0
    assert "hypervis_scaling = 3.2" in capsys.readouterr().out
    assert "hypervis_scaling = 3.2" in said[3][0]
    assert_same_bits(folder / "r1.nc", folder / "r3.nc")
