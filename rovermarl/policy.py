"""The rover policy: a 1-hidden-layer tanh MLP over a flat genome (SPEC section 4).

Flat genome layout for ``obs_dim`` D, ``hidden`` H and 2 outputs::

    W1 (D, H) row-major, input-major | b1 (H,) | W2 (H, 2) row-major | b2 (2,)

so ``n_params = D*H + H + 2*H + 2`` (658 for D=38, H=16).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rovermarl import errors
from rovermarl.resources import packaged

N_OUT = 2


def n_params(obs_dim: int, hidden: int) -> int:
    """Genome length for an ``obs_dim -> hidden -> 2`` MLP."""
    return obs_dim * hidden + hidden + hidden * N_OUT + N_OUT


def unflatten(genome: np.ndarray, obs_dim: int, hidden: int):
    """Views of a flat genome (P,) as ``W1 (D, H), b1 (H,), W2 (H, 2), b2 (2,)``."""
    d, h = obs_dim, hidden
    if genome.shape[-1] != n_params(d, h):
        raise ValueError(f"genome has {genome.shape[-1]} parameters, expected {n_params(d, h)}")
    o1, o2, o3 = d * h, d * h + h, d * h + h + h * N_OUT
    return (genome[..., :o1].reshape(*genome.shape[:-1], d, h), genome[..., o1:o2],
            genome[..., o2:o3].reshape(*genome.shape[:-1], h, N_OUT), genome[..., o3:])


def flatten(w1: np.ndarray, b1: np.ndarray, w2: np.ndarray, b2: np.ndarray) -> np.ndarray:
    """Inverse of :func:`unflatten` for one genome: returns (P,)."""
    return np.concatenate([np.ravel(w1), np.ravel(b1), np.ravel(w2), np.ravel(b2)]).astype(np.float64)


def forward(genome: np.ndarray, obs: np.ndarray, hidden: int) -> np.ndarray:
    """Reference (numpy) policy: genome (P,), obs (..., D) -> actions (..., 2) in [-1, 1]."""
    w1, b1, w2, b2 = unflatten(genome, obs.shape[-1], hidden)
    return np.tanh(np.tanh(obs @ w1 + b1) @ w2 + b2)


@dataclass(frozen=True)
class MLP:
    """The policy's configuration (the ``policy`` group, ``conf/policy/mlp.yaml``: the one home of its default):
    ``hidden`` H units. A world is built with one (``World.policy``), since its kernel runs the policy. The initial
    genome range (``policy.init_low``, ``policy.init_high``) belongs to the learners, which read it from the config."""

    hidden: int = packaged("policy/mlp.yaml")["hidden"]

    def __post_init__(self):
        errors.integer("policy.hidden", self.hidden, 1)

    def n_params(self, obs_dim: int) -> int:
        """Genome length for ``obs_dim`` inputs (658 for 38 and 16 hidden units)."""
        return n_params(obs_dim, self.hidden)
