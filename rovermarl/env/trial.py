"""The build-time trial of a world plug-in (issue 53): its state's declared widths checked, its ``sense`` run once
against its declared observation, and every hook tried on two episodes with guard cells around its state, so that a
mistake ends in one line naming the author's file (:func:`rovermarl.errors.plugin_errors`) when the World is built
(``World.__post_init__``), never in wrong numbers later. Each function reads the World it checks."""

from __future__ import annotations

import dataclasses
import inspect
import os
import sys
from typing import NamedTuple

import numpy as np

from rovermarl import errors
from rovermarl.env.params import Params

PER = ("rover", "episode")


class State(NamedTuple):
    """One array of a world's per-episode state (``World.state``): ``per`` "rover" gives it shape (N*E, width) (row
    ``q = i*E + e``), "episode" (E, width); ``width`` an integer or the name of a World attribute (``"n_pois"``);
    ``dtype`` "float" (the kernel's precision, ``env.dtype``), "float64", "float32", "int64" or "bool"."""

    name: str
    per: str
    width: int | str = 1
    dtype: str = "float"


_HOW = "declare them as fields of its Params, a @dataclass(frozen=True) subclass of World.Params (docs/WORLDS.md)"


def check_params(cls: type) -> None:
    """A World subclass's parameters are the fields of its ``Params`` dataclass: an annotation on the World, or a
    ``Params`` that is no dataclass subclass of :class:`Params`, is one line (TypeError, when the class is made)."""
    own = [k for k, v in vars(cls).get("__annotations__", {}).items() if "ClassVar" not in str(v)]
    if own:
        raise TypeError(f"{cls.__name__} declares parameters on the World ({', '.join(own)}): {_HOW}")
    ps = cls.Params
    if not (isinstance(ps, type) and issubclass(ps, Params)) or (
            "__dataclass_fields__" not in vars(ps) and vars(ps).get("__annotations__")):
        raise TypeError(f"{cls.__name__}.Params must be a subclass of World.Params decorated with "
                        f"@dataclass(frozen=True) (docs/WORLDS.md)")


def no_dataclass(cls: type) -> type:
    """``cls``, refused in one line if made a dataclass: the decorator replaces World's ``__init__``."""
    if dataclasses.is_dataclass(cls):
        raise errors.ConfigError(cls.__name__, "@dataclass", f"a World is no dataclass: {_HOW}")
    return cls


def state_dims(world) -> np.ndarray:
    """(S,) int64: the width of each array of ``World.state``, checked (one line naming the entry)."""
    dims = []
    for k, entry in enumerate(world.state):
        where = f"{type(world).__name__}.state[{k}] ({getattr(entry, 'name', entry)!r})"
        if not isinstance(entry, State):
            raise errors.ConfigError(where, entry, "must be a rovermarl.worlds.State(name, per, width, dtype)")
        errors.choice(f"{where}.per", entry.per, PER)
        errors.choice(f"{where}.dtype", entry.dtype, ("float", "float64", "float32", "int64", "bool"))
        width = getattr(world, entry.width) if isinstance(entry.width, str) else entry.width
        dims.append(errors.integer(f"{where}.width", width, 0))
    return np.array(dims, dtype=np.int64)


def plugin_homes(world) -> list[str]:
    """The directories of the world's own code outside rovermarl (its class's module and its hooks'), where
    :func:`errors.plugin_line` looks for the place of an error."""
    modules = {type(world).__module__, *(getattr(h, "py_func", h).__module__ for h in world.hooks)}
    files = [getattr(sys.modules.get(m), "__file__", None) for m in modules if not m.startswith("rovermarl.")]
    return sorted({os.path.dirname(os.path.realpath(f)) for f in files if f})


