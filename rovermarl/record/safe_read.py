"""Reading a results directory that an adversary may have made: the one home of the safe reads.

- :func:`check_tree`: only directories and regular files under a results dir; a link (even to a place inside), FIFO,
  socket or device is refused before anything is read or written there (a link would let a relaunch write,
  truncate or delete files elsewhere; a FIFO hangs a read).
- :func:`read_bytes`, :func:`read_json`, :func:`read_yaml`, :func:`read_jsonl`: one regular file (``O_NOFOLLOW |
  O_NONBLOCK``, then ``fstat``), at most ``cap`` bytes, parsed and checked by :mod:`rovermarl.record.schemas`.
- :func:`load_npz`, :func:`load_npy`: each member's ``.npy`` header (no object dtype; a shape the caller's
  :class:`Spec`, from the run's config (:class:`RunSize`), allows) and zip sizes are checked before anything is
  inflated or allocated, so memory stays within what a legitimate file of that config takes (twice).
- :func:`safe_label`: a value from a file that becomes part of a path (a config hash, a label), or ``"unknown"``.

Each failure is :class:`Unsafe` (a path refused) or :class:`Corrupt` (a file that is not what it claims), both
``OSError`` subclasses with a one-line message naming the file.
"""

from __future__ import annotations

import errno
import io
import math
import os
import re
import stat
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rovermarl.record import schemas

TEXT_CAP = 64 << 20                           # bytes: the largest json/log a results dir has any reason to hold
YAML_CAP = 1 << 20                            # bytes: the largest yaml (a job's config is a few KB)
LINE_CAP = 1 << 20                            # bytes: one line of a JSON-lines log
HEADER_CAP = 1 << 16                          # bytes: an .npy header (numpy writes 128 or so)
ANY = "*"                                     # in a dict of specs: any other member name
FREE = 1 << 28                                # elements along an axis that no config bounds
MEMBERS = 256                                 # members of an npz whose specs allow any name
HASH = re.compile(r"[0-9a-f]{1,64}")           # a config hash (SHA-256, hex), as a path part
_LABEL = re.compile(r"[A-Za-z0-9_.,=+\-]{1,200}")


class Unsafe(OSError):
    """A path under a results dir that is refused (a link, not a regular file, outside the dir); one line."""


class Corrupt(OSError):
    """A file whose content is not what it claims to be (too large, malformed, extra or odd members); one line."""


# ---- paths -------------------------------------------------------------------------------------------------------
def check_tree(root: Path, what: str = "results dir") -> None:
    """Raise :class:`Unsafe` unless everything under ``root`` (itself may be reached through links) is a directory
    or a regular file; nothing is followed and nothing read."""
    root = Path(root)
    if not root.exists():
        return
    for dirpath, dirnames, filenames in os.walk(root):           # os.walk lists a link to a dir, never enters it
        for name in (*dirnames, *filenames):
            refuse_odd(Path(dirpath) / name, what)


def refuse_odd(path: Path, what: str = "results dir") -> None:
    """Raise :class:`Unsafe` if ``path`` exists and is a symbolic link or neither a directory nor a regular file."""
    try:
        mode = os.lstat(path).st_mode
    except FileNotFoundError:
        return
    if stat.S_ISLNK(mode):
        raise Unsafe(f"{path} is a symbolic link: this {what} is read and written only through its own files; "
                     "remove the link or copy the data in")
    if not (stat.S_ISDIR(mode) or stat.S_ISREG(mode)):
        raise Unsafe(f"{path} is not a regular file or directory (a FIFO, socket or device): refused in this {what}")


def safe_label(value, what: str, warn=None, pattern: re.Pattern = _LABEL) -> str:
    """``value`` if it is a string fit to be part of a file name (``pattern``: letters, digits, ``_.,=+-``, no
    ``..``), else ``"unknown"`` with one ``warn(message)``."""
    if isinstance(value, str) and pattern.fullmatch(value) and ".." not in value:
        return value
    if warn is not None:
        warn(f"{what} {str(value)[:40]!r} is not a valid name; using 'unknown'")
    return "unknown"


