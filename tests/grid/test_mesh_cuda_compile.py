"""The kernels a mesh builds for itself compile for CUDA (sm_90), GPU or not: the DSS, ∇⁴ and
Helmholtz kernels are generated for the DSS table's width, the most copies of a node (4 on the
cube, up to 7 on a refined mesh), so a mesh with nodes of 7 elements makes modules that no cube
run makes (``test_cuda_compile`` compiles the cube's)."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.steppers import make_stepper

from meshes import TC6_TERMS, bipyramid_mesh, case_model

STEPPERS = ("ssprk3", "semi_implicit", "imex", "implicit")


def launched_modules(grid, monkeypatch) -> dict:
    """{Warp module name: module} of the project's kernels that two steps of each of ``STEPPERS``
    (TC6 with ∇⁴, both layouts) launch on ``grid`` on the CPU."""
    found = {}
    real_launch = wp.launch

    def launch(kernel, *args, **kwargs):
        if kernel.func.__module__.startswith("swe_sphere."):
            found[kernel.module.name] = kernel.module
        return real_launch(kernel, *args, **kwargs)

    monkeypatch.setattr(wp, "launch", launch)
    for per_element in (False, True):
        case, model = case_model(
            grid, "tc6_rossby_haurwitz", TC6_TERMS, nu=1e15, nu_div=1e15, nu_s=1e15, per_element=per_element
        )
        for name in STEPPERS:
            stepper = make_stepper(name, model, 300.0)
            x = model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
            stepper.step(x)
            stepper.step(x)
    monkeypatch.undo()
    return found


def test_the_kernels_of_a_mesh_with_nodes_of_7_elements_compile_for_cuda():
    wp.init()
    context = wp._src.context if hasattr(wp, "_src") else wp.context  # as test_cuda_compile: no public query
    if not context.runtime.core.wp_is_cuda_compatibility_enabled():
        pytest.skip("this Warp build has no CUDA compiler (NVRTC)")
    mesh_grid = CubedSphere(0, 4, mesh=bipyramid_mesh(7))
    assert mesh_grid.dss_table.shape[1] == 7
    with pytest.MonkeyPatch.context() as mp:
        on_mesh = launched_modules(mesh_grid, mp)
    with pytest.MonkeyPatch.context() as mp:
        on_cube = launched_modules(CubedSphere(2, 4), mp)
    new = sorted(set(on_mesh) - set(on_cube))
    print("compiled for the mesh alone:", new)
    assert any(name.startswith("dss") for name in new), new  # the width-7 DSS at least
    for name in new:  # into Warp's kernel cache (as test_cuda_compile's): a later run reads the PTX
        paths = wp.compile_aot_module(on_mesh[name], arch=90, use_ptx=True)
        assert len(paths) == 1 and ".entry" in paths[0].read_text(), name
