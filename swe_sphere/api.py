"""The Python entry point: ``swe_sphere.run(scene, **overrides) -> xarray.Dataset``."""

from __future__ import annotations

import tempfile
from pathlib import Path

from .core.runtime import pick_device
from .simulation.simulation import Simulation


def run(
    scene,
    *,
    device: str | None = None,
    output_file=None,
    overwrite: bool = False,
    restart_every: float | None = None,
    progress: bool = False,
    verbose: bool = False,
    initial=None,
    graphs: str | bool | None = None,
    **overrides,
):
    """Run a scene and return its output as an ``xarray.Dataset`` (loaded in memory).

    ``scene``: a scene file, the name of a bundled scene ("tc5_mountain") or a
    ``config.Scene``. ``overrides`` as on the command line: ``ne``, ``np``,
    ``dt`` (s), ``days``, ``stepper``, ``mesh`` (an Exodus II file, as ``--mesh``; dt and ν
    rescale with a new grid as for ``--ne``), and any scene value by its table, e.g. ``hyperviscosity={"nu":
    5e14}``, ``implicit={"preconditioner": "helmholtz"}``, ``output={"every_days":
    0.25}``, ``terms=[...]``, ``planet={"radius": 637122.0, "omega": 7.292e-4}``
    (m, s⁻¹; ``gravity`` in m s⁻²: a planet of one's own, see ``config``); all
    validated like the file (``SceneError``, a ValueError, names the offending
    value). ``device``: "cpu" | "cuda"
    (default: CUDA when present). ``output_file``: also keep the netCDF file there
    (``OutputError`` if it exists, unless ``overwrite``); ``restart_every``
    (days) writes its restart file (see ``Simulation.run``). ``initial``: a function
    ``initial(lat, lon) -> (h, u, v)`` (radians in; m, m s⁻¹ out) giving the state
    at t = 0 instead of the case's (which still gives fcor and hs, and the truth
    the errors are against; ``initial_state.from_function``). Streams of
    ``output={"streams": [...]}`` are written beside ``output_file`` (without
    one, they are dropped with the temporary folder). ``graphs``: "auto", "on" or
    "off" (``Simulation``'s; default ``SWE_SPHERE_GRAPHS``, else "auto").

    Quiet unless ``verbose`` (no Warp banner or module-load lines; ``progress``
    shows a progress bar; with ``output={"log_every_steps": N}`` a line of
    invariant changes and Courant numbers every N steps, ``Simulation.log_line``). Raises ``simulation.BlowUp`` (the result is on the
    exception, the file keeps every good output), ``runtime.Interrupted``
    (SIGINT/SIGTERM in the main thread), ``steppers.StepFailure``,
    ``runtime.ResourceError`` (not enough memory for the grid).

    The dataset holds h, u, v, vorticity on (time, ncol) with time in model
    days (the file's CF time read undecoded: ``ds.h.sel(time=3)``), lat/lon/area on ncol, the diagnostics time
    series (mass_change, l2_h, ...) and the resolved scene in ``ds.attrs["scene"]``.
    """
    import xarray as xr
    from tqdm import tqdm

    device = pick_device(device, verbose=verbose)
    sim = Simulation(scene, device, progress=progress, initial=initial, graphs=graphs, **overrides)
    scene = sim.scene
    with tempfile.TemporaryDirectory(prefix="swe_sphere_") as tmp:
        path = Path(output_file) if output_file is not None else Path(tmp) / f"{scene.name}.nc"
        sim.run(
            path,
            overwrite=overwrite,
            restart_every=restart_every,
            history=f"swe_sphere.run({scene.name!r})",
            log=tqdm.write if verbose else None,
        )  # output={"log_every_steps": N}: a line every N steps
        with xr.open_dataset(path, decode_times=False) as ds:  # time in model days (output.TIME_ATTRS)
            return ds.load()


__all__ = ["run"]
