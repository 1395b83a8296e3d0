"""Configuration errors: one line that names the key, the value and what is allowed; a plug-in's error: one line that
names its file (:func:`plugin_line`)."""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import re


class ConfigError(ValueError):
    """A config value is invalid. ``str(err)`` is ``"key=value: requirement"``."""

    def __init__(self, key: str, value, requirement: str):
        self.key, self.value, self.requirement = key, value, requirement
        super().__init__(f"{key}={_show(value)}: {requirement}")

    def under(self, group: str) -> ConfigError:
        """The same error with its key prefixed by the config group, e.g. ``gamma`` -> ``k.gamma``."""
        return ConfigError(f"{group}.{self.key}", self.value, self.requirement)


class PluginError(ConfigError):
    """A plug-in's own code failed (raised, did not compile, wrote outside its state): ``str(err)`` is one line that
    names its file (:func:`plugin_line`). A :class:`ConfigError`, so every entry point reports it as one."""

    def __init__(self, line: str):
        ValueError.__init__(self, line)
        self.key, self.value, self.requirement = "plug-in", None, line

    def under(self, group: str) -> PluginError:
        return self


def verbose() -> bool:
    """Whether the full text of a plug-in's error is wanted (``HYDRA_FULL_ERROR=1``)."""
    return os.environ.get("HYDRA_FULL_ERROR") == "1"


@contextlib.contextmanager
def plugin_errors(homes):
    """Turn an exception that a plug-in's code in the directories ``homes`` caused into a :class:`PluginError`
    (one line, :func:`plugin_line`); under :func:`verbose` the original, with its full text."""
    try:
        yield
    except ConfigError:
        raise
    except Exception as e:
        line = None if verbose() else plugin_line(e, homes)
        if line is None:
            raise
        raise PluginError(line) from None


def build(section: str, cls, node):
    """``cls(**node)`` of a typed config section: ``cls`` is a dataclass whose fields are the section's keys (a field
    without a default is required) and whose ``__post_init__`` checks their values. A non-mapping, an unknown or
    missing key, or a bad value is one :class:`ConfigError` naming ``section.key``."""
    fields = [f for f in dataclasses.fields(cls) if f.init]
    required = {f.name for f in fields if f.default is f.default_factory is dataclasses.MISSING}
    keys(section, node, {f.name for f in fields}, required)
    try:
        return cls(**node)
    except ConfigError as e:
        raise e.under(section) from None


def keys(section: str, node, allowed=None, required=()) -> None:
    """``node`` must be a mapping; with ``allowed``, of those keys only (``_target_`` aside), ``required`` among
    them."""
    if not isinstance(node, dict):
        raise ConfigError(section, node, "must be a mapping" + (" with keys " + ", ".join(sorted(allowed))
                                                                 if allowed else ""))
    for key in node if allowed is not None else ():
        if key not in allowed and key != "_target_":
            raise ConfigError(f"{section}.{key}", node[key], "unknown key; allowed: " + ", ".join(sorted(allowed)))
    missing = sorted(set(required) - set(node))
    if missing:
        raise ConfigError(f"{section}.{missing[0]}", None, "missing")


def flag(key: str, value, allowed: str = "true or false") -> bool:
    """``value`` if it is a bool, else :class:`ConfigError`."""
    if not isinstance(value, bool):
        raise ConfigError(key, value, f"must be {allowed}")
    return value


def _show(value) -> str:
    if isinstance(value, str):
        return value if value and not any(ch.isspace() for ch in value) else repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_show(v) for v in value) + "]"
    return str(value)


def integer(key: str, value, lo: int | None = None, hi: int | None = None, why: str = "") -> int:
    """``value`` as an int in [lo, hi], else :class:`ConfigError` (``why``, if given, after the bounds)."""
    bad = isinstance(value, bool) or not isinstance(value, int)
    if bad or (lo is not None and value < lo) or (hi is not None and value > hi):
        raise ConfigError(key, value, f"must be an integer{_range(lo, hi)}" + (f": {why}" if why else ""))
    return int(value)


def number(key: str, value, lo: float | None = None, hi: float | None = None, *,
           lo_open: bool = False, hi_open: bool = False) -> float:
    """``value`` as a finite float in the given (optionally open) interval, else :class:`ConfigError`."""
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and value == value
    ok = ok and abs(value) != float("inf")
    ok = ok and (lo is None or (value > lo if lo_open else value >= lo))
    ok = ok and (hi is None or (value < hi if hi_open else value <= hi))
    if not ok:
        raise ConfigError(key, value, f"must be a finite number{_range(lo, hi, lo_open, hi_open, interval=True)}")
    return float(value)


def choice(key: str, value, options) -> str:
    """``value`` if it is one of ``options``, else :class:`ConfigError`."""
    if value not in options:
        raise ConfigError(key, value, "must be one of " + ", ".join(map(str, options)))
    return value


def _range(lo, hi, lo_open: bool = False, hi_open: bool = False, interval: bool = False) -> str:
    """The bounds of an error message: `` in lo..hi`` (``interval``: `` in [lo, hi)`` and the like), `` >= lo``
    (``>``), `` <= hi`` (``<``)."""
    if lo is not None and hi is not None:
        if interval:
            return f" in {'(' if lo_open else '['}{lo}, {hi}{')' if hi_open else ']'}"
        return f" in {lo}..{hi}"
    if lo is not None:
        return f" {'>' if lo_open else '>='} {lo}"
    if hi is not None:
        return f" {'<' if hi_open else '<='} {hi}"
    return ""


