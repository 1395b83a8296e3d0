"""What a job asks of the machine, estimated before any work (and before Ray starts).

:func:`check` refuses, in one line naming the key, a job that cannot fit in this machine's memory, whose one team
evaluation would take longer than :data:`EVALUATION_LIMIT_S`, or whose mutation makes genomes non-finite;
:func:`estimate` gives a feasible job's memory and time; :func:`batch_size` how many runs the driver holds at once.
The cost model is this kernel on a 2-core AVX-512 machine (``benchmarks/throughput.py``: about 320 ns per agent-step
at 38 inputs x 16 hidden units, two thirds of it the MLP), scaled by the MLP's size.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import psutil

from rovermarl import errors
from rovermarl.env.world import World
from rovermarl.parallel import backend
from rovermarl.policy import n_params
from rovermarl.resources import packaged

EVALUATION_LIMIT_S = 3600.0        # one team evaluation longer than this is refused
NS_BASE, NS_PER_MAC, NS_PER_TARGET = 30.0, 0.1, 1.5   # per agent-step: fixed, per MLP multiply-add, per sensed target
SIGMA_LIMIT = 1e100                # a Gaussian mutation beyond this overflows genomes within a run
_RUN, _ENV = packaged("config.yaml"), packaged("env/rovers.yaml")
DEFAULTS = {"generations": _RUN["generations"], "seeds": _RUN["seeds"], "env.episodes": _ENV["episodes"],
            "env.steps": _ENV["steps"], "env.n_rovers": _ENV["n_rovers"],
            "policy.hidden": packaged("policy/mlp.yaml")["hidden"]}      # from conf/: the keys named when too big
MEMORY_KEYS = {"records": ("generations",), "team": ("policy.hidden", "env.n_rovers"),   # a part's keys to name
               "episodes": ("env.episodes", "env.n_rovers", "policy.hidden")}


@dataclass(frozen=True)
class Estimate:
    """Memory (bytes) of the largest parts, and the time (s) of one evaluation and of the whole job."""

    memory: dict[str, float]        # part -> bytes
    evaluation_s: float
    job_s: float
    cpus: int

    @property
    def total_memory(self) -> float:
        return sum(self.memory.values())


def available_memory() -> float:
    """Bytes of memory available to a new job (psutil's ``available``: ``MemAvailable`` on Linux)."""
    return float(psutil.virtual_memory().available)


def estimate(plain: dict, series_bytes: int = 32, per_generation: float = 1.0) -> Estimate:
    """The estimate of a plain composed config; ``series_bytes`` is the algorithm's bytes per generation and
    ``per_generation`` its team evaluations per generation (:meth:`Algorithm.evaluations_per_generation
    <rovermarl.algorithms.Algorithm.evaluations_per_generation>`)."""
    env, g = plain["env"], int(plain["generations"])
    n, e, h = int(env["n_rovers"]), int(env["episodes"]), int(plain["policy"]["hidden"])
    d = World.from_config(plain, trust=True).obs_dim                 # the world's observation blocks (composed)
    genome, seeds = n_params(d, h), int(plain["seeds"])
    memory = {
        "records": 1.0 * batch_size(plain, series_bytes) * run_bytes(plain, series_bytes),   # the driver's runs
        "team": 3.0 * n * genome * 8,                                          # parents, children, the world's copy
        "episodes": 1.0 * e * n * (d + h + 8) * 8,                             # observations, hidden units, state
    }
    evaluation_s = _evaluation_s(plain, d)
    uses_ray = backend(plain.get("parallel") or {}).uses_ray
    cpus = int((plain.get("ray") or {}).get("num_cpus") or os.cpu_count()) if uses_ray else 1
    job_s = evaluation_s * (g * per_generation + 1) * seeds / max(1, min(cpus, seeds))
    return Estimate(memory, evaluation_s, job_s, cpus)


def _evaluation_s(plain: dict, d: int) -> float:
    """Seconds of one team evaluation here, with observations of ``d`` rows."""
    env, h, p = plain["env"], int(plain["policy"]["hidden"]), len(plain["setup"]["coupling"])
    n, e, t = int(env["n_rovers"]), int(env["episodes"]), int(env["steps"])
    return e * t * n * (NS_BASE + NS_PER_MAC * d * h + NS_PER_TARGET * (p + n)) * 1e-9


def precheck(plain: dict) -> None:
    """The time limit of :func:`check` before the world is built, with the paper's observation (3 rows per POI, 2 per
    rover; a plug-in's only adds rows): a world too large to build (env.n_rovers=100000) is refused in one line."""
    try:
        seconds = _evaluation_s(plain, 3 * len(plain["setup"]["coupling"]) + 2 * int(plain["env"]["n_rovers"]))
    except (KeyError, TypeError, ValueError, ArithmeticError):   # malformed: building the world says what is wrong
        return
    _limit(plain, seconds)


def _limit(plain: dict, evaluation_s: float) -> None:
    if evaluation_s > EVALUATION_LIMIT_S:
        key = _largest(plain, ("env.steps", "env.episodes", "policy.hidden", "env.n_rovers"))
        raise errors.ConfigError(key, _get(plain, key), f"one team evaluation would take about "
                                 f"{duration(evaluation_s)} here (limit {duration(EVALUATION_LIMIT_S)})")


def run_bytes(plain: dict, series_bytes: int = 32) -> float:
    """Bytes the driver holds for one run: its score and declared series, every generation."""
    return (int(plain["generations"]) + 1) * (8.0 + series_bytes)


def batch_size(plain: dict, series_bytes: int = 32, memory: float | None = None) -> int:
    """How many runs of a job the driver holds at once: all of them when they fit in a quarter of the available
    ``memory``, else as many as do (at least one); a job streams its runs in batches of this size."""
    memory = available_memory() if memory is None else memory
    return int(max(1, min(int(plain["seeds"]), memory / 4 // run_bytes(plain, series_bytes))))


def check(plain: dict, series_bytes: int = 32, per_generation: float = 1.0) -> Estimate:
    """Raise :class:`~rovermarl.errors.ConfigError` for a job this machine cannot do; else its estimate."""
    sigma = (plain.get("mutation") or {}).get("sigma")
    if isinstance(sigma, (int, float)) and not isinstance(sigma, bool) and abs(sigma) > SIGMA_LIMIT:
        raise errors.ConfigError("mutation.sigma", sigma, f"must be at most {SIGMA_LIMIT:g}: larger Gaussian "
                                 "mutations make genomes non-finite")
    est = estimate(plain, series_bytes, per_generation)
    _limit(plain, est.evaluation_s)
    one_run, avail = run_bytes(plain, series_bytes), available_memory()
    if one_run > avail / 4:                                        # one run's record: never split
        raise errors.ConfigError("generations", _get(plain, "generations"), f"one run needs about {size(one_run)} "
                                 f"of memory for its record, more than a quarter of the {size(avail)} this machine "
                                 "has available")
    if est.total_memory > avail:
        part = max(est.memory, key=est.memory.get)
        key = _largest(plain, MEMORY_KEYS[part])
        raise errors.ConfigError(key, _get(plain, key), f"the job needs about {size(est.total_memory)} of memory "
                                 f"({part}), this machine has {size(avail)} available")
    return est


def _get(plain: dict, key: str):
    node = plain
    for part in key.split("."):
        node = node[part]
    return node


def _largest(plain: dict, keys) -> str:
    """The key whose value is furthest above its default (the one to name)."""
    return max(keys, key=lambda k: float(_get(plain, k)) / DEFAULTS[k])


def duration(seconds: float) -> str:
    """``about``-style durations: ``40 s``, ``12 min``, ``3.5 h``, ``9 days``, ``2e+04 years``."""
    for unit, span in (("years", 365.25 * 86400), ("days", 86400), ("h", 3600), ("min", 60)):
        if seconds >= span * (1 if unit != "days" else 2):
            value = seconds / span
            return f"{value:.2g} {unit}" if value < 1e4 else f"{value:.1e} {unit}"
    return f"{math.ceil(seconds)} s"


def size(nbytes: float) -> str:
    for unit, span in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if nbytes >= span:
            return f"{nbytes / span:.3g} {unit}"
    return f"{nbytes / 1e3:.3g} kB"
