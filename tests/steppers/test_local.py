"""Local time stepping (``steppers.local``, ``lts``) on a refined cube: the one-level limit,
order on TC2, the mass lost at the level interfaces, bitwise restarts, what a run prints and
records, and bad options. (Registered: the generic stepper, restart and forcing tests run it
on the uniform cube, where it has one level.)"""

from __future__ import annotations

import dataclasses

import netCDF4
import numpy as np
import pytest

from swe_sphere.config.scene import load_scene
from swe_sphere.grid.mesh import write_exodus
from swe_sphere.grid.refine import Box, refined_cube
from swe_sphere.simulation.simulation import Simulation

from helpers import cli_main, one_line

BOX = Box(15.0, 45.0, 255.0, 285.0)  # 2×2 elements of the ne4 cube about TC5's mountain


@pytest.fixture(scope="module")
def refined(tmp_path_factory):
    """The ne4 cube refined 2× over ``BOX`` (124 elements; two levels at np 4), as a .g file."""
    return write_exodus(tmp_path_factory.mktemp("mesh") / "r4.g", refined_cube(4, BOX, 1))


def sim_of(case, stepper, dt, days, options=None, mesh=None, ne=None):
    scene = load_scene(case, mesh=mesh, ne=ne, dt=dt, days=days, stepper=stepper)
    scene = dataclasses.replace(scene, stepper_options=dict(options or {}), output_every_days=days)
    return Simulation(scene, "cpu", progress=False)


def steps(sim, n):
    for _ in range(n):
        sim.stepper.step(sim.x)
    return sim.x.numpy()


@pytest.mark.parametrize("inner", ["rk4", "ssprk3"])
def test_one_level_is_the_inner_methods_global_step_bitwise(inner):
    """On the uniform ne2 cube TC2 has one level: lts steps as its inner method's stepper,
    the same bits, and says so."""
    lts = sim_of("tc2_steady", "lts", 1800.0, 0.125, {"inner": inner}, ne=2)
    base = sim_of("tc2_steady", inner, 1800.0, 0.125, ne=2)
    assert lts.stepper.levels.count == 1
    assert "one level, so the global" in lts.stepper.describe()[0]
    np.testing.assert_array_equal(steps(lts, 4), steps(base, 4))


def test_two_levels_restart_bitwise_and_keep_their_levels(refined):
    """TC5 (topography, ∇⁴) on the refined cube: 3 steps, state() and x into a fresh
    simulation, restore, 3 more: bitwise 6 steps; the levels come back from the state (not
    from the flow at step 3)."""
    whole = sim_of("tc5_mountain", "lts", 1800.0, 0.125, mesh=refined)
    assert whole.stepper.levels.elements_per_level() == [66, 58]
    end = steps(whole, 6)
    first = sim_of("tc5_mountain", "lts", 1800.0, 0.125, mesh=refined)
    steps(first, 3)
    state, x = first.stepper.state(), first.x.numpy().copy()
    second = sim_of("tc5_mountain", "lts", 1800.0, 0.125, mesh=refined)
    second.x.assign(x)
    second.stepper.restore(state)
    np.testing.assert_array_equal(second.stepper.levels.level, whole.stepper.levels.level)
    np.testing.assert_array_equal(steps(second, 3), end)


@pytest.mark.slow
@pytest.mark.parametrize(
    "method, inner, order", [("mis4a", "rk4", 3), ("mri_gark_erk33a", "rk4", 3), ("mis2", "ssprk3", 2)]
)
def test_order_and_interface_mass_on_tc2(refined, method, inner, order):
    """TC2 on the refined cube (two levels) for one day at Δt = 900 and 450 s against RK4 at
    56.25 s: the rate of the depth's error within ±0.3 of the table's order (measured 2.97,
    2.92, 2.11). Mass: the levels' parts do not cancel their interface fluxes (evaluated at
    different stages), so the mass changes, by the mismatch of two integrations of the same
    flux: measured 3.7e-10 and 1.6e-11 (MIS4a; MIS2 2.3e-8 and 5.8e-9), falling with Δt as
    the method's error does (by 0.9·2^order or more) and below a hundredth of the depth's error."""
    ref = sim_of("tc2_steady", "rk4", 56.25, 1.0, mesh=refined)
    ref.run(None)
    h_ref = ref.fields()[2]
    errors, masses = [], []
    for dt in (900.0, 450.0):
        sim = sim_of("tc2_steady", "lts", dt, 1.0, {"method": method, "inner": inner}, mesh=refined)
        result = sim.run(None)
        assert sim.stepper.levels.count == 2
        errors.append(np.abs(sim.fields()[2] - h_ref).max() / np.abs(h_ref).max())
        masses.append(abs(result.diagnostics["mass_change"]))
    rate = np.log2(errors[0] / errors[1])
    print(f"\n{method}/{inner}: errors {errors}, rate {rate:.2f}, mass changes {masses}")
    assert abs(rate - order) <= 0.3
    assert masses[0] / masses[1] >= 0.9 * 2**order
    assert all(m < e / 100 for m, e in zip(masses, errors))
    assert masses[1] > 1e-14  # not round-off: the interface's flux mismatch


