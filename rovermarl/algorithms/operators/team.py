"""Team compositions: how parents map to the rovers' genomes and which parents a generation mutates."""

from __future__ import annotations

import numpy as np
from numba.np.random.random_methods import random_interval  # numpy's bounded draw, as its shuffle makes it

from rovermarl.jit import njit


class Team:
    """Base: ``parents`` is (M, P); the world sees :meth:`genomes` (N, P)."""

    n_genomes: int

    def __init__(self, n_agents: int):
        self.n_agents = n_agents

    def init(self, n_params: int, low: float, high: float, rng: np.random.Generator) -> np.ndarray:
        """Initial parents (M, P), uniform in [low, high]."""
        return rng.uniform(low, high, size=(self.n_genomes, n_params))

    def pick(self, k: int, rng: np.random.Generator) -> np.ndarray:
        """Indices of the parents to mutate this generation."""
        raise NotImplementedError

    def mutate(self, parents: np.ndarray, chosen: np.ndarray, mutation, rng: np.random.Generator) -> np.ndarray:
        """Children (M, P): ``parents`` with each chosen row replaced by ``mutation(row, rng)``."""
        children = parents.copy()
        for i in chosen:
            children[i] = mutation(parents[i], rng)
        return children

    def genomes(self, parents: np.ndarray) -> np.ndarray:
        """The team as the world sees it: (N, P)."""
        raise NotImplementedError

    def mutated(self, chosen: np.ndarray) -> np.ndarray:
        """(N,) bool: the rovers whose genome changes when the parents ``chosen`` are mutated."""
        raise NotImplementedError


class HeterogeneousTeam(Team):
    """One genome per rover; each generation mutates ``k`` distinct rovers drawn uniformly."""

    @property
    def n_genomes(self) -> int:
        return self.n_agents

    def pick(self, k, rng):
        return pick_distinct(rng, self.n_agents, k)

    def genomes(self, parents):
        return parents

    def mutated(self, chosen):
        mask = np.zeros(self.n_agents, dtype=bool)
        mask[chosen] = True
        return mask


class HomogeneousTeam(Team):
    """One genome cloned on all rovers; each generation mutates it once, whatever ``k``."""

    n_genomes = 1
    _ONE = np.zeros(1, dtype=np.int64)

    def pick(self, k, rng):
        return self._ONE

    def genomes(self, parents):
        return np.repeat(parents, self.n_agents, axis=0)

    def mutated(self, chosen):
        return np.ones(self.n_agents, dtype=bool)


@njit(cache=True)
def pick_distinct(rng, n, k):
    """``k`` distinct indices of 0..n-1, uniformly: the first k of ``rng.permutation(n)``, the same draws as numpy's
    (its Fisher-Yates shuffle, written out: numba's ``permutation`` took 8 s of a cold start to compile).

    >>> import numpy as np
    >>> pick_distinct(np.random.default_rng(0), 4, 2).tolist()
    [2, 0]
    """
    perm = np.arange(n)
    for i in range(n - 1, 0, -1):
        j = np.int64(random_interval(rng.bit_generator, i))
        perm[i], perm[j] = perm[j], perm[i]
    return perm[:k]
