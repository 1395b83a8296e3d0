"""Checks of a composed job config, run before any work (and before Ray starts). The run-level sections are typed
configs, the one home of their checks (docs/ARCHITECTURE.md, "Configs: one home per default and per check")."""

from __future__ import annotations

import re
from dataclasses import dataclass, fields
from functools import cache

import numpy as np
from omegaconf import DictConfig, ListConfig, OmegaConf, read_write
from omegaconf.errors import InterpolationKeyError

from rovermarl import errors
from rovermarl.parallel import backend
from rovermarl.resources import group_names, option_keys, packaged
from rovermarl.runner import budget
from rovermarl.runner.chunk import parts, to_plain


@cache
def top_level() -> frozenset[str]:
    """The allowed top-level keys: the package's config groups and the run-level keys of ``conf/config.yaml``."""
    return frozenset(group_names() | set(packaged("config.yaml")) - {"defaults", "hydra"})


@dataclass(frozen=True)
class Job:
    """The run-level keys of ``conf/config.yaml`` (their defaults and meanings are there)."""

    seeds: int
    seed: int
    generations: int
    levels: list
    resume: bool | str

    def __post_init__(self):
        errors.integer("seeds", self.seeds, 1)
        errors.integer("seed", self.seed, 0)
        errors.integer("generations", self.generations, 1)
        if not isinstance(self.levels, ListConfig | list):
            raise errors.ConfigError("levels", self.levels, "must be a list of score levels")
        for i, lv in enumerate(self.levels):
            errors.number(f"levels[{i}]", lv)
        if self.resume != "strict":
            errors.flag("resume", self.resume, "true, false or strict")


@dataclass(frozen=True)
class Checkpoint:
    every: int

    def __post_init__(self):
        errors.integer("every", self.every, 1)


@dataclass(frozen=True)
class Record:
    rerun: bool
    behaviour: bool
    occupancy: bool
    every: int
    steps: bool

    def __post_init__(self):
        for key in ("rerun", "behaviour", "occupancy", "steps"):
            errors.flag(key, getattr(self, key))
        errors.integer("every", self.every, 1)


@dataclass(frozen=True)
class Ray:
    address: str | None
    num_cpus: int | None

    def __post_init__(self):
        if self.address is not None and (not isinstance(self.address, str) or not self.address):
            raise errors.ConfigError("address", self.address, "must be null, 'auto' or 'HOST:PORT'")
        if self.num_cpus is not None:
            errors.integer("num_cpus", self.num_cpus, 1)


@dataclass(frozen=True)
class Budget:
    agent_steps: int | None

    def __post_init__(self):
        if self.agent_steps is not None:
            errors.integer("agent_steps", self.agent_steps, 1)


def validate(cfg: DictConfig) -> None:
    """Raise :class:`~rovermarl.errors.ConfigError` naming the first bad key of a composed job config."""
    allowed = top_level()
    for key in cfg:
        if key not in allowed and key != "hydra":
            raise errors.ConfigError(key, OmegaConf.select(cfg, key), "unknown top-level key; allowed: " +
                                     ", ".join(sorted(allowed)))
    errors.keys("setup", _plain(cfg.get("setup")), option_keys("setup")[0])   # World names a missing one
    errors.keys("env", _plain(cfg.get("env")))                                 # and unknown env keys
    errors.keys("policy", _plain(cfg.get("policy")), *option_keys("policy"))
    _section("ray", Ray, cfg)
    Job(**{f.name: cfg.get(f.name) for f in fields(Job)})
    _section("checkpoint", Checkpoint, cfg)
    _section("record", Record, cfg)
    par = backend(cfg.get("parallel"))
    episodes = cfg.env.get("episodes")                   # a shard of no episode would have nothing to score
    if isinstance(episodes, int) and episodes >= 1:      # (env.episodes < 1: its own line later)
        errors.integer("parallel.ic_shards", par.shards, 1, episodes)
    try:
        plain = to_plain(cfg)
    except InterpolationKeyError as e:                 # e.g. ~k: the algorithm's node refers to the group
        missing = re.search(r"Interpolation key '([^']+)' not found", str(e))
        key = missing.group(1) if missing else "config"
        what = ("must be a config with a _target_ (pick an option of the group)" if key in allowed
                else "missing; the config refers to it")
        raise errors.ConfigError(key, None, what) from None
    budget.precheck(plain)                             # a world too large to build is refused first
    built = parts(plain)                               # builds world and algorithm once; the job reuses them
    if apply_budget(cfg, built.algorithm, built.evaluation["fresh_ic"]):
        plain = to_plain(cfg)
        built = parts(plain)
    built.algorithm.check_series()
    built.algorithm.kernel_functions(built.world.compiled)
    try:
        built.algorithm.check_run(built.evaluation["fresh_ic"], local=par.shards == 1)
    except errors.ConfigError as e:                    # its own key (loop) under algorithm; a dotted one is another
        raise (e if "." in str(e.key) else e.under("algorithm")) from None     # section's (parallel.ic_shards)
    budget.check(plain, series_bytes(built.algorithm.series),
                 built.algorithm.evaluations_per_generation(built.evaluation["fresh_ic"]))


def apply_budget(cfg: DictConfig, algorithm, fresh_ic: bool) -> bool:
    """Set ``generations`` from ``budget.agent_steps`` when it is given (the one home of that rule): as many whole
    generations as fit, at :meth:`Algorithm.agent_steps_per_generation
    <rovermarl.algorithms.base.Algorithm.agent_steps_per_generation>` each (19,200,000 agent-steps = 20,000
    generations of CC-(1+1)-ES with 4 rovers, 1,818 of the CCEA's 11 team evaluations). Returns whether it did."""
    steps = None if cfg.get("budget") is None else _section("budget", Budget, cfg).agent_steps
    if steps is None:
        return False
    per = algorithm.agent_steps_per_generation(fresh_ic)
    if steps < per:
        raise errors.ConfigError("budget.agent_steps", steps, f"must be at least one generation ({per} agent-steps "
                                 f"for {type(algorithm).__name__} in this world)")
    with read_write(cfg):
        cfg.generations = steps // per
    return True


def series_bytes(series) -> int:
    """Bytes per generation of an algorithm's declared series."""
    return sum(np.dtype(s.dtype).itemsize * int(np.prod(s.shape)) for s in series)


def _section(key: str, cls, cfg):
    """The typed config of section ``key`` of ``cfg`` (:func:`rovermarl.errors.build`)."""
    return errors.build(key, cls, _plain(cfg.get(key)))


def _plain(node):
    return OmegaConf.to_container(node, resolve=True) if OmegaConf.is_config(node) else node
