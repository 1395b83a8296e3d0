"""A world with the packaged defaults, by setup name: :func:`make_world` (library use, tests, examples)."""

from __future__ import annotations

import copy
import functools
import re

from rovermarl import errors
from rovermarl.env.trial import no_dataclass
from rovermarl.env.world import World, world_class
from rovermarl.policy import MLP
from rovermarl.resources import composer


def make_world(setup: str = "solo", world: type[World] | str | None = None, **overrides) -> World:
    """A :class:`World` with the defaults of ``conf/``, composed by Hydra as the CLI composes ``setup=<setup>`` (its
    ``setup``, ``env`` and ``policy`` sections). Keyword overrides name the world's parameters (fields of its
    ``Params``), e.g. ``make_world("duo", steps=20)`` or the world options of SPEC section 8, ``make_world("duo",
    reward="any_step", speed="clip", poi_type="sign")``; the policy's size is ``hidden=8`` (the key of the policy
    group) or ``policy=MLP(hidden=8)``.

    ``world``: a world plug-in, its class (a subclass of World) or dotted name, built on the setup's POIs with its
    own parameters among the overrides: ``make_world("duo", world=Obstacles, obstacles=[[0, 6, 1]])``
    (``docs/WORLDS.md``). A key that is no field of its ``Params`` is refused in one line naming the key."""
    if world is not None and not isinstance(world, str) and not (isinstance(world, type) and issubclass(world, World)):
        raise errors.ConfigError("world", world, "must be a subclass of rovermarl.env.World or its dotted name")
    cls = world_class(world, trust=True) if isinstance(world, str) else no_dataclass(world)
    if not isinstance(setup, str) or not re.fullmatch(r"[A-Za-z0-9_\-]+", setup):   # one option name, no sweep
        raise errors.ConfigError("setup", setup, "must name a setup (letters, digits, _ and -)")
    cfg = copy.deepcopy(_composed(setup))
    for key, val in overrides.items():
        if key == "policy":                                     # the policy's config whole: MLP(hidden=...)
            if not isinstance(val, MLP):
                raise errors.ConfigError("policy", val, "must be a rovermarl.policy.MLP (e.g. MLP(hidden=16))")
            key, val = "hidden", val.hidden
        section = "setup" if key in ("coupling", "value", "name") else "policy" if key == "hidden" else "env"
        cfg[section][key] = val
    return World.from_config(cfg, cls_=cls)


@functools.cache
def _composed(setup: str) -> dict:
    """The ``setup``, ``env`` and ``policy`` sections of the packaged config with ``setup=<setup>`` (plain)."""
    from hydra.errors import MissingConfigException
    from omegaconf import OmegaConf

    try:
        with composer(keep_hydra=True) as compose:
            cfg = compose("config", overrides=[f"setup='{setup}'"])
    except MissingConfigException as e:
        raise errors.ConfigError("setup", setup, "unknown setup; allowed: " + ", ".join(e.options or ())) from None
    return {s: OmegaConf.to_container(cfg[s], resolve=True) for s in ("setup", "env", "policy")}
