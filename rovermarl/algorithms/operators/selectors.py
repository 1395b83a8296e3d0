"""k-selectors: how many rovers to mutate each generation, built from ``conf/k/*.yaml`` with ``n_agents=N`` and
``f_max=F_max``. A selector subclasses :class:`KSelector`: it sets ``arms`` (the k values it may return), implements
:meth:`~KSelector.choose`, and may learn in ``update`` and expose ``probs`` (one per arm) for recording."""

from __future__ import annotations

import copy
import math

import numpy as np

from rovermarl import errors
from rovermarl.env.kernel import pairwise_sum
from rovermarl.jit import njit


class KSelector:
    """Base class. ``n_agents`` is N; ``f_max`` the best achievable score (for normalised rewards)."""

    arms: tuple[int, ...] = ()
    reward_rule = "improved"  # see :meth:`reward`

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
        """What the selector has learned, checkpointed with the run. By default every attribute (a copy), so a
        selector that learns in plain attributes resumes bit-identically without writing this; override both
        methods to store less."""
        return {name: copy.deepcopy(value) for name, value in vars(self).items()}

    def load_state_dict(self, state: dict) -> None:
        """Restore :meth:`state_dict` (after a checkpoint's JSON round trip: lists back to the type they had)."""
        for name, value in state.items():
            now = getattr(self, name, None)
            if isinstance(now, np.ndarray):
                value = np.array(value, dtype=now.dtype)
            elif isinstance(now, tuple):
                value = tuple(value)
            setattr(self, name, copy.deepcopy(value))

    def _reward_rule(self, reward: str) -> str:
        return errors.choice("reward", reward, ("improved", "gain"))

    def reward(self, f_child: float, f_parent: float) -> float:
        """The bandit reward of a generation by :attr:`reward_rule` (:func:`bandit_reward`)."""
        return bandit_reward(f_child, f_parent, self.reward_rule == "gain", self.f_max)

    def _draw(self, probs: np.ndarray, rng: np.random.Generator) -> int:
        """An arm drawn with probabilities ``probs`` (K,), from one uniform number."""
        return self.arms[draw_arm(probs, rng.random())]

    def _arms(self, arms) -> tuple[int, ...]:
        """Validated arm list; ``None`` means 1..N."""
        if arms is None:
            return tuple(range(1, self.n_agents + 1))
        arms = list(arms) if not isinstance(arms, (str, int)) else [arms]
        if not arms or len(set(arms)) != len(arms):
            raise errors.ConfigError("arms", arms, f"must be a non-empty list of distinct k in 1..{self.n_agents}")
        if any(isinstance(a, bool) or not isinstance(a, int) or not 1 <= a <= self.n_agents for a in arms):
            raise errors.ConfigError("arms", arms, f"every k must be an integer in 1..{self.n_agents} "
                                                   f"(env.n_rovers={self.n_agents})")
        return tuple(arms)


class FixedK(KSelector):
    """Always the same k."""

    def __init__(self, value: int, n_agents: int, f_max: float = 1.0):
        super().__init__(n_agents, f_max)
        self.value = errors.integer("value", value, 1, n_agents, f"k cannot mutate more rovers than "
                                    f"env.n_rovers={n_agents}")
        self.arms = (self.value,)

    def choose(self, rng):
        return self.value


class EXP3(KSelector):
    """EXP3 (Auer et al. 2002) over the arms, with weights kept in log space: ``p_i = (1 - gamma) w_i / sum(w) +
    gamma / K``; the pulled arm's weight is multiplied by ``exp(gamma * (x / p_i) / K)``, ``x`` the bandit
    :meth:`~KSelector.reward`."""

    def __init__(self, n_agents: int, f_max: float = 1.0, gamma: float = 0.1, arms=None,
                 reward: str = "improved"):
        super().__init__(n_agents, f_max)
        self.gamma = errors.number("gamma", gamma, 0, 1, lo_open=True)
        self.arms = self._arms(arms)
        self.reward_rule = self._reward_rule(reward)
        self.log_w = np.zeros(len(self.arms))
        self._probs = self._compute_probs()

    @property
    def probs(self):
        return self._probs

    def _compute_probs(self) -> np.ndarray:
        out = np.empty(len(self.arms))
        exp3_probs(self.log_w, self.gamma, out)
        return out

    def choose(self, rng):
        return self._draw(self._probs, rng)

    def update(self, k, f_child, f_parent):
        probs = np.empty(len(self.arms))
        exp3_update(self.log_w, self._probs, self.arms.index(k), self.reward(f_child, f_parent), self.gamma, probs)
        self._probs = probs

    def state_dict(self):
        return {"log_w": self.log_w.copy()}

    def load_state_dict(self, state):
        self.log_w = np.array(state["log_w"], dtype=np.float64)
        self._probs = self._compute_probs()


