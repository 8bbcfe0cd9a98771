"""The site's run file page (docs/reference/run-file.md) is generated from a real run's file
(docs/_ext/run_file_page.py): every dimension and global attribute that run writes has its
meaning there, and every variable carries its own units and long_name (or is a CF bounds)."""

import sys
from pathlib import Path

import netCDF4
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "docs" / "_ext"))
import run_file_page  # noqa: E402  (the docs' extension, importable without Sphinx)


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    return run_file_page.write_run_file(tmp_path_factory.mktemp("page"))


def test_every_dimension_variable_and_attribute_of_the_run_file_is_on_the_page(run_file):
    t = run_file_page.tables(run_file)
    with netCDF4.Dataset(run_file) as ds:
        assert [d[0] for d in t["dimensions"]] == list(ds.dimensions)
        assert [v[0] for v in t["variables"]] == list(ds.variables)
        assert [a[0] for a in t["attributes"]] == ds.ncattrs()
        assert dict((d[0], d[1]) for d in t["dimensions"])["ncol"] == str(6 * 2**2 * 3**2 + 2)  # ne2 np4
    for name, dims, units, long_name, _ in t["variables"]:
        assert long_name, name
        assert units or dims == "(scalar)" or name.endswith(("_bnds", "_nodes")), name
    # the error norms of a case with an exact solution, Williamson's normalized l2 among them
    assert {"l2_h", "l2_wind", "mass_change"} <= {v[0] for v in t["variables"]}


def test_an_attribute_without_a_meaning_stops_the_page(run_file, tmp_path, monkeypatch):
    monkeypatch.delitem(run_file_page.ATTRIBUTES, "stepper")
    with pytest.raises(KeyError, match=r"without a meaning: \['stepper'\]"):
        run_file_page.tables(run_file)
