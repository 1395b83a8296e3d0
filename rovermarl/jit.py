"""numba's ``njit``, with a compile cache that cannot go stale.

numba's own cache (``cache=True``) stamps a compiled function with its own file only: after an edit of a callee in
another file (``math.py``'s ``tanh`` under ``sense_flat``, say) it loads the old machine code. Every module
of rovermarl that compiles imports ``njit`` from here instead; this module puts :class:`SourcesLocator` in front of
numba's cache locators, so that a cached function's stamp is a hash of every numba-using source it may reach: all of
rovermarl's, and for a plug-in outside the package (a world, an operator) those of its own directory too. A debug
build (``NUMBA_DEBUGINFO``, ``NUMBA_ENABLE_PROFILING``: not vectorised) is stamped apart, so plain runs never load it.
The cache stays where numba puts it (the package's ``__pycache__`` dirs, or ``NUMBA_CACHE_DIR``).

A listener of numba's ``numba:compile`` events sees every compile (a cache miss): the first of a process in a world's
kernel or loop says so on stderr, naming the world and the function (:func:`name_compiled`), and
:func:`compile_seconds` adds up their time, so that a job's throughput leaves it out.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import time
from pathlib import Path

from numba import njit, typeof
from numba.core import caching, config, event

__all__ = ["compile_seconds", "compiled_name", "name_compiled", "njit", "say_if_cold", "sources_stamp"]
PACKAGE = Path(__file__).resolve().parent
_SAID = []                        # non-empty once this process has said that it compiles (or train said it)
_NAMES = {"rovermarl.env.kernel.fused": "the rover world's kernel",
          "rovermarl.algorithms.compiled": "CC-(1+1)-ES's compiled loop in the rover world"}


def say_if_cold(dispatcher, args: tuple, what: str) -> None:
    """Before a call of ``dispatcher(*args)``: if neither this process nor numba's cache has it for these argument
    types, say once per process on stderr that numba compiles ``what`` now. Costs one attribute read once compiled."""
    if _SAID or dispatcher.overloads:
        return
    try:
        sig = tuple(typeof(a) for a in args)
        cached = any(tuple(key[0]) == sig for key in dispatcher._cache._cache_file._load_index())
    except Exception:  # numba's internals moved: say nothing rather than fail the call
        return
    if not cached:
        _notice(what)


def _notice(what: str) -> None:
    said()
    print(f"rovermarl: numba compiles {what} for this machine now (about 20 s on an idle core, once; later processes "
          "load it from the cache; python -m rovermarl.warmup compiles ahead)", file=sys.stderr, flush=True)


def said() -> None:
    """Mark the compile as announced in this process (``rovermarl.train`` says it its own way)."""
    _SAID.append(True)


def name_compiled(module: str, name: str) -> None:
    """Name ``module``'s compiled code in the compile notice (a world's generated kernel: ``"Battery's kernel"``)."""
    _NAMES[module] = name


def compiled_name(module: str) -> str:
    """What the compile notice calls the compiled code of ``module``."""
    return _NAMES.get(module, module)


def compile_seconds() -> float:
    """Seconds this process has spent in numba compiles so far (cache loads not included)."""
    return _Compiles.seconds


class _Compiles(event.Listener):
    """numba's compile events: their time (the outermost of nested ones), and the notice at the first of rovermarl's
    code in a process."""

    seconds, depth, started = 0.0, 0, 0.0

    def on_start(self, ev):
        cls = type(self)
        cls.depth += 1
        if cls.depth == 1:
            cls.started = time.perf_counter()
            fn = getattr(ev.data.get("dispatcher"), "py_func", None)
            module = getattr(fn, "__module__", "") or ""
            if not _SAID and module in _NAMES:                   # a world's kernel or loop: the long compiles
                _notice(f"{compiled_name(module)} ({fn.__name__})")

    def on_end(self, ev):
        cls = type(self)
        cls.depth -= 1
        if cls.depth == 0:
            cls.seconds += time.perf_counter() - cls.started


event.register("numba:compile", _Compiles())


@functools.cache
def _file_hash(path: str, mtime_ns: int, size: int) -> bytes | None:
    """SHA-256 of a source that imports numba (or this module), or None for one that does not (keyed by mtime and size:
    re-read on edit)."""
    data = Path(path).read_bytes()
    compiles = any(key in data for key in (b"from numba", b"import numba", b"from rovermarl.jit import"))
    return hashlib.sha256(data).digest() if compiles else None


def _dir_stamp(directory: Path, recursive: bool) -> list[tuple[str, bytes]]:
    out = []
    for path in sorted(directory.rglob("*.py") if recursive else directory.glob("*.py")):
        st = path.stat()
        digest = _file_hash(str(path), st.st_mtime_ns, st.st_size)
        if digest is not None:
            out.append((str(path.relative_to(directory)), digest))
    return out


def sources_stamp(py_file: str) -> str:
    """The stamp of a function compiled from ``py_file``: a hash of every numba-using source of rovermarl and, for a
    file outside the package, of its own directory."""
    h = hashlib.sha256()
    parts = _dir_stamp(PACKAGE, recursive=True)
    here = Path(py_file).resolve().parent
    if not here.is_relative_to(PACKAGE):
        parts += _dir_stamp(here, recursive=False)
    for name, digest in parts:
        h.update(name.encode() + b"\0" + digest)
    return h.hexdigest()


class SourcesLocator(caching._CacheLocator):
    """numba's own locator for the function (where its cache lives), with :func:`sources_stamp` added to the stamp."""

    def __init__(self, inner, py_file: str):
        self._inner, self._py_file = inner, py_file

    def ensure_cache_path(self):
        self._inner.ensure_cache_path()

    def get_cache_path(self):
        return self._inner.get_cache_path()

    def get_source_stamp(self):
        debug = (bool(config.DEBUGINFO_DEFAULT), bool(config.ENABLE_PROFILING))   # a debug build is cached apart
        return self._inner.get_source_stamp(), sources_stamp(self._py_file), debug

    def get_disambiguator(self):
        return self._inner.get_disambiguator()

    @classmethod
    def from_function(cls, py_func, py_file):
        for other in _NUMBA_LOCATORS:
            inner = other.from_function(py_func, py_file)
            if inner is not None:
                return cls(inner, os.fspath(py_file))
        return None


_NUMBA_LOCATORS = [c for c in caching.CacheImpl._locator_classes if c is not SourcesLocator]
if SourcesLocator not in caching.CacheImpl._locator_classes:
    caching.CacheImpl._locator_classes.insert(0, SourcesLocator)
