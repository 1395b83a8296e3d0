"""The one place where the analysis re-runs a run: to find which rover an update mutated (the Fig. 6 data). This
module alone drives the learner; nothing else in :mod:`rovermarl.analysis` imports it."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from omegaconf import OmegaConf

from rovermarl.runner import Run
from rovermarl.runner.trust import check_targets


def mutated_rovers(config: dict, seed: int, generations_after: Sequence[int], source: str = "a results directory",
                   trust: bool = False) -> list[tuple[np.ndarray, float, bool]]:
    """Re-run seed ``seed`` of the job with the composed ``config`` from scratch. For each generation g of
    ``generations_after`` (increasing): the rovers whose genome g changed in the parent team (int64 indices), the
    parent score after g, and whether g's child was accepted (for the caller to check against the recording).
    Unless ``trust``, ``config`` (read from ``source``) must pass :func:`~rovermarl.runner.trust.check_targets`
    (only classes of the config group at whose node they sit) before anything is built."""
    if not trust:
        check_targets(config, source)
    replay, out = Run(OmegaConf.create(config), seed), []
    for g in generations_after:
        replay.advance(g - 1 - replay.generation)
        parents = replay.team.copy()
        accepted = replay.advance(1)["accepted"]
        changed = np.flatnonzero((replay.team != parents).any(axis=1)).astype(np.int64)
        out.append((changed, replay.score, bool(accepted[0])))
    return out
