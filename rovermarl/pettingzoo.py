"""The rover world as a PettingZoo environment, for any learner (RLlib, BenchMARL, TorchRL, CleanRL-style scripts).

==================== ===========================================================================================
Import               ``from rovermarl.pettingzoo import parallel_env, env`` (the parallel API; AEC through it)
Agents               ``rover_0`` ... ``rover_{N-1}`` (N = ``env.n_rovers``, 4 by default)
Actions              ``Box(-1, 1, (2,))`` in ``env.dtype``: ``(a0, a1)`` (speed, turn; SPEC section 3), clipped to it
Observations         ``Box`` (3P + 2N,) in ``env.dtype``: 38 in every paper setup (SPEC section 2); with
                     ``time_feature=True`` the step t / T as a last number (39); distances / sensor range in
                     [0, 1], bearings / pi in [-1, 1], POI types
State                ``state()`` (``state_space``): every rover's x, y, cos and sin of its heading, t / T, and the
                     episode's layout (a world plug-in's); float64
Episode              ``env.steps`` (15) steps (``max_cycles`` sets it), then every agent is terminated
Reward               the team's, the same for every agent (SPEC section 1, ``env.reward``): ``final`` pays the team
                     return at the last step and 0 before; a per-step reading pays the growth of its running value
                     (``mean_step``: each step's return / T), so the rewards sum to the episode's return
==================== ===========================================================================================

Termination, not truncation, at the horizon: the task is finite by definition (the paper scores the positions after
step T), so a learner must not bootstrap a value beyond it. With ``time_feature=True`` the episode is Markov.

This is the one-environment view of :class:`rovermarl.vector.VectorEnv` (B = 1, no auto-reset): its step, reward,
observation bounds and seeds are that env's (the rollout's compiled hooks), for any world (``RoverParallelEnv(world)``;
``parallel_env`` builds one as :func:`rovermarl.make_world` does). ``reset(seed=s)`` (an integer >= 0, else a
``ValueError``) starts from ``World.initial_conditions(seed=s, n=1)`` (``World.rollout`` replays the episode);
``reset()`` draws the next start of that stream. ``infos[agent]``: ``occupancy`` (P,) rovers within the observation
radius of each POI, ``return`` the team's return so far (after the last step bit-identical to ``World.returns``) and
``step``. docs/GUIDE.md ("For RL users") has a tested example.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Mapping

import numpy as np

try:
    from gymnasium import spaces
    from pettingzoo import ParallelEnv
    from pettingzoo.utils.conversions import parallel_to_aec_wrapper
    from pettingzoo.utils.wrappers import OrderEnforcingWrapper
except ModuleNotFoundError as e:                       # an optional extra: say how to get it
    raise ModuleNotFoundError(f"rovermarl.pettingzoo needs {e.name}: pip install 'rovermarl[pettingzoo]'",
                              name=e.name) from None

from rovermarl.env import World, kernel, make_world
from rovermarl.env.streams import env_seed
from rovermarl.vector import VectorEnv

ACTION_LOW, ACTION_HIGH = -1.0, 1.0
ACTION_RULE = f"an action is 2 finite real numbers (speed, turn), clipped to [{ACTION_LOW:g}, {ACTION_HIGH:g}]"


def parallel_env(setup: str = "solo", render_mode: str | None = None, max_cycles: int | None = None,
                 time_feature: bool = False, **overrides) -> RoverParallelEnv:
    """The parallel environment of ``setup`` with World field ``overrides`` (e.g. ``reward="any_step"``);
    ``max_cycles``: the episode's steps (``env.steps``, PettingZoo's name for the horizon)."""
    if max_cycles is not None:
        if "steps" in overrides and overrides["steps"] != max_cycles:
            raise ValueError(f"max_cycles={max_cycles!r} and steps={overrides['steps']!r}: both set the horizon")
        overrides["steps"] = max_cycles
    return RoverParallelEnv(make_world(setup, **overrides), render_mode=render_mode, time_feature=time_feature)


def env(setup: str = "solo", render_mode: str | None = None, max_cycles: int | None = None,
        time_feature: bool = False, **overrides):
    """The AEC environment: :func:`parallel_env` through PettingZoo's ``parallel_to_aec`` (its wrapper, and the
    order-enforcing one), refusing a bad action at the agent's own step."""
    return OrderEnforcingWrapper(_RoverAEC(parallel_env(setup, render_mode, max_cycles, time_feature, **overrides)))


class _RoverAEC(parallel_to_aec_wrapper):
    """PettingZoo's ``parallel_to_aec_wrapper`` that checks each live agent's action when it is given, before the
    wrapper stores it (else a bad action would surface only at the last agent's step, the turn state moved on)."""

    def step(self, action):
        agent = self.agent_selection
        if not (self.terminations[agent] or self.truncations[agent]):
            self.env.check_action(agent, action)
        super().step(action)


