"""A file written whole or not at all: under a temporary name beside it, then renamed."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path


@contextlib.contextmanager
def replaced(path: Path, mode: int = 0o644):
    """``with replaced(p) as tmp:`` write ``tmp`` (a new file in ``p``'s folder, permissions
    ``mode``); when the block succeeds it is moved onto ``p`` by ``os.replace`` (atomic on
    POSIX: a reader sees the old file or the new one, never a part), else removed. Raises
    ``OSError`` where the folder cannot be written. (Run files, which must also not replace
    another's, go through ``io.output_files.atomic_path`` and its lock.)"""
    path = Path(path)
    handle, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    os.close(handle)
    try:
        os.chmod(tmp, mode)  # mkstemp's is 0600
        yield Path(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
