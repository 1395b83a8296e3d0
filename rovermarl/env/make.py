"""A world with the packaged defaults, by setup name: :func:`make_world` (library use, tests, examples)."""

from __future__ import annotations

import re

from omegaconf import OmegaConf

from rovermarl import errors
from rovermarl.env.world import World, world_class
from rovermarl.policy import MLP
from rovermarl.resources import CONF_DIR


def make_world(setup: str = "solo", world: type[World] | str | None = None, **overrides) -> World:
    """A :class:`World` with the defaults of ``conf/`` (``setup/<setup>.yaml``, ``env/rovers.yaml``,
    ``policy/mlp.yaml``). Keyword overrides name World fields, e.g. ``make_world("duo", steps=20)`` or the world
    options of SPEC section 8, ``make_world("duo", reward="any_step", speed="clip", poi_type="sign")``; the policy's
    size is ``hidden=8`` (the key of the policy group) or ``policy=MLP(hidden=8)``.

    ``world``: a world plug-in, its class (a subclass of World) or dotted name, built on the setup's POIs with its
    own fields among the overrides: ``make_world("duo", world=Obstacles, obstacles=[[0, 6, 1]])``
    (``docs/WORLDS.md``). A key that is no field of it is refused in one line naming the key."""
    if world is not None and not isinstance(world, str) and not (isinstance(world, type) and issubclass(world, World)):
        raise errors.ConfigError("world", world, "must be a subclass of rovermarl.env.World or its dotted name")
    cls = world_class(world, trust=True) if isinstance(world, str) else world
    path = CONF_DIR / "setup" / f"{setup}.yaml"
    if not isinstance(setup, str) or not re.fullmatch(r"[A-Za-z0-9_\-]+", setup) or not path.is_file():
        options = sorted(p.stem for p in (CONF_DIR / "setup").glob("*.yaml"))
        raise errors.ConfigError("setup", setup, "unknown setup; allowed: " + ", ".join(options))
    setup_file = OmegaConf.load(path)
    env = OmegaConf.load(CONF_DIR / "env" / "rovers.yaml")
    if "setup" in setup_file:                                  # `# @package _global_`: it also sets env keys
        env = OmegaConf.merge(env, setup_file.get("env") or {})
        setup_file = setup_file.setup
    policy = OmegaConf.load(CONF_DIR / "policy" / "mlp.yaml")
    cfg = OmegaConf.create({"setup": setup_file, "env": env, "policy": policy})
    for key, val in overrides.items():
        if key == "policy":                                     # the policy's config whole: MLP(hidden=...)
            if not isinstance(val, MLP):
                raise errors.ConfigError("policy", val, "must be a rovermarl.policy.MLP (e.g. MLP(hidden=16))")
            key, val = "hidden", val.hidden
        section = "setup" if key in ("coupling", "value", "name") else "policy" if key == "hidden" else "env"
        cfg[section][key] = val
    return World.from_config(cfg, cls_=cls)
