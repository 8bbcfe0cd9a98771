"""A run of one model for ``peer_dinosaur.py``, in a process of its own (its CPU clock and peak
its own; the peer under its own interpreter, which has Dinosaur and JAX):

* ``python dinosaur_child.py --peer-child IN OUT TRANSFORMS``: Dinosaur from the state in IN;
* ``python dinosaur_child.py --swe-child STUDY CONFIG OUT DEVICE``: swe_sphere's run of STUDY.

Each writes its fields at the last day and its seconds to OUT (``.npz``)."""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np
from peer_dinosaur import STUDIES, parse_swe


# -- the peer, in its own environment ----------------------------------------------------------
def peer_child(inp: Path, out: Path, transforms: str) -> None:
    """Run Dinosaur on the state in ``inp`` (``run_peer`` writes it) and write its fields at
    the start and at the last day (``peer_fields``: vorticity s⁻¹, h and h + hs m) on its
    grid, with the loop's CPU and wall seconds, to ``out``."""
    import functools
    import time

    import jax

    d = np.load(inp)
    jax.config.update("jax_enable_x64", bool(d["x64"]))  # float32: JAX's default, Dinosaur's NeuralGCM use
    from dinosaur import coordinate_systems, layer_coordinates, scales, spherical_harmonic, time_integration, units

    truncation, nodes, dt, days = int(d["truncation"]), int(d["nodes"]), float(d["dt"]), float(d["days"])
    impl = (
        functools.partial(spherical_harmonic.FastSphericalHarmonics, fourier_method="fft")
        if transforms == "fft"
        else spherical_harmonic.RealSphericalHarmonics
    )
    grid = spherical_harmonic.Grid.construct(truncation, nodes, spherical_harmonics_impl=impl)
    lon, sin_lat = grid.nodal_axes
    assert np.allclose(lon, d["lon"][:, 0], atol=1e-12) and np.allclose(sin_lat, np.sin(d["lat"][0]), atol=1e-12)
    coords = coordinate_systems.CoordinateSystem(grid, layer_coordinates.LayerCoordinates(1))
    specs = units.SimUnits.from_si()
    state, eq = peer_state(grid, coords, specs, d)
    dt_nd = float(specs.nondimensionalize(dt * scales.units.s))
    step = time_integration.step_with_filters(
        time_integration.imex_rk_sil3(eq, dt_nd), [time_integration.exponential_step_filter(grid, dt_nd)]
    )
    nsteps = round(days * 86400 / dt)
    loop = jax.jit(time_integration.repeated(step, nsteps)).lower(state).compile()
    cpu0, wall0 = time.process_time(), time.perf_counter()
    final = jax.block_until_ready(loop(state))
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    start = {f"start_{k}": v for k, v in peer_fields(grid, specs, eq, state, d).items()}
    np.savez(out, **peer_fields(grid, specs, eq, final, d), **start, cpu=cpu, wall=wall, steps=nsteps)


def peer_state(grid, coords, specs, d):
    """The peer's modal state and equations from the nodal u, v (m/s), fluid depth h and
    surface height hs (m) in ``d``: its vorticity and divergence from the wind
    (``uv_nodal_to_vor_div_modal``), its potential g (h − H) (H: ``d["mean_depth"]``, the
    reference geopotential g H of its semi-implicit step), its orography g hs, modal
    (Dinosaur's own mountain test sets these two so: ``shallow_water_test._get_mountain``;
    None without a mountain). Nondimensional, Dinosaur's units."""
    from dinosaur import scales, shallow_water, spherical_harmonic

    m, s = scales.units.m, scales.units.s
    nd = specs.nondimensionalize
    wind, metre, g = float(nd(1.0 * m / s)), float(nd(1.0 * m)), specs.g
    depth = float(d["mean_depth"]) * metre
    vor, div = spherical_harmonic.uv_nodal_to_vor_div_modal(grid, d["u"] * wind, d["v"] * wind)
    potential = grid.to_modal(g * (d["h"] * metre - depth))
    orography = grid.to_modal(g * d["hs"] * metre) if np.any(d["hs"]) else None
    state = shallow_water.State(vor[None], div[None], potential[None])
    return state, shallow_water.ShallowWaterEquations(coords, specs, orography, np.array([g * depth]))


def peer_fields(grid, specs, eq, state, d) -> dict:
    """The peer's nodal relative vorticity (s⁻¹), fluid depth h and free surface h + hs (m,
    with its own orography) of a modal ``state``, each clipped of its top total wavenumber as
    the peer's tendencies are (``clip_wavenumbers``: its orography's top mode never acts)."""
    from dinosaur import scales

    per_second = float(specs.dimensionalize(1.0, scales.units("1/s")).magnitude)
    metre, g = float(specs.nondimensionalize(1.0 * scales.units.m)), specs.g
    potential = grid.clip_wavenumbers(state.potential[0])
    surface = potential if eq.orography is None else grid.clip_wavenumbers(state.potential[0] + eq.orography)
    depth = float(d["mean_depth"])
    return dict(
        vorticity=np.asarray(grid.to_nodal(grid.clip_wavenumbers(state.vorticity)))[0] * per_second,
        h=np.asarray(grid.to_nodal(potential)) / g / metre + depth,
        h_surface=np.asarray(grid.to_nodal(surface)) / g / metre + depth,
    )


# -- swe_sphere, in the project's environment --------------------------------------------------
def swe_child(study: str, config: str, out: Path, device: str = "cpu") -> None:
    """Run ``study``'s scene in the configuration ``config`` (``parse_swe``) on ``device`` to its
    last day and write its vorticity, h and h + hs at the last day at its unique nodes, their
    lat/lon (rad) and area, its Δt, the step loop's CPU and wall seconds a day between day 1 and
    the last, and its own score of the study's field (``ref_l2_vorticity`` or
    ``ref_l2_h_surface``), to ``out``."""
    import netCDF4

    from swe_sphere import Simulation

    st, (ne, np_, stepper, dt, sets) = STUDIES[study], parse_swe(config)
    kw = {} if dt is None else {"dt": dt}
    sim = Simulation(
        st.scene,
        device,
        ne=ne,
        np=np_,
        stepper=stepper,
        days=st.days,
        output={"every_days": 1.0},
        case={"reference": "T341"},
        **kw,
        **sets,
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "run.nc"
        result = sim.run(path)
        day = {round(h["steps"] * sim.scene.dt / 86400, 6): h for h in result.history}
        with netCDF4.Dataset(path) as ds:
            f = {k: np.asarray(ds[k][...], dtype=np.float64) for k in ("lat", "lon", "area", "hs")}
            zeta, h = (np.asarray(ds[k][-1], dtype=np.float64) for k in ("vorticity", "h"))
            own = float(ds[f"ref_l2_{st.field}"][-1])
    np.savez(
        out,
        vorticity=zeta,
        h=h,
        h_surface=h + f["hs"],
        lat=np.radians(f["lat"]),
        lon=np.radians(f["lon"]),
        area=f["area"],
        dt=sim.scene.dt,
        cpu_per_day=(day[st.days]["cpu_time"] - day[1.0]["cpu_time"]) / (st.days - 1.0),
        wall_per_day=(day[st.days]["wall_time"] - day[1.0]["wall_time"]) / (st.days - 1.0),
        own=own,
    )


if __name__ == "__main__":
    if sys.argv[1:2] == ["--peer-child"]:
        peer_child(Path(sys.argv[2]), Path(sys.argv[3]), sys.argv[4])
    else:  # --swe-child
        swe_child(sys.argv[2], sys.argv[3], Path(sys.argv[4]), sys.argv[5])
