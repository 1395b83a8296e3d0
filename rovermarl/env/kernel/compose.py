"""The kernel of a world plug-in: :mod:`~rovermarl.env.kernel.fused` compiled around the plug-in's hooks.

numba caches a compiled call of another function only if that function is a global of the caller's module, so a
world whose hooks or state are not the rover world's gets a module of its own: ``fused.py`` as a template
(:func:`fill`), its ``# hooks`` import replaced by the plug-in's functions and a ``state_new`` written from
``World.state``, in a folder of its own beside numba's cache, stamped by the sources its hooks reach
(``docs/WORLDS.md``, "When you edit a world"). Every copy types the record as the one
:class:`~rovermarl.env.kernel.record.KernelWorld` (numba's cache index pickles it by name).
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import inspect
import os
import sys
import sysconfig
import types
from pathlib import Path

from rovermarl import errors
from rovermarl.env.kernel import fused
from rovermarl.env.kernel.hooks import ROVERS, Hooks
from rovermarl.jit import PACKAGE

HOOKS_IMPORT = ("from rovermarl.env.kernel.hooks import (  # hooks\n"
                + "".join(f"    {name},\n" for name in sorted((*Hooks._fields, "state_new"))) + ")\n")
STATE_DTYPES = {"float": "w.poi_xy.dtype", "float64": "np.float64", "float32": "np.float32", "int64": "np.int64",
                "bool": "np.bool_"}     # "float": the kernel's precision (env.dtype)


def kernel_module(hooks: Hooks, state: tuple = ()):
    """The module whose ``rollout``, ``observe``, ``step`` and ``returns_of`` run a world with ``hooks`` and
    ``World.state``: :mod:`~rovermarl.env.kernel.fused` itself for the rover world's, else a generated copy."""
    if hooks == ROVERS and not state:
        return fused
    paths = tuple(_import_path(name, fn) for name, fn in zip(Hooks._fields, hooks, strict=True))
    return _generated(paths, state_source(state))


def state_source(state: tuple) -> str:
    """The source of ``state_new(w, n, n_ep)`` for a declared state: one array per entry, (N*E, width) per rover or
    (E, width) per episode, its width ``w.state_dims[k]``."""
    arrays = []
    for k, entry in enumerate(state):
        rows = "n * n_ep" if entry.per == "rover" else "n_ep"
        arrays.append(f"np.empty(({rows}, w.state_dims[{k}]), dtype={STATE_DTYPES[entry.dtype]})")
    body = "(" + ", ".join(arrays) + ("," if len(arrays) == 1 else "") + ")"
    return f'\n\n@njit(inline="always", cache=True)\ndef state_new(w, n, n_ep):\n    return {body}\n'


def _import_path(name: str, fn) -> tuple[str, str, str]:
    """(hook name, module, attribute) of a hook: a numba function that its module holds under that attribute."""
    py = getattr(fn, "py_func", None)
    if py is None or not hasattr(fn, "targetoptions"):
        raise TypeError(f"world hook {name}={fn!r} must be a numba function (@njit from rovermarl.jit)")
    module, attr = py.__module__, py.__qualname__
    if "." in attr or getattr(sys.modules.get(module), attr, None) is not fn:
        raise TypeError(f"world hook {name}={module}.{attr} must be a top-level function of its module")
    got, want = (list(inspect.signature(f).parameters) for f in (py, getattr(ROVERS, name).py_func))
    if len(got) != len(want):      # else numba's binding error, from the rollout, names neither the hook nor its file
        raise errors.PluginError(f"world hook {name} ({py.__code__.co_filename}:{py.__code__.co_firstlineno}) takes "
                                 f"{len(got)} parameters ({', '.join(got)}); a {name} hook takes {len(want)}: "
                                 f"({', '.join(want)})")
    return name, module, attr


