"""Arrays that depend on the grid alone, built once and kept on disk for every later run.

E3SM makes its grid files (SCRIP, dual grids) once per grid and every run and tool reads
them; here an entry is a set of named numpy arrays under a key (a JSON-able dict naming
what they are a function of: the grid's ne and np, the mesh and map, the version of the
code that builds them). The folder is ``$SWE_SPHERE_CACHE_DIR`` if set, else
``$XDG_CACHE_HOME/swe_sphere``, else ``~/.cache/swe_sphere``; deleting it (or any file
in it) is always safe: what is missing is built again.

An entry is one ``.npz`` file named by the key's SHA-256 whose ``header`` holds the key
and the SHA-256 of the arrays (names, dtypes, shapes and bytes). It is written under a
temporary name in the same folder and moved onto its name with ``os.replace`` (atomic on
POSIX), so a process reading or writing the same entry at the same time sees the whole
file or none. A file that cannot be read, or whose key or checksum differs (damaged, or
another version's), is built again and replaced, never trusted.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from .files import replaced

FORMAT = 1  # of the entry files; part of every key


def cache_dir() -> Path:
    """The cache folder (not created): ``$SWE_SPHERE_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/swe_sphere``, else ``~/.cache/swe_sphere`` (XDG Base Directory)."""
    if os.environ.get("SWE_SPHERE_CACHE_DIR"):
        return Path(os.environ["SWE_SPHERE_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "swe_sphere"


def entry_path(kind: str, key: dict) -> Path:
    """The file of the entry ``kind`` (a word, the file name's start) under ``key``."""
    digest = hashlib.sha256(_key_text(kind, key).encode()).hexdigest()[:24]
    return cache_dir() / f"{kind}-{digest}.npz"


def _key_text(kind: str, key: dict) -> str:
    return json.dumps({"kind": kind, "format": FORMAT, **key}, sort_keys=True)


def checksum(arrays: dict[str, np.ndarray]) -> str:
    """SHA-256 over the arrays' names, dtypes, shapes and bytes, in name order."""
    h = hashlib.sha256()
    for name in sorted(arrays):
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def read(kind: str, key: dict) -> dict[str, np.ndarray] | None:
    """The arrays of an entry, or None where it is missing, unreadable or not this key's
    (its header's key or checksum differs)."""
    path = entry_path(kind, key)
    try:
        with np.load(path, allow_pickle=False) as f:
            arrays = {name: f[name] for name in f.files}
    except (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile):  # missing, cut short, not a zip, bad CRC
        return None
    try:
        header = json.loads(bytes(arrays.pop("header")).decode())
    except (KeyError, ValueError, TypeError):
        return None
    if header.get("key") != _key_text(kind, key) or header.get("sha256") != checksum(arrays):
        return None
    return arrays


def write(kind: str, key: dict, arrays: dict[str, np.ndarray]) -> Path:
    """Store ``arrays`` as the entry ``kind``/``key``, atomically; the folder is made if
    missing. Raises ``OSError`` where it cannot be written (the entry then stays as it was)."""
    path = entry_path(kind, key)
    path.parent.mkdir(parents=True, exist_ok=True)
    header = json.dumps({"key": _key_text(kind, key), "sha256": checksum(arrays)}).encode()
    with replaced(path, mode=0o600) as tmp, open(tmp, "wb") as f:
        np.savez(f, header=np.frombuffer(header, dtype=np.uint8), **arrays)
        f.flush()
        os.fsync(f.fileno())
    return path


def cached(kind: str, key: dict, build: Callable[[], dict[str, np.ndarray]]) -> tuple[dict[str, np.ndarray], bool]:
    """(the arrays of entry ``kind``/``key``, whether they were built now): read from the
    cache, else ``build()`` and stored (a cache folder that cannot be written leaves them
    unstored: the next run builds them again)."""
    arrays = read(kind, key)
    if arrays is not None:
        return arrays, False
    arrays = build()
    try:
        write(kind, key, arrays)
    except OSError:
        pass  # a read-only or full cache costs the next run a build, never this run its output
    return arrays, True
