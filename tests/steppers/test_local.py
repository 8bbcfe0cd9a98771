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
from swe_sphere.grid.refine import refined_cube
from swe_sphere.mesh.mesh import write_exodus
from swe_sphere.simulation.simulation import Simulation
from swe_sphere.steppers.multirate_ab import ab3_weights

from helpers import cli_main, one_line
from meshes import MOUNTAIN_BOX4, refined_ne4
from roundoff import bound

BOX = MOUNTAIN_BOX4  # 2×2 elements of the ne4 cube about TC5's mountain


@pytest.fixture(scope="module")
def refined(tmp_path_factory):
    """The ne4 cube refined 2× over ``BOX`` (124 elements; two levels at np 4), as a .g file."""
    return write_exodus(tmp_path_factory.mktemp("mesh") / "r4.g", refined_ne4())


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


def tc2_errors_and_masses(mesh, options, dts):
    """lts with ``options`` on TC2 for one day at each of ``dts`` on ``mesh`` (two levels):
    the depth's max-norm error against RK4 at 56.25 s, relative, and |the mass change|."""
    ref = sim_of("tc2_steady", "rk4", 56.25, 1.0, mesh=mesh)
    ref.run(None)
    h_ref = ref.fields()[2]
    errors, masses = [], []
    for dt in dts:
        sim = sim_of("tc2_steady", "lts", dt, 1.0, options, mesh=mesh)
        result = sim.run(None)
        assert sim.stepper.levels.count == 2
        errors.append(np.abs(sim.fields()[2] - h_ref).max() / np.abs(h_ref).max())
        masses.append(abs(result.diagnostics["mass_change"]))
    return errors, masses


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
    errors, masses = tc2_errors_and_masses(refined, {"method": method, "inner": inner}, (900.0, 450.0))
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
    ("lts.method=mis5", "lts.method must be one of mis2, mis3c, mis4a, mri_gark_erk33a, mrab3 (got 'mis5')"),
    ("lts.inner=fbrk32", "lts.inner must be one of ssprk3, rk4 (got 'fbrk32')"),
    ("lts.substeps=0", 'lts.substeps must be an integer >= 1 or "levels" (got 0)'),
    ("lts.level_margin=0.5", "lts.level_margin must be a number >= 1 (got 0.5)"),
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


# -- multirate Adams–Bashforth 3 (method "mrab3") ---------------------------------------
MRAB3 = {"method": "mrab3"}


