"""One writer per output directory: ``filelock``'s ``flock`` on ``<dir>/.lock``, held for the life of a launch.

A second launch on the same sweep or job dir stops at once with one line naming the holder (:class:`Locked`); the
lock goes with the holder's process however it ends, and is re-entrant within one process (a single-run launch and
its job share one dir). While held, every write of the block goes through the dir's descriptor
(:func:`rovermarl.record.atomic.beneath`). ``filelock`` (>= 4.3) opens the lock file with ``O_NOFOLLOW`` and never
truncates it; before it does and once the lock is held, a lock file that is a link, not regular, hard-linked or not
this dir's own is refused (:class:`~rovermarl.record.safe_read.Unsafe`) and left as it was; only then is the
holder's line (PID, host, since when) written. A launch that writes nothing leaves no directory behind.
"""

from __future__ import annotations

import contextlib
import errno
import os
import socket
import stat
import time
from pathlib import Path

import filelock

from rovermarl.record.atomic import beneath, remove_stale
from rovermarl.record.safe_read import Unsafe

NAME = ".lock"
_HELD: set[Path] = set()                                 # directories this process holds
TRIES = 100                                              # a lock file removed under us this often: give up


class Locked(Exception):
    """Another process holds the directory's lock; ``str(err)`` is one line naming it."""


@contextlib.contextmanager
def hold(directory: Path, clean: bool = False):
    """Hold ``directory``'s lock (creating the directory) for the ``with`` block, every write of which stays beneath
    it; :class:`Locked` if taken. ``clean``: first remove the temp files a killed launch left under it (a launch's and
    a job's lock, taken before they write)."""
    directory = Path(directory)
    key = directory.resolve()
    if key in _HELD:
        yield directory
        return
    created = [d for d in (key, *key.parents) if not d.exists()]           # deepest first
    for _ in range(TRIES):
        with beneath(directory) as dfd:
            try:
                held = _acquire(dfd, directory)
            except FileNotFoundError:     # the dir was removed meanwhile (by a launch that wrote nothing): again
                continue
            if held is None:              # its lock file was: again
                continue
            try:
                _HELD.add(key)
                if clean:
                    remove_stale(dfd)
                yield directory
            finally:
                _HELD.discard(key)
                if created and os.listdir(dfd) in ([], [NAME]):            # nothing was written: leave nothing,
                    with contextlib.suppress(OSError):                     # removed while still held
                        os.unlink(NAME, dir_fd=dfd)
                    with contextlib.suppress(OSError):
                        for d in created:
                            d.rmdir()
                held.release()
            return
    raise Locked(f"{directory}'s lock file kept disappearing ({TRIES} tries); another launch is using it")


def _acquire(dfd: int, directory: Path) -> filelock.FileLock | None:
    """``directory``'s lock, held by this process; None if its file was removed meanwhile (try again);
    :class:`Locked` if another process holds it."""
    path = directory / NAME
    with contextlib.suppress(FileNotFoundError):
        _own(os.stat(NAME, dir_fd=dfd, follow_symlinks=False), path)
    lock = filelock.FileLock(path, blocking=False, thread_local=False, preserve_lock_file=True,
                             on_acquired=lambda fd: _stamp(dfd, path, fd))
    try:
        lock.acquire()
    except filelock.Timeout:
        try:
            fd = os.open(NAME, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, dir_fd=dfd)
        except FileNotFoundError:
            return None
        try:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "another process"
        finally:
            os.close(fd)
        raise Locked(f"{directory} is in use by {holder}; wait for it to finish or choose another output dir") from None
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise Unsafe(f"{path} is a symbolic link: refused (remove it; a lock is this dir's own file)") from None
        raise
    return lock


def _own(st: os.stat_result, path: Path) -> None:
    """Refuse a lock file that is a link, not a regular file, or shares its data with a file elsewhere."""
    problem = ("is a symbolic link" if stat.S_ISLNK(st.st_mode) else
               "is not a regular file" if not stat.S_ISREG(st.st_mode) else
               f"has {st.st_nlink} hard links (a file elsewhere shares it)" if st.st_nlink > 1 else None)
    if problem:
        raise Unsafe(f"{path} {problem}: refused (remove it; a lock is this dir's own file)")


def _stamp(dfd: int, path: Path, fd: int) -> None:
    """``filelock``'s ``on_acquired``: once locked, check that ``fd`` is the held dir's own lock file, then write the
    holder's line into it (raising makes ``filelock`` let go of the lock)."""
    st = os.fstat(fd)
    _own(st, path)
    now = os.stat(NAME, dir_fd=dfd, follow_symlinks=False)
    if (now.st_ino, now.st_dev) != (st.st_ino, st.st_dev):
        raise Unsafe(f"{path} was replaced while it was being locked: refused (another process is changing this dir)")
    line = f"PID {os.getpid()} on {socket.gethostname()} since {time.strftime('%Y-%m-%d %H:%M:%S')}\n"
    os.ftruncate(fd, 0)
    os.pwrite(fd, line.encode(), 0)
