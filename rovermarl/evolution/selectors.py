"""k-selectors: how many rovers to mutate each generation. Built from ``conf/k/*.yaml`` with
``hydra.utils.instantiate(cfg.k, n_agents=N, f_max=F_max)``.

A selector subclasses :class:`KSelector`: it sets ``arms`` (the k values it may return), implements
:meth:`choose`, and may learn in :meth:`update` and expose ``probs`` (one per arm) for recording.
"""

from __future__ import annotations

import numpy as np

from rovermarl import errors


class KSelector:
    """Base class. ``n_agents`` is N; ``f_max`` the best achievable score (for normalised rewards)."""

    arms: tuple[int, ...] = ()

    def __init__(self, n_agents: int, f_max: float = 1.0):
        self.n_agents = n_agents
        self.f_max = f_max

    @property
    def probs(self) -> np.ndarray | None:
        """Current probability of each arm (K,), or None for selectors without one."""
        return None

    def choose(self, rng: np.random.Generator) -> int:
        """The k of this generation."""
        raise NotImplementedError

    def update(self, k: int, f_child: float, f_parent: float) -> None:
        """Feedback after the generation that used ``k``."""

    def state_dict(self) -> dict:
        return {}

    def load_state_dict(self, state: dict) -> None:
        pass

    def _arms(self, arms) -> tuple[int, ...]:
        """Validated arm list; ``None`` means 1..N."""
        if arms is None:
            return tuple(range(1, self.n_agents + 1))
        arms = list(arms) if not isinstance(arms, (str, int)) else [arms]
        if not arms or len(set(arms)) != len(arms):
            raise errors.ConfigError("arms", arms, f"must be a non-empty list of distinct k in 1..{self.n_agents}")
        for a in arms:
            if isinstance(a, bool) or not isinstance(a, int) or not 1 <= a <= self.n_agents:
                raise errors.ConfigError("arms", arms, f"every k must be an integer in 1..{self.n_agents} "
                                                       f"(env.n_rovers={self.n_agents})")
        return tuple(arms)


class FixedK(KSelector):
    """Always the same k."""

    def __init__(self, value: int, n_agents: int, f_max: float = 1.0):
        super().__init__(n_agents, f_max)
        self.value = errors.integer("value", value, 1, n_agents)
        self.arms = (self.value,)

    def choose(self, rng):
        return self.value


class EXP3(KSelector):
    """EXP3 (Auer et al. 2002) over the arms, with weights kept in log space.

    ``p_i = (1 - gamma) w_i / sum(w) + gamma / K``; the pulled arm's weight is multiplied by
    ``exp(gamma * (x / p_i) / K)``, with ``x = 1`` if ``f_child > f_parent`` else 0 (``reward=improved``)
    or ``x = max(0, f_child - f_parent) / f_max`` (``reward=gain``).
    """

    def __init__(self, n_agents: int, f_max: float = 1.0, gamma: float = 0.1, arms=None,
                 reward: str = "improved"):
        super().__init__(n_agents, f_max)
        self.gamma = errors.number("gamma", gamma, 0, 1, lo_open=True)
        self.arms = self._arms(arms)
        self.reward = errors.choice("reward", reward, ("improved", "gain"))
        self.log_w = np.zeros(len(self.arms))
        self._probs = self._compute_probs()

    @property
    def probs(self):
        return self._probs

    def _compute_probs(self) -> np.ndarray:
        w = np.exp(self.log_w - self.log_w.max())
        return (1.0 - self.gamma) * w / w.sum() + self.gamma / len(self.arms)

    def choose(self, rng):
        cdf = np.cumsum(self._probs)
        a = int(np.searchsorted(cdf, rng.random() * cdf[-1], side="right"))
        return self.arms[min(a, len(self.arms) - 1)]

    def update(self, k, f_child, f_parent):
        if self.reward == "improved":
            x = 1.0 if f_child > f_parent else 0.0
        else:
            x = max(0.0, f_child - f_parent) / self.f_max
        a = self.arms.index(k)
        self.log_w[a] += self.gamma * (x / self._probs[a]) / len(self.arms)
        self.log_w -= self.log_w.max()
        self._probs = self._compute_probs()

    def state_dict(self):
        return {"log_w": self.log_w.copy()}

    def load_state_dict(self, state):
        self.log_w = np.array(state["log_w"], dtype=np.float64)
        self._probs = self._compute_probs()
