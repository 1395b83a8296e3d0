"""Writes that cannot leave their directory: the one home of atomic writes and of the fault-injection hook.

- :func:`beneath`: the dir a command writes to (the one :mod:`~rovermarl.record.lock` holds) is opened once, as the
  user named it; in the block every write under it walks down from that descriptor one part at a time with
  ``O_NOFOLLOW | O_DIRECTORY`` (``openat``; Python has no ``openat2`` ``RESOLVE_BENEATH``). A part that is, or
  becomes, a link or not a dir fails the write in one line (:class:`~rovermarl.record.safe_read.Unsafe`), so a dir
  swapped for a link never takes a file elsewhere. A nested ``beneath`` is opened by that walk too.
- :func:`atomic_open`: a new temp file in the (opened) dir, fsynced, then renamed onto its name (never truncated or
  appended in place); a killed process's temp file is removed by the dir's next lock holder (:func:`remove_stale`).
- :func:`check_output_dir`, :func:`refuse_shared`: the files Hydra writes in place must not be links or hard links.

A write under no ``beneath`` block has its file's own dir as root (only the last part is protected); one outside the
active root is refused. The root is per thread and task (a ``contextvars`` value). See docs/FAULTS.md.
"""

from __future__ import annotations

import contextlib
import contextvars
import errno
import os
import re
import secrets
import signal
import stat
from dataclasses import dataclass
from pathlib import Path

from rovermarl.record.safe_read import Unsafe, check_tree

_DIR = os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC


@dataclass(frozen=True)
class _Root:
    path: str                                     # absolute, as given (lexical: links in it are the user's)
    fd: int


_ROOT: contextvars.ContextVar[_Root | None] = contextvars.ContextVar("rovermarl_write_root", default=None)


@contextlib.contextmanager
def beneath(directory: Path, create: bool = True):
    """Every write of the block under ``directory`` goes through the descriptor of ``directory`` opened now (created
    if missing and ``create``); yields that descriptor."""
    fd = open_dir(directory, create=create, own_root=True)
    token = _ROOT.set(_Root(os.path.abspath(directory), fd))
    try:
        yield fd
    finally:
        _ROOT.reset(token)
        os.close(fd)


def open_dir(path: Path, create: bool = False, own_root: bool = False) -> int:
    """A descriptor (the caller closes it) of the dir ``path``, walked from the active root without following a link
    (:class:`Unsafe` for a link or a non-dir part; ``create``: missing parts are made). Outside any root (or outside
    the active one, with ``own_root``: a new root), ``path`` is opened as named."""
    root = _ROOT.get()
    rel = os.path.relpath(os.path.abspath(path), root.path) if root is not None else "."
    if rel == ".." or rel.startswith(".." + os.sep):
        if not own_root:
            raise Unsafe(f"{path} lies outside {root.path}, the dir being written: refused")
        root = None
    if root is None:
        if create:
            Path(path).mkdir(parents=True, exist_ok=True)
        return os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
    fd, where = os.dup(root.fd), Path(root.path)
    for part in rel.split(os.sep) if rel != "." else ():
        where = where / part
        try:
            try:
                child = os.open(part, _DIR, dir_fd=fd)
            except FileNotFoundError:
                if not create:
                    raise
                with contextlib.suppress(FileExistsError):
                    os.mkdir(part, 0o777, dir_fd=fd)
                child = os.open(part, _DIR, dir_fd=fd)
        except OSError as e:
            if e.errno in (errno.ELOOP, errno.ENOTDIR):
                raise _odd(fd, part, where, root.path) from None
            raise OSError(e.errno, e.strerror, str(where)) from None
        finally:
            os.close(fd)
        fd = child
    return fd


def _odd(dir_fd: int, name: str, where: Path, root: str) -> Unsafe:
    """The one-line refusal of ``name`` in ``dir_fd``: a link or not a directory (either, if it changed since)."""
    try:
        mode = os.stat(name, dir_fd=dir_fd, follow_symlinks=False).st_mode
    except OSError:
        mode = stat.S_IFDIR
    what = ("a symbolic link" if stat.S_ISLNK(mode) else "a symbolic link or not a directory (it changed as it "
            "was opened)" if stat.S_ISDIR(mode) else "not a directory")
    return Unsafe(f"{where} is {what}: nothing is written through it (writes stay in {root}); remove it")


@contextlib.contextmanager
def atomic_open(path: Path, mode: str = "wb", aside: Path | None = None):
    """A temp file next to ``path`` (in its dir, opened by :func:`open_dir`), renamed onto ``path`` only if the block
    succeeds (the old ``path`` first renamed to ``aside``, in the same dir, when given and present). The old file is
    never written: a link or hard link there is replaced, not followed. An OSError of a write names ``path``."""
    path = Path(path)
    dfd = open_dir(path.parent, create=True)
    tmp = f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"                   # (TMP matches it)
    try:
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o666, dir_fd=dfd)
        except OSError as e:                                            # (the umask applies, as to any file)
            raise OSError(e.errno, e.strerror, str(path)) from None
        try:
            with os.fdopen(fd, mode) as f:
                yield f
                f.flush()
                fault(path)
                os.fsync(f.fileno())
            if aside is not None:
                with contextlib.suppress(FileNotFoundError):
                    os.replace(path.name, Path(aside).name, src_dir_fd=dfd, dst_dir_fd=dfd)
            os.replace(tmp, path.name, src_dir_fd=dfd, dst_dir_fd=dfd)
        except OSError as e:                                            # a failed write: name its file
            if e.filename in (None, tmp, path.name) and not isinstance(e, Unsafe):
                raise OSError(e.errno, e.strerror, str(path)) from None
            raise
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp, dir_fd=dfd)
    finally:
        os.close(dfd)


