"""A study's table of results (one row a run or a search) as a CF-1.8 netCDF file.

The rows lie on one dimension, each column a variable on it with its ``units`` and
``long_name``; text columns are CF character arrays (netCDF-4's variable-length strings
are outside CF-1.8 and the classic data model: CDO refuses a file holding them, and the
NCAS CF checker reports them), integers are 32-bit (CF-1.8 has no 64-bit integer type),
and the file carries CF's ``Conventions``, ``title`` and ``history``. A dimension whose
coordinate is text is one CDO cannot read either, so the rows' coordinate is their
number (in xarray, ``set_index`` on text columns labels the rows).
"""

from __future__ import annotations

import numpy as np

from .output_files import atomic_path

CONVENTIONS = "CF-1.8"


def table_dataset(df, dim: str, columns: dict, *, row_long_name: str, title: str, history: str, attrs=None):
    """``df`` (a ``pandas.DataFrame``, one row a run or a search) as an ``xarray.Dataset`` on the
    dimension ``dim``, whose coordinate (int32) numbers the rows (``row_long_name``).

    ``columns``: {column: (units, long_name)}, in the file's order; ``units`` None marks
    a text column (missing values become ""; CF needs no units for text); integer
    columns become int32. ``attrs``: global attributes, strings kept, integers as int32
    (no 64-bit attributes: ``nccopy -k classic`` copies the file), other numbers as floats. ``title`` and ``history`` (``run_file.history_line``) join
    ``Conventions = "CF-1.8"``. Raises ``KeyError`` for a column ``df`` lacks."""
    import xarray as xr

    def column(name, units):
        if units is None:
            return df[name].fillna("").astype(str).to_numpy()
        values = df[name].to_numpy()
        return values.astype(np.int32) if values.dtype.kind == "i" else values

    ds = xr.Dataset(
        {
            name: (dim, column(name, units), dict(long_name=long_name, **({} if units is None else dict(units=units))))
            for name, (units, long_name) in columns.items()
        },
        coords={dim: (dim, np.arange(len(df), dtype=np.int32), dict(long_name=row_long_name, units="1"))},
    )
    ds.attrs.update({k: _attribute(v) for k, v in (attrs or {}).items()})
    ds.attrs.update(Conventions=CONVENTIONS, title=title, history=history)
    return ds


def _attribute(value):
    """A global attribute's value as netCDF-3 can hold it: text, int32 or float64."""
    if isinstance(value, str):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return np.int32(value)
    return float(value)


def write_table_file(ds, path, *, overwrite: bool = False) -> None:
    """Write a ``table_dataset`` to ``path`` (netCDF4) atomically (``output_files.atomic_path``),
    its text columns as character arrays. Raises ``OutputError`` when ``path`` exists and
    not ``overwrite``."""
    text = {name: {"dtype": "S1"} for name, var in ds.data_vars.items() if var.dtype.kind in "OU"}
    with atomic_path(path, overwrite=overwrite) as tmp:
        ds.to_netcdf(tmp, format="NETCDF4", encoding=text)
