"""Every Warp module the project launches compiles for CUDA (sm_80, sm_90), GPU or not.

Warp's NVRTC turns a module into PTX without a CUDA driver, so a kernel that
breaks only in CUDA code generation (the per-node layout, ``wp.static``
branches, the solver kernels) fails here on every machine. The modules are
found, not listed: every ``wp.Kernel`` defined at module level in
``swe_sphere.kernels``'s submodules, plus every project kernel launched while
each bundled scene's model (both layouts: per node, CUDA's default, and per
element; float64 and float32, its tendency and ∇⁴) takes two steps of its stepper on ne = 2 np = 4 on
the CPU, the float32 state (``float32_state``) stepped by rk4, every
stepper (its solvers are the same on every device) on the scene
with the most terms, np 8's per-element ∇⁴ (``laplacian_across``, both precisions) and float32
state's tendency lanes (ne = 2), the ∇⁴ with ν_div ≠ ν and the tensor (both precisions) and the element filter; the DSS kernels are also built with ghosts (MPI; the Helmholtz kernels
read ghosts at run time, one build for both). Warp's
own modules (``warp.optim.linear``) are left to Warp's tests.
"""

from __future__ import annotations

import functools
import importlib
import pkgutil
import re

import numpy as np
import pytest
import warp as wp

import swe_sphere
import swe_sphere.kernels as kernels_pkg
from swe_sphere.adjoint.gradient import step_adjoint
from swe_sphere.cases.library import make_case
from swe_sphere.config.scene import list_scenes, load_scene
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.grid.topology import Topology
from swe_sphere.kernels import dss, hyperviscosity
from swe_sphere.model.shallow_water import ShallowWater
from swe_sphere.solvers.jacobian import KernelPasses
from swe_sphere.solvers.krylov import KernelVectors
from swe_sphere.steppers import STEPPERS, make_stepper

# sm90 (H100, H200: the GPUs the project runs on) by default; sm80 (A100) under -m slow,
# as each arch's compile of every module takes a minute on a 2-core CI machine
ARCHS = (pytest.param(80, marks=pytest.mark.slow), 90)


def _nvrtc_missing() -> str | None:
    """Why Warp cannot compile CUDA here, or None when it can."""
    wp.init()
    context = wp._src.context if hasattr(wp, "_src") else wp.context  # Warp >= 1.10 moved it; no public query
    if not context.runtime.core.wp_is_cuda_compatibility_enabled():
        return "this Warp build has no CUDA compiler (NVRTC)"
    return None


def _module_kernels() -> list[wp.Kernel]:
    """The ``wp.Kernel`` objects defined at module level in swe_sphere.kernels.*."""
    found = []
    for info in pkgutil.iter_modules(kernels_pkg.__path__):
        mod = importlib.import_module(f"{kernels_pkg.__name__}.{info.name}")
        found += [v for v in vars(mod).values() if isinstance(v, wp.Kernel) and v.func.__module__ == mod.__name__]
    return found


def float32_scenes(scenes: list) -> list:
    """The scenes whose float32 models the discovery steps: the one with every tendency term (and
    the ∇⁴), TC1's continuity alone (the dh row's update) and TC4's forcing (an unweighted
    tendency): every compiled branch of a float32 tendency, without a float32 build of each term
    set (each one's float64 build is there; a cold kernel cache compiles each module)."""
    richest = max((s for s in scenes if "pressure_gradient" in s.terms), key=lambda s: len(s.terms))
    alone = next(s for s in scenes if tuple(s.terms) == ("continuity",))
    forced = next(s for s in scenes if "forcing" in s.terms)
    return [richest, alone, forced]


