"""The I/O layer: files in and out.

``run_file`` (the run's CF/UGRID netCDF), ``ugrid`` and ``dual`` (its node mesh and GLL control
volumes), ``remap`` (to a lat-lon grid), ``restart_file`` (the restart file's layout),
``initial_state`` (a start of one's own: a file or a function), ``reanalysis`` (a reanalysis
file's state analysed into spherical harmonics; Williamson's case 7), ``units`` (the units files
carry), ``observations`` (h observed at points, what an assimilation reads of a run),
``formats`` (netCDF or GRIB by a file's first bytes).

May import: ``core``, ``grid``, ``model``, ``cases``, ``solvers``, ``steppers``, ``kernels``.
"""

__all__ = [
    "dual",
    "formats",
    "initial_state",
    "observations",
    "reanalysis",
    "remap",
    "restart_file",
    "run_file",
    "ugrid",
    "units",
]