def test_a_run_prints_and_records_its_levels(tmp_path, capsys, refined):
    out = tmp_path / "o.nc"
    code, stdout, err = cli_main(
        capsys, "run", "tc5_mountain", "--mesh", refined, "--stepper", "lts", "--days", "0.125",
        "--dt", "1800", "--output", out, "--no-progress",
    )  # fmt: skip
    assert code == 0, err
    assert "lts         levels 2: 66, 58 elements (coarsest first), saving's bound 1.36x" in stdout
    assert "element evaluations a coarse step 1424 against 992 for a global rk4 step at the inner step dt/2" in stdout
    with netCDF4.Dataset(out) as ds:
        assert ds.lts_levels == 2 and ds.lts_elements_per_level == "66, 58"
        assert ds.lts_method == "MIS4a" and ds.lts_order == 3 and ds.lts_inner == "rk4"
        assert ds.lts_bound == pytest.approx(124 * 2 / (66 + 2 * 58))


BAD = [
    ("lts.max_levels=0", "lts.max_levels must be an integer >= 1 (got 0)"),
    ("lts.method=mis5", "lts.method must be one of mis2, mis3c, mis4a, mri_gark_erk33a (got 'mis5')"),
    ("lts.inner=fbrk32", "lts.inner must be one of ssprk3, rk4 (got 'fbrk32')"),
    ("lts.substeps=0", 'lts.substeps must be an integer >= 1 or "levels" (got 0)'),
]


@pytest.mark.parametrize("setting, words", BAD, ids=[b[0] for b in BAD])
def test_bad_option_is_one_line(tmp_path, capsys, setting, words):
    out = tmp_path / "o.nc"
    code, _, err = cli_main(
        capsys, "run", "tc5_mountain", "--ne", "2", "--stepper", "lts", "-s", setting, "--output", out
    )
    one_line(code, err, 2, words)
    assert not out.exists()


def test_the_level_assembly_kernel_compiles_for_cuda(tmp_path, refined):
    """The DSS over a level's nodes (``kernels.dss.dss_rows_at``; the tendency kernels are the
    whole grid's over element ranges) as two steps of lts on the refined cube record it
    compiles for CUDA (sm_90), GPU or not."""
    import warp as wp

    context = wp._src.context if hasattr(wp, "_src") else wp.context  # as test_cuda_compile: no public query
    wp.init()
    if not context.runtime.core.wp_is_cuda_compatibility_enabled():
        pytest.skip("this Warp build has no CUDA compiler (NVRTC)")
    sim = sim_of("tc2_steady", "lts", 1800.0, 0.125, mesh=refined)
    steps(sim, 2)
    kernels = {launch.kernel.key: launch.kernel for key in sim.model.launches.keys() for launch in
               (sim.model.launches.recorded(key) or []) if hasattr(launch, "kernel") and hasattr(launch.kernel, "module")}  # fmt: skip
    assert "dss_at" in kernels
    module = kernels["dss_at"].module
    paths = wp.compile_aot_module(module, arch=90, module_dir=tmp_path / "dss_at", use_ptx=True)
    assert len(paths) == 1 and ".entry" in paths[0].read_text()


def test_fewer_substeps_cost_fewer_fast_evaluations(refined):
    """``substeps`` = 1 on the refined cube at 1800 s (the worst element's RK4 limit is
    about 2160 s there): MIS4a's solves take one inner step each (4 RK4 steps, 16 fast
    evaluations a step, not 2^K's 20), and TC2 stays within 1e-3 of the default's depth."""
    runs = {}
    for n in ("levels", 1):
        sim = sim_of("tc2_steady", "lts", 1800.0, 0.25, {"substeps": n}, mesh=refined)
        result = sim.run(None)
        runs[n] = (result.iterations["fast"], sim.fields()[2])
    assert runs["levels"][0] == 12 * 20 and runs[1][0] == 12 * 16
    h = runs["levels"][1]
    assert np.abs(runs[1][1] - h).max() / np.abs(h).max() < 1e-3
