"""swe_sphere: spectral-element shallow-water model on the cubed sphere (HOMME/CAM-SE) in NVIDIA Warp.

Python API (see the README's "Python" section)::

    import swe_sphere
    ds = swe_sphere.run("tc5_mountain", ne=8, days=2, hyperviscosity={"nu": 5e14})
    ds.h.sel(time=2).mean()

``run`` is the whole pipeline (``initial=f(lat, lon) -> (h, u, v)``: a start of
one's own); beneath it, importable from here: ``load_scene``
(a TOML scene → a validated ``Scene``), ``Simulation`` (grid, case, model and
stepper of a scene; ``run``, ``from_checkpoint``, and step by step::

    sim = swe_sphere.Simulation("tc2_steady", ne=8, days=2)
    sim.add_callback(lambda s: print(s.time), every_days=0.5)
    for t in sim.steps(every=1.0):
        ds = sim.state()                # xarray on the nodes; state(remap=1.0) on a lat-lon grid
    sim.advance(days=1.0)

), ``CubedSphere``,
``ShallowWater`` (the RHS), ``make_stepper`` and ``STEPPERS`` (the registry),
``remap_dataset`` (a run on a regular lat-lon grid, for maps::

    ll = swe_sphere.remap_dataset(ds)   # or a run file's path; 1-degree grid
    ll.h_surface.sel(time=2).plot()     # a lat-lon map (matplotlib)

``swe_sphere.studies.plotting.plot_map`` draws the ``swe-sphere plot`` maps and
returns their figures), ``kinetic_energy_spectrum`` and ``zonal_mean`` (a run's
kinetic-energy spectrum by degree and zonal means, ``swe_sphere.studies.analysis``),
``gradient``, ``HeightMisfit``, ``PointHeights`` and ``HeightObservations`` (a run's
gradient, of its final state or against observations at several steps, ``swe_sphere.adjoint``),
``Perturbation``, ``MemberFile`` and ``Variants`` (how the N members of ``Simulation(scene,
members=N, initial=...)`` start, member k the bits of its single run, ``swe_sphere.members``;
``Ensemble``, their driver's deprecated name).
Importing them initialises Warp quietly (``swe_sphere.core.runtime.init_warp``).
"""

_LAZY = {
    "load_scene": "config.scene",
    "Scene": "config.scene",
    "Simulation": "simulation.simulation",
    "CubedSphere": "grid.cubed_sphere",
    "ShallowWater": "model.shallow_water",
    "make_stepper": "steppers",
    "STEPPERS": "steppers",
    "remap_dataset": "io.remap",  # a run on a lat-lon grid: maps from Python
    "kinetic_energy_spectrum": "studies.analysis",  # E_rot, E_div by spherical-harmonic degree
    "zonal_mean": "studies.analysis",
    "gradient": "adjoint.gradient",  # dJ/dx(0), dJ/dν, dJ/dhs of an explicit run (reverse sweep)
    "HeightMisfit": "adjoint.costs",
    "PointHeights": "io.observations",  # h at points, the observation operator H and Hᵀ
    "HeightObservations": "io.observations",  # a cost of the run: observed h at several steps
    "Ensemble": "ensemble",  # deprecated: Simulation(scene, members=N)
    "Perturbation": "members.initial",  # an ensemble's seeded noise in h
    "MemberFile": "members.initial",  # an ensemble's initial states from an ensemble's run file
    "Variants": "members.initial",  # an ensemble's members with their own case parameters and Ω
    # the errors (core.errors): every one is a SweSphereError
    **dict.fromkeys(
        [
            "SweSphereError",
            "SceneError",
            "ArgumentError",
            "OutputError",
            "CheckpointError",
            "BlowUp",
            "Interrupted",
            "StepFailure",
            "ResourceError",
            "MPIUnavailable",
        ],
        "core.errors",
    ),
}


def run(scene, **kwargs):
    """Run a scene; returns an ``xarray.Dataset``. See ``swe_sphere.api.run``."""
    from .api import run as _run

    return _run(scene, **kwargs)


def __getattr__(name):  # the heavy modules (Warp) load on first use, quietly
    from .core.runtime import init_warp, package_version

    if name == "__version__":  # on first use too (``runtime.package_version``)
        globals()[name] = value = package_version()
        return value
    if name not in _LAZY:
        raise AttributeError(f"module 'swe_sphere' has no attribute {name!r}")
    import importlib

    init_warp()
    value = globals()[name] = getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    return value


__all__ = ["__version__", "run", *_LAZY]
