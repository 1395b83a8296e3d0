"""Soak test: a sweep on Ray under periodic SIGKILLs of a worker and of the driver, relaunched until it finishes.

Prints one JSON line: kills survived (worker / driver), relaunches, generations executed vs required, and
whether the final curves equal an undisturbed serial run (``--verify``). Generations executed are counted
from ``ROVERMARL_WORK_LOG``, where every finished chunk appends ``seed start stop`` (``benchmarks/worklog``
wraps the chunk function; the package writes no such log).

    python benchmarks/soak.py [--generations 20000] [--seeds 4] [--period 3] [--verify]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import psutil

ROOT = Path(__file__).resolve().parents[1]


def kill_worker(driver: int) -> bool:
    """SIGKILL one worker of the driver's Ray (its descendant: never another Ray on the machine) that is executing
    a chunk; False if none is running right now."""
    with contextlib.suppress(psutil.Error):
        for p in psutil.Process(driver).children(recursive=True):
            with contextlib.suppress(psutil.Error):
                if " ".join(p.cmdline()).startswith("ray::ChunkWorker.advance"):
                    os.kill(p.pid, signal.SIGKILL)
                    return True
    return False


def executed(work_log: Path) -> int:
    if not work_log.exists():
        return 0
    return sum(int(stop) - int(start) for _, start, stop in (line.split() for line in work_log.read_text().split("\n")
                                                              if line.strip()))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--generations", type=int, default=20000)
    p.add_argument("--seeds", type=int, default=4)
    p.add_argument("--chunk", type=int, default=250)
    p.add_argument("--period", type=float, default=3.0, help="seconds between kills")
    p.add_argument("--verify", action="store_true", help="compare with an undisturbed serial run")
    p.add_argument("--out", type=Path, default=None)
    a = p.parse_args()

    out = a.out or Path(tempfile.mkdtemp(prefix="rovermarl-soak-"))
    work_log = out / "work.log"
    overrides = ["-m", "k=1,2", "setup=duo", f"generations={a.generations}", f"seeds={a.seeds}",
                 f"parallel.chunk={a.chunk}", f"checkpoint.every={a.chunk}", "hydra.callbacks={}"]
    argv = [sys.executable, "-m", "rovermarl.train", *overrides, f"hydra.sweep.dir={out / 'sweep'}"]
    path = os.pathsep.join([str(ROOT / "benchmarks" / "worklog"), os.environ.get("PYTHONPATH", "")])
    env = {**os.environ, "ROVERMARL_WORK_LOG": str(work_log), "PYTHONPATH": path}
    kills = {"worker": 0, "driver": 0}
    launches, t0, turn = 0, time.time(), 0
    while True:
        launches += 1
        driver = subprocess.Popen(argv, cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                  start_new_session=True)
        next_kill = time.time() + a.period + (5.0 if launches > 1 else 0.0)    # let a relaunch start Ray first
        while driver.poll() is None:
            time.sleep(0.05)
            if time.time() < next_kill:
                continue
            if turn % 2 == 0:                                   # a worker's turn: retry until one runs a chunk
                if kill_worker(driver.pid):
                    kills["worker"] += 1
                    turn, next_kill = turn + 1, time.time() + a.period
                continue
            os.killpg(driver.pid, signal.SIGKILL)
            driver.wait()
            kills["driver"] += 1
            turn += 1
            break
        if driver.returncode == 0:
            break
        if driver.returncode != -signal.SIGKILL:
            sys.exit(f"soak: the driver failed with exit code {driver.returncode}")
    wall = time.time() - t0
    required = 2 * a.seeds * a.generations
    result = {"benchmark": "soak", "generations": a.generations, "seeds": a.seeds, "jobs": 2, "chunk": a.chunk,
              "checkpoint_every": a.chunk, "kills_survived": kills, "launches": launches,
              "generations_required": required, "generations_executed": executed(work_log),
              "wall_s": round(wall, 1)}
    result["generations_recomputed"] = result["generations_executed"] - required
    # a killed driver loses at most the chunks it received but had not yet checkpointed: < one chunk per run
    result["recompute_bound"] = kills["driver"] * 2 * a.seeds * a.chunk
    if a.verify:
        from rovermarl.config import compose_config
        from rovermarl.runner.job import run_job
        same = True
        for k in (1, 2):
            job = f"generations={a.generations},k={k},setup=duo"          # seeds is not part of a job's dir name
            if not (out / "sweep" / job / "runs").is_dir():
                sys.exit(f"soak: no job dir {out / 'sweep' / job}: the sweep's dir names changed")
            run_job(compose_config("setup=duo", f"k={k}", f"generations={a.generations}", f"seeds={a.seeds}",
                                   "parallel=serial"), out / "reference" / job)
            for f in sorted((out / "reference" / job).glob("runs/*/curve.npz")):
                with np.load(f) as x, np.load(out / "sweep" / job / f.relative_to(out / "reference" / job)) as y:
                    same &= all(np.array_equal(x[key], y[key]) for key in x.files)
        result["curves_equal_undisturbed"] = bool(same)
    result["out"] = str(out)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