def test_mrab3_weights_integrate_each_levels_quadratic():
    """Over a level's whole step its sub-step weights sum to AB3's (23, −16, 5)/12 h_k/Δt;
    over the coarse step every level's first weights sum to 1 (a constant tendency)."""
    w = ab3_weights(3)  # levels 0, 1, 2: 4 finest sub-steps
    assert w.shape == (4, 3, 3)
    ab3 = np.array([23.0, -16.0, 5.0]) / 12
    np.testing.assert_allclose(w[:, 0].sum(axis=0), ab3, rtol=0, atol=1e-15)
    np.testing.assert_allclose(w[0:2, 1].sum(axis=0), ab3 / 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(w[2:4, 1].sum(axis=0), ab3 / 2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(w[1, 2], ab3 / 4, rtol=0, atol=1e-15)
    np.testing.assert_allclose(w.sum(axis=(0, 2)), [1.0, 1.0, 1.0], rtol=0, atol=1e-15)
    # the first quarter of a level-0 step: ∫_0^¼ of the quadratics through the nodes 0, −1, −2
    basis = [np.polynomial.Polynomial.fit([0, -1, -2], e, 2).convert() for e in np.eye(3)]
    np.testing.assert_allclose(w[0, 0], [b.integ()(0.25) for b in basis], rtol=0, atol=1e-14)


def test_mrab3_one_level_is_the_global_ab3_step():
    """On the uniform ne2 cube (one level) a step after the start is
    x(n+1) = x(n) + Δt (23 F(n) − 16 F(n−1) + 5 F(n−2))/12 through the whole grid's rhs, then
    the ∇⁴, to the round-off of four combinations."""
    sim = sim_of("tc5_mountain", "lts", 900.0, 0.125, MRAB3, ne=2)
    assert "one level, so the global AB3 step (started by rk4)" in sim.stepper.describe()[0]
    model, dt = sim.model, 900.0
    xs = [sim.x.numpy().copy()]
    for _ in range(3):
        sim.stepper.step(sim.x)
        xs.append(sim.x.numpy().copy())
    F = []
    for x in xs[:3]:
        a, out = model.new_state(*x), model.new_state()
        model.rhs(a, out)
        F.append(out.numpy())
    expected = model.new_state(*(xs[2] + dt * (23 * F[2] - 16 * F[1] + 5 * F[0]) / 12))
    model.hyperviscosity(expected, dt)
    scale = np.abs(xs[3]).max(axis=1, keepdims=True)
    assert np.all(np.abs(expected.numpy() - xs[3]) <= bound(8, scale))
    assert np.abs(xs[3] - xs[2]).max() > 1e-3  # the step moved the state


def test_mrab3_restarts_bitwise_in_and_after_its_start(refined, tmp_path):
    """TC5 on the refined cube (two levels): 6 steps whole, and continued from a restart file
    written after 1 step (inside the two-step start) and after 4 (the levels' histories):
    the same bits."""
    whole = sim_of("tc5_mountain", "lts", 1800.0, 6 / 48, MRAB3, mesh=refined)
    whole.run(None)
    for split in (1, 4):
        first = sim_of("tc5_mountain", "lts", 1800.0, split / 48, MRAB3, mesh=refined)
        first.run(None)
        restart = first.write_checkpoint(tmp_path / f"r{split}.restart.nc")
        continued = Simulation.from_checkpoint(restart, "cpu", days=6 / 48, progress=False)
        assert continued.stepper.mrab.started == min(split, 2)
        continued.run(None)
        np.testing.assert_array_equal(continued.x.numpy(), whole.x.numpy())


def test_mrab3_replayed_step_shifts_the_histories_as_a_step_does(refined):
    """A step replayed as a captured graph (``replayed``) leaves the host's history order and
    start count as the step itself does: in the start and after it."""
    sim = sim_of("tc5_mountain", "lts", 1800.0, 0.125, MRAB3, mesh=refined)
    mrab = sim.stepper.mrab
    for _ in range(4):
        saved, started = [list(h) for h in mrab.history], mrab.started
        sim.stepper.step(sim.x)
        stepped = ([list(h) for h in mrab.history], mrab.started)
        mrab.history, mrab.started = [list(h) for h in saved], started
        mrab.replayed()
        assert ([list(h) for h in mrab.history], mrab.started) == stepped
        assert stepped[0][1] != saved[1]  # the fine level's buffers moved


def test_mrab3_evaluates_level_k_two_to_the_k_times(refined):
    """Two levels (66, 58 elements): after the start a coarse step evaluates the coarse level
    once and the fine twice: 66 + 2·58 = 182 element evaluations against 248 for AB3 at
    Δt/2 (the levels' bound, 1.36x), as the run reports."""
    sim = sim_of("tc5_mountain", "lts", 1800.0, 0.125, MRAB3, mesh=refined)
    result = sim.run(None)
    assert sim.stepper.element_evaluations() == {"local": 182, "global": 248}
    assert "182 against 248 for a global AB3 step at the finest step dt/2 (1.36x" in sim.stepper.describe()[1]
    # 6 steps: the start's 2 take 4 RK4 stages at dt/2 each (8), then 1 coarse and 2 fine a step
    assert result.rhs_evals == 2 * 8 + 4 * 1 and result.iterations["fast"] == 4 * 2


@pytest.fixture(scope="module")
def refined3(tmp_path_factory):
    """The ne6 cube refined 4× over ``BOX`` (376 elements; three levels for MRAB3 at 1800 s)."""
    return write_exodus(tmp_path_factory.mktemp("mesh") / "r6x4.g", refined_cube(6, BOX, 2))


def test_mrab3_sums_a_level_every_sub_step_only_where_a_finer_level_reads_it(refined3):
    """Three levels (168, 104, 104 elements): level k's sums go every finest sub-step to the
    nodes that an element of a finer level also touches, and once a level-k step to the
    others (from the grid's gid and the levels: whole unique nodes each side; the finest
    level's all the others). After the
    start a coarse step's dynamics equals the sums at every sub-step at every node (the
    sets overridden) to the round-off of the regrouped sums, and every node's copies keep
    one value (the restart file's)."""
    options = {**MRAB3, "max_levels": 3}
    sims = [sim_of("tc5_mountain", "lts", 1800.0, 0.125, options, mesh=refined3) for _ in range(2)]
    for sim in sims:
        steps(sim, 2)  # the start
    mrab, every, grid = sims[0].stepper.mrab, sims[1].stepper.mrab, sims[0].model.grid
    assert sims[0].stepper.levels.elements_per_level() == [168, 104, 104]
    gid, level = grid.gid, np.repeat(sims[0].stepper.levels.level, grid.np**2)
    for k in range(3):
        touched, finer = np.zeros((2, gid.max() + 1), dtype=bool)
        touched[gid[level == k]], finer[gid[level > k]] = True, True
        np.testing.assert_array_equal(mrab.read[k].numpy(), np.flatnonzero((touched & finer)[gid]))
        np.testing.assert_array_equal(mrab.unread[k].numpy(), np.flatnonzero((touched & ~finer)[gid]))
    every.read = [part.nodes for part in every.parts]
    every.unread = [part.nodes[:0] for part in every.parts]
    for sim in sims:
        sim.stepper.mrab.step(sim.x)
    x, y = (sim.x.numpy() for sim in sims)
    # a node's sums: at most 3 levels × 4 sub-steps × 3 additions of x's size on each side;
    # a later evaluation in the step sees a difference through a step of Courant number < 1,
    # at most twice (level 1 at sub-step 2, level 2 at 1, 2, 3 after level 1's regrouping),
    # and a depth's difference δh moves the wind by about δh √(g/h): the wind's scale is
    # its speed and the gravity wave's
    depth = np.abs(y[2]).max()
    wind = np.abs(y[:2]).max() + np.sqrt(sims[0].model.g * depth)
    scale = np.array([[wind], [wind], [depth]])
    assert np.all(np.abs(x - y) <= bound(3 * 2 * 36, scale))
    assert np.any(x != y)  # regrouped
    _, first, copy_of = np.unique(gid, return_index=True, return_inverse=True)
    np.testing.assert_array_equal(x, x[:, first[copy_of]])


def test_mrab3_order_and_interface_mass_on_tc2(refined):
    """TC2 on the refined cube (two levels), one day at Δt = 450 and 225 s against RK4 at
    56.25 s: the depth's error falls at rate 3 ± 0.3 (measured 2.90); the mass changes by
    the interface's two integrations of one flux (measured 1.9e-9 and 2.0e-10 of it),
    falling as the method's error does and below a hundredth of the depth's error."""
    errors, masses = tc2_errors_and_masses(refined, MRAB3, (450.0, 225.0))
    rate = np.log2(errors[0] / errors[1])
    print(f"\nmrab3: errors {errors}, rate {rate:.2f}, mass changes {masses}")
    assert abs(rate - 3) <= 0.3
    assert masses[0] / masses[1] >= 0.9 * 2**3
    assert all(m < e / 100 for m, e in zip(masses, errors))
