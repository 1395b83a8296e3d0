"""The world as a batched environment for learners: B environments x N agents stepped in one compiled call.

:class:`VectorEnv` steps B environments of one world (any world plug-in: ``VectorEnv(world=...)``) in one compiled
call (:func:`rovermarl.env.kernel.fused.env_step`, the rollout's own hooks), so a policy and initial conditions give
the returns :meth:`World.returns` gives. Its observations (B, N, D), actions (B, N, 2) (speed, turn; clipped to
[-1, 1]), rewards, terminations and truncations (B, N) are the PettingZoo env's (:mod:`rovermarl.pettingzoo`: the
team's reward for every agent, every agent terminated after ``env.steps``, never truncated), batched; with
``time_feature=True`` (the default) the step t / T is the last observation (D = 39 in the paper's world). Auto-reset
is same-step: the step that terminates returns the next episodes' first observations, the last ones in
``infos["final_obs"]`` and the episodes' returns in ``infos["final_return"]`` (``autoreset=False``: the episodes stay
over until ``reset()``). :data:`DEFAULTS` is one set for every view: B = 256 environments of ``setup="solo"``, with
the time feature.

``reset(seed=s)`` draws the B starts from ``World.initial_conditions(SeedSequence(s), n=B)``, later resets and
auto-resets continuing that stream (:mod:`rovermarl.env.streams`); B seeds give environment b the stream of
``SeedSequence(seed[b])``; ``options={"ic": ic}`` starts from given initial conditions (e.g. ``World.run_ic``).
``starts=ic`` (E initial conditions, e.g. a run's 16) makes every reset take its B starts from them in turn,
environment b of the c-th draw taking start ``(c * B + b) mod E`` (:attr:`cursor` counts the starts taken): how PPO
trains on a run's fixed initial conditions. :class:`GymVectorEnv` is the Gymnasium view with the agents flattened
(B*N sub-environments sharing one policy, as SuperSuit's parameter sharing) for single-agent libraries; docs/GUIDE.md
("For RL users") has tested examples.
"""

from __future__ import annotations

import numpy as np

from rovermarl.env import World, make_world
from rovermarl.env.streams import env_stream
from rovermarl.jit import say_if_cold

DEFAULTS = {"num_envs": 256, "setup": "solo", "time_feature": True}   # VectorEnv's and GymVectorEnv's, one set


class VectorEnv:
    """B environments of one world (``world``, else ``make_world(setup, **overrides)``), stepped together."""

    def __init__(self, num_envs: int = DEFAULTS["num_envs"], setup: str = DEFAULTS["setup"], world: World | None = None,
                 time_feature: bool = DEFAULTS["time_feature"], autoreset: bool = True, starts: tuple | None = None,
                 **overrides):
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs={num_envs!r}: must be an integer >= 1")
        self.world = world if world is not None else make_world(setup, **overrides)
        self.num_envs, self.n_agents = int(num_envs), self.world.n_rovers
        self.time_feature, self.autoreset = bool(time_feature), bool(autoreset)
        self.obs_dim = self.world.obs_dim + self.time_feature
        self.dtype = np.dtype(self.world.dtype)
        low, high = (np.concatenate([b[i] for b in self.world.obs_blocks()]) for i in (1, 2))   # the bounds' home
        if self.time_feature:
            low, high = np.append(low, 0.0), np.append(high, 1.0)
        self.obs_low, self.obs_high = low.astype(self.dtype), high.astype(self.dtype)   # (D,) each
        self._compiled = self.world.compiled
        self._rng, self._rngs = np.random.default_rng(), None
        self.starts, self.cursor = None, 0
        if starts is not None:
            self.starts = tuple(np.asarray(a) for a in starts)    # E initial conditions, taken in turn
            e = len(self.starts[1])
            if e < 1 or self.starts[1].shape != (e, self.n_agents):
                raise ValueError(f"starts: heading has shape {self.starts[1].shape}, expected (E, {self.n_agents})")
        self.t, self.over = 0, True

    # ---- episodes ------------------------------------------------------------------------------------------------
    def reset(self, seed=None, options: dict | None = None):
        """Start B episodes; returns observations (B, N, D) and infos. ``seed``: None, an integer >= 0, or B of them;
        ``options={"ic": ic}``: start from these B initial conditions."""
        w, b = self.world, self.num_envs
        if options and "ic" in options:
            ic = tuple(np.asarray(a) for a in options["ic"])
            if ic[1].shape != (b, self.n_agents):
                raise ValueError(f"options['ic']: heading has shape {ic[1].shape}, expected ({b}, {self.n_agents})")
        else:
            self._seed(seed)
            ic = self._draw()
        xy, heading, self._k = w.kernel_args(ic)                     # checked, in env.dtype, the layout's kernel
        self.xy, self.heading = np.array(xy), np.array(heading)     # (B, N, 2), (B, N): stepped in place
        self.layout = np.asarray(ic[2], np.float64) if len(ic) > 2 else np.empty((b, 0))   # (B, K)
        self._acc = self._compiled.env_start(self._k, b)
        self._s = self._compiled.state_of(self.xy, self._k)        # the world's state (World.state): this env's own
        self.value = np.zeros(b)                                     # (B,): each episode's return so far
        self.t, self.over = 0, False
        obs = np.empty((b, self.n_agents, w.obs_dim), self.dtype)
        say_if_cold(self._compiled.observe, (self.xy, self.heading, self._k, self._s, obs),
                    "the environment's functions")
        self._compiled.observe(self.xy, self.heading, self._k, self._s, obs)
        return self._with_time(obs), {"step": 0}

    def step(self, actions: np.ndarray):
        """Move every rover of every environment by its action ``(a0, a1)`` (actions (B, N, 2), clipped to [-1, 1]).
        Returns observations (B, N, D), rewards (B, N), terminations (B, N) (all at the horizon), truncations
        (B, N) (never) and infos (``return`` (B,): each episode's return so far)."""
        if self.over:
            raise RuntimeError("the episodes are over: call reset()")
        a = np.asarray(actions)
        if a.shape != (self.num_envs, self.n_agents, 2):
            raise ValueError(f"actions have shape {a.shape}, expected ({self.num_envs}, {self.n_agents}, 2)")
        if not np.isfinite(a).all():
            raise ValueError("actions are not all finite numbers: an action is 2 finite numbers (speed, turn)")
        a = np.clip(a, -1.0, 1.0).astype(self.dtype)
        w, b, n = self.world, self.num_envs, self.n_agents
        before = self.value.copy()
        obs = np.empty((b, n, w.obs_dim), self.dtype)
        args = (self.xy, self.heading, a, self._k, self._s, self._acc, self.value, obs)
        say_if_cold(self._compiled.env_step, args, "the environment's functions")
        self._compiled.env_step(*args)
        self.t += 1
        done = self.t == w.steps
        if self._compiled.stepwise(self._k):
            reward = self.value - before
        else:
            reward = self.value if done else np.zeros(b)
        rewards = np.repeat(reward[:, None], n, axis=1)
        terminated = np.full((b, n), done)
        infos = {"step": self.t, "return": self.value.copy()}
        obs = self._with_time(obs)
        if done and self.autoreset:                            # same-step auto-reset
            infos.update(final_obs=obs, final_return=self.value.copy())
            obs, _ = self.reset(options={"ic": self._draw()})
        elif done:
            self.over = True
        return obs, rewards, terminated, np.zeros((b, n), bool), infos

    # ---- helpers ---------------------------------------------------------------------------------------------
    def _with_time(self, obs: np.ndarray) -> np.ndarray:
        if not self.time_feature:
            return obs
        t = np.full(obs.shape[:2] + (1,), self.t / self.world.steps, self.dtype)
        return np.concatenate([obs, t], axis=2)

    def _seed(self, seed) -> None:
        if seed is None:
            return
        if np.ndim(seed) == 0:
            self._rng, self._rngs = env_stream(seed), None
            return
        streams = [env_stream(s) for s in seed]
        if len(streams) != self.num_envs:
            raise ValueError(f"seed: {len(streams)} seeds for {self.num_envs} environments")
        self._rngs = streams

    def _draw(self):
        """B starts: the next B of :attr:`starts` in turn, one draw from the batch's stream, or one per environment
        from its own."""
        if self.starts is not None:
            take = (self.cursor + np.arange(self.num_envs)) % len(self.starts[1])
            self.cursor += self.num_envs
            return tuple(a[take] for a in self.starts)
        if self._rngs is None:
            return self.world.initial_conditions(self._rng, n=self.num_envs)
        parts = [self.world.initial_conditions(r, n=1) for r in self._rngs]
        return tuple(np.concatenate(p) for p in zip(*parts, strict=True))


