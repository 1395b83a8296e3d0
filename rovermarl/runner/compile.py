"""A job's first run compiles: whether it will (:func:`cold`, said by :func:`announce`), and compiling ahead by running
the job briefly (:func:`warm`: ``rovermarl.train`` once in the driver, ``python -m rovermarl.warmup`` on request)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from rovermarl import jit
from rovermarl.algorithms import compiled
from rovermarl.algorithms.cc11es import CC11ES
from rovermarl.jit import said
from rovermarl.parallel import backend
from rovermarl.record.atomic import faults_off
from rovermarl.runner.chunk import parts, to_plain
from rovermarl.runner.job import run_job


def cold(cfg: DictConfig) -> dict[str, list[str]]:
    """The job's compiled code not yet in numba's cache for its world and precision (a first run compiles it): the
    world's rollout and evaluation, the compiled CC-(1+1)-ES loop where the job runs it, and the kernel functions the
    algorithm names (``Algorithm.kernel_calls``), as {``jit.compiled_name`` of their module: [function, ...]}; empty
    when all is cached."""
    built = parts(to_plain(cfg))                 # the job's world and algorithm, as validate built them
    world, algorithm = built.world, built.algorithm
    kernel = world.compiled
    code = [kernel.rollout, kernel.evaluate, *algorithm.kernel_functions(kernel)]
    if isinstance(algorithm, CC11ES) and algorithm.loop != "python" and compiled.refusal(
            algorithm, built.evaluation["fresh_ic"], backend(cfg.parallel).shards == 1) is None:
        code.append(compiled.loop_of(kernel).run)
    want = f"array({world.dtype}"
    missing: dict[str, list[str]] = {}
    for fn in filter(None, code):
        try:
            index = fn._cache._cache_file._load_index()                  # {} when missing or stale
        except Exception:  # numba's internals moved: assume the worst, the message only says a compile may come
            index = {}
        if not any(want in str(t) for key in index for t in key[0]):   # str(t): "array(float64, 2d, C)"
            missing.setdefault(jit.compiled_name(fn.py_func.__module__), []).append(fn.py_func.__name__)
    return missing


def warm(cfg: DictConfig) -> float:
    """Run ``cfg`` for 2 generations, 1 seed, serially, into a temporary dir; returns the seconds it took."""
    tiny = OmegaConf.merge(cfg, {"generations": 2, "seeds": 1, "checkpoint": {"every": 2}})
    tiny.parallel = {"_target_": "rovermarl.parallel.Serial", "chunk": cfg.parallel.chunk}
    t0 = time.perf_counter()
    with faults_off(), tempfile.TemporaryDirectory(prefix="rovermarl-warmup-") as d:   # a fault injected into the
        run_job(tiny, Path(d) / "job", name="warmup")                                      # job is not the warm-up's
    return time.perf_counter() - t0


def announce(cfgs: list[DictConfig], log=print) -> list[DictConfig]:
    """If a job's kernel is not cached, say so; returns the jobs to compile ahead (:func:`warm`), one per world and
    precision, empty when everything is cached."""
    todo, seen, what = [], set(), []
    for cfg in cfgs:
        key = (str(cfg.env.get("_target_")), str(cfg.env.dtype), str(cfg.env.reward), str(cfg.algorithm._target_))
        if key not in seen and (missing := cold(cfg)):
            seen.add(key)
            todo.append(cfg)
            what += [f"{name} ({', '.join(fns)})" for name, fns in missing.items()]
    if todo:
        said()                                         # the world's own notice would repeat this one
        log(f"first run of this code here: numba compiles {' and '.join(what)} for this machine (about 30 s on an "
            "idle core, once; later runs load it from the cache; python -m rovermarl.warmup compiles ahead)")
    return todo