class MeanReward(KSelector):
    """Base of selectors that keep each arm's pull count and reward sum, ``counts`` and ``sums`` (K,)."""

    def __init__(self, n_agents: int, f_max: float = 1.0, arms=None, reward: str = "improved"):
        super().__init__(n_agents, f_max)
        self.arms = self._arms(arms)
        self.reward_rule = self._reward_rule(reward)
        self.counts = np.zeros(len(self.arms))
        self.sums = np.zeros(len(self.arms))

    def update(self, k, f_child, f_parent):
        a = self.arms.index(k)
        self.counts[a] += 1
        self.sums[a] += self.reward(f_child, f_parent)

    def state_dict(self):
        return {"counts": self.counts.copy(), "sums": self.sums.copy()}

    def load_state_dict(self, state):
        self.counts = np.array(state["counts"], dtype=np.float64)
        self.sums = np.array(state["sums"], dtype=np.float64)


class UCB1(MeanReward):
    """UCB1 (Auer, Cesa-Bianchi and Fischer 2002): each arm once, then the arm with the highest
    ``mean_a + c * sqrt(2 ln t / n_a)`` (ties: the first arm). Deterministic given the rewards."""

    def __init__(self, n_agents: int, f_max: float = 1.0, c: float = 1.0, arms=None, reward: str = "improved"):
        super().__init__(n_agents, f_max, arms, reward)
        self.c = errors.number("c", c, 0)

    def choose(self, rng):
        untried = np.flatnonzero(self.counts == 0)
        if untried.size:
            return self.arms[untried[0]]
        bonus = self.c * np.sqrt(2.0 * np.log(self.counts.sum()) / self.counts)
        return self.arms[int(np.argmax(self.sums / self.counts + bonus))]


class Thompson(KSelector):
    """Thompson sampling, Beta-Bernoulli on "improved": arm ``a`` has a ``Beta(alpha_a, beta_a)`` posterior on
    P(f_child > f_parent); each generation draws one sample per arm and plays the largest."""

    def __init__(self, n_agents: int, f_max: float = 1.0, alpha: float = 1.0, beta: float = 1.0, arms=None):
        super().__init__(n_agents, f_max)
        self.arms = self._arms(arms)
        self.alpha = np.full(len(self.arms), errors.number("alpha", alpha, 0, lo_open=True))
        self.beta = np.full(len(self.arms), errors.number("beta", beta, 0, lo_open=True))

    def choose(self, rng):
        return self.arms[int(np.argmax(rng.beta(self.alpha, self.beta)))]

    def update(self, k, f_child, f_parent):
        a = self.arms.index(k)
        improved = f_child > f_parent
        self.alpha[a] += improved
        self.beta[a] += not improved

    def state_dict(self):
        return {"alpha": self.alpha.copy(), "beta": self.beta.copy()}

    def load_state_dict(self, state):
        self.alpha = np.array(state["alpha"], dtype=np.float64)
        self.beta = np.array(state["beta"], dtype=np.float64)


class EpsilonGreedy(MeanReward):
    """Epsilon-greedy: with probability ``epsilon`` a uniform arm, else an arm of highest mean reward so far
    (untried arms count as ``initial``; ties share the greedy probability)."""

    def __init__(self, n_agents: int, f_max: float = 1.0, epsilon: float = 0.1, initial: float = 1.0, arms=None,
                 reward: str = "improved"):
        super().__init__(n_agents, f_max, arms, reward)
        self.epsilon = errors.number("epsilon", epsilon, 0, 1)
        self.initial = errors.number("initial", initial)

    @property
    def probs(self):
        means = np.where(self.counts > 0, self.sums / np.maximum(self.counts, 1), self.initial)
        greedy = means == means.max()
        return self.epsilon / len(self.arms) + (1 - self.epsilon) * greedy / greedy.sum()

    def choose(self, rng):
        return self._draw(self.probs, rng)


