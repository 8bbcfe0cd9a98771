"""The files a command writes: refused where one exists (unless overwritten) or is one of its
inputs, one writer a file (a lock file beside it, taken ahead by a command so that it refuses at
its start), written under a ``.part`` name and moved onto the target when whole, so a file
appears complete or not at all; a study's folder locked while it runs."""

from __future__ import annotations

import contextlib
import fcntl
import os
from pathlib import Path

from ..core.errors import OutputError


def check_target(path: Path, overwrite: bool = False) -> None:
    """Raise ``OutputError`` (one line) unless ``path`` may be written: its folder
    exists and is writable, and it does not exist (or ``overwrite`` and it is a
    writable regular file). A symbolic link or a non-regular file (directory,
    FIFO, device) is never written, with or without ``overwrite``."""
    path = Path(path)
    parent = path.absolute().parent
    if path.is_symlink():
        raise OutputError(f"output path is a symbolic link (not written through): {path}")
    if path.exists():
        if path.is_dir():
            raise OutputError(f"output path is a directory: {path}")
        if not path.is_file():
            raise OutputError(f"output path is not a regular file: {path}")
        if not overwrite:
            raise OutputError(f"output file exists: {path} (--overwrite, or overwrite=True in Python, replaces it)")
        if not os.access(path, os.W_OK):
            raise OutputError(f"output file is read-only: {path}")
    if parent.exists() and not parent.is_dir():
        raise OutputError(f"output path's parent is not a directory: {parent}")
    if not parent.is_dir():
        raise OutputError(f"output directory does not exist: {parent}")
    if not os.access(parent, os.W_OK):
        raise OutputError(f"output directory is not writable: {parent}")


def _identity(path: Path):
    """(device, inode) of the file ``path`` names after resolving links; None if there is none."""
    try:
        st = os.stat(path)
    except OSError:
        return None
    return st.st_dev, st.st_ino


def check_distinct(outputs, inputs) -> None:
    """Raise ``OutputError`` (one line) if an output would replace an input.

    Each output path and its ``.part`` and ``.lock`` siblings (``ExclusiveFile``
    writes and removes them) are compared with every input by device and inode
    after resolving links, so another spelling, a link or a hard link of the
    input is caught as well as the same name. ``None`` entries are skipped."""
    known = {}
    for inp in inputs:
        if inp is not None and (ident := _identity(Path(inp))) is not None:
            known[ident] = inp
    for out in outputs:
        if out is None:
            continue
        out = Path(out)
        for path in (out, out.with_name(out.name + ".part"), out.with_name(out.name + ".lock")):
            inp = known.get(_identity(path))
            if inp is not None:
                raise OutputError(
                    f"the output {path} is the input {inp}; writing it would replace the input (choose another output)"
                )


