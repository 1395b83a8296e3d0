"""MAPPO and IPPO from TorchRL (the ``[marl]`` extra) as algorithm plug-ins: ``algorithm=mappo``, ``algorithm=ippo``.

Both train one actor shared by every rover, the world's own policy ``sensors -> tanh(hidden) -> tanh(2)`` (SPEC
section 4): TorchRL's ``MultiAgentMLP`` gives ``loc``, its ``TanhNormal`` samples ``tanh(loc + scale * eps)`` with a
learned state-independent log-std, so the deterministic policy ``tanh(loc)`` is a genome (P,) scored as every other
learner's team is (N copies of it). They differ only in the critic (tanh layers ``value_hidden`` over each rover's
sensors and t / T): MAPPO's is centralised (every rover's observations), IPPO's decentralised (its own). The update is
TorchRL's ``ClipPPOLoss`` with its ``GAE``: ``n_epochs`` passes of ``minibatches`` shuffled minibatches, Adam and
gradient clipping, the advantages normalised per minibatch and rover (as TorchRL's multi-agent PPO losses do).

One generation is one iteration: ``n_steps`` steps (a multiple of ``env.steps``: each iteration starts on fresh
episodes) of ``num_envs`` environments of :class:`rovermarl.vector.VectorEnv`, then the update. Training starts and
``final_team`` follow ``algorithm=ppo``'s rules (:mod:`rovermarl.sb3`). Resume is bit-identical: the state holds the
networks' and Adam's tensors as arrays and the torch and environment random states (one torch thread).

>>> # python -m rovermarl.train algorithm=mappo budget.agent_steps=1536000 setup=duo   # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

try:
    import torch
    from tensordict import TensorDict
    from tensordict.nn import TensorDictModule
    from torchrl.envs.utils import ExplorationType, set_exploration_type
    from torchrl.modules import MultiAgentMLP, ProbabilisticActor, TanhNormal
    from torchrl.objectives import ClipPPOLoss, ValueEstimators
except ModuleNotFoundError as _e:
    raise ModuleNotFoundError(f"rovermarl.marl needs torch and torchrl ({_e.name} is not installed): "
                              'pip install -e ".[marl]"') from None

from rovermarl import errors, policy
from rovermarl.algorithms.base import RunState, generator
from rovermarl.algorithms.final_team import SharedActor, train_starts
from rovermarl.torch_state import RunRng, adam_arrays, load_adam, seeded
from rovermarl.vector import VectorEnv

A = "agents"                                     # TorchRL's group of per-agent entries: (B, N, ...) under it


class _Actor(torch.nn.Module):
    """The world's policy as a Gaussian's location, ``loc = W2 tanh(W1 sensors + b1) + b2`` (B.., N, 2), with a
    learned state-independent ``scale`` (B.., N, 2); TanhNormal's tanh makes ``tanh(loc)`` the deterministic action."""

    def __init__(self, sensors: int, n_agents: int, hidden: int, log_std_init: float):
        super().__init__()
        self.mlp = MultiAgentMLP(n_agent_inputs=sensors, n_agent_outputs=2, n_agents=n_agents, centralized=False,
                                 share_params=True, depth=1, num_cells=hidden, activation_class=torch.nn.Tanh)
        self.log_std = torch.nn.Parameter(torch.full((2,), float(log_std_init)))

    def forward(self, sensors):
        loc = self.mlp(sensors)
        return loc, self.log_std.exp().expand_as(loc)


@dataclass(kw_only=True)
class MARLState(RunState):
    """The iterate's actor and critic ``params`` (by torchrl's names) and Adam's moments ``adam``, as arrays; the
    torch RNG state ``torch``; the environments' bit-generator state ``env_rng`` and ``cursor`` (the next of the
    run's starts, under fixed starts); the kept genome ``best`` (P,) under ``final_team=best``, else None."""

    params: dict
    adam: dict
    torch: np.ndarray
    env_rng: dict
    cursor: int = 0
    best: np.ndarray | None = None