class EXP3S(EXP3):
    """EXP3.S (Auer et al. 2002, section 8), for a best k that changes during the run: after EXP3's update every
    weight also gets ``e * alpha / K`` of the total, so no arm's probability can stay negligible and the bandit
    can move to a new best arm within about ``1 / alpha`` generations. ``alpha = 0`` is EXP3."""

    def __init__(self, n_agents: int, f_max: float = 1.0, gamma: float = 0.1, alpha: float = 0.001, arms=None,
                 reward: str = "improved"):
        self.alpha = errors.number("alpha", alpha, 0, 1)
        super().__init__(n_agents, f_max, gamma, arms, reward)

    def update(self, k, f_child, f_parent):
        a = self.arms.index(k)
        w = np.exp(self.log_w - self.log_w.max())
        w /= w.sum()                                                     # weights as shares: never overflow
        w[a] *= np.exp(self.gamma * (self.reward(f_child, f_parent) / self._probs[a]) / len(self.arms))
        w += np.e * self.alpha / len(self.arms)
        self.log_w = np.log(w / w.max())
        self._probs = self._compute_probs()


class Schedule(KSelector):
    """A fixed schedule: k steps down from ``start`` (null: N) to ``end`` in equal stages over ``horizon``
    generations (by default the run's budget), then stays at ``end``. Many rovers explore early, one at a time
    refines late."""

    def __init__(self, n_agents: int, f_max: float = 1.0, horizon: int = 20000, start=None, end: int = 1):
        super().__init__(n_agents, f_max)
        self.horizon = errors.integer("horizon", horizon, 1)
        start = n_agents if start is None else start
        self.stages = tuple(range(errors.integer("start", start, 1, n_agents),
                                  errors.integer("end", end, 1, start) - 1, -1))
        self.arms = tuple(sorted(self.stages))
        self.t = 0

    def choose(self, rng):
        return self.stages[min(self.t * len(self.stages) // self.horizon, len(self.stages) - 1)]

    def update(self, k, f_child, f_parent):
        self.t += 1

    def state_dict(self):
        return {"t": self.t}

    def load_state_dict(self, state):
        self.t = int(state["t"])


# The numeric rules of the selectors that the compiled generation loop (rovermarl.algorithms.compiled) shares.
@njit(cache=True)
def bandit_reward(f_child, f_parent, gain, f_max):
    """1.0 if ``f_child > f_parent`` else 0.0; with ``gain``, ``max(0, f_child - f_parent) / f_max``.

    >>> bandit_reward(3.0, 2.0, False, 10.0), bandit_reward(3.0, 2.0, True, 10.0)
    (1.0, 0.1)
    """
    if not gain:
        return 1.0 if f_child > f_parent else 0.0
    d = f_child - f_parent
    return (d if d > 0.0 else 0.0) / f_max


@njit(cache=True)
def draw_arm(probs, u):
    """The index of the arm drawn with probabilities ``probs`` (K,) by one uniform ``u`` in [0, 1): the first whose
    cumulative probability exceeds ``u`` times the total (the last if none does).

    >>> import numpy as np
    >>> draw_arm(np.array([0.25, 0.25, 0.5]), 0.5)
    2
    """
    k = probs.shape[0]
    cdf = np.cumsum(probs)
    x = u * cdf[k - 1]
    for a in range(k):
        if cdf[a] > x:
            return a
    return k - 1


@njit(cache=True)
def exp3_probs(log_w, gamma, out):
    """EXP3's probabilities from log weights (K,) into ``out`` (K,): ``(1 - gamma) w / sum(w) + gamma / K`` with
    ``w = exp(log_w - max(log_w))`` (libm's exp, the same in numba and numpy's scalar math).

    >>> import numpy as np
    >>> out = np.empty(2)
    >>> exp3_probs(np.zeros(2), 0.1, out)
    >>> out.tolist()
    [0.5, 0.5]
    """
    k = log_w.shape[0]
    top = log_w.max()
    w = np.empty(k)
    for a in range(k):
        w[a] = math.exp(log_w[a] - top)
    total = pairwise_sum(w)
    for a in range(k):
        out[a] = (1.0 - gamma) * w[a] / total + gamma / k


@njit(cache=True)
def exp3_update(log_w, probs, a, x, gamma, out):
    """EXP3 after arm ``a`` with probabilities ``probs`` (K,) earned reward ``x``: ``log_w`` (K,) in place gains
    ``gamma * (x / probs[a]) / K`` at ``a`` and is shifted to a maximum of 0; the new probabilities go to ``out``
    (K; it may be ``probs``)."""
    k = log_w.shape[0]
    log_w[a] += gamma * (x / probs[a]) / k
    log_w -= log_w.max()
    exp3_probs(log_w, gamma, out)
