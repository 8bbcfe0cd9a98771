"""What the package ships (``swe_sphere.testcases``: scenes, tableaus, references, data) names its
sources, not the folders of the machine that made it (issue 127, item 2: the references' ``solver``
and ``history`` attributes held ``/tmp/...`` paths)."""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import netCDF4
import pytest

# an absolute POSIX path: a slash that starts a word, then at least one folder
ABSOLUTE = re.compile(r"""(?:^|[\s'"=(`:,;])(/[\w.~-]+/[\w.~/-]*)""")


def shipped(suffixes) -> list:
    root = resources.files("swe_sphere.testcases")
    found, stack = [], [root]
    while stack:
        for item in stack.pop().iterdir():
            if item.is_dir():
                stack.append(item)
            elif item.name.endswith(suffixes):
                found.append(item)
    return sorted(found, key=str)


def test_the_absolute_path_pattern_finds_paths_and_not_units():
    found = ABSOLUTE.findall("code /tmp/specref/swsolver.py; --out '/home/x/a.nc' m s-1, h / g, 1/2, swsolver.py")
    assert found == ["/tmp/specref/swsolver.py", "/home/x/a.nc"]


def folders_named(path) -> dict:
    """The absolute paths each text attribute (global or a variable's) of the netCDF file ``path`` names."""
    with netCDF4.Dataset(str(path)) as nc:
        owners = [("global", nc), *nc.variables.items()]
        texts = {
            f"{where}:{name}": value
            for where, obj in owners
            for name in obj.ncattrs()
            if isinstance(value := obj.getncattr(name), str)
        }
    return {k: ABSOLUTE.findall(v) for k, v in texts.items() if ABSOLUTE.findall(v)}


@pytest.mark.parametrize("path", shipped((".nc",)), ids=lambda p: p.name)
def test_no_shipped_netcdf_file_names_a_folder(path):
    assert folders_named(path) == {}


@pytest.mark.parametrize("path", sorted((Path(__file__).parent / "data" / "meshes").glob("*.g")), ids=lambda p: p.name)
def test_no_test_mesh_names_a_folder(path):
    """The repository's Exodus meshes too (mountain_10_x2.g's title named its maker's /Users/... folder)."""
    assert folders_named(path) == {}


@pytest.mark.parametrize("path", shipped((".md", ".toml", ".py")), ids=lambda p: p.name)
def test_no_shipped_text_file_names_a_folder(path):
    assert ABSOLUTE.findall(path.read_text()) == []
