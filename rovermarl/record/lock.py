"""One writer per output directory: an exclusive ``flock`` on ``<dir>/.lock``, held for the life of a launch.

The lock file is opened with ``O_NOFOLLOW`` and must be a regular file (:class:`~rovermarl.record.safe_read.Unsafe`
otherwise): a link planted in a copied results dir is never written through. A second launch on the same sweep or
job dir stops at once with one line that names the holder (PID, host, since
when); the lock goes away with the holder's process, however it ends, so a killed launch never blocks the next.
Within one process the lock is re-entrant (a single-run launch and its job share one dir). A launch that stops
before writing anything leaves no directory behind: the dirs it created for the lock are removed with it.
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

from rovermarl.record.safe_read import Unsafe

NAME = ".lock"
_HELD: set[Path] = set()                                 # directories this process holds


class Locked(Exception):
    """Another process holds the directory's lock; ``str(err)`` is one line naming it."""


@contextlib.contextmanager
def hold(directory: Path):
    """Hold ``directory``'s lock (creating the directory) for the ``with`` block; :class:`Locked` if taken."""
    directory = Path(directory)
    key = directory.resolve()
    if key in _HELD:
        yield directory
        return
    created = [d for d in (key, *key.parents) if not d.exists()]           # deepest first
    directory.mkdir(parents=True, exist_ok=True)
    try:                           # never through a link (a copied results dir's .lock may point anywhere)
        fd = os.open(directory / NAME, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC, 0o666)
    except OSError as e:
        if e.errno != errno.ELOOP:
            raise
        raise Unsafe(f"{directory / NAME} is a symbolic link: refused (remove it; a lock is this dir's own file)") \
            from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise Unsafe(f"{directory / NAME} is not a regular file: refused (remove it)")
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 200, 0).decode(errors="replace").strip() or "another process"
            raise Locked(f"{directory} is in use by {holder}; wait for it to finish or choose another "
                         "output dir") from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"PID {os.getpid()} on {socket.gethostname()} since "
                      f"{time.strftime('%Y-%m-%d %H:%M:%S')}\n".encode(), 0)
        _HELD.add(key)
        try:
            yield directory
        finally:
            _HELD.discard(key)
    finally:
        os.close(fd)                                     # closing releases the lock
        if created and [p.name for p in directory.iterdir()] == [NAME]:   # nothing was written: leave nothing
            with contextlib.suppress(OSError):
                (directory / NAME).unlink()
                for d in created:
                    d.rmdir()
