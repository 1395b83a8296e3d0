"""Configs read back from a results directory run no code of their own (docs/GUIDE.md, docs/FAULTS.md).

Hydra's ``instantiate`` imports whatever a ``_target_`` names, attribute chains included
(``rovermarl.record.outputs.np.save`` is ``numpy.save``), so a read path that rebuilds a run from a job dir's config
first calls :func:`check_targets`. A ``_target_`` may only sit at the root of a config group's node (``k._target_``,
or ``algorithm.k._target_`` where an algorithm's option takes the group's node, ``k: ${k}``) and must be exactly one
of the classes that group's packaged options name (:func:`groups`). Anything else is refused, the config resolved
too (no interpolation may yield a ``_target_`` or another interpolation); configs from before the ``algorithm`` group
pass as :func:`rovermarl.runner.chunk.upgrade` rewrites them. The check only reads YAML: nothing is imported before
it. ``--trust-config`` skips it (e.g. your own plug-in on ``hydra.searchpath``).
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path

from omegaconf import OmegaConf

from rovermarl import errors
from rovermarl.resources import CONF_DIR

REFUSE = "a results directory may not run code; pass --trust-config if you trust it"
LEGACY = ("rovermarl.evolution.", "rovermarl.algorithms.operators.")  # as rovermarl.runner.chunk.upgrade renames
_GROUP_NODE = re.compile(r"\$\{(\w+)\}")                               # ``k: ${k}`` in an algorithm's option


@dataclass(frozen=True)
class Groups:
    """The allow-list: ``classes[group]``, the ``_target_`` the group's options name; ``slots[(group, target)]``,
    the keys of such a node that hold another group's node (``{"k": "k", "mutation": "mutation", ...}``)."""

    classes: dict[str, frozenset[str]]
    slots: dict[tuple[str, str], dict[str, str]]


@functools.cache
def groups(conf_dir: Path = CONF_DIR) -> Groups:
    """The allow-list of ``conf_dir``: every ``<group>/<option>.yaml`` whose root has a ``_target_``."""
    options, classes = [], {}
    for path in sorted(conf_dir.glob("*/*.yaml")):
        node = OmegaConf.to_container(OmegaConf.load(path), resolve=False)
        if isinstance(node, dict) and isinstance(node.get("_target_"), str):
            options.append((path.parent.name, node))
            classes.setdefault(path.parent.name, set()).add(node["_target_"])
    slots: dict[tuple[str, str], dict[str, str]] = {}
    for group, node in options:
        for key, value in node.items():
            m = _GROUP_NODE.fullmatch(value) if isinstance(value, str) else None
            if m and m[1] in classes:
                slots.setdefault((group, node["_target_"]), {})[str(key)] = m[1]
    return Groups({g: frozenset(c) for g, c in sorted(classes.items())}, slots)


def check_targets(config, source: str) -> None:
    """Raise :class:`~rovermarl.errors.ConfigError` (one line: the key, the value, ``source``) unless every
    ``_target_`` of ``config`` (a DictConfig or plain containers, read from ``source``) is a class of the config
    group at whose root it sits; the same holds for ``config`` resolved, which has no interpolation left."""
    try:
        cfg = config if OmegaConf.is_config(config) else OmegaConf.create(config)
    except Exception as e:  # an odd container: not a config
        raise errors.ConfigError("config", type(config).__name__, f"is not a config ({type(e).__name__}), in "
                                 f"{source}") from None
    raw = OmegaConf.to_container(cfg, resolve=False)
    if not isinstance(raw, dict):
        raise errors.ConfigError("config", type(raw).__name__, f"must be a mapping, in {source}")
    allow = groups()
    legacy = "algorithm" not in raw and "k" in raw
    _walk(raw, "", None, allow, legacy, source)
    strings = dict(_strings(raw, ""))
    if not any("${" in value for value in strings.values()):
        return
    try:
        resolved = OmegaConf.to_container(cfg, resolve=True)
    except Exception as e:  # any resolution failure, in one line
        key = str(getattr(e, "full_key", "") or "config")
        first = (str(e).splitlines() or [type(e).__name__])[0]
        raise errors.ConfigError(key, strings.get(key, "?"), f"cannot be resolved ({first}), in {source}") from None
    _walk(resolved, "", None, allow, legacy, source)
    for key, value in _strings(resolved, ""):
        if "${" in value:
            raise errors.ConfigError(key, value, f"resolves to another interpolation, in {source}: {REFUSE}")


def _walk(node, path: str, group: str | None, allow: Groups, legacy: bool, source: str) -> None:
    """Refuse a ``_target_`` of ``node`` (at ``path``) unless ``node`` is the root of a node of ``group``."""
    if isinstance(node, list):
        for i, value in enumerate(node):
            _walk(value, f"{path}[{i}]", None, allow, legacy, source)
        return
    if not isinstance(node, dict):
        return
    slots: dict[str, str] = {}
    if "_target_" in node:
        key, target = f"{path or 'config'}._target_", node["_target_"]
        if group is None:
            raise errors.ConfigError(key, target, "only the node of a config group (" + ", ".join(allow.classes)
                                     + f") may name a class, in {source}: {REFUSE}")
        if legacy and isinstance(target, str) and target.startswith(LEGACY[0]):   # as the runner builds it
            target = LEGACY[1] + target.removeprefix(LEGACY[0])
        if not isinstance(target, str):
            raise errors.ConfigError(key, target, f"must be a dotted class name (a string), in {source}: {REFUSE}")
        if target not in allow.classes[group]:
            where = ("is outside rovermarl" if not target.startswith("rovermarl.") else
                     f"is not a class of the config group {group} ({', '.join(sorted(allow.classes[group]))})")
            raise errors.ConfigError(key, node["_target_"], f"{where}, in {source}: {REFUSE}")
        slots = allow.slots.get((group, target), {})
    for key, value in node.items():
        if key == "_target_":
            continue
        inner = (str(key) if str(key) in allow.classes else None) if not path else slots.get(str(key))
        _walk(value, _join(path, key), inner, allow, legacy, source)


def _strings(node, path: str):
    """Every ``(key, string value)`` of a plain config tree."""
    if isinstance(node, dict):
        for key, value in node.items():
            yield from _strings(value, _join(path, key))
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _strings(value, f"{path}[{i}]")
    elif isinstance(node, str):
        yield path or "config", node


def _join(path: str, key) -> str:
    """``path.key``, the key quoted if it would not read as one word on one line."""
    key = str(key)
    key = key if key and key.isprintable() and not any(c.isspace() for c in key) else repr(key)
    return f"{path}.{key}" if path else key