def check_sense(world) -> None:
    """Run the hook ``sense`` once (seed 0's first start) and check that it fills exactly the rows that
    ``World.obs_blocks`` declares; else one line saying both."""
    p = world.prepare(world.initial_conditions(seed=0, n=1))
    extra = 8
    filled = world.compiled.sensed_rows(p.xy, p.heading, p.kernel, world.compiled.state_of(p.xy, p.kernel), extra)
    d = world.obs_dim
    if not filled[:d].all() or filled[d:].any():
        wrote = int(np.flatnonzero(filled).max(initial=-1)) + 1
        blocks = ", ".join(f"{name} {low.size}" for name, low, _ in world.obs_blocks())
        sense, blocks_at = world.hooks.sense.py_func.__code__.co_filename, inspect.getsourcefile(world.obs_blocks)
        raise errors.PluginError(f"{type(world).__name__}'s hook sense ({sense}) fills {wrote} observation rows, but "
                                 f"its obs_blocks ({blocks_at}) declares {d} ({blocks}): sense must fill each of them "
                                 "and no more" + ("" if filled[d:].any() or not filled[:d].any() else
                                 f"; rows left unfilled: {np.flatnonzero(~filled[:d]).tolist()[:8]}"))


def check_state(world) -> None:
    """A trial run of every hook on seed 0's first two starts (random actions, ``steps`` steps, in the order of
    the rollout) with guard cells beside and below every array of ``World.state``, checked after each hook: a hook
    that writes outside its declared width ends in one line naming the state and the hook (and one that raises
    or does not compile fails here, when the world is built). 0.6-3 ms per build once compiled; its compile
    about a quarter of the rollout's (``docs/WORLDS.md``)."""
    p = world.prepare(world.initial_conditions(seed=0, n=2))
    n_ep, n = p.heading.shape
    f = p.xy.dtype
    x, y, heading = (np.ascontiguousarray(a.T.ravel()) for a in (p.xy[:, :, 0], p.xy[:, :, 1], p.heading))
    sin_h, cos_h = np.sin(heading), np.cos(heading)
    a0, a1 = np.random.default_rng(0).uniform(-1.0, 1.0, (2, n * n_ep)).astype(f)
    guarded = []                                     # (entry, width, buffer (rows + R, width + G), its view)
    for entry, width in zip(world.state, world.kernel.state_dims, strict=True):
        rows = n * n_ep if entry.per == "rover" else n_ep
        dtype = f if entry.dtype == "float" else np.dtype(entry.dtype)
        buf = np.empty((2 * rows + 8, 2 * int(width) + 8), dtype=dtype)
        buf.view(np.uint8)[:] = 0xA5                 # a byte pattern no hook writes by chance
        buf[:rows, :width] = 0                       # the state itself: zeros, as fresh memory mostly is
        guarded.append((entry, int(width), buf, buf[:rows, :width]))
    s = tuple(view for _, _, _, view in guarded)
    obs, xy, returns = np.zeros(world.obs_dim * n * n_ep, dtype=f), np.empty((n_ep, n, 2)), np.empty(n_ep)
    acc = world.compiled.env_start(p.kernel, n_ep)

    def call(hook: int, name: str) -> bool:
        before = [buf.view(np.uint8).copy() for _, _, buf, _ in guarded]
        out = world.compiled.trial(hook, x, y, heading, sin_h, cos_h, a0, a1, n, p.kernel, s, obs, xy, acc,
                                  returns)
        for (entry, width, buf, view), old in zip(guarded, before, strict=True):
            changed = buf.view(np.uint8) != old
            changed[:view.shape[0], :width * buf.itemsize] = False           # inside the declared state
            if changed.any():
                r, c = np.argwhere(changed)[0]
                fn = getattr(world.hooks, name).py_func
                raise errors.PluginError(
                    f"{type(world).__name__}'s hook {name} ({fn.__code__.co_filename}) writes outside its "
                    f"state {entry.name!r} ({entry.per}, width {width}, so (rows, {width})): at row {r}, column "
                    f"{c // buf.itemsize}; write only columns 0..{width - 1} of rows 0..{view.shape[0] - 1}, "
                    f"or declare it wider")
        return out

    call(0, "begin")
    each_step = call(4, "stepwise")
    for _ in range(world.steps):
        call(1, "sense")
        call(2, "move")
        call(3, "tick")
        if each_step:
            call(5, "score_step")
    xy[:] = np.stack([x.reshape(n, n_ep).T, y.reshape(n, n_ep).T], axis=-1)
    call(6, "score_end")