TMP = re.compile(r"\..+\.(\d+)\.[0-9a-f]{8}\.tmp")   # atomic_open's temp file: .<name>.<pid>.<8 hex>.tmp


def remove_stale(dfd: int) -> int:
    """Remove the temp files of :func:`atomic_open` under the dir ``dfd`` (links not followed) whose process is gone;
    returns how many. Only the dir's lock holder calls it, so no other launch writes there."""
    removed = 0
    for _, _, files, fd in os.fwalk(".", dir_fd=dfd):
        for name in files:
            m = TMP.fullmatch(name)
            if m and not _running(int(m.group(1))):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(name, dir_fd=fd)
                    removed += 1
    return removed


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:                                              # another user's process
        return True
    return True


def replace(src: Path, dst: Path) -> None:
    """Rename ``src`` onto ``dst``, both in one dir, by that dir's descriptor (neither name is followed)."""
    src, dst = Path(src), Path(dst)
    if src.parent != dst.parent:
        raise ValueError(f"{src} and {dst} are not in one dir")
    dfd = open_dir(src.parent)
    try:
        os.replace(src.name, dst.name, src_dir_fd=dfd, dst_dir_fd=dfd)
    finally:
        os.close(dfd)


def remove(path: Path) -> None:
    """Remove the file ``path`` (a link there is removed, never followed); nothing if it or its dir is missing."""
    path = Path(path)
    try:
        dfd = open_dir(path.parent)
    except FileNotFoundError:
        return
    try:
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path.name, dir_fd=dfd)
    finally:
        os.close(dfd)


def refuse_shared(path: Path) -> None:
    """:class:`Unsafe` if ``path`` is a symbolic link, or a file with other hard links (a file elsewhere, which an
    in-place write would change); nothing if it is missing."""
    try:
        st = os.lstat(path)
    except FileNotFoundError:
        return
    if stat.S_ISLNK(st.st_mode):
        raise Unsafe(f"{path} is a symbolic link: refused (it would be written in place; remove the link)")
    if stat.S_ISREG(st.st_mode) and st.st_nlink > 1:
        raise Unsafe(f"{path} has {st.st_nlink} hard links: refused (it would be written in place, and so would the "
                     "file it shares; replace it with a copy)")


IN_PLACE = ("multirun.yaml", "train.log")          # Hydra writes these, and .hydra/*.yaml, in place (open "w" / "a")


def check_output_dir(root: Path) -> None:
    """Before a launch into ``root``: no link, FIFO or device under it (:func:`~rovermarl.record.safe_read.check_tree`),
    and none of the files Hydra writes in place (``IN_PLACE``, ``.hydra/*.yaml``) shared with a file elsewhere
    (:func:`refuse_shared`)."""
    check_tree(root, "output dir")
    for dirpath, _, filenames in os.walk(root):
        for name in filenames:
            if name in IN_PLACE or (os.path.basename(dirpath) == ".hydra" and name.endswith(".yaml")):
                refuse_shared(Path(dirpath) / name)


# ---- fault injection ---------------------------------------------------------------------------------------------
FAULT = "ROVERMARL_FAULT"       # the fault-injection suite's hook (tests/test_faults.py): "<file name>:<action>"
_NO_FAULTS = contextvars.ContextVar("rovermarl_no_faults", default=False)


@contextlib.contextmanager
def faults_off():
    """No injected fault in this thread (the compile warm-up's job), whatever ``ROVERMARL_FAULT`` says; the environment
    is left alone, so processes started meanwhile (Ray's) still get it."""
    token = _NO_FAULTS.set(True)
    try:
        yield
    finally:
        _NO_FAULTS.reset(token)


def fault(path: Path) -> None:
    """The fault-injection hook, at each write of a run: with ``ROVERMARL_FAULT=<file name>:<action>`` set, writing
    that file (its temp copy is complete, not yet renamed) ends the process (``kill``: SIGKILL) or fails as the
    disk would (``enospc``, ``eio``: OSError). Unset (always, outside the tests), it does nothing."""
    spec = os.environ.get(FAULT)
    if not spec or _NO_FAULTS.get():
        return
    name, _, action = spec.rpartition(":")
    if name != Path(path).name:
        return
    if action == "kill":
        os.kill(os.getpid(), signal.SIGKILL)
    code = {"enospc": errno.ENOSPC, "eio": errno.EIO}[action]
    raise OSError(code, os.strerror(code), str(path))
