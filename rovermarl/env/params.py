"""A world's configuration: its parameters, the one home of their defaults, their checks, and the config they come from.

:class:`Params` is the configuration object a :class:`~rovermarl.env.World` holds (``world.params``): the paper's
parameters as frozen dataclass fields, checked when built. Their defaults are read from ``conf/env/rovers.yaml`` (the
``env`` group's default option, shipped with the package): that file is their one home, so the command line,
:func:`~rovermarl.env.make_world` and ``World(coupling=..., value=...)`` agree. A world plug-in with parameters of its
own declares them in a nested ``Params`` dataclass subclassing ``World.Params``, and checks them in its ``check``
(``docs/WORLDS.md``). The policy's configuration is its own object, :class:`~rovermarl.policy.MLP`
(``policy.hidden``). :func:`keywords` reads a composed config into a world class's keywords (``World.from_config``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

from omegaconf import OmegaConf

from rovermarl import errors
from rovermarl.env.kernel.rules import POI_TYPES, REWARDS, SPEEDS
from rovermarl.policy import MLP
from rovermarl.resources import packaged

ENV = packaged("env/rovers.yaml")   # the defaults of every World parameter below
DTYPES = ("float64", "float32")     # env.dtype: float32 is close to float64, not bit-identical (README)


def yaml_defaults(cls: type) -> type:
    """Give each annotated field of ``cls`` that ``conf/env/rovers.yaml`` names that file's value as its default (before
    ``@dataclass`` reads the class): the yaml is the defaults' one home."""
    for name in vars(cls).get("__annotations__", {}):
        if name in ENV:
            setattr(cls, name, ENV[name])
    return cls


@dataclass(frozen=True, eq=False)
@yaml_defaults
class Params:
    """The paper's world's parameters (SPEC sections 1-3, 5 and 8; each documented in ``conf/env/rovers.yaml``), checked
    when built: a bad value raises :class:`~rovermarl.errors.ConfigError`, one line naming its config key. A plug-in's
    own fields follow these in its subclass and are checked by its :meth:`check`."""

    coupling: tuple[int, ...]
    value: tuple[float, ...]
    n_rovers: int
    steps: int
    episodes: int
    poi_distance: float
    obs_radius: float
    sensor_range: float
    v_max: float
    w_max_deg: float
    start_box: float
    reward: str
    speed: str
    poi_type: str
    dtype: str
    policy: MLP = field(default_factory=MLP)
    name: str = ""

    def __post_init__(self):
        n = errors.integer("env.n_rovers", self.n_rovers, 1)
        if not isinstance(self.coupling, (list, tuple)) or len(self.coupling) == 0:
            raise errors.ConfigError("setup.coupling", self.coupling, "must be a non-empty list of integers")
        for j, c in enumerate(self.coupling):
            errors.integer(f"setup.coupling[{j}]", c, 1, n, f"a POI cannot need more rovers than env.n_rovers={n}")
        if not isinstance(self.value, (list, tuple)) or len(self.value) != len(self.coupling):
            raise errors.ConfigError("setup.value", self.value,
                                     f"must be a list of {len(self.coupling)} numbers, one per POI")
        for j, v in enumerate(self.value):
            errors.number(f"setup.value[{j}]", v, 0)
        errors.integer("env.steps", self.steps, 1)
        errors.integer("env.episodes", self.episodes, 1)
        errors.number("env.poi_distance", self.poi_distance, 0)
        errors.number("env.obs_radius", self.obs_radius, 0, lo_open=True)
        errors.number("env.sensor_range", self.sensor_range, 0, lo_open=True)
        errors.number("env.v_max", self.v_max, 0)
        errors.number("env.w_max_deg", self.w_max_deg, 0, 180)
        errors.number("env.start_box", self.start_box, 0)
        if not isinstance(self.policy, MLP):
            raise errors.ConfigError("policy", self.policy, "must be a rovermarl.policy.MLP (e.g. MLP(hidden=16))")
        errors.choice("env.reward", self.reward, REWARDS)
        errors.choice("env.speed", self.speed, SPEEDS)
        errors.choice("env.poi_type", self.poi_type, POI_TYPES)
        errors.choice("env.dtype", self.dtype, DTYPES)
        object.__setattr__(self, "coupling", tuple(int(c) for c in self.coupling))   # fields, as given: normalised
        object.__setattr__(self, "value", tuple(float(v) for v in self.value))
        self.check()

    def check(self) -> None:
        """A plug-in's checks of its own fields (raise ``errors.ConfigError``: one line naming key, value and what is
        allowed; normalise a field with ``object.__setattr__``), after the paper's parameters' checks."""


def keywords(cfg, cls: type) -> dict:
    """The keywords of world class ``cls`` (of its ``cls.Params``) from a composed config's ``setup``, ``env`` (its
    ``_target_`` left out) and ``policy`` sections; a key of ``env`` that is no field of ``cls`` is refused in one line
    naming it. ``cfg`` may be a plain dict."""
    cfg = OmegaConf.create(cfg) if isinstance(cfg, dict) else cfg
    setup = OmegaConf.to_container(cfg.setup, resolve=True) if OmegaConf.is_config(cfg.setup) else cfg.setup
    env = dict(OmegaConf.to_container(cfg.env, resolve=True) if OmegaConf.is_config(cfg.env) else cfg.env)
    env.pop("_target_", None)
    known = {f.name for f in fields(cls.Params) if f.init} - {"coupling", "value", "policy", "name"}
    for key in env:
        if key not in known:
            raise errors.ConfigError(f"env.{key}", env[key], "unknown key; allowed: " + ", ".join(sorted(known)))
    for key in ("coupling", "value"):
        if key not in setup:
            raise errors.ConfigError(f"setup.{key}", None, "missing; every setup lists one entry per POI")
    return dict(coupling=tuple(setup["coupling"]), value=tuple(setup["value"]), policy=MLP(hidden=cfg.policy.hidden),
                name=str(setup.get("name", "")), **env)