try:                                        # the Gymnasium view needs gymnasium (rovermarl[pettingzoo] has it)
    import gymnasium
    from gymnasium.vector import AutoresetMode
except ModuleNotFoundError:                 # pragma: no cover - VectorEnv itself needs only numpy
    gymnasium = None


if gymnasium is not None:
    class GymVectorEnv(gymnasium.vector.VectorEnv):
        """A Gymnasium ``VectorEnv`` of B*N single-agent sub-environments: agent i of environment b is
        sub-environment ``b*N + i`` (parameter sharing). Observations (B*N, D), actions (B*N, 2), rewards,
        terminations, truncations (B*N,). Auto-reset is Gymnasium's default, next-step: the step that ends the
        episodes returns their last observations; the next step ignores its actions and returns the next episodes'
        first observations, rewards 0 and no termination (what Gymnasium's wrappers expect)."""

        metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP}

        def __init__(self, num_envs: int = DEFAULTS["num_envs"], setup: str = DEFAULTS["setup"],
                     world: World | None = None, time_feature: bool = DEFAULTS["time_feature"], **overrides):
            self.env = VectorEnv(num_envs, setup, world, time_feature, autoreset=False, **overrides)
            e = self.env
            self.num_envs = e.num_envs * e.n_agents
            self.single_observation_space = gymnasium.spaces.Box(e.obs_low, e.obs_high, dtype=e.dtype)
            self.single_action_space = gymnasium.spaces.Box(-1.0, 1.0, (2,), dtype=e.dtype)
            self.observation_space = gymnasium.vector.utils.batch_space(self.single_observation_space, self.num_envs)
            self.action_space = gymnasium.vector.utils.batch_space(self.single_action_space, self.num_envs)

        def reset(self, *, seed=None, options=None):
            obs, infos = self.env.reset(seed=seed, options=options)
            return obs.reshape(self.num_envs, -1), infos

        def step(self, actions):
            e = self.env
            if e.over:                                      # next-step auto-reset: the actions are ignored
                obs, infos = e.reset()
                no = np.zeros(self.num_envs, bool)
                return obs.reshape(self.num_envs, -1), np.zeros(self.num_envs), no, no.copy(), infos
            obs, rew, term, trunc, infos = e.step(np.asarray(actions).reshape(e.num_envs, e.n_agents, 2))
            return (obs.reshape(self.num_envs, -1), rew.reshape(-1), term.reshape(-1), trunc.reshape(-1), infos)
