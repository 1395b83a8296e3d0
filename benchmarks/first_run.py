"""What a new user waits for: the first run against a warm one, the first ``World.evaluate``, and a relaunch of a
finished sweep. Prints one JSON line.

- ``job``: the default job (``python -m rovermarl.train``, embedded Ray) with an empty ``NUMBA_CACHE_DIR`` (cold),
  then again on that cache (warm); ``job_cold_minus_warm_s`` is the compile a first run pays.
- ``evaluate``: a fresh process that imports rovermarl and scores one team with ``World.evaluate``, cold then warm
  (process start and imports included).
- ``relaunch``: a 6-job sweep (``-m k=1,2,adaptive setup=solo,duo``, small budget) run once, then relaunched: the
  relaunch computes nothing, starts no Ray and redraws no figure.

Each is timed as wall time of a subprocess, ``--rounds`` times, median reported with every round; the load average
is printed beside it (the targets are for idle cores).

    python benchmarks/first_run.py [--rounds 1] [--skip job,evaluate,relaunch] [TRAIN_OVERRIDE ...]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

EVALUATE = ("import numpy as np; from rovermarl.env import make_world; w = make_world('solo'); "
            "w.evaluate(np.zeros((w.n_rovers, w.n_params)), w.initial_conditions(seed=0, n=w.episodes))")
SWEEP = ["-m", "k=1,2,adaptive", "setup=solo,duo", "generations=200", "seeds=2"]


def timed(cmd: list[str], env: dict) -> float:
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - t0


def cold_warm(cmd_of, root: Path) -> tuple[float, float]:
    """Seconds of ``cmd_of(tag)`` on an empty numba cache, then again on it."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(root / "numba"))
    return timed(cmd_of("cold"), env), timed(cmd_of("warm"), env)


def one_round(root: Path, train: list[str], overrides: list[str], skip: set[str], out: dict) -> None:
    """Each measure once, in ``root``; appends its seconds to ``out``."""
    if "job" not in skip:
        cold, warm = cold_warm(lambda tag: [*train, *overrides, f"hydra.run.dir={root / tag}"], root / "j")
        out.setdefault("job_cold_s", []).append(round(cold, 1))
        out.setdefault("job_warm_s", []).append(round(warm, 1))
    if "evaluate" not in skip:
        cold, warm = cold_warm(lambda tag: [sys.executable, "-c", EVALUATE], root / "e")
        out.setdefault("evaluate_cold_s", []).append(round(cold, 1))
        out.setdefault("evaluate_warm_s", []).append(round(warm, 1))
    if "relaunch" not in skip:
        sweep = [*train, *SWEEP, f"hydra.sweep.dir={root / 'sweep'}"]
        timed(sweep, dict(os.environ))
        out.setdefault("relaunch_s", []).append(round(timed(sweep, dict(os.environ)), 1))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=1)
    p.add_argument("--skip", default="", help="comma-separated: job, evaluate, relaunch")
    p.add_argument("overrides", nargs="*", help="overrides of the default job")
    a = p.parse_args()
    skip = set(filter(None, a.skip.split(",")))
    train = [sys.executable, "-m", "rovermarl.train"]
    out: dict = {"benchmark": "first_run", "rounds": a.rounds, "load_before": os.getloadavg()[0]}
    for _ in range(a.rounds):
        with tempfile.TemporaryDirectory(prefix="rovermarl-first-run-") as d:
            one_round(Path(d), train, a.overrides, skip, out)
    med = statistics.median
    for name in ("job", "evaluate"):
        if f"{name}_cold_s" in out:
            out[f"{name}_cold_minus_warm_s"] = round(med(out[f"{name}_cold_s"]) - med(out[f"{name}_warm_s"]), 1)
    if "relaunch_s" in out:
        out["relaunch_median_s"] = med(out["relaunch_s"])
    out["load_after"] = os.getloadavg()[0]
    out["cpus"] = os.cpu_count()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