def _launched_kernels(monkeypatch) -> tuple[list[wp.Kernel], list[wp.Kernel]]:
    """The project's kernels launched by every bundled scene's model and steppers
    (see the module docstring), and the ghost variants of the DSS kernels among them."""
    launched, dss_args = [], set()  # (factory, its arguments but ghosts, its other keywords)
    real_launch = wp.launch

    def launch(kernel, *args, **kwargs):
        launched.append(kernel)
        return real_launch(kernel, *args, **kwargs)

    def noting(factory):
        def built(*args, ghosts=False, **options):
            dss_args.add((factory, args, tuple(sorted(options.items()))))
            return factory(*args, ghosts=ghosts, **options)

        return built

    monkeypatch.setattr(wp, "launch", launch)
    monkeypatch.setattr(Topology, "element_rows", False)  # the DSS's node kernels, CUDA's, not the CPU's rows
    for module, name in ((dss, "dss_rows"), (dss, "dss_update"), (hyperviscosity, "dss_apply")):
        monkeypatch.setattr(module, name, noting(getattr(module, name)))
    scenes = [load_scene(p, ne=2, np_=4) for p in list_scenes()]
    richest = max((s for s in scenes if "pressure_gradient" in s.terms), key=lambda s: len(s.terms))
    grid = CubedSphere(2, 4)
    done = set()
    for scene, precision in [*((s, "float64") for s in scenes), *((s, "float32") for s in float32_scenes(scenes))]:
        case = scene.make_case()
        for per_element in (False, True):
            steppers = STEPPERS if scene is richest and precision == "float64" else (scene.stepper,)
            todo = [name for name in steppers if (scene.terms, name, per_element, precision) not in done]
            if not todo:
                continue
            model = ShallowWater(
                grid,
                scene.terms,
                case.fcor(grid.lat, grid.lon),
                case.hs(grid.lat, grid.lon),
                nu=scene.nu,
                nu_div=scene.nu_div,
                nu_s=scene.nu_s,
                hypervis_subcycle=scene.hypervis_subcycle,
                g=case.planet.g,
                device="cpu",
                per_element=per_element,
                forcing=case.forcing() if "forcing" in scene.terms else None,
                precision=precision,
            )
            for name in todo:
                done.add((scene.terms, name, per_element, precision))
                stepper = make_stepper(name, model, scene.dt)
                x = model.new_state(*np.stack(case.initial(grid.lat, grid.lon)))
                stepper.step(x)  # two steps: a leapfrog's first is its one-step start
                stepper.step(x)
            if (
                scene is richest and precision == "float64"
            ):  # the float32 Helmholtz solves (refined and alone) of "float32" precision
                for name in ("imex", "implicit"):
                    stepper = make_stepper(name, model, scene.dt, precision="float32")
                    stepper.step(model.new_state(*np.stack(case.initial(grid.lat, grid.lon))))
                for name in ("implicit", "epi2"):  # the Krylov work's CUDA backends (a CPU device picks numpy's)
                    stepper = make_stepper(name, model, scene.dt)
                    basis = stepper.kiops.basis if name == "epi2" else stepper.fgmres
                    basis.vectors, stepper.jacobian.passes = KernelVectors(basis), KernelPasses(model)
                    stepper.step(model.new_state(*np.stack(case.initial(grid.lat, grid.lon))))
    # the ∇⁴'s ∇(∇·v) term and its tensor, which no bundled scene has (ν_div ≠ ν, hypervis_scaling)
    for per_element, precision in [(e, p) for e in (False, True) for p in ("float64", "float32")]:
        z = np.zeros(grid.nnodes)
        model = ShallowWater(
            grid,
            ["hyperviscosity"],
            z,
            z,
            nu=1e15,
            nu_div=3e15,
            hypervis_scaling=3.2,
            device="cpu",
            per_element=per_element,
            precision=precision,
        )
        model.hyperviscosity(model.new_state(), 100.0)
        model.hv.rkl1(model.new_state(), 100.0, 2)  # its last pass's RKL1 modes
    # the element filter ([filter]), which no bundled scene has
    z = np.zeros(grid.nnodes)
    ShallowWater(grid, ["continuity"], z, z, element_filter=(0.1, 12.0, 2 / 3), device="cpu").hyperviscosity(
        model.new_state(), 100.0
    )
    # the adjoint's kernels (a gradient's reverse sweep), on TC5's terms with the ∇⁴: the
    # element kernel of the CPU's layout, and the per-node pair of CUDA's
    tc5 = load_scene("tc5_mountain", ne=2, np_=4, dt=1800.0, stepper="rk4")
    swe_sphere.gradient(tc5, 1, swe_sphere.HeightMisfit(0.0))
    model = ShallowWater.from_scene(tc5, grid, per_element=False)
    x = model.new_state(*np.stack(tc5.make_case().initial(grid.lat, grid.lon)))
    step_adjoint(model, make_stepper("rk4", model, tc5.dt)).reverse(x, wp.clone(x))
    # passive tracers ([tracers]), which no bundled scene has: the tendency with their rows and
    # their ∇⁴ (q·hs in the surface's place), both layouts; the transport tests' prescribed wind
    for per_element in (False, True):  # the limiter's kernels, and the ∇⁴'s with it (h's row beside) and without
        limiter = "optimization" if per_element else "none"
        # and the ∇⁴ in the stages (stage_hyperviscosity): TC5's weighted tendency, the flow's pointwise one
        for stage in (False, True):
            model = ShallowWater.from_scene(
                tc5, grid, per_element=per_element, tracers=2, limiter=limiter, stage_hyperviscosity=stage
            )
            u, v, h = tc5.make_case().initial(grid.lat, grid.lon)
            x = model.new_state(u, v, h, masses=np.stack([h, h]))
            make_stepper("rk4", model, tc5.dt).step(x)
        flow = make_case("deformational_flow")
        model = ShallowWater.from_case(grid, flow, ["continuity", "forcing"], per_element=per_element, tracers=1)
        u, v, h = flow.initial(grid.lat, grid.lon)
        make_stepper("ssprk3", model, 720.0).step(model.new_state(u, v, h, masses=h[None]))
        terms = ["continuity", "forcing", "hyperviscosity"]
        model = ShallowWater.from_case(
            grid, flow, terms, nu=0.0, nu_s=1e15, per_element=per_element, tracers=1, stage_hyperviscosity=True
        )
        make_stepper("ssprk3", model, 720.0).step(model.new_state(u, v, h, masses=h[None]))
    # the float32 state ("float32_state"): its conversions, the tendency of the departed state and
    # the stages' float32 combinations, both layouts, compensated and not; not compensated, the
    # state kept between steps (``model.held``) and the ∇⁴ on it
    for per_element in (False, True):
        for compensated in (True, False):
            model = ShallowWater.from_scene(
                tc5, grid, per_element=per_element, precision="float32_state", compensated=compensated
            )
            x = model.held.new(np.stack(tc5.make_case().initial(grid.lat, grid.lon)))
            make_stepper("rk4", model, tc5.dt).step(x)
            model.held.float64(x)  # the diagnostics' float64 copy of a kept state
    # rows no term writes (TC1's wind): the float32 state's combinations of the state alone
    tc1 = load_scene("tc1_cosine_bell", ne=2, np_=4)
    model = ShallowWater.from_scene(tc1, grid, per_element=False, precision="float32_state")
    make_stepper("rk4", model, tc1.dt).step(model.held.new(np.stack(tc1.make_case().initial(grid.lat, grid.lon))))
    # np 8 on the CPU's per-element layout: the ∇⁴'s ``laplacian_across`` (np ≥ 5; float64 and
    # float32) and the float32 state's tendency lanes (np 8's 16 × 16 transposes), which np 4 never
    # launches: ne 2's 24 elements fill one block of 16 lanes and part of a second; the second
    # pass's runs where the topology has its element edges (the CPU's rows)
    monkeypatch.setattr(Topology, "element_rows", True)
    start, fine = len(launched), CubedSphere(2, 8)
    for precision in ("float64", "float32"):
        z = np.zeros(fine.nnodes)
        model = ShallowWater(
            fine, ["hyperviscosity"], z, z, nu=1e15, device="cpu", per_element=True, precision=precision
        )
        model.hyperviscosity(model.new_state(), 100.0)
    model = ShallowWater.from_scene(tc5, fine, per_element=True, precision="float32_state", compensated=False)
    make_stepper("rk4", model, tc5.dt).step(model.held.new(np.stack(tc5.make_case().initial(fine.lat, fine.lon))))
    # of these the lanes alone: the rest are np 4's kernels at another np, or the element-edge DSS
    # (``Topology.edges``: the CPU's alone), whose ghosts the DSS check above would miss
    launched[start:] = [k for k in launched[start:] if k.key.startswith(("laplacian_across", "tendency_across"))]
    ghosted = [factory(*args, ghosts=True, **dict(options)) for factory, args, options in dss_args]
    return [k for k in launched if k.func.__module__.startswith("swe_sphere.")], ghosted