class RoverParallelEnv(ParallelEnv):
    """One episode of one rover team at a time, on a :class:`~rovermarl.env.World`."""

    metadata = {"name": "rovermarl_rovers_v0", "render_modes": ["human", "rgb_array"], "is_parallelizable": True,
                "render_fps": 4}

    def __init__(self, world: World, render_mode: str | None = None, time_feature: bool = False):
        if render_mode not in (None, "human", "rgb_array"):
            raise ValueError(f"render_mode must be None, 'human' or 'rgb_array', got {render_mode!r}")
        self.world, self.render_mode, self.time_feature = world, render_mode, bool(time_feature)
        self.env = VectorEnv(1, world=world, time_feature=time_feature, autoreset=False)   # the one step
        self.possible_agents = [f"rover_{i}" for i in range(world.n_rovers)]
        self.agents: list[str] = []
        self._window, self._warned = None, False                        # human rendering's
        n_state = 4 * world.n_rovers + 1 + world.layout_dim
        self.state_space = spaces.Box(-np.inf, np.inf, (n_state,), dtype=np.float64)
        f = self._f = self.env.dtype.type                                 # env.dtype: the kernel's precision
        self._obs_space = spaces.Box(self.env.obs_low, self.env.obs_high, dtype=f)
        self._act_space = spaces.Box(ACTION_LOW, ACTION_HIGH, (2,), dtype=f)

    def observation_space(self, agent: str) -> spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> spaces.Box:
        return self._act_space

    @property
    def xy(self) -> np.ndarray:
        """(1, N, 2): the rovers' positions now, in ``env.dtype``."""
        return self.env.xy

    @property
    def heading(self) -> np.ndarray:
        """(1, N): the rovers' headings now."""
        return self.env.heading

    @property
    def t(self) -> int:
        return self.env.t

    @property
    def value(self) -> float:
        """The team's return so far in the world's reading (after the last step: the episode's return)."""
        return float(self.env.value[0])

    # ---- episode ---------------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None, options: dict | None = None):
        """Start an episode: from ``World.initial_conditions(seed=seed, n=1)``, or the next start of the stream of
        the last seed. Returns observations and infos per agent. ``seed``: None or an integer >= 0."""
        obs, _ = self.env.reset(seed=None if seed is None else env_seed(seed))
        w = self.world
        self.layout = self.env.layout[0]                                   # (K,): a world plug-in's
        self.path = np.empty((w.steps + 1, w.n_rovers, 2))
        self.path[0] = self.xy[0]
        self.agents = list(self.possible_agents)
        return self._per_agent(obs), self._infos()

    def step(self, actions: dict):
        """Move every rover by its action ``(a0, a1)`` (a missing agent's is (0, 0): straight on at half speed in
        the ``affine`` reading); returns observations, rewards, terminations, truncations and infos. An unknown agent
        or an action that is not 2 finite real numbers is refused (``ValueError`` naming the agent) before any state
        changes."""
        if not self.agents:
            raise RuntimeError("the episode is over: call reset()")
        if not isinstance(actions, Mapping):
            raise ValueError(f"actions must be a dict of agent -> action, got {type(actions).__name__}")
        for key in actions:
            if key not in self.possible_agents:
                p = self.possible_agents
                names = ", ".join(p) if len(p) <= 4 else f"{p[0]} ... {p[-1]}"
                raise ValueError(f"actions[{key!r}]: no such agent; the agents are {names}")
        a = np.zeros((1, self.world.n_rovers, 2), self._f)
        for i, agent in enumerate(self.possible_agents):
            if agent in actions:
                a[0, i] = self.check_action(agent, actions[agent])
        obs, rewards, terminated, _, _ = self.env.step(a)
        self.path[self.t] = self.xy[0]
        reward, done = float(rewards[0, 0]), bool(terminated[0, 0])
        agents = self.agents
        out = (self._per_agent(obs), dict.fromkeys(agents, reward), dict.fromkeys(agents, done),
               dict.fromkeys(agents, False), self._infos())                    # terminated at the horizon: see above
        if done:
            self.agents = []
        return out

    def check_action(self, agent: str, action) -> np.ndarray:
        """``action`` of ``agent`` as a (2,) array in ``env.dtype``, clipped to the action box; ``ValueError`` naming
        the agent, what is wrong and what is allowed when it is not 2 finite real numbers."""
        def refuse(problem: str):
            return ValueError(f"actions[{agent!r}] {problem}: {ACTION_RULE}")

        if action is None:
            raise refuse("is None")
        try:
            x = np.asarray(action)
        except (TypeError, ValueError):                 # e.g. a ragged list
            raise refuse(f"is not an array of numbers ({_show(action)})") from None
        if x.dtype.kind == "c":
            raise refuse(f"is complex ({_show(x)})")
        if x.dtype.kind not in "iuf":                   # bool, str, object, ...
            raise refuse(f"is not real numbers (dtype {x.dtype}: {_show(x)})")
        if x.shape != (2,):
            raise refuse(f"has shape {x.shape}, not (2,)")
        if not np.isfinite(x).all():
            raise refuse(f"is not finite ({_show(x)})")
        return np.clip(x.astype(np.float64), ACTION_LOW, ACTION_HIGH).astype(self._f)

    def _per_agent(self, obs: np.ndarray) -> dict:
        """Observations (1, N, D) as a dict of agent -> (D,)."""
        return {agent: obs[0, i].copy() for i, agent in enumerate(self.possible_agents)}

    def _infos(self) -> dict:
        w = self.world
        count = np.zeros((1, w.n_pois), np.int64)
        track = w.poi_track(self.layout)                                   # POIs that move: where they are now
        pois = w.poi_positions(self.layout) if track is None else np.ascontiguousarray(track[self.t])
        kernel.observers(self.xy.astype(np.float64), pois, w.kernel.obs_radius, count)
        info = {"occupancy": count[0], "return": self.value, "step": self.t}
        return {agent: dict(info) for agent in self.possible_agents}

    def state(self) -> np.ndarray:
        """The global state (for a centralised critic): every rover's x, y, cos and sin of its heading, then t / T,
        then the episode's layout (K,): float64 (``state_space``)."""
        h = self.heading[0].astype(np.float64)
        rovers = np.stack([*self.xy[0].astype(np.float64).T, np.cos(h), np.sin(h)], axis=1).ravel()
        return np.concatenate([rovers, [self.t / self.world.steps], self.layout])

    # ---- drawing ---------------------------------------------------------------------------------------------
    def render(self):
        """``rgb_array``: an (H, W, 3) uint8 image of the POIs and the rovers' paths so far; ``human``: the same in a
        window (None), where there is a display."""
        if self.render_mode is None:
            return None
        if self.render_mode == "human":
            return self._window_show()
        from rovermarl.analysis.draw import new_figure, scene
        fig = new_figure(4.0, 4.0)
        ax = fig.add_subplot()
        lim = self.world.poi_distance + 2 * self.world.obs_radius
        scene(ax, self.world, self.path[None, : self.t + 1], lim, lw=1.5, ms=6, layout=self.layout)
        ax.set_title(f"step {self.t}/{self.world.steps}   return {self.value:g}", fontsize=9)
        fig.canvas.draw()
        return np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()

    def _window_show(self) -> None:
        """The ``rgb_array`` image in a matplotlib window; without a display one warning, then nothing."""
        if not _display():
            if not self._warned:
                warnings.warn("render_mode='human': no display here (no DISPLAY or WAYLAND_DISPLAY); nothing is shown."
                              " Use render_mode='rgb_array' for images", stacklevel=2)
                self._warned = True
            return None
        import matplotlib.pyplot as plt
        self.render_mode = "rgb_array"
        try:
            image = self.render()
        finally:
            self.render_mode = "human"
        if self._window is None:
            self._window = plt.figure("rovermarl").add_subplot()
        self._window.clear()
        self._window.imshow(image)
        self._window.axis("off")
        plt.pause(1.0 / self.metadata["render_fps"])

    def close(self):
        if self._window is not None:
            import matplotlib.pyplot as plt
            plt.close(self._window.figure)
            self._window = None


