"""PPO on the batched environment, in one file, top to bottom (cleanrl's ppo_continuous_action, in numpy).

Every rover of every environment is one PPO sub-environment sharing one policy (``rovermarl.vector.GymVectorEnv``:
B environments x N agents flattened, the step t / T in each observation). The policy is a Gaussian over the two
actions with a tanh MLP for its mean and a learned log-std; the value is a second tanh MLP. Gradients are written
out by hand (no torch needed), Adam updates both. At the end the mean team return of the trained policy (its mean
action) is compared with random play on fresh initial conditions.

    python examples/ppo_vector/ppo_vector.py [--setup solo] [--iterations 150] [--envs 256] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

from rovermarl.vector import GymVectorEnv


def init_mlp(rng, sizes, out_scale):
    """Weights of a tanh MLP: [(W, b), ...], orthogonal-like scaled normal init."""
    layers = []
    for i, (a, b) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        scale = out_scale if i == len(sizes) - 2 else np.sqrt(2.0)
        layers.append([rng.normal(0, scale / np.sqrt(a), (a, b)), np.zeros(b)])
    return layers


def forward(layers, x):
    """Output and the hidden activations (for the backward pass)."""
    acts = [x]
    for i, (w, b) in enumerate(layers):
        x = x @ w + b
        if i < len(layers) - 1:
            x = np.tanh(x)
        acts.append(x)
    return x, acts


def backward(layers, acts, grad_out):
    """Gradients [(dW, db), ...] of a loss whose gradient at the output is grad_out."""
    grads, g = [], grad_out
    for i in range(len(layers) - 1, -1, -1):
        w, _ = layers[i]
        grads.append([acts[i].T @ g, g.sum(axis=0)])
        if i > 0:
            g = (g @ w.T) * (1 - acts[i] ** 2)
    return grads[::-1]


class Adam:
    def __init__(self, params, lr):
        self.lr, self.t = lr, 0
        self.m = [np.zeros_like(p) for p in params]
        self.v = [np.zeros_like(p) for p in params]

    def step(self, params, grads, max_norm=0.5):
        norm = np.sqrt(sum((g ** 2).sum() for g in grads))
        scale = min(1.0, max_norm / (norm + 1e-8))
        self.t += 1
        for p, g, m, v in zip(params, grads, self.m, self.v, strict=True):
            g = g * scale
            m[:] = 0.9 * m + 0.1 * g
            v[:] = 0.999 * v + 0.001 * g * g
            p -= self.lr * (m / (1 - 0.9 ** self.t)) / (np.sqrt(v / (1 - 0.999 ** self.t)) + 1e-8)


def evaluate(env, act, episodes_seed):
    """Mean team return of ``act(obs) -> actions`` over one batch of fresh episodes."""
    obs, _ = env.reset(seed=episodes_seed)
    for _ in range(env.env.world.steps):
        obs, _, _, _, infos = env.step(act(obs))
    return float(infos["return"].mean())


def train(setup="solo", iterations=150, envs=256, seed=0, lr=3e-4, epochs=4, minibatches=8, gamma=0.99, lam=0.95,
          clip=0.2, ent_coef=0.0, hidden=64):
    rng = np.random.default_rng(seed)
    env = GymVectorEnv(num_envs=envs, setup=setup, time_feature=True)
    n, d, steps = env.num_envs, env.single_observation_space.shape[0], env.env.world.steps
    pi = init_mlp(rng, [d, hidden, hidden, 2], 0.01)
    vf = init_mlp(rng, [d, hidden, hidden, 1], 1.0)
    log_std = np.full(2, -0.5)
    params = [p for layer in pi for p in layer] + [log_std] + [p for layer in vf for p in layer]
    opt = Adam(params, lr)
    obs, _ = env.reset(seed=seed)
    t0 = time.perf_counter()
    for it in range(iterations):
        if it:                                               # the next episodes (the env auto-resets next step)
            obs, _ = env.reset()
        # ---- rollout: one episode of every sub-environment ----
        obs_t, act_t, rew_t = np.empty((steps, n, d)), np.empty((steps, n, 2)), np.empty((steps, n))
        val_t, lp_t = np.empty((steps + 1, n)), np.empty((steps, n))
        for t in range(steps):
            mean, _ = forward(pi, obs)
            std = np.exp(log_std)
            a = mean + std * rng.standard_normal(mean.shape)
            obs_t[t], act_t[t], val_t[t] = obs, a, forward(vf, obs)[0][:, 0]
            lp_t[t] = (-0.5 * ((a - mean) / std) ** 2 - log_std - 0.5 * np.log(2 * np.pi)).sum(axis=1)
            obs, rew_t[t], _, _, _ = env.step(np.clip(a, -1, 1))
        val_t[steps] = 0.0                                   # terminated at the horizon: nothing after it
        # ---- advantages (GAE) ----
        adv, last = np.zeros((steps, n)), np.zeros(n)
        for t in range(steps - 1, -1, -1):
            delta = rew_t[t] + gamma * val_t[t + 1] - val_t[t]
            last = delta + gamma * lam * last
            adv[t] = last
        ret = adv + val_t[:steps]
        b_o, b_a, b_lp = obs_t.reshape(-1, d), act_t.reshape(-1, 2), lp_t.reshape(-1)
        b_adv, b_ret = adv.reshape(-1), ret.reshape(-1)
        # ---- PPO epochs over minibatches ----
        size = len(b_o) // minibatches
        for _ in range(epochs):
            order = rng.permutation(len(b_o))
            for k in range(minibatches):
                idx = order[k * size:(k + 1) * size]
                o, a, old_lp = b_o[idx], b_a[idx], b_lp[idx]
                ad = (b_adv[idx] - b_adv[idx].mean()) / (b_adv[idx].std() + 1e-8)
                mean, acts = forward(pi, o)
                std = np.exp(log_std)
                z = (a - mean) / std
                lp = (-0.5 * z ** 2 - log_std - 0.5 * np.log(2 * np.pi)).sum(axis=1)
                ratio = np.exp(lp - old_lp)
                unclipped = ratio * ad
                use = (unclipped <= np.clip(ratio, 1 - clip, 1 + clip) * ad)   # the min picks the unclipped term
                g_lp = np.where(use, -ad * ratio, 0.0) / len(idx)              # d(policy loss)/d(log prob)
                g_mean = g_lp[:, None] * (z / std)                             # d lp / d mean = (a - mean) / std^2
                g_log_std = (g_lp[:, None] * (z ** 2 - 1)).sum(axis=0) - ent_coef
                g_pi = backward(pi, acts, g_mean)
                value, v_acts = forward(vf, o)
                g_v = backward(vf, v_acts, (value[:, 0] - b_ret[idx])[:, None] / len(idx))   # 0.5 * MSE
                grads = [g for layer in g_pi for g in layer] + [g_log_std] + [g for layer in g_v for g in layer]
                opt.step(params, grads)
        if (it + 1) % 25 == 0:
            print(json.dumps({"iteration": it + 1, "agent_steps": (it + 1) * steps * n,
                              "mean_team_return": float(rew_t.sum(axis=0).mean()),
                              "seconds": round(time.perf_counter() - t0, 1)}), flush=True)
    test = GymVectorEnv(num_envs=envs, setup=setup, time_feature=True)
    trained = evaluate(test, lambda o: np.clip(forward(pi, o)[0], -1, 1), 10_000 + seed)
    random = evaluate(test, lambda o: rng.uniform(-1, 1, (len(o), 2)), 10_000 + seed)
    return {"setup": setup, "iterations": iterations, "agent_steps": iterations * steps * n,
            "trained_mean_team_return": trained, "random_mean_team_return": random,
            "seconds": round(time.perf_counter() - t0, 1)}


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--setup", default="solo")
    p.add_argument("--iterations", type=int, default=150)
    p.add_argument("--envs", type=int, default=256)
    p.add_argument("--seed", type=int, default=0)
    a = p.parse_args()
    print(json.dumps(train(a.setup, a.iterations, a.envs, a.seed)))