def hook_sources(modules) -> str:
    """A hash of the sources a world's hooks use: the plug-in modules in ``modules`` and those their globals reach
    (a module, or a function or class from one), transitively. A plug-in module is one outside rovermarl (stamped by
    :mod:`rovermarl.jit`) and outside Python's and the environment's libraries; files beside it that it does not
    reach (another world, a script) are no part of it."""
    h = hashlib.sha256()
    for path in sorted(_reached(modules)):
        h.update(str(path).encode() + b"\0" + hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


_LIBRARIES = tuple({os.path.realpath(sysconfig.get_paths()[k]) + os.sep for k in ("stdlib", "platstdlib", "purelib",
                                                                                  "platlib")})


def _own_file(name: str) -> Path | None:
    """The source file of module ``name`` if it is a plug-in's (see :func:`hook_sources`), else None."""
    if name is None or name == "rovermarl" or name.startswith("rovermarl."):
        return None
    path = getattr(sys.modules.get(name), "__file__", None)             # None: a notebook's, a built-in
    if not path or not path.endswith(".py") or os.path.realpath(path).startswith(_LIBRARIES):
        return None
    return Path(path).resolve()


def _reached(modules) -> set[Path]:
    """The files of the plug-in modules ``modules`` and of those their globals reach."""
    todo, seen, files = list(modules), set(), set()
    while todo:
        name = todo.pop()
        if name in seen or (path := _own_file(name)) is None:
            continue
        seen.add(name)
        files.add(path)
        for value in vars(sys.modules[name]).values():
            if isinstance(value, types.ModuleType):
                todo.append(value.__name__)
            else:
                todo.append(getattr(getattr(value, "py_func", value), "__module__", None))
    return files


def cache_root() -> Path:
    """Where generated modules go: ``NUMBA_CACHE_DIR``, else ``$XDG_CACHE_HOME/rovermarl`` (``~/.cache/rovermarl``)."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "rovermarl"


def fill(template: str, where: str, swaps: dict[str, str]) -> str:
    """``template`` (the source of ``where``) with each key of ``swaps`` replaced by its value; a key that does not
    occur exactly once is a RuntimeError (one line), never a template that silently did not match."""
    for old, new in swaps.items():
        if template.count(old) != 1:
            first = old.strip().splitlines()[0]
            raise RuntimeError(f"{where}: expected once, found {template.count(old)} times: {first!r} "
                               "(rovermarl.env.kernel.compose.fill: the template and its filler disagree)")
        template = template.replace(old, new)
    return template


@functools.cache
def _generated(paths: tuple[tuple[str, str, str], ...], state: str):
    imports = "".join(f"from {module} import {attr} as {name}\n" for name, module, attr in paths)
    modules = sorted({m for _, m, _ in paths})
    stamp = hashlib.sha256((imports + state + hook_sources(modules)).encode()).hexdigest()[:16]
    body = fill(Path(fused.__file__).read_text(), fused.__file__, {HOOKS_IMPORT: imports})
    text = f"# generated by rovermarl.env.kernel.compose from {fused.__file__}; stamp {stamp}\n" + body + state
    where = "".join(str(_own_file(m)) for m in modules)   # two copies: two kernels
    name = hashlib.sha256((imports + state + where).encode()).hexdigest()[:12]
    return load_generated(f"rovermarl_world_{name}", text)


def load_generated(name: str, text: str):
    """The module ``name`` of source ``text``, written (if changed) into a folder of its own under :func:`cache_root`
    (numba's stamp of a generated module hashes its folder) and imported from there; ``algorithms.compiled`` too."""
    path = cache_root() / "rovermarl_worlds" / name / f"{name}.py"
    if path.resolve().is_relative_to(PACKAGE):
        raise RuntimeError(f"NUMBA_CACHE_DIR={os.environ.get('NUMBA_CACHE_DIR')} is inside rovermarl's package")
    if not path.exists() or path.read_text() != text:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{os.getpid()}")
        tmp.write_text(text)
        os.replace(tmp, path)          # atomic: a concurrent process (a Ray worker) reads this or the old one
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module
