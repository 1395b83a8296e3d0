"""stable-baselines3 on the batched environment (the ``[rl]`` extra: ``pip install -e ".[rl]"``): its ``VecEnv`` view
(:class:`VecEnv`) and PPO with parameter sharing as an algorithm plug-in (:class:`PPO`, ``algorithm=ppo``).

``VecEnv`` is :class:`rovermarl.vector.VectorEnv` with the agents flattened: agent i of environment b is
sub-environment ``b*N + i``, all sharing one policy, observations (B*N, D), actions (B*N, 2), rewards and dones
(B*N,); an episode's last step returns the next episode's first observations, the last ones in
``infos[j]["terminal_observation"]``. Its defaults are :data:`rovermarl.vector.DEFAULTS` (one set for every view).

>>> from stable_baselines3 import PPO
>>> from rovermarl.sb3 import VecEnv
>>> PPO("MlpPolicy", VecEnv(setup="solo"), n_steps=15).learn(768_000 // 4)  # doctest: +SKIP

:class:`PPO`'s actor is the world's own policy, ``obs -> tanh(hidden) -> tanh(2)`` (SPEC section 4), as the mean of a
Gaussian with a learned log-std, so its deterministic policy is a genome (P,) scored as every learner's team is (N
copies of it; docs/LEARNERS.md). One generation is one PPO iteration: ``n_steps`` steps of ``num_envs`` environments,
then the update. The critic alone also sees the step t / T: the reward comes at an episode's last step, and without t
its value cannot be learned (PPO then learns nothing).

Training starts (SPEC section 8's regimes; docs/LEARNERS.md, "Like with like"): the run's own initial conditions in
turn under ``evaluation.fresh_ic=false`` (``VectorEnv(starts=...)``), new ones from the run's environment stream
under ``true``. ``final_team`` is ``last`` or ``best`` (:func:`rovermarl.algorithms.final_team.keep_best`). Resume
is bit-identical: the state holds the network and Adam moments as arrays and the torch, numpy-global and environment
random states, and each iteration starts on fresh episodes (``n_steps`` is a multiple of ``env.steps``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

try:
    import torch
    from stable_baselines3 import PPO as _SB3PPO
    from stable_baselines3.common import vec_env as _vec
    from stable_baselines3.common.policies import ActorCriticPolicy
except ModuleNotFoundError as _e:
    raise ModuleNotFoundError(f"rovermarl.sb3 needs torch and stable-baselines3 ({_e.name} is not installed): "
                              'pip install -e ".[rl]"') from None
import gymnasium

from rovermarl import errors, policy
from rovermarl.algorithms.base import RunState, generator
from rovermarl.algorithms.final_team import SharedActor, train_starts
from rovermarl.env import World
from rovermarl.torch_state import RunRng, adam_arrays, load_adam, seeded
from rovermarl.vector import DEFAULTS, VectorEnv


class VecEnv(_vec.VecEnv):
    """stable-baselines3's ``VecEnv`` of B*N sub-environments over one :class:`~rovermarl.vector.VectorEnv` (its
    arguments, its defaults)."""

    def __init__(self, num_envs: int = DEFAULTS["num_envs"], setup: str = DEFAULTS["setup"], world: World | None = None,
                 time_feature: bool = DEFAULTS["time_feature"], **overrides):
        self.env = e = VectorEnv(num_envs, setup, world, time_feature, **overrides)
        obs = gymnasium.spaces.Box(e.obs_low, e.obs_high, dtype=e.dtype)
        super().__init__(e.num_envs * e.n_agents, obs, gymnasium.spaces.Box(-1.0, 1.0, (2,), dtype=e.dtype))
        self._actions = None

    def reset(self) -> np.ndarray:
        seed = self._seeds[0] if self._seeds and self._seeds[0] is not None else None
        obs, _ = self.env.reset(seed=seed)
        self._reset_seeds()
        return obs.reshape(self.num_envs, -1)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions).reshape(self.env.num_envs, self.env.n_agents, 2)

    def step_wait(self):
        obs, rew, term, trunc, infos = self.env.step(self._actions)
        done = (term | trunc).reshape(-1)
        out = [{} for _ in range(self.num_envs)]
        if "final_obs" in infos:
            final = infos["final_obs"].reshape(self.num_envs, -1)
            ret = np.repeat(infos["final_return"], self.env.n_agents)
            for j in range(self.num_envs):
                out[j] = {"terminal_observation": final[j], "TimeLimit.truncated": False,
                          "episode": {"r": float(ret[j]), "l": self.env.t or self.env.world.steps}}
        return obs.reshape(self.num_envs, -1), rew.reshape(-1).astype(np.float32), done, out

    def close(self) -> None:
        pass

    def get_attr(self, attr_name, indices=None):
        value = getattr(self.env, attr_name, None) if attr_name == "render_mode" else getattr(self.env, attr_name)
        return [value] * len(self._indices(indices))

    def set_attr(self, attr_name, value, indices=None) -> None:
        setattr(self.env, attr_name, value)

    def env_method(self, method_name, *args, indices=None, **kwargs):
        return [getattr(self.env, method_name)(*args, **kwargs)] * len(self._indices(indices))

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False] * len(self._indices(indices))

    def _indices(self, indices):
        return range(self.num_envs) if indices is None else ([indices] if isinstance(indices, int) else indices)


class _Split(torch.nn.Module):
    """SB3's ``MlpExtractor`` contract with the time feature (the last input) for the critic only: the actor's
    latent is ``tanh(W1 sensors + b1)`` (the world's hidden layer), the critic's a tanh MLP of every input."""

    def __init__(self, inputs: int, hidden: int, value_hidden: list[int]):
        super().__init__()
        self.policy_net = torch.nn.Sequential(torch.nn.Linear(inputs - 1, hidden), torch.nn.Tanh())
        layers, last = [], inputs
        for h in value_hidden:
            layers += [torch.nn.Linear(last, h), torch.nn.Tanh()]
            last = h
        self.value_net = torch.nn.Sequential(*layers)
        self.latent_dim_pi, self.latent_dim_vf = hidden, last

    def forward(self, features):
        return self.forward_actor(features), self.forward_critic(features)

    def forward_actor(self, features):
        return self.policy_net(features[..., :-1])

    def forward_critic(self, features):
        return self.value_net(features)


class GenomePolicy(ActorCriticPolicy):
    """SB3's actor-critic whose action mean is the world's policy (the sensors, a tanh hidden layer, a tanh on the
    action net's output); the critic also sees the step t / T (an episode's reward comes at its last step)."""

    def _build_mlp_extractor(self) -> None:
        self.mlp_extractor = _Split(self.features_dim, self.net_arch["pi"][0], self.net_arch["vf"])

    def _build(self, lr_schedule) -> None:
        super()._build(lr_schedule)
        self.action_net = torch.nn.Sequential(self.action_net, torch.nn.Tanh())   # its parameters: the optimiser's


@dataclass(kw_only=True)
class PPOState(RunState):
    """The iterate's ``params`` (SB3's policy state_dict as arrays) and Adam's moments ``adam``; the torch and numpy-
    global RNG states SB3 draws from (``torch``, ``numpy``); the environments' bit-generator state ``env_rng`` and
    ``cursor`` (the next of the run's starts, under fixed starts); SB3's ``timesteps``; the kept genome ``best`` (P,)
    under ``final_team=best``, else None."""

    params: dict
    adam: dict
    torch: np.ndarray
    numpy: dict | None
    env_rng: dict
    cursor: int = 0
    timesteps: int
    best: np.ndarray | None = None


class PPO(SharedActor):
    """Built from ``conf/algorithm/ppo.yaml`` (SB3's PPO arguments; ``num_envs`` environments of N rovers)."""

    state_type = PPOState

    def __init__(self, world, num_envs: int = 256, n_steps: int = 15, batch_size: int = 1920, n_epochs: int = 5,
                 learning_rate: float = 3e-4, gamma: float = 0.99, gae_lambda: float = 0.95, clip_range: float = 0.2,
                 ent_coef: float = 0.0, vf_coef: float = 0.5, max_grad_norm: float = 0.5, log_std_init: float = -0.5,
                 value_hidden: tuple = (64, 64), final_team: str = "last", loop: str = "auto"):
        super().__init__(world)
        self._common_keys(loop, final_team, num_envs, n_steps, what="PPO ")
        self.kwargs = {"n_steps": self.n_steps, "batch_size": errors.integer("batch_size", batch_size, 2),
                       "n_epochs": errors.integer("n_epochs", n_epochs, 1),
                       "learning_rate": errors.number("learning_rate", learning_rate, 0, lo_open=True),
                       "gamma": errors.number("gamma", gamma, 0, 1),
                       "gae_lambda": errors.number("gae_lambda", gae_lambda, 0, 1),
                       "clip_range": errors.number("clip_range", clip_range, 0, lo_open=True),
                       "ent_coef": errors.number("ent_coef", ent_coef), "vf_coef": errors.number("vf_coef", vf_coef),
                       "max_grad_norm": errors.number("max_grad_norm", max_grad_norm, 0, lo_open=True)}
        self.policy_kwargs = {"net_arch": {"pi": [world.policy.hidden], "vf": [int(h) for h in value_hidden]},
                              "activation_fn": torch.nn.Tanh,
                              "log_std_init": errors.number("log_std_init", log_std_init)}

    def _model(self, starts=None):
        env = VecEnv(self.num_envs, world=self.world, time_feature=True, starts=starts)
        return _SB3PPO(GenomePolicy, env, policy_kwargs=self.policy_kwargs, device="cpu", verbose=0, **self.kwargs)

    def _init(self, streams, evaluate):
        seeds = np.random.default_rng(streams.algorithm).integers(0, 2**63, 2)
        with RunRng(seeded(int(seeds[0]))) as rng:
            model = self._model(train_starts(evaluate))
            state = self._save(model, rng, np.random.default_rng(streams.mutation).bit_generator.state, 0)
        state.numpy = np.random.RandomState(int(seeds[1]) % 2**32).get_state(legacy=False)
        return state, self._first(state, evaluate)

    def _genomes(self, p) -> np.ndarray:
        """The team (N, P) of an iterate's parameters: N copies of its deterministic actor."""
        genome = policy.flatten(p["mlp_extractor.policy_net.0.weight"].T, p["mlp_extractor.policy_net.0.bias"],
                                p["action_net.0.weight"].T, p["action_net.0.bias"])
        return self.world.homogeneous(genome)

    def _advance(self, state, generation, n, evaluate, observer):
        score, score_before, best = np.empty(n), float(state.score), state.best
        with RunRng(torch.get_rng_state().numpy()):
            model = self._model(train_starts(evaluate))   # its initial weights are replaced: the caller's RNG kept
        with RunRng(state.torch, state.numpy) as rng:
            self._load(model, state)
            env = model.env.env
            env._rng, env.cursor = generator(state.env_rng), int(state.cursor)
            for t in range(n):
                model._last_obs = None                     # every iteration starts on new episodes (resumable)
                model.learn(self.n_steps * model.env.num_envs, reset_num_timesteps=False)
                state = self._save(model, rng, env._rng.bit_generator.state, env.cursor)
                team, (f, final_xy) = self._scored(state, best, evaluate, generation + t + 1, score_before)
                best = state.best
                observer.accepted(generation + t + 1, team, f, f != score_before, final_xy)
                score[t] = state.score = score_before = f
        return state, {"score": score}

    def _save(self, model, rng, env_rng, cursor: int) -> PPOState:
        adam = adam_arrays(dict(model.policy.named_parameters()), model.policy.optimizer.state)
        assert list(adam) == [name for name, _ in model.policy.named_parameters()]     # Adam's order is the policy's
        params = {k: v.detach().numpy().copy() for k, v in model.policy.state_dict().items()}
        numpy = np.random.get_state(legacy=False)  # noqa: NPY002 - SB3 shuffles with it
        return PPOState(params=params, adam=adam, torch=rng.state(), numpy=numpy, env_rng=env_rng, cursor=int(cursor),
                        score=0.0, timesteps=int(model.num_timesteps))

    def _load(self, model, state) -> None:
        model.policy.load_state_dict({k: torch.from_numpy(np.array(v)) for k, v in state.params.items()})
        load_adam(dict(model.policy.named_parameters()), model.policy.optimizer.state, state.adam)
        model.num_timesteps = int(state.timesteps)

