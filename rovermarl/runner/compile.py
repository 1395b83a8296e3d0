"""A job's first run compiles: whether it will (:func:`cold`), and compiling ahead by running the job briefly
(:func:`warm`), which ``rovermarl.train`` does once in the driver, saying so, and ``python -m rovermarl.warmup`` does on
request."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rovermarl.env import World
from rovermarl.jit import said
from rovermarl.record.atomic import faults_off
from rovermarl.runner.job import run_job


def cold(cfg: DictConfig) -> bool:
    """Whether the job's rollout is not in numba's cache yet for its world and precision (a first run compiles)."""
    world = World.from_config(cfg, trust=True)   # composed from the command line (or checked: check_targets)
    try:
        index = world.compiled.rollout._cache._cache_file._load_index()   # {} when missing or stale
    except Exception:  # numba's internals moved: assume the worst, the message only says a compile may come
        return True
    want = f"array({world.dtype}, 2d, C)"
    return not any(str(key[0][0]) == want for key in index)


def warm(cfg: DictConfig) -> float:
    """Run ``cfg`` for 2 generations, 1 seed, serially, into a temporary dir; returns the seconds it took."""
    tiny = OmegaConf.merge(cfg, {"generations": 2, "seeds": 1, "parallel": {"backend": "serial"},
                                 "checkpoint": {"every": 2}})
    t0 = time.perf_counter()
    with faults_off(), tempfile.TemporaryDirectory(prefix="rovermarl-warmup-") as d:   # a fault injected into the
        run_job(tiny, Path(d) / "job", name="warmup")                                      # job is not the warm-up's
    return time.perf_counter() - t0


def announce_and_warm(cfgs: list[DictConfig], log=print) -> float | None:
    """If a job's kernel is not cached: say so, compile it in this process (one job per world and precision) and
    return the seconds; None when everything was cached."""
    todo, seen = [], set()
    for cfg in cfgs:
        key = (str(cfg.env.get("_target_")), str(cfg.env.dtype), str(cfg.env.reward), str(cfg.algorithm._target_))
        if key not in seen and cold(cfg):
            seen.add(key)
            todo.append(cfg)
    if not todo:
        return None
    said()                                             # the world's own notice would repeat this one
    log("first run of this code here: numba compiles the kernel this job uses (about 30 s on an idle core, once; "
        "later runs load it from the cache; python -m rovermarl.warmup compiles ahead)")
    return sum(warm(cfg) for cfg in todo)
