"""Mutation operators. Each is built from ``conf/mutation/*.yaml`` and called as ``op(genome, rng)``."""

from __future__ import annotations

import numpy as np

from rovermarl import errors
from rovermarl.jit import njit


class MixedMutation:
    """SPEC section 6: Gaussian on all parameters with prob ``p_gaussian``, else a uniform reset of
    ``floor(uniform_fraction * P)`` distinct parameters to ``U(low, high)``. No clipping."""

    def __init__(self, p_gaussian: float = 0.2, sigma: float = 0.1, uniform_fraction: float = 0.25,
                 low: float = -2.0, high: float = 2.0):
        self.p_gaussian = errors.number("p_gaussian", p_gaussian, 0, 1)
        self.sigma = errors.number("sigma", sigma, 0)
        self.uniform_fraction = errors.number("uniform_fraction", uniform_fraction, 0, 1)
        self.low = errors.number("low", low)
        self.high = errors.number("high", high)
        if self.high <= self.low:
            raise errors.ConfigError("high", high, f"must be greater than low={low}")

    def n_reset(self, n_params: int) -> int:
        """How many parameters a uniform mutation resets (164 of 658 by default)."""
        return int(np.floor(self.uniform_fraction * n_params))

    def __call__(self, genome: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        """A mutated copy of ``genome`` (P,)."""
        return mixed(genome, rng, self.p_gaussian, self.sigma, self.n_reset(genome.shape[0]), self.low, self.high)


@njit(cache=True)
def mixed(genome, rng, p_gaussian, sigma, m, low, high):
    """The mixed mutation of ``genome`` (P,) (a copy): with probability ``p_gaussian`` N(0, sigma^2) added to every
    parameter, else ``m`` distinct parameters reset to U(low, high). ``rng`` is a numpy Generator (numba draws
    the same numbers from it as numpy does), so the Python loop and the compiled one mutate alike.

    >>> import numpy as np
    >>> mixed(np.zeros(4), np.random.default_rng(0), 0.0, 0.1, 2, -2.0, 2.0).round(2).tolist()
    [1.25, -1.93, 0.0, 0.0]
    """
    if rng.random() < p_gaussian:
        return genome + rng.normal(0.0, sigma, genome.shape[0])
    child, n = genome.copy(), genome.shape[0]
    u, values = rng.random(m), rng.uniform(low, high, m)
    perm = np.arange(n)
    for i in range(m):                  # m distinct entries, by a partial Fisher-Yates shuffle driven by u (m,)
        j = min(i + int(u[i] * (n - i)), n - 1)
        perm[i], perm[j] = perm[j], perm[i]
        child[perm[i]] = values[i]
    return child
