"""Initial-condition shards: each team evaluation's E episodes split over S Ray actors (``parallel.ic_shards=S``).

The generation loop stays in the driver; each actor rolls out its slice of episodes and the per-episode returns are
concatenated in order before the mean, so scores are bit-identical to local evaluation. It pays off only when one
evaluation is heavy (``benchmarks/scaling.py``).
"""

from __future__ import annotations

import numpy as np
import ray
from omegaconf import OmegaConf

from rovermarl.algorithms.base import Evaluator, Measured
from rovermarl.env import Rollout, World
from rovermarl.env.kernel import score


@ray.remote(num_cpus=1)
class ShardActor:
    """Rolls out one slice of a run's initial conditions: xy (e, N, 2), heading (e, N), layout (e, K)."""

    def __init__(self, cfg: dict):
        self.world = World.from_config(OmegaConf.create(cfg), trust=True)   # the driver's composed config
        self.ic = None

    def set_ic(self, xy: np.ndarray, heading: np.ndarray, layout: np.ndarray) -> None:
        self.ic = (xy, heading, layout)

    def draw(self, seed: int, generation: int, lo: int, hi: int) -> None:
        """Episodes ``lo:hi`` of run ``seed``'s initial conditions of ``generation`` (``evaluation.fresh_ic``)."""
        self.ic = tuple(a[lo:hi] for a in self.world.run_ic(seed, generation))

    def returns(self, genomes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """genomes (N, P) -> per-episode returns (e,), final positions (e, N, 2)."""
        final = np.empty(self.ic[0].shape)
        return self.world.returns(genomes, self.ic, final), final

    def rollout(self, genomes: np.ndarray) -> Rollout:
        """genomes (N, P) -> the slice's trajectories (:meth:`World.rollout`)."""
        return self.world.rollout(genomes, self.ic)


class ShardedEvaluation(Evaluator):
    """An :class:`~rovermarl.algorithms.base.Evaluator` over shard actors, with the results and arguments of the local
    :class:`rovermarl.runner.chunk.Evaluation` (under ``fresh_ic`` each actor draws its own slice of a generation's
    initial conditions); no :meth:`kernel_inputs`: teams are scored in other processes."""

    def __init__(self, actors: list, world: World, ic: tuple, keep_final: bool = True, fresh_seed: int | None = None):
        self.actors, self.seed = actors, fresh_seed
        self.fresh = fresh_seed is not None
        self.calls = 0
        self.final_xy = np.empty(ic[0].shape) if keep_final else None
        bounds = np.linspace(0, ic[1].shape[0], len(actors) + 1).round().astype(int)
        self.shards = list(zip(actors, bounds[:-1], bounds[1:], strict=True))     # (actor, lo, hi): its episodes
        ray.get([a.set_ic.remote(*(part[lo:hi] for part in ic)) for a, lo, hi in self.shards])

    def draw(self, generation: int) -> None:
        if not self.fresh:
            super().draw(generation)
        ray.get([a.draw.remote(self.seed, generation, lo, hi) for a, lo, hi in self.shards])

    def measure(self, genomes: np.ndarray) -> Measured:
        self.calls += 1
        genomes = np.ascontiguousarray(genomes)                         # small: sent inline with each call
        parts = ray.get([a.returns.remote(genomes) for a in self.actors])
        returns = np.concatenate([r for r, _ in parts])
        if self.final_xy is None:
            return Measured(float(score(returns)), None)
        self.final_xy[...] = np.concatenate([f for _, f in parts])
        return Measured(float(score(returns)), self.final_xy.copy())

    def rollout(self, genomes: np.ndarray) -> Rollout:
        """The slices' trajectories, concatenated in order: the local rollout's, episode by episode."""
        self.calls += 1
        parts = ray.get([a.rollout.remote(np.ascontiguousarray(genomes)) for a in self.actors])
        return Rollout(*(np.concatenate(arrays) for arrays in zip(*parts, strict=True)))