def _display() -> bool:
    """Whether a window can be shown: a display on Linux, any desktop on macOS and Windows."""
    return sys.platform in ("darwin", "win32") or bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def _show(value, width: int = 60) -> str:
    """``value`` on one short line, for an error message."""
    text = (np.array2string(value, separator=", ", threshold=8, max_line_width=10**6) if isinstance(value, np.ndarray)
            else repr(value))
    text = " ".join(text.split())
    return text if len(text) <= width else text[:width - 3] + "..."


def genome_policy(world: World, genomes: np.ndarray):
    """Actions of a team of genomes (N, P) through the world's MLP (the rollout's compiled ``act``): a function of
    an observation dict, returning an action dict (bit-identical to what :meth:`World.rollout` does)."""
    genomes = np.ascontiguousarray(genomes, dtype=world.dtype)
    agents = [f"rover_{i}" for i in range(world.n_rovers)]

    def policy(observations: dict) -> dict:
        obs = np.stack([observations[a] for a in agents])[None].astype(world.dtype)   # (1, N, D)
        out = np.empty((1, world.n_rovers, 2), world.dtype)
        kernel.act(genomes, np.ascontiguousarray(obs), world.policy.hidden, out)
        return {a: out[0, i] for i, a in enumerate(agents)}

    return policy
