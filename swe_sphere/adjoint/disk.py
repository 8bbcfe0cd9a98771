"""The slower tier of a two-level reverse sweep (``revolve.two_level``): states written to one
temporary file on a disk and read back (``gradient(..., disk=...)``)."""

from __future__ import annotations

import os
import tempfile

import numpy as np
import warp as wp

from ..core.errors import ArgumentError


class DiskTier:
    """States of shape ``shape`` (float64) written to one temporary file in ``folder`` (a path,
    or True: ``tempfile.gettempdir()``, which may be a memory file system such as tmpfs) and
    read back onto ``device``. The file has no name where the system allows (Linux's
    O_TMPFILE), else is unlinked at once: nothing is left in the folder when it is closed, on
    an error, or when the process ends. A context manager: the file is closed on leaving.

    ``save(j, x)`` writes x (a warp array of ``shape``) as record j (8·prod(shape) bytes at
    offset j × that); ``load(j)`` returns a new warp array equal to record j; ``bytes`` is the
    file's size (the records up to the highest written). ``ArgumentError`` for a folder that is not
    a directory; OSError from the writes (a full disk) and reads."""

    def __init__(self, folder, shape, device="cpu"):
        folder = tempfile.gettempdir() if folder is True else os.fspath(folder)
        if not os.path.isdir(folder):
            raise ArgumentError(f"disk must be True or an existing folder (got {folder!r})")
        self.shape, self.device = tuple(shape), device
        self.record = 8 * int(np.prod(self.shape))
        self.bytes = 0
        self.file = tempfile.TemporaryFile(dir=folder, prefix="swe_sphere_states_")

    def save(self, j: int, x) -> None:
        a = np.ascontiguousarray(x.numpy(), dtype=np.float64)
        if a.shape != self.shape:
            raise ValueError(f"a state of shape {self.shape} expected (got {a.shape})")
        self.file.seek(j * self.record)
        self.file.write(a.data)
        self.bytes = max(self.bytes, (j + 1) * self.record)

    def load(self, j: int):
        if not 0 <= j * self.record < self.bytes:
            raise ValueError(f"record {j} was not written")
        a = np.empty(self.shape)
        self.file.seek(j * self.record)
        if self.file.readinto(a.data) != self.record:
            raise OSError(f"record {j}: short read from the states' file")
        return wp.array(a, dtype=wp.float64, device=self.device)

    def close(self) -> None:
        self.file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
