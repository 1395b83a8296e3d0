"""Agent-steps per second of the batched environment (rovermarl.vector) and of the PettingZoo env, in one run.

Random actions (uniform in [-1, 1], drawn by numpy inside the timed loop, as a learner's sampling would be) on the
package's default setup. The clock is this process's CPU time (one core; compile excluded: each env is warmed up
first). The promise (issue 32): at least 1 M agent-steps/s at B = 1024 and at least 30x the PettingZoo env.
Prints one JSON line.

    python benchmarks/vector_env.py [--num-envs 1024] [--seconds 3] [--setup solo] [--dtype float64]
"""

from __future__ import annotations

import argparse
import json
import os
import time

import numpy as np

from rovermarl.pettingzoo import parallel_env
from rovermarl.vector import GymVectorEnv, VectorEnv


def _rate(step, agents_per_step: int, seconds: float) -> float:
    """Agent-steps per CPU second of ``step()`` called for at least ``seconds`` (best of 3 rounds)."""
    best = 0.0
    for _ in range(3):
        n, t0 = 0, time.process_time()
        while time.process_time() - t0 < seconds / 3:
            step()
            n += 1
        best = max(best, n * agents_per_step / (time.process_time() - t0))
    return best


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--num-envs", type=int, default=1024)
    p.add_argument("--seconds", type=float, default=3.0)
    p.add_argument("--setup", default="solo")
    p.add_argument("--dtype", default="float64", choices=("float64", "float32"))
    a = p.parse_args()
    rng = np.random.default_rng(0)

    vec = VectorEnv(a.num_envs, setup=a.setup, dtype=a.dtype)
    vec.reset(seed=0)
    shape = (a.num_envs, vec.n_agents, 2)
    vec.step(rng.uniform(-1, 1, shape))                                   # compile (and the cache) first
    vector_rate = _rate(lambda: vec.step(rng.uniform(-1, 1, shape)), a.num_envs * vec.n_agents, a.seconds)

    gym = GymVectorEnv(a.num_envs, setup=a.setup, dtype=a.dtype)
    gym.reset(seed=0)
    gym_rate = _rate(lambda: gym.step(rng.uniform(-1, 1, (gym.num_envs, 2))), gym.num_envs, a.seconds)

    pz = parallel_env(a.setup, dtype=a.dtype)
    pz.reset(seed=0)

    def pz_step():
        if not pz.agents:
            pz.reset()
        pz.step({agent: rng.uniform(-1, 1, 2) for agent in pz.agents})
    pz_step()
    pz_rate = _rate(pz_step, pz.world.n_rovers, a.seconds)

    print(json.dumps({"benchmark": "vector_env", "setup": a.setup, "dtype": a.dtype, "num_envs": a.num_envs,
                      "agents": vec.n_agents, "actions": "uniform(-1, 1), numpy", "clock": "process CPU time",
                      "vector_agent_steps_per_s": round(vector_rate), "gym_view_agent_steps_per_s": round(gym_rate),
                      "pettingzoo_agent_steps_per_s": round(pz_rate),
                      "vector_over_pettingzoo": round(vector_rate / pz_rate, 1),
                      "promise": {"vector_at_least": 1_000_000, "over_pettingzoo_at_least": 30},
                      "kept": vector_rate >= 1_000_000 and vector_rate / pz_rate >= 30,
                      "loadavg_1m": os.getloadavg()[0], "cpus": os.cpu_count()}))


if __name__ == "__main__":
    main()
