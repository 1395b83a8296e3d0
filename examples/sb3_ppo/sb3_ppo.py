"""stable-baselines3's PPO on the batched environment with parameter sharing, through the package's VecEnv view
(``rovermarl.sb3.VecEnv``: B environments x N rovers flattened into B*N sub-environments of one policy). No adapter
to write. At the end the deterministic policy's mean team return on one batch of fresh episodes is printed, with
random play's on the same episodes.

    pip install -e ".[rl]"
    python examples/sb3_ppo/sb3_ppo.py [--setup solo] [--envs 128] [--iterations 100] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np
import torch
from stable_baselines3 import PPO

from rovermarl.sb3 import VecEnv


def mean_return(env: VecEnv, act, seed: int) -> float:
    """Mean team return of ``act(obs) -> actions`` over one batch of episodes drawn from ``seed``."""
    env.seed(seed)
    obs = env.reset()
    for _ in range(env.env.world.steps):
        env.step_async(act(obs))
        obs, _, _, infos = env.step_wait()
    return float(np.mean([i["episode"]["r"] for i in infos]))


def train(setup="solo", envs=128, iterations=100, seed=0) -> dict:
    torch.set_num_threads(1)
    env = VecEnv(envs, setup=setup)                       # the defaults of every view: time feature on
    steps = env.env.world.steps                           # one episode per sub-environment per iteration
    model = PPO("MlpPolicy", env, n_steps=steps, batch_size=env.num_envs * steps // 8, n_epochs=4, seed=seed,
                device="cpu", verbose=0, policy_kwargs={"log_std_init": -0.5, "activation_fn": torch.nn.Tanh})
    t0 = time.perf_counter()
    model.learn(iterations * steps * env.num_envs)
    test = VecEnv(envs, setup=setup)
    rng = np.random.default_rng(seed)
    return {"setup": setup, "agent_steps": iterations * steps * env.num_envs,
            "trained_mean_team_return": mean_return(test, lambda o: model.predict(o, deterministic=True)[0],
                                                    10_000 + seed),
            "random_mean_team_return": mean_return(test, lambda o: rng.uniform(-1, 1, (len(o), 2)), 10_000 + seed),
            "seconds": round(time.perf_counter() - t0, 1)}


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="solo")
    p.add_argument("--envs", type=int, default=128)
    p.add_argument("--iterations", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    print(json.dumps(train(a.setup, a.envs, a.iterations, a.seed)))
