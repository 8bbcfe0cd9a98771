"""The grid cache (``swe_sphere.core.cache``): where it lives, what it keeps, and that a damaged,
foreign or half-written entry is built again rather than trusted; then the run file's cells
read from it bit for bit as built."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from swe_sphere.core import cache
from swe_sphere.grid.cubed_sphere import CubedSphere
from swe_sphere.io import dual

KEY = {"mesh": "test", "ne": 3, "np": 4}


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "cache"))
    return tmp_path / "cache"


def arrays():
    rng = np.random.default_rng(5)
    return {"vertices": rng.standard_normal((7, 3)), "corners": np.arange(12, dtype=np.int32).reshape(3, 4)}


class Builder:
    """A build that counts its calls."""

    def __init__(self):
        self.calls = 0

    def __call__(self):
        self.calls += 1
        return arrays()


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k]) for k in a)


def test_the_folder_is_the_override_else_xdg_else_home(monkeypatch, tmp_path):
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(tmp_path / "mine"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == tmp_path / "mine"
    monkeypatch.delenv("SWE_SPHERE_CACHE_DIR")
    assert cache.cache_dir() == tmp_path / "xdg" / "swe_sphere"
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.cache_dir() == tmp_path / "home" / ".cache" / "swe_sphere"


def test_an_entry_is_built_once_and_read_back_bit_for_bit(cache_dir):
    build = Builder()
    first, built = cache.cached("grid", KEY, build)
    again, built_again = cache.cached("grid", KEY, build)
    assert (built, built_again, build.calls) == (True, False, 1)
    assert same(first, arrays()) and same(again, arrays())
    assert [p.name for p in cache_dir.iterdir()] == [cache.entry_path("grid", KEY).name]  # no temporary left
    # another key (another grid or build version) is another entry
    cache.cached("grid", {**KEY, "ne": 4}, build)
    assert build.calls == 2 and len(list(cache_dir.iterdir())) == 2


@pytest.mark.parametrize("damage", ["truncated", "flipped", "tampered", "foreign", "garbage", "empty"])
def test_a_damaged_or_foreign_entry_is_rebuilt_not_trusted(cache_dir, damage):
    build = Builder()
    cache.cached("grid", KEY, build)
    path = cache.entry_path("grid", KEY)
    data = path.read_bytes()
    if damage == "truncated":
        path.write_bytes(data[: len(data) // 2])
    elif damage == "flipped":  # one bit of the vertices' bytes: the checksum differs
        at = data.index(arrays()["vertices"].tobytes()[:16]) + 40
        path.write_bytes(data[:at] + bytes([data[at] ^ 1]) + data[at + 1 :])
    elif damage == "tampered":  # a whole zip with this key's header over other arrays: the checksum differs
        with np.load(path) as f:
            header = f["header"]
        with open(path, "wb") as f:
            np.savez(f, header=header, **{**arrays(), "vertices": arrays()["vertices"] + 1e-15})
    elif damage == "foreign":  # a whole, valid entry of another key under this key's name
        other = {**KEY, "ne": 5}
        cache.write("grid", other, {"vertices": np.zeros((2, 3)), "corners": np.zeros((1, 4), np.int32)})
        os.replace(cache.entry_path("grid", other), path)
    elif damage == "garbage":
        path.write_bytes(b"not a cache entry")
    else:
        path.write_bytes(b"")
    assert cache.read("grid", KEY) is None
    got, built = cache.cached("grid", KEY, build)
    assert built and build.calls == 2 and same(got, arrays())
    assert same(cache.read("grid", KEY), arrays())  # and the entry is whole again


def test_a_failed_write_leaves_the_old_entry_and_no_temporary(cache_dir):
    cache.write("grid", KEY, arrays())

    def refuse(src, dst):
        raise OSError("disk full")

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cache.os, "replace", refuse)
        with pytest.raises(OSError, match="disk full"):
            cache.write("grid", KEY, {"vertices": np.ones((7, 3)), "corners": np.zeros((3, 4), np.int32)})
    assert same(cache.read("grid", KEY), arrays())
    assert len(list(cache_dir.iterdir())) == 1


def test_a_cache_that_cannot_be_written_costs_a_build_not_the_result(tmp_path, monkeypatch):
    blocked = tmp_path / "file"
    blocked.write_text("a file where the folder should be")
    monkeypatch.setenv("SWE_SPHERE_CACHE_DIR", str(blocked / "cache"))
    build = Builder()
    got, built = cache.cached("grid", KEY, build)
    got2, built2 = cache.cached("grid", KEY, build)
    assert built and built2 and build.calls == 2 and same(got, arrays()) and same(got2, arrays())


@pytest.mark.parametrize("ne,np_", [(2, 4), (3, 3)])
def test_the_cells_read_from_the_cache_are_those_a_fresh_build_gives(cache_dir, ne, np_):
    fresh = dual.dual_mesh(CubedSphere(ne, np_))  # the Earth's radius, as the key's default
    built = dual.cached_cells(ne, np_)  # past the process's memo
    read = dual.cached_cells(ne, np_)
    assert built[3] is not None and built[3] >= 0 and read[3] is None  # built once, then read
    for got in (built, read):
        for a, b in zip(got[:2], fresh[:2], strict=True):
            assert a.dtype == b.dtype and np.array_equal(a, b)
        assert got[2] == fresh[2] <= dual.RTOL
    assert Path(cache.entry_path("dual_mesh", dual.cache_key(ne, np_))).is_file()
