"""What a file is by its first bytes, whatever its name: netCDF (the classic formats' ``CDF``
and netCDF-4's HDF5 signature) or GRIB (``GRIB``, ERA5's default download), which the reader
refuses with what to do instead. Sources: the netCDF file-format specification (NetCDF Users
Guide, "File Format Specifications"); the HDF5 format signature; WMO FM 92 GRIB section 0."""

from __future__ import annotations

import os
from pathlib import Path

from ..core.errors import SceneError

NETCDF_SIGNATURES = (b"CDF\x01", b"CDF\x02", b"CDF\x05", b"\x89HDF\r\n\x1a\n")
GRIB_SIGNATURE = b"GRIB"


def first_bytes(path, n: int = 8) -> bytes:
    """The first ``n`` bytes of the file ``path``; b"" for anything that is not a readable file."""
    try:
        with open(path, "rb") as f:
            return f.read(n)
    except (OSError, TypeError, ValueError):
        return b""


def is_netcdf(path) -> bool:
    """Whether the file ``path`` starts as a netCDF (classic or netCDF-4/HDF5) file does."""
    return first_bytes(path).startswith(NETCDF_SIGNATURES)


def refuse_grib(path, where: str) -> None:
    """``SceneError`` in one line, saying what to do, where the file ``path`` is GRIB."""
    if isinstance(path, (str, os.PathLike)) and first_bytes(path).startswith(GRIB_SIGNATURE):
        name = Path(path).name
        raise SceneError(
            f"{where}: a GRIB file, and states are read from netCDF: convert it (cdo -f nc copy {name} "
            f"{Path(name).stem}.nc) or download netCDF"
        )


def file_stamp(path) -> tuple | None:
    """(modification time in ns, size) of the file ``path``, the key under which a reader caches
    what it read (a file changed since is read again); None for no such file."""
    try:
        st = Path(path).stat()
        return (st.st_mtime_ns, st.st_size)
    except (OSError, TypeError):
        return None
