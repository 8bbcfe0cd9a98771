"""The Python entry point: ``swe_sphere.run(scene, **overrides) -> xarray.Dataset``."""

from __future__ import annotations

import contextlib
import tempfile
from pathlib import Path

from tqdm import tqdm

from .config.scene import LOAD_KEYWORDS, flat_overrides, load_scene
from .config.state_scene import is_state_file
from .core.arguments import flag_argument, number_argument, path_argument
from .core.backend import pick_device
from .core.errors import OutputError, SceneError
from .io.reanalysis import given
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

    Parameters
    ----------
    scene : str, path, Scene or xarray.Dataset
        A scene file, the name of a bundled scene ("tc5_mountain") or a ``config.Scene``; or a
        reanalysis state, a netCDF file (``*.nc``) or a Dataset of height and wind on a lat-lon
        grid (``io.reanalysis``), run with case 7's settings (``config.scene.load_scene``); its
        level, time and truncation as ``case={"level": 500, "time": "month=1"}``.
    device : {"cpu", "cuda"}, optional
        Warp device (default: ``SWE_SPHERE_DEVICE`` where set, else CUDA when present, else the CPU).
    output_file : str or path, optional
        Also keep the run's netCDF file there; streams of ``output={"streams": [...]}``
        are written beside it (without it they are dropped with a temporary folder).
    overwrite : bool
        Replace an existing ``output_file`` (and restart file).
    restart_every : float, optional
        Write a restart file every this many model days and at the end (``Simulation.run``).
    progress : bool
        Show a progress bar.
    verbose : bool
        Show Warp's banner and module loads, and with ``output={"log_every_steps": N}`` a line of
        invariant changes and Courant numbers every N steps (``simulation.activities.log_line``); quiet otherwise.
    initial : callable, optional
        ``initial(lat, lon) -> (h, u, v)`` (lat, lon in radians; h in m, u, v in m s⁻¹), the state
        at t = 0 instead of the case's; the case still gives fcor, hs and the truth the errors are
        against (``initial_state.from_function``).
    graphs : {"auto", "on", "off"} or bool, optional
        Steps as captured graphs (``Simulation``'s; default ``SWE_SPHERE_GRAPHS``, else "auto").
    **overrides
        As on the command line: ``ne``, ``np``, ``dt`` (s), ``days``, ``stepper``, ``mesh`` (an
        Exodus II file, as ``--mesh``; dt and ν rescale with a new grid as for ``--ne``),
        ``precision`` ("float64" or "float32": the RHS tendency's, as ``--precision``), and any
        scene value by its table, e.g. ``hyperviscosity={"nu": 5e14}``,
        ``implicit={"preconditioner": "helmholtz"}``, ``output={"every_days": 0.25}``,
        ``terms=[...]``, ``planet={"radius": 637122.0, "omega": 7.292e-4}`` (m, s⁻¹; ``gravity``
        in m s⁻²); validated like the file.

    Returns
    -------
    xarray.Dataset
        h, u, v, vorticity on (time, ncol) with time in model days (the file's CF time
        read undecoded: ``ds.h.sel(time=3)``), lat, lon, area on ncol, the diagnostics
        time series (mass_change, l2_h, ...) and the resolved scene in ``ds.attrs["scene"]``.
        A scene with an [ensemble] (``ensemble={"members": N, ...}``) runs its members
        (``Simulation`` with ``members``, as ``swe-sphere run`` does): the fields on (time, member, ncol)
        with their ``_mean`` and ``_spread``, the series on (time, member).

    Raises
    ------
    SceneError
        A bad scene, override, ``device``, ``initial`` (or one with an [ensemble]), ``graphs`` or
        ``restart_every`` (not a number of days > 0), or ``overwrite``, ``progress`` or ``verbose``
        not a bool (a ValueError; the message names the argument or value).
    OutputError
        ``output_file`` is not a path (str or os.PathLike), exists (without ``overwrite``), is
        an input or a directory.
    BlowUp
        The state became non-finite or the depth non-positive; the result is on the
        exception, the file keeps every good output.
    StepFailure
        A solver did not converge.
    Interrupted
        SIGINT or SIGTERM in the main thread.
    ResourceError
        Too little memory for the grid.

    Warns
    -----
    MembersAlike
        An [ensemble]'s members that start alike (``Simulation``'s).
    """
    for name, value in (("overwrite", overwrite), ("progress", progress), ("verbose", verbose)):
        flag_argument(name, value, SceneError)
    if restart_every is not None:
        number_argument("restart_every", restart_every, "days", positive=True, error=SceneError)
    if output_file is not None:
        path = path_argument("output_file", output_file, "a file's path (str or os.PathLike)", OutputError)
        if path.name in ("", "..") or path.is_dir():
            raise OutputError(f"output_file = {str(output_file)!r} is a directory: give a file name in it")
    device = pick_device(device, verbose=verbose)
    with state_source(scene, overrides) as (scene, overrides):  # a reanalysis file or Dataset: its Scene
        return _run(scene, overrides, device, output_file, overwrite, restart_every, progress, verbose, initial, graphs)


def _run(scene, overrides, device, output_file, overwrite, restart_every, progress, verbose, initial, graphs):
    """``run`` once its arguments are checked and ``scene`` is a scene (name, path or Scene): its
    run file (or a temporary one) loaded in memory, time in model days (``output.TIME_ATTRS``)."""
    # a scene's [ensemble] (``ensemble={"members": N, ...}``): its members, the one driver's
    sim = Simulation(scene, device, progress=progress, initial=initial, graphs=graphs, **overrides)
    log = tqdm.write if verbose else None  # output={"log_every_steps": N}: a line every N steps
    import xarray as xr

    with tempfile.TemporaryDirectory(prefix="swe_sphere_") as tmp:
        path = Path(output_file) if output_file is not None else Path(tmp) / f"{sim.scene.name}.nc"
        history = f"swe_sphere.run({sim.scene.name!r})"
        sim.run(path, overwrite=overwrite, restart_every=restart_every, history=history, log=log)
        with xr.open_dataset(path, decode_times=False) as ds:
            return ds.load()


@contextlib.contextmanager
def state_source(scene, overrides: dict):
    """(scene, overrides) as ``run`` takes them, a reanalysis file's path (``*.nc``) or an
    ``xarray.Dataset`` made into its ``Scene`` (``config.scene.load_scene``; the Dataset read as it is
    for the run's length, ``io.reanalysis.given``), with no overrides left; else as given."""
    import xarray as xr

    if not (isinstance(scene, xr.Dataset) or is_state_file(scene)):
        yield scene, overrides
        return
    keywords = {name: overrides.pop(key) for key, name in LOAD_KEYWORDS.items() if key in overrides}
    if not isinstance(scene, xr.Dataset):
        yield load_scene(scene, overrides=flat_overrides(overrides), **keywords), {}
        return
    with given(scene) as name:  # read as it is (no file written), named as given
        yield load_scene(name, overrides=flat_overrides(overrides), **keywords), {}


__all__ = ["run"]