# ---- regular files -----------------------------------------------------------------------------------------------
def open_regular(path: Path):
    """A binary file object of the regular file ``path`` (a link or a FIFO is refused without blocking)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except OSError as e:
        if e.errno == errno.ELOOP:                                    # the last part is a link
            raise Unsafe(f"{path} is a symbolic link: refused") from None
        raise
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise Unsafe(f"{path} is not a regular file (a FIFO, socket, device or dir): refused")
    os.set_blocking(fd, True)
    return os.fdopen(fd, "rb")


def read_bytes(path: Path, cap: int = TEXT_CAP) -> bytes:
    """The content of the regular file ``path``: :class:`Corrupt` if it is over ``cap`` bytes."""
    with open_regular(path) as f:
        size = os.fstat(f.fileno()).st_size
        if size > cap:
            raise Corrupt(f"{path} has {size} bytes, more than the {cap} such a file may have")
        data = f.read(cap + 1)
    if len(data) > cap:
        raise Corrupt(f"{path} grew past {cap} bytes while read")
    return data


def read_text(path: Path, cap: int = TEXT_CAP) -> str:
    return read_bytes(path, cap).decode("utf-8", errors="replace")


def read_json(path: Path, cap: int = TEXT_CAP, kind: str | None = None):
    """The JSON of ``path``, checked by :func:`rovermarl.record.schemas.parse_json` (against the schema of ``kind``,
    a key of :data:`~rovermarl.record.schemas.KINDS`, if given): :class:`Corrupt` naming the file and the field."""
    return _parsed(schemas.parse_json, read_bytes(path, cap), path, kind)


def read_jsonl(path: Path, kind: str | None = None, cap: int = LINE_CAP, chunk: int = 1 << 20):
    """Each non-blank line of a JSON-lines log of any size (``invocations.jsonl``), read ``chunk`` bytes at a time,
    at most ``cap`` bytes a line, each checked as :func:`read_json` checks a file."""
    with open_regular(path) as f:
        rest, number = b"", 0
        while True:
            block = f.read(chunk)
            lines = (rest + block).split(b"\n")
            rest = lines.pop() if block else b""
            if len(rest) > cap:
                raise Corrupt(f"{path}: line {number + len(lines) + 1} is longer than {cap} bytes")
            for line in lines:
                number += 1
                if line.strip():
                    yield _parsed(schemas.parse_json, line, f"{path}: line {number}", kind)
            if not block:
                return


def read_yaml(path: Path, cap: int = YAML_CAP, kind: str | None = None):
    """The plain containers of the YAML of ``path`` (interpolations unresolved), checked as :func:`read_json`
    checks JSON (:func:`rovermarl.record.schemas.parse_yaml`: no alias, anchor or tag)."""
    return _parsed(schemas.parse_yaml, read_text(path, cap), path, kind)


def _parsed(parse, data, where, kind):
    try:
        return parse(data, where, kind)
    except schemas.Invalid as e:
        raise Corrupt(str(e)) from None


# ---- arrays ------------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Spec:
    """What one array may be: ``shape`` (an int per fixed axis, None for one up to ``most`` long), its dtype
    ``kinds`` (numpy kind letters) and at most ``most`` elements along a free axis."""

    shape: tuple[int | None, ...]
    kinds: str = "biuf"
    most: int = 1 << 20

    def allows(self, shape: tuple) -> bool:
        return len(shape) == len(self.shape) and all(
            isinstance(n, int) and 0 <= n and (n == want if want is not None else n <= self.most)
            for n, want in zip(shape, self.shape, strict=True))


def load_npz(path: Path, specs: dict, required=(), max_bytes: int | None = None,
             stored: bool = False) -> dict[str, np.ndarray]:
    """The arrays of ``path`` (an ``.npz``), each checked against ``specs[name]`` (a :class:`Spec` or a tuple of
    them; ``specs[ANY]`` for any other name) before it is read; :class:`Corrupt` for a member outside ``specs``, a
    ``required`` one missing, or one that disagrees with its spec or its zip header. ``max_bytes``: a cap on the
    arrays' total size; ``stored``: every member must be stored uncompressed (as rovermarl writes a run's files and
    checkpoints), so no member is larger than the file."""
    with open_regular(path) as f:
        return _members(path, f, specs, required, max_bytes, stored)


def load_npz_bytes(data: bytes, name: str, specs: dict, required=(), max_bytes=None, stored: bool = True) -> dict:
    """:func:`load_npz` of an ``.npz`` held in memory (a checkpoint's payload), ``name`` naming it."""
    return _members(name, io.BytesIO(data), specs, required, max_bytes, stored)


def _members(path, f, specs: dict, required, max_bytes, stored: bool) -> dict[str, np.ndarray]:
    try:
        zf = zipfile.ZipFile(f)
    except (zipfile.BadZipFile, OSError, ValueError) as e:
        raise Corrupt(f"{path} is not an npz file ({type(e).__name__})") from None
    out, total = {}, 0
    with zf:
        infos = zf.infolist()
        most = MEMBERS if ANY in specs else len(specs)
        if len(infos) > most:
            raise Corrupt(f"{path} holds {len(infos)} members, more than the {most} it may have")
        for info in infos:
            key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            spec = specs.get(key, specs.get(ANY))
            if spec is None or key in out or key == ANY:
                raise Corrupt(f"{path} holds a member {info.filename[:60]!r} that it may not have")
            if stored and info.compress_type != zipfile.ZIP_STORED:
                raise Corrupt(f"{path}: member {key!r} is compressed; rovermarl stores this file's members as they are")
            if info.compress_type == zipfile.ZIP_STORED and info.file_size != info.compress_size:
                raise Corrupt(f"{path}: member {key!r} claims {info.file_size} bytes stored in {info.compress_size}")
            try:
                with zf.open(info) as m:
                    shape, fortran, dtype, header = _header(m, f"{path}[{key}]")
                    nbytes = _check(f"{path}[{key}]", spec, shape, dtype)
                    if info.file_size != header + nbytes:
                        raise Corrupt(f"{path}: member {key!r} declares {info.file_size} bytes, its header "
                                      f"{header + nbytes}")
                    total += nbytes
                    if max_bytes is not None and total > max_bytes:
                        raise Corrupt(f"{path} holds more than the {max_bytes} bytes of arrays it may have")
                    out[key] = _array(m, shape, fortran, dtype, nbytes, f"{path}[{key}]")
            except (zipfile.BadZipFile, EOFError, ValueError, NotImplementedError, RuntimeError) as e:
                raise Corrupt(f"{path}: member {key!r} is unreadable ({type(e).__name__})") from None
    missing = [k for k in required if k not in out]
    if missing:
        raise Corrupt(f"{path} lacks {', '.join(missing)}")
    return out


def load_npy(path: Path, spec: Spec) -> np.ndarray:
    """The array of ``path`` (an ``.npy``), its header checked against ``spec`` and the file's size first."""
    with open_regular(path) as f:
        size = os.fstat(f.fileno()).st_size
        try:
            shape, fortran, dtype, header = _header(f, path)
        except ValueError as e:
            raise Corrupt(f"{path} is not an npy file ({type(e).__name__})") from None
        nbytes = _check(path, spec, shape, dtype)
        if size != header + nbytes:
            raise Corrupt(f"{path} has {size} bytes, its header says {header + nbytes}")
        return _array(f, shape, fortran, dtype, nbytes, path)


def _header(f, where) -> tuple[tuple, bool, np.dtype, int]:
    """(shape, fortran order, dtype, header length) of the ``.npy`` stream ``f`` at its start."""
    fmt = np.lib.format
    start = f.read(fmt.MAGIC_LEN)
    if len(start) != fmt.MAGIC_LEN or not start.startswith(fmt.MAGIC_PREFIX):
        raise Corrupt(f"{where} is not an npy array (bad magic)")
    version = (start[-2], start[-1])
    size_len = {(1, 0): 2, (2, 0): 4, (3, 0): 4}.get(version)
    if size_len is None:
        raise Corrupt(f"{where}: unknown npy version {version}")
    raw = f.read(size_len)
    n = int.from_bytes(raw, "little") if len(raw) == size_len else HEADER_CAP + 1
    if n > HEADER_CAP:
        raise Corrupt(f"{where}: npy header of {n} bytes")
    f2 = io.BytesIO(start + raw + f.read(n))
    f2.seek(fmt.MAGIC_LEN)
    reader = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
    shape, fortran, dtype = reader(f2, max_header_size=HEADER_CAP)
    return shape, bool(fortran), dtype, fmt.MAGIC_LEN + size_len + n


def _check(where, spec: Spec | tuple[Spec, ...], shape: tuple, dtype: np.dtype) -> int:
    """The bytes of an array of ``shape`` and ``dtype``, or :class:`Corrupt` unless one of ``spec`` allows it."""
    specs = spec if isinstance(spec, tuple) else (spec,)
    if dtype.hasobject or dtype.fields is not None or not any(dtype.kind in s.kinds for s in specs):
        raise Corrupt(f"{where} has dtype {dtype}, not one of kinds {specs[0].kinds!r}")
    if not any(s.allows(shape) and dtype.kind in s.kinds for s in specs):
        want = " or ".join(str(tuple("*" if w is None else w for w in s.shape)) for s in specs)
        raise Corrupt(f"{where} has shape {tuple(shape)}, not {want} (free axes at most {specs[0].most})")
    return math.prod(shape) * dtype.itemsize


def _array(f, shape, fortran: bool, dtype: np.dtype, nbytes: int, where) -> np.ndarray:
    data = f.read(nbytes)
    if len(data) != nbytes:
        raise Corrupt(f"{where} is truncated ({len(data)} of {nbytes} bytes)")
    return np.frombuffer(data, dtype=dtype).reshape(shape, order="F" if fortran else "C").copy()


# ---- what a run's files may hold ---------------------------------------------------------------------------------
def _count(value, top: int) -> int | None:
    """``value`` if it is an int in [0, top], else None (a free axis)."""
    return value if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= top else None


@dataclass(frozen=True)
class RunSize:
    """The sizes a run's config implies (None: unknown, a free axis): generations G, rovers N, parameters of a
    genome P, episodes E, steps T, POIs."""

    generations: int | None = None
    rovers: int | None = None
    params: int | None = None
    episodes: int | None = None
    steps: int | None = None
    pois: int | None = None

    @classmethod
    def of(cls, config: dict | None, world=None) -> RunSize:
        """From a job's plain config (and its built world, which knows P), each number checked."""
        config = config if isinstance(config, dict) else {}
        generations = _count(config.get("generations"), 10**10)
        if world is not None:
            return cls(generations, world.n_rovers, world.n_params, world.episodes, world.steps, world.n_pois)
        env = config.get("env") if isinstance(config.get("env"), dict) else {}
        coupling = (config.get("setup") if isinstance(config.get("setup"), dict) else {}).get("coupling")
        return cls(generations, _count(env.get("n_rovers"), 1 << 12), None, _count(env.get("episodes"), 1 << 20),
                   _count(env.get("steps"), 1 << 20), len(coupling) if isinstance(coupling, list) else None)

    def curve(self) -> dict:
        """curve.npz: score (G+1,) and the declared series (G,) or (G, K), K at most max(N, 64)."""
        g, wide = self.generations, max(self.rovers or 0, 64)
        return {"score": Spec((None if g is None else g + 1,), "f", FREE),
                ANY: (Spec((g,), most=FREE), Spec((g, None), most=wide) if g is not None else
                      Spec((None, None), most=FREE))}

    def genomes(self) -> Spec:
        return Spec((self.rovers, self.params), "f")

    def initial_conditions(self) -> dict:
        e, n = self.episodes, self.rovers
        return {"xy": Spec((e, n, 2), "f"), "heading": Spec((e, n), "f"), "layout": Spec((e, None), "f", 1 << 12)}

    def _logged(self) -> int:
        """At most this many logged generations in the observer's files."""
        return FREE if self.generations is None else self.generations + 2

    def behaviour(self) -> dict:
        c, t = self._logged(), None if self.steps is None else self.steps + 1
        return {"generation": Spec((None,), "iuf", c), "score": Spec((None,), "f", c),
                "xy": Spec((None, self.episodes, t, self.rovers, 2), "f", c)}

    def occupancy(self) -> dict:
        c = self._logged()
        return {"generation": Spec((None,), "iuf", c), "count": Spec((None, self.episodes, self.pois), "iu", c)}