@pytest.fixture(scope="session")
def discovered():
    """(module-level kernels, launched kernels, DSS kernels with ghosts)."""
    why = _nvrtc_missing()
    if why:
        pytest.skip(why)
    with pytest.MonkeyPatch.context() as mp:
        return (_module_kernels(), *_launched_kernels(mp))


@pytest.fixture(scope="session")
def modules(discovered):
    """{Warp module name: (module, its kernels' keys)} of every module to compile."""
    found = {}
    for k in (k for group in discovered for k in group):
        found.setdefault(k.module.name, (k.module, set()))[1].add(k.key)
    return found


@pytest.fixture(scope="session")
def ptx(modules):
    """ptx(arch) → {module name: PTX text}, every module compiled once per arch asked for, into
    Warp's kernel cache as its CPU builds are: a later run reads the PTX an earlier one compiled
    (the module's name hashes its source and options, the file's the arch) instead of 106
    modules' compile again (184 s cold, 0.1 s cached: -n 0, load 8-12 on 2 cores)."""

    @functools.cache
    def compiled(arch):
        out = {}
        for name, (module, _) in modules.items():
            paths = wp.compile_aot_module(module, arch=arch, use_ptx=True)
            assert len(paths) == 1 and paths[0].name.endswith(f".sm{arch}.ptx"), (name, paths)
            out[name] = paths[0].read_text()
        return out

    return compiled


