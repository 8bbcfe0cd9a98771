"""No 64-bit integer attributes in the files swe_sphere writes (issue 65, item 10): netCDF-3
(``nccopy -k classic``) holds none, and docs/how-to/other-tools.md says there are none."""

from __future__ import annotations

import netCDF4
import numpy as np
import pandas as pd

from swe_sphere.io.table_file import table_dataset
from swe_sphere.simulation.simulation import Simulation


def _int64_attributes(path) -> list[str]:
    with netCDF4.Dataset(path) as ds:
        found = [k for k, v in ds.__dict__.items() if np.asarray(v).dtype.kind in "iu" and np.asarray(v).itemsize > 4]
        for var in ds.variables.values():
            found += [
                f"{var.name}:{k}"
                for k, v in var.__dict__.items()
                if np.asarray(v).dtype.kind in "iu" and np.asarray(v).itemsize > 4
            ]
    return found


def test_a_restart_file_has_no_64_bit_integer_attribute(tmp_path):
    sim = Simulation("tc2_steady", "cpu", ne=2, np=3, days=0.02, stepper="leapfrog")
    sim.run(None)
    path = sim.write_checkpoint(tmp_path / "r.restart.nc")
    assert _int64_attributes(path) == []
    with netCDF4.Dataset(path) as ds:
        assert ds.step == sim.step > 0


def test_a_table_files_integer_attributes_are_int32(tmp_path):
    ds = table_dataset(
        pd.DataFrame({"dt": [1.0]}),
        "run",
        {"dt": ("s", "dt")},
        row_long_name="run",
        title="t",
        history="h",
        attrs={"ne": 2, "days": 1.5, "case": "tc2"},
    )
    ds.to_netcdf(tmp_path / "t.nc")
    assert _int64_attributes(tmp_path / "t.nc") == [] and ds.attrs["ne"].dtype == np.int32
