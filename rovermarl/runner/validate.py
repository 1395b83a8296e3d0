"""Checks of a composed job config, run before any work (and before Ray starts)."""

from __future__ import annotations

import re
from functools import cache

import numpy as np
from omegaconf import DictConfig, OmegaConf, read_write
from omegaconf.errors import InterpolationKeyError

from rovermarl import errors
from rovermarl.resources import CONF_DIR, option_keys, packaged
from rovermarl.runner import budget
from rovermarl.runner.chunk import parts, to_plain


@cache
def top_level() -> frozenset[str]:
    """The allowed top-level keys: the package's config groups and the run-level keys of ``conf/config.yaml``."""
    groups = {p.name for p in CONF_DIR.iterdir() if p.is_dir() and p.name != "__pycache__"}
    run_keys = set(packaged("config.yaml")) - {"defaults", "hydra"}
    return frozenset(groups | run_keys)


def validate(cfg: DictConfig) -> None:
    """Raise :class:`~rovermarl.errors.ConfigError` naming the first bad key of a composed job config."""
    allowed = top_level()
    for key in cfg:
        if key not in allowed and key != "hydra":
            raise errors.ConfigError(key, OmegaConf.select(cfg, key), "unknown top-level key; allowed: " +
                                     ", ".join(sorted(allowed)))
    _keys("setup", cfg.get("setup"), option_keys("setup")[0], option_keys("setup")[0])  # World names a missing one
    _keys("env", cfg.get("env"), None)  # World names unknown env keys
    _keys(*_group("policy", cfg))
    _keys("ray", cfg.get("ray"), set(packaged("config.yaml")["ray"]), set(packaged("config.yaml")["ray"]))
    errors.integer("seeds", cfg.get("seeds"), 1)
    errors.integer("seed", cfg.get("seed"), 0)
    errors.integer("generations", cfg.get("generations"), 1)
    levels = cfg.get("levels")
    if not OmegaConf.is_list(levels):
        raise errors.ConfigError("levels", levels, "must be a list of score levels")
    for i, lv in enumerate(levels):
        errors.number(f"levels[{i}]", lv)
    if cfg.get("resume") != "strict":
        _flag("resume", cfg.get("resume"), "true, false or strict")
    _keys("checkpoint", cfg.get("checkpoint"), set(packaged("config.yaml")["checkpoint"]))
    errors.integer("checkpoint.every", cfg.checkpoint.get("every"), 1)
    rec = cfg.get("record")
    _keys(*_group("record", cfg))
    for key in ("rerun", "behaviour", "occupancy", "steps"):
        _flag(f"record.{key}", rec.get(key))
    errors.integer("record.every", rec.get("every"), 1)
    par = cfg.get("parallel")
    _keys(*_group("parallel", cfg))
    errors.choice("parallel.backend", par.get("backend"), ("ray", "serial"))
    errors.integer("parallel.chunk", par.get("chunk"), 1)
    errors.integer("parallel.retries", par.get("retries", 0), 0)
    episodes = cfg.env.get("episodes")                   # a shard of no episode would have nothing to score
    errors.integer("parallel.ic_shards", par.get("ic_shards", 1), 1,       # (env.episodes < 1: its own line later)
                   episodes if isinstance(episodes, int) and episodes >= 1 else None)
    if par.get("stall_timeout") is not None:
        errors.number("parallel.stall_timeout", par.stall_timeout, 0, lo_open=True)
    if par.get("workers") is not None:
        errors.integer("parallel.workers", par.workers, 1)
    address = cfg.ray.get("address")
    if address is not None and (not isinstance(address, str) or not address):
        raise errors.ConfigError("ray.address", address, "must be null, 'auto' or 'HOST:PORT'")
    if cfg.ray.get("num_cpus") is not None:
        errors.integer("ray.num_cpus", cfg.ray.num_cpus, 1)
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
    try:
        built.algorithm.check_run(built.evaluation["fresh_ic"], local=par.get("ic_shards", 1) == 1)
    except errors.ConfigError as e:
        raise e.under("algorithm") from None
    budget.check(plain, series_bytes(built.algorithm.series),
                 built.algorithm.evaluations_per_generation(built.evaluation["fresh_ic"]))


def apply_budget(cfg: DictConfig, algorithm, fresh_ic: bool) -> bool:
    """Set ``generations`` from ``budget.agent_steps`` when it is given (the one home of that rule): as many whole
    generations as fit, at :meth:`Algorithm.agent_steps_per_generation
    <rovermarl.algorithms.base.Algorithm.agent_steps_per_generation>` each (19,200,000 agent-steps = 20,000
    generations of CC-(1+1)-ES with 4 rovers, 1,818 of the CCEA's 11 team evaluations). Returns whether it did."""
    node = cfg.get("budget")
    if node is None:
        return False
    _keys("budget", node, {"agent_steps"})
    steps = node.get("agent_steps")
    if steps is None:
        return False
    steps = errors.integer("budget.agent_steps", steps, 1)
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


def _group(group: str, cfg) -> tuple:
    """``_keys`` arguments of a config group: its node, the keys of its options in conf/, those not in every one."""
    allowed, required = option_keys(group)
    return group, cfg.get(group), set(allowed), set(allowed - required)


def _flag(key: str, value, allowed: str = "true or false") -> None:
    if not isinstance(value, bool):
        raise errors.ConfigError(key, value, f"must be {allowed}")


def _keys(section: str, node, allowed: set[str] | None, optional: set[str] = frozenset()) -> None:
    """``node`` must be a mapping; with ``allowed``, of those keys only (all but ``optional`` required)."""
    if not isinstance(node, DictConfig):
        keys = " with keys " + ", ".join(sorted(allowed)) if allowed else ""
        raise errors.ConfigError(section, node, f"must be a mapping{keys}")
    if allowed is None:
        return
    for key in node:
        if key not in allowed and key != "_target_":
            raise errors.ConfigError(f"{section}.{key}", node.get(key), "unknown key; allowed: " +
                                     ", ".join(sorted(allowed)))
    for key in allowed - optional:
        if key not in node:
            raise errors.ConfigError(f"{section}.{key}", None, "missing")