def test_the_discovery_covers_every_term_set_layout_and_kernel_file(discovered, modules):
    """Both layouts of the tendency for each bundled scene's term set, both ∇⁴
    passes in both layouts, the DSS (and its stage combinations and the ∇⁴'s last pass) with and without ghosts, the gravity-wave,
    implicit, forcing and blas kernels, and kernels from every file of swe_sphere.kernels."""
    module_level, launched, ghosted = discovered
    names = list(modules)
    scenes = [load_scene(p) for p in list_scenes()]
    tendency_terms = {tuple(t for t in s.terms if t not in ("hyperviscosity", "forcing")) for s in scenes}
    float32_terms = {
        tuple(t for t in s.terms if t not in ("hyperviscosity", "forcing")) for s in float32_scenes(scenes)
    }
    assert len(float32_terms) == 3  # every term, the continuity alone, and the forced
    for terms, precision in [*((t, "") for t in tendency_terms), *((t, "_float32") for t in float32_terms)]:
        # float32's per-element tendency at np 4 is its lanes' (``model.lanes``: W = 16 elements a vector)
        lanes = "_across__np4_w16" if precision else ""
        pattern = f"tendency({lanes})?__" + "__".join(terms) + f"(__mass)?(__np4)?{precision}_[0-9a-f]{{8}}"
        tendency = [n for n in names if re.fullmatch(pattern, n)]
        # per node (compiled for np 4) and per element, mass-weighted (unforced) or not (forced: TC4's)
        both = ([False, True], [False, False, True, True])
        per_node = [re.search(f"__np4{precision}_[0-9a-f]{{8}}$", n) is not None for n in tendency]
        assert sorted(per_node) in both, (terms, precision, tendency)
        assert all(lanes in n for n, node in zip(tendency, per_node) if not node), tendency
    keys = {k.key for k in launched}
    hv = (
        "laplacian_element__first",
        "laplacian_element__second",
        "laplacian_flux__cartesian__np4",
        "laplacian_flux__rows__np4",
        "laplacian_flux__rows__tensor__np4",
        "laplacian_node__first__np4",
        "laplacian_node__second__np4",
        "dss_apply",
        "dss_apply__euler",  # an RKL1 ∇⁴ super-step's stages
        "dss_apply__rkl",
        "laplacian_element__first__divergent",
        "laplacian_node__first__divergent__np4",
    )
    for key in (
        *hv,
        *(k + "_float32" for k in hv),  # the float32 ∇⁴'s
        "helmholtz_gradient",
        "helmholtz_divergence",
        "helmholtz_assemble",
        "helmholtz_rhs",
        "helmholtz_back_substitution",
        "cg_update",
        "inner3",
        "schur_height",
        "helmholtz_back_substitution_implicit",
        "schur_wind_implicit",  # the IMEX stages' L Y in the back-substitution
        "helmholtz_gradient_float32",
        "helmholtz_divergence_float32",
        "helmholtz_assemble_float32",
        "cg_update_float32",
        "converted_float32",
        "add_converted",
        "cg_check",
        "cg_alpha",
        "refine_check",
        "add_mean_difference",
        "history_dots",
        "history_guess",
        "history_increment_dots",
        "history_coefficients",
        "history_store",
        "jacobian_vector",
        "fd_epsilon",
        "add_scaled",
        "project_dots",
        "lincomb",
        "fgmres_start",
        "fgmres_cycle",
        "arnoldi_column",
        "fgmres_end",
        "row_totals",
        "residual",
        "translating_low",
        "deformational_flow",
        "tracer_laplacian__first",
        "tracer_laplacian__first__row2",
        "tracer_laplacian__second",
        "tracer_laplacian__second__into_weighted",  # the ∇⁴ in the stages, into the tendency
        "tracer_laplacian__second__into_pointwise",
        "element_bounds_np4",
        "neighbour_bounds",
        "limit_stage__mass__weighed__relative",  # a limited stage's tracers, assembled with its dynamics rows
        "limit_stage__mass__from2__relative",  # the ∇⁴ stages' tracers, their change from the stage's state
        "axpbypcz",
        "dss",
    ):
        assert key in keys, key
    assert "tendency__continuity__momentum_advection__coriolis__pressure_gradient__topography__mass__np4" in keys
    assert "tendency__continuity__momentum_advection__coriolis__pressure_gradient__topography__mass__np4__q2" in keys
    assert "tendency__continuity__np4__q1" in keys  # the forced, unweighted tendency of the transport tests
    departed = "continuity__momentum_advection__coriolis__pressure_gradient__topography__mass"
    for key in (
        f"tendency__{departed}__np4__departed_float32",
        f"tendency_across__np4_w16__{departed}__departed_float32",
    ):
        assert key in keys, key  # the float32 state's tendency, per node and per element (its lanes at np 4)
    # np 8's per-element ∇⁴ (both precisions) and the float32 state's np 8 lanes
    for key in ("laplacian_across__first", "laplacian_across__second"):
        assert key in keys and key + "_float32" in keys, key
    assert f"tendency_across__np8_w16__{departed}__departed_float32" in keys
    for key in ("to_departure", "add_increment", "from_departure"):
        assert key in keys, key
    assert any(k.key.endswith("__state_float32") for k in launched)  # the float32 stages' combinations
    assert {"combined_1_float32", "combined_2_float32"} <= keys  # and of rows no term writes
    plain_dss = {
        k.module.name
        for k in launched
        if k.key in ("dss", "dss_float32") or k.key.startswith(("dss_update__", "dss_apply"))
    }
    assert any(k.key.startswith("dss_update__") for k in launched)  # the explicit stages' combinations
    assert any("__assembled" in k.key for k in launched)  # a limited stage's pass: its tracers as they are
    assert len(ghosted) == len(plain_dss) >= 3 and not plain_dss & {k.module.name for k in ghosted}
    files = {k.func.__module__ for k in module_level + launched}
    for info in pkgutil.iter_modules(kernels_pkg.__path__):
        assert f"{kernels_pkg.__name__}.{info.name}" in files, info.name


@pytest.mark.parametrize("arch", ARCHS)
def test_every_module_compiles_to_ptx(modules, ptx, arch):
    """Each module's PTX targets the arch and has an entry for each of its kernels."""
    for name, (_module, keys) in modules.items():
        text = ptx(arch)[name]
        assert f".target sm_{arch}" in text, name
        entries = re.findall(r"\.entry\s+(\w+)_[0-9a-f]{8}_cuda_kernel_forward\(", text)
        assert keys <= set(entries), (name, entries, keys)