def acquire_lock(lock: Path, what) -> int:
    """An exclusive ``flock`` on the file ``lock`` (created, never through a link):
    its descriptor, or ``OutputError`` naming ``what`` when another process holds it.
    The holder removes ``lock`` before closing the descriptor (``release_lock``)."""
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError as err:
            raise OutputError(f"cannot create {lock}: {err.strerror}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            raise OutputError(f"another run is writing {what} (it holds {lock})") from None
        try:  # the previous holder may have removed the file between our open and lock
            if os.stat(lock, follow_symlinks=False).st_ino == os.fstat(fd).st_ino:
                return fd
        except FileNotFoundError:
            pass
        os.close(fd)


def release_lock(lock: Path, fd: int) -> None:
    """Undo ``acquire_lock``: remove the file first, so a waiting process retries on a new one."""
    lock.unlink(missing_ok=True)
    os.close(fd)


@contextlib.contextmanager
def folder_lock(folder: Path, name: str):
    """Create ``folder`` (with its parents) and hold ``folder/name`` locked while the
    block runs, so a second command on the same folder is refused at its start
    (``OutputError``) instead of computing everything and failing at the end. A block
    that raises leaves no folder this made and nothing was written in (a refusal writes
    nothing); one that holds a file is kept."""
    folder = Path(folder)
    made = [p for p in (folder, *folder.parents) if not p.exists()]  # deepest first
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise OutputError(f"cannot create output directory {folder}: {err.strerror}") from None
    lock = folder / name
    fd = acquire_lock(lock, folder)
    done = False
    try:
        yield folder
        done = True
    finally:
        release_lock(lock, fd)
        for path in made if not done else ():
            try:
                path.rmdir()
            except OSError:  # not empty: what the block wrote is kept
                break


_HELD: dict[str, int] = {}  # lock file (absolute) → descriptor: held ahead by ``HeldLock``, not yet taken by a writer


class HeldLock:
    """``with HeldLock(path):`` the writer's lock of ``path`` (``path.lock``) taken now, when
    the object is made, so that a command refuses at its start (``OutputError``, one line,
    when another process writes ``path``) rather than after its set-up and header; the next
    ``ExclusiveFile`` of ``path`` in this process takes it over and releases it when done.
    A lock no writer took over is released at the block's end."""

    def __init__(self, path):
        path = Path(path)
        self.lock = path.with_name(path.name + ".lock")
        self.key = os.path.abspath(self.lock)
        self.fd = acquire_lock(self.lock, path)
        _HELD[self.key] = self.fd

    def __enter__(self) -> HeldLock:
        return self

    def __exit__(self, *exc) -> None:
        if _HELD.get(self.key) == self.fd:
            del _HELD[self.key]
            release_lock(self.lock, self.fd)


class ExclusiveFile:
    """Write ``path`` through ``path.part``, so two processes never write the
    same file and a file is never written through a link: the writer holds an
    exclusive ``flock`` on ``path.lock`` (removed when done; taken over from a
    ``HeldLock`` of this process where there is one) and creates the
    part with O_EXCL | O_NOFOLLOW. A second writer gets ``OutputError``; a
    ``.part`` left by a killed run (its lock is free) is replaced with
    ``overwrite``, else refused. ``commit`` moves the finished part onto
    ``path`` (without ``overwrite``, only if ``path`` still does not exist);
    ``discard`` drops it. As a context manager it yields the part's path and
    commits on success.

    (The lock is a file of its own: HDF5 locks the file it writes itself, and a
    POSIX lock on it would be released when the netCDF library closes it.)
    """

    def __init__(self, path, *, overwrite: bool = False):
        self.path, self.overwrite = Path(path), overwrite
        self.tmp = self.path.with_name(self.path.name + ".part")
        self.lock = self.path.with_name(self.path.name + ".lock")
        check_target(self.path, overwrite)
        self.lock_fd = self._acquire()
        try:
            try:
                self._create()
            except FileExistsError:  # we hold the lock: whoever wrote it is gone
                if not overwrite:
                    raise OutputError(
                        f"{self.tmp} was left by a run that was killed (--overwrite, or overwrite=True in Python, replaces it)"
                    ) from None
                self.tmp.unlink()
                self._create()
        except BaseException:
            self._release()
            raise

    def _acquire(self) -> int:
        held = _HELD.pop(os.path.abspath(self.lock), None)  # taken ahead by the command (``HeldLock``)
        return acquire_lock(self.lock, self.path) if held is None else held

    def _create(self) -> None:
        try:
            os.close(os.open(self.tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644))
        except FileExistsError:
            raise
        except OSError as err:
            raise OutputError(f"cannot create {self.tmp}: {err.strerror}") from None

    def _release(self) -> None:
        if self.lock_fd is not None:
            release_lock(self.lock, self.lock_fd)
            self.lock_fd = None

    def commit(self) -> None:
        try:
            check_target(self.path, self.overwrite)
            if self.overwrite:
                os.replace(self.tmp, self.path)
                return
            try:
                os.link(self.tmp, self.path)  # fails if the target appeared meanwhile
            except FileExistsError:
                raise OutputError(
                    f"{self.path} appeared while it was written; the result is kept in {self.tmp}"
                ) from None
            except OSError:  # a file system without hard links: check, then rename
                check_target(self.path, False)
                os.rename(self.tmp, self.path)
                return
            os.unlink(self.tmp)
        finally:
            self._release()

    def discard(self) -> None:
        self.tmp.unlink(missing_ok=True)
        self._release()

    def __enter__(self) -> Path:
        return self.tmp

    def __exit__(self, kind, value, tb):
        if kind is None:
            self.commit()
        else:
            self.discard()


def release_held_locks() -> None:
    """Release every lock taken ahead (``HeldLock``) that no writer took over (a failing
    process's last act: ``run_file.close_open_runs``)."""
    for key, fd in list(_HELD.items()):
        del _HELD[key]
        release_lock(Path(key), fd)


def check_results(directory: Path, names, overwrite: bool = False) -> None:
    """``check_target`` for each of a command's result files ``names`` under
    ``directory`` (a folder still to be made holds none), so a study is refused
    before it runs rather than replacing an earlier one's results at its end."""
    directory = Path(directory)
    if directory.is_dir():
        for name in names:
            check_target(directory / name, overwrite)


def atomic_path(path: Path, *, overwrite: bool = True) -> ExclusiveFile:
    """``with atomic_path(p) as tmp:`` write tmp; it is moved onto ``p`` if the block succeeds."""
    return ExclusiveFile(path, overwrite=overwrite)