class MAPPO(SharedActor):
    """Built from ``conf/algorithm/mappo.yaml`` (``ippo.yaml``: :class:`IPPO`); ``num_envs`` environments of N
    rovers. The defaults are ``algorithm=ppo``'s (SB3's PPO as this project runs it), so that the learners differ in
    their critic and library, not in their settings."""

    state_type = MARLState
    centralised = True

    def __init__(self, world, num_envs: int = 256, n_steps: int = 15, minibatches: int = 8, n_epochs: int = 5,
                 learning_rate: float = 3e-4, gamma: float = 0.99, gae_lambda: float = 0.95, clip_epsilon: float = 0.2,
                 entropy_coef: float = 0.0, critic_coef: float = 0.5, max_grad_norm: float = 0.5,
                 log_std_init: float = -0.5, value_hidden: tuple = (64, 64), final_team: str = "last",
                 loop: str = "auto"):
        super().__init__(world)
        self._common_keys(loop, final_team, num_envs, n_steps)
        self.minibatches = errors.integer("minibatches", minibatches, 1, self.num_envs * self.n_steps)
        self.n_epochs = errors.integer("n_epochs", n_epochs, 1)
        self.lr = errors.number("learning_rate", learning_rate, 0, lo_open=True)
        self.gamma = errors.number("gamma", gamma, 0, 1)
        self.lmbda = errors.number("gae_lambda", gae_lambda, 0, 1)
        self.clip_epsilon = errors.number("clip_epsilon", clip_epsilon, 0, lo_open=True)
        self.entropy_coef = errors.number("entropy_coef", entropy_coef, 0)
        self.critic_coef = errors.number("critic_coef", critic_coef, 0)
        self.max_grad_norm = errors.number("max_grad_norm", max_grad_norm, 0, lo_open=True)
        self.log_std_init = errors.number("log_std_init", log_std_init)
        self.value_hidden = [errors.integer("value_hidden", h, 1, 100_000) for h in value_hidden]
        if not self.value_hidden or len(set(self.value_hidden)) != 1:
            raise errors.ConfigError("value_hidden", list(value_hidden), "must be one width, one or more times "
                                     "(e.g. [64, 64]: MultiAgentMLP's depth x num_cells)")

    # ---- the networks ------------------------------------------------------------------------------------------
    def _loss(self) -> ClipPPOLoss:
        """A fresh actor, critic and loss (their initial weights from the torch generator in force)."""
        w, n = self.world, self.world.n_rovers
        actor = ProbabilisticActor(
            TensorDictModule(_Actor(w.obs_dim, n, w.policy.hidden, self.log_std_init),
                             in_keys=[(A, "sensors")], out_keys=[(A, "loc"), (A, "scale")]),
            in_keys=[(A, "loc"), (A, "scale")], out_keys=[(A, "action")], distribution_class=TanhNormal,
            distribution_kwargs={"low": -1.0, "high": 1.0, "tanh_loc": False}, return_log_prob=True,
            log_prob_key=(A, "log_prob"))
        critic = TensorDictModule(
            MultiAgentMLP(n_agent_inputs=w.obs_dim + 1, n_agent_outputs=1, n_agents=n, centralized=self.centralised,
                          share_params=True, depth=len(self.value_hidden), num_cells=self.value_hidden[0],
                          activation_class=torch.nn.Tanh),
            in_keys=[(A, "observation")], out_keys=[(A, "state_value")])
        loss = ClipPPOLoss(actor, critic, clip_epsilon=self.clip_epsilon, entropy_bonus=self.entropy_coef > 0,
                           entropy_coeff=self.entropy_coef, critic_coeff=self.critic_coef, loss_critic_type="l2",
                           normalize_advantage=True, normalize_advantage_exclude_dims=(-2,))   # per rover (TorchRL's)
        loss.set_keys(reward=(A, "reward"), action=(A, "action"), sample_log_prob=(A, "log_prob"),
                      value=(A, "state_value"), done=(A, "done"), terminated=(A, "terminated"))
        loss.make_value_estimator(ValueEstimators.GAE, gamma=self.gamma, lmbda=self.lmbda)
        return loss

    # ---- the contract ------------------------------------------------------------------------------------------
    def _init(self, streams, evaluate):
        seed = int(np.random.default_rng(streams.algorithm).integers(0, 2**63))
        with RunRng(seeded(seed)) as rng:
            loss = self._loss()
            state = self._save(loss, None, rng.state(), np.random.default_rng(streams.mutation).bit_generator.state)
        return state, self._first(state, evaluate)

    def _genomes(self, p) -> np.ndarray:
        """The team (N, P) of an iterate's parameters: N copies of its deterministic actor."""
        m = "actor_network_params.module.0.module.mlp.params."
        genome = policy.flatten(p[m + "0.weight"].T, p[m + "0.bias"], p[m + "2.weight"].T, p[m + "2.bias"])
        return self.world.homogeneous(genome)

    def _advance(self, state, generation, n, evaluate, observer):
        score, score_before, best = np.empty(n), float(state.score), state.best
        env = VectorEnv(self.num_envs, world=self.world, time_feature=True, starts=train_starts(evaluate))
        with RunRng(state.torch) as rng:
            loss = self._loss()                          # its initial weights are replaced below
            rng.restore(state.torch)
            opt = self._load(loss, state)
            env._rng, env.cursor = generator(state.env_rng), int(state.cursor)
            for t in range(n):
                self._iteration(loss, opt, env)
                state = self._save(loss, opt, rng.state(), env._rng.bit_generator.state, env.cursor)
                team, (f, final_xy) = self._scored(state, best, evaluate, generation + t + 1, score_before)
                best = state.best
                observer.accepted(generation + t + 1, team, f, f != score_before, final_xy)
                score[t] = state.score = score_before = f
        return state, {"score": score}

    # ---- one iteration -----------------------------------------------------------------------------------------
    def _iteration(self, loss, opt, env) -> None:
        """Collect ``n_steps`` steps of every environment with the sampling policy, then the PPO update."""
        data = self._collect(loss.actor_network, env)             # [B, T]
        with torch.no_grad():
            loss.value_estimator(data, params=loss.critic_network_params,
                                 target_params=loss.target_critic_network_params)
        flat = data.reshape(-1)
        size = flat.shape[0] // self.minibatches
        params = [p for g in opt.param_groups for p in g["params"]]
        for _ in range(self.n_epochs):
            order = torch.randperm(flat.shape[0])
            for i in range(self.minibatches):
                out = loss(flat[order[i * size:(i + 1) * size]])
                total = out["loss_objective"] + out["loss_critic"] + out.get("loss_entropy", 0.0)
                opt.zero_grad()
                total.backward()
                torch.nn.utils.clip_grad_norm_(params, self.max_grad_norm)
                opt.step()

    def _collect(self, actor, env: VectorEnv) -> TensorDict:
        """``n_steps`` steps of B environments: a TensorDict [B, T] with the agents' entries (B, T, N, ...)."""
        b, n = env.num_envs, env.n_agents
        obs, _ = env.reset()
        steps = []
        for _ in range(self.n_steps):
            td = TensorDict({A: _agents(obs, b, n)}, batch_size=[b])
            with torch.no_grad(), set_exploration_type(ExplorationType.RANDOM):   # sampled (the default: its mode)
                actor(td)
            nxt, rew, term, _, infos = env.step(td[A, "action"].numpy())
            nd = _agents(infos.get("final_obs", nxt), b, n)              # the episodes' last observations
            flags = torch.from_numpy(term).unsqueeze(-1)
            nd.update({"reward": torch.from_numpy(rew.astype(np.float32)).unsqueeze(-1), "done": flags.clone(),
                       "terminated": flags})
            td["next"] = TensorDict({A: nd}, batch_size=[b])
            steps.append(td)
            obs = nxt
        return torch.stack(steps, dim=1)

    # ---- the state as arrays -----------------------------------------------------------------------------------
    def _save(self, loss, opt, torch_state, env_rng, cursor: int = 0) -> MARLState:
        named = dict(loss.named_parameters())
        adam = adam_arrays(named, opt.state if opt is not None else {})
        return MARLState(params={k: v.detach().numpy().copy() for k, v in named.items()}, adam=adam,
                         torch=torch_state, env_rng=env_rng, cursor=int(cursor), score=0.0)

    def _load(self, loss, state) -> torch.optim.Adam:
        named = dict(loss.named_parameters())
        if set(named) != set(state.params):
            raise errors.ConfigError("algorithm", type(self).__name__, "the checkpoint's networks are not this "
                                     "configuration's (another torchrl version or other settings)")
        with torch.no_grad():
            for name, param in named.items():
                param.copy_(torch.from_numpy(np.array(state.params[name])))
        opt = torch.optim.Adam(list(named.values()), lr=self.lr, eps=1e-5)
        load_adam(named, opt.state, state.adam)
        return opt


class IPPO(MAPPO):
    """MAPPO's settings with a decentralised critic (each rover's value from its own observation): independent
    learners with parameter sharing (``conf/algorithm/ippo.yaml``)."""

    centralised = False


def _agents(obs: np.ndarray, b: int, n: int) -> TensorDict:
    """The agents' entries of one step: ``observation`` (B, N, D+1) (the critic's: sensors and t / T) and
    ``sensors`` (B, N, D) (the actor's)."""
    o = torch.from_numpy(np.asarray(obs, np.float32))
    return TensorDict({"observation": o, "sensors": o[..., :-1]}, batch_size=[b, n])