def plugin_line(exc: BaseException, homes) -> str | None:
    """One line for an exception a plug-in's code caused (code in one of the directories ``homes``, those of the
    plug-ins a config names: :func:`plugin_homes`), also for a Ray task's error (its cause and the worker's
    traceback text); None for an exception that did not pass through a plug-in's code:

    - raised (also in compiled code, whose frames numba reports): ``<Type>: <message> (in <file>:<line>, <function>)``;
    - a numba function that does not compile: ``<function> in <file>:<line> does not compile: <numba's first line>``.
    """
    import traceback

    cause = getattr(exc, "cause", None) or exc
    homes = [os.path.realpath(h) + os.sep for h in homes]
    if any(c.__name__ == "NumbaError" for c in type(cause).__mro__):
        return _numba_line(str(cause), homes)
    text = getattr(exc, "traceback_str", None) or (str(exc) if cause is not exc else None)   # Ray's: in its text
    if text:
        frames = [(f, int(n), fn) for f, n, fn in re.findall(r'File "([^"]+)", line (\d+), in (\S+)', text)]
    else:
        frames = [(f.filename, f.lineno, f.name) for f in traceback.extract_tb(cause.__traceback__)]
    mine = [f for f in frames if _home(f[0], homes)]
    if not mine:
        return None
    file, line, func = mine[-1]
    message = " ".join(str(cause).split()) or "(no message)"
    return f"{type(cause).__name__}: {message} (in {file}:{line}, {func})"


def _home(file: str, homes) -> bool:
    """Whether ``file`` is in one of the directories ``homes`` (a kernel generated around a plug-in is not)."""
    path = os.path.realpath(file)
    return any(path.startswith(h) for h in homes) and f"{os.sep}rovermarl_worlds{os.sep}" not in path


def _numba_line(text: str, homes) -> str | None:
    """:func:`plugin_line` of numba's compile error ``text``: the innermost place in a plug-in's file that it names,
    else the plug-in function it names (a name it cannot resolve: the line that uses it)."""
    import inspect
    import sys

    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    first = next((ln for ln in lines if not ln.startswith(("Failed in ", "During:"))), "(no message)")
    places = [(f, int(n)) for f, n in re.findall(r'File "([^"]+)", line (\d+)', text) if _home(f, homes)]
    funcs = {}                                                   # the plug-in's numba functions by name
    for module in list(sys.modules.values()):
        if _home(getattr(module, "__file__", None) or "/", homes):
            funcs.update((k, v.py_func) for k, v in vars(module).items() if hasattr(v, "py_func"))
    named = [n for n in re.findall(r"<function (\w+) at 0x", text) if n in funcs]
    if places:
        file, line = places[-1]
        here = [n for n in named if os.path.realpath(inspect.getsourcefile(funcs[n]) or "") == os.path.realpath(file)]
        func = (here or named or ["a function"])[-1]
        return f"{func} in {os.path.realpath(file)}:{line} does not compile: {first}"
    missing = re.search(r"name '(\w+)' is not defined", text)
    uses = {}                                                    # the plug-in's functions that use an undefined name
    for name, fn in funcs.items() if missing else ():
        source, start = inspect.getsourcelines(fn)
        uses[name] = next((start + i for i, ln in enumerate(source) if re.search(rf"\b{missing[1]}\b", ln)), None)
    named = named or [n for n, line in uses.items() if line is not None]    # an inlined hook: numba names none
    if not named:
        return None
    fn = funcs[named[-1]]
    line = uses.get(named[-1]) or fn.__code__.co_firstlineno
    return f"{named[-1]} in {inspect.getsourcefile(fn)}:{line} does not compile: {first}"


def config_plugin_line(exc: BaseException, cfgs) -> str | None:
    """:func:`plugin_line` of ``exc`` over the plug-ins that the configs ``cfgs`` name; None under :func:`verbose`."""
    return None if verbose() else plugin_line(exc, [home for cfg in cfgs for home in plugin_homes(cfg)])


def plugin_homes(cfg) -> list[str]:
    """The directories of the plug-in modules (outside rovermarl) that a config's ``_target_`` keys name and that
    this process has imported."""
    import sys

    from omegaconf import OmegaConf

    out, todo = [], [OmegaConf.to_container(cfg) if OmegaConf.is_config(cfg) else cfg]   # unresolved: no resolver
    while todo:
        node = todo.pop()
        items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, (list, tuple)) else ()
        for key, value in items:
            if key == "_target_" and isinstance(value, str) and not value.startswith("rovermarl."):
                module = sys.modules.get(value.rpartition(".")[0])
                if getattr(module, "__file__", None):
                    out.append(os.path.dirname(module.__file__))
            elif not isinstance(value, (str, int, float, bool, type(None))):
                todo.append(value)
    return out


def printable(value, most: int = 300) -> str:
    """``value`` as text fit for one terminal line: every control character (escape, newline, carriage return, ...)
    and every other unprintable one escaped as Python writes it (``\\x1b``, ``\\n``), cut to ``most`` characters.
    Every string read from a file passes through it before it is printed."""
    text = str(value)
    text = text if len(text) <= most else text[:most] + "..."
    return text if text.isprintable() else "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


class Printable(logging.Formatter):
    """A log formatter whose lines are :func:`printable`: a message quoting a file never writes a raw control
    character (no retitled terminal, no forged second line)."""

    def format(self, record: logging.LogRecord) -> str:
        return printable(super().format(record), 20_000)
