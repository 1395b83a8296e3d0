"""One writer per output directory: an exclusive ``flock`` on ``<dir>/.lock``, held for the life of a launch.

The dir is opened once (:func:`rovermarl.record.atomic.beneath`): the lock file and every write of the block are
reached through its descriptor, never through a link. The lock file is opened with ``O_NOFOLLOW``, never truncated
nor written: a link, a non-regular file or a file with other hard links there is refused in one line
(:class:`~rovermarl.record.safe_read.Unsafe`). Once locked, the holder's line (PID, host, since when) goes into a
new file that it locks too, then renamed onto ``.lock``; a process that locked the replaced file sees that the name
no longer leads to it and tries again. (``filelock`` opens the lock by path, not beneath a held dir, and has no
hard-link check: hence this module.)

A second launch on the same sweep or job dir stops at once with one line that names the holder; the lock goes away
with the holder's process, however it ends, so a killed launch never blocks the next. Within one process the lock
is re-entrant (a single-run launch and its job share one dir). A launch that stops before writing anything leaves
no directory behind: the dirs it created for the lock are removed with it.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import socket
import stat
import time
from pathlib import Path

from rovermarl.record.atomic import atomic_open, beneath
from rovermarl.record.safe_read import Unsafe

NAME = ".lock"
_HELD: set[Path] = set()                                 # directories this process holds
TRIES = 100                                              # a lock file replaced under us this often: give up


class Locked(Exception):
    """Another process holds the directory's lock; ``str(err)`` is one line naming it."""


@contextlib.contextmanager
def hold(directory: Path):
    """Hold ``directory``'s lock (creating the directory) for the ``with`` block, every write of which stays beneath
    it; :class:`Locked` if taken."""
    directory = Path(directory)
    key = directory.resolve()
    if key in _HELD:
        yield directory
        return
    created = [d for d in (key, *key.parents) if not d.exists()]           # deepest first
    for _ in range(TRIES):
        with beneath(directory) as dfd:
            try:
                fd = _acquire(dfd, directory)
            except FileNotFoundError:     # the dir was removed meanwhile (by a launch that wrote nothing): again
                continue
            stamped = _stamp(directory, fd)
            try:
                _HELD.add(key)
                yield directory
            finally:
                _HELD.discard(key)
                if created and os.listdir(dfd) in ([], [NAME]):            # nothing was written: leave nothing,
                    with contextlib.suppress(OSError):                     # removed while still held
                        os.unlink(NAME, dir_fd=dfd)
                    with contextlib.suppress(OSError):
                        for d in created:
                            d.rmdir()
                os.close(stamped)                                          # closing releases the lock
            return
    raise Locked(f"{directory} kept disappearing ({TRIES} tries); another launch is using it")


def _stamp(directory: Path, fd: int) -> int:
    """The holder's line (PID, host, since when) in a new lock file, locked by this process and renamed onto the
    one ``fd`` holds; returns the new one's descriptor (``fd`` is closed)."""
    stamped = None
    try:
        with atomic_open(directory / NAME, "w") as f:
            f.write(f"PID {os.getpid()} on {socket.gethostname()} since {time.strftime('%Y-%m-%d %H:%M:%S')}\n")
            f.flush()
            stamped = os.dup(f.fileno())                                    # kept open: it holds the lock
            fcntl.flock(stamped, fcntl.LOCK_EX | fcntl.LOCK_NB)             # a new file: nobody else has it
    except BaseException:
        if stamped is not None:
            os.close(stamped)
        raise
    finally:
        os.close(fd)
    return stamped


def _acquire(dfd: int, directory: Path) -> int:
    """A descriptor of ``directory``'s lock file, flocked by this process; :class:`Locked` if another holds it."""
    path = directory / NAME
    for _ in range(TRIES):
        try:                       # O_CREAT without O_TRUNC: an existing file is not changed
            fd = os.open(NAME, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o666,
                         dir_fd=dfd)
        except OSError as e:
            if e.errno != errno.ELOOP:
                raise OSError(e.errno, e.strerror, str(path)) from None
            raise Unsafe(f"{path} is a symbolic link: refused (remove it; a lock is this dir's own file)") from None
        st = os.fstat(fd)
        problem = ("is not a regular file" if not stat.S_ISREG(st.st_mode) else
                   f"has {st.st_nlink} hard links (a file elsewhere shares it)" if st.st_nlink > 1 else None)
        if problem:
            os.close(fd)
            raise Unsafe(f"{path} {problem}: refused (remove it; a lock is this dir's own file)")
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "another process"
            os.close(fd)
            raise Locked(f"{directory} is in use by {holder}; wait for it to finish or choose another "
                         "output dir") from None
        try:
            now = os.stat(NAME, dir_fd=dfd, follow_symlinks=False)
        except FileNotFoundError:
            now = None
        if now is not None and (now.st_ino, now.st_dev) == (st.st_ino, st.st_dev):
            return fd
        os.close(fd)                                     # replaced by its holder's new file meanwhile: again
    raise Locked(f"{directory}'s lock file kept changing ({TRIES} tries); another launch is using it")
