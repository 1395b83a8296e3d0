"""The compute of the learners study (launchers/learners.sh), estimated before it runs: each learner's agent-steps per
second of process CPU time in each world (a short run, after its compile), and from it the CPU time of one run and
of every cell at the study's budget. Prints one JSON object; PPO only where torch and stable-baselines3 import.

    python benchmarks/learners.py [--worlds solo,duo,...] [--learners cces_k1,...,ppo] [--agent-steps 19200000]
        [--seeds 8] [--sample 500000]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import time

from rovermarl.config import compose_config
from rovermarl.runner import Run
from rovermarl.runner.validate import validate

WORLDS = {"solo": ("setup=solo",), "duo": ("setup=duo",), "trio": ("setup=trio",),
          "obstacles": ("env=obstacles", "hydra.searchpath=[file://examples/obstacles]"),
          "random_pois": ("env=random_pois", "hydra.searchpath=[file://examples/random_pois]")}
LEARNERS = {"cces_k1": ("k=1",), "cces_adaptive": ("k=adaptive",), "cces_homogeneous": ("team=homogeneous",),
            "ccea_dpp": ("algorithm=ccea", "algorithm.reward=dpp"), "cma": ("algorithm=cma",),
            "ppo": ("algorithm=ppo",)}


def rate(overrides: tuple, sample: int) -> tuple[float, int]:
    """Agent-steps per CPU second of a run of ``overrides``, over about ``sample`` agent-steps; and its per-generation
    agent-steps."""
    cfg = compose_config(*overrides, f"budget.agent_steps={sample * 4}", "record=off")
    validate(cfg)
    run = Run(cfg, 0)
    per = run.parts.algorithm.agent_steps_per_generation()
    run.advance(1)                                                      # compile, warm
    n = max(1, sample // per)
    t = time.process_time()
    run.advance(n)
    return n * per / (time.process_time() - t), per


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--worlds", default=",".join(WORLDS))
    p.add_argument("--agent-steps", type=int, default=19_200_000)
    p.add_argument("--seeds", type=int, default=8)
    p.add_argument("--learners", default=",".join(LEARNERS))
    p.add_argument("--sample", type=int, default=500_000, help="agent-steps measured per learner and world")
    a = p.parse_args()
    rl = all(importlib.util.find_spec(m) for m in ("torch", "stable_baselines3"))
    out = {"agent_steps": a.agent_steps, "seeds": a.seeds, "cells": {}, "skipped": [] if rl else ["ppo: no [rl]"]}
    for world in a.worlds.split(","):
        for learner in a.learners.split(","):
            overrides = LEARNERS[learner]
            if learner == "ppo" and not rl:
                continue
            try:
                steps_per_s, per = rate((*WORLDS[world], *overrides), a.sample)
            except ValueError as e:                                     # a learner the world cannot serve
                out["skipped"].append(f"{world}/{learner}: {e}")
                continue
            run_s = a.agent_steps / steps_per_s
            out["cells"][f"{world}/{learner}"] = {"agent_steps_per_cpu_s": round(steps_per_s),
                                                  "agent_steps_per_generation": per, "run_cpu_s": round(run_s),
                                                  "cell_cpu_s": round(run_s * a.seeds)}
    cells = out["cells"].values()
    out["total_cpu_h"] = round(sum(c["cell_cpu_s"] for c in cells) / 3600, 2)
    out["total_cpu_h_without_ppo"] = round(sum(c["cell_cpu_s"] for k, c in out["cells"].items()
                                               if not k.endswith("/ppo")) / 3600, 2)
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
